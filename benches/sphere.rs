//! Criterion bench: nanoseconds per ray–sphere test for every method × precision, on three
//! fixed batches (seed 7) built once from the hard-case classes:
//! - `sphere/mix`: 512 cases from each of random, inside, far_small, huge, grazing, behind;
//! - `sphere/hits`: 2048 cases from those classes whose exact verdict is a hit;
//! - `sphere/misses`: 2048 cases from those classes whose exact verdict is a miss.
//! - `sphere/fan30`: the fan30 mix, 4096 sphere tests recorded while rendering
//!   `reference/scenes/fan30.toml` (every n-th test of a 256-wide render with the scene's own
//!   method), as the renderer passes them: what a real frame asks of the test. These cases have
//!   no class, so only a method held to zero in every class refuses to time on them.
//!
//! Beside the methods, `certified_floor` ([`rayproof::shapes::sphere::certified::floors`]): the
//! part of `certified` every answer computes, without its certificate, the least a certified
//! answer can cost.
//!
//! One iteration runs a method over the whole batch; the throughput is the batch length, so
//! criterion's elements/s is tests/s (and time/iteration ÷ length is ns/test).
//!
//! Validation comes first, as in libm-test: every method's answer on every well-posed case is
//! judged against the exact oracle as the audit judges it. A judgement the tolerance table
//! forbids outright for the row (method, precision, class) — a wrong verdict where none is
//! allowed, a false hit where `max_false_hits = 0`, an error above `max_ulps` — refuses to
//! time (panics with the replay line). Other wrong verdicts are counted and printed, so the
//! timing is honest about what it times.

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion, Throughput};
use rayproof::audit::tolerance::Table;
use rayproof::audit::{judge, probe_line, Shape};
use rayproof::numerics::Precision;
use rayproof::render::{render, scene, Overrides};
use rayproof::shapes::sphere::cases::{generate, Class};
use rayproof::shapes::sphere::certified::floors::floor;
use rayproof::shapes::sphere::methods::{PickPrecision, Ray, Sphere, SphereHit, METHODS};
use rayproof::shapes::sphere::oracle::{truth, Case, Truth};
use rayproof::shapes::sphere::SphereShape;
use std::hint::black_box;
use std::time::Duration;

const SEED: u64 = 7;
use rayproof::shapes::sphere::batch::MIX;
const PER_CLASS: u64 = 512;
const SIDE_LEN: usize = 2048;
const FAN30_LEN: usize = 4096;

/// A fixed batch: the cases with their oracle truth, and the pre-built inputs that are timed.
/// Cases recorded from a render have no class (`None`).
struct Batch<F: PickPrecision> {
    name: &'static str,
    cases: Vec<(Option<Class>, Case<F>, Truth)>,
    rays: Vec<Ray<F>>,
    spheres: Vec<Sphere<F>>,
}

impl<F: PickPrecision> Batch<F> {
    fn new(name: &'static str, cases: Vec<(Option<Class>, Case<F>, Truth)>) -> Self {
        let rays = cases.iter().map(|(_, c, _)| c.ray()).collect();
        let spheres = cases.iter().map(|(_, c, _)| c.sphere()).collect();
        Batch {
            name,
            cases,
            rays,
            spheres,
        }
    }
}

/// Cases of the mix classes, round robin by index, with their truth.
fn stream<F: PickPrecision>() -> impl Iterator<Item = (Option<Class>, Case<F>, Truth)> {
    (0u64..)
        .flat_map(|i| MIX.into_iter().map(move |class| (class, i)))
        .filter_map(|(class, i)| generate::<F>(SEED, class, i).map(|c| (class, c)))
        .map(|(class, c)| (Some(class), c, truth(&c)))
}

/// Sphere tests recorded while rendering fan30, rounded to `F` as the renderer rounds them.
fn fan30<F: PickPrecision>() -> Vec<(Option<Class>, Case<F>, Truth)> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/scenes/fan30.toml");
    let sc = scene::load(&path).expect("reference/scenes/fan30.toml loads");
    let ov = |every| Overrides {
        size: Some((256, 256)),
        grid: Some(1),
        record_every: every,
        ..Default::default()
    };
    // Pick the stride that yields about FAN30_LEN recorded tests
    let tests = render(&sc, &ov(0)).counts.tests.sphere_tests;
    let every = (tests / FAN30_LEN as u64).max(1);
    render(&sc, &ov(every))
        .recorded
        .into_iter()
        .take(FAN30_LEN)
        .map(|x| {
            let c = Case::from_scalars(x.map(F::from_f64));
            (None, c, truth(&c))
        })
        .collect()
}

// Build batches
fn build<F: PickPrecision>() -> [Batch<F>; 4] {
    let mix: Vec<_> = MIX
        .into_iter()
        .flat_map(|class| {
            (0..PER_CLASS).filter_map(move |i| generate::<F>(SEED, class, i).map(|c| (class, c)))
        })
        .map(|(class, c)| (Some(class), c, truth(&c)))
        .collect();
    let hits = stream::<F>().filter(|(_, _, t)| t.verdict.is_hit());
    let misses = stream::<F>().filter(|(_, _, t)| !t.verdict.is_hit());
    [
        Batch::new("mix", mix),
        Batch::new("hits", hits.take(SIDE_LEN).collect()),
        Batch::new("misses", misses.take(SIDE_LEN).collect()),
        Batch::new("fan30", fan30()),
    ]
}

// Validate against the oracle before timing
fn validate<F: PickPrecision>(b: &Batch<F>) {
    let p = if F::NAME == "f32" {
        Precision::F32
    } else {
        Precision::F64
    };
    let (shape, table) = (&SphereShape, Table::built_in());
    for (k, m) in METHODS.iter().enumerate() {
        let (mut wrong, mut posed) = (0usize, 0usize);
        for (class, case, truth) in &b.cases {
            if truth.ill_posed {
                continue; // not a failure by definition
            }
            posed += 1;
            let input: Vec<f64> = case.scalars().iter().map(|x| x.to_f64()).collect();
            let exact = shape.oracle(&input, p);
            let j = judge(&exact, &shape.run(k, &input, p), shape.info(), p);
            if !j.is_wrong() {
                continue;
            }
            wrong += 1;
            // The class's row forbids it; a recorded render case has no class, so it is held
            // only by a method whose every row forbids it
            let forbids = |class: Class| table.forbids("sphere", m.name, p, class.name(), j);
            let held = match class {
                Some(class) => forbids(*class),
                None => Class::ALL.into_iter().all(forbids),
            };
            assert!(
                !held,
                "refusing to time sphere/{}: {}/{} gave {} on a well-posed {} case, which the \
                 tolerance table forbids\n  replay: {}",
                b.name,
                m.name,
                F::NAME,
                j.verdict_word(),
                class.map_or("recorded render", |c| c.name()),
                probe_line("sphere", p, &input)
            );
        }
        eprintln!(
            "validated sphere/{} {}/{}: {wrong} wrong verdicts of {posed} well-posed cases{}",
            b.name,
            m.name,
            F::NAME,
            if m.robust { "" } else { " (not robust)" }
        );
    }
}

/// One test as the methods take it.
type Test<F> = fn(&Ray<F>, &Sphere<F>) -> Option<SphereHit<F>>;

// Time every method over the whole batch, and certified's floor (its part without the
// certificate: not a method, so not validated)
fn time<F: PickPrecision>(g: &mut BenchmarkGroup<'_, WallTime>, b: &Batch<F>) {
    g.throughput(Throughput::Elements(b.cases.len() as u64));
    let floor: Test<F> = floor;
    let methods = METHODS.iter().map(|m| (m.name, F::pick(m)));
    for (name, f) in methods.chain([("certified_floor", floor)]) {
        g.bench_function(format!("{}/{}", name, F::NAME), |bench| {
            bench.iter(|| {
                let f = black_box(f);
                let mut sum = 0.0f64;
                for (r, s) in black_box(&b.rays).iter().zip(black_box(&b.spheres)) {
                    if let Some(h) = f(r, s) {
                        sum += h.t.to_f64();
                    }
                }
                sum
            })
        });
    }
}

fn sphere(c: &mut Criterion) {
    let (b32, b64) = (build::<f32>(), build::<f64>());
    b32.iter().for_each(validate);
    b64.iter().for_each(validate);
    for (x, y) in b32.iter().zip(&b64) {
        let mut g = c.benchmark_group(format!("sphere/{}", x.name));
        time(&mut g, x);
        time(&mut g, y);
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = sphere
}
criterion_main!(benches);
