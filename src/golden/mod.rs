//! `rayproof check`: golden-image CI for any renderer. A suite file ([`suite`]) lists tests;
//! each test's image is read, made by the user's renderer command, or rendered by rayproof, and
//! compared with its references under idiff's thresholds plus rayproof's (`max_mean`,
//! `max_flip`, the z-test when a variance image is given). rayproof's own reference scenes are
//! one such suite, `reference/suite.toml`: their POV-Ray and Mitsuba renders are external
//! references, `NAME/rayproof.exr` the golden.
//!
//! - A reference with a `manifest.json` entry beside it must match its SHA-256 and, when the test
//!   names a scene, the scene's SHA-256 (else REFUSED: tampered or stale). Its width and
//!   sampling grid are the ones the test image is made with, unless the test says otherwise
//!   (then a warning).
//! - A missing required reference, a renderer command that fails, hangs past the suite's
//!   timeout or writes no readable image: REFUSED, one line in the row. A missing optional
//!   reference: SKIPPED.
//! - `--update` writes a golden (a copy of the test image, with a manifest entry: SHA-256, the
//!   command, the date) only where the golden comparison fails or the golden is missing, never
//!   an external reference, and nothing at all when any test of the run was refused.
//!
//! One file per job: `suite` (the suite file), `references` (rules, manifests, hashes, bless),
//! `rows` (the results and their tables), `html` and `junit` (the reports); this file runs it.

mod html;
mod junit;
mod references;
pub mod renderers;
mod rows;
pub mod suite;

pub use html::html;
pub use junit::junit;
pub use references::{sha256_file, utc_now, Config, Provenance, Rule};
pub use rows::{markdown, table, Row, Status};
pub use suite::{Source, Suite, Test};

use crate::images::{self, Comparison, Image, Verdict, ZParams};
use crate::render::{self, scene};
use anyhow::{bail, Context, Result};
use references::{bless, verified_reference, Blessing};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `check` was asked to do.
pub struct Options {
    pub report: Option<PathBuf>,
    pub update: bool,
    /// Extra configurations for the tests rayproof renders (compared with their external
    /// references only).
    pub configs: Vec<Config>,
    /// Only these tests (by name); empty: all.
    pub tests: Vec<String>,
    pub flip: bool,
}

/// The rows of a run and what `--update` did.
pub struct Outcome {
    /// Failures first.
    pub rows: Vec<Row>,
    /// Goldens written by `--update`.
    pub blessed: Vec<PathBuf>,
    /// `--update` was asked for but some test was refused, so nothing was written.
    pub update_withheld: bool,
}

impl Outcome {
    pub fn refused(&self) -> usize {
        self.rows
            .iter()
            .filter(|r| r.status == Status::Refused)
            .count()
    }
    pub fn failed(&self) -> usize {
        self.rows.iter().filter(|r| r.status.is_failure()).count()
    }
    /// 0 every comparison passes (warnings, known failures and skipped optional references
    /// included), 1 some comparison fails, 3 some test was refused.
    pub fn exit_code(&self) -> u8 {
        if self.refused() > 0 {
            3
        } else if self.failed() > 0 {
            1
        } else {
            0
        }
    }
}

/// The test image, however it was made.
struct Made {
    /// The file it was read from (copied by `--update`).
    file: PathBuf,
    image: Image,
    variance: Option<Image>,
    seconds: f64,
    /// How it was made, for a golden's manifest entry.
    command: String,
    renderer: String,
}

/// The width and sampling grid a test image is made with, and where they came from.
#[derive(Clone, Copy, Default)]
struct Frame {
    width: Option<u32>,
    grid: Option<u32>,
}

/// Makes the test image: reads it, runs the renderer command, or renders the scene.
fn make(suite: &Suite, t: &Test, frame: Frame, scratch: &Path) -> Result<Made, String> {
    let start = Instant::now();
    let out = scratch.join(format!("{}.exr", t.name));
    let var = scratch.join(format!("{}.variance.exr", t.name));
    let abs = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let (file, command, renderer) = match &t.source {
        suite::Source::Image(p) => {
            if !p.exists() {
                return Err(format!("no image at {}", p.display()));
            }
            (p.clone(), format!("(image {})", p.display()), String::new())
        }
        suite::Source::Rayproof(cfg) => {
            // Render in process at the frame's size and grid, written as the golden would be
            let scene_path = t.scene.as_ref().expect("validated: rayproof needs a scene");
            let sc = scene::load(scene_path).map_err(|e| format!("{e:#}"))?;
            let fr = render::export::Frame::of(&sc, frame.width, frame.grid)?;
            let ov = render::Overrides {
                method: Some(cfg.method),
                precision: Some(cfg.precision),
                grid: Some(fr.grid),
                size: Some((fr.width, fr.height)),
                force_all_effects: false,
                progress: false,
                ..Default::default()
            };
            let r = render::render(&sc, &ov);
            let img = Image::rgb(
                r.width,
                r.height,
                r.beauty.iter().flatten().copied().collect(),
            );
            images::write_exr_rgb(&out, &img).map_err(|e| format!("{e:#}"))?;
            let command = format!(
                "rayproof render {} --method {} --precision {} --width {} --spp {} -o OUT.exr",
                scene_path.display(),
                cfg.method.name,
                cfg.precision,
                fr.width,
                fr.grid * fr.grid
            );
            (
                out,
                command,
                format!("rayproof {}", env!("CARGO_PKG_VERSION")),
            )
        }
        suite::Source::Command(template) => {
            // Fill the placeholders; the ones the frame cannot give are an error
            let keys = suite::placeholders(template)?;
            let need = |k: &str, v: Option<u32>| -> Result<String, String> {
                v.map(|x| x.to_string()).ok_or_else(|| {
                    format!("the command uses {{{k}}} but neither the test nor a reference's manifest gives a {}", if k == "width" { "width" } else { "grid" })
                })
            };
            let mut values = vec![
                ("out", out.display().to_string()),
                ("variance", var.display().to_string()),
                ("name", t.name.clone()),
            ];
            if let Some(s) = &t.scene {
                values.push(("scene", abs(s).display().to_string()));
            }
            for k in keys {
                match k.as_str() {
                    "width" => values.push(("width", need("width", frame.width)?)),
                    "grid" => values.push(("grid", need("grid", frame.grid)?)),
                    "spp" => values.push(("spp", need("spp", frame.grid.map(|g| g * g))?)),
                    _ => {}
                }
            }
            let command = suite::fill(template, &values);
            crate::process::run_with_timeout(
                "renderer",
                &command,
                Some(&suite.dir),
                String::new(),
                suite.timeout,
            )?;
            if !out.exists() {
                return Err(format!(
                    "renderer exited 0 but wrote no image ('{command}')"
                ));
            }
            (out, command, String::new())
        }
    };
    // Read the image, and its variance if the test gives one
    let image = images::read_image(&file).map_err(|e| format!("the test image: {e}"))?;
    let variance = match &t.variance {
        None => None,
        Some(v) => {
            let p = match v.as_str() {
                "{variance}" => var.clone(),
                v => suite.dir.join(v.replace("{name}", &t.name)),
            };
            Some(images::read_image(&p).map_err(|e| format!("the variance image: {e}"))?)
        }
    };
    Ok(Made {
        file,
        image,
        variance,
        seconds: start.elapsed().as_secs_f64(),
        command,
        renderer,
    })
}

/// Judges one comparison under its rule; the z-test's verdict replaces idiff's when given.
fn judge(c: &Comparison, z: Option<&images::ZTest>, rule: &Rule) -> (Status, String) {
    let mut why = vec![];
    let verdict = z.map(|z| z.verdict).unwrap_or(c.verdict);
    if verdict == Verdict::Failure {
        why.push(match z {
            Some(z) => format!(
                "z-test: {} pixels fail at α = {:.2e}",
                z.failing_pixels, z.alpha
            ),
            None => format!(
                "{} px ({:.3} %) over fail {}",
                c.n_fail,
                100.0 * c.n_fail as f64 / c.pixels.max(1) as f64,
                rule.idiff.fail
            ),
        });
    }
    if c.mean_error > rule.max_mean {
        why.push(format!(
            "mean error {:.3e} > max_mean {:.0e}",
            c.mean_error, rule.max_mean
        ));
    }
    if let (Some(max), Some(f)) = (rule.max_flip, c.flip_mean) {
        if f > max {
            why.push(format!("mean ꟻLIP {f:.4} > max_flip {max}"));
        }
    }
    let failed = !why.is_empty();
    let note = why.join("; ");
    match (&rule.known_failure, failed) {
        (Some(k), true) => (Status::KnownFailure, k.clone()),
        (Some(k), false) => (
            Status::UnexpectedPass,
            format!("listed as a known failure ({k}) but passes: remove the entry"),
        ),
        (None, true) => (Status::Failure, note),
        (None, false) if verdict == Verdict::Warning => (Status::Warning, note),
        (None, false) => (Status::Pass, note),
    }
}

/// Pixels with a NaN or an infinity in some channel.
fn nonfinite_pixels(img: &Image) -> usize {
    img.data
        .chunks(img.channels.len().max(1))
        .filter(|p| p.iter().any(|v| !v.is_finite()))
        .count()
}

/// The warnings of one comparison: encodings, sampling grids, NaN/Inf.
fn warnings(
    reference: &Image,
    prov: &Provenance,
    made: &Made,
    frame_grid: Option<u32>,
) -> Vec<String> {
    let mut w = vec![];
    let enc = |d: bool| {
        if d {
            "sRGB-encoded (PNG)"
        } else {
            "scene-linear"
        }
    };
    if reference.display_referred != made.image.display_referred {
        w.push(format!(
            "the reference is {} and the test image {}: compared as stored, not converted",
            enc(reference.display_referred),
            enc(made.image.display_referred)
        ));
    }
    if let (Some(want), Some(have)) = (prov.grid, frame_grid) {
        if want != have {
            w.push(format!(
                "sampling grid: the reference was made with {want}×{want} per pixel, the test image with {have}×{have}"
            ));
        }
    }
    for (what, img) in [("reference", reference), ("test image", &made.image)] {
        let n = nonfinite_pixels(img);
        if n > 0 {
            w.push(format!("the {what} has {n} pixels with NaN or Inf"));
        }
    }
    w
}

/// A row with nothing compared yet.
fn row(t: &Test, reference: &str, status: Status, note: String) -> Row {
    Row {
        test: t.name.clone(),
        reference: reference.into(),
        renderer: String::new(),
        config: t.config(),
        status,
        note,
        warnings: vec![],
        comparison: None,
        ztest: None,
        rule: t
            .references
            .iter()
            .find(|r| r.name == reference)
            .map(|r| r.rule.clone())
            .or(t.golden.as_ref().map(|g| g.1.clone()))
            .unwrap_or_else(|| Rule::from_layers(&[]).expect("defaults parse")),
        render_seconds: 0.0,
        images: None,
    }
}

/// A test's rows, and its image when `--update` may bless it.
type TestRun = (Vec<Row>, Option<(Made, Frame)>);

/// One test: its references checked, its image made, every comparison judged. Also returns
/// the image (for `--update`) when the golden comparison failed or the golden is missing.
fn run_test(suite: &Suite, t: &Test, o: &Options, scratch: &Path) -> Result<TestRun> {
    let mut rows = vec![];
    // The scene's hash, for stale references
    let scene_sha = match &t.scene {
        Some(s) => match sha256_file(s) {
            Ok(h) => Some(h),
            Err(e) => {
                let why = format!("the scene: {e:#}");
                let mut all: Vec<Row> = t
                    .references
                    .iter()
                    .map(|r| row(t, &r.name, Status::Refused, why.clone()))
                    .collect();
                if t.golden.is_some() {
                    all.push(row(t, "golden", Status::Refused, why));
                }
                return Ok((all, None));
            }
        },
        None => None,
    };
    // Load every reference (the golden last); missing, tampered, stale, corrupt are refused
    let mut loaded = vec![];
    let golden = t.golden.as_ref().map(|(p, rule)| ("golden", p, true, rule));
    let refs = t
        .references
        .iter()
        .map(|r| (r.name.as_str(), &r.path, r.required, &r.rule));
    let mut golden_missing = false;
    for (name, path, required, rule) in refs.chain(golden) {
        if !path.exists() {
            if name == "golden" {
                golden_missing = true;
                rows.push(row(
                    t,
                    name,
                    Status::New,
                    format!("no golden at {}: run with --update", path.display()),
                ));
            } else if required {
                rows.push(row(
                    t,
                    name,
                    Status::Refused,
                    format!("required reference missing: {}", path.display()),
                ));
            } else {
                rows.push(row(
                    t,
                    name,
                    Status::Skipped,
                    format!("optional reference missing: {}", path.display()),
                ));
            }
            continue;
        }
        match verified_reference(path, scene_sha.as_deref()) {
            Ok((img, prov)) => loaded.push((name, rule, img, prov)),
            Err(e) => rows.push(row(t, name, Status::Refused, format!("{e:#}"))),
        }
    }
    if loaded.is_empty() && !golden_missing {
        return Ok((rows, None));
    }
    // The frame: the test's, else the references' manifests' (which must agree)
    let mut frame = Frame {
        width: t.width,
        grid: t.grid,
    };
    for (what, get) in [("width", 0), ("grid", 1)] {
        let said: Vec<(&str, u32)> = loaded
            .iter()
            .filter_map(|(n, _, _, p)| [p.width, p.grid][get].map(|v| (*n, v)))
            .collect();
        let slot = if get == 0 {
            &mut frame.width
        } else {
            &mut frame.grid
        };
        if slot.is_none() {
            if said.iter().any(|(_, v)| *v != said[0].1) {
                let list: Vec<String> = said.iter().map(|(n, v)| format!("{n} {v}")).collect();
                let why = format!("the references' manifests disagree on the {what} ({}): give {what} in the test", list.join(", "));
                rows.extend(
                    loaded
                        .iter()
                        .map(|(n, ..)| row(t, n, Status::Refused, why.clone())),
                );
                return Ok((rows, None));
            }
            *slot = said.first().map(|s| s.1);
        }
    }
    // Make the test image once
    let made = match make(suite, t, frame, scratch) {
        Ok(m) => m,
        Err(e) => {
            let why = format!("test image: {e}");
            rows.extend(
                loaded
                    .iter()
                    .map(|(n, ..)| row(t, n, Status::Refused, why.clone())),
            );
            if golden_missing {
                for r in rows.iter_mut().filter(|r| r.reference == "golden") {
                    (r.status, r.note) = (Status::Refused, why.clone());
                }
            }
            return Ok((rows, None));
        }
    };
    // Compare with each reference and judge
    let frame_grid = match &t.source {
        suite::Source::Rayproof(_) | suite::Source::Command(_) => frame.grid,
        suite::Source::Image(_) => t.grid,
    };
    let mut golden_failed = golden_missing;
    for (name, rule, reference, prov) in &loaded {
        let mut r = row(t, name, Status::Refused, String::new());
        (r.rule, r.renderer, r.render_seconds) =
            ((*rule).clone(), prov.renderer.clone(), made.seconds);
        r.warnings = warnings(reference, prov, &made, frame_grid);
        match images::compare(reference, &made.image, &rule.idiff) {
            Err(e) => {
                (r.status, r.note) = (Status::Failure, format!("{e}"));
            }
            Ok(mut c) => {
                // The z-test, when a variance is given
                let z = match &made.variance {
                    Some(v) => {
                        let p = ZParams {
                            spp: t.variance_spp,
                            significance: rule.significance,
                            pixel_success_rate: rule.pixel_success_rate,
                        };
                        match images::z_test(reference, &made.image, v, &p) {
                            Ok(z) => Some(z),
                            Err(e) => {
                                (r.status, r.note) =
                                    (Status::Refused, format!("the variance image: {e}"));
                                rows.push(r);
                                continue;
                            }
                        }
                    }
                    None => None,
                };
                // ꟻLIP, when a rule or the report needs it
                let map = if o.flip || o.report.is_some() || rule.max_flip.is_some() {
                    let (kind, mean, map) = images::flip_error(reference, &made.image);
                    (c.flip_mean, c.flip_kind) = (Some(mean), Some(kind));
                    Some(map)
                } else {
                    None
                };
                (r.status, r.note) = judge(&c, z.as_ref(), rule);
                if let (Some(dir), Some(map)) = (&o.report, map) {
                    r.images = Some(write_images(dir, &r, reference, &made.image, &map)?);
                }
                r.comparison = Some(c);
                r.ztest = z;
            }
        }
        if *name == "golden" && matches!(r.status, Status::Failure | Status::New) {
            golden_failed = true;
        }
        rows.push(r);
    }
    Ok((rows, golden_failed.then_some((made, frame))))
}

/// Runs a suite; `--update` writes goldens only after every test ran and none was refused.
pub fn run(suite: &Suite, o: &Options) -> Result<Outcome> {
    // Select the tests; every name asked for must exist
    for n in &o.tests {
        if !suite.tests.iter().any(|t| &t.name == n) {
            let known: Vec<&str> = suite.tests.iter().map(|t| t.name.as_str()).collect();
            bail!(
                "no test '{n}' in {} (known: {})",
                suite.path.display(),
                known.join(", ")
            );
        }
    }
    let mut tests: Vec<Test> = suite
        .tests
        .iter()
        .filter(|t| o.tests.is_empty() || o.tests.contains(&t.name))
        .cloned()
        .collect();
    // Extra configurations of the tests rayproof renders: external references only
    let extra: Vec<Test> = tests
        .iter()
        .filter_map(|t| match &t.source {
            Source::Rayproof(c) => Some((t, c.label())),
            _ => None,
        })
        .flat_map(|(t, label)| {
            o.configs
                .iter()
                .filter(move |c| c.label() != label)
                .map(move |c| Test {
                    source: Source::Rayproof(*c),
                    golden: None,
                    ..t.clone()
                })
        })
        .filter(|t| !t.references.is_empty())
        .collect();
    tests.extend(extra);
    if let Some(dir) = &o.report {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    // Run every test
    let scratch = crate::output::ScratchDir::new("check")?;
    let mut rows = vec![];
    let mut to_bless = vec![];
    for t in &tests {
        let (r, made) = run_test(suite, t, o, &scratch.0)?;
        rows.extend(r);
        if let (Some(m), Some((golden, _))) = (made, &t.golden) {
            to_bless.push((t, golden.clone(), m));
        }
    }
    // Bless: only when nothing was refused, only failing or missing goldens
    let refused = rows.iter().any(|r| r.status == Status::Refused);
    let mut blessed = vec![];
    if o.update && !refused {
        for (t, golden, (m, frame)) in to_bless {
            // Never bless an image with NaN or Inf
            let bad = nonfinite_pixels(&m.image);
            if bad > 0 {
                for r in rows.iter_mut().filter(|r| {
                    r.test == t.name && r.reference == "golden" && r.config == t.config()
                }) {
                    r.note =
                        format!("not blessed: the test image has {bad} pixels with NaN or Inf");
                    r.status = Status::Failure;
                }
                continue;
            }
            let b = Blessing {
                renderer: if m.renderer.is_empty() {
                    suite.name.clone()
                } else {
                    m.renderer.clone()
                },
                command: m.command.clone(),
                width: frame.width.or(Some(m.image.width as u32)),
                grid: frame.grid,
                scene: t.scene.as_deref(),
                scene_sha: t.scene.as_ref().and_then(|s| sha256_file(s).ok()),
            };
            bless(&golden, &m.file, &b)?;
            for r in rows
                .iter_mut()
                .filter(|r| r.test == t.name && r.reference == "golden" && r.config == t.config())
            {
                r.note = format!("{} → written: {}", r.status.label(), golden.display());
                r.status = Status::Updated;
            }
            blessed.push(golden);
        }
    }
    // Failures first (refusals first of all), then warnings, then by test
    rows.sort_by_key(|r| {
        (
            r.status != Status::Refused,
            !r.status.is_failure(),
            r.status != Status::Warning && r.warnings.is_empty(),
            r.test.clone(),
        )
    });
    Ok(Outcome {
        rows,
        blessed,
        update_withheld: o.update && refused,
    })
}

/// Tone-mapped PNGs of the new render, the reference and the ꟻLIP heat map.
fn write_images(
    dir: &Path,
    row: &Row,
    reference: &Image,
    img: &Image,
    map: &[f32],
) -> Result<[String; 3]> {
    let config = row.config.replace(' ', "-");
    let names = [
        format!("{}-new-{config}.png", row.test),
        format!("{}-{}.png", row.test, row.reference),
        format!("{}-{}-{config}-flip.png", row.test, row.reference),
    ];
    let (w, h) = (img.width, img.height);
    images::write_png_rgb8(&dir.join(&names[0]), w, h, &images::tonemap_rgb8(img))?;
    images::write_png_rgb8(&dir.join(&names[1]), w, h, &images::tonemap_rgb8(reference))?;
    images::write_png_rgb8(&dir.join(&names[2]), w, h, &images::heatmap_rgb8(map, w, h))?;
    Ok(names)
}
