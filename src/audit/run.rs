//! Running one shape's audit: cases are generated, judged and tallied in parallel, one
//! precision × class at a time. Tallies merge exactly (see [`super::tally`]), so the result
//! depends only on the seed and the selection, never on the number of threads; nothing is
//! kept per case, so memory does not grow with the case count.

use super::judge::{enclosure_holds, err_over_cond, judge};
use super::tally::{Case, Sample, Tally};
use crate::numerics::{exact, Precision};
pub use crate::shapes::shape::generate;
use crate::shapes::shape::{Answer, Method, Shape, Truth};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A method under audit failed (a crashed or hung child, a malformed answer): the audit stops
/// with this one line.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct MethodFailed(pub String);

/// What to run of one shape.
pub struct Selection<'a> {
    /// The shape.
    pub shape: &'static dyn Shape,
    /// The methods under audit.
    pub methods: Vec<&'a dyn Method>,
    /// Precisions to run.
    pub precisions: Vec<Precision>,
    /// Class indices.
    pub classes: Vec<usize>,
    /// Cases per class and precision.
    pub cases: u64,
    /// Seed of the case streams.
    pub seed: u64,
    /// `(k, n)`: only cases whose index ≡ k (mod n); `(0, 1)` is the whole run.
    pub shard: (u64, u64),
}

/// A method's name and whether it is offered as robust (what a report needs of it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MethodTag {
    /// Method name.
    pub name: String,
    /// Offered as robust.
    pub robust: bool,
    /// The probe arguments that replay this method (outside methods only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replay: Option<String>,
    /// What the routine is (outside methods only: the command, or the library's SHA-256 and
    /// symbol): shards of two routines under one name are not one audit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identity: Option<String>,
}

/// The result of a shape's run (or of merged shards): its selection and its tallies.
pub struct Tallies {
    /// The shape.
    pub shape: &'static dyn Shape,
    /// Cases per class and precision.
    pub cases: u64,
    /// The methods, in tally order.
    pub methods: Vec<MethodTag>,
    /// One group per precision × class.
    pub groups: Vec<Group>,
    /// CPU time the oracle took over the run's cases, all threads (for progress lines only:
    /// never in a report; 0 for merged shards).
    pub oracle_nanos: u64,
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
    /// Precision of the group.
    pub precision: Precision,
    /// Class index in the shape's classes.
    pub class: usize,
    /// One tally per method, in [`Tallies::methods`] order.
    pub tallies: Vec<Tally>,
    /// The cases run, as a sum (mod 2⁶⁴) of one hash per case of its index and inputs'
    /// bits ([`case_hash`]): order-free, so shards add up to the unsharded run's, and two
    /// shards that ran the same cases have the same digest.
    pub digest: u64,
}

/// One case's hash for [`Group::digest`]: FNV-1a over its index and its inputs' bits.
pub fn case_hash(index: u64, input: &[f64]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for word in std::iter::once(index).chain(input.iter().map(|x| x.to_bits())) {
        for b in word.to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
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

/// Cases per batch: each method answers this many at once.
pub(crate) const CHUNK: u64 = 4096;

/// The samples of one case from the methods' answers (residual and enclosure for a
/// right-verdict hit).
fn sample(
    shape: &dyn Shape,
    truth: &Truth,
    input: &[f64],
    answer: Answer,
    prec: Precision,
) -> Sample {
    let judgement = judge(truth, &answer, shape.info(), prec);
    let right_hit = judgement.ulps().is_some();
    let residual = right_hit
        .then(|| shape.residual(input, prec, &answer))
        .flatten();
    let enclosure = answer
        .enclosure
        .filter(|_| right_hit)
        .map(|e| (enclosure_holds(truth, e), exact::ulps(e[0], e[1], prec)));
    let err_over_cond = match (truth, judgement.ulps()) {
        (Truth::Answer(e), Some(u)) => {
            err_over_cond(e, &answer.values, u, shape.info().metric, prec)
        }
        _ => None,
    };
    let count = answer.count;
    Sample {
        judgement,
        count,
        values: answer.values,
        residual,
        enclosure,
        err_over_cond,
    }
}

/// The oracle on one case, and the CPU time it took in nanoseconds.
fn oracle(shape: &dyn Shape, input: &[f64], prec: Precision) -> (Truth, u64) {
    let clock = std::time::Instant::now();
    let truth = shape.oracle(input, prec);
    (truth, clock.elapsed().as_nanos() as u64)
}

/// Every method's answers to a batch of inputs, checked for their number.
pub(crate) fn answers(
    methods: &[&dyn Method],
    prec: Precision,
    inputs: &[Vec<f64>],
) -> Result<Vec<Vec<Answer>>, String> {
    methods
        .iter()
        .map(|m| {
            let a = m.answer(prec, inputs)?;
            if a.len() != inputs.len() {
                return Err(format!(
                    "{}: {} answers to {} cases",
                    m.name(),
                    a.len(),
                    inputs.len()
                ));
            }
            Ok(a)
        })
        .collect()
}

/// A generated case with the oracle's truth (`None`: the generator found no member) and the
/// oracle's time on it.
struct Posed {
    index: u64,
    case: Option<(Vec<f64>, Truth)>,
    nanos: u64,
}

/// Tallies of one precision × class: in batches, each case generated and judged in parallel,
/// every method answering the batch, tallies merged.
fn group(
    sel: &Selection,
    prec: Precision,
    class: usize,
    bar: &ProgressBar,
) -> Result<(Group, u64), String> {
    let shape = sel.shape;
    let empty = || vec![Tally::default(); sel.methods.len()];
    let (k, n) = sel.shard;
    let count = shard_len(sel.cases, sel.shard);
    let mut tallies = empty();
    let mut nanos = 0;
    let mut digest = 0u64;
    for start in (0..count).step_by(CHUNK as usize) {
        let end = (start + CHUNK).min(count);
        // Generate and ask the oracle
        let posed: Vec<Posed> = (start..end)
            .into_par_iter()
            .map(|i| {
                let index = k + i * n;
                let mut nanos = 0;
                let case = generate(shape, sel.seed, class, prec, index).map(|x| {
                    let (t, ns) = oracle(shape, &x, prec);
                    nanos = ns;
                    (x, t)
                });
                Posed { index, case, nanos }
            })
            .collect();
        nanos += posed.iter().map(|p| p.nanos).sum::<u64>();
        for p in &posed {
            let input = p.case.as_ref().map(|(x, _)| &x[..]).unwrap_or(&[]);
            digest = digest.wrapping_add(case_hash(p.index, input));
        }
        // Every method answers the batch of inputs
        let inputs: Vec<Vec<f64>> = posed
            .iter()
            .filter_map(|p| p.case.as_ref().map(|(x, _)| x.clone()))
            .collect();
        let answers = answers(&sel.methods, prec, &inputs)?;
        let mut next = 0;
        let slots: Vec<Option<usize>> = posed
            .iter()
            .map(|p| {
                p.case.as_ref().map(|_| {
                    next += 1;
                    next - 1
                })
            })
            .collect();
        // Judge and tally
        let part = posed
            .into_par_iter()
            .zip(slots)
            .fold(empty, |mut acc, (p, slot)| {
                let case = match (p.case, slot) {
                    (Some((input, truth)), Some(j)) => Case {
                        samples: answers
                            .iter()
                            .map(|a| sample(shape, &truth, &input, a[j].clone(), prec))
                            .collect(),
                        index: p.index,
                        input,
                        truth: Some(truth),
                    },
                    _ => Case {
                        index: p.index,
                        input: vec![],
                        truth: None,
                        samples: vec![],
                    },
                };
                for (m, t) in acc.iter_mut().enumerate() {
                    t.add(&case, m);
                }
                acc
            })
            .reduce(empty, |mut a, b| {
                for (x, y) in a.iter_mut().zip(&b) {
                    x.merge(y);
                }
                a
            });
        for (x, y) in tallies.iter_mut().zip(&part) {
            x.merge(y);
        }
        bar.inc(end - start);
    }
    Ok((
        Group {
            precision: prec,
            class,
            tallies,
            digest,
        },
        nanos,
    ))
}

/// Runs the selection: every precision × class in turn, with a progress bar when asked. An
/// outside method that fails stops the run with its error. The methods are not finished: an
/// outside child lives on for the rest of the run (see [`super::plan::Plan::finish`]).
pub fn run(sel: &Selection, progress: bool) -> Result<Tallies, MethodFailed> {
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
    let (mut out, mut oracle_nanos) = (vec![], 0);
    for &prec in &sel.precisions {
        for &class in &sel.classes {
            let (g, ns) = group(sel, prec, class, &bar).map_err(MethodFailed)?;
            out.push(g);
            oracle_nanos += ns;
        }
    }
    bar.finish_and_clear();
    Ok(Tallies {
        shape: sel.shape,
        cases: sel.cases,
        methods: sel
            .methods
            .iter()
            .map(|m| MethodTag {
                name: m.name().to_string(),
                robust: m.robust(),
                replay: m.replay(),
                identity: m.identity(),
            })
            .collect(),
        groups: out,
        oracle_nanos,
    })
}

/// The oracle's truth and every method's judged sample on one input (`probe`'s step).
pub fn judge_all(
    shape: &dyn Shape,
    methods: &[&dyn Method],
    input: &[f64],
    prec: Precision,
) -> Result<(Truth, Vec<Sample>), String> {
    let (truth, _) = oracle(shape, input, prec);
    let samples = answers(methods, prec, &[input.to_vec()])?
        .into_iter()
        .map(|mut a| sample(shape, &truth, input, a.remove(0), prec))
        .collect();
    for m in methods {
        m.finish()?;
    }
    Ok((truth, samples))
}
