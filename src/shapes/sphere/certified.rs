//! **Certified**: the exact verdict and the correctly rounded `t`, built the way correctly
//! rounded math libraries are (CRlibm, CORE-MATH): a quick phase with a rigorous error bound,
//! and an accurate phase only when the bound cannot decide. Measured cost against `algebraic`
//! (README, `scripts/readme-figures` section 7): 1.9× in `f32`, 7× (fan30's tests) to 23× (the
//! hard-case mix) in `f64`.
//!
//! Three tiers, each rigorous, each handing on only what it cannot decide:
//! 1. **First look** (`f32` inputs): [`first_look`], the textbook discriminant in `f64` with
//!    bounds from two magnitudes, checked against the distance to the nearest `f32` rounding
//!    boundary without a division. It answers nearly every case a renderer asks.
//! 2. **Quick phase** ([`quick_phase`]): the bounds below, quantity by quantity, and for `f64`
//!    inputs Newton steps with a double-double residual.
//! 3. **Accurate phase**: the exact oracle's path.
//!
//! `tests/certified.rs` prints the share of each case class that each tier answers.
//!
//! # Quick phase
//!
//! In `f64`, with `f = o − c`, `A = d·d`, `B = d·f`, `C = f·f − r²` and the discriminant in
//! Lagrange's form `Δ = B² − A·C = A·r² − |d × f|²`. That form cancels only near tangency, not
//! for a far-away sphere, where `B² − AC` loses `2·log₂(|f|/r)` bits. Each quantity carries a
//! rigorous bound on its error (below), so its sign is certain when `|x̂| > e_x`:
//! - `C > 0` certain (origin outside): a miss if `Δ < 0` or `B > 0` is certain, the near root
//!   `t = C / (|B| + √Δ)` if `B < 0` and `Δ > 0` are certain;
//! - `C < 0` certain (inside): the far root, `(|B| + √Δ)/A` when `B ≤ 0`, `|C| / (B + √Δ)` else;
//! - any other case (a sign within its bound: origin on the surface, tangent, `B = 0`) goes
//!   to the accurate phase.
//!
//! The enclosure `[t̂ − E, t̂ + E]` of the exact root then decides the rounding: if both ends
//! round to the same float of the input's precision, that float is the correctly rounded `t`.
//! For `f32` inputs the `f64` quick phase has 29 bits to spare, so this almost always holds.
//! For `f64` inputs one to three Newton steps on the quadratic (more only for grazing rays,
//! which start far off), each with its residual computed with
//! error-free transformations (Dekker's products, Knuth's sums: an exact `f = fh + fl`, the
//! point `f + t̂·d` and `|f + t̂·d|² − r²` in double-double), shrinks `E` by the factor
//! `A·E/|P'(t̂)|`: for a Newton step on a quadratic the new error is exactly
//! `A·(t̂ − t)²/P'(t̂)`. When `C` has lost more than 10 bits (an origin near the surface) or a
//! sign of `C` or `B` is unsure, both are recomputed in double-double (`C = P(0)`,
//! `B = P'(0)/2`) before anything is decided.
//!
//! # The error bounds
//!
//! `u = 2⁻⁵³`. Every rounded operation is `fl(x ∘ y) = (x ∘ y)(1 + δ)`, `|δ| ≤ u`, plus, for a
//! product, an absolute error below `2⁻¹⁰⁷⁵` if it underflows ([`ETA`] covers every such term;
//! sums of floats are exact when they underflow). Sums of `n` terms are within `γₙ Σ|terms|`,
//! `γₙ = nu/(1 − nu)`. With `f̂ᵢ = fᵢ(1 + δ)` and `P_k = |dᵢ f̂ⱼ| + |dⱼ f̂ᵢ|`:
//!
//! | quantity | bound used | from |
//! |---|---|---|
//! | `A` | `4u·Â` | three squares, two sums |
//! | `B` | `6u·Σ\|dᵢ f̂ᵢ\|` | `γ₃` for the dot, `u` for `f̂`, `γ₃` for the sum of magnitudes |
//! | `C` | `7u·(F̂ + r²)` | `γ₃` and `2u` (from `f̂`) on `F = f·f`, `u` on `r²`, `u` on the difference |
//! | `x_k` of `d × f` | `4u·P_k` | two products, the difference, `f̂` |
//! | `Δ` | `8u·Â r² + 5u·X̂ + 9u·Σ P_k\|x̂_k\| + 33u²·Â F̂` | `X = Σ x_k²`: `e_x(2\|x̂\| + e_x)` per term, `γ₃`; `A r²`; the difference |
//! | `√Δ` | `e_Δ/s·(1 + 2u) + 1.01u·s` | `\|√Δ − √Δ̂\| ≤ e_Δ/√Δ̂`, the rounding of `s` |
//! | `n/d` | `(e_n + \|t̂\|·1.01·e_d)/(d̂ − e_d) + 1.01u·\|t̂\|` | exact for `d̂ > e_d` |
//!
//! Every constant is at least the proof's, with room; the bound's own evaluation (about twenty
//! roundings, all of positive terms) is covered by the final factor `1 + 2⁻⁴⁰`. The rounding
//! check compares distances to the rounding boundaries, which are exact or within a stated margin.
//! For `f64` inputs the positions and the direction are first scaled by exact powers of two
//! (as [`super::methods::promote`] does), so no intermediate overflows and an underflowed
//! product is below [`ETA`]; for `f32` inputs in `f64` nothing can over- or underflow (every
//! non-zero product of inputs and differences is at least `2⁻⁵⁹⁶`).
//!
//! # Accurate phase
//!
//! The exact oracle's own path ([`super::oracle::nearest_root`]): the verdict from GMP integer
//! signs and the root from MPFR enclosures at rising precision (Ziv). It is the only code the
//! quick phase can defer to, so on the cases that reach it the audit compares the oracle with
//! itself; the oracle is checked against independent 300-digit truth in `tests/oracle.rs`.
//! [`quick_phase_decides`] says which phase answered a case: the audit's sphere section prints
//! the share of each class that reached the accurate phase.
//!
//! # Conventions
//!
//! Those of the oracle, exactly: a tangent ray hits; an origin exactly on the surface returns the
//! other root if it is ahead; invalid input (a non-finite component, a zero direction, a radius
//! that is not `> 0`) is a miss, as for [`super::methods::promote`]; a root that rounds to zero or
//! overflows in the input's precision is not returned. The quick phase never returns a NaN or an
//! infinite `t`.

// Negated comparisons (`!(x > e)`) on purpose: a NaN must take the unsure or miss branch
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::methods::{ilogb, mul_pow2, Ray, Sphere, SphereHit};
use super::oracle::{nearest_root, Case};
use crate::numerics::dd::{two_prod_split, two_sum};
use crate::numerics::real::Real;

/// `u = 2⁻⁵³`, the unit roundoff of `f64`.
const U: f64 = 1.0 / 9_007_199_254_740_992.0;
/// `2⁻¹⁰⁰⁰`: above the sum of every absolute underflow error the quick phase can make.
pub const ETA: f64 = f64::from_bits(23 << 52);
/// The bound's own rounding: about twenty roundings of positive terms, `(1 + u)²⁰ < 1 + 2⁻⁴⁰`.
const SAFETY: f64 = 1.0 + 1.0 / 1_099_511_627_776.0;

/// What the quick phase decided.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Quick {
    /// Certainly no root with `t > 0` (or invalid input that the phase can see: a radius that is
    /// not `> 0`, a zero direction).
    Miss,
    /// The nearest root with `t > 0` lies in `[th + tl − err, th + tl + err]` (an `f64` pair:
    /// `tl` is zero for `f32` inputs and the Newton step's low part for `f64` inputs).
    Hit {
        /// The enclosure's centre, high part.
        th: f64,
        /// The enclosure's centre, low part.
        tl: f64,
        /// The enclosure's half-width: a rigorous bound on the distance to the exact root.
        err: f64,
    },
    /// A sign is within its bound: only the accurate phase can tell.
    Unsure,
}

/// **Certified**: the exact verdict and the correctly rounded nearest `t > 0`, from a quick
/// `f64` phase with a rigorous error bound, or from the exact oracle's path when the bound
/// cannot decide (see the [module docs](self)).
pub fn certified<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let case = case_of(ray, s);
    // f32 inputs: the first look answers nearly every case a renderer asks
    if F::MANT_BITS == 24 {
        match first_look(&case, 1.0) {
            FirstLook::Miss => return None,
            FirstLook::Hit(t) => return Some(SphereHit { t, enclosure: None }),
            FirstLook::Unsure => {}
        }
    }
    match quick_phase(&case) {
        Quick::Miss => None,
        Quick::Hit { th, tl, err } => match round_certain::<F>(th, tl, err) {
            Some(t) => Some(SphereHit { t, enclosure: None }),
            None => accurate(&case),
        },
        Quick::Unsure => accurate(&case),
    }
}

/// What the first look (`f32` inputs) decided.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FirstLook<F> {
    /// Certainly no root with `t > 0`.
    Miss,
    /// The correctly rounded nearest root.
    Hit(F),
    /// The quick phase's full bounds must look.
    Unsure,
}

/// The first look, for `f32` inputs: the quadratic in `f64` with the textbook discriminant
/// `B² − A·C` and bounds from two magnitudes only, `Q = A·(F + r²)` and `Σ|dᵢ fᵢ|`, checked
/// without a division. `scale` multiplies every bound: 1 in use; the tests pass less to show
/// that a bound too small is caught.
///
/// With `eB = 4.01u·Σ|dᵢ f̂ᵢ|` (the dot's `γ₃`, `f̂`'s `u`), `eC = 7u·(F + r²)` and
/// `eΔ = 24u·Q` (`|B̂² − B²| ≤ eB(2|B̂| + eB) ≤ 8.03u·A·F` by Cauchy–Schwarz, `|Â Ĉ − A C| ≤
/// 2u·A|C| + A·eC`, three roundings, `|C| ≤ F + r²`), the root `t = n/m` (`m = |B| + √Δ`) has
/// relative error at most `(eC/|C| + (eB + e√Δ)/m)(1 + 2⁻¹⁹) + 1.01u` for the near root (and
/// `((eB + e√Δ)/m + eA/A)(1 + 2⁻¹⁹) + 1.01u` for `m/A`). Multiplied out by `|C|·√Δ·m`, the
/// condition that this is below the distance to the nearest `f32` rounding boundary (read off
/// `t`'s bits, in units of `u·2^E ≤ u·t`) needs no division.
#[inline(always)]
pub fn first_look<F: Real>(case: &Case<F>, scale: f64) -> FirstLook<F> {
    let w = |v: [F; 3]| v.map(|x| x.to_f64());
    let (o, d, c, r) = (w(case.o), w(case.d), w(case.c), case.r.to_f64());
    if !(r > 0.0) {
        return FirstLook::Miss;
    }
    // The quadratic (non-finite input makes every test below false: the quick phase decides)
    let f = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let b = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
    let sb = (d[0] * f[0]).abs() + (d[1] * f[1]).abs() + (d[2] * f[2]).abs();
    let ff = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
    let (fr, r2) = (ff + r * r, r * r);
    let cc = ff - r2;
    let disc = b * b - a * cc;
    // The bounds, in units of u
    let (eb, ec, ed) = (4.01 * sb * scale, 7.0 * fr * scale, 24.0 * a * fr * scale);
    // Verdict, in units of u on the right-hand side
    let outside = cc > ec * U;
    if outside && (b > eb * U || disc < -ed * U) {
        return FirstLook::Miss;
    }
    if !(disc > ed * U) || !(outside && b < -eb * U || cc < -ec * U) {
        return FirstLook::Unsure;
    }
    // The root: n / m, m = |B| + √Δ, or m / A inside with B ≤ 0
    let s = disc.sqrt();
    let m = b.abs() + s;
    let (t, lhs, rhs_factor);
    if outside || b > 0.0 {
        // |C| / m: (eC·s·m + (eB·s + eΔ(1+2u))·|C| + 2.03·|C|·s·m)(1 + 2⁻¹⁸) + 1.01·|C|·s·m
        let n = cc.abs();
        t = n / m;
        lhs = (ec * s * m + (eb * s + ed * 1.000_001) * n) * 1.0001 + 3.1 * n * s * m;
        rhs_factor = n * s * m;
    } else {
        // m / A: ((eB·s + eΔ(1+2u)) + (2.02 + 2.0002)·s·m)(1 + 2⁻¹⁸) + 1.01·s·m
        t = m / a;
        lhs = (eb * s + ed * 1.000_001) * 1.0001 + 5.1 * s * m;
        rhs_factor = s * m;
    }
    // Distance from t to the nearest f32 rounding boundary, in units of 2^(E−52) ≥ u·t/2
    let Some((dist, _)) = f32_boundary_distance(t) else {
        return FirstLook::Unsure;
    };
    // |t − t*| ≤ rel·t < rel·2^(E+1) = 2·(rel/u)·unit: certain when 2·(rel/u) < dist
    let tf = F::from_f64(t);
    if 2.0 * lhs < dist * rhs_factor && tf.is_finite() {
        FirstLook::Hit(tf)
    } else {
        FirstLook::Unsure
    }
}

/// Whether the quick phase alone answers this case (`false`: the accurate phase runs).
pub fn quick_phase_decides<F: Real>(case: &Case<F>) -> bool {
    match quick_phase(case) {
        Quick::Miss => true,
        Quick::Hit { th, tl, err } => round_certain::<F>(th, tl, err).is_some(),
        Quick::Unsure => false,
    }
}

#[inline(always)]
fn case_of<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Case<F> {
    Case {
        o: F::unvec3(ray.origin),
        d: F::unvec3(ray.dir),
        c: F::unvec3(s.center),
        r: s.radius,
    }
}

/// The accurate phase: the oracle's exact verdict and correctly rounded root.
#[cold]
fn accurate<F: Real>(case: &Case<F>) -> Option<SphereHit<F>> {
    nearest_root(case).map(|t| SphereHit { t, enclosure: None })
}

/// The quick phase in `f64` (see the module docs for every bound), before the rounding check.
#[inline(always)]
pub fn quick_phase<F: Real>(case: &Case<F>) -> Quick {
    let w = |v: [F; 3]| v.map(|x| x.to_f64());
    let (mut o, mut d, mut c, mut r) = (w(case.o), w(case.d), w(case.c), case.r.to_f64());
    // Input guards: invalid input (a radius not > 0, a non-finite component) is a miss
    if !(r > 0.0) {
        return Quick::Miss;
    }
    let sum = o[0] + o[1] + o[2] + d[0] + d[1] + d[2] + c[0] + c[1] + c[2] + r;
    if !sum.is_finite() {
        return Quick::Miss;
    }
    // f64 inputs: exact power-of-two scales, positions and direction apart (t scales by 2^(kd−kp))
    let mut back = 0;
    if F::MANT_BITS == 53 {
        let mx = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let kp = -ilogb(mx(&[o[0], o[1], o[2], c[0], c[1], c[2], r]));
        let kd = -ilogb(mx(&d));
        o = o.map(|x| mul_pow2(x, kp));
        c = c.map(|x| mul_pow2(x, kp));
        r = mul_pow2(r, kp);
        d = d.map(|x| mul_pow2(x, kd));
        back = kd - kp;
    }
    // The quadratic's coefficients, and the magnitudes their bounds need
    let f = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let (ad, af) = (d.map(f64::abs), f.map(f64::abs));
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if !(a > 0.0) {
        return Quick::Miss; // a zero direction is invalid input
    }
    let mut b = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
    let sb = ad[0] * af[0] + ad[1] * af[1] + ad[2] * af[2];
    let ff = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
    let r2 = r * r;
    let mut cc = ff - r2;
    let (ea, mut eb, mut ec) = (
        4.0 * U * a + ETA,
        6.0 * U * sb + ETA,
        7.0 * U * (ff + r2) + ETA,
    );
    // Second tier, rare: C = P(0) and B = P'(0)/2 in double-double when a sign is unsure or C
    // has lost more than 10 of its 53 bits (an origin near the surface, a ray nearly perpendicular to o − c)
    if !(cc.abs() * (1.0 / 1_099_511_627_776.0) > ec && b.abs() > eb) {
        let z = residual_at_zero(o, d, c, r);
        if z.ep < ec {
            (cc, ec) = (z.p, z.ep);
        }
        if 0.5 * z.edp < eb {
            (b, eb) = (0.5 * z.dp, 0.5 * z.edp);
        }
    }
    // Lagrange's discriminant A r² − |d × f|², with the magnitudes P_k of the cross product
    let x = [
        d[1] * f[2] - d[2] * f[1],
        d[2] * f[0] - d[0] * f[2],
        d[0] * f[1] - d[1] * f[0],
    ];
    let p = [
        ad[1] * af[2] + ad[2] * af[1],
        ad[2] * af[0] + ad[0] * af[2],
        ad[0] * af[1] + ad[1] * af[0],
    ];
    let xx = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    let px = p[0] * x[0].abs() + p[1] * x[1].abs() + p[2] * x[2].abs();
    let ar2 = a * r2;
    let disc = ar2 - xx;
    let ed = 8.0 * U * ar2 + 5.0 * U * xx + 9.0 * U * px + 33.0 * U * U * a * ff + ETA;
    // Signs: the verdict (outside: behind, or a certain miss by the discriminant; inside: the
    // far root, Δ > −AC > 0, but its computed value must show it)
    let outside = cc > ec;
    if outside && (disc < -ed || b > eb) {
        return Quick::Miss;
    }
    if !(disc > ed) || !(outside && b < -eb || cc < -ec) {
        return Quick::Unsure;
    }
    // The root as num/den with their bounds: m = |B| + √Δ; the near root C/m, the far root
    // m/A when B ≤ 0, else |C|/m
    let s = disc.sqrt();
    let es = ed / s * (1.0 + 2.0 * U) + 1.01 * U * s;
    let m = b.abs() + s;
    let em = eb + es + 1.01 * U * m;
    let (num, en, den, eden) = if outside || b > 0.0 {
        (cc.abs(), ec, m, em)
    } else {
        (m, em, a, ea)
    };
    // The root and its enclosure
    if !(den > eden) {
        return Quick::Unsure;
    }
    let t = num / den;
    let err = ((en + t * 1.01 * eden) / (den - eden) + 1.01 * U * t) * SAFETY;
    if !(t.is_finite() && err.is_finite()) {
        return Quick::Unsure;
    }
    // f64 inputs: Newton steps with a double-double residual, until the bound is far below an
    // ulp (one step almost always; grazing rays start far off and take two or three)
    let (mut th, mut tl, mut err): (f64, f64, f64) = (t, 0.0, err);
    if F::MANT_BITS == 53 {
        for _ in 0..3 {
            match newton(o, d, c, r, a, th, err + tl.abs() * (1.0 + 2.0 * U)) {
                Some(x) => (th, tl, err) = x,
                None => return Quick::Unsure,
            }
            if err < (th.next_up() - th) * (1.0 / 1024.0) {
                break;
            }
        }
    }
    // Back to the inputs' scale (exact unless it over- or underflows, which the rounding catches)
    if back != 0 {
        let k = |x: f64| mul_pow2(x, back);
        let (th, tl, err) = (k(th), k(tl), k(err) + ETA);
        if !(th.is_finite() && err.is_finite()) {
            return Quick::Unsure; // beyond f64's range: the accurate phase says what is returned
        }
        return Quick::Hit { th, tl, err };
    }
    Quick::Hit { th, tl, err }
}

/// `P(t) = |f + t·d|² − r²` and `P'(t) = 2 d·(f + t·d)` from the inputs (`f = o − c` exactly),
/// in double-double, each with a rigorous bound on its error.
#[derive(Clone, Copy, Debug)]
struct Residual {
    p: f64,
    ep: f64,
    dp: f64,
    edp: f64,
}

#[inline(always)]
fn residual(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64, t: f64) -> Residual {
    // g = f + t·d = gh + gl*, exactly; gl is gl* after two roundings, within 2.01u·Σ|parts|
    let mut gh = [0.0; 3];
    let mut gl = [0.0; 3];
    let mut egl = [0.0; 3];
    for i in 0..3 {
        let (fh, fl) = two_sum(o[i], -c[i]);
        let (p, pe) = two_prod_split(t, d[i]);
        let (s, se) = two_sum(fh, p);
        gh[i] = s;
        gl[i] = se + pe + fl;
        egl[i] = 2.01 * U * (se.abs() + pe.abs() + fl.abs());
    }
    // Σ gh² − r² as eight exact terms, summed by Knuth's cascade into hi + lo
    let mut terms = [0.0f64; 8];
    for i in 0..3 {
        let (q, qe) = two_prod_split(gh[i], gh[i]);
        terms[2 * i] = q;
        terms[2 * i + 1] = qe;
    }
    let (rr, rre) = two_prod_split(r, r);
    terms[6] = -rr;
    terms[7] = -rre;
    let (mut hi, mut lo, mut mag) = (0.0, 0.0, 0.0);
    for &x in &terms {
        let (s, e) = two_sum(hi, x);
        hi = s;
        lo += e;
        mag += x.abs();
    }
    // The small parts: 2 Σ gh·gl and Σ gl²
    let cross = 2.0 * (gh[0] * gl[0] + gh[1] * gl[1] + gh[2] * gl[2]);
    let cm = 2.0 * ((gh[0] * gl[0]).abs() + (gh[1] * gl[1]).abs() + (gh[2] * gl[2]).abs());
    let sq = gl[0] * gl[0] + gl[1] * gl[1] + gl[2] * gl[2];
    let p = hi + (lo + cross + sq);
    // P's error: the cascade's low sum (eight errors, each ≤ u·mag, summed with γ₇), the small
    // parts' rounding, gl against gl*, and the last three additions
    let mut egl_terms = 0.0;
    for i in 0..3 {
        egl_terms += egl[i] * (2.0 * gh[i].abs() * 1.01 + 2.0 * gl[i].abs() + egl[i]);
    }
    let ep = 64.0 * U * U * mag
        + 4.0 * U * (lo.abs() + cm + cross.abs() + sq)
        + 2.0 * U * p.abs()
        + egl_terms
        + ETA;
    // P' = 2 Σ dᵢ gᵢ and its error (the dot's rounding, the low parts left out)
    let dp = 2.0 * (gh[0] * d[0] + gh[1] * d[1] + gh[2] * d[2]);
    let mut edp = 0.0;
    for i in 0..3 {
        edp += 3.01 * U * (gh[i] * d[i]).abs() + d[i].abs() * (gl[i].abs() + egl[i]);
    }
    let edp = 2.0 * edp + 2.0 * U * dp.abs() + ETA;
    Residual { p, ep, dp, edp }
}

/// [`residual`] at `t = 0` (`C` and `2B` in double-double), kept out of line: it is rare.
#[cold]
#[inline(never)]
fn residual_at_zero(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Residual {
    residual(o, d, c, r, 0.0)
}

/// One Newton step for `P(t) = |f + t·d|² − r²` from `t` (within `err` of the root), the
/// residual in double-double ([`residual`]). Returns the new root as `th + tl` and its bound.
///
/// For a quadratic the exact step from `t` lands at `t₁` with `t₁ − t* = A (t − t*)² / P'(t)`
/// (pure algebra, for any `t` with `P'(t) ≠ 0`). The computed step differs from the exact one
/// by `(e_P + |step|·e_P')/(|P̂'| − e_P')` and its own rounding; `th + tl` is `t + step` exactly.
#[inline(always)]
fn newton(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    a: f64,
    t: f64,
    err: f64,
) -> Option<(f64, f64, f64)> {
    let z = residual(o, d, c, r, t);
    let slope = z.dp.abs() - z.edp;
    if !(slope > 0.0) {
        return None;
    }
    // The step, and the new bound: |t₁ − t*| ≤ A·e²/slope + rest for any bound e on |t − t*|.
    // First e = err; then, since |t − t*| ≤ |step| + |t₁ − t*|, twice e = |step| + the last bound
    // (each pass is valid on its own, so the smallest is kept)
    let step = -z.p / z.dp;
    let ka = a * (1.0 + 5.0 * U) / slope;
    let rest = (z.ep + step.abs() * 1.01 * z.edp) / slope + 1.01 * U * step.abs();
    let mut e1 = (ka * err * err + rest) * SAFETY + ETA;
    for _ in 0..2 {
        let e = err.min(step.abs() * (1.0 + 2.0 * U) + e1);
        e1 = e1.min((ka * e * e + rest) * SAFETY + ETA);
    }
    let (th, tl) = two_sum(t, step);
    (e1.is_finite() && th.is_finite()).then_some((th, tl, e1))
}

/// The distance from `t` to the nearest `f32` rounding boundary, exactly, as `(units, unit)`
/// with `unit = 2^(E−52)` for `t` in `[2^E, 2^(E+1))`; `None` unless `t > 0` is in the normal
/// `f32` range. In that binade the `f32` grid is every 2²⁹ units, the boundaries are the cells'
/// midpoints, and in the binade's first cell the boundary below `2^E` is 2²⁷ units under it.
#[inline(always)]
fn f32_boundary_distance(t: f64) -> Option<(f64, f64)> {
    let bits = t.to_bits();
    let e = (bits >> 52) as i64; // t > 0: the biased exponent; otherwise out of range
    if !(897..=1150).contains(&e) {
        return None;
    }
    let low = (bits & ((1 << 29) - 1)) as i64;
    let mut dist = (low - (1 << 28)).abs();
    if (bits >> 29) & ((1 << 23) - 1) == 0 {
        dist = dist.min(low + (1 << 27));
    }
    Some((dist as f64, f64::from_bits(((e - 52) as u64) << 52)))
}

/// The float of precision `F` nearest to every point of `[th + tl − err, th + tl + err]`, if
/// there is one (the enclosure does not straddle a rounding boundary), it is `> 0` and it is
/// finite with a finite successor.
#[inline(always)]
fn round_certain<F: Real>(th: f64, tl: f64, err: f64) -> Option<F> {
    // f32 (tl = 0): the distance to the nearest rounding boundary, read off th's bits
    if F::MANT_BITS == 24 {
        let (dist, unit) = f32_boundary_distance(th)?;
        let tf = F::from_f64(th);
        return (dist * unit > err && tf.is_finite()).then_some(tf);
    }
    let tf = F::from_f64(th);
    if !(tf > F::ZERO) {
        return None;
    }
    let (up, down) = (tf.next_up(), tf.next_down());
    if !up.is_finite() {
        return None;
    }
    let v = tf.to_f64();
    // Half-ulps below and above (exact), the offset of th from the float (exact: Sterbenz)
    let half_lo = (v - down.to_f64()) * 0.5;
    let half_hi = (up.to_f64() - v) * 0.5;
    let off = th - v;
    // Distances from the enclosure's centre to the two boundaries, with their rounding margin
    let dl = half_lo + off + tl;
    let dh = half_hi - off - tl;
    let margin = 4.0 * U * (half_lo + half_hi + off.abs() + tl.abs());
    (dl > err + margin && dh > err + margin).then_some(tf)
}
