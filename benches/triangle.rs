//! Criterion bench: nanoseconds per ray–triangle test for every method × precision, over a
//! fixed batch (seed 7) of 512 cases from each of the generic, edge, vertex, far and huge
//! classes, and per reflection/refraction vector over 1,024 generic cases (these through
//! `Shape::run`, so they include the input conversion and the answer's `Vec`). One iteration runs a
//! method over the whole batch (criterion's elements/s is tests/s).
//!
//! Validation comes first: every method's answer on every well-posed case is judged against
//! the exact oracle. A wrong verdict by a robust method refuses to time (panics with the replay
//! line); the other methods' wrong verdicts are counted and printed.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rayproof::audit::run::generate;
use rayproof::audit::{judge, probe_line, Shape, Truth};
use rayproof::numerics::Precision;
use rayproof::shapes::optics::{Reflect, Refract};
use rayproof::shapes::triangle::{method, Triangle, METHODS};
use std::hint::black_box;
use std::time::Duration;

const SEED: u64 = 7;
/// A ray and a triangle: origin, direction, vertices.
type Ray<F> = ([F; 3], [F; 3], [[F; 3]; 3]);

const MIX: [&str; 5] = ["generic", "edge", "vertex", "far", "huge"];

/// Cases of the named classes of a shape, generated as the audit does.
fn batch(shape: &dyn Shape, classes: &[&str], per: u64, prec: Precision) -> Vec<Vec<f64>> {
    classes
        .iter()
        .flat_map(|c| {
            let k = shape
                .info()
                .classes
                .iter()
                .position(|x| x == c)
                .expect("class");
            (0..per).filter_map(move |i| generate(shape, SEED, k, prec, i))
        })
        .collect()
}

/// Judges every method on every well-posed case; robust methods must be right.
fn validate(shape: &dyn Shape, cases: &[Vec<f64>], prec: Precision) {
    let truths: Vec<Truth> = cases.iter().map(|v| shape.oracle(v, prec)).collect();
    for (m, info) in shape.info().methods.iter().enumerate() {
        let mut wrong = 0;
        for (v, t) in cases.iter().zip(&truths) {
            if matches!(t, Truth::Answer(e) if e.ill_posed) {
                continue;
            }
            let j = judge(t, &shape.run(m, v, prec), shape.info(), prec);
            if j.is_wrong() || (matches!(t, Truth::Invalid) && j.verdict_word() != "invalid") {
                wrong += 1;
                assert!(
                    !info.robust,
                    "refusing to time {}: {} gave {} on a well-posed case\n  {}",
                    shape.name(),
                    info.name,
                    j.verdict_word(),
                    probe_line(shape.name(), prec, v)
                );
            }
        }
        eprintln!(
            "validated {} {}/{}: {wrong} wrong of {} cases",
            shape.name(),
            info.name,
            prec.name(),
            cases.len()
        );
    }
}

fn triangles<F: rayproof::numerics::real::Real>(c: &mut Criterion, prec: Precision) {
    let cases = batch(&Triangle, &MIX, 512, prec);
    validate(&Triangle, &cases, prec);
    let rays: Vec<Ray<F>> = cases
        .iter()
        .map(|v| {
            let x = |i: usize| [v[i], v[i + 1], v[i + 2]].map(F::from_f64);
            (x(0), x(3), [x(6), x(9), x(12)])
        })
        .collect();
    let mut g = c.benchmark_group("triangle/mix");
    g.throughput(Throughput::Elements(rays.len() as u64));
    for (m, info) in METHODS.iter().enumerate() {
        let f = method::<F>(m);
        g.bench_function(format!("{}/{}", info.name, F::NAME), |b| {
            b.iter(|| {
                let f = black_box(f);
                let mut sum = 0.0;
                for &(o, d, p) in black_box(&rays) {
                    if let Some(h) = f(o, d, p) {
                        sum += h.t.to_f64();
                    }
                }
                sum
            })
        });
    }
    g.finish();
}

fn vectors(c: &mut Criterion, shape: &dyn Shape, prec: Precision) {
    let cases = batch(shape, &["generic"], 1024, prec);
    validate(shape, &cases, prec);
    let mut g = c.benchmark_group(format!("{}/generic", shape.name()));
    g.throughput(Throughput::Elements(cases.len() as u64));
    for (m, info) in shape.info().methods.iter().enumerate() {
        g.bench_function(format!("{}/{}", info.name, prec.name()), |b| {
            b.iter(|| {
                black_box(&cases)
                    .iter()
                    .map(|v| shape.run(m, v, prec).count)
                    .sum::<u32>()
            })
        });
    }
    g.finish();
}

fn bench(c: &mut Criterion) {
    triangles::<f32>(c, Precision::F32);
    triangles::<f64>(c, Precision::F64);
    for prec in Precision::ALL {
        vectors(c, &Reflect, prec);
        vectors(c, &Refract, prec);
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = bench
}
criterion_main!(benches);
