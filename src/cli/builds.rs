//! `rayproof builds`: one C routine under several compilers and flags, side by side (issue 49
//! item 3). Exit 0 when every build gives the baseline's verdicts, 1 when one flips a verdict,
//! 2 for bad usage or a source that does not build.

use super::*;
use anyhow::{anyhow, Context, Result};
use clap::Args;
use rayproof::audit::builds;
use rayproof::audit::plugin::parse_spec;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct BuildsArgs {
    /// The routine: FILE.c:SYMBOL, with the plugin signature (`rayproof header`); the precision
    /// from the symbol's `_f32`/`_f64` suffix or a third field `:f32`/`:f64`.
    #[arg(long)]
    pub source: String,
    /// The shape the routine answers.
    #[arg(long)]
    pub shape: String,
    /// Cases per class.
    #[arg(long, default_value_t = 2000)]
    pub cases: u64,
    /// Seed of the cases (as `audit --seed`).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Compilers (default: gcc and clang, each where installed).
    #[arg(long, value_delimiter = ',')]
    pub compiler: Vec<String>,
    /// Flipped cases printed (all are in the JSON).
    #[arg(long, default_value_t = 10)]
    pub show: usize,
    /// Seconds per batch for each build's worker.
    #[arg(long, default_value_t = 60)]
    pub timeout: u64,
    /// Write the comparison as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub(super) fn run_builds(a: BuildsArgs) -> Result<u8> {
    let (source, symbol, prec) = source_of(&a.source, "--source")?;
    let shape = rayproof::shapes::shape_by_name(&a.shape)
        .ok_or_else(|| anyhow!("--shape {}: unknown shape", a.shape))?;
    if !(1..=1_000_000).contains(&a.cases) {
        anyhow::bail!("--cases {}: from 1 to 1000000", a.cases);
    }
    if let Some(p) = &a.json {
        // Never over the source it builds
        rayproof::output::check_outputs(&[p.as_path()], &[], &[source.as_path()])?;
        rayproof::output::check_json_target(p)?;
    }
    let compilers = compilers(&a.compiler)?;
    let fma = builds::machine_has_fma();
    if !fma {
        say!("this machine has no FMA: only the builds with contraction off are made");
    }
    let list = builds::standard(
        &compilers.iter().map(String::as_str).collect::<Vec<_>>(),
        fma,
    );
    let worker = std::env::current_exe().context("cannot find rayproof's own executable")?;
    if a.timeout == 0 {
        anyhow::bail!("--timeout 0: give at least 1 second per batch");
    }
    let timeout = std::time::Duration::from_secs(a.timeout);
    let spec = format!("{}:{symbol}:{}", source.display(), prec.name());
    let loaded = builds::load_all(
        &spec,
        &source,
        &symbol,
        prec,
        &list,
        shape.info(),
        &worker,
        timeout,
        &|b| b.name.clone(),
    )
    .map_err(|e| anyhow!(e))?;
    for (b, line) in &loaded {
        say!("{:<16} {line}", rayproof::audit::Method::name(b));
    }
    let methods: Vec<(&str, String, &dyn rayproof::shapes::shape::Method)> = loaded
        .iter()
        .map(|(b, l)| {
            (
                rayproof::audit::Method::name(b),
                l.clone(),
                b as &dyn rayproof::shapes::shape::Method,
            )
        })
        .collect();
    // A build's routine that crashes, hangs or answers no answer: exit 4, as for `audit --plugin`
    let c = builds::compare(shape, &methods, prec, a.seed, a.cases)
        .map_err(|e| anyhow::Error::new(rayproof::audit::run::MethodFailed(e)))?;
    say!();
    say!(
        "{:<16} {:>8} {:>7} {:>11} {:>7} {:>12} {:>12}",
        "build",
        "cases",
        "wrong",
        "worst ulps",
        "flips",
        "flips right",
        "adds ulps"
    );
    for r in &c.rows {
        say!(
            "{:<16} {:>8} {:>7} {:>11} {:>7} {:>12} {:>12}",
            r.build,
            r.cases,
            r.wrong,
            r.worst_ulps,
            r.flips,
            r.flips_right,
            r.added_ulps
        );
    }
    let names: Vec<&str> = c.rows.iter().map(|r| r.build.as_str()).collect();
    say!();
    say!(
        "{} cases where the builds disagree on hit or miss (flips against {}){}",
        c.flips.len(),
        names[0],
        if c.flips.is_empty() { "" } else { ":" }
    );
    for f in c.flips.iter().take(a.show) {
        let hits: Vec<String> = names
            .iter()
            .zip(&f.hits)
            .map(|(n, h)| format!("{n} {}", if *h { "hit" } else { "miss" }))
            .collect();
        say!(
            "  {} (exact: {}): {}\n    {} --plugin LIB:{symbol}:{}",
            f.class,
            if f.exact_hit { "hit" } else { "miss" },
            hits.join(", "),
            f.probe,
            prec.name()
        );
    }
    if c.flips.len() > a.show {
        say!("  … {} more (--show, --json)", c.flips.len() - a.show);
    }
    if let Some(p) = &a.json {
        rayproof::output::write_json(p, &c)?;
    }
    Ok(u8::from(!c.flips.is_empty()))
}

/// The compilers of the builds: those asked for (each must run, none named twice), or gcc and
/// clang where installed (each missing one said on stderr).
fn compilers(asked: &[String]) -> Result<Vec<String>> {
    let runs = |c: &str| {
        let line = format!("{} --version", rayproof::audit::exec::shell_word(c));
        rayproof::process::run_with_timeout(
            c,
            &line,
            None,
            String::new(),
            std::time::Duration::from_secs(20),
        )
        .is_ok()
    };
    if !asked.is_empty() {
        if let Some(c) = asked.iter().find(|c| !runs(c)) {
            anyhow::bail!("--compiler {c}: it does not run (`{c} --version` failed)");
        }
        let mut seen = std::collections::HashSet::new();
        if let Some(c) = asked
            .iter()
            .find(|c| !seen.insert(builds::compiler_name(c)))
        {
            anyhow::bail!("--compiler {c}: named twice");
        }
        return Ok(asked.to_vec());
    }
    let found: Vec<String> = ["gcc", "clang"]
        .into_iter()
        .filter(|c| runs(c))
        .map(String::from)
        .collect();
    for c in ["gcc", "clang"]
        .iter()
        .filter(|c| !found.iter().any(|f| f == *c))
    {
        eprintln!("{c}: not installed, its builds left out");
    }
    if found.is_empty() {
        anyhow::bail!("no C compiler: neither gcc nor clang runs (give --compiler)");
    }
    Ok(found)
}

/// The source file of a `FILE.c:SYMBOL` spec, checked (a regular file), and its symbol and
/// precision.
fn source_of(spec: &str, flag: &str) -> Result<(PathBuf, String, rayproof::numerics::Precision)> {
    let (file, symbol, prec) = parse_spec(spec).map_err(|e| anyhow!("{flag}: {e}"))?;
    let source = Path::new(&file);
    if !source.exists() {
        anyhow::bail!("{flag}: no file {file}");
    }
    if !source.is_file() {
        anyhow::bail!("{flag} {file}: not a regular file");
    }
    Ok((
        source.canonicalize().context(flag.to_string())?,
        symbol,
        prec,
    ))
}

/// `--source FILE.c:SYMBOL` of the commands that audit outside routines: the standard builds
/// (those `only` names, or all) of gcc and clang where installed, each loaded as a routine of
/// `shape` named `STEM.BUILD`, with its precisions; each build's command line is printed on
/// stderr.
pub(super) fn built(
    spec: &str,
    only: &[String],
    shape: &rayproof::shapes::shape::ShapeInfo,
    timeout: std::time::Duration,
) -> Result<
    Vec<(
        Box<dyn rayproof::audit::Method + Send>,
        Vec<rayproof::numerics::Precision>,
    )>,
> {
    let (source, symbol, prec) = source_of(spec, "--source")?;
    let compilers = compilers(&[])?;
    let mut list = builds::standard(
        &compilers.iter().map(String::as_str).collect::<Vec<_>>(),
        builds::machine_has_fma(),
    );
    if let Some(n) = only.iter().find(|n| !list.iter().any(|b| &&b.name == n)) {
        let known: Vec<&str> = list.iter().map(|b| b.name.as_str()).collect();
        anyhow::bail!(
            "--build {n}: not a build of this machine (known: {})",
            known.join(", ")
        );
    }
    if !only.is_empty() {
        list.retain(|b| only.contains(&b.name));
    }
    let worker = std::env::current_exe().context("cannot find rayproof's own executable")?;
    let stem = symbol.trim_end_matches("_f32").trim_end_matches("_f64");
    let loaded = builds::load_all(
        spec,
        &source,
        &symbol,
        prec,
        &list,
        shape,
        &worker,
        timeout,
        &|b| format!("{stem}.{}", b.name),
    )
    .map_err(|e| anyhow!("--source {spec}: {e}"))?;
    Ok(loaded
        .into_iter()
        .map(|(b, line)| {
            eprintln!("{:<24} {line}", rayproof::audit::Method::name(&b));
            let has = b.precisions();
            (Box::new(b) as Box<dyn rayproof::audit::Method + Send>, has)
        })
        .collect())
}
