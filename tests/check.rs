//! `rayproof check` end to end on rayproof's own suite (`reference/suite.toml`), run on a copy
//! of the `diffuse` scene's references: it passes as committed, fails when a reference is
//! perturbed, refuses a tampered or stale reference, `--update` rewrites only rayproof's own
//! golden render, and known failures have teeth. (Suites for other renderers: tests/suite.rs.)

use rayproof::golden::sha256_file;
use rayproof::images::{read_image, write_exr_rgb};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A fresh copy of reference/{scenes/diffuse.toml, diffuse/, suite.toml}.
fn fixture(tag: &str) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference");
    let dir = std::env::temp_dir().join(format!("rayproof-check-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    std::fs::create_dir_all(dir.join("diffuse")).unwrap();
    std::fs::copy(
        root.join("scenes/diffuse.toml"),
        dir.join("scenes/diffuse.toml"),
    )
    .unwrap();
    std::fs::copy(root.join("suite.toml"), dir.join("suite.toml")).unwrap();
    for f in ["povray.exr", "mitsuba.exr", "rayproof.exr", "manifest.json"] {
        std::fs::copy(root.join("diffuse").join(f), dir.join("diffuse").join(f)).unwrap();
    }
    dir
}

fn check(dir: &Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let o: Output = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .arg("check")
        .arg("--suite")
        .arg(dir.join("suite.toml"))
        .args(if extra.contains(&"--test") {
            &[][..]
        } else {
            &["--test", "diffuse"][..]
        })
        .args(extra)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The status word of the row for `reference`.
fn status(out: &str, reference: &str) -> String {
    out.lines()
        .find(|l| l.split_whitespace().nth(1) == Some(reference))
        .and_then(|l| l.split_whitespace().nth(4))
        .unwrap_or_else(|| panic!("no {reference} row in:\n{out}"))
        .to_string()
}

/// Adds `delta` to every channel of a 40×40 block (2.4 % of the pixels) and re-hashes it in the
/// manifest, as a re-rendered but different reference would be.
fn perturb(dir: &Path, file: &str, delta: f32) {
    let path = dir.join("diffuse").join(file);
    let mut img = read_image(&path).unwrap();
    let n = img.channels.len();
    for y in 100..140 {
        for x in 100..140 {
            for c in 0..3 {
                img.data[(y * img.width + x) * n + c] += delta;
            }
        }
    }
    write_exr_rgb(&path, &img).unwrap();
    rehash(dir, file);
}

fn rehash(dir: &Path, file: &str) {
    let m = dir.join("diffuse/manifest.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&m).unwrap()).unwrap();
    v["files"][file]["sha256"] = sha256_file(&dir.join("diffuse").join(file)).unwrap().into();
    std::fs::write(&m, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

#[test]
fn committed_references_pass() {
    let dir = fixture("pass");
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}{err}");
    for r in ["povray", "mitsuba", "golden"] {
        assert_eq!(status(&out, r), "PASS", "{out}");
    }
}

#[test]
fn a_perturbed_reference_fails_and_update_leaves_it_alone() {
    let dir = fixture("perturbed");
    perturb(&dir, "povray.exr", 0.2);
    let before = std::fs::read(dir.join("diffuse/povray.exr")).unwrap();
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "povray"), "FAILURE", "{out}");
    assert_eq!(status(&out, "mitsuba"), "PASS", "{out}");
    assert_eq!(
        std::fs::read(dir.join("diffuse/povray.exr")).unwrap(),
        before,
        "--update must never rewrite a POV-Ray reference"
    );
    // A perturbation below the thresholds (0.004 < warn 0.01) still passes
    let dir = fixture("small");
    perturb(&dir, "mitsuba.exr", 0.004);
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
}

#[test]
fn a_tampered_hash_is_refused() {
    let dir = fixture("tampered");
    // One byte changed, manifest not updated
    let p = dir.join("diffuse/mitsuba.exr");
    let mut bytes = std::fs::read(&p).unwrap();
    let k = bytes.len() - 100;
    bytes[k] ^= 1;
    std::fs::write(&p, bytes).unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(3), "{out}");
    assert_eq!(status(&out, "mitsuba"), "REFUSED", "{out}");
    assert!(out.contains("SHA-256"), "{out}");
    assert_eq!(status(&out, "povray"), "PASS", "{out}");
}

#[test]
fn a_changed_scene_refuses_stale_external_references_and_compares_a_stale_golden() {
    let dir = fixture("stale");
    let s = dir.join("scenes/diffuse.toml");
    let text = std::fs::read_to_string(&s).unwrap();
    std::fs::write(
        &s,
        text.replace("albedo = [0.8, 0.15, 0.1]", "albedo = [0.8, 0.15, 0.2]"),
    )
    .unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(3), "{out}");
    // External references cannot be re-made by rayproof: refused
    for r in ["povray", "mitsuba"] {
        assert_eq!(status(&out, r), "REFUSED", "{out}");
    }
    assert!(
        out.contains(
            "was made from another version of the scene scenes/diffuse.toml: re-render it"
        ),
        "{out}"
    );
    // rayproof's own golden is rendered and compared (the albedo changed: it fails), and
    // said to be stale
    assert_eq!(status(&out, "golden"), "FAILURE", "{out}");
    assert!(
        out.contains(
            "warning: stale golden: made from another version of the scene scenes/diffuse.toml"
        ),
        "{out}"
    );
}

#[test]
fn update_writes_a_missing_golden_render_and_only_that() {
    let dir = fixture("update");
    std::fs::remove_file(dir.join("diffuse/rayproof.exr")).unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "golden"), "NEW", "{out}");
    let pov = std::fs::read(dir.join("diffuse/povray.exr")).unwrap();
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(status(&out, "golden"), "UPDATED", "{out}");
    assert_eq!(std::fs::read(dir.join("diffuse/povray.exr")).unwrap(), pov);
    // The new golden is hashed in the manifest and passes a plain check
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(status(&out, "golden"), "PASS", "{out}");
}

#[test]
fn known_failures_have_teeth() {
    // Listed as failing but passing: XPASS, exit 1
    let dir = fixture("xpass");
    let t = dir.join("suite.toml");
    let text = std::fs::read_to_string(&t).unwrap();
    let entry = r#"{ name = "povray", path = "diffuse/povray.exr" }"#;
    assert!(text.contains(entry));
    std::fs::write(
        &t,
        text.replace(
            entry,
            r#"{ name = "povray", path = "diffuse/povray.exr", thresholds = { known_failure = "test entry" } }"#,
        ),
    )
    .unwrap();
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(status(&out, "povray"), "XPASS", "{out}");
    // Listed and failing: XFAIL, exit 0
    perturb(&dir, "povray.exr", 0.2);
    let (code, out, _) = check(&dir, &[]);
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(status(&out, "povray"), "XFAIL", "{out}");
}

#[test]
fn bad_thresholds_are_one_line_errors() {
    let dir = fixture("badthresholds");
    let t = dir.join("suite.toml");
    let text = std::fs::read_to_string(&t).unwrap();
    std::fs::write(&t, text.replacen("fail = 0.05", "fial = 0.05", 1)).unwrap();
    let (code, out, err) = check(&dir, &[]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("fial"), "{err}");
    let (code, _, err) = check(&dir.join("nowhere"), &[]);
    assert_eq!(code, Some(2));
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
}

#[test]
fn report_has_one_row_per_comparison_with_images() {
    let dir = fixture("report");
    let report = dir.join("html");
    let (code, out, _) = check(&dir, &["--report", report.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{out}");
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert_eq!(html.matches("<tr class=").count(), 3, "{html}");
    assert!(html.contains("onmouseover"));
    // Issue 48's frictions: an identical pair points at no pixel, and a long name or log line
    // wraps in its cell instead of pushing the metrics off a 1280-pixel window
    assert!(!html.contains("max 0.000e0 @"), "{html}");
    // (the golden comparison is bit-identical: its row is the identical one)
    assert!(html.contains("identical: no difference"), "{html}");
    assert!(html.contains("max 0 (identical)"), "{html}");
    assert!(html.contains("td:first-child { max-width: 22em; overflow-wrap: anywhere; }"));
    for f in [
        "diffuse-new-promote-f64.png",
        "diffuse-povray.png",
        "diffuse-povray-promote-f64-flip.png",
    ] {
        assert!(report.join(f).is_file(), "{f} missing");
    }
}

#[test]
fn shapes_scene_passes_against_povray_mitsuba_and_its_golden_render() {
    // The committed references of the box/cylinder/torus/ellipsoid scene, read in place (no
    // --update: nothing is written)
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference");
    let (code, out, err) = check(&dir, &["--test", "shapes"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let rows: Vec<&str> = out
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("shapes"))
        .collect();
    assert_eq!(rows.len(), 3, "{out}");
    for r in ["povray", "mitsuba", "golden"] {
        assert_eq!(status(&out, r), "PASS", "{out}");
    }
}

#[test]
fn shapes_thresholds_catch_an_axis_mixup_in_one_ellipsoid() {
    // Teeth: the ellipsoid's x and z semi-axes swapped (0.55, 0.45 → 0.45, 0.55), as a renderer
    // that confused axes would draw it, fails against both external references under the
    // scene's own rules, while the committed scene passes (the test above)
    use rayproof::golden::Suite;
    use rayproof::images::{compare, Image, Verdict};
    use rayproof::render::{render, scene, Overrides};
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference");
    let path = root.join("scenes/shapes.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("radii = [0.55, 0.9, 0.45]"));
    let wrong = scene::parse(
        &text.replace("radii = [0.55, 0.9, 0.45]", "radii = [0.45, 0.9, 0.55]"),
        &path,
    )
    .unwrap();
    let ov = Overrides {
        size: Some((128, 128)),
        grid: Some(8),
        ..Default::default()
    };
    let r = render(&wrong, &ov);
    let img = Image::rgb(
        r.width,
        r.height,
        r.beauty.iter().flatten().copied().collect(),
    );
    let suite = Suite::load(&root.join("suite.toml"), None).unwrap();
    let test = suite.tests.iter().find(|t| t.name == "shapes").unwrap();
    for reference in ["povray", "mitsuba"] {
        let refimg = read_image(&root.join("shapes").join(format!("{reference}.exr"))).unwrap();
        let rule = &test
            .references
            .iter()
            .find(|r| r.name == reference)
            .unwrap()
            .rule;
        let c = compare(&refimg, &img, &rule.idiff).unwrap();
        assert!(
            c.verdict == Verdict::Failure || c.mean_error > rule.max_mean,
            "{reference}: an axis mix-up passed (verdict {:?}, mean {:e})",
            c.verdict,
            c.mean_error
        );
    }
}

#[test]
fn update_with_a_malformed_scene_writes_nothing() {
    // NaN albedo: refused at load, so the test is refused and --update writes no golden
    let dir = fixture("nanalbedo");
    let s = dir.join("scenes/diffuse.toml");
    let text = std::fs::read_to_string(&s).unwrap();
    std::fs::write(
        &s,
        text.replace("albedo = [0.8, 0.15, 0.1]", "albedo = [nan, 0.15, 0.1]"),
    )
    .unwrap();
    std::fs::remove_file(dir.join("diffuse/rayproof.exr")).unwrap();
    let manifest = std::fs::read(dir.join("diffuse/manifest.json")).unwrap();
    let (code, out, _) = check(&dir, &["--update"]);
    assert_eq!(code, Some(3), "{out}");
    assert!(out.contains("albedo"), "{out}");
    assert!(out.contains("--update wrote nothing"), "{out}");
    assert!(!dir.join("diffuse/rayproof.exr").exists());
    assert_eq!(
        std::fs::read(dir.join("diffuse/manifest.json")).unwrap(),
        manifest
    );
}
