//! `rayproof check`: golden-image CI over a suite file (by default rayproof's own reference
//! scenes, `reference/suite.toml`).
//!
//! Exit codes: 0 every comparison passes (warnings, known failures, skipped optional
//! references included); 1 some comparison fails (FAILURE, XPASS, a missing golden); 2 bad
//! usage or a suite file that does not validate (nothing runs); 3 some test was refused (a
//! renderer command failed, hung or wrote no usable image; a required reference is missing,
//! tampered, unreadable, or an external one stale): then `--update` writes nothing. A stale
//! golden is not a refusal: it is compared, and `--update` re-blesses it.

use super::*;
use anyhow::Result;
use clap::Args;
use rayproof::numerics::Precision;
use rayproof::output::{check_outputs, Outputs};
use rayproof::shapes::sphere::methods::Method;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// The suite file: tests, their images or renderer commands, references and thresholds.
    #[arg(long, default_value = "reference/suite.toml")]
    pub suite: PathBuf,
    /// Write an HTML report (index.html and PNGs) into this directory, and each renderer's
    /// whole log as logs/TEST.log.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write goldens where the golden comparison fails, the golden is missing or it is stale
    /// (made from another version of the test's scene or inputs), each with a manifest entry;
    /// external references are never written, and nothing is written when a test is refused.
    #[arg(long)]
    pub update: bool,
    /// Tests rayproof renders: also render with these methods (compared with their external
    /// references only).
    #[arg(long, value_delimiter = ',', value_parser = parse_method)]
    pub method: Vec<&'static Method>,
    /// Precisions for the extra methods (default: both).
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// Only these tests (by name).
    #[arg(long, value_delimiter = ',', alias = "scene")]
    pub test: Vec<String>,
    /// Compute HDR-ꟻLIP even without --report or a max_flip rule.
    #[arg(long)]
    pub flip: bool,
    /// Write every row as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the rows as JUnit XML (for CI systems).
    #[arg(long)]
    pub junit: Option<PathBuf>,
    /// Write the rows as a Markdown table.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
}

pub(super) fn run_check(a: CheckArgs) -> Result<u8> {
    use rayproof::golden as check;
    let suite = check::Suite::load(&a.suite)?;
    // Every output checked before the run, none over an input (the suite, a scene, a reference)
    let inputs = suite.inputs();
    let inputs: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    // The goldens too: no other output of the run may be one, or hold one
    let goldens = suite.goldens();
    let kept: Vec<&Path> = inputs
        .iter()
        .copied()
        .chain(goldens.iter().map(|p| p.as_path()))
        .collect();
    let files: Vec<&Path> = [&a.json, &a.junit, &a.markdown]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    let dirs: Vec<&Path> = a.report.iter().map(|p| p.as_path()).collect();
    check_outputs(&files, &dirs, &kept)?;
    let mut outputs = Outputs::new().reading(&inputs);
    let report_dir = match &a.report {
        Some(d) => Some(outputs.dir(d)?),
        None => None,
    };
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
        report: report_dir.clone(),
        update: a.update,
        configs,
        tests: a.test.clone(),
        flip: a.flip,
    };
    // Run, then the summary: failures first
    let start = Instant::now();
    let out = check::run(&suite, &opts, &mut outputs)?;
    let rows = &out.rows;
    say_raw!("{}", check::table(rows));
    say!(
        "{}: {} comparisons in {:.1} s: {}",
        suite.name,
        rows.len(),
        start.elapsed().as_secs_f64(),
        check::counts(rows)
    );
    if out.update_withheld {
        say!("--update wrote nothing: a test was refused (fix it first)");
    }
    // The reports, staged with the goldens: all committed together
    if let Some(dir) = &report_dir {
        let html = check::html(rows, &suite.name);
        std::fs::write(dir.join("index.html"), html.as_bytes())?;
    }
    if let Some(p) = &a.json {
        outputs.write(p, (serde_json::to_string_pretty(rows)? + "\n").as_bytes())?;
    }
    if let Some(p) = &a.junit {
        outputs.write(p, check::junit(rows, &suite.name).as_bytes())?;
    }
    if let Some(p) = &a.markdown {
        outputs.write(p, check::markdown(rows).as_bytes())?;
    }
    outputs.commit()?;
    for g in &out.blessed {
        say!("updated {}", g.display());
    }
    if let Some(dir) = &a.report {
        say!("report: {}", dir.join("index.html").display());
    }
    Ok(out.exit_code())
}
