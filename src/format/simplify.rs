//! Arc simplification: Douglas–Peucker in 3D.
//!
//! D. H. Douglas and T. K. Peucker, *Algorithms for the reduction of the number of points
//! required to represent a digitized line or its caricature*, The Canadian Cartographer 10(2),
//! 1973. Simari & Singh (2005, section 7) name boundary simplification as future work; here it
//! is applied to every arc before quantisation, so the pool holds only the points needed to
//! keep each boundary within `tolerance` of its original polyline.

use crate::compare::distance_to_segment;
use glam::DVec3;

/// Suggested simplification tolerance as a fraction of the mesh's bounding-box diagonal:
/// 10⁻³. The default point grid ([`super::DEFAULT_BITS`]) adds at most 1.2·10⁻⁴ of the
/// diagonal of the points' box, so a boundary point ends within about 1.1·10⁻³ of the
/// diagonal of where it was (spec appendix B measures sizes for this pair).
pub const DEFAULT_RELATIVE_TOLERANCE: f64 = 1e-3;

/// Marks the points of `points[lo..=hi]` that Douglas–Peucker keeps, with `lo` and `hi`
/// already kept. Iterative, so long arcs cannot overflow the stack.
fn mark_between(points: &[DVec3], lo: usize, hi: usize, tolerance: f64, keep: &mut [bool]) {
    let mut stack = vec![(lo, hi)];
    while let Some((lo, hi)) = stack.pop() {
        if hi <= lo + 1 {
            continue;
        }
        let (Some(&a), Some(&b)) = (points.get(lo), points.get(hi % points.len().max(1))) else {
            continue;
        };
        let mut far = None;
        let mut far_d = tolerance;
        for i in lo + 1..hi {
            if let Some(&p) = points.get(i) {
                let d = distance_to_segment(p, a, b);
                // NaN distances must not drop points either.
                if d > far_d || d.is_nan() {
                    far_d = d;
                    far = Some(i);
                }
            }
        }
        if let Some(i) = far {
            if let Some(k) = keep.get_mut(i) {
                *k = true;
            }
            stack.push((lo, i));
            stack.push((i, hi));
        }
    }
}

/// Indices of the points of a polyline that Douglas–Peucker keeps at `tolerance`, in order.
///
/// `pinned[i]` forces point `i` to stay (junctions, shared points). An open polyline keeps
/// both ends. A closed one (no repeated end point) keeps its first point and the point farthest
/// from it, and at least three points in all.
pub fn simplify_polyline(
    points: &[DVec3],
    pinned: &[bool],
    closed: bool,
    tolerance: f64,
) -> Vec<usize> {
    let n = points.len();
    if n <= 2 || tolerance.is_nan() || tolerance < 0.0 {
        return (0..n).collect();
    }
    let mut keep: Vec<bool> = (0..n)
        .map(|i| pinned.get(i).copied().unwrap_or(false))
        .collect();
    if let Some(k) = keep.first_mut() {
        *k = true;
    }
    let p0 = points[0];
    if closed {
        let far = (1..n)
            .max_by(|&i, &j| {
                let di = (points[i] - p0).length_squared();
                let dj = (points[j] - p0).length_squared();
                di.total_cmp(&dj).then(j.cmp(&i))
            })
            .unwrap_or(1);
        keep[far] = true;
    } else {
        keep[n - 1] = true;
    }
    // Douglas–Peucker between consecutive kept points; a closed loop wraps to point 0, which
    // `mark_between` reads as index n (taken modulo n).
    let anchors: Vec<usize> = (0..n).filter(|&i| keep[i]).collect();
    let mut spans: Vec<(usize, usize)> = anchors.windows(2).map(|w| (w[0], w[1])).collect();
    if closed {
        if let Some(&last) = anchors.last() {
            spans.push((last, n));
        }
    }
    let extended: Vec<DVec3>;
    let pts: &[DVec3] = if closed {
        extended = points.iter().copied().chain([p0]).collect();
        &extended
    } else {
        points
    };
    let mut keep_ext = keep.clone();
    if closed {
        keep_ext.push(true);
    }
    for (lo, hi) in spans {
        mark_between(pts, lo, hi, tolerance, &mut keep_ext);
    }
    keep_ext.truncate(n);
    keep = keep_ext;
    if closed && keep.iter().filter(|&&k| k).count() < 3 {
        // Add the point farthest from the chord through the two kept points.
        let kept: Vec<usize> = (0..n).filter(|&i| keep[i]).collect();
        let (a, b) = (points[kept[0]], points[*kept.last().unwrap_or(&0)]);
        if let Some(i) = (0..n).filter(|&i| !keep[i]).max_by(|&i, &j| {
            distance_to_segment(points[i], a, b)
                .total_cmp(&distance_to_segment(points[j], a, b))
                .then(j.cmp(&i))
        }) {
            keep[i] = true;
        }
    }
    (0..n).filter(|&i| keep[i]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(n: usize, r: f64) -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                DVec3::new(r * t.cos(), r * t.sin(), 0.1 * (3.0 * t).sin())
            })
            .collect()
    }

    /// Largest distance from an original point to the simplified polyline.
    fn deviation(points: &[DVec3], keep: &[usize], closed: bool) -> f64 {
        let mut segs: Vec<(DVec3, DVec3)> = keep
            .windows(2)
            .map(|w| (points[w[0]], points[w[1]]))
            .collect();
        if closed {
            segs.push((points[*keep.last().unwrap()], points[keep[0]]));
        }
        points
            .iter()
            .map(|&p| {
                segs.iter()
                    .map(|&(a, b)| distance_to_segment(p, a, b))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn simplified_polylines_stay_within_tolerance() {
        let pts = circle(500, 1.0);
        for &tol in &[1e-4, 1e-3, 1e-2, 1e-1] {
            for closed in [false, true] {
                let keep = simplify_polyline(&pts, &[], closed, tol);
                assert!(deviation(&pts, &keep, closed) <= tol + 1e-12, "tol {tol}");
                assert!(keep.len() < pts.len());
                assert_eq!(keep[0], 0);
                if !closed {
                    assert_eq!(*keep.last().unwrap(), pts.len() - 1);
                }
                assert!(keep.windows(2).all(|w| w[0] < w[1]));
            }
        }
    }

    #[test]
    fn pinned_points_and_three_loop_points_are_kept() {
        let pts = circle(100, 1.0);
        let mut pinned = vec![false; 100];
        pinned[37] = true;
        let keep = simplify_polyline(&pts, &pinned, false, 10.0);
        assert_eq!(keep, vec![0, 37, 99]);
        let keep = simplify_polyline(&pts, &[], true, 10.0);
        assert_eq!(keep.len(), 3);
        // A straight open line keeps its ends only.
        let line: Vec<DVec3> = (0..10).map(|i| DVec3::X * i as f64).collect();
        assert_eq!(simplify_polyline(&line, &[], false, 1e-9), vec![0, 9]);
    }
}
