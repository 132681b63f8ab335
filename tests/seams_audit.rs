//! The seams between routines inside `rayproof audit` (issue 49 item 5): the box guards with the
//! box shape and `--guard`, exactly-once and transform rows with the triangle and the sphere and
//! for a routine of yours, judged by the tolerance file's `test = "guard" | "once" |
//! "transform"` rules or the defaults, sharded (shard 0 carries yours, the merge runs the
//! built-ins) and merged byte for byte.

use crate::common::{rayproof, s, stderr, stdout};
use serde_json::Value;
use std::path::Path;

fn json(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn rows<'a>(report: &'a Value, test: &str) -> Vec<&'a Value> {
    report["robustness"][test]
        .as_array()
        .map(|a| a.iter().collect())
        .unwrap_or_default()
}

/// The box shape's audit runs the four built-in guards: Ize's robust traversal loses no box
/// (judged, pass), the naive slab loses face hits (reported: the test's teeth); the rows carry no
/// timing (the report depends on the seed alone).
#[test]
fn the_box_audit_judges_the_guards() {
    let dir = crate::common::temp_dir("seams-box");
    let out = dir.join("a.json");
    let o = rayproof(&[
        "audit",
        "--shape",
        "box",
        "--precision",
        "f32",
        "--json",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("box guards"), "{}", stdout(&o));
    let r = json(&out);
    let g = rows(&r, "guard");
    assert_eq!(g.len(), 4 * 4, "4 guards × 4 classes in f32");
    for x in &g {
        assert!(x.get("ns_per_test").is_none(), "{x}");
        let want = if x["guard"] == "ize" {
            "pass"
        } else {
            "reported"
        };
        assert_eq!(x["verdict"], want, "{x}");
        if x["guard"] == "ize" {
            assert_eq!(x["lost"], 0, "{x}");
        }
    }
    let naive: u64 = g
        .iter()
        .filter(|x| x["guard"] == "naive_slab")
        .map(|x| x["lost"].as_u64().unwrap())
        .sum();
    assert!(naive > 0, "the naive slab lost nothing");
    // The same seed gives the same report
    let again = dir.join("b.json");
    rayproof(&[
        "audit",
        "--shape",
        "box",
        "--precision",
        "f32",
        "--json",
        s(&again),
    ]);
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());
}

/// A triangle routine of yours (Möller–Trumbore in f32, through its C ABI) gets exactly-once and
/// transform rows beside its watertightness rows. It leaks and splits rays through shared edges:
/// its once rows fail the audit with probe lines that name it; in the `ideal` transform mode it
/// keeps every verdict (pass), in the carrying modes its rows are reported. A tolerance file's
/// rules judge them instead: `reported = true`, or `max_failures` per row, or a `mode`.
#[test]
fn a_routine_of_yours_is_held_to_one_hit_per_mesh_and_to_its_transforms() {
    let dir = crate::common::temp_dir("seams-yours");
    let lib = crate::common::build_library("routines.c", &dir);
    let spec = format!("{}:triangle_mt_f32", lib.display());
    let out = dir.join("a.json");
    let audit = |extra: &[&str]| {
        let mut a = vec![
            "audit",
            "--shape",
            "triangle",
            "--method",
            "mine",
            "--plugin",
            &spec,
            "--name",
            "mine",
            "--cases",
            "200",
            "--json",
            s(&out),
        ];
        a.extend(extra);
        rayproof(&a)
    };
    let o = audit(&[]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let text = stdout(&o);
    assert!(
        text.contains("once mine f32 grid edge:") && text.contains("--plugin"),
        "{text}"
    );
    let r = json(&out);
    let once = rows(&r, "once");
    assert_eq!(once.len(), 3 * 4, "3 meshes × 4 aims in f32");
    assert!(once
        .iter()
        .all(|x| x["routine"] == "mine" && x["verdict"] == "fail"));
    // Its watertightness rows' replay lines name the routine (helper-21 F5: they replayed the
    // built-ins)
    let wt: Vec<&Value> = rows(&r, "watertight")
        .into_iter()
        .filter(|x| x["method"] == "mine" && x["replay"].is_string())
        .collect();
    assert!(
        !wt.is_empty()
            && wt.iter().all(|x| x["replay"]
                .as_str()
                .unwrap()
                .contains(&format!("--plugin {spec}"))),
        "{wt:?}"
    );
    let tr = rows(&r, "transform");
    assert_eq!(tr.len(), 6 * 4, "6 classes × 4 modes");
    for x in &tr {
        let want = if x["mode"] == "ideal" {
            "pass"
        } else {
            "reported"
        };
        assert_eq!(x["verdict"], want, "{x}");
    }
    assert!(tr.iter().any(|x| x["mode"] == "matrix"
        && x["false_miss"].as_u64().unwrap() + x["false_hit"].as_u64().unwrap() > 0));
    // The tolerance file's rules judge them first
    let rules = dir.join("rules.toml");
    let write = |text: &str| std::fs::write(&rules, text).unwrap();
    write(
        "[[robustness]]\nmethod = \"mine\"\ntest = \"once\"\nreported = true\nwhy = \"a known MT\"\n\n\
         [[robustness]]\nmethod = \"mine\"\ntest = \"watertight\"\nreported = true\nwhy = \"a known MT\"\n\n\
         [[robustness]]\nmethod = \"mine\"\ntest = \"transform\"\nmode = [\"matrix\", \"inverted\"]\nmax_failures = 0\nwhy = \"held\"\n",
    );
    let o = audit(&["--tolerances", s(&rules)]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let r = json(&out);
    assert!(rows(&r, "once").iter().all(|x| x["verdict"] == "reported"));
    for x in rows(&r, "transform") {
        let want = match x["mode"].as_str().unwrap() {
            "matrix" | "inverted"
                if x["false_hit"].as_u64().unwrap() + x["false_miss"].as_u64().unwrap() > 0 =>
            {
                "fail"
            }
            "matrix" | "inverted" | "ideal" => "pass",
            _ => "reported",
        };
        assert_eq!(x["verdict"], want, "{x}");
    }
    assert!(
        stdout(&o).contains("transform triangle mine matrix f32 translation"),
        "{}",
        stdout(&o)
    );
    // --no-seams skips them (its main, reintersection and watertightness rows stay), and
    // cannot be asked together with --seams
    let o = audit(&["--no-seams", "--tolerances", s(&rules)]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    // ... and the rules naming them say they judged nothing (helper-21 F4): the once and the
    // transform rules, not the watertightness one
    let text = stdout(&o);
    let notes: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("note: ") && l.contains("judged no row"))
        .map(|l| match l {
            _ if l.contains("robustness rule 1 ") => "once",
            _ if l.contains("robustness rule 3 ") => "transform",
            _ => l,
        })
        .collect();
    assert_eq!(notes, ["once", "transform"], "{text}");
    let r = json(&out);
    assert!(rows(&r, "once").iter().all(|x| x["routine"] != "mine"));
    assert!(rows(&r, "transform").iter().all(|x| x["routine"] != "mine"));
    assert!(rows(&r, "watertight").iter().any(|x| x["method"] == "mine"));
    let o = audit(&["--no-seams", "--seams"]);
    assert_eq!(o.status.code(), Some(2), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{}", stderr(&o));
    // Bad rules: one line, exit 2
    for (text, says) in [
        ("method = \"mine\"\ntest = \"once\"\nmax_escapes = 1\nwhy = \"x\"\n", "max_failures"),
        ("method = \"mine\"\ntest = \"watertight\"\nmode = \"ideal\"\nreported = true\nwhy = \"x\"\n", "mode names transform rows"),
        ("method = \"mine\"\ntest = \"transform\"\nmode = \"exact\"\nmax_failures = 0\nwhy = \"x\"\n", "mode = \"exact\""),
        ("method = \"nope\"\ntest = \"once\"\nmax_failures = 0\nwhy = \"x\"\n", "no triangle routine with exactly-once rows 'nope'"),
        ("method = \"mine\"\ntest = \"guard\"\nmax_failures = 0\nwhy = \"x\"\n", "no guard"),
        ("method = \"mine\"\nmax_failures = 0\nwhy = \"x\"\n", "max_failures bounds a seam"),
    ] {
        write(&format!("[[robustness]]\n{text}"));
        let o = audit(&["--tolerances", s(&rules)]);
        assert_eq!(o.status.code(), Some(2), "{text}: {}{}", stdout(&o), stderr(&o));
        assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{text}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{text}: {}", stderr(&o));
    }
}

/// A sharded audit with a routine of yours and a guard of yours merges into exactly the unsharded
/// report; shard 0 carries their seam rows, unjudged; a shard whose seam rows were edited, cut
/// or judged by hand is refused (exit 2), and shards run with different guards are not one audit
/// (exit 3).
#[test]
fn seams_shard_and_merge_byte_for_byte() {
    let dir = crate::common::temp_dir("seams-shard");
    let lib = crate::common::build_library("routines.c", &dir);
    let spec = format!("{}:triangle_mt_f32", lib.display());
    let guard = crate::common::build_library("guard_slab.c", &dir);
    let guard_spec = format!("plugin:{}:guard_slab_f32", guard.display());
    let args = |extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = [
            "audit",
            "--shape",
            "triangle",
            "--plugin",
            &spec,
            "--name",
            "mine",
            // The default since the seams run for every routine of yours: still accepted
            "--seams",
            "--cases",
            "60",
            "--guard",
            &guard_spec,
            "--guard-name",
            "slab",
            "--guard",
            "ize",
        ]
        .iter()
        .map(|x| x.to_string())
        .collect();
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let run = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(|x| x.as_str()).collect();
        rayproof(&a)
    };
    let whole = dir.join("whole.json");
    let o = run(args(&["--json", s(&whole)]));
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let w = json(&whole);
    let g = rows(&w, "guard");
    assert_eq!(
        g.len(),
        2 * 4,
        "slab and ize × 4 classes in f32 (the libraries have f32 symbols)"
    );
    assert!(g
        .iter()
        .any(|x| x["guard"] == "slab" && x["verdict"] == "fail"));
    assert!(g
        .iter()
        .all(|x| x["guard"] != "ize" || x["verdict"] == "pass"));
    let shard = |k: &str| {
        let p = dir.join(format!("s{}.json", &k[..1]));
        let o = run(args(&["--shard", k, "--shard-out", s(&p)]));
        assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
        p
    };
    let (s0, s1) = (shard("0/2"), shard("1/2"));
    let file: Value = json(&s0);
    assert!(file["outside"]["once"]
        .as_array()
        .unwrap()
        .iter()
        .all(|x| x["verdict"] == ""));
    assert!(json(&s1)["outside"]["guard"].as_array().unwrap().is_empty());
    let merged = dir.join("merged.json");
    let o = rayproof(&["merge", s(&s1), s(&s0), "--json", s(&merged)]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(
        std::fs::read(&whole).unwrap(),
        std::fs::read(&merged).unwrap()
    );
    // Edited shards judge nothing
    let text = std::fs::read_to_string(&s0).unwrap();
    let edit = |f: &dyn Fn(&mut Value), says: &str, code: i32| {
        let mut v: Value = serde_json::from_str(&text).unwrap();
        f(&mut v);
        let bad = dir.join("bad.json");
        std::fs::write(&bad, serde_json::to_string(&v).unwrap()).unwrap();
        let o = rayproof(&["merge", s(&bad), s(&s1)]);
        assert_eq!(
            o.status.code(),
            Some(code),
            "{says}: {}{}",
            stdout(&o),
            stderr(&o)
        );
        assert!(stderr(&o).contains(says), "{says}: {}", stderr(&o));
    };
    // A failing guard row made to lose nothing (its replay line left: counts a run cannot make)
    edit(
        &|v| {
            for x in v["outside"]["guard"].as_array_mut().unwrap() {
                x["lost"] = 0.into();
                x["first_scale"] = Value::Null;
            }
        },
        "counts a run cannot make",
        2,
    );
    // Every failing once row cut
    edit(
        &|v| {
            v["outside"]["once"]
                .as_array_mut()
                .unwrap()
                .retain(|x| x["leaks"] == 0);
        },
        "exactly-once rows",
        2,
    );
    // Judged by hand
    edit(
        &|v| {
            for x in v["outside"]["transform"].as_array_mut().unwrap() {
                x["verdict"] = "pass".into();
            }
        },
        "counts a run cannot make",
        2,
    );
    // Leaks forgiven, but counted rays kept
    edit(
        &|v| {
            for x in v["outside"]["once"].as_array_mut().unwrap() {
                x["leaks"] = 0.into();
                x["split"] = 0.into();
                x["split_ulps"] = 0.into();
                x["first_leak"] = Value::Null;
            }
        },
        "counts a run cannot make",
        2,
    );
    // Another guard list is another audit
    edit(
        &|v| {
            v["guards"] = serde_json::json!(["ize"]);
            v["outside"]["guard"]
                .as_array_mut()
                .unwrap()
                .retain(|x| x["guard"] == "ize");
        },
        "guards",
        3,
    );
}

/// `--source FILE.c:SYMBOL` puts each build of a C routine into the audit as a routine of its
/// own (`STEM.BUILD`): Möller–Trumbore as usually written gets other rows with contraction on
/// than off (its verdicts flip near edges), every row of each build is judged and sharded like
/// a plugin's, the merge is byte for byte the unsharded audit, and a failing row's replay line
/// builds the same build again. A build this machine cannot make is one line, exit 2.
#[test]
fn contraction_side_by_side_in_the_audit() {
    let dir = crate::common::temp_dir("seams-source");
    let source = format!(
        "{}:tri_mt_f32",
        crate::common::outside("contraction.c").display()
    );
    let args = |extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = [
            "audit",
            "--shape",
            "triangle",
            "--method",
            "tri_mt.gcc-off,tri_mt.gcc-fma",
            "--source",
            &source,
            "--build",
            "gcc-off,gcc-fma",
            "--cases",
            "400",
        ]
        .iter()
        .map(|x| x.to_string())
        .collect();
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let run = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(|x| x.as_str()).collect();
        rayproof(&a)
    };
    let whole = dir.join("whole.json");
    let o = run(args(&["--json", s(&whole)]));
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    // The build lines, as a user would type them
    assert!(
        stderr(&o).contains("gcc -O2 -ffp-contract=fast -mfma -shared -fPIC"),
        "{}",
        stderr(&o)
    );
    let w = json(&whole);
    let mut methods: Vec<&str> = vec![];
    for r in w["shapes"][0]["rows"].as_array().unwrap() {
        let m = r["method"].as_str().unwrap();
        if !methods.contains(&m) {
            methods.push(m);
        }
    }
    assert_eq!(methods, ["tri_mt.gcc-off", "tri_mt.gcc-fma"]);
    // Contraction changes what the routine does at shared edges
    let leaks = |m: &str| -> u64 {
        rows(&w, "once")
            .iter()
            .filter(|x| x["routine"] == m)
            .map(|x| x["leaks"].as_u64().unwrap())
            .sum()
    };
    assert_ne!(leaks("tri_mt.gcc-off"), leaks("tri_mt.gcc-fma"));
    // A failing row replays through the same build
    let line = stdout(&o)
        .lines()
        .find(|l| l.contains("once tri_mt.gcc-fma") && l.contains("--build gcc-fma"))
        .unwrap_or_else(|| panic!("{}", stdout(&o)))
        .split("first: ")
        .nth(1)
        .unwrap()
        .to_string();
    let replay = std::process::Command::new("sh")
        .arg("-c")
        .arg(line.replacen("rayproof", env!("CARGO_BIN_EXE_rayproof"), 1))
        .output()
        .unwrap();
    assert!(
        String::from_utf8_lossy(&replay.stdout).contains("tri_mt.gcc-fma"),
        "{line}: {}",
        String::from_utf8_lossy(&replay.stderr)
    );
    // Shards and their merge
    let s0 = dir.join("s0.json");
    let s1 = dir.join("s1.json");
    for (k, p) in [("0/2", &s0), ("1/2", &s1)] {
        let o = run(args(&["--shard", k, "--shard-out", s(p)]));
        assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    }
    let merged = dir.join("merged.json");
    let o = rayproof(&["merge", s(&s0), s(&s1), "--json", s(&merged)]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(
        std::fs::read(&whole).unwrap(),
        std::fs::read(&merged).unwrap()
    );
    // A build this machine does not make
    let o = run(vec![
        "audit".into(),
        "--shape".into(),
        "triangle".into(),
        "--source".into(),
        source.clone(),
        "--build".into(),
        "icc-fma".into(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--build icc-fma: not a build"),
        "{}",
        stderr(&o)
    );
}

/// `--seams` in an audit narrowed by `--class` gives a routine of yours no seam rows (those
/// cases alone are audited), and the merge expects none: its shards merge into the unsharded
/// report (the reader expected the rows of a whole-class audit: "its exactly-once rows (0) are
/// not the 12 a run of its routines makes", exit 2).
#[test]
fn seams_narrowed_by_class_shard_and_merge() {
    let dir = crate::common::temp_dir("seams-narrowed");
    let lib = crate::common::build_library("routines.c", &dir);
    let spec = format!("{}:triangle_mt_f32", lib.display());
    let args = |extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = [
            "audit", "--shape", "triangle", "--class", "generic", "--cases", "40", "--plugin",
            &spec, "--name", "mine", "--method", "mine", "--seams",
        ]
        .iter()
        .map(|x| x.to_string())
        .collect();
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let run = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(|x| x.as_str()).collect();
        rayproof(&a)
    };
    let whole = dir.join("whole.json");
    let o = run(args(&["--json", s(&whole)]));
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
    let w = json(&whole);
    assert!(rows(&w, "once").is_empty() && rows(&w, "transform").is_empty());
    let (s0, s1) = (dir.join("s0.json"), dir.join("s1.json"));
    for (k, p) in [("0/2", &s0), ("1/2", &s1)] {
        let o = run(args(&["--shard", k, "--shard-out", s(p)]));
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    let merged = dir.join("merged.json");
    let o = rayproof(&["merge", s(&s0), s(&s1), "--json", s(&merged)]);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(&whole).unwrap(),
        std::fs::read(&merged).unwrap()
    );
}
