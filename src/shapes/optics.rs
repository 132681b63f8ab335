//! Reflection and refraction vectors (seed 002 §4): shapes `reflect` and `refract`.
//!
//! **Convention (the chapter's).** `L` points from the surface towards where the light comes
//! from (away from the surface, on the side of `N`), `N` is the surface normal, and for
//! refraction `η = η_L/η_T` (the index of the medium `L` is in over the index of the medium the
//! ray enters). The chapter assumes unit `L`, `N`; the oracles work with the values as given
//! (exact floats that are only approximately unit), so a method's error is measured against the
//! chapter's formula evaluated exactly on its own inputs:
//! - reflection `R = 2(N·L)N − L`;
//! - refraction `T = (η(N·L) − √(1 − η²(1 − (N·L)²)))·N − η·L`, total internal reflection
//!   (count 0) when the radicand is `< 0`, decided exactly with rationals. An exactly zero
//!   radicand is a refraction (count 1), as the chapter's `< 0` says; pbrt's `sin²θt ≥ 1`
//!   calls it TIR. With binary inputs the radicand is never exactly 0 except at `N·L = 0`,
//!   `η = 1` (`η²(1 − c²) = 1` has no dyadic solution otherwise), so the `critical` class lies
//!   within a few ulps of the critical angle on both sides.
//!
//! Invalid input (count 0 expected): NaN/inf, `N = 0`, `L = 0`, and for refraction `η ≤ 0`.
//! Values are judged with [`Metric::NormUlps`]. Refraction's ill-posedness: TIR or not changes
//! when one of the 7 inputs moves by one ulp (14 single moves, exact); reflection is never
//! ill-posed (its count is always 1).

use crate::numerics::exact::{self, nudge, q, round_q, sqrt_encl, ziv, ZIV_CAP};
use crate::numerics::real::{Real, Scalar};
use crate::numerics::vec3::{dot, scale, sub};
use crate::numerics::Precision;
use crate::shapes::shape::{Answer, Expected, MethodInfo, Metric, Shape, ShapeInfo, Truth};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rug::float::Round;
use rug::{Float, Rational};
use std::cmp::Ordering;

type V<S> = [S; 3];

/// Valid vectors: finite and not zero.
fn usable<F: Real>(v: V<F>) -> bool {
    v.iter().all(|x| x.is_finite()) && v.iter().any(|&x| x != F::ZERO)
}

// ---- reflection ----

/// **Chapter** §4.1, as written: `R = 2(N·L)N − L` (no guard).
pub fn reflect_chapter<F: Real>(l: V<F>, n: V<F>) -> Option<V<F>> {
    let c = dot(n, l);
    Some(sub(scale(n, F::from_f64(2.0) * c), l))
}

/// **FMA**: `N·L` accumulated by FMA and `Rᵢ = fma(2(N·L), Nᵢ, −Lᵢ)` (one rounding per
/// component after the dot product); rejects non-finite or zero `L`, `N`.
pub fn reflect_fma<F: Real>(l: V<F>, n: V<F>) -> Option<V<F>> {
    if !usable(l) || !usable(n) {
        return None;
    }
    let c2 = F::from_f64(2.0) * l[2].mul_add(n[2], l[1].mul_add(n[1], l[0] * n[0]));
    Some(std::array::from_fn(|i| c2.mul_add(n[i], -l[i])))
}

/// The reflection methods.
pub const REFLECT_METHODS: [MethodInfo; 2] = [
    MethodInfo {
        name: "chapter",
        robust: false,
        about: "seed 002 §4.1: R = 2(N·L)N − L",
    },
    MethodInfo {
        name: "fma",
        robust: true,
        about: "N·L by FMA, R_i = fma(2(N·L), N_i, −L_i); rejects NaN/inf/zero vectors",
    },
];

// ---- refraction ----

/// **Chapter** §4.2, as written: radicand `1 − η²(1 − (N·L)²)`, TIR if `< 0`, else
/// `T = (η(N·L) − √radicand)N − ηL` (no guard).
pub fn refract_chapter<F: Real>(l: V<F>, n: V<F>, eta: F) -> Option<V<F>> {
    let c = dot(n, l);
    let rad = F::ONE - eta * eta * (F::ONE - c * c);
    if rad < F::ZERO {
        return None;
    }
    Some(sub(scale(n, eta * c - rad.sqrt()), scale(l, eta)))
}

/// **pbrt-v4 `Refract`** with `η = η_L/η_T` (pbrt's `eta` is `η_T/η_L = 1/η`; its divisions by
/// `eta` are written as multiplications by `η`, which is the input here as `eta` is there):
/// `sin²θi = max(0, 1 − cos²θi)`, `sin²θt = sin²θi·η²`, TIR if `sin²θt ≥ 1`,
/// `cosθt = SafeSqrt(1 − sin²θt)`, `T = −ηL + (η cosθi − cosθt)N`. pbrt's flip for
/// `cosθi < 0` (light arriving from inside) is left out: this shape fixes the chapter's
/// formula for every sign of `N·L`.
pub fn refract_pbrt<F: Real>(l: V<F>, n: V<F>, eta: F) -> Option<V<F>> {
    let cos_i = dot(n, l);
    let max0 = |x: F| if x > F::ZERO { x } else { F::ZERO };
    let sin2_i = max0(F::ONE - cos_i * cos_i);
    let sin2_t = sin2_i * (eta * eta);
    if sin2_t >= F::ONE {
        return None;
    }
    let cos_t = max0(F::ONE - sin2_t).sqrt();
    let k = eta * cos_i - cos_t;
    Some(std::array::from_fn(|i| -eta * l[i] + k * n[i]))
}

/// **Wide**: the chapter's formula evaluated in the wider type (`f64` for `f32` inputs,
/// double-double for `f64`), TIR decided on the wide radicand, `T` rounded once; rejects invalid
/// input. Its radicand's error (~2⁻⁵⁰ or ~2⁻¹⁰⁰ of `η²`) is far below the change a one-ulp
/// move of `η` makes near the critical angle (~2⁻²³ or ~2⁻⁵²), so only ill-posed cases flip.
pub fn refract_wide<F: Real>(l: V<F>, n: V<F>, eta: F) -> Option<V<F>> {
    if !usable(l)
        || !usable(n)
        || !eta.is_finite()
        || eta.partial_cmp(&F::ZERO) != Some(Ordering::Greater)
    {
        return None;
    }
    let (lw, nw, ew) = (l.map(|x| x.widen()), n.map(|x| x.widen()), eta.widen());
    let one = F::Wide::ONE;
    let c = dot(nw, lw);
    let rad = one - ew * ew * (one - c * c);
    if rad < F::Wide::ZERO {
        return None;
    }
    let k = ew * c - rad.sqrt();
    Some(std::array::from_fn(|i| F::narrow(k * nw[i] - ew * lw[i])))
}

/// The refraction methods.
pub const REFRACT_METHODS: [MethodInfo; 3] = [
    MethodInfo {
        name: "chapter",
        robust: false,
        about: "seed 002 §4.2: T = (η N·L − √(1 − η²(1 − (N·L)²)))N − ηL, TIR if radicand < 0",
    },
    MethodInfo {
        name: "pbrt",
        robust: false,
        about: "pbrt-v4 Refract: sin²θt = η² max(0, 1 − cos²θi), TIR if ≥ 1, SafeSqrt",
    },
    MethodInfo {
        name: "wide",
        robust: true,
        about: "the chapter's formula in f64 (f32 inputs) or double-double (f64), rounded once",
    },
];

// ---- exact oracles ----

fn qv(v: &[f64]) -> [Rational; 3] {
    [q(v[0]), q(v[1]), q(v[2])]
}
fn qdot(a: &[Rational; 3], b: &[Rational; 3]) -> Rational {
    Rational::from(&a[0] * &b[0]) + Rational::from(&a[1] * &b[1]) + Rational::from(&a[2] * &b[2])
}
fn nonzero(v: &[f64]) -> bool {
    v.iter().any(|&x| x != 0.0)
}

/// Reflection's truth: `R` exactly, each component rounded once.
pub fn reflect_truth(v: &[f64], prec: Precision) -> Truth {
    if !exact::all_finite(v) || !nonzero(&v[0..3]) || !nonzero(&v[3..6]) {
        return Truth::Invalid;
    }
    let (l, n) = (qv(&v[0..3]), qv(&v[3..6]));
    let c2 = qdot(&l, &n) * 2u32;
    let values = (0..3)
        .map(|i| round_q(&(Rational::from(&c2 * &n[i]) - &l[i]), prec))
        .collect();
    Truth::Answer(Expected {
        count: 1,
        values,
        others: vec![],
        ill_posed: false,
        cap_reached: false,
        ..Default::default()
    })
}

/// The exact radicand `1 − η²(1 − (N·L)²)` and `N·L`, or `None` for invalid input.
fn radicand(v: &[f64]) -> Option<(Rational, Rational)> {
    if !exact::all_finite(v)
        || !nonzero(&v[0..3])
        || !nonzero(&v[3..6])
        || v[6].partial_cmp(&0.0) != Some(Ordering::Greater)
    {
        return None;
    }
    let (l, n, eta) = (qv(&v[0..3]), qv(&v[3..6]), q(v[6]));
    let c = qdot(&l, &n);
    let e2 = Rational::from(&eta * &eta);
    let rad = Rational::from(1) - e2 * (Rational::from(1) - Rational::from(&c * &c));
    Some((rad, c))
}

fn refract_count(v: &[f64]) -> u32 {
    radicand(v).is_some_and(|(rad, _)| rad >= 0) as u32
}

/// `Tᵢ = Aᵢ − √rad·Nᵢ` enclosed with `bits` of precision (`Aᵢ = η(N·L)Nᵢ − ηLᵢ` exact).
fn t_enclosure(a: &Rational, rad: &Rational, n: f64, bits: u32) -> (Float, Float) {
    let (s_lo, s_hi) = sqrt_encl(rad, bits);
    let nf = Float::with_val(64, n);
    let mul = |s: &Float, r| Float::with_val_round(bits, s * &nf, r).0;
    let (sn_lo, sn_hi) = if n >= 0.0 {
        (mul(&s_lo, Round::Down), mul(&s_hi, Round::Up))
    } else {
        (mul(&s_hi, Round::Down), mul(&s_lo, Round::Up))
    };
    let a_lo = Float::with_val_round(bits, a, Round::Down).0;
    let a_hi = Float::with_val_round(bits, a, Round::Up).0;
    (
        Float::with_val_round(bits, &a_lo - &sn_hi, Round::Down).0,
        Float::with_val_round(bits, &a_hi - &sn_lo, Round::Up).0,
    )
}

/// Refraction's truth: TIR decided exactly, `T` by Ziv's loop on MPFR enclosures.
pub fn refract_truth(v: &[f64], prec: Precision) -> Truth {
    let Some((rad, c)) = radicand(v) else {
        return Truth::Invalid;
    };
    let count = (rad >= 0) as u32;
    // One-ulp moves of each input
    let ill_posed = (0..7).any(|i| {
        [true, false].into_iter().any(|up| {
            let mut w = v.to_vec();
            w[i] = nudge(v[i], prec, up);
            w[i].is_finite() && refract_count(&w) != count
        })
    });
    let mut values = vec![];
    let mut cap_reached = false;
    if count == 1 {
        let (l, n, eta) = (qv(&v[0..3]), qv(&v[3..6]), q(v[6]));
        let ec = Rational::from(&eta * &c);
        for i in 0..3 {
            let a = Rational::from(&ec * &n[i]) - Rational::from(&eta * &l[i]);
            match ziv(prec, ZIV_CAP, |bits| t_enclosure(&a, &rad, v[3 + i], bits)) {
                Some(x) => values.push(x),
                None => {
                    cap_reached = true;
                    values.push(round_q(&a, prec));
                }
            }
        }
    }
    Truth::Answer(Expected {
        count,
        values,
        others: vec![],
        ill_posed,
        cap_reached,
        ..Default::default()
    })
}

// ---- case generation ----

fn rnd(x: f64, prec: Precision) -> f64 {
    match prec {
        Precision::F32 => x as f32 as f64,
        Precision::F64 => x,
    }
}
fn unit(rng: &mut ChaCha8Rng) -> V<f64> {
    loop {
        let v: V<f64> = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = dot(v, v).sqrt();
        if n > 1e-3 && n <= 1.0 {
            return scale(v, 1.0 / n);
        }
    }
}
/// A unit vector perpendicular to unit `n`.
fn perp(rng: &mut ChaCha8Rng, n: V<f64>) -> V<f64> {
    loop {
        let u = unit(rng);
        let w = sub(u, scale(n, dot(u, n)));
        let len = dot(w, w).sqrt();
        if len > 0.1 {
            return scale(w, 1.0 / len);
        }
    }
}
/// `L = cosθ·N + sinθ·G` for a random tangent `G`.
fn at_angle(rng: &mut ChaCha8Rng, n: V<f64>, cos: f64) -> V<f64> {
    let g = perp(rng, n);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    std::array::from_fn(|i| cos * n[i] + sin * g[i])
}
/// Each component moved by −4…4 ulps: a few ulps off unit length.
fn unnormalise(rng: &mut ChaCha8Rng, v: V<f64>, prec: Precision) -> V<f64> {
    v.map(|x| {
        let k: i32 = rng.random_range(-4..=4);
        (0..k.unsigned_abs()).fold(x, |y, _| nudge(y, prec, k > 0))
    })
}
/// Common ratios both ways, or a random one in [0.3, 3].
fn eta(rng: &mut ChaCha8Rng) -> f64 {
    let common = [1.0 / 1.5, 1.5, 1.0 / 1.333, 1.333, 1.0 / 2.42, 2.42];
    if rng.random_bool(0.5) {
        common[rng.random_range(0..common.len())]
    } else {
        rng.random_range(0.3..3.0)
    }
}
/// NaN/inf injected, or zero `L`/`N`, or `η ≤ 0`.
fn spoil(rng: &mut ChaCha8Rng, v: &mut [f64]) {
    match rng.random_range(0..5) {
        0 => v[0..3].fill(0.0),
        1 => v[3..6].fill(0.0),
        2 if v.len() == 7 => v[6] = if rng.random() { 0.0 } else { -v[6] },
        k => {
            let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][k % 3];
            v[rng.random_range(0..v.len())] = bad;
        }
    }
}

/// Reflection classes.
pub const REFLECT_CLASSES: [&str; 5] = [
    "generic",
    "grazing",
    "normal_incidence",
    "unnormalised",
    "invalid",
];
/// Refraction classes.
pub const REFRACT_CLASSES: [&str; 7] = [
    "generic",
    "critical",
    "grazing",
    "normal_incidence",
    "eta_one",
    "unnormalised",
    "invalid",
];

/// A case `L N [η]` of a class (shared by both shapes; `eta` = None for reflection).
fn propose(class: &str, prec: Precision, with_eta: bool, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let n = unit(rng);
    let mut e = eta(rng);
    let r = |v: V<f64>| v.map(|x| rnd(x, prec));
    let (l, n) = match class {
        "critical" => {
            // At the critical angle of η > 1, rounded, then η moved by −4…4 ulps
            e = rng.random_range(1.05..2.5);
            let l = at_angle(rng, n, (1.0 - 1.0 / (e * e)).sqrt());
            let k: i32 = rng.random_range(-4..=4);
            e = (0..k.unsigned_abs()).fold(rnd(e, prec), |y, _| nudge(y, prec, k > 0));
            (r(l), r(n))
        }
        "grazing" => {
            let c = 10f64.powf(rng.random_range(-8.0..-1.0));
            (r(at_angle(rng, n, c)), r(n))
        }
        "normal_incidence" => {
            let nn = r(n);
            let l = if rng.random() {
                nn
            } else {
                unnormalise(rng, nn, prec)
            };
            (l, nn)
        }
        "eta_one" => {
            e = 1.0;
            let cos = rng.random_range(0.0..1.0);
            (r(at_angle(rng, n, cos)), r(n))
        }
        "unnormalised" => {
            let cos = rng.random_range(0.0..1.0);
            let l = at_angle(rng, n, cos);
            (unnormalise(rng, r(l), prec), unnormalise(rng, r(n), prec))
        }
        // generic and invalid
        _ => {
            let cos = rng.random_range(0.0..1.0);
            (r(at_angle(rng, n, cos)), r(n))
        }
    };
    let mut v: Vec<f64> = l.into_iter().chain(n).collect();
    if with_eta {
        v.push(rnd(e, prec));
    }
    if class == "invalid" {
        spoil(rng, &mut v);
    }
    v
}

// ---- the shapes ----

/// The `reflect` shape.
pub struct Reflect;
/// The `refract` shape.
pub struct Refract;

fn vec_answer<F: Real>(r: Option<V<F>>) -> Answer {
    r.map_or_else(Answer::miss, |v| {
        Answer::hit(v.iter().map(|x| x.to_f64()).collect())
    })
}

fn reflect_in<F: Real>(m: usize, v: &[f64]) -> Answer {
    let x = |i: usize| -> V<F> { [v[i], v[i + 1], v[i + 2]].map(F::from_f64) };
    let f = [reflect_chapter::<F>, reflect_fma::<F>][m];
    vec_answer(f(x(0), x(3)))
}

fn refract_in<F: Real>(m: usize, v: &[f64]) -> Answer {
    let x = |i: usize| -> V<F> { [v[i], v[i + 1], v[i + 2]].map(F::from_f64) };
    let f = [refract_chapter::<F>, refract_pbrt::<F>, refract_wide::<F>][m];
    vec_answer(f(x(0), x(3), F::from_f64(v[6])))
}

const REFLECT: ShapeInfo = ShapeInfo {
    name: "reflect",
    about: "reflection vector R = 2(N·L)N − L, seed 002 §4.1",
    args: &["lx", "ly", "lz", "nx", "ny", "nz"],
    values: &["rx", "ry", "rz"],
    classes: &REFLECT_CLASSES,
    methods: &REFLECT_METHODS,
    metric: Metric::NormUlps,
    ..ShapeInfo::DEFAULTS
};

impl Shape for Reflect {
    fn info(&self) -> &ShapeInfo {
        &REFLECT
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        Some(propose(REFLECT_CLASSES[class], prec, false, rng))
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        reflect_truth(input, prec)
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => reflect_in::<F>(m, input))
    }
}

const REFRACT: ShapeInfo = ShapeInfo {
    name: "refract",
    about: "refraction vector, η = η_L/η_T, TIR when the radicand < 0, seed 002 §4.2",
    args: &["lx", "ly", "lz", "nx", "ny", "nz", "eta"],
    values: &["tx", "ty", "tz"],
    classes: &REFRACT_CLASSES,
    methods: &REFRACT_METHODS,
    metric: Metric::NormUlps,
    ..ShapeInfo::DEFAULTS
};

impl Shape for Refract {
    fn info(&self) -> &ShapeInfo {
        &REFRACT
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        Some(propose(REFRACT_CLASSES[class], prec, true, rng))
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        refract_truth(input, prec)
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => refract_in::<F>(m, input))
    }
}
