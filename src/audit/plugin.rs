//! Auditing a routine in a shared library through its C ABI (`rayproof audit --plugin
//! PATH:SYMBOL`), in batches: arrays in, arrays out, so the call costs nothing per case.
//!
//! One signature serves every shape; `rayproof header` prints the C header that names it per
//! shape and precision. For a shape with `IN` inputs and at most `OUT` output values:
//!
//! ```c
//! int f(size_t n, const float in[][IN], uint32_t count[], float out[][OUT]);   /* f32 */
//! int f(size_t n, const double in[][IN], uint32_t count[], double out[][OUT]); /* f64 */
//! ```
//!
//! The routine answers the `n` cases: `count[i]` is 0 for a miss (no real root, total internal
//! reflection) and otherwise the number of values it wrote to `out[i]` (1 for a hit's `t`, the
//! number of distinct real roots, 3 for a vector); it returns 0, or anything else to report a
//! failure. rayproof fills `count` with a sentinel before the call, so a count left unwritten (a
//! wrong signature) is an error, not an answer. What the routine wrote is judged by the answer
//! contract ([`super::contract`]) as an `--exec` answer line would be: a count the shape cannot
//! have (2 for the sphere, 3 for the quadratic) is a malformed answer, counted in its row.
//!
//! **The routine runs in a worker process** (`rayproof __plugin-worker`, one per symbol, started
//! once and kept for the run): a crash (a segmentation fault, an abort, a stack overflow), a call
//! to `exit()` or a hang takes the worker down, never rayproof. Each batch has a deadline
//! (`--timeout`, seconds per batch, default 60); a worker that dies or misses it is killed with
//! its process group, the batch is split in halves on fresh workers until the one case that
//! kills the routine is found (when it is the case that does, and time allows), and the audit
//! stops with one line naming the library, symbol, batch and case (exit 4, no report). The
//! worker also times the routine's own calls, which `rayproof report` uses.
//!
//! # Use
//!
//! `--plugin PATH:SYMBOL` loads the symbol (with `libloading`) and calls it once per batch of
//! 4,096 cases. `rayproof header` prints the C header: one signature per shape and precision, e.g.
//!
//! ```c
//! typedef int rayproof_sphere_f32(size_t n, const float in[][10], uint32_t count[], float out[][1]);
//! ```
//!
//! `in[i]` holds case i's inputs in the shape's order. The precision comes from a `_f32`/`_f64`
//! suffix of the symbol or an explicit `:f32`/`:f64`; give `--plugin` twice for both.
//! `tests/outside/routines.c` holds the examples `tests/plugin.rs` builds with the system C
//! compiler and audits:
//!
//! ```sh
//! cc -O2 -shared -fPIC tests/outside/routines.c -o libroutines.so -lm
//! rayproof audit --shape sphere --plugin ./libroutines.so:sphere_textbook_f32 --method algebraic
//! rayproof audit --shape triangle --plugin ./libroutines.so:triangle_mt_f32
//! ```
//!
//! The textbook f32 sphere is judged row for row exactly as the built-in `algebraic` (34.8 % wrong
//! verdicts on `far_small` at 2,000 cases); the careful one (the perpendicular discriminant in
//! double, rounded once) passes a strict rule of no wrong verdict and ≤ 1 ulp; the C
//! Möller–Trumbore fails on `vertex` and `tiny`; the quadratic formula of Lengyel's ray-tracing
//! chapter (§1.1) in C, f32 and f64, is judged in every class exactly as the built-in `textbook`.
//!
//! Measured side by side by `scripts/bench-outside` (2026-11-23 16:03 UTC, 2-core AMD EPYC; 7
//! interleaved pairs each, f32 sphere audit at 100,000 cases per class), the audit through the
//! plugin took, in median wall time, 1.00× that of the built-in twin for the careful routine
//! (against `--method promote`, the same perpendicular discriminant and stable pair evaluated
//! wider and rounded once; pairs 0.52–1.06) and 0.99× for the textbook one (against `--method
//! algebraic`; pairs 0.85–1.20): the oracle dominates, and the batch call costs nothing measurable
//! per case.
//!
//! # Failures
//!
//! A library or symbol that cannot be loaded is exit 2; a routine that crashes, calls `exit()`,
//! hangs past `--timeout`, returns non-zero, leaves a count unwritten or writes no value at all (a
//! wrong signature) stops the audit with one line and exit 4, and no report is written.
//! Worst cases replay with `rayproof probe … --plugin PATH:SYMBOL:f32 --name N -- …`, and shards
//! of a plugin audit merge as any other. `rayproof report --plugin …:f32 --plugin …:f64` (or
//! `--exec`) puts your ray–sphere routine beside the built-in methods in its accuracy-vs-cost
//! section, with its own ns per test measured on the same batch (for a plugin, one call per batch;
//! for `--exec`, including the child's start).

use crate::numerics::Precision;
use crate::process::{Broken, Session};
use crate::shapes::shape::{Answer, Method};
use std::ffi::CString;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// A batch routine in f32.
type F32Fn = unsafe extern "C" fn(usize, *const f32, *mut u32, *mut f32) -> i32;
/// A batch routine in f64.
type F64Fn = unsafe extern "C" fn(usize, *const f64, *mut u32, *mut f64) -> i32;

/// The count rayproof writes before the call: a routine must overwrite it.
const UNSET: u32 = u32::MAX;

/// What a worker writes first when its symbol is loaded.
const READY: &[u8] = b"rayproof plugin worker ready\n";

/// `PATH:SYMBOL[:f32|f64]`, the precision taken from a `_f32`/`_f64` suffix of the symbol when
/// not given.
pub fn parse_spec(spec: &str) -> Result<(String, String, Precision), String> {
    let (rest, given) = match spec.rsplit_once(':') {
        Some((r, "f32")) => (r, Some(Precision::F32)),
        Some((r, "f64")) => (r, Some(Precision::F64)),
        _ => (spec, None),
    };
    let (path, symbol) = rest
        .rsplit_once(':')
        .filter(|(p, s)| !p.is_empty() && !s.is_empty())
        .ok_or_else(|| format!("--plugin '{spec}': not PATH:SYMBOL[:f32|f64]"))?;
    let prec = given
        .or_else(|| symbol.ends_with("_f32").then_some(Precision::F32))
        .or_else(|| symbol.ends_with("_f64").then_some(Precision::F64))
        .ok_or_else(|| {
            format!("--plugin '{spec}': say the precision (PATH:SYMBOL:f32 or :f64), or name the symbol …_f32 / …_f64")
        })?;
    Ok((path.to_string(), symbol.to_string(), prec))
}

/// The SHA-256 of a file, read in blocks (a library's size is not held in memory).
fn file_sha256(path: &Path) -> std::io::Result<String> {
    use sha2::{Digest, Sha256};
    let mut f = std::fs::File::open(path)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        match f.read(&mut buf)? {
            0 => break,
            n => h.update(&buf[..n]),
        }
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// A path without a slash would be searched for by the loader: make it explicit.
fn library_path(path: &str) -> String {
    if path.contains('/') {
        path.to_string()
    } else {
        format!("./{path}")
    }
}

// ---- the worker: the routine's own process ----

/// The worker's protocol streams, taken away from the routine: copies of standard input and
/// output (closed on exec), after which standard input is `/dev/null` and standard output is
/// standard error. A routine that prints (a debug dump, `printf`) or reads its standard input
/// would otherwise write into its own answers or eat the next batch: a hostile run made a
/// routine's 4 + 8·n zero bytes pass as answers, the run ending with other rows and no error.
/// What it prints now reaches the parent as the worker's standard error.
fn protocol_streams() -> Result<(std::fs::File, std::fs::File), String> {
    use std::os::fd::FromRawFd;
    let err = |what: &str| format!("plugin worker: {what}: {}", std::io::Error::last_os_error());
    // SAFETY: fcntl, open and dup2 on the process's own descriptors; each new descriptor is
    // owned by one File
    unsafe {
        let input = libc::fcntl(0, libc::F_DUPFD_CLOEXEC, 3);
        if input < 0 {
            return Err(err("copying standard input"));
        }
        let output = libc::fcntl(1, libc::F_DUPFD_CLOEXEC, 3);
        if output < 0 {
            return Err(err("copying standard output"));
        }
        let null = libc::open(c"/dev/null".as_ptr(), libc::O_RDONLY | libc::O_CLOEXEC);
        if null < 0 || libc::dup2(null, 0) < 0 || libc::dup2(2, 1) < 0 {
            return Err(err("setting the routine's standard streams"));
        }
        libc::close(null);
        Ok((
            std::fs::File::from_raw_fd(input),
            std::fs::File::from_raw_fd(output),
        ))
    }
}

/// Serves one symbol: loads it, says `READY`, then answers batches on stdin/stdout until the
/// end of its input (what `rayproof __plugin-worker` runs). A batch is `n` (u64 LE) and `n·inputs`
/// values; the answer is the status (i32 LE), the routine's nanoseconds (u64 LE), `n` counts
/// (u32 LE) and `n·outputs` values, in the precision's width. The error is one line.
pub fn serve(
    path: &str,
    symbol: &str,
    prec: Precision,
    inputs: usize,
    outputs: usize,
) -> Result<(), String> {
    let (mut stdin, mut stdout) = protocol_streams()?;
    // SAFETY: loading runs the library's initialisers; the user asked for this library
    let lib = unsafe { libloading::Library::new(library_path(path)) }
        .map_err(|e| format!("--plugin {path}: cannot load: {e}"))?;
    let cname =
        CString::new(symbol).map_err(|_| format!("--plugin {path}:{symbol}: bad symbol"))?;
    let io = |e: std::io::Error| format!("plugin worker: {e}");
    macro_rules! serve_as {
        ($T:ty, $F:ty) => {{
            // SAFETY: the symbol is used with the documented signature of its precision; a
            // routine with another signature is caught by the count sentinel or crashes this
            // worker, which the parent reports
            let f: $F = unsafe { lib.get::<$F>(cname.as_bytes_with_nul()).map(|f| *f) }
                .map_err(|e| format!("--plugin {path}: no symbol '{symbol}': {e}"))?;
            stdout
                .write_all(READY)
                .and_then(|_| stdout.flush())
                .map_err(io)?;
            const W: usize = std::mem::size_of::<$T>();
            loop {
                let mut n = [0u8; 8];
                if let Err(e) = stdin.read_exact(&mut n) {
                    return if e.kind() == std::io::ErrorKind::UnexpectedEof {
                        Ok(())
                    } else {
                        Err(io(e))
                    };
                }
                let n = u64::from_le_bytes(n) as usize;
                let mut raw = vec![0u8; n * inputs * W];
                stdin.read_exact(&mut raw).map_err(io)?;
                let input: Vec<$T> = raw
                    .chunks_exact(W)
                    .map(|b| <$T>::from_le_bytes(b.try_into().expect("width")))
                    .collect();
                let mut count = vec![UNSET; n];
                let mut out = vec![<$T>::NAN; n * outputs];
                let t0 = Instant::now();
                // SAFETY: the buffers have the documented sizes for n cases
                let status = unsafe { f(n, input.as_ptr(), count.as_mut_ptr(), out.as_mut_ptr()) };
                let nanos = t0.elapsed().as_nanos() as u64;
                let mut answer = Vec::with_capacity(12 + n * 4 + out.len() * W);
                answer.extend(status.to_le_bytes());
                answer.extend(nanos.to_le_bytes());
                count.iter().for_each(|c| answer.extend(c.to_le_bytes()));
                out.iter().for_each(|v| answer.extend(v.to_le_bytes()));
                stdout
                    .write_all(&answer)
                    .and_then(|_| stdout.flush())
                    .map_err(io)?;
            }
        }};
    }
    match prec {
        Precision::F32 => serve_as!(f32, F32Fn),
        Precision::F64 => serve_as!(f64, F64Fn),
    }
}

// ---- the parent's side ----

/// One symbol and its worker.
struct Symbol {
    prec: Precision,
    /// `PATH:SYMBOL`, for messages and replay lines.
    spec: String,
    path: String,
    symbol: String,
    /// The library file's SHA-256 when the run started (its identity in a shard).
    sha256: String,
    /// The running worker (replaced after a failure, for the search of the failing case).
    worker: Mutex<Option<Session>>,
    /// Batches answered so far (the failing batch's number in messages).
    batches: std::sync::atomic::AtomicU64,
    /// Nanoseconds the routine spent in its own calls, over every batch.
    nanos: std::sync::atomic::AtomicU64,
}

/// A routine of a shared library, one symbol per precision, each run in a worker process.
pub struct Plugin {
    name: String,
    symbols: Vec<Symbol>,
    inputs: usize,
    outputs: usize,
    /// The count is the number of values written (the polynomials).
    counted: bool,
    shape: String,
    worker: PathBuf,
    timeout: Duration,
}

/// How a batch went wrong.
enum Failure {
    /// The routine ran and said so, or answered what cannot be an answer: not the case's fault.
    Reported(String),
    /// The worker died (how, and what it said on stderr): the batch is searched for the case
    /// that does it.
    Died(String, String),
    /// The worker did not answer by the deadline (how, what it said): not searched, since each
    /// step of a search could take another `--timeout` (a hang took 3× the deadline).
    Hung(String, String),
}

impl Plugin {
    /// Loads one symbol per spec for a shape, each in its own worker process started from
    /// `worker` (a `rayproof` binary), with a deadline of `timeout` per batch; the method's name
    /// defaults to the first symbol without its precision suffix.
    pub fn load(
        specs: &[String],
        name: Option<&str>,
        shape: &crate::shapes::shape::ShapeInfo,
        worker: &Path,
        timeout: Duration,
    ) -> Result<Plugin, String> {
        let mut p = Plugin {
            name: String::new(),
            symbols: vec![],
            inputs: shape.args.len(),
            outputs: shape.values.len(),
            counted: shape.count_is_values,
            shape: shape.name.to_string(),
            worker: worker.to_path_buf(),
            timeout,
        };
        for spec in specs {
            let (path, symbol, prec) = parse_spec(spec)?;
            if p.symbols.iter().any(|s| s.prec == prec) {
                return Err(format!("--plugin: two {} symbols", prec.name()));
            }
            // A FIFO or a device is no library: opening or reading it may block or never end
            if let Ok(m) = std::fs::metadata(&path) {
                if !m.is_file() {
                    return Err(format!("--plugin '{spec}': {path} is not a regular file"));
                }
            }
            let sha256 = match file_sha256(Path::new(&path)) {
                Ok(h) => h,
                // Found by the loader's search path, not as a file here: named as given
                Err(_) => format!("(not read: {path})"),
            };
            let s = Symbol {
                prec,
                spec: format!("{path}:{symbol}"),
                sha256,
                path,
                symbol,
                worker: Mutex::new(None),
                batches: Default::default(),
                nanos: Default::default(),
            };
            // Load it now: a library or symbol that cannot be loaded is a usage error
            let w = p.start(&s).map_err(|e| match e {
                Failure::Reported(e) | Failure::Died(e, _) | Failure::Hung(e, _) => e,
            })?;
            *s.worker.lock().unwrap_or_else(|e| e.into_inner()) = Some(w);
            if p.name.is_empty() {
                p.name = name.map(str::to_string).unwrap_or_else(|| {
                    s.symbol
                        .trim_end_matches("_f32")
                        .trim_end_matches("_f64")
                        .to_string()
                });
            }
            p.symbols.push(s);
        }
        if p.symbols.is_empty() {
            return Err("--plugin: no symbol given".into());
        }
        Ok(p)
    }

    /// The precisions it has a symbol for.
    pub fn precisions(&self) -> Vec<Precision> {
        self.symbols.iter().map(|s| s.prec).collect()
    }

    /// Nanoseconds the routine of a precision spent in its own calls so far.
    pub fn routine_nanos(&self, prec: Precision) -> u64 {
        self.symbols
            .iter()
            .find(|s| s.prec == prec)
            .map_or(0, |s| s.nanos.load(std::sync::atomic::Ordering::Relaxed))
    }

    /// A fresh worker for a symbol, past its handshake.
    fn start(&self, s: &Symbol) -> Result<Session, Failure> {
        let what = format!("plugin {}", s.spec);
        let ins = self.inputs.to_string();
        let outs = self.outputs.to_string();
        let mut w = Session::spawn(
            &what,
            &self.worker,
            &[
                "__plugin-worker",
                &s.path,
                &s.symbol,
                s.prec.name(),
                &ins,
                &outs,
            ],
            None,
            &[],
            1 << 30,
        )
        .map_err(Failure::Reported)?;
        let ready = |b: &[u8]| (b.len() >= READY.len()).then_some(READY.len());
        match w.exchange(&[], false, Some(&ready), Instant::now() + self.timeout) {
            Ok(b) if b == READY => Ok(w),
            _ => {
                w.wait(Duration::from_millis(200));
                let why = crate::process::explain(&w.stderr());
                let why = why.strip_prefix("error: ").unwrap_or(&why).to_string();
                Err(Failure::Reported(if why.is_empty() {
                    format!("{what}: the worker did not start")
                } else {
                    why
                }))
            }
        }
    }

    /// One batch through a symbol's worker: the status, the routine's nanoseconds, the counts
    /// and the values (as f64).
    fn call(
        &self,
        s: &Symbol,
        inputs: &[Vec<f64>],
    ) -> Result<(i32, u64, Vec<u32>, Vec<f64>), Failure> {
        let n = inputs.len();
        let w = if s.prec == Precision::F32 { 4 } else { 8 };
        let mut req = Vec::with_capacity(8 + n * self.inputs * w);
        req.extend((n as u64).to_le_bytes());
        for &x in inputs.iter().flatten() {
            match s.prec {
                Precision::F32 => req.extend((x as f32).to_le_bytes()),
                Precision::F64 => req.extend(x.to_le_bytes()),
            }
        }
        let size = 12 + n * 4 + n * self.outputs * w;
        let mut slot = s.worker.lock().unwrap_or_else(|e| e.into_inner());
        if slot.is_none() {
            *slot = Some(self.start(s)?);
        }
        let worker = slot.as_mut().expect("started");
        let whole = |b: &[u8]| (b.len() >= size).then_some(size);
        let got = worker.exchange(&req, false, Some(&whole), Instant::now() + self.timeout);
        let bytes = match got {
            Ok(b) => b,
            Err(e) => {
                let status = worker.wait(Duration::from_millis(200));
                let hung = matches!(e, Broken::Deadline);
                let how = match (e, status) {
                    (Broken::Deadline, _) => format!(
                        "did not answer within {} s (killed)",
                        self.timeout.as_secs_f64()
                    ),
                    (_, Some(st)) => match st.code() {
                        Some(c) => format!("ended (exit status {c}: a routine that calls exit()?)"),
                        None => format!(
                            "crashed ({})",
                            signal_name(
                                std::os::unix::process::ExitStatusExt::signal(&st).unwrap_or(0)
                            )
                        ),
                    },
                    (Broken::StdoutCap(_), None) => "wrote more than it may".into(),
                    (Broken::Closed, None) => "closed its output".into(),
                };
                let why = crate::process::explain(&worker.stderr());
                *slot = None;
                return Err(if hung {
                    Failure::Hung(how, why)
                } else {
                    Failure::Died(how, why)
                });
            }
        };
        let status = i32::from_le_bytes(bytes[0..4].try_into().expect("4 bytes"));
        let nanos = u64::from_le_bytes(bytes[4..12].try_into().expect("8 bytes"));
        let counts = bytes[12..12 + n * 4]
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
            .collect();
        let values = bytes[12 + n * 4..]
            .chunks_exact(w)
            .map(|b| match s.prec {
                Precision::F32 => f32::from_le_bytes(b.try_into().expect("4 bytes")) as f64,
                Precision::F64 => f64::from_le_bytes(b.try_into().expect("8 bytes")),
            })
            .collect();
        Ok((status, nanos, counts, values))
    }

    /// The case of `inputs` that makes the worker die, by halving on fresh workers (at most
    /// 16 halvings, within `budget`); `None` when no single case does it.
    fn culprit(&self, s: &Symbol, inputs: &[Vec<f64>], budget: Instant) -> Option<usize> {
        let (mut lo, mut hi) = (0, inputs.len());
        for _ in 0..16 {
            if hi - lo <= 1 || Instant::now() >= budget {
                break;
            }
            let mid = lo + (hi - lo) / 2;
            match self.call(s, &inputs[lo..mid]) {
                Err(Failure::Died(..)) => hi = mid,
                _ => lo = mid,
            }
        }
        (hi - lo == 1 && matches!(self.call(s, &inputs[lo..hi]), Err(Failure::Died(..))))
            .then_some(lo)
    }
}

/// A signal's name, for messages.
fn signal_name(sig: i32) -> String {
    let name = match sig {
        libc::SIGSEGV => "SIGSEGV, a segmentation fault",
        libc::SIGBUS => "SIGBUS",
        libc::SIGFPE => "SIGFPE",
        libc::SIGILL => "SIGILL",
        libc::SIGABRT => "SIGABRT, an abort",
        libc::SIGKILL => "SIGKILL",
        _ => "",
    };
    format!(
        "signal {sig}{}",
        if name.is_empty() {
            String::new()
        } else {
            format!(", {name}")
        }
    )
}

impl Method for Plugin {
    fn name(&self) -> &str {
        &self.name
    }
    fn own_nanos(&self, prec: Precision) -> Option<u64> {
        Some(self.routine_nanos(prec))
    }
    fn replay(&self) -> Option<String> {
        let specs: Vec<String> = self
            .symbols
            .iter()
            .map(|s| format!("--plugin {}:{}", s.spec, s.prec.name()))
            .collect();
        Some(format!("{} --name {}", specs.join(" "), self.name))
    }
    fn identity(&self) -> Option<String> {
        let ids: Vec<String> = self
            .symbols
            .iter()
            .map(|s| format!("--plugin sha256:{}:{}", s.sha256, s.symbol))
            .collect();
        Some(ids.join(" "))
    }
    fn answer(&self, prec: Precision, inputs: &[Vec<f64>]) -> Result<Vec<Answer>, String> {
        let Some(s) = self.symbols.iter().find(|s| s.prec == prec) else {
            return Err(format!(
                "--plugin: {} has no {} symbol",
                self.name,
                prec.name()
            ));
        };
        let n = inputs.len();
        if n == 0 {
            return Ok(vec![]);
        }
        let spec = &s.spec;
        let batch = s.batches.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        let at = |i: usize| {
            crate::audit::exec::case_text(
                &self.shape,
                self.name(),
                prec,
                self.replay().as_deref(),
                &inputs[i],
            )
        };
        let died = |how: String, said: String, case: String| {
            let said = if said.is_empty() {
                String::new()
            } else {
                format!("; it said: {said}")
            };
            format!(
                "plugin {spec} {how} answering batch {batch} ({n} {} cases){case}{said}",
                prec.name()
            )
        };
        let (status, nanos, count, values) = match self.call(s, inputs) {
            Ok(r) => r,
            Err(Failure::Reported(e)) => return Err(e),
            Err(Failure::Hung(how, said)) => {
                return Err(died(how, said, format!("; the batch's first: {}", at(0))));
            }
            Err(Failure::Died(how, said)) => {
                // Which case? Halve the batch on fresh workers while time allows
                let case = self
                    .culprit(
                        s,
                        inputs,
                        Instant::now() + self.timeout.max(Duration::from_secs(5)),
                    )
                    .map(|i| format!("; the case: {}", at(i)))
                    .unwrap_or_else(|| {
                        format!(
                            "; no single case does it alone (the batch's first: {})",
                            at(0)
                        )
                    });
                return Err(died(how, said, case));
            }
        };
        s.nanos
            .fetch_add(nanos, std::sync::atomic::Ordering::Relaxed);
        if status != 0 {
            return Err(format!(
                "plugin {spec} returned {status} (a failure) for batch {batch} of {n} cases"
            ));
        }
        // Every count written (else the protocol is broken: a wrong signature). The answer is
        // what the routine wrote: a count the shape cannot have is the contract's to judge
        // (malformed), as it is for every other way in
        let counted = self.counted;
        let answers = count
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                if c == UNSET {
                    return Err(format!(
                        "plugin {spec} left count[{i}] unwritten (a wrong signature? see `rayproof header`)"
                    ));
                }
                // The values it wrote: the first `count` (at most OUT) for the polynomials, all
                // OUT for a hit of any other shape
                let k = match (c, counted) {
                    (0, _) => 0,
                    (c, true) => (c as usize).min(self.outputs),
                    _ => self.outputs,
                };
                Ok(Answer {
                    count: c,
                    values: values[i * self.outputs..i * self.outputs + k].to_vec(),
                    enclosure: None,
                })
            })
            .collect::<Result<Vec<Answer>, String>>()?;
        // Values never written (still the NaN put there before the call) on every hit of a
        // batch: not an answer but a wrong signature
        let hits: Vec<&Answer> = answers.iter().filter(|a| a.count > 0).collect();
        if hits.len() >= 16 && hits.iter().all(|a| a.values.iter().all(|v| v.is_nan())) {
            return Err(format!(
                "plugin {spec}: every value of {} hits is NaN (a wrong signature? see `rayproof header`)",
                hits.len()
            ));
        }
        Ok(answers)
    }
}

/// The C header: one typedef per shape and precision.
pub fn header(shapes: &[&'static dyn crate::shapes::shape::Shape]) -> String {
    let mut out = [
        "/* rayproof.h: the C signatures of routines audited with `rayproof audit --plugin PATH:SYMBOL`.",
        " * A routine answers n cases at once: in[i] holds case i's inputs in order; it writes",
        " * count[i] = 0 for a miss (no real root, total internal reflection) and 1 for a hit with",
        " * every out[i] value written (t, or a vector's components); the polynomial shapes write",
        " * their number of distinct real roots, ascending in out[i][0 .. count[i]]. It returns 0",
        " * (anything else reports a failure). Build with -shared -fPIC.",
        " *",
        " * The answer contract (the same for --plugin, --exec answer lines, score files and the Rust",
        " * API; each shape's own is stated beside its signature): a count the shape cannot have is",
        " * a malformed answer, counted in its row and failing it whatever its tolerance rule; a hit's",
        " * values are finite (NaN or Inf is a non-finite, wrong value); a ray's t lies in t > 0 (a",
        " * hit at t < 0, -0 or +0 is out of range, a wrong verdict, unless the exact t itself rounds",
        " * to +0); invalid input (NaN or Inf inputs, a degenerate shape) is answered with count 0.",
        " * Directions need not be normalised. A count left unwritten stops the audit (exit 4). */",
        "#ifndef RAYPROOF_H",
        "#define RAYPROOF_H",
        "#include <stddef.h>",
        "#include <stdint.h>",
        "",
    ]
    .join("\n");
    for s in shapes {
        let info = s.info();
        let (i, o) = (info.args.len(), info.values.len());
        out += &format!(
            "\n/* {}: {}\n * in:  {}\n * out: {}\n * contract: {} */\n",
            info.name,
            info.about,
            info.args.join(" "),
            info.values.join(" "),
            super::contract::describe(info)
        );
        for (t, p) in [("float", "f32"), ("double", "f64")] {
            out += &format!(
                "typedef int rayproof_{}_{p}(size_t n, const {t} in[][{i}], uint32_t count[], {t} out[][{o}]);\n",
                info.name
            );
        }
    }
    out + "\n#endif\n"
}
