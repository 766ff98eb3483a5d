//! Rate–distortion report (not a test; run with `cargo bench --bench rd`).
//!
//! For each mesh of a folder (`ELLIP_RD_DIR`, default `../shared/meshes` limited to the
//! paper-scale models; the blob fixtures when that folder is absent) and each K of 4, 8, 12,
//! 18, 24, 32, 48, 64: encode with the default settings, decode (remesh at the source's
//! vertex count) and compare with the source (`ellip::compare`, 100K samples a side).
//! Records bytes, symmetric RMS and Hausdorff distance (fractions of the diagonal), mean
//! normal deviation (degrees), encode and decode seconds. Writes `target/rd/rd.csv` and
//! `target/rd/rd.svg` (RMS against bytes, one line per mesh, both axes logarithmic) and
//! prints the table.

use ellip::compare::{compare_meshes, CompareOptions};
use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, Limits};
use ellip::import::{read_mesh, ImportOptions};
use ellip::remesh::{remesh, RemeshOptions};
use ellip::segment::{RegionCount, SegmentOptions};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

const KS: [usize; 8] = [4, 8, 12, 18, 24, 32, 48, 64];
const PAPER_SCALE: [&str; 8] = [
    "hand",
    "teddy",
    "bunny",
    "horse",
    "duck",
    "penguin",
    "spot",
    "igea_small",
];

struct Row {
    mesh: String,
    k: usize,
    bytes: usize,
    rms: f64,
    hausdorff: f64,
    normals: f64,
    encode_s: f64,
    decode_s: f64,
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files: Vec<PathBuf> = match std::env::var_os("ELLIP_RD_DIR") {
        Some(dir) => {
            let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
                .expect("ELLIP_RD_DIR is a folder")
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.extension().is_some_and(|x| {
                        x == "obj" || x == "ply" || x == "stl" || x == "off" || x == "glb"
                    })
                })
                .collect();
            v.sort();
            v
        }
        None => {
            let shared = root.join("../shared/meshes");
            if shared.is_dir() {
                PAPER_SCALE
                    .iter()
                    .map(|m| shared.join(format!("{m}.obj")))
                    .collect()
            } else {
                eprintln!("../shared/meshes not found: using the blob fixtures");
                (1..=4)
                    .map(|i| root.join(format!("fixtures/meshes/blob{i}.obj")))
                    .collect()
            }
        }
    };
    let mut rows = Vec::new();
    println!("| mesh | K | bytes | RMS % | Hausdorff % | normals ° | encode s | decode s |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for path in &files {
        let Ok(imported) = read_mesh(path, &ImportOptions::default()) else {
            eprintln!("skipping {}", path.display());
            continue;
        };
        let mesh = imported.mesh;
        let name = path
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        for k in KS {
            if k > mesh.face_count() {
                continue;
            }
            let settings = EncodeSettings {
                segment: SegmentOptions {
                    regions: RegionCount::Fixed(k),
                    ..SegmentOptions::default()
                },
                ..EncodeSettings::default()
            };
            let start = Instant::now();
            let Ok(encoded) = encode_mesh(&mesh, &settings, &mut |_| {}) else {
                eprintln!("{name} K={k}: encoding failed");
                continue;
            };
            let encode_s = start.elapsed().as_secs_f64();
            let start = Instant::now();
            let decoded = decode(&encoded.bytes, &Limits::default())
                .map_err(|e| e.to_string())
                .and_then(|r| remesh(&r, &RemeshOptions::default()).map_err(|e| e.to_string()));
            let decode_s = start.elapsed().as_secs_f64();
            let decoded = match decoded {
                Ok(d) => d,
                Err(e) => {
                    eprintln!("{name} K={k}: decoding failed: {e}");
                    continue;
                }
            };
            let c =
                compare_meshes(&mesh, &decoded.mesh, &CompareOptions::default()).expect("compares");
            let rel = c.relative(&c.symmetric);
            let row = Row {
                mesh: name.clone(),
                k,
                bytes: encoded.bytes.len(),
                rms: rel.rms,
                hausdorff: rel.hausdorff,
                normals: c.symmetric.normal_deviation,
                encode_s,
                decode_s,
            };
            println!(
                "| {} | {} | {} | {:.3} | {:.3} | {:.1} | {:.2} | {:.2} |",
                row.mesh,
                row.k,
                row.bytes,
                100.0 * row.rms,
                100.0 * row.hausdorff,
                row.normals,
                row.encode_s,
                row.decode_s
            );
            rows.push(row);
        }
    }
    let out = root.join("target/rd");
    std::fs::create_dir_all(&out).expect("target/rd");
    let mut csv = String::from(
        "mesh,k,bytes,rms,hausdorff,normal_deviation_degrees,encode_seconds,decode_seconds\n",
    );
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{},{:.6e},{:.6e},{:.3},{:.4},{:.4}",
            r.mesh, r.k, r.bytes, r.rms, r.hausdorff, r.normals, r.encode_s, r.decode_s
        );
    }
    std::fs::write(out.join("rd.csv"), csv).expect("rd.csv");
    std::fs::write(out.join("rd.svg"), plot(&rows)).expect("rd.svg");
    eprintln!(
        "wrote {} and {}",
        out.join("rd.csv").display(),
        out.join("rd.svg").display()
    );
}

/// RMS (% of the diagonal) against bytes, log–log, one polyline per mesh.
fn plot(rows: &[Row]) -> String {
    let (w, h, m) = (720.0, 480.0, 60.0);
    let (bx0, bx1) = (100f64.log10(), 20_000f64.log10());
    let (ry0, ry1) = (0.05f64.log10(), 10f64.log10());
    let x = |b: f64| m + (b.max(1.0).log10() - bx0) / (bx1 - bx0) * (w - 2.0 * m);
    let y = |r: f64| h - m - (r.max(1e-9).log10() - ry0) / (ry1 - ry0) * (h - 2.0 * m);
    let colors = [
        "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
        "#bcbd22", "#17becf",
    ];
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n"
    );
    for b in [100.0, 300.0, 1000.0, 3000.0, 10000.0] {
        let _ = writeln!(s, "<line x1='{0:.1}' y1='{1}' x2='{0:.1}' y2='{2}' stroke='#ddd'/><text x='{0:.1}' y='{3}' text-anchor='middle'>{b}</text>", x(b), m, h - m, h - m + 16.0);
    }
    for r in [0.1, 0.3, 1.0, 3.0, 10.0] {
        let _ = writeln!(s, "<line x1='{1}' y1='{0:.1}' x2='{2}' y2='{0:.1}' stroke='#ddd'/><text x='{3}' y='{0:.1}' text-anchor='end'>{r}%</text>", y(r), m, w - m, m - 6.0);
    }
    let _ = writeln!(
        s,
        "<text x='{}' y='{}' text-anchor='middle'>.ellip bytes</text>",
        w / 2.0,
        h - 16.0
    );
    let _ = writeln!(s, "<text x='16' y='{}' transform='rotate(-90 16 {})' text-anchor='middle'>RMS error, % of the bbox diagonal</text>", h / 2.0, h / 2.0);
    let mut names: Vec<&str> = rows.iter().map(|r| r.mesh.as_str()).collect();
    names.dedup();
    for (i, name) in names.iter().enumerate() {
        let c = colors[i % colors.len()];
        let pts: Vec<String> = rows
            .iter()
            .filter(|r| r.mesh == *name)
            .map(|r| format!("{:.1},{:.1}", x(r.bytes as f64), y(100.0 * r.rms)))
            .collect();
        let _ = writeln!(
            s,
            "<polyline fill='none' stroke='{c}' stroke-width='2' points='{}'/>",
            pts.join(" ")
        );
        let _ = writeln!(
            s,
            "<text x='{}' y='{}' fill='{c}'>{name}</text>",
            w - m + 4.0 - 120.0,
            m + 14.0 * i as f64
        );
    }
    s.push_str("</svg>\n");
    s
}
