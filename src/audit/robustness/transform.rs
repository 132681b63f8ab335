//! Shapes behind an instance transform (issue 49, item 2): the ray carried into object space by
//! an affine world-to-object matrix in the working precision, as a renderer carries it, the
//! routine run there, its `t` taken back (an affine map keeps `t`: o + t·d maps to o' + t·d').
//!
//! **Instances.** An object (a sphere: centre within 0.5 of the origin, radius 0.5–1; a
//! triangle: three points of the unit ball, not thin) and an object-to-world matrix
//! M = [L | T], every entry a value of the precision. The renderer's world-to-object matrix
//! W = [L_W | b_W] is M⁻¹ computed exactly and rounded once to the precision: the best inverse
//! it could be given. Classes of M:
//! - `rotation`: a rotation by a random angle about a random axis (its entries are cosines and
//!   sines rounded: not exactly orthogonal), translation within 4 object sizes;
//! - `translation`: the rotation and a translation of 10³–10⁷ object sizes;
//! - `tiny_scale`, `huge_scale`: the rotation and a uniform scale of 10⁻⁸–10⁻³ or 10³–10⁸;
//! - `non_uniform`: scales 1, 10^a, 10^b along rotated axes, a, b ∈ [−4, 4];
//! - `near_singular`: R₁ · diag(1, 1, ε) · R₂, ε ∈ 10⁻⁶–10⁻³ (a flattened instance).
//!
//! **Rays** are made in object space, half of them aimed near the boundary (a sphere's impact
//! parameter h = r(1 ± 10^−u), a triangle's point 10^−u outside or inside an edge, u ∈ [1, 3]),
//! half anywhere over the object and around it; carried to world space by M and rounded to the
//! precision. Then the **exact oracle in world space**: the world ray as given is carried back by
//! M⁻¹ exactly (rationals), and the object's exact answer found there. A case is judged only when
//! it is well posed: a triangle's exact barycentrics all at least 10⁻⁴ from 0, a sphere's
//! 1 − h²/r² at least 10⁻⁴ from 0 (affine maps keep barycentrics, so the margin is the world
//! instance's too). The others are counted in `ill_posed`.
//!
//! **Modes** of carrying the origin: `matrix`, o' = L_W·o + b_W (the 3×4 product renderers
//! store), and `translate_first`, o' = L_W·(o − T) with M's own translation T. For an origin
//! near a far instance the subtraction o − T is exact (Sterbenz), where L_W·o + b_W cancels two
//! large numbers. The direction is d' = L_W·d in both. A renderer given M without its inverse
//! computes it: `inverted` is W found in the working precision, L_W the adjugate of L over its
//! determinant (the rows are cross products of L's columns, each divided by det = c₀·(c₁×c₂))
//! and b_W = −L_W·T, then carried as `matrix` carries; its rounding adds cond(L)·ε to the
//! stored inverse's. Sums are in order, with no FMA. The
//! yardstick `ideal` is the object-space ray computed exactly (M⁻¹ in rationals) and rounded
//! once to the precision (through f64): what remains there is the routine's own error on a
//! rounded ray, and what `matrix` and `translate_first` add beyond it is the carrying's: the
//! stored W, rounded, is off by up to cond(L)·ε in its action on a ray.
//!
//! **Rows** per routine × mode × precision × class: well-posed cases, false hits, false misses,
//! the worst error of `t` in ulps of the precision (over cases both call a hit), and the first
//! wrong case as a `rayproof transform --replay` line (hex floats). The rows are reported.

use crate::audit::Method;
use crate::numerics::exact::ulp;
use crate::numerics::Precision;
use crate::shapes::oracle::sample::{self, ball, cross, dot, lu, mul, normalize, sub, unit, V};
use crate::shapes::shape::{case_rng, hex_text};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use rug::{Float, Rational};
use serde::{Deserialize, Serialize};

/// The classes of transforms.
pub const CLASSES: [&str; 6] = [
    "rotation",
    "translation",
    "tiny_scale",
    "huge_scale",
    "non_uniform",
    "near_singular",
];
/// How the ray's origin is carried into object space.
pub const MODES: [&str; 4] = ["matrix", "translate_first", "inverted", "ideal"];
/// The margin a judged case keeps from the boundary (barycentrics, 1 − h²/r²).
pub const MARGIN: f64 = 1e-4;

/// A 3×4 affine matrix: rows of `[L | T]`.
pub type Affine = [[f64; 4]; 3];

/// One instance and ray: the object's inputs (sphere `c r`, triangle `p0 p1 p2`), M, and the
/// world ray, every value one of the precision.
#[derive(Clone, Debug)]
pub struct Case {
    /// `sphere` or `triangle`.
    pub shape: &'static str,
    /// The object's inputs after the ray's six in the shape's order (4 or 9 values).
    pub object: Vec<f64>,
    /// Object to world.
    pub m: Affine,
    /// World-space origin.
    pub o: V,
    /// World-space direction.
    pub d: V,
}

impl Case {
    /// The replay values: M's 12 entries, o, d, the object.
    pub fn values(&self) -> Vec<f64> {
        self.m
            .iter()
            .flatten()
            .chain(&self.o)
            .chain(&self.d)
            .chain(&self.object)
            .copied()
            .collect()
    }

    /// The case of replay values (`values`), or why not.
    pub fn from_values(shape: &'static str, v: &[f64]) -> Result<Case, String> {
        let n = 18 + object_len(shape);
        if v.len() != n {
            return Err(format!(
                "{shape}: {} values, want {n} (M's 12, o, d, the object)",
                v.len()
            ));
        }
        let m = std::array::from_fn(|i| std::array::from_fn(|j| v[i * 4 + j]));
        if v[15..18].iter().all(|x| *x == 0.0) {
            return Err("the direction d is zero".into());
        }
        if shape == "sphere" && !(v[21] > 0.0) {
            return Err(format!("the radius {} is not positive", v[21]));
        }
        Ok(Case {
            shape,
            object: v[18..].to_vec(),
            m,
            o: [v[12], v[13], v[14]],
            d: [v[15], v[16], v[17]],
        })
    }
}

fn object_len(shape: &str) -> usize {
    match shape {
        "sphere" => 4,
        _ => 9,
    }
}

/// A random rotation matrix (axis–angle, in f64).
fn rotation(rng: &mut ChaCha8Rng) -> [V; 3] {
    let a = unit(rng);
    let th = rng.random_range(0.0..std::f64::consts::TAU);
    let (s, c) = th.sin_cos();
    let k = 1.0 - c;
    [
        [
            c + a[0] * a[0] * k,
            a[0] * a[1] * k - a[2] * s,
            a[0] * a[2] * k + a[1] * s,
        ],
        [
            a[1] * a[0] * k + a[2] * s,
            c + a[1] * a[1] * k,
            a[1] * a[2] * k - a[0] * s,
        ],
        [
            a[2] * a[0] * k - a[1] * s,
            a[2] * a[1] * k + a[0] * s,
            c + a[2] * a[2] * k,
        ],
    ]
}

fn matmul(a: &[V; 3], b: &[V; 3]) -> [V; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn apply(l: &[V; 3], v: V) -> V {
    std::array::from_fn(|i| dot(l[i], v))
}

/// M = [L | T] of a class, entries rounded to the precision.
fn transform(rng: &mut ChaCha8Rng, prec: Precision, class: &str) -> Affine {
    let r = rotation(rng);
    let diag = |s: V| -> [V; 3] { [[s[0], 0.0, 0.0], [0.0, s[1], 0.0], [0.0, 0.0, s[2]]] };
    let (l, t) = match class {
        "rotation" => (r, mul(ball(rng), 4.0)),
        "translation" => (r, mul(unit(rng), lu(rng, 3.0, 7.0))),
        "tiny_scale" | "huge_scale" => {
            let s = match class {
                "tiny_scale" => lu(rng, -8.0, -3.0),
                _ => lu(rng, 3.0, 8.0),
            };
            (matmul(&r, &diag([s; 3])), mul(ball(rng), 4.0 * s))
        }
        "non_uniform" => {
            let s = [1.0, lu(rng, -4.0, 4.0), lu(rng, -4.0, 4.0)];
            (
                matmul(&matmul(&r, &diag(s)), &transpose(&r)),
                mul(ball(rng), 4.0),
            )
        }
        _ => {
            let e = lu(rng, -6.0, -3.0);
            (
                matmul(&matmul(&r, &diag([1.0, 1.0, e])), &rotation(rng)),
                mul(ball(rng), 4.0),
            )
        }
    };
    std::array::from_fn(|i| {
        let row = [l[i][0], l[i][1], l[i][2], t[i]];
        row.map(|x| sample::rp(prec, x))
    })
}

fn transpose(a: &[V; 3]) -> [V; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// An object and an object-space ray aimed near its boundary or anywhere over it.
fn object_ray(rng: &mut ChaCha8Rng, prec: Precision, shape: &str) -> (Vec<f64>, V, V) {
    let dir = unit(rng);
    let near = rng.random::<bool>();
    let edge = |rng: &mut ChaCha8Rng| lu(rng, -3.0, -1.0) * sample::sign(rng);
    match shape {
        "sphere" => {
            let c = sample::rpv(prec, mul(ball(rng), 0.5));
            let r = sample::rp(prec, rng.random_range(0.5..1.0));
            let h = match near {
                true => r * (1.0 + edge(rng)),
                false => r * rng.random_range(0.0..1.5),
            };
            let side = mul(sample::perp(rng, dir), h);
            let aim = sample::add(c, side);
            let obj = vec![c[0], c[1], c[2], r];
            (obj, sub(aim, mul(dir, 3.0)), dir)
        }
        _ => {
            let p: [V; 3] = loop {
                let p = [ball(rng), ball(rng), ball(rng)].map(|v| sample::rpv(prec, v));
                let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
                let longest = (0..3)
                    .map(|k| sample::norm(sub(p[k], p[(k + 1) % 3])))
                    .fold(0.0, f64::max);
                if sample::norm(n) > 0.2 * longest * longest {
                    break p;
                }
            };
            let (u, v) = match near {
                // Near an edge (v = 0), on either side, anywhere along it
                true => {
                    let u = rng.random_range(0.1..0.9);
                    (u * (1.0 - 0.0), edge(rng))
                }
                false => (rng.random_range(-0.25..1.25), rng.random_range(-0.25..1.25)),
            };
            let aim: V = std::array::from_fn(|k| {
                p[0][k] + u * (p[1][k] - p[0][k]) + v * (p[2][k] - p[0][k])
            });
            // Not from within the plane's 10°
            let n = normalize(cross(sub(p[1], p[0]), sub(p[2], p[0])));
            let dir = match dot(dir, n).abs() < 0.17 {
                true => normalize(sample::add(dir, mul(n, 0.5))),
                false => dir,
            };
            (p.concat(), sub(aim, mul(dir, 3.0)), dir)
        }
    }
}

/// The cases of a shape, precision and class.
pub fn cases(seed: u64, shape: &'static str, prec: Precision, class: &str, n: u64) -> Vec<Case> {
    (0..n)
        .map(|i| {
            let mut rng = case_rng(seed, "transform", &format!("{shape} {class}"), prec, i);
            let m = transform(&mut rng, prec, class);
            let (object, oo, od) = object_ray(&mut rng, prec, shape);
            let l: [V; 3] = std::array::from_fn(|r| [m[r][0], m[r][1], m[r][2]]);
            let t = [m[0][3], m[1][3], m[2][3]];
            let o = sample::rpv(prec, sample::add(apply(&l, oo), t));
            let d = sample::rpv(prec, apply(&l, od));
            Case {
                shape,
                object,
                m,
                o,
                d,
            }
        })
        .collect()
}

// ---- exact ----

type Q = Rational;

fn q(x: f64) -> Q {
    Q::from_f64(x).expect("a finite value")
}

fn qdot(a: &[Q; 3], b: &[Q; 3]) -> Q {
    Q::from(&a[0] * &b[0]) + Q::from(&a[1] * &b[1]) + Q::from(&a[2] * &b[2])
}

fn qcross(a: &[Q; 3], b: &[Q; 3]) -> [Q; 3] {
    [
        Q::from(&a[1] * &b[2]) - Q::from(&a[2] * &b[1]),
        Q::from(&a[2] * &b[0]) - Q::from(&a[0] * &b[2]),
        Q::from(&a[0] * &b[1]) - Q::from(&a[1] * &b[0]),
    ]
}

fn qsub(a: &[Q; 3], b: &[Q; 3]) -> [Q; 3] {
    std::array::from_fn(|k| Q::from(&a[k] - &b[k]))
}

/// M⁻¹'s linear part exactly (adjugate over the determinant); `None` for a singular M.
fn inverse(m: &Affine) -> Option<[[Q; 3]; 3]> {
    let l: [[Q; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| q(m[i][j])));
    let cols: [[Q; 3]; 3] = std::array::from_fn(|j| std::array::from_fn(|i| l[i][j].clone()));
    // Rows of the inverse: the cross products of columns over det
    let r0 = qcross(&cols[1], &cols[2]);
    let det = qdot(&cols[0], &r0);
    if det == 0 {
        return None;
    }
    let r1 = qcross(&cols[2], &cols[0]);
    let r2 = qcross(&cols[0], &cols[1]);
    Some([r0, r1, r2].map(|r| r.map(|x| x / &det)))
}

/// The exact answer of a case: `None` a miss, `Some(t)` a hit at t (as a 256-bit float), and
/// whether the case is well posed (its margin from the boundary at least [`MARGIN`]).
pub struct Exact {
    /// The hit's t.
    pub t: Option<Float>,
    /// Well posed: judged.
    pub well_posed: bool,
}

/// The world ray carried into object space by M⁻¹ exactly; `None` for a singular M.
fn exact_object_ray(c: &Case) -> Option<([Q; 3], [Q; 3])> {
    let inv = inverse(&c.m)?;
    let tr: [Q; 3] = std::array::from_fn(|i| q(c.m[i][3]));
    let ow = qsub(&c.o.map(q), &tr);
    let dw = c.d.map(q);
    Some((
        std::array::from_fn(|i| qdot(&inv[i], &ow)),
        std::array::from_fn(|i| qdot(&inv[i], &dw)),
    ))
}

/// The world ray carried back by M⁻¹ exactly, and the object's exact answer there.
pub fn exact(c: &Case) -> Exact {
    let Some((o, d)) = exact_object_ray(c) else {
        return Exact {
            t: None,
            well_posed: false,
        };
    };
    let margin = Q::from_f64(MARGIN).unwrap();
    let far = |x: &Q| Q::from(x.abs_ref()) >= margin;
    match c.shape {
        "sphere" => {
            let cc = [c.object[0], c.object[1], c.object[2]].map(q);
            let r2 = q(c.object[3]) * q(c.object[3]);
            let w = qsub(&o, &cc);
            let a = qdot(&d, &d);
            let b = qdot(&d, &w);
            let cw = qdot(&w, &w) - &r2;
            // No ray or no sphere: nothing to judge (a replay's values; the cases have neither)
            if a == 0 || r2 == 0 {
                return Exact {
                    t: None,
                    well_posed: false,
                };
            }
            let disc = Q::from(&b * &b) - Q::from(&a * &cw);
            // 1 − h²/r² = disc / (a r²)
            let well_posed = far(&(Q::from(&disc / &a) / &r2)) && far(&Q::from(&cw / &r2));
            if disc < 0 || (b >= 0 && cw >= 0) {
                return Exact {
                    t: None,
                    well_posed,
                };
            }
            let p = 256;
            let sq = Float::with_val(p, &disc).sqrt();
            let fb = Float::with_val(p, &b);
            let fa = Float::with_val(p, &a);
            // The nearest root with t > 0: the smaller when the origin is outside
            let t = match cw > 0 {
                true => (-fb - sq) / fa,
                false => (-fb + sq) / fa,
            };
            Exact {
                t: Some(t),
                well_posed,
            }
        }
        _ => {
            let p: [[Q; 3]; 3] =
                std::array::from_fn(|k| std::array::from_fn(|j| q(c.object[3 * k + j])));
            let e1 = qsub(&p[1], &p[0]);
            let e2 = qsub(&p[2], &p[0]);
            let pv = qcross(&d, &e2);
            let det = qdot(&e1, &pv);
            if det == 0 {
                return Exact {
                    t: None,
                    well_posed: false,
                };
            }
            let tv = qsub(&o, &p[0]);
            let u = qdot(&tv, &pv) / &det;
            let qv = qcross(&tv, &e1);
            let v = qdot(&d, &qv) / &det;
            let t = qdot(&e2, &qv) / &det;
            let w = Q::from(1) - &u - &v;
            let well_posed = far(&u) && far(&v) && far(&w);
            let hit = u >= 0 && v >= 0 && w >= 0 && t > 0;
            Exact {
                t: hit.then(|| Float::with_val(256, &t)),
                well_posed,
            }
        }
    }
}

// ---- the renderer's side ----

/// W = M⁻¹ rounded to the precision: `(L_W, b_W)`.
pub fn stored_inverse(m: &Affine, prec: Precision) -> Option<([V; 3], V)> {
    let inv = inverse(m)?;
    let tr: [Q; 3] = std::array::from_fn(|i| q(m[i][3]));
    let round = |x: &Q| sample::rp(prec, x.to_f64());
    let l: [V; 3] = std::array::from_fn(|i| std::array::from_fn(|j| round(&inv[i][j])));
    let b: V = std::array::from_fn(|i| round(&-qdot(&inv[i], &tr)));
    Some((l, b))
}

/// W = M⁻¹ computed in `F` as a renderer given only M computes it: the rows of L_W are the cross
/// products of L's columns over det = c₀·(c₁ × c₂), b_W = −L_W·T (`None`: det is 0 or not
/// finite in `F`).
fn computed_inverse<F: crate::numerics::real::Real>(m: &Affine) -> Option<([V; 3], V)> {
    let f = F::from_f64;
    let col = |j: usize| [f(m[0][j]), f(m[1][j]), f(m[2][j])];
    let cross = |a: [F; 3], b: [F; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let (c0, c1, c2) = (col(0), col(1), col(2));
    let r0 = cross(c1, c2);
    let det = c0[0] * r0[0] + c0[1] * r0[1] + c0[2] * r0[2];
    if det.to_f64() == 0.0 || !det.is_finite() {
        return None;
    }
    let rows = [r0, cross(c2, c0), cross(c0, c1)].map(|r| r.map(|x| x / det));
    let t = col(3);
    let b: [F; 3] = std::array::from_fn(|i| {
        F::from_f64(0.0) - (rows[i][0] * t[0] + rows[i][1] * t[1] + rows[i][2] * t[2])
    });
    let l: [V; 3] = rows.map(|r| r.map(|x| x.to_f64()));
    Some((l, b.map(|x| x.to_f64())))
}

/// The object-space ray as the renderer computes it in `F`, by `mode`.
fn carried<F: crate::numerics::real::Real>(c: &Case, w: &([V; 3], V), mode: &str) -> (V, V) {
    let f = F::from_f64;
    let row = |r: &V, v: [F; 3]| f(r[0]) * v[0] + f(r[1]) * v[1] + f(r[2]) * v[2];
    let o = c.o.map(f);
    let d = c.d.map(f);
    let oo: [F; 3] = match mode {
        "matrix" | "inverted" => std::array::from_fn(|i| row(&w.0[i], o) + f(w.1[i])),
        _ => {
            let rel: [F; 3] = std::array::from_fn(|k| o[k] - f(c.m[k][3]));
            std::array::from_fn(|i| row(&w.0[i], rel))
        }
    };
    let od: [F; 3] = std::array::from_fn(|i| row(&w.0[i], d));
    (oo.map(|x| x.to_f64()), od.map(|x| x.to_f64()))
}

/// The object-space inputs a routine gets for a case, by mode (`None`: M is singular).
pub fn object_input(c: &Case, prec: Precision, mode: &str) -> Option<Vec<f64>> {
    let (o, d) = match mode {
        "ideal" => {
            let (o, d) = exact_object_ray(c)?;
            let round = |x: &Q| sample::rp(prec, x.to_f64());
            (o.each_ref().map(round), d.each_ref().map(round))
        }
        _ => {
            let w = match (mode, prec) {
                ("inverted", Precision::F32) => computed_inverse::<f32>(&c.m)?,
                ("inverted", Precision::F64) => computed_inverse::<f64>(&c.m)?,
                _ => stored_inverse(&c.m, prec)?,
            };
            match prec {
                Precision::F32 => carried::<f32>(c, &w, mode),
                Precision::F64 => carried::<f64>(c, &w, mode),
            }
        }
    };
    Some([&o[..], &d[..], &c.object[..]].concat())
}

/// The built-in routines run by default: of each shape the textbook one and a robust one (for
/// the triangle also pbrt-v4's watertight test, in the precision).
pub const DEFAULT: [(&str, &str); 5] = [
    ("sphere", "algebraic"),
    ("sphere", "rtg7"),
    ("triangle", "moller_trumbore"),
    ("triangle", "watertight"),
    ("triangle", "watertight_wide"),
];

/// The built-in method `name` of `shape`.
pub fn builtin(shape: &'static str, name: &str) -> Option<Routine<'static>> {
    let info = crate::shapes::shape_by_name(shape)?.info();
    info.methods
        .iter()
        .position(|m| m.name == name)
        .map(|i| Routine::BuiltIn(shape, i))
}

/// A routine: a built-in method of the shape (its index) or one from outside the crate.
#[derive(Clone, Copy)]
pub enum Routine<'a> {
    /// The shape's built-in method `i`.
    BuiltIn(&'static str, usize),
    /// A routine of the shape through `--plugin` or `--exec`.
    Outside(&'a dyn Method),
}

impl Routine<'_> {
    /// Its name.
    pub fn name(&self) -> String {
        match self {
            Routine::BuiltIn(s, i) => crate::shapes::shape_by_name(s)
                .map(|sh| sh.info().methods[*i].name.to_string())
                .unwrap_or_default(),
            Routine::Outside(m) => m.name().to_string(),
        }
    }

    /// Its `t` (or a miss) on each input, held to the shape's contract (count 0, or 1 and t).
    pub fn answers(
        &self,
        prec: Precision,
        inputs: &[Vec<f64>],
    ) -> Result<Vec<Option<f64>>, String> {
        let answers = match self {
            Routine::BuiltIn(s, i) => {
                let sh = crate::shapes::shape_by_name(s).expect("a built-in shape");
                inputs.par_iter().map(|x| sh.run(*i, x, prec)).collect()
            }
            Routine::Outside(m) => {
                let mut out = Vec::with_capacity(inputs.len());
                for chunk in inputs.chunks(crate::audit::run::CHUNK as usize) {
                    out.extend(crate::audit::run::answers(&[*m], prec, chunk)?.remove(0));
                }
                out
            }
        };
        let outside = matches!(self, Routine::Outside(_));
        answers
            .into_iter()
            .zip(inputs)
            .map(|(a, x)| match (a.count, &a.values[..]) {
                // A routine of yours is held to the contract: a miss, or one hit and its t
                (0, []) => Ok(None),
                (1, &[t]) => Ok(Some(t)),
                (0, _) if !outside => Ok(None),
                (1, &[t, ..]) if !outside => Ok(Some(t)),
                // Outside the contract (a count the shape cannot have, values that do not match
                // it): a hit at a bad t of its row, as the main rows count a malformed answer
                // (never excused, never a stop)
                _ if outside => Ok(Some(f64::NAN)),
                _ => Err(format!(
                    "routine '{}': answered {} {:?} to the case {}; want count 0, or 1 and T",
                    self.name(),
                    a.count,
                    a.values,
                    crate::audit::exec::case_line(prec, x).trim_end()
                )),
            })
            .collect()
    }
}

/// What a routine's answer to a case is worth against the exact oracle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// A hit at a t that is not finite and positive (or a routine's answer outside the
    /// contract): wrong whatever the case.
    BadT,
    /// Within [`MARGIN`] of the boundary: not judged.
    NotJudged,
    /// A hit where the exact oracle misses.
    FalseHit,
    /// A miss where the exact oracle hits.
    FalseMiss,
    /// The exact oracle's verdict.
    Right,
}

/// The verdict of an answer `t` (`Some(t)` a hit) against the exact answer `e`.
pub fn judge(t: Option<f64>, e: &Exact) -> Verdict {
    match (t, &e.t) {
        (Some(t), _) if !(t.is_finite() && t > 0.0) => Verdict::BadT,
        _ if !e.well_posed => Verdict::NotJudged,
        (Some(_), None) => Verdict::FalseHit,
        (None, Some(_)) => Verdict::FalseMiss,
        _ => Verdict::Right,
    }
}

/// One row: a routine × mode × precision × class.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TransformRow {
    /// `sphere` or `triangle`.
    pub shape: String,
    /// The object-space routine.
    pub routine: String,
    /// `matrix`, `translate_first`, `inverted` or `ideal`.
    pub mode: String,
    /// `f32` or `f64`.
    pub precision: String,
    /// The class of transforms.
    pub class: String,
    /// Cases judged (well posed).
    pub cases: u64,
    /// Cases within [`MARGIN`] of the boundary: not judged.
    pub ill_posed: u64,
    /// Judged cases the routine hits and the exact oracle misses.
    pub false_hit: u64,
    /// Judged cases the exact oracle hits and the routine misses.
    pub false_miss: u64,
    /// Cases (judged or not) the routine hits at a t that is not finite and positive, or
    /// answers outside the shape's contract.
    pub bad_t: u64,
    /// The largest error of t, in ulps of the precision, where both hit.
    pub worst_ulps: f64,
    /// The first wrong case: `rayproof transform --replay …`.
    pub replay: Option<String>,
    /// `pass` or `fail` (a judged row), `reported`; empty in a shard file (the merge judges).
    pub verdict: String,
}

/// Whether a routine's rows in a mode are held by default to no wrong verdict: in the `ideal`
/// mode (the object-space ray correctly rounded), every routine from outside the crate and the
/// built-in methods robust by design. There the routine's own error is all that remains: the
/// rays start within a few object sizes of the object (|o'| ≲ 10 s), so rounding o' and d'
/// moves the impact parameter or a barycentric by a few ε·|o'|/s ≤ 10⁻⁵ in `f32`, below
/// [`MARGIN`], and a robust method's error is of that order too. The other modes add the
/// renderer's carrying (cond(L)·ε, large translations) and are reported: they show what the
/// transform costs, not the routine.
pub fn judged_by_default(shape: &str, routine: &str, mode: &str) -> bool {
    mode == "ideal"
        && crate::shapes::shape_by_name(shape)
            .and_then(|s| s.info().methods.iter().find(|m| m.name == routine))
            .is_none_or(|m| m.robust)
}

/// The wrong verdicts of a row on judged cases: false hits and false misses.
pub fn failures(r: &TransformRow) -> u64 {
    r.false_hit + r.false_miss
}

/// The default verdict of a row: a hit at a bad t fails any row; then
/// [`judged_by_default`] (a judged row with no case shows nothing and fails).
pub fn default_verdict(r: &TransformRow) -> &'static str {
    match judged_by_default(&r.shape, &r.routine, &r.mode) {
        _ if r.bad_t > 0 => "fail",
        false => "reported",
        true if failures(r) > 0 || r.cases == 0 => "fail",
        true => "pass",
    }
}

/// The replay line of a case.
pub fn replay_line(
    c: &Case,
    routine: &str,
    mode: &str,
    prec: Precision,
    extra: Option<&str>,
) -> String {
    let v: Vec<String> = c.values().iter().map(|x| hex_text(*x)).collect();
    // A routine of yours is run as the shape it is given for
    let extra = extra
        .map(|e| format!("--shape {} {e} ", c.shape))
        .unwrap_or_default();
    format!(
        "rayproof transform {extra}--replay {} {routine} {mode} {} {}",
        c.shape,
        prec.name(),
        v.join(" ")
    )
}

/// The error of a computed t against the exact one, in ulps of the precision at the exact t.
pub fn ulps_of(t: f64, exact: &Float, prec: Precision) -> f64 {
    let e = exact.to_f64();
    let u = ulp(e.abs().max(f64::MIN_POSITIVE), prec);
    let diff = Float::with_val(256, t) - exact;
    (diff.to_f64() / u).abs()
}

/// The rows of `routines` (each with its shape) × modes × `precs` × classes, `n` cases each (a
/// routine from outside keeps its child: the caller ends the run with `finish`).
pub fn rows(
    seed: u64,
    routines: &[(&'static str, Routine)],
    precs: &[Precision],
    n: u64,
) -> Result<Vec<TransformRow>, String> {
    let mut out = vec![];
    for &prec in precs {
        for shape in ["sphere", "triangle"] {
            let mine: Vec<&Routine> = routines
                .iter()
                .filter(|(s, _)| *s == shape)
                .map(|(_, r)| r)
                .collect();
            if mine.is_empty() {
                continue;
            }
            for class in CLASSES {
                let cs = cases(seed, shape, prec, class, n);
                let truth: Vec<Exact> = cs.par_iter().map(exact).collect();
                for mode in MODES {
                    // A W the renderer cannot have (M singular, or its determinant 0 or not
                    // finite in the precision: `inverted`) gives no object-space ray: the
                    // renderer sees no instance, a miss
                    let inputs: Vec<Option<Vec<f64>>> =
                        cs.iter().map(|c| object_input(c, prec, mode)).collect();
                    let asked: Vec<Vec<f64>> = inputs.iter().flatten().cloned().collect();
                    for r in &mine {
                        let got = r.answers(prec, &asked)?;
                        let mut got = got.into_iter();
                        let mut row = TransformRow {
                            shape: shape.to_string(),
                            routine: r.name(),
                            mode: mode.to_string(),
                            precision: prec.name().to_string(),
                            class: class.to_string(),
                            cases: 0,
                            ill_posed: 0,
                            false_hit: 0,
                            false_miss: 0,
                            bad_t: 0,
                            worst_ulps: 0.0,
                            replay: None,
                            verdict: String::new(),
                        };
                        for ((c, x), e) in cs.iter().zip(&inputs).zip(&truth) {
                            let t = match x {
                                Some(_) => got.next().flatten(),
                                None => None,
                            };
                            match e.well_posed {
                                true => row.cases += 1,
                                false => row.ill_posed += 1,
                            }
                            let wrong = match judge(t, e) {
                                Verdict::NotJudged => false,
                                Verdict::BadT => {
                                    row.bad_t += 1;
                                    true
                                }
                                Verdict::FalseHit => {
                                    row.false_hit += 1;
                                    true
                                }
                                Verdict::FalseMiss => {
                                    row.false_miss += 1;
                                    true
                                }
                                Verdict::Right => {
                                    if let (Some(t), Some(et)) = (t, &e.t) {
                                        let u = ulps_of(t, et, prec);
                                        row.worst_ulps = row.worst_ulps.max(u);
                                    }
                                    false
                                }
                            };
                            if wrong && row.replay.is_none() {
                                let extra = match r {
                                    Routine::Outside(m) => m.replay(),
                                    Routine::BuiltIn(..) => None,
                                };
                                row.replay = Some(replay_line(
                                    c,
                                    &row.routine,
                                    mode,
                                    prec,
                                    extra.as_deref(),
                                ));
                            }
                        }
                        row.verdict = default_verdict(&row).to_string();
                        out.push(row);
                    }
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact inverse is the inverse: M⁻¹·(M·x) = x exactly for a point x of the precision.
    #[test]
    fn the_exact_inverse_undoes_m() {
        for class in CLASSES {
            for c in cases(1, "triangle", Precision::F32, class, 8) {
                let inv = inverse(&c.m).unwrap();
                let x = [0.5, -0.25, 0.125].map(q);
                let mx: [Q; 3] = std::array::from_fn(|i| {
                    let row: [Q; 3] = std::array::from_fn(|j| q(c.m[i][j]));
                    qdot(&row, &x) + q(c.m[i][3])
                });
                let tr: [Q; 3] = std::array::from_fn(|i| q(c.m[i][3]));
                let back: [Q; 3] = std::array::from_fn(|i| qdot(&inv[i], &qsub(&mx, &tr)));
                assert_eq!(back, x, "{class}");
            }
        }
    }

    /// The inverse a renderer computes in the precision (`inverted`): exact where every step is
    /// (a scale by powers of two and a translation of small integers), and on the rounded
    /// rotations of the classes within a few ulps of the stored (correctly rounded) inverse but
    /// not equal to it: it is computed, not looked up.
    #[test]
    fn the_computed_inverse_is_the_adjugate_over_the_determinant() {
        let m: Affine = [
            [2.0, 0.0, 0.0, 3.0],
            [0.0, 0.25, 0.0, -5.0],
            [0.0, 0.0, 8.0, 7.0],
        ];
        let want = (
            [[0.5, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 0.125]],
            [-1.5, 20.0, -0.875],
        );
        assert_eq!(computed_inverse::<f32>(&m), Some(want));
        assert_eq!(stored_inverse(&m, Precision::F32), Some(want));
        let mut differ = 0;
        for c in cases(3, "sphere", Precision::F32, "rotation", 64) {
            let (l, _) = computed_inverse::<f32>(&c.m).unwrap();
            let (ls, _) = stored_inverse(&c.m, Precision::F32).unwrap();
            for (a, b) in l.iter().flatten().zip(ls.iter().flatten()) {
                assert!((a - b).abs() <= 8.0 * f32::EPSILON as f64, "{a} {b}");
                differ += (a != b) as u32;
            }
        }
        assert!(differ > 0, "the computed inverse is the stored one");
        // And the mode carries the ray by it: not the stored inverse's object rays
        for prec in Precision::ALL {
            let cs = cases(3, "sphere", prec, "non_uniform", 64);
            let moved = cs
                .iter()
                .filter(|c| object_input(c, prec, "inverted") != object_input(c, prec, "matrix"))
                .count();
            assert!(moved > 0, "{}: inverted carries as matrix", prec.name());
        }
    }

    /// Without a transform (M = identity) the exact answer is the object's own exact oracle's.
    #[test]
    fn under_the_identity_the_oracle_is_the_shapes() {
        let id: Affine = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ];
        for shape in ["sphere", "triangle"] {
            let sh = crate::shapes::shape_by_name(shape).unwrap();
            for mut c in cases(2, shape, Precision::F64, "rotation", 64) {
                c.m = id;
                // The world ray is the object ray
                let input = [&c.o[..], &c.d[..], &c.object[..]].concat();
                let crate::shapes::shape::Truth::Answer(theirs) = sh.oracle(&input, Precision::F64)
                else {
                    panic!("{shape} {input:?}: invalid");
                };
                let ours = exact(&c);
                assert_eq!(ours.t.is_some(), theirs.count > 0, "{shape} {input:?}");
                if let (Some(t), Some(tt)) = (&ours.t, theirs.values.first()) {
                    assert!(ulps_of(*tt, t, Precision::F64) <= 0.5, "{shape}");
                }
            }
        }
    }
}
