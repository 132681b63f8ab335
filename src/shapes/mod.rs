//! The audited routine families: each a [`crate::audit::shape::Shape`] with its methods, its
//! exact oracle and its hard-case classes, kept together.

pub mod aabb;
pub mod offset;
pub mod optics;
pub mod poly;
pub mod quadric;
pub mod quick_roots;
pub mod recip;
pub mod reintersect;
pub mod robustness;
pub mod roots;
pub(crate) mod sample;
pub mod sphere;
pub mod sturm;
pub mod torus;
pub mod triangle;
pub mod ulp_box;
pub mod watertight;

use crate::audit::shape::Shape;

/// Every routine family: the sphere, then the seed chapter's in its order.
pub fn registry() -> Vec<&'static dyn Shape> {
    vec![
        &sphere::SphereShape,
        &roots::QUADRATIC,
        &roots::CUBIC,
        &roots::QUARTIC,
        &roots::NEWTON,
        &recip::RCP,
        &recip::RSQRT,
        &triangle::Triangle,
        &aabb::BoxShape,
        &quadric::ELLIPSOID,
        &quadric::CYLINDER,
        &torus::Torus,
        &quadric::EllipsoidNormalShape,
        &torus::TorusNormal,
        &optics::Reflect,
        &optics::Refract,
    ]
}

/// A shape by name.
pub fn shape_by_name(name: &str) -> Option<&'static dyn Shape> {
    registry().into_iter().find(|s| s.name() == name)
}

/// Every shape's name, in registry order.
pub fn shape_names() -> Vec<&'static str> {
    registry().iter().map(|s| s.name()).collect()
}
