//! The float trait every method is written against, instantiated for `f32` and `f64`.
//!
//! Methods are written once over [`Scalar`] (plain arithmetic, so that the double-double type
//! [`crate::numerics::dd::DD`] can stand in for a wider precision) and over [`Real`] (an IEEE binary
//! format with bit access, ulps and hex printing). One `impl_real!` line per type.

pub use super::scalar::{RoundTo, Scalar};
use std::fmt::Debug;

/// An IEEE-754 binary format: `f32` or `f64`.
pub trait Real: Scalar + Send + Sync + 'static + std::fmt::Display {
    /// The glam vector of this precision (`Vec3` or `DVec3`).
    type Vec3: Copy + Debug + Send + Sync;
    /// A format with roughly twice the significand: `f64` for `f32`, double-double for `f64`.
    type Wide: Scalar;
    /// `"f32"` or `"f64"`.
    const NAME: &'static str;
    /// Significand bits including the implicit one (24 or 53).
    const MANT_BITS: u32;
    /// Positive infinity.
    const INFINITY: Self;
    /// A quiet NaN.
    const NAN: Self;

    /// The exact value as `f64` (every `f32` is one).
    fn to_f64(self) -> f64;
    /// The bit pattern, zero-extended.
    fn to_bits_u64(self) -> u64;
    /// The value with this bit pattern (the low 32 bits for `f32`).
    fn from_bits_u64(b: u64) -> Self;
    /// The next float towards +∞ (IEEE `nextUp`).
    fn next_up(self) -> Self;
    /// The next float towards −∞ (IEEE `nextDown`).
    fn next_down(self) -> Self;
    /// Neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// NaN.
    fn is_nan(self) -> bool;
    /// `self·a + b` rounded once (fused multiply–add).
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// The value in [`Real::Wide`], exactly.
    fn widen(self) -> Self::Wide;
    /// The wide value rounded once to this precision (round to nearest, ties to even).
    fn narrow(w: Self::Wide) -> Self;
    /// A glam vector of this precision.
    fn vec3(x: Self, y: Self, z: Self) -> Self::Vec3;
    /// A glam vector's components.
    fn unvec3(v: Self::Vec3) -> [Self; 3];
    /// Parses decimal or C99 hex-float text, rounding once to this precision.
    fn parse(s: &str) -> Option<Self>;

    /// Position of `self` on the number line of this format: adjacent floats differ by one,
    /// `-0.0` and `+0.0` share ordinal 0 (as in Herbie and libm-test).
    fn ordinal(self) -> i64 {
        let bits = self.to_bits_u64();
        let sign_bit = 1u64 << (if Self::MANT_BITS == 24 { 31 } else { 63 });
        let mag = (bits & (sign_bit - 1)) as i64;
        if bits & sign_bit != 0 {
            -mag
        } else {
            mag
        }
    }

    /// Distance in ulps between two finite values of this format.
    fn ulps_between(self, other: Self) -> u64 {
        (self.ordinal() - other.ordinal()).unsigned_abs()
    }

    /// C99 `%a` text of the exact value, e.g. `0x1.8p+1`.
    fn hex(self) -> String {
        hex_float(self.to_f64())
    }
}

/// Formats an `f64` (and so any `f32`, exactly) as a C99 hex float: `-0x1.2p-3`, `0x0p+0`, `inf`, `nan`.
pub fn hex_float(x: f64) -> String {
    if x.is_nan() {
        return "nan".into();
    }
    let sign = if x.is_sign_negative() { "-" } else { "" };
    if x.is_infinite() {
        return format!("{sign}inf");
    }
    if x == 0.0 {
        return format!("{sign}0x0p+0");
    }
    // Normalise subnormals so that the text always reads 0x1.xxx
    let bits = x.abs().to_bits();
    let (mut mant, mut exp) = ((bits & ((1u64 << 52) - 1)), ((bits >> 52) as i64) - 1023);
    if exp == -1023 {
        let shift = mant.leading_zeros() as i64 - 11;
        mant = (mant << shift) & ((1u64 << 52) - 1);
        exp = -1022 - shift;
    }
    let mut digits = format!("{mant:013x}");
    while digits.ends_with('0') {
        digits.pop();
    }
    let frac = if digits.is_empty() {
        String::new()
    } else {
        format!(".{digits}")
    };
    format!("{sign}0x1{frac}p{exp:+}")
}

/// A number as text, decimal or C99 hex float, rounded once to `f64` ([`parse_number_in`]).
pub fn parse_f64(s: &str) -> Option<f64> {
    parse_number_in(s, "f64").ok()
}

/// Parses decimal or C99 hex-float text as a value of precision `prec` ("f32" or "f64"), rounded
/// once; `inf`, `-inf` and `nan` as spelled. The same rules for both notations: a literal too
/// large for the precision is an error, not an infinity, and a non-zero literal that would
/// round to 0 is an error, not a zero; hex text must be exact in `f64`. The error says which.
pub fn parse_number_in(s: &str, prec: &str) -> Result<f64, String> {
    let t = s.trim();
    let lower = t.to_ascii_lowercase();
    let body = lower.trim_start_matches(['+', '-']);
    if matches!(body, "inf" | "infinity" | "nan") {
        return t
            .parse::<f64>()
            .map_err(|_| format!("'{s}' is not a number"));
    }
    // The value, once rounded, and whether the literal itself is zero
    let (v, literal_zero) = if body.starts_with("0x") {
        let with_p = if lower.contains('p') {
            lower.clone()
        } else {
            format!("{lower}p0")
        };
        let v = hexf_parse::parse_hexf64(&with_p, false).map_err(|_| {
            format!("'{s}' is not a hex float exact in f64 (too large, too small, too many digits, or malformed)")
        })?;
        (v, v == 0.0)
    } else {
        let v = t
            .parse::<f64>()
            .map_err(|_| format!("'{s}' is not a number"))?;
        let mantissa = body.split('e').next().unwrap_or("");
        (v, !mantissa.chars().any(|c| ('1'..='9').contains(&c)))
    };
    let v = if prec == "f32" {
        if body.starts_with("0x") {
            v as f32 as f64
        } else {
            t.parse::<f32>()
                .map_err(|_| format!("'{s}' is not a number"))? as f64
        }
    } else {
        v
    };
    if v.is_infinite() {
        return Err(format!(
            "'{s}' overflows {prec} (write inf for an infinity)"
        ));
    }
    if v == 0.0 && !literal_zero {
        return Err(format!("'{s}' underflows {prec} to 0 (write 0 for a zero)"));
    }
    Ok(v)
}

macro_rules! impl_scalar {
    ($t:ty) => {
        impl Scalar for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn copysign(self, s: Self) -> Self {
                <$t>::copysign(self, s)
            }
            #[inline(always)]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
        }
    };
}
impl_scalar!(f32);
impl_scalar!(f64);

macro_rules! impl_real {
    ($t:ty, $bits:ty, $vec:ty, $wide:ty, $mant:expr, $name:expr, $parse:expr) => {
        impl Real for $t {
            type Vec3 = $vec;
            type Wide = $wide;
            const NAME: &'static str = $name;
            const MANT_BITS: u32 = $mant;
            const INFINITY: Self = <$t>::INFINITY;
            const NAN: Self = <$t>::NAN;
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn to_bits_u64(self) -> u64 {
                self.to_bits() as u64
            }
            #[inline(always)]
            fn from_bits_u64(b: u64) -> Self {
                <$t>::from_bits(b as $bits)
            }
            #[inline(always)]
            fn next_up(self) -> Self {
                <$t>::next_up(self)
            }
            #[inline(always)]
            fn next_down(self) -> Self {
                <$t>::next_down(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline(always)]
            fn is_nan(self) -> bool {
                <$t>::is_nan(self)
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                <$t>::mul_add(self, a, b)
            }
            #[inline(always)]
            fn widen(self) -> $wide {
                <$wide>::from(self)
            }
            #[inline(always)]
            fn narrow(w: $wide) -> Self {
                w.round_to()
            }
            #[inline(always)]
            fn vec3(x: Self, y: Self, z: Self) -> $vec {
                <$vec>::new(x, y, z)
            }
            #[inline(always)]
            fn unvec3(v: $vec) -> [Self; 3] {
                v.to_array()
            }
            fn parse(s: &str) -> Option<Self> {
                $parse(s)
            }
        }
    };
}

/// `f32` text parsed with one rounding: decimal through Rust's correctly rounded parser; hex floats
/// through the exact `f64` value (hex text of at most 53 significant bits), then rounded once.
fn parse_f32(s: &str) -> Option<f32> {
    parse_number_in(s, "f32").ok().map(|x| x as f32)
}

impl_real!(f32, u32, glam::Vec3, f64, 24, "f32", parse_f32);
impl_real!(
    f64,
    u64,
    glam::DVec3,
    crate::numerics::dd::DD,
    53,
    "f64",
    parse_f64
);

/// pbrt's `gamma(n) = nε/(1 − nε)`, with ε half the machine epsilon of `F`.
pub fn gamma<F: Real>(n: u32) -> F {
    let eps = F::from_f64(0.5 * 2f64.powi(1 - F::MANT_BITS as i32));
    let ne = F::from_f64(n as f64) * eps;
    ne / (F::ONE - ne)
}

/// ⌊log₂|x|⌋ for finite non-zero `x` (subnormals included); 0 otherwise.
pub fn ilogb(x: f64) -> i32 {
    if x == 0.0 || !x.is_finite() {
        return 0;
    }
    let bits = x.abs().to_bits();
    let e = ((bits >> 52) & 0x7ff) as i32;
    if e == 0 {
        -1023 - ((bits << 12).leading_zeros() as i32)
    } else {
        e - 1023
    }
}

/// `x·2^k`, exact unless the result over- or underflows; for types with `f64`'s exponent range.
pub fn mul_pow2<S: Scalar>(mut x: S, mut k: i32) -> S {
    // 2^k for |k| ≤ 512, built from its bits (powi is a library call)
    let pow2 = |k: i32| f64::from_bits(((k + 1023) as u64) << 52);
    while k.abs() > 512 {
        let step = 512 * k.signum();
        x = x * S::from_f64(pow2(step));
        k -= step;
    }
    x * S::from_f64(pow2(k))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trips() {
        for x in [1.0, -0.0, 0.1, 3.0, f64::MIN_POSITIVE / 8.0, 1e300, -2.5e-7] {
            assert_eq!(parse_f64(&hex_float(x)), Some(x), "{}", hex_float(x));
        }
        assert_eq!(hex_float(3.0), "0x1.8p+1");
        assert_eq!(hex_float(1.0), "0x1p+0");
        assert_eq!((0.1f32).hex(), "0x1.99999ap-4");
    }

    #[test]
    fn ordinals_count_ulps() {
        assert_eq!(1.0f32.ulps_between(1.0f32.next_up()), 1);
        assert_eq!((-0.0f64).ulps_between(0.0), 0);
        assert_eq!((-f64::from_bits(1)).ulps_between(f64::from_bits(1)), 2);
    }
}
