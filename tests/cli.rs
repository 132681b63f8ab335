//! The `rayproof` binary: probe JSON, audit determinism, and one-line errors with exit code 2.

use crate::common::{rayproof, stderr};
use serde_json::Value;
use std::process::{Command, Output};

fn rayproof_threads(threads: &str, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .env("RAYON_NUM_THREADS", threads)
        .args(args)
        .output()
        .expect("binary runs")
}

/// A usage error: exit code 2, exactly one line on stderr naming `what`, no panic.
fn assert_one_line_error(o: &Output, what: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "more than one line: {err}"
    );
    assert!(err.contains(what), "'{what}' not named in: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn probe_json_has_the_documented_shape() {
    let o = rayproof(&[
        "probe",
        "sphere",
        "--precision",
        "f32",
        "--json",
        "--",
        "0",
        "0",
        "-5",
        "0",
        "0",
        "1",
        "0",
        "0",
        "0",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(v["shape"], "sphere");
    assert_eq!(v["precision"], "f32");
    assert_eq!(v["inputs"].as_array().unwrap().len(), 10);
    let oracle = &v["oracle"];
    assert_eq!(oracle["verdict"], "count 1");
    assert_eq!(oracle["ill_posed"], false);
    assert_eq!(oracle["values"][0], "0x1p+2");
    let detail = |name: &str| {
        v["oracle_detail"]
            .as_array()
            .unwrap()
            .iter()
            .find(|d| d["name"] == name)
            .unwrap()["value"]
            .as_str()
            .unwrap()
            .to_string()
    };
    assert_eq!(detail("t (f32)"), "0x1p+2");
    assert_eq!(detail("t (f64)"), "0x1p+2");
    let digits = |s: &str| s.chars().filter(|c| c.is_ascii_digit()).count();
    let root = detail("root t1");
    assert!(digits(&root) >= 40 && root.starts_with("4.000000000000000000000000000000000000000"));
    let methods = v["methods"].as_array().unwrap();
    assert_eq!(
        methods.len(),
        rayproof::shapes::sphere::methods::METHODS.len()
    );
    for r in methods {
        assert_eq!(r["values"][0], "0x1p+2");
        assert_eq!(r["ulps"], 0);
        assert_eq!(r["judgement"], "ok");
        assert!(r["method"].is_string());
    }
}

/// `probe sphere --json` with the ten values.
fn probe_sphere(prec: &str, values: &[&str]) -> Value {
    let mut args = vec!["probe", "sphere", "--precision", prec, "--json", "--"];
    args.extend(values);
    let o = rayproof(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).expect("JSON")
}

#[test]
fn probe_takes_hex_floats_and_reports_findings() {
    // A far-small sphere that the f32 textbook discriminant misses (from the default audit)
    let v = probe_sphere(
        "f32",
        &[
            "0x1p+0", "-0x1p+0", "0x0p+0", "0x1p+0", "0", "0", "0x1p+20", "-0x1p+0", "0", "0x1p-3",
        ],
    );
    assert_eq!(v["oracle"]["verdict"], "count 1");
    let verdict = |m: &str| {
        v["methods"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["method"] == m)
            .unwrap()["judgement"]
            .as_str()
            .unwrap()
            .to_string()
    };
    assert_eq!(verdict("promote"), "ok");
    assert_eq!(verdict("rtg7"), "ok");
    // The textbook discriminant b² − 4ac cancels to ≤ 0 here: 2^40 − (2^40 − 2^-6) in f32
    assert_eq!(verdict("algebraic"), "false_miss");
}

#[test]
fn probe_reports_invalid_input() {
    let v = probe_sphere("f64", &["nan", "0", "0", "0", "0", "1", "0", "0", "0", "1"]);
    assert_eq!(v["oracle"]["verdict"], "invalid");
    for r in v["methods"].as_array().unwrap() {
        assert_eq!(r["judgement"], "invalid");
    }
}

#[test]
fn malformed_arguments_get_one_line_and_exit_2() {
    let o = rayproof(&["probe", "sphere", "--", "1", "2"]);
    assert_one_line_error(&o, "takes 10 values");
    let o = rayproof(&[
        "probe", "sphere", "--", "1", "2", "x", "0", "0", "1", "0", "0", "0", "1",
    ]);
    assert_one_line_error(&o, "oz: 'x'");
    let o = rayproof(&["probe", "nowhere", "--", "1"]);
    assert_one_line_error(&o, "unknown shape 'nowhere'");
    let o = rayproof(&["audit", "--cases", "0"]);
    assert_one_line_error(&o, "--cases");
    let o = rayproof(&["audit", "--method", "magic"]);
    assert_one_line_error(&o, "--method");
    let o = rayproof(&["audit", "--precision", "f16"]);
    assert_one_line_error(&o, "--precision");
    let o = rayproof(&["audit", "--class", "nowhere"]);
    assert_one_line_error(&o, "--class");
    let o = rayproof(&["audit", "--shape", "hexagon"]);
    assert_one_line_error(&o, "--shape");
    let o = rayproof(&["audit", "--shard", "3/2"]);
    assert_one_line_error(&o, "--shard");
    let o = rayproof(&["audit", "--frobnicate"]);
    assert_one_line_error(&o, "--frobnicate");
    let o = rayproof(&["audit", "--cases", "10", "--json", "/no/such/dir/out.json"]);
    assert_one_line_error(&o, "/no/such/dir");
    // A tolerance entry for a method, class or shape that does not exist is an error
    let dir = std::env::temp_dir().join(format!("rayproof-cli-tol-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (body, what) in [
        ("shape = \"sphere\"\nmethod = \"rtg8\"", "no method 'rtg8'"),
        (
            "shape = \"sphere\"\nmethod = \"rtg7\"\nclass = \"sideways\"",
            "no class 'sideways'",
        ),
        (
            "shape = \"hexagon\"\nmethod = \"rtg7\"",
            "unknown shape 'hexagon'",
        ),
        (
            "shape = \"sphere\"\nmethod = \"rtg7\"\nmax_ulpz = 1",
            "max_ulpz",
        ),
    ] {
        let p = dir.join("t.toml");
        std::fs::write(
            &p,
            format!("[[rule]]\n{body}\nwrong = \"none\"\nwhy = \"test\"\n"),
        )
        .unwrap();
        let o = rayproof(&[
            "audit",
            "--shape",
            "sphere",
            "--cases",
            "5",
            "--tolerances",
            p.to_str().unwrap(),
        ]);
        assert_one_line_error(&o, what);
    }
    let o = rayproof(&["audit", "--cases", "5", "--tolerances", "/no/such/t.toml"]);
    assert_one_line_error(&o, "cannot read /no/such/t.toml");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn audit_json_is_byte_identical_for_any_thread_count() {
    let dir = std::env::temp_dir().join(format!("rayproof-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (a, b) = (dir.join("one.json"), dir.join("two.json"));
    let md = dir.join("audit.md");
    let args = |p: &std::path::Path| {
        vec![
            "audit".to_string(),
            "--verbose".into(),
            "--cases".into(),
            "300".into(),
            "--seed".into(),
            "42".into(),
            "--json".into(),
            p.display().to_string(),
        ]
    };
    let one = rayproof_threads(
        "1",
        &args(&a).iter().map(|s| s.as_str()).collect::<Vec<_>>(),
    );
    let mut two_args = args(&b);
    two_args.extend(["--markdown".to_string(), md.display().to_string()]);
    let two = rayproof_threads(
        "2",
        &two_args.iter().map(|s| s.as_str()).collect::<Vec<_>>(),
    );
    assert!(
        one.status.code().is_some_and(|c| c <= 1),
        "{}",
        stderr(&one)
    );
    assert!(
        two.status.code().is_some_and(|c| c <= 1),
        "{}",
        stderr(&two)
    );
    let (ja, jb) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    assert!(!ja.is_empty());
    assert_eq!(ja, jb, "JSON differs between 1 and 2 threads");
    let v: Value = serde_json::from_slice(&ja).unwrap();
    assert_eq!(v["seed"], 42);
    let sphere = &v["shapes"][0];
    assert_eq!(sphere["shape"], "sphere");
    let n_methods = rayproof::shapes::sphere::methods::METHODS.len();
    assert_eq!(sphere["rows"].as_array().unwrap().len(), n_methods * 2 * 9);
    let table = std::fs::read_to_string(&md).unwrap();
    assert!(table.contains("| f32 | far_small | algebraic |"));
    // The printed table names every class and the worst cases carry probe lines
    let text = String::from_utf8_lossy(&one.stdout);
    assert!(text.contains("f32 · far_small") && text.contains("rayproof probe sphere --precision"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn shards_cover_the_case_space() {
    let full = rayproof(&[
        "audit",
        "--cases",
        "50",
        "--class",
        "random",
        "--method",
        "rtg7",
        "--precision",
        "f32",
    ]);
    assert!(full.status.code().is_some_and(|c| c <= 1));
    let dir = crate::common::scratch("shards-cover");
    for shard in ["0/2", "1/2"] {
        let file = dir.join(format!("s{}.json", &shard[..1]));
        let o = rayproof(&[
            "audit",
            "--cases",
            "50",
            "--class",
            "random",
            "--method",
            "rtg7",
            "--precision",
            "f32",
            "--shard",
            shard,
            "--shard-out",
            file.to_str().unwrap(),
        ]);
        let text = String::from_utf8_lossy(&o.stderr);
        assert!(text.contains("sphere: 25 cases × 1 methods"), "{text}");
    }
    // A shard without its file would end unjudged: refused (exit 2, one line)
    let o = rayproof(&["audit", "--cases", "50", "--shard", "0/2"]);
    assert_one_line_error(&o, "without --shard-out");
}

/// An instruction-set cap the kernels cannot follow is bad usage: one line, exit 2, nothing run.
#[test]
fn an_unknown_instruction_set_cap_is_refused_with_one_line() {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .args(["audit", "--shape", "sphere", "--cases", "10"])
        .env("RAYPROOF_ISA", "avx1024")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("RAYPROOF_ISA=\"avx1024\" is not an instruction-set cap"),
        "{err}"
    );
    assert!(o.stdout.is_empty());
    // Only the four names, exactly (the hostile run: blank and padded values ran); a long
    // value is shown cut
    let long = "x".repeat(100_000);
    for v in [
        "",
        " ",
        "\t",
        " avx2",
        "avx2 ",
        "avx2\n",
        "AVX2",
        long.as_str(),
    ] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_rayproof"))
            .args(["audit", "--shape", "sphere", "--cases", "10"])
            .env("RAYPROOF_ISA", v)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{v:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "{v:?}: {err}");
        assert!(err.len() < 300, "{} bytes", err.len());
    }
}
