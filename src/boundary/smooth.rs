//! Constrained relaxation of boundary vertices toward the ellipsoids they touch
//! (Simari & Singh 2005, section 4.1).
//!
//! Each pass moves every boundary point `p` to `(1 − ε)·p + ε·q`, where `q` is the centroid of
//! its *associated points*: its neighbours along the arcs through it, and its projections onto
//! the ellipsoids of the regions on either side of those arcs. All points are updated from the
//! previous pass's positions (Jacobi), so the result does not depend on the order of the
//! vertices.
//!
//! The paper projects radially (Π, section 2); here the projection is the closest point
//! ([`Ellipsoid::closest_point`]), the map the decoder charts boundaries with
//! ([`crate::remesh::chart::Projection::Closest`]). Along a ray from the centre of an
//! elongated ellipsoid the radial projection of a point off the surface slides far along it
//! (the ray meets the surface at a grazing angle), and the pull of those far points dragged
//! boundaries across their regions until they folded in the decoder's charts: on the 12
//! paper-scale meshes at K = 8, 12, 18 and 24 (48 files, without the encoder's decoder check,
//! decoded before boundary heights were blended in), 18 decoded clean with radial projections
//! and 27 with closest points. Where the two ellipsoids meet far from the mesh's boundary
//! the relaxation still pulls toward them; the encoder's decoder check then stores that
//! region's boundaries at the mesh's own points ([`crate::encode::EncodeSettings::verify`]).
//!
//! - An ordinary point between regions A and B has two neighbours and two projections; the
//!   fixed point lies on (within the curve's own curvature of) the curve where A's and B's
//!   ellipsoids intersect, evenly spaced along it.
//! - A junction uses every arc through it (all its neighbours) and the ellipsoids of every
//!   region around it, so it is pulled toward the points the ellipsoids share. But two
//!   junctions next to each other (an arc of one edge) that both lie on every ellipsoid
//!   around them ([`ON_ELLIPSOID`]) are not each other's neighbours: they are where the
//!   relaxation would take them, there is no spacing along such an arc to even out, and
//!   the two would only drag each other along it. On a coarse mesh every arc is one edge:
//!   a cube's twelve triangles, each a region on the sphere through the corners, had every
//!   corner pulled toward its neighbours' centroid (the spheres, all the same, hold nothing
//!   in place), stored 11–12 % of the diagonal inside the cube, which decoded 16–28 % RMS
//!   off; now the corners stay where the mesh has them. (Dropping the link between any two
//!   junctions also kept the cube, but moved the junctions of every mesh with arcs of one
//!   edge: assimp's low-poly spider, clean before, decoded with 6 flipped triangles, and 36
//!   of the 60 small shared meshes' files changed.) Where the ellipsoids around a junction
//!   meet far from the mesh, the pull can drag it across a narrow region and turn that
//!   region's loop round; the encoder's last search holds every junction where the mesh has
//!   it ([`smooth_boundaries_holding`]). Holding them always would cost: the 60 small-mesh
//!   files took 1 167 regions and 123 406 bytes instead of 1 138 and 120 069, and duck at
//!   K = 32 kept 2 flipped triangles.
//! - A point on a mesh-border arc uses its two neighbours along the border and the one
//!   ellipsoid of its region: the border is smoothed along that ellipsoid (it has no second
//!   surface to meet). Where a region boundary meets the border the junction uses both.
//!   Like any Laplacian smoothing this pulls a border loop inward along the ellipsoid, by at
//!   most about ε·h²/(3ρ) per pass (h the edge length, ρ the loop's radius), unless the
//!   ellipsoid holds it (a rim on a great circle stays put: tested); the default 40 passes
//!   move a loop of radius 10·h by at most about two thirds of an edge.
//!
//! - A small hole is kept as the mesh has it: every point of a border loop of fewer than
//!   [`MIN_SMOOTHED_BORDER_LOOP`] vertices stays put. By the bound above a loop of radius
//!   ρ = h (a hole of three to six edges, common in scans) moves by ε·h/3 a pass and
//!   collapses to a point within the default passes: the region around it then has a loop
//!   that encloses nothing and does not decode (an ellipsoid with one triangle missing,
//!   written without the encoder's check).
//!
//! Regions whose ellipsoid is invalid (non-finite or non-positive radii) contribute no
//! projection; a point with nothing associated, or whose update is not finite, stays put.

use super::{BoundaryError, BoundaryGraph, Side};
use crate::ellipsoid::Ellipsoid;
use crate::mesh::Mesh;
use glam::DVec3;

/// Default number of passes of [`smooth_boundaries`]. Measured on two spheres meeting in a
/// circle (edge length h ≈ 0.05 of the radius): ordinary boundary points reach their floor
/// (≈ 0.03·h from both spheres, the bias of the curve's own curvature) after 20 passes at
/// ε = 0.5; triple junctions, pulled aside by arcs that all leave on one side, keep
/// approaching their common point more slowly (1.6·h → 1.05·h after 20 passes, 0.94·h after
/// 40, 0.8·h after 200), so the default is 40.
pub const DEFAULT_ITERATIONS: usize = 40;
/// Default step ε of [`smooth_boundaries`]: 0.5 (ε = 0.3 to 1.0 all converge in 20–40
/// passes on the measurement above; 0.5 is the paper's "small ε" side of that range).
pub const DEFAULT_EPSILON: f64 = 0.5;

/// Border loops with fewer vertices than this are not smoothed. For a loop of n points
/// (radius ρ ≈ n·h/2π) the default passes move it by about 40·ε·h²/(3ρ) ≈ 42·h²/(n·h)
/// toward its centre: a quarter of its radius or more below 32 points.
pub const MIN_SMOOTHED_BORDER_LOOP: usize = 32;

/// How close, in multiples of its largest radius, a junction lies to an ellipsoid when it
/// counts as on it (see the module doc): rounding, not fitting (a region of a few points
/// fitted through them exactly, as a cube's corners on their sphere).
pub const ON_ELLIPSOID: f64 = 1e-9;

/// Iterations and step of the relaxation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothOptions {
    /// Number of relaxation passes (default [`DEFAULT_ITERATIONS`]).
    pub iterations: usize,
    /// Step ε of p ← (1−ε)p + εq, in `[0, 1]` (default [`DEFAULT_EPSILON`]); 0 moves nothing.
    pub epsilon: f64,
}

impl Default for SmoothOptions {
    fn default() -> Self {
        SmoothOptions {
            iterations: DEFAULT_ITERATIONS,
            epsilon: DEFAULT_EPSILON,
        }
    }
}

/// Relaxes every boundary vertex; returns the new position of each vertex of
/// `graph.vertices`, in the same order. `ellipsoids[r]` is region `r`'s; there must be one
/// per region of `graph`.
pub fn smooth_boundaries(
    mesh: &Mesh,
    graph: &BoundaryGraph,
    ellipsoids: &[Ellipsoid],
    options: &SmoothOptions,
) -> Result<Vec<DVec3>, BoundaryError> {
    smooth_boundaries_holding(mesh, graph, ellipsoids, options, &[])
}

/// [`smooth_boundaries`] with the mesh vertices in `held` kept where the mesh has them (the
/// others relax around them). For junctions: where the ellipsoids around one meet far from
/// the mesh, the relaxation drags it toward their common point, across a region narrower
/// than the distance (a low-poly spider's leg: a junction moved 0.77 units across a region
/// about one unit wide, whose loop then ran the other way round and decoded as one turned
/// triangle); the encoder's last search holds every junction
/// ([`crate::encode::encode_mesh`]). Vertices of `held` that are not boundary vertices are
/// ignored.
pub fn smooth_boundaries_holding(
    mesh: &Mesh,
    graph: &BoundaryGraph,
    ellipsoids: &[Ellipsoid],
    options: &SmoothOptions,
    held: &[u32],
) -> Result<Vec<DVec3>, BoundaryError> {
    let epsilon = options.epsilon;
    if !(0.0..=1.0).contains(&epsilon) {
        return Err(BoundaryError::BadOptions {
            what: format!("epsilon is {epsilon}, expected a value in [0, 1]"),
        });
    }
    if ellipsoids.len() < graph.cycles.len() {
        return Err(BoundaryError::BadOptions {
            what: format!(
                "{} ellipsoids for {} regions",
                ellipsoids.len(),
                graph.cycles.len()
            ),
        });
    }
    let positions = mesh.positions();
    let mut points = Vec::with_capacity(graph.vertices.len());
    for &v in &graph.vertices {
        let p = positions
            .get(v as usize)
            .ok_or_else(|| BoundaryError::BadOptions {
                what: format!("boundary vertex {v} is not in the mesh"),
            })?;
        points.push(*p);
    }
    let links = Links::build(graph, ellipsoids, &points)?;
    // The points of small holes stay where the mesh has them, and so do those held.
    let mut pinned = vec![false; points.len()];
    for v in held {
        if let Ok(k) = graph.vertices.binary_search(v) {
            pinned[k] = true;
        }
    }
    for border in mesh.topology().boundary_loops() {
        if border.len() < MIN_SMOOTHED_BORDER_LOOP {
            for v in border {
                if let Ok(k) = graph.vertices.binary_search(v) {
                    pinned[k] = true;
                }
            }
        }
    }
    let mut next = points.clone();
    for _ in 0..options.iterations {
        for (k, out) in next.iter_mut().enumerate() {
            let p = points[k];
            if pinned[k] {
                *out = p;
                continue;
            }
            let mut sum = DVec3::ZERO;
            let mut count = 0usize;
            for &n in links.neighbours(k) {
                sum += points[n as usize];
                count += 1;
            }
            for &r in links.regions(k) {
                let q = ellipsoids[r as usize].closest_point(p);
                if q.is_finite() {
                    sum += q;
                    count += 1;
                }
            }
            let moved = if count == 0 {
                p
            } else {
                (1.0 - epsilon) * p + epsilon * (sum / count as f64)
            };
            *out = if moved.is_finite() { moved } else { p };
        }
        std::mem::swap(&mut points, &mut next);
    }
    Ok(points)
}

/// For each boundary point (index into `graph.vertices`): its neighbours along arcs (same
/// indices) and the regions with a valid ellipsoid on either side of its arcs, as compressed
/// rows without repeats.
struct Links {
    neighbour_offsets: Vec<u32>,
    neighbours: Vec<u32>,
    region_offsets: Vec<u32>,
    regions: Vec<u32>,
}

impl Links {
    /// `points`: each boundary point's position (indices as `graph.vertices`).
    fn build(
        graph: &BoundaryGraph,
        ellipsoids: &[Ellipsoid],
        points: &[DVec3],
    ) -> Result<Links, BoundaryError> {
        let index = |v: u32| {
            graph
                .vertices
                .binary_search(&v)
                .map(|k| k as u32)
                .map_err(|_| BoundaryError::BadOptions {
                    what: format!("arc vertex {v} is not a boundary vertex"),
                })
        };
        let n = graph.vertices.len();
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        let mut touches: Vec<(u32, u32)> = Vec::new();
        for arc in &graph.arcs {
            let valid = |r: u32| ellipsoids.get(r as usize).is_some_and(Ellipsoid::is_valid);
            let mut sides = vec![arc.left];
            if let Side::Region(r) = arc.right {
                sides.push(r);
            }
            sides.retain(|&r| valid(r));
            let vs = &arc.vertices;
            let mut prev: Option<u32> = None;
            for &v in vs {
                let k = index(v)?;
                for &r in &sides {
                    touches.push((k, r));
                }
                if let Some(p) = prev {
                    pairs.push((p, k));
                    pairs.push((k, p));
                }
                prev = Some(k);
            }
            if arc.closed && vs.len() > 1 {
                if let (Some(&a), Some(&b)) = (vs.first(), vs.last()) {
                    let (a, b) = (index(a)?, index(b)?);
                    pairs.push((a, b));
                    pairs.push((b, a));
                }
            }
        }
        let (region_offsets, regions) = compress(n, touches);
        let mut links = Links {
            neighbour_offsets: Vec::new(),
            neighbours: Vec::new(),
            region_offsets,
            regions,
        };
        // Two junctions next to each other (an arc of one edge), each on every ellipsoid
        // around it, are not each other's neighbours: see the module doc.
        let mut held = vec![false; n];
        for &j in &graph.junctions {
            let Some((k, &p)) = graph
                .vertices
                .binary_search(&j)
                .ok()
                .and_then(|k| Some((k, points.get(k)?)))
            else {
                continue;
            };
            let around = links.regions(k);
            held[k] = !around.is_empty()
                && around.iter().all(|&r| {
                    let e = &ellipsoids[r as usize];
                    p.distance(e.closest_point(p)) <= ON_ELLIPSOID * e.radii.max_element()
                });
        }
        pairs.retain(|&(a, b)| !(held[a as usize] && held[b as usize]));
        (links.neighbour_offsets, links.neighbours) = compress(n, pairs);
        Ok(links)
    }

    fn neighbours(&self, k: usize) -> &[u32] {
        &self.neighbours[self.neighbour_offsets[k] as usize..self.neighbour_offsets[k + 1] as usize]
    }

    fn regions(&self, k: usize) -> &[u32] {
        &self.regions[self.region_offsets[k] as usize..self.region_offsets[k + 1] as usize]
    }
}

/// Sorted, deduplicated (row, value) pairs as compressed rows.
fn compress(rows: usize, mut pairs: Vec<(u32, u32)>) -> (Vec<u32>, Vec<u32>) {
    pairs.sort_unstable();
    pairs.dedup();
    let mut offsets = vec![0u32; rows + 1];
    for &(r, _) in &pairs {
        offsets[r as usize + 1] += 1;
    }
    for r in 0..rows {
        offsets[r + 1] += offsets[r];
    }
    (offsets, pairs.into_iter().map(|(_, v)| v).collect())
}
