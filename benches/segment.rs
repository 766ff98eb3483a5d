//! Benchmark: segmentation quality and speed (not a test; run with
//! `cargo bench --bench segment`, optionally followed by `-- quality`, `-- scaling` and/or
//! mesh names to run only those).
//!
//! 1. **Quality** — the paper's models (Simari & Singh 2005, table 1) at the paper's K: hand
//!    18, teddy 8, bunny 8 and horse 20 in volume mode as in the paper; duck, penguin, spot
//!    and igea_small have no K in the paper and get K = 12. For ellipsoids and for planes
//!    (VSA's L²,¹ metric) at the same K: iterations, seconds, peak memory, and the RMS
//!    distance of every region's vertices to the region's proxy as a fraction of the
//!    bounding-box diagonal (radial distance for ellipsoids, distance to the plane for
//!    planes; a vertex shared by several regions counts once in each, against each proxy).
//! 2. **Scaling** — faces against seconds at K = 32 and at most 50 iterations (surface mode),
//!    on meshes from 3K to 270K faces, with seconds / (F·log₂F) to show how far the cost
//!    is from F·log F.
//!
//! Seconds cover the whole `segment` call (metric set-up included, reading the file
//! excluded), with all cores. Each case runs in a child process of its own, so that the
//! peak memory (Linux `VmHWM`) is that case's; the child repeats the run and reports the
//! median of 3 when one run takes under 20 s, else the single run (the largest meshes).
//!
//! The meshes come from `../shared/meshes`; without it the benchmark falls back to the
//! generated fixtures in `fixtures/meshes`, at K = 12.

use ellip::import::{read_mesh, ImportOptions};
use ellip::segment::{segment, segment_planes, Mode, RegionCount, SegmentOptions, Segmentation};
use ellip::Mesh;
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// One case of the quality table: mesh, K, mode, and whether K is the paper's.
struct QualityCase {
    name: &'static str,
    k: usize,
    mode: Mode,
    paper_k: bool,
}

const QUALITY: &[QualityCase] = &[
    QualityCase {
        name: "hand",
        k: 18,
        mode: Mode::Surface,
        paper_k: true,
    },
    QualityCase {
        name: "teddy",
        k: 8,
        mode: Mode::Surface,
        paper_k: true,
    },
    QualityCase {
        name: "bunny",
        k: 8,
        mode: Mode::Volume,
        paper_k: true,
    },
    QualityCase {
        name: "horse",
        k: 20,
        mode: Mode::Volume,
        paper_k: true,
    },
    QualityCase {
        name: "duck",
        k: 12,
        mode: Mode::Surface,
        paper_k: false,
    },
    QualityCase {
        name: "penguin",
        k: 12,
        mode: Mode::Surface,
        paper_k: false,
    },
    QualityCase {
        name: "spot",
        k: 12,
        mode: Mode::Surface,
        paper_k: false,
    },
    QualityCase {
        name: "igea_small",
        k: 12,
        mode: Mode::Surface,
        paper_k: false,
    },
];

/// Meshes of the scaling table, from ~3K to ~270K faces.
const SCALING: &[&str] = &[
    "teddy",
    "bunny",
    "hand",
    "rocker_arm",
    "bunny_scan",
    "armadillo",
    "koala",
    "igea",
];

/// K and iterations of the scaling table.
const SCALING_K: usize = 32;
const SCALING_ITERATIONS: usize = 50;

/// Below this many seconds for one run, a case is run 3 times and the median reported.
const REPEAT_BELOW_SECONDS: f64 = 20.0;

/// What a child process measures.
#[derive(Debug, Clone, Copy)]
struct Measured {
    faces: usize,
    regions: usize,
    iterations: usize,
    seconds: f64,
    runs: usize,
    peak_kib: u64,
    rms_fraction: f64,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--child") {
        child(&args[1..]);
        return;
    }
    // `cargo bench` passes `--bench`; other words choose tables and meshes.
    let words: Vec<&str> = args
        .iter()
        .map(String::as_str)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let tables: Vec<&str> = words
        .iter()
        .copied()
        .filter(|w| matches!(*w, "quality" | "scaling"))
        .collect();
    let names: Vec<&str> = words
        .iter()
        .copied()
        .filter(|w| !matches!(*w, "quality" | "scaling"))
        .collect();
    let wanted_table = |t: &str| tables.is_empty() || tables.contains(&t);
    let wanted_mesh = |n: &str| names.is_empty() || names.contains(&n);

    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shared = root.join("../shared/meshes");
    println!(
        "threads: {} (all cores)",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    if !shared.is_dir() {
        println!(
            "{} is absent: measuring the generated fixtures at K = 12 instead",
            shared.display()
        );
        if wanted_table("quality") {
            quality_fixtures(&root.join("fixtures/meshes"), &wanted_mesh);
        }
        return;
    }
    if wanted_table("quality") {
        quality(&shared, &wanted_mesh);
    }
    if wanted_table("scaling") {
        scaling(&shared, &wanted_mesh);
    }
}

fn quality(dir: &Path, wanted: &dyn Fn(&str) -> bool) {
    println!();
    println!("Quality: ellipsoids (paper's metric) vs planes (L2,1) at the same K, at most 50 iterations");
    println!("K marked * is not the paper's (it gives none for that model): 12 is used.");
    print_quality_header();
    for case in QUALITY.iter().filter(|c| wanted(c.name)) {
        let path = dir.join(format!("{}.obj", case.name));
        if !path.is_file() {
            println!("{:<11} missing: {}", case.name, path.display());
            continue;
        }
        let k_label = format!("{}{}", case.k, if case.paper_k { "" } else { "*" });
        for proxy in ["ellipsoid", "plane"] {
            let mode = if proxy == "plane" {
                None
            } else {
                Some(case.mode)
            };
            let measured = run_child(&path, case.k, mode, proxy, 50);
            print_quality_row(case.name, &k_label, mode, proxy, measured);
        }
    }
}

fn quality_fixtures(dir: &Path, wanted: &dyn Fn(&str) -> bool) {
    println!();
    println!("Quality on the fixtures: ellipsoids vs planes at K = 12, at most 50 iterations");
    print_quality_header();
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "obj"))
                .collect()
        })
        .unwrap_or_default();
    paths.sort();
    for path in paths {
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        if !wanted(&name) {
            continue;
        }
        for proxy in ["ellipsoid", "plane"] {
            let mode = (proxy == "ellipsoid").then_some(Mode::Surface);
            let measured = run_child(&path, 12, mode, proxy, 50);
            print_quality_row(&name, "12", mode, proxy, measured);
        }
    }
}

fn print_quality_header() {
    println!(
        "{:<11} {:>7} {:>4} {:>8} {:>10} {:>5} {:>9} {:>5} {:>9} {:>10}",
        "mesh", "faces", "K", "mode", "proxy", "iters", "seconds", "runs", "peak MiB", "RMS/diag"
    );
}

fn print_quality_row(
    name: &str,
    k: &str,
    mode: Option<Mode>,
    proxy: &str,
    measured: Option<Measured>,
) {
    let mode = match mode {
        Some(Mode::Surface) => "surface",
        Some(Mode::Volume) => "volume",
        None => "-",
    };
    match measured {
        Some(m) => println!(
            "{:<11} {:>7} {:>4} {:>8} {:>10} {:>5} {:>9.3} {:>5} {:>9.1} {:>10.5}",
            name,
            m.faces,
            k,
            mode,
            proxy,
            m.iterations,
            m.seconds,
            m.runs,
            m.peak_kib as f64 / 1024.0,
            m.rms_fraction
        ),
        None => println!("{name:<11} {:>7} {k:>4} {mode:>8} {proxy:>10} failed", "-"),
    }
}

fn scaling(dir: &Path, wanted: &dyn Fn(&str) -> bool) {
    println!();
    println!(
        "Scaling: ellipsoids, surface mode, K = {SCALING_K}, at most {SCALING_ITERATIONS} iterations"
    );
    println!("us/(F log2 F): microseconds per F·log2(F); flat means O(F log F)");
    println!(
        "{:<11} {:>7} {:>5} {:>9} {:>5} {:>9} {:>13} {:>13}",
        "mesh", "faces", "iters", "seconds", "runs", "peak MiB", "us/(F log2 F)", "ms/iteration"
    );
    for name in SCALING.iter().copied().filter(|n| wanted(n)) {
        let path = dir.join(format!("{name}.obj"));
        if !path.is_file() {
            println!("{name:<11} missing: {}", path.display());
            continue;
        }
        match run_child(
            &path,
            SCALING_K,
            Some(Mode::Surface),
            "ellipsoid",
            SCALING_ITERATIONS,
        ) {
            Some(m) => {
                let f = m.faces as f64;
                let ratio = m.seconds * 1e6 / (f * f.log2());
                println!(
                    "{:<11} {:>7} {:>5} {:>9.3} {:>5} {:>9.1} {:>13.4} {:>13.4}",
                    name,
                    m.faces,
                    m.iterations,
                    m.seconds,
                    m.runs,
                    m.peak_kib as f64 / 1024.0,
                    ratio,
                    1e3 * m.seconds / m.iterations.max(1) as f64
                );
            }
            None => println!("{name:<11} failed"),
        }
    }
}

/// Runs one case in a child process and parses its one-line result.
fn run_child(
    path: &Path,
    k: usize,
    mode: Option<Mode>,
    proxy: &str,
    iterations: usize,
) -> Option<Measured> {
    let mode = match mode {
        Some(Mode::Volume) => "volume",
        _ => "surface",
    };
    let out = Command::new(std::env::current_exe().ok()?)
        .arg("--child")
        .arg(path)
        .args([&k.to_string(), mode, proxy, &iterations.to_string()])
        .output()
        .ok()?;
    if !out.status.success() {
        eprintln!(
            "{} (K {k}, {proxy}): {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
        return None;
    }
    let line = String::from_utf8_lossy(&out.stdout);
    let fields: Vec<&str> = line.split_whitespace().collect();
    let [faces, regions, iterations, seconds, runs, peak_kib, rms] = fields[..] else {
        eprintln!("unexpected child output: {line}");
        return None;
    };
    Some(Measured {
        faces: faces.parse().ok()?,
        regions: regions.parse().ok()?,
        iterations: iterations.parse().ok()?,
        seconds: seconds.parse().ok()?,
        runs: runs.parse().ok()?,
        peak_kib: peak_kib.parse().ok()?,
        rms_fraction: rms.parse().ok()?,
    })
    .inspect(|m| {
        if m.regions != k {
            eprintln!("{}: {} regions for K = {k}", path.display(), m.regions);
        }
    })
}

/// The child: `--child PATH K MODE PROXY ITERATIONS`; prints
/// `faces regions iterations seconds runs peak_kib rms_fraction`.
fn child(args: &[String]) {
    let [path, k, mode, proxy, iterations] = args else {
        panic!("usage: --child PATH K surface|volume ellipsoid|plane ITERATIONS");
    };
    let mesh = read_mesh(Path::new(path), &ImportOptions::default())
        .expect("benchmark mesh loads")
        .mesh;
    let options = SegmentOptions {
        regions: RegionCount::Fixed(k.parse().expect("K")),
        max_iterations: iterations.parse().expect("iterations"),
        mode: if mode == "volume" {
            Mode::Volume
        } else {
            Mode::Surface
        },
        ..SegmentOptions::default()
    };
    let diagonal = mesh.bounding_box().map_or(1.0, |b| b.diagonal());
    let mut seconds = Vec::new();
    let mut result = None;
    while seconds.len() < 3 {
        let start = Instant::now();
        let measured = if proxy == "plane" {
            let s = segment_planes(&mesh, &options).expect("segmentation");
            let rms = rms_distance(&mesh, &s, |p, x| p.distance(x));
            (s.region_count(), s.iterations, rms)
        } else {
            let s = segment(&mesh, &options).expect("segmentation");
            let rms = rms_distance(&mesh, &s, |e, x| e.radial_distance(x));
            (s.region_count(), s.iterations, rms)
        };
        seconds.push(start.elapsed().as_secs_f64());
        result = Some(measured);
        if seconds[0] >= REPEAT_BELOW_SECONDS {
            break;
        }
    }
    let (regions, iterations, rms) = result.expect("one run");
    seconds.sort_by(f64::total_cmp);
    println!(
        "{} {regions} {iterations} {:.6} {} {} {:.8}",
        mesh.face_count(),
        seconds[seconds.len() / 2],
        seconds.len(),
        peak_rss_kib(),
        rms / diagonal
    );
}

/// RMS over every region's vertices of their distance to the region's proxy; a vertex shared
/// by several regions counts once in each.
fn rms_distance<P>(mesh: &Mesh, s: &Segmentation<P>, distance: impl Fn(&P, DVec3) -> f64) -> f64 {
    let mut seen = vec![u32::MAX; mesh.vertex_count()];
    let (mut count, mut sum) = (0usize, 0.0);
    for (region, faces) in s.faces_by_region().iter().enumerate() {
        let proxy = &s.proxies[region];
        for &f in faces {
            for v in mesh.faces()[f as usize] {
                if seen[v as usize] != region as u32 {
                    seen[v as usize] = region as u32;
                    let d = distance(proxy, mesh.positions()[v as usize]);
                    count += 1;
                    sum += d * d;
                }
            }
        }
    }
    (sum / count.max(1) as f64).sqrt()
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
