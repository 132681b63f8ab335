//! `rayproof cases` and `rayproof score`: audit code that cannot be called (see
//! [`rayproof::audit::offline`] for the two file formats).

use super::audit::{finish, load_table, print_legend, print_shape, AuditOutput};
use super::*;
use anyhow::{anyhow, bail, Result};
use clap::Args;
use rayproof::audit::offline::{read_answers, read_cases, score_plan, write_cases};
use rayproof::audit::plan::{Options, Plan};
use rayproof::audit::{Report, TOOL};
use rayproof::numerics::Precision;
use rayproof::output::{check_output_dirs, write_atomic_with};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct CasesArgs {
    /// The shape whose cases to write (one shape).
    #[arg(long)]
    pub shape: String,
    /// Classes (repeat or comma-separate); default: all.
    #[arg(long, value_delimiter = ',')]
    pub class: Vec<String>,
    /// Precisions: f32, f64; default: both.
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// Cases per class and precision (default: the shape's).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    pub cases: Option<u64>,
    /// Seed of the case generators (the same as `audit --seed`).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The cases file to write.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Write the lines an --exec child reads instead (`f32 0x1p+0 …`: precision and inputs, no
    /// header, class or index), in the same order: answers to them are a `score --answers` file.
    #[arg(long)]
    pub exec_format: bool,
}

#[derive(Args, Debug)]
pub struct ScoreArgs {
    /// The cases file written by `rayproof cases`.
    #[arg(long, value_name = "FILE")]
    pub cases: PathBuf,
    /// The answers, one line per case in the cases file's order: `COUNT VALUE…`.
    #[arg(long, value_name = "FILE")]
    pub answers: PathBuf,
    /// The shape (checked against the cases file's).
    #[arg(long)]
    pub shape: Option<String>,
    /// The name of the method in the report and in tolerance rules.
    #[arg(long, default_value = "answers")]
    pub method: String,
    #[command(flatten)]
    pub out: AuditOutput,
}

pub(super) fn run_cases(a: CasesArgs) -> Result<u8> {
    check_output_dirs(&[&Some(a.output.clone())])?;
    let plan = Plan::new(&Options {
        shapes: vec![a.shape.clone()],
        classes: a.class.clone(),
        precisions: a.precision.clone(),
        cases: a.cases,
        seed: a.seed,
        ..Options::default()
    })
    .map_err(|e| anyhow!(e))?;
    // Streamed to the file: memory does not grow with --cases
    let mut n = 0;
    write_atomic_with(&a.output, |tmp| {
        let mut w = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        n = write_cases(&plan, a.exec_format, &mut w)?;
        Ok(std::io::Write::flush(&mut w)?)
    })?;
    say!("{n} cases of {} written to {}", a.shape, a.output.display());
    Ok(0)
}

pub(super) fn run_score(a: ScoreArgs) -> Result<u8> {
    let inputs: Vec<PathBuf> = [&a.cases, &a.answers]
        .into_iter()
        .chain(&a.out.tolerances)
        .cloned()
        .collect();
    let outputs = a.out.outputs(&[], &inputs)?;
    // The two files, read (within their cap) and matched line by line
    let read = |p: &PathBuf| {
        rayproof::input::read_text(
            p,
            rayproof::input::MAX_DATA_BYTES,
            rayproof::input::Kind::Stream,
        )
        .map_err(|e| anyhow!("cannot read {}: {e}", p.display()))
    };
    let (cname, aname) = (
        a.cases.display().to_string(),
        a.answers.display().to_string(),
    );
    let cases = read_cases(&read(&a.cases)?, &cname, rayproof::shapes::shape_by_name)
        .map_err(|e| anyhow!(e))?;
    if let Some(s) = a.shape.as_ref().filter(|s| *s != cases.shape.name()) {
        bail!(
            "--shape {s}, but {cname} holds {} cases",
            cases.shape.name()
        );
    }
    let answers = read_answers(&read(&a.answers)?, &aname, &cases).map_err(|e| anyhow!(e))?;
    let plan = score_plan(&cases, answers, &a.method).map_err(|e| anyhow!(e))?;
    // Judged and printed as the audit does
    let table = load_table(&a.out.tolerances, &plan.known())?;
    if let Some(r) = table.robustness.first() {
        bail!(
            "tolerances: {}: score runs no reintersection or watertightness test, so a [[robustness]] rule could never judge a row (give it to `audit`)",
            r.origin
        );
    }
    print_legend(plan.seed, "0/1", &a.out);
    let report = plan.run_shape(0, false)?.report(Some(&table));
    plan.finish()?;
    print_shape(&report, &a.out);
    finish(
        Report {
            tool: TOOL,
            seed: plan.seed,
            shard: "0/1".into(),
            shapes: vec![report],
            robustness: None,
        },
        Some(&table),
        outputs,
        &a.out,
    )
}
