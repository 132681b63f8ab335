//! "Nothing lost, nothing hangs": every input is bounded before it costs. Each reproducer of the
//! issue runs the binary under a 2 GB address-space limit and a deadline: it must finish in
//! seconds with the documented exit code and one line on stderr naming the input and the limit
//! it broke (or, for the path-tree budget, render within the budget and say so), never abort,
//! hang or eat the machine.

use crate::common::{s, scratch};
use std::io::Read;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The address space a reproducer may take: 2 GB (a regression aborts instead of swapping).
const MEMORY: u64 = 2_000_000_000;

/// What a bounded run did.
struct Run {
    /// Exit code; `None` for a signal (an abort) or a run killed at its deadline.
    code: Option<i32>,
    stdout: String,
    stderr: String,
    seconds: f64,
    timed_out: bool,
}

impl Run {
    /// Exit `code`, in time, with one line on stderr containing every one of `want`.
    fn refused(&self, code: i32, want: &[&str]) {
        assert!(
            !self.timed_out,
            "still running after {:.0} s: {}",
            self.seconds, self.stderr
        );
        assert_eq!(self.code, Some(code), "stderr: {}", self.stderr);
        assert_eq!(
            self.stderr.trim_end().lines().count(),
            1,
            "not one line: {}",
            self.stderr
        );
        for w in want {
            assert!(self.stderr.contains(w), "no {w:?} in: {}", self.stderr);
        }
    }
}

/// Runs `rayproof ARGS` in `dir` under [`MEMORY`], killed after `deadline` seconds.
fn bounded(dir: &Path, args: &[&str], deadline: u64) -> Run {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rayproof"));
    c.args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    unsafe {
        c.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: MEMORY as libc::rlim_t,
                rlim_max: MEMORY as libc::rlim_t,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let start = Instant::now();
    let mut child = c.spawn().expect("the rayproof binary runs");
    let read = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut v = vec![];
            let _ = r.read_to_end(&mut v);
            String::from_utf8_lossy(&v).into_owned()
        })
    };
    let out = read(Box::new(child.stdout.take().unwrap()));
    let err = read(Box::new(child.stderr.take().unwrap()));
    let mut timed_out = false;
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        if start.elapsed() > Duration::from_secs(deadline) {
            timed_out = true;
            let _ = child.kill();
            break child.wait().unwrap();
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Run {
        code: if timed_out { None } else { status.code() },
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
        seconds: start.elapsed().as_secs_f64(),
        timed_out,
    }
}

/// A 16×16 scene around `shapes` (TOML appended after the camera, a light and two materials).
fn scene(camera: &str, render: &str, light: &str, shapes: &str) -> String {
    format!(
        r#"[camera]
position = {camera}
look_at = [0.0, 0.0, 0.0]
fov = 40.0
width = 16
height = 16

[render]
{render}

[[lights]]
position = [3.0, 6.0, 4.0]
intensity = {light}

[materials.grey]
type = "diffuse"
albedo = [0.5, 0.5, 0.5]

[materials.glass]
type = "glass"
ior = 1.5

[materials.chrome]
type = "mirror"
reflectance = [0.9, 0.9, 0.9]
{shapes}"#
    )
}

const EYE: &str = "[0.0, 0.0, 12.0]";
const LIGHT: &str = "[40.0, 40.0, 40.0]";
const SPHERE: &str = "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"grey\"\n";

// ---- 1. MPU points ----

#[test]
fn mpu_points_beyond_the_magnitude_limit_are_refused_not_fitted_forever() {
    // Five points at ±1e308: the fit's ball growth looped forever
    let d = scratch("bounds-mpu");
    std::fs::write(
        d.join("far.pts"),
        "1e308 1e308 1e308 0 0 1\n-1e308 -1e308 -1e308 0 0 1\n1e308 -1e308 1e308 0 1 0\n\
         -1e308 1e308 -1e308 1 0 0\n0 0 0 0 0 1\n",
    )
    .unwrap();
    let mpu = "\n[[shapes]]\ntype = \"mpu\"\npoints = \"far.pts\"\nmaterial = \"grey\"\n";
    std::fs::write(d.join("s.toml"), scene(EYE, "", LIGHT, mpu)).unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "o.exr"], 10);
    r.refused(2, &["far.pts", "line 1", "1e150"]);
    assert!(!d.join("o.exr").exists());
    // Just inside the limit the fit ends at once
    std::fs::write(
        d.join("far.pts"),
        "1e150 1e150 1e150 0 0 1\n-1e150 -1e150 -1e150 0 0 1\n1e150 -1e150 1e150 0 1 0\n\
         -1e150 1e150 -1e150 1 0 0\n0 0 0 0 0 1\n",
    )
    .unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "o.exr"], 10);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    // A point file that is a device is not read
    let dev = "\n[[shapes]]\ntype = \"mpu\"\npoints = \"/dev/zero\"\nmaterial = \"grey\"\n";
    std::fs::write(d.join("s.toml"), scene(EYE, "", LIGHT, dev)).unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "o.exr"], 10);
    r.refused(2, &["/dev/zero", "not a regular file"]);
}

// ---- 2. Tolerance tables ----

const MEASURED_RULE: &str = r#"[[rule]]
shape = "sphere"
method = "rtg7"
precision = "f32"
class = "far_small"
wrong = "measured"
why = "a user's measurement"
"#;

fn audit_with(d: &Path, table: &str) -> Run {
    std::fs::write(d.join("t.toml"), table).unwrap();
    bounded(
        d,
        &[
            "audit",
            "--shape",
            "sphere",
            "--method",
            "rtg7",
            "--precision",
            "f32",
            "--class",
            "far_small",
            "--cases",
            "100",
            "--tolerances",
            "t.toml",
        ],
        10,
    )
}

#[test]
fn a_measurement_too_large_for_its_bounds_is_refused_not_computed_forever() {
    let d = scratch("bounds-measured");
    // [1, 10^9]: statrs' beta quantile never returned; the bisection's CDF is not accurate there
    let r = audit_with(
        &d,
        &format!("{MEASURED_RULE}\n[measured]\n\"sphere rtg7 f32 far_small\" = [1, 1000000000]\n"),
    );
    r.refused(2, &["t.toml", "[1, 1000000000]", "at most 10000000 cases"]);
    // At the limit it is judged in time
    let r = audit_with(
        &d,
        &format!("{MEASURED_RULE}\n[measured]\n\"sphere rtg7 f32 far_small\" = [1, 10000000]\n"),
    );
    assert!(
        !r.timed_out && matches!(r.code, Some(0 | 1)),
        "{}",
        r.stderr
    );
}

#[test]
fn a_nan_bound_is_refused_not_passed() {
    let d = scratch("bounds-nan-rule");
    let table = format!(
        "{}max_err_over_cond = nan\n\n[measured]\n\"sphere rtg7 f32 far_small\" = [1, 19860]\n",
        MEASURED_RULE
    );
    let r = audit_with(&d, &table);
    r.refused(2, &["t.toml", "max_err_over_cond", "finite number ≥ 0"]);
}

// ---- 3. The path tree of glass and mirrors ----

/// 40 glass and mirror spheres, 16×16, at `depth` (exponential: 33 s at depth 48 before the
/// budget).
fn forty_spheres(depth: u32) -> String {
    let mut shapes = String::new();
    for x in -2..3 {
        for y in -2..2 {
            for z in 0..2 {
                let m = if (x + y + z) % 2 == 0 {
                    "glass"
                } else {
                    "chrome"
                };
                shapes += &format!(
                    "\n[[shapes]]\ntype = \"sphere\"\ncenter = [{:?}, {:?}, {:?}]\nradius = 0.5\nmaterial = \"{m}\"\n",
                    x as f64 * 1.1,
                    y as f64 * 1.1 + 0.55,
                    -z as f64 * 1.1
                );
            }
        }
    }
    scene(EYE, &format!("max_depth = {depth}"), LIGHT, &shapes)
}

fn sidecar(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn forty_glass_and_mirror_spheres_at_depth_256_render_within_the_tree_budget() {
    let d = scratch("bounds-tree");
    std::fs::write(d.join("s.toml"), forty_spheres(256)).unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "a.exr"], 10);
    assert!(!r.timed_out, "still rendering after {:.0} s", r.seconds);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(r.stdout.contains("tree budget"), "{}", r.stdout);
    let side = sidecar(&d.join("a.exr.json"));
    let cut = side["rays"]["budget_cut"].as_u64().unwrap();
    assert!(cut > 0, "{side}");
    assert_eq!(side["nonfinite_pixels"], 0);
    // No sample's tree exceeds the budget: 4096 segments per primary ray at most
    let rays = &side["rays"];
    let segments = ["primary", "reflection", "refraction"]
        .iter()
        .map(|k| rays[k].as_u64().unwrap())
        .sum::<u64>();
    assert!(segments <= 4096 * rays["primary"].as_u64().unwrap());
    // The same image every run, whatever the threads did
    let r = bounded(&d, &["render", "s.toml", "-o", "b.exr"], 10);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert_eq!(
        std::fs::read(d.join("a.exr")).unwrap(),
        std::fs::read(d.join("b.exr")).unwrap()
    );
    // At depth 12 no tree reaches the budget (2^12 − 1 segments at most)
    std::fs::write(d.join("s.toml"), forty_spheres(12)).unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "c.exr"], 10);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert_eq!(sidecar(&d.join("c.exr.json"))["rays"]["budget_cut"], 0);
}

// ---- 4. Meshes ----

#[test]
fn a_mesh_must_be_a_regular_file_within_its_cap_and_its_mtllib_is_not_read() {
    let d = scratch("bounds-mesh");
    let mesh = |file: &str| {
        format!("\n[[shapes]]\ntype = \"mesh\"\nfile = \"{file}\"\nmaterial = \"grey\"\n")
    };
    // mtllib /dev/zero: tobj read it until the allocation aborted (4.2 GB)
    std::fs::write(
        d.join("m.obj"),
        "mtllib /dev/zero\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nusemtl x\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(d.join("s.toml"), scene(EYE, "", LIGHT, &mesh("m.obj"))).unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "o.exr"], 10);
    assert!(!r.timed_out);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    // file = "/dev/zero"
    std::fs::write(d.join("s.toml"), scene(EYE, "", LIGHT, &mesh("/dev/zero"))).unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "o2.exr"], 10);
    r.refused(2, &["/dev/zero", "not a regular file"]);
    // A file beyond 64 MiB is refused by its size (a sparse file: nothing is written or read)
    let big = std::fs::File::create(d.join("big.obj")).unwrap();
    big.set_len((64 << 20) + 1).unwrap();
    std::fs::write(d.join("s.toml"), scene(EYE, "", LIGHT, &mesh("big.obj"))).unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "o2.exr"], 10);
    r.refused(2, &["big.obj", "67108865 bytes", "64 MiB"]);
    assert!(!d.join("o2.exr").exists());
}

// ---- 5. Images ----

/// A scanline EXR header declaring `w × h` half-float pixels with `channels` channels (R, G, B
/// and more), ZIP-compressed, its offset table and one tiny chunk per entry: a few KB that
/// declare any size.
fn exr_declaring(w: i32, h: i32, channels: usize) -> Vec<u8> {
    let attr = |name: &str, ty: &str, data: &[u8]| {
        let mut v = vec![];
        for s in [name, ty] {
            v.extend_from_slice(s.as_bytes());
            v.push(0);
        }
        v.extend_from_slice(&(data.len() as i32).to_le_bytes());
        v.extend_from_slice(data);
        v
    };
    let mut names: Vec<String> = ["R", "G", "B"].iter().map(|s| s.to_string()).collect();
    names.extend((3..channels).map(|i| format!("A{i:03}")));
    names.sort();
    let mut list = vec![];
    for n in &names {
        list.extend_from_slice(n.as_bytes());
        list.push(0);
        list.extend_from_slice(&1i32.to_le_bytes()); // HALF
        list.extend_from_slice(&[0, 0, 0, 0]); // pLinear, reserved
        list.extend_from_slice(&1i32.to_le_bytes());
        list.extend_from_slice(&1i32.to_le_bytes());
    }
    list.push(0);
    let window: Vec<u8> = [0, 0, w - 1, h - 1]
        .iter()
        .flat_map(|v: &i32| v.to_le_bytes())
        .collect();
    let mut f = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
    f.extend(attr("channels", "chlist", &list));
    f.extend(attr("compression", "compression", &[3]));
    f.extend(attr("dataWindow", "box2i", &window));
    f.extend(attr("displayWindow", "box2i", &window));
    f.extend(attr("lineOrder", "lineOrder", &[0]));
    f.extend(attr("pixelAspectRatio", "float", &1f32.to_le_bytes()));
    f.extend(attr("screenWindowCenter", "v2f", &[0; 8]));
    f.extend(attr("screenWindowWidth", "float", &1f32.to_le_bytes()));
    f.push(0);
    let chunks = (h as usize).div_ceil(16);
    let start = f.len() + 8 * chunks;
    let chunk = |i: usize| {
        let mut c = ((16 * i) as i32).to_le_bytes().to_vec();
        c.extend_from_slice(&8i32.to_le_bytes());
        c.extend_from_slice(&[0; 8]);
        c
    };
    for i in 0..chunks {
        f.extend_from_slice(&((start + 16 * i) as u64).to_le_bytes());
    }
    for i in 0..chunks {
        f.extend(chunk(i));
    }
    f
}

#[test]
fn an_exr_declaring_too_many_channels_is_refused_from_its_header() {
    let d = scratch("bounds-exr");
    let good = d.join("good.exr");
    let img = rayproof::images::Image::rgb(16, 16, vec![0.5; 16 * 16 * 3]);
    rayproof::images::write_exr_rgb(&good, &img).unwrap();
    // 8192² × 64 channels in 14 KB (the issue's took 198 KB): 8 GB of samples; and × 16
    for (channels, samples) in [(64, "4294967296 samples"), (16, "1073741824 samples")] {
        let bad = d.join(format!("c{channels}.exr"));
        let bytes = exr_declaring(8192, 8192, channels);
        assert!(bytes.len() < 20_000, "{} bytes", bytes.len());
        std::fs::write(&bad, bytes).unwrap();
        let r = bounded(&d, &["diff", "good.exr", s(&bad)], 10);
        r.refused(4, &[s(&bad), samples, "at most 268435456"]);
        let r = bounded(
            &d,
            &["downsample", s(&bad), "--factor", "2", "-o", "down.exr"],
            10,
        );
        r.refused(4, &[samples]);
        assert!(!d.join("down.exr").exists());
    }
}

#[test]
fn an_exr_of_ten_thousand_layers_is_refused_from_its_header() {
    use exr::prelude::*;
    let d = scratch("bounds-layers");
    let good = d.join("good.exr");
    let img = rayproof::images::Image::rgb(2, 2, vec![0.5; 12]);
    rayproof::images::write_exr_rgb(&good, &img).unwrap();
    // 10,000 Blender-style layers of one channel and 2×2 pixels: 40,000 samples, far under the
    // sample limit, refused by the channel count
    let list: Vec<AnyChannel<FlatSamples>> = (0..10_000)
        .map(|i| {
            AnyChannel::new(
                format!("L{i:05}.Y").as_str(),
                FlatSamples::F16(vec![f16::ZERO; 4]),
            )
        })
        .collect();
    let layer = Layer::new(
        (2, 2),
        LayerAttributes::default(),
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(list.into()),
    );
    let bad = d.join("layers.exr");
    exr::prelude::Image::from_layer(layer)
        .write()
        .to_file(&bad)
        .unwrap();
    for layer in [None, Some("L00001"), Some("L00001.Y")] {
        let mut args = vec!["diff", s(&bad), "good.exr"];
        args.extend(layer.iter().flat_map(|l| ["--layer", l]));
        let r = bounded(&d, &args, 10);
        r.refused(4, &[s(&bad), "10000 channels in 1 part(s)", "at most 1024"]);
    }
    // 1,100 parts of one channel each
    let parts: Vec<Layer<AnyChannels<FlatSamples>>> = (0..1100)
        .map(|i| {
            Layer::new(
                (2, 2),
                LayerAttributes::named(format!("part{i}").as_str()),
                Encoding::UNCOMPRESSED,
                AnyChannels::sort(
                    vec![AnyChannel::new("Y", FlatSamples::F16(vec![f16::ZERO; 4]))].into(),
                ),
            )
        })
        .collect();
    let bad = d.join("parts.exr");
    exr::prelude::Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions((2, 2))),
        parts,
    )
    .write()
    .to_file(&bad)
    .unwrap();
    let r = bounded(&d, &["diff", "good.exr", s(&bad), "--idiff-compat"], 10);
    r.refused(
        4,
        &[s(&bad), "1100 channels in 1100 part(s)", "at most 1024"],
    );
}

#[test]
fn a_png_over_the_pixel_limit_is_refused_from_its_header() {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let d = scratch("bounds-png");
    // 16384² grey, constant: 268 MB of pixels in a small file
    let side = 16384u32;
    let mut bytes = vec![];
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Best, FilterType::NoFilter)
        .write_image(
            &vec![0u8; (side * side) as usize],
            side,
            side,
            image::ExtendedColorType::L8,
        )
        .unwrap();
    assert!(bytes.len() < 2 << 20, "{} bytes", bytes.len());
    std::fs::write(d.join("big.png"), &bytes).unwrap();
    drop(bytes);
    let good = d.join("good.exr");
    let img = rayproof::images::Image::rgb(16, 16, vec![0.5; 16 * 16 * 3]);
    rayproof::images::write_exr_rgb(&good, &img).unwrap();
    let r = bounded(&d, &["diff", "good.exr", "big.png"], 10);
    r.refused(
        4,
        &["big.png", "16384×16384 pixels", "at most 67108864 (8192²)"],
    );
}

#[test]
fn an_image_must_be_a_regular_file_and_downsample_exits_4_when_it_is_unreadable() {
    let d = scratch("bounds-image-file");
    let good = d.join("good.exr");
    let img = rayproof::images::Image::rgb(16, 16, vec![0.5; 16 * 16 * 3]);
    rayproof::images::write_exr_rgb(&good, &img).unwrap();
    let r = bounded(&d, &["diff", "good.exr", "/dev/zero"], 10);
    r.refused(4, &["/dev/zero", "not a regular file"]);
    std::fs::write(d.join("text.exr"), "not an image").unwrap();
    let r = bounded(
        &d,
        &["downsample", "text.exr", "--factor", "2", "-o", "o.exr"],
        10,
    );
    r.refused(4, &["text.exr", "not an OpenEXR or PNG file"]);
}

// ---- 6. Radiance and the camera ----

#[test]
fn intensities_and_ambient_that_would_overflow_are_refused() {
    let d = scratch("bounds-radiance");
    // 1e300: 132–143 Inf pixels of 16×16, exit 0
    for (tag, text, want) in [
        (
            "intensity",
            scene(EYE, "", "[1e300, 1e300, 1e300]", SPHERE),
            "lights[0].intensity",
        ),
        (
            "ambient",
            scene(EYE, "ambient = [1e300, 1e300, 1e300]", LIGHT, SPHERE),
            "render.ambient",
        ),
    ] {
        std::fs::write(d.join("s.toml"), text).unwrap();
        let r = bounded(&d, &["render", "s.toml", "-o", "o.exr"], 10);
        r.refused(2, &["s.toml:", want, "[0, 1e30]"]);
        assert!(!d.join("o.exr").exists(), "{tag}");
    }
    // At the limit: no Inf pixel
    std::fs::write(
        d.join("s.toml"),
        scene(
            EYE,
            "ambient = [1e30, 1e30, 1e30]",
            "[1e30, 1e30, 1e30]",
            SPHERE,
        ),
    )
    .unwrap();
    let r = bounded(&d, &["render", "s.toml", "-o", "o.exr"], 10);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert_eq!(sidecar(&d.join("o.exr.json"))["nonfinite_pixels"], 0);
}

#[test]
fn a_camera_whose_frame_would_be_nan_is_refused() {
    let d = scratch("bounds-camera");
    // At 1e300, `export` wrote `right <NaN, NaN, NaN>`
    std::fs::write(
        d.join("s.toml"),
        scene("[1e300, 0.0, 5.0]", "", LIGHT, SPHERE),
    )
    .unwrap();
    let r = bounded(&d, &["export", "--to", "povray", "s.toml"], 10);
    r.refused(2, &["s.toml:2:", "camera.position[0]", "1e150"]);
    assert!(!r.stdout.contains("NaN"));
    // An up vector too short to normalise: its cross product underflows
    let tiny = scene(EYE, "", LIGHT, SPHERE).replace(
        "look_at = [0.0, 0.0, 0.0]",
        "look_at = [0.0, 0.0, 0.0]\nup = [1e-200, 1e-200, 0.0]",
    );
    std::fs::write(d.join("s.toml"), tiny).unwrap();
    let r = bounded(&d, &["export", "--to", "mitsuba", "s.toml"], 10);
    r.refused(2, &["s.toml:", "camera", "no finite view direction"]);
    // Within the limits the exported vectors are finite
    std::fs::write(
        d.join("s.toml"),
        scene("[1e150, 0.0, 5.0]", "", LIGHT, SPHERE),
    )
    .unwrap();
    let r = bounded(&d, &["export", "--to", "povray", "s.toml"], 10);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(
        !r.stdout.contains("NaN") && !r.stdout.contains("inf"),
        "{}",
        r.stdout
    );
}

// ---- 7, 8. Suite files and manifests ----

fn check(d: &Path, suite: &str) -> Run {
    std::fs::write(d.join("suite.toml"), suite).unwrap();
    bounded(
        d,
        &["check", "--suite", "suite.toml", "--json", "r.json"],
        20,
    )
}

/// A suite with one test whose command copies `ref.exr` and notes its `{spp}`.
fn copy_suite(head: &str, test: &str) -> String {
    format!(
        "[suite]\n{head}\n\n[[test]]\nname = \"t\"\ncommand = \"echo {{spp}} > spp.txt; cp ref.exr {{out}}\"\n{test}\nreference = [{{ name = \"r\", path = \"refs/ref.exr\" }}]\ngolden = false\n"
    )
}

fn references(d: &Path, grid: u64) {
    std::fs::create_dir_all(d.join("refs")).unwrap();
    let img = rayproof::images::Image::rgb(16, 16, vec![0.5; 16 * 16 * 3]);
    rayproof::images::write_exr_rgb(&d.join("ref.exr"), &img).unwrap();
    rayproof::images::write_exr_rgb(&d.join("refs/ref.exr"), &img).unwrap();
    let sha = rayproof::golden::sha256_file(&d.join("refs/ref.exr")).unwrap();
    let manifest = serde_json::json!({ "files": { "ref.exr": {
        "renderer": "test", "version": "1", "width": 16, "grid": grid, "sha256": sha,
    }}});
    std::fs::write(d.join("refs/manifest.json"), manifest.to_string()).unwrap();
}

#[test]
fn a_suite_timeout_beyond_a_week_is_refused_not_a_panic() {
    let d = scratch("bounds-timeout");
    references(&d, 4);
    // 1e20 s panicked in Duration::from_secs_f64
    let r = check(&d, &copy_suite("timeout = 1e20", ""));
    r.refused(2, &["suite.toml", "suite.timeout", "604800"]);
    let r = check(&d, &copy_suite("timeout = 604800", ""));
    assert_eq!(r.code, Some(0), "{}{}", r.stdout, r.stderr);
}

#[test]
fn a_grid_beyond_64_from_a_suite_or_a_manifest_is_refused() {
    let d = scratch("bounds-grid");
    // {spp} of a 65536 grid overflowed to 0
    references(&d, 4);
    let r = check(&d, &copy_suite("", "grid = 65536"));
    r.refused(2, &["suite.toml", "test 't'", "grid = 65536", "at most 64"]);
    assert!(!d.join("spp.txt").exists());
    let r = check(&d, &copy_suite("", "width = 65536"));
    r.refused(
        2,
        &["suite.toml", "test 't'", "width = 65536", "at most 16384"],
    );
    // From the references' manifest: the test is refused, its command never runs
    references(&d, 65536);
    let r = check(&d, &copy_suite("", ""));
    assert!(!r.timed_out);
    assert_eq!(r.code, Some(3), "{}{}", r.stdout, r.stderr);
    let report = std::fs::read_to_string(d.join("r.json")).unwrap();
    assert!(
        report.contains("grid = 65536 is not a whole number from 1 to 64"),
        "{report}"
    );
    assert!(!d.join("spp.txt").exists());
    // Within the limit the command gets grid²
    references(&d, 64);
    let r = check(&d, &copy_suite("", ""));
    assert_eq!(r.code, Some(0), "{}{}", r.stdout, r.stderr);
    assert_eq!(
        std::fs::read_to_string(d.join("spp.txt")).unwrap().trim(),
        "4096"
    );
}

#[test]
fn a_pixel_next_to_a_point_light_is_f32_max_not_inf_and_a_light_on_the_surface_is_not_nan() {
    // The centre pixel of a 15-wide image looks straight down at the plane's origin; a light
    // 1e-12 above it gives 1e30/1e-24 = 1e54, beyond f32
    let d = scratch("bounds-near-light");
    for (height, want_max) in [("1e-12", true), ("0.0", false)] {
        let text = format!(
            r#"[camera]
position = [0.0, 5.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
fov = 40.0
width = 15
height = 15

[[lights]]
position = [0.0, {height}, 0.0]
intensity = [1e30, 1e30, 1e30]

[materials.grey]
type = "diffuse"
albedo = [0.5, 0.5, 0.5]

[[shapes]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "grey"
"#
        );
        std::fs::write(d.join("s.toml"), text).unwrap();
        let r = bounded(&d, &["render", "s.toml", "-o", "o.exr"], 10);
        assert_eq!(r.code, Some(0), "{}", r.stderr);
        assert_eq!(
            sidecar(&d.join("o.exr.json"))["nonfinite_pixels"],
            0,
            "{height}"
        );
        let img = rayproof::images::read_image(&d.join("o.exr")).unwrap();
        let centre = img.data[(7 * 15 + 7) * 3];
        assert_eq!(centre == f32::MAX, want_max, "{height}: {centre}");
    }
}
