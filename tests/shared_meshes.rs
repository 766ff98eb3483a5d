//! Every real mesh in `../shared/meshes` imports with the topology its README documents.
//! Skips (and says so) when that folder is absent: the meshes are never committed here.

mod common;

use ellip::export::{write_mesh, MeshData};
use ellip::import::{read_mesh, ImportOptions};
use ellip::mesh::curvature::mean_curvature;

/// (file, closed, manifold, genus, boundary loops), from `../shared/meshes/README.md`.
const EXPECTED: &[(&str, bool, bool, Option<u64>, usize)] = &[
    ("hand.obj", true, true, Some(0), 0),
    ("teddy.obj", true, true, Some(0), 0),
    ("bunny.obj", true, true, Some(0), 0),
    ("horse.obj", true, true, Some(0), 0),
    ("dino.obj", false, false, None, 0),
    ("duck.obj", true, true, Some(0), 0),
    ("penguin.obj", true, true, Some(0), 0),
    ("spot.obj", true, true, Some(0), 0),
    ("igea_small.obj", true, true, Some(0), 0),
    ("fandisk.obj", true, true, Some(0), 0),
    ("rocker_arm.obj", true, true, Some(1), 0),
    ("demosthenes.obj", false, true, Some(0), 1),
    ("bunny_scan.obj", false, true, Some(0), 5),
    ("armadillo.obj", true, true, Some(0), 0),
    ("koala.obj", true, true, Some(0), 0),
    ("igea.obj", true, true, Some(0), 0),
];

#[test]
fn real_meshes_have_their_documented_topology() {
    let Some(dir) = common::shared_dir() else {
        return;
    };
    for &(name, closed, manifold, genus, loops) in EXPECTED {
        let path = dir.join(name);
        if !path.exists() {
            eprintln!("skipped: {name} is absent");
            continue;
        }
        let imported =
            read_mesh(&path, &ImportOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mesh = &imported.mesh;
        let t = mesh.topology();
        assert_eq!(t.is_closed(), closed, "{name}: closed");
        assert_eq!(t.is_manifold(), manifold, "{name}: manifold");
        assert_eq!(mesh.genus(), genus, "{name}: genus");
        assert_eq!(t.boundary_loops().len(), loops, "{name}: boundary loops");
        assert_eq!(t.component_count(), 1, "{name}: components");
        assert!(t.is_consistently_oriented(), "{name}: orientation");
        // The files have no degenerate or duplicate faces and no unreferenced vertices.
        assert_eq!(imported.repairs.degenerate_faces, 0, "{name}");
        assert_eq!(imported.repairs.duplicate_faces, 0, "{name}");
        assert_eq!(imported.repairs.unreferenced_vertices, 0, "{name}");
        if closed {
            assert!(
                mesh.volume().unwrap() > 0.0,
                "{name}: closed meshes end up outward"
            );
        }
    }
}

#[test]
fn the_inward_horse_is_turned_outward() {
    let Some(dir) = common::shared_dir() else {
        return;
    };
    let path = dir.join("horse.obj");
    if !path.exists() {
        return;
    }
    let imported = read_mesh(&path, &ImportOptions::default()).unwrap();
    assert_eq!(imported.repairs.reoriented_components, 1);
    let kept = read_mesh(
        &path,
        &ImportOptions {
            keep_orientation: true,
            ..ImportOptions::default()
        },
    )
    .unwrap();
    assert!(kept.mesh.signed_volume() < 0.0);
    let v = imported.mesh.volume().unwrap();
    assert!((v + kept.mesh.signed_volume()).abs() < 1e-12 * v.abs().max(1.0));
}

#[test]
fn every_real_mesh_converts_to_a_valid_glb() {
    let Some(dir) = common::shared_dir() else {
        return;
    };
    if !common::validator_ready() {
        return;
    }
    let out = std::env::temp_dir().join(format!("ellip-shared-glb-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let mut written = Vec::new();
    for &(name, ..) in EXPECTED {
        let path = dir.join(name);
        if !path.exists() {
            continue;
        }
        let mesh = read_mesh(&path, &ImportOptions::default()).unwrap().mesh;
        let normals = mesh.vertex_normals();
        let glb = out.join(name.replace(".obj", ".glb"));
        write_mesh(&glb, &MeshData::from_mesh(&mesh).with_normals(&normals)).unwrap();
        written.push(glb);
    }
    let (ok, report) = common::run_validator(&written);
    assert!(ok, "the validator flags a converted mesh:\n{report}");
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn every_real_mesh_has_finite_curvature() {
    let Some(paths) = common::shared_meshes() else {
        return;
    };
    for path in paths {
        let m = read_mesh(&path, &ImportOptions::default())
            .unwrap_or_else(|e| panic!("{e}"))
            .mesh;
        let h = mean_curvature(&m);
        assert_eq!(h.len(), m.vertex_count());
        assert!(h.iter().all(|x| x.is_finite()), "{}", path.display());
        let edge = m.average_edge_length();
        let mut scaled: Vec<f64> = h.iter().map(|x| x.abs() * edge).collect();
        scaled.sort_by(f64::total_cmp);
        println!(
            "{}: |H|·edge 99th percentile {:.3}, max {:.3}",
            path.display(),
            scaled[scaled.len() * 99 / 100],
            scaled[scaled.len() - 1]
        );
    }
}
