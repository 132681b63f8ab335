//! Polynomial root finders (seed 002 §1.1–§1.4), written once over [`Real`].
//!
//! Coefficient arrays are ASCENDING: `c[0] + c[1]·x + … + c[n]·xⁿ`. Every solver returns its
//! real roots in ascending order; a root appears twice only where the method's own formula
//! produces it twice (the chapter's cubic at `D′ = 0`, Ferrari's two quadratics sharing a root).
//!
//! - [`quadratic_textbook`]: §1.1, `D = b² − 4ac`, `(−b ± √D) / 2a`.
//! - [`quadratic_robust`]: Kahan / pbrt: `D` by [`difference_of_products`] (FMA recovers the
//!   product's rounding error, so `D` has a small relative error and the right sign),
//!   `q = −½(b + copysign(√D, b))`, roots `q/a` and `c/q` (no cancellation), linear when `a = 0`.
//! - [`cubic_chapter`]: §1.2, normalise, depress with `t = x − a/3`, `D′ = −(p/3)³ − (q/2)²`;
//!   Cardano when `D′ < 0`, the double root when `D′ = 0`, the trigonometric form when `D′ > 0`.
//! - [`quartic_ferrari`]: §1.3, depress with `t = x − a/4`, one real root `y` of the resolvent
//!   cubic (solved by [`cubic_chapter`]; the chapter allows any real root, this takes the
//!   largest, the usual choice since it makes `2y − p ≥ 0` when real roots exist), then two
//!   quadratics split by the sign of `q`, solved by [`quadratic_textbook`].
//! - [`poly_roots_robust`]: Yuksel's method (numerics.md §7), any degree. The roots of the
//!   derivative (found recursively, the quadratic by [`quadratic_robust`]) split `[−B, B]`
//!   (`B` a power of two above Fujiwara's root bound) into monotonic pieces; in each piece whose
//!   ends differ in sign, Newton steps clamped to the bracket, with bisection on the floats
//!   (ordinal midpoints) when a step leaves the bracket or the bracket does not halve, run until
//!   the bracket is two adjacent floats: there is no loose `xError`. The signs that move the
//!   bracket come from a compensated Horner evaluation (Graillat–Langlois–Louvet: as accurate
//!   as twice the working precision) on coefficients rescaled by powers of two around `x`, so
//!   neither overflow nor underflow decides a sign; the Newton step itself uses plain Horner.
//!   Of the two final floats, the one with the smaller `|p|` is returned.
//! - [`newton_plain`] and [`newton_bracketed`]: §1.4, the chapter's iteration with a fixed cap,
//!   and the bracketed, safeguarded one (the same bracket solver as Yuksel's method).
//!
//! Rescaling by powers of two is exact; exponents are computed in `f64` (exact conversions),
//! which changes no rounding of the working precision.

use crate::numerics::real::Real;
use std::cmp::Ordering;

// ---- helpers ----

fn lit<F: Real>(x: f64) -> F {
    F::from_f64(x)
}

fn sort<F: Real>(mut v: Vec<F>) -> Vec<F> {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap_or(Ordering::Equal));
    v
}

/// A libm function in the working precision (`f32`'s own for `f32`).
fn libm<F: Real>(x: F, f32f: fn(f32) -> f32, f64f: fn(f64) -> f64) -> F {
    if F::MANT_BITS == 24 {
        F::from_f64(f32f(x.to_f64() as f32) as f64)
    } else {
        F::from_f64(f64f(x.to_f64()))
    }
}

fn cbrt<F: Real>(x: F) -> F {
    libm(x, f32::cbrt, f64::cbrt)
}

fn acos<F: Real>(x: F) -> F {
    libm(x, f32::acos, f64::acos)
}

fn cos<F: Real>(x: F) -> F {
    libm(x, f32::cos, f64::cos)
}

/// `a·b − c·d` with the rounding error of `c·d` recovered by FMA (Kahan; pbrt's
/// `DifferenceOfProducts`): relative error within about 2 units of the last place.
pub fn difference_of_products<F: Real>(a: F, b: F, c: F, d: F) -> F {
    let cd = c * d;
    let err = (-c).mul_add(d, cd);
    let dop = a.mul_add(b, -cd);
    dop + err
}

/// `x·2ⁿ` in `f64`, in steps that stay in range.
fn ldexp(mut x: f64, mut n: i32) -> f64 {
    while n != 0 {
        let k = n.clamp(-1000, 1000);
        x *= 2f64.powi(k);
        n -= k;
    }
    x
}

/// `⌊log₂|x|⌋` of a non-zero finite value.
fn exponent(x: f64) -> i32 {
    let e = ((x.to_bits() >> 52) & 0x7ff) as i32;
    if e == 0 {
        x.abs().log2().floor() as i32
    } else {
        e - 1023
    }
}

/// The coefficients times the power of two that brings the largest magnitude near 1 (exact
/// unless a coefficient is tiny beside the largest and underflows).
pub fn normalised<F: Real>(c: &[F]) -> Vec<F> {
    let m = c.iter().fold(0f64, |m, x| m.max(x.abs().to_f64()));
    if m == 0.0 || !m.is_finite() {
        return c.to_vec();
    }
    let e = exponent(m);
    let (s1, s2) = (
        F::from_f64(ldexp(1.0, -e / 2)),
        F::from_f64(ldexp(1.0, -e + e / 2)),
    );
    c.iter().map(|&x| x * s1 * s2).collect()
}

/// The coefficients without zero high-order terms.
fn trimmed<F: Real>(c: &[F]) -> &[F] {
    let n = c.iter().rposition(|&x| x != F::ZERO).map_or(0, |i| i + 1);
    &c[..n]
}

/// `p(x)` by Horner's rule.
pub fn horner<F: Real>(c: &[F], x: F) -> F {
    c.iter().rev().fold(F::ZERO, |acc, &ci| acc.mul_add(x, ci))
}

/// `p(x)` by compensated Horner (error-free transformations: the result is as accurate as
/// Horner in twice the precision, then rounded).
fn comp_horner<F: Real>(c: &[F], x: F) -> F {
    let n = c.len() - 1;
    let (mut s, mut err) = (c[n], F::ZERO);
    for &ci in c[..n].iter().rev() {
        // TwoProduct(s, x) and TwoSum(p, cᵢ)
        let p = s * x;
        let pe = s.mul_add(x, -p);
        let t = p + ci;
        let z = t - p;
        let se = (p - (t - z)) + (ci - z);
        err = err.mul_add(x, pe + se);
        s = t;
    }
    s + err
}

/// `p(x)` as `(v, e)` with `p(x) ≈ v·2ᵉ`: compensated Horner on the coefficients rescaled so
/// that the largest term `cᵢxⁱ` is about 1. Overflow and underflow of the terms cannot
/// change the sign.
fn eval_scaled<F: Real>(c: &[F], x: F) -> (F, i32) {
    if x == F::ZERO {
        return (c[0], 0);
    }
    // Fast path: |x| ∈ [2^(−64/n), 2^(64/n)] on coefficients normalised near 1 keeps every term
    // and every error term within 2^±130 of 1, normal in both precisions
    let n = c.len().max(2) as i32 - 1;
    let ex = exponent(x.to_f64());
    let top = c.iter().fold(0f64, |m, v| m.max(v.abs().to_f64()));
    if ex.abs() <= 64 / n && (0.5..4.0).contains(&top) {
        return (comp_horner(c, x), 0);
    }
    // x = m·2ᵏ, and the largest term's exponent E
    let k = ex;
    let big = c
        .iter()
        .enumerate()
        .filter(|(_, ci)| **ci != F::ZERO)
        .map(|(i, ci)| exponent(ci.to_f64()) + i as i32 * k)
        .max()
        .unwrap_or(0);
    let scaled: Vec<F> = c
        .iter()
        .enumerate()
        .map(|(i, ci)| F::from_f64(ldexp(ci.to_f64(), i as i32 * k - big)))
        .collect();
    let m = F::from_f64(ldexp(x.to_f64(), -k));
    (comp_horner(&scaled, m), big)
}

/// The sign of `p(x)` (`None` for zero), from [`eval_scaled`].
fn negative_at<F: Real>(c: &[F], x: F) -> Option<bool> {
    let v = eval_scaled(c, x).0;
    if v == F::ZERO {
        None
    } else {
        Some(v < F::ZERO)
    }
}

/// `log₂|p(x)|` (−∞ at a zero), for comparing residuals across scales.
fn log_residual<F: Real>(c: &[F], x: F) -> f64 {
    let (v, e) = eval_scaled(c, x);
    v.abs().to_f64().log2() + e as f64
}

fn derivative<F: Real>(c: &[F]) -> Vec<F> {
    c.iter()
        .enumerate()
        .skip(1)
        .map(|(i, &ci)| F::from_f64(i as f64) * ci)
        .collect()
}

fn from_ordinal<F: Real>(o: i64) -> F {
    let m = F::from_bits_u64(o.unsigned_abs());
    if o < 0 {
        -m
    } else {
        m
    }
}

/// The float halfway between two floats in ordinal (ulp) distance.
fn ordinal_mid<F: Real>(lo: F, hi: F) -> F {
    let (a, b) = (lo.ordinal() as i128, hi.ordinal() as i128);
    from_ordinal((a + (b - a) / 2) as i64)
}

/// A power of two above Fujiwara's bound `2·max |cₙ₋ᵢ/cₙ|^{1/i}` (the last term halved), or
/// infinity when it exceeds the precision's range.
fn root_bound<F: Real>(c: &[F]) -> F {
    let n = c.len() - 1;
    let lead = c[n].abs().to_f64().log2();
    let m = (1..=n)
        .filter(|&i| c[n - i] != F::ZERO)
        .map(|i| {
            let l = c[n - i].abs().to_f64().log2() - lead - (i == n) as u8 as f64;
            l / i as f64
        })
        .fold(f64::NEG_INFINITY, f64::max);
    // 2·max, one more doubling against log₂'s rounding
    let e = if m.is_finite() { m.ceil() + 2.0 } else { 1.0 };
    if e > 1100.0 {
        return F::INFINITY;
    }
    let b = F::from_f64(ldexp(1.0, e as i32));
    if b.is_finite() {
        b
    } else {
        F::INFINITY
    }
}

// ---- quadratics (§1.1) ----

/// §1.1 as printed: `D = b² − 4ac`; no root when `D < 0`, `−b/2a` when `D = 0`, else
/// `(−b ± √D)/2a`.
pub fn quadratic_textbook<F: Real>(coef: [F; 3]) -> Vec<F> {
    let [cc, b, a] = coef;
    // Discriminant
    let d = b * b - lit::<F>(4.0) * a * cc;
    if d < F::ZERO {
        return vec![];
    }
    let two_a = lit::<F>(2.0) * a;
    if d == F::ZERO {
        return vec![-b / two_a];
    }
    // The two roots
    let s = d.sqrt();
    sort(vec![(-b - s) / two_a, (-b + s) / two_a])
}

/// Kahan / pbrt: discriminant by [`difference_of_products`], `q = −½(b + copysign(√D, b))`,
/// roots `q/a`, `c/q`; the linear root when `a = 0`; nothing for NaN/inf coefficients or the
/// zero polynomial.
pub fn quadratic_robust<F: Real>(coef: [F; 3]) -> Vec<F> {
    if coef.iter().any(|x| !x.is_finite()) {
        return vec![];
    }
    // Scale by a power of two so nothing overflows
    let n = normalised(&coef);
    let (cc, b, a) = (n[0], n[1], n[2]);
    if a == F::ZERO {
        return if b == F::ZERO { vec![] } else { vec![-cc / b] };
    }
    // Discriminant with the product's rounding error recovered
    let d = difference_of_products(b, b, lit::<F>(4.0) * a, cc);
    if d < F::ZERO {
        return vec![];
    }
    if d == F::ZERO {
        return vec![-b / (lit::<F>(2.0) * a)];
    }
    // Roots without cancellation
    let q = lit::<F>(-0.5) * (b + d.sqrt().copysign(b));
    sort(vec![q / a, cc / q])
}

// ---- cubic (§1.2) and quartic (§1.3) ----

/// §1.2 as printed: `t³ + at² + bt + c` after dividing by the leading coefficient,
/// `t = x − a/3` gives `x³ + px + q`, `D′ = −(p/3)³ − (q/2)²`: one real root `r + s`
/// (Cardano) when `D′ < 0`, `2r` and the double root `−r` when `D′ = 0`, and
/// `2m·cos(θ + 2πk/3)` with `m = √(−p/3)`, `θ = ⅓·acos(−q/(2m³))` when `D′ > 0`.
pub fn cubic_chapter<F: Real>(coef: [F; 4]) -> Vec<F> {
    // Normalise
    let lead = coef[3];
    let (a, b, cc) = (coef[2] / lead, coef[1] / lead, coef[0] / lead);
    // Depress with t = x − a/3
    let three = lit::<F>(3.0);
    let p = b - a * a / three;
    let q = lit::<F>(2.0) * a * a * a / lit::<F>(27.0) - a * b / three + cc;
    // The discriminant D′
    let (p3, q2) = (p / three, q / lit::<F>(2.0));
    let dd = -(p3 * p3 * p3) - q2 * q2;
    let xs = if dd < F::ZERO {
        // One real root (Cardano)
        let s = (-dd).sqrt();
        vec![cbrt(-q2 + s) + cbrt(-q2 - s)]
    } else if dd == F::ZERO {
        // A simple and a double root
        let r = cbrt(-q2);
        vec![lit::<F>(2.0) * r, -r]
    } else {
        // Three real roots (trigonometric form)
        let m = (-p3).sqrt();
        let theta = acos(-q2 / (m * m * m)) / three;
        let k = lit::<F>(2.0 * std::f64::consts::PI / 3.0);
        let two_m = lit::<F>(2.0) * m;
        vec![
            two_m * cos(theta),
            two_m * cos(theta + k),
            two_m * cos(theta - k),
        ]
    };
    let shift = a / three;
    sort(xs.into_iter().map(|x| x - shift).collect())
}

/// §1.3 as printed: `t⁴ + at³ + bt² + ct + d` after dividing by the leading coefficient,
/// `t = x − a/4` gives `x⁴ + px² + qx + r`; `y` the largest real root of the resolvent
/// `y³ − (p/2)y² − ry + (rp/2 − q²/8)` ([`cubic_chapter`]); with `e = √(2y − p)`,
/// `f = √(y² − r)` the roots are those of `x² + ex + y ∓ f` and `x² − ex + y ± f` (upper signs
/// when `q ≥ 0`), by [`quadratic_textbook`].
pub fn quartic_ferrari<F: Real>(coef: [F; 5]) -> Vec<F> {
    // Normalise
    let lead = coef[4];
    let (a, b, cc, d) = (
        coef[3] / lead,
        coef[2] / lead,
        coef[1] / lead,
        coef[0] / lead,
    );
    // Depress with t = x − a/4
    let a2 = a * a;
    let p = b - lit::<F>(3.0) * a2 / lit::<F>(8.0);
    let q = cc - a * b / lit::<F>(2.0) + a2 * a / lit::<F>(8.0);
    let r = d - a * cc / lit::<F>(4.0) + a2 * b / lit::<F>(16.0)
        - lit::<F>(3.0) * a2 * a2 / lit::<F>(256.0);
    // A real root of the resolvent cubic
    let half = lit::<F>(0.5);
    let resolvent = [r * p * half - q * q / lit::<F>(8.0), -r, -p * half, F::ONE];
    let Some(&y) = cubic_chapter(resolvent).last() else {
        return vec![];
    };
    // Two quadratics, split by the sign of q
    let e = (lit::<F>(2.0) * y - p).sqrt();
    let f = (y * y - r).sqrt();
    let f1 = if q >= F::ZERO { -f } else { f };
    let mut xs = quadratic_textbook([y + f1, e, F::ONE]);
    xs.extend(quadratic_textbook([y - f1, -e, F::ONE]));
    let shift = a / lit::<F>(4.0);
    sort(xs.into_iter().map(|x| x - shift).collect())
}

// ---- Yuksel's method ----

/// A hard cap on the bracket solver's iterations (safeguarded Newton needs a handful; ordinal
/// bisection alone closes any bracket of floats in 64).
const MAX_ITERS: usize = 400;

/// The root in `(lo, hi)`, where `p(lo)` is negative iff `lo_neg` and `p(hi)` has the other
/// sign: Newton from `x`, safeguarded as in Numerical Recipes' `rtsafe` (a step that leaves
/// the bracket or does not halve the step before last is replaced by bisection on the floats),
/// and bisection on the floats also whenever the bracket's width in ulps has not halved in two
/// iterations: Newton can converge linearly (factor 2/3 where a cubic term dominates), which
/// from 1e57 down to 1e-17 outlasts any step cap. Once a Newton step is within two ulps, the
/// float next to it on the root's side is tested too, so the bracket closes to two adjacent
/// floats.
fn solve_bracket<F: Real>(c: &[F], dc: &[F], mut lo: F, mut hi: F, lo_neg: bool, mut x: F) -> F {
    let width = |lo: F, hi: F| hi.ordinal() as i128 - lo.ordinal() as i128;
    let (mut dx_old, mut dx_older) = (F::INFINITY, F::INFINITY);
    let (mut w_old, mut w_older) = (i128::MAX, i128::MAX);
    for _ in 0..MAX_ITERS {
        let w = width(lo, hi);
        if w <= 1 {
            break;
        }
        // Newton step, or bisection when it leaves the bracket or converges too slowly
        let step = horner(c, x) / horner(dc, x);
        let ulp = |v: F| v.abs().next_up() - v.abs();
        let mut y = x - step;
        let halving = w <= w_older / 2;
        (w_older, w_old) = (w_old, w);
        let mut newton = y > lo && y < hi && step.abs() * lit::<F>(2.0) <= dx_older && halving;
        if !newton && (x == lo || x == hi) && step.abs() <= lit::<F>(2.0) * ulp(x) {
            // Newton has converged at an end: the root is next to it
            y = if x == lo {
                lo.next_up()
            } else {
                hi.next_down()
            };
            newton = true;
        } else if !newton {
            y = ordinal_mid(lo, hi);
        }
        dx_older = dx_old;
        dx_old = if newton {
            step.abs()
        } else {
            hi * lit::<F>(0.5) - lo * lit::<F>(0.5)
        };
        // Move an end to y by the sign there
        match negative_at(c, y) {
            None => return y,
            Some(n) if n == lo_neg => lo = y,
            Some(_) => hi = y,
        }
        // A converged Newton step: test the neighbour on the root's side
        let near = (y - x).abs() <= lit::<F>(2.0) * ulp(y);
        let z = if lo == y { y.next_up() } else { y.next_down() };
        if newton && near && z > lo && z < hi {
            match negative_at(c, z) {
                None => return z,
                Some(n) if n == lo_neg => lo = z,
                Some(_) => hi = z,
            }
        }
        x = y;
    }
    // The adjacent float with the smaller residual
    if log_residual(c, hi) < log_residual(c, lo) {
        hi
    } else {
        lo
    }
}

/// The real roots of a normalised polynomial with a non-zero leading coefficient.
fn roots_of<F: Real>(c: &[F]) -> Vec<F> {
    match c.len() {
        0 | 1 => vec![],
        2 => vec![-c[0] / c[1]],
        3 => quadratic_robust([c[0], c[1], c[2]]),
        _ => monotonic_roots(c),
    }
}

/// Yuksel's split: the derivative's roots cut `[−B, B]` into monotonic pieces.
fn monotonic_roots<F: Real>(c: &[F]) -> Vec<F> {
    let n = c.len() - 1;
    let dc = derivative(c);
    // The ends: ±B and the critical points between them
    let bound = root_bound(c);
    let (outer, known) = if bound.is_finite() {
        (bound, true)
    } else {
        (largest::<F>(), false)
    };
    let mut ends = vec![-outer];
    for x in roots_of(&normalised(&dc)) {
        if x > ends[ends.len() - 1] && x < outer {
            ends.push(x);
        }
    }
    ends.push(outer);
    // Signs at the ends (at ±B from the leading term)
    let lead_neg = c[n] < F::ZERO;
    let last = ends.len() - 1;
    let signs: Vec<Option<bool>> = ends
        .iter()
        .enumerate()
        .map(|(i, &x)| match (known, i) {
            (true, 0) => Some(lead_neg != (n % 2 == 1)),
            (true, i) if i == last => Some(lead_neg),
            _ => negative_at(c, x),
        })
        .collect();
    // A root at a critical point, or one per sign change
    let mut out = vec![];
    for i in 0..last {
        if signs[i].is_none() && (i > 0 || !known) {
            out.push(ends[i]);
        }
        if let (Some(a), Some(b)) = (signs[i], signs[i + 1]) {
            if a != b {
                let mid = ends[i] * lit::<F>(0.5) + ends[i + 1] * lit::<F>(0.5);
                out.push(solve_bracket(c, &dc, ends[i], ends[i + 1], a, mid));
            }
        }
    }
    if signs[last].is_none() {
        out.push(ends[last]);
    }
    out
}

/// The largest finite value of the precision.
fn largest<F: Real>() -> F {
    F::INFINITY.next_down()
}

/// Yuksel's method for any degree (numerics.md §7): the real roots, ascending; nothing for
/// NaN/inf coefficients, constants and the zero polynomial.
pub fn poly_roots_robust<F: Real>(coef: &[F]) -> Vec<F> {
    if coef.iter().any(|x| !x.is_finite()) {
        return vec![];
    }
    roots_of(&normalised(trimmed(coef)))
}

// ---- Newton's method (§1.4) ----

/// The fixed step cap of [`newton_plain`].
pub const NEWTON_STEPS: usize = 32;

/// §1.4 as printed: `xᵢ₊₁ = xᵢ − f(xᵢ)/f′(xᵢ)` from `x0`, at most [`NEWTON_STEPS`] steps
/// (fewer once a step changes nothing); `None` when `f′(xᵢ) = 0` (a horizontal tangent). No
/// other check: a diverging iteration returns what it reached.
pub fn newton_plain<F: Real>(coef: &[F], x0: F) -> Option<F> {
    let dc = derivative(coef);
    let mut x = x0;
    for _ in 0..NEWTON_STEPS {
        let d = horner(&dc, x);
        if d == F::ZERO {
            return None;
        }
        let next = x - horner(coef, x) / d;
        if next == x {
            break;
        }
        x = next;
    }
    Some(x)
}

/// Safeguarded Newton in the bracket `[lo, hi]` from `x0`: `None` for NaN/inf inputs,
/// `lo ≥ hi`, `x0` outside the bracket, or no sign change at the ends; otherwise the bracket
/// solver of [`poly_roots_robust`] (signs by compensated, rescaled evaluation).
pub fn newton_bracketed<F: Real>(coef: &[F], lo: F, hi: F, x0: F) -> Option<F> {
    let finite = coef.iter().chain(&[lo, hi, x0]).all(|x| x.is_finite());
    let ordered = lo < hi && x0 >= lo && x0 <= hi;
    if !(finite && ordered) {
        return None;
    }
    let c = normalised(trimmed(coef));
    if c.is_empty() {
        return None;
    }
    // Signs at the ends
    let (sl, sh) = (negative_at(&c, lo), negative_at(&c, hi));
    match (sl, sh) {
        (None, _) => Some(lo),
        (_, None) => Some(hi),
        (Some(a), Some(b)) if a == b => None,
        (Some(a), Some(_)) => Some(solve_bracket(&c, &derivative(&c), lo, hi, a, x0)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_forms_on_exact_cases() {
        // (x − 1)(x − 2)
        assert_eq!(quadratic_textbook([2.0f64, -3.0, 1.0]), vec![1.0, 2.0]);
        assert_eq!(quadratic_robust([2.0f32, -3.0, 1.0]), vec![1.0, 2.0]);
        assert_eq!(quadratic_robust([2.0f64, -4.0, 0.0]), vec![0.5]);
        assert!(quadratic_robust([1.0f64, 0.0, 1.0]).is_empty());
        assert!(quadratic_robust([f64::NAN, 0.0, 1.0]).is_empty());
        // (x − 1)(x − 2)(x − 3) and (x − 1)(x − 2)(x − 3)(x − 4)
        let r = cubic_chapter([-6.0f64, 11.0, -6.0, 1.0]);
        assert!(
            r.iter()
                .zip([1.0, 2.0, 3.0])
                .all(|(a, b)| (a - b).abs() < 1e-12),
            "{r:?}"
        );
        let r = quartic_ferrari([24.0f64, -50.0, 35.0, -10.0, 1.0]);
        assert!(
            r.iter()
                .zip([1.0, 2.0, 3.0, 4.0])
                .all(|(a, b)| (a - b).abs() < 1e-9),
            "{r:?}"
        );
        assert_eq!(
            poly_roots_robust(&[24.0f64, -50.0, 35.0, -10.0, 1.0]),
            vec![1.0, 2.0, 3.0, 4.0]
        );
        assert_eq!(
            poly_roots_robust(&[-6.0f32, 11.0, -6.0, 1.0]),
            vec![1.0, 2.0, 3.0]
        );
        // The quadratic closed form is within one ulp
        let r = poly_roots_robust(&[-2.0f64, 0.0, 1.0]);
        assert!(r[0].ulps_between(-2f64.sqrt()) <= 1 && r[1].ulps_between(2f64.sqrt()) <= 1);
        assert!(poly_roots_robust(&[0.0f64, 0.0, 0.0]).is_empty());
    }

    #[test]
    fn newton_variants() {
        // x³ − 2x + 2 cycles 0 → 1 → 0 under plain Newton
        let c = [2.0f64, -2.0, 0.0, 1.0];
        let plain = newton_plain(&c, 0.0).unwrap();
        assert!((plain - (-1.769_292_354_238_631)).abs() > 0.5);
        let root = newton_bracketed(&c, -2.0, 0.0, 0.0).unwrap();
        assert!((root - (-1.769_292_354_238_631_4)).abs() < 1e-15);
        assert_eq!(newton_bracketed(&c, 0.0, 1.0, 0.5), None);
    }
}
