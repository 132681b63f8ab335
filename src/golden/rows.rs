//! The results of `rayproof check`: one [`Row`] per test × reference × configuration, its
//! [`Status`], and the text and Markdown tables of the rows.

use super::references::Rule;
use crate::images::{Comparison, ZTest};
use serde::Serialize;

/// The judgement of one scene × reference × configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Every check passes: idiff's verdict (or the z-test's) is PASS and the mean error and
    /// mean ꟻLIP are within `max_mean` and `max_flip`.
    Pass,
    /// idiff's verdict is WARNING and no check fails (never with a z-test, which has no warning).
    Warning,
    /// A check fails (idiff's or the z-test's verdict, `max_mean`, `max_flip`), the images
    /// differ in size or channels, or `--update` would not bless a test image with NaN or Inf.
    Failure,
    /// Listed as a known failure and still failing.
    KnownFailure,
    /// Listed as a known failure but passing: the entry must go.
    UnexpectedPass,
    /// The reference could not be used: missing, unreadable, hash mismatch, stale, wrong size.
    Refused,
    /// No golden yet; `--update` writes it.
    New,
    /// An optional reference that is not there.
    Skipped,
    /// A failing or missing golden that `--update` wrote.
    Updated,
}

impl Status {
    /// Whether the row fails the run: a failure, an unexpected pass, a refusal or a missing golden.
    pub fn is_failure(self) -> bool {
        matches!(
            self,
            Status::Failure | Status::UnexpectedPass | Status::Refused | Status::New
        )
    }
    /// The word printed in tables and JUnit: `PASS`, `FAILURE`, `XFAIL`, ….
    pub fn label(self) -> &'static str {
        match self {
            Status::Pass => "PASS",
            Status::Warning => "WARNING",
            Status::Failure => "FAILURE",
            Status::KnownFailure => "XFAIL",
            Status::UnexpectedPass => "XPASS",
            Status::Refused => "REFUSED",
            Status::New => "NEW",
            Status::Skipped => "SKIPPED",
            Status::Updated => "UPDATED",
        }
    }
}

/// One row of the check: a test × reference × configuration.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Test name.
    pub test: String,
    /// Reference name (`golden` for rayproof's own earlier render).
    pub reference: String,
    /// Who made the reference (its manifest's renderer and version).
    pub renderer: String,
    /// How the test image was made: rayproof's method and precision, `command` or `image`.
    pub config: String,
    /// The judgement.
    pub status: Status,
    /// Why (refusals, known failures, the key that failed).
    pub note: String,
    /// What the user should know even when it passes: linear against sRGB-encoded images,
    /// mismatched sampling grids, NaN/Inf pixels.
    pub warnings: Vec<String>,
    /// The metrics (`None` when the comparison could not run).
    pub comparison: Option<Comparison>,
    /// The z-test's result, when the test gives a variance image.
    pub ztest: Option<ZTest>,
    /// The thresholds applied.
    pub rule: Rule,
    /// Seconds spent making the test image (the test's render: the same on each of its rows,
    /// also when the render failed or was killed at its timeout).
    pub render_seconds: f64,
    /// This row's share of the run's time, what JUnit reports as the case's time: its own
    /// comparison (metrics, ꟻLIP, z-test, report images), and for the first row of each test
    /// that is not a skipped optional reference also everything the test did once (reading and
    /// hashing references, the render). So a
    /// test's render is counted once, the rows of a test add up to its wall time, and the rows
    /// of a run add up to the time spent in its tests.
    pub seconds: f64,
    /// The command that runs this comparison again (`rayproof check --suite … --test …`, the
    /// suite's path as it was given: run it where `check` ran).
    pub replay: String,
    /// The lines of the renderer's standard error that explain how it ended ([`log_tail`]: up to
    /// [`LOG_TAIL_LINES`]), when a renderer command made the test image; also when it failed or
    /// was killed. `None` when none explains anything.
    pub log_tail: Option<String>,
    /// Report images, relative to the report directory.
    #[serde(skip)]
    pub images: Option<ReportImages>,
    /// The golden was made from another version of the test's scene or inputs (which ones):
    /// it is compared as usual, and `--update` re-blesses it.
    pub stale: Option<String>,
    /// The test's whole renderer log (the command, how it ended, its standard error and
    /// output), relative to the report directory: `logs/TEST.log` (with `--report` only).
    pub log: Option<String>,
    /// The platform the run was for (`--platform`), when the suite declares platforms.
    pub platform: Option<String>,
    /// The pixels the test's mask left out of this comparison or judged with scaled
    /// tolerances, when it has a mask.
    pub mask: Option<crate::images::MaskCounts>,
}

/// How many lines of a renderer's standard error a row keeps ([`Row::log_tail`]).
pub const LOG_TAIL_LINES: usize = 20;

/// The lines of a renderer's standard error a row keeps: those that explain how it ended
/// ([`crate::process::explaining_lines`]: lines that say error, fatal, cannot, failed, …, or
/// warning, and for a render that failed its last 5 lines), at most [`LOG_TAIL_LINES`], the last kept; `None`
/// when none explains anything (a render that worked and printed only its banner and
/// statistics, as POV-Ray does: its credits are not a reason).
pub fn log_tail(stderr: &str, failed: bool) -> Option<String> {
    let last = if failed { 5 } else { 0 };
    let lines = crate::process::explaining_lines_with(stderr, usize::MAX, last, &["warning"]);
    let tail = &lines[lines.len().saturating_sub(LOG_TAIL_LINES)..];
    (!tail.is_empty()).then(|| tail.join("\n"))
}

/// The report images of one comparison (file names relative to the report directory) and what
/// the page prints beside them.
#[derive(Clone, Debug)]
pub struct ReportImages {
    /// The test image, tone-mapped.
    pub new: String,
    /// The reference, tone-mapped.
    pub reference: String,
    /// The failing pixels (those the comparison counts as over `fail`) in red over the test
    /// image dimmed to grey.
    pub mask: String,
    /// The per-pixel largest channel |test − reference|, divided by its maximum `diff_scale`.
    pub diff: String,
    /// The ꟻLIP heat map.
    pub flip: String,
    /// The difference that shows as the top of the |difference| map's colour scale: the
    /// largest finite |test − reference| (0 when the images are equal).
    pub diff_scale: f64,
    /// Failing pixels in the mask: the comparison's count of pixels over `fail`, or the
    /// z-test's failing pixels when it decides.
    pub mask_pixels: u64,
    /// The test's mask drawn over the test image (left-out pixels striped magenta, scaled ones
    /// tinted blue), when the test has one.
    pub masked: Option<String>,
}

/// The run's counts as the terminal's last line and the HTML header print them:
/// `2 failing, 1 refused` (failing: FAILURE, XPASS and NEW rows; refused: REFUSED rows).
pub fn counts(rows: &[Row]) -> String {
    let refused = rows.iter().filter(|r| r.status == Status::Refused).count();
    let failing = rows.iter().filter(|r| r.status.is_failure()).count() - refused;
    format!("{failing} failing, {refused} refused")
}

/// The text table: one line per row.
pub fn table(rows: &[Row]) -> String {
    let w = rows.iter().map(|r| r.test.len()).max().unwrap_or(0).max(8);
    let mut s = format!(
        "{:<w$} {:<9} {:<12} {:<8} {:>10} {:>10} {:>8} {:>9} {:>9} {:>8}  {}\n",
        "test",
        "reference",
        "config",
        "status",
        "mean",
        "RMS",
        "PSNR",
        "max",
        ">fail %",
        "FLIP",
        "note"
    );
    for r in rows {
        let c = r.comparison.as_ref();
        let f = |x: Option<f64>, p: usize| x.map(|v| format!("{v:.p$e}")).unwrap_or("-".into());
        s += &format!(
            "{:<w$} {:<9} {:<12} {:<8} {:>10} {:>10} {:>8} {:>9} {:>9} {:>8}  {}\n",
            r.test,
            r.reference,
            r.config,
            r.status.label(),
            f(c.map(|c| c.mean_error), 2),
            f(c.map(|c| c.rms_error), 2),
            c.map(|c| format!("{:.1}", c.psnr)).unwrap_or("-".into()),
            f(c.map(|c| c.max_error), 2),
            c.map(|c| format!("{:.3}", 100.0 * c.n_fail as f64 / c.pixels as f64))
                .unwrap_or("-".into()),
            c.and_then(|c| c.flip_mean)
                .map(|v| format!("{v:.4}"))
                .unwrap_or("-".into()),
            // One row, one line: a note or warning of several lines (a suite's skip reason, a
            // path) cannot start a line of its own
            crate::images::one_line(&r.note)
        );
        for warning in &r.warnings {
            s += &format!(
                "{:<w$}   warning: {}\n",
                "",
                crate::images::one_line(warning)
            );
        }
    }
    s
}

/// A Markdown table (for the module docs of `golden`), from the same rows.
pub fn markdown(rows: &[Row]) -> String {
    let mut rows: Vec<&Row> = rows.iter().collect();
    rows.sort_by(|a, b| {
        (&a.test, &a.reference, &a.config).cmp(&(&b.test, &b.reference, &b.config))
    });
    let mut s = String::from(
        "| test | reference | method / precision | status | MAE | RMS | PSNR dB | max error | pixels > fail | HDR-FLIP |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let Some(c) = &r.comparison else {
            s += &format!(
                "| {} | {} | {} | {} | | | | | | |\n",
                r.test,
                r.reference,
                r.config,
                r.status.label()
            );
            continue;
        };
        s += &format!(
            "| {} | {} | {} | {} | {:.2e} | {:.2e} | {:.1} | {:.3} | {:.3} % | {} |\n",
            r.test,
            r.reference,
            r.config,
            r.status.label(),
            c.mean_error,
            c.rms_error,
            c.psnr,
            c.max_error,
            100.0 * c.n_fail as f64 / c.pixels as f64,
            c.flip_mean.map(|v| format!("{v:.4}")).unwrap_or("-".into())
        );
    }
    s
}
