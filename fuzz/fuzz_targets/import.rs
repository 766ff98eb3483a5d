//! Raw bytes into every mesh reader (OBJ, glTF, GLB, PLY, STL, OFF) and the repair after it,
//! with small limits: each must return a mesh or a typed error, never panic, and a mesh it
//! returns must be a valid one (finite positions, faces that index them). The first byte
//! chooses the format; the rest is the file. External glTF buffers are looked for in a
//! directory that does not exist, so nothing outside the input is read.
#![no_main]

use ellip::import::{read_mesh_bytes, ImportLimits, ImportOptions, MeshFormat};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

const FORMATS: [MeshFormat; 6] = [
    MeshFormat::Obj,
    MeshFormat::Gltf,
    MeshFormat::Glb,
    MeshFormat::Ply,
    MeshFormat::Stl,
    MeshFormat::Off,
];

fuzz_target!(|data: &[u8]| {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    let options = ImportOptions {
        format: Some(FORMATS[pick as usize % FORMATS.len()]),
        limits: ImportLimits {
            max_file_bytes: 1 << 20,
            max_vertices: 1 << 14,
            max_faces: 1 << 14,
        },
        ..ImportOptions::default()
    };
    let path = Path::new("/nonexistent-ellip-fuzz/mesh");
    if let Ok(imported) = read_mesh_bytes(bytes, path, &options) {
        let mesh = imported.mesh;
        assert!(mesh.positions().iter().all(|p| p.is_finite()));
        let n = mesh.vertex_count() as u32;
        assert!(mesh.faces().iter().flatten().all(|&v| v < n));
    }
});
