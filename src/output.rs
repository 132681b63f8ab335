//! Writing output files. Every file goes through a temporary sibling (`.NAME.tmpPID`) and a
//! rename, so a failed or interrupted command never leaves a half-written file and never
//! replaces a good one. This is the one atomic writer of the crate.

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

/// Runs `write` on the temporary sibling of `path`, then renames it into place; on any error
/// the temporary file is removed and `path` is left as it was.
pub fn write_atomic_with(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    if path.file_name().is_none() {
        bail!("{}: output path has no file name", path.display());
    }
    let tmp = tmp_for(path);
    let r = write(&tmp).and_then(|_| Ok(std::fs::rename(&tmp, path)?));
    if r.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    r.with_context(|| format!("cannot write {}", path.display()))
}

/// Writes `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |tmp| Ok(std::fs::write(tmp, bytes)?))
}

/// Fails with one line if the directory of any given output path does not exist (checked
/// before a long run, so the run is not wasted).
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
    }
    Ok(())
}

/// A scratch directory under the system's temp directory (`rayproof-TAG-PID-NANOS`), removed
/// with everything in it when dropped.
pub struct ScratchDir(pub PathBuf);

impl ScratchDir {
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
