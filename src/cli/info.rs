//! `ellip info MESH`: what a mesh is made of, for people or (`--json`) for scripts.

use super::{CliError, ReadArgs};
use clap::Args;
use ellip::ellipsoid::Sign;
use ellip::format::{consts::MAGIC, decode, inspect, Limits};
use ellip::import::{read_mesh, RepairReport};
use ellip::mesh::curvature::mean_curvature;
use ellip::remesh::assemble::Treatment;
use ellip::Mesh;
use serde::Serialize;
use std::io::Read;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The mesh file (.obj, .gltf, .glb, .ply, .stl, .off) or `.ellip` file (`-`: a `.ellip`
    /// file on standard input).
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
    if let Some(bytes) = read_if_ellip(&args.input)? {
        return describe_ellip(&args.input, &bytes, args.json);
    }
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

/// The bytes of a `.ellip` input (named `.ellip`, starting with its magic, or `-`), else
/// `None`. Reading stops at the decoder's file-size limit plus one byte.
pub(super) fn read_if_ellip(path: &Path) -> Result<Option<Vec<u8>>, CliError> {
    let cap = Limits::default().max_file_bytes + 1;
    let mut bytes = Vec::new();
    if path.as_os_str() == "-" {
        std::io::stdin().lock().take(cap).read_to_end(&mut bytes)?;
        return Ok(Some(bytes));
    }
    let named = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ellip"));
    let io_error = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut file = std::fs::File::open(path).map_err(io_error)?;
    if !named {
        let mut magic = [0u8; 8];
        let n = file.read(&mut magic).map_err(io_error)?;
        if magic[..n] != MAGIC[..] {
            return Ok(None);
        }
        bytes.extend_from_slice(&magic[..n]);
    }
    file.take(cap).read_to_end(&mut bytes).map_err(io_error)?;
    Ok(Some(bytes))
}

/// What `ellip info` reports about a `.ellip` file.
#[derive(Debug, Serialize)]
struct EllipInfo {
    file: String,
    version: String,
    bytes: u64,
    regions: Vec<RegionInfo>,
    arcs: usize,
    arc_points: usize,
    boundary_points: usize,
    cycles: usize,
    grid_bits: u8,
    /// Worst-case distance between a decoded boundary point and the encoded one.
    point_error_bound: f64,
    source_vertices: u64,
    source_faces: u64,
    simplify_tolerance: Option<f64>,
    measured_error: Option<f64>,
    measured_hausdorff: Option<f64>,
    suggested_vertices: Option<u64>,
    /// The remesh hint (`Treatment::code`), if the file has one.
    remesh_hint: Option<u64>,
    sections: Vec<SectionInfo>,
}

#[derive(Debug, Serialize)]
struct RegionInfo {
    sign: &'static str,
    center: [f64; 3],
    radii: [f64; 3],
    rotation: [f64; 4],
    cycles: usize,
}

#[derive(Debug, Serialize)]
struct SectionInfo {
    tag: String,
    stored_bytes: u64,
    raw_bytes: u64,
    compressed: bool,
    known: bool,
}

fn describe_ellip(path: &Path, bytes: &[u8], json: bool) -> Result<(), CliError> {
    let limits = Limits::default();
    let in_file = |e: ellip::format::DecodeError| format!("{}: {e}", path.display());
    let summary = inspect(bytes, &limits).map_err(in_file)?;
    let rep = decode(bytes, &limits).map_err(in_file)?;
    let info = EllipInfo {
        file: path.display().to_string(),
        version: format!("{}.{}", summary.major, summary.minor),
        bytes: summary.total_bytes,
        regions: rep
            .ellipsoids
            .iter()
            .enumerate()
            .map(|(r, e)| RegionInfo {
                sign: match e.sign {
                    Sign::Positive => "positive",
                    Sign::Negative => "negative",
                },
                center: e.center.to_array(),
                radii: e.radii.to_array(),
                rotation: e.rotation.to_array(),
                cycles: rep.cycles.get(r).map_or(0, Vec::len),
            })
            .collect(),
        arcs: summary.arcs,
        arc_points: summary.arc_points,
        boundary_points: summary.points,
        cycles: summary.cycles,
        grid_bits: summary.grid.bits,
        point_error_bound: summary.error_bound,
        source_vertices: summary.metadata.source_vertices,
        source_faces: summary.metadata.source_faces,
        simplify_tolerance: summary.metadata.simplify_tolerance,
        measured_error: summary.metadata.measured_error,
        measured_hausdorff: summary.metadata.measured_hausdorff,
        suggested_vertices: summary.metadata.suggested_vertices,
        remesh_hint: summary.metadata.remesh_hint,
        sections: summary
            .sections
            .iter()
            .map(|s| SectionInfo {
                tag: s.tag.to_string(),
                stored_bytes: s.stored_bytes,
                raw_bytes: s.raw_bytes,
                compressed: s.flags & 1 != 0,
                known: s.known,
            })
            .collect(),
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&info)?);
        return Ok(());
    }
    println!(
        "file            {} (.ellip {}, {} bytes)",
        info.file, info.version, info.bytes
    );
    println!(
        "source          {} vertices, {} faces",
        info.source_vertices, info.source_faces
    );
    println!(
        "boundaries      {} arcs, {} boundary points ({} arc points), {} cycles",
        info.arcs, info.boundary_points, info.arc_points, info.cycles
    );
    println!(
        "point grid      {} bits per axis, worst-case point error {:.3e}",
        info.grid_bits, info.point_error_bound
    );
    if let Some(t) = info.simplify_tolerance {
        println!("simplified to   {t:.3e}");
    }
    if let Some(e) = info.measured_error {
        println!("measured error  RMS {e:.3e} (decoded against the source)");
    }
    if let Some(h) = info.measured_hausdorff {
        println!("                Hausdorff {h:.3e}");
    }
    if let Some(code) = info.remesh_hint {
        match Treatment::from_code(code) {
            Some(t) => println!("remesh hint     {code}: {t}"),
            None => println!("remesh hint     {code} (unknown to this decoder, ignored)"),
        }
    }
    println!("regions         {}", info.regions.len());
    println!("  region  sign  radii                                  cycles");
    for (r, region) in info.regions.iter().enumerate() {
        let [a, b, c] = region.radii;
        println!(
            "  {r:>6}  {}  {a:>12.6} {b:>12.6} {c:>12.6}  {:>6}",
            if region.sign == "positive" { "+" } else { "-" },
            region.cycles
        );
    }
    println!("sections        tag    stored      raw");
    for s in &info.sections {
        println!(
            "                {}  {:>8} {:>8}{}{}",
            s.tag,
            s.stored_bytes,
            s.raw_bytes,
            if s.compressed { "  deflate" } else { "" },
            if s.known { "" } else { "  (unknown, skipped)" }
        );
    }
    Ok(())
}
