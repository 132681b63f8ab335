//! **Certified**: the exact verdict and the correctly rounded `t`, built the way correctly
//! rounded math libraries are (CRlibm, CORE-MATH): a quick phase with a rigorous error bound,
//! and an accurate phase only when the bound cannot decide. Measured cost against `algebraic`:
//! `reference/figures.md`, from `scripts/readme-figures` section 7.
//!
//! Five tiers, each rigorous, each handing on only what it cannot decide:
//! 1. **First look**: for `f32` inputs [`first_look`], the textbook quadratic in `f64` and one
//!    division-free test of a two-term error bound against the exact distance to the nearest
//!    `f32` rounding boundary; for `f64` inputs its certain misses only (with an allowance for
//!    underflow). It is one branch-free lane ([`first_look_lane`], [`first_look_lane_f64`]):
//!    the scalar method runs its steps with early exits, the batch kernel
//!    ([`super::batch::Certified`]) runs it on 8 `f64` lanes per instruction, then the second
//!    look on lanes for the tests it leaves open, and the scalar tiers below for the rest; every
//!    certain answer is the unique correctly rounded one, so both give the same bits.
//!
//!    For `f32` inputs the common case is decided first by a cheaper sufficient test
//!    (`certain_fast`: a bound below `2²⁰` units and a root far from every rounding boundary,
//!    read off its bits), as the scalar method runs it.
//!
//!    For `f32` inputs the first look's test runs once more, out of line, with `C` from exact
//!    products (tier 1b, [`exact_c_enclosure`]): rays that start on a surface, a renderer's
//!    reflection and shadow rays, have a `C` far below the look's bound on it.
//! 2. **Second look** (`f64` inputs, [`second_look_claim`]): up to three Newton steps from the
//!    look's root, with the residual from exact products (FMA when the CPU has it) and an
//!    a-posteriori bound from the residual quadratic, so no bound on the look's own error is
//!    needed; the sign of `P'` says which root it found. For an origin so near the surface that
//!    the look cannot tell its side, the residual at 0 tells it first (and a ray leaving the
//!    surface is a certain miss). It answers most `f64` hits. (For `f32` inputs the quick phase
//!    measured as fast on what the first look leaves open, and faster on far small spheres.)
//! 3. **Quick phase** ([`quick_phase`]): the bounds below, quantity by quantity, with `C` and
//!    `B` recomputed to about `2⁻⁷²` when `C` has lost bits (for `f32` inputs by splitting
//!    `o − c` into `f32` halves, `split_at_zero`; for `f64` inputs in double-double), and
//!    for `f64` inputs Newton steps with a double-double residual.
//! 4. **Near the surface** (`f64` inputs, [`near_surface_step`]): up to two Newton steps on
//!    `P(t) = C + t(2B + At)` with `C`, `B` and `A` from two `VecSum` passes over their exact
//!    products, for an origin so near the surface that `|f + t·d|² − r²`, off by `2⁻¹⁰⁶·r²`,
//!    cannot tell the rounding; it starts from the second look's enclosure when there is one,
//!    else from the quick phase's.
//! 5. **Accurate phase**: the exact oracle's path.
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
//! [`accurate_phase_runs`] counts its runs: `tests/certified.rs` prints the share of each
//! class that reaches it.
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

pub mod floors;

use super::oracle::{nearest_root, Case};
use super::ray::{Ray, Sphere, SphereHit};
use crate::numerics::dd::{two_prod, two_prod_split, two_sum};
use crate::numerics::real::Real;
use crate::numerics::real::{ilogb, mul_pow2};

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
    // f64 inputs: the whole path compiled with FMA when the CPU has it (the second look's exact
    // products; the same bits either way). Measured (scratch timing, per class): a hit 47 ->
    // 29 ns against FMA for the second look alone; a certain miss pays the call, 3.5 -> 5.1 ns
    // (the clone returns the bare t, in registers), and deciding the misses before the call
    // made the hits slower again (36 ns)
    #[cfg(target_arch = "x86_64")]
    if F::MANT_BITS == 53 && crate::numerics::cpu::fma() {
        // SAFETY: the CPU has FMA
        let t = unsafe { certified_fma(ray, s) };
        return t.map(|t| SphereHit { t, enclosure: None });
    }
    certified_body::<F, { cfg!(not(target_arch = "x86_64")) }>(ray, s)
        .map(|t| SphereHit { t, enclosure: None })
}

/// [`certified`] as a CPU without FMA runs it: the second look's products by Dekker's split
/// (the tiers out of line still take FMA when the CPU has it). For the tests, which compare it
/// with [`certified`] bit for bit: on a CPU with FMA nothing else runs this path.
pub fn certified_without_fma<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    certified_body::<F, false>(ray, s).map(|t| SphereHit { t, enclosure: None })
}

/// [`certified`] compiled with FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn certified_fma<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<F> {
    certified_body::<F, true>(ray, s)
}

/// [`certified`]'s steps, with exact products by FMA (`FMA`) or Dekker's split.
#[inline(always)]
fn certified_body<F: Real, const FMA: bool>(ray: &Ray<F>, s: &Sphere<F>) -> Option<F> {
    let case = to_f64(&case_of(ray, s));
    let l = look(case.o, case.d, case.c, case.r);
    // f32 inputs: the first look answers nearly every case a renderer asks
    if F::MANT_BITS == 24 {
        if l.behind::<false>() || l.missed::<false>() {
            return None;
        }
        if l.fr * (11.0 / 268_435_456.0) >= l.cc.abs() {
            // The C term alone is 2²⁸ units or more, beyond any test's reach (an origin on a
            // surface): C from exact products at once, before the look's root
            return from_the_surface::<F>(&case, &l);
        }
        let root = l.root();
        if let (t, true) = certain_fast(&l, Terms::PROVED, root) {
            return Some(F::from_f64(t));
        }
        let e = estimate_with(&l, Terms::PROVED, root);
        let (t, ok) = certain(&e);
        if ok {
            Some(F::from_f64(t))
        } else {
            after_look_cold::<F>(&case, &l, &e)
        }
    } else {
        // f64 inputs: the first look's certain misses, then the second look and the rest
        if l.behind::<true>() || l.missed::<true>() {
            return None;
        }
        after_look::<F, FMA>(&case, &l)
    }
}

/// A case's inputs in `f64` (exactly).
#[inline(always)]
fn to_f64<F: Real>(case: &Case<F>) -> Case<f64> {
    let w = |v: [F; 3]| v.map(|x| x.to_f64());
    Case {
        o: w(case.o),
        d: w(case.d),
        c: w(case.c),
        r: case.r.to_f64(),
    }
}

/// For `f32` inputs, out of line (the first look's path stays small, no spills for the tiers
/// after it), after the first look's estimate `e` (`s = √Δ̂`): when its test fails on its `C`
/// term (it would pass without it), tier 1b ([`from_the_surface`]); else [`after_look`].
#[cold]
#[inline(never)]
fn after_look_cold<F: Real>(case: &Case<f64>, l: &Look, e: &Estimate) -> Option<F> {
    let dist = f32_boundary_distance(e.t, e.t as f32);
    if e.lhs_disc * ((2.0 * U) * e.t) < dist * e.scale {
        return from_the_surface::<F>(case, l);
    }
    after_look::<F, false>(case, l)
}

/// Tier 1b for `f32` inputs ([`exact_c_look`]), with its exact products by FMA when the CPU
/// has it (the same bits): for a first look `l` whose `C` has lost its bits, the look's test
/// with `C` from exact products; when that cannot decide, [`after_look`].
#[inline(never)]
fn from_the_surface<F: Real>(case: &Case<f64>, l: &Look) -> Option<F> {
    #[cfg(target_arch = "x86_64")]
    if crate::numerics::cpu::fma() {
        // SAFETY: the CPU has FMA
        return unsafe { from_the_surface_fma(case, l) };
    }
    from_the_surface_body::<F, { cfg!(not(target_arch = "x86_64")) }>(case, l)
}

/// [`from_the_surface`] compiled with FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn from_the_surface_fma<F: Real>(case: &Case<f64>, l: &Look) -> Option<F> {
    from_the_surface_body::<F, true>(case, l)
}

/// [`from_the_surface`]'s steps, with exact products by FMA (`FMA`) or Dekker's split.
#[inline(always)]
fn from_the_surface_body<F: Real, const FMA: bool>(case: &Case<f64>, l: &Look) -> Option<F> {
    // (√Δ̂ is the look's, taken again beside the exact products rather than stored)
    let s = l.disc.sqrt();
    match exact_c_look::<FMA>(case, l, Terms::EXACT_C) {
        ExactC::Miss => return None,
        ExactC::Look(l2) => {
            let root = l2.root_with(s);
            if let (t, true) = certain_fast(&l2, Terms::EXACT_C, root) {
                return Some(F::from_f64(t));
            }
            if let (t, true) = certain(&estimate_with(&l2, Terms::EXACT_C, root)) {
                return Some(F::from_f64(t));
            }
        }
        ExactC::Open => {}
    }
    after_look::<F, false>(case, l)
}

/// What the exact-`C` look found.
#[derive(Clone, Copy, Debug)]
enum ExactC {
    /// Outside and heading away, both certain.
    Miss,
    /// The look with `C` replaced by the nearly exact one; both signs (of `C` and `B`) certain.
    Look(Look),
    /// A sign is not certain.
    Open,
}

/// **Tier 1b** (`f32` inputs, when the first look cannot decide): the first look's test again
/// with `C` from exact products, `C' = P(0)` of [`exact_residual`] (by FMA with `FMA`),
/// within `e = 272u²·fr + 1.01u·|C'|`. It answers what the first look leaves open most often in
/// a renderer: rays that start on a surface (reflections, shadows), where `C` is a tiny fraction
/// of `F + r²` and the look's `C`, off by `6u·(F + r²)`, loses its bits.
///
/// **Why the test still holds**, with [`Terms::EXACT_C`] (`k.c = 300u`, `k.disc = 48`): when
/// the signs of `C'` (`|C'| > e`) and of `B` (`B² > 17u²·Q`, [`Look::behind`]'s test) are both
/// certain, the root's formula is the right one (the look's term for a wrong sign of `B` inside
/// the sphere, `4.01u·(1 + R/|C|)`, is not needed). `Δ̂`, `√Δ̂` and `m = |B̂| + √Δ̂` are the
/// look's, with the look's bounds (`e_Δ` covers the look's `Ĉ`, whatever `C'` is): `m` within
/// `u·(23.3·Q/(√Δ·m) + 2.02)`. The near root (outside) and the far root from inside heading
/// away, `|C'|/m`, are then within `u·(272u·fr/|C'| + 1.01 + 23.3·Q/(√Δ·m) + 2.02 + 1.01)`,
/// the far root `m/A` heading in within `u·(23.3·Q/(√Δ·m) + 5.04)`; with `1 ≤ 2Q/(√Δ·m)` both
/// are below `u·(272u·fr/|C'| + 33.4·Q/(√Δ·m))`, and the constants leave the room the first
/// look's test relies on (second-order terms, the test's own roundings). The test's other
/// consequences hold as in [`first_look`]: it implies `Δ > 73u·Q > e_Δ`, so the hit is certain.
/// Nothing underflows: `A`, `r²` are at least `2⁻²⁹⁸` for `f32` inputs, so when the test passes
/// `fr·√Δ·m ≥ 48·Q·fr·2⁻²⁸ > 2⁻⁹²⁰` and `Q·|C'| ≥ Q·e > 2⁻¹⁰⁰⁰`.
#[inline(always)]
fn exact_c_look<const FMA: bool>(case: &Case<f64>, l: &Look, k: Terms) -> ExactC {
    let (o, d, c, r) = (case.o, case.d, case.c, case.r);
    let z = exact_residual_at_zero::<FMA>(o, d, c, r, l, NewtonTerms::PROVED);
    let heading_away = (l.b > 0.0) & (l.b2 > (17.0 * U * U) * l.q);
    let heading_in = (l.b < 0.0) & (l.b2 > (17.0 * U * U) * l.q);
    // (the ratio a constant: 1 in use, so no division at run time)
    let e = z.ep * (k.c / Terms::EXACT_C.c);
    if !(z.p.abs() > e && (heading_away || heading_in) && l.r > 0.0) {
        return ExactC::Open;
    }
    if z.p > 0.0 && heading_away {
        return ExactC::Miss;
    }
    ExactC::Look(Look { cc: z.p, ..*l })
}

/// After a first look `l` that is not a certain miss (the case's inputs in `f64`): the second
/// look; when its enclosure does not decide the rounding, out of line, the tiers after it.
#[inline(always)]
fn after_look<F: Real, const FMA: bool>(case: &Case<f64>, l: &Look) -> Option<F> {
    // f32 inputs: the quick tiers (the second look measured no faster on the few cases the
    // first look leaves open, and slower on far small spheres, where it needs three steps)
    if F::MANT_BITS == 24 {
        return after_second_look(case, l, None, false);
    }
    let (o, d, c, r) = (case.o, case.d, case.c, case.r);
    // (FMA: what [`certified`]'s dispatch found)
    let Second::Open(found) = second_look_body::<FMA, false>(o, d, c, r, l, NewtonTerms::PROVED)
    else {
        return None;
    };
    if let Some(t) = found.and_then(|(th, tl, err)| round_certain::<F>(th, tl, err)) {
        return Some(t);
    }
    after_second_look(case, l, found, true)
}

/// The tiers after the common second look (`looked`: it ran and found the enclosure `found`,
/// or none): for an origin whose side the look could not tell the second look that finds the
/// side first;
/// for `f64` inputs the near-surface tier from the enclosure; then the quick tiers and the
/// accurate phase.
#[cold]
#[inline(never)]
fn after_second_look<F: Real>(
    case: &Case<f64>,
    l: &Look,
    found: Option<(f64, f64, f64)>,
    looked: bool,
) -> Option<F> {
    let mut found = found;
    if looked && found.is_none() && !l.side_certain() {
        let (o, d, c, r) = (case.o, case.d, case.c, case.r);
        match second_look::<true>(o, d, c, r, l, NewtonTerms::PROVED) {
            Second::Miss => return None,
            Second::Open(f) => found = f,
        }
        if let Some(t) = found.and_then(|(th, tl, err)| round_certain::<F>(th, tl, err)) {
            return Some(t);
        }
    }
    if F::MANT_BITS == 53 {
        if let Some(t) = found.and_then(|(th, tl, err)| near_surface(case, th, tl, err)) {
            return Some(F::from_f64(t));
        }
    }
    let v = |v: [f64; 3]| v.map(F::from_f64);
    let case = Case {
        o: v(case.o),
        d: v(case.d),
        c: v(case.c),
        r: F::from_f64(case.r),
    };
    quick_tiers(&case).unwrap_or_else(|| accurate(&case))
}

/// The quick phase, and for `f64` inputs whose enclosure does not decide the rounding the
/// near-surface refinement ([`near_surface`]): `Some` of the answer (`None` for a miss) when
/// they decide, `None` when only the accurate phase can.
#[inline(always)]
fn quick_tiers<F: Real>(case: &Case<F>) -> Option<Option<F>> {
    match quick_phase(case) {
        Quick::Miss => Some(None),
        Quick::Hit { th, tl, err } => match round_certain::<F>(th, tl, err) {
            Some(t) => Some(Some(t)),
            None if F::MANT_BITS == 53 => {
                let w = |v: [F; 3]| v.map(|x| x.to_f64());
                let c64 = Case {
                    o: w(case.o),
                    d: w(case.d),
                    c: w(case.c),
                    r: case.r.to_f64(),
                };
                near_surface(&c64, th, tl, err).map(|t| Some(F::from_f64(t)))
            }
            None => None,
        },
        Quick::Unsure => None,
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

/// The first look's lane answer when it cannot decide (a miss is NaN, a hit is `t > 0`).
pub const UNSURE: f64 = -1.0;

/// The first look's two error terms, in units of `u` (see [`first_look`]); the tests pass
/// smaller ones to show that each term is needed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Terms {
    /// Multiplies `fr/|C|`, the relative error of `C`: 11 in use.
    pub c: f64,
    /// Multiplies `Q/(√Δ·m)`, the relative error from `B`, `A` and `Δ`: 48 in use.
    pub disc: f64,
}

impl Terms {
    /// The terms the proof gives (with room).
    pub const PROVED: Terms = Terms {
        c: 11.0,
        disc: 48.0,
    };
    /// The terms of the exact-`C` look (tier 1b, [`exact_c_enclosure`]): `C'` within `272u²·fr + 1.01u·|C'|`,
    /// so the `C` term is `300u` (tier 1b's docs).
    pub const EXACT_C: Terms = Terms {
        c: 300.0 * U,
        disc: 48.0,
    };
}

/// The first look's quadratic for `f32` inputs, in `f64`.
#[derive(Clone, Copy, Debug)]
struct Look {
    a: f64,
    b: f64,
    b2: f64,
    cc: f64,
    fr: f64,
    q: f64,
    disc: f64,
    r: f64,
}

#[inline(always)]
fn look(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Look {
    // The quadratic P(t) = A t² + 2B t + C and the magnitudes F + r², Q = A·(F + r²)
    let f = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let b = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
    let ff = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
    let r2 = r * r;
    let (cc, fr) = (ff - r2, ff + r2);
    let b2 = b * b;
    Look {
        a,
        b,
        b2,
        cc,
        fr,
        q: a * fr,
        disc: b2 - a * cc,
        r,
    }
}

/// The first look's allowance for underflow with `f64` inputs: a product that underflows is
/// off by at most `η = 2⁻¹⁰⁷⁵`, which moves `Δ` by at most `8η·(A + R + 1)` (`|B| ≤ (A + F)/2`)
/// and `C` by `5η`; `2⁻¹⁰⁶⁸` covers both. (`f32` inputs cannot underflow in `f64`.)
const ETA_LOOK: f64 = f64::from_bits(7 << 52);

impl Look {
    /// A certain miss by the discriminant (`Δ < −e_Δ`, which also means outside) or an invalid
    /// radius: the common miss, decided before any root is taken. With `F64` (inputs in `f64`:
    /// `e_A = 3.01u·A`, `e_Δ ≤ 20.1u·Q`, the same constants cover it) the underflow allowance is
    /// added; an overflow makes `Q` or `Δ` infinite or NaN, and the test false.
    #[inline(always)]
    fn missed<const F64: bool>(&self) -> bool {
        let e = 24.0 * U * self.q;
        let e = if F64 {
            e + ETA_LOOK * (self.a + self.fr + 1.0)
        } else {
            e
        };
        !(self.r > 0.0) | (self.disc < -e)
    }

    /// A certain miss behind the origin: outside (`C > e_C`) and heading away (`B > e_B`,
    /// checked as `B² > 17u²·Q`; with `F64` also `B² ≥ 2⁻¹⁰⁰⁰`, so that `|B| ≥ 2⁻⁵⁰⁰` is far
    /// above the underflow allowance of `B`, `3η`).
    #[inline(always)]
    fn behind<const F64: bool>(&self) -> bool {
        let heading_away = (self.b > 0.0) & (self.b2 > (17.0 * U * U) * self.q);
        let heading_away = if F64 {
            heading_away & (self.b2 >= f64::from_bits(23 << 52))
        } else {
            heading_away
        };
        let e_c = 7.0 * U * self.fr;
        let e_c = if F64 { e_c + ETA_LOOK } else { e_c };
        (self.cc > e_c) & heading_away
    }
}

/// The first look's root of a [`Look`] before rounding, and the two sides of its test.
#[derive(Clone, Copy, Debug)]
struct Estimate {
    t: f64,
    /// `k.c·fr·√Δ·m + k.disc·Q·|C|`: the bound in units of `u·t`, times `|C|·√Δ·m`.
    lhs: f64,
    /// `|C|·√Δ·m`.
    scale: f64,
    /// `k.disc·Q·|C|`: `lhs` without the `C` term.
    lhs_disc: f64,
    /// The look's signs allow a hit (`Δ̂ > 0`, and inside or heading in).
    hit: bool,
}

impl Look {
    /// The root the look's signs point to (no bound): `|C|/m` with `m = |B| + √Δ` (the near
    /// root outside, the far root inside when `B > 0`), else `m/A`; and `√Δ`, `m`. NaN when
    /// `Δ̂ < 0`.
    #[inline(always)]
    fn root(&self) -> (f64, f64, f64) {
        self.root_with(self.disc.sqrt())
    }

    /// [`Look::root`] with `√Δ̂` given.
    #[inline(always)]
    fn root_with(&self, s: f64) -> (f64, f64, f64) {
        let m = self.b.abs() + s;
        let use_c = (self.cc > 0.0) | (self.b > 0.0);
        let t = if use_c { self.cc.abs() } else { m } / if use_c { m } else { self.a };
        (t, s, m)
    }
}

#[inline(always)]
fn estimate(l: &Look, k: Terms) -> Estimate {
    estimate_with(l, k, l.root())
}

/// [`estimate`] from the look's root `(t, √Δ̂, m)`.
#[inline(always)]
fn estimate_with(l: &Look, k: Terms, (t, s, m): (f64, f64, f64)) -> Estimate {
    let n = l.cc.abs();
    // The bound 11·fr/|C| + 48·Q/(√Δ·m) (units of u·t), multiplied out by |C|·√Δ·m
    let sm = s * m;
    Estimate {
        t,
        lhs: k.c * l.fr * sm + k.disc * l.q * n,
        scale: n * sm,
        lhs_disc: k.disc * l.q * n,
        hit: (l.disc > 0.0) & ((l.cc < 0.0) | (l.b < 0.0)),
    }
}

/// The correctly rounded `f32` of an [`Estimate`] (as an `f64`) and whether it is certain:
/// the bound, times `2u·t`, is below the distance from `t` to the nearest `f32` rounding
/// boundary ([`f32_boundary_distance`]), both sides multiplied by `|C|·√Δ·m`: no division.
#[inline(always)]
fn certain(e: &Estimate) -> (f64, bool) {
    let tf = e.t as f32;
    let dist = f32_boundary_distance(e.t, tf);
    let ok = e.hit
        & (e.lhs * ((2.0 * U) * e.t) < dist * e.scale)
        & (e.t >= f32::MIN_POSITIVE as f64)
        & tf.is_finite();
    (tf as f64, ok)
}

/// The first look's rounding check in its common case, in a dozen operations (half of them on
/// integers) where [`certain`] takes two dozen: the correctly rounded `f32` of the look's root
/// `t` (as an `f64`) and whether it is certain, when the bound's two terms are each at most
/// `2¹⁹` units and `t` is at least `2²²` `f64` ulps from the nearest `f32` rounding boundary.
/// When it cannot tell, [`certain`] decides. Tier 1b runs it too, with its terms
/// ([`Terms::EXACT_C`]: the same structure of bound, proved in [`exact_c_look`]'s docs).
///
/// **Why.** With `11·fr/|C| ≤ 2¹⁹` and `48·Q/(√Δ·m) ≤ 2¹⁹` (`k`'s terms; each product
/// rounded once, so within `1 + u` of the test), the bound of [`first_look`]'s proof is at most
/// `2²⁰(1 + u)` units of `u·t*`, and as `u·t* < 1.0001·u·t̂ < 1.0001` `f64` ulps of `t̂`
/// (`t̂ = 2^e·(1 + x)`, `x < 1`, ulp `2^(e−52)`), the root is within `2²¹` ulps of `t̂`. In `t̂`'s binade the `f32`
/// rounding boundaries are the points whose low 29 bits of mantissa are `2²⁸` (half an `f32`
/// ulp), so `|low₂₉ − 2²⁸|` is the distance to the nearest of them in ulps; the boundaries
/// outside the binade are at least `2²⁷` ulps away. At `2²²` or more, none lies within `2²¹`
/// ulps: the root rounds as `t̂` does. `2⁻¹²⁶ ≤ t̂ < f32::MAX` makes that `f32` normal and
/// finite, and the two terms' limits imply the first look's own (`Q/(√Δ·m) < 2²³`,
/// `|C| > 11·2⁻²⁸R`), so the verdict is settled as there. A NaN fails every comparison.
/// `tests/certified.rs` (`roots_whose_look_rounds_wrong_are_exact`) finds looks more than `2¹⁰`
/// ulps from a boundary they crossed, with bounds within these limits.
#[inline(always)]
fn certain_fast(l: &Look, k: Terms, (t, s, m): (f64, f64, f64)) -> (f64, bool) {
    let limit = 1.0 / 524_288.0;
    let small = (l.fr * (k.c * limit) <= l.cc.abs()) & (l.q * (k.disc * limit) <= s * m);
    let low = (t.to_bits() & ((1 << 29) - 1)) as i64 - (1 << 28);
    let far = low.abs() >= 1 << 22;
    let range = (t >= f32::MIN_POSITIVE as f64) & (t < f32::MAX as f64);
    let hit = (l.disc > 0.0) & ((l.cc < 0.0) | (l.b < 0.0));
    (t as f32 as f64, small & far & range & hit)
}

/// The first look's claim for an `f32` case, for the tests: the exact root lies within
/// `[t − err, t + err]` (`err` = the bound in units × `u·t`, with room for the rounding of the
/// division that gives the units), or `None` where it claims nothing: a certain miss, signs
/// that allow no hit, or a bound of `2²⁷` units or more, beyond the proof's range (the test
/// never passes there, since `dist ≤ 2²⁸`, and its second-order terms need the bound small).
pub fn first_look_enclosure(case: &Case<f32>, k: Terms) -> Option<(f64, f64)> {
    let w = |v: [f32; 3]| v.map(|x| x as f64);
    let l = look(w(case.o), w(case.d), w(case.c), case.r as f64);
    (!l.missed::<false>() && !l.behind::<false>())
        .then(|| enclosure(&l, k))
        .flatten()
}

/// The exact-`C` look's claim (tier 1b: the proof is in the docs of `exact_c_look`) for an `f32` case, for the tests, as
/// [`first_look_enclosure`]: `k.c` scales the bound on `C'` (and with it the signs it trusts).
pub fn exact_c_enclosure(case: &Case<f32>, k: Terms) -> Option<(f64, f64)> {
    let case = to_f64(case);
    let l = look(case.o, case.d, case.c, case.r);
    if l.missed::<false>() {
        return None;
    }
    // (Dekker's products: the same bits as FMA's, and the path a CPU without FMA takes)
    match exact_c_look::<false>(&case, &l, k) {
        ExactC::Look(l2) => enclosure(&l2, k),
        ExactC::Miss | ExactC::Open => None,
    }
}

/// A look's enclosure `(t, err)` of the root its signs point to, when the bound is below `2²⁷`
/// units and the signs allow a hit.
fn enclosure(l: &Look, k: Terms) -> Option<(f64, f64)> {
    let e = estimate(l, k);
    let units = e.lhs / e.scale * (1.0 + 1.0 / 1_048_576.0);
    (e.hit && units < 134_217_728.0).then(|| (e.t, units * U * e.t * (1.0 + 1.0 / 1_048_576.0)))
}

/// The first look for one test of `f32` inputs (given in `f64`, exactly), branch-free: the
/// correctly rounded `t` of a certain hit, NaN for a certain miss, or [`UNSURE`]. The batch
/// kernel runs it; the scalar method runs the same steps with early exits.
#[inline(always)]
pub fn first_look_lane(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64, k: Terms) -> f64 {
    let l = look(o, d, c, r);
    let (t, ok) = certain(&estimate(&l, k));
    if l.missed::<false>() | l.behind::<false>() {
        f64::NAN
    } else if ok {
        t
    } else {
        UNSURE
    }
}

/// The first look for one test of `f64` inputs, branch-free: NaN for a certain miss (the same
/// tests as the scalar method's, with the underflow allowance), else [`UNSURE`] (there is no
/// certain hit without the quick phase's Newton steps).
#[inline(always)]
pub fn first_look_lane_f64(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> f64 {
    let l = look(o, d, c, r);
    if l.missed::<true>() | l.behind::<true>() {
        f64::NAN
    } else {
        UNSURE
    }
}

/// The second look's two error terms (see [`second_look_claim`]), scaled: the tests cut
/// each to show it is needed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonTerms {
    /// Multiplies the residual's bound `e_P` (and the slope's, `e_P'`): 1 in use.
    pub residual: f64,
    /// Multiplies the curvature term `0.35·κ·|δ|`: 1 in use.
    pub curvature: f64,
}

impl NewtonTerms {
    /// The terms the proof gives.
    pub const PROVED: NewtonTerms = NewtonTerms {
        residual: 1.0,
        curvature: 1.0,
    };
}

/// The second look, `f64` inputs: the enclosure `[th + tl − err, th + tl + err]` of the nearest
/// root ahead, when the signs that identify it are certain; `None` hands the case on.
///
/// **The step.** From the look's root `t₀` (no bound needed), the exact residual quadratic
/// `P(t₀ + x) = P(t₀) + P'(t₀)·x + A·x²` (pure algebra: `P` is a quadratic). With
/// `κ = 4A·P(t₀)/P'(t₀)²` and `|κ| ≤ ½`, its root nearest 0 is real and is
/// `x* = δ·2/(1 + √(1 − κ))` with `δ = −P(t₀)/P'(t₀)` (rationalise `(−P' ± √(P'² − 4AP))/2A`),
/// so `|x* − δ| = |κ|·|δ|/(1 + √(1 − κ))² ≤ 0.35·|κ|·|δ|`: no bound on `t₀`'s own error is
/// needed, only the residual's. Which root it is follows from the sign of `P'(t₀)`: negative,
/// the smaller root `t₁` (`x* = (|P'| − √D)/2A`); positive, the larger `t₂`. `t₁` is the answer
/// when it is `> 0`; `t₂` only when `t₁ ≤ 0`, which `C ≤ 0` certain gives (with `C = 0` the
/// oracle's convention also answers `t₂`). The rounding check ([`round_certain`]) then proves
/// the root `> 0` (it rounds to a positive float) and its rounding.
///
/// **The residual.** `f + t₀·d = gh + gl*` exactly (`o − c` by Knuth's sum, `t₀·dᵢ` by an exact
/// product, their sum by Knuth's); `gl` rounds `gl* = e + pl + fl` in two additions. Then
/// `Σ gh² − r²` is exactly `s₃` plus seven low parts (exact squares, three of Knuth's sums in a tree), and
/// `P(t₀) = s₃ + low` with `low` their sum plus `2Σ gh·gl + Σ gl²`. With `wᵢ = |fhᵢ| + |phᵢ|`
/// and `M = fr + t₀²·A` (computed; `Σ wᵢ² ≤ 2.03·M`): `|gl*ᵢ| ≤ 2.01u·wᵢ`, `gl` is within
/// `4.05u²·wᵢ` of `gl*`; `low` has 13 terms of total magnitude at most `u·(16.7·M + 2.1·r²)`,
/// summed within `γ₁₂` plus `u` per product: `u²·(217·M + 27·r²)`; using `gl` for `gl*` costs
/// at most `16.7u²·M`; the last addition `1.01u·|P̂|`. So `e_P = 272u²·M + 1.01u·|P̂|` (`r² ≤
/// 1.01·fr ≤ 1.01·M`). The slope `P̂' = 2·Σ dᵢ·(ghᵢ + glᵢ)` is within `8.1u·Σ|dᵢ·ĝᵢ| +
/// 4.2u²·(A + 2.03·M)` (`Σ|dᵢ|wᵢ ≤ (Σdᵢ² + Σwᵢ²)/2`). With `e_P' < 2⁻¹⁰·|P̂'|`,
/// `1/|P'| ≤ v = 1.002·|1/P̂'|` (the reciprocal rounded once), so with `δ̂ = −P̂·(1/P̂')`
/// (two roundings) `|δ̂ − δ| ≤ (e_P + 1.01|δ̂|·e_P')·v + 2.01u·|δ̂|` and
/// `κ ≤ 4A(|P̂| + e_P)·v²`; a product that underflows to 0 there leaves `κ` below `2⁻¹⁰²²`,
/// whose term [`ETA`] covers. Without scaling the inputs: every product that underflows is off by at most
/// `2⁻¹⁰⁷⁵` (sums of floats are exact then), which [`ETA`]`·(1 + M + A)` covers many times over;
/// any overflow leaves an infinity or a NaN that fails a test (`P̂` and `P̂'` must be finite).
/// The bound's own roundings (about twenty, of positive terms) are covered by [`SAFETY`].
///
/// **Cost.** Products are exact in two instructions with FMA (Dekker's split takes about
/// seventeen), so the `f64` path runs this compiled with FMA when the CPU has it ([`certified`]
/// dispatches once; [`second_look`] for the out-of-line entries): the same answers either way,
/// since both products are exact (and a correctly rounded answer is unique).
#[inline(always)]
fn second_look_body<const FMA: bool, const NEAR: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    l: &Look,
    k: NewtonTerms,
) -> Second {
    if !NEAR {
        return Second::Open(newton_steps::<FMA>(o, d, c, r, l, k, l.certainly_inside()));
    }
    // An origin so near the surface that the look cannot tell its side: the side from the
    // residual at 0 (C and 2B to about 2⁻⁹⁷); outside and heading away is a miss
    let z = exact_residual_at_zero::<FMA>(o, d, c, r, l, k);
    if !(z.p.is_finite() && z.dp.is_finite()) {
        return Second::Open(None);
    }
    if z.p > z.ep && z.dp > z.edp {
        return Second::Miss;
    }
    let inside = z.p < -z.ep;
    if !(inside || z.p > z.ep) {
        return Second::Open(None);
    }
    Second::Open(newton_steps::<FMA>(o, d, c, r, l, k, inside))
}

/// The second look's steps from the look's root (NaN when Δ̂ < 0, which fails every test), up
/// to three: a guess far off (a grazing ray, a far sphere's cancelled discriminant) needs more
/// than one. It stops as soon as the enclosure decides the `f64` rounding, and when the
/// residual's own bound keeps it above an eighth of an ulp (an origin near the surface, where
/// more steps of this residual cannot help and the near-surface tier takes over); every
/// enclosure it returns is rigorous, so where it stops changes the cost, not the answer.
/// `inside`: `C < 0` is certain.
#[inline(always)]
fn newton_steps<const FMA: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    l: &Look,
    k: NewtonTerms,
    inside: bool,
) -> Option<(f64, f64, f64)> {
    let mut t0 = l.root().0;
    let mut found = None;
    for _ in 0..3 {
        let z = exact_residual::<FMA>(o, d, c, r, l, t0, k);
        // (the residual's bound at any t near t0, 272u²·M, over the slope: the width below
        // which no further step can shrink the enclosure)
        let floor = (272.0 * U * U) * (l.fr + t0 * t0 * l.a);
        let slope = z.dp.abs();
        let (th, tl, err, left) = enclosing_step(z, l, t0, k)?;
        // The root found: t1 when P'(t0) < 0 (the nearest ahead if it is ahead), else t2
        // (the nearest ahead only inside); the enclosure must lie ahead (th − |tl| − err > 0)
        let ahead = th > (err + tl.abs()) * (1.0 + 4.0 * U);
        found = (ahead && (left || inside)).then_some((th, tl, err));
        // Stop when the enclosure decides the f64 rounding, is tight (the root is that near a
        // boundary), or cannot shrink below an eighth of an ulp (an origin near the surface:
        // the near-surface tier's residual can)
        let ulp = th.next_up() - th;
        let stuck = floor * 8.0 >= ulp * slope;
        if found.is_none() || err < ulp * (1.0 / 1024.0) || round_f64_lane(th, tl, err).1 || stuck {
            break;
        }
        t0 = th;
    }
    found
}

/// What the second look decided.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Second {
    /// Certainly no root ahead (outside, heading away).
    Miss,
    /// The enclosure `(th, tl, err)` of the nearest root ahead, if the look found one: the
    /// rounding check decides whether it answers.
    Open(Option<(f64, f64, f64)>),
}

/// `P(t0)` and `P'(t0)` from exact products, with their bounds (the second look's docs).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn exact_residual<const FMA: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    l: &Look,
    t0: f64,
    k: NewtonTerms,
) -> Residual {
    // g = f + t0·d = gh + gl*, exactly; gl rounds gl*
    let (mut gh, mut gl) = ([0.0; 3], [0.0; 3]);
    for i in 0..3 {
        let (fh, fl) = two_sum(o[i], -c[i]);
        let (ph, pl) = exact_prod::<FMA>(t0, d[i]);
        let (s, e) = two_sum(fh, ph);
        gh[i] = s;
        gl[i] = (e + pl) + fl;
    }
    residual_at::<FMA>(gh, gl, d, r, l, t0, k)
}

/// [`exact_residual`] at `t0 = 0` (`C` and `2B`): there `t0·dᵢ = ±0` and Knuth's sum of it with
/// `fh` is `(fh, 0)`, so `g = fh + fl` (`o − c` by Knuth's sum) is the same point, and the same
/// bounds hold; without the product and the second sum, which lie on the longest chain of
/// dependent operations (tier 1b's, [`exact_c_look`], on every ray that starts on a surface).
#[inline(always)]
fn exact_residual_at_zero<const FMA: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    l: &Look,
    k: NewtonTerms,
) -> Residual {
    let (mut gh, mut gl) = ([0.0; 3], [0.0; 3]);
    for i in 0..3 {
        (gh[i], gl[i]) = two_sum(o[i], -c[i]);
    }
    residual_at::<FMA>(gh, gl, d, r, l, 0.0, k)
}

/// [`exact_residual`] from the point `g = gh + gl` at `t0`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn residual_at<const FMA: bool>(
    gh: [f64; 3],
    gl: [f64; 3],
    d: [f64; 3],
    r: f64,
    l: &Look,
    t0: f64,
    k: NewtonTerms,
) -> Residual {
    let tp = exact_prod::<FMA>;
    // P(t0) = (Σ gh² − r², exactly s3 + seven low parts) + 2 Σ gh·gl + Σ gl²
    // (no array `map` here: it stops the kernel's loop from vectorising)
    let sq = [tp(gh[0], gh[0]), tp(gh[1], gh[1]), tp(gh[2], gh[2])];
    let rr = tp(r, r);
    let (s1, e1) = two_sum(sq[0].0, sq[1].0);
    let (s2, e2) = two_sum(sq[2].0, -rr.0);
    let (s3, e3) = two_sum(s1, s2);
    let small = 2.0 * (gh[0] * gl[0] + gh[1] * gl[1] + gh[2] * gl[2])
        + (gl[0] * gl[0] + gl[1] * gl[1] + gl[2] * gl[2]);
    let low = ((e1 + e2) + (e3 + sq[0].1)) + ((sq[1].1 + sq[2].1) - rr.1) + small;
    let p = s3 + low;
    // P'(t0) = 2 d·g
    let x = [
        d[0] * (gh[0] + gl[0]),
        d[1] * (gh[1] + gl[1]),
        d[2] * (gh[2] + gl[2]),
    ];
    let dp = 2.0 * (x[0] + x[1] + x[2]);
    let sdg = x[0].abs() + x[1].abs() + x[2].abs();
    // Their bounds (the second look's docs), and the underflow allowance
    let big = l.fr + t0 * t0 * l.a;
    let tiny = ETA * (1.0 + big + l.a);
    let ep = ((272.0 * U * U) * big + 1.01 * U * p.abs()) * SAFETY * k.residual + tiny;
    let edp = ((8.1 * U) * sdg + (4.2 * U * U) * (l.a + 2.03 * big)) * SAFETY * k.residual + tiny;
    Residual { p, ep, dp, edp }
}

/// `a·b = p + e` exactly: by FMA (`FMA`, two instructions) or by Dekker's split (about
/// seventeen); the same bits either way wherever neither `a·b` nor a split of `a` or `b`
/// overflows and `e` does not underflow. The method's tests, on wild inputs too, give the same
/// bits under `RAYPROOF_ISA=scalar` (the split) as with FMA; the floor, which has no range
/// guard, did not, and uses FMA semantics on every CPU.
#[inline(always)]
fn exact_prod<const FMA: bool>(a: f64, b: f64) -> (f64, f64) {
    if FMA {
        two_prod(a, b)
    } else {
        two_prod_split(a, b)
    }
}

/// One step of the second look from `t0` and its residual `z`: the enclosure `[th + tl ± err]`
/// of the root of `P` nearest `t0`'s Newton step, and whether it is the smaller root
/// (`P'(t0) < 0`).
#[inline(always)]
fn enclosing_step(z: Residual, l: &Look, t0: f64, k: NewtonTerms) -> Option<(f64, f64, f64, bool)> {
    let (th, tl, err, left, ok) = enclosing_step_lane(z, l, t0, k);
    ok.then_some((th, tl, err, left))
}

/// [`enclosing_step`] branch-free (for the lanes): the enclosure, `left`, and whether it holds.
#[inline(always)]
fn enclosing_step_lane(
    z: Residual,
    l: &Look,
    t0: f64,
    k: NewtonTerms,
) -> (f64, f64, f64, bool, bool) {
    let Residual { p, ep, dp, edp } = z;
    // One division: 1/|P'| ≤ v = |1/P̂'|·1.002 when e_P' < 2⁻¹⁰·|P̂'| (and |P̂'| < 2⁹⁹⁶, so
    // that 1/P̂' is a normal float); the step δ = −P̂·(1/P̂') and its bound; κ ≤ 4A(|P̂| + e_P)·v²,
    // and the curvature term
    let inv = 1.0 / dp;
    let v = inv.abs() * 1.002;
    let ok = (edp * v < 1.0 / 1024.0) & (dp.abs() < 1e300) & p.is_finite();
    let delta = -p * inv;
    let ed = (ep + 1.01 * delta.abs() * edp) * v + 2.01 * U * delta.abs();
    let kappa = 4.0 * (l.a * (1.0 + 4.0 * U) + ETA) * (p.abs() + ep) * v * v;
    let err = (ed + 0.35 * kappa * (delta.abs() + ed) * k.curvature) * SAFETY + ETA;
    let (th, tl) = two_sum(t0, delta);
    let ok = ok & (kappa <= 0.5) & err.is_finite() & th.is_finite();
    (th, tl, err, dp < 0.0, ok)
}

/// The second look on lanes, for a test the first look left open (the inputs in `f64`,
/// exactly; `F32`: the inputs were `f32`, so the answer is rounded to `f32`): the correctly
/// rounded `t` (as an `f64`) when two Newton steps of the second look's common path ([`second_look_claim`]) prove
/// it, else [`UNSURE`]. Branch-free, products by FMA (`mul_add`: the hardware's in the AVX2 and
/// AVX-512 kernels, the C library's in the portable one; exact either way), so the batch
/// kernel runs it on 8 `f64` lanes; every answer is the unique correctly rounded root, so it is
/// the scalar method's, bit for bit. Certain misses are the first look's, not its; invalid
/// input (a radius not `> 0`, a non-finite value, a zero direction) is never answered.
#[inline(always)]
pub fn second_look_lane<const F32: bool>(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> f64 {
    let l = look(o, d, c, r);
    // (a radius that is not > 0 is invalid input: never answered)
    let inside = l.certainly_inside();
    let r_ok = r > 0.0;
    // Two steps written out, not a loop: the kernel's loop must be the innermost to vectorise
    let (t1, best, sure) = lane_step::<F32>(o, d, c, r, &l, inside, l.root().0, UNSURE, !r_ok);
    lane_step::<F32>(o, d, c, r, &l, inside, t1, best, sure).1
}

/// One step of [`second_look_lane`] from `t0`: the next `t0`, and the answer so far (`best`,
/// certain if `sure`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn lane_step<const F32: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    l: &Look,
    inside: bool,
    t0: f64,
    best: f64,
    sure: bool,
) -> (f64, f64, bool) {
    let k = NewtonTerms::PROVED;
    let z = exact_residual::<true>(o, d, c, r, l, t0, k);
    let (th, tl, err, left, ok) = enclosing_step_lane(z, l, t0, k);
    // The root found must be the nearest ahead if it is ahead (t1, or t2 from inside); a
    // certain rounding to a float > 0 proves the whole enclosure > 0 (the scalar steps' `ahead`)
    let (t, rounded) = if F32 {
        round_f32_lane(th, tl, err)
    } else {
        round_f64_lane(th, tl, err)
    };
    let now = ok & (left | inside) & rounded & !sure;
    (
        if ok { th } else { t0 },
        if now { t } else { best },
        sure | now,
    )
}

/// [`second_look_body`] with hardware FMA when the CPU has it, else with Dekker's products (the
/// same bits: both are exact). `NEAR`: the look could not tell the origin's side.
#[inline(always)]
fn second_look<const NEAR: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    l: &Look,
    k: NewtonTerms,
) -> Second {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::numerics::cpu::fma() {
            // SAFETY: the CPU has FMA
            return unsafe { second_look_fma::<NEAR>(o, d, c, r, l, k) };
        }
        second_look_body::<false, NEAR>(o, d, c, r, l, k)
    }
    #[cfg(not(target_arch = "x86_64"))]
    second_look_body::<true, NEAR>(o, d, c, r, l, k)
}

/// [`second_look_body`] compiled with FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn second_look_fma<const NEAR: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    l: &Look,
    k: NewtonTerms,
) -> Second {
    second_look_body::<true, NEAR>(o, d, c, r, l, k)
}

impl Look {
    /// The side of the origin is certain (`|C| > e_C`, the bound of [`Look::behind`] for `f64`
    /// inputs).
    #[inline(always)]
    fn side_certain(&self) -> bool {
        self.cc.abs() > 7.0 * U * self.fr + ETA_LOOK
    }

    /// `C < 0` is certain: the origin is inside.
    #[inline(always)]
    fn certainly_inside(&self) -> bool {
        self.cc < -(7.0 * U * self.fr + ETA_LOOK)
    }
}

/// The second look in full: the common one, and for an origin whose side the look cannot tell,
/// the one that finds the side first.
fn second_look_full(case: &Case<f64>, l: &Look, k: NewtonTerms) -> Second {
    let (o, d, c, r) = (case.o, case.d, case.c, case.r);
    match second_look::<false>(o, d, c, r, l, k) {
        Second::Open(None) if !l.side_certain() => second_look::<true>(o, d, c, r, l, k),
        s => s,
    }
}

/// The second look's claim for a case (inputs in `f64`), for the tests: a certain miss, or the
/// enclosure of the nearest root ahead, or nothing (`Open(None)`, also for the first look's
/// certain misses, which never reach it).
pub fn second_look_claim(case: &Case<f64>, k: NewtonTerms) -> Second {
    let l = look(case.o, case.d, case.c, case.r);
    if l.missed::<true>() || l.behind::<true>() {
        return Second::Open(None);
    }
    second_look_full(case, &l, k)
}

/// The first look, for `f32` inputs: the quadratic in `f64` with the textbook discriminant
/// `Δ = B² − A·C` and one test, `(11·fr/|C| + 48·Q/(√Δ·m))·2u·t < dist` with `fr = F + r²`,
/// `Q = A·fr`, `m = |B| + √Δ` and `dist` the distance from `t` to the nearest `f32` rounding
/// boundary (`f32_boundary_distance`, at most `2⁻²⁴·t`), multiplied out by `|C|·√Δ·m` so that
/// it needs no division. `k` scales the two terms: [`Terms::PROVED`] in use. A certain miss
/// (`Δ < −24u·Q`, or outside and heading away) is decided from the same bounds.
///
/// **Why the test is enough.** With `S = Σ|dᵢfᵢ| ≤ √(A·F)` (Cauchy–Schwarz) and `R = F + r²`,
/// the computed values are within `e_A = 2.01u·A`, `e_B = 4.01u·S`, `e_C = 6.03u·R` and
/// `e_Δ = 19.1u·A·R` (`|B̂² − B²| ≤ 8.03u·AF`, `|ÂĈ − AC| ≤ 8.04u·AR`, three roundings of at
/// most `1.01u·AR` since `|Δ| ≤ A·R`). As `Δ ≤ A·r² ≤ Q` and `B² ≤ Q`, `√Q/m ≤ Q/(√Δ·m)` and
/// `√Δ·m ≤ 2Q`. Then `|√Δ̂ − √Δ| ≤ e_Δ/√Δ̂ + u√Δ̂`, and `m` has relative error at most
/// `(e_B + e_√Δ)/m + u ≤ u·(23.3·Q/(√Δ·m) + 2.02)`. The near root `|C|/m` is within
/// `u·(6.03·R/|C| + 23.3·Q/(√Δ·m) + 3.03)`, the far root `m/A` within
/// `u·(23.3·Q/(√Δ·m) + 5.04)`. Inside the sphere, where the sign of `B` is within `e_B`, the
/// formula chosen may be the other one, which moves `t` by `2|B|/A`, at most
/// `4.01u·(1 + R/|C|)·t` (`√Δ ≥ √(A|C|)`). The worst case, `10.04·R/|C| + 23.3·Q/(√Δ·m) + 9.05`
/// with `1 ≤ 2Q/(√Δ·m)`, is below `10.1·R/|C| + 41.5·Q/(√Δ·m)`. The constants 11 and 48 leave
/// 8 % of room, which covers the second-order terms (the test keeps the bound below `2⁻²⁵`)
/// and the test's own roundings (a few `u`); the factor 2 in `2u·t` covers `t* ≤ t̂(1 + 2⁻²⁵)`.
///
/// The test also settles the verdict: it implies `√Q/(2√Δ) ≤ Q/(√Δ·m) < 2²³`, so
/// `Δ > 73u·Q > e_Δ` (a hit is certain), `|C| > 11·2⁻²⁸R ≫ e_C` (the side is certain), and
/// from outside `|B| ≥ √Δ ≫ e_B` (the direction is certain). Certain misses use the same
/// bounds (`C > 7u·fr`, `B² > 17u²·Q` for `B > e_B`, `Δ < −24u·Q`). Nothing over- or
/// underflows: every non-zero product of the inputs' differences is between `2⁻⁵⁹⁶` and
/// `2⁵¹⁶`, and when the test passes `fr·√Δ·m` and `Q·|C|` are above `2⁻⁹²⁰`
/// (`√Δ·m > 48Q·2⁻²⁸`, `|C| > 11R·2⁻²⁸`), so neither side was rounded by underflow.
/// Non-finite input makes every comparison false: the quick phase decides it.
#[inline(always)]
pub fn first_look<F: Real>(case: &Case<F>, k: Terms) -> FirstLook<F> {
    let w = |v: [F; 3]| v.map(|x| x.to_f64());
    let t = first_look_lane(w(case.o), w(case.d), w(case.c), case.r.to_f64(), k);
    if t.is_nan() {
        FirstLook::Miss
    } else if t > 0.0 {
        FirstLook::Hit(F::from_f64(t))
    } else {
        FirstLook::Unsure
    }
}

thread_local! {
    /// How many times this thread ran the accurate phase.
    static ACCURATE_RUNS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// How many times this thread has run the accurate phase: the tests read it before and after
/// a case to see which tier answered.
pub fn accurate_phase_runs() -> u64 {
    ACCURATE_RUNS.with(|n| n.get())
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
fn accurate<F: Real>(case: &Case<F>) -> Option<F> {
    ACCURATE_RUNS.with(|n| n.set(n.get() + 1));
    nearest_root(case)
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
        (o, d, c, r, back) = scaled(o, d, c, r);
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
        let z = if F::MANT_BITS == 24 {
            split_at_zero(o, d, c, r)
        } else {
            residual_at_zero(o, d, c, r)
        };
        if z.ep < ec {
            (cc, ec) = (z.p, z.ep);
        }
        if 0.5 * z.edp < eb {
            (b, eb) = (0.5 * z.dp, 0.5 * z.edp);
        }
    }
    let (disc, ed) = discriminant(d, f, a, r2, ff);
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

/// Lagrange's discriminant `Δ = A r² − |d × f|²` and its bound `e_Δ` (the module docs' table),
/// from the (scaled) direction `d`, `f = o − c`, `A = d·d`, `r²` and `f·f` as the quick phase
/// computes them.
#[inline(always)]
fn discriminant(d: [f64; 3], f: [f64; 3], a: f64, r2: f64, ff: f64) -> (f64, f64) {
    let (ad, af) = (d.map(f64::abs), f.map(f64::abs));
    // The cross product and the magnitudes P_k of its terms
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
    (disc, ed)
}

/// The quick phase's discriminant `Δ̂` and bound `e_Δ` for a case, and the exact `Δ` of the same
/// (scaled) inputs' `d` and `f = o − c`, for tests of the bound: `None` for input the quick
/// phase rejects before it (a radius not `> 0`, a non-finite component, a zero direction).
/// Both are of the inputs scaled by powers of two (for `f64` inputs), where the phase works.
pub fn discriminant_of<F: Real>(case: &Case<F>) -> Option<(f64, f64, rug::Rational)> {
    let w = |v: [F; 3]| v.map(|x| x.to_f64());
    let (mut o, mut d, mut c, mut r) = (w(case.o), w(case.d), w(case.c), case.r.to_f64());
    let sum = o[0] + o[1] + o[2] + d[0] + d[1] + d[2] + c[0] + c[1] + c[2] + r;
    if !(r > 0.0) || !sum.is_finite() {
        return None;
    }
    if F::MANT_BITS == 53 {
        (o, d, c, r, _) = scaled(o, d, c, r);
    }
    let f = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if !(a > 0.0) {
        return None;
    }
    let ff = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
    let (disc, ed) = discriminant(d, f, a, r * r, ff);
    // The exact value from the same (exact) scaled inputs
    let q = |x: f64| rug::Rational::from_f64(x).expect("finite");
    let (qd, qf): (Vec<_>, Vec<_>) = (0..3).map(|i| (q(d[i]), q(o[i]) - q(c[i]))).unzip();
    let qa = qd.iter().map(|x| x.clone() * x).sum::<rug::Rational>();
    let cross = |i: usize, j: usize| qd[i].clone() * &qf[j] - qd[j].clone() * &qf[i];
    let qx = [cross(1, 2), cross(2, 0), cross(0, 1)];
    let exact = qa * q(r) * q(r) - qx.iter().map(|x| x.clone() * x).sum::<rug::Rational>();
    Some((disc, ed, exact))
}

/// The inputs scaled by exact powers of two, positions (`o`, `c`, `r`) and the direction
/// apart, so that the largest of each is in `[1, 2)`; `t` of the scaled inputs times
/// `2^back` is `t` of the inputs. Finite inputs with `r > 0` and `d ≠ 0`.
#[inline(always)]
#[allow(clippy::type_complexity)]
fn scaled(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
) -> ([f64; 3], [f64; 3], [f64; 3], f64, i32) {
    let mx = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let kp = -ilogb(mx(&[o[0], o[1], o[2], c[0], c[1], c[2], r]));
    let kd = -ilogb(mx(&d));
    (
        o.map(|x| mul_pow2(x, kp)),
        d.map(|x| mul_pow2(x, kd)),
        c.map(|x| mul_pow2(x, kp)),
        mul_pow2(r, kp),
        kd - kp,
    )
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

/// [`residual_at_zero`] for `f32` inputs, at a fraction of its cost: `C` and `2B` to about
/// `2⁻⁷²` of their magnitudes. `f = o − c` is exact as `fh + fl` (Knuth), and `fh` splits into
/// its `f32` rounding `hi` and `lo = fh − hi` (exact, at most 29 bits), so `hi²`, `2·hi·lo`,
/// `dᵢ·hi` and `dᵢ·lo` are exact in `f64` (at most 48 or 53 bits; `f32` inputs cannot
/// underflow them). The large terms (`hiᵢ²` and `−r²` for `C`, `dᵢ·hiᵢ` for `B`) are summed
/// exactly by Knuth's cascade; the rest (the cascade's errors, `2·hi·lo`, `lo²`, `2·fh·fl`,
/// `fl²`, `dᵢ·lo`, `dᵢ·fl`, at most `(2⁻²³ + 6u)·R` in all for `C` with `R = F + r²`, and
/// `(2⁻²⁴ + 4u)·S` for `B` with `S = Σ|dᵢfᵢ|`) is summed in `f64` within `γ₁₆` of its
/// magnitude, plus its own roundings (`u` each), plus the last addition (`u` of the result).
#[cold]
#[inline(never)]
fn split_at_zero(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Residual {
    let (mut cs, mut ce) = (-r * r, 0.0);
    let (mut bs, mut be) = (0.0, 0.0);
    let (mut ff, mut sb) = (r * r, 0.0);
    for i in 0..3 {
        // f = fh + fl exactly; fh = hi + lo exactly
        let (fh, fl) = two_sum(o[i], -c[i]);
        let hi = fh as f32 as f64;
        let lo = fh - hi;
        // The large terms exactly, the rest by plain sums
        let (x, e) = two_sum(cs, hi * hi);
        cs = x;
        ce += e + 2.0 * hi * lo + lo * lo + 2.0 * fh * fl + fl * fl;
        let (y, e) = two_sum(bs, d[i] * hi);
        bs = y;
        be += e + d[i] * lo + d[i] * fl;
        ff += fh * fh;
        sb += (d[i] * fh).abs();
    }
    let (p, dp) = (cs + ce, 2.0 * (bs + be));
    Residual {
        p,
        ep: 16.5 * U * (1.0 / 8_388_608.0 + 6.0 * U) * ff + 1.01 * U * p.abs(),
        dp,
        edp: 2.0 * (16.5 * U * (1.0 / 16_777_216.0 + 4.0 * U) * sb) + 1.01 * U * dp.abs(),
    }
}

/// Two passes of Knuth's cascade over `v` (Ogita, Rump & Oishi's `VecSum`, which keeps the
/// exact sum), then the plain sum of what is left below the last partial sum: the exact sum of
/// the input terms lies within `err` of `hi + lo`. After two passes the leftovers are at most
/// `n²u²·Σ|vᵢ| + u·|sum|` in all, so `err` is about `n³u³·Σ|vᵢ| + n·u²·|sum|`: a sum that
/// cancels to a tiny fraction of its terms keeps about 100 bits of itself.
fn sum2(v: &mut [f64]) -> (f64, f64, f64) {
    let n = v.len();
    for _ in 0..2 {
        for i in 1..n {
            (v[i], v[i - 1]) = two_sum(v[i], v[i - 1]);
        }
    }
    let (mut lo, mut mag) = (0.0, 0.0);
    for &x in &v[..n - 1] {
        lo += x;
        mag += x.abs();
    }
    (v[n - 1], lo, (n as f64 + 1.0) * U * mag * 1.01)
}

/// The residual in the form `P(t) = C + t·(2B + A·t)`, with `C`, `B` and `A` each within about
/// `2⁻¹⁰⁰` of itself ([`sum2`] of their exact products: `o − c = fh + fl` by Knuth's sum, every
/// product split by Dekker's). Near an origin on the surface this form's error is a tiny
/// fraction of `|C|`, where `|f + t·d|² − r²` ([`residual`]) is off by about `2⁻¹⁰⁶·r²`, far
/// more than `|C|` when the origin is within `2⁻⁵⁰` of a large sphere. Scaled `f64` inputs
/// (every magnitude below 4, so nothing overflows; an underflowed product is within [`ETA`]).
#[inline(always)]
fn residual_near<const FMA: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    t: f64,
) -> Residual {
    let two_prod_split = exact_prod::<FMA>;
    // C = Σ (fh + fl)² − r², A = Σ d², B = Σ d·(fh + fl), from exact products
    let mut cv = [0.0; 20];
    let mut av = [0.0; 6];
    let mut bv = [0.0; 12];
    let (rr, rre) = two_prod_split(r, r);
    (cv[3], cv[19]) = (-rr, -rre);
    for i in 0..3 {
        let (fh, fl) = two_sum(o[i], -c[i]);
        // The three large squares first (they cancel against r²), then the small parts
        (cv[i], cv[4 + i]) = two_prod_split(fh, fh);
        (cv[7 + i], cv[10 + i]) = two_prod_split(2.0 * fh, fl);
        (cv[13 + i], cv[16 + i]) = two_prod_split(fl, fl);
        (av[i], av[3 + i]) = two_prod_split(d[i], d[i]);
        (bv[i], bv[3 + i]) = two_prod_split(d[i], fh);
        (bv[6 + i], bv[9 + i]) = two_prod_split(d[i], fl);
    }
    let (ch, cl, ec) = sum2(&mut cv);
    let (ah, al, ea) = sum2(&mut av);
    let (bh, bl, eb) = sum2(&mut bv);
    // P(t) = C + 2B·t + A·t², as exact products where it matters and rounded ones (within u)
    let (tt, tte) = two_prod_split(t, t);
    let (p1, p1e) = two_prod_split(2.0 * bh, t);
    let (p2, p2e) = two_prod_split(ah, tt);
    let rounded = [2.0 * bl * t, ah * tte, al * tt];
    let mut pv = [ch, cl, p1, p1e, p2, p2e, rounded[0], rounded[1], rounded[2]];
    let (ph, pl, esum) = sum2(&mut pv);
    let p = ph + pl;
    let ta = t.abs();
    let ep = esum
        + ec
        + 2.0 * ta * eb
        + tt * ea
        + 1.01 * U * rounded.iter().map(|x| x.abs()).sum::<f64>()
        + (al * tte).abs() * 1.01
        + U * p.abs()
        + ETA;
    // P'(t) = 2(B + A·t), to a few ulps
    let dp = 2.0 * (bh + ah * t);
    let edp =
        2.0 * (eb + bl.abs() + ta * (ea + al.abs()) + 3.01 * U * (bh.abs() + (ah * t).abs())) + ETA;
    Residual {
        p,
        ep: ep * SAFETY,
        dp,
        edp,
    }
}

/// Fourth tier, `f64` inputs: the quick phase's enclosure `[th + tl ± err]` refined by up to two
/// Newton steps with [`residual_near`] ([`near_surface_step`]), for an origin so near the
/// surface that the quick phase's residual cannot tell the rounding. The correctly rounded
/// `t`, or `None` (the accurate phase decides). Products by FMA when the CPU has it.
#[cold]
#[inline(never)]
fn near_surface(case: &Case<f64>, th: f64, tl: f64, err: f64) -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::numerics::cpu::fma() {
            // SAFETY: the CPU has FMA
            return unsafe { near_surface_fma(case, th, tl, err) };
        }
        near_surface_body::<false>(case, th, tl, err)
    }
    #[cfg(not(target_arch = "x86_64"))]
    near_surface_body::<true>(case, th, tl, err)
}

/// [`near_surface_body`] compiled with FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn near_surface_fma(case: &Case<f64>, th: f64, tl: f64, err: f64) -> Option<f64> {
    near_surface_body::<true>(case, th, tl, err)
}

/// [`near_surface`]'s steps, products by FMA (`FMA`) or Dekker's split.
#[inline(always)]
fn near_surface_body<const FMA: bool>(case: &Case<f64>, th: f64, tl: f64, err: f64) -> Option<f64> {
    let (mut th, mut tl, mut err) = (th, tl, err);
    for _ in 0..2 {
        (th, tl, err) = near_surface_step_with::<FMA>(case, th, tl, err)?;
        if let Some(t) = round_certain::<f64>(th, tl, err) {
            return Some(t);
        }
    }
    None
}

/// One Newton step of the near-surface tier from the enclosure `[th + tl ± err]` of a hit's
/// root (of `f64` inputs): the new enclosure, or `None` if the step is not defined (the slope
/// is not certain, or `th` does not scale exactly). Public for the tests, which check it
/// against MPFR's root (Dekker's products here; the tier itself uses FMA when it can: the same
/// bits).
pub fn near_surface_step(case: &Case<f64>, th: f64, tl: f64, err: f64) -> Option<(f64, f64, f64)> {
    near_surface_step_with::<false>(case, th, tl, err)
}

#[inline(always)]
fn near_surface_step_with<const FMA: bool>(
    case: &Case<f64>,
    th: f64,
    tl: f64,
    err: f64,
) -> Option<(f64, f64, f64)> {
    let (o, d, c, r, back) = scaled(case.o, case.d, case.c, case.r);
    // The enclosure in the scaled coordinates (exact, or give up)
    let t = mul_pow2(th, -back);
    if mul_pow2(t, back) != th || !(t > 0.0) {
        return None;
    }
    let e = mul_pow2(err + tl.abs() * (1.0 + 2.0 * U), -back) + ETA;
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let (th, tl, e) = newton_with(residual_near::<FMA>(o, d, c, r, t), a, t, e)?;
    // Back to the inputs' scale (exact unless it over- or underflows, which the rounding catches)
    let k = |x: f64| mul_pow2(x, back);
    let (th, tl, e) = (k(th), k(tl), k(e) + ETA);
    (th.is_finite() && e.is_finite()).then_some((th, tl, e))
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
    newton_with(residual(o, d, c, r, t), a, t, err)
}

/// [`newton`] from a residual `z` at `t` (its value, slope and their bounds) and the
/// quadratic's leading coefficient `a` (within `5u` of `A`).
#[inline(always)]
fn newton_with(z: Residual, a: f64, t: f64, err: f64) -> Option<(f64, f64, f64)> {
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

/// The distance from `t > 0` to the nearest `f32` rounding boundary, or a little less, exactly
/// and branch-free (the batch kernel runs it per lane); `tf` is `t` rounded to `f32`. For `t`
/// in `[2^E, 2^(E+1))` the boundaries around `tf` are half an `f32` ulp, `h = 2^(E−24)`, from
/// it, so the distance is `h − |t − tf|`; when `tf = 2^E ≤ t` the boundary below is only `h/2`
/// under `tf`, at distance `|t − tf| + h/2`, and the smaller of the two is taken always (it
/// can only make the check stricter). Every step is exact (`t` and `tf` share a binade or
/// touch it, and all are multiples of `t`'s ulp below `2^(E−23)`). Meaningful for `tf` a
/// finite normal `f32`, which the caller checks.
#[inline(always)]
fn f32_boundary_distance(t: f64, tf: f32) -> f64 {
    let off = (t - tf as f64).abs();
    let h = f64::from_bits(t.to_bits() & 0x7ff0_0000_0000_0000) * (1.0 / 16_777_216.0);
    (h - off).min(off + 0.5 * h)
}

/// The float of precision `F` nearest to every point of `[th + tl − err, th + tl + err]`, if
/// there is one (the enclosure does not straddle a rounding boundary), it is `> 0` and it is
/// finite with a finite successor.
#[inline(always)]
fn round_certain<F: Real>(th: f64, tl: f64, err: f64) -> Option<F> {
    let (t, ok) = if F::MANT_BITS == 24 {
        round_f32_lane(th, tl, err)
    } else {
        round_f64_lane(th, tl, err)
    };
    ok.then(|| F::from_f64(t))
}

/// [`round_certain`] to `f32`, branch-free: the float (as an `f64`) and whether it is certain.
/// The distance to the nearest rounding boundary is read off `th`'s bits
/// ([`f32_boundary_distance`]).
#[inline(always)]
fn round_f32_lane(th: f64, tl: f64, err: f64) -> (f64, bool) {
    let tf = th as f32;
    let err = (err + tl.abs()) * (1.0 + 2.0 * U);
    let ok =
        (f32_boundary_distance(th, tf) > err) & (th >= f32::MIN_POSITIVE as f64) & tf.is_finite();
    (tf as f64, ok)
}

/// [`round_certain`] to `f64`, branch-free: `th` itself and whether it is certain. For
/// `th > 0` finite its neighbours are the floats of the next and previous bit patterns; the
/// half-ulps below and above are exact, and the distances from the enclosure's centre to the
/// two boundaries carry their rounding margin.
#[inline(always)]
fn round_f64_lane(th: f64, tl: f64, err: f64) -> (f64, bool) {
    let bits = th.to_bits();
    let up = f64::from_bits(bits.wrapping_add(1));
    let down = f64::from_bits(bits.wrapping_sub(1));
    let half_lo = (th - down) * 0.5;
    let half_hi = (up - th) * 0.5;
    let (dl, dh) = (half_lo + tl, half_hi - tl);
    let margin = 4.0 * U * (half_lo + half_hi + tl.abs());
    let ok = (th > 0.0) & up.is_finite() & (dl > err + margin) & (dh > err + margin);
    (th, ok)
}
