//! Exactly one hit per mesh (issue 49, item 4): watertightness is counted per triangle pair
//! (`watertight.rs`); a renderer needs more: a ray through a shared edge or vertex of a mesh
//! must be reported **once** by the mesh, not zero times (a leak) nor twice (a double hit,
//! which any-hit counting, inside tests and transparency take as two surfaces).
//!
//! **Meshes.** Height fields z = h(x, y) over a grid of n×n cells (two triangles each) and a
//! fan of k triangles around a raised centre, of size s (10⁻⁴ … 10⁷), near the origin or
//! 10³–10⁵ sizes away; every shared vertex is one value of the precision, shared exactly by its
//! triangles. Heights vary by at most 0.2 of a cell, so each face's slope is at most 0.4.
//!
//! **Rays** come down at most 26.6° from the vertical (|d_xy| ≤ 0.5 |d_z|) at a shared interior
//! vertex (`vertex`) or a point of a shared interior edge (`edge`), from above the whole mesh;
//! the point, the origin and the direction are rounded to the precision, so a ray passes
//! through the vertex or edge or within rounding of it. **The truth needs no
//! oracle:** a continuous height field whose slopes times the ray's horizontal spread stay below
//! 1 (0.4 × 0.5) is crossed exactly once by such a ray, wherever exactly it lands in the interior.
//!
//! **Counts** per routine: rays with 0 hits (`leaks`), with 2 or more hits at one `t`
//! (`doubles`), and at different `t` (`split`: two surfaces where there is one). The built-in
//! triangle methods are reported.

use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::oracle::sample;
use crate::shapes::shape::{case_rng, hex_text};
use crate::shapes::triangle;
use rand::Rng;
use serde::Serialize;

/// Mesh kinds.
pub const MESHES: [&str; 2] = ["grid", "fan"];
/// Where the rays aim.
pub const AIMS: [&str; 2] = ["vertex", "edge"];
/// Scene sizes, as powers of ten.
pub const SCALES: std::ops::RangeInclusive<i32> = -4..=7;

type V = [f64; 3];

/// A mesh (vertices already values of the precision) and the points rays may aim at.
struct Mesh {
    tris: Vec<[V; 3]>,
    /// Shared interior vertices.
    vertices: Vec<V>,
    /// Shared interior edges.
    edges: Vec<[V; 2]>,
}

/// A grid of n×n cells or a fan of k triangles, of size s at `at`.
fn mesh(rng: &mut rand_chacha::ChaCha8Rng, prec: Precision, kind: &str, s: f64, at: V) -> Mesh {
    let rp = |v: V| sample::rpv(prec, v);
    match kind {
        "grid" => {
            let n = 4usize;
            let cell = s / n as f64;
            let pts: Vec<Vec<V>> = (0..=n)
                .map(|j| {
                    (0..=n)
                        .map(|i| {
                            let h = rng.random_range(0.0..0.2) * cell;
                            rp([at[0] + i as f64 * cell, at[1] + j as f64 * cell, at[2] + h])
                        })
                        .collect()
                })
                .collect();
            let mut tris = vec![];
            let mut edges = vec![];
            for j in 0..n {
                for i in 0..n {
                    let (a, b, c, d) = (pts[j][i], pts[j][i + 1], pts[j + 1][i + 1], pts[j + 1][i]);
                    tris.push([a, b, c]);
                    tris.push([a, c, d]);
                    // The diagonal is shared inside the cell; the cell's sides inside the grid
                    edges.push([a, c]);
                    if i + 1 < n {
                        edges.push([b, c]);
                    }
                    if j + 1 < n {
                        edges.push([c, d]);
                    }
                }
            }
            let vertices = (1..n)
                .flat_map(|j| (1..n).map(move |i| (i, j)))
                .map(|(i, j)| pts[j][i])
                .collect();
            Mesh {
                tris,
                vertices,
                edges,
            }
        }
        _ => {
            let k = rng.random_range(5..12usize);
            let centre = rp([at[0], at[1], at[2] + 0.2 * s]);
            let ring: Vec<V> = (0..k)
                .map(|i| {
                    let a =
                        (i as f64 + rng.random_range(-0.3..0.3)) / k as f64 * std::f64::consts::TAU;
                    let r = s * rng.random_range(0.8..1.2);
                    rp([
                        at[0] + r * a.cos(),
                        at[1] + r * a.sin(),
                        at[2] + rng.random_range(0.0..0.1) * s,
                    ])
                })
                .collect();
            let tris = (0..k)
                .map(|i| [centre, ring[i], ring[(i + 1) % k]])
                .collect();
            let edges = (0..k).map(|i| [centre, ring[i]]).collect();
            Mesh {
                tris,
                vertices: vec![centre],
                edges,
            }
        }
    }
}

/// One ray: its origin and direction, values of the precision.
#[derive(Clone, Debug)]
pub struct OnceRay {
    /// Which mesh (its seed's index) and the ray.
    pub o: V,
    /// Direction.
    pub d: V,
}

/// What one routine made of one ray: how many triangles it hit, and whether at more than one t.
fn count<F: Real>(m: usize, tris: &[[V; 3]], ray: &OnceRay) -> (usize, bool) {
    let f = |v: V| v.map(F::from_f64);
    let (o, d) = (f(ray.o), f(ray.d));
    let ts: Vec<F> = tris
        .iter()
        .filter_map(|t| triangle::method::<F>(m)(o, d, t.map(f)).map(|h| h.t))
        .collect();
    let split = ts.iter().any(|t| *t != ts[0]);
    (ts.len(), split)
}

/// One row: a routine, a precision, a mesh kind and an aim over every size and placement.
#[derive(Clone, Debug, Serialize)]
pub struct OnceRow {
    /// The triangle routine.
    pub routine: String,
    /// `f32` or `f64`.
    pub precision: &'static str,
    /// `grid` or `fan`.
    pub mesh: &'static str,
    /// `vertex` or `edge`.
    pub aim: &'static str,
    /// Rays.
    pub rays: u64,
    /// Rays no triangle reported: the mesh leaks.
    pub leaks: u64,
    /// Rays reported by two or more triangles at one t.
    pub doubles: u64,
    /// Rays reported at two or more different t.
    pub split: u64,
    /// The smallest scene size (power of ten) with a leak.
    pub first_leak: Option<i32>,
    /// The first ray that was not reported exactly once, replayable with `rayproof probe
    /// --shape triangle` on each of its triangles: `o d` in hex floats, then the mesh's seed
    /// cell.
    pub example: Option<String>,
}

/// The rows of the built-in triangle routines × `precs`, `n` meshes per cell (size × placement),
/// a ray at each of their shared vertices and edges.
pub fn rows(seed: u64, precs: &[Precision], n: u64) -> Vec<OnceRow> {
    let mut out = vec![];
    for &prec in precs {
        for kind in MESHES {
            // Every mesh of this kind, with its rays by aim
            let mut cases: Vec<(i32, Vec<[V; 3]>, &'static str, OnceRay)> = vec![];
            for scale in SCALES {
                for placement in ["near", "far"] {
                    for i in 0..n {
                        let class = format!("{kind}-{placement}-{scale}");
                        let mut rng = case_rng(seed, "once", &class, prec, i);
                        let s = 10f64.powi(scale);
                        let at = sample::placed(&mut rng, placement, s);
                        let m = mesh(&mut rng, prec, kind, s, at);
                        let mut aims: Vec<(&'static str, V)> =
                            m.vertices.iter().map(|v| ("vertex", *v)).collect();
                        for e in &m.edges {
                            let u = rng.random_range(0.1..0.9);
                            let p = std::array::from_fn(|k| e[0][k] + u * (e[1][k] - e[0][k]));
                            aims.push(("edge", sample::rpv(prec, p)));
                        }
                        for (aim, p) in aims {
                            let d = sample::rpv(
                                prec,
                                [
                                    rng.random_range(-0.5..0.5),
                                    rng.random_range(-0.5..0.5),
                                    -1.0,
                                ]
                                .map(|x| x * s),
                            );
                            let o = sample::rpv(prec, std::array::from_fn(|k| p[k] - 2.0 * d[k]));
                            cases.push((scale, m.tris.clone(), aim, OnceRay { o, d }));
                        }
                    }
                }
            }
            for (r, info) in triangle::METHODS.iter().enumerate() {
                for aim in AIMS {
                    let mut row = OnceRow {
                        routine: info.name.to_string(),
                        precision: prec.name(),
                        mesh: kind,
                        aim,
                        rays: 0,
                        leaks: 0,
                        doubles: 0,
                        split: 0,
                        first_leak: None,
                        example: None,
                    };
                    for (scale, tris, a, ray) in cases.iter().filter(|c| c.2 == aim) {
                        let _ = a;
                        let (hits, split) = match prec {
                            Precision::F32 => count::<f32>(r, tris, ray),
                            Precision::F64 => count::<f64>(r, tris, ray),
                        };
                        row.rays += 1;
                        match hits {
                            0 => {
                                row.leaks += 1;
                                row.first_leak =
                                    Some(row.first_leak.map_or(*scale, |f: i32| f.min(*scale)));
                            }
                            1 => continue,
                            _ if split => row.split += 1,
                            _ => row.doubles += 1,
                        }
                        if row.example.is_none() {
                            let v: Vec<String> =
                                ray.o.iter().chain(&ray.d).map(|x| hex_text(*x)).collect();
                            row.example = Some(format!("{} hits: o d = {}", hits, v.join(" ")));
                        }
                    }
                    out.push(row);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wide_watertight_test_never_leaks_and_every_ray_is_counted() {
        let rows = rows(1, &Precision::ALL, 2);
        for r in &rows {
            assert!(r.rays > 0, "{r:?}");
            assert!(r.leaks + r.doubles + r.split <= r.rays);
            if r.routine == "watertight_wide" {
                assert_eq!(r.leaks, 0, "{r:?}");
            }
        }
    }
}
