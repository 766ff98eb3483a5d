//! VSA's planar proxies with the L²,¹ metric (Cohen-Steiner, Alliez & Desbrun 2004).

use super::ProxyMetric;
use crate::mesh::Mesh;
use glam::DVec3;
use serde::Serialize;

/// A plane through `point` with unit `normal`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Plane {
    /// A point of the plane (the region's area centroid).
    pub point: DVec3,
    /// Unit normal.
    pub normal: DVec3,
}

/// The L²,¹ metric: a face's error is its area times the squared distance between its
/// normal and the proxy's.
#[derive(Debug, Clone)]
pub struct PlaneMetric {
    _private: (),
}

impl PlaneMetric {
    /// Prepares the metric for a mesh (face normals and areas).
    pub fn new(_mesh: &Mesh) -> Self {
        todo!("being written")
    }
}

impl ProxyMetric for PlaneMetric {
    type Proxy = Plane;

    fn fit(&self, _faces: &[u32], _previous: Option<&Plane>) -> (Plane, f64) {
        todo!("being written")
    }

    fn face_error(&self, _face: u32, _proxy: &Plane) -> f64 {
        todo!("being written")
    }
}
