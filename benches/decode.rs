//! Benchmark: decoding throughput (not a test; run with `cargo bench --bench decode`).
//!
//! The paper's models are encoded once at the paper's K (hand 18, teddy 8, bunny 8 and horse
//! 20, volume mode for the last two as in the paper), then each `.ellip` file is decoded —
//! parsed, checked and remeshed by iterative vertex addition (paper section 5.3) — to about
//! 10K, 100K and 1M output triangles. Reported: output triangles, the median milliseconds of
//! at least 5 runs and half a second (at most 200 runs) and triangles per second, on one
//! thread (the remesher does not use more); and, as a baseline timed the same way in the same
//! run, spade's bulk-loaded Delaunay triangulation of as many points in a square (the floor
//! any remesher built on spade's triangulation pays) and the decode's time over it.
//! Budgets of 20 000 vertices and more are met by subdivision (`remesh::subdivide`).
//! Target (issue 6): at least 1M output triangles per second.
//!
//! With `-- --scaling`: each file decoded by vertex addition alone at [`SCALING_VERTICES`]
//! vertices, the median milliseconds at each and the microseconds each vertex added since
//! the budget before cost: how a decode's time splits into a part per vertex and a part that
//! does not grow with the budget (planning each region).
//!
//! The meshes come from `../shared/meshes`; without it the blob fixtures are used.

use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, Limits};
use ellip::import::{read_mesh, ImportOptions};
use ellip::remesh::{remesh, RemeshOptions};
use ellip::rng::SplitMix64;
use ellip::segment::{Mode, RegionCount, SegmentOptions};
use spade::{DelaunayTriangulation, Point2, Triangulation};
use std::path::Path;
use std::time::Instant;

/// The median seconds of `run`, made at least [`MIN_RUNS`] times and for at least
/// [`MIN_SECONDS`] in all, at most [`MAX_RUNS`] times.
fn median_seconds(mut run: impl FnMut()) -> f64 {
    let mut seconds = Vec::new();
    let started = Instant::now();
    while seconds.len() < MAX_RUNS
        && (seconds.len() < MIN_RUNS || started.elapsed().as_secs_f64() < MIN_SECONDS)
    {
        let start = Instant::now();
        run();
        seconds.push(start.elapsed().as_secs_f64());
    }
    seconds.sort_by(f64::total_cmp);
    seconds[seconds.len() / 2]
}

/// The budgets of `--scaling` (decoded with subdivision off: every vertex is placed by
/// vertex addition).
const SCALING_VERTICES: [usize; 5] = [1_000, 2_000, 5_000, 10_000, 20_000];

const MIN_RUNS: usize = 5;
const MIN_SECONDS: f64 = 0.5;
const MAX_RUNS: usize = 200;

/// `n` points spread over the unit square, the same every run.
fn square_points(n: usize) -> Vec<Point2<f64>> {
    let mut rng = SplitMix64::new(0x9e37_79b9_7f4a_7c15);
    (0..n)
        .map(|_| Point2::new(rng.next_f64(), rng.next_f64()))
        .collect()
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shared = root.join("../shared/meshes");
    let cases: Vec<(std::path::PathBuf, usize, Mode)> = if shared.is_dir() {
        vec![
            (shared.join("hand.obj"), 18, Mode::Surface),
            (shared.join("teddy.obj"), 8, Mode::Surface),
            (shared.join("bunny.obj"), 8, Mode::Volume),
            (shared.join("horse.obj"), 20, Mode::Volume),
        ]
    } else {
        eprintln!("../shared/meshes not found: using the blob fixtures");
        (1..=4)
            .map(|i| {
                (
                    root.join(format!("fixtures/meshes/blob{i}.obj")),
                    i + 2,
                    Mode::Surface,
                )
            })
            .collect()
    };
    let scaling = std::env::args().any(|a| a == "--scaling");
    if scaling {
        println!("| file | K | vertices | ms (median) | µs per vertex since the budget before |");
        println!("|---|---:|---:|---:|---:|");
    } else {
        println!("| file | K | bytes | target triangles | triangles | vertices | ms (median) | triangles / s | spade bulk load, ms | ratio |");
        println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    }
    for (path, k, mode) in cases {
        let Ok(imported) = read_mesh(&path, &ImportOptions::default()) else {
            eprintln!("skipping {}", path.display());
            continue;
        };
        let settings = EncodeSettings {
            segment: SegmentOptions {
                regions: RegionCount::Fixed(k),
                mode,
                ..SegmentOptions::default()
            },
            ..EncodeSettings::default()
        };
        let bytes = encode_mesh(&imported.mesh, &settings, &mut |_| {})
            .expect("encodes")
            .bytes;
        let name = path.file_stem().unwrap_or_default().to_string_lossy();
        if scaling {
            let mut before: Option<(usize, f64)> = None;
            for target in SCALING_VERTICES {
                let options = RemeshOptions {
                    vertices: Some(target),
                    subdivision: false,
                    ..RemeshOptions::default()
                };
                let mut vertices = 0;
                let median = median_seconds(|| {
                    let rep = decode(&bytes, &Limits::default()).expect("decodes");
                    vertices = remesh(&rep, &options)
                        .expect("remeshes")
                        .mesh
                        .vertex_count();
                });
                let per_vertex = before.map_or(String::new(), |(v, t)| {
                    format!(
                        "{:.2}",
                        1e6 * (median - t) / vertices.saturating_sub(v).max(1) as f64
                    )
                });
                println!(
                    "| {name} | {k} | {vertices} | {:.2} | {per_vertex} |",
                    1e3 * median
                );
                before = Some((vertices, median));
            }
            continue;
        }
        for target in [10_000usize, 100_000, 1_000_000] {
            let options = RemeshOptions {
                // A closed triangle mesh has about twice as many triangles as vertices.
                vertices: Some(target / 2),
                ..RemeshOptions::default()
            };
            let mut counts = (0, 0);
            let median = median_seconds(|| {
                let rep = decode(&bytes, &Limits::default()).expect("decodes");
                let out = remesh(&rep, &options).expect("remeshes");
                counts = (out.mesh.face_count(), out.mesh.vertex_count());
            });
            let points = square_points(counts.1);
            let floor = median_seconds(|| {
                let dt = DelaunayTriangulation::<Point2<f64>>::bulk_load(points.clone())
                    .expect("finite points");
                assert_eq!(dt.num_vertices(), points.len());
            });
            println!(
                "| {name} | {k} | {} | {target} | {} | {} | {:.2} | {:.0} | {:.2} | {:.1} |",
                bytes.len(),
                counts.0,
                counts.1,
                1e3 * median,
                counts.0 as f64 / median,
                1e3 * floor,
                median / floor
            );
        }
    }
}
