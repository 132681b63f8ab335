//! idiff's metrics, thresholds and verdict order: [`compare`] two images of the same size,
//! [`Thresholds`] (idiff's defaults, readable from TOML or JSON), the [`Verdict`], and the
//! |REF − TEST| image and heat map used without ꟻLIP. The rules are in the
//! [module documentation](crate::images).

use super::flip::FlipKind;
use super::io::Image;
use serde::{Deserialize, Serialize};

/// Serde for `f64`s that may be infinite: JSON has no `inf`, so non-finite values are written
/// as the strings `"inf"`, `"-inf"`, `"nan"`; numbers and those strings are both read back.
mod nonfinite {
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn ser<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        match *v {
            v if v.is_finite() => s.serialize_f64(v),
            v if v.is_nan() => s.serialize_str("nan"),
            v if v > 0.0 => s.serialize_str("inf"),
            _ => s.serialize_str("-inf"),
        }
    }

    pub fn ser_pair<S: Serializer>(v: &(f32, f32), s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        struct F(f64);
        impl serde::Serialize for F {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                ser(&self.0, s)
            }
        }
        let mut t = s.serialize_tuple(2)?;
        t.serialize_element(&F(v.0 as f64))?;
        t.serialize_element(&F(v.1 as f64))?;
        t.end()
    }

    pub fn de<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum F {
            N(f64),
            S(String),
        }
        match F::deserialize(d)? {
            F::N(x) => Ok(x),
            F::S(s) => s
                .parse()
                .map_err(|_| D::Error::custom(format!("'{s}' is not a number"))),
        }
    }
}

/// idiff's thresholds; [`Default`] gives idiff's defaults. In TOML or JSON any subset of the
/// fields may be given (the rest keep their defaults); `"inf"` is accepted for infinity.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Thresholds {
    /// A channel fails if |a−b| exceeds this…
    #[serde(serialize_with = "nonfinite::ser", deserialize_with = "nonfinite::de")]
    pub fail: f64,
    /// …and |a−b| / mean(|a|, |b|) exceeds this.
    #[serde(serialize_with = "nonfinite::ser", deserialize_with = "nonfinite::de")]
    pub failrelative: f64,
    /// FAILURE needs more than this percentage of pixels failing (or `hardfail`).
    #[serde(serialize_with = "nonfinite::ser", deserialize_with = "nonfinite::de")]
    pub failpercent: f64,
    /// FAILURE if the max error exceeds this (unless nfail ≤ `allowfailures`).
    #[serde(serialize_with = "nonfinite::ser", deserialize_with = "nonfinite::de")]
    pub hardfail: f64,
    /// PASS whenever at most this many pixels fail.
    pub allowfailures: u64,
    /// A channel warns if |a−b| exceeds this…
    #[serde(serialize_with = "nonfinite::ser", deserialize_with = "nonfinite::de")]
    pub warn: f64,
    /// …and |a−b| / mean(|a|, |b|) exceeds this.
    #[serde(serialize_with = "nonfinite::ser", deserialize_with = "nonfinite::de")]
    pub warnrelative: f64,
    /// WARNING needs more than this percentage of pixels warning (or `hardwarn`).
    #[serde(serialize_with = "nonfinite::ser", deserialize_with = "nonfinite::de")]
    pub warnpercent: f64,
    /// WARNING if the max error exceeds this.
    #[serde(serialize_with = "nonfinite::ser", deserialize_with = "nonfinite::de")]
    pub hardwarn: f64,
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            fail: 1e-6,
            failrelative: 0.0,
            failpercent: 0.0,
            hardfail: f64::INFINITY,
            allowfailures: 0,
            warn: 1e-6,
            warnrelative: 0.0,
            warnpercent: 0.0,
            hardwarn: f64::INFINITY,
        }
    }
}

impl Thresholds {
    /// Every threshold must be a non-negative number (infinity allowed).
    pub fn validate(&self) -> Result<(), String> {
        let all = [
            ("fail", self.fail),
            ("failrelative", self.failrelative),
            ("failpercent", self.failpercent),
            ("hardfail", self.hardfail),
            ("warn", self.warn),
            ("warnrelative", self.warnrelative),
            ("warnpercent", self.warnpercent),
            ("hardwarn", self.hardwarn),
        ];
        match all.iter().find(|(_, v)| v.is_nan() || *v < 0.0) {
            Some((name, v)) => Err(format!("{name} = {v} is not a non-negative number")),
            None => Ok(()),
        }
    }
}

/// The outcome of a comparison.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    Pass,
    Warning,
    Failure,
}

impl Verdict {
    /// 0, 1, 2.
    pub fn exit_code(self) -> u8 {
        self as u8
    }

    /// `PASS`, `WARNING`, `FAILURE`.
    pub fn label(self) -> &'static str {
        ["PASS", "WARNING", "FAILURE"][self as usize]
    }
}

/// idiff's verdict, in idiff's order (see the [module documentation](crate::images)).
pub fn verdict(n_fail: u64, n_warn: u64, max_error: f64, pixels: u64, t: &Thresholds) -> Verdict {
    let over = |n: u64, percent: f64| n as f64 > percent / 100.0 * pixels as f64;
    if n_fail <= t.allowfailures {
        Verdict::Pass
    } else if over(n_fail, t.failpercent) || max_error > t.hardfail {
        Verdict::Failure
    } else if over(n_warn, t.warnpercent) || max_error > t.hardwarn {
        Verdict::Warning
    } else {
        Verdict::Pass
    }
}

/// The images differ in width, height or channels (exit code 3).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("size mismatch: {reference} against {test}")]
pub struct SizeMismatch {
    /// `WxH CHANNELS` of the reference, e.g. `64x48 RGB`.
    pub reference: String,
    /// The same for the other image.
    pub test: String,
}

impl SizeMismatch {
    pub fn exit_code(&self) -> u8 {
        3
    }
}

pub(super) fn same_shape(a: &Image, b: &Image) -> Result<(), SizeMismatch> {
    if a.width == b.width && a.height == b.height && a.channels == b.channels {
        return Ok(());
    }
    Err(SizeMismatch {
        reference: a.shape(),
        test: b.shape(),
    })
}

/// Every metric of one comparison.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Comparison {
    pub width: usize,
    pub height: usize,
    pub channels: Vec<String>,
    pub pixels: u64,
    /// Σ|d| / (pixels × channels), non-finite mismatches left out of the sum.
    pub mean_error: f64,
    /// sqrt(Σd² / (pixels × channels)).
    pub rms_error: f64,
    /// 20·log10(peak / RMS); infinite when RMS = 0.
    #[serde(serialize_with = "nonfinite::ser")]
    pub psnr: f64,
    /// max(1, largest finite |value| of either image).
    pub peak: f64,
    /// Σ d² / (ref² + 0.01) / (pixels × channels).
    pub rel_mse: f64,
    /// Largest |d|; infinite if some NaN/Inf mismatches.
    #[serde(serialize_with = "nonfinite::ser")]
    pub max_error: f64,
    /// (x, y, channel index) of the first largest |d|.
    pub max_at: (usize, usize, usize),
    pub max_channel: String,
    /// Reference and test values there.
    #[serde(serialize_with = "nonfinite::ser_pair")]
    pub max_values: (f32, f32),
    /// Pixels with some channel over the warn thresholds.
    pub n_warn: u64,
    /// Pixels with some channel over the fail thresholds.
    pub n_fail: u64,
    /// Pixels with NaN/Inf in one image where the other differs (also in `n_warn`, `n_fail`).
    pub n_nonfinite_mismatch: u64,
    /// Mean ꟻLIP, when computed (filled in by the caller: [`flip_error`](crate::images::flip_error)).
    pub flip_mean: Option<f64>,
    pub flip_kind: Option<FlipKind>,
    pub verdict: Verdict,
}

/// NaN against NaN, or an infinity against the same-signed infinity.
pub(super) fn same_nonfinite(a: f64, b: f64) -> bool {
    (a.is_nan() && b.is_nan()) || (a.is_infinite() && a == b)
}

/// Compares two images of the same size and channels with idiff's rules.
pub fn compare(
    reference: &Image,
    test: &Image,
    t: &Thresholds,
) -> Result<Comparison, SizeMismatch> {
    same_shape(reference, test)?;
    let nch = reference.channels.len();
    let pixels = reference.pixels();
    // Find the peak for PSNR: the largest finite |value| of either image, at least 1
    let peak = reference
        .data
        .iter()
        .chain(&test.data)
        .filter(|v| v.is_finite())
        .fold(1f64, |m, &v| m.max(v.abs() as f64));

    // Accumulate Σ|d|, Σd², relMSE, the largest |d| and the warn/fail counts, pixel by pixel
    let (mut sum, mut sum2, mut rel) = (0f64, 0f64, 0f64);
    let (mut max_error, mut max_i) = (0f64, 0usize);
    let (mut n_warn, mut n_fail, mut n_nonfinite) = (0u64, 0u64, 0u64);
    for p in 0..pixels {
        let (mut warned, mut failed, mut nonfinite) = (false, false, false);
        for i in p * nch..(p + 1) * nch {
            let (a, b) = (reference.data[i] as f64, test.data[i] as f64);
            // |d|, infinite for a NaN/Inf mismatch
            let d = if a.is_finite() && b.is_finite() {
                (a - b).abs()
            } else if same_nonfinite(a, b) {
                0.0
            } else {
                nonfinite = true;
                f64::INFINITY
            };
            if d > max_error {
                (max_error, max_i) = (d, i);
            }
            if !d.is_finite() || d == 0.0 {
                continue;
            }
            sum += d;
            sum2 += d * d;
            rel += d * d / (a * a + 1e-2);
            // rel = |d| / mean(|a|, |b|); here d > 0, so the mean is > 0
            let r = d / ((a.abs() + b.abs()) / 2.0);
            warned |= d > t.warn && r > t.warnrelative;
            failed |= d > t.fail && r > t.failrelative;
        }
        n_nonfinite += nonfinite as u64;
        n_warn += (warned || nonfinite) as u64;
        n_fail += (failed || nonfinite) as u64;
    }

    // Compute the means, PSNR and the place of the largest |d|
    let n = (pixels * nch) as f64;
    let per = |s: f64| if n > 0.0 { s / n } else { 0.0 };
    let rms_error = per(sum2).sqrt();
    let (max_x, max_y, max_c) = match nch {
        0 => (0, 0, 0),
        _ => (
            (max_i / nch) % reference.width,
            max_i / nch / reference.width,
            max_i % nch,
        ),
    };
    Ok(Comparison {
        width: reference.width,
        height: reference.height,
        channels: reference.channels.clone(),
        pixels: pixels as u64,
        mean_error: per(sum),
        rms_error,
        psnr: if rms_error == 0.0 {
            f64::INFINITY
        } else {
            20.0 * (peak / rms_error).log10()
        },
        peak,
        rel_mse: per(rel),
        max_error,
        max_at: (max_x, max_y, max_c),
        max_channel: reference.channels.get(max_c).cloned().unwrap_or_default(),
        max_values: (
            reference.data.get(max_i).copied().unwrap_or(0.0),
            test.data.get(max_i).copied().unwrap_or(0.0),
        ),
        n_warn,
        n_fail,
        n_nonfinite_mismatch: n_nonfinite,
        flip_mean: None,
        flip_kind: None,
        verdict: verdict(n_fail, n_warn, max_error, pixels as u64, t),
    })
}

/// |REF − TEST| per channel (0 where NaN meets NaN or Inf the same Inf; Inf for other
/// non-finite mismatches), scene-linear.
pub fn abs_diff(reference: &Image, test: &Image) -> Result<Image, SizeMismatch> {
    same_shape(reference, test)?;
    let data = reference
        .data
        .iter()
        .zip(&test.data)
        .map(|(&a, &b)| match (a - b).abs() {
            d if d.is_nan() && same_nonfinite(a as f64, b as f64) => 0.0,
            d if d.is_nan() => f32::INFINITY,
            d => d,
        })
        .collect();
    Ok(Image {
        data,
        display_referred: false,
        ..reference.clone()
    })
}

/// Per pixel: the largest channel |d| × 16, clamped to [0, 1] (1 for a NaN/Inf mismatch) —
/// the heat map used without ꟻLIP, like Blender's `idiff … --mulc 16`.
pub fn abs_error_map(reference: &Image, test: &Image) -> Result<Vec<f32>, SizeMismatch> {
    let d = abs_diff(reference, test)?;
    let n = d.channels.len().max(1);
    Ok(d.data
        .chunks(n)
        .map(|p| (p.iter().fold(0f32, |m, &v| m.max(v)) * 16.0).min(1.0))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_serde_accepts_partial_and_inf() {
        let t: Thresholds = serde_json::from_str(r#"{"fail": 0.01, "hardfail": "inf"}"#).unwrap();
        assert_eq!(t.fail, 0.01);
        assert_eq!(t.hardfail, f64::INFINITY);
        assert_eq!(t.warn, 1e-6);
        let back: Thresholds =
            serde_json::from_str(&serde_json::to_string(&Thresholds::default()).unwrap()).unwrap();
        assert_eq!(back, Thresholds::default());
        assert!(serde_json::from_str::<Thresholds>(r#"{"fial": 1}"#).is_err());
        // A TOML table (as `rayproof check` reads): native inf, integers for floats
        let t: Thresholds = toml::from_str("fail = 1\nhardwarn = inf\nallowfailures = 3").unwrap();
        assert_eq!(
            (t.fail, t.hardwarn, t.allowfailures),
            (1.0, f64::INFINITY, 3)
        );
        assert_eq!(t.failpercent, 0.0);
        assert!(Thresholds {
            fail: -1.0,
            ..Default::default()
        }
        .validate()
        .is_err());
        assert!(Thresholds::default().validate().is_ok());
    }
}
