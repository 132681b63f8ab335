//! `rayproof builds` (issue 49 item 3): the same C routine under GCC and Clang, contraction off,
//! on with FMA, and fast-math, audited side by side with the real compilers.
//!
//! `tests/outside/contraction.c`: Möller–Trumbore as usually written flips hit and miss on
//! hundreds of edge cases once the compiler fuses its multiply-adds; the same test with the
//! fusion written in the source (`fmaf` everywhere) gives every contraction build the
//! baseline's verdicts. Fast-math still flips it (it flushes subnormals: the `tiny` class).

use crate::common::{rayproof, stderr, stdout};

const SOURCE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/outside/contraction.c");

/// `rayproof builds` of one symbol with `compilers`: the exit code and the JSON.
fn builds(symbol: &str, compilers: &str) -> (i32, serde_json::Value, String) {
    let dir = crate::common::temp_dir("builds");
    let json = dir.join("b.json");
    let source = format!("{SOURCE}:{symbol}");
    let o = rayproof(&[
        "builds",
        "--shape",
        "triangle",
        "--source",
        &source,
        "--cases",
        "600",
        "--compiler",
        compilers,
        "--json",
        json.to_str().unwrap(),
    ]);
    let text = format!("{}{}", stdout(&o), stderr(&o));
    let v = serde_json::from_str(&std::fs::read_to_string(&json).unwrap_or_default())
        .unwrap_or_else(|_| panic!("no JSON: {text}"));
    (o.status.code().unwrap_or(-1), v, text)
}

fn row<'a>(v: &'a serde_json::Value, build: &str) -> &'a serde_json::Value {
    v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["build"] == build)
        .unwrap_or_else(|| panic!("no row {build}: {v}"))
}

#[test]
fn contraction_flips_the_textbook_triangle_and_not_the_fused_one() {
    let fma = rayproof::audit::builds::machine_has_fma();
    for compiler in ["gcc", "clang"] {
        let (code, v, text) = builds("tri_mt_f32", compiler);
        let off = row(&v, &format!("{compiler}-off"));
        assert_eq!(off["flips"], 0, "{text}");
        // The build lines are printed, to be run again by hand
        assert!(
            text.contains(&format!("{compiler} -O2 -ffp-contract=off -shared -fPIC")),
            "{text}"
        );
        if !fma {
            assert_eq!(code, 0, "{text}");
            continue;
        }
        let on = row(&v, &format!("{compiler}-fma"));
        assert!(on["flips"].as_u64().unwrap() > 50, "{compiler}: {text}");
        assert_eq!(code, 1, "{text}");
        // Each flip replays: its inputs as hex floats, the builds' verdicts per build
        let flips = v["flips"].as_array().unwrap();
        assert!(!flips.is_empty());
        for f in flips {
            assert!(
                f["probe"]
                    .as_str()
                    .unwrap()
                    .starts_with("rayproof probe triangle --precision f32 -- "),
                "{f}"
            );
            assert_eq!(f["hits"].as_array().unwrap().len(), 3);
            assert!(f["probe"].as_str().unwrap().contains("0x1."), "{f}");
        }
        let (_, v, text) = builds("tri_fused_f32", compiler);
        assert_eq!(
            row(&v, &format!("{compiler}-fma"))["flips"],
            0,
            "{compiler}: {text}"
        );
        assert_eq!(
            row(&v, &format!("{compiler}-fma"))["added_ulps"],
            0,
            "{compiler}: {text}"
        );
    }
}

#[test]
fn a_source_that_does_not_build_or_a_missing_compiler_is_one_line() {
    let dir = crate::common::temp_dir("builds-bad");
    let bad = dir.join("bad.c");
    std::fs::write(&bad, "int f(void) { return syntax error; }\n").unwrap();
    let spec = format!("{}:f_f32", bad.display());
    let o = rayproof(&[
        "builds",
        "--shape",
        "triangle",
        "--source",
        &spec,
        "--compiler",
        "gcc",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("build gcc-off failed"),
        "{}",
        stderr(&o)
    );
    let spec = format!("{SOURCE}:tri_mt_f32");
    let o = rayproof(&[
        "builds",
        "--shape",
        "triangle",
        "--source",
        &spec,
        "--compiler",
        "no-such-cc",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--compiler no-such-cc"),
        "{}",
        stderr(&o)
    );
    let o = rayproof(&[
        "builds",
        "--shape",
        "triangle",
        "--source",
        "/no/such.c:f_f32",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}
