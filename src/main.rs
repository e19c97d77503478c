//! The `hystbench` command line: parse, run one command, print its error.

use clap::Parser;

mod cli;

fn main() -> std::process::ExitCode {
    let cli = cli::Cli::parse();
    match cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            let msg = hystbench::error_message(&e);
            eprintln!("error: {msg}");
            std::process::ExitCode::FAILURE
        }
    }
}
