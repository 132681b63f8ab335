//! Spawn rules: how a renderer places the origin of a ray it spawns from a hit (issue 47).
//!
//! A rule is given, per spawned ray, a **query** of 19 values in the working precision:
//!
//! | index | values | what |
//! |---|---|---|
//! | 0–2 | `px py pz` | the renderer's computed hit point |
//! | 3–5 | `ex ey ez` | its per-component absolute error bound (0 where the renderer has none) |
//! | 6–8 | `nx ny nz` | the geometric normal, unit length, either orientation |
//! | 9–11 | `wx wy wz` | the new ray's direction (unit length) |
//! | 12 | `t` | the primary hit's ray parameter |
//! | 13–18 | `ox oy oz dx dy dz` | the primary ray |
//!
//! and answers **`origin` (3 values) and `t_min`** (hits at `t ≤ t_min` on the new ray are not
//! taken; 0 for a rule that only moves the origin). A rule comes as a built-in ([`BUILT_IN`]),
//! as Rust (implement [`SpawnRule`]) or as an outside command (`--exec`, one query per line,
//! [`PROTOCOL`]).

use crate::audit::robustness::offset::spawn_origin;
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::shape::{Method, ShapeInfo};

/// How many values a query holds.
pub const QUERY_LEN: usize = 19;

/// What a rule answers for one query: the new ray's origin and its `t_min`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spawned {
    /// The new ray's origin (values of the working precision).
    pub origin: [f64; 3],
    /// Hits at `t ≤ t_min` are not taken (≥ 0).
    pub t_min: f64,
}

/// A rule under audit.
pub trait SpawnRule: Sync {
    /// Its name in rows.
    fn name(&self) -> &str;
    /// Where it comes from (the source its doc names).
    fn about(&self) -> &str {
        ""
    }
    /// The options that bring it back in a replay line (`--exec '…' --name N`); `None`: a
    /// built-in, named by `--rule`.
    fn replay(&self) -> Option<String> {
        None
    }
    /// The answers for `queries` (each [`QUERY_LEN`] values), in order.
    fn spawn(&self, prec: Precision, queries: &[Vec<f64>]) -> Result<Vec<Spawned>, String>;
}

/// The built-in rules, in report order: `(name, source)`.
pub const BUILT_IN: [(&str, &str); 5] = [
    (
        "pbrt",
        "pbrt-v4 OffsetRayOrigin (interaction.h): p moved along n by Σ|nᵢ|·errᵢ to the side w leaves, each component then one ulp further",
    ),
    (
        "wachter_binder",
        "Wächter & Binder, Ray Tracing Gems ch. 6: p moved 256·n ulps in integer space; p + n/65536 where |pᵢ| < 1/32 (the published constants, in f64 too)",
    ),
    (
        "tmin_1e-4",
        "a fixed t_min = 1e-4 from p (tutorials; Embree's tnear examples)",
    ),
    (
        "mitsuba2_epsilon",
        "Mitsuba 2 spawn_ray: t_min = (1 + max|pᵢ|)·RayEpsilon, RayEpsilon = 1500·2⁻²⁴ (f32) or 1500·2⁻⁵³ (f64)",
    ),
    ("none", "the hit point itself, t_min = 0 (a control)"),
];

/// A built-in rule by name.
pub struct BuiltIn(pub usize);

impl BuiltIn {
    /// The built-in rule called `name`.
    pub fn named(name: &str) -> Option<BuiltIn> {
        BUILT_IN.iter().position(|(n, _)| *n == name).map(BuiltIn)
    }
}

fn v3<F: Real>(q: &[f64], k: usize) -> [F; 3] {
    [
        F::from_f64(q[k]),
        F::from_f64(q[k + 1]),
        F::from_f64(q[k + 2]),
    ]
}

/// Wächter and Binder's offset (Ray Tracing Gems, ch. 6, "A Fast and Robust Method for Avoiding
/// Self-Intersection"): `n` turned to the side `w` leaves, each component of `p` moved by
/// `trunc(256·nᵢ)` units in the last place through its integer representation, or by
/// `nᵢ/65536` where `|pᵢ| < 1/32`.
pub fn wachter_binder_origin<F: Real>(p: [F; 3], n: [F; 3], w: [F; 3]) -> [F; 3] {
    let flip = w[0] * n[0] + w[1] * n[1] + w[2] * n[2] < F::ZERO;
    let n = if flip { [-n[0], -n[1], -n[2]] } else { n };
    std::array::from_fn(|i| {
        if p[i].abs().to_f64() < 1.0 / 32.0 {
            return p[i] + F::from_f64(1.0 / 65536.0) * n[i];
        }
        // The float's bits as a signed integer, as the chapter's `float_as_int`
        let of = (256.0 * n[i].to_f64()).trunc() as i64;
        let of = if p[i] < F::ZERO { -of } else { of };
        let bits = p[i].to_bits_u64();
        let moved = if F::MANT_BITS == 24 {
            (bits as u32 as i32).wrapping_add(of as i32) as u32 as u64
        } else {
            (bits as i64).wrapping_add(of) as u64
        };
        F::from_bits_u64(moved)
    })
}

fn built_in<F: Real>(k: usize, q: &[f64]) -> Spawned {
    let (p, err, n, w) = (v3::<F>(q, 0), v3::<F>(q, 3), v3::<F>(q, 6), v3::<F>(q, 9));
    let at = |o: [F; 3]| o.map(|x| x.to_f64());
    let max_abs = p.iter().fold(0.0f64, |m, x| m.max(x.to_f64().abs()));
    match k {
        0 => Spawned {
            origin: at(spawn_origin(p, err, n, w)),
            t_min: 0.0,
        },
        1 => Spawned {
            origin: at(wachter_binder_origin(p, n, w)),
            t_min: 0.0,
        },
        2 => Spawned {
            origin: at(p),
            t_min: F::from_f64(1e-4).to_f64(),
        },
        3 => {
            let eps = 1500.0 * 2f64.powi(-(F::MANT_BITS as i32));
            // (1 + max|p|)·RayEpsilon in the working precision, as Mitsuba computes it
            let e = (F::ONE + F::from_f64(max_abs)) * F::from_f64(eps);
            Spawned {
                origin: at(p),
                t_min: e.to_f64(),
            }
        }
        _ => Spawned {
            origin: at(p),
            t_min: 0.0,
        },
    }
}

impl SpawnRule for BuiltIn {
    fn name(&self) -> &str {
        BUILT_IN[self.0].0
    }
    fn about(&self) -> &str {
        BUILT_IN[self.0].1
    }
    fn spawn(&self, prec: Precision, queries: &[Vec<f64>]) -> Result<Vec<Spawned>, String> {
        Ok(queries
            .iter()
            .map(|q| crate::in_precision!(prec, F => built_in::<F>(self.0, q)))
            .collect())
    }
}

/// The line protocol of a spawn rule run by `rayproof spawn --exec CMD` (for `rayproof header
/// --spawn`).
pub const PROTOCOL: &str = "# The spawn-rule line protocol: rayproof spawn --exec CMD --name NAME
#
# Input (the child's stdin), one spawned ray per line: the precision, then 19 values as C99 hex
# floats, exact in that precision:
#   f32 PX PY PZ EX EY EZ NX NY NZ WX WY WZ T OX OY OZ DX DY DZ
# P the renderer's computed hit point; E its per-component absolute error bound (0 where there
# is none); N the geometric normal (unit, either orientation); W the new ray's direction (unit);
# T the primary hit's t; O, D the primary ray.
#
# Output (the child's stdout), one line per query, in order:
#   1 OX OY OZ TMIN
# the new ray's origin (in the working precision: an f32 value is rounded once to f32) and its
# t_min (hits at t <= TMIN are not taken; 0 for a rule that only moves the origin), in decimal
# or hex. Anything else (a count other than 1, a missing, NaN, infinite or negative value)
# stops the run with one line naming the query (exit 4).
#
# Queries come in batches of up to 4096 to one child (flush each line; logging to stderr), under
# the same rules as `audit --exec` (rayproof header --exec): its own process group, --timeout
# seconds per batch, output capped; a child that dies or hangs stops the run (exit 4).
";

/// What a spawn rule is to the outside-routine machinery (`--exec` and `--plugin`): 19 values
/// in, 4 out (`OX OY OZ TMIN`), count 1.
pub const INFO: ShapeInfo = ShapeInfo {
    name: "spawn",
    about: "a spawn rule: the new ray's origin and t_min from a hit",
    args: &[
        "px", "py", "pz", "ex", "ey", "ez", "nx", "ny", "nz", "wx", "wy", "wz", "t", "ox", "oy",
        "oz", "dx", "dy", "dz",
    ],
    values: &["ox", "oy", "oz", "tmin"],
    ..ShapeInfo::DEFAULTS
};

/// The C signatures of a spawn rule given as `--plugin PATH:SYMBOL` (for `rayproof header
/// --spawn`).
pub const C_SIGNATURE: &str =
    "/* A spawn rule through its C ABI: rayproof spawn --plugin PATH:SYMBOL (or audit
 * --spawn-rule plugin:PATH:SYMBOL). in[i] is query i (the 19 values above, in the precision),
 * it sets count[i] = 1 and out[i] = origin x y z, t_min, and returns 0. Build with -shared
 * -fPIC; it runs in a worker process, in batches of up to 4096, under --timeout. */
typedef int rayproof_spawn_f32(size_t n, const float in[][19], uint32_t count[], float out[][4]);
typedef int rayproof_spawn_f64(size_t n, const double in[][19], uint32_t count[], double out[][4]);
";

/// A rule from outside the crate: a command (`--exec`, [`crate::audit::exec::Exec`]) or a
/// library's symbol (`--plugin`, [`crate::audit::plugin::Plugin`]) made for [`INFO`], through
/// the machinery that runs outside intersectors.
pub struct OutsideRule(pub Box<dyn Method + Send>);

impl SpawnRule for OutsideRule {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn replay(&self) -> Option<String> {
        self.0.replay()
    }
    fn spawn(&self, prec: Precision, queries: &[Vec<f64>]) -> Result<Vec<Spawned>, String> {
        let mut out = Vec::with_capacity(queries.len());
        for chunk in queries.chunks(crate::audit::run::CHUNK as usize) {
            // Checked for their number, as every outside routine's answers are
            let answers = crate::audit::run::answers(&[self.0.as_ref()], prec, chunk)?.remove(0);
            for (a, q) in answers.iter().zip(chunk) {
                let ok = a.count == 1
                    && a.values.len() == 4
                    && a.values.iter().all(|v| v.is_finite())
                    && a.values[3] >= 0.0;
                if !ok {
                    return Err(format!(
                        "spawn rule '{}': answered {} {:?} to the query {}; want count 1 and OX OY OZ TMIN, finite, TMIN >= 0",
                        self.0.name(),
                        a.count,
                        a.values,
                        crate::audit::exec::case_line(prec, q).trim_end()
                    ));
                }
                out.push(Spawned {
                    origin: [a.values[0], a.values[1], a.values[2]],
                    t_min: a.values[3],
                });
            }
        }
        // Its input closed, the child must end well with nothing more to say (as for `audit
        // --exec`: a line too many shifts every later answer onto the wrong query)
        self.0.finish()?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Wächter–Binder moves a component by whole ulps in the normal's direction, whatever its
    /// sign, and by n/65536 near the origin.
    #[test]
    fn wachter_binder_moves_along_the_normal_by_integer_ulps() {
        let p = [1.0f32, -1.0, 0.01];
        let n = [1.0f32, 1.0, 1.0];
        let o = wachter_binder_origin(p, n, n);
        assert_eq!(o[0].to_bits(), 1.0f32.to_bits() + 256);
        assert!(o[1] > -1.0 && (-1.0f32).to_bits() - o[1].to_bits() == 256);
        assert_eq!(o[2], 0.01 + 1.0 / 65536.0);
        // The other side: the normal turned
        let o = wachter_binder_origin(p, n, [-1.0, 0.0, 0.0]);
        assert_eq!(1.0f32.to_bits() - o[0].to_bits(), 256);
    }

    /// Mitsuba 2's RayEpsilon: 1500·2⁻²⁴ ≈ 8.9e-5 in f32.
    #[test]
    fn mitsuba_epsilon_is_1500_machine_epsilons() {
        let q = [vec![0.0; 12], vec![1.0], vec![0.0; 6]].concat();
        let s = BuiltIn(3).spawn(Precision::F32, &[q.clone()]).unwrap()[0];
        assert_eq!(s.t_min, (1500.0f32 * 2f32.powi(-24)) as f64);
        let s = BuiltIn(3).spawn(Precision::F64, &[q]).unwrap()[0];
        assert_eq!(s.t_min, 1500.0 * 2f64.powi(-53));
    }
}
