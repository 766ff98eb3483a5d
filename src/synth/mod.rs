//! Synthetic meshes of known shape, for tests, fixtures and benchmarks.
//!
//! [`shapes`] builds meshes with analytic answers (spheres, ellipsoids, tori, cylinders,
//! capsules, bowls, cubes, grids); [`blob`] builds smooth unions of known ellipsoids by
//! iso-surface extraction; [`fixtures`] writes the committed files under `fixtures/meshes/`.

pub mod blob;
pub mod fixtures;
pub mod shapes;

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// An ellipsoid as the synthetic shapes and the fixtures' truth files describe it: the unit
/// sphere scaled by `radii` along x, y, z, then rotated by `rotation`, then moved to `center`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EllipsoidSpec {
    /// Centre.
    pub center: DVec3,
    /// Orientation (unit quaternion, stored x, y, z, w).
    pub rotation: DQuat,
    /// Semi-axis lengths, all positive.
    pub radii: DVec3,
}
