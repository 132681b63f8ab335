//! The exact ray–torus oracle.
//!
//! 1. **Validity**: all eight inputs finite, `d ≠ 0`, `0 < r2 < r1` (a ring torus); otherwise
//!    [`Truth::Invalid`].
//! 2. **Roots**: the chapter's quartic (§2.5) with exact rational coefficients from the exact
//!    binary inputs ([`quartic_q`]); its distinct real roots isolated exactly by
//!    [`sturm::isolated`]; the positive ones kept (an isolating interval that straddles 0 is
//!    decided by the sign of the square-free part at 0); the first correctly rounded by
//!    [`sturm::round_in`], the others reported as `others` (an answer nearer one of them is a
//!    wrong root).
//! 3. **Ill-posedness**: each of the eight inputs is moved one ulp of the precision up and down
//!    (sixteen moves, one input at a time; moves that leave the valid domain, e.g. `r2` onto
//!    `r1`, are skipped). The case is ill-posed when a move changes the number of distinct
//!    positive real roots. This covers the two ways the answer jumps: a tangent (double) root
//!    splitting or vanishing, and a root crossing `t = 0` (origin on the surface). It is
//!    conservative: a tangency behind the first hit also marks the case ill-posed.
//! 4. **Normals** ([`normal_truth`]): the first positive root enclosed by bisection on the
//!    square-free quartic (exact rationals), the hit point enclosed exactly from it, and the unit
//!    normal `(p − c)/r2` (`c` the nearest point of the major circle) enclosed with MPFR
//!    directed rounding, in Ziv's loop. On the surface `(p − c)/r2` *is* the normalised gradient
//!    (the gradient equals `8·r1·ρ·(p − c)` there), so no normalisation is rounded.

use super::methods::is_valid;
use crate::numerics::exact::{self, q, ziv, ZIV_CAP};
use crate::numerics::Precision;
use crate::shapes::oracle::sturm::{self, eval};
use crate::shapes::oracle::ulp_box::{
    roots_keep_count, strict_sign as sign_on_box, ulp_box, BoxIv,
};
use crate::shapes::shape::{Expected, Truth};
use rug::float::Round;
use rug::{Float, Rational};
use std::cmp::Ordering;

/// One case's exact inputs: `o`, `d`, `r1`, `r2`.
pub struct ExactCase {
    /// Origin, in the torus's frame.
    pub o: [Rational; 3],
    /// Direction.
    pub d: [Rational; 3],
    /// Distance from the centre to the tube's centre line.
    pub r1: Rational,
    /// Tube radius.
    pub r2: Rational,
}

impl ExactCase {
    /// From the eight scalars `ox oy oz dx dy dz r1 r2` (finite).
    pub fn new(x: &[f64]) -> ExactCase {
        ExactCase {
            o: [q(x[0]), q(x[1]), q(x[2])],
            d: [q(x[3]), q(x[4]), q(x[5])],
            r1: q(x[6]),
            r2: q(x[7]),
        }
    }
}

fn dot_q(a: &[Rational; 3], b: &[Rational; 3]) -> Rational {
    Rational::from(&a[0] * &b[0]) + Rational::from(&a[1] * &b[1]) + Rational::from(&a[2] * &b[2])
}

/// The chapter's quartic with exact coefficients, ascending (same formula as
/// [`super::methods::quartic`]).
pub fn quartic_q(c: &ExactCase) -> [Rational; 5] {
    let (vv, sv) = (dot_q(&c.d, &c.d), dot_q(&c.o, &c.d));
    let r1s = Rational::from(&c.r1 * &c.r1);
    let r2s = Rational::from(&c.r2 * &c.r2);
    let k = dot_q(&c.o, &c.o) - &r1s - &r2s;
    let four_r1s = r1s * 4u32;
    let oz2 = Rational::from(&c.o[2] * &c.o[2]);
    [
        Rational::from(&k * &k) - &four_r1s * (r2s - oz2),
        Rational::from(&sv * &k) * 4u32 + Rational::from(&four_r1s * &c.o[2]) * &c.d[2] * 2u32,
        Rational::from(&vv * &k) * 2u32
            + Rational::from(&sv * &sv) * 4u32
            + Rational::from(&four_r1s * &c.d[2]) * &c.d[2],
        Rational::from(&vv * &sv) * 4u32,
        Rational::from(&vv * &vv),
    ]
}

fn sign(x: &Rational) -> Ordering {
    x.cmp0()
}

/// An isolated simple root of a square-free polynomial, narrowed on demand by bisection. As in
/// [`sturm::isolated`], the root is the only one in `(lo, hi]` (`lo` may be another root).
pub struct Encloser {
    sf: Vec<Rational>,
    /// Lower end (excluded unless it is the root).
    pub lo: Rational,
    /// Upper end.
    pub hi: Rational,
    /// The sign of `sf` at `hi` (non-zero unless the root is exact).
    sign_hi: Ordering,
}

impl Encloser {
    /// `(lo, hi]` isolates one root of `sf`.
    pub fn new(sf: Vec<Rational>, lo: Rational, hi: Rational) -> Encloser {
        let sign_hi = sign(&eval(&sf, &hi));
        let mut e = Encloser {
            sf,
            lo,
            hi,
            sign_hi,
        };
        if e.sign_hi == Ordering::Equal {
            e.lo = e.hi.clone();
        }
        e
    }

    /// Whether the root is known exactly (`lo == hi`).
    pub fn exact(&self) -> bool {
        self.lo == self.hi
    }

    /// Uses `x` as the root if it is one inside the interval (for rational roots bisection
    /// would only approach).
    pub fn try_exact(&mut self, x: &Rational) {
        if !self.exact() && *x > self.lo && *x <= self.hi && eval(&self.sf, x) == 0 {
            self.lo = x.clone();
            self.hi = x.clone();
        }
    }

    /// Bisects until `hi − lo ≤ 2^−bits · max(|lo|, |hi|)`.
    pub fn narrow(&mut self, bits: u32) {
        loop {
            let width = Rational::from(&self.hi - &self.lo);
            let mag = Rational::from(self.lo.abs_ref()).max(Rational::from(self.hi.abs_ref()));
            if self.exact() || width <= (mag >> bits) {
                return;
            }
            let mid = Rational::from(&self.lo + &self.hi) / 2u32;
            match sign(&eval(&self.sf, &mid)) {
                Ordering::Equal => {
                    self.lo = mid.clone();
                    self.hi = mid;
                }
                s if s == self.sign_hi => self.hi = mid,
                _ => self.lo = mid,
            }
        }
    }
}

/// The distinct positive real roots of `p` (exact, ascending), each the only root of the
/// square-free part in `(lo, hi]`, with the square-free part.
pub fn positive_roots(p: &[Rational]) -> (Vec<(Rational, Rational)>, Vec<Rational>) {
    let (roots, sf) = sturm::isolated(p);
    let roots = roots
        .into_iter()
        .filter(|(lo, hi)| is_positive(&sf, lo, hi))
        .collect();
    (roots, sf)
}

/// Whether an isolated root (the only one in `(lo, hi]`) is `> 0`, decided exactly.
fn is_positive(sf: &[Rational], lo: &Rational, hi: &Rational) -> bool {
    if lo == hi {
        return *lo > 0;
    }
    if *lo >= 0 {
        return true;
    }
    if *hi <= 0 {
        return false;
    }
    // lo < 0 < hi: the root is 0 itself, or on the side of 0 where the sign changes
    let at0 = sign(&eval(sf, &Rational::new()));
    if at0 == Ordering::Equal {
        return false;
    }
    let at_hi = sign(&eval(sf, hi));
    at_hi == Ordering::Equal || at_hi != at0
}

/// The number of distinct positive real roots for the scalars `x`, or `None` if invalid.
fn positive_count(x: &[f64]) -> Option<usize> {
    if !valid_f64(x) {
        return None;
    }
    Some(positive_roots(&quartic_q(&ExactCase::new(x))).0.len())
}

/// [`is_valid`] on the scalar list.
pub fn valid_f64(x: &[f64]) -> bool {
    x.len() == 8 && is_valid([x[0], x[1], x[2]], [x[3], x[4], x[5]], x[6], x[7])
}

/// Whether the number of distinct positive roots is the same everywhere on the one-ulp box of
/// `x`: over the box, the quartic (as [`quartic_q`] forms it) keeps a non-zero constant term
/// (no root crosses `t = 0`), and, written for the ray from `o + t₀·d` (`t₀` the point nearest
/// the torus's centre, so the roots are near 0 and the enclosure does not lose them to
/// cancellation), a non-zero leading coefficient and discriminant (no roots collide or leave).
fn box_keeps_count(x: &[f64], prec: Precision) -> bool {
    let Some(b) = ulp_box(x, prec) else {
        return false;
    };
    let (o, d) = ([b[0], b[1], b[2]], [b[3], b[4], b[5]]);
    let t0 = -(x[0] * x[3] + x[1] * x[4] + x[2] * x[5]) / (x[3] * x[3] + x[4] * x[4] + x[5] * x[5]);
    if !t0.is_finite() {
        return false;
    }
    let shifted: [BoxIv; 3] = std::array::from_fn(|i| o[i] + BoxIv::point(t0) * d[i]);
    let (at0, _) = quartic_box(o, d, b[6], b[7]);
    let (_, c) = quartic_box(shifted, d, b[6], b[7]);
    sign_on_box(at0).is_some() && roots_keep_count(&c)
}

/// The constant term and all coefficients (ascending) of [`quartic_q`]'s quartic enclosed over
/// interval inputs.
fn quartic_box(o: [BoxIv; 3], d: [BoxIv; 3], r1: BoxIv, r2: BoxIv) -> (BoxIv, [BoxIv; 5]) {
    let dot = |u: [BoxIv; 3], v: [BoxIv; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let sq = |u: [BoxIv; 3]| u[0].square() + u[1].square() + u[2].square();
    let k4 = BoxIv::point;
    let (vv, sv) = (sq(d), dot(o, d));
    let (r1s, r2s) = (r1.square(), r2.square());
    let k = sq(o) - r1s - r2s;
    let four_r1s = k4(4.0) * r1s;
    let c = [
        k.square() - four_r1s * (r2s - o[2].square()),
        k4(4.0) * sv * k + k4(2.0) * four_r1s * o[2] * d[2],
        k4(2.0) * vv * k + k4(4.0) * sv.square() + four_r1s * d[2].square(),
        k4(4.0) * vv * sv,
        vv.square(),
    ];
    (c[0], c)
}

/// Whether a one-ulp move of one input changes the number of distinct positive roots.
pub fn ill_posed(x: &[f64], prec: Precision, n: usize) -> bool {
    // The whole box first, then one move at a time, each counted exactly
    if box_keeps_count(x, prec) {
        return false;
    }
    (0..8).any(|i| {
        [true, false].into_iter().any(|up| {
            let mut y = x.to_vec();
            y[i] = exact::nudge(x[i], prec, up);
            positive_count(&y).is_some_and(|m| m != n)
        })
    })
}

/// The torus truth: the first positive root correctly rounded, the others as candidates.
pub fn truth(x: &[f64], prec: Precision) -> Truth {
    if !valid_f64(x) {
        return Truth::Invalid;
    }
    let p = quartic_q(&ExactCase::new(x));
    let (roots, sf) = positive_roots(&p);
    let ill = ill_posed(x, prec, roots.len());
    let rounded: Vec<f64> = roots
        .iter()
        .map(|(lo, hi)| sturm::round_in(&sf, lo, hi, prec))
        .collect();
    let cond = rounded.first().and_then(|&t| {
        let (dt, _) = root_gradient(x, t)?;
        let ut = crate::numerics::exact::ulp(t, prec);
        let sum: f64 = (0..8)
            .map(|k| dt[k].abs() * crate::numerics::exact::ulp(x[k], prec))
            .sum();
        (ut > 0.0 && sum.is_finite()).then(|| sum / ut)
    });
    Truth::Answer(Expected {
        count: (!roots.is_empty()) as u32,
        values: rounded.first().copied().into_iter().collect(),
        others: rounded.iter().skip(1).copied().collect(),
        ill_posed: ill,
        cap_reached: rounded.iter().any(|v| v.is_nan()),
        cond,
        ..Default::default()
    })
}

/// First-order derivatives of the first root `t` with respect to the eight inputs `o d r1 r2`,
/// and the hit point `p = o + t·d`, evaluated in `f64` at the correctly rounded `t`. From
/// `F(p) = (|p|² + R² − r²)² − 4R²(px² + py²) = 0` (`R = r1`, `r = r2`):
/// `∂t/∂x = −(∂F/∂x)/(∂F/∂t)` with `∂F/∂t = ∇F·d`, `∂F/∂o = ∇F`, `∂F/∂d = t∇F`,
/// `∂F/∂R = 4R(|p|² + R² − r²) − 8R(px² + py²)`, `∂F/∂r = −4r(|p|² + R² − r²)`. `None` where
/// `∇F·d` is 0 (a tangent ray) or a value is not finite.
pub fn root_gradient(x: &[f64], t: f64) -> Option<([f64; 8], [f64; 3])> {
    let (o, d, big, small) = ([x[0], x[1], x[2]], [x[3], x[4], x[5]], x[6], x[7]);
    let p: [f64; 3] = std::array::from_fn(|i| o[i] + t * d[i]);
    let s = p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + big * big - small * small;
    let g = [
        4.0 * s * p[0] - 8.0 * big * big * p[0],
        4.0 * s * p[1] - 8.0 * big * big * p[1],
        4.0 * s * p[2],
    ];
    let dfdt = g[0] * d[0] + g[1] * d[1] + g[2] * d[2];
    if dfdt == 0.0 || !dfdt.is_finite() || !t.is_finite() {
        return None;
    }
    let dfdr1 = 4.0 * big * s - 8.0 * big * (p[0] * p[0] + p[1] * p[1]);
    let dfdr2 = -4.0 * small * s;
    let df = [g[0], g[1], g[2], t * g[0], t * g[1], t * g[2], dfdr1, dfdr2];
    Some((df.map(|v| -v / dfdt), p))
}

/// First-order sensitivity of the unit normal at the first hit, in ulps of its largest
/// component: how far the normal moves (largest component change) when every input moves one
/// ulp. The normal is `n = w/|w|`, `w = p − q`, `q = R·(px, py, 0)/ρ` the nearest point of the
/// core circle (`ρ = √(px² + py²)`): `∂n/∂p = (I − nnᵀ)/|w| · (I − (R/ρ)(P − eeᵀ))` (`P` the
/// projection on the xy plane, `e = (px, py, 0)/ρ`), `∂n/∂R = −(I − nnᵀ)e/|w|`, and the hit
/// point moves with the inputs and with `t` (`∂p/∂o = I + d ∂t/∂o`, `∂p/∂d = tI + d ∂t/∂d`,
/// `∂p/∂R = d ∂t/∂R`, `∂p/∂r = d ∂t/∂r`). `None` on the axis (`ρ = 0`) or where `t` has none.
pub fn normal_cond(x: &[f64], t: f64, n: [f64; 3], prec: Precision) -> Option<f64> {
    let (dt, p) = root_gradient(x, t)?;
    let (d, big) = ([x[3], x[4], x[5]], x[6]);
    let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
    if !(rho > 0.0) {
        return None;
    }
    let e = [p[0] / rho, p[1] / rho, 0.0];
    let w = [p[0] - big * e[0], p[1] - big * e[1], p[2]];
    let wn = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    if !(wn > 0.0) {
        return None;
    }
    // (I − nnᵀ) v / |w|
    let tangent = |v: [f64; 3]| -> [f64; 3] {
        let k = v[0] * n[0] + v[1] * n[1] + v[2] * n[2];
        std::array::from_fn(|i| (v[i] - k * n[i]) / wn)
    };
    // (I − (R/ρ)(P − eeᵀ)) v
    let through_q = |v: [f64; 3]| -> [f64; 3] {
        let ev = e[0] * v[0] + e[1] * v[1];
        let k = big / rho;
        [
            v[0] - k * (v[0] - ev * e[0]),
            v[1] - k * (v[1] - ev * e[1]),
            v[2],
        ]
    };
    let mut sum = 0.0;
    for k in 0..8 {
        // ∂p/∂x_k
        let mut dp: [f64; 3] = std::array::from_fn(|i| d[i] * dt[k]);
        if k < 3 {
            dp[k] += 1.0;
        } else if k < 6 {
            dp[k - 3] += t;
        }
        let mut dn = tangent(through_q(dp));
        if k == 6 {
            let de = tangent(e);
            dn = std::array::from_fn(|i| dn[i] - de[i]);
        }
        let m = dn.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        sum += m * crate::numerics::exact::ulp(x[k], prec);
    }
    let big_n = n.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let un = crate::numerics::exact::ulp(big_n, prec);
    (un > 0.0 && sum.is_finite()).then(|| sum / un)
}

/// The exact first positive root and its ray, for the normal and reintersection oracles.
pub struct FirstHit {
    /// The case's exact inputs.
    pub case: ExactCase,
    /// The root, isolated.
    pub root: Encloser,
    /// The root correctly rounded to the precision.
    pub t: f64,
    /// Distinct positive roots.
    pub n_roots: usize,
}

/// The first positive root of a valid case, or `None` for a miss.
pub fn first_hit(x: &[f64], prec: Precision) -> Option<FirstHit> {
    let case = ExactCase::new(x);
    let p = quartic_q(&case);
    let (roots, sf) = positive_roots(&p);
    let (lo, hi) = roots.first()?;
    let t = sturm::round_in(&sf, lo, hi, prec);
    let mut root = Encloser::new(sf, lo.clone(), hi.clone());
    for c in rational_candidates(&case) {
        root.try_exact(&c);
    }
    Some(FirstHit {
        case,
        root,
        t,
        n_roots: roots.len(),
    })
}

/// The rational `t` at which a normal component can be exactly zero: `x = 0`, `y = 0`, `z = 0`,
/// `z = ±r2` (top or bottom of the tube, where `ρ = r1`).
fn rational_candidates(c: &ExactCase) -> Vec<Rational> {
    let at = |i: usize, target: Rational| -> Option<Rational> {
        (c.d[i] != 0).then(|| (target - &c.o[i]) / &c.d[i])
    };
    [
        at(0, Rational::new()),
        at(1, Rational::new()),
        at(2, Rational::new()),
        at(2, c.r2.clone()),
        at(2, Rational::from(-&c.r2)),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// A closed interval of MPFR values.
#[derive(Clone)]
struct Iv(Float, Float);

impl Iv {
    fn of_q(lo: &Rational, hi: &Rational, bits: u32) -> Iv {
        Iv(
            Float::with_val_round(bits, lo, Round::Down).0,
            Float::with_val_round(bits, hi, Round::Up).0,
        )
    }
    fn mul(&self, o: &Iv, bits: u32) -> Iv {
        let prods = |r| {
            [
                Float::with_val_round(bits, &self.0 * &o.0, r).0,
                Float::with_val_round(bits, &self.0 * &o.1, r).0,
                Float::with_val_round(bits, &self.1 * &o.0, r).0,
                Float::with_val_round(bits, &self.1 * &o.1, r).0,
            ]
        };
        let lo = prods(Round::Down)
            .into_iter()
            .reduce(|a, b| a.min(&b))
            .expect("4");
        let hi = prods(Round::Up)
            .into_iter()
            .reduce(|a, b| a.max(&b))
            .expect("4");
        Iv(lo, hi)
    }
    /// Divided by an exact positive rational.
    fn div_pos(&self, k: &Rational, bits: u32) -> Iv {
        Iv(
            Float::with_val_round(bits, &self.0 / k, Round::Down).0,
            Float::with_val_round(bits, &self.1 / k, Round::Up).0,
        )
    }
}

/// The exact interval of `a + t·b` for `t ∈ [lo, hi]`.
fn affine(a: &Rational, b: &Rational, lo: &Rational, hi: &Rational) -> (Rational, Rational) {
    let (u, v) = (Rational::from(b * lo) + a, Rational::from(b * hi) + a);
    if u <= v {
        (u, v)
    } else {
        (v, u)
    }
}

/// The exact interval of `x²` for `x ∈ [lo, hi]`.
fn square(lo: &Rational, hi: &Rational) -> (Rational, Rational) {
    let (a, b) = (Rational::from(lo * lo), Rational::from(hi * hi));
    let top = a.clone().max(b.clone());
    if *lo <= 0 && *hi >= 0 {
        (Rational::new(), top)
    } else {
        (a.min(b), top)
    }
}

/// The unit normal `(p − c)/r2` at the hit enclosed by `[lo, hi]`, with `bits` of precision.
fn normal_encl(h: &FirstHit, bits: u32) -> [Iv; 3] {
    let c = &h.case;
    let (lo, hi) = (&h.root.lo, &h.root.hi);
    let p: Vec<(Rational, Rational)> = (0..3).map(|i| affine(&c.o[i], &c.d[i], lo, hi)).collect();
    // ρ² exactly, ρ by directed square roots
    let (sx, sy) = (square(&p[0].0, &p[0].1), square(&p[1].0, &p[1].1));
    let (s_lo, s_hi) = (sx.0 + sy.0, sx.1 + sy.1);
    let r1s = Rational::from(&c.r1 * &c.r1);
    // 1 − r1/ρ, increasing in ρ; exactly 0 when ρ² = r1² on the whole interval
    let scale = if s_lo == r1s && s_hi == r1s {
        Iv(Float::new(bits), Float::new(bits))
    } else {
        let root = |x: &Rational, r| {
            let mut f = Float::with_val_round(bits, x, r).0;
            f.sqrt_round(r);
            f
        };
        let (rho_lo, rho_hi) = (root(&s_lo, Round::Down), root(&s_hi, Round::Up));
        let one_minus = |rho: &Float, r| {
            let ratio = Float::with_val_round(bits, &c.r1 / rho, flip(r)).0;
            Float::with_val_round(bits, 1 - ratio, r).0
        };
        Iv(
            one_minus(&rho_lo, Round::Down),
            one_minus(&rho_hi, Round::Up),
        )
    };
    let pi = |i: usize| Iv::of_q(&p[i].0, &p[i].1, bits);
    [
        pi(0).mul(&scale, bits).div_pos(&c.r2, bits),
        pi(1).mul(&scale, bits).div_pos(&c.r2, bits),
        pi(2).div_pos(&c.r2, bits),
    ]
}

fn flip(r: Round) -> Round {
    match r {
        Round::Down => Round::Up,
        _ => Round::Down,
    }
}

/// The normal truth: the correctly rounded unit outward normal at the first positive hit.
pub fn normal_truth(x: &[f64], prec: Precision) -> Truth {
    if !valid_f64(x) {
        return Truth::Invalid;
    }
    let Some(mut h) = first_hit(x, prec) else {
        return Truth::Answer(Expected {
            count: 0,
            values: vec![],
            others: vec![],
            ill_posed: ill_posed(x, prec, 0),
            cap_reached: false,
            ..Default::default()
        });
    };
    let ill = ill_posed(x, prec, h.n_roots);
    let mut values = vec![];
    let mut cap = false;
    for i in 0..3 {
        let v = ziv(prec, ZIV_CAP, |bits| {
            h.root.narrow(bits + 64);
            let [a, b, c] = normal_encl(&h, bits);
            let Iv(lo, hi) = [a, b, c].into_iter().nth(i).expect("3 components");
            (lo, hi)
        });
        cap |= v.is_none();
        values.push(v.unwrap_or(f64::NAN));
    }
    let cond = (!cap)
        .then(|| normal_cond(x, h.t, [values[0], values[1], values[2]], prec))
        .flatten();
    Truth::Answer(Expected {
        count: 1,
        values,
        others: vec![],
        ill_posed: ill,
        cap_reached: cap,
        cond,
        ..Default::default()
    })
}
