//! Criterion bench: the primary visibility pass of `reference/implicit/bunny.toml` (the MPU
//! bunny at 400×400, seed 004's Table 1) by per-pixel sphere tracing, by the paper's image-space
//! subdivision and by the certified subdivision, 10×10 blocks. Criterion times each mode
//! separately; `scripts/bench-implicit` times all of them in one run and prints the ratios.
//!
//! Validation comes first: the certified pass must reproduce the per-pixel pass's coverage
//! exactly (0 lost, 0 ghost pixels) or the bench refuses to time.

use criterion::{criterion_group, criterion_main, Criterion};
use rayproof::implicit::check::{marcher, size};
use rayproof::implicit::subdiv::{primary, Mode};
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
    // Validate: the certified pass covers exactly the per-pixel pass's pixels
    let full = primary(&m, &lens, (w, h), Mode::Full, 10);
    let cert = primary(&m, &lens, (w, h), Mode::Certified, 10);
    let differ = full
        .pixels
        .iter()
        .zip(&cert.pixels)
        .filter(|(a, b)| a.hit.is_some() != b.hit.is_some())
        .count();
    assert_eq!(differ, 0, "certified coverage differs on {differ} pixels");
    let mut g = c.benchmark_group("bunny_400_primary");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    for mode in Mode::ALL {
        g.bench_function(mode.name(), |b| {
            b.iter(|| black_box(primary(&m, &lens, (w, h), mode, 10).stats.rays))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
