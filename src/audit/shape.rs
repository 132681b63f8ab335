//! The game-math chapter's routines (seed 002), audited like the sphere.
//!
//! Each routine family is a [`Shape`]: named methods written once over [`crate::numerics::real::Real`],
//! an exact oracle (GMP rationals, MPFR enclosures), and named hard-case classes. A case is a
//! flat list of scalars, each exactly representable in the case's precision, so it replays
//! bit for bit through `rayproof probe <shape> --precision P <values…>`.
//!
//! What a routine answers is reduced to a discrete **count** (0 = miss / no real root / total
//! internal reflection; otherwise hit, number of distinct real roots, refracted) and a list of
//! **values** (`t`, the roots in ascending order, vector components), each correctly rounded
//! by the oracle. [`judge`] compares the two the same way for every routine; [`audit`]
//! aggregates judgements into rows shaped like the sphere's.

use crate::numerics::{exact, Precision};
use crate::shapes::sphere::Judgement;
use rand_chacha::ChaCha8Rng;

/// A method of a routine.
#[derive(Clone, Copy, Debug)]
pub struct MethodInfo {
    pub name: &'static str,
    /// The robust anchor: held to zero wrong verdicts on well-posed valid cases.
    pub robust: bool,
    /// One line: where the formula comes from.
    pub about: &'static str,
}

/// How value errors are measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Metric {
    /// Per value, in ulps of the precision (ordinal distance); the row keeps the largest.
    Ulps,
    /// For vectors: the largest component error in ulps of the vector's largest exact
    /// component (a near-zero component of a unit vector is not held to its own tiny ulp).
    NormUlps,
}

/// The oracle's exact answer about one case.
#[derive(Clone, Debug, PartialEq)]
pub enum Truth {
    /// NaN/inf inputs or a degenerate shape: the right answer is a rejection (count 0).
    Invalid,
    Answer(Expected),
}

/// A valid case's exact outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct Expected {
    /// 0 = miss / no real root / TIR; otherwise hit (1), or the number of distinct real roots.
    pub count: u32,
    /// The correctly rounded values in the case's precision (empty when `count` is 0).
    pub values: Vec<f64>,
    /// Other exact candidates for `values[0]` (the far intersection, the other roots): an
    /// answer nearer one of them than to `values[0]` is a wrong root.
    pub others: Vec<f64>,
    /// The count changes when some input moves by one ulp: a disagreement is not a failure.
    pub ill_posed: bool,
    /// The oracle could not round a value within its precision cap.
    pub cap_reached: bool,
}

/// A method's answer.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Answer {
    pub count: u32,
    pub values: Vec<f64>,
}

impl Answer {
    pub fn miss() -> Answer {
        Answer::default()
    }
    pub fn hit(values: Vec<f64>) -> Answer {
        Answer { count: 1, values }
    }
}

/// What a row must show for the audit to pass (the shapes' reviewed tolerance table).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expect {
    /// Wrong verdicts allowed on well-posed valid cases (`u64::MAX`: not checked).
    pub max_wrong: u64,
    /// Largest value error allowed in ulps (`u64::MAX`: not checked).
    pub max_ulps: u64,
    /// A known failure (XFAIL): the row must show at least one wrong verdict or one value error
    /// above `max_ulps`, so the harness is seen to catch it.
    pub must_fail: bool,
}

impl Expect {
    pub const ANY: Expect = Expect {
        max_wrong: u64::MAX,
        max_ulps: u64::MAX,
        must_fail: false,
    };
    pub fn pass(max_ulps: u64) -> Expect {
        Expect {
            max_wrong: 0,
            max_ulps,
            must_fail: false,
        }
    }
    pub fn xfail() -> Expect {
        Expect {
            must_fail: true,
            ..Expect::ANY
        }
    }
}

/// A routine family: its methods, oracle and classes.
pub trait Shape: Sync {
    /// The name used by `--shape` and `rayproof probe <name>`.
    fn name(&self) -> &'static str;
    /// One line for help and reports (with the seed section, e.g. "§2.1").
    fn about(&self) -> &'static str;
    /// Names of the input scalars, in probe order.
    fn args(&self) -> &'static [&'static str];
    /// Names of the output values.
    fn values(&self) -> &'static [&'static str];
    /// Hard-case class names.
    fn classes(&self) -> &'static [&'static str];
    fn methods(&self) -> &'static [MethodInfo];
    fn metric(&self) -> Metric {
        Metric::Ulps
    }
    /// Case of `class` drawn from `rng` (seeded per case by the framework). Every value must be
    /// exactly representable in `prec`. `None` when the generator found no member.
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>>;
    /// The exact answer (inputs as given, in `prec`).
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth;
    /// Runs method `m` in `prec` on the input (converted exactly to the precision).
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer;
    /// Cases per class when `--cases` is not given (an oracle that costs milliseconds per
    /// case, as the torus's does, audits fewer).
    fn default_cases(&self) -> u64 {
        20_000
    }
    /// The tolerance of method `m` in `prec` on `class`. Default: robust methods pass with no
    /// wrong verdict and at most 64 ulps; others are only reported.
    fn expect(&self, m: usize, _prec: Precision, _class: usize) -> Expect {
        if self.methods()[m].robust {
            Expect::pass(64)
        } else {
            Expect::ANY
        }
    }
}

/// Judges an answer against the truth (shared by every routine).
pub fn judge(truth: &Truth, a: &Answer, metric: Metric, prec: Precision) -> Judgement {
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
    if a.count > 0 && a.values.iter().any(|v| !v.is_finite()) {
        return Judgement::NonfiniteT;
    }
    if a.count > e.count {
        return Judgement::FalseHit;
    }
    if a.count < e.count || a.values.len() < e.values.len() {
        return Judgement::FalseMiss;
    }
    if e.count == 0 || e.values.is_empty() {
        return Judgement::Ok { ulps: None };
    }
    // A first value nearer another candidate than the right one is a wrong root
    let (got, right) = (a.values[0], e.values[0]);
    if e.others
        .iter()
        .any(|&o| o != right && (got - o).abs() < (got - right).abs())
    {
        return Judgement::WrongRoot;
    }
    Judgement::Ok {
        ulps: Some(value_error(&e.values, &a.values, metric, prec)),
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

/// The replay command of a case.
pub fn probe_line(shape: &dyn Shape, prec: Precision, input: &[f64]) -> String {
    let vals: Vec<String> = input.iter().map(|&x| hex_text(x)).collect();
    format!(
        "rayproof probe {} --precision {} -- {}",
        shape.name(),
        prec.name(),
        vals.join(" ")
    )
}

/// An input or output value as exact text: a C99 hex float, `inf`, `-inf` or `nan`.
pub fn hex_text(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else {
        crate::numerics::real::hex_float(x)
    }
}

/// Parses probe values (decimal or hex, each rounded once to the precision).
pub fn parse_values(
    shape: &dyn Shape,
    prec: Precision,
    text: &[String],
) -> Result<Vec<f64>, String> {
    if text.len() != shape.args().len() {
        return Err(format!(
            "probe {} takes {} values ({}), got {}",
            shape.name(),
            shape.args().len(),
            shape.args().join(" "),
            text.len()
        ));
    }
    text.iter()
        .zip(shape.args())
        .map(|(s, name)| {
            let v = match prec {
                Precision::F32 => <f32 as crate::numerics::real::Real>::parse(s).map(|x| x as f64),
                Precision::F64 => <f64 as crate::numerics::real::Real>::parse(s),
            };
            v.ok_or_else(|| format!("{name}: '{s}' is not a number in {}", prec.name()))
        })
        .collect()
}
