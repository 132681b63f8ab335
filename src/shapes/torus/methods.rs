//! The ray–torus methods (seed 002 §2.5, §1.4) and the gradient normals (§3), each written once
//! over [`Real`].
//!
//! **Common contract.** The torus lies around the z axis in object space: major radius `r1`
//! (the circle in the xy plane), minor radius `r2` (the tube). The ray is `o + t·d`, `d` not
//! renormalised. Every method returns the nearest root with `t > 0`, or `None`; none panics on
//! any input. The chapter's methods ([`ferrari`], [`yuksel`], [`newton_bbox`]) do not check their
//! input; [`torus_robust`] rejects NaN/inf, `d = 0` and any shape other than a ring torus
//! (`0 < r2 < r1`).

use crate::numerics::real::gamma;
use crate::numerics::real::Real;
pub(super) use crate::numerics::vec3::dot;
use crate::shapes::oracle::poly;

type V<F> = [F; 3];

// Vector helpers over plain arrays

/// `o + t·d` with one rounding per component (fused multiply–add).
#[inline(always)]
pub(super) fn point_at<F: Real>(o: V<F>, d: V<F>, t: F) -> V<F> {
    [
        t.mul_add(d[0], o[0]),
        t.mul_add(d[1], o[1]),
        t.mul_add(d[2], o[2]),
    ]
}

#[inline(always)]
fn two<F: Real>() -> F {
    F::from_f64(2.0)
}

/// The chapter's quartic (§2.5), ascending: `c[0] + c[1]·t + … + c[4]·t⁴ = 0` for `o + t·d` on
/// `(|P|² + r1² − r2²)² = 4r1²(x² + y²)`. With `k = o·o − r1² − r2²`:
/// `a = (d·d)²`, `b = 4(d·d)(o·d)`, `c = 2(d·d)k + 4(o·d)² + 4r1²d_z²`,
/// `d = 4(o·d)k + 8r1²o_z d_z`, `e = k² − 4r1²(r2² − o_z²)`.
pub fn quartic<F: Real>(o: V<F>, d: V<F>, r1: F, r2: F) -> [F; 5] {
    let four = F::from_f64(4.0);
    let (vv, sv) = (dot(d, d), dot(o, d));
    let (r1s, r2s) = (r1 * r1, r2 * r2);
    let k = dot(o, o) - r1s - r2s;
    let four_r1s = four * r1s;
    [
        k * k - four_r1s * (r2s - o[2] * o[2]),
        four * sv * k + two::<F>() * four_r1s * o[2] * d[2],
        two::<F>() * vv * k + four * sv * sv + four_r1s * d[2] * d[2],
        four * vv * sv,
        vv * vv,
    ]
}

/// The smallest strictly positive finite value of an ascending list of roots.
fn first_positive<F: Real>(roots: &[F]) -> Option<F> {
    roots
        .iter()
        .copied()
        .filter(|t| t.is_finite() && *t > F::ZERO)
        .fold(None, |m: Option<F>, t| match m {
            Some(b) if b <= t => Some(b),
            _ => Some(t),
        })
}

/// **Ferrari**: the chapter's quartic (§2.5) solved by the chapter's closed form (§1.3,
/// [`poly::quartic_ferrari`]); the smallest positive root.
pub fn ferrari<F: Real>(o: V<F>, d: V<F>, r1: F, r2: F) -> Option<F> {
    first_positive(&poly::quartic_ferrari(quartic(o, d, r1, r2)))
}

/// **Yuksel**: the chapter's quartic solved by the robust polynomial solver
/// ([`poly::poly_roots_robust`], Yuksel's bracketed Newton); the smallest positive root.
pub fn yuksel<F: Real>(o: V<F>, d: V<F>, r1: F, r2: F) -> Option<F> {
    first_positive(&poly::poly_roots_robust(&quartic(o, d, r1, r2)))
}

/// The parameter interval `[t_in, t_out]` of the ray inside the box `|x|,|y| ≤ h[0]`, `|z| ≤ h[2]`
/// (slab test), or `None` when the ray misses it or it lies behind. A zero direction component
/// is handled explicitly (no `0·∞`).
pub(super) fn slab<F: Real>(o: V<F>, d: V<F>, h: V<F>) -> Option<(F, F)> {
    let (mut t_in, mut t_out) = (-F::INFINITY, F::INFINITY);
    for i in 0..3 {
        if d[i] == F::ZERO {
            // Parallel to the slab: inside it or a miss
            if o[i].abs() > h[i] || o[i].is_nan() {
                return None;
            }
            continue;
        }
        let (a, b) = ((-h[i] - o[i]) / d[i], (h[i] - o[i]) / d[i]);
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        t_in = if a > t_in { a } else { t_in };
        t_out = if b < t_out { b } else { t_out };
    }
    if t_in <= t_out && t_out >= F::ZERO {
        Some((t_in, t_out))
    } else {
        None
    }
}

/// The chapter's bounding box of the torus: half-sizes `r1 + r2, r1 + r2, r2`.
fn bbox<F: Real>(r1: F, r2: F) -> V<F> {
    [r1 + r2, r1 + r2, r2]
}

/// Horner's value and derivative of an ascending polynomial at `t`.
#[inline(always)]
fn horner<F: Real>(c: &[F; 5], t: F) -> (F, F) {
    let (mut p, mut dp) = (c[4], F::ZERO);
    for &ci in c[..4].iter().rev() {
        dp = dp * t + p;
        p = p * t + ci;
    }
    (p, dp)
}

/// Newton iterations [`newton_bbox`] allows before it gives up.
pub const NEWTON_MAX_ITER: usize = 64;

/// **Newton from the bounding box** (§1.4's suggestion for the torus): clip the ray to the box
/// `[−(r1+r2), r1+r2]² × [−r2, r2]`, start at the entry `t` (0 when the origin is inside), and
/// run Newton on the chapter's quartic until a step is below 4 ulps of `t`.
/// - A hit if, after at most [`NEWTON_MAX_ITER`] steps, the last step is below `2^(−p/2)·t`
///   (converged, or oscillating at the quartic's rounding noise) and `t > 0` lies in the box
///   interval; otherwise a miss.
/// - What can go wrong, by construction: from the entry point Newton converges to *a* root, not
///   necessarily the first (it can step over a thin part of the tube, or over a tube it grazes),
///   and it stalls or diverges near a minimum of the quartic that does not reach zero.
pub fn newton_bbox<F: Real>(o: V<F>, d: V<F>, r1: F, r2: F) -> Option<F> {
    let (t_in, t_out) = slab(o, d, bbox(r1, r2))?;
    let c = quartic(o, d, r1, r2);
    let mut t = if t_in > F::ZERO { t_in } else { F::ZERO };
    let tol = F::from_f64(4.0) * gamma::<F>(1);
    let mut step = F::INFINITY;
    for _ in 0..NEWTON_MAX_ITER {
        let (p, dp) = horner(&c, t);
        step = p / dp;
        if !step.is_finite() {
            return None;
        }
        t = t - step;
        if step.abs() <= tol * t.abs() {
            break;
        }
    }
    // Converged, or oscillating at the rounding noise of the quartic (half the digits)
    let noise = F::from_f64(2f64.powi(-(F::MANT_BITS as i32) / 2));
    let slack = tol * t_out.abs();
    (step.abs() <= noise * t.abs() && t > F::ZERO && t >= t_in - slack && t <= t_out + slack)
        .then_some(t)
}

/// Whether the inputs describe a valid ray and a ring torus: all finite, `d ≠ 0`, `0 < r2 < r1`.
/// (`r2 ≥ r1` is a horn or spindle torus, whose surface self-intersects: rejected as degenerate.)
pub fn is_valid<F: Real>(o: V<F>, d: V<F>, r1: F, r2: F) -> bool {
    let all = [o[0], o[1], o[2], d[0], d[1], d[2], r1, r2];
    all.iter().all(|x| x.is_finite()) && d.iter().any(|&x| x != F::ZERO) && r2 > F::ZERO && r2 < r1
}

/// The torus as a signed distance: `√((ρ − r1)² + z²) − r2`, with `ρ = √(x² + y²)` (exact
/// distance to the surface; negative inside the tube). Its zeros are the quartic's real zeros,
/// since the quartic factors as `((ρ−r1)² + z² − r2²)·((ρ+r1)² + z² − r2²)` and the second factor
/// is positive for a ring torus.
#[inline(always)]
pub(super) fn sdf<F: Real>(p: V<F>, r1: F, r2: F) -> F {
    let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
    let u = rho - r1;
    (u * u + p[2] * p[2]).sqrt() - r2
}

/// **The outward normal** at a surface point, not normalised: `p − c`, with `c` the nearest
/// point of the major circle, `c = r1·(x, y, 0)/ρ`. On the surface this is the gradient of the
/// torus function divided by `8·r1·ρ` (a positive factor), and its length is `r2`, but it is
/// evaluated without the cancellation of `|p|² − r1² − r2²` that the plain gradient
/// ([`gradient`]) suffers at the top and bottom of the tube. On the z axis (`ρ = 0`, not on any
/// ring torus) it returns `(0, 0, z)`.
pub fn torus_normal<F: Real>(p: V<F>, r1: F, _r2: F) -> V<F> {
    let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
    if rho.partial_cmp(&F::ZERO) != Some(std::cmp::Ordering::Greater) {
        return [F::ZERO, F::ZERO, p[2]];
    }
    let s = (rho - r1) / rho;
    [p[0] * s, p[1] * s, p[2]]
}

/// **The chapter's gradient** (§3) of `f = (|p|² − r1² − r2²)² − 4r1²(r2² − z²)`, divided by 4:
/// `(x·k, y·k, z·(k + 2r1²))` with `k = |p|² − r1² − r2²`.
pub fn gradient<F: Real>(p: V<F>, r1: F, r2: F) -> V<F> {
    let k = dot(p, p) - r1 * r1 - r2 * r2;
    [p[0] * k, p[1] * k, p[2] * (k + two::<F>() * r1 * r1)]
}

/// `v / |v|`.
pub fn normalize<F: Real>(v: V<F>) -> V<F> {
    let len = dot(v, v).sqrt();
    [v[0] / len, v[1] / len, v[2] / len]
}

/// Newton steps [`torus_robust`] takes on the distance function.
const REFINE_STEPS: usize = 3;

/// **Robust**: the project's anchor; the nearest `t > 0` of [`torus_robust_hit`].
pub fn torus_robust<F: Real>(o: V<F>, d: V<F>, r1: F, r2: F) -> Option<F> {
    torus_robust_hit(o, d, r1, r2).map(|(t, _)| t)
}

/// `K` of the bound `γ(K)·(r1 + r2)` on every component of [`torus_robust_hit`]'s point (the
/// reintersection test's error bound): the largest `|sdf(p)|/(ε(r1 + r2))` measured on the
/// robust hits of every class, with a margin of two (`tests/torus.rs`).
pub const ERR_GAMMA: u32 = 32;

/// **Robust** hit: `t` and the hit point, computed near the torus.
///
/// 0. Reject invalid input ([`is_valid`]); scale the direction by a power of two to unit size
///    (exact, and `t` is scaled back), so that `(d·d)²` cannot overflow or underflow.
/// 1. Reject rays that miss the bounding box, padded by a few ulps so that rounding cannot clip
///    a real hit.
/// 2. Shift the origin to the box entry (Mitsuba's plane shift, applied to the torus):
///    `o' = o + t_s·d` with one rounding per component (fused multiply–add), `t_s = max(t_in, 0)`.
///    A rounded `t_s` only slides `o'` along the ray, and `|o'| ≲ 1.8(r1 + r2)`, so the quartic's
///    coefficients no longer carry the `|o|⁴`-sized cancellation of a far origin, and `o'` is
///    off the true ray by half an ulp of `r1 + r2`, not of `|o|`. Then scale positions by a
///    power of two to `r1 ≈ 1` (exact), so no fourth power of a tiny or huge torus leaves the
///    format's range.
/// 3. Solve the shifted quartic with the robust solver ([`poly::poly_roots_robust`]).
/// 4. Refine each root `t'` (ascending) by Newton on the **signed distance** (`sdf`) at
///    `p = o' + t'·d` (fused): the distance has a unit gradient and none of the cancellation
///    between the quartic's large terms, so the far roots of the shifted quartic gain the
///    accuracy its Horner form loses. A step is kept only while it shrinks `|sdf|` and moves
///    `t'` by less than `2^(−p/2)` of the box length (a longer step would jump to the other root
///    of a near-double pair).
/// 5. The first `t = t_s + t' > 0` is the hit; `p` is returned with it (accurate to a few ulps
///    of `r1 + r2` even when `|o|` is large, which the normal needs).
pub fn torus_robust_hit<F: Real>(o: V<F>, d: V<F>, r1: F, r2: F) -> Option<(F, V<F>)> {
    if !is_valid(o, d, r1, r2) {
        return None;
    }
    // (0) Direction scaled by a power of two to unit size: t = u·sd
    let sd = pow2_scale(
        d.iter()
            .fold(F::ZERO, |m, x| if x.abs() > m { x.abs() } else { m }),
    );
    let d = d.map(|x| x * sd);
    // (1) Padded bounding box
    let pad = F::ONE + gamma::<F>(4);
    let half = bbox(r1, r2).map(|h| h * pad);
    let (u_in, u_out) = slab(o, d, half)?;
    let g3 = two::<F>() * gamma::<F>(3);
    let u_out = u_out * (F::ONE + g3);
    // (2) Origin shifted to the box entry, then positions scaled by a power of two to r1 ≈ 1
    let u_s = if u_in > F::ZERO {
        u_in * (F::ONE - g3)
    } else {
        F::ZERO
    };
    let sp = pow2_scale(r1);
    let os = point_at(o, d, u_s).map(|x| x * sp);
    let (r1s, r2s) = (r1 * sp, r2 * sp);
    // (3) The robust solver on the shifted quartic, in scaled units v = u'·sp
    let roots = poly::poly_roots_robust(&quartic(os, d, r1s, r2s));
    // (4)–(5) Refine, first positive
    let max_step = (u_out - u_s) * sp * F::from_f64(2f64.powi(-(F::MANT_BITS as i32) / 2));
    roots
        .iter()
        .filter(|v| v.is_finite())
        .map(|&v| refine(os, d, r1s, r2s, v, max_step))
        .map(|(v, p)| ((u_s + v / sp) * sd, p.map(|x| x / sp)))
        .find(|(t, _)| t.is_finite() && *t > F::ZERO)
}

/// The power of two `2^−e` that brings `x > 0` to `[1, 2)` (`e` clamped to the format's
/// normal exponents), so that multiplying by it is exact unless a smaller value underflows.
fn pow2_scale<F: Real>(x: F) -> F {
    let emax = if F::MANT_BITS == 24 { 126.0 } else { 1022.0 };
    let e = x.to_f64().log2().floor().clamp(-emax, emax);
    F::from_f64((-e).exp2())
}

/// Newton on the signed distance along the ray from `o`, from `t` (see [`torus_robust_hit`]
/// step 4); returns `t` and `o + t·d`.
fn refine<F: Real>(o: V<F>, d: V<F>, r1: F, r2: F, mut t: F, max_step: F) -> (F, V<F>) {
    let mut p = point_at(o, d, t);
    let mut h = sdf(p, r1, r2);
    for _ in 0..REFINE_STEPS {
        let slope = dot(normalize(torus_normal(p, r1, r2)), d);
        let step = h / slope;
        if step.abs() > max_step || step.is_nan() {
            break;
        }
        let tn = t - step;
        let pn = point_at(o, d, tn);
        let hn = sdf(pn, r1, r2);
        if hn.abs() >= h.abs() || hn.is_nan() {
            break;
        }
        (t, p, h) = (tn, pn, hn);
    }
    (t, p)
}
