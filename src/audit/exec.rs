//! Auditing a routine in any language through a subprocess (`rayproof audit --exec CMD`).
//!
//! **One child for the run.** rayproof starts `sh -c CMD` once (in its own process group, with
//! `PYTHONUNBUFFERED=1` in its environment), writes the cases to its standard input a batch at a
//! time, and reads one answer line per case from its standard output; at the end it closes the
//! child's input and waits for it to exit. A plain `for line in sys.stdin: print(…)` works in
//! Python; a child in another language must flush its output after each answer line (C:
//! `setvbuf(stdout, NULL, _IOLBF, 0)` or `fflush(stdout)`; awk: `fflush()`; sed: `-u`). A child
//! that cannot flush can be run once per batch instead (`--exec-per-batch`: its input is closed at
//! the end of each batch, so it sees the end of its input and flushes on exit).
//!
//! **A case line** (child's input): the precision, then the shape's inputs in order as C99 hex
//! floats (`inf`, `-inf`, `nan` for the invalid class), exact in the precision:
//! `f32 0x1p+0 -0x1.8p-3 0x0p+0 …`. (A `rayproof cases` file has two more fields, the class and
//! the index, and a `#` header: `rayproof cases --exec-format` writes the exec lines instead.)
//!
//! **An answer line** (child's output), one per case in order: the count, then the values, in
//! decimal or hex (`1 0x1.4p+2`, `2 -1.5 3`, `0`; an f32 answer is rounded once to f32). What an
//! answer may be is the answer contract ([`super::contract`], `rayproof header`): an answer
//! outside it is a wrong answer counted in its row; a line that is not an answer at all (a log
//! line on stdout: redirect the child's logging to stderr) stops the audit.
//!
//! **Invalid input** (the `invalid` class: NaN or infinite inputs, degenerate shapes) arrives
//! like any case, and the right answer is `0`. Directions are not normalised.
//!
//! A child that exits, is killed by a signal, answers a line that is not an answer, answers more
//! lines than cases, or does not answer a batch within the timeout stops the audit with one line
//! naming the command, the offending line (quoted) or the first unanswered case (its replay
//! line), and the last lines of the child's stderr ([`super::run::MethodFailed`], exit 4).
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

use super::contract::parse_line;
use crate::numerics::Precision;
use crate::process::{Broken, Session};
use crate::shapes::shape::{hex_text, probe_line_with, Answer, Method};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The line protocol of an `--exec` child, for `rayproof header --exec` (each shape's fields and
/// contract follow it there).
pub fn protocol(shapes: &[&'static dyn crate::shapes::shape::Shape]) -> String {
    let mut out = String::from(
        "# The --exec line protocol: rayproof audit --exec CMD (one child, `sh -c CMD`, for the run)
#
# Input (the child's stdin), one case per line: the precision, then the shape's inputs in
# order as C99 hex floats, exact in that precision (inf, -inf, nan in the invalid class):
#   f32 0x1p+0 -0x1.8p-3 0x0p+0 ...
# `rayproof cases --exec-format -o FILE` writes the same lines to a file.
#
# Output (the child's stdout), one answer line per case, in order: the count, then that many
# values in decimal or hex (`1 0x1.4p+2`, `2 -1.5 3`, `0`); an f32 value is rounded once to f32.
# Flush after each line (Python does: rayproof sets PYTHONUNBUFFERED=1; C: setvbuf(stdout,
# NULL, _IOLBF, 0); awk: fflush(); sed -u). Logging goes to stderr: a line on stdout that is not
# an answer stops the audit (exit 4) with that line quoted and the child's last stderr lines.
#
# Batches of up to 4096 cases are written to the same child; a child that answers only when its
# input ends is found out by its first batch and run once per batch (or say so: --exec-per-batch;
# --exec-keep holds it to flushing). At the end its input closes and it must exit 0 with nothing
# more to say. A child that dies, hangs past --timeout seconds per batch, or answers too many
# lines stops the audit with one line naming the case (exit 4) and no report is written.
#
# Invalid input (NaN or Inf inputs, a degenerate shape) is answered `0`. Directions are not
# normalised. What an answer may be is the shape's contract below (the same for --plugin,
# score files and the Rust API): an answer outside it is a wrong answer counted in its row.
",
    );
    for s in shapes {
        let info = s.info();
        out += &format!(
            "\n# {}: {}\n#   in:  PRECISION {}\n#   out: COUNT {}\n#   contract: {}\n",
            info.name,
            info.about,
            info.args.join(" "),
            info.values.join(" "),
            super::contract::describe(info)
        );
    }
    out
}

/// `s` as one word of a POSIX shell line: as it is when it holds only safe characters, else in
/// single quotes (a quote in it as `'\\''`); one line always: a newline or another control
/// character makes it a bash `$'…'` word instead.
pub fn shell_word(s: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || "_-.,/:=+@%".contains(c);
    if !s.is_empty() && s.chars().all(safe) {
        return s.to_string();
    }
    if s.chars().any(|c| c.is_control()) {
        let mut w = String::from("$'");
        for c in s.chars() {
            match c {
                '\\' => w.push_str("\\\\"),
                '\'' => w.push_str("\\'"),
                '\n' => w.push_str("\\n"),
                '\t' => w.push_str("\\t"),
                c if c.is_control() => w.push_str(&format!("\\x{:02x}", c as u32)),
                c => w.push(c),
            }
        }
        return w + "'";
    }
    format!("'{}'", s.replace('\'', "'\\''"))
}

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
    /// One child for the run, one per batch, or (by default) decided by the first batch.
    pub mode: Mode,
    /// The running child and whether it is kept for the run (once decided).
    state: Mutex<(Option<Session>, Option<bool>)>,
    /// Some child of this command has answered a line (a later deadline is then not a child
    /// that never flushes).
    answered: std::sync::atomic::AtomicBool,
}

/// How many children an `--exec` run starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// One for the run if it answers all of its first batch within [`FIRST_LINE`], its input
    /// still open (it flushes its lines); otherwise its input is closed at the end of that batch
    /// (a child that writes only at exit, as `sed` or `awk` to a pipe do) and every batch gets
    /// its own.
    Auto,
    /// One child for the run (`--exec-keep`): it must flush each answer line.
    Keep,
    /// One child per batch (`--exec-per-batch`), its input closed at the batch's end.
    PerBatch,
}

/// How long the first batch waits for all its answers, its input still open, before the child
/// is taken for one that writes only at exit ([`Mode::Auto`]; at most half the batch's timeout).
pub const FIRST_LINE: Duration = Duration::from_secs(3);

impl Exec {
    /// A routine run by `command` for `shape`.
    pub fn new(name: &str, command: &str, shape: &str, timeout: Duration, mode: Mode) -> Exec {
        Exec {
            name: name.to_string(),
            command: command.to_string(),
            shape: shape.to_string(),
            timeout,
            mode,
            state: Mutex::new((None, None)),
            answered: Default::default(),
        }
    }

    /// Whether the run keeps one child (`None`: not decided yet).
    pub fn keeps_one_child(&self) -> Option<bool> {
        match self.mode {
            Mode::Keep => Some(true),
            Mode::PerBatch => Some(false),
            Mode::Auto => self.state.lock().unwrap_or_else(|e| e.into_inner()).1,
        }
    }

    /// The command as messages name it: on one line (a newline in it shown as `\n`).
    fn what(&self) -> String {
        format!("exec '{}'", self.command.replace('\n', "\\n"))
    }

    /// The last lines of the child's stderr that explain it, as a suffix.
    fn said(s: &Session) -> String {
        let why = crate::process::explain(&s.stderr());
        if why.is_empty() {
            String::new()
        } else {
            format!("; its stderr: {why}")
        }
    }

    fn replay_line(&self, prec: Precision, x: &[f64]) -> String {
        case_text(&self.shape, self.name(), prec, self.replay().as_deref(), x)
    }

    /// The answers of a child kept for the run: `batch` written (or already written), one answer
    /// line read per case as they come (blank lines skipped).
    fn stream(
        &self,
        child: &mut Session,
        batch: &[u8],
        prec: Precision,
        inputs: &[Vec<f64>],
        deadline: Instant,
    ) -> Result<Vec<Answer>, String> {
        let what = self.what();
        let n = inputs.len();
        let mut answers = Vec::with_capacity(n);
        let mut input = batch;
        while answers.len() < n {
            let need = n - answers.len();
            let got = child.exchange(input, false, Some(&|b: &[u8]| lines_end(b, need)), deadline);
            input = b"";
            let bytes = match got {
                Ok(b) => b,
                Err(e) => {
                    // The whole lines it wrote before it broke off are answers too: the first
                    // unanswered case is the one after them
                    let partial = child
                        .pending()
                        .split(|b| *b == b'\n')
                        .rev()
                        .skip(1)
                        .filter(|l| l.iter().any(|b| !b.is_ascii_whitespace()))
                        .count();
                    let done = (answers.len() + partial).min(n - 1);
                    let at = self.replay_line(prec, &inputs[done]);
                    let how = match e {
                        Broken::Deadline => format!(
                            "did not answer within {} s (killed){}",
                            self.timeout.as_secs_f64(),
                            if done == 0
                                && !self.answered.load(std::sync::atomic::Ordering::Relaxed)
                            {
                                "; no answer line arrived: does the child flush its output after each line? (or give --exec-per-batch)"
                            } else {
                                ""
                            }
                        ),
                        Broken::StdoutCap(cap) => format!("wrote more than {cap} bytes (killed)"),
                        Broken::Closed => match child.wait(Duration::from_millis(200)) {
                            Some(st) if !st.success() => format!("failed ({st})"),
                            _ => "ended".to_string(),
                        },
                    };
                    return Err(format!(
                        "{what} {how} after {done} of {n} answers (the first unanswered: {at}){}",
                        Self::said(child)
                    ));
                }
            };
            for l in String::from_utf8_lossy(&bytes)
                .lines()
                .filter(|l| !l.trim().is_empty())
            {
                let i = answers.len();
                let a = parse_line(l, prec).map_err(|e| {
                    let l: String = l.trim().chars().take(200).collect();
                    format!(
                        "{what}: answer {} is not an answer ('{l}': {e}; the case: {}){}",
                        i + 1,
                        self.replay_line(prec, &inputs[i]),
                        Self::said(child)
                    )
                })?;
                answers.push(a);
                self.answered
                    .store(true, std::sync::atomic::Ordering::Relaxed);
            }
        }
        Ok(answers)
    }

    /// The answers of a child for one batch: `batch` written (or already written) and the input
    /// closed, all its output read to its end; exactly one answer line per case.
    fn whole_batch(
        &self,
        child: &mut Session,
        batch: &[u8],
        prec: Precision,
        inputs: &[Vec<f64>],
        deadline: Instant,
    ) -> Result<Vec<Answer>, String> {
        let what = self.what();
        let out = child.exchange(batch, true, None, deadline);
        let status = child.wait(Duration::from_millis(200));
        let said = Self::said(child);
        let out = match out {
            Ok(b) => b,
            Err(Broken::Deadline) => {
                return Err(format!(
                    "{what} did not finish within {} s (killed){said}",
                    self.timeout.as_secs_f64()
                ))
            }
            Err(_) => {
                return Err(format!(
                    "{what} wrote more than {STDOUT_CAP} bytes (killed)"
                ))
            }
        };
        let text = String::from_utf8_lossy(&out);
        let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
        if !status.is_some_and(|s| s.success()) {
            let st = status.map_or("killed".to_string(), |s| s.to_string());
            let at = inputs
                .get(lines.len())
                .map(|x| {
                    format!(
                        " after {} of {} answers (the first unanswered: {})",
                        lines.len(),
                        inputs.len(),
                        self.replay_line(prec, x)
                    )
                })
                .unwrap_or_default();
            return Err(format!("{what} failed ({st}){at}{said}"));
        }
        if lines.len() > inputs.len() {
            let x: String = lines[inputs.len()].trim().chars().take(200).collect();
            return Err(format!(
                "{what} answered {} lines to {} cases (the first extra: '{x}'){said}",
                lines.len(),
                inputs.len()
            ));
        }
        if lines.len() < inputs.len() {
            return Err(format!(
                "{what} answered {} lines to {} cases (the first unanswered: {}){said}",
                lines.len(),
                inputs.len(),
                self.replay_line(prec, &inputs[lines.len()])
            ));
        }
        lines
            .iter()
            .zip(inputs)
            .enumerate()
            .map(|(i, (l, x))| {
                parse_line(l, prec).map_err(|e| {
                    let l: String = l.trim().chars().take(200).collect();
                    format!(
                        "{what}: answer {} is not an answer ('{l}': {e}; the case: {}){said}",
                        i + 1,
                        self.replay_line(prec, x)
                    )
                })
            })
            .collect()
    }
}

/// One case as the child reads it.
pub fn case_line(prec: Precision, input: &[f64]) -> String {
    let vals: Vec<String> = input.iter().map(|&x| hex_text(x)).collect();
    format!("{} {}\n", prec.name(), vals.join(" "))
}

/// How an error names an outside routine's (`name`'s) case: its `rayproof probe` line, for a
/// box guard its `rayproof guard --replay` line, or for a spawn rule its query (a spawn replay
/// needs the triangle too: `rayproof spawn` prints it).
pub fn case_text(
    shape: &str,
    name: &str,
    prec: Precision,
    replay: Option<&str>,
    x: &[f64],
) -> String {
    match shape {
        "spawn" => format!("the query {}", case_line(prec, x).trim_end()),
        "guard" => crate::shapes::shape::guard_line_with(name, prec, replay, x),
        _ => probe_line_with(shape, prec, replay, x),
    }
}

/// Whether `b` holds `n` non-blank lines (the answers of `n` cases): the byte length they end at.
fn answered(b: &[u8], n: usize) -> Option<usize> {
    let mut seen = 0;
    let mut blank = true;
    for (i, &c) in b.iter().enumerate() {
        if c == b'\n' {
            if !blank {
                seen += 1;
                if seen == n {
                    return Some(i + 1);
                }
            }
            blank = true;
        } else if !c.is_ascii_whitespace() {
            blank = false;
        }
    }
    None
}

/// The byte length of the first `n` lines of `b` (with their newlines), once they are all there.
fn lines_end(b: &[u8], n: usize) -> Option<usize> {
    if n == 0 {
        return Some(0);
    }
    b.iter()
        .enumerate()
        .filter(|(_, &c)| c == b'\n')
        .nth(n - 1)
        .map(|(i, _)| i + 1)
}

impl Method for Exec {
    fn name(&self) -> &str {
        &self.name
    }
    fn about(&self) -> &str {
        &self.command
    }
    fn replay(&self) -> Option<String> {
        Some(format!(
            "--exec {} --name {}",
            shell_word(&self.command),
            shell_word(&self.name)
        ))
    }
    fn identity(&self) -> Option<String> {
        Some(format!("--exec {}", self.command))
    }
    fn answer(&self, prec: Precision, inputs: &[Vec<f64>]) -> Result<Vec<Answer>, String> {
        if inputs.is_empty() {
            return Ok(vec![]);
        }
        let what = self.what();
        let batch: String = inputs.iter().map(|x| case_line(prec, x)).collect();
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let keep = match self.mode {
            Mode::Keep => Some(true),
            Mode::PerBatch => Some(false),
            Mode::Auto => state.1,
        };
        if state.0.is_none() || keep == Some(false) {
            state.0 = Some(Session::sh(
                &what,
                &self.command,
                None,
                &[("PYTHONUNBUFFERED", "1")],
                STDOUT_CAP,
            )?);
        }
        let child = state.0.as_mut().expect("started");
        let deadline = Instant::now() + self.timeout;
        let result = match keep {
            Some(false) => self.whole_batch(child, batch.as_bytes(), prec, inputs, deadline),
            Some(true) => self.stream(child, batch.as_bytes(), prec, inputs, deadline),
            None => {
                // The first batch decides: a child that answers all of it while its input is
                // still open flushes its lines, and is kept for the run
                let n = inputs.len();
                let first = child.exchange(batch.as_bytes(), false, Some(&|_| Some(0)), deadline);
                if let Err(Broken::Deadline) = first {
                    // It never read its batch (killed at the deadline): a timeout, not a crash
                    let said = Self::said(child);
                    state.0 = None;
                    return Err(format!(
                        "{what} did not finish within {} s (killed){said}",
                        self.timeout.as_secs_f64()
                    ));
                }
                let whole = first.ok().and_then(|_| {
                    let window = FIRST_LINE.min(self.timeout / 2);
                    child.wait_for(&|b| answered(b, n).map(|_| 0), Instant::now() + window)
                });
                let keeps = whole.is_some();
                state.1 = Some(keeps);
                let child = state.0.as_mut().expect("started");
                if keeps {
                    self.stream(child, b"", prec, inputs, deadline)
                } else {
                    self.whole_batch(child, b"", prec, inputs, deadline)
                }
            }
        };
        if result.is_err() || state.1 == Some(false) || keep == Some(false) {
            state.0 = None;
        }
        result
    }
    fn finish(&self) -> Result<(), String> {
        // One child for the run: its input closes, it must end with nothing more to say
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let Some(mut child) = state.0.take() else {
            return Ok(());
        };
        let what = self.what();
        let rest = child.exchange(b"", true, None, Instant::now() + self.timeout);
        let status = child.wait(Duration::from_millis(200));
        let said = Self::said(&child);
        match rest {
            Ok(b) => {
                if let Some(x) = String::from_utf8_lossy(&b)
                    .lines()
                    .find(|l| !l.trim().is_empty())
                {
                    let x: String = x.trim().chars().take(200).collect();
                    return Err(format!(
                        "{what} answered more lines than cases (the first extra: '{x}'){said}"
                    ));
                }
            }
            Err(_) => {
                return Err(format!(
                    "{what} did not end within {} s of the end of its input (killed){said}",
                    self.timeout.as_secs_f64()
                ))
            }
        }
        match status {
            Some(s) if s.success() => Ok(()),
            Some(s) => Err(format!("{what} failed at the end of its input ({s}){said}")),
            None => Err(format!("{what} did not end after its input (killed){said}")),
        }
    }
}
