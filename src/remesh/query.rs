//! The analytic ray query on a whole representation: the first region surface a ray meets.
