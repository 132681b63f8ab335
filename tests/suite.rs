//! Golden-image CI for any renderer: `rayproof check --suite` with a stand-in for a user's
//! renderer (`tests/outside/standin_render.py`, which writes an EXR by hand). Three tests, one
//! perturbed on purpose: the HTML, JSON and JUnit XML say so, the exit code is 1, and
//! `--update` rewrites only the failing golden. The sampling grid comes from the references'
//! manifest, optional references are skipped, and a renderer that fails, hangs or writes
//! nothing, a corrupt reference or an unknown key is one line, the right exit code, and no
//! golden or manifest written.

use rayproof::golden::sha256_file;
use std::path::{Path, PathBuf};
use std::process::Command;

fn standin() -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/outside/standin_render.py");
    format!("python3 '{}'", p.display())
}

/// Runs the stand-in renderer directly (to make references).
fn render(out: &Path, width: u32, grid: u32) {
    let st = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "{} '{}' --width {width} --grid {grid}",
            standin(),
            out.display()
        ))
        .status()
        .unwrap();
    assert!(st.success());
}

/// A scratch directory with external references for tests a, b, c (made with a 4×4 grid and
/// recorded in a manifest, as `rayproof reference` or the scripts would) and a suite file
/// whose three tests run the stand-in; `extra` is appended to the suite.
fn fixture(tag: &str, b_flags: &str, extra: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rayproof-suite-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("refs")).unwrap();
    let mut files = serde_json::Map::new();
    for t in ["a", "b", "c"] {
        let p = dir.join("refs").join(format!("{t}.exr"));
        render(&p, 48, 4);
        files.insert(
            format!("{t}.exr"),
            serde_json::json!({
                "renderer": "standin", "version": "1", "width": 48, "grid": 4,
                "commands": ["standin_render.py"], "sha256": sha256_file(&p).unwrap(),
            }),
        );
    }
    std::fs::write(
        dir.join("refs/manifest.json"),
        serde_json::to_string_pretty(&serde_json::json!({ "files": files })).unwrap(),
    )
    .unwrap();
    let suite = format!(
        r#"[suite]
name = "standin"
renderer = "{r} {{out}} --width {{width}} --grid {{grid}}"
goldens = "goldens"
timeout = 5

[thresholds]
fail = 0.01
failpercent = 0.1

[[test]]
name = "a"
reference = [{{ name = "ext", path = "refs/a.exr" }}]

[[test]]
name = "b"
command = "{r} {{out}} --width {{width}} --grid {{grid}} {b_flags}"
reference = [{{ name = "ext", path = "refs/b.exr" }}]

[[test]]
name = "c"
reference = [{{ name = "ext", path = "refs/c.exr" }}, {{ name = "other", path = "refs/missing.exr", required = false }}]
{extra}"#,
        r = standin()
    );
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    dir
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

/// The status word of test × reference in the text table.
fn status(out: &str, test: &str, reference: &str) -> String {
    out.lines()
        .find(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            w.len() > 3 && w[0] == test && w[1] == reference
        })
        .and_then(|l| l.split_whitespace().nth(3))
        .unwrap_or_else(|| panic!("no {test} × {reference} row in:\n{out}"))
        .to_string()
}

fn goldens(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir.join("goldens"))
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| {
                    (
                        e.file_name().to_string_lossy().into_owned(),
                        std::fs::read(e.path()).unwrap(),
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn three_tests_one_perturbed_reports_and_blesses_only_the_failing_golden() {
    // First run: no goldens yet (NEW, exit 1); --update blesses all three
    let dir = fixture("three", "", "");
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(1), "{out}{err}");
    for t in ["a", "b", "c"] {
        assert_eq!(status(&out, t, "ext"), "PASS", "{out}");
        assert_eq!(status(&out, t, "golden"), "NEW", "{out}");
    }
    assert_eq!(status(&out, "c", "other"), "SKIPPED", "{out}");
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}");
    let blessed = goldens(&dir);
    assert_eq!(
        blessed.iter().map(|g| g.0.as_str()).collect::<Vec<_>>(),
        ["a.exr", "b.exr", "c.exr", "manifest.json"]
    );
    let m: serde_json::Value =
        serde_json::from_slice(&blessed.iter().find(|g| g.0 == "manifest.json").unwrap().1)
            .unwrap();
    let e = &m["files"]["b.exr"];
    assert_eq!(
        e["sha256"].as_str().unwrap(),
        sha256_file(&dir.join("goldens/b.exr")).unwrap()
    );
    // The command as the suite writes it (no scratch path), the grid it was given beside it
    assert!(
        e["commands"][0]
            .as_str()
            .unwrap()
            .ends_with("{out} --width {width} --grid {grid} "),
        "{e}"
    );
    assert!(e["date"].as_str().unwrap().ends_with('Z'));
    assert_eq!(e["grid"], 4);

    // Now b's renderer is perturbed: b fails against its reference and its golden
    let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    let perturbed = text.replacen("--grid {grid} \"", "--grid {grid} --perturb 0.2\"", 1);
    assert_ne!(text, perturbed);
    std::fs::write(dir.join("suite.toml"), perturbed).unwrap();
    let (html, json, junit) = (
        dir.join("html"),
        dir.join("rows.json"),
        dir.join("junit.xml"),
    );
    let args = [
        "--report",
        html.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--junit",
        junit.to_str().unwrap(),
    ];
    let (code, out, _) = check(&dir, &args);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "b", "ext"), "FAILURE", "{out}");
    assert_eq!(status(&out, "b", "golden"), "FAILURE", "{out}");
    for t in ["a", "c"] {
        assert_eq!(status(&out, t, "ext"), "PASS", "{out}");
        assert_eq!(status(&out, t, "golden"), "PASS", "{out}");
    }
    // Failures first in the terminal, the HTML and the JSON
    let first = out.lines().nth(1).unwrap();
    assert!(first.starts_with("b "), "{out}");
    let page = std::fs::read_to_string(html.join("index.html")).unwrap();
    assert_eq!(page.matches("<tr class=").count(), 7, "{page}");
    assert!(page.find("class=\"fail\"").unwrap() < page.find("class=\"pass\"").unwrap());
    assert!(page.contains("onmouseover"));
    assert!(html.join("b-ext-command-flip.png").is_file());
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rows.as_array().unwrap().len(), 7);
    assert_eq!(rows[0]["test"], "b");
    assert_eq!(rows[0]["status"], "failure");
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert!(xml.contains(r#"tests="7""#), "{xml}");
    assert!(xml.contains(r#"failures="2""#), "{xml}");
    assert!(xml.contains(r#"skipped="1""#), "{xml}");
    assert!(
        xml.contains(r#"<testcase name="b vs golden [command]" classname="b""#),
        "{xml}"
    );

    // --update rewrites b's golden only; the external reference stays, so b still fails
    // (a passing golden is not touched: same bytes and the same modification time)
    let ext = std::fs::read(dir.join("refs/b.exr")).unwrap();
    let mtime = |name: &str| {
        std::fs::metadata(dir.join("goldens").join(name))
            .unwrap()
            .modified()
            .unwrap()
    };
    let kept = [("a.exr", mtime("a.exr")), ("c.exr", mtime("c.exr"))];
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "b", "golden"), "UPDATED", "{out}");
    for (name, test) in [("a.exr", "a"), ("c.exr", "c")] {
        assert_eq!(status(&out, test, "golden"), "PASS", "{out}");
        let before = kept.iter().find(|k| k.0 == name).unwrap().1;
        assert_eq!(
            mtime(name),
            before,
            "{name}: a passing golden was rewritten"
        );
    }
    assert_eq!(status(&out, "b", "ext"), "FAILURE", "{out}");
    let after = goldens(&dir);
    for (name, bytes) in &blessed {
        let now = &after.iter().find(|g| &g.0 == name).unwrap().1;
        match name.as_str() {
            "a.exr" | "c.exr" => assert_eq!(now, bytes, "{name} was rewritten"),
            _ => assert_ne!(now, bytes, "{name} was not rewritten"),
        }
    }
    assert_eq!(std::fs::read(dir.join("refs/b.exr")).unwrap(), ext);
    let (_, out, _) = check(&dir, &[]);
    assert_eq!(status(&out, "b", "golden"), "PASS", "{out}");
}

#[test]
fn the_references_grid_is_used_and_a_declared_mismatch_warns_and_fails() {
    // The references were made with 4×4 sub-samples: the renderer gets {grid} = 4 and passes
    let dir = fixture("grid", "", "");
    let (_, out, _) = check(&dir, &[]);
    assert_eq!(status(&out, "a", "ext"), "PASS", "{out}");
    // A test that insists on 1×1 is told why it fails
    let extra = "grid = 1\n";
    let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    std::fs::write(
        dir.join("suite.toml"),
        text.replacen("name = \"a\"\n", &format!("name = \"a\"\n{extra}"), 1),
    )
    .unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "a", "ext"), "FAILURE", "{out}");
    assert!(
        out.contains("warning: sampling grid: the reference was made with 4×4 per pixel, the test image with 1×1"),
        "{out}"
    );
}

#[test]
fn a_refused_test_is_one_line_exit_3_and_update_writes_nothing() {
    for (tag, flags, want) in [
        ("fails", "--fail", "standin: out of memory (pretend)"),
        ("hangs", "--hang", "did not finish within 5 s (killed)"),
        ("nothing", "--no-output", "wrote no image"),
    ] {
        let dir = fixture(tag, flags, "");
        let t0 = std::time::Instant::now();
        let (code, out, err) = check(&dir, &["--update"]);
        assert!(t0.elapsed().as_secs() < 60);
        assert_eq!(code, Some(3), "{tag}: {out}{err}");
        assert_eq!(status(&out, "b", "ext"), "REFUSED", "{out}");
        let line = out
            .lines()
            .find(|l| l.starts_with("b ") && l.contains("ext"))
            .unwrap();
        assert!(line.contains(want), "{tag}: {line}");
        assert_eq!(status(&out, "a", "ext"), "PASS", "{out}");
        assert!(out.contains("--update wrote nothing"), "{out}");
        assert!(goldens(&dir).is_empty(), "{tag}: a golden was written");
    }
    // A corrupt reference: refused, the rest still judged
    let dir = fixture("corrupt", "", "");
    let p = dir.join("refs/c.exr");
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(3), "{out}");
    assert_eq!(status(&out, "c", "ext"), "REFUSED", "{out}");
    assert!(out.contains("SHA-256"), "{out}");
    assert!(goldens(&dir).is_empty());
    // Without a manifest the truncation itself is what refuses it
    std::fs::remove_file(dir.join("refs/manifest.json")).unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(3), "{out}");
    assert_eq!(status(&out, "c", "ext"), "REFUSED", "{out}");
}

#[test]
fn a_suite_file_that_does_not_validate_is_one_line_exit_2() {
    for (tag, extra, want) in [
        ("key", "colour = 1\n", "unknown field `colour`"),
        ("threshold", "thresholds = { fial = 1 }\n", "fial"),
        (
            "placeholder",
            "command = \"r {outt}\"\n",
            "unknown placeholder {outt}",
        ),
    ] {
        let dir = fixture(tag, "", &format!("\n[[test]]\nname = \"d\"\n{extra}reference = [{{ name = \"ext\", path = \"refs/a.exr\" }}]\n"));
        let (code, out, err) = check(&dir, &["--update"]);
        assert_eq!(code, Some(2), "{tag}: {out}{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(want), "{tag}: {err}");
        assert!(out.is_empty() && goldens(&dir).is_empty());
    }
}

#[test]
fn warnings_name_nan_pixels_and_linear_against_srgb() {
    let dir = fixture("warn", "--nan", "");
    let (_, out, _) = check(&dir, &[]);
    assert!(
        out.contains("warning: the test image has 1 pixels with NaN or Inf"),
        "{out}"
    );
    // A PNG reference (no manifest: the test gives its frame) against the EXR render
    std::fs::create_dir_all(dir.join("png")).unwrap();
    let png = dir.join("png/a.png");
    rayproof::images::write_png_rgb8(&png, 48, 32, &vec![128u8; 48 * 32 * 3]).unwrap();
    let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    std::fs::write(
        dir.join("suite.toml"),
        text.replace("refs/a.exr\" }]", "png/a.png\" }]").replacen(
            "name = \"a\"\n",
            "name = \"a\"\nwidth = 48\ngrid = 4\n",
            1,
        ),
    )
    .unwrap();
    let (_, out, _) = check(&dir, &[]);
    assert!(
        out.contains("the reference is sRGB-encoded (PNG) and the test image scene-linear"),
        "{out}"
    );
}

#[test]
fn the_readme_suite_example_works_as_printed() {
    // The README's mysuite.toml, run where it says (the repository's root: here a directory
    // that links tests/ to it), with its three commands
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let block = readme
        .split("```toml\n# mysuite.toml\n")
        .nth(1)
        .and_then(|s| s.split("```").next())
        .expect("README has the mysuite.toml example");
    let dir = std::env::temp_dir().join(format!("rayproof-readme-suite-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::os::unix::fs::symlink(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests"),
        dir.join("tests"),
    )
    .unwrap();
    std::fs::write(dir.join("suite.toml"), block).unwrap();
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert_eq!(status(&out, "disc", "golden"), "NEW", "{out}");
    assert_eq!(status(&out, "disc", "pbrt"), "SKIPPED", "{out}");
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(dir.join("goldens/disc.exr").is_file() && dir.join("goldens/manifest.json").is_file());
    // As printed: out/ does not exist yet, and every output goes into it
    let (code, out, _) = check(
        &dir,
        &[
            "--report",
            "out/html",
            "--json",
            "out/check.json",
            "--junit",
            "out/junit.xml",
        ],
    );
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(status(&out, "disc", "golden"), "PASS", "{out}");
}

#[test]
fn a_variance_image_makes_the_z_test_decide() {
    // The stand-in writes a per-pixel variance of 1e-4 ({variance}). An unperturbed render
    // passes the z-test; a +0.2 block fails it (z = 80 at 16 spp); a +0.02 block at 1 spp is
    // within its noise (z = 2) and passes, although idiff's thresholds alone would fail it
    for (tag, flags, spp, want) in [
        ("zpass", "", 16, "PASS"),
        ("zfail", "--perturb 0.2", 16, "FAILURE"),
        ("znoise", "--perturb 0.02", 1, "PASS"),
    ] {
        let extra = format!(
            "\n[[test]]\nname = \"z\"\ncommand = \"{} {{out}} --width {{width}} --grid {{grid}} --variance {{variance}} {flags}\"\nvariance = \"{{variance}}\"\nvariance_spp = {spp}\ngolden = false\nreference = [{{ name = \"ext\", path = \"refs/a.exr\" }}]\n",
            standin()
        );
        let dir = fixture(tag, "", &extra);
        let (_, out, err) = check(&dir, &["--test", "z"]);
        assert_eq!(status(&out, "z", "ext"), want, "{out}{err}");
        if want == "FAILURE" {
            assert!(out.contains("z-test:"), "{out}");
        }
        if tag == "znoise" {
            // Without the variance, the same image fails idiff's thresholds
            let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
            std::fs::write(
                dir.join("suite.toml"),
                text.replace("variance = \"{variance}\"\n", ""),
            )
            .unwrap();
            let (_, out, _) = check(&dir, &["--test", "z"]);
            assert_eq!(status(&out, "z", "ext"), "FAILURE", "{out}");
        }
    }
}

#[test]
fn update_never_blesses_an_image_with_nan() {
    let dir = fixture("nanbless", "--nan", "");
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "b", "golden"), "FAILURE", "{out}");
    assert!(
        out.contains("not blessed: the test image has 1 pixels with NaN or Inf"),
        "{out}"
    );
    let written: Vec<String> = goldens(&dir).into_iter().map(|g| g.0).collect();
    assert_eq!(written, ["a.exr", "c.exr", "manifest.json"]);
}

#[test]
fn a_renderer_that_prints_bytes_that_are_not_text_is_judged_as_any_other() {
    // A progress bar in some legacy encoding on stdout and stderr: not a refusal
    let dir = fixture("bytes", "", "");
    let text = std::fs::read_to_string(dir.join("suite.toml")).unwrap();
    std::fs::write(
        dir.join("suite.toml"),
        text.replacen(
            "renderer = \"",
            "renderer = \"printf '\\\\377\\\\376 50%'; printf '\\\\377' >&2; ",
            1,
        ),
    )
    .unwrap();
    let (code, out, err) = check(&dir, &["--test", "a"]);
    assert_eq!(status(&out, "a", "ext"), "PASS", "{out}{err}");
    assert_eq!(code, Some(1), "{out}"); // its golden is still NEW
}

/// The suite of `fixture` with its `[thresholds]` replaced and `extra_b` added to test b.
fn with_thresholds(dir: &Path, thresholds: &str, extra_b: &str) {
    let p = dir.join("suite.toml");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace(
            "[thresholds]\nfail = 0.01\nfailpercent = 0.1\n",
            &format!("[thresholds]\n{thresholds}\n"),
        )
        .replace("name = \"b\"\n", &format!("name = \"b\"\n{extra_b}"));
    std::fs::write(p, text).unwrap();
}

#[test]
fn a_nan_pixel_fails_every_comparison_whatever_the_thresholds() {
    // The issue's reproducer: the README's thresholds let a render with NaN pixels through as
    // WARNING, mean 0, exit 0, no <failure> in the JUnit file
    for (tag, thresholds) in [
        ("readme", "fail = 0.01\nfailpercent = 0.1\nmax_mean = 1e-3"),
        (
            "lax",
            "fail = 1e30\nfailpercent = 100\nallowfailures = 1000000\nhardfail = inf\nwarn = 1e30\nhardwarn = inf\nmax_mean = inf",
        ),
    ] {
        let dir = fixture(&format!("nan-{tag}"), "--nan", "");
        with_thresholds(&dir, thresholds, "");
        let junit = dir.join("junit.xml");
        let (code, out, err) = check(&dir, &["--test", "b", "--junit", junit.to_str().unwrap()]);
        assert_eq!(code, Some(1), "{tag}: {out}{err}");
        assert_eq!(status(&out, "b", "ext"), "FAILURE", "{tag}: {out}");
        let row = out.lines().find(|l| l.starts_with("b ")).unwrap();
        assert!(row.contains("1 NaN and 0 Inf pixel(s)"), "{tag}: {row}");
        let xml = std::fs::read_to_string(&junit).unwrap();
        let failure = xml
            .lines()
            .find(|l| l.contains("<failure"))
            .unwrap_or_else(|| panic!("{tag}: no <failure> in {xml}"));
        assert!(failure.contains("NaN"), "{tag}: {failure}");
    }
    // Not even as an expected failure (a known failure is about differences, not NaN)
    let dir = fixture("nan-xfail", "--nan", "");
    with_thresholds(
        &dir,
        "fail = 0.01\nfailpercent = 0.1",
        "thresholds = { known_failure = \"a known difference\" }\n",
    );
    let (code, out, _) = check(&dir, &["--test", "b"]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "b", "ext"), "FAILURE", "{out}");
    // A test that allows them explicitly is judged by its thresholds alone
    let dir = fixture("nan-allowed", "--nan", "");
    with_thresholds(
        &dir,
        "fail = 0.01\nfailpercent = 0.1\nmax_mean = 1e-3",
        "allow_nonfinite = true\n",
    );
    let (_, out, _) = check(&dir, &["--test", "b"]);
    assert_eq!(status(&out, "b", "ext"), "WARNING", "{out}");
    assert!(!out.contains("NaN and"), "{out}");
}

#[test]
fn a_renderer_that_closes_its_pipes_is_killed_at_its_timeout() {
    // The issue's reproducer: `exec ./hang.sh {out} > render.log 2>&1` with timeout = 3 ran
    // until the script ended by itself; a real hang never ends
    let dir = fixture("closes-pipes", "", "");
    std::fs::write(
        dir.join("hang.sh"),
        "echo $$ > hang.pid\nsleep 20 &\necho $! > sleep.pid\nwait\n",
    )
    .unwrap();
    let p = dir.join("suite.toml");
    let text = std::fs::read_to_string(&p)
        .unwrap()
        .replace("timeout = 5", "timeout = 3")
        .replace(
            "[[test]]\nname = \"a\"\n",
            "[[test]]\nname = \"a\"\ncommand = \"exec sh hang.sh {out} > render.log 2>&1\"\n",
        );
    std::fs::write(&p, text).unwrap();
    let t0 = std::time::Instant::now();
    let (code, out, err) = check(&dir, &["--test", "a"]);
    let wall = t0.elapsed().as_secs_f64();
    assert_eq!(code, Some(3), "{out}{err}");
    assert!(out.contains("did not finish within 3 s"), "{out}");
    assert!(wall < 5.0, "took {wall:.1} s for a 3 s timeout");
    // Nothing of it outlives the run
    std::thread::sleep(std::time::Duration::from_millis(200));
    for f in ["hang.pid", "sleep.pid"] {
        let pid = std::fs::read_to_string(dir.join(f)).unwrap();
        let stat = std::fs::read_to_string(format!("/proc/{}/stat", pid.trim()));
        let alive = stat.is_ok_and(|s| {
            let state = s.rsplit(')').next().unwrap_or("").trim_start();
            !state.starts_with('Z') && !state.starts_with('X')
        });
        assert!(!alive, "{f} {}: still running after the run", pid.trim());
    }
}

#[test]
fn a_test_that_compares_nothing_is_refused_not_passed() {
    // Every reference optional and missing, no golden: nothing was compared, so no pass
    let dir = fixture("compares-nothing", "", "");
    let p = dir.join("suite.toml");
    let text = std::fs::read_to_string(&p).unwrap().replace(
        "[[test]]\nname = \"a\"\nreference = [{ name = \"ext\", path = \"refs/a.exr\" }]",
        "[[test]]\nname = \"a\"\ngolden = false\nreference = [{ name = \"ext\", path = \"refs/gone.exr\", required = false }]",
    );
    std::fs::write(&p, text).unwrap();
    let (code, out, _) = check(&dir, &["--test", "a"]);
    assert_eq!(code, Some(3), "{out}");
    assert!(out.contains("nothing to compare with"), "{out}");
}
