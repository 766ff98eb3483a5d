//! OBJ writer. (Being written.)
