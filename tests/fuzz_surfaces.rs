//! Seeded property-based fuzzing of the input surfaces `tests/fuzz.rs` does not cover:
//!
//! 1. suite files and golden manifests (`check --suite FILE --update --json`), over a suite
//!    built with the stand-in renderer (`tests/outside/standin_render.py`): a test rendered by
//!    the suite's renderer, one by its own command with a variance image, one read from an
//!    image, one rendered by rayproof; references with a manifest, goldens with theirs;
//! 2. tolerance files (`audit --shape rcp --cases 200 --tolerances FILE`), from the built-in
//!    table's rcp rules and measurements;
//! 3. `cases` and answers files (`score --cases FILE --answers FILE`), for rcp and sphere;
//! 4. `--exec` answers: a C child (built here) answers the sphere's cases with the textbook
//!    formula, then mutates its answer lines, its output stream, its exit or its timing;
//! 5. output paths (`--json`, `--markdown`, `-o`, `--report`, `--junit`) given hostile paths:
//!    directories, symbolic links, FIFOs, the run's own inputs, /dev/full, /proc, odd characters,
//!    long names, missing directories, one path twice.
//!
//! Mutations: byte flips, truncations, hostile values (NaN, infinities, -0, 1e308, 1e-320,
//! 2^64, negative counts, empty and very long strings, wrong types, device paths), deleted,
//! duplicated and swapped lines, swapped fields, duplicated keys.
//!
//! Every run must end, within 30 s and under a 4 GB address-space limit, with one of the
//! command's documented exit codes (`src/lib.rs`), never a signal or a panic; an error must be
//! exactly one line on stderr starting with "error" and leave the directory it could touch
//! byte-identical (snapshot before and after, symbolic links and all); a run that succeeds may
//! change only its intended outputs, and leaves no temporary (TMPDIR is the case's own).
//!
//! Runs are seeded: the same cases every time. `RAYPROOF_FUZZ_CASES=N` runs N cases per surface
//! (`RAYPROOF_FUZZ_CASES_SUITE`, `_TOLERANCES`, `_SCORE`, `_EXEC`, `_PATHS` for one surface),
//! `RAYPROOF_FUZZ_SEED=S` draws other cases.

use proptest::prelude::*;
use proptest::test_runner::{RngSeed, TestCaseError};
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::os::unix::ffi::{OsStrExt, OsStringExt};
use std::os::unix::process::CommandExt;
use std::path::{Component, Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

// ---- configuration ----------------------------------------------------------------------------

/// A run that takes longer is a hang.
const RUN_TIMEOUT: Duration = Duration::from_secs(30);
/// The address space of each run (and of what it starts): a blow-up fails, the machine lives.
const ADDRESS_SPACE: u64 = 4 << 30;
/// More resident memory than this, for these small inputs, is a blow-up (stopped or not by the
/// address-space limit).
const PEAK_MEMORY: u64 = 1 << 30;

/// Cases for a surface: `RAYPROOF_FUZZ_CASES_<SURFACE>`, else `RAYPROOF_FUZZ_CASES`, else the
/// default.
fn cases(surface: &str, default: u32) -> u32 {
    let var = |k: &str| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.trim().parse::<u32>().ok())
    };
    var(&format!("RAYPROOF_FUZZ_CASES_{}", surface.to_uppercase()))
        .or_else(|| var("RAYPROOF_FUZZ_CASES"))
        .unwrap_or(default)
}

/// The proptest configuration of a surface: fixed seed, no persistence, bounded shrinking.
fn config(surface: &str, default: u32, seed: u64) -> ProptestConfig {
    let seed = std::env::var("RAYPROOF_FUZZ_SEED")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .map(|s| s.wrapping_mul(1_000_003).wrapping_add(seed))
        .unwrap_or(seed);
    ProptestConfig {
        cases: cases(surface, default),
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        // A mutation's numbers are read modulo the input: shrinking them finds another input,
        // not a smaller one (and reruns hangs)
        max_shrink_iters: 0,
        ..ProptestConfig::default()
    }
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The scratch directory of this test process.
fn base() -> &'static Path {
    static B: OnceLock<PathBuf> = OnceLock::new();
    B.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("rayproof-fuzz-surfaces-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    })
}

/// A fresh, empty directory under the scratch directory.
fn fresh(name: &str) -> PathBuf {
    let d = base().join(name);
    if std::fs::symlink_metadata(&d).is_ok() {
        let _ = std::fs::remove_dir_all(&d);
    }
    std::fs::create_dir_all(d.join("tmp")).unwrap();
    d
}

// ---- running the binary ---------------------------------------------------------------------

/// How a run ended.
struct Run {
    code: Option<i32>,
    signal: Option<i32>,
    timed_out: bool,
    stdout: String,
    stderr: String,
    secs: f64,
    /// Peak resident memory of the run (the largest of it and what it waited for), in bytes.
    peak: u64,
}

/// Runs `rayproof ARGS` in `dir` (TMPDIR `dir/tmp`), in its own process group, under the
/// address-space limit, killed with its group after [`RUN_TIMEOUT`]. Standard output and error
/// go to files beside `dir`, so nothing it leaves running can block the test.
fn run_in(dir: &Path, args: &[OsString]) -> Run {
    use std::os::unix::process::ExitStatusExt;
    let logs = dir.with_extension("logs");
    let _ = std::fs::remove_dir_all(&logs);
    std::fs::create_dir_all(&logs).unwrap();
    let (out, err) = (logs.join("stdout"), logs.join("stderr"));
    let mut c = Command::new(env!("CARGO_BIN_EXE_rayproof"));
    c.args(args)
        .current_dir(dir)
        .env("TMPDIR", dir.join("tmp"))
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap());
    // SAFETY: async-signal-safe calls only (setpgid, setrlimit) between fork and exec
    unsafe {
        c.pre_exec(|| {
            libc::setpgid(0, 0);
            let lim = libc::rlimit {
                rlim_cur: ADDRESS_SPACE as libc::rlim_t,
                rlim_max: ADDRESS_SPACE as libc::rlim_t,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let start = Instant::now();
    let child = c.spawn().expect("the rayproof binary starts");
    let pid = child.id() as i32;
    let mut timed_out = false;
    // Reaped with wait4(2) for its peak memory
    // SAFETY: rusage is plain data; wait4 writes the status and the usage of our own child
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let mut raw = 0;
    loop {
        let w = unsafe { libc::wait4(pid, &mut raw, libc::WNOHANG, &mut usage) };
        if w == pid {
            break;
        }
        assert!(w == 0, "wait4: {}", std::io::Error::last_os_error());
        if start.elapsed() > RUN_TIMEOUT && !timed_out {
            timed_out = true;
            // SAFETY: kill(2) of the run's own process group
            unsafe {
                libc::kill(-pid, libc::SIGKILL);
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    drop(child);
    let status = std::process::ExitStatus::from_raw(raw);
    let read =
        |p: &Path| String::from_utf8_lossy(&std::fs::read(p).unwrap_or_default()).into_owned();
    let r = Run {
        code: status.code(),
        signal: status.signal(),
        timed_out,
        stdout: read(&out),
        stderr: read(&err),
        secs: start.elapsed().as_secs_f64(),
        peak: usage.ru_maxrss as u64 * 1024,
    };
    let _ = std::fs::remove_dir_all(&logs);
    r
}

fn os(args: &[&str]) -> Vec<OsString> {
    args.iter().map(OsString::from).collect()
}

// ---- snapshots --------------------------------------------------------------------------------

/// One entry of a directory tree, as it is on disk (links are not followed).
#[derive(Clone, Debug, PartialEq)]
enum Node {
    File(Vec<u8>),
    Dir,
    Link(PathBuf),
    Other,
}

type Snapshot = BTreeMap<PathBuf, Node>;

/// Every entry under `dir`, by its path relative to `dir`.
fn snapshot(dir: &Path) -> Snapshot {
    fn walk(root: &Path, d: &Path, out: &mut Snapshot) {
        let Ok(rd) = std::fs::read_dir(d) else { return };
        for e in rd.flatten() {
            let p = e.path();
            let rel = p.strip_prefix(root).unwrap().to_path_buf();
            let Ok(m) = std::fs::symlink_metadata(&p) else {
                continue;
            };
            let t = m.file_type();
            if t.is_symlink() {
                out.insert(rel, Node::Link(std::fs::read_link(&p).unwrap_or_default()));
            } else if t.is_dir() {
                out.insert(rel, Node::Dir);
                walk(root, &p, out);
            } else if t.is_file() {
                out.insert(rel, Node::File(std::fs::read(&p).unwrap_or_default()));
            } else {
                out.insert(rel, Node::Other);
            }
        }
    }
    let mut s = Snapshot::new();
    walk(dir, dir, &mut s);
    s
}

/// What changed: `(path, "new" | "changed" | "removed")`.
fn changes(before: &Snapshot, after: &Snapshot) -> Vec<(PathBuf, &'static str)> {
    let mut v = vec![];
    for (p, n) in after {
        match before.get(p) {
            None => v.push((p.clone(), "new")),
            Some(o) if o != n => v.push((p.clone(), "changed")),
            _ => {}
        }
    }
    for p in before.keys() {
        if !after.contains_key(p) {
            v.push((p.clone(), "removed"));
        }
    }
    v
}

/// Copies a directory tree of regular files and directories.
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let t = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &t);
        } else {
            std::fs::copy(e.path(), &t).unwrap();
        }
    }
}

/// A lexically normalised path (`.` and `..` resolved, no filesystem access).
fn normalise(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

// ---- the verdict on one run -------------------------------------------------------------------

/// What a command may do.
struct Expect<'a> {
    /// Its documented exit codes.
    codes: &'a [i32],
    /// The codes that are errors: one line on stderr, nothing changed.
    errors: &'a [i32],
    /// Codes that are errors only when stderr says so (check's 3: a refusal is a verdict, a
    /// renderer that cannot run is an error).
    maybe_errors: &'a [i32],
    /// Whether a change to this path (relative to the case directory) is an intended output of
    /// a run that ended with this code.
    may_write: &'a dyn Fn(&Path, i32) -> bool,
}

/// Checks one run against the contract; the error says what broke and how the run ended.
fn judge(r: &Run, e: &Expect, before: &Snapshot, after: &Snapshot) -> Result<(), String> {
    // RAYPROOF_FUZZ_VERBOSE=1: one line per run (exit, seconds, files changed, stderr's last line)
    if std::env::var_os("RAYPROOF_FUZZ_VERBOSE").is_some() {
        eprintln!(
            "run: exit {:?} in {:.2} s, {} MB, {} change(s): {} | {}",
            r.code,
            r.secs,
            r.peak >> 20,
            changes(before, after).len(),
            clip(r.stderr.trim_end().lines().last().unwrap_or(""), 200),
            clip(r.stdout.lines().nth(1).unwrap_or(""), 200)
        );
    }
    let ended = format!(
        "exit {:?}, signal {:?}, {:.1} s\n--- stderr:\n{}\n--- stdout (tail):\n{}",
        r.code,
        r.signal,
        r.secs,
        clip(&r.stderr, 3000),
        tail(&r.stdout, 1500)
    );
    if r.timed_out {
        return Err(format!(
            "a hang: no end within {} s ({ended})",
            RUN_TIMEOUT.as_secs()
        ));
    }
    let Some(code) = r.code else {
        return Err(format!("killed by a signal ({ended})"));
    };
    if r.peak > PEAK_MEMORY {
        return Err(format!(
            "a memory blow-up: {} MB resident at the peak ({ended})",
            r.peak >> 20
        ));
    }
    if !e.codes.contains(&code) {
        return Err(format!("undocumented exit code {code} ({ended})"));
    }
    if r.stderr.contains("panicked") {
        return Err(format!("a panic ({ended})"));
    }
    let lines: Vec<&str> = r.stderr.trim_end().lines().collect();
    let says_error = lines.iter().any(|l| l.starts_with("error"));
    let error =
        e.errors.contains(&code) || (e.maybe_errors.contains(&code) && !r.stderr.trim().is_empty());
    if error {
        if lines.len() != 1 || !lines[0].starts_with("error") {
            return Err(format!(
                "an error must be exactly one line on stderr starting with \"error\", got {} line(s) ({ended})",
                lines.len()
            ));
        }
    } else if says_error {
        return Err(format!(
            "an \"error\" line with a non-error exit code ({ended})"
        ));
    }
    let diff = changes(before, after);
    if error {
        if !diff.is_empty() {
            return Err(format!("a failed run changed files: {diff:?} ({ended})"));
        }
    } else if let Some(bad) = diff.iter().find(|(p, _)| !(e.may_write)(p, code)) {
        return Err(format!(
            "a file that is not an intended output changed: {bad:?} (all changes: {diff:?}) ({ended})"
        ));
    }
    Ok(())
}

fn clip(s: &str, n: usize) -> String {
    if s.len() <= n {
        return s.to_string();
    }
    let mut k = n;
    while !s.is_char_boundary(k) {
        k -= 1;
    }
    format!("{}… ({} bytes)", &s[..k], s.len())
}

fn tail(s: &str, n: usize) -> String {
    if s.len() <= n {
        return s.to_string();
    }
    let mut k = s.len() - n;
    while !s.is_char_boundary(k) {
        k += 1;
    }
    format!("…{}", &s[k..])
}

/// A failure with its reproducer: the surface, the command, the mutated inputs `(name,
/// original, mutated)` (the lines that differ are shown; the files are kept under
/// `CARGO_TARGET_TMPDIR/fuzz-surfaces-failures/`), and how to replay the case.
fn fail(
    what: &str,
    replay: &str,
    cmd: &[OsString],
    input: &[(&str, &[u8], &[u8])],
    why: String,
) -> TestCaseError {
    let cmd: Vec<String> = cmd.iter().map(|a| format!("{a:?}")).collect();
    let keep = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("fuzz-surfaces-failures")
        .join(replay.replace(' ', "-"));
    let _ = std::fs::remove_dir_all(&keep);
    let mut s = format!(
        "{what}: {why}\n--- reproducer: rayproof {} (replay: RAYPROOF_FUZZ_REPLAY='{replay}' cargo test --release --test integration fuzz_surfaces::replay -- --ignored --nocapture)\n",
        cmd.join(" ")
    );
    for (name, original, mutated) in input {
        let file = keep.join(name);
        std::fs::create_dir_all(file.parent().unwrap()).unwrap();
        std::fs::write(&file, mutated).unwrap();
        s += &format!(
            "--- {name} (kept as {}):\n{}",
            file.display(),
            changed_lines(original, mutated)
        );
    }
    TestCaseError::fail(s)
}

/// The lines of `mutated` that differ from `original`, with their numbers (and the original's).
fn changed_lines(original: &[u8], mutated: &[u8]) -> String {
    let a: Vec<&[u8]> = original.split(|&b| b == b'\n').collect();
    let b: Vec<&[u8]> = mutated.split(|&b| b == b'\n').collect();
    let head = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let tail = a[head..]
        .iter()
        .rev()
        .zip(b[head..].iter().rev())
        .take_while(|(x, y)| x == y)
        .count();
    let show = |l: &[u8]| clip(&format!("{:?}", String::from_utf8_lossy(l)), 400);
    let mut s = String::new();
    for (k, l) in a.iter().enumerate().take(a.len() - tail).skip(head) {
        s += &format!("  was line {}: {}\n", k + 1, show(l));
    }
    for (k, l) in b.iter().enumerate().take(b.len() - tail).skip(head) {
        s += &format!("  now line {}: {}\n", k + 1, show(l));
    }
    if s.is_empty() {
        s = "  (unchanged)\n".into();
    }
    s
}

/// Known failures that are not fixed here: `(surface, does this input hit it, what the failure
/// says, why)`. A case that hits one and fails with that message is reported, not failed.
type KnownFailure = (&'static str, fn(&[u8]) -> bool, &'static str, &'static str);
const KNOWN_FAILURES: &[KnownFailure] = &[(
    "suite",
    names_an_infinite_device,
    "a memory blow-up",
    "every input file is read whole (std::fs::read, read_to_string): a path to an endless device \
     (/dev/zero, /dev/full, /dev/urandom) as a reference, golden, image, scene or variance image \
     grows to the address-space limit (2 GB resident under 4 GB) before \"out of memory\"; the \
     same holds for --suite, --tolerances, --cases, --answers, render and diff inputs",
)];

fn names_an_infinite_device(input: &[u8]) -> bool {
    let text = String::from_utf8_lossy(input);
    ["/dev/zero", "/dev/full", "/dev/urandom"]
        .iter()
        .any(|d| text.contains(d))
}

/// The verdict on a case, or `Ok` for a known failure (printed).
fn verdict(surface: &str, input: &[u8], r: Result<(), TestCaseError>) -> Result<(), TestCaseError> {
    if let Err(e) = &r {
        let text = e.to_string();
        if let Some((_, _, _, why)) = KNOWN_FAILURES
            .iter()
            .find(|(s, hit, says, _)| *s == surface && hit(input) && text.contains(says))
        {
            eprintln!("known failure ({why}): {}", clip(&text, 600));
            return Ok(());
        }
    }
    r
}

// ---- mutations ------------------------------------------------------------------------------

/// How a text file is structured, for value mutations.
#[derive(Clone, Copy, PartialEq)]
enum Style {
    /// `key = value` lines.
    Toml,
    /// `"key": value,` lines (pretty-printed JSON).
    Json,
    /// Whitespace-separated tokens.
    Words,
}

/// One mutation, drawn by proptest: a kind and three free numbers its kind interprets.
#[derive(Clone, Debug)]
struct Mutation {
    kind: usize,
    a: usize,
    b: usize,
    v: usize,
}

fn mutation() -> impl Strategy<Value = Mutation> {
    (
        0usize..12,
        0usize..100_000,
        0usize..100_000,
        0usize..100_000,
    )
        .prop_map(|(kind, a, b, v)| Mutation { kind, a, b, v })
}

/// A very long string of `c`.
fn long(c: char, n: usize) -> String {
    std::iter::repeat_n(c, n).collect()
}

/// Values for `key = value` lines of TOML files.
fn toml_hostile() -> &'static Vec<String> {
    static V: OnceLock<Vec<String>> = OnceLock::new();
    V.get_or_init(|| {
        let mut v: Vec<String> = [
            "nan",
            "+nan",
            "-nan",
            "inf",
            "+inf",
            "-inf",
            "-0",
            "-0.0",
            "0",
            "0.0",
            "-1",
            "1",
            "2",
            "1e308",
            "-1e308",
            "1e-320",
            "5e-324",
            "1e-5",
            "18446744073709551616",
            "18446744073709551615",
            "9223372036854775807",
            "-9223372036854775808",
            "4294967295",
            "4294967296",
            "65",
            "16385",
            "1.5",
            "0x10",
            "true",
            "false",
            "\"\"",
            "\" \"",
            "\"x\"",
            "\"nan\"",
            "\"1\"",
            "[]",
            "[1, 2]",
            "[\"a\", \"a\"]",
            "[[]]",
            "{}",
            "{ fail = nan }",
            "{ fail = -1 }",
            "{ nosuchkey = 1 }",
            "1979-05-27T07:32:00Z",
            "\"..\"",
            "\".\"",
            "\"/\"",
            "\"/dev/null\"",
            "\"/dev/full\"",
            "\"/dev/zero\"",
            "\"/dev/urandom\"",
            "\"/proc/self/status\"",
            "\"/no/such/file\"",
            "\"suite.toml\"",
            "\"refs/manifest.json\"",
            "\"refs/a.exr\"",
            "\"img/c.exr\"",
            "\"goldens\"",
            "\"goldens/a.exr\"",
            "\"{out}\"",
            "\"{unknown}\"",
            "\"{\"",
            "\"}\"",
            "\"{out\"",
            "\"a\\nb\"",
            "\"\\u0000\"",
            "\"\\r\"",
            "\"ü\"",
            "'''\nmulti\nline'''",
            "\"none\"",
            "\"measured\"",
            "\"reject\"",
            "\"rcp\"",
            "\"sphere\"",
            "\"division\"",
            "\"bits+1\"",
            "\"promote\"",
            "\"f32\"",
            "\"f64\"",
            "\"f16\"",
            "[\"f32\", \"f32\"]",
            "[\"mantissa\", \"huge\"]",
            "[0, 0]",
            "[1, 0]",
            "[0, 1]",
            "[9223372036854775807, 9223372036854775807]",
            "[1, 9223372036854775807]",
            "[-1, 5]",
            "[1.5, 2]",
            "[1, 2, 3]",
            "[nan, 1]",
            "{ method = \"promote\", precision = \"f16\" }",
            "{ method = \"nope\", precision = \"f64\" }",
            "{ method = \"promote\" }",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        v.push(format!("\"{}\"", long('x', 100_000)));
        v.push(format!("\"{}\"", long('a', 300)));
        v.push(long('9', 5000));
        v.push(format!("{}.5", long('9', 400)));
        v
    })
}

/// Values for `"key": value` lines of JSON files.
fn json_hostile() -> &'static Vec<String> {
    static V: OnceLock<Vec<String>> = OnceLock::new();
    V.get_or_init(|| {
        let mut v: Vec<String> = [
            "null",
            "true",
            "false",
            "0",
            "-0",
            "-1",
            "1",
            "2",
            "64",
            "65",
            "1.5",
            "1e308",
            "-1e308",
            "1e-320",
            "1e999",
            "18446744073709551616",
            "18446744073709551615",
            "4294967296",
            "4294967295",
            "16385",
            "\"\"",
            "\"x\"",
            "\"24\"",
            "[]",
            "[1]",
            "{}",
            "{\"sha256\": 1}",
            "{\"files\": {}}",
            "NaN",
            "Infinity",
            "\"0000000000000000000000000000000000000000000000000000000000000000\"",
            "\"\\u0000\"",
            "\"a\\nb\"",
            "\"\\ud800\"",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        v.push(format!("{}{}", "[".repeat(200), "]".repeat(200)));
        v.push(format!("{}{}", "[".repeat(100_000), "]".repeat(100_000)));
        v.push(format!("\"{}\"", long('f', 100_000)));
        v.push(long('9', 5000));
        v
    })
}

/// Tokens for numbers, counts and fields of cases and answers (and the `--exec` child's).
const TOKENS: [&str; 60] = [
    "nan",
    "-nan",
    "NaN",
    "inf",
    "-inf",
    "+inf",
    "infinity",
    "Inf",
    "-0",
    "0",
    "-0.0",
    "+0",
    "1",
    "2",
    "3",
    "-1",
    "1e308",
    "1e309",
    "-1e308",
    "1e-320",
    "4.9e-324",
    "1e-400",
    "0x1p-1074",
    "0x1p+1024",
    "0x1.fffffffffffffp+1023",
    "0x",
    "0x1p",
    "0xp1",
    "1e",
    "--1",
    "+-1",
    "18446744073709551616",
    "18446744073709551615",
    "4294967296",
    "4294967295",
    "1.5",
    "1e2",
    "0x1",
    "1_000",
    "\u{661}",
    "1,5",
    "0b1",
    "1..2",
    "",
    "f32",
    "f64",
    "f16",
    "mantissa",
    "tangent",
    "invalid",
    "cases=18446744073709551616",
    "cases=0",
    "cases=-1",
    "cases=99999999999",
    "seed=-1",
    "seed=18446744073709551616",
    "shape=torus",
    "shape=",
    "shape=sphere",
    "#",
];

/// A hostile token: one of [`TOKENS`] or a very long number.
fn token(v: usize) -> String {
    match v % (TOKENS.len() + 3) {
        k if k < TOKENS.len() => TOKENS[k].to_string(),
        k if k == TOKENS.len() => long('9', 100_000),
        k if k == TOKENS.len() + 1 => format!("0.{}1", long('0', 5000)),
        _ => format!("0x1p{}", long('9', 30)),
    }
}

/// Lines inserted whole.
const LINES: [&str; 16] = [
    "",
    " ",
    "#",
    "# a comment",
    "[suite]",
    "[[test]]",
    "[[rule]]",
    "[measured]",
    "{",
    "}",
    "\"files\": {},",
    "0",
    "1 1 1",
    "garbage line",
    "\u{0}",
    "key = ",
];

/// Applies one mutation to a text file.
fn mutate(text: &str, m: &Mutation, style: Style, hostile: &[String]) -> Vec<u8> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let n = lines.len().max(1);
    let value = || match style {
        Style::Words => token(m.v),
        _ => hostile[m.v % hostile.len()].clone(),
    };
    // The lines whose value a value mutation may replace
    let kv: Vec<usize> = (0..lines.len())
        .filter(|&k| match style {
            Style::Toml => lines[k].contains('=') && !lines[k].trim_start().starts_with('#'),
            Style::Json => lines[k].contains("\":"),
            Style::Words => !lines[k].trim().is_empty(),
        })
        .collect();
    let set_value = |line: &str, v: &str| -> String {
        match style {
            Style::Toml => {
                let key = line.split('=').next().unwrap().trim_end();
                format!("{key} = {v}")
            }
            Style::Json => {
                let (key, rest) = line.split_once("\":").unwrap();
                let comma = if rest.trim_end().ends_with(',') {
                    ","
                } else {
                    ""
                };
                format!("{key}\": {v}{comma}")
            }
            Style::Words => line.to_string(),
        }
    };
    match m.kind {
        // Hostile values, most often
        0..=3 if !kv.is_empty() => {
            // Tokens: the first line (a cases file's header) a quarter of the time
            let k = if style == Style::Words && m.a.is_multiple_of(4) {
                kv[0]
            } else {
                kv[m.a % kv.len()]
            };
            if style == Style::Words {
                let mut w: Vec<String> = lines[k].split_whitespace().map(String::from).collect();
                let i = m.b % w.len();
                w[i] = value();
                out[k] = w.join(" ");
            } else {
                out[k] = set_value(lines[k], &value());
            }
        }
        4 => {
            if !out.is_empty() {
                out.remove(m.a % n);
            }
        }
        5 => {
            if !lines.is_empty() {
                out.insert(m.b % n, lines[m.a % n].to_string());
            }
        }
        6 => {
            if !lines.is_empty() {
                out.swap(m.a % n, m.b % n);
            }
        }
        // Swapped fields: two values (or two tokens of a line) trade places
        7 if !kv.is_empty() => {
            let (i, j) = (kv[m.a % kv.len()], kv[m.b % kv.len()]);
            if style == Style::Words {
                let mut w: Vec<&str> = lines[i].split_whitespace().collect();
                let len = w.len();
                w.swap(m.b % len, m.v % len);
                out[i] = w.join(" ");
            } else {
                let val = |l: &str| match style {
                    Style::Toml => l.split_once('=').unwrap().1.trim().to_string(),
                    _ => l
                        .split_once("\":")
                        .unwrap()
                        .1
                        .trim()
                        .trim_end_matches(',')
                        .to_string(),
                };
                out[i] = set_value(lines[i], &val(lines[j]));
                out[j] = set_value(lines[j], &val(lines[i]));
            }
        }
        // A key given twice (TOML, JSON) or a hostile line
        8 => {
            let line = if !kv.is_empty() && style != Style::Words && m.v.is_multiple_of(2) {
                set_value(lines[kv[m.a % kv.len()]], &value())
            } else {
                LINES[m.v % LINES.len()].to_string()
            };
            out.insert(m.b % (out.len() + 1), line);
        }
        9 => {
            let mut bytes = (out.join("\n") + "\n").into_bytes();
            let k = m.a % bytes.len();
            bytes[k] = (m.v % 256) as u8;
            return bytes;
        }
        10 => {
            let mut bytes = (out.join("\n") + "\n").into_bytes();
            bytes.truncate(m.a % (bytes.len() + 1));
            return bytes;
        }
        _ => {
            // Several bytes flipped at once
            let mut bytes = (out.join("\n") + "\n").into_bytes();
            let len = bytes.len();
            for i in 0..4 {
                let k = (m.a + i * m.b) % len;
                bytes[k] ^= 1 << ((m.v + i) % 8);
            }
            return bytes;
        }
    }
    (out.join("\n") + "\n").into_bytes()
}

// ---- fixtures -------------------------------------------------------------------------------

/// The real Python interpreter (not a pyenv shim: each render starts it).
fn python() -> &'static str {
    static P: OnceLock<String> = OnceLock::new();
    P.get_or_init(|| {
        let o = Command::new("python3")
            .args(["-c", "import sys; print(sys.executable)"])
            .output()
            .expect("python3 runs");
        let p = String::from_utf8_lossy(&o.stdout).trim().to_string();
        if p.is_empty() {
            "python3".into()
        } else {
            p
        }
    })
}

fn standin() -> String {
    format!(
        "'{}' '{}'",
        python(),
        crate::common::outside("standin_render.py").display()
    )
}

/// Renders with the stand-in renderer.
fn standin_render(out: &Path, width: u32, grid: u32) {
    let st = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "{} '{}' --width {width} --grid {grid}",
            standin(),
            out.display()
        ))
        .status()
        .unwrap();
    assert!(st.success());
}

/// The suite fixture: references with a manifest, an image, a scene, goldens blessed by a first
/// `--update`; a second run passes (exit 0).
fn suite_template() -> &'static Path {
    static T: OnceLock<PathBuf> = OnceLock::new();
    T.get_or_init(|| {
        let d = fresh("suite-template");
        std::fs::create_dir_all(d.join("refs")).unwrap();
        std::fs::create_dir_all(d.join("img")).unwrap();
        std::fs::create_dir_all(d.join("tmp")).unwrap();
        let mut files = serde_json::Map::new();
        for t in ["a", "b", "c"] {
            let p = d.join("refs").join(format!("{t}.exr"));
            standin_render(&p, 24, 2);
            files.insert(
                format!("{t}.exr"),
                serde_json::json!({
                    "renderer": "standin", "version": "1", "width": 24, "grid": 2,
                    "commands": ["standin_render.py"],
                    "sha256": rayproof::golden::sha256_file(&p).unwrap(),
                }),
            );
        }
        std::fs::copy(d.join("refs/c.exr"), d.join("img/c.exr")).unwrap();
        std::fs::write(
            d.join("refs/manifest.json"),
            serde_json::to_string_pretty(&serde_json::json!({ "scene": "none", "files": files }))
                .unwrap()
                + "\n",
        )
        .unwrap();
        // A small scene for the test rayproof renders
        let scene = std::fs::read_to_string(root().join("reference/scenes/diffuse.toml"))
            .unwrap()
            .replace("width = 256", "width = 16")
            .replace("height = 256", "height = 16")
            .replace("grid = 8", "grid = 1");
        std::fs::write(d.join("scene.toml"), scene).unwrap();
        let suite = format!(
            r#"[suite]
name = "fuzz"
renderer = "{r} {{out}} --width {{width}} --grid {{grid}}"
goldens = "goldens"
timeout = 2

[thresholds]
fail = 0.01
failpercent = 0.1

[golden_thresholds]
fail = 1e-6

[[test]]
name = "a"
[[test.reference]]
name = "ext"
path = "refs/a.exr"

[[test]]
name = "b"
command = "{r} {{out}} --width {{width}} --grid {{grid}} --variance {{variance}}"
variance = "{{variance}}"
variance_spp = 4
thresholds = {{ max_mean = 0.01, significance = 0.01 }}
[[test.reference]]
name = "ext"
path = "refs/b.exr"
required = true
[[test.reference]]
name = "opt"
path = "refs/missing.exr"
required = false

[[test]]
name = "c"
image = "img/c.exr"
grid = 2
golden = "goldens/c-golden.exr"
[[test.reference]]
name = "ext"
path = "refs/c.exr"
thresholds = {{ failpercent = 0.2, max_flip = 0.5 }}

[[test]]
name = "d"
scene = "scene.toml"
width = 16
grid = 1
allow_nonfinite = false
rayproof = {{ method = "promote", precision = "f64" }}
golden_thresholds = {{ fail = 1e-5 }}
"#,
            r = standin()
        );
        std::fs::write(d.join("suite.toml"), suite).unwrap();
        let args = os(&["check", "--suite", "suite.toml", "--update"]);
        let r = run_in(&d, &args);
        assert_eq!(
            r.code,
            Some(0),
            "the fixture's first --update: {}{}",
            r.stdout,
            r.stderr
        );
        let r = run_in(&d, &args);
        assert_eq!(
            r.code,
            Some(0),
            "the fixture passes: {}{}",
            r.stdout,
            r.stderr
        );
        assert!(d.join("goldens/manifest.json").is_file());
        std::fs::write(d.join("rows.json"), b"previous").unwrap();
        d
    })
}

/// The built-in table's rcp rules and measurements: a user table that passes on its own.
fn rcp_tolerances() -> &'static String {
    static T: OnceLock<String> = OnceLock::new();
    T.get_or_init(|| {
        let table = rayproof::audit::tolerance::BUILT_IN;
        let mut out = String::from("# the built-in rules for rcp, as a user's table\n");
        for block in table.split("[[rule]]").skip(1) {
            let block = block.split("\n[measured]").next().unwrap();
            let body: Vec<&str> = block
                .lines()
                .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
                .collect();
            if body.iter().any(|l| l.trim() == "shape = \"rcp\"") {
                out += "\n[[rule]]\n";
                out += &(body.join("\n") + "\n");
            }
        }
        out += "\n[measured]\n";
        let measured = table.split("\n[measured]").nth(1).unwrap();
        for l in measured.lines().filter(|l| l.starts_with("\"rcp ")) {
            out += l;
            out.push('\n');
        }
        out
    })
}

/// The `--exec` child (and the answer maker of `score`'s fixture): reads case lines, answers
/// them (`sphere`: the textbook quadratic; `rcp`: 1/x), then mutates its answers, its output,
/// its exit or its timing as `KIND AT VAL` say.
fn child() -> &'static Path {
    static C: OnceLock<PathBuf> = OnceLock::new();
    C.get_or_init(|| {
        let d = fresh("child");
        let esc = |s: &str| -> String {
            let mut o = String::from("\"");
            for b in s.bytes() {
                match b {
                    b'"' => o += "\\\"",
                    b'\\' => o += "\\\\",
                    0x20..=0x7e => o.push(b as char),
                    _ => o += &format!("\\{b:03o}"),
                }
            }
            o + "\""
        };
        let tokens: Vec<String> = TOKENS.iter().map(|t| esc(t)).collect();
        let lines: Vec<String> = LINES.iter().map(|t| esc(t)).collect();
        let src = CHILD_C
            .replace("@TOKENS@", &tokens.join(", "))
            .replace("@LINES@", &lines.join(", "));
        let c = d.join("child.c");
        std::fs::write(&c, src).unwrap();
        let exe = d.join("child");
        let o = Command::new("cc")
            .args(["-O2", "-o"])
            .arg(&exe)
            .arg(&c)
            .arg("-lm")
            .output()
            .expect("a C compiler (cc)");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        exe
    })
}

const CHILD_C: &str = r#"
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *TOKENS[] = { @TOKENS@ };
static const char *LINES[] = { @LINES@ };
#define NT (sizeof TOKENS / sizeof *TOKENS)
#define NL (sizeof LINES / sizeof *LINES)

static char *answer(const char *shape, char *line) {
    char *out = malloc(128);
    double x[16];
    int n = 0;
    char *save = 0, *w = strtok_r(line, " \t\r\n", &save);
    while ((w = strtok_r(0, " \t\r\n", &save)) && n < 16) x[n++] = strtod(w, 0);
    if (!strcmp(shape, "rcp")) {
        if (n < 1 || !isfinite(x[0]) || x[0] == 0) strcpy(out, "0");
        else snprintf(out, 128, "1 %a", 1.0 / x[0]);
        return out;
    }
    if (n < 10) { strcpy(out, "0"); return out; }
    double f[3], a = 0, b = 0, c = 0;
    for (int i = 0; i < 3; i++) f[i] = x[i] - x[6 + i];
    for (int i = 0; i < 3; i++) { a += x[3 + i] * x[3 + i]; b += x[3 + i] * f[i]; c += f[i] * f[i]; }
    b *= 2; c -= x[9] * x[9];
    double disc = b * b - 4 * a * c;
    if (!(disc > 0)) { strcpy(out, "0"); return out; }
    double s = sqrt(disc), t0 = (-b - s) / (2 * a), t1 = (-b + s) / (2 * a);
    double lo = t0 < t1 ? t0 : t1, hi = t0 < t1 ? t1 : t0;
    if (lo > 0) snprintf(out, 128, "1 %a", lo);
    else if (hi > 0) snprintf(out, 128, "1 %a", hi);
    else strcpy(out, "0");
    return out;
}

static char *cat(const char *a, const char *b, const char *c) {
    size_t n = strlen(a) + strlen(b) + strlen(c) + 1;
    char *o = malloc(n);
    snprintf(o, n, "%s%s%s", a, b, c);
    return o;
}

static void put(const char *s, size_t n) {
    while (n > 0) {
        ssize_t k = write(1, s, n);
        if (k <= 0) return;
        s += k; n -= k;
    }
}

int main(int argc, char **argv) {
    if (argc < 5) return 64;
    const char *shape = argv[1];
    long kind = atol(argv[2]), at = atol(argv[3]), val = atol(argv[4]);
    if (kind == 16) return 0; /* answers nothing, reads nothing */
    size_t cap = 1024, n = 0;
    char **ans = malloc(cap * sizeof *ans);
    char buf[65536];
    while (fgets(buf, sizeof buf, stdin)) {
        if (n + 4 >= cap) ans = realloc(ans, (cap *= 2) * sizeof *ans);
        ans[n++] = answer(shape, buf);
    }
    size_t k = n ? (size_t)at % n : 0;
    const char *tok = TOKENS[val % NT];
    char *hundred = 0;
    switch (kind) {
    case 1: if (n) ans[k] = (char *)LINES[val % NL]; break;
    case 2: if (n) { char *sp = strchr(ans[k], ' '); ans[k] = cat(tok, sp ? sp : "", ""); } break;
    case 3: if (n) ans[k] = cat("1 ", tok, ""); break;
    case 4: if (n) { memmove(ans + k, ans + k + 1, (n - k - 1) * sizeof *ans); n--; } break;
    case 5: if (n) { memmove(ans + k + 1, ans + k, (n - k) * sizeof *ans); n++; } break;
    case 6: if (n > 1) { char *t = ans[k]; ans[k] = ans[(k + 1) % n]; ans[(k + 1) % n] = t; } break;
    case 9: if (n) ans[k] = cat(ans[k], " ", tok); break;
    case 18: if (n) { ans[k] = cat(ans[k], val % 2 ? "\377" : "", ""); if (!(val % 2)) ans[k][0] = 0; } break;
    case 19:
        hundred = malloc(100010);
        strcpy(hundred, "1 0.");
        memset(hundred + 4, '0', 100000);
        strcpy(hundred + 100004, "1");
        if (n) ans[k] = hundred;
        break;
    }
    /* The whole output */
    size_t len = 0;
    for (size_t i = 0; i < n; i++) len += strlen(ans[i]) + 3;
    char *o = malloc(len + 1), *p = o;
    for (size_t i = 0; i < n; i++) {
        size_t l = strlen(ans[i]);
        if (kind == 18 && i == k && !(val % 2)) { memcpy(p, "1 \0 2", 5); p += 5; }
        else { memcpy(p, ans[i], l); p += l; }
        if (kind == 14) { memcpy(p, "\r\n\n", 3); p += 3; } else *p++ = '\n';
    }
    size_t olen = p - o;
    switch (kind) {
    case 7: olen = olen ? (size_t)(at * 7919) % (olen + 1) : 0; break;
    case 8: if (olen) o[(size_t)(at * 7919) % olen] = (char)(val & 255); break;
    case 11: {
        size_t lines = n ? (size_t)at % (n + 1) : 0, cut = 0;
        for (size_t i = 0; i < lines; i++) cut += strlen(ans[i]) + 1;
        put(o, cut < olen ? cut : olen);
        int sigs[] = { SIGSEGV, SIGKILL, SIGABRT, SIGPIPE, SIGTERM };
        raise(sigs[val % 5]);
        return 99;
    }
    case 13: {
        size_t big = 17u << 20;
        char *b = malloc(big);
        memset(b, '1', big);
        put(b, big);
        return 0;
    }
    case 15:
        if (val % 8 == 0) { sleep(10); break; }
        fprintf(stderr, "warning: child is slow today\n");
        break;
    case 17:
        if (fork() == 0) { setsid(); sleep(30); _exit(0); }
        break;
    }
    put(o, olen);
    if (kind == 10) return (int)(val % 256);
    if (kind == 12) {
        for (long i = 0; i < val % 50 + 2; i++) fprintf(stderr, "error: child complaint %ld\nsecond line\n", i);
        return 1;
    }
    return 0;
}
"#;

/// Answers a file of case lines (`PRECISION INPUT…`) with the child, unmutated.
fn answers_for(shape: &str, case_lines: &str) -> String {
    use std::io::Write;
    let mut c = Command::new(child())
        .args([shape, "0", "0", "0"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    c.stdin
        .take()
        .unwrap()
        .write_all(case_lines.as_bytes())
        .unwrap();
    let o = c.wait_with_output().unwrap();
    assert!(o.status.success());
    String::from_utf8(o.stdout).unwrap()
}

/// A cases file of `shape` and the answers the child gives to it; `score` passes or fails on
/// them, never errs.
fn score_template(shape: &str) -> &'static (String, String) {
    static T: OnceLock<Vec<(String, (String, String))>> = OnceLock::new();
    let all = T.get_or_init(|| {
        ["rcp", "sphere"]
            .iter()
            .map(|s| {
                let d = fresh(&format!("score-template-{s}"));
                let r = run_in(
                    &d,
                    &os(&["cases", "--shape", s, "--cases", "3", "-o", "cases.txt"]),
                );
                assert_eq!(r.code, Some(0), "{}", r.stderr);
                let cases = std::fs::read_to_string(d.join("cases.txt")).unwrap();
                // The child reads PRECISION INPUT…: drop the class and the index
                let lines: String = cases
                    .lines()
                    .filter(|l| !l.starts_with('#'))
                    .map(|l| {
                        let w: Vec<&str> = l.split_whitespace().collect();
                        format!("{} {}\n", w[0], w[3..].join(" "))
                    })
                    .collect();
                let answers = answers_for(s, &lines);
                std::fs::write(d.join("answers.txt"), &answers).unwrap();
                let r = run_in(
                    &d,
                    &os(&["score", "--cases", "cases.txt", "--answers", "answers.txt"]),
                );
                assert!(
                    matches!(r.code, Some(0 | 1)),
                    "the fixture scores: {}{}",
                    r.stdout,
                    r.stderr
                );
                (s.to_string(), (cases, answers))
            })
            .collect()
    });
    &all.iter().find(|(s, _)| s == shape).unwrap().1
}

// ---- 1. suite files and golden manifests ---------------------------------------------------

/// The inputs of the suite fixture that no run may change.
fn suite_protected(p: &Path) -> bool {
    [
        "suite.toml",
        "refs/a.exr",
        "refs/b.exr",
        "refs/c.exr",
        "img/c.exr",
        "scene.toml",
    ]
    .iter()
    .any(|q| p == Path::new(q))
        || p.starts_with("tmp")
}

/// Manifest entries of images a run did not write are left as they were. An image the run
/// wrote is one whose bytes changed, or one it says it `updated` (a stale golden is re-blessed
/// with the same bytes: its entry follows the scene).
fn manifests_keep_entries(
    before: &Snapshot,
    after: &Snapshot,
    updated: &[PathBuf],
) -> Result<(), String> {
    for (p, n) in after {
        if p.file_name().is_none_or(|f| f != "manifest.json") {
            continue;
        }
        let (Some(Node::File(old)), Node::File(new)) = (before.get(p), n) else {
            continue;
        };
        if old == new {
            continue;
        }
        let (Ok(old), Ok(new)) = (
            serde_json::from_slice::<serde_json::Value>(old),
            serde_json::from_slice::<serde_json::Value>(new),
        ) else {
            return Err(format!("{}: rewritten, and not as JSON", p.display()));
        };
        let dir = p.parent().unwrap();
        for (file, entry) in old["files"].as_object().into_iter().flatten() {
            let image = dir.join(file);
            if before.get(&image) == after.get(&image)
                && !updated.contains(&image)
                && new["files"].get(file) != Some(entry)
            {
                return Err(format!(
                    "{}: the entry of {file}, an image the run did not write, changed: {entry} → {:?}",
                    p.display(),
                    new["files"].get(file)
                ));
            }
        }
    }
    Ok(())
}

fn suite_case(target: usize, m: &Mutation) -> Result<(), TestCaseError> {
    let d = fresh("suite");
    copy_tree(suite_template(), &d);
    let (file, style, hostile) = match target {
        0..=2 => ("suite.toml", Style::Toml, toml_hostile()),
        3 => ("refs/manifest.json", Style::Json, json_hostile()),
        _ => ("goldens/manifest.json", Style::Json, json_hostile()),
    };
    let text = std::fs::read_to_string(d.join(file)).unwrap();
    let input = mutate(&text, m, style, hostile);
    std::fs::write(d.join(file), &input).unwrap();
    let args = os(&[
        "check",
        "--suite",
        "suite.toml",
        "--update",
        "--json",
        "rows.json",
    ]);
    let before = snapshot(&d);
    let r = run_in(&d, &args);
    let after = snapshot(&d);
    // The goldens --update may write, as the suite names them (read by the library: none when
    // the suite does not validate), their manifests and the directories that hold them
    let goldens: Vec<PathBuf> = rayproof::golden::Suite::load(&d.join("suite.toml"), None)
        .map(|s| {
            s.tests
                .iter()
                .filter_map(|t| t.golden.as_ref())
                .filter_map(|(g, _)| normalise(g).strip_prefix(&d).ok().map(Path::to_path_buf))
                .collect()
        })
        .unwrap_or_default();
    let may_write = |p: &Path, code: i32| {
        if p == Path::new("rows.json") {
            return true;
        }
        // A refusal writes its reports, never a golden (--update is withheld)
        code != 3
            && !suite_protected(p)
            && goldens.iter().any(|g| {
                p == g
                    || (p.file_name().is_some_and(|f| f == "manifest.json")
                        && p.parent() == g.parent())
                    || (g.starts_with(p) && matches!(after.get(p), Some(Node::Dir)))
            })
    };
    let e = Expect {
        codes: &[0, 1, 2, 3],
        errors: &[2],
        maybe_errors: &[3],
        may_write: &may_write,
    };
    let mut res = judge(&r, &e, &before, &after);
    if res.is_ok() && before != after {
        let updated: Vec<PathBuf> = r
            .stdout
            .lines()
            .filter_map(|l| l.strip_prefix("updated "))
            .map(|p| normalise(Path::new(p)))
            .collect();
        res = manifests_keep_entries(&before, &after, &updated);
    }
    if res.is_ok() && before.get(Path::new("rows.json")) != after.get(Path::new("rows.json")) {
        let rows = std::fs::read(d.join("rows.json")).unwrap();
        if !serde_json::from_slice::<serde_json::Value>(&rows).is_ok_and(|v| v.is_array()) {
            res = Err("--json wrote something that is not a JSON array of rows".into());
        }
    }
    let replay = format!("suite {target} {} {} {} {}", m.kind, m.a, m.b, m.v);
    let res = res.map_err(|why| {
        fail(
            &format!("suite surface ({file} mutated: {m:?})"),
            &replay,
            &args,
            &[(file, text.as_bytes(), &input)],
            why,
        )
    });
    verdict("suite", &input, res)
}

proptest! {
    #![proptest_config(config("suite", 70, 0x5_17e))]

    #[test]
    fn a_mutated_suite_or_manifest_is_checked_or_refused_in_one_line(target in 0usize..5, m in mutation()) {
        suite_case(target, &m)?;
    }
}

// ---- 2. tolerance files -------------------------------------------------------------------

fn tolerance_case(m: &Mutation) -> Result<(), TestCaseError> {
    let d = fresh("tolerances");
    std::fs::create_dir_all(d.join("tmp")).unwrap();
    let input = mutate(rcp_tolerances(), m, Style::Toml, toml_hostile());
    std::fs::write(d.join("t.toml"), &input).unwrap();
    // A previous run's report: what --json and --markdown may replace
    std::fs::write(d.join("out.json"), b"{\"previous\": true}").unwrap();
    std::fs::write(d.join("out.md"), b"# rayproof audit\n\nprevious\n").unwrap();
    let args = os(&[
        "audit",
        "--shape",
        "rcp",
        "--cases",
        "200",
        "--tolerances",
        "t.toml",
        "--json",
        "out.json",
        "--markdown",
        "out.md",
    ]);
    let before = snapshot(&d);
    let r = run_in(&d, &args);
    let after = snapshot(&d);
    let may_write = |p: &Path, _: i32| p == Path::new("out.json") || p == Path::new("out.md");
    let e = Expect {
        codes: &[0, 1, 2],
        errors: &[2],
        maybe_errors: &[],
        may_write: &may_write,
    };
    let mut res = judge(&r, &e, &before, &after);
    if res.is_ok() && matches!(r.code, Some(0 | 1)) {
        let json = std::fs::read(d.join("out.json")).unwrap();
        if serde_json::from_slice::<serde_json::Value>(&json).is_err() {
            res = Err("the report is not JSON".into());
        }
    }
    let replay = format!("tolerances {} {} {} {}", m.kind, m.a, m.b, m.v);
    let res = res.map_err(|why| {
        fail(
            &format!("tolerance surface ({m:?})"),
            &replay,
            &args,
            &[("t.toml", rcp_tolerances().as_bytes(), &input)],
            why,
        )
    });
    verdict("tolerances", &input, res)
}

#[test]
fn the_rcp_tolerance_fixture_passes_on_its_own() {
    let d = fresh("tolerances-fixture");
    std::fs::write(d.join("t.toml"), rcp_tolerances()).unwrap();
    let r = run_in(
        &d,
        &os(&[
            "audit",
            "--shape",
            "rcp",
            "--cases",
            "200",
            "--tolerances",
            "t.toml",
        ]),
    );
    assert_eq!(r.code, Some(0), "{}{}", r.stdout, r.stderr);
}

/// A measurement of 10^7 cases: statrs' Beta inverse never ended there (the audit hung).
#[test]
fn a_measurement_of_ten_million_cases_is_judged_in_time() {
    let d = fresh("tolerances-1e7");
    let table = rcp_tolerances().replace(
        "\"rcp x0+newton f32 start_out_of_bound\" = [20000, 20000]",
        "\"rcp x0+newton f32 start_out_of_bound\" = [10000000, 10000000]",
    );
    assert_ne!(&table, rcp_tolerances());
    std::fs::write(d.join("t.toml"), table).unwrap();
    let r = run_in(
        &d,
        &os(&[
            "audit",
            "--shape",
            "rcp",
            "--cases",
            "200",
            "--tolerances",
            "t.toml",
        ]),
    );
    assert!(
        !r.timed_out && r.code == Some(0),
        "exit {:?} (timed out: {}): {}{}",
        r.code,
        r.timed_out,
        r.stdout,
        r.stderr
    );
}

proptest! {
    #![proptest_config(config("tolerances", 70, 0x7013))]

    #[test]
    fn a_mutated_tolerance_file_judges_or_is_refused_in_one_line(m in mutation()) {
        tolerance_case(&m)?;
    }
}

// ---- 3. cases and answers files -----------------------------------------------------------

fn score_case(shape: usize, target: usize, m: &Mutation) -> Result<(), TestCaseError> {
    let shape = ["rcp", "sphere"][shape];
    let (orig_cases, orig_answers) = score_template(shape);
    let (cases, answers) = (orig_cases, orig_answers);
    let d = fresh("score");
    std::fs::create_dir_all(d.join("tmp")).unwrap();
    let (cases, answers) = match target {
        0 => (
            mutate(cases, m, Style::Words, &[]),
            answers.as_bytes().to_vec(),
        ),
        _ => (
            cases.as_bytes().to_vec(),
            mutate(answers, m, Style::Words, &[]),
        ),
    };
    std::fs::write(d.join("cases.txt"), &cases).unwrap();
    std::fs::write(d.join("answers.txt"), &answers).unwrap();
    std::fs::write(d.join("out.json"), b"{\"previous\": true}").unwrap();
    let args = os(&[
        "score",
        "--cases",
        "cases.txt",
        "--answers",
        "answers.txt",
        "--json",
        "out.json",
    ]);
    let before = snapshot(&d);
    let r = run_in(&d, &args);
    let after = snapshot(&d);
    let may_write = |p: &Path, _: i32| p == Path::new("out.json");
    let e = Expect {
        codes: &[0, 1, 2],
        errors: &[2],
        maybe_errors: &[],
        may_write: &may_write,
    };
    let res = judge(&r, &e, &before, &after).map_err(|why| {
        fail(
            &format!(
                "score surface ({shape}, {} mutated: {m:?})",
                ["cases.txt", "answers.txt"][target]
            ),
            &format!(
                "score {} {target} {} {} {} {}",
                ["0", "1"][(shape == "sphere") as usize],
                m.kind,
                m.a,
                m.b,
                m.v
            ),
            &args,
            &[
                ("cases.txt", orig_cases.as_bytes(), &cases),
                ("answers.txt", orig_answers.as_bytes(), &answers),
            ],
            why,
        )
    });
    verdict("score", if target == 0 { &cases } else { &answers }, res)
}

proptest! {
    #![proptest_config(config("score", 80, 0x5c0e))]

    #[test]
    fn mutated_cases_or_answers_are_scored_or_refused_in_one_line(shape in 0usize..2, target in 0usize..2, m in mutation()) {
        score_case(shape, target, &m)?;
    }
}

// ---- 4. --exec answers --------------------------------------------------------------------

fn exec_case(kind: usize, at: usize, val: usize) -> Result<(), TestCaseError> {
    let d = fresh("exec");
    std::fs::create_dir_all(d.join("tmp")).unwrap();
    std::fs::write(d.join("out.json"), b"{\"previous\": true}").unwrap();
    let cmd = format!("'{}' sphere {kind} {at} {val}", child().display());
    let mut args = os(&[
        "audit",
        "--shape",
        "sphere",
        "--cases",
        "50",
        "--exec",
        &cmd,
        "--timeout",
        "5",
        "--json",
        "out.json",
    ]);
    // The child answers at exit: kept for the run, rayproof finds that out on the first batch
    // after a grace of 2.6 s, then starts it per batch. Three cases in four start per batch at
    // once (the same answers reach the same reader, 1.2 s a case instead of 3.8 s); the fourth
    // takes the way through the grace
    if !(at + val).is_multiple_of(4) {
        args.push("--exec-per-batch".into());
    }
    let before = snapshot(&d);
    let r = run_in(&d, &args);
    let after = snapshot(&d);
    let may_write = |p: &Path, _: i32| p == Path::new("out.json");
    let e = Expect {
        codes: &[0, 1, 4],
        errors: &[2, 3, 4],
        maybe_errors: &[],
        may_write: &may_write,
    };
    let res = judge(&r, &e, &before, &after).map_err(|why| {
        fail(
            &format!("exec surface (child kind {kind} at {at} val {val})"),
            &format!("exec {kind} {at} {val}"),
            &args,
            &[],
            why,
        )
    });
    verdict("exec", cmd.as_bytes(), res)
}

#[test]
fn the_unmutated_exec_child_is_audited() {
    let d = fresh("exec-fixture");
    let cmd = format!("'{}' sphere 0 0 0", child().display());
    let r = run_in(
        &d,
        &os(&[
            "audit",
            "--shape",
            "sphere",
            "--cases",
            "50",
            "--exec",
            &cmd,
            "--timeout",
            "5",
        ]),
    );
    assert!(matches!(r.code, Some(0 | 1)), "{}{}", r.stdout, r.stderr);
    assert!(!r.stderr.contains("error"), "{}", r.stderr);
}

proptest! {
    #![proptest_config(config("exec", 80, 0xe8ec))]

    #[test]
    fn mutated_exec_answers_are_judged_or_stop_in_one_line(kind in 0usize..20, at in 0usize..1000, val in 0usize..1000) {
        exec_case(kind, at, val)?;
    }
}

// ---- 5. output paths ----------------------------------------------------------------------

/// The directory the output-path runs see: the inputs of four commands, and things an output
/// must never replace or write through.
fn paths_fixture(d: &Path) {
    let (cases, answers) = score_template("rcp");
    std::fs::create_dir_all(d.join("tmp")).unwrap();
    std::fs::write(d.join("t.toml"), rcp_tolerances()).unwrap();
    std::fs::write(d.join("cases.txt"), cases).unwrap();
    std::fs::write(d.join("answers.txt"), answers).unwrap();
    let t = suite_template();
    std::fs::copy(t.join("refs/a.exr"), d.join("ref.exr")).unwrap();
    std::fs::copy(t.join("refs/a.exr"), d.join("img.exr")).unwrap();
    std::fs::write(
        d.join("s.toml"),
        "[[test]]\nname = \"t\"\nimage = \"img.exr\"\ngolden = false\n[[test.reference]]\nname = \"r\"\npath = \"ref.exr\"\n",
    )
    .unwrap();
    std::fs::write(d.join("victim.txt"), b"a user's file").unwrap();
    std::fs::create_dir_all(d.join("adir")).unwrap();
    std::fs::write(d.join("adir/inside.txt"), b"a user's file in a directory").unwrap();
    std::fs::create_dir_all(d.join("made")).unwrap();
    std::fs::write(
        d.join("made").join(rayproof::output::MARKER),
        b"made by rayproof\n",
    )
    .unwrap();
    std::fs::write(d.join("made/index.html"), b"an old report").unwrap();
    let link = |target: &str, name: &str| std::os::unix::fs::symlink(target, d.join(name)).unwrap();
    link("victim.txt", "link-file");
    link("adir", "link-dir");
    link("nowhere/x", "dangling");
    link("/dev/full", "link-devfull");
    link("t.toml", "link-input");
    std::fs::hard_link(d.join("t.toml"), d.join("hard-t.toml")).unwrap();
    std::fs::hard_link(d.join("cases.txt"), d.join("hard-cases.txt")).unwrap();
    let fifo = std::ffi::CString::new(d.join("fifo").as_os_str().as_bytes()).unwrap();
    // SAFETY: mkfifo with a NUL-terminated path
    assert_eq!(unsafe { libc::mkfifo(fifo.as_ptr(), 0o644) }, 0);
}

/// Hostile output paths (relative to the case directory unless absolute); `None`: a fresh
/// ordinary path.
fn hostile_path(k: usize) -> Option<OsString> {
    let list: Vec<OsString> = vec![
        "adir".into(),
        "adir/".into(),
        "made".into(),
        "victim.txt".into(),
        "link-file".into(),
        "link-dir".into(),
        "link-dir/via-link.json".into(),
        "dangling".into(),
        "link-devfull".into(),
        "link-input".into(),
        "fifo".into(),
        "t.toml".into(),
        "cases.txt".into(),
        "answers.txt".into(),
        "s.toml".into(),
        "img.exr".into(),
        "ref.exr".into(),
        "hard-t.toml".into(),
        "hard-cases.txt".into(),
        "./t.toml".into(),
        "adir/../cases.txt".into(),
        "/dev/full".into(),
        "/dev/null".into(),
        "/dev/stdout".into(),
        "/proc/self/status".into(),
        "/proc/version".into(),
        "/proc/nonexistent/x.json".into(),
        "/sys/x.json".into(),
        "/".into(),
        "".into(),
        ".".into(),
        "..".into(),
        "nodir/x.json".into(),
        "adir/nodir/x.json".into(),
        "link-file/x.json".into(),
        "victim.txt/x.json".into(),
        "victim.txt/".into(),
        "fresh.json/".into(),
        "fresh.json/.".into(),
        "made/".into(),
        "a b.json".into(),
        "new\nline.json".into(),
        "nodir\nsecond line/x.json".into(),
        "tab\t.json".into(),
        "quote'\"$(touch pwned).json".into(),
        "-dash.json".into(),
        "ü-ñ-\u{202e}.json".into(),
        OsString::from_vec(b"bad-\xff\xfe.json".to_vec()),
        ".hidden.json".into(),
        "x.json.".into(),
        "adir/../up.json".into(),
        long('x', 200).into(),
        long('y', 220).into(),
        long('z', 255).into(),
        long('w', 256).into(),
        format!("{}x.json", "d/".repeat(2100)).into(),
        format!("{}x.json", "./".repeat(2100)).into(),
    ];
    list.get(k).cloned()
}

/// How many [`hostile_path`]s there are.
fn hostile_paths() -> usize {
    (0..).find(|&k| hostile_path(k).is_none()).unwrap()
}

fn paths_case(command: usize, picks: &[usize]) -> Result<(), TestCaseError> {
    // A directory per test thread: two tests run paths cases side by side
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    thread_local! {
        static SLOT: usize = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
    let d = fresh(&format!("paths-{}", SLOT.with(|s| *s)));
    paths_fixture(&d);
    let n = hostile_paths();
    // A pick past the hostile list is a fresh ordinary path
    let path = |slot: usize, ext: &str| -> OsString {
        let k = picks[slot];
        hostile_path(k % (n + n / 3)).unwrap_or_else(|| format!("fresh-{slot}.{ext}").into())
    };
    let (mut args, flags): (Vec<OsString>, Vec<(&str, &str)>) = match command % 4 {
        0 => (
            os(&[
                "audit",
                "--shape",
                "rcp",
                "--cases",
                "20",
                "--tolerances",
                "t.toml",
            ]),
            vec![("--json", "json"), ("--markdown", "md")],
        ),
        1 => (
            os(&["cases", "--shape", "rcp", "--cases", "2"]),
            vec![("-o", "txt")],
        ),
        2 => (
            os(&["score", "--cases", "cases.txt", "--answers", "answers.txt"]),
            vec![("--json", "json"), ("--markdown", "md")],
        ),
        _ => (
            os(&["check", "--suite", "s.toml"]),
            vec![
                ("--report", "d"),
                ("--json", "json"),
                ("--junit", "xml"),
                ("--markdown", "md"),
            ],
        ),
    };
    // Every flag of the command, or only some (the first always)
    let mut outputs: Vec<(&str, OsString)> = vec![];
    for (i, (flag, ext)) in flags.iter().enumerate() {
        if i > 0 && picks[4 + i].is_multiple_of(3) {
            continue;
        }
        let p = path(i, ext);
        args.push(flag.into());
        args.push(p.clone());
        outputs.push((flag, p));
    }
    // The same path for two outputs, now and then
    if outputs.len() > 1 && picks[4].is_multiple_of(7) {
        let p = outputs[0].1.clone();
        args.push(outputs[1].0.into());
        args.push(p.clone());
        outputs.push((outputs[1].0, p));
    }
    let before = snapshot(&d);
    let r = run_in(&d, &args);
    let after = snapshot(&d);
    // The intended outputs, as paths relative to the case directory (through a linked directory)
    let canon_d = std::fs::canonicalize(&d).unwrap();
    let intended: Vec<(bool, Option<PathBuf>)> = outputs
        .iter()
        .map(|(flag, p)| {
            let full = normalise(&d.join(p));
            let parent = full
                .parent()
                .map(|q| std::fs::canonicalize(q).unwrap_or(q.to_path_buf()));
            let real = match (parent, full.file_name()) {
                (Some(q), Some(f)) => q.join(f),
                _ => full.clone(),
            };
            (
                *flag == "--report",
                real.strip_prefix(&canon_d).ok().map(Path::to_path_buf),
            )
        })
        .collect();
    // `check` makes an output's missing directories (issue 48): those may appear too
    let may_write = |p: &Path, _: i32| {
        intended.iter().any(|(dir, q)| match q {
            Some(q) if *dir => p.starts_with(q),
            Some(q) => p == q,
            None => false,
        }) || (command % 4 == 3
            && intended
                .iter()
                .any(|(_, q)| q.as_ref().is_some_and(|q| q.starts_with(p) && q != p)))
    };
    let codes: &[i32] = if command % 4 == 3 {
        &[0, 1, 2, 3]
    } else {
        &[0, 1, 2]
    };
    let e = Expect {
        codes,
        errors: &[2],
        maybe_errors: &[3],
        may_write: &may_write,
    };
    let mut res = judge(&r, &e, &before, &after);
    // A run that succeeded wrote every output it was given
    if res.is_ok() && matches!(r.code, Some(0 | 1)) {
        for ((flag, p), (dir, q)) in outputs.iter().zip(&intended) {
            let ok = match q {
                Some(q) if *dir => d.join(q).join("index.html").is_file(),
                Some(q) => matches!(after.get(q), Some(Node::File(_))),
                None => false,
            };
            if !ok {
                res = Err(format!(
                    "exit {:?}, but {flag} {p:?} was not written (stdout: {})",
                    r.code,
                    tail(&r.stdout, 800)
                ));
                break;
            }
        }
    }
    let replay = format!(
        "paths {command} {}",
        picks
            .iter()
            .map(|p| p.to_string())
            .collect::<Vec<_>>()
            .join(" ")
    );
    let res = res.map_err(|why| {
        fail(
            &format!("output-path surface (command {})", command % 4),
            &replay,
            &args,
            &[],
            why,
        )
    });
    verdict(
        "paths",
        &args
            .iter()
            .flat_map(|a| a.as_bytes().to_vec())
            .collect::<Vec<u8>>(),
        res,
    )
}

proptest! {
    #![proptest_config(config("paths", 80, 0x9a75))]

    #[test]
    fn hostile_output_paths_are_written_or_refused_in_one_line(command in 0usize..4, picks in proptest::collection::vec(0usize..1000, 8)) {
        paths_case(command, &picks)?;
    }
}

/// Every hostile path once, as each command's first output (the random cases mix them).
#[test]
fn every_hostile_output_path_once_per_command() {
    let n = hostile_paths();
    for command in 0..4 {
        for k in 0..n {
            let picks = [k, n, n, n, 1, 1, 1, 1];
            if let Err(e) = paths_case(command, &picks) {
                panic!("{e}");
            }
        }
    }
}

/// Replays one case: `RAYPROOF_FUZZ_REPLAY='SURFACE NUMBERS…'` as a failure prints it
/// (`suite TARGET KIND A B V`, `tolerances KIND A B V`, `score SHAPE TARGET KIND A B V`,
/// `exec KIND AT VAL`, `paths COMMAND P0 … P7`).
#[test]
#[ignore]
fn replay() {
    let spec =
        std::env::var("RAYPROOF_FUZZ_REPLAY").expect("RAYPROOF_FUZZ_REPLAY='SURFACE NUMBERS…'");
    let w: Vec<&str> = spec.split_whitespace().collect();
    let n: Vec<usize> = w[1..].iter().map(|x| x.parse().unwrap()).collect();
    let m = |k: usize| Mutation {
        kind: n[k],
        a: n[k + 1],
        b: n[k + 2],
        v: n[k + 3],
    };
    let r = match w[0] {
        "suite" => suite_case(n[0], &m(1)),
        "tolerances" => tolerance_case(&m(0)),
        "score" => score_case(n[0], n[1], &m(2)),
        "exec" => exec_case(n[0], n[1], n[2]),
        "paths" => paths_case(n[0], &n[1..]),
        s => panic!("no surface {s}"),
    };
    if let Err(e) = r {
        panic!("{e}");
    }
    eprintln!("{spec}: passes");
}
