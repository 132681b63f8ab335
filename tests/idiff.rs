//! idiff parity, judged by the real idiff: `tests/idiff/fixtures.json` holds what OpenImageIO
//! 2.4's `idiff` printed and returned on 21 pairs × 10 option sets (`scripts/idiff-fixtures`).
//! The pairs are regenerated here by `scripts/idiff-pairs` and proven byte-identical to the
//! ones idiff saw (SHA-256). Then:
//! - `rayproof diff --idiff-compat` agrees with idiff on all 210: exit code, pixels over warn
//!   and over fail, and mean, RMS, PSNR and max error as idiff prints them (`%g`), with the
//!   max error's place;
//! - `rayproof diff` agrees the same way on every pair outside the deliberate differences, and
//!   on those, gives what the README's table of deliberate differences says, as that table
//!   says idiff does.

use rayproof::golden::sha256_file;
use rayproof::images::fmt_g;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The pairs on which rayproof deliberately differs (README: "Deliberate differences from idiff").
const DELIBERATE: [&str; 7] = ["nan1", "nan2", "inf1", "inf2", "infsign", "rgba", "size"];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn fixtures() -> Value {
    let text = std::fs::read_to_string(root().join("tests/idiff/fixtures.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The pairs, regenerated and checked against the hashes idiff's run recorded.
fn pairs(fx: &Value, tag: &str) -> Vec<(String, PathBuf, PathBuf)> {
    let dir = std::env::temp_dir().join(format!("rayproof-idiff-{tag}-{}", std::process::id()));
    let out = Command::new("python3")
        .arg(root().join("scripts/idiff-pairs"))
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success());
    let pairs: Vec<(String, PathBuf, PathBuf)> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            (w[0].to_string(), PathBuf::from(w[1]), PathBuf::from(w[2]))
        })
        .collect();
    for (_, a, b) in &pairs {
        for p in [a, b] {
            let name = p.file_name().unwrap().to_str().unwrap();
            assert_eq!(
                fx["images"][name].as_str(),
                Some(sha256_file(p).unwrap().as_str()),
                "{name} is not the image idiff compared"
            );
        }
    }
    pairs
}

/// rayproof diff's JSON and exit code.
fn diff(a: &Path, b: &Path, opts: &[String], compat: bool) -> (i32, Value) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_rayproof"));
    cmd.arg("diff")
        .args(opts)
        .args(["--no-flip", "--json", "-"]);
    if compat {
        cmd.arg("--idiff-compat");
    }
    let out = cmd.arg(a).arg(b).output().unwrap();
    let code = out.status.code().unwrap();
    let json = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
    (code, json)
}

/// A number as idiff prints it (`%g`), from rayproof's JSON (a number or "inf"/"nan").
fn g(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        v => fmt_g(v.as_f64().unwrap(), 6),
    }
}

/// Where rayproof and idiff differ on one run, if they do.
fn disagreement(run: &Value, code: i32, j: &Value) -> Option<String> {
    let c = &j["comparison"];
    let mut diffs = vec![];
    if run["exit"].as_i64() != Some(code as i64) {
        diffs.push(format!("exit {} vs idiff {}", code, run["exit"]));
    }
    if c.is_null() {
        return Some(diffs.join("; ") + " (no comparison)");
    }
    for (k, ours) in [("warn_pixels", &c["n_warn"]), ("fail_pixels", &c["n_fail"])] {
        if run[k] != *ours {
            diffs.push(format!("{k} {ours} vs idiff {}", run[k]));
        }
    }
    for (k, ours) in [
        ("mean", &c["mean_error"]),
        ("rms", &c["rms_error"]),
        ("psnr", &c["psnr"]),
        ("max", &c["max_error"]),
    ] {
        let ours = g(ours);
        if run[k].as_str() != Some(ours.as_str()) {
            diffs.push(format!("{k} {ours} vs idiff {}", run[k]));
        }
    }
    if let Some(at) = run["max_at"].as_array() {
        let ch = c["channels"][c["max_at"][2].as_u64().unwrap() as usize].clone();
        let ours = [c["max_at"][0].clone(), c["max_at"][1].clone(), ch];
        if at[..] != ours[..] {
            diffs.push(format!("max at {ours:?} vs idiff {at:?}"));
        }
    }
    (!diffs.is_empty()).then(|| diffs.join("; "))
}

fn options(run: &Value) -> Vec<String> {
    run["options"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o.as_str().unwrap().to_string())
        .collect()
}

#[test]
fn idiff_compat_reproduces_every_recorded_idiff_run() {
    let fx = fixtures();
    assert!(
        fx["idiff"].as_str().unwrap().starts_with("2.4"),
        "{}",
        fx["idiff"]
    );
    let pairs = pairs(&fx, "compat");
    let runs = fx["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 210);
    let mut bad = vec![];
    for run in runs {
        let (_, a, b) = pairs.iter().find(|p| p.0 == run["pair"]).unwrap();
        let (code, j) = diff(a, b, &options(run), true);
        if let Some(d) = disagreement(run, code, &j) {
            bad.push(format!("{} {:?}: {d}", run["pair"], options(run)));
        }
    }
    assert!(
        bad.is_empty(),
        "{} of 210 differ:\n{}",
        bad.len(),
        bad.join("\n")
    );
}

#[test]
fn rayproof_differs_from_idiff_only_where_the_readme_says() {
    let fx = fixtures();
    let pairs = pairs(&fx, "default");
    // Outside the deliberate differences: idiff's every number
    let mut bad = vec![];
    let mut ours_at_defaults = std::collections::BTreeMap::new();
    for run in fx["runs"].as_array().unwrap() {
        let pair = run["pair"].as_str().unwrap();
        let (_, a, b) = pairs.iter().find(|p| p.0 == pair).unwrap();
        let (code, j) = diff(a, b, &options(run), false);
        if options(run).is_empty() {
            ours_at_defaults.insert(pair.to_string(), (code, run["exit"].as_i64().unwrap()));
        }
        if !DELIBERATE.contains(&pair) {
            if let Some(d) = disagreement(run, code, &j) {
                bad.push(format!("{pair} {:?}: {d}", options(run)));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    // The deliberate ones: the README's table, row by row, at idiff's default thresholds
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let table = readme
        .split("<!-- idiff-differences -->")
        .nth(1)
        .and_then(|s| s.split("<!-- /idiff-differences -->").next())
        .expect("README has the table of deliberate differences");
    let word = |code: i64| match code {
        0 => "PASS",
        1 => "WARNING",
        2 => "FAILURE",
        3 => "refused",
        _ => "error",
    };
    let mut seen = vec![];
    for line in table.lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let pair = cells[1].trim_matches('`');
        let (ours, theirs) = ours_at_defaults[pair];
        assert!(
            cells[3].starts_with(word(theirs)),
            "README says idiff gives '{}' on {pair}; the fixture says {}",
            cells[3],
            word(theirs)
        );
        assert!(
            cells[4].starts_with(word(ours as i64)),
            "README says rayproof gives '{}' on {pair}; it gives {}",
            cells[4],
            word(ours as i64)
        );
        seen.push(pair.to_string());
    }
    seen.sort();
    let mut want: Vec<String> = DELIBERATE.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(
        seen, want,
        "the README table lists exactly the deliberate differences"
    );
}
