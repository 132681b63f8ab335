//! Ray–triangle (seed 002 §2.1): the chapter's plane-then-barycentrics method, Möller–Trumbore,
//! and the watertight test of Woop, Benthin & Wald (2013) as pbrt-v4 implements it; an exact
//! oracle; the hard-case classes; the closed-mesh watertightness test (issue 6 item 3) and the
//! hit point the reintersection test ([`crate::audit::robustness::reintersect`]) spawns rays from.
//!
//! **Contract.** A case is `o d p0 p1 p2` (15 scalars). The answer is a hit (count 1) when the
//! ray `o + t·d` meets the *closed* triangle (edges and vertices included) at some `t > 0`;
//! value = `t`. A ray parallel to the plane (`N·d = 0`, including a ray lying in the plane) is a
//! miss, as in the chapter ("如果L.V = 0,那么就不会相交"). Invalid input (NaN/inf, `d = 0`, or a
//! degenerate triangle with `(p1−p0)×(p2−p0) = 0` exactly) must be rejected.
//!
//! **Oracle.** Every input is an integer times a power of two; scaled by one common power of two
//! (which leaves `t` unchanged) they are GMP integers, and everything below is exact:
//! `N = (p1−p0)×(p2−p0)`, `t = N·(p0−o) / N·d`, and the edge functions
//! `eᵢ = d·((pⱼ−o)×(pₖ−o))` (cyclic), whose sum is `N·d`. The ray meets the closed triangle iff
//! every `eᵢ` is 0 or has the sign of `N·d`. `t` is rounded once from the exact rational.
//! **Ill-posed**: the count changes when one of the 15 inputs moves by one ulp of its precision,
//! up or down (30 single moves, each evaluated exactly; a move that makes the input invalid
//! counts as a miss). Joint moves of several inputs are not tried.

use super::shape::generate as gen_case;
use crate::numerics::exact::{self, decompose, nudge, round_q};
use crate::numerics::real::gamma;
use crate::numerics::real::{Real, Scalar};
use crate::numerics::vec3::{add, cross, dot, scale, sub};
use crate::numerics::Precision;
use crate::shapes::oracle::ulp_box::{strict_sign as sign_on_box, ulp_box, BoxIv};
use crate::shapes::shape::{Answer, Domain, Expected, MethodInfo, Shape, ShapeInfo, Truth};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rug::{Integer, Rational};

use std::cmp::Ordering;

type V<S> = [S; 3];

// ---- vector helpers over plain arrays (f32, f64, double-double) ----

#[inline(always)]
fn vabs<S: Scalar>(a: V<S>) -> V<S> {
    [a[0].abs(), a[1].abs(), a[2].abs()]
}
#[inline(always)]
fn vmax<S: Scalar>(a: V<S>) -> S {
    let m = if a[0] > a[1] { a[0] } else { a[1] };
    if m > a[2] {
        m
    } else {
        a[2]
    }
}
fn all_finite<F: Real>(o: V<F>, d: V<F>, p: &[V<F>; 3]) -> bool {
    o.iter()
        .chain(&d)
        .chain(p.iter().flatten())
        .all(|x| x.is_finite())
}

/// A hit: the ray parameter and the barycentric weights `(b0, b1, b2)` of the hit point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit<F> {
    /// The ray parameter of the hit.
    pub t: F,
    /// Barycentric weights of the hit point (they sum to 1).
    pub b: [F; 3],
}

// ---- the methods ----

/// **Chapter** (seed 002 §2.1), as written: `N = (P1−P0)×(P2−P0)`, the 4-D plane
/// `L = ⟨N, −N·P0⟩`, `t = −(L·S)/(L·V)` (miss when `L·V = 0`), the point `R = S + tV`, then
/// `w1, w2` from the 2×2 system with `Q1 = P1−P0`, `Q2 = P2−P0`, `R' = R−P0`:
/// `[w1 w2] = [[Q2², −Q1·Q2], [−Q1·Q2, Q1²]]·[R'·Q1, R'·Q2] / (Q1²Q2² − (Q1·Q2)²)`;
/// inside iff `w1 ≥ 0`, `w2 ≥ 0`, `w1 + w2 ≤ 1`. The shape's `t > 0` is tested on `t`
/// (`!(t > 0)`, so a NaN `t` is a miss). No other guard: a degenerate triangle gives `L·V = 0`.
pub fn chapter_hit<F: Real>(o: V<F>, d: V<F>, p: [V<F>; 3]) -> Option<TriHit<F>> {
    let (q1, q2) = (sub(p[1], p[0]), sub(p[2], p[0]));
    // Plane L = (N, −N·P0)
    let n = cross(q1, q2);
    let lw = -dot(n, p[0]);
    let lv = dot(n, d);
    if lv == F::ZERO {
        return None;
    }
    let t = -(dot(n, o) + lw) / lv;
    if t.partial_cmp(&F::ZERO) != Some(Ordering::Greater) {
        return None;
    }
    // Barycentrics of R = S + tV by the 2×2 system
    let r = sub(add(o, scale(d, t)), p[0]);
    let (q11, q22, q12) = (dot(q1, q1), dot(q2, q2), dot(q1, q2));
    let inv = F::ONE / (q11 * q22 - q12 * q12);
    let (rq1, rq2) = (dot(r, q1), dot(r, q2));
    let w1 = inv * (q22 * rq1 - q12 * rq2);
    let w2 = inv * (q11 * rq2 - q12 * rq1);
    if w1 >= F::ZERO && w2 >= F::ZERO && w1 + w2 <= F::ONE {
        Some(TriHit {
            t,
            b: [F::ONE - w1 - w2, w1, w2],
        })
    } else {
        None
    }
}

/// The determinant threshold of Möller & Trumbore's paper (`#define EPSILON 0.000001`).
pub const MT_EPSILON: f64 = 1e-6;

/// **Möller–Trumbore** (JGT 1997, the non-culling branch of the paper's code): `E1 = P1−P0`,
/// `E2 = P2−P0`, `P = D×E2`, `det = E1·P`, miss if `|det| < ε` with the paper's absolute
/// `ε = 1e-6`; `T = O−P0`, `u = T·P/det ∈ [0,1]`, `Q = T×E1`, `v = D·Q/det ≥ 0`, `u+v ≤ 1`,
/// `t = E2·Q/det`. The paper returns `t` without a range test; the shape's `t > 0` is added.
pub fn moller_trumbore_hit<F: Real>(o: V<F>, d: V<F>, p: [V<F>; 3]) -> Option<TriHit<F>> {
    let (e1, e2) = (sub(p[1], p[0]), sub(p[2], p[0]));
    // Determinant, rejected near zero by the absolute epsilon
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    let eps = F::from_f64(MT_EPSILON);
    if det > -eps && det < eps {
        return None;
    }
    let inv = F::ONE / det;
    // First barycentric
    let tv = sub(o, p[0]);
    let u = dot(tv, pv) * inv;
    if u < F::ZERO || u > F::ONE {
        return None;
    }
    // Second barycentric and t
    let qv = cross(tv, e1);
    let v = dot(d, qv) * inv;
    if v < F::ZERO || u + v > F::ONE {
        return None;
    }
    let t = dot(e2, qv) * inv;
    if t.partial_cmp(&F::ZERO) != Some(Ordering::Greater) {
        return None;
    }
    Some(TriHit {
        t,
        b: [F::ONE - u - v, u, v],
    })
}

/// pbrt-v4's `DifferenceOfProducts`: `a·b − c·d` by Kahan's FMA pair.
#[inline(always)]
fn dop_fma<F: Real>(a: F, b: F, c: F, d: F) -> F {
    let cd = c * d;
    let diff = a.mul_add(b, -cd);
    let err = (-c).mul_add(d, cd);
    diff + err
}

/// `a·b − c·d` evaluated in the wider type and rounded once: `f64` for `f32` (the products of
/// two `f32` are exact in `f64`, so the sign is exact, as in pbrt's double fallback), and
/// double-double for `f64` (products of two `f64` are exact by FMA `two_prod`; the
/// double-double difference of the two exact products has the exact sign).
#[inline(always)]
fn dop_wide<F: Real>(a: F, b: F, c: F, d: F) -> F {
    F::narrow(a.widen() * b.widen() - c.widen() * d.widen())
}

/// The unit roundoff the watertight error bounds use for a type (pbrt's `gamma`).
fn gamma_of<S: Scalar>(eps: f64, n: u32) -> S {
    let ne = n as f64 * eps;
    S::from_f64(ne / (1.0 - ne))
}

/// Woop–Benthin–Wald in pbrt-v4's form (`IntersectTriangle`, shapes.cpp), over any scalar:
/// `eps` is the unit roundoff of `S` (for its `gamma`), `dop` evaluates `a·b − c·d`, `refine`
/// re-evaluates the three edge functions when one is exactly 0. `pbrt_units`: pbrt's `Δt`
/// bound as written, whose `δx, δy` add the largest *sheared* `z` (scaled by `1/d_z`) to the
/// unscaled `x, y`; otherwise the unscaled `z`, which is what the error of `x + S_x·z` depends
/// on (the two agree for unit `d`; for `|d| ≪ 1` pbrt's bound is huge and rejects real hits).
fn woop<S: Scalar>(
    o: V<S>,
    d: V<S>,
    p: [V<S>; 3],
    eps: f64,
    pbrt_units: bool,
    dop: impl Fn(S, S, S, S) -> S,
    refine: impl Fn(S, S, S, S) -> S,
) -> Option<TriHit<S>> {
    let zero = S::ZERO;
    // Degenerate triangle
    let ng = cross(sub(p[2], p[0]), sub(p[1], p[0]));
    if dot(ng, ng) == zero {
        return None;
    }
    // Translate to the ray origin
    let mut pt = [sub(p[0], o), sub(p[1], o), sub(p[2], o)];
    // Permute so that the largest |d| component is z
    let ad = vabs(d);
    let kz = if ad[0] > ad[1] {
        if ad[0] > ad[2] {
            0
        } else {
            2
        }
    } else if ad[1] > ad[2] {
        1
    } else {
        2
    };
    let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
    let perm = |v: V<S>| [v[kx], v[ky], v[kz]];
    let d = perm(d);
    pt = pt.map(perm);
    // Shear x, y so that the ray runs along +z
    let (sx, sy, sz) = (-d[0] / d[2], -d[1] / d[2], S::ONE / d[2]);
    for v in &mut pt {
        v[0] = v[0] + sx * v[2];
        v[1] = v[1] + sy * v[2];
    }
    // Edge functions, re-evaluated at higher precision when one is exactly 0
    let [a, b, c] = pt;
    let edges = |f: &dyn Fn(S, S, S, S) -> S| {
        [
            f(b[0], c[1], b[1], c[0]),
            f(c[0], a[1], c[1], a[0]),
            f(a[0], b[1], a[1], b[0]),
        ]
    };
    let mut e = edges(&dop);
    if e.contains(&zero) {
        e = edges(&refine);
    }
    // Edge and determinant tests
    if e.iter().any(|&x| x < zero) && e.iter().any(|&x| x > zero) {
        return None;
    }
    let det = e[0] + e[1] + e[2];
    if det == zero {
        return None;
    }
    // Scaled hit distance and its sign against det
    let z = [a[2] * sz, b[2] * sz, c[2] * sz];
    let t_scaled = e[0] * z[0] + e[1] * z[1] + e[2] * z[2];
    if (det < zero && t_scaled >= zero) || (det > zero && t_scaled <= zero) {
        return None;
    }
    // Barycentrics and t
    let inv_det = S::ONE / det;
    let bary = e.map(|x| x * inv_det);
    let t = t_scaled * inv_det;
    // Conservative t > 0: pbrt's delta_t bound
    let max_z = vmax(vabs(z));
    let max_x = vmax(vabs([a[0], b[0], c[0]]));
    let max_y = vmax(vabs([a[1], b[1], c[1]]));
    let max_zxy = if pbrt_units {
        max_z
    } else {
        vmax(vabs([a[2], b[2], c[2]]))
    };
    let g = |n| gamma_of::<S>(eps, n);
    let delta_z = g(3) * max_z;
    let delta_x = g(5) * (max_x + max_zxy);
    let delta_y = g(5) * (max_y + max_zxy);
    let two = S::from_f64(2.0);
    let delta_e = two * (g(2) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    let max_e = vmax(vabs(e));
    let delta_t = S::from_f64(3.0)
        * (g(3) * max_e * max_z + delta_e * max_z + delta_z * max_e)
        * inv_det.abs();
    // NaN-safe form of pbrt's `t <= deltaT` rejection
    if t.partial_cmp(&delta_t) != Some(Ordering::Greater) {
        return None;
    }
    Some(TriHit { t, b: bary })
}

/// **Watertight** (Woop, Benthin & Wald 2013; pbrt-v4 `IntersectTriangle`): translate to the
/// origin, permute so that the largest `|d|` axis is z, shear, FMA edge functions
/// (`DifferenceOfProducts`); when an edge function is exactly 0 all three are re-evaluated in the
/// wider type (`dop_wide`: `f64` for `f32` as in pbrt, double-double for `f64`); conservative
/// `t > Δt`. Additions to pbrt, for bad input only: non-finite input is rejected up front, and
/// the `t` test is written NaN-safe.
pub fn watertight_hit<F: Real>(o: V<F>, d: V<F>, p: [V<F>; 3]) -> Option<TriHit<F>> {
    if !all_finite(o, d, &p) {
        return None;
    }
    let eps = 0.5 * 2f64.powi(1 - F::MANT_BITS as i32);
    woop(o, d, p, eps, true, dop_fma::<F>, dop_wide::<F>)
}

/// The renderer's ray–triangle test: [`watertight_hit`]'s `t` (nearest `t > 0`, or `None`).
pub fn watertight<F: Real>(o: [F; 3], d: [F; 3], p: [[F; 3]; 3]) -> Option<F> {
    watertight_hit(o, d, p).map(|h| h.t)
}

/// The unit roundoff bound used for the wider type: `2⁻⁵³` for `f64`, `2⁻¹⁰⁰` for
/// double-double (its operations are accurate to a small multiple of `2⁻¹⁰⁴`).
fn wide_eps<F: Real>() -> f64 {
    if F::MANT_BITS == 24 {
        2f64.powi(-53)
    } else {
        2f64.powi(-100)
    }
}

/// **Watertight, promoted**: the same algorithm run entirely in the wider type (`f64` for `f32`
/// inputs, double-double for `f64`), `t` and the barycentrics rounded once. The audit's robust
/// anchor: its rounding errors are ~2⁻²⁹ (f32) or ~2⁻⁴⁷ (f64) of what a one-ulp move of an input
/// does, so only ill-posed cases can flip; its range covers the huge and tiny classes. Its `Δt`
/// uses consistent units (see `woop`), so tiny directions keep their hits, while rays in the
/// plane, whose `det` is rounding noise, are still rejected.
pub fn watertight_wide_hit<F: Real>(o: V<F>, d: V<F>, p: [V<F>; 3]) -> Option<TriHit<F>> {
    if !all_finite(o, d, &p) {
        return None;
    }
    let w = |v: V<F>| v.map(|x| x.widen());
    let plain = |a: F::Wide, b: F::Wide, c: F::Wide, d: F::Wide| a * b - c * d;
    let h = woop(w(o), w(d), p.map(w), wide_eps::<F>(), false, plain, plain)?;
    let t = F::narrow(h.t);
    // A t that underflows to 0 in F is no longer a hit at t > 0
    (t > F::ZERO).then(|| TriHit {
        t,
        b: h.b.map(F::narrow),
    })
}

/// A ray–triangle method over one precision.
pub type TriFn<F> = fn(V<F>, V<F>, [V<F>; 3]) -> Option<TriHit<F>>;

/// The methods, in audit order.
pub const METHODS: [MethodInfo; 4] = [
    MethodInfo {
        name: "chapter",
        robust: false,
        about: "seed 002 §2.1: plane L=(N,−N·P0), t=−(L·S)/(L·V), barycentrics by the 2×2 system",
    },
    MethodInfo {
        name: "moller_trumbore",
        robust: false,
        about: "Möller & Trumbore 1997, non-culling, |det| < 1e-6 rejected",
    },
    MethodInfo {
        name: "watertight",
        robust: false,
        about: "Woop/Benthin/Wald 2013 as pbrt-v4: shear, FMA edge functions, wide fallback at 0",
    },
    MethodInfo {
        name: "watertight_wide",
        robust: true,
        about: "the watertight algorithm evaluated in f64 (f32 inputs) or double-double (f64)",
    },
];

/// Method `m` instantiated for `F`.
pub fn method<F: Real>(m: usize) -> TriFn<F> {
    match m {
        0 => chapter_hit::<F>,
        1 => moller_trumbore_hit::<F>,
        2 => watertight_hit::<F>,
        _ => watertight_wide_hit::<F>,
    }
}

// ---- exact oracle ----

/// Finite inputs as integers after scaling all by one power of two.
fn scaled_ints(v: &[f64]) -> Vec<Integer> {
    let parts: Vec<(i64, i32)> = v.iter().map(|&x| decompose(x)).collect();
    let emin = parts
        .iter()
        .filter(|(m, _)| *m != 0)
        .map(|&(_, e)| e)
        .min()
        .unwrap_or(0);
    parts
        .iter()
        .map(|&(m, e)| Integer::from(m) << ((e - emin) as u32))
        .collect()
}

type IV = [Integer; 3];

fn isub(a: &IV, b: &IV) -> IV {
    std::array::from_fn(|i| Integer::from(&a[i] - &b[i]))
}
fn idot(a: &IV, b: &IV) -> Integer {
    Integer::from(&a[0] * &b[0]) + Integer::from(&a[1] * &b[1]) + Integer::from(&a[2] * &b[2])
}
fn icross(a: &IV, b: &IV) -> IV {
    [
        Integer::from(&a[1] * &b[2]) - Integer::from(&a[2] * &b[1]),
        Integer::from(&a[2] * &b[0]) - Integer::from(&a[0] * &b[2]),
        Integer::from(&a[0] * &b[1]) - Integer::from(&a[1] * &b[0]),
    ]
}

/// The exact outcome of one ray against one triangle.
#[derive(Clone, Debug, PartialEq)]
pub enum ExactTri {
    /// NaN or infinite input, a zero direction or a degenerate triangle.
    Invalid,
    /// No crossing with `t > 0` (or a ray parallel to the plane).
    Miss,
    /// `t = num/den > 0`; `boundary`: the crossing is on an edge or a vertex (some `eᵢ = 0`).
    Hit {
        /// Numerator of `t`.
        num: Integer,
        /// Denominator of `t` (of the same sign as `num`).
        den: Integer,
        /// The crossing is on an edge or a vertex (some edge function is 0).
        boundary: bool,
    },
}

impl ExactTri {
    fn count(&self) -> u32 {
        matches!(self, ExactTri::Hit { .. }) as u32
    }
    /// The exact `t` of a hit.
    pub fn t(&self) -> Option<Rational> {
        match self {
            ExactTri::Hit { num, den, .. } => Some(Rational::from((num.clone(), den.clone()))),
            _ => None,
        }
    }
}

/// The exact answer for the 15 inputs `o d p0 p1 p2` (any finite values; NaN/inf are invalid).
pub fn exact_tri(v: &[f64]) -> ExactTri {
    if !exact::all_finite(v) {
        return ExactTri::Invalid;
    }
    let z = scaled_ints(v);
    let vec = |i: usize| -> IV { [z[i].clone(), z[i + 1].clone(), z[i + 2].clone()] };
    let (o, d, p) = (vec(0), vec(3), [vec(6), vec(9), vec(12)]);
    // Invalid: zero direction or degenerate triangle
    let n = icross(&isub(&p[1], &p[0]), &isub(&p[2], &p[0]));
    if d.iter().all(|x| *x == 0) || n.iter().all(|x| *x == 0) {
        return ExactTri::Invalid;
    }
    // Parallel ray: a miss
    let den = idot(&n, &d);
    if den == 0 {
        return ExactTri::Miss;
    }
    // t > 0
    let num = idot(&n, &isub(&p[0], &o));
    if num.cmp0() != den.cmp0() {
        return ExactTri::Miss;
    }
    // Edge functions: all 0 or of the sign of N·d
    let r: Vec<IV> = p.iter().map(|pi| isub(pi, &o)).collect();
    let e: Vec<Integer> = (0..3)
        .map(|i| idot(&d, &icross(&r[(i + 1) % 3], &r[(i + 2) % 3])))
        .collect();
    let s = den.cmp0();
    if e.iter()
        .any(|x| x.cmp0() != s && x.cmp0() != Ordering::Equal)
    {
        return ExactTri::Miss;
    }
    let boundary = e.iter().any(|x| *x == 0);
    ExactTri::Hit { num, den, boundary }
}

/// The count (hit 1, miss or invalid 0) on the whole one-ulp box of `v`, as [`exact_tri`]
/// decides it but in interval arithmetic; `None` when a sign it rests on is uncertain there.
fn box_count(v: &[f64], prec: Precision) -> Option<u32> {
    let b = ulp_box(v, prec)?;
    let vec = |i: usize| [b[i], b[i + 1], b[i + 2]];
    let sub = |x: [BoxIv; 3], y: [BoxIv; 3]| std::array::from_fn(|i| x[i] - y[i]);
    let dot = |x: [BoxIv; 3], y: [BoxIv; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let cross = |x: [BoxIv; 3], y: [BoxIv; 3]| {
        [
            x[1] * y[2] - x[2] * y[1],
            x[2] * y[0] - x[0] * y[2],
            x[0] * y[1] - x[1] * y[0],
        ]
    };
    let (o, d, p) = (vec(0), vec(3), [vec(6), vec(9), vec(12)]);
    // N·d ≠ 0 everywhere (so d ≠ 0 and N ≠ 0: valid), of sign s
    let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let s = sign_on_box(dot(n, d))?;
    // A miss as soon as t ≤ 0 or an edge function has the other sign; a hit when all agree
    let num = sign_on_box(dot(n, sub(p[0], o)));
    let r = p.map(|pi| sub(pi, o));
    let e: Vec<Option<i8>> = (0..3)
        .map(|i| sign_on_box(dot(d, cross(r[(i + 1) % 3], r[(i + 2) % 3]))))
        .collect();
    if num == Some(-s) || e.contains(&Some(-s)) {
        return Some(0);
    }
    (num == Some(s) && e.iter().all(|&x| x == Some(s))).then_some(1)
}

/// Whether a single one-ulp move of one input changes the count (30 moves).
fn ill_posed(v: &[f64], prec: Precision, count: u32) -> bool {
    // The whole box first, then one move at a time, each decided exactly
    if box_count(v, prec) == Some(count) {
        return false;
    }
    (0..v.len()).any(|i| {
        [true, false].into_iter().any(|up| {
            let mut w = v.to_vec();
            w[i] = nudge(v[i], prec, up);
            w[i].is_finite() && exact_tri(&w).count() != count
        })
    })
}

/// The oracle's truth for a case.
pub fn truth(v: &[f64], prec: Precision) -> Truth {
    let e = exact_tri(v);
    if e == ExactTri::Invalid {
        return Truth::Invalid;
    }
    let count = e.count();
    let values = e.t().map(|t| vec![round_q(&t, prec)]).unwrap_or_default();
    Truth::Answer(Expected {
        count,
        values,
        others: vec![],
        ill_posed: ill_posed(v, prec, count),
        cap_reached: false,
        ..Default::default()
    })
}

// ---- case generation (in f64, each value rounded once to the precision) ----

fn rnd(x: f64, prec: Precision) -> f64 {
    match prec {
        Precision::F32 => x as f32 as f64,
        Precision::F64 => x,
    }
}
fn rv(v: V<f64>, prec: Precision) -> V<f64> {
    v.map(|x| rnd(x, prec))
}
fn lu(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    10f64.powf(rng.random_range(lo..hi))
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
fn ball(rng: &mut ChaCha8Rng) -> V<f64> {
    scale(unit(rng), rng.random::<f64>().cbrt())
}
/// `Σ bᵢ pᵢ` for barycentrics `(1−u−v, u, v)`.
fn bary(p: &[V<f64>; 3], u: f64, v: f64) -> V<f64> {
    std::array::from_fn(|i| (1.0 - u - v) * p[0][i] + u * p[1][i] + v * p[2][i])
}
/// A value on the grid `k·2⁻⁶`, `|k| ≤ 2¹⁰` (exact in f32, and so are its small sums).
fn grid(rng: &mut ChaCha8Rng) -> f64 {
    rng.random_range(-1024i32..=1024) as f64 / 64.0
}
fn grid_v(rng: &mut ChaCha8Rng) -> V<f64> {
    std::array::from_fn(|_| grid(rng))
}
/// `x` moved by `k` ulps of the precision (`k` may be negative).
fn move_ulps(x: f64, k: i32, prec: Precision) -> f64 {
    (0..k.unsigned_abs()).fold(x, |y, _| nudge(y, prec, k > 0))
}
fn flat(o: V<f64>, d: V<f64>, p: [V<f64>; 3]) -> Vec<f64> {
    let mut v = vec![];
    v.extend(o);
    v.extend(d);
    p.iter().for_each(|pi| v.extend(pi));
    v
}
fn nondegenerate(p: &[V<f64>; 3]) -> bool {
    let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    dot(n, n) > 1e-6 * dot(sub(p[1], p[0]), sub(p[1], p[0])).powi(2)
}

/// A triangle around `c` of size `s`, and a ray from distance `s·10^[0,2]` aimed at the
/// barycentric point `(u, v)` drawn from `[lo, hi]` (hits and misses).
fn general(
    rng: &mut ChaCha8Rng,
    c: V<f64>,
    s: f64,
    lo: f64,
    hi: f64,
) -> (V<f64>, V<f64>, [V<f64>; 3]) {
    loop {
        let p: [V<f64>; 3] = std::array::from_fn(|_| add(c, scale(ball(rng), s)));
        if !nondegenerate(&p) {
            continue;
        }
        let o = add(c, scale(unit(rng), s * lu(rng, 0.0, 2.0)));
        let target = bary(&p, rng.random_range(lo..hi), rng.random_range(lo..hi));
        return (o, sub(target, o), p);
    }
}

/// A grid triangle and a grid origin (everything exact in f32), scaled by a power of two.
fn grid_case(rng: &mut ChaCha8Rng) -> (V<f64>, [V<f64>; 3]) {
    loop {
        let p = [grid_v(rng), grid_v(rng), grid_v(rng)];
        if nondegenerate(&p) {
            return (grid_v(rng), p);
        }
    }
}

/// Moves one random component of `d` by ±1…16 ulps.
fn tilt(rng: &mut ChaCha8Rng, mut d: V<f64>, prec: Precision) -> V<f64> {
    let i = rng.random_range(0..3);
    let k = rng.random_range(1..=16) * if rng.random() { 1 } else { -1 };
    d[i] = move_ulps(d[i], k, prec);
    d
}

/// Through an edge (`vertex = false`) or a vertex: exactly on the grid, the same tilted by a few
/// ulps, or in general position with the aim point rounded.
fn edge_or_vertex(rng: &mut ChaCha8Rng, prec: Precision, vertex: bool) -> Vec<f64> {
    let pick = rng.random_range(0..3usize);
    let (i, j) = (rng.random_range(0..3usize), rng.random_range(1..3usize));
    let j = (i + j) % 3;
    if pick < 2 {
        let (o, p) = grid_case(rng);
        // An exact point of the edge: p_i + (k/8)(p_j − p_i)
        let k = if vertex {
            0.0
        } else {
            rng.random_range(1..8) as f64 / 8.0
        };
        let target = add(p[i], scale(sub(p[j], p[i]), k));
        let mut d = sub(target, o);
        if pick == 1 {
            d = tilt(rng, d, prec);
        }
        let sc = 2f64.powi(rng.random_range(-8..8));
        return flat(scale(o, sc), scale(d, sc), p.map(|v| scale(v, sc)));
    }
    let (o, _, p) = general(rng, [0.0; 3], 1.0, 0.0, 1.0);
    let (o, p) = (rv(o, prec), p.map(|v| rv(v, prec)));
    let u = if vertex { 0.0 } else { rng.random::<f64>() };
    let target = add(p[i], scale(sub(p[j], p[i]), u));
    flat(o, rv(sub(target, o), prec), p)
}

/// A ray in the plane (exactly, on the grid) or near it (tilted by ulps, or rounded).
fn parallel(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let (_, p) = grid_case(rng);
    let (e1, e2) = (sub(p[1], p[0]), sub(p[2], p[0]));
    let k = |rng: &mut ChaCha8Rng| rng.random_range(-16i32..=16) as f64 / 8.0;
    // Origin and direction as exact small combinations of the edges
    let o = add(p[0], add(scale(e1, k(rng)), scale(e2, k(rng))));
    let d = add(scale(e1, k(rng)), scale(e2, k(rng)));
    if d == [0.0; 3] {
        return parallel(rng, prec);
    }
    match rng.random_range(0..3) {
        0 => flat(o, d, p),
        1 => flat(o, tilt(rng, d, prec), p),
        _ => {
            let i = rng.random_range(0..3);
            let mut o2 = o;
            o2[i] = move_ulps(o[i], rng.random_range(1..=16), prec);
            flat(o2, tilt(rng, d, prec), p)
        }
    }
}

/// Exactly collinear or coincident vertices on the grid.
fn degenerate(rng: &mut ChaCha8Rng) -> Vec<f64> {
    let (o, p0, a) = (grid_v(rng), grid_v(rng), grid_v(rng));
    let ks = [0.0, 0.5, 2.0, -1.0, 3.0, 1.0];
    let (k1, k2) = (ks[rng.random_range(0..6)], ks[rng.random_range(0..6)]);
    let p = [p0, add(p0, scale(a, k1)), add(p0, scale(a, k2))];
    flat(o, sub(p0, o), p)
}

/// A general case with NaN/inf injected, or a zero direction.
fn invalid(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let (o, d, p) = general(rng, [0.0; 3], 1.0, 0.0, 1.0);
    let mut v = flat(o, d, p)
        .into_iter()
        .map(|x| rnd(x, prec))
        .collect::<Vec<_>>();
    match rng.random_range(0..4) {
        0 => v[3..6].fill(0.0),
        k => {
            let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][k - 1];
            let n = rng.random_range(1..=2);
            for _ in 0..n {
                let i = rng.random_range(0..15);
                v[i] = bad;
            }
        }
    }
    v
}

/// The class names, in order.
pub const CLASSES: [&str; 9] = [
    "generic",
    "edge",
    "vertex",
    "parallel",
    "degenerate",
    "huge",
    "tiny",
    "far",
    "invalid",
];

fn propose(class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let scaled = |rng: &mut ChaCha8Rng, s: f64| {
        let c = scale(unit(rng), s * rng.random_range(0.0..10.0));
        let (o, d, p) = general(rng, c, s, -0.5, 1.5);
        flat(o, d, p)
    };
    let v = match CLASSES[class] {
        "generic" => {
            let s = lu(rng, -1.0, 1.0);
            scaled(rng, s)
        }
        "edge" => edge_or_vertex(rng, prec, false),
        "vertex" => edge_or_vertex(rng, prec, true),
        "parallel" => parallel(rng, prec),
        "degenerate" => degenerate(rng),
        "huge" => {
            let s = lu(rng, 6.0, 30.0);
            scaled(rng, s)
        }
        "tiny" => {
            let s = lu(rng, -30.0, -6.0);
            scaled(rng, s)
        }
        "far" => {
            // Small, but at least a few ulps of 1e5 in f32 (1/128)
            let s = match prec {
                Precision::F32 => lu(rng, -1.5, 0.5),
                Precision::F64 => lu(rng, -3.0, 0.0),
            };
            let c = scale(unit(rng), 1e5 * rng.random_range(1.0..2.0));
            let (o, d, p) = general(rng, c, s, -0.2, 1.2);
            // Half the rays come from near the world origin
            if rng.random() {
                let o0 = ball(rng);
                flat(o0, sub(bary(&p, 0.3, 0.3), o0), p)
            } else {
                flat(o, d, p)
            }
        }
        _ => invalid(rng, prec),
    };
    v.into_iter().map(|x| rnd(x, prec)).collect()
}

// ---- the shape ----

/// The `triangle` shape of the audit.
pub struct Triangle;

const ARGS: [&str; 15] = [
    "ox", "oy", "oz", "dx", "dy", "dz", "p0x", "p0y", "p0z", "p1x", "p1y", "p1z", "p2x", "p2y",
    "p2z",
];

fn split<F: Real>(v: &[f64]) -> (V<F>, V<F>, [V<F>; 3]) {
    let x = |i: usize| -> V<F> { [v[i], v[i + 1], v[i + 2]].map(F::from_f64) };
    (x(0), x(3), [x(6), x(9), x(12)])
}

fn run_in<F: Real>(m: usize, v: &[f64]) -> Answer {
    let (o, d, p) = split::<F>(v);
    match method::<F>(m)(o, d, p) {
        Some(h) => Answer::hit(vec![h.t.to_f64()]),
        None => Answer::miss(),
    }
}

const TRIANGLE: ShapeInfo = ShapeInfo {
    name: "triangle",
    about: "ray–triangle, seed 002 §2.1 (closed triangle, t > 0)",
    args: &ARGS,
    classes: &CLASSES,
    methods: &METHODS,
    domain: Domain::RayParameter,
    ..ShapeInfo::DEFAULTS
};

impl Shape for Triangle {
    fn info(&self) -> &ShapeInfo {
        &TRIANGLE
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        // A valid class redraws a proposal that rounding made invalid (degenerate)
        let wants_valid = !matches!(CLASSES[class], "degenerate" | "invalid");
        (0..100)
            .map(|_| propose(class, prec, rng))
            .find(|v| !wants_valid || exact_tri(v) != ExactTri::Invalid)
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        truth(input, prec)
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => run_in::<F>(m, input))
    }
}

// ---- the hit point a renderer spawns rays from (reintersection test) ----

/// The hit point and its per-component error bound, as each method can justify them:
/// - `chapter` evaluates its own point `R = o + t·d`; it has no bound on the error of its `t`,
///   so it can justify only the rounding of that last step, `γ(2)·(|o| + |t·d|)`.
/// - `moller_trumbore`, `watertight`, `watertight_wide` reproject onto the triangle from their
///   barycentrics, `p = Σ bᵢpᵢ` with pbrt's bound `γ(7)·Σ|bᵢpᵢ|` (valid whatever the errors of
///   the `bᵢ`, since `Σbᵢ = 1` up to rounding).
pub(crate) fn hit_point<F: Real>(
    m: usize,
    o: V<F>,
    d: V<F>,
    p: &[V<F>; 3],
    h: &TriHit<F>,
) -> (V<F>, V<F>) {
    if m == 0 {
        let td = scale(d, h.t);
        let g = gamma::<F>(2);
        let err = std::array::from_fn(|i| g * (o[i].abs() + td[i].abs()));
        return (add(o, td), err);
    }
    let terms = [
        scale(p[0], h.b[0]),
        scale(p[1], h.b[1]),
        scale(p[2], h.b[2]),
    ];
    let pt = add(add(terms[0], terms[1]), terms[2]);
    let sum_abs = add(add(vabs(terms[0]), vabs(terms[1])), vabs(terms[2]));
    let g = gamma::<F>(7);
    (pt, scale(sum_abs, g))
}

/// Cases of a class for tests and benches (the audit's own generator, seeded per case).
pub fn cases(seed: u64, class: &str, prec: Precision, n: u64) -> Vec<Vec<f64>> {
    let k = CLASSES
        .iter()
        .position(|c| *c == class)
        .expect("known class");
    (0..n)
        .filter_map(|i| gen_case(&Triangle, seed, k, prec, i))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::exact::q;
    use rand::{Rng, SeedableRng};

    /// The wide fallback's sign of `a·b − c·d` is exact, on products that nearly cancel.
    #[test]
    fn wide_difference_of_products_has_the_exact_sign() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..20_000 {
            let (a, b): (f64, f64) = (rng.random_range(-4.0..4.0), rng.random_range(-4.0..4.0));
            let c: f64 = rng.random_range(0.5..2.0);
            // d such that c·d ≈ a·b, moved by a few ulps
            let k: i32 = rng.random_range(-3..=3);
            let d = move_ulps(a * b / c, k, Precision::F64);
            let exact = q(a) * q(b) - q(c) * q(d);
            let got = dop_wide(a, b, c, d);
            assert_eq!(
                got.partial_cmp(&0.0),
                exact.cmp0().into(),
                "{a} {b} {c} {d}"
            );
            let (a, b, c, d) = (
                a as f32,
                b as f32,
                c as f32,
                (a as f32 * b as f32) / c as f32,
            );
            let exact = q(a as f64) * q(b as f64) - q(c as f64) * q(d as f64);
            assert_eq!(dop_wide(a, b, c, d).partial_cmp(&0.0), exact.cmp0().into());
        }
    }

    /// The wide fallback has teeth. Kahan's FMA `a·b − c·d` has a relative error ≤ 2u
    /// (Jeannerod, Louvet & Muller 2013), so outside underflow its 0 is an exact 0 and the
    /// fallback finds the same 0. It decides only where the edge products underflow: an edge
    /// `b c` a subnormal distance from the ray, with the triangle close enough to the origin
    /// that pbrt's `Δt` does not reject the hit. A seeded search finds such triangles; wherever
    /// the answer with the fallback differs from the answer without it, the watertight method
    /// must agree with the exact oracle, and there must be at least one such triangle.
    #[test]
    fn wide_fallback_decides_underflowed_edge_functions() {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let (mut found, mut decided) = (0, 0);
        for _ in 0..200_000 {
            // c tiny, b nearly −k·c: the line b–c passes next to the ray
            let c: [f32; 2] = std::array::from_fn(|_| rng.random_range(1e-22f32..1e-20));
            let k: f32 = rng.random_range(0.5..2.0);
            let b: [f32; 2] = std::array::from_fn(|i| -k * c[i] * rng.random_range(0.99..1.01f32));
            let exact = (b[0] as f64) * (c[1] as f64) - (b[1] as f64) * (c[0] as f64);
            if dop_fma(b[0], c[1], b[1], c[0]) != 0.0 || exact == 0.0 {
                continue;
            }
            found += 1;
            let z: f32 = 10f32.powf(rng.random_range(-25.0..1.0));
            let dz: f32 = 10f32.powf(rng.random_range(-20.0..0.0));
            let a: [f32; 2] = [-rng.random_range(1e-21f32..1.0), 0.0];
            let tri = [[a[0], a[1], z], [b[0], b[1], z], [c[0], c[1], z]];
            let (o, d) = ([0.0f32; 3], [0.0f32, 0.0, dz]);
            let v: Vec<f64> = o
                .iter()
                .chain(&d)
                .chain(tri.iter().flatten())
                .map(|&x| x as f64)
                .collect();
            let truth = exact_tri(&v).t().is_some();
            let eps = 0.5 * 2f64.powi(-23);
            let without = woop(o, d, tri, eps, true, dop_fma::<f32>, dop_fma::<f32>).is_some();
            let with = watertight_hit(o, d, tri).is_some();
            if with != without {
                decided += 1;
                assert_eq!(with, truth, "{v:?}");
            }
        }
        println!("{found} underflowed edge functions, {decided} decided by the fallback");
        assert!(
            decided > 0,
            "no case where the fallback decides: the test has no teeth"
        );
    }

    #[test]
    fn generators_fill_every_class_with_representable_values() {
        for prec in Precision::ALL {
            for class in CLASSES {
                for v in cases(2, class, prec, 20) {
                    assert_eq!(v.len(), 15);
                    assert!(v.iter().all(|&x| exact::representable(x, prec)), "{class}");
                }
            }
        }
    }
}
