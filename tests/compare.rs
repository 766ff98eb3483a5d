//! `ellip::compare` and `ellip compare`: the sampled figures against brute force and against
//! shapes whose distances are known, determinism, hostile inputs, and the command line.

use ellip::compare::{
    closest_point_on_triangle, compare_meshes, sample_surface, CompareError, CompareOptions,
    Comparison, Deviation,
};
use ellip::synth::shapes::{bowl, hemisphere, icosphere, torus};
use ellip::Mesh;
use glam::DVec3;
use std::path::Path;
use std::process::{Command, Output};

fn options(samples: usize) -> CompareOptions {
    CompareOptions {
        samples,
        ..CompareOptions::default()
    }
}

/// A smooth, non-uniform bump field: a perturbed copy of a mesh.
fn perturbed(mesh: &Mesh, amplitude: f64) -> Mesh {
    mesh.map_positions(|p| {
        p + DVec3::new(
            (3.0 * p.y + 1.0).sin(),
            (2.0 * p.z - 0.5).cos(),
            (4.0 * p.x).sin(),
        ) * amplitude
    })
    .unwrap()
}

/// The deviation of `source` from `target` by testing every sample against every triangle,
/// with the samples `compare_meshes` draws (A with the seed, B with seed + 1).
fn brute_force(source: &Mesh, target: &Mesh, samples: usize, seed: u64) -> (f64, f64, f64, f64) {
    let closest = |p: DVec3| -> (f64, usize) {
        let mut best = (f64::INFINITY, usize::MAX);
        for f in 0..target.face_count() {
            if target.face_normal(f) == DVec3::ZERO {
                continue;
            }
            let d2 = closest_point_on_triangle(p, target.corners(f)).distance_squared(p);
            if d2 < best.0 {
                best = (d2, f);
            }
        }
        best
    };
    let points = sample_surface(source, samples, seed);
    let (mut max_d2, mut sum_d2, mut sum_d, mut sum_angle) = (0.0f64, 0.0, 0.0, 0.0);
    for s in &points {
        let (d2, f) = closest(s.point);
        max_d2 = max_d2.max(d2);
        sum_d2 += d2;
        sum_d += d2.sqrt();
        sum_angle += s.normal.angle_between(target.face_normal(f)).to_degrees();
    }
    for (f, face) in source.faces().iter().enumerate() {
        if source.face_normal(f) != DVec3::ZERO {
            for &v in face {
                max_d2 = max_d2.max(closest(source.positions()[v as usize]).0);
            }
        }
    }
    let n = points.len() as f64;
    (max_d2.sqrt(), (sum_d2 / n).sqrt(), sum_d / n, sum_angle / n)
}

fn assert_matches_brute_force(a: &Mesh, b: &Mesh, samples: usize, what: &str) {
    let opts = options(samples);
    let c = compare_meshes(a, b, &opts).unwrap();
    for (d, (source, target, seed)) in [
        (&c.a_to_b, (a, b, opts.seed)),
        (&c.b_to_a, (b, a, opts.seed + 1)),
    ] {
        let (h, rms, mean, angle) = brute_force(source, target, samples, seed);
        // The issue asks for 1% on RMS and Hausdorff; the index is exact, so the figures agree
        // to rounding (1e-9 relative; angles to 1e-6° as ties may pick another face).
        let x = &d.distances;
        assert!(
            rms > 0.0 && h > 0.0,
            "{what}: a test that can fail needs a distance"
        );
        assert!(
            (x.hausdorff - h).abs() <= 1e-9 * h,
            "{what}: H {} vs {h}",
            x.hausdorff
        );
        assert!(
            (x.rms - rms).abs() <= 1e-9 * rms,
            "{what}: RMS {} vs {rms}",
            x.rms
        );
        assert!(
            (x.mean - mean).abs() <= 1e-9 * mean,
            "{what}: mean {} vs {mean}",
            x.mean
        );
        assert!(
            (d.normal_deviation - angle).abs() < 1e-6,
            "{what}: normals {} vs {angle}",
            d.normal_deviation
        );
    }
}

#[test]
fn figures_match_brute_force_on_small_meshes() {
    let sphere = icosphere(1.0, 2); // 320 faces
    assert_matches_brute_force(&sphere, &perturbed(&sphere, 0.03), 3000, "sphere");
    let ring = torus(1.0, 0.3, 24, 12); // 576 faces
    assert_matches_brute_force(&ring, &perturbed(&ring, 0.05), 3000, "torus");
    // Open surfaces: boundary edges and rims are where closest points land on edges.
    assert_matches_brute_force(&hemisphere(1.0, 2), &bowl(1.0, 2), 3000, "hemisphere/bowl");
}

#[test]
fn a_sphere_scaled_by_1_01_is_0_01_away() {
    // A = icosphere (5120 faces, every vertex on the unit sphere), B = A × 1.01. Every face of
    // B is its A face moved out by 1% of that face's plane distance d_f ∈ [1 − sag, 1], so
    // every distance, either way, lies in [0.01·(1 − sag), 0.01]; the sag of this tessellation
    // is below 1e-3, so all figures are within 0.1% of 0.01.
    let a = icosphere(1.0, 4);
    let b = a.map_positions(|p| p * 1.01).unwrap();
    let c = compare_meshes(&a, &b, &options(20_000)).unwrap();
    for d in [&c.a_to_b, &c.b_to_a, &c.symmetric] {
        let x = &d.distances;
        for value in [x.hausdorff, x.rms, x.mean] {
            assert!((0.00999..=0.01 + 1e-12).contains(&value), "{x:?}");
        }
        // Equal normals, except where a closest point lands on an edge of the other mesh
        // and the tie goes to the neighbouring face (~4° apart): 0.03° on average here.
        assert!(d.normal_deviation < 0.1, "{}", d.normal_deviation);
    }
    // Relative figures are fractions of A's diagonal (a little under 2√3 here).
    let diagonal = a.bounding_box().unwrap().diagonal();
    assert_eq!(c.diagonal, diagonal);
    let relative = c.relative(&c.symmetric);
    assert_eq!(relative.rms, c.symmetric.distances.rms / diagonal);
    assert!(
        (0.00999 / 3.47..0.01 / 3.4).contains(&relative.rms),
        "{relative:?}"
    );
}

#[test]
fn a_translated_copy_is_the_translation_apart() {
    // A convex polytope P and P + t are exactly |t| apart in Hausdorff distance, reached at
    // P's vertex extreme against t (the icosphere's pole): vertices are measured, so the
    // figure is exact, not a sampled lower bound.
    let a = icosphere(1.0, 3);
    let t = DVec3::new(0.0, 0.0, 0.05);
    let b = a.map_positions(|p| p + t).unwrap();
    let c = compare_meshes(&a, &b, &options(20_000)).unwrap();
    for d in [&c.a_to_b, &c.b_to_a] {
        let x = &d.distances;
        assert!((x.hausdorff - 0.05).abs() < 1e-12, "{x:?}");
        assert!(x.mean < x.rms && x.rms < 0.05, "{x:?}");
    }
    assert!((c.a_to_b.farthest - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
}

#[test]
fn identical_meshes_are_zero_apart() {
    let ring = torus(1.0, 0.4, 30, 16);
    let c = compare_meshes(&ring, &ring, &options(10_000)).unwrap();
    assert!(c.symmetric.distances.hausdorff < 1e-12, "{:?}", c.symmetric);
    assert!(c.symmetric.normal_deviation < 1e-6);
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let a = icosphere(1.0, 3);
    let b = perturbed(&a, 0.02);
    let run = |threads: usize| -> Comparison {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| compare_meshes(&a, &b, &options(30_000)).unwrap())
    };
    let one = run(1);
    for threads in [2, 3, 8] {
        let other = run(threads);
        let bits = |d: &Deviation| {
            [
                d.distances.hausdorff,
                d.distances.rms,
                d.distances.mean,
                d.normal_deviation,
            ]
            .map(f64::to_bits)
        };
        assert_eq!(
            bits(&one.symmetric),
            bits(&other.symmetric),
            "{threads} threads"
        );
        assert_eq!(one, other, "{threads} threads");
    }
    // And another seed gives other samples: the figures move, a little.
    let reseeded = compare_meshes(
        &a,
        &b,
        &CompareOptions {
            seed: 99,
            ..options(30_000)
        },
    )
    .unwrap();
    assert_ne!(reseeded.a_to_b.distances.rms, one.a_to_b.distances.rms);
    let (r1, r2) = (reseeded.a_to_b.distances.rms, one.a_to_b.distances.rms);
    assert!((r1 - r2).abs() < 0.02 * r2, "{r1} vs {r2}");
}

#[test]
fn meshes_without_surface_are_typed_errors() {
    let sphere = icosphere(1.0, 1);
    let empty = Mesh::new(Vec::new(), Vec::new()).unwrap();
    let r = compare_meshes(&sphere, &empty, &options(100));
    assert!(
        matches!(
            r,
            Err(CompareError::NoSurface {
                mesh: "B",
                faces: 0
            })
        ),
        "{r:?}"
    );
    // Only degenerate faces: collinear corners, and a sliver whose normal underflows.
    let flat = Mesh::new(
        vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::X * 2.0,
            DVec3::new(0.0, 1e-170, 0.0),
            DVec3::new(1e-170, 0.0, 0.0),
        ],
        vec![[0, 1, 2], [0, 3, 4]],
    )
    .unwrap();
    let r = compare_meshes(&flat, &sphere, &options(100));
    assert!(
        matches!(
            r,
            Err(CompareError::NoSurface {
                mesh: "A",
                faces: 2
            })
        ),
        "{r:?}"
    );
}

#[test]
fn degenerate_faces_beside_real_ones_are_ignored() {
    // The sphere plus a zero-area face far away: it is neither sampled nor a closest face.
    let sphere = icosphere(1.0, 2);
    let (mut positions, mut faces) = sphere.clone().into_parts();
    let n = positions.len() as u32;
    positions.extend([DVec3::splat(5.0), DVec3::splat(6.0), DVec3::splat(7.0)]);
    faces.push([n, n + 1, n + 2]);
    let with_sliver = Mesh::new(positions, faces).unwrap();
    let c = compare_meshes(&sphere, &with_sliver, &options(2000)).unwrap();
    assert!(c.symmetric.distances.hausdorff < 1e-12, "{:?}", c.symmetric);
    assert_eq!(c.b_to_a.vertices, sphere.vertex_count());
}

#[test]
fn any_scale_is_measured_exactly_and_overflow_is_an_error() {
    // Scaling both meshes by a power of two scales every figure by it exactly.
    let a = icosphere(1.0, 2);
    let b = perturbed(&a, 0.03);
    let base = compare_meshes(&a, &b, &options(3000)).unwrap();
    for e in [-300, -100, 100, 300] {
        let s = 2f64.powi(e);
        let (sa, sb) = (
            a.map_positions(|p| p * s).unwrap(),
            b.map_positions(|p| p * s).unwrap(),
        );
        let c = compare_meshes(&sa, &sb, &options(3000)).unwrap();
        let (x, y) = (c.symmetric.distances, base.symmetric.distances);
        assert_eq!(
            [x.hausdorff, x.rms, x.mean],
            [y.hausdorff * s, y.rms * s, y.mean * s]
        );
        assert_eq!(
            c.symmetric.normal_deviation,
            base.symmetric.normal_deviation
        );
        assert_eq!(c.relative(&c.symmetric), base.relative(&base.symmetric));
    }
    // 1e300 against its mirror image: 2e300 apart, near f64::MAX, still finite.
    let far = a.map_positions(|p| p * 1e299 + DVec3::X * 1e300).unwrap();
    let mirror = far.map_positions(|p| p - DVec3::X * 2e300).unwrap();
    let c = compare_meshes(&far, &mirror, &options(500)).unwrap();
    assert!(c.symmetric.distances.hausdorff.is_finite());
    assert!((c.symmetric.distances.hausdorff / 2e300 - 1.0).abs() < 1e-9);
    // Farther than f64::MAX: a typed error.
    let edge = a.map_positions(|p| p * 1e300 + DVec3::X * 1.5e308).unwrap();
    let other = a.map_positions(|p| p * 1e300 - DVec3::X * 1.5e308).unwrap();
    let r = compare_meshes(&edge, &other, &options(100));
    assert!(matches!(r, Err(CompareError::Overflow { .. })), "{r:?}");
    // 1e300 beside 1e-300: at the common scale the small one has no area left.
    let tiny = a.map_positions(|p| p * 1e-300).unwrap();
    let huge = a.map_positions(|p| p * 1e300).unwrap();
    let r = compare_meshes(&tiny, &huge, &options(100));
    assert!(
        matches!(r, Err(CompareError::NoSurface { mesh: "A", .. })),
        "{r:?}"
    );
}

// ---- the command line ----

fn ellip(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ellip"))
        .args(args)
        .output()
        .expect("the ellip binary runs")
}

fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/meshes")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

#[test]
fn cli_prints_json_with_both_directions_and_relative_figures() {
    let (a, b) = (fixture("blob1.obj"), fixture("blob2.obj"));
    let out = ellip(&["compare", &a, &b, "--samples", "5000", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let diagonal = json["diagonal"].as_f64().unwrap();
    for key in ["a_to_b", "b_to_a", "symmetric"] {
        let row = &json[key];
        let h = row["hausdorff"].as_f64().unwrap();
        let rms = row["rms"].as_f64().unwrap();
        let mean = row["mean"].as_f64().unwrap();
        assert!(0.0 < mean && mean <= rms && rms <= h, "{key}: {row}");
        let rel = row["rms_relative"].as_f64().unwrap();
        assert!((rel * diagonal - rms).abs() < 1e-12 * rms.max(1.0), "{key}");
        let angle = row["normal_deviation_degrees"].as_f64().unwrap();
        assert!((0.0..=180.0).contains(&angle));
    }
    assert_eq!(json["a_to_b"]["samples"], 5000);
    // The same command prints the same bytes.
    let again = ellip(&["compare", &a, &b, "--samples", "5000", "--json"]);
    assert_eq!(out.stdout, again.stdout);
}

#[test]
fn cli_prints_a_table() {
    let a = fixture("icosphere.obj");
    let out = ellip(&["compare", &a, &a, "--samples", "1000"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for label in ["Hausdorff", "RMS", "A → B", "B → A", "symmetric"] {
        assert!(text.contains(label), "{label} missing from {text}");
    }
}

/// An error is exit code 1 and exactly one line on stderr, never a panic message.
fn assert_clean_failure(out: &Output, context: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{context}: stderr {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{context}: {stderr:?}");
    assert!(stderr.starts_with("ellip: error: "), "{context}: {stderr}");
    assert!(!stderr.contains("panicked"), "{context}: {stderr}");
}

#[test]
fn cli_errors_are_one_line() {
    let a = fixture("icosphere.obj");
    assert_clean_failure(&ellip(&["compare", &a, "/nonexistent.obj"]), "missing file");
    assert_clean_failure(&ellip(&["compare", &a, &a, "--samples", "0"]), "0 samples");
    assert_eq!(ellip(&["compare", &a]).status.code(), Some(2));
}

#[test]
fn cli_reads_an_ellip_file_or_fails_cleanly() {
    // A `.ellip` input is decoded and remeshed; until the remesher is complete, the command
    // must fail with one line rather than panic.
    let dir = std::env::temp_dir().join(format!("ellip-compare-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let encoded = dir.join("blob1.ellip");
    let src = fixture("blob1.obj");
    let out = ellip(&["encode", &src, "-k", "3", "-o", encoded.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = ellip(&[
        "compare",
        &src,
        encoded.to_str().unwrap(),
        "--samples",
        "2000",
        "--json",
    ]);
    if out.status.success() {
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        // Three fitted ellipsoids of a blob made of three: close to the source.
        let rel = json["symmetric"]["rms_relative"].as_f64().unwrap();
        assert!(rel < 0.02, "RMS {rel} of the diagonal");
    } else {
        assert_clean_failure(&out, "compare with .ellip");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
