//! Ray–ellipsoid (seed 002 §2.3), ray–cylinder (§2.4) and the ellipsoid's gradient normal (§3),
//! against exact oracles.
//!
//! **Shapes.** The chapter's ellipsoid `x² + m²y² + n²z² = r²` (args `o, d, r, m, n`: semi-axes
//! `r`, `r/m`, `r/n`; `m`, `n` are the chapter's ratios of the x semi-axis to the y and z ones),
//! and its elliptic cylinder `x² + m²y² = r²`, `0 ≤ z ≤ h`, lateral surface only (args
//! `o, d, r, m, h`). Both are the unit-free sphere `|S(o + t·d)|² = r²` after the diagonal map
//! `S = diag(1, m, n)` (cylinder: `diag(1, m, 0)`), which is how the robust methods solve them.
//!
//! **Answer.** The nearest root `t > 0` (for the cylinder: whose point has `0 ≤ z ≤ h`, decided
//! exactly); a tangent ray (discriminant 0) is a hit. An origin exactly on the surface gives the
//! root `t = 0`, which is not a hit: the answer is the other root if it is positive.
//! A cylinder ray parallel to the axis (`dx = dy = 0`) never crosses the lateral surface: a miss,
//! also when it lies in the surface.
//!
//! **Invalid input**: a NaN or infinite scalar, `d = 0`, or `r`, `m`, `n` (`h`) not `> 0`.
//!
//! **Oracle.** Inputs are exact rationals, so `A = |S d|²`, `B' = S d · S o`,
//! `C = |S o|² − r²` and `Δ = B'² − AC` are exact; root signs and the cylinder's `z` range are
//! signs of `P + Q√Δ` with rational `P`, `Q`, decided exactly. Root values are enclosed with MPFR
//! in the stable form (`q = −(B' + sign(B')√Δ)`, roots `q/A`, `C/q`) and rounded by Ziv's loop.
//! **Ill-posed**: a single input moved one ulp of its precision up or down (18 moves, each
//! decided exactly) changes the count or which root is the answer (the origin crossing the
//! surface, or the near root crossing a cap plane), as in the sphere's oracle.

use super::oracle::sample::{self, add, ball, cube, lu, mul, normalize, perp, rp, rpv, sub, unit};
use crate::numerics::exact;
use crate::numerics::real::{ilogb, mul_pow2};
use crate::numerics::real::{Real, Scalar};
use crate::numerics::Precision;
use crate::shapes::oracle::ulp_box::{strict_sign as sign_on_box, ulp_box, BoxIv};
use crate::shapes::shape::{Answer, Domain, Expected, MethodInfo, Metric, Shape, ShapeInfo, Truth};
use crate::shapes::sphere::methods::{nearest_positive, rtg7_roots};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rug::float::Round;
use rug::{Float, Rational};
use std::cmp::Ordering;

type V<S> = [S; 3];

// ---- methods ----

/// Both roots, ascending, of `|o + t·d|² = r²` (a sphere at the origin) by the perpendicular
/// discriminant and the stable pair (RTG ch. 7 method 5; pbrt's `v = o − (b/2a)·d`).
#[inline(always)]
fn sphere_roots<S: Scalar>(o: V<S>, d: V<S>, r: S) -> Option<(S, S)> {
    let (a, b) = rtg7_roots(o, d, [S::ZERO; 3], r)?;
    Some(if a <= b { (a, b) } else { (b, a) })
}

/// The map `S`: `[v₀, s₁·v₁, s₂·v₂]` in the working precision.
#[inline(always)]
fn stretch<F: Real>(v: V<F>, s: V<F>) -> V<F> {
    [v[0] * s[0], v[1] * s[1], v[2] * s[2]]
}

/// `x·s` (or `x/s`) in the wide type times `2^k`, formed from exponent-normalised factors so that
/// nothing over- or underflows on the way (exact for products; a quotient is rounded once).
#[inline(always)]
fn wide_scaled<F: Real>(x: F, s: F, k: i32, div: bool) -> F::Wide {
    let (ex, es) = (ilogb(x.to_f64()), ilogb(s.to_f64()));
    let (nx, ns) = (mul_pow2(x.widen(), -ex), mul_pow2(s.widen(), -es));
    let (p, e) = if div {
        (nx / ns, ex - es)
    } else {
        (nx * ns, ex + es)
    };
    mul_pow2(p, e + k)
}

/// `ilogb(x·s)` (or of `x/s`) up to one, or `i32::MIN` for a zero product.
fn exp_of<F: Real>(x: F, s: F, div: bool) -> i32 {
    if x == F::ZERO || s == F::ZERO {
        return i32::MIN;
    }
    let (ex, es) = (ilogb(x.to_f64()), ilogb(s.to_f64()));
    if div {
        ex - es
    } else {
        ex + es
    }
}

/// Both roots (ascending, in the wide type) of `|S(o + t·d)|² = r²` where `S` multiplies
/// (or, with `div`, divides) component `i` by `s[i]` (`s[i] = 0` drops the component). The
/// stretched ray is formed in the wide type and prescaled by exact powers of two (positions and
/// radius to about 1, direction to about 1), so it is exact for products and never over- or
/// underflows; [`sphere_roots`] then runs in the wide type.
fn wide_roots<F: Real>(o: V<F>, d: V<F>, s: V<F>, r: F, div: bool) -> Option<(F::Wide, F::Wide)> {
    // Power-of-two prescale
    let ep = (0..3)
        .map(|i| exp_of(o[i], s[i], div))
        .fold(ilogb(r.to_f64()), i32::max);
    let ed = (0..3).map(|i| exp_of(d[i], s[i], div)).max()?;
    if ed == i32::MIN {
        return None;
    }
    let (kp, kd) = (-ep, -ed);
    let ow = std::array::from_fn(|i| wide_scaled(o[i], s[i], kp, div));
    let dw = std::array::from_fn(|i| wide_scaled(d[i], s[i], kd, div));
    let (t0, t1) = sphere_roots(ow, dw, mul_pow2(r.widen(), kp))?;
    // Back to the ray's own parameter
    Some((mul_pow2(t0, kd - kp), mul_pow2(t1, kd - kp)))
}

/// A root of the wide type rounded once to `F`, if it stays `> 0` and finite.
fn narrow_hit<F: Real>(t: F::Wide) -> Option<F> {
    let t = F::narrow(t);
    (t > F::ZERO && t.is_finite()).then_some(t)
}

/// Valid quadric input: finite, `d ≠ 0`, every shape parameter `> 0`.
fn valid<F: Real>(o: V<F>, d: V<F>, params: &[F]) -> bool {
    o.iter().chain(&d).chain(params).all(|x| x.is_finite())
        && d.iter().any(|&x| x != F::ZERO)
        && params.iter().all(|&p| p > F::ZERO)
}

/// The chapter's quadratic `a t² + b t + c` for the stretched ray (`s` the map's diagonal):
/// `a = Σ sᵢ²dᵢ²`, `b = 2 Σ sᵢ²oᵢdᵢ`, `c = Σ sᵢ²oᵢ² − r²`, each `sᵢ²` formed as `sᵢ·sᵢ`.
fn chapter_coefficients<F: Real>(o: V<F>, d: V<F>, s: V<F>, r: F) -> (F, F, F) {
    let s2 = s.map(|x| x * x);
    let two = F::from_f64(2.0);
    let a = s2[0] * d[0] * d[0] + s2[1] * d[1] * d[1] + s2[2] * d[2] * d[2];
    let b = two * (s2[0] * o[0] * d[0] + s2[1] * o[1] * d[1] + s2[2] * o[2] * d[2]);
    let c = s2[0] * o[0] * o[0] + s2[1] * o[1] * o[1] + s2[2] * o[2] * o[2] - r * r;
    (a, b, c)
}

/// The textbook roots `(−b ∓ √D)/2a`, `D = b² − 4ac`, or `None` when `D < 0` (as computed;
/// `D = 0` is the chapter's tangent, a hit).
fn chapter_roots<F: Real>(a: F, b: F, c: F) -> Option<(F, F)> {
    let disc = b * b - F::from_f64(4.0) * a * c;
    if disc < F::ZERO {
        return None;
    }
    let sq = disc.sqrt();
    let two_a = F::from_f64(2.0) * a;
    Some(((-b - sq) / two_a, (-b + sq) / two_a))
}

/// **Chapter** ellipsoid (§2.3): the quadratic's coefficients as the chapter gives them, the
/// textbook roots, the smaller positive one. No input guard: NaN makes every comparison fail.
pub fn ellipsoid_chapter<F: Real>(o: V<F>, d: V<F>, r: F, m: F, n: F) -> Option<F> {
    let (a, b, c) = chapter_coefficients(o, d, [F::ONE, m, n], r);
    let (t0, t1) = chapter_roots(a, b, c)?;
    nearest_positive(t0, t1)
}

/// **Perp** ellipsoid: the stretched ray `(x, m·y, n·z)` formed in the working precision, then
/// the perpendicular discriminant and stable pair of RTG ch. 7 (as the sphere's `rtg7`).
pub fn ellipsoid_perp<F: Real>(o: V<F>, d: V<F>, r: F, m: F, n: F) -> Option<F> {
    if !valid(o, d, &[r, m, n]) {
        return None;
    }
    let s = [F::ONE, m, n];
    let (t0, t1) = sphere_roots(stretch(o, s), stretch(d, s), r)?;
    nearest_positive(t0, t1).filter(|t| t.is_finite())
}

/// **Robust** ellipsoid, the anchor: [`ellipsoid_perp`]'s formula with the stretched ray formed
/// exactly in the wide type (`f64` for `f32`, double-double for `f64`) after an exact
/// power-of-two prescale, and the root rounded once. Invalid input is rejected.
pub fn ellipsoid_robust_mn<F: Real>(o: V<F>, d: V<F>, r: F, m: F, n: F) -> Option<F> {
    if !valid(o, d, &[r, m, n]) {
        return None;
    }
    let (t0, t1) = wide_roots(o, d, [F::ONE, m, n], r, false)?;
    narrow_hit::<F>(nearest_positive(t0, t1)?)
}

/// The renderer's ray–ellipsoid test: centred at 0, semi-axes `radii` along x, y, z; the nearest
/// `t > 0` or `None` (miss, invalid input). The ray is mapped onto the unit sphere in the wide
/// type (`oᵢ/radiiᵢ`, one rounding there), then solved as [`ellipsoid_robust_mn`].
pub fn ellipsoid_robust<F: Real>(o: V<F>, d: V<F>, radii: V<F>) -> Option<F> {
    if !valid(o, d, &radii) {
        return None;
    }
    let (t0, t1) = wide_roots(o, d, radii, F::ONE, true)?;
    narrow_hit::<F>(nearest_positive(t0, t1)?)
}

/// The ellipsoid's gradient `(2x/a², 2y/b², 2z/c²)` at `p` (semi-axes `radii = (a, b, c)`), not
/// normalised: the chapter's §3 normal.
pub fn ellipsoid_normal<F: Real>(p: V<F>, radii: V<F>) -> V<F> {
    std::array::from_fn(|i| F::from_f64(2.0) * p[i] / (radii[i] * radii[i]))
}

/// Whether `z = oz + t·dz` lies in `[0, h]` (in any scalar type).
#[inline(always)]
fn in_height<S: Scalar>(oz: S, dz: S, t: S, h: S) -> bool {
    let z = oz + t * dz;
    S::ZERO <= z && z <= h
}

/// The first of two ascending roots that is `> 0` and whose hit lies in `[0, h]`.
#[inline(always)]
fn first_in_height<S: Scalar>(t0: S, t1: S, oz: S, dz: S, h: S) -> Option<S> {
    [t0, t1]
        .into_iter()
        .find(|&t| t > S::ZERO && in_height(oz, dz, t, h))
}

/// **Chapter** cylinder (§2.4): its coefficients `a = dx² + m²dy²`, `b = 2(ox dx + m² oy dy)`,
/// `c = ox² + m² oy² − r²`, the textbook roots, and the first positive one whose `z` is in
/// `[0, h]` (the near root, else the far one). `dx = dy = 0` divides by zero (NaN: a miss).
pub fn cylinder_chapter<F: Real>(o: V<F>, d: V<F>, r: F, m: F, h: F) -> Option<F> {
    let (a, b, c) = chapter_coefficients(o, d, [F::ONE, m, F::ZERO], r);
    let (t0, t1) = chapter_roots(a, b, c)?;
    let (t0, t1) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    first_in_height(t0, t1, o[2], d[2], h)
}

/// **Perp** cylinder: pbrt's 2-D discriminant trick and the stable pair on the stretched
/// `(x, m·y)` in the working precision, `z` checked in the working precision.
pub fn cylinder_perp<F: Real>(o: V<F>, d: V<F>, r: F, m: F, h: F) -> Option<F> {
    if !valid(o, d, &[r, m, h]) {
        return None;
    }
    let s = [F::ONE, m, F::ZERO];
    let (t0, t1) = sphere_roots(stretch(o, s), stretch(d, s), r)?;
    first_in_height(t0, t1, o[2], d[2], h).filter(|t| t.is_finite())
}

/// **Robust** cylinder, the anchor: [`cylinder_perp`]'s formula in the wide type after the exact
/// prescale, `z` checked in the wide type, the root rounded once.
pub fn cylinder_robust_m<F: Real>(o: V<F>, d: V<F>, r: F, m: F, h: F) -> Option<F> {
    if !valid(o, d, &[r, m, h]) {
        return None;
    }
    let (t0, t1) = wide_roots(o, d, [F::ONE, m, F::ZERO], r, false)?;
    let t = first_in_height(t0, t1, o[2].widen(), d[2].widen(), h.widen())?;
    narrow_hit::<F>(t)
}

/// The renderer's ray–cylinder test: lateral surface `x² + y² = r²`, `0 ≤ z ≤ h` (chapter §2.4
/// with `m = 1`); the nearest `t > 0` whose hit is in the height range, or `None`.
pub fn cylinder_robust<F: Real>(o: V<F>, d: V<F>, r: F, h: F) -> Option<F> {
    cylinder_robust_m(o, d, r, F::ONE, h)
}

/// **Chapter** normal: the chapter's hit point `o + t·d` and gradient `(2x, 2m²y, 2n²z)`,
/// normalised, all in the working precision (`None`: no hit).
pub fn normal_chapter<F: Real>(o: V<F>, d: V<F>, r: F, m: F, n: F) -> Option<V<F>> {
    let t = ellipsoid_chapter(o, d, r, m, n)?;
    Some(gradient_unit(o, d, t, [F::ONE, m, n]))
}

/// **Robust t** normal: [`ellipsoid_robust_mn`]'s `t`, then the point and gradient as the
/// chapter forms them in the working precision (an accurate `t` is not enough far away).
pub fn normal_robust_t<F: Real>(o: V<F>, d: V<F>, r: F, m: F, n: F) -> Option<V<F>> {
    let t = ellipsoid_robust_mn(o, d, r, m, n)?;
    Some(gradient_unit(o, d, t, [F::ONE, m, n]))
}

/// `(p₀, m²p₁, n²p₂)/|…|` at `p = o + t·d`, in one scalar type.
#[inline(always)]
fn gradient_unit<S: Scalar>(o: V<S>, d: V<S>, t: S, s: V<S>) -> V<S> {
    let g: V<S> = std::array::from_fn(|i| {
        let two = S::from_f64(2.0);
        two * s[i] * s[i] * (o[i] + t * d[i])
    });
    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    g.map(|x| x / len)
}

/// **Robust** normal: the robust root, the point `o + t·d` and the gradient all in the wide type
/// (the gradient prescaled by a power of two before its length is taken), rounded once.
pub fn normal_robust<F: Real>(o: V<F>, d: V<F>, r: F, m: F, n: F) -> Option<V<F>> {
    if !valid(o, d, &[r, m, n]) {
        return None;
    }
    let (t0, t1) = wide_roots(o, d, [F::ONE, m, n], r, false)?;
    let t = nearest_positive(t0, t1)?;
    narrow_hit::<F>(t)?;
    let s = [F::ONE, m, n].map(|x| x.widen());
    let p: V<F::Wide> = std::array::from_fn(|i| o[i].widen() + t * d[i].widen());
    // Gradient to about 1 by a power of two, then normalised
    let g: V<F::Wide> = std::array::from_fn(|i| s[i] * s[i] * p[i]);
    let big = g
        .iter()
        .map(|&x| ilogb(F::narrow(x).to_f64()))
        .max()
        .unwrap_or(0);
    let g = g.map(|x| mul_pow2(x, -big));
    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    Some(g.map(|x| F::narrow(x / len)))
}

// ---- exact arithmetic ----

/// A closed MPFR interval with outward rounding.
#[derive(Clone, Debug)]
struct Iv {
    lo: Float,
    hi: Float,
}

impl Iv {
    fn q(x: &Rational, bits: u32) -> Iv {
        Iv {
            lo: Float::with_val_round(bits, x, Round::Down).0,
            hi: Float::with_val_round(bits, x, Round::Up).0,
        }
    }
    fn add(&self, o: &Iv) -> Iv {
        let bits = self.lo.prec();
        Iv {
            lo: Float::with_val_round(bits, &self.lo + &o.lo, Round::Down).0,
            hi: Float::with_val_round(bits, &self.hi + &o.hi, Round::Up).0,
        }
    }
    fn neg(&self) -> Iv {
        Iv {
            lo: -self.hi.clone(),
            hi: -self.lo.clone(),
        }
    }
    /// The hull of `a op b` over the four end-point pairs, each rounded outward.
    fn hull(&self, o: &Iv, div: bool) -> Iv {
        let bits = self.lo.prec();
        let mut lo: Option<Float> = None;
        let mut hi: Option<Float> = None;
        for a in [&self.lo, &self.hi] {
            for b in [&o.lo, &o.hi] {
                let (l, h) = if div {
                    (
                        Float::with_val_round(bits, a / b, Round::Down).0,
                        Float::with_val_round(bits, a / b, Round::Up).0,
                    )
                } else {
                    (
                        Float::with_val_round(bits, a * b, Round::Down).0,
                        Float::with_val_round(bits, a * b, Round::Up).0,
                    )
                };
                if lo.as_ref().is_none_or(|x| l < *x) {
                    lo = Some(l);
                }
                if hi.as_ref().is_none_or(|x| h > *x) {
                    hi = Some(h);
                }
            }
        }
        Iv {
            lo: lo.expect("four products"),
            hi: hi.expect("four products"),
        }
    }
    fn mul(&self, o: &Iv) -> Iv {
        self.hull(o, false)
    }
    /// Division by an interval that excludes 0.
    fn div(&self, o: &Iv) -> Iv {
        self.hull(o, true)
    }
    fn square(&self) -> Iv {
        let bits = self.lo.prec();
        let sq = |x: &Float, r| Float::with_val_round(bits, x * x, r).0;
        if self.lo >= 0 {
            Iv {
                lo: sq(&self.lo, Round::Down),
                hi: sq(&self.hi, Round::Up),
            }
        } else if self.hi <= 0 {
            Iv {
                lo: sq(&self.hi, Round::Down),
                hi: sq(&self.lo, Round::Up),
            }
        } else {
            let (a, b) = (sq(&self.lo, Round::Up), sq(&self.hi, Round::Up));
            Iv {
                lo: Float::with_val(bits, 0),
                hi: if a > b { a } else { b },
            }
        }
    }
    fn sqrt(&self) -> Iv {
        let mut lo = self.lo.clone();
        if lo < 0 {
            lo = Float::with_val(lo.prec(), 0);
        }
        let mut hi = self.hi.clone();
        lo.sqrt_round(Round::Down);
        hi.sqrt_round(Round::Up);
        Iv { lo, hi }
    }
}

/// The sign of `p + q·√Δ` (`Δ ≥ 0`), exactly.
fn sign_pq(p: &Rational, q: &Rational, disc: &Rational) -> Ordering {
    let (sp, sq) = (
        p.cmp0(),
        if disc.cmp0() == Ordering::Equal {
            Ordering::Equal
        } else {
            q.cmp0()
        },
    );
    if sq == Ordering::Equal || sp == sq {
        return sp;
    }
    if sp == Ordering::Equal {
        return sq;
    }
    // Opposite signs: the larger magnitude wins
    let pp = Rational::from(p * p);
    let qq = Rational::from(q * q) * disc;
    match pp.cmp(&qq) {
        Ordering::Greater => sp,
        Ordering::Less => sq,
        Ordering::Equal => Ordering::Equal,
    }
}

/// The exact quadratic `A t² + 2B' t + C` of a stretched ray, with `Δ = B'² − AC`.
struct Quad {
    a: Rational,
    bh: Rational,
    c: Rational,
    disc: Rational,
}

impl Quad {
    /// For `|S(o + t·d)|² = r²`, `S = diag(s)`.
    fn new(o: &[Rational; 3], d: &[Rational; 3], s: &[Rational; 3], r: &Rational) -> Quad {
        let s2: Vec<Rational> = s.iter().map(|x| Rational::from(x * x)).collect();
        let dot = |u: &[Rational; 3], v: &[Rational; 3]| -> Rational {
            (0..3).fold(Rational::new(), |acc, i| {
                acc + Rational::from(&u[i] * &v[i]) * &s2[i]
            })
        };
        let (a, bh) = (dot(d, d), dot(o, d));
        let c = dot(o, o) - Rational::from(r * r);
        let disc = Rational::from(&bh * &bh) - Rational::from(&a * &c);
        Quad { a, bh, c, disc }
    }
    fn real(&self) -> bool {
        self.a.cmp0() == Ordering::Greater && self.disc.cmp0() != Ordering::Less
    }
    /// `∓1` for root `k` (0: the smaller, `(−B' − √Δ)/A`; 1: the larger).
    fn pm(k: usize) -> Rational {
        Rational::from(if k == 0 { -1 } else { 1 })
    }
    /// The sign of root `k`.
    fn root_sign(&self, k: usize) -> Ordering {
        sign_pq(&Rational::from(-&self.bh), &Quad::pm(k), &self.disc)
    }
    /// The sign of `u + v·t_k` (for the cylinder's height): `A(u + v t) = (Au − vB') ± v√Δ`.
    fn affine_sign(&self, k: usize, u: &Rational, v: &Rational) -> Ordering {
        let p = Rational::from(&self.a * u) - Rational::from(v * &self.bh);
        sign_pq(&p, &(Quad::pm(k) * v), &self.disc)
    }
    /// An enclosure of root `k` at `bits` (stable form, no cancellation).
    fn root(&self, k: usize, bits: u32) -> Iv {
        let zero = || Iv::q(&Rational::new(), bits);
        if self.bh.cmp0() == Ordering::Equal && self.disc.cmp0() == Ordering::Equal {
            return zero();
        }
        let s = Iv::q(&self.disc, bits).sqrt();
        let b = Iv::q(&self.bh, bits);
        let (a, c) = (Iv::q(&self.a, bits), Iv::q(&self.c, bits));
        // q = −(B' + sign(B')√Δ); q/A and C/q
        let neg_b = self.bh.cmp0() != Ordering::Less;
        let q = if neg_b {
            b.add(&s).neg()
        } else {
            b.neg().add(&s)
        };
        let (qa, cq) = (q.div(&a), c.div(&q));
        match (neg_b, k) {
            (true, 0) | (false, 1) => qa,
            _ => cq,
        }
    }
    /// Root `k` correctly rounded (`None` at the cap).
    fn round_root(&self, k: usize, prec: Precision) -> Option<f64> {
        exact::ziv(prec, exact::ZIV_CAP, |bits| {
            let r = self.root(k, bits);
            (r.lo, r.hi)
        })
    }
}

/// The answer's root index: the first root `> 0` that `accept` keeps.
fn first_root(qd: &Quad, accept: impl Fn(usize) -> bool) -> Option<usize> {
    if !qd.real() {
        return None;
    }
    (0..2).find(|&k| qd.root_sign(k) == Ordering::Greater && accept(k))
}

/// Which quadric an input vector describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Ellipsoid,
    Cylinder,
}

fn qv(v: &[f64], k: usize) -> [Rational; 3] {
    [exact::q(v[k]), exact::q(v[k + 1]), exact::q(v[k + 2])]
}

fn valid_f64(v: &[f64]) -> bool {
    valid([v[0], v[1], v[2]], [v[3], v[4], v[5]], &v[6..9])
}

/// The exact quadratic and the answer's root index (`None`: miss or invalid input).
fn solve(kind: Kind, v: &[f64]) -> Option<(Quad, Option<usize>)> {
    if !valid_f64(v) {
        return None;
    }
    let (o, d) = (qv(v, 0), qv(v, 3));
    let one = Rational::from(1);
    let (r, m, third) = (exact::q(v[6]), exact::q(v[7]), exact::q(v[8]));
    let s = match kind {
        Kind::Ellipsoid => [one, m, third.clone()],
        Kind::Cylinder => [one, m, Rational::new()],
    };
    let qd = Quad::new(&o, &d, &s, &r);
    let k = first_root(&qd, |k| match kind {
        Kind::Ellipsoid => true,
        // 0 ≤ oz + t·dz ≤ h
        Kind::Cylinder => {
            let lo = qd.affine_sign(k, &o[2], &d[2]) != Ordering::Less;
            let top = Rational::from(&o[2] - &third);
            lo && qd.affine_sign(k, &top, &d[2]) != Ordering::Greater
        }
    });
    Some((qd, k))
}

/// The answer's root index, for the one-ulp moves (invalid counts as a miss).
fn key(kind: Kind, v: &[f64]) -> Option<usize> {
    solve(kind, v).and_then(|(_, k)| k)
}

/// The answer's root index on the whole one-ulp box of `v` (`Some(None)`: a miss everywhere),
/// in interval arithmetic, with `Δ = A r² − |S d × S o|²` (Lagrange's identity: no
/// cancellation far away); `None` when some sign it rests on is uncertain on the box.
fn box_key(kind: Kind, v: &[f64], prec: Precision) -> Option<Option<usize>> {
    let b = ulp_box(v, prec)?;
    // Valid everywhere: every shape parameter > 0, some direction component ≠ 0
    if !b[6..9].iter().all(|x| x.lo > 0.0) || !b[3..6].iter().any(|&x| sign_on_box(x).is_some()) {
        return None;
    }
    let third = match kind {
        Kind::Ellipsoid => b[8],
        Kind::Cylinder => BoxIv::point(0.0),
    };
    let s = [BoxIv::point(1.0), b[7], third];
    let u: [BoxIv; 3] = std::array::from_fn(|i| s[i] * b[i]);
    let w: [BoxIv; 3] = std::array::from_fn(|i| s[i] * b[3 + i]);
    let sq = |x: &[BoxIv; 3]| x[0].square() + x[1].square() + x[2].square();
    let cross = [
        w[1] * u[2] - w[2] * u[1],
        w[2] * u[0] - w[0] * u[2],
        w[0] * u[1] - w[1] * u[0],
    ];
    let (a, r2) = (sq(&w), b[6].square());
    let bh = w[0] * u[0] + w[1] * u[1] + w[2] * u[2];
    let c = sq(&u) - r2;
    let disc = a * r2 - sq(&cross);
    if sign_on_box(a)? < 0 {
        return None;
    }
    // Real roots, and which of them are > 0
    let candidates: &[usize] = match (sign_on_box(disc)?, sign_on_box(c)?) {
        (-1, _) => return Some(None),
        (_, -1) => &[1],
        _ if sign_on_box(bh)? < 0 => &[0, 1],
        _ => return Some(None),
    };
    if kind == Kind::Ellipsoid {
        return Some(Some(candidates[0]));
    }
    // The cylinder: the first candidate whose z is in [0, h], each decided on the box
    let root = BoxIv::sqrt(disc);
    let q = match sign_on_box(bh)? {
        1 => -(bh + root),
        _ => root - bh,
    };
    let (qa, cq) = (q / a, c / q);
    let (t0, t1) = if q.hi < 0.0 { (qa, cq) } else { (cq, qa) };
    for &k in candidates {
        let z = b[2] + [t0, t1][k] * b[5];
        match (sign_on_box(z)?, sign_on_box(z - b[8])?) {
            (1, -1) => return Some(Some(k)),
            _ => continue,
        }
    }
    Some(None)
}

fn ill_posed(kind: Kind, v: &[f64], base: Option<usize>, prec: Precision) -> bool {
    // The whole box first, then one move at a time, each decided exactly
    if box_key(kind, v, prec) == Some(base) {
        return false;
    }
    (0..v.len()).any(|i| {
        [true, false].into_iter().any(|up| {
            let mut m = v.to_vec();
            m[i] = exact::nudge(v[i], prec, up);
            key(kind, &m) != base
        })
    })
}

impl QuadricShape {
    /// The exact first hit `t > 0` of an `f64` case rounded to `f64` (`None`: a miss or invalid
    /// input), without the truth's ill-posedness and other root: what the reintersection test
    /// asks of its spawned rays.
    pub fn first_hit_f64(&self, v: &[f64]) -> Option<f64> {
        let (qd, k) = solve(self.kind, v)?;
        qd.round_root(k?, Precision::F64)
    }
}

/// The exact answer of an ellipsoid or cylinder case.
fn oracle(kind: Kind, v: &[f64], prec: Precision) -> Truth {
    let Some((qd, k)) = solve(kind, v) else {
        return Truth::Invalid;
    };
    let ill_posed = ill_posed(kind, v, k, prec);
    let Some(k) = k else {
        return Truth::Answer(Expected {
            count: 0,
            values: vec![],
            others: vec![],
            ill_posed,
            cap_reached: false,
            ..Default::default()
        });
    };
    let t = qd.round_root(k, prec);
    let other = qd.round_root(1 - k, prec);
    Truth::Answer(Expected {
        count: 1,
        values: vec![t.unwrap_or(f64::NAN)],
        others: other.into_iter().collect(),
        ill_posed,
        cap_reached: t.is_none(),
        ..Default::default()
    })
}

/// The exact unit normal at the exact ellipsoid hit, each component correctly rounded.
fn normal_oracle(v: &[f64], prec: Precision) -> Truth {
    let Some((qd, k)) = solve(Kind::Ellipsoid, v) else {
        return Truth::Invalid;
    };
    let ill_posed = ill_posed(Kind::Ellipsoid, v, k, prec);
    let Some(k) = k else {
        return Truth::Answer(Expected {
            count: 0,
            values: vec![],
            others: vec![],
            ill_posed,
            cap_reached: false,
            ..Default::default()
        });
    };
    let (o, d) = (qv(v, 0), qv(v, 3));
    let s2 = [
        Rational::from(1),
        exact::q(v[7]).square(),
        exact::q(v[8]).square(),
    ];
    let component = |i: usize| {
        exact::ziv(prec, exact::ZIV_CAP, |bits| {
            let t = qd.root(k, bits);
            // g = S²(o + t·d), n = g/|g|
            let g: Vec<Iv> = (0..3)
                .map(|j| {
                    let p = Iv::q(&o[j], bits).add(&t.mul(&Iv::q(&d[j], bits)));
                    p.mul(&Iv::q(&s2[j], bits))
                })
                .collect();
            let len = g[0].square().add(&g[1].square()).add(&g[2].square()).sqrt();
            let n = g[i].div(&len);
            (n.lo, n.hi)
        })
    };
    let n: Vec<Option<f64>> = (0..3).map(component).collect();
    Truth::Answer(Expected {
        count: 1,
        values: n.iter().map(|x| x.unwrap_or(f64::NAN)).collect(),
        others: vec![],
        ill_posed,
        cap_reached: n.iter().any(|x| x.is_none()),
        ..Default::default()
    })
}

// ---- the shapes ----

/// A quadric method over the scalar inputs `o, d, p₁, p₂, p₃`.
type QFn<F, T> = fn(V<F>, V<F>, F, F, F) -> Option<T>;

fn call<F: Real, T>(f: QFn<F, T>, v: &[f64]) -> Option<T> {
    let a = |k: usize| [v[k], v[k + 1], v[k + 2]].map(F::from_f64);
    let p = |k: usize| F::from_f64(v[k]);
    f(a(0), a(3), p(6), p(7), p(8))
}

fn t_answer<F: Real>(t: Option<F>) -> Answer {
    match t {
        Some(t) => Answer::hit(vec![t.to_f64()]),
        None => Answer::miss(),
    }
}

fn run_t<F: Real>(fs: [QFn<F, F>; 3], m: usize, v: &[f64]) -> Answer {
    t_answer(call(fs[m], v))
}

const CHAPTER_ABOUT: &str = "the chapter's coefficients a, b, c and the textbook quadratic";

const ELLIPSOID_METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "chapter",
        robust: false,
        about: CHAPTER_ABOUT,
    },
    MethodInfo {
        name: "perp",
        robust: false,
        about: "stretched ray (x, my, nz) + RTG7 perpendicular discriminant and stable pair, working precision",
    },
    MethodInfo {
        name: "robust",
        robust: true,
        about: "perp with the stretched ray formed exactly in the wide type (f64 / double-double), rounded once",
    },
];

/// Ellipsoid class names.
pub const ELLIPSOID_CLASSES: &[&str] = &[
    "random",
    "inside",
    "on_surface",
    "tangent",
    "behind",
    "far_small",
    "huge",
    "grazing",
    "flat",
    "elongated",
    "invalid",
];

/// The three methods of a kind of quadric.
fn t_fns<F: Real>(kind: Kind) -> [QFn<F, F>; 3] {
    match kind {
        Kind::Ellipsoid => [ellipsoid_chapter, ellipsoid_perp, ellipsoid_robust_mn],
        Kind::Cylinder => [cylinder_chapter, cylinder_perp, cylinder_robust_m],
    }
}

fn normal_fns<F: Real>() -> [QFn<F, V<F>>; 3] {
    [normal_chapter, normal_robust_t, normal_robust]
}

const CYLINDER_METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "chapter",
        robust: false,
        about: CHAPTER_ABOUT,
    },
    MethodInfo {
        name: "perp",
        robust: false,
        about:
            "pbrt's 2-D perpendicular discriminant and stable pair on (x, my), working precision",
    },
    MethodInfo {
        name: "robust",
        robust: true,
        about: "perp in the wide type (f64 / double-double) incl. the z check, rounded once",
    },
];

/// Cylinder class names.
pub const CYLINDER_CLASSES: &[&str] = &[
    "generic",
    "parallel_axis",
    "grazing",
    "cap_edge",
    "inside",
    "far_small",
    "huge",
    "invalid",
];

/// A ray–quadric routine: the ellipsoid (§2.3) or the cylinder's lateral surface (§2.4).
pub struct QuadricShape {
    kind: Kind,
    info: ShapeInfo,
}

/// Ray–ellipsoid `x² + m²y² + n²z² = r²`, nearest `t > 0`.
pub static ELLIPSOID: QuadricShape = QuadricShape {
    kind: Kind::Ellipsoid,
    info: ShapeInfo {
        name: "ellipsoid",
        about: "ray–ellipsoid x² + m²y² + n²z² = r², nearest t > 0 (seed 002 §2.3)",
        args: &["ox", "oy", "oz", "dx", "dy", "dz", "r", "m", "n"],
        classes: ELLIPSOID_CLASSES,
        methods: ELLIPSOID_METHODS,
        domain: Domain::RayParameter,
        ..ShapeInfo::DEFAULTS
    },
};

/// Ray–cylinder `x² + m²y² = r²`, `0 ≤ z ≤ h`, the lateral surface.
pub static CYLINDER: QuadricShape = QuadricShape {
    kind: Kind::Cylinder,
    info: ShapeInfo {
        name: "cylinder",
        about: "ray–cylinder x² + m²y² = r², 0 ≤ z ≤ h, lateral surface (seed 002 §2.4)",
        args: &["ox", "oy", "oz", "dx", "dy", "dz", "r", "m", "h"],
        classes: CYLINDER_CLASSES,
        methods: CYLINDER_METHODS,
        ..ELLIPSOID.info
    },
};

impl Shape for QuadricShape {
    fn info(&self) -> &ShapeInfo {
        &self.info
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        let class = self.info.classes[class];
        Some(match self.kind {
            Kind::Ellipsoid => propose_ellipsoid(class, prec, rng),
            Kind::Cylinder => propose_cylinder(class, prec, rng),
        })
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        oracle(self.kind, input, prec)
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => run_t(t_fns::<F>(self.kind), m, input))
    }
}

/// The ellipsoid's unit normal at the hit (§3) as an audited routine.
pub struct EllipsoidNormalShape;

const NORMAL_METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "chapter",
        robust: false,
        about: "chapter t, p = o + t·d and gradient (2x, 2m²y, 2n²z) normalised, working precision",
    },
    MethodInfo {
        name: "robust_t",
        robust: false,
        about: "robust t rounded, then p and the gradient in the working precision",
    },
    MethodInfo {
        name: "robust",
        robust: true,
        about: "robust root, p and the gradient in the wide type, normalised, rounded once",
    },
];

fn run_n<F: Real>(m: usize, v: &[f64]) -> Answer {
    match call(normal_fns::<F>()[m], v) {
        Some(n) => Answer::hit(n.iter().map(|x| x.to_f64()).collect()),
        None => Answer::miss(),
    }
}

const ELLIPSOID_NORMAL: ShapeInfo = ShapeInfo {
    name: "ellipsoid_normal",
    about: "unit gradient normal of x² + m²y² + n²z² = r² at the ray's hit (seed 002 §3)",
    values: &["nx", "ny", "nz"],
    methods: NORMAL_METHODS,
    metric: Metric::NormUlps,
    domain: Domain::Real,
    ..ELLIPSOID.info
};

impl Shape for EllipsoidNormalShape {
    fn info(&self) -> &ShapeInfo {
        &ELLIPSOID_NORMAL
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        ELLIPSOID.generate(class, prec, rng)
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        normal_oracle(input, prec)
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => run_n::<F>(m, input))
    }
}

// ---- case generators ----

/// The chapter's ellipsoid in `f64`: semi-axes `r`, `r/m`, `r/n`.
#[derive(Clone, Copy)]
struct Ell {
    r: f64,
    m: f64,
    n: f64,
}

impl Ell {
    fn axes(self) -> [f64; 3] {
        [self.r, self.r / self.m, self.r / self.n]
    }
    /// Largest semi-axis.
    fn extent(self) -> f64 {
        self.axes().into_iter().fold(0.0, f64::max)
    }
    /// The image of a point of the unit ball (a surface point for a unit vector).
    fn at(self, u: [f64; 3]) -> [f64; 3] {
        let a = self.axes();
        [a[0] * u[0], a[1] * u[1], a[2] * u[2]]
    }
    /// The unit outward normal at a surface point.
    fn normal(self, p: [f64; 3]) -> [f64; 3] {
        normalize([p[0], self.m * self.m * p[1], self.n * self.n * p[2]])
    }
}

/// Ratios m, n for a class: near 1, or flat (one ≫ 1), or elongated (≪ 1).
fn ratios(rng: &mut ChaCha8Rng, class: &str) -> (f64, f64) {
    let mut mn = [lu(rng, -0.3, 0.3), lu(rng, -0.3, 0.3)];
    let k = rng.random_range(0..2);
    match class {
        "flat" => mn[k] = lu(rng, 2.0, 4.0),
        "elongated" => {
            mn[k] = lu(rng, -4.0, -2.0);
            if rng.random::<bool>() {
                mn[1 - k] = lu(rng, -4.0, -2.0);
            }
        }
        _ => {}
    }
    (mn[0], mn[1])
}

fn quad_case(o: [f64; 3], d: [f64; 3], p: [f64; 3], prec: Precision) -> Vec<f64> {
    let mut v = vec![];
    for a in [o, d, p] {
        v.extend_from_slice(&rpv(prec, a));
    }
    v
}

/// A floor-like approach: from `h` above the surface point `p` (unit normal `g`), 3 in 5 rays
/// looking down at the surface, the others within 0.1 rad of the horizon.
fn floor_ray(rng: &mut ChaCha8Rng, p: [f64; 3], g: [f64; 3], h: f64) -> ([f64; 3], [f64; 3]) {
    let o = add(p, mul(g, h));
    let d = if rng.random_range(0..5) < 3 {
        let v = unit(rng);
        if sample::dot(v, g) > 0.0 {
            sub(v, mul(g, 2.0 * sample::dot(v, g)))
        } else {
            v
        }
    } else {
        let tilt = lu(rng, -4.0, -1.0) * sample::sign(rng);
        normalize(add(perp(rng, g), mul(g, tilt)))
    };
    (o, d)
}

/// Relative machine epsilon of the precision.
fn eps(prec: Precision) -> f64 {
    match prec {
        Precision::F32 => f32::EPSILON as f64,
        Precision::F64 => f64::EPSILON,
    }
}

/// Makes one input invalid: a non-finite scalar, a parameter ≤ 0, or `d = 0`.
fn invalidate(rng: &mut ChaCha8Rng, v: &mut [f64]) {
    match rng.random_range(0..3) {
        0 => v[rng.random_range(0..9)] = sample::non_finite(rng),
        1 => v[rng.random_range(6..9)] = -v[6] * rng.random_range(0..2) as f64,
        _ => {
            for x in &mut v[3..6] {
                *x = 0.0 * sample::sign(rng);
            }
        }
    }
}

fn propose_ellipsoid(class: &str, prec: Precision, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let (m, n) = ratios(rng, class);
    let r = lu(rng, -2.0, 3.0);
    let mut e = Ell { r, m, n };
    let ext = e.extent();
    let (o, d) = match class {
        "inside" => (e.at(mul(ball(rng), 0.999)), unit(rng)),
        "on_surface" => {
            let p = rpv(prec, e.at(unit(rng)));
            let o = p.map(|x| sample::nudge_k(x, prec, rng.random_range(-3..=3)));
            (o, unit(rng))
        }
        "tangent" | "grazing" => {
            // Along the tangent plane at p; grazing: moved off it by up to 1e-3 of the extent
            let p = e.at(unit(rng));
            let g = e.normal(p);
            let t = perp(rng, g);
            let off = if class == "grazing" {
                ext * lu(rng, -6.0, -3.0) * sample::sign(rng)
            } else {
                0.0
            };
            let o = sub(
                add(p, mul(g, off)),
                mul(t, ext * rng.random_range(0.5..4.0)),
            );
            (o, t)
        }
        "behind" => {
            let q = e.at(ball(rng));
            let u = unit(rng);
            let o = add(q, mul(u, ext * (2.0 + lu(rng, -1.0, 1.0))));
            (
                o,
                normalize(add(u, mul(perp(rng, u), rng.random_range(0.0..0.5)))),
            )
        }
        "far_small" => {
            let o = mul(unit(rng), ext / lu(rng, -6.0, -2.0));
            let target = e.at(mul(ball(rng), 1.5));
            (o, normalize(sub(target, o)))
        }
        "huge" => {
            e.r = lu(rng, 4.0, 6.5);
            let p = e.at(unit(rng));
            let h = e.r * lu(rng, eps(prec).log10() - 1.0, -3.0);
            floor_ray(rng, p, e.normal(p), h)
        }
        _ => {
            // random, flat, elongated, invalid: origin within 10 extents, half the rays aimed
            let o = mul(cube(rng), 10.0 * ext * lu(rng, -1.0, 0.0));
            let d = if rng.random::<bool>() {
                normalize(sub(e.at(mul(ball(rng), 1.5)), o))
            } else {
                unit(rng)
            };
            (o, d)
        }
    };
    let mut v = quad_case(o, d, [e.r, e.m, e.n], prec);
    if class == "tangent" {
        v[6] = sample::nudge_k(v[6], prec, rng.random_range(-8..=8));
    }
    if class == "invalid" {
        invalidate(rng, &mut v);
    }
    v.into_iter().map(|x| rp(prec, x)).collect()
}

fn propose_cylinder(class: &str, prec: Precision, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let m = lu(rng, -0.3, 0.3);
    let mut r = lu(rng, -2.0, 3.0);
    let mut h = r * lu(rng, -0.3, 0.6);
    // A point of the elliptic cross-section at radius fraction ρ, angle θ, height z
    let at = |r: f64, rho: f64, th: f64, z: f64| [rho * r * th.cos(), rho * r / m * th.sin(), z];
    let normal2 = |p: [f64; 3]| normalize([p[0], m * m * p[1], 0.0]);
    let th = rng.random_range(0.0..std::f64::consts::TAU);
    let ext = r * m.recip().max(1.0);
    let (o, d) = match class {
        "parallel_axis" => {
            h = r * lu(rng, 0.0, 4.0);
            let mut d = [0.0, 0.0, sample::sign(rng)];
            for x in &mut d[..2] {
                if rng.random_range(0..3) > 0 {
                    *x = lu(rng, -8.0, -3.0) * sample::sign(rng);
                }
            }
            let o = at(
                r,
                rng.random_range(0.5..1.5),
                th,
                h * rng.random_range(-1.0..2.0),
            );
            (o, normalize(d))
        }
        "grazing" => {
            let p = at(r, 1.0, th, h * rng.random_range(0.0..1.0));
            let g = normal2(p);
            let tan = [-g[1], g[0], 0.0];
            let d = normalize(add(tan, [0.0, 0.0, rng.random_range(-0.5..0.5)]));
            let off = ext * lu(rng, -6.0, -3.0) * sample::sign(rng);
            let o = sub(
                add(p, mul(g, off)),
                mul(d, ext * rng.random_range(0.5..4.0)),
            );
            (o, d)
        }
        "cap_edge" => {
            // A rim point, a few ulps off in z, approached from a random direction
            let z = if rng.random::<bool>() { 0.0 } else { h };
            let mut q = rpv(prec, at(r, 1.0, th, z));
            q[2] = if z == 0.0 {
                rng.random_range(-4..=4) as f64 * 2f64.powi(-140)
            } else {
                sample::nudge_k(rp(prec, h), prec, rng.random_range(-4..=4))
            };
            let o = add(q, mul(unit(rng), ext * rng.random_range(0.5..4.0)));
            (o, normalize(sub(q, o)))
        }
        "inside" => (
            at(
                r,
                rng.random_range(0.0..0.999),
                th,
                h * rng.random_range(0.001..0.999),
            ),
            unit(rng),
        ),
        "far_small" => {
            r = lu(rng, -3.0, 2.0);
            h = r * lu(rng, -0.3, 1.0);
            let ext = r * m.recip().max(1.0);
            let o = add(
                [0.0, 0.0, h / 2.0],
                mul(unit(rng), ext / lu(rng, -6.0, -2.0)),
            );
            let target = at(
                r,
                rng.random_range(0.0..1.2),
                th,
                h * rng.random_range(-0.2..1.2),
            );
            (o, normalize(sub(target, o)))
        }
        "huge" => {
            r = lu(rng, 4.0, 6.5);
            h = r * lu(rng, -1.0, 1.0);
            let p = at(r, 1.0, th, h * rng.random_range(0.0..1.0));
            let height = r * lu(rng, eps(prec).log10() - 1.0, -3.0);
            floor_ray(rng, p, normal2(p), height)
        }
        _ => {
            // generic, invalid
            let o = add([0.0, 0.0, h / 2.0], mul(cube(rng), 3.0 * ext.max(h)));
            let d = if rng.random::<bool>() {
                let target = at(
                    r,
                    rng.random_range(0.0..1.2),
                    th,
                    h * rng.random_range(-0.2..1.2),
                );
                normalize(sub(target, o))
            } else {
                unit(rng)
            };
            (o, d)
        }
    };
    let mut v = quad_case(o, d, [r, m, h], prec);
    if class == "invalid" {
        invalidate(rng, &mut v);
    }
    v.into_iter().map(|x| rp(prec, x)).collect()
}
