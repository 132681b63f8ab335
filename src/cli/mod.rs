//! The command line: argument definitions (clap derive; doc comments are the help text) and the
//! commands they run.
//!
//! Exit codes, for every command:
//! - 0: success (for `audit` and `merge`: every row within the tolerance table; `audit
//!   --shard-out` leaves that check to the merge)
//! - 1: `audit` or `merge` ran, and some row broke its tolerance-table entry (a regression)
//! - 2: bad usage or input (a malformed argument, an unknown method or class, an unwritable file,
//!   and for `merge` a shard file that is unreadable, truncated, corrupt or not a shard)
//! - 3: `merge` only: the shard files are sound but are not one audit's shards 0/N … N−1/N
//!   (a shard missing or given twice; a different seed, case count, selection, N or version)

use crate::audit::sphere_probe;
use crate::audit::sphere_run::{self, AuditOptions};
use crate::numerics::Precision;
use crate::shapes::sphere::cases::Class;
use crate::shapes::sphere::methods::{method_by_name, Method, METHODS};
use crate::shapes::sphere::tolerance;
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

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
    Diff(crate::images::DiffArgs),
    /// Render every reference scene and compare it with the POV-Ray, Mitsuba and golden references.
    Check(CheckArgs),
    /// Measure what accuracy costs in time: write DIR/index.html, report.md, report.json and figures.
    Report(ReportArgs),
    /// Render an implicit scene per pixel and by image-space subdivision (seed 004), shadows off
    /// and on, and compare every pixel (exit 1 if the certified mode loses or adds one).
    ImplicitCheck(ImplicitCheckArgs),
}

#[derive(Args, Debug)]
pub struct ImplicitCheckArgs {
    /// Scene file (TOML) whose shapes are all implicit (sdf, blob, mpu).
    pub scene: PathBuf,
    /// Block size of the image-space subdivision, in pixels (the paper: 10).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub region: u32,
    /// Image width (the height keeps the camera's aspect ratio); default: the camera's.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,
    /// Render each configuration this many times and keep the fastest.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeat: u32,
    /// Write the full report (every lost, ghost and moved pixel) as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

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
}

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

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Target renderer: povray or mitsuba.
    #[arg(long = "to", value_parser = ["povray", "mitsuba"])]
    pub to: String,
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Image width (the height keeps the scene's aspect ratio); default: the scene's.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: Option<u32>,
    /// n×n sub-pixel grid; default: the scene's camera.grid.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub grid: Option<u32>,
}

#[derive(Args, Debug)]
pub struct DownsampleArgs {
    /// Input EXR (R, G, B; any sample type).
    pub input: PathBuf,
    /// Block size n: the output is (W/n)×(H/n), each pixel the mean of an n×n block.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub factor: u32,
    /// Output EXR (float32 R, G, B).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output EXR (linear float32); a JSON sidecar with the statistics goes beside it.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Tone-mapped PNG preview.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Ray–sphere method (overrides render.method).
    #[arg(long, value_parser = parse_method)]
    pub method: Option<&'static Method>,
    /// f32 or f64 (overrides render.precision).
    #[arg(long, value_parser = parse_precision)]
    pub precision: Option<Precision>,
    /// Samples per pixel, a square n² (overrides camera.grid = n).
    #[arg(long, value_parser = parse_spp)]
    pub spp: Option<u32>,
    /// Image width; the height keeps the scene's aspect ratio (overrides camera.width/height).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: Option<u32>,
    /// Print the chosen effects and why, then render.
    #[arg(long)]
    pub explain: bool,
    /// Turn every effect on (to measure what specialisation saves).
    #[arg(long)]
    pub all_effects: bool,
    /// Test every object for every ray (no BVH), as seed 000's 1996 renderer did.
    #[arg(long)]
    pub flat: bool,
    /// Extra EXR layers: depth, normal, rays (comma-separated).
    #[arg(long, value_delimiter = ',', value_parser = ["depth", "normal", "rays"])]
    pub layers: Vec<String>,
}

fn parse_spp(s: &str) -> Result<u32, String> {
    let n: u32 = s
        .parse()
        .map_err(|_| format!("'{s}' is not a number of samples"))?;
    let g = (n as f64).sqrt().round() as u32;
    if n == 0 || g * g != n {
        return Err(format!(
            "{n} is not a square (1, 4, 9, 16, …): the sub-pixel grid is n×n"
        ));
    }
    Ok(g)
}

#[derive(Args, Debug)]
pub struct AuditArgs {
    /// Cases per class and precision (default 20000; for routines whose oracle is slow, such as
    /// the torus, their own smaller default).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub cases: Option<u64>,
    /// Seed of every case generator; the same seed gives byte-identical JSON.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Shapes (routine families) to audit: sphere, the game-math chapter's routines (see
    /// `rayproof probe --help`), or all (repeat or comma-separate). Default: all, or only the
    /// sphere when --method, --class or sharding is given.
    #[arg(long, value_delimiter = ',', value_parser = parse_shape)]
    pub shape: Vec<String>,
    /// Methods to audit (repeat or comma-separate); default: all. Names are the selected
    /// shape's (a single shape).
    #[arg(long, value_delimiter = ',')]
    pub method: Vec<String>,
    /// Precisions: f32, f64 (repeat or comma-separate); default: both.
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// Case classes (repeat or comma-separate); default: all. Names are the selected shape's.
    #[arg(long, value_delimiter = ',')]
    pub class: Vec<String>,
    /// Run only shard K of N (cases whose index ≡ K mod N), written as K/N.
    #[arg(long, value_parser = parse_shard, default_value = "0/1")]
    pub shard: (u64, u64),
    /// Write this shard's raw per-case results for `rayproof merge` (the tolerance table is then
    /// checked by the merge, not here).
    #[arg(long, value_name = "FILE")]
    pub shard_out: Option<PathBuf>,
    /// Write the full report as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the table as Markdown.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
    /// Replayable worst cases to print per row (0 for none).
    #[arg(long, default_value_t = 1)]
    pub worst: usize,
}

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Shard files from `rayproof audit --shard K/N --shard-out FILE`: each K of 0 … N−1 once,
    /// in any order.
    #[arg(required = true, value_name = "SHARD")]
    pub shards: Vec<PathBuf>,
    /// Write the full report as JSON (byte-identical to the unsharded audit's).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the table as Markdown.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
    /// Replayable worst cases to print per row (0 for none).
    #[arg(long, default_value_t = 1)]
    pub worst: usize,
}

#[derive(Subcommand, Debug)]
pub enum ProbeCommand {
    /// One ray against one sphere.
    Sphere(ProbeSphereArgs),
    /// A routine of the game-math chapter: `probe SHAPE [--precision P] [--json] -- VALUES…`
    /// (`probe SHAPE --help` names the values).
    #[command(external_subcommand)]
    Routine(Vec<String>),
}

/// The arguments of `rayproof probe SHAPE` for a routine (parsed after the shape is known, so
/// the help names its values).
#[derive(Parser, Debug)]
pub struct ProbeShapeArgs {
    /// f32 or f64.
    #[arg(long, value_parser = parse_precision, default_value = "f64")]
    pub precision: Precision,
    /// Print the JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// The input values in the shape's order (decimal or hex floats, each rounded once to the
    /// precision); put them after `--` when the first is negative.
    #[arg(allow_hyphen_values = true)]
    pub values: Vec<String>,
}

/// Parses the command line; `probe --help` lists the routines.
pub fn parse() -> Result<Cli, clap::Error> {
    use clap::{CommandFactory, FromArgMatches};
    let list: Vec<String> = crate::shapes::registry()
        .iter()
        .map(|s| format!("  {:<16} {}", s.name(), s.about()))
        .collect();
    let cmd = Cli::command().mut_subcommand("probe", |c| {
        c.after_help(format!(
            "Routines (probe NAME --help for their values):\n{}",
            list.join("\n")
        ))
    });
    Cli::from_arg_matches(&cmd.try_get_matches()?)
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

/// `rayproof probe SHAPE …` for a routine.
fn run_probe_routine(argv: &[String]) -> Result<u8> {
    use clap::{CommandFactory, FromArgMatches};
    let name = argv.first().map(String::as_str).unwrap_or("");
    let Some(shape) = crate::shapes::shape_by_name(name) else {
        bail!(
            "probe: unknown shape '{name}' (known: {})",
            shape_names().join(", ")
        );
    };
    let cmd = ProbeShapeArgs::command()
        .name(shape.name())
        .bin_name(format!("rayproof probe {name}"))
        .about(shape.about())
        .after_help(format!(
            "Values: {}\nOutputs: {}\nMethods: {}",
            shape.args().join(" "),
            shape.values().join(" "),
            shape
                .methods()
                .iter()
                .map(|m| m.name)
                .collect::<Vec<_>>()
                .join(", ")
        ));
    let parsed = cmd
        .try_get_matches_from(argv)
        .and_then(|m| ProbeShapeArgs::from_arg_matches(&m));
    let p = match parsed {
        Ok(p) => p,
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelp => {
            say_raw!("{e}");
            return Ok(0);
        }
        Err(e) => bail!("{}", one_line(&e).trim_start_matches("error: ")),
    };
    let input = crate::audit::shape::parse_values(shape, p.precision, &p.values)
        .map_err(|e| anyhow!("{e}"))?;
    say_raw!(
        "{}",
        crate::audit::generic::probe(shape, p.precision, &input, p.json)
    );
    Ok(0)
}

#[derive(Args, Debug)]
pub struct ProbeSphereArgs {
    /// Ray origin X,Y,Z (decimal or hex floats, each rounded once to the precision).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub origin: [String; 3],
    /// Ray direction X,Y,Z, used as given (not renormalised).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub dir: [String; 3],
    /// Sphere centre X,Y,Z.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub center: [String; 3],
    /// Sphere radius.
    #[arg(long, value_parser = parse_number, allow_hyphen_values = true)]
    pub radius: String,
    /// f32 or f64.
    #[arg(long, value_parser = parse_precision, default_value = "f64")]
    pub precision: Precision,
    /// Print the JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

fn parse_method(s: &str) -> Result<&'static Method, String> {
    method_by_name(s).ok_or_else(|| {
        format!(
            "unknown method '{s}' (known: {})",
            METHODS
                .iter()
                .map(|m| m.name)
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

fn parse_shape(s: &str) -> Result<String, String> {
    if s == "all" || s == "sphere" || crate::shapes::shape_by_name(s).is_some() {
        Ok(s.to_string())
    } else {
        Err(format!(
            "unknown shape '{s}' (known: all, {})",
            shape_names().join(", ")
        ))
    }
}

/// Every auditable shape: the sphere, then the routines' registry.
fn shape_names() -> Vec<&'static str> {
    std::iter::once("sphere")
        .chain(crate::shapes::registry().iter().map(|s| s.name()))
        .collect()
}

fn parse_precision(s: &str) -> Result<Precision, String> {
    match s {
        "f32" => Ok(Precision::F32),
        "f64" => Ok(Precision::F64),
        _ => Err(format!("unknown precision '{s}' (known: f32, f64)")),
    }
}

fn parse_class(s: &str) -> Result<Class, String> {
    Class::from_name(s).ok_or_else(|| {
        format!(
            "unknown class '{s}' (known: {})",
            Class::ALL.map(|c| c.name()).join(", ")
        )
    })
}

fn parse_shard(s: &str) -> Result<(u64, u64), String> {
    let bad = || format!("'{s}' is not a shard K/N with 0 ≤ K < N");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n): (u64, u64) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || k >= n {
        return Err(bad());
    }
    Ok((k, n))
}

fn parse_number(s: &str) -> Result<String, String> {
    crate::numerics::real::parse_f64(s)
        .map(|_| s.trim().to_string())
        .ok_or_else(|| format!("'{s}' is not a decimal or hex-float number"))
}

fn parse_triple(s: &str) -> Result<[String; 3], String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("'{s}' is not three comma-separated numbers X,Y,Z"));
    }
    let v: Vec<String> = parts
        .iter()
        .map(|p| parse_number(p))
        .collect::<Result<_, _>>()?;
    Ok([v[0].clone(), v[1].clone(), v[2].clone()])
}

/// Writes a file through a temporary sibling and a rename, so no half-written file is left.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path.file_name().context("output path has no file name")?;
    let tmp = dir.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// Fails with one line if the directory of any given output path does not exist.
fn check_output_dirs(paths: &[&Option<PathBuf>]) -> Result<()> {
    for p in paths.iter().copied().flatten() {
        let dir = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        if !dir.is_dir() {
            bail!(
                "{}: directory {} does not exist",
                p.display(),
                dir.display()
            );
        }
    }
    Ok(())
}

/// The exit code of a command that failed with `e` (see the module documentation).
pub fn error_exit_code(e: &anyhow::Error) -> u8 {
    if e.downcast_ref::<sphere_run::IncompatibleShards>().is_some() {
        3
    } else {
        2
    }
}

/// Runs a parsed command; returns the process exit code.
pub fn run(cli: Cli) -> Result<u8> {
    match cli.command {
        Command::Audit(a) => run_audit(a),
        Command::Merge(m) => run_merge(m),
        Command::Render(r) => run_render(r),
        Command::Diff(d) => Ok(crate::images::run_diff(d)),
        Command::Check(c) => run_check(c),
        Command::ImplicitCheck(a) => run_implicit_check(a),
        Command::Report(r) => {
            crate::report::run(&crate::report::ReportOptions {
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
        Command::Export(e) => {
            let sc = crate::render::scene::load(&e.scene)?;
            let fr = crate::render::export::Frame::of(&sc, e.width, e.grid);
            if let Some(why) = crate::render::export::unsupported(&sc, &e.to) {
                anyhow::bail!("{}: {why}", e.scene.display());
            }
            say_raw!(
                "{}",
                match e.to.as_str() {
                    "povray" => crate::render::export::povray(&sc, fr),
                    _ => crate::render::export::mitsuba(&sc, fr),
                }
            );
            Ok(0)
        }
        Command::Downsample(d) => {
            check_output_dirs(&[&Some(d.output.clone())])?;
            let big = crate::images::read_image(&d.input)?;
            let small = crate::render::export::downsample(&big, d.factor as usize)
                .with_context(|| d.input.display().to_string())?;
            crate::images::write_exr_rgb(&d.output, &small)?;
            let (w, h) = (small.width, small.height);
            say!(
                "{}: {w}×{h} (mean of {f}×{f} blocks)",
                d.output.display(),
                f = d.factor
            );
            Ok(0)
        }
        Command::Probe(ProbeCommand::Routine(argv)) => run_probe_routine(&argv),
        Command::Probe(ProbeCommand::Sphere(p)) => {
            say_raw!(
                "{}",
                sphere_probe::sphere(&p.origin, &p.dir, &p.center, &p.radius, p.precision, p.json)?
            );
            Ok(0)
        }
    }
}

fn run_audit(a: AuditArgs) -> Result<u8> {
    // Which shapes: sharding, --method and --class keep the sphere-only audit they always meant
    let sharded = a.shard != (0, 1) || a.shard_out.is_some();
    let narrowed = !a.method.is_empty() || !a.class.is_empty();
    let all = shape_names();
    let every = a.shape.iter().any(|s| s == "all") || (a.shape.is_empty() && !sharded && !narrowed);
    let names: Vec<&'static str> = if a.shape.is_empty() {
        if sharded || narrowed {
            vec!["sphere"]
        } else {
            all
        }
    } else if a.shape.iter().any(|s| s == "all") {
        all
    } else {
        all.into_iter()
            .filter(|n| a.shape.iter().any(|s| s == n))
            .collect()
    };
    if narrowed && names.len() != 1 {
        bail!("--method and --class name one shape's methods and classes: give a single --shape");
    }
    if sharded && names != ["sphere"] {
        bail!("--shard and --shard-out cover the sphere only: give --shape sphere");
    }
    let precisions = if a.precision.is_empty() {
        Precision::ALL.to_vec()
    } else {
        a.precision.clone()
    };
    let others: Vec<&'static dyn crate::audit::shape::Shape> = names
        .iter()
        .filter_map(|n| crate::shapes::shape_by_name(n))
        .collect();
    let mut shape_opts = crate::audit::generic::Options {
        cases: a.cases.unwrap_or(20_000),
        seed: a.seed,
        precisions: precisions.clone(),
        methods: a.method.clone(),
        classes: a.class.clone(),
    };
    for s in &others {
        crate::audit::generic::validate(*s, &shape_opts).map_err(|e| anyhow!("{e}"))?;
    }
    // Check output paths before the long run
    check_output_dirs(&[&a.json, &a.markdown, &a.shard_out])?;
    let sphere = if names.contains(&"sphere") {
        match audit_sphere(&a, precisions)? {
            SphereAudit::Shard => return Ok(0),
            SphereAudit::Done(r) => Some(r),
        }
    } else {
        None
    };
    // The game-math chapter's routines
    let mut shapes = vec![];
    for s in others {
        let start = Instant::now();
        shape_opts.cases = a.cases.unwrap_or(s.default_cases());
        let r = crate::audit::generic::run(s, &shape_opts).map_err(|e| anyhow!("{e}"))?;
        say_raw!("{}", crate::audit::generic::table(&r));
        if a.worst > 0 {
            say_raw!("{}", crate::audit::generic::worst_cases(&r, a.worst));
        }
        say!(
            "{}: {} cases × {} methods in {:.1} s",
            s.name(),
            r.cases_per_class * (r.rows.len() / s.methods().len().max(1)) as u64,
            s.methods().len(),
            start.elapsed().as_secs_f64()
        );
        shapes.push(r);
    }
    // Reintersection and watertightness, with every shape
    let robust = every.then(|| {
        let start = Instant::now();
        let r = crate::shapes::robustness::run(a.seed, &shape_opts.precisions);
        say_raw!("{}", crate::shapes::robustness::table(&r, false));
        say!(
            "reintersection and watertightness in {:.1} s",
            start.elapsed().as_secs_f64()
        );
        r
    });
    write_audit_files(
        sphere.as_ref(),
        &shapes,
        robust.as_ref(),
        &a.json,
        &a.markdown,
    )?;
    // Verdict: the sphere's tolerance table and every shape's
    let mut code = sphere.as_ref().map_or(0, tolerance_verdict);
    for r in &shapes {
        let shape = crate::shapes::shape_by_name(r.shape).expect("audited shape");
        let breaks = crate::audit::generic::check(shape, r);
        if breaks.is_empty() {
            say!("{}: every row within its tolerance", r.shape);
        } else {
            say!("{}: {} row(s) out of tolerance", r.shape, breaks.len());
            for b in &breaks {
                say!("  {b}");
            }
            code = 1;
        }
    }
    if let Some(r) = &robust {
        let breaks = crate::shapes::robustness::check(r);
        if breaks.is_empty() {
            say!("reintersection and watertightness: the robust methods reach 0");
        } else {
            for b in &breaks {
                say!("  {b}");
            }
            code = 1;
        }
    }
    Ok(code)
}

enum SphereAudit {
    Done(sphere_run::Report),
    /// A shard file was written; the merge checks the tolerance table.
    Shard,
}

/// The sphere's audit: prints its table and, for `--shard-out`, writes the shard file.
fn audit_sphere(a: &AuditArgs, precisions: Vec<Precision>) -> Result<SphereAudit> {
    let methods = a
        .method
        .iter()
        .map(|m| parse_method(m).map_err(|e| anyhow!("--method: {e}")))
        .collect::<Result<Vec<_>>>()?;
    let classes = a
        .class
        .iter()
        .map(|c| parse_class(c).map_err(|e| anyhow!("--class: {e}")))
        .collect::<Result<Vec<_>>>()?;
    let opts = AuditOptions {
        cases: a.cases.unwrap_or(20_000),
        seed: a.seed,
        methods: if methods.is_empty() {
            METHODS.iter().collect()
        } else {
            methods
        },
        precisions,
        classes: if classes.is_empty() {
            Class::ALL.to_vec()
        } else {
            classes
        },
        shard: a.shard,
        progress: std::io::stderr().is_terminal(),
    };
    let start = Instant::now();
    sphere_run::ORACLE_NANOS.store(0, std::sync::atomic::Ordering::Relaxed);
    let (report, shard) = match &a.shard_out {
        Some(_) => {
            let (report, shard) = sphere_run::run_shard(&opts);
            (report, Some(shard))
        }
        None => (sphere_run::run(&opts), None),
    };
    let secs = start.elapsed().as_secs_f64();
    print_report(&report, a.worst);
    let n = cases_per_method(&report);
    say!(
        "\n{} cases × {} methods in {:.1} s on {} threads ({:.0} cases/s)",
        n,
        opts.methods.len(),
        secs,
        rayon::current_num_threads(),
        n as f64 / secs
    );
    let oracle_secs =
        sphere_run::ORACLE_NANOS.load(std::sync::atomic::Ordering::Relaxed) as f64 * 1e-9;
    say!(
        "oracle alone: {:.1} s of CPU time, {:.0} cases/s per core (exact verdict, ill-posedness, Ziv roots)",
        oracle_secs,
        n as f64 / oracle_secs.max(1e-9)
    );
    // A shard for merging: the merge checks the tolerance table on the whole run
    if let (Some(p), Some(shard)) = (&a.shard_out, &shard) {
        write_report_files(&report, &a.json, &a.markdown)?;
        write_atomic(p, shard.to_json().as_bytes())?;
        say!(
            "shard {}/{} written to {}; the tolerance table is checked by `rayproof merge`",
            opts.shard.0,
            opts.shard.1,
            p.display()
        );
        return Ok(SphereAudit::Shard);
    }
    Ok(SphereAudit::Done(report))
}

/// The JSON of an audit with routines: the sphere's report fields (when audited), then
/// `shapes`, one report per routine family with rows shaped like the sphere's.
#[derive(serde::Serialize)]
struct AuditJson<'a> {
    #[serde(flatten)]
    sphere: Option<&'a sphere_run::Report>,
    #[serde(skip_serializing_if = "Option::is_none")]
    tool: Option<&'static str>,
    shapes: &'a [crate::audit::generic::ShapeReport],
    #[serde(skip_serializing_if = "Option::is_none")]
    robustness: Option<&'a crate::shapes::robustness::Robustness>,
}

/// Writes `--json` and `--markdown` of an audit: the sphere-only report is unchanged.
fn write_audit_files(
    sphere: Option<&sphere_run::Report>,
    shapes: &[crate::audit::generic::ShapeReport],
    robustness: Option<&crate::shapes::robustness::Robustness>,
    json: &Option<PathBuf>,
    markdown: &Option<PathBuf>,
) -> Result<()> {
    if shapes.is_empty() {
        if let Some(r) = sphere {
            return write_report_files(r, json, markdown);
        }
    }
    if let Some(p) = json {
        let v = AuditJson {
            sphere,
            tool: sphere.is_none().then_some(sphere_run::TOOL),
            shapes,
            robustness,
        };
        write_atomic(p, (serde_json::to_string_pretty(&v)? + "\n").as_bytes())?;
    }
    if let Some(p) = markdown {
        let mut text = sphere.map(sphere_run::markdown).unwrap_or_default();
        for r in shapes {
            text += "\n";
            text += &crate::audit::generic::markdown(r);
        }
        if let Some(r) = robustness {
            text += "\n";
            text += &crate::shapes::robustness::table(r, true);
        }
        write_atomic(p, text.as_bytes())?;
    }
    Ok(())
}

fn run_merge(m: MergeArgs) -> Result<u8> {
    check_output_dirs(&[&m.json, &m.markdown])?;
    // Read and check each shard on its own (exit 2 on a bad file)
    let mut shards = vec![];
    for p in &m.shards {
        let bytes = std::fs::read(p).with_context(|| format!("cannot read {}", p.display()))?;
        let shard =
            sphere_run::Shard::from_json(&bytes).map_err(|e| anyhow!("{}: {e}", p.display()))?;
        shards.push((p.display().to_string(), shard));
    }
    // Check that they make up one audit (exit 3), interleave and aggregate
    let (count, methods) = (shards.len(), shards[0].1.methods.len());
    let report = sphere_run::merge(shards)?;
    print_report(&report, m.worst);
    say!(
        "\n{} cases × {} methods merged from {} shards",
        cases_per_method(&report),
        methods,
        count
    );
    write_report_files(&report, &m.json, &m.markdown)?;
    Ok(tolerance_verdict(&report))
}

/// Cases per method: the cases of every precision × class of the first method's rows.
fn cases_per_method(report: &sphere_run::Report) -> u64 {
    let first = report.rows.first().map(|r| r.method);
    report
        .rows
        .iter()
        .filter(|r| Some(r.method) == first)
        .map(|r| r.cases)
        .sum()
}

/// Prints the table and the worst cases (the same for `audit` and `merge`).
fn print_report(report: &sphere_run::Report, worst: usize) {
    say_raw!("{}", sphere_run::table(report));
    if worst > 0 {
        say!("\nWorst cases (replay with the probe line):");
        say_raw!("{}", sphere_run::worst_cases(report, worst));
    }
}

/// Writes `--json` and `--markdown` (the same for `audit` and `merge`).
fn write_report_files(
    report: &sphere_run::Report,
    json: &Option<PathBuf>,
    markdown: &Option<PathBuf>,
) -> Result<()> {
    if let Some(p) = json {
        let text = serde_json::to_string_pretty(report)? + "\n";
        write_atomic(p, text.as_bytes())?;
    }
    if let Some(p) = markdown {
        write_atomic(p, sphere_run::markdown(report).as_bytes())?;
    }
    Ok(())
}

/// Compares with the tolerance table, prints the verdict and returns the exit code.
fn tolerance_verdict(report: &sphere_run::Report) -> u8 {
    let breaks = tolerance::check(report);
    if breaks.is_empty() {
        say!("tolerance table: every row within its entry");
        0
    } else {
        say!("tolerance table: {} row(s) out of bounds", breaks.len());
        for b in &breaks {
            say!("  {b}");
        }
        1
    }
}

fn run_render(a: RenderArgs) -> Result<u8> {
    use crate::render::{self, output, scene};
    let sc = scene::load(&a.scene)?;
    // Refuse before rendering if an output cannot be written
    check_output_dirs(&[&a.output, &a.png])?;
    let ov = render::Overrides {
        method: a.method,
        precision: a.precision.map(|p| p.name()),
        grid: a.spp,
        size: a.width.map(|w| {
            let fr = crate::render::export::Frame::of(&sc, Some(w), None);
            (fr.width, fr.height)
        }),
        force_all_effects: a.all_effects,
        progress: std::io::stderr().is_terminal(),
        flat: a.flat,
        ..Default::default()
    };
    let r = render::render(&sc, &ov);
    if a.explain {
        say!("effects for {}:", a.scene.display());
        for line in &r.effects.reasons {
            say!("  {line}");
        }
    }
    let c = &r.counts;
    say!(
        "{}×{} with {} in {}: {:.3} s\nrays: primary {}, shadow {}, reflection {}, refraction {} (total {})\n\
         missing every shape: primary {}, shadow (light reached) {}, reflection {}, refraction {}\n\
         tests: sphere {} ({} hits), other {}, BVH nodes {}",
        r.width, r.height, r.method, r.precision, r.seconds, c.primary, c.shadow, c.reflection, c.refraction, c.total(),
        c.primary_miss, c.shadow_miss, c.reflection_miss, c.refraction_miss,
        c.tests.sphere_tests, c.tests.sphere_hits, c.tests.other_tests, c.tests.bvh_nodes
    );
    if c.tests.implicit_tests > 0 {
        say!(
            "sphere tracing: {} implicit tests, {} field evaluations",
            c.tests.implicit_tests,
            c.tests.march_steps
        );
    }
    let lights = sc.file.lights.len() + sc.file.directional.len();
    say!("{}", render::budget_line(&r, lights));
    if let Some(out) = &a.output {
        let layers = output::Layers {
            depth: a.layers.iter().any(|l| l == "depth"),
            normal: a.layers.iter().any(|l| l == "normal"),
            rays: a.layers.iter().any(|l| l == "rays"),
        };
        output::write_exr(&r, out, layers)?;
        let stats = output::stats_json(&r, &a.scene.display().to_string(), lights);
        let side = PathBuf::from(format!("{}.json", out.display()));
        write_atomic(
            &side,
            (serde_json::to_string_pretty(&stats)? + "\n").as_bytes(),
        )?;
    }
    if let Some(png) = &a.png {
        output::write_png(&r, png)?;
    }
    Ok(0)
}

fn run_check(a: CheckArgs) -> Result<u8> {
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

/// `implicit-check`: both renders, the table, exit 1 if the certified mode differs in coverage.
fn run_implicit_check(a: ImplicitCheckArgs) -> Result<u8> {
    use crate::implicit::{check, subdiv::Mode};
    check_output_dirs(&[&a.json])?;
    let sc = crate::render::scene::load(&a.scene)?;
    let r = check::run(
        &sc,
        &check::Options {
            region: a.region as usize,
            width: a.width,
            repeat: a.repeat,
        },
    )?;
    say_raw!("{}", check::table(&r));
    if let Some(p) = &a.json {
        write_atomic(p, (serde_json::to_string_pretty(&r)? + "\n").as_bytes())?;
    }
    let broken = r
        .runs
        .iter()
        .filter(|x| x.mode == Mode::Certified)
        .filter_map(|x| x.versus_full.as_ref())
        .any(|c| c.lost + c.ghost > 0);
    if broken {
        say!("certified mode: coverage differs from per-pixel tracing (a Lipschitz bound does not hold)");
        return Ok(1);
    }
    say!("certified mode: 0 lost and 0 ghost pixels against per-pixel tracing");
    Ok(0)
}
