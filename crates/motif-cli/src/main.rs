//! `motif`: structure-aware 3D content creation from the command line.
//!
//! A thin front end: it parses arguments, calls the library crates, prints results, and maps
//! errors to exit codes (0 success, 1 failure, 2 bad usage or bad input).

mod cli;
mod commands;
mod output;
mod progress;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    if let Some(threads) = cli.global.threads {
        // A second initialisation can only fail if something already built the pool; ignore.
        let _ = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build_global();
    }
    match commands::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", output::describe(&err));
            ExitCode::from(output::exit_code(&err))
        }
    }
}
