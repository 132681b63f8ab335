//! Implicit surfaces (seed 004): sphere tracing against the audited analytic intersections,
//! `implicit-check` on the reference scenes (the certified mode loses nothing; the paper's
//! sampling loses the adversarial features), blob against POV-Ray 3.7, and bad input.

use crate::common::rayproof;
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rayproof::implicit::field::{Field, SdfPart};
use rayproof::implicit::march::Marcher;
use rayproof::render::scene;
use rayproof::render::subdiv::check::{self, Options};
use rayproof::render::subdiv::Mode;
use rayproof::shapes::{aabb, quadric, torus};
use std::path::Path;

fn sdf(part: SdfPart) -> Marcher {
    Marcher::new(vec![Field::Sdf {
        parts: vec![part],
        blend: 0.0,
    }])
}

/// Random rays from a shell of radius 4–6 aimed at points within `spread` of the origin.
fn rays(seed: u64, n: usize, spread: f64) -> Vec<(DVec3, DVec3)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let unit = |rng: &mut rand_chacha::ChaCha8Rng| loop {
        let v = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.length_squared() > 1e-3 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    };
    (0..n)
        .map(|_| {
            let o = unit(&mut rng) * rng.random_range(4.0..6.0);
            let target = unit(&mut rng) * rng.random_range(0.0..spread);
            (o, (target - o).normalize())
        })
        .collect()
}

/// Sphere tracing agrees with an analytic first hit: hit/miss everywhere except within
/// `graze` of tangency (where `near_tangent` says so), and `t` to 1e-12 relative.
fn agree(
    m: &Marcher,
    exact: impl Fn(DVec3, DVec3) -> Option<f64>,
    near_tangent: impl Fn(DVec3, DVec3) -> bool,
    seed: u64,
) -> (usize, usize) {
    let (mut hits, mut skipped) = (0, 0);
    for (o, d) in rays(seed, 4000, 2.0) {
        if near_tangent(o, d) {
            skipped += 1;
            continue;
        }
        let traced = m.trace(o, d, 0.0);
        let want = exact(o, d);
        match (traced.hit, want) {
            (Some((t, _)), Some(e)) => {
                assert!(
                    (t - e).abs() <= 1e-12 * e,
                    "o {o:?} d {d:?}: traced {t:e}, exact {e:e}"
                );
                hits += 1;
            }
            (None, None) => {}
            (a, b) => panic!("o {o:?} d {d:?}: traced {a:?}, exact {b:?}"),
        }
        assert!(!traced.capped);
    }
    (hits, skipped)
}

#[test]
fn sphere_tracing_matches_the_robust_sphere() {
    let m = sdf(SdfPart::Sphere {
        center: [0.0; 3],
        radius: 1.0,
    });
    let exact =
        |o: DVec3, d: DVec3| quadric::ellipsoid_robust(o.to_array(), d.to_array(), [1.0; 3]);
    // Tangent: the ray's closest approach to the centre is within 1e-6 of the radius
    let tangent = |o: DVec3, d: DVec3| ((o - d * o.dot(d)).length() - 1.0).abs() < 1e-6;
    let (hits, _) = agree(&m, exact, tangent, 1);
    assert!(hits > 1000, "{hits}");
}

#[test]
fn sphere_tracing_matches_the_robust_box() {
    let (lo, hi) = ([-0.7, -0.4, -1.0], [0.5, 0.9, 0.3]);
    let m = sdf(SdfPart::Box { min: lo, max: hi });
    let exact = |o: DVec3, d: DVec3| aabb::box_robust(o.to_array(), d.to_array(), lo, hi);
    // Near an edge or face plane at the crossing (the slab's padding and grazing rays)
    let near = |o: DVec3, d: DVec3| {
        let f = Field::Sdf {
            parts: vec![SdfPart::Box { min: lo, max: hi }],
            blend: 0.0,
        };
        // Closest approach of the ray to the box surface, sampled finely
        (0..20000).any(|k| {
            let p = o + d * (k as f64 * 6e-4);
            let v = f.eval(p).abs();
            let q = (p - (DVec3::from_array(lo) + DVec3::from_array(hi)) * 0.5).abs()
                - (DVec3::from_array(hi) - DVec3::from_array(lo)) * 0.5;
            // Within 1e-4 of the surface and within 1e-3 of an edge (two near-zero coordinates)
            v < 1e-3 && [q.x, q.y, q.z].iter().filter(|c| c.abs() < 1e-3).count() >= 2
        })
    };
    let (hits, _) = agree(&m, exact, near, 2);
    assert!(hits > 1000, "{hits}");
}

#[test]
fn sphere_tracing_matches_the_robust_torus() {
    let (major, minor) = (1.0, 0.3);
    let m = sdf(SdfPart::Torus {
        center: [0.0; 3],
        major,
        minor,
    });
    // The routine's torus is around z: swap y and z (a reflection, t unchanged)
    let sw = |v: DVec3| [v.x, v.z, v.y];
    let exact =
        |o: DVec3, d: DVec3| torus::torus_robust_hit(sw(o), sw(d), major, minor).map(|h| h.0);
    let f = Field::Sdf {
        parts: vec![SdfPart::Torus {
            center: [0.0; 3],
            major,
            minor,
        }],
        blend: 0.0,
    };
    // Tangent: the ray's distance to the tube surface has a local minimum near 0
    let tangent = |o: DVec3, d: DVec3| {
        let g: Vec<f64> = (0..40000)
            .map(|k| f.eval(o + d * (k as f64 * 3e-4)))
            .collect();
        g.windows(3)
            .any(|w| w[1] <= w[0] && w[1] <= w[2] && w[1].abs() < 1e-5)
    };
    let (hits, _) = agree(&m, exact, tangent, 3);
    assert!(hits > 1000, "{hits}");
}

fn reference(name: &str) -> scene::Scene {
    scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("reference/implicit/{name}.toml")),
    )
    .expect("reference scene")
}

fn run(name: &str) -> check::Report {
    check::run(
        &reference(name),
        &Options {
            region: 10,
            // The bunny at half its 400×400 (the full size is the bench's)
            width: (name == "bunny").then_some(200),
            repeat: 1,
        },
    )
    .expect("implicit scene")
}

/// The comparison of the run named `name` (`certified`, `certified/local`, …).
fn versus(r: &check::Report, name: &str, shadows: bool) -> check::Comparison {
    r.runs
        .iter()
        .find(|x| x.name == name && x.shadows == shadows)
        .and_then(|x| x.versus_full.clone())
        .expect("compared")
}

#[test]
fn certified_mode_loses_nothing_on_every_reference_scene() {
    for name in ["blob", "sdf", "thin", "speck", "bunny"] {
        let r = run(name);
        for (shadows, run) in [false, true]
            .into_iter()
            .flat_map(|s| ["certified", "certified/local"].map(|n| (s, n)))
        {
            let c = versus(&r, run, shadows);
            assert_eq!(
                (c.lost, c.ghost, c.moved),
                (0, 0, 0),
                "{name} {run} shadows {shadows}"
            );
            assert!(c.surface_pixels > 1000, "{name}");
            assert_eq!(
                c.colour_differs, 0,
                "{name} shadows {shadows}: {}",
                c.max_colour_diff
            );
        }
        // The certified pass traces under 60 % of the pixel rays of per-pixel tracing
        let full = r.runs.iter().find(|x| x.mode == Mode::Full).expect("full");
        let cert = r
            .runs
            .iter()
            .find(|x| x.mode == Mode::Certified)
            .expect("certified");
        assert!(5 * cert.primary.rays < 3 * full.primary.rays, "{name}");
    }
}

#[test]
fn paper_sampling_loses_the_adversarial_features() {
    // The rod between sample rows: every lost pixel is in a skipped block
    let c = versus(&run("thin"), "paper", false);
    assert!(c.lost > 100, "{}", c.lost);
    assert!(c
        .pixels
        .iter()
        .filter(|p| p.kind == "lost")
        .all(|p| p.cause == "skipped" && p.y == 23));
    // The speck inside block (12, 4), between the samples
    let c = versus(&run("speck"), "paper", false);
    assert!(c.lost >= 4, "{}", c.lost);
    assert!(c
        .pixels
        .iter()
        .filter(|p| p.kind == "lost")
        .all(|p| p.cause == "skipped" && (120..130).contains(&p.x) && (40..50).contains(&p.y)));
}

#[test]
fn backward_trace_from_inside_finds_the_entry() {
    // Case ②: a start length past the entry point, inside the object
    let m = sdf(SdfPart::Sphere {
        center: [0.0; 3],
        radius: 1.0,
    });
    for (o, d) in rays(9, 500, 0.5) {
        let Some(e) = quadric::ellipsoid_robust(o.to_array(), d.to_array(), [1.0; 3]) else {
            continue;
        };
        let r = m.trace(o, d, e + 0.1);
        assert!(r.backward);
        let t = r.hit.expect("hit").0;
        assert!((t - e).abs() <= 1e-12 * e, "{t} vs {e}");
    }
}

#[test]
fn blob_matches_povray_reference() {
    // reference/implicit/blob/povray.exr: 256 wide, 8×8 grid (scripts/render-povray)
    let s = reference("blob");
    let r = rayproof::render::render(
        &s,
        &rayproof::render::Overrides {
            grid: Some(8),
            size: Some((256, 192)),
            ..Default::default()
        },
    );
    let pov = rayproof::images::read_image(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/implicit/blob/povray.exr"),
    )
    .expect("POV-Ray reference");
    assert_eq!((pov.width, pov.height), (256, 192));
    let nc = pov.channels.len();
    let (mut sum, mut max) = (0.0f64, 0.0f64);
    for (i, px) in r.beauty.iter().enumerate() {
        for (c, v) in px.iter().enumerate() {
            let e = (v - pov.data[i * nc + c]).abs() as f64;
            sum += e;
            max = max.max(e);
        }
    }
    let mean = sum / (3.0 * r.beauty.len() as f64);
    // Measured: mean 6.2e-7, max 7.8e-5 (the silhouette's sub-pixel coverage)
    assert!(mean < 5e-6 && max < 1e-3, "mean {mean:e}, max {max:e}");
}

#[test]
fn bad_input_gets_one_line_and_exit_2() {
    let dir = tempdir();
    let bad = [
        ("threshold = 0.0", "threshold"),
        ("threshold = nan", "threshold"),
    ];
    for (line, field) in bad {
        let p = dir.join("bad.toml");
        std::fs::write(
            &p,
            format!(
                "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 40.0\nwidth = 8\nheight = 8\n\
                 [materials.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\
                 [[shapes]]\ntype = \"blob\"\n{line}\nmaterial = \"m\"\ncomponents = [{{ center = [0.0, 0.0, 0.0], radius = 1.0, strength = 1.0 }}]\n"
            ),
        )
        .unwrap();
        let out = rayproof(&["implicit-check", p.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(err.contains(field), "{err}");
    }
    // A scene that is not all implicit
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/scenes/diffuse.toml");
    let out = rayproof(&["implicit-check", scenes.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("not implicit"), "{err}");
    // Mitsuba has no implicit surfaces; POV-Ray has no smooth union
    let sdf = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference/implicit/sdf.toml");
    for to in ["mitsuba", "povray"] {
        let out = rayproof(&["export", "--to", to, sdf.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2));
        assert!(out.stdout.is_empty());
    }
    // A zero region
    let out = rayproof(&["implicit-check", sdf.to_str().unwrap(), "--region", "0"]);
    assert_eq!(out.status.code(), Some(2));
    // A camera that sees only background: nothing to compare is refused, not passed
    let away = dir.join("away.toml");
    let text = std::fs::read_to_string(&sdf).unwrap();
    assert!(text.contains("look_at = [0.0, 0.2, 0.0]"));
    std::fs::write(
        &away,
        text.replace("look_at = [0.0, 0.2, 0.0]", "look_at = [0.0, 1.5, 10.0]"),
    )
    .unwrap();
    let out = rayproof(&["implicit-check", away.to_str().unwrap(), "--width", "40"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("would compare nothing"), "{err}");
    assert!(out.stdout.is_empty());
}

fn tempdir() -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("rayproof-implicit-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// An interval enclosure of the blob's `|∇f|` on `[lo, hi]` (∇f = Σ 4sᵢ(1 − uᵢ)·v/Rᵢ²).
fn blob_gradient_enclosure(
    comps: &[rayproof::implicit::field::BlobComponent],
    lo: DVec3,
    hi: DVec3,
) -> rayproof::numerics::interval::Interval<f64> {
    use rayproof::numerics::interval::Interval as I;
    let mut g = [I::point(0.0); 3];
    for c in comps {
        let v = [0, 1, 2].map(|k| I::new(lo[k], hi[k]) - I::point(c.center[k]));
        let k = 1.0 / (c.radius * c.radius);
        let u = (v[0].square() + v[1].square() + v[2].square()) * I::point(k);
        if u.lo >= 1.0 {
            continue;
        }
        let one_u = I::new((1.0 - u.hi).max(0.0), 1.0 - u.lo);
        let a = one_u * I::point(4.0 * c.strength * k);
        for d in 0..3 {
            g[d] = g[d] + a * v[d];
        }
    }
    (g[0].square() + g[1].square() + g[2].square()).sqrt()
}

#[test]
fn blob_local_bounds_hold_on_samples_and_intervals() {
    let s = reference("blob");
    let f = s.implicits.values().next().expect("blob").clone();
    let Field::Blob { components, .. } = &f else {
        panic!("not a blob")
    };
    let lb = f.local_bounds().expect("local bounds");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let (mut worst, mut worst_h) = (0.0f64, 0.0f64);
    for i in 0..lb.len() {
        let ((lo, hi), [l, e, h, _]) = lb.cell(i);
        let pts: Vec<DVec3> = (0..48)
            .map(|_| lo + (hi - lo) * DVec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        for w in pts.windows(2) {
            let (g0, g1) = (f.gradient(w[0]), f.gradient(w[1]));
            assert!(g0.length() <= l, "cell {i}: {} > {l}", g0.length());
            worst = worst.max(g0.length() / l);
            let d = (w[0] - w[1]).length();
            assert!((g0 - g1).length() <= h * d, "cell {i}: curvature above {h}");
            worst_h = worst_h.max((g0 - g1).length() / (h * d));
        }
        // Interval evaluation: a value |∇f| takes on a small box never exceeds the bound
        let a = pts[0];
        let b = (a + (hi - lo) * 0.05).min(hi);
        assert!(
            blob_gradient_enclosure(components, a, b).lo <= l,
            "cell {i}"
        );
        if lb.rings(i) > 0 {
            let sg = f.eval(pts[0]).signum();
            assert!(pts.iter().all(|&p| f.eval(p) * sg > e), "cell {i}");
        }
    }
    // Teeth: the bounds are tight enough that halving one is caught by the samples
    assert!(worst > 0.5, "{worst}");
    assert!(worst_h > 0.0);
}

/// Traces every pixel of `name` at `w`×`h` with the field's proved steps multiplied by each of
/// `ks`, along the ray (`ray`) or as balls, and counts, per factor, the rays whose steps crossed
/// the surface: a safe trace (steps of at least eps) reaches the inside at most eps past the
/// surface, so a first inside point farther past the hit than 2·eps (or none) is a step that
/// crossed it. Returns the hits and the counts.
fn crossings(name: &str, (w, h): (usize, usize), ray: bool, ks: &[f64]) -> (u32, Vec<u32>) {
    let s = reference(name);
    let f = s.implicits.values().next().expect("implicit").clone();
    let m = Marcher::new(vec![f.clone()]);
    let lens = rayproof::render::Lens::new(&s, w, h);
    let mut crossed = vec![0u32; ks.len()];
    let mut hits = 0;
    for y in 0..h {
        for x in 0..w {
            let d = lens.dir(x as f64 + 0.5, y as f64 + 0.5);
            let Some((t, _)) = m.trace(lens.pos, d, 0.0).hit else {
                continue;
            };
            hits += 1;
            for (n, &k) in crossed.iter_mut().zip(ks) {
                let dir = ray.then_some(d);
                *n += inside_at(&f, lens.pos, d, dir, m.eps, k).is_none_or(|b| b > t + 2.0 * m.eps)
                    as u32;
            }
        }
    }
    println!("{name}, steps along the ray: {ray}, hits {hits}, crossings for step factors {ks:?}: {crossed:?}");
    (hits, crossed)
}

#[test]
fn proved_steps_never_cross_the_blob_surface() {
    // The proved steps (balls and steps along the ray) never cross; doubled steps (every bound
    // halved) do. (Each cell's halved Lipschitz bound is also caught by sampling:
    // blob_local_bounds_hold_on_samples_and_intervals.)
    for ray in [false, true] {
        let (hits, crossed) = crossings("blob", (200, 150), ray, &[1.0, 2.0, 4.0, 8.0]);
        assert!(hits > 5000, "{hits}");
        assert_eq!(crossed[0], 0, "the proved steps cross the surface");
        assert!(
            crossed[1] > 100,
            "doubled steps went unnoticed: {crossed:?}"
        );
    }
}

#[test]
fn proved_steps_never_cross_the_bunny_surface() {
    // The MPU's proved bounds (local quadrics and partition-of-unity weights, rules 3 and 4 of
    // the step, balls and rays): never crossing, and with teeth, steps a quarter longer cross
    for ray in [false, true] {
        let (hits, crossed) = crossings("bunny", (160, 160), ray, &[1.0, 1.25, 2.0]);
        assert!(hits > 10000, "{hits}");
        assert_eq!(crossed[0], 0, "the proved steps cross the surface");
        assert!(crossed[1] > 0, "longer steps went unnoticed: {crossed:?}");
    }
}

/// Sphere tracing with steps of `k·step` (bounds divided by `k`; along `dir` or balls) to the
/// first inside point.
fn inside_at(f: &Field, o: DVec3, d: DVec3, dir: Option<DVec3>, eps: f64, k: f64) -> Option<f64> {
    let mut t = 0.0;
    for _ in 0..4096 {
        let v = f.step(o + d * t, dir);
        if v < 0.0 {
            return Some(t);
        }
        t += (k * v).max(eps);
        if t > 100.0 {
            return None;
        }
    }
    None
}
