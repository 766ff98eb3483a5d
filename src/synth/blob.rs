//! Smooth unions of known ellipsoids, meshed by iso-surface extraction. (Being written.)
