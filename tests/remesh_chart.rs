//! Region charts and the analytic ray query (issue 6, item 1; Simari & Singh 2005, section
//! 5.1) on the real decode path: fixture blobs encoded with as many regions as they have
//! ellipsoids, `.ellip` bytes decoded (quantised boundary points), charts built from the
//! decoded cycles, compared against the source mesh and its segmentation.

use ellip::compare::distance_to_segment;
use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, Limits};
use ellip::import::{read_mesh, ImportOptions};
use ellip::remesh::query::{region_loop_points, RayQuery};
use ellip::remesh::RemeshError;
use ellip::representation::Representation;
use ellip::rng::SplitMix64;
use ellip::segment::{RegionCount, SegmentOptions};
use ellip::Mesh;
use glam::DVec3;

mod common;

/// A fixture blob, its segmentation labels and its decoded representation.
struct Encoded {
    mesh: Mesh,
    labels: Vec<u32>,
    rep: Representation,
    diagonal: f64,
}

fn encode_blob(name: &str, regions: usize) -> Encoded {
    let path = format!("{}/fixtures/meshes/{name}.obj", env!("CARGO_MANIFEST_DIR"));
    let mesh = read_mesh(path.as_ref(), &ImportOptions::default())
        .unwrap()
        .mesh;
    let settings = EncodeSettings {
        segment: SegmentOptions {
            regions: RegionCount::Fixed(regions),
            ..SegmentOptions::default()
        },
        ..EncodeSettings::default()
    };
    let encoded = encode_mesh(&mesh, &settings, &mut |_| {}).unwrap();
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    assert_eq!(rep.region_count(), regions);
    let diagonal = mesh.bounding_box().unwrap().diagonal();
    Encoded {
        mesh,
        labels: encoded.segmentation.labels,
        rep,
        diagonal,
    }
}

/// Every boundary segment of every region's loops.
fn boundary_segments(rep: &Representation) -> Vec<(DVec3, DVec3)> {
    let mut out = Vec::new();
    for r in 0..rep.region_count() as u32 {
        for l in region_loop_points(rep, r) {
            for (i, &a) in l.iter().enumerate() {
                out.push((a, l[(i + 1) % l.len()]));
            }
        }
    }
    out
}

/// Möller–Trumbore: the smallest t > 0 where the ray meets a source triangle, and that face.
fn brute_force_hit(mesh: &Mesh, origin: DVec3, direction: DVec3) -> Option<(f64, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for f in 0..mesh.face_count() {
        let [a, b, c] = mesh.corners(f);
        let (e1, e2) = (b - a, c - a);
        let p = direction.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-15 {
            continue;
        }
        let s = origin - a;
        let u = s.dot(p) / det;
        if !(0.0..=1.0).contains(&u) {
            continue;
        }
        let q = s.cross(e1);
        let v = direction.dot(q) / det;
        if v < 0.0 || u + v > 1.0 {
            continue;
        }
        let t = e2.dot(q) / det;
        if t > 0.0 && best.is_none_or(|(bt, _)| t < bt) {
            best = Some((t, f));
        }
    }
    best
}

/// Faces whose centroid is farther than 2% of the diagonal from every boundary segment: the
/// chart of the face's label contains the centroid for ≥ 99% of them, and another region's
/// chart claims it on the same side (contains it, and its ellipsoid passes within 2% of the
/// diagonal of it) for ≤ 1%.
#[test]
fn charts_contain_their_regions_faces() {
    for (name, k) in [("blob1", 3), ("blob2", 4)] {
        let blob = encode_blob(name, k);
        let query = RayQuery::new(&blob.rep).unwrap();
        let charts = query.charts();
        for c in charts {
            assert!(c.clearance() > 0.1, "{name}: pole too near the boundary");
        }
        let segments = boundary_segments(&blob.rep);
        let band = 0.02 * blob.diagonal;
        let (mut checked, mut own, mut other) = (0usize, 0usize, 0usize);
        for f in 0..blob.mesh.face_count() {
            let c = blob.mesh.face_centroid(f);
            if segments
                .iter()
                .any(|&(a, b)| distance_to_segment(c, a, b) < band)
            {
                continue;
            }
            checked += 1;
            let label = blob.labels[f] as usize;
            own += usize::from(charts[label].contains(c));
            other += usize::from(charts.iter().enumerate().any(|(j, chart)| {
                j != label && chart.contains(c) && chart.ellipsoid.radial_distance(c) < band
            }));
        }
        let own_rate = own as f64 / checked as f64;
        let other_rate = other as f64 / checked as f64;
        eprintln!(
            "{name}: {checked} of {} faces away from boundaries; own chart contains {:.2}%, \
             another chart claims {:.2}%",
            blob.mesh.face_count(),
            100.0 * own_rate,
            100.0 * other_rate
        );
        assert!(checked > blob.mesh.face_count() / 2, "{name}: {checked}");
        assert!(own_rate >= 0.99, "{name}: {own_rate}");
        assert!(other_rate <= 0.01, "{name}: {other_rate}");
    }
}

/// Ray statistics against the source mesh: fractions of rays whose hit distance is within 1%
/// and 5% of the diagonal, whose region matches the source face's label, and the worst
/// distance error in diagonals. A ray both miss counts as agreeing.
fn compare_rays(mesh: &Mesh, labels: &[u32], query: &RayQuery, rays: usize) -> [f64; 4] {
    let bbox = mesh.bounding_box().unwrap();
    let diagonal = bbox.diagonal();
    let mut rng = SplitMix64::new(31);
    let (mut close, mut near, mut same_region, mut worst) = (0usize, 0usize, 0usize, 0.0f64);
    for _ in 0..rays {
        let u = rng.unit_vector();
        let jitter = DVec3::new(
            rng.range_f64(-0.1, 0.1),
            rng.range_f64(-0.1, 0.1),
            rng.range_f64(-0.1, 0.1),
        ) * bbox.size();
        let origin = bbox.center() + u * diagonal;
        let direction = (bbox.center() + jitter - origin).normalize();
        let analytic = query.first_hit(origin, direction);
        let brute = brute_force_hit(mesh, origin, direction);
        match (analytic, brute) {
            (Some(h), Some((t, f))) => {
                let error = (h.t - t).abs();
                worst = worst.max(error);
                close += usize::from(error <= 0.01 * diagonal);
                near += usize::from(error <= 0.05 * diagonal);
                same_region += usize::from(h.region == labels[f]);
                assert!((h.normal.length() - 1.0).abs() < 1e-9);
            }
            (None, None) => {
                close += 1;
                near += 1;
                same_region += 1;
            }
            _ => worst = f64::INFINITY,
        }
    }
    let rate = |n: usize| n as f64 / rays as f64;
    [rate(close), rate(near), rate(same_region), worst / diagonal]
}

/// 2000 rays from outside (one diagonal from the box centre) towards the centre (jittered
/// by up to 10% of the box size): the analytic first hit agrees with a brute-force
/// intersection against the source mesh within 1% of the diagonal for ≥ 98% of the rays and
/// within 5% for ≥ 99.5%, and the region hit equals the segmentation label of the source face
/// hit for ≥ 95%.
///
/// Measured (blob1, blob2): 98.65% and 98.20% within 1%; the misses are grazing rays near
/// boundaries, where the ellipsoid fit's radial error (≤ 1.5% of the diagonal there) is
/// stretched along the ray, and one or two rays that slip between two regions' boundary
/// curves (each region's boundary is its own radial projection, so the curves do not meet
/// exactly). That is the representation's accuracy, not the query's: the unit tests in
/// `remesh::query` check the query exactly.
#[test]
fn ray_query_matches_brute_force_on_the_source() {
    for (name, k) in [("blob1", 3), ("blob2", 4)] {
        let blob = encode_blob(name, k);
        let query = RayQuery::new(&blob.rep).unwrap();
        let rays = 2000;
        let [close_rate, near_rate, region_rate, worst] =
            compare_rays(&blob.mesh, &blob.labels, &query, rays);
        eprintln!(
            "{name}: hit distance within 1% of the diagonal for {:.2}% of {rays} rays, \
             within 5% for {:.2}% (worst {worst:.4} diagonals), same region for {:.2}%",
            100.0 * close_rate,
            100.0 * near_rate,
            100.0 * region_rate
        );
        assert!(close_rate >= 0.98, "{name}: {close_rate}");
        assert!(near_rate >= 0.995, "{name}: {near_rate}");
        assert!(region_rate >= 0.95, "{name}: {region_rate}");
    }
}

/// Decoded files with absurd but valid geometry give typed errors, never a panic; invalid
/// ones are refused before charting.
#[test]
fn hostile_representations_give_typed_errors() {
    let blob = encode_blob("blob1", 3);
    // Every boundary point at one place: every loop encloses nothing, so every region with
    // a boundary is empty, and no ray hits anything.
    let mut same = blob.rep.clone();
    let p = same.points[0];
    same.points.iter_mut().for_each(|q| *q = p);
    let query = RayQuery::new(&same).unwrap();
    assert!(query.charts().iter().all(|c| c.is_empty()));
    let mut rng = SplitMix64::new(33);
    for _ in 0..100 {
        let origin = rng.unit_vector() * 10.0;
        assert_eq!(query.first_hit(origin, -origin), None);
    }
    // Region 0's ellipsoid shrunk a billionfold, its boundary points now a billion radii
    // away: a typed error or a usable query, never a panic.
    let mut torn = blob.rep.clone();
    torn.ellipsoids[0].radii *= 1e-9;
    match RayQuery::new(&torn) {
        Ok(query) => {
            let _ = query.first_hit(DVec3::splat(10.0), -DVec3::ONE);
        }
        Err(e) => assert!(matches!(e, RemeshError::Region { .. }), "{e}"),
    }
    // A non-finite point breaks the format's rule P1.
    let mut nan = blob.rep.clone();
    nan.points[0].x = f64::NAN;
    assert!(matches!(RayQuery::new(&nan), Err(RemeshError::Invalid(_))));
    // Boundary points scattered at random: whatever the charts become, no panic, and every
    // hit found lies on its region's ellipsoid.
    let mut rng = SplitMix64::new(32);
    let mut scattered = blob.rep.clone();
    scattered
        .points
        .iter_mut()
        .for_each(|q| *q = rng.unit_vector() * rng.range_f64(0.0, 1e6));
    if let Ok(query) = RayQuery::new(&scattered) {
        for _ in 0..200 {
            let origin = rng.unit_vector() * 10.0;
            if let Some(h) = query.first_hit(origin, -origin) {
                let e = &scattered.ellipsoids[h.region as usize];
                assert!(e.implicit(h.point).abs() < 1e-9);
            }
        }
    }
}

/// Real meshes beside the project (skipped where absent), encoded at K = 20 with 5 Lloyd
/// iterations: every region gets a chart — teddy and dino have regions whose boundary
/// quantises to fewer than three distinct points, which must give empty regions or dropped
/// holes, not errors — and 1000 rays agree with brute force within 5% of the diagonal for
/// ≥ 85% (measured: teddy 97.8%, dino 90.6%). The misses are the representation's: e.g. a
/// dino limb fit by a near-cylinder (one radius ≈ 1400) projects radially onto a strip of no
/// width, and a 22-face region whose boundary simplified to 3 points.
#[test]
fn real_meshes_chart_every_region() {
    let Some(paths) = common::shared_meshes() else {
        return;
    };
    for path in paths {
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        if !["teddy", "dino"].contains(&name.as_str()) {
            continue;
        }
        let mesh = read_mesh(&path, &ImportOptions::default()).unwrap().mesh;
        let settings = EncodeSettings {
            segment: SegmentOptions {
                regions: RegionCount::Fixed(20),
                max_iterations: 5,
                ..SegmentOptions::default()
            },
            ..EncodeSettings::default()
        };
        let encoded = encode_mesh(&mesh, &settings, &mut |_| {}).unwrap();
        let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
        let query = RayQuery::new(&rep).unwrap();
        let [_, near_rate, region_rate, _] =
            compare_rays(&mesh, &encoded.segmentation.labels, &query, 1000);
        println!(
            "{name}: {} empty regions; within 5% for {:.1}%, same region {:.1}%",
            query.charts().iter().filter(|c| c.is_empty()).count(),
            100.0 * near_rate,
            100.0 * region_rate
        );
        assert!(near_rate >= 0.85, "{name}: {near_rate}");
        assert!(region_rate >= 0.75, "{name}: {region_rate}");
    }
}
