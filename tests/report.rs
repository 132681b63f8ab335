//! `rayproof report`: a quick run writes every part with measured (non-trivial) numbers, and a
//! failing run leaves the previous report untouched.

use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

fn rayproof(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .output()
        .expect("binary runs")
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn quick_report_has_every_part_with_measured_numbers() {
    let out = tmp("report-quick");
    let o = rayproof(&[
        "report",
        "--quick",
        "--cases",
        "300",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Files
    for f in [
        "index.html",
        "report.md",
        "report.json",
        "pareto-wrong-rate.svg",
        "pareto-max-ulps.svg",
        "pareto-p99-bits.svg",
        "bits-geometric-f32.svg",
        "render-fan30.svg",
        "img/seed1996-geometric-f64.png",
        "img/floor-rtg7-f32.png",
        "spawn-gap-near.svg",
        "spawn-gap-far.svg",
        "spawn-pareto.svg",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let json: Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    // Accuracy vs cost: every method × 2 precisions, each timed, the naive ones caught
    let n_methods = rayproof::shapes::sphere::methods::METHODS.len();
    let cost = json["cost"].as_array().unwrap();
    assert_eq!(cost.len(), 2 * n_methods);
    assert!(cost
        .iter()
        .all(|r| r["ns"]["median_ns"].as_f64().unwrap() > 0.0));
    let row = |m: &str, p: &str| {
        cost.iter()
            .find(|r| r["method"] == m && r["precision"] == p)
            .unwrap()
            .clone()
    };
    assert!(
        row("geometric", "f32")["wrong"].as_u64().unwrap() > 0,
        "teeth: naive f32 fails"
    );
    assert_eq!(row("promote", "f64")["wrong"].as_u64(), Some(0));
    // certified is on the plot, right everywhere: no wrong verdict, the correctly rounded t
    for p in ["f32", "f64"] {
        assert_eq!(row("certified", p)["wrong"].as_u64(), Some(0));
        assert_eq!(row("certified", p)["max_ulps"].as_f64(), Some(0.0));
    }
    assert!(row("algebraic", "f32")["max_ulps"].as_f64().unwrap() > 1e3);
    // Render trade-off: 3 scenes × every configuration, the baseline has zero error to itself
    let renders = json["renders"].as_array().unwrap();
    assert_eq!(renders.len(), 3 * 2 * n_methods);
    let base = renders
        .iter()
        .find(|r| r["scene"] == "fan30" && r["method"] == "promote" && r["precision"] == "f64")
        .unwrap();
    assert_eq!(base["vs_baseline_mean"].as_f64(), Some(0.0));
    // Seed 000: 8 configurations, d measured, the flat render tests all 30 spheres per ray
    let seed = &json["seed1996"];
    let runs = seed["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 8);
    let flat = runs
        .iter()
        .find(|r| r["flat"] == true && r["method"] == "geometric" && r["precision"] == "f64")
        .unwrap();
    let c = &flat["counts"];
    let rays = c["primary"].as_u64().unwrap()
        + c["shadow"].as_u64().unwrap()
        + c["reflection"].as_u64().unwrap()
        + c["refraction"].as_u64().unwrap();
    assert_eq!(c["sphere_tests"].as_u64().unwrap(), 30 * rays);
    let d = (c["primary"].as_u64().unwrap()
        + c["reflection"].as_u64().unwrap()
        + c["refraction"].as_u64().unwrap()) as f64
        / c["primary"].as_u64().unwrap() as f64;
    assert!((4.0..6.0).contains(&d), "d = {d}");
    // Newton: rows with measured max ulps
    assert!(!json["newton"].as_array().unwrap().is_empty());
    // Spawn rules: five rules × 2 precisions × 12 sizes × 2 placements; pbrt passes with no
    // self-hit, the rule with no offset self-hits
    let spawn = json["spawn"].as_array().unwrap();
    assert_eq!(spawn.len(), 5 * 2 * 12 * 2);
    let hits = |rule: &str| -> u64 {
        spawn
            .iter()
            .filter(|r| r["rule"] == rule)
            .map(|r| r["self_hits"].as_u64().unwrap())
            .sum()
    };
    assert_eq!(hits("pbrt"), 0);
    assert!(hits("none") > 0);
    assert!(spawn
        .iter()
        .filter(|r| r["rule"] == "pbrt")
        .all(|r| r["verdict"] == "pass"));
    // The seams (issue 49): every built-in guard and triangle routine × 2 precisions, the
    // default transform routines in every mode; Ize's guard loses no box and the naive slab
    // loses face hits, the wide watertight test never leaks, the ideal carrying loses nothing
    let seams = &json["seams"];
    let guard = seams["guard"].as_array().unwrap();
    assert_eq!(guard.len(), 4 * 2 * 4);
    let lost = |g: &str| -> u64 {
        guard
            .iter()
            .filter(|r| r["guard"] == g)
            .map(|r| r["lost"].as_u64().unwrap())
            .sum()
    };
    assert_eq!(lost("ize"), 0);
    assert!(lost("naive_slab") > 0);
    assert!(guard
        .iter()
        .all(|r| r["ns_per_test"].as_f64().unwrap() > 0.0));
    let once = seams["once"].as_array().unwrap();
    assert_eq!(once.len(), 4 * 2 * 3 * 4);
    assert!(once
        .iter()
        .filter(|r| r["routine"] == "watertight_wide")
        .all(|r| r["leaks"] == 0 && r["rays"].as_u64().unwrap() > 0));
    let transform = seams["transform"].as_array().unwrap();
    assert_eq!(transform.len(), 5 * 4 * 2 * 6);
    assert!(transform
        .iter()
        .filter(|r| r["mode"] == "ideal")
        .all(|r| r["false_hit"] == 0 && r["false_miss"] == 0));
    // The Markdown and HTML carry the paper's figures and the plots
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## 8. The seams between routines"));
    assert!(md.contains("3.43× (2 h ÷ 35 min)") && md.contains("pareto-max-ulps.svg"));
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(html.contains("<table") && html.contains("<img"));
}

#[test]
fn failed_report_leaves_the_previous_one_and_says_why_in_one_line() {
    let out = tmp("report-keep");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("index.html"), "previous").unwrap();
    let o = rayproof(&[
        "report",
        "--quick",
        "--cases",
        "50",
        "--reference",
        "no/such/reference",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("no/such/reference") && !err.contains("panicked"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("index.html")).unwrap(),
        "previous"
    );
    // No partial directory left beside it
    let parent = out.parent().unwrap();
    let leftovers: Vec<_> = std::fs::read_dir(parent)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".report-keep."))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn an_outside_routine_joins_the_accuracy_vs_cost_section() {
    let out = tmp("report-outside");
    let o = rayproof(&[
        "report",
        "--quick",
        "--cases",
        "200",
        "--exec",
        "python3 tests/outside/sphere_textbook.py",
        "--name",
        "py",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let json: Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let cost = json["cost"].as_array().unwrap();
    assert_eq!(
        cost.len(),
        2 * (rayproof::shapes::sphere::methods::METHODS.len() + 1),
        "the built-in methods and py, in two precisions"
    );
    let py: Vec<&Value> = cost.iter().filter(|r| r["method"] == "py").collect();
    assert_eq!(py.len(), 2);
    // Timed, and judged as the textbook formula it is: wrong verdicts like `algebraic` in f64
    for r in &py {
        assert!(r["ns"]["median_ns"].as_f64().unwrap() > 0.0, "{r}");
    }
    let f64 = |m: &str| {
        cost.iter()
            .find(|r| r["method"] == m && r["precision"] == "f64")
            .unwrap()["wrong"]
            .clone()
    };
    assert_eq!(f64("py"), f64("algebraic"));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("| py | f64 |"), "no py row in the report");
}

/// `report --source FILE.c:SYMBOL --build NAME` (issue 49: every command that takes outside
/// routines takes `--source`): the build is the report's outside routine, named `STEM.BUILD`,
/// timed and judged beside the built-in methods; two builds are refused in one line (the report
/// puts one routine beside them).
#[test]
fn a_source_build_joins_the_report() {
    if std::process::Command::new("gcc")
        .arg("--version")
        .output()
        .is_err()
    {
        panic!("gcc is needed (.ci/run installs it)");
    }
    let src = format!(
        "{}/tests/outside/routines.c:sphere_textbook_f32",
        env!("CARGO_MANIFEST_DIR")
    );
    let out = tmp("report-source");
    let o = rayproof(&[
        "report",
        "--quick",
        "--cases",
        "200",
        "--source",
        &src,
        "--build",
        "gcc-fma",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("gcc -O2 -ffp-contract=fast"),
        "the build line: {err}"
    );
    let json: Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let rows: Vec<&Value> = json["cost"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["method"] == "sphere_textbook.gcc-fma")
        .collect();
    assert!(!rows.is_empty(), "no row of the build in {}", json["cost"]);
    for r in &rows {
        assert!(r["ns"]["median_ns"].as_f64().unwrap() > 0.0, "{r}");
    }
    let o = rayproof(&[
        "report",
        "--quick",
        "--cases",
        "200",
        "--source",
        &src,
        "--build",
        "gcc-off,gcc-fma",
        "--out",
        tmp("report-source-2").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.trim_end()
            .lines()
            .last()
            .unwrap()
            .contains("one --source with one --build"),
        "{err}"
    );
}
