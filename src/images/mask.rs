//! Masks: per-pixel weights that leave pixels out of a comparison or scale their tolerance (a
//! timestamp, a noisy sky, a known-unstable region), as Filament's per-pixel masks and QGIS's
//! tolerance masks do.
//!
//! A weight `w` in [0, 1] per pixel of the display window: 0 leaves the pixel out of every
//! metric (it is not counted among the pixels either, so percentages are of the pixels compared),
//! 1 judges it as usual, and in between its difference counts `w` times itself, i.e. its
//! tolerances are multiplied by 1/w (`fail`, `warn`, `max_mean`'s sum, the max error, the z-test's
//! z, the ꟻLIP map). Pixels outside the display window have weight 1.

use super::io::{Image, Window};
use serde::Serialize;

/// One part of a mask: a rectangle of the display window, in absolute pixel coordinates (those
/// the reports give), left out (`weight` 0) or with its tolerance scaled (`weight` = 1/scale);
/// or a grey image of the display window's size whose first channel is the weight.
#[derive(Clone, Debug, PartialEq)]
pub enum MaskPart {
    /// `[x, y, width, height]` and its weight.
    Rect {
        /// Left column.
        x: i64,
        /// Top row.
        y: i64,
        /// Width in pixels.
        width: u64,
        /// Height in pixels.
        height: u64,
        /// 0 leaves the pixels out; 1/`tolerance` otherwise.
        weight: f32,
    },
    /// A mask image: its first channel, as stored (0 black … 1 white), is the weight.
    Image(Image),
}

/// The weights over a display window.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    /// The display window the weights cover.
    pub window: Window,
    /// One weight per pixel of `window`, row by row.
    pub weights: Vec<f32>,
}

/// What a mask did to one comparison: its pixels left out and judged with scaled tolerances,
/// of the compared window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct MaskCounts {
    /// Pixels left out of every metric (weight 0).
    pub excluded: u64,
    /// Pixels judged with tolerances scaled by 1/weight (0 < weight < 1).
    pub scaled: u64,
}

impl Mask {
    /// The weights of `parts` over the display window `window`: the smallest weight any part
    /// gives a pixel. A rectangle reaching outside the window, a weight outside [0, 1], a NaN,
    /// or a mask image of another size is an error (one line), never a mask that silently
    /// covers less.
    pub fn build(window: Window, parts: &[MaskPart]) -> Result<Mask, String> {
        let mut weights = vec![1f32; window.pixels()];
        for part in parts {
            match part {
                MaskPart::Rect {
                    x,
                    y,
                    width,
                    height,
                    weight,
                } => {
                    let inside = *x >= window.x
                        && *y >= window.y
                        && *width > 0
                        && *height > 0
                        && (x - window.x) as u64 + width <= window.width as u64
                        && (y - window.y) as u64 + height <= window.height as u64;
                    if !inside {
                        return Err(format!(
                            "mask rect [{x}, {y}, {width}, {height}] is not inside the display window {window}"
                        ));
                    }
                    if !(0.0..=1.0).contains(weight) {
                        return Err(format!("mask weight {weight} is not in [0, 1]"));
                    }
                    for row in 0..*height as usize {
                        let start = (*y - window.y) as usize + row;
                        let start = start * window.width + (*x - window.x) as usize;
                        for w in &mut weights[start..start + *width as usize] {
                            *w = w.min(*weight);
                        }
                    }
                }
                MaskPart::Image(img) => {
                    if (img.width, img.height) != (window.width, window.height) {
                        return Err(format!(
                            "the mask image is {}×{}, the images compared {}×{}: a mask covers the display window",
                            img.width, img.height, window.width, window.height
                        ));
                    }
                    let n = img.channels.len().max(1);
                    // Grey: a colour mask (R, G and B not equal) says nothing one weight can
                    let rgb: Vec<usize> = ["R", "G", "B"]
                        .iter()
                        .filter_map(|c| img.channels.iter().position(|x| x == c))
                        .collect();
                    for (i, w) in weights.iter_mut().enumerate() {
                        let v = img.data[i * n + rgb.first().copied().unwrap_or(0)];
                        if rgb.len() == 3
                            && rgb
                                .iter()
                                .any(|&c| img.data[i * n + c] != img.data[i * n + rgb[0]])
                        {
                            let (x, y) = (i % window.width, i / window.width);
                            return Err(format!(
                                "the mask image is in colour at ({x}, {y}): a mask is grey (R = G = B), its value the weight"
                            ));
                        }
                        if !(0.0..=1.0).contains(&v) {
                            let (x, y) = (i % window.width, i / window.width);
                            return Err(format!(
                                "the mask image has {v} at ({x}, {y}): a weight is in [0, 1] (0 leaves a pixel out)"
                            ));
                        }
                        *w = w.min(v);
                    }
                }
            }
        }
        Ok(Mask { window, weights })
    }

    /// The weight of pixel (x, y), absolute coordinates: 1 outside the window.
    pub fn weight(&self, x: i64, y: i64) -> f32 {
        let w = &self.window;
        if x < w.x || y < w.y || x >= w.x + w.width as i64 || y >= w.y + w.height as i64 {
            return 1.0;
        }
        self.weights[(y - w.y) as usize * w.width + (x - w.x) as usize]
    }

    /// Its pixels left out and scaled inside `window` (the compared window): a walk of the part
    /// of `window` the mask covers, whatever the size of `window`.
    pub fn counts(&self, window: Window) -> MaskCounts {
        let mut c = MaskCounts::default();
        let m = &self.window;
        let (x0, y0) = (window.x.max(m.x), window.y.max(m.y));
        let x1 = (window.x + window.width as i64).min(m.x + m.width as i64);
        let y1 = (window.y + window.height as i64).min(m.y + m.height as i64);
        for y in y0..y1 {
            for x in x0..x1 {
                let w = self.weight(x, y);
                c.excluded += (w == 0.0) as u64;
                c.scaled += (w > 0.0 && w < 1.0) as u64;
            }
        }
        c
    }

    /// The weights of the pixels of `window`, row by row (for a per-pixel map over it).
    pub fn over(&self, window: Window) -> Vec<f32> {
        let mut v = Vec::with_capacity(window.pixels());
        for y in window.y..window.y + window.height as i64 {
            for x in window.x..window.x + window.width as i64 {
                v.push(self.weight(x, y));
            }
        }
        v
    }

    /// The mean of a per-pixel map over `window` (a ꟻLIP map) under the mask: each value times
    /// its weight, over the pixels not left out. 0 when every pixel is left out.
    pub fn weighted_mean(&self, window: Window, map: &[f32]) -> f64 {
        let (mut sum, mut n) = (0f64, 0u64);
        for (v, w) in map.iter().zip(self.over(window)) {
            if w > 0.0 {
                sum += *v as f64 * w as f64;
                n += 1;
            }
        }
        if n == 0 {
            0.0
        } else {
            sum / n as f64
        }
    }
}

/// The mask drawn over a tone-mapped image (8-bit RGB over `window`): pixels left out crossed
/// by magenta diagonal stripes on a darkened image, scaled pixels tinted blue in proportion to
/// how much their tolerance grew, the others as they are.
pub fn mask_overlay_rgb8(mask: &Mask, window: Window, rgb: &[u8]) -> Vec<u8> {
    let weights = mask.over(window);
    let mut out = Vec::with_capacity(rgb.len());
    for (i, (p, w)) in rgb.chunks(3).zip(weights).enumerate() {
        let (x, y) = (i % window.width.max(1), i / window.width.max(1));
        if w == 0.0 {
            if (x + y) % 8 < 3 {
                out.extend([230, 0, 200]);
            } else {
                out.extend(p.iter().map(|&c| c / 3));
            }
        } else if w < 1.0 {
            let t = (1.0 - w) * 0.6;
            let mix = |c: u8, to: f32| (c as f32 * (1.0 - t) + to * t).round() as u8;
            out.extend([mix(p[0], 40.0), mix(p[1], 120.0), mix(p[2], 255.0)]);
        } else {
            out.extend_from_slice(p);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rects_and_images_combine_by_the_smallest_weight() {
        let win = Window::at_origin(4, 3);
        let img = Image::new(4, 3, &["Y"], vec![1.0; 12]);
        let mut grey = img.clone();
        grey.data[5] = 0.5; // (1, 1)
        let m = Mask::build(
            win,
            &[
                MaskPart::Rect {
                    x: 2,
                    y: 0,
                    width: 2,
                    height: 1,
                    weight: 0.0,
                },
                MaskPart::Image(grey),
            ],
        )
        .unwrap();
        assert_eq!(m.weight(2, 0), 0.0);
        assert_eq!(m.weight(3, 0), 0.0);
        assert_eq!(m.weight(1, 1), 0.5);
        assert_eq!(m.weight(0, 0), 1.0);
        assert_eq!(m.weight(9, 9), 1.0);
        assert_eq!(
            m.counts(win),
            MaskCounts {
                excluded: 2,
                scaled: 1
            }
        );
        // A rectangle reaching outside, a bad weight, a mask of another size: errors
        let r = |x, w, weight| MaskPart::Rect {
            x,
            y: 0,
            width: w,
            height: 1,
            weight,
        };
        assert!(Mask::build(win, &[r(3, 2, 0.0)]).is_err());
        assert!(Mask::build(win, &[r(-1, 1, 0.0)]).is_err());
        assert!(Mask::build(win, &[r(0, 1, f32::NAN)]).is_err());
        assert!(Mask::build(win, &[r(0, 1, 1.5)]).is_err());
        let small = Image::new(2, 2, &["Y"], vec![1.0; 4]);
        assert!(Mask::build(win, &[MaskPart::Image(small)]).is_err());
        let mut nan = img.clone();
        nan.data[0] = f32::NAN;
        assert!(Mask::build(win, &[MaskPart::Image(nan)]).is_err());
    }
}
