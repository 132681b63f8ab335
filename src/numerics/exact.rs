//! Exact helpers shared by the routines' oracles: inputs as GMP rationals, correct rounding of an
//! exact rational, and Ziv's loop for values only MPFR enclosures can reach (roots).

use crate::numerics::Precision;
use rug::float::Round;
use rug::{Float, Rational};

/// The exact value of a finite `f64` (every `f32` input is an `f64` exactly).
pub fn q(x: f64) -> Rational {
    Rational::from_f64(x).expect("finite input")
}

/// `x = m·2^e` exactly (`m` odd or 0).
pub fn decompose(x: f64) -> (i64, i32) {
    if x == 0.0 {
        return (0, 0);
    }
    let bits = x.to_bits();
    let (eb, frac) = (
        ((bits >> 52) & 0x7ff) as i32,
        (bits & ((1u64 << 52) - 1)) as i64,
    );
    let (mut m, mut e) = if eb == 0 {
        (frac, -1074)
    } else {
        (frac | (1i64 << 52), eb - 1075)
    };
    let tz = m.trailing_zeros() as i32;
    m >>= tz;
    e += tz;
    (if x < 0.0 { -m } else { m }, e)
}

/// Whether every input is finite (the oracles call this first).
pub fn all_finite(input: &[f64]) -> bool {
    input.iter().all(|x| x.is_finite())
}

/// `x` rounded correctly (to nearest, ties to even) to the precision, returned as `f64`
/// (an `f32` result widened exactly). Overflow gives ±inf; subnormals are rounded as IEEE does.
pub fn round_q(x: &Rational, prec: Precision) -> f64 {
    let bits = match prec {
        Precision::F32 => 24,
        Precision::F64 => 53,
    };
    // Round once with an unbounded exponent, then again into IEEE's subnormal range
    let (mut f, ord) = Float::with_val_round(bits, x, Round::Nearest);
    f.subnormalize_ieee_round(ord, Round::Nearest);
    round_float(&f, prec, Round::Nearest)
}

/// `x` (an MPFR value that is exact or already correctly rounded far beyond the target)
/// rounded to the precision with `round`.
pub fn round_float(x: &Float, prec: Precision, round: Round) -> f64 {
    match prec {
        Precision::F32 => x.to_f32_round(round) as f64,
        Precision::F64 => x.to_f64_round(round),
    }
}

/// Ziv's loop: `enclose(bits)` returns `[lo, hi]` holding the exact value, computed with `bits`
/// of working precision. The precision doubles (from 128 up to `cap` bits) until both ends
/// round to the same value of the target precision; `None` when the cap is reached (a tie or
/// an exact zero that the enclosure cannot decide; the caller reports it as `cap_reached`).
pub fn ziv(
    prec: Precision,
    cap: u32,
    mut enclose: impl FnMut(u32) -> (Float, Float),
) -> Option<f64> {
    let mut bits = 128;
    while bits <= cap {
        let (lo, hi) = enclose(bits);
        let a = round_float(&lo, prec, Round::Nearest);
        let b = round_float(&hi, prec, Round::Nearest);
        if a.to_bits() == b.to_bits() || (a == 0.0 && b == 0.0) {
            return Some(a);
        }
        bits *= 2;
    }
    None
}

/// The default cap of [`ziv`] in bits.
pub const ZIV_CAP: u32 = 8192;

/// `√x` enclosed with `bits` of precision, for `x ≥ 0` exact.
pub fn sqrt_encl(x: &Rational, bits: u32) -> (Float, Float) {
    let mut lo = Float::with_val_round(bits, x, Round::Down).0;
    let mut hi = Float::with_val_round(bits, x, Round::Up).0;
    lo.sqrt_round(Round::Down);
    hi.sqrt_round(Round::Up);
    (lo, hi)
}

/// The input moved one ulp of its precision up (`up`) or down: the perturbations that decide
/// whether a case is ill-posed.
pub fn nudge(x: f64, prec: Precision, up: bool) -> f64 {
    match prec {
        Precision::F32 => {
            let v = x as f32;
            (if up { v.next_up() } else { v.next_down() }) as f64
        }
        Precision::F64 => {
            if up {
                x.next_up()
            } else {
                x.next_down()
            }
        }
    }
}

/// Whether `x` is exactly representable in the precision.
pub fn representable(x: f64, prec: Precision) -> bool {
    match prec {
        Precision::F32 => (x as f32) as f64 == x || x.is_nan(),
        Precision::F64 => true,
    }
}

/// Distance in ulps of the precision between two finite values (−0 and +0 are the same point).
pub fn ulps(a: f64, b: f64, prec: Precision) -> u64 {
    fn ord64(x: f64) -> i128 {
        let b = x.to_bits();
        let m = (b & !(1u64 << 63)) as i128;
        if b >> 63 == 1 {
            -m
        } else {
            m
        }
    }
    fn ord32(x: f32) -> i128 {
        let b = x.to_bits();
        let m = (b & !(1u32 << 31)) as i128;
        if b >> 31 == 1 {
            -m
        } else {
            m
        }
    }
    let d = match prec {
        Precision::F32 => ord32(a as f32) - ord32(b as f32),
        Precision::F64 => ord64(a) - ord64(b),
    };
    u64::try_from(d.unsigned_abs()).unwrap_or(u64::MAX)
}

/// The size of one ulp of the precision at `x` (the gap above `|x|`).
pub fn ulp(x: f64, prec: Precision) -> f64 {
    match prec {
        Precision::F32 => {
            let a = (x as f32).abs();
            (a.next_up() - a) as f64
        }
        Precision::F64 => {
            let a = x.abs();
            a.next_up() - a
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_and_ulps() {
        let third = Rational::from((1, 3));
        assert_eq!(round_q(&third, Precision::F32), (1.0f32 / 3.0) as f64);
        assert_eq!(round_q(&third, Precision::F64), 1.0 / 3.0);
        assert_eq!(ulps(1.0, 1.0f64.next_up(), Precision::F64), 1);
        assert_eq!(ulps(-0.0, 0.0, Precision::F32), 0);
        assert_eq!(ulps(1.0, (1.0f32).next_up() as f64, Precision::F32), 1);
        let two = Rational::from(2);
        let r = ziv(Precision::F64, ZIV_CAP, |b| sqrt_encl(&two, b));
        assert_eq!(r, Some(2f64.sqrt()));
        let r = ziv(Precision::F32, ZIV_CAP, |b| sqrt_encl(&two, b));
        assert_eq!(r, Some(2f32.sqrt() as f64));
    }
}
