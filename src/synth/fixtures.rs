//! The generator of the committed fixture meshes in `fixtures/meshes/`.
//!
//! `ellip fixtures` (a hidden subcommand) runs [`write_fixtures`]; a test regenerates every
//! file into a temporary folder and compares it byte for byte with the committed copy, so a
//! change to any shape, to the blob extractor or to the OBJ writer shows up as a failing test
//! and has to be made deliberately (by regenerating and committing).
//!
//! Each mesh is written as OBJ; shapes made of known ellipsoids also get a `NAME.json` with the
//! true ellipsoids (`{"ellipsoids": [{"center", "rotation" (x, y, z, w), "radii"}]}`).

use super::blob::{blob, random_ellipsoids, BlobOptions};
use super::shapes;
use super::EllipsoidSpec;
use crate::export::{write_mesh, ExportError, MeshData};
use crate::mesh::Mesh;
use glam::{DQuat, DVec3};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One fixture: a mesh, and the ellipsoids it is made of when they are known.
#[derive(Debug, Clone)]
pub struct Fixture {
    /// File stem, e.g. `blob1`.
    pub name: &'static str,
    /// The mesh.
    pub mesh: Mesh,
    /// The true ellipsoids (empty when the shape is not made of ellipsoids).
    pub truth: Vec<EllipsoidSpec>,
}

/// The seeds and ellipsoid counts of the blob fixtures.
pub const BLOBS: [(&str, u64, usize); 4] = [
    ("blob1", 1, 3),
    ("blob2", 2, 4),
    ("blob3", 3, 5),
    ("blob4", 4, 6),
];

/// Faces the blob extractor aims for.
pub const BLOB_FACES: usize = 8000;

/// Builds every fixture, in a fixed order.
pub fn build_fixtures() -> Vec<Fixture> {
    let plain = |name, mesh| Fixture {
        name,
        mesh,
        truth: Vec::new(),
    };
    let unit_sphere = EllipsoidSpec {
        center: DVec3::ZERO,
        rotation: DQuat::IDENTITY,
        radii: DVec3::ONE,
    };
    let ellipsoid = EllipsoidSpec {
        center: DVec3::new(0.25, -0.5, 0.125),
        rotation: DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
        radii: DVec3::new(1.5, 0.75, 0.5),
    };
    let mut fixtures = vec![
        Fixture {
            name: "icosphere",
            mesh: shapes::icosphere(1.0, 4),
            truth: vec![unit_sphere],
        },
        Fixture {
            name: "ellipsoid",
            mesh: shapes::ellipsoid(&ellipsoid, 4),
            truth: vec![ellipsoid],
        },
        plain("torus", shapes::torus(1.0, 0.35, 64, 32)),
        plain("capsule", shapes::capsule(0.5, 1.5, 32)),
        plain("bowl", shapes::bowl(1.0, 4)),
        plain("hemisphere", shapes::hemisphere(1.0, 4)),
        plain("cube", shapes::cube(1.0, 8)),
    ];
    let options = BlobOptions {
        target_faces: BLOB_FACES,
        ..BlobOptions::default()
    };
    for (name, seed, count) in BLOBS {
        let truth = random_ellipsoids(seed, count);
        let mesh = blob(&truth, &options).expect("the fixture blobs are well formed");
        fixtures.push(Fixture { name, mesh, truth });
    }
    fixtures
}

#[derive(Serialize)]
struct Truth<'a> {
    ellipsoids: &'a [EllipsoidSpec],
}

/// Writes every fixture into `dir`, returning the paths written.
pub fn write_fixtures(dir: &Path) -> Result<Vec<PathBuf>, ExportError> {
    let mut written = Vec::new();
    for fixture in build_fixtures() {
        let path = dir.join(format!("{}.obj", fixture.name));
        write_mesh(&path, &MeshData::from_mesh(&fixture.mesh))?;
        written.push(path);
        if !fixture.truth.is_empty() {
            let path = dir.join(format!("{}.json", fixture.name));
            let mut json = serde_json::to_string_pretty(&Truth {
                ellipsoids: &fixture.truth,
            })
            .expect("plain data serialises");
            json.push('\n');
            crate::atomic::write_atomic(&path, |w| w.write_all(json.as_bytes())).map_err(
                |source| ExportError::Io {
                    path: path.clone(),
                    source,
                },
            )?;
            written.push(path);
        }
    }
    Ok(written)
}
