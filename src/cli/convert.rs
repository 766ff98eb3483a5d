//! `ellip convert IN OUT`: mesh to mesh, formats chosen by extension; through `.ellip` too.
//!
//! - mesh → mesh: a plain format conversion, or with `--via-ellip` a round trip through a
//!   `.ellip` representation in memory (segment, encode, decode, remesh);
//! - `.ellip` → mesh: the same as `ellip decode`;
//! - mesh → `.ellip`: the same as `ellip encode`.

use super::decode::{output_format, print_report, remesh_and_write, RemeshArgs};
use super::segment::{progress_bar, show_progress, SegmentationArgs};
use super::{refuse_overwriting, shown, CliError, ReadArgs};
use clap::Args;
use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::export::{write_mesh, MeshData};
use ellip::format::{decode, Limits};
use ellip::import::read_mesh;
use ellip::segment::SegmentOptions;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// The file to read: a mesh (.obj, .gltf, .glb, .ply, .stl, .off) or a .ellip file.
    input: PathBuf,
    /// The file to write: a mesh (.obj, .gltf, .glb, .ply) or a .ellip file.
    output: PathBuf,
    /// Mesh to mesh through a .ellip representation in memory: segment (the -k ... options),
    /// encode, decode, remesh (the --vertices ... options).
    #[arg(long)]
    via_ellip: bool,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
    #[command(flatten)]
    segmentation: SegmentationArgs,
    #[command(flatten)]
    remesh: RemeshArgs,
    #[command(flatten)]
    read: ReadArgs,
}

fn is_ellip(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ellip"))
}

pub fn run(args: &ConvertArgs) -> Result<(), CliError> {
    refuse_overwriting(&args.input, &args.output)?;
    let segmentation = args.segmentation.options(false)?;
    let segmenting = args.via_ellip || is_ellip(&args.output);
    if !segmenting && segmentation != SegmentOptions::default() {
        return Err(
            "segmentation options (-k, --tolerance, ...) apply only with --via-ellip or a .ellip output"
                .into(),
        );
    }
    let ellip_bytes = ellip_input(&args.input)?;
    if args.remesh.given() && !(args.via_ellip || ellip_bytes.is_some()) {
        return Err(
            "remeshing options (--vertices, --scheme, --colors) apply only with --via-ellip or a .ellip input"
                .into(),
        );
    }
    if !args.via_ellip && is_ellip(&args.output) && args.remesh.given() {
        return Err("remeshing options do not apply to a .ellip output".into());
    }
    if let Some(bytes) = ellip_bytes {
        if args.via_ellip || is_ellip(&args.output) {
            return Err(format!(
                "{}: already a .ellip file; convert it to a mesh (.glb, .gltf, .obj, .ply)",
                shown(&args.input)
            )
            .into());
        }
        let format = output_format(&args.output)?;
        let rep = decode(&bytes, &Limits::default())
            .map_err(|e| format!("{}: {e}", shown(&args.input)))?;
        let report = remesh_and_write(
            &rep,
            &args.remesh.options(None)?,
            &args.input,
            &args.output,
            format,
            args.remesh.colors,
            args.quiet,
        )?;
        if !args.quiet {
            print_report(&report);
        }
        return Ok(());
    }
    if segmenting {
        return convert_through_ellip(args, segmentation);
    }
    let imported = read_mesh(&args.input, &args.read.import_options()?)?;
    let mesh = &imported.mesh;
    let normals = mesh.vertex_normals();
    write_mesh(
        &args.output,
        &MeshData::from_mesh(mesh).with_normals(&normals),
    )?;
    if !args.quiet {
        let repairs = imported.repairs.describe();
        eprintln!(
            "wrote {} ({} vertices, {} faces){}",
            args.output.display(),
            mesh.vertex_count(),
            mesh.face_count(),
            if repairs.is_empty() {
                String::new()
            } else {
                format!("; on reading: {}", repairs.join("; "))
            }
        );
        for w in &imported.warnings {
            eprintln!("warning: {w}");
        }
    }
    Ok(())
}

/// The bytes of a `.ellip` input (by extension or signature), else `None`.
fn ellip_input(path: &Path) -> Result<Option<Vec<u8>>, CliError> {
    if path.as_os_str() == "-" {
        return Err(
            "convert reads files, not standard input; use `ellip decode -` for a .ellip on stdin"
                .into(),
        );
    }
    super::info::read_if_ellip(path)
}

/// Mesh → `.ellip` (written when the output is one), or mesh → `.ellip` in memory → mesh.
fn convert_through_ellip(args: &ConvertArgs, segment: SegmentOptions) -> Result<(), CliError> {
    let to_ellip = is_ellip(&args.output);
    let format = if to_ellip {
        None
    } else {
        Some(output_format(&args.output)?)
    };
    let remesh_options = args.remesh.options(None)?;
    let imported = read_mesh(&args.input, &args.read.import_options()?)?;
    if !args.quiet {
        for w in &imported.warnings {
            eprintln!("warning: {w}");
        }
    }
    let settings = EncodeSettings {
        segment: args
            .segmentation
            .for_mesh(segment, &imported.mesh, args.quiet),
        ..EncodeSettings::default()
    };
    let bar = progress_bar(args.quiet, &settings.segment);
    let encoded = encode_mesh(&imported.mesh, &settings, &mut |p| show_progress(&bar, &p))?;
    bar.finish_and_clear();
    let Some(format) = format else {
        ellip::format::write_file(&args.output, &encoded.bytes)
            .map_err(|e| format!("{}: {e}", shown(&args.output)))?;
        if !args.quiet {
            eprintln!(
                "wrote {}: {} bytes, {} regions",
                shown(&args.output),
                encoded.bytes.len(),
                encoded.representation.region_count()
            );
        }
        return Ok(());
    };
    let rep = decode(&encoded.bytes, &Limits::default())?;
    let report = remesh_and_write(
        &rep,
        &remesh_options,
        &args.input,
        &args.output,
        format,
        args.remesh.colors,
        args.quiet,
    )?;
    if !args.quiet {
        eprintln!(
            "through .ellip: {} bytes, {} regions",
            encoded.bytes.len(),
            rep.region_count()
        );
        print_report(&report);
    }
    Ok(())
}
