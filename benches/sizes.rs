//! Benchmark: `.ellip` file sizes on real meshes (not a test; run with
//! `cargo bench --bench sizes`).
//!
//! The paper's models at the paper's K (Simari & Singh 2005, table 1: hand 18, teddy 8, and
//! bunny 8 and horse 20 in volume mode) and every paper-scale model at K = 32, encoded with
//! the default settings (boundary tolerance 10⁻³ of the diagonal, grid bits chosen per file):
//! bytes in all and per section, the grid bits chosen, the pool size before and after
//! simplification, and the largest distance from a boundary point before simplification to
//! its decoded arc — which the boundary tolerance bounds — as a fraction of the diagonal
//! (where the encoder's decoder check mended regions, the unsimplified encoding it is
//! measured against may be mended differently, and the column says so instead).
//!
//! The meshes come from `../shared/meshes`; without it the benchmark uses the generated blob
//! fixtures at K = their ellipsoid count.

use ellip::compare::distance_to_segment;
use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, inspect, Limits};
use ellip::import::{read_mesh, ImportOptions};
use ellip::representation::Representation;
use ellip::segment::{Mode, RegionCount, SegmentOptions};
use std::path::{Path, PathBuf};

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shared = root.join("../shared/meshes");
    let mut cases: Vec<(PathBuf, usize, Mode)> = Vec::new();
    if shared.is_dir() {
        for (name, k, mode) in [
            ("hand", 18, Mode::Surface),
            ("teddy", 8, Mode::Surface),
            ("bunny", 8, Mode::Volume),
            ("horse", 20, Mode::Volume),
        ] {
            cases.push((shared.join(format!("{name}.obj")), k, mode));
        }
        for name in [
            "hand",
            "teddy",
            "bunny",
            "horse",
            "duck",
            "penguin",
            "spot",
            "igea_small",
        ] {
            cases.push((shared.join(format!("{name}.obj")), 32, Mode::Surface));
        }
    } else {
        eprintln!("../shared/meshes not found: using the blob fixtures");
        for (name, k) in [("blob1", 3), ("blob2", 4), ("blob3", 5), ("blob4", 6)] {
            let path = root.join(format!("fixtures/meshes/{name}.obj"));
            cases.push((path, k, Mode::Surface));
        }
    }
    println!(
        "| mesh | K | mode | bytes | META | ELPS | ARCS | PNTS | CYCL | framing | bits | points (before) | worst boundary error / diag |"
    );
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (path, k, mode) in cases {
        let mesh = match read_mesh(&path, &ImportOptions::default()) {
            Ok(m) => m.mesh,
            Err(e) => {
                eprintln!("skipping {}: {e}", path.display());
                continue;
            }
        };
        let segment = SegmentOptions {
            regions: RegionCount::Fixed(k),
            mode,
            ..SegmentOptions::default()
        };
        let settings = EncodeSettings {
            segment: segment.clone(),
            ..EncodeSettings::default()
        };
        let encoded = encode_mesh(&mesh, &settings, &mut |_| {}).expect("encodes");
        // The same boundary unsimplified and nearly unquantised, to measure what was lost.
        // Only comparable when neither encoding was mended by the decoder check (mending
        // changes regions, or stores some boundaries at the mesh's points).
        let exact_encoding = encode_mesh(
            &mesh,
            &EncodeSettings {
                segment,
                simplify_tolerance: 0.0,
                bits: Some(24),
                ..EncodeSettings::default()
            },
            &mut |_| {},
        )
        .expect("encodes");
        let comparable =
            encoded.verification.rounds == 0 && exact_encoding.verification.rounds == 0;
        let exact = exact_encoding.representation;
        let decoded = decode(&encoded.bytes, &Limits::default()).expect("decodes");
        let summary = inspect(&encoded.bytes, &Limits::default()).expect("inspects");
        let diagonal = mesh.bounding_box().map_or(1.0, |b| b.diagonal());
        let section = |tag: &[u8; 4]| {
            summary
                .sections
                .iter()
                .find(|s| &s.tag.0 == tag)
                .map_or(0, |s| s.stored_bytes)
        };
        let payloads: u64 = summary.sections.iter().map(|s| s.stored_bytes).sum();
        println!(
            "| {} | {k} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} ({}) | {} |",
            path.file_stem().unwrap_or_default().to_string_lossy(),
            if mode == Mode::Volume {
                "volume"
            } else {
                "surface"
            },
            encoded.bytes.len(),
            section(b"META"),
            section(b"ELPS"),
            section(b"ARCS"),
            section(b"PNTS"),
            section(b"CYCL"),
            encoded.bytes.len() as u64 - payloads,
            encoded.bits,
            summary.points,
            encoded.boundary_points,
            if comparable {
                format!("{:.2e}", worst_boundary_error(&exact, &decoded) / diagonal)
            } else {
                format!(
                    "— (mended: {} and {} rounds)",
                    encoded.verification.rounds, exact_encoding.verification.rounds
                )
            },
        );
    }
}

/// The largest distance from a point of an arc of `exact` to the same arc of `decoded` (a
/// polyline), over all arcs; the arcs correspond one to one (simplification keeps them).
fn worst_boundary_error(exact: &Representation, decoded: &Representation) -> f64 {
    let mut worst = 0.0f64;
    for i in 0..exact.arcs.len().min(decoded.arcs.len()) {
        let (Some(before), Some(mut after)) = (exact.arc_positions(i), decoded.arc_positions(i))
        else {
            continue;
        };
        // A closed loop's last segment returns to its first point.
        if let (true, Some(&first)) = (decoded.arcs[i].closed, after.first()) {
            after.push(first);
        }
        for &p in &before {
            let d = after
                .windows(2)
                .map(|w| distance_to_segment(p, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            if d.is_finite() {
                worst = worst.max(d);
            }
        }
    }
    worst
}
