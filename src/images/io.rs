//! Image I/O: the [`Image`] type, readers of OpenEXR and PNG that never panic on a bad file,
//! the EXR and PNG writers (through [`crate::output::write_atomic_with`]) and the 8-bit sRGB
//! preview.

use std::cell::Cell;
use std::path::{Path, PathBuf};

/// A decoded image: interleaved `f32` samples, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
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

    /// Width × height.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// `4x3 RGBA`.
    pub fn shape(&self) -> String {
        format!("{}x{} {}", self.width, self.height, self.channels.concat())
    }

    /// Indices of R, G, B (by name; else the first channels).
    pub(super) fn rgb_indices(&self) -> [usize; 3] {
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
    Unreadable {
        /// The file, as named.
        path: PathBuf,
        /// What is wrong with it, one line.
        reason: String,
    },
}

impl ImageError {
    /// The documented exit code of an unusable input: 4.
    pub fn exit_code(&self) -> u8 {
        4
    }
}

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
const PNG_MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// `s` with every run of whitespace, newlines included, as one space.
pub fn one_line(s: &str) -> String {
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
    // Read the file (a regular file, within the cap) and decode it by its magic bytes; a
    // decoder's panic becomes an error
    let bytes = crate::input::read_capped(path, MAX_IMAGE_BYTES, crate::input::Kind::Regular)
        .map_err(|e| fail(&e))?;
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

/// The most pixels rayproof reads from one image (8192²; also the largest image it renders).
pub const MAX_PIXELS: u64 = 1 << 26;
/// The most samples (pixels × channels, as the header declares them) rayproof reads from one
/// image file of any format: 2^28 = 8192² × 4 (RGBA). A decoder holds every channel of the
/// file, so the channel count is bounded too: an EXR of 8192² × 64 channels declared in 198 KB
/// aborted after allocating, and a valid 4 MB EXR of 16 channels took 5.8 GB.
pub const MAX_SAMPLES: u64 = 1 << 28;
/// The largest image file: 1088 MiB, an uncompressed float32 EXR of [`MAX_SAMPLES`] samples
/// (1 GiB) with room for its header and offset tables. The file is read whole before decoding.
pub const MAX_IMAGE_BYTES: u64 = 4 * MAX_SAMPLES + (64 << 20);

/// Checks an image's declared size against [`MAX_PIXELS`] and [`MAX_SAMPLES`]: one line if it
/// is too large.
fn check_declared(w: u64, h: u64, channels: u64) -> Result<(), String> {
    if w * h > MAX_PIXELS {
        return Err(format!(
            "it declares {w}×{h} pixels; at most {MAX_PIXELS} (8192²) are read"
        ));
    }
    if w * h * channels > MAX_SAMPLES {
        return Err(format!(
            "it declares {w}×{h} pixels × {channels} channels = {} samples; at most {MAX_SAMPLES} (8192² × 4) are read",
            w * h * channels
        ));
    }
    Ok(())
}

fn decode_exr(bytes: &[u8]) -> Result<Image, String> {
    use exr::prelude::*;
    // The declared sizes, against the limits and the file's own length, before any allocation:
    // every part's pixels, and its channels (the decoder holds them all)
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| e.to_string())?;
    let mut samples = 0u64;
    for h in &meta.headers {
        let (w, ht) = (h.layer_size.width() as u64, h.layer_size.height() as u64);
        let channels = h.channels.list.len() as u64;
        check_declared(w, ht, channels).map_err(|e| format!("its data window: {e}"))?;
        samples += w * ht * channels;
        if samples > MAX_SAMPLES {
            return Err(format!(
                "its {} parts declare more than {MAX_SAMPLES} samples (8192² × 4) together; at most that many are read",
                meta.headers.len()
            ));
        }
        if h.chunk_count as u64 * 8 > bytes.len() as u64 {
            return Err(format!(
                "it declares {} chunks, whose offset table alone needs more than its {} bytes: truncated or corrupt",
                h.chunk_count,
                bytes.len()
            ));
        }
    }
    // Read the first valid layer, all channels, at full resolution
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
    // Gather R, G, B (and A) as f32 planes
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
    // Interleave the planes
    let data = (0..w * h)
        .flat_map(|i| planes.iter().map(move |p| p[i]))
        .collect();
    Ok(self::Image::new(w, h, &names, data))
}

fn decode_png(bytes: &[u8]) -> Result<Image, String> {
    use image::{ColorType, DynamicImage, ImageDecoder};
    // The declared size against the limits, from the header alone (channels as decoded: RGB or
    // RGBA)
    let header = image::codecs::png::PngDecoder::new(std::io::Cursor::new(bytes))
        .map_err(|e| e.to_string())?;
    let (w, h) = header.dimensions();
    let channels = 3 + u64::from(header.color_type().has_alpha());
    check_declared(w as u64, h as u64, channels)?;
    drop(header);
    // Decode, noting alpha and 16-bit samples
    let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
        .map_err(|e| e.to_string())?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let alpha = img.color().has_alpha();
    let wide = matches!(
        img.color(),
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16
    );
    // Expand to RGB(A) and scale code values to [0, 1]
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

/// Code value × (1 / max) in float32, as OpenImageIO converts (so idiff and rayproof read the
/// same floats: `x / 255` differs from it in the last bit for some codes).
fn scale<T: Copy + Into<f32>>(v: &[T], max: f32) -> Vec<f32> {
    let inv = 1.0 / max;
    v.iter().map(|&x| x.into() * inv).collect()
}

/// Writes every channel of `img` as a float32 EXR, atomically.
pub fn write_exr_rgb(path: &Path, img: &Image) -> anyhow::Result<()> {
    use exr::prelude::*;
    // One float32 plane per channel, in a single layer
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
    // Write it through a temporary sibling
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

/// Linear [0, 1] → 8-bit sRGB (ꟻLIP's `LinearRGB2sRGB`, then × 255 rounded).
pub(super) fn srgb8(x: f64) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let v = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0 + 0.5) as u8
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
