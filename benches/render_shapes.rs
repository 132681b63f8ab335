//! Criterion bench: nanoseconds per renderer hit test ([`solid_hit`]: the robust routine in its
//! object space, plus the normal) for the box, cylinder side, ellipsoid and torus of
//! `reference/scenes/shapes.toml`, each on a fixed batch of the rays a frame asks about it
//! ([`sample_rays`], seed 7: camera rays towards its bounds and secondary rays spawned from its
//! hits). One iteration runs the whole batch; criterion's elements/s is tests/s.
//!
//! Validation comes first: every well-posed ray of the box, cylinder and torus batches is judged
//! by that routine's exact oracle, and a wrong verdict refuses to time (panics with the replay
//! line). The ellipsoid's routine has no audit shape of the same form (`routine_input`), so its
//! batch is timed unjudged; `tests/render.rs` checks its hits and normals analytically.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::DVec3;
use rand::SeedableRng;
use rayproof::audit::Judgement;
use rayproof::audit::{judge, Answer, Truth};
use rayproof::numerics::Precision;
use rayproof::render::geom::{routine_input, sample_rays, solid_hit, Prim};
use rayproof::render::{build_geometry, scene};
use rayproof::shapes::shape_by_name;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

/// Camera rays per shape (each hit adds three secondary rays).
const CAMERA_RAYS: usize = 256;

/// The kind of a routine primitive, for the bench name.
fn kind(p: &Prim) -> Option<&'static str> {
    match p {
        Prim::Box { .. } => Some("box"),
        Prim::CylinderSide { .. } => Some("cylinder"),
        Prim::Ellipsoid { .. } => Some("ellipsoid"),
        Prim::Torus { .. } => Some("torus"),
        _ => None,
    }
}

/// Panics on a wrong verdict of a well-posed ray; returns how many were judged.
fn validate(p: &Prim, rays: &[(DVec3, DVec3)]) -> usize {
    let mut judged = 0;
    for &(o, d) in rays {
        let Some((name, input)) = routine_input(p, o, d) else {
            return 0;
        };
        let shape = shape_by_name(name).expect("registered shape");
        let truth = shape.oracle(&input, Precision::F64);
        if matches!(&truth, Truth::Answer(e) if e.ill_posed) {
            continue;
        }
        let answer = solid_hit(p, o, d).map_or(Answer::miss(), |(t, _)| Answer::hit(vec![t]));
        match judge(&truth, &answer, shape.info(), Precision::F64) {
            Judgement::Ok { .. } => judged += 1,
            j => panic!(
                "{name}: {j:?}; refusing to time. Replay: {}",
                rayproof::shapes::shape::probe_line(shape.name(), Precision::F64, &input)
            ),
        }
    }
    judged
}

fn bench(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/scenes/shapes.toml");
    let s = scene::load(&path).expect("shapes scene");
    let (geo, _) = build_geometry(&s);
    let cam = DVec3::from_array(s.file.camera.position);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut g = c.benchmark_group("render_shapes");
    g.measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_millis(500));
    for obj in &geo.objects {
        let Some(name) = kind(&obj.prim) else {
            continue;
        };
        let rays = sample_rays(&obj.prim, cam, CAMERA_RAYS, &mut rng);
        let judged = validate(&obj.prim, &rays);
        eprintln!(
            "render_shapes/{name}: {} rays, {judged} judged right by the exact oracle",
            rays.len()
        );
        g.throughput(Throughput::Elements(rays.len() as u64));
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut hits = 0u32;
                for &(o, d) in &rays {
                    hits += solid_hit(black_box(&obj.prim), black_box(o), black_box(d)).is_some()
                        as u32;
                }
                hits
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
