//! The spawned ray audited both ways (issue 47): a spawn rule must keep the new ray off its own
//! surface (no **self-hit**) without starting it past a nearby one (no **skipped neighbour**).
//!
//! **Instances.** Per precision, scale `s = 10^e` (`e` in [`SCALES`], scene sizes 1e-4 to 1e7)
//! and placement ([`PLACEMENTS`]: `near`, within 4 sizes of the origin; `far`, 10³–10⁵ sizes
//! away), `per_cell` triangles of size `s`, vertices rounded to the precision. One primary ray
//! per triangle, from outside, aimed at a random point of it. The renderer's intersector is
//! pbrt-v4's watertight test in the working precision; its hit gives the point a renderer
//! really has, reprojected from its barycentrics, with pbrt's bound `γ(7)·Σ|bᵢpᵢ|`
//! (`triangle::hit_point`). From it, [`SPAWNED`] directions: half to the side the primary ray
//! came from (reflection), half through (transmission), uniform on each hemisphere, rounded.
//!
//! **The rule's answer** for each (its [`rules`]): an origin `o'` and a `t_min`.
//!
//! **Self-hit, judged exactly.** The ideal spawned ray leaves the exact hit `p*` (the exact
//! root, [`triangle::exact_tri`]) along `w`; off a flat triangle it never meets the triangle
//! again. So the rule's ray self-hits when the exact oracle finds a hit of `(o', w)` on the
//! triangle at `t > t_min`: its origin was left on or behind the surface. The renderer's
//! intersector on the same ray (`t > t_min`) is counted beside it: it can add false hits or
//! hide true ones.
//!
//! **Skipped neighbour, judged exactly.** A second surface parallel to the triangle at a gap
//! `g` on the side `w` leaves to (a thin slab, a parallel triangle above a triangle) is met by
//! the ideal ray at `t = g/(ŵ·n̂)`. The rule's ray takes hits only from `o' + t_min·w` on, whose
//! height above the triangle's plane is the rule's **reach** `r = n̂·(o' + t_min·w − p₀)` (`n̂`
//! turned to `w`'s side; the numerator exact in rationals, divided by `|n|` in `f64`). A
//! neighbour at `g < r` is skipped (the new ray starts past it), one at `g > r` is found. So the
//! **smallest gap the rule resolves** over a set of rays is the largest reach among them: the
//! exact answer of a bisection over `g`, without the bisection (a unit test runs the bisection
//! with the exact oracle on a real neighbour triangle and finds the same value). It is reported
//! in scene units and in ulps of `max|p*ᵢ|` in the precision.
//!
//! **A tilted neighbour** (a slightly tilted triangle above the hit, or locally the underside
//! of a sphere resting on the surface near it): a plane through `p* + g·n̂` tilted by
//! [`TILT_DEGREES`] toward where the new ray starts is skipped below `reach + tan(tilt)·along`,
//! `along` the start's distance from `p*` along the surface (exact, then rounded). A rule that
//! moves the start along the surface or along the new ray (a `t_min`) skips it sooner; a unit
//! test bisects over `g` with the exact oracle on such a plane and finds the same value.
//!
//! A rule that leaves no self-hit at every scale and a gap of a few ulps of `|p|` is what a
//! renderer wants; the table shows where each rule stands.

pub mod rules;

pub use rules::{BuiltIn, OutsideRule, SpawnRule, Spawned, BUILT_IN, INFO, PROTOCOL, QUERY_LEN};

use crate::numerics::exact::{q, ulp};
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::oracle::sample;
use crate::shapes::shape::{case_rng, hex_text};
use crate::shapes::triangle::{self, exact_tri, ExactTri};
use rug::Rational;
use serde::{Deserialize, Serialize};

/// The scales' exponents: scene sizes `10^-4` to `10^7`.
pub const SCALES: std::ops::RangeInclusive<i32> = -4..=7;
/// Where the triangles sit: within 4 sizes of the origin, or 10³–10⁵ sizes away.
pub const PLACEMENTS: [&str; 2] = ["near", "far"];
/// Spawned rays per triangle (half reflection side, half transmission side).
pub const SPAWNED: usize = 8;
/// The intersector that finds the primary hits (pbrt-v4's watertight test), and by default
/// the one run on the spawned rays ([`watertight`]).
const INTERSECTOR: usize = 2;

/// The default intersector of the spawned rays: pbrt-v4's watertight triangle test, built in.
pub fn watertight() -> crate::shapes::shape::Builtin {
    crate::shapes::shape::Builtin {
        shape: crate::shapes::shape_by_name("triangle").expect("the triangle is registered"),
        index: INTERSECTOR,
    }
}

/// One spawned ray: the triangle (9 values), the rule's query, the exact hit.
#[derive(Clone)]
pub struct Ray {
    tri: [[f64; 3]; 3],
    /// The rule's query ([`QUERY_LEN`] values).
    pub query: Vec<f64>,
    /// One ulp of `max|p*ᵢ|` in the precision (the unit of a gap in ulps).
    pub hit_ulp: f64,
}

/// The rays of one cell (precision × scale × placement).
pub struct Cell {
    /// The precision.
    pub prec: Precision,
    /// The scale's exponent.
    pub scale: i32,
    /// `near` or `far`.
    pub placement: &'static str,
    /// Its spawned rays.
    pub rays: Vec<Ray>,
}

/// One row: a rule in one cell.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SpawnRow {
    /// The rule.
    pub rule: String,
    /// `f32` or `f64`.
    pub precision: String,
    /// The scale's exponent (scene size `10^scale`).
    pub scale: i32,
    /// `near` or `far`.
    pub placement: String,
    /// Spawned rays judged.
    pub rays: u64,
    /// Rays that re-hit their own triangle (the exact oracle).
    pub self_hits: u64,
    /// Rays on which the renderer's intersector (`intersector`) re-hits it.
    pub self_hits_intersector: u64,
    /// The triangle routine run on the spawned rays: a built-in method's name (default
    /// `watertight`, pbrt-v4's) or a routine of the user's (`--intersector`).
    #[serde(default)]
    pub intersector: String,
    /// Rays whose first point taking hits lies behind the surface's plane (a negative reach:
    /// the rule sent the ray through its own surface, whether or not it meets the triangle).
    #[serde(default)]
    pub behind: u64,
    /// The smallest gap to a parallel neighbour that every ray resolves (the largest reach;
    /// 0 when no ray starts above the surface), in scene units.
    pub gap: f64,
    /// The same in ulps of the hit point's largest component.
    pub gap_ulps: f64,
    /// The smallest gap resolved to a neighbour tilted by [`TILT_DEGREES`] (the largest
    /// `reach + tan(tilt)·along`), in scene units.
    #[serde(default)]
    pub gap_tilted: f64,
    /// The same in ulps of the hit point's largest component.
    #[serde(default)]
    pub gap_tilted_ulps: f64,
    /// A replay line of a self-hit, if any.
    pub self_hit_replay: Option<String>,
    /// A replay line of the ray with the largest reach.
    pub gap_replay: Option<String>,
    /// A replay line of a ray started behind the surface, if any.
    #[serde(default)]
    pub behind_replay: Option<String>,
    /// `pass` or `fail` against its [`Goal`], `reported` without one (set by [`judge_rows`]).
    #[serde(default)]
    pub verdict: String,
}

/// What a rule's rows are held to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Goal {
    /// Self-hits (exact oracle) allowed per row, and as many rays behind the surface.
    pub max_self_hits: u64,
    /// The widest resolved gap allowed per row, in ulps of `max|p|` (`None`: only the
    /// scene-size bound).
    pub max_gap_ulps: Option<f64>,
}

/// Every judged row's gap bound, whatever its goal, for the parallel and the tilted neighbour:
/// a rule whose new ray starts as far above the surface as the triangle is wide (the cell's
/// scene size) skips a neighbour at the scale of the scene itself, a light leak no renderer
/// wants. (pbrt's rule stays under a seventh of it in the worst cell: f32, 10⁵ sizes from the
/// origin.)
pub const MAX_GAP_SCENES: f64 = 1.0;

impl Goal {
    /// The default goal of a rule from outside the crate and of pbrt-v4's rule (the crate's
    /// own): no self-hit, no ray behind the surface; the gap reported.
    pub const NO_SELF_HIT: Goal = Goal {
        max_self_hits: 0,
        max_gap_ulps: None,
    };

    /// A row's verdict: `fail` when it has no ray (it shows nothing), a ray behind the surface,
    /// more self-hits than allowed, a gap over the bound or as wide as the scene
    /// ([`MAX_GAP_SCENES`]); else `pass`.
    pub fn verdict(&self, r: &SpawnRow) -> &'static str {
        let scene = MAX_GAP_SCENES * 10f64.powi(r.scale);
        let too_wide = self.max_gap_ulps.is_some_and(|m| !(r.gap_ulps <= m))
            || !(r.gap < scene)
            || !(r.gap_tilted < scene);
        let wrong_side = r.self_hits.max(r.behind) > self.max_self_hits;
        if r.rays == 0 || wrong_side || too_wide {
            "fail"
        } else {
            "pass"
        }
    }
}

/// The default goal of a rule named `rule`: [`Goal::NO_SELF_HIT`] for a rule from outside the
/// crate (`outside`) and for `pbrt` (the rule the crate's own reintersection test uses); the
/// other built-ins (and the `none` control) are reported.
pub fn default_goal(rule: &str, outside: bool) -> Option<Goal> {
    (outside || rule == BUILT_IN[0].0).then_some(Goal::NO_SELF_HIT)
}

/// Sets every row's verdict from `goal_of(row)` (`None`: `reported`).
pub fn judge_rows(rows: &mut [SpawnRow], goal_of: &dyn Fn(&SpawnRow) -> Option<Goal>) {
    for r in rows {
        r.verdict = goal_of(r).map_or("reported", |g| g.verdict(r)).into();
    }
}

/// A failed row in one line: its counts, its widest gap and the replay line that shows it.
pub fn failure(r: &SpawnRow) -> String {
    let at = format!(
        "spawn rule {} {} scene size 1e{} {}",
        r.rule, r.precision, r.scale, r.placement
    );
    if r.rays == 0 {
        return format!("{at}: no spawned ray in the cell (it shows nothing)");
    }
    let replay = if r.self_hits > 0 {
        format!(
            "replay of a self-hit: {}",
            r.self_hit_replay.as_deref().unwrap_or("-")
        )
    } else if r.behind > 0 {
        format!(
            "replay of a ray behind the surface: {}",
            r.behind_replay.as_deref().unwrap_or("-")
        )
    } else {
        format!(
            "replay of the widest reach: {}",
            r.gap_replay.as_deref().unwrap_or("-")
        )
    };
    format!(
        "{at}: {} self-hits and {} rays behind the surface of {}; smallest resolved gap {:.3e} \
         ({} ulps of max|p|), {:.3e} to a neighbour tilted {TILT_DEGREES}° (the scene is 1e{} \
         wide); {replay}",
        r.self_hits,
        r.behind,
        r.rays,
        r.gap,
        ulps_text(r.gap_ulps),
        r.gap_tilted,
        r.scale
    )
}

fn v3(v: &[f64], k: usize) -> [f64; 3] {
    [v[k], v[k + 1], v[k + 2]]
}

/// The rays of one cell, from the seed (the same for every rule).
pub fn cell(seed: u64, prec: Precision, scale: i32, placement: &'static str, n: u64) -> Cell {
    let rays = crate::in_precision!(prec, F => cell_in::<F>(seed, scale, placement, n));
    Cell {
        prec,
        scale,
        placement,
        rays,
    }
}

fn cell_in<F: Real>(seed: u64, scale: i32, placement: &str, n: u64) -> Vec<Ray> {
    let prec = Precision::of::<F>();
    let s = 10f64.powi(scale);
    let mut out = vec![];
    // n triangles whose primary ray the renderer's intersector hits (a miss is drawn again,
    // up to 8n draws: a cell is never empty for want of a lucky draw)
    let mut made = 0;
    for i in 0..8 * n {
        if made == n {
            break;
        }
        let class = format!("spawn-{placement}-{scale}");
        let mut rng = case_rng(seed, "spawn", &class, prec, i);
        let at = sample::placed(&mut rng, placement, s);
        // A triangle of size s, not degenerate in the precision
        let tri = loop {
            let t: [[f64; 3]; 3] = std::array::from_fn(|_| {
                sample::rpv(
                    prec,
                    sample::add(at, sample::mul(sample::ball(&mut rng), s)),
                )
            });
            let n = sample::cross(sample::sub(t[1], t[0]), sample::sub(t[2], t[0]));
            if sample::norm(n) > 0.05 * s * s {
                break t;
            }
        };
        // A primary ray from outside at a random point of it
        let aim = sample::point_in(&mut rng, &tri);
        let o = sample::rpv(
            prec,
            sample::add(aim, sample::mul(sample::unit(&mut rng), 3.0 * s)),
        );
        let d = sample::rpv(prec, sample::sub(aim, o));
        let input: Vec<f64> = [o, d, tri[0], tri[1], tri[2]].concat();
        // The exact hit
        let Some(t_exact) = exact_tri(&input).t() else {
            continue;
        };
        let p_star: [f64; 3] =
            std::array::from_fn(|k| (q(o[k]) + t_exact.clone() * q(d[k])).to_f64());
        let hit_ulp = ulp(p_star.iter().fold(0.0f64, |m, x| m.max(x.abs())), prec);
        // The renderer's hit and point
        let f = |a: [f64; 3]| a.map(F::from_f64);
        let (of, df, tf) = (f(o), f(d), tri.map(f));
        let Some(h) = triangle::method::<F>(INTERSECTOR)(of, df, tf) else {
            continue;
        };
        let (p, err) = triangle::hit_point(INTERSECTOR, of, df, &tf, &h);
        let nrm = sample::normalize(sample::cross(
            sample::sub(tri[1], tri[0]),
            sample::sub(tri[2], tri[0]),
        ));
        let nf = f(nrm);
        let towards_o = sample::dot(nrm, d) < 0.0;
        for k in 0..SPAWNED {
            // Half to the side the primary ray came from, half through
            let reflect = k % 2 == 0;
            let w = loop {
                let w = sample::unit(&mut rng);
                let side = sample::dot(w, nrm) > 0.0;
                if w.iter().any(|x| *x != 0.0) && (side == towards_o) == reflect {
                    break sample::rpv(prec, w);
                }
            };
            if sample::dot(w, nrm) == 0.0 {
                continue;
            }
            let query: Vec<f64> = [
                p.map(|x| x.to_f64()),
                err.map(|x| x.to_f64()),
                nf.map(|x| x.to_f64()),
                w,
                [h.t.to_f64(), o[0], o[1]],
                [o[2], d[0], d[1]],
                [d[2], 0.0, 0.0],
            ]
            .concat()[..QUERY_LEN]
                .to_vec();
            out.push(Ray {
                tri,
                query,
                hit_ulp,
            });
        }
        made += 1;
    }
    out
}

/// What a rule's answer does on one ray.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// The exact oracle finds the new ray on its own triangle at `t > t_min`.
    pub self_hit: bool,
    /// The exact `t` of that hit.
    pub self_hit_t: Option<f64>,
    /// The renderer's intersector finds it there.
    pub self_hit_intersector: bool,
    /// The height of the first point the new ray takes hits from above the triangle's plane,
    /// on the side it leaves to (scene units; negative: behind the surface).
    pub reach: f64,
    /// How far that point lies from the exact hit along the surface (scene units): what a
    /// tilted neighbour adds to the reach ([`TILT_DEGREES`]).
    pub along: f64,
}

/// The tilt of the second neighbour: a plane through the point `g` above the hit, tilted by
/// this angle toward where the new ray starts (the worst direction). Its smallest resolved gap
/// is `reach + tan(tilt)·along`: a rule that moves the origin along the surface or along the
/// new ray (a `t_min`) skips a tilted neighbour, or the underside of a sphere resting on the
/// surface near the hit (locally such a plane), well before a parallel one.
pub const TILT_DEGREES: f64 = 10.0;

/// The spawned ray of `s` against its own triangle: the triangle audit's 15 inputs
/// `o' w p0 p1 p2`.
fn spawned_input(ray: &Ray, s: &Spawned) -> Vec<f64> {
    [
        s.origin,
        v3(&ray.query, 9),
        ray.tri[0],
        ray.tri[1],
        ray.tri[2],
    ]
    .concat()
}

/// The `t` the intersector `method` (a triangle routine: built-in or the user's, through the
/// outside-routine machinery, in batches) finds on each spawned ray (`None`: a miss).
pub fn intersect(
    method: &dyn crate::shapes::shape::Method,
    prec: Precision,
    rays: &[(&Ray, &Spawned)],
) -> Result<Vec<Option<f64>>, String> {
    let mut out = Vec::with_capacity(rays.len());
    let inputs: Vec<Vec<f64>> = rays.iter().map(|(r, s)| spawned_input(r, s)).collect();
    for chunk in inputs.chunks(crate::audit::run::CHUNK as usize) {
        let answers = crate::audit::run::answers(&[method], prec, chunk)?.remove(0);
        for (a, x) in answers.iter().zip(chunk) {
            // The triangle contract: a miss (0) or a hit (1) with a finite t; anything else is
            // no answer to count
            let t = a.values.first().copied();
            match (a.count, t) {
                (0, _) => out.push(None),
                (1, Some(t)) if t.is_finite() => out.push(Some(t)),
                _ => {
                    return Err(format!(
                        "intersector '{}': answered {} {:?} to the spawned ray {}; want 0, or 1 and a finite t",
                        method.name(),
                        a.count,
                        a.values,
                        crate::audit::exec::case_line(prec, x).trim_end()
                    ))
                }
            }
        }
    }
    Ok(out)
}

/// Whether a rule's answer is finite (a built-in rule's offset can overflow on absurd input).
pub fn finite(s: &Spawned) -> bool {
    s.origin.iter().all(|x| x.is_finite()) && s.t_min.is_finite() && s.t_min >= 0.0
}

/// The error for an answer that is not [`finite`].
pub fn not_finite(rule: &str, s: &Spawned, prec: Precision, query: &[f64]) -> String {
    format!(
        "spawn rule '{rule}': answered origin {:?}, t_min {} to the query {}: not finite (or t_min < 0)",
        s.origin,
        s.t_min,
        crate::audit::exec::case_line(prec, query).trim_end()
    )
}

/// Judges a rule's answer `s` on `ray`, with the intersector's `t` on the spawned ray
/// ([`intersect`]).
pub fn judge(ray: &Ray, s: &Spawned, intersector_t: Option<f64>) -> Verdict {
    let w = v3(&ray.query, 9);
    let input = spawned_input(ray, s);
    let t_min = q(s.t_min);
    let exact = exact_tri(&input).t().filter(|t| *t > t_min);
    // A NaN t is no hit; any other t past t_min is one
    let intersector = intersector_t.is_some_and(|t| t > s.t_min);
    // The reach: n·(o' + t_min·w − p0) / |n|, n turned to w's side
    let [a, b, c] = ray.tri.map(|p| p.map(q));
    let e1: [Rational; 3] = std::array::from_fn(|i| b[i].clone() - &a[i]);
    let e2: [Rational; 3] = std::array::from_fn(|i| c[i].clone() - &a[i]);
    let n: [Rational; 3] = std::array::from_fn(|i| {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        e1[j].clone() * &e2[k] - e1[k].clone() * &e2[j]
    });
    let dot = |x: &[Rational; 3], y: &[Rational; 3]| -> Rational {
        x.iter().zip(y).map(|(u, v)| u.clone() * v).sum()
    };
    let wq = w.map(q);
    let start: [Rational; 3] =
        std::array::from_fn(|i| q(s.origin[i]) + t_min.clone() * &wq[i] - &a[i]);
    let mut h = dot(&n, &start);
    if dot(&n, &wq) < 0 {
        h = -h;
    }
    // h/|n| without overflow: h over the normal's largest component (exact), then over the
    // length of the normal so scaled (in [1, √3]); clamped to the largest finite value
    let big = n
        .iter()
        .map(|x| x.clone().abs())
        .max()
        .expect("three components");
    let scaled: [Rational; 3] = std::array::from_fn(|i| n[i].clone() / &big);
    let reach = ((h.clone() / &big).to_f64() / dot(&scaled, &scaled).to_f64().sqrt())
        .clamp(-f64::MAX, f64::MAX);
    // Along the surface: |Δ|² − (n·Δ)²/(n·n), Δ = start − p*, p* the exact primary hit (the
    // start's height over the plane is the same from p0 and from p*)
    let primary: Vec<f64> = [
        v3(&ray.query, 13),
        v3(&ray.query, 16),
        ray.tri[0],
        ray.tri[1],
        ray.tri[2],
    ]
    .concat();
    let along = match exact_tri(&primary).t() {
        Some(t) => {
            let p_star: [Rational; 3] = std::array::from_fn(|i| {
                q(ray.query[13 + i]) + t.clone() * q(ray.query[16 + i]) - &a[i]
            });
            let delta: [Rational; 3] = std::array::from_fn(|i| start[i].clone() - &p_star[i]);
            // Scaled by the largest component so that no square overflows
            let m = delta
                .iter()
                .map(|x| x.clone().abs())
                .max()
                .expect("three components");
            if m == 0 {
                0.0
            } else {
                let u: [Rational; 3] = std::array::from_fn(|i| delta[i].clone() / &m);
                let hn = dot(&n, &u);
                let t2 = dot(&u, &u) - hn.clone() * &hn / dot(&n, &n);
                (t2.to_f64().max(0.0).sqrt() * m.to_f64()).min(f64::MAX)
            }
        }
        None => 0.0,
    };
    Verdict {
        self_hit: exact.is_some(),
        self_hit_t: exact.map(|t| t.to_f64()),
        self_hit_intersector: intersector,
        reach,
        along,
    }
}

/// The replay line of `ray` under `rule`: `rayproof spawn … --replay -- VALUES` (the query,
/// then the triangle's 9 values); `intersector` the options that bring back the run's
/// intersector (empty for the default).
pub fn replay_line(rule: &dyn SpawnRule, prec: Precision, ray: &Ray, intersector: &str) -> String {
    let rule_how = rule
        .replay()
        .unwrap_or_else(|| format!("--rule {}", rule.name()));
    let how = if intersector.is_empty() {
        rule_how
    } else {
        format!("{rule_how} {intersector}")
    };
    let values: Vec<String> = ray
        .query
        .iter()
        .chain(ray.tri.iter().flatten())
        .map(|x| hex_text(*x))
        .collect();
    format!(
        "rayproof spawn {how} --precision {} --replay -- {}",
        prec.name(),
        values.join(" ")
    )
}

/// A ray from a replay line's values (the query, then the triangle).
pub fn ray_of(values: &[f64], prec: Precision) -> Result<Ray, String> {
    if values.len() != QUERY_LEN + 9 {
        return Err(format!(
            "a spawn replay takes {} values (the {QUERY_LEN} of the query, then the triangle's 9); got {}",
            QUERY_LEN + 9,
            values.len()
        ));
    }
    if values.iter().any(|x| !x.is_finite()) {
        return Err("a spawn replay's values must be finite".into());
    }
    let t = &values[QUERY_LEN..];
    let zero = |k: usize| values[k..k + 3].iter().all(|x| *x == 0.0);
    if zero(6) || zero(9) {
        return Err(
            "a spawn replay's normal (values 7-9) and direction (10-12) must not be zero".into(),
        );
    }
    if values[3..6].iter().any(|x| *x < 0.0) {
        return Err("a spawn replay's error bound (values 4-6) must not be negative".into());
    }
    let tri: Vec<f64> = [values[0], values[0], values[0], 1.0, 0.0, 0.0]
        .iter()
        .chain(t)
        .copied()
        .collect();
    if matches!(exact_tri(&tri), ExactTri::Invalid) {
        return Err("a spawn replay's triangle (the last 9 values) is degenerate".into());
    }
    let p = v3(values, 0);
    Ok(Ray {
        tri: [v3(t, 0), v3(t, 3), v3(t, 6)],
        query: values[..QUERY_LEN].to_vec(),
        hit_ulp: ulp(p.iter().fold(0.0f64, |m, x| m.max(x.abs())), prec),
    })
}

/// The rows of `rule` over `cells`, with pbrt-v4's watertight test as the intersector.
pub fn rows(rule: &dyn SpawnRule, cells: &[Cell]) -> Result<Vec<SpawnRow>, String> {
    rows_with(rule, cells, &watertight(), "")
}

/// The rows of `rule` over `cells`: one call of the rule for all their rays, then one of the
/// `intersector` (a triangle routine) for all the spawned rays; replay lines carry
/// `intersector_option` (the options naming it, empty for the default).
pub fn rows_with(
    rule: &dyn SpawnRule,
    cells: &[Cell],
    intersector: &dyn crate::shapes::shape::Method,
    intersector_option: &str,
) -> Result<Vec<SpawnRow>, String> {
    let mut out = vec![];
    for prec in [Precision::F32, Precision::F64] {
        let mine: Vec<&Cell> = cells.iter().filter(|c| c.prec == prec).collect();
        let queries: Vec<Vec<f64>> = mine
            .iter()
            .flat_map(|c| c.rays.iter().map(|r| r.query.clone()))
            .collect();
        if queries.is_empty() {
            continue;
        }
        let answers = rule.spawn(prec, &queries)?;
        if let Some((s, q)) = answers.iter().zip(&queries).find(|(s, _)| !finite(s)) {
            return Err(not_finite(rule.name(), s, prec, q));
        }
        if answers.len() != queries.len() {
            return Err(format!(
                "spawn rule '{}': {} answers to {} queries",
                rule.name(),
                answers.len(),
                queries.len()
            ));
        }
        let rays: Vec<(&Ray, &Spawned)> = mine
            .iter()
            .flat_map(|c| c.rays.iter())
            .zip(&answers)
            .collect();
        let ts = intersect(intersector, prec, &rays)?;
        let mut at = 0;
        for c in mine {
            let mut row = SpawnRow {
                rule: rule.name().to_string(),
                precision: prec.name().to_string(),
                scale: c.scale,
                placement: c.placement.to_string(),
                rays: 0,
                self_hits: 0,
                self_hits_intersector: 0,
                intersector: intersector.name().to_string(),
                behind: 0,
                gap: 0.0,
                gap_ulps: 0.0,
                gap_tilted: 0.0,
                gap_tilted_ulps: 0.0,
                self_hit_replay: None,
                gap_replay: None,
                behind_replay: None,
                verdict: String::new(),
            };
            for ray in &c.rays {
                let v = judge(ray, &answers[at], ts[at]);
                at += 1;
                row.rays += 1;
                if v.self_hit {
                    row.self_hits += 1;
                    if row.self_hit_replay.is_none() {
                        row.self_hit_replay =
                            Some(replay_line(rule, prec, ray, intersector_option));
                    }
                }
                row.self_hits_intersector += v.self_hit_intersector as u64;
                if v.reach < 0.0 {
                    row.behind += 1;
                    if row.behind_replay.is_none() {
                        row.behind_replay = Some(replay_line(rule, prec, ray, intersector_option));
                    }
                }
                let tilted = (v.reach + TILT_DEGREES.to_radians().tan() * v.along).min(f64::MAX);
                if tilted > row.gap_tilted {
                    row.gap_tilted = tilted;
                    row.gap_tilted_ulps = (tilted / ray.hit_ulp).min(f64::MAX);
                }
                if v.reach > row.gap {
                    row.gap = v.reach;
                    row.gap_ulps = (v.reach / ray.hit_ulp).min(f64::MAX);
                    row.gap_replay = Some(replay_line(rule, prec, ray, intersector_option));
                }
            }
            out.push(row);
        }
    }
    Ok(out)
}

/// The cells of a run: every precision of `precs`, scale and placement, `n` triangles each.
pub fn cells(seed: u64, precs: &[Precision], n: u64) -> Vec<Cell> {
    use rayon::prelude::*;
    let keys: Vec<(Precision, i32, &'static str)> = precs
        .iter()
        .flat_map(|&p| SCALES.flat_map(move |s| PLACEMENTS.map(|pl| (p, s, pl))))
        .collect();
    keys.into_par_iter()
        .map(|(p, s, pl)| cell(seed, p, s, pl, n))
        .collect()
}

/// A number of ulps as a table shows it: one decimal, or three digits and an exponent from 1e6.
pub fn ulps_text(x: f64) -> String {
    if x < 1e6 {
        format!("{x:.1}")
    } else {
        format!("{x:.3e}")
    }
}

/// The rows as a Markdown table.
pub fn markdown(rows: &[SpawnRow]) -> String {
    let intersector = rows
        .first()
        .map_or("intersector", |r| r.intersector.as_str());
    let mut t = format!(
        "| rule | precision | placement | scene size | rays | self-hits (exact) | self-hits ({}) | behind the surface | smallest resolved gap | in ulps of max\\|p\\| | tilted 10°, ulps | verdict |\n|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|\n",        intersector.replace('|', "\\|"),

    );
    for r in rows {
        // A cell with no ray says nothing of the rule
        let (gap, ulps, tilted) = if r.rays == 0 {
            ("—".to_string(), "—".to_string(), "—".to_string())
        } else {
            (
                format!("{:.3e}", r.gap),
                ulps_text(r.gap_ulps),
                ulps_text(r.gap_tilted_ulps),
            )
        };
        t += &format!(
            "| {} | {} | {} | 1e{} | {} | {} | {} | {} | {gap} | {ulps} | {tilted} | {} |\n",
            r.rule.replace('|', "\\|"),
            r.precision,
            r.placement,
            r.scale,
            r.rays,
            r.self_hits,
            r.self_hits_intersector,
            r.behind,
            r.verdict,
        );
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rule broken by hand: pbrt's with the offset's sign flipped, or with its error bound
    /// 1000× too small (issue 47, "a deliberately broken rule caught").
    struct Broken {
        flip: bool,
        weak: f64,
    }

    impl SpawnRule for Broken {
        fn name(&self) -> &str {
            "broken"
        }
        fn spawn(&self, prec: Precision, queries: &[Vec<f64>]) -> Result<Vec<Spawned>, String> {
            let mut q2 = queries.to_vec();
            for q in &mut q2 {
                for k in 3..6 {
                    q[k] *= self.weak;
                }
                if self.flip {
                    for k in 9..12 {
                        q[k] = -q[k];
                    }
                }
            }
            BuiltIn(0).spawn(prec, &q2)
        }
    }

    fn total(rows: &[SpawnRow]) -> (u64, u64) {
        rows.iter()
            .fold((0, 0), |(r, s), x| (r + x.rays, s + x.self_hits))
    }

    /// pbrt's rule leaves no self-hit at any scale; no offset at all re-hits; the rule with its
    /// sign flipped or its bound 1000× too small re-hits: the test has teeth.
    #[test]
    fn pbrts_rule_never_self_hits_and_broken_rules_do() {
        let cells = cells(7, &[Precision::F32, Precision::F64], 6);
        let (rays, hits) = total(&rows(&BuiltIn(0), &cells).unwrap());
        assert!(rays > 1000);
        assert_eq!(hits, 0);
        let none = total(&rows(&BuiltIn(4), &cells).unwrap()).1;
        assert!(none > rays / 10, "no offset: {none} of {rays}");
        let flipped = total(
            &rows(
                &Broken {
                    flip: true,
                    weak: 1.0,
                },
                &cells,
            )
            .unwrap(),
        )
        .1;
        assert!(flipped > rays / 4, "sign flipped: {flipped} of {rays}");
        let weak = total(
            &rows(
                &Broken {
                    flip: false,
                    weak: 1e-3,
                },
                &cells,
            )
            .unwrap(),
        )
        .1;
        assert!(weak > 0, "bound 1000x too small: no self-hit");
    }

    /// pbrt-v4's gap, by its error analysis rather than a sample: the computed point is within
    /// `err` of the exact hit (`|pᵢ − p*ᵢ| ≤ errᵢ`, pbrt's γ₇ bound), so its height over the
    /// plane is at most `d = Σ|n̂ᵢ|·errᵢ` either way; the rule moves it by `d` along `n̂` (`d`
    /// and `d·nᵢ` rounded: relative `η = 16u` covers them, the normal's rounding to the
    /// precision and the reach's own division) and each component's sum is rounded, then moved
    /// one ulp further: at most 2 ulps of `max(|pᵢ|, |o'ᵢ|)`. So for every ray, every seed and
    /// every scale `0 < reach ≤ (1 + η)·(2d + Σ|nᵢ|·2·ulp(max(|pᵢ|, |o'ᵢ|)))`: the smallest gap
    /// pbrt resolves is twice its error bound plus rounding, in scene units growing with |p|.
    #[test]
    fn pbrts_gap_is_bounded_by_twice_its_error_bound() {
        let mut checked = 0;
        for seed in [1, 2, 3, 99] {
            for c in cells(seed, &[Precision::F32, Precision::F64], 4) {
                let queries: Vec<Vec<f64>> = c.rays.iter().map(|r| r.query.clone()).collect();
                let answers = BuiltIn(0).spawn(c.prec, &queries).unwrap();
                let u = match c.prec {
                    Precision::F32 => 2f64.powi(-24),
                    Precision::F64 => 2f64.powi(-53),
                };
                for (ray, s) in c.rays.iter().zip(&answers) {
                    let v = judge(ray, s, None);
                    let (p, err, n) = (v3(&ray.query, 0), v3(&ray.query, 3), v3(&ray.query, 6));
                    let d: f64 = (0..3).map(|i| n[i].abs() * err[i]).sum();
                    let rounding: f64 = (0..3)
                        .map(|i| n[i].abs() * 2.0 * ulp(p[i].abs().max(s.origin[i].abs()), c.prec))
                        .sum();
                    let bound = (1.0 + 16.0 * u) * (2.0 * d + rounding);
                    assert!(
                        v.reach > 0.0 && v.reach <= bound,
                        "seed {seed} {} 1e{} {}: reach {:e}, bound {bound:e} (d {d:e})",
                        c.prec.name(),
                        c.scale,
                        c.placement,
                        v.reach
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 2000, "{checked}");
    }

    /// The reach is the answer of a bisection over the gap with the exact oracle: a neighbour
    /// triangle parallel to the first just below the reach is skipped, just above it is hit.
    #[test]
    fn the_reach_is_where_a_real_neighbour_starts_to_be_found() {
        let cells = cells(11, &[Precision::F32], 2);
        let mut checked = 0;
        for c in cells.iter().filter(|c| c.scale == 0 || c.scale == 5) {
            let answers = BuiltIn(2)
                .spawn(
                    c.prec,
                    &c.rays.iter().map(|r| r.query.clone()).collect::<Vec<_>>(),
                )
                .unwrap();
            for (ray, s) in c.rays.iter().zip(&answers).take(4) {
                let v = judge(ray, s, None);
                if v.reach <= 0.0 {
                    continue;
                }
                let w = v3(&ray.query, 9);
                let n = sample::normalize(sample::cross(
                    sample::sub(ray.tri[1], ray.tri[0]),
                    sample::sub(ray.tri[2], ray.tri[0]),
                ));
                let n = if sample::dot(n, w) < 0.0 {
                    sample::mul(n, -1.0)
                } else {
                    n
                };
                // The neighbour: the triangle scaled up 1000× about its centroid, lifted by g
                let found = |g: f64| {
                    let centre = sample::mul(
                        sample::add(sample::add(ray.tri[0], ray.tri[1]), ray.tri[2]),
                        1.0 / 3.0,
                    );
                    let big: Vec<f64> = ray
                        .tri
                        .iter()
                        .flat_map(|p| {
                            sample::add(
                                sample::add(centre, sample::mul(sample::sub(*p, centre), 1e3)),
                                sample::mul(n, g),
                            )
                        })
                        .collect();
                    let input: Vec<f64> = [s.origin.to_vec(), w.to_vec(), big].concat();
                    exact_tri(&input).t().is_some_and(|t| t > q(s.t_min))
                };
                // Bisection over g in [0, 4·reach]
                let (mut lo, mut hi) = (0.0, 4.0 * v.reach);
                assert!(!found(lo + v.reach * 1e-3) && found(hi));
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if found(mid) {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                let rel = (hi - v.reach).abs() / v.reach;
                // (the neighbour's vertices are rounded to f64 far from the origin)
                assert!(rel < 1e-4, "bisection {hi:e}, reach {:e}", v.reach);
                checked += 1;
            }
        }
        assert!(checked >= 4, "{checked}");
    }

    /// The tilted gap is the answer of a bisection too: a plane through `p* + g·n̂` tilted by
    /// [`TILT_DEGREES`] toward where the new ray starts, built as a large triangle, is skipped
    /// below `reach + tan(tilt)·along` and found above (a fixed t_min moves the start along the
    /// new ray, so its tilted gap is wider than its parallel one).
    #[test]
    fn the_tilted_gap_is_where_a_tilted_neighbour_starts_to_be_found() {
        let cells = cells(5, &[Precision::F64], 2);
        let mut checked = 0;
        for c in cells.iter().filter(|c| c.scale == 0) {
            let answers = BuiltIn(2)
                .spawn(
                    c.prec,
                    &c.rays.iter().map(|r| r.query.clone()).collect::<Vec<_>>(),
                )
                .unwrap();
            for (ray, s) in c.rays.iter().zip(&answers) {
                let v = judge(ray, s, None);
                if v.reach <= 0.0 || v.along <= 0.0 {
                    continue;
                }
                let w = v3(&ray.query, 9);
                let (o, d) = (v3(&ray.query, 13), v3(&ray.query, 16));
                let t = exact_tri(&[o.to_vec(), d.to_vec(), ray.tri.concat()].concat())
                    .t()
                    .unwrap()
                    .to_f64();
                let p = sample::add(o, sample::mul(d, t));
                let n = sample::normalize(sample::cross(
                    sample::sub(ray.tri[1], ray.tri[0]),
                    sample::sub(ray.tri[2], ray.tri[0]),
                ));
                let n = if sample::dot(n, w) < 0.0 {
                    sample::mul(n, -1.0)
                } else {
                    n
                };
                // ê: the start's offset from p* along the surface, normalised
                let start = sample::add(s.origin, sample::mul(w, s.t_min));
                let delta = sample::sub(start, p);
                let e =
                    sample::normalize(sample::sub(delta, sample::mul(n, sample::dot(n, delta))));
                let th = TILT_DEGREES.to_radians();
                let m = sample::add(sample::mul(n, th.cos()), sample::mul(e, th.sin()));
                if sample::dot(m, w) < 0.2 {
                    continue; // the new ray must run into the tilted plane
                }
                let u1 = sample::normalize(sample::cross(m, e));
                let u2 = sample::cross(m, u1);
                let found = |g: f64| {
                    let x = sample::add(p, sample::mul(n, g));
                    let big = 1e3;
                    let vs: Vec<f64> = [
                        sample::add(x, sample::mul(u1, big)),
                        sample::add(x, sample::add(sample::mul(u1, -big), sample::mul(u2, big))),
                        sample::add(x, sample::add(sample::mul(u1, -big), sample::mul(u2, -big))),
                    ]
                    .concat();
                    let input: Vec<f64> = [s.origin.to_vec(), w.to_vec(), vs].concat();
                    exact_tri(&input).t().is_some_and(|t| t > q(s.t_min))
                };
                let want = v.reach + th.tan() * v.along;
                let (mut lo, mut hi) = (0.0, 4.0 * want);
                assert!(!found(want * 0.5) && found(hi));
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if found(mid) {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                assert!(
                    (hi - want).abs() < 1e-6 * want,
                    "bisection {hi:e}, tilted gap {want:e}"
                );
                assert!(want > v.reach);
                checked += 1;
            }
        }
        assert!(checked >= 4, "{checked}");
    }
}
