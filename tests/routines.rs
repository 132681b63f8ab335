//! The routines of the game-math chapter through the binary: `audit --shape` for every registered
//! shape (rows for every method × precision × class, byte-identical for a seed), and `probe`
//! replaying the audit's own examples to the same judgement.

use crate::common::rayproof;
use rayproof::shapes::registry;
use serde_json::Value;
use std::process::{Command, Output};

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A usage error: exit 2, one line on stderr naming `what`, no panic.
fn assert_one_line_error(o: &Output, what: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains(what), "'{what}' not in {err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// Splits a probe line into the binary's arguments.
fn probe_args(line: &str) -> Vec<String> {
    line.split_whitespace()
        .skip(1) // "rayproof"
        .map(str::to_string)
        .collect()
}

#[test]
fn every_shape_audits_deterministically_and_its_examples_replay() {
    let dir = std::env::temp_dir().join(format!("rayproof-routines-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for shape in registry() {
        let name = shape.name();
        let run = |file: &str, threads: &str| {
            let path = dir.join(file);
            let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
                .env("RAYON_NUM_THREADS", threads)
                .args(["audit", "--shape", name, "--cases", "40", "--seed", "7"])
                .arg("--json")
                .arg(&path)
                .output()
                .unwrap();
            assert!(
                matches!(o.status.code(), Some(0 | 1)),
                "{name}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            std::fs::read(&path).unwrap()
        };
        // Same seed, different thread counts: the same bytes
        let (a, b) = (
            run(&format!("{name}-1.json"), "1"),
            run(&format!("{name}-2.json"), "2"),
        );
        assert!(a == b, "{name}: the JSON depends on the thread count");
        let v: Value = serde_json::from_slice(&a).unwrap();
        let report = &v["shapes"][0];
        assert_eq!(report["shape"], name);
        // A row for every method × precision × class
        let rows = report["rows"].as_array().unwrap();
        assert_eq!(
            rows.len(),
            shape.info().methods.len() * 2 * shape.info().classes.len(),
            "{name}"
        );
        for r in rows {
            assert_eq!(r["cases"], 40, "{name}");
            let gen_fail = r["generator_failures"].as_u64().unwrap();
            assert!(
                gen_fail < 40,
                "{name} {}: generator never succeeds",
                r["class"]
            );
        }
        // Each example's probe line replays to the judgement it was filed under
        let mut replayed = 0;
        for r in rows {
            for e in r["examples"].as_array().unwrap().iter().take(2) {
                let mut args = probe_args(e["probe"].as_str().unwrap());
                args.insert(2, "--json".into());
                let refs: Vec<&str> = args.iter().map(String::as_str).collect();
                let o = rayproof(&refs);
                assert_eq!(o.status.code(), Some(0), "{refs:?}");
                let p: Value = serde_json::from_str(&text(&o)).unwrap();
                let m = p["methods"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|m| m["method"] == r["method"])
                    .unwrap();
                let kind = e["kind"].as_str().unwrap();
                let want = match kind {
                    "worst_ulps" | "worst_residual" | "enclosure_violation" => "ok",
                    "invalid_nan_t" | "invalid_hit" => "invalid",
                    k => k,
                };
                assert_eq!(m["judgement"], want, "{name}: {refs:?}");
                assert_eq!(m["values"], e["method_values"], "{name}: {refs:?}");
                if kind == "worst_ulps" {
                    assert_eq!(m["ulps"], e["ulps"], "{name}: {refs:?}");
                }
                replayed += 1;
            }
        }
        eprintln!("{name}: {} rows, {replayed} examples replayed", rows.len());
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn probe_refuses_bad_input_with_one_line() {
    for shape in registry() {
        let name = shape.name();
        // Wrong count of values
        let mut args = vec!["probe", name, "--"];
        args.extend(std::iter::repeat_n("1", shape.info().args.len() + 1));
        assert_one_line_error(&rayproof(&args), name);
        // Not a number
        let mut args = vec!["probe", name, "--"];
        args.extend(std::iter::repeat_n("zz", shape.info().args.len()));
        assert_one_line_error(&rayproof(&args), "not a number");
        // Help names the values
        let o = rayproof(&["probe", name, "--help"]);
        assert_eq!(o.status.code(), Some(0));
        assert!(text(&o).contains(shape.info().args[0]), "{}", text(&o));
        // NaN everywhere: an answer, never a panic
        let mut args = vec!["probe", name, "--json", "--"];
        args.extend(std::iter::repeat_n("nan", shape.info().args.len()));
        let o = rayproof(&args);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let p: Value = serde_json::from_str(&text(&o)).unwrap();
        assert_eq!(p["oracle"]["verdict"], "invalid", "{name}");
    }
    assert_one_line_error(&rayproof(&["probe", "dodecahedron", "1"]), "dodecahedron");
    assert_one_line_error(&rayproof(&["audit", "--shape", "dodecahedron"]), "--shape");
}

#[test]
fn method_and_class_need_one_shape() {
    let o = rayproof(&["audit", "--shape", "all", "--method", "x", "--cases", "1"]);
    assert_one_line_error(&o, "--shape");
    let o = rayproof(&["audit", "--shape", "sphere,box", "--class", "inside"]);
    assert_one_line_error(&o, "--shape");
}
