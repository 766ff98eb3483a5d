//! Synthetic meshes of known shape, for tests, fixtures and benchmarks.
//!
//! [`shapes`] builds meshes with analytic answers (spheres, ellipsoids, tori, cylinders,
//! capsules, bowls, cubes, grids); [`blob`] builds smooth unions of known ellipsoids by
//! iso-surface extraction; [`fixtures`] writes the committed files under `fixtures/meshes/`.

pub mod blob;
pub mod fixtures;
pub mod shapes;
