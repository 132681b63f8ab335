//! Criterion bench: nanoseconds per call of every root-finder, Newton and rcp/rsqrt method in
//! `f32` and `f64`, on a fixed batch per shape: 128 cases (seed 7) from each class but
//! `invalid`, round robin.
//!
//! The polynomial solvers are timed directly on coefficient arrays already in the precision
//! ([`poly::quadratic_textbook`], …, [`poly::poly_roots_robust`]); the Newton and rcp/rsqrt
//! methods through `Shape::run` (which adds the exact `f64` → `F` conversion of the inputs).
//! The throughput is the batch length, so criterion's elements/s is calls/s.
//!
//! Validation comes first: every method's answer on every case is judged against the exact
//! oracle. A wrong verdict or a value error beyond the tolerance table on a row the table holds
//! to zero wrong verdicts refuses to time (panics with the replay line); other wrong verdicts
//! (the chapter's known failures) are counted and printed, so the timing says what it times.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rayproof::audit::run::generate;
use rayproof::audit::tolerance::Table;
use rayproof::audit::{judge, probe_line, Shape, Truth};
use rayproof::numerics::real::Real;
use rayproof::numerics::Precision;
use rayproof::shapes::oracle::poly;
use rayproof::shapes::registry;
use std::hint::black_box;
use std::time::Duration;

const SEED: u64 = 7;
const PER_CLASS: u64 = 128;

/// The batch of a shape: `(class, input)` round robin over the valid classes.
fn batch(shape: &dyn Shape, prec: Precision) -> Vec<(usize, Vec<f64>)> {
    let classes: Vec<usize> = (0..shape.info().classes.len())
        .filter(|&c| shape.info().classes[c] != "invalid")
        .collect();
    (0..PER_CLASS)
        .flat_map(|i| classes.iter().map(move |&c| (c, i)))
        .filter_map(|(c, i)| generate(shape, SEED, c, prec, i).map(|v| (c, v)))
        .collect()
}

/// Judges every method on the batch; panics where the tolerance table forbids a failure.
fn validate(shape: &dyn Shape, prec: Precision, cases: &[(usize, Vec<f64>)]) {
    let table = Table::built_in();
    let truths: Vec<Truth> = cases.iter().map(|(_, v)| shape.oracle(v, prec)).collect();
    for (m, info) in shape.info().methods.iter().enumerate() {
        let mut wrong = 0;
        for ((class, input), truth) in cases.iter().zip(&truths) {
            let well_posed = matches!(truth, Truth::Answer(e) if !e.ill_posed);
            let j = judge(truth, &shape.run(m, input, prec), shape.info(), prec);
            let class = shape.info().classes[*class];
            let forbidden = table.forbids(shape.name(), info.name, prec, class, j);
            if well_posed && (j.is_wrong() || forbidden) {
                wrong += 1;
                assert!(
                    !forbidden,
                    "refusing to time {} {} {}: {j:?}\n  {}",
                    shape.name(),
                    info.name,
                    prec.name(),
                    probe_line(shape.name(), prec, input)
                );
            }
        }
        eprintln!(
            "{} {} {}: {wrong} of {} well-posed cases wrong or beyond the table",
            shape.name(),
            info.name,
            prec.name(),
            cases.len()
        );
    }
}

/// Coefficients in `F`, ascending (probe order is leading first).
fn ascending<F: Real>(cases: &[(usize, Vec<f64>)]) -> Vec<Vec<F>> {
    cases
        .iter()
        .map(|(_, v)| v.iter().rev().map(|&x| F::from_f64(x)).collect())
        .collect()
}

/// The solver of method `m` of a polynomial shape of degree `n`.
fn solver<F: Real>(n: usize, m: usize) -> fn(&[F]) -> Vec<F> {
    match (n, m) {
        (2, 0) => |c| poly::quadratic_textbook([c[0], c[1], c[2]]),
        (2, _) => |c| poly::quadratic_robust([c[0], c[1], c[2]]),
        (3, 0) => |c| poly::cubic_chapter([c[0], c[1], c[2], c[3]]),
        (4, 0) => |c| poly::quartic_ferrari([c[0], c[1], c[2], c[3], c[4]]),
        _ => |c| poly::poly_roots_robust(c),
    }
}

fn time_polys<F: Real>(c: &mut Criterion, shape: &dyn Shape, prec: Precision) {
    let cases = batch(shape, prec);
    validate(shape, prec, &cases);
    let coeffs = ascending::<F>(&cases);
    let n = shape.info().args.len() - 1;
    let mut g = c.benchmark_group(format!("poly/{}", shape.name()));
    g.throughput(Throughput::Elements(coeffs.len() as u64));
    for (m, info) in shape.info().methods.iter().enumerate() {
        let f = solver::<F>(n, m);
        g.bench_function(format!("{}/{}", info.name, prec.name()), |b| {
            b.iter(|| {
                for c in &coeffs {
                    black_box(f(black_box(c)));
                }
            })
        });
    }
    g.finish();
}

fn time_shape(c: &mut Criterion, shape: &dyn Shape, prec: Precision) {
    let cases = batch(shape, prec);
    validate(shape, prec, &cases);
    let mut g = c.benchmark_group(format!("poly/{}", shape.name()));
    g.throughput(Throughput::Elements(cases.len() as u64));
    for (m, info) in shape.info().methods.iter().enumerate() {
        g.bench_function(format!("{}/{}", info.name, prec.name()), |b| {
            b.iter(|| {
                for (_, v) in &cases {
                    black_box(shape.run(m, black_box(v), prec));
                }
            })
        });
    }
    g.finish();
}

fn benches(c: &mut Criterion) {
    for shape in registry() {
        let polynomial = ["quadratic", "cubic", "quartic"].contains(&shape.name());
        if !polynomial && !["newton", "rcp", "rsqrt"].contains(&shape.name()) {
            continue;
        }
        for prec in Precision::ALL {
            match (polynomial, prec) {
                (true, Precision::F32) => time_polys::<f32>(c, shape, prec),
                (true, Precision::F64) => time_polys::<f64>(c, shape, prec),
                (false, _) => time_shape(c, shape, prec),
            }
        }
    }
}

criterion_group! {
    name = poly_benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1))
        .sample_size(20);
    targets = benches
}
criterion_main!(poly_benches);
