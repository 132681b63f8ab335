//! The references of `rayproof check` and how they are judged and kept: the [`Rule`] of one
//! comparison (from the suite file's layered tables), the `manifest.json` beside a reference
//! and the SHA-256 checks that refuse a tampered or stale one, and [`bless`], which writes a
//! golden and its manifest entry for `--update`.

use crate::images::{Image, Thresholds};
use crate::render::scene::{MAX_GRID, MAX_SIDE};
use crate::shapes::sphere::methods::Method;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// A rendering configuration: method and precision.
#[derive(Clone, Copy, Debug)]
pub struct Config {
    /// The ray–sphere method.
    pub method: &'static Method,
    /// `"f32"` or `"f64"`.
    pub precision: &'static str,
}

impl Config {
    /// `METHOD PRECISION`, as rows show it.
    pub fn label(&self) -> String {
        format!("{} {}", self.method.name, self.precision)
    }
}

/// Hex SHA-256 of a file (a reference, a golden or a scene): a regular file of at most the
/// largest image file ([`crate::images::MAX_IMAGE_BYTES`]; a test's scene of `/dev/zero` was read until
/// memory ran out).
pub fn sha256_file(path: &Path) -> Result<String> {
    let bytes = crate::input::read_capped(
        path,
        crate::images::MAX_IMAGE_BYTES,
        crate::input::Kind::Regular,
    )
    .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
    Ok(sha256_bytes(&bytes))
}

/// Hex SHA-256 of bytes.
pub fn sha256_bytes(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Thresholds of one comparison: idiff's, plus rayproof's keys.
#[derive(Clone, Debug, Serialize)]
pub struct Rule {
    /// idiff's thresholds (fail, warn, percentages, hard limits, allowed failures).
    pub idiff: Thresholds,
    /// Mean absolute error (over pixels × channels) above this fails.
    pub max_mean: f64,
    /// Mean ꟻLIP (LDR when both images are PNG, else HDR) above this fails (computed only when
    /// given, or for the report).
    pub max_flip: Option<f64>,
    /// The z-test's settings, used when the test gives a variance image.
    pub significance: f64,
    /// The z-test passes when at least this share of channel tests pass.
    pub pixel_success_rate: f64,
    /// The z-test's mean-shift test fails at this family-wise significance.
    pub shift_significance: f64,
    /// Why this comparison is expected to fail.
    pub known_failure: Option<String>,
}

impl Rule {
    /// The rule of layered tables (later layers win): rayproof's keys `max_mean`, `max_flip`,
    /// `significance`, `pixel_success_rate`, `known_failure`; every other key is idiff's.
    pub fn from_layers(layers: &[&toml::Table]) -> Result<Rule> {
        let mut merged = toml::Table::new();
        for t in layers {
            merged.extend((*t).clone());
        }
        // Take out rayproof's own keys; the rest are idiff's thresholds
        let mut number = |k: &str| -> Result<Option<f64>> {
            match merged.remove(k) {
                Some(v) => {
                    let x = v
                        .as_float()
                        .or(v.as_integer().map(|i| i as f64))
                        .with_context(|| format!("{k} must be a number"))?;
                    if x.is_nan() || x < 0.0 {
                        bail!("{k} = {x} is not a non-negative number");
                    }
                    Ok(Some(x))
                }
                None => Ok(None),
            }
        };
        let max_mean = number("max_mean")?.unwrap_or(f64::INFINITY);
        let max_flip = number("max_flip")?;
        let z = crate::images::ZParams::default();
        let significance = number("significance")?.unwrap_or(z.significance);
        let pixel_success_rate = number("pixel_success_rate")?.unwrap_or(z.pixel_success_rate);
        let shift_significance = number("shift_significance")?.unwrap_or(z.shift_significance);
        if !(significance > 0.0 && significance < 1.0)
            || !(shift_significance > 0.0 && shift_significance < 1.0)
            || pixel_success_rate > 1.0
        {
            bail!("significance and shift_significance must lie in (0, 1) and pixel_success_rate in [0, 1]");
        }
        let known_failure = match merged.remove("known_failure") {
            Some(v) => Some(
                v.as_str()
                    .context("known_failure must be a string")?
                    .to_string(),
            ),
            None => None,
        };
        let idiff: Thresholds = merged
            .try_into()
            .map_err(|e: toml::de::Error| anyhow::anyhow!("{}", e.message().trim()))?;
        idiff.validate().map_err(anyhow::Error::msg)?;
        Ok(Rule {
            idiff,
            max_mean,
            max_flip,
            significance,
            pixel_success_rate,
            shift_significance,
            known_failure,
        })
    }
}

/// What a manifest says of one image: who made it, how, at which width and sampling grid.
#[derive(Clone, Debug, Default)]
pub struct Provenance {
    /// `renderer version`, or empty when no manifest describes the image.
    pub renderer: String,
    /// Image width the manifest records.
    pub width: Option<u32>,
    /// Image height the manifest records.
    pub height: Option<u32>,
    /// `n` of the n×n sampling grid the manifest records.
    pub grid: Option<u32>,
    /// A golden made by `check --calibrate`: how many renders, the variance image beside it
    /// and the SHA-256 the calibration recorded for it (checked, with the variance's own
    /// manifest entry, when it is read).
    pub calibration: Option<(u32, PathBuf, String)>,
}

/// The manifest of the images in `dir` (`dir/manifest.json`), if there is one.
fn manifest(dir: &Path) -> Result<Option<serde_json::Value>> {
    // A run killed while it put goldens and this manifest in place is finished first
    crate::output::recover(dir);
    let p = dir.join("manifest.json");
    if !p.exists() {
        return Ok(None);
    }
    let text =
        crate::input::read_text(&p, crate::input::MAX_TEXT_BYTES, crate::input::Kind::Stream)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", p.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: malformed JSON", p.display()))?;
    // An object whose "files" is an object of objects: anything else is not a manifest
    let files = v.get("files").unwrap_or(&serde_json::Value::Null);
    if !v.is_object()
        || !(files.is_object() || files.is_null())
        || files
            .as_object()
            .is_some_and(|f| f.values().any(|e| !e.is_object()))
    {
        bail!(
            "{}: not a manifest (an object whose \"files\" maps file names to entries)",
            p.display()
        );
    }
    Ok(Some(v))
}

/// A whole number of a manifest entry from 1 to `max` (a width: the largest image side; a
/// grid: the largest sub-pixel grid); an error names the file, the key and the limit.
fn entry_u32(entry: &serde_json::Value, key: &str, max: u32, path: &Path) -> Result<Option<u32>> {
    match entry.get(key) {
        None | Some(serde_json::Value::Null) => Ok(None),
        Some(v) => v
            .as_u64()
            .filter(|&x| (1..=max as u64).contains(&x))
            .map(|x| Some(x as u32))
            .with_context(|| {
                format!(
                    "{}: the manifest's {key} = {v} is not a whole number from 1 to {max}",
                    path.display()
                )
            }),
    }
}

fn dir_and_name(path: &Path) -> (PathBuf, String) {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    (dir, name)
}

/// What a test's image is made from now: its scene and its declared inputs, each as the suite
/// writes it with its SHA-256.
#[derive(Clone, Debug, Default)]
pub struct Sources {
    pub scene: Option<(String, String)>,
    pub inputs: Vec<(String, String)>,
    /// The renderer command as the suite writes it (placeholders unfilled), for a test made by
    /// a command.
    pub command: Option<String>,
    /// The frame the test itself gives (`width`, `height`, `grid`; `None` where it gives none).
    pub frame: [(&'static str, Option<u32>); 3],
}

/// Why a manifest entry was made from other sources than the test's now (`None`: the same, as
/// far as the entry records them): the files whose hash differs, or that the entry does not
/// know or the test no longer has. `own`: the entry is a golden's, which `--update` writes with
/// every source (so a source it lacks makes it stale); an external reference's entry is judged
/// on what it records.
pub fn staleness(entry: &serde_json::Value, now: &Sources, own: bool) -> Option<String> {
    let mut changed = vec![];
    match (
        entry.get("scene_sha256").and_then(|v| v.as_str()),
        &now.scene,
    ) {
        (Some(want), Some((name, have))) if want != have => {
            changed.push(format!("the scene {name}"))
        }
        (None, Some((name, _))) if own => changed.push(format!("the scene {name} (not recorded)")),
        (Some(_), None) if own => changed.push("a scene the test no longer has".to_string()),
        _ => {}
    }
    // A golden is made by one command with one frame: another command or frame is another
    // image (an external reference records its own renderer's commands: not compared)
    if own {
        let was = entry
            .get("commands")
            .and_then(|c| c.get(0))
            .and_then(|c| c.as_str());
        if let (Some(was), Some(now)) = (was, &now.command) {
            if was != now {
                changed.push(format!("the renderer command (was `{was}`)"));
            }
        }
        for (k, now) in now.frame {
            let was = entry.get(k).and_then(|v| v.as_u64());
            if let (Some(was), Some(now)) = (was, now) {
                if was != u64::from(now) {
                    changed.push(format!("the {k} ({now}, was {was})"));
                }
            }
        }
    }
    let recorded = entry.get("inputs").and_then(|v| v.as_object());
    if recorded.is_some() || own {
        let empty = serde_json::Map::new();
        let recorded = recorded.unwrap_or(&empty);
        for (name, have) in &now.inputs {
            match recorded.get(name).and_then(|v| v.as_str()) {
                Some(want) if want == have => {}
                Some(_) => changed.push(format!("the input {name}")),
                None => changed.push(format!("the input {name} (not recorded)")),
            }
        }
        for name in recorded.keys() {
            if !now.inputs.iter().any(|(n, _)| n == name) {
                changed.push(format!("the input {name} (no longer one)"));
            }
        }
    }
    (!changed.is_empty()).then(|| changed.join(", "))
}

/// Loads a reference and, when the manifest beside it describes it, proves it is that file
/// (SHA-256), and says whether it was made from other versions of the test's scene and inputs
/// ([`staleness`]; the caller decides: a stale golden is compared and re-blessed, a stale
/// external reference refused). A tampered reference is an error. An external reference with
/// no manifest is read as it is, with an empty provenance; a golden with none is refused. Any
/// format [`super::formats`] reads.
pub fn verified_reference(
    path: &Path,
    now: &Sources,
    own: bool,
) -> Result<(Image, Provenance, Option<String>)> {
    let (dir, file) = dir_and_name(path);
    let mut prov = Provenance::default();
    let mut stale = None;
    let m = manifest(&dir)?;
    // A golden is rayproof's own only with its manifest entry (its hash, what made it): a file
    // at a golden's path without one is not compared as a golden, and so never re-blessed
    // over (it may be a user's file)
    if own && m.is_none() {
        bail!(
            "{} has no manifest.json beside it: not a golden rayproof blessed (its hash and what made it are unknown); move it away and run --update to bless one",
            path.display()
        );
    }
    if let Some(m) = m {
        let entry = m["files"].get(&file).with_context(|| {
            format!(
                "{} has no entry in {}",
                path.display(),
                dir.join("manifest.json").display()
            )
        })?;
        // Check the file's hash and its scene's hash against the manifest
        let sha = sha256_file(path)?;
        let want = entry["sha256"].as_str().unwrap_or("");
        if sha != want {
            bail!(
                "{} has SHA-256 {sha}, the manifest says {want}: refusing a reference that was changed outside the scripts",
                path.display()
            );
        }
        stale = staleness(entry, now, own);
        prov = Provenance {
            renderer: format!(
                "{} {}",
                entry["renderer"].as_str().unwrap_or("?"),
                entry["version"].as_str().unwrap_or("")
            )
            .trim()
            .to_string(),
            width: entry_u32(entry, "width", MAX_SIDE, path)?,
            height: entry_u32(entry, "height", MAX_SIDE, path)?,
            grid: entry_u32(entry, "grid", MAX_GRID, path)?,
            calibration: calibration(entry, &dir, path)?,
        };
    }
    let img = super::formats::read_any(path).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok((img, prov, stale))
}

/// The largest number of `check --calibrate` renders (a manifest that records more is not one
/// rayproof wrote).
pub const MAX_RENDERS: u32 = 1000;

/// A golden's calibration, as its manifest entry records it: the renders (2 to
/// [`MAX_RENDERS`]) and the variance image's name, a file beside it.
fn calibration(
    entry: &serde_json::Value,
    dir: &Path,
    path: &Path,
) -> Result<Option<(u32, PathBuf, String)>> {
    let Some(c) = entry
        .get("calibration")
        .filter(|c| c.get("variance").is_some())
    else {
        return Ok(None);
    };
    let renders = c
        .get("renders")
        .and_then(|r| r.as_u64())
        .filter(|r| (2..=MAX_RENDERS as u64).contains(r));
    let name = c
        .get("variance")
        .and_then(|v| v.as_str())
        .filter(|n| !n.is_empty() && !n.contains(['/', '\\']) && *n != "." && *n != "..");
    let sha = c.get("variance_sha256").and_then(|v| v.as_str());
    match (renders, name, sha) {
        (Some(r), Some(n), Some(h)) => Ok(Some((r as u32, dir.join(n), h.to_string()))),
        _ => bail!(
            "{}: the manifest's calibration is not {{renders: 2 to {}, variance: a file name beside it, variance_sha256}}",
            path.display(),
            MAX_RENDERS
        ),
    }
}

/// How a blessed golden was made, for its manifest entry.
pub struct Blessing {
    pub renderer: String,
    /// The command as the suite writes it (placeholders unfilled), never a scratch path.
    pub command: String,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub grid: Option<u32>,
    /// The scene and inputs the image was made from, with their hashes.
    pub sources: Sources,
    /// `check --calibrate`'s record (renders, seeds, the variance image), when it made the file.
    pub calibration: Option<serde_json::Value>,
}

/// Stages a golden (`bytes`: exactly the test image compared) and its entry in the manifest
/// beside it: the command as written, the frame, and the test's own scene and inputs by hash
/// (only `--update` calls this, after every test of the run was validated).
pub fn bless(records: &mut Records, golden: &Path, bytes: Vec<u8>, b: &Blessing) -> Result<()> {
    let mut entry = serde_json::json!({
        "renderer": b.renderer,
        "commands": [b.command],
        "written_by": format!("rayproof {} check --update", env!("CARGO_PKG_VERSION")),
    });
    if let Some(w) = b.width {
        entry["width"] = w.into();
    }
    if let Some(h) = b.height {
        entry["height"] = h.into();
    }
    if let Some(g) = b.grid {
        entry["grid"] = g.into();
        entry["samples_per_pixel"] = (g * g).into();
    }
    if let Some((name, sha)) = &b.sources.scene {
        entry["scene"] = name.clone().into();
        entry["scene_sha256"] = sha.clone().into();
    }
    let inputs: serde_json::Map<String, serde_json::Value> = b
        .sources
        .inputs
        .iter()
        .map(|(n, h)| (n.clone(), h.clone().into()))
        .collect();
    entry["inputs"] = inputs.into();
    if let Some(c) = &b.calibration {
        entry["calibration"] = c.clone();
    }
    records.add(golden, bytes, entry, None);
    Ok(())
}

/// The renderers `rayproof reference` runs, as their manifest entries name them.
pub const OUTSIDE_RENDERERS: &[&str] = &["POV-Ray", "Mitsuba 3"];

/// Image files and the manifest entries that describe them, staged together into one run's
/// outputs (the one writer of manifests in the crate): every manifest is read and validated,
/// and every image and manifest staged, before anything is written.
#[derive(Default)]
pub struct Records {
    files: Vec<(PathBuf, Vec<u8>, serde_json::Value, Option<PathBuf>)>,
}

impl Records {
    /// Adds an image file and its entry (`entry` plus, when staged, the date and the bytes'
    /// SHA-256; the scene names the manifest's scene when it has none).
    pub fn add(
        &mut self,
        path: &Path,
        bytes: Vec<u8>,
        entry: serde_json::Value,
        scene: Option<&Path>,
    ) {
        self.files.push((
            path.to_path_buf(),
            bytes,
            entry,
            scene.map(Path::to_path_buf),
        ));
    }

    /// Stages every image and, once per directory, its updated manifest. Each directory is
    /// locked first (an exclusive lock held until the run's outputs are committed, so that two
    /// runs writing one directory take turns) and its manifest read under the lock: a run
    /// changes only its own entries, and `check --update` never replaces an entry another
    /// writer made (a reference of `rayproof reference`).
    pub fn stage(self, out: &mut crate::output::Outputs) -> Result<()> {
        // One manifest per directory, however the directory is spelled (`g/`, `g/../g/`):
        // spelled twice, it was locked twice (a wait on itself) and written as two outputs
        let mut manifests: Vec<(PathBuf, PathBuf, serde_json::Value)> = vec![];
        for (path, bytes, mut entry, scene) in self.files {
            let (dir, file) = dir_and_name(&path);
            let same = crate::output::canonical(&dir);
            let k = match manifests.iter().position(|(_, c, _)| *c == same) {
                Some(k) => k,
                None => {
                    out.hold(crate::output::DirLock::exclusive(&dir)?);
                    let m = manifest(&dir)?.unwrap_or(serde_json::json!({ "files": {} }));
                    manifests.push((dir.clone(), same, m));
                    manifests.len() - 1
                }
            };
            let m = &mut manifests[k].2;
            let by_update = |e: &serde_json::Value| {
                e.get("written_by")
                    .and_then(|w| w.as_str())
                    .is_some_and(|w| w.ends_with("check --update"))
            };
            // Another writer's: said so, or (written before entries said so) an outside
            // renderer's reference
            let another = |e: &serde_json::Value| match e.get("written_by").and_then(|w| w.as_str())
            {
                Some(w) => !w.ends_with("check --update"),
                None => e
                    .get("renderer")
                    .and_then(|r| r.as_str())
                    .is_some_and(|r| OUTSIDE_RENDERERS.contains(&r)),
            };
            if let Some(old) = m.get("files").and_then(|f| f.get(&file)) {
                if by_update(&entry) && another(old) {
                    bail!(
                        "{}: its manifest entry was not written by `check --update` (a reference?): --update does not replace it (give the test its own goldens directory)",
                        path.display()
                    );
                }
                // And the other way: a reference never replaces a golden a suite blessed
                if !by_update(&entry) && by_update(old) {
                    bail!(
                        "{}: its manifest entry was written by `check --update` (a golden): `rayproof reference` does not replace it (write the reference elsewhere, or remove the golden first)",
                        path.display()
                    );
                }
            }
            if let (Some(s), None) = (&scene, m.get("scene")) {
                m["scene"] = serde_json::json!(s.display().to_string());
            }
            entry["date"] = utc_now().into();
            entry["sha256"] = Sha256::digest(&bytes)
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect::<String>()
                .into();
            if m.get("files").is_none_or(|f| f.is_null()) {
                m["files"] = serde_json::json!({});
            }
            m["files"][file] = entry;
            out.write(&path, &bytes)?;
        }
        for (dir, _, m) in manifests {
            let text = serde_json::to_string_pretty(&m)? + "\n";
            out.write(&dir.join("manifest.json"), text.as_bytes())?;
        }
        Ok(())
    }
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
