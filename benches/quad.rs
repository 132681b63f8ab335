//! Criterion bench: nanoseconds per test for every box, ellipsoid, cylinder and ellipsoid-normal
//! method in `f32` and `f64`, over a fixed batch per shape (seed 7): 256 cases from each valid
//! class, round robin.
//!
//! Validation comes first: every method's answer on every case is judged against the exact
//! oracle. A wrong verdict (or an invalid-input hit) by a method offered as robust on a
//! well-posed case refuses to time (panics with the replay line); the conservative box slab's
//! false hits along edges are by design and only counted. Other methods' wrong verdicts are
//! counted and printed, so the timing is honest about what it times.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rayproof::audit::run::generate;
use rayproof::audit::{judge, probe_line, Shape, Truth};
use rayproof::numerics::real::Real;
use rayproof::numerics::Precision;
use rayproof::shapes::{aabb, quadric};
use std::hint::black_box;
use std::time::Duration;

const SEED: u64 = 7;
const PER_CLASS: u64 = 256;

/// The batch of a shape: every valid class, round robin by index.
fn batch(shape: &dyn Shape, prec: Precision) -> Vec<Vec<f64>> {
    let classes: Vec<usize> = (0..shape.info().classes.len())
        .filter(|&c| shape.info().classes[c] != "invalid")
        .collect();
    (0..PER_CLASS)
        .flat_map(|i| classes.iter().map(move |&c| (c, i)))
        .filter_map(|(c, i)| generate(shape, SEED, c, prec, i))
        .collect()
}

/// Judges every method on every case; panics on a robust method's wrong verdict.
fn validate(shape: &dyn Shape, prec: Precision, cases: &[Vec<f64>]) {
    for (m, info) in shape.info().methods.iter().enumerate() {
        let mut wrong = 0;
        for v in cases {
            let truth = shape.oracle(v, prec);
            let ill = matches!(&truth, Truth::Answer(e) if e.ill_posed);
            let j = judge(&truth, &shape.run(m, v, prec), shape.info(), prec);
            if !ill && j.is_wrong() {
                wrong += 1;
                let by_design = shape.name() == "box" && j == rayproof::audit::Judgement::FalseHit;
                assert!(
                    !info.robust || by_design,
                    "{} {} {}: {:?}, refusing to time\n  {}",
                    shape.name(),
                    info.name,
                    prec.name(),
                    j,
                    probe_line(shape.name(), prec, v)
                );
            }
        }
        eprintln!(
            "{} {} {}: {wrong} wrong verdicts in {} cases",
            shape.name(),
            info.name,
            prec.name(),
            cases.len()
        );
    }
}

/// A method over the typed inputs `(o, d, params)`.
type In<F> = ([F; 3], [F; 3], Vec<F>);

fn typed<F: Real>(v: &[f64]) -> In<F> {
    let a = |k: usize| [v[k], v[k + 1], v[k + 2]].map(F::from_f64);
    (a(0), a(3), v[6..].iter().map(|&x| F::from_f64(x)).collect())
}

/// The typed methods of each shape, in the shape's method order (results reduced to a float so
/// that the optimiser cannot drop them).
fn methods<F: Real>(shape: &str) -> Vec<fn(&In<F>) -> F> {
    fn t<F: Real>(x: Option<F>) -> F {
        x.unwrap_or(F::ZERO)
    }
    fn n<F: Real>(x: Option<[F; 3]>) -> F {
        x.map_or(F::ZERO, |v| v[0] + v[1] + v[2])
    }
    match shape {
        "box" => vec![
            |i| {
                t(aabb::faces(
                    i.0,
                    i.1,
                    [i.2[0], i.2[1], i.2[2]],
                    [i.2[3], i.2[4], i.2[5]],
                ))
            },
            |i| {
                t(aabb::slab(
                    i.0,
                    i.1,
                    [i.2[0], i.2[1], i.2[2]],
                    [i.2[3], i.2[4], i.2[5]],
                ))
            },
            |i| {
                t(aabb::robust_slab(
                    i.0,
                    i.1,
                    [i.2[0], i.2[1], i.2[2]],
                    [i.2[3], i.2[4], i.2[5]],
                ))
            },
        ],
        "ellipsoid" => vec![
            |i| t(quadric::ellipsoid_chapter(i.0, i.1, i.2[0], i.2[1], i.2[2])),
            |i| t(quadric::ellipsoid_perp(i.0, i.1, i.2[0], i.2[1], i.2[2])),
            |i| {
                t(quadric::ellipsoid_robust_mn(
                    i.0, i.1, i.2[0], i.2[1], i.2[2],
                ))
            },
        ],
        "cylinder" => vec![
            |i| t(quadric::cylinder_chapter(i.0, i.1, i.2[0], i.2[1], i.2[2])),
            |i| t(quadric::cylinder_perp(i.0, i.1, i.2[0], i.2[1], i.2[2])),
            |i| t(quadric::cylinder_robust_m(i.0, i.1, i.2[0], i.2[1], i.2[2])),
        ],
        _ => vec![
            |i| n(quadric::normal_chapter(i.0, i.1, i.2[0], i.2[1], i.2[2])),
            |i| n(quadric::normal_robust_t(i.0, i.1, i.2[0], i.2[1], i.2[2])),
            |i| n(quadric::normal_robust(i.0, i.1, i.2[0], i.2[1], i.2[2])),
        ],
    }
}

fn time_in<F: Real>(c: &mut Criterion, shape: &dyn Shape, prec: Precision) {
    let cases = batch(shape, prec);
    validate(shape, prec, &cases);
    let inputs: Vec<In<F>> = cases.iter().map(|v| typed::<F>(v)).collect();
    let mut g = c.benchmark_group(format!("{}/{}", shape.name(), prec.name()));
    g.throughput(Throughput::Elements(inputs.len() as u64));
    for (info, f) in shape.info().methods.iter().zip(methods::<F>(shape.name())) {
        g.bench_function(info.name, |b| {
            b.iter(|| {
                let f = black_box(f);
                inputs.iter().fold(F::ZERO, |acc, i| acc + f(i))
            })
        });
    }
    g.finish();
}

fn benches(c: &mut Criterion) {
    let shapes: [&dyn Shape; 4] = [
        &aabb::BoxShape,
        &quadric::ELLIPSOID,
        &quadric::CYLINDER,
        &quadric::EllipsoidNormalShape,
    ];
    for shape in shapes {
        time_in::<f32>(c, shape, Precision::F32);
        time_in::<f64>(c, shape, Precision::F64);
    }
}

criterion_group! {
    name = quad;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = benches
}
criterion_main!(quad);
