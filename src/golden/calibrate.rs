//! `check --calibrate N`: thresholds learned from a Monte Carlo renderer's own noise.
//!
//! A test whose renderer command takes `{seed}` is rendered N times, with seeds 1 to N. The
//! golden becomes the per-pixel mean of the N renders, and beside it `NAME.variance.exr` holds
//! the variance of a fresh render's difference from that mean: the unbiased sample variance s²
//! of one render, times (1 + 1/N) for the golden's own noise. The golden's manifest entry
//! records the calibration (renders, seeds, the variance file and its SHA-256), and from then on
//! `check` judges the golden comparison with the noise-aware z-test on that variance: per pixel,
//! Student's t with N − 1 degrees of freedom (a variance estimated from N renders), and a
//! mean-shift test over the whole image (a shift of the mean is a regression, noise is not).
//!
//! Calibration also proposes idiff thresholds for a team that keeps them instead (printed, never
//! written): from the leave-one-out residuals r = (xᵢ − mean)·N/(N − 1) (render i against the
//! mean of the others), `fail` = the 99.9th percentile over pixels of the largest channel |r|,
//! `failpercent` = 0.5 (five times the 0.1 % of pixels over `fail` among the calibration's own
//! renders), `max_mean` = twice the largest mean |r| of one render.
//!
//! Nothing is written unless every render of every test asked for succeeded and is finite; the
//! goldens, the variance images and their manifest entries are committed together.

use super::references::{bless, Blessing, Records};
use super::{formats, make, sources, Frame, Made, Suite, Test};
use crate::images::{self, Image};
use anyhow::{bail, Result};
use std::path::{Path, PathBuf};

pub use super::references::MAX_RENDERS;

/// What one test's calibration made.
#[derive(Debug)]
pub struct Calibrated {
    /// The test.
    pub test: String,
    /// How many renders (seeds 1 to `renders`).
    pub renders: u32,
    /// The golden written: the renders' mean.
    pub golden: PathBuf,
    /// The variance image written beside it.
    pub variance: PathBuf,
    /// The proposed idiff thresholds: `fail`, `failpercent`, `max_mean`.
    pub proposal: (f64, f64, f64),
    /// The largest per-pixel standard deviation of one render, and the median.
    pub sigma: (f64, f64),
}

pub use super::suite::variance_path;

/// Whether a test can be calibrated: a renderer command with `{seed}` and an OpenEXR golden.
fn calibratable(t: &Test) -> Result<&Path, String> {
    let command = match &t.source {
        super::Source::Command(c) => c,
        _ => return Err("its image is not made by a renderer command".into()),
    };
    if !command.contains("{seed}") {
        return Err(format!(
            "its command '{command}' has no {{seed}}: N renders with one seed are one render"
        ));
    }
    match &t.golden {
        Some((g, _)) if formats::Format::of_path(g) == Some(formats::Format::Exr) => Ok(g),
        Some((g, _)) => Err(format!(
            "its golden {} is not OpenEXR: the mean of N renders is kept in float",
            g.display()
        )),
        None => Err("it has no golden".into()),
    }
}

/// Calibrates the selected tests (every test when `names` is empty). `Err`: bad usage (exit 2).
/// `Ok(Err(line))`: a render failed or was not finite (exit 3), nothing staged.
pub fn calibrate(
    suite: &Suite,
    names: &[String],
    renders: u32,
    outputs: &mut crate::output::Outputs,
) -> Result<Result<Vec<Calibrated>, String>> {
    if !(2..=MAX_RENDERS).contains(&renders) {
        bail!("--calibrate {renders}: give from 2 to {MAX_RENDERS} renders (a variance needs two)");
    }
    let tests: Vec<&Test> = suite
        .tests
        .iter()
        .filter(|t| names.is_empty() || names.contains(&t.name))
        .collect();
    for n in names {
        if !suite.tests.iter().any(|t| &t.name == n) {
            bail!("no test '{n}' in {}", suite.path.display());
        }
    }
    // A test skipped on this platform is not rendered: named, it is an error; else left out
    let platform = suite.platform.as_deref().unwrap_or_default();
    for t in &tests {
        if let (Some(why), false) = (&t.skip, names.is_empty()) {
            bail!(
                "--calibrate: test '{}' is skipped on platform {platform}: {why}",
                t.name
            );
        }
    }
    let tests: Vec<&Test> = tests.into_iter().filter(|t| t.skip.is_none()).collect();
    for t in &tests {
        if let Err(why) = calibratable(t) {
            bail!("--calibrate: test '{}': {why}", t.name);
        }
    }
    let scratch = crate::output::ScratchDir::new("calibrate")?;
    let mut records = Records::default();
    let mut done = vec![];
    for t in tests {
        let golden = calibratable(t).map_err(anyhow::Error::msg)?.to_path_buf();
        let now = match sources(t) {
            Ok(s) => s,
            Err(e) => return Ok(Err(format!("test '{}': {e}", t.name))),
        };
        let frame = Frame {
            width: t.width,
            height: t.height,
            grid: t.grid,
        };
        // N renders, each checked as a test image is, and finite
        let mut made: Vec<Made> = vec![];
        for seed in 1..=renders as u64 {
            let (m, _, tail) = make(suite, t, frame, &scratch.0, seed);
            let m = match m {
                Ok(m) => m,
                Err(e) => {
                    let tail = tail.map(|t| format!(" ({})", t.replace('\n', " | ")));
                    return Ok(Err(format!(
                        "test '{}', seed {seed}: {e}{}",
                        t.name,
                        tail.unwrap_or_default()
                    )));
                }
            };
            let bad = super::nonfinite_pixels(&m.image);
            if bad > 0 {
                return Ok(Err(format!(
                    "test '{}', seed {seed}: {bad} pixels with NaN or Inf: a calibration is of finite renders",
                    t.name
                )));
            }
            if let Some(first) = made.first() {
                let (a, b) = (&first.image, &m.image);
                if a.shape() != b.shape() || a.data_window() != b.data_window() {
                    return Ok(Err(format!(
                        "test '{}': seed {seed} made a {} image, seed 1 a {}",
                        t.name,
                        b.shape(),
                        a.shape()
                    )));
                }
            }
            made.push(m);
        }
        let imgs: Vec<&Image> = made.iter().map(|m| &m.image).collect();
        let (mean, variance, proposal, sigma) = statistics(&imgs);
        // Renders that never vary calibrate nothing ({seed} without effect); sums past the
        // float range are no variance either
        if variance.data.iter().all(|&v| v == 0.0) {
            return Ok(Err(format!(
                "test '{}': the {renders} renders are identical at every pixel: its renderer ignores {{seed}}, so there is no noise to learn",
                t.name
            )));
        }
        let bad = mean
            .data
            .iter()
            .chain(&variance.data)
            .filter(|v| !v.is_finite())
            .count();
        if bad > 0 {
            return Ok(Err(format!(
                "test '{}': {bad} samples of the mean or variance overflow float32 (renders of ±3e38?): not a noise to learn",
                t.name
            )));
        }
        // The golden (the mean) and the variance, as EXR bytes
        let bytes = |img: &Image, name: &str| -> Result<Vec<u8>> {
            let p = scratch.0.join(name);
            images::exr_to(&p, img)?;
            Ok(std::fs::read(&p)?)
        };
        let var_path = variance_path(&golden);
        let mean_bytes = bytes(&mean, "mean.exr")?;
        let var_bytes = bytes(&variance, "variance.exr")?;
        let var_name = var_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let sha = super::references::sha256_bytes(&var_bytes);
        let first = &made[0];
        let b = Blessing {
            renderer: suite.name.clone(),
            command: first.command.clone(),
            width: frame.width.or(Some(first.image.width as u32)),
            height: frame.height.or(Some(first.image.height as u32)),
            grid: frame.grid,
            sources: now,
            calibration: Some(serde_json::json!({
                "renders": renders,
                "seeds": format!("1..{renders}"),
                "variance": var_name,
                "variance_sha256": sha,
                "what": "golden = mean of the renders; variance = s² of one render × (1 + 1/renders)",
            })),
        };
        bless(&mut records, &golden, mean_bytes, &b)?;
        let var_entry = Blessing {
            calibration: Some(serde_json::json!({
                "variance_of": golden.file_name().map(|n| n.to_string_lossy().into_owned()),
                "renders": renders,
            })),
            ..b
        };
        bless(&mut records, &var_path, var_bytes, &var_entry)?;
        done.push(Calibrated {
            test: t.name.clone(),
            renders,
            golden,
            variance: var_path,
            proposal,
            sigma,
        });
    }
    records.stage(outputs)?;
    Ok(Ok(done))
}

/// The mean image, the variance of a fresh render against it, the proposed thresholds
/// (`fail`, `failpercent`, `max_mean`) and (largest, median) per-sample σ, of N ≥ 2 images of
/// one shape.
fn statistics(imgs: &[&Image]) -> (Image, Image, (f64, f64, f64), (f64, f64)) {
    let n = imgs.len() as f64;
    let first = imgs[0];
    let len = first.data.len();
    // Mean and unbiased variance per sample, in f64 (two passes: exact enough and simple)
    let mut mean = vec![0f64; len];
    for img in imgs {
        for (m, v) in mean.iter_mut().zip(&img.data) {
            *m += *v as f64 / n;
        }
    }
    let mut var = vec![0f64; len];
    for img in imgs {
        for ((s, m), v) in var.iter_mut().zip(&mean).zip(&img.data) {
            let d = *v as f64 - m;
            *s += d * d / (n - 1.0);
        }
    }
    let with = |data: Vec<f32>| Image {
        data,
        ..first.clone()
    };
    let mean_img = with(mean.iter().map(|&m| m as f32).collect());
    let var_img = with(var.iter().map(|&s| (s * (1.0 + 1.0 / n)) as f32).collect());
    // Leave-one-out residuals: render i against the mean of the others
    let nc = first.channels.len().max(1);
    let loo = n / (n - 1.0);
    let mut per_pixel: Vec<f64> = vec![];
    let mut worst_mean = 0f64;
    for img in imgs {
        let mut sum = 0f64;
        for (px, vals) in img.data.chunks(nc).enumerate() {
            let mut big = 0f64;
            for (c, v) in vals.iter().enumerate() {
                let r = ((*v as f64) - mean[px * nc + c]).abs() * loo;
                sum += r;
                big = big.max(r);
            }
            per_pixel.push(big);
        }
        worst_mean = worst_mean.max(sum / len.max(1) as f64);
    }
    per_pixel.sort_by(f64::total_cmp);
    let q = |f: f64| per_pixel[((per_pixel.len() - 1) as f64 * f).round() as usize];
    let mut sig: Vec<f64> = var.iter().map(|s| s.sqrt()).collect();
    sig.sort_by(f64::total_cmp);
    let sigma = (
        sig.last().copied().unwrap_or(0.0),
        sig.get(sig.len() / 2).copied().unwrap_or(0.0),
    );
    (mean_img, var_img, (q(0.999), 0.5, 2.0 * worst_mean), sigma)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_variance_are_the_renders_own() {
        let a = Image::new(2, 1, &["Y"], vec![1.0, 0.0]);
        let b = Image::new(2, 1, &["Y"], vec![3.0, 0.0]);
        let (m, v, _, sigma) = statistics(&[&a, &b]);
        assert_eq!(m.data, [2.0, 0.0]);
        // s² = ((1-2)² + (3-2)²)/1 = 2, times 1 + 1/2
        assert_eq!(v.data, [3.0, 0.0]);
        assert_eq!(sigma.0, 2f64.sqrt());
    }
}
