//! HDR-ꟻLIP (and LDR-ꟻLIP for two PNGs) over `nv-flip`, and the magma heat map.
//!
//! HDR-ꟻLIP as NVlabs/flip does it; followed: `cpp/tool/FLIP-tool.cpp` (exposure loop, number of
//! exposures), `cpp/CPP/image.h` `computeExposures` and `cpp/CPP/tensor.h` `toneMap` (also
//! vendored in nv-flip-sys 0.1.1, `extern/cpp/CPP/`), and OIIO `imagebufalgo_flip.cpp` for the
//! median guard. Per exposure e: x ↦ sRGB8(clamp(ACES(2^e · x), 0, 1)) for both images, LDR-ꟻLIP
//! at 67 pixels per degree, and the per-pixel maximum over exposures.

use super::io::{srgb8, Image};
use serde::Serialize;

mod ldr;

/// ꟻLIP's default viewing: 67 pixels per degree (0.7 m from a 0.7 m wide 4K screen).
const PIXELS_PER_DEGREE: f32 = 67.0;

/// Which ꟻLIP the comparison carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FlipKind {
    /// Scene-linear input: exposures × ACES × sRGB, per-pixel max of LDR-ꟻLIP.
    Hdr,
    /// Both images display-referred (PNG): LDR-ꟻLIP of the stored values.
    Ldr,
}

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

/// R, G, B of pixel `p` with non-finite values and negatives replaced by 0 (ꟻLIP only).
fn sanitized(img: &Image, idx: [usize; 3], p: usize) -> [f64; 3] {
    let n = img.channels.len().max(1);
    let px = &img.data[p * n..(p + 1) * n];
    idx.map(|i| match px.get(i) {
        Some(&v) if v.is_finite() => (v as f64).max(0.0),
        _ => 0.0,
    })
}

/// (start, stop) exposures in stops, as ꟻLIP's `computeExposures`:
/// start = log2(x₀.₈₅ / Y_max), stop = log2(x₀.₈₅ / Y_median), Y = 0.2126R + 0.7152G + 0.0722B,
/// Y_median = mean of the sorted luminances at n/2 − 1 and n/2 (ꟻLIP's), floored at f32::EPSILON
/// as OIIO does (ꟻLIP itself would divide by 0 when most pixels are black). Found by selection,
/// not a sort: linear in the pixels.
fn exposure_range(rgb: impl Iterator<Item = [f64; 3]>) -> (f64, f64) {
    let mut y: Vec<f64> = rgb
        .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
        .collect();
    let n = y.len();
    let y_max = y
        .iter()
        .copied()
        .fold(0f64, f64::max)
        .max(f32::EPSILON as f64);
    let y_median = match n {
        0 => 0.0,
        1 => y[0],
        _ => {
            let (below, upper, _) = y.select_nth_unstable_by(n / 2, f64::total_cmp);
            let lower = below
                .iter()
                .copied()
                .max_by(f64::total_cmp)
                .unwrap_or(*upper);
            0.5 * (lower + *upper)
        }
    }
    .max(f32::EPSILON as f64);
    let x = aces_input_for_085();
    let start = (x / y_max).log2();
    (start, (x / y_median).log2().max(start))
}

/// One exposure's x ↦ sRGB8(clamp(ACES(m · x), 0, 1)) on a sample x, non-finite and negative
/// samples counting as 0: the same value as [`srgb8`] of [`aces`] in f64, without a `pow` per
/// sample. The map is a step function of x (both curves are nondecreasing), so it is held as
/// its 255 steps: `steps[k − 1]` is the least non-negative f32 that encodes to k or more, found
/// by bisection over the f32s' bit patterns (ordered as the values are). A sample's top 16 bits
/// pick one of 2¹⁶ buckets of 2¹⁵ consecutive f32s: its code is the bucket's first f32's, plus
/// one if it lies at or above the step inside the bucket, if there is one. A bucket spans 2⁻⁹
/// to 2⁻⁸ of its value and the steps lie about that far apart at the closest, so a bucket holds
/// at most one step inside (measured at exposures 10⁻¹² to 10¹² in steps of ×1.37); an exposure
/// where one holds more counts the steps at or below each sample instead
/// (`encode_is_srgb8_of_aces` checks every f16 and a million f32s against the direct
/// computation, both ways).
struct Exposure {
    steps: [f32; 255],
    /// Per bucket: the code of its first f32
    codes: Vec<u8>,
    /// Per bucket: the step strictly inside it (not on its first f32), or +∞
    inside: Vec<f32>,
    /// A bucket holds two steps or more inside: `codes` and `inside` are not used
    several: bool,
}

impl Exposure {
    fn new(m: f64) -> Exposure {
        let direct = |bits: u32| srgb8(aces(f32::from_bits(bits) as f64 * m));
        let finite = f32::MAX.to_bits();
        let steps: [f32; 255] = std::array::from_fn(|k| {
            // The least bit pattern in [0, MAX] encoding to k + 1 or more (MAX + 1 if none)
            let (mut lo, mut hi) = (0u32, finite + 1);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                match direct(mid) as usize > k {
                    true => hi = mid,
                    false => lo = mid + 1,
                }
            }
            match lo > finite {
                true => f32::INFINITY,
                false => f32::from_bits(lo),
            }
        });
        let code = |x: f32| steps.partition_point(|&t| t <= x) as u8;
        let codes: Vec<u8> = (0..1u32 << 16)
            .map(|b| code(f32::from_bits(b << 15)))
            .collect();
        // The steps strictly inside a bucket, one pass over the steps (they are sorted)
        let mut inside = vec![f32::INFINITY; 1 << 16];
        let mut several = false;
        for t in steps.iter().filter(|t| t.is_finite()) {
            let bits = t.to_bits();
            if bits & 0x7fff != 0 {
                let b = &mut inside[(bits >> 15) as usize];
                several |= b.is_finite();
                *b = b.min(*t);
            }
        }
        Exposure {
            steps,
            codes,
            inside,
            several,
        }
    }

    #[inline(always)]
    fn encode(&self, x: f32) -> u8 {
        // Non-finite, negative and NaN samples count as 0 (bucket 0's first f32; a step inside
        // bucket 0 lies above 0)
        let x = if x > 0.0 && x <= f32::MAX { x } else { 0.0 };
        if self.several {
            return self.steps.partition_point(|&t| t <= x) as u8;
        }
        let b = (x.to_bits() >> 15) as usize;
        self.codes[b] + (self.inside[b] <= x) as u8
    }

    /// `encode` of samples `idx` of each pixel (`n` samples each) of `src`, into `dst`.
    fn encode_rows(&self, src: &[f32], n: usize, idx: [usize; 3], dst: &mut [u8]) {
        if idx.iter().all(|&i| i < n) {
            for (o, px) in dst.chunks_exact_mut(3).zip(src.chunks_exact(n)) {
                for c in 0..3 {
                    o[c] = self.encode(px[idx[c]]);
                }
            }
        } else {
            for (o, px) in dst.chunks_exact_mut(3).zip(src.chunks(n)) {
                for c in 0..3 {
                    o[c] = self.encode(px.get(idx[c]).copied().unwrap_or(0.0));
                }
            }
        }
    }
}

/// Exposures encoded in one pass over the samples: the image's rows are read from memory once
/// for the group (a band's samples do not stay in cache from one exposure to the next).
const GROUP: usize = 4;

/// `encode` by each of `tables` of the samples `idx` of each pixel of `src` (`n` samples a
/// pixel): one 8-bit sRGB image per table. A chunk of pixels is encoded by every table while it
/// is in the L1 cache.
fn encode_group(tables: &[Exposure], src: &[f32], n: usize, idx: [usize; 3]) -> Vec<Vec<u8>> {
    const CHUNK: usize = 512;
    let px = src.len() / n;
    let mut outs: Vec<Vec<u8>> = tables.iter().map(|_| vec![0u8; px * 3]).collect();
    for (i, chunk) in src.chunks(CHUNK * n).enumerate() {
        let m = chunk.len() / n;
        for (t, o) in tables.iter().zip(outs.iter_mut()) {
            t.encode_rows(chunk, n, idx, &mut o[i * CHUNK * 3..(i * CHUNK + m) * 3]);
        }
    }
    outs
}

fn flip_ldr8(w: usize, h: usize, reference: &[u8], test: &[u8]) -> Vec<f32> {
    ldr::flip_rgb8(w, h, reference, test, PIXELS_PER_DEGREE)
}

fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| x as f64).sum::<f64>() / v.len().max(1) as f64
}

/// Rows above and below a band that ꟻLIP reads but does not keep: the larger of the radii of
/// its spatial filter (⌈3·√(0.04 / 2π²)·67⌉ = 10 at 67 pixels per degree) and of its feature
/// filter (⌈3 · ½ · 0.082 · 67⌉ = 9); `halo_is_the_filters_reach` checks it against the filters
/// the kernel makes. Its filters clamp at the image's edge and reach no further than their
/// radius (a pixel of the map is a function of the filtered values at that pixel alone), so a
/// band's rows come out bit for bit as over the whole image
/// (`banded_flip_is_the_whole_image_flip` checks it).
const HALO: usize = 10;

/// The rows of one band: about 2²⁰ pixels (ꟻLIP keeps some 200 bytes per pixel it is given, so
/// its memory is a band's, not the image's), and at least 256 rows, so that the halo costs at
/// most 5/64 more work.
fn band_rows(w: usize) -> usize {
    ((1 << 20) / w.max(1)).max(256)
}

/// `out[i] = max(out[i], m[i])`.
fn max_into(out: &mut [f32], m: &[f32]) {
    for (a, &e) in out.iter_mut().zip(m) {
        *a = a.max(e);
    }
}

/// The per-pixel maximum over `count` LDR-ꟻLIP maps of a `w × h` image, the k-th made from the
/// 8-bit sRGB rows `enc(k..k + j, y0, y1)[i]` gives for both images (rows `y0..y1`, exposure
/// k + i, [`GROUP`] exposures at most at a time). Computed in bands of
/// `rows` rows (each with [`HALO`] rows more above and below), spread over threads: by band
/// when there are enough bands, else by exposure within each band.
fn banded_flip<E>(w: usize, h: usize, rows: usize, count: usize, enc: E) -> Vec<f32>
where
    E: Fn(std::ops::Range<usize>, usize, usize) -> Vec<(Vec<u8>, Vec<u8>)> + Sync,
{
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let rows = rows.max(1);
    // One band's maximum map, its exposures over `split` threads
    let band = |b: usize, out: &mut [f32], split: usize| {
        let (y0, y1) = (b * rows, ((b + 1) * rows).min(h));
        let (lo, hi) = (y0.saturating_sub(HALO), (y1 + HALO).min(h));
        let one = |k: usize| {
            let (r, t) = &enc(k..k + 1, lo, hi)[0];
            flip_ldr8(w, hi - lo, r, t)
        };
        let keep = |out: &mut [f32], m: &[f32]| max_into(out, &m[(y0 - lo) * w..(y1 - lo) * w]);
        let split = split.clamp(1, count.max(1));
        if split == 1 {
            for k0 in (0..count).step_by(GROUP) {
                for (r, t) in enc(k0..(k0 + GROUP).min(count), lo, hi) {
                    keep(out, &flip_ldr8(w, hi - lo, &r, &t));
                }
            }
            return;
        }
        let maps: Vec<Vec<f32>> = std::thread::scope(|s| {
            let workers: Vec<_> = (0..split)
                .map(|j| {
                    let (one, keep) = (&one, &keep);
                    s.spawn(move || {
                        let mut acc = vec![0f32; (y1 - y0) * w];
                        for k in (j..count).step_by(split) {
                            let m = one(k);
                            keep(&mut acc, &m);
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
        for m in maps {
            max_into(out, &m);
        }
    };
    let mut map = vec![0f32; w * h];
    let mut bands: Vec<(usize, &mut [f32])> = map.chunks_mut(rows * w.max(1)).enumerate().collect();
    if bands.len() < threads {
        for (b, out) in bands {
            band(b, out, threads);
        }
    } else {
        // Bands dealt round-robin to the threads
        let mut per: Vec<Vec<(usize, &mut [f32])>> = (0..threads).map(|_| vec![]).collect();
        for (k, item) in bands.drain(..).enumerate() {
            per[k % threads].push(item);
        }
        std::thread::scope(|s| {
            for mine in per {
                let band = &band;
                s.spawn(move || {
                    for (b, out) in mine {
                        band(b, out, 1);
                    }
                });
            }
        });
    }
    map
}

/// HDR-ꟻLIP of two scene-linear images (R, G, B; non-finite and negative values count as 0):
/// the mean and the per-pixel error map in [0, 1]. The exposure range follows the reference
/// (the test if the reference is black); 0 when both are black. Its memory is the map, the
/// reference's luminances and a band per thread (`banded_flip`), not ꟻLIP's of the image.
/// Panics if the sizes differ (check with [`compare`](crate::images::compare) first).
pub fn hdr_flip(reference: &Image, test: &Image) -> (f64, Vec<f32>) {
    hdr_flip_in_bands(reference, test, band_rows(reference.width))
}

/// Every pixel's sanitised R, G, B.
fn pixels(img: &Image, idx: [usize; 3]) -> impl Iterator<Item = [f64; 3]> + '_ {
    (0..img.pixels()).map(move |p| sanitized(img, idx, p))
}

fn hdr_flip_in_bands(reference: &Image, test: &Image, rows: usize) -> (f64, Vec<f32>) {
    assert!(reference.width == test.width && reference.height == test.height);
    let (w, h) = (reference.width, reference.height);
    let (ri, ti) = (reference.rgb_indices(), test.rgb_indices());
    // Two black images have no error
    let black = |img: &Image, idx| pixels(img, idx).all(|p| p.iter().all(|&c| c == 0.0));
    let (rb, tb) = (black(reference, ri), black(test, ti));
    if rb && tb {
        return (0.0, vec![0.0; w * h]);
    }
    // The exposures: from the reference, or the test if the reference is black
    let (start, stop) = match rb {
        true => exposure_range(pixels(test, ti)),
        false => exposure_range(pixels(reference, ri)),
    };
    let count = ((stop - start).ceil() as usize).max(2);
    let step = (stop - start) / (count - 1) as f64;
    // Exposure k of rows y0..y1: sRGB8(ACES(2^e · x)), through each exposure's table
    let tables: Vec<Exposure> = (0..count)
        .map(|k| Exposure::new((start + k as f64 * step).exp2()))
        .collect();
    let enc = |ks: std::ops::Range<usize>, y0: usize, y1: usize| {
        let rows = |img: &Image, idx: [usize; 3]| {
            let n = img.channels.len().max(1);
            encode_group(
                &tables[ks.clone()],
                &img.data[y0 * w * n..y1 * w * n],
                n,
                idx,
            )
        };
        rows(reference, ri)
            .into_iter()
            .zip(rows(test, ti))
            .collect()
    };
    let map = banded_flip(w, h, rows, count, enc);
    (mean(&map), map)
}

/// LDR-ꟻLIP of two display-referred images (the stored values, clamped, as 8-bit sRGB), in
/// bands as [`hdr_flip`].
pub fn ldr_flip(reference: &Image, test: &Image) -> (f64, Vec<f32>) {
    assert!(reference.width == test.width && reference.height == test.height);
    let w = reference.width;
    let enc = |_: std::ops::Range<usize>, y0: usize, y1: usize| {
        let rows = |img: &Image| -> Vec<u8> {
            let n = img.channels.len().max(1);
            let idx = img.rgb_indices();
            img.data[y0 * w * n..y1 * w * n]
                .chunks(n)
                .flat_map(|p| idx.map(|i| (p[i].clamp(0.0, 1.0) * 255.0 + 0.5) as u8))
                .collect()
        };
        vec![(rows(reference), rows(test))]
    };
    let map = banded_flip(w, reference.height, band_rows(w), 1, enc);
    (mean(&map), map)
}

/// LDR-ꟻLIP if both images are display-referred (PNG), HDR-ꟻLIP otherwise.
pub fn flip_error(reference: &Image, test: &Image) -> (FlipKind, f64, Vec<f32>) {
    // Data windows that differ: both over their union (0 outside a data window)
    if reference.data_window() != test.data_window() {
        let window = reference.data_window().union(&test.data_window());
        return flip_error(&reference.padded(window), &test.padded(window));
    }
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

#[cfg(test)]
mod tests {
    use super::*;

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
        let (start, stop) = exposure_range(rgb.into_iter());
        let x = aces_input_for_085();
        assert!((start - (x / 8.0).log2()).abs() < 1e-12);
        assert!((stop - (x / 1.5).log2()).abs() < 1e-12);
        // Mostly black: the median is floored at f32::EPSILON, not 0
        let (_, stop) = exposure_range([px(0.0), px(0.0), px(0.0), px(1.0)].into_iter());
        assert!((stop - (x / f32::EPSILON as f64).log2()).abs() < 1e-9);
    }

    /// The exposure table gives what `srgb8(aces(m · x))` gives: every f16 (the samples of a half
    /// EXR) and a million f32s, at exposures from very dark to very bright.
    #[test]
    fn encode_is_srgb8_of_aces() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for (m, several) in [1e-9, 0.013, 0.5, 1.0, 3.7, 1e4, 1e30, 0.7]
            .into_iter()
            .zip([false, false, false, false, false, false, false, true])
        {
            let mut e = Exposure::new(m);
            assert!(!e.several, "m = {m}: a bucket with two steps");
            // The way taken if one did
            e.several = several;
            let direct = |x: f32| match x.is_finite() {
                true => srgb8(aces(x.max(0.0) as f64 * m)),
                false => srgb8(0.0),
            };
            let halves = (0..=u16::MAX).map(|h| exr::prelude::f16::from_bits(h).to_f32());
            let floats = (0..1_000_000).map(|_| f32::from_bits(rnd() as u32));
            for x in halves.chain(floats) {
                assert_eq!(
                    e.encode(x),
                    direct(x),
                    "x = {x:e} ({:#x}), m = {m}",
                    x.to_bits()
                );
            }
        }
    }

    #[test]
    fn halo_is_the_filters_reach() {
        assert_eq!(ldr::reach(PIXELS_PER_DEGREE), HALO);
    }

    /// The bands' map is the whole image's, bit for bit: bands of 1, 7 and 37 rows (each with
    /// its halo) against one band holding the image, on noise with edges and a bright spot.
    #[test]
    fn banded_flip_is_the_whole_image_flip() {
        let (w, h) = (29, 83);
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut a: Vec<f32> = (0..w * h * 3).map(|_| rnd() * 2.0).collect();
        let b: Vec<f32> = a.iter().map(|&v| v + 0.2 * rnd() - 0.1).collect();
        a[(40 * w + 10) * 3] = 60.0;
        let (a, b) = (Image::rgb(w, h, a), Image::rgb(w, h, b));
        let (m, whole) = hdr_flip_in_bands(&a, &b, h);
        assert!(m > 0.01, "{m}");
        for rows in [1, 7, 37] {
            let (mb, banded) = hdr_flip_in_bands(&a, &b, rows);
            assert_eq!(mb, m, "bands of {rows} rows");
            assert!(banded == whole, "bands of {rows} rows");
        }
    }
}
