//! The JUnit XML report of `rayproof check` (what CI systems read), with `quick-junit`: one
//! test case per comparison, named `TEST vs REFERENCE [CONFIG]`, in one suite.

use super::rows::{Row, Status};
use quick_junit::{NonSuccessKind, Report, TestCase, TestCaseStatus, TestSuite};

/// The rows as JUnit XML: failures (FAILURE, XPASS, NEW) as `<failure>`, refusals as
/// `<error>`, skipped optional references as `<skipped>`, the rest as passes; notes and
/// warnings go to each case's system-out.
pub fn junit(rows: &[Row], suite_name: &str) -> String {
    let mut suite = TestSuite::new(suite_name);
    for r in rows {
        // The status
        let mut status = match r.status {
            Status::Failure | Status::UnexpectedPass | Status::New => {
                TestCaseStatus::non_success(NonSuccessKind::Failure)
            }
            Status::Refused => TestCaseStatus::non_success(NonSuccessKind::Error),
            Status::Skipped => TestCaseStatus::skipped(),
            Status::Pass | Status::Warning | Status::KnownFailure | Status::Updated => {
                TestCaseStatus::success()
            }
        };
        if !matches!(status, TestCaseStatus::Success { .. }) {
            status.set_message(format!("{}: {}", r.status.label(), r.note));
            status.set_type(r.status.label());
        }
        // The case, its metrics and warnings as output
        let mut case = TestCase::new(
            format!("{} vs {} [{}]", r.test, r.reference, r.config),
            status,
        );
        case.set_classname(r.test.clone());
        case.set_time(std::time::Duration::from_secs_f64(
            r.render_seconds.max(0.0),
        ));
        let mut out = format!("{} {}", r.status.label(), r.note);
        if let Some(c) = &r.comparison {
            out += &format!(
                "\nmean {:.3e} RMS {:.3e} max {:.3e} at ({}, {}, {}); {} px over fail, {} over warn; HDR-FLIP {}",
                c.mean_error,
                c.rms_error,
                c.max_error,
                c.max_at.0,
                c.max_at.1,
                c.max_channel,
                c.n_fail,
                c.n_warn,
                c.flip_mean.map(|v| format!("{v:.4}")).unwrap_or("-".into())
            );
        }
        for w in &r.warnings {
            out += &format!("\nwarning: {w}");
        }
        if let Some(l) = &r.log {
            out += &format!("\nrenderer log: {l} (in the report directory)");
        }
        case.set_system_out(out);
        suite.add_test_case(case);
    }
    let mut report = Report::new(suite_name);
    report.add_test_suite(suite);
    report
        .to_string()
        .unwrap_or_else(|e| format!("<!-- cannot serialise: {e} -->\n"))
}
