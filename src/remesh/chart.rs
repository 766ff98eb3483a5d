//! A region's chart (Simari & Singh 2005, section 5.1): ellipsoid → unit sphere → rotation
//! that takes a pole far from the region to the north pole → stereographic projection to the
//! plane, and back; and the point-in-region test in that plane.
//!
//! Orientation conventions:
//! - boundary loops are given with the region on their left when seen with the **mesh's**
//!   outward normal up (spec §6.5). For a negative ellipsoid the mesh's outward normal is the
//!   ellipsoid's inward normal, so on the unit sphere (seen from outside) such a region lies
//!   on the loops' right; [`RegionChart::new`] reverses those loops.
//! - [`RegionChart::sphere_to_plane`] (projection from the north pole onto z = 0, plane seen
//!   from +z) reverses orientation: a loop with a region on its left on the sphere, seen from
//!   outside, has it on its right in the plane. The chart's stored plane loops
//!   ([`RegionChart::plane_loops`]) are reversed once more so that the region is on their
//!   left in the plane: the outer boundary counter-clockwise, holes clockwise.

use super::RemeshError;
use crate::ellipsoid::{Ellipsoid, Sign};
use glam::{DQuat, DVec2, DVec3};
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};
use std::sync::{Arc, Mutex};

/// Number of evenly spread (Fibonacci) directions tried as poles, besides the loops' own
/// centres and their antipodes.
const POLE_CANDIDATES: usize = 256;

/// Loops beyond this count add no candidate poles of their own (hostile inputs can have
/// many).
const MAX_LOOP_CANDIDATES: usize = 64;

/// Unit-sphere directions closer than this count as one point.
const SAME_DIRECTION: f64 = 1e-12;

/// A pole closer than this angle (radians) to the boundary is never chosen: the boundary
/// would project to coordinates too large to test against.
const MIN_CLEARANCE: f64 = 1e-6;

/// A map between one ellipsoid's surface and the plane, with the region's boundary projected
/// into it.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionChart {
    /// The region's ellipsoid.
    pub ellipsoid: Ellipsoid,
    /// Rotates unit-sphere points so that the chosen pole becomes the north pole (0, 0, 1).
    pub rotation: DQuat,
    /// The boundary loops in plane coordinates, region on the left (outer counter-clockwise,
    /// holes clockwise), consecutive duplicates removed, first point not repeated. Empty:
    /// the chart covers the whole ellipsoid.
    plane_loops: Vec<Vec<DVec2>>,
    /// Angular distance (radians, on the unit sphere) from the pole to the nearest boundary
    /// edge; π for the whole ellipsoid.
    clearance: f64,
    /// Edges of `plane_loops` bucketed by horizontal slab, for point-in-polygon.
    index: EdgeIndex,
    /// The region encloses nothing ([`RegionChart::empty`]).
    empty: bool,
    /// How points off the surface reach it ([`RegionChart::to_sphere`]).
    projection: Projection,
    /// The unit-sphere directions of the boundary points the chart was made from.
    known: KnownDirections,
}

/// The unit-sphere directions [`RegionChart::to_sphere`] gave for the boundary points a
/// chart was made from, sorted by the points' bits: the meshing maps the same points again
/// (untangling's crossing test, the boundary's offsets, the boundary-only triangulation),
/// and their closest points on the ellipsoid are iterative (with the table, hand K = 18
/// decodes 5 % faster at 5 000 vertices, snowden's encode 6 %). A cache, not part of what
/// the chart is: any two compare equal. The chart's ellipsoid and projection, which the
/// directions depend on, are not changed once it is made.
#[derive(Debug, Clone, Default)]
struct KnownDirections(Arc<Vec<([u64; 3], DVec3)>>);

impl KnownDirections {
    /// The table of these (point, direction) pairs (the first of a repeated point kept).
    fn new(mut pairs: Vec<([u64; 3], DVec3)>) -> KnownDirections {
        pairs.sort_by_key(|&(bits, _)| bits);
        pairs.dedup_by_key(|&mut (bits, _)| bits);
        KnownDirections(Arc::new(pairs))
    }

    /// The direction kept for `p`, if it is one of the points.
    fn get(&self, p: DVec3) -> Option<DVec3> {
        let bits = p.to_array().map(f64::to_bits);
        let found = self.0.binary_search_by_key(&bits, |&(b, _)| b).ok()?;
        self.0.get(found).map(|&(_, u)| u)
    }
}

impl PartialEq for KnownDirections {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// How a chart maps a point that is not on its ellipsoid (a stored boundary point) to the
/// surface.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Projection {
    /// The closest surface point ([`Ellipsoid::closest_point`]), the default: it moves a
    /// point along the normal only, so boundary points close together keep their order
    /// however oblique the ray from the centre is.
    #[default]
    Closest,
    /// Along the ray from the centre (Π, paper section 2).
    Radial,
    /// The closest point on this ellipsoid (the region's own), then along its inward normal
    /// onto the chart's surface (a stand-in inside it): the inverse of lifting the stand-in's
    /// points to their closest points on this ellipsoid
    /// ([`super::surface::Lift::Closest`]). Where the normal misses the stand-in, along the
    /// ray from the centre.
    NormalOnto(Ellipsoid),
}

/// How `choose_pole`'s pattern search may move the pole away from the boundary.
///
/// It accepts a pole when the region's loops enclose a positive area in its chart, whose
/// straight edges are images of circles through the pole, not of the great-circle arcs
/// between the points; beside a loop whose edges are longer than the pole's distance to it
/// the two disagree. From inside a triangular hole the search walked out through an edge
/// into the circle through the hole's corners, where the straight triangle keeps the
/// hole's orientation: the region (an ellipsoid with one face of an icosphere missing) was
/// charted as its hole, one triangle turned over. Kept from crossing the boundary, the
/// search also changes charts that were sound (one of the small meshes' 48 files written
/// without the encoder's check, clean in its fifth meshing attempt, was not in any): the
/// decoder tries it last ([`super::assemble::assemble`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PoleWalk {
    /// Any move that keeps the pole outside the region by the chart's test.
    #[default]
    Free,
    /// Only moves along which no boundary edge lies (a move no longer than the pole's
    /// clearance is one).
    Uncrossed,
}

/// Charts already made, by their exact inputs: [`RegionChart::with_projection`] is a pure
/// function of the ellipsoid, the loops' points, the projection and the pole walk, and a
/// file that needs several meshing attempts (boundary treatments) charts most of its regions
/// alike in each, untangling and then meshing them. Snowden's head scan (npm), whose file
/// decodes in 14 meshings, made 1 479 charts of which 614 had distinct inputs; `regr01`
/// (assimp) 2 483, of which 372. A hit is the chart made before, bit for bit.
///
/// One memo serves one decode ([`super::remesh`]), or the decodes of a caller that decodes
/// files alike one after another ([`super::remesh_with_charts`]): the encoder's check,
/// whose rounds of mending change a few regions at a time. [`ChartMemo::age`], at the start
/// of each of those decodes, drops the charts the decode before did not ask for, so that
/// the memo holds two decodes' charts at most, and charts of more than [`MEMO_MAX_POINTS`]
/// loop points in all are made but not kept. Shared between threads, it is locked while a
/// chart is looked up or kept, not while one is made.
#[derive(Debug, Default)]
pub struct ChartMemo {
    kept: Mutex<KeptCharts>,
}

/// A chart kept by a [`ChartMemo`] (or why there is none), with its loop points.
type KeptChart = (Result<RegionChart, &'static str>, usize);

/// What a [`ChartMemo`] holds, by [`chart_key`].
#[derive(Debug, Default)]
struct KeptCharts {
    /// The charts asked for since the last [`ChartMemo::age`].
    current: HashMap<Vec<u64>, KeptChart>,
    /// The charts asked for before it and not since.
    previous: HashMap<Vec<u64>, KeptChart>,
    /// The loop points of the charts kept, in both.
    points: usize,
}

/// Most loop points the charts a [`ChartMemo`] keeps may have in all: about 100 bytes each
/// (the key, the plane loops and their index), so at most a few hundred megabytes for a
/// file whose every attempt charts a million boundary points.
pub const MEMO_MAX_POINTS: usize = 4_000_000;

impl ChartMemo {
    /// [`RegionChart::with_projection`], made once for each distinct input.
    pub fn chart(
        &self,
        region: u32,
        ellipsoid: &Ellipsoid,
        loops: &[Vec<DVec3>],
        projection: Projection,
        walk: PoleWalk,
    ) -> Result<RegionChart, RemeshError> {
        let named = |known: &Result<RegionChart, &'static str>| {
            known
                .clone()
                .map_err(|what| RemeshError::Region { region, what })
        };
        let key = chart_key(ellipsoid, loops, projection, walk);
        {
            let mut memo = self.lock();
            if let Some((known, _)) = memo.current.get(&key) {
                return named(known);
            }
            if let Some((key, known)) = memo.previous.remove_entry(&key) {
                let chart = named(&known.0);
                memo.current.insert(key, known);
                return chart;
            }
        }
        let made = RegionChart::with_projection(region, ellipsoid, loops, projection, walk);
        let kept = match &made {
            Ok(chart) => Ok(chart.clone()),
            Err(RemeshError::Region { what, .. }) => Err(*what),
            Err(_) => return made,
        };
        let count = loops.iter().map(Vec::len).sum::<usize>();
        let mut memo = self.lock();
        let points = memo.points + count;
        if points <= MEMO_MAX_POINTS && !memo.current.contains_key(&key) {
            memo.points = points;
            memo.current.insert(key, (kept, count));
        }
        made
    }

    /// Drops the charts not asked for since the last call: the charts asked for since then
    /// are kept for the next, the others forgotten. Called by
    /// [`super::remesh_with_charts`] as each decode starts.
    pub fn age(&self) {
        let mut memo = self.lock();
        let dropped: usize = memo.previous.values().map(|&(_, count)| count).sum();
        memo.points -= dropped;
        memo.previous = std::mem::take(&mut memo.current);
    }

    /// How many distinct inputs' charts (or failures) are kept.
    pub fn len(&self) -> usize {
        let memo = self.lock();
        memo.current.len() + memo.previous.len()
    }

    /// Whether no chart is kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The memo, locked. A thread that panicked while holding it left it whole (a chart is
    /// inserted in one call), so a poisoned lock is taken as it is.
    fn lock(&self) -> std::sync::MutexGuard<'_, KeptCharts> {
        self.kept
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// The inputs of [`RegionChart::with_projection`] (but the region, which only names it in
/// errors) as bits: equal keys, equal charts.
fn chart_key(
    ellipsoid: &Ellipsoid,
    loops: &[Vec<DVec3>],
    projection: Projection,
    walk: PoleWalk,
) -> Vec<u64> {
    let points: usize = loops.iter().map(Vec::len).sum();
    let mut key = Vec::with_capacity(32 + loops.len() + 3 * points);
    let push_ellipsoid = |key: &mut Vec<u64>, e: &Ellipsoid| {
        key.extend(e.center.to_array().map(f64::to_bits));
        key.extend(e.rotation.to_array().map(f64::to_bits));
        key.extend(e.radii.to_array().map(f64::to_bits));
        key.push(e.sign as u64);
    };
    push_ellipsoid(&mut key, ellipsoid);
    match projection {
        Projection::Closest => key.push(0),
        Projection::Radial => key.push(1),
        Projection::NormalOnto(real) => {
            key.push(2);
            push_ellipsoid(&mut key, &real);
        }
    }
    key.push(walk as u64);
    key.push(loops.len() as u64);
    for l in loops {
        key.push(l.len() as u64);
        key.extend(l.iter().flat_map(|p| p.to_array().map(f64::to_bits)));
    }
    key
}

impl RegionChart {
    /// The chart of region `region` on `ellipsoid`, bounded by `loops`: closed polylines of
    /// boundary points near the ellipsoid (mapped to the unit sphere by
    /// [`RegionChart::to_sphere`]; the first point not repeated at the end), each with the
    /// region on its left when seen with the mesh's outward normal up (spec §6.5; for a
    /// negative ellipsoid that is the inner side). No loops: the whole ellipsoid.
    ///
    /// The pole — the point the projection sends to infinity — is chosen outside the region
    /// and as far as possible from its boundary (section 5.1, "rotate the region away from
    /// the north pole"): evenly spread candidate directions plus each loop's centre and
    /// antipode are scored by their angular distance to the boundary's great-circle edges;
    /// the best one outside the region is then improved by a local pattern search. A
    /// candidate is outside the region exactly when the region's projected loops, oriented
    /// with the region on their left in the plane, enclose a positive total signed area
    /// (with the pole inside, the bounded side is the complement and the sum is negative);
    /// edges longer than 0.1 rad are measured along their arcs, split into equal pieces of
    /// at most that (longer where a boundary's long edges would need more than 4096).
    ///
    /// Errors ([`RemeshError::Region`]): the ellipsoid is not valid, a point is not finite,
    /// a loop has fewer than three distinct directions on the unit sphere, or no candidate
    /// pole lies outside the region (e.g. degenerate loops enclosing nothing).
    pub fn new(
        region: u32,
        ellipsoid: &Ellipsoid,
        loops: &[Vec<DVec3>],
    ) -> Result<RegionChart, RemeshError> {
        RegionChart::with_projection(
            region,
            ellipsoid,
            loops,
            Projection::Closest,
            PoleWalk::Free,
        )
    }

    /// [`RegionChart::new`] with the boundary points mapped to the surface by `projection`
    /// and the pole placed with `walk`.
    pub fn with_projection(
        region: u32,
        ellipsoid: &Ellipsoid,
        loops: &[Vec<DVec3>],
        projection: Projection,
        walk: PoleWalk,
    ) -> Result<RegionChart, RemeshError> {
        let fail = |what: &'static str| RemeshError::Region { region, what };
        if !ellipsoid.is_valid() {
            return Err(fail("ellipsoid not valid"));
        }
        let probe = RegionChart {
            projection,
            ..RegionChart::with_pole(ellipsoid, DVec3::Z)
        };
        let mut sphere_loops = Vec::with_capacity(loops.len());
        let mut known = Vec::with_capacity(loops.iter().map(Vec::len).sum());
        for l in loops {
            if l.iter().any(|p| !p.is_finite()) {
                return Err(fail("boundary point not finite"));
            }
            let mut s = dedup_directions(l.iter().map(|&p| {
                let u = probe.to_sphere(p);
                known.push((p.to_array().map(f64::to_bits), u));
                u
            }));
            if count_distinct(&s) < 3 {
                return Err(fail("boundary loop has fewer than 3 distinct points"));
            }
            if ellipsoid.sign == Sign::Negative {
                s.reverse();
            }
            sphere_loops.push(s);
        }
        if sphere_loops.is_empty() {
            return Ok(probe);
        }
        let (pole, clearance) = choose_pole(ellipsoid, &sphere_loops, walk).ok_or(fail(
            "no pole outside the region (its boundary loops enclose nothing)",
        ))?;
        let mut chart = RegionChart {
            projection,
            ..RegionChart::with_pole(ellipsoid, pole)
        };
        chart.plane_loops = project_loops(&chart, &sphere_loops);
        chart.clearance = clearance;
        chart.index = EdgeIndex::new(&chart.plane_loops);
        chart.known = KnownDirections::new(known);
        Ok(chart)
    }

    /// The chart whose projection centre (the point mapped to infinity) is `pole`, a
    /// direction on the unit sphere of `ellipsoid`, with no boundary: it contains the whole
    /// ellipsoid.
    pub fn with_pole(ellipsoid: &Ellipsoid, pole: DVec3) -> RegionChart {
        let pole = pole.try_normalize().unwrap_or(DVec3::Z);
        RegionChart {
            ellipsoid: *ellipsoid,
            rotation: DQuat::from_rotation_arc(pole, DVec3::Z),
            plane_loops: Vec::new(),
            clearance: std::f64::consts::PI,
            index: EdgeIndex::default(),
            empty: false,
            projection: Projection::Closest,
            known: KnownDirections::default(),
        }
    }

    /// The chart of a region that encloses nothing (e.g. its loops collapsed to points:
    /// [`is_degenerate_loop`]): it contains no point.
    pub fn empty(ellipsoid: &Ellipsoid) -> RegionChart {
        RegionChart {
            empty: true,
            clearance: 0.0,
            ..RegionChart::with_pole(ellipsoid, DVec3::Z)
        }
    }

    /// Whether the region encloses nothing ([`RegionChart::empty`]).
    pub fn is_empty(&self) -> bool {
        self.empty
    }

    /// How the chart maps points off its surface (boundary points) onto it.
    pub fn projection(&self) -> Projection {
        self.projection
    }

    /// The pole: the unit-sphere direction the projection sends to infinity.
    pub fn pole(&self) -> DVec3 {
        self.rotation.inverse() * DVec3::Z
    }

    /// Angular distance (radians, on the unit sphere) from the pole to the nearest boundary
    /// edge; π when the chart covers the whole ellipsoid, 0 when it is empty.
    pub fn clearance(&self) -> f64 {
        self.clearance
    }

    /// Whether the chart covers the whole ellipsoid (the region has no boundary).
    pub fn is_whole(&self) -> bool {
        self.plane_loops.is_empty() && !self.empty
    }

    /// The region's boundary loops in plane coordinates, the region on their left (outer
    /// boundary counter-clockwise, holes clockwise). Empty for the whole ellipsoid.
    pub fn plane_loops(&self) -> &[Vec<DVec2>] {
        &self.plane_loops
    }

    /// A point (on or near the ellipsoid) → the unit-sphere direction of its closest surface
    /// point ([`Ellipsoid::closest_point`]: along the normal, so nearby boundary points keep
    /// their order however oblique the radial direction is). For the boundary points the
    /// chart was made from, the direction found then.
    pub fn to_sphere(&self, p: DVec3) -> DVec3 {
        if let Some(u) = self.known.get(p) {
            return u;
        }
        let surface = match self.projection {
            Projection::Closest => self.ellipsoid.closest_point(p),
            Projection::Radial => p,
            Projection::NormalOnto(real) => {
                let x = real.closest_point(p);
                let inward = -real.outward_normal(x);
                // The first crossing ahead (the stand-in lies inside the real ellipsoid).
                self.ellipsoid
                    .intersect_ray(x, inward)
                    .and_then(|ts| ts.into_iter().find(|t| *t >= 0.0))
                    .map_or(x, |t| x + t * inward)
            }
        };
        self.ellipsoid
            .to_unit_sphere(surface)
            .try_normalize()
            .unwrap_or(DVec3::X)
    }

    /// Unit-sphere direction → plane, stereographically from the north pole after rotation.
    /// Reverses orientation (see the module documentation).
    pub fn sphere_to_plane(&self, u: DVec3) -> DVec2 {
        let v = self.rotation * u;
        // The pole itself goes to a far but finite point.
        let d = (1.0 - v.z).max(1e-300);
        DVec2::new(v.x / d, v.y / d)
    }

    /// Plane → unit-sphere direction (inverse of [`RegionChart::sphere_to_plane`]).
    pub fn plane_to_sphere(&self, q: DVec2) -> DVec3 {
        let s = q.length_squared();
        let d = 1.0 + s;
        let v = DVec3::new(2.0 * q.x / d, 2.0 * q.y / d, (s - 1.0) / d);
        self.rotation.inverse() * v
    }

    /// A point (on or near the ellipsoid) → the plane, through its radial projection.
    pub fn to_plane(&self, p: DVec3) -> DVec2 {
        self.sphere_to_plane(self.to_sphere(p))
    }

    /// Plane → the point on the ellipsoid.
    pub fn from_plane(&self, q: DVec2) -> DVec3 {
        self.ellipsoid.from_unit_sphere(self.plane_to_sphere(q))
    }

    /// Whether the radial projection of `p` onto the ellipsoid lies in the region (section
    /// 5.1). Non-finite points are outside; the ellipsoid's centre counts as the direction of
    /// its local +x axis.
    pub fn contains(&self, p: DVec3) -> bool {
        let u = self
            .ellipsoid
            .to_unit_sphere(p)
            .try_normalize()
            .unwrap_or(DVec3::X);
        p.is_finite() && self.contains_sphere(u)
    }

    /// Whether the unit-sphere direction `u` lies in the region. The pole is outside (unless
    /// the chart is whole).
    pub fn contains_sphere(&self, u: DVec3) -> bool {
        if !u.is_finite() || self.empty {
            return false;
        }
        if self.is_whole() {
            return true;
        }
        // The pole and directions rounding onto it are outside the region by construction.
        if (self.rotation * u).z >= 1.0 {
            return false;
        }
        self.contains_plane(self.sphere_to_plane(u))
    }

    /// Whether the plane point `q` lies in the region: even–odd rule over all projected loops
    /// (the outer cycle and its holes; valid because the pole is outside the region).
    /// Non-finite points are outside; a whole chart contains every finite point.
    pub fn contains_plane(&self, q: DVec2) -> bool {
        if !q.is_finite() {
            return false;
        }
        !self.empty && (self.is_whole() || self.index.contains(q))
    }
}

/// Whether a boundary loop of finite points encloses nothing on `ellipsoid`: fewer than three
/// distinct directions from its centre (e.g. quantisation collapsed a tiny region's boundary
/// to a point). [`RegionChart::new`] refuses such loops; a caller may drop them, and treat a
/// region whose loops are all degenerate as empty ([`RegionChart::empty`]), as
/// [`super::query::chart_region`] does. Loops with a non-finite point are not degenerate
/// (they are errors).
pub fn is_degenerate_loop(ellipsoid: &Ellipsoid, points: &[DVec3]) -> bool {
    if points.iter().any(|p| !p.is_finite()) {
        return false;
    }
    let probe = RegionChart::with_pole(ellipsoid, DVec3::Z);
    count_distinct(&dedup_directions(
        points.iter().map(|&p| probe.to_sphere(p)),
    )) < 3
}

/// Unit-sphere directions with consecutive repeats (and a repeated first point at the end)
/// removed.
fn dedup_directions(points: impl Iterator<Item = DVec3>) -> Vec<DVec3> {
    let mut out: Vec<DVec3> = Vec::new();
    for u in points {
        if out
            .last()
            .is_none_or(|&l| (l - u).length() > SAME_DIRECTION)
        {
            out.push(u);
        }
    }
    while out.len() > 1 {
        match (out.first(), out.last()) {
            (Some(&a), Some(&b)) if (a - b).length() <= SAME_DIRECTION => {
                out.pop();
            }
            _ => break,
        }
    }
    out
}

/// The number of distinct directions in `points`, counted up to three.
fn count_distinct(points: &[DVec3]) -> usize {
    let mut found: Vec<DVec3> = Vec::with_capacity(3);
    for &u in points {
        if found.iter().all(|&f| (f - u).length() > SAME_DIRECTION) {
            found.push(u);
            if found.len() == 3 {
                break;
            }
        }
    }
    found.len()
}

/// `n` directions spread evenly over the unit sphere (a Fibonacci lattice); deterministic.
fn fibonacci_directions(n: usize) -> Vec<DVec3> {
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden_angle * i as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// The angle between two unit vectors, accurate for small and large angles.
fn angle_between(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Angular distance from `c` to the shorter great-circle arc from `a` to `b` (all unit): the
/// reference [`SphereEdges::distance`] is tested against.
#[cfg(test)]
fn arc_distance(c: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ends = angle_between(c, a).min(angle_between(c, b));
    let Some(n) = a.cross(b).try_normalize() else {
        return ends;
    };
    // c's closest point on the great circle lies between a and b.
    if a.cross(c).dot(n) >= 0.0 && c.cross(b).dot(n) >= 0.0 {
        c.dot(n).abs().min(1.0).asin().min(ends)
    } else {
        ends
    }
}

/// The edges of unit-sphere loops, each with its great circle's unit normal (computed once:
/// the pole search measures hundreds of candidates against every edge).
struct SphereEdges {
    /// Per edge: its ends and, unless they are (anti)parallel, the normal of a × b.
    edges: Vec<(DVec3, DVec3, Option<DVec3>)>,
}

impl SphereEdges {
    fn new(loops: &[Vec<DVec3>]) -> SphereEdges {
        let edges = loops
            .iter()
            .flat_map(|l| {
                l.iter().enumerate().map(|(i, &a)| {
                    let b = l.get(i + 1).or(l.first()).copied().unwrap_or(a);
                    (a, b, a.cross(b).try_normalize())
                })
            })
            .collect();
        SphereEdges { edges }
    }

    /// Whether the shorter great-circle arc from `p` to `q` (unit vectors) crosses an edge.
    fn crossed_by(&self, p: DVec3, q: DVec3) -> bool {
        let Some(m) = p.cross(q).try_normalize() else {
            return false;
        };
        let within = |s: DVec3, a: DVec3, b: DVec3, n: DVec3| {
            a.cross(s).dot(n) >= 0.0 && s.cross(b).dot(n) >= 0.0
        };
        self.edges.iter().any(|&(a, b, n)| {
            let Some(n) = n else {
                return false;
            };
            let Some(x) = m.cross(n).try_normalize() else {
                return false;
            };
            [x, -x]
                .into_iter()
                .any(|s| within(s, p, q, m) && within(s, a, b, n))
        })
    }

    /// Every `step`-th edge (the nearest of them is no nearer than the nearest of all).
    fn every(&self, step: usize) -> SphereEdges {
        SphereEdges {
            edges: self.edges.iter().step_by(step.max(1)).copied().collect(),
        }
    }

    /// Angular distance from `c` to the nearest edge.
    ///
    /// The minimum is taken over squared chord lengths, which grow with the angle, and
    /// turned into an angle once: no inverse trigonometry per edge.
    fn distance(&self, c: DVec3) -> f64 {
        self.distance_beyond(c, f64::NEG_INFINITY, 0).0
    }

    /// [`Self::distance`] if it is more than `floor`; otherwise some value at most `floor`,
    /// found without scanning every edge (the scan stops at the first edge clearly closer
    /// than `floor`). With it, the edge the scan ended on: the nearest, or the one that
    /// stopped it.
    ///
    /// The scan starts at edge `start` and wraps round. Edges come in order along their
    /// loops, so the edge nearest to one point is a good start for a point near it: if that
    /// point's scan is to stop, it stops at once (the pattern search in [`choose_pole`]
    /// tries eight moves around its pole each step, most of them no farther out).
    fn distance_beyond(&self, c: DVec3, floor: f64, start: usize) -> (f64, usize) {
        self.distance_beyond_blocked(c, floor, start, &[])
    }

    /// [`Self::distance_beyond`], trying the edges `blockers` first: the edges that stopped
    /// the scans of points near `c` (a pole's moves are stopped by the few edges nearest to
    /// it, which the scan from one of them may reach only after most of the loop). The same
    /// result: a scan that some edge stops returns minus infinity, whichever edge it is.
    fn distance_beyond_blocked(
        &self,
        c: DVec3,
        floor: f64,
        start: usize,
        blockers: &[usize],
    ) -> (f64, usize) {
        // The chord² of `floor`, lowered a little so that rounding never stops a scan whose
        // distance would come out above `floor`.
        let stop = if floor > 0.0 {
            let half = (0.5 * floor).min(std::f64::consts::FRAC_PI_2).sin();
            4.0 * half * half * (1.0 - 1e-9)
        } else {
            f64::NEG_INFINITY
        };
        for &k in blockers {
            if let Some(&(a, b, n)) = self.edges.get(k) {
                if arc_chord_squared(c, a, b, n) < stop {
                    return (f64::NEG_INFINITY, k);
                }
            }
        }
        let start = if start < self.edges.len() { start } else { 0 };
        let (before, from) = self.edges.split_at(start);
        let mut best = f64::INFINITY;
        let mut nearest = start;
        for (k, &(a, b, n)) in from.iter().chain(before).enumerate() {
            let d = arc_chord_squared(c, a, b, n);
            if d < best {
                best = d;
                nearest = (start + k) % self.edges.len();
            }
            if best < stop {
                return (f64::NEG_INFINITY, nearest);
            }
        }
        if best.is_finite() {
            (2.0 * (0.5 * best.max(0.0).sqrt()).min(1.0).asin(), nearest)
        } else {
            (best, nearest)
        }
    }
}

/// Squared chord length from `c` to its nearest point on the shorter great-circle arc from
/// `a` to `b` (all unit; `n` the unit normal of a × b, if any): 4·sin²(θ/2) for the angular
/// distance θ of [`arc_distance`].
fn arc_chord_squared(c: DVec3, a: DVec3, b: DVec3, n: Option<DVec3>) -> f64 {
    let ends = (c - a).length_squared().min((c - b).length_squared());
    let Some(n) = n else {
        return ends;
    };
    if a.cross(c).dot(n) >= 0.0 && c.cross(b).dot(n) >= 0.0 {
        // sin θ = |c·n|; chord² = 2 − 2 cos θ = 2 sin²θ / (1 + cos θ), without cancellation.
        let s = c.dot(n).abs().min(1.0);
        let cos = (1.0 - s * s).max(0.0).sqrt();
        (2.0 * s * s / (1.0 + cos)).min(ends)
    } else {
        ends
    }
}

/// Unit-sphere loops (region on the left, seen from outside) → plane loops with the region
/// on their left in the plane (the projection reverses orientation, so each is reversed).
fn project_loops(chart: &RegionChart, sphere_loops: &[Vec<DVec3>]) -> Vec<Vec<DVec2>> {
    sphere_loops
        .iter()
        .map(|l| l.iter().rev().map(|&u| chart.sphere_to_plane(u)).collect())
        .collect()
}

/// Twice the signed area of a closed polygon (positive counter-clockwise), its corners in
/// order (taken once each: they may be computed on the way).
fn doubled_signed_area(polygon: impl IntoIterator<Item = DVec2>) -> f64 {
    let mut corners = polygon.into_iter();
    let Some(first) = corners.next() else {
        return 0.0;
    };
    let (mut sum, mut a) = (0.0, first);
    for b in corners.chain(std::iter::once(first)) {
        // Relative to the first corner, to limit cancellation.
        sum += (a - first).perp_dot(b - first);
        a = b;
    }
    sum
}

/// Whether `pole` lies outside the region bounded by the loops of `area` (made by
/// [`AreaLoops::new`]): then the region's image in the plane is bounded and its loops, region
/// on the left, enclose a positive total area; with the pole inside, the bounded side is the
/// complement and the total is negative.
fn is_outside(ellipsoid: &Ellipsoid, area: &AreaLoops, pole: DVec3) -> bool {
    let chart = RegionChart::with_pole(ellipsoid, pole);
    let total: f64 = area
        .loops
        .iter()
        .map(|l| doubled_signed_area(l.iter().map(|&u| chart.sphere_to_plane(u))))
        .sum();
    total.is_finite() && total > 0.0
}

/// Longest edge (angle on the unit sphere, radians) whose chord stands for its arc in
/// [`is_outside`]: a chord of 0.1 strays at most 1/800 from its arc (θ²/8).
const MAX_AREA_EDGE: f64 = 0.1;

/// Most points [`AreaLoops`] adds to a region's loops: on a boundary whose long edges add
/// up to more than this many pieces of [`MAX_AREA_EDGE`] (a hostile file's loops of
/// thousands of edges across the sphere), the pieces are made longer: the pole's test
/// measures at most 4096 points more than the loops (and at most 32 pieces an edge).
const MAX_AREA_PIECES: f64 = 4096.0;

/// A region's unit-sphere loops as [`is_outside`] measures them, made once for the many poles
/// [`choose_pole`] tries: in reverse order, as [`project_loops`] takes them, and with every
/// edge longer than [`MAX_AREA_EDGE`] split into equal pieces along its great-circle arc.
///
/// The region's edges are great-circle arcs, which the projection maps to circular arcs, not
/// to the chords between their ends: a pole near a long edge may lie between the two, and
/// the chords' area gives it the wrong side (a three-point hole with edges of 60–90°, a
/// pole 40° beyond one of them). A loop of shorter edges is measured as it is. (An edge
/// between antipodes, with no one arc, is left whole.)
struct AreaLoops {
    loops: Vec<Vec<DVec3>>,
}

impl AreaLoops {
    fn new(sphere_loops: &[Vec<DVec3>]) -> AreaLoops {
        let cos_max = MAX_AREA_EDGE.cos();
        // Each edge from a loop's corner `i` to the one before it, as the loop is measured.
        let edges = |l: &[DVec3]| -> Vec<(DVec3, DVec3)> {
            (0..l.len())
                .rev()
                .map(|i| (l[i], if i == 0 { l[l.len() - 1] } else { l[i - 1] }))
                .collect()
        };
        let long = |a: DVec3, b: DVec3| -> Option<(f64, f64)> {
            if a.dot(b) >= cos_max {
                return None;
            }
            let angle = angle_between(a, b);
            let sin = angle.sin();
            (sin > 1e-9).then_some((angle, sin))
        };
        let total: f64 = sphere_loops
            .iter()
            .flat_map(|l| edges(l))
            .filter_map(|(a, b)| long(a, b))
            .map(|(angle, _)| angle)
            .sum();
        let piece = MAX_AREA_EDGE.max(total / MAX_AREA_PIECES);
        let loops = sphere_loops
            .iter()
            .map(|l| {
                let mut out = Vec::with_capacity(l.len());
                for (a, b) in edges(l) {
                    out.push(a);
                    let Some((angle, sin)) = long(a, b) else {
                        continue;
                    };
                    let pieces = (angle / piece).ceil() as usize;
                    out.extend((1..pieces).map(|k| {
                        let t = k as f64 / pieces as f64;
                        ((a * ((1.0 - t) * angle).sin() + b * (t * angle).sin()) / sin).normalize()
                    }));
                }
                out
            })
            .collect();
        AreaLoops { loops }
    }
}

/// Boundary points beyond which candidate poles are ranked against a subsample of the loops
/// (every k-th point), keeping the pole search linear in the boundary size.
const SCORING_POINTS: usize = 4096;

/// Every k-th point of each loop (at least three per loop), so that about `budget` remain.
fn decimate_loops(loops: &[Vec<DVec3>], budget: usize) -> Vec<Vec<DVec3>> {
    let total: usize = loops.iter().map(Vec::len).sum();
    let k = total.div_ceil(budget.max(1)).max(1);
    loops
        .iter()
        .map(|l| {
            let step = k.min(l.len() / 3).max(1);
            l.iter().step_by(step).copied().collect()
        })
        .collect()
}

/// Edges a pole candidate's first, upper-bound score is taken against ([`choose_pole`]).
/// Any subset of the edges bounds the score from above, and the best-first search accepts
/// the same pole whatever the bound: a looser one only scores more candidates in full.
/// Four cost the fewest instructions of 4, 8, 16, 48 and 96 (callgrind, hand K = 18 and
/// horse K = 24 at 5 000 vertices: 48 cost 9 % more than 4, 16 3 %, 8 under 1 %).
const BOUND_EDGES: usize = 4;

/// A pole candidate in [`choose_pole`]'s best-first ranking: by score, then bounds before
/// scores (a bound equal to a score may hide a better candidate), then the candidates'
/// order.
#[derive(Debug, Clone, Copy)]
struct Ranked {
    score: f64,
    bound: bool,
    index: usize,
}

impl PartialEq for Ranked {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Ranked {}

impl PartialOrd for Ranked {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Ranked {
    fn cmp(&self, other: &Self) -> Ordering {
        self.score
            .total_cmp(&other.score)
            .then(self.bound.cmp(&other.bound))
            .then(other.index.cmp(&self.index))
    }
}

/// The pole outside the region farthest from its boundary, and that distance (section 5.1).
///
/// Candidates are ranked by their distance to a subsample of the boundary (all of it up to
/// [`SCORING_POINTS`] points); a candidate is accepted only if it is outside the region and
/// at least [`MIN_CLEARANCE`] from the whole boundary.
fn choose_pole(
    ellipsoid: &Ellipsoid,
    loops: &[Vec<DVec3>],
    walk: PoleWalk,
) -> Option<(DVec3, f64)> {
    let all = SphereEdges::new(loops);
    let area = AreaLoops::new(loops);
    // Up to SCORING_POINTS boundary points the coarse edges are all of them.
    let scored_in_full = loops.iter().map(Vec::len).sum::<usize>() <= SCORING_POINTS;
    let decimated;
    let coarse = if scored_in_full {
        &all
    } else {
        decimated = SphereEdges::new(&decimate_loops(loops, SCORING_POINTS));
        &decimated
    };
    let score = |c: DVec3| coarse.distance(c);
    // A candidate with its full coarse score: its distance to the whole boundary if it is
    // acceptable (outside, which the caller may know already).
    let accept = |c: DVec3, score: f64, outside: bool| {
        let exact = if scored_in_full {
            score
        } else {
            all.distance(c)
        };
        (exact >= MIN_CLEARANCE && (outside || is_outside(ellipsoid, &area, c))).then_some(exact)
    };
    let mut candidates = fibonacci_directions(POLE_CANDIDATES);
    let mean: DVec3 = loops.iter().flatten().copied().sum();
    candidates.extend((-mean).try_normalize());
    for l in loops.iter().take(MAX_LOOP_CANDIDATES) {
        let centre: DVec3 = l.iter().copied().sum();
        if let Some(c) = centre.try_normalize() {
            candidates.push(c);
            candidates.push(-c);
        }
    }
    // The first acceptable candidate by decreasing score (ties in the candidates' order).
    // Best-first: every candidate starts with an upper bound of its score, its distance to
    // a sample of the edges, and is scored against all of them only when it comes on top;
    // a scored candidate on top is ahead of every other (ties go to bounds, to be scored
    // first), so only the few candidates near the top are ever scored in full. A candidate
    // inside the region can never be accepted: it is dropped before it is scored (where the
    // region is most of its ellipsoid, the candidates farthest from its boundary are
    // inside it).
    let sample = coarse.every(coarse.edges.len().div_ceil(BOUND_EDGES));
    let mut ranked: BinaryHeap<Ranked> = candidates
        .iter()
        .enumerate()
        .map(|(index, &c)| Ranked {
            score: sample.distance(c),
            bound: true,
            index,
        })
        .collect();
    let mut first = None;
    while let Some(top) = ranked.pop() {
        let c = candidates[top.index];
        if top.bound {
            if is_outside(ellipsoid, &area, c) {
                ranked.push(Ranked {
                    score: score(c),
                    bound: false,
                    ..top
                });
            }
        } else if let Some(d) = accept(c, top.score, true) {
            first = Some((top.score, c, d));
            break;
        }
    }
    let (mut best_score, mut best, mut best_distance) = first?;
    // The coarse edge nearest to the pole: where the moves' scans start.
    let mut near = coarse.distance_beyond(best, f64::NEG_INFINITY, 0).1;
    // Pattern search: move the pole away from the boundary while it improves.
    let mut step = 0.5 * (4.0 * std::f64::consts::PI / POLE_CANDIDATES as f64).sqrt();
    // The edges that stopped the last moves' scans, latest last: tried first.
    let mut blockers: Vec<usize> = Vec::with_capacity(BLOCKERS + 1);
    for _ in 0..40 {
        let (t1, t2) = best.any_orthonormal_pair();
        let mut moves: Vec<(f64, DVec3, usize)> = Vec::with_capacity(8);
        for k in 0..8 {
            let (s, c) = (k as f64 * std::f64::consts::FRAC_PI_4).sin_cos();
            let dir = t1 * c + t2 * s;
            let Some(c) = (best * step.cos() + dir * step.sin()).try_normalize() else {
                continue;
            };
            let (score, nearest) = coarse.distance_beyond_blocked(c, best_score, near, &blockers);
            if score > best_score {
                moves.push((score, c, nearest));
            } else if score == f64::NEG_INFINITY && !blockers.contains(&nearest) {
                blockers.push(nearest);
                if blockers.len() > BLOCKERS {
                    blockers.remove(0);
                }
            }
        }
        moves.sort_by(|a, b| b.0.total_cmp(&a.0));
        // (A move no longer than the pole's clearance cannot reach an edge.)
        let allowed =
            |c: DVec3| walk == PoleWalk::Free || step < best_distance || !all.crossed_by(best, c);
        match moves
            .into_iter()
            .filter(|&(_, c, _)| allowed(c))
            .find_map(|(s, c, nearest)| accept(c, s, false).map(|d| (s, c, d, nearest)))
        {
            Some((s, c, d, nearest)) => {
                (best_score, best, best_distance, near) = (s, c, d, nearest)
            }
            None => {
                step *= 0.5;
                if step < 1e-4 {
                    break;
                }
            }
        }
    }
    Some((best, best_distance))
}

/// Edges that stopped recent moves' scans the pole search tries first
/// ([`SphereEdges::distance_beyond_blocked`]): a pole at its best is about as far from two
/// or three edges, which stop every move.
const BLOCKERS: usize = 4;

/// Largest number of horizontal slabs of an [`EdgeIndex`].
const MAX_SLABS: usize = 4096;

/// The edges of closed plane polygons, bucketed by horizontal slab so that an even–odd
/// crossing test only looks at the edges of one slab.
#[derive(Debug, Clone, PartialEq, Default)]
struct EdgeIndex {
    /// Bounding box of all points.
    min: DVec2,
    max: DVec2,
    /// Every edge, as its two ends.
    edges: Vec<[DVec2; 2]>,
    /// Slab count; slab `s` covers y in `min.y + [s, s + 1) · height / slabs`.
    slabs: usize,
    /// Per slab, the range of `items` holding its edges (CSR offsets, `slabs + 1` long).
    starts: Vec<usize>,
    /// Edge indices, slab by slab.
    items: Vec<u32>,
}

impl EdgeIndex {
    fn new(loops: &[Vec<DVec2>]) -> EdgeIndex {
        let mut edges = Vec::new();
        let (mut min, mut max) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for l in loops {
            for (i, &a) in l.iter().enumerate() {
                let b = l.get(i + 1).or(l.first()).copied().unwrap_or(a);
                min = min.min(a);
                max = max.max(a);
                if a != b {
                    edges.push([a, b]);
                }
            }
        }
        if edges.is_empty() || !(min.is_finite() && max.is_finite()) {
            return EdgeIndex::default();
        }
        let mut index = EdgeIndex {
            min,
            max,
            edges,
            ..EdgeIndex::default()
        };
        // About two edges per slab on a smooth loop; fewer slabs when long edges would fill
        // many of them.
        let n = index.edges.len();
        let mut slabs = (n / 2).clamp(1, MAX_SLABS);
        while slabs > 1 && index.entries(slabs) > 16 * n + 1024 {
            slabs /= 2;
        }
        index.slabs = slabs;
        let mut counts = vec![0usize; slabs + 1];
        for e in &index.edges {
            let (lo, hi) = index.slab_range(e);
            for c in &mut counts[lo + 1..=hi + 1] {
                *c += 1;
            }
        }
        for s in 0..slabs {
            counts[s + 1] += counts[s];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[slabs]];
        for (k, e) in index.edges.iter().enumerate() {
            let (lo, hi) = index.slab_range(e);
            for f in &mut fill[lo..=hi] {
                items[*f] = k as u32;
                *f += 1;
            }
        }
        index.starts = counts;
        index.items = items;
        index
    }

    /// The slab holding height `y` (clamped into range).
    fn slab(&self, y: f64, slabs: usize) -> usize {
        let h = self.max.y - self.min.y;
        if h <= 0.0 {
            return 0;
        }
        let s = ((y - self.min.y) / h * slabs as f64).floor();
        // `as` saturates; NaN cannot occur for points inside the finite box.
        (s.max(0.0) as usize).min(slabs - 1)
    }

    /// First and last slab an edge touches.
    fn slab_range(&self, e: &[DVec2; 2]) -> (usize, usize) {
        let (a, b) = (self.slab(e[0].y, self.slabs), self.slab(e[1].y, self.slabs));
        (a.min(b), a.max(b))
    }

    /// Slab entries the edges would need with `slabs` slabs.
    fn entries(&self, slabs: usize) -> usize {
        self.edges
            .iter()
            .map(|e| self.slab(e[0].y, slabs).abs_diff(self.slab(e[1].y, slabs)) + 1)
            .sum()
    }

    /// Even–odd point-in-polygon over all the loops (a ray towards +x).
    fn contains(&self, q: DVec2) -> bool {
        if self.edges.is_empty()
            || q.x < self.min.x
            || q.y < self.min.y
            || q.x > self.max.x
            || q.y > self.max.y
        {
            return false;
        }
        let s = self.slab(q.y, self.slabs);
        let (Some(&from), Some(&to)) = (self.starts.get(s), self.starts.get(s + 1)) else {
            return false;
        };
        let mut inside = false;
        for &k in self.items.get(from..to).unwrap_or(&[]) {
            let Some(&[a, b]) = self.edges.get(k as usize) else {
                continue;
            };
            if (a.y > q.y) != (b.y > q.y) {
                let x = a.x + (q.y - a.y) * (b.x - a.x) / (b.y - a.y);
                if q.x < x {
                    inside = !inside;
                }
            }
        }
        inside
    }
}

#[cfg(test)]
mod tests {
    /// The memo gives what [`RegionChart::with_projection`] gives, bit for bit, once per
    /// distinct input: the same loops charted again are a hit; another projection, pole walk
    /// or point is another chart; a failure is remembered and named for the region asking.
    #[test]
    fn the_chart_memo_gives_the_chart_made_once_per_input() {
        let e = Ellipsoid {
            center: DVec3::ZERO,
            rotation: DQuat::IDENTITY,
            radii: DVec3::new(1.0, 1.5, 0.7),
            sign: Sign::Positive,
        };
        // A loop round the top, the region on its left seen from outside, off the surface
        // (so that the projections differ).
        let cap: Vec<DVec3> = (0..12)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 12.0;
                DVec3::new(0.7 * a.cos(), 0.9 * a.sin(), 0.6)
            })
            .collect();
        let loops = vec![cap.clone()];
        let memo = ChartMemo::default();
        let made = |loops: &[Vec<DVec3>], projection, walk| {
            RegionChart::with_projection(3, &e, loops, projection, walk).unwrap()
        };
        let free = (Projection::Closest, PoleWalk::Free);
        for _ in 0..2 {
            let chart = memo.chart(3, &e, &loops, free.0, free.1).unwrap();
            assert_eq!(chart, made(&loops, free.0, free.1));
        }
        assert_eq!(memo.len(), 1);
        // The premise: another projection is another chart.
        assert_ne!(
            made(&loops, Projection::Radial, PoleWalk::Free),
            made(&loops, free.0, free.1)
        );
        for (projection, walk) in [
            (Projection::Radial, PoleWalk::Free),
            (Projection::Closest, PoleWalk::Uncrossed),
        ] {
            let chart = memo.chart(3, &e, &loops, projection, walk).unwrap();
            assert_eq!(chart, made(&loops, projection, walk));
        }
        let mut moved = cap.clone();
        moved[0].z = f64::from_bits(moved[0].z.to_bits() + 1);
        let chart = memo.chart(3, &e, &[moved.clone()], free.0, free.1).unwrap();
        assert_eq!(chart, made(&[moved], free.0, free.1));
        assert_eq!(memo.len(), 4);
        // A loop that encloses nothing: the error, for whichever region asks.
        let collapsed = vec![vec![DVec3::Z; 3]];
        for region in [5, 6] {
            match memo.chart(region, &e, &collapsed, free.0, free.1) {
                Err(RemeshError::Region { region: r, .. }) => assert_eq!(r, region),
                other => panic!("{other:?}"),
            }
        }
        assert_eq!(memo.len(), 5);
        // Aged, the charts asked for since are kept for the next age, the others dropped.
        memo.age();
        assert_eq!(memo.len(), 5);
        let chart = memo.chart(3, &e, &loops, free.0, free.1).unwrap();
        assert_eq!(chart, made(&loops, free.0, free.1));
        memo.age();
        assert_eq!(memo.len(), 1);
        memo.age();
        assert!(memo.is_empty());
    }

    /// A chart maps the boundary points it was made from to the directions it found then
    /// (its table), and those are what the projection gives, bit for bit, under every
    /// projection; other points are mapped afresh.
    #[test]
    fn a_charts_loop_points_map_as_the_projection_maps_them() {
        let e = Ellipsoid {
            center: DVec3::new(0.3, -0.2, 0.1),
            rotation: DQuat::from_rotation_y(0.4),
            radii: DVec3::new(1.0, 1.5, 0.7),
            sign: Sign::Positive,
        };
        let inner = Ellipsoid {
            radii: e.radii * 0.8,
            ..e
        };
        let cap: Vec<DVec3> = (0..12)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 12.0;
                e.center + e.rotation * DVec3::new(0.7 * a.cos(), 0.9 * a.sin(), 0.6)
            })
            .collect();
        let other = e.center + e.rotation * DVec3::new(0.1, 0.2, 0.9);
        for (chart_e, projection) in [
            (e, Projection::Closest),
            (e, Projection::Radial),
            (inner, Projection::NormalOnto(e)),
        ] {
            let chart = RegionChart::with_projection(
                0,
                &chart_e,
                std::slice::from_ref(&cap),
                projection,
                PoleWalk::Free,
            )
            .unwrap();
            assert_eq!(chart.known.0.len(), cap.len());
            // The same ellipsoid and projection, no table.
            let fresh = RegionChart {
                projection,
                ..RegionChart::with_pole(&chart_e, DVec3::Z)
            };
            assert!(fresh.known.0.is_empty());
            for &p in cap.iter().chain([&other]) {
                let (kept, made) = (chart.to_sphere(p), fresh.to_sphere(p));
                assert_eq!(
                    kept.to_array().map(f64::to_bits),
                    made.to_array().map(f64::to_bits)
                );
            }
        }
    }

    #[test]
    fn boundary_distance_equals_the_nearest_arc_by_angle() {
        let mut rng = SplitMix64::new(23);
        for _ in 0..200 {
            let loops: Vec<Vec<DVec3>> = (0..2)
                .map(|_| (0..7).map(|_| rng.unit_vector()).collect())
                .collect();
            let c = rng.unit_vector();
            let reference = loops
                .iter()
                .flat_map(|l| (0..l.len()).map(move |i| (l[i], l[(i + 1) % l.len()])))
                .map(|(a, b)| arc_distance(c, a, b))
                .fold(f64::INFINITY, f64::min);
            let edges = SphereEdges::new(&loops);
            let fast = edges.distance(c);
            assert!((fast - reference).abs() < 1e-12, "{fast} vs {reference}");
            // Wherever the scan starts: the same distance, and an edge that near (edges
            // that meet at the nearest point tie), or, below a floor, a value at most the
            // floor.
            for start in 0..=edges.edges.len() {
                let (d, nearest) = edges.distance_beyond(c, f64::NEG_INFINITY, start);
                assert_eq!(d, fast);
                let (a, b, _) = edges.edges[nearest];
                assert!((arc_distance(c, a, b) - fast).abs() < 1e-12);
                for floor in [0.5 * fast, 2.0 * fast] {
                    let (d, _) = edges.distance_beyond(c, floor, start);
                    assert!(if floor < fast { d == fast } else { d <= floor });
                    // Whatever edges are tried first.
                    let blockers = [start % 14, (start + 5) % 14, 99];
                    let (e, _) = edges.distance_beyond_blocked(c, floor, start, &blockers);
                    assert_eq!(e, d);
                }
            }
        }
        // Tiny distances keep their precision.
        let a = DVec3::X;
        let b = DVec3::new(0.0, 1.0, 0.0);
        let c = DVec3::new(1.0, 1.0, 1e-9).normalize();
        let d = SphereEdges::new(&[vec![a, b, DVec3::new(0.0, 0.0, -1.0)]]).distance(c);
        assert!((d - arc_distance(c, a, b)).abs() < 1e-20, "{d}");
    }

    use super::*;
    use crate::rng::SplitMix64;

    fn tilted(sign: Sign) -> Ellipsoid {
        Ellipsoid {
            center: DVec3::new(0.3, -1.0, 2.0),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.4),
            radii: DVec3::new(2.0, 0.5, 1.0),
            sign,
        }
    }

    /// `n` unit directions on the circle at angle `half_angle` around `axis`, counter-clockwise
    /// seen from outside above `axis` (the cap around `axis` on the left) unless `clockwise`.
    fn circle(axis: DVec3, half_angle: f64, n: usize, clockwise: bool) -> Vec<DVec3> {
        let a = axis.normalize();
        let t1 = a.any_orthonormal_pair().0;
        let t2 = a.cross(t1);
        let mut out: Vec<DVec3> = (0..n)
            .map(|i| {
                let phi = std::f64::consts::TAU * i as f64 / n as f64;
                a * half_angle.cos() + (t1 * phi.cos() + t2 * phi.sin()) * half_angle.sin()
            })
            .collect();
        if clockwise {
            out.reverse();
        }
        out
    }

    /// Unit directions → points near the ellipsoid (radially off by up to ±0.1%).
    fn on_ellipsoid(e: &Ellipsoid, dirs: &[DVec3], rng: &mut SplitMix64) -> Vec<DVec3> {
        dirs.iter()
            .map(|&u| e.from_unit_sphere(u * rng.range_f64(0.999, 1.001)))
            .collect()
    }

    #[test]
    fn plane_round_trip_is_exact_to_rounding() {
        let e = tilted(Sign::Positive);
        let chart = RegionChart::with_pole(&e, DVec3::new(1.0, 2.0, -0.5));
        let mut rng = SplitMix64::new(7);
        for _ in 0..1000 {
            let u = rng.unit_vector();
            let p = e.from_unit_sphere(u);
            let back = chart.from_plane(chart.to_plane(p));
            assert!((back - p).length() < 1e-9, "{p} → {back}");
        }
    }

    /// A cap bounded by a circle of latitude (local z = cos θ), both loop directions, both
    /// signs, small and large caps: `contains` agrees with the analytic answer for 4000 random
    /// points (at radial scales 0.5–2) outside a band of ±0.01 rad around the circle; the pole
    /// lies in the complement, at least 95% as far from the circle as the best pole.
    #[test]
    fn cap_regions_match_the_analytic_answer() {
        let mut rng = SplitMix64::new(11);
        for sign in [Sign::Positive, Sign::Negative] {
            let e = tilted(sign);
            for theta in [0.3f64, 1.2, 2.0, 2.8] {
                for reversed in [false, true] {
                    let dirs = circle(DVec3::Z, theta, 200, reversed);
                    let points = on_ellipsoid(&e, &dirs, &mut rng);
                    let chart = RegionChart::new(0, &e, &[points]).unwrap();
                    // Counter-clockwise around +z seen from outside: the cap z > cos θ is on
                    // the left; reversing the loop or the sign (mesh normal inward) swaps.
                    let cap = reversed == (sign == Sign::Negative);
                    let in_region = |u: DVec3| (angle_between(u, DVec3::Z) < theta) == cap;
                    let pole = chart.pole();
                    assert!(!in_region(pole), "sign {sign:?} θ {theta} rev {reversed}");
                    let region_radius = if cap {
                        theta
                    } else {
                        std::f64::consts::PI - theta
                    };
                    let best = std::f64::consts::PI - region_radius;
                    assert!(
                        chart.clearance() >= 0.95 * best,
                        "clearance {} best {best}",
                        chart.clearance()
                    );
                    // The outer loop runs counter-clockwise in the plane.
                    assert!(doubled_signed_area(chart.plane_loops()[0].iter().copied()) > 0.0);
                    let mut checked = 0;
                    for _ in 0..4000 {
                        let u = rng.unit_vector();
                        if (angle_between(u, DVec3::Z) - theta).abs() < 0.01 {
                            continue;
                        }
                        checked += 1;
                        let p = e.from_unit_sphere(u * rng.range_f64(0.5, 2.0));
                        assert_eq!(chart.contains(p), in_region(u), "{u}");
                    }
                    assert!(checked > 3900);
                }
            }
        }
    }

    /// A sphere with three circular holes (half-angles 0.5, 0.3, 0.4 rad): the pole goes into
    /// the biggest hole, within 0.02 rad of its centre; `contains` is exact outside ±0.01 rad
    /// bands. Then a region covering 95% of the sphere (one hole of 5% of the area).
    #[test]
    fn regions_with_holes_put_the_pole_in_the_biggest_hole() {
        let mut rng = SplitMix64::new(12);
        let e = tilted(Sign::Positive);
        let holes = [(DVec3::Z, 0.5), (-DVec3::Z, 0.3), (DVec3::X, 0.4)];
        let loops: Vec<Vec<DVec3>> = holes
            .iter()
            .map(|&(axis, angle)| on_ellipsoid(&e, &circle(axis, angle, 150, true), &mut rng))
            .collect();
        let chart = RegionChart::new(3, &e, &loops).unwrap();
        assert!(
            angle_between(chart.pole(), DVec3::Z) < 0.02,
            "{}",
            chart.pole()
        );
        assert!(chart.clearance() > 0.48);
        let mut checked = 0;
        for _ in 0..4000 {
            let u = rng.unit_vector();
            let d: Vec<f64> = holes
                .iter()
                .map(|&(a, angle)| angle_between(u, a) - angle)
                .collect();
            if d.iter().any(|x| x.abs() < 0.01) {
                continue;
            }
            checked += 1;
            let inside = d.iter().all(|&x| x > 0.0);
            assert_eq!(chart.contains(e.from_unit_sphere(u)), inside, "{u}");
        }
        assert!(checked > 3800);

        // 95%: a hole of area 0.05 · 4π is a cap with 1 − cos θ = 0.1.
        let axis = DVec3::new(1.0, -2.0, 0.5).normalize();
        let theta = 0.9f64.acos();
        let hole = on_ellipsoid(&e, &circle(axis, theta, 100, true), &mut rng);
        let chart = RegionChart::new(4, &e, &[hole]).unwrap();
        assert!(angle_between(chart.pole(), axis) < 0.02);
        let mut inside = 0;
        for _ in 0..4000 {
            let u = rng.unit_vector();
            let a = angle_between(u, axis);
            if (a - theta).abs() < 0.01 {
                continue;
            }
            assert_eq!(chart.contains(e.from_unit_sphere(u)), a > theta);
            inside += usize::from(a > theta);
        }
        // About 95% of the points, give or take 1.5% (binomial σ ≈ 0.35%).
        assert!((3740..=3860).contains(&inside), "{inside}");
    }

    /// A boundary of 30 000 points (beyond the scoring subsample): the pole is still in the
    /// complement, within 5% of the best clearance, and `contains` is exact outside a ±0.005
    /// rad band.
    #[test]
    fn long_boundaries_are_scored_on_a_subsample() {
        let mut rng = SplitMix64::new(15);
        let e = tilted(Sign::Positive);
        let axis = DVec3::new(0.3, 0.4, -1.0).normalize();
        let loop_points = on_ellipsoid(&e, &circle(axis, 1.0, 30_000, false), &mut rng);
        let chart = RegionChart::new(0, &e, &[loop_points]).unwrap();
        let best = std::f64::consts::PI - 1.0;
        assert!(chart.clearance() >= 0.95 * best && chart.clearance() <= best + 1e-6);
        assert!(angle_between(chart.pole(), -axis) < 0.05 * best);
        for _ in 0..2000 {
            let u = rng.unit_vector();
            let a = angle_between(u, axis);
            if (a - 1.0).abs() > 0.005 {
                assert_eq!(chart.contains(e.from_unit_sphere(u)), a < 1.0);
            }
        }
    }

    #[test]
    fn no_loops_is_the_whole_ellipsoid() {
        let e = tilted(Sign::Negative);
        let chart = RegionChart::new(0, &e, &[]).unwrap();
        assert!(chart.is_whole());
        let mut rng = SplitMix64::new(13);
        for _ in 0..100 {
            assert!(chart.contains(e.from_unit_sphere(rng.unit_vector())));
        }
        assert!(chart.contains(e.center));
        assert!(!chart.contains(DVec3::NAN));
    }

    #[test]
    fn hostile_loops_give_typed_errors() {
        let e = tilted(Sign::Positive);
        let good = circle(DVec3::Z, 1.0, 20, false)
            .iter()
            .map(|&u| e.from_unit_sphere(u))
            .collect::<Vec<_>>();
        let region_error = |loops: &[Vec<DVec3>]| match RegionChart::new(5, &e, loops) {
            Err(RemeshError::Region { region: 5, what }) => what,
            other => panic!("expected a region error, got {other:?}"),
        };
        let mut nan = good.clone();
        nan[3].y = f64::NAN;
        assert!(region_error(&[good.clone(), nan]).contains("not finite"));
        let mut inf = good.clone();
        inf[0].x = f64::INFINITY;
        assert!(region_error(&[inf]).contains("not finite"));
        assert!(region_error(&[good[..2].to_vec()]).contains("fewer than 3"));
        assert!(region_error(&[vec![good[0]; 10]]).contains("fewer than 3"));
        assert!(region_error(&[vec![]]).contains("fewer than 3"));
        // Three pool points on one normal line of the surface reach it at one point.
        let foot = e.from_unit_sphere(DVec3::X);
        let normal = e.outward_normal(foot);
        let line = [0.01, 0.02, 0.03].map(|s| foot + normal * s).to_vec();
        assert!(region_error(&[line]).contains("fewer than 3"));
        // Back and forth along a path: distinct points, yet the loop encloses nothing.
        let path = circle(DVec3::Z, 1.0, 20, false)[..10]
            .iter()
            .map(|&u| e.from_unit_sphere(u))
            .collect::<Vec<_>>();
        let there_and_back: Vec<DVec3> = path
            .iter()
            .chain(path.iter().rev().skip(1))
            .copied()
            .collect();
        match RegionChart::new(5, &e, &[there_and_back]) {
            Ok(chart) => assert!(chart.clearance() >= MIN_CLEARANCE),
            Err(RemeshError::Region { region: 5, .. }) => {}
            Err(other) => panic!("{other}"),
        }
        // Huge but finite coordinates, and a broken ellipsoid.
        let huge = vec![
            DVec3::splat(1e308),
            DVec3::new(-1e308, 1e308, 0.0),
            DVec3::X,
        ];
        let _ = RegionChart::new(5, &e, &[huge]);
        let mut bad = e;
        bad.radii.x = 0.0;
        assert!(matches!(
            RegionChart::new(5, &bad, &[good]),
            Err(RemeshError::Region { .. })
        ));
    }

    #[test]
    fn edge_index_agrees_with_a_plain_even_odd_scan() {
        let mut rng = SplitMix64::new(14);
        // A star polygon with a hole, 400 points.
        let star: Vec<DVec2> = (0..300)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 300.0;
                let r = 1.0 + 0.4 * (7.0 * a).sin();
                DVec2::new(r * a.cos(), r * a.sin())
            })
            .collect();
        let hole: Vec<DVec2> = (0..100)
            .rev()
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 100.0;
                DVec2::new(0.1 + 0.3 * a.cos(), 0.3 * a.sin())
            })
            .collect();
        let loops = vec![star, hole];
        let index = EdgeIndex::new(&loops);
        assert!(index.slabs > 1);
        let plain = |q: DVec2| {
            let mut inside = false;
            for l in &loops {
                for (i, &a) in l.iter().enumerate() {
                    let b = l[(i + 1) % l.len()];
                    if (a.y > q.y) != (b.y > q.y)
                        && q.x < a.x + (q.y - a.y) * (b.x - a.x) / (b.y - a.y)
                    {
                        inside = !inside;
                    }
                }
            }
            inside
        };
        let mut inside = 0;
        for _ in 0..20_000 {
            let q = DVec2::new(rng.range_f64(-1.6, 1.6), rng.range_f64(-1.6, 1.6));
            assert_eq!(index.contains(q), plain(q), "{q}");
            inside += usize::from(plain(q));
        }
        assert!(inside > 2000 && inside < 18_000);
    }

    /// A region that is its ellipsoid but for a small triangular hole (a hundredth of a
    /// radian to a tenth across, as a face of a finely tessellated mesh): kept from
    /// crossing the boundary, the pole stays in the hole and the chart holds the rest.
    #[test]
    fn a_pole_kept_from_crossing_the_boundary_stays_in_a_small_hole() {
        let e = Ellipsoid {
            center: DVec3::new(0.2, -0.1, 0.3),
            rotation: DQuat::from_rotation_y(0.4),
            radii: DVec3::new(1.0, 0.6, 0.8),
            sign: Sign::Positive,
        };
        let axis = DVec3::new(0.3, 1.0, -0.2).normalize();
        let (t1, t2) = axis.any_orthonormal_pair();
        for size in [0.01, 0.04, 0.1] {
            // An obtuse triangle, region on the left seen from outside: clockwise about
            // the axis.
            let corners: Vec<DVec3> = [(0.0, 1.0), (2.2, 0.3), (4.0, 1.2)]
                .iter()
                .map(|&(angle, r): &(f64, f64)| {
                    let (sin, cos) = angle.sin_cos();
                    (axis + size * r * (t1 * cos - t2 * sin)).normalize()
                })
                .collect();
            let hole: Vec<DVec3> = corners.iter().map(|&u| e.from_unit_sphere(u)).collect();
            let chart = RegionChart::with_projection(
                0,
                &e,
                &[hole],
                Projection::Closest,
                PoleWalk::Uncrossed,
            )
            .unwrap();
            let inside_hole = corners.iter().sum::<DVec3>().normalize();
            assert!(!chart.contains(e.from_unit_sphere(inside_hole)), "{size}");
            assert!(chart.contains(e.from_unit_sphere(-axis)), "{size}");
            assert!(chart.contains(e.from_unit_sphere(t1)), "{size}");
        }
    }

    /// A hole of three corners with edges of 58°, 64° and 88° (the opening of a small box
    /// in `snowden.obj`, region 10): the pole lies in the hole as its great-circle edges bound
    /// it, not just beyond its longest edge, where the chords between the projected corners
    /// put it before the long edges were split (40° into the region).
    #[test]
    fn a_pole_stays_in_a_hole_of_long_edges() {
        for sign in [Sign::Positive, Sign::Negative] {
            let e = tilted(sign);
            // Seen from outside, the region on the loop's left (inside it, negative).
            let mut corners = [
                DVec3::new(0.677, 0.729, -0.105),
                DVec3::new(0.751, -0.659, -0.027),
                DVec3::new(0.732, 0.009, 0.681),
            ]
            .map(DVec3::normalize);
            if sign == Sign::Negative {
                corners.reverse();
            }
            let hole: Vec<DVec3> = corners.iter().map(|&u| e.from_unit_sphere(u)).collect();
            let chart = RegionChart::new(10, &e, &[hole]).unwrap();
            // In the hole: on the corners' side of every edge's great circle.
            let pole = chart.pole();
            let mut centre = DVec3::ZERO;
            for i in 0..3 {
                let (a, b, c) = (corners[i], corners[(i + 1) % 3], corners[(i + 2) % 3]);
                let n = a.cross(b);
                assert!(n.dot(pole) * n.dot(c) > 0.0, "{sign:?}: pole {pole}");
                centre += c;
            }
            // The incircle's radius is about 0.37 rad.
            assert!(chart.clearance() > 0.3, "{}", chart.clearance());
            assert!(!chart.contains(e.from_unit_sphere(centre.normalize())));
            assert!(chart.contains(e.from_unit_sphere(-centre.normalize())));
        }
    }

    /// [`AreaLoops`] splits each long edge into pieces of at most [`MAX_AREA_EDGE`] along its
    /// great circle, reversed as the plane loops are; a boundary of thousands of edges of 170°
    /// (a hostile file's) gets at most [`MAX_AREA_PIECES`] more points.
    #[test]
    fn area_loops_follow_the_arcs_within_a_budget() {
        let corners = [DVec3::X, DVec3::Y, DVec3::new(0.0, 0.6, 0.8)];
        let area = AreaLoops::new(&[corners.to_vec()]);
        let l = &area.loops[0];
        // Reversed, from the last corner: edges of 53.13°, 90° and 90°, in 10, 16 and 16
        // pieces.
        assert_eq!(l.len(), 10 + 16 + 16);
        assert_eq!(l[0], corners[2]);
        let mut corner_at = vec![0];
        for (k, &u) in l.iter().enumerate() {
            assert!((u.length() - 1.0).abs() < 1e-12);
            let next = l[(k + 1) % l.len()];
            assert!(angle_between(u, next) <= MAX_AREA_EDGE + 1e-12);
            if corners.contains(&u) && k > 0 {
                corner_at.push(k);
            }
        }
        // The corners in reverse order, each piece on its edge's great circle.
        assert_eq!(corner_at, [0, 10, 26]);
        assert_eq!(l[10], corners[1]);
        assert_eq!(l[26], corners[0]);
        for (from, to, (a, b)) in [
            (0, 10, (corners[2], corners[1])),
            (10, 26, (corners[1], corners[0])),
            (26, 42, (corners[0], corners[2])),
        ] {
            let n = a.cross(b).normalize();
            for &u in &l[from..to] {
                assert!(u.dot(n).abs() < 1e-12);
            }
        }

        for n in [2_000, 20_000] {
            let zigzag: Vec<DVec3> = (0..n)
                .map(|i| {
                    let phi = std::f64::consts::TAU * i as f64 / n as f64;
                    let lat: f64 = if i % 2 == 0 { 1.48 } else { -1.48 };
                    DVec3::new(phi.cos() * lat.cos(), phi.sin() * lat.cos(), lat.sin())
                })
                .collect();
            let area = AreaLoops::new(&[zigzag]);
            let added = area.loops[0].len() - n;
            // 2 000 edges: pieces of 1.45 rad, three an edge.
            assert!(added <= MAX_AREA_PIECES as usize, "{n}: {added}");
            assert_eq!(added > 0, n == 2_000, "{n}: {added}");
        }
    }
}
