//! Uniform refinement of an assembled mesh: each triangle split into four at its edges'
//! midpoints, every new point put back on the surface its edge lies on.
//!
//! Iterative vertex addition (section 5.3) places vertices where the error is, but each
//! insertion costs a priority-queue pop and a Delaunay update; at hundreds of thousands of
//! vertices that dominates decoding. On a smooth surface the adaptive mesh's density is
//! already right at a fraction of the budget: splitting every triangle into four keeps that
//! distribution (the chord error, which grows with the squared edge length, drops fourfold
//! everywhere) at a linear cost. So a large budget is met by meshing adaptively at a quarter
//! (or a sixteenth, ...) of it and subdividing ([`super::assemble`] decides).
//!
//! Where the new point of an edge goes: onto the surface the edge lies on — inside a region
//! (both faces in it) or on the mesh border, the region's ellipsoid (radial projection, as
//! the adaptive scheme's points are placed); between two regions, the intersection curve of
//! their ellipsoids (Newton, as in [`super::refine`]) — *plus the mean of its ends' offsets
//! from that surface*. Boundary points need not lie on the ellipsoids (stored points are
//! quantised, refined ones lie on the curve only where the fits meet); snapping the new
//! points fully would tilt the ever smaller triangles at a boundary point until they flip,
//! whereas carrying the offsets blends them linearly into the interior: each level halves
//! the distance over which a boundary point's offset fades. Where a projection fails or lands
//! far from the chord, or where a new point would turn a triangle over, the chord midpoint
//! is used.
//!
//! Both faces of an edge use its one new point, so a closed manifold mesh stays closed and
//! manifold: V' = V + E, F' = 4F, except where a face would get a child turned against its
//! ellipsoid even with chord midpoints (a face nearly edge-on to it, whose normal turns
//! across the face): that face stays whole and its neighbours split only their other edges
//! (red–green refinement). A clean coarse mesh (no flipped or degenerate triangle) thus gives
//! a clean subdivided one.

use super::assemble::{measured, DEGENERATE_AREA};
use super::refine::project_to_intersection;
use super::{RemeshError, Remeshed};
use crate::ellipsoid::{Ellipsoid, NormalSide};
use crate::mesh::{Mesh, MAX_ELEMENTS};
use crate::representation::Representation;
use glam::DVec3;

/// Marks an edge whose new point is not made yet.
const UNSET: u32 = u32::MAX;

/// Splits every triangle of `coarse` into four (fewer around faces left whole), `levels`
/// times (see the module doc), and checks the result ([`super::assemble::check_mesh`]). Deterministic.
///
/// Errors: [`RemeshError::TooManyVertices`] when the result would exceed `max_vertices` (or
/// the mesh's index range); [`RemeshError::Mesh`] if the result is refused (a bug).
pub fn subdivide(
    rep: &Representation,
    coarse: Remeshed,
    levels: u32,
    max_vertices: usize,
) -> Result<Remeshed, RemeshError> {
    if levels == 0 {
        return Ok(coarse);
    }
    let Remeshed {
        mut mesh,
        mut face_regions,
        treatment,
        ..
    } = coarse;
    for _ in 0..levels {
        let t = mesh.topology();
        let needed = mesh.vertex_count() + t.edge_count();
        if needed > max_vertices.min(MAX_ELEMENTS) || mesh.face_count() * 4 > MAX_ELEMENTS {
            return Err(RemeshError::TooManyVertices {
                needed,
                max: max_vertices,
            });
        }
        let (positions, faces, regions) = split_faces(rep, &mesh, &face_regions);
        mesh = Mesh::new(positions, faces)?;
        face_regions = regions;
    }
    Ok(Remeshed {
        treatment,
        ..measured(rep, mesh, face_regions)
    })
}

/// One level: the positions (old ones first, then the new points in use, in order of their
/// edges' first use), the faces ([`children`] of each face in turn: four, or fewer next to
/// a face left whole) and their regions.
fn split_faces(
    rep: &Representation,
    mesh: &Mesh,
    face_regions: &[u32],
) -> (Vec<DVec3>, Vec<[u32; 3]>, Vec<u32>) {
    let faces = mesh.faces();
    let topology = mesh.topology();
    let mut positions = Vec::with_capacity(mesh.vertex_count() + topology.edge_count());
    positions.extend_from_slice(mesh.positions());
    let region_of = |f: usize| face_regions.get(f).copied().unwrap_or(0);
    // Per face, the new point of each edge (edge i runs from corner i to corner i + 1).
    let mut middles = vec![[UNSET; 3]; faces.len()];
    for (f, face) in faces.iter().enumerate() {
        for i in 0..3 {
            if middles[f][i] != UNSET {
                continue;
            }
            let (a, b) = (face[i], face[(i + 1) % 3]);
            let region = region_of(f);
            let across = topology.across(f, i).map(|(g, j)| (g as usize, j));
            let first = rep.ellipsoids.get(region as usize);
            let second = across
                .map(|(g, _)| region_of(g))
                .filter(|&r| r != region)
                .and_then(|r| rep.ellipsoids.get(r as usize));
            let (pa, pb) = (positions[a as usize], positions[b as usize]);
            let point = match (first, second) {
                (Some(e), None) => between(pa, pb, |p| Some(e.project_radially(p))),
                (Some(e1), Some(e2)) => between(pa, pb, |p| project_to_intersection(e1, e2, p)),
                _ => 0.5 * (pa + pb),
            };
            let index = positions.len() as u32;
            positions.push(point);
            middles[f][i] = index;
            if let Some((g, j)) = across {
                middles[g][j] = index;
            }
        }
    }
    let nv = mesh.vertex_count();
    // Whether each edge's new point is used (indexed by point − nv): edges stay whole around
    // faces that cannot be split without turning a child over.
    let mut split = vec![true; positions.len() - nv];
    let is_split = |split: &[bool], v: u32| split.get(v as usize - nv).copied().unwrap_or(false);
    // What check_mesh would count: a flipped or degenerate child.
    let diagonal = mesh.bounding_box().map_or(0.0, |b| b.diagonal());
    let min_doubled_area = 2.0 * DEGENERATE_AREA * diagonal * diagonal;
    let sides: Vec<NormalSide> = rep.ellipsoids.iter().map(Ellipsoid::normal_side).collect();
    let turned = |positions: &[DVec3], split: &[bool], f: usize| {
        let Some(side) = sides.get(region_of(f) as usize) else {
            return false;
        };
        let cut = middles[f].map(|m| is_split(split, m).then_some(m));
        children(faces[f], cut).iter().flatten().any(|child| {
            let [p, q, r] = child.map(|v| positions[v as usize]);
            let n = (q - p).cross(r - p);
            n.length() <= min_doubled_area || side.along((p + q + r) / 3.0, n) <= 0.0
        })
    };
    // Where a new point turns a child against its ellipsoid (a strongly curved spot, or
    // offsets that disagree), the face's new points go back to the chord midpoints: its
    // children then lie in its plane, oriented as it is. That moves its neighbours' points
    // too, hence the rounds.
    for _ in 0..REPAIR_ROUNDS {
        let mut moved = false;
        for f in 0..faces.len() {
            if !turned(&positions, &split, f) {
                continue;
            }
            let face = faces[f];
            for i in 0..3 {
                let chord =
                    0.5 * (positions[face[i] as usize] + positions[face[(i + 1) % 3] as usize]);
                let m = &mut positions[middles[f][i] as usize];
                if *m != chord {
                    *m = chord;
                    moved = true;
                }
            }
        }
        if !moved {
            break;
        }
    }
    // Where even chord midpoints turn a child (a face nearly edge-on to its ellipsoid, whose
    // normal turns across it), the face is left whole and its neighbours split only the
    // edges they do not share with it (red–green refinement), until no child is turned. The
    // set of whole edges only grows, and with every edge whole the faces are the coarse
    // ones, which are sound: this ends, with a mesh as clean as the coarse one.
    let mut queue: Vec<usize> = (0..faces.len()).rev().collect();
    let mut queued = vec![true; faces.len()];
    while let Some(f) = queue.pop() {
        queued[f] = false;
        if !turned(&positions, &split, f) {
            continue;
        }
        for (i, &m) in middles[f].iter().enumerate() {
            let slot = m as usize - nv;
            if !split[slot] {
                continue;
            }
            split[slot] = false;
            if let Some((g, _)) = topology.across(f, i) {
                let g = g as usize;
                if !queued[g] {
                    queued[g] = true;
                    queue.push(g);
                }
            }
        }
    }
    // Only the new points in use are kept, in order.
    let mut renumber = vec![u32::MAX; split.len()];
    let mut kept = nv;
    for (slot, &used) in split.iter().enumerate() {
        if used {
            positions[kept] = positions[nv + slot];
            renumber[slot] = kept as u32;
            kept += 1;
        }
    }
    positions.truncate(kept);
    let mut new_faces = Vec::with_capacity(faces.len() * 4);
    let mut new_regions = Vec::with_capacity(faces.len() * 4);
    for (f, &face) in faces.iter().enumerate() {
        let cut = middles[f].map(|m| {
            let slot = m as usize - nv;
            split[slot].then_some(renumber[slot])
        });
        for child in children(face, cut).into_iter().flatten() {
            new_faces.push(child);
            new_regions.push(region_of(f));
        }
    }
    (positions, new_faces, new_regions)
}

/// The triangles `face` is split into when its edges with a new point (`cut[i]` on edge i,
/// from corner i to corner i + 1) are split: four with three, three with two, two with one,
/// the face itself with none; all oriented as the face.
fn children(face: [u32; 3], cut: [Option<u32>; 3]) -> [Option<[u32; 3]>; 4] {
    let [a, b, c] = face;
    match cut {
        [Some(ab), Some(bc), Some(ca)] => [
            Some([a, ab, ca]),
            Some([ab, b, bc]),
            Some([ca, bc, c]),
            Some([ab, bc, ca]),
        ],
        [None, None, None] => [Some(face), None, None, None],
        _ => {
            // Rotate so that the corners are (u, v, w) with edge u→v the first whole edge
            // after a cut one.
            let k = (0..3)
                .find(|&k| cut[k].is_none() && cut[(k + 2) % 3].is_some())
                .unwrap_or(0);
            let (u, v, w) = (face[k], face[(k + 1) % 3], face[(k + 2) % 3]);
            let (vw, wu) = (cut[(k + 1) % 3], cut[(k + 2) % 3]);
            match (vw, wu) {
                (Some(vw), Some(wu)) => {
                    [Some([vw, w, wu]), Some([u, v, vw]), Some([u, vw, wu]), None]
                }
                (None, Some(wu)) => [Some([u, v, wu]), Some([v, w, wu]), None, None],
                // Unreachable: k is chosen with cut[k + 2] set.
                (Some(vw), None) => [Some([u, v, vw]), Some([u, vw, w]), None, None],
                (None, None) => [Some(face), None, None, None],
            }
        }
    }
}

/// Most rounds of moving new points back to their chords in [`split_faces`].
const REPAIR_ROUNDS: usize = 4;

/// Largest distance of a new point from its chord's midpoint, as a fraction of the chord: a
/// smooth surface's sagitta is far smaller wherever the adaptive mesh resolves it.
const MAX_BULGE: f64 = 0.25;

/// The new point of the edge `a`–`b` on the surface `project` maps to: the projected chord
/// midpoint plus the mean of the ends' offsets from their projections (see the module doc);
/// the chord midpoint where a projection fails or strays more than [`MAX_BULGE`].
fn between(a: DVec3, b: DVec3, project: impl Fn(DVec3) -> Option<DVec3>) -> DVec3 {
    let mid = 0.5 * (a + b);
    let reach = MAX_BULGE * (b - a).length();
    let offset = |p: DVec3| project(p).map(|q| p - q);
    match (project(mid), offset(a), offset(b)) {
        (Some(m), Some(oa), Some(ob)) => {
            let point = m + 0.5 * (oa + ob);
            if point.is_finite() && (point - mid).length() <= reach {
                point
            } else {
                mid
            }
        }
        _ => mid,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Red–green: a face nearly edge-on to a flat ellipsoid, whose normal turns across it so
    /// that one of its children faces against the ellipsoid even with chord midpoints, stays
    /// whole; its neighbour splits only the edges it does not share with it; nothing in the
    /// result faces against the ellipsoid. (Near the rim of an ellipsoid ten times flatter
    /// than wide, where the normal turns fastest.)
    #[test]
    fn a_face_edge_on_to_its_ellipsoid_stays_whole_and_its_neighbour_splits_around_it() {
        use crate::ellipsoid::{Ellipsoid, Sign};
        let e = Ellipsoid {
            center: DVec3::ZERO,
            rotation: glam::DQuat::IDENTITY,
            radii: DVec3::new(1.0, 1.0, 0.1),
            sign: Sign::Positive,
        };
        let rep = Representation {
            ellipsoids: vec![e],
            ..Representation::default()
        };
        let facing = |t: [DVec3; 3]| {
            (t[1] - t[0])
                .cross(t[2] - t[0])
                .dot(e.normal((t[0] + t[1] + t[2]) / 3.0))
        };
        let chord_children = |t: [DVec3; 3]| {
            let m = [
                0.5 * (t[0] + t[1]),
                0.5 * (t[1] + t[2]),
                0.5 * (t[2] + t[0]),
            ];
            [
                [t[0], m[0], m[2]],
                [m[0], t[1], m[1]],
                [m[2], m[1], t[2]],
                [m[0], m[1], m[2]],
            ]
        };
        // Found by a random search over triangles of points on the ellipsoid near its rim.
        let (a, b) = (
            DVec3::new(0.4021, 0.0005, 0.0916),
            DVec3::new(0.9824, 0.1609, 0.0095),
        );
        let apex = DVec3::new(0.7818, 0.1717, -0.0599);
        // The edge-on face faces the ellipsoid, one of its chord children does not.
        assert!(facing([a, b, apex]) > 0.0);
        assert!(chord_children([a, b, apex])
            .iter()
            .any(|&t| facing(t) <= 0.0));
        // The neighbour across a–b, and its chord children, face it.
        let d = DVec3::new(0.2961, -0.2155, 0.0931);
        assert!(facing([b, a, d]) > 0.0);
        assert!(chord_children([b, a, d]).iter().all(|&t| facing(t) > 0.0));
        let mesh = Mesh::new(vec![a, b, apex, d], vec![[0, 1, 2], [1, 0, 3]]).unwrap();
        let (positions, faces, regions) = split_faces(&rep, &mesh, &[0, 0]);
        assert!(faces.contains(&[0, 1, 2]), "{faces:?}");
        // The neighbour: its two other edges split, three children, none on edge 0–1's
        // midpoint (which is not made).
        assert_eq!(faces.len(), 1 + 3, "{faces:?}");
        assert_eq!(positions.len(), 4 + 2);
        assert_eq!(regions, vec![0; 4]);
        for t in &faces {
            let corners = t.map(|v| positions[v as usize]);
            assert!(facing(corners) > 0.0, "{t:?}");
        }
    }

    /// Every pattern of cut edges tiles the face: the children are counter-clockwise, their
    /// areas add up to the face's, and each cut edge's point is used.
    #[test]
    fn children_tile_the_face_in_every_pattern() {
        // Corners 0, 1, 2 and the midpoints of edges 0 (0→1), 1 (1→2), 2 (2→0) as 3, 4, 5.
        let p = [
            glam::DVec2::new(0.0, 0.0),
            glam::DVec2::new(4.0, 0.0),
            glam::DVec2::new(1.0, 3.0),
        ];
        let mut points = p.to_vec();
        for i in 0..3 {
            points.push(0.5 * (p[i] + p[(i + 1) % 3]));
        }
        let area = |t: [u32; 3]| {
            let [a, b, c] = t.map(|v| points[v as usize]);
            0.5 * (b - a).perp_dot(c - a)
        };
        let whole = area([0, 1, 2]);
        for pattern in 0..8u32 {
            let cut: [Option<u32>; 3] =
                std::array::from_fn(|i| (pattern >> i & 1 == 1).then_some(3 + i as u32));
            let kids: Vec<[u32; 3]> = children([0, 1, 2], cut).into_iter().flatten().collect();
            assert_eq!(
                kids.len(),
                1 + pattern.count_ones() as usize,
                "{pattern:03b}"
            );
            let total: f64 = kids.iter().map(|&t| area(t)).sum();
            assert!((total - whole).abs() < 1e-12, "{pattern:03b}: {total}");
            for &t in &kids {
                assert!(area(t) > 0.0, "{pattern:03b}: {t:?}");
            }
            for (i, c) in cut.iter().enumerate() {
                if let Some(m) = c {
                    assert!(
                        kids.iter().any(|t| t.contains(m)),
                        "{pattern:03b}: edge {i}"
                    );
                }
            }
        }
    }
}
