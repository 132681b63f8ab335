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

/// A fresh scratch directory for one test: `rayproof-test-TAG-PID` under the temp directory.
pub fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rayproof-test-{tag}-{}", std::process::id()));
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
