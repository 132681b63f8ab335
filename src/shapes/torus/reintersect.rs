//! Torus reintersection (issue 6 item 8).
//!
//! Instances: per decade `10^k … 10^(k+1)`, `k = −4 … 3`, `per_scale` tori with `r1` log-uniform
//! in the decade, `r2 = r1·10^U[−2, log10 0.9]`, centred at `c`, a random point up to `100·r1`
//! from the world origin. A primary ray starts `2–4·(r1 + r2)` from `c`, aimed at a random point
//! of the surface. Each method intersects it in object space (`o − c`, rounded, as a renderer
//! does); a hit spawns [`SPAWNED`] rays in random directions, half on the reflection side
//! (`w·n > 0`) and half on the transmission side, from the origin given by
//! [`offset::spawn_origin`]. The exact oracle then decides each spawned ray from its exact
//! origin and the exact centre: a **re-hit** is a hit the method reports where the exact
//! answer is a miss, or at `t` below half the exact first positive root.
//!
//! **How `err` was chosen** (the same rule for every method, so that the rows compare the
//! methods' roots, not their offsets). A hit point is `p_w = c + p`, `p = o' + t·d` (fused);
//! the world sum is one rounding, `γ(2)·|p_w|` per component. The object-space point is as
//! good as the method's `t`: for the robust method the Newton step on the signed distance leaves
//! `|sdf(p)|` at the rounding level of `√(x² + y²)`, which mixes components, so its bound is
//! `γ(K)·(r1 + r2)` in *every* component (a bound `γ·|pᵢ|` would vanish at the top of a thin
//! tube, where `p` has a large `x` but the normal is along `z`). [`ERR_GAMMA`] = `K` is the
//! largest `|sdf(p)|/(ε(r1 + r2))` measured on the robust method's hits with a margin (see
//! `tests/torus.rs`). The chapter's methods cannot justify any bound (their `t` can be off by
//! many ulps); they are given the same one.

use super::cases::{round_to, surface_frame, unit};
use super::methods::{normalize, point_at, torus_normal, torus_robust_hit};
use super::oracle::{positive_roots, quartic_q, ExactCase};
use super::{pick, METHODS};
use crate::audit::shape::case_rng;
use crate::numerics::exact::q;
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::offset::{error_bound, gamma, spawn_origin, ReintersectRow};
use crate::shapes::sturm;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::f64::consts::TAU;

/// Spawned rays per hit (half on each side).
pub const SPAWNED: usize = 8;

/// `K` of the robust bound `γ(K)·(r1 + r2)`.
pub const ERR_GAMMA: u32 = 32;

/// Decades of scale, `10^k` for `k` in this range.
const DECADES: std::ops::Range<i32> = -4..4;

/// One instance: centre, radii, primary ray (all exact in the precision).
struct Instance {
    c: [f64; 3],
    r1: f64,
    r2: f64,
    o: [f64; 3],
    d: [f64; 3],
}

fn instance(rng: &mut ChaCha8Rng, k: i32, prec: Precision) -> Instance {
    let r = |x: f64| round_to(x, prec);
    let r1 = r(10f64.powf(k as f64 + rng.random_range(0.0..1.0)));
    let r2 = r(r1 * 10f64.powf(rng.random_range(-2.0..0.9f64.log10())));
    let c = unit(rng).map(|x| r(x * 100.0 * r1 * rng.random_range(0.0..1.0)));
    let (p, ..) = surface_frame(
        r1,
        r2,
        rng.random_range(0.0..TAU),
        rng.random_range(0.0..TAU),
    );
    let u = unit(rng);
    let dist = (r1 + r2) * rng.random_range(2.0..4.0);
    let o = [0, 1, 2].map(|i| r(c[i] + u[i] * dist));
    let d = [0, 1, 2].map(|i| r(c[i] + p[i] - o[i]));
    Instance { c, r1, r2, o, d }
}

/// The exact first positive root for the ray from exact `s` along `w` on the instance, rounded
/// to `f64` (`None`: exact miss).
fn exact_first(inst: &Instance, s: [f64; 3], w: [f64; 3]) -> Option<f64> {
    let case = ExactCase {
        o: [0, 1, 2].map(|i| q(s[i]) - q(inst.c[i])),
        d: w.map(q),
        r1: q(inst.r1),
        r2: q(inst.r2),
    };
    let p = quartic_q(&case);
    let (roots, _) = positive_roots(&p);
    roots
        .first()
        .map(|r| sturm::round_root(&p, r, Precision::F64))
}

/// Spawned rays and re-hits of method `m` on one instance.
fn run_instance<F: Real>(m: usize, inst: &Instance, rng: &mut ChaCha8Rng) -> (u64, u64) {
    let f = |a: [f64; 3]| a.map(F::from_f64);
    let (c, r1, r2) = (f(inst.c), F::from_f64(inst.r1), F::from_f64(inst.r2));
    let method = pick::<F>(m);
    let to_obj = |s: [F; 3]| [s[0] - c[0], s[1] - c[1], s[2] - c[2]];
    let (o, d) = (to_obj(f(inst.o)), f(inst.d));
    // Hit point (the robust method's own, the others' o + t·d fused), normal, error bound
    let hit = if METHODS[m].robust {
        torus_robust_hit(o, d, r1, r2)
    } else {
        method(o, d, r1, r2).map(|t| (t, point_at(o, d, t)))
    };
    let Some((_, p)) = hit else {
        return (0, 0);
    };
    let pw = [c[0] + p[0], c[1] + p[1], c[2] + p[2]];
    let n = normalize(torus_normal(p, r1, r2));
    let world = error_bound(pw, 2);
    let own = gamma::<F>(ERR_GAMMA) * (r1 + r2);
    let err = world.map(|e| e + own);
    let mut rehits = 0;
    for j in 0..SPAWNED {
        // A direction on the reflection (even j) or transmission (odd j) side
        let mut w = f(unit(rng));
        let out = w[0] * n[0] + w[1] * n[1] + w[2] * n[2] > F::ZERO;
        if out != (j % 2 == 0) {
            w = w.map(|x| -x);
        }
        let s = spawn_origin(pw, err, n, w);
        let Some(t2) = method(to_obj(s), w, r1, r2) else {
            continue;
        };
        let exact = exact_first(inst, s.map(|x| x.to_f64()), w.map(|x| x.to_f64()));
        if exact.is_none_or(|te| t2.to_f64() < 0.5 * te) {
            rehits += 1;
        }
    }
    (SPAWNED as u64, rehits)
}

/// One row per method: spawned rays and re-hits over `per_scale` instances per decade.
pub fn reintersection(seed: u64, per_scale: u64, prec: Precision) -> Vec<ReintersectRow> {
    (0..METHODS.len())
        .map(|m| {
            let (rays, rehits) = DECADES
                .flat_map(|k| (0..per_scale).map(move |i| (k, i)))
                .collect::<Vec<_>>()
                .into_par_iter()
                .map(|(k, i)| {
                    let mut rng = case_rng(seed, "torus_reintersect", &k.to_string(), prec, i);
                    let inst = instance(&mut rng, k, prec);
                    match prec {
                        Precision::F32 => run_instance::<f32>(m, &inst, &mut rng),
                        Precision::F64 => run_instance::<f64>(m, &inst, &mut rng),
                    }
                })
                .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
            ReintersectRow {
                shape: "torus",
                method: METHODS[m].name,
                precision: prec.name(),
                robust: METHODS[m].robust,
                rays,
                rehits,
                scales: [DECADES.start as f64, DECADES.end as f64],
            }
        })
        .collect()
}
