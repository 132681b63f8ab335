//! Criterion bench: nanoseconds per value for every row of the Newton table (src/newton.rs):
//! `1/x` and `1/√x` by division / `√`, and from the hardware estimate or the bit trick with
//! 0–3 Newton steps, in `f32`.
//!
//! Each variant runs over the table's fixed timed array (4096 inputs spread evenly over
//! `[1, 2)` for `1/x`, `[1, 4)` for `1/√x`); the throughput is the array length, so criterion's
//! elements/s is values/s.
//!
//! Validation comes first, as in libm-test: every variant's answers on the timed array are
//! compared with MPFR, and a variant whose largest error exceeds its documented bound
//! ([`Variant::bound_ulps`]) is refused (panics with the input as a hex float).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rayproof::numerics::real::hex_float;
use rayproof::shapes::recip::newton::{accuracy, eval_slice, timed_inputs, Func, Variant};
use std::hint::black_box;
use std::time::Duration;

const LEN: usize = 4096;

fn newton(c: &mut Criterion) {
    for func in Func::ALL {
        // The timed array and its exact values
        let xs = timed_inputs(func, LEN);
        let exact = func.exact_all(&xs);
        let mut g = c.benchmark_group(format!("newton/{}", func.name()));
        g.throughput(Throughput::Elements(LEN as u64));
        for v in Variant::all().into_iter().filter(|v| v.func() == func) {
            // Validate against MPFR before timing
            let acc = accuracy(v, &xs, &exact);
            assert!(
                acc.max_ulps <= v.bound_ulps(),
                "refusing to time {}: {} ulps at {} (answer {}), documented bound {}",
                v.label(),
                acc.max_ulps,
                hex_float(acc.worst_input as f64),
                hex_float(acc.worst_output as f64),
                v.bound_ulps()
            );
            eprintln!(
                "validated {}: max {:.4} ulps (bound {:.4}) on {} inputs",
                v.label(),
                acc.max_ulps,
                v.bound_ulps(),
                acc.inputs
            );
            // Time the whole array
            let name = match v.steps() {
                None => v.start_name().to_string(),
                Some(s) => format!("{}+{s}", v.start_name()),
            };
            let mut out = vec![0f32; LEN];
            g.bench_function(name, |b| {
                b.iter(|| {
                    let _ = eval_slice(v, black_box(&xs), &mut out);
                    black_box(&mut out);
                })
            });
        }
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    targets = newton
}
criterion_main!(benches);
