//! `rayproof audit --shard K/N --shard-out FILE` and `rayproof merge`: the merge of a run's
//! shards is the unsharded run, byte for byte (JSON, Markdown, table, exit status), for the
//! sphere, for another shape and for several shapes at once; a shard set that is incomplete,
//! inconsistent or corrupt is refused with one line and an exit code.

use crate::common::{rayproof, scratch, stderr, stdout};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

/// A fresh scratch directory for one test.
fn s(p: &Path) -> String {
    p.display().to_string()
}

/// Runs `rayproof` with string arguments.
fn run(args: &[String]) -> Output {
    rayproof(&args.iter().map(String::as_str).collect::<Vec<_>>())
}

/// An audit selection: small, several methods, precisions and classes of the sphere.
fn selection(seed: u64, cases: u64) -> Vec<String> {
    [
        "--cases",
        &cases.to_string(),
        "--seed",
        &seed.to_string(),
        "--shape",
        "sphere",
        "--method",
        "algebraic,rtg7,hearn_baker,interval",
        "--precision",
        "f32,f64",
        "--class",
        "far_small,tangent,on_surface,invalid",
    ]
    .map(String::from)
    .to_vec()
}

/// A selection of another shape: every triangle method on three classes.
fn triangle_selection(seed: u64, cases: u64) -> Vec<String> {
    [
        "--cases",
        &cases.to_string(),
        "--seed",
        &seed.to_string(),
        "--shape",
        "triangle",
        "--class",
        "vertex,far,invalid",
    ]
    .map(String::from)
    .to_vec()
}

/// A user tolerance file that the sphere selection breaks at any seed: the textbook
/// discriminant on far-small f32 spheres held to no wrong verdict.
fn strict_table(dir: &Path) -> PathBuf {
    let p = dir.join("strict.toml");
    std::fs::write(
        &p,
        "[[rule]]\nshape = \"sphere\"\nmethod = \"algebraic\"\nprecision = \"f32\"\n\
         class = \"far_small\"\nwrong = \"none\"\nwhy = \"a test: this row must fail\"\n",
    )
    .unwrap();
    p
}

/// Writes shard `k/n` of a selection to `path`; the shard run itself must succeed.
fn write_shard(sel: &[String], k: u64, n: u64, path: &Path) {
    let mut args = vec!["audit".to_string()];
    args.extend_from_slice(sel);
    args.extend([
        "--shard".into(),
        format!("{k}/{n}"),
        "--shard-out".into(),
        s(path),
    ]);
    let o = run(&args);
    // A shard leaves the tolerance table to the merge, so it exits 0 even where the run breaks it
    assert_eq!(o.status.code(), Some(0), "shard {k}/{n}: {}", stderr(&o));
    assert!(
        stdout(&o).contains("checked by `rayproof merge`"),
        "{}",
        stdout(&o)
    );
}

/// What an audit or a merge produced.
struct Outputs {
    code: Option<i32>,
    json: Vec<u8>,
    markdown: Vec<u8>,
    /// stdout (`--verbose`: the full tables; the timing lines go to stderr).
    table: String,
}

fn unsharded(sel: &[String], dir: &Path, extra: &[&str]) -> Outputs {
    let (json, md) = (dir.join("audit.json"), dir.join("audit.md"));
    let mut args = vec!["audit".to_string(), "--verbose".to_string()];
    args.extend_from_slice(sel);
    args.extend(["--json".into(), s(&json), "--markdown".into(), s(&md)]);
    args.extend(extra.iter().map(|e| e.to_string()));
    let o = run(&args);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", stderr(&o));
    assert!(stderr(&o).contains(" methods in "), "{}", stderr(&o));
    Outputs {
        code: o.status.code(),
        json: std::fs::read(&json).unwrap(),
        markdown: std::fs::read(&md).unwrap(),
        table: stdout(&o),
    }
}

fn merged(shards: &[&Path], dir: &Path, extra: &[&str]) -> Outputs {
    let (json, md) = (dir.join("merged.json"), dir.join("merged.md"));
    let mut args = vec!["merge".to_string(), "--verbose".to_string()];
    args.extend(shards.iter().map(|p| s(p)));
    args.extend(["--json".into(), s(&json), "--markdown".into(), s(&md)]);
    args.extend(extra.iter().map(|e| e.to_string()));
    let o = run(&args);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(" methods merged from "),
        "{}",
        stderr(&o)
    );
    Outputs {
        code: o.status.code(),
        json: std::fs::read(&json).unwrap(),
        markdown: std::fs::read(&md).unwrap(),
        table: stdout(&o),
    }
}

/// The two runs give the same bytes, and what they give is not trivially equal: every row is
/// there, cases were judged, wrong verdicts were found and worst cases were printed.
fn assert_same(full: &Outputs, merge: &Outputs, sel_rows: usize) {
    assert_eq!(
        String::from_utf8_lossy(&full.json),
        String::from_utf8_lossy(&merge.json),
        "JSON differs"
    );
    assert!(full.json == merge.json, "JSON bytes differ");
    assert!(full.markdown == merge.markdown, "Markdown differs");
    assert_eq!(full.table, merge.table, "terminal table differs");
    assert_eq!(full.code, merge.code, "exit status differs");
    let v: Value = serde_json::from_slice(&merge.json).unwrap();
    assert_eq!(v["shard"], "0/1");
    let rows: Vec<&Value> = v["shapes"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|s| s["rows"].as_array().unwrap())
        .collect();
    assert_eq!(rows.len(), sel_rows);
    let n = |r: &Value, k: &str| r[k].as_u64().unwrap();
    assert!(rows.iter().all(|r| n(r, "cases") > 0));
    assert!(rows.iter().all(|r| r["verdict"]["status"].is_string()));
    let wrong: u64 = rows
        .iter()
        .map(|r| n(r, "false_hit") + n(r, "false_miss") + n(r, "wrong_root"))
        .sum();
    assert!(wrong > 0, "no wrong verdict at all: a weak comparison");
    assert!(rows
        .iter()
        .any(|r| r["ulps"]["max"].as_f64().unwrap() > 0.0));
    assert!(rows
        .iter()
        .any(|r| !r["examples"].as_array().unwrap().is_empty()));
    assert!(merge.table.contains("rayproof probe "));
}

const ROWS: usize = 4 * 2 * 4;

#[test]
fn merge_of_three_shards_in_any_order_is_the_unsharded_audit() {
    // With the built-in table the selection passes; with the strict user table it fails
    let dir = scratch("three");
    let strict = strict_table(&dir);
    for (extra, want_code) in [
        (vec![], 0),
        (vec!["--tolerances", strict.to_str().unwrap()], 1),
    ] {
        let sel = selection(1, 90);
        let full = unsharded(&sel, &dir, &extra);
        assert_eq!(full.code, Some(want_code), "{extra:?}");
        // The shards are run with the table (they carry it to the merge)
        let shard_sel: Vec<String> = sel
            .iter()
            .cloned()
            .chain(extra.iter().map(|e| e.to_string()))
            .collect();
        let shards: Vec<PathBuf> = (0..3).map(|k| dir.join(format!("s{k}.json"))).collect();
        for (k, p) in shards.iter().enumerate() {
            write_shard(&shard_sel, k as u64, 3, p);
        }
        let merge = merged(&[&shards[2], &shards[0], &shards[1]], &dir, &extra);
        assert_same(&full, &merge, ROWS);
        // and in order, and without --tolerances on the merge: the shards' table judges
        let merge = merged(&[&shards[0], &shards[1], &shards[2]], &dir, &[]);
        assert_same(&full, &merge, ROWS);
        let md = String::from_utf8_lossy(&merge.markdown);
        assert!(md.contains("| f32 | far_small | algebraic |"), "{md}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn shards_carry_their_tolerance_table() {
    // The reproducer: shards run with --tolerances of a failing audit, merged without
    // it, exited 0 "pass" where the unsharded audit exits 1
    let dir = scratch("carry");
    let strict = strict_table(&dir);
    let sel = selection(1, 40);
    let with: Vec<String> = sel
        .iter()
        .cloned()
        .chain(["--tolerances".to_string(), s(&strict)])
        .collect();
    let full = unsharded(&with, &dir, &[]);
    assert_eq!(full.code, Some(1));
    let p = |name: &str| dir.join(name);
    for k in 0..2 {
        write_shard(&with, k, 2, &p(&format!("t{k}.json")));
    }
    let (t0, t1) = (p("t0.json"), p("t1.json"));
    let merge = merged(&[&t0, &t1], &dir, &[]);
    assert_eq!(merge.code, Some(1), "{}", merge.table);
    assert_same(&full, &merge, ROWS);
    // Shards run with two different tables, or one with and one without, are not one audit
    let other = dir.join("other.toml");
    std::fs::write(
        &other,
        std::fs::read_to_string(&strict)
            .unwrap()
            .replace("a test", "another test"),
    )
    .unwrap();
    let mut with_other = sel.clone();
    with_other.extend(["--tolerances".to_string(), s(&other)]);
    write_shard(&with_other, 1, 2, &p("o1.json"));
    assert_refused(&dir, &[&t0, &p("o1.json")], 3, "tolerance table");
    write_shard(&sel, 1, 2, &p("n1.json"));
    assert_refused(&dir, &[&t0, &p("n1.json")], 3, "tolerance table");
    // A merge given another table than the shards carry is refused; the same one is accepted
    for (shards, table) in [
        ([&t0, &t1], &other),
        ([&p("n0.json"), &p("n1.json")], &strict),
    ] {
        write_shard(&sel, 0, 2, &p("n0.json"));
        let out = dir.join("refused.json");
        let o = run(&[
            "merge".into(),
            s(shards[0]),
            s(shards[1]),
            "--tolerances".into(),
            s(table),
            "--json".into(),
            s(&out),
        ]);
        assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
        assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{}", stderr(&o));
        assert!(stderr(&o).contains("is not the table the shards were run with"));
        assert!(!out.exists());
    }
    let merge = merged(
        &[&t1, &t0],
        &dir,
        &["--tolerances", strict.to_str().unwrap()],
    );
    assert_same(&full, &merge, ROWS);
    // A carried table whose text no longer matches its hash is a corrupt shard
    let mut v: Value = serde_json::from_slice(&std::fs::read(&t1).unwrap()).unwrap();
    v["tolerances"]["text"] = "".into();
    std::fs::write(p("bad.json"), serde_json::to_vec(&v).unwrap()).unwrap();
    assert_refused(
        &dir,
        &[&t0, &p("bad.json")],
        2,
        "does not match its SHA-256",
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn merge_is_the_unsharded_audit_for_another_shape_and_for_several() {
    let dir = scratch("shapes");
    // The triangle alone: 4 methods × 2 precisions × 3 classes
    let sel = triangle_selection(5, 120);
    let full = unsharded(&sel, &dir, &[]);
    let shards: Vec<PathBuf> = (0..4).map(|k| dir.join(format!("t{k}.json"))).collect();
    for (k, p) in shards.iter().enumerate() {
        write_shard(&sel, k as u64, 4, p);
    }
    let merge = merged(&[&shards[3], &shards[1], &shards[0], &shards[2]], &dir, &[]);
    assert_same(&full, &merge, 4 * 2 * 3);
    assert!(merge.table.contains("rayproof probe triangle --precision"));
    // Three shapes in one audit, every method and class
    let sel: Vec<String> = [
        "--cases",
        "60",
        "--seed",
        "7",
        "--shape",
        "box,refract,quadratic",
    ]
    .map(String::from)
    .to_vec();
    let full = unsharded(&sel, &dir, &[]);
    let shards: Vec<PathBuf> = (0..2).map(|k| dir.join(format!("m{k}.json"))).collect();
    for (k, p) in shards.iter().enumerate() {
        write_shard(&sel, k as u64, 2, p);
    }
    let merge = merged(&[&shards[1], &shards[0]], &dir, &[]);
    let v: Value = serde_json::from_slice(&merge.json).unwrap();
    let shapes: Vec<&str> = v["shapes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["shape"].as_str().unwrap())
        .collect();
    assert_eq!(shapes, ["box", "refract", "quadratic"]);
    let rows = v["shapes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["rows"].as_array().unwrap().len())
        .sum();
    assert_same(&full, &merge, rows);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn merge_of_one_shard_is_the_unsharded_audit() {
    let dir = scratch("one");
    let sel = selection(3, 70);
    let full = unsharded(&sel, &dir, &["--worst", "3"]);
    let shard = dir.join("all.json");
    write_shard(&sel, 0, 1, &shard);
    let merge = merged(&[&shard], &dir, &["--worst", "3"]);
    assert_same(&full, &merge, ROWS);
    // --worst reaches the merge: with the default the table differs
    let default = merged(&[&shard], &dir, &[]);
    assert_ne!(default.table, full.table);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn shard_files_hold_no_decimal_floats() {
    let dir = scratch("floats");
    let shard = dir.join("s.json");
    write_shard(&selection(1, 40), 1, 2, &shard);
    let v: Value = serde_json::from_slice(&std::fs::read(&shard).unwrap()).unwrap();
    assert_eq!(v["format"], "rayproof-audit-shard");
    assert_eq!(v["format_version"], 8);
    assert_eq!(v["shard"]["k"], 1);
    assert_eq!(v["shard"]["n"], 2);
    // Every number is an integer; floats are hex text, so they round-trip exactly
    fn walk(v: &Value, numbers: &mut usize, hex: &mut usize) {
        match v {
            Value::Number(n) => {
                assert!(n.is_u64(), "a non-integer number {n} in a shard");
                *numbers += 1;
            }
            Value::String(s) if s.starts_with("0x") || s.starts_with("-0x") => *hex += 1,
            Value::Array(a) => a.iter().for_each(|x| walk(x, numbers, hex)),
            Value::Object(o) => o.values().for_each(|x| walk(x, numbers, hex)),
            _ => {}
        }
    }
    let (mut numbers, mut hex) = (0, 0);
    walk(&v, &mut numbers, &mut hex);
    assert!(
        numbers > 100 && hex > 100,
        "{numbers} numbers, {hex} hex floats"
    );
    // Shard 1/2 of 40 cases: 20 cases in every tally, examples from odd indices only
    let sphere = &v["shapes"][0];
    for g in sphere["groups"].as_array().unwrap() {
        for t in g["tallies"].as_array().unwrap() {
            assert_eq!(t["cases"], 20);
            for e in t["examples"].as_array().unwrap() {
                assert_eq!(e[1]["index"].as_u64().unwrap() % 2, 1, "{e}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A refusal: exit `code`, exactly one line on stderr containing `what`, no panic, and no
/// report written.
fn assert_refused(dir: &Path, shards: &[&Path], code: i32, what: &str) {
    let out = dir.join("refused.json");
    let mut args = vec!["merge".to_string(), "--verbose".to_string()];
    args.extend(shards.iter().map(|p| s(p)));
    args.extend(["--json".into(), s(&out)]);
    let o = run(&args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(code), "{shards:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(err.starts_with("error: "), "{err}");
    assert!(err.contains(what), "'{what}' not in: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "a refused merge wrote {}", out.display());
}

#[test]
fn merge_refuses_a_shard_set_that_is_not_one_audit() {
    let dir = scratch("sets");
    let sel = selection(1, 30);
    let p = |name: &str| dir.join(name);
    for k in 0..3 {
        write_shard(&sel, k, 3, &p(&format!("s{k}.json")));
    }
    let (s0, s1, s2) = (p("s0.json"), p("s1.json"), p("s2.json"));
    // The complete set merges (so each refusal below is about what was changed)
    let o = run(&["merge".into(), s(&s0), s(&s1), s(&s2)]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", stderr(&o));

    // Missing and duplicate shards
    assert_refused(&dir, &[&s0, &s1], 3, "missing shard 2/3");
    assert_refused(&dir, &[&s2], 3, "missing shard 0/3, 1/3");
    assert_refused(&dir, &[&s0, &s1, &s1], 3, "shard 1/3 given twice");
    assert_refused(&dir, &[&s0, &s1, &s2, &s0], 3, "shard 0/3 given twice");

    // Shards of another audit: seed, cases, selection, N
    write_shard(&selection(2, 30), 1, 3, &p("seed2.json"));
    assert_refused(&dir, &[&s0, &p("seed2.json"), &s2], 3, "seed 1 vs 2");
    write_shard(&selection(1, 31), 1, 3, &p("cases31.json"));
    assert_refused(&dir, &[&s0, &p("cases31.json"), &s2], 3, "cases per class");
    let mut other = selection(1, 30);
    other[7] = "algebraic,rtg7".into();
    write_shard(&other, 1, 3, &p("methods.json"));
    assert_refused(&dir, &[&s0, &p("methods.json"), &s2], 3, "methods");
    let mut other = selection(1, 30);
    other[11] = "tangent,far_small,on_surface,invalid".into();
    write_shard(&other, 1, 3, &p("order.json"));
    assert_refused(&dir, &[&s0, &p("order.json"), &s2], 3, "classes");
    write_shard(&sel, 1, 2, &p("n2.json"));
    assert_refused(&dir, &[&s0, &p("n2.json"), &s2], 3, "shard count N");

    // A shard from another rayproof version
    let mut v: Value = serde_json::from_slice(&std::fs::read(&s1).unwrap()).unwrap();
    v["tool"] = "rayproof 0.0.1".into();
    std::fs::write(p("old.json"), serde_json::to_vec(&v).unwrap()).unwrap();
    assert_refused(
        &dir,
        &[&s0, &p("old.json"), &s2],
        3,
        "written by rayproof 0.0.1",
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn merge_refuses_corrupt_files_with_one_line() {
    let dir = scratch("corrupt");
    let sel = selection(1, 30);
    let p = |name: &str| dir.join(name);
    write_shard(&sel, 0, 2, &p("s0.json"));
    write_shard(&sel, 1, 2, &p("s1.json"));
    let s0 = p("s0.json");
    let good = std::fs::read(p("s1.json")).unwrap();
    let o = run(&["merge".into(), s(&s0), s(&p("s1.json"))]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", stderr(&o));

    let put = |name: &str, bytes: &[u8]| {
        std::fs::write(p(name), bytes).unwrap();
        p(name)
    };
    let tampered = |name: &str, edit: &dyn Fn(&mut Value)| {
        let mut v: Value = serde_json::from_slice(&good).unwrap();
        edit(&mut v);
        put(name, &serde_json::to_vec(&v).unwrap())
    };

    // Unreadable, truncated, empty, binary, and JSON that is not a shard
    assert_refused(&dir, &[&s0, &p("absent.json")], 2, "cannot read");
    let half = put("half.json", &good[..good.len() / 2]);
    assert_refused(&dir, &[&s0, &half], 2, "truncated shard");
    assert_refused(&dir, &[&s0, &put("empty.json", b"")], 2, "empty.json");
    assert_refused(
        &dir,
        &[&s0, &put("bin.json", &[0xff, 0xfe, 0, 7])],
        2,
        "bin.json",
    );
    assert_refused(
        &dir,
        &[&s0, &put("arr.json", b"[1, 2]")],
        2,
        "not a rayproof audit shard",
    );
    // the audit's own report JSON is not a shard
    let mut args = vec!["audit".to_string()];
    args.extend_from_slice(&sel);
    args.extend(["--json".into(), s(&p("report.json"))]);
    run(&args);
    assert_refused(
        &dir,
        &[&s0, &p("report.json")],
        2,
        "not a rayproof audit shard",
    );

    // A shard damaged inside: format version, a tally's case count, a tally removed, a float
    // that is not exact text, an unknown shape or class, an unknown field, a bad K/N
    let f = tampered("version.json", &|v| v["format_version"] = 99.into());
    assert_refused(&dir, &[&s0, &f], 2, "format version 99");
    let f = tampered("count.json", &|v| {
        v["shapes"][0]["groups"][3]["tallies"][0]["cases"] = 14.into()
    });
    assert_refused(&dir, &[&s0, &f], 2, "14 cases where shard 1/2 of 30 has 15");
    let f = tampered("tally.json", &|v| {
        v["shapes"][0]["groups"][3]["tallies"]
            .as_array_mut()
            .unwrap()
            .pop();
    });
    assert_refused(&dir, &[&s0, &f], 2, "3 tallies for 4 methods");
    let f = tampered("float.json", &|v| {
        v["shapes"][0]["groups"][0]["tallies"][0]["examples"][0][1]["input"][0] =
            "0x1.zzp+3".into();
    });
    assert_refused(&dir, &[&s0, &f], 2, "not an exact float");
    let f = tampered("number.json", &|v| {
        v["shapes"][0]["groups"][0]["tallies"][0]["examples"][0][1]["input"][0] = 1.5.into();
    });
    assert_refused(&dir, &[&s0, &f], 2, "corrupt shard");
    let f = tampered("shape.json", &|v| v["shapes"][0]["shape"] = "magic".into());
    assert_refused(&dir, &[&s0, &f], 2, "unknown shape 'magic'");
    let f = tampered("class.json", &|v| {
        v["shapes"][0]["classes"][1] = "magic".into()
    });
    assert_refused(&dir, &[&s0, &f], 2, "unknown class 'magic'");
    let f = tampered("field.json", &|v| v["extra"] = 1.into());
    assert_refused(&dir, &[&s0, &f], 2, "unknown field");
    let f = tampered("kn.json", &|v| v["shard"]["k"] = 7.into());
    assert_refused(&dir, &[&s0, &f], 2, "shard 7/2");
    let f = tampered("cases.json", &|v| {
        v["shapes"][0]["cases_per_class"] = u64::MAX.into()
    });
    assert_refused(&dir, &[&s0, &f], 2, "corrupt shard");
    // Counts a run cannot make: a finding zeroed (its example kept), an ill-posed case
    // dropped, a finding added without its example
    let mut edits = 0;
    for (name, key, delta, want) in [
        ("fh.json", "false_hit", None, "an example for each finding"),
        (
            "posed.json",
            "ill_posed",
            Some(-1),
            "cases = generator failures",
        ),
        (
            "fm.json",
            "false_miss",
            Some(1),
            "an example for each finding",
        ),
    ] {
        let f = tampered(name, &|v| {
            // The first tally with this finding (or any tally, to add one)
            for g in v["shapes"][0]["groups"].as_array_mut().unwrap() {
                for t in g["tallies"].as_array_mut().unwrap() {
                    let n = t[key].as_i64().unwrap();
                    let apply = match delta {
                        None => n > 0,
                        Some(d) if d > 0 => n == 0,
                        Some(_) => n > 0,
                    };
                    if apply {
                        t[key] = delta.map_or(0, |d| n + d).into();
                        return;
                    }
                }
            }
        });
        let changed = std::fs::read(&f).unwrap() != good;
        edits += changed as usize;
        assert_refused(&dir, &[&s0, &f], 2, want);
    }
    assert_eq!(edits, 3);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn merge_usage_errors_get_one_line_and_exit_2() {
    let o = rayproof(&["merge"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("SHARD"), "{}", stderr(&o));
    let o = rayproof(&["merge", "x.json", "--json", "/no/such/dir/out.json"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("/no/such/dir"), "{}", stderr(&o));
    let o = rayproof(&[
        "audit",
        "--cases",
        "5",
        "--shard-out",
        "/no/such/dir/s.json",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("/no/such/dir"), "{}", stderr(&o));
}

/// A shard knows what it is (issue 45): shards of two routines that share `--name` are not one
/// audit, and a copy of shard 1/2 relabelled 0/2 is not shard 0/2. Both merged to
/// "verdict: pass" before.
#[test]
fn merge_refuses_two_routines_under_one_name_and_a_relabelled_copy() {
    let dir = scratch("identity");
    let sphere = crate::common::outside("sphere_textbook.py");
    let base = |cmd: &str| -> Vec<String> {
        [
            "--cases",
            "40",
            "--seed",
            "1",
            "--shape",
            "sphere",
            "--precision",
            "f64",
            "--class",
            "random,tangent",
            "--exec",
            cmd,
            "--name",
            "mine",
        ]
        .iter()
        .map(|x| x.to_string())
        .collect()
    };
    let (a, b) = (
        format!("python3 '{}'", sphere.display()),
        // Another routine under the same name: every case a miss
        "while read l; do echo 0; done".to_string(),
    );
    let (s0, s1) = (dir.join("s0.json"), dir.join("s1.json"));
    write_shard(&base(&a), 0, 2, &s0);
    write_shard(&base(&b), 1, 2, &s1);
    let o = run(&["merge".to_string(), s(&s0), s(&s1)]);
    assert_eq!(o.status.code(), Some(3), "{}", stdout(&o));
    let err = stderr(&o);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("not shards of one audit: methods"), "{err}");
    assert!(err.contains("--exec while read l"), "{err}");
    // The same routine: merges
    write_shard(&base(&a), 1, 2, &s1);
    let o = run(&["merge".to_string(), s(&s0), s(&s1)]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", stderr(&o));
    // A copy of 1/2 relabelled 0/2
    let text = std::fs::read_to_string(&s1).unwrap();
    let fake = dir.join("fake0.json");
    std::fs::write(
        &fake,
        text.replacen(
            "\"shard\":{\"k\":1,\"n\":2}",
            "\"shard\":{\"k\":0,\"n\":2}",
            1,
        ),
    )
    .unwrap();
    assert_ne!(
        std::fs::read(&fake).unwrap(),
        text.as_bytes(),
        "the label moved"
    );
    let o = run(&["merge".to_string(), s(&fake), s(&s1)]);
    let err = stderr(&o);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    // Refused as shard 1's cases (exit 3), or as a shard 0 without the routine's rows that
    // shard 0 carries (a corrupt file, exit 2)
    match o.status.code() {
        Some(3) => assert!(
            err.contains("is labelled shard 0/2 but holds case")
                || err.contains("ran the same cases"),
            "{err}"
        ),
        Some(2) => assert!(err.contains("rows (0) are not the"), "{err}"),
        c => panic!("{c:?}: {err}"),
    }
    std::fs::remove_dir_all(&dir).ok();
}
