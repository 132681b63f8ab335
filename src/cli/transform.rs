//! `rayproof transform`: shapes behind an instance transform (issue 49 item 2). The ray carried
//! into object space by the stored world-to-object matrix in the working precision (`matrix`)
//! or with the translation taken off first (`translate_first`), or by the inverse the renderer
//! computes itself from M (`inverted`), the object's routine run there,
//! judged by the exact oracle in world space; classes of transforms from rotations to large
//! translations and near-singular scales. The `ideal` mode (the object-space ray correctly
//! rounded) of a routine of yours and of the robust built-ins is judged (no wrong verdict), the
//! other rows reported: exit 0, 1 when a judged row has a wrong verdict or any routine answers
//! a hit at a t that is not finite and positive, 2 bad usage, 4 a routine of yours that breaks
//! its contract, crashes or hangs; `--replay` exits 1 on a wrong answer, 0 on a right one or a
//! case within the margin (not judged).

use super::*;
use anyhow::{anyhow, bail, Result};
use clap::Args;
use rayproof::audit::robustness::transform::{self, builtin, Case, Routine, DEFAULT, MODES};
use rayproof::numerics::Precision;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct TransformArgs {
    /// Cases per shape, class and precision.
    #[arg(long, default_value_t = 2000)]
    pub cases: u64,
    /// Seed of the cases.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Precisions (default: both; a plugin's own).
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// The shape: sphere or triangle (default: both; one with a routine of yours).
    #[arg(long)]
    pub shape: Option<String>,
    /// Built-in methods of the shapes (default: algebraic and rtg7 for the sphere,
    /// moller_trumbore, watertight and watertight_wide for the triangle; none when a routine of yours is given).
    #[arg(long, value_delimiter = ',')]
    pub method: Vec<String>,
    /// An object-space routine of yours (`--exec`, `--plugin`, `--name`, `--timeout`: the
    /// shape's protocol, `rayproof header`).
    #[command(flatten)]
    pub outside: super::outside::OutsideArgs,
    /// Write the rows as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Replay one case: SHAPE ROUTINE MODE PRECISION and the values as printed (M's 12, o, d,
    /// the object).
    #[arg(long, num_args = 1.., value_name = "ARG", allow_hyphen_values = true)]
    pub replay: Vec<String>,
}

fn shape_name(s: &str) -> Result<&'static str> {
    match s {
        "sphere" => Ok("sphere"),
        "triangle" => Ok("triangle"),
        _ => bail!("--shape {s}: sphere or triangle"),
    }
}

pub(super) fn run_transform(a: TransformArgs) -> Result<u8> {
    let shapes: Vec<&'static str> = match &a.shape {
        Some(s) => vec![shape_name(s)?],
        None if a.outside.any() => {
            bail!("--shape: which shape your routine is (sphere or triangle)")
        }
        None => vec!["sphere", "triangle"],
    };
    let outside = match a.outside.any() {
        true => {
            let info = rayproof::shapes::shape_by_name(shapes[0])
                .expect("a shape")
                .info();
            a.outside.methods(&info)?
        }
        false => vec![],
    };
    let mut routines: Vec<(&'static str, Routine)> = vec![];
    if a.method.is_empty() && outside.is_empty() {
        for (s, m) in DEFAULT.iter().filter(|(s, _)| shapes.contains(s)) {
            routines.push((s, builtin(s, m).expect("a built-in method")));
        }
    }
    for m in &a.method {
        let found = shapes.iter().find_map(|s| builtin(s, m).map(|r| (*s, r)));
        routines.push(
            found
                .ok_or_else(|| anyhow!("--method {m}: not a method of {}", shapes.join(" or ")))?,
        );
    }
    for (m, _) in &outside {
        if shapes.iter().any(|s| builtin(s, m.name()).is_some()) {
            bail!(
                "--name {}: a built-in method's name; give another",
                m.name()
            );
        }
        routines.push((shapes[0], Routine::Outside(m.as_ref())));
    }
    if !a.replay.is_empty() {
        return replay(&a.replay, &routines);
    }
    if !(1..=100_000).contains(&a.cases) {
        bail!("--cases {}: from 1 to 100000", a.cases);
    }
    let precs = super::outside::OutsideArgs::precisions(&a.precision, &outside)?;
    if let Some(p) = &a.json {
        a.outside.check_json(p)?;
    }
    let rows = match transform::rows(a.seed, &routines, &precs, a.cases).and_then(|r| {
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
        "{:<9} {:<16} {:<16} {:<4} {:<14} {:>6} {:>6} {:>8} {:>9} {:>5} {:>12}  verdict",
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
        "worst ulps"
    );
    for r in &rows {
        say!(
            "{:<9} {:<16} {:<16} {:<4} {:<14} {:>6} {:>6} {:>8} {:>9} {:>5} {:>12}  {}",
            r.shape,
            r.routine,
            r.mode,
            r.precision,
            r.class,
            r.cases,
            r.ill_posed,
            r.false_hit,
            r.false_miss,
            r.bad_t,
            format_ulps(r.worst_ulps),
            r.verdict
        );
    }
    for r in rows.iter().filter(|r| r.replay.is_some()) {
        say!(
            "first wrong ({} {} {} {}): {}",
            r.routine,
            r.mode,
            r.precision,
            r.class,
            r.replay.as_deref().unwrap_or_default()
        );
    }
    if let Some(p) = &a.json {
        rayproof::output::write_json(p, &rows)?;
    }
    // A t that is not finite and positive is wrong in any row; the ideal mode holds the
    // routines judged by default (yours, the robust built-ins) to no wrong verdict
    if rows.iter().any(|r| r.verdict == "fail") {
        say!("verdict: FAIL (a hit at a t that is not finite and positive, or a wrong verdict of a judged routine in the ideal mode)");
        return Ok(1);
    }
    say!("other rows reported: wrong verdicts on well-posed cases (at least {:e} from the boundary) and t errors", transform::MARGIN);
    say!(
        "verdict: {}",
        match rows.iter().any(|r| r.verdict == "pass") {
            true => "pass (the ideal mode of every judged routine: no wrong verdict)",
            false => "reported (no judged row)",
        }
    );
    Ok(0)
}

fn format_ulps(u: f64) -> String {
    match u {
        u if !u.is_finite() => "inf".into(),
        u if u < 1e4 => format!("{u:.1}"),
        u => format!("{u:.2e}"),
    }
}

/// `--replay SHAPE ROUTINE MODE PREC v…`: the exact answer and the routine's (exit 0 the
/// verdicts agree, 1 they do not).
fn replay(args: &[String], routines: &[(&'static str, Routine)]) -> Result<u8> {
    if args.len() < 4 {
        bail!("--replay SHAPE ROUTINE MODE PRECISION and the values");
    }
    let shape = shape_name(&args[0])?;
    let mode = MODES
        .iter()
        .copied()
        .find(|m| *m == args[2])
        .ok_or_else(|| anyhow!("--replay mode {}: {}", args[2], MODES.join(" or ")))?;
    let prec = parse_precision(&args[3]).map_err(anyhow::Error::msg)?;
    let mut v = vec![];
    for (k, s) in args[4..].iter().enumerate() {
        let x = rayproof::audit::hexfloat::parse_exact(s)
            .ok_or_else(|| anyhow!("--replay value {} ({s}): not a number", k + 1))?;
        let exact = match prec {
            Precision::F32 => (x as f32) as f64 == x,
            Precision::F64 => true,
        };
        if !x.is_finite() || !exact {
            bail!(
                "--replay value {} ({s}): not a finite value of {}",
                k + 1,
                prec.name()
            );
        }
        v.push(x);
    }
    let case = Case::from_values(shape, &v).map_err(anyhow::Error::msg)?;
    let routine = match routines
        .iter()
        .find(|(s, r)| *s == shape && r.name() == args[1])
    {
        Some((_, r)) => *r,
        None => builtin(shape, &args[1]).ok_or_else(|| {
            anyhow!(
                "--replay {}: not a {shape} method (or give yours with --exec/--plugin and --name)",
                args[1]
            )
        })?,
    };
    let e = transform::exact(&case);
    let input = transform::object_input(&case, prec, mode)
        .ok_or_else(|| {
            anyhow!("--replay: no object-space ray (M singular, or its determinant 0 or not finite in the precision: a miss)")
        })?;
    let t = match routine.answers(prec, &[input.clone()]) {
        Ok(t) => t[0],
        Err(e) => {
            eprintln!("error: {}", rayproof::images::one_line(&e));
            return Ok(4);
        }
    };
    let hex = |x: &[f64]| {
        x.iter()
            .map(|x| rayproof::shapes::shape::hex_text(*x))
            .collect::<Vec<_>>()
            .join(" ")
    };
    say!(
        "object-space ray ({mode}, {}): o d = {}",
        prec.name(),
        hex(&input[..6])
    );
    say!(
        "exact (world space): {}{}",
        match &e.t {
            Some(t) => format!("hit at t = {}", t.to_string_radix(10, Some(20))),
            None => "miss".into(),
        },
        if e.well_posed {
            ""
        } else {
            " (within the margin of the boundary: not judged)"
        }
    );
    say!(
        "{}: {}",
        args[1],
        match t {
            Some(t) => format!(
                "hit at t = {t:e} ({})",
                rayproof::shapes::shape::hex_text(t)
            ),
            None => "miss".into(),
        }
    );
    let v = transform::judge(t, &e);
    if let (transform::Verdict::Right, Some(t), Some(et)) = (v, t, &e.t) {
        say!(
            "error: {} ulps of {}",
            format_ulps(transform::ulps_of(t, et, prec)),
            prec.name()
        );
    }
    say!(
        "{}",
        match v {
            transform::Verdict::BadT => "wrong: a hit at a t that is not finite and positive",
            transform::Verdict::NotJudged => "not judged (the rows count it as ill-posed)",
            transform::Verdict::FalseHit => "wrong: a false hit",
            transform::Verdict::FalseMiss => "wrong: a false miss",
            transform::Verdict::Right => "right",
        }
    );
    Ok(matches!(
        v,
        transform::Verdict::BadT | transform::Verdict::FalseHit | transform::Verdict::FalseMiss
    ) as u8)
}
