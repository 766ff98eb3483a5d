//! One region's triangulation in its chart with spade's constrained Delaunay triangulation:
//! iterative vertex addition (section 5.3) and the parametric grid (section 5.2).
