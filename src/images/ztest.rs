//! The noise-aware z-test of Mitsuba 3 (`src/render/tests/test_renders.py`): a test image with
//! a per-pixel variance passes if its differences from the reference are plausible noise.

use super::io::Image;
use super::mask::Mask;
use super::metrics::{same_nonfinite, same_shape, SizeMismatch, Verdict};
use serde::Serialize;

/// The complementary error function, Numerical Recipes' `erfcc` (Press et al., *Numerical
/// Recipes in C*, 2nd ed., §6.2): a Chebyshev fit with fractional error below 1.2·10⁻⁷
/// everywhere, including the far tail where p-values live.
pub fn erfc(x: f64) -> f64 {
    const C: [f64; 10] = [
        -1.265_512_23,
        1.000_023_68,
        0.374_091_96,
        0.096_784_18,
        -0.186_288_06,
        0.278_868_07,
        -1.135_203_98,
        1.488_515_87,
        -0.822_152_23,
        0.170_872_77,
    ];
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = C.iter().rev().fold(0.0, |acc, &c| c + t * acc);
    let r = t * (-z * z + poly).exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Šidák-corrected per-test significance: 1 − (1 − significance)^(1/tests).
pub fn sidak_alpha(significance: f64, tests: u64) -> f64 {
    -((-significance).ln_1p() / tests.max(1) as f64).exp_m1()
}

/// Settings of the z-test.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ZParams {
    /// Samples per pixel of the test image; the variance image is then the per-sample
    /// variance. With 1, the variance image is the variance of the test pixel itself.
    pub spp: u64,
    /// Family-wise significance level, Šidák-corrected over the pixels.
    pub significance: f64,
    /// Fraction of pixels (counted as passing channels / channels) that must pass.
    pub pixel_success_rate: f64,
    /// Degrees of freedom of the variance: 0 when it is known (a renderer's own estimate over
    /// many samples: z is normal), k when it is a sample variance of k + 1 renders
    /// (`check --calibrate`: the statistic is then Student's t with k degrees of freedom, so a
    /// variance estimated from few renders does not fail pixels whose estimate came out small).
    pub dof: u64,
    /// Family-wise significance of the mean-shift test (Šidák-corrected over the channels). Per
    /// channel, each pixel's signed statistic w·(test − ref)/sqrt(var/spp), clamped to ±4 so that
    /// a few outliers (fireflies: the per-pixel test's business) cannot move it, is summed over
    /// the n pixels and divided by sqrt(n·v), where v bounds the clamped statistic's variance
    /// under noise alone (1 for a normal z; min(16, k/(k − 2)) for Student's t with k degrees of
    /// freedom). Under independent noise the sum is symmetric about 0 with variance ≤ n·v, so
    /// the result is at most standard normal (the central limit theorem; conservative); a shift
    /// of the whole image's mean (a regression the per-pixel test misses when each pixel's noise
    /// is larger than the shift) moves it by shift/σ·sqrt(n/v).
    pub shift_significance: f64,
}

impl Default for ZParams {
    fn default() -> Self {
        ZParams {
            spp: 1,
            significance: 0.01,
            pixel_success_rate: 0.9975,
            dof: 0,
            shift_significance: 1e-6,
        }
    }
}

/// The z-test's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ZTest {
    /// Significance, pixel success rate and samples per pixel used.
    pub params: ZParams,
    /// Channels tested: the reference's channels that the variance image also has.
    pub channels: Vec<String>,
    /// Pixels tested.
    pub pixels: u64,
    /// Per-channel significance after the Šidák correction.
    pub alpha: f64,
    /// The smallest p-value over all pixels and channels.
    pub min_p: f64,
    /// (x, y, channel index into `channels`) of the first smallest p-value, x and y in
    /// absolute pixel coordinates (as the comparison's `max_at`).
    pub min_p_at: (i64, i64, usize),
    /// The name of the channel with the smallest p-value.
    pub min_p_channel: String,
    /// Pixels with some channel's p ≤ alpha, or beyond noise.
    pub failing_pixels: u64,
    /// Pixels no noise explains: a NaN/Inf mismatch, a difference in a channel the variance
    /// does not cover (alpha), or (calibrated) a change where the renders never varied: any one
    /// fails the test, whatever the success rate allows.
    pub beyond_noise: u64,
    /// Channel tests with p > alpha.
    pub passing_channels: u64,
    /// The mean-shift statistic of each tested channel (`channels`' order), at most standard
    /// normal under noise alone ([`ZParams::shift_significance`]).
    pub shift_z: Vec<f64>,
    /// The smallest two-sided p-value of `shift_z`.
    pub shift_p: f64,
    /// The mean-shift test's per-channel significance after the Šidák correction; the image's
    /// mean has shifted beyond its noise when `shift_p` ≤ this.
    pub shift_alpha: f64,
    /// PASS or FAILURE (the z-test has no warning): enough pixels pass, nothing is beyond noise,
    /// and no channel's mean shifted.
    pub verdict: Verdict,
    /// Per pixel of the reference's data window, row by row: whether it is one of
    /// `failing_pixels` (what the report draws as the failing pixels when the z-test decides).
    #[serde(skip)]
    pub failing_map: Vec<bool>,
}

/// Why a z-test could not be run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ZTestError {
    /// The test image, or the variance, is not the reference's size and channels.
    #[error("{0}")]
    Size(#[from] SizeMismatch),
    /// A variance sample is NaN, infinite or negative: no variance, so no test (an infinite
    /// variance would make every difference plausible noise).
    #[error("{count} variance samples are NaN, infinite or negative (the first, {value}, at ({x}, {y}) {channel})")]
    Variance {
        /// How many samples of the tested channels.
        count: u64,
        /// The first one's value.
        value: f32,
        /// Its position (absolute, as the reports give pixels).
        x: i64,
        /// Its row.
        y: i64,
        /// Its channel.
        channel: String,
    },
}

/// Per pixel and channel, z = |test − ref| · sqrt(spp / max(var, 10⁻⁴)) and p = 2(1 − Φ(z)) =
/// erfc(z/√2) (with a calibrated variance, `dof` > 0: var as it is, p from Student's t, and a
/// change where var = 0 is beyond noise); a channel passes if p > α = 1 − (1 − significance)^(1/pixels), and the test
/// passes if passing channels / channels ≥ success rate × pixels. NaN against NaN (or the same
/// Inf) passes; any other NaN/Inf in the images fails.
/// A variance sample of a tested channel that is NaN, infinite or negative refuses the test
/// ([`ZTestError::Variance`]).
pub fn z_test(
    reference: &Image,
    test: &Image,
    variance: &Image,
    p: &ZParams,
) -> Result<ZTest, ZTestError> {
    z_test_masked(reference, test, variance, p, None)
}

/// [`z_test`] under a mask: a pixel of weight 0 is not tested (nor counted among the pixels the
/// Šidák correction and the success rate are of), a pixel of weight w < 1 has its z times w.
pub fn z_test_masked(
    reference: &Image,
    test: &Image,
    variance: &Image,
    p: &ZParams,
    mask: Option<&Mask>,
) -> Result<ZTest, ZTestError> {
    same_shape(reference, test)?;
    // Pair each channel of the reference (alpha only if the variance has it) with the variance's
    let var_idx: Option<Vec<(usize, usize)>> = reference
        .channels
        .iter()
        .enumerate()
        .filter(|(_, c)| *c != "A" || variance.channels.contains(c))
        .map(|(i, c)| {
            variance
                .channels
                .iter()
                .position(|v| v == c)
                .map(|j| (i, j))
        })
        .collect();
    let idx = match var_idx {
        Some(v) if variance.data_window() == reference.data_window() => v,
        _ => {
            return Err(SizeMismatch {
                reference: reference.shape(),
                test: variance.shape(),
            }
            .into())
        }
    };
    // A variance is finite and non-negative, every sample tested
    let nv = variance.channels.len();
    let mut bad: Option<(u64, f32, usize, usize)> = None;
    for px in 0..variance.pixels() {
        for &(_, j) in &idx {
            let v = variance.data[px * nv + j];
            if !(v.is_finite() && v >= 0.0) {
                let b = bad.get_or_insert((0, v, px, j));
                b.0 += 1;
            }
        }
    }
    if let Some((count, value, px, j)) = bad {
        let (x, y) = (px % variance.width, px / variance.width);
        return Err(ZTestError::Variance {
            count,
            value,
            x: variance.origin.0 + x as i64,
            y: variance.origin.1 + y as i64,
            channel: variance.channels[j].clone(),
        });
    }
    // Test every pixel and channel against the Šidák-corrected significance
    let (nr, nv) = (reference.channels.len(), variance.channels.len());
    let pixels =
        reference.pixels() as u64 - mask.map_or(0, |m| m.counts(reference.data_window()).excluded);
    let alpha = sidak_alpha(p.significance, pixels);
    let weight_of = |px: usize| {
        let (x, y) = (px % reference.width, px / reference.width);
        mask.map_or(1.0, |m| {
            m.weight(reference.origin.0 + x as i64, reference.origin.1 + y as i64) as f64
        })
    };
    let (mut min_p, mut min_at) = (f64::INFINITY, (reference.origin.0, reference.origin.1, 0));
    let (mut failing_pixels, mut passing) = (0u64, 0u64);
    // The mean-shift sums of clamped statistics and their counts, per tested channel
    const CLAMP: f64 = 4.0;
    let mut shift = vec![(0f64, 0u64); idx.len()];
    let null_variance = match p.dof {
        0 => 1.0,
        1 | 2 => CLAMP * CLAMP,
        k => (k as f64 / (k as f64 - 2.0)).min(CLAMP * CLAMP),
    };
    let students = (p.dof > 0).then(|| {
        statrs::distribution::StudentsT::new(0.0, 1.0, p.dof as f64)
            .expect("a positive number of degrees of freedom")
    });
    // What no noise explains, whatever the success rate allows: a NaN/Inf mismatch, and any
    // difference in a channel the variance does not cover (alpha without a variance for it)
    let untested: Vec<usize> = (0..nr)
        .filter(|i| !idx.iter().any(|&(c, _)| c == *i))
        .collect();
    let mut beyond_noise = 0u64;
    let mut failing_map = vec![false; reference.pixels()];
    for px in 0..reference.pixels() {
        let weight = weight_of(px);
        if weight == 0.0 {
            continue;
        }
        let mut failed = false;
        let mut beyond = untested.iter().any(|&i| {
            let (r, t) = (reference.data[px * nr + i], test.data[px * nr + i]);
            r != t && !same_nonfinite(r as f64, t as f64)
        });
        for (k, &(i, j)) in idx.iter().enumerate() {
            let (r, t) = (
                reference.data[px * nr + i] as f64,
                test.data[px * nr + i] as f64,
            );
            let var = variance.data[px * nv + j] as f64;
            // A sample variance of renders (dof > 0) is taken as it is: where the renders did
            // not vary at all, any change is beyond their noise (Mitsuba's floor of 10⁻⁴, a
            // σ of 0.01, let a calibrated pixel with no noise change by 0.1)
            let calibrated_flat = p.dof > 0 && var == 0.0;
            let pv = if calibrated_flat && r.is_finite() && t.is_finite() {
                shift[k].1 += 1;
                if t == r {
                    1.0
                } else {
                    beyond = true;
                    0.0
                }
            } else if r.is_finite() && t.is_finite() {
                let var = if p.dof > 0 { var } else { var.max(1e-4) };
                let z = (t - r).abs() * (p.spp as f64 / var).sqrt() * weight;
                let signed = (t - r) * (p.spp as f64 / var).sqrt() * weight;
                shift[k].0 += signed.clamp(-CLAMP, CLAMP);
                shift[k].1 += 1;
                match &students {
                    Some(st) => {
                        use statrs::distribution::ContinuousCDF;
                        (2.0 * st.sf(z)).min(1.0)
                    }
                    None => erfc(z / std::f64::consts::SQRT_2).min(1.0), // the fit gives 1 + 3e-8 at 0
                }
            } else if same_nonfinite(r, t) {
                1.0
            } else {
                beyond = true;
                0.0
            };
            if pv < min_p {
                let (x, y) = (px % reference.width, px / reference.width);
                let (x, y) = (reference.origin.0 + x as i64, reference.origin.1 + y as i64);
                (min_p, min_at) = (pv, (x, y, k));
            }
            if pv > alpha {
                passing += 1;
            } else {
                failed = true;
            }
        }
        failing_pixels += (failed || beyond) as u64;
        failing_map[px] = failed || beyond;
        beyond_noise += beyond as u64;
    }
    // Pass if enough channel tests pass
    let channels: Vec<String> = idx
        .iter()
        .map(|&(i, _)| reference.channels[i].clone())
        .collect();
    let shift_z: Vec<f64> = shift
        .iter()
        .map(|&(s, n)| match n {
            0 => 0.0,
            n => s / (n as f64 * null_variance).sqrt(),
        })
        .collect();
    let shift_p = shift_z
        .iter()
        .map(|z| erfc(z.abs() / std::f64::consts::SQRT_2).min(1.0))
        .fold(1.0, f64::min);
    let shift_alpha = sidak_alpha(p.shift_significance, channels.len() as u64);
    let ok = beyond_noise == 0
        && shift_p > shift_alpha
        && passing as f64 / channels.len().max(1) as f64 >= p.pixel_success_rate * pixels as f64;
    Ok(ZTest {
        params: *p,
        min_p_channel: channels.get(min_at.2).cloned().unwrap_or_default(),
        channels,
        pixels,
        alpha,
        min_p: if min_p.is_finite() { min_p } else { 1.0 },
        min_p_at: min_at,
        failing_pixels,
        beyond_noise,
        passing_channels: passing,
        shift_z,
        shift_p,
        shift_alpha,
        failing_map,
        verdict: if ok { Verdict::Pass } else { Verdict::Failure },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erfc_is_accurate_to_nr_bound() {
        // Reference values: Python's math.erfc (correctly rounded to a few ulps)
        let refs = [
            (0.0, 1.0),
            (0.1, 0.8875370839817152),
            (0.5, 0.4795001221869535),
            (1.0, 0.15729920705028513),
            (2.0, 0.004677734981047265),
            (3.0, 2.2090496998585438e-05),
            (4.0, 1.541725790028002e-08),
            (5.0, 1.5374597944280351e-12),
            (6.0, 2.1519736712498916e-17),
            (8.0, 1.1224297172982928e-29),
            (10.0, 2.088487583762545e-45),
        ];
        for (x, want) in refs {
            let rel = (erfc(x) - want).abs() / want;
            assert!(rel < 1.2e-7, "erfc({x}) = {} vs {want}: rel {rel}", erfc(x));
            // erfc(−x) = 2 − erfc(x)
            let neg = erfc(-x);
            assert!(
                (neg - (2.0 - want)).abs() < 1e-7 * 2.0,
                "erfc(-{x}) = {neg}"
            );
        }
    }

    #[test]
    fn few_renders_judge_with_students_t_not_the_normal() {
        // One pixel 5 σ off among 100: the normal p (5.7e-7) is under α = 1.0e-4 (fails),
        // Student's t with 3 degrees of freedom gives p = 0.015 (within the noise of a variance
        // estimated from 4 renders)
        let r = Image::new(100, 1, &["Y"], vec![0.5; 100]);
        let mut t = r.clone();
        t.data[7] += 5.0;
        let v = Image::new(100, 1, &["Y"], vec![1.0; 100]);
        let p = |dof| ZParams {
            dof,
            pixel_success_rate: 1.0,
            ..Default::default()
        };
        let normal = z_test(&r, &t, &v, &p(0)).unwrap();
        let students = z_test(&r, &t, &v, &p(3)).unwrap();
        assert_eq!((normal.failing_pixels, students.failing_pixels), (1, 0));
        assert!((students.min_p - 0.0154).abs() < 1e-3, "{}", students.min_p);
    }

    #[test]
    fn a_change_where_calibration_renders_never_varied_is_beyond_noise() {
        // 100 pixels of noise σ = 0.1, one whose renders never varied (variance 0): a change of
        // 1e-3 there fails a calibrated test (Mitsuba's floor of 1e-4 let 0.1 through)
        let r = Image::new(100, 1, &["Y"], vec![0.5; 100]);
        let mut v = Image::new(100, 1, &["Y"], vec![0.01; 100]);
        v.data[3] = 0.0;
        let mut t = r.clone();
        t.data[3] += 1e-3;
        let p = ZParams {
            dof: 7,
            ..Default::default()
        };
        let z = z_test(&r, &t, &v, &p).unwrap();
        assert_eq!((z.beyond_noise, z.verdict), (1, Verdict::Failure));
        // Unchanged there: a pass
        assert_eq!(z_test(&r, &r, &v, &p).unwrap().verdict, Verdict::Pass);
    }

    #[test]
    fn sidak_alpha_matches_direct_formula() {
        let direct = |s: f64, n: u64| 1.0 - (1.0 - s).powf(1.0 / n as f64);
        for n in [1, 100, 4096] {
            let a = sidak_alpha(0.01, n);
            assert!(
                (a - direct(0.01, n)).abs() < 1e-12 * a.max(1e-300) + 1e-15,
                "{n}"
            );
        }
        assert!((sidak_alpha(0.01, 1) - 0.01).abs() < 1e-15);
        // For many tests the direct formula cancels; α ≈ −ln(1 − s)/n stays accurate
        let n = 1u64 << 40;
        let approx = -(0.99f64).ln() / n as f64;
        assert!((sidak_alpha(0.01, n) / approx - 1.0).abs() < 1e-9);
    }
}
