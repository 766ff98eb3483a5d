//! `ellip info MESH`: what a mesh is made of, for people or (`--json`) for scripts.

use super::{CliError, ReadArgs};
use clap::Args;
use ellip::import::{read_mesh, RepairReport};
use ellip::mesh::curvature::mean_curvature;
use ellip::Mesh;
use serde::Serialize;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The mesh file (.obj, .gltf, .glb, .ply, .stl, .off).
    input: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    read: ReadArgs,
}

/// Everything `ellip info` reports about a mesh.
#[derive(Debug, Serialize)]
struct MeshInfo {
    file: String,
    format: &'static str,
    file_bytes: u64,
    vertices: usize,
    faces: usize,
    edges: usize,
    components: usize,
    boundary_loops: usize,
    closed: bool,
    manifold: bool,
    consistently_oriented: bool,
    /// `null` where the genus is not defined (non-manifold or non-orientable).
    genus: Option<u64>,
    bbox_min: [f64; 3],
    bbox_max: [f64; 3],
    bbox_diagonal: f64,
    area: f64,
    /// `null` unless the mesh is closed.
    volume: Option<f64>,
    average_edge_length: f64,
    curvature: CurvatureRange,
    repairs: RepairReport,
    warnings: Vec<String>,
}

/// Range of the per-vertex mean curvature. Percentiles are reported beside the extremes
/// because the extremes of a discrete estimate sit on a few noisy vertices.
#[derive(Debug, Serialize)]
struct CurvatureRange {
    min: f64,
    p01: f64,
    median: f64,
    p99: f64,
    max: f64,
}

pub fn run(args: &InfoArgs) -> Result<(), CliError> {
    let imported = read_mesh(&args.input, &args.read.import_options()?)?;
    let file_bytes = std::fs::metadata(&args.input)?.len();
    let info = describe(
        &imported.mesh,
        args.input.display().to_string(),
        imported.format.name(),
        file_bytes,
        imported.repairs,
        imported.warnings,
    );
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        print_text(&info);
    }
    Ok(())
}

fn describe(
    mesh: &Mesh,
    file: String,
    format: &'static str,
    file_bytes: u64,
    repairs: RepairReport,
    warnings: Vec<String>,
) -> MeshInfo {
    let t = mesh.topology();
    let bbox = mesh.bounding_box().expect("an imported mesh has vertices");
    MeshInfo {
        file,
        format,
        file_bytes,
        vertices: mesh.vertex_count(),
        faces: mesh.face_count(),
        edges: t.edge_count(),
        components: t.component_count(),
        boundary_loops: t.boundary_loops().len(),
        closed: t.is_closed(),
        manifold: t.is_manifold(),
        consistently_oriented: t.is_consistently_oriented(),
        genus: mesh.genus(),
        bbox_min: bbox.min.to_array(),
        bbox_max: bbox.max.to_array(),
        bbox_diagonal: bbox.diagonal(),
        area: mesh.area(),
        volume: mesh.volume(),
        average_edge_length: mesh.average_edge_length(),
        curvature: curvature_range(&mean_curvature(mesh)),
        repairs,
        warnings,
    }
}

fn curvature_range(values: &[f64]) -> CurvatureRange {
    let mut sorted = values.to_vec();
    sorted.sort_unstable_by(f64::total_cmp);
    let at = |q: f64| {
        if sorted.is_empty() {
            0.0
        } else {
            sorted[((sorted.len() - 1) as f64 * q).round() as usize]
        }
    };
    CurvatureRange {
        min: at(0.0),
        p01: at(0.01),
        median: at(0.5),
        p99: at(0.99),
        max: at(1.0),
    }
}

fn print_text(i: &MeshInfo) {
    let yes = |b: bool| if b { "yes" } else { "no" };
    println!(
        "file            {} ({}, {} bytes)",
        i.file, i.format, i.file_bytes
    );
    println!(
        "size            {} vertices, {} faces, {} edges",
        i.vertices, i.faces, i.edges
    );
    println!(
        "topology        {} component(s), {} boundary loop(s), genus {}",
        i.components,
        i.boundary_loops,
        i.genus.map_or("n/a".to_string(), |g| g.to_string())
    );
    println!(
        "                closed: {}, manifold: {}, consistently oriented: {}",
        yes(i.closed),
        yes(i.manifold),
        yes(i.consistently_oriented)
    );
    let [x0, y0, z0] = i.bbox_min;
    let [x1, y1, z1] = i.bbox_max;
    println!("bounding box    [{x0:.6}, {y0:.6}, {z0:.6}] .. [{x1:.6}, {y1:.6}, {z1:.6}]");
    println!("                diagonal {:.6}", i.bbox_diagonal);
    println!(
        "area / volume   {:.6} / {}",
        i.area,
        i.volume
            .map_or("n/a (not closed)".into(), |v| format!("{v:.6}"))
    );
    println!("average edge    {:.6}", i.average_edge_length);
    let c = &i.curvature;
    println!(
        "mean curvature  min {:.4}, 1% {:.4}, median {:.4}, 99% {:.4}, max {:.4}",
        c.min, c.p01, c.median, c.p99, c.max
    );
    let repairs = i.repairs.describe();
    if repairs.is_empty() {
        println!("repairs         none");
    } else {
        println!("repairs         {}", repairs.join("; "));
    }
    for w in &i.warnings {
        println!("warning         {w}");
    }
}
