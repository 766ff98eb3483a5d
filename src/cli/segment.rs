//! `ellip segment IN -k 12 -o seg.glb`: segment a mesh into ellipsoidal (or, with
//! `--planes`, planar) regions, write it coloured per region, and report how well each
//! region's proxy fits.
//!
//! The output duplicates every vertex once per region it touches, so that each face takes
//! its region's colour (glTF `COLOR_0`, PLY `red green blue alpha`); faces keep their order.
//! OBJ holds no colours: the mesh is written as it is and stderr says so.

use super::{refuse_overwriting, shown, CliError, ReadArgs};
use clap::{Args, ValueEnum};
use ellip::ellipsoid::{Ellipsoid, Sign};
use ellip::export::{write_mesh, MeshData};
use ellip::import::{read_mesh, MeshFormat};
use ellip::preview::palette::{palette, Color};
use ellip::segment::{
    default_region_count, segment_with, EllipsoidMetric, Mode, Plane, PlaneMetric, Progress,
    RegionCount, SegmentOptions, Segmentation, WeightOverrides, DEFAULT_REGIONS,
};
use ellip::Mesh;
use glam::DVec3;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;
use std::collections::HashMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Most worker threads `--threads` accepts.
const MAX_THREADS: usize = 1024;

#[derive(Debug, Args)]
pub struct SegmentArgs {
    /// The mesh to read (.obj, .gltf, .glb, .ply, .stl, .off).
    input: PathBuf,
    /// Write the mesh coloured per region here (.glb, .gltf, .ply; .obj without colours).
    /// Without it, only the statistics are printed.
    #[arg(long, short, value_name = "FILE")]
    output: Option<PathBuf>,
    #[command(flatten)]
    segmentation: SegmentationArgs,
    /// Segment into planes with VSA's L²,¹ metric instead, for comparison; the statistics
    /// then give each vertex's distance to its region's plane.
    #[arg(long)]
    planes: bool,
    /// Print the statistics as JSON (and nothing else on stdout).
    #[arg(long)]
    json: bool,
    /// Print nothing on stderr but errors (no progress bar, no notes).
    #[arg(long, short)]
    quiet: bool,
    #[command(flatten)]
    read: ReadArgs,
}

/// The segmentation's options, shared by `ellip segment` and `ellip encode`.
#[derive(Debug, Args)]
pub struct SegmentationArgs {
    /// Number of regions [default: 12, and one more for each further connected component of
    /// the mesh, which needs a region of its own].
    #[arg(
        long = "regions",
        short = 'k',
        value_name = "N",
        allow_negative_numbers = true
    )]
    regions: Option<i64>,
    /// Instead of -k: as few regions as reach this RMS error, as a fraction of the
    /// bounding-box diagonal (e.g. 0.01) — for `segment`, of the vertices to their
    /// ellipsoids; for `encode`, of the decoded mesh against the input (rate control: the
    /// smallest file that meets it).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    tolerance: Option<f64>,
    /// Most Lloyd iterations after seeding.
    #[arg(long, value_name = "N", default_value_t = 50)]
    iterations: usize,
    /// What the ellipsoids approximate: the surface, or the volume (paper, section 3).
    #[arg(long, value_enum, default_value_t = ModeArg::Surface)]
    mode: ModeArg,
    /// Use only positive ellipsoids (no inner surfaces for concavities).
    #[arg(long)]
    no_negative: bool,
    /// Weight each face's error by its area (the metric as an integral over the surface)
    /// instead of the paper's plain sum over vertices, which lets densely tessellated parts
    /// pull the fits. `encode` falls back to it when no file with the plain sum decodes
    /// clean.
    #[arg(long)]
    area_weighting: bool,
    /// Worker threads [default: all cores]. The result does not depend on it.
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    threads: Option<i64>,
    /// Weight of the Euclidean (radial) distance, α [default: the paper's].
    #[arg(long, value_name = "W", allow_negative_numbers = true)]
    alpha: Option<f64>,
    /// Weight of the normal distance, β [default: the paper's].
    #[arg(long, value_name = "W", allow_negative_numbers = true)]
    beta: Option<f64>,
    /// Weight of the curvature distance, γ [default: the paper's].
    #[arg(long, value_name = "W", allow_negative_numbers = true)]
    gamma: Option<f64>,
    /// Weight of the volume term in volume mode, δ [default: the paper's].
    #[arg(long, value_name = "W", allow_negative_numbers = true)]
    delta: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ModeArg {
    Surface,
    Volume,
}

/// Everything `ellip segment` reports.
#[derive(Debug, Serialize)]
struct Report {
    file: String,
    /// The file written, `null` without `-o`.
    output: Option<String>,
    /// Whether the output holds per-region colours (not for OBJ).
    colored: bool,
    /// "ellipsoid" or "plane".
    proxy: &'static str,
    /// "surface" or "volume" (ellipsoids only).
    #[serde(skip_serializing_if = "Option::is_none")]
    mode: Option<Mode>,
    vertices: usize,
    faces: usize,
    bbox_diagonal: f64,
    iterations: usize,
    seconds: f64,
    /// Sum of the region errors in the segmentation's own metric.
    total_error: f64,
    /// RMS over every region's vertices of the distance to the region's proxy (radial
    /// distance for ellipsoids, distance to the plane for planes), in % of the diagonal.
    /// A vertex shared by several regions counts once in each.
    rms_error_percent: f64,
    regions: Vec<RegionReport>,
}

/// One region's statistics.
#[derive(Debug, Serialize)]
struct RegionReport {
    region: usize,
    faces: usize,
    vertices: usize,
    /// The region's error in the segmentation's metric.
    error: f64,
    /// RMS distance of the region's vertices to its proxy, in % of the diagonal.
    rms_error_percent: f64,
    /// The sRGB colour the region has in the output.
    color: [u8; 3],
    #[serde(flatten)]
    proxy: ProxyReport,
}

/// A region's proxy.
#[derive(Debug, Serialize)]
#[serde(untagged)]
enum ProxyReport {
    Ellipsoid {
        sign: &'static str,
        center: [f64; 3],
        radii: [f64; 3],
        /// Unit quaternion x, y, z, w.
        rotation: [f64; 4],
    },
    Plane {
        point: [f64; 3],
        normal: [f64; 3],
    },
}

pub fn run(args: &SegmentArgs) -> Result<(), CliError> {
    let options = args.segmentation.options(args.planes)?;
    let output_format = match &args.output {
        Some(output) => {
            refuse_overwriting(&args.input, output)?;
            Some(output_format(output)?)
        }
        None => None,
    };
    let imported = read_mesh(&args.input, &args.read.import_options()?)?;
    if !args.quiet {
        for w in &imported.warnings {
            eprintln!("warning: {w}");
        }
    }
    let mesh = &imported.mesh;
    let options = args.segmentation.for_mesh(options, mesh, args.quiet);
    let diagonal = mesh.bounding_box().map_or(0.0, |b| b.diagonal());

    let bar = progress_bar(args.quiet, &options);
    let mut on_progress = |p: Progress| show_progress(&bar, &p);
    let start = Instant::now();
    let (labels, proxies, summary) = if args.planes {
        let metric = PlaneMetric::new(mesh);
        let s = segment_with(mesh, &metric, &options, &mut on_progress)?;
        bar.finish_and_clear();
        let proxies: Vec<ProxyReport> = s.proxies.iter().map(plane_report).collect();
        let rms = region_rms(mesh, &s, |plane: &Plane, p| plane.distance(p));
        (s.labels.clone(), proxies, summarise(&s, rms))
    } else {
        let metric = EllipsoidMetric::new(mesh, &options)?;
        let s = segment_with(mesh, &metric, &options, &mut on_progress)?;
        bar.finish_and_clear();
        let proxies: Vec<ProxyReport> = s.proxies.iter().map(ellipsoid_report).collect();
        let rms = region_rms(mesh, &s, |e: &Ellipsoid, p| e.radial_distance(p));
        (s.labels.clone(), proxies, summarise(&s, rms))
    };
    let seconds = start.elapsed().as_secs_f64();

    let palette = palette(proxies.len());
    let colored = matches!(
        output_format,
        Some(MeshFormat::Glb | MeshFormat::Gltf | MeshFormat::Ply)
    );
    if let (Some(output), Some(format)) = (&args.output, output_format) {
        write_output(mesh, &labels, &palette, output, format)?;
        if !args.quiet && !colored {
            eprintln!(
                "note: {} holds no vertex colours, so the regions are not coloured; write .glb, .gltf or .ply to see them",
                shown(output)
            );
        }
    }

    let percent = |d: f64| {
        if diagonal > 0.0 {
            100.0 * d / diagonal
        } else {
            0.0
        }
    };
    let regions = proxies
        .into_iter()
        .zip(&summary.regions)
        .enumerate()
        .map(|(region, (proxy, r))| RegionReport {
            region,
            faces: r.faces,
            vertices: r.vertices,
            error: r.error,
            rms_error_percent: percent(r.rms),
            color: palette.get(region).map_or([0; 3], |c| c.srgb()),
            proxy,
        })
        .collect();
    let report = Report {
        file: shown(&args.input),
        output: args.output.as_deref().map(shown),
        colored,
        proxy: if args.planes { "plane" } else { "ellipsoid" },
        mode: (!args.planes).then_some(options.mode),
        vertices: mesh.vertex_count(),
        faces: mesh.face_count(),
        bbox_diagonal: diagonal,
        iterations: summary.iterations,
        seconds,
        total_error: summary.total_error,
        rms_error_percent: percent(summary.rms),
        regions,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&report);
    }
    if !args.quiet {
        if let Some(output) = &report.output {
            eprintln!(
                "wrote {output} ({} regions, {} faces)",
                report.regions.len(),
                report.faces
            );
        }
    }
    Ok(())
}

impl SegmentationArgs {
    /// Whether -k/--regions was given.
    pub fn has_regions(&self) -> bool {
        self.regions.is_some()
    }

    /// `options` for `mesh`: when neither -k nor --tolerance was given, the default region
    /// count for it ([`ellip::segment::default_region_count`]: one more region for each
    /// further connected component), said on stderr unless `quiet` when it is not the
    /// usual one.
    pub fn for_mesh(&self, options: SegmentOptions, mesh: &Mesh, quiet: bool) -> SegmentOptions {
        if self.regions.is_some() || self.tolerance.is_some() {
            return options;
        }
        let k = default_region_count(mesh);
        if k != DEFAULT_REGIONS && !quiet {
            if k == mesh.face_count() {
                eprintln!("note: the mesh has only {k} faces: {k} regions, one a face; -k chooses");
            } else {
                eprintln!(
                    "note: the mesh has {} separate components: {k} regions ({DEFAULT_REGIONS}, and one for each further component); -k chooses",
                    mesh.topology().component_count()
                );
            }
        }
        SegmentOptions {
            regions: RegionCount::Fixed(k),
            ..options
        }
    }

    /// The library's options from the command line, each value checked (one-line errors, before
    /// the mesh is read). `planes` says whether the plane metric will be used.
    pub fn options(&self, planes: bool) -> Result<SegmentOptions, CliError> {
        let args = self;
        let regions = match (args.regions, args.tolerance) {
            (Some(_), Some(_)) => {
                return Err("give either -k/--regions or --tolerance, not both".into())
            }
            (Some(k), None) => match usize::try_from(k) {
                Ok(k) if k >= 1 => RegionCount::Fixed(k),
                _ => return Err(format!("-k/--regions must be at least 1, not {k}").into()),
            },
            (None, Some(t)) if t.is_finite() && t > 0.0 => RegionCount::Tolerance(t),
            (None, Some(t)) => {
                return Err(format!(
                    "--tolerance must be a positive fraction of the bounding-box diagonal, not {t}"
                )
                .into())
            }
            (None, None) => SegmentOptions::default().regions,
        };
        let threads = match args.threads {
            None => None,
            Some(n) => match usize::try_from(n) {
                Ok(n) if (1..=MAX_THREADS).contains(&n) => Some(n),
                _ => {
                    return Err(
                        format!("--threads must be between 1 and {MAX_THREADS}, not {n}").into(),
                    )
                }
            },
        };
        let weight = |name: &str, w: Option<f64>| -> Result<Option<f64>, CliError> {
            match w {
                Some(w) if !(w.is_finite() && w >= 0.0) => {
                    Err(format!("--{name} must be a finite weight >= 0, not {w}").into())
                }
                Some(_) if planes => Err(format!(
                    "--{name} weighs the ellipsoid metric; it does not apply to --planes"
                )
                .into()),
                w => Ok(w),
            }
        };
        let weights = WeightOverrides {
            alpha: weight("alpha", args.alpha)?,
            beta: weight("beta", args.beta)?,
            gamma: weight("gamma", args.gamma)?,
            delta: weight("delta", args.delta)?,
        };
        if planes && (args.mode != ModeArg::Surface || args.no_negative || args.area_weighting) {
            return Err(
                "--mode, --no-negative and --area-weighting choose ellipsoids; they do not apply to --planes"
                    .into(),
            );
        }
        Ok(SegmentOptions {
            regions,
            max_iterations: args.iterations,
            weights,
            mode: match args.mode {
                ModeArg::Surface => Mode::Surface,
                ModeArg::Volume => Mode::Volume,
            },
            allow_negative: !args.no_negative,
            area_weighting: args.area_weighting,
            threads,
            ..SegmentOptions::default()
        })
    }
}

/// The output's format, refusing the ones ellip reads but does not write.
fn output_format(output: &Path) -> Result<MeshFormat, CliError> {
    match MeshFormat::from_path(output) {
        Some(f @ (MeshFormat::Obj | MeshFormat::Ply | MeshFormat::Glb | MeshFormat::Gltf)) => Ok(f),
        _ => Err(format!(
            "{}: cannot write this format; segment writes .glb, .gltf, .ply (coloured) or .obj",
            shown(output)
        )
        .into()),
    }
}

/// A progress bar on stderr, hidden when stderr is not a terminal or with `--quiet`.
pub fn progress_bar(quiet: bool, options: &SegmentOptions) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(
        Some(options.max_iterations as u64),
        ProgressDrawTarget::stderr(),
    );
    let style = ProgressStyle::with_template(
        "{spinner} segmenting [{bar:30}] {pos}/{len} iterations, {msg} ({elapsed})",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar())
    .progress_chars("=> ");
    bar.set_style(style);
    bar.set_message("preparing");
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

/// Shows one report of the loop on the bar.
pub fn show_progress(bar: &ProgressBar, p: &Progress) {
    bar.set_position(p.iteration as u64);
    if p.iteration == 0 {
        bar.set_message(format!("seeding: {} regions", p.regions));
    } else {
        bar.set_message(format!(
            "{} regions, error {:.4e} (best {:.4e})",
            p.regions, p.error, p.best_error
        ));
    }
}

/// Per-region numbers for the report.
struct RegionSummary {
    faces: usize,
    vertices: usize,
    error: f64,
    /// RMS distance of the region's vertices to its proxy (model units).
    rms: f64,
}

struct Summary {
    regions: Vec<RegionSummary>,
    iterations: usize,
    total_error: f64,
    /// RMS over all (region, vertex) pairs.
    rms: f64,
}

/// The distances of each region's vertices to its proxy: for each region, its vertex count
/// and the sum of squared distances. A vertex shared by several regions is measured against
/// each of their proxies.
fn region_rms<P>(
    mesh: &Mesh,
    s: &Segmentation<P>,
    distance: impl Fn(&P, DVec3) -> f64,
) -> Vec<(usize, f64)> {
    let mut out = Vec::with_capacity(s.proxies.len());
    let mut seen = vec![u32::MAX; mesh.vertex_count()];
    for (region, faces) in s.faces_by_region().iter().enumerate() {
        let Some(proxy) = s.proxies.get(region) else {
            continue;
        };
        let mut count = 0;
        let mut sum = 0.0;
        for &f in faces {
            let Some(face) = mesh.faces().get(f as usize) else {
                continue;
            };
            for &v in face {
                let (Some(mark), Some(&p)) =
                    (seen.get_mut(v as usize), mesh.positions().get(v as usize))
                else {
                    continue;
                };
                if *mark != region as u32 {
                    *mark = region as u32;
                    count += 1;
                    let d = distance(proxy, p);
                    sum += d * d;
                }
            }
        }
        out.push((count, sum));
    }
    out
}

fn summarise<P>(s: &Segmentation<P>, rms: Vec<(usize, f64)>) -> Summary {
    let by_region = s.faces_by_region();
    let regions = (0..s.proxies.len())
        .map(|r| {
            let (vertices, sum) = rms.get(r).copied().unwrap_or((0, 0.0));
            RegionSummary {
                faces: by_region.get(r).map_or(0, Vec::len),
                vertices,
                error: s.region_errors.get(r).copied().unwrap_or(0.0),
                rms: if vertices > 0 {
                    (sum / vertices as f64).sqrt()
                } else {
                    0.0
                },
            }
        })
        .collect();
    let (count, sum) = rms
        .iter()
        .fold((0usize, 0.0), |(n, s), &(c, x)| (n + c, s + x));
    Summary {
        regions,
        iterations: s.iterations,
        total_error: s.total_error,
        rms: if count > 0 {
            (sum / count as f64).sqrt()
        } else {
            0.0
        },
    }
}

fn ellipsoid_report(e: &Ellipsoid) -> ProxyReport {
    ProxyReport::Ellipsoid {
        sign: match e.sign {
            Sign::Positive => "positive",
            Sign::Negative => "negative",
        },
        center: e.center.to_array(),
        radii: e.radii.to_array(),
        rotation: e.rotation.to_array(),
    }
}

fn plane_report(p: &Plane) -> ProxyReport {
    ProxyReport::Plane {
        point: p.point.to_array(),
        normal: p.normal.to_array(),
    }
}

/// Writes the mesh with each face in its region's colour: every vertex is duplicated once
/// per region that uses it. OBJ, which has no colours, gets the mesh as it is.
fn write_output(
    mesh: &Mesh,
    labels: &[u32],
    palette: &[Color],
    output: &Path,
    format: MeshFormat,
) -> Result<(), CliError> {
    let normals = mesh.vertex_normals();
    let linear = matches!(format, MeshFormat::Glb | MeshFormat::Gltf);
    if format == MeshFormat::Obj {
        write_mesh(output, &MeshData::from_mesh(mesh).with_normals(&normals))?;
        return Ok(());
    }
    let mut index: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.vertex_count() * 5 / 4);
    let mut positions = Vec::with_capacity(mesh.vertex_count());
    let mut vertex_normals = Vec::with_capacity(mesh.vertex_count());
    let mut colors = Vec::with_capacity(mesh.vertex_count());
    let mut triangles = Vec::with_capacity(mesh.face_count());
    for (f, face) in mesh.faces().iter().enumerate() {
        let region = labels.get(f).copied().unwrap_or(0);
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
                vertex_normals.push(normals.get(v as usize).copied().unwrap_or(DVec3::Z));
                colors.push(color);
                // Below the face count times 3, which a Mesh keeps within u32.
                u32::try_from(positions.len() - 1).unwrap_or(u32::MAX)
            });
        }
        triangles.push(triangle);
    }
    let data = MeshData {
        positions: &positions,
        triangles: &triangles,
        normals: Some(&vertex_normals),
        colors: Some(&colors),
    };
    write_mesh(output, &data)?;
    Ok(())
}

fn print_text(r: &Report) {
    println!(
        "mesh        {}: {} vertices, {} faces, diagonal {:.6}",
        r.file, r.vertices, r.faces, r.bbox_diagonal
    );
    let what = match (r.proxy, r.mode) {
        ("plane", _) => "planes (L2,1 metric)".to_string(),
        (_, Some(Mode::Volume)) => "ellipsoids (volume mode)".to_string(),
        _ => "ellipsoids (surface mode)".to_string(),
    };
    println!(
        "segmented   {} {what}, {} iteration(s) in {:.2} s, total error {:.6e}",
        r.regions.len(),
        r.iterations,
        r.seconds,
        r.total_error
    );
    let distance = if r.proxy == "plane" {
        "RMS distance to the plane"
    } else {
        "RMS radial error"
    };
    println!("RMS %       {distance} of each region's vertices, in % of the bounding-box diagonal");
    if r.proxy == "plane" {
        println!(
            "{:>6} {:>7}  {:<29}  {:>7}",
            "region", "faces", "normal", "RMS %"
        );
    } else {
        println!(
            "{:>6} {:>7}  {:<4}  {:<38}  {:>7}",
            "region", "faces", "sign", "radii", "RMS %"
        );
    }
    for g in &r.regions {
        match &g.proxy {
            ProxyReport::Ellipsoid { sign, radii, .. } => println!(
                "{:>6} {:>7}  {:<4}  {:>12.6} {:>12.6} {:>12.6}  {:>7.3}",
                g.region,
                g.faces,
                if *sign == "negative" { "-" } else { "+" },
                radii[0],
                radii[1],
                radii[2],
                g.rms_error_percent
            ),
            ProxyReport::Plane { normal, .. } => println!(
                "{:>6} {:>7}  {:>9.5} {:>9.5} {:>9.5}  {:>7.3}",
                g.region, g.faces, normal[0], normal[1], normal[2], g.rms_error_percent
            ),
        }
    }
    println!(
        "total  {:>7}  {distance} {:.3} %",
        r.faces, r.rms_error_percent
    );
}
