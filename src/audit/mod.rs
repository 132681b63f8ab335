//! The audit: every method × precision × class of a routine family against its oracle.

pub mod generic;
pub mod shape;
pub mod sphere_probe;
pub mod sphere_run;
