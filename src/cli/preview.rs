//! `ellip preview IN -o out.png`: a picture of what ellip made of a mesh.
//!
//! For a mesh: three panels side by side, the source (grey), its regions (the source's faces
//! in their region colours, with the boundaries between regions) and the decoded mesh (the
//! mesh → `.ellip` → mesh round trip, coloured by region). For a `.ellip` file: the decoded
//! mesh coloured by region, and the same mesh in grey. Every panel is drawn by the same
//! camera ([`ellip::preview`]), so they line up.

use super::segment::{progress_bar, show_progress, SegmentationArgs};
use super::{refuse_overwriting, shown, CliError, ReadArgs};
use clap::Args;
use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, Limits};
use ellip::import::read_mesh;
use ellip::preview::{render, Panel, RenderOptions, MAX_PANEL_SIDE};
use ellip::remesh::{remesh, RemeshOptions, Remeshed};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct PreviewArgs {
    /// The mesh (.obj, .gltf, .glb, .ply, .stl, .off) or .ellip file to show.
    input: PathBuf,
    /// The PNG file to write (written atomically, never over the input).
    #[arg(long, short, value_name = "FILE.png")]
    output: PathBuf,
    /// Size of each panel in pixels, WIDTHxHEIGHT.
    #[arg(long, value_name = "WxH", default_value = "480x480")]
    size: String,
    /// Vertex budget of the decoded mesh [default: the file's suggestion, else 20000].
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    vertices: Option<i64>,
    /// How a mesh is encoded (ignored for a .ellip input).
    #[command(flatten)]
    segmentation: SegmentationArgs,
    /// Print nothing on stderr but errors.
    #[arg(long, short)]
    quiet: bool,
    #[command(flatten)]
    read: ReadArgs,
}

pub fn run(args: &PreviewArgs) -> Result<(), CliError> {
    let (width, height) = parse_size(&args.size)?;
    let is_png = args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        return Err(format!(
            "{}: preview writes PNG images; name the output .png",
            shown(&args.output)
        )
        .into());
    }
    refuse_overwriting(&args.input, &args.output)?;
    let remesh_options = remesh_options(args.vertices)?;
    let options = RenderOptions {
        width,
        height,
        ..RenderOptions::default()
    };
    let mut timings = Vec::new();

    let (image, decoded_error) = match super::info::read_if_ellip(&args.input)? {
        Some(bytes) => {
            let rep = decode(&bytes, &Limits::default())
                .map_err(|e| format!("{}: {e}", shown(&args.input)))?;
            let start = Instant::now();
            let decoded = remesh(&rep, &remesh_options)
                .map_err(|e| format!("{}: cannot remesh: {e}", shown(&args.input)))?;
            timings.push(("remesh", start.elapsed().as_secs_f64()));
            let panels = [
                region_panel("regions", &decoded),
                Panel::plain(
                    format!("decoded: {} triangles", decoded.mesh.face_count()),
                    &decoded.mesh,
                    Some(&decoded.normals),
                ),
            ];
            let start = Instant::now();
            let image = render(&panels, &options)?;
            timings.push(("render", start.elapsed().as_secs_f64()));
            (image, None)
        }
        None => {
            let segment = args.segmentation.options(false)?;
            let imported = read_mesh(&args.input, &args.read.import_options()?)?;
            if !args.quiet {
                for w in &imported.warnings {
                    eprintln!("warning: {w}");
                }
            }
            let mesh = &imported.mesh;
            let settings = EncodeSettings {
                segment: args.segmentation.for_mesh(segment, mesh, args.quiet),
                ..EncodeSettings::default()
            };
            let bar = progress_bar(args.quiet, &settings.segment);
            let start = Instant::now();
            let encoded = encode_mesh(mesh, &settings, &mut |p| show_progress(&bar, &p))?;
            bar.finish_and_clear();
            timings.push(("encode", start.elapsed().as_secs_f64()));
            let regions = encoded.segmentation.region_count();
            // The real decode path: the file's bytes, quantised boundary points and all.
            let start = Instant::now();
            let decoded = decode(&encoded.bytes, &Limits::default())
                .map_err(|e| e.to_string())
                .and_then(|rep| remesh(&rep, &remesh_options).map_err(|e| e.to_string()));
            timings.push(("decode", start.elapsed().as_secs_f64()));
            let mut panels = vec![
                Panel::plain(
                    format!("source: {} triangles", mesh.face_count()),
                    mesh,
                    None,
                ),
                Panel::regions(
                    format!("regions: {regions}, {} bytes", encoded.bytes.len()),
                    mesh,
                    None,
                    &encoded.segmentation.labels,
                ),
            ];
            panels.push(match &decoded {
                Ok(d) => region_panel("decoded", d),
                Err(_) => Panel::empty("decoded: failed"),
            });
            let start = Instant::now();
            let image = render(&panels, &options)?;
            timings.push(("render", start.elapsed().as_secs_f64()));
            (image, decoded.err())
        }
    };
    let start = Instant::now();
    image.write_png(&args.output)?;
    timings.push(("write", start.elapsed().as_secs_f64()));

    if !args.quiet {
        let times: Vec<String> = timings
            .iter()
            .map(|(what, s)| format!("{what} {s:.2} s"))
            .collect();
        eprintln!(
            "wrote {}: {}x{} ({} panels of {width}x{height}); {}",
            shown(&args.output),
            image.width(),
            image.height(),
            image.width() / width,
            times.join(", ")
        );
    }
    match decoded_error {
        None => Ok(()),
        Some(e) => Err(format!(
            "{}: the decoded panel is empty, decoding failed: {e} (the other panels were written)",
            shown(&args.input)
        )
        .into()),
    }
}

/// The decoded mesh coloured by region, titled with its triangle count.
fn region_panel<'a>(title: &str, decoded: &'a Remeshed) -> Panel<'a> {
    Panel::regions(
        format!("{title}: {} triangles", decoded.mesh.face_count()),
        &decoded.mesh,
        Some(&decoded.normals),
        &decoded.face_regions,
    )
}

/// `WxH`, each side 1 to [`MAX_PANEL_SIDE`] pixels.
fn parse_size(size: &str) -> Result<(u32, u32), CliError> {
    let bad = || -> CliError {
        format!("--size must be WIDTHxHEIGHT, each 1 to {MAX_PANEL_SIDE} pixels (e.g. 480x480), not {size}").into()
    };
    let (w, h) = size.split_once(['x', 'X']).ok_or_else(bad)?;
    let side = |s: &str| -> Result<u32, CliError> {
        match s.trim().parse::<u32>() {
            Ok(n) if (1..=MAX_PANEL_SIDE).contains(&n) => Ok(n),
            _ => Err(bad()),
        }
    };
    Ok((side(w)?, side(h)?))
}

/// The remeshing options: the default, with `--vertices` checked.
fn remesh_options(vertices: Option<i64>) -> Result<RemeshOptions, CliError> {
    let vertices = match vertices {
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
    Ok(RemeshOptions {
        vertices,
        ..RemeshOptions::default()
    })
}
