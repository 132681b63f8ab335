//! Writing output files: the one way every command writes.
//!
//! - **All outputs of a run are staged and committed together** ([`Outputs`]): each file is
//!   written to a temporary sibling, each directory output (a report) is built in a temporary
//!   sibling directory, and only when the work is done are they renamed into place, together
//!   (a directory replaces its previous version in one atomic exchange, `renameat2`). If any
//!   write fails, or the set is dropped uncommitted, every temporary is removed and no output is
//!   touched.
//! - **Never over an input, never over what rayproof did not make.** A run declares its inputs
//!   ([`Outputs::reading`], [`check_outputs`]); an output that is one of them (the same file by
//!   path or by inode), or that is named twice, is refused before the work starts. An output path
//!   that exists and is not a regular file (a directory, a symbolic link, a FIFO, a device) is
//!   refused; a directory output replaces only a directory that rayproof made and that holds
//!   nothing else: its marker file [`MARKER`] lists what rayproof wrote there, and a file or
//!   directory put there since (goldens kept in a report directory) refuses the replacement. A
//!   directory output that is or holds an input or another output of the run, or any output
//!   inside an input directory, is refused before the work ([`check_outputs`]); paths are
//!   compared [`canonical`] (`g/../g/x` is `g/x`, links resolved).
//! - **Temporaries no user file can be mistaken for**: `.NAME.rayproof-PID-NONCE.tmp` (files) and
//!   `.NAME.rayproof-PID-NONCE.dir` (directories, which hold [`MARKER`]). What a killed run left is
//!   removed by the next run writing the same output: only regular files of that exact pattern,
//!   and only directories of that pattern that hold the marker, whose process no longer exists.
//! - **Signals**: SIGINT or SIGTERM stops the run. The handler kills the outside commands running
//!   ([`crate::process`]), waits for a commit in progress to finish whole (a commit that has not
//!   started never starts), removes every temporary and exits with 130. So an interrupted run
//!   leaves every old output byte-identical, or the run's new outputs all in place; never a mix.
//!   A SIGKILL cannot be caught: a commit of two or more outputs is decided in a journal
//!   before its first rename, and the next run finishes it ([`recover`], `journal.rs`); the
//!   temporaries of a run killed before its commit are removed by the next run.

use crate::process::{interrupted, wait_if_interrupted};
use anyhow::{bail, Context, Result};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

mod journal;
pub use journal::recover;

/// The file inside every directory rayproof makes as an output (a report): a directory without
/// it is never replaced, and a stale temporary directory without it is never removed.
pub const MARKER: &str = ".rayproof-output";

/// The temporaries being written now, removed by [`clean_up_on_signals`]'s handler.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Held while a commit renames its outputs: the signal handler waits for it.
static COMMIT: Mutex<()> = Mutex::new(());
/// Set once a commit has renamed an output into place: an interrupt after it must not say
/// that no output was replaced (a hostile run saw that in 7 of 50 SIGINTs of `check --update`).
static RENAMED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
/// Temporaries being created and written now (see [`staging`]).
static IN_FLIGHT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

fn live(f: impl FnOnce(&mut Vec<PathBuf>)) {
    if let Ok(mut v) = LIVE.lock() {
        f(&mut v);
    }
}

/// Removes a temporary that is no longer live and forgets it (a signal has nothing left to
/// clean).
fn discard(p: &Path) {
    remove_temporary(p);
    live(|v| v.retain(|q| q != p));
}

/// Removes a temporary: a file, or a directory with everything in it.
fn remove_temporary(p: &Path) {
    match std::fs::symlink_metadata(p) {
        Ok(m) if m.is_dir() => {
            // A writer may still add a file while it goes: try again
            for _ in 0..5 {
                if std::fs::remove_dir_all(p).is_ok() || !p.exists() {
                    break;
                }
            }
        }
        Ok(_) => {
            let _ = std::fs::remove_file(p);
        }
        Err(_) => {}
    }
}

/// On SIGINT or SIGTERM: stop the outside commands, let a commit in progress finish, remove
/// every temporary, exit with 130 (the shell's code for an interrupted command).
pub fn clean_up_on_signals() {
    let installed = ctrlc::set_handler(|| {
        // From now on no other thread decides how the run ends and no commit starts; the
        // outside commands running now, and all they started, go first
        crate::process::interrupt();
        // A commit in progress finishes whole
        let _commit = COMMIT.lock().unwrap_or_else(|e| e.into_inner());
        // Temporaries being written are finished first (a stuck writer is given up on)
        let start = std::time::Instant::now();
        while IN_FLIGHT.load(std::sync::atomic::Ordering::SeqCst) > 0
            && start.elapsed() < WRITE_GRACE
        {
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        live(|v| {
            for p in v.drain(..) {
                remove_temporary(&p);
            }
        });
        // An allocation that failed ends the run as an interrupt does, with its own line
        let oom = OUT_OF_MEMORY.load(std::sync::atomic::Ordering::SeqCst);
        if oom != 0 {
            eprintln!("error: {}", OutOfMemory(oom));
            std::process::exit(EXIT_OUT_OF_MEMORY as i32);
        }
        // Whether a commit replaced anything before the signal (it waited for the commit)
        if RENAMED.load(std::sync::atomic::Ordering::SeqCst) {
            eprintln!("error: interrupted after its outputs were written (all in place); temporary files removed");
        } else {
            eprintln!("error: interrupted; temporary files removed, no output replaced");
        }
        std::process::exit(130);
    });
    HANDLER.store(installed.is_ok(), std::sync::atomic::Ordering::SeqCst);
}

/// The exit code of a run that ran out of memory (sysexits' `EX_OSERR`).
pub const EXIT_OUT_OF_MEMORY: u8 = 71;

/// The size of an allocation that failed (0: none yet), for the interrupt handler.
static OUT_OF_MEMORY: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Whether [`clean_up_on_signals`] installed its handler.
static HANDLER: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// The line of a failed allocation (formatting it allocates nothing).
struct OutOfMemory(usize);

impl std::fmt::Display for OutOfMemory {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "out of memory: an allocation of {} bytes failed (the machine's memory or the process's \
             address-space limit, `ulimit -v`); temporary files removed, no output replaced",
            self.0
        )
    }
}

/// Ends the run because an allocation of `bytes` failed, for the binary's global allocator: one
/// line and exit [`EXIT_OUT_OF_MEMORY`], never an abort. The interrupt handler does it, so the
/// outside commands are killed and the temporaries removed as for SIGINT and no output is
/// replaced (a commit under way finishes whole). Where no handler was installed, or it has not
/// ended the process within 20 s (the handler waits up to 10 s for writers; a lock it needs
/// may be held by the thread that ran out), the line is written here and the process exits.
/// Allocates nothing itself.
pub fn out_of_memory(bytes: usize) -> ! {
    use std::sync::atomic::Ordering::SeqCst;
    let first = OUT_OF_MEMORY
        .compare_exchange(0, bytes.max(1), SeqCst, SeqCst)
        .is_ok();
    if HANDLER.load(SeqCst) {
        if first {
            // SAFETY: raise has no preconditions; the handler runs on its own thread
            unsafe { libc::raise(libc::SIGINT) };
        }
        std::thread::sleep(std::time::Duration::from_secs(20));
    }
    use std::io::Write;
    let _ = writeln!(
        std::io::stderr(),
        "error: {}",
        OutOfMemory(OUT_OF_MEMORY.load(SeqCst))
    );
    // SAFETY: _exit ends the process at once, running nothing that could allocate
    unsafe { libc::_exit(EXIT_OUT_OF_MEMORY as i32) }
}

/// Runs `f`, which creates and writes the temporary `path`, registered for removal on SIGINT or
/// SIGTERM. The handler waits (up to [`WRITE_GRACE`]) for every `f` under way before it removes
/// the temporaries: a writer between the handler's removal and its exit would otherwise create
/// its file again and leave it behind (seen once in about 60 interrupted renders). Started after
/// the signal, `f` does not run.
fn staging<T>(path: &Path, f: impl FnOnce() -> T) -> T {
    use std::sync::atomic::Ordering::SeqCst;
    IN_FLIGHT.fetch_add(1, SeqCst);
    if interrupted() {
        IN_FLIGHT.fetch_sub(1, SeqCst);
        wait_if_interrupted();
    }
    live(|v| v.push(path.to_path_buf()));
    let r = f();
    IN_FLIGHT.fetch_sub(1, SeqCst);
    // Interrupted meanwhile: the handler removes what `f` made and ends the run
    wait_if_interrupted();
    r
}

/// How long the signal handler waits for temporaries being written (see [`staging`]).
const WRITE_GRACE: std::time::Duration = std::time::Duration::from_secs(10);

/// A fresh nonce for a temporary's name.
fn nonce() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    static COUNT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(COUNT.fetch_add(1, std::sync::atomic::Ordering::Relaxed));
    h.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0),
    );
    h.finish()
}

/// The longest file name a Linux file system takes, in bytes.
const NAME_MAX: usize = 255;
/// The bytes a temporary's name adds to the output's: `.`, `.rayproof-`, a pid (at most 10
/// digits), `-`, 16 hex digits and `.tmp` or `.dir`.
const TMP_OVERHEAD: usize = 1 + 10 + 10 + 1 + 16 + 4;

/// The part of an output's file name its temporaries carry: the whole name, or its first
/// `NAME_MAX - TMP_OVERHEAD` bytes (on a character boundary) when the temporary's name would
/// be longer than a file system takes (a 250-character output name was refused: its
/// temporary's name was too long).
fn tmp_stem(name: &str) -> &str {
    let mut k = NAME_MAX - TMP_OVERHEAD;
    if name.len() <= k {
        return name;
    }
    while !name.is_char_boundary(k) {
        k -= 1;
    }
    &name[..k]
}

/// The temporary sibling of `path`: `.NAME.rayproof-PID-NONCE.KIND` in the same directory (NAME
/// cut by [`tmp_stem`]), named through the directory as `path` writes it (`with_file_name` drops
/// `./` components, so a probe could pass where the output's own path is too long: found by
/// `tests/fuzz_surfaces.rs`).
fn tmp_for(path: &Path, kind: &str) -> PathBuf {
    use std::os::unix::ffi::OsStrExt;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = format!(
        ".{}.rayproof-{}-{:016x}.{kind}",
        tmp_stem(&name),
        std::process::id(),
        nonce()
    );
    let bytes = path.as_os_str().as_bytes();
    let end = bytes.len() - bytes.iter().rev().take_while(|&&b| b == b'/').count();
    let cut = bytes[..end]
        .iter()
        .rposition(|&b| b == b'/')
        .map_or(0, |i| i + 1);
    if path.file_name().map(|n| n.as_bytes()) != Some(&bytes[cut..end]) {
        return path.with_file_name(tmp);
    }
    let mut t = bytes[..cut].to_vec();
    t.extend_from_slice(tmp.as_bytes());
    PathBuf::from(std::ffi::OsStr::from_bytes(&t))
}

/// The process id in a temporary's name `.NAME.rayproof-PID-NONCE.KIND`, if `file` is exactly
/// such a name for `name` (cut by [`tmp_stem`]) and `kind`.
fn temporary_pid(file: &str, name: &str, kind: &str) -> Option<u32> {
    let rest = file
        .strip_prefix(&format!(".{}.rayproof-", tmp_stem(name)))?
        .strip_suffix(&format!(".{kind}"))?;
    let (pid, nonce) = rest.split_once('-')?;
    if nonce.len() != 16 || !nonce.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    pid.parse().ok()
}

/// Removes the temporaries an earlier, killed run left beside `path`: regular files named
/// `.NAME.rayproof-PID-NONCE.tmp`, and directories named `.NAME.rayproof-PID-NONCE.dir` that hold
/// [`MARKER`], whose process no longer exists. Nothing else, whatever its name.
pub fn remove_stale(path: &Path) {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    // A killed run's decided commit is finished before its temporaries could look stale
    journal::recover(dir);
    let name = name.to_string_lossy();
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Ok(meta) = std::fs::symlink_metadata(e.path()) else {
            continue;
        };
        let pid = if meta.is_file() {
            temporary_pid(&file, &name, "tmp")
        } else if meta.is_dir() && marked(&e.path()) {
            temporary_pid(&file, &name, "dir")
        } else {
            None
        };
        let Some(pid) = pid else {
            continue;
        };
        if journal::dead(pid) {
            remove_temporary(&e.path());
        }
    }
}

/// What identifies a file: its device and inode when it exists, else its [`canonical`] path
/// (the same however it is spelled, even where its directory does not exist yet).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Identity {
    /// Device and inode of an existing file.
    Inode(u64, u64),
    /// The canonical path of a file that does not exist yet.
    Path(PathBuf),
}

/// A path's [`Identity`].
pub fn identity(path: &Path) -> Identity {
    if let Ok(m) = std::fs::metadata(path) {
        return Identity::Inode(m.dev(), m.ino());
    }
    Identity::Path(canonical(path))
}

/// Whether two paths name the same file (by device and inode when both exist, else by the
/// canonical path of their directories and their names).
pub fn same_file(a: &Path, b: &Path) -> bool {
    identity(a) == identity(b)
}

/// Refuses an output whose file name is longer than a file system takes: its temporary, cut
/// by [`tmp_stem`], would be made, and the work done, before the rename into place failed
/// (found by `scripts/hostile-run`).
fn check_name_length(path: &Path) -> Result<()> {
    let n = path.file_name().map_or(0, |n| n.len());
    if n > NAME_MAX {
        bail!(
            "{}: the file name has {n} bytes, more than a file system takes ({NAME_MAX})",
            path.display()
        );
    }
    Ok(())
}

/// Refuses an output path that exists and is not a regular file: a directory, a symbolic link,
/// a FIFO, a device or a socket is never replaced (nor written through).
fn check_target(path: &Path) -> Result<()> {
    if path.file_name().is_none() {
        bail!("{}: output path has no file name", path.display());
    }
    check_name_length(path)?;
    // `FILE/` or `FILE/.` names a directory: no file can be renamed there
    let text = path.as_os_str().as_encoded_bytes();
    if text.ends_with(b"/") || text.ends_with(b"/.") {
        bail!(
            "{}: output path ends with '/' (a directory); give a file name",
            path.display()
        );
    }
    match std::fs::symlink_metadata(path) {
        Ok(m) if !m.file_type().is_file() => {
            let what = match m.file_type() {
                t if t.is_dir() => "a directory",
                t if t.is_symlink() => "a symbolic link",
                _ => "not a regular file (a FIFO, device or socket)",
            };
            bail!(
                "{}: is {what}; rayproof only replaces regular files",
                path.display()
            )
        }
        _ => Ok(()),
    }
}

/// Whether `dir` holds [`MARKER`] as a regular file: a link of that name (to any file) or a
/// directory is not rayproof's marker (a user's directory with such a link was replaced: found
/// by `scripts/hostile-run`).
fn marked(dir: &Path) -> bool {
    std::fs::symlink_metadata(dir.join(MARKER)).is_ok_and(|m| m.is_file())
}

/// Everything inside `dir`, as paths relative to it (`/`-separated; a directory ends in `/`),
/// sorted, without [`MARKER`]; links are listed, never followed.
fn listing(dir: &Path) -> std::io::Result<Vec<String>> {
    fn walk(root: &Path, rel: &str, out: &mut Vec<String>) -> std::io::Result<()> {
        for e in std::fs::read_dir(root.join(rel))? {
            let e = e?;
            let name = e.file_name().to_string_lossy().into_owned();
            let r = format!("{rel}{name}");
            if r == MARKER {
                continue;
            }
            if e.file_type()?.is_dir() {
                out.push(format!("{r}/"));
                walk(root, &format!("{r}/"), out)?;
            } else {
                out.push(r);
            }
        }
        Ok(())
    }
    let mut out = vec![];
    walk(dir, "", &mut out)?;
    out.sort();
    Ok(out)
}

/// The first line of [`MARKER`]; the lines after it list what the directory held when
/// rayproof committed it ([`listing`]).
const MARKER_HEAD: &str = "made by rayproof; it holds:";

/// Writes `dir`'s [`MARKER`]: its head and the listing of what `dir` holds now.
fn write_marker(dir: &Path) -> std::io::Result<()> {
    let mut text = format!("{MARKER_HEAD}\n");
    for l in listing(dir)? {
        text.push_str(&l);
        text.push('\n');
    }
    std::fs::write(dir.join(MARKER), text)
}

/// Refuses to replace a directory rayproof made if it holds anything its marker does not list:
/// a file put there since (goldens kept in a report directory were deleted with it, issue 46),
/// or anything in a directory made by a rayproof that did not list its files.
fn check_holds_only_its_report(path: &Path) -> Result<()> {
    let marker = std::fs::read_to_string(path.join(MARKER)).unwrap_or_default();
    let mut lines = marker.lines();
    let listed: std::collections::HashSet<&str> = match lines.next() {
        Some(MARKER_HEAD) => lines.collect(),
        _ => Default::default(),
    };
    let now = listing(path).with_context(|| format!("cannot read {}", path.display()))?;
    if let Some(extra) = now.iter().find(|e| !listed.contains(e.as_str())) {
        bail!(
            "{}: holds {}, which rayproof did not write there; rayproof replaces a report directory only when it holds nothing but its own report: move that out or give a new directory",
            path.display(),
            path.join(extra).display()
        );
    }
    Ok(())
}

/// Refuses a directory output that exists and is not a directory rayproof made, or that holds
/// anything rayproof did not write there.
fn check_dir_target(path: &Path) -> Result<()> {
    if path.file_name().is_none() {
        bail!("{}: output directory has no name", path.display());
    }
    check_name_length(path)?;
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() && marked(path) => check_holds_only_its_report(path),
        Ok(m) if m.is_dir() => bail!(
            "{}: is a directory rayproof did not make (no {MARKER} in it); rayproof only replaces its own output directories: give a new one",
            path.display()
        ),
        Ok(_) => bail!(
            "{}: exists and is not a directory; rayproof never replaces it",
            path.display()
        ),
        Err(_) => Ok(()),
    }
}

/// `path` absolute and without `.` or `..`: its longest existing ancestor canonicalised (links
/// resolved), the rest joined to it word by word (so `g/../g/x` and `g/x` are one path even
/// before `x` exists).
///
/// Each path's resolution is remembered for the rest of the process, whether it resolved or
/// not (a suite of 10,000 tests names the same few directories and 10,000 goldens not yet
/// written about 50,000 times: each `realpath` costs a `readlink` per component, and
/// validating it took over a second on a 2-core machine, issue 46 item 6). rayproof never
/// changes its working directory and never makes a link, so a path it later creates resolves
/// as its parent and name did: the remembered answer stays the answer.
pub fn canonical(path: &Path) -> PathBuf {
    use std::collections::HashMap;
    use std::path::Component;
    use std::sync::{Mutex, OnceLock};
    static CWD: OnceLock<PathBuf> = OnceLock::new();
    type Memo = Mutex<HashMap<PathBuf, Option<PathBuf>>>;
    static RESOLVED: OnceLock<Memo> = OnceLock::new();
    let cwd = CWD.get_or_init(|| std::env::current_dir().unwrap_or_default());
    let resolve = |base: &Path| -> Option<PathBuf> {
        let memo = RESOLVED.get_or_init(Default::default);
        if let Some(p) = memo.lock().ok().and_then(|m| m.get(base).cloned()) {
            return p;
        }
        let p = std::fs::canonicalize(base).ok();
        if let Ok(mut m) = memo.lock() {
            m.insert(base.to_path_buf(), p.clone());
        }
        p
    };
    let abs = cwd.join(path);
    for base in abs.ancestors() {
        if let Some(mut out) = resolve(base) {
            for c in abs.strip_prefix(base).unwrap_or(Path::new("")).components() {
                match c {
                    Component::ParentDir => {
                        out.pop();
                    }
                    Component::Normal(n) => out.push(n),
                    _ => {}
                }
            }
            return out;
        }
    }
    abs
}

/// Refuses a run's outputs that hold or sit inside another of its paths: a directory output
/// (a report) that is or contains an input or another output (it would be replaced with the
/// directory: goldens kept in a report directory were deleted, issue 46), and an output inside
/// an input that is a directory.
fn check_containment(outputs: &[(&Path, bool)], inputs: &[&Path]) -> Result<()> {
    let input_dirs: Vec<(PathBuf, &Path)> = inputs
        .iter()
        .filter(|p| p.is_dir())
        .map(|p| (canonical(p), *p))
        .collect();
    if input_dirs.is_empty() && !outputs.iter().any(|(_, d)| *d) {
        return Ok(());
    }
    let outs: Vec<PathBuf> = outputs.iter().map(|(p, _)| canonical(p)).collect();
    for (k, (o, _)) in outputs.iter().enumerate() {
        if let Some((_, d)) = input_dirs.iter().find(|(c, _)| outs[k].starts_with(c)) {
            bail!(
                "{}: is inside {}, an input of this run; rayproof never writes over its inputs",
                o.display(),
                d.display()
            );
        }
    }
    let others = inputs
        .iter()
        .map(|p| (*p, "an input"))
        .chain(outputs.iter().map(|(p, _)| (*p, "another output")));
    let others: Vec<(PathBuf, &Path, &str)> = others.map(|(p, w)| (canonical(p), p, w)).collect();
    for (k, (d, _)) in outputs.iter().enumerate().filter(|(_, (_, dir))| *dir) {
        let inside = others
            .iter()
            .enumerate()
            .find(|(j, (c, _, _))| *j != inputs.len() + k && c.starts_with(&outs[k]));
        if let Some((_, (_, p, what))) = inside {
            bail!(
                "{}: holds {}, {what} of this run, which replacing the directory would delete: give the report a directory of its own",
                d.display(),
                p.display()
            );
        }
    }
    Ok(())
}

/// Fails with one line if `p` exists and is not a JSON document (its first byte other than
/// white space is neither `[` nor `{`): a `--json` output replaces only a file rayproof could
/// have written. What an outside routine runs (a script named through the shell's quoting, a
/// glob or a variable) is not always a word of its command line; it is never JSON.
pub fn check_json_target(p: &Path) -> Result<()> {
    check_replaceable(p, "--json replaces only JSON", &|head| {
        matches!(
            head.iter().find(|b| !b.is_ascii_whitespace()),
            None | Some(b'[') | Some(b'{')
        )
    })
}

/// Fails with one line if `p` exists and is not a Markdown report that starts with `heading`
/// (after white space): a `--markdown` output replaces only a report rayproof could have
/// written (a source file or notes named by mistake are never one).
pub fn check_markdown_target(p: &Path, heading: &str) -> Result<()> {
    let rule = format!("--markdown replaces only a report that starts with `{heading}`");
    check_replaceable(p, &rule, &|head| {
        let start = head.iter().position(|b| !b.is_ascii_whitespace());
        start.is_none_or(|i| head[i..].starts_with(heading.as_bytes()))
    })
}

/// Fails with one line (`rule` says why) if `p` is an existing regular file whose first 4 KiB
/// `ours` does not accept as a file rayproof could have written there.
fn check_replaceable(p: &Path, rule: &str, ours: &dyn Fn(&[u8]) -> bool) -> Result<()> {
    use std::io::Read;
    let Ok(m) = std::fs::metadata(p) else {
        return Ok(());
    };
    if !m.is_file() {
        // The other checks name what it is
        return Ok(());
    }
    let mut head = vec![0u8; 4096];
    let n = std::fs::File::open(p)
        .and_then(|mut f| f.read(&mut head))
        .with_context(|| format!("{}: cannot be read", p.display()))?;
    if ours(&head[..n]) {
        return Ok(());
    }
    bail!(
        "{}: exists and is not a file rayproof writes there; {rule} (a file rayproof could have written)",
        p.display()
    )
}

/// Fails with one line if an output's directory does not exist or cannot take a temporary, if
/// an output is one of the inputs or is named twice, if a directory output holds an input or
/// another output (`check_containment`), or if an output exists and may not be replaced
/// (checked before a long run, so that the run is not wasted). Directory outputs go in `dirs`.
pub fn check_outputs(files: &[&Path], dirs: &[&Path], inputs: &[&Path]) -> Result<()> {
    check_outputs_with(files, dirs, inputs, false)
}

/// [`check_outputs`]; with `make_dirs`, an output's directory that does not exist yet is
/// allowed (the run's [`Outputs::making_dirs`] makes it): its nearest existing ancestor must be
/// a directory that takes a temporary. `check` does so, as its `--report` and `--json` into a
/// fresh `out/` are one command line of the README.
pub fn check_outputs_with(
    files: &[&Path],
    dirs: &[&Path],
    inputs: &[&Path],
    make_dirs: bool,
) -> Result<()> {
    let mut seen: Vec<(Identity, &Path)> = inputs.iter().map(|p| (identity(p), *p)).collect();
    // rayproof itself is an input of every run
    let exe = std::env::current_exe().ok();
    if let Some(e) = &exe {
        seen.push((identity(e), e.as_path()));
    }
    let n_inputs = seen.len();
    for (p, is_dir) in files
        .iter()
        .map(|p| (*p, false))
        .chain(dirs.iter().map(|p| (*p, true)))
    {
        let id = identity(p);
        if let Some((k, (_, other))) = seen.iter().enumerate().find(|(_, (i, _))| *i == id) {
            if k < n_inputs {
                bail!(
                    "{}: is an input of this run ({}); rayproof never writes over its inputs",
                    p.display(),
                    other.display()
                );
            }
            bail!("{}: named as two outputs of this run", p.display());
        }
        seen.push((id, p));
        // A directory that does not exist yet is made when the output is staged (and removed
        // again if the run ends without committing): its nearest existing ancestor must be a
        // directory that takes a temporary
        let dir = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let existing = dir
            .ancestors()
            .filter(|d| !d.as_os_str().is_empty())
            .find(|d| std::fs::symlink_metadata(d).is_ok())
            .unwrap_or(Path::new("."));
        if !make_dirs && !dir.is_dir() {
            bail!(
                "{}: directory {} does not exist",
                p.display(),
                dir.display()
            );
        }
        if !existing.is_dir() {
            bail!("{}: {} is not a directory", p.display(), existing.display());
        }
        if is_dir {
            check_dir_target(p)?;
        } else {
            check_target(p)?;
        }
        // Can a temporary be created there? (a read-only directory, /proc, …) Made under
        // `staging`, like every temporary: a signal between its creation and its removal left
        // it behind (1 of 80 interrupted renders, tests/signals.rs, once its tests ran beside
        // others)
        let probe = match existing == dir {
            true => p.to_path_buf(),
            false => existing.join(p.file_name().unwrap_or_default()),
        };
        let tmp = tmp_for(&probe, "tmp");
        let made = staging(&tmp, || std::fs::File::create(&tmp));
        discard(&tmp);
        made.map_err(|e| anyhow::anyhow!("cannot write {}: {e}", p.display()))?;
    }
    let outputs: Vec<(&Path, bool)> = files
        .iter()
        .map(|p| (*p, false))
        .chain(dirs.iter().map(|p| (*p, true)))
        .collect();
    check_containment(&outputs, inputs)
}

/// [`check_outputs`] for files of a run that declares no input.
pub fn check_output_dirs(paths: &[&Option<PathBuf>]) -> Result<()> {
    let files: Vec<&Path> = paths.iter().filter_map(|p| p.as_deref()).collect();
    check_outputs(&files, &[], &[])
}

/// One staged output: its temporary and its place.
struct Staged {
    tmp: PathBuf,
    path: PathBuf,
    dir: bool,
}

/// All the outputs of one run, committed together: each is written to its temporary sibling,
/// and only when every one has been written are they renamed into place. If any write fails, or
/// the set is dropped uncommitted, every temporary is removed and no output is touched.
#[derive(Default)]
pub struct Outputs {
    staged: Vec<Staged>,
    inputs: Vec<(Identity, PathBuf)>,
    /// Directory locks held until the outputs are committed (or dropped).
    locks: Vec<DirLock>,
    /// Directories made for outputs whose directory did not exist (outermost first): removed
    /// again, when still empty, if the outputs are dropped uncommitted.
    made_dirs: Vec<PathBuf>,
    /// Whether an output's missing directories are made ([`Outputs::making_dirs`]).
    make_dirs: bool,
}

/// An exclusive advisory lock (`flock(2)`) on a directory, released when dropped.
pub struct DirLock {
    _held: std::fs::File,
}

/// How long a run waits for another to release a directory's lock.
pub const LOCK_WAIT: std::time::Duration = std::time::Duration::from_secs(600);

impl DirLock {
    /// Locks `dir` (created first if missing), waiting up to [`LOCK_WAIT`] for another run to
    /// release it, and saying on stderr that it waits.
    pub fn exclusive(dir: &Path) -> Result<DirLock> {
        use std::os::fd::AsRawFd;
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let f =
            std::fs::File::open(dir).with_context(|| format!("cannot open {}", dir.display()))?;
        let t0 = std::time::Instant::now();
        let mut said = false;
        loop {
            // SAFETY: flock on a descriptor we own
            if unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } == 0 {
                return Ok(DirLock { _held: f });
            }
            let e = std::io::Error::last_os_error();
            if e.raw_os_error() != Some(libc::EWOULDBLOCK) {
                return Err(anyhow::Error::new(e).context(format!("cannot lock {}", dir.display())));
            }
            if t0.elapsed() > LOCK_WAIT {
                bail!(
                    "{} stayed locked by another rayproof run for {} s (it writes goldens or references there)",
                    dir.display(),
                    LOCK_WAIT.as_secs()
                );
            }
            if !said {
                eprintln!(
                    "waiting for {}: another rayproof run is writing goldens or references there",
                    dir.display()
                );
                said = true;
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
    }
}

impl Outputs {
    /// An empty set of staged outputs.
    pub fn new() -> Outputs {
        Outputs::default()
    }

    /// Holds `lock` until the outputs are committed or dropped.
    pub fn hold(&mut self, lock: DirLock) {
        self.locks.push(lock);
    }

    /// Makes an output's missing directories when it is staged (removed again if the outputs
    /// are dropped uncommitted); without it, an output into a missing directory fails to stage.
    pub fn making_dirs(mut self) -> Outputs {
        self.make_dirs = true;
        self
    }

    /// Declares the run's inputs: no output may be one of them.
    pub fn reading(mut self, inputs: &[&Path]) -> Outputs {
        self.inputs
            .extend(inputs.iter().map(|p| (identity(p), p.to_path_buf())));
        self
    }

    /// Refuses an output that is an input or already staged.
    fn claim(&self, path: &Path) -> Result<()> {
        let id = identity(path);
        if let Some((_, p)) = self.inputs.iter().find(|(i, _)| *i == id) {
            bail!(
                "{}: is an input of this run ({}); rayproof never writes over its inputs",
                path.display(),
                p.display()
            );
        }
        if self.staged.iter().any(|s| identity(&s.path) == id) {
            bail!("{}: named as two outputs of this run", path.display());
        }
        Ok(())
    }

    /// Makes the directories `path` needs that do not exist yet (`--json out/check.json` into a
    /// fresh `out/`), remembering them.
    fn make_parents(&mut self, path: &Path) -> Result<()> {
        let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) else {
            return Ok(());
        };
        if !self.make_dirs {
            return Ok(());
        }
        let missing: Vec<&Path> = dir
            .ancestors()
            .filter(|d| !d.as_os_str().is_empty())
            .take_while(|d| std::fs::symlink_metadata(d).is_err())
            .collect();
        for d in missing.into_iter().rev() {
            std::fs::create_dir(d).with_context(|| format!("cannot create {}", d.display()))?;
            self.made_dirs.push(d.to_path_buf());
        }
        Ok(())
    }

    /// Stages `path`: runs `write` on its temporary sibling.
    pub fn write_with(
        &mut self,
        path: &Path,
        write: impl FnOnce(&Path) -> Result<()>,
    ) -> Result<()> {
        check_target(path)?;
        self.claim(path)?;
        self.make_parents(path)?;
        remove_stale(path);
        let tmp = tmp_for(path, "tmp");
        if let Err(e) = staging(&tmp, || write(&tmp)) {
            discard(&tmp);
            return Err(e.context(format!("cannot write {}", path.display())));
        }
        self.staged.push(Staged {
            tmp,
            path: path.to_path_buf(),
            dir: false,
        });
        Ok(())
    }

    /// Stages `bytes` for `path`.
    pub fn write(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        self.write_with(path, |tmp| Ok(std::fs::write(tmp, bytes)?))
    }

    /// Stages a directory output: `fill` writes its files into a temporary sibling directory
    /// (marked with [`MARKER`]), which replaces `path` on commit. An existing `path` must be a
    /// directory rayproof made.
    pub fn dir_with(&mut self, path: &Path, fill: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
        check_dir_target(path)?;
        self.claim(path)?;
        self.make_parents(path)?;
        remove_stale(path);
        let tmp = tmp_for(path, "dir");
        // Made under `staging`; filled after, by path (once the handler removed it, writes in it
        // fail: nothing in `fill` may create it again, so no create_dir_all of it)
        let made = staging(&tmp, || {
            std::fs::create_dir(&tmp)
                .and_then(|_| std::fs::write(tmp.join(MARKER), format!("{MARKER_HEAD}\n")))
                .with_context(|| format!("cannot create {}", tmp.display()))
        })
        .and_then(|_| fill(&tmp));
        if let Err(e) = made {
            discard(&tmp);
            return Err(e.context(format!("cannot write {}", path.display())));
        }
        self.staged.push(Staged {
            tmp,
            path: path.to_path_buf(),
            dir: true,
        });
        Ok(())
    }

    /// Stages a directory output to be filled by the caller: the temporary sibling directory
    /// (marked with [`MARKER`]) that replaces `path` on commit.
    pub fn dir(&mut self, path: &Path) -> Result<PathBuf> {
        let mut made = None;
        self.dir_with(path, |tmp| {
            made = Some(tmp.to_path_buf());
            Ok(())
        })?;
        made.context("no staging directory")
    }

    /// Renames every staged output into place, all of them or (interrupted before it starts)
    /// none. A signal that arrives during the commit waits for it to finish.
    pub fn commit(mut self) -> Result<()> {
        let _commit = COMMIT.lock().unwrap_or_else(|e| e.into_inner());
        if interrupted() {
            bail!("interrupted");
        }
        // Last checks (each directory's marker lists what it holds), then the renames
        for s in &self.staged {
            if s.dir {
                write_marker(&s.tmp)
                    .with_context(|| format!("cannot write {}", s.path.display()))?;
                check_dir_target(&s.path)?;
            } else {
                check_target(&s.path)?;
            }
        }
        // Two or more: decided in a journal first, so that a SIGKILL between two renames
        // leaves the next run a commit to finish (journal.rs)
        let staged = std::mem::take(&mut self.staged);
        let journal = if staged.len() > 1 {
            let pid = std::process::id();
            let entries: Vec<journal::Entry> = staged
                .iter()
                .map(|s| journal::Entry {
                    tmp: absolute(&s.tmp),
                    path: absolute(&s.path),
                    aside: s.dir.then(|| absolute(&tmp_for(&s.path, "old"))),
                })
                .collect();
            match journal::begin(&entries, pid, nonce()) {
                Ok(j) => Some((j, entries)),
                Err(e) => {
                    for s in &staged {
                        discard(&s.tmp);
                    }
                    return Err(anyhow::Error::new(e).context("cannot write the commit journal"));
                }
            }
        } else {
            None
        };
        for (i, s) in staged.iter().enumerate() {
            let r = match &journal {
                Some((_, entries)) => journal::put_in_place(&entries[i]),
                // The old version out and the new in, in one step; then the old one goes
                None if s.dir && s.path.exists() => {
                    exchange(&s.tmp, &s.path).map(|_| remove_temporary(&s.tmp))
                }
                None => std::fs::rename(&s.tmp, &s.path),
            };
            live(|v| v.retain(|p| p != &s.tmp));
            if r.is_ok() {
                RENAMED.store(true, std::sync::atomic::Ordering::SeqCst);
            }
            if let Err(e) = r {
                // No temporary is left: this one's and the rest's (a failed rename left them)
                for t in &staged[i..] {
                    discard(&t.tmp);
                }
                if let Some((j, _)) = journal {
                    j.finish();
                }
                return Err(
                    anyhow::Error::new(e).context(format!("cannot write {}", s.path.display()))
                );
            }
        }
        if let Some((j, _)) = journal {
            j.finish();
        }
        self.made_dirs.clear();
        Ok(())
    }
}

/// `path` with its directory [`canonical`]: the same file from any working directory (a
/// journal is read by another run).
fn absolute(path: &Path) -> PathBuf {
    match (path.parent(), path.file_name()) {
        (Some(d), Some(n)) => canonical(if d.as_os_str().is_empty() {
            Path::new(".")
        } else {
            d
        })
        .join(n),
        _ => canonical(path),
    }
}

/// Exchanges two paths atomically (`renameat2(RENAME_EXCHANGE)`).
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    use std::os::unix::ffi::OsStrExt;
    let ca = std::ffi::CString::new(a.as_os_str().as_bytes())?;
    let cb = std::ffi::CString::new(b.as_os_str().as_bytes())?;
    // SAFETY: renameat2 with two NUL-terminated paths relative to the working directory
    let r = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            ca.as_ptr(),
            libc::AT_FDCWD,
            cb.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

impl Drop for Outputs {
    fn drop(&mut self) {
        for s in &self.staged {
            discard(&s.tmp);
        }
        // Directories made for outputs never committed: innermost first, only if empty
        for d in self.made_dirs.iter().rev() {
            let _ = std::fs::remove_dir(d);
        }
    }
}

/// Runs `write` on the temporary sibling of `path`, then renames it into place; on any error
/// the temporary file is removed and `path` is left as it was.
pub fn write_atomic_with(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let mut out = Outputs::new();
    out.write_with(path, write)?;
    out.commit()
}

/// Writes `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |tmp| Ok(std::fs::write(tmp, bytes)?))
}

/// Writes `value` as pretty JSON (with a final newline) to `path` atomically.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    write_atomic(
        path,
        (serde_json::to_string_pretty(value)? + "\n").as_bytes(),
    )
}

/// A scratch directory under the system's temp directory (`rayproof-TAG-PID-NANOS`), removed
/// with everything in it when dropped, and on SIGINT or SIGTERM.
pub struct ScratchDir(pub PathBuf);

impl ScratchDir {
    /// Creates `rayproof-TAG-PID-NONCE` under the system's temp directory, after removing the
    /// scratch directories of runs that died without removing theirs (killed by SIGKILL).
    pub fn new(tag: &str) -> Result<ScratchDir> {
        ScratchDir::new_in(&std::env::temp_dir(), tag)
    }

    /// [`ScratchDir::new`] under `tmp`.
    pub fn new_in(tmp: &Path, tag: &str) -> Result<ScratchDir> {
        remove_dead_runs_scratch(tmp);
        let p = tmp.join(format!(
            "rayproof-{tag}-{}-{:016x}",
            std::process::id(),
            nonce()
        ));
        // Made under `staging`, like every temporary: created and registered apart, a signal
        // between the two, or a creation after the handler's clean-up, left it behind (once in
        // 40 interrupted `check --update` runs, tests/signals.rs, the whole suite running)
        if let Err(e) = staging(&p, || std::fs::create_dir_all(&p)) {
            discard(&p);
            return Err(anyhow::Error::new(e).context(format!("cannot create {}", p.display())));
        }
        Ok(ScratchDir(p))
    }
}

/// Removes, under `tmp`, the scratch directories of rayproof runs that are dead: only
/// rayproof's own, recognised by name (`rayproof-TAG-PID-NONCE`, 16 hex digits), owned by this
/// user, a real directory (not a link), whose process no longer exists. A live process of that
/// pid (a run still going, or the pid reused) keeps its directory.
pub fn remove_dead_runs_scratch(tmp: &Path) {
    let Ok(entries) = std::fs::read_dir(tmp) else {
        return;
    };
    // SAFETY: geteuid has no arguments and cannot fail
    let me = unsafe { libc::geteuid() };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(rest) = name.strip_prefix("rayproof-") else {
            continue;
        };
        let mut parts = rest.rsplitn(3, '-');
        let (Some(nonce), Some(pid), Some(tag)) = (parts.next(), parts.next(), parts.next()) else {
            continue;
        };
        let ours = nonce.len() == 16
            && nonce.bytes().all(|b| b.is_ascii_hexdigit())
            && !tag.is_empty()
            && tag.bytes().all(|b| b.is_ascii_lowercase());
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        if !ours || !journal::dead(pid) {
            continue;
        }
        let Ok(meta) = std::fs::symlink_metadata(e.path()) else {
            continue;
        };
        if !meta.is_dir() || meta.uid() != me {
            continue;
        }
        let _ = std::fs::remove_dir_all(e.path());
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        discard(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 48: an output's missing directories are made when it is staged, stay when it is
    /// committed, and are removed again (only those, only if empty) when it is not.
    #[test]
    fn missing_output_directories_are_made_and_unmade_with_the_output() {
        let tmp = std::env::temp_dir().join(format!("rayproof-parents-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir_all(&tmp).unwrap();
        // Not asked to: no directory made, the output fails to stage
        let mut out = Outputs::new();
        assert!(out.write(&tmp.join("a/b/c.json"), b"{}").is_err());
        assert!(!tmp.join("a").exists());
        let mut out = Outputs::new().making_dirs();
        out.write(&tmp.join("a/b/c.json"), b"{}").unwrap();
        assert!(tmp.join("a/b").is_dir());
        drop(out);
        assert!(!tmp.join("a").exists());
        let mut out = Outputs::new().making_dirs();
        out.write(&tmp.join("a/b/c.json"), b"{}").unwrap();
        out.commit().unwrap();
        assert_eq!(std::fs::read(tmp.join("a/b/c.json")).unwrap(), b"{}");
        std::fs::remove_dir_all(&tmp).unwrap();
    }

    /// Issue 46 (10): the scratch directory of a run killed by SIGKILL is removed by the next
    /// run; a live run's, another name's, a link and a directory of a live pid are kept.
    #[test]
    fn a_dead_runs_scratch_is_removed_and_nothing_else() {
        let tmp = std::env::temp_dir().join(format!("rayproof-sweep-test-{}", std::process::id()));
        std::fs::create_dir_all(&tmp).unwrap();
        let mut gone = std::process::Command::new("true").spawn().unwrap();
        let dead = gone.id();
        gone.wait().unwrap();
        let me = std::process::id();
        let dead_dir = tmp.join(format!("rayproof-check-{dead}-0123456789abcdef"));
        let kept = [
            format!("rayproof-check-{me}-0123456789abcdef"),
            format!("rayproof-check-1-0123456789abcdef"),
            format!("rayproof-check-{dead}-0123"),
            format!("rayproof-{dead}-0123456789abcdef"),
            format!("other-check-{dead}-0123456789abcdef"),
        ];
        std::fs::create_dir_all(dead_dir.join("inner")).unwrap();
        std::fs::write(dead_dir.join("inner/f"), b"x").unwrap();
        for k in &kept {
            std::fs::create_dir_all(tmp.join(k)).unwrap();
        }
        let link = tmp.join(format!("rayproof-reference-{dead}-fedcba9876543210"));
        std::os::unix::fs::symlink(tmp.join(&kept[0]), &link).unwrap();
        // A new scratch directory sweeps its parent first
        let made = ScratchDir::new_in(&tmp, "check").unwrap();
        assert!(made.0.is_dir());
        assert!(!dead_dir.exists());
        for k in &kept {
            assert!(tmp.join(k).is_dir(), "{k} removed");
        }
        assert!(link.symlink_metadata().is_ok(), "the link was removed");
        drop(made);
        std::fs::remove_dir_all(&tmp).unwrap();
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = std::env::temp_dir().join(format!("rayproof-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.txt");
        write_atomic(&path, b"old").unwrap();
        let r = write_atomic_with(&path, |tmp| {
            std::fs::write(tmp, b"half")?;
            bail!("interrupted")
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
        assert_eq!(left.len(), 1, "a temporary was left");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn only_exact_temporaries_of_dead_runs_are_cleaned() {
        let dir = std::env::temp_dir().join(format!("rayproof-stale-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("keep.exr");
        let dead = 999_999_999u32;
        let stale_file = dir.join(format!(".keep.exr.rayproof-{dead}-0123456789abcdef.tmp"));
        std::fs::write(&stale_file, b"x").unwrap();
        let stale_dir = dir.join(format!(".keep.exr.rayproof-{dead}-0123456789abcdef.dir"));
        std::fs::create_dir_all(&stale_dir).unwrap();
        std::fs::write(stale_dir.join(MARKER), b"").unwrap();
        // A user's directory of the old pattern and of the new one without the marker
        let users = [
            dir.join(format!(".keep.exr.tmp{dead}")),
            dir.join(format!(".keep.exr.rayproof-{dead}-0123456789abcdef.tmp.d")),
            dir.join(format!(".keep.exr.rayproof-{dead}-0123456789abcdef.dir2")),
        ];
        let user_dir = dir.join(format!(".keep.exr.rayproof-{dead}-fedcba9876543210.dir"));
        std::fs::create_dir_all(user_dir.join("thesis")).unwrap();
        for u in &users {
            std::fs::create_dir_all(u.join("precious")).unwrap();
        }
        remove_stale(&out);
        assert!(!stale_file.exists() && !stale_dir.exists());
        assert!(user_dir.join("thesis").exists());
        for u in &users {
            assert!(u.join("precious").exists(), "{}", u.display());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
