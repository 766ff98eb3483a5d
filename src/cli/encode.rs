//! `ellip encode IN -o OUT.ellip`: segment a mesh and store it as a `.ellip` file.

use super::segment::{progress_bar, show_progress, SegmentationArgs};
use super::{refuse_overwriting, shown, CliError, ReadArgs};
use clap::Args;
use ellip::encode::{
    encode_mesh, encode_to_target, measure_encoding, store_measurement, EncodeSettings, Measured,
    Probe, Target,
};
use ellip::format::{inspect, simplify::DEFAULT_RELATIVE_TOLERANCE, Limits};
use ellip::import::read_mesh;
use ellip::segment::RegionCount;
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct EncodeArgs {
    /// The mesh to read (.obj, .gltf, .glb, .ply, .stl, .off).
    input: PathBuf,
    /// The `.ellip` file to write; `-` writes to standard output.
    #[arg(long, short, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    segmentation: SegmentationArgs,
    /// Bits per axis of the boundary-point grid, 1 to 24; the worst-case point error is half
    /// a grid step, diagonal / (2·(2^B − 1)). Default: the resolution (10 to 16 bits) that
    /// gives the smallest file within the boundary tolerance.
    #[arg(long, value_name = "B")]
    bits: Option<u8>,
    /// Boundary tolerance, as a fraction of the bounding-box diagonal: no stored boundary
    /// point is farther than this from the boundary it stands for (simplification and grid
    /// rounding together). 0 keeps every boundary point.
    #[arg(long, value_name = "FRACTION", default_value_t = DEFAULT_RELATIVE_TOLERANCE)]
    simplify: f64,
    /// Decode the file, compare it with the input and print and store the RMS and Hausdorff
    /// error (shown by `ellip info`).
    #[arg(long)]
    report: bool,
    /// Rate control: the lowest error that fits in this many bytes (searches -k, then the
    /// boundary tolerance at the K that no longer fits; implies --report).
    #[arg(long, value_name = "N")]
    max_bytes: Option<usize>,
    /// Write the segmentation as it is, without decoding the file to check it. By default
    /// the encoder decodes what it wrote and mends each region that does not mesh cleanly:
    /// a boundary that folds in its chart is stored at the mesh's own points, a small region
    /// is dissolved into its neighbours, another is split, and so is a region decoded a
    /// tenth of the diagonal farther from the mesh than its ellipsoid lies (or 2 % farther
    /// in RMS); so the file may
    /// hold more or fewer regions than -k asks for. A file the decoder meshes clean only
    /// after its first boundary treatment names the one that works (a remesh hint, 2 bytes),
    /// so that decoders mesh it once; so does a file that the arcs as stored mesh clean and
    /// closer to the mesh than the first treatment's (where the mesh has creases).
    #[arg(long)]
    no_verify: bool,
    /// Print the report as JSON on stdout (not with `-o -`).
    #[arg(long)]
    json: bool,
    /// Print nothing on stderr but errors.
    #[arg(long, short)]
    quiet: bool,
    #[command(flatten)]
    read: ReadArgs,
}

/// What `ellip encode` reports.
#[derive(Debug, Serialize)]
struct EncodeReport {
    file: String,
    output: String,
    vertices: usize,
    faces: usize,
    regions: usize,
    /// Regions the segmentation was asked for; `regions` differs when the decoder check
    /// split or dissolved some.
    requested_regions: usize,
    /// Rounds of mending the decoder check needed (the name is kept from when every round
    /// split regions).
    split_rounds: usize,
    /// Rounds of mending tried in all (more than split_rounds when none made the file
    /// clean and an earlier one was kept).
    mending_rounds_tried: usize,
    /// The region count the segmentation was raised to when no file at the requested
    /// count decoded clean (null: not raised).
    raised_regions: Option<usize>,
    /// Whether the segmentation was done again with each face's error weighted by its area,
    /// because no file with the plain weighting decoded clean.
    area_weighted: bool,
    /// "clean", "not checked" (--no-verify), or what is still wrong with the decoded file.
    decode_check: String,
    arcs: usize,
    boundary_points: usize,
    points_after_simplification: usize,
    bits: u8,
    bytes: usize,
    input_bytes: u64,
    /// Raw float32 positions and u32 indices: 12 bytes per vertex and per face.
    raw_bytes: u64,
    ratio_to_input: f64,
    ratio_to_raw: f64,
    /// What decoding loses (with --report, --tolerance or --max-bytes).
    error: Option<ErrorReport>,
    /// Encodings rate control tried (0 without it).
    rate_control_probes: usize,
    /// Those encodings, in order (empty without rate control).
    rate_control: Vec<ProbeReport>,
    sections: Vec<SectionReport>,
}

/// One encoding rate control tried ([`ellip::encode::Probe`]).
#[derive(Debug, Serialize)]
struct ProbeReport {
    /// Regions asked for.
    regions: usize,
    /// Boundary tolerance, as a fraction of the bounding-box diagonal.
    boundary_tolerance: f64,
    /// File size with the measurement stored.
    bytes: usize,
    /// Measured RMS error as a fraction of the diagonal.
    rms_fraction: f64,
    /// Whether the file decodes clean (or was not checked).
    clean: bool,
    /// Whether it is the further searches' file at an earlier probe's setting.
    searched_again: bool,
}

impl From<&Probe> for ProbeReport {
    fn from(p: &Probe) -> Self {
        ProbeReport {
            regions: p.regions,
            boundary_tolerance: p.boundary_tolerance,
            bytes: p.bytes,
            rms_fraction: p.rms,
            clean: p.clean,
            searched_again: p.searched_again,
        }
    }
}

/// The measured error of the decoded file against the input, symmetric.
#[derive(Debug, Serialize)]
struct ErrorReport {
    rms: f64,
    hausdorff: f64,
    rms_fraction: f64,
    hausdorff_fraction: f64,
    normal_deviation_degrees: f64,
}

#[derive(Debug, Serialize)]
struct SectionReport {
    tag: String,
    stored_bytes: u64,
    raw_bytes: u64,
}

pub fn run(args: &EncodeArgs) -> Result<(), CliError> {
    let to_stdout = args.output.as_os_str() == "-";
    if to_stdout && args.json {
        return Err("--json prints on stdout; it cannot go with -o -".into());
    }
    if !to_stdout {
        refuse_overwriting(&args.input, &args.output)?;
    }
    if !(args.simplify.is_finite() && args.simplify >= 0.0) {
        return Err(format!("--simplify must be a fraction >= 0, not {}", args.simplify).into());
    }
    let mut settings = EncodeSettings {
        segment: args.segmentation.options(false)?,
        simplify_tolerance: args.simplify,
        bits: args.bits,
        verify: !args.no_verify,
        ..EncodeSettings::default()
    };
    let imported = read_mesh(&args.input, &args.read.import_options()?)?;
    if !args.quiet {
        for w in &imported.warnings {
            eprintln!("warning: {w}");
        }
    }
    let mesh = &imported.mesh;
    // --max-bytes searches the region count itself.
    if args.max_bytes.is_none() {
        settings.segment = args
            .segmentation
            .for_mesh(settings.segment, mesh, args.quiet);
    }
    // Rate control: --tolerance (the decoded RMS error) or --max-bytes search -k.
    let target = match (settings.segment.regions, args.max_bytes) {
        (RegionCount::Tolerance(_), Some(_)) => {
            return Err("give either --tolerance or --max-bytes, not both".into())
        }
        (RegionCount::Tolerance(t), None) => Some(Target::Rms(t)),
        (RegionCount::Fixed(_), Some(_)) if args.segmentation.has_regions() => {
            return Err("give either -k/--regions or --max-bytes, not both".into())
        }
        (_, Some(0)) => return Err("--max-bytes must be at least 1".into()),
        (_, Some(n)) => Some(Target::MaxBytes(n)),
        _ => None,
    };
    let (encoded, bytes, measured, probes) = match target {
        Some(target) => {
            let quiet = args.quiet;
            let rc = encode_to_target(mesh, &settings, target, &mut |p: &Probe| {
                if !quiet {
                    eprintln!(
                        "  {} K = {:>3}, boundary tolerance {:.1e}: {} bytes, RMS {:.4}% of the diagonal{}",
                        if p.searched_again { "searched again at" } else { "tried" },
                        p.regions,
                        p.boundary_tolerance,
                        p.bytes,
                        100.0 * p.rms,
                        if p.clean { "" } else { ", not clean" }
                    );
                }
            })?;
            (rc.encoded, rc.bytes, Some(rc.measured), rc.probes)
        }
        None => {
            let bar = progress_bar(args.quiet, &settings.segment);
            let encoded = encode_mesh(mesh, &settings, &mut |p| show_progress(&bar, &p))?;
            bar.finish_and_clear();
            if args.report {
                let measured = measure_encoding(mesh, &encoded.bytes, settings.segment.threads)?;
                let bytes = store_measurement(&encoded, &measured)?;
                (encoded, bytes, Some(measured), Vec::new())
            } else {
                let bytes = encoded.bytes.clone();
                (encoded, bytes, None, Vec::new())
            }
        }
    };

    if to_stdout {
        let mut out = std::io::stdout().lock();
        out.write_all(&bytes)?;
        out.flush()?;
    } else {
        ellip::format::write_file(&args.output, &bytes)?;
    }

    let summary = inspect(&bytes, &Limits::default())?;
    let input_bytes = std::fs::metadata(&args.input).map_or(0, |m| m.len());
    let raw_bytes = 12 * (mesh.vertex_count() + mesh.face_count()) as u64;
    let bytes = bytes.len();
    let report = EncodeReport {
        file: shown(&args.input),
        output: shown(&args.output),
        vertices: mesh.vertex_count(),
        faces: mesh.face_count(),
        regions: summary.regions,
        requested_regions: encoded.verification.requested_regions,
        split_rounds: encoded.verification.rounds,
        mending_rounds_tried: encoded.verification.tried,
        raised_regions: encoded.verification.raised_regions,
        area_weighted: encoded.verification.area_weighted,
        decode_check: match (&encoded.verification.problem, args.no_verify) {
            (_, true) => "not checked".into(),
            (None, false) => "clean".into(),
            (Some(p), false) => p.clone(),
        },
        arcs: summary.arcs,
        boundary_points: encoded.boundary_points,
        points_after_simplification: summary.points,
        bits: encoded.bits,
        bytes,
        input_bytes,
        raw_bytes,
        ratio_to_input: input_bytes as f64 / bytes as f64,
        ratio_to_raw: raw_bytes as f64 / bytes as f64,
        error: measured.map(|m: Measured| ErrorReport {
            rms: m.rms,
            hausdorff: m.hausdorff,
            rms_fraction: m.rms / m.diagonal,
            hausdorff_fraction: m.hausdorff / m.diagonal,
            normal_deviation_degrees: m.normal_deviation,
        }),
        rate_control_probes: probes.len(),
        rate_control: probes.iter().map(ProbeReport::from).collect(),
        sections: summary
            .sections
            .iter()
            .map(|s| SectionReport {
                tag: s.tag.to_string(),
                stored_bytes: s.stored_bytes,
                raw_bytes: s.raw_bytes,
            })
            .collect(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else if !args.quiet {
        print_report(&report);
    }
    if let (Some(problem), false) = (&encoded.verification.problem, args.quiet) {
        let v = &encoded.verification;
        let kept = if v.rounds == v.tried {
            String::new()
        } else {
            format!(" (the file kept is round {}'s)", v.rounds)
        };
        eprintln!(
            "warning: {}: the file {problem} at its default density, even after {} rounds of \
             mending regions{kept}",
            report.output, v.tried
        );
    }
    Ok(())
}

/// The report in words, on stderr (stdout may carry the file).
fn print_report(r: &EncodeReport) {
    eprintln!(
        "wrote {}: {} bytes — {} regions, {} arcs, {} boundary points ({} before simplification), {} bits",
        r.output, r.bytes, r.regions, r.arcs, r.points_after_simplification, r.boundary_points, r.bits
    );
    if r.area_weighted {
        eprintln!(
            "no file with the plain metric decoded clean: segmented again with each face's error weighted by its area"
        );
    }
    if let Some(raised) = r.raised_regions {
        eprintln!(
            "{} regions asked for, but no file with them decoded clean: segmented again into {raised}",
            r.requested_regions
        );
    }
    if r.regions != r.raised_regions.unwrap_or(r.requested_regions) {
        eprintln!(
            "{} regions asked for, {} stored: {} round(s) mended the regions the decoder could not mesh cleanly",
            r.raised_regions.unwrap_or(r.requested_regions),
            r.regions,
            r.split_rounds
        );
    }
    eprintln!(
        "ratio {:.1}:1 to the input file ({} bytes), {:.1}:1 to raw float32 positions + u32 indices ({} bytes)",
        r.ratio_to_input, r.input_bytes, r.ratio_to_raw, r.raw_bytes
    );
    if let Some(e) = &r.error {
        eprintln!(
            "decoded error: RMS {:.4}%, Hausdorff {:.4}% of the diagonal, normals {:.2}° (stored in the file)",
            100.0 * e.rms_fraction,
            100.0 * e.hausdorff_fraction,
            e.normal_deviation_degrees
        );
    }
    let sections: Vec<String> = r
        .sections
        .iter()
        .map(|s| format!("{} {}", s.tag, s.stored_bytes))
        .collect();
    eprintln!(
        "payload bytes per section: {} (+ 28 header, 20 per section)",
        sections.join(", ")
    );
}
