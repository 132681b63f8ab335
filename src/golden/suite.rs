//! The suite file of `rayproof check --suite FILE`: which images are under test, how each is
//! made, what it is compared with and under which thresholds. Read and validated whole before
//! anything runs: an unknown key, a test without an image source, an unknown placeholder or a
//! bad threshold is one line naming the file and the test (exit 2).
//!
//! ```toml
//! [suite]
//! name = "myrender"
//! renderer = "myrender {scene} -o {out} --spp {spp}"   # tests without their own source use it
//! timeout = 600                                        # seconds per render command
//! goldens = "goldens"                                  # where --update writes NAME.exr
//! output = "exr"                  # the renderer's format: {out} and goldens end in .exr
//!
//! [thresholds]          # every external reference (idiff keys, max_mean, max_flip, …)
//! fail = 0.05
//! failpercent = 0.1
//!
//! [golden_thresholds]   # the comparison with the test's own golden
//! fail = 1e-6
//!
//! [[test]]
//! name = "cornell"
//! scene = "scenes/cornell.toml"        # {scene}; relative to this file
//! inputs = ["scenes/light.inc"]        # other files the image is made from (hashed)
//! width = 64                           # {width}; height = 48 for {height} (non-square)
//! grid = 8                             # {grid}, {spp} = grid²; else the references' manifests'
//! [[test.reference]]
//! name = "povray"
//! path = "refs/cornell/povray.exr"
//! required = false                     # missing: SKIPPED, not a failure
//! thresholds = { failpercent = 0.2 }
//! ```
//!
//! A test's image comes from exactly one of `image = "PATH"` (an image already rendered),
//! `command = "TEMPLATE"` (or the suite's `renderer`), or `rayproof = { method, precision }`
//! (rayproof renders `scene` itself). Placeholders: `{scene}`, `{out}` (the file the command
//! must write), `{variance}` (its variance image, for the z-test), `{width}`, `{height}`,
//! `{grid}`, `{spp}`, `{name}`. Commands run through `sh -c` in the suite file's directory,
//! placeholders shell-quoted. A renderer given `{width}` or `{height}` must write that size.
//!
//! `output` (in `[suite]` or a test) names the format of the renderer's image by its extension
//! (`exr` by default; `png`, `jpg`, `tif`, `ppm`, `hdr`, `tga`, `bmp`, … as [`super::formats`]
//! reads them): `{out}` ends in it, the default golden is `GOLDENS/NAME.EXT`, and a golden named
//! for another format is a suite error (a golden keeps its real format). An `image` test's
//! format is its extension's. `scene` and `inputs` are hashed into a golden's manifest entry: a
//! golden made from other versions of them is stale (compared, then re-blessed by `--update`).
//!
//! **Platforms.** `[suite] platforms = ["linux-x86_64", "macos-arm64"]` makes a run name one
//! (`check --platform NAME`, else `RAYPROOF_PLATFORM`; neither, or one not in the list, is exit
//! 2): it replaces `{platform}` in every path of the suite (`goldens = "goldens/{platform}"`)
//! and in commands, and chooses `[platform.NAME]` thresholds (`thresholds`,
//! `golden_thresholds`), layered after the suite's, and a test's `[test.platform.NAME]` after
//! the test's (with `skip = "why"`: the test is SKIPPED on that platform). `{platform}` in a
//! suite without `platforms` is an error: no platform's golden stands in for another's.
//!
//! **Masks.** `[[test.mask]]` with `rect = [x, y, width, height]` (display-window pixels) leaves
//! those pixels out of every comparison of the test, or with `tolerance = K` (≥ 1) judges them
//! with K times the tolerances; `image = "PATH"` is a grey image of the frame's size whose first
//! channel is the weight (0 out, 1 as usual, g: tolerances × 1/g). See [`crate::images::Mask`].
//!
//! **Seeds.** `{seed}` in a command is `check --seed` (default 0); `check --calibrate N` renders
//! with seeds 1 to N ([`super::calibrate`]).
//!
//! A NaN or an infinity in a test image fails every comparison of the test, whatever its
//! thresholds (idiff lets a few through under `failpercent`); a test whose image may hold them on
//! purpose says `allow_nonfinite = true`.

use super::formats::Format;
use super::references::Rule;
use crate::golden::Config;
use crate::numerics::Precision;
use crate::render::scene::{MAX_GRID, MAX_SIDE};
use anyhow::{bail, Result};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::time::Duration;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSpec {
    #[serde(default)]
    suite: HeadSpec,
    #[serde(default)]
    thresholds: toml::Table,
    #[serde(default)]
    golden_thresholds: toml::Table,
    #[serde(default)]
    test: Vec<TestSpec>,
    #[serde(default)]
    platform: std::collections::BTreeMap<String, PlatformSpec>,
}

/// `[platform.NAME]` of the suite, or `[test.platform.NAME]` of a test: the thresholds of one
/// platform (layered after the ones they refine), and a test's reason to skip it.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct PlatformSpec {
    #[serde(default)]
    thresholds: toml::Table,
    #[serde(default)]
    golden_thresholds: toml::Table,
    skip: Option<String>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct HeadSpec {
    name: Option<String>,
    renderer: Option<String>,
    timeout: Option<f64>,
    goldens: Option<String>,
    output: Option<String>,
    platforms: Option<Vec<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TestSpec {
    name: toml::Spanned<String>,
    scene: Option<String>,
    image: Option<String>,
    command: Option<String>,
    rayproof: Option<BuiltinSpec>,
    width: Option<u32>,
    height: Option<u32>,
    grid: Option<u32>,
    output: Option<String>,
    inputs: Option<Vec<String>>,
    variance: Option<String>,
    variance_spp: Option<u64>,
    allow_nonfinite: Option<bool>,
    golden: Option<toml::Value>,
    #[serde(default)]
    thresholds: toml::Table,
    #[serde(default)]
    golden_thresholds: toml::Table,
    #[serde(default)]
    reference: Vec<RefSpec>,
    #[serde(default)]
    platform: std::collections::BTreeMap<String, PlatformSpec>,
    #[serde(default)]
    mask: Vec<MaskSpec>,
}

/// `[[test.mask]]`: `rect = [x, y, width, height]` (left out, or with `tolerance = K` its
/// tolerances × K), or `image = "PATH"` (a grey image: its first channel is the weight).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaskSpec {
    rect: Option<Vec<i64>>,
    tolerance: Option<f64>,
    image: Option<String>,
}

/// One part of a test's mask, as the suite gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum MaskSource {
    /// A rectangle and its weight (0: left out).
    Rect([i64; 4], f32),
    /// A mask image, joined to the suite's directory.
    Image(PathBuf),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BuiltinSpec {
    method: String,
    precision: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RefSpec {
    name: String,
    path: String,
    #[serde(default = "yes")]
    required: bool,
    #[serde(default)]
    thresholds: toml::Table,
}

fn yes() -> bool {
    true
}

/// How a test's image is made.
#[derive(Clone, Debug)]
pub enum Source {
    /// An image already on disk.
    Image(PathBuf),
    /// A renderer command template.
    Command(String),
    /// rayproof renders the test's scene itself.
    Rayproof(Config),
}

/// One reference image of a test.
#[derive(Clone, Debug)]
pub struct Reference {
    /// Reference name (`povray`, `mitsuba`, …).
    pub name: String,
    /// Path of the image: the suite file's `path`, joined to the suite's directory.
    pub path: PathBuf,
    /// A missing optional reference is SKIPPED; a missing required one is REFUSED.
    pub required: bool,
    /// Its thresholds.
    pub rule: Rule,
}

/// One test of a suite.
#[derive(Clone, Debug)]
pub struct Test {
    /// Test name, unique in the suite.
    pub name: String,
    /// The scene file, joined to the suite's directory: what rayproof renders, `{scene}` in a
    /// command, and the file whose SHA-256 a reference's manifest must match. `None`: no scene.
    pub scene: Option<PathBuf>,
    /// The scene as the suite file writes it (what a golden's manifest entry records).
    pub scene_name: Option<String>,
    /// Other files the image is made from (`inputs = ["light.inc"]`: include files, textures),
    /// as written and joined to the suite's directory: hashed in a golden's manifest entry
    /// with the scene, so that a golden made before one changed is stale.
    pub inputs: Vec<(String, PathBuf)>,
    /// The command as the suite file writes it (placeholders unfilled): what a golden's
    /// manifest entry records.
    pub command: Option<String>,
    /// How the test image is made: read, rendered by the user's command, or by rayproof.
    pub source: Source,
    /// Width and sampling grid the test asks for (else the references' manifests say).
    pub width: Option<u32>,
    /// Height the test asks for (`{height}`; else the references' manifests say).
    pub height: Option<u32>,
    /// The format the test image must have: the suite's or the test's `output` (a renderer's
    /// `{out}` ends in its extension), rayproof's own renders are OpenEXR, an `image` is what
    /// its extension names. `None`: an image whose extension names no format (read by its bytes).
    pub output: Option<Format>,
    /// The extension of `{out}` and of the default golden: the `output` as written (`ppm`,
    /// `jpg`), `exr` by default, an image's own.
    pub out_ext: String,
    /// `n` of the n×n sampling grid.
    pub grid: Option<u32>,
    /// The test image's variance (a path, or a template with `{variance}`), for the z-test.
    pub variance: Option<String>,
    /// Samples per pixel behind the variance image (the z-test's `spp`); at least 1, default 1.
    pub variance_spp: u64,
    /// NaN or Inf pixels in the test image are allowed (`allow_nonfinite = true`); by default
    /// one fails every comparison of the test, whatever the thresholds.
    pub allow_nonfinite: bool,
    /// The golden image `--update` may write, with its rule.
    pub golden: Option<(PathBuf, Rule)>,
    /// The references the test image is compared with.
    pub references: Vec<Reference>,
    /// The test's mask (`[[test.mask]]`): pixels left out of every comparison of the test, or
    /// judged with scaled tolerances. Empty: none.
    pub mask: Vec<MaskSource>,
    /// The line of the suite file where the test starts (its `[[test]]`), for annotations that
    /// point at it; 1 when the file writes its tests otherwise.
    pub line: usize,
    /// Why the test is skipped on the chosen platform (`[test.platform.NAME] skip = "…"`):
    /// every row SKIPPED with this reason, nothing made or compared.
    pub skip: Option<String>,
}

impl Test {
    /// The configuration label of a row: rayproof's method and precision, or how the image
    /// was made.
    pub fn config(&self) -> String {
        match &self.source {
            Source::Rayproof(c) => c.label(),
            Source::Command(_) => "command".into(),
            Source::Image(_) => "image".into(),
        }
    }
}

/// A whole suite file, validated.
#[derive(Clone, Debug)]
pub struct Suite {
    /// The suite file.
    pub path: PathBuf,
    /// The suite file's directory: relative paths and commands start there.
    pub dir: PathBuf,
    /// The suite's name (`[suite] name`, default `rayproof check`), in reports and JUnit.
    pub name: String,
    /// How long one render command may take before it is killed and the test refused
    /// (`[suite] timeout`, default 600 s).
    pub timeout: Duration,
    /// The tests, in file order.
    pub tests: Vec<Test>,
    /// The platform the run is for (`--platform NAME` or `RAYPROOF_PLATFORM`): one of the
    /// suite's `platforms`, put for `{platform}` in its paths and commands, and choosing the
    /// `[platform.NAME]` thresholds. `None`: the suite declares no platforms.
    pub platform: Option<String>,
    /// The goldens, their manifests and variances, and the references of the suite's other
    /// platforms: files no output of this run may replace.
    pub others: Vec<PathBuf>,
}

/// The longest `[suite] timeout`: one week, in seconds (a render command that may run longer is
/// not a test; 1e20 s made `Duration::from_secs_f64` panic).
pub const MAX_TIMEOUT: f64 = 7.0 * 24.0 * 3600.0;

/// The placeholders a command may use.
pub const PLACEHOLDERS: [&str; 10] = [
    "scene", "out", "variance", "width", "height", "grid", "spp", "name", "platform", "seed",
];

/// The placeholders in a template; an unknown one or an unclosed brace is an error.
pub fn placeholders(template: &str) -> Result<Vec<String>, String> {
    let mut found = vec![];
    let mut rest = template;
    while let Some(i) = rest.find('{') {
        let after = &rest[i + 1..];
        let j = after
            .find('}')
            .ok_or_else(|| format!("'{template}': an unclosed '{{'"))?;
        let key = &after[..j];
        if !PLACEHOLDERS.contains(&key) {
            return Err(format!(
                "'{template}': unknown placeholder {{{key}}} (known: {})",
                PLACEHOLDERS.map(|p| format!("{{{p}}}")).join(" ")
            ));
        }
        found.push(key.to_string());
        rest = &after[j + 1..];
    }
    Ok(found)
}

/// Fills a template, each value shell-quoted.
pub fn fill(template: &str, values: &[(&str, String)]) -> String {
    let quote = |s: &str| format!("'{}'", s.replace('\'', r"'\''"));
    let mut s = template.to_string();
    for (k, v) in values {
        s = s.replace(&format!("{{{k}}}"), &quote(v));
    }
    s
}

impl Suite {
    /// Reads and validates a suite file for one platform (`None`: a suite that declares none).
    pub fn load(path: &Path, platform: Option<&str>) -> Result<Suite> {
        let text = crate::input::read_text(
            path,
            crate::input::MAX_TEXT_BYTES,
            crate::input::Kind::Stream,
        )
        .map_err(|e| anyhow::anyhow!("cannot read suite file {}: {e}", path.display()))?;
        let spec: FileSpec = toml::from_str(&text)
            .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.message().trim()))?;
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf();
        // The platform: one of those the suite declares, when it declares some; never another
        // platform's golden or thresholds in its place
        let platforms = spec.suite.platforms.clone();
        if let Some(list) = &platforms {
            if list.is_empty() {
                bail!(
                    "{}: suite.platforms is empty: name the platforms, or leave it out",
                    path.display()
                );
            }
            for (i, p) in list.iter().enumerate() {
                if !file_name_safe(p) || list[..i].contains(p) {
                    bail!(
                        "{}: suite.platforms: {:?} is repeated or not a name of 1 to 100 letters, digits, '-', '_' or '.' (it becomes part of file names)",
                        path.display(),
                        p.chars().take(80).collect::<String>()
                    );
                }
            }
        }
        let known = |list: &[String]| list.join(", ");
        match (&platforms, platform) {
            (None, Some(p)) => bail!(
                "{}: --platform {p} (or RAYPROOF_PLATFORM): the suite declares no platforms (add platforms = [...] to [suite])",
                path.display()
            ),
            (Some(list), None) => bail!(
                "{}: the suite keeps goldens or thresholds per platform ({}): give --platform NAME or set RAYPROOF_PLATFORM (no platform's golden stands in for another's)",
                path.display(),
                known(list)
            ),
            (Some(list), Some(p)) if !list.iter().any(|x| x == p) => bail!(
                "{}: platform '{p}' is not one the suite declares ({})",
                path.display(),
                known(list)
            ),
            _ => {}
        }
        if platforms.is_none() && text.contains("{platform}") {
            bail!(
                "{}: {{platform}} is used but the suite declares no platforms (add platforms = [...] to [suite])",
                path.display()
            );
        }
        let declared_platform = |where_: &str, name: &str| -> Result<()> {
            match &platforms {
                Some(list) if list.iter().any(|x| x == name) => Ok(()),
                Some(list) => bail!(
                    "{}: {where_}[platform.{name}]: '{name}' is not one of the suite's platforms ({})",
                    path.display(),
                    known(list)
                ),
                None => bail!(
                    "{}: {where_}[platform.{name}]: the suite declares no platforms (add platforms = [...] to [suite])",
                    path.display()
                ),
            }
        };
        for name in spec.platform.keys() {
            declared_platform("", name)?;
        }
        let empty = PlatformSpec::default();
        let on = spec
            .platform
            .get(platform.unwrap_or_default())
            .unwrap_or(&empty);
        if on.skip.is_some() {
            bail!(
                "{}: [platform.{}]: skip belongs in a test's [test.platform.NAME]",
                path.display(),
                platform.unwrap_or_default()
            );
        }
        let sub = |p: &str| p.replace("{platform}", platform.unwrap_or_default());
        let at = |p: &str| dir.join(sub(p));
        let timeout = spec.suite.timeout.unwrap_or(600.0);
        if !(timeout > 0.0 && timeout <= MAX_TIMEOUT) {
            bail!(
                "{}: suite.timeout = {timeout}: must be a positive number of seconds, at most {MAX_TIMEOUT} (one week)",
                path.display()
            );
        }
        let goldens = spec.suite.goldens.as_deref().map(at);
        let output_format = |o: &str| {
            Format::from_ext(o).ok_or_else(|| {
                format!(
                    "output = \"{o}\" is not an image format rayproof reads (known: {})",
                    super::formats::known_extensions()
                )
            })
        };
        let suite_output = match &spec.suite.output {
            Some(o) => Some(
                output_format(o).map_err(|e| anyhow::anyhow!("{}: suite.{e}", path.display()))?,
            ),
            None => None,
        };
        let mut tests: Vec<Test> = vec![];
        // The names seen so far: a set, not a search of `tests` (10,000 tests: 5·10⁷ compares)
        let mut names: std::collections::HashSet<String> = Default::default();
        let mut others: Vec<PathBuf> = vec![];
        // Where the lines end, for the line of each test's name (one pass: a suite of 10,000
        // tests validates in well under a second)
        let newlines: Vec<usize> = text
            .bytes()
            .enumerate()
            .filter(|(_, b)| *b == b'\n')
            .map(|(i, _)| i)
            .collect();
        for t in spec.test {
            // The line of the test's name, for CI annotations (the parser's own span of it)
            let line = newlines.partition_point(|&n| n < t.name.span().start) + 1;
            let test_name: String = t.name.get_ref().clone();
            let ctx = |what: String| format!("{}: test '{}': {what}", path.display(), test_name);
            for name in t.platform.keys() {
                declared_platform(&format!("test '{}': ", test_name), name)?;
            }
            let t_on = t
                .platform
                .get(platform.unwrap_or_default())
                .unwrap_or(&empty);
            if t_on.skip.as_deref().is_some_and(|s| s.trim().is_empty()) {
                bail!(ctx(
                    "skip = \"\": say why the test is skipped on this platform".into()
                ));
            }
            // A unique, file-name-safe name
            if !file_name_safe(&test_name) {
                bail!(ctx("a name must be letters, digits, '-', '_' or '.'".into()));
            }
            if !names.insert(test_name.clone()) {
                bail!(ctx("a second test with this name".into()));
            }
            // Exactly one image source
            let source = match (&t.image, &t.command, &t.rayproof, &spec.suite.renderer) {
                (Some(i), None, None, _) => Source::Image(at(i)),
                (None, Some(c), None, _) => Source::Command(c.clone()),
                (None, None, Some(b), _) => {
                    Source::Rayproof(builtin(b).map_err(|e| anyhow::anyhow!(ctx(e)))?)
                }
                (None, None, None, Some(r)) => Source::Command(r.clone()),
                (None, None, None, None) => bail!(ctx(
                    "no image: give image, command or rayproof (or suite.renderer)".into()
                )),
                _ => bail!(ctx("give only one of image, command and rayproof".into())),
            };
            if let Source::Command(c) = &source {
                let keys = placeholders(c).map_err(|e| anyhow::anyhow!(ctx(e)))?;
                if !keys.iter().any(|k| k == "out") {
                    bail!(ctx(format!(
                        "the command '{c}' has no {{out}}: where does it write?"
                    )));
                }
                if keys.iter().any(|k| k == "scene") && t.scene.is_none() {
                    bail!(ctx(
                        "the command uses {scene} but the test has no scene".into()
                    ));
                }
            }
            if matches!(source, Source::Rayproof(_)) && t.scene.is_none() {
                bail!(ctx("rayproof renders a scene: give scene".into()));
            }
            if let Some(v) = &t.variance {
                placeholders(v).map_err(|e| anyhow::anyhow!(ctx(e)))?;
            }
            if t.grid == Some(0) || t.width == Some(0) || t.height == Some(0) {
                bail!(ctx("width, height and grid must be at least 1".into()));
            }
            if let Some(h) = t.height.filter(|&h| h > MAX_SIDE) {
                bail!(ctx(format!(
                    "height = {h}: an image side may be at most {MAX_SIDE}"
                )));
            }
            // The test image's format: declared, else rayproof's EXR or the image's extension
            let declared = match &t.output {
                Some(o) => Some(output_format(o).map_err(|e| anyhow::anyhow!(ctx(e)))?),
                None => suite_output,
            };
            let output = match &source {
                Source::Rayproof(_) => {
                    if declared.is_some_and(|d| d != Format::Exr) {
                        bail!(ctx("rayproof writes OpenEXR: output must be \"exr\"".into()));
                    }
                    if t.height.is_some() {
                        bail!(ctx(
                            "rayproof keeps the scene's aspect ratio: give width, not height"
                                .into()
                        ));
                    }
                    Some(Format::Exr)
                }
                Source::Command(_) => Some(declared.unwrap_or(Format::Exr)),
                Source::Image(p) => declared.or(Format::of_path(p)),
            };
            let out_ext = match (&t.output, &spec.suite.output, &source) {
                (_, _, Source::Rayproof(_)) => "exr".to_string(),
                (Some(o), _, _) | (None, Some(o), _) => o.to_ascii_lowercase(),
                (None, None, Source::Image(p)) if output.is_some() => p
                    .extension()
                    .map(|e| e.to_string_lossy().to_ascii_lowercase())
                    .unwrap_or_default(),
                _ => "exr".to_string(),
            };
            // The mask: rectangles and images
            let mut mask = vec![];
            for m in &t.mask {
                mask.push(match (&m.rect, &m.image, m.tolerance) {
                    (Some(r), None, tol) => {
                        if r.len() != 4 || r[2] <= 0 || r[3] <= 0 {
                            bail!(ctx(format!("mask rect {r:?}: [x, y, width, height] with a width and height of at least 1")));
                        }
                        let weight = match tol {
                            None => 0.0,
                            Some(k) if k.is_finite() && k >= 1.0 => (1.0 / k) as f32,
                            Some(k) => bail!(ctx(format!("mask tolerance = {k}: a factor of at least 1 by which the rectangle's tolerances grow (leave it out to ignore the rectangle)"))),
                        };
                        MaskSource::Rect([r[0], r[1], r[2], r[3]], weight)
                    }
                    (None, Some(i), None) => MaskSource::Image(at(i)),
                    _ => bail!(ctx("a [[test.mask]] is rect = [x, y, width, height] (with an optional tolerance) or image = \"PATH\"".into())),
                });
            }
            // Inputs the image is made from, besides the scene
            let mut inputs = vec![];
            for i in t.inputs.iter().flatten() {
                if i.is_empty() || inputs.iter().any(|(n, _): &(String, PathBuf)| n == i) {
                    bail!(ctx(format!("input '{i}' is empty or repeated")));
                }
                inputs.push((i.clone(), at(i)));
            }
            if let Some(g) = t.grid.filter(|&g| g > MAX_GRID) {
                bail!(ctx(format!(
                    "grid = {g}: the sub-pixel grid n may be at most {MAX_GRID}"
                )));
            }
            if let Some(w) = t.width.filter(|&w| w > MAX_SIDE) {
                bail!(ctx(format!(
                    "width = {w}: an image side may be at most {MAX_SIDE}"
                )));
            }
            // Rules: suite defaults, then the test's, then the reference's own
            let rule = |layers: &[&toml::Table]| {
                Rule::from_layers(layers).map_err(|e| anyhow::anyhow!(ctx(format!("{e:#}"))))
            };
            let mut references = vec![];
            for r in &t.reference {
                if r.name.is_empty() || references.iter().any(|o: &Reference| o.name == r.name) {
                    bail!(ctx(format!(
                        "reference name '{}' is empty or repeated",
                        r.name
                    )));
                }
                // It becomes part of the report's file names
                if !file_name_safe(&r.name) {
                    bail!(ctx(format!(
                        "reference name {:?}: a name must be letters, digits, '-', '_' or '.' (it names the report's files)",
                        r.name.chars().take(80).collect::<String>()
                    )));
                }
                references.push(Reference {
                    name: r.name.clone(),
                    path: at(&r.path),
                    required: r.required,
                    rule: rule(&[
                        &spec.thresholds,
                        &on.thresholds,
                        &t.thresholds,
                        &t_on.thresholds,
                        &r.thresholds,
                    ])?,
                });
            }
            // The golden: a path, false, or by default GOLDENS/NAME.exr when the suite names a
            // goldens directory
            let golden_path = match &t.golden {
                Some(toml::Value::String(p)) => Some(at(p)),
                Some(toml::Value::Boolean(false)) => None,
                Some(toml::Value::Boolean(true)) | None => goldens
                    .as_ref()
                    .map(|g| g.join(format!("{}.{out_ext}", test_name))),
                Some(_) => bail!(ctx("golden must be a path or false".into())),
            };
            // The same files of the suite's other platforms: no output of this run may be one
            for other in platforms.iter().flatten() {
                if Some(other.as_str()) == platform {
                    continue;
                }
                let at_other = |p: &str| dir.join(p.replace("{platform}", other));
                let golden = match &t.golden {
                    Some(toml::Value::String(p)) => Some(at_other(p)),
                    Some(toml::Value::Boolean(false)) => None,
                    _ => spec
                        .suite
                        .goldens
                        .as_deref()
                        .map(|g| at_other(g).join(format!("{}.{out_ext}", test_name))),
                };
                if let Some(g) = golden {
                    others.push(variance_path(&g));
                    others.push(g.with_file_name("manifest.json"));
                    others.push(g);
                }
                others.extend(t.reference.iter().map(|r| at_other(&r.path)));
            }
            // A golden keeps its real format: its name says the test image's
            if let (Some(g), Some(f)) = (&golden_path, output) {
                if Format::of_path(g) != Some(f) {
                    bail!(ctx(format!(
                        "the golden {} would hold a {} file: name it .{out_ext} (a golden keeps its real format)",
                        g.display(),
                        f.name(),
                    )));
                }
            }
            if golden_path.is_some() && references.iter().any(|r| r.name == "golden") {
                bail!(ctx(
                    "'golden' is the name of the test's own golden image".into()
                ));
            }
            let golden = match golden_path {
                Some(p) => Some((
                    p,
                    rule(&[
                        &spec.golden_thresholds,
                        &on.golden_thresholds,
                        &t.golden_thresholds,
                        &t_on.golden_thresholds,
                    ])?,
                )),
                None => None,
            };
            if golden.is_none() && references.is_empty() {
                bail!(ctx(
                    "nothing to compare with: no reference and no golden".into()
                ));
            }
            tests.push(Test {
                name: test_name.clone(),
                scene: t.scene.as_deref().map(at),
                scene_name: t.scene.clone(),
                inputs,
                command: match &source {
                    Source::Command(c) => Some(c.clone()),
                    _ => None,
                },
                source,
                width: t.width,
                height: t.height,
                output,
                out_ext,
                grid: t.grid,
                variance: t.variance.as_deref().map(sub),
                variance_spp: t.variance_spp.unwrap_or(1).max(1),
                allow_nonfinite: t.allow_nonfinite.unwrap_or(false),
                golden,
                references,
                skip: t_on.skip.clone(),
                mask,
                line,
            });
        }
        if tests.is_empty() {
            bail!("{}: no [[test]]", path.display());
        }
        // A golden is never a file another part of the suite reads: --update would write over it
        let suite = Suite {
            path: path.to_path_buf(),
            dir: dir.clone(),
            name: String::new(),
            timeout: Duration::ZERO,
            tests: tests.clone(),
            platform: None,
            others: vec![],
        };
        // Each file's identity once (a look-up per golden: linear in the suite's size)
        let read: std::collections::HashMap<crate::output::Identity, PathBuf> = suite
            .inputs()
            .into_iter()
            .rev()
            .map(|p| (crate::output::identity(&p), p))
            .collect();
        let mut goldens: std::collections::HashMap<crate::output::Identity, String> =
            Default::default();
        for t in &tests {
            if let Some((g, _)) = &t.golden {
                let id = crate::output::identity(g);
                // One golden, two tests (`g/a.exr` and `g/../g/a.exr`), or a golden that is
                // another test's calibrated variance (tests `a` and `a.variance`): --update or
                // --calibrate would write one file twice
                let variance = variance_path(g);
                for (what, p) in [("golden", g), ("calibrated variance", &variance)] {
                    let mine = format!("the {what} of test '{}'", t.name);
                    if let Some(other) = goldens.insert(crate::output::identity(p), mine.clone()) {
                        // Two goldens: said as before; a golden and a variance: which is which
                        if let (Some(o), "golden") =
                            (other.strip_prefix("the golden of test "), what)
                        {
                            bail!(
                                "{}: tests {o} and '{}' have one golden, {}: give each its own",
                                path.display(),
                                t.name,
                                p.display()
                            );
                        }
                        bail!(
                            "{}: {other} and {mine} are one file, {}: give each its own",
                            path.display(),
                            p.display()
                        );
                    }
                }
                if let Some(r) = read.get(&id) {
                    bail!(
                        "{}: test '{}': its golden {} is a file the suite reads ({}): --update would write over it",
                        path.display(),
                        t.name,
                        g.display(),
                        r.display()
                    );
                }
            }
        }
        Ok(Suite {
            path: path.to_path_buf(),
            dir,
            name: spec.suite.name.unwrap_or_else(|| "rayproof check".into()),
            timeout: Duration::from_secs_f64(timeout),
            tests,
            platform: platform.map(str::to_string),
            others,
        })
    }
}

impl Suite {
    /// Every file the suite reads: the suite file, scenes, test images and references, so that
    /// no output of a run replaces one. (A manifest beside references may also describe goldens:
    /// `--update` rewrites only the goldens' entries in it.)
    pub fn inputs(&self) -> Vec<PathBuf> {
        let mut v = vec![self.path.clone()];
        for t in &self.tests {
            v.extend(t.scene.clone());
            v.extend(t.inputs.iter().map(|(_, p)| p.clone()));
            if let Source::Image(p) = &t.source {
                v.push(p.clone());
            }
            v.extend(t.references.iter().map(|r| r.path.clone()));
            v.extend(t.mask.iter().filter_map(|m| match m {
                MaskSource::Image(p) => Some(p.clone()),
                MaskSource::Rect(..) => None,
            }));
            // A variance image the suite gives (not the renderer's `{variance}`)
            if let Some(var) = t.variance.as_deref().filter(|v| *v != "{variance}") {
                v.push(self.dir.join(var.replace("{name}", &t.name)));
            }
        }
        v
    }

    /// The goldens and the manifests beside them: read by `check`, written only by `--update`,
    /// never replaced (nor held in a report directory) by another output of a run.
    pub fn goldens(&self) -> Vec<PathBuf> {
        let mut v = vec![];
        for (g, _) in self.tests.iter().filter_map(|t| t.golden.as_ref()) {
            v.push(g.clone());
            v.push(variance_path(g));
            let dir = g.parent().unwrap_or(Path::new("."));
            v.push(dir.join("manifest.json"));
        }
        v.sort();
        v.dedup();
        v
    }
}

/// The variance image `check --calibrate` writes beside a golden: `DIR/STEM.variance.exr` (a
/// file of the suite's goldens: no other test's golden, no output of a run may be it).
pub fn variance_path(golden: &Path) -> PathBuf {
    let stem = golden
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    golden.with_file_name(format!("{stem}.variance.exr"))
}

/// Whether a name from the suite can become part of a file name: letters, digits, `-`, `_`
/// or `.`, at most 100 of them, and not only dots.
fn file_name_safe(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 100
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
        && !name.chars().all(|c| c == '.')
}

/// `rayproof = { method, precision }`.
fn builtin(b: &BuiltinSpec) -> Result<Config, String> {
    let method = crate::shapes::sphere::methods::method_by_name(&b.method)
        .ok_or_else(|| format!("rayproof.method '{}' is not a ray–sphere method", b.method))?;
    let precision = Precision::ALL
        .iter()
        .find(|p| p.name() == b.precision)
        .ok_or_else(|| format!("rayproof.precision '{}' is not f32 or f64", b.precision))?;
    Ok(Config {
        method,
        precision: precision.name(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placeholders_are_checked_and_filled_quoted() {
        assert_eq!(
            placeholders("r {scene} -o {out} --spp {spp}").unwrap(),
            ["scene", "out", "spp"]
        );
        assert!(placeholders("r {scen}")
            .unwrap_err()
            .contains("unknown placeholder {scen}"));
        assert!(placeholders("r {out").is_err());
        assert_eq!(fill("r {out}", &[("out", "a b'c".into())]), r"r 'a b'\''c'");
    }
}
