//! What the integration tests share: running the binary, scratch directories, building the C
//! routines under `tests/outside/`.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `rayproof ARGS` (in `dir` when given) and returns its output.
pub fn rayproof_in(dir: Option<&Path>, args: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rayproof"));
    c.args(args);
    if let Some(d) = dir {
        c.current_dir(d);
    }
    c.output().expect("the rayproof binary runs")
}

/// Runs `rayproof ARGS` and returns its output.
pub fn rayproof(args: &[&str]) -> Output {
    rayproof_in(None, args)
}

/// Standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A fresh scratch directory for one test: `rayproof-test-FILE-TAG-PID` under the temp
/// directory, `FILE` the calling test file's name: every test file runs in this one process,
/// at once, so a tag is only unique within its file.
#[track_caller]
pub fn scratch(tag: &str) -> PathBuf {
    let file = Path::new(std::panic::Location::caller().file());
    let stem = file.file_stem().unwrap_or_default().to_string_lossy();
    let d = std::env::temp_dir().join(format!("rayproof-test-{stem}-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A scratch directory removed when it goes out of scope (for tests that leave nothing behind).
pub struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A fresh scratch directory as [`scratch`] makes it, removed on drop.
#[track_caller]
pub fn temp_dir(tag: &str) -> TempDir {
    TempDir(scratch(tag))
}

/// A path as `&str`.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

/// Builds `tests/outside/SRC` as a shared library in `dir` with the system C compiler.
pub fn build_library(src: &str, dir: &Path) -> PathBuf {
    let name = Path::new(src)
        .file_stem()
        .unwrap()
        .to_string_lossy()
        .into_owned();
    let lib = dir.join(format!("lib{name}.so"));
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/outside")
        .join(src);
    let o = Command::new("cc")
        .args(["-O2", "-shared", "-fPIC"])
        .arg(&path)
        .arg("-o")
        .arg(&lib)
        .arg("-lm")
        .output()
        .expect("a C compiler (cc)");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    lib
}

/// `tests/outside/FILE` as an absolute path.
pub fn outside(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/outside")
        .join(file)
}

/// Runs the test `name` (its path in the test binary, e.g. `reproducers::every_…`) in a process
/// of its own and returns false; returns true in that process. For a test that measures its
/// children's peak memory (a child forked from this process starts with this process's
/// resident set, which in the one test binary is every running test's), or that makes its
/// process the subreaper of what it starts. The test's output is printed here.
pub fn in_own_process(name: &str) -> bool {
    const KEY: &str = "RAYPROOF_TEST_IN_OWN_PROCESS";
    if std::env::var(KEY).as_deref() == Ok(name) {
        return true;
    }
    let o = Command::new(std::env::current_exe().unwrap())
        .args([name, "--exact", "--nocapture", "--test-threads", "1"])
        .env(KEY, name)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    print!("{text}");
    assert!(
        o.status.success() && text.contains("1 passed"),
        "{name} in a process of its own:\n{text}"
    );
    false
}

/// Writes a one-part EXR: `w × h` float channels (name, one value per pixel or a plane) with
/// its data window at `origin` in the display window `display` ((x, y), (w, h)).
pub fn write_exr(
    path: &Path,
    (w, h): (usize, usize),
    origin: (i32, i32),
    display: ((i32, i32), (usize, usize)),
    channels: &[(&str, Vec<f32>)],
) {
    use exr::prelude::*;
    let list: Vec<AnyChannel<FlatSamples>> = channels
        .iter()
        .map(|(n, v)| {
            let plane = if v.len() == 1 {
                vec![v[0]; w * h]
            } else {
                v.clone()
            };
            assert_eq!(plane.len(), w * h);
            AnyChannel::new(*n, FlatSamples::F32(plane))
        })
        .collect();
    let attributes = LayerAttributes {
        layer_position: Vec2(origin.0, origin.1),
        ..Default::default()
    };
    let layer = Layer::new(
        (w, h),
        attributes,
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(list.into()),
    );
    let display = IntegerBounds::new(Vec2(display.0 .0, display.0 .1), display.1);
    exr::prelude::Image::new(ImageAttributes::new(display), layer)
        .write()
        .to_file(path)
        .unwrap();
}
