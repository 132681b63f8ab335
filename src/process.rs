//! Running an outside command with a time limit: `sh -c CMD` in its own process group, its
//! standard input written and closed, its output read to the end, the whole group killed when
//! the limit passes. The one runner of the crate: `audit --exec` (a routine's batch) and
//! `check --suite` (a renderer's command) both use it.

use std::io::{Read, Write};
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

/// Runs `sh -c command` (in `dir` when given) with `input` on its standard input; its standard
/// output (invalid UTF-8 replaced by U+FFFD), or one line saying why it failed: it could not start, did not finish within
/// `timeout` (then its process group is killed), or exited with a failure (with the first
/// non-empty line of its standard error). `what` names the command in those lines.
pub fn run_with_timeout(
    what: &str,
    command: &str,
    dir: Option<&Path>,
    input: String,
    timeout: Duration,
) -> Result<String, String> {
    // Its own process group, so that a timeout kills whatever it started
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg(command)
        .process_group(0)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if let Some(d) = dir {
        cmd.current_dir(d);
    }
    let mut child = cmd
        .spawn()
        .map_err(|e| format!("{what}: cannot start: {e}"))?;
    // Write the input and close it, while the output is read
    let mut stdin = child.stdin.take().expect("piped");
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(input.as_bytes());
    });
    let (mut out, mut err) = (
        child.stdout.take().expect("piped"),
        child.stderr.take().expect("piped"),
    );
    let (tx, rx) = mpsc::channel();
    let reader = std::thread::spawn(move || {
        // Bytes that are not UTF-8 (a renderer's progress bar) are kept as U+FFFD, never an error
        let mut bytes = Vec::new();
        let r = out
            .read_to_end(&mut bytes)
            .map(|_| String::from_utf8_lossy(&bytes).into_owned());
        let _ = tx.send(r);
    });
    let errs = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = err.read_to_string(&mut text);
        text
    });
    // The whole run within the limit, or the group is killed
    let out = match rx.recv_timeout(timeout) {
        Ok(r) => r,
        Err(_) => {
            // SAFETY: kill(2) on the child's process group; no memory is touched
            unsafe {
                libc::kill(-(child.id() as i32), libc::SIGKILL);
            }
            let _ = child.wait();
            let _ = (writer.join(), reader.join(), errs.join());
            return Err(format!(
                "{what}: did not finish within {} s (killed)",
                timeout.as_secs_f64()
            ));
        }
    };
    // Its exit status, with the first line it wrote to standard error
    let status = child.wait().map_err(|e| format!("{what}: {e}"))?;
    let _ = (writer.join(), reader.join());
    let stderr = errs.join().unwrap_or_default();
    let first_err = stderr.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    if !status.success() {
        return Err(format!(
            "{what} failed ({status}){}",
            if first_err.is_empty() {
                String::new()
            } else {
                format!(": {}", first_err.trim())
            }
        ));
    }
    out.map_err(|e| format!("{what}: cannot read its output: {e}"))
}
