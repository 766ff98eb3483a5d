//! Meshes of simple shapes with analytic properties. (Being written.)
