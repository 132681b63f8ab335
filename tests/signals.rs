//! All or nothing under SIGINT and SIGTERM: runs of `render`, `report`, `audit --json
//! --shard-out` and `check --update` interrupted at seeded random moments (before, during and
//! after their work) leave every old output byte-identical or every output new, never a mix;
//! and no temporary, scratch directory or process of theirs behind.
//!
//! 210 interrupted runs by default (`RAYPROOF_SIGNAL_RUNS` scales them), one test per command.

use crate::common::{outside, scratch};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A seeded stream (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// What an output holds: a file's bytes (under the empty name), or every file of a directory by
/// relative name.
type Contents = Vec<(String, Vec<u8>)>;

/// The bytes of an output: a file's, or every file of a directory (by relative name).
fn contents(p: &Path) -> Option<Contents> {
    let m = std::fs::symlink_metadata(p).ok()?;
    if m.is_file() {
        return Some(vec![(String::new(), std::fs::read(p).ok()?)]);
    }
    let mut v = vec![];
    let mut stack = vec![p.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).ok()?.flatten() {
            let q = e.path();
            if q.is_dir() {
                stack.push(q);
            } else {
                let rel = q.strip_prefix(p).unwrap().display().to_string();
                v.push((rel, std::fs::read(&q).ok()?));
            }
        }
    }
    v.sort();
    Some(v)
}

/// One command under test: how to run it (old and new) and which outputs it writes.
struct Case {
    name: &'static str,
    dir: PathBuf,
    outputs: Vec<PathBuf>,
    new_args: Vec<String>,
    runs: usize,
}

fn rayproof(dir: &Path, args: &[String]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(dir)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// Runs to completion (the old outputs).
fn complete(dir: &Path, args: &[String]) -> Duration {
    let t0 = Instant::now();
    let st = rayproof(dir, args).wait().unwrap();
    assert!(matches!(st.code(), Some(0 | 1)), "{args:?}: {st}");
    t0.elapsed()
}

/// Files in `dir` (recursively) that look like rayproof temporaries, and scratch directories
/// of process `pid`.
fn leftovers(dir: &Path, pid: u32) -> Vec<String> {
    let mut v = vec![];
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if n.contains(".rayproof-") && n != ".rayproof-output" {
                v.push(e.path().display().to_string());
            }
            if e.path().is_dir() {
                stack.push(e.path());
            }
        }
    }
    for e in std::fs::read_dir(std::env::temp_dir())
        .into_iter()
        .flatten()
        .flatten()
    {
        // rayproof's scratch directories, `rayproof-TAG-PID-NONCE` (16 hex digits): not another
        // test's `rayproof-…-N-…` whose N is this run's pid again
        let n = e.file_name().to_string_lossy().into_owned();
        let ours = n
            .split_once(&format!("-{pid}-"))
            .is_some_and(|(head, nonce)| {
                head.starts_with("rayproof-")
                    && nonce.len() == 16
                    && nonce.chars().all(|c| c.is_ascii_hexdigit())
            });
        if ours {
            v.push(e.path().display().to_string());
        }
    }
    v
}

/// One command (`render`, `audit`, `check` for `check --update`, `report`) with its old
/// outputs in place.
fn setup(which: &str) -> Case {
    let scale: f64 = std::env::var("RAYPROOF_SIGNAL_RUNS")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .map_or(1.0, |n| n / 210.0);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let d = scratch(&format!("signals-{which}")).join(which);
    std::fs::create_dir_all(&d).unwrap();
    // The old outputs: one complete run of `old`
    let case = |name, outputs: &[&str], old: Vec<String>, new_args, runs: usize| {
        complete(&d, &old);
        Case {
            name,
            outputs: outputs.iter().map(|f| d.join(f)).collect(),
            dir: d.clone(),
            new_args,
            runs: ((runs as f64 * scale).round() as usize).max(1),
        }
    };
    match which {
        "render" => {
            // render: the EXR, its sidecar and the PNG
            let scene = root.join("reference/scenes/fan30.toml");
            let render = |w: &str| {
                strings(&[
                    "render",
                    scene.to_str().unwrap(),
                    "--width",
                    w,
                    "-o",
                    "o.exr",
                    "--png",
                    "o.png",
                ])
            };
            case(
                "render",
                &["o.exr", "o.exr.json", "o.png"],
                render("96"),
                render("160"),
                80,
            )
        }
        "audit" => {
            // audit: the JSON, the Markdown and the shard, together
            let audit = |seed: &str| {
                strings(&[
                    "audit",
                    "--shape",
                    "rcp,box,sphere",
                    "--cases",
                    "1000",
                    "--seed",
                    seed,
                    "--json",
                    "a.json",
                    "--markdown",
                    "a.md",
                    "--shard-out",
                    "s.json",
                ])
            };
            case(
                "audit",
                &["a.json", "a.md", "s.json"],
                audit("1"),
                audit("2"),
                86,
            )
        }
        "check" => {
            // check --update: goldens, their manifest, the report directory and the JSON
            let suite = |perturb: &str| {
                format!(
                    "[suite]\nrenderer = \"echo $$ >> pids; python3 {} {{out}} --width 48 --grid 2 --perturb {perturb}\"\ngoldens = \"goldens\"\n\n[[test]]\nname = \"a\"\n\n[[test]]\nname = \"b\"\n",
                    outside("standin_render.py").display()
                )
            };
            std::fs::write(d.join("old.toml"), suite("0")).unwrap();
            std::fs::write(d.join("new.toml"), suite("0.25")).unwrap();
            let check = |s: &str| {
                strings(&[
                    "check", "--suite", s, "--update", "--report", "rep", "--json", "c.json",
                ])
            };
            let outputs = [
                "goldens/a.exr",
                "goldens/b.exr",
                "goldens/manifest.json",
                "rep",
                "c.json",
            ];
            case(
                "check --update",
                &outputs,
                check("old.toml"),
                check("new.toml"),
                40,
            )
        }
        "report" => {
            // report: a whole directory
            let out = d.join("rep");
            let report = |seed: &str| {
                strings(&[
                    "report",
                    "--quick",
                    "--seed",
                    seed,
                    "--out",
                    out.to_str().unwrap(),
                    "--reference",
                    root.join("reference").to_str().unwrap(),
                ])
            };
            case("report", &["rep"], report("1"), report("2"), 4)
        }
        _ => unreachable!("{which}"),
    }
}

/// Interrupts `which`'s runs at seeded moments (its own stream: the same moments whichever
/// commands run and in what order), checking after each that its outputs are all old or all
/// new and that nothing of it is left.
fn interrupted_runs(which: &str, seed: u64) {
    let mut rng = Rng(seed);
    let mut total = 0;
    let mut tally = vec![];
    {
        let case = setup(which);
        let old: Vec<_> = case.outputs.iter().map(|p| contents(p)).collect();
        assert!(
            old.iter().all(|c| c.is_some()),
            "{}: old outputs missing",
            case.name
        );
        // A complete new run: how long one takes (interrupts land before, during and after its
        // work), and that it replaces every output
        let span = complete(&case.dir, &case.new_args);
        let new: Vec<_> = case.outputs.iter().map(|p| contents(p)).collect();
        assert!(
            new.iter().zip(&old).all(|(n, o)| n != o),
            "{}: a complete new run left some output as it was",
            case.name
        );
        let (mut old_kept, mut all_new) = (0, 0);
        for i in 0..case.runs {
            // Back to the old outputs (a full old run), then interrupt a new one
            restore(&case, &old);
            let delay = span.mul_f64(1.2 * rng.unit());
            let sig = if i % 2 == 0 {
                libc::SIGTERM
            } else {
                libc::SIGINT
            };
            let mut child = rayproof(&case.dir, &case.new_args);
            let pid = child.id();
            std::thread::sleep(delay);
            // SAFETY: kill(2) on the child this test started
            unsafe {
                libc::kill(pid as i32, sig);
            }
            let st = child.wait().unwrap();
            let now: Vec<_> = case.outputs.iter().map(|p| contents(p)).collect();
            let same_old = now.iter().zip(&old).filter(|(a, b)| a == b).count();
            let n = case.outputs.len();
            assert!(
                same_old == n || now.iter().zip(&old).all(|(a, b)| a != b),
                "{} run {i} ({st}, after {delay:?}): a mix of old and new outputs ({same_old} of {n} old)",
                case.name
            );
            if same_old == n {
                old_kept += 1;
            } else {
                all_new += 1;
            }
            assert!(
                st.code() == Some(130)
                    || st.code() == Some(0)
                    || st.code() == Some(1)
                    || st.code().is_none(),
                "{} run {i}: exit {st}",
                case.name
            );
            let left = leftovers(&case.dir, pid);
            assert!(
                left.is_empty(),
                "{} run {i}: left behind {left:?}",
                case.name
            );
            total += 1;
        }
        // No renderer of check outlives its run
        let pids = std::fs::read_to_string(case.dir.join("pids")).unwrap_or_default();
        for p in pids.lines() {
            let alive = std::fs::read_to_string(format!("/proc/{p}/stat")).is_ok_and(|s| {
                let state = s.rsplit(')').next().unwrap_or("").trim_start();
                !state.starts_with('Z')
            });
            assert!(!alive, "{}: renderer {p} outlived its run", case.name);
        }
        tally.push(format!(
            "{}: {} runs, {old_kept} all old, {all_new} all new",
            case.name, case.runs
        ));
    }
    eprintln!("{total} interrupted runs\n{}", tally.join("\n"));
    assert!(total >= 1);
}

// One test per command, so that the four run side by side

#[test]
fn interrupted_renders_leave_all_old_or_all_new_outputs_and_nothing_behind() {
    interrupted_runs("render", 20261126);
}

#[test]
fn interrupted_audits_leave_all_old_or_all_new_outputs_and_nothing_behind() {
    interrupted_runs("audit", 20261127);
}

#[test]
fn interrupted_check_updates_leave_all_old_or_all_new_outputs_and_nothing_behind() {
    interrupted_runs("check", 20261128);
}

#[test]
fn interrupted_reports_leave_all_old_or_all_new_outputs_and_nothing_behind() {
    interrupted_runs("report", 20261129);
}

/// Puts the old outputs back exactly (files and directories).
fn restore(case: &Case, old: &[Option<Contents>]) {
    for (p, c) in case.outputs.iter().zip(old) {
        let c = c.as_ref().unwrap();
        if c.len() == 1 && c[0].0.is_empty() {
            std::fs::write(p, &c[0].1).unwrap();
        } else {
            let _ = std::fs::remove_dir_all(p);
            for (rel, bytes) in c {
                let q = p.join(rel);
                std::fs::create_dir_all(q.parent().unwrap()).unwrap();
                std::fs::write(q, bytes).unwrap();
            }
        }
    }
}
