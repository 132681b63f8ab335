//! A user's files are sacred: rayproof writes only what it made, never over an input of the
//! same run, never over a directory it did not make, and its clean-up touches nothing of the
//! user's. Each case below destroyed a user's file before (the issue "Nothing lost, nothing
//! hangs"); each checks the user's files byte for byte.

use crate::common::{rayproof_in, s, scratch, stderr};
use std::path::{Path, PathBuf};

/// Every file under `dir` with its bytes, sorted (symbolic links as their targets' names).
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut v = vec![];
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            let m = std::fs::symlink_metadata(&p).unwrap();
            if m.is_dir() {
                stack.push(p.clone());
                v.push((p, b"<dir>".to_vec()));
            } else if m.is_symlink() {
                v.push((
                    p.clone(),
                    std::fs::read_link(&p)
                        .unwrap()
                        .to_string_lossy()
                        .into_owned()
                        .into_bytes(),
                ));
            } else {
                v.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    v.sort();
    v
}

fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("s.toml");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/scenes/diffuse.toml"),
        &p,
    )
    .unwrap();
    p
}

/// Refused with one line and exit 2, the directory byte-identical.
fn refused(dir: &Path, args: &[&str], what: &str) {
    let before = snapshot(dir);
    let o = rayproof_in(Some(dir), args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(what), "{args:?}: '{what}' not in {err}");
    assert_eq!(snapshot(dir), before, "{args:?}: a file changed");
}

#[test]
fn an_output_that_is_an_input_or_named_twice_is_refused() {
    let d = scratch("sacred-inputs");
    let sc = scene(&d);
    // render -o X --png X: it exited 2 after replacing X and X.json
    std::fs::write(d.join("X"), b"the user's X").unwrap();
    std::fs::write(d.join("X.json"), b"the user's X.json").unwrap();
    refused(
        &d,
        &["render", s(&sc), "--width", "8", "-o", "X", "--png", "X"],
        "named as two outputs",
    );
    // render s.toml -o s.toml: it overwrote its own scene and exited 0
    refused(
        &d,
        &["render", s(&sc), "--width", "8", "-o", s(&sc)],
        "is an input of this run",
    );
    refused(
        &d,
        &["render", "s.toml", "--width", "8", "--png", "./s.toml"],
        "is an input of this run",
    );
    // score … --json cases.txt: it overwrote its own cases file and exited 0
    let o = rayproof_in(
        Some(&d),
        &[
            "cases",
            "--shape",
            "rcp",
            "--cases",
            "3",
            "--precision",
            "f32",
            "-o",
            "cases.txt",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let lines = std::fs::read_to_string(d.join("cases.txt"))
        .unwrap()
        .lines()
        .count();
    std::fs::write(d.join("answers.txt"), "0\n".repeat(lines - 1)).unwrap();
    refused(
        &d,
        &[
            "score",
            "--cases",
            "cases.txt",
            "--answers",
            "answers.txt",
            "--json",
            "cases.txt",
        ],
        "is an input of this run",
    );
    refused(
        &d,
        &[
            "score",
            "--cases",
            "cases.txt",
            "--answers",
            "answers.txt",
            "--json",
            "a.json",
            "--markdown",
            "a.json",
        ],
        "named as two outputs",
    );
    // The same file under another name (a hard link) is the same input
    std::fs::hard_link(d.join("cases.txt"), d.join("alias.txt")).unwrap();
    refused(
        &d,
        &[
            "score",
            "--cases",
            "cases.txt",
            "--answers",
            "answers.txt",
            "--json",
            "alias.txt",
        ],
        "is an input of this run",
    );
    // merge: a shard is an input
    let o = rayproof_in(
        Some(&d),
        &[
            "audit",
            "--shape",
            "rcp",
            "--cases",
            "20",
            "--shard",
            "0/1",
            "--shard-out",
            "sh.json",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    refused(
        &d,
        &["merge", "sh.json", "--json", "sh.json"],
        "is an input of this run",
    );
    // downsample: the input
    refused(
        &d,
        &["downsample", "X", "--factor", "2", "-o", "X"],
        "is an input of this run",
    );
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn report_out_never_replaces_a_directory_or_file_rayproof_did_not_make() {
    // `report --out DIR` replaced a user's directory whole (precious/thesis.txt gone, exit 0);
    // an existing file became a directory
    let d = scratch("sacred-report");
    std::fs::create_dir_all(d.join("precious")).unwrap();
    std::fs::write(d.join("precious/thesis.txt"), b"years of work").unwrap();
    std::fs::write(d.join("notes.txt"), b"notes").unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (out, what) in [
        (d.join("precious"), "a directory rayproof did not make"),
        (d.join("notes.txt"), "exists and is not a directory"),
    ] {
        let before = snapshot(&d);
        let o = rayproof_in(Some(root), &["report", "--quick", "--out", s(&out)]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(what), "{err}");
        assert_eq!(snapshot(&d), before);
    }
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn check_update_never_writes_a_reference() {
    // goldens = "refs" with a reference refs/disc.exr: --update overwrote the reference and its
    // manifest entry. Now the suite is refused before anything runs.
    let d = scratch("sacred-golden");
    std::fs::create_dir_all(d.join("refs")).unwrap();
    let standin = crate::common::outside("standin_render.py");
    let st = std::process::Command::new("python3")
        .arg(&standin)
        .arg(d.join("refs/disc.exr"))
        .args(["--width", "16", "--grid", "1"])
        .status()
        .unwrap();
    assert!(st.success());
    std::fs::write(d.join("refs/manifest.json"), "{\"files\": {}}\n").unwrap();
    std::fs::write(
        d.join("suite.toml"),
        format!(
            "[suite]\nrenderer = \"python3 {} {{out}} --width 16 --grid 1 --perturb 0.5\"\ngoldens = \"refs\"\n\n[[test]]\nname = \"disc\"\nreference = [{{ name = \"ext\", path = \"refs/disc.exr\" }}]\n",
            standin.display()
        ),
    )
    .unwrap();
    refused(
        &d,
        &["check", "--suite", "suite.toml", "--update"],
        "is a file the suite reads",
    );
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn the_clean_up_removes_only_rayproof_temporaries() {
    // The clean-up of stale temporaries deleted a user's directory `.keep.exr.tmp99999999/`
    let d = scratch("sacred-cleanup");
    let sc = scene(&d);
    let users = [
        d.join(".keep.exr.tmp99999999"),
        d.join(".keep.exr.rayproof-99999999-0123456789abcdef.tmp"),
        d.join(".keep.exr.rayproof-99999999-0123456789abcdef.dir"),
    ];
    for u in &users {
        std::fs::create_dir_all(u.join("precious")).unwrap();
        std::fs::write(u.join("precious/data"), b"mine").unwrap();
    }
    // What a killed run of rayproof left: removed
    let stale = d.join(".keep.exr.rayproof-99999999-fedcba9876543210.tmp");
    std::fs::write(&stale, b"half").unwrap();
    let o = rayproof_in(
        Some(&d),
        &["render", s(&sc), "--width", "8", "-o", "keep.exr"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for u in &users {
        assert_eq!(
            std::fs::read(u.join("precious/data")).unwrap(),
            b"mine",
            "{}",
            u.display()
        );
    }
    assert!(!stale.exists());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn a_check_run_commits_its_reports_and_goldens_together() {
    // A suite with a golden to bless and every report: all land, no temporary is left
    let d = scratch("sacred-together");
    let standin = crate::common::outside("standin_render.py");
    std::fs::write(
        d.join("suite.toml"),
        format!(
            "[suite]\nrenderer = \"python3 {} {{out}} --width 16 --grid 1\"\ngoldens = \"goldens\"\n\n[[test]]\nname = \"disc\"\n",
            standin.display()
        ),
    )
    .unwrap();
    let o = rayproof_in(
        Some(&d),
        &[
            "check",
            "--suite",
            "suite.toml",
            "--update",
            "--report",
            "rep",
            "--json",
            "c.json",
            "--junit",
            "j.xml",
            "--markdown",
            "c.md",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o)); // NEW, then written
    for f in [
        "goldens/disc.exr",
        "goldens/manifest.json",
        "rep/index.html",
        "c.json",
        "j.xml",
        "c.md",
    ] {
        assert!(d.join(f).is_file(), "{f} missing");
    }
    let left: Vec<String> = snapshot(&d)
        .into_iter()
        .map(|(p, _)| p.display().to_string())
        .filter(|p| p.contains(".rayproof-") && !p.ends_with(".rayproof-output"))
        .collect();
    assert!(left.is_empty(), "temporaries left: {left:?}");
    // The report directory is rayproof's: a second run replaces it
    let o = rayproof_in(
        Some(&d),
        &["check", "--suite", "suite.toml", "--report", "rep"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    std::fs::remove_dir_all(&d).ok();
}
