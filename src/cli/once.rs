//! `rayproof once`: exactly one hit per mesh (issue 49 item 4). Rays through the shared vertices
//! and edges of height-field grids, fans and icospheres (sizes 1e-4 to 1e7, near and far), each
//! crossing the surface exactly once, rounded or exactly through the vertex or edge; per
//! triangle routine, the rays it leaks (0 hits), doubles (2 or more at one t), splits (hits at
//! different t) or answers with a t that is not finite and positive. The built-in routines are
//! reported, except `watertight_wide` (robust by design); it and a routine of yours (`--exec`,
//! `--plugin`) are judged: exit 0 when none leaks,
//! splits, answers a bad t or a hit that cannot be the crossing, 1 otherwise, 2 bad usage, 4 a routine that breaks its contract,
//! crashes or hangs.

use super::*;
use anyhow::Result;
use clap::Args;
use rayproof::audit::robustness::once::{self, Routine};
use rayproof::numerics::Precision;
use rayproof::shapes::triangle;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct OnceArgs {
    /// Meshes per kind, scene size and placement.
    #[arg(long, default_value_t = 8)]
    pub per_cell: u64,
    /// Seed of the meshes and rays.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Precisions (default: both; a plugin's own).
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// Built-in triangle routines (default: all, or none when a routine of yours is given):
    /// chapter, moller_trumbore, watertight, watertight_wide.
    #[arg(long, value_delimiter = ',')]
    pub method: Vec<String>,
    /// A triangle routine of yours (`--exec`, `--plugin`, `--name`, `--timeout`: the
    /// triangle's protocol, `rayproof header --exec`).
    #[command(flatten)]
    pub outside: super::outside::OutsideArgs,
    /// Write the rows as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub(super) fn run_once(a: OnceArgs) -> Result<u8> {
    if !(1..=1_000).contains(&a.per_cell) {
        anyhow::bail!("--per-cell {}: from 1 to 1000", a.per_cell);
    }
    let info = rayproof::shapes::shape_by_name("triangle")
        .expect("the triangle shape")
        .info();
    let outside = a.outside.methods(&info)?;
    let builtin = |n: &str| triangle::METHODS.iter().position(|m| m.name == n);
    for (m, _) in &outside {
        if builtin(m.name()).is_some() {
            anyhow::bail!(
                "--name {}: a built-in routine's name; give another",
                m.name()
            );
        }
    }
    let chosen: Vec<usize> = match (a.method.is_empty(), outside.is_empty()) {
        (true, true) => (0..triangle::METHODS.len()).collect(),
        (true, false) => vec![],
        _ => a
            .method
            .iter()
            .map(|n| {
                builtin(n).ok_or_else(|| {
                    let known: Vec<&str> = triangle::METHODS.iter().map(|m| m.name).collect();
                    anyhow::anyhow!(
                        "--method {n}: not a triangle routine (known: {})",
                        known.join(", ")
                    )
                })
            })
            .collect::<Result<_>>()?,
    };
    let precs = super::outside::OutsideArgs::precisions(&a.precision, &outside)?;
    if let Some(p) = &a.json {
        a.outside.check_json(p)?;
    }
    let routines: Vec<Routine> = chosen
        .into_iter()
        .map(Routine::BuiltIn)
        .chain(outside.iter().map(|(m, _)| Routine::Outside(m.as_ref())))
        .collect();
    let rows = match once::rows(a.seed, &routines, &precs, a.per_cell).and_then(|r| {
        // A child kept for the run ends here, and how it ended is checked
        for (m, _) in &outside {
            m.finish()?;
        }
        Ok(r)
    }) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {}", rayproof::images::one_line(&e));
            return Ok(4);
        }
    };
    say!(
        "{:<16} {:<4} {:<6} {:<12} {:>6} {:>6} {:>8} {:>6} {:>9} {:>5} {:>5} {:>10}  judged",
        "routine",
        "prec",
        "mesh",
        "aim",
        "rays",
        "leaks",
        "doubles",
        "split",
        "split ulps",
        "bad",
        "wrong",
        "leak from"
    );
    for r in &rows {
        say!(
            "{:<16} {:<4} {:<6} {:<12} {:>6} {:>6} {:>8} {:>6} {:>9} {:>5} {:>5} {:>10}  {}",
            r.routine,
            r.precision,
            r.mesh,
            r.aim,
            r.rays,
            r.leaks,
            r.doubles,
            r.split,
            r.split_ulps,
            r.bad,
            r.wrong,
            r.first_leak.map_or("-".into(), |s| format!("1e{s}")),
            r.verdict
        );
    }
    if let Some(d) = rows.iter().find(|r| r.meshes_dropped > 0) {
        say!(
            "{} {} meshes left out: rounding to {} may have made them not convex",
            d.meshes_dropped,
            d.mesh,
            d.precision
        );
    }
    for r in rows.iter().filter(|r| r.first.is_some()) {
        say!(
            "first {} ({} {} {} {}):",
            r.first.as_deref().unwrap_or_default(),
            r.routine,
            r.precision,
            r.mesh,
            r.aim
        );
        for l in r.replay.iter().take(3) {
            say!("  {l}");
        }
        if r.replay.len() > 3 {
            say!("  ({} more in --json)", r.replay.len() - 3);
        }
    }
    if let Some(p) = &a.json {
        rayproof::output::write_json(p, &rows)?;
    }
    let failed = rows.iter().any(|r| r.verdict == "fail");
    say!(
        "verdict: {}",
        match (failed, rows.iter().any(|r| r.verdict == "pass")) {
            (true, _) => {
                "FAIL (a judged routine leaked, split, answered a bad t or a hit that is not the crossing)"
            }
            (false, true) => "pass",
            (false, false) => "reported (no judged routine)",
        }
    );
    Ok(failed as u8)
}
