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
    /// Reference directory (scenes/ and POV-Ray references); default: `reference` here, else
    /// the `reference/` of the source tree this rayproof was built from.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Cases per class for the audit part (the audit's default).
    #[arg(long, default_value_t = 20_000, value_parser = clap::value_parser!(u64).range(1..))]
    pub cases: u64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Small renders, few repeats, strided Newton inputs: a smoke run in seconds.
    #[arg(long)]
    pub quick: bool,
    /// A ray–sphere routine of yours (--plugin with an f32 or an f64 symbol or both, or --exec)
    /// beside the built-in methods in the accuracy-vs-cost section (in the precisions it has).
    #[command(flatten)]
    pub outside: super::outside::OutsideArgs,
}

pub(super) fn run_report(r: ReportArgs) -> Result<u8> {
    // An outside routine answers both precisions
    let sphere = rayproof::shapes::shape_by_name("sphere").expect("registered");
    let mut routines = r.outside.methods(sphere.info())?;
    if routines.len() > 1 {
        anyhow::bail!("report puts one outside ray–sphere routine beside the built-in methods: give one --plugin routine, one --exec, or one --source with one --build");
    }
    let (outside, outside_precisions) = match routines.pop() {
        Some((m, has)) => (
            Some(std::sync::Arc::from(m)),
            has.unwrap_or(rayproof::numerics::Precision::ALL.to_vec()),
        ),
        None => (None, vec![]),
    };
    rayproof::report::run(&rayproof::report::ReportOptions {
        outside,
        outside_precisions,
        out: r.out.clone(),
        reference: reference_dir(&r.reference)?,
        seed: r.seed,
        cases: r.cases,
        quick: r.quick,
        progress: std::io::stderr().is_terminal(),
    })?;
    say!("report written to {}/index.html", r.out.display());
    Ok(0)
}

/// The reference directory: the one given, else `reference` here, else the source tree's.
fn reference_dir(given: &Option<PathBuf>) -> Result<PathBuf> {
    if let Some(d) = given {
        return Ok(d.clone());
    }
    let here = PathBuf::from("reference");
    let built = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("reference");
    [here, built]
        .into_iter()
        .find(|d| d.join("scenes").is_dir())
        .ok_or_else(|| {
            anyhow::anyhow!(
                "report: no reference directory here or at {}: give --reference DIR (rayproof's reference/)",
                env!("CARGO_MANIFEST_DIR")
            )
        })
}
