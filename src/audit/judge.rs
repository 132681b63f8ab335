//! How one method's answer compares with the oracle's truth on one case: one rule for every
//! shape, after the one check of the answer contract ([`super::contract`]).

use super::contract;
use crate::numerics::{exact, Precision};
use crate::shapes::shape::{Answer, Expected, Metric, ShapeInfo, Truth};
use serde::{Deserialize, Serialize};

/// How one method's answer compares with the oracle on one case.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Judgement {
    /// Right verdict; for a hit, `ulps` from the correctly rounded value(s) by the metric.
    Ok {
        /// The value error by the shape's metric (`None` for a miss or an invalid case).
        ulps: Option<u64>,
    },
    /// Hit (or more roots) reported where the exact answer has fewer.
    FalseHit,
    /// Miss (or fewer roots) reported where the exact answer has more.
    FalseMiss,
    /// A first value nearer another exact candidate (the other root) than the right one.
    WrongRoot,
    /// A hit with a NaN or infinite value on valid input.
    NonfiniteT,
    /// Invalid input, reported as a miss (the right answer).
    Rejected,
    /// Invalid input, answered with a NaN or infinite value.
    InvalidNanT,
    /// Invalid input, answered with a finite hit.
    InvalidHit,
    /// An answer the contract does not allow (a count the shape cannot have, values that do not
    /// match the count): never right, on any case.
    Malformed,
    /// A hit outside the shape's interval (`t ≤ 0` for a ray): a wrong verdict.
    OutOfRange,
}

impl Judgement {
    /// The short verdict word used in JSON: ok, false_hit, false_miss, wrong_root, nonfinite_t,
    /// out_of_range, malformed, invalid.
    pub fn verdict_word(self) -> &'static str {
        match self {
            Judgement::Ok { .. } => "ok",
            Judgement::FalseHit => "false_hit",
            Judgement::FalseMiss => "false_miss",
            Judgement::WrongRoot => "wrong_root",
            Judgement::NonfiniteT => "nonfinite_t",
            Judgement::OutOfRange => "out_of_range",
            Judgement::Malformed => "malformed",
            Judgement::Rejected | Judgement::InvalidNanT | Judgement::InvalidHit => "invalid",
        }
    }
    /// A wrong answer on valid input (a wrong verdict when the case is well posed, a
    /// disagreement when it is ill-posed). A malformed answer is wrong on every case.
    pub fn is_wrong(self) -> bool {
        matches!(
            self,
            Judgement::FalseHit
                | Judgement::FalseMiss
                | Judgement::WrongRoot
                | Judgement::NonfiniteT
                | Judgement::OutOfRange
                | Judgement::Malformed
        )
    }
    /// The value error of a right answer.
    pub fn ulps(self) -> Option<u64> {
        match self {
            Judgement::Ok { ulps } => ulps,
            _ => None,
        }
    }
}

/// Judges an answer against the truth: first the answer contract (a malformed answer is
/// malformed on any case), then the verdict, then the value's error by the shape's metric.
pub fn judge(truth: &Truth, a: &Answer, shape: &ShapeInfo, prec: Precision) -> Judgement {
    if contract::malformed(shape, a).is_some() {
        return Judgement::Malformed;
    }
    // Invalid input: only a rejection is right
    let e = match truth {
        Truth::Invalid => {
            return if a.count == 0 {
                Judgement::Rejected
            } else if a.values.iter().any(|v| !v.is_finite()) {
                Judgement::InvalidNanT
            } else {
                Judgement::InvalidHit
            }
        }
        Truth::Answer(e) => e,
    };
    // The verdict: non-finite values, then the count
    if a.count > 0 && a.values.iter().any(|v| !v.is_finite()) {
        return Judgement::NonfiniteT;
    }
    // A hit outside the shape's interval (t ≤ 0), whatever the exact answer
    let exact_zero = e
        .values
        .first()
        .is_some_and(|&v| v == 0.0 && v.is_sign_positive());
    if contract::out_of_range(shape, a, exact_zero) {
        return Judgement::OutOfRange;
    }
    if a.count > e.count {
        return Judgement::FalseHit;
    }
    if a.count == 0 && e.values.first().is_some_and(|v| v.is_infinite()) {
        // The exact value lies beyond the format's range: it cannot be returned, a miss is right
        return Judgement::Ok { ulps: None };
    }
    if a.count < e.count || a.values.len() < e.values.len() {
        return Judgement::FalseMiss;
    }
    if e.count == 0 || e.values.is_empty() {
        return Judgement::Ok { ulps: None };
    }
    // A first value nearer another candidate than the right one is a wrong root
    let got = a.values[0];
    let right = e.value_f64.unwrap_or(e.values[0]);
    if e.others
        .iter()
        .any(|&o| o != right && (got - o).abs() < (got - right).abs())
    {
        return Judgement::WrongRoot;
    }
    Judgement::Ok {
        ulps: Some(value_error(&e.values, &a.values, shape.metric, prec)),
    }
}

/// The error of `got` against the correctly rounded `want`, by the metric.
pub fn value_error(want: &[f64], got: &[f64], metric: Metric, prec: Precision) -> u64 {
    match metric {
        Metric::Ulps => want
            .iter()
            .zip(got)
            .map(|(&w, &g)| exact::ulps(w, g, prec))
            .max()
            .unwrap_or(0),
        Metric::NormUlps => {
            let scale = want.iter().fold(0f64, |m, w| m.max(w.abs()));
            let unit = exact::ulp(scale, prec);
            want.iter()
                .zip(got)
                .map(|(&w, &g)| ((w - g).abs() / unit).ceil())
                .fold(0f64, f64::max) as u64
        }
    }
}

/// A right answer's error over the case's sensitivity (`None` when the oracle gives none): with
/// one sensitivity per value (`Expected::conds`, by the `Ulps` metric), the largest
/// `ulps(value_i) / max(1, cond_i)`; otherwise the answer's error `ulps` over `max(1, cond)`.
pub fn err_over_cond(
    e: &Expected,
    got: &[f64],
    ulps: u64,
    metric: Metric,
    prec: Precision,
) -> Option<f64> {
    if !e.conds.is_empty() && metric == Metric::Ulps {
        return Some(
            e.values
                .iter()
                .zip(got)
                .zip(&e.conds)
                .map(|((&w, &g), &c)| exact::ulps(w, g, prec) as f64 / c.max(1.0))
                .fold(0.0, f64::max),
        );
    }
    e.cond.map(|c| ulps as f64 / c.max(1.0))
}

/// Whether an enclosure `[lo, hi]` contains the exact first value. Checked through the value
/// correctly rounded to `f64` (or to the case's precision): rounding is monotonic and the ends
/// are floats, so a rounded value outside means the exact value is outside.
pub fn enclosure_holds(truth: &Truth, enclosure: [f64; 2]) -> bool {
    match truth {
        Truth::Answer(e) => match e.value_f64.or(e.values.first().copied()) {
            Some(t) => enclosure[0] <= t && t <= enclosure[1],
            None => true,
        },
        Truth::Invalid => true,
    }
}

#[cfg(test)]
mod err_over_cond_tests {
    use super::*;

    /// Each value is held to its own sensitivity: a badly conditioned root does not excuse an
    /// error on a well-conditioned one (the largest cond would give 10/1000 here).
    #[test]
    fn each_root_is_judged_by_its_own_sensitivity() {
        let e = Expected {
            count: 2,
            values: vec![1.0, 2.0],
            conds: vec![1000.0, 0.5],
            ..Default::default()
        };
        let step = |x: f64, k: u64| f64::from_bits(x.to_bits() + k);
        let got = [step(1.0, 10), step(2.0, 10)];
        let r = err_over_cond(&e, &got, 10, Metric::Ulps, Precision::F64).unwrap();
        assert_eq!(r, 10.0);
        // Error on the ill-conditioned root only: 10/1000
        let got = [step(1.0, 10), 2.0];
        let r = err_over_cond(&e, &got, 10, Metric::Ulps, Precision::F64).unwrap();
        assert_eq!(r, 0.01);
        // One sensitivity for the answer (the other shapes)
        let one = Expected {
            cond: Some(4.0),
            ..e.clone()
        };
        let one = Expected {
            conds: vec![],
            ..one
        };
        assert_eq!(
            err_over_cond(&one, &got, 10, Metric::Ulps, Precision::F64),
            Some(2.5)
        );
    }
}
