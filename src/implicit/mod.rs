//! Implicit surfaces (seed 004, Wu & Pan): signed distance functions, POV-Ray's blob field and
//! an MPU implicit fitted to the Stanford bunny, rendered by sphere tracing (Hart 1996) with a
//! stated Lipschitz bound per field, and image-space subdivision (§2) checked pixel by pixel
//! against per-pixel tracing.

pub mod check;
pub mod field;
pub mod march;
pub mod mpu;
pub mod subdiv;
