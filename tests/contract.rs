//! The answer contract (`rayproof::audit::contract`): one validator for every way in.
//!
//! - The reproducers: a hit at `t ≤ 0` is never "ok"; `--exec` takes no answer that
//!   `--plugin` refuses (and the reverse): `2 1`, `1 1 2`, `0 5 6 7` are malformed answers,
//!   counted in their rows, never false hits or false misses.
//! - A table of answers in and outside the contract (counts, value counts, NaN, ±0, t < 0,
//!   t = inf, extra values), chosen per case by the case's inputs, run through `--exec`,
//!   `--plugin`, `score` and the Rust API: the same rows, count for count.
//! - A line that is not an answer at all stops the run with one line naming the case, exit 4.

use crate::common::{build_library, outside, rayproof, s, scratch, stderr, stdout};
use rayproof::audit::{Answer, Audit};
use rayproof::numerics::Precision;
use serde_json::Value;
use std::path::Path;

const CASE: [&str; 10] = ["0", "0", "-5", "0", "0", "1", "0", "0", "0", "1"];

/// `probe sphere` of the case (t = 4) with an `--exec` child answering `answer`: the
/// exec method's judgement word and the whole output.
fn probe_exec(answer: &str) -> (Option<i32>, String, String) {
    let cmd = format!("sed 's/.*/{answer}/'");
    let mut args = vec![
        "probe",
        "sphere",
        "--precision",
        "f32",
        "--exec",
        &cmd,
        "--",
    ];
    args.extend(CASE);
    let o = rayproof(&args);
    let out = stdout(&o);
    let word = out
        .lines()
        .find(|l| l.trim_start().starts_with("exec "))
        .and_then(|l| l.split_whitespace().nth(1))
        .unwrap_or("")
        .to_string();
    (o.status.code(), word, out + &stderr(&o))
}

#[test]
fn a_hit_at_t_at_most_zero_is_never_ok() {
    // The reproducer: `1 -1` was "ok (2147483648 ulps)"
    for answer in ["1 -1", "1 -0x1p+0", "1 0", "1 -0", "1 -1e-45"] {
        let (code, word, out) = probe_exec(answer);
        assert_eq!(code, Some(0), "{out}");
        assert_eq!(word, "out_of_range", "{answer}: {out}");
    }
    // A hit at the right t is still right, and a non-finite one is non-finite
    assert_eq!(probe_exec("1 4").1, "ok");
    assert_eq!(probe_exec("1 inf").1, "nonfinite_t");
    assert_eq!(probe_exec("1 nan").1, "nonfinite_t");
}

#[test]
fn exec_takes_no_answer_outside_the_contract() {
    // The reproducers: each was taken (`2 1` as a false hit, `1 1 2` as ok with
    // 16777216 ulps, `0 5 6 7` as a false miss)
    for answer in ["2 1", "1 1 2", "0 5 6 7", "1", "3 4"] {
        let (code, word, out) = probe_exec(answer);
        assert_eq!(code, Some(0), "{out}");
        assert_eq!(word, "malformed", "{answer}: {out}");
    }
}

#[test]
fn a_line_that_is_not_an_answer_stops_the_run_naming_the_case() {
    for answer in ["x", "1 4 foo", "-1 4", "1.5 4"] {
        let (code, _, out) = probe_exec(answer);
        assert_eq!(code, Some(4), "{answer}: {out}");
        let err: Vec<&str> = out.lines().filter(|l| l.starts_with("error")).collect();
        assert_eq!(err.len(), 1, "{out}");
        assert!(
            err[0].contains("rayproof probe sphere --precision f32"),
            "{}",
            err[0]
        );
    }
}

/// The key of a case: the XOR of its inputs' f64 bits (every NaN as the quiet NaN), as the C
/// and Python routines compute it.
fn key(x: &[f64]) -> u64 {
    x.iter()
        .map(|v| {
            if v.is_nan() {
                0x7ff8_0000_0000_0000
            } else {
                v.to_bits()
            }
        })
        .fold(0, |k, b| k ^ b)
}

/// The tables of `contract_table.py` and `contract.c`, written out as answers.
fn table(shape: &str) -> Vec<Answer> {
    let a = |count: u32, values: &[f64]| Answer {
        count,
        values: values.to_vec(),
        enclosure: None,
    };
    match shape {
        "sphere" => vec![
            a(0, &[]),
            a(1, &[-1.0]),
            a(1, &[0.0]),
            a(1, &[-0.0]),
            a(1, &[f64::INFINITY]),
            a(1, &[f64::NAN]),
            a(2, &[1.0]),
            a(7, &[1.0]),
            a(1, &[5.0]),
            a(1, &[2f64.powi(100)]),
            // Text only: a value count that does not match the count
            a(1, &[1.0, 2.0]),
            a(0, &[5.0]),
            a(1, &[]),
        ],
        _ => vec![
            a(0, &[]),
            a(1, &[0.5]),
            a(2, &[-1.0, 1.0]),
            a(2, &[1.0, -1.0]),
            a(3, &[1.0, 2.0]),
            a(2, &[f64::NAN, 1.0]),
            a(1, &[-0.0]),
            // Text only
            a(1, &[1.0, 2.0]),
            a(2, &[1.0]),
        ],
    }
}

/// Every row's counts and findings, without what names the way in (the method's name and its
/// replay line).
fn comparable(rows: &[Value]) -> Vec<Value> {
    rows.iter()
        .map(|r| {
            let mut r = r.clone();
            let o = r.as_object_mut().unwrap();
            o.remove("method");
            for e in o["examples"].as_array_mut().unwrap() {
                e.as_object_mut().unwrap().remove("probe");
            }
            o["verdict"] = o["verdict"]["status"].clone();
            r
        })
        .collect()
}

fn json_rows(path: &Path) -> Vec<Value> {
    let v: Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    v["shapes"][0]["rows"].as_array().unwrap().clone()
}

const CASES: &str = "300";

/// The rows of the table's first `n` entries audited through `--exec`, `score`, the Rust API
/// and, when `plugin` names a symbol, `--plugin`.
fn every_way(shape: &str, n: usize, plugin: Option<&str>) -> Vec<(&'static str, Vec<Value>)> {
    let dir = scratch(&format!("contract-{shape}-{n}"));
    let sel = ["--shape", shape, "--precision", "f64", "--cases", CASES];
    let mut out = vec![];
    // --exec
    let json = dir.join("exec.json");
    let child = format!(
        "python3 {} {shape} {n}",
        outside("contract_table.py").display()
    );
    let mut args = vec![
        "audit",
        "--exec",
        &child,
        "--name",
        "mine",
        "--method",
        "mine",
        "--json",
        s(&json),
    ];
    args.extend(sel);
    let o = rayproof(&args);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
    out.push(("exec", json_rows(&json)));
    // --plugin
    if let Some(sym) = plugin {
        let lib = build_library("contract.c", &dir);
        let spec = format!("{}:{sym}", lib.display());
        let json = dir.join("plugin.json");
        let mut args = vec![
            "audit",
            "--plugin",
            &spec,
            "--name",
            "mine",
            "--method",
            "mine",
            "--json",
            s(&json),
        ];
        args.extend(sel);
        let o = rayproof(&args);
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
        out.push(("plugin", json_rows(&json)));
    }
    // cases → answers → score
    let answers = table(shape);
    let answers = &answers[..n];
    let cases = dir.join("cases.txt");
    let mut args = vec!["cases", "-o", s(&cases)];
    args.extend(sel);
    let o = rayproof(&args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let mut text = String::new();
    for line in std::fs::read_to_string(&cases).unwrap().lines() {
        if line.starts_with('#') {
            continue;
        }
        let x: Vec<f64> = line
            .split_whitespace()
            .skip(3)
            .map(|w| rayproof::numerics::real::parse_f64(w).unwrap_or(f64::NAN))
            .collect();
        let a = &answers[(key(&x) % n as u64) as usize];
        let vals: Vec<String> = a
            .values
            .iter()
            .map(|&v| rayproof::shapes::shape::hex_text(v))
            .collect();
        text += &format!("{} {}\n", a.count, vals.join(" "));
    }
    let (answer_file, json) = (dir.join("answers.txt"), dir.join("score.json"));
    std::fs::write(&answer_file, text).unwrap();
    let o = rayproof(&[
        "score",
        "--cases",
        s(&cases),
        "--answers",
        s(&answer_file),
        "--method",
        "mine",
        "--json",
        s(&json),
    ]);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
    out.push(("score", json_rows(&json)));
    // The Rust API
    let owned: Vec<Answer> = answers.to_vec();
    let report = Audit::shape(shape)
        .unwrap()
        .method("mine", move |x: &[f64], _: Precision| {
            owned[(key(x) % owned.len() as u64) as usize].clone()
        })
        .precisions(&[Precision::F64])
        .cases(CASES.parse().unwrap())
        .run()
        .unwrap();
    // Through JSON text as the others are (serde_json's reader rounds some floats differently)
    let rows: Value = serde_json::from_str(&serde_json::to_string(&report.rows).unwrap()).unwrap();
    out.push(("api", rows.as_array().unwrap().clone()));
    std::fs::remove_dir_all(&dir).ok();
    out
}

/// Asserts that every way in gave the same rows, and returns the summed counts of one.
fn same_rows(ways: &[(&str, Vec<Value>)]) -> [u64; 4] {
    let first = comparable(&ways[0].1);
    for (name, rows) in &ways[1..] {
        let these = comparable(rows);
        assert_eq!(first.len(), these.len());
        for (a, b) in first.iter().zip(&these) {
            assert_eq!(
                a, b,
                "{} and {name} differ on {} {}",
                ways[0].0, a["precision"], a["class"]
            );
        }
    }
    let sum = |k: &str| {
        ways[0]
            .1
            .iter()
            .map(|r| r[k].as_u64().unwrap())
            .sum::<u64>()
    };
    [
        sum("malformed"),
        sum("out_of_range") + sum("ill_posed_out_of_range"),
        sum("nonfinite_t"),
        sum("false_hit") + sum("false_miss") + sum("wrong_root"),
    ]
}

#[test]
fn every_way_in_gives_the_same_rows_for_answers_in_and_outside_the_contract() {
    for (shape, all, c_symbol, in_c) in [
        ("sphere", 13, "contract_sphere_f64", 10),
        ("quadratic", 9, "contract_quadratic_f64", 7),
    ] {
        // What C can write: four ways in
        let [malformed, range, nonfinite, wrong] =
            same_rows(&every_way(shape, in_c, Some(c_symbol)));
        assert!(malformed > 0 && nonfinite > 0 && wrong > 0, "{shape}");
        if shape == "sphere" {
            assert!(range > 0, "{shape}");
        }
        // With the text-only entries (a value count that does not match the count): three ways
        let [malformed_all, ..] = same_rows(&every_way(shape, all, None));
        assert!(malformed_all > malformed, "{shape}");
    }
}

#[test]
fn a_row_with_a_malformed_answer_fails_whatever_its_rule() {
    // No tolerance rule for `mine`: its rows are "reported only", but a malformed answer fails
    let dir = scratch("contract-malformed");
    let json = dir.join("a.json");
    let o = rayproof(&[
        "audit",
        "--shape",
        "sphere",
        "--class",
        "random",
        "--precision",
        "f64",
        "--cases",
        "50",
        "--exec",
        "sed 's/.*/2 1/'",
        "--name",
        "mine",
        "--method",
        "mine",
        "--json",
        s(&json),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let rows = json_rows(&json);
    assert_eq!(rows[0]["malformed"], 50);
    assert_eq!(rows[0]["verdict"]["status"], "fail");
    assert!(
        stdout(&o).contains("outside the answer contract"),
        "{}",
        stdout(&o)
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_header_states_the_contract() {
    let o = rayproof(&["header"]);
    let h = stdout(&o);
    for want in [
        "count = 0 for a miss (no value), 1 for a hit",
        "t is finite and > 0",
        "distinct real roots (0 to 2), followed by that many values in ascending order",
        "malformed",
    ] {
        assert!(h.contains(want), "'{want}' not in the header:\n{h}");
    }
}
