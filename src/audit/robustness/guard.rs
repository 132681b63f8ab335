//! The box that guards the primitive (issue 49, item 1): a BVH node's slab test with the
//! interval `[0, t_max]`, `t_max` the closest hit so far as the renderer holds it (rounded),
//! must never cull a box that holds a primitive the ray hits at that `t`.
//!
//! **Cases.** A triangle of size s (10⁻⁴ … 10⁷, near the origin or 10³–10⁵ sizes away) inside an
//! axis-aligned box, in four classes:
//! - `inside`: the box is the triangle's bounds grown by up to s on every side;
//! - `tight`: the box is the triangle's bounds exactly (its vertices touch the faces);
//! - `on_face`: the triangle lies in the box's entry face (`lo[a]` of one axis a) and the ray
//!   enters through it, so the exact entry distance is the hit distance;
//! - `grazing`: as `on_face`, the ray at 0.1°–1° to the face.
//!
//! A ray from 3s away aims at a random point of the triangle; the exact oracle (rationals) gives
//! its hit `t*`, and `t_max` = `t*` rounded to the nearest value of the precision, as the
//! primitive routine would return it at best. The box holds the hit point, so the guard must say
//! hit: a miss is **lost geometry**. (An exact slab test fails too, where `t_max` rounds below
//! `t*` = the entry: the robust tests pad `t_max` for that.)
//!
//! **Guards.** `naive_slab` (reciprocal direction, min/max per slab, `t_near ≤ t_far`),
//! `williams` (Williams et al. 2005, "An Efficient and Robust Ray–Box Intersection Algorithm":
//! sign-indexed bounds, strict `t_min < t1 && t_max > t0` at the end), `pbrt`
//! (pbrt-v4 `Bounds3::IntersectP`: every slab's far distance × (1 + 2γ₃), then the strict
//! `tMin < raytMax`), `ize` (Ize 2013, "Robust BVH Ray Traversal": far distances **and the
//! ray's `t_max`** × (1 + 2γ₃), `t_near ≤ t_far`). `ize` is judged (0 lost boxes); the others
//! are reported.
//!
//! **Why `ize` loses none, by construction.** Each computed distance (p − oᵢ)·(1/dᵢ) is the exact
//! one times (1 + θ), |θ| ≤ γ₃ (three roundings: the difference, the reciprocal, the product).
//! So every computed near distance is ≤ (1 + γ₃)·t_enter and every padded far distance is
//! ≥ (1 − γ₃)(1 + 2γ₃)·t_exit ≥ t_exit (to first order; the pad's own rounding is inside the
//! margin). The hit is in the box, so t_enter ≤ t* ≤ t_exit, and `t_max` = fl(t*) ≥ (1 − u)·t*,
//! so the padded `t_max` ≥ (1 − u)(1 + 2γ₃)·t* ≥ (1 + γ₃)·t*. Every computed lower bound is
//! then ≤ every computed upper bound, and `t_near ≤ t_far` holds: the box is entered. The naive
//! slab has no pad (its entry rounds above `t_max` where the hit is on the entry face), and
//! Williams' and pbrt's final `tmin < t_max` is strict: a box whose computed entry equals
//! `t_max` (the face holding the hit) is culled, whatever the pad on the far distances.

use crate::numerics::real::{gamma, Real};
use crate::numerics::Precision;
use crate::shapes::oracle::sample;
use crate::shapes::shape::{case_rng, Method, ShapeInfo};
use crate::shapes::triangle::exact_tri;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// The guards, in the order of the table.
pub const GUARDS: [&str; 4] = ["naive_slab", "williams", "pbrt", "ize"];

/// A guard from outside the crate (`--exec` or `--plugin`): the 13 values `o d lo hi t_max` in,
/// one value out, 1 (the box is entered) or 0 (culled), with count 1.
pub const INFO: ShapeInfo = ShapeInfo {
    name: "guard",
    about: "a ray–box guard: is the box entered within [0, t_max]",
    args: &[
        "ox", "oy", "oz", "dx", "dy", "dz", "lox", "loy", "loz", "hix", "hiy", "hiz", "tmax",
    ],
    values: &["hit"],
    ..ShapeInfo::DEFAULTS
};

/// The line protocol of a guard run by `rayproof guard --exec`.
pub const PROTOCOL: &str = "# The guard line protocol: rayproof guard --exec CMD --name NAME
#
# Input (the child's stdin), one case per line: the precision, then 13 values as C99 hex floats,
# exact in that precision:
#   f32 OX OY OZ DX DY DZ LOX LOY LOZ HIX HIY HIZ TMAX
# the ray o + t d, the box [LO, HI], and TMAX, the closest hit so far (the hit of a triangle in
# the box, rounded to the precision).
#
# Output (the child's stdout), one line per case, in order:
#   1 HIT
# HIT = 1 when the ray enters the box for some t in [0, TMAX], 0 when the box is culled.
# Anything else stops the run with one line naming the case (exit 4). Cases come in batches of
# up to 4096 under the rules of `audit --exec` (rayproof header --exec).
";

/// The C signatures of a guard given as `--plugin PATH:SYMBOL`.
pub const C_SIGNATURE: &str =
    "/* A ray-box guard through its C ABI: rayproof guard --plugin PATH:SYMBOL. in[i] is case i
 * (o d lo hi t_max: 13 values in the precision); it sets count[i] = 1 and out[i][0] = 1 when
 * the ray enters the box within [0, t_max], 0 when it culls it, and returns 0. Build with -shared
 * -fPIC; it runs in a worker process, in batches of up to 4096, under --timeout. */
typedef int rayproof_guard_f32(size_t n, const float in[][13], uint32_t count[], float out[][1]);
typedef int rayproof_guard_f64(size_t n, const double in[][13], uint32_t count[], double out[][1]);
";

/// A guard under audit: built in, or a user's routine (judged: it must lose nothing).
pub enum Guard<'a> {
    /// One of [`GUARDS`].
    BuiltIn(&'static str),
    /// A user's, through the machinery that runs outside intersectors.
    Outside(&'a (dyn Method + Send)),
}

/// A guard an audit holds (`audit --guard`): a built-in's name or a user's routine.
pub enum Owned {
    /// One of [`GUARDS`].
    BuiltIn(&'static str),
    /// A user's (`exec:CMD`, `plugin:PATH:SYMBOL`).
    Outside(Box<dyn Method + Send>),
}

impl Owned {
    /// The guard to run.
    pub fn guard(&self) -> Guard<'_> {
        match self {
            Owned::BuiltIn(n) => Guard::BuiltIn(n),
            Owned::Outside(m) => Guard::Outside(m.as_ref()),
        }
    }
}

impl Guard<'_> {
    /// Its name.
    pub fn name(&self) -> &str {
        match self {
            Guard::BuiltIn(n) => n,
            Guard::Outside(m) => m.name(),
        }
    }

    /// Whether it enters each case's box; with `timed`, its nanoseconds per case.
    fn admits_all(
        &self,
        prec: Precision,
        cases: &[&Case],
        timed: bool,
    ) -> Result<(Vec<bool>, Option<f64>), String> {
        match self {
            Guard::BuiltIn(g) => {
                let admitted = cases.iter().map(|c| admits(g, prec, &c.values)).collect();
                if !timed {
                    return Ok((admitted, None));
                }
                // Its cost: the fastest of 16 timed passes over the cases (one pass is at the
                // mercy of a page fault or the other core)
                let ns = (0..16)
                    .map(|_| {
                        let start = std::time::Instant::now();
                        let n = cases
                            .iter()
                            .filter(|c| std::hint::black_box(admits(g, prec, &c.values)))
                            .count();
                        std::hint::black_box(n);
                        start.elapsed().as_nanos() as f64 / cases.len().max(1) as f64
                    })
                    .fold(f64::INFINITY, f64::min);
                Ok((admitted, Some(ns)))
            }
            Guard::Outside(m) => {
                let start = std::time::Instant::now();
                let mut out = Vec::with_capacity(cases.len());
                let inputs: Vec<Vec<f64>> = cases.iter().map(|c| c.values.to_vec()).collect();
                for chunk in inputs.chunks(crate::audit::run::CHUNK as usize) {
                    let answers = crate::audit::run::answers(&[*m as &dyn Method], prec, chunk)?;
                    for (a, q) in answers[0].iter().zip(chunk) {
                        // Held to the contract: count 1 and a value of 0 or 1
                        if a.count != 1
                            || a.values.len() != 1
                            || !(a.values[0] == 0.0 || a.values[0] == 1.0)
                        {
                            return Err(format!(
                                "guard '{}': answered {} {:?} to the case {}; want count 1 and HIT = 1 (entered) or 0 (culled)",
                                m.name(),
                                a.count,
                                a.values,
                                crate::audit::exec::case_line(prec, q).trim_end()
                            ));
                        }
                        out.push(a.values[0] == 1.0);
                    }
                }
                m.finish()?;
                let ns = start.elapsed().as_nanos() as f64 / cases.len().max(1) as f64;
                Ok((out, timed.then_some(ns)))
            }
        }
    }
}
/// The case classes.
pub const CLASSES: [&str; 4] = ["inside", "tight", "on_face", "grazing"];
/// Scene sizes, as powers of ten.
pub const SCALES: std::ops::RangeInclusive<i32> = -4..=7;

type V<F> = [F; 3];

/// Whether `guard` lets the ray `o + t·d`, `t ∈ [0, tmax]`, into the box `[lo, hi]`.
pub fn guard<F: Real>(name: &str, o: V<F>, d: V<F>, lo: V<F>, hi: V<F>, tmax: F) -> bool {
    let inv = d.map(|x| F::ONE / x);
    let pad = F::ONE + F::from_f64(2.0) * gamma::<F>(3);
    // Near and far distances of slab i (by the sign of 1/dᵢ)
    let span = |i: usize| {
        let (near, far) = if inv[i] < F::ZERO {
            (hi[i], lo[i])
        } else {
            (lo[i], hi[i])
        };
        ((near - o[i]) * inv[i], (far - o[i]) * inv[i])
    };
    match name {
        "naive_slab" => {
            let (mut t0, mut t1) = (F::ZERO, tmax);
            for i in 0..3 {
                let (a, b) = span(i);
                let (near, far) = if a < b { (a, b) } else { (b, a) };
                if near > t0 {
                    t0 = near;
                }
                if far < t1 {
                    t1 = far;
                }
            }
            t0 <= t1
        }
        "williams" | "pbrt" => {
            // Slab x initialises, y and z narrow with plain comparisons
            let far = |f: F| if name == "pbrt" { f * pad } else { f };
            let (mut tmin, tmax0) = span(0);
            let mut tfar = far(tmax0);
            for i in 1..3 {
                let (a, b) = span(i);
                let b = far(b);
                if tmin > b || a > tfar {
                    return false;
                }
                if a > tmin {
                    tmin = a;
                }
                if b < tfar {
                    tfar = b;
                }
            }
            tmin < tmax && tfar > F::ZERO
        }
        "ize" => {
            let (mut t0, mut t1) = (F::ZERO, tmax * pad);
            for i in 0..3 {
                let (a, b) = span(i);
                let b = b * pad;
                // NaN-safe narrowing (a NaN slab leaves the interval alone)
                if a > t0 {
                    t0 = a;
                }
                if b < t1 {
                    t1 = b;
                }
            }
            t0 <= t1
        }
        _ => unreachable!("guard names are checked"),
    }
}

/// One case: the ray, the box and `t_max`, as values of the precision (in f64).
#[derive(Clone, Debug)]
pub struct Case {
    /// `o d lo hi tmax`: 13 values.
    pub values: [f64; 13],
}

/// The cases of one class, scale and placement: `n` rays that hit their triangle.
pub fn cases(
    seed: u64,
    prec: Precision,
    class: &str,
    scale: i32,
    placement: &str,
    n: u64,
) -> Vec<Case> {
    let s = 10f64.powi(scale);
    let rp = |v: [f64; 3]| sample::rpv(prec, v);
    let mut out = vec![];
    for i in 0..8 * n {
        if out.len() as u64 == n {
            break;
        }
        let mut rng = case_rng(
            seed,
            "guard",
            &format!("{class}-{placement}-{scale}"),
            prec,
            i,
        );
        let at = sample::placed(&mut rng, placement, s);
        let on_face = class == "on_face" || class == "grazing";
        let axis = rng.random_range(0..3usize);
        // The triangle (flat in axis a at one value of the precision, for the face classes)
        let plane = sample::rp(prec, at[axis]);
        let mut tri: [[f64; 3]; 3] =
            std::array::from_fn(|_| rp(sample::add(at, sample::mul(sample::ball(&mut rng), s))));
        if on_face {
            for v in &mut tri {
                v[axis] = plane;
            }
        }
        let n_ = sample::cross(sample::sub(tri[1], tri[0]), sample::sub(tri[2], tri[0]));
        if sample::norm(n_) < 0.05 * s * s {
            continue;
        }
        // The box: the triangle's bounds (tight), or around them
        let tight_lo: [f64; 3] =
            std::array::from_fn(|k| tri.iter().map(|v| v[k]).fold(f64::INFINITY, f64::min));
        let tight_hi: [f64; 3] =
            std::array::from_fn(|k| tri.iter().map(|v| v[k]).fold(f64::NEG_INFINITY, f64::max));
        let (mut lo, mut hi) = (tight_lo, tight_hi);
        match class {
            "inside" => {
                for k in 0..3 {
                    // Rounding may move a bound inward: the tight bounds at least
                    lo[k] = sample::rp(prec, lo[k] - rng.random_range(0.0..s)).min(tight_lo[k]);
                    hi[k] = sample::rp(prec, hi[k] + rng.random_range(0.0..s)).max(tight_hi[k]);
                }
            }
            "tight" => {}
            _ => {
                // The face at `plane` is the entry face: the box extends up from it
                hi[axis] = sample::rp(prec, plane + s);
                for k in (0..3).filter(|&k| k != axis) {
                    lo[k] = sample::rp(prec, lo[k] - rng.random_range(0.0..s));
                    hi[k] = sample::rp(prec, hi[k] + rng.random_range(0.0..s));
                }
            }
        }
        if (0..3).any(|k| lo[k] >= hi[k]) {
            continue;
        }
        // The ray: from 3s away at a random point of the triangle (from below the entry face)
        let aim = sample::point_in(&mut rng, &tri);
        let mut w = sample::unit(&mut rng);
        if on_face {
            let angle = match class {
                "grazing" => rng.random_range(0.1f64..1.0).to_radians(),
                _ => rng.random_range(10f64..80.0).to_radians(),
            };
            let lateral = (0..3)
                .filter(|&k| k != axis)
                .map(|k| w[k] * w[k])
                .sum::<f64>()
                .sqrt();
            for k in (0..3).filter(|&k| k != axis) {
                w[k] = w[k] / lateral.max(1e-300) * angle.cos();
            }
            w[axis] = angle.sin();
        }
        let o = rp(sample::sub(aim, sample::mul(w, 3.0 * s)));
        // A direction of any length: the hit t is not always near 1
        let d = rp(sample::mul(
            sample::sub(aim, o),
            sample::lu(&mut rng, -2.0, 2.0),
        ));
        if on_face && o[axis] >= plane {
            continue;
        }
        let input: Vec<f64> = [o, d, tri[0], tri[1], tri[2]].concat();
        let Some(t) = exact_tri(&input).t() else {
            continue;
        };
        // t_max: the exact hit rounded to the nearest value of the precision
        let bits = match prec {
            Precision::F32 => 24,
            Precision::F64 => 53,
        };
        let tmax = rug::Float::with_val(bits, &t).to_f64();
        if tmax <= 0.0 || !tmax.is_finite() {
            continue;
        }
        let mut values = [0.0; 13];
        values[..3].copy_from_slice(&o);
        values[3..6].copy_from_slice(&d);
        values[6..9].copy_from_slice(&lo);
        values[9..12].copy_from_slice(&hi);
        values[12] = tmax;
        out.push(Case { values });
    }
    out
}

/// Whether `guard` lets the case in, in its precision.
pub fn admits(name: &str, prec: Precision, v: &[f64; 13]) -> bool {
    fn at<F: Real>(name: &str, v: &[f64; 13]) -> bool {
        let f = |k: usize| {
            [
                F::from_f64(v[k]),
                F::from_f64(v[k + 1]),
                F::from_f64(v[k + 2]),
            ]
        };
        guard(name, f(0), f(3), f(6), f(9), F::from_f64(v[12]))
    }
    match prec {
        Precision::F32 => at::<f32>(name, v),
        Precision::F64 => at::<f64>(name, v),
    }
}

/// One row: a guard, a precision and a class over every scale and placement.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GuardRow {
    /// The guard.
    pub guard: String,
    /// `f32` or `f64`.
    pub precision: String,
    /// The case class.
    pub class: String,
    /// Cases (rays that hit a triangle inside the box).
    pub cases: u64,
    /// Boxes the guard culled: lost geometry.
    pub lost: u64,
    /// The smallest scene size (power of ten) with a lost box.
    pub first_scale: Option<i32>,
    /// Nanoseconds per box test, this guard over these cases (the fastest of 16 timed passes,
    /// the conversion of the 13 values to the precision included). Not timed in `audit`, whose
    /// report depends on the seed alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ns_per_test: Option<f64>,
    /// `pass` or `fail` (a judged guard: it must lose nothing), `reported`; empty in a shard
    /// file (the merge judges).
    pub verdict: String,
    /// The first lost case, replayable: `rayproof guard --replay GUARD PREC o d lo hi tmax`.
    pub replay: Option<String>,
}

/// Whether a guard's rows are held to losing nothing by default: `ize` (robust by its
/// analysis: `t_max` widened by 1 + 2γ₃ covers the slab's rounding) and every guard from
/// outside the crate (a renderer's: lost geometry is a wrong picture). The other built-ins show
/// the test's teeth and are reported.
pub fn judged_by_default(guard: &str) -> bool {
    guard == "ize" || !GUARDS.contains(&guard)
}

/// The default verdict of a row ([`judged_by_default`]; a row with no case shows nothing and
/// fails).
pub fn default_verdict(r: &GuardRow) -> &'static str {
    match judged_by_default(&r.guard) {
        false => "reported",
        true if r.lost > 0 || r.cases == 0 => "fail",
        true => "pass",
    }
}

/// The replay line of a case: `rayproof guard [OUTSIDE ARGS] --replay NAME PREC v×13`.
pub fn replay_line(outside: Option<&str>, name: &str, prec: Precision, v: &[f64; 13]) -> String {
    crate::shapes::shape::guard_line_with(name, prec, outside, v)
}

/// A user's guard on one case: entered or culled (its contract checked).
pub fn admits_one(m: &(dyn Method + Send), prec: Precision, c: &Case) -> Result<bool, String> {
    Guard::Outside(m)
        .admits_all(prec, &[c], false)
        .map(|(a, _)| a[0])
}

/// The rows of `guards` × `precs` × classes, `n` cases per class, scale and placement, with
/// their default verdicts; `timed`: each guard's cost measured too (`guard`, `report`).
pub fn rows(
    seed: u64,
    guards: &[Guard],
    precs: &[Precision],
    n: u64,
    timed: bool,
) -> Result<Vec<GuardRow>, String> {
    let mut out = vec![];
    for &prec in precs {
        for class in CLASSES {
            let all: Vec<(i32, Case)> = SCALES
                .flat_map(|scale| {
                    ["near", "far"].into_iter().flat_map(move |pl| {
                        cases(seed, prec, class, scale, pl, n)
                            .into_iter()
                            .map(move |c| (scale, c))
                    })
                })
                .collect();
            let refs: Vec<&Case> = all.iter().map(|(_, c)| c).collect();
            for g in guards {
                let (admitted, ns) = g.admits_all(prec, &refs, timed)?;
                let lost: Vec<&(i32, Case)> = all
                    .iter()
                    .zip(&admitted)
                    .filter(|(_, a)| !**a)
                    .map(|(c, _)| c)
                    .collect();
                let mut row = GuardRow {
                    guard: g.name().to_string(),
                    precision: prec.name().to_string(),
                    class: class.to_string(),
                    cases: all.len() as u64,
                    lost: lost.len() as u64,
                    first_scale: lost.iter().map(|(s, _)| *s).min(),
                    ns_per_test: ns,
                    verdict: String::new(),
                    replay: lost.first().map(|(_, c)| match g {
                        Guard::BuiltIn(n) => replay_line(None, n, prec, &c.values),
                        Guard::Outside(m) => {
                            replay_line(m.replay().as_deref(), m.name(), prec, &c.values)
                        }
                    }),
                };
                row.verdict = default_verdict(&row).to_string();
                out.push(row);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ize_loses_no_box_and_the_naive_slab_loses_face_hits() {
        let guards: Vec<Guard> = GUARDS.iter().map(|g| Guard::BuiltIn(g)).collect();
        let rows = rows(1, &guards, &Precision::ALL, 4, true).unwrap();
        for r in &rows {
            assert!(r.cases > 0, "{r:?}");
            if r.guard == "ize" {
                assert_eq!(r.lost, 0, "{r:?}");
            }
        }
        let lost = |g: &str, class: &str| {
            rows.iter()
                .filter(|r| r.guard == g && r.class == class)
                .map(|r| r.lost)
                .sum::<u64>()
        };
        assert!(lost("naive_slab", "on_face") > 0);
        assert!(lost("williams", "on_face") > 0);
    }
}
