//! The encoding pipeline (`ellip::encode`): what the boundary tolerance promises, and the
//! automatic choice of the grid.

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

fn distance_to_segment(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-300)).clamp(0.0, 1.0);
    (p - (a + ab * t)).length()
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
