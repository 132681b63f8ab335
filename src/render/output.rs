//! Render output: a linear float32 EXR (beauty R, G, B, plus optional `depth.Z`, `normal.X/Y/Z`,
//! `rays.Y` channels), a JSON sidecar with the statistics, and a tone-mapped PNG preview.
//! Every file is written to a temporary sibling and renamed into place.

use super::Render;
use crate::images::{exr_planes_to, png_rgb8_to, srgb8, Window};
use anyhow::Result;
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

/// Writes the EXR to `path` (a temporary file: the caller stages it, see
/// [`crate::output::Outputs`]) through the one EXR encoder, [`crate::images::exr_planes_to`]:
/// beauty `R`, `G`, `B`, then the layers asked for (a layer whose plane the render did not fill
/// is written as 0).
pub fn write_exr(r: &Render, path: &Path, layers: Layers) -> Result<()> {
    let n = r.width * r.height;
    let plane = |f: &dyn Fn(usize) -> f32| (0..n).map(f).collect::<Vec<f32>>();
    let at = |v: &[f32], i: usize| v.get(i).copied().unwrap_or(0.0);
    let normal = |i: usize, k: usize| r.normal.get(i).map_or(0.0, |v| v[k]);
    let mut planes = vec![
        ("R", plane(&|i| r.beauty[i][0])),
        ("G", plane(&|i| r.beauty[i][1])),
        ("B", plane(&|i| r.beauty[i][2])),
    ];
    if layers.depth {
        planes.push(("depth.Z", plane(&|i| at(&r.depth, i))));
    }
    if layers.normal {
        for (k, name) in ["normal.X", "normal.Y", "normal.Z"].into_iter().enumerate() {
            planes.push((name, plane(&|i| normal(i, k))));
        }
    }
    if layers.rays {
        planes.push(("rays.Y", plane(&|i| at(&r.rays, i))));
    }
    let frame = Window::at_origin(r.width, r.height);
    exr_planes_to(path, (r.width, r.height), (0, 0), frame, planes)
}

/// Writes the PNG preview (clamp, sRGB: [`crate::images::srgb8`]) to `path` (a temporary file,
/// staged by the caller).
pub fn write_png(r: &Render, path: &Path) -> Result<()> {
    let buf: Vec<u8> = r
        .beauty
        .iter()
        .flat_map(|p| p.map(|x| srgb8(x as f64)))
        .collect();
    png_rgb8_to(path, r.width, r.height, &buf)
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
