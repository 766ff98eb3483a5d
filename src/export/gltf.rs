//! GLTF writer. (Being written.)
