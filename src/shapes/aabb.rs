//! Ray–box (seed 002 §2.2): the chapter's face-by-face test, the classic slab test and the
//! conservative slab test of Ize 2013 / pbrt-v4, against an exact rational oracle.
//!
//! **Semantics.** The box is the closed set `[lo, hi]` (per axis `lo < hi`; the chapter's box
//! `[0, rx]×[0, ry]×[0, rz]` is `lo = 0`). The ray `o + t·d` lies in the box for `t` in a closed
//! interval `[t₀, t₁]` (possibly empty). The answer is the first surface crossing with `t > 0`:
//! the entry `t₀` when `t₀ > 0`, otherwise the exit `t₁` when `t₁ > 0` (origin inside, or on the
//! surface going in), otherwise a miss. An origin exactly on a face is a touch at `t = 0`, not a
//! crossing: going in it gives the exit, going out a miss. A ray that slides inside a face plane
//! (`dᵢ = ±0`, `oᵢ = loᵢ` or `hiᵢ`) touches the closed box and is answered the same way.
//!
//! **Invalid input** (the right answer is a rejection): a NaN or infinite scalar, `d = 0`, or
//! `loᵢ ≥ hiᵢ` on some axis (an inverted or flat box).
//!
//! **Ill-posed** (a disagreement is not a failure): some single input moved by one ulp of its
//! precision, up or down (24 moves, each decided exactly), changes the count or switches the
//! answer between the entry and the exit.

use super::oracle::sample::{self, add, cube, lu, mul, normalize, perp, rp, rpv, sub, unit};
use crate::numerics::exact;
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::oracle::ulp_box::{strict_sign as sign_on_box, ulp_box, BoxIv};
use crate::shapes::shape::{Answer, Domain, Expected, MethodInfo, Shape, ShapeInfo, Truth};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rug::Rational;

type V<F> = [F; 3];

/// **Faces**, the chapter's test: for each axis only the front-facing plane (by the sign of
/// `dᵢ`; none when `dᵢ = 0`), `t = (plane − oᵢ)/dᵢ`, kept if `t > 0` and the two other
/// coordinates of `o + t·d` lie in the face (closed); the first such face, in x, y, z order, wins.
/// - Origin inside or on a face going in: every front plane is behind, so a **miss**.
/// - Never divides by zero; NaN inputs fail every comparison (a miss).
pub fn faces<F: Real>(o: V<F>, d: V<F>, lo: V<F>, hi: V<F>) -> Option<F> {
    for i in 0..3 {
        // Front-facing plane of axis i
        let plane = if d[i] > F::ZERO {
            lo[i]
        } else if d[i] < F::ZERO {
            hi[i]
        } else {
            continue;
        };
        let t = (plane - o[i]) / d[i];
        // In-face check of the two other coordinates (NaN t fails t > 0)
        let inside = t > F::ZERO
            && (1..3).all(|k| {
                let j = (i + k) % 3;
                let p = o[j] + t * d[j];
                lo[j] <= p && p <= hi[j]
            });
        if inside {
            return Some(t);
        }
    }
    None
}

/// **Slab**, the classic test (Smits; Williams et al. 2005): `1/dᵢ`, the near and far plane
/// chosen by the sign of `1/dᵢ`, the x slab initialising `[tmin, tmax]`, then y and z narrowing
/// it with plain comparisons; `t = tmin`, or `tmax` when `tmin < 0`; a miss when `t < 0`.
/// - Origin exactly on a slab plane with `dᵢ = ±0`: `0·∞ = NaN`. On the x axis the NaN is never
///   replaced, so the answer is NaN (reported as a hit) or a miss, whatever y and z say.
/// - Origin on a face: `t = 0` is returned (a hit at the origin) instead of the exit or a miss.
pub fn slab<F: Real>(o: V<F>, d: V<F>, lo: V<F>, hi: V<F>) -> Option<F> {
    // Near and far distances of one slab
    let span = |i: usize| {
        let inv = F::ONE / d[i];
        let (near, far) = if inv < F::ZERO {
            (hi[i], lo[i])
        } else {
            (lo[i], hi[i])
        };
        ((near - o[i]) * inv, (far - o[i]) * inv)
    };
    let (mut tmin, mut tmax) = span(0);
    for i in 1..3 {
        let (a, b) = span(i);
        if tmin > b || a > tmax {
            return None;
        }
        if a > tmin {
            tmin = a;
        }
        if b < tmax {
            tmax = b;
        }
    }
    // First crossing, as the classic code picks it
    let t = if tmin < F::ZERO { tmax } else { tmin };
    if t < F::ZERO {
        None
    } else {
        Some(t)
    }
}

/// **Robust slab** (Ize 2013, pbrt-v4 `Bounds3::IntersectP`), the robust anchor and
/// [`box_robust`]: invalid input rejected up front; near and far plane chosen by the sign bit of
/// `dᵢ` (so `±0` selects like `±∞`), every far distance scaled by `1 + 2γ₃`, and the interval
/// narrowed only by comparisons that a NaN (`0·∞`, origin on a plane with `dᵢ = ±0`) fails, so
/// the NaN slab leaves the interval unconstrained, as the exact answer does.
/// - Conservative: the padding turns near-misses within about `2γ₃·t` into hits (false hits by
///   design); a computed interval is never narrower than the exact one, so no false miss.
/// - Exit `t` (origin inside) is returned padded: a few ulps above the exact value.
/// - Origin on a face: the near distance is exactly `0`, so the exit or a miss, as specified.
pub fn robust_slab<F: Real>(o: V<F>, d: V<F>, lo: V<F>, hi: V<F>) -> Option<F> {
    if !valid(o, d, lo, hi) {
        return None;
    }
    let pad = F::ONE + F::from_f64(2.0) * crate::numerics::real::gamma::<F>(3);
    let (mut t0, mut t1) = (-F::INFINITY, F::INFINITY);
    for i in 0..3 {
        // Planes by the sign bit of d, so that −0 behaves like a negative direction
        let inv = F::ONE / d[i];
        let neg = F::ONE.copysign(d[i]) < F::ZERO;
        let (near, far) = if neg { (hi[i], lo[i]) } else { (lo[i], hi[i]) };
        let tn = (near - o[i]) * inv;
        let tf = (far - o[i]) * inv * pad;
        // NaN-safe narrowing: a NaN fails the comparison and leaves the bound alone
        if tn > t0 {
            t0 = tn;
        }
        if tf < t1 {
            t1 = tf;
        }
        if t0 > t1 {
            return None;
        }
    }
    // First crossing with t > 0
    if t0 > F::ZERO {
        Some(t0)
    } else if t1 > F::ZERO && t1.is_finite() {
        Some(t1)
    } else {
        None
    }
}

/// The renderer's ray–box test: [`robust_slab`] (first surface crossing `t > 0`, the exit when
/// the origin is inside; `None` for a miss or invalid input). Conservative: a ray passing within
/// about `2γ₃·t` of an edge may be reported as a hit.
pub fn box_robust<F: Real>(o: V<F>, d: V<F>, lo: V<F>, hi: V<F>) -> Option<F> {
    robust_slab(o, d, lo, hi)
}

/// Valid input: every scalar finite, `d ≠ 0`, `loᵢ < hiᵢ` on every axis.
fn valid<F: Real>(o: V<F>, d: V<F>, lo: V<F>, hi: V<F>) -> bool {
    let finite = |v: V<F>| v.iter().all(|x| x.is_finite());
    finite(o)
        && finite(d)
        && finite(lo)
        && finite(hi)
        && d.iter().any(|&x| x != F::ZERO)
        && (0..3).all(|i| lo[i] < hi[i])
}

// ---- the exact oracle ----

/// Which surface crossing the exact answer is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Crossing {
    Miss,
    Entry,
    Exit,
}

/// The exact interval `[t₀, t₁]` of the ray inside the closed box (valid input), or `None`.
fn span_exact(v: &[f64]) -> Option<(Rational, Rational)> {
    let (mut t0, mut t1): (Option<Rational>, Option<Rational>) = (None, None);
    for i in 0..3 {
        let (o, d, lo, hi) = (v[i], v[3 + i], v[6 + i], v[9 + i]);
        if d == 0.0 {
            // Parallel slab: all t or none
            if o < lo || o > hi {
                return None;
            }
            continue;
        }
        let (qo, qd) = (exact::q(o), exact::q(d));
        let ta = (exact::q(lo) - &qo) / &qd;
        let tb = (exact::q(hi) - qo) / qd;
        let (a, b) = if ta <= tb { (ta, tb) } else { (tb, ta) };
        if t0.as_ref().is_none_or(|t| a > *t) {
            t0 = Some(a);
        }
        if t1.as_ref().is_none_or(|t| b < *t) {
            t1 = Some(b);
        }
    }
    let (t0, t1) = (t0?, t1?);
    (t0 <= t1).then_some((t0, t1))
}

fn valid_f64(v: &[f64]) -> bool {
    let a = |k: usize| [v[k], v[k + 1], v[k + 2]];
    valid(a(0), a(3), a(6), a(9))
}

/// The exact crossing and its `t` (invalid input counts as a miss, for the one-ulp moves).
fn crossing(v: &[f64]) -> (Crossing, Option<(Rational, Rational)>) {
    if !valid_f64(v) {
        return (Crossing::Miss, None);
    }
    let Some((t0, t1)) = span_exact(v) else {
        return (Crossing::Miss, None);
    };
    let c = if t0 > 0 {
        Crossing::Entry
    } else if t1 > 0 {
        Crossing::Exit
    } else {
        Crossing::Miss
    };
    (c, Some((t0, t1)))
}

/// The crossing on the whole one-ulp box of `v`, in interval arithmetic (`None`: some
/// comparison it rests on is uncertain there, or a direction component may be 0).
fn box_crossing(v: &[f64], prec: Precision) -> Option<Crossing> {
    let b = ulp_box(v, prec)?;
    let (mut t0, mut t1) = (BoxIv::point(f64::NEG_INFINITY), BoxIv::point(f64::INFINITY));
    for i in 0..3 {
        let (o, d, lo, hi) = (b[i], b[3 + i], b[6 + i], b[9 + i]);
        // Valid everywhere (lo < hi), and the slab's order known from d's sign
        if lo.hi >= hi.lo {
            return None;
        }
        let (ta, tb) = ((lo - o) / d, (hi - o) / d);
        let (a, b) = if sign_on_box(d)? > 0 {
            (ta, tb)
        } else {
            (tb, ta)
        };
        t0 = BoxIv::new(t0.lo.max(a.lo), t0.hi.max(a.hi));
        t1 = BoxIv::new(t1.lo.min(b.lo), t1.hi.min(b.hi));
    }
    // Miss when t₀ > t₁ or t₁ ≤ 0; entry when t₀ ≤ t₁ and t₀ > 0; exit when t₀ ≤ 0 < t₁
    if t0.lo > t1.hi || t1.hi <= 0.0 {
        return Some(Crossing::Miss);
    }
    if t0.hi > t1.lo || t1.lo <= 0.0 {
        return None;
    }
    match (t0.lo > 0.0, t0.hi <= 0.0) {
        (true, _) => Some(Crossing::Entry),
        (_, true) => Some(Crossing::Exit),
        _ => None,
    }
}

/// Whether a one-ulp move of one input changes the crossing.
fn ill_posed(v: &[f64], base: Crossing, prec: Precision) -> bool {
    // The whole box first, then one move at a time, each decided exactly
    if box_crossing(v, prec) == Some(base) {
        return false;
    }
    (0..v.len()).any(|i| {
        [true, false].into_iter().any(|up| {
            let mut m = v.to_vec();
            m[i] = exact::nudge(v[i], prec, up);
            crossing(&m).0 != base
        })
    })
}

/// The exact first surface crossing `t > 0` of an `f64` case rounded to `f64` (`None`: a miss
/// or invalid input), without the truth's ill-posedness: what the reintersection test asks.
pub fn first_crossing_f64(v: &[f64]) -> Option<f64> {
    match crossing(v) {
        (Crossing::Entry, Some((t0, _))) => Some(exact::round_q(&t0, Precision::F64)),
        (Crossing::Exit, Some((_, t1))) => Some(exact::round_q(&t1, Precision::F64)),
        _ => None,
    }
}

/// The exact answer of a box case.
pub fn oracle(v: &[f64], prec: Precision) -> Truth {
    if !valid_f64(v) {
        return Truth::Invalid;
    }
    let (c, span) = crossing(v);
    let ill_posed = ill_posed(v, c, prec);
    let round = |t: &Rational| exact::round_q(t, prec);
    let (count, values, others) = match (c, span) {
        (Crossing::Entry, Some((t0, t1))) => (1, vec![round(&t0)], vec![round(&t1)]),
        (Crossing::Exit, Some((t0, t1))) => (1, vec![round(&t1)], vec![round(&t0)]),
        _ => (0, vec![], vec![]),
    };
    Truth::Answer(Expected {
        count,
        values,
        others,
        ill_posed,
        cap_reached: false,
        ..Default::default()
    })
}

// ---- the shape ----

/// Ray–box as an audited routine.
pub struct BoxShape;

type BoxFn<F> = fn(V<F>, V<F>, V<F>, V<F>) -> Option<F>;

fn method<F: Real>(m: usize) -> BoxFn<F> {
    [faces::<F>, slab::<F>, robust_slab::<F>][m]
}

const METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "faces",
        robust: false,
        about: "the chapter's face-by-face test: front planes by sign of d, in-face check (§2.2)",
    },
    MethodInfo {
        name: "slab",
        robust: false,
        about: "classic slab test with 1/d and plain min/max (Smits; Williams et al. 2005)",
    },
    MethodInfo {
        name: "robust_slab",
        robust: true,
        about:
            "conservative slab: far distance × (1 + 2γ₃), NaN-safe comparisons (Ize 2013, pbrt-v4)",
    },
];

/// The class names, in order.
pub const CLASSES: &[&str] = &[
    "generic",
    "on_face_plane",
    "zero_dir",
    "grazing_edge",
    "inside",
    "behind",
    "huge",
    "tiny",
    "invalid",
];

fn run_in<F: Real>(m: usize, v: &[f64]) -> Answer {
    let a = |k: usize| [v[k], v[k + 1], v[k + 2]].map(F::from_f64);
    match method::<F>(m)(a(0), a(3), a(6), a(9)) {
        Some(t) => Answer::hit(vec![t.to_f64()]),
        None => Answer::miss(),
    }
}

const BOX: ShapeInfo = ShapeInfo {
    name: "box",
    about: "ray–box, first surface crossing t > 0 (seed 002 §2.2)",
    args: &[
        "ox", "oy", "oz", "dx", "dy", "dz", "lox", "loy", "loz", "hix", "hiy", "hiz",
    ],
    classes: CLASSES,
    methods: METHODS,
    domain: Domain::RayParameter,
    ..ShapeInfo::DEFAULTS
};

impl Shape for BoxShape {
    fn info(&self) -> &ShapeInfo {
        &BOX
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        Some(propose(CLASSES[class], prec, rng))
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        oracle(input, prec)
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => run_in::<F>(m, input))
    }
}

// ---- case generators ----

/// Scales of the ordinary classes: `10^[-2, 3)`.
const SCALES: (f64, f64) = (-2.0, 3.0);

/// A box of scale `s = 10^u`, `u` uniform in `exps`, centred within `s` of the origin:
/// `(lo, hi)` in the precision.
fn make_box(rng: &mut ChaCha8Rng, exps: (f64, f64), prec: Precision) -> ([f64; 3], [f64; 3]) {
    let s = lu(rng, exps.0, exps.1);
    let c = mul(cube(rng), s);
    let e: [f64; 3] = std::array::from_fn(|_| s * lu(rng, -1.0, 0.0));
    (rpv(prec, sub(c, e)), rpv(prec, add(c, e)))
}

/// A point of the box grown by `k` about its centre.
fn in_box(rng: &mut ChaCha8Rng, lo: [f64; 3], hi: [f64; 3], k: f64) -> [f64; 3] {
    std::array::from_fn(|i| {
        let (c, e) = (0.5 * (lo[i] + hi[i]), 0.5 * (hi[i] - lo[i]));
        c + e * k * rng.random_range(-1.0..1.0)
    })
}

fn case(o: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3], prec: Precision) -> Vec<f64> {
    let mut v = vec![];
    for a in [rpv(prec, o), rpv(prec, d), lo, hi] {
        v.extend_from_slice(&a);
    }
    v
}

/// A generic case at a scale drawn from `exps`: origin within a few scales, half the rays aimed at the box.
fn generic(rng: &mut ChaCha8Rng, exps: (f64, f64), prec: Precision) -> Vec<f64> {
    let (lo, hi) = make_box(rng, exps, prec);
    let s = sample::norm(sub(hi, lo));
    let o = mul(cube(rng), 3.0 * s * lu(rng, 0.0, 1.0));
    let d = if rng.random::<bool>() {
        normalize(sub(in_box(rng, lo, hi, 1.2), o))
    } else {
        unit(rng)
    };
    case(o, d, lo, hi, prec)
}

/// One proposal of a class.
fn propose(class: &str, prec: Precision, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let f32 = prec == Precision::F32;
    let v = match class {
        "on_face_plane" => {
            let (lo, hi) = make_box(rng, SCALES, prec);
            let mut o = in_box(rng, lo, hi, 1.5);
            let k = rng.random_range(0..3);
            o[k] = if rng.random::<bool>() { lo[k] } else { hi[k] };
            let mut d = unit(rng);
            if rng.random_range(0..4) == 0 {
                d[k] = 0.0 * sample::sign(rng);
            }
            case(o, d, lo, hi, prec)
        }
        "zero_dir" => {
            // One or two zero components (±0); half the time the origin on that slab's plane
            let (lo, hi) = make_box(rng, SCALES, prec);
            let zeros: &[usize] =
                [&[0][..], &[0, 1], &[0, 2], &[1], &[2], &[1, 2]][rng.random_range(0..6)];
            let q = in_box(rng, lo, hi, 1.2);
            let mut d = unit(rng);
            for &k in zeros {
                d[k] = 0.0;
            }
            let d = normalize(d);
            let mut o = sub(q, mul(d, rng.random_range(1.0..5.0) * (hi[0] - lo[0])));
            for &k in zeros {
                if rng.random::<bool>() {
                    o[k] = if rng.random::<bool>() { lo[k] } else { hi[k] };
                }
            }
            let mut d = d;
            for &k in zeros {
                d[k] = 0.0 * sample::sign(rng);
            }
            case(o, d, lo, hi, prec)
        }
        "grazing_edge" => {
            // A point on an edge (or a corner), moved a few ulps, approached from outside
            let (lo, hi) = make_box(rng, SCALES, prec);
            let mut q = in_box(rng, lo, hi, 1.0);
            let free = rng.random_range(0..4);
            for i in (0..3).filter(|&i| i != free) {
                let b = if rng.random::<bool>() { lo[i] } else { hi[i] };
                q[i] = sample::nudge_k(b, prec, rng.random_range(-4..=4));
            }
            let centre = in_box(rng, lo, hi, 0.0);
            let out = normalize(add(normalize(sub(q, centre)), mul(unit(rng), 0.8)));
            let l = rng.random_range(0.5..4.0) * (hi[0] - lo[0]);
            let o = add(q, mul(out, l));
            case(o, normalize(sub(q, o)), lo, hi, prec)
        }
        "inside" => {
            let (lo, hi) = make_box(rng, SCALES, prec);
            let o = in_box(rng, lo, hi, 0.999);
            case(o, unit(rng), lo, hi, prec)
        }
        "behind" => {
            // Moving away from a point of the box, from beyond its diagonal
            let (lo, hi) = make_box(rng, SCALES, prec);
            let q = in_box(rng, lo, hi, 1.0);
            let diag = sample::norm(sub(hi, lo));
            let u = unit(rng);
            let o = add(q, mul(u, diag * (1.0 + lu(rng, -0.5, 1.0))));
            let d = normalize(add(u, mul(perp(rng, u), rng.random_range(0.0..0.5))));
            case(o, d, lo, hi, prec)
        }
        "huge" => generic(rng, if f32 { (20.0, 30.0) } else { (100.0, 250.0) }, prec),
        "tiny" => generic(
            rng,
            if f32 {
                (-30.0, -20.0)
            } else {
                (-250.0, -100.0)
            },
            prec,
        ),
        "invalid" => {
            let mut v = generic(rng, SCALES, prec);
            match rng.random_range(0..4) {
                0 => v[rng.random_range(0..12)] = sample::non_finite(rng),
                1 => {
                    let k = rng.random_range(0..3);
                    v.swap(6 + k, 9 + k);
                }
                2 => {
                    let k = rng.random_range(0..3);
                    v[9 + k] = v[6 + k];
                }
                _ => {
                    for x in &mut v[3..6] {
                        *x = 0.0 * sample::sign(rng);
                    }
                }
            }
            v
        }
        _ => generic(rng, SCALES, prec),
    };
    v.into_iter().map(|x| rp(prec, x)).collect()
}
