//! Reciprocal and reciprocal square root by Newton refinement (seed `002` §1.5,
//! "倒数和平方根的优化").
//!
//! The chapter takes a cheap approximation and refines it with Newton's method:
//! - reciprocal, the root of `f(x) = 1/x − r`: `x_{k+1} = x_k (2 − r x_k)`. Every `x_k` must stay
//!   positive (`f` has a pole at 0), which holds exactly when `0 < x_0 < 2/r`;
//! - reciprocal square root, the root of `f(y) = 1/y² − r`: `y_{k+1} = y_k (3 − r y_k²) / 2`,
//!   which needs `0 < y_0 < √(3/r)`; then `√r = r · (1/√r)` costs one multiplication.
//!
//! With the relative error `e_k = 1 − r x_k` (resp. `1 − y_k √r`) one step maps
//! `e ↦ e²` (resp. `e ↦ (3/2)e² − (1/2)e³`): each step roughly squares the error, so the number
//! of correct bits doubles. Here each is run from two starts, 0–3 steps, in `f32`, and compared
//! with the exact value from MPFR and with the plain `1/x` and `1/√x`:
//! - [`Start::Hardware`]: the x86 estimate instructions `rcpps`/`rsqrtps` (the packed forms of
//!   `rcpss`/`rsqrtss`, same estimate per lane), documented by Intel to
//!   `|relative error| ≤ 1.5·2⁻¹²`. Other architectures get a portable stand-in, the exact value
//!   rounded to 12 significant bits (relative error ≤ 2⁻¹², within the same bound).
//! - [`Start::Bits`]: integer arithmetic on the float's bit pattern ([`BitTrick`]).
//!
//! **Error measure.** For an input `x` with exact value `v` (`1/x` or `1/√x`) and an answer `a`,
//! the error is `|a − v| / ulp_f32(v)` ulps, where `ulp_f32(v) = 2^(⌊log₂ v⌋ − 23)` is the
//! spacing of `f32` values in the binade of `v` ([`ulp_f32_at`]). `v` is MPFR's value of
//! `1/x` (resp. `1/√x`) correctly rounded to `f64`; the difference from the true `v` is at most
//! 2⁻²⁹ ulp_f32, and a correctly rounded `f32` answer still measures ≤ 0.5 exactly (the `f32`
//! midpoints are `f64` values and rounding is monotone). NaN answers count as infinitely wrong.
//!
//! **Scale invariance.** Every method here commutes with scaling by powers of two as long as
//! inputs, results and intermediates stay normal: `approx(x·2^k) = approx(x)·2^−k` for the
//! reciprocal, `approx(x·4^k) = approx(x)·2^−k` for the reciprocal square root (the bit tricks
//! subtract exponent fields, the hardware tables read only the significand, and in a Newton step
//! `r·x` is unchanged). So one binade, `[1, 2)`, covers every normal reciprocal input, and two,
//! `[1, 4)`, every reciprocal square root input (its answer depends on the exponent's parity).
//! [`table`] goes through all of them; the tests check the invariance on other binades.

use crate::numerics::real::{hex_float, Real, Scalar};
use crate::numerics::timing::{self, Timing};
use rayon::prelude::*;
use rug::{Assign, Float};
use serde::Serialize;

/// Which function is approximated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Func {
    /// `1/x`.
    Rcp,
    /// `1/√x`.
    Rsqrt,
}

impl Func {
    /// Both functions, `rcp` first.
    pub const ALL: [Func; 2] = [Func::Rcp, Func::Rsqrt];

    /// `rcp` or `rsqrt`.
    pub fn name(self) -> &'static str {
        match self {
            Func::Rcp => "rcp",
            Func::Rsqrt => "rsqrt",
        }
    }

    /// The inputs the table covers, `[lo, hi)`: one binade for `1/x`, two for `1/√x`.
    pub fn range(self) -> (f32, f32) {
        match self {
            Func::Rcp => (1.0, 2.0),
            Func::Rsqrt => (1.0, 4.0),
        }
    }

    /// The exact value at `x`, correctly rounded to `f64` by MPFR, in a caller's scratch `Float`
    /// (so that a loop allocates once).
    pub fn exact_with(self, x: f32, scratch: &mut Float) -> f64 {
        scratch.set_prec(53);
        scratch.assign(x);
        match self {
            Func::Rcp => scratch.recip_mut(),
            Func::Rsqrt => scratch.recip_sqrt_mut(),
        }
        scratch.to_f64()
    }

    /// The exact value at `x`, correctly rounded to `f64` (MPFR).
    pub fn exact(self, x: f32) -> f64 {
        self.exact_with(x, &mut Float::new(53))
    }

    /// The exact values of many inputs, in parallel.
    pub fn exact_all(self, xs: &[f32]) -> Vec<f64> {
        xs.par_iter()
            .map_init(|| Float::new(53), |s, &x| self.exact_with(x, s))
            .collect()
    }

    /// `k` in the chapter's start condition `0 < x₀ < k·v`: 2 for `1/x`, √3 for `1/√x`.
    pub fn start_limit(self) -> f64 {
        match self {
            Func::Rcp => 2.0,
            Func::Rsqrt => 3f64.sqrt(),
        }
    }

    /// One Newton step from `x` towards this function of `r` (see [`rcp_step`], [`rsqrt_step`]).
    #[inline(always)]
    pub fn step<S: Scalar>(self, r: S, x: S) -> S {
        match self {
            Func::Rcp => rcp_step(r, x),
            Func::Rsqrt => rsqrt_step(r, x),
        }
    }
}

/// Where the Newton iteration starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Start {
    /// The hardware estimate (`rcpps`/`rsqrtps` on x86_64; a portable stand-in elsewhere).
    Hardware,
    /// The bit trick ([`rcp_bits`], [`rsqrt_bits`]).
    Bits,
}

impl Start {
    /// Both starts, hardware first.
    pub const ALL: [Start; 2] = [Start::Hardware, Start::Bits];

    /// `hardware` or `bits`.
    pub fn name(self) -> &'static str {
        match self {
            Start::Hardware => "hardware",
            Start::Bits => "bits",
        }
    }
}

/// Whether [`Start::Hardware`] is the real instruction (x86_64) or the portable stand-in.
pub const HARDWARE_IS_NATIVE: bool = hw::NATIVE;

/// One way to compute `1/x` or `1/√x` in `f32`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// The reference way: `1.0 / x` or `1.0 / x.sqrt()`.
    Reference(Func),
    /// A start refined by `steps` Newton steps.
    Newton {
        /// The function approximated.
        func: Func,
        /// Where the iteration starts.
        start: Start,
        /// Newton steps after the start (0: the start alone).
        steps: u32,
    },
}

/// The most Newton steps the table and [`eval_slice`] run.
pub const MAX_STEPS: u32 = 3;

impl Variant {
    /// Every variant, in the order the table lists them: per function, the reference way, then
    /// each start with 0..=3 steps.
    pub fn all() -> Vec<Variant> {
        Func::ALL
            .into_iter()
            .flat_map(|func| {
                std::iter::once(Variant::Reference(func)).chain(Start::ALL.into_iter().flat_map(
                    move |start| {
                        (0..=MAX_STEPS).map(move |steps| Variant::Newton { func, start, steps })
                    },
                ))
            })
            .collect()
    }

    /// The function the variant computes.
    pub fn func(self) -> Func {
        match self {
            Variant::Reference(f) | Variant::Newton { func: f, .. } => f,
        }
    }

    /// `"division"` or `"sqrt"` for the reference ways, else the start's name.
    pub fn start_name(self) -> &'static str {
        match self {
            Variant::Reference(Func::Rcp) => "division",
            Variant::Reference(Func::Rsqrt) => "sqrt",
            Variant::Newton { start, .. } => start.name(),
        }
    }

    /// Newton steps (`None` for the reference ways).
    pub fn steps(self) -> Option<u32> {
        match self {
            Variant::Reference(_) => None,
            Variant::Newton { steps, .. } => Some(steps),
        }
    }

    /// `rcp division`, `rsqrt bits+2`, ….
    pub fn label(self) -> String {
        match self.steps() {
            None => format!("{} {}", self.func().name(), self.start_name()),
            Some(s) => format!("{} {}+{s}", self.func().name(), self.start_name()),
        }
    }

    /// The documented bound on the relative error `|a − v| / v` over normal inputs.
    ///
    /// - `1/x`: 2⁻²⁴, correct rounding (IEEE 754).
    /// - `1/√x`: 2·2⁻²⁴ and a little, two correct roundings (`√`, then `/`).
    /// - hardware start: 1.5·2⁻¹² (Intel SDM, RCPSS/RSQRTSS: "|Relative Error| ≤ 1.5 ∗ 2⁻¹²").
    /// - bit-trick start: [`bits_start_bound`], derived from the magic constant.
    /// - each step: `e ↦ e² + ρ` (`1/x`) or `e ↦ (3/2)e² + (1/2)e³ + ρ` (`1/√x`), where
    ///   `ρ = 4·2⁻²⁴` allows for the step's three or four roundings (each ≤ 2⁻²⁴ relative,
    ///   entering with weight at most about 1; the cross terms are far below the spare 2⁻²⁴).
    pub fn bound_rel(self) -> f64 {
        let u = f32_unit_roundoff();
        match self {
            Variant::Reference(Func::Rcp) => u,
            Variant::Reference(Func::Rsqrt) => 2.0 * u + u * u,
            Variant::Newton { func, start, steps } => {
                let e0 = match start {
                    Start::Hardware => 1.5 * 2f64.powi(-12),
                    Start::Bits => bits_start_bound::<f32>(func),
                };
                refined_bound(func, e0, steps, u)
            }
        }
    }

    /// The documented bound in ulps (the table's measure): 0.5 for the division (correct
    /// rounding), 1.5 for `1/√x` (0.5 for the division plus < 1 from the rounded `√`), otherwise
    /// [`Variant::bound_rel`]` · 2²⁴` (since `v / ulp_f32(v) < 2²⁴`).
    pub fn bound_ulps(self) -> f64 {
        match self {
            Variant::Reference(Func::Rcp) => 0.5,
            Variant::Reference(Func::Rsqrt) => 1.5,
            Variant::Newton { .. } => self.bound_rel() * 2f64.powi(24),
        }
    }
}

/// The relative error bound after `steps` Newton steps from a start within `e0`, each step
/// computed in a format of unit roundoff `u`: `e ↦ e² + 4u` (`1/x`) or
/// `e ↦ (3/2)e² + (1/2)e³ + 4u` (`1/√x`).
///
/// Why `4u` holds for one step (normal operands, no overflow): for `1/x` with `x = (1 − e)/r`,
/// `fl(r x) = (1 − e)(1 + δ₁)`, `2 − fl(r x)` rounds by `δ₂` and the product by `δ₃`, so the
/// result is `(1/r)(1 − e² − δ₁(1 − e)²)(1 + δ₂)(1 + δ₃)`: relative error
/// `≤ e² + u(1 + |e|)² + 2u + O(u²)`, within `e² + 4u` while `|e| ≤ 0.4`. For `1/√x` with
/// `y = (1 − e)/√r`, `(r y) y` rounds twice, `3 − ·` once, `y · (·)` once and `· 0.5` is exact:
/// `(1/√r)(1 − (3/2)e² + (1/2)e³ − (1 − e)³(δ₁ + δ₂)/2)(1 + δ₃)(1 + δ₄)`, within
/// `(3/2)e² + (1/2)|e|³ + 4u` while `|e| ≤ 0.25`. The bit-trick starts are within 0.051 (`1/x`)
/// and 0.035 (`1/√x`), [`bits_start_bound`], and each step shrinks the error.
pub fn refined_bound(func: Func, e0: f64, steps: u32, u: f64) -> f64 {
    (0..steps).fold(e0, |e, _| match func {
        Func::Rcp => e * e + 4.0 * u,
        Func::Rsqrt => 1.5 * e * e + 0.5 * e * e * e + 4.0 * u,
    })
}

/// The proven bound of `bits+k` in `F` on normal inputs (every intermediate normal), in the
/// audit's measure: the ordinal distance, in ulps of `F`, from the correctly rounded value
/// ([`crate::numerics::exact::ulps`]).
///
/// With `ε` = [`refined_bound`] from [`bits_start_bound`], `u = 2⁻ᵖ`, the answer `a` and the
/// rounded value `v̂` of `v`: `|a − v̂| ≤ εv + u·v` (`v̂` is within half an ulp, `≤ u v`), and
/// between `min(a, v̂) ≥ v(1 − ε − u)` and `max(a, v̂)` consecutive values are at least
/// `min(a, v̂)·u` apart (a spacing `2^(e−p+1)` in the binade `[2^e, 2^(e+1))` exceeds `x·2⁻ᵖ`).
/// So the distance is at most `(ε + u) / ((1 − ε − u) u)` ulps, rounded up here. This is what
/// `src/audit/tolerances.toml` holds `rcp`/`rsqrt` `bits+k` to, in both precisions.
pub fn bits_bound_ulps<F: BitTrick>(func: Func, steps: u32) -> u64 {
    let u = 2f64.powi(-(F::MANT_BITS as i32));
    let e = refined_bound(func, bits_start_bound::<F>(func), steps, u);
    ((e + u) / ((1.0 - e - u) * u)).ceil() as u64
}

/// 2⁻²⁴, the relative rounding error bound of `f32`.
fn f32_unit_roundoff() -> f64 {
    2f64.powi(-(f32::MANT_BITS as i32))
}

// ---- the formulas, written once ----

/// One Newton step for `1/r`: `x (2 − r x)`.
#[inline(always)]
pub fn rcp_step<S: Scalar>(r: S, x: S) -> S {
    x * (S::from_f64(2.0) - r * x)
}

/// One Newton step for `1/√r`, as the chapter writes it: `y (3 − r y²) / 2`.
#[inline(always)]
pub fn rsqrt_step<S: Scalar>(r: S, y: S) -> S {
    y * (S::from_f64(3.0) - r * y * y) * S::from_f64(0.5)
}

/// A binary format with bit-trick starts.
pub trait BitTrick: Real {
    /// `bits(1/x) ≈ RCP_MAGIC − bits(x)`.
    const RCP_MAGIC: u64;
    /// `bits(1/√x) ≈ RSQRT_MAGIC − (bits(x) >> 1)`.
    const RSQRT_MAGIC: u64;
}

impl BitTrick for f32 {
    /// `0x7EF311C3`: Michal Drobot, ShaderFastMathLib.h (2014, "Low Level Optimizations for AMD
    /// GCN"), `IEEE_INT_RCP_CONST_NR1`, "derived from batch testing" (its NR0 constant
    /// `0x7EF311C2` differs by one unit).
    const RCP_MAGIC: u64 = 0x7EF3_11C3;
    /// `0x5f3759df`: Quake III Arena, `Q_rsqrt` in q_math.c (1999); analysed by C. Lomont,
    /// "Fast Inverse Square Root" (2003).
    const RSQRT_MAGIC: u64 = 0x5f37_59df;
}

impl BitTrick for f64 {
    /// `0x7FDE623822FC16E6`: P. Khuong, "0x7FDE623822FC16E6: a magic constant for double float
    /// reciprocal" (2011).
    const RCP_MAGIC: u64 = 0x7FDE_6238_22FC_16E6;
    /// `0x5fe6ec85e7de30da`: C. Lomont, "Fast Inverse Square Root" (2003), the 64-bit constant.
    const RSQRT_MAGIC: u64 = 0x5fe6_ec85_e7de_30da;
}

/// The bit-trick start for `1/x`: the bit pattern subtracted from a magic constant, which
/// negates the exponent and approximates the significand's reciprocal linearly.
#[inline(always)]
pub fn rcp_bits<F: BitTrick>(x: F) -> F {
    F::from_bits_u64(F::RCP_MAGIC.wrapping_sub(x.to_bits_u64()))
}

/// The bit-trick start for `1/√x`: half the bit pattern subtracted from a magic constant.
#[inline(always)]
pub fn rsqrt_bits<F: BitTrick>(x: F) -> F {
    F::from_bits_u64(F::RSQRT_MAGIC.wrapping_sub(x.to_bits_u64() >> 1))
}

/// The bit-trick start for either function.
#[inline(always)]
pub fn bits_start<F: BitTrick>(func: Func, x: F) -> F {
    match func {
        Func::Rcp => rcp_bits(x),
        Func::Rsqrt => rsqrt_bits(x),
    }
}

/// The largest relative error of the bit-trick start over normal inputs, derived from the
/// magic constant (no sampling).
///
/// On a binade the trick is piecewise linear in the significand `m ∈ [0, 1)`: with
/// `q = bits⁻¹(MAGIC − bits(1))` for `1/x` written `2^e (1 + μ)`, the start is
/// `2^e (1 + μ − m)` while `m ≤ μ` and `2^(e−1) (2 + μ − m)` after the borrow; for `1/√x` the
/// same with `m/2` in place of `m`, on the even binade (`q` from `bits(1) >> 1`) and the odd one
/// (`q` from `bits(2) >> 1`). The scaled answer `z(m) = start · (1+m)` (resp.
/// `start · √(g(1+m))`, `g ∈ {1, 2}`) has the form `c (a − s m) (1+m)^p`, whose extremes lie at
/// the piece ends or at `m* = (p a − s) / (s (1 + p))`. The result is the largest `|z − 1|`
/// there, plus one unit of the last place for `>> 1` dropping a bit.
pub fn bits_start_bound<F: BitTrick>(func: Func) -> f64 {
    let frac = 2f64.powi(-(F::MANT_BITS as i32 - 1));
    let one = F::ONE.to_bits_u64();
    // q = 2^e (1 + μ) for a bit pattern
    let split = |bits: u64| -> (f64, f64) {
        let q = F::from_bits_u64(bits).to_f64();
        let e = q.log2().floor();
        (2f64.powf(e), q / 2f64.powf(e) - 1.0)
    };
    // Largest |c (a − s m) g^p (1+m)^p − 1| on [lo, hi]
    let piece = |c: f64, a: f64, s: f64, g: f64, p: f64, lo: f64, hi: f64| -> f64 {
        let z = |m: f64| c * (a - s * m) * (g * (1.0 + m)).powf(p) - 1.0;
        let vertex = ((p * a - s) / (s * (1.0 + p))).clamp(lo, hi);
        [lo, hi, vertex]
            .map(|m| z(m).abs())
            .into_iter()
            .fold(0.0, f64::max)
    };
    // Both pieces of one binade: before and after the borrow at m = μ/s
    let binade = |q_bits: u64, s: f64, g: f64, p: f64| -> f64 {
        let (c, mu) = split(q_bits);
        let knee = mu / s;
        let before = piece(c, 1.0 + mu, s, g, p, 0.0, knee.min(1.0));
        // No borrow within the binade when the knee lies beyond it
        let after = if knee < 1.0 {
            piece(0.5 * c, 2.0 + mu, s, g, p, knee.max(0.0), 1.0)
        } else {
            0.0
        };
        before.max(after)
    };
    match func {
        Func::Rcp => binade(F::RCP_MAGIC.wrapping_sub(one), 1.0, 1.0, 1.0),
        Func::Rsqrt => {
            let two = F::from_f64(2.0).to_bits_u64();
            let even = binade(F::RSQRT_MAGIC.wrapping_sub(one >> 1), 0.5, 1.0, 0.5);
            let odd = binade(F::RSQRT_MAGIC.wrapping_sub(two >> 1), 0.5, 2.0, 0.5);
            even.max(odd) + 2.0 * frac
        }
    }
}

// ---- the hardware estimate ----

#[cfg(target_arch = "x86_64")]
mod hw {
    use std::arch::x86_64::{_mm_loadu_ps, _mm_rcp_ps, _mm_rsqrt_ps, _mm_storeu_ps};
    pub const NATIVE: bool = true;

    /// `rcpps` on four lanes.
    #[inline(always)]
    pub fn rcp4(x: [f32; 4]) -> [f32; 4] {
        let mut out = [0f32; 4];
        // SAFETY: SSE is part of the x86_64 baseline; both pointers address four f32s.
        unsafe { _mm_storeu_ps(out.as_mut_ptr(), _mm_rcp_ps(_mm_loadu_ps(x.as_ptr()))) };
        out
    }

    /// `rsqrtps` on four lanes.
    #[inline(always)]
    pub fn rsqrt4(x: [f32; 4]) -> [f32; 4] {
        let mut out = [0f32; 4];
        // SAFETY: as in rcp4.
        unsafe { _mm_storeu_ps(out.as_mut_ptr(), _mm_rsqrt_ps(_mm_loadu_ps(x.as_ptr()))) };
        out
    }
}

#[cfg(not(target_arch = "x86_64"))]
mod hw {
    pub const NATIVE: bool = false;

    /// The stand-in estimate: `v` rounded to 12 significant bits (relative error ≤ 2⁻¹²).
    fn round12(v: f32) -> f32 {
        let drop = 24 - 12;
        let b = v.to_bits();
        f32::from_bits((b.wrapping_add(1 << (drop - 1))) & !((1u32 << drop) - 1))
    }

    #[inline(always)]
    pub fn rcp4(x: [f32; 4]) -> [f32; 4] {
        x.map(|v| round12(1.0 / v))
    }

    #[inline(always)]
    pub fn rsqrt4(x: [f32; 4]) -> [f32; 4] {
        x.map(|v| round12(1.0 / v.sqrt()))
    }
}

/// The hardware estimate of one value (see [`Start::Hardware`]).
pub fn hardware_estimate(func: Func, x: f32) -> f32 {
    let v = [x; 4];
    match func {
        Func::Rcp => hw::rcp4(v)[0],
        Func::Rsqrt => hw::rsqrt4(v)[0],
    }
}

// ---- evaluation over slices ----

/// `out` and the input differ in length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{input} inputs but room for {output} outputs")]
pub struct LengthMismatch {
    /// Inputs given.
    pub input: usize,
    /// Room for outputs.
    pub output: usize,
}

/// `f` over four lanes at a time (the estimate instructions' width on the x86_64 baseline);
/// the tail is padded with ones.
#[inline(always)]
fn map4(xs: &[f32], out: &mut [f32], f: impl Fn([f32; 4]) -> [f32; 4]) {
    let mut xc = xs.chunks_exact(4);
    let mut oc = out.chunks_exact_mut(4);
    for (x, o) in (&mut xc).zip(&mut oc) {
        o.copy_from_slice(&f([x[0], x[1], x[2], x[3]]));
    }
    // Tail
    let rest = xc.remainder();
    if !rest.is_empty() {
        let mut pad = [1f32; 4];
        pad[..rest.len()].copy_from_slice(rest);
        oc.into_remainder().copy_from_slice(&f(pad)[..rest.len()]);
    }
}

/// `f` on every element, as a plain loop the compiler vectorises.
#[inline(always)]
fn map1(xs: &[f32], out: &mut [f32], f: impl Fn(f32) -> f32) {
    for (o, &x) in out.iter_mut().zip(xs) {
        *o = f(x);
    }
}

/// Inputs per block: the start values of a block are written, then refined in place while
/// still in L1.
const BLOCK: usize = 256;

/// One Newton variant over a slice, monomorphised per step count: per block, the start pass,
/// then `STEPS` steps per element.
fn run_newton<const STEPS: u32>(func: Func, start: Start, xs: &[f32], out: &mut [f32]) {
    for (x, o) in xs.chunks(BLOCK).zip(out.chunks_mut(BLOCK)) {
        // Start values
        match (func, start) {
            (Func::Rcp, Start::Hardware) => map4(x, o, hw::rcp4),
            (Func::Rsqrt, Start::Hardware) => map4(x, o, hw::rsqrt4),
            (Func::Rcp, Start::Bits) => map1(x, o, rcp_bits::<f32>),
            (Func::Rsqrt, Start::Bits) => map1(x, o, rsqrt_bits::<f32>),
        }
        // Refinement; the function is a literal in each arm so the step is resolved statically
        let refine = |f: Func, o: &mut [f32]| {
            for (y, &r) in o.iter_mut().zip(x) {
                for _ in 0..STEPS {
                    *y = f.step(r, *y);
                }
            }
        };
        match func {
            Func::Rcp => refine(Func::Rcp, o),
            Func::Rsqrt => refine(Func::Rsqrt, o),
        }
    }
}

/// Computes `out[i] ≈ 1/xs[i]` (or `1/√xs[i]`) by `v`. Any input is accepted (zero, negative,
/// NaN, subnormal, infinite give whatever the formula gives); step counts above
/// [`MAX_STEPS`] are clamped to it.
pub fn eval_slice(v: Variant, xs: &[f32], out: &mut [f32]) -> Result<(), LengthMismatch> {
    if xs.len() != out.len() {
        return Err(LengthMismatch {
            input: xs.len(),
            output: out.len(),
        });
    }
    match v {
        Variant::Reference(Func::Rcp) => map1(xs, out, |x| 1.0 / x),
        Variant::Reference(Func::Rsqrt) => map1(xs, out, |x| 1.0 / x.sqrt()),
        Variant::Newton { func, start, steps } => match steps {
            0 => run_newton::<0>(func, start, xs, out),
            1 => run_newton::<1>(func, start, xs, out),
            2 => run_newton::<2>(func, start, xs, out),
            _ => run_newton::<3>(func, start, xs, out),
        },
    }
    Ok(())
}

/// One value by `v` (see [`eval_slice`]).
pub fn eval(v: Variant, x: f32) -> f32 {
    let mut out = [0f32];
    // Lengths match by construction
    let _ = eval_slice(v, &[x], &mut out);
    out[0]
}

// ---- accuracy ----

/// `ulp_f32(v) = 2^(⌊log₂|v|⌋ − 23)`, the spacing of `f32` values in the binade of `v`
/// (2⁻¹⁴⁹ below the normal range; NaN for NaN and infinite `v`).
pub fn ulp_f32_at(v: f64) -> f64 {
    if !v.is_finite() {
        return f64::NAN;
    }
    let a = v.abs();
    if a < f32::MIN_POSITIVE as f64 {
        return 2f64.powi(-149);
    }
    let e = ((a.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    2f64.powi(e - 23)
}

/// Accuracy of one variant over a set of inputs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Accuracy {
    /// Inputs evaluated.
    pub inputs: u64,
    /// Largest error in ulps (infinite if any answer is NaN).
    pub max_ulps: f64,
    /// The input with the largest error (the first such), and its answer.
    pub worst_input: f32,
    /// The answer at `worst_input`.
    pub worst_output: f32,
    /// Mean error in ulps.
    pub mean_ulps: f64,
    /// Largest relative error `|a − v| / v`.
    pub max_rel: f64,
}

impl Accuracy {
    fn empty() -> Self {
        Accuracy {
            inputs: 0,
            max_ulps: 0.0,
            worst_input: f32::NAN,
            worst_output: f32::NAN,
            mean_ulps: 0.0,
            max_rel: 0.0,
        }
    }

    /// Combines two disjoint sets, `self` first (keeps the first worst input on ties).
    fn merge(self, o: Accuracy) -> Accuracy {
        let n = self.inputs + o.inputs;
        let (worst_input, worst_output, max_ulps) = if o.max_ulps > self.max_ulps {
            (o.worst_input, o.worst_output, o.max_ulps)
        } else {
            (self.worst_input, self.worst_output, self.max_ulps)
        };
        Accuracy {
            inputs: n,
            max_ulps,
            worst_input,
            worst_output,
            mean_ulps: if n == 0 {
                0.0
            } else {
                (self.mean_ulps * self.inputs as f64 + o.mean_ulps * o.inputs as f64) / n as f64
            },
            max_rel: self.max_rel.max(o.max_rel),
        }
    }
}

/// Inputs evaluated together when measuring accuracy.
const CHUNK: usize = 4096;

/// The accuracy of `v` on `xs` against their exact values `exact` (from [`Func::exact_all`]),
/// in parallel. Extra elements of the longer slice are ignored.
pub fn accuracy(v: Variant, xs: &[f32], exact: &[f64]) -> Accuracy {
    let n = xs.len().min(exact.len());
    xs[..n]
        .par_chunks(CHUNK)
        .zip(exact[..n].par_chunks(CHUNK))
        .map(|(x, e)| {
            let mut a = vec![0f32; x.len()];
            let _ = eval_slice(v, x, &mut a);
            let mut acc = Accuracy::empty();
            let mut sum = 0.0;
            // Per input error in ulps at the exact value
            for i in 0..x.len() {
                let err = (a[i] as f64 - e[i]).abs();
                let ulps = nan_to_inf(err / ulp_f32_at(e[i]));
                let rel = nan_to_inf(err / e[i].abs());
                sum += ulps;
                acc.max_rel = acc.max_rel.max(rel);
                if ulps > acc.max_ulps || acc.worst_input.is_nan() {
                    (acc.max_ulps, acc.worst_input, acc.worst_output) = (ulps, x[i], a[i]);
                }
            }
            acc.inputs = x.len() as u64;
            acc.mean_ulps = sum / x.len() as f64;
            acc
        })
        .reduce(Accuracy::empty, Accuracy::merge)
}

fn nan_to_inf(x: f64) -> f64 {
    if x.is_nan() {
        f64::INFINITY
    } else {
        x
    }
}

// ---- the table ----

/// How much of the range, and how long to time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NewtonOpts {
    /// Every `stride`-th `f32` of the range (1: all of them; 0 is taken as 1).
    pub stride: u32,
    /// Length of the fixed timed array.
    pub timed_len: usize,
    /// Timed runs per variant (the median is reported).
    pub runs: usize,
    /// Minimum duration of one run, in nanoseconds.
    pub min_ns: f64,
}

impl NewtonOpts {
    /// Every input: 2²³ for `1/x`, 2²⁴ for `1/√x`. What the report uses.
    pub fn exhaustive() -> Self {
        NewtonOpts {
            stride: 1,
            timed_len: 4096,
            runs: 15,
            min_ns: 2e5,
        }
    }

    /// Every 97th input and short timing, for tests.
    pub fn fast() -> Self {
        NewtonOpts {
            stride: 97,
            timed_len: 4096,
            runs: 3,
            min_ns: 2e4,
        }
    }
}

/// One row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct NewtonRow {
    /// The variant.
    pub variant: Variant,
    /// `rcp` or `rsqrt`.
    pub function: &'static str,
    /// `hardware`, `bits`, or for the reference ways `division` / `sqrt`.
    pub start: &'static str,
    /// Newton steps; `None` for the reference ways.
    pub steps: Option<u32>,
    /// Whether a hardware start is the real instruction.
    pub native: bool,
    /// Inputs evaluated.
    pub inputs: u64,
    /// Largest error in ulps (infinite if any answer is NaN).
    pub max_ulps: f64,
    /// The first input with the largest error, and its answer, as hex floats.
    pub worst_input: String,
    /// The answer at `worst_input`, as a hex float.
    pub worst_output: String,
    /// Mean error in ulps.
    pub mean_ulps: f64,
    /// Largest relative error `|a − v| / v`.
    pub max_rel: f64,
    /// [`Variant::bound_ulps`].
    pub bound_ulps: f64,
    /// Nanoseconds per value over the fixed timed array.
    pub ns: Timing,
}

/// Every `stride`-th `f32` of `[lo, hi)` (both positive), in order.
pub fn inputs(lo: f32, hi: f32, stride: u32) -> Vec<f32> {
    let (a, b) = (lo.to_bits(), hi.to_bits());
    (a..b.max(a))
        .step_by(stride.max(1) as usize)
        .map(f32::from_bits)
        .collect()
}

/// `len` inputs spread evenly (by bit pattern) over the function's range: the timed array.
pub fn timed_inputs(func: Func, len: usize) -> Vec<f32> {
    let (lo, hi) = func.range();
    let span = (hi.to_bits() - lo.to_bits()) as u64;
    (0..len as u64)
        .map(|i| f32::from_bits(lo.to_bits() + (i * span / len.max(1) as u64) as u32))
        .collect()
}

/// Nanoseconds per value of `v` over `xs`.
pub fn time_variant(v: Variant, xs: &[f32], runs: usize, min_ns: f64) -> Timing {
    let mut out = vec![0f32; xs.len()];
    timing::measure(xs.len(), runs, min_ns, || {
        let _ = eval_slice(v, std::hint::black_box(xs), &mut out);
        std::hint::black_box(&mut out);
    })
}

/// The table: every [`Variant`] over every (or every `stride`-th) `f32` of its function's
/// range, against MPFR, with its time per value. The exact values are computed once per
/// function and shared by its variants.
pub fn table(opts: &NewtonOpts) -> Vec<NewtonRow> {
    let mut rows = Vec::new();
    for func in Func::ALL {
        // Exact values, once
        let (lo, hi) = func.range();
        let xs = inputs(lo, hi, opts.stride);
        let exact = func.exact_all(&xs);
        let timed = timed_inputs(func, opts.timed_len);
        // Every variant of this function
        for v in Variant::all().into_iter().filter(|v| v.func() == func) {
            let acc = accuracy(v, &xs, &exact);
            rows.push(NewtonRow {
                variant: v,
                function: func.name(),
                start: v.start_name(),
                steps: v.steps(),
                native: !matches!(
                    v,
                    Variant::Newton {
                        start: Start::Hardware,
                        ..
                    }
                ) || HARDWARE_IS_NATIVE,
                inputs: acc.inputs,
                max_ulps: acc.max_ulps,
                worst_input: hex_float(acc.worst_input as f64),
                worst_output: hex_float(acc.worst_output as f64),
                mean_ulps: acc.mean_ulps,
                max_rel: acc.max_rel,
                bound_ulps: v.bound_ulps(),
                ns: time_variant(v, &timed, opts.runs, opts.min_ns),
            });
        }
    }
    rows
}

// ---- the start-value bound ----

/// What the iteration did from one start value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Reached the exact value to within 4 ulps of `f64` at this step.
    Converged {
        /// The step that reached it (0: the start itself).
        step: usize,
    },
    /// An iterate left `(0, ∞)` (became ≤ 0 or NaN) at this step. From there the iteration no
    /// longer approaches `v`: for `1/x` it runs off to −∞; for `1/√x` it settles on the other
    /// root `−v` or blows up.
    Diverged {
        /// The step at which the iterate left `(0, ∞)` (0: the start itself).
        step: usize,
    },
    /// Neither within the steps run.
    Undecided,
}

/// The iteration from `x₀ = k·v` (`v` the exact answer), in `f64`.
#[derive(Clone, Debug, Serialize)]
pub struct StartRow {
    /// `rcp` or `rsqrt`.
    pub function: &'static str,
    /// The input `r`.
    pub r: f64,
    /// The start's multiple of the answer: `x₀ = k·v`.
    pub k: f64,
    /// The chapter's limit on `k`: 2 for `1/x`, √3 for `1/√x`.
    pub limit: f64,
    /// `0 < k < limit`.
    pub inside: bool,
    /// `x_n / v` for n = 0..=steps (1 is the root).
    pub scaled: Vec<f64>,
    /// What the iteration did.
    pub outcome: Outcome,
}

/// Runs the chapter's iterations from `x₀ = k·v` for each `k` (with `v = 1/r` or `1/√r`),
/// `steps` steps each, recording `x_n / v`: the data behind "the start must lie in
/// `(0, 2/r)`" (resp. `(0, √(3/r))`).
pub fn start_bound_demo(func: Func, r: f64, ks: &[f64], steps: usize) -> Vec<StartRow> {
    let v = match func {
        Func::Rcp => 1.0 / r,
        Func::Rsqrt => 1.0 / r.sqrt(),
    };
    ks.iter()
        .map(|&k| {
            // Iterate, recording x_n / v
            let mut x = k * v;
            let mut scaled = vec![x / v];
            for _ in 0..steps {
                x = func.step(r, x);
                scaled.push(x / v);
            }
            // First divergence or convergence
            let diverged = scaled.iter().position(|&s| s.is_nan() || s <= 0.0);
            let converged = scaled
                .iter()
                .position(|&s| (s - 1.0).abs() <= 4.0 * f64::EPSILON);
            let outcome = match (diverged, converged) {
                (Some(d), _) => Outcome::Diverged { step: d },
                (None, Some(c)) => Outcome::Converged { step: c },
                (None, None) => Outcome::Undecided,
            };
            StartRow {
                function: func.name(),
                r,
                k,
                limit: func.start_limit(),
                inside: k > 0.0 && k < func.start_limit(),
                scaled,
                outcome,
            }
        })
        .collect()
}

/// The chapter's bound as data: `k` in {0.5, 1.5, 1.99, 2.01, 3} for `1/x` and
/// {0.5, 1.5, 1.73, 1.74, 3} for `1/√x` (√3 ≈ 1.732), `r = 3`, 24 steps (starts near the
/// limit need about 20: the first step lands near 0).
pub fn start_bound_table() -> Vec<StartRow> {
    let mut rows = start_bound_demo(Func::Rcp, 3.0, &[0.5, 1.5, 1.99, 2.01, 3.0], 24);
    rows.extend(start_bound_demo(
        Func::Rsqrt,
        3.0,
        &[0.5, 1.5, 1.73, 1.74, 3.0],
        24,
    ));
    rows
}
