//! Benchmark: which real meshes round-trip clean (not a test; run with
//! `cargo bench --bench clean`, or `cargo bench --bench clean -- --large` for the large
//! meshes, `-- --no-verify` for files written without the encoder's decoder check).
//!
//! Each mesh is encoded at each K with the default settings (as `ellip encode MESH -k K`) and
//! the file decoded at its suggested density (as `ellip decode F.ellip -o F.ply`). Clean, as
//! [`ellip::remesh::assemble::MeshCheck::is_clean_from`] says: closed where the source is,
//! manifold where the source is, consistently oriented, no flipped or degenerate triangle
//! (issue 6's check).
//! Reported per file: the regions written, bytes, encode and decode seconds, how many times
//! the decoder meshed the regions ([`ellip::remesh::Remeshed::attempts`]: one when its
//! first attempt is clean) and what is wrong, then the count of clean files and of
//! meshings. The README's table "files that decode clean" comes from here.
//!
//! By default: the 12 meshes of `../shared/meshes` under 25 000 faces at K = 8, 12, 18, 24
//! and 32 (K = 8 to 24 with `--no-verify`); with `--large`, the 4 larger ones at K = 12 and
//! 18. Without `../shared`, the blob fixtures at K = 4 and 8. With `--dir DIR`: every mesh
//! file in DIR (meshes the project has not seen), at the default K and at 18, each plus one
//! region for each further connected component
//! ([`ellip::segment::default_region_count`]).
//!
//! With `--budgets`: the small meshes at K = 12 and 24, each file decoded at each of
//! [`BUDGETS`] vertices without subdivision (every vertex placed by vertex addition), and
//! besides the clean decodes, those whose first meshing attempt is clean (one meshing): how
//! files fare at densities the encoder's check did not look at.
//!
//! With `--parametric`, every decode uses the parametric scheme (section 5.2) instead of
//! vertex addition.

use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, Limits};
use ellip::import::{read_mesh, ImportOptions, MeshFormat};
use ellip::remesh::{remesh, RemeshOptions, Scheme};
use ellip::segment::{default_region_count, RegionCount, SegmentOptions, DEFAULT_REGIONS};
use std::path::{Path, PathBuf};
use std::time::Instant;

const SMALL: [&str; 12] = [
    "hand",
    "teddy",
    "bunny",
    "horse",
    "dino",
    "duck",
    "penguin",
    "spot",
    "igea_small",
    "fandisk",
    "rocker_arm",
    "demosthenes",
];

const LARGE: [&str; 4] = ["armadillo", "bunny_scan", "koala", "igea"];

/// The vertex budgets of `--budgets`.
const BUDGETS: [usize; 5] = [1_000, 2_000, 5_000, 12_500, 31_250];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let large = args.iter().any(|a| a == "--large");
    let verify = !args.iter().any(|a| a == "--no-verify");
    let budgets = args.iter().any(|a| a == "--budgets");
    let scheme = if args.iter().any(|a| a == "--parametric") {
        Scheme::Parametric
    } else {
        Scheme::Adaptive
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shared = root.join("../shared/meshes");
    let dir = args.iter().position(|a| a == "--dir").map(|i| {
        args.get(i + 1)
            .map(PathBuf::from)
            .expect("--dir needs a folder")
    });
    let (paths, ks): (Vec<PathBuf>, Vec<usize>) = if let Some(dir) = dir {
        let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| MeshFormat::from_path(p).is_some())
            .collect();
        paths.sort();
        (paths, vec![DEFAULT_REGIONS, 18])
    } else if shared.is_dir() {
        let names: &[&str] = if large { &LARGE } else { &SMALL };
        let ks = match (large, verify) {
            _ if budgets => vec![12, 24],
            (true, _) => vec![12, 18],
            (false, true) => vec![8, 12, 18, 24, 32],
            (false, false) => vec![8, 12, 18, 24],
        };
        let paths = names
            .iter()
            .map(|n| shared.join(format!("{n}.obj")))
            .collect();
        (paths, ks)
    } else {
        eprintln!("../shared/meshes not found: using the blob fixtures");
        let paths = (1..=4)
            .map(|i| root.join(format!("fixtures/meshes/blob{i}.obj")))
            .collect();
        (paths, vec![4, 8])
    };
    println!(
        "decoder check: {}",
        if verify { "on" } else { "off (--no-verify)" }
    );
    // Each file is decoded as `ellip decode` does by default, or at each budget.
    let decodings: Vec<(String, RemeshOptions)> = if budgets {
        BUDGETS
            .iter()
            .map(|&b| {
                let options = RemeshOptions {
                    vertices: Some(b),
                    subdivision: false,
                    scheme,
                    ..RemeshOptions::default()
                };
                (b.to_string(), options)
            })
            .collect()
    } else {
        let options = RemeshOptions {
            scheme,
            ..RemeshOptions::default()
        };
        vec![("default".to_string(), options)]
    };
    println!("| file | K | regions | bytes | encode s | vertices | decode s | meshings | result |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---|");
    let (mut clean, mut total, mut meshings, mut first_clean) = (0, 0, 0, 0);
    for path in &paths {
        let Ok(imported) = read_mesh(path, &ImportOptions::default()) else {
            eprintln!("skipping {}", path.display());
            continue;
        };
        let name = path.file_stem().unwrap_or_default().to_string_lossy();
        // A source that is not manifold gives a mesh that is not either.
        let source_manifold = imported.mesh.topology().is_manifold();
        // Each further component needs a region of its own.
        let extra = default_region_count(&imported.mesh) - DEFAULT_REGIONS;
        for k in ks.iter().map(|k| k + extra) {
            let settings = EncodeSettings {
                segment: SegmentOptions {
                    regions: RegionCount::Fixed(k),
                    ..SegmentOptions::default()
                },
                verify,
                ..EncodeSettings::default()
            };
            let start = Instant::now();
            let encoded = match encode_mesh(&imported.mesh, &settings, &mut |_| {}) {
                Ok(e) => e,
                Err(e) => {
                    total += decodings.len();
                    println!("| {name} | {k} | | | | | | | encode error: {e} |");
                    continue;
                }
            };
            let encode_seconds = start.elapsed().as_secs_f64();
            for (vertices, options) in &decodings {
                total += 1;
                let start = Instant::now();
                let result = decode(&encoded.bytes, &Limits::default())
                    .map_err(|e| e.to_string())
                    .and_then(|rep| remesh(&rep, options).map_err(|e| e.to_string()));
                let decode_seconds = start.elapsed().as_secs_f64();
                let attempts = result.as_ref().map_or(0, |out| out.attempts);
                meshings += attempts;
                let verdict = match result {
                    Ok(out) if out.check.is_clean_from(source_manifold) => {
                        clean += 1;
                        first_clean += usize::from(out.attempts == 1);
                        if out.check.manifold {
                            "clean".to_string()
                        } else {
                            "clean (not manifold, as its source)".to_string()
                        }
                    }
                    Ok(out) => out.check.faults(),
                    Err(e) => format!("does not decode: {e}"),
                };
                println!(
                    "| {name} | {k} | {} | {} | {encode_seconds:.2} | {vertices} | {decode_seconds:.2} | {attempts} | {verdict} |",
                    encoded.representation.region_count(),
                    encoded.bytes.len(),
                );
            }
        }
    }
    println!(
        "\nclean: {clean} of {total} ({first_clean} in one meshing); meshings (Remeshed::attempts) in all: {meshings}"
    );
}
