//! Benchmark: time to fit one ellipsoid to one region (not a test; run with
//! `cargo bench --bench fit`).
//!
//! Regions of 1K, 10K and 100K samples: a 30% cap of an ellipsoid with axis ratio 1:3, with
//! 0.5% noise on positions, normals and curvatures. For each size it prints the median over
//! repeated runs of a fit with one sign (positive, negative), both signs, and a warm start
//! from the previous answer without fresh starts (the segmentation's refit). Target: a
//! 100K-sample region in under 50 ms per sign on one core.

use ellip::ellipsoid::fit::SignChoice;
use ellip::ellipsoid::{fit_ellipsoid, Ellipsoid, FitInput, FitOptions, MeshScale, Sign};
use ellip::rng::SplitMix64;
use glam::{DQuat, DVec3};
use std::time::Instant;

struct Region {
    points: Vec<DVec3>,
    normals: Vec<DVec3>,
    curvatures: Vec<f64>,
}

fn make_region(n: usize, seed: u64) -> Region {
    let mut rng = SplitMix64::new(seed);
    let truth = Ellipsoid {
        center: DVec3::new(0.3, -0.1, 0.2),
        rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.4, -0.3, 0.9),
        radii: DVec3::new(3.0, 1.5, 1.0),
        sign: Sign::Positive,
    };
    let mut region = Region {
        points: Vec::with_capacity(n),
        normals: Vec::with_capacity(n),
        curvatures: Vec::with_capacity(n),
    };
    let sigma = 0.005;
    let gauss = |rng: &mut SplitMix64| DVec3::new(rng.normal(), rng.normal(), rng.normal());
    while region.points.len() < n {
        let Some(u) = gauss(&mut rng).try_normalize() else {
            continue;
        };
        // The cap u·(1,1,1)/√3 > 0.4 covers about 30% of the unit sphere.
        if u.dot(DVec3::ONE.normalize()) < 0.4 {
            continue;
        }
        let p = truth.from_unit_sphere(u);
        let n = truth.normal(p);
        region.points.push(p + gauss(&mut rng) * sigma * 2.0);
        region
            .normals
            .push((n + gauss(&mut rng) * sigma).normalize());
        region
            .curvatures
            .push(truth.mean_curvature(p) * (1.0 + sigma * rng.normal()));
    }
    region
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    median(&mut times)
}

fn main() {
    let scale = MeshScale::new(8.0, 0.02, 20.0);
    let base = FitOptions::surface(&scale);
    println!("ellipsoid fit, median of runs (ms); 30% cap, axis ratio 1:3, 0.5% noise");
    println!(
        "{:>8} {:>10} {:>10} {:>10} {:>12} {:>6}",
        "samples", "positive", "negative", "both", "warm (both)", "runs"
    );
    for (n, runs) in [(1_000, 41), (10_000, 21), (100_000, 11)] {
        let region = make_region(n, 42);
        let input = FitInput::new(&region.points, &region.normals, &region.curvatures)
            .expect("equal lengths");
        let only = |sign| FitOptions {
            signs: SignChoice::Only(sign),
            ..base
        };
        let pos = time_ms(runs, || {
            std::hint::black_box(fit_ellipsoid(&input, &only(Sign::Positive)));
        });
        let neg = time_ms(runs, || {
            std::hint::black_box(fit_ellipsoid(&input, &only(Sign::Negative)));
        });
        let both = time_ms(runs, || {
            std::hint::black_box(fit_ellipsoid(&input, &base));
        });
        let previous = fit_ellipsoid(&input, &base).ellipsoid;
        let warm_options = FitOptions {
            fresh_starts_with_warm: false,
            ..base
        };
        let warm_input = input.with_start(previous);
        let warm = time_ms(runs, || {
            std::hint::black_box(fit_ellipsoid(&warm_input, &warm_options));
        });
        println!("{n:>8} {pos:>10.2} {neg:>10.2} {both:>10.2} {warm:>12.2} {runs:>6}");
    }
}
