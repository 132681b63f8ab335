//! Image I/O: the [`Image`] type, readers of OpenEXR and PNG that never panic on a bad file,
//! the EXR and PNG writers (through [`crate::output::write_atomic_with`]) and the 8-bit sRGB
//! preview.

use serde::Serialize;
use std::cell::Cell;
use std::path::{Path, PathBuf};

/// A rectangle of pixels in an image's absolute coordinates (OpenEXR's `dataWindow` and
/// `displayWindow`; a PNG is one window at (0, 0)). Written `WxH+X+Y` as OpenImageIO writes
/// geometry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Window {
    /// Column of the top-left pixel (may be negative).
    pub x: i64,
    /// Row of the top-left pixel (may be negative).
    pub y: i64,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

impl Window {
    /// A `width × height` window at (0, 0).
    pub fn at_origin(width: usize, height: usize) -> Window {
        Window {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// The smallest window holding both (either may be empty).
    pub fn union(&self, other: &Window) -> Window {
        if self.width == 0 || self.height == 0 {
            return *other;
        }
        if other.width == 0 || other.height == 0 {
            return *self;
        }
        let (x, y) = (self.x.min(other.x), self.y.min(other.y));
        let x1 = (self.x + self.width as i64).max(other.x + other.width as i64);
        let y1 = (self.y + self.height as i64).max(other.y + other.height as i64);
        Window {
            x,
            y,
            width: (x1 - x) as usize,
            height: (y1 - y) as usize,
        }
    }

    /// Width × height.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }
}

impl std::fmt::Display for Window {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}{:+}{:+}", self.width, self.height, self.x, self.y)
    }
}

/// How the layer of an image was chosen (see [`read_image_layer`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LayerPick {
    /// Named by the caller (`--layer NAME`).
    Named,
    /// The default: a layer named `Combined` (Blender's beauty) with colour channels, the first
    /// in OpenImageIO's order.
    Combined,
    /// The default without such a `Combined` layer: the file's one layer with colour channels
    /// (`R`, `G`, `B`, or `Y` without `X`, `Z`); its other layers have none.
    FirstRgb,
    /// The default when several layers have colour channels and none is a `Combined` with them
    /// (Mitsuba's AOVs, `diffuse.*` beside `specular.*`), or when the file has two `Combined`
    /// layers (two view layers) or one without colour: every channel of the file, each layer
    /// compared, as idiff compares them.
    Every,
    /// The default: the file's only layer.
    Only,
    /// Every channel of the file's first part, as idiff compares them (`--idiff-compat`
    /// without `--layer`).
    All,
}

/// Which layer of a multilayer EXR was read, for the report.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct LayerInfo {
    /// The layer read, by its channel-name prefix (`ViewLayer.Combined`; `""` for the channels
    /// whose names have no prefix); `None` when every channel of the first part was read.
    pub name: Option<String>,
    /// How it was chosen.
    pub pick: LayerPick,
    /// Every layer of the file, in OpenImageIO's channel order (`""`: unprefixed channels).
    pub layers: Vec<String>,
}

impl LayerInfo {
    /// `ViewLayer.Combined`, or what the other cases read.
    pub fn label(&self) -> String {
        match self.name.as_deref() {
            None if self.pick == LayerPick::Every => {
                format!("every layer ({})", layer_names(&self.layers))
            }
            None => "all channels of the first part".into(),
            Some("") => "the channels without a layer name".into(),
            Some(n) => n.into(),
        }
    }
}

/// A decoded image: interleaved `f32` samples, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels (of the data window).
    pub width: usize,
    /// Height in pixels (of the data window).
    pub height: usize,
    /// The channels' names in OpenImageIO's order (`R`, `G`, `B`, `A`, then others): within a
    /// layer without its prefix (`R` of `ViewLayer.Combined.R`), in full when every channel of
    /// the file was read.
    pub channels: Vec<String>,
    /// `width × height × channels.len()` samples.
    pub data: Vec<f32>,
    /// True for PNG: samples are display-referred code values / 255 (or / 65535).
    pub display_referred: bool,
    /// Absolute position of the top-left stored pixel (an EXR's `dataWindow` minimum; (0, 0)
    /// for PNG). Pixel positions are reported in these coordinates, as idiff reports them.
    pub origin: (i64, i64),
    /// The display window (the frame; for PNG the image itself). Outside its data window an
    /// image's pixels are 0.
    pub display: Window,
    /// The layer read from a multilayer EXR; `None` for a file whose channels have no layer
    /// names, and for PNG.
    pub layer: Option<LayerInfo>,
    /// The exact values of an EXR's `UINT` channels (object and material IDs), per channel in
    /// the order of `channels` (`None`: a float channel), stored as `data` is; empty when the
    /// image has none. `data` holds them as OpenImageIO reads them (`u / (2³² − 1)`), which
    /// `--idiff-compat` compares; rayproof's own rules compare these, exactly as integers.
    pub uint: Vec<Option<Vec<u32>>>,
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
            origin: (0, 0),
            display: Window::at_origin(width, height),
            layer: None,
            uint: vec![],
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

    /// The data window: where the stored pixels are, in absolute coordinates.
    pub fn data_window(&self) -> Window {
        Window {
            x: self.origin.0,
            y: self.origin.1,
            width: self.width,
            height: self.height,
        }
    }

    /// The sample of channel `c` at absolute position (x, y): 0 outside the data window or
    /// beyond the channels, as OpenImageIO reads it.
    pub fn at(&self, x: i64, y: i64, c: usize) -> f32 {
        let (dx, dy) = (x - self.origin.0, y - self.origin.1);
        let n = self.channels.len();
        if dx >= 0 && dy >= 0 && (dx as usize) < self.width && (dy as usize) < self.height && c < n
        {
            self.data[(dy as usize * self.width + dx as usize) * n + c]
        } else {
            0.0
        }
    }

    /// Sample `c` at absolute `(x, y)` exactly: a `UINT` channel's integer, else [`Image::at`].
    pub fn at_exact(&self, x: i64, y: i64, c: usize) -> f64 {
        match self.uint.get(c) {
            Some(Some(plane)) => {
                let (dx, dy) = (x - self.origin.0, y - self.origin.1);
                if dx >= 0 && dy >= 0 && (dx as usize) < self.width && (dy as usize) < self.height {
                    plane[dy as usize * self.width + dx as usize] as f64
                } else {
                    0.0
                }
            }
            _ => self.at(x, y, c) as f64,
        }
    }

    /// Whether channel `c` is an EXR `UINT` channel.
    pub fn is_uint(&self, c: usize) -> bool {
        matches!(self.uint.get(c), Some(Some(_)))
    }

    /// The same image stored over `window` (pixels outside the data window are 0); the
    /// display window and channels are kept.
    pub fn padded(&self, window: Window) -> Image {
        if window == self.data_window() {
            return self.clone();
        }
        let n = self.channels.len();
        let mut data = vec![0f32; window.pixels() * n];
        for (p, px) in data.chunks_mut(n.max(1)).enumerate().take(window.pixels()) {
            let (x, y) = (
                window.x + (p % window.width) as i64,
                window.y + (p / window.width) as i64,
            );
            for (c, v) in px.iter_mut().enumerate() {
                *v = self.at(x, y, c);
            }
        }
        let uint = self
            .uint
            .iter()
            .enumerate()
            .map(|(c, plane)| {
                plane.as_ref().map(|_| {
                    (0..window.pixels())
                        .map(|p| {
                            let (x, y) = (
                                window.x + (p % window.width) as i64,
                                window.y + (p / window.width) as i64,
                            );
                            self.at_exact(x, y, c) as u32
                        })
                        .collect()
                })
            })
            .collect();
        Image {
            width: window.width,
            height: window.height,
            data,
            origin: (window.x, window.y),
            uint,
            ..self.clone()
        }
    }

    /// The channel names, run together when each is one letter (`RGBA`), else comma-separated.
    pub fn channel_list(&self) -> String {
        if self.channels.iter().all(|c| c.chars().count() == 1) {
            self.channels.concat()
        } else {
            self.channels.join(",")
        }
    }

    /// `4x3 RGBA`; with a data window other than the display window at (0, 0),
    /// `40x30+8+12 RGB in display window 64x48+0+0`; with a layer, `(layer NAME)` after it.
    pub fn shape(&self) -> String {
        let mut s = if self.display == Window::at_origin(self.width, self.height)
            && self.origin == (0, 0)
        {
            format!("{}x{} {}", self.width, self.height, self.channel_list())
        } else {
            format!(
                "{} {} in display window {}",
                self.data_window(),
                self.channel_list(),
                self.display
            )
        };
        if let Some(name) = self.layer.as_ref().and_then(|l| l.name.as_deref()) {
            s += &format!(" (layer {})", if name.is_empty() { "\"\"" } else { name });
        }
        s
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

/// `s` with every run of whitespace, newlines included, as one space, and other control
/// characters escaped ([`escape_controls`]).
pub fn one_line(s: &str) -> String {
    escape_controls(&s.split_whitespace().collect::<Vec<_>>().join(" "))
}

/// `s` with each control character other than a space or a tab (ESC, NUL, a bell, C1 codes:
/// bytes an outside routine wrote that a terminal would act on) shown as `\u{1b}`, and line
/// breaks as `\n` and `\r`: an error stays one line of plain text.
pub fn escape_controls(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push(c),
            c if c.is_control() => out.push_str(&format!("\\u{{{:x}}}", c as u32)),
            c => out.push(c),
        }
    }
    out
}

/// Which layer of a multilayer EXR [`read_image_layer`] reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LayerSelect<'a> {
    /// A layer named `Combined` (Blender's beauty, `ViewLayer.Combined.R` …), else the first
    /// layer with `R`, `G` and `B` channels, else the file's only layer; several layers and none
    /// of these is an error that lists them.
    #[default]
    Default,
    /// The layer of this name: its whole prefix (`ViewLayer.Combined`), or its last part(s)
    /// when only one layer ends so (`Combined`); `""` names the channels without a prefix.
    Named(&'a str),
    /// As idiff reads a file (`--idiff-compat` without `--layer`): every channel of an EXR's
    /// first part; a PNG's colour associated with (multiplied by) its alpha as OpenImageIO
    /// associates it.
    AsIdiff,
}

/// Reads an OpenEXR or PNG image, recognised by its magic bytes, not its extension: the
/// default layer of an EXR ([`LayerSelect::Default`]), see [`read_image_layer`].
pub fn read_image(path: &Path) -> Result<Image, ImageError> {
    read_image_layer(path, LayerSelect::Default)
}

/// Reads an OpenEXR or PNG image, recognised by its magic bytes, not its extension.
///
/// EXR: the layer `select` picks (a layer is the channels sharing a name prefix, as
/// `ViewLayer.Combined.R/G/B/A` in Blender's multilayer files; the parts of a multipart file are
/// searched too, a part's name prefixing its channels), any sample type, as `f32`, with its data
/// window's origin and the display window; channels in OpenImageIO's order (`R`, `G`, `B`, `A`,
/// then the others; `X`, `Y`, `Z` in that order in a layer that has `X`). A single channel
/// (`Y`, `Z`, `R`) is one channel. Subsampled (luminance-chroma) and deep files are refused.
/// PNG: 8- or 16-bit, grey as one channel `Y` (with alpha `Y`, `A`), palettes as RGB(A), kept
/// display-referred (value / 255 or / 65535), as stored (straight alpha; [`LayerSelect::AsIdiff`]
/// associates it as OpenImageIO does), its `oFFs` offset (in pixels) as the data window's origin
/// as OpenImageIO reads it.
pub fn read_image_layer(path: &Path, select: LayerSelect) -> Result<Image, ImageError> {
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
        quietly(|| decode_exr(&bytes, select)).and_then(|r| r)
    } else if bytes.starts_with(&PNG_MAGIC) {
        match select {
            LayerSelect::Named(n) => Err(format!(
                "it is a PNG, which has no layer '{n}' (--layer names a layer of a multilayer EXR)"
            )),
            LayerSelect::AsIdiff => quietly(|| decode_png(&bytes, true)).and_then(|r| r),
            LayerSelect::Default => quietly(|| decode_png(&bytes, false)).and_then(|r| r),
        }
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

/// The most bytes a decoder may allocate for what is not pixels: a PNG's ICC profile (`iCCP`)
/// and compressed text (`zTXt`, `iTXt`), inflated. 16 MiB: real ICC profiles are kilobytes to
/// a few megabytes; a 1.5 MB `iCCP` chunk that inflated to 1.5 GB aborted rayproof.
pub const MAX_ANCILLARY_BYTES: u64 = 16 << 20;

/// Decodes `bytes` as `format` with the `image` crate, every allocation bounded: the header
/// under [`MAX_ANCILLARY_BYTES`]; then `declared(width, height, colour type)` checks the size it
/// declares against rayproof's limits and gives the samples it holds; then the pixels, under
/// those samples × `bytes_per_sample` + [`MAX_ANCILLARY_BYTES`] (the PNG decoder bounds every
/// chunk it inflates by that).
pub fn decode_bounded(
    bytes: &[u8],
    format: image::ImageFormat,
    bytes_per_sample: u64,
    declared: impl FnOnce(u32, u32, image::ColorType) -> Result<u64, String>,
) -> Result<image::DynamicImage, String> {
    use image::ImageDecoder;
    let reader = |cap: u64| {
        let mut r = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
        let mut l = image::Limits::default();
        l.max_alloc = Some(cap);
        r.limits(l);
        r
    };
    // A decoder's error, said plainly when it is the memory limit
    let said = |e: image::ImageError| match e {
        image::ImageError::Limits(e) => format!(
            "it needs more memory than its pixels and {} MiB of other data: refused ({e})",
            MAX_ANCILLARY_BYTES >> 20
        ),
        e => e.to_string(),
    };
    let header = reader(MAX_ANCILLARY_BYTES).into_decoder().map_err(said)?;
    let (w, h) = header.dimensions();
    let samples = declared(w, h, header.color_type())?;
    drop(header);
    reader(samples * bytes_per_sample + MAX_ANCILLARY_BYTES)
        .decode()
        .map_err(said)
}

/// The most channels rayproof reads from one EXR file, every part together: 1024 (Blender's
/// multilayer files with every pass and Cryptomatte hold about 100). A file of 10,000 layers of
/// a few pixels stays within `MAX_SAMPLES` but is refused by this.
pub const MAX_CHANNELS: u64 = 1024;
/// The most pixels rayproof reads from one image (8192²; also the largest image it renders).
pub const MAX_PIXELS: u64 = 1 << 26;
/// The most samples (pixels × channels, as the header declares them) rayproof reads from one
/// image file of any format: 2^28 = 8192² × 4 (RGBA). A decoder holds every channel of the
/// file, so the channel count is bounded too: an EXR of 8192² × 64 channels declared in 198 KB
/// aborted after allocating, and a valid 4 MB EXR of 16 channels took 5.8 GB.
pub const MAX_SAMPLES: u64 = 1 << 28;
/// The largest image file: 1088 MiB, an uncompressed float32 EXR of `MAX_SAMPLES` samples
/// (1 GiB) with room for its header and offset tables. The file is read whole before decoding.
pub const MAX_IMAGE_BYTES: u64 = 4 * MAX_SAMPLES + (64 << 20);

/// Checks an image's declared size against [`MAX_PIXELS`] and [`MAX_SAMPLES`]: one line if it
/// is too large.
pub(crate) fn check_declared(w: u64, h: u64, channels: u64) -> Result<(), String> {
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

/// `layer.suffix` as OpenImageIO splits it: the layer with its dot, and the suffix.
fn split_name(full: &str) -> (&str, &str) {
    match full.rfind('.') {
        Some(i) => (&full[..=i], &full[i + 1..]),
        None => ("", full),
    }
}

/// The order in which OpenImageIO presents an EXR's channels (`exrinput.cpp`, `ChanNameHolder`):
/// by layer, then `R`, `G`, `B`, `Y`, …, `A`, …, `Z` (case-insensitive), then by name; in a layer
/// with an `X` and a `Y` or `Z`, `X`, `Y`, `Z` come after `B`.
pub(super) fn oiio_order(names: &[String]) -> Vec<usize> {
    const SPECIAL: [&str; 20] = [
        "R", "Red", "G", "Green", "B", "Blue", "Y", "real", "imag", "A", "Alpha", "AR", "RA", "AG",
        "GA", "AB", "BA", "Z", "Depth", "Zback",
    ];
    const SPECIAL_XYZ: [&str; 21] = [
        "R", "Red", "G", "Green", "B", "Blue", "X", "Y", "Z", "real", "imag", "A", "Alpha", "AR",
        "RA", "AG", "GA", "AB", "BA", "Depth", "Zback",
    ];
    let has = |layer: &str, suffix: &str| {
        names.iter().any(|n| {
            let (l, s) = split_name(n);
            l == layer && s.eq_ignore_ascii_case(suffix)
        })
    };
    let mut order: Vec<usize> = (0..names.len()).collect();
    order.sort_by_cached_key(|&i| {
        let (layer, suffix) = split_name(&names[i]);
        let xyz = has(layer, "X") && (has(layer, "Y") || has(layer, "Z"));
        let list: &[&str] = if xyz { &SPECIAL_XYZ } else { &SPECIAL };
        let special = list
            .iter()
            .position(|t| t.eq_ignore_ascii_case(suffix))
            .unwrap_or(10_000);
        (layer.to_string(), special, suffix.to_string())
    });
    order
}

/// `a, b, ""` for a message.
fn layer_names(layers: &[String]) -> String {
    let q: Vec<String> = layers
        .iter()
        .map(|l| {
            if l.is_empty() {
                "\"\"".into()
            } else {
                l.clone()
            }
        })
        .collect();
    q.join(", ")
}

fn decode_exr(bytes: &[u8], select: LayerSelect) -> Result<Image, String> {
    use exr::prelude::*;
    // The declared sizes, against the limits and the file's own length, before any allocation:
    // the channels of every part, every part's pixels, and its channels (the decoder holds them
    // all)
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| e.to_string())?;
    let channels: u64 = meta
        .headers
        .iter()
        .map(|h| h.channels.list.len() as u64)
        .sum();
    if channels > MAX_CHANNELS {
        return Err(format!(
            "it declares {channels} channels in {} part(s); at most {MAX_CHANNELS} are read",
            meta.headers.len()
        ));
    }
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
        if let Some(c) = h.channels.list.iter().find(|c| c.sampling != Vec2(1, 1)) {
            return Err(format!(
                "its channel {} is subsampled ({}×{}); subsampled (luminance-chroma) files are not read",
                c.name, c.sampling.0, c.sampling.1
            ));
        }
    }
    // Decode every part, all channels, at full resolution
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .non_parallel()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| e.to_string())?;
    let parts = &image.layer_data;
    // Every channel: (part, index, full name, name as stored); a part's name prefixes its
    // channels in a multipart file, unless they carry it already
    let multipart = parts.len() > 1;
    let mut chans: Vec<(usize, usize, String, String)> = vec![];
    for (p, part) in parts.iter().enumerate() {
        let prefix = part
            .attributes
            .layer_name
            .as_ref()
            .map(|n| n.to_string())
            .filter(|n| multipart && !n.is_empty());
        for (k, c) in part.channel_data.list.iter().enumerate() {
            let name = c.name.to_string();
            let full = match &prefix {
                Some(pre) if !name.starts_with(&format!("{pre}.")) => format!("{pre}.{name}"),
                _ => name.clone(),
            };
            chans.push((p, k, full, name));
        }
    }
    let names: Vec<String> = chans.iter().map(|c| c.2.clone()).collect();
    let order = oiio_order(&names);
    let layer_of = |i: usize| split_name(&names[i]).0.trim_end_matches('.').to_string();
    let mut layers: Vec<String> = vec![];
    for &i in &order {
        if layers.last() != Some(&layer_of(i)) {
            layers.push(layer_of(i));
        }
    }
    // The layer asked for
    let (chosen, pick): (Option<String>, LayerPick) = match select {
        LayerSelect::AsIdiff => (None, LayerPick::All),
        LayerSelect::Named(n) => {
            let ends = |l: &String| l.ends_with(&format!(".{n}"));
            if layers.iter().any(|l| l == n) {
                (Some(n.to_string()), LayerPick::Named)
            } else {
                let found: Vec<&String> =
                    layers.iter().filter(|l| !n.is_empty() && ends(l)).collect();
                match found[..] {
                    [one] => (Some(one.clone()), LayerPick::Named),
                    [] => {
                        return Err(format!(
                            "it has no layer '{n}' (its layers: {})",
                            layer_names(&layers)
                        ))
                    }
                    _ => {
                        return Err(format!(
                            "'{n}' names several of its layers ({}): give the whole name",
                            layer_names(&found.into_iter().cloned().collect::<Vec<_>>())
                        ))
                    }
                }
            }
        }
        LayerSelect::Default => {
            let suffixes = |l: &String| -> Vec<&str> {
                order
                    .iter()
                    .filter(|&&i| layer_of(i) == *l)
                    .map(|&i| split_name(&names[i]).1)
                    .collect()
            };
            // Colour: R, G and B, or a luminance Y that is not a vector's (X, Y, Z)
            let colour = |l: &String| {
                let s = suffixes(l);
                let has = |c: &str| s.iter().any(|x| x.eq_ignore_ascii_case(c));
                ["R", "G", "B"].iter().all(|c| has(c)) || (has("Y") && !has("X") && !has("Z"))
            };
            // A layer named Combined is the beauty: the default when it is the one such layer
            // and has colour; two view layers' Combined, or a Combined without colour, are
            // not silently passed over: every layer is compared
            // Within the first part, as idiff (another part is another image: --layer picks it)
            let first: Vec<&String> = layers
                .iter()
                .filter(|l| order.iter().any(|&i| layer_of(i) == **l && chans[i].0 == 0))
                .collect();
            let combined: Vec<&String> = first
                .iter()
                .copied()
                .filter(|l| *l == "Combined" || l.ends_with(".Combined"))
                .collect();
            let coloured: Vec<&String> = first.iter().copied().filter(|l| colour(l)).collect();
            match (&combined[..], &coloured[..]) {
                ([l], _) if colour(l) => (Some((*l).clone()), LayerPick::Combined),
                ([_, ..], _) => (None, LayerPick::Every),
                ([], [l]) => ((*l).clone().into(), LayerPick::FirstRgb),
                ([], [_, _, ..]) => (None, LayerPick::Every),
                ([], []) if layers.len() == 1 => (Some(layers[0].clone()), LayerPick::Only),
                _ => {
                    return Err(format!(
                        "it has several layers and none has colour channels (R, G, B or Y): choose one with --layer (its layers: {})",
                        layer_names(&layers)
                    ))
                }
            }
        }
    };
    // Its channels, in order, all from one part; idiff reads the first part alone, its
    // channels as stored
    let picked: Vec<usize> = match &chosen {
        Some(l) => order
            .iter()
            .copied()
            .filter(|&i| layer_of(i) == *l)
            .collect(),
        // Every layer: every channel of the file's first part, in OpenImageIO's order
        None if pick == LayerPick::Every => {
            order.iter().copied().filter(|&i| chans[i].0 == 0).collect()
        }
        None => {
            let first: Vec<usize> = (0..chans.len()).filter(|&i| chans[i].0 == 0).collect();
            let stored: Vec<String> = first.iter().map(|&i| chans[i].3.clone()).collect();
            oiio_order(&stored).into_iter().map(|j| first[j]).collect()
        }
    };
    let part = chans[picked[0]].0;
    if picked.iter().any(|&i| chans[i].0 != part) {
        if pick == LayerPick::Every {
            return Err(format!(
                "its layers with colour channels are in several parts and none is Combined: choose one with --layer (its layers: {})",
                layer_names(&layers)
            ));
        }
        return Err(format!(
            "its layer '{}' is split over several parts",
            chosen.unwrap_or_default()
        ));
    }
    let layer = &parts[part];
    let (w, h) = (layer.size.width(), layer.size.height());
    // Each channel written straight into the interleaved samples (no planar f32 copy: an
    // 8192² RGBA file held its half samples, four float planes and the interleaved copy at once)
    let n = picked.len();
    let mut data = vec![0f32; w * h * n];
    let mut uint = Vec::new();
    for (k, &i) in picked.iter().enumerate() {
        let ch = &layer.channel_data.list[chans[i].1];
        if ch.sample_data.len() != w * h {
            return Err("channel size does not match the data window".into());
        }
        let slots = data.iter_mut().skip(k).step_by(n);
        // UINT: kept exactly, and scaled to [0, 1] as OpenImageIO reads it: the integer to
        // float first, then times the float 1/(2³² − 1) (so 16777216 and 16777217 are one
        // value there, as the real idiff says; tests/read_as_written.rs)
        match &ch.sample_data {
            exr::prelude::FlatSamples::U32(v) => {
                for (d, &x) in slots.zip(v) {
                    *d = x as f32 * (1.0 / u32::MAX as f32);
                }
                uint.push(Some(v.clone()));
            }
            other => {
                for (d, x) in slots.zip(other.values_as_f32()) {
                    *d = x;
                }
                uint.push(None);
            }
        }
    }
    // Name the channels within their layer (in full: all of them)
    let channel_names: Vec<&str> = picked
        .iter()
        .map(|&i| match pick {
            LayerPick::All => chans[i].3.as_str(),
            LayerPick::Every => names[i].as_str(),
            _ => split_name(&names[i]).1,
        })
        .collect();
    let mut img = self::Image::new(w, h, &channel_names, data);
    if uint.iter().any(|u| u.is_some()) {
        img.uint = uint;
    }
    let pos = layer.attributes.layer_position;
    img.origin = (pos.x() as i64, pos.y() as i64);
    let display = image.attributes.display_window;
    img.display = Window {
        x: display.position.x() as i64,
        y: display.position.y() as i64,
        width: display.size.width(),
        height: display.size.height(),
    };
    let plain = layers.len() == 1 && layers[0].is_empty() && !multipart;
    img.layer = (!plain).then_some(LayerInfo {
        name: chosen,
        pick,
        layers,
    });
    Ok(img)
}

/// What OpenImageIO takes from a PNG's chunks besides the pixels (`png_pvt.h`): the `oFFs`
/// offset when in pixels, and the gamma with which it associates alpha: 1 with an `sRGB` chunk
/// or without `gAMA`, else 1/gAMA rounded to hundredths (2.2 for 0.45455). The chunks before
/// the first `IDAT` are walked; the decoder checks them.
fn png_chunks(bytes: &[u8]) -> ((i64, i64), f32) {
    let (mut offset, mut gama, mut srgb) = ((0, 0), None, false);
    let mut i = 8;
    while let Some(head) = bytes.get(i..i + 8) {
        let n = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as usize;
        let Some(data) = bytes.get(i + 8..(i + 8).saturating_add(n)) else {
            break;
        };
        let be = |k: usize| [data[k], data[k + 1], data[k + 2], data[k + 3]];
        match &head[4..] {
            b"IDAT" => break,
            b"oFFs" if n == 9 && data[8] == 0 => {
                offset = (
                    i32::from_be_bytes(be(0)) as i64,
                    i32::from_be_bytes(be(4)) as i64,
                )
            }
            b"gAMA" if n == 4 => gama = Some(u32::from_be_bytes(be(0))),
            b"sRGB" => srgb = true,
            _ => {}
        }
        i += 12 + n;
    }
    let gamma = match gama {
        Some(g) if g > 0 && !srgb => {
            // libpng's gamma (× 0.00001 in double), inverted to float, rounded to hundredths
            let g = (1.0 / (g as f64 * 0.00001)) as f32;
            ((100.0 * g as f64) as f32).round() / 100.0
        }
        _ => 1.0,
    };
    (offset, gamma)
}

/// OpenImageIO's association of a PNG's colour with its alpha (`png_associateAlpha`), on the
/// code values: c·a / max in integers at gamma 1, else c·(a/max)^gamma truncated.
fn associate<T: Copy + Into<u32> + TryFrom<u32>>(data: &mut [T], n: usize, gamma: f32, max: u32) {
    let inv_max = (1.0 / max as f64) as f32;
    for px in data.chunks_mut(n) {
        let a: u32 = px[n - 1].into();
        let scale = ((a as f32 * inv_max) as f64).powf(gamma as f64) as f32;
        for c in &mut px[..n - 1] {
            let v: u32 = (*c).into();
            let v = if gamma == 1.0 {
                v * a / max
            } else {
                (v as f32 * scale) as u32
            };
            *c = T::try_from(v.min(max)).unwrap_or(*c);
        }
    }
}

fn decode_png(bytes: &[u8], associate_alpha: bool) -> Result<Image, String> {
    use image::{ColorType, DynamicImage};
    // The declared size against the limits, from the header alone (channels as decoded: Y,
    // YA, RGB or RGBA); then decoded, noting grey, alpha and 16-bit samples (2 bytes each)
    let mut grey = false;
    let img = decode_bounded(bytes, image::ImageFormat::Png, 2, |w, h, color| {
        grey = matches!(
            color,
            ColorType::L8 | ColorType::La8 | ColorType::L16 | ColorType::La16
        );
        let channels = if grey { 1 } else { 3 } + u64::from(color.has_alpha());
        check_declared(w as u64, h as u64, channels)?;
        Ok(w as u64 * h as u64 * channels)
    })?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let alpha = img.color().has_alpha();
    let wide = matches!(
        img.color(),
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16
    );
    // Grey as one channel Y (and A), as OpenImageIO reads it; palettes as RGB(A); the code
    // values, associated with alpha if asked, scaled to [0, 1]
    let names: &[&str] = match (grey, alpha) {
        (true, false) => &["Y"],
        (true, true) => &["Y", "A"],
        (false, false) => &["R", "G", "B"],
        (false, true) => &["R", "G", "B", "A"],
    };
    let (offset, gamma) = png_chunks(bytes);
    let n = names.len();
    let data: Vec<f32> = if wide {
        let mut v = match (grey, alpha) {
            (true, false) => img.to_luma16().into_raw(),
            (true, true) => img.to_luma_alpha16().into_raw(),
            (false, false) => DynamicImage::to_rgb16(&img).into_raw(),
            (false, true) => DynamicImage::to_rgba16(&img).into_raw(),
        };
        if alpha && associate_alpha {
            associate(&mut v, n, gamma, 65535);
        }
        scale(&v, 65535.0)
    } else {
        let mut v = match (grey, alpha) {
            (true, false) => img.to_luma8().into_raw(),
            (true, true) => img.to_luma_alpha8().into_raw(),
            (false, false) => DynamicImage::to_rgb8(&img).into_raw(),
            (false, true) => DynamicImage::to_rgba8(&img).into_raw(),
        };
        if alpha && associate_alpha {
            associate(&mut v, n, gamma, 255);
        }
        scale(&v, 255.0)
    };
    let mut out = Image::new(w, h, names, data);
    out.display_referred = true;
    out.origin = offset;
    out.display = Window {
        x: offset.0,
        y: offset.1,
        width: w,
        height: h,
    };
    Ok(out)
}

/// Code value × (1 / max) in float32, as OpenImageIO converts (so idiff and rayproof read the
/// same floats: `x / 255` differs from it in the last bit for some codes).
fn scale<T: Copy + Into<f32>>(v: &[T], max: f32) -> Vec<f32> {
    let inv = 1.0 / max;
    v.iter().map(|&x| x.into() * inv).collect()
}

/// Writes every channel of `img` as a float32 EXR, atomically, with its data and display
/// windows.
pub fn write_exr_rgb(path: &Path, img: &Image) -> anyhow::Result<()> {
    crate::output::write_atomic_with(path, |tmp| exr_to(tmp, img))
}

/// The EXR encoder (of [`write_exr_rgb`], `diff`'s image and every render), to `tmp` as given (a
/// temporary the caller stages, see [`crate::output::Outputs`]). Compressed on this thread: the
/// parallel writer starts a thread pool per file, whose threads cost more CPU than they save on
/// a frame, and it writes the blocks in whatever order they finish (a different file each run).
pub fn exr_to(tmp: &Path, img: &Image) -> anyhow::Result<()> {
    let n = img.channels.len();
    let planes = (0..n)
        .map(|c| {
            let plane = img.data.iter().skip(c).step_by(n).copied().collect();
            (img.channels[c].as_str(), plane)
        })
        .collect();
    exr_planes_to(
        tmp,
        (img.width, img.height),
        img.origin,
        img.display,
        planes,
    )
}

/// [`exr_to`] of planes: one float32 plane of `size` samples per named channel, in a single
/// layer whose data window starts at `origin` in the display window `display`.
pub fn exr_planes_to(
    tmp: &Path,
    size: (usize, usize),
    origin: (i64, i64),
    display: Window,
    planes: Vec<(&str, Vec<f32>)>,
) -> anyhow::Result<()> {
    use exr::prelude::*;
    let list: Vec<AnyChannel<FlatSamples>> = planes
        .into_iter()
        .map(|(name, plane)| {
            assert_eq!(plane.len(), size.0 * size.1, "EXR plane size");
            AnyChannel::new(name, FlatSamples::F32(plane))
        })
        .collect();
    // Its data window where it was, in its display window
    let i32_of = |v: i64| {
        i32::try_from(v).map_err(|_| anyhow::anyhow!("position {v} is beyond OpenEXR's range"))
    };
    let attributes = LayerAttributes {
        layer_position: Vec2(i32_of(origin.0)?, i32_of(origin.1)?),
        ..Default::default()
    };
    let layer = Layer::new(
        size,
        attributes,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(list.into()),
    );
    let d = display;
    let display = IntegerBounds::new(Vec2(i32_of(d.x)?, i32_of(d.y)?), (d.width, d.height));
    Ok(
        exr::prelude::Image::new(ImageAttributes::new(display), layer)
            .write()
            .non_parallel()
            .to_file(tmp)?,
    )
}

/// Writes 8-bit RGB (`w × h × 3` bytes) as a PNG, atomically.
pub fn write_png_rgb8(path: &Path, w: usize, h: usize, rgb: &[u8]) -> anyhow::Result<()> {
    crate::output::write_atomic_with(path, |tmp| png_rgb8_to(tmp, w, h, rgb))
}

/// [`write_png_rgb8`]'s encoder, to `tmp` as given (a temporary the caller stages).
pub fn png_rgb8_to(tmp: &Path, w: usize, h: usize, rgb: &[u8]) -> anyhow::Result<()> {
    let img = image::RgbImage::from_raw(w as u32, h as u32, rgb.to_vec())
        .ok_or_else(|| anyhow::anyhow!("{} bytes is not {w}x{h} RGB", rgb.len()))?;
    Ok(img.save_with_format(tmp, image::ImageFormat::Png)?)
}

/// Linear [0, 1] → 8-bit sRGB (ꟻLIP's `LinearRGB2sRGB`, then × 255 rounded).
pub fn srgb8(x: f64) -> u8 {
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
