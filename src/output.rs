//! Writing output files. Every file goes through a temporary sibling (`.NAME.tmpPID`) and a
//! rename, so a failed or interrupted command never leaves a half-written file and never
//! replaces a good one. This is the one atomic writer of the crate.
//!
//! - A command that writes several files (`render -o X.exr --png Y.png` and its `X.exr.json`)
//!   renames them only when every one was written.
//! - An output path that exists and is not a regular file (a directory, a symbolic link, a FIFO, a
//!   device) is refused, never replaced.
//! - Output paths are checked before the work starts (their directory exists and takes a
//!   temporary file).
//! - SIGINT or SIGTERM removes the temporaries being written and exits with 130; what a SIGKILL
//!   leaves (`.NAME.tmpPID`) is removed by the next write of the same output.

use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// The temporary sibling of `path`: `.NAME.tmpPID` in the same directory.
fn tmp_for(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp{}", std::process::id()))
}

/// The temporaries being written now, removed by [`clean_up_on_signals`]'s handler.
static LIVE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn live(f: impl FnOnce(&mut Vec<PathBuf>)) {
    if let Ok(mut v) = LIVE.lock() {
        f(&mut v);
    }
}

/// Set by the signal handler before it does anything else.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether SIGINT or SIGTERM arrived.
pub fn interrupted() -> bool {
    INTERRUPTED.load(std::sync::atomic::Ordering::SeqCst)
}

/// Once SIGINT or SIGTERM arrived, the handler ends the run (exit 130): a thread that sees the
/// effects of the interruption (a child killed by the handler) waits here instead of reporting
/// them as its own failure.
pub fn wait_if_interrupted() {
    while interrupted() {
        std::thread::sleep(std::time::Duration::from_secs(1));
    }
}

/// On SIGINT or SIGTERM, removes every temporary being written and exits with 130 (the
/// shell's code for an interrupted command), so a killed command leaves no `.NAME.tmpPID`.
/// (A SIGKILL cannot be caught: the next write of the same output removes what it left.)
pub fn clean_up_on_signals() {
    let _ = ctrlc::set_handler(|| {
        // From now on no other thread decides how the run ends
        INTERRUPTED.store(true, std::sync::atomic::Ordering::SeqCst);
        // The outside commands running now, and all they started, go first
        crate::process::kill_all();
        live(|v| {
            for p in v.drain(..) {
                let _ = std::fs::remove_file(&p).or_else(|_| std::fs::remove_dir_all(&p));
            }
        });
        eprintln!("error: interrupted; temporary files removed");
        std::process::exit(130);
    });
}

/// Runs `f` with `path` (a temporary file or directory) registered for removal on SIGINT or
/// SIGTERM.
pub fn tracked<T>(path: &Path, f: impl FnOnce() -> T) -> T {
    live(|v| v.push(path.to_path_buf()));
    let r = f();
    live(|v| v.retain(|p| p != path));
    r
}

/// Removes the temporaries an earlier, killed run left beside `path`: `.NAME.KINDPID` (a file
/// or a directory) whose process no longer exists.
pub fn remove_stale(path: &Path, kind: &str) {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!(".{}.{kind}", name.to_string_lossy());
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = n.strip_prefix(&prefix).and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_file(e.path()).or_else(|_| std::fs::remove_dir_all(e.path()));
        }
    }
}

/// Refuses an output path that exists and is not a regular file: a directory, a symbolic link,
/// a FIFO, a device or a socket is never replaced (nor written through).
fn check_target(path: &Path) -> Result<()> {
    if path.file_name().is_none() {
        bail!("{}: output path has no file name", path.display());
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

/// Several output files committed together: each is written to its temporary sibling, and
/// only when every one has been written are they renamed into place. If any write fails, or
/// the set is dropped uncommitted, every temporary is removed and no output is touched.
#[derive(Default)]
pub struct Outputs {
    staged: Vec<(PathBuf, PathBuf)>,
}

impl Outputs {
    /// An empty set of staged outputs.
    pub fn new() -> Outputs {
        Outputs::default()
    }

    /// Stages `path`: runs `write` on its temporary sibling.
    pub fn write_with(
        &mut self,
        path: &Path,
        write: impl FnOnce(&Path) -> Result<()>,
    ) -> Result<()> {
        check_target(path)?;
        remove_stale(path, "tmp");
        let tmp = tmp_for(path);
        live(|v| v.push(tmp.clone()));
        if let Err(e) = write(&tmp) {
            let _ = std::fs::remove_file(&tmp);
            live(|v| v.retain(|p| p != &tmp));
            return Err(e.context(format!("cannot write {}", path.display())));
        }
        self.staged.push((tmp, path.to_path_buf()));
        Ok(())
    }

    /// Stages `bytes` for `path`.
    pub fn write(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        self.write_with(path, |tmp| Ok(std::fs::write(tmp, bytes)?))
    }

    /// Renames every staged file into place.
    pub fn commit(mut self) -> Result<()> {
        for (tmp, path) in std::mem::take(&mut self.staged) {
            let r = std::fs::rename(&tmp, &path);
            live(|v| v.retain(|p| p != &tmp));
            r.with_context(|| format!("cannot write {}", path.display()))?;
        }
        Ok(())
    }
}

impl Drop for Outputs {
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
            live(|v| v.retain(|p| p != tmp));
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

/// Fails with one line if the directory of any given output path does not exist, or the path
/// is not a regular file that may be replaced (checked before a long run, so the run is not
/// wasted).
pub fn check_output_dirs(paths: &[&Option<PathBuf>]) -> Result<()> {
    for p in paths.iter().copied().flatten() {
        let dir = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        if !dir.is_dir() {
            bail!(
                "{}: directory {} does not exist",
                p.display(),
                dir.display()
            );
        }
        check_target(p)?;
        // Can a temporary sibling be created there? (a read-only directory, /proc, …)
        let tmp = tmp_for(p);
        std::fs::File::create(&tmp)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", p.display()))?;
        let _ = std::fs::remove_file(&tmp);
    }
    Ok(())
}

/// A scratch directory under the system's temp directory (`rayproof-TAG-PID-NANOS`), removed
/// with everything in it when dropped.
pub struct ScratchDir(pub PathBuf);

impl ScratchDir {
    /// Creates `rayproof-TAG-PID-NANOS` under the system's temp directory.
    pub fn new(tag: &str) -> Result<ScratchDir> {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.subsec_nanos())
            .unwrap_or(0);
        let p = std::env::temp_dir().join(format!("rayproof-{tag}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&p).with_context(|| format!("cannot create {}", p.display()))?;
        Ok(ScratchDir(p))
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(!tmp_for(&path).exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
