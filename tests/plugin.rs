//! `rayproof audit --plugin PATH:SYMBOL`: C routines in a shared library, built here with the
//! system C compiler from `tests/outside/routines.c`, audited through their C ABI in batches.

use crate::common::rayproof;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The library, built once.
fn library() -> &'static Path {
    static LIB: OnceLock<PathBuf> = OnceLock::new();
    LIB.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("rayproof-plugin-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let lib = dir.join("libroutines.so");
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/outside/routines.c");
        let o = Command::new("cc")
            .args(["-O2", "-shared", "-fPIC"])
            .arg(&src)
            .arg("-o")
            .arg(&lib)
            .arg("-lm")
            .output()
            .expect("a C compiler (cc)");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        lib
    })
}

fn plugin(symbol: &str) -> String {
    format!("{}:{symbol}", library().display())
}

/// An audit's JSON rows (and its exit code).
fn audit(args: &[&str]) -> (Option<i32>, Vec<Value>) {
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    let json =
        std::env::temp_dir().join(format!("rayproof-plugin-{}-{n}.json", std::process::id()));
    let mut all = vec!["audit"];
    all.extend(args);
    all.extend(["--json", json.to_str().unwrap(), "--worst", "0"]);
    let o = rayproof(&all);
    assert!(
        o.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    std::fs::remove_file(&json).ok();
    (
        o.status.code(),
        v["shapes"][0]["rows"].as_array().unwrap().clone(),
    )
}

fn wrong(r: &Value) -> u64 {
    ["false_hit", "false_miss", "wrong_root", "nonfinite_t"]
        .iter()
        .map(|k| r[k].as_u64().unwrap())
        .sum()
}

#[test]
fn a_textbook_c_sphere_shows_its_failures_and_a_careful_one_passes() {
    let dir = std::env::temp_dir().join(format!("rayproof-plugin-t-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // The textbook one beside the built-in `algebraic`, the same formula in f32: the same rows
    let sel = [
        "--shape",
        "sphere",
        "--class",
        "far_small,tangent,random,invalid",
        "--cases",
        "2000",
    ];
    let mut args = sel.to_vec();
    let spec = plugin("sphere_textbook_f32");
    args.extend(["--plugin", &spec, "--method", "algebraic"]);
    let (_, rows) = audit(&args);
    let of =
        |m: &str| -> Vec<Value> { rows.iter().filter(|r| r["method"] == m).cloned().collect() };
    let (c, built_in) = (of("sphere_textbook"), of("algebraic"));
    assert_eq!(c.len(), 4);
    for (x, y) in c.iter().zip(&built_in) {
        for k in [
            "well_posed",
            "false_hit",
            "false_miss",
            "wrong_root",
            "ulps",
            "invalid",
        ] {
            assert_eq!(x[k], y[k], "{} {k}", x["class"]);
        }
    }
    let class = |rows: &[Value], c: &str| rows.iter().find(|r| r["class"] == c).unwrap().clone();
    assert!(wrong(&class(&c, "far_small")) > 100 && wrong(&class(&c, "tangent")) > 20);
    // Held to what a robust method does, the textbook one fails and the careful one passes
    for (symbol, want) in [("sphere_textbook_f32", 1), ("sphere_careful_f32", 0)] {
        let name = symbol.trim_end_matches("_f32");
        let rules = dir.join(format!("{name}.toml"));
        std::fs::write(
            &rules,
            format!("[[rule]]\nshape = \"sphere\"\nmethod = \"{name}\"\nwrong = \"none\"\nmax_ulps = 1\ninvalid = \"reject\"\nwhy = \"as promote\"\n"),
        )
        .unwrap();
        let spec = plugin(symbol);
        let mut args = sel.to_vec();
        args.extend(["--plugin", &spec, "--tolerances", rules.to_str().unwrap()]);
        let (code, rows) = audit(&args);
        assert_eq!(code, Some(want), "{symbol}");
        if want == 0 {
            // (the built-in methods are in the same table, each judged by its own rule)
            let mine: Vec<&Value> = rows.iter().filter(|r| r["method"] == name).collect();
            assert!(!mine.is_empty() && mine.len() < rows.len(), "{symbol}");
            assert!(
                mine.iter()
                    .all(|r| wrong(r) == 0 && r["ulps"]["max"] == 0.0),
                "{symbol}"
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_c_moller_trumbore_fails_on_vertex_and_tiny_triangles() {
    let spec = plugin("triangle_mt_f32");
    let (_, rows) = audit(&[
        "--shape",
        "triangle",
        "--class",
        "vertex,tiny,generic",
        "--cases",
        "1000",
        "--plugin",
        &spec,
    ]);
    let class = |c: &str| rows.iter().find(|r| r["class"] == c).unwrap().clone();
    assert!(wrong(&class("vertex")) > 10, "{:?}", class("vertex"));
    assert!(wrong(&class("tiny")) > 10, "{:?}", class("tiny"));
}

/// A row without the fields that name its method (its verdict and replay lines do).
fn judged(r: &Value) -> Value {
    let mut r = r.clone();
    for k in ["method", "verdict", "examples"] {
        r.as_object_mut().unwrap().remove(k);
    }
    r
}

#[test]
fn a_c_quadratic_in_both_precisions_is_judged_exactly_as_the_same_formula_built_in() {
    // Every class of the quadratic, f32 and f64: counts are numbers of roots, values two
    let (f32s, f64s) = (
        plugin("quadratic_textbook_f32"),
        plugin("quadratic_textbook_f64"),
    );
    let (_, rows) = audit(&[
        "--shape",
        "quadratic",
        "--cases",
        "1500",
        "--plugin",
        &f32s,
        "--plugin",
        &f64s,
        "--method",
        "textbook",
    ]);
    let of =
        |m: &str| -> Vec<Value> { rows.iter().filter(|r| r["method"] == m).cloned().collect() };
    let (c, built_in) = (of("quadratic_textbook"), of("textbook"));
    assert_eq!(c.len(), built_in.len());
    assert!(c.len() >= 16, "both precisions, every class");
    for (x, y) in c.iter().zip(&built_in) {
        assert_eq!(judged(x), judged(y), "{} {}", x["precision"], x["class"]);
    }
    // The same formula's known failures show: near_zero and huge_range lose most digits in f32
    let f32_near_zero = c
        .iter()
        .find(|r| r["precision"] == "f32" && r["class"] == "near_zero")
        .unwrap();
    assert!(f32_near_zero["ulps"]["max"].as_f64().unwrap() > 1e6);
}

#[test]
fn a_plugin_audit_in_shards_merges_to_the_unsharded_report() {
    let dir = std::env::temp_dir().join(format!("rayproof-plugin-shard-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let spec = plugin("triangle_mt_f32");
    let sel = [
        "audit",
        "--shape",
        "triangle",
        "--class",
        "vertex,generic",
        "--cases",
        "1200",
        "--plugin",
        &spec,
        "--worst",
        "2",
    ];
    let path = |n: &str| dir.join(n).to_str().unwrap().to_string();
    // Whole
    let mut whole = sel.to_vec();
    let whole_json = path("whole.json");
    whole.extend(["--json", &whole_json]);
    let o = rayproof(&whole);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{o:?}");
    // Three shards, merged
    let shards: Vec<String> = (0..3).map(|k| path(&format!("{k}.shard"))).collect();
    for (k, out) in shards.iter().enumerate() {
        let shard = format!("{k}/3");
        let mut args = sel.to_vec();
        args.extend(["--shard", &shard, "--shard-out", out]);
        let o = rayproof(&args);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let merged_json = path("merged.json");
    let mut merge = vec!["merge", "--worst", "2", "--json", &merged_json];
    merge.extend(shards.iter().map(|s| s.as_str()));
    let o = rayproof(&merge);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{o:?}");
    assert_eq!(
        std::fs::read(&whole_json).unwrap(),
        std::fs::read(&merged_json).unwrap()
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_libraries_and_routines_get_one_line_and_an_exit_code() {
    let sel = [
        "audit", "--shape", "sphere", "--class", "random", "--cases", "50",
    ];
    let lib = library().display().to_string();
    for (spec, code, what) in [
        ("/no/such/lib.so:f_f32".to_string(), 2, "cannot load"),
        (format!("{lib}:absent_f32"), 2, "no symbol 'absent_f32'"),
        (format!("{lib}:sphere_textbook"), 2, "say the precision"),
        (plugin("crashes_f32"), 4, "crashed (signal 11, SIGSEGV"),
        (plugin("fails_f32"), 4, "returned 7"),
        (plugin("forgets_counts_f32"), 4, "left count[0] unwritten"),
        (plugin("nan_values_f32"), 4, "is NaN (a wrong signature?"),
    ] {
        let json =
            std::env::temp_dir().join(format!("rayproof-plugin-bad-{}.json", std::process::id()));
        let mut args = sel.to_vec();
        args.extend(["--plugin", &spec, "--json", json.to_str().unwrap()]);
        let o = rayproof(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{spec}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{spec}: {err}");
        assert!(err.contains(what), "{spec}: '{what}' not in {err}");
        assert!(!json.exists(), "{spec}: a report was written");
    }
}

#[test]
fn a_routine_that_takes_its_process_down_never_takes_rayproof() {
    // In the issue these ended rayproof itself: an abort (134), a stack overflow (139, the
    // handler had no alternate stack), exit(0) made rayproof exit 0 with no report, a hang ran
    // forever. Now each is one line, exit 4, no report, within the deadline.
    let sel = [
        "audit",
        "--shape",
        "sphere",
        "--class",
        "random",
        "--cases",
        "50",
        "--timeout",
        "3",
    ];
    for (symbol, what) in [
        ("aborts_f32", "crashed (signal 6, SIGABRT"),
        ("overflows_stack_f32", "stack overflow"),
        (
            "calls_exit_f32",
            "ended (exit status 0: a routine that calls exit()?)",
        ),
        ("hangs_f32", "did not answer within 3 s (killed)"),
        ("writes_past_out_f32", "crashed (signal"),
    ] {
        let json =
            std::env::temp_dir().join(format!("rayproof-plugin-down-{}.json", std::process::id()));
        let mut args = sel.to_vec();
        let spec = plugin(symbol);
        args.extend(["--plugin", &spec, "--json", json.to_str().unwrap()]);
        let t0 = std::time::Instant::now();
        let o = rayproof(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(4), "{symbol}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{symbol}: {err}");
        assert!(err.contains(what), "{symbol}: '{what}' not in {err}");
        assert!(
            err.contains("answering batch 1 (50 f32 cases)"),
            "{symbol}: {err}"
        );
        assert!(!json.exists(), "{symbol}: a report was written");
        // A hang costs the deadline once (it was searched for its case, 3× the deadline: hostile
        // run of issue 47); a crash's search for the case is bounded too
        let bound = if symbol == "hangs_f32" { 8 } else { 30 };
        assert!(
            t0.elapsed().as_secs() < bound,
            "{symbol}: {:?}",
            t0.elapsed()
        );
    }
}

#[test]
fn a_crash_names_the_case_that_causes_it() {
    // One case of a batch makes the routine crash: the batch is halved on fresh workers until
    // that case is found, and its replay line is the message
    let spec = plugin("crashes_on_one_case_f32");
    let o = rayproof(&[
        "probe",
        "sphere",
        "--precision",
        "f32",
        "--plugin",
        &spec,
        "--",
        "0.25",
        "0",
        "0",
        "1",
        "0",
        "0",
        "5",
        "0",
        "0",
        "1",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(4), "{err}");
    assert!(
        err.contains("the case: rayproof probe sphere --precision f32 --plugin"),
        "{err}"
    );
    assert!(err.contains("-- 0x1p-2 0x0p+0"), "{err}");
    // In an audit, among thousands of cases that pass
    let dir = std::env::temp_dir().join(format!("rayproof-plugin-one-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cases = dir.join("c.txt");
    let o = rayproof(&[
        "cases",
        "--shape",
        "sphere",
        "--class",
        "random",
        "--precision",
        "f32",
        "--cases",
        "3000",
        "-o",
        cases.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0));
    // The same routine is fine on every generated case (none has ox = 0.25 exactly)...
    let o = rayproof(&[
        "audit",
        "--shape",
        "sphere",
        "--class",
        "random",
        "--precision",
        "f32",
        "--cases",
        "3000",
        "--plugin",
        &spec,
    ]);
    assert!(
        matches!(o.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_header_declares_every_shape_in_both_precisions() {
    let o = rayproof(&["header"]);
    assert!(o.status.success());
    let h = String::from_utf8_lossy(&o.stdout);
    for s in rayproof::shapes::registry() {
        for p in ["f32", "f64"] {
            assert!(
                h.contains(&format!("typedef int rayproof_{}_{p}(", s.name())),
                "{}",
                s.name()
            );
        }
    }
    assert!(h.contains("const float in[][10], uint32_t count[], float out[][1]"));
    // It compiles, and the test routines match their declarations
    let dir = std::env::temp_dir().join(format!("rayproof-header-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("rayproof.h"), h.as_bytes()).unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/outside/routines.c");
    let check = format!(
        "#include \"rayproof.h\"\n#include \"{}\"\nrayproof_sphere_f32 *a = sphere_textbook_f32, *b = sphere_careful_f32;\nrayproof_triangle_f32 *c = triangle_mt_f32;\nrayproof_quadratic_f32 *d = quadratic_textbook_f32;\nrayproof_quadratic_f64 *e = quadratic_textbook_f64;\n",
        src.display()
    );
    std::fs::write(dir.join("check.c"), check).unwrap();
    let o = Command::new("cc")
        .args(["-fsyntax-only", "-Werror", "-Wincompatible-pointer-types"])
        .arg(dir.join("check.c"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn several_outside_routines_sit_beside_the_built_ins_in_one_table() {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/outside/sphere_textbook.py");
    let exec = format!("python3 {}", script.display());
    let (textbook, careful) = (plugin("sphere_textbook_f32"), plugin("sphere_careful_f32"));
    let base = [
        "--shape",
        "sphere",
        "--precision",
        "f32",
        "--class",
        "far_small",
        "--cases",
        "300",
    ];
    let mut args = base.to_vec();
    args.extend([
        "--plugin",
        &textbook,
        "--plugin",
        &careful,
        "--exec",
        &exec,
        "--name",
        "c_textbook",
        "--name",
        "c_careful",
        "--name",
        "py",
    ]);
    let (code, rows) = audit(&args);
    assert!(matches!(code, Some(0 | 1)));
    let names: Vec<&str> = rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
    for m in [
        "algebraic",
        "rtg7",
        "certified",
        "c_textbook",
        "c_careful",
        "py",
    ] {
        assert!(names.contains(&m), "{m} not in {names:?}");
    }
    // The C textbook routine is the built-in algebraic in f32; the Python one is in f64, so
    // it differs from both on far_small
    let row = |m: &str| rows.iter().find(|r| r["method"] == m).unwrap();
    assert_eq!(
        row("c_textbook")["false_miss"],
        row("algebraic")["false_miss"]
    );
    // --method narrows to the routines it names, outside ones included
    let mut args = base.to_vec();
    args.extend([
        "--plugin",
        &textbook,
        "--plugin",
        &careful,
        "--name",
        "c_textbook",
        "--name",
        "c_careful",
        "--method",
        "rtg7,c_careful",
    ]);
    let (_, rows) = audit(&args);
    let names: Vec<&str> = rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
    assert_eq!(names, ["rtg7", "c_careful"]);
    // Names must be unique, and a --method that names nothing is an error
    let o = rayproof(&[
        "audit", "--shape", "sphere", "--plugin", &textbook, "--exec", "cat", "--name", "rtg7",
    ]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let o = rayproof(&[
        "audit", "--shape", "sphere", "--plugin", &textbook, "--method", "nobody",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("unknown method 'nobody'"));
}

#[test]
fn an_outside_triangle_routine_gets_the_watertightness_rows() {
    // The C Möller–Trumbore through the plugin (asked about the triangles around where each ray
    // leaves the mesh) leaks exactly where the built-in Möller–Trumbore does (asked about every
    // triangle): the same escapes and grazing misses, mesh by mesh and kind by kind
    let dir = std::env::temp_dir().join(format!("rayproof-plugin-wt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("a.json");
    let o = rayproof(&[
        "audit",
        "--shape",
        "triangle",
        "--cases",
        "200",
        "--plugin",
        &plugin("triangle_mt_f32"),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(
        matches!(o.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let rows = v["robustness"]["watertight"].as_array().unwrap();
    let of = |m: &str| -> Vec<(String, String, u64, u64, u64)> {
        rows.iter()
            .filter(|r| r["method"] == m && r["precision"] == "f32")
            .map(|r| {
                (
                    r["mesh"].as_str().unwrap().to_string(),
                    r["kind"].as_str().unwrap().to_string(),
                    r["rays"].as_u64().unwrap(),
                    r["escaped"].as_u64().unwrap(),
                    r["grazing"].as_u64().unwrap(),
                )
            })
            .collect()
    };
    let (c, builtin) = (of("triangle_mt"), of("moller_trumbore"));
    assert_eq!(c.len(), 7);
    assert_eq!(c, builtin);
    assert!(c.iter().map(|r| r.3).sum::<u64>() > 100, "{c:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Reintersection rows (rays spawned from the routine's own hits with rayproof's offset rule,
/// `o + t·d` and its rounding bound) of an outside triangle routine on the single triangle and
/// the hinge, under every rule: the C Möller–Trumbore never hits its own triangle again with the
/// rule on, a copy whose `t` is 0.1 % short does (its point lies in front of the triangle by far
/// more than the bound), and without an offset both re-hit (the control).
#[test]
fn an_outside_triangle_routine_gets_the_reintersection_rows() {
    let dir = std::env::temp_dir().join(format!("rayproof-plugin-ri-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("a.json");
    let o = rayproof(&[
        "audit",
        "--shape",
        "triangle",
        "--cases",
        "100",
        "--plugin",
        &plugin("triangle_mt_f32"),
        "--plugin",
        &plugin("triangle_short_t_f32"),
        "--plugin",
        &plugin("triangle_chapter_f32"),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(
        matches!(o.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let rows = v["robustness"]["reintersection"].as_array().unwrap();
    let row = |m: &str, shape: &str, rule: &str| -> &Value {
        rows.iter()
            .find(|r| r["method"] == m && r["shape"] == shape && r["rule"] == rule)
            .unwrap_or_else(|| panic!("no reintersection row {m} {shape} {rule}"))
    };
    let self_hits = |r: &Value| r["rehits"].as_u64().unwrap() - r["neighbour"].as_u64().unwrap();
    for m in ["triangle_mt", "triangle_short_t"] {
        for shape in ["triangle", "hinge"] {
            let on = row(m, shape, "on");
            assert!(on["rays"].as_u64().unwrap() > 2000, "{on}");
            assert!(
                self_hits(row(m, shape, "off")) > 100,
                "control: {m} {shape}"
            );
        }
    }
    // Pinned to the same formula built in: the C chapter test is the built-in `chapter` in f32
    // bit for bit, and an outside routine's point is the chapter's own `o + t·d` with its bound,
    // so its rows on the single triangle and the hinge, every rule, are the built-in's number
    // for number (a hinge answered per triangle and combined otherwise than nearest-first, a
    // point or bound computed otherwise, differ here)
    let of = |m: &str| -> Vec<Vec<Value>> {
        rows.iter()
            .filter(|r| r["method"] == m && r["precision"] == "f32")
            .map(|r| {
                ["shape", "rule", "rays", "rehits", "neighbour", "ill_posed"]
                    .iter()
                    .map(|k| r[*k].clone())
                    .collect()
            })
            .collect()
    };
    let (c, builtin) = (of("triangle_chapter"), of("chapter"));
    assert!(
        c.iter().any(|r| r[0] == "hinge") && c.iter().any(|r| r[0] == "triangle"),
        "{c:?}"
    );
    assert_eq!(c, builtin);
    assert_eq!(self_hits(row("triangle_mt", "triangle", "on")), 0);
    // At the hinge, only crossings of the neighbour (the rule is applied per triangle)
    assert_eq!(self_hits(row("triangle_mt", "hinge", "on")), 0);
    let short = row("triangle_short_t", "triangle", "on");
    assert!(
        self_hits(short) > 100,
        "a 0.1 % short t is not seen: {short}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A tolerance file's `[[robustness]]` rules judge an outside routine's robustness rows before
/// the default (no escape): the C Möller–Trumbore leaks, so by default its watertightness rows
/// fail and the audit exits 1; a rule allowing as many escapes as a row has passes it, one fewer
/// fails it, `reported = true` only reports it; a rule naming a method the audit does not have,
/// or bounding nothing, is refused in one line (exit 2).
#[test]
fn a_tolerance_file_holds_an_outside_routine_to_its_own_robustness_rule() {
    let dir = std::env::temp_dir().join(format!("rayproof-plugin-rr-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("a.json");
    let run = |rules: Option<&str>| {
        let mut args = vec![
            "audit".to_string(),
            "--shape".into(),
            "triangle".into(),
            "--precision".into(),
            "f32".into(),
            "--cases".into(),
            "100".into(),
            "--plugin".into(),
            plugin("triangle_mt_f32"),
            "--json".into(),
            json.to_str().unwrap().into(),
        ];
        if let Some(text) = rules {
            let f = dir.join("rules.toml");
            std::fs::write(&f, text).unwrap();
            args.extend(["--tolerances".into(), f.to_str().unwrap().into()]);
        }
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = rayproof(&a);
        let rows: Vec<(u64, String)> = if o.status.code().is_some_and(|c| c <= 1) {
            let v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
            v["robustness"]["watertight"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|r| r["method"] == "triangle_mt")
                .map(|r| {
                    (
                        r["escaped"].as_u64().unwrap(),
                        r["verdict"].as_str().unwrap().to_string(),
                    )
                })
                .collect()
        } else {
            vec![]
        };
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).to_string(),
            rows,
        )
    };
    // The default: escapes fail
    let (code, _, rows) = run(None);
    assert_eq!(code, Some(1));
    let most = rows.iter().map(|r| r.0).max().unwrap();
    assert!(most > 0, "{rows:?}");
    assert!(
        rows.iter().all(|(e, v)| (*e > 0) == (v == "fail")),
        "{rows:?}"
    );
    let rule = |body: &str| {
        format!("[[robustness]]\nmethod = \"triangle_mt\"\ntest = \"watertight\"\n{body}\nwhy = \"a test\"\n")
    };
    // Allowed as many as the worst row: every row passes (the audit may still fail elsewhere)
    let (_, _, rows) = run(Some(&rule(&format!("max_escapes = {most}"))));
    assert!(
        !rows.is_empty() && rows.iter().all(|r| r.1 == "pass"),
        "{rows:?}"
    );
    // One fewer: the worst row fails
    let (code, _, rows) = run(Some(&rule(&format!("max_escapes = {}", most - 1))));
    assert_eq!(code, Some(1));
    assert!(
        rows.iter().any(|r| r.0 == most && r.1 == "fail"),
        "{rows:?}"
    );
    // Reported only
    let (_, _, rows) = run(Some(&rule("reported = true")));
    assert!(
        !rows.is_empty() && rows.iter().all(|r| r.1 == "reported"),
        "{rows:?}"
    );
    // Refused: an unknown method, a rule that bounds nothing, a bound of the other test
    for (text, want) in [
        (
            rule("max_escapes = 1").replace("triangle_mt\"", "nobody\""),
            "no method 'nobody'",
        ),
        (rule(""), "exactly one"),
        (
            rule("max_self_hits = 0"),
            "max_self_hits bounds the reintersection test",
        ),
    ] {
        let (code, err, _) = run(Some(&text));
        assert_eq!(code, Some(2), "{text}: {err}");
        assert!(
            err.contains(want) && err.trim().lines().count() == 1,
            "{want:?} not in {err:?}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
