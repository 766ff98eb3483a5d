//! Benchmark: boundary extraction and smoothing on igea (270K faces) with 32 regions (not a
//! test; run with `cargo bench --bench boundary`).
//!
//! Uses `../shared/meshes/igea.obj` when present, else a generated 270K-face torus. The
//! labelling grows 32 random seed faces breadth-first over manifold edges (connected regions,
//! like a segmentation's). Prints the median of 11 runs of [`extract_boundaries`] and of
//! [`smooth_boundaries`] with default options (every region's ellipsoid a sphere around the
//! mesh centre, which costs what any ellipsoid costs).

use ellip::boundary::{extract_boundaries, smooth_boundaries, SmoothOptions};
use ellip::ellipsoid::Ellipsoid;
use ellip::import::{read_mesh, ImportOptions};
use ellip::rng::SplitMix64;
use ellip::Mesh;
use std::collections::VecDeque;
use std::path::Path;
use std::time::Instant;

const REGIONS: usize = 32;
const RUNS: usize = 11;

fn main() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes/igea.obj");
    let (name, mesh) = if path.exists() {
        let mesh = read_mesh(&path, &ImportOptions::default())
            .expect("igea loads")
            .mesh;
        ("igea.obj".to_string(), mesh)
    } else {
        eprintln!("{} is absent; using a generated torus", path.display());
        let mesh = ellip::synth::shapes::torus(1.0, 0.3, 450, 300);
        ("torus".to_string(), mesh)
    };
    let labels = grow_regions(&mesh, REGIONS, 1);
    let mut extract = Vec::new();
    let mut graph = None;
    for _ in 0..RUNS {
        let start = Instant::now();
        let g = extract_boundaries(&mesh, &labels, REGIONS).expect("labels fit");
        extract.push(start.elapsed().as_secs_f64());
        graph = Some(g);
    }
    let graph = graph.expect("at least one run");
    let centre = mesh.bounding_box().map(|b| b.center()).unwrap_or_default();
    let radius = mesh
        .bounding_box()
        .map(|b| b.diagonal() / 2.0)
        .unwrap_or(1.0);
    let ellipsoids = vec![Ellipsoid::sphere(centre, radius); REGIONS];
    let mut smooth = Vec::new();
    for _ in 0..RUNS {
        let start = Instant::now();
        let points = smooth_boundaries(&mesh, &graph, &ellipsoids, &SmoothOptions::default())
            .expect("options are valid");
        smooth.push(start.elapsed().as_secs_f64());
        assert_eq!(points.len(), graph.vertices.len());
    }
    println!(
        "{name}: {} faces, {REGIONS} regions: {} boundary vertices, {} junctions, {} arcs, {} cycles",
        mesh.face_count(),
        graph.vertices.len(),
        graph.junctions.len(),
        graph.arcs.len(),
        graph.cycles.iter().map(Vec::len).sum::<usize>()
    );
    println!(
        "  extract_boundaries  median {:.2} ms",
        1e3 * median(&mut extract)
    );
    println!(
        "  smooth_boundaries   median {:.2} ms ({} passes)",
        1e3 * median(&mut smooth),
        SmoothOptions::default().iterations
    );
}

/// `k` random seed faces grown breadth-first: connected regions covering the mesh.
fn grow_regions(mesh: &Mesh, k: usize, seed: u64) -> Vec<u32> {
    let n = mesh.face_count();
    let mut rng = SplitMix64::new(seed);
    let mut labels = vec![u32::MAX; n];
    let mut queue = VecDeque::new();
    for l in 0..k as u32 {
        let f = rng.below(n as u64) as usize;
        if labels[f] == u32::MAX {
            labels[f] = l;
            queue.push_back(f);
        }
    }
    while let Some(f) = queue.pop_front() {
        for g in mesh.topology().neighbors(f) {
            if labels[g as usize] == u32::MAX {
                labels[g as usize] = labels[f];
                queue.push_back(g as usize);
            }
        }
    }
    for l in &mut labels {
        if *l == u32::MAX {
            *l = 0;
        }
    }
    labels
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}
