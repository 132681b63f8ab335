//! `rayproof diff REF TEST`: image comparison with OpenImageIO `idiff`'s semantics, plus relMSE,
//! HDR-ꟻLIP and an optional noise-aware per-pixel z-test.
//!
//! Exit codes of `rayproof diff`:
//! - 0: PASS
//! - 1: WARNING
//! - 2: FAILURE; also bad usage (clap errors exit 2 in this binary, like every rayproof
//!   command), an output directory that does not exist, or an output that cannot be written
//! - 3: the images, or the variance image, differ in width, height or channels
//! - 4: an input file is unreadable: missing, empty, truncated, corrupt, or not OpenEXR/PNG
//!
//! Errors are one line on stderr, `error: …`, naming the file.
//!
//! The metrics and the verdict follow `idiff` (OIIO `idiff.cpp`, `imagebufalgo_compare.cpp`):
//! a pixel fails if any channel has |a−b| > `fail` and |a−b|/mean(|a|,|b|) > `failrelative`;
//! the verdict is PASS if nfail ≤ `allowfailures`, else FAILURE if nfail > `failpercent`% of
//! the pixels or the max error > `hardfail`, else WARNING if nwarn > `warnpercent`% or the max
//! error > `hardwarn`, else PASS.
//!
//! Deliberate differences from `idiff`:
//! - images of different width, height or channel count are refused (exit 3), not compared
//!   over the union of their data windows;
//! - +Inf against −Inf is a mismatch (NaN = NaN and Inf = Inf of the same sign stay equal);
//!   a non-finite mismatch counts as a warning as well as a failure, and is left out of the
//!   mean, RMS and relMSE sums (whose denominators stay pixels × channels);
//! - the report is always printed in full; its `Max error` line shows the one channel's two
//!   values, with enough digits to reproduce them;
//! - `--diff-exr` writes |REF − TEST| whenever asked, even for identical images;
//! - only the first layer/part of an EXR and its `R`, `G`, `B` (and `A`) channels are read;
//!   PNGs are kept display-referred (code value / 255 or / 65535), not linearised;
//! - additions: relMSE, mean ꟻLIP, the z-test, `--json`, `--heatmap`.
//!
//! Additions:
//! - relMSE = mean over pixels × channels of d² / (ref² + 0.01);
//! - mean ꟻLIP ([`flip_error`]): HDR-ꟻLIP for scene-linear input, LDR-ꟻLIP when both images
//!   are PNGs; both go through nv-flip's 8-bit input, so differences under one sRGB code value
//!   can vanish. A PNG compared with an EXR is compared as stored, with a note;
//! - `--variance VAR.exr [--spp N]`: Mitsuba's z-test ([`z_test`]); the variance is the
//!   per-sample variance when N > 1, the variance of the test pixel itself when N = 1 (the
//!   default). The verdict is then the z-test's, PASS or FAILURE;
//! - `--heatmap`: magma map of the ꟻLIP error, or with `--no-flip` of the largest channel
//!   |d| × 16 clamped to 1 (like Blender's `idiff … --mulc 16`);
//! - `--json FILE`: the comparison, thresholds and z-test; `--json -` prints the JSON on
//!   stdout instead of the text report. JSON has no infinity: `"inf"` stands for it.
//!
//! Output files are written to a temporary sibling and renamed into place; their directories
//! are checked before any image is read.

use serde::{Deserialize, Serialize};
use std::cell::Cell;
use std::io::Write;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// Images
// ---------------------------------------------------------------------------------------------

/// A decoded image: interleaved `f32` samples, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    /// `R`, `G`, `B`, and `A` if present.
    pub channels: Vec<String>,
    /// `width × height × channels.len()` samples.
    pub data: Vec<f32>,
    /// True for PNG: samples are display-referred code values / 255 (or / 65535).
    pub display_referred: bool,
}

impl Image {
    /// A scene-linear image; panics if `data` does not hold `width × height × channels` samples.
    pub fn new(width: usize, height: usize, channels: &[&str], data: Vec<f32>) -> Image {
        assert_eq!(
            data.len(),
            width * height * channels.len(),
            "image data size"
        );
        Image {
            width,
            height,
            channels: channels.iter().map(|c| c.to_string()).collect(),
            data,
            display_referred: false,
        }
    }

    /// A scene-linear RGB image.
    pub fn rgb(width: usize, height: usize, data: Vec<f32>) -> Image {
        Image::new(width, height, &["R", "G", "B"], data)
    }

    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// `4x3 RGBA`.
    fn shape(&self) -> String {
        format!("{}x{} {}", self.width, self.height, self.channels.concat())
    }

    /// Indices of R, G, B (by name; else the first channels).
    fn rgb_indices(&self) -> [usize; 3] {
        let last = self.channels.len().saturating_sub(1);
        let by_name = |n: &str, k: usize| {
            self.channels
                .iter()
                .position(|c| c == n)
                .unwrap_or(k.min(last))
        };
        [by_name("R", 0), by_name("G", 1), by_name("B", 2)]
    }
}

/// An input image that cannot be used (exit code 4).
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// Missing, empty, truncated, corrupt, not OpenEXR/PNG, or without R, G, B channels.
    #[error("cannot read {}: {reason}", path.display())]
    Unreadable { path: PathBuf, reason: String },
}

impl ImageError {
    pub fn exit_code(&self) -> u8 {
        4
    }
}

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
const PNG_MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Reads an OpenEXR or PNG image, recognised by its magic bytes, not its extension.
///
/// EXR: the first layer's `R`, `G`, `B` (and `A`) channels, any sample type, as `f32`.
/// PNG: 8- or 16-bit, grey expanded to RGB, kept display-referred (value / 255 or / 65535).
pub fn read_image(path: &Path) -> Result<Image, ImageError> {
    let fail = |reason: &str| ImageError::Unreadable {
        path: path.to_path_buf(),
        reason: one_line(reason),
    };
    let bytes = std::fs::read(path).map_err(|e| fail(&e.to_string()))?;
    let decoded = if bytes.is_empty() {
        Err("empty file".to_string())
    } else if bytes.starts_with(&EXR_MAGIC) {
        quietly(|| decode_exr(&bytes)).and_then(|r| r)
    } else if bytes.starts_with(&PNG_MAGIC) {
        quietly(|| decode_png(&bytes)).and_then(|r| r)
    } else {
        Err("not an OpenEXR or PNG file".to_string())
    };
    let img = decoded.map_err(|e| fail(&e))?;
    if img.pixels() == 0 {
        return Err(fail("the image has no pixels"));
    }
    Ok(img)
}

thread_local!(static QUIET_PANICS: Cell<bool> = const { Cell::new(false) });

/// Runs `f`, turning a panic into an error without printing it (a decoder's last resort).
/// The panic hook is wrapped once; it stays silent only on this thread, only during `f`.
fn quietly<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET_PANICS.with(Cell::get) {
                previous(info)
            }
        }));
    });
    QUIET_PANICS.with(|q| q.set(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET_PANICS.with(|q| q.set(false));
    r.map_err(|p| {
        let msg = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        format!("corrupt file (decoder failed: {msg})")
    })
}

fn decode_exr(bytes: &[u8]) -> Result<Image, String> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| e.to_string())?;
    let layer = image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let list = &layer.channel_data.list;
    let find = |name: &str| list.iter().find(|c| c.name.to_string() == name);
    let mut names = vec!["R", "G", "B"];
    if find("A").is_some() {
        names.push("A");
    }
    let mut planes = Vec::new();
    for n in &names {
        let ch = find(n).ok_or_else(|| {
            let have: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
            format!(
                "the first layer has no R, G, B channels (it has {})",
                have.join(", ")
            )
        })?;
        let plane: Vec<f32> = ch.sample_data.values_as_f32().collect();
        if plane.len() != w * h {
            return Err("channel size does not match the data window".into());
        }
        planes.push(plane);
    }
    let data = (0..w * h)
        .flat_map(|i| planes.iter().map(move |p| p[i]))
        .collect();
    Ok(self::Image::new(w, h, &names, data))
}

fn decode_png(bytes: &[u8]) -> Result<Image, String> {
    use image::{ColorType, DynamicImage};
    let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
        .map_err(|e| e.to_string())?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let alpha = img.color().has_alpha();
    let wide = matches!(
        img.color(),
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16
    );
    let data: Vec<f32> = match (wide, alpha) {
        (false, false) => scale(DynamicImage::to_rgb8(&img).as_raw(), 255.0),
        (false, true) => scale(DynamicImage::to_rgba8(&img).as_raw(), 255.0),
        (true, false) => scale(DynamicImage::to_rgb16(&img).as_raw(), 65535.0),
        (true, true) => scale(DynamicImage::to_rgba16(&img).as_raw(), 65535.0),
    };
    let names: &[&str] = if alpha {
        &["R", "G", "B", "A"]
    } else {
        &["R", "G", "B"]
    };
    let mut out = Image::new(w, h, names, data);
    out.display_referred = true;
    Ok(out)
}

fn scale<T: Copy + Into<f32>>(v: &[T], max: f32) -> Vec<f32> {
    v.iter().map(|&x| x.into() / max).collect()
}

/// Writes every channel of `img` as a float32 EXR, atomically.
pub fn write_exr_rgb(path: &Path, img: &Image) -> anyhow::Result<()> {
    use exr::prelude::*;
    let n = img.channels.len();
    let list: Vec<AnyChannel<FlatSamples>> = (0..n)
        .map(|c| {
            let plane = img.data.iter().skip(c).step_by(n).copied().collect();
            AnyChannel::new(img.channels[c].as_str(), FlatSamples::F32(plane))
        })
        .collect();
    let layer = Layer::new(
        (img.width, img.height),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(list.into()),
    );
    crate::output::write_atomic_with(path, |tmp| {
        Ok(exr::prelude::Image::from_layer(layer)
            .write()
            .to_file(tmp)?)
    })
}

/// Writes 8-bit RGB (`w × h × 3` bytes) as a PNG, atomically.
pub fn write_png_rgb8(path: &Path, w: usize, h: usize, rgb: &[u8]) -> anyhow::Result<()> {
    crate::output::write_atomic_with(path, |tmp| {
        let img = image::RgbImage::from_raw(w as u32, h as u32, rgb.to_vec())
            .ok_or_else(|| anyhow::anyhow!("{} bytes is not {w}x{h} RGB", rgb.len()))?;
        Ok(img.save_with_format(tmp, image::ImageFormat::Png)?)
    })
}

// ---------------------------------------------------------------------------------------------
// Metrics (idiff)
// ---------------------------------------------------------------------------------------------

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

/// idiff's verdict, in idiff's order (see the module documentation).
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

fn same_shape(a: &Image, b: &Image) -> Result<(), SizeMismatch> {
    if a.width == b.width && a.height == b.height && a.channels == b.channels {
        return Ok(());
    }
    Err(SizeMismatch {
        reference: a.shape(),
        test: b.shape(),
    })
}

/// Which ꟻLIP the comparison carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FlipKind {
    /// Scene-linear input: exposures × ACES × sRGB, per-pixel max of LDR-ꟻLIP.
    Hdr,
    /// Both images display-referred (PNG): LDR-ꟻLIP of the stored values.
    Ldr,
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
    /// Mean ꟻLIP, when computed (filled in by the caller: [`flip_error`]).
    pub flip_mean: Option<f64>,
    pub flip_kind: Option<FlipKind>,
    pub verdict: Verdict,
}

/// NaN against NaN, or an infinity against the same-signed infinity.
fn same_nonfinite(a: f64, b: f64) -> bool {
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
    let peak = reference
        .data
        .iter()
        .chain(&test.data)
        .filter(|v| v.is_finite())
        .fold(1f64, |m, &v| m.max(v.abs() as f64));

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

// ---------------------------------------------------------------------------------------------
// ꟻLIP
// ---------------------------------------------------------------------------------------------
//
// HDR-ꟻLIP as NVlabs/flip does it; followed: `cpp/tool/FLIP-tool.cpp` (exposure loop, number of
// exposures), `cpp/CPP/image.h` `computeExposures` and `cpp/CPP/tensor.h` `toneMap` (also
// vendored in nv-flip-sys 0.1.1, `extern/cpp/CPP/`), and OIIO `imagebufalgo_flip.cpp` for the
// median guard. Per exposure e: x ↦ sRGB8(clamp(ACES(2^e · x), 0, 1)) for both images, LDR-ꟻLIP
// at 67 pixels per degree, and the per-pixel maximum over exposures.

/// ꟻLIP's ACES fit (Narkowicz's curve with FLIP's 0.6 pre-exposure folded in):
/// (c0·x² + c1·x + c2) / (c3·x² + c4·x + c5).
const ACES: [f64; 6] = [
    0.6 * 0.6 * 2.51,
    0.6 * 0.03,
    0.0,
    0.6 * 0.6 * 2.43,
    0.6 * 0.59,
    0.14,
];

fn aces(x: f64) -> f64 {
    let [c0, c1, c2, c3, c4, c5] = ACES;
    (x * x * c0 + x * c1 + c2) / (x * x * c3 + x * c4 + c5)
}

/// The input where the ACES curve reaches 0.85: the larger root of
/// (c0 − t·c3)x² + (c1 − t·c4)x + (c2 − t·c5) = 0 with t = 0.85.
fn aces_input_for_085() -> f64 {
    let t = 0.85;
    let [c0, c1, c2, c3, c4, c5] = ACES;
    let (a, b, c) = (c0 - t * c3, c1 - t * c4, c2 - t * c5);
    if a == 0.0 {
        return -c / b;
    }
    let d1 = -0.5 * b / a;
    d1 + (d1 * d1 - c / a).sqrt()
}

/// Linear [0, 1] → 8-bit sRGB (ꟻLIP's `LinearRGB2sRGB`, then × 255 rounded).
fn srgb8(x: f64) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let v = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0 + 0.5) as u8
}

/// R, G, B per pixel with non-finite values and negatives replaced by 0 (ꟻLIP only).
fn sanitized_rgb(img: &Image) -> Vec<[f64; 3]> {
    let n = img.channels.len().max(1);
    let idx = img.rgb_indices();
    let clean = |v: f32| {
        if v.is_finite() {
            (v as f64).max(0.0)
        } else {
            0.0
        }
    };
    img.data
        .chunks(n)
        .map(|p| idx.map(|i| p.get(i).map_or(0.0, |&v| clean(v))))
        .collect()
}

/// (start, stop) exposures in stops, as ꟻLIP's `computeExposures`:
/// start = log2(x₀.₈₅ / Y_max), stop = log2(x₀.₈₅ / Y_median), Y = 0.2126R + 0.7152G + 0.0722B,
/// Y_median = mean of the sorted luminances at n/2 − 1 and n/2 (ꟻLIP's), floored at f32::EPSILON
/// as OIIO does (ꟻLIP itself would divide by 0 when most pixels are black).
fn exposure_range(rgb: &[[f64; 3]]) -> (f64, f64) {
    let mut y: Vec<f64> = rgb
        .iter()
        .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
        .collect();
    y.sort_by(f64::total_cmp);
    let n = y.len();
    let y_max = y.last().copied().unwrap_or(0.0).max(f32::EPSILON as f64);
    let y_median = match n {
        0 => 0.0,
        1 => y[0],
        _ => 0.5 * (y[n / 2 - 1] + y[n / 2]),
    }
    .max(f32::EPSILON as f64);
    let x = aces_input_for_085();
    let start = (x / y_max).log2();
    (start, (x / y_median).log2().max(start))
}

fn flip_ldr8(w: usize, h: usize, reference: &[u8], test: &[u8]) -> Vec<f32> {
    let r = nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, reference);
    let t = nv_flip::FlipImageRgb8::with_data(w as u32, h as u32, test);
    nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE).to_vec()
}

fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| x as f64).sum::<f64>() / v.len().max(1) as f64
}

/// HDR-ꟻLIP of two scene-linear images (R, G, B; non-finite and negative values count as 0):
/// the mean and the per-pixel error map in [0, 1]. The exposure range follows the reference
/// (the test if the reference is black); 0 when both are black.
/// Panics if the sizes differ (check with [`compare`] first).
pub fn hdr_flip(reference: &Image, test: &Image) -> (f64, Vec<f32>) {
    assert!(reference.width == test.width && reference.height == test.height);
    let (w, h) = (reference.width, reference.height);
    let (r, t) = (sanitized_rgb(reference), sanitized_rgb(test));
    let black = |v: &[[f64; 3]]| v.iter().all(|p| p.iter().all(|&c| c == 0.0));
    if black(&r) && black(&t) {
        return (0.0, vec![0.0; w * h]);
    }
    let (start, stop) = exposure_range(if black(&r) { &t } else { &r });
    let count = ((stop - start).ceil() as usize).max(2);
    let step = (stop - start) / (count - 1) as f64;

    // One LDR-ꟻLIP per exposure, spread over threads; keep the per-pixel maximum
    let one = |k: usize| {
        let m = (start + k as f64 * step).exp2();
        let enc = |v: &[[f64; 3]]| -> Vec<u8> {
            v.iter()
                .flat_map(|p| p.map(|c| srgb8(aces(c * m))))
                .collect()
        };
        flip_ldr8(w, h, &enc(&r), &enc(&t))
    };
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(count);
    let maps: Vec<Vec<f32>> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|j| {
                let one = &one;
                s.spawn(move || {
                    let mut acc = vec![0f32; w * h];
                    for k in (j..count).step_by(threads) {
                        for (a, e) in acc.iter_mut().zip(one(k)) {
                            *a = a.max(e);
                        }
                    }
                    acc
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|h| h.join().expect("FLIP worker"))
            .collect()
    });
    let mut map = vec![0f32; w * h];
    for m in maps {
        for (a, e) in map.iter_mut().zip(m) {
            *a = a.max(e);
        }
    }
    (mean(&map), map)
}

/// LDR-ꟻLIP of two display-referred images (the stored values, clamped, as 8-bit sRGB).
pub fn ldr_flip(reference: &Image, test: &Image) -> (f64, Vec<f32>) {
    assert!(reference.width == test.width && reference.height == test.height);
    let enc = |img: &Image| -> Vec<u8> {
        let n = img.channels.len().max(1);
        let idx = img.rgb_indices();
        img.data
            .chunks(n)
            .flat_map(|p| idx.map(|i| (p[i].clamp(0.0, 1.0) * 255.0 + 0.5) as u8))
            .collect()
    };
    let map = flip_ldr8(
        reference.width,
        reference.height,
        &enc(reference),
        &enc(test),
    );
    (mean(&map), map)
}

/// LDR-ꟻLIP if both images are display-referred (PNG), HDR-ꟻLIP otherwise.
pub fn flip_error(reference: &Image, test: &Image) -> (FlipKind, f64, Vec<f32>) {
    if reference.display_referred && test.display_referred {
        let (m, map) = ldr_flip(reference, test);
        (FlipKind::Ldr, m, map)
    } else {
        let (m, map) = hdr_flip(reference, test);
        (FlipKind::Hdr, m, map)
    }
}

/// An error map (values in [0, 1]; NaN shown as 1) coloured with ꟻLIP's magma map, 8-bit RGB.
pub fn heatmap_rgb8(err_map: &[f32], w: usize, h: usize) -> Vec<u8> {
    let v: Vec<f32> = err_map
        .iter()
        .map(|&e| if e.is_nan() { 1.0 } else { e.clamp(0.0, 1.0) })
        .collect();
    nv_flip::FlipImageFloat::with_data(w as u32, h as u32, &v)
        .apply_color_lut(&nv_flip::magma_lut())
        .to_vec()
}

/// 8-bit RGB preview: clamp to [0, 1], then sRGB-encode (display-referred images are only
/// clamped and quantised, being encoded already).
pub fn tonemap_rgb8(img: &Image) -> Vec<u8> {
    let n = img.channels.len().max(1);
    let idx = img.rgb_indices();
    img.data
        .chunks(n)
        .flat_map(|p| {
            idx.map(|i| {
                let v = p[i] as f64;
                if img.display_referred {
                    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
                } else {
                    srgb8(v)
                }
            })
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Noise-aware z-test (Mitsuba 3, src/render/tests/test_renders.py)
// ---------------------------------------------------------------------------------------------

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
}

impl Default for ZParams {
    fn default() -> Self {
        ZParams {
            spp: 1,
            significance: 0.01,
            pixel_success_rate: 0.9975,
        }
    }
}

/// The z-test's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ZTest {
    pub params: ZParams,
    /// Channels tested: the reference's channels that the variance image also has.
    pub channels: Vec<String>,
    pub pixels: u64,
    /// Per-channel significance after the Šidák correction.
    pub alpha: f64,
    pub min_p: f64,
    /// (x, y, channel index into `channels`) of the first smallest p-value.
    pub min_p_at: (usize, usize, usize),
    pub min_p_channel: String,
    /// Pixels with some channel's p ≤ alpha.
    pub failing_pixels: u64,
    /// Channel tests with p > alpha.
    pub passing_channels: u64,
    pub verdict: Verdict,
}

/// Per pixel and channel, z = |test − ref| · sqrt(spp / max(var, 10⁻⁴)) and p = 2(1 − Φ(z)) =
/// erfc(z/√2); a channel passes if p > α = 1 − (1 − significance)^(1/pixels), and the test
/// passes if passing channels / channels ≥ success rate × pixels. NaN against NaN (or the same
/// Inf) passes; any other NaN/Inf in the images fails.
pub fn z_test(
    reference: &Image,
    test: &Image,
    variance: &Image,
    p: &ZParams,
) -> Result<ZTest, SizeMismatch> {
    same_shape(reference, test)?;
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
        Some(v) if variance.width == reference.width && variance.height == reference.height => v,
        _ => {
            return Err(SizeMismatch {
                reference: reference.shape(),
                test: variance.shape(),
            })
        }
    };
    let (nr, nv) = (reference.channels.len(), variance.channels.len());
    let pixels = reference.pixels() as u64;
    let alpha = sidak_alpha(p.significance, pixels);
    let (mut min_p, mut min_at) = (f64::INFINITY, (0, 0, 0));
    let (mut failing_pixels, mut passing) = (0u64, 0u64);
    for px in 0..reference.pixels() {
        let mut failed = false;
        for (k, &(i, j)) in idx.iter().enumerate() {
            let (r, t) = (
                reference.data[px * nr + i] as f64,
                test.data[px * nr + i] as f64,
            );
            let var = variance.data[px * nv + j] as f64;
            let pv = if r.is_finite() && t.is_finite() {
                let var = if var.is_nan() { 1e-4 } else { var.max(1e-4) };
                let z = (t - r).abs() * (p.spp as f64 / var).sqrt();
                erfc(z / std::f64::consts::SQRT_2).min(1.0) // the fit gives 1 + 3e-8 at 0
            } else if same_nonfinite(r, t) {
                1.0
            } else {
                0.0
            };
            if pv < min_p {
                (min_p, min_at) = (pv, (px % reference.width, px / reference.width, k));
            }
            if pv > alpha {
                passing += 1;
            } else {
                failed = true;
            }
        }
        failing_pixels += failed as u64;
    }
    let channels: Vec<String> = idx
        .iter()
        .map(|&(i, _)| reference.channels[i].clone())
        .collect();
    let ok = passing as f64 / channels.len().max(1) as f64 >= p.pixel_success_rate * pixels as f64;
    Ok(ZTest {
        params: *p,
        min_p_channel: channels.get(min_at.2).cloned().unwrap_or_default(),
        channels,
        pixels,
        alpha,
        min_p: if min_p.is_finite() { min_p } else { 1.0 },
        min_p_at: min_at,
        failing_pixels,
        passing_channels: passing,
        verdict: if ok { Verdict::Pass } else { Verdict::Failure },
    })
}

// ---------------------------------------------------------------------------------------------
// Report
// ---------------------------------------------------------------------------------------------

/// C's `%.{prec}g`: `prec` significant digits, trailing zeros dropped, exponent form when the
/// exponent is < −4 or ≥ `prec`; `inf`, `-inf`, `nan`.
pub fn fmt_g(x: f64, prec: usize) -> String {
    if x.is_nan() {
        return "nan".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf" } else { "-inf" }.into();
    }
    if x == 0.0 {
        return "0".into();
    }
    let p = prec.max(1);
    let sci = format!("{:.*e}", p - 1, x);
    let (mantissa, exp) = sci.split_once('e').expect("exponent");
    let exp: i32 = exp.parse().expect("exponent");
    let trim = |s: &str| -> String {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s.to_string()
        }
    };
    if exp < -4 || exp >= p as i32 {
        let sign = if exp < 0 { '-' } else { '+' };
        format!("{}e{sign}{:02}", trim(mantissa), exp.abs())
    } else {
        trim(&format!("{:.*}", (p as i32 - 1 - exp) as usize, x))
    }
}

fn g(x: f64) -> String {
    fmt_g(x, 6)
}

fn report_body(ref_name: &str, test_name: &str, c: &Comparison, t: &Thresholds) -> String {
    let pct = |n: u64| fmt_g(100.0 * n as f64 / c.pixels.max(1) as f64, 4);
    let mut s = format!("Comparing \"{ref_name}\" and \"{test_name}\"\n");
    s += &format!("  Mean error = {}\n", g(c.mean_error));
    s += &format!("  RMS error = {}\n", g(c.rms_error));
    s += &format!("  Peak SNR = {}\n", g(c.psnr));
    if c.max_error == 0.0 {
        s += "  Max error  = 0\n";
    } else {
        let (x, y, _) = c.max_at;
        s += &format!(
            "  Max error  = {} @ ({x}, {y}, {})  values are {} vs {}\n",
            c.max_error, c.max_channel, c.max_values.0, c.max_values.1
        );
    }
    s += &format!(
        "  {} pixels ({}%) over {}\n",
        c.n_warn,
        pct(c.n_warn),
        g(t.warn)
    );
    s += &format!(
        "  {} pixels ({}%) over {}\n",
        c.n_fail,
        pct(c.n_fail),
        g(t.fail)
    );
    if c.n_nonfinite_mismatch > 0 {
        s += &format!(
            "  {} pixels ({}%) with a NaN/Inf mismatch\n",
            c.n_nonfinite_mismatch,
            pct(c.n_nonfinite_mismatch)
        );
    }
    s += &format!("  relMSE = {}\n", g(c.rel_mse));
    if let (Some(m), Some(k)) = (c.flip_mean, c.flip_kind) {
        let name = if k == FlipKind::Hdr { "HDR" } else { "LDR" };
        s += &format!("  Mean {name}-FLIP = {}\n", g(m));
    }
    s
}

/// idiff's report (plus relMSE and ꟻLIP), ending with the verdict line.
pub fn report_text(ref_name: &str, test_name: &str, c: &Comparison, t: &Thresholds) -> String {
    report_body(ref_name, test_name, c, t) + c.verdict.label() + "\n"
}

fn z_report(z: &ZTest) -> String {
    let (x, y, _) = z.min_p_at;
    let tests = z.pixels * z.channels.len() as u64;
    format!(
        "  z-test (spp {}, significance {}, Šidák alpha = {}):\n    min p-value = {} @ ({x}, {y}, {})\n    {} pixels ({}%) fail; {} of {} channel tests pass, {} needed\n",
        z.params.spp,
        g(z.params.significance),
        g(z.alpha),
        g(z.min_p),
        z.min_p_channel,
        z.failing_pixels,
        fmt_g(100.0 * z.failing_pixels as f64 / z.pixels.max(1) as f64, 4),
        z.passing_channels,
        tests,
        g((z.params.pixel_success_rate * tests as f64).ceil()),
    )
}

// ---------------------------------------------------------------------------------------------
// Command line
// ---------------------------------------------------------------------------------------------

fn parse_threshold(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a non-negative number (inf allowed)")),
    }
}

fn parse_unit_open(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v < 1.0 => Ok(v),
        _ => Err(format!("'{s}' is not a number strictly between 0 and 1")),
    }
}

fn parse_unit_closed(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not a number between 0 and 1")),
    }
}

/// `rayproof diff`: compare two images (OpenEXR or PNG) like OpenImageIO's idiff.
///
/// Exit codes: 0 PASS, 1 WARNING, 2 FAILURE (also bad usage and unwritable outputs), 3 size
/// mismatch, 4 unreadable input.
#[derive(clap::Args, Debug, Clone)]
pub struct DiffArgs {
    /// Reference image (OpenEXR or PNG, recognised by content).
    pub reference: PathBuf,
    /// Test image.
    pub test: PathBuf,
    /// A pixel fails if some channel differs by more than this…
    #[arg(long, default_value_t = 1e-6, value_parser = parse_threshold)]
    pub fail: f64,
    /// …and by more than this relative to the mean of the two |values|.
    #[arg(long, default_value_t = 0.0, value_parser = parse_threshold)]
    pub failrelative: f64,
    /// FAILURE needs more than this percentage of pixels to fail.
    #[arg(long, default_value_t = 0.0, value_parser = parse_threshold)]
    pub failpercent: f64,
    /// FAILURE if the max error exceeds this, however few pixels fail.
    #[arg(long, default_value_t = f64::INFINITY, value_parser = parse_threshold)]
    pub hardfail: f64,
    /// PASS if at most this many pixels fail (overrides everything else).
    #[arg(long, default_value_t = 0)]
    pub allowfailures: u64,
    /// A pixel warns if some channel differs by more than this…
    #[arg(long, default_value_t = 1e-6, value_parser = parse_threshold)]
    pub warn: f64,
    /// …and by more than this relative to the mean of the two |values|.
    #[arg(long, default_value_t = 0.0, value_parser = parse_threshold)]
    pub warnrelative: f64,
    /// WARNING needs more than this percentage of pixels to warn.
    #[arg(long, default_value_t = 0.0, value_parser = parse_threshold)]
    pub warnpercent: f64,
    /// WARNING if the max error exceeds this.
    #[arg(long, default_value_t = f64::INFINITY, value_parser = parse_threshold)]
    pub hardwarn: f64,
    /// Write |REF − TEST| per channel as a float32 EXR (always, even if identical).
    #[arg(long, value_name = "FILE")]
    pub diff_exr: Option<PathBuf>,
    /// Write a magma heat map PNG of the ꟻLIP error (with --no-flip: of the largest channel
    /// |REF − TEST| × 16, clamped).
    #[arg(long, value_name = "FILE.png")]
    pub heatmap: Option<PathBuf>,
    /// Skip ꟻLIP (faster).
    #[arg(long)]
    pub no_flip: bool,
    /// Write the metrics, thresholds and z-test as JSON ('-': stdout, instead of the text).
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Noise-aware mode: per-pixel variance of the test image (EXR); the verdict is then the
    /// z-test's (PASS or FAILURE).
    #[arg(long, value_name = "VAR.exr")]
    pub variance: Option<PathBuf>,
    /// Samples per pixel of the test image [default: 1]; with N > 1 the variance image is
    /// the per-sample variance, with 1 the variance of the pixel mean.
    #[arg(long, requires = "variance", value_parser = clap::value_parser!(u64).range(1..))]
    pub spp: Option<u64>,
    /// Family-wise significance of the z-test, Šidák-corrected over pixels [default: 0.01].
    #[arg(long, requires = "variance", value_parser = parse_unit_open)]
    pub significance: Option<f64>,
    /// Fraction of pixels that must pass the z-test [default: 0.9975].
    #[arg(long, requires = "variance", value_parser = parse_unit_closed)]
    pub pixel_success_rate: Option<f64>,
    /// Print only the verdict line.
    #[arg(short, long)]
    pub quiet: bool,
}

impl DiffArgs {
    /// The idiff thresholds given on the command line.
    pub fn thresholds(&self) -> Thresholds {
        Thresholds {
            fail: self.fail,
            failrelative: self.failrelative,
            failpercent: self.failpercent,
            hardfail: self.hardfail,
            allowfailures: self.allowfailures,
            warn: self.warn,
            warnrelative: self.warnrelative,
            warnpercent: self.warnpercent,
            hardwarn: self.hardwarn,
        }
    }

    /// The z-test settings given on the command line.
    pub fn z_params(&self) -> ZParams {
        let d = ZParams::default();
        ZParams {
            spp: self.spp.unwrap_or(d.spp),
            significance: self.significance.unwrap_or(d.significance),
            pixel_success_rate: self.pixel_success_rate.unwrap_or(d.pixel_success_rate),
        }
    }
}

/// An exit code and a one-line message.
struct Exit(u8, String);

fn out(text: &str) {
    let _ = std::io::stdout().lock().write_all(text.as_bytes());
}

/// Output files: their directory exists, they are not directories, not one of the inputs.
fn check_output(path: &Path, inputs: &[&Path]) -> Result<(), Exit> {
    let bad = |why: String| Exit(2, format!("cannot write {}: {why}", path.display()));
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(bad(format!("directory {} does not exist", dir.display())));
    }
    if path.is_dir() {
        return Err(bad("it is a directory".into()));
    }
    let canon = |p: &Path| std::fs::canonicalize(p).ok();
    if canon(path).is_some() && inputs.iter().any(|i| canon(i) == canon(path)) {
        return Err(bad("it is one of the input images".into()));
    }
    Ok(())
}

/// Runs `rayproof diff`: prints the report (or only the verdict, or the JSON), writes the
/// requested files, and returns the exit code; errors are printed as one line on stderr.
pub fn run_diff(a: DiffArgs) -> u8 {
    match diff(&a) {
        Ok(code) => code,
        Err(Exit(code, msg)) => {
            let _ = writeln!(std::io::stderr(), "error: {}", one_line(&msg));
            code
        }
    }
}

fn diff(a: &DiffArgs) -> Result<u8, Exit> {
    let t = a.thresholds();
    let json_stdout = a.json.as_deref() == Some(Path::new("-"));

    // Outputs are checked before any work
    let mut inputs = vec![a.reference.as_path(), a.test.as_path()];
    inputs.extend(a.variance.as_deref());
    let json_file = a.json.as_deref().filter(|_| !json_stdout);
    for p in [a.diff_exr.as_deref(), a.heatmap.as_deref(), json_file]
        .into_iter()
        .flatten()
    {
        check_output(p, &inputs)?;
    }

    // Inputs
    let read = |p: &Path| read_image(p).map_err(|e| Exit(e.exit_code(), e.to_string()));
    let reference = read(&a.reference)?;
    let test = read(&a.test)?;
    let variance = a.variance.as_deref().map(read).transpose()?;
    let (rn, tn) = (a.reference.display(), a.test.display());
    let mismatch = |e: SizeMismatch| Exit(3, format!("{rn} and {tn}: {e}"));

    // Metrics, z-test, ꟻLIP
    let mut c = compare(&reference, &test, &t).map_err(mismatch)?;
    let z = match &variance {
        Some(v) => Some(z_test(&reference, &test, v, &a.z_params()).map_err(|e| {
            let vn = a.variance.as_deref().unwrap_or(Path::new("")).display();
            Exit(
                3,
                format!(
                    "{rn} and variance {vn}: {e} (the variance needs the same size and R, G, B)"
                ),
            )
        })?),
        None => None,
    };
    let flip_map = (!a.no_flip).then(|| {
        let (kind, m, map) = flip_error(&reference, &test);
        (c.flip_kind, c.flip_mean) = (Some(kind), Some(m));
        map
    });
    let verdict = z.as_ref().map_or(c.verdict, |z| z.verdict);

    // Files
    let (w, h) = (reference.width, reference.height);
    let write_err = |e: anyhow::Error| Exit(2, format!("{e:#}"));
    if let Some(p) = &a.diff_exr {
        let d = abs_diff(&reference, &test).map_err(mismatch)?;
        write_exr_rgb(p, &d).map_err(write_err)?;
    }
    if let Some(p) = &a.heatmap {
        let map = match flip_map {
            Some(m) => m,
            None => abs_error_map(&reference, &test).map_err(mismatch)?,
        };
        write_png_rgb8(p, w, h, &heatmap_rgb8(&map, w, h)).map_err(write_err)?;
    }
    if let Some(p) = &a.json {
        let doc = serde_json::json!({
            "reference": a.reference.display().to_string(),
            "test": a.test.display().to_string(),
            "verdict": verdict,
            "exit_code": verdict.exit_code(),
            "comparison": c,
            "thresholds": t,
            "ztest": z,
        });
        let text = serde_json::to_string_pretty(&doc).expect("JSON") + "\n";
        if json_stdout {
            out(&text);
        } else {
            crate::output::write_atomic(p, text.as_bytes()).map_err(write_err)?;
        }
    }

    // Report
    if json_stdout {
    } else if a.quiet {
        out(&format!("{}\n", verdict.label()));
    } else {
        let mut s = String::new();
        if reference.display_referred != test.display_referred {
            let kind = |i: &Image| match i.display_referred {
                true => "display-referred (PNG)",
                false => "scene-linear (EXR)",
            };
            s += &format!(
                "note: {rn} is {} and {tn} is {}; they are compared as stored, without colour conversion\n",
                kind(&reference),
                kind(&test)
            );
        }
        s += &report_body(&rn.to_string(), &tn.to_string(), &c, &t);
        if let Some(z) = &z {
            s += &z_report(z);
            s += &format!(
                "  idiff verdict: {} (the z-test decides)\n",
                c.verdict.label()
            );
        }
        s += verdict.label();
        s += "\n";
        out(&s);
    }
    Ok(verdict.exit_code())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fmt_g_matches_c() {
        // printf("%g") of each value
        let cases = [
            (1e-6, "1e-06"),
            (0.0001, "0.0001"),
            (0.00012345678, "0.000123457"),
            (123456.0, "123456"),
            (1234567.0, "1.23457e+06"),
            (0.5, "0.5"),
            (33.979400086720375, "33.9794"),
            (100.0, "100"),
            (-2.5e-7, "-2.5e-07"),
        ];
        for (x, want) in cases {
            assert_eq!(fmt_g(x, 6), want, "{x}");
        }
        assert_eq!(fmt_g(18.75, 4), "18.75");
        assert_eq!(fmt_g(100.0 / 3.0, 4), "33.33");
        assert_eq!(fmt_g(f64::INFINITY, 6), "inf");
        assert_eq!(fmt_g(0.0, 6), "0");
    }

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

    #[test]
    fn aces_reaches_085_at_the_root() {
        let x = aces_input_for_085();
        // hand: a = 0.16002, b = −0.2829, c = −0.119 → x ≈ 2.11887
        assert!((x - 2.11887).abs() < 1e-4, "{x}");
        assert!((aces(x) - 0.85).abs() < 1e-12);
        assert_eq!(aces(0.0), 0.0);
    }

    #[test]
    fn exposure_range_uses_max_and_flip_median() {
        // Grey pixels: Y = value; sorted Y = [0.5, 1, 2, 8]: median (1+2)/2 = 1.5, max 8
        let px = |v: f64| [v, v, v];
        let rgb = [px(2.0), px(0.5), px(8.0), px(1.0)];
        let (start, stop) = exposure_range(&rgb);
        let x = aces_input_for_085();
        assert!((start - (x / 8.0).log2()).abs() < 1e-12);
        assert!((stop - (x / 1.5).log2()).abs() < 1e-12);
        // Mostly black: the median is floored at f32::EPSILON, not 0
        let (_, stop) = exposure_range(&[px(0.0), px(0.0), px(0.0), px(1.0)]);
        assert!((stop - (x / f32::EPSILON as f64).log2()).abs() < 1e-9);
    }

    #[test]
    fn srgb8_endpoints_and_midpoint() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(f64::NAN), 0);
        assert_eq!(srgb8(7.0), 255);
        // 1.055·0.214^(1/2.4) − 0.055 = 0.49996, ×255 = 127.49 → 127;
        // 1.055·0.2159^(1/2.4) − 0.055 = 0.50200, ×255 = 128.01 → 128
        assert_eq!(srgb8(0.214), 127);
        assert_eq!(srgb8(0.2159), 128);
    }

    #[test]
    fn quietly_turns_a_panic_into_an_error() {
        assert_eq!(quietly(|| 7), Ok(7));
        let e = quietly(|| -> u8 { panic!("boom {}", 1) }).unwrap_err();
        assert!(e.contains("boom 1"), "{e}");
        assert!(!QUIET_PANICS.with(Cell::get));
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
