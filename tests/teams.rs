//! Golden-image CI as teams run it (issue 48): goldens and thresholds per platform, masks,
//! thresholds learned from a Monte Carlo renderer's noise (`check --calibrate`), GitHub
//! annotations and a Markdown summary, and outputs into directories that do not exist yet.
//! The renderer is the stand-in (`tests/outside/standin_render.py`): `--seed`/`--noise` make it
//! a Monte Carlo renderer, `--stamp` writes a timestamp, `STANDIN_SHIFT` moves its mean without
//! changing the command a golden records.

use crate::common::{s, scratch};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `rayproof ARGS` in `dir` with `env` set (and GitHub's variables cleared unless given).
fn run(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rayproof"));
    c.args(args).current_dir(dir);
    for k in [
        "GITHUB_ACTIONS",
        "GITHUB_STEP_SUMMARY",
        "RAYPROOF_PLATFORM",
        "STANDIN_SHIFT",
    ] {
        c.env_remove(k);
    }
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().unwrap()
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
}

/// The rows of a `--json` file.
fn rows(p: &Path) -> Vec<serde_json::Value> {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn row<'a>(rows: &'a [serde_json::Value], test: &str) -> &'a serde_json::Value {
    rows.iter()
        .find(|r| r["test"] == test)
        .unwrap_or_else(|| panic!("no row for {test}"))
}

/// The README's `teams.toml`, as printed, in a scratch directory that links `tests/` (its
/// commands run from the repository's root): two platforms (macos-arm64 looser on the goldens),
/// a plain test, a test (looser: 1e-3) with a timestamp masked out and a rectangle at 4×
/// tolerance, a Monte Carlo test (96×64 pixels, noise σ = 0.02) skipped on macos-arm64.
fn teams_suite(tag: &str) -> PathBuf {
    let d = scratch(tag);
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let block = readme
        .split("```toml\n# teams.toml\n")
        .nth(1)
        .and_then(|s| s.split("```").next())
        .expect("README has the teams.toml example");
    std::os::unix::fs::symlink(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests"),
        d.join("tests"),
    )
    .unwrap();
    std::fs::write(d.join("suite.toml"), block).unwrap();
    d
}

#[test]
fn a_platform_is_chosen_never_guessed_and_its_goldens_and_thresholds_are_its_own() {
    let d = teams_suite("platforms");
    // No platform: exit 2, the choices named; an unknown one too; nothing written
    let o = run(&d, &["check", "--suite", "suite.toml"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("give --platform NAME or set RAYPROOF_PLATFORM"));
    assert!(text(&o).contains("linux-x86_64, macos-arm64"));
    let o = run(
        &d,
        &["check", "--suite", "suite.toml", "--platform", "windows"],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(!d.join("goldens").exists());
    // Bless linux's goldens (RAYPROOF_PLATFORM chooses it as --platform does)
    let linux = [("RAYPROOF_PLATFORM", "linux-x86_64")];
    let o = run(
        &d,
        &[
            "check",
            "--suite",
            "suite.toml",
            "--test",
            "disc,clock",
            "--update",
        ],
        &linux,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(d.join("goldens/linux-x86_64/disc.exr").is_file());
    // macos-arm64 has no golden: NEW (exit 1), never linux's in its place; mc is skipped there
    let o = run(
        &d,
        &[
            "check",
            "--suite",
            "suite.toml",
            "--platform",
            "macos-arm64",
            "--json",
            "m.json",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let m = rows(&d.join("m.json"));
    assert_eq!(row(&m, "disc")["status"], "new");
    assert_eq!(row(&m, "disc")["platform"], "macos-arm64");
    assert!(row(&m, "disc")["note"]
        .as_str()
        .unwrap()
        .contains("goldens/macos-arm64/disc.exr"));
    assert_eq!(row(&m, "mc")["status"], "skipped");
    assert!(row(&m, "mc")["note"]
        .as_str()
        .unwrap()
        .contains("skipped on platform macos-arm64: no Metal device"));
    assert!(row(&m, "mc")["replay"]
        .as_str()
        .unwrap()
        .ends_with("--platform macos-arm64"));
    let o = run(
        &d,
        &[
            "check",
            "--suite",
            "suite.toml",
            "--platform",
            "macos-arm64",
            "--test",
            "disc",
            "--update",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    // A change of 1e-4 of the image: over linux's 1e-6, under macos-arm64's 1e-3
    let shift = [("STANDIN_SHIFT", "1e-4")];
    for (platform, want, fail) in [("linux-x86_64", 1, 1e-6), ("macos-arm64", 0, 1e-3)] {
        let o = run(
            &d,
            &[
                "check",
                "--suite",
                "suite.toml",
                "--test",
                "disc",
                "--platform",
                platform,
                "--json",
                "p.json",
            ],
            &shift,
        );
        assert_eq!(o.status.code(), Some(want), "{platform}: {}", text(&o));
        let p = rows(&d.join("p.json"));
        assert_eq!(row(&p, "disc")["rule"]["idiff"]["fail"], fail, "{platform}");
    }
    // A [platform.NAME] the suite does not declare is a suite error
    let bad = std::fs::read_to_string(d.join("suite.toml")).unwrap() + "\n[platform.beos]\n";
    std::fs::write(d.join("bad.toml"), bad).unwrap();
    let o = run(
        &d,
        &["check", "--suite", "bad.toml", "--platform", "linux-x86_64"],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("'beos' is not one of the suite's platforms"));
}

#[test]
fn a_mask_leaves_pixels_out_of_every_metric_and_is_counted_and_drawn() {
    let d = teams_suite("mask");
    let p = ["--platform", "linux-x86_64", "--test", "clock"];
    let args = |extra: &[&'static str]| -> Vec<&str> {
        let mut a = vec!["check", "--suite", "suite.toml"];
        a.extend(p);
        a.extend(extra);
        a
    };
    assert_eq!(run(&d, &args(&["--update"]), &[]).status.code(), Some(0));
    // The timestamp changed (another render): the masked test still passes, its counts said
    let o = run(&d, &args(&["--json", "c.json", "--report", "html"]), &[]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let c = rows(&d.join("c.json"));
    let clock = row(&c, "clock");
    assert_eq!(clock["mask"]["excluded"], 32);
    assert_eq!(clock["mask"]["scaled"], 32);
    // Percentages are of the pixels compared: 48×32 − 32
    assert_eq!(clock["comparison"]["pixels"], 48 * 32 - 32);
    let html = std::fs::read_to_string(d.join("html/index.html")).unwrap();
    assert!(
        html.contains("mask: 32 px left out, 32 px at scaled tolerance"),
        "{html}"
    );
    assert!(d.join("html/clock-golden-command-masked.png").is_file());
    // The difference map and the failing pixels follow the mask: the timestamp it leaves out
    // does not set the map's scale (nothing else changed: no difference to draw)
    assert!(html.contains("identical: no difference"), "{html}");
    assert!(html.contains("0 px over fail 0.001"), "{html}");
    // Without the mask the same render fails: the mask is what lets the timestamp through
    let suite = std::fs::read_to_string(d.join("suite.toml")).unwrap();
    let unmasked = suite.replacen("rect = [0, 0, 8, 4]", "rect = [0, 4, 8, 4]", 1);
    assert_ne!(unmasked, suite);
    std::fs::write(d.join("suite.toml"), unmasked).unwrap();
    let o = run(&d, &args(&["--json", "u.json"]), &[]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    std::fs::write(d.join("suite.toml"), &suite).unwrap();
    // A change in the 4× rectangle: 1e-6·3 fails at 1e-6 alone, passes at 4e-6
    // (checked through the library: the metric under the weights)
    use rayproof::images::{compare, compare_masked, Image, Mask, MaskPart, Thresholds};
    let a = Image::new(4, 1, &["Y"], vec![0.5; 4]);
    let mut b = a.clone();
    b.data[3] += 3e-6;
    b.data[0] = f32::NAN; // left out: not even a NaN counts there
    let t = Thresholds {
        fail: 1e-6,
        ..Default::default()
    };
    let rect = |x, weight| MaskPart::Rect {
        x,
        y: 0,
        width: 1,
        height: 1,
        weight,
    };
    let mask = Mask::build(a.display, &[rect(0, 0.0), rect(3, 0.25)]).unwrap();
    let masked = compare_masked(&a, &b, &t, &mask).unwrap();
    assert_eq!((masked.n_fail, masked.pixels), (0, 3));
    assert_eq!(masked.n_nonfinite_mismatch, 0);
    assert!(masked.max_error < 1e-6, "{}", masked.max_error);
    assert_eq!(compare(&a, &b, &t).unwrap().n_fail, 2);
    // A rectangle outside the frame is refused, not clipped
    assert!(Mask::build(a.display, &[rect(4, 0.0)]).is_err());
}

#[test]
fn calibration_learns_the_noise_passes_fresh_seeds_and_catches_a_one_percent_shift() {
    let d = teams_suite("calibrate");
    let base = [
        "check",
        "--suite",
        "suite.toml",
        "--platform",
        "linux-x86_64",
        "--test",
        "mc",
    ];
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut a: Vec<&str> = base.to_vec();
        a.extend(extra);
        a
    };
    // Only a command with {seed} and an EXR golden is calibrated; N ≥ 2
    let o = run(&d, &with(&["--calibrate", "1"]), &[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let o = run(
        &d,
        &[
            "check",
            "--suite",
            "suite.toml",
            "--platform",
            "linux-x86_64",
            "--test",
            "disc",
            "--calibrate",
            "4",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("has no {seed}"), "{}", text(&o));
    // A renderer that fails on one seed: exit 3, nothing written
    let o = run(&d, &with(&["--calibrate", "8"]), &[("STANDIN_SHIFT", "x")]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(!d.join("goldens/linux-x86_64/mc.exr").exists());
    // 8 renders: the mean as golden, the variance beside it, thresholds proposed
    let o = run(&d, &with(&["--calibrate", "8"]), &[]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = text(&o);
    assert!(out.contains("calibrated mc: 8 renders"), "{out}");
    assert!(out.contains("golden_thresholds = { fail = "), "{out}");
    let g = d.join("goldens/linux-x86_64");
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(g.join("manifest.json")).unwrap()).unwrap();
    let cal = &manifest["files"]["mc.exr"]["calibration"];
    assert_eq!(cal["renders"], 8);
    assert_eq!(cal["variance"], "mc.variance.exr");
    assert!(manifest["files"]["mc.variance.exr"]["sha256"].is_string());
    // The variance is about (1 + 1/8)·0.02² (the stand-in's σ), pixel by pixel
    let var = rayproof::images::read_image(&g.join("mc.variance.exr")).unwrap();
    let mean = var.data.iter().map(|&v| v as f64).sum::<f64>() / var.data.len() as f64;
    let want = 1.125 * 0.02f64.powi(2);
    assert!(
        (mean / want - 1.0).abs() < 0.1,
        "mean variance {mean}, want {want}"
    );
    // Eight fresh seeds pass: Student's t per pixel, and no shift of the mean
    for seed in 100..108 {
        let seed = seed.to_string();
        let mut a = with(&["--json", "s.json"]);
        a.extend(["--seed", &seed]);
        let o = run(&d, &a, &[]);
        assert_eq!(o.status.code(), Some(0), "seed {seed}: {}", text(&o));
        let r = rows(&d.join("s.json"));
        let z = &row(&r, "mc")["ztest"];
        assert_eq!(z["params"]["dof"], 7);
        assert!(row(&r, "mc")["note"]
            .as_str()
            .unwrap()
            .contains("z-test (calibrated, 8 renders)"));
    }
    // The report draws the z-test's failing pixels (none), not those over idiff's `fail`
    let o = run(&d, &with(&["--report", "rep", "--seed", "99"]), &[]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let html = std::fs::read_to_string(d.join("rep/index.html")).unwrap();
    assert!(html.contains("0 px fail the z-test (it decides)"), "{html}");
    // A 1 % shift of the mean, up or down, fails on the mean-shift test, whatever the seed
    for shift in ["0.01", "-0.01"] {
        for seed in ["200", "201"] {
            let mut a = with(&["--json", "f.json"]);
            a.extend(["--seed", seed]);
            let o = run(&d, &a, &[("STANDIN_SHIFT", shift)]);
            assert_eq!(o.status.code(), Some(1), "shift {shift}: {}", text(&o));
            let r = rows(&d.join("f.json"));
            let note = row(&r, "mc")["note"].as_str().unwrap().to_string();
            assert!(note.contains("mean shifted beyond its noise"), "{note}");
            // Per pixel, the shift hides in the noise
            assert_eq!(row(&r, "mc")["ztest"]["failing_pixels"], 0, "{note}");
        }
    }
    // --update never replaces the mean of 8 renders by one render
    let before = std::fs::read(g.join("mc.exr")).unwrap();
    let o = run(&d, &with(&["--update"]), &[("STANDIN_SHIFT", "0.01")]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("re-make it with --calibrate N"),
        "{}",
        text(&o)
    );
    assert_eq!(std::fs::read(g.join("mc.exr")).unwrap(), before);
    // A variance changed outside rayproof: the golden comparison is refused, not judged
    let mut v = std::fs::read(g.join("mc.variance.exr")).unwrap();
    let n = v.len();
    v[n - 1] ^= 1;
    std::fs::write(g.join("mc.variance.exr"), v).unwrap();
    let o = run(&d, &with(&[]), &[]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(
        text(&o).contains("the calibrated golden's variance"),
        "{}",
        text(&o)
    );
}

#[test]
fn ci_gets_annotations_on_the_test_lines_and_a_summary_failing_first() {
    let d = teams_suite("ci");
    let linux = ["--platform", "linux-x86_64", "--test", "disc,clock"];
    let mut a = vec!["check", "--suite", "suite.toml", "--update"];
    a.extend(linux);
    assert_eq!(run(&d, &a, &[]).status.code(), Some(0));
    // disc fails (a shift of 1e-4), clock passes; annotations under GITHUB_ACTIONS, the
    // summary appended to the step's file (what was there kept)
    std::fs::write(d.join("step.md"), "earlier step\n").unwrap();
    let mut a = vec![
        "check",
        "--suite",
        "suite.toml",
        "--report",
        "out/html",
        "--junit",
        "out/junit.xml",
        "--report-url",
        "https://ci.example/1/index.html",
    ];
    a.extend(linux);
    let step = d.join("step.md");
    let o = run(
        &d,
        &a,
        &[
            ("GITHUB_ACTIONS", "true"),
            ("GITHUB_STEP_SUMMARY", s(&step)),
            ("STANDIN_SHIFT", "1e-4"),
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let errors: Vec<&str> = out.lines().filter(|l| l.starts_with("::error ")).collect();
    assert_eq!(errors.len(), 1, "{out}");
    // On disc's name line of the suite file, the platform in the title, escaped text
    let line = std::fs::read_to_string(d.join("suite.toml"))
        .unwrap()
        .lines()
        .position(|l| l.starts_with("name = \"disc\""))
        .unwrap()
        + 1;
    assert!(
        errors[0].starts_with(&format!(
            "::error file=suite.toml,line={line},title=FAILURE disc vs golden [command] on linux-x86_64::"
        )),
        "{}",
        errors[0]
    );
    assert!(errors[0].contains("%25) over fail"), "{}", errors[0]);
    assert!(
        errors[0].contains("%0Areplay: rayproof check"),
        "{}",
        errors[0]
    );
    let summary = std::fs::read_to_string(&step).unwrap();
    assert!(
        summary.starts_with("earlier step\n## ❌ `teams` on `linux-x86_64`"),
        "{summary}"
    );
    let disc = summary.find("| ❌ | [disc](https://ci.example/1/index.html#disc--golden--command)");
    let clock = summary.find("| ✅ | [clock]");
    assert!(
        disc.is_some() && clock.is_some() && disc < clock,
        "{summary}"
    );
    assert!(summary.contains("32 out, 32 scaled"), "{summary}");
    // The anchor is the HTML row's id; the JUnit file (made in a directory that did not
    // exist) stays valid
    let html = std::fs::read_to_string(d.join("out/html/index.html")).unwrap();
    assert!(html.contains("id=\"disc--golden--command\""));
    assert!(html.contains("Platform: <b>linux-x86_64</b>"));
    let o = Command::new("xmllint")
        .args(["--noout", "--schema"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/junit-10.xsd"))
        .arg(d.join("out/junit.xml"))
        .output()
        .expect("xmllint (Debian: libxml2-utils)");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // --summary FILE: written with the run's outputs, into a new directory; no annotations
    // without GITHUB_ACTIONS or --annotations
    let mut a = vec![
        "check",
        "--suite",
        "suite.toml",
        "--summary",
        "new/dir/summary.md",
    ];
    a.extend(linux);
    let o = run(&d, &a, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(!text(&o).contains("::error"));
    let summary = std::fs::read_to_string(d.join("new/dir/summary.md")).unwrap();
    assert!(
        summary.starts_with("## ✅ `teams` on `linux-x86_64`"),
        "{summary}"
    );
}

#[test]
fn outputs_go_into_new_directories_and_a_failed_run_leaves_none() {
    let d = teams_suite("dirs");
    let o = run(
        &d,
        &[
            "check",
            "--suite",
            "suite.toml",
            "--platform",
            "linux-x86_64",
            "--test",
            "disc",
            "--update",
            "--json",
            "out/a/check.json",
            "--report",
            "out/b/html",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(d.join("out/a/check.json").is_file());
    assert!(d.join("out/b/html/index.html").is_file());
    // A run that cannot commit (its report would replace a user's directory) makes no directory
    std::fs::create_dir_all(d.join("mine")).unwrap();
    std::fs::write(d.join("mine/thesis.tex"), "x").unwrap();
    let o = run(
        &d,
        &[
            "check",
            "--suite",
            "suite.toml",
            "--platform",
            "linux-x86_64",
            "--test",
            "disc",
            "--json",
            "fresh/deep/check.json",
            "--report",
            "mine",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(!d.join("fresh").exists(), "{}", text(&o));
    assert_eq!(
        std::fs::read_to_string(d.join("mine/thesis.tex")).unwrap(),
        "x"
    );
}
