//! Mean curvature per vertex. (Being written: placeholder signature.)

use super::Mesh;

/// Mean curvature at every vertex.
pub fn mean_curvature(mesh: &Mesh) -> Vec<f64> {
    vec![0.0; mesh.vertex_count()]
}
