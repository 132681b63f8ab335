//! `rayproof check`: golden-image CI. Every scene of `reference/scenes/` is rendered by rayproof
//! and compared with the references committed beside it:
//!
//! - `reference/NAME/povray.exr` and `mitsuba.exr`, made by the real POV-Ray 3.7 and Mitsuba 3
//!   (`scripts/render-references`), never rewritten by `check`;
//! - `reference/NAME/rayproof.exr`, rayproof's own golden render of the gated configuration,
//!   rewritten by `--update` when it fails or is new (Blender's `BLENDER_TEST_UPDATE` rule).
//!
//! `reference/NAME/manifest.json` says how each file was made and holds its SHA-256 and the
//! SHA-256 of the scene file it was made from. A reference whose hash does not match is refused
//! (tampered), and one made from another version of the scene is refused (stale).
//! `reference/thresholds.toml` holds the idiff thresholds per scene × reference, plus `max_mean`
//! and `known_failure` (expected to fail, with the reason; passing then is an error).
//!
//! One file per job: `references` (thresholds, manifests, hashes, `--update`), `rows` (the
//! results and their text and Markdown tables) and `html` (the report); this file runs the check.

mod html;
mod references;
mod rows;

pub use html::html;
pub use references::{sha256_file, utc_now, Config, Rule, ThresholdFile};
pub use rows::{markdown, table, Row, Status};

use crate::images::{self, Comparison, Image, Verdict};
use crate::render::{self, scene};
use anyhow::{bail, Context, Result};
use references::{manifest, update_golden, verified_reference};
use std::path::{Path, PathBuf};

/// The two external reference renderers, by file stem.
pub const EXTERNAL: [&str; 2] = ["povray", "mitsuba"];

/// What `check` was asked to do.
pub struct Options {
    pub reference: PathBuf,
    pub report: Option<PathBuf>,
    pub update: bool,
    /// Extra configurations besides the gated one (compared with POV-Ray and Mitsuba only).
    pub configs: Vec<Config>,
    pub scenes: Vec<String>,
    pub flip: bool,
}

/// Renders one scene with one configuration at the references' size and grid.
fn render_image(sc: &scene::Scene, cfg: Config, width: u32, grid: u32) -> (Image, f64) {
    let fr = crate::render::export::Frame::of(sc, Some(width), Some(grid));
    let ov = render::Overrides {
        method: Some(cfg.method),
        precision: Some(cfg.precision),
        grid: Some(fr.grid),
        size: Some((fr.width, fr.height)),
        force_all_effects: false,
        progress: false,
        ..Default::default()
    };
    let r = render::render(sc, &ov);
    let data = r.beauty.iter().flatten().copied().collect();
    (Image::rgb(r.width, r.height, data), r.seconds)
}

/// Judges one comparison under its rule.
fn judge(c: &Comparison, rule: &Rule) -> (Status, String) {
    let mut note = String::new();
    let mut failed = c.verdict == Verdict::Failure;
    if c.mean_error > rule.max_mean {
        failed = true;
        note = format!(
            "mean error {:.3e} > max_mean {:.0e}",
            c.mean_error, rule.max_mean
        );
    }
    match (&rule.known_failure, failed) {
        (Some(why), true) => (Status::KnownFailure, why.clone()),
        (Some(why), false) => (
            Status::UnexpectedPass,
            format!("listed as a known failure ({why}) but passes: remove the entry"),
        ),
        (None, true) => (Status::Failure, note),
        (None, false) if c.verdict == Verdict::Warning => (Status::Warning, note),
        (None, false) => (Status::Pass, note),
    }
}

/// Runs the check; returns the rows, failures first.
pub fn run(o: &Options, th: &ThresholdFile) -> Result<Vec<Row>> {
    // List the scenes; every one asked for must exist
    let scenes_dir = o.reference.join("scenes");
    let mut names: Vec<String> = std::fs::read_dir(&scenes_dir)
        .with_context(|| format!("cannot read {}", scenes_dir.display()))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let p = e.path();
            let stem = p.file_stem()?.to_string_lossy().into_owned();
            (p.extension()? == "toml").then_some(stem)
        })
        .collect();
    names.sort();
    for s in &o.scenes {
        if !names.contains(s) {
            bail!(
                "no scene '{s}' in {} (known: {})",
                scenes_dir.display(),
                names.join(", ")
            );
        }
    }
    if !o.scenes.is_empty() {
        names.retain(|n| o.scenes.contains(n));
    }
    // Render every scene and compare it with each of its references
    if let Some(dir) = &o.report {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let mut rows = vec![];
    for name in &names {
        // Load the scene, its hash and its references' manifest
        let scene_path = scenes_dir.join(format!("{name}.toml"));
        let sc = scene::load(&scene_path)?;
        let scene_sha = sha256_file(&scene_path)?;
        let dir = o.reference.join(name);
        let m = manifest(&dir).unwrap_or(serde_json::json!({ "files": {} }));
        // The references' frame: every entry must agree on width and grid
        let (mut width, mut grid) = (None, None);
        for (_, e) in m["files"].as_object().into_iter().flatten() {
            let (w, g) = (e["width"].as_u64(), e["grid"].as_u64());
            if (width.is_some() && width != w) || (grid.is_some() && grid != g) {
                bail!(
                    "{}: entries disagree on width or grid",
                    dir.join("manifest.json").display()
                );
            }
            (width, grid) = (w, g);
        }
        let (width, grid) = (width.unwrap_or(256) as u32, grid.unwrap_or(8) as u32);
        // The gated configuration, then the extra ones (external references only)
        let mut configs = vec![th.gated];
        for c in &o.configs {
            if c.label() != th.gated.label() {
                configs.push(*c);
            }
        }
        for cfg in configs {
            // Render once per configuration; the gated one meets all three references
            let (img, secs) = render_image(&sc, cfg, width, grid);
            let gated = cfg.label() == th.gated.label();
            let refs: Vec<&str> = if gated {
                vec!["povray", "mitsuba", "rayproof"]
            } else {
                EXTERNAL.to_vec()
            };
            for r in refs {
                // Verify the reference, compare, judge
                let rule = th.rule(name, r)?;
                let mut row = Row {
                    scene: name.clone(),
                    reference: r.to_string(),
                    renderer: String::new(),
                    config: cfg.label(),
                    status: Status::Refused,
                    note: String::new(),
                    comparison: None,
                    rule,
                    render_seconds: secs,
                    images: None,
                };
                match verified_reference(&dir, &format!("{r}.exr"), &m, &scene_sha) {
                    Err(e) if r == "rayproof" && !dir.join("rayproof.exr").exists() => {
                        let _ = e;
                        row.status = Status::New;
                        row.note = "no golden render yet: run `rayproof check --update`".into();
                    }
                    Err(e) => row.note = format!("{e:#}"),
                    Ok((reference, who)) => {
                        row.renderer = who;
                        match images::compare(&reference, &img, &row.rule.idiff) {
                            Err(e) => row.note = format!("{e}"),
                            Ok(mut c) => {
                                // ꟻLIP and the report images
                                let map = if o.flip || o.report.is_some() {
                                    let (kind, mean, map) = images::flip_error(&reference, &img);
                                    c.flip_mean = Some(mean);
                                    c.flip_kind = Some(kind);
                                    Some(map)
                                } else {
                                    None
                                };
                                (row.status, row.note) = judge(&c, &row.rule);
                                if let (Some(dir), Some(map)) = (&o.report, map) {
                                    row.images =
                                        Some(write_images(dir, &row, &reference, &img, &map)?);
                                }
                                row.comparison = Some(c);
                            }
                        }
                    }
                }
                // Rayproof's own golden: rewrite it when failing or new, if asked
                if r == "rayproof" && o.update && row.status.is_failure() {
                    update_golden(&dir, &scene_path, &scene_sha, &img, cfg, width, grid)?;
                    row.note = format!("updated ({})", row.status.label());
                    row.status = Status::Pass;
                }
                rows.push(row);
            }
        }
    }
    // Failures first, then by scene
    rows.sort_by_key(|r| {
        (
            !r.status.is_failure(),
            r.status != Status::Warning,
            r.scene.clone(),
        )
    });
    Ok(rows)
}

/// Tone-mapped PNGs of the new render, the reference and the ꟻLIP heat map.
fn write_images(
    dir: &Path,
    row: &Row,
    reference: &Image,
    img: &Image,
    map: &[f32],
) -> Result<[String; 3]> {
    let stem = format!(
        "{}-{}-{}",
        row.scene,
        row.reference,
        row.config.replace(' ', "-")
    );
    let names = [
        format!("{}-new-{}.png", row.scene, row.config.replace(' ', "-")),
        format!("{}-{}.png", row.scene, row.reference),
        format!("{stem}-flip.png"),
    ];
    let (w, h) = (img.width, img.height);
    images::write_png_rgb8(&dir.join(&names[0]), w, h, &images::tonemap_rgb8(img))?;
    images::write_png_rgb8(&dir.join(&names[1]), w, h, &images::tonemap_rgb8(reference))?;
    images::write_png_rgb8(&dir.join(&names[2]), w, h, &images::heatmap_rgb8(map, w, h))?;
    Ok(names)
}
