//! Ray–torus (seed 002 §2.5) and the torus normal from the gradient (§3) (issue 6 items 5, 6);
//! its reintersection rows come from [`crate::audit::robustness::reintersect`].
//!
//! - [`Torus`] (`torus`): the nearest `t > 0` of the ray `o + t·d` on the torus around the z
//!   axis (major radius `r1`, minor radius `r2`), by four methods ([`methods`]).
//! - [`TorusNormal`] (`torus_normal`): the unit normal at that hit, one method per torus method.
//!
//! The renderer calls [`torus_robust`] and [`torus_normal`].

pub mod cases;
pub mod methods;
pub mod oracle;

pub use methods::{torus_normal, torus_robust, torus_robust_hit, ERR_GAMMA};

use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::shape::{Answer, Domain, MethodInfo, Metric, Shape, ShapeInfo, Truth};
use rand_chacha::ChaCha8Rng;

/// A ray–torus method over one precision.
pub type TorusFn<F> = fn([F; 3], [F; 3], F, F) -> Option<F>;

/// The methods, in table order.
pub const METHODS: [MethodInfo; 4] = [
    MethodInfo {
        name: "ferrari",
        robust: false,
        about: "§2.5 quartic coefficients, §1.3 Ferrari closed form",
    },
    MethodInfo {
        name: "yuksel",
        robust: false,
        about: "§2.5 quartic coefficients, Yuksel's bracketed-Newton polynomial solver",
    },
    MethodInfo {
        name: "newton_bbox",
        robust: false,
        about: "§1.4: Newton on the §2.5 quartic from the bounding-box entry",
    },
    MethodInfo {
        name: "robust",
        robust: true,
        about: "box clip, origin shifted to the box entry, Yuksel, Newton on the signed distance",
    },
];

/// Method `m` in precision `F`.
pub fn pick<F: Real>(m: usize) -> TorusFn<F> {
    match m {
        0 => methods::ferrari::<F>,
        1 => methods::yuksel::<F>,
        2 => methods::newton_bbox::<F>,
        _ => methods::torus_robust::<F>,
    }
}

const ARGS: [&str; 8] = ["ox", "oy", "oz", "dx", "dy", "dz", "r1", "r2"];

/// The eight inputs converted exactly to `F`.
fn unpack<F: Real>(x: &[f64]) -> ([F; 3], [F; 3], F, F) {
    let f = |i: usize| F::from_f64(x[i]);
    ([f(0), f(1), f(2)], [f(3), f(4), f(5)], f(6), f(7))
}

/// Method `m`'s `t` on the inputs, in `F`.
fn hit_t<F: Real>(m: usize, x: &[f64]) -> Option<F> {
    let (o, d, r1, r2) = unpack::<F>(x);
    pick::<F>(m)(o, d, r1, r2)
}

/// Method `m`'s unit normal at its own hit: the robust method takes its hit point (computed from
/// the shifted origin) and its cancellation-free normal ([`torus_normal`]); the chapter's
/// methods evaluate `o + t·d` plainly and the chapter's gradient ([`methods::gradient`]).
fn hit_normal<F: Real>(m: usize, x: &[f64]) -> Option<[F; 3]> {
    let (o, d, r1, r2) = unpack::<F>(x);
    let n = if METHODS[m].robust {
        let (_, p) = torus_robust_hit(o, d, r1, r2)?;
        torus_normal(p, r1, r2)
    } else {
        let t = pick::<F>(m)(o, d, r1, r2)?;
        let p = [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
        methods::gradient(p, r1, r2)
    };
    Some(methods::normalize(n))
}

fn answer<const N: usize, F: Real>(v: Option<[F; N]>) -> Answer {
    match v {
        Some(v) => Answer::hit(v.iter().map(|x| x.to_f64()).collect()),
        None => Answer::miss(),
    }
}

/// The ray–torus shape.
pub struct Torus;

/// The unit normal at the ray–torus hit.
pub struct TorusNormal;

const TORUS: ShapeInfo = ShapeInfo {
    name: "torus",
    about: "§2.5 ray–torus, nearest t > 0 (torus around z, radii r1 > r2 > 0)",
    args: &ARGS,
    classes: &cases::CLASSES,
    methods: &METHODS,
    // The exact quartic oracle (Sturm isolation and one-ulp ill-posedness over 8 inputs) costs
    // milliseconds per case.
    default_cases: 500,
    domain: Domain::RayParameter,
    reports_cond: true,
    ..ShapeInfo::DEFAULTS
};

impl Shape for Torus {
    fn info(&self) -> &ShapeInfo {
        &TORUS
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        cases::generate(class, prec, rng)
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        oracle::truth(input, prec)
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => answer(hit_t::<F>(m, input).map(|t| [t])))
    }
}

const TORUS_NORMAL: ShapeInfo = ShapeInfo {
    name: "torus_normal",
    about: "§3 unit normal (normalised gradient) at the ray–torus hit",
    values: &["nx", "ny", "nz"],
    metric: Metric::NormUlps,
    domain: Domain::Real,
    ..TORUS
};

impl Shape for TorusNormal {
    fn info(&self) -> &ShapeInfo {
        &TORUS_NORMAL
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        cases::generate(class, prec, rng)
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        oracle::normal_truth(input, prec)
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => answer(hit_normal::<F>(m, input)))
    }
}
