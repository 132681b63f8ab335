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
//! A routine that crashes the process (a segmentation fault) is caught by a signal handler
//! installed around the call: one line naming the library and symbol, exit 4, no report.
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
//! A library or symbol that cannot be loaded is exit 2; a routine that crashes (a segmentation
//! fault is caught around the call), returns non-zero, leaves a count unwritten or writes no value
//! at all (a wrong signature) stops the audit with one line and exit 4, and no report is written.
//! Worst cases replay with `rayproof probe … --plugin PATH:SYMBOL:f32 --name N -- …`, and shards
//! of a plugin audit merge as any other. `rayproof report --plugin …:f32 --plugin …:f64` (or
//! `--exec`) puts your ray–sphere routine beside the built-in methods in its accuracy-vs-cost
//! section, with its own ns per test measured on the same batch (for a plugin, one call per batch;
//! for `--exec`, including the child's start).

use super::shape::{Answer, Method};
use crate::numerics::Precision;
use std::ffi::CString;
use std::sync::Mutex;

/// A batch routine in f32.
type F32Fn = unsafe extern "C" fn(usize, *const f32, *mut u32, *mut f32) -> i32;
/// A batch routine in f64.
type F64Fn = unsafe extern "C" fn(usize, *const f64, *mut u32, *mut f64) -> i32;

/// The count rayproof writes before the call: a routine must overwrite it.
const UNSET: u32 = u32::MAX;

/// One loaded symbol.
enum Routine {
    F32(F32Fn),
    F64(F64Fn),
}

/// A routine of a shared library, one symbol per precision.
pub struct Plugin {
    name: String,
    /// `PATH:SYMBOL` per precision, for messages and replay lines.
    specs: Vec<(Precision, String)>,
    routines: Vec<(Precision, Routine)>,
    inputs: usize,
    outputs: usize,
    /// The count is the number of values written (the polynomials).
    counted: bool,
    /// Keeps the libraries loaded while their symbols are used.
    _libs: Vec<libloading::Library>,
}

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

impl Plugin {
    /// Loads one symbol per spec for a shape with `inputs` inputs and `outputs` values; the
    /// method's name defaults to the first symbol without its precision suffix.
    pub fn load(
        specs: &[String],
        name: Option<&str>,
        shape: &super::shape::ShapeInfo,
    ) -> Result<Plugin, String> {
        let mut p = Plugin {
            name: String::new(),
            specs: vec![],
            routines: vec![],
            inputs: shape.args.len(),
            outputs: shape.values.len(),
            counted: shape.count_is_values,
            _libs: vec![],
        };
        for spec in specs {
            let (path, symbol, prec) = parse_spec(spec)?;
            if p.routines.iter().any(|(q, _)| *q == prec) {
                return Err(format!("--plugin: two {} symbols", prec.name()));
            }
            // A path without a slash would be searched for by the loader: make it explicit
            let file = if path.contains('/') {
                path.clone()
            } else {
                format!("./{path}")
            };
            // SAFETY: loading runs the library's initialisers; the user asked for this library
            let lib = unsafe { libloading::Library::new(&file) }
                .map_err(|e| format!("--plugin {path}: cannot load: {e}"))?;
            let cname =
                CString::new(symbol.clone()).map_err(|_| format!("--plugin {spec}: bad symbol"))?;
            // SAFETY: the symbol is used with the documented signature of its precision; a
            // routine with another signature is caught by the count sentinel or crashes, which
            // the signal handler reports
            let routine = unsafe {
                match prec {
                    Precision::F32 => lib
                        .get::<F32Fn>(cname.as_bytes_with_nul())
                        .map(|f| Routine::F32(*f)),
                    Precision::F64 => lib
                        .get::<F64Fn>(cname.as_bytes_with_nul())
                        .map(|f| Routine::F64(*f)),
                }
            }
            .map_err(|e| format!("--plugin {path}: no symbol '{symbol}': {e}"))?;
            p.routines.push((prec, routine));
            p.specs.push((prec, format!("{path}:{symbol}")));
            p._libs.push(lib);
            if p.name.is_empty() {
                p.name = name.map(str::to_string).unwrap_or_else(|| {
                    symbol
                        .trim_end_matches("_f32")
                        .trim_end_matches("_f64")
                        .to_string()
                });
            }
        }
        if p.routines.is_empty() {
            return Err("--plugin: no symbol given".into());
        }
        Ok(p)
    }

    /// The precisions it has a symbol for.
    pub fn precisions(&self) -> Vec<Precision> {
        self.routines.iter().map(|(p, _)| *p).collect()
    }

    fn spec(&self, prec: Precision) -> &str {
        self.specs
            .iter()
            .find(|(p, _)| *p == prec)
            .map(|(_, s)| s.as_str())
            .unwrap_or("")
    }
}

/// What the crash handler prints: set before each call (the calls are not concurrent).
static CALLING: Mutex<Option<CString>> = Mutex::new(None);
/// The message as a raw pointer for the signal handler (which must not lock).
static MESSAGE: std::sync::atomic::AtomicPtr<libc::c_char> =
    std::sync::atomic::AtomicPtr::new(std::ptr::null_mut());

/// On a crash inside a plugin: write the message and leave with exit code 4. Only
/// async-signal-safe calls (`write`, `_exit`).
extern "C" fn crashed(_sig: libc::c_int) {
    let msg = MESSAGE.load(std::sync::atomic::Ordering::SeqCst);
    if !msg.is_null() {
        // SAFETY: the message is a NUL-terminated string kept alive in CALLING
        unsafe {
            let len = libc::strlen(msg);
            libc::write(2, msg as *const libc::c_void, len);
        }
    }
    // SAFETY: leaving at once, without unwinding or running destructors, is what a crash needs
    unsafe { libc::_exit(4) }
}

/// Runs `call` with crash handlers for the signals a bad routine raises, which print `what`.
fn guarded<T>(what: &str, call: impl FnOnce() -> T) -> T {
    let text = CString::new(format!("error: {what}\n")).unwrap_or_default();
    let mut slot = CALLING.lock().unwrap_or_else(|e| e.into_inner());
    MESSAGE.store(text.as_ptr() as *mut _, std::sync::atomic::Ordering::SeqCst);
    *slot = Some(text);
    let signals = [
        libc::SIGSEGV,
        libc::SIGBUS,
        libc::SIGFPE,
        libc::SIGILL,
        libc::SIGABRT,
    ];
    // SAFETY: plain sigaction calls; the old handlers are restored after the call
    let old: Vec<libc::sigaction> = signals
        .iter()
        .map(|&sig| unsafe {
            let mut new: libc::sigaction = std::mem::zeroed();
            new.sa_sigaction = crashed as extern "C" fn(libc::c_int) as usize;
            let mut old: libc::sigaction = std::mem::zeroed();
            libc::sigaction(sig, &new, &mut old);
            old
        })
        .collect();
    let r = call();
    for (&sig, old) in signals.iter().zip(&old) {
        // SAFETY: restoring what was there
        unsafe {
            libc::sigaction(sig, old, std::ptr::null_mut());
        }
    }
    MESSAGE.store(std::ptr::null_mut(), std::sync::atomic::Ordering::SeqCst);
    *slot = None;
    r
}

impl Method for Plugin {
    fn name(&self) -> &str {
        &self.name
    }
    fn replay(&self) -> Option<String> {
        let specs: Vec<String> = self
            .specs
            .iter()
            .map(|(p, s)| format!("--plugin {s}:{}", p.name()))
            .collect();
        Some(format!("{} --name {}", specs.join(" "), self.name))
    }
    fn answer(&self, prec: Precision, inputs: &[Vec<f64>]) -> Result<Vec<Answer>, String> {
        let Some((_, routine)) = self.routines.iter().find(|(p, _)| *p == prec) else {
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
        let spec = self.spec(prec);
        let what = format!("plugin {spec} crashed answering {n} {} cases", prec.name());
        let mut count = vec![UNSET; n];
        // Arrays in, arrays out, one call per batch
        let (status, values): (i32, Vec<f64>) = match routine {
            Routine::F32(f) => {
                let input: Vec<f32> = inputs.iter().flatten().map(|&x| x as f32).collect();
                let mut out = vec![f32::NAN; n * self.outputs];
                debug_assert_eq!(input.len(), n * self.inputs);
                // SAFETY: the buffers have the documented sizes for n cases
                let s = guarded(&what, || unsafe {
                    f(n, input.as_ptr(), count.as_mut_ptr(), out.as_mut_ptr())
                });
                (s, out.into_iter().map(f64::from).collect())
            }
            Routine::F64(f) => {
                let input: Vec<f64> = inputs.iter().flatten().copied().collect();
                let mut out = vec![f64::NAN; n * self.outputs];
                // SAFETY: as above
                let s = guarded(&what, || unsafe {
                    f(n, input.as_ptr(), count.as_mut_ptr(), out.as_mut_ptr())
                });
                (s, out)
            }
        };
        if status != 0 {
            return Err(format!(
                "plugin {spec} returned {status} (a failure) for a batch of {n} cases"
            ));
        }
        // Every count written (else the protocol is broken: a wrong signature). The answer is
        // what the routine wrote: a count the shape cannot have is the contract's to judge
        // (malformed), as it is for every other way in
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
                let k = match (c, self.counted) {
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
pub fn header(shapes: &[&'static dyn super::shape::Shape]) -> String {
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
