//! Render-level trade-off: each method × precision renders the hard scenes; its time is set
//! against its image error versus the f64 robust render and versus the POV-Ray reference.

use crate::images::{compare, read_image, Image, Thresholds};
use crate::numerics::timing::Timing;
use crate::render::scene::Frame;
use crate::render::{self, scene, Overrides};
use crate::shapes::sphere::methods::{Method, METHODS};
use serde::Serialize;
use std::path::Path;

/// The scenes where the methods differ visibly (far spheres, a huge floor sphere, many spheres).
pub const SCENES: [&str; 3] = ["fan30", "far", "floor"];

/// The configuration every other is compared with: the gated robust one.
pub const BASELINE: (&str, &str) = ("promote", "f64");

/// One render's cost and error.
#[derive(Clone, Debug, Serialize)]
pub struct RenderRow {
    /// Scene name.
    pub scene: String,
    /// Ray–sphere method.
    pub method: &'static str,
    /// `"f32"` or `"f64"`.
    pub precision: &'static str,
    /// Offered as robust.
    pub robust: bool,
    /// Wall seconds per frame at the timing grid (Timing's fields in seconds).
    pub seconds: Timing,
    /// Samples per pixel of the timed frames, and of the compared image.
    pub timed_spp: u32,
    /// Samples per pixel of the compared image.
    pub image_spp: u32,
    /// Rays traced in one timed frame.
    pub rays: u64,
    /// Mean |Δ| and share of pixels over 0.05 against the baseline render.
    pub vs_baseline_mean: f64,
    /// Share of pixels with a channel over 0.05 against the baseline render.
    pub vs_baseline_fail: f64,
    /// The same against POV-Ray's reference (None when the reference is missing).
    pub vs_povray_mean: Option<f64>,
    /// Share of pixels with a channel over 0.05 against POV-Ray's reference.
    pub vs_povray_fail: Option<f64>,
    /// File name of the tone-mapped PNG in the report's `img/`.
    pub png: String,
}

/// Renders every scene with every method × precision: once at the references' size and grid
/// (the image that is compared and shown, written as a PNG into `img_dir`), and `runs` times,
/// interleaved, at `time_grid`² samples per pixel for the timing (a 64-spp frame of every
/// configuration `runs` times would take minutes; time is proportional to the samples).
pub fn run(
    reference: &Path,
    img_dir: &Path,
    width: Option<u32>,
    grid: Option<u32>,
    time_grid: u32,
    runs: usize,
) -> anyhow::Result<Vec<RenderRow>> {
    let configs: Vec<(&'static Method, &'static str)> = METHODS
        .iter()
        .flat_map(|m| [(m, "f32"), (m, "f64")])
        .collect();
    let t = Thresholds {
        fail: 0.05,
        warn: 0.01,
        ..Default::default()
    };
    let mut rows = vec![];
    for name in SCENES {
        // Scene and references at their size
        let sc = scene::load(&reference.join("scenes").join(format!("{name}.toml")))?;
        let fr =
            Frame::of(&sc, width.or(Some(256)), grid.or(Some(8))).map_err(anyhow::Error::msg)?;
        let povray = read_image(&reference.join(name).join("povray.exr"))
            .ok()
            .filter(|i| i.width == fr.width as usize && i.height == fr.height as usize);
        let ov = |m: &'static Method, p: &'static str, grid: u32| Overrides {
            method: Some(m),
            precision: Some(p),
            grid: Some(grid),
            size: Some((fr.width, fr.height)),
            ..Default::default()
        };
        // The compared images
        let mut images: Vec<Option<(Image, u64)>> = configs
            .iter()
            .map(|&(m, p)| {
                let r = render::render(&sc, &ov(m, p, fr.grid));
                Some((super::seed::to_image(&r), r.counts.total()))
            })
            .collect();
        // Timed renders, interleaved
        let mut secs = vec![vec![]; configs.len()];
        for _ in 0..runs.max(1) {
            for (k, &(m, p)) in configs.iter().enumerate() {
                secs[k].push(render::render(&sc, &ov(m, p, time_grid)).seconds);
            }
        }
        let base_k = configs
            .iter()
            .position(|(m, p)| (m.name, *p) == BASELINE)
            .expect("baseline is a configuration");
        let base = images[base_k].clone().expect("rendered").0;
        for (k, &(m, p)) in configs.iter().enumerate() {
            let (img, rays) = images[k].take().expect("rendered");
            let vb = compare(&base, &img, &t)?;
            let vp = povray.as_ref().map(|r| compare(r, &img, &t)).transpose()?;
            let png = format!("{name}-{}-{p}.png", m.name);
            let rgb = crate::images::tonemap_rgb8(&img);
            crate::images::write_png_rgb8(&img_dir.join(&png), img.width, img.height, &rgb)?;
            let px = vb.pixels.max(1) as f64;
            rows.push(RenderRow {
                scene: name.into(),
                method: m.name,
                precision: p,
                robust: m.robust,
                seconds: Timing::of(secs[k].clone()),
                timed_spp: time_grid * time_grid,
                image_spp: fr.grid * fr.grid,
                rays,
                vs_baseline_mean: vb.mean_error,
                vs_baseline_fail: vb.n_fail as f64 / px,
                vs_povray_mean: vp.as_ref().map(|c| c.mean_error),
                vs_povray_fail: vp.as_ref().map(|c| c.n_fail as f64 / px),
                png,
            });
        }
        // The POV-Ray reference beside them
        if let Some(r) = &povray {
            let rgb = crate::images::tonemap_rgb8(r);
            crate::images::write_png_rgb8(
                &img_dir.join(format!("{name}-povray.png")),
                r.width,
                r.height,
                &rgb,
            )?;
        }
    }
    Ok(rows)
}
