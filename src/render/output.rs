//! Render output: a linear float32 EXR (beauty R, G, B, plus optional `depth.Z`, `normal.X/Y/Z`,
//! `rays.Y` channels), a JSON sidecar with the statistics, and a tone-mapped PNG preview.
//! Every file is written to a temporary sibling and renamed into place.

use super::Render;
use anyhow::{Context, Result};
use exr::prelude::*;
use std::path::Path;

/// Which extra EXR layers to write.
#[derive(Clone, Copy, Debug, Default)]
pub struct Layers {
    /// Write the depth layer (`Z`).
    pub depth: bool,
    /// Write the normal layer (`N.X`, `N.Y`, `N.Z`).
    pub normal: bool,
    /// Write the rays-per-pixel layer.
    pub rays: bool,
}

/// The files of one render: the EXR with its JSON sidecar (paths), the PNG preview, the EXR's
/// extra layers.
pub struct Files<'a> {
    /// The EXR and its sidecar.
    pub exr: Option<(&'a Path, &'a Path)>,
    /// The PNG preview.
    pub png: Option<&'a Path>,
    /// Extra EXR layers.
    pub layers: Layers,
}

/// Writes a render's files together: all of them, or none replaced (staged by
/// [`crate::output::Outputs`], never over one of `inputs`). `scene` and `lights` go in the sidecar.
pub fn write_all(
    r: &Render,
    files: &Files,
    scene: &str,
    lights: usize,
    inputs: &[&Path],
) -> Result<()> {
    let mut out = crate::output::Outputs::new().reading(inputs);
    if let Some((exr, side)) = files.exr {
        out.write_with(exr, |tmp| write_exr(r, tmp, files.layers))?;
        let stats = stats_json(r, scene, lights);
        out.write(
            side,
            (serde_json::to_string_pretty(&stats)? + "\n").as_bytes(),
        )?;
    }
    if let Some(png) = files.png {
        out.write_with(png, |tmp| write_png(r, tmp))?;
    }
    out.commit()
}

/// Writes the EXR to `path` (a temporary file: the caller stages it, see [`crate::output::Outputs`]).
/// The samples are read from the planes as the encoder asks for each pixel (no copy per channel).
pub fn write_exr(r: &Render, path: &Path, layers: Layers) -> Result<()> {
    let ch = |name: &str| ChannelDescription::named(name, SampleType::F32);
    let opt = |on: bool, name: &str| on.then(|| ch(name));
    let channels = (
        ch("R"),
        ch("G"),
        ch("B"),
        opt(layers.depth, "depth.Z"),
        opt(layers.normal, "normal.X"),
        opt(layers.normal, "normal.Y"),
        opt(layers.normal, "normal.Z"),
        opt(layers.rays, "rays.Y"),
    );
    // A layer's plane is empty when the render did not fill it; its channel is then not written
    let at = |v: &[f32], i: usize| v.get(i).copied().unwrap_or(0.0);
    let pixel = |p: Vec2<usize>| {
        let i = p.y() * r.width + p.x();
        let [cr, cg, cb] = r.beauty[i];
        let [nx, ny, nz] = r.normal.get(i).copied().unwrap_or([0.0; 3]);
        (cr, cg, cb, at(&r.depth, i), nx, ny, nz, at(&r.rays, i))
    };
    let layer = Layer::new(
        (r.width, r.height),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        SpecificChannels::new(channels, pixel),
    );
    // Compressed on this thread: the parallel writer starts a thread pool per file, whose
    // threads cost more CPU than they save on a frame, and it writes the blocks in whatever
    // order they finish (a different file each run)
    Ok(Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_file(path)?)
}

/// sRGB transfer of a linear value clamped to [0, 1].
fn srgb(x: f32) -> u8 {
    let x = x.clamp(0.0, 1.0);
    let v = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0 + 0.5) as u8
}

/// Writes the PNG preview (clamp, sRGB) to `path` (a temporary file, staged by the caller).
pub fn write_png(r: &Render, path: &Path) -> Result<()> {
    let buf: Vec<u8> = r.beauty.iter().flat_map(|p| p.map(srgb)).collect();
    let img =
        image::RgbImage::from_raw(r.width as u32, r.height as u32, buf).context("image size")?;
    Ok(img.save_with_format(path, image::ImageFormat::Png)?)
}

/// The statistics as JSON (also written beside the EXR as `<file>.json`).
pub fn stats_json(r: &Render, scene: &str, lights: usize) -> serde_json::Value {
    serde_json::json!({
        "scene": scene,
        "width": r.width,
        "height": r.height,
        "method": r.method,
        "precision": r.precision,
        "effects": r.effects,
        "rays": r.counts,
        "total_rays": r.counts.total(),
        // Pixels with NaN or Inf in R, G or B: 0 for every valid scene (tests/hostile.rs)
        "nonfinite_pixels": r.beauty.iter().filter(|p| p.iter().any(|v| !v.is_finite())).count(),
        "seconds": r.seconds,
        "budget": super::budget_line(r, lights),
    })
}
