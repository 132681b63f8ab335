//! The spawn rules' figures (issue 47): the smallest resolved gap against scene size per rule and
//! precision, near and far from the origin, and the Pareto of self-hits against the widest gap.
//! Written by `rayproof spawn --plots` and in section 7 of `rayproof report`.

use super::plot::{lines_svg, pareto_svg, Point};
use crate::audit::robustness::spawn::SpawnRow;

/// The figures of a run: `(file name, SVG)`.
pub fn figures(rows: &[SpawnRow]) -> Vec<(String, String)> {
    let mut keys: Vec<(String, String)> = vec![];
    for r in rows {
        let k = (r.rule.clone(), r.precision.clone());
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    let mut out = vec![];
    for placement in ["near", "far"] {
        let series: Vec<(String, Vec<(f64, f64)>)> = keys
            .iter()
            .map(|(rule, prec)| {
                let v = rows
                    .iter()
                    .filter(|r| {
                        r.rule == *rule
                            && r.precision == *prec
                            && r.placement == placement
                            && r.rays > 0
                    })
                    .map(|r| (10f64.powi(r.scale), r.gap_ulps))
                    .collect();
                (format!("{rule} {prec}"), v)
            })
            .collect();
        out.push((
            format!("gap-{placement}.svg"),
            lines_svg(
                &format!("Smallest resolved gap, {placement} the origin"),
                "scene size",
                "gap (ulps of max|p|)",
                &series,
            ),
        ));
    }
    // Per rule and precision: the widest gap against the self-hit rate
    let floor = 1e-5;
    let points: Vec<Point> = keys
        .iter()
        .enumerate()
        .map(|(i, (rule, prec))| {
            let mine: Vec<&SpawnRow> = rows
                .iter()
                .filter(|r| r.rule == *rule && r.precision == *prec && r.rays > 0)
                .collect();
            let rays: u64 = mine.iter().map(|r| r.rays).sum();
            let hits: u64 = mine.iter().map(|r| r.self_hits).sum();
            let gap = mine.iter().map(|r| r.gap_ulps).fold(0.0, f64::max);
            Point {
                label: format!("{rule} {prec}"),
                x: gap.max(0.1),
                y: hits as f64 / rays.max(1) as f64,
                robust: hits == 0,
                colour: i / 2,
                square: prec == "f64",
            }
        })
        .collect();
    out.push((
        "pareto.svg".into(),
        pareto_svg(
            "Self-hits against the widest gap (lower left is better)",
            "widest resolved gap over all scenes (ulps of max|p|)",
            "self-hit rate",
            &points,
            floor,
        ),
    ));
    out
}
