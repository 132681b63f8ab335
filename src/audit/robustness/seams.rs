//! The seams between routines in an audit (issue 49 item 5): the box guard before the
//! primitive ([`super::guard`]), exactly one hit per closed mesh ([`super::once`]) and shapes
//! behind an instance transform ([`super::transform`]), as rows of `rayproof audit`.
//!
//! **Which rows run.** With the box shape audited whole, the four built-in guards; with the
//! triangle, every built-in triangle routine on the exactly-once meshes and the default triangle
//! methods under transforms; with the sphere, its default methods under transforms. Unless
//! `--no-seams`, a routine of yours (`--exec`, `--plugin`, `--source` with `--shape triangle` or
//! `sphere`, every class) gets the exactly-once rows (triangle) and the transform rows; a guard
//! of yours comes in as `--guard exec:CMD` or
//! `--guard plugin:PATH:SYMBOL`. The sizes are [`super::GUARD_PER_CELL`],
//! [`super::ONCE_PER_CELL`] and [`super::TRANSFORM_CASES`]; the rows are not sharded (the merge
//! runs the built-in ones, shard 0 carries yours) and carry no timing (the report depends on the
//! seed alone: `rayproof report` has the guards' cost).
//!
//! **Verdicts.** A tolerance file's `[[robustness]]` rule with `test = "guard"`, `"once"` or
//! `"transform"` (and `mode` for transforms) judges a row first, bounding its failures
//! (`max_failures`) or reporting it; else the default: `ize` and your guards lose no box,
//! `watertight_wide` and your triangle routines report each ray once, the robust built-ins and
//! your routines keep every verdict in the `ideal` transform mode; the rest is reported, and a
//! hit at a bad t fails any row. **Teeth**: where the built-in rows ran, the naive slab must lose
//! some box, a routine not robust by design must leak or split some ray, and some `f32` row of a
//! carrying mode must flip a verdict, or the audit fails: a test that cannot see the defect it is
//! for proves nothing.

use super::guard::{self, GuardRow, CLASSES as GUARD_CLASSES};
use super::once::{self, OnceRow, AIMS, MESHES};
use super::transform::{self, TransformRow, CLASSES as TRANSFORM_CLASSES, MODES};
use super::{Outside, GUARD_PER_CELL, ONCE_PER_CELL, TRANSFORM_CASES};
use crate::audit::Method;
use crate::numerics::Precision;

/// Checks shard 0's seam rows: exactly one per `--guard` guard × precision × class, per outside
/// triangle routine × precision × mesh × aim, per outside sphere or triangle routine × mode ×
/// precision × class, in the order a run makes them, each with counts a run can make and no
/// verdict (the merge judges). `routines`: the shard's outside routines as `(shape, name)`.
pub fn check_shard_rows(
    o: &Outside,
    routines: &[(String, String)],
    guards: &[String],
    precisions: &[Precision],
) -> Result<(), String> {
    // The rows a run makes, in its order
    let names = |shape: &str| -> Vec<&str> {
        routines
            .iter()
            .filter(|(s, _)| s == shape)
            .map(|(_, n)| n.as_str())
            .collect()
    };
    let guard_names: Vec<&str> = guards
        .iter()
        .map(|g| g.split(' ').next().unwrap_or_default())
        .collect();
    let mut want_guard = vec![];
    let mut want_once = vec![];
    for p in precisions {
        for c in GUARD_CLASSES {
            for g in &guard_names {
                want_guard.push(format!("{g} {} {c}", p.name()));
            }
        }
    }
    // The outside routines' rows go shape by shape, as the plan runs them
    let mut want_transform = vec![];
    let mut shapes: Vec<&str> = vec![];
    for (s, _) in routines {
        if !shapes.contains(&s.as_str()) {
            shapes.push(s);
        }
    }
    for shape in shapes {
        if shape == "triangle" {
            for p in precisions {
                for m in MESHES {
                    for r in names(shape) {
                        for a in AIMS {
                            want_once.push(format!("{r} {} {m} {a}", p.name()));
                        }
                    }
                }
            }
        }
        if matches!(shape, "sphere" | "triangle") {
            for p in precisions {
                for c in TRANSFORM_CLASSES {
                    for mode in MODES {
                        for r in names(shape) {
                            want_transform.push(format!("{shape} {r} {mode} {} {c}", p.name()));
                        }
                    }
                }
            }
        }
    }
    let have_guard: Vec<String> = o
        .guard
        .iter()
        .map(|r| format!("{} {} {}", r.guard, r.precision, r.class))
        .collect();
    let have_once: Vec<String> = o
        .once
        .iter()
        .map(|r| format!("{} {} {} {}", r.routine, r.precision, r.mesh, r.aim))
        .collect();
    let have_transform: Vec<String> = o
        .transform
        .iter()
        .map(|r| {
            format!(
                "{} {} {} {} {}",
                r.shape, r.routine, r.mode, r.precision, r.class
            )
        })
        .collect();
    for (what, have, want) in [
        ("guard", have_guard, want_guard),
        ("exactly-once", have_once, want_once),
        ("transform", have_transform, want_transform),
    ] {
        if have != want {
            return Err(format!(
                "its {what} rows ({}) are not the {} a run of its routines makes",
                have.len(),
                want.len()
            ));
        }
    }
    // Counts a run cannot make judge nothing
    let per_guard_row = 2 * guard::SCALES.count() as u64 * GUARD_PER_CELL;
    if let Some(r) = o.guard.iter().find(|r| {
        r.cases != per_guard_row
            || r.lost > r.cases
            || (r.lost > 0) != r.first_scale.is_some()
            || (r.lost > 0) != r.replay.is_some()
            || r.first_scale.is_some_and(|s| !guard::SCALES.contains(&s))
            || r.ns_per_test.is_some()
            || !r.verdict.is_empty()
    }) {
        return Err(format!(
            "guard row {} {} {}: counts a run cannot make",
            r.guard, r.precision, r.class
        ));
    }
    if let Some(r) = o.once.iter().find(|r| {
        let counted = r.leaks + r.doubles + r.split + r.bad + r.wrong;
        counted > r.rays
            || r.rays == 0
            || (r.split == 0 && r.split_ulps > 0)
            || (counted > 0) != r.first.is_some()
            || (r.leaks > 0) != r.first_leak.is_some()
            || (r.first.is_none() && !r.replay.is_empty())
            // The first ray's kind is one the row counted
            || r.first.as_deref().is_some_and(|f| {
                let n = match f {
                    "leak" => r.leaks,
                    "double" => r.doubles,
                    "split" => r.split,
                    "bad" => r.bad,
                    "wrong" => r.wrong,
                    _ => 0,
                };
                n == 0
            })
            || !r.verdict.is_empty()
    }) {
        return Err(format!(
            "exactly-once row {} {} {} {}: counts a run cannot make",
            r.routine, r.precision, r.mesh, r.aim
        ));
    }
    if let Some(r) = o.transform.iter().find(|r| {
        let wrong = r.false_hit + r.false_miss;
        r.cases + r.ill_posed != TRANSFORM_CASES
            || wrong > r.cases
            || r.bad_t > TRANSFORM_CASES
            || !(r.worst_ulps >= 0.0 && r.worst_ulps.is_finite())
            || (wrong + r.bad_t > 0) != r.replay.is_some()
            || !r.verdict.is_empty()
    }) {
        return Err(format!(
            "transform row {} {} {} {} {}: counts a run cannot make",
            r.shape, r.routine, r.mode, r.precision, r.class
        ));
    }
    Ok(())
}

/// The seam rows of routines from outside the crate: exactly-once for triangle routines,
/// transforms for sphere and triangle routines (`shape`'s), over the audit's precisions.
pub fn outside_seams(
    seed: u64,
    shape: &'static str,
    precisions: &[Precision],
    methods: &[&dyn Method],
) -> Result<(Vec<OnceRow>, Vec<TransformRow>), String> {
    let once = match shape {
        "triangle" => {
            let r: Vec<once::Routine> =
                methods.iter().map(|m| once::Routine::Outside(*m)).collect();
            once::rows(seed, &r, precisions, ONCE_PER_CELL)?
        }
        _ => vec![],
    };
    let transform = match shape {
        "sphere" | "triangle" => {
            let r: Vec<(&'static str, transform::Routine)> = methods
                .iter()
                .map(|m| (shape, transform::Routine::Outside(*m)))
                .collect();
            transform::rows(seed, &r, precisions, TRANSFORM_CASES)?
        }
        _ => vec![],
    };
    Ok((once, transform))
}

/// Whether `audit` (without `--no-seams`) gives a routine of `shape` seam rows when `classes` of its classes
/// are audited: a sphere or triangle routine in an audit of its shape's every class (one narrowed
/// by `--class` is about those cases alone). The plan runs them and a shard's reader expects them
/// by this one rule.
pub fn run_for(shape: &crate::shapes::shape::ShapeInfo, classes: usize) -> bool {
    matches!(shape.name, "sphere" | "triangle") && classes == shape.classes.len()
}

/// The box-guard rows of the audit's guards (`audit --guard`; none: empty).
pub fn guard_rows(
    seed: u64,
    precisions: &[Precision],
    guards: &[guard::Guard],
) -> Result<Vec<GuardRow>, String> {
    if guards.is_empty() {
        return Ok(vec![]);
    }
    guard::rows(seed, guards, precisions, GUARD_PER_CELL, false)
}

/// Clears the verdicts of seam rows bound for a shard file (the merge judges them).
pub fn unjudged(o: &mut Outside) {
    o.guard.iter_mut().for_each(|r| r.verdict.clear());
    o.once.iter_mut().for_each(|r| r.verdict.clear());
    o.transform.iter_mut().for_each(|r| r.verdict.clear());
}

/// One line per failing row and per missing tooth.
pub fn check(
    guard_rows: &[GuardRow],
    once_rows: &[OnceRow],
    transform_rows: &[TransformRow],
) -> Vec<String> {
    let mut out = vec![];
    for r in guard_rows.iter().filter(|r| r.verdict == "fail") {
        out.push(format!(
            "guard {} {} {}: {} of {} boxes holding the hit culled (lost geometry); replay: {}",
            r.guard,
            r.precision,
            r.class,
            r.lost,
            r.cases,
            r.replay.as_deref().unwrap_or("-")
        ));
    }
    for r in once_rows.iter().filter(|r| r.verdict == "fail") {
        out.push(format!(
            "once {} {} {} {}: {} of {} rays not reported once ({} leaks, {} split, {} bad t, {} wrong hits); first: {}",
            r.routine,
            r.precision,
            r.mesh,
            r.aim,
            once::failures(r),
            r.rays,
            r.leaks,
            r.split,
            r.bad,
            r.wrong,
            r.replay.first().map_or("-", |s| s.as_str())
        ));
    }
    for r in transform_rows.iter().filter(|r| r.verdict == "fail") {
        out.push(format!(
            "transform {} {} {} {} {}: {} false hits, {} false misses of {} well-posed cases, {} hits at a bad t; replay: {}",
            r.shape,
            r.routine,
            r.mode,
            r.precision,
            r.class,
            r.false_hit,
            r.false_miss,
            r.cases,
            r.bad_t,
            r.replay.as_deref().unwrap_or("-")
        ));
    }
    // Teeth, where the built-in rows ran
    let naive: Vec<&GuardRow> = guard_rows
        .iter()
        .filter(|r| r.guard == "naive_slab")
        .collect();
    if !naive.is_empty() && naive.iter().all(|r| r.lost == 0) {
        out.push(format!(
            "guard: the naive slab loses no box of {}, so the test cannot see lost geometry",
            naive.iter().map(|r| r.cases).sum::<u64>()
        ));
    }
    let teeth: Vec<&OnceRow> = once_rows
        .iter()
        .filter(|r| matches!(r.routine.as_str(), "chapter" | "moller_trumbore"))
        .collect();
    if !teeth.is_empty() && teeth.iter().all(|r| r.leaks + r.split == 0) {
        out.push(
            "once: neither the chapter's routine nor Möller–Trumbore leaks or splits a ray, so the test cannot see a crack"
                .into(),
        );
    }
    let carried: Vec<&TransformRow> = transform_rows
        .iter()
        .filter(|r| {
            r.precision == "f32"
                && r.mode != "ideal"
                && transform::DEFAULT.contains(&(r.shape.as_str(), r.routine.as_str()))
        })
        .collect();
    if !carried.is_empty() && carried.iter().all(|r| transform::failures(r) == 0) {
        out.push(
            "transform: no f32 row of a carrying mode flips a verdict, so the test cannot see a transform's error"
                .into(),
        );
    }
    out
}

/// Summary lines: one per seam that ran.
pub fn summary(
    guard_rows: &[GuardRow],
    once_rows: &[OnceRow],
    transform_rows: &[TransformRow],
) -> String {
    let mut s = String::new();
    if !guard_rows.is_empty() {
        let each: Vec<String> = names(guard_rows.iter().map(|r| r.guard.as_str()))
            .into_iter()
            .map(|g| {
                let mine = guard_rows.iter().filter(|r| r.guard == g);
                let (lost, cases) = mine.fold((0, 0), |(l, c), r| (l + r.lost, c + r.cases));
                format!("{g} {lost}/{cases}")
            })
            .collect();
        s += &format!(
            "box guards       lost boxes (goal 0 for ize and yours): {}\n",
            each.join(", ")
        );
    }
    if !once_rows.is_empty() {
        let each: Vec<String> = names(once_rows.iter().map(|r| r.routine.as_str()))
            .into_iter()
            .map(|g| {
                let mine: Vec<&OnceRow> = once_rows.iter().filter(|r| r.routine == g).collect();
                let sum = |f: fn(&OnceRow) -> u64| mine.iter().map(|r| f(r)).sum::<u64>();
                format!(
                    "{g} {} leaks {} split of {}",
                    sum(|r| r.leaks),
                    sum(|r| r.split),
                    sum(|r| r.rays)
                )
            })
            .collect();
        s += &format!(
            "exactly once     (goal 0 leaks, splits, wrong hits for watertight_wide and yours): {}\n",
            each.join("; ")
        );
    }
    if !transform_rows.is_empty() {
        let each: Vec<String> = names(transform_rows.iter().map(|r| r.routine.as_str()))
            .into_iter()
            .map(|g| {
                let by_mode: Vec<String> = MODES
                    .iter()
                    .map(|m| {
                        let n: u64 = transform_rows
                            .iter()
                            .filter(|r| r.routine == g && r.mode == *m)
                            .map(transform::failures)
                            .sum();
                        format!("{m} {n}")
                    })
                    .collect();
                format!("{g} ({})", by_mode.join(", "))
            })
            .collect();
        s += &format!(
            "transforms       wrong verdicts by mode (goal 0 in ideal for robust methods and yours): {}\n",
            each.join("; ")
        );
    }
    s
}

/// Each name once, in order.
fn names<'a>(all: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut out: Vec<&str> = vec![];
    for n in all {
        if !out.contains(&n) {
            out.push(n);
        }
    }
    out
}

/// The three tables (terminal, or Markdown when `md`); empty where a seam did not run.
pub fn table(
    guard_rows: &[GuardRow],
    once_rows: &[OnceRow],
    transform_rows: &[TransformRow],
    md: bool,
) -> String {
    let mut s = String::new();
    let row = |cells: Vec<String>, widths: &[usize]| -> String {
        if md {
            format!("| {} |\n", cells.join(" | "))
        } else {
            let mut line: Vec<String> = cells
                .iter()
                .zip(widths)
                .map(|(c, w)| format!("{c:<w$}"))
                .collect();
            if let Some(l) = line.last_mut() {
                *l = l.trim_end().to_string();
            }
            format!("{}\n", line.join(" "))
        }
    };
    let head = |title: &str, cells: &[&str], widths: &[usize]| -> String {
        let mut h = match md {
            true => format!("\n### {title}\n\n"),
            false => format!("\n{title}\n"),
        };
        h += &row(cells.iter().map(|c| c.to_string()).collect(), widths);
        if md {
            h += &format!("|{}\n", "---|".repeat(cells.len()));
        }
        h
    };
    if !guard_rows.is_empty() {
        let w = [14, 4, 8, 7, 6, 10, 8];
        s += &head(
            "Box guards: boxes holding the hit that the slab test culls (lost geometry)",
            &[
                "guard",
                "prec",
                "class",
                "cases",
                "lost",
                "from size",
                "verdict",
            ],
            &w,
        );
        for r in guard_rows {
            s += &row(
                vec![
                    r.guard.clone(),
                    r.precision.clone(),
                    r.class.clone(),
                    r.cases.to_string(),
                    r.lost.to_string(),
                    r.first_scale.map_or("-".into(), |x| format!("1e{x}")),
                    r.verdict.clone(),
                ],
                &w,
            );
        }
    }
    if !once_rows.is_empty() {
        let w = [16, 4, 6, 12, 6, 6, 7, 6, 4, 5, 8];
        s += &head(
            "Exactly once: rays through shared edges and vertices of closed meshes",
            &[
                "routine", "prec", "mesh", "aim", "rays", "leaks", "doubles", "split", "bad",
                "wrong", "verdict",
            ],
            &w,
        );
        for r in once_rows {
            s += &row(
                vec![
                    r.routine.clone(),
                    r.precision.clone(),
                    r.mesh.clone(),
                    r.aim.clone(),
                    r.rays.to_string(),
                    r.leaks.to_string(),
                    r.doubles.to_string(),
                    r.split.to_string(),
                    r.bad.to_string(),
                    r.wrong.to_string(),
                    r.verdict.clone(),
                ],
                &w,
            );
        }
    }
    if !transform_rows.is_empty() {
        let w = [9, 16, 16, 4, 14, 6, 6, 9, 10, 5, 8];
        s += &head(
            "Transforms: the shape behind an instance transform, judged in world space",
            &[
                "shape",
                "routine",
                "mode",
                "prec",
                "class",
                "cases",
                "ill",
                "false hit",
                "false miss",
                "bad t",
                "verdict",
            ],
            &w,
        );
        for r in transform_rows {
            s += &row(
                vec![
                    r.shape.clone(),
                    r.routine.clone(),
                    r.mode.clone(),
                    r.precision.clone(),
                    r.class.clone(),
                    r.cases.to_string(),
                    r.ill_posed.to_string(),
                    r.false_hit.to_string(),
                    r.false_miss.to_string(),
                    r.bad_t.to_string(),
                    r.verdict.clone(),
                ],
                &w,
            );
        }
    }
    // The first failing case of each judged row that failed, replayable
    let mut lines = vec![];
    for r in guard_rows.iter().filter(|r| r.verdict == "fail") {
        if let Some(l) = &r.replay {
            lines.push(format!(
                "first lost ({} {} {}): {l}",
                r.guard, r.precision, r.class
            ));
        }
    }
    for r in once_rows.iter().filter(|r| r.verdict == "fail") {
        for l in r.replay.iter().take(3) {
            lines.push(format!(
                "first {} ({} {} {} {}): {l}",
                r.first.as_deref().unwrap_or("-"),
                r.routine,
                r.precision,
                r.mesh,
                r.aim
            ));
        }
    }
    for r in transform_rows.iter().filter(|r| r.verdict == "fail") {
        if let Some(l) = &r.replay {
            lines.push(format!(
                "first wrong ({} {} {} {}): {l}",
                r.routine, r.mode, r.precision, r.class
            ));
        }
    }
    for l in lines {
        s += &format!("{}{l}\n", if md { "\n" } else { "" });
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The teeth: the built-in rows of a small run have each defect somewhere (the naive slab
    /// loses a box, Möller–Trumbore leaks, an f32 carrying mode flips a verdict); with those
    /// rows made clean, `check` says the test cannot see it. A failing judged row is a line.
    #[test]
    fn the_seams_have_teeth() {
        let r = super::super::run(1, &["box", "triangle", "sphere"], &[Precision::F32]).unwrap();
        assert!(check(&r.guard, &r.once, &r.transform).is_empty());
        let mut guard = r.guard.clone();
        for x in guard.iter_mut().filter(|x| x.guard == "naive_slab") {
            x.lost = 0;
        }
        assert!(check(&guard, &r.once, &r.transform)[0].contains("the naive slab loses no box"));
        let mut once = r.once.clone();
        for x in once.iter_mut() {
            (x.leaks, x.split) = (0, 0);
        }
        assert!(check(&r.guard, &once, &r.transform)[0].contains("cannot see a crack"));
        let mut tr = r.transform.clone();
        for x in tr.iter_mut() {
            (x.false_hit, x.false_miss) = (0, 0);
        }
        assert!(check(&r.guard, &r.once, &tr)[0].contains("cannot see a transform's error"));
        let mut guard = r.guard.clone();
        guard.iter_mut().find(|x| x.guard == "ize").unwrap().verdict = "fail".into();
        assert!(check(&guard, &r.once, &r.transform)[0].starts_with("guard ize f32"));
    }
}
