//! The arithmetic a method body needs ([`Scalar`]) and one rounding from a wider type
//! ([`RoundTo`]): implemented by `f32`, `f64` (in [`super::real`]) and the double-double
//! [`super::dd::DD`], so that the same body runs in all three.

use std::fmt::Debug;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Arithmetic a method body needs. Implemented by `f32`, `f64` and the double-double [`crate::numerics::dd::DD`].
pub trait Scalar:
    Copy
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// Square root: correctly rounded for `f32` and `f64`; for `DD` one Newton step from the
    /// `f64` root (relative error a small multiple of 2⁻¹⁰⁴).
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// `self` with the sign of `s` (IEEE `copysign`).
    fn copysign(self, s: Self) -> Self;
    /// Nearest value of the type to `x`.
    fn from_f64(x: f64) -> Self;
}

/// Rounds a wider value once to the narrow type.
pub trait RoundTo<T> {
    /// The value rounded once to `T`.
    fn round_to(self) -> T;
}
impl RoundTo<f32> for f64 {
    fn round_to(self) -> f32 {
        self as f32
    }
}
