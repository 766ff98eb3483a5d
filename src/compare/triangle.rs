//! The exact closest point of a triangle to a point, for every triangle including degenerate
//! ones (a segment or a point).

use glam::DVec3;

/// The point of triangle `[a, b, c]` closest to `p`.
///
/// Classifies `p` into the triangle's Voronoi regions (vertex, edge, face) as in C. Ericson,
/// *Real-Time Collision Detection* (2005), section 5.1.5. A degenerate triangle (collinear or
/// coincident corners, where the face region is empty) is treated as the union of its three
/// edges, so the answer is always a point of the triangle's closed point set.
pub fn closest_point_on_triangle(p: DVec3, [a, b, c]: [DVec3; 3]) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let normal = ab.cross(ac);
    if normal.length_squared() <= 0.0 || !normal.is_finite() {
        return closest_point_on_edges(p, [a, b, c]);
    }
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return closest_point_on_segment(p, a, b);
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return closest_point_on_segment(p, a, c);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return closest_point_on_segment(p, b, c);
    }
    let sum = va + vb + vc;
    let v = vb / sum;
    let w = vc / sum;
    let q = a + ab * v + ac * w;
    // A nearly degenerate triangle can make the barycentric weights meaningless.
    if sum > 0.0 && q.is_finite() && v >= 0.0 && w >= 0.0 && v + w <= 1.0 + 1e-12 {
        q
    } else {
        closest_point_on_edges(p, [a, b, c])
    }
}

/// The point of segment `ab` closest to `p`; `a` when the segment is a point.
pub fn closest_point_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= 0.0 || !len2.is_finite() {
        return a;
    }
    let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
    a + ab * t
}

/// Distance from `p` to the segment `ab` (to `a` when the segment is a point).
pub fn distance_to_segment(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    closest_point_on_segment(p, a, b).distance(p)
}

/// The closest point of the three edges; ties go to the first edge (ab, bc, ca).
fn closest_point_on_edges(p: DVec3, [a, b, c]: [DVec3; 3]) -> DVec3 {
    let mut best = closest_point_on_segment(p, a, b);
    let mut best_d2 = best.distance_squared(p);
    for (s, t) in [(b, c), (c, a)] {
        let q = closest_point_on_segment(p, s, t);
        let d2 = q.distance_squared(p);
        if d2 < best_d2 {
            best = q;
            best_d2 = d2;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    const TRI: [DVec3; 3] = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(0.0, 2.0, 0.0),
    ];

    fn close(a: DVec3, b: DVec3) -> bool {
        a.distance(b) < 1e-12
    }

    /// The closest of a dense barycentric grid of the triangle: a reference that knows
    /// nothing about Voronoi regions (its error is at most the grid spacing).
    fn closest_by_grid(p: DVec3, [a, b, c]: [DVec3; 3]) -> f64 {
        let n = 400;
        let mut best = f64::INFINITY;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let q = a + (b - a) * u + (c - a) * v;
                best = best.min(q.distance(p));
            }
        }
        best
    }

    #[test]
    fn face_region_projects_onto_the_plane() {
        let p = DVec3::new(0.5, 0.5, 3.0);
        assert!(close(
            closest_point_on_triangle(p, TRI),
            DVec3::new(0.5, 0.5, 0.0)
        ));
        let below = DVec3::new(0.25, 1.0, -2.0);
        assert!(close(
            closest_point_on_triangle(below, TRI),
            DVec3::new(0.25, 1.0, 0.0)
        ));
    }

    #[test]
    fn vertex_regions_give_the_corners() {
        assert!(close(
            closest_point_on_triangle(DVec3::new(-1.0, -1.0, 0.5), TRI),
            TRI[0]
        ));
        assert!(close(
            closest_point_on_triangle(DVec3::new(3.0, -0.5, -1.0), TRI),
            TRI[1]
        ));
        assert!(close(
            closest_point_on_triangle(DVec3::new(-0.5, 3.0, 2.0), TRI),
            TRI[2]
        ));
    }

    #[test]
    fn edge_regions_give_the_edge_points() {
        // Below edge ab (y < 0).
        assert!(close(
            closest_point_on_triangle(DVec3::new(1.0, -1.0, 1.0), TRI),
            DVec3::new(1.0, 0.0, 0.0)
        ));
        // Left of edge ac (x < 0).
        assert!(close(
            closest_point_on_triangle(DVec3::new(-2.0, 0.5, 0.0), TRI),
            DVec3::new(0.0, 0.5, 0.0)
        ));
        // Beyond the hypotenuse bc: (2,1) projects onto x + y = 2 at (1.5, 0.5).
        assert!(close(
            closest_point_on_triangle(DVec3::new(2.0, 1.0, -0.25), TRI),
            DVec3::new(1.5, 0.5, 0.0)
        ));
    }

    #[test]
    fn degenerate_triangles_are_their_edges() {
        // Collinear, c between a and b.
        let line = [
            DVec3::ZERO,
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
        ];
        let q = closest_point_on_triangle(DVec3::new(3.0, 2.0, 0.0), line);
        assert!(close(q, DVec3::new(3.0, 0.0, 0.0)), "{q}");
        let q = closest_point_on_triangle(DVec3::new(-1.0, 1.0, 0.0), line);
        assert!(close(q, DVec3::ZERO), "{q}");
        // Two coincident corners: a segment.
        let seg = [DVec3::ZERO, DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0)];
        let q = closest_point_on_triangle(DVec3::new(1.0, 0.0, 1.5), seg);
        assert!(close(q, DVec3::new(0.0, 0.0, 1.5)), "{q}");
        // All three coincident: a point.
        let point = [DVec3::ONE; 3];
        assert!(close(
            closest_point_on_triangle(DVec3::ZERO, point),
            DVec3::ONE
        ));
        // Nearly collinear (area ~1e-18): still on the triangle and as close as the grid.
        let sliver = [
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5, 1e-18, 0.0),
        ];
        let p = DVec3::new(0.3, 0.7, 0.2);
        let q = closest_point_on_triangle(p, sliver);
        assert!((q.distance(p) - closest_by_grid(p, sliver)).abs() < 1e-9);
        assert!(q.is_finite() && q.y.abs() < 1e-12 && (0.0..=1.0).contains(&q.x));
    }

    #[test]
    fn matches_a_dense_grid_on_random_triangles() {
        let mut rng = SplitMix64::new(11);
        for _ in 0..60 {
            let tri = [
                rng.unit_vector(),
                rng.unit_vector(),
                rng.unit_vector() * 0.5,
            ];
            let p = rng.unit_vector() * rng.range_f64(0.0, 2.0);
            let q = closest_point_on_triangle(p, tri);
            let reference = closest_by_grid(p, tri);
            // The grid overestimates by at most its spacing (longest edge / 400 < 0.005).
            let d = q.distance(p);
            assert!(d <= reference + 1e-12, "{d} > grid {reference}");
            assert!(d >= reference - 0.005, "{d} far below grid {reference}");
            // And q lies in the triangle's plane, inside it (barycentric weights >= 0).
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            assert!((q - tri[0]).dot(n).abs() < 1e-9 * n.length());
        }
    }

    #[test]
    fn segment_of_zero_length_is_its_point() {
        let a = DVec3::new(1.0, 2.0, 3.0);
        assert_eq!(closest_point_on_segment(DVec3::ZERO, a, a), a);
    }
}
