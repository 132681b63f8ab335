//! `rayproof implicit-check SCENE`: renders an implicit scene by per-pixel sphere tracing and by
//! image-space subdivision (the paper's and the certified), with shadows off and on as in the
//! paper's Table 1, and compares every pixel with the per-pixel render.
//!
//! A pixel is **lost** when per-pixel tracing hits a surface there and the subdivision does
//! not, a **ghost** in the opposite case, and **moved** when both hit but the distances differ
//! by more than the tracer's `eps`. Lost pixels are attributed: `skipped` (its block was
//! skipped as background), `past-surface` (its trace started beyond the per-pixel hit: the
//! paper's undetected case ③), or `other`; and placed: `silhouette` (a 4-neighbour is
//! background in the per-pixel render) or `interior` (a thin feature or a small object inside).

use crate::implicit::march::{Marcher, Tracer};
use crate::render::scene::Scene;
use crate::render::subdiv::{self, Mode, Primary, Stats};
use crate::render::{Lens, RayCounts};
use anyhow::{bail, Result};
use glam::DVec3;
use serde::Serialize;
use std::time::Instant;

/// One lost, ghost or moved pixel.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PixelDiff {
    /// Column.
    pub x: usize,
    /// Row (0 at the top).
    pub y: usize,
    /// lost, ghost or moved
    pub kind: &'static str,
    /// For lost pixels: skipped, past-surface or other
    pub cause: &'static str,
    /// silhouette or interior (per the per-pixel render)
    pub place: &'static str,
    /// Per-pixel distance and this mode's (`null` for a miss)
    pub full_t: Option<f64>,
    /// This mode's distance (`null` for a miss).
    pub mode_t: Option<f64>,
    /// Start length of this mode's final trace for the pixel (0: from the eye).
    pub start: Option<f64>,
}

/// A mode's pixels against the per-pixel render.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Comparison {
    /// Pixels where the per-pixel render hits a surface.
    pub surface_pixels: u64,
    /// Pixels the per-pixel render hits and this mode misses.
    pub lost: u64,
    /// Lost pixels on a silhouette (a 4-neighbour is background in the per-pixel render).
    pub lost_silhouette: u64,
    /// Lost pixels inside a surface's image (a thin feature or a small object).
    pub lost_interior: u64,
    /// Pixels this mode hits and the per-pixel render misses.
    pub ghost: u64,
    /// Pixels both hit at distances that differ by more than the tracer's `eps`.
    pub moved: u64,
    /// Pixels whose colour differs by more than 1e-6 (relative to max(1, value)).
    pub colour_differs: u64,
    /// Largest colour difference, relative to max(1, value).
    pub max_colour_diff: f64,
    /// Every lost, ghost and moved pixel, row-major.
    pub pixels: Vec<PixelDiff>,
}

/// One render: a mode with shadows off or on.
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// How primary visibility was found.
    pub mode: Mode,
    /// How the primary rays' steps were bounded (shadow rays: always the renderer's own,
    /// local bounds).
    pub tracer: Tracer,
    /// `mode` or `mode/tracer` for the tracers other than the baseline's.
    pub name: String,
    /// Whether shadow rays were traced.
    pub shadows: bool,
    /// Counters of the primary pass.
    pub primary: Stats,
    /// Shadow rays and their tests.
    pub secondary: RayCounts,
    /// Primary visibility, shading, and their sum (wall clock, all threads).
    pub primary_seconds: f64,
    /// Shading seconds (wall clock, all threads).
    pub shade_seconds: f64,
    /// Primary plus shading seconds.
    pub seconds: f64,
    /// Rays of every kind: primary traces plus shadow rays.
    pub rays: u64,
    /// Field evaluations: primary traces, cones, shadow rays.
    pub steps: u64,
    /// Against the per-pixel render with the same shadows and tracer (a per-pixel render:
    /// against the baseline's; `None` for the baseline).
    pub versus_full: Option<Comparison>,
    /// The baseline's time (per-pixel, `global` tracer) over this one's.
    pub speedup: f64,
}

/// The whole check.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The scene file.
    pub scene: String,
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Block size of the image-space subdivision, in pixels.
    pub region: usize,
    /// The tracer's `eps`: the step at which it probes for a proven hit.
    pub eps: f64,
    /// Each implicit shape's global Lipschitz bound (the `global` and `paper` tracers'), by name.
    pub lipschitz: Vec<(String, f64)>,
    /// Each implicit shape's proved global bound: the largest of its local bounds.
    pub lipschitz_proved: Vec<(String, f64)>,
    /// Every render: each mode with shadows off and on.
    pub runs: Vec<Run>,
}

/// Options of the check.
#[derive(Clone, Debug)]
pub struct Options {
    /// Block size of the image-space subdivision, in pixels.
    pub region: usize,
    /// Image width (height keeps the camera's aspect); `None`: the camera's.
    pub width: Option<u32>,
    /// Repeats of each render, in turns (every configuration once per round); the fastest time
    /// is kept.
    pub repeat: u32,
}

/// The image size for the scene and a width override.
pub fn size(s: &Scene, width: Option<u32>) -> (usize, usize) {
    let (cw, ch) = (
        *s.file.camera.width.get_ref() as usize,
        *s.file.camera.height.get_ref() as usize,
    );
    match width {
        Some(w) => (
            w as usize,
            ((w as usize * ch) as f64 / cw as f64).round().max(1.0) as usize,
        ),
        None => (cw, ch),
    }
}

/// The scene's implicit fields as one marcher, and each field's material index.
pub fn marcher(s: &Scene) -> Result<(Marcher, Vec<usize>)> {
    let names: Vec<&String> = s.file.materials.keys().collect();
    let mut fields = vec![];
    let mut mats = vec![];
    for (i, sh) in s.file.shapes.iter().enumerate() {
        let Some(f) = s.implicits.get(&i) else {
            bail!(
                "{}: shapes[{i}] is not implicit; implicit-check needs a scene of implicit shapes only (sdf, blob, mpu), where a pixel without a surface is background",
                s.path.display()
            );
        };
        fields.push(f.clone());
        mats.push(names.iter().position(|k| *k == sh.material()).unwrap_or(0));
    }
    if fields.is_empty() {
        bail!("{}: the scene has no shapes", s.path.display());
    }
    Ok((Marcher::new(fields), mats))
}

/// The renders of a check, in order: the baseline (per-pixel, global bounds, the judge) first;
/// then the paper's subdivision and the certified one on the same tracer; per-pixel and
/// certified with local bounds; and the paper's own renderer (no box clipping, global bound)
/// per pixel and with its subdivision.
pub const RUNS: [(Mode, Tracer); 7] = [
    (Mode::Full, Tracer::Global),
    (Mode::Paper, Tracer::Global),
    (Mode::Certified, Tracer::Global),
    (Mode::Full, Tracer::Local),
    (Mode::Certified, Tracer::Local),
    (Mode::Full, Tracer::Paper),
    (Mode::Paper, Tracer::Paper),
];

/// One configuration's render: the primary pass, the shaded image, the secondary rays and the
/// shading time.
type Rendered = (Primary, Vec<[f32; 3]>, RayCounts, f64);

impl Report {
    /// The verdict `implicit-check` exits with: whether the certified mode lost or added a
    /// pixel against per-pixel tracing (shadows off or on).
    pub fn certified_differs(&self) -> bool {
        self.runs
            .iter()
            .filter(|x| x.mode == Mode::Certified)
            .filter_map(|x| x.versus_full.as_ref())
            .any(|c| c.lost + c.ghost > 0)
    }
}

/// Runs the check.
pub fn run(s: &Scene, opts: &Options) -> Result<Report> {
    let (local, mats) = marcher(s)?;
    let (w, h) = size(s, opts.width);
    let lens = Lens::new(s, w, h);
    let mut runs = vec![];
    let by = |t: Tracer| Marcher::with(local.fields.clone(), t);
    let marchers = [by(Tracer::Global), local.clone(), by(Tracer::Paper)];
    let m = &marchers[0];
    for shadows in [false, true] {
        let marcher = |tracer: Tracer| {
            &marchers[match tracer {
                Tracer::Global => 0,
                Tracer::Local => 1,
                Tracer::Paper => 2,
            }]
        };
        // Fastest of the repeats, taken in turns (every configuration once per round), so that
        // a shared machine's load changes reach every configuration alike
        let mut bests: Vec<Option<Rendered>> = RUNS.iter().map(|_| None).collect();
        for _ in 0..opts.repeat.max(1) {
            for ((mode, tracer), best) in RUNS.into_iter().zip(bests.iter_mut()) {
                let m = marcher(tracer);
                let p = subdiv::primary(m, &lens, (w, h), mode, opts.region);
                let t0 = Instant::now();
                let hits: Vec<Option<(f64, DVec3, usize)>> = p
                    .pixels
                    .iter()
                    .enumerate()
                    .map(|(k, px)| {
                        px.hit.map(|(t, i)| {
                            let d = lens.dir((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
                            (t, m.normal(i, lens.pos + d * t), mats[i])
                        })
                    })
                    .collect();
                let (beauty, counts) =
                    crate::render::shade_primary(s, &lens, (w, h), &hits, shadows);
                let shade = t0.elapsed().as_secs_f64();
                if best
                    .as_ref()
                    .is_none_or(|b| p.seconds + shade < b.0.seconds + b.3)
                {
                    *best = Some((p, beauty, counts, shade));
                }
            }
        }
        // Each tracer's per-pixel render (the first is the baseline's)
        let mut fulls: Vec<(Tracer, Primary, Vec<[f32; 3]>, f64)> = vec![];
        for ((mode, tracer), best) in RUNS.into_iter().zip(bests) {
            let m = marcher(tracer);
            // A subdivision is judged against per-pixel tracing with its own tracer, and a
            // per-pixel render against the baseline's
            let full = if mode == Mode::Full {
                fulls.first()
            } else {
                fulls.iter().find(|f| f.0 == tracer)
            }
            .map(|f| (&f.1, &f.2, f.3));
            let (p, beauty, counts, shade) = best.expect("at least one repeat");
            let seconds = p.seconds + shade;
            let versus_full = full.map(|(fp, fb, _)| compare(m, fp, fb, &p, &beauty, w, h));
            let speedup = fulls.first().map_or(1.0, |f| f.3 / seconds);
            runs.push(Run {
                mode,
                tracer,
                name: if tracer == Tracer::Global {
                    mode.name().to_string()
                } else {
                    format!("{}/{}", mode.name(), tracer.name())
                },
                shadows,
                primary: p.stats,
                secondary: counts,
                primary_seconds: p.seconds,
                shade_seconds: shade,
                seconds,
                rays: p.stats.rays + counts.shadow,
                steps: p.stats.steps + p.stats.cone_steps + counts.tests.march_steps,
                versus_full,
                speedup,
            });
            if mode == Mode::Full {
                fulls.push((tracer, p, beauty, seconds));
            }
        }
    }
    // A check that compares nothing is refused, not passed: a camera that sees only background
    // would give "0 lost, 0 ghost" whatever the tracer does
    let compared = runs
        .iter()
        .filter_map(|x| x.versus_full.as_ref())
        .any(|c| c.surface_pixels > 0);
    if !compared {
        bail!(
            "{}: no pixel of the {w}×{h} image shows a surface (the camera sees only background): implicit-check would compare nothing",
            s.path.display()
        );
    }
    Ok(Report {
        scene: s.path.display().to_string(),
        width: w,
        height: h,
        region: opts.region,
        eps: m.eps,
        lipschitz: m
            .fields
            .iter()
            .map(|f| (f.kind().to_string(), f.lipschitz()))
            .collect(),
        lipschitz_proved: m
            .fields
            .iter()
            .map(|f| {
                let l = f.local_bounds().map_or(f.lipschitz(), |b| b.global().0);
                (f.kind().to_string(), l)
            })
            .collect(),
        runs,
    })
}

/// Pixel-by-pixel comparison of a mode with the per-pixel render.
fn compare(
    m: &Marcher,
    full: &Primary,
    full_rgb: &[[f32; 3]],
    mode: &Primary,
    rgb: &[[f32; 3]],
    w: usize,
    h: usize,
) -> Comparison {
    let mut c = Comparison::default();
    let background = |x: i64, y: i64| {
        x >= 0
            && y >= 0
            && (x as usize) < w
            && (y as usize) < h
            && full.pixels[y as usize * w + x as usize].hit.is_none()
    };
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            let (a, b) = (full.pixels[k], mode.pixels[k]);
            c.surface_pixels += a.hit.is_some() as u64;
            let place = if [(-1, 0), (1, 0), (0, -1), (0, 1)]
                .iter()
                .any(|(dx, dy)| background(x as i64 + dx, y as i64 + dy))
            {
                "silhouette"
            } else {
                "interior"
            };
            let (kind, cause) = match (a.hit, b.hit) {
                (Some((ta, _)), None) => {
                    c.lost += 1;
                    if place == "silhouette" {
                        c.lost_silhouette += 1;
                    } else {
                        c.lost_interior += 1;
                    }
                    let cause = if b.skipped {
                        "skipped"
                    } else if b.start > ta + m.eps {
                        "past-surface"
                    } else {
                        "other"
                    };
                    ("lost", cause)
                }
                (None, Some(_)) => {
                    c.ghost += 1;
                    ("ghost", "")
                }
                (Some((ta, _)), Some((tb, _))) if (ta - tb).abs() > m.eps => {
                    c.moved += 1;
                    (
                        "moved",
                        if b.start > ta + m.eps {
                            "past-surface"
                        } else {
                            ""
                        },
                    )
                }
                _ => ("", ""),
            };
            let diff = (0..3)
                .map(|i| {
                    (full_rgb[k][i] - rgb[k][i]).abs() as f64
                        / (full_rgb[k][i].abs() as f64).max(1.0)
                })
                .fold(0.0, f64::max);
            c.max_colour_diff = c.max_colour_diff.max(diff);
            c.colour_differs += (diff > 1e-6) as u64;
            if !kind.is_empty() {
                c.pixels.push(PixelDiff {
                    x,
                    y,
                    kind,
                    cause,
                    place,
                    full_t: a.hit.map(|h| h.0),
                    mode_t: b.hit.map(|h| h.0),
                    start: b.start.is_finite().then_some(b.start),
                });
            }
        }
    }
    c
}

/// The report as a text table (one row per render) and the losses.
pub fn table(r: &Report) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "implicit-check {} — {}×{}, regions {}×{}, eps {:.3e}, global Lipschitz {} (proved: {})",
        r.scene,
        r.width,
        r.height,
        r.region,
        r.region,
        r.eps,
        r.lipschitz
            .iter()
            .map(|(k, l)| format!("{k} {l:.4}"))
            .collect::<Vec<_>>()
            .join(", "),
        r.lipschitz_proved
            .iter()
            .map(|(k, l)| format!("{k} {l:.4}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        o,
        "{:<20} {:<7} {:>9} {:>11} {:>9} {:>10} {:>9} {:>8} {:>6} {:>6} {:>6} {:>8} {:>8}",
        "mode",
        "shadows",
        "rays",
        "steps",
        "skipped",
        "primary s",
        "total s",
        "speedup",
        "lost",
        "ghost",
        "moved",
        "surface",
        "colour≠"
    );
    for run in &r.runs {
        let c = run.versus_full.clone().unwrap_or_default();
        let _ = writeln!(
            o,
            "{:<20} {:<7} {:>9} {:>11} {:>9} {:>10.4} {:>9.4} {:>7.2}× {:>6} {:>6} {:>6} {:>8} {:>8}",
            run.name,
            if run.shadows { "on" } else { "off" },
            run.rays,
            run.steps,
            run.primary.regions_skipped,
            run.primary_seconds,
            run.seconds,
            run.speedup,
            c.lost,
            c.ghost,
            c.moved,
            if run.versus_full.is_none() { String::new() } else { c.surface_pixels.to_string() },
            c.colour_differs
        );
    }
    for run in r
        .runs
        .iter()
        .filter(|x| x.versus_full.as_ref().is_some_and(|c| c.lost > 0))
    {
        let c = run.versus_full.as_ref().expect("filtered");
        let mut causes = std::collections::BTreeMap::new();
        for p in c.pixels.iter().filter(|p| p.kind == "lost") {
            *causes.entry((p.cause, p.place)).or_insert(0u64) += 1;
        }
        let first: Vec<String> = c
            .pixels
            .iter()
            .filter(|p| p.kind == "lost")
            .take(8)
            .map(|p| format!("({}, {})", p.x, p.y))
            .collect();
        let _ = writeln!(
            o,
            "{} (shadows {}): {} of {} surface pixels lost ({}); first at {}",
            run.name,
            if run.shadows { "on" } else { "off" },
            c.lost,
            c.surface_pixels,
            causes
                .iter()
                .map(|((cause, place), n)| format!("{n} {cause}/{place}"))
                .collect::<Vec<_>>()
                .join(", "),
            first.join(" ")
        );
    }
    o
}
