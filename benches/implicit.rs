//! Criterion bench: the primary visibility pass of `reference/implicit/bunny.toml` (the MPU
//! bunny at 400×400, seed 004's Table 1) for every (mode, tracer) pair of
//! [`rayproof::render::subdiv::check::RUNS`], 10×10 blocks. Criterion times each separately;
//! `scripts/bench-implicit` times all of them in one run and prints the ratios.
//!
//! Validation comes first: each certified pass must reproduce the coverage of the per-pixel
//! pass with its tracer exactly (0 lost, 0 ghost pixels) or the bench refuses to time.

use criterion::{criterion_group, criterion_main, Criterion};
use rayproof::implicit::march::{Marcher, Tracer};
use rayproof::render::subdiv::check::{marcher, size, RUNS};
use rayproof::render::subdiv::{primary, Mode};
use rayproof::render::{scene, Lens};
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/implicit/bunny.toml");
    let s = scene::load(&path).expect("bunny scene");
    let (m, _) = marcher(&s).expect("implicit scene");
    let (w, h) = size(&s, None);
    let lens = Lens::new(&s, w, h);
    let by = |t: Tracer| Marcher::with(m.fields.clone(), t);
    // Validate: each certified pass covers exactly its per-pixel pass's pixels
    for t in [Tracer::Global, Tracer::Local] {
        let full = primary(&by(t), &lens, (w, h), Mode::Full, 10);
        let cert = primary(&by(t), &lens, (w, h), Mode::Certified, 10);
        let differ = full
            .pixels
            .iter()
            .zip(&cert.pixels)
            .filter(|(a, b)| a.hit.is_some() != b.hit.is_some())
            .count();
        assert_eq!(
            differ, 0,
            "certified/{t:?} coverage differs on {differ} pixels"
        );
    }
    let mut g = c.benchmark_group("bunny_400_primary");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    for (mode, t) in RUNS {
        let mt = by(t);
        g.bench_function(format!("{}/{}", mode.name(), t.name()), |b| {
            b.iter(|| black_box(primary(&mt, &lens, (w, h), mode, 10).stats.rays))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
