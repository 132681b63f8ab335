//! Watertightness (issue 6 item 3; issue 17 item 2 made it an audit class with replay lines):
//! rays that must hit a triangle mesh, counted per ray–triangle method and precision where no
//! triangle reports a hit. Deterministic for a seed. Two families of rays:
//!
//! - **Closed meshes**, rays from inside: a level-3 icosphere (1280 triangles, radius 1) `near`
//!   the origin and `far` from it (centred about `10⁵` away, where an `f32` ulp is 1/128 of the
//!   radius, as Embree's `verify` places its watertightness meshes). The origin is drawn within
//!   half the radius of the centre; the direction is `random`, or aimed at a random point of a
//!   mesh `edge`, or at a mesh `vertex` (the aim point is exact in `f64`, the direction rounded
//!   once). Every such ray crosses the mesh, so a ray no triangle reports escaped through a
//!   crack. The exact oracle confirms every escape (up to 64) and a sample of the other rays.
//! - **Folds**, rays from outside aimed at a point of the edge two triangles share (a random
//!   parallelogram, perturbed). Where the shared edge is *not* a silhouette seen from the ray's
//!   origin (the two triangles lie on opposite sides of the plane through the origin and the
//!   edge), a ray the exact oracle sends across must hit one of them: missing both is a leak.
//!   Where it is a silhouette, a ray grazing the fold can rightly miss both: such rays are
//!   counted as `grazing`, not as leaks. This is the case of issue 17: the exact oracle hits both
//!   triangles of a fold, 2.4e-7 and 4.4e-8 from the edge, and the `f32` watertight method misses
//!   both. That is what the method does by design: its edge functions are evaluated once per
//!   edge and shared by both triangles, so it cannot leak *between* them, but near a silhouette
//!   both lie on one side of the edge and a rounding of the shear moves the ray off both at once.
//!   The `grazing` column counts it; its replay line shows it. Most such misses are on rays the
//!   oracle calls ill-posed (a one-ulp move of some input changes the answer). The rest
//!   (`grazing_well_posed`; e.g. 1 of about 2,900 `f64` fold rays at seed 8) are false misses
//!   of a single triangle by a rounding of the shear larger than one ulp of an input: that is
//!   the method's single-triangle accuracy, which the triangle audit's rows judge (its
//!   watertight rows carry measured false-miss rates), not a leak, so they are reported and not
//!   failed. (Holding them to 0, as this test first did, failed seeds 8, 11 and 16.)
//!
//! A row's `replay` is the `rayproof probe triangle` line of the first escaped (or grazing) ray
//! and the triangle the exact oracle says it crosses first.

use crate::numerics::exact::q;
use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::oracle::sample::{add, ball, lu, mul, normalize, rpv, sub, unit, V};
use crate::shapes::shape::{case_rng, probe_line_with, Truth};
use crate::shapes::triangle::{self, exact_tri, method, ExactTri, METHODS};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use rug::Rational;
use serde::{Deserialize, Serialize};

/// One method × precision × mesh × ray kind.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WatertightRow {
    /// The triangle method (a built-in, or a routine from outside the crate).
    pub method: String,
    /// `"f32"` or `"f64"`.
    pub precision: String,
    /// `near` or `far` closed mesh, or `fold`.
    pub mesh: String,
    /// `random`, `edge`, `vertex` (closed meshes) or `shared_edge` (folds).
    pub kind: String,
    /// Rays cast.
    pub rays: u64,
    /// Rays the oracle sends across the mesh for which no triangle reported a hit.
    pub escaped: u64,
    /// `escaped / rays`.
    pub rate: f64,
    /// Fold rays across a silhouette edge that the oracle says hit and the method misses
    /// (not a leak; see the module doc).
    pub grazing: u64,
    /// Of those, rays the oracle does not call ill-posed for either triangle (a one-ulp move of
    /// no input changes its answer): single-triangle false misses, reported (see the module doc).
    pub grazing_well_posed: u64,
    /// Rays checked by the exact oracle (closed meshes: every escape, up to 64, plus 16 others).
    pub oracle_checked: u64,
    /// Checked rays from inside a closed mesh that the oracle finds escaping, or crossing an
    /// even number of times off edges and vertices: must be 0.
    pub oracle_violations: u64,
    /// The replay line of the first escaped (or else grazing) ray.
    pub replay: Option<String>,
    /// What the row is held to ([`crate::audit::robustness::judge`]): `pass` or `fail` (no
    /// escape), `reported` (a built-in method not watertight by design).
    #[serde(default)]
    pub verdict: String,
}

/// A closed mesh: vertices (rounded once to the precision, shared exactly) and index triples.
pub struct Mesh {
    /// The vertices.
    pub vertices: Vec<V>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside.
    pub faces: Vec<[usize; 3]>,
}

/// The subdivided icosahedron of `level` around `center` with radius `radius`, outward faces.
pub fn icosphere(level: u32, center: V, radius: f64, prec: Precision) -> Mesh {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let mut vs: Vec<V> = [
        [-1.0, g, 0.0],
        [1.0, g, 0.0],
        [-1.0, -g, 0.0],
        [1.0, -g, 0.0],
        [0.0, -1.0, g],
        [0.0, 1.0, g],
        [0.0, -1.0, -g],
        [0.0, 1.0, -g],
        [g, 0.0, -1.0],
        [g, 0.0, 1.0],
        [-g, 0.0, -1.0],
        [-g, 0.0, 1.0],
    ]
    .to_vec();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let norm = normalize;
    vs = vs.into_iter().map(norm).collect();
    for _ in 0..level {
        let mut mid = std::collections::HashMap::new();
        let mut next = vec![];
        for f in &faces {
            let m: Vec<usize> = (0..3)
                .map(|k| {
                    let (a, b) = (f[k], f[(k + 1) % 3]);
                    *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                        vs.push(norm(mul(add(vs[a], vs[b]), 0.5)));
                        vs.len() - 1
                    })
                })
                .collect();
            next.extend([
                [f[0], m[0], m[2]],
                [f[1], m[1], m[0]],
                [f[2], m[2], m[1]],
                [m[0], m[1], m[2]],
            ]);
        }
        faces = next;
    }
    let vertices = vs
        .into_iter()
        .map(|v| rpv(prec, add(center, mul(v, radius))))
        .collect();
    Mesh { vertices, faces }
}

/// The closed meshes: name and centre (radius 1).
pub const MESHES: [(&str, V); 2] = [
    ("near", [0.25, -0.5, 0.125]),
    ("far", [1.0e5, -0.75e5, 0.5e5]),
];
/// The ray kinds from inside a closed mesh.
pub const KINDS: [&str; 3] = ["random", "edge", "vertex"];

/// The 15 inputs of a ray and a triangle.
fn flat(o: V, d: V, p: [V; 3]) -> Vec<f64> {
    [&o[..], &d[..], &p.concat()[..]].concat()
}

/// The triangle of `tris` the exact oracle says the ray crosses first, as a probe line (with a
/// routine of yours named by `extra`, its `--plugin`/`--exec` options: helper-21 F5 found them
/// left out, so the line replayed the built-ins, not the routine that escaped).
fn replay_line(
    prec: Precision,
    extra: Option<&str>,
    tris: &[[V; 3]],
    o: V,
    d: V,
) -> Option<String> {
    let first = tris
        .iter()
        .filter_map(|p| exact_tri(&flat(o, d, *p)).t().map(|t| (t, *p)))
        .min_by(|a, b| a.0.cmp(&b.0))?;
    Some(probe_line_with(
        "triangle",
        prec,
        extra,
        &flat(o, d, first.1),
    ))
}

/// The rays from inside one closed mesh, each drawn from its own seed.
fn closed_rays(
    seed: u64,
    rays: u64,
    prec: Precision,
    name: &str,
    kind: &str,
    mesh: &Mesh,
    centre: V,
) -> Vec<(V, V)> {
    (0..rays)
        .map(|i| {
            let mut rng = case_rng(seed, "watertight", &format!("{name} {kind}"), prec, i);
            let o = rpv(prec, add(centre, mul(ball(&mut rng), 0.5)));
            let aim = match kind {
                "random" => add(o, unit(&mut rng)),
                _ => {
                    let f = mesh.faces[rng.random_range(0..mesh.faces.len())];
                    let (a, b) = (mesh.vertices[f[0]], mesh.vertices[f[1]]);
                    let u = if kind == "vertex" {
                        0.0
                    } else {
                        rng.random::<f64>()
                    };
                    add(a, mul(sub(b, a), u))
                }
            };
            (o, rpv(prec, sub(aim, o)))
        })
        .collect()
}

/// The rows of routines from outside the crate (any [`crate::audit::Method`] of the triangle
/// shape, called per ray and triangle in batches): the same meshes, rays, oracle checks and
/// folds as [`run`]. A ray from inside a closed mesh is put to the triangles around where it
/// leaves the mesh (the 1-ring of every triangle the wide `f64` watertight method hits), not to
/// all 1,280: a leak is a miss there, and the calls stay few enough for a library that builds a
/// scene per call.
pub fn run_outside(
    seed: u64,
    rays: u64,
    prec: Precision,
    methods: &[&dyn crate::audit::Method],
) -> Result<Vec<WatertightRow>, String> {
    let mut rows = vec![];
    let wide = METHODS
        .iter()
        .position(|m| m.name == "watertight_wide")
        .expect("a built-in method");
    for (name, centre) in MESHES {
        let mesh = icosphere(3, centre, 1.0, prec);
        let tris: Vec<[V; 3]> = mesh
            .faces
            .iter()
            .map(|f| f.map(|i| mesh.vertices[i]))
            .collect();
        // Each vertex's faces, for the 1-rings
        let mut around = vec![vec![]; mesh.vertices.len()];
        for (k, f) in mesh.faces.iter().enumerate() {
            for &v in f {
                around[v].push(k);
            }
        }
        for kind in KINDS {
            let cases = closed_rays(seed, rays, prec, name, kind, &mesh, centre);
            // The candidate triangles of each ray
            let candidates: Vec<Vec<usize>> = cases
                .par_iter()
                .map(|&(o, d)| {
                    let f = method::<f64>(wide);
                    let mut c: Vec<usize> = tris
                        .iter()
                        .enumerate()
                        .filter(|(_, p)| f(o, d, **p).is_some())
                        .flat_map(|(k, _)| {
                            mesh.faces[k]
                                .iter()
                                .flat_map(|&v| around[v].iter().copied())
                        })
                        .collect();
                    c.sort_unstable();
                    c.dedup();
                    c
                })
                .collect();
            let inputs: Vec<Vec<f64>> = cases
                .iter()
                .zip(&candidates)
                .flat_map(|(&(o, d), c)| {
                    let tris = &tris;
                    c.iter().map(move |&k| flat(o, d, tris[k]))
                })
                .collect();
            for m in methods {
                let hits = any_hits(*m, prec, &inputs, candidates.iter().map(Vec::len))?;
                let escaped: Vec<usize> = (0..cases.len()).filter(|&k| !hits[k]).collect();
                let sample: Vec<usize> = escaped.iter().copied().take(64).collect();
                let violations = sample
                    .par_iter()
                    .filter(|&&k| !exact_mesh_ok(&mesh, cases[k].0, cases[k].1))
                    .count();
                let mut r = row(0, prec, name, kind, rays);
                r.method = m.name().to_string();
                r.escaped = escaped.len() as u64;
                r.rate = r.escaped as f64 / rays.max(1) as f64;
                r.oracle_checked = sample.len() as u64;
                r.oracle_violations = violations as u64;
                r.replay = escaped.first().and_then(|&k| {
                    replay_line(prec, m.replay().as_deref(), &tris, cases[k].0, cases[k].1)
                });
                rows.push(r);
            }
        }
    }
    // The folds: both triangles of each
    let folds = fold_cases(seed, rays, prec);
    let inputs: Vec<Vec<f64>> = folds
        .iter()
        .flat_map(|(tris, o, d, _)| tris.iter().map(move |p| flat(*o, *d, *p)))
        .collect();
    for m in methods {
        let hits = any_hits(*m, prec, &inputs, folds.iter().map(|_| 2))?;
        let missed: Vec<&Fold> = folds
            .iter()
            .zip(&hits)
            .filter(|(_, h)| !**h)
            .map(|(f, _)| f)
            .collect();
        let mut r = fold_row(&missed, prec, m.replay().as_deref(), folds.len());
        r.method = m.name().to_string();
        rows.push(r);
    }
    Ok(rows)
}

/// Whether each ray hits any of its triangles, by an outside method: `inputs` holds each ray's
/// cases in turn, `counts` how many each ray has. Asked in batches of 4,096 cases.
fn any_hits(
    m: &dyn crate::audit::Method,
    prec: Precision,
    inputs: &[Vec<f64>],
    counts: impl Iterator<Item = usize>,
) -> Result<Vec<bool>, String> {
    let mut answers = Vec::with_capacity(inputs.len());
    for chunk in inputs.chunks(4096) {
        answers.extend(m.answer(prec, chunk)?.into_iter().map(|a| a.count > 0));
    }
    let mut out = vec![];
    let mut at = 0;
    for n in counts {
        out.push(answers[at..at + n].iter().any(|&h| h));
        at += n;
    }
    Ok(out)
}

/// Whether method `m` reports any hit of the ray on the triangles.
fn any_hit<F: Real>(m: usize, tris: &[[V; 3]], o: V, d: V) -> bool {
    let f = method::<F>(m);
    let (o, d) = (o.map(F::from_f64), d.map(F::from_f64));
    tris.iter()
        .any(|p| f(o, d, p.map(|v| v.map(F::from_f64))).is_some())
}

/// The exact check of one ray from inside: at least one crossing, and an odd number of them
/// unless the ray touches an edge or a vertex of a triangle it crosses.
pub fn exact_mesh_ok(mesh: &Mesh, o: V, d: V) -> bool {
    let (mut count, mut boundary) = (0u32, false);
    for f in &mesh.faces {
        let p = f.map(|i| mesh.vertices[i]);
        if let ExactTri::Hit { boundary: b, .. } = exact_tri(&flat(o, d, p)) {
            count += 1;
            boundary |= b;
        }
    }
    count > 0 && (boundary || count % 2 == 1)
}

/// Every row: both closed meshes × [`KINDS`] and the folds, every method, `rays` rays each.
pub fn run(seed: u64, rays: u64, prec: Precision) -> Vec<WatertightRow> {
    let mut rows = vec![];
    for (name, centre) in MESHES {
        rows.extend(closed(seed, rays, prec, name, centre));
    }
    rows.extend(folds(seed, rays, prec));
    rows
}

fn row(
    m: usize,
    prec: Precision,
    mesh: &'static str,
    kind: &'static str,
    rays: u64,
) -> WatertightRow {
    WatertightRow {
        method: METHODS[m].name.to_string(),
        precision: prec.name().into(),
        mesh: mesh.into(),
        kind: kind.into(),
        rays,
        escaped: 0,
        rate: 0.0,
        grazing: 0,
        grazing_well_posed: 0,
        oracle_checked: 0,
        oracle_violations: 0,
        replay: None,
        verdict: String::new(),
    }
}

/// Rays from inside one closed mesh.
fn closed(
    seed: u64,
    rays: u64,
    prec: Precision,
    name: &'static str,
    centre: V,
) -> Vec<WatertightRow> {
    let mesh = icosphere(3, centre, 1.0, prec);
    let tris: Vec<[V; 3]> = mesh
        .faces
        .iter()
        .map(|f| f.map(|i| mesh.vertices[i]))
        .collect();
    let mut rows = vec![];
    for kind in KINDS {
        // The rays: origin within half the radius of the centre, each drawn from its own seed
        let cases = closed_rays(seed, rays, prec, name, kind, &mesh, centre);
        for m in 0..METHODS.len() {
            let escaped: Vec<usize> = (0..cases.len())
                .into_par_iter()
                .filter(|&k| {
                    let (o, d) = cases[k];
                    !match prec {
                        Precision::F32 => any_hit::<f32>(m, &tris, o, d),
                        Precision::F64 => any_hit::<f64>(m, &tris, o, d),
                    }
                })
                .collect();
            // The oracle confirms every escape checked, and a sample of the others
            let sample: Vec<usize> = escaped
                .iter()
                .copied()
                .take(64)
                .chain((0..16).map(|k| k * cases.len() / 16))
                .filter(|&k| k < cases.len())
                .collect();
            let violations = sample
                .par_iter()
                .filter(|&&k| !exact_mesh_ok(&mesh, cases[k].0, cases[k].1))
                .count();
            let mut r = row(m, prec, name, kind, rays);
            r.escaped = escaped.len() as u64;
            r.rate = r.escaped as f64 / rays.max(1) as f64;
            r.oracle_checked = sample.len() as u64;
            r.oracle_violations = violations as u64;
            r.replay = escaped
                .first()
                .and_then(|&k| replay_line(prec, None, &tris, cases[k].0, cases[k].1));
            rows.push(r);
        }
    }
    rows
}

/// The sign of the orientation of `x` against the plane through `o`, `b`, `c` (exact).
fn side(o: V, b: V, c: V, x: V) -> i32 {
    let rel = |v: V| -> [Rational; 3] { std::array::from_fn(|i| q(v[i]) - q(o[i])) };
    let [u, v, w] = [rel(b), rel(c), rel(x)];
    let minor = |i: usize, j: usize| Rational::from(&v[i] * &w[j]) - Rational::from(&v[j] * &w[i]);
    let det = &u[0] * minor(1, 2) - &u[1] * minor(0, 2) + &u[2] * minor(0, 1);
    det.cmp0() as i32
}

/// One fold: triangles `a b c` and `c b e` sharing `b c`, and a ray from outside aimed at a
/// point of `b c`.
fn fold(rng: &mut ChaCha8Rng, prec: Precision) -> ([[V; 3]; 2], V, V) {
    let s = lu(rng, -2.0, 2.0);
    let at = mul(unit(rng), s * lu(rng, -1.0, 3.0));
    let pt = |rng: &mut ChaCha8Rng| add(at, mul(ball(rng), 10.0 * s));
    let (a, b, c) = (pt(rng), pt(rng), pt(rng));
    // The far vertex across b–c: a perturbed parallelogram
    let e = add(sub(add(b, c), a), mul(ball(rng), 3.0 * s));
    let [a, b, c, e] = [a, b, c, e].map(|v| rpv(prec, v));
    let o = rpv(prec, pt(rng));
    let aim = add(b, mul(sub(c, b), rng.random_range(0.1..0.9)));
    ([[a, b, c], [c, b, e]], o, rpv(prec, sub(aim, o)))
}

/// Whether the oracle calls the ray ill-posed against either triangle.
fn ill_posed(prec: Precision, tris: &[[V; 3]; 2], o: V, d: V) -> bool {
    tris.iter()
        .any(|p| match triangle::truth(&flat(o, d, *p), prec) {
            Truth::Answer(e) => e.ill_posed,
            Truth::Invalid => false,
        })
}

/// A fold, a ray the oracle says hits it, and whether the shared edge is a silhouette from the
/// ray's origin.
type Fold = ([[V; 3]; 2], V, V, bool);

/// The fold rays the oracle says hit.
fn fold_cases(seed: u64, rays: u64, prec: Precision) -> Vec<Fold> {
    (0..rays)
        .into_par_iter()
        .filter_map(|i| {
            let mut rng = case_rng(seed, "watertight", "fold shared_edge", prec, i);
            let (tris, o, d) = fold(&mut rng, prec);
            let ex = tris.map(|p| exact_tri(&flat(o, d, p)));
            if ex.contains(&ExactTri::Invalid) || ex.iter().all(|e| e.t().is_none()) {
                return None;
            }
            let [a, b, c] = tris[0];
            let silhouette = side(o, b, c, a) * side(o, b, c, tris[1][2]) >= 0;
            Some((tris, o, d, silhouette))
        })
        .collect()
}

/// The fold row of a method from the fold rays it missed (leaks where the edge is no
/// silhouette, grazing misses where it is).
fn fold_row(missed: &[&Fold], prec: Precision, extra: Option<&str>, rays: usize) -> WatertightRow {
    let leaks: Vec<_> = missed.iter().filter(|x| !x.3).collect();
    let mut r = row(0, prec, "fold", "shared_edge", rays as u64);
    r.escaped = leaks.len() as u64;
    r.rate = r.escaped as f64 / r.rays.max(1) as f64;
    r.grazing = (missed.len() - leaks.len()) as u64;
    r.grazing_well_posed = missed
        .iter()
        .filter(|x| x.3 && !ill_posed(prec, &x.0, x.1, x.2))
        .count() as u64;
    r.replay = leaks
        .first()
        .map(|x| ***x)
        .or(missed.first().map(|x| **x))
        .and_then(|(tris, o, d, _)| replay_line(prec, extra, &tris, o, d));
    r
}

/// Rays from outside aimed at the shared edges of folds.
fn folds(seed: u64, rays: u64, prec: Precision) -> Vec<WatertightRow> {
    let cases = fold_cases(seed, rays, prec);
    (0..METHODS.len())
        .map(|m| {
            let missed: Vec<&Fold> = cases
                .par_iter()
                .filter(|(tris, o, d, _)| match prec {
                    Precision::F32 => !any_hit::<f32>(m, tris, *o, *d),
                    Precision::F64 => !any_hit::<f64>(m, tris, *o, *d),
                })
                .collect();
            let mut r = fold_row(&missed, prec, None, cases.len());
            r.method = METHODS[m].name.to_string();
            r
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact `(x − p)·((b − p) × (c − p))` with rationals: which side of the plane p b c x lies.
    fn facing(p: V, b: V, c: V, x: V) -> std::cmp::Ordering {
        let r = |v: V| -> [Rational; 3] { std::array::from_fn(|i| q(v[i]) - q(p[i])) };
        let [u, v, w] = [r(b), r(c), r(x)];
        let cross = [
            Rational::from(&u[1] * &v[2]) - Rational::from(&u[2] * &v[1]),
            Rational::from(&u[2] * &v[0]) - Rational::from(&u[0] * &v[2]),
            Rational::from(&u[0] * &v[1]) - Rational::from(&u[1] * &v[0]),
        ];
        let dot = Rational::from(&w[0] * &cross[0])
            + Rational::from(&w[1] * &cross[1])
            + Rational::from(&w[2] * &cross[2]);
        dot.cmp0()
    }

    /// The fold rows' leak counts, against an independent count on the same folds: a ray that
    /// misses both triangles leaks unless the shared edge is a silhouette from its origin, here
    /// decided the other way round (one triangle faces the origin and the other does not), with
    /// the second triangle's far vertex found by value, not by index. The chapter's method and
    /// Möller–Trumbore leak through folds (known leaks), so a classification that hides them
    /// (calling every edge a silhouette, say) fails here.
    #[test]
    fn fold_leaks_match_an_independent_silhouette_count() {
        let prec = Precision::F32;
        let cases = fold_cases(1, 3000, prec);
        let rows = folds(1, 3000, prec);
        for (m, info) in METHODS.iter().enumerate() {
            let independent = cases
                .iter()
                .filter(|(tris, o, d, _)| !any_hit::<f32>(m, tris, *o, *d))
                .filter(|(tris, o, _, _)| {
                    let [a, b, c] = tris[0];
                    let e = *tris[1].iter().find(|v| **v != b && **v != c).unwrap();
                    // Triangle a b c and triangle c b e, wound alike: the edge is a silhouette
                    // when the origin sees one from the front and the other from the back
                    let f0 = facing(a, b, c, *o);
                    let f1 = facing(c, b, e, *o);
                    !(f0 != f1 || f0 == std::cmp::Ordering::Equal)
                })
                .count() as u64;
            let row = rows.iter().find(|r| r.method == info.name).unwrap();
            assert_eq!(row.escaped, independent, "{}", info.name);
            if !info.robust && info.name != "watertight" {
                assert!(independent > 0, "{}: no known leak to see", info.name);
            }
        }
    }
}
