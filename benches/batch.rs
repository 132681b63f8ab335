//! Criterion bench: the batched (structure-of-arrays) ray–sphere kernels against the scalar
//! methods on the same tests, `f32` and `f64`.
//!
//! The batch is `benches/sphere.rs`'s `sphere/mix`: 512 cases (seed 7) from each of random,
//! inside, far_small, huge, grazing, behind (`batch::MIX`). For `geometric`, `geometric_fma`, `rtg7` and
//! `certified` (whose lanes run its first look, the rest finished by its scalar phases), one
//! iteration runs over the whole batch: the scalar method (AoS rays and spheres, called
//! directly, and once more through a function pointer, as `benches/sphere.rs` calls every
//! method), then the batched kernel with each instruction set this machine has (`sse2`, and
//! `avx2` and `avx512` when available). The throughput is the batch length, so elements/s is tests/s.
//!
//! Validation comes first: every kernel must give the scalar method's answer bit for bit (same
//! hit/miss, same bits of `t`) on every test of the batch, or the bench refuses to time it and
//! prints the replay line.

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion, Throughput};
use rayproof::numerics::real::Real;
use rayproof::shapes::sphere::batch::{
    check_identical, mix_cases, run_batch, run_scalar, BatchMethod, Certified, CertifiedFloor,
    Geometric, GeometricFma, Isa, Rtg7, SphereBatch,
};
use rayproof::shapes::sphere::methods::{Ray, Sphere, SphereHit};
use std::hint::black_box;
use std::time::Duration;

const SEED: u64 = 7;
const PER_CLASS: u64 = 512;

/// The mix batch in both layouts.
struct Inputs<F: Real> {
    batch: SphereBatch<F>,
    rays: Vec<Ray<F>>,
    spheres: Vec<Sphere<F>>,
}

fn inputs<F: Real>() -> Inputs<F> {
    let cases = mix_cases::<F>(SEED, PER_CLASS);
    Inputs {
        batch: SphereBatch::from_cases(&cases),
        rays: cases.iter().map(|c| c.ray()).collect(),
        spheres: cases.iter().map(|c| c.sphere()).collect(),
    }
}

// Validate, then time scalar and every instruction set
fn time<M: BatchMethod, F: Real>(g: &mut BenchmarkGroup<'_, WallTime>, x: &Inputs<F>) {
    let n = x.batch.len();
    let mut out = vec![F::ZERO; n];
    for isa in Isa::all_available() {
        if let Err(e) = check_identical::<M, F>(isa, &x.batch) {
            panic!(
                "refusing to time {}/{} {}: {e}",
                M::NAME,
                F::NAME,
                isa.name()
            );
        }
        eprintln!(
            "validated {}/{} {}: bit-identical to the scalar method on {n} tests",
            M::NAME,
            F::NAME,
            isa.name()
        );
    }
    g.bench_function(format!("{}/{}/scalar", M::NAME, F::NAME), |b| {
        b.iter(|| {
            let _ = run_scalar::<M, F>(black_box(&x.rays), black_box(&x.spheres), &mut out);
            black_box(&mut out);
        })
    });
    // The same scalar method called as benches/sphere.rs calls it: through a function pointer
    // the compiler cannot see through, so it is not inlined into the loop
    let f: fn(&Ray<F>, &Sphere<F>) -> Option<SphereHit<F>> = M::scalar::<F>;
    g.bench_function(format!("{}/{}/scalar-by-pointer", M::NAME, F::NAME), |b| {
        b.iter(|| {
            let f = black_box(f);
            for ((o, r), s) in out
                .iter_mut()
                .zip(black_box(&x.rays))
                .zip(black_box(&x.spheres))
            {
                *o = f(r, s).map_or(F::NAN, |h| h.t);
            }
            black_box(&mut out);
        })
    });
    for isa in Isa::all_available() {
        g.bench_function(format!("{}/{}/{}", M::NAME, F::NAME, isa.name()), |b| {
            b.iter(|| {
                let _ = run_batch::<M, F>(isa, black_box(&x.batch), &mut out);
                black_box(&mut out);
            })
        });
    }
}

fn batch(c: &mut Criterion) {
    let (x32, x64) = (inputs::<f32>(), inputs::<f64>());
    let mut g = c.benchmark_group("batch/mix");
    g.throughput(Throughput::Elements(x32.batch.len() as u64));
    time::<Geometric, f32>(&mut g, &x32);
    time::<GeometricFma, f32>(&mut g, &x32);
    time::<Rtg7, f32>(&mut g, &x32);
    time::<Certified, f32>(&mut g, &x32);
    time::<CertifiedFloor, f32>(&mut g, &x32);
    g.throughput(Throughput::Elements(x64.batch.len() as u64));
    time::<Geometric, f64>(&mut g, &x64);
    time::<GeometricFma, f64>(&mut g, &x64);
    time::<Rtg7, f64>(&mut g, &x64);
    time::<Certified, f64>(&mut g, &x64);
    time::<CertifiedFloor, f64>(&mut g, &x64);
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = batch
}
criterion_main!(benches);
