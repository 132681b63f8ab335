//! idiff's metrics, thresholds and verdict order: [`compare`] two images of the same size,
//! [`Thresholds`] (idiff's defaults, readable from TOML or JSON), the [`Verdict`], and the
//! |REF − TEST| image and heat map used without ꟻLIP. The rules are in the
//! [module documentation](crate::images).

use super::flip::FlipKind;
use super::io::{Image, LayerInfo, Window};
use super::mask::Mask;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

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
    /// idiff: at most `allowfailures` pixels fail, or neither FAILURE nor WARNING applies.
    /// The z-test: enough channel tests pass.
    Pass,
    /// idiff: not FAILURE, but more than `warnpercent` % of the pixels warn or the max error
    /// exceeds `hardwarn`. The z-test never warns.
    Warning,
    /// idiff: more than `allowfailures` pixels fail, and more than `failpercent` % of the
    /// pixels fail or the max error exceeds `hardfail`. The z-test: too few channel tests pass.
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
/// The thresholds are float32 as in idiff (`failpercent` 0.1 is 0.100000001).
pub fn verdict(n_fail: u64, n_warn: u64, max_error: f64, pixels: u64, t: &Thresholds) -> Verdict {
    let f32t = |x: f64| x as f32 as f64;
    let over = |n: u64, percent: f64| n as f64 > f32t(percent) / 100.0 * pixels as f64;
    if n_fail <= t.allowfailures {
        Verdict::Pass
    } else if over(n_fail, t.failpercent) || max_error > f32t(t.hardfail) {
        Verdict::Failure
    } else if over(n_warn, t.warnpercent) || max_error > f32t(t.hardwarn) {
        Verdict::Warning
    } else {
        Verdict::Pass
    }
}

/// The images differ in display window, channels or layer (or, where they must be stored
/// alike, in data window): exit code 3.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("size mismatch: {reference} against {test}")]
pub struct SizeMismatch {
    /// `WxH CHANNELS` of the reference, e.g. `64x48 RGB` (see [`Image::shape`]).
    pub reference: String,
    /// The same for the other image.
    pub test: String,
}

impl SizeMismatch {
    /// The documented exit code of a size or channel mismatch: 3.
    pub fn exit_code(&self) -> u8 {
        3
    }
}

/// The two images show the same frame: one display window, the same channels, and the same
/// layer (unless one of them is a file without layer names). Their data windows may differ.
pub(super) fn same_frame(a: &Image, b: &Image) -> Result<(), SizeMismatch> {
    let name = |i: &Image| {
        i.layer
            .as_ref()
            .and_then(|l| l.name.clone())
            .filter(|n| !n.is_empty())
    };
    let layers_agree = match (name(a), name(b)) {
        (Some(x), Some(y)) => x == y,
        _ => true,
    };
    if a.display == b.display && a.channels == b.channels && layers_agree {
        return Ok(());
    }
    Err(SizeMismatch {
        reference: a.shape(),
        test: b.shape(),
    })
}

/// [`same_frame`], and the same data window: the samples line up one for one.
pub(super) fn same_shape(a: &Image, b: &Image) -> Result<(), SizeMismatch> {
    same_frame(a, b)?;
    if a.data_window() == b.data_window() {
        return Ok(());
    }
    Err(SizeMismatch {
        reference: a.shape(),
        test: b.shape(),
    })
}

/// The two images stored over the union of their data windows (a pixel outside an image's
/// data window is 0, as OpenEXR defines it and idiff reads it), so that every per-pixel tool
/// ([`abs_diff`], [`z_test`](crate::images::z_test), ꟻLIP, the previews) sees them aligned.
/// Refused (exit 3) unless they show the same frame: one display window, the same channels, the
/// same layer.
/// Refused too (with [`AlignError::FarApart`]) when the union holds more than
/// `MAX_UNION_FACTOR` (2) times the pixels the two images hold (plus 2¹⁶), or more than
/// [`MAX_PIXELS`](super::MAX_PIXELS) (an 8192² image and a 1×1 window at (16383, 16383) were
/// padded to 16384², 4 GiB a channel set, found by a hostile run): padding two 1×1
/// windows far apart would allocate their whole union. The metrics ([`compare`]) need no
/// alignment; only the per-pixel products (ꟻLIP, the z-test, maps, previews) do.
/// Images already stored over one window are borrowed, not copied (two 8192² images were
/// copied whole for `diff --flip`).
pub fn align<'a>(
    reference: &'a Image,
    test: &'a Image,
) -> Result<(Cow<'a, Image>, Cow<'a, Image>), AlignError> {
    same_frame(reference, test).map_err(AlignError::Frame)?;
    let window = reference.data_window().union(&test.data_window());
    let pad = |img: &'a Image| match img.data_window() == window {
        true => Cow::Borrowed(img),
        false => Cow::Owned(img.padded(window)),
    };
    let held = reference.pixels() as u128 + test.pixels() as u128;
    let union = window.width as u128 * window.height as u128;
    if union > MAX_UNION_FACTOR as u128 * held + (1 << 16) || union > super::MAX_PIXELS as u128 {
        return Err(AlignError::FarApart {
            reference: reference.data_window(),
            test: test.data_window(),
            union,
        });
    }
    Ok((pad(reference), pad(test)))
}

/// How many times the pixels two images hold their data windows' union may hold, for
/// [`align`] to pad both to it: 2, so that at least half of a padded image is its own pixels.
/// At 4, a union three quarters empty had a black median luminance, which HDR-ꟻLIP answers
/// with some 25 exposures instead of 2: a 0.45 MB pair ran ꟻLIP for over 11 minutes (a
/// hostile run).
pub const MAX_UNION_FACTOR: u64 = 2;

/// Why two images cannot be stored over one window.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AlignError {
    /// They do not show one frame.
    #[error(transparent)]
    Frame(SizeMismatch),
    /// Their data windows are so far apart that their union is mostly empty.
    #[error("the data windows {reference} and {test} are far apart: their union holds {union} pixels, more than {MAX_UNION_FACTOR}× the pixels the images hold or 8192²; per-pixel maps (ꟻLIP, the z-test, heat map, difference image, previews) are not made over it (the metrics are)")]
    FarApart {
        /// The reference's data window.
        reference: Window,
        /// The test's.
        test: Window,
        /// The pixels of their union.
        union: u128,
    },
}

/// Every metric of one comparison.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Comparison {
    /// Width in pixels of the compared window: the union of both data windows.
    pub width: usize,
    /// Height in pixels of the compared window.
    pub height: usize,
    /// The compared window, in absolute pixel coordinates (those of `max_at`).
    pub window: Window,
    /// The reference's display window (the test's is the same, unless under idiff's semantics).
    pub display: Window,
    /// The layers read from the reference and the test (`None`: a file without layers).
    pub layers: [Option<LayerInfo>; 2],
    /// Channel names compared: the reference's, or the test's if it has more channels.
    pub channels: Vec<String>,
    /// `width × height`.
    pub pixels: u64,
    /// The pixels the percentages (printed, and `failpercent`, `warnpercent`) are of: the
    /// reference's data window, as idiff's `npels` (a cropped reference can print 156 %).
    pub npels: u64,
    /// Σ|d| / (pixels × channels), non-finite mismatches left out of the sum.
    #[serde(serialize_with = "nonfinite::ser")]
    pub mean_error: f64,
    /// sqrt(Σd² / (pixels × channels)).
    #[serde(serialize_with = "nonfinite::ser")]
    pub rms_error: f64,
    /// 20·log10(peak / RMS); infinite when RMS = 0.
    #[serde(serialize_with = "nonfinite::ser")]
    pub psnr: f64,
    /// max(1, largest finite |value| of either image).
    #[serde(serialize_with = "nonfinite::ser")]
    pub peak: f64,
    /// Σ d² / (ref² + 0.01) / (pixels × channels).
    #[serde(serialize_with = "nonfinite::ser")]
    pub rel_mse: f64,
    /// Largest |d|; infinite if some NaN/Inf mismatches.
    #[serde(serialize_with = "nonfinite::ser")]
    pub max_error: f64,
    /// (x, y, channel index) of the first largest |d|, x and y in absolute pixel coordinates
    /// (an EXR's data window at (8, 12) shifts them), as idiff reports them.
    pub max_at: (i64, i64, usize),
    /// The name of the channel at `max_at`.
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
    /// HDR or LDR ꟻLIP, when computed.
    pub flip_kind: Option<FlipKind>,
    /// Whose rules decided NaN/Inf and size mismatches.
    pub semantics: Semantics,
    /// PASS, WARNING or FAILURE under the thresholds.
    pub verdict: Verdict,
}

/// NaN against NaN, or an infinity against the same-signed infinity.
pub(super) fn same_nonfinite(a: f64, b: f64) -> bool {
    (a.is_nan() && b.is_nan()) || (a.is_infinite() && a == b)
}

/// Whose rules decide what idiff leaves to taste.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Semantics {
    /// rayproof's, stricter for CI: a NaN/Inf mismatch is a failing pixel (also +Inf against
    /// −Inf) and stays out of the sums, and one makes the verdict FAILURE whatever
    /// `failpercent` or `allowfailures` allow; images of different size or channels are refused.
    #[default]
    Rayproof,
    /// idiff 2.4's exactly (`--idiff-compat`): a NaN/Inf mismatch only sets the max error to
    /// inf the first time, the next ones enter the sums (mean, RMS, PSNR become inf or nan) and
    /// the counts; NaN matches NaN and any infinity any infinity; images of different size or
    /// channels are compared over the union, a missing pixel or channel read as 0.
    Idiff,
}

/// Compares two images of the same size and channels with idiff's rules (rayproof's
/// semantics): what `rayproof diff` computes.
///
/// ```
/// use rayproof::images::{compare, Image, Thresholds};
///
/// // Two 2×1 RGB images; one channel of one pixel differs by 0.5
/// let a = Image::new(2, 1, &["R", "G", "B"], vec![0.2; 6]);
/// let mut b = a.clone();
/// b.data[0] = 0.7;
/// let c = compare(&a, &b, &Thresholds::default()).unwrap();
/// assert_eq!(c.n_fail, 1); // |0.5| is over idiff's default fail threshold
/// assert!((c.mean_error - 0.5 / 6.0).abs() < 1e-9);
/// ```
pub fn compare(
    reference: &Image,
    test: &Image,
    t: &Thresholds,
) -> Result<Comparison, SizeMismatch> {
    compare_as(reference, test, t, Semantics::Rayproof)
}

/// Compares two images with idiff's arithmetic: each difference, its relative size and the
/// thresholds in float32 as idiff computes them (0.05 is 0.05000000075), sums in double over
/// batches of 4,096 pixels; `semantics` decides NaN/Inf and size mismatches.
// `!(x <= y)` is idiff's own NaN-aware test (true when x is NaN), kept as written
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn compare_as(
    reference: &Image,
    test: &Image,
    t: &Thresholds,
    semantics: Semantics,
) -> Result<Comparison, SizeMismatch> {
    compare_weighted(reference, test, t, semantics, None)
}

/// [`compare`] under a mask ([`Mask`]): a pixel of weight 0 is left out of every sum and count
/// (and of `pixels` and `npels`, so percentages are of the pixels compared); a pixel of weight
/// w < 1 has each |a − b| counted as w·|a − b| (its tolerances × 1/w).
pub fn compare_masked(
    reference: &Image,
    test: &Image,
    t: &Thresholds,
    mask: &Mask,
) -> Result<Comparison, SizeMismatch> {
    compare_weighted(reference, test, t, Semantics::Rayproof, Some(mask))
}

#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn compare_weighted(
    reference: &Image,
    test: &Image,
    t: &Thresholds,
    semantics: Semantics,
    mask: Option<&Mask>,
) -> Result<Comparison, SizeMismatch> {
    let idiff = semantics == Semantics::Idiff;
    if !idiff {
        same_frame(reference, test)?;
    }
    // The compared window: the union of both data windows, in absolute coordinates; a pixel
    // outside an image's data window, or a channel it lacks, is 0
    let window = reference.data_window().union(&test.data_window());
    let (w, h) = (window.width, window.height);
    let nch = reference.channels.len().max(test.channels.len());
    let value = |img: &Image, x: i64, y: i64, c: usize| img.at(x, y, c);
    let f32t = |x: f64| x as f32 as f64;
    let (fail, warn) = (f32t(t.fail), f32t(t.warn));
    let (failrel, warnrel) = (f32t(t.failrelative), f32t(t.warnrelative));

    // Accumulate Σ|d|, Σd², relMSE, the largest |d| and the warn/fail counts, pixel by pixel
    let (mut sum, mut sum2, mut rel_sum) = (0f64, 0f64, 0f64);
    let (mut batch, mut batch2) = (0f64, 0f64);
    let (mut max_error, mut max_at) = (0f64, (window.x, window.y, 0));
    let mut peak = 1f32;
    let (mut n_warn, mut n_fail, mut n_nonfinite) = (0u64, 0u64, 0u64);
    // Only the pixels a data window holds are walked (two 1×1 windows 2·10⁹ pixels apart are
    // two pixels of work, not a walk of their union). A pixel neither holds is 0 against 0:
    // it adds nothing to a sum or a count, and skipping a run of them changes no result
    // bit: the batch sums flush at most once in it (the next flushes would add 0), and only
    // idiff's NaN maximum is reset by one (`!(0 <= NaN)`), done here as its first would.
    // Indices in u128: a union of two windows of i32 coordinates can hold 2⁶⁴ pixels
    let wide = w as u128;
    let end = (wide * h as u128, 0, 0);
    let mut next = 0u128;
    // The held pixels, then the end of the window: each preceded by the run skipped before it
    for (p, x, y) in held_pixels(window, reference.data_window(), test.data_window()).chain([end]) {
        if p > next {
            if max_error.is_nan() {
                let (x, y) = ((next % wide) as i64, (next / wide) as i64);
                (max_error, max_at) = (0.0, (window.x + x, window.y + y, 0));
            }
            if p / 4096 > next / 4096 {
                (sum, sum2, batch, batch2) = (sum + batch, sum2 + batch2, 0.0, 0.0);
            }
        }
        if p == end.0 {
            break;
        }
        next = p + 1;
        // Left out by the mask: no sum, no count (the batch flush below still runs)
        let weight = mask.map_or(1.0, |m| m.weight(x, y)) as f64;
        if weight == 0.0 {
            if (p + 1) % 4096 == 0 {
                (sum, sum2, batch, batch2) = (sum + batch, sum2 + batch2, 0.0, 0.0);
            }
            continue;
        }
        let (mut warned, mut failed, mut nonfinite) = (false, false, false);
        for c in 0..nch {
            let (a, b) = (value(reference, x, y, c), value(test, x, y, c));
            // NaN and Inf
            if !a.is_finite() || !b.is_finite() {
                let same = if idiff {
                    a.is_nan() == b.is_nan() && a.is_infinite() == b.is_infinite()
                } else {
                    same_nonfinite(a as f64, b as f64)
                };
                if same {
                    continue;
                }
                nonfinite = true;
                if max_error.is_finite() || !idiff {
                    if max_error.is_finite() {
                        (max_error, max_at) = (f64::INFINITY, (x, y, c));
                    }
                    continue;
                }
                // idiff: the second mismatch and on fall through to the arithmetic
            }
            // The difference and its relative size, in float32 as idiff has them; an EXR's
            // UINT channel (an ID) under rayproof's rules exactly, as integers (in float32,
            // IDs 16777216 and 16777217 are one value)
            let exact = !idiff && (reference.is_uint(c) || test.is_uint(c));
            let (a64, b64) = if exact {
                (reference.at_exact(x, y, c), test.at_exact(x, y, c))
            } else {
                (a as f64, b as f64)
            };
            let f = if exact {
                (a64 - b64).abs()
            } else {
                (a - b).abs() as f64
            } * weight;
            let (aa, ba) = (a.abs(), b.abs());
            // OIIO's lerp(|a|, |b|, 0.5): in double, returned as float
            let meanabs = if exact {
                0.5 * a64.abs() + 0.5 * b64.abs()
            } else {
                (0.5 * aa as f64 + 0.5 * ba as f64) as f32 as f64
            };
            if aa.max(ba) > peak {
                peak = aa.max(ba);
            }
            let rel = if meanabs > 0.0 { f / meanabs } else { 0.0 };
            batch += f;
            batch2 += f * f;
            rel_sum += f * f / (a64 * a64 + 1e-2);
            if !(f <= max_error) {
                (max_error, max_at) = (f, (x, y, c));
            }
            // As idiff 2.4 counts (measured): a NaN difference never counts, an infinite one
            // does whatever its (NaN) relative size
            warned |= f > warn && !(rel <= warnrel);
            failed |= f > fail && !(rel <= failrel);
        }
        n_nonfinite += nonfinite as u64;
        // rayproof counts every NaN/Inf mismatch as warning and failing
        n_warn += (warned || (nonfinite && !idiff)) as u64;
        n_fail += (failed || (nonfinite && !idiff)) as u64;
        if (p + 1) % 4096 == 0 {
            (sum, sum2, batch, batch2) = (sum + batch, sum2 + batch2, 0.0, 0.0);
        }
    }
    (sum, sum2) = (sum + batch, sum2 + batch2);

    // Means over pixels × channels, PSNR against the peak, the verdict over the reference's
    // pixels (idiff's npels)
    // The mask's left-out pixels are not among those compared
    let (out_window, out_reference) = match mask {
        Some(m) => (
            m.counts(window).excluded,
            m.counts(reference.data_window()).excluded,
        ),
        None => (0, 0),
    };
    let pixels = (w as u128 * h as u128).min(u64::MAX as u128) as u64 - out_window;
    let n = pixels as f64 * nch as f64;
    let per = |s: f64| if n > 0.0 { s / n } else { 0.0 };
    let rms_error = per(sum2).sqrt();
    let (mx, my, mc) = max_at;
    let channels = if reference.channels.len() >= test.channels.len() {
        &reference.channels
    } else {
        &test.channels
    };
    // The pixels the percentages are of: idiff's npels, the reference's data window (fewer
    // than the compared pixels when the reference's data window is smaller: stricter)
    let npels = reference.pixels() as u64 - out_reference;
    Ok(Comparison {
        width: w,
        height: h,
        window,
        display: reference.display,
        layers: [reference.layer.clone(), test.layer.clone()],
        channels: channels.clone(),
        pixels,
        npels,
        mean_error: per(sum),
        rms_error,
        psnr: if rms_error == 0.0 {
            f64::INFINITY
        } else {
            20.0 * (peak as f64 / rms_error).log10()
        },
        peak: peak as f64,
        rel_mse: per(rel_sum),
        max_error,
        max_at,
        max_channel: channels.get(mc).cloned().unwrap_or_default(),
        max_values: (value(reference, mx, my, mc), value(test, mx, my, mc)),
        n_warn,
        n_fail,
        n_nonfinite_mismatch: n_nonfinite,
        flip_mean: None,
        flip_kind: None,
        semantics,
        // rayproof's semantics: a NaN/Inf mismatch is a failure whatever the percentages allow
        verdict: match verdict(n_fail, n_warn, max_error, npels.max(1), t) {
            _ if !idiff && n_nonfinite > 0 => Verdict::Failure,
            v => v,
        },
    })
}

/// The pixels of `window` that `a` or `b` holds, in row-major order: (index in `window`, x, y).
/// Linear in the pixels the two hold, whatever the size of `window`.
fn held_pixels(window: Window, a: Window, b: Window) -> impl Iterator<Item = (u128, i64, i64)> {
    // The row ranges, merged: each row once
    let rows = |v: Window| (v.y, v.y + v.height as i64);
    let spans = |v: [(i64, i64); 2]| {
        let [mut p, mut q] = v;
        if q.0 < p.0 {
            std::mem::swap(&mut p, &mut q);
        }
        match (p.0 >= p.1, q.0 >= q.1) {
            (true, _) => vec![q],
            (_, true) => vec![p],
            _ if q.0 <= p.1 => vec![(p.0, p.1.max(q.1))],
            _ => vec![p, q],
        }
    };
    let cols = move |y: i64| {
        let c = |v: Window| match (v.y..v.y + v.height as i64).contains(&y) {
            true => (v.x, v.x + v.width as i64),
            false => (0, 0),
        };
        spans([c(a), c(b)])
    };
    spans([rows(a), rows(b)])
        .into_iter()
        .flat_map(|(y0, y1)| y0..y1)
        .flat_map(move |y| {
            cols(y).into_iter().flat_map(move |(x0, x1)| {
                (x0..x1).map(move |x| {
                    let p = (y - window.y) as u128 * window.width as u128 + (x - window.x) as u128;
                    (p, x, y)
                })
            })
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

    /// Walking only the pixels the files hold gives every metric bit for bit as walking the
    /// whole union (the images padded to it): windows apart, overlapping and nested, with
    /// batches of 4,096 pixels crossed in the skipped runs, under both semantics, and with
    /// idiff's NaN maximum (reset by the next pixel, a skipped one included).
    #[test]
    fn the_sparse_walk_is_the_walk_of_the_union() {
        let img = |w: usize, h: usize, at: (i64, i64), k: f32| {
            let data = (0..w * h * 3)
                .map(|i| ((i as f32 * 0.37 + k).sin() * 0.5 + 0.5) * (1.0 + k))
                .collect();
            let mut m = Image::rgb(w, h, data);
            m.origin = at;
            m.display = Window::at_origin(4, 4);
            m
        };
        let mut nan = img(3, 2, (0, 0), 0.5);
        // The last pixel of its row (2, 0): G then B NaN, so that under idiff's rules the
        // maximum is NaN when the skipped run after it starts
        nan.data[7] = f32::NAN;
        nan.data[8] = f32::NAN;
        let mut nan_last = img(3, 2, (300, 50), 0.5);
        nan_last.data[16] = f32::NAN;
        nan_last.data[17] = f32::NAN;
        let cases = [
            (img(7, 5, (0, 0), 0.1), img(9, 4, (150, 90), 0.2)),
            (img(70, 50, (-3, 2), 0.1), img(40, 60, (20, 30), 0.3)),
            (img(100, 80, (0, 0), 0.1), img(10, 8, (40, 40), 0.4)),
            (img(5, 5, (200, 0), 0.6), img(5, 5, (0, 100), 0.7)),
            (nan.clone(), img(3, 2, (300, 50), 0.8)),
            (img(3, 2, (300, 50), 0.8), nan),
            // The NaN maximum at the last held pixel, only skipped pixels after it
            (img(3, 2, (400, 0), 0.9), nan_last),
        ];
        for (a, b) in cases {
            let window = a.data_window().union(&b.data_window());
            let (pa, pb) = (a.padded(window), b.padded(window));
            for sem in [Semantics::Rayproof, Semantics::Idiff] {
                let t = Thresholds::default();
                let sparse = compare_as(&a, &b, &t, sem).unwrap();
                let dense = compare_as(&pa, &pb, &t, sem).unwrap();
                let bits = |c: &Comparison| {
                    [
                        c.mean_error,
                        c.rms_error,
                        c.psnr,
                        c.rel_mse,
                        c.max_error,
                        c.peak,
                    ]
                    .map(f64::to_bits)
                };
                assert_eq!(bits(&sparse), bits(&dense), "{sem:?} {window}");
                assert_eq!(sparse.max_at, dense.max_at, "{sem:?} {window}");
                assert_eq!(
                    (sparse.n_warn, sparse.n_fail, sparse.pixels),
                    (dense.n_warn, dense.n_fail, dense.pixels)
                );
            }
        }
    }

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
