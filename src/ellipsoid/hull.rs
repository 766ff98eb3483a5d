//! Convex hull of a point set in 3D, for the volume metric's V(R) (Simari & Singh 2005,
//! section 4: "for our volume approximation V of each mesh segment we use the volume of the
//! convex hull").
//!
//! Quickhull (Barber, Dobkin & Huhdanpaa 1996): start from a tetrahedron of extreme points,
//! give every remaining point to a face it lies above, then repeatedly take a face's farthest
//! point, remove every face that point sees, and cone the horizon to it. A point closer than
//! a tolerance (10⁻¹² of the extent) to a plane counts as on it, which keeps the hull
//! consistent on coplanar and co-spherical input. Written here rather than taken from a crate:
//! the crates at hand either use f32 / another glam version or bring large dependency trees,
//! and the volume only needs this one routine.
//!
//! Deterministic: the same points in the same order give the same hull.

use glam::DVec3;
use std::collections::HashMap;

/// A convex hull: triangles over the input points' indices, oriented outward.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvexHull {
    /// Outward-oriented triangles, indexing the input points.
    pub faces: Vec<[u32; 3]>,
    /// Enclosed volume.
    pub volume: f64,
}

/// Volume of the convex hull of `points`; 0 when they are fewer than four, flat, or
/// non-finite.
pub fn convex_hull_volume(points: &[DVec3]) -> f64 {
    compute_convex_hull(points).map_or(0.0, |h| h.volume)
}

struct Face {
    v: [u32; 3],
    normal: DVec3,
    offset: f64,
    outside: Vec<u32>,
    alive: bool,
}

/// The convex hull of `points`; `None` when it has no volume (fewer than four points, all
/// coplanar, any non-finite coordinate, more than 2³² points) or, defensively, if rounding
/// ever left the face structure inconsistent.
pub fn compute_convex_hull(points: &[DVec3]) -> Option<ConvexHull> {
    if points.len() < 4 || u32::try_from(points.len()).is_err() {
        return None;
    }
    if points.iter().any(|p| !p.is_finite()) {
        return None;
    }
    let (lo, hi) = points.iter().fold((points[0], points[0]), |(lo, hi), &p| {
        (lo.min(p), hi.max(p))
    });
    let origin = 0.5 * (lo + hi);
    let pts: Vec<DVec3> = points.iter().map(|&p| p - origin).collect();
    let extent = (hi - lo).length();
    let eps = 1e-12 * extent.max(f64::MIN_POSITIVE);
    let at = |i: u32| pts[i as usize];

    let [i0, i1, i2, i3] = find_simplex(&pts, eps)?;
    let interior = (at(i0) + at(i1) + at(i2) + at(i3)) / 4.0;
    let mut faces: Vec<Face> = Vec::new();
    let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
    for tri in [[i0, i1, i2], [i0, i1, i3], [i0, i2, i3], [i1, i2, i3]] {
        let mut f = make_face(&pts, tri);
        if f.normal.dot(interior) - f.offset > 0.0 {
            f = make_face(&pts, [tri[0], tri[2], tri[1]]);
        }
        add_face(&mut faces, &mut edges, f)?;
    }
    for i in 0..pts.len() as u32 {
        if [i0, i1, i2, i3].contains(&i) {
            continue;
        }
        let p = at(i);
        if let Some(f) = faces.iter_mut().find(|f| f.normal.dot(p) - f.offset > eps) {
            f.outside.push(i);
        }
    }

    let mut stack: Vec<usize> = (0..faces.len()).collect();
    let mut stamp = vec![0u32; faces.len()];
    let mut round = 0u32;
    let mut queue = Vec::new();
    let mut visible = Vec::new();
    let mut horizon = Vec::new();
    let mut orphans = Vec::new();
    while let Some(fi) = stack.pop() {
        let face = &faces[fi];
        if !face.alive || face.outside.is_empty() {
            continue;
        }
        let eye = *face.outside.iter().max_by(|&&a, &&b| {
            let da = face.normal.dot(at(a));
            let db = face.normal.dot(at(b));
            da.total_cmp(&db).then(b.cmp(&a))
        })?;
        let e = at(eye);
        // Faces the eye sees, by search across edges from this one; the horizon is the set
        // of edges between a visible face and a hidden one.
        round = round.wrapping_add(1);
        stamp.resize(faces.len(), 0);
        queue.clear();
        visible.clear();
        horizon.clear();
        queue.push(fi);
        stamp[fi] = round;
        while let Some(g) = queue.pop() {
            visible.push(g);
            let v = faces[g].v;
            for k in 0..3 {
                let (a, b) = (v[k], v[(k + 1) % 3]);
                let &n = edges.get(&(b, a))?;
                if stamp[n] == round {
                    continue;
                }
                let nf = &faces[n];
                if nf.normal.dot(e) - nf.offset > eps {
                    stamp[n] = round;
                    queue.push(n);
                } else {
                    horizon.push((a, b));
                }
            }
        }
        orphans.clear();
        for &g in &visible {
            let f = &mut faces[g];
            f.alive = false;
            orphans.extend(f.outside.drain(..).filter(|&i| i != eye));
            let v = f.v;
            for k in 0..3 {
                edges.remove(&(v[k], v[(k + 1) % 3]));
            }
        }
        let first_new = faces.len();
        for &(a, b) in &horizon {
            let f = make_face(&pts, [a, b, eye]);
            add_face(&mut faces, &mut edges, f)?;
        }
        for &i in &orphans {
            let p = at(i);
            if let Some(f) = faces[first_new..]
                .iter_mut()
                .find(|f| f.normal.dot(p) - f.offset > eps)
            {
                f.outside.push(i);
            }
        }
        stack.extend(first_new..faces.len());
    }

    let hull_faces: Vec<[u32; 3]> = faces.iter().filter(|f| f.alive).map(|f| f.v).collect();
    let volume: f64 = hull_faces
        .iter()
        .map(|&[a, b, c]| {
            let (pa, pb, pc) = (at(a) - interior, at(b) - interior, at(c) - interior);
            pa.dot(pb.cross(pc))
        })
        .sum::<f64>()
        / 6.0;
    (volume.is_finite() && volume > 0.0).then_some(ConvexHull {
        faces: hull_faces,
        volume,
    })
}

/// Four affinely independent extreme points, or `None` when the set is flat.
fn find_simplex(pts: &[DVec3], eps: f64) -> Option<[u32; 4]> {
    let n = pts.len() as u32;
    let at = |i: u32| pts[i as usize];
    // Extremes along each axis.
    let mut extremes = [0u32; 6];
    for i in 0..n {
        let p = at(i);
        for axis in 0..3 {
            if p[axis] < at(extremes[2 * axis])[axis] {
                extremes[2 * axis] = i;
            }
            if p[axis] > at(extremes[2 * axis + 1])[axis] {
                extremes[2 * axis + 1] = i;
            }
        }
    }
    let (mut i0, mut i1, mut best) = (0, 0, -1.0);
    for &a in &extremes {
        for &b in &extremes {
            let d = (at(a) - at(b)).length_squared();
            if d > best {
                (i0, i1, best) = (a, b, d);
            }
        }
    }
    if best.sqrt() <= eps {
        return None;
    }
    let dir = (at(i1) - at(i0)).normalize();
    let farthest = |score: &dyn Fn(DVec3) -> f64| -> (u32, f64) {
        (0..n).fold((0, -1.0), |(bi, bs), i| {
            let s = score(at(i));
            if s > bs {
                (i, s)
            } else {
                (bi, bs)
            }
        })
    };
    let (i2, d2) = farthest(&|p| (p - at(i0)).cross(dir).length());
    if d2 <= eps {
        return None;
    }
    let normal = (at(i1) - at(i0)).cross(at(i2) - at(i0)).normalize();
    let (i3, d3) = farthest(&|p| normal.dot(p - at(i0)).abs());
    if d3 <= eps {
        return None;
    }
    Some([i0, i1, i2, i3])
}

fn make_face(pts: &[DVec3], v: [u32; 3]) -> Face {
    let [a, b, c] = v.map(|i| pts[i as usize]);
    let normal = (b - a).cross(c - a).normalize_or_zero();
    Face {
        v,
        normal,
        offset: normal.dot(a),
        outside: Vec::new(),
        alive: true,
    }
}

/// Append a face and register its directed edges; `None` if an edge is already taken, which
/// would mean an inconsistent hull.
fn add_face(faces: &mut Vec<Face>, edges: &mut HashMap<(u32, u32), usize>, f: Face) -> Option<()> {
    let index = faces.len();
    let v = f.v;
    for k in 0..3 {
        if edges.insert((v[k], v[(k + 1) % 3]), index).is_some() {
            return None;
        }
    }
    faces.push(f);
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    fn check_hull(points: &[DVec3], hull: &ConvexHull) {
        // Closed 2-manifold: every directed edge has its twin, and Euler's formula holds.
        let mut edges = std::collections::HashSet::new();
        let mut vertices = std::collections::HashSet::new();
        for f in &hull.faces {
            for k in 0..3 {
                assert!(edges.insert((f[k], f[(k + 1) % 3])));
                vertices.insert(f[k]);
            }
        }
        for &(a, b) in &edges {
            assert!(edges.contains(&(b, a)));
        }
        let (v, e, f) = (vertices.len(), edges.len() / 2, hull.faces.len());
        assert_eq!(v as i64 - e as i64 + f as i64, 2);
        // Every point is inside every face's plane (up to rounding).
        for t in &hull.faces {
            let [a, b, c] = t.map(|i| points[i as usize]);
            let n = (b - a).cross(c - a);
            if n.length() < 1e-12 {
                continue;
            }
            let n = n.normalize();
            for p in points {
                assert!(n.dot(*p - a) < 1e-9, "{}", n.dot(*p - a));
            }
        }
    }

    #[test]
    fn cube_with_points_on_faces_edges_and_inside() {
        // Heavily coplanar input: a 6×6×6 grid over the unit cube.
        let mut points = Vec::new();
        for i in 0..6 {
            for j in 0..6 {
                for k in 0..6 {
                    points.push(DVec3::new(i as f64, j as f64, k as f64) / 5.0 + 3.0);
                }
            }
        }
        let hull = compute_convex_hull(&points).unwrap();
        assert!((hull.volume - 1.0).abs() < 1e-12, "{}", hull.volume);
        check_hull(&points, &hull);
    }

    #[test]
    fn random_points_in_a_ball_and_on_a_sphere() {
        let mut rng = SplitMix64::new(11);
        let mut on_sphere = Vec::new();
        for _ in 0..3000 {
            let v = DVec3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
            on_sphere.push(v * 2.0 + DVec3::new(100.0, -50.0, 7.0));
        }
        let hull = compute_convex_hull(&on_sphere).unwrap();
        check_hull(&on_sphere, &hull);
        // Every point is a hull vertex; the volume is a little under the ball's.
        let ball = 4.0 / 3.0 * std::f64::consts::PI * 8.0;
        assert!(
            hull.volume < ball && hull.volume > 0.99 * ball,
            "{}",
            hull.volume
        );
        let mut mixed = on_sphere.clone();
        for _ in 0..2000 {
            let v = DVec3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
            mixed.push(v * rng.range_f64(0.0, 1.99) + DVec3::new(100.0, -50.0, 7.0));
        }
        let h2 = compute_convex_hull(&mixed).unwrap();
        assert!((h2.volume - hull.volume).abs() < 1e-9 * hull.volume);
    }

    #[test]
    fn tetrahedron_and_octahedron_exact() {
        let tet = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        assert!((convex_hull_volume(&tet) - 1.0 / 6.0).abs() < 1e-15);
        let oct = [
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
            DVec3::ZERO,
        ];
        let h = compute_convex_hull(&oct).unwrap();
        assert!((h.volume - 4.0 / 3.0).abs() < 1e-14);
        assert_eq!(h.faces.len(), 8);
    }

    #[test]
    fn degenerate_sets_have_no_volume() {
        assert_eq!(convex_hull_volume(&[]), 0.0);
        assert_eq!(convex_hull_volume(&[DVec3::X; 10]), 0.0);
        let line: Vec<DVec3> = (0..10).map(|i| DVec3::splat(i as f64)).collect();
        assert_eq!(convex_hull_volume(&line), 0.0);
        let plane: Vec<DVec3> = (0..30)
            .map(|i| DVec3::new((i % 7) as f64, (i / 7) as f64 * 1.5, 2.0))
            .collect();
        assert_eq!(convex_hull_volume(&plane), 0.0);
        let bad = [
            DVec3::ZERO,
            DVec3::X,
            DVec3::Y,
            DVec3::new(0.0, 0.0, f64::NAN),
        ];
        assert_eq!(convex_hull_volume(&bad), 0.0);
    }
}
