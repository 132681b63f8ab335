//! The audited routine families: each a [`crate::shapes::shape::Shape`] with its methods, its
//! exact oracle and its hard-case classes, kept together.
//!
//! # The routines of Lengyel's ray-tracing chapter
//!
//! Every ray-tracing routine of the chapter (Lengyel, *Mathematics for 3D Game Programming and
//! Computer Graphics*, ch. 6) is a shape like the sphere ([`sphere`]): written once over
//! `f32`/`f64`, an exact oracle, named classes, one row per method × precision × class, and a
//! replay line for every failure. `rayproof audit` runs them all after the sphere (`--shape
//! NAME,..` selects; `--method`/`--class` then name that shape's methods and classes); `rayproof
//! probe NAME --precision P -- VALUES…` replays one case (`rayproof probe --help` lists the shapes,
//! `rayproof probe NAME --help` their values).
//!
//! | shape | chapter § | methods (robust anchor *) | oracle |
//! |---|---|---|---|
//! | `quadratic`, `cubic`, `quartic` | 1.1–1.3 | textbook / Cardano + trigonometric / Ferrari; Kahan–pbrt FMA discriminant *, Yuksel's bracketed Newton * | Sturm sequences over GMP rationals, roots rounded by exact signs at float midpoints |
//! | `newton` | 1.4 | the chapter's iteration; bracketed Newton * | Sturm |
//! | `rcp`, `rsqrt` | 1.5 | bit-trick or given start + 1–3 Newton steps; start-bound classes (0 < x₀ < 2/r) | MPFR |
//! | `triangle` | 2.1 | the chapter's 4-D plane + 2×2 barycentrics, Möller–Trumbore, watertight (Woop et al., as pbrt-v4), watertight in the wide type * | exact rationals |
//! | `box` | 2.2 | face by face, slab, robust slab (1 + 2γ₃, NaN-safe) * | exact rationals |
//! | `ellipsoid`, `cylinder` | 2.3, 2.4 | the chapter's coefficients, perpendicular-vector form, the same in the wide type * | exact discriminant sign, MPFR roots |
//! | `torus` | 2.5 | Ferrari, Yuksel, Newton from the bounding-box entry, origin-shifted robust solver * | exact quartic, Sturm |
//! | `ellipsoid_normal`, `torus_normal` | 3 | gradient at the method's hit | exact gradient at the exact hit (MPFR) |
//! | `reflect`, `refract` | 4 | the chapter's formulas, FMA / pbrt-v4, wide * | exact TIR decision (rationals), MPFR vectors |
//!
//! A routine's answer is a *count* (hit or miss; number of distinct real roots; refracted or total
//! internal reflection) and *values* (t, the roots, vector components). Wrong counts on well-posed
//! cases are false hits / false misses; a value nearer another exact root is a wrong root; value
//! errors are in ulps (for vectors, in ulps of the largest component). Ill-posed cases (the count
//! changes under a one-ulp move of some input) are reported apart, as for the sphere. Every shape
//! is judged by the one tolerance table ([`crate::audit::tolerance`]): robust methods have 0 wrong
//! verdicts and a measured ulp bound; the chapter's known failures are expected failures, so the
//! audit fails if the harness stops finding them.
//!
//! # An excerpt
//!
//! Every shape's f32 rows on the class where a chapter method does worst, from
//! `scripts/audit-excerpt-routines --cases 300` (seed 1; rows marked * are the robust anchors):
//!
//! ```text
//! quadratic · f32 · huge_range   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   textbook              300      0            0/0/0/0    0.000%  1.249e+09 1.203e+09
//!   robust *              300      0            0/0/0/0    0.000%          1         1
//!
//! cubic · f32 · tiny_leading   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   chapter               280     20         0/52/0/105   56.071%  2.363e+09 2.358e+09
//!   yuksel *              280     20            0/0/0/0    0.000%          0         0
//!
//! quartic · f32 · tiny_leading   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   ferrari               277     23         0/35/0/242  100.000%          0         0
//!   yuksel *              277     23            0/0/0/0    0.000%          0         0
//!
//! newton · f32 · flat_start   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   newton_plain          300      0          0/0/300/0  100.000%          0         0
//!   newton_bracketed *    300      0            0/0/0/0    0.000%          0         0
//!
//! rcp · f32 · start_out_of_bound   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   division *            300      0            0/0/0/0    0.000%          0         0
//!   bits+1                300      0            0/0/0/0    0.000%  4.187e+04 3.869e+04
//!   bits+2                300      0            0/0/0/0    0.000%        103        85
//!   bits+3                300      0            0/0/0/0    0.000%          2         2
//!   x0+newton             300      0          0/0/0/300  100.000%          0         0
//!
//! rsqrt · f32 · start_out_of_bound   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   sqrt *                300      0            0/0/0/0    0.000%          1         1
//!   bits+1                300      0            0/0/0/0    0.000%  2.722e+04 2.114e+04
//!   bits+2                300      0            0/0/0/0    0.000%         51        51
//!   bits+3                300      0            0/0/0/0    0.000%          1         1
//!   x0+newton             300      0          0/0/0/160   53.333%  2.625e+09 2.621e+09
//!
//! triangle · f32 · vertex   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   chapter               105    195            5/2/0/0    6.667%          5         5
//!   moller_trumbore       105    195           13/0/0/0   12.381%         12        12
//!   watertight            105    195           23/0/0/0   21.905%          3         3
//!   watertight_wide *     105    195            0/0/0/0    0.000%          0         0
//!
//! box · f32 · inside   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   faces                 300      0          0/300/0/0  100.000%          0         0
//!   slab                  300      0            0/0/0/0    0.000%          1         1
//!   robust_slab *         300      0            0/0/0/0    0.000%          7         7
//!
//! ellipsoid · f32 · far_small   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   chapter               297      3         58/39/10/0   36.027%       6782      6718
//!   perp                  297      3            0/1/0/0    0.337%         14         3
//!   robust *              297      3            0/0/0/0    0.000%          0         0
//!
//! cylinder · f32 · far_small   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   chapter               297      3         13/77/17/0   36.027%       7078      4518
//!   perp                  297      3            0/0/0/0    0.000%          2         2
//!   robust *              297      3            0/0/0/0    0.000%          0         0
//!
//! torus · f32 · far   (300 cases per class; errors in ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   ferrari               300      0        30/100/16/0   48.667%   5.14e+05 4.966e+05
//!   yuksel                300      0         30/124/6/0   53.333%  5.002e+05 4.739e+05
//!   newton_bbox           300      0          5/228/4/0   79.000%  3.456e+04 3.456e+04
//!   robust *              300      0            0/0/0/0    0.000%          1         0
//!
//! ellipsoid_normal · f32 · far_small   (300 cases per class; errors in norm_ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   chapter               298      2          68/46/0/0   38.255%  2.298e+07 2.154e+07
//!   robust_t              298      2            0/0/0/0    0.000%  1.416e+06 7.342e+05
//!   robust *              298      2            0/0/0/0    0.000%          1         0
//!
//! torus_normal · f32 · far   (300 cases per class; errors in norm_ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   ferrari               300      0         49/100/0/0   49.667%  2.837e+07 2.569e+07
//!   yuksel                300      0         36/107/0/0   47.667%  1.761e+07 1.712e+07
//!   newton_bbox           300      0          6/207/0/0   71.000%  2.644e+07 2.644e+07
//!   robust *              300      0            0/0/0/0    0.000%         11         8
//!
//! reflect · f32 · generic   (300 cases per class; errors in norm_ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   chapter               300      0            0/0/0/0    0.000%          3         2
//!   fma *                 300      0            0/0/0/0    0.000%          2         2
//!
//! refract · f32 · critical   (300 cases per class; errors in norm_ulps)
//!   method               well    ill  wrong fh/fm/wr/nf      rate   max ulps       p99
//!   chapter               180    120            3/0/0/0    1.667%       6942      5252
//!   pbrt                  180    120            2/0/0/0    1.111%       6942      5252
//!   wide *                180    120            0/0/0/0    0.000%          0         0
//! ```
//!
//! The renderer intersects boxes, closed cylinders, ellipsoids and tori through these robust
//! routines (see [`crate::render`]).

pub mod aabb;
pub mod optics;
pub mod oracle;
pub mod quadric;
pub mod recip;
pub mod roots;
pub mod shape;
pub mod sphere;
pub mod torus;
pub mod triangle;

use shape::Shape;

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
