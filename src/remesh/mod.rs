//! Remeshing: a [`Representation`] back to a triangle mesh (Simari & Singh 2005, section 5).
//!
//! One stage per module:
//! - [`chart`]: each region's map to the plane (section 5.1): the ellipsoid to the unit
//!   sphere, a rotation that keeps the north pole away from the region, stereographic
//!   projection; point-in-region against the projected outer cycle and holes;
//! - [`query`]: the analytic ray query on a whole representation (first hit → point, normal,
//!   region), the use the paper motivates;
//! - [`refine`]: boundary arcs refined on the intersection curve of the two ellipsoids they
//!   separate, one set of points shared by both regions;
//! - [`surface`]: the surface a region is meshed on: its ellipsoid, with the boundary's
//!   offsets from it blended in near the boundary so that the mesh meets the stored
//!   boundary points without a fringe of standing triangles;
//! - [`triangulate`]: one region's constrained Delaunay triangulation in its chart (spade),
//!   by iterative vertex addition (section 5.3, the default) or from a parametric grid
//!   (section 5.2);
//! - [`assemble`]: the regions joined into one watertight mesh with analytic normals;
//! - [`subdivide`]: for large budgets, that mesh made at a fraction of the budget and split
//!   uniformly, every new point on its ellipsoid or boundary curve.
//!
//! [`remesh`] runs them all.

pub mod assemble;
pub mod chart;
pub mod query;
pub mod refine;
pub mod subdivide;
pub mod surface;
pub mod triangulate;

pub use chart::ChartMemo;

use crate::mesh::{Mesh, MeshError};
use crate::representation::{InvalidRepresentation, Representation};
use glam::DVec3;

/// How a region's interior is tessellated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scheme {
    /// Iterative vertex addition (section 5.3): insert the face centre farthest from the
    /// ellipsoid until the budget or the tolerance is reached. The default.
    #[default]
    Adaptive,
    /// A regular azimuth/elevation grid on the unit sphere, the points inside the region
    /// kept (section 5.2).
    Parametric,
}

/// Vertex budget used when neither the options nor the file suggest one.
pub const DEFAULT_VERTICES: usize = 20_000;

/// Largest vertex budget a decode may use unless the caller raises it: a hostile file's
/// suggested count must not exhaust memory.
pub const MAX_VERTICES: usize = 20_000_000;

/// What the remesher is asked for. Every field has a default ([`Default`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RemeshOptions {
    /// Total output vertex budget, shared among regions by their error; `None`: the file's
    /// suggestion, else [`DEFAULT_VERTICES`]. Capped at `max_vertices`.
    pub vertices: Option<usize>,
    /// Stop refining once every face's centre is within this distance of its region's
    /// surface ([`surface`]), as a fraction of the bounding-box diagonal; `None`: only the
    /// budget stops.
    pub tolerance: Option<f64>,
    /// Adaptive (default) or parametric.
    pub scheme: Scheme,
    /// Upper bound on the budget (default [`MAX_VERTICES`]).
    pub max_vertices: usize,
    /// Whether a budget large enough ([`RemeshOptions::subdivision_levels`]: at least four
    /// times [`SUBDIVISION_COARSE_VERTICES`] and [`SUBDIVISION_VERTICES_PER_REGION`] per
    /// region; adaptive scheme, no tolerance) may be met by meshing adaptively at a quarter,
    /// a sixteenth or a sixty-fourth of it and splitting every triangle into four
    /// ([`subdivide`]); default true. Off, every vertex is placed by iterative vertex
    /// addition (two to four times slower from 20 000 vertices up).
    pub subdivision: bool,
    /// When some region fails in every meshing attempt: whether the attempts are made again
    /// leaving out each region that fails (a hole, counted in
    /// [`assemble::MeshCheck::omitted_regions`]) so that the rest decodes; default true.
    /// Off, such a file fails with [`RemeshError::Region`].
    pub leave_out: bool,
}

/// Fewest vertices the adaptive mesh that [`subdivide`] refines is made with.
///
/// Measured against the source (`ellip decode --vertices N`, then `ellip compare SOURCE
/// OUT`: symmetric RMS as % of the diagonal, normal deviation) on the decode bench's files
/// (hand and horse at 18 regions, teddy and bunny at 8, hand at K = 64), at 20 000, 30 000,
/// 80 000 and 320 000 vertices: with 5 000 instead of 10 000, RMS within 1.5 % of what it
/// was (hand at 20 000: 0.252 % instead of 0.260 %; horse at 30 000: 1.679 % instead of
/// 1.658 %), 4 % for hand at K = 64, and normals within 0.3°. The budgets from 20 000 to
/// 40 000 vertices, which were met by vertex addition alone, take a quarter to a half of
/// the time (README, "Large budgets are met by subdivision"). From a coarser mesh it costs
/// more: at 5 000 vertices, one level from 1 250 is about what vertex addition gives at half
/// the budget; hand at 80 000 vertices, three levels from 1 250, was 9 % worse in RMS than
/// vertex addition alone.
pub const SUBDIVISION_COARSE_VERTICES: usize = 5_000;

/// Fewest vertices per region the adaptive mesh that [`subdivide`] refines is made with: a
/// coarser mesh is mostly boundary, and subdividing it spreads evenly the vertices vertex
/// addition would put where the error is. Measured against the source at 5 000 to 20 000
/// vertices (vertex addition at a quarter of the budget subdivided once, against vertex
/// addition alone) on hand at K = 64 and the npm bunny at K = 100: from 20 and 12 coarse
/// vertices per region, 32 % and 17 % worse in RMS; from 39 and 25, 7 % and 6 %; from 78
/// and 50, 4 % worse and 5 % better.
pub const SUBDIVISION_VERTICES_PER_REGION: usize = 64;

/// Most levels of subdivision (each multiplies the vertex count by about four).
pub const MAX_SUBDIVISION_LEVELS: u32 = 3;

impl Default for RemeshOptions {
    fn default() -> Self {
        RemeshOptions {
            vertices: None,
            tolerance: None,
            scheme: Scheme::Adaptive,
            max_vertices: MAX_VERTICES,
            subdivision: true,
            leave_out: true,
        }
    }
}

impl RemeshOptions {
    /// Checks every option: a budget of at least one vertex (and no more than
    /// `max_vertices`), a finite positive tolerance, `max_vertices` at least 1.
    pub fn validate(&self) -> Result<(), RemeshError> {
        let invalid = |what, value: String| Err(RemeshError::InvalidOption { what, value });
        if self.max_vertices == 0 {
            return invalid("max_vertices", "0 (must be at least 1)".into());
        }
        match self.vertices {
            Some(0) => return invalid("vertices", "0 (must be at least 1)".into()),
            Some(n) if n > self.max_vertices => {
                return invalid(
                    "vertices",
                    format!("{n} (more than the maximum of {})", self.max_vertices),
                )
            }
            _ => {}
        }
        if let Some(t) = self.tolerance {
            if !(t.is_finite() && t > 0.0) {
                return invalid(
                    "tolerance",
                    format!("{t} (must be a positive fraction of the bounding-box diagonal)"),
                );
            }
        }
        Ok(())
    }

    /// How many times [`remesh`] subdivides an adaptive mesh to meet `budget` vertices for a
    /// representation of `regions` regions: the most levels (up to
    /// [`MAX_SUBDIVISION_LEVELS`]) that leave the adaptive mesh at least
    /// [`SUBDIVISION_COARSE_VERTICES`] and [`SUBDIVISION_VERTICES_PER_REGION`] per region;
    /// 0 unless [`RemeshOptions::subdivision`] is on, the scheme adaptive and no tolerance
    /// set (a tolerance is met by vertex addition alone).
    pub fn subdivision_levels(&self, budget: usize, regions: usize) -> u32 {
        if !self.subdivision || self.scheme != Scheme::Adaptive || self.tolerance.is_some() {
            return 0;
        }
        let fewest = SUBDIVISION_COARSE_VERTICES
            .max(regions.saturating_mul(SUBDIVISION_VERTICES_PER_REGION));
        let mut levels = 0;
        while levels < MAX_SUBDIVISION_LEVELS && budget / 4usize.pow(levels + 1) >= fewest {
            levels += 1;
        }
        levels
    }

    /// The vertex budget for `rep`: the option, else the file's suggestion, else the source
    /// mesh's vertex count (when the file gives one), else [`DEFAULT_VERTICES`]; capped at
    /// `max_vertices`, at least 1.
    pub fn budget(&self, rep: &Representation) -> usize {
        let m = &rep.metadata;
        let suggested = m
            .suggested_vertices
            .or((m.source_vertices > 0).then_some(m.source_vertices))
            .map(|n| usize::try_from(n).unwrap_or(usize::MAX));
        self.vertices
            .or(suggested)
            .unwrap_or(DEFAULT_VERTICES)
            .clamp(1, self.max_vertices.max(1))
    }
}

/// A remeshed representation.
#[derive(Debug, Clone)]
pub struct Remeshed {
    /// The triangle mesh; closed and manifold when every arc separates two regions.
    pub mesh: Mesh,
    /// Per vertex, the analytic unit normal (averaged across the regions a boundary vertex
    /// touches), oriented like the faces.
    pub normals: Vec<DVec3>,
    /// Per face, the region it belongs to.
    pub face_regions: Vec<u32>,
    /// What was measured on the result.
    pub check: assemble::MeshCheck,
    /// The regions left out because they could not be meshed in the attempt kept, in
    /// increasing order (their count is [`assemble::MeshCheck::omitted_regions`]); empty
    /// unless every attempt at meshing them all failed.
    pub omitted: Vec<u32>,
    /// How many times the regions were meshed to make this, over every budget tried: one
    /// when the first meshing is clean (at the budget, or coarser and then subdivided);
    /// each fallback (another boundary treatment or projection, another budget, regions
    /// left out) counts one more ([`assemble::assemble`]). Decoding time grows with it.
    pub attempts: usize,
    /// The boundary treatment the mesh was made with (of the coarse mesh, when subdivided);
    /// `None` for a mesh not made by [`remesh`]. A file whose
    /// [`crate::representation::Metadata::remesh_hint`] names it meshes this way first.
    pub treatment: Option<assemble::Treatment>,
}

impl Remeshed {
    /// The regions of a representation of `region_count` regions that have no face in the
    /// mesh and were not left out ([`Remeshed::omitted`]), in increasing order: regions
    /// whose every boundary loop encloses nothing (quantisation merged its points, spec
    /// §12). Right for a region a few grid steps across, which the regions around it close
    /// over; a larger one is lost (the encoder checks its own files for that,
    /// [`crate::encode::MAX_LOST`]).
    pub fn faceless_regions(&self, region_count: usize) -> Vec<u32> {
        let mut has_faces = vec![false; region_count];
        for &r in &self.face_regions {
            if let Some(h) = has_faces.get_mut(r as usize) {
                *h = true;
            }
        }
        (0u32..)
            .zip(has_faces)
            .filter(|&(r, has)| !has && !self.omitted.contains(&r))
            .map(|(r, _)| r)
            .collect()
    }

    /// Where its flipped and degenerate triangles are
    /// ([`assemble::triangle_faults_by_region`] of `rep`, the representation it was made
    /// from); empty, without a walk over the mesh, when its check found none.
    pub fn faulty_regions(&self, rep: &Representation) -> Vec<assemble::RegionTriangleFaults> {
        if self.check.flipped + self.check.degenerate == 0 {
            return Vec::new();
        }
        assemble::triangle_faults_by_region(rep, &self.mesh, &self.face_regions)
    }
}

/// Why a representation could not be remeshed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RemeshError {
    /// The representation breaks a rule of the format.
    #[error(transparent)]
    Invalid(#[from] InvalidRepresentation),
    /// A region's boundary cannot be mapped or triangulated (e.g. its cycles cross).
    #[error("region {region}: {what}")]
    Region {
        /// The region.
        region: u32,
        /// What is wrong.
        what: &'static str,
    },
    /// An option is out of range.
    #[error("invalid option {what}: {value}")]
    InvalidOption {
        /// The option.
        what: &'static str,
        /// Its value, as text.
        value: String,
    },
    /// The geometry cannot be meshed at a usable scale (e.g. radii so large that areas or
    /// spacings overflow).
    #[error("geometry out of range: {what}")]
    Geometry {
        /// What overflowed.
        what: &'static str,
    },
    /// The representation needs more vertices than the options allow (its boundary points
    /// alone, plus a minimal tessellation of each closed ellipsoid).
    #[error("needs at least {needed} vertices, more than the maximum of {max}")]
    TooManyVertices {
        /// The fewest vertices this representation can be meshed with.
        needed: usize,
        /// [`RemeshOptions::max_vertices`].
        max: usize,
    },
    /// The assembled mesh was refused (a bug: reported, never written).
    #[error("internal error, the assembled mesh is invalid: {0}")]
    Mesh(#[from] MeshError),
}

/// Remeshes a representation (validated first, options too): refines the boundary arcs
/// ([`refine`]), maps each region to its chart ([`chart`]), triangulates every region
/// ([`triangulate`]) sharing the vertex budget among them by their error, and joins them
/// into one mesh ([`assemble`]). Deterministic: the same input gives the same mesh.
pub fn remesh(rep: &Representation, options: &RemeshOptions) -> Result<Remeshed, RemeshError> {
    remesh_with_charts(rep, options, &ChartMemo::default())
}

/// [`remesh`], its charts kept in `charts` and taken from there when a region's chart has
/// the same inputs (ellipsoid, loop points, projection, pole walk) as one made in this
/// call or the one before: for a caller that decodes representations alike one after
/// another, each a few regions from the last (the encoder's check of its rounds of
/// mending). The mesh is the same as [`remesh`]'s, bit for bit ([`ChartMemo`]). The
/// charts that the call before did not ask for are dropped first ([`ChartMemo::age`]).
pub fn remesh_with_charts(
    rep: &Representation,
    options: &RemeshOptions,
    charts: &ChartMemo,
) -> Result<Remeshed, RemeshError> {
    charts.age();
    assemble::assemble(rep, options, charts)
}
