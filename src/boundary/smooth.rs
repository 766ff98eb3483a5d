//! Constrained relaxation of boundary vertices toward the ellipsoids they touch
//! (Simari & Singh 2005, section 4.1). (Being written.)

use super::BoundaryGraph;
use crate::ellipsoid::Ellipsoid;
use crate::mesh::Mesh;
use glam::DVec3;

/// Iterations and step of the relaxation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothOptions {
    /// Number of relaxation passes.
    pub iterations: usize,
    /// Step ε of p ← (1−ε)p + εq.
    pub epsilon: f64,
}

/// Relaxes every boundary vertex; returns the new position of each vertex of
/// `graph.vertices`, in the same order.
pub fn smooth_boundaries(
    _mesh: &Mesh,
    _graph: &BoundaryGraph,
    _ellipsoids: &[Ellipsoid],
    _options: &SmoothOptions,
) -> Vec<DVec3> {
    todo!("being written")
}
