//! The report as text: the terminal table, Markdown and the replayable worst cases. One layout
//! for every shape; the columns a shape does not report (err/cond, residuals, enclosures) are
//! left out.

use super::report::{Report, ShapeReport};
use super::row::{Row, Status};
use std::fmt::Write;

/// Formats a count compactly: integers below 10⁵, else one decimal of scientific notation.
fn num(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x < 1e5 {
        format!("{}", x.round() as u64)
    } else {
        format!("{x:.1e}")
    }
}

/// Formats a ratio: two decimals below 10, else as [`num`].
fn ratio(x: f64) -> String {
    if x < 10.0 {
        format!("{x:.2}")
    } else {
        num(x)
    }
}

/// The verdict of a row in a word.
fn word(r: &Row) -> &'static str {
    match r.verdict.as_ref().map(|v| v.status) {
        None => "",
        Some(Status::Pass) => "ok",
        Some(Status::KnownFailure) => "xfail",
        Some(Status::Undecided) => "?",
        Some(Status::Unchecked) => "-",
        Some(Status::Fail) => "FAIL",
    }
}

fn wrong(r: &Row) -> String {
    let mut s = format!(
        "{}/{}/{}/{}",
        r.false_hit, r.false_miss, r.wrong_root, r.nonfinite_t
    );
    // Outside the contract: shown only where it happened, so the usual columns stay narrow
    let range = r.out_of_range + r.ill_posed_out_of_range;
    if range > 0 {
        s += &format!(" +{range} t≤0");
    }
    if r.ill_posed_nonfinite > 0 {
        s += &format!(" +{} nf ill-posed", r.ill_posed_nonfinite);
    }
    if r.malformed > 0 {
        s += &format!(" +{} malformed", r.malformed);
    }
    s
}

fn invalid(r: &Row) -> String {
    if r.invalid.cases == 0 {
        "-".into()
    } else {
        format!(
            "{}/{}/{}",
            r.invalid.rejected, r.invalid.nonfinite_t, r.invalid.hit
        )
    }
}

/// The lines that explain the columns, once per audit.
pub fn legend(report_seed: u64, shard: &str) -> String {
    format!(
        "rayproof audit — seed {report_seed} (shard {shard})\n\
         well = well-posed cases; ill = ill-posed (a 1-ulp input change flips the exact verdict), reported apart\n\
         wrong = false hit / false miss / wrong root / non-finite value on well-posed cases (+N t≤0: hits outside t > 0; +N malformed: answers outside the contract, see `rayproof header`); rate = wrong / well\n\
         ulps = error against the correctly rounded value (norm_ulps: in ulps of the largest component); bits = log2(1+ulps)\n\
         err/cond = max of ulps / (ulps the value moves when every input moves 1 ulp): ≈1 is as good as the inputs allow\n\
         resid = hit point's distance from the surface in ulps of its size; invalid = invalid inputs rejected / NaN / hit\n\
         verdict: ok within tolerance, xfail a known failure shown, ? too few cases to tell, - not checked, FAIL\n"
    )
}

/// The summary's legend: one line.
pub fn short_legend(report_seed: u64, shard: &str) -> String {
    format!(
        "rayproof audit — seed {report_seed} (shard {shard}); one line per routine family × precision \
         (wrong = wrong verdicts on well-posed cases; --verbose or --markdown: the full tables)\n"
    )
}

/// One shape's terminal table: a block per precision × class.
pub fn shape_table(s: &ShapeReport) -> String {
    let cond = s.rows.iter().any(|r| r.err_over_cond.is_some());
    let resid = s.rows.iter().any(|r| r.residual_ulps.is_some());
    // The method column fits the longest name (an outside method's may be long)
    let w = s
        .rows
        .iter()
        .map(|r| r.method.chars().count())
        .fold(16, usize::max);
    let mut out = format!(
        "\n{} — {}  (errors in {}; {} cases per class)\n",
        s.shape, s.about, s.metric, s.cases_per_class
    );
    let mut key = None;
    for r in &s.rows {
        let enclosures = s
            .rows
            .iter()
            .any(|x| x.precision == r.precision && x.class == r.class && x.enclosure.is_some());
        // A block header per precision × class
        if key != Some((r.precision, &r.class)) {
            key = Some((r.precision, &r.class));
            let mut h = format!(
                "{} · {}\n  {:<w$} {:>6} {:>5} {:>17} {:>9} {:>8} {:>7} {:>6}",
                r.precision.name(),
                r.class,
                "method",
                "well",
                "ill",
                "wrong fh/fm/wr/nf",
                "rate",
                "max ulp",
                "p99",
                "bits99"
            );
            if cond {
                h += &format!(" {:>8}", "err/cond");
            }
            if resid {
                h += &format!(" {:>9}", "resid max");
            }
            h += &format!(" {:>12} {:>7}", "invalid", "verdict");
            if enclosures {
                h += "  enclosure";
            }
            out += &h;
            out += "\n";
        }
        // The row
        let mut line = format!(
            "  {:<w$} {:>6} {:>5} {:>17} {:>8.4}% {:>8} {:>7} {:>6.1}",
            r.method,
            r.well_posed,
            r.ill_posed,
            wrong(r),
            r.wrong_rate * 100.0,
            num(r.ulps.max),
            num(r.ulps.p99),
            r.bits.p99
        );
        if cond {
            line += &format!(
                " {:>8}",
                r.err_over_cond
                    .as_ref()
                    .map_or("-".into(), |s| ratio(s.max))
            );
        }
        if resid {
            line += &format!(
                " {:>9}",
                r.residual_ulps.as_ref().map_or("-".into(), |s| num(s.max))
            );
        }
        line += &format!(" {:>12} {:>7}", invalid(r), word(r));
        if let Some(e) = &r.enclosure {
            line += &format!(
                "  {} viol, width med {}",
                e.violations,
                num(e.width_ulps.median)
            );
        }
        out += line.trim_end();
        out += "\n";
    }
    out
}

/// The first line of an audit's Markdown: `--markdown` replaces only a file that starts so.
pub const MARKDOWN_HEADING: &str = "# rayproof audit";

/// The whole report as Markdown: a table per shape, then the reintersection tests.
pub fn markdown(report: &Report) -> String {
    let mut out = format!(
        "{MARKDOWN_HEADING}\n\nSeed {}, shard {}.\n",
        report.seed, report.shard
    );
    for s in &report.shapes {
        let cond = s.rows.iter().any(|r| r.err_over_cond.is_some());
        let resid = s.rows.iter().any(|r| r.residual_ulps.is_some());
        let _ = write!(
            out,
            "\n### {} — {}\n\nErrors in {}; {} cases per class.\n\n\
             | precision | class | method | well-posed | ill-posed | false hit | false miss | wrong root | non-finite | wrong % | max ulps | p99 ulps | median ulps | p99 bits |{}{} invalid rejected/NaN/hit | verdict |\n\
             |---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|{}{}---|---|\n",
            s.shape,
            s.about,
            s.metric,
            s.cases_per_class,
            if cond { " max err/cond |" } else { "" },
            if resid { " max residual |" } else { "" },
            if cond { "---:|" } else { "" },
            if resid { "---:|" } else { "" },
        );
        for r in &s.rows {
            let mut line = format!(
                "| {} | {} | {}{} | {} | {} | {} | {} | {} | {} | {:.4} | {} | {} | {} | {:.1} |",
                r.precision.name(),
                r.class,
                r.method,
                if r.robust { " (robust)" } else { "" },
                r.well_posed,
                r.ill_posed,
                r.false_hit,
                r.false_miss,
                r.wrong_root,
                r.nonfinite_t,
                r.wrong_rate * 100.0,
                num(r.ulps.max),
                num(r.ulps.p99),
                num(r.ulps.median),
                r.bits.p99,
            );
            if cond {
                let c = r
                    .err_over_cond
                    .as_ref()
                    .map_or("-".into(), |s| ratio(s.max));
                line += &format!(" {c} |");
            }
            if resid {
                let x = r.residual_ulps.as_ref().map_or("-".into(), |s| num(s.max));
                line += &format!(" {x} |");
            }
            let _ = writeln!(out, "{line} {} | {} |", invalid(r), word(r));
        }
    }
    if let Some(r) = &report.robustness {
        out += "\n";
        out += &crate::audit::robustness::table(r, true);
    }
    out
}

/// The worst cases of every row (up to `per_row`), each with the line that replays it.
pub fn worst_cases(s: &ShapeReport, per_row: usize) -> String {
    let mut out = String::new();
    for r in &s.rows {
        for e in r
            .examples
            .iter()
            .filter(|e| e.kind != "worst_residual")
            .take(per_row)
        {
            let _ = writeln!(
                out,
                "{} {} {} {} {} (case {}): method [{}] oracle [{}]{}\n  {}",
                s.shape,
                r.method,
                r.precision.name(),
                r.class,
                e.kind,
                e.index,
                e.method_values.join(" "),
                e.oracle_values.join(" "),
                e.ulps.map(|u| format!(", {u} ulps")).unwrap_or_default(),
                e.probe
            );
        }
    }
    out
}

/// The one-screen summary of a shape: one line per precision with its cases, the method with
/// the most wrong verdicts (its rate over well-posed cases and its worst class) and the rows'
/// verdict (`FAIL` when a row is out of tolerance; unjudged for a shard).
pub fn summary(s: &ShapeReport) -> String {
    let mut out = String::new();
    let mut precisions: Vec<_> = s.rows.iter().map(|r| r.precision).collect();
    precisions.dedup();
    for p in precisions {
        let rows: Vec<&Row> = s.rows.iter().filter(|r| r.precision == p).collect();
        let Some(first) = rows.first() else { continue };
        let cases: u64 = rows
            .iter()
            .filter(|r| r.method == first.method)
            .map(|r| r.cases)
            .sum();
        let methods = rows.iter().filter(|r| r.class == first.class).count();
        // The method with the highest overall wrong-verdict rate, and its worst class
        let mut worst: Option<(f64, &str, &str)> = None;
        for m in rows
            .iter()
            .filter(|r| r.class == first.class)
            .map(|r| r.method.as_str())
        {
            let mine: Vec<&&Row> = rows.iter().filter(|r| r.method == m).collect();
            let wrong: u64 = mine.iter().map(|r| r.wrong()).sum();
            let posed: u64 = mine.iter().map(|r| r.well_posed).sum();
            let rate = wrong as f64 / posed.max(1) as f64;
            let class = mine
                .iter()
                .max_by(|a, b| a.wrong_rate.total_cmp(&b.wrong_rate))
                .map_or("", |r| r.class.as_str());
            if worst.is_none_or(|w| rate > w.0) {
                worst = Some((rate, m, class));
            }
        }
        let count = |st: Status| {
            rows.iter()
                .filter(|r| r.verdict.as_ref().is_some_and(|v| v.status == st))
                .count()
        };
        let verdict = if rows.iter().all(|r| r.verdict.is_none()) {
            "unjudged (shard)".to_string()
        } else if count(Status::Fail) > 0 {
            format!("FAIL ({} rows out of tolerance)", count(Status::Fail))
        } else if count(Status::Undecided) > 0 {
            format!(
                "pass ({} rows within their rule, {} known failures, {} too few cases to tell)",
                count(Status::Pass),
                count(Status::KnownFailure),
                count(Status::Undecided)
            )
        } else {
            format!(
                "pass ({} rows within their rule, {} known failures)",
                count(Status::Pass),
                count(Status::KnownFailure)
            )
        };
        let worst = match worst {
            Some((rate, m, class)) if rate > 0.0 => {
                format!("worst {m} {:.3} % wrong (most on {class})", 100.0 * rate)
            }
            _ => "no wrong verdict".to_string(),
        };
        let _ = writeln!(
            out,
            "{:<16} {} {:>9} cases × {} methods  {worst:<52} {verdict}",
            s.shape,
            p.name(),
            cases,
            methods,
        );
    }
    out
}
