//! The answer contract: what a routine may answer for a shape, stated once and checked once for
//! every way an answer comes in (the Rust API, `--plugin`, `--exec`, `score`, `probe`), so the
//! same routine gets the same verdict whichever way it is audited.
//!
//! An answer is a **count** and a list of **values** ([`Answer`]):
//!
//! - **Count.** For a shape whose count is its number of values (the polynomials: distinct real
//!   roots), `0 ≤ count ≤ OUT` (OUT = the shape's number of output values), followed by exactly
//!   `count` values in non-decreasing order. For every other shape the count is `0` (a miss, no
//!   real root, total internal reflection) with no value, or `1` (a hit) with all `OUT` values.
//! - **Values.** A hit's values are finite. A NaN or an infinity is a *non-finite value* (a
//!   wrong answer on valid input, `nan_t` on invalid input), never a miss.
//! - **Interval of `t`.** For the ray shapes (sphere, triangle, box, ellipsoid, cylinder, torus:
//!   [`Domain::RayParameter`]) a hit's `t` lies in `t > 0`: a hit at `t < 0`, at `-0`, or at `+0`
//!   is *out of range*, except `+0` where the exact `t > 0` itself rounds to `0` in the precision
//!   (below half the least subnormal). Roots, reciprocals and vector components
//!   ([`Domain::Real`]) may be any finite value.
//! - **Invalid input** (NaN or infinite inputs, a degenerate shape) is answered with count 0.
//!
//! An answer that breaks the count or the number of values is **malformed**: counted in its row
//! on every case (well-posed, ill-posed or invalid) and never excused: a row with a malformed
//! answer fails whatever its rule. A hit outside the interval is **out of range**: a wrong
//! verdict like a false hit, counted on well-posed cases (and on ill-posed ones, as a
//! disagreement). Neither is ever "ok".
//!
//! The text protocol (an `--exec` child's answer line, a line of a `score` answers file) is
//! parsed by [`parse_line`]: the count as a whole number, then the values in decimal or C99 hex
//! (`inf`, `-inf`, `nan` allowed); a line that does not parse is not an answer but a broken
//! protocol, and stops the run (`--exec`: exit 4; `score`: exit 2) with one line naming the case.

use crate::numerics::real::parse_f64;
use crate::numerics::Precision;
use crate::shapes::shape::{Answer, Domain, ShapeInfo};

/// How many values a hit of the shape has at most, and whether the count is the number of
/// values (else a hit is `1` with all of them).
fn shape_of(info: &ShapeInfo) -> (usize, bool) {
    (info.values.len(), info.count_is_values)
}

/// Why an answer's count and values do not fit the shape (`None`: they fit).
pub fn malformed(info: &ShapeInfo, a: &Answer) -> Option<String> {
    let (out, counted) = shape_of(info);
    let (c, k) = (a.count as usize, a.values.len());
    if counted {
        if c > out {
            return Some(format!(
                "count {c}, but a {} case has at most {out} roots",
                info.name
            ));
        }
        if k != c {
            return Some(format!("count {c} with {k} value(s)"));
        }
        if a.values.windows(2).any(|w| w[0] > w[1]) {
            return Some("roots not in ascending order".into());
        }
        return None;
    }
    match (c, k) {
        (0, 0) => None,
        (0, k) => Some(format!("a miss (count 0) with {k} value(s)")),
        (1, k) if k == out => None,
        (1, k) => Some(format!(
            "a hit with {k} value(s), where a {} hit has {out} ({})",
            info.name,
            info.values.join(" ")
        )),
        (c, _) => Some(format!(
            "count {c}, but a {} answer is 0 (miss) or 1 (hit)",
            info.name
        )),
    }
}

/// Whether a well-formed hit with finite values lies outside the shape's interval; `exact_zero`:
/// the oracle's correctly rounded first value is `+0` (the exact `t > 0` underflows).
pub fn out_of_range(info: &ShapeInfo, a: &Answer, exact_zero: bool) -> bool {
    if info.domain != Domain::RayParameter || a.count == 0 {
        return false;
    }
    match a.values.first() {
        Some(&t) if t < 0.0 => true,
        Some(&t) if t == 0.0 => t.is_sign_negative() || !exact_zero,
        _ => false,
    }
}

/// The interval a hit's first value must lie in, in words.
pub fn interval(info: &ShapeInfo) -> &'static str {
    match info.domain {
        Domain::RayParameter => {
            "a hit's t is finite and > 0 (+0 only where the exact t rounds to 0)"
        }
        Domain::Real => "a hit's values are finite",
    }
}

/// The contract of a shape in words (for `rayproof header` and help texts).
pub fn describe(info: &ShapeInfo) -> String {
    let (out, counted) = shape_of(info);
    let names = info.values.join(" ");
    let count = if counted {
        format!("count = the number of distinct real roots (0 to {out}), followed by that many values in ascending order ({names})")
    } else {
        format!("count = 0 for a miss (no value), 1 for a hit with all {out} value(s) ({names})")
    };
    let range = interval(info);
    format!("{count}; {range}; NaN or Inf in a hit is a non-finite (wrong) value; invalid input is answered with count 0")
}

/// A number of an answer: decimal or hex, `inf`, `-inf`, `nan`.
pub fn number(s: &str) -> Option<f64> {
    match s {
        "nan" | "NaN" | "-nan" => Some(f64::NAN),
        _ => parse_f64(s),
    }
}

/// Parses one answer line of the text protocol (`COUNT VALUE…`), rounding each value once to
/// the precision. An error is a broken protocol (not a count, not a number), not a wrong answer:
/// the contract is checked by the judge.
pub fn parse_line(line: &str, prec: Precision) -> Result<Answer, String> {
    let mut w = line.split_whitespace();
    let first = w.next().ok_or("an empty line")?;
    let count: u32 = first
        .parse()
        .map_err(|_| format!("'{first}' is not a count (a whole number)"))?;
    let values = w
        .map(|s| {
            let v = number(s).ok_or_else(|| format!("'{s}' is not a number"))?;
            Ok(match prec {
                Precision::F32 => v as f32 as f64,
                Precision::F64 => v,
            })
        })
        .collect::<Result<Vec<f64>, String>>()?;
    Ok(Answer {
        count,
        values,
        enclosure: None,
    })
}
