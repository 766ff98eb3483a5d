//! Blobs of known ellipsoids as ground truth: topology, face budget, triangle quality, the
//! vertices' distance to the true ellipsoids, determinism and volume.

use ellip::rng::SplitMix64;
use ellip::synth::blob::{blob, distance_to_ellipsoid, random_ellipsoids, BlobOptions};
use ellip::synth::EllipsoidSpec;
use ellip::Mesh;
use glam::DVec3;

const SEEDS: [u64; 3] = [1, 2, 3];
const COUNTS: [usize; 4] = [3, 4, 5, 6];
const TARGET: usize = 6000;

fn options(target_faces: usize) -> BlobOptions {
    BlobOptions {
        target_faces,
        ..BlobOptions::default()
    }
}

/// Distance from `p` to the nearest true ellipsoid surface.
fn nearest_surface(ellipsoids: &[EllipsoidSpec], p: DVec3) -> f64 {
    ellipsoids
        .iter()
        .map(|e| distance_to_ellipsoid(e, p).abs())
        .fold(f64::INFINITY, f64::min)
}

/// Checks every property a fixture blob must have, for one seed, count and face target.
fn check_blob(seed: u64, count: usize, target: usize) {
    let ellipsoids = random_ellipsoids(seed, count);
    assert_eq!(ellipsoids.len(), count);
    let mesh = blob(&ellipsoids, &options(target)).unwrap();
    let what = format!("seed {seed}, {count} ellipsoids, target {target}");

    let t = mesh.topology();
    assert!(t.is_closed(), "{what}: not closed");
    assert!(t.is_manifold(), "{what}: not manifold");
    assert!(
        t.is_consistently_oriented(),
        "{what}: inconsistent orientation"
    );
    assert_eq!(t.component_count(), 1, "{what}");
    assert_eq!(mesh.genus(), Some(0), "{what}");
    assert!(mesh.volume().unwrap() > 0.0, "{what}: faces point inward");

    // Within ±30% of the face target.
    let faces = mesh.face_count() as f64;
    assert!(
        (faces / target as f64 - 1.0).abs() <= 0.3,
        "{what}: {faces} faces"
    );

    // No degenerate faces.
    let areas = mesh.face_areas();
    let mean = areas.iter().sum::<f64>() / areas.len() as f64;
    let smallest = areas.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        smallest >= 1e-6 * mean,
        "{what}: face area {smallest} vs mean {mean}"
    );

    // On the true surfaces except in the seams, and never far from them.
    let diagonal = mesh.bounding_box().unwrap().diagonal();
    let distances: Vec<f64> = mesh
        .positions()
        .iter()
        .map(|&p| nearest_surface(&ellipsoids, p))
        .collect();
    let on_surface = distances.iter().filter(|&&d| d <= 1e-6 * diagonal).count();
    let fraction = on_surface as f64 / distances.len() as f64;
    assert!(fraction >= 0.9, "{what}: only {fraction} on the surfaces");
    let farthest = distances.iter().copied().fold(0.0, f64::max);
    assert!(
        farthest <= 0.01 * diagonal,
        "{what}: a vertex is {farthest} from the surfaces (diagonal {diagonal})"
    );

    // Where a face lies wholly on one ellipsoid, it faces the way that ellipsoid does.
    for f in 0..mesh.face_count() {
        let corners = mesh.corners(f);
        let Some(e) = ellipsoids.iter().find(|e| {
            corners
                .iter()
                .all(|&p| distance_to_ellipsoid(e, p).abs() <= 1e-6 * diagonal)
        }) else {
            continue;
        };
        let c = mesh.face_centroid(f);
        let q = e.rotation.inverse() * (c - e.center);
        let outward = e.rotation * (q / (e.radii * e.radii));
        assert!(
            outward.dot(mesh.face_normal(f)) > 0.0,
            "{what}: face {f} faces inward"
        );
    }
}

#[test]
fn fixture_blobs_are_closed_genus_zero_and_on_the_true_surfaces() {
    for seed in SEEDS {
        for count in COUNTS {
            check_blob(seed, count, TARGET);
        }
    }
}

#[test]
fn face_budget_extremes_keep_every_property() {
    for seed in SEEDS {
        check_blob(seed, 6, 2_000);
        check_blob(seed, 3, 20_000);
    }
}

#[test]
fn same_seed_gives_identical_meshes() {
    let a = blob(&random_ellipsoids(7, 5), &options(TARGET)).unwrap();
    let b = blob(&random_ellipsoids(7, 5), &options(TARGET)).unwrap();
    assert_eq!(a.faces(), b.faces());
    assert_eq!(a.positions().len(), b.positions().len());
    for (p, q) in a.positions().iter().zip(b.positions()) {
        assert_eq!(
            p.to_array().map(f64::to_bits),
            q.to_array().map(f64::to_bits)
        );
    }
    let c = blob(&random_ellipsoids(8, 5), &options(TARGET)).unwrap();
    assert_ne!(a.positions(), c.positions());
}

/// Volume of the plain union by Monte Carlo in its bounding box (fixed seed).
fn monte_carlo_union_volume(ellipsoids: &[EllipsoidSpec], mesh: &Mesh, samples: usize) -> f64 {
    let bounds = mesh.bounding_box().unwrap();
    // Pad the box a little: the mesh's chords sit slightly inside the true surface.
    let pad = 0.02 * bounds.diagonal();
    let (lo, hi) = (
        bounds.min - DVec3::splat(pad),
        bounds.max + DVec3::splat(pad),
    );
    let mut rng = SplitMix64::new(12345);
    let inside = (0..samples)
        .filter(|_| {
            let p = DVec3::new(
                rng.range_f64(lo.x, hi.x),
                rng.range_f64(lo.y, hi.y),
                rng.range_f64(lo.z, hi.z),
            );
            ellipsoids
                .iter()
                .any(|e| distance_to_ellipsoid_sign(e, p) < 0.0)
        })
        .count();
    let size = hi - lo;
    size.x * size.y * size.z * inside as f64 / samples as f64
}

/// Negative inside `e` (the quadric's sign is all the Monte Carlo estimate needs).
fn distance_to_ellipsoid_sign(e: &EllipsoidSpec, p: DVec3) -> f64 {
    let q = e.rotation.inverse() * (p - e.center);
    (q / e.radii).length_squared() - 1.0
}

#[test]
fn volume_matches_monte_carlo_estimate_of_the_union() {
    for seed in SEEDS {
        for count in [3, 6] {
            let ellipsoids = random_ellipsoids(seed, count);
            let mesh = blob(&ellipsoids, &options(TARGET)).unwrap();
            let volume = mesh.volume().unwrap();
            // 400k samples: standard error about 0.2% of the volume.
            let estimate = monte_carlo_union_volume(&ellipsoids, &mesh, 400_000);
            let relative = (volume / estimate - 1.0).abs();
            assert!(
                relative < 0.03,
                "seed {seed}, {count}: mesh {volume} vs Monte Carlo {estimate}"
            );
        }
    }
}

#[test]
fn random_ellipsoids_overlap_their_predecessors() {
    for seed in SEEDS {
        let ellipsoids = random_ellipsoids(seed, 6);
        for (i, e) in ellipsoids.iter().enumerate().skip(1) {
            // Some point of e's surface lies inside an earlier ellipsoid.
            let mut rng = SplitMix64::new(seed * 100 + i as u64);
            let overlaps = (0..4000).any(|_| {
                let u = DVec3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
                let p = e.center + e.rotation * (u * e.radii);
                ellipsoids[..i]
                    .iter()
                    .any(|o| distance_to_ellipsoid_sign(o, p) < 0.0)
            });
            assert!(overlaps, "seed {seed}: ellipsoid {i} is detached");
            let ratio = e.radii.max_element() / e.radii.min_element();
            assert!(ratio <= 3.0 + 1e-12, "seed {seed}: axis ratio {ratio}");
        }
        // And the surface mesh matches the true surface distances in both directions:
        // every ellipsoid contributes on-surface vertices.
        let mesh = blob(&ellipsoids, &options(TARGET)).unwrap();
        let diagonal = mesh.bounding_box().unwrap().diagonal();
        for (i, e) in ellipsoids.iter().enumerate() {
            let on = mesh
                .positions()
                .iter()
                .filter(|&&p| distance_to_ellipsoid(e, p).abs() <= 1e-6 * diagonal)
                .count();
            assert!(
                on * 20 >= mesh.vertex_count() / ellipsoids.len(),
                "seed {seed}: ellipsoid {i} has only {on} vertices"
            );
        }
    }
}
