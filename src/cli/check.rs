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
use rayproof::output::{check_outputs_with, Outputs};
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
    /// The platform (or device) of this run, one of the suite's `platforms`: its goldens
    /// (`{platform}` in their paths) and its `[platform.NAME]` thresholds; else the environment's
    /// RAYPROOF_PLATFORM. A suite that declares platforms needs one: no platform's golden
    /// stands in for another's.
    #[arg(long)]
    pub platform: Option<String>,
    /// The value of `{seed}` in renderer commands.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Render each test (or those of --test) N times with `{seed}` = 1..N, write the mean as
    /// its golden and the variance of one render beside it (NAME.variance.exr), and propose
    /// thresholds; later runs judge the golden with the z-test on that variance.
    #[arg(long, value_name = "N")]
    pub calibrate: Option<u32>,
    /// Print GitHub Actions annotations (`::error file=SUITE,line=L::…` on each failing test's
    /// `[[test]]` line, `::warning` for warnings and expected failures); on by default when
    /// GITHUB_ACTIONS=true.
    #[arg(long)]
    pub annotations: bool,
    /// Write a Markdown summary (failing rows first, linked to the HTML report) to this file;
    /// without it, appended to $GITHUB_STEP_SUMMARY when that is set.
    #[arg(long)]
    pub summary: Option<PathBuf>,
    /// Where the HTML report will be seen (the URL of the uploaded report's index.html): the
    /// summary links each row there; without it the summary names --report's path, unlinked.
    #[arg(long, value_name = "URL")]
    pub report_url: Option<String>,
}

pub(super) fn run_check(a: CheckArgs) -> Result<u8> {
    use rayproof::golden as check;
    let platform = a
        .platform
        .clone()
        .or_else(|| std::env::var("RAYPROOF_PLATFORM").ok())
        .filter(|p| !p.is_empty());
    let suite = check::Suite::load(&a.suite, platform.as_deref())?;
    // Every output checked before the run, none over an input (the suite, a scene, a reference)
    let inputs = suite.inputs();
    let inputs: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    // The goldens too: no other output of the run may be one, or hold one
    let goldens = suite.goldens();
    let kept: Vec<&Path> = inputs
        .iter()
        .copied()
        .chain(goldens.iter().map(|p| p.as_path()))
        .chain(suite.others.iter().map(|p| p.as_path()))
        .collect();
    let files: Vec<&Path> = [&a.json, &a.junit, &a.markdown, &a.summary]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    let dirs: Vec<&Path> = a.report.iter().map(|p| p.as_path()).collect();
    check_outputs_with(&files, &dirs, &kept, true)?;
    // The step summary GitHub's runner names: appended to, so checked as an output too
    let step_summary = std::env::var_os("GITHUB_STEP_SUMMARY")
        .filter(|p| !p.is_empty() && a.summary.is_none())
        .map(PathBuf::from);
    if let Some(p) = &step_summary {
        appendable(p, &kept)?;
    }
    if let Some(u) = &a.report_url {
        check::ci::check_url(u).map_err(anyhow::Error::msg)?;
    }
    // Under annotations, nothing but them is read as a workflow command: a note, a suite name
    // or a path printed in the table cannot forge one (GitHub's stop-commands)
    let annotate = a.annotations || std::env::var("GITHUB_ACTIONS").is_ok_and(|v| v == "true");
    let token = format!(
        "rayproof-{}",
        &check::sha256_bytes(
            format!(
                "{:?} {} {:?}",
                std::time::SystemTime::now(),
                std::process::id(),
                a.suite
            )
            .as_bytes()
        )[..32]
    );
    if annotate {
        say!("::stop-commands::{token}");
    }
    let mut outputs = Outputs::new().reading(&inputs).making_dirs();
    if let Some(n) = a.calibrate {
        if a.update || a.report.is_some() || !files.is_empty() || !a.method.is_empty() {
            anyhow::bail!("--calibrate writes goldens and their variance only: run check again for reports (--report, --json, --junit, --markdown) and --update");
        }
        return calibrate(&suite, &a.test, n, outputs);
    }
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
        seed: a.seed,
    };
    // Run, then the summary: failures first
    let start = Instant::now();
    let out = check::run(&suite, &opts, &mut outputs)?;
    let rows = &out.rows;
    say_raw!("{}", check::table(rows));
    say!(
        "{}: {} comparisons in {:.1} s: {}",
        rayproof::images::one_line(&suite.name),
        rows.len(),
        start.elapsed().as_secs_f64(),
        check::counts(rows)
    );
    if out.update_withheld {
        say!("--update wrote nothing: a test was refused (fix it first)");
    }
    // The reports, staged with the goldens: all committed together
    if let Some(dir) = &report_dir {
        let html = check::html(rows, &suite.name, suite.platform.as_deref());
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
    // The CI summary: to its file, with the run's other outputs, or to the step summary
    let index = a.report.as_ref().map(|d| d.join("index.html"));
    let summary = check::ci::summary(
        rows,
        &suite,
        out.exit_code(),
        a.report_url.as_deref(),
        index.as_deref(),
    );
    if let Some(p) = &a.summary {
        outputs.write(p, summary.as_bytes())?;
    }
    outputs.commit()?;
    if let Some(p) = &step_summary {
        // The runner's file for this step: appended to, as its protocol says
        let appended = std::fs::OpenOptions::new()
            .append(true)
            .open(p)
            .or_else(|_| {
                std::fs::OpenOptions::new()
                    .append(true)
                    .create_new(true)
                    .open(p)
            })
            .and_then(|mut f| std::io::Write::write_all(&mut f, (summary + "\n").as_bytes()));
        if let Err(e) = appended {
            say!(
                "cannot append the summary to GITHUB_STEP_SUMMARY ({}): {e}",
                p.display()
            );
        }
    }
    for g in &out.blessed {
        say!("updated {}", g.display());
    }
    if let Some(dir) = &a.report {
        say!("report: {}", dir.join("index.html").display());
    }
    if annotate {
        say!("::{token}::");
        say_raw!("{}", check::ci::annotations(rows, &suite));
    }
    Ok(out.exit_code())
}

/// GitHub's step summary file: a regular file (or none yet, in a directory), never a file the
/// run reads or keeps (the suite, a scene, a golden): it is appended to, not replaced.
fn appendable(p: &Path, kept: &[&Path]) -> Result<()> {
    let id = rayproof::output::identity(p);
    if let Some(k) = kept.iter().find(|k| rayproof::output::identity(k) == id) {
        anyhow::bail!(
            "GITHUB_STEP_SUMMARY={}: is {} of this run; rayproof never writes over its inputs or goldens",
            p.display(),
            k.display()
        );
    }
    match std::fs::metadata(p) {
        Ok(m) if !m.is_file() => anyhow::bail!(
            "GITHUB_STEP_SUMMARY={}: not a regular file (a directory, FIFO or device)",
            p.display()
        ),
        Ok(_) => Ok(()),
        Err(_) => {
            let dir = p
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
                .unwrap_or(Path::new("."));
            if dir.is_dir() {
                Ok(())
            } else {
                anyhow::bail!(
                    "GITHUB_STEP_SUMMARY={}: its directory does not exist",
                    p.display()
                )
            }
        }
    }
}

/// `check --calibrate N`: every render made and checked before anything is written (exit 3 and
/// nothing written when one fails).
fn calibrate(
    suite: &rayproof::golden::Suite,
    tests: &[String],
    n: u32,
    mut outputs: Outputs,
) -> Result<u8> {
    use rayproof::golden::calibrate;
    let start = Instant::now();
    let done = match calibrate::calibrate(suite, tests, n, &mut outputs)? {
        Ok(done) => done,
        Err(why) => {
            say!("--calibrate wrote nothing: {why}");
            return Ok(3);
        }
    };
    outputs.commit()?;
    for c in &done {
        let (fail, pct, mean) = c.proposal;
        say!(
            "calibrated {}: {} renders (seeds 1..{}) in {:.1} s; per-sample σ: median {:.3e}, largest {:.3e}",
            c.test,
            c.renders,
            c.renders,
            start.elapsed().as_secs_f64(),
            c.sigma.1,
            c.sigma.0
        );
        say!(
            "  wrote {} (their mean) and {} (one render's variance × (1 + 1/{}))",
            c.golden.display(),
            c.variance.display(),
            c.renders
        );
        say!(
            "  the golden comparison now runs the z-test (Student's t, {} degrees of freedom, and the mean-shift test)",
            c.renders - 1
        );
        say!("  idiff thresholds the renders support, if you keep those instead (not written):");
        say_raw!(
            "  [[test]] name = \"{}\"  golden_thresholds = {{ fail = {:.3e}, failpercent = {pct}, max_mean = {:.3e} }}\n",
            c.test,
            fail,
            mean
        );
    }
    Ok(0)
}
