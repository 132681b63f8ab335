//! Vector helpers over plain arrays `[S; 3]`, one set for every scalar type (`f32`, `f64`, the
//! double-double): the methods' bodies, the oracles' case generators and the robustness checks
//! all use these. Each is written in one evaluation order (left to right, no fused operation),
//! so a body gives the same bits whichever file it is in.

use super::scalar::Scalar;

/// A 3-vector as a plain array.
pub type V<S> = [S; 3];

/// `a + b`.
#[inline(always)]
pub fn add<S: Scalar>(a: V<S>, b: V<S>) -> V<S> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
#[inline(always)]
pub fn sub<S: Scalar>(a: V<S>, b: V<S>) -> V<S> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `k·a`.
#[inline(always)]
pub fn scale<S: Scalar>(a: V<S>, k: S) -> V<S> {
    [a[0] * k, a[1] * k, a[2] * k]
}

/// `a·b`, summed left to right.
#[inline(always)]
pub fn dot<S: Scalar>(a: V<S>, b: V<S>) -> S {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a × b`.
#[inline(always)]
pub fn cross<S: Scalar>(a: V<S>, b: V<S>) -> V<S> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
