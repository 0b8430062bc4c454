//! The `aepipe` command: parse the flags (clap, in `aepipe::cli`), dispatch, and turn an
//! error into one line on stderr and the exit code of the README's table.

use aepipe::cli::{dispatch, Cli};
use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            // Usage errors exit 1 (the README's table); --help and --version exit 0.
            let code = if e.use_stderr() { 1 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    match dispatch(cli) {
        Ok(outcome) => ExitCode::from(outcome.code()),
        Err(e) => {
            eprintln!("aepipe: {}", one_line(&e.to_string()));
            ExitCode::from(e.code())
        }
    }
}

/// Errors are printed on one line, whatever a library message holds.
fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
