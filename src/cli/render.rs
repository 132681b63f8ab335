//! `rayproof render`, `export` and `downsample`.

use super::*;
use anyhow::{Context, Result};
use clap::Args;
use rayproof::numerics::Precision;
use rayproof::shapes::sphere::methods::Method;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output EXR (linear float32); a JSON sidecar with the statistics goes beside it.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Tone-mapped PNG preview.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Ray–sphere method (overrides render.method).
    #[arg(long, value_parser = parse_method)]
    pub method: Option<&'static Method>,
    /// f32 or f64 (overrides render.precision).
    #[arg(long, value_parser = parse_precision)]
    pub precision: Option<Precision>,
    /// Samples per pixel, a square n² (overrides camera.grid = n).
    #[arg(long, value_parser = parse_spp)]
    pub spp: Option<u32>,
    /// Image width; the height keeps the scene's aspect ratio (overrides camera.width/height).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: Option<u32>,
    /// Print the chosen effects and why, then render.
    #[arg(long)]
    pub explain: bool,
    /// Turn every effect on (to measure what specialisation saves).
    #[arg(long)]
    pub all_effects: bool,
    /// Test every object for every ray (no BVH), as seed 000's 1996 renderer did.
    #[arg(long)]
    pub flat: bool,
    /// Extra EXR layers: depth, normal, rays (comma-separated).
    #[arg(long, value_delimiter = ',', value_parser = ["depth", "normal", "rays"])]
    pub layers: Vec<String>,
}

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Target renderer: povray or mitsuba.
    #[arg(long = "to", value_parser = ["povray", "mitsuba"])]
    pub to: String,
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Image width (the height keeps the scene's aspect ratio); default: the scene's.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: Option<u32>,
    /// n×n sub-pixel grid; default: the scene's camera.grid.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub grid: Option<u32>,
}

#[derive(Args, Debug)]
pub struct DownsampleArgs {
    /// Input EXR (R, G, B; any sample type).
    pub input: PathBuf,
    /// Block size n: the output is (W/n)×(H/n), each pixel the mean of an n×n block.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub factor: u32,
    /// Output EXR (float32 R, G, B).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

pub(super) fn run_render(a: RenderArgs) -> Result<u8> {
    use rayproof::render::{self, output, scene};
    let sc = scene::load(&a.scene)?;
    // Refuse before rendering if an output cannot be written, is named twice or is an input
    let side = a
        .output
        .as_ref()
        .map(|o| PathBuf::from(format!("{}.json", o.display())));
    let inputs = sc.files();
    let inputs: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    let files: Vec<&Path> = [&a.output, &side, &a.png]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    rayproof::output::check_outputs(&files, &[], &inputs)?;
    // The size and grid asked for, within the documented limits
    let fr = rayproof::render::scene::Frame::of(&sc, a.width, a.spp).map_err(anyhow::Error::msg)?;
    let ov = render::Overrides {
        method: a.method,
        precision: a.precision.map(|p| p.name()),
        grid: a.spp,
        size: a.width.map(|_| (fr.width, fr.height)),
        force_all_effects: a.all_effects,
        progress: std::io::stderr().is_terminal(),
        flat: a.flat,
        // The depth, normal and rays planes are only written as EXR layers
        beauty_only: a.output.is_none() || a.layers.is_empty(),
        ..Default::default()
    };
    let r = render::render(&sc, &ov);
    if a.explain {
        say!("effects for {}:", a.scene.display());
        for line in &r.effects.reasons {
            say!("  {line}");
        }
    }
    let lights = sc.file.lights.len() + sc.file.directional.len();
    say_raw!("{}", render::summary(&r, lights));
    // The EXR, its sidecar and the PNG: all written, or none replaced
    let layers = output::Layers {
        depth: a.layers.iter().any(|l| l == "depth"),
        normal: a.layers.iter().any(|l| l == "normal"),
        rays: a.layers.iter().any(|l| l == "rays"),
    };
    let files = output::Files {
        exr: a.output.as_deref().zip(side.as_deref()),
        png: a.png.as_deref(),
        layers,
    };
    output::write_all(&r, &files, &a.scene.display().to_string(), lights, &inputs)?;
    Ok(0)
}

pub(super) fn run_export(e: ExportArgs) -> Result<u8> {
    let sc = rayproof::render::scene::load(&e.scene)?;
    let fr =
        rayproof::render::scene::Frame::of(&sc, e.width, e.grid).map_err(anyhow::Error::msg)?;
    if let Some(why) = rayproof::render::export::unsupported(&sc, &e.to) {
        anyhow::bail!("{}: {why}", e.scene.display());
    }
    say_raw!(
        "{}",
        match e.to.as_str() {
            "povray" => rayproof::render::export::povray(&sc, fr),
            _ => rayproof::render::export::mitsuba(&sc, fr),
        }
    );
    Ok(0)
}

pub(super) fn run_downsample(d: DownsampleArgs) -> Result<u8> {
    rayproof::output::check_outputs(&[&d.output], &[], &[&d.input])?;
    let big = rayproof::images::read_image(&d.input)?;
    let small = rayproof::render::export::downsample(&big, d.factor as usize)
        .with_context(|| d.input.display().to_string())?;
    rayproof::images::write_exr_rgb(&d.output, &small)?;
    let (w, h) = (small.width, small.height);
    say!(
        "{}: {w}×{h} (mean of {f}×{f} blocks)",
        d.output.display(),
        f = d.factor
    );
    Ok(0)
}
