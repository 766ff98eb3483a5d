//! The `ellip` command-line tool: a thin layer over the library. Each subcommand lives in
//! its own module under `src/cli/`; this file parses arguments, runs one, and turns any
//! error into one line on stderr and exit code 1 (clap exits with 2 on bad usage).
#![forbid(unsafe_code)]

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    cli::install_panic_hook();
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("ellip: error: {}", cli::one_line(&error.to_string()));
            ExitCode::FAILURE
        }
    }
}
