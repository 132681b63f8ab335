//! The machinery every family's oracle shares: Sturm sequences and polynomial roots
//! ([`sturm`], [`poly`]), the one-ulp box and its interval signs ([`ulp_box`]), the quick phase
//! that proves correctly rounded roots from `f64` estimates ([`quick_roots`]), and the seeded
//! sampling helpers the case generators draw from (`sample`).

pub mod poly;
pub mod quick_roots;
pub(crate) mod sample;
pub mod sturm;
pub mod ulp_box;
