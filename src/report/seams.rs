//! Section 8 of the report: the seams between routines (issue 49), for the built-in routines:
//! the box test that guards the primitive (`rayproof guard`), the shape behind an instance
//! transform (`rayproof transform`) and exactly one hit per closed mesh (`rayproof once`). Each
//! table sums that command's rows; the commands have every row and the replay lines.

use crate::audit::robustness::guard::{self, Guard, GuardRow, GUARDS};
use crate::audit::robustness::once::{self, OnceRow};
use crate::audit::robustness::transform::{self, TransformRow, CLASSES, MODES};
use crate::numerics::Precision;
use anyhow::{anyhow, Result};
use serde::Serialize;
use std::fmt::Write as _;

/// The three commands' rows for the built-in routines.
#[derive(Clone, Debug, Serialize)]
pub struct Seams {
    /// `rayproof guard --per-cell N`: every built-in guard, both precisions.
    pub guard: Vec<GuardRow>,
    /// `rayproof once --per-cell N`: every built-in triangle routine, both precisions.
    pub once: Vec<OnceRow>,
    /// `rayproof transform --cases N`: the default routines, every mode.
    pub transform: Vec<TransformRow>,
    /// The sizes the rows were made with: guard's and once's per cell, transform's cases.
    pub sizes: [u64; 3],
}

/// The rows at the commands' default sizes (`quick`: smaller ones), seed `seed`.
pub fn rows(seed: u64, quick: bool) -> Result<Seams> {
    let sizes = if quick { [2, 1, 200] } else { [32, 8, 2000] };
    let guards: Vec<Guard> = GUARDS.iter().map(|g| Guard::BuiltIn(g)).collect();
    let guard =
        guard::rows(seed, &guards, &Precision::ALL, sizes[0], true).map_err(|e| anyhow!(e))?;
    let routines: Vec<once::Routine> = (0..crate::shapes::triangle::METHODS.len())
        .map(once::Routine::BuiltIn)
        .collect();
    let once = once::rows(seed, &routines, &Precision::ALL, sizes[1]).map_err(|e| anyhow!(e))?;
    let routines: Vec<(&'static str, transform::Routine)> = transform::DEFAULT
        .iter()
        .map(|(s, m)| (*s, transform::builtin(s, m).expect("a built-in method")))
        .collect();
    let transform =
        transform::rows(seed, &routines, &Precision::ALL, sizes[2]).map_err(|e| anyhow!(e))?;
    Ok(Seams {
        guard,
        once,
        transform,
        sizes,
    })
}

/// The section's Markdown.
pub fn markdown(s: &Seams) -> Result<String> {
    let mut t = String::new();
    t += "\n## 8. The seams between routines (issue 49)\n\n";
    // The box guard
    writeln!(
        t,
        "**The box test before the primitive** (`rayproof guard --per-cell {}`): rays the exact \
         oracle says hit a triangle inside a box (inside it, on a tight box, lying on a face, \
         grazing a face), `t_max` the rounded hit t, scenes of size 1e-4 … 1e7 near and far from \
         the origin; a culled box is lost geometry. The cost is this machine's, nanoseconds per \
         box test (the fastest of 16 timed passes per class, averaged over the classes by cases).\n",
        s.sizes[0]
    )?;
    t += "| guard | precision | cases | lost | lost by class | smallest size with a loss | ns/test |\n|---|---|---:|---:|---|---:|---:|\n";
    for g in GUARDS {
        for p in Precision::ALL {
            let mine: Vec<&GuardRow> = s
                .guard
                .iter()
                .filter(|r| r.guard == g && r.precision == p.name())
                .collect();
            let cases: u64 = mine.iter().map(|r| r.cases).sum();
            let lost: u64 = mine.iter().map(|r| r.lost).sum();
            let by_class: Vec<String> = mine
                .iter()
                .filter(|r| r.lost > 0)
                .map(|r| format!("{} {}", r.class, r.lost))
                .collect();
            let ns = mine
                .iter()
                .map(|r| r.ns_per_test.unwrap_or(f64::NAN) * r.cases as f64)
                .sum::<f64>()
                / cases.max(1) as f64;
            let first = mine.iter().filter_map(|r| r.first_scale).min();
            writeln!(
                t,
                "| {g} | {} | {cases} | {lost} | {} | {} | {ns:.2} |",
                p.name(),
                if by_class.is_empty() {
                    "—".into()
                } else {
                    by_class.join(", ")
                },
                first.map_or("—".into(), |e| format!("1e{e}")),
            )?;
        }
    }
    // The transform
    writeln!(
        t,
        "\n**The instance transform** (`rayproof transform --cases {}`): the world ray carried \
         into object space in the working precision by the stored inverse as the 3×4 product \
         (`matrix`), with the translation taken off first (`translate_first`), by the inverse \
         computed in the precision from M (`inverted`), and exactly then rounded once (`ideal`); \
         judged by the exact oracle in world space on well-posed cases. Each cell: wrong verdicts \
         (false hits + false misses) of the cases judged.\n",
        s.sizes[2]
    )?;
    t += "| routine | precision | class |";
    for m in MODES {
        write!(t, " `{m}` |")?;
    }
    t += " worst t error, ulps (`ideal`) |\n|---|---|---|";
    t += &"---:|".repeat(MODES.len() + 1);
    t += "\n";
    for (shape, routine) in transform::DEFAULT {
        for p in Precision::ALL {
            for class in CLASSES {
                let of = |mode: &str| {
                    s.transform.iter().find(|r| {
                        r.shape == shape
                            && r.routine == routine
                            && r.precision == p.name()
                            && r.class == class
                            && r.mode == mode
                    })
                };
                write!(t, "| {shape}: {routine} | {} | {class} |", p.name())?;
                for m in MODES {
                    match of(m) {
                        Some(r) => write!(t, " {} / {} |", r.false_hit + r.false_miss, r.cases)?,
                        None => t += " — |",
                    }
                }
                match of("ideal") {
                    Some(r) => writeln!(t, " {:.1} |", r.worst_ulps)?,
                    None => t += " — |\n",
                }
            }
        }
    }
    // Exactly once
    writeln!(
        t,
        "\n**Exactly one hit per mesh** (`rayproof once --per-cell {}`): closed grids, fans and \
         icospheres of size 1e-4 … 1e7 near and far from the origin, rays through their shared \
         vertices and edges (rounded, and exactly through them). A leak is a ray no triangle \
         reports; a double, two triangles at one t; a split, hits at different t (the widest in \
         ulps).\n",
        s.sizes[1]
    )?;
    t += "| routine | precision | rays | leaks | doubles | splits | widest split, ulps | bad t | not the crossing |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for m in crate::shapes::triangle::METHODS.iter().map(|m| m.name) {
        for p in Precision::ALL {
            let mine: Vec<&OnceRow> = s
                .once
                .iter()
                .filter(|r| r.routine == m && r.precision == p.name())
                .collect();
            let sum = |f: fn(&OnceRow) -> u64| mine.iter().map(|r| f(r)).sum::<u64>();
            writeln!(
                t,
                "| {m} | {} | {} | {} | {} | {} | {} | {} | {} |",
                p.name(),
                sum(|r| r.rays),
                sum(|r| r.leaks),
                sum(|r| r.doubles),
                sum(|r| r.split),
                mine.iter().map(|r| r.split_ulps).max().unwrap_or(0),
                sum(|r| r.bad),
                sum(|r| r.wrong),
            )?;
        }
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The section's tables hold every built-in routine and sum the rows they were given: a lost
    /// box, a leak and a wrong transform verdict put in the rows come out in the tables.
    #[test]
    fn the_tables_sum_the_rows() {
        let mut s = rows(3, true).unwrap();
        let md = markdown(&s).unwrap();
        for g in GUARDS {
            assert_eq!(md.matches(&format!("| {g} | f")).count(), 2, "{g}");
        }
        for m in crate::shapes::triangle::METHODS {
            assert_eq!(
                md.matches(&format!("| {} | f", m.name)).count(),
                2,
                "{}",
                m.name
            );
        }
        let (ize, leaks) = (
            s.guard
                .iter()
                .filter(|r| r.guard == "ize")
                .map(|r| r.lost)
                .sum::<u64>(),
            s.once
                .iter()
                .filter(|r| r.routine == "watertight_wide")
                .map(|r| r.leaks)
                .sum::<u64>(),
        );
        assert_eq!((ize, leaks), (0, 0), "the robust ones lose nothing");
        let r = s.guard.iter_mut().find(|r| r.guard == "ize").unwrap();
        r.lost = 7777;
        let r = s
            .once
            .iter_mut()
            .find(|r| r.routine == "watertight_wide")
            .unwrap();
        r.leaks = 8888;
        let r = s.transform.iter_mut().find(|r| r.mode == "ideal").unwrap();
        r.false_miss = 9999;
        let md = markdown(&s).unwrap();
        for n in ["7777", "8888", "9999 /"] {
            assert!(md.contains(n), "{n} not in the tables");
        }
    }
}
