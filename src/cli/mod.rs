//! The command line: argument definitions (clap derive; doc comments are the help text) and the
//! commands they run.
//!
//! Exit codes: written once, in the crate documentation (`src/lib.rs`, "Exit codes of the
//! `rayproof` command"); [`error_exit_code`] maps a failed command's error to its code.

use anyhow::Result;
use clap::{Parser, Subcommand};

/// Set once stdout's reader has gone away; later output is dropped.
static STDOUT_CLOSED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Writes to stdout. A closed pipe (`rayproof … | head`) silences later output but never stops
/// the command, so the files it was asked to write are still written.
fn emit(text: &str) {
    use std::io::Write;
    use std::sync::atomic::Ordering::Relaxed;
    if STDOUT_CLOSED.load(Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            STDOUT_CLOSED.store(true, Relaxed);
        }
    }
}

macro_rules! say {
    () => { emit("\n") };
    ($($t:tt)*) => { emit(&(format!($($t)*) + "\n")) };
}
macro_rules! say_raw {
    ($($t:tt)*) => { emit(&format!($($t)*)) };
}

mod args;
mod audit;
mod builds;
mod check;
pub mod diff;
mod guard;
mod header;
mod implicit;
mod offline;
mod once;
mod outside;
mod probe;
mod reference;
mod render;
mod report;
mod spawn;
mod transform;

use args::*;
use audit::{AuditArgs, MergeArgs};
use builds::BuildsArgs;
use check::CheckArgs;
pub use diff::{run_diff, DiffArgs};
use guard::GuardArgs;
use implicit::ImplicitCheckArgs;
use offline::{CasesArgs, ScoreArgs};
use once::OnceArgs;
use probe::ProbeCommand;
use reference::ReferenceArgs;
use render::{DownsampleArgs, ExportArgs, RenderArgs};
use report::ReportArgs;
use spawn::SpawnArgs;
use transform::TransformArgs;

/// Proves how accurate ray–sphere intersection methods are, against an exact MPFR oracle.
#[derive(Parser, Debug)]
#[command(name = "rayproof", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Audit every method × precision × case class against the oracle and print a table.
    Audit(AuditArgs),
    /// Merge the shard files of `audit --shard K/N --shard-out FILE` into the unsharded report.
    Merge(MergeArgs),
    /// Write an audit's cases to a file, for code that cannot be called (then `score`).
    Cases(CasesArgs),
    /// Judge a file of answers to `cases` with the oracle, as the audit would.
    Score(ScoreArgs),
    /// Print the C header of routines audited with `audit --plugin` (one signature per shape
    /// and precision); with --exec, the line protocol of `audit --exec` children.
    Header(header::HeaderArgs),
    /// Run the oracle and every method on one ray and one shape.
    #[command(subcommand)]
    Probe(ProbeCommand),
    /// Render a scene file with the Whitted integrator specialised to the effects it needs.
    Render(RenderArgs),
    /// Write a scene for a reference renderer (POV-Ray 3.7 or Mitsuba 3) to stdout.
    Export(ExportArgs),
    /// Box-average n×n pixel blocks of an EXR (a supersampled POV-Ray render → an n×n grid).
    Downsample(DownsampleArgs),
    /// Compare two images as OpenImageIO's idiff does (exit 0 pass, 1 warn, 2 fail, 3 size, 4 file).
    Diff(DiffArgs),
    /// Golden-image CI: run a suite file's tests (default: rayproof's reference scenes) against
    /// their references and goldens (exit 0 pass, 1 fail, 2 bad suite, 3 refused).
    Check(CheckArgs),
    /// Make references for a scene with the real POV-Ray and Mitsuba, each with its manifest
    /// entry (hashes, commands, width, sampling grid).
    Reference(ReferenceArgs),
    /// Audit spawn rules both ways: self-hits (judged exactly) and the smallest gap to a
    /// neighbour each resolves, at scene sizes 1e-4 to 1e7 (exit 1 if a rule of yours self-hits).
    Spawn(SpawnArgs),
    /// Audit the box that guards the primitive: slab tests with t_max = a primitive's rounded
    /// hit, on boxes holding that hit (lost geometry counted; exit 1 if `ize` loses a box).
    Guard(GuardArgs),
    /// One C routine compiled under several compilers and flags (contraction off, on with FMA,
    /// fast-math) and audited side by side: the cases where builds flip hit or miss (exit 1).
    Builds(BuildsArgs),
    /// Count how many times each triangle routine reports a ray through a shared vertex or edge
    /// of a mesh (exactly once is right: 0 is a leak, 2 a double hit).
    Once(OnceArgs),
    /// Audit shapes behind an instance transform: the ray carried into object space in the
    /// working precision, judged by the exact oracle in world space (rows reported).
    Transform(TransformArgs),
    /// Measure what accuracy costs in time: write DIR/index.html, report.md, report.json and figures.
    Report(ReportArgs),
    /// Render an implicit scene per pixel and by image-space subdivision (seed 004), shadows off
    /// and on, and compare every pixel (exit 1 if the certified mode loses or adds one).
    ImplicitCheck(ImplicitCheckArgs),
    /// (Internal) the worker process that runs a `--plugin` routine.
    #[command(name = "__plugin-worker", hide = true)]
    PluginWorker {
        path: String,
        symbol: String,
        precision: String,
        inputs: usize,
        outputs: usize,
    },
}

/// Parses the command line; `probe --help` lists the routines.
pub fn parse(args: Vec<std::ffi::OsString>) -> Result<Cli, clap::Error> {
    use clap::{CommandFactory, FromArgMatches};
    let list: Vec<String> = rayproof::shapes::registry()
        .iter()
        .map(|s| format!("  {:<16} {}", s.name(), s.info().about))
        .collect();
    let mut cmd = Cli::command().mut_subcommand("probe", |c| {
        c.after_help(format!(
            "Shapes (probe NAME --help for their values):\n{}",
            list.join("\n")
        ))
    });
    // The judged commands say their exit codes where a CI author looks (all: src/lib.rs)
    for name in ["audit", "merge", "score"] {
        cmd = cmd.mut_subcommand(name, |c| {
            c.after_help(
                "Exit codes: 0 no row out of tolerance and no goal missed (rows with too few cases to tell are listed as undecided); 1 one is; 2 bad usage or input (one line on stderr); 3 merge: the shards are not one audit's, or --tolerances is not the table they ran with; 4 a routine of yours failed (crashed, hung past --timeout, answered a line that is not an answer); 71 out of memory; 130 interrupted (no output replaced). Every command's codes: the crate documentation, src/lib.rs.",
            )
        });
    }
    Cli::from_arg_matches(&cmd.try_get_matches_from(args)?)
}

/// A clap error as one line (a first line ending in ':' is joined with its list, and a
/// "[possible values: …]" line is appended).
pub fn one_line(e: &clap::Error) -> String {
    let text = e.render().to_string();
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
    line
}

/// The exit code of a command that failed with `e` (the table in `src/lib.rs`).
pub fn error_exit_code(e: &anyhow::Error) -> u8 {
    if e.downcast_ref::<rayproof::audit::shard::IncompatibleShards>()
        .is_some()
        || e.downcast_ref::<rayproof::golden::renderers::RendererFailed>()
            .is_some()
    {
        3
    } else if e
        .downcast_ref::<rayproof::audit::run::MethodFailed>()
        .is_some()
    {
        4
    } else if let Some(image) = e.downcast_ref::<rayproof::images::ImageError>() {
        // `downsample`'s unreadable input, as `diff`'s
        image.exit_code()
    } else {
        2
    }
}

/// Runs a parsed command; returns the process exit code.
pub fn run(cli: Cli) -> Result<u8> {
    match cli.command {
        Command::Audit(a) => audit::run_audit(a),
        Command::Merge(m) => audit::run_merge(m),
        Command::Cases(c) => offline::run_cases(c),
        Command::Score(s) => offline::run_score(s),
        Command::Header(a) => header::run_header(a),
        Command::Probe(p) => probe::run_probe(p),
        Command::Render(r) => render::run_render(r),
        Command::Export(e) => render::run_export(e),
        Command::Downsample(d) => render::run_downsample(d),
        Command::Diff(d) => Ok(run_diff(d)),
        Command::Check(c) => check::run_check(c),
        Command::Reference(r) => reference::run_reference(r),
        Command::Report(r) => report::run_report(r),
        Command::Spawn(a) => spawn::run_spawn(a),
        Command::Guard(a) => guard::run_guard(a),
        Command::Once(a) => once::run_once(a),
        Command::Transform(a) => transform::run_transform(a),
        Command::Builds(a) => builds::run_builds(a),
        Command::ImplicitCheck(a) => implicit::run_implicit_check(a),
        Command::PluginWorker {
            path,
            symbol,
            precision,
            inputs,
            outputs,
        } => {
            let prec = args::parse_precision(&precision).map_err(anyhow::Error::msg)?;
            rayproof::audit::plugin::serve(&path, &symbol, prec, inputs, outputs)
                .map_err(anyhow::Error::msg)?;
            Ok(0)
        }
    }
}
