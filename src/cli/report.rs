//! `rayproof report`: what accuracy costs in time.

use super::*;
use anyhow::Result;
use clap::Args;
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Output directory (replaced as a whole when the report is complete).
    #[arg(long, default_value = "target/report")]
    pub out: PathBuf,
    /// Reference directory (scenes/ and POV-Ray references).
    #[arg(long, default_value = "reference")]
    pub reference: PathBuf,
    /// Cases per class for the audit part (the audit's default).
    #[arg(long, default_value_t = 20_000, value_parser = clap::value_parser!(u64).range(1..))]
    pub cases: u64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Small renders, few repeats, strided Newton inputs: a smoke run in seconds.
    #[arg(long)]
    pub quick: bool,
    /// A ray–sphere routine of yours (--plugin with f32 and f64 symbols, or --exec) beside the
    /// built-in methods in the accuracy-vs-cost section.
    #[command(flatten)]
    pub outside: super::audit::OutsideArgs,
}

pub(super) fn run_report(r: ReportArgs) -> Result<u8> {
    // An outside routine answers both precisions
    let sphere = rayproof::shapes::shape_by_name("sphere").expect("registered");
    let mut routines = r.outside.methods(sphere)?;
    if routines.len() > 1 {
        anyhow::bail!("report puts one outside ray–sphere routine beside the built-in methods: give one --plugin routine or one --exec");
    }
    let outside = match routines.pop() {
        Some((_, Some(has))) if has.len() < 2 => {
            anyhow::bail!("report --plugin needs an f32 and an f64 symbol (give --plugin twice)")
        }
        Some((m, _)) => Some(std::sync::Arc::from(m)),
        None => None,
    };
    rayproof::report::run(&rayproof::report::ReportOptions {
        outside,
        out: r.out.clone(),
        reference: r.reference.clone(),
        seed: r.seed,
        cases: r.cases,
        quick: r.quick,
        progress: std::io::stderr().is_terminal(),
    })?;
    say!("report written to {}/index.html", r.out.display());
    Ok(0)
}
