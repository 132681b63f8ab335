//! `rayproof reference SCENE --with povray,mitsuba`: references for a user's own scene, made by
//! the real POV-Ray 3.7 and Mitsuba 3 as `scripts/render-povray` and `scripts/render-mitsuba`
//! make rayproof's own. Each is exported (`render::export`), rendered with the real renderer
//! (run through `process.rs`, with a time limit), brought to the n×n sampling grid, and written
//! with its manifest entry (renderer, version, exact commands, width, grid, date, seconds, the
//! SHA-256 of the file and of the scene), which `check` reads to make the test image with the
//! same grid.
//!
//! - POV-Ray renders at n·W × n·H without anti-aliasing (the cell centres) and the n×n blocks
//!   are averaged here.
//! - Mitsuba runs the Whitted integrator of `scripts/mitsuba_whitted.py` (built into the
//!   binary), with the Python interpreter of `$RAYPROOF_MITSUBA_PYTHON` or `python3`; the
//!   scene's `grid` sets Mitsuba's stratified n×n sampler.
//!
//! Every renderer asked for is found first; a missing one is one line with how to install it
//! (exit 3) and nothing is rendered or written.
//!
//! ```sh
//! rayproof reference scenes/mine.toml --with povray,mitsuba --width 256 --grid 8
//! ```
//!
//! exports `scenes/mine.toml`, renders it with both, and writes `scenes/../mine/{povray,mitsuba}.exr`
//! with their manifest entries (`--dir` puts them elsewhere). Mitsuba's Python needs the `mitsuba`
//! package. `scripts/render-povray` and `scripts/render-mitsuba` (which also set up a Mitsuba venv
//! and libLLVM 19) run it for rayproof's own scenes.

use super::references::{sha256_file, Records};
use crate::render::{export, scene};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The Whitted integrator for Mitsuba 3 (the same file `scripts/render-mitsuba` runs).
const MITSUBA_WHITTED: &str = include_str!("../../scripts/mitsuba_whitted.py");

/// A reference renderer could not be found or failed (exit 3).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct RendererFailed(pub String);

/// What `rayproof reference` was asked to do.
pub struct Request {
    /// The scene file.
    pub scene: PathBuf,
    /// The renderers: `povray`, `mitsuba`.
    pub with: Vec<String>,
    /// Image width in pixels (default: the scene's); the height keeps the scene's aspect ratio.
    pub width: Option<u32>,
    /// `n` of the n×n sub-pixel grid (default: the scene's `camera.grid`).
    pub grid: Option<u32>,
    /// Where NAME's references go; default `DIR/NAME/` beside the scene (`reference/NAME/` for
    /// `reference/scenes/NAME.toml`).
    pub dir: Option<PathBuf>,
    /// How long one renderer may take before it is killed.
    pub timeout: Duration,
    /// Mitsuba variant (`scalar_rgb`, or `llvm_ad_rgb` with libLLVM).
    pub mitsuba_variant: String,
}

/// The directory a scene's references go to by default.
pub fn default_dir(scene: &Path) -> PathBuf {
    let name = scene.file_stem().unwrap_or_default();
    let dir = scene.parent().unwrap_or(Path::new("."));
    match dir.file_name() {
        Some(d) if d == "scenes" => dir.parent().unwrap_or(Path::new(".")).join(name),
        _ => dir.join(name),
    }
}

fn mitsuba_python() -> String {
    std::env::var("RAYPROOF_MITSUBA_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// A renderer's image fit to be a reference: the frame's size, every value finite.
fn check_reference_image(
    renderer: &str,
    img: &crate::images::Image,
    w: u32,
    h: u32,
) -> Result<(), RendererFailed> {
    if (img.width, img.height) != (w as usize, h as usize) {
        return Err(RendererFailed(format!(
            "{renderer} made a {}×{} image where the frame is {w}×{h}: not written",
            img.width, img.height
        )));
    }
    let bad = img.data.iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        return Err(RendererFailed(format!(
            "{renderer}'s image has {bad} NaN or Inf value(s): not written"
        )));
    }
    Ok(())
}

/// The renderer's version, or why it cannot run (with how to install it).
fn find(renderer: &str) -> Result<String, RendererFailed> {
    let run = |cmd: &str| {
        crate::process::run_with_timeout(
            renderer,
            cmd,
            None,
            String::new(),
            Duration::from_secs(60),
        )
    };
    match renderer {
        "povray" => {
            let out = run("povray --version 2>&1").map_err(|_| {
                RendererFailed(
                    "povray not found: install POV-Ray 3.7 (Debian: apt-get install povray)".into(),
                )
            })?;
            let v = out
                .split_whitespace()
                .skip_while(|w| *w != "POV-Ray")
                .nth(1)
                .unwrap_or("?");
            Ok(v.to_string())
        }
        "mitsuba" => {
            let py = mitsuba_python();
            run(&format!("{py} -c 'import mitsuba, numpy; print(mitsuba.__version__)'"))
                .map(|v| v.trim().to_string())
                .map_err(|_| {
                    RendererFailed(format!(
                        "mitsuba not importable by {py}: pip install mitsuba numpy (or set RAYPROOF_MITSUBA_PYTHON to a Python that has them; scripts/render-mitsuba sets one up, with libLLVM 19 for llvm_ad_rgb)"
                    ))
                })
        }
        r => Err(RendererFailed(format!(
            "unknown renderer '{r}' (known: povray, mitsuba)"
        ))),
    }
}

/// Makes the references; returns the files written.
pub fn make(req: &Request) -> Result<Vec<PathBuf>> {
    // Everything checked before anything is rendered: the scene, what it can be exported to,
    // every renderer
    let sc = scene::load(&req.scene)?;
    let mut versions = vec![];
    for r in &req.with {
        if let Some(why) = export::unsupported(&sc, r) {
            bail!("{}: cannot be exported to {r}: {why}", req.scene.display());
        }
        versions.push(find(r)?);
    }
    let fr = scene::Frame::of(&sc, req.width, req.grid).map_err(anyhow::Error::msg)?;
    let dir = req.dir.clone().unwrap_or_else(|| default_dir(&req.scene));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let scene_sha = sha256_file(&req.scene)?;
    let tmp = crate::output::ScratchDir::new("reference")?;
    let mut written = vec![];
    let mut records = Records::default();
    for (r, version) in req.with.iter().zip(versions) {
        // Export, render, bring to the grid
        let start = Instant::now();
        let shown = req.scene.display();
        let (g, w, h) = (fr.grid, fr.width, fr.height);
        let (bytes, commands, renderer, version) = match r.as_str() {
            "povray" => {
                std::fs::write(tmp.0.join("scene.pov"), export::povray(&sc, fr))?;
                let cmd = format!(
                    "povray +Iscene.pov +Obig.exr +FE +W{} +H{} -A -D -V -GA +WT{}",
                    w * g,
                    h * g,
                    std::thread::available_parallelism()
                        .map(|n| n.get())
                        .unwrap_or(1)
                );
                crate::process::run_with_timeout(
                    "povray",
                    &cmd,
                    Some(&tmp.0),
                    String::new(),
                    req.timeout,
                )
                .map_err(RendererFailed)?;
                let big = crate::images::read_image(&tmp.0.join("big.exr"))
                    .map_err(|e| RendererFailed(format!("povray's image: {e}")))?;
                let img = export::downsample(&big, g as usize)?;
                let out = tmp.0.join("povray.exr");
                check_reference_image("povray", &img, w, h)?;
                crate::images::write_exr_rgb(&out, &img)?;
                let commands = vec![
                    format!("rayproof export --to povray {shown} --width {w} --grid {g} > scene.pov"),
                    cmd,
                    format!("rayproof downsample big.exr --factor {g} -o povray.exr (done by rayproof reference)"),
                ];
                (std::fs::read(out)?, commands, "POV-Ray", version)
            }
            _ => {
                std::fs::write(tmp.0.join("scene.xml"), export::mitsuba(&sc, fr))?;
                std::fs::write(tmp.0.join("mitsuba_whitted.py"), MITSUBA_WHITTED)?;
                let v = &req.mitsuba_variant;
                let cmd = format!(
                    "{} mitsuba_whitted.py scene.xml mitsuba.exr --variant {v}",
                    mitsuba_python()
                );
                crate::process::run_with_timeout(
                    "mitsuba",
                    &cmd,
                    Some(&tmp.0),
                    String::new(),
                    req.timeout,
                )
                .map_err(RendererFailed)?;
                let file = tmp.0.join("mitsuba.exr");
                let bytes = std::fs::read(&file)
                    .map_err(|e| RendererFailed(format!("mitsuba wrote no image: {e}")))?;
                let img = crate::images::read_image(&file)
                    .map_err(|e| RendererFailed(format!("mitsuba's image: {e}")))?;
                check_reference_image("mitsuba", &img, w, h)?;
                let commands = vec![
                    format!(
                        "rayproof export --to mitsuba {shown} --width {w} --grid {g} > scene.xml"
                    ),
                    format!(
                        "python scripts/mitsuba_whitted.py scene.xml mitsuba.exr --variant {v}"
                    ),
                ];
                (bytes, commands, "Mitsuba 3", format!("{version} {v}"))
            }
        };
        // The file and its manifest entry
        let path = dir.join(format!("{r}.exr"));
        let entry = serde_json::json!({
            "renderer": renderer,
            "version": version,
            "commands": commands,
            "width": w,
            "grid": g,
            "samples_per_pixel": g * g,
            "seconds": (start.elapsed().as_secs_f64() * 100.0).round() / 100.0,
            "scene_sha256": scene_sha,
            "written_by": format!("rayproof {} reference", env!("CARGO_PKG_VERSION")),
        });
        records.add(&path, bytes, entry, Some(&req.scene));
        written.push(path);
    }
    // Every reference and the manifest together, never over the scene
    let mut out = crate::output::Outputs::new().reading(&[&req.scene]);
    records.stage(&mut out)?;
    out.commit()?;
    Ok(written)
}
