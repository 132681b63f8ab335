//! Ray–sphere (Fan, Shen, Wang & Feng 1996; Lengyel's ray-tracing chapter, §2.3): the methods,
//! their exact oracle and the hard-case classes, audited as a [`Shape`] like every other routine
//! family.
//!
//! A case is the ten scalars `o, d, c, r` (origin, direction, centre, radius); the answer is
//! the nearest `t > 0`. Beside the common row fields the sphere's oracle gives each case's
//! sensitivity (err/cond), its rows report the hit point's residual, and the `interval` method's
//! enclosures are checked.
//!
//! # Methods
//!
//! Every method takes the ray as given (origin, direction; *not* renormalised) and the sphere
//! (centre, radius). It returns the nearest hit with `t > 0`, or a miss, and never panics. Each doc
//! comment in [`methods`] states the method's conventions: origin exactly on the surface, D = 0,
//! zero direction, and whether a unit direction is assumed.
//!
//! | method | what it is | tangent (D = 0) | unit d assumed |
//! |---|---|---|---|
//! | `algebraic` | Fan et al. 1996 §1 and Lengyel's ray-tracing chapter §2.3: `A t² + B t + C`, `t = (−B ∓ √(B²−4AC))/2A` | miss (the paper's `≤ 0`) | no |
//! | `geometric` | Fan et al. 1996 §2, the paper's "non-analytic" test, four steps as written | hit | **yes** |
//! | `geometric_fma` | `geometric` as a compiler builds it with FMA contraction: every `a·b + c` one fused multiply-add (the batch kernels' FMA variant) | hit | **yes** |
//! | `press` | Numerical Recipes: `q = −½(B + sign(B)√D)`, roots `C/q`, `q/A` | hit | no |
//! | `hearn_baker` | discriminant `r² − \|Δp − (Δp·d̂)d̂\|²` from the perpendicular vector | hit | no (normalises internally) |
//! | `rtg7` | Ray Tracing Gems ch. 7, method 5: the perpendicular discriminant with Press's root pair | hit | no |
//! | `promote` | `rtg7`, computed in f64 for f32 inputs or in double-double for f64 inputs, after an exact power-of-two prescale, and rounded once | hit | no |
//! | `certified` | the exact verdict and the correctly rounded `t`: a first look (for `f32` inputs a division-free test of the `f64` root against the nearest `f32` rounding boundary; for `f64` inputs its certain misses), a quick `f64` phase with per-quantity bounds (for `f64` inputs Newton steps with a double-double residual, and near the surface on `C + t(2B + At)` with `C` nearly exact), the oracle's exact path when no bound decides ([`certified`]) | hit | no |
//! | `interval` | pbrt-v4 `Sphere::BasicIntersect` in outward-rounded interval arithmetic; returns the midpoint and the enclosure | hit only if provable | no |
//!
//! # Case classes
//!
//! Case `i` of a class is drawn from its own stream ([`cases`]), so any case can be regenerated
//! alone, and `--shard K/N` splits the work exactly. The oracle's exact quantities confirm that
//! each case belongs to its class; a proposal that fails the check is drawn again.
//!
//! | class | what it is (membership as confirmed by the oracle) |
//! |---|---|
//! | `inside` | origin strictly inside (`C < 0`); 1 case in 16 has the origin exactly at the centre |
//! | `on_surface` | `\|\|o−c\| − r\| ≤ 16` ulps of r; a quarter are exactly on the sphere (Pythagorean quadruples) |
//! | `tangent` | the distance from the centre to the line is within 16 ulps of r, ahead of the origin; a quarter are exactly tangent |
//! | `behind` | origin outside and the whole sphere behind it (`B' > r·\|d\|`) |
//! | `far_small` | `r/\|o−c\|` from 1e-6 to 1e-2, aimed within 1.5 radii |
//! | `huge` | `r ≥ 1e4`, origin above the surface by 1e-3·r down to below the precision's resolution (a sphere used as a floor) |
//! | `grazing` | the line passes within 1e-3·r of the limb, but farther than the tangent band |
//! | `random` | general position over five decades of scale |
//! | `invalid` | NaN or ±inf in any component, zero direction, zero/negative/NaN radius, and subnormal directions and scenes (the last two are valid but degenerate, and are judged like any case) |
//!
//! # What the audit shows
//!
//! Four of the sphere's blocks from `rayproof audit --shape sphere --verbose --worst 0` (seed 1,
//! 20,000 cases per class; the legend it prints first is explained in [`crate::audit`]):
//!
//! ```text
//! sphere — ray–sphere |o + t·d − c| = r, nearest t > 0 (seed 000; seed 002 §2.3)  (errors in ulps; 20000 cases per class)
//! f32 · far_small
//!   method             well   ill wrong fh/fm/wr/nf      rate  max ulp     p99 bits99 err/cond resid max      invalid verdict  enclosure
//!   algebraic         19860   140     1855/4864/0/0  33.8318%     7089    5773   12.5     3759     6.1e9            -   xfail
//!   geometric         19860   140  3544/2474/1314/0  36.9184%     7088    5758   12.5     3759     6.1e9            -   xfail
//!   press             19860   140  3785/2189/1382/0  37.0393%     7089    5770   12.5     3759     6.1e9            -   xfail
//!   hearn_baker       19860   140           0/0/1/0   0.0050%       11       4    2.3     2.74     3.3e6            -      ok
//!   rtg7              19860   140           0/0/1/0   0.0050%       11       3    2.0     1.91     1.7e6            -      ok
//!   promote           19860   140           0/0/0/0   0.0000%        0       0    0.0     0.00     5.1e5            -      ok
//!   interval          19860   140        0/1383/0/0   6.9637%       55       6    2.8     4.90     3.5e6            -      ok  0 viol, width med 48
//! f32 · huge
//!   method             well   ill wrong fh/fm/wr/nf      rate  max ulp     p99 bits99 err/cond resid max      invalid verdict  enclosure
//!   algebraic         17198  2802           0/0/9/0   0.0523%    1.6e7   6.4e6   22.6     1.45         2            -       -
//!   geometric         17198  2802           0/3/6/0   0.0523%    1.6e7   6.4e6   22.6     1.45         2            -       -
//!   press             17198  2802           0/0/6/0   0.0349%    1.6e7   6.5e6   22.6     1.58         2            -       -
//!   hearn_baker       17198  2802          4/0/11/0   0.0872%    2.9e7   7.9e6   22.9     1.73         3            -      ok
//!   rtg7              17198  2802           1/0/6/0   0.0407%    1.6e7   6.5e6   22.6     1.58         1            -      ok
//!   promote           17198  2802           0/0/0/0   0.0000%        1       0    0.0     0.00         0            -      ok
//!   interval          17198  2802       0/55/1675/0  10.0593%    4.1e6   1.9e6   20.8     1.11         2            -      ok  0 viol, width med 4.8e5
//! f64 · tangent
//!   method             well   ill wrong fh/fm/wr/nf      rate  max ulp     p99 bits99 err/cond resid max      invalid verdict  enclosure
//!   algebraic         11640  8360       394/926/0/0  11.3402%    1.1e8   8.3e7   26.3     4.28        27            -   xfail
//!   geometric         11640  8360     1121/498/60/0  14.4244%    1.9e8   1.3e8   27.0     6.52        44            -   xfail
//!   press             11640  8360     1097/287/56/0  12.3711%    1.7e8   1.2e8   26.8     6.94        27            -   xfail
//!   hearn_baker       11640  8360           3/0/3/0   0.0515%    9.9e7   3.5e7   25.1     0.54         4            -      ok
//!   rtg7              11640  8360           2/0/1/0   0.0258%    9.9e7   3.5e7   25.1     0.91         3            -      ok
//!   promote           11640  8360           0/0/0/0   0.0000%        0       0    0.0     0.00         0            -      ok
//!   interval          11640  8360        0/5691/0/0  48.8918%    9.9e7   9.6e7   26.5     1.36         3            -      ok  0 viol, width med 2.6e8
//! f32 · invalid
//!   method             well   ill wrong fh/fm/wr/nf      rate  max ulp     p99 bits99 err/cond resid max      invalid verdict  enclosure
//!   algebraic          5833   198         0/465/0/0   7.9719%      190      92    6.5       80     20055 12948/408/613   xfail
//!   geometric          5833   198        0/491/10/0   8.5891%    1.1e9   1.1e9   30.0    3.2e6     9.8e6 12936/411/622   xfail
//!   press              5833   198         0/465/0/0   7.9719%      189      91    6.5       79     19950  13354/0/615   xfail
//!   hearn_baker        5833   198         0/465/0/0   7.9719%        5       4    2.3     1.55        27  13357/0/612   xfail
//!   rtg7               5833   198         0/465/0/0   7.9719%        3       2    1.6     0.76        78    13969/0/0   xfail
//!   promote            5833   198           0/0/0/0   0.0000%        0       0    0.0     0.00        27    13969/0/0      ok
//!   interval           5833   198         0/465/0/0   7.9719%       20       3    2.0     0.76        78    13969/0/0      ok  0 viol, width med 44
//! ```
//!
//! What it says:
//! - **Fan et al.'s textbook quadratic (`algebraic`) fails on far-small spheres in f32.** It gives
//!   a wrong verdict on a third of the well-posed cases, and its errors are up to 3,759 times
//!   larger than the input rounding forces (err/cond). `geometric` and `press` fail the same way,
//!   because all three subtract two nearly equal squares. `hearn_baker` and `rtg7` fix this by
//!   computing the perpendicular vector.
//! - **Huge spheres used as floors (f32) look bad for every method, but the case is to blame, not
//!   the method.** The near root is off by up to 1.6e7 ulps. But err/cond ≈ 1.5 shows that a
//!   one-ulp change of the inputs already moves `t` that far: `o − c` and `|o−c|² − r²` cannot be
//!   represented in f32. Only `promote`, which computes in a wider type, gets those cases right.
//!   The pbrt-style `interval` stays conservative: it never gives a false hit, and its enclosures
//!   always hold. But on 9.7 % of these floor cases it returns the far side of the sphere, because
//!   the near root's interval reaches below 0.
//! - **Near tangents** break the paper's methods in both precisions, at 11–14 % wrong verdicts.
//! - **Invalid input.** The paper's methods return NaN `t` on subnormal directions (`|d|²`
//!   underflows to 0) and hits on negative radii. The robust methods reject every invalid input.
//!   Without `promote`'s power-of-two prescaling, the robust methods still miss hits when the
//!   direction is subnormal.
//!
//! # Benchmarks
//!
//! `cargo bench --bench sphere` runs criterion over four fixed batches: a mix of six classes,
//! hits only, misses only, and `fan30`: 4,096 sphere tests recorded while rendering
//! `reference/scenes/fan30.toml`, as the renderer passes them. It covers every method × precision.
//! `cargo bench --bench batch` times the structure-of-arrays kernels ([`batch`]) against the scalar
//! methods (answers checked bit-identical first), and `cargo bench --bench newton` the reciprocal
//! and reciprocal-square-root refinements (each checked against its error bound first). Before
//! timing, it judges every answer against the oracle, and it refuses to time a method that breaks
//! a strict row of the table. Nanoseconds per test on the mix batch (3,072 cases) from one run on
//! a 2-core machine (median of 20 samples; the machine is shared, so compare ratios):
//!
//! | method | f32 | f64 |
//! |---|---:|---:|
//! | algebraic | 6.3 | 6.8 |
//! | geometric | 3.5 | 3.9 |
//! | press | 8.1 | 7.4 |
//! | hearn_baker | 12.4 | 13.2 |
//! | rtg7 | 11.5 | 18.8 |
//! | promote | 34.7 | 392.7 |
//! | interval | 136.2 | 179.0 |
//!
//! What accuracy costs: `rtg7` is about 2× the textbook quadratic and fixes the far-small failure.
//! Being right everywhere costs 5.5× in f32 (`promote` through f64) and about 58× in f64
//! (double-double division and square root). `rayproof report` measures the same trade-off in one
//! run ([`crate::report`]).

pub mod batch;
pub mod cases;
pub mod certified;
pub mod methods;
pub mod oracle;
pub mod ray;

use crate::numerics::real::{Real, Scalar};
use crate::numerics::Precision;
use crate::shapes::shape::{Answer, Domain, Expected, MethodInfo, Shape, ShapeInfo, Truth};
use cases::Class;
use methods::{PickPrecision, METHODS};
use oracle::{Case, Verdict};
use rand_chacha::ChaCha8Rng;

/// Significant digits of the oracle's decimal roots in `probe`.
const DIGITS: usize = 45;

/// The sphere's methods as the audit lists them.
const METHOD_INFO: [MethodInfo; METHODS.len()] = {
    let mut out = [MethodInfo {
        name: "",
        robust: false,
        about: "",
    }; METHODS.len()];
    let mut i = 0;
    while i < METHODS.len() {
        out[i] = MethodInfo {
            name: METHODS[i].name,
            robust: METHODS[i].robust,
            about: METHODS[i].summary,
        };
        i += 1;
    }
    out
};

/// The class names, in [`Class::ALL`] order.
const CLASS_NAMES: [&str; Class::ALL.len()] = {
    let mut out = [""; Class::ALL.len()];
    let mut i = 0;
    while i < Class::ALL.len() {
        out[i] = Class::ALL[i].name();
        i += 1;
    }
    out
};

const INFO: ShapeInfo = ShapeInfo {
    name: "sphere",
    about: "ray–sphere |o + t·d − c| = r, nearest t > 0 (seed 000; seed 002 §2.3)",
    args: &["ox", "oy", "oz", "dx", "dy", "dz", "cx", "cy", "cz", "r"],
    classes: &CLASS_NAMES,
    methods: &METHOD_INFO,
    reports_cond: true,
    reports_residual: true,
    domain: Domain::RayParameter,
    ..ShapeInfo::DEFAULTS
};

/// The ray–sphere shape.
pub struct SphereShape;

/// The case in the precision `F` (its values are exactly representable there).
fn case_in<F: Real>(input: &[f64]) -> Case<F> {
    Case::from_scalars(std::array::from_fn(|i| F::from_f64(input[i])))
}

/// The oracle's truth in the audit's terms.
fn truth_in<F: Real>(input: &[f64]) -> Truth {
    let case = case_in::<F>(input);
    let t = oracle::truth(&case);
    if t.verdict == Verdict::Invalid {
        return Truth::Invalid;
    }
    let hit = t.verdict.is_hit();
    // The other root is the wrong-root candidate
    let other = t
        .roots
        .map(|[t1, t2]| if t.verdict == Verdict::Near { t2 } else { t1 });
    Truth::Answer(Expected {
        count: hit as u32,
        values: t
            .t_in::<F>()
            .filter(|_| hit)
            .map(|x| x.to_f64())
            .into_iter()
            .collect(),
        others: other.filter(|_| hit).into_iter().collect(),
        ill_posed: t.ill_posed,
        cap_reached: t.cap_reached,
        value_f64: t.t_f64.filter(|_| hit),
        cond: oracle::condition_ulps(&case, &t),
        conds: vec![],
    })
}

/// Method `m` in the precision `F`.
fn run_in<F: PickPrecision>(m: usize, input: &[f64]) -> Answer {
    let case = case_in::<F>(input);
    match F::pick(&METHODS[m])(&case.ray(), &case.sphere()) {
        None => Answer::miss(),
        Some(h) => Answer {
            count: 1,
            values: vec![h.t.to_f64()],
            enclosure: h.enclosure.map(|e| [e[0].to_f64(), e[1].to_f64()]),
        },
    }
}

impl Shape for SphereShape {
    fn info(&self) -> &ShapeInfo {
        &INFO
    }
    /// The sphere keeps its own case streams (see [`cases::case_rng`]), so its cases are the
    /// ones every earlier report was made from.
    fn case_rng(&self, seed: u64, class: usize, prec: Precision, index: u64) -> ChaCha8Rng {
        crate::in_precision!(prec, F => cases::case_rng::<F>(seed, Class::ALL[class], index))
    }
    fn generate(&self, class: usize, prec: Precision, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        crate::in_precision!(prec, F => cases::generate_from::<F>(rng, Class::ALL[class])
            .map(|c| c.scalars().iter().map(|x| x.to_f64()).collect()))
    }
    fn oracle(&self, input: &[f64], prec: Precision) -> Truth {
        crate::in_precision!(prec, F => truth_in::<F>(input))
    }
    fn run(&self, m: usize, input: &[f64], prec: Precision) -> Answer {
        crate::in_precision!(prec, F => run_in::<F>(m, input))
    }
    /// `|o + t·d − c| − r` at the method's `t`, in ulps of `r`.
    fn residual(&self, input: &[f64], prec: Precision, answer: &Answer) -> Option<f64> {
        let t = *answer.values.first()?;
        Some(crate::in_precision!(prec, F => {
            oracle::residual_ulps(&case_in::<F>(input), F::from_f64(t)).abs()
        }))
    }
    /// Both exact roots in decimal, and the precision at which the rounding became certain.
    fn oracle_detail(&self, input: &[f64], prec: Precision) -> Vec<(String, String)> {
        crate::in_precision!(prec, F => {
            let case = case_in::<F>(input);
            let t = oracle::truth(&case);
            let mut out: Vec<(String, String)> = oracle::roots_decimal(&case, DIGITS)
                .into_iter()
                .enumerate()
                .map(|(i, r)| (format!("root t{}", i + 1), r))
                .collect();
            if let (Some(a), Some(b)) = (t.t_f32, t.t_f64) {
                out.push(("t (f32)".into(), a.hex()));
                out.push(("t (f64)".into(), b.hex()));
            }
            out.push(("precision bits".into(), t.prec.to_string()));
            out
        })
    }
}
