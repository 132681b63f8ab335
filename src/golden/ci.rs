//! What a CI job shows a reviewer: GitHub Actions workflow commands (annotations on the suite
//! file's `[[test]]` lines) and a Markdown summary (for `$GITHUB_STEP_SUMMARY`), failing rows
//! first, each linked to its row of the HTML report.
//!
//! Annotations (GitHub's `::error file=F,line=L,title=T::MESSAGE`): one `error` per failing row
//! (FAILURE, XPASS, NEW, REFUSED), one `warning` per row that passes with a warning or is an
//! expected failure; passing and skipped rows make none. Their text is escaped as the runner
//! parses it (`%`, CR and LF in the message; also `:` and `,` in properties), so a renderer's
//! message cannot end one early or forge another.

use super::rows::{Row, Status};
use super::Suite;

/// The rows beyond which the summary only counts (GitHub caps a step summary at 1 MiB).
pub const SUMMARY_ROWS: usize = 200;

/// An annotation's message, escaped as GitHub's runner reads it.
fn data(s: &str) -> String {
    s.replace('%', "%25")
        .replace('\r', "%0D")
        .replace('\n', "%0A")
}

/// An annotation's property value, escaped.
fn property(s: &str) -> String {
    data(s).replace(':', "%3A").replace(',', "%2C")
}

/// The anchor of a row in the HTML report: its test, reference and configuration, as
/// [`super::html()`] names the rows.
pub fn anchor(r: &Row) -> String {
    format!("{}--{}--{}", r.test, r.reference, r.config)
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The row's one-line reason: its note, else its first warning, else its status.
fn reason(r: &Row) -> String {
    let text = match (r.note.trim(), r.warnings.first()) {
        ("", Some(w)) => w.clone(),
        ("", None) => r.status.label().to_string(),
        (n, _) => n.to_string(),
    };
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// GitHub Actions workflow commands for the rows: `::error` and `::warning` lines on the suite
/// file's `[[test]]` lines, failures first, each ending in a newline.
pub fn annotations(rows: &[Row], suite: &Suite) -> String {
    let mut out = String::new();
    for r in rows {
        let level = match r.status {
            s if s.is_failure() => "error",
            Status::Warning | Status::KnownFailure => "warning",
            _ => continue,
        };
        let line = suite
            .tests
            .iter()
            .find(|t| t.name == r.test)
            .map_or(1, |t| t.line);
        let platform = r
            .platform
            .as_deref()
            .map(|p| format!(" on {p}"))
            .unwrap_or_default();
        let title = format!(
            "{} {} vs {} [{}]{platform}",
            r.status.label(),
            r.test,
            r.reference,
            r.config
        );
        let mut message = reason(r);
        if !r.replay.is_empty() {
            message += &format!("\nreplay: {}", r.replay);
        }
        out += &format!(
            "::{level} file={},line={line},title={}::{}\n",
            property(&suite.path.display().to_string()),
            property(&title),
            data(&message)
        );
    }
    out
}

/// A `--report-url`: non-empty, without a fragment (rayproof adds each row's), whitespace,
/// control characters or any of `()[]<>|"'\`` that would end a Markdown link or table cell.
pub fn check_url(url: &str) -> Result<(), String> {
    let bad = url
        .chars()
        .find(|c| c.is_whitespace() || c.is_control() || "#()[]<>|\"'`\\".contains(*c));
    match (url.is_empty(), bad) {
        (true, _) => Err("--report-url is empty".into()),
        (_, Some(c)) => Err(format!(
            "--report-url {:?}: {c:?} cannot stand in a link of the summary (percent-encode it; no #fragment: each row adds its own)",
            url.chars().take(200).collect::<String>()
        )),
        _ => Ok(()),
    }
}

/// Markdown text in a table cell: one line, `|` escaped, at most 300 characters.
fn cell(s: &str) -> String {
    let one: String = s.split_whitespace().collect::<Vec<_>>().join(" ");
    let short: String = match one.chars().count() {
        n if n > 300 => one.chars().take(299).collect::<String>() + "…",
        _ => one,
    };
    short
        .replace('\\', "\\\\")
        .replace('|', "\\|")
        .replace('&', "&amp;")
        .replace('<', "&lt;")
}

/// The run as a Markdown summary: a headline with the counts and the exit code, then a table of
/// the rows (failures first, as the rows come), each linked to its row of the HTML report at
/// `report_url` (where the report's `index.html` will be seen) when given; else the report's
/// path (`report_path`) is named, unlinked (a relative link in a step summary leads nowhere).
/// Rows after the first [`SUMMARY_ROWS`] are counted, not listed.
pub fn summary(
    rows: &[Row],
    suite: &Suite,
    exit: u8,
    report_url: Option<&str>,
    report_path: Option<&std::path::Path>,
) -> String {
    let report = report_url;
    let failing = rows.iter().filter(|r| r.status.is_failure()).count();
    let icon = |s: Status| match s {
        s if s.is_failure() => "❌",
        Status::Warning | Status::KnownFailure => "⚠️",
        Status::Skipped => "⏭️",
        _ => "✅",
    };
    let platform = suite
        .platform
        .as_deref()
        .map(|p| format!(" on `{p}`"))
        .unwrap_or_default();
    let mut s = format!(
        "## {} `{}`{platform}\n\n**{}** of {} comparisons (exit {exit}).",
        icon(if failing > 0 {
            Status::Failure
        } else {
            Status::Pass
        }),
        cell(&suite.name),
        super::counts(rows),
        rows.len()
    );
    match (report, report_path) {
        (Some(rep), _) => s += &format!(" [HTML report]({rep})"),
        (None, Some(p)) => {
            s += &format!(
                " HTML report: `{}` (give --report-url to link its rows here).",
                cell(&p.display().to_string())
            )
        }
        _ => {}
    }
    s += "\n\n| | test | reference | config | status | max error | pixels > fail | mask | why |\n|---|---|---|---|---|---|---|---|---|\n";
    for (i, r) in rows.iter().enumerate() {
        if i >= SUMMARY_ROWS {
            let more = &rows[i..];
            let fail = more.iter().filter(|r| r.status.is_failure()).count();
            s += &format!(
                "\n{} more rows ({fail} failing) left out: the JSON and JUnit reports have them all.\n",
                more.len()
            );
            break;
        }
        let c = r.comparison.as_ref();
        let test = match report {
            Some(rep) => format!("[{}]({rep}#{})", cell(&r.test), anchor(r)),
            None => cell(&r.test),
        };
        let why = if r.status == Status::Pass && r.warnings.is_empty() && r.note.is_empty() {
            String::new()
        } else {
            cell(&reason(r))
        };
        s += &format!(
            "| {} | {test} | {} | {} | {} | {} | {} | {} | {why} |\n",
            icon(r.status),
            cell(&r.reference),
            cell(&r.config),
            r.status.label(),
            c.map_or("-".into(), |c| format!("{:.3e}", c.max_error)),
            c.map_or("-".into(), |c| format!(
                "{} ({:.3} %)",
                c.n_fail,
                100.0 * c.n_fail as f64 / c.pixels.max(1) as f64
            )),
            r.mask.map_or("-".into(), |m| format!(
                "{} out, {} scaled",
                m.excluded, m.scaled
            )),
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn annotation_text_cannot_end_a_command_early() {
        assert_eq!(data("50% off\r\nnext"), "50%25 off%0D%0Anext");
        assert_eq!(property("a:b,c%"), "a%3Ab%2Cc%25");
        assert_eq!(cell("a | b\n c & <d>"), "a \\| b c &amp; &lt;d>");
        assert!(check_url("https://ci.example/1/index.html").is_ok());
        for bad in [
            "",
            "http://x/#f",
            "http://x/a b",
            "http://x/\n::error::X",
            "a)b",
            "a|b",
        ] {
            assert!(check_url(bad).is_err(), "{bad:?}");
        }
    }
}
