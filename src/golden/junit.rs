//! The JUnit XML report of `rayproof check` (what CI servers read), written with `quick-xml`
//! and valid against the common `junit-10.xsd` (Maven Surefire's schema, as pytest ships it;
//! `tests/data/junit-10.xsd`, which `tests/junit.rs` validates with the real `xmllint`).
//!
//! One `<testsuites>` holding one `<testsuite>` (both named after the suite), one `<testcase>`
//! per row, named `TEST vs REFERENCE [CONFIG]`, its `classname` the test.
//!
//! | status | element in the `<testcase>` | `type` | `message` starts | counted in |
//! |---|---|---|---|---|
//! | PASS, WARNING, UPDATED | none (a pass) | | | `tests` |
//! | FAILURE | `<failure>` | `FAILURE` | `FAILURE: ` | `failures` |
//! | XPASS | `<failure>` | `XPASS` | `XPASS (a known failure now passes): ` | `failures` |
//! | NEW | `<failure>` | `NEW` | `NEW: ` | `failures` |
//! | REFUSED | `<error>` | `REFUSED` | `REFUSED: ` | `errors` |
//! | XFAIL | `<skipped>` | `XFAIL` | `XFAIL (expected failure): ` | `skipped` |
//! | SKIPPED | `<skipped>` | `SKIPPED` | `SKIPPED: ` | `skipped` |
//!
//! An unexpected pass fails the run (exit 1: the `known_failure` entry must go), so it is a
//! `<failure>`: a CI server shows the case that failed the job in red (as a `<skipped>` it
//! would show a green or grey run that exited 1), told apart from a plain failure by its `type`
//! and message. An expected failure does not fail the run: it is `<skipped>` with its reason,
//! so a dashboard counts it neither as a pass nor as a failure.
//!
//! The `<failure>`, `<error>` and XFAIL's `<skipped>` hold, as text, what a reviewer needs
//! without the HTML report: the row's headline, its metrics (or that nothing was compared), the
//! z-test, the thresholds, the render time, the command that replays it, the warnings and the
//! tail of the renderer's standard error. Every case also has the one-line result and metrics
//! in `<system-out>`, and a passing or skipped case with a renderer log has it in
//! `<system-err>`.
//!
//! **Times.** A case's `time` is its row's [`Row::seconds`]: its own comparison, and for the
//! first row of each test (the first that is not a skipped optional reference) also the test's
//! render and reading its references, so a render is counted once, never on each comparison. Each time is written in whole milliseconds and the
//! `<testsuite>` and `<testsuites>` times are the sum of those, so the file adds up exactly. A
//! refused test is timed too: a render killed at a 5 s timeout shows about 5 s.
//!
//! Text that XML 1.0 cannot hold (control characters such as a renderer's colour escapes) is
//! written as `\u{1b}`.

use super::rows::{Row, Status};
use quick_xml::events::{BytesDecl, BytesText, Event};
use quick_xml::Writer;
use std::io;

/// The JUnit element of a status: `None` (a pass), `failure`, `error` or `skipped`.
pub fn element(status: Status) -> Option<&'static str> {
    match status {
        Status::Pass | Status::Warning | Status::Updated => None,
        Status::Failure | Status::UnexpectedPass | Status::New => Some("failure"),
        Status::Refused => Some("error"),
        Status::KnownFailure | Status::Skipped => Some("skipped"),
    }
}

/// The start of a non-passing case's `message` (before the row's note).
fn headline(status: Status) -> &'static str {
    match status {
        Status::UnexpectedPass => "XPASS (a known failure now passes)",
        Status::KnownFailure => "XFAIL (expected failure)",
        s => s.label(),
    }
}

/// The rows as JUnit XML (see the module's table).
pub fn junit(rows: &[Row], suite_name: &str) -> String {
    write(rows, suite_name).unwrap_or_else(|e| {
        // Writing into memory does not fail; say so in the file if it ever does
        format!("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- cannot serialise: {e} -->\n")
    })
}

/// Whole milliseconds of a time in seconds (NaN and negative: 0).
fn millis(seconds: f64) -> u64 {
    (seconds.max(0.0) * 1000.0).round() as u64
}

/// Milliseconds as seconds with three decimals (`junit-10.xsd`'s `SUREFIRE_TIME`).
fn time(ms: u64) -> String {
    format!("{}.{:03}", ms / 1000, ms % 1000)
}

/// Text as XML 1.0 may hold it: characters it forbids written as `\u{…}`.
fn xml_safe(s: &str) -> String {
    s.chars()
        .map(|c| match c {
            '\t' | '\n' | '\r' | '\u{20}'..='\u{d7ff}' | '\u{e000}'..='\u{fffd}' => c.to_string(),
            c if c >= '\u{10000}' => c.to_string(),
            c => format!("\\u{{{:x}}}", c as u32),
        })
        .collect()
}

/// One line of XML-safe text (for attributes).
fn attr(s: &str) -> String {
    xml_safe(&s.split_whitespace().collect::<Vec<_>>().join(" "))
}

fn write(rows: &[Row], suite_name: &str) -> io::Result<String> {
    let count = |f: &dyn Fn(&Row) -> bool| rows.iter().filter(|r| f(r)).count().to_string();
    let tests = rows.len().to_string();
    let failures = count(&|r| element(r.status) == Some("failure"));
    let errors = count(&|r| element(r.status) == Some("error"));
    let skipped = count(&|r| element(r.status) == Some("skipped"));
    let total = time(rows.iter().map(|r| millis(r.seconds)).sum());
    let name = attr(suite_name);
    let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
    w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))?;
    // junit-10.xsd: `skipped` is allowed on <testsuite>, not on <testsuites>
    w.create_element("testsuites")
        .with_attributes([
            ("name", name.as_str()),
            ("tests", &tests),
            ("failures", &failures),
            ("errors", &errors),
            ("time", &total),
        ])
        .write_inner_content(|w| {
            w.create_element("testsuite")
                .with_attributes([
                    ("name", name.as_str()),
                    ("tests", &tests),
                    ("failures", &failures),
                    ("errors", &errors),
                    ("skipped", &skipped),
                    ("time", &total),
                ])
                .write_inner_content(|w| {
                    for r in rows {
                        case(w, r)?;
                    }
                    Ok(())
                })?;
            Ok(())
        })?;
    let mut xml = String::from_utf8(w.into_inner()).map_err(io::Error::other)?;
    xml.push('\n');
    Ok(xml)
}

/// One `<testcase>`.
fn case(w: &mut Writer<Vec<u8>>, r: &Row) -> io::Result<()> {
    let name = attr(&format!("{} vs {} [{}]", r.test, r.reference, r.config));
    let classname = attr(&r.test);
    let t = time(millis(r.seconds));
    w.create_element("testcase")
        .with_attributes([
            ("name", name.as_str()),
            ("classname", classname.as_str()),
            ("time", t.as_str()),
        ])
        .write_inner_content(|w| {
            if let Some(el) = element(r.status) {
                let message = attr(&match r.note.trim() {
                    "" => headline(r.status).to_string(),
                    note => format!("{}: {note}", headline(r.status)),
                });
                let el = w
                    .create_element(el)
                    .with_attributes([("type", r.status.label()), ("message", message.as_str())]);
                // A missing optional reference: its message says all there is
                if r.status == Status::Skipped {
                    el.write_empty()?;
                } else {
                    el.write_text_content(BytesText::new(&xml_safe(&details(r))))?;
                }
            }
            w.create_element("system-out")
                .write_text_content(BytesText::new(&xml_safe(&summary(r))))?;
            if let (None | Some("skipped"), Some(log)) = (element(r.status), &r.log_tail) {
                w.create_element("system-err")
                    .write_text_content(BytesText::new(&xml_safe(log)))?;
            }
            Ok(())
        })?;
    Ok(())
}

/// The metrics on one line, or `None` when nothing was compared.
fn metrics(r: &Row) -> Option<String> {
    let c = r.comparison.as_ref()?;
    Some(format!(
        "mean {:.3e}, RMS {:.3e}, PSNR {:.1} dB, max {:.3e} at ({}, {}, {}) (reference {}, test {}); {} px ({:.3} %) over fail, {} over warn; {} {}",
        c.mean_error,
        c.rms_error,
        c.psnr,
        c.max_error,
        c.max_at.0,
        c.max_at.1,
        c.max_channel,
        c.max_values.0,
        c.max_values.1,
        c.n_fail,
        100.0 * c.n_fail as f64 / c.pixels.max(1) as f64,
        c.n_warn,
        match c.flip_kind {
            Some(crate::images::FlipKind::Ldr) => "LDR-FLIP",
            _ => "HDR-FLIP",
        },
        c.flip_mean
            .map(|v| format!("{v:.4}"))
            .unwrap_or("not computed".into())
    ))
}

/// `<system-out>`: the result and the metrics.
fn summary(r: &Row) -> String {
    let mut s = r.status.label().to_string();
    if !r.note.is_empty() {
        s += &format!(" {}", r.note);
    }
    if let Some(m) = metrics(r) {
        s += &format!("\n{m}");
    }
    for w in &r.warnings {
        s += &format!("\nwarning: {w}");
    }
    if let Some(l) = &r.log {
        s += &format!("\nrenderer log: {l} (in the report directory)");
    }
    s
}

/// The text of a `<failure>`, `<error>` or XFAIL's `<skipped>`.
fn details(r: &Row) -> String {
    let t = &r.rule.idiff;
    let mut s = format!(
        "{} vs {} [{}]: {}\n",
        r.test,
        r.reference,
        r.config,
        r.status.label()
    );
    if !r.note.is_empty() {
        s += &format!("{}\n", r.note);
    }
    s += &match metrics(r) {
        Some(m) => format!("metrics: {m}\n"),
        None => "metrics: none (nothing was compared)\n".into(),
    };
    if let Some(z) = &r.ztest {
        s += &format!(
            "z-test: {} pixels fail at alpha {:.3e}: {}\n",
            z.failing_pixels,
            z.alpha,
            z.verdict.label()
        );
    }
    s += &format!(
        "thresholds: fail {} failrelative {} failpercent {} hardfail {} allowfailures {} warn {} warnrelative {} warnpercent {} hardwarn {}; max_mean {}; max_flip {}",
        t.fail,
        t.failrelative,
        t.failpercent,
        t.hardfail,
        t.allowfailures,
        t.warn,
        t.warnrelative,
        t.warnpercent,
        t.hardwarn,
        r.rule.max_mean,
        r.rule
            .max_flip
            .map(|v| v.to_string())
            .unwrap_or("none".into()),
    );
    if let Some(k) = &r.rule.known_failure {
        s += &format!("; known_failure \"{k}\"");
    }
    s += &format!("\nrender: {:.3} s\n", r.render_seconds);
    if !r.replay.is_empty() {
        s += &format!("replay: {}\n", r.replay);
    }
    for w in &r.warnings {
        s += &format!("warning: {w}\n");
    }
    if let Some(log) = &r.log_tail {
        s += &format!(
            "renderer log (the lines that explain how it ended, {} at most):\n{log}\n",
            super::rows::LOG_TAIL_LINES
        );
    }
    if let Some(l) = &r.log {
        s += &format!("whole renderer log: {l} (in the report directory)\n");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_and_text_as_the_schema_wants_them() {
        assert_eq!(time(millis(2.3456)), "2.346");
        assert_eq!(time(millis(0.0)), "0.000");
        assert_eq!(time(millis(f64::NAN)), "0.000");
        assert_eq!(time(millis(-1.0)), "0.000");
        assert_eq!(time(millis(1234.5)), "1234.500");
        assert_eq!(xml_safe("a\u{1b}[31mb\u{0}\t"), "a\\u{1b}[31mb\\u{0}\t");
        assert_eq!(xml_safe("\u{fffe}\u{10000}"), "\\u{fffe}\u{10000}");
        assert_eq!(attr(" two\nlines "), "two lines");
    }
}
