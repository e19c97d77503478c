//! The `hystbench` command line: parse, run one command, print its error.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = hystbench::cli::Cli::parse();
    match hystbench::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
