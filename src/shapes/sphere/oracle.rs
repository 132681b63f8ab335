//! The exact ray–sphere oracle.
//!
//! Inputs are the exact binary values of the ten float arguments. Every value is an integer
//! times a power of two, so after scaling all of them by one power of two (which leaves `t`
//! unchanged) they are GMP integers, and the quadratic `A t² + 2B' t + C` with
//! `A = d·d`, `B' = d·(o−c)`, `C = |o−c|² − r²`, `Δ = B'² − A·C` has exact integer
//! coefficients. The verdict depends only on the signs of `Δ`, `C` and `B'`.
//!
//! 1. **Verdict** (hit near root / hit far root / miss / invalid input): first by a cheap
//!    outward-rounded `f64` interval evaluation, which is rigorous; only when it cannot decide a
//!    sign, exactly with integers.
//! 2. **Ill-posedness**: the verdict is recomputed with each of the ten inputs moved by one ulp
//!    of its own precision, up and down. First all twenty at once as an interval box (if the box
//!    decides, no single move can flip); otherwise one by one, exactly.
//! 3. **Roots**: both roots enclosed with MPFR directed rounding (the stable form
//!    `q = −(B' + sign(B')√Δ)`, roots `q/A` and `C/q`, so there is no cancellation) at rising
//!    precision until the enclosure of the answer rounds to one `f32` and one `f64`
//!    (Ziv's strategy). If [`PREC_CAP`] bits do not suffice, `cap_reached` is set.
//!
//! # Why it is fast
//!
//! The sphere is a small part of the default audit's time (`reference/figures.md`, per family),
//! while the routines' exact oracles use nearly all of its CPU time. Three reasons:
//! - The exact verdict first goes through the outward-rounded `f64` interval filter. GMP integers
//!   are used only when the filter cannot decide a sign.
//! - The ill-posedness check evaluates all 20 one-ulp moves at once as one interval box, and
//!   decides them one by one, exactly, only when the box is undecided.
//! - MPFR starts at 2·p + 64 bits and doubles only when the rounding is still uncertain.

use super::ray::{Ray, Sphere};
use crate::numerics::interval::Interval;
use crate::numerics::real::Real;
use rug::float::Round;
use rug::ops::{AddAssignRound, DivAssignRound, MulAssignRound};
use rug::{Float, Integer};
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;

/// Precision, in bits, at which the root search gives up.
pub const PREC_CAP: u32 = 16384;

/// One audit case: the ten scalar inputs in the precision under test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Case<F> {
    /// Origin.
    pub o: [F; 3],
    /// Direction.
    pub d: [F; 3],
    /// Centre.
    pub c: [F; 3],
    /// Radius.
    pub r: F,
}

impl<F: Real> Case<F> {
    /// The case's ray.
    pub fn ray(&self) -> Ray<F> {
        Ray {
            origin: F::vec3(self.o[0], self.o[1], self.o[2]),
            dir: F::vec3(self.d[0], self.d[1], self.d[2]),
        }
    }
    /// The case's sphere.
    pub fn sphere(&self) -> Sphere<F> {
        Sphere {
            center: F::vec3(self.c[0], self.c[1], self.c[2]),
            radius: self.r,
        }
    }
    /// The inputs in a fixed order: o, d, c, r.
    pub fn scalars(&self) -> [F; 10] {
        let (o, d, c) = (self.o, self.d, self.c);
        [o[0], o[1], o[2], d[0], d[1], d[2], c[0], c[1], c[2], self.r]
    }
    /// The case from its ten scalars, in [`Case::scalars`] order.
    pub fn from_scalars(s: [F; 10]) -> Self {
        Case {
            o: [s[0], s[1], s[2]],
            d: [s[3], s[4], s[5]],
            c: [s[6], s[7], s[8]],
            r: s[9],
        }
    }
    /// Valid input: all finite, a non-zero direction, a radius `> 0`.
    pub fn is_valid(&self) -> bool {
        self.scalars().iter().all(|x| x.is_finite())
            && self.d.iter().any(|&x| x != F::ZERO)
            && self.r > F::ZERO
    }
    /// The replay arguments of `rayproof probe sphere`: `--precision P -- ox oy oz dx dy dz cx cy cz r`
    /// in hex floats.
    pub fn probe_args(&self) -> String {
        let v = |a: [F; 3]| format!("{} {} {}", a[0].hex(), a[1].hex(), a[2].hex());
        format!(
            "--precision {} -- {} {} {} {}",
            F::NAME,
            v(self.o),
            v(self.d),
            v(self.c),
            self.r.hex()
        )
    }
}

/// The exact outcome for valid input.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// No root with `t > 0`.
    Miss,
    /// The smaller root `t₁ = (−B' − √Δ)/A` is the nearest positive one (origin outside).
    Near,
    /// The larger root `t₂` is the nearest positive one (origin inside or on the surface).
    Far,
    /// The input is not a valid ray and sphere.
    Invalid,
}

impl Verdict {
    /// `Near` or `Far`.
    pub fn is_hit(self) -> bool {
        matches!(self, Verdict::Near | Verdict::Far)
    }
}

/// The verdict from the signs of `Δ`, `C` and `B'`, or `None` when a needed sign is unknown.
fn decide(disc: Option<i8>, c: Option<i8>, bh: Option<i8>) -> Option<Verdict> {
    Some(match c? {
        1 => {
            if bh? >= 0 || disc? < 0 {
                Verdict::Miss
            } else {
                Verdict::Near
            }
        }
        // On the surface: roots 0 and −2B'/A
        0 => {
            if bh? < 0 {
                Verdict::Far
            } else {
                Verdict::Miss
            }
        }
        _ => Verdict::Far,
    })
}

/// Signs of (Δ, C, B') from an `f64` interval evaluation over boxes of the inputs.
fn interval_signs(x: &[Interval<f64>; 10]) -> (Option<i8>, Option<i8>, Option<i8>) {
    let f = [x[0] - x[6], x[1] - x[7], x[2] - x[8]];
    let d = [x[3], x[4], x[5]];
    let a = d[0].square() + d[1].square() + d[2].square();
    let bh = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
    let c = f[0].square() + f[1].square() + f[2].square() - x[9].square();
    let disc = bh.square() - a * c;
    (disc.sign(), c.sign(), bh.sign())
}

/// The exact integer quantities of a valid case.
pub struct Exact {
    /// `A = d·d`.
    pub a: Integer,
    /// `B' = d·(o − c)`.
    pub bh: Integer,
    /// `C = |o − c|² − r²`.
    pub c: Integer,
    /// `Δ = B'² − A·C`.
    pub disc: Integer,
    /// The radius, scaled like the other inputs.
    pub r: Integer,
    /// The scaled inputs o, d, c.
    pub o: [Integer; 3],
    /// The scaled direction.
    pub d: [Integer; 3],
    /// The scaled centre.
    pub center: [Integer; 3],
}

fn decode(x: f64) -> (Integer, i32) {
    let bits = x.to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i32;
    let frac = bits & ((1u64 << 52) - 1);
    let (m, e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1u64 << 52), exp - 1075)
    };
    let m = Integer::from(m);
    (if x.is_sign_negative() { -m } else { m }, e)
}

impl Exact {
    /// Exact coefficients of a valid case (all inputs finite).
    pub fn new<F: Real>(case: &Case<F>) -> Exact {
        let s = case.scalars();
        let dec: Vec<(Integer, i32)> = s.iter().map(|x| decode(x.to_f64())).collect();
        let emin = dec
            .iter()
            .filter(|(m, _)| *m != 0)
            .map(|(_, e)| *e)
            .min()
            .unwrap_or(0);
        let v: Vec<Integer> = dec
            .into_iter()
            .map(|(m, e)| m << (e - emin).max(0) as u32)
            .collect();
        let o = [v[0].clone(), v[1].clone(), v[2].clone()];
        let d = [v[3].clone(), v[4].clone(), v[5].clone()];
        let center = [v[6].clone(), v[7].clone(), v[8].clone()];
        let r = v[9].clone();
        let f: [Integer; 3] = std::array::from_fn(|i| Integer::from(&o[i] - &center[i]));
        let dot = |a: &[Integer; 3], b: &[Integer; 3]| -> Integer {
            Integer::from(&a[0] * &b[0])
                + Integer::from(&a[1] * &b[1])
                + Integer::from(&a[2] * &b[2])
        };
        let a = dot(&d, &d);
        let bh = dot(&d, &f);
        let c = dot(&f, &f) - Integer::from(&r * &r);
        let disc = Integer::from(&bh * &bh) - Integer::from(&a * &c);
        Exact {
            a,
            bh,
            c,
            disc,
            r,
            o,
            d,
            center,
        }
    }

    /// The verdict from the exact signs of `Δ`, `C` and `B'`.
    pub fn verdict(&self) -> Verdict {
        let sg = |x: &Integer| x.cmp0() as i8;
        decide(Some(sg(&self.disc)), Some(sg(&self.c)), Some(sg(&self.bh)))
            .expect("exact signs always decide")
    }
}

/// The exact verdict of a case: interval filter first, integers when it cannot decide.
pub fn verdict<F: Real>(case: &Case<F>) -> Verdict {
    if !case.is_valid() {
        return Verdict::Invalid;
    }
    let x = case.scalars().map(|v| Interval::point(v.to_f64()));
    let (disc, c, bh) = interval_signs(&x);
    decide(disc, c, bh).unwrap_or_else(|| Exact::new(case).verdict())
}

/// Does a one-ulp move of any single input change the verdict?
pub fn ill_posed<F: Real>(case: &Case<F>, base: Verdict) -> bool {
    let s = case.scalars();
    // All twenty moves at once, as one box
    let boxed = s.map(|v| Interval::new(v.next_down().to_f64(), v.next_up().to_f64()));
    let moved_valid = s
        .iter()
        .all(|v| v.next_down().is_finite() && v.next_up().is_finite())
        && case.r.next_down() > F::ZERO
        && case.d.iter().all(|&x| x != F::ZERO);
    if moved_valid {
        let (disc, c, bh) = interval_signs(&boxed);
        if decide(disc, c, bh) == Some(base) {
            return false;
        }
    }
    // One move at a time, each decided exactly
    (0..10).any(|i| {
        [s[i].next_up(), s[i].next_down()].into_iter().any(|v| {
            let mut m = s;
            m[i] = v;
            verdict(&Case::from_scalars(m)) != base
        })
    })
}

/// A signed enclosure `[lo, hi]` of an exact value.
#[derive(Clone, Debug)]
pub struct Encl {
    /// Lower end.
    pub lo: Float,
    /// Upper end.
    pub hi: Float,
}

impl Encl {
    fn round32(&self) -> Option<f32> {
        let (a, b) = (
            self.lo.to_f32_round(Round::Nearest),
            self.hi.to_f32_round(Round::Nearest),
        );
        (a.to_bits() == b.to_bits()).then_some(a)
    }
    fn round64(&self) -> Option<f64> {
        let (a, b) = (
            self.lo.to_f64_round(Round::Nearest),
            self.hi.to_f64_round(Round::Nearest),
        );
        (a.to_bits() == b.to_bits()).then_some(a)
    }
    /// The midpoint.
    pub fn mid(&self) -> Float {
        let mut m = self.lo.clone() + &self.hi;
        m /= 2u32;
        m
    }
}

fn conv(prec: u32, x: &Integer, round: Round) -> Float {
    Float::with_val_round(prec, x, round).0
}

/// Both roots `t₁ ≤ t₂`, enclosed at `prec` bits with directed rounding. Needs `Δ ≥ 0` and `q ≠ 0`.
pub fn root_enclosures(ex: &Exact, prec: u32) -> (Encl, Encl) {
    // √Δ
    let mut s_lo = conv(prec, &ex.disc, Round::Down);
    s_lo.sqrt_round(Round::Down);
    let mut s_hi = conv(prec, &ex.disc, Round::Up);
    s_hi.sqrt_round(Round::Up);
    // |q| = |B'| + √Δ; q < 0 when B' ≥ 0
    let bmag = Integer::from(ex.bh.abs_ref());
    let mut q_lo = conv(prec, &bmag, Round::Down);
    q_lo.add_assign_round(&s_lo, Round::Down);
    let mut q_hi = conv(prec, &bmag, Round::Up);
    q_hi.add_assign_round(&s_hi, Round::Up);
    let q_neg = ex.bh.cmp0() != Ordering::Less;
    // |q/A|
    let mut qa_lo = q_lo.clone();
    qa_lo.div_assign_round(&conv(prec, &ex.a, Round::Up), Round::Down);
    let mut qa_hi = q_hi.clone();
    qa_hi.div_assign_round(&conv(prec, &ex.a, Round::Down), Round::Up);
    // |C/q|
    let cmag = Integer::from(ex.c.abs_ref());
    let mut cq_lo = conv(prec, &cmag, Round::Down);
    cq_lo.div_assign_round(&q_hi, Round::Down);
    let mut cq_hi = conv(prec, &cmag, Round::Up);
    cq_hi.div_assign_round(&q_lo, Round::Up);
    // Signs, then order
    let signed = |lo: Float, hi: Float, neg: bool| {
        if neg {
            Encl { lo: -hi, hi: -lo }
        } else {
            Encl { lo, hi }
        }
    };
    let c_neg = ex.c.cmp0() == Ordering::Less;
    let qa = signed(qa_lo, qa_hi, q_neg);
    let cq = signed(cq_lo, cq_hi, q_neg != c_neg);
    if q_neg {
        (qa, cq)
    } else {
        (cq, qa)
    }
}

/// What the oracle says about one case.
#[derive(Clone, Debug)]
pub struct Truth {
    /// The exact outcome.
    pub verdict: Verdict,
    /// A one-ulp move of one input changes the verdict.
    pub ill_posed: bool,
    /// Both roots `t₁ ≤ t₂` to about 17 digits, when `Δ ≥ 0`.
    pub roots: Option<[f64; 2]>,
    /// The correctly rounded nearest positive root.
    pub t_f32: Option<f32>,
    /// The correctly rounded nearest positive root in `f64`.
    pub t_f64: Option<f64>,
    /// The precision at which rounding became certain.
    pub prec: u32,
    /// Ziv's loop reached [`PREC_CAP`] without certainty (t_f32/t_f64 then hold the best guess).
    pub cap_reached: bool,
}

impl Truth {
    /// The correctly rounded answer in the precision `F`.
    pub fn t_in<F: Real>(&self) -> Option<F> {
        if F::MANT_BITS == 24 {
            self.t_f32.map(|t| F::from_f64(t as f64))
        } else {
            self.t_f64.map(F::from_f64)
        }
    }
}

/// Runs the oracle on one case.
pub fn truth<F: Real>(case: &Case<F>) -> Truth {
    let v = verdict(case);
    let mut out = Truth {
        verdict: v,
        ill_posed: false,
        roots: None,
        t_f32: None,
        t_f64: None,
        prec: 0,
        cap_reached: false,
    };
    if v == Verdict::Invalid {
        return out;
    }
    out.ill_posed = ill_posed(case, v);
    let ex = Exact::new(case);
    if let Some(z) = ziv(&ex, v, F::MANT_BITS) {
        out.roots = Some(z.roots);
        out.prec = z.prec;
        if let Some((t_f32, t_f64)) = z.t {
            out.t_f32 = Some(t_f32);
            out.t_f64 = Some(t_f64);
        }
        out.cap_reached = z.cap_reached;
    }
    out
}

/// Both roots, and the answer root of a hit rounded by Ziv's loop.
struct Rounded {
    /// Both roots `t₁ ≤ t₂` to about 17 digits.
    roots: [f64; 2],
    /// The answer root correctly rounded to `f32` and `f64` (a hit only).
    t: Option<(f32, f64)>,
    /// The precision at which both roundings became certain (or [`PREC_CAP`]).
    prec: u32,
    cap_reached: bool,
}

/// Ziv's loop: `None` when there are no two real roots to enclose (`Δ < 0`, or `B' = Δ = 0`);
/// otherwise both roots, and for a hit verdict `v` the answer root, starting at
/// `2·mant_bits + 64` bits and doubling until its enclosure rounds to one `f32` and one `f64`.
fn ziv(ex: &Exact, v: Verdict, mant_bits: u32) -> Option<Rounded> {
    if ex.disc.cmp0() == Ordering::Less
        || (ex.bh.cmp0() == Ordering::Equal && ex.disc.cmp0() == Ordering::Equal)
    {
        return None;
    }
    let mut prec = 2 * mant_bits + 64;
    loop {
        let (t1, t2) = root_enclosures(ex, prec);
        let roots = [t1.mid().to_f64(), t2.mid().to_f64()];
        let ans = match v {
            Verdict::Near => t1,
            Verdict::Far => t2,
            _ => {
                return Some(Rounded {
                    roots,
                    t: None,
                    prec,
                    cap_reached: false,
                })
            }
        };
        if let (Some(a), Some(b)) = (ans.round32(), ans.round64()) {
            return Some(Rounded {
                roots,
                t: Some((a, b)),
                prec,
                cap_reached: false,
            });
        }
        if prec >= PREC_CAP {
            let m = ans.mid();
            return Some(Rounded {
                roots,
                t: Some((m.to_f32(), m.to_f64())),
                prec,
                cap_reached: true,
            });
        }
        prec *= 2;
    }
}

/// The exact verdict and the correctly rounded nearest root with `t > 0`, in the case's own
/// precision: the accurate phase of [`super::certified`]. `None` for a miss, invalid input,
/// or a root that rounds to zero or overflows in `F`.
pub fn nearest_root<F: Real>(case: &Case<F>) -> Option<F> {
    let v = verdict(case);
    if !v.is_hit() {
        return None;
    }
    let (t32, t64) = ziv(&Exact::new(case), v, F::MANT_BITS)?.t?;
    let t = if F::MANT_BITS == 24 {
        F::from_f64(t32 as f64)
    } else {
        F::from_f64(t64)
    };
    (t > F::ZERO && t.is_finite()).then_some(t)
}

/// Both exact roots as decimal strings with `digits` significant digits.
pub fn roots_decimal<F: Real>(case: &Case<F>, digits: usize) -> Vec<String> {
    if !case.is_valid() {
        return vec![];
    }
    let ex = Exact::new(case);
    if ex.disc.cmp0() == Ordering::Less
        || (ex.bh.cmp0() == Ordering::Equal && ex.disc.cmp0() == Ordering::Equal)
    {
        return vec![];
    }
    let prec = (digits as f64 * 3.33) as u32 + 128;
    let (t1, t2) = root_enclosures(&ex, prec);
    [t1, t2]
        .iter()
        .map(|e| e.mid().to_string_radix(10, Some(digits)))
        .collect()
}

/// Signed distance of the exact point `o + t·d` from the sphere, `|p − c| − r`, in ulps of `r`
/// in the precision `F` (computed with MPFR at 256 bits).
pub fn residual_ulps<F: Real>(case: &Case<F>, t: F) -> f64 {
    let p = 256;
    let fl = |x: F| Float::with_val(p, x.to_f64());
    let tt = fl(t);
    let mut n2 = Float::with_val(p, 0);
    for i in 0..3 {
        let mut x = fl(case.d[i]);
        x.mul_assign_round(&tt, Round::Nearest);
        x += fl(case.o[i]);
        x -= fl(case.c[i]);
        n2 += x.square();
    }
    let res = n2.sqrt() - fl(case.r);
    let ulp_r = ulp(case.r);
    (res / ulp_r).to_f64()
}

/// First-order sensitivity of the answer to the inputs, in ulps of `t`: how far `t` moves when
/// every input moves by one ulp of its precision, Σᵢ |∂t/∂xᵢ|·ulp(xᵢ) / ulp(t).
///
/// From `F(t, x) = |o + t·d − c|² − r² = 0`: with `p = o + t·d − c`, `∂F/∂t = 2 d·p`,
/// `∂F/∂o = 2p`, `∂F/∂c = −2p`, `∂F/∂d = 2t·p`, `∂F/∂r = −2r`, and `∂t/∂x = −(∂F/∂x)/(∂F/∂t)`.
/// A method whose error is a small multiple of this is as accurate as the inputs allow
/// (backward stable); a large multiple means the method, not the case, lost the digits.
/// Evaluated in `f64` at the exact root: an estimate, not a bound. `None` for misses and
/// when `∂F/∂t` is 0 (an exactly tangent ray).
pub fn condition_ulps<F: Real>(case: &Case<F>, truth: &Truth) -> Option<f64> {
    let t = truth.t_in::<F>()?.to_f64();
    let (o, d, c) = (
        case.o.map(|x| x.to_f64()),
        case.d.map(|x| x.to_f64()),
        case.c.map(|x| x.to_f64()),
    );
    let p: [f64; 3] = std::array::from_fn(|i| (o[i] - c[i]) + t * d[i]);
    let dfdt = 2.0 * (d[0] * p[0] + d[1] * p[1] + d[2] * p[2]);
    if dfdt == 0.0 || !t.is_finite() {
        return None;
    }
    let mut sum = 2.0 * case.r.to_f64() * ulp(case.r);
    for (i, pi) in p.iter().enumerate() {
        sum += 2.0 * pi.abs() * (ulp(case.o[i]) + ulp(case.c[i]) + t.abs() * ulp(case.d[i]));
    }
    let ut = ulp(F::from_f64(t));
    Some(sum / dfdt.abs() / ut)
}

/// The ulp of `x` in its own precision (spacing of the floats at `|x|`).
pub fn ulp<F: Real>(x: F) -> f64 {
    let a = x.abs();
    (a.next_up().to_f64() - a.to_f64()).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn case(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Case<f64> {
        Case { o, d, c, r }
    }

    #[test]
    fn hand_derived_cases() {
        // Unit sphere at the origin, ray from z = −5 along +z: roots 4 and 6
        let t = truth(&case([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], [0.0; 3], 1.0));
        assert_eq!(t.verdict, Verdict::Near);
        assert_eq!(t.roots, Some([4.0, 6.0]));
        assert_eq!(t.t_f64, Some(4.0));
        // Non-unit direction (0,0,2): roots halve
        let t = truth(&case([0.0, 0.0, -5.0], [0.0, 0.0, 2.0], [0.0; 3], 1.0));
        assert_eq!(t.t_f64, Some(2.0));
        // From the centre: far root r/|d|
        let t = truth(&case([0.0; 3], [0.0, 3.0, 4.0], [0.0; 3], 10.0));
        assert_eq!((t.verdict, t.t_f64), (Verdict::Far, Some(2.0)));
        // Behind: miss
        assert_eq!(
            truth(&case([0.0, 0.0, 5.0], [0.0, 0.0, 1.0], [0.0; 3], 1.0)).verdict,
            Verdict::Miss
        );
        // Exactly tangent at (1,0,0): a hit, and ill-posed
        let t = truth(&case([1.0, 0.0, -5.0], [0.0, 0.0, 1.0], [0.0; 3], 1.0));
        assert_eq!(
            (t.verdict, t.t_f64, t.ill_posed),
            (Verdict::Near, Some(5.0), true)
        );
        // On the surface looking in: far root 2, and ill-posed (the near root is 0)
        let t = truth(&case([0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0; 3], 1.0));
        assert_eq!(
            (t.verdict, t.t_f64, t.ill_posed),
            (Verdict::Far, Some(2.0), true)
        );
        // 1/3 is not a float: roots (−1 ∓ ...) — t = 1/3 exactly for o=(0,0,-4/3)... use r=1, o at z=-4, d=(0,0,9)
        let t = truth(&case([0.0, 0.0, -4.0], [0.0, 0.0, 9.0], [0.0; 3], 1.0));
        assert_eq!(t.t_f64, Some(1.0 / 3.0));
        assert_eq!(t.t_f32, Some(1.0f32 / 3.0));
        // Invalid inputs
        assert_eq!(
            verdict(&case([f64::NAN, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0; 3], 1.0)),
            Verdict::Invalid
        );
        assert_eq!(
            verdict(&case([0.0; 3], [0.0; 3], [0.0; 3], 1.0)),
            Verdict::Invalid
        );
        assert_eq!(
            verdict(&case([0.0; 3], [1.0, 0.0, 0.0], [0.0; 3], -1.0)),
            Verdict::Invalid
        );
    }

    #[test]
    fn ties_resolve_exactly() {
        // t = 1 + 2^-24 exactly: halfway between two f32, rounds to even (1.0)
        let h = 1.0 + 2f64.powi(-24);
        let t = truth(&case(
            [0.0, 0.0, -(h + 1.0)],
            [0.0, 0.0, 1.0],
            [0.0; 3],
            1.0,
        ));
        assert_eq!(t.t_f32, Some(1.0f32));
        assert_eq!(t.t_f64, Some(h));
        assert!(!t.cap_reached);
    }

    #[test]
    fn residual_is_zero_at_the_exact_root() {
        let c = case([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], [0.0; 3], 1.0);
        assert_eq!(residual_ulps(&c, 4.0), 0.0);
        assert!((residual_ulps(&c, 4.0f64.next_down()) - 2.0).abs() < 1e-9);
    }
}
