//! The audit's report: one [`ShapeReport`] per shape (its rows, each with the tolerance
//! table's verdict) and the reintersection and watertightness tests of a whole audit. The JSON
//! of `--json` is this structure; the same seed gives byte-identical JSON.

use super::row::{Row, RowKey, Status};
use super::run::Tallies;
use super::tolerance::{Table, DEFAULT_GOAL};
use crate::audit::robustness::Robustness;
use serde::Serialize;

/// The `tool` field of reports and shard files.
pub const TOOL: &str = concat!("rayproof ", env!("CARGO_PKG_VERSION"));

/// One shape's rows.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ShapeReport {
    /// The shape's name.
    pub shape: String,
    /// One line: what the shape computes and where it comes from.
    pub about: String,
    /// How value errors are measured: `ulps` or `norm_ulps`.
    pub metric: &'static str,
    /// Cases per class and precision.
    pub cases_per_class: u64,
    /// One row per method × precision × class, in that order.
    pub rows: Vec<Row>,
}

/// The whole audit.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// The tool and its version: `rayproof X.Y.Z`.
    pub tool: &'static str,
    /// Seed of the case streams.
    pub seed: u64,
    /// `K/N` for a shard's own report; `0/1` for a whole run and for a merge.
    pub shard: String,
    /// One report per shape, in audit order.
    pub shapes: Vec<ShapeReport>,
    /// The reintersection and watertightness tests (run when every shape is audited).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robustness: Option<Robustness>,
}

impl Tallies {
    /// The rows, in precision × class × method order, judged by `table` when given.
    pub fn report(&self, table: Option<&Table>) -> ShapeReport {
        let info = self.shape.info();
        let mut rows = vec![];
        for g in &self.groups {
            for (m, t) in self.methods.iter().zip(&g.tallies) {
                let key = RowKey {
                    shape: info.name,
                    replay: m.replay.as_deref(),
                    method: &m.name,
                    robust: m.robust,
                    precision: g.precision,
                    class: info.classes[g.class],
                    has_cond: info.reports_cond,
                    has_residual: info.reports_residual,
                };
                let mut row = t.row(&key);
                let yours = !info.methods.iter().any(|b| b.name == m.name);
                row.verdict =
                    table.map(|tb| tb.verdict(info.name, &row, yours, |u| t.ulps.above(u)));
                rows.push(row);
            }
        }
        ShapeReport {
            shape: info.name.to_string(),
            about: info.about.to_string(),
            metric: info.metric.name(),
            cases_per_class: self.cases,
            rows,
        }
    }
}

/// The verdict of a judged audit: its rows counted by status, what failed and what could not
/// be told, one line each.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// Judged rows.
    pub rows: u64,
    /// Rows within their rule.
    pub pass: u64,
    /// Known failures shown, as expected.
    pub known_failures: u64,
    /// Rows no rule applies to (reported only).
    pub unchecked: u64,
    /// Rows outside their rule.
    pub out_of_tolerance: u64,
    /// Known failures too few cases could show.
    pub undecided: Vec<String>,
    /// Rows out of tolerance and robustness goals missed.
    pub failures: Vec<String>,
}

impl Outcome {
    /// No row out of tolerance, no robustness goal missed.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }
    /// The command's exit status: 0 pass, 1 a failure (`src/lib.rs` lists every code).
    pub fn exit_code(&self) -> u8 {
        if self.passed() {
            0
        } else {
            1
        }
    }
}

impl Report {
    /// The verdict: every judged row counted by status, the failures and the undecided rows.
    pub fn outcome(&self) -> Outcome {
        let judged: Vec<Status> = self
            .rows()
            .filter_map(|(_, r)| r.verdict.as_ref().map(|v| v.status))
            .collect();
        let n = |s: Status| judged.iter().filter(|&&x| x == s).count() as u64;
        Outcome {
            rows: self.rows().count() as u64,
            pass: n(Status::Pass),
            known_failures: n(Status::KnownFailure),
            unchecked: n(Status::Unchecked),
            out_of_tolerance: n(Status::Fail),
            undecided: self.undecided(),
            failures: self.failures(),
        }
    }

    /// Rows of every shape with their shape's name.
    pub fn rows(&self) -> impl Iterator<Item = (&str, &Row)> {
        self.shapes
            .iter()
            .flat_map(|s| s.rows.iter().map(move |r| (s.shape.as_str(), r)))
    }

    /// Every row out of tolerance, and every robustness goal missed, one line each.
    pub fn failures(&self) -> Vec<String> {
        let mut out: Vec<String> = self.shapes.iter().flat_map(|s| s.failures()).collect();
        if let Some(r) = &self.robustness {
            out.extend(crate::audit::robustness::check(r));
        }
        out
    }

    /// The rules of the user's file (`[[rule]]` and `[[robustness]]`) that judged no row of
    /// this run (a precision, class, test or mode the run did not audit), one line each: said,
    /// so that a rule's silence is not read as its pass.
    pub fn unused_rules(&self, table: &Table) -> Vec<String> {
        let yours = |origin: &str| !origin.starts_with("built-in");
        let rules = table
            .rules
            .iter()
            .filter(|r| yours(&r.origin))
            .filter(|r| {
                !self.rows().any(|(_, x)| {
                    x.verdict.as_ref().and_then(|v| v.rule.as_ref()) == Some(&r.origin)
                })
            })
            .map(|r| format!("{} judged no row of this run (its shape, method, precision and class: none audited here)", r.origin));
        let robust = table
            .robustness
            .iter()
            .filter(|r| yours(&r.origin))
            .filter(|r| !self.robustness.as_ref().is_some_and(|x| r.names_a_row(x)))
            .map(|r| format!("{} judged no row of this run (its routine, test, precision and mode: none run here; the seams need an audit of every class and no --no-seams)", r.origin));
        rules.chain(robust).collect()
    }

    /// Rows whose known failure could not be shown with so few cases, one line each.
    pub fn undecided(&self) -> Vec<String> {
        self.rows()
            .filter(|(_, r)| {
                r.verdict
                    .as_ref()
                    .is_some_and(|v| v.status == Status::Undecided)
            })
            .map(|(shape, r)| {
                format!(
                    "{shape} {} {} {}: {}",
                    r.method,
                    r.precision.name(),
                    r.class,
                    r.verdict
                        .as_ref()
                        .map(|v| v
                            .reasons
                            .iter()
                            .chain(&v.notes)
                            .cloned()
                            .collect::<Vec<_>>()
                            .join("; "))
                        .unwrap_or_default()
                )
            })
            .collect()
    }
}

impl ShapeReport {
    /// Every row out of tolerance, one line each (empty when the shape passes).
    pub fn failures(&self) -> Vec<String> {
        self.rows
            .iter()
            .filter(|r| r.verdict.as_ref().is_some_and(|v| v.status == Status::Fail))
            .map(|r| {
                let v = r.verdict.as_ref().expect("filtered");
                let goal = match v.rule.as_deref() {
                    Some(DEFAULT_GOAL) => format!(" ({DEFAULT_GOAL}: see `rayproof audit --help`)"),
                    _ => String::new(),
                };
                format!(
                    "{} {} {} {}: {}{goal}",
                    self.shape,
                    r.method,
                    r.precision.name(),
                    r.class,
                    v.reasons.join("; ")
                )
            })
            .collect()
    }
}
