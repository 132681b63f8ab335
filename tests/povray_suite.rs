//! The real POV-Ray 3.7 as a user's renderer, driven by a suite (issue 36, items 1–3 and the
//! POV-Ray part of 7): three small scenes sharing an include file, rendered to PNG (`+FN`) at a
//! non-square size through `{width}` and `{height}`; an edited scene makes its golden stale (it
//! renders, fails, and `--update` re-blesses it); an edited include file makes every golden
//! stale; a missing include is reported by POV-Ray's own error line, not by its first line
//! (`cannot open the user configuration file`, printed on every run), and the whole log is kept
//! in the report and linked from the HTML, the JUnit XML and the JSON.
//!
//! POV-Ray must be installed (Debian's `povray`; `.ci/run` installs it): without it these tests
//! fail, they do not skip.

use crate::common::scratch;
use rayproof::golden::sha256_file;
use std::path::Path;
use std::process::Command;

/// Fails loudly when POV-Ray is not installed.
fn require_povray() {
    let ok = Command::new("sh")
        .arg("-c")
        .arg("command -v povray")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    assert!(
        ok,
        "POV-Ray is not installed: these tests run the real one (apt-get install povray; .ci/run installs it)"
    );
}

fn check(dir: &Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(dir)
        .arg("check")
        .arg("--suite")
        .arg(dir.join("suite.toml"))
        .args(extra)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn line<'a>(out: &'a str, test: &str, reference: &str) -> &'a str {
    out.lines()
        .find(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            w.len() > 3 && w[0] == test && w[1] == reference
        })
        .unwrap_or_else(|| panic!("no {test} × {reference} row in:\n{out}"))
}

fn status(out: &str, test: &str) -> String {
    line(out, test, "golden")
        .split_whitespace()
        .nth(3)
        .unwrap()
        .to_string()
}

fn stale(out: &str, test: &str) -> bool {
    let row = line(out, test, "golden");
    out.lines()
        .skip_while(|l| *l != row)
        .skip(1)
        .take_while(|l| l.trim_start().starts_with("warning:"))
        .any(|l| l.contains("stale golden"))
}

/// A scene: a floor and two spheres lit by `light.inc`'s light at x = `lx`.
fn scene(lx: &str, colour: &str) -> String {
    format!(
        "#version 3.7;\nglobal_settings {{ assumed_gamma 1.0 }}\n#declare LX = {lx};\n#include \"light.inc\"\n\
         camera {{ location <0, 1.5, -5> look_at <0, 0.5, 0> right x*image_width/image_height }}\n\
         plane {{ y, 0 pigment {{ rgb <0.8, 0.8, 0.8> }} }}\n\
         sphere {{ <-0.8, 0.5, 0>, 0.5 pigment {{ rgb {colour} }} }}\n\
         sphere {{ <0.8, 0.5, 0>, 0.5 pigment {{ rgb <0.1, 0.3, 1> }} }}\n"
    )
}

const LIGHT: &str = "light_source { <LX, 4, -3> color rgb 1 }\n";

#[test]
fn povray_png_goldens_follow_the_scene_and_its_include_file() {
    require_povray();
    let dir = scratch("povray-follow");
    std::fs::write(dir.join("light.inc"), LIGHT).unwrap();
    std::fs::write(dir.join("balls.pov"), scene("3", "<1, 0.2, 0.1>")).unwrap();
    std::fs::write(dir.join("green.pov"), scene("-2", "<0.1, 1, 0.2>")).unwrap();
    std::fs::write(dir.join("grey.pov"), scene("0", "<0.5, 0.5, 0.5>")).unwrap();
    let suite = r#"[suite]
name = "povray"
renderer = "povray +I{scene} +O{out} +FN +W{width} +H{height} -D -V"
output = "png"
goldens = "goldens"
timeout = 60

[[test]]
name = "balls"
scene = "balls.pov"
inputs = ["light.inc"]
width = 40
height = 30

[[test]]
name = "green"
scene = "green.pov"
inputs = ["light.inc"]
width = 32
height = 20

[[test]]
name = "grey"
scene = "grey.pov"
inputs = ["light.inc"]
width = 24
height = 24
"#;
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    let tests = ["balls", "green", "grey"];

    // No goldens yet: NEW; --update blesses PNG goldens of the asked size
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(1), "{out}{err}");
    for t in tests {
        assert_eq!(status(&out, t), "NEW", "{out}");
    }
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    for (t, w, h) in [("balls", 40, 30), ("green", 32, 20), ("grey", 24, 24)] {
        let p = dir.join(format!("goldens/{t}.png"));
        let bytes = std::fs::read(&p).unwrap();
        assert!(bytes.starts_with(b"\x89PNG"), "{t}: not a PNG");
        let img = rayproof::images::read_image(&p).unwrap();
        assert_eq!((img.width, img.height), (w, h), "{t}");
        assert!(!dir.join(format!("goldens/{t}.exr")).exists());
    }
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("goldens/manifest.json")).unwrap()).unwrap();
    let e = &m["files"]["balls.png"];
    assert_eq!(
        e["commands"][0], "povray +I{scene} +O{out} +FN +W{width} +H{height} -D -V",
        "{e}"
    );
    assert_eq!(e["scene"], "balls.pov");
    assert_eq!(
        e["inputs"]["light.inc"].as_str().unwrap(),
        sha256_file(&dir.join("light.inc")).unwrap()
    );
    assert_eq!(
        (e["width"].as_u64(), e["height"].as_u64()),
        (Some(40), Some(30))
    );
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    for t in tests {
        assert_eq!(status(&out, t), "PASS", "{out}");
    }
    let blessed: Vec<Vec<u8>> = tests
        .iter()
        .map(|t| std::fs::read(dir.join(format!("goldens/{t}.png"))).unwrap())
        .collect();

    // The light moves in one scene: rendered and compared (FAILURE), the row says stale
    std::fs::write(dir.join("balls.pov"), scene("3.05", "<1, 0.2, 0.1>")).unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "balls"), "FAILURE", "{out}");
    assert!(stale(&out, "balls"), "{out}");
    assert!(line(&out, "balls", "golden").contains("px"), "{out}");
    for t in ["green", "grey"] {
        assert_eq!(status(&out, t), "PASS", "{out}");
        assert!(!stale(&out, t), "{out}");
    }
    // --update --test balls re-blesses it, and only it
    let (code, out, _) = check(&dir, &["--update", "--test", "balls"]);
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(status(&out, "balls"), "UPDATED", "{out}");
    let now: Vec<Vec<u8>> = tests
        .iter()
        .map(|t| std::fs::read(dir.join(format!("goldens/{t}.png"))).unwrap())
        .collect();
    assert_ne!(now[0], blessed[0]);
    assert_eq!(now[1..], blessed[1..]);
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    assert!(!out.contains("stale"), "{out}");

    // The include file changes without changing a pixel: every golden is stale but passes, and
    // --update re-blesses every one (stale goldens are always re-blessed)
    std::fs::write(dir.join("light.inc"), format!("// the key light\n{LIGHT}")).unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    for t in tests {
        assert_eq!(status(&out, t), "PASS", "{out}");
        assert!(stale(&out, t), "{out}");
    }
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}");
    for t in tests {
        assert_eq!(status(&out, t), "UPDATED", "{out}");
    }
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    assert!(!out.contains("stale"), "{out}");
}

#[test]
fn povray_failing_include_shows_its_error_line_and_keeps_the_log() {
    require_povray();
    let dir = scratch("povray-include");
    std::fs::write(dir.join("light.inc"), LIGHT).unwrap();
    std::fs::write(dir.join("ok.pov"), scene("3", "<1, 0.2, 0.1>")).unwrap();
    std::fs::write(
        dir.join("broken.pov"),
        scene("3", "<1, 0.2, 0.1>").replace("light.inc", "spot.inc"),
    )
    .unwrap();
    // Keys the first rayproof of issue 36 knew too: EXR output, square frames
    let suite = r#"[suite]
name = "povray"
renderer = "povray +I{scene} +O{out} +FE +W{width} +H{width} -D -V"
goldens = "goldens"
timeout = 60

[[test]]
name = "ok"
scene = "ok.pov"
width = 16

[[test]]
name = "broken"
scene = "broken.pov"
width = 16
"#;
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    let (report, junit, json) = (
        dir.join("report"),
        dir.join("junit.xml"),
        dir.join("rows.json"),
    );
    let (code, out, err) = check(
        &dir,
        &[
            "--update",
            "--report",
            report.to_str().unwrap(),
            "--junit",
            junit.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ],
    );
    assert_eq!(code, Some(3), "{out}{err}");
    let row = line(&out, "broken", "golden");
    assert!(row.contains("REFUSED"), "{row}");
    assert!(row.contains("Cannot open include file spot.inc"), "{row}");
    assert!(!row.contains("user configuration file"), "{row}");
    assert!(!row.contains("Stream to console"), "{row}");
    assert!(out.contains("--update wrote nothing"), "{out}");
    assert!(!dir.join("goldens").exists());
    // The whole log, in the report: the command, POV-Ray's every line
    let log = std::fs::read_to_string(report.join("logs/broken.log")).unwrap();
    assert!(log.starts_with("$ povray +I"), "{log}");
    assert!(
        log.contains("cannot open the user configuration file"),
        "{log}"
    );
    assert!(log.contains("Cannot open include file spot.inc"), "{log}");
    assert!(log.contains("Render failed"), "{log}");
    assert!(report.join("logs/ok.log").is_file());
    let page = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(page.contains("href=\"logs/broken.log\""), "{page}");
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert!(xml.contains("logs/broken.log"), "{xml}");
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let broken = rows
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["test"] == "broken")
        .unwrap();
    assert_eq!(broken["log"], "logs/broken.log");
    // The tail a row keeps is what explains the failure, never POV-Ray's credits banner; a
    // render that worked keeps none (its banner explains nothing)
    let tail = broken["log_tail"].as_str().unwrap();
    assert!(tail.contains("Cannot open include file spot.inc"), "{tail}");
    assert!(!tail.contains("Persistence of Vision"), "{tail}");
    assert!(!tail.contains("POV-Ray is based on"), "{tail}");
    let ok = rows
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["test"] == "ok")
        .unwrap();
    assert_eq!(ok["log_tail"], serde_json::Value::Null, "{ok}");
    assert!(!xml.contains("Persistence of Vision"), "{xml}");
}
