//! The encoding pipeline (`ellip::encode`): what the boundary tolerance promises, and the
//! automatic choice of the grid.

mod common;

use ellip::compare::distance_to_segment;
use ellip::encode::{encode_mesh, EncodeSettings, AUTO_BITS};
use ellip::format::{decode, inspect, Limits};
use ellip::import::{read_mesh, ImportOptions};
use ellip::segment::{RegionCount, SegmentOptions};
use ellip::Mesh;
use glam::DVec3;
use std::path::Path;

fn blob(name: &str) -> Mesh {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("fixtures/meshes/{name}.obj"));
    read_mesh(&path, &ImportOptions::default()).unwrap().mesh
}

fn settings(k: usize) -> EncodeSettings {
    EncodeSettings {
        segment: SegmentOptions {
            regions: RegionCount::Fixed(k),
            ..SegmentOptions::default()
        },
        ..EncodeSettings::default()
    }
}

#[test]
fn every_boundary_point_stays_within_the_boundary_tolerance() {
    for (name, k) in [("blob2", 4), ("blob3", 5)] {
        let mesh = blob(name);
        let diagonal = mesh.bounding_box().unwrap().diagonal();
        for tolerance in [1e-3, 4e-3] {
            let mut s = settings(k);
            s.simplify_tolerance = tolerance;
            let encoded = encode_mesh(&mesh, &s, &mut |_| {}).unwrap();
            // The same boundary, neither simplified nor (to 24 bits) quantised.
            let mut exact = settings(k);
            exact.simplify_tolerance = 0.0;
            exact.bits = Some(24);
            let exact = encode_mesh(&mesh, &exact, &mut |_| {})
                .unwrap()
                .representation;
            let decoded = decode(&encoded.bytes, &Limits::default()).unwrap();
            assert_eq!(decoded.arcs.len(), exact.arcs.len());
            let mut worst = 0.0f64;
            for i in 0..exact.arcs.len() {
                let mut after = decoded.arc_positions(i).unwrap();
                if decoded.arcs[i].closed {
                    after.push(after[0]);
                }
                for p in exact.arc_positions(i).unwrap() {
                    let d = after
                        .windows(2)
                        .map(|w| distance_to_segment(p, w[0], w[1]))
                        .fold(f64::INFINITY, f64::min);
                    worst = worst.max(d);
                }
            }
            println!(
                "{name} τ = {tolerance}: {} bytes at {} bits, worst boundary error {:.2e}·diag",
                encoded.bytes.len(),
                encoded.bits,
                worst / diagonal
            );
            // The grid's exact rounding (24 bits) is the only slack.
            assert!(worst <= tolerance * diagonal * (1.0 + 1e-6), "{worst}");
            // Ellipsoids move by at most the grid's bound, itself within the tolerance.
            let bound = inspect(&encoded.bytes, &Limits::default())
                .unwrap()
                .error_bound;
            assert!(bound < tolerance * diagonal);
            for (a, b) in encoded
                .representation
                .ellipsoids
                .iter()
                .zip(&decoded.ellipsoids)
            {
                for u in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE.normalize()] {
                    let d = (a.from_unit_sphere(u) - b.from_unit_sphere(u)).length();
                    assert!(d <= bound * (1.0 + 1e-9) + 1e-12, "{d} > {bound}");
                }
            }
        }
    }
}

#[test]
fn the_automatic_grid_gives_the_smallest_file_of_those_it_tries() {
    let mesh = blob("blob2");
    let auto = encode_mesh(&mesh, &settings(4), &mut |_| {}).unwrap();
    assert!(AUTO_BITS.contains(&auto.bits));
    for bits in [auto.bits.saturating_sub(1), auto.bits + 1, 12]
        .into_iter()
        .filter(|b| AUTO_BITS.contains(b))
    {
        let mut s = settings(4);
        s.bits = Some(bits);
        match encode_mesh(&mesh, &s, &mut |_| {}) {
            Ok(fixed) => assert!(
                auto.bytes.len() <= fixed.bytes.len(),
                "{} bits: {} < {}",
                bits,
                fixed.bytes.len(),
                auto.bytes.len()
            ),
            // Too coarse a grid for the tolerance is refused, not silently exceeded.
            Err(e) => assert!(e.to_string().contains("bits"), "{e}"),
        }
    }
    // Deterministic.
    let again = encode_mesh(&mesh, &settings(4), &mut |_| {}).unwrap();
    assert!(again.bytes == auto.bytes);
}

/// Symmetric RMS distance by brute force, independent of `ellip::compare`: `n` points on
/// each mesh (at fixed barycentric spots of evenly strided faces, weighted by face area)
/// against every triangle of the other.
fn brute_force_rms(a: &Mesh, b: &Mesh, n: usize) -> f64 {
    fn closest_on_triangle(p: DVec3, t: [DVec3; 3]) -> f64 {
        // Distance to the plane when the projection falls inside, else to the edges.
        let [a, b, c] = t;
        let n = (b - a).cross(c - a);
        let area2 = n.length();
        if area2 > 0.0 {
            let nn = n / area2;
            let q = p - nn * (p - a).dot(nn);
            let inside = [(a, b), (b, c), (c, a)]
                .iter()
                .all(|&(u, v)| (v - u).cross(q - u).dot(nn) >= 0.0);
            if inside {
                return (p - q).length();
            }
        }
        [(a, b), (b, c), (c, a)]
            .iter()
            .map(|&(u, v)| distance_to_segment(p, u, v))
            .fold(f64::INFINITY, f64::min)
    }
    let one_way = |from: &Mesh, to: &Mesh| {
        let faces = from.face_count();
        let stride = (faces / n).max(1);
        let (mut sum, mut weight) = (0.0, 0.0);
        for f in (0..faces).step_by(stride) {
            let [x, y, z] = from.corners(f);
            let area = from.face_area(f);
            for (u, v) in [(1.0 / 3.0, 1.0 / 3.0), (0.6, 0.2), (0.2, 0.6), (0.2, 0.2)] {
                let p = x * u + y * v + z * (1.0 - u - v);
                let d = (0..to.face_count())
                    .map(|g| closest_on_triangle(p, to.corners(g)))
                    .fold(f64::INFINITY, f64::min);
                sum += area * d * d;
                weight += area;
            }
        }
        (sum / weight).sqrt()
    };
    one_way(a, b).max(one_way(b, a))
}

#[test]
fn rate_control_meets_an_error_target_and_a_byte_budget() {
    use ellip::encode::{encode_to_target, Target};
    use ellip::remesh::{remesh, RemeshOptions};
    let mesh = blob("blob2");
    let diagonal = mesh.bounding_box().unwrap().diagonal();
    let target = 0.003;
    let rc = encode_to_target(&mesh, &settings(4), Target::Rms(target), &mut |_| {}).unwrap();
    let stored = decode(&rc.bytes, &Limits::default()).unwrap();
    assert_eq!(stored.metadata.measured_error, Some(rc.measured.rms));
    assert!(rc.measured.rms <= target * diagonal);
    // Checked independently: brute force on about 500 faces a side (sampling error a few %).
    let decoded = remesh(&stored, &RemeshOptions::default()).unwrap().mesh;
    let independent = brute_force_rms(&mesh, &decoded, 500) / diagonal;
    println!(
        "RMS target {target}: K = {}, {} bytes, measured {:.5}, brute force {independent:.5}",
        rc.encoded.segmentation.region_count(),
        rc.bytes.len(),
        rc.measured.rms / diagonal
    );
    assert!(independent <= target * 1.1, "{independent}");
    // Every smaller file tried that decodes clean missed the target (one with faults may
    // not be kept, however small).
    assert_eq!(rc.encoded.verification.problem, None);
    for p in rc.probes.iter().filter(|p| p.clean) {
        if p.bytes < rc.bytes.len() {
            assert!(p.rms > target, "{p:?}");
        }
    }

    for budget in [600, 900] {
        let rc =
            encode_to_target(&mesh, &settings(4), Target::MaxBytes(budget), &mut |_| {}).unwrap();
        assert!(rc.bytes.len() <= budget, "{} > {budget}", rc.bytes.len());
        let stored = decode(&rc.bytes, &Limits::default()).unwrap();
        assert!(stored.metadata.measured_hausdorff.is_some());
        // The smallest K that no longer fits was tried with coarser boundaries (a file with
        // more regions may fit that way).
        let default = settings(4).simplify_tolerance;
        if let Some(flip) = rc
            .probes
            .iter()
            .filter(|p| p.boundary_tolerance == default && p.bytes > budget)
            .map(|p| p.regions)
            .min()
        {
            let factors = if flip == 1 { [4.0, 16.0] } else { [2.0, 4.0] };
            for factor in factors {
                assert!(
                    rc.probes
                        .iter()
                        .any(|p| p.regions == flip && p.boundary_tolerance == default * factor),
                    "K = {flip} at {factor}x the boundary tolerance not tried: {:?}",
                    rc.probes
                );
            }
        }
        // No probe that fitted and decodes clean had a lower error.
        for p in rc.probes.iter().filter(|p| p.clean) {
            if p.bytes <= budget {
                // Probes store the error as a fraction of the diagonal: equal up to rounding.
                assert!(
                    p.rms * diagonal >= rc.measured.rms * (1.0 - 1e-12),
                    "{p:?} kept {} bytes",
                    rc.bytes.len()
                );
            }
        }
    }
    // A budget nothing fits is an error, not an overrun.
    assert!(encode_to_target(&mesh, &settings(4), Target::MaxBytes(100), &mut |_| {}).is_err());
}

/// Rate control keeps a file that decodes clean: the horse in 1 500 bytes was kept at
/// K = 6 with 4× the boundary tolerance, 1.50 % of the diagonal and not manifold (the
/// plain K = 5 file missed at 3.51 %). Each probe that is not clean now gets the
/// area-weighted search too (clean at K = 5 and 4×, 1 327 bytes, 0.97 %), and the best
/// probe that meets the target, when not clean, the rest of encode_mesh's searches. The
/// file kept fits, decodes clean as a reader decodes it and has the lowest error of the
/// clean probes that fit. In 1 400 bytes (since the check measures regions off the source
/// in RMS too, every probe at 1 500 is clean), the probes at K = 2, 3 and 4 decode with
/// faults. Skipped without `../shared/meshes`.
#[test]
fn rate_control_keeps_a_file_that_decodes_clean() {
    use ellip::encode::{encode_to_target, Target};
    let Some(mesh) = common::shared_mesh("horse") else {
        return;
    };
    let budget = 1400;
    let rc = encode_to_target(
        &mesh,
        &EncodeSettings::default(),
        Target::MaxBytes(budget),
        &mut |_| {},
    )
    .unwrap();
    assert!(rc.bytes.len() <= budget);
    assert_eq!(rc.encoded.verification.problem, None);
    let check = decoded_check(&rc.bytes);
    assert!(check.is_clean(), "{check:?}");
    assert!(
        rc.probes.iter().any(|p| !p.clean),
        "no probe decodes with faults: {:?}",
        rc.probes
    );
    let diagonal = mesh.bounding_box().unwrap().diagonal();
    for p in rc.probes.iter().filter(|p| p.clean && p.bytes <= budget) {
        assert!(p.rms * diagonal >= rc.measured.rms * (1.0 - 1e-12), "{p:?}");
    }
}

/// Decodes `bytes` as a reader would and returns the remeshed check.
fn decoded_check(bytes: &[u8]) -> ellip::remesh::assemble::MeshCheck {
    let rep = decode(bytes, &Limits::default()).unwrap();
    ellip::remesh::remesh(&rep, &ellip::remesh::RemeshOptions::default())
        .unwrap()
        .check
}

/// Asserts that a decoded mesh has no flipped or degenerate triangle and leaves out no
/// region (for meshes with open pieces, which [`MeshCheck::is_clean`] would not call clean).
///
/// [`MeshCheck::is_clean`]: ellip::remesh::assemble::MeshCheck::is_clean
fn assert_whole_and_unturned(c: &ellip::remesh::assemble::MeshCheck) {
    assert_eq!(
        (c.flipped, c.degenerate, c.omitted_regions),
        (0, 0, 0),
        "{c:?}"
    );
}

#[test]
fn the_encoder_checks_its_file_against_the_decoder() {
    let mesh = blob("blob2");
    let encoded = encode_mesh(&mesh, &settings(4), &mut |_| {}).unwrap();
    let v = &encoded.verification;
    assert_eq!(v.requested_regions, 4);
    assert_eq!((v.rounds, v.problem.as_deref()), (0, None));
    assert_eq!(encoded.representation.region_count(), 4);
    assert!(decoded_check(&encoded.bytes).is_clean());
    // Without the check: the same file (this one needed no split).
    let unchecked = EncodeSettings {
        verify: false,
        ..settings(4)
    };
    assert_eq!(
        encode_mesh(&mesh, &unchecked, &mut |_| {}).unwrap().bytes,
        encoded.bytes
    );
}

/// The thread count (`SegmentOptions::threads`, `--threads`) bounds the segmentation and
/// the decoder check alike, and changes no byte of the file: one, three and all cores give
/// the same file (blob3 at K = 6, whose check measures every region against the source in
/// parallel).
#[test]
fn the_file_does_not_depend_on_the_thread_count() {
    let mesh = blob("blob3");
    let with_threads = |threads: Option<usize>| {
        let mut s = settings(6);
        s.segment.threads = threads;
        encode_mesh(&mesh, &s, &mut |_| {}).unwrap().bytes
    };
    let all = with_threads(None);
    for threads in [1, 3] {
        assert_eq!(with_threads(Some(threads)), all, "{threads} threads");
    }
}

/// Real meshes whose K = 12 segmentation has regions the decoder cannot mesh (their
/// boundaries fold in their charts, or their triangles flip): the encoder splits them, and
/// the file it writes decodes clean; a file that decodes clean as it is is not mended.
/// fandisk's plain file has 2 flipped triangles; penguin's decodes clean (and so does
/// horse's, the other mesh here before, since faces left turned lose their interior
/// corners; its file is still mended, for regions far from the source).
#[test]
fn real_meshes_with_unchartable_regions_are_split_until_they_decode_clean() {
    for name in ["penguin", "fandisk"] {
        let Some(mesh) = common::shared_mesh(name) else {
            return;
        };
        let unchecked = EncodeSettings {
            verify: false,
            ..settings(12)
        };
        let plain = encode_mesh(&mesh, &unchecked, &mut |_| {}).unwrap();
        let rep = decode(&plain.bytes, &Limits::default()).unwrap();
        let options = ellip::remesh::RemeshOptions::default();
        let plain = ellip::remesh::remesh(&rep, &options);
        let plain_clean = plain.as_ref().is_ok_and(|r| r.check.is_clean());
        if plain.as_ref().map_or(true, |r| !r.omitted.is_empty()) {
            // The decoder's first attempt fails somewhere, and region_faults says where.
            let faults = ellip::remesh::assemble::region_faults(
                &rep,
                &options,
                &ellip::remesh::ChartMemo::default(),
            )
            .unwrap();
            assert!(!faults.is_empty(), "{name}");
            // Folds name two loop edges apart in space that cross in the chart.
            for f in faults.iter().filter_map(|f| f.crossing) {
                assert!(f.iter().flatten().all(|p| p.is_finite()), "{name}");
            }
        }
        let encoded = encode_mesh(&mesh, &settings(12), &mut |_| {}).unwrap();
        let v = &encoded.verification;
        assert_eq!(v.problem, None, "{name}");
        assert!(decoded_check(&encoded.bytes).is_clean(), "{name}");
        if plain_clean {
            assert_eq!(v.rounds, 0, "{name}");
        } else {
            assert!(v.rounds >= 1, "{name}");
            assert!(encoded.representation.region_count() > 12, "{name}");
        }
    }
}

/// A region decoded far from its source where its ellipsoid is not is mended like one that
/// does not mesh cleanly. dino at K = 12 fitted a front leg with an ellipsoid (radii
/// 0.031 × 0.042 × 0.45 of a model 1.41 across) that runs far past the foot; the region's
/// only boundary loop is at the top of the leg, so it decoded as all of the ellipsoid below
/// that loop: a spike through the floor, 30.7 % of the diagonal from the source (RMS
/// 4.4 %), although the file decoded clean. Mended (the leg split, then the tail, which its
/// split left meshed on the wrong part of its ellipsoid), the file is 6.3 % from it (RMS
/// 0.87 %).
#[test]
fn regions_decoded_off_their_source_are_mended() {
    let Some(mesh) = common::shared_mesh("dino") else {
        return;
    };
    let encoded = encode_mesh(&mesh, &settings(12), &mut |_| {}).unwrap();
    assert_eq!(encoded.verification.problem, None);
    assert!(encoded.verification.rounds >= 1);
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    let out = ellip::remesh::remesh(&rep, &ellip::remesh::RemeshOptions::default()).unwrap();
    assert!(out.check.is_sound_from(false), "{:?}", out.check);
    let options = ellip::compare::CompareOptions {
        samples: 20_000,
        ..Default::default()
    };
    let c = ellip::compare::compare_meshes(&mesh, &out.mesh, &options).unwrap();
    let relative = c.symmetric.distances.hausdorff / c.diagonal;
    assert!(relative < 0.1, "Hausdorff {relative}");
}

/// A file that the decoder's first treatment does not mesh clean names the one that does
/// (its remesh hint), and decoders mesh it once, into the same mesh as the search without
/// the hint makes, at budgets other than the check's too: horse at K = 20, which names the
/// stored arcs, narrow ears pruned, untangled, rays from the centres (code 17). (The file
/// of this test until the pole's test measured long edges along their arcs, horse at K = 20
/// in volume mode, now meshes clean with the first treatment.)
#[test]
fn a_file_names_the_treatment_that_meshes_it_clean() {
    use ellip::remesh::assemble::Treatment;
    use ellip::remesh::{remesh, RemeshOptions};
    let Some(mesh) = common::shared_mesh("horse") else {
        return;
    };
    let encoded = encode_mesh(&mesh, &settings(20), &mut |_| {}).unwrap();
    assert_eq!(encoded.verification.problem, None);
    let summary = inspect(&encoded.bytes, &Limits::default()).unwrap();
    let hint = summary.metadata.remesh_hint.expect("a remesh hint");
    let treatment = Treatment::from_code(hint).expect("a treatment this decoder knows");
    assert_ne!(treatment, Treatment::FIRST);
    assert_eq!(summary.minor, 1);
    let hinted = decode(&encoded.bytes, &Limits::default()).unwrap();
    let mut unhinted = hinted.clone();
    unhinted.metadata.remesh_hint = None;
    for vertices in [5_000, 50_000] {
        let options = RemeshOptions {
            vertices: Some(vertices),
            ..RemeshOptions::default()
        };
        let once = remesh(&hinted, &options).unwrap();
        let searched = remesh(&unhinted, &options).unwrap();
        assert!(once.check.is_clean(), "{vertices}: {:?}", once.check);
        assert_eq!(once.attempts, 1, "{vertices}");
        assert!(searched.attempts > 1, "{vertices}");
        assert_eq!(once.treatment, Some(treatment));
        assert_eq!(searched.treatment, Some(treatment));
        assert!(once.mesh.positions() == searched.mesh.positions());
        assert!(once.mesh.faces() == searched.mesh.faces());
    }
}

/// Where the source has creases, the fitted ellipsoids meet off them, and the arcs as
/// stored follow them better than arcs refined onto the ellipsoids' intersection curves: a
/// file the decoder's first treatment meshes clean names the later one whose mesh is closer
/// to the source. A cube of 8 × 8 squares a side at K = 6, one flat ellipsoid a face:
/// 2.09 % of the diagonal RMS with the first treatment, 1.64 % with the stored arcs, no ear
/// pruned (the last release named no treatment).
#[test]
fn a_creased_source_names_the_treatment_that_meshes_it_closest() {
    use ellip::compare::{compare_meshes, CompareOptions};
    use ellip::remesh::assemble::Treatment;
    use ellip::remesh::{remesh, RemeshOptions};
    let cube = ellip::synth::shapes::cube(1.0, 8);
    let encoded = encode_mesh(&cube, &settings(6), &mut |_| {}).unwrap();
    assert_eq!(encoded.verification.problem, None);
    let named = decode(&encoded.bytes, &Limits::default()).unwrap();
    let hint = named.metadata.remesh_hint.expect("a remesh hint");
    let treatment = Treatment::from_code(hint).expect("a treatment this decoder knows");
    assert!(!treatment.refined, "{treatment}");
    let mut first = named.clone();
    first.metadata.remesh_hint = Some(Treatment::FIRST.code());
    let rms = |rep: &ellip::representation::Representation, expected: Treatment| {
        let out = remesh(rep, &RemeshOptions::default()).unwrap();
        assert!(out.check.is_clean(), "{expected}: {}", out.check.faults());
        assert_eq!(out.treatment, Some(expected));
        let c = compare_meshes(&cube, &out.mesh, &CompareOptions::default()).unwrap();
        c.symmetric.distances.rms / c.diagonal
    };
    let (named_rms, first_rms) = (rms(&named, treatment), rms(&first, Treatment::FIRST));
    assert!(
        named_rms < 0.9 * first_rms,
        "named {named_rms}, first {first_rms}"
    );
}

/// Where splitting cannot make a file decode clean, the encoder still prefers a file that
/// decodes whole (with a few faulty triangles) to one the decoder refuses or meshes only
/// unsound: dino at K = 8 unmended has a region whose loops cross in every attempt (one of
/// them encloses nothing, which kept it from being untangled); the decoder's last resort,
/// which leaves out the regions that fail, untangles it without that loop, and the file
/// decodes whole but not consistently oriented (with the region left out, before). The
/// encoding kept decodes whole and sound.
#[test]
fn a_file_that_decodes_is_kept_over_one_that_does_not() {
    let Some(mesh) = common::shared_mesh("dino") else {
        return;
    };
    let source_manifold = mesh.topology().is_manifold();
    let options = ellip::remesh::RemeshOptions::default();
    let unchecked = EncodeSettings {
        verify: false,
        ..settings(8)
    };
    let plain = encode_mesh(&mesh, &unchecked, &mut |_| {}).unwrap();
    let rep = decode(&plain.bytes, &Limits::default()).unwrap();
    let plain = ellip::remesh::remesh(&rep, &options);
    assert!(plain.map_or(true, |out| !out.check.is_sound_from(source_manifold)));
    let encoded = encode_mesh(&mesh, &settings(8), &mut |_| {}).unwrap();
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    let out = ellip::remesh::remesh(&rep, &options).expect("the kept file decodes");
    assert_eq!(out.check.omitted_regions, 0);
    let v = &encoded.verification;
    assert!(v.rounds >= 1);
    // The file kept comes from mending at the requested count, not from a fallback.
    assert_eq!((v.raised_regions, v.area_weighted), (None, false), "{v:?}");
    // Whatever is left is said, judged as the encoder judges: dino has two pinched edges,
    // and its files need not be more manifold than it.
    assert!(!source_manifold);
    assert_eq!(
        v.problem.is_none(),
        out.check.is_clean_from(source_manifold),
        "{:?} {:?}",
        v.problem,
        out.check
    );
    assert!(out.check.is_sound_from(source_manifold), "{:?}", out.check);
}

/// When no mending makes the file at the requested region count decode clean, the encoder
/// segments again weighting faces by area, then with half as many regions more. armadillo
/// at K = 12 has regions that fold over their ellipsoids however they are split: no round
/// of mending its plain segmentation gives a file that decodes. Until the first meshing
/// attempt pruned only narrow double ears (`refine::Prune::Narrow`), weighting by area did
/// not help either and the count was raised to 18 (20 regions, 2 359 bytes); now the
/// weighted segmentation, mended, decodes clean (27 regions, 3 155 bytes) and is kept.
#[test]
fn when_no_file_at_the_requested_count_decodes_clean_the_encoder_falls_back() {
    let Some(mesh) = common::shared_mesh("armadillo") else {
        return;
    };
    let encoded = encode_mesh(&mesh, &settings(12), &mut |_| {}).unwrap();
    let v = &encoded.verification;
    assert_eq!(v.requested_regions, 12);
    // One fallback made the file kept: weighting by area or, failing that, more regions.
    assert!(v.area_weighted != v.raised_regions.is_some(), "{v:?}");
    assert!(encoded.representation.region_count() > 12);
    let check = decoded_check(&encoded.bytes);
    assert!(check.is_clean(), "{check:?}");
    assert_eq!(v.problem, None);
}

/// A sphere with specks, as a scan has them: fins (one triangle on an edge of the sphere,
/// which makes the edge non-manifold and the fin a piece of its own) wound either way, and
/// loose triangles. Returns the mesh and the specks' vertices.
fn sphere_with_specks() -> (Mesh, Vec<DVec3>) {
    let sphere = ellip::synth::shapes::icosphere(1.0, 3);
    let mut positions = sphere.positions().to_vec();
    let mut faces = sphere.faces().to_vec();
    let mut speck_points = Vec::new();
    let count = faces.len();
    for k in 0..6 {
        let [a, b, _] = faces[k * 211 % count];
        let mid = 0.5 * (positions[a as usize] + positions[b as usize]);
        let apex = mid + 0.15 * mid.normalize() + 0.05 * DVec3::new(1.0, 0.5, -0.3);
        positions.push(apex);
        let v = positions.len() as u32 - 1;
        faces.push(if k % 2 == 0 { [a, b, v] } else { [b, a, v] });
        speck_points.extend([positions[a as usize], positions[b as usize], apex]);
    }
    for corners in [
        [
            DVec3::new(1.6, 0.0, 0.0),
            DVec3::new(1.7, 0.05, 0.0),
            DVec3::new(1.62, 0.1, 0.04),
        ],
        [
            DVec3::new(0.0, -1.5, 0.2),
            DVec3::new(0.0, -1.52, 0.3),
            DVec3::new(0.08, -1.55, 0.25),
        ],
    ] {
        let first = positions.len() as u32;
        positions.extend(corners);
        faces.push([first, first + 1, first + 2]);
        speck_points.extend(corners);
    }
    // Two triangles folded along their shared edge, open and not flat: a piece of Stanford's
    // dragon at `res3` (its corners, moved and scaled 20 times).
    let first = positions.len() as u32;
    let folded = [
        [-0.0878745, 0.0601804, -0.0207355],
        [-0.0880203, 0.0585681, -0.0207129],
        [-0.0871673, 0.0600944, -0.0220295],
        [-0.0858736, 0.0603059, -0.0224792],
    ]
    .map(|p| {
        DVec3::new(0.0, 0.0, 1.6) + 20.0 * (DVec3::from_array(p) - DVec3::new(-0.087, 0.06, -0.021))
    });
    positions.extend(folded);
    faces.extend([[first, first + 1, first + 2], [first, first + 2, first + 3]]);
    speck_points.extend(folded);
    (Mesh::new(positions, faces).unwrap(), speck_points)
}

/// Specks (pieces with fewer vertices than an ellipsoid has parameters, flat or open) are
/// fitted with spheres tangent to them and stored as the mesh has them: they decode where
/// they were, none turned over, even without the encoder's check. (Stanford's dragon at
/// `res4` has 351 one-triangle pieces; fitted with ellipsoids and smoothed, 38 of them
/// decoded flipped.)
#[test]
fn specks_decode_where_they_were_and_unflipped() {
    let (mesh, speck_points) = sphere_with_specks();
    let specks = ellip::segment::proxy::speck_faces(&mesh);
    assert_eq!(specks.iter().filter(|&&s| s).count(), 10);
    assert!(specks[..1280].iter().all(|&s| !s));
    let settings = EncodeSettings {
        verify: false,
        segment: SegmentOptions::default(),
        ..EncodeSettings::default()
    };
    let encoded = encode_mesh(&mesh, &settings, &mut |_| {}).unwrap();
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    let out = ellip::remesh::remesh(&rep, &ellip::remesh::RemeshOptions::default()).unwrap();
    assert_whole_and_unturned(&out.check);
    // The folded pair's analytic normals face its own way (the normal of its corners on a
    // needle through them points anywhere).
    let folded = &speck_points[speck_points.len() - 4..];
    let facing = (folded[1] - folded[0]).cross(folded[2] - folded[0])
        + (folded[2] - folded[0]).cross(folded[3] - folded[0]);
    for &p in folded {
        let (nearest, _) = out
            .mesh
            .positions()
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.distance(p).total_cmp(&b.1.distance(p)))
            .unwrap();
        let along = out.normals[nearest].dot(facing.normalize());
        assert!(along > 0.5, "{p}: normal {along} along the pair's own");
    }
    // Every speck's corner is a decoded vertex (to within the grid: 12 bits or more over a
    // box 3.3 across).
    for p in speck_points {
        let nearest = out
            .mesh
            .positions()
            .iter()
            .map(|q| q.distance(p))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 2e-3, "{p}: nearest decoded vertex {nearest} away");
    }
}

/// A speck thinner than the point grid's step can come out of the grid turned over: the
/// dragon from npm at `res3` has pairs of triangles on the same three points wound either
/// way, slivers a grid step high, and quantised, 8 of its 11 flipped triangles were such
/// specks turned against the spheres fitted to their source triangles. Here a sliver whose
/// grid positions wind the other way (in grid steps: (0, 0.45), (4, 1.55), (2.6, 1.3) round
/// to (0, 0), (4, 2), (3, 1)) beside a sphere, on a 10-bit grid the two corner specks fix:
/// stored, its sphere has the other sign, and it decodes unflipped.
#[test]
fn a_speck_the_grid_turns_over_decodes_unflipped() {
    let sphere = ellip::synth::shapes::icosphere(1.0, 3);
    let mut positions = sphere.positions().to_vec();
    let mut faces = sphere.faces().to_vec();
    let step = 4.0 / 1023.0;
    let at = |x: f64, y: f64| DVec3::new(-2.0 + (600.0 + x) * step, -2.0 + (700.0 + y) * step, 1.5);
    for corners in [
        [
            DVec3::splat(-2.0),
            DVec3::new(-1.9, -2.0, -2.0),
            DVec3::new(-2.0, -1.9, -2.0),
        ],
        [
            DVec3::splat(2.0),
            DVec3::new(2.0, 1.9, 2.0),
            DVec3::new(1.9, 2.0, 2.0),
        ],
        [at(0.0, 0.45), at(4.0, 1.55), at(2.6, 1.3)],
    ] {
        let first = positions.len() as u32;
        positions.extend(corners);
        faces.push([first, first + 1, first + 2]);
    }
    let mesh = Mesh::new(positions, faces).unwrap();
    let specks = ellip::segment::proxy::speck_faces(&mesh);
    assert_eq!(specks.iter().filter(|&&s| s).count(), 3);
    let settings = EncodeSettings {
        verify: false,
        bits: Some(10),
        ..EncodeSettings::default()
    };
    let encoded = encode_mesh(&mesh, &settings, &mut |_| {}).unwrap();
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    // The sliver's stored corners wind the other way round +z.
    let stored = |p: DVec3| {
        rep.points
            .iter()
            .copied()
            .min_by(|a, b| a.distance(p).total_cmp(&b.distance(p)))
            .unwrap()
    };
    let [a, b, c] = [at(0.0, 0.45), at(4.0, 1.55), at(2.6, 1.3)].map(stored);
    assert!(a.distance(at(0.0, 0.45)) < step, "{a}");
    assert!((b - a).cross(c - a).z < 0.0, "{a} {b} {c}");
    let out = ellip::remesh::remesh(&rep, &ellip::remesh::RemeshOptions::default()).unwrap();
    assert_whole_and_unturned(&out.check);
}

/// A cube, the first mesh many people try: each of its twelve triangles a region on the
/// sphere through the corners (the corners' averaged normals are the sphere's), every
/// boundary an arc of one edge between two corners. Boundary smoothing pulled each corner
/// toward its neighbours (the spheres, all one, held nothing in place): the file stored
/// them 11–12 % of the diagonal inside the cube, and it decoded 16–28 % RMS off; and at its
/// 8 vertices the decoder refined two arcs onto that sphere (10 vertices, 21 % off). The
/// corners are now stored where the mesh has them (within the boundary tolerance), and at
/// its source density the cube decodes as itself: its 8 corners and 12 triangles. At any
/// other density it decoded as the twelve sphere caps it was fitted with (9.8, 13.5 and
/// 13.8 % of the diagonal RMS at 100, 1 000 and 10 000 vertices); measured with the normals
/// of their own side of the cube's edges, its triangles are fitted with their planes
/// (`mesh::crease`, `fit_tangent_sphere`), and it decodes as itself at every density.
#[test]
fn a_cube_decodes_as_itself() {
    let cube = ellip::synth::shapes::cube(1.0, 1);
    let diagonal = 3f64.sqrt();
    let encoded = encode_mesh(&cube, &EncodeSettings::default(), &mut |_| {}).unwrap();
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    let nearest = |points: &[DVec3], p: DVec3| {
        points
            .iter()
            .map(|q| q.distance(p))
            .fold(f64::INFINITY, f64::min)
    };
    assert_eq!(rep.points.len(), 8);
    for &p in &rep.points {
        // The boundary tolerance (10⁻³ of the diagonal) bounds each stored point's error.
        let d = nearest(cube.positions(), p);
        assert!(
            d <= 1e-3 * diagonal,
            "stored point {p} is {d} from every corner"
        );
    }
    let out = ellip::remesh::remesh(&rep, &ellip::remesh::RemeshOptions::default()).unwrap();
    assert!(out.check.is_clean(), "{}", out.check.faults());
    for &c in cube.positions() {
        let d = nearest(out.mesh.positions(), c);
        assert!(
            d <= 1e-3 * diagonal,
            "corner {c} is {d} from the decoded mesh"
        );
    }
    assert_eq!((out.mesh.vertex_count(), out.mesh.face_count()), (8, 12));
    let rms = brute_force_rms(&cube, &out.mesh, 12);
    assert!(rms <= 1e-3 * diagonal, "RMS {rms}");
    for vertices in [100, 1_000, 10_000] {
        let options = ellip::remesh::RemeshOptions {
            vertices: Some(vertices),
            ..Default::default()
        };
        let out = ellip::remesh::remesh(&rep, &options).unwrap();
        assert!(out.check.is_clean(), "{vertices}: {}", out.check.faults());
        let rms = brute_force_rms(&cube, &out.mesh, 200);
        assert!(rms <= 1e-5 * diagonal, "{vertices} vertices: RMS {rms}");
    }
}

/// A closed piece too small for its vertices to determine an ellipsoid, one region whole,
/// is decoded as its whole ellipsoid: the one of its solid (`ellipsoid::fit::fit_solid`,
/// radii 1.24 times the half-extents of a box), not what its eight corners leave free. Even
/// without the encoder's check. Fitted to its corners, each box was decoded as a sphere up
/// to twice the size of the whole mesh: 336 % of the diagonal RMS from the source at 2 000
/// vertices, 0.72 % now.
#[test]
fn small_closed_pieces_decode_as_the_ellipsoids_of_their_solids() {
    let (mesh, boxes) = common::three_boxes();
    let settings = EncodeSettings {
        verify: false,
        ..settings(3)
    };
    let encoded = encode_mesh(&mesh, &settings, &mut |_| {}).unwrap();
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    assert_eq!(rep.ellipsoids.len(), 3);
    assert!(rep.cycles.iter().all(Vec::is_empty), "whole regions");
    for e in &rep.ellipsoids {
        let (half, centre) = boxes
            .iter()
            .copied()
            .min_by(|a, b| a.1.distance(e.center).total_cmp(&b.1.distance(e.center)))
            .unwrap();
        let mut radii = e.radii.to_array();
        radii.sort_by(f64::total_cmp);
        let mut expected = (1.2407 * half).to_array();
        expected.sort_by(f64::total_cmp);
        // The file stores radii to a few parts in a thousand.
        for (r, x) in radii.iter().zip(expected) {
            assert!((r - x).abs() < 0.01 * x + 1e-3, "{radii:?} for {half}");
        }
        assert!(e.center.distance(centre) < 0.5, "{e:?}");
    }
    let options = ellip::remesh::RemeshOptions {
        vertices: Some(2_000),
        ..Default::default()
    };
    let out = ellip::remesh::remesh(&rep, &options).unwrap();
    let diagonal = mesh.bounding_box().unwrap().diagonal();
    let rms = brute_force_rms(&mesh, &out.mesh, 400) / diagonal;
    assert!(rms < 0.01, "RMS {:.3} % of the diagonal", 100.0 * rms);
}
