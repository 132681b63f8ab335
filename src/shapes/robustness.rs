//! The two mesh-and-spawn tests of issue 6 that are not per-case audits: reintersection (rays
//! spawned from computed hits with the project's offset rule must not hit their own surface
//! again) for every closed shape, and watertightness (rays from inside a closed triangle mesh far
//! from the origin must not escape through cracks). Run by the default `rayproof audit`.

use super::offset::ReintersectRow;
use super::triangle::{self, WatertightRow};
use crate::numerics::Precision;
use serde::Serialize;

/// Instances per decade of scale (1e-4 … 1e4) in the reintersection test.
pub const PER_SCALE: u64 = 24;
/// Rays per kind in the watertightness test.
pub const WATERTIGHT_RAYS: u64 = 3000;

/// Both tests' rows.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Robustness {
    pub seed: u64,
    pub reintersection: Vec<ReintersectRow>,
    pub watertight: Vec<WatertightRow>,
}

/// Runs both tests in the given precisions.
pub fn run(seed: u64, precisions: &[Precision]) -> Robustness {
    let mut reintersection = vec![];
    let mut watertight = vec![];
    for &p in precisions {
        reintersection.extend(super::reintersect::reintersection_all(seed, PER_SCALE, p));
        reintersection.extend(triangle::reintersection(seed, PER_SCALE, p));
        reintersection.extend(super::torus::reintersection(seed, PER_SCALE, p));
        watertight.extend(triangle::watertight_test(seed, WATERTIGHT_RAYS, p));
    }
    Robustness {
        seed,
        reintersection,
        watertight,
    }
}

/// The robust methods' goal: no re-hit and no escaped ray. One line per row that misses it.
pub fn check(r: &Robustness) -> Vec<String> {
    let robust_tri: Vec<&str> = triangle::METHODS
        .iter()
        .filter(|m| m.robust || m.name == "watertight")
        .map(|m| m.name)
        .collect();
    let mut out = vec![];
    for row in r.reintersection.iter().filter(|x| x.robust && x.rehits > 0) {
        out.push(format!(
            "reintersection {} {} {}: {} re-hits of {} spawned rays (goal 0)",
            row.shape, row.method, row.precision, row.rehits, row.rays
        ));
    }
    for row in r
        .watertight
        .iter()
        .filter(|x| robust_tri.contains(&x.method) && (x.escaped > 0 || x.oracle_violations > 0))
    {
        out.push(format!(
            "watertight {} {} {}: {} of {} rays escaped (goal 0)",
            row.method, row.precision, row.kind, row.escaped, row.rays
        ));
    }
    for row in r.watertight.iter().filter(|x| x.oracle_violations > 0) {
        out.push(format!(
            "watertight {} {}: the oracle found {} rays that do not cross the mesh an odd number of times",
            row.method, row.precision, row.oracle_violations
        ));
    }
    out
}

/// The terminal / Markdown table (Markdown when `md`).
pub fn table(r: &Robustness, md: bool) -> String {
    let mut s = String::new();
    if md {
        s += "### Reintersection: spawned rays that hit their own surface again\n\n";
        s += "| shape | method | prec | spawned rays | re-hits |\n|---|---|---|---:|---:|\n";
    } else {
        s += "\nreintersection (offset rule of src/routines/offset.rs, scales 1e-4 … 1e4)\n";
        s += &format!(
            "{:<10} {:<16} {:<4} {:>10} {:>8}\n",
            "shape", "method", "prec", "rays", "re-hits"
        );
    }
    for x in &r.reintersection {
        let m = format!("{}{}", x.method, if x.robust { " (robust)" } else { "" });
        s += &if md {
            format!(
                "| {} | {} | {} | {} | {} |\n",
                x.shape, m, x.precision, x.rays, x.rehits
            )
        } else {
            format!(
                "{:<10} {:<16} {:<4} {:>10} {:>8}\n",
                x.shape, m, x.precision, x.rays, x.rehits
            )
        };
    }
    if md {
        s += "\n### Watertightness: rays from inside a closed mesh 1e5 from the origin that escape\n\n";
        s += "| method | prec | rays | escaped | rate | oracle-checked | oracle violations |\n|---|---|---|---:|---:|---:|---:|\n";
    } else {
        s += "\nwatertightness (icosphere 1e5 from the origin; Embree's bound 0.002 %)\n";
        s += &format!(
            "{:<16} {:<4} {:<7} {:>7} {:>8} {:>9}\n",
            "method", "prec", "rays", "count", "escaped", "rate"
        );
    }
    for x in &r.watertight {
        s += &if md {
            format!(
                "| {} | {} | {} {} | {} | {:.4} % | {} | {} |\n",
                x.method,
                x.precision,
                x.rays,
                x.kind,
                x.escaped,
                100.0 * x.rate,
                x.oracle_checked,
                x.oracle_violations
            )
        } else {
            format!(
                "{:<16} {:<4} {:<7} {:>7} {:>8} {:>8.4}%\n",
                x.method,
                x.precision,
                x.kind,
                x.rays,
                x.escaped,
                100.0 * x.rate
            )
        };
    }
    s
}
