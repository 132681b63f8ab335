//! What every ray–sphere method takes and gives: the ray, the sphere and the hit.

use crate::numerics::real::Real;

/// A ray `o + t·d`, in the precision `F`.
#[derive(Clone, Copy, Debug)]
pub struct Ray<F: Real> {
    /// Origin `o`.
    pub origin: F::Vec3,
    /// Direction `d`, as given (not renormalised).
    pub dir: F::Vec3,
}

/// A sphere `|p − c| = r`.
#[derive(Clone, Copy, Debug)]
pub struct Sphere<F: Real> {
    /// Centre `c`.
    pub center: F::Vec3,
    /// Radius `r`.
    pub radius: F,
}

/// A hit: the ray parameter, and for methods that bound their error, an enclosure `[lo, hi]`
/// that the method claims contains the exact root.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereHit<F> {
    /// The ray parameter of the nearest hit with `t > 0`.
    pub t: F,
    /// The method's claimed enclosure of the exact root, if it gives one.
    pub enclosure: Option<[F; 2]>,
}

impl<F> SphereHit<F> {
    pub(super) fn at(t: F) -> Option<Self> {
        Some(SphereHit { t, enclosure: None })
    }
}
