//! Local Lipschitz bounds: a uniform grid of boxes over a convex region that holds a field's
//! zero set, each box with a *proved* bound on `|∇f|` over the box and on the rounding error
//! of the field's evaluation there, and the safe step that uses them.
//!
//! The fields derive their box bounds analytically ([`super::mpu::Mpu`]: quadric gradients and
//! partition-of-unity weights; [`super::field::Field::blob`]: the supports that meet the box);
//! this module turns them into steps. Sampling never enters a bound: the tests sample only to
//! check them.
//!
//! # The step rule
//! Let `Ω` be the grid's box, `Z ⊂ Ω` the zero set, `f` C¹ on `Ω` with `|∇f| ≤ L_c` on each
//! cell `c`, and `|f̃(x) − f(x)| ≤ e_c` for the computed value `f̃` at every `x` in cell `c`.
//! For `x` in cell `c`, let `L̂`, `ê` be the maxima of `L`, `e` over the 3×3×3 cells around `c`
//! (clamped to the grid), and `δ` half the smallest cell width. The step is
//!
//! `s(x) = max( min((|f̃(x)| − ê)⁺/L̂, δ), (|f̃(x)| − e_g)⁺/L_g )`
//!
//! with `L_g`, `e_g` the maxima over all cells (the global bound, valid on all of `Ω`).
//! **No zero lies within `s(x)` of `x`.** Take `z ∈ Z` with `|x − z| < s`. The segment
//! `[x, z]` lies in `Ω` (convex, holds both ends). In the first case, `|x − z| < δ`, so the
//! segment stays in the neighbour cells (δ is half a cell, which also absorbs a cell index off
//! by one through rounding), where `|∇f| ≤ L̂`; by the mean value theorem
//! `|f(x)| = |f(x) − f(z)| ≤ L̂·|x − z| < (|f̃(x)| − ê)⁺`, impossible as `|f(x)| ≥ |f̃(x)| − ê`.
//! The second case is the same with the global maxima. A step may cross into other cells: the
//! first form is clamped to `δ` so that it never leaves the neighbourhood whose bound it used;
//! the second uses a bound valid everywhere. Outside `Ω` the global form alone is used (it
//! holds on every segment that reaches `Z`: the part outside `Ω` is covered by the field's own
//! argument, see [`super::mpu`] and [`super::field`]).
//!
//! The step carries the sign of `f̃` (negative inside) and is at least `f64::MIN_POSITIVE` in
//! magnitude so that the sign survives: a point whose `|f̃|` is within the rounding error of 0
//! gets a step of (nearly) 0, which the tracer treats as "near the surface" and settles by
//! probing for a sign change.
//!
//! # Rounding of the bounds themselves
//! The box bounds are computed in floating point from the fields' coefficients. Every bound
//! is a sum of at most a few hundred non-negative terms, each a product of a few rounded
//! quantities, so its relative rounding error is below 1e-12; [`LocalBounds::build`] inflates
//! every cell bound by a factor `1 + 1e-9` and the fields compute sums of magnitudes only.

use glam::DVec3;
use rayon::prelude::*;

/// Relative inflation of every computed bound against its own rounding.
pub const ROUNDING_SLACK: f64 = 1e-9;

/// What a field proves about one box of the grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellBound {
    /// `sup |∇f|` over the box.
    pub lipschitz: f64,
    /// A bound on `|f̃ − f|` anywhere in the box.
    pub error: f64,
    /// `f` has no zero in the box (its range over the box, widened by `error`, excludes 0).
    pub zero_free: bool,
    /// A Lipschitz constant of `∇f` over the box (a bound on `‖∇²f‖` where it exists).
    pub curvature: f64,
    /// A bound on the rounding error of the computed `|∇f|` in the box.
    pub gradient_error: f64,
}

/// A cell's `(L, e, H, g_e)`: Lipschitz bound, evaluation error, curvature, gradient error.
type Quad = [f64; 4];

#[inline]
fn qmax(a: Quad, b: Quad) -> Quad {
    [
        a[0].max(b[0]),
        a[1].max(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
    ]
}

/// Rings of zero-free cells counted around a cell (the largest empty-block step, in cells).
const MAX_RINGS: u8 = 64;

/// One level of the pyramid: cells `2^k` fine cells wide.
#[derive(Clone, Debug)]
struct Level {
    dims: [usize; 3],
    delta: f64,
    /// Per cell: the maxima of its [`Quad`] over its 3×3×3 neighbourhood.
    near: Vec<Quad>,
}

impl Level {
    /// The level of `raw` per-cell bounds on a `dims` grid whose cells are `h` wide.
    fn new(raw: &[Quad], dims: [usize; 3], h: DVec3) -> Level {
        let near = (0..raw.len())
            .into_par_iter()
            .map(|i| {
                let c = [
                    i % dims[0],
                    (i / dims[0]) % dims[1],
                    i / (dims[0] * dims[1]),
                ];
                let r = |k: usize| c[k].saturating_sub(1)..=(c[k] + 1).min(dims[k] - 1);
                let mut m = [0.0; 4];
                for z in r(2) {
                    for y in r(1) {
                        for x in r(0) {
                            m = qmax(m, raw[(z * dims[1] + y) * dims[0] + x]);
                        }
                    }
                }
                m
            })
            .collect();
        Level {
            dims,
            delta: 0.5 * h.min_element(),
            near,
        }
    }
}

/// A grid of proved local Lipschitz bounds (module doc).
#[derive(Clone, Debug)]
pub struct LocalBounds {
    lo: DVec3,
    hi: DVec3,
    inv_h: DVec3,
    /// Per fine cell: its own bounds.
    raw: Vec<Quad>,
    /// The pyramid, finest first: level `k + 1` max-pools 2×2×2 cells of level `k`.
    levels: Vec<Level>,
    /// Per fine cell: `r` such that every cell within `r` cells (Chebyshev) is zero-free, or 0.
    rings: Vec<u8>,
    /// The smallest fine cell width.
    h_min: f64,
    global: (f64, f64),
}

impl LocalBounds {
    /// Builds the grid over `[lo, hi]` (a box that holds the zero set) with `dims` cells per
    /// axis; `cell(blo, bhi)` returns what the field proves over the cell `[blo, bhi]`. The
    /// global bound is the maximum over the cells and `floor_l` (e.g. 1 for a field that is
    /// 1-Lipschitz outside).
    pub fn build(
        (lo, hi): (DVec3, DVec3),
        dims: [usize; 3],
        floor_l: f64,
        cell: impl Fn(DVec3, DVec3) -> CellBound + Sync,
    ) -> LocalBounds {
        let dims = dims.map(|n| n.max(1));
        let h = (hi - lo) / DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
        let n = dims[0] * dims[1] * dims[2];
        let grow = 1.0 + ROUNDING_SLACK;
        // Each cell's own bounds
        let cells: Vec<CellBound> = (0..n)
            .into_par_iter()
            .map(|i| {
                let (x, y, z) = (
                    i % dims[0],
                    (i / dims[0]) % dims[1],
                    i / (dims[0] * dims[1]),
                );
                let blo = lo + h * DVec3::new(x as f64, y as f64, z as f64);
                cell(blo, (blo + h).min(hi))
            })
            .collect();
        let raw: Vec<Quad> = cells
            .iter()
            .map(|c| [c.lipschitz, c.error, c.curvature, c.gradient_error].map(|v| v * grow))
            .collect();
        // Rings of zero-free cells: erode the zero-free set one cell (26-neighbourhood) at a
        // time; cells outside the grid are zero-free (the zero set lies in it)
        let mut rings: Vec<u8> = vec![0; n];
        let mut free: Vec<bool> = cells.iter().map(|c| c.zero_free).collect();
        for r in 1..=MAX_RINGS {
            let next: Vec<bool> = (0..n)
                .into_par_iter()
                .map(|i| {
                    let c = [
                        i % dims[0],
                        (i / dims[0]) % dims[1],
                        i / (dims[0] * dims[1]),
                    ];
                    let rg = |k: usize| c[k].saturating_sub(1)..=(c[k] + 1).min(dims[k] - 1);
                    free[i]
                        && rg(2).all(|z| {
                            rg(1).all(|y| rg(0).all(|x| free[(z * dims[1] + y) * dims[0] + x]))
                        })
                })
                .collect();
            if !next.iter().any(|&b| b) {
                break;
            }
            for (i, &b) in next.iter().enumerate() {
                if b {
                    rings[i] = r;
                }
            }
            free = next;
        }
        // The pyramid: max-pool 2×2×2 cells until one cell is left
        let mut levels = vec![Level::new(&raw, dims, h)];
        let (mut cur, mut d, mut hk) = (raw.clone(), dims, h);
        while d.iter().any(|&k| k > 1) {
            let nd = d.map(|k| k.div_ceil(2));
            let mut next = vec![[0.0; 4]; nd[0] * nd[1] * nd[2]];
            for (i, &q) in cur.iter().enumerate() {
                let (x, y, z) = (i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1]));
                let j = ((z / 2) * nd[1] + y / 2) * nd[0] + x / 2;
                next[j] = qmax(next[j], q);
            }
            hk *= 2.0;
            levels.push(Level::new(&next, nd, hk));
            (cur, d) = (next, nd);
        }
        let global = raw
            .iter()
            .fold((floor_l, 0.0f64), |a, b| (a.0.max(b[0]), a.1.max(b[1])));
        LocalBounds {
            lo,
            hi,
            inv_h: DVec3::ONE / h,
            raw,
            levels,
            rings,
            h_min: h.min_element(),
            global,
        }
    }

    /// The global bound `(L_g, e_g)`: the maxima over every cell.
    pub fn global(&self) -> (f64, f64) {
        self.global
    }

    /// Cells per axis.
    pub fn dims(&self) -> [usize; 3] {
        self.levels[0].dims
    }

    /// Fine cell `i`'s zero-free rings (0: it may hold a zero, or a neighbour may).
    pub fn rings(&self, i: usize) -> u8 {
        self.rings[i]
    }

    /// Cell `i`'s box and its own `[L, e, H, g_e]` (inflated), for tests and reports.
    pub fn cell(&self, i: usize) -> ((DVec3, DVec3), [f64; 4]) {
        let d = self.dims();
        let h = DVec3::ONE / self.inv_h;
        let (x, y, z) = (i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1]));
        let blo = self.lo + h * DVec3::new(x as f64, y as f64, z as f64);
        ((blo, (blo + h).min(self.hi)), self.raw[i])
    }

    /// The number of cells.
    pub fn len(&self) -> usize {
        self.raw.len()
    }

    /// True when the grid has no cell (never: every axis has at least one).
    pub fn is_empty(&self) -> bool {
        self.raw.is_empty()
    }

    /// Fine cell of `x`, if `x` is in the grid's box.
    #[inline]
    fn fine(&self, x: DVec3) -> Option<[usize; 3]> {
        if !(x.cmpge(self.lo).all() && x.cmple(self.hi).all()) {
            return None;
        }
        let q = (x - self.lo) * self.inv_h;
        let d = self.levels[0].dims;
        let q = [q.x, q.y, q.z];
        Some([0, 1, 2].map(|k| (q[k] as usize).min(d[k] - 1)))
    }

    /// True when `x` is in a cell that may be near a zero (not inside a zero-free block): there
    /// the step can use the gradient.
    #[inline]
    pub fn near_zero(&self, x: DVec3) -> bool {
        let d = self.levels[0].dims;
        self.fine(x)
            .is_some_and(|c| self.rings[(c[2] * d[1] + c[1]) * d[0] + c[0]] == 0)
    }

    /// The safe step from `x`, where the field's computed value is `f` and, optionally, the
    /// computed `|∇f(x)|` is `grad` (module doc): signed as `f`, at least `f64::MIN_POSITIVE`
    /// in magnitude.
    #[inline]
    pub fn step(&self, x: DVec3, f: f64, grad: Option<f64>) -> f64 {
        let (lg, eg) = self.global;
        let mut s = (f.abs() - eg).max(0.0) / lg;
        if let Some(c0) = self.fine(x) {
            let d = self.levels[0].dims;
            // Inside a block of zero-free cells r rings deep: no zero within r cells
            let r = self.rings[(c0[2] * d[1] + c0[1]) * d[0] + c0[0]];
            s = s.max(r as f64 * self.h_min * (1.0 - ROUNDING_SLACK));
            // Finest level first; a coarser level helps only while the step is clamped
            for (k, lv) in self.levels.iter().enumerate() {
                let c = c0.map(|v| v >> k);
                let [l, e, h, ge] = lv.near[(c[2] * lv.dims[1] + c[1]) * lv.dims[0] + c[0]];
                let a = (f.abs() - e).max(0.0);
                let mut t = a / l;
                if let Some(g) = grad {
                    // |∇f| ≤ g + H·s on the ball of radius s: the root of H·s² + g·s = a
                    let g = g + ge;
                    let q = 2.0 * a / (g + (g * g + 4.0 * h * a).sqrt());
                    t = t.max(q * (1.0 - ROUNDING_SLACK));
                }
                s = s.max(t.min(lv.delta));
                if t <= lv.delta {
                    break;
                }
            }
        }
        let s = s.max(f64::MIN_POSITIVE);
        if f < 0.0 {
            -s
        } else {
            s
        }
    }
}
