//! Benchmark: load and analyse the largest mesh at hand (not a test; run with
//! `cargo bench --bench analyze`).
//!
//! Measures the largest `.obj` in `../shared/meshes` when present (else the largest generated
//! fixture), and a generated 1M-face torus written as OBJ. Prints faces, the median of 5 runs
//! for loading (parse + repair + topology) and for analysis (normals, curvature, measures),
//! and peak memory. Each mesh is measured in a child process of its own, so that the peak
//! memory is that mesh's.

use ellip::import::{read_mesh, ImportOptions};
use ellip::mesh::curvature::mean_curvature;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() {
    // `cargo bench` passes `--bench`; a plain path argument means "measure this one".
    if let Some(path) = std::env::args().skip(1).find(|a| !a.starts_with("--")) {
        measure(Path::new(&path));
        return;
    }
    let mut cases = Vec::new();
    match largest_mesh() {
        Some(path) => cases.push(path),
        None => eprintln!("no mesh found in ../shared/meshes or fixtures/meshes"),
    }
    let torus = std::env::temp_dir().join(format!("ellip-bench-torus-{}.obj", std::process::id()));
    let mesh = ellip::synth::shapes::torus(1.0, 0.3, 1000, 500);
    ellip::export::write_mesh(&torus, &ellip::export::MeshData::from_mesh(&mesh))
        .expect("temporary OBJ is written");
    drop(mesh);
    cases.push(torus.clone());
    for path in &cases {
        let status = std::process::Command::new(std::env::current_exe().expect("own path"))
            .arg(path)
            .status()
            .expect("child runs");
        assert!(status.success(), "measuring {} failed", path.display());
        println!();
    }
    let _ = std::fs::remove_file(&torus);
}

fn measure(path: &Path) {
    let options = ImportOptions::default();
    let baseline_kib = peak_rss_kib();
    let mut load = Vec::new();
    let mut analyse = Vec::new();
    let mut faces = 0;
    for _ in 0..5 {
        let start = Instant::now();
        let imported = read_mesh(path, &options).expect("benchmark mesh loads");
        load.push(start.elapsed().as_secs_f64());
        let mesh = imported.mesh;
        faces = mesh.face_count();
        let start = Instant::now();
        let normals = mesh.vertex_normals();
        let curvature = mean_curvature(&mesh);
        let stats = (
            mesh.area(),
            mesh.volume(),
            mesh.genus(),
            mesh.average_edge_length(),
            mesh.bounding_box(),
        );
        analyse.push(start.elapsed().as_secs_f64());
        std::hint::black_box((normals, curvature, stats));
    }
    let peak_kib = peak_rss_kib();
    let (l, a) = (median(&mut load), median(&mut analyse));
    let bytes_per_face = (peak_kib.saturating_sub(baseline_kib) as f64 * 1024.0) / faces as f64;
    println!("mesh            {}", path.display());
    println!("faces           {faces}");
    println!("load            {l:.3} s (median of 5: parse, repair, topology)");
    println!("analyse         {a:.3} s (median of 5: normals, curvature, measures)");
    println!("total           {:.3} s", l + a);
    println!(
        "peak memory     {:.1} MiB ({bytes_per_face:.0} bytes per face above the baseline)",
        peak_kib as f64 / 1024.0
    );
}

fn largest_mesh() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    [root.join("../shared/meshes"), root.join("fixtures/meshes")]
        .iter()
        .find_map(|dir| {
            std::fs::read_dir(dir)
                .ok()?
                .filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "obj"))
                .max_by_key(|p| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0))
        })
}

fn median(xs: &mut [f64]) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

/// Peak resident set size of this process (Linux `VmHWM`), 0 where unknown.
fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}
