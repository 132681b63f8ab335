//! The cheap, rigorous filter every oracle's ill-posedness test tries first, as the sphere's
//! does: a case is **ill-posed** when moving one input by one ulp of its precision (up or down)
//! changes the exact answer's discrete outcome (hit or miss, which root, how many roots). Doing
//! that exactly takes two exact decisions per input (16 to 30 per case), which is most of an
//! exact oracle's time. Instead, every input is widened to the box of its two neighbours
//! ([`ulp_box`]) and the outcome is computed once in outward-rounded `f64` interval arithmetic
//! over the whole box. If every sign the outcome depends on is certain on the box, no single
//! move (each a point of the box) can change it, and the case is well-posed; only when the box
//! cannot decide does the oracle make its one-move-at-a-time exact decisions.
//!
//! For a polynomial whose coefficients range over a box, the number of distinct real roots is
//! constant when the leading coefficient and the discriminant keep their signs on the box
//! ([`roots_keep_count`]): real roots move continuously with the coefficients and can appear
//! or vanish only by colliding (discriminant 0) or leaving to infinity (leading coefficient 0).

use crate::numerics::exact::nudge;
use crate::numerics::interval::Interval;
use crate::numerics::Precision;
use std::cell::Cell;

/// An `f64` interval.
pub type BoxIv = Interval<f64>;

thread_local! {
    static OFF: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f` with the filters off on this thread (this one, and the quick phase of the roots
/// oracle, `shapes::oracle::quick_roots`), so that every decision is made exactly: what the tests
/// compare the filtered oracles against.
pub fn without_filter<T>(f: impl FnOnce() -> T) -> T {
    OFF.with(|off| {
        let was = off.replace(true);
        let out = f();
        off.set(was);
        out
    })
}

/// Whether the oracles' quick phases may run on this thread (see [`without_filter`]).
pub fn filters_on() -> bool {
    !OFF.with(Cell::get)
}

/// Each input widened to `[one ulp down, one ulp up]` in its precision, or `None` when some
/// input or neighbour is not finite (the filter then has nothing to say) or the filter is off.
pub fn ulp_box(v: &[f64], prec: Precision) -> Option<Vec<BoxIv>> {
    if !filters_on() {
        return None;
    }
    v.iter()
        .map(|&x| {
            let (lo, hi) = (nudge(x, prec, false), nudge(x, prec, true));
            (lo.is_finite() && hi.is_finite()).then(|| Interval::new(lo, hi))
        })
        .collect()
}

/// `x · 2^k` rounded outward (exact unless it leaves the normal range).
fn scale(x: BoxIv, k: i32) -> BoxIv {
    x * 2f64.powi(k)
}

/// The coefficients (ascending) scaled by one power of two so that the largest magnitude is
/// about 1: the discriminant is homogeneous in them, so its sign is unchanged, and nothing
/// overflows on the way.
pub(crate) fn normalised(c: &[BoxIv]) -> Vec<BoxIv> {
    let big = c
        .iter()
        .map(|x| x.lo.abs().max(x.hi.abs()))
        .fold(0.0f64, f64::max);
    if !(big > 0.0 && big.is_finite()) {
        return c.to_vec();
    }
    let k = -(big.log2().floor() as i32);
    c.iter().map(|&x| scale(x, k)).collect()
}

/// An enclosure of the discriminant of the polynomial `Σ cᵢ xⁱ` (ascending, degree 2 to 4,
/// scaled as [`normalised`] does), by the classical formulas.
pub(crate) fn discriminant(c: &[BoxIv]) -> BoxIv {
    let p = |k: f64| Interval::point(k);
    match c.len() {
        3 => {
            let (cc, b, a) = (c[0], c[1], c[2]);
            b.square() - p(4.0) * a * cc
        }
        4 => {
            let (d, cc, b, a) = (c[0], c[1], c[2], c[3]);
            b.square() * cc.square()
                - p(4.0) * a * cc.square() * cc
                - p(4.0) * b.square() * b * d
                - p(27.0) * a.square() * d.square()
                + p(18.0) * a * b * cc * d
        }
        5 => {
            let (e, d, cc, b, a) = (c[0], c[1], c[2], c[3], c[4]);
            let (a2, b2, c2, d2, e2) =
                (a.square(), b.square(), cc.square(), d.square(), e.square());
            p(256.0) * a2 * a * e2 * e - p(192.0) * a2 * b * d * e2 - p(128.0) * a2 * c2 * e2
                + p(144.0) * a2 * cc * d2 * e
                - p(27.0) * a2 * d2.square()
                + p(144.0) * a * b2 * cc * e2
                - p(6.0) * a * b2 * d2 * e
                - p(80.0) * a * b * c2 * d * e
                + p(18.0) * a * b * cc * d2 * d
                + p(16.0) * a * c2.square() * e
                - p(4.0) * a * c2 * cc * d2
                - p(27.0) * b2.square() * e2
                + p(18.0) * b2 * b * cc * d * e
                - p(4.0) * b2 * b * d2 * d
                - p(4.0) * b2 * c2 * cc * e
                + b2 * c2 * d2
        }
        _ => Interval::everything(),
    }
}

/// Whether every polynomial with coefficients (ascending, degree 1 to 4) in the given
/// intervals has the same number of distinct real roots, all simple: the leading coefficient
/// and (degree ≥ 2) the discriminant keep one strict sign over the box.
pub fn roots_keep_count(c: &[BoxIv]) -> bool {
    let c = normalised(c);
    let lead_sure = c.last().is_some_and(|l| matches!(l.sign(), Some(1 | -1)));
    lead_sure && (c.len() == 2 || matches!(discriminant(&c).sign(), Some(1 | -1)))
}

/// An outcome decided on a box, if every sign it rests on is certain there.
pub fn strict_sign(x: BoxIv) -> Option<i8> {
    match x.sign() {
        Some(s) if s != 0 => Some(s),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(c: &[f64]) -> Vec<BoxIv> {
        c.iter().map(|&x| Interval::point(x)).collect()
    }

    #[test]
    fn discriminants_have_the_right_sign() {
        // (x−1)(x−2): 1; x² + 1: −4
        assert_eq!(discriminant(&pt(&[2.0, -3.0, 1.0])).sign(), Some(1));
        assert_eq!(discriminant(&pt(&[1.0, 0.0, 1.0])).sign(), Some(-1));
        // (x−1)(x−2)(x−3): 4 > 0; x³ − x² + x − 1 = (x−1)(x²+1): < 0
        assert_eq!(discriminant(&pt(&[-6.0, 11.0, -6.0, 1.0])).sign(), Some(1));
        assert_eq!(discriminant(&pt(&[-1.0, 1.0, -1.0, 1.0])).sign(), Some(-1));
        // (x−1)(x−2)(x−3)(x−4) > 0; (x−1)(x−2)(x²+1) < 0; (x−1)²(x−2)(x−3) = 0
        assert_eq!(
            discriminant(&pt(&[24.0, -50.0, 35.0, -10.0, 1.0])).sign(),
            Some(1)
        );
        assert_eq!(
            discriminant(&pt(&[2.0, -3.0, 3.0, -3.0, 1.0])).sign(),
            Some(-1)
        );
        // An exact zero is enclosed, never given a strict sign
        let zero = discriminant(&pt(&[6.0, -17.0, 17.0, -7.0, 1.0]));
        assert!(
            zero.contains(0.0) && strict_sign(zero).is_none(),
            "{zero:?}"
        );
    }

    #[test]
    fn a_double_root_or_a_vanishing_lead_is_never_kept() {
        assert!(roots_keep_count(&pt(&[2.0, -3.0, 1.0])));
        assert!(!roots_keep_count(&pt(&[1.0, -2.0, 1.0])));
        assert!(!roots_keep_count(&pt(&[6.0, -17.0, 17.0, -7.0, 1.0])));
        let b = ulp_box(&[1e-45f32 as f64, 1.0, 1.0], Precision::F32).unwrap();
        assert!(!roots_keep_count(&[b[1], b[2], b[0]]));
    }
}
