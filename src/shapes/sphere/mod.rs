//! Ray–sphere (seed 000, Fan, Shen, Wang & Feng 1996; seed 002 §2.3): the methods, their exact
//! oracle and the hard-case classes, audited as a [`Shape`] like every other routine family.
//!
//! A case is the ten scalars `o, d, c, r` (origin, direction, centre, radius); the answer is
//! the nearest `t > 0`. Beside the common row fields the sphere's oracle gives each case's
//! sensitivity (err/cond), its rows report the hit point's residual, and the `interval` method's
//! enclosures are checked.

pub mod batch;
pub mod cases;
pub mod methods;
pub mod oracle;

use crate::audit::shape::{Answer, Expected, MethodInfo, Shape, ShapeInfo, Truth};
use crate::numerics::real::{Real, Scalar};
use crate::numerics::Precision;
use cases::Class;
use methods::{PickPrecision, METHODS};
use oracle::{Case, Verdict};
use rand_chacha::ChaCha8Rng;

/// Significant digits of the oracle's decimal roots in `probe`.
const DIGITS: usize = 45;

/// The sphere's methods as the audit lists them.
const METHOD_INFO: [MethodInfo; METHODS.len()] = {
    let mut out = [MethodInfo {
        name: "",
        robust: false,
        about: "",
    }; METHODS.len()];
    let mut i = 0;
    while i < METHODS.len() {
        out[i] = MethodInfo {
            name: METHODS[i].name,
            robust: METHODS[i].robust,
            about: METHODS[i].summary,
        };
        i += 1;
    }
    out
};

/// The class names, in [`Class::ALL`] order.
const CLASS_NAMES: [&str; Class::ALL.len()] = {
    let mut out = [""; Class::ALL.len()];
    let mut i = 0;
    while i < Class::ALL.len() {
        out[i] = Class::ALL[i].name();
        i += 1;
    }
    out
};

const INFO: ShapeInfo = ShapeInfo {
    name: "sphere",
    about: "ray–sphere |o + t·d − c| = r, nearest t > 0 (seed 000; seed 002 §2.3)",
    args: &["ox", "oy", "oz", "dx", "dy", "dz", "cx", "cy", "cz", "r"],
    classes: &CLASS_NAMES,
    methods: &METHOD_INFO,
    reports_cond: true,
    reports_residual: true,
    ..ShapeInfo::DEFAULTS
};

/// The ray–sphere shape.
pub struct SphereShape;

/// The case in the precision `F` (its values are exactly representable there).
fn case_in<F: Real>(input: &[f64]) -> Case<F> {
    Case::from_scalars(std::array::from_fn(|i| F::from_f64(input[i])))
}

/// The oracle's truth in the audit's terms.
fn truth_in<F: Real>(input: &[f64]) -> Truth {
    let case = case_in::<F>(input);
    let t = oracle::truth(&case);
    if t.verdict == Verdict::Invalid {
        return Truth::Invalid;
    }
    let hit = t.verdict.is_hit();
    // The other root is the wrong-root candidate
    let other = t
        .roots
        .map(|[t1, t2]| if t.verdict == Verdict::Near { t2 } else { t1 });
    Truth::Answer(Expected {
        count: hit as u32,
        values: t
            .t_in::<F>()
            .filter(|_| hit)
            .map(|x| x.to_f64())
            .into_iter()
            .collect(),
        others: other.filter(|_| hit).into_iter().collect(),
        ill_posed: t.ill_posed,
        cap_reached: t.cap_reached,
        value_f64: t.t_f64.filter(|_| hit),
        cond: oracle::condition_ulps(&case, &t),
    })
}

/// Method `m` in the precision `F`.
fn run_in<F: PickPrecision>(m: usize, input: &[f64]) -> Answer {
    let case = case_in::<F>(input);
    match F::pick(&METHODS[m])(&case.ray(), &case.sphere()) {
        None => Answer::miss(),
        Some(h) => Answer {
            count: 1,
            values: vec![h.t.to_f64()],
            enclosure: h.enclosure.map(|e| [e[0].to_f64(), e[1].to_f64()]),
        },
    }
}

impl Shape for SphereShape {
    fn info(&self) -> &ShapeInfo {
        &INFO
    }
    /// The sphere keeps its own case streams (see [`cases::case_rng`]), so its cases are the
    /// ones every earlier report was made from.
    fn case_rng(&self, seed: u64, class: usize, prec: Precision, index: u64) -> ChaCha8Rng {
        crate::in_precision!(prec, F => cases::case_rng::<F>(seed, Class::ALL[class], index))
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        crate::in_precision!(prec, F => cases::generate_from::<F>(rng, Class::ALL[class])
            .map(|c| c.scalars().iter().map(|x| x.to_f64()).collect()))
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        crate::in_precision!(prec, F => truth_in::<F>(input))
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => run_in::<F>(m, input))
    }
    /// `|o + t·d − c| − r` at the method's `t`, in ulps of `r`.
    fn residual(&self, input: &[f64], prec: Precision, answer: &Answer) -> Option<f64> {
        let t = *answer.values.first()?;
        Some(crate::in_precision!(prec, F => {
            oracle::residual_ulps(&case_in::<F>(input), F::from_f64(t)).abs()
        }))
    }
    /// Both exact roots in decimal, and the precision at which the rounding became certain.
    fn oracle_detail(&self, input: &[f64], prec: Precision) -> Vec<(String, String)> {
        crate::in_precision!(prec, F => {
            let case = case_in::<F>(input);
            let t = oracle::truth(&case);
            let mut out: Vec<(String, String)> = oracle::roots_decimal(&case, DIGITS)
                .into_iter()
                .enumerate()
                .map(|(i, r)| (format!("root t{}", i + 1), r))
                .collect();
            if let (Some(a), Some(b)) = (t.t_f32, t.t_f64) {
                out.push(("t (f32)".into(), a.hex()));
                out.push(("t (f64)".into(), b.hex()));
            }
            out.push(("precision bits".into(), t.prec.to_string()));
            out
        })
    }
}
