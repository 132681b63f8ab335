//! `rayproof check`: golden-image CI over the reference scenes.

use super::*;
use crate::numerics::Precision;
use crate::output::{check_output_dirs, write_atomic};
use crate::shapes::sphere::methods::Method;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Reference directory: scenes/, NAME/{povray,mitsuba,rayproof}.exr, NAME/manifest.json,
    /// thresholds.toml.
    #[arg(long, default_value = "reference")]
    pub reference: PathBuf,
    /// Write an HTML report (index.html and PNGs) into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Rewrite rayproof's own golden render (NAME/rayproof.exr) where it fails or is missing;
    /// the POV-Ray and Mitsuba references are never rewritten.
    #[arg(long)]
    pub update: bool,
    /// Also render with these methods (compared with POV-Ray and Mitsuba only).
    #[arg(long, value_delimiter = ',', value_parser = parse_method)]
    pub method: Vec<&'static Method>,
    /// Precisions for the extra methods (default: both).
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// Only these scenes (by name).
    #[arg(long, value_delimiter = ',')]
    pub scene: Vec<String>,
    /// Compute HDR-ꟻLIP even without --report.
    #[arg(long)]
    pub flip: bool,
    /// Write every row as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the rows as a Markdown table.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
}

pub(super) fn run_check(a: CheckArgs) -> Result<u8> {
    use crate::golden as check;
    check_output_dirs(&[&a.json, &a.markdown])?;
    let th = check::ThresholdFile::load(&a.reference.join("thresholds.toml"))?;
    // Extra configurations: each method × each precision
    let precisions = if a.precision.is_empty() {
        Precision::ALL.to_vec()
    } else {
        a.precision.clone()
    };
    let configs = a
        .method
        .iter()
        .flat_map(|m| {
            precisions.iter().map(|p| check::Config {
                method: m,
                precision: p.name(),
            })
        })
        .collect();
    let opts = check::Options {
        reference: a.reference.clone(),
        report: a.report.clone(),
        update: a.update,
        configs,
        scenes: a.scene.clone(),
        flip: a.flip,
    };
    let start = Instant::now();
    let rows = check::run(&opts, &th)?;
    say_raw!("{}", check::table(&rows));
    let failed = rows.iter().filter(|r| r.status.is_failure()).count();
    say!(
        "{} comparisons in {:.1} s: {} failing (gated configuration: {})",
        rows.len(),
        start.elapsed().as_secs_f64(),
        failed,
        th.gated.label()
    );
    if let Some(dir) = &a.report {
        let html = check::html(&rows, "rayproof check");
        write_atomic(&dir.join("index.html"), html.as_bytes())?;
        say!("report: {}", dir.join("index.html").display());
    }
    if let Some(p) = &a.json {
        write_atomic(p, (serde_json::to_string_pretty(&rows)? + "\n").as_bytes())?;
    }
    if let Some(p) = &a.markdown {
        write_atomic(p, check::markdown(&rows).as_bytes())?;
    }
    Ok(if failed > 0 { 1 } else { 0 })
}
