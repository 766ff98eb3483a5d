//! The metric interface of the Lloyd loop, and the paper's ellipsoid metric behind it.

use super::{SegmentError, SegmentOptions};
use crate::ellipsoid::Ellipsoid;
use crate::mesh::Mesh;

/// A proxy shape and how faces are measured against it: the only thing the Lloyd loop knows
/// about the primitive (as CGAL's VSA: `fit_proxy` and `compute_error`).
pub trait ProxyMetric: Sync {
    /// The fitted shape.
    type Proxy: Clone + Send + Sync + std::fmt::Debug;

    /// Fits the best proxy to a set of faces, starting from `previous` (the region's proxy in
    /// the last iteration) when given. Returns the proxy and the region's error against it.
    fn fit(&self, faces: &[u32], previous: Option<&Self::Proxy>) -> (Self::Proxy, f64);

    /// The error of one face against a proxy: what the flooding compares.
    fn face_error(&self, face: u32, proxy: &Self::Proxy) -> f64;
}

/// The paper's metric (sections 2 and 3), with the mesh's normals and curvatures computed once.
#[derive(Debug, Clone)]
pub struct EllipsoidMetric {
    _private: (),
}

impl EllipsoidMetric {
    /// Prepares the metric for a mesh: normals, curvatures, scale and weights.
    pub fn new(_mesh: &Mesh, _options: &SegmentOptions) -> Result<Self, SegmentError> {
        todo!("being written")
    }
}

impl ProxyMetric for EllipsoidMetric {
    type Proxy = Ellipsoid;

    fn fit(&self, _faces: &[u32], _previous: Option<&Ellipsoid>) -> (Ellipsoid, f64) {
        todo!("being written")
    }

    fn face_error(&self, _face: u32, _proxy: &Ellipsoid) -> f64 {
        todo!("being written")
    }
}
