//! Decoding end to end (issue 6, item 10): fixture meshes are encoded, the bytes decoded
//! (quantised boundary points, the real path), and the representation remeshed; the meshes
//! are checked for closedness, clean triangles, distance to the source, the vertex budget
//! and determinism. Every tolerance is stated where it is asserted.

mod common;

use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, Limits};
use ellip::import::{read_mesh, ImportOptions};
use ellip::remesh::subdivide::subdivide;
use ellip::remesh::{
    remesh, remesh_with_charts, ChartMemo, RemeshOptions, Remeshed, Scheme,
    SUBDIVISION_COARSE_VERTICES, SUBDIVISION_VERTICES_PER_REGION,
};
use ellip::representation::Representation;
use ellip::rng::SplitMix64;
use ellip::segment::{RegionCount, SegmentOptions};
use ellip::Mesh;
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn source(name: &str) -> Mesh {
    let path = root().join("fixtures/meshes").join(name);
    read_mesh(&path, &ImportOptions::default()).unwrap().mesh
}

/// The number of ellipsoids a blob fixture is the union of.
fn blob_ellipsoids(name: &str) -> usize {
    let path = root()
        .join("fixtures/meshes")
        .join(name)
        .with_extension("json");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["ellipsoids"].as_array().unwrap().len()
}

/// Encodes `mesh` at `k` regions and decodes the bytes.
fn encode(mesh: &Mesh, k: usize) -> (Vec<u8>, Representation) {
    encode_with(mesh, k, true)
}

/// [`encode`] without the encoder's decoder check: the segmentation as it is, whatever the
/// decoder makes of it.
fn encode_unchecked(mesh: &Mesh, k: usize) -> (Vec<u8>, Representation) {
    encode_with(mesh, k, false)
}

fn encode_with(mesh: &Mesh, k: usize, verify: bool) -> (Vec<u8>, Representation) {
    let settings = EncodeSettings {
        segment: SegmentOptions {
            regions: RegionCount::Fixed(k),
            ..SegmentOptions::default()
        },
        verify,
        ..EncodeSettings::default()
    };
    let encoded = encode_mesh(mesh, &settings, &mut |_| {}).unwrap();
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    (encoded.bytes, rep)
}

fn options(vertices: usize, scheme: Scheme) -> RemeshOptions {
    RemeshOptions {
        vertices: Some(vertices),
        scheme,
        ..RemeshOptions::default()
    }
}

/// Adaptive options at `vertices` with every vertex placed by vertex addition (no
/// subdivision).
fn by_vertex_addition(vertices: usize) -> RemeshOptions {
    RemeshOptions {
        subdivision: false,
        ..options(vertices, Scheme::Adaptive)
    }
}

fn diagonal(mesh: &Mesh) -> f64 {
    mesh.bounding_box().unwrap().diagonal()
}

/// Asserts what every decoded mesh must be: no degenerate or flipped triangle, manifold,
/// consistently oriented, normals unit length and agreeing with the faces around them.
fn assert_clean(out: &Remeshed, context: &str) {
    let c = out.check;
    assert_eq!(c.degenerate, 0, "{context}: degenerate triangles");
    assert_eq!(c.flipped, 0, "{context}: flipped triangles");
    assert!(c.manifold, "{context}: not manifold");
    assert!(
        c.consistently_oriented,
        "{context}: inconsistent orientation"
    );
    let t = out.mesh.topology();
    assert_eq!(t.nonmanifold_edge_count(), 0, "{context}");
    assert_eq!(out.normals.len(), out.mesh.vertex_count());
    assert_eq!(out.face_regions.len(), out.mesh.face_count());
    for n in &out.normals {
        assert!((n.length() - 1.0).abs() < 1e-9, "{context}: normal {n}");
    }
    // Vertex normals agree with the face normals around them (smooth shading that is not
    // inside out). Inside a region they are the ellipsoid's own normals: the mean cosine to a
    // face's corner normals is near 1. A boundary vertex averages the normals of the
    // ellipsoids that meet there, which can differ by tens of degrees where the fit is coarse
    // (measured on the 8-region torus: 0.999 inside, 0.877 on faces touching a boundary;
    // over all faces 0.943, below the 0.95 this test first asked of all faces together).
    let mut regions_of = vec![Vec::<u32>::new(); out.mesh.vertex_count()];
    for (f, tri) in out.mesh.faces().iter().enumerate() {
        for &v in tri {
            let r = out.face_regions[f];
            if !regions_of[v as usize].contains(&r) {
                regions_of[v as usize].push(r);
            }
        }
    }
    let (mut inside, mut inside_n, mut across, mut across_n) = (0.0, 0usize, 0.0, 0usize);
    for f in 0..out.mesh.face_count() {
        let n = out.mesh.face_normal(f);
        let tri = out.mesh.faces()[f];
        let c: f64 = tri
            .iter()
            .map(|&v| n.dot(out.normals[v as usize]) / 3.0)
            .sum();
        if tri.iter().any(|&v| regions_of[v as usize].len() > 1) {
            across += c;
            across_n += 1;
        } else {
            inside += c;
            inside_n += 1;
        }
    }
    // Thresholds: coarse meshes (a 100-vertex sphere: 0.970 inside) and coarse fits (blob3:
    // 0.794 at boundaries) pass; an inside-out mesh gives negative values.
    if inside_n > 0 {
        let inside = inside / inside_n as f64;
        assert!(
            inside > 0.95,
            "{context}: mean cosine inside regions {inside}"
        );
    }
    if across_n > 0 {
        let across = across / across_n as f64;
        assert!(
            across > 0.5,
            "{context}: mean cosine at boundaries {across}"
        );
    }
}

/// Asserts that every edge has two faces.
fn assert_closed(out: &Remeshed, context: &str) {
    assert!(out.check.closed, "{context}: {:?}", out.check);
    assert_eq!(out.mesh.topology().border_edge_count(), 0, "{context}");
}

// ---------------------------------------------------------------------------------------
// Distance between meshes

/// Distance from `p` to the triangle `a b c` (Ericson, Real-Time Collision Detection, 5.1.5).
fn point_triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (p - a).length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (p - b).length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + v * ab)).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (p - c).length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + w * ac)).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + w * (c - b))).length();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).length()
}

/// `count` points on `mesh`, area-weighted, deterministic.
fn sample_surface(mesh: &Mesh, count: usize, seed: u64) -> Vec<DVec3> {
    let areas = mesh.face_areas();
    let mut cumulative = Vec::with_capacity(areas.len());
    let mut total = 0.0;
    for a in &areas {
        total += a;
        cumulative.push(total);
    }
    let mut rng = SplitMix64::new(seed);
    (0..count)
        .map(|_| {
            let x = rng.next_f64() * total;
            let f = cumulative.partition_point(|&c| c < x).min(areas.len() - 1);
            let [a, b, c] = mesh.corners(f);
            let (mut u, mut v) = (rng.next_f64(), rng.next_f64());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            a + u * (b - a) + v * (c - a)
        })
        .collect()
}

/// Distance from `p` to `mesh`: brute force over a uniform grid of triangle boxes, searched
/// in growing shells until no closer triangle can exist.
struct Nearest<'a> {
    mesh: &'a Mesh,
    min: DVec3,
    cell: f64,
    dims: [usize; 3],
    cells: Vec<Vec<u32>>,
}

impl<'a> Nearest<'a> {
    fn new(mesh: &'a Mesh) -> Self {
        let bb = mesh.bounding_box().unwrap();
        let size = bb.size().max(DVec3::splat(1e-9));
        let cell = (size.x * size.y * size.z / mesh.face_count() as f64).cbrt() * 2.0;
        let dims = [
            (size.x / cell).ceil() as usize + 1,
            (size.y / cell).ceil() as usize + 1,
            (size.z / cell).ceil() as usize + 1,
        ];
        let mut cells = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let index = |p: DVec3, min: DVec3| {
            let q = ((p - min) / cell).floor();
            [
                (q.x.max(0.0) as usize).min(dims[0] - 1),
                (q.y.max(0.0) as usize).min(dims[1] - 1),
                (q.z.max(0.0) as usize).min(dims[2] - 1),
            ]
        };
        for f in 0..mesh.face_count() {
            let [a, b, c] = mesh.corners(f);
            let lo = index(a.min(b).min(c), bb.min);
            let hi = index(a.max(b).max(c), bb.min);
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        cells[(x * dims[1] + y) * dims[2] + z].push(f as u32);
                    }
                }
            }
        }
        Nearest {
            mesh,
            min: bb.min,
            cell,
            dims,
            cells,
        }
    }

    fn distance(&self, p: DVec3) -> f64 {
        let q = ((p - self.min) / self.cell).floor();
        let centre = [q.x as i64, q.y as i64, q.z as i64];
        let mut best = f64::INFINITY;
        let max_shell = *self.dims.iter().max().unwrap() as i64 + 2;
        for shell in 0..=max_shell {
            // Every point in cells outside this shell is at least shell·cell away (minus the
            // part of a cell p may be off the grid by, which the extra shell covers).
            if best < (shell as f64 - 1.0) * self.cell {
                break;
            }
            for x in centre[0] - shell..=centre[0] + shell {
                for y in centre[1] - shell..=centre[1] + shell {
                    for z in centre[2] - shell..=centre[2] + shell {
                        let on_shell = (x - centre[0]).abs() == shell
                            || (y - centre[1]).abs() == shell
                            || (z - centre[2]).abs() == shell;
                        if !on_shell
                            || x < 0
                            || y < 0
                            || z < 0
                            || x >= self.dims[0] as i64
                            || y >= self.dims[1] as i64
                            || z >= self.dims[2] as i64
                        {
                            continue;
                        }
                        let c =
                            (x as usize * self.dims[1] + y as usize) * self.dims[2] + z as usize;
                        for &f in &self.cells[c] {
                            let [a, b, cc] = self.mesh.corners(f as usize);
                            best = best.min(point_triangle_distance(p, a, b, cc));
                        }
                    }
                }
            }
        }
        best
    }
}

/// Symmetric sampled distance between two meshes: (RMS, max) over `count` points sampled on
/// each, as fractions of `a`'s bounding-box diagonal.
fn symmetric_distance(a: &Mesh, b: &Mesh, count: usize) -> (f64, f64) {
    let (na, nb) = (Nearest::new(a), Nearest::new(b));
    let mut sum = 0.0;
    let mut max: f64 = 0.0;
    for p in sample_surface(a, count, 1) {
        let d = nb.distance(p);
        sum += d * d;
        max = max.max(d);
    }
    for p in sample_surface(b, count, 2) {
        let d = na.distance(p);
        sum += d * d;
        max = max.max(d);
    }
    let diag = diagonal(a);
    ((sum / (2 * count) as f64).sqrt() / diag, max / diag)
}

#[test]
fn the_distance_helper_agrees_with_brute_force() {
    let mesh = source("torus.obj");
    let near = Nearest::new(&mesh);
    let mut rng = SplitMix64::new(5);
    for _ in 0..200 {
        let p = DVec3::new(
            rng.range_f64(-2.0, 2.0),
            rng.range_f64(-2.0, 2.0),
            rng.range_f64(-1.0, 1.0),
        );
        let brute = (0..mesh.face_count())
            .map(|f| {
                let [a, b, c] = mesh.corners(f);
                point_triangle_distance(p, a, b, c)
            })
            .fold(f64::INFINITY, f64::min);
        assert!((near.distance(p) - brute).abs() < 1e-12, "{p}");
    }
}

// ---------------------------------------------------------------------------------------
// Fixtures

/// Symmetric sampled distance bounds for the blobs (2000 points sampled on each side), as
/// fractions of the diagonal, at 8000 vertices. Measured (RMS, max): blob1 0.00141, 0.0136;
/// blob2 0.00103, 0.0113; blob3 0.00102, 0.0095; blob4 0.00121, 0.0106 — the maxima sit
/// where the fitted ellipsoids' intersection leaves the source's crease. Bounds about twice
/// the worst.
const BLOB_RMS_BOUND: f64 = 0.003;
const BLOB_MAX_BOUND: f64 = 0.025;

#[test]
fn blobs_decode_to_closed_clean_meshes_near_their_source() {
    for name in ["blob1.obj", "blob2.obj", "blob3.obj", "blob4.obj"] {
        let mesh = source(name);
        let (_, rep) = encode(&mesh, blob_ellipsoids(name));
        let out = remesh(&rep, &options(8000, Scheme::Adaptive)).unwrap();
        assert_clean(&out, name);
        assert_closed(&out, name);
        // Clean the first time: no fallback meshing was needed.
        assert_eq!(out.attempts, 1, "{name}");
        assert_eq!(out.mesh.topology().component_count(), 1, "{name}");
        let (rms, max) = symmetric_distance(&mesh, &out.mesh, 2000);
        println!("{name}: rms {rms:.5}, max {max:.5} of the diagonal");
        assert!(rms < BLOB_RMS_BOUND, "{name}: rms {rms}");
        assert!(max < BLOB_MAX_BOUND, "{name}: max {max}");
    }
}

/// A file's remesh hint is the treatment tried first: a blob that meshes clean in the first
/// attempt meshes clean, once, with another treatment when its file names that one; a hint
/// that names no treatment, or one not in the sequence, changes nothing.
#[test]
fn the_remesh_hint_is_tried_first() {
    use ellip::remesh::assemble::Treatment;
    let mesh = source("blob3.obj");
    let (_, mut rep) = encode(&mesh, blob_ellipsoids("blob3.obj"));
    let options = options(4000, Scheme::Adaptive);
    let plain = remesh(&rep, &options).unwrap();
    assert_clean(&plain, "blob3");
    assert_eq!(plain.attempts, 1);
    assert_eq!(plain.treatment, Some(Treatment::FIRST));
    let stored = Treatment {
        refined: false,
        prune: ellip::remesh::refine::Prune::Off,
        ..Treatment::FIRST
    };
    rep.metadata.remesh_hint = Some(stored.code());
    let hinted = remesh(&rep, &options).unwrap();
    assert_clean(&hinted, "blob3 hinted");
    assert_eq!(hinted.attempts, 1);
    assert_eq!(hinted.treatment, Some(stored));
    let same = |a: &Remeshed, b: &Remeshed| {
        a.mesh.positions() == b.mesh.positions() && a.mesh.faces() == b.mesh.faces()
    };
    assert!(
        !same(&hinted, &plain),
        "the stored arcs are not the refined ones"
    );
    // Code 6 has the fourth pruning value; rays where untangling would drop points are not
    // tried without untangling (they would repeat the closest points').
    let not_tried = Treatment {
        untangle: false,
        radial_where_untangled: true,
        ..stored
    };
    for code in [6, 1 << 7, u64::MAX, not_tried.code()] {
        rep.metadata.remesh_hint = Some(code);
        let out = remesh(&rep, &options).unwrap();
        assert!(same(&out, &plain), "hint {code}");
        assert_eq!(out.treatment, Some(Treatment::FIRST), "hint {code}");
    }
}

#[test]
fn a_sphere_only_file_gives_a_closed_sphere() {
    let bytes = std::fs::read(root().join("fixtures/ellip/v1/sphere.ellip")).unwrap();
    let rep = decode(&bytes, &Limits::default()).unwrap();
    assert_eq!(rep.region_count(), 1);
    assert!(rep.cycles[0].is_empty());
    let e = rep.ellipsoids[0];
    // 50 000: subdivided once; its new points must land on the sphere too.
    for budget in [100, 1000, 5000, 50_000] {
        let out = remesh(&rep, &options(budget, Scheme::Adaptive)).unwrap();
        let context = format!("sphere at {budget}");
        assert_clean(&out, &context);
        assert_closed(&out, &context);
        let n = out.mesh.vertex_count();
        assert!(
            n.abs_diff(budget) * 100 <= budget,
            "{context}: {n} vertices"
        );
        // Every vertex on the ellipsoid (to rounding).
        let scale = e.radii.max_element();
        for p in out.mesh.positions() {
            assert!(e.radial_distance(*p) < 1e-9 * scale, "{context}: {p}");
        }
        // Euler characteristic 2.
        let t = out.mesh.topology();
        let chi = n as i64 - t.edge_count() as i64 + out.mesh.face_count() as i64;
        assert_eq!(chi, 2, "{context}");
    }
}

/// Whole ellipsoids at the smallest budgets: three thin boxes, each a piece of eight
/// vertices encoded as one region (the ellipsoid of its solid, radii down to 1.24), decoded
/// at 10 to 100 vertices by either scheme. Each half of a whole ellipsoid gets its pole
/// first: with only its equator, a half was the equator's polygon, and both halves used the
/// same chords (edges of four faces): at 24 to 60 vertices the three decoded not manifold,
/// with up to 4 flipped triangles (by the parametric scheme at 10 to 100), and one alone at
/// 8 vertices with 2 flipped.
#[test]
fn thin_whole_ellipsoids_decode_clean_at_the_smallest_budgets() {
    let (mesh, _) = common::three_boxes();
    let (_, rep) = encode_unchecked(&mesh, 3);
    assert!(rep.cycles.iter().all(Vec::is_empty), "three whole regions");
    for budget in [10, 24, 30, 40, 60, 100] {
        for options in [
            by_vertex_addition(budget),
            options(budget, Scheme::Parametric),
        ] {
            let out = remesh(&rep, &options).unwrap();
            let c = out.check;
            let context = format!("{budget} {:?}", options.scheme);
            assert_eq!((c.flipped, c.degenerate), (0, 0), "{context}: {c:?}");
            assert!(
                c.closed && c.manifold && c.consistently_oriented,
                "{context}: {c:?}"
            );
            assert_eq!(out.attempts, 1, "{context}");
        }
    }
}

#[test]
fn an_open_hemisphere_keeps_one_border_loop() {
    let mesh = source("hemisphere.obj");
    let (_, rep) = encode(&mesh, 1);
    assert!(rep
        .arcs
        .iter()
        .any(|a| a.right == ellip::representation::Side::Border));
    let out = remesh(&rep, &options(3000, Scheme::Adaptive)).unwrap();
    assert_clean(&out, "hemisphere");
    assert!(!out.check.closed);
    assert_eq!(out.check.border_loops, 1);
    assert_eq!(out.mesh.topology().boundary_loops().len(), 1);
    let (rms, max) = symmetric_distance(&mesh, &out.mesh, 2000);
    // Measured 0.00014 and 0.0017 of the diagonal.
    println!("hemisphere: rms {rms:.5}, max {max:.5}");
    assert!(rms < 0.001 && max < 0.005, "{rms} {max}");
}

/// An ellipsoid with a small hole (one triangle of a subdivided icosahedron missing; scans
/// have them by the dozen), written without the encoder's check: it decodes as the
/// ellipsoid around its hole. Boundary smoothing shrank the three-point border loop to a
/// point (nothing to chart); with a hole a fiftieth of the surface across, the chart's pole
/// walked out of the hole and the region was meshed as the hole, one triangle turned over.
#[test]
fn an_ellipsoid_with_a_small_hole_decodes_around_it() {
    for subdivisions in [2, 3] {
        let sphere = ellip::synth::shapes::icosphere(1.0, subdivisions);
        let positions: Vec<DVec3> = sphere
            .positions()
            .iter()
            .map(|p| *p * DVec3::new(1.0, 0.6, 0.8))
            .collect();
        let mesh = Mesh::new(positions, sphere.faces()[1..].to_vec()).unwrap();
        let context = format!("{} faces and a hole", mesh.face_count());
        let (_, rep) = encode_unchecked(&mesh, 1);
        let out = remesh(&rep, &RemeshOptions::default()).unwrap();
        assert_clean(&out, &context);
        assert_eq!(out.check.border_loops, 1, "{context}");
        // The budget is the source's vertex count: as many triangles, give or take 2 %.
        let (got, want) = (out.mesh.face_count(), mesh.face_count());
        assert!(
            got.abs_diff(want) * 50 <= want,
            "{context}: {got} triangles"
        );
        // Measured 0.0036 and 0.022 of the diagonal at 319 faces, 0.0010 and 0.011 at
        // 1 279: the source's flat faces, not the decoder (whose points are on the fitted
        // ellipsoid).
        let (rms, max) = symmetric_distance(&mesh, &out.mesh, 2000);
        println!("{context}: rms {rms:.4}, max {max:.4}");
        assert!(rms < 0.005 && max < 0.03, "{context}: {rms} {max}");
    }
}

#[test]
fn the_bowl_decodes_with_its_inner_surface_facing_out() {
    let mesh = source("bowl.obj");
    let (_, rep) = encode(&mesh, 4);
    let out = remesh(&rep, &options(5000, Scheme::Adaptive)).unwrap();
    assert_clean(&out, "bowl");
    assert_eq!(
        out.check.closed,
        mesh.topology().is_closed(),
        "closed like its source"
    );
    let negative = rep
        .ellipsoids
        .iter()
        .any(|e| e.sign == ellip::ellipsoid::Sign::Negative);
    assert!(
        negative,
        "the bowl is fitted with an inner (negative) surface"
    );
    let (rms, max) = symmetric_distance(&mesh, &out.mesh, 2000);
    // Measured 0.00032 and 0.0061 of the diagonal.
    println!("bowl: rms {rms:.5}, max {max:.5}");
    assert!(rms < 0.001 && max < 0.012, "{rms} {max}");
}

#[test]
fn the_torus_decodes_to_a_closed_torus() {
    let mesh = source("torus.obj");
    let (_, rep) = encode(&mesh, 8);
    let out = remesh(&rep, &options(6000, Scheme::Adaptive)).unwrap();
    assert_clean(&out, "torus");
    assert_closed(&out, "torus");
    assert_eq!(out.mesh.genus(), Some(1));
    let (rms, max) = symmetric_distance(&mesh, &out.mesh, 2000);
    // Measured 0.0023 and 0.0136 of the diagonal (two of the eight fitted ellipsoids are
    // nearly cylinders and planes, meshed through a stand-in chart surface).
    println!("torus: rms {rms:.5}, max {max:.5}");
    assert!(rms < 0.005 && max < 0.025, "{rms} {max}");
}

/// A boundary stored off its ellipsoids (as on real meshes, where the fits miss the
/// boundary): the two-hemisphere file with its equator moved out by 2 %, 5 % and 10 % of the
/// radii. The paper's scheme puts every interior vertex on the ellipsoid, so the triangles
/// at the equator climb to it within an edge length and stand up as the budget grows (the
/// decoder before the blend: up to 89.9° off the ellipsoid's normal at 20 000 vertices).
/// With the boundary's heights blended in ([`ellip::remesh::surface`]) no triangle leans
/// more than 30° off (the blend's slope is at most 27°; measured 23.7–27.8°), at any budget,
/// and the equator points stay where the file put them.
#[test]
fn boundaries_off_their_ellipsoids_blend_in_without_standing_triangles() {
    for scale in [1.02, 1.05, 1.1] {
        let mut rep = ellip::format::sample::two_hemispheres();
        let e = rep.ellipsoids[0];
        for p in &mut rep.points {
            *p = e.center + (*p - e.center) * scale;
        }
        for budget in [2_000, 20_000, 80_000] {
            let context = format!("scale {scale}, {budget} vertices");
            let out = remesh(&rep, &options(budget, Scheme::Adaptive)).unwrap();
            assert_clean(&out, &context);
            assert_closed(&out, &context);
            let mut worst: f64 = 0.0;
            for f in 0..out.mesh.face_count() {
                let n = out.mesh.face_normal(f);
                let cos = n.dot(e.normal(out.mesh.face_centroid(f))).clamp(-1.0, 1.0);
                worst = worst.max(cos.acos().to_degrees());
            }
            println!("{context}: worst lean {worst:.1}°");
            assert!(worst < 30.0, "{context}: a triangle leans {worst}° off");
            for p in &rep.points {
                assert!(
                    out.mesh.positions().contains(p),
                    "{context}: boundary point {p} moved"
                );
            }
        }
    }
}

#[test]
fn the_vertex_budget_is_honoured_within_one_percent() {
    let mesh = source("blob2.obj");
    let (_, rep) = encode(&mesh, blob_ellipsoids("blob2.obj"));
    for scheme in [Scheme::Adaptive, Scheme::Parametric] {
        for budget in [2_000, 5_000, 20_000] {
            let out = remesh(&rep, &options(budget, scheme)).unwrap();
            let n = out.mesh.vertex_count();
            println!("{scheme:?} {budget}: {n} vertices");
            assert!(
                n.abs_diff(budget) * 100 <= budget,
                "{scheme:?}: {n} vertices for a budget of {budget}"
            );
            assert_closed(&out, &format!("{scheme:?} {budget}"));
        }
    }
}

/// The parametric grid meets the budget within 1 % where a piece's count jumps from nothing
/// to a row or more: the torus at K = 12 is one large region and eleven bands round the
/// tube, ten of which get no grid point at their first request and several hundred at
/// four times it. Each piece's mesh is chosen among its gridding rounds' for the closest
/// total; when only whole rounds were compared, it decoded 3 784 vertices at 5 000.
#[test]
fn the_parametric_grid_meets_the_budget_by_each_pieces_rounds() {
    let (_, rep) = encode(&source("torus.obj"), 12);
    for budget in [5_000, 20_000] {
        assert_parametric_budget_met(&rep, budget, "torus K = 12");
    }
}

/// Decodes `rep` parametrically at `budget` vertices and asserts the mesh within 1 % of it,
/// clean and closed.
fn assert_parametric_budget_met(rep: &Representation, budget: usize, what: &str) {
    let out = remesh(rep, &options(budget, Scheme::Parametric)).unwrap();
    let n = out.mesh.vertex_count();
    let context = format!("{what} at {budget}: {n} vertices");
    println!("{context}");
    assert!(n.abs_diff(budget) * 100 <= budget, "{context}");
    assert_clean(&out, &context);
    assert_closed(&out, &context);
}

/// A single piece's grid meets its budget within 1 % too, though a whole row of it is about
/// 4 % of its points at 5 000: the azimuths are scaled by the miss. The sphere fixture (one
/// region, no boundary, meshed as two halves) decoded 5 185 vertices at 5 000 and 9 829 at
/// 10 000 with whole rows alone.
#[test]
fn a_single_pieces_grid_meets_the_budget_by_its_azimuths() {
    let bytes = std::fs::read(root().join("fixtures/ellip/v1/sphere.ellip")).unwrap();
    let rep = decode(&bytes, &Limits::default()).unwrap();
    for budget in [1_000, 3_000, 5_000, 10_000, 30_000] {
        assert_parametric_budget_met(&rep, budget, "the sphere fixture");
    }
}

/// Small pieces and bands meet the budget too. A small piece's count jumps several per cent
/// a row, and its rows are resized by the miss up to three times before its azimuths are
/// scaled; a band no row fits in at its share's rows gets denser rows until one does, thinned
/// to its share. The capsule at K = 3 decoded 1 124 vertices at 1 000 (a piece asked for
/// 555 got 658 or 470, round after round), at K = 6 4 835 at 5 000; at K = 12 one band got
/// 0 points or 620 for its 151.
#[test]
fn small_pieces_and_bands_meet_the_parametric_budget() {
    let capsule = source("capsule.obj");
    for (k, budget) in [(3, 1_000), (6, 5_000), (12, 5_000)] {
        let (_, rep) = encode(&capsule, k);
        assert_parametric_budget_met(&rep, budget, &format!("capsule K = {k}"));
    }
}

/// Boundary points no region's loops use (an ear pruned from both regions' loops, a loop
/// that encloses nothing) are not in the mesh, and do not count against the budget: vertex
/// addition meets it exactly. blob1 encoded at K = 12 has 3 such points (2 997 vertices at
/// 3 000 when they were counted); Stanford's dragon at `res4` has 596, and decoded 4 404
/// vertices at 5 000.
#[test]
fn unused_boundary_points_do_not_count_against_the_budget() {
    let (_, rep) = encode(&source("blob1.obj"), 12);
    for budget in [1_000, 3_000, 10_000] {
        let out = remesh(&rep, &options(budget, Scheme::Adaptive)).unwrap();
        assert_clean(&out, &format!("{budget}"));
        assert_eq!(out.mesh.vertex_count(), budget);
    }
}

/// A treatment that meshes clean but stops short of the budget is not the last word. An
/// octahedron less one face, encoded as one region, names the stored arcs as its first
/// treatment (the one clean at its own 6 vertices); their loop is the missing face's three
/// edges, far off the ellipsoid, and the boundary clearance keeps every face after the
/// first split from being split again: it decoded 4 vertices at any budget of 1 000 or
/// more. The refined arcs meet the budget, clean.
#[test]
fn a_clean_mesh_short_of_the_budget_is_not_the_last_word() {
    use ellip::remesh::assemble::Treatment;
    let (x, y, z) = (1.0, 1.5, 0.7);
    let positions = vec![
        DVec3::new(x, 0.0, 0.0),
        DVec3::new(-x, 0.0, 0.0),
        DVec3::new(0.0, y, 0.0),
        DVec3::new(0.0, -y, 0.0),
        DVec3::new(0.0, 0.0, z),
        DVec3::new(0.0, 0.0, -z),
    ];
    // The octahedron's eight faces, outward, less [0, 3, 5].
    let faces = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
    ];
    let mesh = Mesh::new(positions, faces).unwrap();
    let (_, rep) = encode(&mesh, 1);
    let stored = rep
        .metadata
        .remesh_hint
        .and_then(Treatment::from_code)
        .expect("a hint");
    assert!(
        !stored.refined,
        "the hint names the stored arcs: {stored:?}"
    );
    for budget in [1_000, 5_000] {
        let out = remesh(&rep, &options(budget, Scheme::Adaptive)).unwrap();
        let context = format!("{budget}");
        assert_clean(&out, &context);
        assert_eq!(out.check.border_loops, 1, "{context}");
        let n = out.mesh.vertex_count();
        assert!(
            n.abs_diff(budget) * 100 <= budget,
            "{n} vertices at {budget}"
        );
        assert_eq!(out.attempts, 2, "{context}");
        assert!(out.treatment.is_some_and(|t| t.refined), "{context}");
    }
}

/// Mending faces turned against the ellipsoid removes interior vertices; vertex addition is
/// made again to make up for them. Two hemispheres whose boundary points are pulled to 0.6
/// of their distance from the centre (the blend falls steeply from them, and faces next to
/// the boundary turn over) decoded 1 758 vertices at 2 000 and 4 331 at 5 000 before, and
/// 4 681 at 5 000 with one retry.
#[test]
fn vertices_mending_removes_are_made_up_for() {
    let mut rep = ellip::format::sample::two_hemispheres();
    let e = rep.ellipsoids[0];
    for p in &mut rep.points {
        *p = e.center + (*p - e.center) * 0.6;
    }
    for budget in [2_000, 5_000] {
        let out = remesh(&rep, &by_vertex_addition(budget)).unwrap();
        // Clean by the decoder's check (not `assert_clean`: the analytic vertex normals
        // lean from faces on the steep blend, a mean cosine of 0.949 inside the regions).
        assert!(out.check.is_clean(), "{budget}: {}", out.check.faults());
        let n = out.mesh.vertex_count();
        assert!(
            n.abs_diff(budget) * 100 <= budget,
            "{n} vertices at {budget}"
        );
    }
}

#[test]
fn subdivision_levels_follow_the_budget() {
    let o = RemeshOptions::default();
    let c = SUBDIVISION_COARSE_VERTICES;
    // A few regions: the coarse mesh's floor is SUBDIVISION_COARSE_VERTICES.
    for (budget, levels) in [
        (4 * c - 1, 0),
        (4 * c, 1),
        (16 * c - 1, 1),
        (16 * c, 2),
        (64 * c, 3),
        (ellip::remesh::MAX_VERTICES, 3),
    ] {
        assert_eq!(o.subdivision_levels(budget, 8), levels, "{budget}");
    }
    // Many regions: SUBDIVISION_VERTICES_PER_REGION each.
    let regions = 1_000;
    let floor = regions * SUBDIVISION_VERTICES_PER_REGION;
    assert!(floor > c, "the premise: the regions set the floor");
    for (budget, levels) in [
        (4 * floor - 1, 0),
        (4 * floor, 1),
        (16 * floor - 1, 1),
        (16 * floor, 2),
        (64 * floor, 3),
    ] {
        assert_eq!(o.subdivision_levels(budget, regions), levels, "{budget}");
    }
    // Only the adaptive scheme, without a tolerance, and only when allowed.
    for other in [
        RemeshOptions {
            subdivision: false,
            ..o.clone()
        },
        RemeshOptions {
            tolerance: Some(1e-3),
            ..o.clone()
        },
        RemeshOptions {
            scheme: Scheme::Parametric,
            ..o.clone()
        },
    ] {
        assert_eq!(other.subdivision_levels(64 * c, 8), 0, "{other:?}");
    }
}

/// Large budgets are met by meshing adaptively at a quarter of the budget and splitting every
/// triangle into four (issue 6's throughput). The result must be what vertex addition gives:
/// clean and closed, the budget within 1 %, as close to the source (RMS within 10 %), and
/// near the surface vertex addition meshes (symmetric RMS under 0.1 % of the diagonal).
/// Faces left whole (red–green) may cost at most 0.1 % of the new vertices.
#[test]
fn subdivision_meets_large_budgets_like_vertex_addition() {
    let budget = 4 * SUBDIVISION_COARSE_VERTICES;
    for name in ["blob1.obj", "blob4.obj"] {
        let mesh = source(name);
        let (_, rep) = encode(&mesh, blob_ellipsoids(name));
        let levels = RemeshOptions::default().subdivision_levels(budget, rep.region_count());
        assert_eq!(levels, 1, "{name}");
        let fast = remesh(&rep, &options(budget, Scheme::Adaptive)).unwrap();
        let slow = remesh(&rep, &by_vertex_addition(budget)).unwrap();
        assert_clean(&fast, name);
        assert_closed(&fast, name);
        let n = fast.mesh.vertex_count();
        assert!(n.abs_diff(budget) * 100 <= budget, "{name}: {n} vertices");
        // It is the adaptive mesh at a quarter of the budget, subdivided once: every coarse
        // edge gets a new point (V + E vertices) unless a face had to stay whole.
        let coarse = remesh(&rep, &by_vertex_addition(budget / 4)).unwrap();
        let (v, e) = (
            coarse.mesh.vertex_count(),
            coarse.mesh.topology().edge_count(),
        );
        let again = subdivide(&rep, coarse, 1, usize::MAX).unwrap();
        assert_eq!(again.mesh.positions(), fast.mesh.positions(), "{name}");
        assert_eq!(again.mesh.faces(), fast.mesh.faces(), "{name}");
        assert!(
            n <= v + e && n * 1000 >= (v + e) * 999,
            "{name}: {n} of {}",
            v + e
        );
        let (f, s) = (rms_to(&mesh, &fast.mesh), rms_to(&mesh, &slow.mesh));
        let (between, _) = symmetric_distance(&fast.mesh, &slow.mesh, 4000);
        println!("{name}: RMS subdivided {f:.5}, vertex addition {s:.5}, apart {between:.5}");
        assert!(f <= 1.1 * s, "{name}: subdivided {f} vs {s}");
        assert!(between < 1e-3, "{name}: {between}");
    }
}

/// A real file (the bunny at K = 8, volume mode, as in the paper) at 500 000 vertices: its
/// adaptive mesh at a sixty-fourth of the budget is clean, subdivided three times it stays
/// clean and closed with about 64 times the triangles, and that is what the decoder returns.
/// (Before boundary heights were blended in, some of its coarse faces stood nearly edge-on
/// to their ellipsoids and stayed whole under red–green refinement; red–green itself is
/// tested in `remesh::subdivide`.)
#[test]
fn subdivision_keeps_a_clean_coarse_mesh_clean() {
    let Some(mesh) = common::shared_mesh("bunny") else {
        return;
    };
    let settings = EncodeSettings {
        segment: SegmentOptions {
            regions: RegionCount::Fixed(8),
            mode: ellip::segment::Mode::Volume,
            ..SegmentOptions::default()
        },
        ..EncodeSettings::default()
    };
    let bytes = encode_mesh(&mesh, &settings, &mut |_| {}).unwrap().bytes;
    let rep = decode(&bytes, &Limits::default()).unwrap();
    let budget = 500_000;
    assert_eq!(
        RemeshOptions::default().subdivision_levels(budget, rep.region_count()),
        3
    );
    let coarse = remesh(&rep, &by_vertex_addition(budget.div_ceil(64))).unwrap();
    assert_clean(&coarse, "coarse");
    let (v, f) = (coarse.mesh.vertex_count(), coarse.mesh.face_count());
    let fine = subdivide(&rep, coarse, 3, usize::MAX).unwrap();
    assert_clean(&fine, "subdivided");
    assert_closed(&fine, "subdivided");
    // 64 triangles per coarse one, fewer where faces stay whole (some, not many).
    assert!(
        fine.mesh.face_count() > 63 * f && fine.mesh.face_count() <= 64 * f,
        "{} of {}",
        fine.mesh.face_count(),
        64 * f
    );
    assert!(
        fine.mesh.vertex_count() > 63 * v,
        "{}",
        fine.mesh.vertex_count()
    );
    let decoded = remesh(&rep, &options(budget, Scheme::Adaptive)).unwrap();
    assert_eq!(decoded.mesh.faces(), fine.mesh.faces());
}

/// A file whose meshes are not clean: horse at K = 12 written without the encoder's check
/// (2 flipped triangles at 15 625 vertices, 7 at 62 500). At 250 000 vertices the decoder
/// subdivides its coarse mesh (15 625 vertices) twice and returns that, instead of meshing
/// at a quarter of the budget (62 500 vertices, more than `FALLBACK_MAX_VERTICES`) or at the
/// whole of it, for every meshing attempt (horse K = 20 took 28 s at 500 000 vertices that
/// way). The result is about the budget and no worse than the coarse mesh: subdivision adds
/// no fault of its own. (Should the decoder come to mesh this file clean, the premise fails
/// and another file is needed.)
#[test]
fn a_coarse_mesh_that_is_not_clean_is_subdivided_not_searched_at_the_full_budget() {
    let Some(mesh) = common::shared_mesh("horse") else {
        return;
    };
    let (_, rep) = encode_unchecked(&mesh, 12);
    let budget = 250_000;
    assert_eq!(
        RemeshOptions::default().subdivision_levels(budget, rep.region_count()),
        2
    );
    assert!(budget / 4 > ellip::remesh::assemble::FALLBACK_MAX_VERTICES);
    let coarse = remesh(&rep, &by_vertex_addition(budget / 16)).unwrap();
    // The premise: were the coarse mesh clean, this would test the clean path.
    assert!(!coarse.check.is_clean(), "{:?}", coarse.check);
    assert!(coarse.attempts > 1, "{}", coarse.attempts);
    let (faults, attempts) = (
        coarse.check.flipped + coarse.check.degenerate,
        coarse.attempts,
    );
    let fine = subdivide(&rep, coarse, 2, usize::MAX).unwrap();
    let decoded = remesh(&rep, &options(budget, Scheme::Adaptive)).unwrap();
    assert_eq!(decoded.mesh.positions(), fine.mesh.positions());
    assert_eq!(decoded.mesh.faces(), fine.mesh.faces());
    // The coarse mesh's attempts and no other: nothing was meshed at 62 500 vertices.
    assert_eq!(decoded.attempts, attempts);
    let c = decoded.check;
    assert!(c.flipped + c.degenerate <= faults, "{c:?} from {faults}");
    let n = decoded.mesh.vertex_count();
    assert!(n.abs_diff(budget) * 100 <= budget, "{n} vertices");
}

/// The first meshing attempt drops only the double ears whose chord is narrow
/// ([`ellip::remesh::refine::MAX_PRUNED_ANGLE`]). Pruning every one, hand K = 18 at 12 500
/// vertices had a chord 0.2 long across a finger of radius 0.1: the face on it turned over,
/// too close to the chord to be split (one flipped triangle), in the first two attempts, and
/// the third, without pruning, was clean. Now the first is.
#[test]
fn a_pruned_chord_does_not_cut_across_a_finger() {
    let Some(hand) = common::shared_mesh("hand") else {
        return;
    };
    let (_, rep) = encode(&hand, 18);
    let out = remesh(&rep, &by_vertex_addition(12_500)).unwrap();
    assert_clean(&out, "hand K = 18 at 12 500 vertices");
    assert_eq!(out.attempts, 1);
}

/// The encoder checks its file at one budget (the source's vertex count); a user decodes at
/// any. The horse at K = 24 has needle-like regions on its legs (radii down to 0.004 of a
/// 0.2 model), whose charts are far from isotropic: vertex addition used to split faces near
/// their boundaries into faces turned over (2 flipped triangles at 5 000 and at 12 500
/// vertices for this release's file; 30 and 198 for the last release's). Now a face at the
/// target scale is not split into a turned face, and both budgets decode clean.
#[test]
fn thin_regions_decode_clean_above_the_checked_budget() {
    let Some(mesh) = common::shared_mesh("horse") else {
        return;
    };
    let (_, rep) = encode(&mesh, 24);
    for budget in [5_000, 12_500] {
        let out = remesh(&rep, &by_vertex_addition(budget)).unwrap();
        assert_clean(&out, &format!("horse K = 24 at {budget} vertices"));
        assert_closed(&out, "horse");
    }
}

/// A coarse budget meshes every part of a region. hand at K = 12 has fingers fitted by
/// needles (radii 0.31 × 0.038 × 0.037 of a model 1.2 across): at 1 000 and 2 000 vertices one
/// ended in a flat cut 0.15 below its tip, 11 % of the diagonal from the source (4 % at
/// 5 000), because the faces across the tip turn over when first split and were left whole
/// (`CURVED_FACE_SPACINGS` in `remesh::triangulate`).
#[test]
fn coarse_budgets_mesh_fingers_to_their_tips() {
    let Some(hand) = common::shared_mesh("hand") else {
        return;
    };
    let (_, rep) = encode(&hand, 12);
    for budget in [1_000, 2_000] {
        let context = format!("hand K = 12 at {budget} vertices");
        let out = remesh(&rep, &by_vertex_addition(budget)).unwrap();
        assert_clean(&out, &context);
        let (rms, max) = symmetric_distance(&hand, &out.mesh, 20_000);
        println!("{context}: rms {rms:.4}, max {max:.4}");
        // Measured max 0.041 at both budgets (0.109 at 1 000 with the tip left flat).
        assert!(max < 0.06, "{context}: rms {rms}, max {max}");
    }
}

/// Splitting a face far from its surface into faces turned against the ellipsoid (the
/// test above) can leave one turned where the splits reach the boundary: dino at K = 8 has
/// a leg fitted by a needle (radii 0.46 × 0.030 × 0.034), and its file decoded with 1
/// flipped triangle in each of 12 meshing attempts (the encoder then mended it to 16
/// regions, 11 meshings to decode). Such a region is meshed again with its faces judged by
/// their length alone, and the file the encoder writes decodes clean at once.
#[test]
fn a_region_whose_curved_splits_leave_a_turned_face_is_meshed_by_length() {
    let Some(dino) = common::shared_mesh("dino") else {
        return;
    };
    let (_, rep) = encode(&dino, 8);
    let out = remesh(&rep, &RemeshOptions::default()).unwrap();
    assert_clean(&out, "dino K = 8");
    assert_eq!(out.attempts, 1);
}

/// A face that vertex addition leaves turned against its ellipsoid after diagonal swaps (two
/// corners on a boundary edge that lies off the ellipsoid, the third inside the region close
/// to it) is mended by removing the interior corners of the turned faces
/// (`AdaptiveTriangulation::finish`): duck at K = 12, decoded by vertex addition alone at
/// 31 250 vertices, kept 1 flipped triangle after 11 meshings; it is clean in one.
#[test]
fn a_face_left_turned_is_mended_by_removing_its_interior_corner() {
    let Some(duck) = common::shared_mesh("duck") else {
        return;
    };
    let (_, rep) = encode(&duck, 12);
    let out = remesh(&rep, &by_vertex_addition(31_250)).unwrap();
    assert_clean(&out, "duck K = 12 at 31 250 vertices");
    assert_eq!(out.attempts, 1);
}

/// Real meshes whose segmentation has nearly flat or needle-like regions (radii in the
/// thousands), whose estimated area is far too large: the adaptive scheme still spends its
/// budget (it lowers the minimum spacing) instead of stopping at a fraction of it (spot at
/// K = 18 decoded to 518 of 2 930 vertices, igea_small to 911 of 8 268).
#[test]
fn the_budget_is_spent_where_the_area_estimate_is_too_large() {
    for name in ["spot", "igea_small"] {
        let Some(mesh) = common::shared_mesh(name) else {
            return;
        };
        let (_, rep) = encode(&mesh, 18);
        let budget = mesh.vertex_count();
        let out = remesh(&rep, &RemeshOptions::default()).unwrap();
        let n = out.mesh.vertex_count();
        assert!(
            n.abs_diff(budget) * 100 <= budget,
            "{name}: {n} vertices for a budget of {budget}"
        );
        assert_clean(&out, name);
    }
}

/// RMS of the distance from the source's vertices to `mesh` (fraction of the diagonal).
fn rms_to(source: &Mesh, mesh: &Mesh) -> f64 {
    let near = Nearest::new(mesh);
    let sum: f64 = source
        .positions()
        .iter()
        .map(|&p| near.distance(p).powi(2))
        .sum();
    (sum / source.vertex_count() as f64).sqrt() / diagonal(source)
}

/// RMS distance (fraction of the diagonal) from `out`'s surface to the representation's:
/// [`ELLIPSOID_SAMPLES`] points drawn uniformly by area from its faces
/// ([`ellip::compare::sample_surface`]), each one's distance to the closest point of its
/// face's region's ellipsoid.
fn rms_to_ellipsoids(rep: &Representation, out: &Remeshed, diagonal: f64) -> f64 {
    let samples = ellip::compare::sample_surface(&out.mesh, ELLIPSOID_SAMPLES, 1);
    let squared: f64 = samples
        .iter()
        .map(|s| {
            let e = &rep.ellipsoids[out.face_regions[s.face as usize] as usize];
            s.point.distance_squared(e.closest_point(s.point))
        })
        .sum();
    (squared / samples.len() as f64).sqrt() / diagonal
}

/// Samples [`rms_to_ellipsoids`] draws.
const ELLIPSOID_SAMPLES: usize = 50_000;

/// The paper's Figure 8 claim, measured: at an equal vertex count the adaptive scheme is
/// closer to the representation's surface (the ellipsoids the remesher approximates) than
/// the parametric grid. Measured at 1 500 and 5 000 vertices: adaptive RMS 0.87–0.93 of the
/// grid's on the four blobs; asserted at most 0.95.
///
/// Not measured against the source: there the fit's own error (about 0.1 % of the diagonal)
/// is ten times the schemes' difference, and which scheme comes closer is a coin toss: at
/// 1 000, 1 500, 2 000, 3 000 and 5 000 vertices on the four blobs the grid came closer to
/// the source 11 times in 20 (symmetric RMS, `ellip compare`), and 14 once its azimuths
/// were scaled to meet its count (`RegionCdt::insert_grid`), blob4 at 1 500 among them,
/// which this test asserted before (the source's vertices 0.000919 of the diagonal from the
/// grid, 0.000926 from vertex addition).
///
/// The claim holds against the paper's grid (2·rows azimuths in every row, crowded round
/// its poles; ours thins only the rows within about 14° of them), not against every grid:
/// thinned to an even density (`POLE_ROW_SPACINGS` 1), the grid's RMS from the ellipsoids is
/// 8–16 % below vertex addition's on the blobs at 1 000 to 5 000 vertices (largest
/// distances the same: the boundary's blend sets them).
#[test]
fn adaptive_beats_parametric_at_equal_vertex_count() {
    for name in ["blob1.obj", "blob2.obj", "blob3.obj", "blob4.obj"] {
        let mesh = source(name);
        let (_, rep) = encode(&mesh, blob_ellipsoids(name));
        for budget in [1500, 5000] {
            // The grid's count is close to the budget; the adaptive scheme is given exactly it.
            let parametric = remesh(&rep, &options(budget, Scheme::Parametric)).unwrap();
            let count = parametric.mesh.vertex_count();
            let adaptive = remesh(&rep, &options(count, Scheme::Adaptive)).unwrap();
            assert_eq!(adaptive.mesh.vertex_count(), count, "{name}");
            let diagonal = diagonal(&mesh);
            let (a, p) = (
                rms_to_ellipsoids(&rep, &adaptive, diagonal),
                rms_to_ellipsoids(&rep, &parametric, diagonal),
            );
            println!(
                "{name}: {count} vertices, RMS to the ellipsoids adaptive {a:.3e}, \
                 parametric {p:.3e} ({:.3})",
                a / p
            );
            assert!(a <= 0.95 * p, "{name}: adaptive {a} vs parametric {p}");
        }
    }
}

#[test]
fn decoding_is_deterministic() {
    let mesh = source("blob3.obj");
    let (bytes, rep) = encode(&mesh, blob_ellipsoids("blob3.obj"));
    let again = decode(&bytes, &Limits::default()).unwrap();
    for scheme in [Scheme::Adaptive, Scheme::Parametric] {
        let a = remesh(&rep, &options(4000, scheme)).unwrap();
        let b = remesh(&again, &options(4000, scheme)).unwrap();
        assert_eq!(a.mesh.positions(), b.mesh.positions());
        assert_eq!(a.mesh.faces(), b.mesh.faces());
        assert_eq!(a.normals, b.normals);
        assert_eq!(a.face_regions, b.face_regions);
    }
}

/// Charts kept across decodes ([`remesh_with_charts`], as the encoder's check keeps them
/// across its rounds of mending) leave every file's mesh as it is decoded alone; a file
/// decoded again finds every chart it needs among them, and those of the decode before
/// the last are dropped.
#[test]
fn charts_kept_across_decodes_change_no_mesh() {
    let files: Vec<Representation> = ["blob2.obj", "blob3.obj"]
        .iter()
        .map(|name| encode_unchecked(&source(name), blob_ellipsoids(name)).1)
        .collect();
    let at = options(3000, Scheme::Adaptive);
    let charts = ChartMemo::default();
    let mut kept = Vec::new();
    for rep in [&files[0], &files[0], &files[1], &files[1]] {
        let shared = remesh_with_charts(rep, &at, &charts).unwrap();
        let alone = remesh(rep, &at).unwrap();
        assert_eq!(shared.mesh.positions(), alone.mesh.positions());
        assert_eq!(shared.mesh.faces(), alone.mesh.faces());
        assert_eq!(shared.normals, alone.normals);
        assert_eq!(shared.face_regions, alone.face_regions);
        kept.push(charts.len());
    }
    // A chart a region at least for the first file, all found again by its second decode;
    // none of the second file's found among them; the first's dropped after two decodes
    // that did not ask for them.
    assert!(kept[0] >= files[0].region_count(), "{kept:?}");
    assert_eq!(kept[1], kept[0]);
    assert!(kept[2] >= kept[1] + files[1].region_count(), "{kept:?}");
    assert_eq!(kept[3], kept[2] - kept[0]);
}

#[test]
fn the_tolerance_stops_refinement_early() {
    let mesh = source("blob1.obj");
    let (_, rep) = encode(&mesh, blob_ellipsoids("blob1.obj"));
    let coarse = remesh(
        &rep,
        &RemeshOptions {
            vertices: Some(50_000),
            tolerance: Some(0.01),
            ..RemeshOptions::default()
        },
    )
    .unwrap();
    let fine = remesh(
        &rep,
        &RemeshOptions {
            vertices: Some(50_000),
            tolerance: Some(0.001),
            ..RemeshOptions::default()
        },
    )
    .unwrap();
    let (c, f) = (coarse.mesh.vertex_count(), fine.mesh.vertex_count());
    println!("tolerance 1%: {c} vertices, 0.1%: {f} vertices");
    assert!(c < f && f < 50_000, "{c} {f}");
    assert_closed(&coarse, "coarse");
    assert_closed(&fine, "fine");
}

#[test]
fn golden_files_remesh_cleanly() {
    let dir = root().join("fixtures/ellip/v1");
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "ellip") {
            continue;
        }
        let rep = decode(&std::fs::read(&path).unwrap(), &Limits::default()).unwrap();
        let out = remesh(&rep, &options(3000, Scheme::Adaptive))
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let context = path.display().to_string();
        assert_clean(&out, &context);
        let border = rep
            .arcs
            .iter()
            .any(|a| a.right == ellip::representation::Side::Border);
        assert_eq!(out.check.closed, !border, "{context}");
    }
}

/// Every committed fuzz crash input remeshes to a mesh or an error, without panicking.
#[test]
fn fuzz_regressions_remesh_without_panicking() {
    let dir = root().join("fuzz/regressions");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return;
    };
    for entry in entries {
        let path = entry.unwrap().path();
        let Ok(rep) = decode(&std::fs::read(&path).unwrap(), &Limits::small()) else {
            continue;
        };
        for scheme in [Scheme::Adaptive, Scheme::Parametric] {
            let _ = remesh(
                &rep,
                &RemeshOptions {
                    vertices: Some(2_000),
                    scheme,
                    max_vertices: 100_000,
                    ..RemeshOptions::default()
                },
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// CLI

fn ellip(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_ellip"))
        .args(args)
        .output()
        .expect("the ellip binary runs")
}

fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ellip-remesh-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A cylinder of 32 sides whose ends are single 32-gons, as Blender writes its default
/// cylinder (assimp's `empty_mat.obj`): its caps are flat, fitted by ellipsoids thousands of
/// radii across, whose grids hold few points.
fn flat_capped_cylinder_obj() -> String {
    let n = 32;
    let mut obj = String::new();
    for i in 0..n {
        let (s, c) = (std::f64::consts::TAU * i as f64 / n as f64).sin_cos();
        obj += &format!("v {s} -1 {}\nv {s} 1 {}\n", -c, -c);
    }
    for i in 0..n {
        let j = (i + 1) % n;
        obj += &format!(
            "f {} {} {} {}\n",
            2 * i + 1,
            2 * i + 2,
            2 * j + 2,
            2 * j + 1
        );
    }
    let top: Vec<String> = (0..n).map(|i| (2 * i + 2).to_string()).collect();
    let bottom: Vec<String> = (0..n).rev().map(|i| (2 * i + 1).to_string()).collect();
    obj += &format!("f {}\nf {}\n", top.join(" "), bottom.join(" "));
    obj
}

/// `ellip decode --json` reports the budget it was asked for, and a decode more than 1 %
/// short of it says so on standard error (and only then). The flat-capped cylinder,
/// written without the decoder check, has nearly flat regions whose boundaries lie far off
/// their ellipsoids: vertex addition stops at 63 vertices of 5 000, where the parametric
/// grid gives 5 519. (Its checked file's grid gave 4 275 until the check measured regions
/// off the source in RMS too; now both schemes meet the budget there. Once the sphere
/// fixture's grid gave 9 829 at 10 000.)
#[test]
fn a_decode_short_of_its_budget_says_so() {
    let dir = scratch("short");
    let mesh = dir.join("cylinder.obj");
    std::fs::write(&mesh, flat_capped_cylinder_obj()).unwrap();
    let input = dir.join("cylinder.ellip");
    let out = ellip(&[
        "encode",
        mesh.to_str().unwrap(),
        "-o",
        input.to_str().unwrap(),
        "--no-verify",
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let output = dir.join("cylinder.ply");
    let mut shorts = 0;
    for scheme in ["adaptive", "parametric"] {
        let out = ellip(&[
            "decode",
            input.to_str().unwrap(),
            "-o",
            output.to_str().unwrap(),
            "--vertices",
            "5000",
            "--scheme",
            scheme,
            "--json",
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{scheme}: {stderr}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["vertex_budget"], 5000, "{scheme}");
        let n = v["vertices"].as_u64().unwrap();
        let short = n * 100 < 99 * 5000;
        assert_eq!(
            stderr.contains("short of the budget of 5000"),
            short,
            "{scheme}: {n} vertices: {stderr}"
        );
        shorts += usize::from(short);
    }
    assert_eq!(shorts, 1, "the adaptive decode is the short one");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn ellip_decode_writes_a_valid_glb() {
    let dir = scratch("decode");
    let mesh = source("blob2.obj");
    let (bytes, _) = encode(&mesh, blob_ellipsoids("blob2.obj"));
    let input = dir.join("blob2.ellip");
    std::fs::write(&input, &bytes).unwrap();
    let glb = dir.join("blob2.glb");
    let colored = dir.join("blob2-colors.glb");
    let out = ellip(&[
        "decode",
        input.to_str().unwrap(),
        "-o",
        glb.to_str().unwrap(),
        "--vertices",
        "3000",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["closed"], true);
    assert_eq!(v["flipped_triangles"], 0);
    assert_eq!(v["meshing_attempts"], 1);
    // The first treatment, code 0 (what a remesh hint would name).
    assert_eq!(v["treatment"], 0);
    let n = v["vertices"].as_u64().unwrap();
    assert!(n.abs_diff(3000) <= 30, "{n}");
    let out = ellip(&[
        "decode",
        input.to_str().unwrap(),
        "-o",
        colored.to_str().unwrap(),
        "--colors",
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stderr.is_empty());
    // The file reads back as the mesh that was written.
    let back = read_mesh(&glb, &ImportOptions::default()).unwrap().mesh;
    assert_eq!(back.vertex_count() as u64, n);
    assert!(back.topology().is_closed());
    // Refusals are one-line errors.
    for args in [
        vec!["decode", input.to_str().unwrap(), "-o", "x.stl"],
        vec![
            "decode",
            input.to_str().unwrap(),
            "-o",
            "x.glb",
            "--vertices",
            "0",
        ],
        vec![
            "decode",
            input.to_str().unwrap(),
            "-o",
            "x.glb",
            "--tolerance",
            "-1",
        ],
        vec!["decode", glb.to_str().unwrap(), "-o", "x.glb"],
        vec![
            "decode",
            input.to_str().unwrap(),
            "-o",
            input.to_str().unwrap(),
        ],
    ] {
        let out = ellip(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
    }
    if common::validator_ready() {
        let (ok, stdout) = common::run_validator(&[glb.clone(), colored.clone()]);
        assert!(ok, "the validator reports problems: {stdout}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn ellip_convert_goes_through_ellip() {
    let dir = scratch("convert");
    let input = root().join("fixtures/meshes/blob1.obj");
    let ellip_file = dir.join("blob1.ellip");
    let via = dir.join("via.ply");
    let back = dir.join("back.obj");
    let k = blob_ellipsoids("blob1.obj").to_string();
    let runs: [Vec<&str>; 3] = [
        vec![
            "convert",
            input.to_str().unwrap(),
            via.to_str().unwrap(),
            "--via-ellip",
            "-k",
            &k,
            "--vertices",
            "2000",
            "--quiet",
        ],
        vec![
            "convert",
            input.to_str().unwrap(),
            ellip_file.to_str().unwrap(),
            "-k",
            &k,
            "--quiet",
        ],
        vec![
            "convert",
            ellip_file.to_str().unwrap(),
            back.to_str().unwrap(),
            "--vertices",
            "2000",
            "--quiet",
        ],
    ];
    for args in &runs {
        let out = ellip(args);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for path in [&via, &back] {
        let m = read_mesh(path, &ImportOptions::default()).unwrap().mesh;
        assert!(m.topology().is_closed(), "{}", path.display());
        assert!(
            m.vertex_count().abs_diff(2000) <= 20,
            "{}",
            m.vertex_count()
        );
    }
    // Remeshing options without anything to remesh are refused.
    let out = ellip(&[
        "convert",
        input.to_str().unwrap(),
        dir.join("x.glb").to_str().unwrap(),
        "--vertices",
        "100",
    ]);
    assert_eq!(out.status.code(), Some(1));
    std::fs::remove_dir_all(&dir).ok();
}

/// `--no-subdivision` places every vertex by vertex addition: at 40 000 vertices both ways
/// decode clean and closed, to different meshes.
#[test]
fn ellip_decode_can_turn_subdivision_off() {
    let dir = scratch("no-subdivision");
    let mesh = source("blob1.obj");
    let (bytes, _) = encode(&mesh, blob_ellipsoids("blob1.obj"));
    let input = dir.join("blob1.ellip");
    std::fs::write(&input, &bytes).unwrap();
    let mut written = Vec::new();
    for extra in [None, Some("--no-subdivision")] {
        let output = dir.join(format!("blob1-{}.ply", extra.is_some()));
        let mut args = vec![
            "decode",
            input.to_str().unwrap(),
            "-o",
            output.to_str().unwrap(),
            "--vertices",
            "40000",
            "--json",
        ];
        args.extend(extra);
        let out = ellip(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["closed"], true, "{extra:?}");
        assert_eq!(v["flipped_triangles"], 0, "{extra:?}");
        written.push(std::fs::read(&output).unwrap());
    }
    assert_ne!(written[0], written[1]);
    std::fs::remove_dir_all(&dir).ok();
}

/// A band whose outer loop quantisation collapsed (a tiny cap's boundary, three points at
/// one position) is still meshed, bounded by its other loop, so the mesh stays closed: on a
/// closed surface which loop is outer is the encoder's choice. The decoder used to drop the
/// whole region and leave a hole where the cap across its other loop met it (horse at
/// K = 32 in some mending rounds). The point-in-region query agrees.
#[test]
fn a_region_whose_outer_loop_collapsed_keeps_its_other_loops() {
    use ellip::ellipsoid::Ellipsoid;
    use ellip::representation::{Arc, ArcRef, Cycle, Metadata, Side};
    let sphere = Ellipsoid::sphere(DVec3::ZERO, 1.0);
    let (north, band, south) = (0u32, 1u32, 2u32);
    // Latitude 0.5, counter-clockwise seen from above: the north cap on its left.
    let lat = 0.5f64;
    let mut points: Vec<DVec3> = (0..16)
        .map(|i| {
            let lon = std::f64::consts::TAU * i as f64 / 16.0;
            DVec3::new(lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin())
        })
        .collect();
    // The south cap's loop, collapsed to one position.
    points.extend([DVec3::NEG_Z; 3]);
    let cycle = |arc: u32, reversed: bool, outer: bool| Cycle {
        arcs: vec![ArcRef { arc, reversed }],
        outer,
    };
    let rep = Representation {
        ellipsoids: vec![sphere; 3],
        points,
        arcs: vec![
            Arc {
                points: (0..16).collect(),
                closed: true,
                left: north,
                right: Side::Region(band),
            },
            Arc {
                points: vec![16, 17, 18],
                closed: true,
                left: south,
                right: Side::Region(band),
            },
        ],
        cycles: vec![
            vec![cycle(0, false, true)],
            // The collapsed loop is the band's outer one, the other its hole.
            vec![cycle(1, true, true), cycle(0, true, false)],
            vec![cycle(1, false, true)],
        ],
        metadata: Metadata {
            source_vertices: 600,
            source_faces: 1196,
            ..Metadata::default()
        },
    };
    rep.validate().unwrap();
    let out = remesh(&rep, &RemeshOptions::default()).unwrap();
    assert_clean(&out, "collapsed outer loop");
    assert_closed(&out, "collapsed outer loop");
    let band_faces = out.face_regions.iter().filter(|&&r| r == band).count();
    assert!(band_faces > out.mesh.face_count() / 2, "{band_faces}");
    assert!(!out.face_regions.contains(&south));
    let chart = ellip::remesh::query::chart_region(&rep, band).unwrap();
    assert!(chart.contains(DVec3::X) && chart.contains(DVec3::new(0.0, 0.6, -0.8)));
    assert!(!chart.contains(DVec3::Z));
    // The cap has no face, and is not a region left out: `ellip decode` says so.
    assert_eq!(out.faceless_regions(rep.region_count()), [south]);
    assert!(out.omitted.is_empty());
    let dir = scratch("collapsed-loop");
    let input = dir.join("collapsed.ellip");
    let bytes = ellip::format::encode(&rep, &Default::default()).unwrap();
    std::fs::write(&input, bytes).unwrap();
    let output = dir.join("collapsed.ply");
    let decoded = ellip(&[
        "decode",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--json",
    ]);
    assert!(decoded.status.success());
    let v: serde_json::Value = serde_json::from_slice(&decoded.stdout).unwrap();
    assert_eq!(v["empty_regions"], serde_json::json!([south]));
    assert_eq!(v["omitted_regions"], serde_json::json!([]));
    let note = String::from_utf8_lossy(&decoded.stderr);
    assert!(note.contains("region(s) 2 have no face"), "{note}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Two separate pieces of a surface whose borders lie at the same positions (crossed cards
/// whose corners quantisation brought together: Wuson's whiskers in assimp's test models),
/// or are the same points (two fins of a scan on one non-manifold edge, each a piece of its
/// own: Stanford's dragon at `res4`), stay apart: two domes over one equator, each region on
/// the left of its border loop, so that glued, every equator edge would be run the same way
/// by both its faces.
#[test]
fn separate_pieces_whose_borders_meet_stay_apart() {
    use ellip::ellipsoid::Ellipsoid;
    use ellip::representation::{Arc, ArcRef, Cycle, Metadata, Side};
    let n = 24u32;
    // The equator, counter-clockwise seen from above: the domes on its left.
    let equator: Vec<DVec3> = (0..n)
        .map(|i| {
            let lon = std::f64::consts::TAU * i as f64 / n as f64;
            DVec3::new(lon.cos(), lon.sin(), 0.0)
        })
        .collect();
    let flat = Ellipsoid {
        radii: DVec3::new(1.0, 1.0, 0.5),
        ..Ellipsoid::sphere(DVec3::ZERO, 1.0)
    };
    let border = |from: u32, left: u32| Arc {
        points: (from..from + n).collect(),
        closed: true,
        left,
        right: Side::Border,
    };
    for shared in [false, true] {
        let cycle = |arc: u32| {
            vec![Cycle {
                arcs: vec![ArcRef {
                    arc,
                    reversed: false,
                }],
                outer: true,
            }]
        };
        let (points, second) = if shared {
            (equator.clone(), 0)
        } else {
            ([equator.clone(), equator.clone()].concat(), n)
        };
        let rep = Representation {
            ellipsoids: vec![Ellipsoid::sphere(DVec3::ZERO, 1.0), flat],
            points,
            arcs: vec![border(0, 0), border(second, 1)],
            cycles: vec![cycle(0), cycle(1)],
            metadata: Metadata::default(),
        };
        rep.validate().unwrap();
        let out = remesh(&rep, &options(1000, Scheme::Adaptive)).unwrap();
        let what = format!("two domes, points shared: {shared}");
        assert_clean(&out, &what);
        assert!(
            out.check.consistently_oriented && out.check.manifold,
            "{what}"
        );
        // Each dome keeps its own border loop (the equator's points and those refinement
        // put between them), sharing no vertex with the other.
        assert_eq!(out.check.border_loops, 2, "{what}");
        let loops = out.mesh.topology().boundary_loops();
        assert_eq!(loops.len(), 2, "{what}");
        assert!(loops[0].len() >= n as usize && loops[0].len() == loops[1].len());
        assert!(loops[0].iter().all(|v| !loops[1].contains(v)), "{what}");
    }
}

/// Untangling drops boundary points until a region's loops stop crossing in its chart; where
/// a whole loop folds (the closest points of a boundary deep inside a thin ellipsoid jump
/// between its sides), that leaves a triangle, turned over. The decoder then tries charting
/// such regions along the rays from their ellipsoids' centres, where those see the loops
/// uncrossed: teddy at K = 18, written without the encoder's check, decodes clean that way
/// (1 flipped triangle when every region was untangled or every region charted radially).
#[test]
fn regions_whose_loops_fold_are_charted_along_rays_instead_of_untangled() {
    let Some(mesh) = common::shared_mesh("teddy") else {
        return;
    };
    let (_, rep) = encode_unchecked(&mesh, 18);
    let out = remesh(&rep, &RemeshOptions::default()).unwrap();
    assert!(out.check.is_clean(), "{:?}", out.check);
}

/// armadillo at K = 12, written without the encoder's decoder check, has regions whose
/// loops cross in every attempt (its regions fold over their ellipsoids): the decoder
/// leaves them out and meshes the rest, with a hole where each would be, and says so.
#[test]
fn regions_no_attempt_can_mesh_are_left_out_as_holes() {
    let Some(mesh) = common::shared_mesh("armadillo") else {
        return;
    };
    let (bytes, rep) = encode_unchecked(&mesh, 12);
    let out = remesh(&rep, &RemeshOptions::default()).unwrap();
    let c = out.check;
    assert!(!out.omitted.is_empty(), "{c:?}");
    assert_eq!(c.omitted_regions, out.omitted.len());
    assert!(out.omitted.windows(2).all(|w| w[0] < w[1]));
    assert!(!c.is_clean() && !c.is_sound());
    assert!(c.faults().contains("left out"), "{}", c.faults());
    // The regions left out have no face, every other region has faces, and their holes
    // are the mesh's border.
    for r in 0..rep.region_count() as u32 {
        let faces = out.face_regions.iter().filter(|&&f| f == r).count();
        assert_eq!(
            out.omitted.contains(&r),
            faces == 0,
            "region {r}: {faces} faces"
        );
    }
    assert!(!c.closed && c.border_loops > 0, "{c:?}");
    // What is meshed is meshed as well as ever: no flipped or degenerate triangle.
    assert_eq!(c.flipped + c.degenerate, 0, "{c:?}");
    // Asked not to leave regions out, the decoder says which region fails.
    let strict = RemeshOptions {
        leave_out: false,
        ..RemeshOptions::default()
    };
    assert!(matches!(
        remesh(&rep, &strict),
        Err(ellip::remesh::RemeshError::Region { .. })
    ));
    // The same from the command line: a warning naming them, and --no-holes to fail.
    let expected: Vec<u64> = out.omitted.iter().map(|&r| u64::from(r)).collect();
    let dir = scratch("left-out");
    let input = dir.join("armadillo12.ellip");
    std::fs::write(&input, &bytes).unwrap();
    let output = dir.join("armadillo12.ply");
    let args = [
        "decode",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
    ];
    let out = ellip(&[&args[..], &["--json"]].concat());
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let listed: Vec<u64> = v["omitted_regions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_u64().unwrap())
        .collect();
    assert_eq!(listed, expected);
    assert!(String::from_utf8_lossy(&out.stderr).contains("left out"));
    let refused = ellip(&[&args[..], &["--no-holes"]].concat());
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("region"));
    std::fs::remove_dir_all(&dir).ok();
}

/// duck at K = 12, written without the encoder's decoder check, decodes with flipped
/// triangles in several regions: `triangle_faults_by_region` names each region that has
/// any with its counts, which add up to the check's and agree with each region's own
/// triangles tested against its ellipsoid; `ellip decode --json` lists the same, and its
/// warning names them.
#[test]
fn flipped_triangles_are_told_by_region() {
    use ellip::remesh::assemble::{triangle_faults_by_region, RegionTriangleFaults};
    let Some(mesh) = common::shared_mesh("duck") else {
        return;
    };
    let (bytes, rep) = encode_unchecked(&mesh, 12);
    let out = remesh(&rep, &RemeshOptions::default()).unwrap();
    let c = out.check;
    assert!(c.flipped > 0, "the file decodes clean now: {c:?}");
    let faults = triangle_faults_by_region(&rep, &out.mesh, &out.face_regions);
    assert!(faults.windows(2).all(|w| w[0].region < w[1].region));
    assert!(faults.iter().all(|f| f.flipped + f.degenerate > 0));
    let total = |count: fn(&RegionTriangleFaults) -> usize| faults.iter().map(count).sum::<usize>();
    assert_eq!(total(|f| f.flipped), c.flipped);
    assert_eq!(total(|f| f.degenerate), c.degenerate);
    // Each region's flipped triangles, counted here: normal against the ellipsoid's at
    // the centroid (none of these is degenerate).
    for (r, e) in rep.ellipsoids.iter().enumerate() {
        let side = e.normal_side();
        let flipped = (0..out.mesh.face_count())
            .filter(|&f| out.face_regions[f] == r as u32)
            .filter(|&f| side.along(out.mesh.face_centroid(f), out.mesh.face_area_vector(f)) < 0.0)
            .count();
        let listed = faults.iter().find(|f| f.region == r as u32);
        assert_eq!(listed.map_or(0, |f| f.flipped), flipped, "region {r}");
    }
    let dir = scratch("faulty-regions");
    let input = dir.join("duck12.ellip");
    std::fs::write(&input, &bytes).unwrap();
    let output = dir.join("duck12.ply");
    let run = ellip(&[
        "decode",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--json",
    ]);
    assert!(run.status.success());
    let v: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let listed: Vec<(u64, u64, u64)> = v["faulty_regions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            let n = |key: &str| f[key].as_u64().unwrap();
            (
                n("region"),
                n("flipped_triangles"),
                n("degenerate_triangles"),
            )
        })
        .collect();
    let expected: Vec<(u64, u64, u64)> = faults
        .iter()
        .map(|f| (u64::from(f.region), f.flipped as u64, f.degenerate as u64))
        .collect();
    assert_eq!(listed, expected);
    let stderr = String::from_utf8_lossy(&run.stderr);
    let first = &faults[0];
    assert!(
        stderr.contains(&format!(
            "by region: {} ({} flipped",
            first.region, first.flipped
        )),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The stored boundary edges of `region`, by point index, each the way its cycle runs it.
fn directed_boundary(rep: &Representation, region: usize) -> Vec<(u32, u32)> {
    let mut directed = Vec::new();
    for cycle in &rep.cycles[region] {
        for a in &cycle.arcs {
            let arc = &rep.arcs[a.arc as usize];
            let mut points = arc.points.clone();
            if arc.closed {
                points.push(points[0]);
            }
            if a.reversed {
                points.reverse();
            }
            directed.extend(points.windows(2).map(|w| (w[0], w[1])));
        }
    }
    directed
}

/// An open tube with a fin along one of its meridians, from rim to rim: one triangle on each
/// meridian edge, which makes the edge non-manifold (a border to each of its three faces).
/// The tube stays one piece, cut open along the meridian, and its one region's boundary
/// runs round one rim, up the meridian, round the other rim and down the meridian again.
/// Decoded, the meridian's two ways cancel (a seam, `assemble::without_seams`): the tube is
/// meshed across it with its two rims as loops. Before, the two ways were the same segment
/// constrained twice, the region's loops crossed in every chart and the tube was left out
/// of the mesh (a hole where the source has a surface).
#[test]
fn a_region_on_both_sides_of_a_non_manifold_edge_is_meshed_across_it() {
    let (around, along) = (24u32, 6u32);
    let tube = ellip::synth::shapes::cylinder(1.0, 3.0, around, along);
    let mut positions = tube.positions().to_vec();
    let mut faces = tube.faces().to_vec();
    for j in 0..along {
        // Vertex 0 of each ring lies on the meridian at x = 1, y = 0.
        let (a, b) = (j * around, (j + 1) * around);
        let apex =
            0.5 * (positions[a as usize] + positions[b as usize]) + DVec3::new(0.4, 0.0, 0.0);
        positions.push(apex);
        faces.push([a, b, positions.len() as u32 - 1]);
    }
    let mesh = Mesh::new(positions, faces).unwrap();
    let t = mesh.topology();
    assert_eq!(t.nonmanifold_edge_count(), along as usize);
    // The tube (cut along the meridian) and the fins, each a piece of its own.
    let pieces = t.component_count();
    assert_eq!(pieces, 1 + along as usize);
    let (_, rep) = encode_unchecked(&mesh, pieces);
    // The tube's region: the one with the longest boundary (two rims; a fin has three
    // edges); its cycle runs the meridian both ways.
    let tube_region = (0..rep.region_count())
        .max_by_key(|&r| directed_boundary(&rep, r).len())
        .unwrap();
    let directed = directed_boundary(&rep, tube_region);
    assert!(
        directed.iter().any(|&(u, v)| directed.contains(&(v, u))),
        "the tube's boundary runs no edge both ways"
    );
    let out = remesh(&rep, &RemeshOptions::default()).unwrap();
    assert_eq!(out.check.omitted_regions, 0, "{:?}", out.check);
    assert_eq!(
        (out.check.flipped, out.check.degenerate),
        (0, 0),
        "{:?}",
        out.check
    );
    // The tube is there: its faces cover its area (2π · 3 ≈ 18.85) to within 2 % (0.2 % off
    // when written).
    let tube_area: f64 = (0..out.mesh.face_count())
        .filter(|&f| out.face_regions[f] as usize == tube_region)
        .map(|f| 0.5 * out.mesh.face_area_vector(f).length())
        .sum();
    let expected = std::f64::consts::TAU * 3.0;
    assert!(
        (tube_area / expected - 1.0).abs() < 0.02,
        "tube area {tube_area}, expected {expected}"
    );
}

/// A torus with a fin on every edge of one meridian: cut along that circle it stays one
/// piece, a tube whose two rims are the meridian run both ways, so every edge of its one
/// region's boundary is a seam. Such a region closes on itself; it is left out of the mesh
/// and counted so (`RemeshError::Region`, the way a region whose loops cross is), not
/// skipped as if it enclosed nothing: with every seam dropped it had no loop left, and it
/// was missing from the mesh without a word. `region_faults` says why
/// (`RegionFault::seam`), for the encoder's check to cut it.
#[test]
fn a_region_whose_every_boundary_edge_is_a_seam_is_left_out_and_said_so() {
    let (around, meridian) = (24u32, 12u32);
    let (major, minor) = (2.0, 0.6);
    let torus = ellip::synth::shapes::torus(major, minor, around, meridian);
    let mut positions = torus.positions().to_vec();
    let mut faces = torus.faces().to_vec();
    // Vertices 0..meridian are the meridian at angle 0 round the axis, centred on
    // (major, 0, 0).
    for j in 0..meridian {
        let (a, b) = (j, (j + 1) % meridian);
        let middle = 0.5 * (positions[a as usize] + positions[b as usize]);
        let out = (middle - DVec3::new(major, 0.0, 0.0)).normalize();
        positions.push(middle + 0.3 * out);
        faces.push([a, b, positions.len() as u32 - 1]);
    }
    let mesh = Mesh::new(positions, faces).unwrap();
    let t = mesh.topology();
    assert_eq!(t.nonmanifold_edge_count(), meridian as usize);
    let pieces = t.component_count();
    assert_eq!(pieces, 1 + meridian as usize, "the cut torus and the fins");
    let (_, rep) = encode_unchecked(&mesh, pieces);
    // The torus's region: the one with the longest boundary (the meridian twice; a fin has
    // three edges).
    let torus_region = (0..rep.region_count())
        .max_by_key(|&r| directed_boundary(&rep, r).len())
        .unwrap();
    assert_eq!(rep.region_count(), pieces, "the torus is one region");
    // Every directed edge of its boundary has its reverse there too.
    let directed = directed_boundary(&rep, torus_region);
    assert!(!directed.is_empty());
    assert!(
        directed.iter().all(|&(u, v)| directed.contains(&(v, u))),
        "{directed:?}"
    );
    let out = remesh(&rep, &RemeshOptions::default()).unwrap();
    let torus_faces = out
        .face_regions
        .iter()
        .filter(|&&r| r as usize == torus_region)
        .count();
    assert_eq!(torus_faces, 0);
    assert_eq!(out.check.omitted_regions, 1, "{:?}", out.check);
    assert!(
        out.omitted.contains(&(torus_region as u32)),
        "{:?}",
        out.omitted
    );
    let faults = ellip::remesh::assemble::region_faults(
        &rep,
        &RemeshOptions::default(),
        &ellip::remesh::ChartMemo::default(),
    )
    .unwrap();
    let seams: Vec<u32> = faults.iter().filter(|f| f.seam).map(|f| f.region).collect();
    assert_eq!(seams, [torus_region as u32], "{faults:?}");
}
