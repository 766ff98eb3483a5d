//! The check the `decode_remesh` and `remesh` targets make of a representation the decoder
//! accepted (issue 6, item 9): remeshing it gives a mesh or a typed error, never a panic or
//! a hang, and a mesh it gives is consistent.

use ellip::remesh::subdivide::subdivide;
use ellip::remesh::{remesh, RemeshOptions};
use ellip::representation::Representation;

/// Remeshes `rep` with `options`, then subdivides what it gives once, and checks both.
pub fn check_remesh(rep: &Representation, options: &RemeshOptions) {
    if let Ok(out) = remesh(rep, options) {
        // Regions left out: counted, each once, in order, real regions, and without faces.
        assert_eq!(out.omitted.len(), out.check.omitted_regions);
        assert!(out.omitted.windows(2).all(|w| w[0] < w[1]));
        assert!(out
            .omitted
            .iter()
            .all(|&r| (r as usize) < rep.region_count()));
        assert!(out.face_regions.iter().all(|r| !out.omitted.contains(r)));
        assert_eq!(out.normals.len(), out.mesh.vertex_count());
        assert_eq!(out.face_regions.len(), out.mesh.face_count());
        assert!(out.normals.iter().all(|n| n.is_finite()));
        // Subdivision (used from 20 000 vertices, too slow to reach here) on what the
        // hostile file meshed to.
        if let Ok(fine) = subdivide(rep, out, 1, options.max_vertices) {
            assert_eq!(fine.normals.len(), fine.mesh.vertex_count());
            assert_eq!(fine.face_regions.len(), fine.mesh.face_count());
            assert!(fine.normals.iter().all(|n| n.is_finite()));
        }
    }
}
