//! Boundary arcs refined on the intersection curve of the two ellipsoids they separate
//! (Simari & Singh 2005, section 4.1: relaxed boundaries lie on these intersections).
//!
//! A stored arc may be coarse (simplified by [`Representation::simplify_arcs`]) while the
//! regions on either side are meshed finely. Each arc is refined once, into a polyline both
//! regions use, so that the assembled mesh stays watertight (issue 6, item 5):
//!
//! - a segment is split when it is longer than the target spacing `h` (the edge length the
//!   vertex budget gives the interiors, so boundary and interior densities match), or when
//!   the curve strays from its chord by more than the tolerance;
//! - the new point is the foot on the curve {f₁ = 0, f₂ = 0} of the two ellipsoids'
//!   implicit functions (Newton's method for underdetermined systems,
//!   x ← x − Jᵀ(JJᵀ)⁻¹f, from the chord midpoint; fitted ellipsoids need not meet there,
//!   and then the midpoint of the two radial projections stands in) plus the mean of the
//!   segment ends' offsets from the curve, kept only if it lies within half a chord of the
//!   midpoint and in the middle three fifths along the chord; otherwise the midpoint;
//! - an arc on the mesh border (one region) gets radial projections onto its one ellipsoid;
//! - stored points (junctions included) are never moved.
//!
//! The work is bounded whatever the file: each stored segment is split at most
//! [`MAX_DEPTH`] times deep, and at most `max_new_points` points are added in all (the
//! spacing is widened first so that the spacing rule alone stays within that cap).

use crate::ellipsoid::Ellipsoid;
use crate::representation::Representation;
use glam::DVec3;

/// Deepest bisection of one stored segment (at most 2^MAX_DEPTH − 1 new points in it).
pub const MAX_DEPTH: u32 = 12;

/// Newton iterations of [`project_to_intersection`].
const NEWTON_ITERATIONS: usize = 12;

/// |f| (dimensionless: |u|² − 1) below which a Newton iterate is on both surfaces.
const NEWTON_RESIDUAL: f64 = 1e-10;

/// How the arcs are refined.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineSettings {
    /// Target spacing h between consecutive boundary points, in model units.
    pub spacing: f64,
    /// Largest distance (model units) allowed between a segment's midpoint and the curve
    /// before it is split; segments shorter than a quarter of the spacing are not split for
    /// it.
    pub tolerance: f64,
    /// Most points added over all arcs.
    pub max_new_points: usize,
    /// Which points both neighbouring charts see as convex are dropped
    /// ([`prune_double_ears`]).
    pub prune: Prune,
}

/// Which double ears ([`prune_double_ears`]) are dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Prune {
    /// None.
    Off,
    /// Those whose neighbours' chord spans at most [`MAX_PRUNED_ANGLE`] on both ellipsoids.
    Narrow,
    /// All of them.
    All,
}

/// The widest angle (radians, between the two neighbours' closest points seen from the
/// centre of either ellipsoid's unit sphere) across which [`Prune::Narrow`] drops a point.
///
/// A chord that wide cuts through the ellipsoid instead of following it: on hand K = 18 at
/// 12 500 vertices a pruned chord 0.2 long crossed a finger of radius 0.1, the face on it
/// turned over, and the face was too close to the chord to be split (one flipped triangle in
/// the first two meshing attempts). Measured on 37 stored files (the shared meshes at K = 12
/// and 24, five CGAL meshes, the paper's four) decoded at 1 000 to 31 250 vertices without
/// subdivision: the first meshing attempt was clean in 106 of 185 decodes pruning every
/// ear, in 122 with a limit of 0.5 and in 131 with 1.0, which also keeps fewer of the ears
/// a clean mesh needs dropped.
pub const MAX_PRUNED_ANGLE: f64 = 1.0;

/// The refined arcs: one pool of points shared by every arc.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RefinedBoundary {
    /// The representation's points (unchanged, same indices) followed by the new ones.
    pub points: Vec<DVec3>,
    /// For each arc of the representation, its refined chain as indices into `points`,
    /// with the arc's conventions (a closed arc does not repeat its first point).
    pub arcs: Vec<Vec<u32>>,
    /// How many points were added.
    pub added: usize,
    /// How many double ears were dropped across a chord wider than [`MAX_PRUNED_ANGLE`]
    /// ([`Prune::All`]; with [`Prune::Narrow`] they are kept and not counted): none, and
    /// the arcs are those [`Prune::Narrow`] gives.
    pub wide_ears: usize,
}

/// Refines every arc of `rep` (see the module documentation). Deterministic.
pub fn refine_arcs(rep: &Representation, settings: &RefineSettings) -> RefinedBoundary {
    let mut points = rep.points.clone();
    let mut arcs = Vec::with_capacity(rep.arcs.len());
    let spacing = widened_spacing(rep, settings);
    let mut budget = settings.max_new_points;
    let mut wide_ears = 0;
    for arc in &rep.arcs {
        let left = rep.ellipsoids.get(arc.left as usize);
        let right = arc
            .right
            .region()
            .and_then(|r| rep.ellipsoids.get(r as usize));
        let Some(left) = left else {
            arcs.push(arc.points.clone());
            continue;
        };
        let curve = Curve {
            first: left,
            second: right,
        };
        let mut chain = Vec::with_capacity(arc.points.len());
        let n = arc.points.len();
        let segments = if arc.closed { n } else { n.saturating_sub(1) };
        for k in 0..n {
            let i = arc.points[k];
            chain.push(i);
            if k >= segments {
                continue;
            }
            let j = arc.points[(k + 1) % n];
            let (Some(&a), Some(&b)) = (rep.points.get(i as usize), rep.points.get(j as usize))
            else {
                continue;
            };
            let mut split = Split {
                curve: &curve,
                spacing,
                tolerance: settings.tolerance,
                budget: &mut budget,
                points: &mut points,
                chain: &mut chain,
            };
            split.segment(a, b, 0);
        }
        if let Some(right) = right {
            wide_ears += prune_double_ears(
                &mut chain,
                &points,
                arc.closed,
                [left, right],
                settings.prune,
            );
        }
        arcs.push(chain);
    }
    let added = points.len() - rep.points.len();
    RefinedBoundary {
        points,
        arcs,
        added,
        wide_ears,
    }
}

/// Whether the corner `a → b → c` turns towards the region on its left, as that region's
/// chart sees it: the orientation of the three points' closest points on `e` (the map the
/// decoder's charts use by default; the stereographic projection preserves orientation),
/// seen with the mesh's outward normal up.
fn turns_left(e: &Ellipsoid, [p, q, r]: [DVec3; 3]) -> bool {
    e.sign.factor() * (q - p).cross(r - q).dot(e.outward_normal(q)) > 0.0
}

/// Removes the chain points at which both regions see a convex corner (with
/// [`Prune::Narrow`], only where the chord that replaces them spans at most
/// [`MAX_PRUNED_ANGLE`] on both ellipsoids); returns how many of the removed points were
/// across a wider chord.
///
/// Boundary points need not lie on either ellipsoid, and each region's chart maps them to
/// their closest points on its own: at a nearly straight point the two charts can disagree on
/// which side the corner bends to. When both see it bending away from them, the thin
/// triangle (previous, point, next) would be inside both regions and the glued mesh would
/// not be manifold. Dropping the point (from the one chain both regions use) removes the
/// conflict; it is nearly on the chord of its neighbours. Junctions stay.
pub fn prune_double_ears(
    chain: &mut Vec<u32>,
    points: &[DVec3],
    closed: bool,
    [left, right]: [&Ellipsoid; 2],
    prune: Prune,
) -> usize {
    if prune == Prune::Off {
        return 0;
    }
    // Each chain point's closest points on both ellipsoids, found once (the scan asks for
    // each in up to three corners, and again after a removal).
    let feet: Vec<[DVec3; 2]> = chain
        .iter()
        .map(|&i| {
            let p = points.get(i as usize).copied().unwrap_or_default();
            [left.closest_point(p), right.closest_point(p)]
        })
        .collect();
    let wide = |a: usize, c: usize| {
        [left, right].iter().enumerate().any(|(side, e)| {
            let on_sphere = |k: usize| e.to_unit_sphere(feet[k][side]);
            let angle = on_sphere(a).angle_between(on_sphere(c));
            angle.is_nan() || angle > MAX_PRUNED_ANGLE
        })
    };
    let mut wide_ears = 0;
    // The corner at chain position b, between positions a and c.
    let mut conflict = |a: usize, b: usize, c: usize| {
        let on = |side: usize| [a, b, c].map(|k| feet[k][side]);
        let [l, r] = [on(0), on(1)];
        if !(turns_left(left, l) && turns_left(right, [r[2], r[1], r[0]])) {
            return false;
        }
        if !wide(a, c) {
            return true;
        }
        wide_ears += usize::from(prune == Prune::All);
        prune == Prune::All
    };
    // One scan with backtracking: after a removal the previous point is checked again.
    // Chain positions.
    let mut kept: Vec<usize> = Vec::with_capacity(chain.len());
    for next in 0..chain.len() {
        while kept.len() >= 2 {
            let (a, b) = (kept[kept.len() - 2], kept[kept.len() - 1]);
            if conflict(a, b, next) {
                kept.pop();
            } else {
                break;
            }
        }
        kept.push(next);
    }
    if closed {
        // The corners across the seam (first point kept as the loop's anchor).
        let mut guard = kept.len();
        while kept.len() > 3 && guard > 0 {
            guard -= 1;
            let n = kept.len();
            if conflict(kept[n - 2], kept[n - 1], kept[0]) {
                kept.pop();
            } else if conflict(kept[n - 1], kept[0], kept[1]) && n > 3 {
                kept.remove(0);
            } else {
                break;
            }
        }
    }
    let min_len = if closed { 3 } else { 2 };
    if kept.len() >= min_len {
        *chain = kept.into_iter().map(|k| chain[k]).collect();
    }
    wide_ears
}

/// The spacing, widened so that splitting every segment to it adds at most
/// `max_new_points` points.
fn widened_spacing(rep: &Representation, settings: &RefineSettings) -> f64 {
    let mut needed = 0.0;
    for arc in &rep.arcs {
        let n = arc.points.len();
        let segments = if arc.closed { n } else { n.saturating_sub(1) };
        for k in 0..segments {
            let a = arc.points.get(k).and_then(|&i| rep.points.get(i as usize));
            let b = arc
                .points
                .get((k + 1) % n)
                .and_then(|&i| rep.points.get(i as usize));
            if let (Some(a), Some(b)) = (a, b) {
                needed += ((*a - *b).length() / settings.spacing).floor();
            }
        }
    }
    let cap = settings.max_new_points as f64;
    if needed.is_finite() && needed <= cap {
        settings.spacing
    } else if needed.is_finite() && cap > 0.0 {
        settings.spacing * (needed / cap) * 1.001
    } else {
        f64::INFINITY
    }
}

/// The curve an arc lies on: the intersection of two ellipsoids, or one ellipsoid.
struct Curve<'a> {
    first: &'a Ellipsoid,
    second: Option<&'a Ellipsoid>,
}

impl Curve<'_> {
    /// The curve's point for `p`: its Newton projection onto the intersection of the two
    /// ellipsoids when that converges within `reach` of `p`, else the midpoint of its radial
    /// projections onto both (the fits need not meet there); on the border, its radial
    /// projection onto the one ellipsoid.
    fn foot(&self, p: DVec3, reach: f64) -> DVec3 {
        match self.second {
            Some(second) => project_to_intersection(self.first, second, p)
                .filter(|f| (*f - p).length() <= reach)
                .unwrap_or_else(|| {
                    0.5 * (self.first.project_radially(p) + second.project_radially(p))
                }),
            None => self.first.project_radially(p),
        }
    }

    /// A point of the curve near the chord `a`–`b`'s midpoint (see the module doc), carried
    /// by the mean of the ends' offsets from the curve, and between the ends along the
    /// chord: within half the chord's length of its midpoint, and in its middle three fifths
    /// once projected on it; else, or when an end lies farther than that from the curve, the
    /// chord's midpoint.
    ///
    /// Stored points lie off the curve wherever the fitted ellipsoids miss the boundary;
    /// points put on the curve between them would make the arc zigzag in and out by that
    /// offset, and the surfaces blended to it ([`super::surface`]) ripple with it. Carried by
    /// the ends' offsets, the new points follow the stored polyline's distance from the
    /// curve and the curve's shape. A point beside one end would fold the polyline back on
    /// itself (a hairpin whose thin triangle both regions' charts can take for their own).
    fn point_between(&self, a: DVec3, b: DVec3) -> DVec3 {
        let mid = 0.5 * (a + b);
        let chord = (b - a).length();
        let reach = 0.5 * chord;
        // Ends farther from the curve than that say nothing of the arc's shape: midpoint.
        let offset = |p: DVec3| Some(p - self.foot(p, reach)).filter(|o| o.length() <= reach);
        let (Some(oa), Some(ob)) = (offset(a), offset(b)) else {
            return mid;
        };
        let m = self.foot(mid, reach) + 0.5 * (oa + ob);
        let along = (m - a).dot(b - a) / (chord * chord);
        if m.is_finite() && (m - mid).length() <= reach && (0.2..=0.8).contains(&along) {
            m
        } else {
            mid
        }
    }
}

/// Recursive bisection of one stored segment.
struct Split<'a, 'c> {
    curve: &'a Curve<'c>,
    spacing: f64,
    tolerance: f64,
    budget: &'a mut usize,
    points: &'a mut Vec<DVec3>,
    chain: &'a mut Vec<u32>,
}

impl Split<'_, '_> {
    /// Appends to the chain the points strictly between `a` and `b` (in order).
    fn segment(&mut self, a: DVec3, b: DVec3, depth: u32) {
        if depth >= MAX_DEPTH || *self.budget == 0 {
            return;
        }
        let length = (b - a).length();
        if !length.is_finite() || length <= 0.0 {
            return;
        }
        let too_long = length > self.spacing;
        if !too_long && length <= 0.25 * self.spacing {
            return;
        }
        let m = self.curve.point_between(a, b);
        let strays = (m - 0.5 * (a + b)).length() > self.tolerance;
        if !(too_long || strays) {
            return;
        }
        let Ok(index) = u32::try_from(self.points.len()) else {
            return;
        };
        *self.budget -= 1;
        self.points.push(m);
        self.segment(a, m, depth + 1);
        self.chain.push(index);
        self.segment(m, b, depth + 1);
    }
}

/// Newton projection of `p` onto the intersection curve of two ellipsoids' surfaces:
/// x ← x − Jᵀ(JJᵀ)⁻¹f with f = (|u₁|² − 1, |u₂|² − 1). `None` when the surfaces are
/// (nearly) tangent along the way or the iteration does not converge.
pub fn project_to_intersection(e1: &Ellipsoid, e2: &Ellipsoid, p: DVec3) -> Option<DVec3> {
    // f and ∇f of |u|² − 1 with u = R⁻¹(x − c)/r: ∇f = 2 R (u / r).
    let eval = |e: &Ellipsoid, x: DVec3| {
        let u = e.to_unit_sphere(x);
        (u.length_squared() - 1.0, 2.0 * (e.rotation * (u / e.radii)))
    };
    let mut x = p;
    for _ in 0..NEWTON_ITERATIONS {
        let (f1, g1) = eval(e1, x);
        let (f2, g2) = eval(e2, x);
        if f1.abs() < NEWTON_RESIDUAL && f2.abs() < NEWTON_RESIDUAL {
            return x.is_finite().then_some(x);
        }
        let (a, b, d) = (g1.dot(g1), g1.dot(g2), g2.dot(g2));
        let det = a * d - b * b;
        // Parallel gradients: the surfaces touch, the curve is not defined there.
        if !det.is_finite() || det <= 1e-10 * a * d {
            return None;
        }
        let l1 = (d * f1 - b * f2) / det;
        let l2 = (a * f2 - b * f1) / det;
        x -= l1 * g1 + l2 * g2;
        if !x.is_finite() {
            return None;
        }
    }
    let (f1, _) = eval(e1, x);
    let (f2, _) = eval(e2, x);
    (f1.abs() < NEWTON_RESIDUAL && f2.abs() < NEWTON_RESIDUAL).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::representation::{Arc, ArcRef, Cycle, Metadata, Side};

    /// Two unit spheres whose centres are 1 apart meet on a circle of radius √3/2 in the
    /// plane x = 0.5.
    fn two_spheres(points: Vec<DVec3>) -> Representation {
        let n = points.len() as u32;
        Representation {
            ellipsoids: vec![
                Ellipsoid::sphere(DVec3::ZERO, 1.0),
                Ellipsoid::sphere(DVec3::X, 1.0),
            ],
            points,
            arcs: vec![Arc {
                points: (0..n).collect(),
                closed: true,
                left: 0,
                right: Side::Region(1),
            }],
            cycles: vec![
                vec![Cycle {
                    arcs: vec![ArcRef {
                        arc: 0,
                        reversed: false,
                    }],
                    outer: true,
                }],
                vec![Cycle {
                    arcs: vec![ArcRef {
                        arc: 0,
                        reversed: true,
                    }],
                    outer: true,
                }],
            ],
            metadata: Metadata::default(),
        }
    }

    fn circle_point(t: f64) -> DVec3 {
        let r = 0.75f64.sqrt();
        DVec3::new(0.5, r * t.cos(), r * t.sin())
    }

    /// Stored points off the curve (here 0.05 outside it, away from its axis): the points
    /// refined between them keep about that offset instead of dropping onto the curve (an
    /// arc that zigzags in and out, and surfaces blended to it that ripple).
    #[test]
    fn refined_points_carry_their_ends_offsets() {
        let out = |p: DVec3| {
            let radial = DVec3::new(0.0, p.y, p.z).normalize();
            p + 0.05 * radial
        };
        let stored: Vec<DVec3> = (0..6)
            .map(|k| out(circle_point(std::f64::consts::TAU * k as f64 / 6.0)))
            .collect();
        let rep = two_spheres(stored);
        let settings = RefineSettings {
            spacing: 0.1,
            tolerance: 1e-3,
            max_new_points: 10_000,
            prune: Prune::Off,
        };
        let refined = refine_arcs(&rep, &settings);
        assert!(refined.added > 30);
        for p in &refined.points {
            let off_axis = DVec3::new(0.0, p.y, p.z).length();
            assert!((p.x - 0.5).abs() < 1e-9, "{p}");
            // The mean of two ends' offset vectors is shorter where their directions part:
            // by 0.05·(1 − cos 30°) ≈ 0.007 between stored points 60° apart, less deeper.
            let r = 0.75f64.sqrt();
            assert!(
                off_axis > r + 0.04 && off_axis < r + 0.05 + 1e-9,
                "{p}: {off_axis}"
            );
        }
    }

    /// Whatever the ends, a refined point lies within half the chord of its midpoint and in
    /// the chord's middle three fifths (no hairpin), or is the midpoint itself.
    #[test]
    fn refined_points_lie_between_their_ends() {
        let e1 = Ellipsoid::sphere(DVec3::ZERO, 1.0);
        let e2 = Ellipsoid::sphere(DVec3::X, 1.0);
        let curve = Curve {
            first: &e1,
            second: Some(&e2),
        };
        let mut rng = crate::rng::SplitMix64::new(7);
        let mut off_midpoint = 0;
        for _ in 0..2000 {
            let mut point = || {
                circle_point(rng.next_f64() * std::f64::consts::TAU)
                    + 0.3
                        * DVec3::new(
                            rng.next_f64() - 0.5,
                            rng.next_f64() - 0.5,
                            rng.next_f64() - 0.5,
                        )
            };
            let (a, b) = (point(), point());
            let m = curve.point_between(a, b);
            let mid = 0.5 * (a + b);
            if m == mid {
                continue;
            }
            off_midpoint += 1;
            let chord = (b - a).length();
            let along = (m - a).dot(b - a) / (chord * chord);
            assert!((m - mid).length() <= 0.5 * chord + 1e-12, "{a} {b} {m}");
            assert!((0.2..=0.8).contains(&along), "{a} {b} {m}: {along}");
        }
        assert!(off_midpoint > 1000, "{off_midpoint}");
        // Ends on the curve (no offsets): the new point is on the curve too, between them.
        for k in 0..100 {
            let t = k as f64 * 0.06;
            let (a, b) = (circle_point(t), circle_point(t + 0.5));
            let m = curve.point_between(a, b);
            assert!(
                e1.implicit(m).abs() < 1e-9 && e2.implicit(m).abs() < 1e-9,
                "{a} {b} {m}"
            );
            assert!((m - circle_point(t + 0.25)).length() < 1e-6, "{m}");
        }
    }

    #[test]
    fn newton_lands_on_both_surfaces() {
        let e1 = Ellipsoid::sphere(DVec3::ZERO, 1.0);
        let e2 = Ellipsoid::sphere(DVec3::X, 1.0);
        let p = project_to_intersection(&e1, &e2, DVec3::new(0.4, 0.5, 0.3)).unwrap();
        assert!(
            e1.implicit(p).abs() < 1e-9 && e2.implicit(p).abs() < 1e-9,
            "{p}"
        );
        // Concentric spheres never meet.
        let e3 = Ellipsoid::sphere(DVec3::ZERO, 2.0);
        assert_eq!(
            project_to_intersection(&e1, &e3, DVec3::new(1.5, 0.0, 0.0)),
            None
        );
    }

    #[test]
    fn a_coarse_loop_is_refined_on_the_intersection_circle() {
        let stored: Vec<DVec3> = (0..3)
            .map(|k| circle_point(std::f64::consts::TAU * k as f64 / 3.0))
            .collect();
        let rep = two_spheres(stored.clone());
        let settings = RefineSettings {
            spacing: 0.1,
            tolerance: 1e-3,
            max_new_points: 10_000,
            prune: Prune::All,
        };
        let refined = refine_arcs(&rep, &settings);
        assert_eq!(&refined.points[..3], &stored[..]);
        let chain = &refined.arcs[0];
        assert_eq!(chain.len(), 3 + refined.added);
        // Circumference 2π·0.866 ≈ 5.44: about 54 segments of at most 0.1.
        assert!((48..=100).contains(&chain.len()), "{}", chain.len());
        for w in 0..chain.len() {
            let a = refined.points[chain[w] as usize];
            let b = refined.points[chain[(w + 1) % chain.len()] as usize];
            assert!((a - b).length() <= 0.1 + 1e-12, "{w} {a} {b} {chain:?}");
            assert!(
                (a.x - 0.5).abs() < 1e-9 && (a.length() - 1.0).abs() < 1e-9,
                "{a}"
            );
        }
        // Deterministic.
        assert_eq!(refine_arcs(&rep, &settings), refined);
    }

    /// An arc along a circle of latitude (colatitude 1 rad) on the unit sphere, seen as the
    /// outer surface on its left and the inner surface on its right: both regions see every
    /// corner turn away from them, so every point inside it is a double ear.
    fn latitude_arc(span: f64, n: usize) -> Vec<DVec3> {
        (0..n)
            .map(|k| {
                let t = span * k as f64 / (n - 1) as f64;
                DVec3::new(1f64.sin() * t.cos(), 1f64.sin() * t.sin(), 1f64.cos())
            })
            .collect()
    }

    #[test]
    fn pruning_keeps_the_ears_whose_chord_would_be_wide() {
        let outer = Ellipsoid::sphere(DVec3::ZERO, 1.0);
        let inner = outer.flipped();
        let angle = |a: DVec3, b: DVec3| a.angle_between(b);
        // Spanning 3 rad of longitude: its ends are 2 rad apart on the sphere.
        let points = latitude_arc(3.0, 31);
        let every: Vec<u32> = (0..31).collect();
        let pruned = |prune| {
            let mut chain = every.clone();
            let wide = prune_double_ears(&mut chain, &points, false, [&outer, &inner], prune);
            (chain, wide)
        };
        assert_eq!(pruned(Prune::Off), (every.clone(), 0));
        // Every ear dropped: the chord from end to end crosses 2 rad of the sphere.
        let (all, wide) = pruned(Prune::All);
        assert_eq!(all, vec![0, 30]);
        assert!(wide > 0);
        // Narrow: points are dropped, but no chord left spans more than the limit.
        let (narrow, wide) = pruned(Prune::Narrow);
        assert_eq!(wide, 0);
        assert!((3..31).contains(&narrow.len()), "{narrow:?}");
        assert_eq!((narrow[0], narrow[narrow.len() - 1]), (0, 30));
        for w in narrow.windows(2) {
            let (a, b) = (points[w[0] as usize], points[w[1] as usize]);
            assert!(angle(a, b) <= MAX_PRUNED_ANGLE, "{w:?}: {}", angle(a, b));
        }
        // Where no chord is wide, pruning every ear is pruning the narrow ones.
        let short = latitude_arc(0.5, 11);
        let mut all: Vec<u32> = (0..11).collect();
        let mut narrow = all.clone();
        let pairs = [&outer, &inner];
        assert_eq!(
            prune_double_ears(&mut all, &short, false, pairs, Prune::All),
            0
        );
        assert_eq!(
            prune_double_ears(&mut narrow, &short, false, pairs, Prune::Narrow),
            0
        );
        assert_eq!(all, narrow);
        assert_eq!(all, vec![0, 10]);
    }

    #[test]
    fn the_cap_bounds_the_new_points() {
        let stored: Vec<DVec3> = (0..4)
            .map(|k| circle_point(std::f64::consts::TAU * k as f64 / 4.0))
            .collect();
        let rep = two_spheres(stored);
        for cap in [0, 1, 7, 100] {
            let settings = RefineSettings {
                spacing: 1e-9,
                tolerance: 0.0,
                max_new_points: cap,
                prune: Prune::All,
            };
            let refined = refine_arcs(&rep, &settings);
            assert!(refined.added <= cap, "{cap}: {}", refined.added);
        }
    }

    #[test]
    fn points_far_from_the_curve_keep_new_points_near_the_chord() {
        // The stored points lie nowhere near the spheres' intersection.
        let stored = vec![
            DVec3::new(50.0, 0.0, 0.0),
            DVec3::new(50.0, 3.0, 0.0),
            DVec3::new(50.0, 0.0, 3.0),
        ];
        let rep = two_spheres(stored.clone());
        let settings = RefineSettings {
            spacing: 0.5,
            tolerance: 1e-3,
            max_new_points: 1000,
            prune: Prune::All,
        };
        let refined = refine_arcs(&rep, &settings);
        for p in &refined.points {
            assert!((p.x - 50.0).abs() < 1e-9, "{p}");
        }
    }
}
