//! PLY writer. (Being written.)
