//! Mean curvature per vertex. (Being written.)
