//! Ray–sphere: the methods, their exact oracle, the hard-case classes, and how a method's answer
//! is judged against the oracle.

pub mod batch;
pub mod cases;
pub mod methods;
pub mod oracle;
pub mod tolerance;

use crate::numerics::real::Real;
use methods::SphereHit;
use oracle::{Case, Truth, Verdict};
use serde::{Deserialize, Serialize};

/// How one method's answer compares with the oracle on one case.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Judgement {
    /// Right verdict; for a hit, `ulps` from the correctly rounded root.
    Ok { ulps: Option<u64> },
    /// Hit reported where the exact answer is a miss.
    FalseHit,
    /// Miss reported where the exact answer is a hit.
    FalseMiss,
    /// Hit nearer the other root of the quadratic than the nearest positive one.
    WrongRoot,
    /// A hit with NaN or infinite `t` on valid input.
    NonfiniteT,
    /// Invalid input, reported as a miss (the right answer).
    Rejected,
    /// Invalid input, answered with a NaN or infinite `t`.
    InvalidNanT,
    /// Invalid input, answered with a finite hit.
    InvalidHit,
}

impl Judgement {
    /// The short verdict word used in JSON: ok, false_hit, false_miss, wrong_root, nonfinite_t, invalid.
    pub fn verdict_word(self) -> &'static str {
        match self {
            Judgement::Ok { .. } => "ok",
            Judgement::FalseHit => "false_hit",
            Judgement::FalseMiss => "false_miss",
            Judgement::WrongRoot => "wrong_root",
            Judgement::NonfiniteT => "nonfinite_t",
            Judgement::Rejected | Judgement::InvalidNanT | Judgement::InvalidHit => "invalid",
        }
    }
    /// A wrong answer on valid input (counted only when the case is well posed).
    pub fn is_wrong(self) -> bool {
        matches!(
            self,
            Judgement::FalseHit
                | Judgement::FalseMiss
                | Judgement::WrongRoot
                | Judgement::NonfiniteT
        )
    }
}

/// Judges a method's answer against the oracle's truth.
pub fn judge<F: Real>(truth: &Truth, hit: Option<SphereHit<F>>) -> Judgement {
    if truth.verdict == Verdict::Invalid {
        return match hit {
            None => Judgement::Rejected,
            Some(h) if !h.t.is_finite() => Judgement::InvalidNanT,
            Some(_) => Judgement::InvalidHit,
        };
    }
    match (truth.verdict.is_hit(), hit) {
        (false, None) => Judgement::Ok { ulps: None },
        (_, Some(h)) if !h.t.is_finite() => Judgement::NonfiniteT,
        (false, Some(_)) => Judgement::FalseHit,
        // A root beyond the format's range cannot be returned: a miss is right
        (true, None) if truth.t_in::<F>().is_some_and(|t| !t.is_finite()) => {
            Judgement::Ok { ulps: None }
        }
        (true, None) => Judgement::FalseMiss,
        (true, Some(h)) => {
            let want: F = truth.t_in::<F>().expect("a hit has a root");
            // Which root is the answer nearer to?
            if let Some([t1, t2]) = truth.roots {
                let (right, other) = if truth.verdict == Verdict::Near {
                    (t1, t2)
                } else {
                    (t2, t1)
                };
                let got = h.t.to_f64();
                if (got - other).abs() < (got - right).abs() {
                    return Judgement::WrongRoot;
                }
            }
            Judgement::Ok {
                ulps: Some(h.t.ulps_between(want)),
            }
        }
    }
}

/// Whether an enclosure `[lo, hi]` contains the exact root (checked through the correctly
/// rounded `f64` root: a value outside surely means the exact root is outside).
pub fn enclosure_holds<F: Real>(truth: &Truth, enclosure: [F; 2]) -> bool {
    match truth.t_f64 {
        Some(t) => enclosure[0].to_f64() <= t && t <= enclosure[1].to_f64(),
        None => true,
    }
}

/// Runs the oracle and every selected method on a case (used by `probe` and the tests).
pub fn run_case<F: methods::PickPrecision>(
    case: &Case<F>,
    methods: &[&'static methods::Method],
) -> (Truth, Vec<(&'static str, Option<SphereHit<F>>, Judgement)>) {
    let truth = oracle::truth(case);
    let (ray, sphere) = (case.ray(), case.sphere());
    let rows = methods
        .iter()
        .map(|m| {
            let hit = F::pick(m)(&ray, &sphere);
            (m.name, hit, judge(&truth, hit))
        })
        .collect();
    (truth, rows)
}
