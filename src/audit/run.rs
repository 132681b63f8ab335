//! Running one shape's audit: cases are generated, judged and tallied in parallel, one
//! precision × class at a time. Tallies merge exactly (see [`super::tally`]), so the result
//! depends only on the seed and the selection, never on the number of threads; nothing is
//! kept per case, so memory does not grow with the case count.

use super::judge::{enclosure_holds, judge};
use super::shape::{Method, Shape, Truth};
use super::tally::{Case, Sample, Tally};
use crate::numerics::{exact, Precision};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU64, Ordering};

/// CPU time spent in oracles (all threads), for the terminal summary only (never in a report).
pub static ORACLE_NANOS: AtomicU64 = AtomicU64::new(0);

/// What to run of one shape.
pub struct Selection<'a> {
    pub shape: &'static dyn Shape,
    pub methods: Vec<&'a dyn Method>,
    pub precisions: Vec<Precision>,
    /// Class indices.
    pub classes: Vec<usize>,
    pub cases: u64,
    pub seed: u64,
    /// `(k, n)`: only cases whose index ≡ k (mod n); `(0, 1)` is the whole run.
    pub shard: (u64, u64),
}

/// A method's name and whether it is offered as robust (what a report needs of it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MethodTag {
    pub name: String,
    pub robust: bool,
}

/// The result of a shape's run (or of merged shards): its selection and its tallies.
pub struct Tallies {
    pub shape: &'static dyn Shape,
    pub cases: u64,
    pub methods: Vec<MethodTag>,
    pub groups: Vec<Group>,
}

impl Tallies {
    /// The value errors of one row's right-verdict answers on well-posed cases, ascending (the
    /// sample its `ulps` summarises).
    pub fn ulps(&self, method: &str, prec: Precision, class: &str) -> Vec<u64> {
        let Some(k) = self.methods.iter().position(|m| m.name == method) else {
            return vec![];
        };
        self.groups
            .iter()
            .filter(|g| g.precision == prec && self.shape.info().classes[g.class] == class)
            .flat_map(|g| g.tallies[k].ulps.runs())
            .flat_map(|(u, c)| std::iter::repeat_n(u, c as usize))
            .collect()
    }
}

/// The tallies of one precision × class, one per method.
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    pub precision: Precision,
    pub class: usize,
    pub tallies: Vec<Tally>,
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
    debug_assert!(v.iter().all(|&x| exact::representable(x, prec)));
    Some(v)
}

/// Generates, judges and samples one case.
pub fn evaluate(sel: &Selection, class: usize, prec: Precision, index: u64) -> Case {
    let shape = sel.shape;
    let Some(input) = generate(shape, sel.seed, class, prec, index) else {
        return Case {
            index,
            input: vec![],
            truth: None,
            samples: vec![],
        };
    };
    let (truth, samples) = judge_all(shape, &sel.methods, &input, prec);
    Case {
        index,
        input,
        truth: Some(truth),
        samples,
    }
}

/// The indices of shard `(k, n)` among `0..cases`: `k, k + n, k + 2n, …`.
pub fn shard_indices(cases: u64, (k, n): (u64, u64)) -> impl Iterator<Item = u64> {
    (k..cases).step_by(usize::try_from(n.max(1)).unwrap_or(usize::MAX))
}

/// How many indices shard `(k, n)` has among `0..cases`.
pub fn shard_len(cases: u64, (k, n): (u64, u64)) -> u64 {
    if k >= cases {
        0
    } else {
        (cases - k - 1) / n.max(1) + 1
    }
}

/// Tallies of one precision × class: cases in parallel, tallies merged.
fn group(sel: &Selection, prec: Precision, class: usize, bar: &ProgressBar) -> Group {
    let methods = sel.methods.len();
    let empty = || vec![Tally::default(); methods];
    let (k, n) = sel.shard;
    let count = shard_len(sel.cases, sel.shard);
    let tallies = (0..count)
        .into_par_iter()
        .fold(empty, |mut acc, i| {
            let case = evaluate(sel, class, prec, k + i * n);
            for (m, t) in acc.iter_mut().enumerate() {
                t.add(&case, m);
            }
            bar.inc(1);
            acc
        })
        .reduce(empty, |mut a, b| {
            for (x, y) in a.iter_mut().zip(&b) {
                x.merge(y);
            }
            a
        });
    Group {
        precision: prec,
        class,
        tallies,
    }
}

/// Runs the selection: every precision × class in turn, with a progress bar when asked.
pub fn run(sel: &Selection, progress: bool) -> Tallies {
    let per_group = shard_len(sel.cases, sel.shard);
    let total = per_group * (sel.classes.len() * sel.precisions.len()) as u64;
    let bar = if progress {
        ProgressBar::new(total)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} audit {} {{bar:40}} {{pos}}/{{len}} cases  {{per_sec}}  eta {{eta}}",
            sel.shape.name()
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut out = vec![];
    for &prec in &sel.precisions {
        for &class in &sel.classes {
            out.push(group(sel, prec, class, &bar));
        }
    }
    bar.finish_and_clear();
    Tallies {
        shape: sel.shape,
        cases: sel.cases,
        methods: sel
            .methods
            .iter()
            .map(|m| MethodTag {
                name: m.name().to_string(),
                robust: m.robust(),
            })
            .collect(),
        groups: out,
    }
}

/// The oracle's truth and every method's judged sample on one input (the audit's step for
/// each case, and `probe`'s).
pub fn judge_all(
    shape: &dyn Shape,
    methods: &[&dyn Method],
    input: &[f64],
    prec: Precision,
) -> (Truth, Vec<Sample>) {
    let clock = std::time::Instant::now();
    let truth = shape.oracle(input, prec);
    ORACLE_NANOS.fetch_add(clock.elapsed().as_nanos() as u64, Ordering::Relaxed);
    let samples = methods
        .iter()
        .map(|m| {
            let answer = m.run(input, prec);
            let judgement = judge(&truth, &answer, shape.info().metric, prec);
            // Residual and enclosure of a right-verdict hit
            let right_hit = judgement.ulps().is_some();
            let residual = right_hit
                .then(|| shape.residual(input, prec, &answer))
                .flatten();
            let enclosure = answer
                .enclosure
                .filter(|_| right_hit)
                .map(|e| (enclosure_holds(&truth, e), exact::ulps(e[0], e[1], prec)));
            Sample {
                judgement,
                values: answer.values,
                residual,
                enclosure,
            }
        })
        .collect();
    (truth, samples)
}
