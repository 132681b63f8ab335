//! `rayproof once`: exactly one hit per mesh (issue 49 item 4). Rays through the shared vertices
//! and edges of height-field grids and fans (sizes 1e-4 to 1e7, near and far), each crossing the
//! surface exactly once; per triangle routine, the rays it leaks (0 hits), doubles (2 or more at
//! one t) or splits (hits at different t). The built-in routines are reported: exit 0, 2 bad
//! usage.

use super::*;
use anyhow::Result;
use clap::Args;
use rayproof::audit::robustness::once;
use rayproof::numerics::Precision;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct OnceArgs {
    /// Meshes per kind, scene size and placement.
    #[arg(long, default_value_t = 8)]
    pub per_cell: u64,
    /// Seed of the meshes and rays.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Precisions (default: both).
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// Write the rows as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub(super) fn run_once(a: OnceArgs) -> Result<u8> {
    if !(1..=10_000).contains(&a.per_cell) {
        anyhow::bail!("--per-cell {}: from 1 to 10000", a.per_cell);
    }
    if let Some(p) = &a.json {
        rayproof::output::check_output_dirs(&[&Some(p.clone())])?;
    }
    let precs = match a.precision.is_empty() {
        true => Precision::ALL.to_vec(),
        false => a.precision.clone(),
    };
    let rows = once::rows(a.seed, &precs, a.per_cell);
    say!(
        "{:<16} {:<4} {:<5} {:<6} {:>6} {:>6} {:>8} {:>6} {:>10}",
        "routine",
        "prec",
        "mesh",
        "aim",
        "rays",
        "leaks",
        "doubles",
        "split",
        "leak from"
    );
    for r in &rows {
        say!(
            "{:<16} {:<4} {:<5} {:<6} {:>6} {:>6} {:>8} {:>6} {:>10}",
            r.routine,
            r.precision,
            r.mesh,
            r.aim,
            r.rays,
            r.leaks,
            r.doubles,
            r.split,
            r.first_leak.map_or("-".into(), |s| format!("1e{s}"))
        );
    }
    for r in rows.iter().filter(|r| r.example.is_some()) {
        say!(
            "first ({} {} {} {}): {}",
            r.routine,
            r.precision,
            r.mesh,
            r.aim,
            r.example.as_deref().unwrap_or_default()
        );
    }
    if let Some(p) = &a.json {
        rayproof::output::write_atomic(
            p,
            (serde_json::to_string_pretty(&rows)? + "\n").as_bytes(),
        )?;
    }
    Ok(0)
}
