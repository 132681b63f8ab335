//! Hostile scenes (issue 16's reproducers): every bad value is refused at load with one line
//! naming the file, the line and the field (exit 2), sizes, grids and depths beyond the
//! documented limits are refused before anything is allocated, and every reference scene
//! renders without a NaN or Inf pixel.

use crate::common::scratch;
use std::path::Path;
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn rayproof(args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Writes `text` as `d/s.toml` and renders it to `d/o.exr` with `args`: exit code and stderr.
fn render_text(d: &Path, text: &str, args: &[&str]) -> (Option<i32>, String) {
    let s = d.join("s.toml");
    std::fs::write(&s, text).unwrap();
    let out = d.join("o.exr");
    let mut all = vec!["render", s.to_str().unwrap(), "-o", out.to_str().unwrap()];
    all.extend(args);
    let (code, _, err) = rayproof(&all);
    (code, err)
}

/// A reference scene with one text replacement, rendered at 16 pixels wide: the exit code and
/// standard error.
fn mutated(tag: &str, scene: &str, from: &str, to: &str, extra: &[&str]) -> (Option<i32>, String) {
    let text = std::fs::read_to_string(root().join("reference/scenes").join(scene)).unwrap();
    assert!(text.contains(from), "{scene} has no '{from}'");
    let d = scratch(tag);
    let (code, err) = render_text(&d, &text.replacen(from, to, 1), extra);
    let out = d.join("o.exr");
    assert!(
        !out.exists() || code == Some(0),
        "{tag}: an output was written on failure"
    );
    (code, err)
}

#[test]
fn bad_scene_values_are_refused_at_load_with_file_line_and_field() {
    let cases: &[(&str, &str, &str, &str, &str)] = &[
        // (tag, scene, from, to, what the one line must say)
        (
            "nan-centre",
            "diffuse.toml",
            "center = [-1.1, 0.7, 0.0]",
            "center = [nan, 0.7, 0.0]",
            "shapes[1].center",
        ),
        (
            "inf-radius",
            "diffuse.toml",
            "radius = 0.7",
            "radius = inf",
            "radius",
        ),
        (
            "neg-radius",
            "diffuse.toml",
            "radius = 0.7",
            "radius = -0.7",
            "radius",
        ),
        (
            "nan-light",
            "diffuse.toml",
            "position = [3.0, 6.0, 4.0]",
            "position = [nan, 6.0, 4.0]",
            "lights[0].position",
        ),
        (
            "inf-intensity",
            "diffuse.toml",
            "intensity = [60.0, 60.0, 60.0]",
            "intensity = [inf, 60.0, 60.0]",
            "lights[0].intensity",
        ),
        (
            "nan-albedo",
            "diffuse.toml",
            "albedo = [0.8, 0.15, 0.1]",
            "albedo = [nan, 0.15, 0.1]",
            "albedo",
        ),
        (
            "neg-reflectance",
            "mirror.toml",
            "reflectance = [0.9, 0.9, 0.9]",
            "reflectance = [-0.9, 0.9, 0.9]",
            "reflectance",
        ),
        (
            "nan-camera",
            "diffuse.toml",
            "position = [0.0, 1.6, 6.0]",
            "position = [nan, 1.6, 6.0]",
            "camera.position",
        ),
        (
            "zero-up",
            "diffuse.toml",
            "up = [0.0, 1.0, 0.0]",
            "up = [0.0, 0.0, 0.0]",
            "camera.up",
        ),
        (
            "eye-at-target",
            "diffuse.toml",
            "look_at = [0.0, 0.6, 0.0]",
            "look_at = [0.0, 1.6, 6.0]",
            "camera.look_at",
        ),
        (
            "depth",
            "glass.toml",
            "max_depth = 10",
            "max_depth = 10000",
            "render.max_depth",
        ),
        (
            "ior",
            "glass.toml",
            "ior = 1.5",
            "ior = 1e308",
            "ior must be in [0.01, 100]",
        ),
        (
            "height",
            "diffuse.toml",
            "height = 256",
            "height = 4294967295",
            "each side may be at most 16384",
        ),
        (
            "grid",
            "diffuse.toml",
            "grid = 8",
            "grid = 100",
            "grid: n may be at most 64",
        ),
    ];
    let mut bad = vec![];
    for (tag, scene, from, to, want) in cases {
        let (code, err) = mutated(tag, scene, from, to, &["--width", "16"]);
        let one_line = err.trim_end().lines().count() == 1;
        let located = err.contains("s.toml:");
        if code != Some(2) || !one_line || !located || !err.contains(want) {
            bad.push(format!("{tag}: exit {code:?}, stderr {err:?}"));
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn a_tall_aspect_with_a_width_override_is_refused_before_allocating() {
    // 3 × 100,000,000 at --width 16 would be 16 × 533,333,333 pixels (110.9 GB of beauty)
    let text = std::fs::read_to_string(root().join("reference/scenes/diffuse.toml")).unwrap();
    let d = scratch("aspect");
    let tall =
        text.replacen("width = 256", "width = 3", 1)
            .replacen("height = 256", "height = 10000", 1);
    let (code, err) = render_text(&d, &tall, &["--width", "16"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("each side may be at most 16384"), "{err}");
    let (code, err) = render_text(&d, &tall, &["--spp", "10000"]);
    assert_eq!(code, Some(2), "{err}");
}

#[test]
fn a_mesh_with_a_nan_vertex_is_refused() {
    let d = scratch("obj");
    std::fs::write(d.join("m.obj"), "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n").unwrap();
    let text = std::fs::read_to_string(root().join("reference/scenes/diffuse.toml")).unwrap();
    let mesh =
        format!("{text}\n[[shapes]]\ntype = \"mesh\"\nfile = \"m.obj\"\nmaterial = \"red\"\n");
    let (code, err) = render_text(&d, &mesh, &["--width", "16"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("vertex 2") && err.contains("not finite"),
        "{err}"
    );
}

#[test]
fn every_reference_scene_renders_without_nan_or_inf() {
    let d = scratch("finite");
    for e in std::fs::read_dir(root().join("reference/scenes")).unwrap() {
        let p = e.unwrap().path();
        let out = d.join(format!("{}.exr", p.file_stem().unwrap().to_str().unwrap()));
        let (code, _, err) = rayproof(&[
            "render",
            p.to_str().unwrap(),
            "--width",
            "48",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, Some(0), "{}: {err}", p.display());
        let side: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(format!("{}.json", out.display())).unwrap(),
        )
        .unwrap();
        assert_eq!(side["nonfinite_pixels"], 0, "{}", p.display());
    }
}

/// `bytes` with the data window's xMax and yMax replaced (an EXR header field).
fn patch_window(bytes: &[u8], xmax: i32, ymax: i32) -> Vec<u8> {
    let key = b"dataWindow\0box2i\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    let mut out = bytes.to_vec();
    out[at + 8..at + 12].copy_from_slice(&xmax.to_le_bytes());
    out[at + 12..at + 16].copy_from_slice(&ymax.to_le_bytes());
    out
}

#[test]
fn an_exr_declaring_a_huge_window_is_refused_before_allocating() {
    let d = scratch("exr");
    let good = d.join("good.exr");
    let img = rayproof::images::Image::rgb(16, 16, vec![0.5; 16 * 16 * 3]);
    rayproof::images::write_exr_rgb(&good, &img).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    for (tag, xmax, ymax, want) in [
        (
            "tera",
            (1 << 20) - 1,
            (1 << 20) - 1,
            "declares 1048576×1048576 pixels",
        ),
        ("65536", 65535, 65535, "declares 65536×65536 pixels"),
        ("ymax", 15, 0x7fff_fff0, "data window"),
        ("chunks", 15, 40_000, "chunks"),
    ] {
        let bad = d.join(format!("{tag}.exr"));
        std::fs::write(&bad, patch_window(&bytes, xmax, ymax)).unwrap();
        let (code, _, err) = rayproof(&["diff", good.to_str().unwrap(), bad.to_str().unwrap()]);
        assert_eq!(code, Some(4), "{tag}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(want), "{tag}: {err}");
        let out = d.join("down.exr");
        let (code, _, err) = rayproof(&[
            "downsample",
            bad.to_str().unwrap(),
            "--factor",
            "2",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(code == Some(2) || code == Some(4), "{tag}: {code:?} {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
}

/// `probe sphere` with `x` as the ray origin's x: exit code and standard error.
fn probe_x(prec: &str, x: &str) -> (Option<i32>, String) {
    let tail = ["0", "0", "1", "0", "0", "0", "0", "5", "1"];
    let mut args = vec!["probe", "sphere", "--precision", prec, "--", x];
    args.extend(tail);
    let (code, _, err) = rayproof(&args);
    (code, err)
}

#[test]
fn decimal_and_hex_numbers_follow_one_rule_on_the_command_line() {
    // Too large or too small for the precision: an error naming what was wrong, in both notations
    for (v, prec, want) in [
        ("1e400", "f64", "overflows f64"),
        ("0x1p+1024", "f64", "not a hex float exact in f64"),
        ("1e-400", "f64", "underflows f64 to 0"),
        ("0x1p-1100", "f64", "not a hex float exact in f64"),
        ("1e39", "f32", "overflows f32"),
        ("0x1p+200", "f32", "overflows f32"),
        ("1e-50", "f32", "underflows f32 to 0"),
    ] {
        let (code, err) = probe_x(prec, v);
        assert_eq!(code, Some(2), "{v} {prec}: {err}");
        assert!(err.contains(want) && err.contains(v), "{v} {prec}: {err}");
    }
    // Spelled infinities, zeros and subnormals stay values
    for v in ["inf", "-0", "0x0p+0", "1e-45", "0x1p-149"] {
        let (code, err) = probe_x("f32", v);
        assert_eq!(code, Some(0), "{v}: {err}");
    }
}

/// Sends SIGTERM to a running rayproof: it must exit 130 and leave `d` empty.
fn terminate(mut child: std::process::Child, d: &Path) {
    // SAFETY: kill(2) on our own child
    unsafe {
        libc::kill(child.id() as i32, libc::SIGTERM);
    }
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130));
    assert!(names(d).is_empty(), "{:?}", names(d));
}

/// The names in a directory.
fn names(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_failed_multi_file_write_replaces_nothing_and_leaves_no_temporary() {
    let d = scratch("multi");
    let scene = root().join("reference/scenes/diffuse.toml");
    let good = d.join("good.exr");
    let (code, _, err) = rayproof(&[
        "render",
        scene.to_str().unwrap(),
        "--width",
        "16",
        "-o",
        good.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let before = (
        std::fs::read(&good).unwrap(),
        std::fs::read(d.join("good.exr.json")).unwrap(),
    );
    let listing = names(&d);
    // --png names a directory: refused before rendering, nothing replaced
    std::fs::create_dir_all(d.join("DIR")).unwrap();
    let (code, _, err) = rayproof(&[
        "render",
        scene.to_str().unwrap(),
        "--width",
        "8",
        "-o",
        good.to_str().unwrap(),
        "--png",
        d.join("DIR").to_str().unwrap(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("is a directory"), "{err}");
    assert_eq!(
        (
            std::fs::read(&good).unwrap(),
            std::fs::read(d.join("good.exr.json")).unwrap()
        ),
        before
    );
    let mut want = listing.clone();
    want.push("DIR".into());
    want.sort();
    assert_eq!(names(&d), want);
    // A symbolic link and a FIFO are never replaced
    std::os::unix::fs::symlink(&good, d.join("link.exr")).unwrap();
    let fifo = d.join("fifo.exr");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    for (p, what) in [
        (d.join("link.exr"), "a symbolic link"),
        (fifo.clone(), "not a regular file"),
    ] {
        let (code, _, err) = rayproof(&[
            "render",
            scene.to_str().unwrap(),
            "--width",
            "8",
            "-o",
            p.to_str().unwrap(),
        ]);
        assert_eq!(code, Some(2), "{err}");
        assert!(err.contains(what), "{err}");
        assert!(
            std::fs::symlink_metadata(&p)
                .unwrap()
                .file_type()
                .is_symlink()
                == (what == "a symbolic link")
        );
    }
    assert_eq!(std::fs::read(&good).unwrap(), before.0);
    // What a killed run left beside an output is removed by the next write of it
    let stale = d.join(".good.exr.rayproof-4000000000-0123456789abcdef.tmp");
    std::fs::write(&stale, b"half").unwrap();
    let (code, _, err) = rayproof(&[
        "render",
        scene.to_str().unwrap(),
        "--width",
        "16",
        "-o",
        good.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(!stale.exists());
}

#[test]
fn output_paths_are_checked_before_the_work_starts() {
    let d = scratch("early");
    let t0 = std::time::Instant::now();
    for (target, want) in [
        (d.to_str().unwrap().to_string(), "is a directory"),
        ("/proc/version".to_string(), "cannot write /proc/version"),
    ] {
        let (code, _, err) = rayproof(&["audit", "--json", &target]);
        assert_eq!(code, Some(2), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(want) && !err.contains(".tmp"), "{err}");
    }
    // Refused at once, not after a minute of auditing
    assert!(t0.elapsed().as_secs() < 20, "{:?}", t0.elapsed());
}

#[test]
fn a_terminated_render_exits_130_and_leaves_nothing() {
    let d = scratch("term");
    let scene = root().join("reference/scenes/fan30.toml");
    let out = d.join("o.exr");
    let child = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .args([
            "render",
            scene.to_str().unwrap(),
            "--width",
            "2048",
            "--spp",
            "16",
            "-o",
            out.to_str().unwrap(),
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(500));
    terminate(child, &d);
}

#[test]
fn a_terminated_report_leaves_no_staging_directory() {
    let d = scratch("report");
    let out = d.join("rep");
    let child = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(root())
        .args(["report", "--quick", "--out", out.to_str().unwrap()])
        .stderr(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until its staging directory exists, then terminate it
    let t0 = std::time::Instant::now();
    while !names(&d).iter().any(|n| n.starts_with(".rep.rayproof-")) {
        assert!(t0.elapsed().as_secs() < 30, "no staging directory appeared");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    terminate(child, &d);
}
