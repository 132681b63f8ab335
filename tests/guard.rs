//! The seams between routines (issue 49): `rayproof guard` (item 1), the box that guards the
//! primitive, and `rayproof once` (item 4), exactly one hit per mesh.
//!
//! `rayproof guard`: the box that guards the primitive. Boxes that hold a
//! triangle's exact hit, `t_max` = that hit rounded: the naive slab test and the strict
//! comparisons of Williams et al. and pbrt-v4 cull boxes whose entry face holds the hit (lost
//! geometry), Ize's robust traversal culls none; every lost case replays.

use crate::common::{rayproof, stderr, stdout};

#[test]
fn the_naive_slab_loses_face_hits_and_izes_traversal_loses_none() {
    let dir = crate::common::temp_dir("guard");
    let json = dir.join("g.json");
    let o = rayproof(&["guard", "--per-cell", "8", "--json", json.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("verdict: pass"));
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rows.len(), 4 * 4 * 2);
    let lost = |g: &str, class: &str| -> u64 {
        rows.iter()
            .filter(|r| r["guard"] == g && r["class"] == class)
            .map(|r| r["lost"].as_u64().unwrap())
            .sum()
    };
    for class in ["inside", "tight", "on_face", "grazing"] {
        assert_eq!(lost("ize", class), 0, "ize {class}");
        // A box that holds the triangle with room to spare is never lost
        if class == "inside" {
            for g in ["naive_slab", "williams", "pbrt"] {
                assert_eq!(lost(g, class), 0, "{g} {class}");
            }
        }
    }
    for g in ["naive_slab", "williams", "pbrt"] {
        assert!(lost(g, "on_face") > 0, "{g} loses no face hit");
    }
    // Every lost case replays: the guard culls it, Ize's lets it in
    for r in rows.iter().filter(|r| r["lost"].as_u64() > Some(0)) {
        let line = r["replay"].as_str().unwrap();
        let args: Vec<&str> = line.split(' ').skip(1).collect();
        let o = rayproof(&args);
        assert_eq!(o.status.code(), Some(1), "{line}: {}", stdout(&o));
        assert!(stdout(&o).contains("MISS"), "{line}");
        let mut ize = args.clone();
        ize[2] = "ize";
        let o = rayproof(&ize);
        assert_eq!(o.status.code(), Some(0), "{line}: {}", stdout(&o));
    }
    // Bad input: one line, exit 2
    for bad in [
        &["guard", "--guard", "nope"][..],
        &["guard", "--per-cell", "0"],
        &[
            "guard", "--replay", "ize", "f32", "0x1p+0", "1", "1", "1", "1", "1", "1", "1", "1",
            "1", "1", "1", "0.1",
        ],
    ] {
        let o = rayproof(bad);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stderr(&o));
        assert_eq!(
            stderr(&o).trim_end().lines().count(),
            1,
            "{bad:?}: {}",
            stderr(&o)
        );
    }
}

/// Builds `tests/outside/guard_slab.c` as a command in `dir` (with `flags`).
fn build_command(dir: &std::path::Path, name: &str, flags: &[&str]) -> std::path::PathBuf {
    let exe = dir.join(name);
    let o = std::process::Command::new("cc")
        .args(["-O2", "-ffp-contract=off"])
        .args(flags)
        .arg(crate::common::outside("guard_slab.c"))
        .arg("-o")
        .arg(&exe)
        .output()
        .expect("a C compiler (cc)");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    exe
}

#[test]
fn a_users_guard_is_judged_through_exec_and_plugin_alike() {
    let dir = crate::common::temp_dir("guard-outside");
    let naive = build_command(&dir, "guard_slab", &[]);
    let robust = build_command(&dir, "guard_robust", &["-DROBUST=1"]);
    let lib = crate::common::build_library("guard_slab.c", &dir);
    let rows_of = |args: &[&str], want: i32| -> Vec<serde_json::Value> {
        let json = dir.join("rows.json");
        let mut a = vec!["guard", "--per-cell", "6", "--json", json.to_str().unwrap()];
        a.extend(args);
        let o = rayproof(&a);
        assert_eq!(
            o.status.code(),
            Some(want),
            "{a:?}: {}{}",
            stdout(&o),
            stderr(&o)
        );
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
    };
    let lost = |rows: &[serde_json::Value], g: &str| -> Vec<u64> {
        rows.iter()
            .filter(|r| r["guard"] == g)
            .map(|r| r["lost"].as_u64().unwrap())
            .collect()
    };
    // The naive slab of the C file, as a command and as a library: judged, it loses face hits
    // (exit 1), exactly as many as the built-in naive slab, case for case
    let exec = rows_of(
        &[
            "--guard",
            "naive_slab",
            "--exec",
            naive.to_str().unwrap(),
            "--name",
            "mine",
        ],
        1,
    );
    let plugin_spec = format!("{}:guard_slab_f32", lib.display());
    let plugin = rows_of(&["--plugin", &plugin_spec, "--name", "mine"], 1);
    assert_eq!(lost(&exec, "mine"), lost(&exec, "naive_slab"));
    // The library has the f32 symbol: its rows are the command's f32 rows
    let f32_rows: Vec<serde_json::Value> = exec
        .iter()
        .filter(|r| r["precision"] == "f32")
        .cloned()
        .collect();
    assert_eq!(lost(&plugin, "mine"), lost(&f32_rows, "mine"));
    assert!(lost(&exec, "mine").iter().sum::<u64>() > 0);
    assert!(exec
        .iter()
        .filter(|r| r["guard"] == "mine")
        .all(|r| r["verdict"] != "reported"));
    // Its first lost case replays through the same command
    let line = exec
        .iter()
        .find(|r| r["guard"] == "mine" && r["replay"].is_string())
        .unwrap()["replay"]
        .as_str()
        .unwrap()
        .to_string();
    let o = std::process::Command::new("sh")
        .arg("-c")
        .arg(line.replacen("rayproof", env!("CARGO_BIN_EXE_rayproof"), 1))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{line}: {}", stdout(&o));
    // Ize's pad in C: nothing lost, exit 0
    let r = rows_of(&["--exec", robust.to_str().unwrap(), "--name", "robust"], 0);
    assert_eq!(lost(&r, "robust").iter().sum::<u64>(), 0);
    // A guard that answers 2: its contract broken, one line, exit 4
    let o = rayproof(&[
        "guard",
        "--per-cell",
        "1",
        "--exec",
        "sed 's/.*/1 2/'",
        "--name",
        "two",
    ]);
    assert_eq!(o.status.code(), Some(4), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("want count 1 and HIT = 1"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn rays_through_shared_vertices_are_reported_once_by_the_wide_watertight_test_only() {
    let dir = crate::common::temp_dir("once");
    let json = dir.join("once.json");
    let o = rayproof(&["once", "--per-cell", "2", "--json", json.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // 4 routines × 2 precisions × 3 meshes × 4 aims
    assert_eq!(rows.len(), 4 * 2 * 3 * 4);
    let sum = |routine: &str, key: &str| -> u64 {
        rows.iter()
            .filter(|r| r["routine"] == routine)
            .map(|r| r[key].as_u64().unwrap())
            .sum()
    };
    // The watertight tests never leak; Möller–Trumbore (|det| < 1e-6 rejected) and the
    // chapter's test do, from the smallest scenes
    for w in ["watertight", "watertight_wide"] {
        assert_eq!(sum(w, "leaks"), 0, "{w}");
    }
    assert!(sum("moller_trumbore", "leaks") > 0);
    assert!(sum("chapter", "leaks") > 0);
    // At a shared vertex every triangle around it reports the ray: doubles, and for the
    // f32/f64 watertight test hits at different t (two surfaces where there is one)
    assert!(sum("watertight_wide", "doubles") > 0);
    assert!(sum("watertight", "split") > 0);
    // Rays exactly through a vertex: the wide test reports every triangle around it, at one t
    let exact = |routine: &str, key: &str| -> u64 {
        rows.iter()
            .filter(|r| r["routine"] == routine && r["aim"] == "vertex_exact")
            .map(|r| r[key].as_u64().unwrap())
            .sum()
    };
    assert!(exact("watertight_wide", "rays") > 0);
    assert!(exact("watertight_wide", "doubles") * 2 > exact("watertight_wide", "rays"));
    // Every ray is counted once, in one of the outcomes; built-in rows are reported, except the
    // wide watertight test's, robust by design: judged, and within its goal
    for r in &rows {
        let bad = ["leaks", "doubles", "split", "bad"]
            .iter()
            .map(|k| r[k].as_u64().unwrap())
            .sum::<u64>();
        assert!(bad <= r["rays"].as_u64().unwrap(), "{r}");
        assert_eq!(bad > 0, r["first"].is_string(), "{r}");
        assert_eq!(bad > 0, !r["replay"].as_array().unwrap().is_empty(), "{r}");
        assert_eq!(r["bad"], 0, "{r}");
        let want = match r["routine"] == "watertight_wide" {
            true => "pass",
            false => "reported",
        };
        assert_eq!(r["verdict"], want, "{r}");
    }
    assert!(stdout(&o).contains("verdict: pass"), "{}", stdout(&o));
}

/// A routine of yours is judged: one that answers every case with a hit at t = −1 gives bad
/// hits (exit 1, never "pass"), one that misses everything leaks (exit 1), one that answers
/// outside the contract stops the run (one line, exit 4), and bad usage is one line, exit 2.
#[test]
fn once_judges_a_routine_of_yours() {
    let dir = crate::common::temp_dir("once-yours");
    let json = dir.join("once.json");
    let run = |child: &str| {
        rayproof(&[
            "once",
            "--per-cell",
            "1",
            "--precision",
            "f32",
            "--exec",
            child,
            "--name",
            "mine",
            "--json",
            json.to_str().unwrap(),
        ])
    };
    let rows = || -> Vec<serde_json::Value> {
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
    };
    let o = run("awk '{print \"1 -0x1p+0\"; fflush()}'");
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("verdict: FAIL"), "{}", stdout(&o));
    for r in rows() {
        assert_eq!(r["routine"], "mine");
        assert_eq!(r["verdict"], "fail", "{r}");
        assert_eq!(r["bad"], r["rays"], "{r}");
    }
    let o = run("awk '{print 0; fflush()}'");
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    for r in rows() {
        assert_eq!(r["leaks"], r["rays"], "{r}");
        assert_eq!(r["first"], "leak", "{r}");
        // A leak replays on the triangle the exact oracle says the ray crosses first
        let line = r["replay"][0].as_str().unwrap();
        assert!(
            line.starts_with("rayproof probe triangle --precision f32 --exec"),
            "{line}"
        );
    }
    // An answer outside the triangle's contract (two hits) is a bad answer of its ray, as the
    // main rows count a malformed one: every row fails (it stopped the run, exit 4, before the
    // seams ran in every audit of a routine of yours)
    let o = run("awk '{print \"2 1 2\"; fflush()}'");
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    for r in rows() {
        assert_eq!(r["verdict"], "fail", "{r}");
        assert_eq!(r["bad"], r["rays"], "{r}");
    }
    for bad in [
        &["once", "--method", "nope"][..],
        &["once", "--per-cell", "0"],
        &["once", "--exec", "cat", "--name", "watertight"],
    ] {
        let o = rayproof(bad);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stderr(&o));
        assert_eq!(stderr(&o).lines().count(), 1, "{bad:?}: {}", stderr(&o));
    }
}

/// `rayproof transform` (item 2): shapes behind an instance transform. Under a translation of
/// 10³–10⁷ object sizes the 3×4 product in f32 loses verdicts for every routine, the textbook
/// and the robust alike; taking the translation off first loses none; the ideal carrying (the
/// exact object ray rounded once) loses none in any class: what `matrix` and `translate_first`
/// lose under non-uniform and near-singular scales is the rounded stored inverse's; the inverse
/// a renderer computes itself from M (`inverted`) loses verdicts under translation as the stored
/// one does (b_W = −L_W·T rounds at the translation's scale). Every wrong
/// case replays (exit 1), and the same case carried ideally does not (exit 0).
#[test]
fn transforms_lose_verdicts_where_the_carrying_rounds() {
    let dir = crate::common::temp_dir("transform");
    let json = dir.join("t.json");
    let o = rayproof(&[
        "transform",
        "--cases",
        "400",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // 5 routines × 4 modes × 2 precisions × 6 classes
    assert_eq!(rows.len(), 5 * 4 * 2 * 6);
    let wrong = |r: &serde_json::Value| {
        r["false_hit"].as_u64().unwrap() + r["false_miss"].as_u64().unwrap()
    };
    for r in &rows {
        assert!(r["cases"].as_u64().unwrap() >= 390, "{r}");
        match (r["mode"].as_str().unwrap(), r["class"].as_str().unwrap()) {
            ("ideal", _) => assert_eq!(wrong(r), 0, "{r}"),
            ("translate_first", "translation") => assert_eq!(wrong(r), 0, "{r}"),
            ("matrix" | "inverted", "translation") if r["precision"] == "f32" => {
                assert!(wrong(r) > 0, "{r}")
            }
            _ => {}
        }
        assert_eq!(wrong(r) > 0, r["replay"].is_string(), "{r}");
    }
    for r in rows.iter().filter(|r| r["replay"].is_string()).take(6) {
        let line = r["replay"].as_str().unwrap();
        let args: Vec<&str> = line.split(' ').skip(1).collect();
        let o = rayproof(&args);
        assert_eq!(
            o.status.code(),
            Some(1),
            "{line}: {}{}",
            stdout(&o),
            stderr(&o)
        );
        let mut ideal = args.clone();
        ideal[4] = "ideal";
        let o = rayproof(&ideal);
        assert_eq!(o.status.code(), Some(0), "{line}: {}", stdout(&o));
    }
    // A routine of yours that answers outside the contract (two hits) has a bad t on every
    // case, as a malformed answer counts in the main rows: every row fails, exit 1
    let o = rayproof(&[
        "transform",
        "--cases",
        "5",
        "--shape",
        "triangle",
        "--precision",
        "f32",
        "--exec",
        "awk '{print \"2 1 2\"; fflush()}'",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let table = stdout(&o);
    let rows: Vec<&str> = table
        .lines()
        .filter(|l| l.starts_with("triangle  exec"))
        .collect();
    assert!(
        !rows.is_empty()
            && rows.iter().all(|l| {
                let w: Vec<&str> = l.split_whitespace().collect();
                // cases … bad t … verdict: every case a bad t, the row failed
                w[5] == w[9] && w.last() == Some(&"fail")
            }),
        "{table}"
    );
    // A line that is not an answer at all stops the run: one line, exit 4
    let o = rayproof(&[
        "transform",
        "--cases",
        "5",
        "--shape",
        "triangle",
        "--precision",
        "f32",
        "--exec",
        "awk '{print \"junk\"; fflush()}'",
    ]);
    assert_eq!(o.status.code(), Some(4), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
    // Bad usage: one line, exit 2
    for bad in [
        &["transform", "--shape", "cube"][..],
        &["transform", "--cases", "0"],
        &["transform", "--exec", "cat"],
        &["transform", "--method", "nope"],
        &[
            "transform",
            "--replay",
            "sphere",
            "rtg7",
            "matrix",
            "f32",
            "1",
            "2",
        ],
        &["transform", "--replay", "sphere", "rtg7", "sideways", "f32"],
    ] {
        let o = rayproof(bad);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stderr(&o));
        assert_eq!(stderr(&o).lines().count(), 1, "{bad:?}: {}", stderr(&o));
    }
}
