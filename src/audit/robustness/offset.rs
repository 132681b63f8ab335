//! The project's ray-origin offset rule for reintersection (pbrt-v4's `OffsetRayOrigin`, item 8
//! of issue 6), and the reintersection row every closed shape reports.
//!
//! A computed hit point `p` carries a per-component absolute error bound `err` (what the method
//! can guarantee: `γ(k)·|p|` for a point reprojected onto the surface, more for `o + t·d`).
//! The spawned origin is `p` moved along the normal by `Σ|nᵢ|·errᵢ` to the side the new ray
//! leaves on, and each component is then rounded one ulp further away. The offset scales with
//! `|p|` (size-aware): a shape at 1e-4 gets a 1e-4-sized offset, not a fixed epsilon.

use crate::numerics::real::{gamma, Real};
use serde::{Deserialize, Serialize};

/// The bound `γ(k)·|pᵢ|` per component.
pub fn error_bound<F: Real>(p: [F; 3], k: u32) -> [F; 3] {
    let g = gamma::<F>(k);
    [g * p[0].abs(), g * p[1].abs(), g * p[2].abs()]
}

/// The spawned origin for a ray leaving `p` (error `err`) along `w`, given the unit geometric
/// normal `n` (either orientation; as in pbrt, a longer `n` scales the offset by its squared
/// length).
pub fn spawn_origin<F: Real>(p: [F; 3], err: [F; 3], n: [F; 3], w: [F; 3]) -> [F; 3] {
    let d = n[0].abs() * err[0] + n[1].abs() * err[1] + n[2].abs() * err[2];
    let mut off = [d * n[0], d * n[1], d * n[2]];
    // To the side the ray leaves on
    if w[0] * n[0] + w[1] * n[1] + w[2] * n[2] < F::ZERO {
        off = [-off[0], -off[1], -off[2]];
    }
    let mut po = [p[0] + off[0], p[1] + off[1], p[2] + off[2]];
    // Round each component away from p
    for i in 0..3 {
        if off[i] > F::ZERO {
            po[i] = po[i].next_up();
        } else if off[i] < F::ZERO {
            po[i] = po[i].next_down();
        }
    }
    po
}

/// How a reintersection test spawns rays: the project's rule, and two controls that must show
/// re-hits (or the test could not see a broken rule).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// [`spawn_origin`] with the method's error bound.
    On,
    /// The same with the error bound 1000× too small.
    Weak,
    /// No offset: the spawned ray starts at the computed hit point.
    Off,
}

impl Rule {
    /// Every rule, in report order.
    pub const ALL: [Rule; 3] = [Rule::On, Rule::Weak, Rule::Off];
    /// The factor on the error bound.
    pub fn factor(self) -> f64 {
        match self {
            Rule::On => 1.0,
            Rule::Weak => 1e-3,
            Rule::Off => 0.0,
        }
    }
    /// `on`, `weak` or `off`.
    pub fn name(self) -> &'static str {
        match self {
            Rule::On => "on",
            Rule::Weak => "weak",
            Rule::Off => "off",
        }
    }
}

/// One method × precision × [`Rule`] of the reintersection test: rays spawned from computed hits
/// that hit the same surface again where the ideal spawned ray does not (see
/// [`crate::audit::robustness::reintersect`]).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ReintersectRow {
    /// The surface.
    pub shape: String,
    /// The intersection method (a built-in's, or a routine's from outside the crate).
    pub method: String,
    /// `"f32"` or `"f64"`.
    pub precision: String,
    /// Offered as robust.
    pub robust: bool,
    /// `on`, `weak` (error bound ×1e-3) or `off` (no offset).
    pub rule: String,
    /// Spawned rays tested.
    pub rays: u64,
    /// Spawned rays the method reports hitting the surface before half the distance to the ideal
    /// ray's next crossing (false self-hits).
    pub rehits: u64,
    /// Of the re-hits, those on another part of the surface (the other triangle of a hinge) that
    /// the exact answer for the spawned ray confirms: the offset, applied per part as in pbrt,
    /// carried the origin across the neighbour. A limit of the rule, not of the method.
    pub neighbour: u64,
    /// Reported hits whose ideal crossing lies within the self-hit zone: judged neither way.
    pub ill_posed: u64,
    /// What the row is held to ([`crate::audit::robustness::judge`]): `pass` or `fail` (no
    /// self-hit under the offset rule), `control` (the rule weak or off), `reported` (a built-in
    /// method not robust by design).
    #[serde(default)]
    pub verdict: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_away_along_the_leaving_side() {
        let p = [1.0f32, 2.0, 3.0];
        let err = error_bound(p, 5);
        let n = [0.0, 0.0, 1.0];
        let up = spawn_origin(p, err, n, [0.0, 0.0, 1.0]);
        let down = spawn_origin(p, err, n, [0.0, 1.0, -1.0]);
        assert!(up[2] > p[2] && down[2] < p[2]);
        assert_eq!((up[0], up[1]), (p[0], p[1]));
        // Size-aware: the offset scales with |p|
        let small = spawn_origin([0.0, 0.0, 3e-4f32], error_bound([0.0, 0.0, 3e-4], 5), n, n);
        assert!(small[2] - 3e-4 < 1e-9);
    }
}
