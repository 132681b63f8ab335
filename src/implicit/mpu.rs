//! Multi-level partition of unity implicits (Ohtake, Belyaev, Alexa, Turk, Seidel 2003), the
//! surface the seed paper (Wu & Pan) renders for the Stanford bunny.
//!
//! # Fit ([`Mpu::fit`])
//! An octree over a cube that contains [`Mpu::bounds`]. Each cell (centre `c`, diagonal `d`)
//! gets a support ball of radius `R = alpha·d`; while the ball holds fewer than `min_points`
//! points, `R ← R + lambda·R` (paper §3). In the ball, with the paper's weights
//! `w(x) = b(3|x−c|/(2R))` (`b` the quadratic B-spline on [−1.5, 1.5]):
//! - if every normal `nᵢ` in the ball has `nᵢ·n̄ > 0` (`n̄` the weighted mean normal): the
//!   bivariate quadratic `w = h(u, v)` in the frame `(t₁, t₂, n̄)` at `c`, by weighted least
//!   squares, giving `Q(x) = (x−c)·n̄ − h(u, v)`: positive along the normals, `|∇Q| ≈ 1` at
//!   the data, so `Q` ≈ signed distance near it;
//! - otherwise a general quadric (10 coefficients) minimising the paper's
//!   `(1/Σw)·Σ wᵢ Q(pᵢ)² + (1/m)·Σ (Q(q_j) − d_j)²`, the auxiliary points `q_j` being the cell
//!   centre and its 8 corners, `d_j` the mean of `(q_j − p)·n_p` over the 6 nearest ball
//!   points when those all agree in sign (else `q_j` is dropped). When all 9 are dropped (a
//!   thin sheet through the cell), the offset points `pᵢ ± (R/20)·nᵢ` with targets `±R/20`
//!   are used instead, which fix the sign and the scale the same way;
//! - a cell whose ball `R = alpha·d` holds **no point** is not fitted (nothing to fit; the
//!   paper's growth would fit far-away data and extrapolate it into empty space) and not
//!   split: it gets `Q(x) = s·(D + g·(x − c))`, the first-order expansion at `c` of the
//!   distance to the data (`D` the distance from `c` to its nearest point `p`,
//!   `g = (c − p)/D`), signed by the side `s` (+1 outside) that the 6 nearest points' normals
//!   vote for (`Σ (c − pᵢ)·nᵢ/|c − pᵢ|²`). In the ball `D + g·(x − c) ≥ D − R ≥ 0`, so such a
//!   cell adds no zero set. (A cone `s·(D − |x − c|)`, a true lower bound of the distance to
//!   the data, disagrees more with the neighbouring fits and gave a larger gradient: 4.6
//!   against 3.9 on the bunny.)
//!
//! The paper's third local type (piecewise quadrics for sharp edges and corners) is not built:
//! a scanned bunny has none. Coordinates are centred on `c` and scaled by `1/R` for the
//! solves (a small ridge keeps them regular). The error of a fit is the largest Taubin
//! distance `|Q(p)|/|∇Q(p)|` over the ball's points. A cell is split into 8 when that error
//! exceeds `max_error · (bounding-box diagonal)`, its depth is below `max_depth`, and its
//! ball (before growth) holds at least `split_points` points: with fewer, the children's balls
//! (half the radius, about a quarter of the points on a surface) would all be grown to about
//! the same `min_points` nearest points, which lowers the error little and multiplies the
//! overlapping supports (cost per evaluation, and extrapolated quadrics; the paper stops such
//! cells by `max_depth` alone).
//!
//! **Linear extension.** Each fitted quadric is used as is within the sphere `(m, ρ)` that
//! holds its ball's points (`m` their centroid, `ρ` the largest distance to it) and is
//! continued to first order (C¹) outside it: `Q̃(x) = Q(π(x)) + ∇Q(π(x))·(x − π(x))`, `π`
//! the radial projection onto that sphere. This changes nothing at the data and bounds the
//! gradient where a ball's quadric would otherwise be extrapolated quadratically across
//! empty space. On the bunny (defaults) the measured Lipschitz bound is 3.90; it was 6.0
//! without the extension (with cones for the empty cells: 4.6 with it, 6.6 without). The
//! paper's splitting (`split_points = min_points`) gives 7.7, with 2.7× the cells and about
//! 3× the evaluation cost, for a 26% smaller worst error at the points.
//!
//! # Evaluation ([`Mpu::eval`])
//! `f(x) = Σ wᵢ(x) Qᵢ(x) / Σ wᵢ(x)` over the accepted local fits whose support ball contains
//! `x`. **f > 0 outside** (along the input normals), `f < 0` inside. The set is the one found
//! by descending the octree (an accepted node contributes and is not descended); for speed,
//! [`Mpu::eval`] reads it from a uniform grid over `bounds()` whose cells list the local fits
//! whose ball meets the cell (`Mpu::eval_tree` is the descent, kept as the reference the
//! tests compare with). The root cube contains `bounds()` and the root ball (`alpha > 1/2`)
//! covers it, and every cell's ball covers the cell, so inside `bounds()` some support always
//! covers `x`. Outside `bounds()` (or, with `alpha ≤ 1/2`, where no support covers `x`),
//! `f(x) = dist(x, bounds()) + floor`, `floor` = half the margin: if the zero set lies in
//! `bounds()` shrunk by `floor`, then `dist(x, Z) ≥ dist(x, bounds()) + floor` for every `x`
//! outside (for a box `B` shrunk by `δ`, `dist(x, B_δ) ≥ dist(x, B) + δ`), so this branch
//! never over-states the distance and is 1-Lipschitz. [`MpuStats::shell_min`] is the smallest
//! MPU value met in that shell at fit time: positive (no zero there) on the bunny and the
//! sphere, the measured support for that premise.
//!
//! # Lipschitz bounds
//! **Measured** ([`Mpu::lipschitz`], the global bound of the `global` and `paper` tracers, as
//! before local bounds): `max(1, 1.5 × max |∇f|)` over a 64³ grid of `bounds()` and 36
//! samples around every input point. Not a proof.
//!
//! **Proved, per box** ([`Mpu::local_bounds`]: a grid of `LIPSCHITZ_REFINE³` boxes per cell of
//! the evaluation grid over `bounds()`, see [`super::lipschitz`] for the step rule). For a box
//! `B` (centre `x₀`, half-diagonal `r`), over the fits `i` whose ball meets `B`:
//! - `Q̃ᵢ` is C¹ and `∇Q̃ᵢ` is `Kᵢ`-Lipschitz on `B` with `Kᵢ = ‖Hᵢ‖_F` when `B` lies inside
//!   the sphere (its farthest point from `m` within `ρ`: there `Q̃ᵢ = Qᵢ`) and `Kᵢ = 3‖Hᵢ‖_F`
//!   otherwise: inside the sphere
//!   `∇²Q̃ = H`; outside, `∇Q̃ = ∇Q(π) + φ(|z|)·(Hu − (u·Hu)u)`, `u = z/|z|`,
//!   `φ = ρ(1 − ρ/|z|)`, whose derivative is at most `‖H‖ρ/|z| ≤ ‖H‖` (first term) plus
//!   `|φ'|·‖H‖ + (φ/|z|)·4‖H‖ ≤ ‖H‖ + ‖H‖` (`φ' = ρ²/|z|² ≤ 1`, `φ/|z| ≤ 1/4`). Hence, with
//!   `vᵢ, gᵢ` the value and gradient at `x₀`: `sup_B |∇Q̃ᵢ| ≤ |gᵢ| + Kᵢr` and
//!   `sup_B |Q̃ᵢ − Q̃ⱼ| ≤ |vᵢ − vⱼ| + |gᵢ − gⱼ|r + (Kᵢ + Kⱼ)r²/2` (Taylor with a Lipschitz
//!   gradient), `sup_B |∇Q̃ᵢ − ∇Q̃ⱼ| ≤ |gᵢ − gⱼ| + (Kᵢ + Kⱼ)r`.
//! - Weights `wᵢ = b(tᵢ)`, `tᵢ = 1.5|x − cᵢ|/Rᵢ` over `[t_min, t_max]` (nearest and farthest
//!   point of `B`): `b` decreases, so `b(t_max) ≤ wᵢ ≤ b(t_min)`; `|∇wᵢ| ≤ (1.5/Rᵢ)·max |b'|`
//!   (`|b'|` peaks at 1 at `t = 1/2`); `‖∇²wᵢ‖ ≤ 2(1.5/Rᵢ)²` (the radial and tangential
//!   eigenvalues `s²b''` and `s²b'/t` lie in `[−2s², s²]`).
//! - `W = Σ wⱼ ≥ W_lo = max(min_S Σ b(t_max,S), w_floor)`, the minimum over the box's
//!   `WEIGHT_SPLIT³` sub-boxes `S` (which tile it: shared faces are computed by the same
//!   operations) of the sum of each weight's least value on `S` (at `S`'s farthest point from
//!   its centre); `w_floor = b(0.75/alpha)`: every point lies in a leaf cell whose ball
//!   (`R ≥ alpha·diagonal`) reaches it at `t ≤ 0.75/alpha`. (One sum over the whole box, each
//!   weight at its own farthest corner, was about half as large, and `W_lo` divides every term
//!   below, squared in `H_B`.)
//! - The shares `λⱼ = wⱼ/W` sum to 1 with `0 ≤ λⱼ ≤ b(t_min,ⱼ)/W_lo`; a "mix" of per-fit bounds
//!   `mⱼ` is the largest `Σ λⱼmⱼ` under these constraints (fill the largest `mⱼ` first).
//! - `∇f = Σ λᵢ∇Q̃ᵢ + Σ ∇wᵢ(Q̃ᵢ − f)/W` and `Q̃ᵢ − f = Σⱼ λⱼ(Q̃ᵢ − Q̃ⱼ)`, so
//!   `L_B = mix(|gᵢ| + Kᵢr) + Σᵢ sup|∇wᵢ|·mixⱼ(sup|Q̃ᵢ − Q̃ⱼ|)/W_lo`.
//! - `W∇²f = Σ [(∇Q̃ᵢ − ∇f)⊗∇wᵢ + ∇wᵢ⊗(∇Q̃ᵢ − ∇f) + wᵢ∇²Q̃ᵢ + ∇²wᵢ(Q̃ᵢ − f)]` (differentiate
//!   `W∇f = Σ wᵢ∇Q̃ᵢ + Σ ∇wᵢ(Q̃ᵢ − f)`), so `H_B = Σᵢ [2 sup|∇wᵢ|(mixⱼ sup|∇Q̃ᵢ − ∇Q̃ⱼ| +
//!   spread) + ‖∇²wᵢ‖·mixⱼ sup|Q̃ᵢ − Q̃ⱼ|]/W_lo + mix(Kᵢ)`, `spread` the second term of `L_B`.
//! - `f ∈ [−mix(−vⱼ + reachⱼ), mix(vⱼ + reachⱼ)]`, `reachⱼ = |gⱼ|r + Kⱼr²/2`: the box is
//!   zero-free when this range, widened by the evaluation error, excludes 0.
//! - Rounding: `vᵢ` and `gᵢ` are computed, so every difference gets the evaluation error `e`
//!   twice and each gradient `1e-12·(|bᵢ| + 3‖Hᵢ‖·|z|max)`; `e = 4(n + 100)·u·max Tᵢ` with
//!   `Tᵢ` the sum of the magnitudes of `Q̃ᵢ`'s terms over `B` (`n` fits, each value ~15
//!   roundings, the weighted mean `n` more; `|f| ≤ max|Q̃ᵢ|` as a mean), and the computed
//!   gradient vector is within `1e-10·(L_B + Σ sup|∇wᵢ|·max Tᵢ/W_lo)` of `∇f` (each component
//!   is ~`n + 100` roundings of terms of at most these magnitudes: over 1000× below, enough for
//!   the vector's norm, which the step along a ray uses, not only its length's).
//!
//! Outside `bounds()` the field is the box distance plus `floor` (1-Lipschitz, never above the
//! distance to the zero set), so the grid's global floor is 1. On the bunny the proved bounds
//! are looser than `|∇f|` (the measured `|∇f|` is 2.6 at most): over the 38,156 boxes near the
//! surface the median `L_B` is 2.5 (2.4× the largest `|∇f|` sampled on the box's 3³ lattice)
//! and the median `H_B` 51 (54× the largest sampled difference quotient of `∇f`); they were
//! 3.4 and 103 when `W_lo` was one sum over the box and `Kᵢ` always `3‖Hᵢ‖_F`. The boxes are
//! about a third of a support radius across, where the weights vary by a factor of ~3, and the
//! triangle inequality over ~17 overlapping fits loses the cancellation that keeps the true
//! `|∇f|` near 1; the terms with `∇wᵢ` dominate `H_B`. The tracer's cost follows `H_B`
//! closely: before these two tightenings, with every curvature bound halved (unsafe, measured
//! only) the certified pass took 28 evaluations per hit instead of 36, with a quarter 22; the
//! two tightenings took it to 24.
//!
//! # Ghost surfaces
//! Local quadrics extrapolated into empty space can have zero sets away from the data.
//! `tests/mpu.rs` measures them against the bunny mesh's inside/outside (generalised winding
//! number) on a grid, binned by the distance to the mesh: on a 40³ grid over `bounds()`, no
//! point 0.2 or more from the mesh has the wrong sign (outside and inside alike); between 0.1
//! and 0.2, 1 of 2493; closer, the smooth MPU surface and the flat-faced mesh differ (137 of
//! 2321 within 0.1, mostly MPU bulging past the faces). No random segment staying ≥ 0.4 from
//! the mesh sees a sign change. Outside and ≥ 0.05 from the mesh, `f` is at most 1.87× the
//! distance to the mesh, so `f/lipschitz()` stays below half of it there.
//!
//! # Cost (bunny, defaults, the 2-core dev machine)
//! Fit ≈ 0.09 s on both cores, including the Lipschitz measurement, plus the proved local
//! bounds (75³ boxes, each with its ~17² pairs of fits and the weights on 4³ sub-boxes): loading
//! the bunny scene took 2.3–2.4 s at load ~2 on 2026-11-25 04:17 UTC, against 1.6 s with one
//! weight sum per box (the two builds alternated); 2393 cells, 2094 leaves (1072
//! bivariate, 319 general, 703 empty); [`Mpu::eval`] ≈ 0.35 µs (≈ 15 contributing fits near
//! the surface, ≈ 10 elsewhere), [`Mpu::eval_grad`] ≈ 0.45 µs.

use super::lipschitz::{CellBound, LocalBounds};
use crate::input::MAX_MAGNITUDE;
use crate::numerics::interval::Interval;
use anyhow::{anyhow, bail, Context, Result};
use glam::DVec3;
use rayon::prelude::*;
use std::path::Path;

/// Fit parameters. Paper values except `max_error` and `split_points`, which are ours.
#[derive(Clone, Debug, PartialEq)]
pub struct MpuOptions {
    /// ε₀: a cell is split while its fit's largest Taubin distance exceeds
    /// `max_error × (diagonal of the points' bounding box)`. Default 0.002 (0.032 for the
    /// bunny, whose diagonal is 15.76 and mean edge ≈ 0.4). On data as sparse as the bunny,
    /// `split_points` ends the subdivision for most cells before ε₀ is met (1237 of its 1391
    /// fitted leaves are above it; worst error at the points 0.065, mean 0.010); 0.001–0.01
    /// change the cell count by ±10% and the worst error not at all.
    pub max_error: f64,
    /// Support radius = `alpha × cell diagonal` (paper: 0.75). Must be > 1/2 for the root ball
    /// to cover the whole root cube.
    pub alpha: f64,
    /// N_min: a support grows until it holds this many points (paper: 15).
    pub min_points: usize,
    /// Deepest octree level (root = 0). At most 30.
    pub max_depth: u32,
    /// Support growth step: `R ← R + lambda·R` (paper: 0.1).
    pub lambda: f64,
    /// A cell is split only if its support ball (before growth) holds at least this many
    /// points (default 30 = 2·N_min; see the module doc). `min_points` reproduces the
    /// paper's octree except that cells needing growth are not split.
    pub split_points: usize,
}

impl Default for MpuOptions {
    fn default() -> Self {
        MpuOptions {
            max_error: 0.002,
            alpha: 0.75,
            min_points: 15,
            max_depth: 12,
            lambda: 0.1,
            split_points: 30,
        }
    }
}

/// Statistics of a fit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MpuStats {
    /// Octree nodes (accepted local fits plus split cells).
    pub cells: usize,
    /// Accepted local fits (the leaves).
    pub leaves: usize,
    /// Leaves fitted by the bivariate quadratic.
    pub bivariate: usize,
    /// Leaves fitted by a general quadric with the cell's auxiliary points.
    pub general: usize,
    /// Leaves fitted by a general quadric with the normal-offset fallback (or, for
    /// degenerate input, a plane).
    pub general_offsets: usize,
    /// Leaves for cells whose support ball holds no point (planes `s·(D + g·(x − c))`).
    pub empty: usize,
    /// Empty leaves whose nearest points disagreed on the side (the weighted vote decided).
    pub empty_split_vote: usize,
    /// Leaves whose ball was grown to reach `min_points`.
    pub grown: usize,
    /// Leaves accepted with an error above `max_error` (too few points to split, or at
    /// `max_depth`).
    pub over_error: usize,
    /// Deepest level reached.
    pub depth: u32,
    /// Largest fit error (Taubin distance, world units) over the leaves.
    pub max_leaf_error: f64,
    /// Entries in the evaluation grid's lists, and its cells per axis.
    pub grid_entries: usize,
    /// Cells per axis of the evaluation grid.
    pub grid_size: usize,
    /// Largest measured `|∇f|` (before the safety factor), and where.
    pub max_gradient: f64,
    /// Where the largest `|∇f|` was measured.
    pub max_gradient_at: DVec3,
    /// Smallest MPU value on the measurement grid's points in the shell between `bounds()`
    /// shrunk by `floor` and `bounds()` (> 0 means no zero set seen there; module doc).
    pub shell_min: f64,
}

/// Safety factor on the measured gradient maximum (the baseline's global bound).
pub const LIPSCHITZ_SAFETY: f64 = 1.5;
/// Cells per axis of the local Lipschitz grid per cell of the evaluation grid.
pub const LIPSCHITZ_REFINE: usize = 3;

/// Sub-boxes per axis over which a box's lower bound of `Σ wᵢ` is taken (module doc).
const WEIGHT_SPLIT: usize = 4;
/// Grid resolution per axis of the Lipschitz measurement.
pub const LIPSCHITZ_GRID: usize = 64;
/// `bounds()` = the points' bounding box grown by this fraction of its diagonal per side.
pub const BOUNDS_MARGIN: f64 = 0.05;
/// Points that vote on an empty cell's side.
const EMPTY_NEAREST: usize = 6;
const NONE: u32 = u32::MAX;

/// An octree node (for building, statistics and the reference descent).
#[derive(Clone, Debug)]
struct Node {
    c: DVec3,
    /// Squared radius around `c` containing every support at or below this node.
    reach2: f64,
    /// First of 8 children, or `NONE`.
    child: u32,
    /// The accepted local fit, or `NONE`.
    leaf: u32,
}

/// An accepted local function: weight centre `c`, support `R`; the quadric is in `z = x − m`:
/// `Q = a·(z0², z1², z2², z0z1, z0z2, z1z2) + b·z + k`, continued linearly outside
/// `|z| ≤ ρ`.
#[derive(Clone, Debug)]
struct Local {
    c: DVec3,
    r2: f64,
    /// 1.5 / R.
    s: f64,
    m: DVec3,
    rho: f64,
    rho2: f64,
    a: [f64; 6],
    b: DVec3,
    k: f64,
}

impl Local {
    #[inline(always)]
    fn quad(&self, z: DVec3) -> f64 {
        let a = &self.a;
        z.x * (a[0] * z.x + a[3] * z.y + a[4] * z.z)
            + z.y * (a[1] * z.y + a[5] * z.z)
            + a[2] * z.z * z.z
            + self.b.dot(z)
            + self.k
    }
    /// `H·v` (H the Hessian of the quadratic part).
    #[inline(always)]
    fn hess(&self, v: DVec3) -> DVec3 {
        let a = &self.a;
        DVec3::new(
            2.0 * a[0] * v.x + a[3] * v.y + a[4] * v.z,
            2.0 * a[1] * v.y + a[3] * v.x + a[5] * v.z,
            2.0 * a[2] * v.z + a[4] * v.x + a[5] * v.y,
        )
    }
    /// `‖H‖_F`, an upper bound of the Hessian's spectral norm.
    fn hess_norm(&self) -> f64 {
        let a = &self.a;
        (4.0 * (a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
            + 2.0 * (a[3] * a[3] + a[4] * a[4] + a[5] * a[5]))
            .sqrt()
    }
    /// Q at `p` (with the linear extension).
    #[inline(always)]
    fn q(&self, p: DVec3) -> f64 {
        let z = p - self.m;
        let z2 = z.length_squared();
        if z2 <= self.rho2 {
            self.quad(z)
        } else {
            let zp = z * (self.rho / z2.sqrt());
            self.quad(zp) + (self.hess(zp) + self.b).dot(z - zp)
        }
    }
    /// Q and ∇Q at `p`.
    #[inline]
    fn q_grad(&self, p: DVec3) -> (f64, DVec3) {
        let z = p - self.m;
        let z2 = z.length_squared();
        if z2 <= self.rho2 {
            (self.quad(z), self.hess(z) + self.b)
        } else {
            // ∇Q̃ = g + ρ(1 − ρ/|z|)(Hẑ − (ẑ·Hẑ)ẑ), g = ∇Q(π).
            let r = z2.sqrt();
            let u = z / r;
            // Same operations as `q`, so that eval and eval_grad agree to the bit.
            let zp = z * (self.rho / r);
            let g = self.hess(zp) + self.b;
            let hu = self.hess(u);
            let v = self.quad(zp) + g.dot(z - zp);
            (
                v,
                g + (self.rho * (1.0 - self.rho / r)) * (hu - hu.dot(u) * u),
            )
        }
    }
}

/// The quadratic B-spline on [−1.5, 1.5] and its derivative, for t ≥ 0.
#[inline(always)]
fn bspline(t: f64) -> (f64, f64) {
    if t < 0.5 {
        (0.75 - t * t, -2.0 * t)
    } else if t < 1.5 {
        let u = 1.5 - t;
        (0.5 * u * u, -u)
    } else {
        (0.0, 0.0)
    }
}

#[inline(always)]
fn weight(r: f64, radius: f64) -> f64 {
    bspline(1.5 * r / radius).0
}

/// A fitted MPU implicit. See the module doc.
#[derive(Clone, Debug)]
pub struct Mpu {
    nodes: Vec<Node>,
    locals: Vec<Local>,
    lo: DVec3,
    hi: DVec3,
    floor: f64,
    lipschitz: f64,
    /// Proved lower bound of `Σ wᵢ` at every point of `bounds()` (0 when `alpha ≤ 1/2`).
    w_floor: f64,
    /// Proved local Lipschitz bounds over `bounds()`.
    local: Option<LocalBounds>,
    /// Evaluation grid: `gn` cells per axis over `bounds()`; cell `i` lists
    /// `list[start[i]..start[i+1]]`.
    gn: usize,
    ginv: DVec3,
    start: Vec<u32>,
    list: Vec<u32>,
    stats: MpuStats,
}

/// A quadric in `y = x − c` during fitting:
/// `Q = a·(y0², y1², y2², y0y1, y0y2, y1y2) + b·y + k`.
#[derive(Clone, Copy, Debug, Default)]
struct Quadric {
    a: [f64; 6],
    b: DVec3,
    k: f64,
}

impl Quadric {
    fn value(&self, y: DVec3) -> f64 {
        let a = &self.a;
        y.x * (a[0] * y.x + a[3] * y.y + a[4] * y.z)
            + y.y * (a[1] * y.y + a[5] * y.z)
            + a[2] * y.z * y.z
            + self.b.dot(y)
            + self.k
    }
    fn grad(&self, y: DVec3) -> DVec3 {
        let a = &self.a;
        DVec3::new(
            2.0 * a[0] * y.x + a[3] * y.y + a[4] * y.z,
            2.0 * a[1] * y.y + a[3] * y.x + a[5] * y.z,
            2.0 * a[2] * y.z + a[4] * y.x + a[5] * y.y,
        ) + self.b
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Bivariate,
    General,
    GeneralOffsets,
    Empty,
    EmptySplitVote,
}

struct CellFit {
    local: Local,
    /// Points in the ball before growth.
    nball: usize,
    err: f64,
    grown: bool,
    kind: Kind,
}

/// Uniform grid over the points for ball queries.
struct PointGrid<'a> {
    pts: &'a [DVec3],
    lo: DVec3,
    inv_h: f64,
    dims: [usize; 3],
    start: Vec<u32>,
    idx: Vec<u32>,
}

impl<'a> PointGrid<'a> {
    fn new(pts: &'a [DVec3], lo: DVec3, hi: DVec3) -> Self {
        let ext = (hi - lo).max(DVec3::splat(1e-300));
        let target = (pts.len() as f64 / 2.0).max(1.0);
        let h = (ext.x * ext.y * ext.z / target)
            .cbrt()
            .max(ext.max_element() / 128.0);
        let dims = [0, 1, 2].map(|k| ((ext[k] / h).ceil() as usize).clamp(1, 128));
        let inv_h = 1.0 / h;
        let cell = |p: DVec3| -> usize {
            let q = (p - lo) * inv_h;
            let i = (q.x as usize).min(dims[0] - 1);
            let j = (q.y as usize).min(dims[1] - 1);
            let k = (q.z as usize).min(dims[2] - 1);
            (k * dims[1] + j) * dims[0] + i
        };
        let n = dims[0] * dims[1] * dims[2];
        let mut count = vec![0u32; n + 1];
        for &p in pts {
            count[cell(p) + 1] += 1;
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut idx = vec![0u32; pts.len()];
        for (i, &p) in pts.iter().enumerate() {
            let c = cell(p);
            idx[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        PointGrid {
            pts,
            lo,
            inv_h,
            dims,
            start: count,
            idx,
        }
    }

    /// Indices of the points with `|p − c| < r`, in increasing index order.
    fn ball(&self, c: DVec3, r: f64, out: &mut Vec<u32>) {
        out.clear();
        let lo = ((c - DVec3::splat(r) - self.lo) * self.inv_h).floor();
        let hi = ((c + DVec3::splat(r) - self.lo) * self.inv_h).floor();
        let rng = |k: usize| -> Option<(usize, usize)> {
            if hi[k] < 0.0 || lo[k] > (self.dims[k] - 1) as f64 {
                return None;
            }
            Some((
                lo[k].max(0.0) as usize,
                (hi[k] as usize).min(self.dims[k] - 1),
            ))
        };
        let (Some((i0, i1)), Some((j0, j1)), Some((k0, k1))) = (rng(0), rng(1), rng(2)) else {
            return;
        };
        let r2 = r * r;
        for k in k0..=k1 {
            for j in j0..=j1 {
                let row = (k * self.dims[1] + j) * self.dims[0];
                let (s, e) = (self.start[row + i0], self.start[row + i1 + 1]);
                for &i in &self.idx[s as usize..e as usize] {
                    if (self.pts[i as usize] - c).length_squared() < r2 {
                        out.push(i);
                    }
                }
            }
        }
        out.sort_unstable();
    }
}

/// Solves the symmetric positive (semi)definite system `m·x = r` by Cholesky with a small
/// relative ridge; `None` if it still fails or the answer is not finite.
fn solve_spd<const N: usize>(m: &[[f64; N]; N], r: &[f64; N]) -> Option<[f64; N]> {
    let tr: f64 = (0..N).map(|i| m[i][i]).sum();
    if tr.is_nan() || tr <= 0.0 || !tr.is_finite() {
        return None;
    }
    for ridge in [1e-12, 1e-9, 1e-6] {
        let mut l = *m;
        for (i, row) in l.iter_mut().enumerate() {
            row[i] += ridge * tr / N as f64;
        }
        let mut ok = true;
        for j in 0..N {
            let d = l[j][j] - l[j][..j].iter().map(|v| v * v).sum::<f64>();
            if d.is_nan() || d <= 0.0 {
                ok = false;
                break;
            }
            let d = d.sqrt();
            l[j][j] = d;
            for i in j + 1..N {
                let s = l[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
                l[i][j] = s / d;
            }
        }
        if !ok {
            continue;
        }
        let mut x = *r;
        for i in 0..N {
            let mut s = x[i];
            for k in 0..i {
                s -= l[i][k] * x[k];
            }
            x[i] = s / l[i][i];
        }
        for i in (0..N).rev() {
            let mut s = x[i];
            for k in i + 1..N {
                s -= l[k][i] * x[k];
            }
            x[i] = s / l[i][i];
        }
        if x.iter().all(|v| v.is_finite()) {
            return Some(x);
        }
    }
    None
}

/// Fits the bivariate quadratic; `None` when the system is singular.
fn fit_bivariate(
    pts: &[DVec3],
    ball: &[u32],
    w: &[f64],
    c: DVec3,
    r: f64,
    n: DVec3,
) -> Option<Quadric> {
    let (t1, t2) = n.any_orthonormal_pair();
    let mut m = [[0.0; 6]; 6];
    let mut rhs = [0.0; 6];
    for (&i, &wi) in ball.iter().zip(w) {
        let y = (pts[i as usize] - c) / r;
        let (u, v, h) = (y.dot(t1), y.dot(t2), y.dot(n));
        let phi = [u * u, 2.0 * u * v, v * v, u, v, 1.0];
        for a in 0..6 {
            rhs[a] += wi * phi[a] * h;
            for b in 0..6 {
                m[a][b] += wi * phi[a] * phi[b];
            }
        }
    }
    let th = solve_spd(&m, &rhs)?;
    // World: Q = n·y − (θ0 (t1·y)² + 2θ1 (t1·y)(t2·y) + θ2 (t2·y)²)/r − θ3 t1·y − θ4 t2·y − θ5 r.
    let mut s = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            s[i][j] = -(th[0] * t1[i] * t1[j]
                + th[1] * (t1[i] * t2[j] + t2[i] * t1[j])
                + th[2] * t2[i] * t2[j])
                / r;
        }
    }
    Some(Quadric {
        a: [
            s[0][0],
            s[1][1],
            s[2][2],
            2.0 * s[0][1],
            2.0 * s[0][2],
            2.0 * s[1][2],
        ],
        b: n - th[3] * t1 - th[4] * t2,
        k: -th[5] * r,
    })
}

fn quadric_basis(y: DVec3) -> [f64; 10] {
    [
        y.x * y.x,
        y.y * y.y,
        y.z * y.z,
        y.x * y.y,
        y.x * y.z,
        y.y * y.z,
        y.x,
        y.y,
        y.z,
        1.0,
    ]
}

/// Fits the general quadric with auxiliary values `aux` (world points, target values).
fn fit_general(
    pts: &[DVec3],
    ball: &[u32],
    w: &[f64],
    c: DVec3,
    r: f64,
    aux: &[(DVec3, f64)],
) -> Option<Quadric> {
    let sw: f64 = w.iter().sum();
    let mut m = [[0.0; 10]; 10];
    let mut rhs = [0.0; 10];
    for (&i, &wi) in ball.iter().zip(w) {
        let phi = quadric_basis((pts[i as usize] - c) / r);
        let s = wi / sw;
        for a in 0..10 {
            for b in 0..10 {
                m[a][b] += s * phi[a] * phi[b];
            }
        }
    }
    let s = 1.0 / aux.len() as f64;
    for &(q, d) in aux {
        let phi = quadric_basis((q - c) / r);
        for a in 0..10 {
            rhs[a] += s * phi[a] * d;
            for b in 0..10 {
                m[a][b] += s * phi[a] * phi[b];
            }
        }
    }
    let th = solve_spd(&m, &rhs)?;
    let (r1, r2) = (1.0 / r, 1.0 / (r * r));
    Some(Quadric {
        a: [
            th[0] * r2,
            th[1] * r2,
            th[2] * r2,
            th[3] * r2,
            th[4] * r2,
            th[5] * r2,
        ],
        b: DVec3::new(th[6], th[7], th[8]) * r1,
        k: th[9],
    })
}

/// The paper's auxiliary points: the cell centre and corners whose 6 nearest ball points
/// agree on the side.
fn aux_points(
    pts: &[DVec3],
    nrm: &[DVec3],
    ball: &[u32],
    c: DVec3,
    half: f64,
) -> Vec<(DVec3, f64)> {
    let mut out = Vec::with_capacity(9);
    let mut near: Vec<(f64, u32)> = Vec::with_capacity(ball.len());
    let mut qs = vec![c];
    for s in 0..8 {
        let sg = |b: i32| if s & b != 0 { 1.0 } else { -1.0 };
        qs.push(c + half * DVec3::new(sg(1), sg(2), sg(4)));
    }
    for q in qs {
        near.clear();
        near.extend(
            ball.iter()
                .map(|&i| ((pts[i as usize] - q).length_squared(), i)),
        );
        let k = near.len().min(6);
        if k == 0 {
            continue;
        }
        if k < near.len() {
            near.select_nth_unstable_by(k - 1, |a, b| a.partial_cmp(b).unwrap());
        }
        let ds: Vec<f64> = near[..k]
            .iter()
            .map(|&(_, i)| (q - pts[i as usize]).dot(nrm[i as usize]))
            .collect();
        if ds.iter().all(|&d| d > 0.0) || ds.iter().all(|&d| d < 0.0) {
            out.push((q, ds.iter().sum::<f64>() / k as f64));
        }
    }
    out
}

/// The side vote and plane of a cell whose ball `(c, r)` holds no point (module doc).
fn empty_cell(grid: &PointGrid, nrm: &[DVec3], c: DVec3, r: f64, ball: &mut Vec<u32>) -> CellFit {
    let pts = grid.pts;
    let k = EMPTY_NEAREST.min(pts.len());
    let mut rr = r;
    while ball.len() < k {
        rr *= 1.25;
        grid.ball(c, rr, ball);
    }
    let mut near: Vec<(f64, u32)> = ball
        .iter()
        .map(|&i| ((pts[i as usize] - c).length(), i))
        .collect();
    near.sort_unstable_by(|a, b| a.partial_cmp(b).unwrap());
    let near = &near[..k];
    let vote = |&(d, i): &(f64, u32)| (c - pts[i as usize]).dot(nrm[i as usize]) / (d * d);
    let s: f64 = near.iter().map(vote).sum();
    let sign = if s >= 0.0 { 1.0 } else { -1.0 };
    let split = !near.iter().all(|x| vote(x) * sign > 0.0);
    let (d, p) = (near[0].0, pts[near[0].1 as usize]);
    let g = (c - p) / d;
    CellFit {
        local: Local {
            c,
            r2: r * r,
            s: 1.5 / r,
            m: c,
            rho: f64::INFINITY,
            rho2: f64::INFINITY,
            a: [0.0; 6],
            b: sign * g,
            k: sign * d,
        },
        nball: 0,
        err: 0.0,
        grown: false,
        kind: if split {
            Kind::EmptySplitVote
        } else {
            Kind::Empty
        },
    }
}

fn fit_cell(
    grid: &PointGrid,
    nrm: &[DVec3],
    c: DVec3,
    half: f64,
    opts: &MpuOptions,
    ball: &mut Vec<u32>,
) -> CellFit {
    let pts = grid.pts;
    let need = opts.min_points.min(pts.len()).max(1);
    let mut r = opts.alpha * half * 2.0 * 3f64.sqrt();
    grid.ball(c, r, ball);
    if ball.is_empty() {
        return empty_cell(grid, nrm, c, r, ball);
    }
    let nball = ball.len();
    let grown = nball < need;
    while ball.len() < need {
        r += opts.lambda * r;
        grid.ball(c, r, ball);
    }
    let w: Vec<f64> = ball
        .iter()
        .map(|&i| weight((pts[i as usize] - c).length(), r))
        .collect();
    let nsum: DVec3 = ball
        .iter()
        .zip(&w)
        .map(|(&i, &wi)| wi * nrm[i as usize])
        .sum();
    let nbar = nsum.normalize_or_zero();
    let mut fit = None;
    if nbar != DVec3::ZERO && ball.iter().all(|&i| nrm[i as usize].dot(nbar) > 0.0) {
        fit = fit_bivariate(pts, ball, &w, c, r, nbar).map(|q| (q, Kind::Bivariate));
    }
    if fit.is_none() {
        let aux = aux_points(pts, nrm, ball, c, half);
        if !aux.is_empty() {
            fit = fit_general(pts, ball, &w, c, r, &aux).map(|q| (q, Kind::General));
        }
    }
    if fit.is_none() {
        let delta = r / 20.0;
        let aux: Vec<(DVec3, f64)> = ball
            .iter()
            .flat_map(|&i| {
                let (p, n) = (pts[i as usize], nrm[i as usize]);
                [(p + delta * n, delta), (p - delta * n, -delta)]
            })
            .collect();
        fit = fit_general(pts, ball, &w, c, r, &aux).map(|q| (q, Kind::GeneralOffsets));
    }
    // Degenerate input (e.g. all points coincide): the plane through the ball's centroid
    // with the mean normal.
    let centroid: DVec3 =
        ball.iter().map(|&i| pts[i as usize] - c).sum::<DVec3>() / ball.len() as f64;
    let (q, kind) = fit.unwrap_or_else(|| {
        let n = if nbar == DVec3::ZERO { DVec3::X } else { nbar };
        (
            Quadric {
                a: [0.0; 6],
                b: n,
                k: -n.dot(centroid),
            },
            Kind::GeneralOffsets,
        )
    });
    let err = ball
        .iter()
        .map(|&i| {
            let y = pts[i as usize] - c;
            let v = q.value(y).abs();
            if v == 0.0 {
                0.0
            } else {
                v / q.grad(y).length()
            }
        })
        .fold(
            0.0,
            |a: f64, b| if b.is_nan() { f64::INFINITY } else { a.max(b) },
        );
    // Re-centre the quadric on the points' centroid m (z = x − m = y − δ, δ = m − c).
    let rho = ball
        .iter()
        .map(|&i| (pts[i as usize] - c - centroid).length())
        .fold(0.0, f64::max);
    let local = Local {
        c,
        r2: r * r,
        s: 1.5 / r,
        m: c + centroid,
        rho,
        rho2: rho * rho,
        a: q.a,
        b: q.grad(centroid),
        k: q.value(centroid),
    };
    CellFit {
        local,
        nball,
        err,
        grown,
        kind,
    }
}

impl Mpu {
    /// Fits the MPU implicit to oriented points (normals point outward; they are normalised
    /// here). Deterministic: the octree is built level by level, each level's cells fitted
    /// in parallel and stored in order.
    ///
    /// # Panics
    /// If `points` is empty, the slices' lengths differ, a coordinate is not finite or beyond
    /// ±[`MAX_MAGNITUDE`] (the fit's squared distances would overflow and its searches never end), a normal
    /// is zero or not finite, or an option is out of range (`alpha`, `lambda` and `max_error`
    /// must be positive, `max_depth ≤ 30`).
    pub fn fit(points: &[DVec3], normals: &[DVec3], opts: &MpuOptions) -> Mpu {
        assert!(!points.is_empty(), "Mpu::fit: no points");
        assert_eq!(
            points.len(),
            normals.len(),
            "Mpu::fit: points and normals differ in length"
        );
        assert!(
            opts.alpha > 0.0 && opts.lambda > 0.0 && opts.max_error > 0.0 && opts.max_depth <= 30,
            "Mpu::fit: options out of range: {opts:?}"
        );
        assert!(
            points.iter().all(|p| p.is_finite()),
            "Mpu::fit: non-finite point"
        );
        assert!(
            points
                .iter()
                .all(|p| p.abs().max_element() <= MAX_MAGNITUDE),
            "Mpu::fit: a point beyond ±{MAX_MAGNITUDE:e}"
        );
        let nrm: Vec<DVec3> = normals
            .iter()
            .map(|n| {
                let u = n.normalize_or_zero();
                assert!(
                    u != DVec3::ZERO && u.is_finite(),
                    "Mpu::fit: zero or non-finite normal"
                );
                u
            })
            .collect();
        let (plo, phi) = points.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(a, b), &p| (a.min(p), b.max(p)),
        );
        let diag = (phi - plo).length();
        // A single point (or all coincident) still gets a box of positive size.
        let margin = (BOUNDS_MARGIN * diag).max(1e-3 * (1.0 + plo.abs().max_element()));
        let (lo, hi) = (plo - DVec3::splat(margin), phi + DVec3::splat(margin));
        let tol = opts.max_error * diag.max(margin);
        let grid = PointGrid::new(points, plo, phi);

        let mut nodes = vec![Node {
            c: 0.5 * (lo + hi),
            reach2: 0.0,
            child: NONE,
            leaf: NONE,
        }];
        let mut halves = vec![0.5 * (hi - lo).max_element()];
        let mut depths = vec![0u32];
        let mut locals: Vec<Local> = Vec::new();
        let mut stats = MpuStats::default();
        let mut level: Vec<usize> = vec![0];
        while !level.is_empty() {
            let fits: Vec<CellFit> = level
                .par_iter()
                .map_init(Vec::new, |ball, &i| {
                    fit_cell(&grid, &nrm, nodes[i].c, halves[i], opts, ball)
                })
                .collect();
            let mut next = Vec::new();
            for (&i, f) in level.iter().zip(fits) {
                let depth = depths[i];
                stats.depth = stats.depth.max(depth);
                let split =
                    f.err > tol && depth < opts.max_depth && f.nball >= opts.split_points.max(1);
                if split {
                    let first = nodes.len();
                    nodes[i].child = first as u32;
                    let (c, h) = (nodes[i].c, 0.5 * halves[i]);
                    for s in 0..8 {
                        let sg = |b: i32| if s & b != 0 { h } else { -h };
                        nodes.push(Node {
                            c: c + DVec3::new(sg(1), sg(2), sg(4)),
                            reach2: 0.0,
                            child: NONE,
                            leaf: NONE,
                        });
                        halves.push(h);
                        depths.push(depth + 1);
                        next.push(first + s as usize);
                    }
                    continue;
                }
                match f.kind {
                    Kind::Bivariate => stats.bivariate += 1,
                    Kind::General => stats.general += 1,
                    Kind::GeneralOffsets => stats.general_offsets += 1,
                    Kind::Empty => stats.empty += 1,
                    Kind::EmptySplitVote => {
                        stats.empty += 1;
                        stats.empty_split_vote += 1;
                    }
                }
                stats.grown += usize::from(f.grown);
                stats.over_error += usize::from(f.err > tol);
                stats.max_leaf_error = stats.max_leaf_error.max(f.err);
                nodes[i].leaf = locals.len() as u32;
                locals.push(f.local);
            }
            level = next;
        }
        // Reach radii, children before parents (children have larger indices).
        for i in (0..nodes.len()).rev() {
            let reach = if nodes[i].leaf != NONE {
                locals[nodes[i].leaf as usize].r2.sqrt()
            } else {
                let f = nodes[i].child as usize;
                (f..f + 8)
                    .map(|j| (nodes[j].c - nodes[i].c).length() + nodes[j].reach2.sqrt())
                    .fold(0.0, f64::max)
            };
            // Round up a little so that pruning never drops a contributing support.
            nodes[i].reach2 = (reach * (1.0 + 1e-12)).powi(2);
        }
        stats.cells = nodes.len();
        stats.leaves = locals.len();
        let mut mpu = Mpu {
            nodes,
            locals,
            lo,
            hi,
            floor: 0.5 * margin,
            lipschitz: 1.0,
            // A leaf cell's ball (R ≥ alpha·diagonal) reaches t = 1.5·|x − c|/R ≤ 0.75/alpha
            w_floor: if opts.alpha > 0.5 {
                bspline(0.75 / opts.alpha).0 * (1.0 - 1e-9)
            } else {
                0.0
            },
            local: None,
            gn: 1,
            ginv: DVec3::ONE,
            start: vec![],
            list: vec![],
            stats,
        };
        mpu.build_grid();
        mpu.measure_lipschitz(points, &nrm);
        let gn = mpu.gn * LIPSCHITZ_REFINE;
        let local = LocalBounds::build((lo, hi), [gn; 3], 1.0, |a, b| mpu.box_bound(a, b));
        mpu.local = Some(local);
        mpu
    }

    /// Lists, for each cell of a uniform grid over `bounds()`, the local fits whose ball
    /// meets the cell (exact sphere–box test), in increasing index order.
    fn build_grid(&mut self) {
        let ext = self.hi - self.lo;
        // Cells of about half the median support radius of the fitted (non-empty) leaves.
        let mut radii: Vec<f64> = self
            .locals
            .iter()
            .filter(|l| l.rho.is_finite())
            .map(|l| l.r2.sqrt())
            .collect();
        radii.sort_unstable_by(|a, b| a.partial_cmp(b).unwrap());
        let med = radii
            .get(radii.len() / 2)
            .copied()
            .unwrap_or(ext.max_element());
        // (Finer grids shorten the lists but cost memory and cache: on the bunny, 0.5 gives
        // 25³ cells, 0.29 M entries and the fastest random-access evaluation of 0.5–0.15.)
        let gn = ((ext.max_element() / (0.5 * med)).ceil() as usize).clamp(4, 96);
        let h = ext / gn as f64;
        let lo = self.lo;
        let mut pairs: Vec<(u32, u32)> = self
            .locals
            .par_iter()
            .enumerate()
            .flat_map_iter(|(li, l)| {
                let r = l.r2.sqrt();
                let cell = |v: f64, k: usize| {
                    ((v - lo[k]) / h[k]).floor().clamp(0.0, (gn - 1) as f64) as usize
                };
                let i0 = [0, 1, 2].map(|k| cell(l.c[k] - r, k));
                let i1 = [0, 1, 2].map(|k| cell(l.c[k] + r, k));
                let mut out = Vec::new();
                for z in i0[2]..=i1[2] {
                    for y in i0[1]..=i1[1] {
                        for x in i0[0]..=i1[0] {
                            let blo = lo + h * DVec3::new(x as f64, y as f64, z as f64);
                            let bhi = blo + h;
                            let d = (blo - l.c).max(l.c - bhi).max(DVec3::ZERO);
                            if d.length_squared() < l.r2 {
                                out.push((((z * gn + y) * gn + x) as u32, li as u32));
                            }
                        }
                    }
                }
                out.into_iter()
            })
            .collect();
        pairs.par_sort_unstable();
        let n = gn * gn * gn;
        let mut start = vec![0u32; n + 1];
        for &(c, _) in &pairs {
            start[c as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        self.list = pairs.into_iter().map(|(_, l)| l).collect();
        self.start = start;
        self.gn = gn;
        self.ginv = DVec3::ONE / h;
        self.stats.grid_entries = self.list.len();
        self.stats.grid_size = gn;
    }

    /// Measures `max |∇f|` on a grid over `bounds()` and around every input point; sets
    /// `lipschitz = max(1, 1.5 · max)` and the shell minimum.
    fn measure_lipschitz(&mut self, points: &[DVec3], nrm: &[DVec3]) {
        let g = LIPSCHITZ_GRID;
        let (lo, hi) = (self.lo, self.hi);
        let step = (hi - lo) / g as f64;
        let inner_lo = lo + DVec3::splat(self.floor);
        let inner_hi = hi - DVec3::splat(self.floor);
        let this = &*self;
        let grid = (0..g * g * g)
            .into_par_iter()
            .map(|n| {
                let (i, j, k) = (n % g, (n / g) % g, n / (g * g));
                let p = lo + step * DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5);
                let (v, gr) = this
                    .eval_mpu_grad(p)
                    .unwrap_or((f64::INFINITY, DVec3::ZERO));
                let shell = p.cmplt(inner_lo).any() || p.cmpgt(inner_hi).any();
                (gr.length(), p, if shell { v } else { f64::INFINITY })
            })
            .reduce(
                || (0.0, DVec3::ZERO, f64::INFINITY),
                |a, b| {
                    let m = if b.0 > a.0 { (b.0, b.1) } else { (a.0, a.1) };
                    (m.0, m.1, a.2.min(b.2))
                },
            );
        let h = step.length();
        let near = points
            .par_iter()
            .zip(nrm)
            .enumerate()
            .map(|(idx, (&p, &n))| {
                let (t1, t2) = n.any_orthonormal_pair();
                // A deterministic per-point twist so that the samples are not all aligned.
                let tw = ((idx % 7) as f64 - 3.0) / 10.0;
                let mut best = (0.0, p);
                for s in [-1.0, -0.5, -0.25, -0.1, 0.0, 0.1, 0.25, 0.5, 1.0] {
                    for (a, b) in [(0.0, 0.0), (0.3, 0.0), (0.0, 0.3), (-0.3, -0.3)] {
                        let q = p + h * (s * n + (a + tw * b) * t1 + (b - tw * a) * t2);
                        if let Some((_, gr)) = this.eval_mpu_grad(q) {
                            if gr.length() > best.0 {
                                best = (gr.length(), q);
                            }
                        }
                    }
                }
                best
            })
            .reduce(|| (0.0, DVec3::ZERO), |a, b| if b.0 > a.0 { b } else { a });
        let (m, at) = if near.0 > grid.0 {
            near
        } else {
            (grid.0, grid.1)
        };
        self.stats.max_gradient = m;
        self.stats.max_gradient_at = at;
        self.stats.shell_min = grid.2;
        self.lipschitz = (LIPSCHITZ_SAFETY * m).max(1.0);
    }

    /// Reads a `.pts` file: one point per line, `x y z nx ny nz` separated by white space;
    /// blank lines and lines starting with `#` are skipped. Normals are normalised. Errors
    /// (with the 1-based line number) on a wrong count of numbers, a number that does not
    /// parse, a non-finite value, a coordinate beyond ±[`MAX_MAGNITUDE`], a zero normal, or a
    /// file without points. The file must be a regular file of at most
    /// [`crate::input::MAX_MESH_BYTES`].
    pub fn load_points(path: &Path) -> Result<(Vec<DVec3>, Vec<DVec3>)> {
        let text = crate::input::read_text(
            path,
            crate::input::MAX_MESH_BYTES,
            crate::input::Kind::Regular,
        )
        .map_err(|e| anyhow!("reading points from {}: {e}", path.display()))?;
        Self::parse_points(&text).with_context(|| format!("in {}", path.display()))
    }

    /// [`Mpu::load_points`] on text already read.
    pub fn parse_points(text: &str) -> Result<(Vec<DVec3>, Vec<DVec3>)> {
        let (mut pts, mut nrm) = (Vec::new(), Vec::new());
        for (ln, line) in text.lines().enumerate() {
            let ln = ln + 1;
            let t = line.trim();
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let mut v = [0.0f64; 6];
            let mut count = 0;
            for tok in t.split_whitespace() {
                if count < 6 {
                    v[count] = tok
                        .parse::<f64>()
                        .map_err(|_| anyhow!("line {ln}: cannot parse {tok:?} as a number"))?;
                    if !v[count].is_finite() {
                        bail!("line {ln}: {tok:?} is not finite");
                    }
                    if count < 3 && v[count].abs() > MAX_MAGNITUDE {
                        bail!(
                            "line {ln}: the coordinate {tok} is beyond ±{MAX_MAGNITUDE:e}, the largest a point may have (the fit's squared distances must stay finite)"
                        );
                    }
                }
                count += 1;
            }
            if count != 6 {
                bail!("line {ln}: expected 6 numbers `x y z nx ny nz`, found {count}");
            }
            let n = DVec3::new(v[3], v[4], v[5]);
            let u = n.normalize_or_zero();
            if u == DVec3::ZERO || !u.is_finite() {
                bail!(
                    "line {ln}: the normal ({}, {}, {}) has no direction",
                    v[3],
                    v[4],
                    v[5]
                );
            }
            pts.push(DVec3::new(v[0], v[1], v[2]));
            nrm.push(u);
        }
        if pts.is_empty() {
            bail!("no points (every line is blank or a # comment)");
        }
        Ok((pts, nrm))
    }

    #[inline(always)]
    fn inside(&self, p: DVec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }

    /// Distance to `bounds()` (0 inside) and its gradient.
    #[inline]
    fn box_dist(&self, p: DVec3) -> (f64, DVec3) {
        let e = (self.lo - p).max(p - self.hi).max(DVec3::ZERO);
        let d = e.length();
        if d == 0.0 {
            return (0.0, DVec3::ZERO);
        }
        let sgn = DVec3::select(p.cmplt(self.lo), DVec3::NEG_ONE, DVec3::ONE);
        (d, sgn * e / d)
    }

    /// The local fits listed for the grid cell of `p` (inside `bounds()`).
    #[inline(always)]
    fn cell_list(&self, p: DVec3) -> &[u32] {
        let q = (p - self.lo) * self.ginv;
        let m = (self.gn - 1) as f64;
        let (i, j, k) = (
            q.x.clamp(0.0, m) as usize,
            q.y.clamp(0.0, m) as usize,
            q.z.clamp(0.0, m) as usize,
        );
        let c = (k * self.gn + j) * self.gn + i;
        &self.list[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// The MPU blend: `Some(f)` when a support covers `p`.
    #[inline]
    fn eval_mpu(&self, p: DVec3) -> Option<f64> {
        let (mut sw, mut swq) = (0.0, 0.0);
        for &li in self.cell_list(p) {
            let l = &self.locals[li as usize];
            let d2 = (p - l.c).length_squared();
            if d2 < l.r2 {
                let t = d2.sqrt() * l.s;
                let w = if t < 0.5 {
                    0.75 - t * t
                } else {
                    let u = 1.5 - t;
                    0.5 * u * u
                };
                sw += w;
                swq += w * l.q(p);
            }
        }
        (sw > 0.0).then(|| swq / sw)
    }

    /// The MPU blend and its analytic gradient.
    fn eval_mpu_grad(&self, p: DVec3) -> Option<(f64, DVec3)> {
        let (mut sw, mut swq) = (0.0, 0.0);
        let (mut gw, mut gwq) = (DVec3::ZERO, DVec3::ZERO);
        for &li in self.cell_list(p) {
            let l = &self.locals[li as usize];
            let y = p - l.c;
            let d2 = y.length_squared();
            if d2 < l.r2 {
                let r = d2.sqrt();
                let (w, dw) = bspline(r * l.s);
                // ∇w = b'(t)·(1.5/R)·y/|y|
                let gradw = if r > 0.0 {
                    (dw * l.s / r) * y
                } else {
                    DVec3::ZERO
                };
                let (q, gq) = l.q_grad(p);
                sw += w;
                swq += w * q;
                gw += gradw;
                gwq += gradw * q + w * gq;
            }
        }
        (sw > 0.0).then(|| {
            let f = swq / sw;
            (f, (gwq - f * gw) / sw)
        })
    }

    /// The proved `(sup |∇f|, evaluation error)` over the box `[blo, bhi] ⊂ bounds()` (module
    /// doc, "Local Lipschitz bounds").
    fn box_bound(&self, blo: DVec3, bhi: DVec3) -> CellBound {
        // The local fits whose ball may meet the box: every evaluation cell it touches, padded
        let pad = 1e-9 * (self.hi - self.lo).max_element();
        let m = (self.gn - 1) as f64;
        let idx = |v: DVec3| ((v - self.lo) * self.ginv).clamp(DVec3::ZERO, DVec3::splat(m));
        let (i0, i1) = (idx(blo - pad), idx(bhi + pad));
        let mut cand: Vec<u32> = vec![];
        for k in i0.z as usize..=i1.z as usize {
            for j in i0.y as usize..=i1.y as usize {
                for i in i0.x as usize..=i1.x as usize {
                    let c = (k * self.gn + j) * self.gn + i;
                    cand.extend(&self.list[self.start[c] as usize..self.start[c + 1] as usize]);
                }
            }
        }
        cand.sort_unstable();
        cand.dedup();
        let (x0, r) = ((blo + bhi) * 0.5, (bhi - blo).length() * 0.5);
        // Per fit i: Q̃ᵢ(x₀), ∇Q̃ᵢ(x₀) and its rounding, Kᵢ = 3‖Hᵢ‖_F, sup |∇wᵢ|, inf wᵢ, and the
        // scale Tᵢ of the terms of Q̃ᵢ over the box
        struct Fit {
            v: f64,
            g: DVec3,
            gerr: f64,
            k: f64,
            dw: f64,
            s2: f64,
            c: DVec3,
            s: f64,
            whi: f64,
            t: f64,
        }
        let fits: Vec<Fit> = cand
            .iter()
            .filter_map(|&li| {
                let l = &self.locals[li as usize];
                // Distances from the weight centre to the box: nearest, farthest
                let near = (blo - l.c).max(l.c - bhi).max(DVec3::ZERO).length();
                if near * near >= l.r2 * (1.0 + 1e-9) {
                    return None;
                }
                let far = (blo - l.c).abs().max((bhi - l.c).abs()).length();
                let (tmin, tmax) = (near * l.s, far * l.s);
                // |b'(t)| rises as 2t to 1 at t = 1/2, then falls as 1.5 − t
                let db = if tmax < 0.5 {
                    2.0 * tmax
                } else if tmin > 0.5 {
                    (1.5 - tmin).max(0.0)
                } else {
                    1.0
                };
                let whi = bspline(tmin).0 * (1.0 + 1e-9) + 1e-15;
                let hn = l.hess_norm();
                let zmax = (blo - l.m).abs().max((bhi - l.m).abs()).length();
                let zeta = zmax.min(l.rho);
                let aabs: f64 = l.a.iter().map(|x| x.abs()).sum();
                let t = l.k.abs() + l.b.length() * zmax + aabs * zeta * zeta + hn * zeta * zmax;
                let (v, g) = l.q_grad(x0);
                Some(Fit {
                    v,
                    g,
                    // The computed gradient's rounding (~30 roundings of terms ≤ this scale)
                    gerr: 1e-12 * (l.b.length() + 3.0 * hn * zmax),
                    // Inside the sphere Q̃ = Q: ∇Q̃ is ‖H‖-Lipschitz there, 3‖H‖ elsewhere
                    k: if zmax * (1.0 + 1e-12) <= l.rho {
                        hn
                    } else {
                        3.0 * hn
                    },
                    dw: db * l.s,
                    s2: l.s * l.s,
                    c: l.c,
                    s: l.s,
                    whi,
                    t,
                })
            })
            .collect();
        // Evaluation error: n + 100 roundings of terms no larger than the largest Tᵢ, 4× over
        let tmax = fits.iter().map(|f| f.t).fold(0.0, f64::max);
        let err = 4.0 * (fits.len() as f64 + 100.0) * f64::EPSILON * 0.5 * tmax;
        // Σ wᵢ on the box: on each of its WEIGHT_SPLIT³ sub-boxes at least the sum of the
        // weights' least values there (each at the sub-box's farthest point from its centre), so
        // on the box at least the smallest such sum; and ≥ w_floor anywhere in bounds()
        let sub = (bhi - blo) / WEIGHT_SPLIT as f64;
        let edge = |i: usize, k: usize| {
            if i == WEIGHT_SPLIT {
                bhi[k]
            } else {
                blo[k] + sub[k] * i as f64
            }
        };
        // Per fit, axis and slice of the split: the squared farthest distance along that axis
        let sq: Vec<[[f64; WEIGHT_SPLIT]; 3]> = fits
            .iter()
            .map(|f| {
                [0, 1, 2].map(|k| {
                    std::array::from_fn(|i| {
                        let d = (edge(i, k) - f.c[k])
                            .abs()
                            .max((edge(i + 1, k) - f.c[k]).abs());
                        d * d
                    })
                })
            })
            .collect();
        let mut wsum = f64::INFINITY;
        for n in 0..WEIGHT_SPLIT.pow(3) {
            let c = [
                n % WEIGHT_SPLIT,
                (n / WEIGHT_SPLIT) % WEIGHT_SPLIT,
                n / WEIGHT_SPLIT.pow(2),
            ];
            let w: f64 = fits
                .iter()
                .zip(&sq)
                .map(|(f, q)| {
                    let far = (q[0][c[0]] + q[1][c[1]] + q[2][c[2]]).sqrt();
                    (bspline(far * f.s).0 * (1.0 - 1e-9) - 1e-15).max(0.0)
                })
                .sum();
            wsum = wsum.min(w);
        }
        let wsum = wsum.max(self.w_floor);
        if wsum <= 0.0 {
            return CellBound {
                lipschitz: f64::INFINITY,
                error: err,
                zero_free: false,
                curvature: f64::INFINITY,
                gradient_error: f64::INFINITY,
            };
        }
        // The shares λⱼ = wⱼ/W lie in [0, whiⱼ/W_lo] and sum to 1
        let cap: Vec<f64> = fits.iter().map(|f| (f.whi / wsum).min(1.0)).collect();
        let mut order: Vec<(f64, f64)> = Vec::with_capacity(fits.len());
        // The largest Σ λⱼ·vⱼ over such shares: fill the largest vⱼ first
        let mut mix = |vals: &mut dyn Iterator<Item = f64>| -> f64 {
            order.clear();
            order.extend(vals.zip(cap.iter().copied()));
            order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
            let (mut left, mut sum) = (1.0f64, 0.0);
            for &(v, c) in &order {
                let take = c.min(left);
                sum += take * v;
                left -= take;
                if left <= 0.0 {
                    break;
                }
            }
            // Rounding of the shares: the unfilled remainder at the smallest value is ≥ 0
            sum * (1.0 + 1e-12)
        };
        // ∇f = Σ λᵢ∇Q̃ᵢ + Σ ∇wᵢ(Q̃ᵢ − f)/W, with |Q̃ᵢ − f| = |Σⱼ λⱼ(Q̃ᵢ − Q̃ⱼ)|
        let gmax = mix(&mut fits.iter().map(|a| a.g.length() + a.gerr + a.k * r));
        let mut spread = 0.0;
        // Per fit: sup |Q̃ᵢ − f| and sup |∇Q̃ᵢ − Σ λⱼ∇Q̃ⱼ| (mixes over the shares)
        let mut dq = vec![0.0; fits.len()];
        let mut dg = vec![0.0; fits.len()];
        for (i, a) in fits.iter().enumerate() {
            if a.dw == 0.0 {
                continue;
            }
            dq[i] = mix(&mut fits.iter().map(|b| {
                (a.v - b.v).abs()
                    + 2.0 * err
                    + ((a.g - b.g).length() + a.gerr + b.gerr) * r
                    + 0.5 * (a.k + b.k) * r * r
            }));
            dg[i] = mix(&mut fits
                .iter()
                .map(|b| (a.g - b.g).length() + a.gerr + b.gerr + (a.k + b.k) * r));
            spread += a.dw * dq[i];
        }
        let lipschitz = gmax + spread / wsum;
        // W∇²f = Σ [(∇Q̃ᵢ − ∇f)⊗∇wᵢ + ∇wᵢ⊗(∇Q̃ᵢ − ∇f) + wᵢ∇²Q̃ᵢ + ∇²wᵢ(Q̃ᵢ − f)], with
        // |∇Q̃ᵢ − ∇f| ≤ dgᵢ + spread/W, ‖∇²Q̃ᵢ‖ ≤ Kᵢ, ‖∇²wᵢ‖ ≤ 2sᵢ² (module doc)
        let curv = fits
            .iter()
            .zip(dq.iter().zip(&dg))
            .map(|(a, (q, g))| 2.0 * a.dw * (g + spread / wsum) + 2.0 * a.s2 * q)
            .sum::<f64>()
            / wsum
            + mix(&mut fits.iter().map(|a| a.k));
        // The computed gradient vector's rounding: far above ~100 roundings of its terms'
        // magnitudes
        let tmag = fits.iter().map(|f| f.t).fold(0.0, f64::max);
        let gerr = 1e-10 * (gmax + fits.iter().map(|f| f.dw).sum::<f64>() * tmag / wsum);
        // f's range: a mix of the fits' ranges Q̃ⱼ(x₀) ± (|∇Q̃ⱼ(x₀)|·r + Kⱼr²/2)
        let reach = |f: &Fit| (f.g.length() + f.gerr) * r + 0.5 * f.k * r * r + err;
        let fmax = mix(&mut fits.iter().map(|f| f.v + reach(f)));
        let fmin = -mix(&mut fits.iter().map(|f| -f.v + reach(f)));
        CellBound {
            lipschitz,
            error: err,
            zero_free: fmin > err || fmax < -err,
            curvature: curv,
            gradient_error: gerr,
        }
    }

    /// An interval enclosure of `|∇f|` over the box `[lo, hi] ⊂ bounds()` by outward-rounded
    /// interval arithmetic on [`Mpu::eval_grad`]'s formula (`(Σ ∇wᵢQ̃ᵢ + wᵢ∇Q̃ᵢ − f·Σ∇wᵢ)/Σwᵢ`),
    /// independent of the local bounds' derivation: for tests. `None` when a local fit's
    /// linear-extension sphere cuts the box (the branch is not enclosed).
    pub fn gradient_enclosure(&self, lo: DVec3, hi: DVec3) -> Option<Interval<f64>> {
        type I = Interval<f64>;
        let iv = |a: DVec3, b: DVec3| [0, 1, 2].map(|k| I::new(a[k], b[k]));
        let x = iv(lo, hi);
        let zero = I::point(0.0);
        let (mut sw, mut swq) = (zero, zero);
        let (mut gw, mut gwq) = ([zero; 3], [zero; 3]);
        let mut list: Vec<u32> = vec![];
        for z in [lo.z, hi.z] {
            for y in [lo.y, hi.y] {
                for xx in [lo.x, hi.x] {
                    list.extend(self.cell_list(DVec3::new(xx, y, z)));
                }
            }
        }
        list.sort_unstable();
        list.dedup();
        for &li in &list {
            let l = &self.locals[li as usize];
            let near = (lo - l.c).max(l.c - hi).max(DVec3::ZERO).length();
            if near * near >= l.r2 {
                continue;
            }
            // Only boxes wholly inside the fit's sphere (or a plane's): Q̃ = Q there
            let far_m = (lo - l.m).abs().max((hi - l.m).abs()).length();
            if far_m > l.rho {
                return None;
            }
            let y = [0, 1, 2].map(|k| x[k] - I::point(l.c[k]));
            let zz = [0, 1, 2].map(|k| x[k] - I::point(l.m[k]));
            let r = (y[0].square() + y[1].square() + y[2].square()).sqrt();
            let t = r * I::point(l.s);
            // b and b'·s/r on each B-spline piece the range of t meets, joined
            let mut pieces = vec![];
            if t.lo < 0.5 {
                let tt = I::new(t.lo, t.hi.min(0.5));
                pieces.push((I::point(0.75) - tt.square(), I::point(-2.0 * l.s * l.s)));
            }
            if t.hi >= 0.5 {
                let tt = I::new(t.lo.max(0.5), t.hi.min(1.5));
                let u = I::point(1.5) - tt;
                let rr = I::new(r.lo.max(0.5 / l.s), r.hi);
                pieces.push((u.square() * I::point(0.5), -(u * I::point(l.s)) / rr));
            }
            let hull = |a: I, b: I| I::new(a.lo.min(b.lo), a.hi.max(b.hi));
            let (w, k) = pieces
                .into_iter()
                .reduce(|a, b| (hull(a.0, b.0), hull(a.1, b.1)))?;
            // Past the support (t ≥ 1.5) both are 0
            let (w, k) = if t.hi >= 1.5 {
                (hull(w, zero), hull(k, zero))
            } else {
                (w, k)
            };
            // Q and ∇Q = Hz + b on the box
            let a = &l.a;
            let (z0, z1, z2) = (zz[0], zz[1], zz[2]);
            let c = |v: f64| I::point(v);
            let q = z0 * (c(a[0]) * z0 + c(a[3]) * z1 + c(a[4]) * z2)
                + z1 * (c(a[1]) * z1 + c(a[5]) * z2)
                + c(a[2]) * z2.square()
                + c(l.b.x) * z0
                + c(l.b.y) * z1
                + c(l.b.z) * z2
                + c(l.k);
            let gq = [
                c(2.0 * a[0]) * z0 + c(a[3]) * z1 + c(a[4]) * z2 + c(l.b.x),
                c(2.0 * a[1]) * z1 + c(a[3]) * z0 + c(a[5]) * z2 + c(l.b.y),
                c(2.0 * a[2]) * z2 + c(a[4]) * z0 + c(a[5]) * z1 + c(l.b.z),
            ];
            sw = sw + w;
            swq = swq + w * q;
            for d in 0..3 {
                let dw = k * y[d];
                gw[d] = gw[d] + dw;
                gwq[d] = gwq[d] + dw * q + w * gq[d];
            }
        }
        let f = swq / sw;
        let g = [0, 1, 2].map(|d| (gwq[d] - f * gw[d]) / sw);
        Some((g[0].square() + g[1].square() + g[2].square()).sqrt())
    }

    /// The proved local Lipschitz bounds over `bounds()`.
    pub fn local_bounds(&self) -> &LocalBounds {
        self.local.as_ref().expect("built by fit")
    }

    /// The implicit: **positive outside**, negative inside, ≈ signed distance near the
    /// surface; outside `bounds()`, `dist(p, bounds()) + floor()` (module doc).
    #[inline]
    pub fn eval(&self, p: DVec3) -> f64 {
        if self.inside(p) {
            if let Some(v) = self.eval_mpu(p) {
                return v;
            }
        }
        self.box_dist(p).0 + self.floor
    }

    /// The analytic gradient of [`Mpu::eval`]: of the blend inside `bounds()`, of the box
    /// distance outside.
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        self.eval_grad(p).1
    }

    /// [`Mpu::eval`] and [`Mpu::gradient`] together.
    pub fn eval_grad(&self, p: DVec3) -> (f64, DVec3) {
        if self.inside(p) {
            if let Some(vg) = self.eval_mpu_grad(p) {
                return vg;
            }
        }
        let (d, g) = self.box_dist(p);
        (d + self.floor, g)
    }

    /// [`Mpu::eval`] by descending the octree instead of reading the grid (the reference;
    /// the same set of local fits, summed in another order).
    pub fn eval_tree(&self, p: DVec3) -> f64 {
        if !self.inside(p) {
            return self.box_dist(p).0 + self.floor;
        }
        let mut stack = vec![0u32];
        let (mut sw, mut swq) = (0.0, 0.0);
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if (p - node.c).length_squared() >= node.reach2 {
                continue;
            }
            if node.leaf != NONE {
                let l = &self.locals[node.leaf as usize];
                let d2 = (p - l.c).length_squared();
                if d2 < l.r2 {
                    let w = bspline(d2.sqrt() * l.s).0;
                    sw += w;
                    swq += w * l.q(p);
                }
            } else {
                stack.extend(node.child..node.child + 8);
            }
        }
        if sw > 0.0 {
            swq / sw
        } else {
            self.box_dist(p).0 + self.floor
        }
    }

    /// The cost of one [`Mpu::eval`] at `p` inside `bounds()`: (local fits listed in its grid
    /// cell, local fits whose support contains `p`).
    pub fn eval_cost(&self, p: DVec3) -> (usize, usize) {
        if !self.inside(p) {
            return (0, 0);
        }
        let list = self.cell_list(p);
        let used = list
            .iter()
            .filter(|&&li| {
                let l = &self.locals[li as usize];
                (p - l.c).length_squared() < l.r2
            })
            .count();
        (list.len(), used)
    }

    /// A box containing the zero set: the points' bounding box grown by
    /// [`BOUNDS_MARGIN`] × its diagonal on every side.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// The value of [`Mpu::eval`] on `bounds()`'s faces from outside (half the margin).
    pub fn floor(&self) -> f64 {
        self.floor
    }

    /// The global step bound of the `global` and `paper` tracers (step `f(x)/lipschitz()`).
    /// **Measured, not proved** (the proved bounds: [`Mpu::local_bounds`]): `max(1, 1.5 × max |∇f|)`, the maximum over a 64³ grid of `bounds()` and 36
    /// samples within one grid-cell diagonal of each input point (along and across the
    /// normal). The outside branch is 1-Lipschitz. Bunny, default options: 3.90 (max |∇f| =
    /// 2.60, met in the empty margin behind the ears, where a large cell's ear-tip quadric
    /// blends with the empty cells' distance planes; near the surface |∇f| ≤ 2.2).
    pub fn lipschitz(&self) -> f64 {
        self.lipschitz
    }

    /// Octree nodes (accepted local fits plus split cells).
    pub fn cells(&self) -> usize {
        self.stats.cells
    }

    /// Accepted local fits (the octree's leaves).
    pub fn leaves(&self) -> usize {
        self.stats.leaves
    }

    /// Fit statistics.
    pub fn stats(&self) -> &MpuStats {
        &self.stats
    }
}
