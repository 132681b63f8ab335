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
/// for the group (a tile's samples do not stay in cache from one exposure to the next).
const GROUP: usize = 4;

/// `encode` by each of `tables` of the samples `idx` of each pixel of `src` (`w` pixels a row,
/// `n` samples a pixel) in `win`: one 8-bit sRGB image of `win` per table. A chunk of pixels is
/// encoded by every table while it is in the L1 cache.
fn encode_group(
    tables: &[&Exposure],
    src: &[f32],
    (w, n): (usize, usize),
    idx: [usize; 3],
    win: Rect,
) -> Vec<Vec<u8>> {
    const CHUNK: usize = 512;
    let mut outs: Vec<Vec<u8>> = tables.iter().map(|_| vec![0u8; win.pixels() * 3]).collect();
    let mut o = 0;
    for y in win.y0..win.y1 {
        for chunk in src[(y * w + win.x0) * n..(y * w + win.x1) * n].chunks(CHUNK * n) {
            let m = chunk.len() / n;
            for (t, out) in tables.iter().zip(outs.iter_mut()) {
                t.encode_rows(chunk, n, idx, &mut out[o * 3..(o + m) * 3]);
            }
            o += m;
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

/// Rows above and below a tile, and columns left and right of it, that ꟻLIP reads but does not
/// keep: the larger of the radii of its spatial filter (⌈3·√(0.04 / 2π²)·67⌉ = 10 at 67 pixels
/// per degree) and of its feature filter (⌈3 · ½ · 0.082 · 67⌉ = 9); `halo_is_the_filters_reach`
/// checks it against the filters the kernel makes. Its filters are separable, clamp at the
/// image's edge and reach no further than their radius along x, then along y (a pixel's
/// filtered values read the pixels within HALO of it in x and in y, and a pixel of the map is a
/// function of the filtered values at that pixel alone), so a tile's pixels come out bit for
/// bit as over the whole image (`tiled_flip_is_the_whole_image_flip` checks it).
const HALO: usize = 10;

/// Pixels of a tile: ꟻLIP keeps some 100 bytes per pixel it is given, so its memory is a
/// tile's per thread, not the image's.
const TILE_PIXELS: usize = 1 << 20;

/// A tile's least rows, where the image has them (the halo costs at most 5/64 more work), and
/// its least columns, where the image has them.
const TILE_MIN: usize = 256;

/// (columns, rows) of the tiles of a `w × h` image: whole rows, about [`TILE_PIXELS`] and at
/// least [`TILE_MIN`] of them (as the bands before the tiles), as long as that is no more than
/// [`TILE_PIXELS`]; a wider image is cut into columns of tiles of equal width, each about
/// [`TILE_PIXELS`] (8192 wide: 4096 × 256; 4194304 × 1: 2²⁰ × 1, where a whole row as one band
/// held 3.1× idiff's memory).
fn tile_shape(w: usize, h: usize) -> (usize, usize) {
    let (w, h) = (w.max(1), h.max(1));
    let rows = (TILE_PIXELS / w).max(TILE_MIN).min(h);
    let across = w.div_ceil((TILE_PIXELS / rows).max(TILE_MIN));
    (w.div_ceil(across), rows)
}

/// Columns `x0..x1` of rows `y0..y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rect {
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

impl Rect {
    fn width(&self) -> usize {
        self.x1.saturating_sub(self.x0)
    }

    fn pixels(&self) -> usize {
        self.width() * self.y1.saturating_sub(self.y0)
    }

    /// [`HALO`] more on each side, within a `w × h` image.
    fn grown(&self, (w, h): (usize, usize)) -> Rect {
        Rect {
            x0: self.x0.saturating_sub(HALO),
            x1: (self.x1 + HALO).min(w),
            y0: self.y0.saturating_sub(HALO),
            y1: (self.y1 + HALO).min(h),
        }
    }

    fn meet(&self, o: &Rect) -> Rect {
        Rect {
            x0: self.x0.max(o.x0),
            x1: self.x1.min(o.x1),
            y0: self.y0.max(o.y0),
            y1: self.y1.min(o.y1),
        }
    }

    /// Row `y` of `self` (`per` values a pixel) in a buffer of `of`.
    fn row_in<'a, T>(&self, buf: &'a [T], of: &Rect, y: usize, per: usize) -> &'a [T] {
        let i = ((y - of.y0) * of.width() + self.x0 - of.x0) * per;
        &buf[i..i + self.width() * per]
    }
}

/// The least rectangle of rows `rows` holding every column that `span(y)` says differs in row
/// y (as `(first, last + 1)`); `None` if no row does.
fn differing(
    rows: std::ops::Range<usize>,
    span: impl Fn(usize) -> Option<(usize, usize)>,
) -> Option<Rect> {
    let mut d: Option<Rect> = None;
    for y in rows {
        if let Some((x0, x1)) = span(y) {
            d = Some(match d {
                None => Rect {
                    x0,
                    x1,
                    y0: y,
                    y1: y + 1,
                },
                Some(d) => Rect {
                    x0: d.x0.min(x0),
                    x1: d.x1.max(x1),
                    y0: d.y0,
                    y1: y + 1,
                },
            });
        }
    }
    d
}

/// `(first, last + 1)` of the indices in `0..n` where `differs`.
fn span(n: usize, differs: impl Fn(usize) -> bool) -> Option<(usize, usize)> {
    let first = (0..n).find(|&i| differs(i))?;
    let last = (first..n).rev().find(|&i| differs(i))?;
    Some((first, last + 1))
}

/// The per-pixel maximum over `count` LDR-ꟻLIP maps of two `w × h` images, the k-th made from
/// the 8-bit sRGB images `enc(ks, win)[i]` gives for both images over the rectangle `win`
/// (exposure `ks[i]`, [`GROUP`] exposures at most at a time). Computed in tiles of `tile`
/// (columns, rows), each with [`HALO`] more on each side, spread over threads (each tile's
/// exposures over several when there are fewer tiles than threads).
///
/// Work that is provably zero is skipped (`skip`): where two images agree on every pixel within
/// [`HALO`] of a pixel, in x and in y, ꟻLIP's two inputs there are the same, and so are their
/// filtered values: the colour difference is 0, 0^0.7 = 0, and 0 to the power
/// 1 − √(feature difference of 0) = 1 is 0 (exactly +0.0, as the map starts). So a tile is
/// computed only within [`HALO`] of the pixels where the images' R, G, B differ bit for bit
/// (any encoding of equal samples is equal; none: the tile is skipped, as the black outside a
/// data window is), and each exposure only within [`HALO`] of the pixels whose codes differ
/// there (a frame that saturates to 255, or stays 0, in both images at an exposure costs
/// nothing at it). `skip_is_exact` checks the map bit for bit against the one with nothing
/// skipped.
fn tiled_flip<E>(
    reference: &Image,
    test: &Image,
    tile: (usize, usize),
    count: usize,
    skip: bool,
    enc: E,
) -> Vec<f32>
where
    E: Fn(&[usize], Rect) -> Vec<(Vec<u8>, Vec<u8>)> + Sync,
{
    let (w, h) = (reference.width, reference.height);
    let (cols, rows) = (tile.0.max(1), tile.1.max(1));
    let tiles: Vec<Rect> = (0..h)
        .step_by(rows)
        .flat_map(|y0| {
            (0..w).step_by(cols).map(move |x0| Rect {
                x0,
                x1: (x0 + cols).min(w),
                y0,
                y1: (y0 + rows).min(h),
            })
        })
        .collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let split = (threads / tiles.len().max(1)).clamp(1, count.max(1));
    // Where the images differ: R, G, B bit for bit (a missing channel as 0, as it is encoded)
    let (ri, ti) = (reference.rgb_indices(), test.rgb_indices());
    let (rn, tn) = (reference.channels.len().max(1), test.channels.len().max(1));
    let rgb = |data: &[f32], n: usize, idx: [usize; 3], p: usize| {
        idx.map(|i| data[p * n..(p + 1) * n].get(i).map_or(0, |v| v.to_bits()))
    };
    let raw = |y: usize, r: &Rect| {
        let p = |x: usize| y * w + r.x0 + x;
        span(r.width(), |x| {
            rgb(&reference.data, rn, ri, p(x)) != rgb(&test.data, tn, ti, p(x))
        })
        .map(|(a, b)| (r.x0 + a, r.x0 + b))
    };
    let map = std::sync::Mutex::new(vec![0f32; w * h]);
    let one = |item: usize| {
        let (core, part) = (tiles[item / split], item % split);
        // Where this tile's map can be other than 0
        let reach = match skip {
            true => {
                let win = core.grown((w, h));
                match differing(win.y0..win.y1, |y| raw(y, &win)) {
                    Some(d) => d.grown((w, h)).meet(&core),
                    None => return,
                }
            }
            false => core,
        };
        if reach.pixels() == 0 {
            return;
        }
        let win = reach.grown((w, h));
        let mut acc = vec![0f32; reach.pixels()];
        let ks: Vec<usize> = (part..count).step_by(split).collect();
        for group in ks.chunks(GROUP) {
            for (r, t) in enc(group, win) {
                // Where this exposure's map can be other than 0
                let keep = match skip {
                    true => {
                        let codes = |y| {
                            span(win.width(), |x| {
                                let i = ((y - win.y0) * win.width() + x) * 3;
                                r[i..i + 3] != t[i..i + 3]
                            })
                        };
                        let codes = |y| codes(y).map(|(a, b)| (win.x0 + a, win.x0 + b));
                        match differing(win.y0..win.y1, codes) {
                            Some(d) => d.grown((w, h)).meet(&reach),
                            None => continue,
                        }
                    }
                    false => reach,
                };
                if keep.pixels() == 0 {
                    continue;
                }
                let sub = keep.grown((w, h));
                let m = match sub == win {
                    true => flip_ldr8(win.width(), win.y1 - win.y0, &r, &t),
                    false => {
                        let crop = |v: &[u8]| -> Vec<u8> {
                            (sub.y0..sub.y1)
                                .flat_map(|y| sub.row_in(v, &win, y, 3).iter().copied())
                                .collect()
                        };
                        flip_ldr8(sub.width(), sub.y1 - sub.y0, &crop(&r), &crop(&t))
                    }
                };
                for y in keep.y0..keep.y1 {
                    let i = (y - reach.y0) * reach.width() + keep.x0 - reach.x0;
                    max_into(&mut acc[i..i + keep.width()], keep.row_in(&m, &sub, y, 1));
                }
            }
        }
        let mut map = map.lock().expect("the FLIP map");
        for y in reach.y0..reach.y1 {
            let (i, j) = (y * w + reach.x0, (y - reach.y0) * reach.width());
            max_into(&mut map[i..i + reach.width()], &acc[j..j + reach.width()]);
        }
    };
    let items = tiles.len() * split;
    let next = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|s| {
        for _ in 0..threads.min(items) {
            s.spawn(|| loop {
                match next.fetch_add(1, std::sync::atomic::Ordering::Relaxed) {
                    i if i < items => one(i),
                    _ => break,
                }
            });
        }
    });
    map.into_inner().expect("the FLIP map")
}

/// `out[i] = max(out[i], m[i])`.
fn max_into(out: &mut [f32], m: &[f32]) {
    for (a, &e) in out.iter_mut().zip(m) {
        *a = a.max(e);
    }
}

/// HDR-ꟻLIP of two scene-linear images (R, G, B; non-finite and negative values count as 0):
/// the mean and the per-pixel error map in [0, 1]. The exposure range follows the reference
/// (the test if the reference is black); 0 when both are black. Its memory is the map, the
/// reference's luminances and a tile per thread (`tiled_flip`), not ꟻLIP's of the image.
/// Panics if the sizes differ (check with [`compare`](crate::images::compare) first).
pub fn hdr_flip(reference: &Image, test: &Image) -> (f64, Vec<f32>) {
    let tile = tile_shape(reference.width, reference.height);
    hdr_flip_tiled(reference, test, tile, true)
}

/// Every pixel's sanitised R, G, B.
fn pixels(img: &Image, idx: [usize; 3]) -> impl Iterator<Item = [f64; 3]> + '_ {
    (0..img.pixels()).map(move |p| sanitized(img, idx, p))
}

fn hdr_flip_tiled(
    reference: &Image,
    test: &Image,
    tile: (usize, usize),
    skip: bool,
) -> (f64, Vec<f32>) {
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
    // Exposure k: sRGB8(ACES(2^e · x)), through each exposure's table
    let tables: Vec<Exposure> = (0..count)
        .map(|k| Exposure::new((start + k as f64 * step).exp2()))
        .collect();
    let enc = |ks: &[usize], win: Rect| {
        let tables: Vec<&Exposure> = ks.iter().map(|&k| &tables[k]).collect();
        let codes = |img: &Image, idx: [usize; 3]| {
            let n = img.channels.len().max(1);
            encode_group(&tables, &img.data, (w, n), idx, win)
        };
        codes(reference, ri)
            .into_iter()
            .zip(codes(test, ti))
            .collect()
    };
    let map = tiled_flip(reference, test, tile, count, skip, enc);
    (mean(&map), map)
}

/// LDR-ꟻLIP of two display-referred images (the stored values, clamped, as 8-bit sRGB), in
/// tiles as [`hdr_flip`].
pub fn ldr_flip(reference: &Image, test: &Image) -> (f64, Vec<f32>) {
    assert!(reference.width == test.width && reference.height == test.height);
    let w = reference.width;
    let enc = |_: &[usize], win: Rect| {
        let codes = |img: &Image| -> Vec<u8> {
            let n = img.channels.len().max(1);
            let idx = img.rgb_indices();
            (win.y0..win.y1)
                .flat_map(|y| img.data[(y * w + win.x0) * n..(y * w + win.x1) * n].chunks(n))
                .flat_map(|p| idx.map(|i| (p[i].clamp(0.0, 1.0) * 255.0 + 0.5) as u8))
                .collect()
        };
        vec![(codes(reference), codes(test))]
    };
    let tile = tile_shape(w, reference.height);
    let map = tiled_flip(reference, test, tile, 1, true, enc);
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

    /// Noise with edges and a bright spot (`a`), and `a` changed a little (`b`).
    fn noise_pair(w: usize, h: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
        let mut seed = seed;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut a: Vec<f32> = (0..w * h * 3).map(|_| rnd() * 2.0).collect();
        let b: Vec<f32> = a.iter().map(|&v| v + 0.2 * rnd() - 0.1).collect();
        a[((h / 2) * w + w / 3) * 3] = 60.0;
        (a, b)
    }

    /// The tiles' map is the whole image's, bit for bit: tiles of whole rows (1, 7 and 37 of
    /// them), of a few columns, and of a single pixel (each with its halo) against one tile
    /// holding the image, nothing skipped, on noise with edges and a bright spot.
    #[test]
    fn tiled_flip_is_the_whole_image_flip() {
        let (w, h) = (29, 83);
        let (a, b) = noise_pair(w, h, 0x9e37_79b9_7f4a_7c15);
        let (a, b) = (Image::rgb(w, h, a), Image::rgb(w, h, b));
        let (m, whole) = hdr_flip_tiled(&a, &b, (w, h), false);
        assert!(m > 0.01, "{m}");
        for tile in [(w, 1), (w, 7), (w, 37), (5, h), (7, 37), (13, 11), (1, 1)] {
            let (mt, tiled) = hdr_flip_tiled(&a, &b, tile, false);
            assert_eq!(mt, m, "tiles of {tile:?}");
            assert!(tiled == whole, "tiles of {tile:?}");
        }
    }

    /// A very wide image is cut into columns of tiles (its memory is a tile's per thread, not a
    /// row's), a normal one into bands of whole rows as before, a tall narrow one into bands.
    #[test]
    fn tiles_are_bounded_for_every_shape() {
        assert_eq!(tile_shape(3840, 2160), (3840, 273));
        assert_eq!(tile_shape(2048, 2048), (2048, 512));
        assert_eq!(tile_shape(8192, 8192), (4096, 256));
        assert_eq!(tile_shape(4_194_304, 1), (1 << 20, 1));
        assert_eq!(tile_shape(1, 4_194_304), (1, 1 << 20));
        for (w, h) in [
            (4_194_304, 1),
            (1 << 22, 3),
            (100_000, 300),
            (5000, 5000),
            (1, 1 << 22),
        ] {
            let (c, r) = tile_shape(w, h);
            let window = (c + 2 * HALO).min(w) * (r + 2 * HALO).min(h);
            assert!(window <= 2 * TILE_PIXELS, "{w}×{h}");
        }
    }

    /// Skipping the work that is provably zero leaves the map bit for bit as computed in full:
    /// a frame mostly exact black in both (its median black: ~24 exposures), an area the same in
    /// both, one that saturates in both at the high exposures, NaN, −0, negatives and ∞ in
    /// places, in tiles of several shapes; and a pair that differs in one pixel.
    #[test]
    fn skip_is_exact() {
        let (w, h) = (61, 97);
        let (mut a, mut b) = noise_pair(w, h, 0x2545_f491_4f6c_dd1d);
        for y in 0..h {
            for x in 0..w {
                let p = (y * w + x) * 3;
                for c in 0..3 {
                    match (x, y) {
                        // black in both, but a −0 here and there
                        _ if y >= 40 || x >= 45 => {
                            a[p + c] = 0.0;
                            b[p + c] = if (x + y) % 7 == 0 { -0.0 } else { 0.0 };
                        }
                        // the same in both
                        _ if y < 12 => b[p + c] = a[p + c],
                        // bright: saturates in both at the higher exposures
                        _ if x < 8 => (a[p + c], b[p + c]) = (50.0 + a[p + c], 40.0 + b[p + c]),
                        _ => {}
                    }
                }
            }
        }
        (a[(20 * w + 20) * 3], b[(21 * w + 30) * 3 + 1]) = (f32::NAN, -3.0);
        b[(5 * w + 5) * 3 + 2] = f32::INFINITY;
        let (a, b) = (Image::rgb(w, h, a), Image::rgb(w, h, b));
        let (m, full) = hdr_flip_tiled(&a, &b, (w, h), false);
        assert!(m > 0.001, "{m}");
        assert!(full[(h - 1) * w..].iter().all(|&e| e == 0.0));
        for tile in [(w, h), (w, 9), (17, 13), (4, 50)] {
            let (ms, skipped) = hdr_flip_tiled(&a, &b, tile, true);
            assert_eq!(ms, m, "tiles of {tile:?}");
            let differ = skipped
                .iter()
                .zip(&full)
                .filter(|(s, f)| s.to_bits() != f.to_bits())
                .count();
            assert_eq!(differ, 0, "tiles of {tile:?}");
        }
        // One pixel apart: only its reach is computed, and it is what the full map says
        let mut c = a.clone();
        c.data[(30 * w + 30) * 3] += 0.5;
        let (m1, one) = hdr_flip_tiled(&a, &c, (w, h), true);
        let (m2, all) = hdr_flip_tiled(&a, &c, (w, h), false);
        assert!(m1 > 0.0 && m1 == m2 && one == all);
    }
}
