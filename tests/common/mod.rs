//! Helpers shared by integration tests (each test crate uses some of them).
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// The `.obj` files in `dir`, sorted (none if it cannot be read).
pub fn obj_files(dir: &Path) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    paths.retain(|p| p.extension().is_some_and(|e| e == "obj"));
    paths.sort();
    paths
}

/// `../shared/meshes`, the real meshes beside the project (never committed into it), or
/// `None` — saying so — where it is absent.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes");
    if dir.is_dir() {
        Some(dir)
    } else {
        println!("skipped: {} is absent", dir.display());
        None
    }
}

/// The real mesh `name` (`name.obj` in [`shared_dir`]), imported with the default options;
/// `None` — saying so — where the folder is absent.
pub fn shared_mesh(name: &str) -> Option<ellip::Mesh> {
    let path = shared_dir()?.join(format!("{name}.obj"));
    let imported = ellip::import::read_mesh(&path, &ellip::import::ImportOptions::default());
    Some(
        imported
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .mesh,
    )
}

/// The real meshes of [`shared_dir`], sorted.
pub fn shared_meshes() -> Option<Vec<PathBuf>> {
    shared_dir().map(|dir| obj_files(&dir))
}
use std::process::Command;

/// Whether the Khronos glTF Validator can run here (`node` answers and
/// `.ci/node_modules/gltf-validator` is installed). When it cannot, prints why and returns
/// false — unless `ELLIP_REQUIRE_GLTF_VALIDATOR=1` (CI sets it), which makes it a failure.
pub fn validator_ready() -> bool {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let why = if !root.join(".ci/node_modules/gltf-validator").is_dir() {
        "gltf-validator is not installed (run `npm ci --prefix .ci`)".to_string()
    } else {
        match Command::new("node").arg("--version").output() {
            Ok(out) if out.status.success() => return true,
            Ok(out) => format!("`node --version` failed: {}", out.status),
            Err(e) => format!("node is not available: {e}"),
        }
    };
    let required = std::env::var("ELLIP_REQUIRE_GLTF_VALIDATOR").is_ok_and(|v| v == "1");
    assert!(!required, "ELLIP_REQUIRE_GLTF_VALIDATOR=1 but {why}");
    println!("skipped: {why}");
    false
}

/// Runs `.ci/validate-gltf.mjs` on `files`: whether every file passed (no error and no
/// warning), and what the validator printed.
pub fn run_validator(files: &[PathBuf]) -> (bool, String) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new("node")
        .arg(root.join(".ci/validate-gltf.mjs"))
        .args(files)
        .output()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    println!("{stdout}");
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    (out.status.success(), stdout)
}

/// Three thin boxes of a CAD assembly (two plates of assimp's `regr01` and a flat bar), each
/// a closed piece of eight vertices, as one mesh; with each box's half-extents and centre.
pub fn three_boxes() -> (ellip::Mesh, Vec<(glam::DVec3, glam::DVec3)>) {
    use glam::DVec3;
    let boxes = vec![
        (DVec3::new(30.0, 2.5, 72.5), DVec3::ZERO),
        (DVec3::new(60.0, 15.0, 2.0), DVec3::new(0.0, 100.0, 0.0)),
        (DVec3::new(140.0, 8.0, 1.0), DVec3::new(200.0, 0.0, 0.0)),
    ];
    let (mut positions, mut faces) = (Vec::new(), Vec::new());
    for &(half, centre) in &boxes {
        let cube = ellip::synth::shapes::cube(1.0, 1)
            .map_positions(|p| 2.0 * p * half + centre)
            .unwrap();
        let first = positions.len() as u32;
        positions.extend_from_slice(cube.positions());
        faces.extend(cube.faces().iter().map(|f| f.map(|v| v + first)));
    }
    (ellip::Mesh::new(positions, faces).unwrap(), boxes)
}
