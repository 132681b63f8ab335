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
//! from their certified `t` (always case ①). A block one pixel wide or tall (from splitting an
//! odd width) is not cone-marched: its cone is nearly a ray, and its pixels' own traces march
//! with steps along their directions, which cost fewer evaluations than the cone's. No pixel that per-pixel tracing hits can be lost,
//! given valid bounds: with the `local` tracer every bound is proved ([`crate::implicit::lipschitz`]);
//! with `global`, the MPU's is measured.

pub mod check;

use crate::implicit::march::{Marcher, Traced};
use crate::render::Lens;
use rayon::prelude::*;
use serde::Serialize;

/// How primary visibility is found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Per-pixel sphere tracing (the baseline).
    Full,
    /// Wu & Pan's image-space subdivision, as the paper describes it.
    Paper,
    /// The subdivision with certifying cones: provably loses no pixel.
    Certified,
}

impl Mode {
    /// Every mode, in report order.
    pub const ALL: [Mode; 3] = [Mode::Full, Mode::Paper, Mode::Certified];
    /// The mode's name in reports and on the command line.
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
    /// Certifying cones traced.
    pub cones: u64,
    /// Blocks of the image-space subdivision.
    pub regions: u64,
    /// Blocks whose samples hit, blocks traced by §2.3's correction, blocks skipped.
    pub regions_hit: u64,
    /// Blocks traced by the paper's §2.3 correction.
    pub regions_corrected: u64,
    /// Blocks skipped as background.
    pub regions_skipped: u64,
    /// Pixels started outside (①), inside (②), and redone from the eye after case ③ was detected.
    pub case1: u64,
    /// Pixels whose trace started inside the surface (case ②).
    pub case2: u64,
    /// Pixels redone from the eye after case ③ (started past the surface) was detected.
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
    /// Distance and field index of the hit, `None` for background.
    pub hit: Option<(f64, usize)>,
    /// Start length of the pixel's final trace (0: from the eye); `NAN` if never traced.
    pub start: f64,
    /// The pixel's block was skipped.
    pub skipped: bool,
}

/// A primary pass: pixels row-major, counters, seconds.
pub struct Primary {
    /// One per pixel, row-major.
    pub pixels: Vec<Pixel>,
    /// Counters of the pass.
    pub stats: Stats,
    /// Wall-clock seconds of the pass.
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
    let g = Grid::new(m, lens, (w, h), region);
    let mut pixels = vec![
        Pixel {
            start: f64::NAN,
            ..Pixel::default()
        };
        w * h
    ];
    let mut stats = Stats::default();
    match mode {
        Mode::Full => g.full(&mut pixels, &mut stats),
        Mode::Paper => g.paper(&mut pixels, &mut stats),
        Mode::Certified => g.certified(&mut pixels, &mut stats),
    }
    Primary {
        pixels,
        stats,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// Pixels found per block (row-major index, pixel) with the block's counters.
type Found = (Vec<(usize, Pixel)>, Stats);

/// Writes each block's pixels into the image and adds its counters.
fn merge(found: Vec<Found>, pixels: &mut [Pixel], stats: &mut Stats) {
    for (out, st) in found {
        *stats += st;
        for (i, px) in out {
            pixels[i] = px;
        }
    }
}

/// The image of one primary pass, cut into `region × region` blocks (`nx × ny` of them), and
/// its pixel rays.
struct Grid<'a> {
    m: &'a Marcher,
    lens: &'a Lens,
    w: usize,
    h: usize,
    region: usize,
    nx: usize,
    ny: usize,
    /// Block coordinates, row-major.
    blocks: Vec<(usize, usize)>,
}

impl<'a> Grid<'a> {
    fn new(m: &'a Marcher, lens: &'a Lens, (w, h): (usize, usize), region: usize) -> Self {
        let region = region.max(1);
        let (nx, ny) = (w.div_ceil(region), h.div_ceil(region));
        let blocks = (0..ny)
            .flat_map(|by| (0..nx).map(move |bx| (bx, by)))
            .collect();
        Grid {
            m,
            lens,
            w,
            h,
            region,
            nx,
            ny,
            blocks,
        }
    }

    /// Traces pixel `(x, y)`'s ray through its centre from length `t`.
    fn trace(&self, x: usize, y: usize, t: f64) -> Traced {
        let d = self.lens.dir(x as f64 + 0.5, y as f64 + 0.5);
        self.m.trace(self.lens.pos, d, t)
    }

    /// Block `(bx, by)`, clipped to the image.
    fn block(&self, bx: usize, by: usize) -> Block {
        Block {
            x0: bx * self.region,
            y0: by * self.region,
            x1: ((bx + 1) * self.region).min(self.w),
            y1: ((by + 1) * self.region).min(self.h),
        }
    }

    /// Indices of the (up to 8) blocks around block `(bx, by)`.
    fn neighbours(&self, bx: usize, by: usize) -> Vec<usize> {
        let mut v = vec![];
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (x, y) = (bx as i64 + dx, by as i64 + dy);
                if (dx, dy) != (0, 0)
                    && x >= 0
                    && y >= 0
                    && (x as usize) < self.nx
                    && (y as usize) < self.ny
                {
                    v.push(y as usize * self.nx + x as usize);
                }
            }
        }
        v
    }

    /// Mode full: every pixel from the eye.
    fn full(&self, pixels: &mut [Pixel], stats: &mut Stats) {
        let w = self.w;
        // Trace the rows in parallel
        let rows: Vec<(Vec<Pixel>, Stats)> = (0..self.h)
            .into_par_iter()
            .map(|y| {
                let mut st = Stats::default();
                let row = (0..w)
                    .map(|x| {
                        let r = self.trace(x, y, 0.0);
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
        // Copy them into the image
        for (y, (row, st)) in rows.into_iter().enumerate() {
            pixels[y * w..(y + 1) * w].copy_from_slice(&row);
            *stats += st;
        }
    }

    /// Mode paper (§2.2–2.3): samples, then every other pixel from the block's start length.
    fn paper(&self, pixels: &mut [Pixel], stats: &mut Stats) {
        // §2.2: 9 samples per block, from the eye
        let sampled: Vec<Samples> = self
            .blocks
            .par_iter()
            .map(|&(bx, by)| self.paper_samples(self.block(bx, by)))
            .collect();
        // Keep the samples; each block's smallest and largest sampled hit length
        let (lo, hi) = self.keep_samples(&sampled, pixels, stats);
        // §2.3: trace the other pixels of blocks with a sampled hit or next to one
        let filled: Vec<Found> = self
            .blocks
            .par_iter()
            .enumerate()
            .map(|(k, &(bx, by))| self.paper_fill(k, (bx, by), &sampled[k].0, &lo, &hi))
            .collect();
        merge(filled, pixels, stats);
    }

    /// Block `b`'s samples at the 3×3 positions of [`sample_offsets`], each traced once.
    fn paper_samples(&self, b: Block) -> Samples {
        let (ox, oy) = (sample_offsets(b.x1 - b.x0), sample_offsets(b.y1 - b.y0));
        let mut st = Stats::default();
        let mut seen = vec![];
        for &sy in &oy {
            for &sx in &ox {
                let (x, y) = (b.x0 + sx, b.y0 + sy);
                if seen.iter().any(|(p, _)| *p == (x, y)) {
                    continue;
                }
                let r = self.trace(x, y, 0.0);
                st.ray(&r);
                seen.push(((x, y), r));
            }
        }
        (seen, st)
    }

    /// Writes the samples as their pixels' results; returns each block's smallest and largest
    /// sampled hit length (±inf without a hit).
    fn keep_samples(
        &self,
        sampled: &[Samples],
        pixels: &mut [Pixel],
        stats: &mut Stats,
    ) -> (Vec<f64>, Vec<f64>) {
        let mut lo = vec![f64::INFINITY; self.nx * self.ny];
        let mut hi = vec![f64::NEG_INFINITY; self.nx * self.ny];
        for (k, (samples, st)) in sampled.iter().enumerate() {
            *stats += *st;
            for ((x, y), r) in samples {
                pixels[y * self.w + x] = Pixel {
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
        (lo, hi)
    }

    /// Block `k` at `(bx, by)` after its `samples`: its start length from its own samples or
    /// its neighbours' (§2.3), or skipped as background; then every other pixel traced.
    fn paper_fill(
        &self,
        k: usize,
        (bx, by): (usize, usize),
        samples: &[((usize, usize), Traced)],
        lo: &[f64],
        hi: &[f64],
    ) -> Found {
        let w = self.w;
        let b = self.block(bx, by);
        let mut st = Stats {
            regions: 1,
            ..Stats::default()
        };
        // The start length, or skip the block
        let around = self.neighbours(bx, by);
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
        // Trace the pixels that were not sampled
        let mut out = vec![];
        for (x, y) in b.pixels() {
            if samples.iter().any(|(p, _)| *p == (x, y)) {
                continue;
            }
            let px = self.paper_pixel(x, y, s, deepest, &mut st);
            out.push((y * w + x, px));
        }
        (out, st)
    }

    /// Pixel `(x, y)` traced from start length `s`: case ② if the trace went backward, case ③
    /// suspected (and the pixel redone from the eye) if it ends deeper than `deepest`, else ①.
    fn paper_pixel(&self, x: usize, y: usize, s: f64, deepest: f64, st: &mut Stats) -> Pixel {
        let r = self.trace(x, y, s);
        st.ray(&r);
        let depth = r.hit.map_or(f64::INFINITY, |h| h.0);
        if r.backward {
            st.case2 += 1;
            Pixel {
                hit: r.hit,
                start: s,
                skipped: false,
            }
        } else if depth > deepest {
            // Case ③ suspected: deeper than anything sampled around
            st.case3_redone += 1;
            let again = self.trace(x, y, 0.0);
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
        }
    }

    /// Mode certified: each block certified by cone marching, then skipped, split or traced.
    fn certified(&self, pixels: &mut [Pixel], stats: &mut Stats) {
        let (m, lens) = (self.m, self.lens);
        let (lo, hi) = (m.lo, m.hi);
        let centre = (lo + hi) * 0.5;
        // Past this distance every ray has left the scene's bounding sphere
        let far = (lens.pos - centre).length() + (hi - lo).length() * 0.5 + 4.0 * m.eps;
        // Certify the blocks in parallel
        let done: Vec<Found> = self
            .blocks
            .par_iter()
            .map(|&(bx, by)| {
                let mut st = Stats {
                    regions: 1,
                    ..Stats::default()
                };
                let mut out = vec![];
                let b = self.block(bx, by);
                certify(m, lens, self.w, b, 0.0, far, &mut st, &mut out);
                if out.iter().all(|(_, p)| p.skipped) {
                    st.regions_skipped += 1;
                } else {
                    st.regions_hit += 1;
                }
                (out, st)
            })
            .collect();
        merge(done, pixels, stats);
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
    // A block one pixel wide or tall is traced pixel by pixel from t: its cone is (nearly) a
    // ray, which its pixels' traces march with the cheaper steps along their own directions
    if b.x1 - b.x0 == 1 || b.y1 - b.y0 == 1 {
        trace_pixels(m, lens, w, b, t, st, out);
        return;
    }
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
    trace_pixels(m, lens, w, b, t, st, out);
}

/// Traces block `b`'s pixels from the certified length `t`.
fn trace_pixels(
    m: &Marcher,
    lens: &Lens,
    w: usize,
    b: Block,
    t: f64,
    st: &mut Stats,
    out: &mut Vec<(usize, Pixel)>,
) {
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
