//! Mean curvature per vertex, by the cotangent formula with mixed Voronoi areas of
//! M. Meyer, M. Desbrun, P. Schröder and A. H. Barr, *Discrete Differential-Geometry
//! Operators for Triangulated 2-Manifolds*, VisMath 2002 / Springer 2003 (section 3.5 and
//! the pseudocode of their Figure 4).
//!
//! For a vertex xᵢ with a closed one-ring, the mean curvature normal is
//!
//! K(xᵢ) = 1/(2·A_mixed) · Σⱼ (cot αᵢⱼ + cot βᵢⱼ)(xᵢ − xⱼ),
//!
//! summed over the one-ring neighbours xⱼ, with αᵢⱼ and βᵢⱼ the angles opposite the edge
//! xᵢxⱼ. A_mixed adds, over the faces around xᵢ, the Voronoi area of xᵢ in the face when the
//! face is not obtuse, half the face's area when it is obtuse at xᵢ, and a quarter of it when
//! it is obtuse elsewhere.
//!
//! # Sign convention
//!
//! H = ½ · K · n, with n the vertex's angle-weighted normal
//! ([`Mesh::vertex_normals`]). A sphere of radius r whose faces point outward has H = +1/r
//! everywhere; where the surface is concave seen from the side its faces point to (a bowl
//! seen from inside, a sphere whose faces point inward) H is negative; a plane has H = 0.
//! H scales as 1/length.
//!
//! # Vertices without an estimate
//!
//! The formula needs a closed disc of faces around the vertex. A vertex on a border or on a
//! non-manifold edge ([`Topology::is_open_vertex`](super::Topology::is_open_vertex)), a vertex
//! whose faces are all degenerate, and a vertex where the arithmetic overflows get no estimate
//! of their own. They take the mean of their one-ring neighbours' values, in rounds that
//! reach outward: round 1 fills the vertices next to one with an estimate, from those, round
//! 2 the ones next to those, and so on; each round reads only values set before it, so the
//! result does not depend on vertex order. Vertices that no round reaches (their connected
//! piece, through shared vertices, has no estimate at all) and unreferenced vertices get 0.
//!
//! # Degenerate triangles
//!
//! The result is always finite. A face whose doubled area is at most [`DEGENERATE_AREA`]
//! times its longest squared edge (angles below about 10⁻¹² rad), or whose measures overflow,
//! is skipped: it adds neither area nor curvature. Every cotangent is clamped to
//! ±[`MAX_COTANGENT`] (angles below about 0.057° or above 179.943°) so that slivers cannot
//! dominate a sum. Any value that still comes out non-finite is replaced by 0.
//!
//! # Cost
//!
//! One pass over the faces accumulating per-vertex sums, one pass over the vertices, and a
//! breadth-first pass over the open vertices only; no allocation per vertex. It runs on one
//! thread, so the result is the same bit for bit on every machine with the same float
//! semantics.

use super::Mesh;
use glam::DVec3;

/// Bound on the magnitude of every cotangent weight (the cotangent of about 0.057°).
pub const MAX_COTANGENT: f64 = 1e3;

/// Faces whose doubled area is at most this times their longest squared edge are skipped.
pub const DEGENERATE_AREA: f64 = 1e-12;

/// Mean curvature H at every vertex, with the sign convention and the treatment of open and
/// degenerate vertices described in the [module docs](self). Computes the vertex normals;
/// use [`mean_curvature_with_normals`] when they are at hand.
pub fn mean_curvature(mesh: &Mesh) -> Vec<f64> {
    mean_curvature_with_normals(mesh, &mesh.vertex_normals())
}

/// [`mean_curvature`] with the unit vertex normals given (normally
/// [`Mesh::vertex_normals`]); H is the mean curvature normal's component along them.
///
/// # Panics
/// If `vertex_normals` does not have one normal per vertex.
pub fn mean_curvature_with_normals(mesh: &Mesh, vertex_normals: &[DVec3]) -> Vec<f64> {
    assert_eq!(
        vertex_normals.len(),
        mesh.vertex_count(),
        "one normal per vertex"
    );
    let (laplacian, mixed_area) = accumulate(mesh);
    let faces = mesh.faces();
    let topology = mesh.topology();
    let mut has_estimate = vec![false; mesh.vertex_count()];
    let mut curvature = vec![0.0; mesh.vertex_count()];
    for v in 0..mesh.vertex_count() {
        let area = mixed_area[v];
        if area > 0.0 && !topology.is_open_vertex(faces, v as u32) {
            // H = ½ K·n with K = Σ / (2 A_mixed).
            let h = laplacian[v].dot(vertex_normals[v]) / (4.0 * area);
            if h.is_finite() {
                curvature[v] = h;
                has_estimate[v] = true;
            }
        }
    }
    fill_from_neighbours(mesh, &mut curvature, &has_estimate);
    curvature
}

/// One pass over the faces: for each vertex, Σ (cot α + cot β)(xᵢ − xⱼ) and A_mixed.
fn accumulate(mesh: &Mesh) -> (Vec<DVec3>, Vec<f64>) {
    let positions = mesh.positions();
    let mut laplacian = vec![DVec3::ZERO; positions.len()];
    let mut mixed_area = vec![0.0; positions.len()];
    for face in mesh.faces() {
        let v = face.map(|i| i as usize);
        let p = v.map(|i| positions[i]);
        // e[k] is the edge opposite corner k, from corner k+1 to corner k+2.
        let e = [p[2] - p[1], p[0] - p[2], p[1] - p[0]];
        let squared = e.map(|e| e.length_squared());
        let twice_area = e[1].cross(e[2]).length();
        let longest = squared[0].max(squared[1]).max(squared[2]);
        if !(twice_area.is_finite() && longest.is_finite())
            || twice_area <= DEGENERATE_AREA * longest
        {
            continue;
        }
        // At corner k the two edges leaving it are e[k+2] and −e[k+1].
        let dots = [0, 1, 2].map(|k| -e[(k + 1) % 3].dot(e[(k + 2) % 3]));
        let cot = dots.map(|d| (d / twice_area).clamp(-MAX_COTANGENT, MAX_COTANGENT));
        for k in 0..3 {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            // Edge opposite k joins corners i and j; e[k] = p[j] − p[i].
            let w = cot[k] * e[k];
            laplacian[v[i]] -= w;
            laplacian[v[j]] += w;
        }
        let area = 0.5 * twice_area;
        match dots.iter().position(|&d| d < 0.0) {
            Some(obtuse) => {
                for (k, &vk) in v.iter().enumerate() {
                    mixed_area[vk] += if k == obtuse { 0.5 } else { 0.25 } * area;
                }
            }
            None => {
                for (k, &vk) in v.iter().enumerate() {
                    // Voronoi area: ⅛ (|x_k x_{k+1}|² cot ∠_{k+2} + |x_k x_{k+2}|² cot ∠_{k+1}).
                    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                    mixed_area[vk] += 0.125 * (squared[j] * cot[j] + squared[i] * cot[i]);
                }
            }
        }
    }
    (laplacian, mixed_area)
}

/// Gives every vertex without an estimate the mean of its one-ring neighbours that have a
/// value, in outward rounds (see the [module docs](self)); 0 where no round reaches.
fn fill_from_neighbours(mesh: &Mesh, curvature: &mut [f64], has_estimate: &[bool]) {
    const UNSET: u32 = 0;
    let n = curvature.len();
    // 1 for vertices with their own estimate, r + 1 for those filled in round r.
    let mut round_of = vec![UNSET; n];
    let mut frontier = Vec::new();
    for v in 0..n {
        if has_estimate[v] {
            round_of[v] = 1;
            frontier.push(v as u32);
        } else {
            curvature[v] = 0.0;
        }
    }
    if frontier.len() == n {
        return;
    }
    let faces = mesh.faces();
    let topology = mesh.topology();
    // Which vertex last counted each vertex as a neighbour, to count every neighbour once.
    let mut seen_by = vec![u32::MAX; n];
    let mut queued = vec![false; n];
    let mut candidates = Vec::new();
    let mut round = 1u32;
    while !frontier.is_empty() {
        candidates.clear();
        for &u in &frontier {
            for &f in topology.faces_around(u) {
                for w in faces[f as usize] {
                    if round_of[w as usize] == UNSET && !queued[w as usize] {
                        queued[w as usize] = true;
                        candidates.push(w);
                    }
                }
            }
        }
        for &w in &candidates {
            let (mut sum, mut count) = (0.0, 0u32);
            for &f in topology.faces_around(w) {
                for x in faces[f as usize] {
                    let r = round_of[x as usize];
                    if x != w && r != UNSET && r <= round && seen_by[x as usize] != w {
                        seen_by[x as usize] = w;
                        sum += curvature[x as usize];
                        count += 1;
                    }
                }
            }
            // Every candidate touches the frontier, so count > 0.
            let mean = sum / f64::from(count.max(1));
            curvature[w as usize] = if mean.is_finite() { mean } else { 0.0 };
            round_of[w as usize] = round + 1;
        }
        std::mem::swap(&mut frontier, &mut candidates);
        round += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;
    use crate::synth::shapes;
    use glam::{DQuat, EulerRot};

    /// Largest relative deviation of `h[v]` from `expected` over the vertices `pick` accepts.
    fn worst_relative_error(
        mesh: &Mesh,
        h: &[f64],
        expected: f64,
        pick: impl Fn(usize, DVec3) -> bool,
    ) -> (f64, usize) {
        let mut worst = 0.0f64;
        let mut checked = 0;
        for (v, &p) in mesh.positions().iter().enumerate() {
            if pick(v, p) {
                worst = worst.max((h[v] - expected).abs() / expected.abs());
                checked += 1;
            }
        }
        (worst, checked)
    }

    /// `mesh` with each position mapped in order by a stateful `map`.
    fn map_each(mesh: &Mesh, mut map: impl FnMut(DVec3) -> DVec3) -> Mesh {
        let positions = mesh.positions().iter().map(|&p| map(p)).collect();
        Mesh::new(positions, mesh.faces().to_vec()).unwrap()
    }

    fn flipped(mesh: &Mesh) -> Mesh {
        let faces = mesh.faces().iter().map(|&[a, b, c]| [a, c, b]).collect();
        Mesh::new(mesh.positions().to_vec(), faces).unwrap()
    }

    #[test]
    fn sphere_has_inverse_radius_at_every_vertex() {
        let r = 2.5;
        for s in [4, 5] {
            // 5,120 and 20,480 faces.
            let m = shapes::icosphere(r, s);
            let h = mean_curvature(&m);
            let (worst, checked) = worst_relative_error(&m, &h, 1.0 / r, |_, _| true);
            eprintln!("icosphere s={s}: worst relative error {worst:.2e} over {checked}");
            assert_eq!(checked, m.vertex_count());
            assert!(worst < 0.02, "{worst}");
        }
    }

    #[test]
    fn ellipsoid_tips_match_the_analytic_values() {
        // At the tip (0, 0, c) of x²/a² + y²/b² + z²/c² = 1 the principal curvatures are
        // c/a² and c/b². The icosphere's poles map to the two tips.
        let radii = DVec3::new(2.0, 1.5, 1.0);
        let spec = crate::synth::EllipsoidSpec {
            center: DVec3::ZERO,
            rotation: DQuat::IDENTITY,
            radii,
        };
        let m = shapes::ellipsoid(&spec, 5);
        let h = mean_curvature(&m);
        let expected = 0.5 * radii.z * (1.0 / (radii.x * radii.x) + 1.0 / (radii.y * radii.y));
        let tip = |_, p: DVec3| p.x == 0.0 && p.y == 0.0;
        let (worst, checked) = worst_relative_error(&m, &h, expected, tip);
        eprintln!("ellipsoid tips: worst relative error {worst:.2e}");
        assert_eq!(checked, 2);
        assert!(worst < 0.03, "{worst}");
    }

    #[test]
    fn jittered_sphere_stays_close() {
        // Vertices slid along the sphere by up to a fifth of an edge: an irregular mesh
        // whose vertices are still exactly on the sphere. The cotangent formula does not
        // converge pointwise on irregular meshes (Hildebrandt, Polthier & Wardetzky 2006), so
        // single vertices stray by over 10%, but the errors average out: the mean stays
        // within 0.1% and the root-mean-square error within 5%.
        let r = 1.2;
        let sphere = shapes::icosphere(r, 5);
        let step = 0.2 * sphere.average_edge_length();
        let mut rng = SplitMix64::new(5);
        let m = map_each(&sphere, |p| {
            let d = DVec3::new(
                rng.range_f64(-1.0, 1.0),
                rng.range_f64(-1.0, 1.0),
                rng.range_f64(-1.0, 1.0),
            );
            (p + step * d).normalize() * r
        });
        let h = mean_curvature(&m);
        let count = h.len() as f64;
        let mean_error = (h.iter().sum::<f64>() / count * r - 1.0).abs();
        let rms_error = (h.iter().map(|x| (x * r - 1.0).powi(2)).sum::<f64>() / count).sqrt();
        let (worst, _) = worst_relative_error(&m, &h, 1.0 / r, |_, _| true);
        eprintln!("jittered sphere: mean {mean_error:.2e}, rms {rms_error:.2e}, worst {worst:.2e}");
        assert!(mean_error < 1e-3, "{mean_error}");
        assert!(rms_error < 0.05, "{rms_error}");
        assert!(worst < 0.3, "{worst}");
    }

    #[test]
    fn inward_sphere_is_negative() {
        let r = 0.7;
        let m = flipped(&shapes::icosphere(r, 5));
        let h = mean_curvature(&m);
        let (worst, _) = worst_relative_error(&m, &h, -1.0 / r, |_, _| true);
        eprintln!("inward icosphere: worst relative error {worst:.2e}");
        assert!(worst < 0.02, "{worst}");
    }

    #[test]
    fn bowl_is_negative() {
        let r = 1.5;
        let m = shapes::bowl(r, 5);
        let h = mean_curvature(&m);
        let t = m.topology();
        let interior = |v: usize, _| !t.is_open_vertex(m.faces(), v as u32);
        let (worst, checked) = worst_relative_error(&m, &h, -1.0 / r, interior);
        eprintln!("bowl interior: worst relative error {worst:.2e} over {checked}");
        assert!(worst < 0.02, "{worst}");
        // The rim takes its neighbours' values, so it is close too.
        let (rim, _) = worst_relative_error(&m, &h, -1.0 / r, |_, _| true);
        eprintln!("bowl with rim: worst relative error {rim:.2e}");
        assert!(rim < 0.02, "{rim}");
    }

    #[test]
    fn cylinder_has_half_inverse_radius_away_from_its_ends() {
        let (r, height) = (0.5, 4.0);
        // 64 around, rings spaced like the vertices around: near-square quads.
        let m = shapes::cylinder(r, height, 64, 80);
        let h = mean_curvature(&m);
        let spacing = height / 80.0;
        let away = |_, p: DVec3| p.z.abs() < 0.5 * height - 1.5 * spacing;
        let (worst, checked) = worst_relative_error(&m, &h, 0.5 / r, away);
        eprintln!("cylinder: worst relative error {worst:.2e} over {checked}");
        assert_eq!(checked, 64 * 77);
        assert!(worst < 0.03, "{worst}");
    }

    #[test]
    fn torus_equators_match_the_analytic_values() {
        let (big, small) = (3.0, 1.0);
        let m = shapes::torus(big, small, 192, 64);
        let h = mean_curvature(&m);
        let rho = |p: DVec3| p.x.hypot(p.y);
        let on = |target: f64| move |_, p: DVec3| (rho(p) - target).abs() < 1e-9;
        let outer = (big + 2.0 * small) / (2.0 * small * (big + small));
        let inner = (big - 2.0 * small) / (2.0 * small * (big - small));
        let (worst_outer, n_outer) = worst_relative_error(&m, &h, outer, on(big + small));
        let (worst_inner, n_inner) = worst_relative_error(&m, &h, inner, on(big - small));
        eprintln!(
            "torus: outer {worst_outer:.2e} over {n_outer}, inner {worst_inner:.2e} over {n_inner}"
        );
        assert_eq!((n_outer, n_inner), (192, 192));
        assert!(worst_outer < 0.03, "{worst_outer}");
        assert!(worst_inner < 0.03, "{worst_inner}");
    }

    /// A flat grid, optionally jittered in its plane, then rotated and moved off the origin
    /// so that rounding is not trivially zero.
    fn tilted_grid(jitter: f64, seed: u64) -> (Mesh, f64) {
        let (size, n) = (3.0, 40u32);
        let spacing = size / f64::from(n);
        let mut rng = SplitMix64::new(seed);
        let rotation = DQuat::from_euler(EulerRot::ZXY, 0.4, 1.1, -0.3);
        let offset = DVec3::new(10.0, -3.0, 7.0);
        let m = map_each(&shapes::grid(size, n), |p| {
            let dx = jitter * spacing * rng_pair(&mut rng);
            rotation * (p + dx) + offset
        });
        (m, spacing)
    }

    fn rng_pair(rng: &mut SplitMix64) -> DVec3 {
        DVec3::new(rng.range_f64(-1.0, 1.0), rng.range_f64(-1.0, 1.0), 0.0)
    }

    #[test]
    fn flat_grids_have_zero_curvature() {
        for (jitter, seed) in [(0.0, 1), (0.3, 2), (0.3, 3)] {
            let (m, spacing) = tilted_grid(jitter, seed);
            let h = mean_curvature(&m);
            let worst = h.iter().fold(0.0f64, |w, x| w.max(x.abs())) * spacing;
            eprintln!("flat grid jitter {jitter}: worst |H|·edge {worst:.2e}");
            assert!(worst < 1e-9, "{worst}");
        }
    }

    #[test]
    fn scaling_divides_curvature() {
        let spec = crate::synth::EllipsoidSpec {
            center: DVec3::new(0.3, 0.2, -0.1),
            rotation: DQuat::from_euler(EulerRot::XYZ, 0.2, 0.5, -0.4),
            radii: DVec3::new(2.0, 1.0, 0.6),
        };
        // Noise makes the curvature vary in sign and size from vertex to vertex.
        let mut rng = SplitMix64::new(9);
        let m = map_each(&shapes::ellipsoid(&spec, 4), |p| {
            p * (1.0 + 0.02 * rng.range_f64(-1.0, 1.0))
        });
        let h = mean_curvature(&m);
        let scale = 3.7;
        let scaled = mean_curvature(&m.map_positions(|p| p * scale).unwrap());
        let typical = h.iter().map(|x| x.abs()).fold(0.0, f64::max);
        for (a, b) in h.iter().zip(&scaled) {
            assert!((b * scale - a).abs() <= 1e-9 * typical, "{a} vs {b}");
        }
    }

    #[test]
    fn open_vertices_take_their_neighbours_mean() {
        let m = shapes::hemisphere(1.0, 3);
        let h = mean_curvature(&m);
        let t = m.topology();
        let faces = m.faces();
        let rim = &t.boundary_loops()[0];
        for &v in rim {
            let mut neighbours: Vec<u32> = t
                .faces_around(v)
                .iter()
                .flat_map(|&f| faces[f as usize])
                .filter(|&w| w != v && !t.is_open_vertex(faces, w))
                .collect();
            neighbours.sort_unstable();
            neighbours.dedup();
            assert!(!neighbours.is_empty());
            let mean =
                neighbours.iter().map(|&w| h[w as usize]).sum::<f64>() / neighbours.len() as f64;
            assert!((h[v as usize] - mean).abs() < 1e-12);
        }
    }

    #[test]
    fn open_vertices_fill_outward_in_rounds() {
        // A strip of triangles (every vertex on the border) glued to nothing: no estimate
        // anywhere, so all zero; glued by a vertex to a sphere: filled from it.
        let strip_positions: Vec<DVec3> = (0..12)
            .map(|i| DVec3::new(f64::from(i / 2), f64::from(i % 2), 0.0))
            .collect();
        let strip_faces: Vec<[u32; 3]> = (0..10u32)
            .map(|i| {
                if i % 2 == 0 {
                    [i, i + 1, i + 2]
                } else {
                    [i, i + 2, i + 1]
                }
            })
            .collect();
        let strip = Mesh::new(strip_positions.clone(), strip_faces.clone()).unwrap();
        assert!(mean_curvature(&strip).iter().all(|&x| x == 0.0));

        let sphere = shapes::icosphere(1.0, 2);
        let n = sphere.vertex_count() as u32;
        let mut positions = sphere.positions().to_vec();
        positions.extend(
            strip_positions
                .iter()
                .map(|p| *p + DVec3::new(0.0, 0.0, 5.0)),
        );
        let mut faces = sphere.faces().to_vec();
        faces.extend(strip_faces.iter().map(|f| f.map(|i| i + n)));
        // Share the strip's first vertex with sphere vertex 0.
        for f in faces.iter_mut().skip(sphere.face_count()) {
            for i in f.iter_mut() {
                if *i == n {
                    *i = 0;
                }
            }
        }
        let glued = Mesh::new(positions, faces).unwrap();
        let h = mean_curvature(&glued);
        assert!(h.iter().all(|x| x.is_finite()));
        // Vertex 0 is now open (its strip edges are borders); the strip gets filled.
        let sphere_h = mean_curvature(&sphere);
        let n = n as usize;
        assert_eq!(h[1..n], sphere_h[1..n]);
        // Vertex 0 and the strip take values spreading out from the sphere.
        assert!((h[0] - 1.0).abs() < 0.01);
        for (v, &x) in h.iter().enumerate().skip(n + 1) {
            assert!((x - 1.0).abs() < 0.01, "vertex {v}: {x}");
        }
        // The strip's own first vertex is no longer used.
        assert_eq!(h[n], 0.0);
    }

    #[test]
    fn degenerate_faces_stay_finite() {
        // A sphere with one vertex dragged onto a neighbour (zero-area faces), one pushed
        // almost onto an edge (a sliver), and a collinear triangle added.
        let sphere = shapes::icosphere(1.0, 3);
        let mut positions = sphere.positions().to_vec();
        let [a, b, c] = sphere.faces()[0];
        positions[a as usize] = positions[b as usize];
        let [_, e, f] = sphere.faces()[50];
        let [g, ..] = sphere.faces()[50];
        positions[g as usize] =
            0.5 * (positions[e as usize] + positions[f as usize]) + DVec3::splat(1e-14);
        let mut faces = sphere.faces().to_vec();
        let n = positions.len() as u32;
        positions.extend([DVec3::ZERO, DVec3::X, 2.0 * DVec3::X]);
        faces.push([n, n + 1, n + 2]);
        let m = Mesh::new(positions, faces).unwrap();
        let h = mean_curvature(&m);
        assert!(h.iter().all(|x| x.is_finite()));
        assert!(h[c as usize].is_finite());
        // Huge coordinates overflow the products: still finite.
        let huge = sphere.map_positions(|p| p * 1e300).unwrap();
        assert!(mean_curvature(&huge).iter().all(|x| x.is_finite()));
        let tiny = sphere.map_positions(|p| p * 1e-300).unwrap();
        assert!(mean_curvature(&tiny).iter().all(|x| x.is_finite()));
    }

    #[test]
    fn given_normals_give_the_same_result() {
        let m = shapes::torus(2.0, 0.5, 30, 12);
        assert_eq!(
            mean_curvature(&m),
            mean_curvature_with_normals(&m, &m.vertex_normals())
        );
    }
}
