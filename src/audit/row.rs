//! One row of the report: a method in a precision on a class, made from its [`Tally`], with the
//! tolerance table's [`Verdict`] (given by [`super::tolerance`]).

use super::hist::Stats;
use super::tally::{Candidate, Counts, InvalidStats, Tally, KINDS};
use crate::numerics::Precision;
use crate::shapes::shape::{hex_text, probe_line_with};
use serde::Serialize;

/// The outcome of a row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Within its rule.
    Pass,
    /// A known failure, shown as expected.
    KnownFailure,
    /// Too few cases to tell whether a known failure still fails.
    Undecided,
    /// No rule applies: reported only.
    Unchecked,
    /// Outside its rule.
    Fail,
}

/// A row's verdict with its reasons (one line each).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// Within tolerance, a known failure shown, too few cases to tell, not checked, or failed.
    pub status: Status,
    /// The rule that applied (`FILE rule N`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rule: Option<String>,
    /// The row's own count `[k, n]` under a measured rule (wrong verdicts, or failures of a
    /// known failure, in well-posed cases): what `[measured]` records for it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<[u64; 2]>,
    /// Why the row fails, one line each (empty unless the status is `fail`).
    pub reasons: Vec<String>,
    /// What else the verdict says (a known failure shown, or too few cases to tell).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

/// A case worth replaying, with the command that replays it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Example {
    /// One of [`KINDS`].
    pub kind: String,
    /// Index of the case in its class's stream.
    pub index: u64,
    /// The `rayproof probe` line that replays the case.
    pub probe: String,
    /// The method's values, as hex floats.
    pub method_values: Vec<String>,
    /// The oracle's correctly rounded values, as hex floats.
    pub oracle_values: Vec<String>,
    /// The method's error by the shape's metric (`None` for a wrong verdict).
    pub ulps: Option<u64>,
}

/// Enclosure checks for methods that return one.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct EnclosureStats {
    /// Enclosures checked (hits on well-posed cases).
    pub checked: u64,
    /// Enclosures that did not contain the exact value.
    pub violations: u64,
    /// Width `hi − lo` in ulps of the precision.
    pub width_ulps: Stats,
}

/// One row: a method in a precision on a class.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Row {
    /// Method name.
    pub method: String,
    /// Offered as robust: held to the strict rows of the tolerance table.
    pub robust: bool,
    /// Precision of the inputs and the arithmetic.
    pub precision: Precision,
    /// Case class name.
    pub class: String,
    /// Cases run (valid and invalid), cases the generator found no member for (a broken
    /// generator shows here), ill- and well-posed cases, oracle hits, the oracle's precision cap
    /// reached, and every kind of wrong verdict: the tally's own counters.
    #[serde(flatten)]
    pub counts: Counts,
    /// Wrong verdicts / well-posed valid cases.
    pub wrong_rate: f64,
    /// Ill-posed cases on which the method's verdict differs from the exact one (not failures).
    pub ill_posed_disagree: u64,
    /// Value error (by the shape's metric) over right-verdict answers of well-posed cases.
    pub ulps: Stats,
    /// Herbie's bits of error, log2(1 + ulps).
    pub bits: Stats,
    /// Error relative to the case's sensitivity: ulps / max(1, condition ulps). Near 1: as
    /// accurate as the inputs allow; large: the method lost digits the case did not force it
    /// to lose. Only for shapes whose oracle gives the sensitivity.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub err_over_cond: Option<Stats>,
    /// |hit-point residual| in ulps of the shape's size (shapes that report it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_ulps: Option<Stats>,
    /// What the method did on invalid inputs.
    pub invalid: InvalidStats,
    /// Enclosure checks (methods that return an enclosure).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub enclosure: Option<EnclosureStats>,
    /// Cases worth replaying, one per kind of [`crate::audit::tally::KINDS`] that occurred.
    pub examples: Vec<Example>,
    /// The tolerance table's verdict (not given for a shard, whose merge judges it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub verdict: Option<Verdict>,
}

impl std::ops::Deref for Row {
    type Target = Counts;
    fn deref(&self) -> &Counts {
        &self.counts
    }
}

impl std::ops::DerefMut for Row {
    fn deref_mut(&mut self) -> &mut Counts {
        &mut self.counts
    }
}

/// What a row is about, beside its tally.
pub struct RowKey<'a> {
    /// Shape name.
    pub shape: &'a str,
    /// The probe arguments that replay an outside method.
    pub replay: Option<&'a str>,
    /// Method name.
    pub method: &'a str,
    /// Offered as robust.
    pub robust: bool,
    /// Precision of the row.
    pub precision: Precision,
    /// Case class name.
    pub class: &'a str,
    /// The shape's oracle gives the sensitivity (err/cond) / reports residuals.
    pub has_cond: bool,
    /// The shape reports hit-point residuals.
    pub has_residual: bool,
}

impl Tally {
    /// The row of this tally.
    pub fn row(&self, key: &RowKey) -> Row {
        let mut examples: Vec<&(String, Candidate)> = self.examples.iter().collect();
        examples.sort_by_key(|(kind, c)| {
            let rank = KINDS.iter().position(|k| k == kind).unwrap_or(KINDS.len());
            // The worst first, the residual last, failures by first occurrence between
            match rank {
                0 => (0, 0, 0),
                r if r == KINDS.len() - 1 => (2, 0, 0),
                r => (1, c.index, r),
            }
        });
        let hex = |v: &[f64]| v.iter().map(|&x| hex_text(x)).collect();
        Row {
            method: key.method.to_string(),
            robust: key.robust,
            precision: key.precision,
            class: key.class.to_string(),
            counts: self.counts.clone(),
            wrong_rate: self.wrong() as f64 / self.well_posed.max(1) as f64,
            ill_posed_disagree: self.ill_posed_disagree,
            ulps: self.ulps.stats(),
            bits: self.ulps.stats_of(|u| (1.0 + u as f64).log2()),
            err_over_cond: key.has_cond.then(|| self.err_over_cond.stats()),
            residual_ulps: key.has_residual.then(|| self.residual.stats()),
            invalid: self.invalid.clone(),
            enclosure: (self.enclosures > 0).then(|| EnclosureStats {
                checked: self.enclosures,
                violations: self.enclosure_violations,
                width_ulps: self.enclosure_widths.stats(),
            }),
            examples: examples
                .into_iter()
                .map(|(kind, c)| Example {
                    kind: kind.clone(),
                    index: c.index,
                    probe: probe_line_with(key.shape, key.precision, key.replay, &c.input),
                    method_values: hex(&c.method_values),
                    oracle_values: hex(&c.oracle_values),
                    ulps: c.ulps,
                })
                .collect(),
            verdict: None,
        }
    }
}
