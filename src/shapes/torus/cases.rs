//! Seeded hard-case classes for the ray–torus audit.
//!
//! Every generator works in `f64` and rounds each of the eight scalars once to the case's
//! precision; the oracle then decides the exact answer (a generator never claims one). Radii
//! are drawn log-uniformly, `r1 ∈ 2^[−2, 2]`, so the cases span scales without
//! over- or underflowing the quartic's fourth powers in `f32`.

use crate::numerics::Precision;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;

/// Class names, in the order of [`generate`]'s index.
pub const CLASSES: [&str; 8] = [
    "generic",
    "grazing",
    "hole",
    "inside_tube",
    "far",
    "thin",
    "fat",
    "invalid",
];

type V = [f64; 3];
use crate::numerics::vec3::{add, scale, sub};

/// `x` rounded to the precision (as `f64`).
pub fn round_to(x: f64, prec: Precision) -> f64 {
    match prec {
        Precision::F32 => x as f32 as f64,
        Precision::F64 => x,
    }
}

/// A uniformly random unit vector.
pub fn unit(rng: &mut ChaCha8Rng) -> V {
    loop {
        let v = [
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ];
        let n2: f64 = v.iter().map(|x| x * x).sum();
        if n2 > 1e-4 && n2 <= 1.0 {
            return scale(v, 1.0 / n2.sqrt());
        }
    }
}

fn log2_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo..hi).exp2()
}

/// A uniform point in the torus' bounding box.
fn in_box(rng: &mut ChaCha8Rng, r1: f64, r2: f64) -> V {
    let big = r1 + r2;
    [
        rng.random_range(-big..big),
        rng.random_range(-big..big),
        rng.random_range(-r2..r2),
    ]
}

/// A point of the torus surface at angles `θ` (around z) and `φ` (around the tube), with the
/// outward unit normal and the two unit tangents there.
pub fn surface_frame(r1: f64, r2: f64, theta: f64, phi: f64) -> (V, V, V, V) {
    let u = [theta.cos(), theta.sin(), 0.0];
    let n = [phi.cos() * u[0], phi.cos() * u[1], phi.sin()];
    let p = add(scale(u, r1), scale(n, r2));
    let t1 = [-theta.sin(), theta.cos(), 0.0];
    let t2 = [-phi.sin() * u[0], -phi.sin() * u[1], phi.cos()];
    (p, n, t1, t2)
}

/// The eight scalars `o d r1 r2`, each rounded once to the precision.
fn pack(o: V, d: V, r1: f64, r2: f64, prec: Precision) -> Vec<f64> {
    [o[0], o[1], o[2], d[0], d[1], d[2], r1, r2]
        .into_iter()
        .map(|x| round_to(x, prec))
        .collect()
}

/// A ray from `o` aimed at `target` (direction `target − o`, not normalised).
fn aimed(o: V, target: V, r1: f64, r2: f64, prec: Precision) -> Vec<f64> {
    pack(o, sub(target, o), r1, r2, prec)
}

/// `r1` log-uniform in `2^[−2, 2]` and `r2 = r1·U[lo, hi]`.
fn radii(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> (f64, f64) {
    let r1 = log2_uniform(rng, -2.0, 2.0);
    (r1, r1 * rng.random_range(lo..hi))
}

/// Origin uniform in a cube of half-size `k·(r1 + r2)`, aimed at a uniform point of the box.
fn generic(rng: &mut ChaCha8Rng, prec: Precision, r1: f64, r2: f64, k: f64) -> Vec<f64> {
    let big = k * (r1 + r2);
    let o = [
        rng.random_range(-big..big),
        rng.random_range(-big..big),
        rng.random_range(-big..big),
    ];
    aimed(o, in_box(rng, r1, r2), r1, r2, prec)
}

/// Nearly tangent to the tube: a tangent line at a random surface point, moved off along the
/// normal by `±r2·2^−s`, `s ∈ [4, p − 6]` (p the significand bits): two close roots or none.
fn grazing(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let (r1, r2) = radii(rng, 0.2, 0.8);
    let (p, n, t1, t2) = surface_frame(
        r1,
        r2,
        rng.random_range(0.0..TAU),
        rng.random_range(0.0..TAU),
    );
    let a = rng.random_range(0.0..TAU);
    let w = add(scale(t1, a.cos()), scale(t2, a.sin()));
    let bits = match prec {
        Precision::F32 => 24.0,
        Precision::F64 => 53.0,
    };
    let h =
        r2 * (-rng.random_range(4.0..bits - 6.0f64)).exp2() * if rng.random() { 1.0 } else { -1.0 };
    let o = sub(
        add(p, scale(n, h)),
        scale(w, r1 * rng.random_range(1.0..4.0)),
    );
    pack(o, w, r1, r2, prec)
}

/// Through the hole: origin above or below, near the axis, aimed at a point of the hole disk
/// (some at the inner wall); one case in eight exactly on the axis along ∓z.
fn hole(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let (r1, r2) = radii(rng, 0.1, 0.8);
    let side = if rng.random() { 1.0 } else { -1.0 };
    let z0 = side * r2 * rng.random_range(1.5..6.0);
    if rng.random_range(0..8) == 0 {
        return pack([0.0, 0.0, z0], [0.0, 0.0, -side], r1, r2, prec);
    }
    let inner = r1 - r2;
    let j = 0.5 * inner;
    let o = [rng.random_range(-j..j), rng.random_range(-j..j), z0];
    let (rho, th) = (
        inner * rng.random_range(0.0..1.1),
        rng.random_range(0.0..TAU),
    );
    aimed(o, [rho * th.cos(), rho * th.sin(), 0.0], r1, r2, prec)
}

/// Origin inside the tube (depth up to 0.95·r2 from the tube's centre circle), any direction.
fn inside_tube(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let (r1, r2) = radii(rng, 0.1, 0.9);
    let depth = r2 * rng.random_range(0.0..0.95);
    // A point of the torus with minor radius `depth` is that far from the centre circle
    let (o, ..) = surface_frame(
        r1,
        depth,
        rng.random_range(0.0..TAU),
        rng.random_range(0.0..TAU),
    );
    pack(o, unit(rng), r1, r2, prec)
}

/// Origin at `10^[2, 4]·r1` in a random direction, aimed at a uniform point of the box.
fn far(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let (r1, r2) = radii(rng, 0.1, 0.9);
    let dist = r1 * 10f64.powf(rng.random_range(2.0..4.0));
    let o = scale(unit(rng), dist);
    aimed(o, in_box(rng, r1, r2), r1, r2, prec)
}

/// `r2 = r1·10^−3·2^[−1, 1]`; origin in a cube of half-size `3r1`, aimed within `1.5·r2` of a
/// point of the tube's centre circle (otherwise nearly every ray would miss).
fn thin(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let r1 = log2_uniform(rng, -2.0, 2.0);
    let r2 = r1 * 1e-3 * log2_uniform(rng, -1.0, 1.0);
    let b = 3.0 * r1;
    let o = [
        rng.random_range(-b..b),
        rng.random_range(-b..b),
        rng.random_range(-b..b),
    ];
    let th = rng.random_range(0.0..TAU);
    let c = [r1 * th.cos(), r1 * th.sin(), 0.0];
    let target = add(
        c,
        scale(unit(rng), 1.5 * r2 * rng.random_range(0.0..1.0f64).cbrt()),
    );
    aimed(o, target, r1, r2, prec)
}

/// `r2 = r1·(1 − 2^−s)`, `s ∈ [2, 10]`: a tube nearly closing the hole.
fn fat(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let r1 = log2_uniform(rng, -2.0, 2.0);
    let r2 = r1 * (1.0 - (-rng.random_range(2.0..10.0f64)).exp2());
    generic(rng, prec, r1, r2, 3.0)
}

/// A generic case broken one way: NaN or ±inf in a random input, `r2 ≤ 0`, `r1 ≤ 0`,
/// `r2 ≥ r1` (horn or spindle torus), or a zero direction.
fn invalid(rng: &mut ChaCha8Rng, prec: Precision) -> Vec<f64> {
    let (r1, r2) = radii(rng, 0.1, 0.9);
    let mut x = generic(rng, prec, r1, r2, 3.0);
    let i = rng.random_range(0..8);
    match rng.random_range(0..7) {
        0 => x[i] = f64::NAN,
        1 => {
            x[i] = if rng.random() {
                f64::INFINITY
            } else {
                f64::NEG_INFINITY
            }
        }
        2 => x[7] = if rng.random() { 0.0 } else { -x[7] },
        3 => x[6] = if rng.random() { 0.0 } else { -x[6] },
        4 => x[7] = round_to(x[6] * rng.random_range(1.0..2.0), prec),
        5 => x[7] = x[6],
        _ => x[3..6].fill(0.0),
    }
    x
}

/// Case of class `class` (index into [`CLASSES`]).
pub fn generate(class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
    Some(match class {
        0 => {
            let (r1, r2) = radii(rng, 0.1, 0.9);
            generic(rng, prec, r1, r2, 4.0)
        }
        1 => grazing(rng, prec),
        2 => hole(rng, prec),
        3 => inside_tube(rng, prec),
        4 => far(rng, prec),
        5 => thin(rng, prec),
        6 => fat(rng, prec),
        7 => invalid(rng, prec),
        _ => return None,
    })
}
