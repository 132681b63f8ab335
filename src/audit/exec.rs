//! Auditing a routine in any language through a subprocess (`rayproof audit --exec CMD`).
//!
//! For every batch of cases rayproof starts `sh -c CMD`, writes the batch to its standard
//! input and closes it, and reads one answer line per case from its standard output until it
//! exits. Because the child sees the end of its input, it needs no flushing protocol: a plain
//! `for line in sys.stdin: print(…)` works.
//!
//! **A case line** (child's input): the precision, then the shape's inputs in order as C99 hex
//! floats (`inf`, `-inf`, `nan` for the invalid class), exact in the precision:
//! `f32 0x1p+0 -0x1.8p-3 0x0p+0 …`.
//!
//! **An answer line** (child's output), one per case in order: the count, then the values, in
//! decimal or hex (`1 0x1.4p+2`, `2 -1.5 3`, `0`; an f32 answer is rounded once to f32).
//!
//! A child that exits with a failure, is killed by a signal, answers a malformed line or the
//! wrong number of lines, or does not finish a batch within the timeout stops the audit with
//! one line naming the command and the case ([`super::run::MethodFailed`], exit 4).
//!
//! # Example
//!
//! `tests/outside/sphere_textbook.py` is the textbook ray–sphere in Python, which `tests/exec.rs`
//! checks is judged row for row exactly as the built-in `algebraic`:
//!
//! ```sh
//! rayproof audit --shape sphere --precision f64 --exec 'python3 tests/outside/sphere_textbook.py' --name py
//! ```
//!
//! Its worst cases print replay lines that bring the child along
//! (`rayproof probe sphere --precision f64 --exec '…' --name py -- …`). `--method` adds built-in
//! methods to the same rows, `--tolerances` judges yours. The timeout is `--timeout` seconds
//! per batch (default 60); the child's whole process group is then killed, and a failing child
//! leaves no report written.
//!
//! Measured by `scripts/bench-outside` (2026-11-23 16:03 UTC, 2-core AMD EPYC; median of 5 runs)
//! with a trivial child (`--exec "awk '{print 0}'"`, 240,000 `rcp` cases, whose oracle is cheap):
//! 388,000 cases/s end to end; the sphere's audit through the same child is bound by its oracle,
//! 99,000 cases/s.

use super::contract::parse_line;
use super::shape::{hex_text, probe_line_with, Answer, Method};
use crate::numerics::Precision;
use std::time::Duration;

/// Standard output an `--exec` child may write per batch: 16 MiB.
pub const STDOUT_CAP: usize = 16 << 20;

/// A routine run by a command.
pub struct Exec {
    /// The method's name in rows and replay lines.
    pub name: String,
    /// The command, run under `sh -c`: case lines on its stdin, one answer line per case on its stdout.
    pub command: String,
    /// The shape's name, for replay lines in errors.
    pub shape: String,
    /// How long one batch may take.
    pub timeout: Duration,
}

/// One case as the child reads it.
pub fn case_line(prec: Precision, input: &[f64]) -> String {
    let vals: Vec<String> = input.iter().map(|&x| hex_text(x)).collect();
    format!("{} {}\n", prec.name(), vals.join(" "))
}

impl Exec {
    /// Runs the child on one batch: its standard output, or why it failed. The output is capped
    /// at [`STDOUT_CAP`] (a batch's answers are a few hundred kilobytes).
    fn run_batch(&self, input: String) -> Result<String, String> {
        let what = format!("exec '{}'", self.command);
        crate::process::run_capped(&what, &self.command, None, input, self.timeout, STDOUT_CAP)
    }
}

impl Method for Exec {
    fn name(&self) -> &str {
        &self.name
    }
    fn about(&self) -> &str {
        &self.command
    }
    fn replay(&self) -> Option<String> {
        Some(format!("--exec '{}' --name {}", self.command, self.name))
    }
    fn answer(&self, prec: Precision, inputs: &[Vec<f64>]) -> Result<Vec<Answer>, String> {
        if inputs.is_empty() {
            return Ok(vec![]);
        }
        let batch: String = inputs.iter().map(|x| case_line(prec, x)).collect();
        let out = self.run_batch(batch)?;
        let what = format!("exec '{}'", self.command);
        let lines: Vec<&str> = out.lines().filter(|l| !l.trim().is_empty()).collect();
        if lines.len() != inputs.len() {
            let at = inputs
                .get(lines.len())
                .or(inputs.last())
                .expect("not empty");
            return Err(format!(
                "{what} answered {} lines to {} cases (the first unanswered: {})",
                lines.len(),
                inputs.len(),
                probe_line_with(&self.shape, prec, self.replay().as_deref(), at)
            ));
        }
        lines
            .iter()
            .zip(inputs)
            .enumerate()
            .map(|(i, (l, x))| {
                parse_line(l, prec).map_err(|e| {
                    format!(
                        "{what}: answer {} ('{}'): {e} (case: {})",
                        i + 1,
                        l.trim(),
                        probe_line_with(&self.shape, prec, self.replay().as_deref(), x)
                    )
                })
            })
            .collect()
    }
}
