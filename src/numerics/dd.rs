//! Double-double arithmetic: an unevaluated sum `hi + lo` of two `f64` with |lo| ≤ ½ulp(hi),
//! about 106 significant bits. It is the "wider type" of `f64` for the `promote` method.
//!
//! Algorithms: Dekker/Knuth error-free transformations (`two_sum`, `two_prod` by FMA), and the
//! accurate division and square root of Hida, Li & Bailey's QD library, written from their
//! published formulas. Relative error of each operation is a small multiple of 2⁻¹⁰⁴.

use super::scalar::{RoundTo, Scalar};
use std::cmp::Ordering;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A double-double number `hi + lo`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DD {
    /// The leading part: the pair's sum rounded to `f64`.
    pub hi: f64,
    /// The remainder, `|lo| ≤ ½ ulp(hi)`.
    pub lo: f64,
}

/// Error-free sum (Knuth's TwoSum): `a + b = s + e` exactly, for finite `a + b`.
#[inline(always)]
pub(crate) fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

// Error-free sum when |a| ≥ |b|
#[inline(always)]
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

/// Error-free product without FMA (Dekker's product, Veltkamp's split): `a·b = p + e` exactly
/// when `|a|, |b| < 2⁹⁹⁶` and nothing underflows. Faster than [`two_prod`] where FMA is a
/// library call (a build without `target-feature=+fma`).
#[inline(always)]
pub(crate) fn two_prod_split(a: f64, b: f64) -> (f64, f64) {
    const SPLIT: f64 = 134_217_729.0; // 2^27 + 1
    let split = |x: f64| {
        let g = SPLIT * x;
        let hi = g - (g - x);
        (hi, x - hi)
    };
    let p = a * b;
    let ((ah, al), (bh, bl)) = (split(a), split(b));
    (p, ((ah * bh - p) + ah * bl + al * bh) + al * bl)
}

/// Error-free product by FMA: `a·b = p + e` exactly (barring underflow, where `e` is within
/// `2⁻¹⁰⁷⁵`). One instruction more than the product where the CPU has FMA and the code is
/// compiled for it; a library call otherwise.
#[inline(always)]
pub(crate) fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

impl DD {
    /// The pair `hi + lo` as given (not renormalised).
    pub const fn new(hi: f64, lo: f64) -> Self {
        DD { hi, lo }
    }
}

impl From<f64> for DD {
    fn from(x: f64) -> Self {
        DD { hi: x, lo: 0.0 }
    }
}

impl RoundTo<f64> for DD {
    /// `hi + lo` rounded once: exact, since `hi` is already the nearest double of the pair's sum.
    fn round_to(self) -> f64 {
        self.hi + self.lo
    }
}

impl Add for DD {
    type Output = DD;
    #[inline(always)]
    fn add(self, b: DD) -> DD {
        // IEEE-style accurate addition (QD `ieee_add`)
        let (s1, s2) = two_sum(self.hi, b.hi);
        let (t1, t2) = two_sum(self.lo, b.lo);
        let (s1, s2) = quick_two_sum(s1, s2 + t1);
        let (hi, lo) = quick_two_sum(s1, s2 + t2);
        DD { hi, lo }
    }
}

impl Neg for DD {
    type Output = DD;
    #[inline(always)]
    fn neg(self) -> DD {
        DD {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Sub for DD {
    type Output = DD;
    #[inline(always)]
    fn sub(self, b: DD) -> DD {
        self + (-b)
    }
}

impl Mul for DD {
    type Output = DD;
    #[inline(always)]
    fn mul(self, b: DD) -> DD {
        let (p, e) = two_prod(self.hi, b.hi);
        let e = e + (self.hi * b.lo + self.lo * b.hi);
        let (hi, lo) = quick_two_sum(p, e);
        DD { hi, lo }
    }
}

impl Div for DD {
    type Output = DD;
    #[inline(always)]
    fn div(self, b: DD) -> DD {
        // Long division in three partial quotients (QD `accurate_div`)
        let q1 = self.hi / b.hi;
        let r = self - b * DD::from(q1);
        let q2 = r.hi / b.hi;
        let r = r - b * DD::from(q2);
        let q3 = r.hi / b.hi;
        let (hi, lo) = quick_two_sum(q1, q2);
        DD { hi, lo } + DD::from(q3)
    }
}

impl PartialOrd for DD {
    fn partial_cmp(&self, o: &DD) -> Option<Ordering> {
        match self.hi.partial_cmp(&o.hi)? {
            Ordering::Equal => self.lo.partial_cmp(&o.lo),
            ord => Some(ord),
        }
    }
}

impl Scalar for DD {
    const ZERO: DD = DD::new(0.0, 0.0);
    const ONE: DD = DD::new(1.0, 0.0);
    fn sqrt(self) -> DD {
        // One Newton step from the double root (Karp's trick): √a ≈ x + (a − x²)/(2x)
        if self.hi <= 0.0 || !self.hi.is_finite() {
            return DD::from(self.hi.sqrt());
        }
        let x = self.hi.sqrt();
        let (p, e) = two_prod(x, x);
        let r = (self - DD::new(p, e)).hi;
        let (hi, lo) = quick_two_sum(x, r / (2.0 * x));
        DD { hi, lo }
    }
    fn abs(self) -> DD {
        if self.hi < 0.0 {
            -self
        } else {
            self
        }
    }
    fn copysign(self, s: DD) -> DD {
        if (self.hi < 0.0) != s.hi.is_sign_negative() {
            -self
        } else {
            self
        }
    }
    fn from_f64(x: f64) -> DD {
        DD::from(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rug::Float;

    fn exact(x: DD) -> Float {
        Float::with_val(300, x.hi) + x.lo
    }

    #[test]
    fn operations_are_accurate_to_about_104_bits() {
        let a = DD::from(1.0) / DD::from(3.0);
        let b = DD::from(2.0).sqrt();
        let want_a = Float::with_val(300, 1) / 3u32;
        let want_b = Float::with_val(300, 2).sqrt();
        for (got, want) in [(exact(a), want_a), (exact(b), want_b)] {
            let rel = ((got - &want) / &want).abs().to_f64();
            assert!(rel < 2f64.powi(-102), "relative error {rel:e}");
        }
        let c = (DD::from(1e16) + DD::from(1.0)) - DD::from(1e16);
        assert_eq!(c.round_to(), 1.0);
    }
}
