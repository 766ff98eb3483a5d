//! One region's triangulation in its chart with spade's constrained Delaunay triangulation:
//! iterative vertex addition (section 5.3) and the parametric grid (section 5.2).
//!
//! The API the assembler uses (the bodies are issue 6's work in progress):
//!
//! ```text
//! AdaptiveTriangulation::new(&RegionInput, min_spacing) -> Result<Self, RemeshError>
//!     .worst_error() -> Option<f64>   // radial distance of the worst face centre, model units
//!     .insert_worst() -> bool         // false when no candidate is left
//!     .added() -> usize               // interior vertices inserted so far
//!     .finish() -> RegionMesh
//! triangulate_parametric(&RegionInput, interior_vertices) -> Result<RegionMesh, RemeshError>
//! ```

use super::chart::RegionChart;
use glam::DVec3;

/// What one region's triangulation starts from.
#[derive(Debug, Clone, Copy)]
pub struct RegionInput<'a> {
    /// The region (for error messages).
    pub region: u32,
    /// Its chart (which holds its ellipsoid).
    pub chart: &'a RegionChart,
    /// Positions of the boundary vertices the loops refer to (shared with the neighbours).
    pub boundary: &'a [DVec3],
    /// The region's boundary loops as indices into `boundary`, each closed (the first index
    /// not repeated at the end), with the region on its left (outward normal up).
    pub loops: &'a [Vec<u32>],
}

/// A triangle corner: a boundary vertex (index into [`RegionInput::boundary`]) or a new
/// interior vertex (index into [`RegionMesh::interior`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Corner {
    /// Index into the input's boundary vertices.
    Boundary(u32),
    /// Index into [`RegionMesh::interior`].
    Interior(u32),
}

/// One region's triangles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RegionMesh {
    /// New vertices, on the ellipsoid.
    pub interior: Vec<DVec3>,
    /// Triangles, counter-clockwise seen against the ellipsoid's signed normal
    /// ([`crate::ellipsoid::Ellipsoid::normal`]): outward for positive ellipsoids, inward for
    /// negative ones.
    pub triangles: Vec<[Corner; 3]>,
}
