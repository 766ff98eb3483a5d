//! Boundaries between regions: the graph of arcs and junctions where regions meet, each
//! region's oriented boundary cycles, and their smoothing (Simari & Singh 2005, section 4.1).
//!
//! Terms: a *boundary vertex* lies on an edge whose two faces are in different regions, or on
//! a mesh border edge. A *junction* is a boundary vertex where three or more regions meet, or
//! where a region boundary meets the mesh border (more generally: where the set of "sides"
//! around it is not exactly two). An *arc* is a chain of boundary edges between two junctions
//! (or a closed loop with no junction), bordering exactly two regions, or one region and the
//! mesh border. A region's *cycles* are closed sequences of arcs, each walked with the region
//! on its left.

mod smooth;

pub use smooth::{smooth_boundaries, SmoothOptions};

use crate::mesh::Mesh;
use serde::Serialize;

/// What lies on the other side of an arc.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum Side {
    /// Another region.
    Region(u32),
    /// The mesh border (or a non-manifold edge, which is a border between its faces).
    Border,
}

/// A chain of boundary edges between two junctions, or a closed loop.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Arc {
    /// Mesh vertex indices in order. For an arc between junctions the first and last are
    /// junctions; for a closed loop the first vertex is not repeated at the end.
    pub vertices: Vec<u32>,
    /// Whether the arc is a closed loop without junctions.
    pub closed: bool,
    /// The region on the arc's left when walked from first to last vertex (outward normals up).
    pub left: u32,
    /// What is on its right.
    pub right: Side,
}

/// An arc used forward or backward in a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ArcRef {
    /// Index into [`BoundaryGraph::arcs`].
    pub arc: u32,
    /// Walked from last vertex to first.
    pub reversed: bool,
}

/// One closed boundary of a region, with the region on its left.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Cycle {
    /// The arcs in order.
    pub arcs: Vec<ArcRef>,
    /// Whether this is the region's outer boundary (exactly one per region that has any;
    /// the others are holes).
    pub outer: bool,
}

/// The boundary graph of a segmentation.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct BoundaryGraph {
    /// Every boundary vertex (mesh vertex indices, increasing).
    pub vertices: Vec<u32>,
    /// The junctions (mesh vertex indices, increasing).
    pub junctions: Vec<u32>,
    /// The arcs.
    pub arcs: Vec<Arc>,
    /// For each region, its boundary cycles (empty for a region without boundary, e.g. a
    /// closed component covered by one region).
    pub cycles: Vec<Vec<Cycle>>,
}

/// Why the boundary graph could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum BoundaryError {
    /// `labels` has the wrong length or a label out of range.
    #[error("labels do not match the mesh: {what}")]
    BadLabels {
        /// What is wrong.
        what: String,
    },
}

/// Extracts the boundary graph of a labelling of `mesh`'s faces into `region_count` regions.
pub fn extract_boundaries(
    _mesh: &Mesh,
    _labels: &[u32],
    _region_count: usize,
) -> Result<BoundaryGraph, BoundaryError> {
    todo!("being written")
}
