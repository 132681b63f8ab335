//! Local Lipschitz bounds: a uniform grid of boxes over a convex region `Ω` that holds a
//! field's zero set, each box with *proved* bounds, and the safe sphere-tracing step that uses
//! them ([`LocalBounds::step`]).
//!
//! The fields derive their box bounds analytically ([`super::mpu`]: the local quadrics'
//! gradients and Hessians and the partition-of-unity weights; [`super::field`]: the blob's
//! supports that meet the box). Per box `c` a field states ([`CellBound`]): `L_c ≥ sup |∇f|`,
//! `H_c` a Lipschitz constant of `∇f`, `e_c ≥ |f̃ − f|` (the rounding of the computed value
//! `f̃`), `g_c ≥ |∇f̃ − ∇f|` (the rounding of the computed gradient vector), and whether `f` is provably zero-free on the box. Sampling
//! never enters a bound; the tests sample to check them.
//!
//! # The step rule
//! For `x` in fine cell `c`, the step is the largest of these, each of which is safe alone:
//! 1. **Global** (`x ∈ Ω`): `(|f̃| − e_g)⁺/L_g`, the maxima over every cell.
//! 2. **Zero-free block**: with `p` the projection of `x` onto `Ω` (`x` itself inside), `out =
//!    |x − p|`, and every cell within `r` cells (Chebyshev) of `p`'s cell zero-free (`h` the
//!    smallest cell width): `√(out² + (r·h)²)`. A zero `y` that close has
//!    `|y − p|² ≤ |y − x|² − out² < (r·h)²` (`(y − p)·(x − p) ≤ 0` for a projection onto a
//!    convex set), so `y` would lie in the zero-free block; cells beyond `Ω` hold no zero.
//! 3. **Local, per pyramid level `k`** (cells `2ᵏ` fine cells wide, bounds max-pooled): with
//!    `L̂, Ĥ, ê, ĝ` the maxima over the 3×3×3 cells around `x`'s cell and `δ_k` half a cell
//!    width, `min(t, δ_k)` where `t = max(a/L̂, 2a/(p + √(p² + 2Ĥa)))`, `a = (|f̃| − ê)⁺`, and
//!    `p` the rate at which `|f|` can fall from `x` (the second form only where the gradient
//!    was computed: cells that are not zero-free blocks): in any direction (a ball, the step
//!    of a cone or of a ray), `p = |∇f̃(x)| + ĝ`; along a ray of unit direction `u` (the step
//!    then only says that the ray's segment holds no zero), `p = ĝ − sign(f̃)·u·∇f̃(x)`, which
//!    is negative when the ray moves away from the zero set.
//! 4. **Local, own cell**: the same `t` from the bounds of `x`'s own fine cell alone (not
//!    max-pooled), clamped to how far the ball (or the ray) reaches inside that cell: the
//!    smallest distance from `x` to the cell's faces (along a ray, the distance to where it
//!    leaves the cell), shrunk by [`ROUNDING_SLACK`]. The box is recomputed by the same
//!    floating-point operations as when its bounds were proved; if rounding put `x` just outside
//!    its computed cell, a distance is negative and the rule gives nothing. Near the surface,
//!    where steps are far shorter than a cell, this avoids the neighbours' maxima (the curvature
//!    bound varies by 10× between neighbouring cells).
//!
//! **Why 3 and 4 are safe.** Take a zero `z` with `ρ = |x − z| < s ≤ δ_k` (along a ray: the first zero
//! `z = x + ρu` on it). The segment `[x, z]` lies in `Ω` (convex, holds both) and, as
//! `ρ < δ_k`, in the cells around `x`'s (δ is half a cell, so a cell index off by one through
//! rounding is covered too), or for rule 4 in `x`'s own cell, where `|∇f| ≤ L̂` and `∇f` is
//! `Ĥ`-Lipschitz. By the mean value
//! theorem `|f(x)| ≤ L̂ρ < a` in the first form. In the second, with `v = (z − x)/ρ` and
//! `φ(τ) = f(x + τv)`: `|φ'(τ) − φ'(0)| ≤ Ĥτ`, so by Taylor `|φ(ρ)| ≥ |φ(0)| − ρ·σφ'(0) −
//! Ĥρ²/2` (`σ = sign f(x)`, the sign that `|f|` falls with), and `−σφ'(0) = −σ v·∇f(x) ≤ p`
//! because `|∇f̃ − ∇f| ≤ ĝ` (any `v`: `|v·∇f| ≤ |∇f̃| + ĝ`; `v = u`: `−σu·∇f ≤ −σu·∇f̃ + ĝ`).
//! Hence `0 = |f(z)| ≥ |f(x)| − pρ − Ĥρ²/2 > |f(x)| − ps − Ĥs²/2 = |f(x)| − a ≥ 0` for `s` the
//! positive root of `Ĥs²/2 + ps = a` (`|f(x)| ≥ |f̃(x)| − ê ≥ a`): a contradiction. The root is
//! computed as `2a/(p + √(p² + 2Ĥa))`, whose denominator is positive for any sign of `p` when
//! `Ĥa > 0`. **A step never uses a bound beyond the region it was proved for**: the local forms
//! are clamped to `δ_k`, inside the neighbourhood whose maxima they used; a coarser level (wider
//! `δ`, larger maxima) is tried only while the finer one is clamped; the global form holds
//! everywhere.
//!
//! The step carries the sign of `f̃` (negative inside) and is at least `f64::MIN_POSITIVE` in
//! magnitude so that the sign survives: a point whose `|f̃|` is within the rounding error of 0
//! gets a step of (nearly) 0, which the tracer treats as "near the surface" and settles by
//! probing for a sign change.
//!
//! # Rounding of the bounds themselves
//! Every bound is computed in floating point as sums and products of non-negative terms, each a
//! few roundings from exact, so its relative error is far below 1e-12; [`LocalBounds::build`]
//! inflates every cell bound by `1 + 1e-9` ([`ROUNDING_SLACK`]) and the computed steps are
//! shrunk by the same factor. The fields add the rounding of their own inputs (the quadrics'
//! values and gradients at the box centre) explicitly.

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
    /// A bound on the rounding error `|∇f̃ − ∇f|` of the computed gradient vector in the box.
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

/// The linear indices of cell `i`'s 3×3×3 neighbourhood (itself included) on a `dims` grid,
/// clipped at the grid's faces.
fn neighbourhood(i: usize, dims: [usize; 3]) -> impl Iterator<Item = usize> {
    let c = [
        i % dims[0],
        (i / dims[0]) % dims[1],
        i / (dims[0] * dims[1]),
    ];
    let r = move |k: usize| c[k].saturating_sub(1)..=(c[k] + 1).min(dims[k] - 1);
    r(2).flat_map(move |z| {
        r(1).flat_map(move |y| r(0).map(move |x| (z * dims[1] + y) * dims[0] + x))
    })
}

impl Level {
    /// The level of `raw` per-cell bounds on a `dims` grid whose cells are `h` wide.
    fn new(raw: &[Quad], dims: [usize; 3], h: DVec3) -> Level {
        let near = (0..raw.len())
            .into_par_iter()
            .map(|i| neighbourhood(i, dims).fold([0.0; 4], |m, j| qmax(m, raw[j])))
            .collect();
        Level {
            dims,
            delta: 0.5 * h.min_element(),
            near,
        }
    }
}

/// Fine cell `c`'s box on the grid over `[lo, hi]` with cells `h` wide: the same floating-point
/// operations wherever it is needed, so that a step uses the very box a bound was proved on.
#[inline]
fn cell_box(lo: DVec3, hi: DVec3, h: DVec3, c: [usize; 3]) -> (DVec3, DVec3) {
    let blo = lo + h * DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
    (blo, (blo + h).min(hi))
}

/// The local step of a cell's (or neighbourhood's) bounds `[L, e, H, ĝ]` at a point where the
/// computed value is `f` (module doc, rule 3, unclamped).
#[inline]
fn local_step([l, e, h, ge]: Quad, f: f64, grad: Option<DVec3>, dir: Option<DVec3>) -> f64 {
    let a = (f.abs() - e).max(0.0);
    let mut t = a / l;
    if let Some(g) = grad {
        // The rate at which |f| can fall: along the ray, or in any direction
        let p = match dir {
            Some(u) => ge - u.dot(g) * f.signum(),
            None => g.length() + ge,
        };
        // The root of H·s²/2 + p·s = a (0 when a = 0, whatever p)
        let root = (p * p + 2.0 * h * a).sqrt();
        if a > 0.0 && p + root > 0.0 {
            t = t.max(2.0 * a / (p + root) * (1.0 - ROUNDING_SLACK));
        }
    }
    t
}

/// A grid of proved local Lipschitz bounds (module doc).
#[derive(Clone, Debug)]
pub struct LocalBounds {
    lo: DVec3,
    hi: DVec3,
    /// The fine cells' width, and its reciprocal.
    h: DVec3,
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
    /// 1-Lipschitz outside; reported, the step uses the global form on `Ω` only).
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
                let (blo, bhi) = cell_box(lo, hi, h, [x, y, z]);
                cell(blo, bhi)
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
                .map(|i| free[i] && neighbourhood(i, dims).all(|j| free[j]))
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
            h,
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
        let c = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
        (cell_box(self.lo, self.hi, self.h, c), self.raw[i])
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
    /// computed gradient is `grad` (module doc): signed as `f`, at least `f64::MIN_POSITIVE` in
    /// magnitude. With `dir` (a unit vector) the step holds for the ray from `x` along `dir`
    /// only; without, for the ball around `x`.
    #[inline]
    pub fn step(&self, x: DVec3, f: f64, grad: Option<DVec3>, dir: Option<DVec3>) -> f64 {
        let (lg, eg) = self.global;
        let mut s: f64 = 0.0;
        // Zero-free block around the cell of x's projection p onto Ω: a zero y within
        // √(out² + (r·h)²) of x has |y − p| ≤ r·h (p is a projection onto a convex set)
        let p = x.clamp(self.lo, self.hi);
        let out2 = (x - p).length_squared();
        let d = self.levels[0].dims;
        let cp = self.fine(p).expect("p is in Ω");
        let rh = self.rings[(cp[2] * d[1] + cp[1]) * d[0] + cp[0]] as f64 * self.h_min;
        s = s.max((out2 + rh * rh).sqrt() * (1.0 - ROUNDING_SLACK));
        if out2 == 0.0 {
            // Global (on Ω only: a field may jump at Ω's boundary, as the MPU's does)
            s = s.max((f.abs() - eg).max(0.0) / lg);
            // The own cell (x's computed cell, which x may lie just outside of: then no reach)
            let (blo, bhi) = cell_box(self.lo, self.hi, self.h, cp);
            let (below, above) = (x - blo, bhi - x);
            let reach = match dir {
                // Where the ray leaves the box
                Some(u) => [0, 1, 2]
                    .map(|k| match u[k] {
                        v if v > 0.0 => above[k] / v,
                        v if v < 0.0 => -below[k] / v,
                        _ => f64::INFINITY,
                    })
                    .into_iter()
                    .fold(f64::INFINITY, f64::min),
                None => below.min(above).min_element(),
            };
            if reach > 0.0 {
                let own = self.raw[(cp[2] * d[1] + cp[1]) * d[0] + cp[0]];
                let t = local_step(own, f, grad, dir);
                s = s.max(t.min(reach * (1.0 - ROUNDING_SLACK)));
            }
            // The neighbourhoods, finest level first; a coarser level helps only while the
            // step is clamped
            for (k, lv) in self.levels.iter().enumerate() {
                let c = cp.map(|v| v >> k);
                let near = lv.near[(c[2] * lv.dims[1] + c[1]) * lv.dims[0] + c[0]];
                let t = local_step(near, f, grad, dir);
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
