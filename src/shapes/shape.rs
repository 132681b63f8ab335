//! What the audit knows about a routine family ([`Shape`]), about a method under audit
//! ([`Method`]), and the two sides of a judgement: the oracle's [`Truth`] and a method's
//! [`Answer`].
//!
//! A case is a flat list of scalars, each exactly representable in the case's precision, so
//! it replays bit for bit through `rayproof probe <shape> --precision P -- <values…>`. What a
//! routine answers is reduced to a discrete **count** (0 = miss / no real root / total internal
//! reflection; otherwise hit, number of distinct real roots, refracted) and a list of
//! **values** (`t`, the roots in ascending order, vector components), each correctly rounded by
//! the oracle.

use crate::numerics::Precision;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sha2::{Digest, Sha256};

/// Where a hit's first value must lie.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Domain {
    /// Any finite value: roots, reciprocals, vector components.
    Real,
    /// A ray parameter: `t > 0` (`+0` only as the rounding of an exact `t` below half the least
    /// subnormal).
    RayParameter,
}

/// A built-in method of a shape.
#[derive(Clone, Copy, Debug)]
pub struct MethodInfo {
    /// Method name (`--method`).
    pub name: &'static str,
    /// Offered as robust: held to the strict rows of the tolerance table.
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

impl Metric {
    /// The metric's name in reports: `ulps` or `norm_ulps`.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Ulps => "ulps",
            Metric::NormUlps => "norm_ulps",
        }
    }
}

/// The oracle's exact answer about one case.
#[derive(Clone, Debug, PartialEq)]
pub enum Truth {
    /// NaN/inf inputs or a degenerate shape: the right answer is a rejection (count 0).
    Invalid,
    /// A valid case: its exact outcome.
    Answer(Expected),
}

/// A valid case's exact outcome.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Expected {
    /// 0 = miss / no real root / TIR; otherwise hit (1), or the number of distinct real roots.
    pub count: u32,
    /// The correctly rounded values in the case's precision (empty when `count` is 0).
    pub values: Vec<f64>,
    /// Other exact candidates for `values[0]` (the far intersection, the other roots): an
    /// answer nearer one of them than to the right one is a wrong root.
    pub others: Vec<f64>,
    /// The count changes when some input moves by one ulp: a disagreement is not a failure.
    pub ill_posed: bool,
    /// The oracle could not round a value within its precision cap.
    pub cap_reached: bool,
    /// `values[0]` correctly rounded to `f64` (sharper than `values[0]` for an `f32` case);
    /// wrong roots and enclosures are judged against it when the oracle gives it.
    pub value_f64: Option<f64>,
    /// How far `values[0]` moves, in its ulps, when every input moves by one ulp (the case's
    /// own sensitivity); a method's error divided by it is reported as err/cond.
    pub cond: Option<f64>,
    /// For shapes with several values (the roots of a polynomial): each value's sensitivity, in
    /// the order of `values`; err/cond is then the largest of each value's error over its own
    /// sensitivity (an ill-conditioned root does not excuse a well-conditioned one).
    pub conds: Vec<f64>,
}

/// A method's answer.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Answer {
    /// 0 for a miss (or no real root); otherwise the number of hits or distinct real roots.
    pub count: u32,
    /// The values, in the shape's order (empty for a miss).
    pub values: Vec<f64>,
    /// An enclosure `[lo, hi]` the method claims holds the exact `values[0]` (checked).
    pub enclosure: Option<[f64; 2]>,
}

impl Answer {
    /// A miss: count 0, no values.
    pub fn miss() -> Answer {
        Answer::default()
    }
    /// A hit with these values (count 1).
    pub fn hit(values: Vec<f64>) -> Answer {
        Answer {
            count: 1,
            values,
            enclosure: None,
        }
    }
}

/// What stays fixed about a shape: its names, its built-in methods, how errors are measured.
#[derive(Debug)]
pub struct ShapeInfo {
    /// The name used by `--shape` and `rayproof probe <name>`.
    pub name: &'static str,
    /// One line for help and reports (with the seed section, e.g. "§2.1").
    pub about: &'static str,
    /// Names of the input scalars, in probe order.
    pub args: &'static [&'static str],
    /// Names of the output values.
    pub values: &'static [&'static str],
    /// Hard-case class names.
    pub classes: &'static [&'static str],
    /// The built-in methods, in report order.
    pub methods: &'static [MethodInfo],
    /// How value errors are measured.
    pub metric: Metric,
    /// Cases per class when `--cases` is not given (an oracle that costs milliseconds per
    /// case, as the torus's does, audits fewer).
    pub default_cases: u64,
    /// The oracle gives each case's sensitivity ([`Expected::cond`]): rows report err/cond.
    pub reports_cond: bool,
    /// [`Shape::residual`] is implemented: rows report hit-point residuals.
    pub reports_residual: bool,
    /// The count is the number of values (the polynomials' distinct real roots); otherwise a
    /// non-zero count comes with all the values (`t`, or a vector's components).
    pub count_is_values: bool,
    /// Where a hit's first value must lie (the answer contract's interval, [`crate::audit::contract`]).
    pub domain: Domain,
}

impl ShapeInfo {
    /// What a shape's info starts from (`..ShapeInfo::DEFAULTS`): one value `t`, errors in ulps,
    /// 20,000 cases per class, no err/cond, no residual.
    pub const DEFAULTS: ShapeInfo = ShapeInfo {
        name: "",
        about: "",
        args: &[],
        values: &["t"],
        classes: &[],
        methods: &[],
        metric: Metric::Ulps,
        default_cases: 20_000,
        reports_cond: false,
        reports_residual: false,
        count_is_values: false,
        domain: Domain::Real,
    };
}

/// A routine family: its methods, oracle and classes. The fixed facts are one [`ShapeInfo`];
/// the code is `generate`, `oracle` and `run`.
pub trait Shape: Sync {
    /// The shape's fixed facts.
    fn info(&self) -> &ShapeInfo;
    /// Case of `class` drawn from `rng` (seeded per case by [`Shape::case_rng`]). Every value
    /// must be exactly representable in `prec`. `None` when the generator found no member.
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>>;
    /// The exact answer (inputs as given, in `prec`).
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth;
    /// Runs built-in method `m` in `prec` on the input (converted exactly to the precision).
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer;

    /// The generator of case `index`: by default a ChaCha8 stream keyed by the SHA-256 of
    /// seed, shape, class, precision and index, so any case is generated alone.
    fn case_rng(&self, seed: u64, class: usize, prec: Precision, index: u64) -> ChaCha8Rng {
        let info = self.info();
        case_rng(seed, info.name, info.classes[class], prec, index)
    }
    /// The hit point's distance from the surface in ulps of the shape's size, for an answer
    /// judged right (`None`: the shape does not report residuals).
    fn residual(&self, _input: &[f64], _prec: Precision, _answer: &Answer) -> Option<f64> {
        None
    }
    /// Extra lines of the oracle's answer for `probe` (e.g. the exact roots in decimal).
    fn oracle_detail(&self, _input: &[f64], _prec: Precision) -> Vec<(String, String)> {
        vec![]
    }

    /// The shape's name (`--shape`).
    fn name(&self) -> &'static str {
        self.info().name
    }
}

/// A ChaCha8 stream keyed by the SHA-256 of seed, a stream name, a class name, precision and
/// index (the default case generator of a shape, and the streams of the reintersection tests).
pub fn case_rng(seed: u64, name: &str, class: &str, prec: Precision, index: u64) -> ChaCha8Rng {
    let mut h = Sha256::new();
    h.update(seed.to_le_bytes());
    h.update(name.as_bytes());
    h.update([0]);
    h.update(class.as_bytes());
    h.update([0]);
    h.update(prec.name().as_bytes());
    h.update(index.to_le_bytes());
    ChaCha8Rng::from_seed(h.finalize().into())
}

/// A method under audit: one of a shape's own ([`Builtin`]) or one written outside the crate
/// (a Rust function, a shared library, a subprocess). It answers a batch of cases of one
/// precision, in order; each case's inputs are exactly representable in `prec`.
pub trait Method: Sync {
    /// The method's name in rows and replay lines.
    fn name(&self) -> &str;
    /// Offered as robust (robust methods must reject invalid input).
    fn robust(&self) -> bool {
        false
    }
    /// One line: where the method comes from.
    fn about(&self) -> &str {
        ""
    }
    /// The `rayproof probe` arguments that bring this method into a replay (e.g.
    /// `--exec 'CMD' --name N`); `None`: the probe knows it (a shape's own method).
    fn replay(&self) -> Option<String> {
        None
    }
    /// What the routine is, so that shards of two routines that share a name are never one
    /// audit: an `--exec` command, a library's SHA-256 and symbol; `None`: a built-in method.
    fn identity(&self) -> Option<String> {
        None
    }
    /// One answer per input, in order. An error (a crashed or hung child, a malformed
    /// answer) stops the audit with that one line.
    fn answer(&self, prec: Precision, inputs: &[Vec<f64>]) -> Result<Vec<Answer>, String>;
    /// Called once the run has no more cases: a method that keeps an outside process for the
    /// run ends it here and checks how it ended (an error stops the audit as in `answer`).
    fn finish(&self) -> Result<(), String> {
        Ok(())
    }
    /// Nanoseconds the routine itself spent in its calls of precision `prec` so far, timed where
    /// it runs (a plugin's worker times each call of the symbol); `None`: only the whole
    /// `answer` can be timed.
    fn own_nanos(&self, _prec: Precision) -> Option<u64> {
        None
    }
}

/// A method that answers one case at a time and cannot fail (a shape's own, a Rust function):
/// every `PerCase` is a [`Method`] whose batches run in parallel.
pub trait PerCase: Sync {
    /// The method's name in rows and replay lines.
    fn name(&self) -> &str;
    /// Offered as robust (robust methods must reject invalid input).
    fn robust(&self) -> bool {
        false
    }
    /// One line: where the method comes from.
    fn about(&self) -> &str {
        ""
    }
    /// The method's answer on one case (inputs exactly representable in `prec`).
    fn run(&self, input: &[f64], prec: Precision) -> Answer;
}

impl<T: PerCase> Method for T {
    fn name(&self) -> &str {
        PerCase::name(self)
    }
    fn robust(&self) -> bool {
        PerCase::robust(self)
    }
    fn about(&self) -> &str {
        PerCase::about(self)
    }
    fn answer(&self, prec: Precision, inputs: &[Vec<f64>]) -> Result<Vec<Answer>, String> {
        use rayon::prelude::*;
        Ok(inputs.par_iter().map(|x| self.run(x, prec)).collect())
    }
}

/// Built-in method `index` of a shape.
#[derive(Clone, Copy)]
pub struct Builtin {
    /// The shape.
    pub shape: &'static dyn Shape,
    /// Index into the shape's [`ShapeInfo::methods`].
    pub index: usize,
}

impl Builtin {
    /// Every built-in method of a shape.
    pub fn all(shape: &'static dyn Shape) -> Vec<Builtin> {
        (0..shape.info().methods.len())
            .map(|index| Builtin { shape, index })
            .collect()
    }
    fn info(&self) -> &'static MethodInfo {
        &self.shape.info().methods[self.index]
    }
}

impl PerCase for Builtin {
    fn name(&self) -> &str {
        self.info().name
    }
    fn robust(&self) -> bool {
        self.info().robust
    }
    fn about(&self) -> &str {
        self.info().about
    }
    fn run(&self, input: &[f64], prec: Precision) -> Answer {
        self.shape.run(self.index, input, prec)
    }
}

/// Runs a generic expression in a precision: `in_precision!(prec, F => run_in::<F>(m, input))`
/// evaluates `run_in::<f32>` or `run_in::<f64>`.
#[macro_export]
macro_rules! in_precision {
    ($prec:expr, $F:ident => $e:expr) => {
        match $prec {
            $crate::numerics::Precision::F32 => {
                type $F = f32;
                $e
            }
            $crate::numerics::Precision::F64 => {
                type $F = f64;
                $e
            }
        }
    };
}

/// An input or output value as exact text: a C99 hex float, `inf`, `-inf` or `nan`.
pub fn hex_text(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else {
        crate::numerics::real::hex_float(x)
    }
}

/// The replay command of a case.
pub fn probe_line(shape: &str, prec: Precision, input: &[f64]) -> String {
    probe_line_with(shape, prec, None, input)
}

/// The replay command of a case for a method the probe must be told about (`extra`, e.g.
/// `--exec 'CMD' --name N`).
pub fn probe_line_with(shape: &str, prec: Precision, extra: Option<&str>, input: &[f64]) -> String {
    let vals: Vec<String> = input.iter().map(|&x| hex_text(x)).collect();
    let extra = extra.map(|e| format!(" {e}")).unwrap_or_default();
    format!(
        "rayproof probe {shape} --precision {}{extra} -- {}",
        prec.name(),
        vals.join(" ")
    )
}

/// The replay command of a box-guard case (13 values: `o d lo hi t_max`) for the guard `name`,
/// `extra` the options that bring a guard of yours (`--exec 'CMD' --name N`).
pub fn guard_line_with(name: &str, prec: Precision, extra: Option<&str>, v: &[f64]) -> String {
    let vals: Vec<String> = v.iter().map(|x| hex_text(*x)).collect();
    let args = extra.map(|a| format!(" {a}")).unwrap_or_default();
    format!(
        "rayproof guard{args} --replay {name} {} {}",
        prec.name(),
        vals.join(" ")
    )
}

/// Generates case `index` of a class (public for tests and benches).
pub fn generate(
    shape: &dyn Shape,
    seed: u64,
    class: usize,
    prec: Precision,
    index: u64,
) -> Option<Vec<f64>> {
    let mut rng = shape.case_rng(seed, class, prec, index);
    let v = shape.generate(class, prec, &mut rng)?;
    debug_assert!(v
        .iter()
        .all(|&x| crate::numerics::exact::representable(x, prec)));
    Some(v)
}
