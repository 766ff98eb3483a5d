//! `ellip compare A B`: how far apart two meshes are, as a table or (`--json`) for scripts.

use super::{info::read_if_ellip, CliError, ReadArgs};
use clap::Args;
use ellip::compare::{compare_meshes, CompareOptions, Comparison, Deviation, DEFAULT_SAMPLES};
use ellip::format::{decode, Limits};
use ellip::import::read_mesh;
use ellip::remesh::{remesh, RemeshOptions};
use ellip::Mesh;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct CompareArgs {
    /// The reference mesh (.obj, .gltf, .glb, .ply, .stl, .off, or .ellip, remeshed with the
    /// default options). Relative figures are fractions of its bounding-box diagonal.
    a: PathBuf,
    /// The mesh compared with it (same formats).
    b: PathBuf,
    /// Points sampled uniformly by area on each mesh.
    #[arg(long, default_value_t = DEFAULT_SAMPLES, value_name = "N")]
    samples: usize,
    /// Seed of the sampling (the same seed gives the same figures).
    #[arg(long, default_value_t = CompareOptions::default().seed)]
    seed: u64,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    read: ReadArgs,
}

/// One direction (or the symmetric figures) as reported.
#[derive(Debug, Serialize)]
struct Row {
    hausdorff: f64,
    rms: f64,
    mean: f64,
    /// The same three as fractions of A's bounding-box diagonal.
    hausdorff_relative: f64,
    rms_relative: f64,
    mean_relative: f64,
    /// Degrees, oriented normals.
    normal_deviation_degrees: f64,
    /// Degrees, orientation ignored.
    unsigned_normal_deviation_degrees: f64,
    farthest_point: [f64; 3],
    samples: usize,
    vertices: usize,
}

#[derive(Debug, Serialize)]
struct Report {
    a: MeshSummary,
    b: MeshSummary,
    seed: u64,
    diagonal: f64,
    a_to_b: Row,
    b_to_a: Row,
    symmetric: Row,
}

#[derive(Debug, Serialize)]
struct MeshSummary {
    file: String,
    vertices: usize,
    faces: usize,
}

pub fn run(args: &CompareArgs) -> Result<(), CliError> {
    let a = load_mesh(&args.a, &args.read)?;
    let b = load_mesh(&args.b, &args.read)?;
    let options = CompareOptions {
        samples: args.samples,
        seed: args.seed,
    };
    let c = compare_meshes(&a, &b, &options)?;
    let summary = |path: &Path, mesh: &Mesh| MeshSummary {
        file: path.display().to_string(),
        vertices: mesh.vertex_count(),
        faces: mesh.face_count(),
    };
    let report = Report {
        a: summary(&args.a, &a),
        b: summary(&args.b, &b),
        seed: args.seed,
        diagonal: c.diagonal,
        a_to_b: describe(&c, &c.a_to_b),
        b_to_a: describe(&c, &c.b_to_a),
        symmetric: describe(&c, &c.symmetric),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&report, args.samples);
    }
    Ok(())
}

/// A mesh file through the importer, or a `.ellip` file decoded and remeshed.
fn load_mesh(path: &Path, read: &ReadArgs) -> Result<Mesh, CliError> {
    if let Some(bytes) = read_if_ellip(path)? {
        let in_file = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
        let rep = decode(&bytes, &Limits::default()).map_err(|e| in_file(&e))?;
        let remeshed = remesh(&rep, &RemeshOptions::default()).map_err(|e| in_file(&e))?;
        return Ok(remeshed.mesh);
    }
    Ok(read_mesh(path, &read.import_options()?)?.mesh)
}

fn describe(c: &Comparison, d: &Deviation) -> Row {
    let relative = c.relative(d);
    Row {
        hausdorff: d.distances.hausdorff,
        rms: d.distances.rms,
        mean: d.distances.mean,
        hausdorff_relative: relative.hausdorff,
        rms_relative: relative.rms,
        mean_relative: relative.mean,
        normal_deviation_degrees: d.normal_deviation,
        unsigned_normal_deviation_degrees: d.unsigned_normal_deviation,
        farthest_point: d.farthest.to_array(),
        samples: d.samples,
        vertices: d.vertices,
    }
}

fn print_text(r: &Report, samples: usize) {
    println!(
        "A  {} ({} vertices, {} faces)",
        r.a.file, r.a.vertices, r.a.faces
    );
    println!(
        "B  {} ({} vertices, {} faces)",
        r.b.file, r.b.vertices, r.b.faces
    );
    println!(
        "{samples} area samples per mesh (seed {}) and every vertex for the Hausdorff distance",
        r.seed
    );
    println!(
        "percentages are of A's bounding-box diagonal, {}",
        format_length(r.diagonal)
    );
    println!();
    println!(
        "             {:>21} {:>21} {:>21} {:>12} {:>10}",
        "Hausdorff", "RMS", "mean", "normal dev.", "unsigned"
    );
    for (name, row) in [
        ("A → B", &r.a_to_b),
        ("B → A", &r.b_to_a),
        ("symmetric", &r.symmetric),
    ] {
        let cell = |abs: f64, rel: f64| format!("{} ({:.4}%)", format_length(abs), rel * 100.0);
        println!(
            "{name:<12} {:>21} {:>21} {:>21} {:>11.3}° {:>9.3}°",
            cell(row.hausdorff, row.hausdorff_relative),
            cell(row.rms, row.rms_relative),
            cell(row.mean, row.mean_relative),
            row.normal_deviation_degrees,
            row.unsigned_normal_deviation_degrees
        );
    }
}

/// Four significant digits, in plain notation for everyday magnitudes.
fn format_length(x: f64) -> String {
    if x == 0.0 || (1e-3..1e5).contains(&x.abs()) {
        let digits = if x == 0.0 {
            4
        } else {
            (3 - x.abs().log10().floor() as i32).max(0) as usize
        };
        format!("{x:.digits$}")
    } else {
        format!("{x:.3e}")
    }
}
