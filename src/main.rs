//! The `rayproof` binary: parse, run, map errors to exit codes (see [`rayproof::cli`]).

use clap::error::ErrorKind;
use clap::Parser;
use rayproof::cli::{error_exit_code, run, Cli};
use std::process::ExitCode;

fn main() -> ExitCode {
    // Usage errors: one line naming the argument, exit 2
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => {
            print!("{e}");
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            let text = e.render().to_string();
            // One line; a first line ending in ':' ("…not provided:") is joined with its list
            // and a "[possible values: …]" line is appended
            let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
            let mut line = lines
                .next()
                .unwrap_or("error: invalid arguments")
                .to_string();
            if line.ends_with(':') {
                if let Some(next) = lines.next() {
                    line = format!("{line} {next}");
                }
            }
            if let Some(values) = text
                .lines()
                .map(str::trim)
                .find(|l| l.starts_with("[possible values:"))
            {
                line = format!("{line} {values}");
            }
            eprintln!("{line}");
            return ExitCode::from(2);
        }
    };
    match run(cli) {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(error_exit_code(&e))
        }
    }
}
