//! An arbitrary small mesh, written as an OFF file and imported as a user's file is
//! (repairs included), encoded at 1 to 6 regions with the decoder check, plainly or with
//! area weighting: a file that decodes and remeshes, or a typed error; never a panic or a
//! hang. Small integer coordinates make what real exports have and generators do not:
//! coincident and collinear points, zero-area and duplicated faces, non-manifold edges,
//! pieces of one or two faces.
#![no_main]

use arbitrary::Arbitrary;
use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{self, Limits};
use ellip::import::{read_mesh_bytes, ImportOptions, MeshFormat};
use ellip::remesh::{remesh, RemeshOptions};
use ellip::segment::{RegionCount, SegmentOptions};
use libfuzzer_sys::fuzz_target;
use std::fmt::Write;
use std::path::Path;

/// Most faces a mesh may have here: the encoder's search makes up to a few hundred
/// segmentations and decodes, which must stay fast.
const MAX_FACES: usize = 64;

#[derive(Arbitrary, Debug)]
struct Input {
    vertices: Vec<[i8; 3]>,
    /// Corner indices, taken modulo the vertex count.
    faces: Vec<[u8; 3]>,
    regions: u8,
    area_weighting: bool,
}

fuzz_target!(|input: Input| {
    let n = input.vertices.len();
    if n < 3 || input.faces.is_empty() || input.faces.len() > MAX_FACES {
        return;
    }
    let mut off = format!("OFF\n{n} {} 0\n", input.faces.len());
    for [x, y, z] in &input.vertices {
        writeln!(off, "{x} {y} {z}").unwrap();
    }
    for face in &input.faces {
        let [a, b, c] = face.map(|i| usize::from(i) % n);
        writeln!(off, "3 {a} {b} {c}").unwrap();
    }
    let options = ImportOptions {
        format: Some(MeshFormat::Off),
        ..ImportOptions::default()
    };
    let Ok(imported) = read_mesh_bytes(off.as_bytes(), Path::new("fuzz.off"), &options) else {
        return;
    };
    let settings = EncodeSettings {
        segment: SegmentOptions {
            regions: RegionCount::Fixed(1 + usize::from(input.regions % 6)),
            area_weighting: input.area_weighting,
            ..SegmentOptions::default()
        },
        ..EncodeSettings::default()
    };
    let Ok(encoded) = encode_mesh(&imported.mesh, &settings, &mut |_| {}) else {
        return;
    };
    let rep = format::decode(&encoded.bytes, &Limits::default()).expect("its own file decodes");
    let _ = remesh(&rep, &RemeshOptions::default());
});
