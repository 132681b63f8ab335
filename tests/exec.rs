//! `rayproof audit --exec CMD`: a routine in any language, audited through a subprocess.
//! - A Python textbook ray–sphere is judged exactly as the built-in `algebraic` (the same
//!   formula in IEEE doubles), and its worst cases replay through `probe --exec`;
//! - a child that crashes, hangs, answers a malformed line or too few lines stops the audit
//!   with one line and exit 4, within the timeout, and writes no report.

use crate::common::{rayproof, scratch};
use serde_json::Value;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

fn script() -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/outside/sphere_textbook.py");
    format!("python3 {}", p.display())
}

#[test]
fn a_python_routine_is_judged_as_the_same_built_in_formula() {
    let dir = scratch("python");
    let json = dir.join("a.json");
    let o = rayproof(&[
        "audit",
        "--shape",
        "sphere",
        "--precision",
        "f64",
        "--cases",
        "400",
        "--seed",
        "3",
        "--method",
        "algebraic",
        "--exec",
        &script(),
        "--name",
        "py",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(
        o.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let rows = v["shapes"][0]["rows"].as_array().unwrap();
    fn of<'a>(rows: &'a [Value], m: &'a str) -> impl Iterator<Item = &'a Value> {
        rows.iter().filter(move |r| r["method"] == m)
    }
    let of = |m: &'static str| of(rows, m);
    // Row by row the same counts and errors as the built-in method
    let mut compared = 0;
    for (a, p) in of("algebraic").zip(of("py")) {
        for k in [
            "well_posed",
            "ill_posed",
            "false_hit",
            "false_miss",
            "wrong_root",
            "ulps",
            "invalid",
        ] {
            assert_eq!(a[k], p[k], "{} {k}", a["class"]);
        }
        compared += 1;
    }
    assert_eq!(compared, 9);
    // The tangent class shows the textbook failure; the worst case replays through the probe
    let tangent = of("py").find(|r| r["class"] == "tangent").unwrap();
    assert!(tangent["false_miss"].as_u64().unwrap() + tangent["false_hit"].as_u64().unwrap() > 0);
    let ex = &tangent["examples"][0];
    let line = ex["probe"].as_str().unwrap();
    assert!(
        line.contains("--exec '") && line.contains("--name py"),
        "{line}"
    );
    // The replay line, with --json before the values
    let replay = line
        .replacen("rayproof", env!("CARGO_BIN_EXE_rayproof"), 1)
        .replacen(" -- ", " --json -- ", 1);
    let o = Command::new("sh").arg("-c").arg(replay).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let p: Value = serde_json::from_slice(&o.stdout).unwrap();
    let py = p["methods"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["method"] == "py")
        .unwrap();
    assert_eq!(py["values"], ex["method_values"]);
    std::fs::remove_dir_all(&dir).ok();
}

/// An outside sphere routine gets the reintersection rows of the built-in methods: the same
/// instances, primary and spawned rays and judgement. The Python textbook formula in doubles is
/// the built-in `algebraic` in f64, bit for bit, so its rows (every rule) are `algebraic`'s.
#[test]
fn an_outside_sphere_gets_the_reintersection_rows_of_the_same_built_in_formula() {
    let dir = scratch("reintersect");
    let json = dir.join("a.json");
    let o = rayproof(&[
        "audit",
        "--shape",
        "sphere",
        "--precision",
        "f64",
        "--cases",
        "50",
        "--exec",
        &script(),
        "--name",
        "py",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(
        o.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let rows = v["robustness"]["reintersection"].as_array().unwrap();
    let of = |m: &str| -> Vec<Vec<Value>> {
        rows.iter()
            .filter(|r| r["method"] == m)
            .map(|r| {
                [
                    "shape",
                    "precision",
                    "rule",
                    "rays",
                    "rehits",
                    "neighbour",
                    "ill_posed",
                ]
                .iter()
                .map(|k| r[*k].clone())
                .collect()
            })
            .collect()
    };
    let (py, builtin) = (of("py"), of("algebraic"));
    assert_eq!(py.len(), 3, "{py:?}");
    assert_eq!(py, builtin);
    // The controls re-hit: the rows can see a broken offset
    assert!(py[2][4].as_u64().unwrap() > 100, "{py:?}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_failing_child_stops_the_audit_with_one_line_and_exit_4() {
    let dir = scratch("failing");
    for (cmd, what) in [
        ("exit 3", "failed (exit status: 3)"),
        ("echo broken >&2; kill -9 $$", "failed (signal: 9"),
        ("sleep 30", "did not finish within 2 s"),
        (
            "while read l; do echo '1 zz'; done",
            "answer 1 is not an answer ('1 zz': 'zz' is not a number; the case: rayproof probe sphere",
        ),
        (
            "head -n 2 | while read l; do echo 0; done",
            "answered 2 lines to 10 cases",
        ),
        // (`1` alone is an answer, a malformed one: tests/contract.rs)
        ("while read l; do echo -1 4; done", "'-1' is not a count"),
    ] {
        let json = dir.join("r.json");
        let start = Instant::now();
        let o = rayproof(&[
            "audit",
            "--shape",
            "sphere",
            "--cases",
            "10",
            "--class",
            "random",
            "--exec",
            cmd,
            "--exec-timeout",
            "2",
            "--json",
            json.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(4), "{cmd}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{cmd}: {err}");
        assert!(err.contains(what), "{cmd}: '{what}' not in {err}");
        assert!(!json.exists(), "{cmd}: a report was written");
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "{cmd}: took {:?}",
            start.elapsed()
        );
    }
    // Usage: --exec needs one shape, and its name must not be a built-in method's
    let o = rayproof(&["audit", "--exec", "cat", "--cases", "5"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("single --shape"));
    let o = rayproof(&[
        "audit", "--shape", "sphere", "--method", "rtg7", "--exec", "cat", "--name", "rtg7",
        "--cases", "5",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("routine name rtg7: a built-in method of sphere")
            && err.contains("give --name"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// How many times a child was started (it appends a line to `starts` each time).
fn starts(dir: &Path) -> usize {
    std::fs::read_to_string(dir.join("starts"))
        .map(|s| s.lines().count())
        .unwrap_or(0)
}

#[test]
fn one_child_answers_the_whole_run() {
    // 2 classes × 2 precisions × 5,000 cases: 8 batches of at most 4,096, one child
    let dir = scratch("persistent");
    let cmd = format!("echo $$ >> starts; exec {}", script());
    let run = |extra: &[&str]| {
        let mut args = vec![
            "audit",
            "--shape",
            "sphere",
            "--class",
            "tangent,random",
            "--cases",
            "5000",
            "--exec",
            &cmd,
            "--name",
            "py",
        ];
        args.extend(extra);
        Command::new(env!("CARGO_BIN_EXE_rayproof"))
            .current_dir(&dir)
            .args(&args)
            .output()
            .unwrap()
    };
    let o = run(&[]);
    assert!(
        matches!(o.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // (the reintersection test's rays, after the cases, go to the same child)
    assert_eq!(starts(&dir), 1, "the child was started more than once");
    // --exec-per-batch: one per batch, as before (8 of cases, then the reintersection test's)
    std::fs::remove_file(dir.join("starts")).unwrap();
    let o = run(&["--exec-per-batch"]);
    assert!(
        matches!(o.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(starts(&dir) > 8, "{} starts", starts(&dir));
    // A child that writes only at exit (awk to a pipe) is found out by its first batch and
    // run once per batch; with --exec-keep it is held to flushing, and the message says so
    let lazy = "echo $$ >> starts; exec awk '{print 0}'";
    std::fs::remove_file(dir.join("starts")).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(&dir)
        .args([
            "audit",
            "--shape",
            "rcp",
            "--class",
            "huge",
            "--cases",
            "5000",
            "--precision",
            "f32",
            "--exec",
            lazy,
            "--timeout",
            "20",
        ])
        .output()
        .unwrap();
    assert!(
        matches!(o.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(starts(&dir), 2);
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(&dir)
        .args([
            "audit",
            "--shape",
            "rcp",
            "--class",
            "huge",
            "--cases",
            "50",
            "--precision",
            "f32",
            "--exec",
            lazy,
            "--timeout",
            "2",
            "--exec-keep",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(4), "{err}");
    assert!(
        err.contains("does the child flush its output after each line?"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_stray_line_or_an_extra_answer_is_quoted() {
    // A log line on stdout (as Mitsuba writes its warnings): the line quoted, with the case it
    // was taken as the answer to, and the child's stderr
    let py =
        |body: &str| format!("python3 -c 'import sys\nfor i, l in enumerate(sys.stdin):\n{body}'");
    for (cmd, want) in [
        (
            py("    print(\"2026-11-26 WARN [Scene] a log line\") if i == 3 else None\n    print(0)\n    print(\"working\", file=sys.stderr)"),
            "answer 4 is not an answer ('2026-11-26 WARN [Scene] a log line'",
        ),
        (py("    print(0)\n    print(0) if i == 49 else None"), "answered more lines than cases (the first extra: '0')"),
        (py("    sys.exit(3) if i == 7 else print(0)"), "after 7 of 50 answers (the first unanswered: rayproof probe"),
    ] {
        let o = rayproof(&[
            "audit", "--shape", "sphere", "--class", "random", "--precision", "f32", "--cases",
            "50", "--exec", &cmd, "--timeout", "10",
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(4), "{cmd}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(want), "'{want}' not in {err}");
    }
}

/// One program serves both ways in: `cases --exec-format` writes exactly what an `--exec` child
/// reads, the child's output is a `score --answers` file, and the scored rows are the audit's.
#[test]
fn the_exec_format_cases_file_feeds_the_same_child_and_scores_as_the_audit() {
    let dir = scratch("exec-format");
    let p = |n: &str| dir.join(n).to_str().unwrap().to_string();
    let sel = ["--shape", "sphere", "--precision", "f64", "--cases", "300"];
    // The audit through the child
    let mut args = vec!["audit"];
    args.extend(sel);
    let audit_json = p("audit.json");
    let cmd = script();
    args.extend(["--exec", &cmd, "--name", "py", "--method", "py"]);
    args.extend(["--worst", "0", "--json", &audit_json]);
    let o = rayproof(&args);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{o:?}");
    // The same cases as a file in both formats
    for (file, exec) in [("cases.txt", false), ("lines.txt", true)] {
        let mut a = vec!["cases"];
        a.extend(sel);
        let out = p(file);
        a.extend(["-o", &out]);
        if exec {
            a.push("--exec-format");
        }
        let o = rayproof(&a);
        assert_eq!(o.status.code(), Some(0), "{o:?}");
    }
    let lines = std::fs::read_to_string(p("lines.txt")).unwrap();
    let first = lines.lines().next().unwrap();
    assert!(
        first.starts_with("f64 0x") || first.starts_with("f64 -0x"),
        "{first}"
    );
    let cases = std::fs::read_to_string(p("cases.txt")).unwrap();
    assert_eq!(
        cases.lines().count(),
        lines.lines().count() + 1,
        "one header line"
    );
    // The child answers the exec-format file as it is
    let answers = Command::new("sh")
        .args([
            "-c",
            &format!("{cmd} < {} > {}", p("lines.txt"), p("answers.txt")),
        ])
        .status()
        .unwrap();
    assert!(answers.success());
    let score_json = p("score.json");
    let o = rayproof(&[
        "score",
        "--cases",
        &p("cases.txt"),
        "--answers",
        &p("answers.txt"),
        "--method",
        "py",
        "--worst",
        "0",
        "--json",
        &score_json,
    ]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{o:?}");
    let rows = |f: &str| -> Vec<Value> {
        let v: Value = serde_json::from_slice(&std::fs::read(f).unwrap()).unwrap();
        let mut r = v["shapes"][0]["rows"].as_array().unwrap().clone();
        for x in &mut r {
            x.as_object_mut().unwrap().remove("examples");
        }
        r
    };
    let (a, s) = (rows(&audit_json), rows(&score_json));
    assert!(!a.is_empty());
    assert_eq!(a, s);
}

/// Run once per batch, a child that answers one line too many is refused with the line quoted
/// (the reader must not take the first answers and drop the rest).
#[test]
fn a_per_batch_child_with_one_answer_too_many_is_refused() {
    let o = rayproof(&[
        "audit",
        "--shape",
        "sphere",
        "--class",
        "random",
        "--precision",
        "f32",
        "--cases",
        "50",
        "--exec",
        "awk '{print 0} END {print \"1 0x1p+0\"}'",
        "--exec-per-batch",
        "--timeout",
        "10",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(4), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("answered 51 lines to 50 cases (the first extra: '1 0x1p+0')"),
        "{err}"
    );
}
