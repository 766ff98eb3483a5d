//! Benchmark: decoding throughput (not a test; run with `cargo bench --bench decode`).
//!
//! The paper's models are encoded once at the paper's K (hand 18, teddy 8, bunny 8 and horse
//! 20, volume mode for the last two as in the paper), then each `.ellip` file is decoded —
//! parsed, checked and remeshed by iterative vertex addition (paper section 5.3) — to about
//! 10K, 100K and 1M output triangles. Reported: output triangles, the median seconds of 3
//! runs and triangles per second, on one thread (the remesher does not use more).
//! Budgets of 40 000 vertices and more are met by subdivision (`remesh::subdivide`).
//! Target (issue 6): at least 1M output triangles per second.
//!
//! The meshes come from `../shared/meshes`; without it the blob fixtures are used.

use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, Limits};
use ellip::import::{read_mesh, ImportOptions};
use ellip::remesh::{remesh, RemeshOptions};
use ellip::segment::{Mode, RegionCount, SegmentOptions};
use std::path::Path;
use std::time::Instant;

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
    println!("| file | K | bytes | target triangles | triangles | vertices | seconds (median) | triangles / s |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
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
        for target in [10_000usize, 100_000, 1_000_000] {
            let options = RemeshOptions {
                // A closed triangle mesh has about twice as many triangles as vertices.
                vertices: Some(target / 2),
                ..RemeshOptions::default()
            };
            let runs = 3;
            let mut seconds = Vec::with_capacity(runs);
            let mut counts = (0, 0);
            for _ in 0..runs {
                let start = Instant::now();
                let rep = decode(&bytes, &Limits::default()).expect("decodes");
                let out = remesh(&rep, &options).expect("remeshes");
                seconds.push(start.elapsed().as_secs_f64());
                counts = (out.mesh.face_count(), out.mesh.vertex_count());
            }
            seconds.sort_by(f64::total_cmp);
            let median = seconds[seconds.len() / 2];
            println!(
                "| {} | {k} | {} | {target} | {} | {} | {median:.3} | {:.0} |",
                path.file_stem().unwrap_or_default().to_string_lossy(),
                bytes.len(),
                counts.0,
                counts.1,
                counts.0 as f64 / median
            );
        }
    }
}
