//! The ray–sphere methods, each written once over [`Real`].
//!
//! **Common contract.** Every method takes the ray as given (origin `o`, direction `d`, *not*
//! renormalised) and the sphere (centre `c`, radius `r`), and returns the nearest hit with
//! `t > 0` (the hit point is `o + t·d`) or `None` for a miss. None of them panics on any input.
//! A method that returns a non-finite `t`, or a hit on an invalid input, is reported by the audit
//! as a finding; the seed's two methods are kept exactly as written and do not guard against it.
//!
//! Conventions that differ between methods are stated in each doc comment:
//! origin exactly on the surface (`|o−c| = r`), a zero discriminant (tangent ray), a zero
//! direction, and whether a unit direction is assumed.
//!
//! Some comparisons are written negated (`!(x >= 0)`) on purpose: a NaN must take the miss branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub use super::certified::certified;
pub use super::ray::{Ray, Sphere, SphereHit};
use crate::numerics::interval::Interval;
use crate::numerics::real::{ilogb, mul_pow2, Real, Scalar};
use crate::numerics::vec3::scale;
pub(super) use crate::numerics::vec3::{dot, sub};

type V<S> = [S; 3];

// Vector helpers over plain arrays, so that the same body runs on f32, f64 and double-double.
/// `a·b + c`, fused into one rounding when `FMA` (what a C compiler's contraction makes of it),
/// else two roundings.
#[inline(always)]
pub(super) fn madd<F: Real, const FMA: bool>(a: F, b: F, c: F) -> F {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}
/// [`dot`] as a contracting compiler evaluates it when `FMA`: `fma(a₂, b₂, fma(a₁, b₁, a₀b₀))`.
#[inline(always)]
pub(super) fn dot_c<F: Real, const FMA: bool>(a: V<F>, b: V<F>) -> F {
    madd::<F, FMA>(a[2], b[2], madd::<F, FMA>(a[1], b[1], a[0] * b[0]))
}
#[inline(always)]
fn parts<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> (V<F>, V<F>, V<F>, F) {
    (
        F::unvec3(ray.origin),
        F::unvec3(ray.dir),
        F::unvec3(s.center),
        s.radius,
    )
}

/// The smaller strictly positive of two roots, as the seed's "偏小的正根" (smaller positive root).
#[inline(always)]
pub(crate) fn nearest_positive<S: Scalar>(t0: S, t1: S) -> Option<S> {
    let (a, b) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    if a > S::ZERO {
        Some(a)
    } else if b > S::ZERO {
        Some(b)
    } else {
        None
    }
}

/// **Algebraic** (textbook quadratic), seed `000` §1 and seed `002` §2.3.
///
/// `A t² + B t + C = 0` with `A = d·d`, `B = 2 d·(o−c)`, `C = |o−c|² − r²`, discriminant
/// `D = B² − 4AC`, roots `t = (−B ∓ √D) / 2A`; the smaller positive root is returned.
/// - Unit direction: not assumed (A is computed).
/// - `D = 0` (tangent): a **miss**, as the seed states ("判别式 B²−4C ≤ 0 时无交点").
/// - Origin on the surface: `C = 0`, roots `0` and `−B/A`; the `t = 0` root is not returned.
/// - `d = 0`: `A = 0`, division by zero; the roots are NaN or ±inf and are returned as computed.
pub fn algebraic<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let (o, d, c, r) = parts(ray, s);
    // Quadratic coefficients
    let f = sub(o, c);
    let a = dot(d, d);
    let b = F::from_f64(2.0) * dot(d, f);
    let cc = dot(f, f) - r * r;
    // Discriminant; the seed rejects D ≤ 0
    let disc = b * b - F::from_f64(4.0) * a * cc;
    if disc <= F::ZERO {
        return None;
    }
    // Both roots by the textbook formula
    let sq = disc.sqrt();
    let two_a = F::from_f64(2.0) * a;
    let t0 = (-b - sq) / two_a;
    let t1 = (-b + sq) / two_a;
    nearest_positive(t0, t1).and_then(SphereHit::at)
}

/// **Geometric** ("non-analytic", 非解析法), seed `000` §2, its four steps as written.
///
/// 1. `R_oc = c − o`, `L_oc = R_oc·R_oc`; the origin is inside when `L_oc < r²`.
/// 2. `d_min = R_oc·d`; if outside and `d_min < 0`, miss.
/// 3. `d_hc² = r² − L_oc + d_min²`; if outside and `d_hc² < 0`, miss.
/// 4. outside: `t = d_min − √d_hc²`; on the surface or inside: `t = d_min + √d_hc²`.
/// - Unit direction: **assumed** (the seed normalises `R_d`); other lengths give wrong `t`.
/// - `d_hc² = 0` (tangent): a hit at `t = d_min`.
/// - Origin on the surface (`L_oc = r²`): step 4's "on or inside" branch, the far root `2·d_min`.
/// - `d = 0`: `d_min = 0`, a miss from outside; from inside `t = √(r² − L_oc)`, a wrong hit.
pub fn geometric<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    geometric_body::<F, false>(ray, s)
}

/// **Geometric with FMA contraction**: [`geometric`] as a C or C++ compiler builds it with
/// contraction on (`-ffp-contract=fast`, or `on` with `-mfma`): every `a·b + c` is one fused
/// multiply-add, so `L_oc`, `d_min` and `d_hc² = (r² − L_oc) + d_min²` are rounded fewer times
/// and the bits of `t` differ from [`geometric`]'s. The audit judges it as a method of its own;
/// the batch kernels run it with hardware FMA. Conventions as [`geometric`]'s. Without hardware
/// FMA in the build, the scalar method calls the C library's `fma` (exact, slow).
pub fn geometric_fma<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    geometric_body::<F, true>(ray, s)
}

#[inline(always)]
fn geometric_body<F: Real, const FMA: bool>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let (o, d, c, r) = parts(ray, s);
    // (1) Origin relative to the sphere
    let roc = sub(c, o);
    let loc = dot_c::<F, FMA>(roc, roc);
    let r2 = r * r;
    let outside = loc > r2;
    // (2) Distance along the ray to the point nearest the centre
    let d_min = dot_c::<F, FMA>(roc, d);
    if outside && d_min < F::ZERO {
        return None;
    }
    // (3) Squared half chord
    let dhc2 = madd::<F, FMA>(d_min, d_min, r2 - loc);
    if outside && dhc2 < F::ZERO {
        return None;
    }
    // (4) First intersection
    let t = if outside {
        d_min - dhc2.sqrt()
    } else {
        d_min + dhc2.sqrt()
    };
    if t > F::ZERO {
        SphereHit::at(t)
    } else {
        None
    }
}

/// **Press** et al. (Numerical Recipes): the stable root pair of the textbook quadratic.
///
/// Same `A, B, C, D` as [`algebraic`], then `q = −½(B + sign(B)·√D)`, roots `C/q` and `q/A`.
/// Avoids the cancellation in `−B ± √D` but not the one in `D` itself.
/// - Unit direction: not assumed. `D = 0` (tangent): a hit. Origin on the surface: `C = 0` gives
///   the root `0`, which is not returned, and the other root `q/A`.
/// - `d = 0` or non-finite input: `q = 0` or NaN, and the method returns a miss.
pub fn press<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let (o, d, c, r) = parts(ray, s);
    // Quadratic coefficients, as in the textbook
    let f = sub(o, c);
    let a = dot(d, d);
    let b = F::from_f64(2.0) * dot(d, f);
    let cc = dot(f, f) - r * r;
    let disc = b * b - F::from_f64(4.0) * a * cc;
    if !(disc >= F::ZERO) {
        return None;
    }
    // Stable pair q/A, C/q
    let q = F::from_f64(-0.5) * (b + disc.sqrt().copysign(b));
    if !(q != F::ZERO) || !(a > F::ZERO) {
        return None;
    }
    nearest_positive(cc / q, q / a).and_then(finite_hit)
}

/// **Hearn & Baker** (Computer Graphics, eq. 10-72; RTG ch. 7 "method 2"): the discriminant from the
/// squared length of the perpendicular vector from the centre to the ray line.
///
/// `d̂ = d/|d|`, `Δp = c − o`, `t_ca = Δp·d̂`, `D = r² − |Δp − t_ca·d̂|²`,
/// `t = (t_ca ∓ √D)/|d|`. Avoids cancelling `|Δp|²` against `t_ca²` (the far-small-sphere loss),
/// but keeps the cancellation in `t_ca − √D` (the huge-sphere loss).
/// - Unit direction: not assumed (`d` is normalised internally). `D = 0`: a hit.
/// - Origin on the surface: the root at `t ≈ 0` is rejected only if it rounds to `≤ 0`.
/// - `d = 0` or non-finite input: NaN propagates into `D` and the method returns a miss.
pub fn hearn_baker<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let (o, d, c, r) = parts(ray, s);
    // Unit direction
    let len = dot(d, d).sqrt();
    let dh = scale(d, F::ONE / len);
    // Perpendicular vector from the centre to the ray line
    let dp = sub(c, o);
    let tca = dot(dp, dh);
    let perp = sub(dp, scale(dh, tca));
    let disc = r * r - dot(perp, perp);
    if !(disc >= F::ZERO) {
        return None;
    }
    // Both roots in units of |d|
    let sq = disc.sqrt();
    nearest_positive((tca - sq) / len, (tca + sq) / len).and_then(finite_hit)
}

/// The body of [`rtg7`], over any [`Scalar`] so that [`promote`] can run it in a wider type.
#[inline(always)]
fn rtg7_core<S: Scalar>(o: V<S>, d: V<S>, c: V<S>, r: S) -> Option<S> {
    let (t0, t1) = rtg7_roots(o, d, c, r)?;
    nearest_positive(t0, t1)
}

/// Both roots of [`rtg7`] (`c/q`, `q/a`, unordered), or `None` when there is no real pair: also
/// used by the quadrics (`routines::quadric`), which map their surface onto a sphere.
#[inline(always)]
pub(crate) fn rtg7_roots<S: Scalar>(o: V<S>, d: V<S>, c: V<S>, r: S) -> Option<(S, S)> {
    // Input guard: a radius that is not > 0 (negative, zero, NaN) is no sphere
    if !(r > S::ZERO) {
        return None;
    }
    // Quadratic a t² + 2b' t + c with b' = f·d
    let f = sub(o, c);
    let a = dot(d, d);
    let b = dot(f, d);
    let cc = dot(f, f) - r * r;
    // Discriminant from the perpendicular vector: b'² − ac = a(r² − |f − (f·d̂)d̂|²)
    let len = a.sqrt();
    let dh = [d[0] / len, d[1] / len, d[2] / len];
    let fd = sub(f, scale(dh, dot(f, dh)));
    let disc = a * (r * r - dot(fd, fd));
    if !(disc >= S::ZERO) {
        return None;
    }
    // Stable pair q/a, c/q
    let q = -b - disc.sqrt().copysign(b);
    if !(q != S::ZERO) || !(a > S::ZERO) {
        return None;
    }
    Some((cc / q, q / a))
}

/// **RTG7**: Haines, Günther & Akenine-Möller, Ray Tracing Gems ch. 7, "method 5": the
/// Hearn–Baker discriminant combined with the Press root pair, for a non-unit direction.
///
/// `b' = f·d` (f = o − c), `D = a(r² − |f − (f·d̂)d̂|²)`, `q = −b' − sign(b')√D`, roots `c/q`, `q/a`.
/// - Unit direction: not assumed. `D = 0` (tangent): a hit.
/// - Origin on the surface: `c = 0` gives the root `0`, which is not returned.
/// - `d = 0`, non-finite input, or a radius that is not `> 0`: a miss (NaN-safe guards).
pub fn rtg7<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let (o, d, c, r) = parts(ray, s);
    rtg7_core(o, d, c, r).and_then(finite_hit)
}

/// **Promote**: [`rtg7`]'s formula evaluated in the wider type (`f64` for `f32` inputs,
/// double-double for `f64` inputs) and rounded once to `F`.
///
/// Before widening, positions (o, c, r) and the direction are each scaled by an exact power of
/// two so that their largest magnitude is about 1, and `t` is scaled back at the end. This costs
/// two exponent reads and is exact, and it keeps subnormal or huge inputs from underflowing or
/// overflowing in `|d|²` and `|o−c|²` (the wider type has no more exponent range than `f64`).
/// - Conventions as [`rtg7`]; additionally a root that rounds to `0` or overflows in `F` is not returned.
pub fn promote<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let (o, d, c, r) = parts(ray, s);
    // Exact power-of-two scales for positions and direction
    let max_abs = |v: &[F]| v.iter().fold(0.0f64, |m, x| m.max(x.to_f64().abs()));
    let kp = -ilogb(max_abs(&[o[0], o[1], o[2], c[0], c[1], c[2], r]));
    let kd = -ilogb(max_abs(&d));
    let wp = |v: V<F>| v.map(|x| mul_pow2(x.widen(), kp));
    // Wide evaluation, scaled back, rounded once
    let t = rtg7_core(
        wp(o),
        d.map(|x| mul_pow2(x.widen(), kd)),
        wp(c),
        mul_pow2(r.widen(), kp),
    )?;
    let t = F::narrow(mul_pow2(t, kd - kp));
    if t > F::ZERO {
        finite_hit(t)
    } else {
        None
    }
}

/// **Interval** (pbrt-v4 `Sphere::BasicIntersect`): the whole computation in outward-rounded
/// interval arithmetic, returning the midpoint of the chosen root's interval and the interval
/// itself as a claimed enclosure of the exact root.
///
/// `a = |d|²`, `b = 2d·(o−c)`, `c = |o−c|² − r²`, `v = (o−c) − (b/2a)d`,
/// `D = 4a(r + |v|)(r − |v|)`; rejects unless `D` is surely `≥ 0`; `q = −½(b ± √D)`,
/// roots `q/a`, `c/q`; rejects unless the far root is surely `> 0`; takes the near root only if
/// it is surely `> 0`, else the far one.
/// - Unit direction: not assumed. Tangent: a hit only if the interval `D` is surely `≥ 0`.
/// - Origin on the surface: the near root's interval straddles 0, so the far root is returned.
/// - `d = 0` or non-finite input: the intervals become unbounded or NaN and the method misses;
///   a radius that is not `> 0` is rejected up front.
pub fn interval<F: Real>(ray: &Ray<F>, s: &Sphere<F>) -> Option<SphereHit<F>> {
    let (o, d, c, r) = parts(ray, s);
    if !(r > F::ZERO) {
        return None;
    }
    let p = Interval::point;
    // Ray in the sphere's frame
    let oi = [p(o[0]) - p(c[0]), p(o[1]) - p(c[1]), p(o[2]) - p(c[2])];
    let di = [p(d[0]), p(d[1]), p(d[2])];
    let ri = p(r);
    // Quadratic coefficients
    let a = di[0].square() + di[1].square() + di[2].square();
    let b = (di[0] * oi[0] + di[1] * oi[1] + di[2] * oi[2]) * F::from_f64(2.0);
    let cc = oi[0].square() + oi[1].square() + oi[2].square() - ri.square();
    // Discriminant from the perpendicular vector v
    let k = b / (a * F::from_f64(2.0));
    let v = [oi[0] - k * di[0], oi[1] - k * di[1], oi[2] - k * di[2]];
    let len = (v[0].square() + v[1].square() + v[2].square()).sqrt();
    let disc = a * F::from_f64(4.0) * (ri + len) * (ri - len);
    if !(disc.lo >= F::ZERO) {
        return None;
    }
    // Stable root pair
    let root = disc.sqrt();
    let q = if b.mid() < F::ZERO {
        (b - root) * F::from_f64(-0.5)
    } else {
        (b + root) * F::from_f64(-0.5)
    };
    let (mut t0, mut t1) = (q / a, cc / q);
    if t0.lo > t1.lo {
        std::mem::swap(&mut t0, &mut t1);
    }
    // Conservative choice of root
    if !(t1.lo > F::ZERO) {
        return None;
    }
    let t = if t0.lo > F::ZERO { t0 } else { t1 };
    let mid = t.mid();
    if !(mid.is_finite() && t.hi.is_finite()) {
        return None;
    }
    Some(SphereHit {
        t: mid,
        enclosure: Some([t.lo, t.hi]),
    })
}

#[inline(always)]
fn finite_hit<F: Real>(t: F) -> Option<SphereHit<F>> {
    if t.is_finite() {
        SphereHit::at(t)
    } else {
        None
    }
}

/// A named method with its two instantiations.
#[derive(Debug)]
pub struct Method {
    /// The method's name (`--method`, `render.method`).
    pub name: &'static str,
    /// One line: what the method is and where it comes from.
    pub summary: &'static str,
    /// Whether the method is offered as robust (held to the tolerance table's strict rows).
    pub robust: bool,
    /// The `f32` instantiation.
    pub f32: fn(&Ray<f32>, &Sphere<f32>) -> Option<SphereHit<f32>>,
    /// The `f64` instantiation.
    pub f64: fn(&Ray<f64>, &Sphere<f64>) -> Option<SphereHit<f64>>,
}

/// Picks a method's instantiation for a precision.
pub trait PickPrecision: Real {
    /// The method's instantiation for `Self`.
    fn pick(m: &Method) -> fn(&Ray<Self>, &Sphere<Self>) -> Option<SphereHit<Self>>;
}
impl PickPrecision for f32 {
    fn pick(m: &Method) -> fn(&Ray<f32>, &Sphere<f32>) -> Option<SphereHit<f32>> {
        m.f32
    }
}
impl PickPrecision for f64 {
    fn pick(m: &Method) -> fn(&Ray<f64>, &Sphere<f64>) -> Option<SphereHit<f64>> {
        m.f64
    }
}

macro_rules! method {
    ($name:ident, $robust:expr, $summary:expr) => {
        Method {
            name: stringify!($name),
            summary: $summary,
            robust: $robust,
            f32: $name::<f32>,
            f64: $name::<f64>,
        }
    };
}

/// Every ray–sphere method, in the order reports list them.
pub const METHODS: &[Method] = &[
    method!(
        algebraic,
        false,
        "textbook quadratic (seed 000 §1, seed 002 §2.3)"
    ),
    method!(
        geometric,
        false,
        "1996 non-analytic test, four steps (seed 000 §2); assumes unit d"
    ),
    method!(
        geometric_fma,
        false,
        "geometric as a compiler builds it with FMA contraction (every a*b + c fused)"
    ),
    method!(
        press,
        false,
        "stable root pair q = -(b+sign(b)sqrt(D))/2, c/q, q/a (Numerical Recipes)"
    ),
    method!(
        hearn_baker,
        false,
        "discriminant from the perpendicular vector (Hearn & Baker 10-72)"
    ),
    method!(
        rtg7,
        true,
        "perpendicular discriminant + stable pair (Ray Tracing Gems ch. 7, method 5)"
    ),
    method!(
        promote,
        true,
        "rtg7 in f64 (for f32) or double-double (for f64), rounded once"
    ),
    method!(
        certified,
        true,
        "exact verdict and correctly rounded t: a quick f64 phase with a rigorous error bound, the exact oracle's path when it cannot decide"
    ),
    method!(
        interval,
        true,
        "pbrt-v4 interval arithmetic, midpoint plus enclosure"
    ),
];

/// Looks a method up by name.
pub fn method_by_name(name: &str) -> Option<&'static Method> {
    METHODS.iter().find(|m| m.name == name)
}
