//! One region's triangulation in its chart with spade's constrained Delaunay triangulation:
//! iterative vertex addition (section 5.3) and the parametric grid (section 5.2).
//!
//! The API the assembler uses:
//!
//! ```text
//! AdaptiveTriangulation::new(&RegionInput, min_spacing) -> Result<Self, RemeshError>
//!     .worst_error() -> Option<f64>   // distance of the worst face centre from the surface
//!     .insert_worst() -> bool         // false when no candidate is left
//!     .added() -> usize               // interior vertices inserted so far
//!     .finish() -> RegionMesh
//! triangulate_parametric(&RegionInput, interior_vertices, min_spacing) -> Result<RegionMesh, RemeshError>
//! ```
//!
//! Both start from the same boundary-only triangulation: the boundary vertices mapped to the
//! plane by the region's chart, each loop edge a constraint, the faces inside the region
//! found by a flood fill from the outer face that toggles across constraints. The chart's
//! pole must lie outside the region (its image is the unbounded side); a region found on the
//! right of its loops is refused, since the pole is then inside it.
//!
//! Boundary edges are never split and boundary vertices never moved: the output shares them
//! exactly with the neighbouring regions. Faces along a boundary edge keep that chord's
//! distance to the surface (refining the arcs is [`super::refine`]'s job), so
//! [`AdaptiveTriangulation::worst_error`] reports the worst face that may still be split,
//! not the worst face.
//!
//! Triangles are oriented once per region: the chart's handedness against the ellipsoid's
//! signed normal is measured on a small plane triangle (it is the same everywhere, the map
//! being conformal). On decoded files an ear of three consecutive boundary points, which lie
//! off the ellipsoid, can still face against the normal, as can a face vertex addition
//! would not split; where swapping its diagonal with an inside neighbour turns fewer faces,
//! the output has the other diagonal (`RegionCdt::swap_turned`, the classic edge flip).

use super::chart::RegionChart;
use super::surface::RegionSurface;
use super::RemeshError;
use crate::ellipsoid::NormalSide;
use crate::rng::SplitMix64;
use glam::{DVec2, DVec3};
use spade::handles::{FixedFaceHandle, FixedVertexHandle, InnerTag};
use spade::{
    validate_coordinate, ConstrainedDelaunayTriangulation, HasPosition, Point2, Triangulation,
};
use std::cmp::Ordering;
use std::collections::{HashMap, HashSet, VecDeque};

/// What one region's triangulation starts from.
#[derive(Debug, Clone, Copy)]
pub struct RegionInput<'a> {
    /// The region (for error messages).
    pub region: u32,
    /// The surface it is meshed on ([`RegionSurface::chart`] holds the chart).
    pub surface: &'a RegionSurface,
    /// Positions of the boundary vertices the loops refer to (shared with the neighbours).
    pub boundary: &'a [DVec3],
    /// The region's boundary loops as indices into `boundary`, each closed (the first index
    /// not repeated at the end), with the region on its left (outward normal up).
    pub loops: &'a [Vec<u32>],
    /// Points (model units, on or near the region's surface) whose surface points are its
    /// first interior vertices, before either scheme adds any, each where its chart
    /// position lies strictly inside the region: a whole ellipsoid's half gets its pole
    /// (`assemble`'s `split_whole`). Without it, a half given no vertex of its own was its
    /// equator's polygon, and both halves' polygons used the same chords (every one an edge
    /// of four faces, flat across the ellipsoid).
    pub seeds: &'a [DVec3],
    /// About how many vertices the region's mesh ends with (0: not known): room for them is
    /// made at once, not by growing the triangulation's storage as vertices come (its
    /// copies and fresh pages were 7 % of a decode of hand K = 18 at 5 000 vertices).
    pub expected_vertices: usize,
}

/// A triangle corner: a boundary vertex (index into [`RegionInput::boundary`]) or a new
/// interior vertex (index into [`RegionMesh::interior`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Corner {
    /// Index into the input's boundary vertices.
    Boundary(u32),
    /// Index into [`RegionMesh::interior`].
    Interior(u32),
}

/// One region's triangles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RegionMesh {
    /// New vertices, on the region's surface ([`RegionSurface::point`]).
    pub interior: Vec<DVec3>,
    /// Triangles, counter-clockwise seen against the ellipsoid's signed normal
    /// ([`crate::ellipsoid::Ellipsoid::normal`]): outward for positive ellipsoids, inward for
    /// negative ones.
    pub triangles: Vec<[Corner; 3]>,
    /// Triangles turned against the ellipsoid (normal more than 90° from its signed normal
    /// at their centroid) left after diagonal swaps (`RegionCdt::swap_turned`).
    pub turned: usize,
}

/// A vertex of the chart's triangulation: its plane position, its 3D position, what it is.
#[derive(Debug, Clone, Copy)]
struct Vertex {
    position: Point2<f64>,
    point: DVec3,
    /// Its height above the ellipsoid along the outward normal ([`RegionSurface::height_of`]).
    height: f64,
    corner: Corner,
    /// For a boundary vertex, the chart positions and heights of its neighbours along its
    /// (first) loop.
    along: Option<[(DVec2, f64); 2]>,
    /// A lower bound on the distance from its foot on the ellipsoid to the boundary's feet
    /// (zero on the boundary; [`RegionSurface::point_height_and_clearance`]).
    clearance: f64,
}

impl Vertex {
    /// An interior vertex: at `plane` in the chart, at `point` (at `height` above the
    /// ellipsoid) on the surface, the region's `index`-th interior vertex, its foot at least
    /// `clearance` from the boundary's.
    fn interior(plane: DVec2, (point, height, clearance): Lifted, index: u32) -> Vertex {
        Vertex {
            position: to_point(plane),
            point,
            height,
            corner: Corner::Interior(index),
            along: None,
            clearance,
        }
    }

    /// Its chart position.
    fn plane(&self) -> DVec2 {
        DVec2::new(self.position.x, self.position.y)
    }
}

impl HasPosition for Vertex {
    type Scalar = f64;

    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// A chart position's surface point, its height above the ellipsoid and its foot's clearance
/// from the boundary's feet ([`RegionSurface::point_height_and_clearance`]).
type Lifted = (DVec3, f64, f64);

/// A lower bound on the distance from the ellipsoid point `x` to the boundary's feet, from a
/// lifted point's own bound: its foot lies its height from it (triangle inequality).
fn carried_clearance((point, height, clearance): Lifted, x: DVec3) -> f64 {
    clearance - height.abs() - point.distance(x)
}

/// The face data says whether the face lies inside the region.
type Cdt = ConstrainedDelaunayTriangulation<Vertex, (), (), bool>;

/// Two loop edges that cross in a region's chart: their end points, in space.
pub type Crossing = [[DVec3; 2]; 2];

/// Why a boundary-only triangulation failed.
enum Failure {
    Error(RemeshError),
    /// Two loop edges cross (the edges, when spade names the one in the way).
    Crossing(RemeshError, Option<Box<Crossing>>),
}

impl Failure {
    fn into_error(self) -> RemeshError {
        match self {
            Failure::Error(e) | Failure::Crossing(e, _) => e,
        }
    }
}

impl From<RemeshError> for Failure {
    fn from(e: RemeshError) -> Self {
        Failure::Error(e)
    }
}

/// When a region's loops cross in its chart (the boundary-only triangulation fails with
/// "boundary loops cross"): the first two loop edges found crossing.
pub fn boundary_crossing(input: &RegionInput) -> Option<Crossing> {
    match RegionCdt::build(input) {
        Err(Failure::Crossing(_, c)) => c.map(|c| *c),
        _ => None,
    }
}

fn region_error(region: u32, what: &'static str) -> RemeshError {
    RemeshError::Region { region, what }
}

fn to_point(q: DVec2) -> Point2<f64> {
    Point2::new(q.x, q.y)
}

fn is_valid_plane_point(q: DVec2) -> bool {
    validate_coordinate(q.x).is_ok() && validate_coordinate(q.y).is_ok()
}

/// A region's constrained Delaunay triangulation in its chart, its faces marked inside or
/// outside the region. Shared by both schemes.
#[derive(Clone)]
struct RegionCdt {
    surface: RegionSurface,
    cdt: Cdt,
    /// Inserted interior vertices, in insertion order ([`Corner::Interior`] indices).
    interior: Vec<DVec3>,
    /// Whether a face counter-clockwise in the plane is clockwise about the ellipsoid's
    /// signed normal, so that [`RegionCdt::finish`] must reverse it.
    flip: bool,
    /// The region's ellipsoid's normal, for [`RegionCdt::is_turned`].
    side: NormalSide,
    /// The boundary loops' edges as unit-sphere directions (for the parametric scheme).
    segments: Vec<[DVec3; 2]>,
    /// The faces around the last inserted vertex (a buffer reused across insertions).
    star: Vec<FixedFaceHandle<InnerTag>>,
}

impl RegionCdt {
    /// The boundary-only triangulation: every boundary vertex inserted once, every loop edge a
    /// constraint, the faces inside the region found by a flood fill from the outer face that
    /// toggles inside/outside across constraint edges.
    fn new(input: &RegionInput) -> Result<RegionCdt, RemeshError> {
        Self::build(input).map_err(Failure::into_error)
    }

    /// [`RegionCdt::new`], telling which loop edges cross when that is what failed.
    fn build(input: &RegionInput) -> Result<RegionCdt, Failure> {
        let region = input.region;
        let err = |what| Failure::Error(region_error(region, what));
        let loops = clean_loops(input)?;
        let surface = input.surface.clone();
        let chart = &surface.chart;
        if !chart.ellipsoid.is_valid() {
            return Err(err("its ellipsoid is degenerate"));
        }

        // Per boundary point (clean_loops checked the indices): its unit-sphere direction
        // and chart position, found once (the closest point is iterative), and its handle.
        let n = input.boundary.len();
        let mut directions: Vec<DVec3> = vec![DVec3::NAN; n];
        let mut planes: Vec<DVec2> = vec![DVec2::NAN; n];
        let mut handles: Vec<Option<FixedVertexHandle>> = vec![None; n];
        for &i in loops.iter().flatten() {
            let i = i as usize;
            let point = input.boundary[i];
            if !point.is_finite() {
                return Err(err("a boundary point is not finite"));
            }
            let u = chart.to_sphere(point);
            let q = chart.sphere_to_plane(u);
            if !is_valid_plane_point(q) {
                return Err(err("a boundary point has no valid position in the chart"));
            }
            directions[i] = u;
            planes[i] = q;
        }
        // A planar triangulation of v vertices has about 3v edges and 2v faces.
        let vertices = input.expected_vertices.max(input.boundary.len());
        let mut cdt = Cdt::with_capacity(vertices, 3 * vertices, 2 * vertices);
        let mut plane_sum = DVec2::ZERO;
        let mut hint: Option<FixedVertexHandle> = None;
        let plane_of = |i: u32| planes[i as usize];
        let mut heights = vec![0.0; planes.len()];
        for &i in loops.iter().flatten() {
            let i = i as usize;
            heights[i] = surface.height_of(planes[i], input.boundary[i]);
        }
        let level_of = |i: u32| (planes[i as usize], heights[i as usize]);
        for lp in &loops {
            for (k, &i) in lp.iter().enumerate() {
                if handles[i as usize].is_some() {
                    continue;
                }
                let point = input.boundary[i as usize];
                let q = plane_of(i);
                plane_sum += q;
                let previous = lp[(k + lp.len() - 1) % lp.len()];
                let next = lp[(k + 1) % lp.len()];
                let vertex = Vertex {
                    position: to_point(q),
                    point,
                    height: heights[i as usize],
                    corner: Corner::Boundary(i),
                    along: Some([level_of(previous), level_of(next)]),
                    clearance: 0.0,
                };
                let before = cdt.num_vertices();
                let inserted = match hint {
                    Some(h) => cdt.insert_with_hint(vertex, h),
                    None => cdt.insert(vertex),
                };
                let handle = inserted.map_err(|_| err("a boundary point cannot be inserted"))?;
                if cdt.num_vertices() == before {
                    return Err(err("two boundary points map to the same chart position"));
                }
                handles[i as usize] = Some(handle);
                hint = Some(handle);
            }
        }
        if cdt.num_inner_faces() == 0 {
            return Err(err("the boundary encloses no area in the chart"));
        }

        for lp in &loops {
            for (k, &a) in lp.iter().enumerate() {
                let b = lp[(k + 1) % lp.len()];
                let (Some(ha), Some(hb)) = (handles[a as usize], handles[b as usize]) else {
                    return Err(err("a boundary loop refers to a missing point"));
                };
                if cdt.exists_constraint(ha, hb) {
                    return Err(err("a boundary edge is used twice"));
                }
                if !cdt.can_add_constraint(ha, hb) {
                    let other = cdt
                        .get_conflicting_edges_between_vertices(ha, hb)
                        .next()
                        .map(|e| [e.from().data().point, e.to().data().point]);
                    let this = [cdt.vertex(ha).data().point, cdt.vertex(hb).data().point];
                    return Err(Failure::Crossing(
                        region_error(region, "boundary loops cross"),
                        other.map(|o| Box::new([this, o])),
                    ));
                }
                cdt.try_add_constraint(ha, hb);
                if !cdt.exists_constraint(ha, hb) {
                    return Err(err("a boundary point lies on another boundary edge"));
                }
            }
        }

        let any_inside =
            mark_inside(&mut cdt).ok_or_else(|| err("the boundary loops are inconsistent"))?;
        if !any_inside {
            return Err(err("the boundary encloses no area in the chart"));
        }

        let count = cdt.num_vertices().max(1) as f64;
        let flip = !plane_is_counter_clockwise(chart, plane_sum / count)
            .ok_or_else(|| err("its chart is degenerate"))?;
        let direction = |i: u32| directions[i as usize];
        let segments = loops
            .iter()
            .flat_map(|lp| {
                (0..lp.len()).map(|k| [direction(lp[k]), direction(lp[(k + 1) % lp.len()])])
            })
            .collect();
        let side = surface.ellipsoid().normal_side();
        let mut region_cdt = RegionCdt {
            surface,
            cdt,
            interior: Vec::new(),
            flip,
            side,
            segments,
            star: Vec::new(),
        };
        region_cdt.check_sides(&loops, &handles, region)?;
        for &seed in input.seeds {
            region_cdt.insert_seed(seed);
        }
        Ok(region_cdt)
    }

    /// Inserts the surface point at the chart position of `point` as an interior vertex,
    /// when that position lies strictly inside an inside face ([`RegionInput::seeds`]).
    fn insert_seed(&mut self, point: DVec3) {
        let plane = self.surface.chart.to_plane(point);
        if !is_valid_plane_point(plane) {
            return;
        }
        let q = to_point(plane);
        let spade::PositionInTriangulation::OnFace(face) = self.cdt.locate(q) else {
            return;
        };
        let face = self.cdt.face(face);
        let strictly_inside = face
            .adjacent_edges()
            .iter()
            .all(|e| e.side_query(q).is_on_left_side());
        if *face.data() && strictly_inside {
            let hint = face.vertices()[0].fix();
            let lifted = self
                .surface
                .point_height_and_clearance(plane, |_| f64::NEG_INFINITY);
            self.insert_interior(plane, lifted, hint);
        }
    }
    /// The region must lie on the left of its loops (seen against the signed normal); if most
    /// loop edges see it on their right, the flood fill found the complement: the chart's pole
    /// lies inside the region.
    fn check_sides(
        &self,
        loops: &[Vec<u32>],
        handles: &[Option<FixedVertexHandle>],
        region: u32,
    ) -> Result<(), RemeshError> {
        let (mut agree, mut disagree) = (0usize, 0usize);
        for lp in loops {
            for (k, &a) in lp.iter().enumerate() {
                let b = lp[(k + 1) % lp.len()];
                let (Some(ha), Some(hb)) = (handles[a as usize], handles[b as usize]) else {
                    continue;
                };
                let Some(edge) = self.cdt.get_edge_from_neighbors(ha, hb) else {
                    continue;
                };
                // The face on the plane-left of a→b; in 3D it is on the left iff !flip.
                let left_inside = edge.face().as_inner().is_some_and(|f| *f.data());
                if left_inside != self.flip {
                    agree += 1;
                } else {
                    disagree += 1;
                }
            }
        }
        if disagree > agree {
            return Err(region_error(
                region,
                "the region lies on the right of its loops in its chart (the pole is inside it)",
            ));
        }
        Ok(())
    }

    /// Inserts an interior vertex strictly inside an inside face (the caller checked it),
    /// marks its star ([`RegionCdt::star`]) inside, returns its handle; `None` if spade
    /// refused it or found a vertex already there.
    fn insert_interior(
        &mut self,
        plane: DVec2,
        lifted: Lifted,
        hint: FixedVertexHandle,
    ) -> Option<FixedVertexHandle> {
        let index = u32::try_from(self.interior.len()).ok()?;
        let before = self.cdt.num_vertices();
        let vertex = Vertex::interior(plane, lifted, index);
        let point = vertex.point;
        let handle = self.cdt.insert_with_hint(vertex, hint).ok()?;
        if self.cdt.num_vertices() == before {
            return None;
        }
        self.interior.push(point);
        self.star.clear();
        self.star.extend(
            self.cdt
                .vertex(handle)
                .out_edges()
                .filter_map(|e| e.face().as_inner().map(|f| f.fix())),
        );
        for &face in &self.star {
            *self.cdt.face_data_mut(face) = true;
        }
        Some(handle)
    }

    /// Whether the face with these corners (counter-clockwise in the plane) is turned
    /// against the region's ellipsoid: its normal, oriented as [`RegionCdt::finish`] will
    /// orient it, against the ellipsoid's signed normal at its centroid (the test
    /// [`super::assemble::check_mesh`] applies to the assembled mesh).
    fn is_turned(&self, corners: [DVec3; 3]) -> bool {
        let facing = self.side.facing(corners);
        if self.flip {
            facing > 0.0
        } else {
            facing < 0.0
        }
    }

    /// The inside faces as triangles, oriented with the ellipsoid's signed normal.
    fn finish(self) -> RegionMesh {
        let any_turned = self.any_turned(None);
        self.finish_knowing(any_turned)
    }

    /// Whether an inside face is turned against the ellipsoid; with `turned`, only those
    /// faces (by their corners) are looked at: vertex addition tests every face it makes.
    fn any_turned(&self, turned: Option<&[[FixedVertexHandle; 3]]>) -> bool {
        let is_turned_inside = |f: FixedFaceHandle<InnerTag>| {
            let f = self.cdt.face(f);
            *f.data() && self.is_turned(f.vertices().map(|v| v.data().point))
        };
        match turned {
            Some(turned) => turned.iter().any(|&[a, b, c]| {
                self.cdt
                    .get_edge_from_neighbors(a, b)
                    .filter(|e| e.next().to().fix() == c)
                    .and_then(|e| e.face().as_inner())
                    .is_some_and(|f| is_turned_inside(f.fix()))
            }),
            None => self.cdt.fixed_inner_faces().any(is_turned_inside),
        }
    }

    /// [`RegionCdt::finish`], told whether a face is turned ([`RegionCdt::any_turned`]).
    /// Only a region with a turned face is mended ([`RegionCdt::swap_turned`]); the others
    /// are read off as they are.
    fn finish_knowing(self, any_turned: bool) -> RegionMesh {
        let orient = |[a, b, c]: [Corner; 3]| if self.flip { [a, c, b] } else { [a, b, c] };
        let inside = self.cdt.inner_faces().filter(|f| *f.data());
        let (triangles, turned) = if any_turned {
            let mut faces: Vec<[Vertex; 3]> =
                inside.map(|f| f.vertices().map(|v| *v.data())).collect();
            let turned = self.swap_turned(&mut faces);
            let triangles = faces.iter().map(|f| orient(f.map(|v| v.corner))).collect();
            (triangles, turned)
        } else {
            let triangles = inside
                .map(|f| orient(f.vertices().map(|v| v.data().corner)))
                .collect();
            (triangles, 0)
        };
        RegionMesh {
            interior: self.interior,
            triangles,
            turned,
        }
    }
}

impl RegionCdt {
    /// Mends faces turned against the ellipsoid that vertex addition left (ears of boundary
    /// points, faces it would not split) by swapping the diagonal of a turned face and an
    /// inside neighbour where that turns fewer of the two (the classic edge flip). A swap is
    /// made only where both new faces are counter-clockwise in the plane, so the
    /// triangulation stays planar in the chart, and neither is much smaller than the smaller
    /// old face ([`SWAP_MIN_AREA_SHARE`]); boundary edges are never swapped. Each swap
    /// lowers the count of turned faces, so the passes end. Returns the count left.
    fn swap_turned(&self, faces: &mut [[Vertex; 3]]) -> usize {
        let turned = |t: &[Vertex; 3]| usize::from(self.is_turned(t.map(|v| v.point)));
        let mut count: Vec<usize> = faces.iter().map(turned).collect();
        if count.iter().all(|&c| c == 0) {
            return 0;
        }
        // Directed edge (by corners) → the face that runs it.
        let mut by_edge: HashMap<(Corner, Corner), usize> = HashMap::new();
        for (f, t) in faces.iter().enumerate() {
            for k in 0..3 {
                by_edge.insert((t[k].corner, t[(k + 1) % 3].corner), f);
            }
        }
        let boundary: HashSet<(Corner, Corner)> = self
            .cdt
            .undirected_edges()
            .filter(|e| e.is_constraint_edge())
            .flat_map(|e| {
                let [a, b] = e.vertices().map(|v| v.data().corner);
                [(a, b), (b, a)]
            })
            .collect();
        let plane_area =
            |[a, b, c]: [Vertex; 3]| 0.5 * (b.plane() - a.plane()).perp_dot(c.plane() - a.plane());
        let area =
            |[a, b, c]: [Vertex; 3]| 0.5 * (b.point - a.point).cross(c.point - a.point).length();
        let mut changed = true;
        while changed {
            changed = false;
            for f in 0..faces.len() {
                if count[f] == 0 {
                    continue;
                }
                for k in 0..3 {
                    let t = faces[f];
                    let (u, v, w) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                    if boundary.contains(&(u.corner, v.corner)) {
                        continue;
                    }
                    let Some(&g) = by_edge.get(&(v.corner, u.corner)) else {
                        continue;
                    };
                    let Some(x) = faces[g]
                        .into_iter()
                        .find(|c| c.corner != u.corner && c.corner != v.corner)
                    else {
                        continue;
                    };
                    // (u, v, w) and (v, u, x) become (w, u, x) and (x, v, w).
                    let new = [[w, u, x], [x, v, w]];
                    let old_area = area(t).min(area(faces[g]));
                    let old_plane = plane_area(t).min(plane_area(faces[g]));
                    let sound = new.iter().all(|&n| {
                        plane_area(n) > SWAP_MIN_AREA_SHARE * old_plane
                            && area(n) > SWAP_MIN_AREA_SHARE * old_area
                    });
                    let now = [turned(&new[0]), turned(&new[1])];
                    if !sound || now[0] + now[1] >= count[f] + count[g] {
                        continue;
                    }
                    for old in [t, faces[g]] {
                        for j in 0..3 {
                            by_edge.remove(&(old[j].corner, old[(j + 1) % 3].corner));
                        }
                    }
                    for (face, n) in [(f, new[0]), (g, new[1])] {
                        for j in 0..3 {
                            by_edge.insert((n[j].corner, n[(j + 1) % 3].corner), face);
                        }
                        faces[face] = n;
                    }
                    count[f] = now[0];
                    count[g] = now[1];
                    changed = true;
                    break;
                }
            }
        }
        count.iter().sum()
    }
}

/// A diagonal swap ([`RegionCdt::swap_turned`]) must leave both faces at least this share of
/// the smaller old face's area, in the chart and in space: a turned face is not traded for
/// a sliver.
const SWAP_MIN_AREA_SHARE: f64 = 0.25;

/// The loops with their indices checked, consecutive repeats merged, and at least three
/// distinct points each.
fn clean_loops(input: &RegionInput) -> Result<Vec<Vec<u32>>, RemeshError> {
    let err = |what| region_error(input.region, what);
    if input.loops.is_empty() {
        return Err(err(
            "a region without boundary loops cannot be charted in the plane",
        ));
    }
    let mut loops = Vec::with_capacity(input.loops.len());
    for lp in input.loops {
        let mut clean: Vec<u32> = Vec::with_capacity(lp.len());
        for &i in lp {
            if i as usize >= input.boundary.len() {
                return Err(err("a boundary loop refers to a missing point"));
            }
            if clean.last() != Some(&i) {
                clean.push(i);
            }
        }
        while clean.len() > 1 && clean.first() == clean.last() {
            clean.pop();
        }
        if clean.len() < 3 {
            return Err(err("a boundary loop has fewer than three distinct points"));
        }
        loops.push(clean);
    }
    Ok(loops)
}

/// Marks each inner face inside or outside the region ([`flood_fill`]); whether any is
/// inside. `None` (nothing marked) if the loops do not bound a region.
fn mark_inside(cdt: &mut Cdt) -> Option<bool> {
    let inside = flood_fill(cdt)?;
    let mut any_inside = false;
    for face in cdt.fixed_inner_faces() {
        let flag = inside.get(face.index()).copied().unwrap_or(false);
        any_inside |= flag;
        *cdt.face_data_mut(face) = flag;
    }
    Some(any_inside)
}

/// Inside/outside per face index: a breadth-first flood fill from the outer face that toggles
/// across constraint edges. `None` if some face is reached with both states (loops that do not
/// bound a region).
fn flood_fill(cdt: &Cdt) -> Option<Vec<bool>> {
    let mut state: Vec<Option<bool>> = vec![None; cdt.num_all_faces()];
    let mut queue: VecDeque<(FixedFaceHandle<InnerTag>, bool)> = VecDeque::new();
    for edge in cdt.convex_hull() {
        let across = edge.rev().face().as_inner().or(edge.face().as_inner());
        if let Some(face) = across {
            queue.push_back((face.fix(), edge.is_constraint_edge()));
        }
    }
    while let Some((face, inside)) = queue.pop_front() {
        let slot = state.get_mut(face.index())?;
        match *slot {
            Some(s) if s != inside => return None,
            Some(_) => continue,
            None => *slot = Some(inside),
        }
        for edge in cdt.face(face).adjacent_edges() {
            if let Some(next) = edge.rev().face().as_inner() {
                queue.push_back((next.fix(), inside != edge.is_constraint_edge()));
            }
        }
    }
    Some(state.into_iter().map(|s| s == Some(true)).collect())
}

/// Whether the chart maps counter-clockwise plane triangles to counter-clockwise triangles
/// about the ellipsoid's signed normal, checked with the 3D normal of a small plane triangle
/// at `q` (the map is conformal, so the answer is the same everywhere); `None` if degenerate.
fn plane_is_counter_clockwise(chart: &RegionChart, q: DVec2) -> Option<bool> {
    let h = 1e-4 * (1.0 + q.length());
    let p0 = chart.from_plane(q);
    let px = chart.from_plane(q + DVec2::new(h, 0.0));
    let py = chart.from_plane(q + DVec2::new(0.0, h));
    let s = (px - p0).cross(py - p0).dot(chart.ellipsoid.normal(p0));
    (s.is_finite() && s != 0.0).then_some(s > 0.0)
}

/// A face worth splitting: its error, its corners and its handle.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    error: f64,
    corners: [FixedVertexHandle; 3],
    face: u32,
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.error
            .total_cmp(&other.error)
            .then_with(|| other.corners.cmp(&self.corners))
    }
}

/// The candidates, at most one per face: a binary max-heap in [`Candidate`]'s order, with
/// each face's place in it, so that a face an insertion remakes has its candidate replaced
/// or removed where it is ([`CandidateHeap::set`]). Every entry is a face as it is now: the
/// worst candidate is the top, with no stale entries to pop first (a heap of entries pushed
/// anew held about three per vertex, two of them stale by the time they came on top).
#[derive(Debug, Clone, Default)]
struct CandidateHeap {
    entries: Vec<Candidate>,
    /// Per face index, its entry's place in `entries` ([`NO_ENTRY`]: none).
    places: Vec<u32>,
}

/// A face with no entry in the [`CandidateHeap`].
const NO_ENTRY: u32 = u32::MAX;

impl CandidateHeap {
    fn peek(&self) -> Option<&Candidate> {
        self.entries.first()
    }

    fn clear(&mut self) {
        self.entries.clear();
        self.places.clear();
    }

    /// Removes and returns the worst candidate.
    fn pop(&mut self) -> Option<Candidate> {
        let last = self.entries.len().checked_sub(1)?;
        self.swap(0, last);
        let top = self.entries.pop()?;
        self.places[top.face as usize] = NO_ENTRY;
        self.sift_down(0);
        Some(top)
    }

    /// Makes `candidate` the entry of `face` (`None`: no entry), replacing its entry if it
    /// has one.
    fn set(&mut self, face: usize, candidate: Option<Candidate>) {
        if face >= self.places.len() {
            if candidate.is_none() {
                return;
            }
            self.places.resize(face + 1, NO_ENTRY);
        }
        let place = self.places[face];
        match (place, candidate) {
            (NO_ENTRY, None) => {}
            (NO_ENTRY, Some(c)) => {
                self.places[face] = self.entries.len() as u32;
                self.entries.push(c);
                self.sift_up(self.entries.len() - 1);
            }
            (i, Some(c)) => {
                let i = i as usize;
                let worse = c > self.entries[i];
                self.entries[i] = c;
                if worse {
                    self.sift_up(i);
                } else {
                    self.sift_down(i);
                }
            }
            (i, None) => {
                let (i, last) = (i as usize, self.entries.len() - 1);
                self.swap(i, last);
                self.entries.pop();
                self.places[face] = NO_ENTRY;
                if i < last {
                    self.sift_up(i);
                    self.sift_down(i);
                }
            }
        }
    }

    fn swap(&mut self, i: usize, j: usize) {
        self.entries.swap(i, j);
        self.places[self.entries[i].face as usize] = i as u32;
        self.places[self.entries[j].face as usize] = j as u32;
    }

    fn sift_up(&mut self, mut i: usize) {
        while i > 0 {
            let parent = (i - 1) / 2;
            if self.entries[i] <= self.entries[parent] {
                break;
            }
            self.swap(i, parent);
            i = parent;
        }
    }

    fn sift_down(&mut self, mut i: usize) {
        let n = self.entries.len();
        loop {
            let (left, right) = (2 * i + 1, 2 * i + 2);
            let mut worst = i;
            if left < n && self.entries[left] > self.entries[worst] {
                worst = left;
            }
            if right < n && self.entries[right] > self.entries[worst] {
                worst = right;
            }
            if worst == i {
                break;
            }
            self.swap(i, worst);
            i = worst;
        }
    }
}

/// Iterative vertex addition (section 5.3), the default decoder: the region's boundary in its
/// chart, then repeatedly the inside face whose flat centroid is farthest from the region's
/// surface is split at a new vertex on the surface.
///
/// The distance is measured to the surface point at the face's *plane* centroid (the paper
/// measures to the ellipsoid along the ray from its centre; near the boundary the surface is
/// the ellipsoid displaced toward the boundary points, [`super::surface`]), and a face turned
/// against its ellipsoid counts as infinitely far. The new vertex is that plane centroid
/// mapped to the surface ([`RegionSurface::point`]): the plane centroid lies strictly inside the plane triangle
/// (checked with spade's exact orientation predicate), hence inside the region, so the
/// boundary is never split. The faces' candidates are kept in a max-heap of one entry per
/// face, updated in place (`CandidateHeap`): an insertion makes or remakes only the new
/// vertex's star (spade never removes a face on insertion), whose entries it replaces, so
/// [`AdaptiveTriangulation::insert_worst`] costs O(log n) plus spade's insertion near its
/// hint.
pub struct AdaptiveTriangulation {
    inner: RegionCdt,
    heap: CandidateHeap,
    min_spacing: f64,
    /// Every face found turned when it was made, by its corners (it may be gone since).
    turned: Vec<[FixedVertexHandle; 3]>,
    /// Whether a face at the target scale is one by its length alone
    /// ([`Self::judge_by_length`]).
    by_length: bool,
    /// Whether a face was split into a turned one only because its centroid lay far from
    /// the surface ([`Self::made_curved_splits`]).
    curved_splits: bool,
    /// Whether only faces turned against the ellipsoid are candidates ([`Self::mend`]).
    turned_only: bool,
}

impl AdaptiveTriangulation {
    /// The boundary-only triangulation of `input`, every inside face a candidate. A candidate
    /// whose new vertex would lie closer than `min_spacing` (model units) to a corner of its
    /// face is dropped, and its face never split.
    ///
    /// Errors ([`RemeshError::Region`]): no loops, a loop with fewer than three distinct
    /// points or a missing index, non-finite points, two boundary points at the same chart
    /// position, crossing loops, a boundary point on another boundary edge, an edge used
    /// twice, a boundary enclosing no area, a region on the wrong side of its loops.
    pub fn new(input: &RegionInput, min_spacing: f64) -> Result<Self, RemeshError> {
        check_min_spacing(min_spacing)?;
        Ok(Self::start(RegionCdt::new(input)?, min_spacing, false))
    }

    /// Vertex addition on `inner` as it is, every inside face (with `turned_only`, every
    /// face turned against the ellipsoid) a candidate.
    fn start(inner: RegionCdt, min_spacing: f64, turned_only: bool) -> Self {
        let mut this = AdaptiveTriangulation {
            inner,
            heap: CandidateHeap::default(),
            min_spacing,
            turned: Vec::new(),
            by_length: false,
            curved_splits: false,
            turned_only,
        };
        this.push_inside_faces();
        this
    }

    /// `inner`'s triangles, its faces turned against the ellipsoid split first as vertex
    /// addition splits them (whatever that gives, and so on with the turned faces made),
    /// until none is left that may be split under `min_spacing` or `max_insertions` vertices
    /// are added.
    fn mend(inner: RegionCdt, min_spacing: f64, max_insertions: usize) -> RegionMesh {
        let mut this = Self::start(inner, min_spacing, true);
        for _ in 0..max_insertions {
            if !this.insert_worst() {
                break;
            }
        }
        this.finish()
    }

    /// The distance (model units) of the worst face's flat centroid from the surface among
    /// the faces that may still be split (infinite for a face turned against its
    /// ellipsoid); `None` when none is left.
    pub fn worst_error(&self) -> Option<f64> {
        self.heap.peek().map(|c| c.error)
    }

    /// Splits the worst face; `false` when no candidate is left.
    pub fn insert_worst(&mut self) -> bool {
        while let Some(candidate) = self.heap.pop() {
            // The same split point push_face checked (the face is unchanged).
            let handles = candidate.corners.map(|h| self.inner.cdt.vertex(h));
            let corners = handles.each_ref().map(|v| v.data());
            let [qa, qb, qc] = corners.map(Vertex::plane);
            let plane = (qa + qb + qc) / 3.0;
            // Its foot's clearance from the corners' (the foot of a corner lies its height
            // from it): where all are deep inside the region the height is zero at once.
            let point = self.inner.surface.point_height_and_clearance(plane, |x| {
                corners
                    .iter()
                    .map(|c| carried_clearance((c.point, c.height, c.clearance), x))
                    .fold(f64::NEG_INFINITY, f64::max)
            });
            // A face that is not turned is not split into one that is and cannot be split in
            // turn (a turned face is split whatever it gives: nothing is lost).
            let verdict = if candidate.error.is_finite() {
                self.judge_split(&candidate, plane, point)
            } else {
                Verdict::Split
            };
            if verdict == Verdict::Refuse
                || self
                    .inner
                    .insert_interior(plane, point, candidate.corners[0])
                    .is_none()
            {
                continue;
            }
            self.curved_splits |= verdict == Verdict::SplitCurved;
            let star = std::mem::take(&mut self.inner.star);
            for &face in &star {
                self.push_face(face);
            }
            self.inner.star = star;
            return true;
        }
        false
    }

    /// Sets the minimum spacing (see [`AdaptiveTriangulation::new`]) and makes every inside
    /// face a candidate again under it: lowered, it lets refinement go on where the budget
    /// was not spent (a region whose estimated area was too large for its real size).
    pub fn set_min_spacing(&mut self, min_spacing: f64) {
        if check_min_spacing(min_spacing).is_err() {
            return;
        }
        self.min_spacing = min_spacing;
        self.heap.clear();
        self.push_inside_faces();
    }

    /// Makes every inside face a candidate ([`Self::push_face`]).
    fn push_inside_faces(&mut self) {
        let faces: Vec<FixedFaceHandle<InnerTag>> = self
            .inner
            .cdt
            .fixed_inner_faces()
            .filter(|&f| *self.inner.cdt.face(f).data())
            .collect();
        for face in faces {
            self.push_face(face);
        }
    }

    /// Judges from now on whether a face is at the target scale by its length alone, however
    /// far its centroid lies from the surface (`CURVED_FACE_SPACINGS` off): a face across
    /// a part curved more sharply than the spacing stays whole rather than be split into
    /// faces turned against the ellipsoid. For a region where such splits left a turned
    /// face ([`Self::made_curved_splits`]).
    pub fn judge_by_length(&mut self) {
        self.by_length = true;
    }

    /// Whether some face at the target scale by its length was split into a face turned
    /// against the ellipsoid because its centroid lay far from the surface
    /// (`CURVED_FACE_SPACINGS`).
    pub fn made_curved_splits(&self) -> bool {
        self.curved_splits
    }

    /// Interior vertices inserted so far.
    pub fn added(&self) -> usize {
        self.inner.interior.len()
    }

    /// The region's triangles. Where a face is left turned against the ellipsoid after
    /// diagonal swaps (`RegionCdt::swap_turned`), the interior corners of the turned faces
    /// are removed instead, round after round (`RegionCdt::drop_turned_corners`, as the
    /// parametric scheme does with its grid points), if that leaves fewer turned faces:
    /// a face with two corners on a boundary edge that lies off the ellipsoid and one
    /// inside the region close to it can be turned however it is split or swapped, and the
    /// face that fills the vertex's hole reaches farther in. Measured on the five decodes
    /// of `cargo bench --bench clean -- --budgets` that were not clean (1 or 2 flipped
    /// triangles after 10 to 12 meshings each): duck K = 12 at 31 250 vertices and K = 24
    /// at 12 500 now clean in one meshing, penguin K = 12 and demosthenes K = 12 at 1 000
    /// clean in 8 and 9; horse K = 24 at 1 000 keeps its one.
    pub fn finish(self) -> RegionMesh {
        if !self.inner.any_turned(Some(&self.turned)) {
            return self.inner.finish_knowing(false);
        }
        let swapped = self.inner.clone().finish_knowing(true);
        if swapped.turned == 0 {
            return swapped;
        }
        let mut dropped = self.inner;
        let added = dropped.interior.len();
        // Its last round looked at every face: none is looked for again.
        let left = dropped.drop_turned_corners();
        let dropped = dropped.finish_knowing(left);
        if dropped.turned < swapped.turned
            && (added - dropped.interior.len()) as f64 <= MAX_DROPPED_SHARE * added as f64
        {
            dropped
        } else {
            swapped
        }
    }

    /// Whether, and why, the candidate's face is split at `plane` (its plane centroid; `point`
    /// and its height, the new vertex): not when that gives a face turned against its
    /// ellipsoid ([`RegionCdt::is_turned`]) that is not to be mended by splitting it in turn.
    ///
    /// On a thin ellipsoid the chart is far from isotropic (a region on radii 250 × 0.005 ×
    /// 0.007 is stretched fifty thousand times more along one axis than the others), so near
    /// the boundary a point inside a face in the plane can land beyond the face's edge on the
    /// surface, where the boundary's offsets have pulled the edge in: the new face across
    /// that edge is turned over. A turned face is split first ([`Self::push_face`]), but at
    /// the scale of the target edge length its splits are turned again until the boundary
    /// clearance or the spacing stops them, and a turned face is left (horse at K = 24: 198
    /// flipped triangles at 12 500 vertices). So a face at the target scale (no longer than
    /// [`STRICT_FACE_SPACINGS`] minimum spacings and, unless [`Self::judge_by_length`], its
    /// centroid within [`CURVED_FACE_SPACINGS`] of the surface) is not split into a turned
    /// face at all; any other, which spans enough of a curved surface that its first splits
    /// may be turned and mended by the next (the blobs' first splits, a finger's tip), only
    /// not into a turned face that cannot be split ([`Self::split_point`]). A refused face
    /// stays as it is.
    fn judge_split(&self, candidate: &Candidate, plane: DVec2, point: Lifted) -> Verdict {
        let handles = candidate.corners.map(|h| self.inner.cdt.vertex(h));
        let corners = handles.each_ref().map(|v| v.data());
        // Never inserted: its index is not used.
        let new = Vertex::interior(plane, point, u32::MAX);
        let edges = [[0, 1], [1, 2], [2, 0]];
        let mut turned = edges
            .iter()
            .map(|&[i, j]| [corners[i], corners[j], &new])
            .filter(|face| self.inner.is_turned(face.map(|v| v.point)))
            .peekable();
        if turned.peek().is_none() {
            return Verdict::Split;
        }
        let longest = edges
            .iter()
            .map(|&[i, j]| corners[i].point.distance(corners[j].point))
            .fold(0.0, f64::max);
        let short = longest <= STRICT_FACE_SPACINGS * self.min_spacing;
        let near = candidate.error <= CURVED_FACE_SPACINGS * self.min_spacing;
        if (short && (near || self.by_length))
            || turned.any(|face| self.split_point(face).is_none())
        {
            Verdict::Refuse
        } else if short {
            Verdict::SplitCurved
        } else {
            Verdict::Split
        }
    }

    /// Where the face with these corners (counter-clockwise in the plane) is split: the
    /// surface point at its plane centroid, its height the corners' mean (the blend is
    /// smooth over a face; the exact height is taken for the vertex inserted). `None` when
    /// the centroid is not a valid plane point, lies too close to a boundary edge at a corner
    /// ([`BOUNDARY_CLEARANCE`], [`CLEARANCE_SPACINGS`]), or the point too close to a corner
    /// (the minimum spacing).
    fn split_point(&self, corners: [&Vertex; 3]) -> Option<(DVec2, DVec3)> {
        let surface = &self.inner.surface;
        let plane = corners.iter().map(|c| c.plane()).sum::<DVec2>() / 3.0;
        if !is_valid_plane_point(plane) {
            return None;
        }
        let height = corners.iter().map(|c| c.height).sum::<f64>() / 3.0;
        let point = surface.at_height(plane, height);
        let clear = corners.iter().all(|c| {
            c.along.is_none_or(|along| {
                let corner = c.plane();
                // The chart length of CLEARANCE_SPACINGS minimum spacings here (the chart's
                // scale from the corner to the split point).
                let cap = CLEARANCE_SPACINGS * self.min_spacing * corner.distance(plane)
                    / c.point.distance(point);
                along.iter().all(|&(other, other_height)| {
                    let level =
                        c.height.abs().max(other_height.abs()) <= LEVEL_SPACINGS * self.min_spacing;
                    let length = match corner.distance(other) {
                        length if level && cap.is_finite() => length.min(cap),
                        length => length,
                    };
                    distance_to_segment(plane, corner, other) >= BOUNDARY_CLEARANCE * length
                })
            })
        });
        let spacing = self
            .min_spacing
            .max(SPACING_FLOOR * surface.chart.ellipsoid.radii.max_element());
        (clear && point.is_finite() && corners.iter().all(|c| c.point.distance(point) >= spacing))
            .then_some((plane, point))
    }

    /// Makes the face's candidate its entry in the heap, or removes its entry when it has
    /// none ([`Self::candidate`]).
    fn push_face(&mut self, face: FixedFaceHandle<InnerTag>) {
        let candidate = self.candidate(face);
        self.heap.set(face.index(), candidate);
    }

    /// The face's candidate; none when its split point is too close to a corner or not
    /// strictly inside it (or, mending, when it is not turned).
    fn candidate(&mut self, face: FixedFaceHandle<InnerTag>) -> Option<Candidate> {
        let face = self.inner.cdt.face(face);
        let vertices = face.vertices();
        let corners = vertices.each_ref().map(|v| v.data());
        let [pa, pb, pc] = corners.map(|c| c.point);
        // Every face vertex addition makes comes here (the faces an insertion makes are its
        // new vertex's star): the turned ones are noted for RegionCdt::swap_turned.
        let turned = self.inner.is_turned([pa, pb, pc]);
        if turned {
            self.turned.push(vertices.map(|v| v.fix()));
        } else if self.turned_only {
            return None;
        }
        let (plane, point) = self.split_point(corners)?;
        let centroid = (pa + pb + pc) / 3.0;
        let error = point.distance(centroid);
        if !error.is_finite() {
            return None;
        }
        // A face turned against its ellipsoid (the test the assembled mesh is checked with)
        // is the worst there is: it is split before any other, whatever the tolerance.
        let error = if turned { f64::INFINITY } else { error };
        let q = to_point(plane);
        face.adjacent_edges()
            .iter()
            .all(|e| e.side_query(q).is_on_left_side())
            .then(|| Candidate {
                error,
                corners: vertices.map(|v| v.fix()),
                face: face.fix().index() as u32,
            })
    }
}

/// The largest share of a region's interior vertices that [`AdaptiveTriangulation::finish`]
/// may remove to mend its turned faces: each removal can turn the face that fills its hole,
/// whose corners go in turn. The mended regions of the budgets sweep lost 1, 2, 43 of 311
/// and 78 of 332; a square with a hole on a sphere, refined with no minimum spacing, would
/// lose 457 of 500.
const MAX_DROPPED_SHARE: f64 = 0.25;

/// A minimum spacing must be finite and not negative ([`RemeshError::InvalidOption`]).
fn check_min_spacing(min_spacing: f64) -> Result<(), RemeshError> {
    if min_spacing >= 0.0 && min_spacing.is_finite() {
        Ok(())
    } else {
        Err(RemeshError::InvalidOption {
            what: "min_spacing",
            value: min_spacing.to_string(),
        })
    }
}

/// Faces up to this many minimum spacings long (eight target edge lengths: the adaptive
/// scheme's minimum spacing is a quarter of the target) are never split into a face turned
/// against the ellipsoid ([`AdaptiveTriangulation::judge_split`]).
/// Measured: horse K = 24 (the last release's file) at 12 500 vertices has 36, 4 and 4
/// flipped triangles at 4, 16 and 32 (198 without); at 32 hand K = 18 decodes clean on its
/// first meshing attempt at 5 000 vertices (at 16 on its third); at 64 blob3's large first
/// faces stop refining (RMS 2.5 % of the diagonal instead of 0.08 %).
const STRICT_FACE_SPACINGS: f64 = 32.0;

/// A face whose flat centroid lies more than this many minimum spacings (one target edge
/// length) from the surface is not at the target scale, however short: it cuts across a part
/// curved more sharply than the spacing, and is split even into faces turned against the
/// ellipsoid, which are split in turn ([`AdaptiveTriangulation::judge_split`]).
/// Its three corners on the sides of a finger near its tip, such a face was left as a flat
/// cut: hand K = 12 decoded 11 % of the diagonal from its source at 1 000 and 2 000 vertices
/// (4.1 % with this rule, as at 5 000), spot K = 24 8.4 % at 5 000 (1.9 %), penguin K = 12
/// 9.1 % at every budget (2.3–2.6 %). Measured on the small meshes at K = 12 and 24 and 1 000
/// to 12 500 vertices: at 3, horse K = 24 has a flipped triangle at 5 000; at 4 none has one
/// it did not have before. Where such splits do leave a turned face (dino K = 8's leg at
/// 3 000 vertices), the region is meshed again without them (`assemble`'s
/// `mend_curved_splits`).
const CURVED_FACE_SPACINGS: f64 = 4.0;

/// What [`AdaptiveTriangulation::judge_split`] decides for a face.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// Left whole: a face split from it would be turned against the ellipsoid and stay so.
    Refuse,
    /// Split.
    Split,
    /// Split into a face turned against the ellipsoid although at the target scale by its
    /// length, because its centroid lies far from the surface ([`CURVED_FACE_SPACINGS`]).
    SplitCurved,
}

/// Below this fraction of the largest radius two vertices count as one: a split point that
/// close to a corner is never inserted, whatever `min_spacing` says.
const SPACING_FLOOR: f64 = 1e-9;

/// A split point must lie at least this fraction of a boundary edge's chart length away from
/// it. Boundary edges are chords that interior vertices cannot improve: without a clearance
/// the worst faces along a coarse boundary would be split again and again, their new vertices
/// converging onto the edge (slivers whose error never drops). The centroid of a face whose
/// apex lies half an edge length from it is 1/6 of the length away, so faces along the
/// boundary are split until their apex is about that close, and no further.
///
/// A *level* edge (both ends within [`LEVEL_SPACINGS`] minimum spacings of the ellipsoid)
/// longer than [`CLEARANCE_SPACINGS`] minimum spacings counts as that long: measured
/// against the whole of a long edge, the clearance kept every face of a strip narrower than
/// about half its length from being split. A fillet of a CAD part between two straight
/// creases, its boundary simplified to the creases' ends, decoded as a few flat faces across
/// it: fandisk's file at K = 24 decoded 0.58 % of the diagonal RMS from its source, one
/// region 2.4 % (0.27 % with this rule).
const BOUNDARY_CLEARANCE: f64 = 0.15;

/// The longest a level boundary edge counts as for [`BOUNDARY_CLEARANCE`], in minimum
/// spacings (two target edge lengths). Measured on the 60 small shared meshes' files of the
/// last release decoded at their default density, RMS summed over the files, every edge
/// capped (level or not): 31.75 % at 4 (two files with a flipped triangle), 32.10 % at 8,
/// 32.28 % at 16, 33.17 % uncapped; level edges capped at 8: 32.24 %.
const CLEARANCE_SPACINGS: f64 = 8.0;

/// How far from the ellipsoid, in minimum spacings, both ends of a boundary edge may lie for
/// [`CLEARANCE_SPACINGS`] to apply. Near an edge far off the ellipsoid the boundary blend
/// climbs steeply and faces split close to it turned over: with every edge capped, the
/// budgets sweep (`cargo bench --bench clean -- --budgets`) decoded 114 of 120 files clean
/// instead of 117; with this, 115.
const LEVEL_SPACINGS: f64 = 4.0;

/// Distance from `p` to the segment `a`–`b`.
fn distance_to_segment(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * t)
}

/// The parametric scheme (section 5.2): a regular azimuth/elevation grid on the unit sphere
/// in the ellipsoid's own frame (its local axes, so the grid follows the ellipsoid's
/// parameterisation), the grid points inside the region and at least half a grid step (on
/// the unit sphere) from its boundary inserted (each nudged by a billionth of its chart
/// position, so that no four share a circle), the grid points at a corner of a face turned
/// against the ellipsoid dropped again (`RegionCdt::drop_turned_corners`), the inside faces
/// returned. Where a turned face is left (one between boundary points only: a region too
/// small for the grid, its boundary far off its ellipsoid) and diagonal swaps leave one too,
/// the turned faces are split as vertex addition splits them, its minimum spacing
/// `min_spacing` (model units), adding at most an eighth of `interior_vertices` or 64
/// vertices, if that leaves fewer.
///
/// `interior_vertices` is a target, not exact: the grid is sized from the region's share of
/// the sphere (the spherical area of its boundary-only triangulation), then resized once from
/// the count it gave; if it still gives more than twice the request, an evenly spread subset
/// of the requested size is kept. Very thin regions get a coarser grid: at most
/// `max(16·interior_vertices, 2¹⁶)` grid points are tested.
///
/// Errors: as [`AdaptiveTriangulation::new`] (a negative or non-finite `min_spacing` too).
pub fn triangulate_parametric(
    input: &RegionInput,
    interior_vertices: usize,
    min_spacing: f64,
) -> Result<RegionMesh, RemeshError> {
    check_min_spacing(min_spacing)?;
    let mut inner = RegionCdt::new(input)?;
    if interior_vertices > 0 {
        inner.insert_grid(interior_vertices);
    }
    if !inner.drop_turned_corners() {
        // No face is turned (its last round looked at every one): none is looked for again.
        return Ok(inner.finish_knowing(false));
    }
    // Diagonal swaps (RegionCdt::finish) mend some turned faces that splits would not: the
    // one with fewer turned faces is kept, the grid alone on a tie.
    let most = (interior_vertices / 8).max(MIN_MENDING_VERTICES);
    let split = AdaptiveTriangulation::mend(inner.clone(), min_spacing, most);
    let swapped = inner.finish();
    Ok(if split.turned < swapped.turned {
        split
    } else {
        swapped
    })
}

impl RegionCdt {
    /// Inserts the grid points of [`triangulate_parametric`] for a target of
    /// `interior_vertices` (at least 1).
    fn insert_grid(&mut self, interior_vertices: usize) {
        let target = interior_vertices as f64;
        let share = self.sphere_share().clamp(1e-12, 1.0);
        let mut asked = (target / (2.0 * share)).sqrt().ceil();
        let mut rows = self.grid_rows(asked, interior_vertices);
        let mut points = self.grid_points(rows, 1.0);
        // The rows resized by the miss (the share is an estimate, and a region's span of
        // elevations is not a whole sphere's), a few times, the closest grid kept.
        let (mut tried_rows, mut tried) = (rows, points.len());
        for _ in 0..MAX_ROW_RESIZES {
            let ratio = target / tried.max(1) as f64;
            if tried == 0 || (0.9..=1.1).contains(&ratio) {
                break;
            }
            asked = (asked * ratio.sqrt()).ceil();
            // The same rows (both capped, as for a region whose share is far
            // underestimated) give the same grid: it is not made again.
            let resized = self.grid_rows(asked, interior_vertices);
            if resized == tried_rows {
                break;
            }
            let found = self.grid_points(resized, 1.0);
            (tried_rows, tried) = (resized, found.len());
            if found.len().abs_diff(interior_vertices) < points.len().abs_diff(interior_vertices) {
                (rows, points) = (resized, found);
            }
        }
        // A band narrower than a row gets no grid point at the rows its share asks for: the
        // rows are doubled until one fits (a few times), and its azimuths thinned to the
        // target below.
        if points.is_empty() {
            let mut denser = rows;
            for _ in 0..MAX_ROW_DOUBLINGS {
                let more = self.grid_rows(2.0 * denser, interior_vertices);
                if more <= denser {
                    break;
                }
                denser = more;
                let found = self.grid_points(denser, 1.0);
                if !found.is_empty() {
                    (rows, points) = (denser, found);
                    break;
                }
            }
        }
        // Whole rows come near the target, not to it (a row of a grid of 50 is about 4 % of
        // its points): the azimuths are scaled by the miss, the cells a little off square,
        // and the closer grid kept. Where no rows came within 10 % (a band a few rows wide,
        // whose count jumps by a row at a time), they are scaled more.
        if !points.is_empty() {
            let scale = target / points.len() as f64;
            let most = if (0.9..=1.1).contains(&scale) {
                MAX_AZIMUTH_SCALE
            } else {
                MAX_BAND_AZIMUTH_SCALE
            };
            let room = self.azimuth_room(rows, interior_vertices).min(most);
            if (scale - 1.0).abs() > AZIMUTH_SCALE_SLACK {
                let scaled = self.grid_points(rows, scale.clamp(1.0 / most, room));
                if scaled.len().abs_diff(interior_vertices)
                    < points.len().abs_diff(interior_vertices)
                {
                    points = scaled;
                }
            }
        }
        // A share estimate far off (hostile or degenerate boundaries) can still overshoot: keep
        // an evenly spread subset, so the cost stays proportional to the request.
        if points.len() > 2 * interior_vertices {
            let stride = points.len() as f64 / interior_vertices as f64;
            points = (0..interior_vertices)
                .filter_map(|k| points.get((k as f64 * stride) as usize).copied())
                .collect();
        }
        // Lifted only now, for the points kept, in grid order, each with the clearance the point
        // before carries to it: the blend is searched only near the boundary (the same heights:
        // see OffsetBlend::height_and_clearance).
        let mut previous: Option<Lifted> = None;
        let points: Vec<(DVec2, Lifted)> = points
            .into_iter()
            .map(|plane| {
                let lifted = self.surface.point_height_and_clearance(plane, |x| {
                    previous.map_or(f64::NEG_INFINITY, |p| carried_clearance(p, x))
                });
                previous = Some(lifted);
                (plane, lifted)
            })
            .collect();
        // Each point is inserted next to the one before (spade locates it from there); the
        // first is located from a corner of its face. grid_points found every point inside
        // the region and clear of its boundary, so none lies on a boundary edge.
        let mut hint = None;
        for (plane, point) in points {
            let hint_here = match hint {
                Some(h) => h,
                None => {
                    let spade::PositionInTriangulation::OnFace(face) =
                        self.cdt.locate(to_point(plane))
                    else {
                        continue;
                    };
                    self.cdt.face(face).vertices()[0].fix()
                }
            };
            if let Some(v) = self.insert_interior(plane, point, hint_here) {
                hint = Some(v);
            }
        }
    }
}

/// How many times closer than the plain grid's azimuth step (π / rows) a row's neighbours
/// may lie ([`RegionCdt::grid_points`]): only the rows within about 14° of a pole are
/// thinned (cos(elevation) below 1/4). At 1, every row's neighbours lie an elevation step
/// apart on the sphere (a grid of even density), and on the blobs the parametric scheme
/// came closer to the surface than vertex addition: RMS from the ellipsoids 8–16 % lower at
/// 1 000 to 5 000 vertices (from the source, blob1 at about 1 500: 0.074 % of the diagonal
/// against 0.084 %), against the paper's Figure 8, which compares with its plain grid
/// (`tests/remesh.rs`); at 4 it stays the paper's grid but near its poles.
const POLE_ROW_SPACINGS: f64 = 4.0;

/// How far from its target a grid's count may be before [`RegionCdt::insert_grid`] scales its
/// azimuths (a share of the target).
const AZIMUTH_SCALE_SLACK: f64 = 0.002;

/// The most [`RegionCdt::insert_grid`] scales a grid's azimuths by (or divides them by): its
/// cells stay within a quarter of square.
const MAX_AZIMUTH_SCALE: f64 = 1.25;

/// The most [`RegionCdt::insert_grid`] scales a grid's azimuths by (or divides them by)
/// where no rows come within 10 % of the target: a band a few rows wide (a band narrower
/// than a row of the grid its share asks for is gridded with rows denser by up to
/// 2^[`MAX_ROW_DOUBLINGS`] until a row fits, and that row thinned to its share).
const MAX_BAND_AZIMUTH_SCALE: f64 = 8.0;

/// How many times [`RegionCdt::insert_grid`] doubles the rows for a band no row fits in.
const MAX_ROW_DOUBLINGS: usize = 4;

/// How many times [`RegionCdt::insert_grid`] resizes the rows by a grid's miss (more than
/// 10 %) before it scales the azimuths.
const MAX_ROW_RESIZES: usize = 3;

/// Relative size of the nudge [`nudge_grid_point`] gives each grid point in the chart.
const GRID_NUDGE: f64 = 1e-9;

/// Grid point (`row`, `column`)'s chart position `plane`, scaled by 1 ± [`GRID_NUDGE`] (a
/// fixed pseudo-random factor per point). A row of the grid projects to a circle, and so do
/// the four corners of each of its cells (an isosceles trapezoid on the sphere is cyclic, and
/// stereographic projection keeps circles): spade's incircle test, asked about four points
/// on one circle, falls back to exact arithmetic, which cost a third of the parametric
/// scheme's time. Nudged far below any tolerance, no four points share a circle and the
/// quick test decides. Measured (callgrind, whole decodes at 20 000 vertices): hand K = 18
/// 2 674 -> 1 963 M instructions, teddy K = 8 2 363 -> 1 338 M, bunny K = 8 4 306 -> 2 329 M;
/// on the 16 shared meshes' files at K = 24 and hand's at K = 18, at 3 000 and 20 000
/// vertices, the same 21 of 34 decodes clean and RMS errors summed 10.747 -> 10.750 % of the
/// diagonal.
fn nudge_grid_point(plane: DVec2, row: usize, column: usize) -> DVec2 {
    let mut rng = SplitMix64::new(((row as u64) << 32) ^ column as u64);
    plane * (1.0 + GRID_NUDGE * rng.range_f64(-1.0, 1.0))
}

/// Largest number of grid points [`triangulate_parametric`] tests, at least.
const MIN_GRID_BUDGET: f64 = (1u64 << 16) as f64;

impl RegionCdt {
    /// A vertex's direction on the chart's unit sphere (from its chart position: interior
    /// points lie off the chart's ellipsoid once lifted or displaced).
    fn sphere_direction(&self, v: &Vertex) -> DVec3 {
        let p = v.position();
        self.surface.chart.plane_to_sphere(DVec2::new(p.x, p.y))
    }

    /// The region's share of the unit sphere: the spherical area of its inside faces' corner
    /// directions over 4π.
    fn sphere_share(&self) -> f64 {
        let area: f64 = self
            .cdt
            .inner_faces()
            .filter(|f| *f.data())
            .map(|f| {
                let [a, b, c] = f.vertices().map(|v| self.sphere_direction(v.data()));
                // Van Oosterom & Strackee: tan(E/2) = |a·(b×c)| / (1 + a·b + b·c + c·a).
                let numerator = a.dot(b.cross(c)).abs();
                let denominator = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
                2.0 * numerator.atan2(denominator)
            })
            .sum();
        area / (4.0 * std::f64::consts::PI)
    }

    /// The rows of the grid [`Self::grid_points`] makes when `rows` are asked for a target of
    /// `target` points: whole, at least 2, and few enough that at most
    /// max(16·`target`, [`MIN_GRID_BUDGET`]) grid points are tested.
    fn grid_rows(&self, rows: f64, target: usize) -> f64 {
        let (budget, span) = self.grid_budget(target);
        // Rows within the range times 2·rows azimuths must stay within the budget, and a band
        // narrower than one row still costs a whole row: 2·rows azimuths at most the budget
        // (a hostile sliver of a region spanning 10⁻⁹ of the elevations asked for 5.7 million
        // rows, and tested 11 million azimuths in each of the rows it crossed: 16 s).
        rows.min((budget / (2.0 * span)).sqrt())
            .min(budget / 2.0)
            .max(2.0)
            .floor()
    }

    /// How many times more azimuths than 2·`rows` a grid for a target of `target` points may
    /// test within the budget of [`Self::grid_rows`] (at least 1).
    fn azimuth_room(&self, rows: f64, target: usize) -> f64 {
        let (budget, span) = self.grid_budget(target);
        (budget / (2.0 * rows * (rows * span).max(1.0))).max(1.0)
    }

    /// The most grid points a grid for a target of `target` points may test, and the share
    /// of the elevations the region spans.
    fn grid_budget(&self, target: usize) -> (f64, f64) {
        let (low, high) = self.elevation_range();
        let budget = (16.0 * target as f64).max(MIN_GRID_BUDGET);
        let span = ((high - low) / std::f64::consts::PI).clamp(1e-9, 1.0);
        (budget, span)
    }

    /// The grid points with `rows` elevations (as [`Self::grid_rows`] gives them) and
    /// 2·`rows`·`azimuth_scale` azimuths in each row (`azimuth_scale` 1 for the paper's
    /// square cells), fewer near the poles (no closer than a [`POLE_ROW_SPACINGS`]th of that
    /// azimuth step, at least one per row), that lie inside the region (in an inside face of
    /// the boundary-only triangulation) and at least half an elevation step from every
    /// boundary edge, as chart positions, row by row.
    ///
    /// The grid's poles are the ends of the ellipsoid's local z axis. With 2·`rows`
    /// azimuths in every row (the plain grid), a region holding one crowded the rows round
    /// it, and the triangles between neighbours in a row were slivers: hand's file at its
    /// default K (12 regions) meshed at 200 000 vertices had 1 040 triangles of less than
    /// 10⁻¹⁴ of the squared diagonal (neighbours 2·10⁻⁶ of the diagonal apart) in one
    /// region, and took 11 meshings (27 s) to find a treatment without them; now one
    /// (1.8 s).
    fn grid_points(&self, rows: f64, azimuth_scale: f64) -> Vec<DVec2> {
        use std::f64::consts::{FRAC_PI_2, PI};
        let (low, high) = self.elevation_range();
        let step = PI / rows;
        let clearance = 0.5 * step;
        let near = SegmentGrid::new(&self.segments, clearance);
        let first = ((low + FRAC_PI_2) / step - 0.5).floor().max(0.0) as usize;
        let last = (((high + FRAC_PI_2) / step - 0.5).ceil().max(0.0) as usize).min(rows as usize);
        // An inside face lies within its corners' box: a grid point outside it is in none,
        // and is not located (most of a row lies outside the region).
        let (mut box_low, mut box_high) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for face in self.cdt.inner_faces().filter(|f| *f.data()) {
            for v in face.vertices() {
                box_low = box_low.min(v.data().plane());
                box_high = box_high.max(v.data().plane());
            }
        }

        let mut points = Vec::new();
        let mut hint: Option<FixedVertexHandle> = None;
        // Where the row before began: the next row's first point is next to it (the last
        // point of a row is half way round).
        let mut row_start: Option<FixedVertexHandle> = None;
        for i in first..last {
            let elevation = -FRAC_PI_2 + (i as f64 + 0.5) * step;
            let (sin_el, cos_el) = elevation.sin_cos();
            hint = row_start.or(hint);
            row_start = None;
            let columns = (azimuth_scale * 2.0 * rows)
                .min(POLE_ROW_SPACINGS * azimuth_scale * 2.0 * rows * cos_el)
                .round()
                .max(1.0);
            let azimuth_step = 2.0 * PI / columns;
            for j in 0..columns as usize {
                let (sin_az, cos_az) = ((j as f64 + 0.5) * azimuth_step).sin_cos();
                let u = DVec3::new(cos_el * cos_az, cos_el * sin_az, sin_el);
                let plane = nudge_grid_point(self.surface.chart.sphere_to_plane(u), i, j);
                if !is_valid_plane_point(plane)
                    || plane.cmplt(box_low).any()
                    || plane.cmpgt(box_high).any()
                {
                    continue;
                }
                let at = match hint {
                    Some(h) => self.cdt.locate_with_hint(to_point(plane), h),
                    None => self.cdt.locate(to_point(plane)),
                };
                let spade::PositionInTriangulation::OnFace(face) = at else {
                    continue;
                };
                let face = self.cdt.face(face);
                hint = Some(face.vertices()[0].fix());
                row_start = row_start.or(hint);
                if !*face.data() || near.is_near(u) {
                    continue;
                }
                points.push(plane);
            }
        }
        points
    }

    /// The elevations (local frame, radians) the region spans: the extremes of its inside
    /// faces' great-circle edges, widened to a pole the region contains.
    fn elevation_range(&self) -> (f64, f64) {
        use std::f64::consts::FRAC_PI_2;
        let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
        for face in self.cdt.inner_faces().filter(|f| *f.data()) {
            let corners = face.vertices().map(|v| self.sphere_direction(v.data()));
            for k in 0..3 {
                let (a, b) = (corners[k], corners[(k + 1) % 3]);
                let (z_low, z_high) = arc_z_range(a, b);
                low = low.min(z_low);
                high = high.max(z_high);
            }
        }
        for (pole, z) in [(DVec3::Z, 1.0), (DVec3::NEG_Z, -1.0)] {
            let plane = self.surface.chart.sphere_to_plane(pole);
            if is_valid_plane_point(plane) {
                if let spade::PositionInTriangulation::OnFace(f) = self.cdt.locate(to_point(plane))
                {
                    if *self.cdt.face(f).data() {
                        low = low.min(z);
                        high = high.max(z);
                    }
                }
            }
        }
        if low > high {
            return (-FRAC_PI_2, FRAC_PI_2);
        }
        (low.clamp(-1.0, 1.0).asin(), high.clamp(-1.0, 1.0).asin())
    }
}

/// Most rounds of [`RegionCdt::drop_turned_corners`]. igea's file at K = 24 meshed
/// parametrically at 20 000 vertices needs 27 (a region whose boundary has chords as long as
/// its ellipsoid's smallest radius).
const MAX_DROP_ROUNDS: usize = 64;

/// The fewest vertices [`triangulate_parametric`] may add to mend the faces left turned
/// against the ellipsoid (an eighth of the request if more).
const MIN_MENDING_VERTICES: usize = 64;

impl RegionCdt {
    /// Removes the interior vertices (grid points, or vertex addition's) that are corners of
    /// faces turned against the ellipsoid ([`RegionCdt::is_turned`]), round after round
    /// until none is left (at most [`MAX_DROP_ROUNDS`]); then numbers the interior vertices
    /// left in order. Whether a turned face is left (one with no interior vertex, or after
    /// the last round).
    ///
    /// The grid does not know the boundary's shape: near a boundary chord that cuts deep
    /// under a curved ellipsoid (its stored points far apart), a face from the chord to a
    /// grid point close to it stands across the surface and is turned over; so are the
    /// faces that fan from one point to a denser row beside it. Vertex addition never makes
    /// such a face ([`AdaptiveTriangulation::insert_worst`] refuses the split); here the
    /// points are dropped instead, and the faces that fill their holes reach farther. On the
    /// 16 shared meshes' files at K = 24 and hand's at K = 18, at 3 000 and 20 000 vertices,
    /// 21 of 34 parametric decodes were clean before (1–18 flipped triangles left in the
    /// others after every meshing attempt), all 34 with this.
    fn drop_turned_corners(&mut self) -> bool {
        let mut dropped = false;
        let mut turned = false;
        for round in 0..=MAX_DROP_ROUNDS {
            let mut drop: Vec<Point2<f64>> = Vec::new();
            turned = false;
            for face in self.cdt.inner_faces().filter(|f| *f.data()) {
                let corners = face.vertices();
                if self.is_turned(corners.each_ref().map(|v| v.data().point)) {
                    turned = true;
                    drop.extend(
                        corners
                            .iter()
                            .filter(|v| matches!(v.data().corner, Corner::Interior(_)))
                            .map(|v| v.data().position),
                    );
                }
            }
            if drop.is_empty() || round == MAX_DROP_ROUNDS {
                break;
            }
            // Each removal renumbers handles: the points are found by position.
            for position in drop {
                if let spade::PositionInTriangulation::OnVertex(v) = self.cdt.locate(position) {
                    self.cdt.remove(v);
                    dropped = true;
                }
            }
            // The faces that fill a hole are new, not marked: the region's interior
            // vertices are strictly inside it, so marking again keeps the rest.
            if mark_inside(&mut self.cdt).is_none() {
                break;
            }
        }
        if dropped {
            self.renumber_interior();
        }
        turned
    }

    /// Numbers the interior vertices left in the triangulation 0, 1, … in the order they
    /// were inserted, and keeps only their points in [`RegionCdt::interior`].
    fn renumber_interior(&mut self) {
        let mut left: Vec<(u32, FixedVertexHandle)> = self
            .cdt
            .fixed_vertices()
            .filter_map(|v| match self.cdt.vertex(v).data().corner {
                Corner::Interior(i) => Some((i, v)),
                Corner::Boundary(_) => None,
            })
            .collect();
        left.sort_unstable_by_key(|&(i, _)| i);
        let mut interior = Vec::with_capacity(left.len());
        for (i, v) in left {
            let Some(&point) = self.interior.get(i as usize) else {
                continue;
            };
            self.cdt.vertex_data_mut(v).corner = Corner::Interior(interior.len() as u32);
            interior.push(point);
        }
        self.interior = interior;
    }
}

/// The range of z along the shorter great-circle arc from unit vector `a` to `b`.
fn arc_z_range(a: DVec3, b: DVec3) -> (f64, f64) {
    let (mut low, mut high) = (a.z.min(b.z), a.z.max(b.z));
    let normal = a.cross(b);
    if let Some(n) = normal.try_normalize() {
        // The circle's highest point is the pole's projection onto its plane.
        if let Some(top) = (DVec3::Z - n * n.z).try_normalize() {
            for extreme in [top, -top] {
                // On the arc iff it lies between a and b.
                if a.cross(extreme).dot(normal) >= 0.0 && extreme.cross(b).dot(normal) >= 0.0 {
                    low = low.min(extreme.z);
                    high = high.max(extreme.z);
                }
            }
        }
    }
    (low, high)
}

/// The boundary's length over this is the least cell size of [`SegmentGrid::new`]: the
/// boundary is cut into at most this many pieces of a cell or less, plus one per segment.
const MAX_GRID_PIECES: f64 = (1u64 << 14) as f64;

/// The width of [`SegmentGrid`]'s cells in clearances. A piece of a segment is listed in
/// every cell its box, grown by the clearance, touches: 27 to 64 cells when they are as wide
/// as the clearance, and building the lists took a quarter of a parametric decode. At 4 the
/// lists are several times shorter, each cell lists a few more segments, and the grid points
/// kept are the same (212 parametric decodes byte-identical). Instructions (callgrind) at
/// 20 000 vertices, cells one clearance wide -> four: teddy K = 24 1 155 -> 827 M, bunny
/// K = 24 2 485 -> 1 880 M, hand K = 18 1 898 -> 1 519 M, teddy K = 8 1 339 -> 1 227 M,
/// bunny K = 8 (volume) 2 360 -> 2 118 M.
const SEGMENT_CELL_CLEARANCES: f64 = 4.0;

/// Boundary segments (unit-sphere chords) bucketed in a uniform grid of cells
/// [`SEGMENT_CELL_CLEARANCES`] times as large as the clearance (larger on a long boundary,
/// see [`MAX_GRID_PIECES`]), to find the grid points closer than the clearance to the
/// boundary. The buckets are one sorted list of (cell, segment) pairs, a cell's segments
/// found by binary search.
struct SegmentGrid<'a> {
    segments: &'a [[DVec3; 2]],
    clearance: f64,
    cell: f64,
    /// (cell, segment) pairs, sorted, without repeats.
    entries: Vec<([i64; 3], u32)>,
}

impl<'a> SegmentGrid<'a> {
    fn new(segments: &'a [[DVec3; 2]], clearance: f64) -> SegmentGrid<'a> {
        // Cells SEGMENT_CELL_CLEARANCES clearances wide, or larger where the boundary is so
        // long that the pieces would outnumber MAX_GRID_PIECES (a hostile file's tiny
        // clearance once asked for gigabytes); a larger cell only lists more segments per
        // cell.
        let length: f64 = segments.iter().map(|&[a, b]| a.distance(b)).sum();
        let cell = (SEGMENT_CELL_CLEARANCES * clearance)
            .max(1e-9)
            .max(length / MAX_GRID_PIECES);
        let mut entries: Vec<([i64; 3], u32)> = Vec::new();
        for (index, &[a, b]) in segments.iter().enumerate() {
            // Pieces no longer than a cell, each registered in the cells its box (grown by
            // the clearance) touches.
            let pieces = ((a.distance(b) / cell).ceil() as usize).clamp(1, 1 << 16);
            for p in 0..pieces {
                let from = a.lerp(b, p as f64 / pieces as f64);
                let to = a.lerp(b, (p + 1) as f64 / pieces as f64);
                let lo = Self::key(from.min(to) - DVec3::splat(clearance), cell);
                let hi = Self::key(from.max(to) + DVec3::splat(clearance), cell);
                for x in lo[0]..=hi[0] {
                    for y in lo[1]..=hi[1] {
                        for z in lo[2]..=hi[2] {
                            entries.push(([x, y, z], index as u32));
                        }
                    }
                }
            }
        }
        entries.sort_unstable();
        entries.dedup();
        SegmentGrid {
            segments,
            clearance,
            cell,
            entries,
        }
    }

    fn key(p: DVec3, cell: f64) -> [i64; 3] {
        let k = (p / cell).floor();
        [k.x as i64, k.y as i64, k.z as i64]
    }

    /// Whether `u` lies closer than the clearance to a boundary segment.
    fn is_near(&self, u: DVec3) -> bool {
        let clearance = self.clearance;
        let key = Self::key(u, self.cell);
        let first = self.entries.partition_point(|&(k, _)| k < key);
        self.entries
            .get(first..)
            .unwrap_or_default()
            .iter()
            .take_while(|&&(k, _)| k == key)
            .any(|&(_, i)| {
                self.segments
                    .get(i as usize)
                    .is_some_and(|&[a, b]| crate::compare::distance_to_segment(u, a, b) < clearance)
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ellipsoid::{Ellipsoid, Sign};
    use crate::rng::SplitMix64;

    fn sphere(sign: Sign) -> Ellipsoid {
        Ellipsoid {
            sign,
            ..Ellipsoid::sphere(DVec3::new(1.0, 2.0, 3.0), 2.0)
        }
    }

    /// A square loop (`inner` = a smaller one inside, reversed, as a hole) around the south
    /// pole of a sphere charted from its north pole.
    fn square_with_hole(e: &Ellipsoid) -> (RegionChart, Vec<DVec3>, Vec<Vec<u32>>) {
        let chart = RegionChart::with_pole(e, DVec3::Z);
        let corner = |x: f64, y: f64| chart.from_plane(DVec2::new(x, y));
        let boundary = vec![
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
            corner(-0.3, -0.3),
            corner(0.3, -0.3),
            corner(0.3, 0.3),
            corner(-0.3, 0.3),
        ];
        (chart, boundary, vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]])
    }

    #[test]
    fn flood_fill_marks_the_ring_between_loops() {
        let e = sphere(Sign::Negative);
        let (chart, boundary, loops) = square_with_hole(&e);
        let input = RegionInput {
            region: 0,
            surface: &RegionSurface::new(chart.clone()),
            boundary: &boundary,
            loops: &loops,
            seeds: &[],
            expected_vertices: 0,
        };
        let cdt = RegionCdt::new(&input).unwrap();
        let mut inside = 0;
        for f in cdt.cdt.inner_faces() {
            let c = f.center();
            let r = c.x.abs().max(c.y.abs());
            assert_eq!(*f.data(), r > 0.3 && r < 1.0, "face centred at {c:?}");
            inside += usize::from(*f.data());
        }
        // The ring between two squares: 8 triangles.
        assert_eq!(inside, 8);
    }

    #[test]
    fn chart_handedness_is_the_analytic_one() {
        // The inverse stereographic projection from the north pole reverses orientation with
        // respect to the outward normal; the ellipsoid's affine map keeps it; a negative
        // ellipsoid's signed normal points inward.
        let mut rng = SplitMix64::new(3);
        for sign in [Sign::Positive, Sign::Negative] {
            for _ in 0..20 {
                let e = Ellipsoid {
                    center: DVec3::ZERO,
                    rotation: glam::DQuat::from_axis_angle(rng.unit_vector(), 1.3),
                    radii: DVec3::new(0.5, 2.0, 1.0),
                    sign,
                };
                let chart = RegionChart::with_pole(&e, rng.unit_vector());
                let q = DVec2::new(rng.range_f64(-3.0, 3.0), rng.range_f64(-3.0, 3.0));
                assert_eq!(
                    plane_is_counter_clockwise(&chart, q),
                    Some(sign == Sign::Negative)
                );
            }
        }
    }

    #[test]
    fn arc_z_range_finds_interior_extremes() {
        let mut rng = SplitMix64::new(5);
        for _ in 0..200 {
            let (a, b) = (rng.unit_vector(), rng.unit_vector());
            let (low, high) = arc_z_range(a, b);
            // Brute force along the arc (slerp).
            let angle = a.angle_between(b);
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..=1000 {
                let t = k as f64 / 1000.0;
                let p = (a * ((1.0 - t) * angle).sin() + b * (t * angle).sin()) / angle.sin();
                lo = lo.min(p.z);
                hi = hi.max(p.z);
            }
            assert!((low - lo).abs() < 1e-5 && (high - hi).abs() < 1e-5);
        }
    }

    #[test]
    fn segment_grid_agrees_with_brute_force() {
        let mut rng = SplitMix64::new(9);
        let points: Vec<DVec3> = (0..40).map(|_| rng.unit_vector()).collect();
        let segments: Vec<[DVec3; 2]> = points
            .iter()
            .zip(points.iter().cycle().skip(1))
            .map(|(&a, &b)| [a, b])
            .collect();
        let clearance = 0.05;
        let grid = SegmentGrid::new(&segments, clearance);
        for _ in 0..5000 {
            let u = rng.unit_vector();
            let brute = segments
                .iter()
                .any(|&[a, b]| crate::compare::distance_to_segment(u, a, b) < clearance);
            assert_eq!(grid.is_near(u), brute);
        }
    }

    #[test]
    fn grid_points_are_every_grid_point_inside_and_clear() {
        // The elevation band and the box that spare grid_points most locations must not
        // lose a point: it keeps, in order, exactly the (nudged) grid points that an unhinted
        // locate puts in an inside face at least half a step from the boundary. A ring round the
        // chart's south pole, and a square off to one side of a tilted pole's chart.
        use std::f64::consts::{FRAC_PI_2, PI};
        let e = sphere(Sign::Positive);
        let (ring_chart, ring, ring_loops) = square_with_hole(&e);
        let tilted = RegionChart::with_pole(&e, DVec3::new(0.3, -0.2, 1.0));
        let square: Vec<DVec3> = [(0.7, 1.9), (1.9, 1.9), (2.0, 0.7), (0.8, 0.6)]
            .map(|(x, y)| tilted.from_plane(DVec2::new(x, y)))
            .to_vec();
        let cases = [
            (ring_chart, ring, ring_loops),
            (tilted, square, vec![vec![0, 1, 2, 3]]),
        ];
        for (chart, boundary, loops) in &cases {
            let input = RegionInput {
                region: 0,
                surface: &RegionSurface::new(chart.clone()),
                boundary,
                loops,
                seeds: &[],
                expected_vertices: 0,
            };
            let cdt = RegionCdt::new(&input).unwrap();
            for rows in [20.0, 40.0, 101.0] {
                let step = PI / rows;
                let near = SegmentGrid::new(&cdt.segments, 0.5 * step);
                let mut expected = Vec::new();
                for i in 0..rows as usize {
                    let elevation = -FRAC_PI_2 + (i as f64 + 0.5) * step;
                    for j in 0..2 * rows as usize {
                        let azimuth = (j as f64 + 0.5) * step;
                        let u = DVec3::new(
                            elevation.cos() * azimuth.cos(),
                            elevation.cos() * azimuth.sin(),
                            elevation.sin(),
                        );
                        let plane = nudge_grid_point(cdt.surface.chart.sphere_to_plane(u), i, j);
                        if !is_valid_plane_point(plane) {
                            continue;
                        }
                        if let spade::PositionInTriangulation::OnFace(f) =
                            cdt.cdt.locate(to_point(plane))
                        {
                            if *cdt.cdt.face(f).data() && !near.is_near(u) {
                                expected.push(plane);
                            }
                        }
                    }
                }
                assert!(expected.len() > 4, "{rows} rows: {}", expected.len());
                assert_eq!(cdt.grid_points(rows, 1.0), expected, "{rows} rows");
            }
        }
    }

    #[test]
    fn adaptive_output_is_deterministic_and_respects_min_spacing() {
        let e = sphere(Sign::Positive);
        let (chart, boundary, loops) = square_with_hole(&e);
        let input = RegionInput {
            region: 0,
            surface: &RegionSurface::new(chart.clone()),
            boundary: &boundary,
            loops: &loops,
            seeds: &[],
            expected_vertices: 0,
        };
        let run = |spacing: f64| {
            let mut tri = AdaptiveTriangulation::new(&input, spacing).unwrap();
            while tri.added() < 500 && tri.insert_worst() {}
            tri.finish()
        };
        assert_eq!(run(0.0), run(0.0));
        // With a spacing of 0.3 (the region spans about 1.6) the refinement runs out of
        // candidates early (67 vertices); without it, it does not.
        let spaced = run(0.3);
        assert!(
            (1..500).contains(&spaced.interior.len()),
            "{}",
            spaced.interior.len()
        );
        assert_eq!(run(0.0).interior.len(), 500);
    }

    /// Every heap entry is a face as it is now: its three corners form an inside face, with
    /// the face index the entry names, and the heap knows each entry's place; checked for
    /// every entry after each of 300 insertions, on a region with a hole. Most inside faces
    /// have an entry (with no minimum spacing, only those along the boundary's clearance do
    /// not).
    #[test]
    fn every_candidate_is_a_face_as_it_is_now() {
        let e = sphere(Sign::Positive);
        let (chart, boundary, loops) = square_with_hole(&e);
        let surface = RegionSurface::new(chart);
        let input = RegionInput {
            region: 0,
            surface: &surface,
            boundary: &boundary,
            loops: &loops,
            seeds: &[],
            expected_vertices: 0,
        };
        let mut tri = AdaptiveTriangulation::new(&input, 0.0).unwrap();
        let mut checked = 0;
        while tri.added() < 300 && tri.insert_worst() {
            let heap = &tri.heap;
            for (place, candidate) in heap.entries.iter().enumerate() {
                let [a, b, c] = candidate.corners;
                let edge = tri.inner.cdt.get_edge_from_neighbors(a, b).unwrap();
                let face = edge.face().as_inner().unwrap();
                assert!(*face.data());
                assert_eq!(edge.next().to().fix(), c);
                assert_eq!(face.fix().index(), candidate.face as usize);
                assert_eq!(heap.places[candidate.face as usize], place as u32);
                checked += 1;
            }
            let with_entry = heap.places.iter().filter(|&&p| p != NO_ENTRY).count();
            assert_eq!(with_entry, heap.entries.len());
            let inside = tri.inner.cdt.inner_faces().filter(|f| *f.data()).count();
            assert!(
                2 * heap.entries.len() > inside,
                "{} of {inside}",
                heap.entries.len()
            );
        }
        assert_eq!(tri.added(), 300);
        assert!(checked > 10_000, "{checked}");
    }

    /// The candidate heap against a plain binary heap of the same candidates, rebuilt from
    /// each face's latest candidate: the same worst candidate after every one of 20 000
    /// random changes (a face's candidate set, replaced or removed, or the worst popped),
    /// with ties in error broken by the corners as `Candidate`'s order says.
    #[test]
    fn the_candidate_heap_gives_the_worst_candidate_first() {
        use std::collections::BinaryHeap;
        let mut rng = SplitMix64::new(7);
        let mut heap = CandidateHeap::default();
        // The model: each face's candidate.
        let mut latest: Vec<Option<Candidate>> = vec![None; 300];
        let handle = |i: u64| FixedVertexHandle::from_index(i as usize);
        for step in 0..20_000 {
            let face = (rng.next_u64() % 300) as usize;
            match rng.next_u64() % 4 {
                0 => {
                    let popped = heap.pop();
                    let reference: BinaryHeap<Candidate> =
                        latest.iter().flatten().copied().collect();
                    let expected = reference.peek().copied();
                    assert_eq!(
                        popped.map(|c| c.face),
                        expected.map(|c| c.face),
                        "step {step}"
                    );
                    if let Some(c) = popped {
                        latest[c.face as usize] = None;
                    }
                }
                1 => {
                    heap.set(face, None);
                    latest[face] = None;
                }
                _ => {
                    // Few distinct errors, so that ties are common.
                    let error = match rng.next_u64() % 8 {
                        0 => f64::INFINITY,
                        k => k as f64,
                    };
                    let corner = rng.next_u64() % 50;
                    let c = Candidate {
                        error,
                        corners: [handle(corner), handle(corner + 1), handle(face as u64)],
                        face: face as u32,
                    };
                    heap.set(face, Some(c));
                    latest[face] = Some(c);
                }
            }
            let reference: BinaryHeap<Candidate> = latest.iter().flatten().copied().collect();
            assert_eq!(heap.entries.len(), reference.len(), "step {step}");
            assert_eq!(
                heap.peek().map(|c| c.face),
                reference.peek().map(|c| c.face),
                "step {step}"
            );
        }
    }

    /// A strip along an elongated ellipsoid (radii 1, 1, 8; the decoder's charts cap
    /// radii at four times a region's reach), six long and 0.2 wide, between two long
    /// boundary edges (a fillet of a CAD part: its straight boundary simplified to its
    /// ends). Faces along a long edge have their centroids closer to it than 0.15 of its
    /// length: with the clearance measured against whole edges, refinement ran out of faces
    /// to split after 175 vertices; measured against edges no longer than
    /// [`CLEARANCE_SPACINGS`] minimum spacings, the strip takes the 400 asked for.
    #[test]
    fn a_strip_between_long_boundary_edges_is_refined() {
        let e = Ellipsoid {
            center: DVec3::ZERO,
            rotation: glam::DQuat::IDENTITY,
            radii: DVec3::new(1.0, 1.0, 8.0),
            sign: Sign::Positive,
        };
        let on_surface = |phi: f64, z: f64| {
            let r = (1.0 - (z / 8.0) * (z / 8.0)).sqrt();
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        };
        // Counter-clockwise seen from outside (+x): across the bottom, up the long edge at
        // φ = 0.1, back across the top, down the long edge at φ = −0.1.
        let mut boundary = Vec::new();
        for k in 0..=4 {
            boundary.push(on_surface(-0.1 + f64::from(k) / 20.0, -3.0));
        }
        for k in 0..=4 {
            boundary.push(on_surface(0.1 - f64::from(k) / 20.0, 3.0));
        }
        let loops = vec![(0..boundary.len() as u32).collect::<Vec<u32>>()];
        let chart = RegionChart::with_pole(&e, -DVec3::X);
        let input = RegionInput {
            region: 0,
            surface: &RegionSurface::new(chart),
            boundary: &boundary,
            loops: &loops,
            seeds: &[],
            expected_vertices: 0,
        };
        let mut tri = AdaptiveTriangulation::new(&input, 0.01).unwrap();
        while tri.added() < 400 && tri.insert_worst() {}
        let added = tri.added();
        let mesh = tri.finish();
        assert_eq!(added, 400, "the strip ran out of faces to split");
        assert_eq!(mesh.turned, 0);
        for p in &mesh.interior {
            let off = ((*p / e.radii).length() - 1.0).abs();
            assert!(off <= 1e-9, "an interior vertex lies {off} off the surface");
        }
    }

    /// Quadrilateral regions on a sphere, corners raised or sunk at random: wherever the
    /// chart's Delaunay diagonal leaves a face turned against the sphere and the other
    /// diagonal would turn neither face (and keep both faces' areas), the region comes out
    /// with the other diagonal; no region comes out with more turned faces than before.
    #[test]
    fn a_turned_face_is_mended_by_swapping_its_diagonal() {
        let e = Ellipsoid {
            radii: DVec3::new(0.4, 2.0, 1.0),
            ..sphere(Sign::Positive)
        };
        let chart = RegionChart::with_pole(&e, DVec3::Z);
        let surface = RegionSurface::new(chart.clone());
        let turned = |t: [DVec3; 3]| {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            n.dot(e.normal((t[0] + t[1] + t[2]) / 3.0)) < 0.0
        };
        let area = |t: [DVec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).length();
        let plane_area = |t: [DVec2; 3]| (t[1] - t[0]).perp_dot(t[2] - t[0]);
        let mut rng = SplitMix64::new(11);
        let (mut mendable, mut before_total, mut after_total) = (0, 0, 0);
        for _ in 0..10_000 {
            let boundary: Vec<DVec3> = (0..4)
                .map(|k| {
                    let angle = k as f64 * std::f64::consts::FRAC_PI_2 + rng.range_f64(-0.5, 0.5);
                    let x = chart.from_plane(DVec2::from_angle(angle) * rng.range_f64(0.2, 2.0));
                    x + 0.5 * rng.unit_vector()
                })
                .collect();
            let plane: Vec<DVec2> = boundary.iter().map(|&p| chart.to_plane(p)).collect();
            let loops = vec![vec![0, 1, 2, 3]];
            let input = RegionInput {
                region: 0,
                surface: &surface,
                boundary: &boundary,
                loops: &loops,
                seeds: &[],
                expected_vertices: 0,
            };
            let Ok(cdt) = RegionCdt::new(&input) else {
                continue;
            };
            if cdt.cdt.num_vertices() != 4 {
                continue;
            }
            let delaunay: Vec<[usize; 3]> = cdt
                .cdt
                .inner_faces()
                .filter(|f| *f.data())
                .map(|f| {
                    f.vertices().map(|v| match v.data().corner {
                        Corner::Boundary(i) => i as usize,
                        Corner::Interior(_) => unreachable!(),
                    })
                })
                .collect();
            if delaunay.len() != 2 {
                continue;
            }
            // Corners counter-clockwise in the plane, oriented as finish orients them.
            let flip = cdt.flip;
            let points = |[a, b, c]: [usize; 3]| {
                if flip { [a, c, b] } else { [a, b, c] }.map(|i| boundary[i])
            };
            let before = delaunay.iter().filter(|&&t| turned(points(t))).count();
            // The other diagonal: the one between the corners not on the Delaunay one.
            let shared: Vec<usize> = (0..4)
                .filter(|i| delaunay.iter().all(|t| t.contains(i)))
                .collect();
            let apart: Vec<usize> = (0..4).filter(|i| !shared.contains(i)).collect();
            let other = [
                [apart[0], apart[1], shared[0]],
                [apart[0], apart[1], shared[1]],
            ]
            .map(|[a, b, c]| {
                // Counter-clockwise in the plane, as the chart's faces are.
                if plane_area([a, b, c].map(|i| plane[i])) > 0.0 {
                    [a, b, c]
                } else {
                    [a, c, b]
                }
            });
            let out = cdt.finish();
            let after = out
                .triangles
                .iter()
                .filter(|t| {
                    turned(t.map(|c| match c {
                        Corner::Boundary(i) => boundary[i as usize],
                        Corner::Interior(_) => unreachable!(),
                    }))
                })
                .count();
            assert!(after <= before);
            before_total += before;
            after_total += after;
            let old_area = delaunay
                .iter()
                .map(|&t| area(points(t)))
                .fold(f64::MAX, f64::min);
            let old_plane = delaunay
                .iter()
                .map(|&t| plane_area(t.map(|i| plane[i])))
                .fold(f64::MAX, f64::min);
            let sound = other.iter().all(|&t| {
                area(points(t)) > 0.3 * old_area
                    && plane_area(t.map(|i| plane[i])) > 0.3 * old_plane
            });
            // The other diagonal lies inside the quadrilateral (it is convex in the plane).
            let quad: f64 = delaunay
                .iter()
                .map(|&t| plane_area(t.map(|i| plane[i])))
                .sum();
            let split: f64 = other.iter().map(|&t| plane_area(t.map(|i| plane[i]))).sum();
            let convex = (split - quad).abs() <= 1e-9 * quad;
            if before > 0 && convex && sound && other.iter().all(|&t| !turned(points(t))) {
                assert_eq!(after, 0, "{boundary:?}");
                mendable += 1;
            }
        }
        assert!(mendable >= 10, "{mendable} mendable regions");
        assert!(
            after_total < before_total,
            "{after_total} of {before_total}"
        );
    }
}
