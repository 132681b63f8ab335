//! The references of `rayproof check` and how they are loaded: `reference/thresholds.toml`
//! ([`ThresholdFile`], one [`Rule`] per scene × reference), each scene's `manifest.json`, and the
//! SHA-256 checks that refuse a tampered or stale reference. `--update` rewrites rayproof's own
//! golden render and its manifest entry here.

use crate::images::{self, Image, Thresholds};
use crate::shapes::sphere::methods::Method;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::Path;

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
        // Read the table and its gated configuration (`[check]`)
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
        // Merge the base table with the scene × reference entry, which wins
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
        // Take out rayproof's own keys; the rest are idiff's thresholds
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

/// The manifest of a scene's references.
pub(super) fn manifest(dir: &Path) -> Result<serde_json::Value> {
    let p = dir.join("manifest.json");
    let text =
        std::fs::read_to_string(&p).with_context(|| format!("cannot read {}", p.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: malformed JSON", p.display()))
}

/// Loads a reference and proves it is the one the manifest describes, made from this scene.
pub(super) fn verified_reference(
    dir: &Path,
    file: &str,
    m: &serde_json::Value,
    scene_sha: &str,
) -> Result<(Image, String)> {
    // Check the file's hash and its scene's hash against the manifest
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
    // Read it; name its renderer and version
    let img = images::read_image(&path)?;
    let who = format!(
        "{} {}",
        entry["renderer"].as_str().unwrap_or("?"),
        entry["version"].as_str().unwrap_or("")
    );
    Ok((img, who.trim().to_string()))
}

/// Writes rayproof.exr and its manifest entry (only `--update` calls this).
pub(super) fn update_golden(
    dir: &Path,
    scene_path: &Path,
    scene_sha: &str,
    img: &Image,
    cfg: Config,
    width: u32,
    grid: u32,
) -> Result<()> {
    // Write the image, then its manifest entry (with the new hash)
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
        "date": utc_now(),
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
