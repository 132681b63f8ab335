//! Goldens that follow the scene, manifests that record what a golden was made from, and the
//! files a renderer may leave at `{out}` (issue 36, items 1 and 3 and "Bad input"), with the
//! stand-in renderer `tests/outside/standin_render.py` (the real POV-Ray: tests/povray_suite.rs).
//!
//! - A golden made from an older scene or include file is compared as usual, its row says it is
//!   stale, and `--update` re-blesses it (every stale golden, passing or not).
//! - The manifest records each test's own scene and inputs by hash and the command as the suite
//!   writes it, never a scratch path.
//! - A directory, a symbolic link, an empty or truncated file, a file of another format than
//!   declared or an EXR of 10,000 parts at `{out}`: one line naming the test and the problem,
//!   the test refused, nothing blessed.

use crate::common::{s, scratch};
use rayproof::golden::sha256_file;
use std::path::{Path, PathBuf};
use std::process::Command;

fn standin() -> String {
    format!(
        "python3 '{}'",
        s(&crate::common::outside("standin_render.py"))
    )
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

/// The row line of test × reference in the text table.
fn line<'a>(out: &'a str, test: &str, reference: &str) -> &'a str {
    out.lines()
        .find(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            w.len() > 3 && w[0] == test && w[1] == reference
        })
        .unwrap_or_else(|| panic!("no {test} × {reference} row in:\n{out}"))
}

fn status(out: &str, test: &str, reference: &str) -> String {
    line(out, test, reference)
        .split_whitespace()
        .nth(3)
        .unwrap()
        .to_string()
}

/// The warning lines under a test's row.
fn warnings<'a>(out: &'a str, test: &str, reference: &str) -> Vec<&'a str> {
    let row = line(out, test, reference);
    out.lines()
        .skip_while(|l| *l != row)
        .skip(1)
        .take_while(|l| l.trim_start().starts_with("warning:"))
        .collect()
}

fn manifest(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("goldens/manifest.json")).unwrap())
        .unwrap()
}

/// Two tests of the stand-in, each with its own scene file and a shared include file.
fn fixture(tag: &str) -> PathBuf {
    let dir = scratch(&format!("follow-{tag}"));
    std::fs::write(dir.join("a.scene"), "sphere 1\n").unwrap();
    std::fs::write(dir.join("b.scene"), "sphere 2\n").unwrap();
    let suite = format!(
        r#"[suite]
name = "follow"
renderer = "{r} {{out}} --width {{width}} --grid {{grid}}"
goldens = "goldens"
timeout = 20

[[test]]
name = "a"
scene = "a.scene"
width = 24
grid = 2

[[test]]
name = "b"
scene = "b.scene"
width = 24
grid = 2
"#,
        r = standin()
    );
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    dir
}

#[test]
fn a_stale_golden_is_compared_and_update_reblesses_it() {
    let dir = fixture("stale");
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let a0 = std::fs::read(dir.join("goldens/a.exr")).unwrap();
    let b0 = std::fs::read(dir.join("goldens/b.exr")).unwrap();
    // The scene changes, the image does not: compared (PASS), the row says stale, exit 0
    std::fs::write(dir.join("a.scene"), "sphere 1 # edited\n").unwrap();
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert_eq!(status(&out, "a", "golden"), "PASS", "{out}");
    let w = warnings(&out, "a", "golden");
    assert!(
        w.iter()
            .any(|l| l.contains("stale golden: made from another version of the scene a.scene")),
        "{out}"
    );
    assert!(warnings(&out, "b", "golden").is_empty(), "{out}");
    // --update --test a re-blesses it though it passes: its manifest entry follows the scene
    let (code, out, err) = check(&dir, &["--update", "--test", "a"]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert_eq!(status(&out, "a", "golden"), "UPDATED", "{out}");
    assert!(
        line(&out, "a", "golden").contains("stale → written"),
        "{out}"
    );
    assert_eq!(std::fs::read(dir.join("goldens/a.exr")).unwrap(), a0);
    assert_eq!(std::fs::read(dir.join("goldens/b.exr")).unwrap(), b0);
    let m = manifest(&dir);
    assert_eq!(
        m["files"]["a.exr"]["scene_sha256"].as_str().unwrap(),
        sha256_file(&dir.join("a.scene")).unwrap()
    );
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    assert!(!out.contains("stale"), "{out}");
    // The scene changes and so does the image: a stale golden that fails is a failure (exit 1),
    // not a refusal, and --update re-blesses it
    std::fs::write(dir.join("b.scene"), "sphere 2 # moved\n").unwrap();
    let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    let moved = text.replacen(
        "name = \"b\"\n",
        &format!(
            "name = \"b\"\ncommand = \"{} {{out}} --width {{width}} --grid {{grid}} --perturb 0.3\"\n",
            standin()
        ),
        1,
    );
    std::fs::write(dir.join("suite.toml"), moved).unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "b", "golden"), "FAILURE", "{out}");
    assert!(warnings(&out, "b", "golden")
        .iter()
        .any(|l| l.contains("stale golden")));
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(
        line(&out, "b", "golden").contains("FAILURE, stale → written"),
        "{out}"
    );
    assert_ne!(std::fs::read(dir.join("goldens/b.exr")).unwrap(), b0);
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
}

#[test]
fn the_manifest_records_the_command_as_written_and_each_tests_own_scene_and_inputs() {
    let dir = fixture("manifest");
    std::fs::write(dir.join("light.inc"), "light 1\n").unwrap();
    let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    std::fs::write(
        dir.join("suite.toml"),
        text.replace(
            "scene = \"b.scene\"\n",
            "scene = \"b.scene\"\ninputs = [\"light.inc\"]\n",
        ),
    )
    .unwrap();
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let m = manifest(&dir);
    for (t, scene) in [("a", "a.scene"), ("b", "b.scene")] {
        let e = &m["files"][format!("{t}.exr")];
        assert_eq!(
            e["commands"][0].as_str().unwrap(),
            format!("{} {{out}} --width {{width}} --grid {{grid}}", standin()),
            "{e}"
        );
        assert_eq!(e["scene"], scene, "{e}");
        assert_eq!(
            e["scene_sha256"].as_str().unwrap(),
            sha256_file(&dir.join(scene)).unwrap()
        );
        assert_eq!(
            (e["width"].as_u64(), e["height"].as_u64()),
            (Some(24), Some(16))
        );
    }
    assert!(m.get("scene").is_none(), "one scene for the directory: {m}");
    assert_eq!(
        m["files"]["b.exr"]["inputs"]["light.inc"].as_str().unwrap(),
        sha256_file(&dir.join("light.inc")).unwrap()
    );
    assert_eq!(m["files"]["a.exr"]["inputs"], serde_json::json!({}));
    // An include file changes: only the test that declares it is stale
    std::fs::write(dir.join("light.inc"), "light 2\n").unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    assert!(warnings(&out, "b", "golden")
        .iter()
        .any(|l| l.contains("another version of the input light.inc")));
    assert!(warnings(&out, "a", "golden").is_empty(), "{out}");
    // An input that cannot be read refuses the test, with its name
    std::fs::remove_file(dir.join("light.inc")).unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(3), "{out}");
    assert!(
        line(&out, "b", "golden").contains("the input light.inc: cannot read"),
        "{out}"
    );
}

/// An EXR of `parts` one-pixel parts, each with `groups` layers of R, G, B channels (named
/// `LAYER.R` … when more than one, as Blender's multilayer files), written with the exr crate.
fn many_layer_exr(path: &Path, parts: usize, groups: usize) {
    use exr::prelude::*;
    let layers: Vec<Layer<AnyChannels<FlatSamples>>> = (0..parts)
        .map(|i| {
            let ch = |n: String| AnyChannel::new(n.as_str(), FlatSamples::F32(vec![0.5]));
            let list: Vec<AnyChannel<FlatSamples>> = (0..groups)
                .flat_map(|g| {
                    ["R", "G", "B"].map(|c| {
                        ch(if groups == 1 {
                            c.to_string()
                        } else {
                            format!("L{g}.{c}")
                        })
                    })
                })
                .collect();
            Layer::new(
                (1, 1),
                LayerAttributes::named(format!("layer{i}").as_str()),
                Encoding::UNCOMPRESSED,
                AnyChannels::sort(list.into()),
            )
        })
        .collect();
    Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions((1, 1))),
        layers,
    )
    .write()
    .to_file(path)
    .unwrap();
}

#[test]
fn bad_renderer_outputs_are_one_line_the_test_refused_nothing_blessed() {
    // What the "renderer" leaves at {out} (a shell command), and what the row must say
    let png = "cp good.png {out}";
    let cases: [(&str, &str, &str); 8] = [
        (
            "directory",
            "mkdir {out}",
            "is a directory, not an image file",
        ),
        (
            "symlink",
            "ln -s \"$PWD/goldens/t.exr\" {out}",
            "is a symbolic link",
        ),
        ("empty", ": > {out}", "is empty (0 bytes)"),
        ("truncated", "head -c 1000 good.exr > {out}", "cannot read"),
        (
            "other-format",
            png,
            "is a PNG file, but the test's output format is OpenEXR",
        ),
        (
            "not-an-image",
            "echo hello > {out}",
            "is not a file of the test's output format, OpenEXR",
        ),
        (
            "parts",
            "cp parts.exr {out}",
            "it has 10000 layers (in 10000 part(s)); at most 256",
        ),
        (
            "channel-layers",
            "cp groups.exr {out}",
            "it has 10000 layers (in 1 part(s)); at most 256",
        ),
    ];
    let dir = scratch("bad-outputs");
    // good.exr and good.png from the stand-in; layers.exr with 10,000 parts
    let st = Command::new("sh")
        .arg("-c")
        .arg(format!("{} good.exr --width 24 --grid 1", standin()))
        .current_dir(&dir)
        .status()
        .unwrap();
    assert!(st.success());
    let img = rayproof::images::read_image(&dir.join("good.exr")).unwrap();
    rayproof::images::write_png_rgb8(
        &dir.join("good.png"),
        img.width,
        img.height,
        &rayproof::images::tonemap_rgb8(&img),
    )
    .unwrap();
    many_layer_exr(&dir.join("parts.exr"), 10_000, 1);
    many_layer_exr(&dir.join("groups.exr"), 1, 10_000);
    // Every row is run; the failures of all rows are reported together
    let mut failed: Vec<String> = vec![];
    for (tag, command, want) in cases {
        // A blessed golden for t; u has none yet
        let suite = |cmd: &str| {
            format!(
                "[suite]\nname = \"bad\"\ngoldens = \"goldens\"\ntimeout = 20\n\n[[test]]\nname = \"t\"\ncommand = \"{}\"\n\n[[test]]\nname = \"u\"\ncommand = \"cp good.exr {{out}}\"\n",
                cmd.replace('"', "\\\"")
            )
        };
        let _ = std::fs::remove_dir_all(dir.join("goldens"));
        std::fs::write(dir.join("suite.toml"), suite("cp good.exr {out}")).unwrap();
        let (code, out, err) = check(&dir, &["--update", "--test", "t"]);
        assert_eq!(code, Some(0), "{tag}: {out}{err}");
        let before = (
            std::fs::read(dir.join("goldens/t.exr")).unwrap(),
            std::fs::read(dir.join("goldens/manifest.json")).unwrap(),
        );
        // Now the renderer leaves the bad file
        std::fs::write(dir.join("suite.toml"), suite(command)).unwrap();
        let t0 = std::time::Instant::now();
        let (code, out, err) = check(&dir, &["--update"]);
        let row = out
            .lines()
            .find(|l| l.starts_with("t ") && l.contains(" golden "))
            .unwrap_or("")
            .to_string();
        let next = out.lines().skip_while(|l| *l != row).nth(1).unwrap_or("");
        let after = (
            std::fs::read(dir.join("goldens/t.exr")).unwrap_or_default(),
            std::fs::read(dir.join("goldens/manifest.json")).unwrap_or_default(),
        );
        let checks = [
            (t0.elapsed().as_secs() < 30, "took 30 s or more"),
            (code == Some(3), "exit code is not 3"),
            (row.contains("REFUSED"), "the row is not REFUSED"),
            (row.contains(want), "the row does not say the problem"),
            (
                row.contains("test image"),
                "the row does not say 'test image'",
            ),
            (row.len() < 800, "the row is longer than 800 bytes"),
            // One line: the row has no continuation, stderr says nothing more
            (!next.starts_with(' '), "the row has a continuation line"),
            (err.trim().is_empty(), "something on standard error"),
            // Nothing blessed: t's golden and the manifest as they were, no golden for u
            (
                out.contains("--update wrote nothing"),
                "--update was not withheld",
            ),
            (after == before, "the golden or its manifest changed"),
            (
                !dir.join("goldens/u.exr").exists(),
                "u's golden was written",
            ),
        ];
        for (ok, what) in checks {
            if !ok {
                let row: String = row.chars().take(300).collect();
                failed.push(format!("{tag}: {what} (exit {code:?}; row: {row})"));
            }
        }
    }
    assert!(failed.is_empty(), "\n{}", failed.join("\n"));
}

#[test]
fn the_output_format_follows_the_suite_and_goldens_keep_theirs() {
    let dir = scratch("output-format");
    let st = Command::new("sh")
        .arg("-c")
        .arg(format!("{} good.exr --width 24 --grid 1", standin()))
        .current_dir(&dir)
        .status()
        .unwrap();
    assert!(st.success());
    let img = rayproof::images::read_image(&dir.join("good.exr")).unwrap();
    rayproof::images::write_png_rgb8(
        &dir.join("good.png"),
        img.width,
        img.height,
        &rayproof::images::tonemap_rgb8(&img),
    )
    .unwrap();
    // A renderer that writes only to a name ending in .png (as POV-Ray's +FN appends it)
    let suite = "[suite]\nname = \"fmt\"\ngoldens = \"goldens\"\noutput = \"png\"\n\n[[test]]\nname = \"p\"\ncommand = \"case {out} in *.png) cp good.png {out};; *) exit 9;; esac\"\n";
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let golden = std::fs::read(dir.join("goldens/p.png")).unwrap();
    assert_eq!(golden, std::fs::read(dir.join("good.png")).unwrap());
    assert!(!dir.join("goldens/p.exr").exists());
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(status(&out, "p", "golden"), "PASS", "{out}");
    // A golden named for another format than the output's: one line, exit 2
    let bad = suite.replace(
        "name = \"p\"\n",
        "name = \"p\"\ngolden = \"goldens/p.exr\"\n",
    );
    std::fs::write(dir.join("suite.toml"), bad).unwrap();
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(err.contains("would hold a PNG file: name it .png"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    // An unknown output format: one line, exit 2
    std::fs::write(dir.join("suite.toml"), suite.replace("\"png\"", "\"pdf\"")).unwrap();
    let (code, _, err) = check(&dir, &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("output = \"pdf\" is not an image format rayproof reads"),
        "{err}"
    );
    // Other formats the image crate reads are test images and references: a PPM against a
    // BMP of the same pixels passes
    let ppm = b"P6\n2 1\n255\n\xff\x00\x00\x00\x00\xff".to_vec();
    std::fs::write(dir.join("t.ppm"), &ppm).unwrap();
    let bmp = image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 0, 0, 255]).unwrap();
    bmp.save_with_format(dir.join("r.bmp"), image::ImageFormat::Bmp)
        .unwrap();
    let suite = "[[test]]\nname = \"x\"\nimage = \"t.ppm\"\ngolden = false\nreference = [{ name = \"bmp\", path = \"r.bmp\" }]\n";
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert_eq!(status(&out, "x", "bmp"), "PASS", "{out}");
}

#[test]
fn height_fills_its_placeholder_and_the_frame_is_checked() {
    let dir = scratch("height");
    // A "renderer" that writes a PPM of {width} × {height}
    let suite = "[suite]\nname = \"h\"\ngoldens = \"goldens\"\noutput = \"ppm\"\n\n[[test]]\nname = \"wide\"\nwidth = 5\nheight = 2\ncommand = \"python3 -c 'import sys; w, h = int(sys.argv[2]), int(sys.argv[3]); open(sys.argv[1], \\\"wb\\\").write(b\\\"P6 %d %d 255 \\\" % (w, h) + bytes(3 * w * h))' {out} {width} {height}\"\n";
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let m = manifest(&dir);
    assert_eq!(m["files"]["wide.ppm"]["height"], 2, "{m}");
    assert_eq!(m["files"]["wide.ppm"]["width"], 5, "{m}");
    // Without height in the test, the golden's manifest gives it
    std::fs::write(dir.join("suite.toml"), suite.replace("height = 2\n", "")).unwrap();
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}{err}");
    // A renderer that ignores {height} is refused, not compared
    let square = suite.replace("{width} {height}", "{width} {width}");
    std::fs::write(
        dir.join("suite.toml"),
        square.replace("{width} {width}\"", "{width} {width} {height}\""),
    )
    .unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(3), "{out}");
    assert!(
        line(&out, "wide", "golden")
            .contains("wrote a 5×5 image, but its command was given {height} = 2"),
        "{out}"
    );
}

/// Every cause of a stale golden, one at a time from a fresh blessing: the scene changed, an
/// input changed, added or removed, the renderer command changed, the frame (grid, width) the
/// test gives changed. Each is named in `check`'s warning, `--update` re-blesses the golden, and
/// after it nothing is stale.
#[test]
fn every_cause_of_a_stale_golden_is_named_and_reblessed() {
    type Edit = fn(&Path);
    let edits: [(&str, Edit, &str); 7] = [
        (
            "scene",
            |d| std::fs::write(d.join("a.scene"), "sphere 3\n").unwrap(),
            "another version of the scene a.scene",
        ),
        (
            "input-changed",
            |d| std::fs::write(d.join("x.inc"), "x 2\n").unwrap(),
            "another version of the input x.inc",
        ),
        (
            "input-added",
            |d| {
                std::fs::write(d.join("z.inc"), "z 1\n").unwrap();
                let p = d.join("suite.toml");
                let t = std::fs::read_to_string(&p).unwrap();
                std::fs::write(
                    &p,
                    t.replace(
                        r#"inputs = ["x.inc", "y.inc"]"#,
                        r#"inputs = ["x.inc", "y.inc", "z.inc"]"#,
                    ),
                )
                .unwrap();
            },
            "the input z.inc (not recorded)",
        ),
        (
            "input-removed",
            |d| {
                let p = d.join("suite.toml");
                let t = std::fs::read_to_string(&p).unwrap();
                std::fs::write(
                    &p,
                    t.replace(r#"inputs = ["x.inc", "y.inc"]"#, r#"inputs = ["x.inc"]"#),
                )
                .unwrap();
            },
            "the input y.inc (no longer one)",
        ),
        (
            "command",
            |d| {
                let p = d.join("suite.toml");
                let t = std::fs::read_to_string(&p).unwrap();
                std::fs::write(
                    &p,
                    t.replace("--grid {grid}\"", "--grid {grid} --perturb 0\""),
                )
                .unwrap();
            },
            "the renderer command (was `",
        ),
        (
            "grid",
            |d| {
                let p = d.join("suite.toml");
                let t = std::fs::read_to_string(&p).unwrap();
                std::fs::write(&p, t.replace("grid = 2", "grid = 3")).unwrap();
            },
            "the grid (3, was 2)",
        ),
        (
            "width",
            |d| {
                let p = d.join("suite.toml");
                let t = std::fs::read_to_string(&p).unwrap();
                std::fs::write(&p, t.replace("width = 24", "width = 32")).unwrap();
            },
            "the width (32, was 24)",
        ),
    ];
    for (tag, edit, want) in edits {
        let dir = scratch(&format!("follow-cause-{tag}"));
        std::fs::write(dir.join("a.scene"), "sphere 1\n").unwrap();
        std::fs::write(dir.join("x.inc"), "x 1\n").unwrap();
        std::fs::write(dir.join("y.inc"), "y 1\n").unwrap();
        let suite = format!(
            r#"[suite]
name = "causes"
renderer = "{r} {{out}} --width {{width}} --grid {{grid}}"
goldens = "goldens"
timeout = 20

[[test]]
name = "a"
scene = "a.scene"
inputs = ["x.inc", "y.inc"]
width = 24
grid = 2
"#,
            r = standin()
        );
        std::fs::write(dir.join("suite.toml"), suite).unwrap();
        let (code, out, err) = check(&dir, &["--update"]);
        assert_eq!(code, Some(0), "{tag}: {out}{err}");
        let (code, out, err) = check(&dir, &[]);
        assert_eq!(code, Some(0), "{tag}: {out}{err}");
        assert!(!out.contains("stale"), "{tag}: fresh, yet {out}");
        edit(&dir);
        // Named, whether the image changed (exit 1) or not (exit 0)
        let (code, out, err) = check(&dir, &[]);
        assert!(matches!(code, Some(0 | 1)), "{tag}: {out}{err}");
        assert!(
            warnings(&out, "a", "golden")
                .iter()
                .any(|l| l.contains("stale golden") && l.contains(want)),
            "{tag}: no stale warning naming {want:?} in\n{out}"
        );
        // Re-blessed, and then fresh
        let (code, out, err) = check(&dir, &["--update"]);
        assert_eq!(code, Some(0), "{tag}: {out}{err}");
        assert!(
            line(&out, "a", "golden").contains("stale → written"),
            "{tag}: {out}"
        );
        let (code, out, err) = check(&dir, &[]);
        assert_eq!(code, Some(0), "{tag}: {out}{err}");
        assert!(!out.contains("stale"), "{tag}: after --update, {out}");
    }
}

/// A file at a golden's path with no manifest beside it is not a golden rayproof blessed: the
/// test is refused (its staleness and hash cannot be known), and `--update` writes nothing over
/// it (the hostile run: `goldens = "."` and a user's `victim.exr` was replaced).
#[test]
fn a_golden_without_a_manifest_is_refused_and_never_overwritten() {
    let dir = scratch("follow-nomanifest");
    std::fs::write(dir.join("victim.exr"), b"the user's own file").unwrap();
    let suite = format!(
        r#"[suite]
name = "nomanifest"
renderer = "{r} {{out}} --width 8 --grid 1"
goldens = "."
timeout = 20

[[test]]
name = "victim"
"#,
        r = standin()
    );
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    for extra in [&[][..], &["--update"][..]] {
        let (code, out, err) = check(&dir, extra);
        assert_eq!(code, Some(3), "{extra:?}: {out}{err}");
        assert!(
            line(&out, "victim", "golden").contains("REFUSED")
                && out.contains("no manifest.json beside it"),
            "{out}"
        );
        assert_eq!(
            std::fs::read(dir.join("victim.exr")).unwrap(),
            b"the user's own file"
        );
    }
}

/// Issue 46 (3): two `check --update` runs at once on one suite (`--test a` and `--test b`, as
/// two CI jobs would) both keep their manifest entry, every time: the goldens directory is
/// locked from the manifest's read to the commit, and the manifest is read under the lock.
/// (Before: one entry lost about one try in three.)
#[test]
fn two_updates_at_once_keep_both_entries() {
    let dir = fixture("concurrent");
    for round in 0..12 {
        let _ = std::fs::remove_dir_all(dir.join("goldens"));
        let run = |t: &'static str| {
            let dir = dir.clone();
            std::thread::spawn(move || check(&dir, &["--update", "--test", t]))
        };
        let (a, b) = (run("a"), run("b"));
        for (t, h) in [("a", a), ("b", b)] {
            let (code, out, err) = h.join().unwrap();
            assert_eq!(code, Some(0), "round {round} {t}: {out}{err}");
        }
        let m = manifest(&dir);
        for f in ["a.exr", "b.exr"] {
            let e = &m["files"][f];
            assert!(
                e.is_object(),
                "round {round}: {f} lost from the manifest: {m}"
            );
            assert_eq!(
                e["sha256"].as_str().unwrap(),
                sha256_file(&dir.join("goldens").join(f)).unwrap(),
                "round {round}"
            );
        }
        let (code, out, err) = check(&dir, &[]);
        assert_eq!(code, Some(0), "round {round}: {out}{err}");
    }
}

/// Issue 46 (4): `--update` never replaces a manifest entry it did not write (a reference of
/// `rayproof reference` for another suite sharing the directory): one line, exit 2, the
/// reference and its entry byte-identical.
#[test]
fn update_never_replaces_a_reference_entry() {
    let dir = fixture("not-mine");
    std::fs::create_dir_all(dir.join("goldens")).unwrap();
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    // The entry of a.exr as `rayproof reference` writes one (no `check --update` writer)
    let mut m = manifest(&dir);
    m["files"]["a.exr"]["written_by"] = serde_json::json!("rayproof reference");
    let text = serde_json::to_string_pretty(&m).unwrap() + "\n";
    std::fs::write(dir.join("goldens/manifest.json"), &text).unwrap();
    let before = std::fs::read(dir.join("goldens/a.exr")).unwrap();
    std::fs::write(dir.join("a.scene"), "sphere 1 # changed\n").unwrap();
    let (code, out, err) = check(&dir, &["--update", "--test", "a"]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(err.contains("was not written by `check --update`"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert_eq!(std::fs::read(dir.join("goldens/a.exr")).unwrap(), before);
    assert_eq!(
        std::fs::read_to_string(dir.join("goldens/manifest.json")).unwrap(),
        text
    );
    // An entry from before entries named their writer: an outside renderer's is a reference
    m["files"]["a.exr"]
        .as_object_mut()
        .unwrap()
        .remove("written_by");
    m["files"]["a.exr"]["renderer"] = serde_json::json!("POV-Ray");
    let text = serde_json::to_string_pretty(&m).unwrap() + "\n";
    std::fs::write(dir.join("goldens/manifest.json"), &text).unwrap();
    let (code, _, err) = check(&dir, &["--update", "--test", "a"]);
    assert_eq!(code, Some(2), "{err}");
    assert_eq!(
        std::fs::read_to_string(dir.join("goldens/manifest.json")).unwrap(),
        text
    );
}

/// Issue 46 (1): a test's variance image is an input of the suite: a golden at its path (the
/// golden of another test) is refused when the suite is read, one line, exit 2, nothing run.
#[test]
fn a_variance_image_is_an_input_no_golden_may_be_written_over() {
    let dir = fixture("variance-input");
    let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    let text = text.replacen(
        "name = \"a\"\n",
        "name = \"a\"\nvariance = \"goldens/b.exr\"\n",
        1,
    );
    std::fs::write(dir.join("suite.toml"), text).unwrap();
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(
        err.contains("test 'b': its golden") && err.contains("a file the suite reads"),
        "{err}"
    );
    assert!(!dir.join("goldens").exists());
}

/// Issue 46 (9): a suite of 10,000 tests is read and validated in under a second (it was
/// quadratic in file-system calls: 2,000 tests took 72 s), measured with `--test t0`, which
/// renders one, against the same run from a suite of that test alone.
#[test]
fn a_suite_of_10000_tests_validates_in_under_a_second() {
    // The same run (one test rendered: its golden is new, exit 1) from a suite of 10,000 tests
    // and from a suite of that one test: the difference is what validating 9,999 more costs,
    // start-up and the render cancelled (on a loaded 2-core machine the run of one test alone
    // took over a second). Each the fastest of 3 runs.
    let run = |n: usize| -> f64 {
        let dir = scratch(&format!("follow-{n}"));
        std::fs::write(dir.join("a.scene"), "sphere 1\n").unwrap();
        let mut suite = format!(
            "[suite]\nname = \"big\"\nrenderer = \"{} {{out}} --width {{width}} --grid {{grid}}\"\ngoldens = \"goldens\"\ntimeout = 20\n",
            standin()
        );
        for i in 0..n {
            suite +=
                &format!("\n[[test]]\nname = \"t{i}\"\nscene = \"a.scene\"\nwidth = 8\ngrid = 1\n");
        }
        std::fs::write(dir.join("suite.toml"), suite).unwrap();
        (0..3)
            .map(|_| {
                let t0 = std::time::Instant::now();
                let (code, out, err) = check(&dir, &["--test", "t0"]);
                let took = t0.elapsed().as_secs_f64();
                assert_eq!(code, Some(1), "{out}{err}");
                assert_eq!(status(&out, "t0", "golden"), "NEW", "{out}");
                took
            })
            .fold(f64::INFINITY, f64::min)
    };
    let (one, all) = (run(1), run(10_000));
    println!("10,000 tests: {all:.2} s, 1 test: {one:.2} s");
    assert!(
        all - one < 1.0,
        "validating 9,999 more tests took {:.2} s ({all:.2} s against {one:.2} s)",
        all - one
    );
}

/// Issue 46 (the error): a reference named `povray/linux` passed validation, every test ran, and
/// then `--report` failed on a file name built from it (exit 2, no JUnit, no JSON). Names from
/// the suite are checked where they become file names: refused when the suite is read.
#[test]
fn a_reference_name_that_cannot_be_a_file_name_is_refused_up_front() {
    let dir = fixture("ref-name");
    let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    for bad in ["povray/linux", "..", "a b"] {
        let t = text.replacen(
            "name = \"a\"\n",
            &format!("name = \"a\"\nreference = [{{ name = \"{bad}\", path = \"a.exr\" }}]\n"),
            1,
        );
        std::fs::write(dir.join("suite.toml"), t).unwrap();
        let (code, out, err) = check(&dir, &["--report", "rep"]);
        assert_eq!(code, Some(2), "{bad}: {out}{err}");
        assert!(
            err.contains("names the report's files") && err.trim().lines().count() == 1,
            "{bad}: {err}"
        );
        assert!(
            !dir.join("rep").exists() && out.is_empty(),
            "{bad}: work was done: {out}"
        );
    }
}

/// Issue 46 (2): a report directory is replaced only when it holds nothing but the report
/// rayproof wrote, and a report directory that is or holds a golden, a manifest or another
/// output of the run is refused before any work. (Before: `check --report rep` with the goldens
/// kept in `rep/goldens` compared them, exit 0, and deleted them with the old report.)
#[test]
fn a_report_directory_never_takes_goldens_or_a_users_file_with_it() {
    let dir = fixture("report-holds");
    let suite = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    std::fs::write(
        dir.join("suite.toml"),
        suite.replace("goldens = \"goldens\"", "goldens = \"rep/goldens\""),
    )
    .unwrap();
    // The report first, then goldens blessed into it: the next report is refused, goldens kept
    let (code, out, err) = check(&dir, &["--test", "a", "--report", "rep"]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(
        err.contains("give the report a directory of its own"),
        "{err}"
    );
    assert!(err.contains("rep/goldens/a.exr"), "{err}");
    std::fs::create_dir_all(dir.join("rep")).unwrap();
    std::fs::write(dir.join("rep/.rayproof-output"), "made by rayproof\n").unwrap();
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let golden = std::fs::read(dir.join("rep/goldens/a.exr")).unwrap();
    let (code, out, err) = check(&dir, &["--report", "rep"]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("rep/goldens"), "{err}");
    assert_eq!(
        std::fs::read(dir.join("rep/goldens/a.exr")).unwrap(),
        golden
    );
    // With --update too (the goldens would be written inside the report being replaced)
    let (code, out, err) = check(&dir, &["--update", "--report", "rep"]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert_eq!(
        std::fs::read(dir.join("rep/goldens/a.exr")).unwrap(),
        golden
    );
    // A report of its own is replaced, again and again; a user's file put in it is not lost
    std::fs::write(dir.join("suite.toml"), &suite).unwrap();
    let (code, out, err) = check(&dir, &["--update", "--report", "own"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let (code, out, err) = check(&dir, &["--report", "own"]);
    assert_eq!(code, Some(0), "{out}{err}");
    std::fs::create_dir(dir.join("own/notes")).unwrap();
    std::fs::write(dir.join("own/notes/mine.txt"), "mine\n").unwrap();
    let (code, out, err) = check(&dir, &["--report", "own"]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(
        err.contains("own/notes/") && err.contains("did not write there"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(dir.join("own/notes/mine.txt")).unwrap(),
        "mine\n"
    );
    // An output inside the report directory: refused, nothing written
    std::fs::remove_dir_all(dir.join("own/notes")).unwrap();
    let (code, out, err) = check(&dir, &["--report", "own", "--json", "own/rows.json"]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(err.contains("another output of this run"), "{err}");
    assert!(!dir.join("own/rows.json").exists());
}

/// Issue 46 (5): goldens in one directory spelled two ways (`goldens/` and
/// `goldens/../goldens/`) are one directory: one manifest, locked once, both entries kept. Two
/// tests that name one golden two ways are refused when the suite is read. (Before: every test
/// ran, then "named as two outputs", exit 2, nothing written.)
#[test]
fn goldens_spelled_two_ways_are_one_directory() {
    let dir = fixture("two-spellings");
    let suite = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    let two_ways = suite.replace(
        "name = \"b\"\n",
        "name = \"b\"\ngolden = \"goldens/../goldens/b.exr\"\n",
    );
    assert_ne!(two_ways, suite);
    std::fs::write(dir.join("suite.toml"), &two_ways).unwrap();
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let m = manifest(&dir);
    for f in ["a.exr", "b.exr"] {
        assert_eq!(
            m["files"][f]["sha256"].as_str().unwrap(),
            sha256_file(&dir.join("goldens").join(f)).unwrap()
        );
    }
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}{err}");
    // One golden named by two tests
    std::fs::write(
        dir.join("suite.toml"),
        two_ways.replace("goldens/../goldens/b.exr", "goldens/./a.exr"),
    )
    .unwrap();
    let (code, out, err) = check(&dir, &["--update"]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(err.contains("have one golden"), "{err}");
    assert!(out.is_empty(), "no test ran: {out}");
}
