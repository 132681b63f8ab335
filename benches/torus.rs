//! Criterion bench: nanoseconds per ray–torus test for every method × precision, on a fixed
//! batch (seed 7): 128 cases from each valid class (generic, grazing, hole, inside_tube, far,
//! thin, fat), and the robust normal against the chapter's gradient at the robust hits.
//!
//! One iteration runs a method over the whole batch; the throughput is the batch length, so
//! criterion's elements/s is tests/s.
//!
//! Validation comes first: every method's answer on every well-posed case is judged against the
//! exact oracle. A wrong verdict or an error beyond the bound where the tolerance table holds
//! the row (the robust method) refuses to time, with the replay line; the other methods' wrong
//! verdicts are counted and printed, so the timing is honest about what it times.

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion, Throughput};
use rayproof::audit::run::generate;
use rayproof::audit::tolerance::Table;
use rayproof::audit::{judge, probe_line, Shape, Truth};
use rayproof::numerics::real::Real;
use rayproof::numerics::Precision;
use rayproof::shapes::torus::{
    cases, methods, pick, torus_normal, torus_robust_hit, Torus, METHODS,
};
use std::hint::black_box;
use std::time::Duration;

const SEED: u64 = 7;
const PER_CLASS: u64 = 128;

/// The batch of one precision: inputs as scalars (with class and truth) and as `F` tuples.
struct Batch<F> {
    cases: Vec<(usize, Vec<f64>, Truth)>,
    inputs: Vec<([F; 3], [F; 3], F, F)>,
}

fn build<F: Real>(p: Precision) -> Batch<F> {
    let cases: Vec<_> = (0..cases::CLASSES.len() - 1)
        .flat_map(|class| (0..PER_CLASS).map(move |i| (class, i)))
        .filter_map(|(class, i)| generate(&Torus, SEED, class, p, i).map(|x| (class, x)))
        .map(|(class, x)| {
            let t = Torus.oracle(&x, p);
            (class, x, t)
        })
        .collect();
    let inputs = cases
        .iter()
        .map(|(_, x, _)| {
            let f = |i: usize| F::from_f64(x[i]);
            ([f(0), f(1), f(2)], [f(3), f(4), f(5)], f(6), f(7))
        })
        .collect();
    Batch { cases, inputs }
}

// Validate against the oracle before timing
fn validate<F: Real>(b: &Batch<F>, p: Precision) {
    let table = Table::built_in();
    for (m, info) in METHODS.iter().enumerate() {
        let (mut wrong, mut posed) = (0, 0);
        for (class, x, truth) in &b.cases {
            if matches!(truth, Truth::Answer(e) if e.ill_posed) {
                continue;
            }
            posed += 1;
            let j = judge(truth, &Torus.run(m, x, p), Torus.info(), p);
            let forbidden = table.forbids("torus", info.name, p, cases::CLASSES[*class], j);
            let beyond = j.ulps().is_some() && forbidden;
            if !j.is_wrong() && !beyond {
                continue;
            }
            wrong += 1;
            assert!(
                !forbidden,
                "refusing to time torus {}/{}: {} on a well-posed {} case, which the tolerance \
                 table holds to zero\n  replay: {}",
                info.name,
                F::NAME,
                j.verdict_word(),
                cases::CLASSES[*class],
                probe_line(Torus.name(), p, x)
            );
        }
        eprintln!(
            "validated torus {}/{}: {wrong} wrong or out-of-bound of {posed} well-posed cases{}",
            info.name,
            F::NAME,
            if info.robust { "" } else { " (not robust)" }
        );
    }
}

/// A normal at a surface point.
type NormalFn<F> = fn([F; 3], F, F) -> [F; 3];

// Time every method over the whole batch, then the two normals at the robust hits
fn time<F: Real>(g: &mut BenchmarkGroup<'_, WallTime>, b: &Batch<F>) {
    g.throughput(Throughput::Elements(b.inputs.len() as u64));
    for (m, info) in METHODS.iter().enumerate() {
        let f = pick::<F>(m);
        g.bench_function(format!("{}/{}", info.name, F::NAME), |bench| {
            bench.iter(|| {
                let f = black_box(f);
                let mut sum = 0.0f64;
                for &(o, d, r1, r2) in black_box(&b.inputs) {
                    if let Some(t) = f(o, d, r1, r2) {
                        sum += t.to_f64();
                    }
                }
                sum
            })
        });
    }
    let hits: Vec<_> = b
        .inputs
        .iter()
        .filter_map(|&(o, d, r1, r2)| torus_robust_hit(o, d, r1, r2).map(|(_, p)| (p, r1, r2)))
        .collect();
    let normals: [(&str, NormalFn<F>); 2] = [
        ("normal_robust", torus_normal::<F>),
        ("normal_gradient", methods::gradient::<F>),
    ];
    for (name, n) in normals {
        g.bench_function(format!("{name}/{}", F::NAME), |bench| {
            bench.iter(|| {
                let mut sum = 0.0f64;
                for &(p, r1, r2) in black_box(&hits) {
                    sum += methods::normalize(n(p, r1, r2))[0].to_f64();
                }
                sum
            })
        });
    }
}

fn torus(c: &mut Criterion) {
    let (b32, b64) = (build::<f32>(Precision::F32), build::<f64>(Precision::F64));
    validate(&b32, Precision::F32);
    validate(&b64, Precision::F64);
    let mut g = c.benchmark_group("torus/mix");
    time(&mut g, &b32);
    time(&mut g, &b64);
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = torus
}
criterion_main!(benches);
