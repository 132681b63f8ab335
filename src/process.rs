//! Running an outside command under control: the one runner of the crate (`audit --exec`
//! batches, `check` renderers, `reference` renderers and their version probes).
//!
//! - **Its own process group**: `sh -c CMD` starts a new group, and everything it starts without
//!   leaving the group is killed with it.
//! - **A deadline that does not depend on its pipes**: the run ends at the deadline whatever the
//!   command does with its standard streams (closes them, redirects them to a file, hands them to
//!   a background process). Standard input is written and closed and both outputs are read in
//!   one `poll(2)` loop whose every wait ends at the deadline.
//! - **Nothing outlives the run**: rayproof is the *subreaper* of its descendants
//!   (`PR_SET_CHILD_SUBREAPER`), so a process that left the group (`setsid`) and outlived its
//!   parent becomes rayproof's child. When the command ends, or at its deadline, its group is
//!   killed and so is every such orphan, and all are reaped.
//! - **Nothing outlives rayproof, even killed by SIGKILL**: the group's leader is a guard (a fork
//!   of the started child that stays behind, `guard`) whose parent-death signal
//!   (`PR_SET_PDEATHSIG`) kills the whole group the moment rayproof dies, however it dies.
//! - **Capped output**: standard output up to a cap the caller gives (beyond it the command is
//!   killed and the error says the cap); standard error keeps its first and last 64 KiB.
//! - **Killed on SIGINT and SIGTERM**: the running groups are registered, and the signal handler
//!   ([`crate::output::clean_up_on_signals`]) kills them and the orphans before it exits.

use std::io::{Read, Write};
use std::os::fd::AsRawFd;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::Path;
use std::process::{Command, ExitStatus, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Standard output kept by default: 256 MiB (a batch of answers or a renderer's log is far
/// smaller).
pub const STDOUT_CAP: usize = 256 << 20;
/// Standard error kept: this much of its start and of its end.
const STDERR_KEEP: usize = 64 << 10;

/// The process groups running now (their leaders' pids), killed on SIGINT or SIGTERM.
static GROUPS: Mutex<Vec<i32>> = Mutex::new(Vec::new());

fn groups(f: impl FnOnce(&mut Vec<i32>)) {
    if let Ok(mut g) = GROUPS.lock() {
        f(&mut g);
    }
}

/// Makes rayproof the subreaper of its descendants, once: orphans become its children.
fn become_subreaper() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // SAFETY: prctl with integer arguments only
        unsafe {
            libc::prctl(libc::PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0);
        }
    });
}

/// On the parent's death (the guard's `PR_SET_PDEATHSIG`): kill the whole group, the guard too.
extern "C" fn kill_own_group(_: libc::c_int) {
    // SAFETY: kill is async-signal-safe
    unsafe {
        libc::kill(0, libc::SIGKILL);
    }
}

/// The guard, in the forked child before `exec`: forks the command (which returns to `exec`),
/// then stays as the group's leader, asks the kernel for SIGTERM when rayproof dies (whose
/// handler kills the whole group), closes every file descriptor (the command's pipes and
/// `Command`'s exec-error pipe stay the command's alone), waits for the command and ends as it
/// ended: its exit code, or the same signal. Only async-signal-safe calls: the parent may have
/// threads.
///
/// # Safety
/// Called only in a child between `fork` and `exec` (a `pre_exec` hook).
unsafe fn guard(parent: libc::pid_t) -> std::io::Result<()> {
    let command = libc::fork();
    if command < 0 {
        return Err(std::io::Error::last_os_error());
    }
    if command == 0 {
        // The command: on to exec
        return Ok(());
    }
    let mut sa: libc::sigaction = std::mem::zeroed();
    sa.sa_sigaction = kill_own_group as *const () as libc::sighandler_t;
    libc::sigaction(libc::SIGTERM, &sa, std::ptr::null_mut());
    let mut set: libc::sigset_t = std::mem::zeroed();
    libc::sigemptyset(&mut set);
    libc::sigaddset(&mut set, libc::SIGTERM);
    libc::sigprocmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
    libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM, 0, 0, 0);
    // rayproof died before the request took effect
    if libc::getppid() != parent {
        libc::kill(0, libc::SIGKILL);
    }
    if libc::syscall(libc::SYS_close_range, 0u32, u32::MAX, 0u32) != 0 {
        for fd in 0..65536 {
            libc::close(fd);
        }
    }
    let mut st = 0;
    loop {
        let r = libc::waitpid(command, &mut st, 0);
        if r == command {
            break;
        }
        if r < 0 && *libc::__errno_location() != libc::EINTR {
            libc::_exit(127);
        }
    }
    if libc::WIFSIGNALED(st) {
        let sig = libc::WTERMSIG(st);
        let none = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        libc::setrlimit(libc::RLIMIT_CORE, &none);
        libc::signal(sig, libc::SIG_DFL);
        libc::kill(libc::getpid(), sig);
    }
    libc::_exit(libc::WEXITSTATUS(st))
}

/// Set by [`interrupt`] (the signal handler's first step) before anything else.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Marks the run interrupted (SIGINT or SIGTERM: from now on no other thread decides how the
/// run ends, and no commit starts), then kills every outside command with all it started.
pub fn interrupt() {
    INTERRUPTED.store(true, std::sync::atomic::Ordering::SeqCst);
    kill_all();
}

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

/// Kills every running group and every orphan rayproof adopted (the signal handler's step).
pub fn kill_all() {
    let mut running = vec![];
    groups(|g| running = g.clone());
    for &pgid in &running {
        // SAFETY: kill(2) on a process group; no memory is touched
        unsafe {
            libc::kill(-pgid, libc::SIGKILL);
        }
    }
    settle(&running);
    kill_orphans();
}

/// A process as `/proc/PID/stat` shows it.
struct Proc {
    pid: i32,
    ppid: i32,
    pgrp: i32,
    zombie: bool,
}

/// Every process `/proc` shows.
fn processes() -> Vec<Proc> {
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return vec![];
    };
    dir.flatten()
        .filter_map(|e| {
            let pid = e.file_name().to_str()?.parse::<i32>().ok()?;
            let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
            // After the command's closing parenthesis: state, ppid, pgrp
            let mut w = stat.rsplit_once(')')?.1.split_whitespace();
            let state = w.next()?;
            Some(Proc {
                pid,
                ppid: w.next()?.parse().ok()?,
                pgrp: w.next()?.parse().ok()?,
                zombie: state == "Z" || state == "X",
            })
        })
        .collect()
}

/// Waits (up to a second) until no live process is left in these killed groups, so that their
/// children have been handed to rayproof, the subreaper, before the orphans are collected.
fn settle(killed: &[i32]) {
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(1)
        && processes()
            .iter()
            .any(|p| !p.zombie && killed.contains(&p.pgrp))
    {
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The pids of rayproof's own children.
fn children() -> Vec<i32> {
    let me = std::process::id() as i32;
    processes()
        .into_iter()
        .filter(|p| p.ppid == me)
        .map(|p| p.pid)
        .collect()
}

/// Kills and reaps every child of rayproof that is not a running command's leader: orphans
/// adopted from the commands' process trees. Repeats while killing them orphans more.
fn kill_orphans() {
    for _ in 0..64 {
        let mut running = vec![];
        groups(|g| running = g.clone());
        let orphans: Vec<i32> = children()
            .into_iter()
            .filter(|p| !running.contains(p))
            .collect();
        if orphans.is_empty() {
            return;
        }
        for &pid in &orphans {
            // SAFETY: kill(2) and waitpid(2) on a child of ours; its group goes too
            unsafe {
                libc::kill(pid, libc::SIGKILL);
                libc::kill(-pid, libc::SIGKILL);
                libc::waitpid(pid, std::ptr::null_mut(), 0);
            }
        }
    }
}

/// Whether the child `pid` has exited, without reaping it (its pid, and so its group's id,
/// stay reserved until it is reaped).
fn has_exited(pid: i32) -> bool {
    // SAFETY: waitid(2) with WNOWAIT fills a siginfo_t we own and reaps nothing
    unsafe {
        let mut info: libc::siginfo_t = std::mem::zeroed();
        libc::waitid(
            libc::P_PID,
            pid as libc::id_t,
            &mut info,
            libc::WEXITED | libc::WNOHANG | libc::WNOWAIT,
        ) == 0
            && info.si_pid() != 0
    }
}

/// What a finished command left.
pub struct Finished {
    /// Its exit status.
    pub status: ExitStatus,
    /// Its standard output (up to the cap).
    pub stdout: Vec<u8>,
    /// Its standard error (the first and last 64 KiB).
    pub stderr: String,
}

/// Standard error kept as its first and last [`STDERR_KEEP`] bytes.
#[derive(Default)]
struct Tail {
    head: Vec<u8>,
    tail: std::collections::VecDeque<u8>,
    dropped: usize,
}

impl Tail {
    fn push(&mut self, bytes: &[u8]) {
        let room = STDERR_KEEP.saturating_sub(self.head.len());
        let (h, rest) = bytes.split_at(room.min(bytes.len()));
        self.head.extend_from_slice(h);
        self.tail.extend(rest);
        while self.tail.len() > STDERR_KEEP {
            self.tail.pop_front();
            self.dropped += 1;
        }
    }
    fn text(&self) -> String {
        let mut s = String::from_utf8_lossy(&self.head).into_owned();
        if self.dropped > 0 {
            s += &format!(
                "\n[… {} bytes of standard error left out …]\n",
                self.dropped
            );
        }
        s + &String::from_utf8_lossy(&self.tail.iter().copied().collect::<Vec<u8>>())
    }
}

/// A running outside process under the module's rules, spoken to through its pipes: what
/// `--exec` children, plugin workers and renderer commands run in. Every exchange has a
/// deadline that holds whatever the process does with its pipes; dropping the session kills
/// the process's group and every orphan it left.
pub struct Session {
    what: String,
    child: std::process::Child,
    pgid: i32,
    stdin: Option<std::process::ChildStdin>,
    stdout: Option<std::process::ChildStdout>,
    stderr: Option<std::process::ChildStderr>,
    /// Output read but not yet taken.
    buf: Vec<u8>,
    errs: Tail,
    status: Option<ExitStatus>,
    stdout_cap: usize,
    /// Its standard output passed the cap (it was killed): every later exchange says so too.
    over_cap: bool,
}

/// Says, from the output read so far, how many of its bytes make a whole answer (`None`: not
/// yet).
pub type Complete<'a> = &'a dyn Fn(&[u8]) -> Option<usize>;

/// How an exchange ended before its answer was complete.
pub enum Broken {
    /// The deadline passed (the process group is killed).
    Deadline,
    /// Standard output passed its cap (killed).
    StdoutCap(usize),
    /// Standard output ended (the process closed it, or exited) before the answer was whole.
    Closed,
}

impl Session {
    /// Starts `program ARGS` (in `dir` when given) in its own process group, its three standard
    /// streams piped. `what` names it in error lines.
    pub fn spawn(
        what: &str,
        program: &Path,
        args: &[&str],
        dir: Option<&Path>,
        env: &[(&str, &str)],
        stdout_cap: usize,
    ) -> Result<Session, String> {
        become_subreaper();
        let mut cmd = Command::new(program);
        let parent = std::process::id() as libc::pid_t;
        // SAFETY: the hook calls only async-signal-safe functions (`guard`)
        unsafe {
            cmd.pre_exec(move || guard(parent));
        }
        cmd.args(args)
            .process_group(0)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        for (k, v) in env {
            cmd.env(k, v);
        }
        if let Some(d) = dir {
            cmd.current_dir(d);
        }
        let mut child = cmd
            .spawn()
            .map_err(|e| format!("{what}: cannot start: {e}"))?;
        let pgid = child.id() as i32;
        groups(|g| g.push(pgid));
        let (stdin, stdout, stderr) =
            (child.stdin.take(), child.stdout.take(), child.stderr.take());
        for fd in [
            stdin.as_ref().map(|s| s.as_raw_fd()),
            stdout.as_ref().map(|s| s.as_raw_fd()),
            stderr.as_ref().map(|s| s.as_raw_fd()),
        ]
        .into_iter()
        .flatten()
        {
            // SAFETY: fcntl on a pipe we own
            unsafe {
                let flags = libc::fcntl(fd, libc::F_GETFL);
                libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK);
            }
        }
        Ok(Session {
            what: what.to_string(),
            child,
            pgid,
            stdin,
            stdout,
            stderr,
            buf: vec![],
            errs: Tail::default(),
            status: None,
            stdout_cap,
            over_cap: false,
        })
    }

    /// Starts `sh -c command` as [`Session::spawn`] does.
    pub fn sh(
        what: &str,
        command: &str,
        dir: Option<&Path>,
        env: &[(&str, &str)],
        stdout_cap: usize,
    ) -> Result<Session, String> {
        Session::spawn(
            what,
            Path::new("sh"),
            &["-c", command],
            dir,
            env,
            stdout_cap,
        )
    }

    /// The name given at the start.
    pub fn what(&self) -> &str {
        &self.what
    }

    /// Closes the process's standard input (it sees the end of its input).
    pub fn close_input(&mut self) {
        self.stdin = None;
    }

    /// Writes `input` (then closes standard input if `close`), reading the process's output
    /// meanwhile, until `complete` says how many bytes of the output make the answer (it is
    /// given everything read so far, and returns `Some(n)` once the answer is whole; with `None`
    /// for `complete`, the answer is all the output, up to its end). Every wait ends at
    /// `deadline`. The answer's bytes are taken from the output; the rest stays for the next
    /// exchange.
    pub fn exchange(
        &mut self,
        input: &[u8],
        close: bool,
        complete: Option<Complete>,
        deadline: Instant,
    ) -> Result<Vec<u8>, Broken> {
        self.exchange_or_wait(input, close, complete, deadline, true)
    }

    /// Output read but not yet taken by an exchange (what a process said before it broke off).
    pub fn pending(&self) -> &[u8] {
        &self.buf
    }

    /// Reads the process's output until `complete` says the answer is whole, or until `until`
    /// passes, which (unlike an exchange's deadline) leaves the process running: `None` then.
    pub fn wait_for(
        &mut self,
        complete: &dyn Fn(&[u8]) -> Option<usize>,
        until: Instant,
    ) -> Option<Vec<u8>> {
        self.exchange_or_wait(b"", false, Some(complete), until, false)
            .ok()
    }

    fn exchange_or_wait(
        &mut self,
        input: &[u8],
        close: bool,
        complete: Option<Complete>,
        deadline: Instant,
        kill_at_deadline: bool,
    ) -> Result<Vec<u8>, Broken> {
        // Killed at the cap in an earlier exchange (a `wait_for` whose caller only sees "not
        // yet"): the cap, not the kill, is what the next one reports (it said "failed (signal
        // 9) after 1 of 20 answers" for `cat /dev/zero`, one run in two)
        if self.over_cap {
            return Err(Broken::StdoutCap(self.stdout_cap));
        }
        let mut written = 0;
        let mut chunk = vec![0u8; 1 << 16];
        let mut exited_at: Option<Instant> = None;
        loop {
            if written == input.len() && close {
                self.stdin = None;
            }
            // The answer may already be whole
            if let Some(f) = complete {
                if written == input.len() {
                    if let Some(n) = f(&self.buf) {
                        return Ok(self.buf.drain(..n).collect());
                    }
                }
            }
            if self.stdout.is_none()
                && self.stderr.is_none()
                && (self.status.is_some() || complete.is_some())
            {
                if complete.is_some() {
                    return Err(Broken::Closed);
                }
                return Ok(std::mem::take(&mut self.buf));
            }
            // The process ended: its group and what it left go now; pipes still open after a
            // moment are held by a process we could not see, and are given up
            if self.status.is_none() && has_exited(self.pgid) {
                self.end_group();
                self.status = self.child.try_wait().ok().flatten();
                exited_at = Some(Instant::now());
            }
            if exited_at.is_some_and(|t| t.elapsed() > Duration::from_millis(500)) {
                self.stdout = None;
                self.stderr = None;
                continue;
            }
            let now = Instant::now();
            if now >= deadline {
                if kill_at_deadline {
                    self.kill();
                }
                return Err(Broken::Deadline);
            }
            // Wait for any stream, at most until the deadline (and briefly, to see an exit)
            let mut fds = vec![];
            let pending_input = written < input.len();
            for (fd, ev) in [
                (
                    self.stdin
                        .as_ref()
                        .filter(|_| pending_input)
                        .map(|s| s.as_raw_fd()),
                    libc::POLLOUT,
                ),
                (self.stdout.as_ref().map(|s| s.as_raw_fd()), libc::POLLIN),
                (self.stderr.as_ref().map(|s| s.as_raw_fd()), libc::POLLIN),
            ] {
                if let Some(fd) = fd {
                    fds.push(libc::pollfd {
                        fd,
                        events: ev,
                        revents: 0,
                    });
                }
            }
            let wait = (deadline - now).min(Duration::from_millis(20));
            // SAFETY: poll(2) on a valid array of pollfd
            unsafe {
                libc::poll(
                    fds.as_mut_ptr(),
                    fds.len() as libc::nfds_t,
                    wait.as_millis() as i32,
                );
            }
            if pending_input {
                if let Some(s) = self.stdin.as_mut() {
                    match s.write(&input[written..]) {
                        Ok(n) => written += n,
                        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                        // The process closed its input: it chose to stop reading
                        Err(_) => {
                            self.stdin = None;
                            written = input.len();
                        }
                    }
                } else {
                    written = input.len();
                }
            }
            if let Some(o) = self.stdout.as_mut() {
                match o.read(&mut chunk) {
                    Ok(0) => self.stdout = None,
                    Ok(n) => {
                        self.buf.extend_from_slice(&chunk[..n]);
                        if self.buf.len() > self.stdout_cap {
                            self.over_cap = true;
                            self.kill();
                            return Err(Broken::StdoutCap(self.stdout_cap));
                        }
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                    Err(_) => self.stdout = None,
                }
            }
            if let Some(e) = self.stderr.as_mut() {
                match e.read(&mut chunk) {
                    Ok(0) => self.stderr = None,
                    Ok(n) => self.errs.push(&chunk[..n]),
                    Err(x) if x.kind() == std::io::ErrorKind::WouldBlock => {}
                    Err(_) => self.stderr = None,
                }
            }
        }
    }

    /// The process's exit status once it has ended (waiting up to `grace` for it).
    pub fn wait(&mut self, grace: Duration) -> Option<ExitStatus> {
        let until = Instant::now() + grace;
        while self.status.is_none() {
            if has_exited(self.pgid) {
                self.end_group();
                self.status = self.child.try_wait().ok().flatten();
            } else if Instant::now() >= until {
                break;
            } else {
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        self.status
    }

    /// What it wrote to standard error so far (its first and last 64 KiB).
    pub fn stderr(&self) -> String {
        self.errs.text()
    }

    /// Kills the group and its orphans, now.
    pub fn kill(&mut self) {
        if self.status.is_none() {
            // SAFETY: kill(2) on the group its unreaped leader holds
            unsafe {
                libc::kill(-self.pgid, libc::SIGKILL);
            }
            settle(&[self.pgid]);
            self.status = self.child.wait().ok();
        }
        kill_orphans();
        self.stdin = None;
        self.stdout = None;
        self.stderr = None;
    }

    /// The leader has exited (unreaped): its group and its orphans go.
    fn end_group(&mut self) {
        // SAFETY: kill(2) on the group its unreaped leader still holds
        unsafe {
            libc::kill(-self.pgid, libc::SIGKILL);
        }
        settle(&[self.pgid]);
        kill_orphans();
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        self.kill();
        groups(|g| g.retain(|&p| p != self.pgid));
        // Killed by the signal handler: not the command's failure; the handler ends the run
        wait_if_interrupted();
    }
}

/// Runs `sh -c command` (in `dir` when given) with `input` on its standard input, under the
/// rules of the module: its output, or why it could not run, was stopped (deadline, output cap:
/// its group killed) or failed. `what` names the command in the error lines.
pub fn run(
    what: &str,
    command: &str,
    dir: Option<&Path>,
    input: &[u8],
    timeout: Duration,
    stdout_cap: usize,
) -> Result<Finished, String> {
    run_logged(what, command, dir, input, timeout, stdout_cap).0
}

/// [`run`], and the standard error the command wrote (its first and last 64 KiB) however the
/// run ended: a renderer's log is wanted most when it was killed at its deadline.
pub fn run_logged(
    what: &str,
    command: &str,
    dir: Option<&Path>,
    input: &[u8],
    timeout: Duration,
    stdout_cap: usize,
) -> (Result<Finished, String>, String) {
    let deadline = Instant::now() + timeout;
    let mut s = match Session::sh(what, command, dir, &[], stdout_cap) {
        Ok(s) => s,
        Err(e) => return (Err(e), String::new()),
    };
    let out = s.exchange(input, true, None, deadline);
    let status = s.wait(Duration::from_millis(100));
    let stderr = s.stderr();
    let r = match out {
        Err(Broken::Deadline) => Err(format!(
            "{what}: did not finish within {} s (killed)",
            timeout.as_secs_f64()
        )),
        Err(Broken::StdoutCap(cap)) => Err(format!(
            "{what}: wrote more than {} MiB to standard output (killed; the cap is {cap} bytes)",
            cap >> 20
        )),
        Err(Broken::Closed) => unreachable!("a whole-output exchange ends with the output"),
        Ok(stdout) => Ok(Finished {
            status: status.unwrap_or_else(|| ExitStatus::from_raw(-1)),
            stdout,
            stderr: stderr.clone(),
        }),
    };
    (r, stderr)
}

/// Lines of a renderer's standard error that say nothing about why it failed, though they say
/// `cannot`, `error` or `fatal`: POV-Ray 3.7 prints `povray: cannot open the user configuration
/// file …` on every run without one, and its option listing has `Fatal Stream to
/// console.........On` (settings with dot leaders).
fn noise(line: &str) -> bool {
    let l = line.to_lowercase();
    // A setting: a label of words, then dot leaders
    let setting = line.find("....").is_some_and(|i| {
        i > 0
            && line[..i]
                .chars()
                .all(|c| c.is_ascii_alphabetic() || c == ' ')
    });
    l.contains("cannot open the user configuration file") || setting
}

/// The lines of a command's standard error that explain how it ended, in the order written,
/// without repeats or known noise (`noise`): the first `says_max` that say error, fatal or
/// cannot (or can't, failed, traceback, out of memory), and the last `last` non-empty lines (a
/// renderer's first line is often noise, its last ones the reason).
pub fn explaining_lines(stderr: &str, says_max: usize, last: usize) -> Vec<&str> {
    explaining_lines_with(stderr, says_max, last, &[])
}

/// [`explaining_lines`], `also` words counting as saying something (a row's log tail keeps a
/// renderer's `warning` lines).
pub fn explaining_lines_with<'a>(
    stderr: &'a str,
    says_max: usize,
    last: usize,
    also: &[&str],
) -> Vec<&'a str> {
    let lines: Vec<&str> = stderr
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !noise(l))
        .collect();
    let says = |l: &str| {
        let l = l.to_lowercase();
        [
            "error",
            "fatal",
            "cannot",
            "can't",
            "failed",
            "traceback",
            "out of memory",
        ]
        .iter()
        .chain(also)
        .any(|w| l.contains(w))
    };
    let says_idx: Vec<usize> = (0..lines.len())
        .filter(|&i| says(lines[i]))
        .take(says_max)
        .collect();
    let last = lines.len().saturating_sub(last)..lines.len();
    let mut picked: Vec<&str> = vec![];
    for (i, &l) in lines.iter().enumerate() {
        if (says_idx.contains(&i) || last.contains(&i)) && !picked.contains(&l) {
            picked.push(l);
        }
    }
    picked
}

/// The lines of a failed command's standard error that explain it, as one line: the first four
/// that say error, fatal or cannot, and the last three ([`explaining_lines`]), joined by ` | `;
/// at most 600 characters, its end kept (where the reason is).
pub fn explain(stderr: &str) -> String {
    let s = explaining_lines(stderr, 4, 3).join(" | ");
    let n = s.chars().count();
    if n > 600 {
        return "… ".to_string() + &s.chars().skip(n - 600).collect::<String>();
    }
    s
}

/// Why a finished command failed, one line (`None`: it exited 0): `WHAT failed (exit status:
/// N): ` and the lines of its standard error that explain it ([`explain`]).
pub fn failure(what: &str, f: &Finished) -> Option<String> {
    if f.status.success() {
        return None;
    }
    let why = explain(&f.stderr);
    let status = match f.status.signal() {
        Some(s) => format!("signal: {s}"),
        None => format!("exit status: {}", f.status.code().unwrap_or(-1)),
    };
    Some(format!(
        "{what} failed ({status}){}",
        if why.is_empty() {
            String::new()
        } else {
            format!(": {why}")
        }
    ))
}

/// Runs `sh -c command` as [`run`] does and returns its standard output as text (invalid UTF-8
/// replaced by U+FFFD), or one line saying why it failed: it could not start, did not finish
/// within `timeout`, wrote more than [`STDOUT_CAP`], or exited with a failure (with the lines
/// of its standard error that explain it).
pub fn run_with_timeout(
    what: &str,
    command: &str,
    dir: Option<&Path>,
    input: String,
    timeout: Duration,
) -> Result<String, String> {
    run_capped(what, command, dir, input, timeout, STDOUT_CAP)
}

/// [`run_with_timeout`] with another cap on standard output.
pub fn run_capped(
    what: &str,
    command: &str,
    dir: Option<&Path>,
    input: String,
    timeout: Duration,
    stdout_cap: usize,
) -> Result<String, String> {
    let f = run(what, command, dir, input.as_bytes(), timeout, stdout_cap)?;
    if let Some(e) = failure(what, &f) {
        return Err(e);
    }
    Ok(String::from_utf8_lossy(&f.stdout).into_owned())
}

#[cfg(test)]
mod tests {
    use super::explain;

    #[test]
    fn explain_shows_the_reason_not_the_noise() {
        // POV-Ray 3.7's standard error for a missing include (abridged, as it prints it)
        let pov = "povray: cannot open the user configuration file /root/.povray/3.7/povray.conf: No such file or directory\n\
                   Persistence of Vision(tm) Ray Tracer Version 3.7.0.10.unofficial (g++ @\n\
                   Information Output Options\n  Fatal Stream to console.........On \n\
                   ==== [Parsing...] ==========================================================\n\
                   File 'a.pov' line 2: Parse Error: Cannot open include file light.inc.\n\
                   Fatal error in parser: Cannot parse input.\nRender failed\n\n";
        let e = explain(pov);
        assert!(e.contains("Cannot open include file light.inc"), "{e}");
        assert!(!e.contains("user configuration file"), "{e}");
        assert!(!e.contains("Stream to console"), "{e}");
        assert!(e.ends_with("Render failed"), "{e}");
        // A warning first, the reason last
        let gpu = "warning: GPU driver is old\nloading scene\nout of memory\n";
        assert!(explain(gpu).contains("out of memory"));
        // Long: the end is kept
        let long = format!("{}\nthe reason\n", "x".repeat(2000));
        let e = explain(&long);
        assert!(e.ends_with("the reason") && e.chars().count() < 610, "{e}");
    }
}
