//! `rayproof reference SCENE --with povray` (and `mitsuba`): the real POV-Ray and Mitsuba 3
//! (installed by `.ci/run`) render the scene's reference with its manifest entry, and a suite
//! that compares rayproof's render with it takes the reference's sampling grid from that manifest, so a correct render passes;
//! one that insists on another grid is warned and fails. A missing renderer is one line with
//! how to install it, exit 3, and nothing written.

use std::path::{Path, PathBuf};
use std::process::Command;

fn rayproof(args: &[&str], path: Option<&Path>) -> (Option<i32>, String, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rayproof"));
    c.args(args);
    if let Some(p) = path {
        c.env("PATH", p);
    }
    let o = c.output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rayproof-reference-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.join("scenes")).unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(
        root.join("reference/scenes/diffuse.toml"),
        d.join("scenes/diffuse.toml"),
    )
    .unwrap();
    d
}

#[test]
fn povray_reference_then_a_suite_that_uses_its_grid() {
    reference_then_a_suite_that_uses_its_grid("povray", "3.7", "povray +Iscene.pov");
}

/// Mitsuba 3 from PyPI (`scalar_rgb`, installed by `.ci/run`), as issue 36 asks: its reference
/// for the scene, and a suite that passes against it (and fails at another grid).
#[test]
fn mitsuba_reference_then_a_suite_that_uses_its_grid() {
    reference_then_a_suite_that_uses_its_grid(
        "mitsuba",
        "3.",
        "python scripts/mitsuba_whitted.py scene.xml mitsuba.exr --variant scalar_rgb",
    );
}

fn reference_then_a_suite_that_uses_its_grid(renderer: &str, version: &str, command: &str) {
    let d = scratch(renderer);
    let scene = d.join("scenes/diffuse.toml");
    let (code, out, err) = rayproof(
        &[
            "reference",
            scene.to_str().unwrap(),
            "--with",
            renderer,
            "--width",
            "64",
            "--grid",
            "4",
        ],
        None,
    );
    assert_eq!(code, Some(0), "{out}{err}");
    // Beside the scenes directory, with the grid in its manifest
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("diffuse/manifest.json")).unwrap())
            .unwrap();
    let e = &m["files"][format!("{renderer}.exr")];
    assert_eq!(
        (e["grid"].as_u64(), e["width"].as_u64()),
        (Some(4), Some(64)),
        "{e}"
    );
    assert!(e["version"].as_str().unwrap().starts_with(version), "{e}");
    assert!(
        e["commands"][1].as_str().unwrap().starts_with(command),
        "{e}"
    );
    // rayproof's render at the manifest's grid passes against the real renderer
    let suite = |extra: &str| {
        format!(
            "[thresholds]\nfail = 0.05\nfailpercent = 0.1\nmax_mean = 1e-3\n\n[[test]]\nname = \"diffuse\"\nscene = \"scenes/diffuse.toml\"\nrayproof = {{ method = \"promote\", precision = \"f64\" }}\ngolden = false\n{extra}reference = [{{ name = \"{renderer}\", path = \"diffuse/{renderer}.exr\" }}]\n"
        )
    };
    std::fs::write(d.join("suite.toml"), suite("")).unwrap();
    let s = d.join("suite.toml");
    let (code, out, _) = rayproof(&["check", "--suite", s.to_str().unwrap()], None);
    assert_eq!(code, Some(0), "{out}");
    let row = out
        .lines()
        .find(|l| l.starts_with("diffuse "))
        .unwrap_or_else(|| panic!("no row in {out}"));
    let w: Vec<&str> = row.split_whitespace().collect();
    assert_eq!(
        w[..5],
        ["diffuse", renderer, "promote", "f64", "PASS"],
        "{out}"
    );
    // A render at grid 1 (the scene's own) is told why it fails
    std::fs::write(d.join("suite.toml"), suite("grid = 1\n")).unwrap();
    let (code, out, _) = rayproof(&["check", "--suite", s.to_str().unwrap()], None);
    assert_eq!(code, Some(1), "{out}");
    assert!(
        out.contains("warning: sampling grid: the reference was made with 4×4"),
        "{out}"
    );
}

#[test]
fn a_missing_renderer_is_one_line_exit_3_and_nothing_written() {
    let d = scratch("missing");
    let scene = d.join("scenes/diffuse.toml");
    // A PATH with only a shell: no povray
    let bin = d.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    std::os::unix::fs::symlink("/bin/sh", bin.join("sh")).unwrap();
    let (code, out, err) = rayproof(
        &["reference", scene.to_str().unwrap(), "--with", "povray"],
        Some(&bin),
    );
    assert_eq!(code, Some(3), "{out}{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("apt-get install povray"), "{err}");
    assert!(!d.join("diffuse").exists(), "something was written");
    // Mitsuba through a Python that does not exist
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .args(["reference", scene.to_str().unwrap(), "--with", "mitsuba"])
        .env("RAYPROOF_MITSUBA_PYTHON", "/nonexistent/python3")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("pip install mitsuba"), "{err}");
    assert!(!d.join("diffuse").exists());
}

#[test]
fn a_renderer_image_that_cannot_be_a_reference_is_not_written() {
    // A stand-in on PATH named povray (not a claim about POV-Ray: what rayproof does with a
    // renderer that exits 0 with a bad image): NaN values, or another size than the frame's
    let outside = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/outside");
    for (tag, value, extra_rows, want) in [
        ("nan", "float('nan')", 0, "NaN or Inf value(s): not written"),
        ("size", "0.5", 4, "where the frame is"),
    ] {
        let d = scratch(&format!("bad-{tag}"));
        let bin = d.join("bin");
        std::fs::create_dir_all(&bin).unwrap();
        let fake = bin.join("povray");
        std::fs::write(
            &fake,
            format!(
                r#"#!/bin/sh
case "$1" in --version) echo "POV-Ray 3.7.0.10 (stand-in)"; exit 0;; esac
for a in "$@"; do case "$a" in +O*) out="${{a#+O}}";; +W[0-9]*) w="${{a#+W}}";; +H[0-9]*) h="${{a#+H}}";; esac; done
exec python3 -c "import sys; sys.path.insert(0, '{o}'); import standin_render as s; w, h = $w, $h + {extra_rows}; s.write_exr('$out', w, h, [[[{value}] * 3 for x in range(w)] for y in range(h)])"
"#,
                o = outside.display()
            ),
        )
        .unwrap();
        std::fs::set_permissions(&fake, std::os::unix::fs::PermissionsExt::from_mode(0o755))
            .unwrap();
        let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap());
        let scene = d.join("scenes/diffuse.toml");
        let (code, out, err) = rayproof(
            &[
                "reference",
                scene.to_str().unwrap(),
                "--with",
                "povray",
                "--width",
                "16",
                "--grid",
                "1",
            ],
            Some(Path::new(&path)),
        );
        assert_eq!(code, Some(3), "{tag}: {out}{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{tag}: {err}");
        assert!(err.contains(want), "{tag}: {err}");
        assert!(
            !d.join("diffuse/povray.exr").exists(),
            "{tag}: a reference was written"
        );
    }
}

/// Issue 46's hostile run (F3): `check --update` never replaces a reference's entry, and now
/// the other way too: `rayproof reference` never writes over a golden (and its manifest entry)
/// that a suite blessed in the same directory. (Before: exit 0, the golden replaced silently,
/// and the suite then failed as stale and could not re-bless it.)
#[test]
fn a_reference_never_replaces_a_blessed_golden() {
    let d = scratch("over-golden");
    let scene = d.join("scenes/diffuse.toml");
    let img = d.join("mine.exr");
    let (code, out, err) = rayproof(
        &[
            "render",
            scene.to_str().unwrap(),
            "--width",
            "16",
            "-o",
            img.to_str().unwrap(),
        ],
        None,
    );
    assert_eq!(code, Some(0), "{out}{err}");
    let suite = d.join("suite.toml");
    std::fs::write(
        &suite,
        "[suite]\ngoldens = \"diffuse\"\n\n[[test]]\nname = \"povray\"\nimage = \"mine.exr\"\n",
    )
    .unwrap();
    let (code, out, err) = rayproof(
        &["check", "--suite", suite.to_str().unwrap(), "--update"],
        None,
    );
    assert_eq!(code, Some(0), "{out}{err}");
    let golden = std::fs::read(d.join("diffuse/povray.exr")).unwrap();
    let manifest = std::fs::read(d.join("diffuse/manifest.json")).unwrap();
    let (code, out, err) = rayproof(
        &[
            "reference",
            scene.to_str().unwrap(),
            "--with",
            "povray",
            "--width",
            "16",
            "--grid",
            "1",
        ],
        None,
    );
    assert_ne!(code, Some(0), "{out}{err}");
    assert!(err.contains("written by `check --update`"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert_eq!(std::fs::read(d.join("diffuse/povray.exr")).unwrap(), golden);
    assert_eq!(
        std::fs::read(d.join("diffuse/manifest.json")).unwrap(),
        manifest
    );
}
