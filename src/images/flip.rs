//! HDR-ꟻLIP (and LDR-ꟻLIP for two PNGs) over `nv-flip`, and the magma heat map.
//!
//! HDR-ꟻLIP as NVlabs/flip does it; followed: `cpp/tool/FLIP-tool.cpp` (exposure loop, number of
//! exposures), `cpp/CPP/image.h` `computeExposures` and `cpp/CPP/tensor.h` `toneMap` (also
//! vendored in nv-flip-sys 0.1.1, `extern/cpp/CPP/`), and OIIO `imagebufalgo_flip.cpp` for the
//! median guard. Per exposure e: x ↦ sRGB8(clamp(ACES(2^e · x), 0, 1)) for both images, LDR-ꟻLIP
//! at 67 pixels per degree, and the per-pixel maximum over exposures.

use super::io::{srgb8, Image};
use serde::Serialize;

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
/// Panics if the sizes differ (check with [`compare`](crate::images::compare) first).
pub fn hdr_flip(reference: &Image, test: &Image) -> (f64, Vec<f32>) {
    assert!(reference.width == test.width && reference.height == test.height);
    let (w, h) = (reference.width, reference.height);
    // Sanitise both images; two black images have no error
    let (r, t) = (sanitized_rgb(reference), sanitized_rgb(test));
    let black = |v: &[[f64; 3]]| v.iter().all(|p| p.iter().all(|&c| c == 0.0));
    if black(&r) && black(&t) {
        return (0.0, vec![0.0; w * h]);
    }
    // Choose the exposures: from the reference, or the test if the reference is black
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
    // Merge the workers' maps: the per-pixel maximum again
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
        let (start, stop) = exposure_range(&rgb);
        let x = aces_input_for_085();
        assert!((start - (x / 8.0).log2()).abs() < 1e-12);
        assert!((stop - (x / 1.5).log2()).abs() < 1e-12);
        // Mostly black: the median is floored at f32::EPSILON, not 0
        let (_, stop) = exposure_range(&[px(0.0), px(0.0), px(0.0), px(1.0)]);
        assert!((stop - (x / f32::EPSILON as f64).log2()).abs() < 1e-9);
    }
}
