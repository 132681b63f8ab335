//! The root finders as audit shapes: `quadratic`, `cubic`, `quartic` (seed 002 §1.1–§1.3) and
//! `newton` (§1.4).
//!
//! **Polynomials.** Probe arguments are the coefficients LEADING FIRST (`a b c` is
//! `ax² + bx + c`); the methods of [`super::oracle::poly`] take them ascending. The answer's count is
//! the number of distinct real roots, its values those roots ascending, correctly rounded
//! ([`super::oracle::sturm`]; a double root appears once). Invalid: a NaN/inf coefficient or the zero
//! polynomial. A case is **ill-posed** when the number of distinct real roots changes as any
//! one coefficient moves one ulp up or down (2(n+1) exact Sturm counts). An exact double root
//! is ill-posed by construction (moving the constant term splits it or removes it); a leading
//! coefficient exactly 0 too (a one-ulp leading term adds a root far out).
//!
//! **Newton.** Arguments `a b c d lo hi x0`: the cubic `ax³ + bx² + cx + d` (leading first),
//! a bracket and a start in it. The exact answer is the root in `[lo, hi]`: count 1 with its
//! correctly rounded value, or 0 when the bracket holds no root. Invalid: NaN/inf, the zero
//! polynomial, `lo ≥ hi`, `x0` outside the bracket, or several distinct roots in the bracket
//! (the answer would not be one root; no class generates it). Ill-posed: the number of roots in
//! the bracket changes as one of the six inputs `a b c d lo hi` moves one ulp. The other real
//! roots of the cubic are the `others` of the judgement: plain Newton landing nearer one of
//! them is a wrong root.

use super::oracle::poly;
use super::oracle::quick_roots;
use super::oracle::sturm::{self, RealRoot};
use crate::numerics::exact::{all_finite, nudge, q};
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::oracle::ulp_box::{
    roots_keep_count, strict_sign as sign_on_box, ulp_box, BoxIv,
};
use crate::shapes::shape::{Answer, Expected, MethodInfo, Shape, ShapeInfo, Truth};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rug::Rational;

// ---- generation helpers ----

/// `x` rounded into the precision.
fn fit(x: f64, prec: Precision) -> f64 {
    match prec {
        Precision::F32 => x as f32 as f64,
        Precision::F64 => x,
    }
}

/// Significand bits of the precision.
fn bits(prec: Precision) -> i32 {
    match prec {
        Precision::F32 => 24,
        Precision::F64 => 53,
    }
}

/// `±10^U(lo, hi)`.
fn magnitude(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    let s = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    s * 10f64.powf(rng.random_range(lo..hi))
}

/// A random root of moderate size, representable in the precision.
fn root(rng: &mut ChaCha8Rng, prec: Precision) -> f64 {
    fit(magnitude(rng, -1.0, 1.0), prec)
}

/// Ascending coefficients of `lead · ∏(x − rᵢ) · ∏(x² + pⱼx + qⱼ)`, computed in `f64` and
/// rounded into the precision (the oracle decides the truth of the rounded polynomial).
fn from_factors(lead: f64, roots: &[f64], quads: &[(f64, f64)], prec: Precision) -> Vec<f64> {
    let mut c = vec![lead];
    let mul = |c: &[f64], f: &[f64]| {
        let mut out = vec![0.0; c.len() + f.len() - 1];
        for (i, a) in c.iter().enumerate() {
            for (j, b) in f.iter().enumerate() {
                out[i + j] += a * b;
            }
        }
        out
    };
    for &r in roots {
        c = mul(&c, &[-r, 1.0]);
    }
    for &(p, qq) in quads {
        c = mul(&c, &[qq, p, 1.0]);
    }
    c.into_iter().map(|x| fit(x, prec)).collect()
}

/// A complex pair `α ± iβ` as the factor `x² − 2αx + α² + β²`.
fn complex_pair(rng: &mut ChaCha8Rng) -> (f64, f64) {
    let alpha = magnitude(rng, -1.0, 1.0);
    let beta = alpha.abs() * 10f64.powf(rng.random_range(-2.0..0.5));
    (-2.0 * alpha, alpha * alpha + beta * beta)
}

/// Leading-first probe order from ascending coefficients.
fn leading_first(mut c: Vec<f64>) -> Vec<f64> {
    c.reverse();
    c
}

// ---- the polynomial shapes ----

/// A polynomial shape of one degree.
pub struct Roots {
    degree: usize,
    info: ShapeInfo,
}

/// Quadratics `a x² + b x + c` (Lengyel §1.1).
pub static QUADRATIC: Roots = Roots {
    degree: 2,
    info: ShapeInfo {
        name: "quadratic",
        about: "real roots of ax²+bx+c (§1.1)",
        args: &["a", "b", "c"],
        values: &["x1", "x2"],
        classes: QUADRATIC_CLASSES,
        methods: QUADRATIC_METHODS,
        count_is_values: true,
        reports_cond: true,
        ..ShapeInfo::DEFAULTS
    },
};
/// The Sturm oracle with one-ulp ill-posedness costs about 0.1 ms per cubic or quartic case:
/// 5,000 cases per class by default.
pub static CUBIC: Roots = Roots {
    degree: 3,
    info: ShapeInfo {
        name: "cubic",
        about: "real roots of ax³+bx²+cx+d (§1.2)",
        args: &["a", "b", "c", "d"],
        values: &["x1", "x2", "x3"],
        classes: CUBIC_CLASSES,
        methods: CUBIC_METHODS,
        default_cases: 5_000,
        ..QUADRATIC.info
    },
};
/// Quartics by Ferrari's resolvent cubic (Lengyel §1.3).
pub static QUARTIC: Roots = Roots {
    degree: 4,
    info: ShapeInfo {
        name: "quartic",
        about: "real roots of ax⁴+bx³+cx²+dx+e (§1.3)",
        args: &["a", "b", "c", "d", "e"],
        values: &["x1", "x2", "x3", "x4"],
        classes: QUARTIC_CLASSES,
        methods: QUARTIC_METHODS,
        default_cases: 5_000,
        ..QUADRATIC.info
    },
};

const QUADRATIC_METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "textbook",
        robust: false,
        about: "§1.1: D = b² − 4ac, (−b ± √D)/2a",
    },
    MethodInfo {
        name: "robust",
        robust: true,
        about: "Kahan/pbrt: D by FMA difference of products, q = −½(b + sign(b)√D), q/a and c/q",
    },
];

const CUBIC_METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "chapter",
        robust: false,
        about: "§1.2: depressed cubic, Cardano / double root / trigonometric form by D′",
    },
    MethodInfo {
        name: "yuksel",
        robust: true,
        about: "Yuksel: derivative roots split into monotonic pieces, bracketed Newton to one ulp",
    },
];

const QUARTIC_METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "ferrari",
        robust: false,
        about: "§1.3: depressed quartic, resolvent cubic (§1.2), two quadratics (§1.1)",
    },
    MethodInfo {
        name: "yuksel",
        robust: true,
        about: "Yuksel: derivative roots split into monotonic pieces, bracketed Newton to one ulp",
    },
];

/// Every class; a degree uses the ones that exist for it (see `Roots::classes`).
pub const GENERIC: &str = "generic";
/// Class: a repeated root (a small dyadic with exact coefficients, or a random one).
pub const DOUBLE_ROOT: &str = "double_root";
/// Class: two roots `r` and `r(1 + δ)`, from a few thousand ulps apart (ill-posed) to past √ulp.
pub const CLUSTERED: &str = "clustered";
/// Class: one root 10⁻³ … 10⁻¹⁰ (f32) or 10⁻⁶ … 10⁻²⁰ (f64) of the others.
pub const NEAR_ZERO: &str = "near_zero";
/// Class: coefficients over 10^±15 (f32) or 10^±30 (f64).
pub const HUGE_RANGE: &str = "huge_range";
/// Class: complex pairs only.
pub const NO_REAL: &str = "no_real";
/// Class: a leading coefficient 10⁻⁴ … 10⁻¹⁴ (f32) or 10⁻⁸ … 10⁻³⁰ (f64) of the others; 1 in 16 exactly 0.
pub const TINY_LEADING: &str = "tiny_leading";
/// Class: Kahan's hard quadratic, `b² − ac` a few units in the last place of `b²`.
pub const KAHAN: &str = "kahan";
/// Class: NaN, ±∞ or a zero polynomial.
pub const INVALID: &str = "invalid";

const QUADRATIC_CLASSES: &[&str] = &[
    GENERIC,
    DOUBLE_ROOT,
    CLUSTERED,
    NEAR_ZERO,
    HUGE_RANGE,
    NO_REAL,
    TINY_LEADING,
    KAHAN,
    INVALID,
];
/// A cubic always has a real root: no `no_real`.
const CUBIC_CLASSES: &[&str] = &[
    GENERIC,
    DOUBLE_ROOT,
    CLUSTERED,
    NEAR_ZERO,
    HUGE_RANGE,
    TINY_LEADING,
    INVALID,
];
const QUARTIC_CLASSES: &[&str] = &[
    GENERIC,
    DOUBLE_ROOT,
    CLUSTERED,
    NEAR_ZERO,
    HUGE_RANGE,
    NO_REAL,
    TINY_LEADING,
    INVALID,
];

impl Roots {
    /// Coefficients (ascending) of a case of `class`.
    fn coefficients(&self, class: &str, prec: Precision, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let n = self.degree;
        let lead = fit(magnitude(rng, -1.0, 1.0), prec);
        let others = |rng: &mut ChaCha8Rng, k: usize| -> Vec<f64> {
            (0..k).map(|_| root(rng, prec)).collect()
        };
        match class {
            // Random coefficients over two decades
            GENERIC => (0..=n)
                .map(|_| fit(magnitude(rng, -1.0, 1.0), prec))
                .collect(),
            // A repeated root: a small dyadic (exact coefficients) or a random one
            DOUBLE_ROOT => {
                let r = if rng.random_bool(0.5) {
                    rng.random_range(-16..=16) as f64 / 4.0
                } else {
                    root(rng, prec)
                };
                let mut rs = vec![r, r];
                rs.extend(others(rng, n - 2));
                from_factors(lead, &rs, &[], prec)
            }
            // Two roots r and r(1 + δ), δ log-uniform in [2¹⁰, 2^(p/2+6)] ulps: from a few
            // thousand ulps (ill-posed) to past √ulp, where well-posed cases begin
            CLUSTERED => {
                let r = root(rng, prec);
                let p = bits(prec) as f64;
                let delta = 2f64.powf(rng.random_range((11.0 - p)..(7.0 - p / 2.0)));
                let mut rs = vec![r, fit(r * (1.0 + delta), prec)];
                rs.extend(others(rng, n - 2));
                from_factors(lead, &rs, &[], prec)
            }
            // One root 10⁻³ … 10⁻¹⁰ (f32) or 10⁻⁶ … 10⁻²⁰ (f64) of the others
            NEAR_ZERO => {
                let (lo, hi) = match prec {
                    Precision::F32 => (3.0, 10.0),
                    Precision::F64 => (6.0, 20.0),
                };
                let mut rs = others(rng, n - 1);
                rs.push(fit(magnitude(rng, -hi, -lo), prec));
                from_factors(lead, &rs, &[], prec)
            }
            // Coefficients over 10^±15 (f32) or 10^±30 (f64)
            HUGE_RANGE => {
                let e = match prec {
                    Precision::F32 => 15.0,
                    Precision::F64 => 30.0,
                };
                (0..=n).map(|_| fit(magnitude(rng, -e, e), prec)).collect()
            }
            // Complex pairs only
            NO_REAL => {
                let quads: Vec<(f64, f64)> = (0..n / 2).map(|_| complex_pair(rng)).collect();
                from_factors(lead, &[], &quads, prec)
            }
            // A monic polynomial of degree n − 1 under a leading term 10⁻⁴ … 10⁻¹⁴ (f32) or
            // 10⁻⁸ … 10⁻³⁰ (f64) of the others; 1 case in 16 exactly 0
            TINY_LEADING => {
                let (lo, hi) = match prec {
                    Precision::F32 => (4.0, 14.0),
                    Precision::F64 => (8.0, 30.0),
                };
                let mut c = from_factors(1.0, &others(rng, n - 1), &[], prec);
                let tiny = if rng.random_range(0..16) == 0 {
                    0.0
                } else {
                    fit(magnitude(rng, -hi, -lo), prec)
                };
                c.push(tiny);
                c
            }
            KAHAN => kahan(prec, rng),
            _ => invalid(n, prec, rng),
        }
    }

    fn solve<F: Real>(&self, m: usize, c: &[f64]) -> Vec<F> {
        let c: Vec<F> = c.iter().map(|&x| F::from_f64(x)).collect();
        match (self.degree, m) {
            (2, 0) => poly::quadratic_textbook([c[0], c[1], c[2]]),
            (2, _) => poly::quadratic_robust([c[0], c[1], c[2]]),
            (3, 0) => poly::cubic_chapter([c[0], c[1], c[2], c[3]]),
            (4, 0) => poly::quartic_ferrari([c[0], c[1], c[2], c[3], c[4]]),
            _ => poly::poly_roots_robust(&c),
        }
    }
}

/// Kahan's hard quadratic (his `94906265.625, 94906267, 94906268.375` in double):
/// `a x² − 2b x + c` with `a, b, c ≈ 2^(p/2)` and `b² − ac` a few units of `b²`'s last place,
/// so the naive discriminant keeps no correct digit.
fn kahan(prec: Precision, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let p = bits(prec);
    // b on a grid of 2^(p/2 − p + 3): a few fractional bits, like Kahan's
    let scale = 2f64.powi(p / 2);
    let b = fit(scale * rng.random_range(1.0..2.0), prec);
    let a = fit(b - rng.random_range(1.0..64.0), prec);
    // b² − ac = k units of the last place of b²
    let ulp_b2 = 2f64.powi((b * b).log2().floor() as i32 + 1 - p);
    let k = rng.random_range(-16.0..48.0);
    let c = fit((b * b - k * ulp_b2) / a, prec);
    let s = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    vec![s * c, -2.0 * s * b, s * a]
}

/// NaN/±inf in one coefficient, or the zero polynomial (ascending).
fn invalid(n: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut c: Vec<f64> = (0..=n)
        .map(|_| fit(magnitude(rng, -1.0, 1.0), prec))
        .collect();
    match rng.random_range(0..4) {
        0 => c.iter_mut().for_each(|x| *x = 0.0),
        k => c[rng.random_range(0..=n)] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][k - 1],
    }
    c
}

/// Exact ascending coefficients of probe-order (leading-first) input.
fn exact_ascending(input: &[f64]) -> Vec<Rational> {
    input.iter().rev().map(|&x| q(x)).collect()
}

/// The number of distinct real roots of `input` (leading first) changes when one coefficient
/// moves one ulp up or down.
fn count_unstable(input: &[f64], prec: Precision, count: u32) -> bool {
    // The whole box first, then one move at a time, each counted exactly
    if let Some(b) = ulp_box(input, prec) {
        if roots_keep_count(&b.into_iter().rev().collect::<Vec<_>>()) {
            return false;
        }
    }
    (0..input.len()).any(|i| {
        [true, false].into_iter().any(|up| {
            let mut moved = input.to_vec();
            moved[i] = nudge(moved[i], prec, up);
            moved[i].is_finite() && sturm::count_distinct(&exact_ascending(&moved)) != count
        })
    })
}

impl Shape for Roots {
    fn info(&self) -> &ShapeInfo {
        &self.info
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        let c = self.coefficients(self.info().classes[class], prec, rng);
        Some(leading_first(c))
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        if !all_finite(input) {
            return Truth::Invalid;
        }
        let c = exact_ascending(input);
        if sturm::trim(&c).is_empty() {
            return Truth::Invalid;
        }
        // The quick phase proves most cases; the exact Sturm path runs when it cannot
        let asc: Vec<f64> = input.iter().rev().copied().collect();
        let values = quick_roots::rounded_roots(&asc, prec)
            .unwrap_or_else(|| sturm::rounded_roots(&c, prec));
        let count = values.len() as u32;
        // Each root's own sensitivity: a multiple root (f' = 0) excuses any error
        let conds = values
            .iter()
            .map(|&x| root_cond(input, x, prec).unwrap_or(f64::INFINITY))
            .collect();
        Truth::Answer(Expected {
            count,
            others: values.iter().skip(1).copied().collect(),
            conds,
            values,
            ill_posed: count_unstable(input, prec, count),
            cap_reached: false,
            ..Default::default()
        })
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        let c: Vec<f64> = input.iter().rev().copied().collect();
        let values: Vec<f64> = match prec {
            Precision::F32 => self
                .solve::<f32>(m, &c)
                .iter()
                .map(|x| x.to_f64())
                .collect(),
            Precision::F64 => self
                .solve::<f64>(m, &c)
                .iter()
                .map(|x| x.to_f64())
                .collect(),
        };
        Answer {
            count: values.len() as u32,
            values,
            enclosure: None,
        }
    }
}

// ---- the Newton shape ----

/// Newton's method on a cubic in a bracket (§1.4).
pub struct Newton;

/// Newton's method on a cubic in a bracket (Lengyel §1.4).
pub static NEWTON: Newton = Newton;

const NEWTON_METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "newton_plain",
        robust: false,
        about: "§1.4: x − f(x)/f′(x) from x0, 32 steps at most, miss on f′ = 0",
    },
    MethodInfo {
        name: "newton_bracketed",
        robust: true,
        about: "safeguarded Newton: clamped to the bracket, bisection fallback, to one ulp",
    },
];

/// Class: three real roots, a bracket around one, `x₀` near the root.
pub const NEAR_ROOT: &str = "near_root";
/// Class: `x₀` at the critical point between two roots (`f′(x₀) ≈ 0`).
pub const FLAT_START: &str = "flat_start";
/// Class: one real root and a complex pair, `x₀` at the far end of a wide bracket.
pub const FAR_START: &str = "far_start";
/// Class: `(x − r)³ + δ`, a simple root amid a complex pair: Newton converges linearly.
pub const MULTIPLE_ROOT: &str = "multiple_root";

const NEWTON_CLASSES: &[&str] = &[NEAR_ROOT, FLAT_START, FAR_START, MULTIPLE_ROOT, INVALID];

/// Whether the number of roots in the bracket is the same everywhere on the one-ulp box of
/// `a b c d lo hi`: the cubic keeps its count of distinct real roots, none crosses an end of
/// the bracket (the cubic's sign at each end is certain), and `lo < hi` throughout.
fn bracket_keeps_count(v: &[f64], prec: Precision) -> bool {
    let Some(b) = ulp_box(v, prec) else {
        return false;
    };
    let horner = |x: BoxIv| b[1..4].iter().fold(b[0], |acc, &c| acc * x + c);
    b[4].hi < b[5].lo
        && sign_on_box(horner(b[4])).is_some()
        && sign_on_box(horner(b[5])).is_some()
        && roots_keep_count(&[b[3], b[2], b[1], b[0]])
}

/// The state of a bracket: roots in it, with 2 standing for "several"; `None` when invalid.
fn bracket_state(c: &[Rational], lo: f64, hi: f64) -> Option<u32> {
    if sturm::trim(c).is_empty() || lo >= hi {
        return None;
    }
    Some(sturm::count_in(c, &q(lo), &q(hi)).min(2))
}

impl Newton {
    /// `(ascending cubic, lo, hi, x0)` of a case of `class`, before rounding checks.
    fn case(
        &self,
        class: &str,
        prec: Precision,
        rng: &mut ChaCha8Rng,
    ) -> (Vec<f64>, f64, f64, f64) {
        let lead = fit(magnitude(rng, -1.0, 1.0), prec);
        match class {
            // Three real roots; a bracket around one, well inside its gaps; x0 near the root
            NEAR_ROOT => {
                let mut rs: Vec<f64> = (0..3).map(|_| root(rng, prec)).collect();
                rs.sort_by(f64::total_cmp);
                let k = rng.random_range(0..3);
                let gap = [rs[1] - rs[0], rs[2] - rs[1]]
                    .into_iter()
                    .chain([rs[k].abs() + 1.0])
                    .fold(f64::INFINITY, f64::min);
                let r = rs[k];
                let x0 = r + gap * magnitude(rng, -6.0, -1.5);
                let c = from_factors(lead, &rs, &[], prec);
                (
                    c,
                    fit(r - 0.4 * gap, prec),
                    fit(r + 0.4 * gap, prec),
                    fit(x0, prec),
                )
            }
            // Three real roots r1 < r2 < r3; x0 at the critical point between r1 and r2
            // (f′(x0) ≈ 0), the bracket from there to the middle of r2 and r3
            FLAT_START => {
                let mut rs: Vec<f64> = (0..3).map(|_| root(rng, prec)).collect();
                rs.sort_by(f64::total_cmp);
                let c = from_factors(lead, &rs, &[], prec);
                // The critical point of the exact cubic through the roots
                let (s1, s2) = (
                    rs.iter().sum::<f64>(),
                    rs[0] * rs[1] + rs[0] * rs[2] + rs[1] * rs[2],
                );
                let xc = (s1 - (s1 * s1 - 3.0 * s2).max(0.0).sqrt()) / 3.0;
                let x0 = fit(xc, prec);
                let lo = fit(x0 - 0.1 * (x0 - rs[0]).abs(), prec);
                (c, lo, fit(0.5 * (rs[1] + rs[2]), prec), x0)
            }
            // One real root and a complex pair; a wide bracket with x0 at its far end
            FAR_START => {
                let r = root(rng, prec);
                let c = from_factors(lead, &[r], &[complex_pair(rng)], prec);
                let w = r.abs().max(1.0) * 10f64.powf(rng.random_range(0.5..3.0));
                let (lo, hi) = (
                    fit(r - w * rng.random_range(0.1..1.0), prec),
                    fit(r + w, prec),
                );
                let x0 = if rng.random_bool(0.5) { lo } else { hi };
                (c, lo, hi, x0)
            }
            // (x − r)³ + δ: one simple real root r − ∛δ amid a complex pair, ∛δ/|r| from
            // 10⁻² to 10⁻⁶; Newton converges linearly (factor ⅔) until it is within ∛δ
            MULTIPLE_ROOT => {
                let r = root(rng, prec);
                let cr = r.abs() * magnitude(rng, -6.0, -2.0);
                let delta = cr * cr * cr;
                let mut c = from_factors(1.0, &[r, r, r], &[], prec);
                c[0] = fit(c[0] + delta, prec);
                let w = r.abs() * rng.random_range(0.1..0.5);
                let (lo, hi) = (fit(r - w, prec), fit(r + w, prec));
                let x0 = if rng.random_bool(0.5) { lo } else { hi };
                (c, lo, hi, x0)
            }
            // NaN/inf anywhere, the zero cubic, an empty bracket, a start outside it
            _ => {
                let mut c: Vec<f64> = (0..4).map(|_| root(rng, prec)).collect();
                let (mut lo, mut hi, mut x0) = (-1.0, 1.0, 0.5);
                match rng.random_range(0..5) {
                    0 => c = vec![0.0; 4],
                    1 => c[rng.random_range(0..4)] = f64::NAN,
                    2 => x0 = [f64::NAN, f64::INFINITY][rng.random_range(0..2)],
                    3 => (lo, hi) = (1.0, -1.0),
                    _ => x0 = 2.0,
                }
                (c, lo, hi, x0)
            }
        }
    }
}

/// First-order sensitivity of a root `x` of `Σ a_i x^i` (`lead_first`, leading coefficient
/// first) to its coefficients, in ulps of `x`: how far `x` moves when every coefficient moves one
/// ulp of the precision, `Σ |x|^i ulp(a_i) / |f'(x)| / ulp(x)`. Evaluated in `f64` at the
/// correctly rounded root: an estimate, not a bound. `None` where `f'(x)` is 0 (a multiple root).
///
/// Why a Newton method is judged by err/cond (`tolerances.toml`): Horner's rule evaluates `f(x)`
/// with an absolute error at most `γ₂ₙ Σ|a_i||x|^i` (Higham, *Accuracy and Stability*, eq. 5.3;
/// `γ₆` for a cubic), and since `ulp(a) ≥ u|a|` (`u = 2^-p`) that is at most `γ₂ₙ/u · cond ·
/// ulp(x)`, about `2n·cond` ulps of `x` after division by `f'`. Newton's iterates, once within
/// that band of the root, stay within twice it (a step is the computed residual over the
/// derivative); the result's rounding adds half an ulp. So a Newton iteration that has converged
/// on a cubic is within `12·cond + 1` ulps, whatever the seed or the case count. With signs from
/// compensated Horner (Yuksel's solver) the band is second order, `γ₂ₙ²/u · cond`: within one ulp
/// of the sign change plus a negligible `8n²u·cond`.
pub fn root_cond(lead_first: &[f64], x: f64, prec: Precision) -> Option<f64> {
    if !x.is_finite() {
        return None;
    }
    let n = lead_first.len() - 1;
    // f'(x) by Horner on the derivative's coefficients
    let df = lead_first[..n]
        .iter()
        .enumerate()
        .fold(0.0, |acc, (i, &a)| acc * x + (n - i) as f64 * a);
    if df == 0.0 || !df.is_finite() {
        return None;
    }
    let u = crate::numerics::exact::ulp;
    let ax = x.abs();
    let sum = lead_first.iter().fold(0.0, |acc, &a| acc * ax + u(a, prec));
    let ux = u(x, prec);
    (ux > 0.0).then(|| sum / df.abs() / ux)
}

const NEWTON_INFO: ShapeInfo = ShapeInfo {
    name: "newton",
    about: "Newton's method on ax³+bx²+cx+d in [lo, hi] from x0 (§1.4)",
    args: &["a", "b", "c", "d", "lo", "hi", "x0"],
    values: &["x"],
    classes: NEWTON_CLASSES,
    methods: NEWTON_METHODS,
    // The Sturm oracle with one-ulp ill-posedness costs about 0.1 ms per case.
    default_cases: 5_000,
    reports_cond: true,
    ..ShapeInfo::DEFAULTS
};

impl Shape for Newton {
    fn info(&self) -> &ShapeInfo {
        &NEWTON_INFO
    }
    /// A proposal whose rounded cubic does not have exactly one root in the bracket (the
    /// rounding can add or remove one) is redrawn, up to 16 times.
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        let name = self.info().classes[class];
        (0..16).find_map(|_| {
            let (c, lo, hi, x0) = self.case(name, prec, rng);
            let member = name == INVALID || {
                let exact: Vec<Rational> = c.iter().map(|&x| q(x)).collect();
                bracket_state(&exact, lo, hi) == Some(1)
            };
            let mut v = leading_first(c);
            v.extend([lo, hi, x0]);
            member.then_some(v)
        })
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        if !all_finite(input) {
            return Truth::Invalid;
        }
        let c = exact_ascending(&input[..4]);
        let (lo, hi, x0) = (input[4], input[5], input[6]);
        let state = bracket_state(&c, lo, hi);
        if state.is_none() || state == Some(2) || !(x0 >= lo && x0 <= hi) {
            return Truth::Invalid;
        }
        // Ill-posed: the bracket's root count moves under one-ulp moves of a b c d lo hi
        // (the whole box first, then one move at a time, each counted exactly)
        let ill_posed = !bracket_keeps_count(&input[..6], prec)
            && (0..6).any(|i| {
                [true, false].into_iter().any(|up| {
                    let mut m = input.to_vec();
                    m[i] = nudge(m[i], prec, up);
                    m[i].is_finite()
                        && bracket_state(&exact_ascending(&m[..4]), m[4], m[5]) != state
                })
            });
        let asc: Vec<f64> = input[..4].iter().rev().copied().collect();
        let all = quick_roots::rounded_roots(&asc, prec)
            .unwrap_or_else(|| sturm::rounded_roots(&c, prec));
        let values = if state == Some(1) {
            // The one root is in (lo, hi], or is lo itself
            let ql = q(lo);
            let at_lo = sturm::sign_at(&c, &ql) == std::cmp::Ordering::Equal;
            let iso = RealRoot {
                hi: if at_lo { ql.clone() } else { q(hi) },
                lo: ql,
                multiplicity: 1,
            };
            vec![sturm::round_root(&c, &iso, prec)]
        } else {
            vec![]
        };
        let mut others = all;
        if let Some(p) = values
            .first()
            .and_then(|v| others.iter().position(|o| o == v))
        {
            others.remove(p);
        }
        let cond = values
            .first()
            .and_then(|&x| root_cond(&input[..4], x, prec));
        Truth::Answer(Expected {
            count: values.len() as u32,
            values,
            others,
            ill_posed,
            cap_reached: false,
            cond,
            ..Default::default()
        })
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => run_newton::<F>(m, input))
    }
}

fn run_newton<F: Real>(m: usize, input: &[f64]) -> Answer {
    let v: Vec<F> = input.iter().map(|&x| F::from_f64(x)).collect();
    let c = [v[3], v[2], v[1], v[0]];
    let x = match m {
        0 => poly::newton_plain(&c, v[6]),
        _ => poly::newton_bracketed(&c, v[4], v[5], v[6]),
    };
    match x {
        Some(x) => Answer::hit(vec![x.to_f64()]),
        None => Answer::miss(),
    }
}
