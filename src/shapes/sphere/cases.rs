//! Named, seeded case classes for the ray–sphere audit.
//!
//! Case `i` of class `k` in precision `P` under seed `s` is drawn from its own ChaCha8 stream
//! seeded by a hash of `(s, k, P, i)`, so any case can be regenerated alone, in any order, on any
//! number of threads. A generator proposes a case; the oracle's exact quantities confirm that it
//! belongs to the class; a rejected proposal is redrawn from the same stream.

use super::oracle::{Case, Exact};
use crate::numerics::real::Real;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rug::{Float, Integer};
use serde::Serialize;
use std::cmp::Ordering;

/// Half-width, in ulps of `r`, of the "within ±k ulps" bands of `on_surface` and `tangent`.
pub const K_ULPS: f64 = 16.0;

/// The hard-case classes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    /// Origin strictly inside the sphere (1 in 16 exactly at the centre).
    Inside,
    /// Origin on the surface: exactly (Pythagorean quadruples) or within ±k ulps of `r`.
    OnSurface,
    /// Ray tangent to the sphere ahead of the origin: exactly, or within ±k ulps of `r`.
    Tangent,
    /// Origin outside and the whole sphere behind it.
    Behind,
    /// A sphere whose radius is 1e-6 … 1e-2 of its distance, aimed at within 1.5 radii.
    FarSmall,
    /// Radius ≥ 1e4 with the origin at most 1e-3·r above the surface (a sphere used as a floor).
    Huge,
    /// Ray passing within 1e-3·r of the limb but farther than the tangent band.
    Grazing,
    /// General position over six decades of scale.
    Random,
    /// NaN/±inf components, zero direction, zero/negative/NaN radius, subnormal inputs.
    Invalid,
}

impl Class {
    /// Every class, in report order.
    pub const ALL: [Class; 9] = [
        Class::Inside,
        Class::OnSurface,
        Class::Tangent,
        Class::Behind,
        Class::FarSmall,
        Class::Huge,
        Class::Grazing,
        Class::Random,
        Class::Invalid,
    ];
    /// The class's name (`--class`).
    pub const fn name(self) -> &'static str {
        match self {
            Class::Inside => "inside",
            Class::OnSurface => "on_surface",
            Class::Tangent => "tangent",
            Class::Behind => "behind",
            Class::FarSmall => "far_small",
            Class::Huge => "huge",
            Class::Grazing => "grazing",
            Class::Random => "random",
            Class::Invalid => "invalid",
        }
    }
    /// The class of this name.
    pub fn from_name(s: &str) -> Option<Class> {
        Class::ALL.into_iter().find(|c| c.name() == s)
    }
}

/// The stream of case `index` of `class` in precision `F` under `seed`.
pub fn case_rng<F: Real>(seed: u64, class: Class, index: u64) -> ChaCha8Rng {
    let mut h = seed ^ 0x9e37_79b9_7f4a_7c15;
    for w in [class as u64 + 1, F::MANT_BITS as u64, index] {
        h = splitmix(h ^ w);
    }
    ChaCha8Rng::seed_from_u64(h)
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Proposals a generator may make before giving up on a case.
const MAX_ATTEMPTS: usize = 200;

/// Generates case `index` of `class`: the first proposal the oracle confirms as a member.
/// Returns `None` only if `MAX_ATTEMPTS` proposals were all rejected (counted by the audit).
pub fn generate<F: Real>(seed: u64, class: Class, index: u64) -> Option<Case<F>> {
    generate_from(&mut case_rng::<F>(seed, class, index), class)
}

/// The first proposal drawn from `rng` that the oracle confirms as a member of `class`.
pub fn generate_from<F: Real>(rng: &mut ChaCha8Rng, class: Class) -> Option<Case<F>> {
    (0..MAX_ATTEMPTS)
        .map(|_| propose::<F>(rng, class))
        .find(|c| is_member(c, class))
}

// ---- sampling helpers (all in f64, rounded once to F) ----
use crate::numerics::vec3::{add, scale as mul, sub};

fn lu(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    10f64.powf(rng.random_range(lo..hi))
}
fn unit(rng: &mut ChaCha8Rng) -> [f64; 3] {
    loop {
        let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = norm(v);
        if n > 1e-3 && n <= 1.0 {
            return mul(v, 1.0 / n);
        }
    }
}
fn ball(rng: &mut ChaCha8Rng) -> [f64; 3] {
    mul(unit(rng), rng.random::<f64>().cbrt())
}
fn cube(rng: &mut ChaCha8Rng) -> [f64; 3] {
    std::array::from_fn(|_| rng.random_range(-1.0..1.0))
}
fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}
fn normalize(v: [f64; 3]) -> [f64; 3] {
    mul(v, 1.0 / norm(v))
}
/// A random unit vector perpendicular to the unit vector `d`.
fn perp(rng: &mut ChaCha8Rng, d: [f64; 3]) -> [f64; 3] {
    loop {
        let u = unit(rng);
        let k = u[0] * d[0] + u[1] * d[1] + u[2] * d[2];
        let p = sub(u, mul(d, k));
        if norm(p) > 0.1 {
            return normalize(p);
        }
    }
}
fn to_f<F: Real>(v: [f64; 3]) -> [F; 3] {
    v.map(F::from_f64)
}
/// Moves `x` by `k` ulps of its own precision.
fn nudge<F: Real>(mut x: F, k: i32) -> F {
    for _ in 0..k.abs() {
        x = if k > 0 { x.next_up() } else { x.next_down() };
    }
    x
}

/// Integer quadruples a² + b² + c² = m², for points exactly on a sphere.
const QUADRUPLES: [[i32; 4]; 10] = [
    [3, 4, 0, 5],
    [2, 2, 1, 3],
    [2, 3, 6, 7],
    [1, 4, 8, 9],
    [4, 4, 7, 9],
    [2, 6, 9, 11],
    [6, 6, 7, 11],
    [3, 4, 12, 13],
    [2, 10, 11, 15],
    [1, 12, 12, 17],
];
/// Integer triples with a zero component, for exact tangents to an axis-aligned ray.
const TRIPLES: [[i32; 3]; 4] = [[3, 4, 5], [5, 12, 13], [8, 15, 17], [0, 1, 1]];

/// A random signed permutation of an integer vector.
fn shuffle_signs(rng: &mut ChaCha8Rng, v: [i32; 3]) -> [f64; 3] {
    let perm = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ][rng.random_range(0..6)];
    std::array::from_fn(|i| {
        let s = if rng.random::<bool>() { -1.0 } else { 1.0 };
        s * v[perm[i]] as f64
    })
}

fn subnormal_scale<F: Real>() -> f64 {
    if F::MANT_BITS == 24 {
        1e-41
    } else {
        1e-315
    }
}

/// One proposal for a class (not yet confirmed). Each class draws from `rng` in its own fixed
/// order, so a case is bit-identical for every seed across versions: keep the draws in order.
fn propose<F: Real>(rng: &mut ChaCha8Rng, class: Class) -> Case<F> {
    match class {
        Class::Random => propose_random(rng),
        Class::Inside => propose_inside(rng),
        Class::OnSurface => propose_on_surface(rng),
        Class::Tangent => propose_tangent(rng),
        Class::Behind => propose_behind(rng),
        Class::FarSmall => propose_far_small(rng),
        Class::Huge => propose_huge(rng),
        Class::Grazing => propose_grazing(rng),
        Class::Invalid => propose_invalid(rng),
    }
}

/// A case from `f64` values, each rounded once to `F`.
fn mk<F: Real>(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Case<F> {
    Case::<F> {
        o: to_f(o),
        d: to_f(d),
        c: to_f(c),
        r: F::from_f64(r),
    }
}

/// [`Class::Random`]: general position.
fn propose_random<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    // Scene scale s, sphere within it, origin up to 10 s away, half the rays aimed
    let s = lu(rng, -2.0, 3.0);
    let c = mul(cube(rng), s);
    let r = s * lu(rng, -2.0, 0.0);
    let o = mul(cube(rng), s * lu(rng, 0.0, 1.0));
    let d = if rng.random::<bool>() {
        normalize(sub(add(c, mul(ball(rng), 1.5 * r)), o))
    } else {
        unit(rng)
    };
    mk(o, d, c, r)
}

/// [`Class::Inside`]: origin strictly inside, 1 in 16 at the centre.
fn propose_inside<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    let s = lu(rng, -2.0, 3.0);
    let c = mul(cube(rng), s);
    let r = s * lu(rng, -1.0, 0.0);
    let o = if rng.random_range(0..16) == 0 {
        c
    } else {
        add(c, mul(ball(rng), 0.999 * r))
    };
    mk(o, unit(rng), c, r)
}

/// [`Class::OnSurface`]: 1 in 4 exactly on the sphere, the rest within a few ulps of it.
fn propose_on_surface<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    if rng.random_range(0..4) == 0 {
        // Exactly on the sphere: o = c + (a,b,c)·2^k with |(a,b,c)| = m, r = m·2^k
        let q = QUADRUPLES[rng.random_range(0..QUADRUPLES.len())];
        let scale = 2f64.powi(rng.random_range(-10..10));
        let c = std::array::from_fn(|_| rng.random_range(-100..100) as f64 * scale);
        let o = add(c, mul(shuffle_signs(rng, [q[0], q[1], q[2]]), scale));
        mk(o, unit(rng), c, q[3] as f64 * scale)
    } else {
        // Rounded surface point, then up to ±3 ulps per coordinate
        let s = lu(rng, -2.0, 3.0);
        let c = mul(cube(rng), s);
        let r = s * lu(rng, -1.0, 0.0);
        let mut case = mk(add(c, mul(unit(rng), r)), unit(rng), c, r);
        for x in case.o.iter_mut() {
            *x = nudge(*x, rng.random_range(-3..=3));
        }
        case
    }
}

/// [`Class::Tangent`]: 1 in 4 exactly tangent, the rest within a few ulps of it.
fn propose_tangent<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    if rng.random_range(0..4) == 0 {
        // Exactly tangent: axis-aligned d, offset (a,b,0)·2^k with |(a,b)| = m = r/2^k
        let t = TRIPLES[rng.random_range(0..TRIPLES.len())];
        let axis = rng.random_range(0..3);
        let scale = 2f64.powi(rng.random_range(-10..10));
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut off = [0.0; 3];
        off[i] = t[0] as f64 * scale * if rng.random::<bool>() { 1.0 } else { -1.0 };
        off[j] = t[1] as f64 * scale * if rng.random::<bool>() { 1.0 } else { -1.0 };
        let mut d = [0.0; 3];
        d[axis] = if rng.random::<bool>() { 1.0 } else { -1.0 };
        let c: [f64; 3] = std::array::from_fn(|_| rng.random_range(-100..100) as f64 * scale);
        let back = rng.random_range(1..64) as f64 * scale;
        let o = sub(add(c, off), mul(d, back));
        mk(o, d, c, t[2] as f64 * scale)
    } else {
        // Rounded tangent: o = c + r·n⊥ − L·d, optionally nudged by ±k/2 ulps
        let s = lu(rng, -2.0, 3.0);
        let c = if rng.random::<bool>() {
            [0.0; 3]
        } else {
            mul(cube(rng), s)
        };
        let r = s * lu(rng, -1.0, 0.0);
        let d = unit(rng);
        let n = perp(rng, d);
        let o = sub(add(c, mul(n, r)), mul(d, r * rng.random_range(0.5..4.0)));
        let mut case = mk(o, d, c, r);
        case.r = nudge(case.r, rng.random_range(-8..=8));
        case
    }
}

/// [`Class::Behind`]: origin outside, the whole sphere behind it.
fn propose_behind<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    let s = lu(rng, -2.0, 3.0);
    let c = mul(cube(rng), s);
    let r = s * lu(rng, -2.0, 0.0);
    let dist = r * lu(rng, 0.05, 3.0);
    let away = unit(rng);
    let o = add(c, mul(away, dist));
    // Directions within the cone that keeps the whole sphere behind
    let half = (r / dist).asin();
    let spread = ((std::f64::consts::FRAC_PI_2 - half) * rng.random::<f64>()).tan();
    let d = normalize(add(away, mul(perp(rng, away), spread)));
    mk(o, d, c, r)
}

/// [`Class::FarSmall`]: a small, distant sphere, aimed at.
fn propose_far_small<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    let r = lu(rng, -3.0, 2.0);
    let dist = r / lu(rng, -6.0, -2.0);
    let o = mul(cube(rng), lu(rng, -1.0, 1.0));
    let c = add(o, mul(unit(rng), dist));
    let target = add(c, mul(ball(rng), 1.5 * r));
    mk(o, normalize(sub(target, o)), c, r)
}

/// [`Class::Huge`]: a sphere used as a floor, the origin just above it.
fn propose_huge<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    let r = lu(rng, 4.0, 6.5);
    let c = add([0.0, -r, 0.0], mul(cube(rng), 10.0));
    // Height above the surface, down to where f32/f64 can no longer tell it from 0
    let eps = 2f64.powi(1 - F::MANT_BITS as i32);
    let h = r * lu(rng, eps.log10() - 1.0, -3.0);
    let up = normalize(add([0.0, 1.0, 0.0], mul(cube(rng), 0.01)));
    let o = add(c, mul(up, r + h));
    let d = if rng.random_range(0..5) < 3 {
        // Looking down at the floor
        let mut v = unit(rng);
        v[1] = -v[1].abs();
        v
    } else {
        // Near the horizon, up to 0.1 rad either side
        let tilt = lu(rng, -4.0, -1.0) * if rng.random::<bool>() { 1.0 } else { -1.0 };
        normalize(add(perp(rng, up), mul(up, tilt)))
    };
    mk(o, d, c, r)
}

/// [`Class::Grazing`]: a ray near the limb, outside the tangent band.
fn propose_grazing<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    let s = lu(rng, -2.0, 3.0);
    let c = if rng.random::<bool>() {
        [0.0; 3]
    } else {
        mul(cube(rng), s)
    };
    let r = s * lu(rng, -1.0, 0.0);
    let d = unit(rng);
    let n = perp(rng, d);
    let lo = (2.0 * K_ULPS * 2f64.powi(1 - F::MANT_BITS as i32)).log10() + 0.3;
    let h = r * (1.0 + lu(rng, lo, -3.0) * if rng.random::<bool>() { 1.0 } else { -1.0 });
    let o = sub(add(c, mul(n, h)), mul(d, r * rng.random_range(0.5..4.0)));
    mk(o, d, c, r)
}

/// [`Class::Invalid`]: a random case with one value spoiled.
fn propose_invalid<F: Real>(rng: &mut ChaCha8Rng) -> Case<F> {
    let mut case = propose_random::<F>(rng);
    let mut s = case.scalars();
    let i = rng.random_range(0..10);
    let tiny = subnormal_scale::<F>();
    match rng.random_range(0..10) {
        0 => s[i] = F::NAN,
        1 => s[i] = F::INFINITY,
        2 => s[i] = -F::INFINITY,
        3 => (3..6).for_each(|k| s[k] = F::ZERO),
        4 => s[9] = F::ZERO,
        5 => s[9] = -s[9],
        6 => s[9] = F::NAN,
        // A whole subnormal direction: valid, but |d|² underflows to 0
        7 => (3..6).for_each(|k| s[k] = F::from_f64(s[k].to_f64() * tiny)),
        // A whole scene at subnormal scale
        8 => s
            .iter_mut()
            .for_each(|x| *x = F::from_f64(x.to_f64() / (1e4 * case.r.to_f64()) * tiny * 1e3)),
        // One subnormal direction component
        _ => s[3 + i % 3] = F::from_f64(tiny),
    }
    case = Case::from_scalars(s);
    case
}

/// High-precision geometry of a valid case, in units of `r`'s ulp and of `r`.
struct Geometry {
    /// `(|o − c| − r) / ulp(r)`
    surface_ulps: f64,
    /// `(h − r) / ulp(r)` with `h` the distance from the centre to the ray line
    tangent_ulps: f64,
    /// `(|o − c| − r) / r`
    height_rel: f64,
    /// `(h − r) / r`
    perp_rel: f64,
    /// `r / |o − c|`
    size_ratio: f64,
}

fn geometry<F: Real>(case: &Case<F>, ex: &Exact) -> Geometry {
    const P: u32 = 320;
    let fl = |x: &Integer| Float::with_val(P, x);
    let f: Vec<Float> = (0..3).map(|i| fl(&ex.o[i]) - fl(&ex.center[i])).collect();
    let f2 = Float::with_val(P, &f[0] * &f[0])
        + Float::with_val(P, &f[1] * &f[1])
        + Float::with_val(P, &f[2] * &f[2]);
    let dist = f2.clone().sqrt();
    // h² = |f|² − B'²/A
    let h2 = f2 - fl(&ex.bh).square() / fl(&ex.a);
    let h = if h2.is_sign_negative() {
        Float::with_val(P, 0)
    } else {
        h2.sqrt()
    };
    let r = fl(&ex.r);
    // ulp(r) in the scaled units: ulp(r_float) · (r_scaled / r_float)
    let ulp_scaled = Float::with_val(P, &r) * (super::oracle::ulp(case.r) / case.r.to_f64());
    let rel = |x: &Float| Float::with_val(P, x - &r);
    Geometry {
        surface_ulps: (rel(&dist) / &ulp_scaled).to_f64(),
        tangent_ulps: (rel(&h) / &ulp_scaled).to_f64(),
        height_rel: (rel(&dist) / &r).to_f64(),
        perp_rel: (rel(&h) / &r).to_f64(),
        size_ratio: (Float::with_val(P, &r) / &dist).to_f64(),
    }
}

fn has_subnormal<F: Real>(case: &Case<F>) -> bool {
    let min_normal = if F::MANT_BITS == 24 {
        f32::MIN_POSITIVE as f64
    } else {
        f64::MIN_POSITIVE
    };
    case.scalars().iter().any(|x| {
        let v = x.to_f64().abs();
        v != 0.0 && v < min_normal
    })
}

/// Is the case a member of the class, by the oracle's exact quantities?
pub fn is_member<F: Real>(case: &Case<F>, class: Class) -> bool {
    if class == Class::Invalid {
        return !case.is_valid() || has_subnormal(case);
    }
    if !case.is_valid() || has_subnormal(case) {
        return false;
    }
    let ex = Exact::new(case);
    let (c, bh) = (ex.c.cmp0(), ex.bh.cmp0());
    match class {
        Class::Random => true,
        Class::Inside => c == Ordering::Less,
        Class::Behind => {
            // Wholly behind: B' > r·|d|, i.e. B' > 0 and B'² > r²·A
            let rr = Integer::from(&ex.r * &ex.r);
            bh == Ordering::Greater
                && c == Ordering::Greater
                && Integer::from(&ex.bh * &ex.bh) > rr * &ex.a
        }
        _ => {
            let g = geometry(case, &ex);
            match class {
                Class::OnSurface => g.surface_ulps.abs() <= K_ULPS,
                Class::Tangent => {
                    c == Ordering::Greater && bh == Ordering::Less && g.tangent_ulps.abs() <= K_ULPS
                }
                Class::Grazing => {
                    c == Ordering::Greater
                        && bh == Ordering::Less
                        && g.tangent_ulps.abs() > K_ULPS
                        && g.perp_rel.abs() <= 1e-3
                }
                Class::FarSmall => {
                    c == Ordering::Greater && (5e-7..=1.05e-2).contains(&g.size_ratio)
                }
                Class::Huge => {
                    case.r.to_f64() >= 1e4 && c == Ordering::Greater && g.height_rel <= 1e-3
                }
                _ => unreachable!("handled above"),
            }
        }
    }
}
