//! Every outside process under control: an `--exec` child (and everything it starts) is killed
//! with its process group at its deadline, whatever it does with its pipes, and nothing of it
//! outlives the run. (The renderer of a suite: tests/suite.rs.)

use crate::common::{rayproof_in, scratch, stderr};
use std::path::Path;
use std::time::Instant;

/// Whether a process is alive (not a zombie) by the pid written in `file`.
fn alive(file: &Path) -> bool {
    let Ok(pid) = std::fs::read_to_string(file) else {
        return false;
    };
    std::fs::read_to_string(format!("/proc/{}/stat", pid.trim())).is_ok_and(|s| {
        let state = s.rsplit(')').next().unwrap_or("").trim_start();
        !state.starts_with('Z') && !state.starts_with('X')
    })
}

#[test]
fn an_exec_child_is_killed_at_its_deadline_whatever_it_does_with_its_pipes() {
    let dir = scratch("deadline-exec");
    for (tag, cmd, want) in [
        // Closes its stdout and stderr and lives on
        (
            "closes",
            "echo $$ > closes.pid; exec sleep 30 > /dev/null 2> /dev/null",
            Some(4),
        ),
        // Hands stdout to a file and hangs (the check renderer of the issue, through --exec)
        (
            "log",
            "echo $$ > log.pid; exec sh -c 'sleep 30' > exec.log 2>&1",
            Some(4),
        ),
        // A grandchild holds only stderr while the child hangs
        (
            "stderr",
            "sh -c 'echo $$ > stderr.pid; exec sleep 30' > /dev/null & sleep 30",
            Some(4),
        ),
        // A grandchild that left the group (setsid) keeps stdout; the child answers and exits:
        // the answers count, the grandchild is killed with the run
        (
            "setsid",
            "setsid sh -c 'echo $$ > setsid.pid; exec sleep 300' & awk '{print 0}'",
            Some(0),
        ),
    ] {
        let t0 = Instant::now();
        let o = rayproof_in(
            Some(&dir),
            &[
                "audit",
                "--shape",
                "sphere",
                "--class",
                "random",
                "--precision",
                "f64",
                "--cases",
                "20",
                "--exec",
                cmd,
                "--exec-timeout",
                "2",
            ],
        );
        let wall = t0.elapsed().as_secs_f64();
        let err = stderr(&o);
        let code = o.status.code();
        if want == Some(4) {
            assert_eq!(code, Some(4), "{tag}: {err}");
            assert!(
                err.contains("did not finish within 2 s (killed)"),
                "{tag}: {err}"
            );
            assert_eq!(err.trim_end().lines().count(), 1, "{tag}: {err}");
        } else {
            assert!(matches!(code, Some(0 | 1)), "{tag}: {err}");
        }
        assert!(wall < 4.0, "{tag}: took {wall:.1} s for a 2 s deadline");
        std::thread::sleep(std::time::Duration::from_millis(200));
        let pid = dir.join(format!("{tag}.pid"));
        assert!(pid.exists(), "{tag}: the command did not start");
        assert!(!alive(&pid), "{tag}: a process outlived the run");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_exec_child_that_floods_stdout_is_stopped_at_the_cap() {
    // `yes` prints forever: stopped by the deadline or the output cap, never an exhausted memory
    let dir = scratch("deadline-flood");
    let t0 = Instant::now();
    let o = rayproof_in(
        Some(&dir),
        &[
            "audit",
            "--shape",
            "sphere",
            "--class",
            "random",
            "--cases",
            "20",
            "--exec",
            "yes",
            "--exec-timeout",
            "3",
        ],
    );
    assert_eq!(o.status.code(), Some(4), "{}", stderr(&o));
    assert!(t0.elapsed().as_secs_f64() < 6.0);
    std::fs::remove_dir_all(&dir).ok();
}

/// Starts `rayproof audit --exec CMD` (20 random sphere cases, a 600 s exec timeout) in `dir`
/// and waits until CMD has written each of `pids` (its processes are running).
fn audit_exec_started(dir: &Path, cmd: &str, pids: &[&str]) -> std::process::Child {
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(dir)
        .args([
            "audit",
            "--shape",
            "sphere",
            "--class",
            "random",
            "--cases",
            "20",
            "--exec",
            cmd,
            "--exec-timeout",
            "600",
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !pids.iter().all(|f| dir.join(f).exists()) {
        assert!(
            t0.elapsed().as_secs() < 20,
            "{cmd}: the child never started"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child
}

#[test]
fn sigterm_and_sigint_kill_the_exec_child_and_all_it_started() {
    let dir = scratch("deadline-signal");
    for (tag, sig) in [("term", libc::SIGTERM), ("int", libc::SIGINT)] {
        let cmd = format!(
            "echo $$ > {tag}.pid; setsid sh -c 'echo $$ > {tag}-away.pid; exec sleep 300' & sleep 300"
        );
        let mut child = audit_exec_started(
            &dir,
            &cmd,
            &[&format!("{tag}.pid"), &format!("{tag}-away.pid")],
        );
        // SAFETY: kill(2) on the rayproof process this test started
        unsafe {
            libc::kill(child.id() as i32, sig);
        }
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(130), "{tag}");
        std::thread::sleep(std::time::Duration::from_millis(200));
        for f in [format!("{tag}.pid"), format!("{tag}-away.pid")] {
            assert!(!alive(&dir.join(&f)), "{tag}: {f} outlived rayproof");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Runs rayproof in `dir` with `args` while this test, a process outside rayproof's tree that
/// rayproof can neither see nor kill, holds the command's standard output and/or error: the
/// command writes its pid to `cmd.pid` and waits for `held` before it goes on. Returns the exit
/// code, stdout and stderr, and the wall time; a run that has not ended after `limit` seconds is
/// killed and the test fails.
fn with_pipes_held_from_outside(
    dir: &Path,
    args: &[&str],
    fds: &[u32],
    limit: f64,
) -> (Option<i32>, String, String, f64) {
    let (out, err) = (dir.join("rayproof.out"), dir.join("rayproof.err"));
    let t0 = Instant::now();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(dir)
        .args(args)
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let pid_file = dir.join("cmd.pid");
    let mut held = vec![];
    let status = loop {
        if held.is_empty() {
            if let Some(pid) = std::fs::read_to_string(&pid_file)
                .ok()
                .and_then(|p| p.trim().parse::<u32>().ok())
            {
                // The command's own pipe ends, opened through /proc by this process
                for fd in fds {
                    held.push(
                        std::fs::OpenOptions::new()
                            .write(true)
                            .open(format!("/proc/{pid}/fd/{fd}"))
                            .unwrap(),
                    );
                }
                std::fs::write(dir.join("held"), "").unwrap();
            }
        }
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed().as_secs_f64() > limit {
            child.kill().ok();
            child.wait().ok();
            panic!(
                "{args:?} with fds {fds:?} held from outside: still running after {limit} s\n{}",
                std::fs::read_to_string(&err).unwrap_or_default()
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let wall = t0.elapsed().as_secs_f64();
    assert!(!held.is_empty(), "{args:?}: the command never started");
    drop(held);
    (
        status.code(),
        std::fs::read_to_string(&out).unwrap(),
        std::fs::read_to_string(&err).unwrap(),
        wall,
    )
}

/// The give-up path of `process.rs`: a command that has exited while a process outside
/// rayproof's tree (not a descendant: no group kill or subreaper reaches it) still holds its
/// standard output, its standard error or both. rayproof gives the pipes up after its grace and
/// the run ends as the command's did: a renderer under `check`, an `--exec` child (one for the
/// run, which rayproof reads to its end for stray lines), each well within the deadline.
#[test]
fn a_pipe_held_from_outside_the_tree_does_not_outlive_the_deadline() {
    let wait = "echo $$ > cmd.pid; while [ ! -e held ]; do sleep 0.02; done";
    for (tag, fds) in [("out", &[1][..]), ("err", &[2][..]), ("both", &[1, 2][..])] {
        // check: the stand-in renderer writes its image, then the shell exits
        let dir = scratch(&format!("deadline-held-check-{tag}"));
        let standin = crate::common::outside("standin_render.py");
        let suite = format!(
            r#"[suite]
name = "held"
renderer = "{wait}; python3 '{}' {{out}} --width 16 --grid 1"
goldens = "goldens"
timeout = 20

[[test]]
name = "a"
"#,
            standin.display()
        );
        std::fs::write(dir.join("suite.toml"), suite).unwrap();
        let (code, out, err, wall) = with_pipes_held_from_outside(
            &dir,
            &["check", "--suite", "suite.toml", "--update"],
            fds,
            60.0,
        );
        assert_eq!(code, Some(0), "check, {tag} held: {out}{err}");
        assert!(
            wall < 20.0,
            "check, {tag} held: {wall:.1} s for a 20 s deadline"
        );
        assert!(dir.join("goldens/a.exr").exists(), "{out}");
        std::fs::remove_dir_all(&dir).ok();

        // --exec: one child for the run answers every case and exits
        let dir = scratch(&format!("deadline-held-exec-{tag}"));
        let cmd = format!("{wait}; awk '{{print 0}}'");
        let (code, out, err, wall) = with_pipes_held_from_outside(
            &dir,
            &[
                "audit",
                "--shape",
                "sphere",
                "--class",
                "random",
                "--precision",
                "f64",
                "--cases",
                "20",
                "--exec",
                &cmd,
                "--exec-timeout",
                "20",
            ],
            fds,
            60.0,
        );
        assert!(
            matches!(code, Some(0 | 1)),
            "--exec, {tag} held: {out}{err}"
        );
        assert!(
            wall < 20.0,
            "--exec, {tag} held: {wall:.1} s for a 20 s deadline"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// Issue 46 (10): SIGKILL cannot be caught, yet an `--exec` child and what it started in its
/// group die with rayproof: the group's leader is a guard whose parent-death signal kills the
/// group. (Before the guard, `sleep` ran on for its 300 s as an orphan.) The renderers of
/// `check` and `reference` run under the same runner.
#[test]
fn sigkill_of_rayproof_kills_the_exec_child_and_its_group() {
    let dir = scratch("deadline-sigkill");
    let cmd = "echo $$ > sh.pid; sh -c 'echo $$ > inner.pid; exec sleep 300' & sleep 300";
    let mut child = audit_exec_started(&dir, cmd, &["sh.pid", "inner.pid"]);
    std::thread::sleep(std::time::Duration::from_millis(100));
    child.kill().unwrap();
    child.wait().unwrap();
    let t0 = Instant::now();
    while ["sh.pid", "inner.pid"].iter().any(|f| alive(&dir.join(f))) {
        assert!(
            t0.elapsed().as_secs() < 10,
            "the child outlived a SIGKILLed rayproof by 10 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::fs::remove_dir_all(&dir).ok();
}
