//! Outward-rounded interval arithmetic over `f32`/`f64`, in the manner of pbrt-v4's `Interval`.
//!
//! Every operation computes in round-to-nearest and then widens each end by one ulp
//! (`next_down`/`next_up`), so the result contains the exact result of the operation applied to
//! any points of the operands. An empty or invalid operation yields `[-inf, +inf]` or NaN ends,
//! which every caller treats as "undecided".

use crate::numerics::real::Real;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A closed interval `[lo, hi]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval<F> {
    /// Lower end.
    pub lo: F,
    /// Upper end.
    pub hi: F,
}

#[inline(always)]
fn min4<F: Real>(a: F, b: F, c: F, d: F) -> F {
    let m = |x: F, y: F| if y < x || x.is_nan() { y } else { x };
    m(m(a, b), m(c, d))
}

#[inline(always)]
fn max4<F: Real>(a: F, b: F, c: F, d: F) -> F {
    let m = |x: F, y: F| if y > x || x.is_nan() { y } else { x };
    m(m(a, b), m(c, d))
}

impl<F: Real> Interval<F> {
    /// The exact point `x`.
    #[inline(always)]
    pub fn point(x: F) -> Self {
        Interval { lo: x, hi: x }
    }
    /// `[lo, hi]`, for callers that already know the order.
    #[inline(always)]
    pub fn new(lo: F, hi: F) -> Self {
        Interval { lo, hi }
    }
    /// The whole line: what an undecidable operation returns.
    pub fn everything() -> Self {
        Interval {
            lo: -F::INFINITY,
            hi: F::INFINITY,
        }
    }
    /// `{x² : x ∈ self}`, outward rounded (from 0 when the interval contains 0).
    #[inline(always)]
    pub fn square(self) -> Self {
        let (a, b) = (self.lo * self.lo, self.hi * self.hi);
        if self.lo <= F::ZERO && self.hi >= F::ZERO {
            let m = if a > b { a } else { b };
            Interval::new(F::ZERO, m.next_up())
        } else if a < b {
            Interval::new(a.next_down(), b.next_up())
        } else {
            Interval::new(b.next_down(), a.next_up())
        }
    }
    /// `{√x : x ∈ self, x ≥ 0}`, outward rounded: the lower end is 0 when the interval reaches 0
    /// or below; an interval wholly below 0 gets a NaN upper end.
    #[inline(always)]
    pub fn sqrt(self) -> Self {
        let lo = if self.lo > F::ZERO {
            self.lo.sqrt().next_down()
        } else {
            F::ZERO
        };
        Interval::new(
            if lo < F::ZERO { F::ZERO } else { lo },
            self.hi.sqrt().next_up(),
        )
    }
    /// Midpoint, the value pbrt reports as the interval's float.
    #[inline(always)]
    pub fn mid(self) -> F {
        let h = F::from_f64(0.5);
        self.lo * h + self.hi * h
    }
    /// True when every point of the interval is strictly positive.
    #[inline(always)]
    pub fn surely_positive(self) -> bool {
        self.lo > F::ZERO
    }
    /// True when every point is strictly negative.
    #[inline(always)]
    pub fn surely_negative(self) -> bool {
        self.hi < F::ZERO
    }
    /// True when the interval is the single point zero.
    #[inline(always)]
    pub fn surely_zero(self) -> bool {
        self.lo == F::ZERO && self.hi == F::ZERO
    }
    /// The sign of every point, if they share one (`Some(0)` only for the point zero).
    #[inline(always)]
    pub fn sign(self) -> Option<i8> {
        if self.surely_positive() {
            Some(1)
        } else if self.surely_negative() {
            Some(-1)
        } else if self.surely_zero() {
            Some(0)
        } else {
            None
        }
    }
    /// Does the interval contain `x`?
    pub fn contains(self, x: F) -> bool {
        self.lo <= x && x <= self.hi
    }
}

impl<F: Real> Add for Interval<F> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Interval::new((self.lo + o.lo).next_down(), (self.hi + o.hi).next_up())
    }
}

impl<F: Real> Sub for Interval<F> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Interval::new((self.lo - o.hi).next_down(), (self.hi - o.lo).next_up())
    }
}

impl<F: Real> Neg for Interval<F> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Interval::new(-self.hi, -self.lo)
    }
}

impl<F: Real> Mul for Interval<F> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let p = [
            self.lo * o.lo,
            self.lo * o.hi,
            self.hi * o.lo,
            self.hi * o.hi,
        ];
        Interval::new(
            min4(p[0], p[1], p[2], p[3]).next_down(),
            max4(p[0], p[1], p[2], p[3]).next_up(),
        )
    }
}

impl<F: Real> Div for Interval<F> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        // A divisor that may be zero gives no information
        if !(o.lo > F::ZERO || o.hi < F::ZERO) {
            return Interval::everything();
        }
        let q = [
            self.lo / o.lo,
            self.lo / o.hi,
            self.hi / o.lo,
            self.hi / o.hi,
        ];
        Interval::new(
            min4(q[0], q[1], q[2], q[3]).next_down(),
            max4(q[0], q[1], q[2], q[3]).next_up(),
        )
    }
}

/// Scales by an exact constant (a power of two), rounding outward.
impl<F: Real> Mul<F> for Interval<F> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, k: F) -> Self {
        self * Interval::point(k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encloses_exact_results() {
        let third = Interval::point(1.0f32) / Interval::point(3.0f32);
        let exact = 1.0f64 / 3.0;
        assert!((third.lo as f64) < exact && exact < third.hi as f64);
        let s = Interval::point(2.0f64).sqrt();
        assert!(s.lo * s.lo <= 2.0 && s.hi * s.hi >= 2.0);
        assert_eq!(Interval::new(-1.0f32, 2.0).square().lo, 0.0);
        assert_eq!(
            (Interval::point(1.0f32) / Interval::new(-1.0, 1.0)).hi,
            f32::INFINITY
        );
    }
}
