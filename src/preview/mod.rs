//! Preview: pictures of meshes and their regions.

pub mod palette;
