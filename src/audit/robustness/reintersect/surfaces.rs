//! The surfaces of the reintersection test: how each places an instance, runs a method, asks its
//! exact oracle, and gives the renderer's hit point with its error bound.
//!
//! **Error bounds `err`** (per component, what each method can justify):
//! - box, no reprojection: `p = o + t·d` with `|pᵢ − p*ᵢ| ≤ γₖ(|oᵢ| + |t·dᵢ|)`; `k` counts the
//!   roundings of `t` and of `p`: `faces` `t = (b − o)/d` (2) + 2 → `k = 4`; `slab`
//!   `(b − o)·(1/d)` (3) + 2 → `k = 5`; `robust_slab` exit padded by `1 + 2γ₃` (≤ 6 more) + 3 + 2
//!   → `k = 11`. The normal is the face nearest `p` (relative to the size of its terms).
//! - sphere, ellipsoid, cylinder: the hit is reprojected onto the surface as pbrt does
//!   (`p ← p·r/ρ` in the stretched frame, `ρ = |S p|`; the sphere about its centre), so `err`
//!   comes from the reprojection alone and is the same for every method: pbrt's `γ₅|p|` for the
//!   sphere (plus `γ₁|p|` for adding the centre back), `γ₇|p|` for the ellipsoid (two more
//!   roundings for `m·y`, `n·z`), `γ₅|(x, y)|` for the cylinder's lateral surface (its `z` error
//!   does not matter: the normal has no `z`).
//! - torus: the robust method's own point (Newton on the signed distance leaves `|sdf(p)|` at
//!   the rounding level of `√(x² + y²)`, which mixes components), bound `γ(K)·(r1 + r2)` in every
//!   component with `K` = [`ERR_GAMMA`] measured in `tests/torus.rs`; the chapter's methods
//!   (`o + t·d` fused) cannot justify any bound and are given the same one.
//! - triangle: `chapter` evaluates `o + t·d`, bound `γ(2)·(|o| + |t·d|)` (its `t` has none);
//!   the others reproject from their barycentrics, `p = Σ bᵢpᵢ`, pbrt's `γ(7)·Σ|bᵢpᵢ|`.
//!
//! The harness adds `γ₂(|p| + |c|)` for a world translation `c`.

use super::{point, Instance};
use crate::audit::robustness::offset::ReintersectRow;
use crate::numerics::exact::q;
use crate::numerics::exact::round_q;
use crate::numerics::real::gamma;
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::oracle::sample::{self, add, lu, mul, rp, rpv, sub};
use crate::shapes::oracle::sturm;
use crate::shapes::shape::Shape;
use crate::shapes::sphere::methods::{PickPrecision, METHODS as SPHERE_METHODS};
use crate::shapes::sphere::oracle::{self as sphere_oracle, Case};
use crate::shapes::torus::methods::{torus_normal, torus_robust_hit, ERR_GAMMA};
use crate::shapes::torus::oracle::{positive_roots, quartic_q, ExactCase};
use crate::shapes::{aabb, quadric, torus, triangle};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// The surfaces, in table order (`hinge`: two triangles sharing an edge, hit next to it).
pub const NAMES: [&str; 7] = [
    "box",
    "ellipsoid",
    "cylinder",
    "sphere",
    "torus",
    "triangle",
    "hinge",
];

/// A surface under the reintersection test.
pub(crate) trait Surface: Sync {
    fn name(&self) -> &'static str;
    /// `(name, robust)` of every method.
    fn methods(&self) -> Vec<(&'static str, bool)>;
    /// An instance of size `s` around the world point `at`.
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, at: [f64; 3], prec: Precision) -> Instance;
    /// Method `m` on a case `o, d, params` (object space).
    fn run<F: PickPrecision>(&self, m: usize, input: &[F]) -> Option<F>;
    /// The exact first root `t > 0` of an `f64` case, rounded to `f64` (`None`: a miss).
    fn exact(&self, input: &[f64]) -> Option<f64>;
    /// Method `m`'s hit at `t` as the renderer's point, its error bound and the unit normal.
    fn surface<F: PickPrecision>(&self, m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]);
    /// The largest normal curvature of the instance with these parameters (0: flat parts).
    fn curvature(&self, _params: &[f64]) -> f64 {
        0.0
    }
    /// Whether method `m` hits another part of the surface on the spawned ray (`f64` values)
    /// than on the primary one (surfaces made of several parts only).
    fn other_part<F: PickPrecision>(&self, _m: usize, _primary: &[F], _spawned: &[f64]) -> bool {
        false
    }
}

/// The rows of the surface called `name`.
pub(super) fn rows_of(name: &str, seed: u64, n: u64, prec: Precision) -> Vec<ReintersectRow> {
    match name {
        "box" => super::rows(&BoxR, seed, n, prec),
        "ellipsoid" => super::rows(&QuadR { cylinder: false }, seed, n, prec),
        "cylinder" => super::rows(&QuadR { cylinder: true }, seed, n, prec),
        "sphere" => super::rows(&SphereR, seed, n, prec),
        "torus" => super::rows(&TorusR, seed, n, prec),
        "triangle" => super::rows(&TriR { hinge: false }, seed, n, prec),
        "hinge" => super::rows(&TriR { hinge: true }, seed, n, prec),
        _ => vec![],
    }
}

fn v3<F: Copy>(v: &[F], k: usize) -> [F; 3] {
    [v[k], v[k + 1], v[k + 2]]
}

/// A routine's method as `Option<t>`.
fn shape_run<F: Real>(shape: &dyn Shape, m: usize, input: &[F]) -> Option<F> {
    let a = shape.run(m, &super::to_f64(input), Precision::of::<F>());
    (a.count > 0).then(|| F::from_f64(a.values[0]))
}

fn shape_methods(shape: &dyn Shape) -> Vec<(&'static str, bool)> {
    shape
        .info()
        .methods
        .iter()
        .map(|m| (m.name, m.robust))
        .collect()
}

fn unit_f<F: Real>(g: [F; 3]) -> [F; 3] {
    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    g.map(|x| x / len)
}

fn max_r<F: Real>(a: F, b: F) -> F {
    if b > a {
        b
    } else {
        a
    }
}

struct BoxR;

impl Surface for BoxR {
    fn name(&self) -> &'static str {
        "box"
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        shape_methods(&aabb::BoxShape)
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, at: [f64; 3], prec: Precision) -> Instance {
        let e: [f64; 3] = std::array::from_fn(|_| s * lu(rng, -1.0, 0.0));
        let (lo, hi) = (rpv(prec, sub(at, e)), rpv(prec, add(at, e)));
        let aim = std::array::from_fn(|i| lo[i] + (hi[i] - lo[i]) * rng.random_range(0.1..0.9));
        Instance {
            params: [lo, hi].concat(),
            c: [0.0; 3],
            aim,
            ext: sample::norm(sub(hi, lo)),
        }
    }
    fn run<F: PickPrecision>(&self, m: usize, input: &[F]) -> Option<F> {
        shape_run(&aabb::BoxShape, m, input)
    }
    fn exact(&self, input: &[f64]) -> Option<f64> {
        aabb::first_crossing_f64(input)
    }
    fn surface<F: PickPrecision>(&self, m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]) {
        let (o, d, lo, hi) = (v3(input, 0), v3(input, 3), v3(input, 6), v3(input, 9));
        let p = point(o, d, t);
        // The face nearest p, relative to the size of the terms that formed it
        let mut best = (F::INFINITY, 0, F::ONE);
        for i in 0..3 {
            let size = o[i].abs() + (t * d[i]).abs() + max_r(hi[i].abs(), lo[i].abs());
            for (b, sgn) in [(lo[i], -F::ONE), (hi[i], F::ONE)] {
                let dist = (p[i] - b).abs() / size;
                if dist < best.0 {
                    best = (dist, i, sgn);
                }
            }
        }
        let mut n = [F::ZERO; 3];
        n[best.1] = best.2;
        let g = gamma::<F>([4, 5, 11][m]);
        let err = std::array::from_fn(|i| g * (o[i].abs() + (t * d[i]).abs()));
        (p, err, n)
    }
}

/// The ellipsoid or the cylinder (at the object-space origin, moved by a world translation).
struct QuadR {
    cylinder: bool,
}

impl QuadR {
    fn shape(&self) -> &'static dyn Shape {
        if self.cylinder {
            &quadric::CYLINDER
        } else {
            &quadric::ELLIPSOID
        }
    }
}

impl Surface for QuadR {
    fn name(&self) -> &'static str {
        self.shape().name()
    }
    fn curvature(&self, params: &[f64]) -> f64 {
        // Semi-axes r, r/m (and r/n): an ellipse's curvature peaks at a_max / a_min²
        let axes = if self.cylinder {
            vec![params[0], params[0] / params[1]]
        } else {
            vec![params[0], params[0] / params[1], params[0] / params[2]]
        };
        let (lo, hi) = axes
            .iter()
            .fold((f64::INFINITY, 0f64), |(l, h), &a| (l.min(a), h.max(a)));
        hi / (lo * lo)
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        shape_methods(self.shape())
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, at: [f64; 3], prec: Precision) -> Instance {
        let (m, third) = (lu(rng, -0.3, 0.3), lu(rng, -0.3, 0.3));
        let ext = s * m.recip().max(third.recip()).max(1.0);
        let c = rpv(prec, at);
        let u = mul(sample::ball(rng), 0.8);
        let (params, local) = if self.cylinder {
            let h = s * lu(rng, -0.3, 0.6);
            let local = [s * u[0], s / m * u[1], h * (0.5 + 0.5 * u[2])];
            (vec![s, m, h], local)
        } else {
            (
                vec![s, m, third],
                [s * u[0], s / m * u[1], s / third * u[2]],
            )
        };
        Instance {
            params: params.into_iter().map(|x| rp(prec, x)).collect(),
            c,
            aim: add(c, local),
            ext: ext.max(if self.cylinder { s } else { 0.0 }),
        }
    }
    fn run<F: PickPrecision>(&self, m: usize, input: &[F]) -> Option<F> {
        shape_run(self.shape(), m, input)
    }
    fn exact(&self, input: &[f64]) -> Option<f64> {
        let shape = if self.cylinder {
            &quadric::CYLINDER
        } else {
            &quadric::ELLIPSOID
        };
        shape.first_hit_f64(input)
    }
    fn surface<F: PickPrecision>(&self, _m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]) {
        let (o, d) = (v3(input, 0), v3(input, 3));
        let (r, m, third) = (input[6], input[7], input[8]);
        let p = point(o, d, t);
        // Reproject radially in the stretched frame
        let s = [F::ONE, m, if self.cylinder { F::ZERO } else { third }];
        let sp: [F; 3] = std::array::from_fn(|i| s[i] * p[i]);
        let rho = (sp[0] * sp[0] + sp[1] * sp[1] + sp[2] * sp[2]).sqrt();
        let k = r / rho;
        let mut q = p.map(|x| x * k);
        if self.cylinder {
            q[2] = p[2];
        }
        let n = unit_f(std::array::from_fn(|i| s[i] * s[i] * q[i]));
        let g = gamma::<F>(if self.cylinder { 5 } else { 7 });
        let err = std::array::from_fn(|i| {
            if self.cylinder && i == 2 {
                F::ZERO
            } else {
                g * q[i].abs()
            }
        });
        (q, err, n)
    }
}

/// The sphere of `src/shapes/sphere`, every method of its `METHODS` table; hits reprojected onto
/// the sphere by this test (none of the methods does it itself).
pub(super) struct SphereR;

fn sphere_case<F: Copy>(v: &[F]) -> Case<F> {
    Case {
        o: v3(v, 0),
        d: v3(v, 3),
        c: v3(v, 6),
        r: v[9],
    }
}

impl Surface for SphereR {
    fn name(&self) -> &'static str {
        "sphere"
    }
    fn curvature(&self, params: &[f64]) -> f64 {
        1.0 / params[3]
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        SPHERE_METHODS.iter().map(|m| (m.name, m.robust)).collect()
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, at: [f64; 3], prec: Precision) -> Instance {
        let c = rpv(prec, at);
        let r = rp(prec, s);
        Instance {
            params: vec![c[0], c[1], c[2], r],
            c: [0.0; 3],
            aim: add(c, mul(sample::ball(rng), 0.8 * r)),
            ext: r,
        }
    }
    fn run<F: PickPrecision>(&self, m: usize, input: &[F]) -> Option<F> {
        let case = sphere_case(input);
        F::pick(&SPHERE_METHODS[m])(&case.ray(), &case.sphere()).map(|h| h.t)
    }
    fn exact(&self, input: &[f64]) -> Option<f64> {
        let truth = sphere_oracle::truth(&sphere_case(input));
        if truth.verdict.is_hit() {
            truth.t_in::<f64>()
        } else {
            None
        }
    }
    fn surface<F: PickPrecision>(&self, _m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]) {
        let (o, d, c, r) = (v3(input, 0), v3(input, 3), v3(input, 6), input[9]);
        // pbrt: p ← c + (p − c)·r/|p − c|, error γ₅|p − c| (+ γ₁|p| for adding c back)
        let p = point(o, d, t);
        let f: [F; 3] = std::array::from_fn(|i| p[i] - c[i]);
        let k = r / (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        let f = f.map(|x| x * k);
        let q: [F; 3] = std::array::from_fn(|i| c[i] + f[i]);
        let (g5, g1) = (gamma::<F>(5), gamma::<F>(1));
        let err = std::array::from_fn(|i| g5 * f[i].abs() + g1 * q[i].abs());
        (q, err, unit_f(f))
    }
}

/// The torus around the z axis at its object-space origin, moved by a world translation.
struct TorusR;

impl Surface for TorusR {
    fn name(&self) -> &'static str {
        "torus"
    }
    fn curvature(&self, params: &[f64]) -> f64 {
        // The tube's 1/r2, or the inner equator's 1/(r1 − r2)
        (1.0 / params[1]).max(1.0 / (params[0] - params[1]))
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        shape_methods(&torus::Torus)
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, at: [f64; 3], prec: Precision) -> Instance {
        let r1 = rp(prec, s);
        let r2 = rp(
            prec,
            r1 * 10f64.powf(rng.random_range(-2.0..0.9f64.log10())),
        );
        let (theta, phi) = (
            rng.random_range(0.0..std::f64::consts::TAU),
            rng.random_range(0.0..std::f64::consts::TAU),
        );
        let (p, ..) = torus::cases::surface_frame(r1, r2, theta, phi);
        let c = rpv(prec, at);
        Instance {
            params: vec![r1, r2],
            c,
            aim: add(c, p),
            ext: r1 + r2,
        }
    }
    fn run<F: PickPrecision>(&self, m: usize, input: &[F]) -> Option<F> {
        torus::pick::<F>(m)(v3(input, 0), v3(input, 3), input[6], input[7])
    }
    fn exact(&self, input: &[f64]) -> Option<f64> {
        let case = ExactCase {
            o: v3(input, 0).map(q),
            d: v3(input, 3).map(q),
            r1: q(input[6]),
            r2: q(input[7]),
        };
        let p = quartic_q(&case);
        let (roots, sf) = positive_roots(&p);
        roots
            .first()
            .map(|(lo, hi)| sturm::round_in(&sf, lo, hi, Precision::F64))
    }
    fn surface<F: PickPrecision>(&self, m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]) {
        let (o, d, r1, r2) = (v3(input, 0), v3(input, 3), input[6], input[7]);
        // The robust method's own point; the others' o + t·d
        let p = match torus::METHODS[m].robust {
            true => torus_robust_hit(o, d, r1, r2).map_or(point(o, d, t), |h| h.1),
            false => point(o, d, t),
        };
        let e = gamma::<F>(ERR_GAMMA) * (r1 + r2);
        (p, [e; 3], unit_f(torus_normal(p, r1, r2)))
    }
}

/// One triangle, or two sharing the edge `a b` (`hinge`: `A = a b c`, `B = b a e`, folded by up
/// to 60° either way, hit at or next to the shared edge).
pub(super) struct TriR {
    pub(super) hinge: bool,
}

impl TriR {
    /// The case of triangle `k` (0 or 1) of a hinge, or of the single triangle.
    pub(super) fn tri<F: Copy>(&self, input: &[F], k: usize) -> ([F; 3], [F; 3], [[F; 3]; 3]) {
        let v = |i: usize| v3(input, 6 + 3 * i);
        let p = if k == 0 {
            [v(0), v(1), v(2)]
        } else {
            [v(1), v(0), v(3)]
        };
        (v3(input, 0), v3(input, 3), p)
    }
    pub(super) fn tris(&self) -> usize {
        1 + self.hinge as usize
    }
    /// Method `m`'s hit `h` on triangle `k` as the renderer's point, its error bound and the
    /// triangle's unit normal (`m = 0`, the chapter's `o + t·d`, is also the rule for a routine
    /// that returns only `t`).
    pub(super) fn point_of<F: Real>(
        &self,
        m: usize,
        input: &[F],
        k: usize,
        h: &triangle::TriHit<F>,
    ) -> ([F; 3], [F; 3], [F; 3]) {
        let (o, d, p) = self.tri(input, k);
        let (pt, err) = triangle::hit_point(m, o, d, &p, h);
        let e1: [F; 3] = std::array::from_fn(|i| p[1][i] - p[0][i]);
        let e2: [F; 3] = std::array::from_fn(|i| p[2][i] - p[0][i]);
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        (pt, err, unit_f(n))
    }

    /// The nearest hit of method `m` over the triangles.
    fn hit<F: Real>(&self, m: usize, input: &[F]) -> Option<(usize, triangle::TriHit<F>)> {
        (0..self.tris())
            .filter_map(|k| {
                let (o, d, p) = self.tri(input, k);
                triangle::method::<F>(m)(o, d, p).map(|h| (k, h))
            })
            .min_by(|a, b| {
                a.1.t
                    .partial_cmp(&b.1.t)
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
    }
}

impl Surface for TriR {
    fn name(&self) -> &'static str {
        if self.hinge {
            "hinge"
        } else {
            "triangle"
        }
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        // pbrt's watertight test is built to pass this one (its conservative `t > Δt`)
        triangle::METHODS
            .iter()
            .map(|m| (m.name, m.robust || m.name == "watertight"))
            .collect()
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, at: [f64; 3], prec: Precision) -> Instance {
        let ball = |rng: &mut ChaCha8Rng| add(at, mul(sample::ball(rng), s));
        loop {
            let (a, b) = (rpv(prec, ball(rng)), rpv(prec, ball(rng)));
            let edge = sub(b, a);
            if sample::norm(edge) < 0.2 * s {
                continue;
            }
            // c off the edge, e its mirror image folded about the edge
            let (q_, n_) = (sample::perp(rng, edge), sample::normalize(edge));
            let nrm = sample::normalize(sample::cross(n_, q_));
            let along = |rng: &mut ChaCha8Rng| add(a, mul(edge, rng.random_range(0.1..0.9)));
            let h = s * rng.random_range(0.3..1.0);
            let c = rpv(prec, add(along(rng), mul(q_, h)));
            let fold: f64 = rng.random_range(-1.0..1.0f64) * std::f64::consts::FRAC_PI_3;
            let e_dir = add(mul(q_, -fold.cos()), mul(nrm, fold.sin()));
            let e = rpv(
                prec,
                add(along(rng), mul(e_dir, s * rng.random_range(0.3..1.0))),
            );
            // Aimed at the shared edge (exactly, a quarter of the time) or just off it
            let on_edge = add(a, mul(edge, rng.random_range(0.05..0.95)));
            let off = if rng.random_bool(0.25) {
                0.0
            } else {
                lu(rng, -7.0, -1.0)
            };
            let (aim, params) = if self.hinge {
                let aim = add(on_edge, mul(sub(c, on_edge), off));
                (aim, [a, b, c, e].concat())
            } else {
                let (u, v) = (rng.random::<f64>(), rng.random::<f64>());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let aim = add(a, add(mul(edge, u), mul(sub(c, a), v)));
                (aim, [a, b, c].concat())
            };
            return Instance {
                params,
                c: [0.0; 3],
                aim,
                ext: s,
            };
        }
    }
    fn run<F: PickPrecision>(&self, m: usize, input: &[F]) -> Option<F> {
        self.hit(m, input).map(|(_, h)| h.t)
    }
    fn exact(&self, input: &[f64]) -> Option<f64> {
        (0..self.tris())
            .filter_map(|k| {
                let (o, d, p) = self.tri(input, k);
                let v = [&o[..], &d[..], &p.concat()[..]].concat();
                triangle::exact_tri(&v)
                    .t()
                    .map(|t| round_q(&t, Precision::F64))
            })
            .min_by(f64::total_cmp)
    }
    fn surface<F: PickPrecision>(&self, m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]) {
        let (k, h) = self.hit(m, input).expect("a hit");
        debug_assert!(h.t == t);
        self.point_of(m, input, k, &h)
    }
    fn other_part<F: PickPrecision>(&self, m: usize, primary: &[F], spawned: &[f64]) -> bool {
        let spawned: Vec<F> = spawned.iter().map(|&x| F::from_f64(x)).collect();
        match (self.hit(m, primary), self.hit(m, &spawned)) {
            (Some((a, _)), Some((b, _))) => a != b,
            _ => false,
        }
    }
}
