//! The commit journal: a run's outputs put in place all together even when the run is killed
//! by SIGKILL in the middle of its renames (issue 46, F1: 8 of about 70 SIGKILLs of `check
//! --update` left some goldens new and the rest, with the manifest, old; every later `check`
//! refused the suite).
//!
//! A commit of two or more outputs is decided before its first rename, in two phases:
//!
//! 1. In each directory that receives an output, other than the first output's (the *home*), a
//!    `.rayproof-commit-PID-NONCE.pending` file lists the whole commit.
//! 2. In the home directory, `.rayproof-commit-PID-NONCE.journal` is written under a temporary
//!    name and renamed into place: from that rename on, the commit is decided.
//!
//! Then the outputs are renamed into place, the pending files removed, and the journal last.
//!
//! **Recovery** ([`recover`], run by every later run before it reads a manifest or stages an
//! output in a directory): a journal of a process that no longer exists is *rolled forward*
//! (each temporary still there is renamed into place, which is what the killed run was doing);
//! a pending file whose journal does not exist belongs to a commit that was never decided and
//! is removed (the killed run's temporaries are removed as stale, so the old outputs stay). A
//! killed run therefore leaves, to the next run, either every old output or every new one.
//!
//! What it guards against is the process being killed, not the machine losing power: nothing is
//! synced to the disk.
//!
//! A directory output in a journaled commit is replaced in two renames (the old one set aside
//! as `.NAME.rayproof-PID-NONCE.old`, removed after): an atomic exchange leaves the old
//! version under the temporary's name, which a recovery cannot tell from the new one.

use std::io::{Error, ErrorKind, Result};
use std::os::unix::ffi::{OsStrExt, OsStringExt};
use std::path::{Path, PathBuf};

/// The first line of a journal and of a pending file.
const HEAD: &str = "rayproof commit journal 1";

/// One output of a commit: its temporary, its place, and for a directory the name its old
/// version is set aside under while it is replaced.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// The staged temporary (absolute).
    pub tmp: PathBuf,
    /// Where it goes (absolute).
    pub path: PathBuf,
    /// For a directory output: where the old directory waits to be removed.
    pub aside: Option<PathBuf>,
}

/// A decided commit: its journal and pending files, removed by [`Journal::finish`].
#[derive(Debug)]
pub struct Journal {
    journal: PathBuf,
    pending: Vec<PathBuf>,
}

/// `bytes` as lower-case hex (a path may hold any byte but `/0`).
fn hex(p: &Path) -> String {
    p.as_os_str()
        .as_bytes()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn unhex(s: &str) -> Option<PathBuf> {
    if s.is_empty() || s.len() % 2 != 0 {
        return None;
    }
    let bytes = (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(s.get(i..i + 2)?, 16).ok())
        .collect::<Option<Vec<u8>>>()?;
    Some(PathBuf::from(std::ffi::OsString::from_vec(bytes)))
}

/// The text of a journal (and of each pending file): the head, the journal's own path, the
/// pending files, the entries, and `end` (a file cut short is never taken for a whole one).
fn text(journal: &Path, pending: &[PathBuf], entries: &[Entry]) -> String {
    let mut t = format!("{HEAD}\njournal {}\n", hex(journal));
    for p in pending {
        t += &format!("pending {}\n", hex(p));
    }
    for e in entries {
        match &e.aside {
            None => t += &format!("file {} {}\n", hex(&e.tmp), hex(&e.path)),
            Some(a) => t += &format!("dir {} {} {}\n", hex(&e.tmp), hex(&e.path), hex(a)),
        }
    }
    t + "end\n"
}

/// What a journal says: its path, its pending files and its entries; `None` if it is not a
/// whole journal.
fn parse(t: &str) -> Option<(PathBuf, Vec<PathBuf>, Vec<Entry>)> {
    let mut lines = t.lines();
    if lines.next()? != HEAD {
        return None;
    }
    let journal = unhex(lines.next()?.strip_prefix("journal ")?)?;
    let (mut pending, mut entries) = (vec![], vec![]);
    for l in lines {
        let w: Vec<&str> = l.split(' ').collect();
        match w.as_slice() {
            ["end"] => return Some((journal, pending, entries)),
            ["pending", p] => pending.push(unhex(p)?),
            ["file", t, p] => entries.push(Entry {
                tmp: unhex(t)?,
                path: unhex(p)?,
                aside: None,
            }),
            ["dir", t, p, a] => entries.push(Entry {
                tmp: unhex(t)?,
                path: unhex(p)?,
                aside: Some(unhex(a)?),
            }),
            _ => return None,
        }
    }
    None
}

/// The name of a commit's files in a directory: `.rayproof-commit-PID-NONCE.KIND`.
fn name(pid: u32, nonce: u64, kind: &str) -> String {
    format!(".rayproof-commit-{pid}-{nonce:016x}.{kind}")
}

/// The pid and kind of a commit file's name.
fn parse_name(file: &str) -> Option<(u32, &str)> {
    let rest = file.strip_prefix(".rayproof-commit-")?;
    let (pid, rest) = rest.split_once('-')?;
    let (nonce, kind) = rest.split_once('.')?;
    if nonce.len() != 16 || !nonce.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    Some((pid.parse().ok()?, kind))
}

/// Writes the journal of a commit of `entries` made by process `pid`: the pending files, then
/// the journal (the decision). On an error, whatever was written is removed and nothing is
/// decided.
pub fn begin(entries: &[Entry], pid: u32, nonce: u64) -> Result<Journal> {
    let dir_of = |p: &Path| p.parent().map(Path::to_path_buf).unwrap_or_default();
    let home = dir_of(&entries[0].path);
    let journal = home.join(name(pid, nonce, "journal"));
    let mut pending: Vec<PathBuf> = vec![];
    for e in entries {
        let p = dir_of(&e.path).join(name(pid, nonce, "pending"));
        if dir_of(&e.path) != home && !pending.contains(&p) {
            pending.push(p);
        }
    }
    let t = text(&journal, &pending, entries);
    let undo = |made: &[PathBuf]| {
        for m in made {
            let _ = std::fs::remove_file(m);
        }
    };
    let mut made = vec![];
    for p in &pending {
        if let Err(e) = std::fs::write(p, &t) {
            undo(&made);
            return Err(e);
        }
        made.push(p.clone());
    }
    let part = home.join(name(pid, nonce, "part"));
    made.push(part.clone());
    if let Err(e) = std::fs::write(&part, &t).and_then(|_| std::fs::rename(&part, &journal)) {
        undo(&made);
        return Err(e);
    }
    Ok(Journal { journal, pending })
}

impl Journal {
    /// The commit is done: its pending files go, then its journal.
    pub fn finish(self) {
        for p in &self.pending {
            let _ = std::fs::remove_file(p);
        }
        let _ = std::fs::remove_file(&self.journal);
    }
}

/// Puts one output in place: a file by one rename; a directory by setting the old one aside
/// (when there is one), renaming the new one in and removing the old one.
pub fn put_in_place(e: &Entry) -> Result<()> {
    if let Some(aside) = &e.aside {
        if std::fs::symlink_metadata(&e.path).is_ok() {
            std::fs::rename(&e.path, aside)?;
        }
        std::fs::rename(&e.tmp, &e.path)?;
        super::remove_temporary(aside);
        return Ok(());
    }
    std::fs::rename(&e.tmp, &e.path)
}

/// Whether process `pid` no longer exists (and is not this one). A pid no process can have (0,
/// or over `i32::MAX`: Linux pids stay under 2²²) is dead.
pub fn dead(pid: u32) -> bool {
    if pid == std::process::id() {
        return false;
    }
    if pid == 0 || pid > i32::MAX as u32 {
        return true;
    }
    // SAFETY: signal 0 only checks that the process exists
    let gone = unsafe { libc::kill(pid as i32, 0) } != 0;
    gone && Error::last_os_error().raw_os_error() == Some(libc::ESRCH)
}

/// Finishes, in `dir`, the commits of killed runs (see the module's doc): rolls a decided one
/// forward, drops an undecided one. Says on stderr what it did. Errors are not fatal to the
/// run that recovers: an output it cannot put in place stays as the killed run left it, with
/// its journal, for the next run.
pub fn recover(dir: &Path) {
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some((pid, kind)) = parse_name(&file) else {
            continue;
        };
        if !dead(pid) || !std::fs::symlink_metadata(e.path()).is_ok_and(|m| m.is_file()) {
            continue;
        }
        let path = e.path();
        match kind {
            "journal" => roll_forward(&path, pid),
            "pending" => {
                // Its journal decides: rolled forward from there, or never decided
                let text = std::fs::read_to_string(&path).unwrap_or_default();
                match parse(&text) {
                    Some((journal, _, _)) if journal.exists() => roll_forward(&journal, pid),
                    _ => {
                        let _ = std::fs::remove_file(&path);
                    }
                }
            }
            "part" => {
                let _ = std::fs::remove_file(&path);
            }
            _ => {}
        }
    }
}

/// Rolls the journal `path` of the dead process `pid` forward: every temporary still there is
/// put in place, every directory set aside removed, then the pending files and the journal.
fn roll_forward(path: &Path, pid: u32) {
    let Ok(text) = std::fs::read_to_string(path) else {
        return;
    };
    let Some((_, pending, entries)) = parse(&text) else {
        eprintln!(
            "warning: {}: a commit journal of a killed rayproof run (pid {pid}) that cannot be read; left as it is",
            path.display()
        );
        return;
    };
    let mut placed = 0;
    for e in &entries {
        let r = if std::fs::symlink_metadata(&e.tmp).is_ok() {
            put_in_place(e).map(|_| placed += 1)
        } else {
            // Already in place; a directory set aside may remain
            if let Some(a) = &e.aside {
                super::remove_temporary(a);
            }
            Ok(())
        };
        match r {
            Err(err) if err.kind() != ErrorKind::NotFound => {
                eprintln!(
                    "warning: cannot finish the commit of a killed rayproof run (pid {pid}): {}: {err}; its journal {} is kept",
                    e.path.display(),
                    path.display()
                );
                return;
            }
            _ => {}
        }
    }
    for p in &pending {
        let _ = std::fs::remove_file(p);
    }
    let _ = std::fs::remove_file(path);
    if placed > 0 {
        eprintln!(
            "note: finished the commit of a killed rayproof run (pid {pid}): {placed} of its {} outputs put in place",
            entries.len()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pid that no longer exists.
    fn dead_pid() -> u32 {
        let mut c = std::process::Command::new("true").spawn().unwrap();
        let pid = c.id();
        c.wait().unwrap();
        pid
    }

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("rayproof-journal-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(d.join("g")).unwrap();
        std::fs::create_dir_all(d.join("out")).unwrap();
        d
    }

    /// Three outputs in two directories (two goldens and a report file), old and staged.
    fn staged(d: &Path, pid: u32) -> Vec<Entry> {
        let mut v = vec![];
        for (i, p) in ["g/a.exr", "g/manifest.json", "out/check.json"]
            .iter()
            .enumerate()
        {
            let path = d.join(p);
            std::fs::write(&path, "old").unwrap();
            let tmp = path.with_file_name(format!(".t{i}.rayproof-{pid}-0000000000000000.tmp"));
            std::fs::write(&tmp, "new").unwrap();
            v.push(Entry {
                tmp,
                path,
                aside: None,
            });
        }
        v
    }

    fn contents(e: &[Entry]) -> Vec<String> {
        e.iter()
            .map(|e| std::fs::read_to_string(&e.path).unwrap())
            .collect()
    }

    /// Issue 46, F1: killed after k of its renames (k = 0 to all), a decided commit is finished
    /// by the next run, whichever directory it looks in first; nothing of it is left.
    #[test]
    fn a_commit_killed_between_its_renames_is_rolled_forward() {
        let pid = dead_pid();
        for k in 0..=3 {
            for first in ["g", "out"] {
                let d = scratch("forward");
                let e = staged(&d, pid);
                let j = begin(&e, pid, 7).unwrap();
                for x in &e[..k] {
                    put_in_place(x).unwrap();
                }
                std::mem::forget(j);
                recover(&d.join(first));
                assert_eq!(contents(&e), ["new"; 3], "k = {k}, first {first}");
                for sub in ["g", "out"] {
                    let left: Vec<_> = std::fs::read_dir(d.join(sub))
                        .unwrap()
                        .flatten()
                        .map(|f| f.file_name().to_string_lossy().into_owned())
                        .filter(|f| f.starts_with('.'))
                        .collect();
                    assert!(left.is_empty(), "k = {k}: left {left:?}");
                }
                std::fs::remove_dir_all(&d).unwrap();
            }
        }
    }

    /// Killed before its journal was in place (pending files only, or a partial journal), the
    /// commit was never decided: recovery leaves every old output and removes its files.
    #[test]
    fn an_undecided_commit_leaves_every_old_output() {
        let pid = dead_pid();
        let d = scratch("undecided");
        let e = staged(&d, pid);
        let j = begin(&e, pid, 9).unwrap();
        std::fs::rename(&j.journal, j.journal.with_extension("part")).unwrap();
        std::mem::forget(j);
        recover(&d.join("out"));
        recover(&d.join("g"));
        assert_eq!(contents(&e), ["old"; 3]);
        for sub in ["g", "out"] {
            let commit_files = std::fs::read_dir(d.join(sub))
                .unwrap()
                .flatten()
                .filter(|f| {
                    f.file_name()
                        .to_string_lossy()
                        .starts_with(".rayproof-commit")
                })
                .count();
            assert_eq!(commit_files, 0, "{sub}");
        }
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A live run's journal is never touched, and a cut-short journal is never taken for one.
    #[test]
    fn a_live_runs_journal_and_a_cut_journal_are_left_alone() {
        let d = scratch("live");
        let me = std::process::id();
        let e = staged(&d, me);
        let j = begin(&e, me, 3).unwrap();
        recover(&d.join("g"));
        assert_eq!(contents(&e), ["old"; 3]);
        let t = std::fs::read_to_string(&j.journal).unwrap();
        assert!(parse(&t).is_some());
        assert!(parse(t.trim_end_matches("end\n")).is_none());
        assert!(parse(&t[..t.len() / 2]).is_none());
        j.finish();
        std::fs::remove_dir_all(&d).unwrap();
    }
}
