//! Sampling helpers shared by the box and quadric case generators and the reintersection test:
//! every value is drawn in `f64` and rounded once to the case's precision.

use crate::numerics::exact;
pub use crate::numerics::vec3::{add, cross, dot, scale as mul, sub};
use crate::numerics::Precision;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

pub type V = [f64; 3];

/// `10^u`, `u` uniform in `[lo, hi)` (log-uniform magnitudes).
pub fn lu(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    10f64.powf(rng.random_range(lo..hi))
}
/// ±1 with equal odds.
pub fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.random::<bool>() {
        1.0
    } else {
        -1.0
    }
}
/// A uniform point of `[-1, 1]³`.
pub fn cube(rng: &mut ChaCha8Rng) -> V {
    std::array::from_fn(|_| rng.random_range(-1.0..1.0))
}
/// A uniform unit vector.
pub fn unit(rng: &mut ChaCha8Rng) -> V {
    loop {
        let v = cube(rng);
        let n = norm(v);
        if n > 1e-3 && n <= 1.0 {
            return mul(v, 1.0 / n);
        }
    }
}
/// A uniform point of the unit ball.
pub fn ball(rng: &mut ChaCha8Rng) -> V {
    mul(unit(rng), rng.random::<f64>().cbrt())
}
/// A random unit vector perpendicular to `v` (any length).
/// Where a scene of size `s` sits: `near` the origin (within 4 s of it) or `far` (10³–10⁵ s
/// away, in a random direction): the placements of the robustness audits (spawn, guard, once).
pub fn placed(rng: &mut ChaCha8Rng, placement: &str, s: f64) -> V {
    match placement {
        "near" => mul(ball(rng), 4.0 * s),
        _ => mul(unit(rng), s * lu(rng, 3.0, 5.0)),
    }
}

/// A random point of a triangle, away from its edges: barycentrics u, v in [0.02, 0.96], folded
/// back when u + v > 0.95.
pub fn point_in(rng: &mut ChaCha8Rng, tri: &[V; 3]) -> V {
    let (u, v): (f64, f64) = (rng.random_range(0.02..0.96), rng.random_range(0.02..0.96));
    let (u, v) = if u + v > 0.95 {
        (1.0 - u, 1.0 - v)
    } else {
        (u, v)
    };
    std::array::from_fn(|k| tri[0][k] + u * (tri[1][k] - tri[0][k]) + v * (tri[2][k] - tri[0][k]))
}

pub fn perp(rng: &mut ChaCha8Rng, v: V) -> V {
    let d = normalize(v);
    loop {
        let u = unit(rng);
        let p = sub(u, mul(d, dot(u, d)));
        if norm(p) > 0.1 {
            return normalize(p);
        }
    }
}
/// `|a|`, scaled by its largest component first so that `|a|²` cannot over- or underflow.
pub fn norm(a: V) -> f64 {
    let big = a.iter().fold(0f64, |m, x| m.max(x.abs()));
    if big == 0.0 {
        return 0.0;
    }
    let u = mul(a, 1.0 / big);
    big * dot(u, u).sqrt()
}
pub fn normalize(a: V) -> V {
    let big = a.iter().fold(0f64, |m, x| m.max(x.abs()));
    let a = mul(a, 1.0 / big);
    mul(a, 1.0 / norm(a))
}
/// `x` rounded to the precision (an `f32` widened exactly).
pub fn rp(prec: Precision, x: f64) -> f64 {
    match prec {
        Precision::F32 => x as f32 as f64,
        Precision::F64 => x,
    }
}
pub fn rpv(prec: Precision, v: V) -> V {
    v.map(|x| rp(prec, x))
}
/// `x` moved by `k` ulps of the precision.
pub fn nudge_k(mut x: f64, prec: Precision, k: i32) -> f64 {
    for _ in 0..k.unsigned_abs() {
        x = exact::nudge(x, prec, k > 0);
    }
    x
}
/// An invalid scalar: NaN, +inf or −inf.
pub fn non_finite(rng: &mut ChaCha8Rng) -> f64 {
    [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][rng.random_range(0..3)]
}
