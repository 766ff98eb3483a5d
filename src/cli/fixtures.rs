//! `ellip fixtures` (hidden): regenerates the committed fixture meshes.

use super::CliError;
use clap::Args;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct FixturesArgs {
    /// Folder to write into.
    #[arg(long, default_value = "fixtures/meshes")]
    out: PathBuf,
}

pub fn run(args: &FixturesArgs) -> Result<(), CliError> {
    std::fs::create_dir_all(&args.out)?;
    let written = ellip::synth::fixtures::write_fixtures(&args.out)?;
    for path in written {
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
