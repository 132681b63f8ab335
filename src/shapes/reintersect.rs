//! Reintersection (issue 6 item 8) for the box, the ellipsoid, the cylinder and the sphere (its
//! sampling helpers are [`super::sample`], shared with the box and quadric case generators).
//!
//! **Test.** Per precision, `per_scale` instances in each decade of scale `10^[-4, 4)`, placed up
//! to 100 scales from the origin (the box and the sphere through their own parameters, the
//! ellipsoid and the cylinder, which sit at their object-space origin, through a world
//! translation `c`: the method is given `o − c` rounded, as a renderer would). One primary ray
//! per instance comes from outside, aimed at an interior point. Each method's hit spawns four
//! rays with [`super::offset::spawn_origin`] in random directions, two to the reflection side (outside)
//! and two to the transmission side. A **re-hit** is a spawned ray for which the method reports a
//! hit that the exact oracle of that spawned (object-space) ray says is not there: a hit where
//! the exact answer is a miss, or a `t` below half the exact first positive root.
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
//!   does not matter: the normal has no `z`). A world translation adds `γ₂(|p| + |c|)`.

use super::offset::{gamma, spawn_origin, ReintersectRow};
use super::sample::{self, add, cube, lu, mul, normalize, rp, rpv, sub, unit};
use crate::audit::shape::{Shape, Truth};
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::aabb;
use crate::shapes::quadric;
use crate::shapes::sphere::methods::{PickPrecision, METHODS as SPHERE_METHODS};
use crate::shapes::sphere::oracle::{self as sphere_oracle, Case};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Decades of scale: `10^[-4, 4)`.
const DECADES: i32 = 8;
/// Spawned rays per hit: two to each side.
const SPAWNED: usize = 4;

/// One instance of a closed shape: its parameters (after `o, d` in a case), its world
/// translation, a world point inside it, and its size.
struct Instance {
    params: Vec<f64>,
    c: [f64; 3],
    aim: [f64; 3],
    ext: f64,
}

/// A closed shape under the reintersection test.
trait Closed: Sync {
    fn name(&self) -> &'static str;
    /// `(name, robust)` of every method.
    fn methods(&self) -> Vec<(&'static str, bool)>;
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, prec: Precision) -> Instance;
    /// Method `m` on a case `o, d, params` (object space).
    fn run<F: PickPrecision>(&self, m: usize, input: &[F]) -> Option<F>;
    /// The exact first root `t > 0`, correctly rounded (`None`: a miss).
    fn exact<F: PickPrecision>(&self, input: &[F]) -> Option<f64>;
    /// Method `m`'s hit at `t` as a surface point, its error bound and the unit outward normal.
    fn surface<F: PickPrecision>(&self, m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]);
}

fn prec_of<F: Real>() -> Precision {
    if F::MANT_BITS == 24 {
        Precision::F32
    } else {
        Precision::F64
    }
}

fn v3<F: Real>(v: &[F], k: usize) -> [F; 3] {
    [v[k], v[k + 1], v[k + 2]]
}

fn to_f64<F: Real>(v: &[F]) -> Vec<f64> {
    v.iter().map(|x| x.to_f64()).collect()
}

/// A routine's method as `Option<t>`.
fn shape_run<F: Real>(shape: &dyn Shape, m: usize, input: &[F]) -> Option<F> {
    let a = shape.run(m, &to_f64(input), prec_of::<F>());
    (a.count > 0).then(|| F::from_f64(a.values[0]))
}

/// A routine's exact first root.
fn shape_exact<F: Real>(shape: &dyn Shape, input: &[F]) -> Option<f64> {
    match shape.oracle(&to_f64(input), prec_of::<F>()) {
        Truth::Answer(e) if e.count > 0 => Some(e.values[0]),
        _ => None,
    }
}

fn shape_methods(shape: &dyn Shape) -> Vec<(&'static str, bool)> {
    shape
        .info()
        .methods
        .iter()
        .map(|m| (m.name, m.robust))
        .collect()
}

/// `o + t·d` in the working precision.
fn point<F: Real>(o: [F; 3], d: [F; 3], t: F) -> [F; 3] {
    std::array::from_fn(|i| o[i] + t * d[i])
}

fn unit_f<F: Real>(g: [F; 3]) -> [F; 3] {
    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    g.map(|x| x / len)
}

/// Places an instance up to 100 scales from the origin.
fn offset_centre(rng: &mut ChaCha8Rng, s: f64) -> [f64; 3] {
    mul(cube(rng), 100.0 * s)
}

struct BoxR;

impl Closed for BoxR {
    fn name(&self) -> &'static str {
        "box"
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        shape_methods(&aabb::BoxShape)
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, prec: Precision) -> Instance {
        let c = offset_centre(rng, s);
        let e: [f64; 3] = std::array::from_fn(|_| s * lu(rng, -1.0, 0.0));
        let (lo, hi) = (rpv(prec, sub(c, e)), rpv(prec, add(c, e)));
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
    fn exact<F: PickPrecision>(&self, input: &[F]) -> Option<f64> {
        shape_exact(&aabb::BoxShape, input)
    }
    fn surface<F: PickPrecision>(&self, m: usize, input: &[F], t: F) -> ([F; 3], [F; 3], [F; 3]) {
        let (o, d, lo, hi) = (v3(input, 0), v3(input, 3), v3(input, 6), v3(input, 9));
        let p = point(o, d, t);
        // The face nearest p, relative to the size of the terms that formed it
        let mut best = (F::INFINITY, 0, F::ONE);
        for i in 0..3 {
            let size = o[i].abs() + (t * d[i]).abs() + hi[i].abs().max_r(lo[i].abs());
            for (b, sgn) in [(lo[i], -F::ONE), (hi[i], F::ONE)] {
                let dist = (p[i] - b).abs() / size;
                if dist < best.0 {
                    best = (dist, i, sgn);
                }
            }
        }
        let mut n = [F::ZERO; 3];
        n[best.1] = best.2;
        let k = [4, 5, 11][m];
        let g = gamma::<F>(k);
        let err = std::array::from_fn(|i| g * (o[i].abs() + (t * d[i]).abs()));
        (p, err, n)
    }
}

/// `max` for [`Real`] values (no NaN here).
trait MaxR {
    fn max_r(self, o: Self) -> Self;
}
impl<F: Real> MaxR for F {
    fn max_r(self, o: F) -> F {
        if o > self {
            o
        } else {
            self
        }
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

impl Closed for QuadR {
    fn name(&self) -> &'static str {
        self.shape().name()
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        shape_methods(self.shape())
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, prec: Precision) -> Instance {
        let (m, third) = (lu(rng, -0.3, 0.3), lu(rng, -0.3, 0.3));
        let ext = s * m.recip().max(third.recip()).max(1.0);
        let c = rpv(prec, offset_centre(rng, s));
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
    fn exact<F: PickPrecision>(&self, input: &[F]) -> Option<f64> {
        shape_exact(self.shape(), input)
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
        let (g, lateral) = (gamma::<F>(if self.cylinder { 5 } else { 7 }), self.cylinder);
        let err = std::array::from_fn(|i| {
            if lateral && i == 2 {
                F::ZERO
            } else {
                g * q[i].abs()
            }
        });
        (q, err, n)
    }
}

/// The sphere of `src/sphere`, every method of its `METHODS` table; hits reprojected onto the
/// sphere by this test (none of the methods does it itself).
struct SphereR;

impl Closed for SphereR {
    fn name(&self) -> &'static str {
        "sphere"
    }
    fn methods(&self) -> Vec<(&'static str, bool)> {
        SPHERE_METHODS.iter().map(|m| (m.name, m.robust)).collect()
    }
    fn instance(&self, rng: &mut ChaCha8Rng, s: f64, prec: Precision) -> Instance {
        let c = rpv(prec, offset_centre(rng, s));
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
    fn exact<F: PickPrecision>(&self, input: &[F]) -> Option<f64> {
        let truth = sphere_oracle::truth(&sphere_case(input));
        if truth.verdict.is_hit() {
            truth.t_in::<F>().map(|t| t.to_f64())
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

fn sphere_case<F: Real>(v: &[F]) -> Case<F> {
    Case {
        o: v3(v, 0),
        d: v3(v, 3),
        c: v3(v, 6),
        r: v[9],
    }
}

/// Where spawned rays start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Spawn {
    /// The project's rule: reprojected hit (quadrics), offset by `err` along the normal.
    Offset,
    /// The control: the raw hit `o + t·d`, no reprojection and no offset.
    Raw,
}

/// `(spawned rays, re-hits)` of one method on one instance.
fn spawn_and_test<K: Closed, F: PickPrecision>(
    k: &K,
    m: usize,
    inst: &Instance,
    (o_w, d): ([F; 3], [F; 3]),
    dirs: &[[f64; 3]; SPAWNED],
    spawn: Spawn,
) -> (u64, u64) {
    let c = inst.c.map(F::from_f64);
    let params: Vec<F> = inst.params.iter().map(|&x| F::from_f64(x)).collect();
    let case = |o: [F; 3], d: [F; 3]| [&o[..], &d[..], &params[..]].concat();
    // Primary hit, in object space
    let o_obj: [F; 3] = std::array::from_fn(|i| o_w[i] - c[i]);
    let input = case(o_obj, d);
    let Some(t) = k.run(m, &input) else {
        return (0, 0);
    };
    let (p_obj, mut err, n) = k.surface(m, &input, t);
    // Back to the world
    let p_w: [F; 3] = std::array::from_fn(|i| p_obj[i] + c[i]);
    if c.iter().any(|&x| x != F::ZERO) {
        let g2 = gamma::<F>(2);
        err = std::array::from_fn(|i| err[i] + g2 * (p_w[i].abs() + c[i].abs()));
    }
    let mut out = (0, 0);
    for (j, dir) in dirs.iter().enumerate() {
        // Reflection side (outside) for the first half, transmission side for the rest
        let mut w = dir.map(F::from_f64);
        let wn = w[0] * n[0] + w[1] * n[1] + w[2] * n[2];
        if wn == F::ZERO {
            continue;
        }
        if (wn > F::ZERO) != (j < SPAWNED / 2) {
            w = w.map(|x| -x);
        }
        let po_w = match spawn {
            Spawn::Offset => spawn_origin(p_w, err, n, w),
            Spawn::Raw => point(o_w, d, t),
        };
        let po_obj: [F; 3] = std::array::from_fn(|i| po_w[i] - c[i]);
        let spawned = case(po_obj, w);
        out.0 += 1;
        if let Some(t2) = k.run(m, &spawned) {
            let exact = k.exact(&spawned);
            if exact.is_none_or(|te| t2.to_f64() < 0.5 * te) {
                out.1 += 1;
            }
        }
    }
    out
}

/// Every method of one shape on one instance: `(rays, re-hits)` per method.
fn trial<K: Closed, F: PickPrecision>(
    k: &K,
    seed: u64,
    index: u64,
    spawn: Spawn,
) -> Vec<(u64, u64)> {
    let prec = prec_of::<F>();
    let mut rng = crate::audit::shape::case_rng(seed, k.name(), "reintersect", prec, index);
    let decade = (index % DECADES as u64) as f64 - 4.0;
    let s = 10f64.powf(decade + rng.random::<f64>());
    let inst = k.instance(&mut rng, s, prec);
    // A primary ray from outside, aimed at the interior point
    let o_w = rpv(
        prec,
        add(
            inst.aim,
            mul(unit(&mut rng), inst.ext * (2.0 + lu(&mut rng, -1.0, 1.0))),
        ),
    );
    let d = rpv(prec, normalize(sub(inst.aim, o_w)));
    let dirs: [[f64; 3]; SPAWNED] = std::array::from_fn(|_| rpv(prec, unit(&mut rng)));
    (0..k.methods().len())
        .map(|m| {
            let ray = (o_w.map(F::from_f64), d.map(F::from_f64));
            spawn_and_test(k, m, &inst, ray, &dirs, spawn)
        })
        .collect()
}

fn rows_in<K: Closed, F: PickPrecision>(
    k: &K,
    seed: u64,
    per_scale: u64,
    spawn: Spawn,
) -> Vec<ReintersectRow> {
    let n = per_scale * DECADES as u64;
    let per: Vec<Vec<(u64, u64)>> = (0..n)
        .into_par_iter()
        .map(|i| trial::<K, F>(k, seed, i, spawn))
        .collect();
    k.methods()
        .into_iter()
        .enumerate()
        .map(|(m, (method, robust))| ReintersectRow {
            shape: k.name(),
            method,
            precision: F::NAME,
            robust,
            rays: per.iter().map(|v| v[m].0).sum(),
            rehits: per.iter().map(|v| v[m].1).sum(),
            scales: [-4.0, 4.0],
        })
        .collect()
}

fn rows_with<K: Closed>(
    k: &K,
    seed: u64,
    per_scale: u64,
    prec: Precision,
    spawn: Spawn,
) -> Vec<ReintersectRow> {
    match prec {
        Precision::F32 => rows_in::<K, f32>(k, seed, per_scale, spawn),
        Precision::F64 => rows_in::<K, f64>(k, seed, per_scale, spawn),
    }
}

fn rows<K: Closed>(k: &K, seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    rows_with(k, seed, per_scale, prec, Spawn::Offset)
}

/// Reintersection rows of the box (one per method).
pub fn box_rows(seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    rows(&BoxR, seed, per_scale, prec)
}

/// Reintersection rows of the ellipsoid and the cylinder (one per method each).
pub fn quadric_rows(seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    let mut v = rows(&QuadR { cylinder: false }, seed, per_scale, prec);
    v.extend(rows(&QuadR { cylinder: true }, seed, per_scale, prec));
    v
}

/// Reintersection rows of the sphere's methods (hits reprojected by the test, as pbrt does).
pub fn sphere_rows(seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    rows(&SphereR, seed, per_scale, prec)
}

/// Every closed shape of this module: box, ellipsoid, cylinder, sphere.
pub fn reintersection_all(seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    let mut v = box_rows(seed, per_scale, prec);
    v.extend(quadric_rows(seed, per_scale, prec));
    v.extend(sphere_rows(seed, per_scale, prec));
    v
}

/// The control run: the same instances and rays, but every spawned ray starts at the method's
/// raw hit `o + t·d` (no reprojection, no offset), as a renderer without the rule would. Its
/// re-hits show that the test sees self-intersection when the rule is missing.
pub fn reintersection_raw_all(seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    let mut v = rows_with(&BoxR, seed, per_scale, prec, Spawn::Raw);
    for k in [QuadR { cylinder: false }, QuadR { cylinder: true }] {
        v.extend(rows_with(&k, seed, per_scale, prec, Spawn::Raw));
    }
    v.extend(rows_with(&SphereR, seed, per_scale, prec, Spawn::Raw));
    v
}

/// The rows as a terminal table.
pub fn table(rows: &[ReintersectRow]) -> String {
    let mut s = format!(
        "{:<10} {:<12} {:<4} {:>7} {:>8} {:>7}\n",
        "shape", "method", "prec", "robust", "rays", "rehits"
    );
    for r in rows {
        s += &format!(
            "{:<10} {:<12} {:<4} {:>7} {:>8} {:>7}\n",
            r.shape, r.method, r.precision, r.robust, r.rays, r.rehits
        );
    }
    s
}
