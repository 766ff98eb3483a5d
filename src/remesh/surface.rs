//! A region's surface as the decoder meshes it: a point of the chart's plane → the chart's
//! ellipsoid → the region's own ellipsoid → plus the boundary's offsets, blended in near the
//! boundary.
//!
//! The paper places every interior vertex on the region's ellipsoid (section 5.3) and keeps
//! the stored boundary points where they are. On real meshes the two disagree: an ellipsoid
//! fitted to a whole region passes a few tenths of a percent to a few percent of the
//! diagonal from the region's boundary (the surface bends away from the fit where it meets
//! its neighbours). Meshed literally, the gap is closed by a fringe of triangles that climb
//! from the ellipsoid to the boundary within one edge length; as the budget grows those
//! triangles stand up, and the first one to lean past the vertical faces against its
//! ellipsoid (a flipped triangle). Vertex addition makes it worse, since the fringe is where
//! the faces are farthest from the ellipsoid, so that is where it keeps inserting.
//!
//! So the surface a region is meshed on is its ellipsoid displaced, near the boundary, by
//! the boundary's own offsets ([`OffsetBlend`]): each boundary point's *foot* is where its
//! chart position lands on the ellipsoid and its *offset* is its signed height above the
//! foot along the ellipsoid's outward normal; an interior point x gets the offsets of the
//! nearby boundary interpolated (inverse-distance weighting over the boundary's segments,
//! which is exact on the boundary), faded out with a smoothstep over a band [`BLEND_REACH`]
//! times as wide as that offset (never narrower than the mesh's target edge length), and is
//! moved that far along the normal at x. Heights, not vectors: offsets from opposite sides
//! of a curved region point different ways, and blending them as vectors would shear the
//! surface sideways until it folds. The displaced surface meets every boundary point whose
//! foot is its closest point on the ellipsoid (the decoder's default chart) exactly, leaves
//! it parallel to the ellipsoid, and rises or falls to it with a slope of at most about
//! 1.5 / [`BLEND_REACH`] (0.5, 27°), whatever the budget; beyond the band it is the
//! ellipsoid itself. Both regions along an arc blend to the same
//! points, so the mesh stays watertight, and the crease along the arc is the angle between
//! the two ellipsoids there.

use super::chart::RegionChart;
use crate::ellipsoid::Ellipsoid;
use glam::{DVec2, DVec3};
use std::cell::RefCell;

/// How wide, in multiples of the offset it fades, the band is over which a boundary point's
/// offset blends into the ellipsoid: the displaced surface's slope against the ellipsoid is
/// at most about 1.5 / `BLEND_REACH` (the smoothstep's steepest slope over the band).
pub const BLEND_REACH: f64 = 3.0;

/// How an interior point of the chart's surface reaches the region's ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lift {
    /// The chart is on the region's ellipsoid: nothing to do.
    None,
    /// The chart is on a stand-in with the region's centre: along the ray from the centre
    /// onto this ellipsoid (the region's own).
    Radial(Ellipsoid),
    /// The chart is on a stand-in inside this ellipsoid (the region's own): to the closest
    /// point on it.
    Closest(Ellipsoid),
    /// The chart is on a sphere seen from `origin`: along the ray from `origin`, the
    /// crossing with this ellipsoid nearest to the chart's point.
    FromPoint {
        /// Where the rays start.
        origin: DVec3,
        /// The region's own ellipsoid.
        ellipsoid: Ellipsoid,
    },
}

impl Lift {
    /// `p`, a point of the chart's surface, on the region's ellipsoid.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        match *self {
            Lift::None => p,
            Lift::Radial(e) => e.project_radially(p),
            Lift::Closest(e) => e.closest_point(p),
            Lift::FromPoint { origin, ellipsoid } => {
                let best = ellipsoid.intersect_ray(origin, p - origin).and_then(|ts| {
                    ts.into_iter()
                        .filter(|t| *t > 0.0)
                        .min_by(|a, b| (a - 1.0).abs().total_cmp(&(b - 1.0).abs()))
                });
                best.map_or(p, |t| origin + t * (p - origin))
            }
        }
    }
}

/// The surface one region (or piece of one) is meshed on: see the module documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionSurface {
    /// The chart: plane ↔ the chart's ellipsoid, and the region's boundary in the plane.
    pub chart: RegionChart,
    lift: Lift,
    blend: OffsetBlend,
}

impl RegionSurface {
    /// The surface of `chart`'s own ellipsoid, without offsets.
    pub fn new(chart: RegionChart) -> RegionSurface {
        RegionSurface::lifted(chart, Lift::None)
    }

    /// The chart's surface carried onto the region's ellipsoid by `lift`, without offsets.
    pub fn lifted(chart: RegionChart, lift: Lift) -> RegionSurface {
        RegionSurface {
            chart,
            lift,
            blend: OffsetBlend::default(),
        }
    }

    /// The same surface with the heights of `boundary` (the points `loops` index, closed
    /// loops without the first point repeated) above the ellipsoid blended in over bands at
    /// least `min_band` wide. Loop indices out of range are skipped.
    pub fn with_offsets(
        self,
        boundary: &[DVec3],
        loops: &[Vec<u32>],
        min_band: f64,
    ) -> RegionSurface {
        let e = self.ellipsoid();
        let feet: Vec<DVec3> = boundary
            .iter()
            .map(|&b| self.on_ellipsoid(self.chart.to_plane(b)))
            .collect();
        let heights: Vec<f64> = boundary
            .iter()
            .zip(&feet)
            .map(|(&b, &f)| (b - f).dot(e.outward_normal(f)))
            .collect();
        let blend = OffsetBlend::new(&feet, &heights, loops, min_band);
        RegionSurface { blend, ..self }
    }

    /// The region's own ellipsoid (the chart's, unless the chart is on a stand-in).
    pub fn ellipsoid(&self) -> &Ellipsoid {
        match &self.lift {
            Lift::None => &self.chart.ellipsoid,
            Lift::Radial(e) | Lift::Closest(e) | Lift::FromPoint { ellipsoid: e, .. } => e,
        }
    }

    /// The point of the region's ellipsoid at chart position `q` (no offsets).
    pub fn on_ellipsoid(&self, q: DVec2) -> DVec3 {
        self.lift.apply(self.chart.from_plane(q))
    }

    /// The point of the surface at chart position `q`: on the ellipsoid, moved along its
    /// outward normal by the blended boundary height there.
    pub fn point(&self, q: DVec2) -> DVec3 {
        self.point_and_height(q).0
    }

    /// [`RegionSurface::point`] and the height it was moved by.
    pub fn point_and_height(&self, q: DVec2) -> (DVec3, f64) {
        let (point, height, _) = self.point_height_and_clearance(q, |_| f64::NEG_INFINITY);
        (point, height)
    }

    /// [`RegionSurface::point_and_height`], given a lower bound on the distance from the
    /// ellipsoid's point at `q` to the boundary's feet (`clearance_of` of that point, e.g.
    /// from nearby points' clearances by the triangle inequality), with such a bound for
    /// the point itself ([`OffsetBlend::height_and_clearance`]). The same point and height.
    pub fn point_height_and_clearance(
        &self,
        q: DVec2,
        clearance_of: impl FnOnce(DVec3) -> f64,
    ) -> (DVec3, f64, f64) {
        let x = self.on_ellipsoid(q);
        let (h, clearance) = self.blend.height_and_clearance(x, clearance_of(x));
        (self.raise(x, h), h, clearance)
    }

    /// The point at chart position `q` raised by `height` along the ellipsoid's outward
    /// normal (the surface itself where `height` is the blended height there).
    pub fn at_height(&self, q: DVec2, height: f64) -> DVec3 {
        self.raise(self.on_ellipsoid(q), height)
    }

    /// How far `p`, a point whose chart position is `q`, lies above the ellipsoid along its
    /// outward normal there.
    pub fn height_of(&self, q: DVec2, p: DVec3) -> f64 {
        let x = self.on_ellipsoid(q);
        (p - x).dot(self.ellipsoid().outward_normal(x))
    }

    fn raise(&self, x: DVec3, height: f64) -> DVec3 {
        if height == 0.0 {
            return x;
        }
        x + height * self.ellipsoid().outward_normal(x)
    }
}

/// Boundary heights blended into a region's interior (see the module documentation).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct OffsetBlend {
    /// The boundary's segments: feet (on the ellipsoid) and heights of both ends.
    segments: Vec<Segment>,
    /// Narrowest band.
    min_band: f64,
    /// Widest band anywhere ([`BLEND_REACH`] times the largest height, at least
    /// `min_band`): beyond it from every foot the height is zero.
    max_band: f64,
    /// Segments nearer than this to a point are the ones its height is blended from
    /// ([`WEIGHT_REACH`] times the widest band), their weights tapered to zero at it.
    reach: f64,
    /// Side of the cubic cells the segments are bucketed by: at least `reach` /
    /// [`CELL_FILL`] (more where the columns below would outnumber
    /// [`MAX_COLUMNS_PER_SEGMENT`] per segment).
    side: f64,
    /// The segments by the cells they pass through, column by column (a column: the cells
    /// with the same x and y), each column sorted by z then segment: the cell's z and the
    /// segment. A point's segments lie in its cell and the 26 around it.
    cells: Vec<(i64, u32)>,
    /// The columns the segments' cells span, x then y, from `first_column`: where each one
    /// starts in `cells` (and, last, the end), so that a point's nine columns are found
    /// without a search.
    column_starts: Vec<u32>,
    /// The x and y of the lowest column.
    first_column: [i64; 2],
    /// How many columns along y.
    columns_y: i64,
}

thread_local! {
    /// One bit per segment of the blend [`OffsetBlend::height`] is asked of: the segments
    /// near the point, in increasing order without sorting them (all clear between calls).
    static NEAR: RefCell<Vec<u64>> = const { RefCell::new(Vec::new()) };
}

/// Most cell entries of a blend beyond four per segment: a boundary far longer than its
/// region's bands (hostile files) gets larger cells instead of more entries.
const MAX_CELL_ENTRIES: f64 = (1u64 << 20) as f64;

/// How far, in widest bands, a segment still weighs in a point's height.
const WEIGHT_REACH: f64 = 2.0;

/// Most columns of cells ([`OffsetBlend::column_starts`]) per boundary segment: a
/// boundary that spans far more than its bands (a large region with thin offsets) gets
/// larger cells instead of more columns.
const MAX_COLUMNS_PER_SEGMENT: f64 = 64.0;

/// Columns any blend may have, whatever its segment count.
const MIN_COLUMN_CAP: f64 = 4096.0;

/// Most columns of any blend (16 MiB of column starts).
const MAX_COLUMN_CAP: f64 = (1u64 << 22) as f64;

/// The reach over a cell's side. A segment's point within the reach of a query is within
/// a quarter cell of a sample the segment was bucketed by (samples a quarter cell apart),
/// so that sample's cell is the query's or a neighbour of it.
const CELL_FILL: f64 = 0.75;

#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    foot: [DVec3; 2],
    height: [f64; 2],
    /// `foot[1] - foot[0]`, its squared length and its length: computed once, not per
    /// query (a query weighs tens of segments).
    along: DVec3,
    length2: f64,
    length: f64,
}

impl Segment {
    fn new(foot: [DVec3; 2], height: [f64; 2]) -> Segment {
        let along = foot[1] - foot[0];
        let length2 = along.length_squared();
        Segment {
            foot,
            height,
            along,
            length2,
            length: length2.sqrt(),
        }
    }
}

impl OffsetBlend {
    /// The blend of `heights` at `feet` along `loops` (see [`RegionSurface::with_offsets`]).
    /// Empty (zero height everywhere) when every height is zero or an input is not finite.
    pub fn new(feet: &[DVec3], heights: &[f64], loops: &[Vec<u32>], min_band: f64) -> Self {
        let longest = heights.iter().map(|h| h.abs()).fold(0.0, f64::max);
        // Offsets at rounding level (points computed on the ellipsoid) blend nothing.
        let usable = longest > 1e-9 * min_band
            && longest.is_finite()
            && min_band.is_finite()
            && min_band >= 0.0
            && feet.iter().all(|f| f.is_finite());
        if !usable {
            return OffsetBlend::default();
        }
        let mut segments = Vec::new();
        for lp in loops {
            let ends = |k: usize| -> Option<(DVec3, f64)> {
                let i = *lp.get(k)? as usize;
                Some((*feet.get(i)?, *heights.get(i)?))
            };
            for k in 0..lp.len() {
                let (Some((fa, oa)), Some((fb, ob))) = (ends(k), ends((k + 1) % lp.len())) else {
                    continue;
                };
                segments.push(Segment::new([fa, fb], [oa, ob]));
            }
        }
        let max_band = (BLEND_REACH * longest).max(min_band);
        let reach = WEIGHT_REACH * max_band;
        let length: f64 = segments.iter().map(|s| s.length).sum();
        let (lo, hi) = feet.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &f| (lo.min(f), hi.max(f)),
        );
        let cap =
            (MAX_COLUMNS_PER_SEGMENT * segments.len() as f64).clamp(MIN_COLUMN_CAP, MAX_COLUMN_CAP);
        let columns_at =
            |side: f64| ((hi.x - lo.x) / side + 2.0).floor() * ((hi.y - lo.y) / side + 2.0).floor();
        let mut side = (reach / CELL_FILL).max(4.0 * length / MAX_CELL_ENTRIES);
        // Larger cells gather more segments beyond the reach, which the height skips: the
        // result does not change. A few steps close to the cap, then a side that meets it
        // surely (each factor of the count at most √cap).
        for _ in 0..4 {
            let columns = columns_at(side);
            if columns <= cap {
                break;
            }
            side *= (columns / cap).sqrt().max(1.01);
        }
        if columns_at(side) > cap {
            side = side.max((hi.x - lo.x).max(hi.y - lo.y) / (cap.sqrt() - 2.0));
        }
        if !(side.is_finite() && side > 0.0 && columns_at(side) <= cap) {
            return OffsetBlend::default();
        }
        let mut keyed = Vec::new();
        for (index, s) in segments.iter().enumerate() {
            let [a, b] = s.foot;
            // Samples a quarter cell apart.
            let steps = ((a.distance(b) / (0.25 * side)).ceil()).max(1.0) as usize;
            let mut last = None;
            for k in 0..=steps {
                let key = cell_of(a.lerp(b, k as f64 / steps as f64), side);
                if last != Some(key) {
                    keyed.push((key, index as u32));
                    last = Some(key);
                }
            }
        }
        keyed.sort_unstable();
        keyed.dedup();
        // Every key lies within the feet's box, so within the columns counted above.
        let (first, last) = (cell_of(lo, side), cell_of(hi, side));
        let columns_y = last[1] - first[1] + 1;
        let columns = ((last[0] - first[0] + 1) * columns_y) as usize;
        let mut column_starts = Vec::with_capacity(columns + 1);
        let mut next = 0;
        for column in 0..columns as i64 {
            let (x, y) = (first[0] + column / columns_y, first[1] + column % columns_y);
            next += keyed[next..]
                .iter()
                .take_while(|(k, _)| (k[0], k[1]) < (x, y))
                .count();
            column_starts.push(next as u32);
        }
        column_starts.push(keyed.len() as u32);
        OffsetBlend {
            segments,
            min_band,
            max_band,
            reach,
            side,
            cells: keyed.into_iter().map(|(k, s)| (k[2], s)).collect(),
            column_starts,
            first_column: [first[0], first[1]],
            columns_y,
        }
    }

    /// The entries of column (`x`, `y`) with z from `z - 1` to `z + 1`: a range of
    /// `cells` (empty outside the columns).
    fn run(&self, x: i64, y: i64, z: i64) -> (usize, usize) {
        let (cx, cy) = (x - self.first_column[0], y - self.first_column[1]);
        if cx < 0 || cy < 0 || cy >= self.columns_y {
            return (0, 0);
        }
        let column = (cx * self.columns_y + cy) as usize;
        let (Some(&from), Some(&to)) = (
            self.column_starts.get(column),
            self.column_starts.get(column + 1),
        ) else {
            return (0, 0);
        };
        let (from, to) = (from as usize, to as usize);
        let entries = &self.cells[from..to];
        (
            from + entries.partition_point(|&(k, _)| k < z - 1),
            from + entries.partition_point(|&(k, _)| k <= z + 1),
        )
    }

    /// The height at `x`, a point on the ellipsoid: the heights of the boundary segments
    /// within the reach of `x`, weighted by the inverse cube of their distance to `x` (each
    /// segment's height taken at its point nearest to `x`, its weight scaled by its length
    /// and tapered to zero at the reach), faded by a smoothstep over [`BLEND_REACH`] times
    /// that height (at least the minimum band) from the nearest foot. Exact at the feet;
    /// zero beyond the widest band.
    pub fn height(&self, x: DVec3) -> f64 {
        self.height_and_clearance(x, f64::NEG_INFINITY).0
    }

    /// [`OffsetBlend::height`] at `x`, given `clearance`, a lower bound on the distance from
    /// `x` to the boundary's feet (minus infinity when none is known), and such a bound for
    /// `x` found on the way (the nearest foot's distance, at most the reach). Where the
    /// bound is at least the widest band the height is zero, found without a search: most
    /// vertex additions ask for points deep inside the region, whose neighbours' bounds
    /// less the distance to them tell so.
    pub fn height_and_clearance(&self, x: DVec3, clearance: f64) -> (f64, f64) {
        if self.segments.is_empty() {
            return (0.0, f64::INFINITY);
        }
        if !x.is_finite() {
            return (0.0, 0.0);
        }
        // A margin for the rounding of the bound's distances.
        if clearance >= self.max_band * (1.0 + CLEARANCE_MARGIN) {
            return (0.0, clearance);
        }
        let centre = cell_of(x, self.side);
        // The three cells along z of each (x, y) column are one run of entries.
        let mut runs = [(0, 0); 9];
        for (run, (dx, dy)) in runs
            .iter_mut()
            .zip((-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (dx, dy))))
        {
            *run = self.run(centre[0] + dx, centre[1] + dy, centre[2]);
        }
        if runs.iter().all(|(from, to)| from == to) {
            return (0.0, self.reach);
        }
        let mut nearest = f64::INFINITY;
        let mut weights = 0.0;
        let mut sum = 0.0;
        let mut exact = None;
        let beyond = self.reach * self.reach * (1.0 + 1e-12);
        // A segment's weight and height added in; its height when `x` lies on it.
        let mut weigh = |s: &Segment| -> Option<f64> {
            let (a, ab, length2) = (s.foot[0], s.along, s.length2);
            let t = if length2 > 0.0 {
                ((x - a).dot(ab) / length2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let d2 = (a + ab * t - x).length_squared();
            // Clearly beyond the reach, without the square root (the cells hold many such).
            if d2 > beyond {
                return None;
            }
            let d = d2.sqrt();
            let height = s.height[0] + (s.height[1] - s.height[0]) * t;
            if d <= 0.0 {
                return Some(height);
            }
            if d >= self.reach {
                return None;
            }
            nearest = nearest.min(d);
            let taper = 1.0 - (d / self.reach) * (d / self.reach);
            let w = s.length * taper * taper / (d * d * d);
            weights += w;
            sum += w * height;
            None
        };
        // The segments of the runs, each once, in increasing order (the order of the sums):
        // marked in a bitmap and read back word by word, each word cleared as it is read.
        NEAR.with_borrow_mut(|bits| {
            let words = self.segments.len().div_ceil(64);
            if bits.len() < words {
                bits.resize(words, 0);
            }
            let (mut low, mut high) = (usize::MAX, 0);
            for &(from, to) in &runs {
                for &(_, segment) in self.cells.get(from..to).unwrap_or_default() {
                    let word = segment as usize / 64;
                    if let Some(w) = bits.get_mut(word) {
                        *w |= 1 << (segment % 64);
                        (low, high) = (low.min(word), high.max(word));
                    }
                }
            }
            for word in low..=high {
                let Some(w) = bits.get_mut(word) else {
                    break;
                };
                let mut marked = std::mem::take(w);
                while marked != 0 {
                    let segment = word * 64 + marked.trailing_zeros() as usize;
                    marked &= marked - 1;
                    // Past an exact hit the rest is only cleared.
                    if exact.is_none() {
                        exact = self.segments.get(segment).and_then(&mut weigh);
                    }
                }
            }
        });
        if let Some(height) = exact {
            return (height, 0.0);
        }
        // The nearest segment within the reach, else the reach (the cells give every segment
        // nearer than it): a lower bound on the distance to every segment.
        let clearance = nearest.min(self.reach);
        if !(nearest < self.max_band && weights > 0.0 && weights.is_finite()) {
            return (0.0, clearance);
        }
        let height = sum / weights;
        let band = (BLEND_REACH * height.abs()).max(self.min_band);
        let s = (nearest / band).min(1.0);
        let out = height * (1.0 - s * s * (3.0 - 2.0 * s));
        if out.is_finite() {
            (out, clearance)
        } else {
            (0.0, clearance)
        }
    }
}

/// Relative margin by which a clearance must exceed the widest band to skip the search
/// ([`OffsetBlend::height_and_clearance`]): its distances are rounded.
const CLEARANCE_MARGIN: f64 = 1e-9;

/// The cubic cell of side `side` holding `p` (coordinates clamped far inside i64).
fn cell_of(p: DVec3, side: f64) -> [i64; 3] {
    let key = |v: f64| (v / side).floor().clamp(-1e15, 1e15) as i64;
    [key(p.x), key(p.y), key(p.z)]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square loop of feet on the plane z = 0, each `h` above it.
    fn square(h: f64) -> OffsetBlend {
        let feet = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        OffsetBlend::new(&feet, &[h; 4], &[vec![0, 1, 2, 3]], 0.01)
    }

    #[test]
    fn the_blend_is_exact_on_the_boundary_and_zero_beyond_its_band() {
        let b = square(0.1);
        for x in [DVec3::new(0.5, 0.0, 0.0), DVec3::new(1.0, 1.0, 0.0)] {
            assert!((b.height(x) - 0.1).abs() < 1e-12);
        }
        // Band: 3 × 0.1 from the nearest foot.
        assert_eq!(b.height(DVec3::new(0.5, 0.31, 0.0)), 0.0);
        let inside = b.height(DVec3::new(0.5, 0.15, 0.0));
        assert!(inside > 0.0 && inside < 0.1, "{inside}");
    }

    /// [`OffsetBlend::height`] by scanning every segment in order, without the cells.
    fn height_by_scan(b: &OffsetBlend, x: DVec3) -> f64 {
        let (mut nearest, mut weights, mut sum) = (f64::INFINITY, 0.0, 0.0);
        for s in &b.segments {
            let [p, q] = s.foot;
            let pq = q - p;
            let t = ((x - p).dot(pq) / pq.length_squared()).clamp(0.0, 1.0);
            let d = (p + pq * t - x).length();
            let height = s.height[0] + (s.height[1] - s.height[0]) * t;
            if d <= 0.0 {
                return height;
            }
            if d < b.reach {
                nearest = nearest.min(d);
                let taper = 1.0 - (d / b.reach) * (d / b.reach);
                let w = pq.length() * taper * taper / (d * d * d);
                weights += w;
                sum += w * height;
            }
        }
        if !(nearest < b.max_band && weights > 0.0) {
            return 0.0;
        }
        let height = sum / weights;
        let band = (BLEND_REACH * height.abs()).max(b.min_band);
        let s = (nearest / band).min(1.0);
        height * (1.0 - s * s * (3.0 - 2.0 * s))
    }

    #[test]
    fn the_cells_give_the_heights_of_a_scan_of_every_segment_bit_for_bit() {
        // A loop of 200 segments, each with its own height so that the order of the sum
        // shows; the cells find the segments within the reach and visit them in order.
        let feet: Vec<DVec3> = (0..200)
            .map(|k| {
                let t = k as f64 / 200.0 * std::f64::consts::TAU;
                DVec3::new(t.cos(), t.sin(), 0.0)
            })
            .collect();
        let heights: Vec<f64> = (0..200).map(|k| 0.01 + 1e-4 * k as f64).collect();
        let blend = OffsetBlend::new(&feet, &heights, &[(0..200).collect()], 0.01);
        let mut blended = 0;
        for k in 0..400 {
            let t = 0.05 * k as f64;
            let x = (1.0 + 0.0002 * (k % 100) as f64) * DVec3::new(t.cos(), t.sin(), 0.0);
            // An exact hit on a foot between probes ends its sum early.
            assert!((blend.height(feet[k % 200]) - heights[k % 200]).abs() < 1e-12);
            let h = blend.height(x);
            blended += usize::from(h != 0.0);
            assert_eq!(h.to_bits(), height_by_scan(&blend, x).to_bits(), "{x}");
        }
        assert!(blended > 300, "{blended} of 400 probes in the band");
    }

    #[test]
    fn the_blend_rises_no_steeper_than_its_reach_allows() {
        let h = 0.05;
        let b = square(h);
        let step = 1e-4;
        let mut worst: f64 = 0.0;
        let mut y = 0.0;
        while y < 0.5 {
            let z0 = b.height(DVec3::new(0.5, y, 0.0));
            let z1 = b.height(DVec3::new(0.5, y + step, 0.0));
            worst = worst.max((z1 - z0).abs() / step);
            y += step;
        }
        assert!(worst <= 1.5 / BLEND_REACH + 1e-3, "slope {worst}");
    }

    /// The height at `x` by the formula of [`OffsetBlend::height`] summed over every
    /// segment, without the cells.
    fn brute_height(b: &OffsetBlend, x: DVec3) -> f64 {
        let (mut nearest, mut weights, mut sum) = (f64::INFINITY, 0.0, 0.0);
        for s in &b.segments {
            let [p, q] = s.foot;
            let t = ((x - p).dot(q - p) / (q - p).length_squared()).clamp(0.0, 1.0);
            let d = p.lerp(q, t).distance(x);
            if d < b.reach {
                nearest = f64::min(nearest, d);
                let taper = 1.0 - (d / b.reach).powi(2);
                let w = (q - p).length() * taper * taper / d.powi(3);
                weights += w;
                sum += w * (s.height[0] + (s.height[1] - s.height[0]) * t);
            }
        }
        if nearest >= b.max_band || weights == 0.0 {
            return 0.0;
        }
        let h = sum / weights;
        let s = (nearest / (BLEND_REACH * h.abs()).max(b.min_band)).min(1.0);
        h * (1.0 - s * s * (3.0 - 2.0 * s))
    }

    /// The cell lookup finds every segment within the reach: the height equals the same
    /// formula summed over all segments, at points around a wavy loop of short and long
    /// segments.
    #[test]
    fn the_cells_find_every_segment_a_height_is_blended_from() {
        let mut rng = crate::rng::SplitMix64::new(3);
        let feet: Vec<DVec3> = (0..60)
            .map(|k| {
                let t = std::f64::consts::TAU * (k as f64 + 0.6 * rng.next_f64()) / 60.0;
                DVec3::new(t.cos(), t.sin(), 0.1 * (3.0 * t).sin())
            })
            .collect();
        let heights: Vec<f64> = (0..60)
            .map(|k| 0.02 + 0.03 * ((k % 7) as f64 / 7.0))
            .collect();
        let lp: Vec<u32> = (0..60).filter(|k| k % 9 != 4).collect();
        let b = OffsetBlend::new(&feet, &heights, &[lp], 0.01);
        let mut blended = 0;
        for _ in 0..5000 {
            let x = DVec3::new(
                2.4 * rng.next_f64() - 1.2,
                2.4 * rng.next_f64() - 1.2,
                0.4 * rng.next_f64() - 0.2,
            );
            let (h, expected) = (b.height(x), brute_height(&b, x));
            assert!(
                (h - expected).abs() <= 1e-12 * expected.abs().max(1e-3),
                "{x}: {h} vs {expected}"
            );
            blended += usize::from(h != 0.0);
        }
        assert!(blended > 100, "{blended}");
    }

    /// A boundary far wider than its bands (a large region with thin offsets) would need
    /// millions of columns of cells as wide as the reach: the cells are made larger instead,
    /// and the heights do not change.
    #[test]
    fn a_boundary_far_wider_than_its_bands_gets_larger_cells_and_the_same_heights() {
        let mut rng = crate::rng::SplitMix64::new(5);
        let n = 40;
        let feet: Vec<DVec3> = (0..n)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / n as f64;
                DVec3::new(t.cos(), t.sin(), 0.0)
            })
            .collect();
        let heights: Vec<f64> = (0..n).map(|k| 1e-4 * (1 + k % 3) as f64).collect();
        let b = OffsetBlend::new(&feet, &heights, &[(0..n as u32).collect()], 1e-4);
        // Cells as wide as the reach (0.0018 / 0.75) would need (2 / 0.0024)² columns.
        assert!(b.side > 10.0 * b.reach / CELL_FILL, "side {}", b.side);
        assert!(b.column_starts.len() as f64 <= MIN_COLUMN_CAP + 1.0);
        let mut blended = 0;
        for _ in 0..4000 {
            // Near the polygon, within a few bands of it.
            let k = (rng.next_f64() * n as f64) as usize % n;
            let on = feet[k].lerp(feet[(k + 1) % n], rng.next_f64());
            let off = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5;
            let x = on + 0.002 * off;
            let (h, expected) = (b.height(x), brute_height(&b, x));
            assert!(
                (h - expected).abs() <= 1e-9 * expected.abs() + 1e-18,
                "{x}: {h} vs {expected}"
            );
            blended += usize::from(h != 0.0);
        }
        assert!(blended > 1000, "{blended}");
    }

    /// The clearance a height comes with is a lower bound on the distance to every segment,
    /// and a point given such a bound (here its own, and neighbours' less the distance to
    /// them) gets the same height, to the bit, as without one.
    #[test]
    fn clearances_are_lower_bounds_and_change_no_height() {
        let mut rng = crate::rng::SplitMix64::new(11);
        let n = 50;
        let feet: Vec<DVec3> = (0..n)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / n as f64;
                DVec3::new(t.cos(), t.sin(), 0.05 * (5.0 * t).cos())
            })
            .collect();
        let heights: Vec<f64> = (0..n).map(|k| 0.01 + 0.01 * (k % 4) as f64).collect();
        let b = OffsetBlend::new(&feet, &heights, &[(0..n as u32).collect()], 0.01);
        let nearest_foot = |x: DVec3| {
            b.segments
                .iter()
                .map(|s| {
                    let t = ((x - s.foot[0]).dot(s.along) / s.length2).clamp(0.0, 1.0);
                    (s.foot[0] + s.along * t).distance(x)
                })
                .fold(f64::INFINITY, f64::min)
        };
        let (mut skipped, mut blended) = (0, 0);
        for _ in 0..4000 {
            let x = DVec3::new(
                2.4 * rng.next_f64() - 1.2,
                2.4 * rng.next_f64() - 1.2,
                0.2 * rng.next_f64() - 0.1,
            );
            let (h, clearance) = b.height_and_clearance(x, f64::NEG_INFINITY);
            assert_eq!(h.to_bits(), b.height(x).to_bits());
            assert!(clearance <= nearest_foot(x), "{x}: {clearance}");
            // Given its own bound.
            assert_eq!(
                b.height_and_clearance(x, clearance).0.to_bits(),
                h.to_bits()
            );
            // A point nearby, its bound carried over by the triangle inequality.
            let y = x + 0.05 * (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5);
            let carried = clearance - x.distance(y);
            let (g, bound) = b.height_and_clearance(y, carried);
            assert_eq!(g.to_bits(), b.height(y).to_bits(), "{y}");
            assert!(bound <= nearest_foot(y), "{y}: {bound}");
            skipped += usize::from(carried >= b.max_band);
            blended += usize::from(h != 0.0);
        }
        assert!(
            blended > 100 && skipped > 100,
            "{blended} blended, {skipped} skipped"
        );
    }

    #[test]
    fn zero_offsets_blend_nothing() {
        let b = square(0.0);
        assert_eq!(b, OffsetBlend::default());
        assert_eq!(b.height(DVec3::new(0.5, 0.0, 0.0)), 0.0);
    }
}
