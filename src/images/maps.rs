//! The report's views of where two images differ, however small the difference: a mask of the
//! failing pixels and the |difference| normalised to its maximum (the ꟻLIP heat map is almost
//! black for a difference of 1e-6, which is still a failure at `fail = 1e-6`).

use super::flip::heatmap_rgb8;
use super::io::Image;
use super::mask::Mask;
use super::metrics::{same_nonfinite, same_shape, SizeMismatch, Thresholds};

/// The failing pixels of a comparison under rayproof's semantics, as [`super::compare`] counts
/// them in `n_fail`: a pixel fails when one channel's |a − b| (in `f32`) is over `fail` (as
/// `f32`) and its relative size over `failrelative`, or when one channel is a NaN/Inf mismatch.
/// One `bool` per pixel, row by row.
// `!(x <= y)` is idiff's NaN-aware test, as `compare` has it
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn fail_mask(
    reference: &Image,
    test: &Image,
    t: &Thresholds,
    mask: Option<&Mask>,
) -> Result<Vec<bool>, SizeMismatch> {
    same_shape(reference, test)?;
    let f32t = |x: f64| x as f32 as f64;
    let (fail, failrel) = (f32t(t.fail), f32t(t.failrelative));
    let n = reference.channels.len().max(1);
    let weights = mask.map(|m| m.over(reference.data_window()));
    let fails = |a: f32, b: f32, w: f64| -> bool {
        if w == 0.0 {
            return false;
        }
        if !a.is_finite() || !b.is_finite() {
            return !same_nonfinite(a as f64, b as f64);
        }
        let f = (a - b).abs() as f64 * w;
        let meanabs = (0.5 * a.abs() as f64 + 0.5 * b.abs() as f64) as f32;
        let rel = if meanabs > 0.0 {
            f / meanabs as f64
        } else {
            0.0
        };
        f > fail && !(rel <= failrel)
    };
    Ok(reference
        .data
        .chunks(n)
        .zip(test.data.chunks(n))
        .enumerate()
        .map(|(i, (a, b))| {
            let w = weights.as_ref().map_or(1.0, |v| v[i] as f64);
            a.iter().zip(b).any(|(&a, &b)| fails(a, b, w))
        })
        .collect())
}

/// The mask as 8-bit RGB: failing pixels red (255, 0, 0), the others the test image's tone-mapped
/// luminance dimmed to at most 35 % grey, so the failing region shows where it is in the picture.
pub fn mask_rgb8(mask: &[bool], test_rgb8: &[u8]) -> Vec<u8> {
    mask.iter()
        .zip(test_rgb8.chunks(3))
        .flat_map(|(&bad, p)| {
            if bad {
                [255, 0, 0]
            } else {
                let y = 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64;
                let g = (0.35 * y).round() as u8;
                [g, g, g]
            }
        })
        .collect()
}

/// The |difference| map of a comparison: per pixel the largest channel |test − reference|.
#[derive(Clone, Debug, PartialEq)]
pub struct DiffMap {
    /// Per pixel, row by row: the largest finite channel |d| divided by `scale` (in [0, 1]; 0
    /// everywhere when the images are equal), or NaN for a pixel with a NaN/Inf mismatch.
    pub values: Vec<f32>,
    /// The largest finite |d| of the image: what 1 means (0 when no finite difference).
    pub scale: f64,
    /// Pixels with a NaN/Inf mismatch (drawn in cyan, outside the colour scale).
    pub nonfinite: u64,
}

/// The normalised |difference| map (see [`DiffMap`]); under a mask each pixel's |d| times its
/// weight (a left-out pixel is 0: a timestamp the comparison ignores does not set the scale).
pub fn diff_map(
    reference: &Image,
    test: &Image,
    mask: Option<&Mask>,
) -> Result<DiffMap, SizeMismatch> {
    same_shape(reference, test)?;
    let n = reference.channels.len().max(1);
    let mut nonfinite = 0;
    let weights = mask.map(|m| m.over(reference.data_window()));
    let raw: Vec<f32> = reference
        .data
        .chunks(n)
        .zip(test.data.chunks(n))
        .enumerate()
        .map(|(i, (a, b))| {
            let w = weights.as_ref().map_or(1.0, |v| v[i]);
            if w == 0.0 {
                return 0.0;
            }
            let mut m = 0f32;
            for (&a, &b) in a.iter().zip(b) {
                if !a.is_finite() || !b.is_finite() {
                    if !same_nonfinite(a as f64, b as f64) {
                        nonfinite += 1;
                        return f32::NAN;
                    }
                    continue;
                }
                m = m.max((a - b).abs());
            }
            m * w
        })
        .collect();
    let scale = raw
        .iter()
        .filter(|v| !v.is_nan())
        .fold(0f32, |m, &v| m.max(v));
    let values = raw
        .iter()
        .map(|&v| match v {
            v if v.is_nan() => f32::NAN,
            _ if scale == 0.0 => 0.0,
            v => (v as f64 / scale as f64) as f32,
        })
        .collect();
    Ok(DiffMap {
        values,
        scale: scale as f64,
        nonfinite,
    })
}

/// The map as 8-bit RGB: ꟻLIP's magma colour scale from 0 (black) to `scale` (pale yellow),
/// NaN/Inf mismatches cyan (0, 255, 255).
pub fn diff_map_rgb8(map: &DiffMap, w: usize, h: usize) -> Vec<u8> {
    let finite: Vec<f32> = map
        .values
        .iter()
        .map(|&v| if v.is_nan() { 0.0 } else { v })
        .collect();
    let mut rgb = heatmap_rgb8(&finite, w, h);
    for (p, v) in rgb.chunks_mut(3).zip(&map.values) {
        if v.is_nan() {
            p.copy_from_slice(&[0, 255, 255]);
        }
    }
    rgb
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::images::compare;

    /// The mask counts exactly the pixels `compare` counts as failing, on differences around
    /// the thresholds, relative sizes, NaN and Inf.
    #[test]
    fn the_mask_is_the_comparisons_failing_pixels() {
        let values = [
            0.0f32,
            1e-7,
            1e-6,
            1.5e-6,
            0.01,
            0.0100001,
            0.5,
            1.0,
            -0.3,
            f32::NAN,
            f32::INFINITY,
            -f32::INFINITY,
        ];
        let mut a = vec![];
        let mut b = vec![];
        for (i, &x) in values.iter().enumerate() {
            for (j, &y) in values.iter().enumerate() {
                a.extend([0.2, x, 0.2]);
                b.extend([0.2, y, 0.2 + (i + j) as f32 * 1e-7]);
            }
        }
        let n = values.len() * values.len();
        let ra = Image::new(n, 1, &["R", "G", "B"], a);
        let rb = Image::new(n, 1, &["R", "G", "B"], b);
        for t in [
            Thresholds::default(),
            Thresholds {
                fail: 1e-6,
                ..Default::default()
            },
            Thresholds {
                fail: 1e-9,
                failrelative: 0.5,
                ..Default::default()
            },
        ] {
            let mask = fail_mask(&ra, &rb, &t, None).unwrap();
            let c = compare(&ra, &rb, &t).unwrap();
            assert_eq!(
                mask.iter().filter(|&&m| m).count() as u64,
                c.n_fail,
                "{t:?}"
            );
            assert!(
                c.n_fail > 0 && (c.n_fail as usize) < n,
                "{t:?}: {}",
                c.n_fail
            );
        }
    }

    #[test]
    fn a_one_in_a_million_change_fills_the_scale() {
        let a = Image::new(4, 1, &["R", "G", "B"], vec![0.5; 12]);
        let mut b = a.clone();
        b.data[3] += 1e-6; // pixel 1, R
        b.data[7] += 0.5e-6; // pixel 2, G
        b.data[11] = f32::NAN; // pixel 3, B
        let m = diff_map(&a, &b, None).unwrap();
        let d = ((0.5f32 + 1e-6) - 0.5) as f64;
        assert_eq!(m.scale, d);
        assert_eq!(m.values[0], 0.0);
        assert_eq!(m.values[1], 1.0);
        assert!((m.values[2] - 0.5).abs() < 0.1, "{}", m.values[2]);
        assert!(m.values[3].is_nan() && m.nonfinite == 1);
        let rgb = diff_map_rgb8(&m, 4, 1);
        assert!(rgb[..3].iter().all(|&v| v < 10), "{rgb:?}");
        assert!(
            rgb[3..6].iter().map(|&v| v as u32).sum::<u32>() > 500,
            "{rgb:?}"
        );
        assert_eq!(rgb[9..12], [0, 255, 255]);
        let equal = diff_map(&a, &a, None).unwrap();
        assert_eq!((equal.scale, equal.values[1]), (0.0, 0.0));
    }
}
