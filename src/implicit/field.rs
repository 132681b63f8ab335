//! The implicit fields, each with the Lipschitz bound that makes its sphere tracing safe.
//!
//! Convention: `f(p) > 0` outside, `< 0` inside, `= 0` on the surface. A field with Lipschitz
//! constant `L` (`|f(p) − f(q)| ≤ L·|p − q|`) has no surface point within `|f(p)|/L` of `p`, so a
//! step of that length can never cross the surface (Hart 1996, §2).
//!
//! | field | L | why |
//! |---|---|---|
//! | SDF sphere, torus, box | 1 | exact Euclidean distances |
//! | smooth union (polynomial smin, blend k) | 1 | ∂smin/∂a, ∂smin/∂b ≥ 0 and sum to 1, so ∇ is a convex combination of the parts' gradients |
//! | blob: threshold − Σ sᵢ(1 − rᵢ²/Rᵢ²)² | Σ \|sᵢ\|·8/(3√3·Rᵢ) | \|d/dr s(1 − r²/R²)²\| peaks at r = R/√3 with value 8s/(3√3·R); the components add |
//! | MPU | measured, see [`super::mpu`] | max \|∇f\| on a dense sample × a safety factor (the `global` and `paper` tracers) |
//!
//! **Local bounds** ([`Field::step`], the `local` tracer): blobs and MPU carry a grid of proved
//! per-box bounds ([`super::lipschitz`]); the blob's are in [`Field::blob`]'s helper (the
//! supports that meet a box, each at its largest slope over the box's distances), the MPU's in
//! [`super::mpu`]. SDFs step by `f` (L = 1, no rounding allowance: left as it was).

use super::lipschitz::{CellBound, LocalBounds};
use super::mpu::Mpu;
use glam::DVec3;
use serde::Deserialize;
use std::sync::Arc;

/// One part of a signed-distance shape.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum SdfPart {
    /// A sphere.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
    },
    /// In the xz plane around +y, as the scene's torus.
    Torus {
        /// Centre.
        center: [f64; 3],
        /// Distance from the centre to the tube's centre line.
        major: f64,
        /// Tube radius.
        minor: f64,
    },
    /// Axis-aligned box.
    Box {
        /// Minimum corner.
        min: [f64; 3],
        /// Maximum corner.
        max: [f64; 3],
    },
}

impl SdfPart {
    /// The exact signed distance.
    #[inline]
    pub fn distance(&self, p: DVec3) -> f64 {
        match *self {
            SdfPart::Sphere { center, radius } => (p - DVec3::from_array(center)).length() - radius,
            SdfPart::Torus {
                center,
                major,
                minor,
            } => {
                let q = p - DVec3::from_array(center);
                let ring = (q.x * q.x + q.z * q.z).sqrt() - major;
                (ring * ring + q.y * q.y).sqrt() - minor
            }
            SdfPart::Box { min, max } => {
                let (lo, hi) = (DVec3::from_array(min), DVec3::from_array(max));
                let c = (lo + hi) * 0.5;
                let q = (p - c).abs() - (hi - lo) * 0.5;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
        }
    }

    /// A box around the part.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        match *self {
            SdfPart::Sphere { center, radius } => {
                let c = DVec3::from_array(center);
                (c - radius, c + radius)
            }
            SdfPart::Torus {
                center,
                major,
                minor,
            } => {
                let c = DVec3::from_array(center);
                let e = DVec3::new(major + minor, minor, major + minor);
                (c - e, c + e)
            }
            SdfPart::Box { min, max } => (DVec3::from_array(min), DVec3::from_array(max)),
        }
    }

    /// The first problem with the part's values.
    pub fn problem(&self) -> Option<String> {
        let fin = |v: &[f64]| v.iter().all(|x| x.is_finite());
        match *self {
            SdfPart::Sphere { center, radius } => (!(fin(&center) && radius > 0.0 && radius.is_finite()))
                .then(|| format!("sphere needs a finite center and radius > 0, got {center:?}, {radius}")),
            SdfPart::Torus {
                center,
                major,
                minor,
            } => (!(fin(&center) && minor > 0.0 && minor < major && major.is_finite())).then(|| {
                format!("torus needs a finite center and 0 < minor < major, got {center:?}, {major}, {minor}")
            }),
            SdfPart::Box { min, max } => (!fin(&min) || !fin(&max) || (0..3).any(|k| min[k] >= max[k]))
                .then(|| format!("box needs finite min < max on every axis, got {min:?}, {max:?}")),
        }
    }
}

/// One blob component: POV-Ray's `sphere { center, radius, strength }`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BlobComponent {
    /// Centre.
    pub center: [f64; 3],
    /// Radius of influence: the component adds nothing beyond it.
    pub radius: f64,
    /// Strength (negative strengths subtract).
    pub strength: f64,
}

/// An implicit field with its bound, ready to trace.
#[derive(Debug, Clone)]
pub enum Field {
    /// Parts joined by the polynomial smooth minimum with blend `k` (0: hard union).
    Sdf {
        /// The parts.
        parts: Vec<SdfPart>,
        /// Blend width `k` of the smooth minimum.
        blend: f64,
    },
    /// POV-Ray's blob: `threshold − Σ sᵢ(1 − r²/Rᵢ²)²` over components with `r < Rᵢ`.
    Blob {
        /// Field value of the surface.
        threshold: f64,
        /// The components.
        components: Vec<BlobComponent>,
        /// `1/Rᵢ²` and the Lipschitz bound, precomputed.
        inv_r2: Vec<f64>,
        /// The analytic global bound `Σ |sᵢ|·8/(3√3·Rᵢ)` (the module table).
        lipschitz: f64,
        /// Proved local bounds over the positive components' box.
        local: Arc<LocalBounds>,
    },
    /// A multi-level partition-of-unity surface fitted to points.
    Mpu(Arc<Mpu>),
}

/// The polynomial smooth minimum (quadratic, blend width `k`).
#[inline]
fn smin(a: f64, b: f64, k: f64) -> f64 {
    if k <= 0.0 {
        return a.min(b);
    }
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// The blob's local bounds (module table): over a box, `|∇f| ≤ Σ` over the components whose
/// support meets the box of the largest slope `σ(r) = 4|s|·r(1 − r²/R²)/R²` on the box's range
/// of distances `r` from the centre (σ rises to its peak 8|s|/(3√3·R) at `R/√3`, then falls);
/// components that miss the box add nothing there. The box grid covers the positive
/// components' box (which holds the zero set); outside it only negative components reach, so
/// the global floor is their summed peak. Evaluation error: each of `n` terms `s(1 − u)²` is
/// computed to within ~10 roundings of `|s|`, and the sum adds `n` more, so
/// `4(n + 20)·u·(|threshold| + Σ|sᵢ|)` over the components that meet the box.
fn blob_bounds(threshold: f64, components: &[BlobComponent]) -> LocalBounds {
    let peak = 8.0 / (3.0 * 3f64.sqrt());
    let floor_l = components
        .iter()
        .filter(|c| c.strength < 0.0)
        .map(|c| -c.strength * peak / c.radius)
        .sum::<f64>();
    let (lo, hi) = components
        .iter()
        .filter(|c| c.strength > 0.0)
        .map(|c| {
            let ctr = DVec3::from_array(c.center);
            (ctr - c.radius, ctr + c.radius)
        })
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), (c, d)| {
            (a.min(c), b.max(d))
        });
    if !(lo.cmple(hi).all()) {
        // No positive component: no surface, one cell
        return LocalBounds::build((DVec3::ZERO, DVec3::ONE), [1; 3], floor_l, |_, _| {
            CellBound {
                lipschitz: 0.0,
                error: 0.0,
                zero_free: true,
                curvature: 0.0,
                gradient_error: 0.0,
            }
        });
    }
    // Cells a quarter of the smallest positive radius across, at most 64 per axis
    let rmin = components
        .iter()
        .filter(|c| c.strength > 0.0)
        .map(|c| c.radius)
        .fold(f64::INFINITY, f64::min);
    let dims = [0, 1, 2].map(|k| (((hi[k] - lo[k]) / (0.25 * rmin)).ceil() as usize).clamp(1, 64));
    let n = components.len() as f64;
    LocalBounds::build((lo, hi), dims, floor_l, |blo, bhi| {
        // Slope bound, magnitude of the terms, and the density's range
        let (mut l, mut mag, mut dlo, mut dhi) = (0.0, threshold.abs(), 0.0, 0.0);
        let (mut hess, mut gmag) = (0.0, 0.0);
        for c in components {
            let ctr = DVec3::from_array(c.center);
            let near = (blo - ctr).max(ctr - bhi).max(DVec3::ZERO).length();
            if near >= c.radius * (1.0 + 1e-9) {
                continue;
            }
            let far = (blo - ctr)
                .abs()
                .max((bhi - ctr).abs())
                .length()
                .min(c.radius);
            let sigma = |r: f64| {
                let q = r / c.radius;
                4.0 * c.strength.abs() * q * (1.0 - q * q) / c.radius
            };
            let top = c.radius / 3f64.sqrt();
            l += if near <= top && top <= far {
                c.strength.abs() * peak / c.radius
            } else {
                sigma(near).max(sigma(far))
            };
            mag += c.strength.abs();
            // ∇² s(1 − u)² = −4s/R²·((1 − u)I − 2yyᵀ/R²): norm ≤ 4|s|/R²·max(1 − u, |1 − 3u|) ≤ 8|s|/R²
            hess += 8.0 * c.strength.abs() / (c.radius * c.radius);
            gmag += 4.0 * c.strength.abs() / c.radius;
            let (a, b) = (
                1.0 - (near / c.radius).powi(2),
                1.0 - (far / c.radius).powi(2),
            );
            let (a, b) = (c.strength * a * a, c.strength * b.max(0.0) * b.max(0.0));
            dlo += a.min(b);
            dhi += a.max(b);
        }
        let error = 4.0 * (n + 20.0) * 0.5 * f64::EPSILON * mag;
        // The slack 1e-9·mag covers the rounding of the range itself
        let (flo, fhi) = (threshold - dhi, threshold - dlo);
        CellBound {
            lipschitz: l,
            error,
            zero_free: flo > error + 1e-9 * mag || fhi < -(error + 1e-9 * mag),
            curvature: hess,
            // ∇f = Σ −4s(1 − u)y/R²: ~10 roundings per component of terms ≤ 4|s|/R, so the
            // vector's error is far below 1e-10 relative
            gradient_error: 1e-10 * gmag,
        }
    })
}

impl Field {
    /// A blob field (the Lipschitz bound is computed here).
    pub fn blob(threshold: f64, components: Vec<BlobComponent>) -> Field {
        let peak = 8.0 / (3.0 * 3f64.sqrt());
        let lipschitz = components
            .iter()
            .map(|c| c.strength.abs() * peak / c.radius)
            .sum::<f64>();
        let inv_r2 = components
            .iter()
            .map(|c| 1.0 / (c.radius * c.radius))
            .collect();
        let local = Arc::new(blob_bounds(threshold, &components));
        Field::Blob {
            threshold,
            components,
            inv_r2,
            lipschitz,
            local,
        }
    }

    /// A safe sphere-tracing step from `p`, signed as `f(p)` (negative inside): no surface point
    /// lies closer, or, with `dir` (a unit vector), none on the ray from `p` along `dir` within
    /// the step. SDFs: `f` itself (1-Lipschitz); blobs and MPU: the local bounds
    /// ([`super::lipschitz`]).
    #[inline]
    pub fn step(&self, p: DVec3, dir: Option<DVec3>) -> f64 {
        match self {
            Field::Sdf { .. } => self.eval(p),
            Field::Blob { local, .. } => Self::step_with(
                local,
                p,
                dir,
                || self.eval(p),
                || (self.eval(p), self.gradient(p)),
            ),
            Field::Mpu(m) => {
                Self::step_with(m.local_bounds(), p, dir, || m.eval(p), || m.eval_grad(p))
            }
        }
    }

    /// The local step at `p`: with the gradient where a zero may be near, else the value alone.
    #[inline]
    fn step_with(
        b: &LocalBounds,
        p: DVec3,
        dir: Option<DVec3>,
        value: impl Fn() -> f64,
        with_grad: impl Fn() -> (f64, DVec3),
    ) -> f64 {
        if b.near_zero(p) {
            let (f, g) = with_grad();
            b.step(p, f, Some(g), dir)
        } else {
            b.step(p, value(), None, None)
        }
    }

    /// The proved local bounds, for fields that have them (blobs and MPU).
    pub fn local_bounds(&self) -> Option<&LocalBounds> {
        match self {
            Field::Sdf { .. } => None,
            Field::Blob { local, .. } => Some(local),
            Field::Mpu(m) => Some(m.local_bounds()),
        }
    }

    /// `f(p)`: positive outside.
    #[inline]
    pub fn eval(&self, p: DVec3) -> f64 {
        match self {
            Field::Sdf { parts, blend } => {
                let mut d = f64::INFINITY;
                for part in parts {
                    d = smin(d, part.distance(p), *blend);
                }
                d
            }
            Field::Blob {
                threshold,
                components,
                inv_r2,
                ..
            } => {
                let mut density = 0.0;
                for (c, k) in components.iter().zip(inv_r2) {
                    let u = (p - DVec3::from_array(c.center)).length_squared() * k;
                    if u < 1.0 {
                        density += c.strength * (1.0 - u) * (1.0 - u);
                    }
                }
                threshold - density
            }
            Field::Mpu(m) => m.eval(p),
        }
    }

    /// The global Lipschitz bound of [`Field::eval`] (see the module table), proved.
    pub fn lipschitz(&self) -> f64 {
        match self {
            Field::Sdf { .. } => 1.0,
            Field::Blob { lipschitz, .. } => *lipschitz,
            Field::Mpu(m) => m.lipschitz(),
        }
    }

    /// A bound on the rounding error of [`Field::eval`] anywhere (0 for SDFs: not covered).
    pub fn eval_error(&self) -> f64 {
        self.local_bounds().map_or(0.0, |b| b.global().1)
    }

    /// `∇f` (analytic for blobs, central differences for SDFs, the MPU's own).
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        match self {
            Field::Blob {
                components, inv_r2, ..
            } => {
                let mut g = DVec3::ZERO;
                for (c, k) in components.iter().zip(inv_r2) {
                    let v = p - DVec3::from_array(c.center);
                    let u = v.length_squared() * k;
                    if u < 1.0 {
                        g += v * (4.0 * c.strength * (1.0 - u) * k);
                    }
                }
                g
            }
            Field::Sdf { .. } => {
                let h = 1e-7 * p.abs().max_element().max(1.0);
                let d = |e: DVec3| self.eval(p + e * h) - self.eval(p - e * h);
                DVec3::new(d(DVec3::X), d(DVec3::Y), d(DVec3::Z)) / (2.0 * h)
            }
            Field::Mpu(m) => m.gradient(p),
        }
    }

    /// A box that holds the whole zero set.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let grow = |(a, b): (DVec3, DVec3), (c, d): (DVec3, DVec3)| (a.min(c), b.max(d));
        let empty = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        match self {
            Field::Sdf { parts, .. } => parts.iter().map(SdfPart::bounds).fold(empty, grow),
            // The surface needs density ≥ threshold > 0, so a positive component within reach
            Field::Blob { components, .. } => components
                .iter()
                .filter(|c| c.strength > 0.0)
                .map(|c| {
                    let ctr = DVec3::from_array(c.center);
                    (ctr - c.radius, ctr + c.radius)
                })
                .fold(empty, grow),
            Field::Mpu(m) => m.bounds(),
        }
    }

    /// The field's kind, for reports.
    pub fn kind(&self) -> &'static str {
        match self {
            Field::Sdf { .. } => "sdf",
            Field::Blob { .. } => "blob",
            Field::Mpu(_) => "mpu",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blob_bound_holds_on_a_line_through_the_peak() {
        // One component: the steepest slope is 8s/(3√3 R) at r = R/√3
        let f = Field::blob(
            0.5,
            vec![BlobComponent {
                center: [0.0; 3],
                radius: 2.0,
                strength: 3.0,
            }],
        );
        let l = f.lipschitz();
        let mut worst: f64 = 0.0;
        for i in 0..2000 {
            let (a, b) = (i as f64 * 1e-3, i as f64 * 1e-3 + 1e-6);
            worst = worst.max((f.eval(DVec3::X * a) - f.eval(DVec3::X * b)).abs() / 1e-6);
        }
        assert!(worst <= l && worst > 0.999 * l, "{worst} vs {l}");
    }

    #[test]
    fn smooth_union_lies_below_the_hard_union() {
        let parts = vec![
            SdfPart::Sphere {
                center: [0.0; 3],
                radius: 1.0,
            },
            SdfPart::Sphere {
                center: [1.5, 0.0, 0.0],
                radius: 1.0,
            },
        ];
        let hard = Field::Sdf {
            parts: parts.clone(),
            blend: 0.0,
        };
        let soft = Field::Sdf { parts, blend: 0.5 };
        let p = DVec3::new(0.75, 0.9, 0.0);
        assert!(soft.eval(p) < hard.eval(p));
        assert_eq!(soft.eval(DVec3::new(-3.0, 0.0, 0.0)), 2.0);
    }
}
