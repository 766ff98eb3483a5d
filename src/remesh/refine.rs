//! Boundary arcs refined on the intersection curve of the two ellipsoids they separate
//! (Simari & Singh 2005, section 4.1: relaxed boundaries lie on these intersections).
