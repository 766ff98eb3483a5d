//! Encode: a mesh to its ellipsoidal representation and to `.ellip` bytes.
//!
//! The pipeline, one stage per module: [`segment`](crate::segment) the faces into regions
//! with their ellipsoids → [`extract_boundaries`] → [`smooth_boundaries`] toward the
//! ellipsoids (Simari & Singh 2005, section 4.1) → [`Representation::from_boundary`] →
//! [`Representation::simplify_arcs`] (Douglas–Peucker, the paper's future-work note) →
//! [`format::encode`] (quantised, compressed, checksummed; `spec/ELLIP.md`).

use crate::boundary::{extract_boundaries, smooth_boundaries, BoundaryError, SmoothOptions};
use crate::ellipsoid::Ellipsoid;
use crate::format::{self, simplify::DEFAULT_RELATIVE_TOLERANCE, EncodeError, EncodeOptions};
use crate::mesh::Mesh;
use crate::representation::{InvalidRepresentation, Metadata, Representation};
use crate::segment::{
    segment_with, EllipsoidMetric, Progress, SegmentError, SegmentOptions, Segmentation,
};

/// Everything the encoder can be told. Every field has a default ([`Default`]).
#[derive(Debug, Clone, PartialEq)]
pub struct EncodeSettings {
    /// The segmentation (default: [`SegmentOptions::default`], 12 regions).
    pub segment: SegmentOptions,
    /// Boundary smoothing (default: [`SmoothOptions::default`]).
    pub smooth: SmoothOptions,
    /// Boundary tolerance as a fraction of the bounding-box diagonal (default
    /// [`DEFAULT_RELATIVE_TOLERANCE`], 10⁻³): no stored boundary point is farther than this
    /// from the boundary it stands for, simplification and quantisation together. 0 keeps
    /// every boundary point (then only the grid moves them).
    pub simplify_tolerance: f64,
    /// Bits per axis of the boundary-point grid; `None` (the default): the one of
    /// [`AUTO_BITS`] that gives the smallest file within the boundary tolerance
    /// ([`format::DEFAULT_BITS`] when the tolerance is 0).
    pub bits: Option<u8>,
}

impl Default for EncodeSettings {
    fn default() -> Self {
        EncodeSettings {
            segment: SegmentOptions::default(),
            smooth: SmoothOptions::default(),
            simplify_tolerance: DEFAULT_RELATIVE_TOLERANCE,
            bits: None,
        }
    }
}

/// The result of encoding.
#[derive(Debug, Clone)]
pub struct Encoded {
    /// The `.ellip` file.
    pub bytes: Vec<u8>,
    /// The representation the file holds (before quantisation).
    pub representation: Representation,
    /// The segmentation it came from.
    pub segmentation: Segmentation<Ellipsoid>,
    /// Boundary points before simplification.
    pub boundary_points: usize,
    /// Boundary points simplification removed.
    pub removed_points: usize,
    /// Bits per axis of the point grid used.
    pub bits: u8,
}

/// Why a mesh could not be encoded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EncodeMeshError {
    /// The segmentation refused the mesh or the options.
    #[error(transparent)]
    Segment(#[from] SegmentError),
    /// The boundary stage refused the segmentation or the smoothing options.
    #[error(transparent)]
    Boundary(#[from] BoundaryError),
    /// The representation broke a rule of the format (a bug: reported, never written).
    #[error("internal error, the representation is invalid: {0}")]
    Representation(#[from] InvalidRepresentation),
    /// The format refused the representation or the options.
    #[error(transparent)]
    Format(#[from] EncodeError),
    /// An option is out of range.
    #[error("invalid option {what}: {value}")]
    InvalidOption {
        /// The option.
        what: &'static str,
        /// Its value, as text.
        value: String,
    },
}

/// Encodes a mesh: segments it, extracts and smooths the boundaries, simplifies the arcs and
/// writes `.ellip` bytes. `progress` hears from the segmentation loop, its long part.
pub fn encode_mesh(
    mesh: &Mesh,
    settings: &EncodeSettings,
    progress: &mut dyn FnMut(Progress),
) -> Result<Encoded, EncodeMeshError> {
    let tolerance = settings.simplify_tolerance;
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(EncodeMeshError::InvalidOption {
            what: "simplify tolerance",
            value: tolerance.to_string(),
        });
    }
    let metric = EllipsoidMetric::new(mesh, &settings.segment)?;
    let segmentation = segment_with(mesh, &metric, &settings.segment, progress)?;
    let graph = extract_boundaries(mesh, &segmentation.labels, segmentation.region_count())?;
    let smoothed = smooth_boundaries(mesh, &graph, &segmentation.proxies, &settings.smooth)?;
    let mut positions = mesh.positions().to_vec();
    for (&v, &p) in graph.vertices.iter().zip(&smoothed) {
        positions[v as usize] = p;
    }
    let diagonal = mesh.bounding_box().map_or(0.0, |b| b.diagonal());
    let metadata = Metadata {
        source_vertices: mesh.vertex_count() as u64,
        source_faces: mesh.face_count() as u64,
        simplify_tolerance: None,
        measured_error: None,
        // Decoders default to the source's vertex count: no need to store it twice.
        suggested_vertices: None,
    };
    let representation =
        Representation::from_boundary(segmentation.proxies.clone(), &positions, &graph, metadata)?;
    let boundary_points = representation.points.len();
    let absolute_tolerance = tolerance * diagonal;
    let stored = match settings.bits {
        Some(bits) => store(&representation, absolute_tolerance, bits)?,
        None if absolute_tolerance == 0.0 => {
            store(&representation, absolute_tolerance, format::DEFAULT_BITS)?
        }
        // The grid and the simplification share the boundary tolerance: try each split and
        // keep the smallest file (ties: the finer grid).
        None => {
            let mut best: Option<Stored> = None;
            for bits in AUTO_BITS {
                let grid_error = format::Grid::around(&representation.points, bits).error_bound();
                if grid_error >= absolute_tolerance {
                    continue;
                }
                let candidate = store(&representation, absolute_tolerance, bits)?;
                if best
                    .as_ref()
                    .is_none_or(|b| candidate.bytes.len() <= b.bytes.len())
                {
                    best = Some(candidate);
                }
            }
            match best {
                Some(b) => b,
                None => store(&representation, absolute_tolerance, *AUTO_BITS.end())?,
            }
        }
    };
    Ok(Encoded {
        bytes: stored.bytes,
        representation: stored.representation,
        segmentation,
        boundary_points,
        removed_points: stored.removed_points,
        bits: stored.bits,
    })
}

/// Grid resolutions the automatic choice tries. Coarser grids give smaller files still (9
/// bits: hand at K = 18 in 1 982 bytes instead of 2 047) but their rounding noise, up to
/// half the default tolerance, folds decoded boundaries: the torus fixture decoded with 58
/// flipped triangles at 9 bits and none at 10, and 4 of 13 real meshes failed to decode
/// instead of 3 (spec/ELLIP.md, appendix B).
pub const AUTO_BITS: std::ops::RangeInclusive<u8> = 10..=16;

/// One way of storing a representation.
struct Stored {
    bytes: Vec<u8>,
    representation: Representation,
    removed_points: usize,
    bits: u8,
}

/// Simplifies the arcs with what the grid of `bits` leaves of the boundary tolerance
/// (`absolute_tolerance`, model units; 0: no simplification) and writes the file.
fn store(
    representation: &Representation,
    absolute_tolerance: f64,
    bits: u8,
) -> Result<Stored, EncodeMeshError> {
    let mut representation = representation.clone();
    // The boundary tolerance bounds a stored point's whole error: Douglas–Peucker gets what
    // the grid's rounding leaves (the grid over all points is at least as coarse as the one
    // over the points simplification keeps).
    let grid_error = format::Grid::around(&representation.points, bits).error_bound();
    let simplify_tolerance = absolute_tolerance - grid_error;
    if absolute_tolerance > 0.0 && simplify_tolerance <= 0.0 {
        return Err(EncodeMeshError::InvalidOption {
            what: "bits",
            value: format!(
                "{bits}: the grid alone moves points by up to {grid_error:.3e}, more than the \
                 boundary tolerance {absolute_tolerance:.3e}; use more bits or a larger tolerance"
            ),
        });
    }
    let removed_points = if absolute_tolerance > 0.0 {
        representation.metadata.simplify_tolerance = Some(simplify_tolerance);
        representation.simplify_arcs(simplify_tolerance)
    } else {
        0
    };
    let bytes = format::encode(&representation, &EncodeOptions { bits })?;
    Ok(Stored {
        bytes,
        representation,
        removed_points,
        bits,
    })
}
