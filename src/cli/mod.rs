//! Argument definitions and dispatch for the `ellip` binary.

mod compare;
mod convert;
mod decode;
mod encode;
mod fixtures;
mod info;
mod preview;
mod segment;

use clap::{Args, Parser, Subcommand};
use ellip::import::{ImportOptions, Weld};

/// The error type of every subcommand: shown to the user as one line.
pub type CliError = Box<dyn std::error::Error + Send + Sync>;

const EXAMPLES: &str = "\
Examples:
  ellip info fixtures/meshes/blob1.obj          describe a mesh: size, topology, curvature, repairs
  ellip info bunny.ply --json                   the same as JSON, for scripts
  ellip convert scan.stl scan.glb               convert between OBJ, glTF/GLB, PLY, STL and OFF
  ellip convert part.obj part.ply --weld 1e-6   join vertices closer than 1e-6 on the way
  ellip segment bunny.obj -k 12 -o seg.glb      12 ellipsoidal regions, coloured, with statistics
  ellip encode hand.obj -k 18 -o hand.ellip     store 18 ellipsoidal regions in a few kilobytes
  ellip info hand.ellip                         version, regions, arcs, bytes per section
  ellip decode hand.ellip -o hand.glb           back to a watertight mesh (20000 vertices by default)
  ellip decode hand.ellip -o hand.ply --vertices 100000 --colors
  ellip convert bunny.obj bunny.glb --via-ellip -k 24   mesh → .ellip → mesh in one step
  ellip compare hand.obj hand2.obj              Hausdorff, RMS and mean distance, normal deviation
  ellip preview bunny.obj -k 12 -o bunny.png    source, regions and decoded mesh side by side";

/// ellip: dense triangle meshes as a few dozen ellipsoidal regions.
#[derive(Debug, Parser)]
#[command(name = "ellip", version, about, after_help = EXAMPLES)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Describe a mesh: counts, topology, bounding box, volume, curvature, repairs made.
    #[command(after_help = "Example:\n  ellip info fixtures/meshes/torus.obj --json")]
    Info(info::InfoArgs),
    /// Convert a mesh between formats, chosen by the files' extensions; or through .ellip.
    ///
    /// Reads .obj, .gltf, .glb, .ply, .stl and .off; writes .obj, .gltf (+ .bin), .glb and
    /// .ply. A .ellip input is decoded and remeshed (as `decode`), a .ellip output is
    /// encoded (as `encode`), and `--via-ellip` goes mesh → .ellip → mesh in memory. The
    /// output is written atomically and never replaces the input.
    #[command(
        after_help = "Examples:\n  ellip convert fixtures/meshes/torus.obj torus.glb\n  ellip convert fixtures/meshes/blob2.obj blob2.glb --via-ellip -k 4 --vertices 5000\n  ellip convert blob2.ellip blob2.ply --colors"
    )]
    Convert(convert::ConvertArgs),
    /// Segment a mesh into ellipsoidal regions (or planes) and write it coloured per region.
    ///
    /// Prints, for each region, its faces, the ellipsoid's sign and radii and the RMS radial
    /// error of its vertices (in % of the bounding-box diagonal). Writes .glb, .gltf or .ply
    /// with per-region vertex colours (.obj without colours), atomically, never over the input.
    #[command(
        after_help = "Examples:\n  ellip segment fixtures/meshes/blob2.obj -k 4 -o blob2-regions.glb\n  ellip segment bunny.obj --tolerance 0.01 --mode volume --json\n  ellip segment bunny.obj -k 12 --planes -o planes.ply"
    )]
    Segment(segment::SegmentArgs),
    /// Encode a mesh as a `.ellip` file: ellipsoidal regions and the boundaries between them.
    ///
    /// Segments the mesh (the same options as `segment`), smooths and simplifies the
    /// boundaries, quantises them and writes the file atomically; reports the size and the
    /// ratio to the input and to raw float32 positions + u32 indices.
    #[command(
        after_help = "Example:\n  ellip encode fixtures/meshes/blob3.obj -k 5 -o blob3.ellip"
    )]
    Encode(encode::EncodeArgs),
    /// Decode a `.ellip` file back to a triangle mesh (.glb, .gltf, .obj, .ply).
    ///
    /// Remeshes every region within a total vertex budget (shared among regions by their
    /// error), joins them into one mesh with shared boundary vertices and analytic normals,
    /// and writes it atomically. Reports vertices, triangles, regions, whether the mesh is
    /// closed, and the time taken.
    #[command(
        after_help = "Examples:\n  ellip decode blob3.ellip -o blob3.glb\n  ellip decode blob3.ellip -o blob3.ply --vertices 50000 --colors\n  ellip decode blob3.ellip -o blob3.obj --scheme parametric --json\n  cat blob3.ellip | ellip decode - -o blob3.glb --tolerance 0.001"
    )]
    Decode(decode::DecodeArgs),
    /// Measure how far apart two meshes are: Hausdorff, RMS and mean distance, normal deviation.
    ///
    /// Samples points uniformly by area on each mesh (seeded: the same files give the same
    /// figures), finds each one's exact closest point on the other mesh, and reports both
    /// directions and the symmetric figures (the worse direction), absolute and as a
    /// percentage of A's bounding-box diagonal. A `.ellip` file is decoded and remeshed first.
    #[command(
        after_help = "Examples:\n  ellip compare fixtures/meshes/blob1.obj fixtures/meshes/blob2.obj\n  ellip compare bunny.obj bunny.ellip --samples 1000000 --json"
    )]
    Compare(compare::CompareArgs),
    /// Draw a mesh, its regions and its decoded mesh side by side into a PNG image.
    ///
    /// A mesh gives three panels: the source in grey, the source coloured by region with the
    /// boundaries between regions, and the decoded mesh (mesh → .ellip → mesh, coloured by
    /// region); the encoding takes the same options as `encode`. A .ellip file gives two:
    /// the decoded mesh coloured by region, and in grey. One camera for every panel (a
    /// three-quarter view fitted to the meshes), software rendering, the same bytes
    /// for the same input. Written atomically, never over the input.
    #[command(
        after_help = "Examples:\n  ellip preview fixtures/meshes/blob3.obj -k 5 -o blob3.png\n  ellip preview bunny.obj -k 12 -o bunny.png --size 640x480\n  ellip preview hand.ellip -o hand.png --vertices 50000"
    )]
    Preview(preview::PreviewArgs),
    /// Regenerate the committed fixture meshes (for developers).
    #[command(hide = true)]
    Fixtures(fixtures::FixturesArgs),
}

/// Options shared by every command that reads a mesh.
#[derive(Debug, Args)]
pub struct ReadArgs {
    /// Join vertices closer than this distance (model units) instead of only exactly equal ones.
    #[arg(long, value_name = "DISTANCE")]
    weld: Option<f64>,
    /// Keep the file's face orientation instead of making it consistent and outward.
    #[arg(long)]
    keep_orientation: bool,
}

impl ReadArgs {
    fn import_options(&self) -> Result<ImportOptions, CliError> {
        let weld = match self.weld {
            None => Weld::Exact,
            Some(d) if d.is_finite() && d >= 0.0 => Weld::Within(d),
            Some(d) => return Err(format!("--weld must be a distance >= 0, not {d}").into()),
        };
        Ok(ImportOptions {
            weld,
            keep_orientation: self.keep_orientation,
            ..ImportOptions::default()
        })
    }
}

/// Runs one parsed command.
pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Info(args) => info::run(&args),
        Command::Convert(args) => convert::run(&args),
        Command::Encode(args) => encode::run(&args),
        Command::Decode(args) => decode::run(&args),
        Command::Segment(args) => segment::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Preview(args) => preview::run(&args),
        Command::Fixtures(args) => fixtures::run(&args),
    }
}

/// Folds a message onto one line.
pub fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A panic is a bug: report it in one line, without a backtrace, and exit 101.
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let what = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        // `ellip info x | head`: the reader went away. Not a bug; stop quietly, with the
        // status a shell gives a process ended by SIGPIPE.
        if what.contains("failed printing to stdout") && what.contains("Broken pipe") {
            std::process::exit(141);
        }
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!(
            "ellip: internal error (please report it): {}{at}",
            one_line(&what)
        );
    }));
}

/// Path shown in messages.
pub fn shown(path: &std::path::Path) -> String {
    path.display().to_string()
}

/// Fails when `output` names the same file as `input`.
pub fn refuse_overwriting(
    input: &std::path::Path,
    output: &std::path::Path,
) -> Result<(), CliError> {
    let same = match (input.canonicalize(), output.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same {
        return Err(format!(
            "{}: refusing to overwrite the input; choose another output file",
            shown(output)
        )
        .into());
    }
    Ok(())
}
