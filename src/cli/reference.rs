//! `rayproof reference SCENE --with povray,mitsuba`: references for your own scene, made by the
//! real renderers, with a manifest entry each (see [`rayproof::golden::renderers`]).
//!
//! Exit codes: 0 written; 2 bad usage or a scene that cannot be exported; 3 a renderer is
//! missing (one line saying how to install it; nothing rendered) or failed (nothing written for
//! it).

use super::*;
use anyhow::Result;
use clap::Args;
use rayproof::golden::renderers::{make, Request};
use std::path::PathBuf;
use std::time::Duration;

#[derive(Args, Debug)]
pub struct ReferenceArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// The renderers: povray, mitsuba (comma-separated).
    #[arg(long, value_delimiter = ',', required = true, value_parser = ["povray", "mitsuba"])]
    pub with: Vec<String>,
    /// Image width (the height keeps the scene's aspect ratio) [default: the scene's].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: Option<u32>,
    /// n×n sub-pixel grid, recorded in the manifest [default: the scene's camera.grid].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub grid: Option<u32>,
    /// Directory for NAME's references [default: DIR/NAME beside DIR/NAME.toml, reference/NAME
    /// for reference/scenes/NAME.toml].
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Seconds one renderer may take before it is killed.
    #[arg(long, default_value_t = 3600.0)]
    pub timeout: f64,
    /// Mitsuba variant (llvm_ad_rgb needs libLLVM; scalar_rgb intersects in float64).
    #[arg(long, default_value = "scalar_rgb")]
    pub mitsuba_variant: String,
}

pub(super) fn run_reference(a: ReferenceArgs) -> Result<u8> {
    // At most a week, as a suite's timeout (1e20 did not fit a Duration: a panic)
    let most = rayproof::golden::suite::MAX_TIMEOUT;
    if !(a.timeout > 0.0 && a.timeout <= most) {
        anyhow::bail!("--timeout must be a positive number of seconds, at most {most} (one week)");
    }
    let req = Request {
        scene: a.scene,
        with: a.with,
        width: a.width,
        grid: a.grid,
        dir: a.dir,
        timeout: Duration::from_secs_f64(a.timeout),
        mitsuba_variant: a.mitsuba_variant,
    };
    for p in make(&req)? {
        say!("wrote {} (and its manifest entry)", p.display());
    }
    Ok(0)
}
