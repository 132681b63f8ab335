//! Aggregation: every judged case of one method × precision × class is added to a [`Tally`];
//! a tally becomes one row of the report ([`super::row`]).
//!
//! A tally is exact and mergeable: counts add, samples are histograms ([`super::hist`]), and the
//! examples are chosen by rules that do not depend on the order of the cases (the worst value
//! error, ties to the lowest index; the lowest index of each failure kind). So a run split in
//! any way — over threads, or over shards merged later — gives the same rows, byte for byte.

use super::hist::{FloatHist, Hist};
use super::judge::Judgement;
use crate::shapes::shape::Truth;
use serde::{Deserialize, Serialize};

/// What was recorded of one case for one method.
pub struct Sample {
    /// How the answer compares with the oracle.
    pub judgement: Judgement,
    /// The method's count.
    pub count: u32,
    /// The method's values, exactly.
    pub values: Vec<f64>,
    /// The hit point's residual, for shapes that report one (right-verdict hits only).
    pub residual: Option<f64>,
    /// Whether the method's enclosure holds, and its width in ulps.
    pub enclosure: Option<(bool, u64)>,
    /// The error over the case's sensitivity, for shapes whose oracle gives it (right-verdict
    /// hits only): [`crate::audit::judge::err_over_cond`].
    pub err_over_cond: Option<f64>,
}

/// One evaluated case: its inputs, the oracle's truth, and one sample per method.
pub struct Case {
    /// Index of the case in its class's stream.
    pub index: u64,
    /// The inputs, exactly.
    pub input: Vec<f64>,
    /// `None` when the generator found no member.
    pub truth: Option<Truth>,
    /// One sample per method, in tally order.
    pub samples: Vec<Sample>,
}

/// What happened on invalid inputs.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct InvalidStats {
    /// Invalid cases run.
    pub cases: u64,
    /// Invalid cases the method rejected (the right answer).
    pub rejected: u64,
    /// Invalid cases answered with a NaN or infinite value.
    pub nonfinite_t: u64,
    /// Invalid cases answered with a finite hit.
    pub hit: u64,
}

impl InvalidStats {
    fn merge(&mut self, o: &InvalidStats) {
        self.cases += o.cases;
        self.rejected += o.rejected;
        self.nonfinite_t += o.nonfinite_t;
        self.hit += o.hit;
    }
}

/// A case kept as an example: everything needed to print and replay it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Index of the case in its class's stream.
    pub index: u64,
    /// The inputs, exactly (hex floats in a shard file).
    #[serde(with = "super::hexfloat::exact_vec")]
    pub input: Vec<f64>,
    /// The method's values, exactly.
    #[serde(with = "super::hexfloat::exact_vec")]
    pub method_values: Vec<f64>,
    /// The oracle's correctly rounded values, exactly.
    #[serde(with = "super::hexfloat::exact_vec")]
    pub oracle_values: Vec<f64>,
    /// The method's error by the shape's metric (`None` for a wrong verdict).
    pub ulps: Option<u64>,
    /// What the example is worst at, for choosing between candidates: the ulps, or the
    /// residual's `f64` bits (which order like the non-negative values).
    pub key: u64,
}

/// The kinds of example, in the order a row lists them (worst first, residual last).
pub const KINDS: [&str; 11] = [
    "worst_ulps",
    "malformed",
    "false_hit",
    "false_miss",
    "wrong_root",
    "nonfinite_t",
    "out_of_range",
    "enclosure_violation",
    "invalid_nan_t",
    "invalid_hit",
    "worst_residual",
];

/// Whether `kind` keeps its largest `key` (else its lowest index).
fn keeps_worst(kind: &str) -> bool {
    kind.starts_with("worst_")
}

/// The case counters of a tally, and of the row made from it: what was run and every kind of
/// wrong verdict (one list, so that a row cannot forget a counter its tally has).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Counts {
    /// Cases run.
    pub cases: u64,
    /// Cases for which the generator found no member.
    pub generator_failures: u64,
    /// Valid cases that a one-ulp move of one input flips.
    pub ill_posed: u64,
    /// Valid cases that no one-ulp move flips.
    pub well_posed: u64,
    /// Well-posed valid cases whose exact count is not 0.
    pub oracle_hits: u64,
    /// Cases whose value's rounding the oracle could not make certain.
    pub cap_reached: u64,
    /// Well-posed cases with more hits or roots than the exact answer.
    pub false_hit: u64,
    /// Well-posed cases with fewer hits or roots than the exact answer.
    pub false_miss: u64,
    /// Well-posed cases whose first value is nearer another root than the right one.
    pub wrong_root: u64,
    /// Well-posed cases answered with a NaN or infinite value.
    pub nonfinite_t: u64,
    /// Well-posed cases answered with a hit outside the shape's interval (`t ≤ 0`).
    #[serde(default)]
    pub out_of_range: u64,
    /// Ill-posed cases answered with a hit outside the shape's interval (never excused: no
    /// one-ulp move makes `t ≤ 0` right).
    #[serde(default)]
    pub ill_posed_out_of_range: u64,
    /// Ill-posed cases answered with a hit whose value is NaN or infinite (a routine of yours
    /// is held to finite hits on every case: [`super::tolerance`]).
    #[serde(default)]
    pub ill_posed_nonfinite: u64,
    /// Cases of any kind (valid or invalid, well- or ill-posed) answered outside the answer
    /// contract ([`super::contract`]): a row with one fails whatever its rule.
    #[serde(default)]
    pub malformed: u64,
}

impl Counts {
    /// Wrong verdicts on well-posed valid cases: false hits, false misses, wrong roots,
    /// non-finite values, hits out of range.
    pub fn wrong(&self) -> u64 {
        self.false_hit + self.false_miss + self.wrong_root + self.nonfinite_t + self.out_of_range
    }

    /// Adds another tally's counts.
    fn merge(&mut self, o: &Counts) {
        self.cases += o.cases;
        self.generator_failures += o.generator_failures;
        self.ill_posed += o.ill_posed;
        self.well_posed += o.well_posed;
        self.oracle_hits += o.oracle_hits;
        self.cap_reached += o.cap_reached;
        self.false_hit += o.false_hit;
        self.false_miss += o.false_miss;
        self.wrong_root += o.wrong_root;
        self.nonfinite_t += o.nonfinite_t;
        self.out_of_range += o.out_of_range;
        self.ill_posed_out_of_range += o.ill_posed_out_of_range;
        self.ill_posed_nonfinite += o.ill_posed_nonfinite;
        self.malformed += o.malformed;
    }
}

/// Everything a row needs from the cases of one method × precision × class.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Tally {
    /// Cases run and wrong verdicts by kind.
    #[serde(flatten)]
    pub counts: Counts,
    /// Ill-posed cases on which the method's verdict differs from the exact one.
    pub ill_posed_disagree: u64,
    /// What the method did on invalid inputs.
    pub invalid: InvalidStats,
    /// Value errors of right-verdict answers on well-posed cases.
    pub ulps: Hist,
    /// Error over the case's sensitivity, for shapes whose oracle gives it.
    pub err_over_cond: FloatHist,
    /// Hit-point residuals in ulps of the shape's size, for shapes that report them.
    pub residual: FloatHist,
    /// Enclosures checked, violated, and their widths in ulps.
    pub enclosures: u64,
    /// Enclosures that did not contain the exact value.
    pub enclosure_violations: u64,
    /// Enclosure widths, in ulps.
    pub enclosure_widths: Hist,
    /// One candidate per kind of [`KINDS`].
    pub examples: Vec<(String, Candidate)>,
}

impl std::ops::Deref for Tally {
    type Target = Counts;
    fn deref(&self) -> &Counts {
        &self.counts
    }
}

impl std::ops::DerefMut for Tally {
    fn deref_mut(&mut self) -> &mut Counts {
        &mut self.counts
    }
}

impl Tally {
    /// Keeps `c` as the example of `kind` if it beats the one kept.
    fn offer(&mut self, kind: &str, c: impl FnOnce() -> Candidate, key: u64, index: u64) {
        let better = |old: &Candidate| {
            if keeps_worst(kind) {
                key > old.key || (key == old.key && index < old.index)
            } else {
                index < old.index
            }
        };
        match self.examples.iter_mut().find(|(k, _)| k == kind) {
            Some((_, old)) if better(old) => *old = c(),
            Some(_) => {}
            None => self.examples.push((kind.to_string(), c())),
        }
    }

    /// Adds method `k`'s sample of one case.
    pub fn add(&mut self, case: &Case, k: usize) {
        self.cases += 1;
        let Some(truth) = &case.truth else {
            self.generator_failures += 1;
            return;
        };
        let s = &case.samples[k];
        let candidate = |ulps: Option<u64>, key: u64| {
            let oracle_values = match truth {
                Truth::Answer(e) => e.values.clone(),
                Truth::Invalid => vec![],
            };
            move || Candidate {
                index: case.index,
                input: case.input.clone(),
                method_values: s.values.clone(),
                oracle_values,
                ulps,
                key,
            }
        };
        // Outside the contract: counted on every case, never excused
        if s.judgement == Judgement::Malformed {
            self.malformed += 1;
            self.offer("malformed", candidate(None, 0), 0, case.index);
        }
        let e = match truth {
            // Invalid input: a rejection is right
            Truth::Invalid => {
                self.invalid.cases += 1;
                match s.judgement {
                    Judgement::Rejected => self.invalid.rejected += 1,
                    Judgement::Malformed => {}
                    Judgement::InvalidNanT => {
                        self.invalid.nonfinite_t += 1;
                        self.offer("invalid_nan_t", candidate(None, 0), 0, case.index);
                    }
                    _ => {
                        self.invalid.hit += 1;
                        self.offer("invalid_hit", candidate(None, 0), 0, case.index);
                    }
                }
                return;
            }
            Truth::Answer(e) => e,
        };
        self.cap_reached += e.cap_reached as u64;
        // Ill-posed cases are reported apart
        if e.ill_posed {
            self.ill_posed += 1;
            self.ill_posed_disagree += s.judgement.is_wrong() as u64;
            if s.judgement == Judgement::OutOfRange {
                self.ill_posed_out_of_range += 1;
                self.offer("out_of_range", candidate(None, 0), 0, case.index);
            }
            if s.judgement == Judgement::NonfiniteT {
                self.ill_posed_nonfinite += 1;
                self.offer("nonfinite_t", candidate(None, 0), 0, case.index);
            }
            return;
        }
        self.well_posed += 1;
        self.oracle_hits += (e.count > 0) as u64;
        let (kind, counter) = match s.judgement {
            Judgement::FalseHit => ("false_hit", &mut self.false_hit),
            Judgement::FalseMiss => ("false_miss", &mut self.false_miss),
            Judgement::WrongRoot => ("wrong_root", &mut self.wrong_root),
            Judgement::NonfiniteT => ("nonfinite_t", &mut self.nonfinite_t),
            Judgement::OutOfRange => ("out_of_range", &mut self.out_of_range),
            Judgement::Ok { ulps: Some(u) } => {
                self.add_right(case, k, u, candidate);
                return;
            }
            _ => return,
        };
        *counter += 1;
        self.offer(kind, candidate(None, 0), 0, case.index);
    }

    /// A right verdict with a value error of `u`: its samples and the worst-case examples.
    fn add_right<F: FnOnce() -> Candidate>(
        &mut self,
        case: &Case,
        k: usize,
        u: u64,
        candidate: impl Fn(Option<u64>, u64) -> F,
    ) {
        let s = &case.samples[k];
        self.ulps.add(u);
        if let Some(r) = s.err_over_cond {
            self.err_over_cond.add(r);
        }
        if u > 0 {
            self.offer("worst_ulps", candidate(Some(u), u), u, case.index);
        }
        if let Some(r) = s.residual {
            self.residual.add(r);
            let key = if r.is_nan() { f64::INFINITY } else { r.abs() }.to_bits();
            self.offer("worst_residual", candidate(None, key), key, case.index);
        }
        if let Some((holds, width)) = s.enclosure {
            self.enclosures += 1;
            self.enclosure_widths.add(width);
            if !holds {
                self.enclosure_violations += 1;
                self.offer("enclosure_violation", candidate(Some(u), 0), 0, case.index);
            }
        }
    }

    /// Whether the tally is one a run can make: its counts add up (every case counted once,
    /// each finding within what it counts over, as many samples as right answers) and an
    /// example is kept for each kind of finding that occurred, and none for one that did not.
    /// A shard file's tallies pass this before a merge judges them. The error names the first
    /// count that does not add up.
    pub fn check(&self) -> Result<(), String> {
        let sum = |v: &[u64]| v.iter().try_fold(0u64, |a, &b| a.checked_add(b));
        let i = &self.invalid;
        let wrong = sum(&[
            self.false_hit,
            self.false_miss,
            self.wrong_root,
            self.nonfinite_t,
            self.out_of_range,
        ]);
        let rules: [(&str, bool); 13] = [
            (
                "cases = generator failures + invalid + ill-posed + well-posed",
                sum(&[
                    self.generator_failures,
                    i.cases,
                    self.ill_posed,
                    self.well_posed,
                ]) == Some(self.cases),
            ),
            (
                "invalid outcomes ≤ invalid cases",
                sum(&[i.rejected, i.nonfinite_t, i.hit]).is_some_and(|n| n <= i.cases),
            ),
            (
                "wrong verdicts ≤ well-posed cases",
                wrong.is_some_and(|w| w <= self.well_posed),
            ),
            (
                "oracle hits ≤ well-posed cases",
                self.oracle_hits <= self.well_posed,
            ),
            (
                "ill-posed findings ≤ ill-posed cases",
                self.ill_posed_disagree <= self.ill_posed
                    && self.ill_posed_out_of_range + self.ill_posed_nonfinite
                        <= self.ill_posed_disagree,
            ),
            ("malformed ≤ cases", self.malformed <= self.cases),
            (
                "cap reached ≤ valid cases",
                self.cap_reached <= self.ill_posed.saturating_add(self.well_posed),
            ),
            (
                "value errors ≤ right verdicts",
                wrong
                    .is_some_and(|w| self.ulps.count() <= self.well_posed - w.min(self.well_posed)),
            ),
            (
                "err/cond and residual samples ≤ value errors",
                self.err_over_cond.count() <= self.ulps.count()
                    && self.residual.count() <= self.ulps.count(),
            ),
            (
                "enclosures ≤ value errors, violations ≤ enclosures, widths = enclosures",
                self.enclosures <= self.ulps.count()
                    && self.enclosure_violations <= self.enclosures
                    && self.enclosure_widths.count() == self.enclosures,
            ),
            (
                "examples of known kinds, once each",
                self.examples
                    .iter()
                    .all(|(k, _)| KINDS.contains(&k.as_str()))
                    && (1..self.examples.len()).all(|j| {
                        !self.examples[..j]
                            .iter()
                            .any(|(k, _)| *k == self.examples[j].0)
                    }),
            ),
            (
                "an example for each finding that occurred, none for one that did not",
                [
                    ("malformed", self.malformed),
                    ("false_hit", self.false_hit),
                    ("false_miss", self.false_miss),
                    ("wrong_root", self.wrong_root),
                    (
                        "nonfinite_t",
                        self.nonfinite_t.saturating_add(self.ill_posed_nonfinite),
                    ),
                    (
                        "out_of_range",
                        self.out_of_range
                            .saturating_add(self.ill_posed_out_of_range),
                    ),
                    ("enclosure_violation", self.enclosure_violations),
                    ("invalid_nan_t", i.nonfinite_t),
                    ("invalid_hit", i.hit),
                ]
                .iter()
                .all(|(k, n)| self.examples.iter().any(|(e, _)| e == k) == (*n > 0)),
            ),
            (
                "a worst-error example exactly when some error is above 0",
                self.examples.iter().any(|(e, _)| e == "worst_ulps")
                    == self.ulps.max().is_some_and(|m| m > 0),
            ),
        ];
        match rules.iter().find(|(_, holds)| !holds) {
            Some((rule, _)) => Err(format!("its counts do not add up ({rule})")),
            None => Ok(()),
        }
    }

    /// Adds another tally of the same row (another slice of its cases).
    pub fn merge(&mut self, o: &Tally) {
        self.counts.merge(&o.counts);
        self.ill_posed_disagree += o.ill_posed_disagree;
        self.invalid.merge(&o.invalid);
        self.ulps.merge(&o.ulps);
        self.err_over_cond.merge(&o.err_over_cond);
        self.residual.merge(&o.residual);
        self.enclosures += o.enclosures;
        self.enclosure_violations += o.enclosure_violations;
        self.enclosure_widths.merge(&o.enclosure_widths);
        for (kind, c) in &o.examples {
            self.offer(kind, || c.clone(), c.key, c.index);
        }
    }
}

#[cfg(test)]
mod merge_tests {
    use super::Tally;
    use serde_json::Value;

    /// Every counter of a tally (top level and nested objects of counts), by path.
    fn counters(v: &Value, path: String, out: &mut Vec<(String, u64)>) {
        if let Value::Object(m) = v {
            for (k, x) in m {
                let p = format!("{path}.{k}");
                match x {
                    Value::Number(n) if n.is_u64() => out.push((p, n.as_u64().unwrap())),
                    Value::Object(_) if k == "invalid" => counters(x, p, out),
                    _ => {}
                }
            }
        }
    }

    /// Merging sums every counter, whatever its name: a tally whose every counter is non-zero
    /// (each a different value) merged into itself has each doubled. A counter the merge forgets
    /// (the enclosure violations, say: no audited case has one, so the shard tests cannot see
    /// it) fails here.
    #[test]
    fn merge_sums_every_counter() {
        let mut v = serde_json::to_value(Tally::default()).unwrap();
        let mut next = 1u64;
        fn fill(v: &mut Value, next: &mut u64) {
            if let Value::Object(m) = v {
                for (k, x) in m.iter_mut() {
                    match x {
                        Value::Number(n) if n.is_u64() => {
                            *x = Value::from(*next);
                            *next += 1;
                        }
                        Value::Object(_) if k == "invalid" => fill(x, next),
                        _ => {}
                    }
                }
            }
        }
        fill(&mut v, &mut next);
        let mut before = vec![];
        counters(&v, String::new(), &mut before);
        assert!(before.len() >= 18, "{before:?}");
        assert!(before.iter().any(|(k, _)| k == ".enclosure_violations"));
        let t: Tally = serde_json::from_value(v).unwrap();
        let mut merged = t.clone();
        merged.merge(&t);
        let mut after = vec![];
        counters(
            &serde_json::to_value(&merged).unwrap(),
            String::new(),
            &mut after,
        );
        for ((k, a), (k2, b)) in before.iter().zip(&after) {
            assert_eq!(k, k2);
            assert_eq!(*b, 2 * a, "{k}: {a} merged with itself gives {b}");
        }
    }
}
