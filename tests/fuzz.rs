//! Property-based fuzzing of the two hostile inputs a user hands rayproof: scene files and
//! image files. Mutated reference scenes are rendered, mutated EXR headers are diffed; every run
//! must end with exit 0 or a one-line error with a documented code, never an abort or a signal,
//! write no file but the intended outputs, and leave an existing output byte-identical when it
//! fails.

use crate::common::scratch;
use proptest::prelude::*;
use std::path::Path;
use std::process::Command;
use std::sync::OnceLock;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The reference scenes' text (the meshes of some are not needed: those scenes have none).
fn scenes() -> &'static Vec<(String, String)> {
    static S: OnceLock<Vec<(String, String)>> = OnceLock::new();
    S.get_or_init(|| {
        ["diffuse", "mirror", "glass", "far", "floor", "shapes"]
            .iter()
            .map(|n| {
                let t = std::fs::read_to_string(root().join(format!("reference/scenes/{n}.toml")))
                    .unwrap();
                (n.to_string(), t)
            })
            .collect()
    })
}

/// Values that have broken parsers and renderers before.
const HOSTILE: [&str; 16] = [
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "1e308",
    "-1e308",
    "4294967295",
    "99999999999",
    "1e-320",
    "\"x\"",
    "[]",
    "[1.0]",
    "[nan, nan, nan]",
    "[0.0, 0.0, 0.0]",
    "10000",
];

/// One mutation of a scene's text: a number replaced, a line dropped or doubled.
fn mutate(text: &str, kind: usize, at: usize, value: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let i = at % lines.len();
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    match kind % 4 {
        // the value of a `key = value` line
        0 | 1 => {
            let candidates: Vec<usize> = (0..lines.len())
                .filter(|&k| lines[k].contains('='))
                .collect();
            let k = candidates[at % candidates.len()];
            let key = lines[k].split('=').next().unwrap().trim_end();
            out[k] = format!("{key} = {}", HOSTILE[value % HOSTILE.len()]);
        }
        2 => {
            out.remove(i);
        }
        _ => out.insert(i, lines[i].to_string()),
    }
    out.join("\n") + "\n"
}

/// Exit code and standard error of a command; `None` for a signal (an abort).
fn run(args: &[&str]) -> (Option<i32>, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn listing(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2500, rng_seed: proptest::test_runner::RngSeed::Fixed(2500), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn a_mutated_scene_renders_or_is_one_line_exit_2(scene in 0usize..6, kind in 0usize..4, at in 0usize..10_000, value in 0usize..64) {
        let (name, text) = &scenes()[scene];
        let d = scratch("scene");
        let s = d.join("s.toml");
        std::fs::write(&s, mutate(text, kind, at, value)).unwrap();
        // An existing output that a failure must leave as it was
        let out = d.join("o.exr");
        std::fs::write(&out, b"previous").unwrap();
        let (code, err) = run(&["render", s.to_str().unwrap(), "--width", "8", "--spp", "1", "-o", out.to_str().unwrap()]);
        prop_assert!(code == Some(0) || code == Some(2), "{name}: exit {code:?}: {err}");
        if code == Some(2) {
            prop_assert_eq!(err.trim_end().lines().count(), 1, "{}: {}", name, err);
            prop_assert_eq!(std::fs::read(&out).unwrap(), b"previous".to_vec());
            prop_assert_eq!(listing(&d), vec!["o.exr".to_string(), "s.toml".to_string()]);
        } else {
            prop_assert_eq!(listing(&d), vec!["o.exr".to_string(), "o.exr.json".to_string(), "s.toml".to_string()]);
            let side: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("o.exr.json")).unwrap()).unwrap();
            prop_assert_eq!(&side["nonfinite_pixels"], &serde_json::json!(0), "{}", name);
        }
    }

    #[test]
    fn a_mutated_exr_header_is_compared_or_refused_in_one_line(byte in 0usize..400, value in 0u8..=255, cut in 0usize..8) {
        let d = scratch("fuzz-exr");
        let good = d.join("good.exr");
        if !good.exists() {
            let img = rayproof::images::Image::rgb(16, 16, (0..768).map(|i| i as f32 / 768.0).collect());
            rayproof::images::write_exr_rgb(&good, &img).unwrap();
        }
        let mut bytes = std::fs::read(&good).unwrap();
        let k = byte % bytes.len().min(400);
        bytes[k] = value;
        if cut == 0 {
            bytes.truncate(k + 1);
        }
        let bad = d.join("bad.exr");
        std::fs::write(&bad, &bytes).unwrap();
        let (code, err) = run(&["diff", "--no-flip", "-q", good.to_str().unwrap(), bad.to_str().unwrap()]);
        prop_assert!(matches!(code, Some(0..=4)), "exit {code:?}: {err}");
        if matches!(code, Some(3) | Some(4)) {
            prop_assert_eq!(err.trim_end().lines().count(), 1, "{}", err);
        }
    }
}
