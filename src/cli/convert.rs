//! `ellip convert IN OUT`: mesh to mesh, formats chosen by extension.

use super::{refuse_overwriting, CliError, ReadArgs};
use clap::Args;
use ellip::export::{write_mesh, MeshData};
use ellip::import::read_mesh;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// The mesh to read (.obj, .gltf, .glb, .ply, .stl, .off).
    input: PathBuf,
    /// The file to write (.obj, .gltf, .glb, .ply).
    output: PathBuf,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
    #[command(flatten)]
    read: ReadArgs,
}

pub fn run(args: &ConvertArgs) -> Result<(), CliError> {
    refuse_overwriting(&args.input, &args.output)?;
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
