//! **Floors**: the part of [`certified`](super::certified) that every certified answer computes,
//! with its certificate left out. Not a method (its answers are not proven; it is in no table
//! of the audit): a measuring stick for what the speed targets leave room for. Timed
//! beside `algebraic` and `certified` in `benches/sphere.rs` and `benches/batch.rs`.
//!
//! - `f32` inputs: the first look's root (the quadratic in `f64`, its square root and its
//!   division), rounded to `f32`, with the verdict from the signs alone (no bound), no rounding
//!   check and no later tier. A certified `f32` answer cannot cost less: the look is
//!   its first step on every case.
//! - `f64` inputs: the look's root and one Newton step with the residual from exact products
//!   (the second look's, by FMA: the CPU's, else the C library's `fma`, so that the scalar form
//!   and every batch kernel give the same bits on every input), the verdict from the signs alone, no rounding
//!   check and no later step. The textbook formula in `f64` cannot prove its `t` within one
//!   ulp: its last three roundings (square root, sum, division) alone allow `2.5u·t`, more than
//!   an ulp anywhere in a binade. So a certified `f64` hit evaluates something beyond `f64` at
//!   least once; this is the least of that the method does.

use super::{case_of, exact_residual, look, to_f64, Look, NewtonTerms};
use crate::numerics::real::Real;
use crate::shapes::sphere::ray::{Ray, Sphere, SphereHit};

/// The floor's answer for one test (see the [module docs](self)): `t`, or `None` for a miss.
pub fn floor<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    #[cfg(target_arch = "x86_64")]
    if F::MANT_BITS == 53 && crate::numerics::cpu::fma() {
        // SAFETY: the CPU has FMA
        return unsafe { floor_fma(ray, s) };
    }
    // Without hardware FMA, `mul_add` (the C library's `fma`): the batch lanes' products, bit
    // for bit. Dekker's split would give other bits where a product or its split overflows
    // (wild inputs such as |d| ≈ 1e303: found with RAYPROOF_ISA=scalar on an FMA machine),
    // and the floor has no range guard to keep it from them
    floor_body::<F, true>(ray, s)
}

/// [`floor`] compiled with FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn floor_fma<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    floor_body::<F, true>(ray, s)
}

/// [`floor`]'s steps, in the method's order (the certain misses before the root).
#[inline(always)]
fn floor_body<F: Real, const FMA: bool>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let case = to_f64(&case_of(ray, s));
    let l = look(case.o, case.d, case.c, case.r);
    if naive_miss(&l) {
        return None;
    }
    let t = floor_root::<FMA>(case.o, case.d, case.c, case.r, &l, F::MANT_BITS == 24);
    (t > 0.0).then(|| SphereHit {
        t: F::from_f64(t),
        enclosure: None,
    })
}

/// [`floor`] for one test on lane values (the inputs in `f64`, exactly; `f32`: they were `f32`),
/// branch-free: `t`, or NaN for a miss. Products by FMA (`FMA`) or Dekker's split: the same
/// bits.
#[inline(always)]
pub fn floor_lane<const FMA: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    f32: bool,
) -> f64 {
    let l = look(o, d, c, r);
    let t = floor_root::<FMA>(o, d, c, r, &l, f32);
    // (one NaN for every miss, as the scalar form's `None` gives)
    if naive_miss(&l) | !(t > 0.0) {
        f64::NAN
    } else {
        t
    }
}

/// The floor's verdict, without a bound: a miss when `Δ̂ ≤ 0`, or outside and heading away by
/// the signs of `Ĉ` and `B̂` (the method decides its certain misses with bounds on both).
#[inline(always)]
fn naive_miss(l: &Look) -> bool {
    !(l.disc > 0.0) | ((l.cc > 0.0) & (l.b > 0.0))
}

/// The floor's root of a look `l` that is not a certain miss: the look's root, rounded to `f32`
/// (`f32`) or after one Newton step with the exact residual.
#[inline(always)]
fn floor_root<const FMA: bool>(
    o: [f64; 3],
    d: [f64; 3],
    c: [f64; 3],
    r: f64,
    l: &Look,
    f32: bool,
) -> f64 {
    let t0 = l.root().0;
    if f32 {
        t0 as f32 as f64
    } else {
        let z = exact_residual::<FMA>(o, d, c, r, l, t0, NewtonTerms::PROVED);
        t0 - z.p / z.dp
    }
}
