//! `rayproof spawn`: spawn rules audited both ways (issue 47; the method in
//! `rayproof::audit::robustness::spawn`).

use super::*;
use anyhow::{anyhow, bail, Result};
use rayproof::audit::robustness::spawn::{
    self, BuiltIn, OutsideRule, SpawnRow, SpawnRule, BUILT_IN,
};
use rayproof::numerics::Precision;
use rayproof::output::{check_outputs, Outputs};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct SpawnArgs {
    /// A built-in rule (repeatable): pbrt, wachter_binder, tmin_1e-4, mitsuba2_epsilon, none.
    /// Default: all five, unless --exec gives rules of your own.
    #[arg(long, value_name = "NAME")]
    pub rule: Vec<String>,
    /// Rules of yours: `--exec CMD` (one query per line, `rayproof header --spawn`), `--plugin
    /// PATH:SYMBOL` (its C ABI, the same header), named by `--name` (plugins first, then
    /// commands), each batch under `--timeout` seconds.
    #[command(flatten)]
    pub outside: super::outside::OutsideArgs,
    /// Precisions (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "f32,f64", value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// The triangle routine run on the spawned rays beside the exact oracle (the renderer's
    /// intersector): a built-in triangle method (default `watertight`, pbrt-v4's; `rayproof
    /// probe --help` lists them), `exec:CMD` or `plugin:PATH:SYMBOL` (a triangle routine as
    /// `audit --shape triangle` takes one, `rayproof header`).
    #[arg(long, value_name = "METHOD", default_value = "watertight")]
    pub intersector: String,
    /// Triangles per precision × scene size × placement (each with 8 spawned rays).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u64).range(1..=4096))]
    pub per_cell: u64,
    /// The seed of the triangles and rays.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A judged rule (yours, and pbrt's) also fails when, in some cell, the smallest gap it
    /// resolves is over this many ulps of the hit point (it starts past neighbours that close:
    /// light leaks). Default: the gap is reported, not judged.
    #[arg(long, value_name = "ULPS", value_parser = parse_ulps)]
    pub max_gap_ulps: Option<f64>,
    /// Write the rows as JSON.
    #[arg(long, conflicts_with = "replay")]
    pub json: Option<PathBuf>,
    /// Write the table as Markdown.
    #[arg(long, conflicts_with = "replay")]
    pub markdown: Option<PathBuf>,
    /// Write the figures to this directory (made by rayproof): the smallest resolved gap
    /// against scene size per rule and precision, near and far (`gap-near.svg`,
    /// `gap-far.svg`), and self-hits against the widest gap (`pareto.svg`).
    #[arg(long, value_name = "DIR", conflicts_with = "replay")]
    pub plots: Option<PathBuf>,
    /// Replay one spawned ray (the values of a replay line, after `--`): the rule's origin and
    /// t_min, the exact self-hit and the reach.
    #[arg(long)]
    pub replay: bool,
    /// The replay's values: the 19 of the query, then the triangle's 9.
    #[arg(last = true, allow_hyphen_values = true)]
    pub values: Vec<String>,
}

fn parse_ulps(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x >= 0.0 && x.is_finite() => Ok(x),
        _ => Err(format!("'{s}' is not a number of ulps (finite, >= 0)")),
    }
}

/// The rules the arguments name: built-ins, then yours.
fn rules(a: &SpawnArgs) -> Result<Vec<Box<dyn SpawnRule>>> {
    let names: Vec<String> = if a.rule.is_empty() && !a.outside.any() {
        BUILT_IN.iter().map(|(n, _)| n.to_string()).collect()
    } else {
        a.rule.clone()
    };
    spawn_rules(&names, &a.outside, &a.precision, "--name")
}

/// The options that bring back the run's `--intersector` in a replay line (empty for the
/// default), shell-quoted.
fn intersector_option(a: &SpawnArgs) -> String {
    if a.intersector == "watertight" {
        String::new()
    } else {
        format!(
            "--intersector {}",
            rayproof::audit::exec::shell_word(&a.intersector)
        )
    }
}

/// The intersector `--intersector` names: a built-in triangle method, `exec:CMD` or
/// `plugin:PATH:SYMBOL` (a triangle routine, through the outside-routine machinery).
fn intersector(a: &SpawnArgs) -> Result<Box<dyn rayproof::audit::Method>> {
    let triangle = rayproof::shapes::shape_by_name("triangle").expect("registered");
    let info = triangle.info();
    let (builtin, theirs) = super::outside::OutsideArgs::from_specs(
        std::slice::from_ref(&a.intersector),
        &[],
        a.outside.exec_timeout,
    );
    if !builtin.is_empty() {
        let index = info
            .methods
            .iter()
            .position(|m| m.name == a.intersector)
            .ok_or_else(|| {
                anyhow!(
                    "--intersector '{}': not a triangle method (built-in: {}; or exec:CMD, plugin:PATH:SYMBOL)",
                    a.intersector,
                    info.methods.iter().map(|m| m.name).collect::<Vec<_>>().join(", ")
                )
            })?;
        return Ok(Box::new(rayproof::shapes::shape::Builtin {
            shape: triangle,
            index,
        }));
    }
    let (m, has) = theirs.methods(info)?.remove(0);
    if let Some(p) = a
        .precision
        .iter()
        .find(|p| has.as_ref().is_some_and(|h| !h.contains(p)))
    {
        bail!(
            "--intersector {}: no {} symbol (give --precision, or a :{} symbol)",
            a.intersector,
            p.name(),
            p.name()
        );
    }
    Ok(m)
}

/// Spawn rules: the built-ins `builtin` names, then the routines of `outside` (plugins, then
/// commands, made for [`spawn::INFO`]). Names are checked and unique.
pub(super) fn spawn_rules(
    builtin: &[String],
    outside: &super::outside::OutsideArgs,
    precisions: &[Precision],
    flag: &str,
) -> Result<Vec<Box<dyn SpawnRule>>> {
    let mut out: Vec<Box<dyn SpawnRule>> = vec![];
    for n in builtin {
        let r = BuiltIn::named(n).ok_or_else(|| {
            anyhow!(
                "unknown spawn rule '{n}' (built-in: {})",
                BUILT_IN.map(|(n, _)| n).join(", ")
            )
        })?;
        out.push(Box::new(r));
    }
    for (m, has) in outside.methods(&spawn::INFO)? {
        if BuiltIn::named(m.name()).is_some() {
            bail!("{flag} {}: a built-in rule's name; give another", m.name());
        }
        // A plugin answers the precisions it has symbols for: asked another, a usage error
        if let Some(p) = precisions
            .iter()
            .find(|p| has.as_ref().is_some_and(|h| !h.contains(p)))
        {
            bail!(
                "--plugin {}: no {} symbol (give --precision, or a :{} symbol)",
                m.name(),
                p.name(),
                p.name()
            );
        }
        out.push(Box::new(OutsideRule(m)));
    }
    for (i, r) in out.iter().enumerate() {
        if out[..i].iter().any(|x| x.name() == r.name()) {
            bail!("the spawn rule {} is named twice", r.name());
        }
    }
    Ok(out)
}

pub(super) fn run_spawn(a: SpawnArgs) -> Result<u8> {
    let rules = rules(&a)?;
    if a.replay {
        return replay(&a, &rules);
    }
    if !a.values.is_empty() {
        bail!("values after `--` are for --replay");
    }
    let files: Vec<&Path> = [&a.json, &a.markdown]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    let dirs: Vec<&Path> = a.plots.iter().map(|p| p.as_path()).collect();
    let inputs = a.outside.input_files();
    let inputs: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    check_outputs(&files, &dirs, &inputs)?;
    let mut precs = a.precision.clone();
    precs.dedup();
    let cells = spawn::cells(a.seed, &precs, a.per_cell);
    let mut rows: Vec<SpawnRow> = vec![];
    let intersector = intersector(&a)?;
    let failed = |e| anyhow!(rayproof::audit::run::MethodFailed(e));
    for r in &rules {
        rows.extend(
            spawn::rows_with(
                r.as_ref(),
                &cells,
                intersector.as_ref(),
                &intersector_option(&a),
            )
            .map_err(failed)?,
        );
    }
    intersector.finish().map_err(failed)?;
    // Verdicts: a rule of yours and pbrt's (the crate's own) are held to no self-hit, no ray
    // behind the surface (and --max-gap-ulps); the other built-ins are reported
    let goal = |x: &SpawnRow| {
        spawn::default_goal(&x.rule, BuiltIn::named(&x.rule).is_none()).map(|g| spawn::Goal {
            max_gap_ulps: a.max_gap_ulps,
            ..g
        })
    };
    spawn::judge_rows(&mut rows, &goal);
    say_raw!("{}", spawn::markdown(&rows));
    let mut failed = vec![];
    say!();
    for r in &rules {
        let mine: Vec<&SpawnRow> = rows.iter().filter(|x| x.rule == r.name()).collect();
        let rays: u64 = mine.iter().map(|x| x.rays).sum();
        let hits: u64 = mine.iter().map(|x| x.self_hits).sum();
        let behind: u64 = mine.iter().map(|x| x.behind).sum();
        let widest = mine
            .iter()
            .filter(|x| x.rays > 0)
            .max_by(|a, b| a.gap_ulps.total_cmp(&b.gap_ulps));
        let worst = mine
            .iter()
            .filter(|x| x.self_hits > 0)
            .max_by_key(|x| x.self_hits);
        let fails = mine.iter().filter(|x| x.verdict == "fail").count();
        let verdict = if mine.iter().all(|x| x.verdict == "reported") {
            "reported".to_string()
        } else if fails > 0 || mine.is_empty() {
            failed.push(r.name().to_string());
            format!("FAIL in {fails} of {} cells", mine.len())
        } else {
            "pass".to_string()
        };
        let gap = widest.map_or(String::new(), |w| {
            format!(
                "; widest gap {:.3e} ({} ulps of |p|) at {} scene size 1e{} {}{}",
                w.gap,
                spawn::ulps_text(w.gap_ulps),
                w.precision,
                w.scale,
                w.placement,
                if a.max_gap_ulps.is_some_and(|m| w.gap_ulps > m) {
                    ", over --max-gap-ulps"
                } else {
                    ""
                }
            )
        });
        say!(
            "{}: {verdict}: {hits} self-hits, {behind} behind the surface in {rays} spawned rays{gap}{}",
            r.name(),
            worst.map_or(String::new(), |w| format!(
                " (most: {} of {} at {} scene size 1e{} {}; replay: {})",
                w.self_hits,
                w.rays,
                w.precision,
                w.scale,
                w.placement,
                w.self_hit_replay.as_deref().unwrap_or("")
            ))
        );
        if let Some(f) = mine.iter().find(|x| x.verdict == "fail") {
            say!("  first failing cell: {}", spawn::failure(f));
        }
    }
    let mut out = Outputs::new();
    if let Some(p) = &a.json {
        out.write(p, (serde_json::to_string_pretty(&rows)? + "\n").as_bytes())?;
    }
    if let Some(p) = &a.markdown {
        out.write(p, spawn::markdown(&rows).as_bytes())?;
    }
    if let Some(p) = &a.plots {
        let figures = rayproof::report::spawn::figures(&rows);
        out.dir_with(p, |tmp| {
            for (name, svg) in &figures {
                std::fs::write(tmp.join(name), svg)?;
            }
            Ok(())
        })?;
    }
    out.commit()?;
    if failed.is_empty() {
        say!("verdict: pass");
        Ok(0)
    } else {
        say!(
            "verdict: FAIL ({}: self-hits, rays behind the surface or a gap over --max-gap-ulps)",
            failed.join(", ")
        );
        Ok(1)
    }
}

fn replay(a: &SpawnArgs, rules: &[Box<dyn SpawnRule>]) -> Result<u8> {
    let [rule] = rules else {
        bail!("--replay takes one rule (--rule NAME, --exec CMD or --plugin PATH:SYMBOL)");
    };
    let [prec] = a.precision[..] else {
        bail!("--replay takes one --precision");
    };
    let values: Vec<f64> = a
        .values
        .iter()
        .map(|s| {
            // Read exactly (as f64) first: a value the precision cannot hold is refused, not rounded
            let v = rayproof::numerics::real::parse_number_in(s, "f64").map_err(|e| anyhow!(e))?;
            if prec == Precision::F32 && v as f32 as f64 != v {
                bail!("{s}: not a value of f32 (a replay's values are exact in its precision)");
            }
            Ok(v)
        })
        .collect::<Result<_>>()?;
    let ray = spawn::ray_of(&values, prec).map_err(|e| anyhow!(e))?;
    let s = rule
        .spawn(prec, &[ray.query.clone()])
        .map_err(|e| anyhow!(rayproof::audit::run::MethodFailed(e)))?[0];
    let intersector = intersector(a)?;
    let t = spawn::intersect(intersector.as_ref(), prec, &[(&ray, &s)])
        .and_then(|t| intersector.finish().map(|_| t[0]))
        .map_err(|e| anyhow!(rayproof::audit::run::MethodFailed(e)))?;
    if !spawn::finite(&s) {
        bail!("{}", spawn::not_finite(rule.name(), &s, prec, &ray.query));
    }
    let v = spawn::judge(&ray, &s, t);
    let hex = |x: f64| rayproof::shapes::shape::hex_text(x);
    say!(
        "rule {}: origin {} {} {}, t_min {}",
        rule.name(),
        hex(s.origin[0]),
        hex(s.origin[1]),
        hex(s.origin[2]),
        hex(s.t_min)
    );
    match v.self_hit_t {
        Some(t) => say!(
            "self-hit: the exact oracle finds the triangle again at t = {} (> t_min)",
            hex(t)
        ),
        None => say!("self-hit: none (the exact oracle)"),
    }
    say!(
        "self-hit by the intersector {}: {}",
        intersector.name(),
        if v.self_hit_intersector { "yes" } else { "no" }
    );
    let ulps = v.reach / ray.hit_ulp;
    let too_wide = a.max_gap_ulps.is_some_and(|m| !(ulps <= m));
    if v.reach < 0.0 {
        say!(
            "behind the surface: the new ray starts taking hits {:e} ({}) behind its own surface",
            -v.reach,
            hex(-v.reach)
        );
    } else {
        say!(
            "reach: {:e} ({}, {} ulps of max|p|) above the surface: a parallel neighbour nearer than that is skipped{}",
            v.reach,
            hex(v.reach),
            spawn::ulps_text(ulps),
            if too_wide { "; over --max-gap-ulps" } else { "" }
        );
    }
    Ok(if v.self_hit || v.reach < 0.0 || too_wide {
        1
    } else {
        0
    })
}
