//! Reintersection: rays spawned from a computed hit must not hit their own surface again (issue 6
//! item 8; issue 17 item 1 gave it teeth). One test for every surface: the box, the ellipsoid, the
//! cylinder, the sphere, the torus, a single triangle and two triangles sharing an edge
//! (`surfaces.rs`).
//!
//! **Instances.** Per precision, `per_scale` instances in each decade of size `10^[-4, 4)` and
//! each placement: `near` (up to 100 sizes from the origin) and `far` (`10³`–`10⁵` sizes away,
//! the far-small class, where an `f32` hit point is off by thousandths of the shape's size).
//! The box and the sphere carry their position in their parameters; the other surfaces sit at
//! their object-space origin behind a world translation `c`, so the method is given `o − c`
//! rounded, as a renderer would. One primary ray per instance comes from outside, aimed at a
//! point of the instance (the shared edge for the hinge).
//!
//! **Spawned rays.** Each method's hit gives the point a renderer really has, in the working
//! precision (the method's own `o + t·d`, or its reprojection onto the surface where the method
//! or pbrt does that), with a per-component error bound `err` (`Surface::surface`). From it,
//! [`SPAWNED`] rays leave in random directions, half to the reflection side of the computed
//! normal and half to the transmission side, from [`spawn_origin`] under three rules
//! ([`Rule`]): the project's rule, the rule 1000× too weak, and no offset at all. The last two
//! are controls: a test that finds no re-hit without an offset cannot see a broken offset.
//!
//! **Judgement, against the ideal ray.** The reference is the spawned ray a renderer would have
//! with exact arithmetic: from the exact primary hit `p*` (the exact root, rounded to `f64`) along
//! the same direction `w`. Its next genuine crossing `L` is found by the exact oracle from
//! `p* + z₀·w`, `z₀ = 16·2⁻⁵³·(max|pᵢ| + size)/|w·n|` (just past `p*`'s own `f64` error). A
//! **re-hit** is a hit the method reports on its spawned ray at `t < L/2` (for a reflection ray
//! off a convex surface or any ray off a single triangle `L = ∞`, so every hit is a re-hit).
//! The **self-hit zone** is `z = 4·(reach)/|w·n|`, where the reach is the rule's offset along
//! the normal plus two ulps of `max|pᵢ|`: as far as a spawned origin can sit from `p*`. A ray
//! whose ideal crossing lies within it (`L < z`) is **ill-posed** at this precision: rounding
//! alone decides it, so it is counted apart and judged neither way.
//!
//! Three more kinds of spawned ray are ill-posed, each because the renderer's point is not `p*`:
//! - a **grazing chord**: the ideal ray crosses again before `p* + z₀·w` (seen by looking back
//!   from there), so within the zone;
//! - a **tilted grazing ray**: a spawned origin can sit the reach from `p*` (the point's
//!   rounding and the rule's offset), where the surface's normal is turned by up to curvature ×
//!   reach (`Surface::curvature`); a ray leaving at less than that angle meets the surface
//!   again or not as the placement decides (a far `f32` sphere, reflection at 3e-5
//!   rad: it re-enters 0.13 along; a far `f32` torus whose offset, 76, is its tube's radius);
//! - a **displaced far crossing**: the method's hit lies beyond the zone and the exact answer
//!   for the spawned ray, from its own origin, confirms it: the moved origin sends the ray
//!   across a rim, an edge or a far part that the ideal ray just misses (a far `f32` cylinder
//!   whose spawned ray leaves below the open rim the ideal ray passes just above).
//!
//! None of these can hide a broken offset: a self-hit is a hit within the zone, from an origin
//! the offset left on the wrong side. Before they were separated, robust methods "re-hit" at
//! seeds 3, 5, 6, 7, 9, 11 and 16 (one ray in about 3,000 each), so the audit's verdict
//! depended on its seed.
//!
//! A re-hit that lands on *another part* of the surface (the other triangle of a hinge) and that
//! the exact answer for the spawned ray confirms is also counted as `neighbour`: the offset,
//! applied per triangle as in pbrt, carried the origin across the neighbour. That is a limit of
//! the rule at shared edges, not an error of the method, and the audit reports it apart.
//!
//! Judging the spawned ray from its own, offset origin instead (what this test did before issue
//! 17) is blind: a point left inside by rounding makes the exact answer a hit at a tiny `t`, so
//! the self-hit looks right and no breakage of the offset rule is ever seen.

mod outside;
mod surfaces;

use super::offset::{spawn_origin, ReintersectRow, Rule};
use crate::numerics::real::gamma;
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::oracle::sample::{add, lu, mul, normalize, rpv, sub, unit};
use crate::shapes::sphere::methods::PickPrecision;
use rand::Rng;
use rayon::prelude::*;
use std::cell::OnceCell;

pub use outside::outside_rows;
pub(crate) use surfaces::Surface;
pub use surfaces::NAMES;

/// Decades of size: `10^[-4, 4)`.
const DECADES: i32 = 8;
/// Where instances sit: name and `log10` of their distance from the origin, in sizes.
const PLACEMENTS: [(&str, f64, f64); 2] = [("near", -1.0, 2.0), ("far", 3.0, 5.0)];
/// Spawned rays per hit: half to each side.
pub const SPAWNED: usize = 8;
/// The self-hit zone in units of how far a spawned origin can sit from `p*` (see the module doc).
const ZONE: f64 = 4.0;

/// One instance: its parameters (after `o, d` in a case), its world translation, a world point
/// the primary ray is aimed at, and its size.
pub(crate) struct Instance {
    pub params: Vec<f64>,
    pub c: [f64; 3],
    pub aim: [f64; 3],
    pub ext: f64,
}

/// Spawned rays, re-hits and ill-posed hits of one method under one rule.
#[derive(Clone, Copy, Default)]
struct Count {
    rays: u64,
    rehits: u64,
    neighbour: u64,
    ill_posed: u64,
}

impl std::ops::AddAssign for Count {
    fn add_assign(&mut self, o: Count) {
        self.rays += o.rays;
        self.rehits += o.rehits;
        self.neighbour += o.neighbour;
        self.ill_posed += o.ill_posed;
    }
}

fn to_f64<F: Real>(v: &[F]) -> Vec<f64> {
    v.iter().map(|x| x.to_f64()).collect()
}

fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `o + t·d` in the working precision.
pub(crate) fn point<F: Real>(o: [F; 3], d: [F; 3], t: F) -> [F; 3] {
    std::array::from_fn(|i| o[i] + t * d[i])
}

/// The ideal ray's next genuine crossing from `p*` along `w` (object space): the exact first root
/// from `p* + z₀·w` (past `p*`'s own crossing) plus `z₀`; `f64::INFINITY` when there is none,
/// `None` when it lies within the self-hit zone `z` (ill-posed), also when it lies before
/// `p* + z₀·w` (a grazing ray's short chord, which the forward search would step over).
fn ideal_next<K: Surface>(
    k: &K,
    params: &[f64],
    ps: [f64; 3],
    w: [f64; 3],
    z0: f64,
    z: f64,
) -> Option<f64> {
    let q = add(ps, mul(w, z0));
    // A crossing between p* and q (a grazing chord shorter than z₀) is within the zone: seen
    // looking back from q, it comes before p*'s own, which is z₀ away up to p*'s error (z₀/16)
    let back = [&q[..], &w.map(|x| -x)[..], params].concat();
    if k.exact(&back).is_some_and(|t| t < 0.875 * z0) {
        return None;
    }
    let next = k
        .exact(&[&q[..], &w[..], params].concat())
        .map_or(f64::INFINITY, |t| z0 + t);
    (next >= z).then_some(next)
}

/// Method `m` on one instance: its primary hit, then the spawned rays under every rule.
fn spawn_and_test<K: Surface, F: PickPrecision>(
    k: &K,
    m: usize,
    inst: &Instance,
    (o_w, d): ([F; 3], [F; 3]),
    dirs: &[[f64; 3]; SPAWNED],
) -> [Count; 3] {
    let mut out = [Count::default(); 3];
    let c = inst.c.map(F::from_f64);
    let params: Vec<F> = inst.params.iter().map(|&x| F::from_f64(x)).collect();
    let params64 = to_f64(&params);
    let case = |o: [F; 3], d: [F; 3]| [&o[..], &d[..], &params[..]].concat();
    // Primary hit, in object space
    let o_obj: [F; 3] = std::array::from_fn(|i| o_w[i] - c[i]);
    let input = case(o_obj, d);
    let Some(t) = k.run(m, &input) else {
        return out;
    };
    // The exact primary hit p* (a method hit where the exact answer misses is not this test's)
    let Some(ts) = k.exact(&to_f64(&input)) else {
        return out;
    };
    let (o64, d64) = (o_obj.map(|x| x.to_f64()), d.map(|x| x.to_f64()));
    let ps: [f64; 3] = std::array::from_fn(|i| o64[i] + ts * d64[i]);
    // The renderer's point, its error bound and normal, in the world
    let (p_obj, mut err, n) = k.surface(m, &input, t);
    let p_w: [F; 3] = std::array::from_fn(|i| p_obj[i] + c[i]);
    if c.iter().any(|&x| x != F::ZERO) {
        let g2 = gamma::<F>(2);
        err = std::array::from_fn(|i| err[i] + g2 * (p_w[i].abs() + c[i].abs()));
    }
    let n64 = normalize(n.map(|x| x.to_f64()));
    let pmax = p_w.iter().fold(0f64, |a, x| a.max(x.to_f64().abs()));
    // The rule's offset along the normal plus two ulps: how far a spawned origin can sit from p*
    let reach = (0..3).map(|i| n64[i].abs() * err[i].to_f64()).sum::<f64>()
        + 2.0 * pmax * 2f64.powi(1 - F::MANT_BITS as i32);
    let curvature = k.curvature(&params64);
    // Past p*'s own error (an f64 point from the exact root rounded to f64)
    let past = 16.0 * 2f64.powi(-53) * (pmax + inst.ext);
    for (j, dir) in dirs.iter().enumerate() {
        // Reflection side for the first half, transmission side for the rest
        let mut w = dir.map(F::from_f64);
        let wn = dot3(w.map(|x| x.to_f64()), n64);
        if wn == 0.0 {
            continue;
        }
        if (wn > 0.0) != (j < SPAWNED / 2) {
            w = w.map(|x| -x);
        }
        let w64 = w.map(|x| x.to_f64());
        let (z0, z) = (
            past / wn.abs(),
            (ZONE * reach / wn.abs()).max(4.0 * past / wn.abs()),
        );

        // A spawned origin can sit `reach` from p* (rounding and the rule's offset), where the
        // surface's normal is turned by up to curvature × reach: a ray leaving at less than that
        // angle meets the surface again or not as the placement decides. The same rays are set
        // aside under every rule, so the rules are compared on one population
        let tilted = wn.abs() < curvature * reach;
        let next = OnceCell::new();
        for (r, rule) in Rule::ALL.iter().enumerate() {
            let e = err.map(|x| x * F::from_f64(rule.factor()));
            let po_w = spawn_origin(p_w, e, n, w);
            let po_obj: [F; 3] = std::array::from_fn(|i| po_w[i] - c[i]);
            out[r].rays += 1;
            if tilted {
                out[r].ill_posed += 1;
                continue;
            }
            let Some(t2) = k.run(m, &case(po_obj, w)) else {
                continue;
            };
            match next.get_or_init(|| ideal_next(k, &params64, ps, w64, z0, z)) {
                None => out[r].ill_posed += 1,
                Some(l) if t2.to_f64() < 0.5 * l => {
                    // Is the method right for its own ray (the exact answer from its origin)?
                    let spawned = to_f64(&case(po_obj, w));
                    let confirmed = || k.exact(&spawned).is_some_and(|te| t2.to_f64() >= 0.5 * te);
                    // Beyond the self-hit zone and real for the spawned ray: its origin, moved by
                    // rounding, sends it across a rim, an edge or a far side the ideal ray just
                    // misses. Rounding of the origin decides that, not the offset: ill-posed
                    if t2.to_f64() >= z && confirmed() {
                        out[r].ill_posed += 1;
                        continue;
                    }
                    out[r].rehits += 1;
                    // On the other part of the surface: a crossed neighbour
                    if k.other_part(m, &input, &spawned) && confirmed() {
                        out[r].neighbour += 1;
                    }
                }
                Some(_) => {}
            }
        }
    }
    out
}

/// Every method of one surface on one instance, per rule.
fn trial<K: Surface, F: PickPrecision>(k: &K, seed: u64, index: u64) -> Vec<[Count; 3]> {
    let prec = Precision::of::<F>();
    let mut rng = crate::shapes::shape::case_rng(seed, k.name(), "reintersect", prec, index);
    // Size by decade, placement near or far
    let decade = (index % DECADES as u64) as f64 - 4.0;
    let (_, lo, hi) = PLACEMENTS[(index / DECADES as u64) as usize % PLACEMENTS.len()];
    let s = 10f64.powf(decade + rng.random::<f64>());
    let at = mul(unit(&mut rng), s * lu(&mut rng, lo, hi));
    let inst = k.instance(&mut rng, s, at, prec);
    // A primary ray from outside, aimed at the instance's point
    let o_w = rpv(
        prec,
        add(
            inst.aim,
            mul(unit(&mut rng), inst.ext * (2.0 + lu(&mut rng, -1.0, 0.0))),
        ),
    );
    let d = rpv(prec, normalize(sub(inst.aim, o_w)));
    let dirs: [[f64; 3]; SPAWNED] = std::array::from_fn(|_| rpv(prec, unit(&mut rng)));
    let ray = (o_w.map(F::from_f64), d.map(F::from_f64));
    (0..k.methods().len())
        .map(|m| spawn_and_test(k, m, &inst, ray, &dirs))
        .collect()
}

fn rows_in<K: Surface, F: PickPrecision>(k: &K, seed: u64, per_scale: u64) -> Vec<ReintersectRow> {
    let n = per_scale * DECADES as u64 * PLACEMENTS.len() as u64;
    let per: Vec<Vec<[Count; 3]>> = (0..n)
        .into_par_iter()
        .map(|i| trial::<K, F>(k, seed, i))
        .collect();
    let mut rows = vec![];
    for (m, (method, robust)) in k.methods().into_iter().enumerate() {
        for (r, rule) in Rule::ALL.iter().enumerate() {
            let mut c = Count::default();
            per.iter().for_each(|v| c += v[m][r]);
            rows.push(ReintersectRow {
                shape: k.name().into(),
                method: method.into(),
                precision: F::NAME.into(),
                robust,
                rule: rule.name().into(),
                rays: c.rays,
                rehits: c.rehits,
                neighbour: c.neighbour,
                ill_posed: c.ill_posed,
                verdict: String::new(),
            });
        }
    }
    rows
}

fn rows<K: Surface>(k: &K, seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    match prec {
        Precision::F32 => rows_in::<K, f32>(k, seed, per_scale),
        Precision::F64 => rows_in::<K, f64>(k, seed, per_scale),
    }
}

/// The rows of one surface of [`NAMES`] (every method × rule) in one precision; empty for
/// another name.
pub fn rows_of(name: &str, seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    surfaces::rows_of(name, seed, per_scale, prec)
}

/// Every surface's rows in one precision.
pub fn reintersection_all(seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    NAMES
        .iter()
        .flat_map(|name| rows_of(name, seed, per_scale, prec))
        .collect()
}

/// The rows as a terminal table.
pub fn table(rows: &[ReintersectRow]) -> String {
    let mut s = format!(
        "{:<10} {:<16} {:<4} {:<6} {:>7} {:>8} {:>7} {:>10} {:>10}\n",
        "shape", "method", "prec", "rule", "robust", "rays", "rehits", "neighbour", "ill-posed"
    );
    for r in rows {
        s += &format!(
            "{:<10} {:<16} {:<4} {:<6} {:>7} {:>8} {:>7} {:>10} {:>10}\n",
            r.shape,
            r.method,
            r.precision,
            r.rule,
            r.robust,
            r.rays,
            r.rehits,
            r.neighbour,
            r.ill_posed
        );
    }
    s
}
