//! `rayproof audit` and `rayproof merge`.

use super::*;
use crate::audit::sphere_run::{self, AuditOptions};
use crate::numerics::Precision;
use crate::output::{check_output_dirs, write_atomic};
use crate::shapes::sphere::cases::Class;
use crate::shapes::sphere::methods::METHODS;
use crate::shapes::sphere::tolerance;
use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

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

pub(super) fn run_audit(a: AuditArgs) -> Result<u8> {
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

pub(super) enum SphereAudit {
    Done(sphere_run::Report),
    /// A shard file was written; the merge checks the tolerance table.
    Shard,
}

/// The sphere's audit: prints its table and, for `--shard-out`, writes the shard file.
pub(super) fn audit_sphere(a: &AuditArgs, precisions: Vec<Precision>) -> Result<SphereAudit> {
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
pub(super) struct AuditJson<'a> {
    #[serde(flatten)]
    sphere: Option<&'a sphere_run::Report>,
    #[serde(skip_serializing_if = "Option::is_none")]
    tool: Option<&'static str>,
    shapes: &'a [crate::audit::generic::ShapeReport],
    #[serde(skip_serializing_if = "Option::is_none")]
    robustness: Option<&'a crate::shapes::robustness::Robustness>,
}

/// Writes `--json` and `--markdown` of an audit: the sphere-only report is unchanged.
pub(super) fn write_audit_files(
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

pub(super) fn run_merge(m: MergeArgs) -> Result<u8> {
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
pub(super) fn cases_per_method(report: &sphere_run::Report) -> u64 {
    let first = report.rows.first().map(|r| r.method);
    report
        .rows
        .iter()
        .filter(|r| Some(r.method) == first)
        .map(|r| r.cases)
        .sum()
}

/// Prints the table and the worst cases (the same for `audit` and `merge`).
pub(super) fn print_report(report: &sphere_run::Report, worst: usize) {
    say_raw!("{}", sphere_run::table(report));
    if worst > 0 {
        say!("\nWorst cases (replay with the probe line):");
        say_raw!("{}", sphere_run::worst_cases(report, worst));
    }
}

/// Writes `--json` and `--markdown` (the same for `audit` and `merge`).
pub(super) fn write_report_files(
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
pub(super) fn tolerance_verdict(report: &sphere_run::Report) -> u8 {
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
