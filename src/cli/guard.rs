//! `rayproof guard`: the box that guards the primitive (issue 49 item 1): slab tests with
//! `t_max` = a primitive's rounded hit, on boxes that hold that hit; a culled box is lost
//! geometry. A user's guard comes in as `--exec CMD` or `--plugin PATH:SYMBOL` (the 13 values
//! `o d lo hi t_max` in, `1 HIT` out: `rayproof header --guard`). Exit 0 when every judged guard
//! (`ize`, and every guard of yours) loses nothing, 1 otherwise, 2 bad usage, 4 a guard of
//! yours that breaks its contract, crashes or hangs.

use super::*;
use anyhow::Result;
use clap::Args;
use rayproof::audit::robustness::guard::{self, Guard, GUARDS};
use rayproof::numerics::Precision;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct GuardArgs {
    /// Cases per class, scene size and placement.
    #[arg(long, default_value_t = 32)]
    pub per_cell: u64,
    /// Seed of the cases.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Precisions (default: both; a plugin's own).
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// Built-in guards (default: all, or none when a guard of yours is given): naive_slab,
    /// williams, pbrt, ize.
    #[arg(long, value_delimiter = ',')]
    pub guard: Vec<String>,
    /// A guard of yours (`--exec`, `--plugin`, `--name`, `--timeout`).
    #[command(flatten)]
    pub outside: super::outside::OutsideArgs,
    /// Write the rows as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Replay one case: GUARD PRECISION and the 13 values (o, d, lo, hi, t_max) as printed.
    #[arg(long, num_args = 15, value_name = "ARG", allow_hyphen_values = true)]
    pub replay: Vec<String>,
}

pub(super) fn run_guard(a: GuardArgs) -> Result<u8> {
    let outside = a.outside.methods(&guard::INFO)?;
    for (m, _) in &outside {
        if GUARDS.contains(&m.name()) {
            anyhow::bail!("--name {}: a built-in guard's name; give another", m.name());
        }
    }
    if !a.replay.is_empty() {
        return replay(&a.replay, &outside);
    }
    if !(1..=100_000).contains(&a.per_cell) {
        anyhow::bail!("--per-cell {}: from 1 to 100000", a.per_cell);
    }
    let names: Vec<&'static str> = match (a.guard.is_empty(), outside.is_empty()) {
        (true, true) => GUARDS.to_vec(),
        (true, false) => vec![],
        _ => a
            .guard
            .iter()
            .map(|g| {
                GUARDS.iter().copied().find(|k| k == g).ok_or_else(|| {
                    anyhow::anyhow!("--guard {g}: not a guard (known: {})", GUARDS.join(", "))
                })
            })
            .collect::<Result<_>>()?,
    };
    let precs = super::outside::OutsideArgs::precisions(&a.precision, &outside)?;
    if let Some(p) = &a.json {
        a.outside.check_json(p)?;
    }
    let guards: Vec<Guard> = names
        .iter()
        .map(|g| Guard::BuiltIn(g))
        .chain(outside.iter().map(|(m, _)| Guard::Outside(m.as_ref())))
        .collect();
    let rows = match guard::rows(a.seed, &guards, &precs, a.per_cell, true) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {}", rayproof::images::one_line(&e));
            return Ok(4);
        }
    };
    say!(
        "{:<14} {:<4} {:<8} {:>7} {:>6} {:>10} {:>9}  verdict",
        "guard",
        "prec",
        "class",
        "cases",
        "lost",
        "from size",
        "ns/test"
    );
    for r in &rows {
        say!(
            "{:<14} {:<4} {:<8} {:>7} {:>6} {:>10} {:>9.2}  {}",
            r.guard,
            r.precision,
            r.class,
            r.cases,
            r.lost,
            r.first_scale.map_or("-".into(), |s| format!("1e{s}")),
            r.ns_per_test.unwrap_or(f64::NAN),
            r.verdict
        );
    }
    for r in rows.iter().filter(|r| r.replay.is_some()) {
        say!(
            "first lost ({} {} {}): {}",
            r.guard,
            r.precision,
            r.class,
            r.replay.as_deref().unwrap_or_default()
        );
    }
    if let Some(p) = &a.json {
        rayproof::output::write_json(p, &rows)?;
    }
    let failed = rows.iter().any(|r| r.verdict == "fail");
    say!(
        "verdict: {}",
        if failed {
            "FAIL (a judged guard lost geometry, or ran no case)"
        } else {
            "pass"
        }
    );
    Ok(failed as u8)
}

/// `--replay GUARD PREC v×13`: the guard's answer (exit 0 entered, 1 culled: the box holds a
/// hit at t ≤ t_max's exact value, so a cull is lost geometry).
fn replay(args: &[String], outside: &[super::outside::Outside]) -> Result<u8> {
    let prec = parse_precision(&args[1]).map_err(anyhow::Error::msg)?;
    let mut v = [0f64; 13];
    for (k, s) in args[2..].iter().enumerate() {
        let x = rayproof::audit::hexfloat::parse_exact(s)
            .ok_or_else(|| anyhow::anyhow!("--replay value {} ({s}): not a number", k + 1))?;
        let exact = match prec {
            Precision::F32 => (x as f32) as f64 == x,
            Precision::F64 => true,
        };
        if !x.is_finite() || !exact {
            anyhow::bail!(
                "--replay value {} ({s}): not a finite value of {}",
                k + 1,
                prec.name()
            );
        }
        v[k] = x;
    }
    let admitted = match GUARDS.iter().copied().find(|k| *k == args[0]) {
        Some(g) => guard::admits(g, prec, &v),
        None => {
            let (m, _) = outside
                .iter()
                .find(|(m, _)| m.name() == args[0])
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "--replay {}: not a guard (built-in: {}; or give yours with --exec/--plugin and --name)",
                        args[0],
                        GUARDS.join(", ")
                    )
                })?;
            let c = guard::Case { values: v };
            match guard::admits_one(m.as_ref(), prec, &c) {
                Ok(a) => a,
                Err(e) => {
                    eprintln!("error: {}", rayproof::images::one_line(&e));
                    return Ok(4);
                }
            }
        }
    };
    say!(
        "{} {}: {}",
        args[0],
        prec.name(),
        if admitted {
            "hit (the box is entered)"
        } else {
            "MISS: the box is culled"
        }
    );
    Ok((!admitted) as u8)
}
