//! The generator of the committed fixture meshes. (Being written.)
