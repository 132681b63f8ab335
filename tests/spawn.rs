//! `rayproof spawn` (issue 47): spawn rules audited both ways, built-in and outside, and
//! Mitsuba 3's own `spawn_ray` live (PyPI `mitsuba`, variant `scalar_rgb`, installed by
//! `.ci/run`).

use crate::common::scratch;
use std::path::Path;
use std::process::{Command, Output};

fn spawn(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(dir)
        .arg("spawn")
        .args(args)
        .output()
        .unwrap()
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The JSON rows of a run.
fn rows(path: &Path) -> Vec<serde_json::Value> {
    serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(path).unwrap())
        .unwrap()
        .as_array()
        .unwrap()
        .clone()
}

fn sum(rows: &[serde_json::Value], rule: &str, key: &str) -> u64 {
    rows.iter()
        .filter(|r| r["rule"] == rule)
        .map(|r| r[key].as_u64().unwrap())
        .sum()
}

/// The five built-in rules over every scale, placement and precision: pbrt-v4's rule never
/// self-hits and resolves gaps of a few ulps of |p| (growing with |p|); no offset self-hits
/// about half its rays; a fixed t_min self-hits at large scenes; and a printed replay line
/// replays its self-hit (exit 1).
#[test]
fn the_built_in_rules_at_every_scale() {
    let d = scratch("spawn-built-in");
    let o = spawn(
        &d,
        &["--per-cell", "8", "--json", "s.json", "--plots", "figs"],
    );
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    let r = rows(&d.join("s.json"));
    assert_eq!(r.len(), 5 * 2 * 12 * 2);
    // The figures: a line per rule and precision, near and far; the Pareto of the ten
    for f in ["gap-near.svg", "gap-far.svg", "pareto.svg"] {
        let svg = std::fs::read_to_string(d.join("figs").join(f)).unwrap();
        for label in [
            "pbrt f32",
            "wachter_binder f64",
            "tmin_1e-4 f32",
            "mitsuba2_epsilon f64",
        ] {
            assert!(svg.contains(label), "{f}: no {label}");
        }
    }
    assert_eq!(sum(&r, "pbrt", "self_hits"), 0);
    assert!(sum(&r, "pbrt", "rays") > 1500);
    let none = sum(&r, "none", "self_hits");
    assert!(none * 3 > sum(&r, "none", "rays"), "none: {none}");
    // pbrt: a gap under 32 ulps of |p| everywhere; in scene units it grows with the scene
    for x in r.iter().filter(|x| x["rule"] == "pbrt") {
        let u = x["gap_ulps"].as_f64().unwrap();
        assert!(u > 0.0 && u < 32.0, "{x}");
    }
    let gap = |rule: &str, prec: &str, pl: &str, scale: i64| {
        r.iter()
            .find(|x| {
                x["rule"] == rule
                    && x["precision"] == prec
                    && x["placement"] == pl
                    && x["scale"] == scale
            })
            .unwrap()["gap"]
            .as_f64()
            .unwrap()
    };
    assert!(gap("pbrt", "f32", "near", 7) > 1e6 * gap("pbrt", "f32", "near", -4));
    // A fixed t_min of 1e-4: no self-hit in small f32 scenes, self-hits in large ones
    let tmin_hits = |scale: i64| {
        r.iter()
            .filter(|x| x["rule"] == "tmin_1e-4" && x["precision"] == "f32" && x["scale"] == scale)
            .map(|x| x["self_hits"].as_u64().unwrap())
            .sum::<u64>()
    };
    assert_eq!(tmin_hits(-2), 0);
    assert!(tmin_hits(5) > 10);
    // The summary says each rule's count, and a self-hit's replay line replays it
    assert!(out.contains("pbrt: reported: 0 self-hits"), "{out}");
    let line = out
        .lines()
        .find(|l| l.starts_with("none: reported:"))
        .unwrap();
    let replay = line.split("replay: ").nth(1).unwrap().trim_end_matches(')');
    let args: Vec<&str> = replay.split_whitespace().skip(2).collect();
    let o = spawn(&d, &args);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{replay}: {out}{err}");
    assert!(
        out.contains("self-hit: the exact oracle finds the triangle again"),
        "{out}"
    );
}

/// A rule of yours through --exec: the hit point itself (no offset) fails (exit 1) with its
/// self-hits; a child that answers a malformed line stops the run (exit 4, one line).
#[test]
fn an_outside_rule_that_self_hits_fails_and_a_malformed_answer_stops_the_run() {
    let d = scratch("spawn-exec");
    let same = "python3 -c 'import sys\nfor l in sys.stdin:\n    w = l.split()\n    print(1, w[1], w[2], w[3], 0, flush=True)'";
    let o = spawn(&d, &["--per-cell", "2", "--exec", same, "--name", "mine"]);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{out}{err}");
    assert!(out.contains("mine: FAIL:"), "{out}");
    assert!(out.contains("verdict: FAIL (mine:"), "{out}");
    for bad in [
        "2 0 0 0 0",
        "1 0 0 0",
        "1 0 0 0 -1",
        "1 nan 0 0 0",
        "1 0 0 0 inf",
    ] {
        let cmd = format!("while read l; do echo '{bad}'; done");
        let o = spawn(
            &d,
            &["--per-cell", "1", "--precision", "f32", "--exec", &cmd],
        );
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(4), "{bad}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{bad}: {err}");
    }
}

/// Mitsuba 3's own `spawn_ray` (the real Mitsuba, `scalar_rgb`), side by side with pbrt-v4's
/// rule: no self-hit; its offset, (1 + max|p|)·RayEpsilon along the normal, costs a gap of
/// hundreds of ulps of |p| where pbrt's costs a few, and in a scene of size 1e-4 near the
/// origin about 1e6 ulps (a neighbour 1e-4 away is skipped).
#[test]
fn mitsuba_spawn_ray_beside_pbrts_rule() {
    let d = scratch("spawn-mitsuba");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/mitsuba_spawn.py");
    let cmd = format!("python3 {}", script.display());
    let o = spawn(
        &d,
        &[
            "--precision",
            "f32",
            "--per-cell",
            "8",
            "--rule",
            "pbrt",
            "--exec",
            &cmd,
            "--name",
            "mitsuba3",
            "--json",
            "m.json",
        ],
    );
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{out}{err}");
    let r = rows(&d.join("m.json"));
    assert_eq!(sum(&r, "mitsuba3", "self_hits"), 0);
    assert_eq!(sum(&r, "mitsuba3", "rays"), sum(&r, "pbrt", "rays"));
    for m in r.iter().filter(|x| x["rule"] == "mitsuba3") {
        let p = r
            .iter()
            .find(|x| {
                x["rule"] == "pbrt" && x["scale"] == m["scale"] && x["placement"] == m["placement"]
            })
            .unwrap();
        let (mu, pu) = (
            m["gap_ulps"].as_f64().unwrap(),
            p["gap_ulps"].as_f64().unwrap(),
        );
        assert!(mu > 300.0 && mu > 20.0 * pu, "{m} against {p}");
    }
    let tiny = r
        .iter()
        .find(|x| x["rule"] == "mitsuba3" && x["scale"] == -4 && x["placement"] == "near")
        .unwrap();
    assert!(tiny["gap"].as_f64().unwrap() > 5e-5, "{tiny}");
}
