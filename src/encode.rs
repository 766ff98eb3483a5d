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
    /// Arc simplification tolerance as a fraction of the bounding-box diagonal (default
    /// [`DEFAULT_RELATIVE_TOLERANCE`], 10⁻³); 0 keeps every boundary point.
    pub simplify_tolerance: f64,
    /// Bits per axis of the boundary-point grid (default [`format::DEFAULT_BITS`]).
    pub bits: u8,
}

impl Default for EncodeSettings {
    fn default() -> Self {
        EncodeSettings {
            segment: SegmentOptions::default(),
            smooth: SmoothOptions::default(),
            simplify_tolerance: DEFAULT_RELATIVE_TOLERANCE,
            bits: format::DEFAULT_BITS,
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
    let absolute_tolerance = tolerance * diagonal;
    let metadata = Metadata {
        source_vertices: mesh.vertex_count() as u64,
        source_faces: mesh.face_count() as u64,
        simplify_tolerance: (absolute_tolerance > 0.0).then_some(absolute_tolerance),
        measured_error: None,
        suggested_vertices: Some(mesh.vertex_count() as u64),
    };
    let mut representation =
        Representation::from_boundary(segmentation.proxies.clone(), &positions, &graph, metadata)?;
    let boundary_points = representation.points.len();
    let removed_points = if absolute_tolerance > 0.0 {
        representation.simplify_arcs(absolute_tolerance)
    } else {
        0
    };
    let bytes = format::encode(
        &representation,
        &EncodeOptions {
            bits: settings.bits,
        },
    )?;
    Ok(Encoded {
        bytes,
        representation,
        segmentation,
        boundary_points,
        removed_points,
    })
}
