//! Image files as renderers write them: the formats `rayproof check` reads (every one the
//! `exr` crate and the `image` crate's enabled decoders read), the format a suite declares for
//! its renderer's output (`output = "png"`), and the checks a test image passes before it is
//! compared or blessed.
//!
//! A test image is refused (one line naming the problem) when the renderer wrote a directory, a
//! symbolic link (it could point at the golden itself), an empty or truncated file, a file of
//! another format than the one declared, or an EXR of more than [`MAX_EXR_LAYERS`] layers.
//!
//! OpenEXR and PNG are read by [`crate::images::read_image`]; the other formats here, with the
//! same limits on their declared size: 8- and 16-bit images (JPEG, TIFF, BMP, TGA, PNM, GIF,
//! WebP, QOI, ICO, DDS, farbfeld) are display-referred code values / 255 or / 65535 as PNG is,
//! float images (Radiance HDR, float TIFF) scene-linear; grey is expanded to RGB.

use crate::images::{self, Image, MAX_PIXELS};
use image::ImageFormat;
use std::path::Path;

/// The most layers an EXR test image or reference may have: 256, counting each part and, in a
/// part, each group of channels named `LAYER.CHANNEL` (Blender's multilayer files: one part,
/// `ViewLayer.Combined.R` …; a few view layers × a few dozen passes). A test image is one
/// picture: a file of 10,000 layers is not a renderer's frame. Measured with the reader before
/// this limit: 10,000 parts of 64² px took 2.2 s and 537 MB to read one of them (a 508 MB file),
/// and 10,000 layers as channel groups of one part were refused with a 300 KB "line" naming
/// every channel. Counted from the headers, before anything is decoded.
pub const MAX_EXR_LAYERS: usize = 256;

/// The longest message about one file: a refusal is one line of a table.
const MAX_MESSAGE: usize = 400;

/// The largest image file read: the cap of [`crate::images::read_image`] (1088 MiB, an
/// uncompressed float32 EXR of 8192² × 4 samples with its tables).
const MAX_FILE_BYTES: u64 = 16 * MAX_PIXELS + (64 << 20);

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// An image file format rayproof reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// OpenEXR (the `exr` crate).
    Exr,
    /// A format the `image` crate reads.
    Other(ImageFormat),
}

impl Format {
    /// The format a file name extension names (`exr`, `png`, `jpg`, `tif`, `ppm`, …), if it is
    /// one rayproof reads.
    pub fn from_ext(ext: &str) -> Option<Format> {
        let ext = ext.to_ascii_lowercase();
        if ext == "exr" {
            return Some(Format::Exr);
        }
        ImageFormat::from_extension(&ext)
            .filter(|f| f.reading_enabled() && *f != ImageFormat::OpenExr)
            .map(Format::Other)
    }

    /// The format of a path's extension.
    pub fn of_path(p: &Path) -> Option<Format> {
        p.extension()
            .and_then(|e| e.to_str())
            .and_then(Format::from_ext)
    }

    /// Its name in messages: `OpenEXR`, `PNG`, `JPEG`, ….
    pub fn name(self) -> String {
        match self {
            Format::Exr => "OpenEXR".into(),
            Format::Other(f) => format!("{f:?}")
                .to_uppercase()
                .replace("FARBFELD", "farbfeld"),
        }
    }

    /// The extensions that name it, the usual one first.
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            Format::Exr => &["exr"],
            Format::Other(f) => f.extensions_str(),
        }
    }
}

/// The extensions `output` may name, for an error message.
pub fn known_extensions() -> String {
    let mut v = vec!["exr".to_string()];
    for f in ImageFormat::all() {
        if f.reading_enabled() && f != ImageFormat::OpenExr {
            v.extend(f.extensions_str().iter().map(|e| e.to_string()));
        }
    }
    v.join(", ")
}

/// The format of a file's bytes, by their magic numbers (TGA has none: `None`).
pub fn sniff(bytes: &[u8]) -> Option<Format> {
    if bytes.starts_with(&EXR_MAGIC) {
        return Some(Format::Exr);
    }
    image::guess_format(bytes)
        .ok()
        .filter(|f| f.reading_enabled())
        .map(Format::Other)
}

/// A test image, checked and decoded: the image, the exact bytes it was decoded from (what
/// `--update` blesses), and their format.
pub struct TestImage {
    /// The decoded image.
    pub image: Image,
    /// The file's bytes.
    pub bytes: Vec<u8>,
    /// Their format, by their magic numbers (TGA: as declared).
    pub format: Format,
}

/// Reads a file a renderer wrote (or a test's image), refusing what cannot be a test image: a
/// directory, a symbolic link, a device, an empty or truncated file, a file whose format is not
/// `declared` (when the suite declares one), an EXR of too many parts. One line, without the
/// path (the row names the test).
pub fn read_test_image(path: &Path, declared: Option<Format>) -> Result<TestImage, String> {
    // What is at the path: a regular file, not a link to one
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(format!("no file at {}", path.display()))
        }
        Err(e) => return Err(format!("{}: {e}", path.display())),
    };
    let kind = meta.file_type();
    if kind.is_symlink() {
        return Err(format!(
            "{} is a symbolic link, not an image file (a link could point at any file, the golden too)",
            path.display()
        ));
    }
    if kind.is_dir() {
        return Err(format!(
            "{} is a directory, not an image file",
            path.display()
        ));
    }
    if !kind.is_file() {
        return Err(format!(
            "{} is not a regular file (a device, a FIFO or a socket is not read)",
            path.display()
        ));
    }
    if meta.len() == 0 {
        return Err(format!("{} is empty (0 bytes)", path.display()));
    }
    let bytes = crate::input::read_capped(path, MAX_FILE_BYTES, crate::input::Kind::Regular)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    // Its format, by its bytes, against the declared one
    let format = match (sniff(&bytes), declared) {
        (Some(f), Some(d)) if f != d => {
            return Err(format!(
                "{} is a {} file, but the test's output format is {}",
                path.display(),
                f.name(),
                d.name()
            ))
        }
        (Some(f), _) => f,
        // TGA has no magic number: it is what its decoder makes of it
        (None, Some(Format::Other(ImageFormat::Tga))) => Format::Other(ImageFormat::Tga),
        (None, Some(d)) => {
            return Err(format!(
            "{} is not a file of the test's output format, {} (nor of any format rayproof reads)",
            path.display(),
            d.name()
        ))
        }
        (None, None) => {
            return Err(format!(
                "{} is not an image file rayproof reads ({})",
                path.display(),
                known_extensions()
            ))
        }
    };
    let image = decode(path, &bytes, format)?;
    Ok(TestImage {
        image,
        bytes,
        format,
    })
}

/// Reads a reference (or a variance image): any format rayproof reads, by its magic numbers.
pub fn read_any(path: &Path) -> Result<Image, String> {
    let bytes = crate::input::read_capped(path, MAX_FILE_BYTES, crate::input::Kind::Regular)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    match sniff(&bytes) {
        Some(f) => decode(path, &bytes, f),
        None if Format::of_path(path) == Some(Format::Other(ImageFormat::Tga)) => {
            decode(path, &bytes, Format::Other(ImageFormat::Tga))
        }
        // EXR and PNG readers say what is wrong with an empty or unknown file
        None => images::read_image(path).map_err(|e| shorten(e.to_string())),
    }
}

/// Decodes `bytes` (read from `path`) as `format`.
fn decode(path: &Path, bytes: &[u8], format: Format) -> Result<Image, String> {
    let fail = |why: String| format!("cannot read {}: {}", path.display(), images::one_line(&why));
    match format {
        Format::Exr => {
            // Count the parts from the headers before anything is decoded
            let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
                .map_err(|e| fail(e.to_string()))?;
            let layers: usize = meta
                .headers
                .iter()
                .map(|h| {
                    let mut groups: Vec<String> = h
                        .channels
                        .list
                        .iter()
                        .map(|c| {
                            let n = c.name.to_string();
                            n.rsplit_once('.')
                                .map(|(g, _)| g.to_string())
                                .unwrap_or_default()
                        })
                        .collect();
                    groups.sort();
                    groups.dedup();
                    groups.len().max(1)
                })
                .sum();
            if layers > MAX_EXR_LAYERS {
                return Err(fail(format!(
                    "it has {layers} layers (in {} part(s)); at most {MAX_EXR_LAYERS} are read",
                    meta.headers.len()
                )));
            }
            read_same(path, bytes).map_err(shorten)
        }
        Format::Other(ImageFormat::Png) => read_same(path, bytes).map_err(shorten),
        Format::Other(f) => decode_other(bytes, f).map_err(fail).map_err(shorten),
    }
}

/// A message cut to [`MAX_MESSAGE`] characters (a decoder may list every channel of a file).
fn shorten(s: String) -> String {
    let n = s.chars().count();
    if n <= MAX_MESSAGE {
        return s;
    }
    let head: String = s.chars().take(MAX_MESSAGE).collect();
    format!("{head} … ({} more characters)", n - MAX_MESSAGE)
}

/// [`images::read_image`] on `path`, which must still hold `bytes` (the bytes checked and
/// blessed are the bytes compared).
fn read_same(path: &Path, bytes: &[u8]) -> Result<Image, String> {
    let img = images::read_image(path).map_err(|e| e.to_string())?;
    let again = crate::input::read_capped(path, MAX_FILE_BYTES, crate::input::Kind::Regular)
        .unwrap_or_default();
    if again != bytes {
        return Err(format!(
            "{} changed while it was read: not compared",
            path.display()
        ));
    }
    Ok(img)
}

/// Decodes a format of the `image` crate, its declared size checked first.
fn decode_other(bytes: &[u8], f: ImageFormat) -> Result<Image, String> {
    use image::ColorType;
    // The declared size against the limits (RGB or RGBA as decoded), then the pixels, every
    // allocation bounded (4 bytes a sample: the float formats)
    let img = crate::images::decode_bounded(bytes, f, 4, |w, h, color| {
        let channels = 3 + u64::from(color.has_alpha());
        crate::images::check_declared(w as u64, h as u64, channels)?;
        Ok(w as u64 * h as u64 * channels)
    })?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w * h == 0 {
        return Err("the image has no pixels".into());
    }
    let alpha = img.color().has_alpha();
    let float = matches!(img.color(), ColorType::Rgb32F | ColorType::Rgba32F);
    let wide = matches!(
        img.color(),
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16
    );
    let scale = |v: &[f32], max: f32| -> Vec<f32> {
        let inv = 1.0 / max;
        v.iter().map(|&x| x * inv).collect()
    };
    let data: Vec<f32> = match (float, wide, alpha) {
        (true, _, false) => img.to_rgb32f().into_raw(),
        (true, _, true) => img.to_rgba32f().into_raw(),
        (false, false, false) => scale(
            &img.to_rgb8().iter().map(|&x| x as f32).collect::<Vec<_>>(),
            255.0,
        ),
        (false, false, true) => scale(
            &img.to_rgba8().iter().map(|&x| x as f32).collect::<Vec<_>>(),
            255.0,
        ),
        (false, true, false) => scale(
            &img.to_rgb16().iter().map(|&x| x as f32).collect::<Vec<_>>(),
            65535.0,
        ),
        (false, true, true) => scale(
            &img.to_rgba16()
                .iter()
                .map(|&x| x as f32)
                .collect::<Vec<_>>(),
            65535.0,
        ),
    };
    let names: &[&str] = if alpha {
        &["R", "G", "B", "A"]
    } else {
        &["R", "G", "B"]
    };
    let mut out = Image::new(w, h, names, data);
    out.display_referred = !float;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extensions_name_formats_and_bytes_are_sniffed() {
        assert_eq!(Format::from_ext("EXR"), Some(Format::Exr));
        assert_eq!(
            Format::from_ext("png"),
            Some(Format::Other(ImageFormat::Png))
        );
        assert_eq!(
            Format::from_ext("jpg"),
            Some(Format::Other(ImageFormat::Jpeg))
        );
        assert_eq!(
            Format::from_ext("ppm"),
            Some(Format::Other(ImageFormat::Pnm))
        );
        assert_eq!(Format::from_ext("txt"), None);
        assert_eq!(sniff(&[0x76, 0x2f, 0x31, 0x01, 2]), Some(Format::Exr));
        assert_eq!(
            sniff(b"P6\n2 2\n255\n"),
            Some(Format::Other(ImageFormat::Pnm))
        );
        assert_eq!(sniff(b"hello"), None);
        assert!(known_extensions().contains("tiff"));
    }

    #[test]
    fn a_ppm_decodes_as_display_referred_rgb() {
        let ppm = b"P6\n2 1\n255\n\xff\x00\x00\x00\x00\xff";
        let img = decode_other(ppm, ImageFormat::Pnm).unwrap();
        assert_eq!((img.width, img.height), (2, 1));
        assert!(img.display_referred);
        assert_eq!(img.data, [1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    }
}
