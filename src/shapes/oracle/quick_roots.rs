//! The quick phase of the polynomial oracle (§1.1–§1.3): every distinct real root of a
//! polynomial with `f64` coefficients, correctly rounded, proved without rational arithmetic
//! when a cheap proof exists; the exact Sturm path ([`super::sturm::rounded_roots`]) runs only
//! when it does not. As correctly rounded libraries do, a fast estimate is made and then
//! *checked* rigorously; nothing from the estimate is trusted.
//!
//! 1. **How many real roots**: the discriminant's sign, enclosed in interval arithmetic
//!    (quadratic: 2 or 0; cubic: 3 or 1; quartic: 2 if negative, else 4 or 0 by the signs of
//!    `P = 8ac − 3b²` and `D = 64a³e − 16a²c² + 16ab²c − 16a²bd − 3b⁴`). A non-zero discriminant
//!    also makes every root simple.
//! 2. **Where**: estimates in `f64` (the derivative's roots split the line into monotone
//!    pieces, each bisected on its sign change), each rounded to the precision.
//! 3. **The proof**: for each estimate `a`, the polynomial's signs at the two rounding
//!    boundaries of `a` (the exact midpoints to its neighbours) are certain and opposite, so a
//!    root lies strictly between them and rounds to `a`. A sign is decided by `f64` interval
//!    Horner when it can (an `f32` boundary is an `f64`), otherwise exactly with integers (the
//!    boundary and the coefficients are dyadic). An estimate off by an ulp or two is walked to
//!    the right float. With as many disjoint proved brackets as real roots, each holds exactly
//!    one, and the list is the exact answer.

use super::sturm::{from_ordinal, ordinal};
use super::ulp_box::{discriminant, filters_on, normalised, strict_sign, BoxIv};
use crate::numerics::exact::decompose;
use crate::numerics::interval::Interval;
use crate::numerics::Precision;
use rug::Integer;

/// Every distinct real root of `Σ cᵢ xⁱ` (ascending, degree 1 to 4, finite, non-zero leading
/// coefficient), correctly rounded to the precision and ascending, or `None` when the quick
/// phase cannot prove it.
pub fn rounded_roots(c: &[f64], prec: Precision) -> Option<Vec<f64>> {
    let n = c.len().checked_sub(1)?;
    if !filters_on() || !(1..=4).contains(&n) || c[n] == 0.0 || !c.iter().all(|x| x.is_finite()) {
        return None;
    }
    let count = real_count(c)?;
    let estimates = estimates(c);
    if estimates.len() != count {
        return None;
    }
    let mut out: Vec<f64> = vec![];
    for x in estimates {
        let a = proved(c, x, prec)?;
        // Disjoint brackets: strictly ascending floats
        if out.last().is_some_and(|&prev| prev >= a) {
            return None;
        }
        out.push(a);
    }
    Some(out)
}

/// The number of distinct real roots (all simple), from certain signs of the discriminant
/// (and, for a quartic with a positive one, of `P` and `D`).
fn real_count(c: &[f64]) -> Option<usize> {
    let n = c.len() - 1;
    if n == 1 {
        return Some(1);
    }
    let k = normalised(&c.iter().map(|&x| Interval::point(x)).collect::<Vec<_>>());
    let disc = strict_sign(discriminant(&k))?;
    Some(match (n, disc) {
        (2, 1) => 2,
        (2, _) => 0,
        (3, 1) => 3,
        (3, _) => 1,
        (_, -1) => 2,
        _ => {
            let (e, d, cc, b, a) = (k[0], k[1], k[2], k[3], k[4]);
            let p = |x: f64| Interval::point(x);
            let pp = p(8.0) * a * cc - p(3.0) * b.square();
            let dd = p(64.0) * a.square() * a * e - p(16.0) * a.square() * cc.square()
                + p(16.0) * a * b.square() * cc
                - p(16.0) * a.square() * b * d
                - p(3.0) * b.square().square();
            match (strict_sign(pp), strict_sign(dd)) {
                (Some(-1), Some(-1)) => 4,
                (Some(1), _) | (_, Some(1)) => 0,
                _ => return None,
            }
        }
    })
}

/// `p(x)` in `f64` (Horner), for estimates only.
fn horner(c: &[f64], x: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &k| acc * x + k)
}

/// Estimates of the distinct real roots, ascending: the roots of the derivative (recursively)
/// split `[−B, B]` (Cauchy's bound) into monotone pieces, and each piece whose ends differ in
/// sign is bisected in `f64`.
fn estimates(c: &[f64]) -> Vec<f64> {
    let n = c.len() - 1;
    if n == 1 {
        return vec![-c[0] / c[1]];
    }
    let bound = 1.0 + c[..n].iter().map(|x| (x / c[n]).abs()).fold(0.0, f64::max);
    if !bound.is_finite() {
        return vec![];
    }
    let derivative: Vec<f64> = (1..=n).map(|i| c[i] * i as f64).collect();
    let mut cuts = vec![-bound];
    cuts.extend(
        estimates(&derivative)
            .into_iter()
            .filter(|x| x.abs() < bound),
    );
    cuts.push(bound);
    let mut out = vec![];
    for w in cuts.windows(2) {
        let (mut lo, mut hi) = (w[0], w[1]);
        let (slo, shi) = (horner(c, lo), horner(c, hi));
        if slo == 0.0 {
            out.push(lo);
            continue;
        }
        if slo.signum() == shi.signum() || shi == 0.0 {
            continue;
        }
        // Bisection on the f64 line (ordinal midpoints: any range in ≤ 64 steps)
        loop {
            let (a, b) = (ordinal(lo, Precision::F64), ordinal(hi, Precision::F64));
            if b as i128 - a as i128 <= 1 {
                break;
            }
            let m = from_ordinal(((a as i128 + b as i128) / 2) as i64, Precision::F64);
            if horner(c, m).signum() == slo.signum() {
                lo = m;
            } else {
                hi = m;
            }
        }
        out.push(hi);
    }
    out.dedup();
    out
}

/// The float of the precision that the root near estimate `x` rounds to, proved: exact signs
/// at floats walked from the estimate (galloping, then halving) find two adjacent floats with
/// opposite signs, and the sign at their rounding boundary picks one.
fn proved(c: &[f64], x: f64, prec: Precision) -> Option<f64> {
    let o0 = ordinal(round(x, prec), prec);
    // The sign at the float of ordinal `o` (`Some(None)`: `p` vanishes there)
    let at = |o: i64| {
        let f = from_ordinal(o, prec);
        f.is_finite().then(|| boundary_sign(c, f, f, prec))
    };
    let Some(s0) = at(o0)? else {
        return Some(from_ordinal(o0, prec));
    };
    // Walk toward the root: down if the estimate is on the root's right (where p has the
    // derivative's sign), else up; double the step until the sign changes
    let derivative: Vec<f64> = (1..c.len()).map(|i| c[i] * i as f64).collect();
    let dir = if f64::from(s0) == horner(&derivative, x).signum() {
        -1
    } else {
        1
    };
    let (mut near, mut step) = (o0, 1i64);
    let mut far = loop {
        if step > 1 << 12 {
            return None;
        }
        let o = o0 + dir * step;
        match at(o)? {
            None => return Some(from_ordinal(o, prec)),
            Some(s) if s == s0 => (near, step) = (o, step * 2),
            Some(_) => break o,
        }
    };
    // Halve until the two floats are adjacent
    while (far - near).abs() > 1 {
        let mid = near + (far - near) / 2;
        match at(mid)? {
            None => return Some(from_ordinal(mid, prec)),
            Some(s) if s == s0 => near = mid,
            Some(_) => far = mid,
        }
    }
    // The root is strictly between them: the sign at the boundary decides (a tie: give up)
    let (lo, hi) = (near.min(far), near.max(far));
    let (a, b) = (from_ordinal(lo, prec), from_ordinal(hi, prec));
    let s_lo = if lo == near { s0 } else { -s0 };
    Some(if boundary_sign(c, a, b, prec)? == s_lo {
        b
    } else {
        a
    })
}

fn round(x: f64, prec: Precision) -> f64 {
    match prec {
        Precision::F32 => x as f32 as f64,
        Precision::F64 => x,
    }
}

/// The sign (±1; `None` for an exact zero) of `p` at the exact midpoint of floats `a ≤ b` of
/// the precision, adjacent or equal.
fn boundary_sign(c: &[f64], a: f64, b: f64, prec: Precision) -> Option<i8> {
    if prec == Precision::F32 || a == b {
        // A float, or the midpoint of two adjacent f32 values, is an f64: f64 intervals first
        let m = Interval::point(a * 0.5 + b * 0.5);
        let c0 = Interval::point(c[c.len() - 1]);
        let v: BoxIv = c[..c.len() - 1]
            .iter()
            .rev()
            .fold(c0, |acc, &k| acc * m + Interval::point(k));
        if let Some(s) = strict_sign(v) {
            return Some(s);
        }
    }
    exact_sign(c, a, b)
}

/// The exact sign of `p((a + b)/2)` (±1, or `None` for zero), in integers: the midpoint is
/// `M·2^e` and each coefficient `Cᵢ·2^fᵢ`, so `p` is `Σ Cᵢ·Mⁱ·2^(fᵢ + i·e)`.
fn exact_sign(c: &[f64], a: f64, b: f64) -> Option<i8> {
    let ((ma, ea), (mb, eb)) = (decompose(a), decompose(b));
    let e0 = ea.min(eb);
    let m = (Integer::from(ma) << (ea - e0) as u32) + (Integer::from(mb) << (eb - e0) as u32);
    let e = e0 - 1;
    let terms: Vec<(Integer, i64)> = c
        .iter()
        .enumerate()
        .filter(|(_, &k)| k != 0.0)
        .map(|(i, &k)| {
            let (ck, fk) = decompose(k);
            let value = Integer::from(ck) * Integer::from(rug::ops::Pow::pow(&m, i as u32));
            (value, fk as i64 + i as i64 * e as i64)
        })
        .collect();
    let g = terms.iter().map(|t| t.1).min()?;
    let sum: Integer = terms.into_iter().map(|(v, k)| v << (k - g) as u32).sum();
    match sum.cmp0() {
        std::cmp::Ordering::Greater => Some(1),
        std::cmp::Ordering::Less => Some(-1),
        std::cmp::Ordering::Equal => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::oracle::sturm;

    fn exact(c: &[f64], prec: Precision) -> Vec<f64> {
        sturm::rounded_roots(&sturm::exact_coeffs(c), prec)
    }

    #[test]
    fn agrees_with_sturm_where_it_answers() {
        let polys: &[&[f64]] = &[
            &[-2.0, 0.0, 1.0],                // ±√2
            &[1.0, 0.0, 1.0],                 // none
            &[-6.0, 11.0, -6.0, 1.0],         // 1, 2, 3 (exact roots)
            &[-1.0, 0.0, 0.0, 3.0],           // ∛(1/3)
            &[24.0, -50.0, 35.0, -10.0, 1.0], // 1, 2, 3, 4
            &[2.0, -3.0, 3.0, -3.0, 1.0],     // 1, 2
            &[1.0, 0.0, 5.0, 0.0, 1.0],       // none
            &[1e-30, -3.0, 1e10],             // widely spread
            &[0.1, -0.7, 1.3, 0.2, -0.9],
        ];
        for c in polys {
            for prec in Precision::ALL {
                let quick = rounded_roots(c, prec);
                assert!(quick.is_some(), "{c:?} {prec:?}: the quick phase gave up");
                assert_eq!(quick.unwrap(), exact(c, prec), "{c:?} {prec:?}");
            }
        }
    }

    #[test]
    fn a_double_root_is_left_to_the_exact_path() {
        assert_eq!(rounded_roots(&[1.0, -2.0, 1.0], Precision::F64), None);
        assert_eq!(
            rounded_roots(&[6.0, -17.0, 17.0, -7.0, 1.0], Precision::F32),
            None
        );
    }
}
