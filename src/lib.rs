//! # rayproof
//!
//! Tells, with proof, how accurate and how fast ray-tracing numerics are.
//!
//! Terminology (after libm-test):
//! - **method**: one way to intersect a ray with a shape, written once over [`numerics::real::Real`]
//!   (e.g. [`shapes::sphere::methods::algebraic`]), instantiated for `f32` and `f64`;
//! - **oracle**: the exact answer from the inputs' exact binary values ([`shapes::sphere::oracle`]),
//!   with MPFR (through `rug`) for roots and GMP integers for signs;
//! - **class**: a named, seeded generator of hard cases whose membership the oracle confirms
//!   ([`shapes::sphere::cases::Class`]);
//! - **judgement**: how one method's answer compares with the oracle ([`audit::judge::Judgement`]);
//! - **audit**: every method × precision × class, aggregated into rows ([`audit`]), checked
//!   against one tolerance table ([`audit::tolerance`]).

pub mod audit;
pub mod golden;
pub mod images;
pub mod implicit;
pub mod numerics;
pub mod output;
pub mod process;
pub mod render;
pub mod report;
pub mod shapes;
