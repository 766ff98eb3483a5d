//! `ellip decode IN.ellip -o OUT.glb`: a `.ellip` file back to a triangle mesh (issue 6).
//!
//! Decodes the file (every check of `spec/ELLIP.md`), remeshes it ([`ellip::remesh`]) at the
//! asked vertex budget and writes the mesh with its analytic normals, atomically. With
//! `--colors`, each region gets its colour of the palette `ellip segment` uses; colours are
//! per vertex, so the vertices on a boundary between regions are written once per region
//! (the file then holds one open piece per region; without `--colors` it is one watertight
//! mesh).

use super::{refuse_overwriting, shown, CliError};
use clap::{Args, ValueEnum};
use ellip::export::{write_mesh, MeshData};
use ellip::format::{decode, Limits};
use ellip::import::MeshFormat;
use ellip::preview::palette::palette;
use ellip::remesh::assemble::{triangle_faults_note, BUDGET_MET};
use ellip::remesh::{remesh, RemeshOptions, Remeshed, Scheme};
use ellip::representation::Representation;
use glam::DVec3;
use serde::Serialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, Args)]
pub struct DecodeArgs {
    /// The `.ellip` file to read; `-` reads standard input.
    input: PathBuf,
    /// The mesh to write (.glb, .gltf, .obj, .ply).
    #[arg(long, short, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    remesh: RemeshArgs,
    /// Stop adding vertices once every region is this close to its ellipsoid, as a fraction
    /// of the bounding-box diagonal of the boundary points (e.g. 0.001); the vertex budget
    /// still applies.
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    tolerance: Option<f64>,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Print nothing on stderr but errors.
    #[arg(long, short)]
    quiet: bool,
}

/// The remeshing options shared by `ellip decode` and `ellip convert`.
#[derive(Debug, Args)]
pub struct RemeshArgs {
    /// Total vertex budget of the output, shared among regions by their error [default:
    /// the file's suggestion, else 20000].
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    vertices: Option<i64>,
    /// How region interiors are meshed: iterative vertex addition where the error is largest
    /// (adaptive), or a regular grid on the unit sphere (parametric).
    #[arg(long, value_enum, default_value_t = SchemeArg::Adaptive)]
    scheme: SchemeArg,
    /// Place every vertex by adaptive vertex addition. By default a budget of 20000 vertices
    /// or more (and 256 per region) is met by meshing adaptively at a quarter (or a
    /// sixteenth, a sixty-fourth) of it and splitting every triangle into four, several times
    /// faster for the same error.
    #[arg(long)]
    no_subdivision: bool,
    /// Fail when a region cannot be meshed, instead of leaving it out (a hole) with a
    /// warning.
    #[arg(long)]
    no_holes: bool,
    /// Colour each region (.glb, .gltf, .ply; not .obj).
    #[arg(long)]
    pub colors: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SchemeArg {
    Adaptive,
    Parametric,
}

impl RemeshArgs {
    /// Whether any remeshing option was given.
    pub fn given(&self) -> bool {
        self.vertices.is_some()
            || self.scheme != SchemeArg::Adaptive
            || self.colors
            || self.no_subdivision
            || self.no_holes
    }

    /// The library's options (checked; `tolerance` as given on the command line).
    pub fn options(&self, tolerance: Option<f64>) -> Result<RemeshOptions, CliError> {
        let vertices = match self.vertices {
            None => None,
            Some(n) => match usize::try_from(n) {
                Ok(n) if (1..=ellip::remesh::MAX_VERTICES).contains(&n) => Some(n),
                _ => {
                    return Err(format!(
                        "--vertices must be between 1 and {}, not {n}",
                        ellip::remesh::MAX_VERTICES
                    )
                    .into())
                }
            },
        };
        if let Some(t) = tolerance {
            if !(t.is_finite() && t > 0.0) {
                return Err(format!(
                    "--tolerance must be a positive fraction of the bounding-box diagonal, not {t}"
                )
                .into());
            }
        }
        Ok(RemeshOptions {
            vertices,
            tolerance,
            scheme: match self.scheme {
                SchemeArg::Adaptive => Scheme::Adaptive,
                SchemeArg::Parametric => Scheme::Parametric,
            },
            subdivision: !self.no_subdivision,
            leave_out: !self.no_holes,
            ..RemeshOptions::default()
        })
    }
}

/// What `ellip decode` reports.
#[derive(Debug, Serialize)]
pub struct DecodeReport {
    file: String,
    output: String,
    scheme: &'static str,
    regions: usize,
    vertices: usize,
    /// The vertex budget asked for ([`RemeshOptions::budget`]: the option, else the file's
    /// suggestion or source vertex count, else the default).
    vertex_budget: usize,
    triangles: usize,
    /// Every edge has exactly two faces (of the mesh before any colouring split).
    closed: bool,
    manifold: bool,
    border_loops: usize,
    degenerate_triangles: usize,
    flipped_triangles: usize,
    /// The regions left out because they could not be meshed (holes in the mesh), in
    /// increasing order.
    omitted_regions: Vec<u32>,
    /// The regions with no face that were not left out: every boundary loop of theirs
    /// encloses nothing ([`Remeshed::faceless_regions`]), in increasing order.
    empty_regions: Vec<u32>,
    /// The regions with flipped or degenerate triangles, each with its counts, in
    /// increasing order ([`ellip::remesh::Remeshed::faulty_regions`]; they add up to
    /// `flipped_triangles` and `degenerate_triangles`).
    faulty_regions: Vec<FaultyRegion>,
    colored: bool,
    /// How many times the regions were meshed ([`Remeshed::attempts`]).
    meshing_attempts: usize,
    /// The boundary treatment the mesh was made with ([`Remeshed::treatment`], as
    /// `Treatment::code`: what a file's remesh hint would name).
    treatment: Option<u64>,
    seconds: f64,
}

/// A region with flipped or degenerate triangles, in [`DecodeReport`].
#[derive(Debug, Serialize)]
pub struct FaultyRegion {
    region: u32,
    flipped_triangles: usize,
    degenerate_triangles: usize,
}

pub fn run(args: &DecodeArgs) -> Result<(), CliError> {
    let options = args.remesh.options(args.tolerance)?;
    let from_stdin = args.input.as_os_str() == "-";
    if !from_stdin {
        refuse_overwriting(&args.input, &args.output)?;
    }
    let format = output_format(&args.output)?;
    let bytes = read_ellip(&args.input)?;
    let rep =
        decode(&bytes, &Limits::default()).map_err(|e| format!("{}: {e}", shown(&args.input)))?;
    let report = remesh_and_write(
        &rep,
        &options,
        &args.input,
        &args.output,
        format,
        args.remesh.colors,
        args.quiet,
    )?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else if !args.quiet {
        print_report(&report);
    }
    Ok(())
}

/// The bytes of a `.ellip` input, or of standard input for `-`.
fn read_ellip(path: &Path) -> Result<Vec<u8>, CliError> {
    super::info::read_if_ellip(path)?.ok_or_else(|| {
        format!(
            "{}: not a .ellip file (it does not start with the .ellip signature)",
            shown(path)
        )
        .into()
    })
}

/// The output's format, refusing the ones ellip reads but does not write.
pub fn output_format(output: &Path) -> Result<MeshFormat, CliError> {
    match MeshFormat::from_path(output) {
        Some(f @ (MeshFormat::Obj | MeshFormat::Ply | MeshFormat::Glb | MeshFormat::Gltf)) => Ok(f),
        _ => Err(format!(
            "{}: cannot write this format; write .glb, .gltf, .obj or .ply",
            shown(output)
        )
        .into()),
    }
}

/// Remeshes `rep`, writes the mesh to `output` and says what was made; notes on standard
/// error (unless `quiet`) a mesh that is not clean, regions left out and a mesh short of
/// its budget (below [`BUDGET_MET`] of it).
pub fn remesh_and_write(
    rep: &Representation,
    options: &RemeshOptions,
    input: &Path,
    output: &Path,
    format: MeshFormat,
    colors: bool,
    quiet: bool,
) -> Result<DecodeReport, CliError> {
    let start = Instant::now();
    let remeshed = remesh(rep, options).map_err(|e| format!("{}: {e}", shown(input)))?;
    let seconds = start.elapsed().as_secs_f64();
    let colored = colors && format != MeshFormat::Obj;
    if colors && !colored && !quiet {
        eprintln!(
            "note: {} holds no vertex colours, so the regions are not coloured; write .glb, .gltf or .ply to see them",
            shown(output)
        );
    }
    if colored {
        write_colored(&remeshed, rep.region_count(), output, format)?;
    } else {
        let data = MeshData::from_mesh(&remeshed.mesh).with_normals(&remeshed.normals);
        write_mesh(output, &data)?;
    }
    let check = remeshed.check;
    let faulty = remeshed.faulty_regions(rep);
    if !quiet && !check.is_clean() {
        eprintln!(
            "warning: the mesh is not clean: {}{}",
            check.faults(),
            triangle_faults_note(&faulty)
        );
    }
    let budget = options.budget(rep);
    let vertices = remeshed.mesh.vertex_count();
    let short = (vertices as f64) < BUDGET_MET * budget as f64;
    if !quiet && options.tolerance.is_none() && remeshed.omitted.is_empty() && short {
        eprintln!(
            "note: {vertices} vertices, short of the budget of {budget}: {}",
            match options.scheme {
                Scheme::Adaptive =>
                    "the regions take no more (nearly flat regions, boundaries far off their ellipsoids)",
                Scheme::Parametric =>
                    "the parametric grid's count follows the regions' shapes (the adaptive scheme meets the budget)",
            }
        );
    }
    if !quiet && !remeshed.omitted.is_empty() {
        let listed: Vec<String> = remeshed.omitted.iter().map(u32::to_string).collect();
        eprintln!(
            "warning: region(s) {} could not be meshed and were left out, leaving holes (--no-holes fails instead)",
            listed.join(", ")
        );
    }
    let empty = remeshed.faceless_regions(rep.region_count());
    if !quiet && !empty.is_empty() {
        let listed: Vec<String> = empty.iter().map(u32::to_string).collect();
        eprintln!(
            "note: region(s) {} have no face: every boundary loop of theirs encloses nothing once its points are quantised (right for a region a few grid steps across; a larger one is lost from this file)",
            listed.join(", ")
        );
    }
    Ok(DecodeReport {
        file: shown(input),
        output: shown(output),
        scheme: match options.scheme {
            Scheme::Adaptive => "adaptive",
            Scheme::Parametric => "parametric",
        },
        regions: rep.region_count(),
        vertices,
        vertex_budget: budget,
        triangles: remeshed.mesh.face_count(),
        closed: check.closed,
        manifold: check.manifold,
        border_loops: check.border_loops,
        degenerate_triangles: check.degenerate,
        flipped_triangles: check.flipped,
        omitted_regions: remeshed.omitted.clone(),
        empty_regions: empty,
        faulty_regions: faulty
            .into_iter()
            .map(|f| FaultyRegion {
                region: f.region,
                flipped_triangles: f.flipped,
                degenerate_triangles: f.degenerate,
            })
            .collect(),
        colored,
        meshing_attempts: remeshed.attempts,
        treatment: remeshed.treatment.map(|t| t.code()),
        seconds,
    })
}

/// The report in words, on stderr.
pub fn print_report(r: &DecodeReport) {
    eprintln!(
        "wrote {}: {} vertices, {} triangles, {} regions ({}), {}{}, in {:.2} s{}",
        r.output,
        r.vertices,
        r.triangles,
        r.regions,
        r.scheme,
        if r.closed {
            "closed".to_string()
        } else {
            format!("open ({} border loops)", r.border_loops)
        },
        if r.colored {
            ", coloured per region"
        } else {
            ""
        },
        r.seconds,
        match r.meshing_attempts {
            0 | 1 => String::new(),
            n => format!(" ({n} meshing attempts)"),
        }
    );
}

/// Writes the mesh with each face in its region's colour: a vertex is written once per
/// region that uses it.
fn write_colored(
    remeshed: &Remeshed,
    regions: usize,
    output: &Path,
    format: MeshFormat,
) -> Result<(), CliError> {
    let palette = palette(regions);
    let linear = matches!(format, MeshFormat::Glb | MeshFormat::Gltf);
    let mesh = &remeshed.mesh;
    let mut index: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.vertex_count() * 5 / 4);
    let mut positions = Vec::with_capacity(mesh.vertex_count());
    let mut normals = Vec::with_capacity(mesh.vertex_count());
    let mut colors = Vec::with_capacity(mesh.vertex_count());
    let mut triangles = Vec::with_capacity(mesh.face_count());
    for (f, face) in mesh.faces().iter().enumerate() {
        let region = remeshed.face_regions.get(f).copied().unwrap_or(0);
        let color = palette
            .get(region as usize)
            .map_or([128, 128, 128, 255], |c| {
                if linear {
                    c.linear_rgba()
                } else {
                    c.srgb_rgba()
                }
            });
        let mut triangle = [0u32; 3];
        for (corner, &v) in triangle.iter_mut().zip(face) {
            *corner = *index.entry((region, v)).or_insert_with(|| {
                positions.push(
                    mesh.positions()
                        .get(v as usize)
                        .copied()
                        .unwrap_or_default(),
                );
                normals.push(
                    remeshed
                        .normals
                        .get(v as usize)
                        .copied()
                        .unwrap_or(DVec3::Z),
                );
                colors.push(color);
                u32::try_from(positions.len() - 1).unwrap_or(u32::MAX)
            });
        }
        triangles.push(triangle);
    }
    let data = MeshData {
        positions: &positions,
        triangles: &triangles,
        normals: Some(&normals),
        colors: Some(&colors),
    };
    write_mesh(output, &data)?;
    Ok(())
}
