//! Primary visibility of implicit scenes: per-pixel sphere tracing, Wu & Pan's image-space
//! subdivision (seed 004, §2), and a certified variant that provably loses no pixel.
//!
//! **Full.** Every pixel is traced from the eye (clipped to the scene box).
//!
//! **Paper** (§2.1–2.3). The image is cut into `region × region` blocks (10×10 in the paper).
//! Each block traces 9 sample rays from the eye at the 3×3 positions `⌊(2i+1)·n/6⌋`
//! (1, 5, 8 for n = 10; the paper's Figure 2 is not in the text we have, so this is our
//! reading of "uniform local sampling"). The samples' results are kept as those pixels' own. A
//! block whose samples hit starts every other pixel at the smallest sampled hit length; a block
//! without a sampled hit is traced only if one of its 8 neighbours has one (§2.3's error
//! correction), from the neighbours' smallest length; other blocks are skipped as background.
//! From the start length: case ① (outside) traces forward; case ② (inside) traces backward to the
//! surface; case ③ (the start already crossed the surface) is detected by a depth test in the
//! spirit of the Rayskip fill the paper cites: a forward trace that ends (hit or miss) deeper
//! than every sampled hit of the block and its neighbours is redone from the eye. None of these
//! decisions is proved: a feature between samples can be lost.
//!
//! **Certified.** The same blocks, with each decision made by a Lipschitz certificate instead
//! of samples. A block's pixel rays lie in a cone around the ray through its centre of
//! half-angle θ (the largest angle to a corner pixel's ray). With `D(p)` the safe step
//! (a lower bound of the distance to every surface), the pixel rays' points at parameters
//! `t' ∈ [t, t + D(c(t)) − 2t·sin(θ/2))` lie within `D` of the axis point `c(t)`, so the cone is
//! free of surface there. Marching the axis by that margin certifies `[0, t)` for every pixel of
//! the block: it is skipped when `t` passes the scene's bounding sphere, and otherwise it splits
//! into four narrower cones that continue from `t`, down to 2×2 pixels, whose pixels are traced
//! from their certified `t` (always case ①). No pixel that per-pixel tracing hits can be lost,
//! given a valid Lipschitz bound (measured, not proved, for MPU).

use super::march::{Marcher, Traced};
use crate::render::Lens;
use rayon::prelude::*;
use serde::Serialize;

/// How primary visibility is found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Full,
    Paper,
    Certified,
}

impl Mode {
    pub const ALL: [Mode; 3] = [Mode::Full, Mode::Paper, Mode::Certified];
    pub fn name(self) -> &'static str {
        match self {
            Mode::Full => "full",
            Mode::Paper => "paper",
            Mode::Certified => "certified",
        }
    }
}

/// Counters of one primary pass.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Stats {
    /// Pixel rays traced (samples, fills and redone rays).
    pub rays: u64,
    /// Field evaluations of the pixel rays.
    pub steps: u64,
    /// Field evaluations of the certifying cones.
    pub cone_steps: u64,
    pub cones: u64,
    pub regions: u64,
    /// Blocks whose samples hit, blocks traced by §2.3's correction, blocks skipped.
    pub regions_hit: u64,
    pub regions_corrected: u64,
    pub regions_skipped: u64,
    /// Pixels started outside (①), inside (②), and redone from the eye after case ③ was detected.
    pub case1: u64,
    pub case2: u64,
    pub case3_redone: u64,
    /// Rays ended by the step cap.
    pub capped: u64,
}

impl std::ops::AddAssign for Stats {
    fn add_assign(&mut self, o: Self) {
        self.rays += o.rays;
        self.steps += o.steps;
        self.cone_steps += o.cone_steps;
        self.cones += o.cones;
        self.regions += o.regions;
        self.regions_hit += o.regions_hit;
        self.regions_corrected += o.regions_corrected;
        self.regions_skipped += o.regions_skipped;
        self.case1 += o.case1;
        self.case2 += o.case2;
        self.case3_redone += o.case3_redone;
        self.capped += o.capped;
    }
}

impl Stats {
    fn ray(&mut self, r: &Traced) {
        self.rays += 1;
        self.steps += r.steps as u64;
        self.capped += r.capped as u64;
    }
}

/// Per-pixel result: the hit (distance, field) and where the pixel's trace started.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pixel {
    pub hit: Option<(f64, usize)>,
    /// Start length of the pixel's final trace (0: from the eye); `NAN` if never traced.
    pub start: f64,
    /// The pixel's block was skipped.
    pub skipped: bool,
}

/// A primary pass: pixels row-major, counters, seconds.
pub struct Primary {
    pub pixels: Vec<Pixel>,
    pub stats: Stats,
    pub seconds: f64,
}

/// One block's samples (pixel, trace) and counters.
type Samples = (Vec<((usize, usize), Traced)>, Stats);

/// A block of pixels `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug)]
struct Block {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl Block {
    fn pixels(self) -> impl Iterator<Item = (usize, usize)> {
        (self.y0..self.y1).flat_map(move |y| (self.x0..self.x1).map(move |x| (x, y)))
    }
}

/// The sample offsets inside a block of `n` pixels: `⌊(2i+1)·n/6⌋`, i = 0, 1, 2.
pub fn sample_offsets(n: usize) -> [usize; 3] {
    [0, 1, 2].map(|i| ((2 * i + 1) * n / 6).min(n.saturating_sub(1)))
}

/// Finds the primary hits of the image by `mode`, with `region`-pixel blocks.
pub fn primary(
    m: &Marcher,
    lens: &Lens,
    (w, h): (usize, usize),
    mode: Mode,
    region: usize,
) -> Primary {
    let start = std::time::Instant::now();
    let region = region.max(1);
    let trace =
        |x: usize, y: usize, t: f64| m.trace(lens.pos, lens.dir(x as f64 + 0.5, y as f64 + 0.5), t);
    let (nx, ny) = (w.div_ceil(region), h.div_ceil(region));
    let block = |bx: usize, by: usize| Block {
        x0: bx * region,
        y0: by * region,
        x1: ((bx + 1) * region).min(w),
        y1: ((by + 1) * region).min(h),
    };
    let mut pixels = vec![
        Pixel {
            start: f64::NAN,
            ..Pixel::default()
        };
        w * h
    ];
    let mut stats = Stats::default();
    let blocks: Vec<(usize, usize)> = (0..ny)
        .flat_map(|by| (0..nx).map(move |bx| (bx, by)))
        .collect();
    match mode {
        Mode::Full => {
            // Every pixel from the eye, rows in parallel
            let rows: Vec<(Vec<Pixel>, Stats)> = (0..h)
                .into_par_iter()
                .map(|y| {
                    let mut st = Stats::default();
                    let row = (0..w)
                        .map(|x| {
                            let r = trace(x, y, 0.0);
                            st.ray(&r);
                            st.case1 += 1;
                            Pixel {
                                hit: r.hit,
                                start: 0.0,
                                skipped: false,
                            }
                        })
                        .collect();
                    (row, st)
                })
                .collect();
            for (y, (row, st)) in rows.into_iter().enumerate() {
                pixels[y * w..(y + 1) * w].copy_from_slice(&row);
                stats += st;
            }
        }
        Mode::Paper => {
            // §2.2: 9 samples per block, from the eye
            let sampled: Vec<Samples> = blocks
                .par_iter()
                .map(|&(bx, by)| {
                    let b = block(bx, by);
                    let (ox, oy) = (sample_offsets(b.x1 - b.x0), sample_offsets(b.y1 - b.y0));
                    let mut st = Stats::default();
                    let mut seen = vec![];
                    for &sy in &oy {
                        for &sx in &ox {
                            let (x, y) = (b.x0 + sx, b.y0 + sy);
                            if seen.iter().any(|(p, _)| *p == (x, y)) {
                                continue;
                            }
                            let r = trace(x, y, 0.0);
                            st.ray(&r);
                            seen.push(((x, y), r));
                        }
                    }
                    (seen, st)
                })
                .collect();
            // Each block's smallest and largest sampled hit length
            let mut lo = vec![f64::INFINITY; nx * ny];
            let mut hi = vec![f64::NEG_INFINITY; nx * ny];
            for (k, (samples, st)) in sampled.iter().enumerate() {
                stats += *st;
                for ((x, y), r) in samples {
                    pixels[y * w + x] = Pixel {
                        hit: r.hit,
                        start: 0.0,
                        skipped: false,
                    };
                    stats.case1 += 1;
                    if let Some((t, _)) = r.hit {
                        lo[k] = lo[k].min(t);
                        hi[k] = hi[k].max(t);
                    }
                }
            }
            // §2.3: blocks without a sampled hit next to one that has
            let neigh = |bx: usize, by: usize| {
                let mut v = vec![];
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (x, y) = (bx as i64 + dx, by as i64 + dy);
                        if (dx, dy) != (0, 0)
                            && x >= 0
                            && y >= 0
                            && (x as usize) < nx
                            && (y as usize) < ny
                        {
                            v.push(y as usize * nx + x as usize);
                        }
                    }
                }
                v
            };
            let filled: Vec<(Vec<(usize, Pixel)>, Stats)> = blocks
                .par_iter()
                .enumerate()
                .map(|(k, &(bx, by))| {
                    let b = block(bx, by);
                    let mut st = Stats {
                        regions: 1,
                        ..Stats::default()
                    };
                    let around = neigh(bx, by);
                    let n_lo = around.iter().map(|&j| lo[j]).fold(f64::INFINITY, f64::min);
                    let deepest = around.iter().map(|&j| hi[j]).fold(hi[k], f64::max);
                    let s = if lo[k].is_finite() {
                        st.regions_hit += 1;
                        lo[k]
                    } else if n_lo.is_finite() {
                        st.regions_corrected += 1;
                        n_lo
                    } else {
                        st.regions_skipped += 1;
                        let out = b
                            .pixels()
                            .map(|(x, y)| {
                                (
                                    y * w + x,
                                    Pixel {
                                        hit: None,
                                        start: f64::NAN,
                                        skipped: true,
                                    },
                                )
                            })
                            .collect();
                        return (out, st);
                    };
                    let mut out = vec![];
                    for (x, y) in b.pixels() {
                        if sampled[k].0.iter().any(|(p, _)| *p == (x, y)) {
                            continue;
                        }
                        let r = trace(x, y, s);
                        st.ray(&r);
                        let depth = r.hit.map_or(f64::INFINITY, |h| h.0);
                        let px = if r.backward {
                            st.case2 += 1;
                            Pixel {
                                hit: r.hit,
                                start: s,
                                skipped: false,
                            }
                        } else if depth > deepest {
                            // Case ③ suspected: deeper than anything sampled around
                            st.case3_redone += 1;
                            let again = trace(x, y, 0.0);
                            st.ray(&again);
                            Pixel {
                                hit: again.hit,
                                start: 0.0,
                                skipped: false,
                            }
                        } else {
                            st.case1 += 1;
                            Pixel {
                                hit: r.hit,
                                start: s,
                                skipped: false,
                            }
                        };
                        out.push((y * w + x, px));
                    }
                    (out, st)
                })
                .collect();
            for (out, st) in filled {
                stats += st;
                for (i, px) in out {
                    pixels[i] = px;
                }
            }
        }
        Mode::Certified => {
            let (lo, hi) = (m.lo, m.hi);
            let centre = (lo + hi) * 0.5;
            // Past this distance every ray has left the scene's bounding sphere
            let far = (lens.pos - centre).length() + (hi - lo).length() * 0.5 + 4.0 * m.eps;
            let done: Vec<(Vec<(usize, Pixel)>, Stats)> = blocks
                .par_iter()
                .map(|&(bx, by)| {
                    let mut st = Stats {
                        regions: 1,
                        ..Stats::default()
                    };
                    let mut out = vec![];
                    let b = block(bx, by);
                    certify(m, lens, w, b, 0.0, far, &mut st, &mut out);
                    if out.iter().all(|(_, p)| p.skipped) {
                        st.regions_skipped += 1;
                    } else {
                        st.regions_hit += 1;
                    }
                    (out, st)
                })
                .collect();
            for (out, st) in done {
                stats += st;
                for (i, px) in out {
                    pixels[i] = px;
                }
            }
        }
    }
    Primary {
        pixels,
        stats,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// Certifies block `b` free of surface beyond `t` by cone marching; skips it, splits it, or
/// traces its pixels from the certified length.
#[allow(clippy::too_many_arguments)]
fn certify(
    m: &Marcher,
    lens: &Lens,
    w: usize,
    b: Block,
    mut t: f64,
    far: f64,
    st: &mut Stats,
    out: &mut Vec<(usize, Pixel)>,
) {
    // The cone: axis through the block's centre, half-angle to the farthest corner pixel
    let axis = lens.dir((b.x0 + b.x1) as f64 * 0.5, (b.y0 + b.y1) as f64 * 0.5);
    let corners = [
        (b.x0, b.y0),
        (b.x1 - 1, b.y0),
        (b.x0, b.y1 - 1),
        (b.x1 - 1, b.y1 - 1),
    ];
    // |d − axis| = 2 sin(φ/2): the chord is what the bound needs, no trigonometry
    let chord = corners
        .iter()
        .map(|&(x, y)| (lens.dir(x as f64 + 0.5, y as f64 + 0.5) - axis).length())
        .fold(0.0, f64::max)
        * (1.0 + 1e-12);
    st.cones += 1;
    // March the axis while the ball at c(t) covers the cone's cross-section
    loop {
        if t > far {
            // Certified empty
            for (x, y) in b.pixels() {
                out.push((
                    y * w + x,
                    Pixel {
                        hit: None,
                        start: t,
                        skipped: true,
                    },
                ));
            }
            return;
        }
        let (d, _) = m.bound(lens.pos + axis * t);
        st.cone_steps += 1;
        let margin = d - t * chord;
        if margin <= (0.25 * t * chord).max(m.eps) {
            break;
        }
        t += margin;
    }
    // Stalled: split into four narrower cones, or trace the pixels from t
    let (wx, wy) = (b.x1 - b.x0, b.y1 - b.y0);
    if wx > 2 || wy > 2 {
        let (mx, my) = (b.x0 + wx.div_ceil(2), b.y0 + wy.div_ceil(2));
        for (x0, x1) in [(b.x0, mx), (mx, b.x1)] {
            for (y0, y1) in [(b.y0, my), (my, b.y1)] {
                if x0 < x1 && y0 < y1 {
                    certify(m, lens, w, Block { x0, y0, x1, y1 }, t, far, st, out);
                }
            }
        }
        return;
    }
    for (x, y) in b.pixels() {
        let r = m.trace(lens.pos, lens.dir(x as f64 + 0.5, y as f64 + 0.5), t);
        st.ray(&r);
        if r.backward {
            st.case2 += 1;
        } else {
            st.case1 += 1;
        }
        out.push((
            y * w + x,
            Pixel {
                hit: r.hit,
                start: t,
                skipped: false,
            },
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn paper_sample_positions() {
        assert_eq!(sample_offsets(10), [1, 5, 8]);
        assert_eq!(sample_offsets(5), [0, 2, 4]);
        assert_eq!(sample_offsets(1), [0, 0, 0]);
    }

    #[test]
    fn cone_chord_is_the_angle() {
        // 2 sin(φ/2) for unit vectors
        let (a, b) = (DVec3::X, DVec3::new(0.6, 0.8, 0.0));
        let phi = a.angle_between(b);
        assert!(((a - b).length() - 2.0 * (phi / 2.0).sin()).abs() < 1e-15);
    }
}
