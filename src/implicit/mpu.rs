//! Multi-level partition of unity implicits (Ohtake, Belyaev, Alexa, Turk, Seidel 2003), the
//! surface the seed paper (Wu & Pan) renders for the Stanford bunny.
//!
//! **Fit** ([`Mpu::fit`]). An octree over a cube that contains [`Mpu::bounds`]. Each cell (centre
//! `c`, diagonal `d`) gets a support ball of radius `R = alpha·d`; while the ball holds fewer
//! than `min_points` points, `R ← R + lambda·R` (paper §3). In the ball, with the paper's
//! weights `w(x) = b(3|x−c|/(2R))` (`b` the quadratic B-spline on [−1.5, 1.5]):
//! - if every normal `n_i` in the ball has `n_i·n̄ > 0` (`n̄` the weighted mean normal): the
//!   bivariate quadratic `w = h(u, v)` in the frame `(t₁, t₂, n̄)` at `c`, by weighted least
//!   squares, giving `Q(x) = (x−c)·n̄ − h(u, v)`: positive along the normals, gradient ≈ `n̄`
//!   at the fit, so `Q` ≈ signed distance near the data;
//! - otherwise: a general quadric (10 coefficients) minimising the paper's
//!   `(1/Σw)·Σ wᵢ Q(pᵢ)² + (1/m)·Σ (Q(q_j) − d_j)²` with the auxiliary points `q_j` at the
//!   cell centre and its 8 corners, `d_j` the mean of `(q_j − p)·n_p` over the 6 nearest ball
//!   points when those all agree in sign (else `q_j` is dropped). When all 9 are dropped (a
//!   thin sheet through the cell), the offset points `pᵢ ± (R/20)·nᵢ` with `d = ±R/20` are
//!   used instead, which fixes the sign and the scale the same way.
//!
//! The paper's third local type (piecewise quadrics for sharp edges and corners) is not built:
//! a scanned bunny has none. Coordinates are centred on `c` and scaled by `1/R` for the
//! solves (a small ridge keeps them regular). The error of a fit is the largest Taubin
//! distance `|Q(p)|/|∇Q(p)|` over the ball's points. A cell whose error is above
//! `max_error · (bounding-box diagonal)` is split into 8, unless it is at `max_depth` or its
//! ball had to be grown: a grown ball means the cell is already finer than the point spacing,
//! and its children's balls would be grown to about the same `min_points` nearest points, so
//! splitting cannot lower the error (it would only multiply cells; the paper stops such cells
//! by `max_depth` alone).
//!
//! **Evaluation** ([`Mpu::eval`]). `f(x) = Σ wᵢ(x) Qᵢ(x) / Σ wᵢ(x)` over the accepted fits
//! whose support ball contains `x`, found by descending the flat node array (an accepted
//! node contributes and is not descended; each node stores the radius reaching all supports
//! below it, to prune). **f > 0 outside** (along the input normals), `f < 0` inside. The
//! root cube contains `bounds()` and the root ball (`alpha > 1/2`) covers the root cube, so
//! inside `bounds()` some support always covers `x`. Outside `bounds()` (or, with
//! `alpha ≤ 1/2`, where no support covers `x`), `f(x) = dist(x, bounds()) + floor`, with
//! `floor = margin/2`: if the zero set lies in `bounds()` shrunk by `floor`, then
//! `dist(x, Z) ≥ dist(x, bounds()) + floor` for every `x` outside (for a box `B` shrunk by
//! `δ`, `dist(x, B_δ) ≥ dist(x, B) + δ`), so this branch never over-states the distance and
//! is 1-Lipschitz. [`MpuStats::shell_min`] records the smallest MPU value seen in that shell
//! at fit time (positive for the bunny and the sphere), which is the measured support for
//! that premise.
//!
//! **Lipschitz bound** ([`Mpu::lipschitz`]). MPU has no analytic bound; it is *measured*:
//! the largest `|∇f|` over a 64³ grid of `bounds()` plus samples on and around every input
//! point, times 1.5, and at least 1 (the outside branch is 1-Lipschitz). It is not a proof.
//! For the bunny (defaults) see [`MpuStats`] and `tests/mpu.rs`.
//!
//! **Ghost surfaces.** Local quadrics extrapolated into empty space can have zero sets away
//! from the data; `tests/mpu.rs` measures them against the mesh's inside/outside
//! (generalised winding number) on a grid.

use anyhow::{anyhow, bail, Context, Result};
use glam::DVec3;
use rayon::prelude::*;
use std::path::Path;

/// Fit parameters. Paper defaults except `max_error`, which is ours (see its doc).
#[derive(Clone, Debug, PartialEq)]
pub struct MpuOptions {
    /// ε₀: a cell is split while its fit's largest Taubin distance exceeds
    /// `max_error × (diagonal of the points' bounding box)`. Default 0.002: for the bunny
    /// (diagonal 15.76) that is 0.032, about 1/12 of the mean vertex spacing.
    pub max_error: f64,
    /// Support radius = `alpha × cell diagonal` (paper: 0.75). Must be > 1/2 for the root ball
    /// to cover the whole root cube.
    pub alpha: f64,
    /// N_min: the support grows until it holds this many points (paper: 15).
    pub min_points: usize,
    /// Deepest octree level (root = 0). At most 30.
    pub max_depth: u32,
    /// Support growth step: `R ← R + lambda·R` (paper: 0.1).
    pub lambda: f64,
}

impl Default for MpuOptions {
    fn default() -> Self {
        MpuOptions {
            max_error: 0.002,
            alpha: 0.75,
            min_points: 15,
            max_depth: 12,
            lambda: 0.1,
        }
    }
}

/// Statistics of a fit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MpuStats {
    /// Octree nodes (accepted fits plus split cells).
    pub cells: usize,
    /// Accepted local fits (the leaves).
    pub leaves: usize,
    /// Leaves fitted by the bivariate quadratic.
    pub bivariate: usize,
    /// Leaves fitted by a general quadric with the cell's auxiliary points.
    pub general: usize,
    /// Leaves fitted by a general quadric with the normal-offset fallback.
    pub general_offsets: usize,
    /// Leaves for cells whose support ball holds no point (a cone `±(D − |x − c|)`).
    pub empty: usize,
    /// Empty leaves whose nearest points disagreed on the side (the weighted vote decided).
    pub empty_split_vote: usize,
    /// Leaves accepted above `max_error` because their ball was grown.
    pub grown_over_error: usize,
    /// Leaves accepted above `max_error` because they are at `max_depth`.
    pub depth_over_error: usize,
    /// Deepest level reached.
    pub depth: u32,
    /// Largest fit error (Taubin distance, world units) over the leaves.
    pub max_leaf_error: f64,
    /// Largest measured `|∇f|` (before the safety factor) and where it was.
    pub max_gradient: f64,
    pub max_gradient_at: DVec3,
    /// Smallest MPU value seen on the grid points in the shell between `bounds()` shrunk by
    /// `floor` and `bounds()` (should be > 0; see the module doc).
    pub shell_min: f64,
}

/// Safety factor on the measured gradient maximum.
pub const LIPSCHITZ_SAFETY: f64 = 1.5;
/// Grid resolution per axis of the Lipschitz measurement.
pub const LIPSCHITZ_GRID: usize = 64;
/// `bounds()` = the points' bounding box grown by this fraction of its diagonal per side.
pub const BOUNDS_MARGIN: f64 = 0.05;

const NO_CHILD: u32 = 0;
const STACK: usize = 256;

/// One octree node; accepted nodes carry their quadric in `y = x − c`:
/// `Q = a·(y0², y1², y2², y0y1, y0y2, y1y2) + b·y + k`.
#[derive(Clone, Debug)]
struct Node {
    c: DVec3,
    /// Support radius (accepted nodes) squared.
    r2: f64,
    /// 1.5 / R, for the weight's argument.
    s: f64,
    /// Squared radius around `c` containing every support below (and including) this node.
    reach2: f64,
    /// Index of the first of 8 children, or `NO_CHILD` for an accepted node.
    child: u32,
    a: [f64; 6],
    b: DVec3,
    k: f64,
    /// Coefficient of `|y|` (non-zero only for empty cells: `Q = s·(D − |y|)`).
    cone: f64,
}

/// A fitted MPU implicit. See the module doc.
#[derive(Clone, Debug)]
pub struct Mpu {
    nodes: Vec<Node>,
    lo: DVec3,
    hi: DVec3,
    floor: f64,
    lipschitz: f64,
    stats: MpuStats,
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
        let h = (ext.x * ext.y * ext.z / target).cbrt().max(ext.max_element() / 128.0);
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
    if !(tr > 0.0) || !tr.is_finite() {
        return None;
    }
    for ridge in [1e-12, 1e-9, 1e-6] {
        let mut l = *m;
        for (i, row) in l.iter_mut().enumerate() {
            row[i] += ridge * tr / N as f64;
        }
        let mut ok = true;
        'outer: for j in 0..N {
            let mut d = l[j][j];
            for k in 0..j {
                d -= l[j][k] * l[j][k];
            }
            if !(d > 0.0) {
                ok = false;
                break 'outer;
            }
            let d = d.sqrt();
            l[j][j] = d;
            for i in j + 1..N {
                let mut s = l[i][j];
                for k in 0..j {
                    s -= l[i][k] * l[j][k];
                }
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

/// A quadric in `y = x − c` (see [`Node`]).
#[derive(Clone, Copy, Debug, Default)]
struct Quadric {
    a: [f64; 6],
    b: DVec3,
    k: f64,
    cone: f64,
}

impl Quadric {
    #[inline(always)]
    fn value(&self, y: DVec3) -> f64 {
        let a = &self.a;
        y.x * (a[0] * y.x + a[3] * y.y + a[4] * y.z)
            + y.y * (a[1] * y.y + a[5] * y.z)
            + a[2] * y.z * y.z
            + self.b.dot(y)
            + self.k
            + self.cone * y.length()
    }
    #[inline(always)]
    fn grad(&self, y: DVec3) -> DVec3 {
        let a = &self.a;
        let r = y.length();
        let cone = if r > 0.0 { (self.cone / r) * y } else { DVec3::ZERO };
        DVec3::new(
            2.0 * a[0] * y.x + a[3] * y.y + a[4] * y.z,
            2.0 * a[1] * y.y + a[3] * y.x + a[5] * y.z,
            2.0 * a[2] * y.z + a[4] * y.x + a[5] * y.y,
        ) + self.b
            + cone
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
    nball: usize,
    r: f64,
    q: Quadric,
    err: f64,
    grown: bool,
    kind: Kind,
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
            s[i][j] = -(th[0] * t1[i] * t1[j] + th[1] * (t1[i] * t2[j] + t2[i] * t1[j])
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
        cone: 0.0,
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
        cone: 0.0,
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

/// Points that decide an empty cell's side.
const EMPTY_NEAREST: usize = 6;

/// A cell whose support ball holds no point: `Q = s·(D − |x − c|)`, `D` the distance from `c`
/// to the nearest point, `s` the side (+1 outside) voted by the nearest points' normals
/// (`Σ cos∠(c − p, n_p)/|c − p|` over the [`EMPTY_NEAREST`] nearest). `D − |x − c|` is a lower
/// bound of the distance from `x` to the data, ≥ 0 in the ball.
fn empty_cell(
    grid: &PointGrid,
    nrm: &[DVec3],
    c: DVec3,
    r: f64,
    opts: &MpuOptions,
    ball: &mut Vec<u32>,
) -> CellFit {
    let pts = grid.pts;
    let k = EMPTY_NEAREST.min(pts.len());
    let mut rr = r;
    while ball.len() < k {
        rr += opts.lambda.max(0.1) * rr;
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
    CellFit {
        nball: 0,
        r,
        q: if std::env::var("MPU_PLANE").is_ok() {
            let g = (c - pts[near[0].1 as usize]) / near[0].0;
            Quadric { a: [0.0; 6], b: sign * g, k: sign * near[0].0, cone: 0.0 }
        } else {
            Quadric {
                a: [0.0; 6],
                b: DVec3::ZERO,
                k: sign * near[0].0,
                cone: -sign,
            }
        },
        err: 0.0,
        grown: false,
        kind: if split { Kind::EmptySplitVote } else { Kind::Empty },
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
        return empty_cell(grid, nrm, c, r, opts, ball);
    }
    let grown = ball.len() < need;
    let nball = ball.len();
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
    // Last resort (degenerate input, e.g. all points coincide): the plane through the ball's
    // weighted centroid with the mean normal, or a sphere-like distance to it.
    let (q, kind) = fit.unwrap_or_else(|| {
        let sw: f64 = w.iter().sum::<f64>().max(f64::MIN_POSITIVE);
        let centroid: DVec3 = ball
            .iter()
            .zip(&w)
            .map(|(&i, &wi)| wi * (pts[i as usize] - c))
            .sum::<DVec3>()
            / sw;
        let n = if nbar == DVec3::ZERO { DVec3::X } else { nbar };
        (
            Quadric {
                a: [0.0; 6],
                b: n,
                k: -n.dot(centroid),
                cone: 0.0,
            },
            Kind::GeneralOffsets,
        )
    });
    let err = ball
        .iter()
        .map(|&i| {
            let y = pts[i as usize] - c;
            let g = q.grad(y).length();
            let v = q.value(y).abs();
            if v == 0.0 {
                0.0
            } else {
                v / g
            }
        })
        .fold(0.0, |a: f64, b| if b.is_nan() { f64::INFINITY } else { a.max(b) });
    CellFit {
        nball,
        r,
        q,
        err,
        grown,
        kind,
    }
}

impl Mpu {
    /// Fits the MPU implicit to oriented points (normals point outward; they are normalised
    /// here). Deterministic (the octree is built level by level; each level's cells are
    /// fitted in parallel and stored in order).
    ///
    /// # Panics
    /// If `points` is empty, the slices' lengths differ, a coordinate is not finite, a normal
    /// is zero, or an option is out of range (`alpha`, `lambda`, `max_error` must be positive,
    /// `max_depth ≤ 30`).
    pub fn fit(points: &[DVec3], normals: &[DVec3], opts: &MpuOptions) -> Mpu {
        assert!(!points.is_empty(), "Mpu::fit: no points");
        assert_eq!(points.len(), normals.len(), "Mpu::fit: points and normals differ in length");
        assert!(
            opts.alpha > 0.0 && opts.lambda > 0.0 && opts.max_error > 0.0 && opts.max_depth <= 30,
            "Mpu::fit: options out of range: {opts:?}"
        );
        assert!(points.iter().all(|p| p.is_finite()), "Mpu::fit: non-finite point");
        let nrm: Vec<DVec3> = normals
            .iter()
            .map(|n| {
                let u = n.normalize_or_zero();
                assert!(u != DVec3::ZERO && u.is_finite(), "Mpu::fit: zero or non-finite normal");
                u
            })
            .collect();
        let (plo, phi) = points
            .iter()
            .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        let diag = (phi - plo).length();
        // A single point (or all coincident) still gets a box of positive size.
        let margin = (BOUNDS_MARGIN * diag).max(1e-3 * (1.0 + plo.abs().max_element()));
        let (lo, hi) = (plo - DVec3::splat(margin), phi + DVec3::splat(margin));
        let tol = opts.max_error * diag.max(margin);
        let grid = PointGrid::new(points, plo, phi);
        let split_min: usize = std::env::var("MPU_SPLIT_MIN").ok().and_then(|v| v.parse().ok()).unwrap_or(0);

        let centre = 0.5 * (lo + hi);
        let half0 = 0.5 * (hi - lo).max_element();
        let mut nodes: Vec<Node> = Vec::new();
        let mut halves: Vec<f64> = Vec::new();
        let mut depths: Vec<u32> = Vec::new();
        let mut stats = MpuStats::default();
        nodes.push(Node {
            c: centre,
            r2: 0.0,
            s: 0.0,
            reach2: 0.0,
            child: NO_CHILD,
            a: [0.0; 6],
            b: DVec3::ZERO,
            k: 0.0,
            cone: 0.0,
        });
        halves.push(half0);
        depths.push(0);
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
                let node = &mut nodes[i];
                node.r2 = f.r * f.r;
                node.s = 1.5 / f.r;
                let accept = f.err <= tol || depth >= opts.max_depth || f.grown || f.nball < split_min;
                if accept {
                    node.a = f.q.a;
                    node.b = f.q.b;
                    node.k = f.q.k;
                    node.cone = f.q.cone;
                    stats.leaves += 1;
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
                    if f.err > tol {
                        if f.grown {
                            stats.grown_over_error += 1;
                        } else {
                            stats.depth_over_error += 1;
                        }
                    }
                    stats.max_leaf_error = stats.max_leaf_error.max(f.err);
                } else {
                    let first = nodes.len();
                    nodes[i].child = first as u32;
                    let (c, h) = (nodes[i].c, 0.5 * halves[i]);
                    for s in 0..8 {
                        let sg = |b: i32| if s & b != 0 { h } else { -h };
                        nodes.push(Node {
                            c: c + DVec3::new(sg(1), sg(2), sg(4)),
                            r2: 0.0,
                            s: 0.0,
                            reach2: 0.0,
                            child: NO_CHILD,
                            a: [0.0; 6],
                            b: DVec3::ZERO,
                            k: 0.0,
                            cone: 0.0,
                        });
                        halves.push(h);
                        depths.push(depth + 1);
                        next.push(first + s as usize);
                    }
                }
            }
            level = next;
        }
        // Reach radii, children before parents (children always have larger indices).
        for i in (0..nodes.len()).rev() {
            let reach = if nodes[i].child == NO_CHILD {
                nodes[i].r2.sqrt()
            } else {
                let f = nodes[i].child as usize;
                (f..f + 8)
                    .map(|j| (nodes[j].c - nodes[i].c).length() + nodes[j].reach2.sqrt())
                    .fold(0.0, f64::max)
            };
            // Round up a little so that the pruning test never drops a contributing support.
            nodes[i].reach2 = (reach * (1.0 + 1e-12)).powi(2);
        }
        stats.cells = nodes.len();
        let mut mpu = Mpu {
            nodes,
            lo,
            hi,
            floor: 0.5 * margin,
            lipschitz: 1.0,
            stats,
        };
        mpu.measure_lipschitz(points, &nrm);
        mpu
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
                let (v, gr) = this.eval_mpu_grad(p).unwrap_or((f64::INFINITY, DVec3::ZERO));
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
                let mut best = (0.0, p);
                for s in [-1.0, -0.5, -0.25, -0.1, 0.0, 0.1, 0.25, 0.5, 1.0] {
                    for (a, b) in [(0.0, 0.0), (0.3, 0.0), (0.0, 0.3), (-0.3, -0.3)] {
                        // A deterministic per-point twist so the samples are not all aligned.
                        let tw = ((idx % 7) as f64 - 3.0) / 10.0;
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
        let (m, at) = if near.0 > grid.0 { near } else { (grid.0, grid.1) };
        self.stats.max_gradient = m;
        self.stats.max_gradient_at = at;
        self.stats.shell_min = grid.2;
        self.lipschitz = (LIPSCHITZ_SAFETY * m).max(1.0);
    }

    /// Reads a `.pts` file: one point per line, `x y z nx ny nz` separated by white space;
    /// blank lines and lines starting with `#` are skipped. Normals are normalised. Errors
    /// (with the 1-based line number) on a wrong count of numbers, a number that does not
    /// parse, a non-finite value, a zero normal, or a file without points.
    pub fn load_points(path: &Path) -> Result<(Vec<DVec3>, Vec<DVec3>)> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading points from {}", path.display()))?;
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
                    v[count] = tok.parse::<f64>().map_err(|_| {
                        anyhow!("line {ln}: cannot parse {tok:?} as a number")
                    })?;
                    if !v[count].is_finite() {
                        bail!("line {ln}: {tok:?} is not finite");
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
                bail!("line {ln}: the normal ({}, {}, {}) has no direction", v[3], v[4], v[5]);
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

    /// Distance to the box (0 inside) and its gradient.
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

    /// The MPU blend: `Some(f)` when a support covers `p`.
    #[inline]
    fn eval_mpu(&self, p: DVec3) -> Option<f64> {
        let nodes = &self.nodes[..];
        let mut stack = [0u32; STACK];
        let mut sp = 1usize;
        let (mut sw, mut swq) = (0.0, 0.0);
        while sp > 0 {
            sp -= 1;
            let node = &nodes[stack[sp] as usize];
            let y = p - node.c;
            let d2 = y.length_squared();
            if d2 >= node.reach2 {
                continue;
            }
            if node.child == NO_CHILD {
                if d2 < node.r2 {
                    let r = d2.sqrt();
                    let t = r * node.s;
                    let w = if t < 0.5 {
                        0.75 - t * t
                    } else {
                        let u = 1.5 - t;
                        0.5 * u * u
                    };
                    let a = &node.a;
                    let q = y.x * (a[0] * y.x + a[3] * y.y + a[4] * y.z)
                        + y.y * (a[1] * y.y + a[5] * y.z)
                        + a[2] * y.z * y.z
                        + node.b.dot(y)
                        + node.k
                        + node.cone * r;
                    sw += w;
                    swq += w * q;
                }
            } else {
                let c = node.child;
                for j in 0..8 {
                    stack[sp + j] = c + j as u32;
                }
                sp += 8;
            }
        }
        if sw > 0.0 {
            Some(swq / sw)
        } else {
            None
        }
    }

    /// The MPU blend and its analytic gradient.
    fn eval_mpu_grad(&self, p: DVec3) -> Option<(f64, DVec3)> {
        let nodes = &self.nodes[..];
        let mut stack = [0u32; STACK];
        let mut sp = 1usize;
        let (mut sw, mut swq) = (0.0, 0.0);
        let (mut gw, mut gwq) = (DVec3::ZERO, DVec3::ZERO);
        while sp > 0 {
            sp -= 1;
            let node = &nodes[stack[sp] as usize];
            let y = p - node.c;
            let d2 = y.length_squared();
            if d2 >= node.reach2 {
                continue;
            }
            if node.child == NO_CHILD {
                if d2 < node.r2 {
                    let r = d2.sqrt();
                    let (w, dw) = bspline(r * node.s);
                    // ∇w = b'(t)·(1.5/R)·y/|y|
                    let gradw = if r > 0.0 { (dw * node.s / r) * y } else { DVec3::ZERO };
                    let q = Quadric {
                        a: node.a,
                        b: node.b,
                        k: node.k,
                        cone: node.cone,
                    };
                    let qv = q.value(y);
                    sw += w;
                    swq += w * qv;
                    gw += gradw;
                    gwq += gradw * qv + w * q.grad(y);
                }
            } else {
                let c = node.child;
                for j in 0..8 {
                    stack[sp + j] = c + j as u32;
                }
                sp += 8;
            }
        }
        if sw > 0.0 {
            let f = swq / sw;
            Some((f, (gwq - f * gw) / sw))
        } else {
            None
        }
    }

    /// The implicit: **positive outside**, negative inside, ≈ signed distance near the
    /// surface. Outside `bounds()`: `dist(p, bounds()) + floor` (see the module doc).
    #[inline]
    pub fn eval(&self, p: DVec3) -> f64 {
        if self.inside(p) {
            if let Some(v) = self.eval_mpu(p) {
                return v;
            }
        }
        self.box_dist(p).0 + self.floor
    }

    /// The analytic gradient of [`Mpu::eval`] (of the blend inside `bounds()`, of the box
    /// distance outside; zero on the box's faces' inner side where no support covers `p`).
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        self.eval_grad(p).1
    }

    /// [`Mpu::eval`] and [`Mpu::gradient`] in one descent.
    pub fn eval_grad(&self, p: DVec3) -> (f64, DVec3) {
        if self.inside(p) {
            if let Some(vg) = self.eval_mpu_grad(p) {
                return vg;
            }
        }
        let (d, g) = self.box_dist(p);
        (d + self.floor, g)
    }

    /// A box containing the zero set: the points' bounding box grown by
    /// [`BOUNDS_MARGIN`]·diagonal on every side.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// The value outside `bounds()` at the box itself (half the margin).
    pub fn floor(&self) -> f64 {
        self.floor
    }

    /// Step bound for sphere tracing: step `f(x)/lipschitz()`. **Measured, not proved**:
    /// `max(1, 1.5 × max|∇f|)` with the maximum over a 64³ grid of `bounds()` and 36 samples
    /// around each input point (within one grid-cell diagonal, along and across the normal).
    /// Bunny with the default options: see `tests/mpu.rs` (about 2.6 when this was written).
    pub fn lipschitz(&self) -> f64 {
        self.lipschitz
    }

    /// Octree nodes (accepted fits plus split cells).
    pub fn cells(&self) -> usize {
        self.stats.cells
    }

    /// Accepted local fits.
    pub fn leaves(&self) -> usize {
        self.stats.leaves
    }

    /// Fit statistics.
    pub fn stats(&self) -> &MpuStats {
        &self.stats
    }

    #[doc(hidden)]
    pub fn debug_contrib(&self, p: DVec3) -> Vec<String> {
        let mut out = vec![];
        for node in &self.nodes {
            let y = p - node.c;
            if node.child == NO_CHILD && y.length_squared() < node.r2 {
                let q = Quadric { a: node.a, b: node.b, k: node.k, cone: node.cone };
                let (w, _) = bspline(y.length() * node.s);
                out.push(format!("c {:.2?} R {:.2} w {:.3} Q {:.3} |gQ| {:.3} cone {} |a| {:.3} |b| {:.3}", node.c, node.r2.sqrt(), w, q.value(y), q.grad(y).length(), node.cone, node.a.iter().map(|v| v.abs()).sum::<f64>(), node.b.length()));
            }
        }
        out
    }

    /// The cost of one [`Mpu::eval`] at `p` inside `bounds()`: (nodes visited, local fits that
    /// contribute).
    pub fn eval_cost(&self, p: DVec3) -> (usize, usize) {
        let mut stack = vec![0u32];
        let (mut visited, mut used) = (0, 0);
        while let Some(i) = stack.pop() {
            visited += 1;
            let node = &self.nodes[i as usize];
            let d2 = (p - node.c).length_squared();
            if d2 >= node.reach2 {
                continue;
            }
            if node.child == NO_CHILD {
                used += usize::from(d2 < node.r2);
            } else {
                stack.extend(node.child..node.child + 8);
            }
        }
        (visited, used)
    }
}
