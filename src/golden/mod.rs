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

use crate::images::{self, Comparison, Image, Thresholds, Verdict};
use crate::render::{self, scene};
use crate::shapes::sphere::methods::Method;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The two external reference renderers, by file stem.
pub const EXTERNAL: [&str; 2] = ["povray", "mitsuba"];

/// A rendering configuration: method and precision.
#[derive(Clone, Copy, Debug)]
pub struct Config {
    pub method: &'static Method,
    pub precision: &'static str,
}

impl Config {
    pub fn label(&self) -> String {
        format!("{} {}", self.method.name, self.precision)
    }
}

/// Hex SHA-256 of a file.
pub fn sha256_file(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

/// The judgement of one scene × reference × configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Pass,
    Warning,
    Failure,
    /// Listed as a known failure and still failing.
    KnownFailure,
    /// Listed as a known failure but passing: the entry must go.
    UnexpectedPass,
    /// The reference could not be used: missing, unreadable, hash mismatch, stale, wrong size.
    Refused,
    /// No golden render yet (rayproof.exr); `--update` writes it.
    New,
}

impl Status {
    pub fn is_failure(self) -> bool {
        matches!(
            self,
            Status::Failure | Status::UnexpectedPass | Status::Refused | Status::New
        )
    }
    pub fn label(self) -> &'static str {
        match self {
            Status::Pass => "PASS",
            Status::Warning => "WARNING",
            Status::Failure => "FAILURE",
            Status::KnownFailure => "XFAIL",
            Status::UnexpectedPass => "XPASS",
            Status::Refused => "REFUSED",
            Status::New => "NEW",
        }
    }
}

/// Thresholds of one comparison: idiff's, plus rayproof's two keys.
#[derive(Clone, Debug, Serialize)]
pub struct Rule {
    pub idiff: Thresholds,
    /// Mean absolute error (over pixels × channels) above this fails.
    pub max_mean: f64,
    /// Why this comparison is expected to fail.
    pub known_failure: Option<String>,
}

/// `reference/thresholds.toml`.
pub struct ThresholdFile {
    table: toml::Table,
    /// The configuration the thresholds gate, and that `rayproof.exr` holds.
    pub gated: Config,
}

impl ThresholdFile {
    pub fn load(path: &Path) -> Result<ThresholdFile> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let table: toml::Table = toml::from_str(&text)
            .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.message()))?;
        let check = table.get("check").and_then(|v| v.as_table());
        let get = |k: &str, d: &str| {
            check
                .and_then(|c| c.get(k))
                .and_then(|v| v.as_str())
                .unwrap_or(d)
                .to_string()
        };
        let method = crate::shapes::sphere::methods::method_by_name(&get("method", "rtg7"))
            .with_context(|| format!("{}: check.method is not a known method", path.display()))?;
        let precision = match get("precision", "f64").as_str() {
            "f32" => "f32",
            "f64" => "f64",
            p => bail!(
                "{}: check.precision '{p}' is not f32 or f64",
                path.display()
            ),
        };
        let tf = ThresholdFile {
            table,
            gated: Config { method, precision },
        };
        // Every rule must parse
        let mut names = vec![];
        if let Some(sc) = tf.table.get("scenes").and_then(|v| v.as_table()) {
            for (scene, refs) in sc {
                for r in refs.as_table().into_iter().flat_map(|t| t.keys()) {
                    names.push((scene.clone(), r.clone()));
                }
            }
        }
        for (s, r) in names
            .iter()
            .map(|(s, r)| (s.as_str(), r.as_str()))
            .chain([("", "povray"), ("", "rayproof")])
        {
            tf.rule(s, r)
                .with_context(|| format!("{}", path.display()))?;
        }
        Ok(tf)
    }

    /// The rule for `scene` × `reference`: `[default]` (or `[golden]` for rayproof's own render),
    /// overridden by `[scenes.SCENE.REFERENCE]`.
    pub fn rule(&self, scene: &str, reference: &str) -> Result<Rule> {
        let base = if reference == "rayproof" {
            "golden"
        } else {
            "default"
        };
        let mut merged = toml::Table::new();
        let layers = [
            self.table.get(base),
            self.table
                .get("scenes")
                .and_then(|s| s.get(scene))
                .and_then(|s| s.get(reference)),
        ];
        for layer in layers.into_iter().flatten() {
            let t = layer
                .as_table()
                .context("a threshold entry is not a table")?;
            merged.extend(t.clone());
        }
        let take = |m: &mut toml::Table, k: &str| m.remove(k);
        let max_mean = match take(&mut merged, "max_mean") {
            Some(v) => v
                .as_float()
                .or(v.as_integer().map(|i| i as f64))
                .context("max_mean must be a number")?,
            None => f64::INFINITY,
        };
        let known_failure = match take(&mut merged, "known_failure") {
            Some(v) => Some(
                v.as_str()
                    .context("known_failure must be a string")?
                    .to_string(),
            ),
            None => None,
        };
        let idiff: Thresholds = merged.try_into().map_err(|e: toml::de::Error| {
            anyhow::anyhow!("[{scene}.{reference}]: {}", e.message())
        })?;
        idiff.validate().map_err(anyhow::Error::msg)?;
        Ok(Rule {
            idiff,
            max_mean,
            known_failure,
        })
    }
}

/// One row of the check: a scene × reference × configuration.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub scene: String,
    pub reference: String,
    pub renderer: String,
    pub config: String,
    pub status: Status,
    /// Why (refusals, known failures, mean over max_mean).
    pub note: String,
    pub comparison: Option<Comparison>,
    pub rule: Rule,
    pub render_seconds: f64,
    /// Report images, relative to the report directory.
    #[serde(skip)]
    pub images: Option<[String; 3]>,
}

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

/// The manifest of a scene's references.
fn manifest(dir: &Path) -> Result<serde_json::Value> {
    let p = dir.join("manifest.json");
    let text =
        std::fs::read_to_string(&p).with_context(|| format!("cannot read {}", p.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: malformed JSON", p.display()))
}

/// Loads a reference and proves it is the one the manifest describes, made from this scene.
fn verified_reference(
    dir: &Path,
    file: &str,
    m: &serde_json::Value,
    scene_sha: &str,
) -> Result<(Image, String)> {
    let entry = m["files"]
        .get(file)
        .with_context(|| format!("{file} has no entry in the manifest"))?;
    let path = dir.join(file);
    let sha = sha256_file(&path)?;
    let want = entry["sha256"].as_str().unwrap_or("");
    if sha != want {
        bail!(
            "{} has SHA-256 {sha}, the manifest says {want}: refusing a reference that was changed outside the scripts",
            path.display()
        );
    }
    if entry["scene_sha256"].as_str() != Some(scene_sha) {
        bail!(
            "{} was made from another version of the scene file: re-render it (scripts/render-references)",
            path.display()
        );
    }
    let img = images::read_image(&path)?;
    let who = format!(
        "{} {}",
        entry["renderer"].as_str().unwrap_or("?"),
        entry["version"].as_str().unwrap_or("")
    );
    Ok((img, who.trim().to_string()))
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
    if let Some(dir) = &o.report {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let mut rows = vec![];
    for name in &names {
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
        let mut configs = vec![th.gated];
        for c in &o.configs {
            if c.label() != th.gated.label() {
                configs.push(*c);
            }
        }
        for cfg in configs {
            let (img, secs) = render_image(&sc, cfg, width, grid);
            let gated = cfg.label() == th.gated.label();
            let refs: Vec<&str> = if gated {
                vec!["povray", "mitsuba", "rayproof"]
            } else {
                EXTERNAL.to_vec()
            };
            for r in refs {
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

/// Writes rayproof.exr and its manifest entry (only `--update` calls this).
fn update_golden(
    dir: &Path,
    scene_path: &Path,
    scene_sha: &str,
    img: &Image,
    cfg: Config,
    width: u32,
    grid: u32,
) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join("rayproof.exr");
    images::write_exr_rgb(&path, img)?;
    let mut m = manifest(dir).unwrap_or(serde_json::json!({ "files": {} }));
    if m.get("scene").is_none() {
        m["scene"] = serde_json::json!(scene_path.display().to_string());
    }
    m["files"]["rayproof.exr"] = serde_json::json!({
        "renderer": "rayproof",
        "version": env!("CARGO_PKG_VERSION"),
        "commands": [format!(
            "rayproof render {} --method {} --precision {} --width {width} --spp {} -o rayproof.exr (written by rayproof check --update)",
            scene_path.display(), cfg.method.name, cfg.precision, grid * grid
        )],
        "width": width,
        "grid": grid,
        "samples_per_pixel": grid * grid,
        "date": crate::golden::utc_now(),
        "scene_sha256": scene_sha,
        "sha256": sha256_file(&path)?,
    });
    let text = serde_json::to_string_pretty(&m)? + "\n";
    crate::output::write_atomic(&dir.join("manifest.json"), text.as_bytes())
}

/// The current UTC time as `YYYY-MM-DDTHH:MM:SSZ` (civil-from-days, no time crate).
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    let (days, rem) = (secs.div_euclid(86400), secs.rem_euclid(86400));
    // Howard Hinnant's days → civil date
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let mo = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + (mo <= 2) as i64;
    format!(
        "{y:04}-{mo:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
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

/// The text table: one line per row.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:<8} {:<9} {:<12} {:<8} {:>10} {:>10} {:>8} {:>9} {:>9} {:>8}  {}\n",
        "scene",
        "reference",
        "config",
        "status",
        "mean",
        "RMS",
        "PSNR",
        "max",
        ">fail %",
        "FLIP",
        "note"
    );
    for r in rows {
        let c = r.comparison.as_ref();
        let f = |x: Option<f64>, p: usize| x.map(|v| format!("{v:.p$e}")).unwrap_or("-".into());
        s += &format!(
            "{:<8} {:<9} {:<12} {:<8} {:>10} {:>10} {:>8} {:>9} {:>9} {:>8}  {}\n",
            r.scene,
            r.reference,
            r.config,
            r.status.label(),
            f(c.map(|c| c.mean_error), 2),
            f(c.map(|c| c.rms_error), 2),
            c.map(|c| format!("{:.1}", c.psnr)).unwrap_or("-".into()),
            f(c.map(|c| c.max_error), 2),
            c.map(|c| format!("{:.3}", 100.0 * c.n_fail as f64 / c.pixels as f64))
                .unwrap_or("-".into()),
            c.and_then(|c| c.flip_mean)
                .map(|v| format!("{v:.4}"))
                .unwrap_or("-".into()),
            r.note
        );
    }
    s
}

/// A Markdown table (for the README), from the same rows.
pub fn markdown(rows: &[Row]) -> String {
    let mut rows: Vec<&Row> = rows.iter().collect();
    rows.sort_by(|a, b| {
        (&a.scene, &a.reference, &a.config).cmp(&(&b.scene, &b.reference, &b.config))
    });
    let mut s = String::from(
        "| scene | reference | method / precision | status | MAE | RMS | PSNR dB | max error | pixels > fail | HDR-FLIP |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let Some(c) = &r.comparison else {
            s += &format!(
                "| {} | {} | {} | {} | | | | | | |\n",
                r.scene,
                r.reference,
                r.config,
                r.status.label()
            );
            continue;
        };
        s += &format!(
            "| {} | {} | {} | {} | {:.2e} | {:.2e} | {:.1} | {:.3} | {:.3} % | {} |\n",
            r.scene,
            r.reference,
            r.config,
            r.status.label(),
            c.mean_error,
            c.rms_error,
            c.psnr,
            c.max_error,
            100.0 * c.n_fail as f64 / c.pixels as f64,
            c.flip_mean.map(|v| format!("{v:.4}")).unwrap_or("-".into())
        );
    }
    s
}

/// The HTML report in the style of Blender's render report: one row per scene × reference,
/// failures first; hovering over the new render shows the reference and vice versa.
pub fn html(rows: &[Row], title: &str) -> String {
    let esc = |s: &str| {
        s.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;")
    };
    let mut body = String::new();
    for r in rows {
        let class = match r.status {
            s if s.is_failure() => "fail",
            Status::Warning => "warn",
            Status::KnownFailure => "xfail",
            _ => "pass",
        };
        let imgs = match &r.images {
            Some([new, reference, flip]) => format!(
                "<td><img src=\"{new}\" onmouseover=\"this.src='{reference}'\" onmouseout=\"this.src='{new}'\"></td>\
                 <td><img src=\"{reference}\" onmouseover=\"this.src='{new}'\" onmouseout=\"this.src='{reference}'\"></td>\
                 <td><img src=\"{flip}\"></td>"
            ),
            None => "<td></td><td></td><td></td>".into(),
        };
        let metrics = match &r.comparison {
            Some(c) => format!(
                "mean {:.3e}<br>RMS {:.3e}<br>PSNR {:.1} dB<br>max {:.4} @ ({}, {}, {})<br>{} px ({:.3} %) &gt; {}<br>{} px &gt; warn {}<br>HDR-ꟻLIP {}",
                c.mean_error,
                c.rms_error,
                c.psnr,
                c.max_error,
                c.max_at.0,
                c.max_at.1,
                c.max_channel,
                c.n_fail,
                100.0 * c.n_fail as f64 / c.pixels as f64,
                r.rule.idiff.fail,
                c.n_warn,
                r.rule.idiff.warn,
                c.flip_mean.map(|v| format!("{v:.4}")).unwrap_or("-".into())
            ),
            None => String::new(),
        };
        body += &format!(
            "<tr class=\"{class}\"><td><b>{}</b><br>vs {} ({})<br>{}<br><b>{}</b><br><small>{}</small></td>{imgs}<td class=\"m\">{metrics}</td></tr>\n",
            esc(&r.scene),
            esc(&r.reference),
            esc(&r.renderer),
            esc(&r.config),
            r.status.label(),
            esc(&r.note)
        );
    }
    let failed = rows.iter().filter(|r| r.status.is_failure()).count();
    format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{title}</title><style>\n\
         body {{ font-family: sans-serif; margin: 1em; }}\n\
         table {{ border-collapse: collapse; }}\n\
         td, th {{ border: 1px solid #ccc; padding: 4px; vertical-align: top; }}\n\
         img {{ width: 256px; image-rendering: pixelated; background: repeating-conic-gradient(#ddd 0 25%, #fff 0 50%) 0 0 / 16px 16px; }}\n\
         tr.fail {{ background: #f8d7da; }} tr.warn {{ background: #fff3cd; }} tr.xfail {{ background: #e2e3e5; }}\n\
         td.m {{ font-family: monospace; font-size: 90%; }}\n\
         </style></head><body>\n<h1>{title}</h1>\n<p>{} comparisons, {failed} failing. Hover over an image to swap new and reference. \
         Heat map: HDR-ꟻLIP error (magma).</p>\n<table>\n<tr><th>Name</th><th>New</th><th>Reference</th><th>Diff (ꟻLIP)</th><th>Metrics</th></tr>\n{body}</table>\n</body></html>\n",
        rows.len()
    )
}
