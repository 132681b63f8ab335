//! The number layer: the float trait every method is written against, double-double, outward
//! rounded intervals, exact rationals and correct rounding, and in-run timing.

pub mod cpu;
pub mod dd;
pub mod exact;
pub mod interval;
pub mod real;
pub mod scalar;
pub mod timing;
pub mod vec3;

use serde::{Deserialize, Serialize};

/// Which arithmetic a row is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Precision {
    /// IEEE-754 binary32.
    F32,
    /// IEEE-754 binary64.
    F64,
}

impl Precision {
    /// Both precisions, `f32` first.
    pub const ALL: [Precision; 2] = [Precision::F32, Precision::F64];
    /// The precision of the float type `F`.
    pub fn of<F: real::Real>() -> Precision {
        if F::MANT_BITS == 24 {
            Precision::F32
        } else {
            Precision::F64
        }
    }
    /// `"f32"` or `"f64"`.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}
