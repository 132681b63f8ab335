//! Conformance with the real OpenImageIO `idiff`, run live (Debian's `openimageio-tools`; the
//! test fails, loudly, when `idiff` or `oiiotool` is missing: CI installs them).
//!
//! The files: the 21 pairs of `scripts/idiff-pairs` (noise offsets, relative changes, HDR,
//! negative and tiny values, a threshold edge, NaN and Inf, RGB against RGBA, two sizes, 8-bit
//! PNG), and pairs made here by the real `oiiotool` with small controlled differences (all
//! channels +2e-4, a 6×4 block +0.02, one pixel +0.3): float, half, RGBA, tiled, every
//! compression (none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab, and the lossy ones
//! against their uncompressed source), Blender-style multilayer (`ViewLayer.Combined.R/G/B/A`,
//! `ViewLayer.Depth.Z`), single-channel `R`, `Y`, `Z`, 8- and 16-bit PNG (RGB, grey, grey with
//! alpha, RGBA with no colour chunk, an `sRGB` chunk, a `gAMA` chunk; an `oFFs` offset),
//! data windows moved (`--origin`), cropped (`--crop`) and beyond the display window, display
//! windows away from (0, 0) (`--fullsize`), a multipart file, a truncated file. The first are
//! compared under 10 option sets, the others under 4 of them (idiff costs 0.2 s of CPU a run).
//!
//! What is required:
//! - `rayproof diff --idiff-compat` agrees with `idiff -v` on every run (but a truncated file,
//!   which idiff reads as zeros and rayproof refuses): exit code, pixels over
//!   warn and over fail, their percentages, mean, RMS, PSNR and max error as idiff prints them
//!   (`%g`), and the max error's position and channel. With `--layer NAME` (idiff has no such
//!   option), the idiff it must agree with is idiff on the files reduced to that layer by
//!   `oiiotool --ch`.
//! - `rayproof diff` agrees the same way (the channel compared by its name within the layer),
//!   except on the pairs of the README's table of deliberate differences, where it gives what
//!   that table says at idiff's defaults; and on the multilayer pairs, where it agrees at every
//!   option set with idiff on the files reduced to the layer it reports (`Combined`).
//!
//! Run with `--nocapture` to see the table: files × option sets.

use rayproof::images::fmt_g;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The option sets (those of the recorded parity runs before this test ran idiff live).
const OPTIONS: [&[&str]; 10] = [
    &[],
    &["--fail", "0.05", "--failpercent", "1"],
    &["--fail", "0.01", "--warn", "0.001"],
    &[
        "--fail",
        "0.004",
        "--failrelative",
        "0.01",
        "--warn",
        "0.002",
        "--warnrelative",
        "0.005",
    ],
    &["--fail", "0.01", "--failpercent", "50", "--hardfail", "0.1"],
    &["--fail", "0.001", "--allowfailures", "10"],
    &["--fail", "1", "--warn", "0.02", "--warnpercent", "5"],
    &["--fail", "1", "--warn", "1", "--hardwarn", "0.03"],
    &[
        "--fail",
        "0.1",
        "--failpercent",
        "0.5",
        "--warn",
        "0.01",
        "--warnpercent",
        "0.5",
    ],
    &["--fail", "0", "--warn", "0"],
];

/// The option sets of the pairs made by oiiotool (whose point is reading files as idiff does;
/// idiff costs 0.2 s of CPU per run, mostly its start): defaults, absolute thresholds that
/// tell the three changes apart, relative thresholds, percentages.
const FILE_OPTIONS: [&[&str]; 4] = [OPTIONS[0], OPTIONS[2], OPTIONS[3], OPTIONS[8]];

/// The pairs of the README's table of deliberate differences.
const DELIBERATE: [&str; 17] = [
    "nan1",
    "nan2",
    "inf1",
    "inf2",
    "infsign",
    "rgba",
    "size",
    "displaydiff",
    "multilayer",
    "multilayer-depth",
    "truncated",
    "png8-rgba",
    "png16-rgba",
    "png8-rgba-srgb",
    "png8-rgba-gamma22",
    "png16-rgba-gamma18",
    "png8-grey-alpha",
];

/// The pairs on which `--idiff-compat` does not follow idiff either (README table).
const COMPAT_REFUSES: [&str; 1] = ["truncated"];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `TOOL --version`, or a panic that says how to install it.
fn version(tool: &str) -> String {
    match Command::new(tool).arg("--version").output() {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout).trim().to_string(),
        Ok(o) => panic!(
            "`{tool} --version` failed ({}): the live idiff conformance test needs OpenImageIO's tools (Debian/Ubuntu: apt-get install openimageio-tools)",
            o.status
        ),
        Err(e) => panic!(
            "{tool} not found ({e}): the live idiff conformance test needs OpenImageIO's tools (Debian/Ubuntu: apt-get install openimageio-tools)"
        ),
    }
}

/// Runs `oiiotool ARGS` in `dir`; panics with its stderr if it fails.
fn oiio(dir: &Path, args: &[&str]) {
    let o = Command::new("oiiotool")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("oiiotool runs");
    assert!(
        o.status.success(),
        "oiiotool {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// What idiff printed and returned.
#[derive(Debug, Default)]
struct Idiff {
    exit: i32,
    mean: Option<String>,
    rms: Option<String>,
    psnr: Option<String>,
    max: Option<String>,
    max_at: Option<(i64, i64, String)>,
    /// (pixels, percentage as printed) over warn, then over fail.
    over: Vec<(u64, String)>,
    stdout: String,
}

/// `idiff -v OPTIONS A B`, parsed.
fn idiff(dir: &Path, a: &Path, b: &Path, opts: &[&str]) -> Idiff {
    let o = Command::new("idiff")
        .arg("-v")
        .args(opts)
        .arg(a)
        .arg(b)
        .current_dir(dir)
        .output()
        .expect("idiff runs");
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let mut r = Idiff {
        exit: o.status.code().expect("idiff exit code"),
        ..Default::default()
    };
    for line in out.lines().map(str::trim) {
        let value = |key: &str| {
            line.strip_prefix(key)
                .map(|v| v.trim_start().trim_start_matches('=').trim().to_string())
        };
        if let Some(v) = value("Mean error") {
            r.mean = Some(v);
        } else if let Some(v) = value("RMS error") {
            r.rms = Some(v);
        } else if let Some(v) = value("Peak SNR") {
            r.psnr = Some(v);
        } else if let Some(v) = value("Max error") {
            // `0.3 @ (40, 30, R)  values are …`, or `0`
            let (num, rest) = v.split_once(" @ (").unwrap_or((&v, ""));
            r.max = Some(num.trim().to_string());
            if let Some((at, _)) = rest.split_once(')') {
                let f: Vec<&str> = at.splitn(3, ", ").collect();
                r.max_at = Some((
                    f[0].parse().unwrap(),
                    f[1].parse().unwrap(),
                    f[2].to_string(),
                ));
            }
        } else if let Some((n, rest)) = line.split_once(" pixels (") {
            if let (Ok(n), Some((pct, _))) = (n.parse::<u64>(), rest.split_once("%) over")) {
                r.over.push((n, pct.to_string()));
            }
        }
    }
    r.stdout = out;
    r
}

/// `rayproof diff [--idiff-compat] OPTIONS EXTRA A B --json -`: exit code and JSON.
fn rayproof(a: &Path, b: &Path, opts: &[&str], extra: &[String], compat: bool) -> (i32, Value) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_rayproof"));
    cmd.arg("diff")
        .args(opts)
        .args(extra)
        .args(["--no-flip", "--json", "-"]);
    if compat {
        cmd.arg("--idiff-compat");
    }
    let out = cmd.arg(a).arg(b).output().unwrap();
    let json = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
    (out.status.code().unwrap(), json)
}

/// A number as idiff prints it (`%g`), from rayproof's JSON (a number or "inf"/"nan").
fn g(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        v => fmt_g(v.as_f64().unwrap(), 6),
    }
}

/// Where rayproof and idiff differ on one run, if they do. `suffix_only`: channels compared by
/// their name within the layer (rayproof's default semantics name `B` of `ViewLayer.Combined.B`).
fn disagreement(run: &Idiff, code: i32, j: &Value, suffix_only: bool) -> Option<String> {
    let c = &j["comparison"];
    let mut diffs = vec![];
    if run.exit != code {
        diffs.push(format!("exit {code} vs idiff {}", run.exit));
    }
    if c.is_null() {
        return (!diffs.is_empty()).then(|| diffs.join("; ") + " (no comparison)");
    }
    let npels = c["npels"].as_u64().unwrap();
    for (k, (key, ours)) in [("warn", &c["n_warn"]), ("fail", &c["n_fail"])]
        .into_iter()
        .enumerate()
    {
        let ours = ours.as_u64().unwrap();
        let pct = fmt_g(100.0 * ours as f64 / npels.max(1) as f64, 3);
        match run.over.get(k) {
            Some((n, p)) if *n == ours && *p == pct => {}
            theirs => diffs.push(format!("{key} pixels {ours} ({pct}%) vs idiff {theirs:?}")),
        }
    }
    for (k, theirs, ours) in [
        ("mean", &run.mean, &c["mean_error"]),
        ("rms", &run.rms, &c["rms_error"]),
        ("psnr", &run.psnr, &c["psnr"]),
        ("max", &run.max, &c["max_error"]),
    ] {
        let ours = g(ours);
        if theirs.as_deref() != Some(ours.as_str()) {
            diffs.push(format!("{k} {ours} vs idiff {theirs:?}"));
        }
    }
    if let Some((x, y, ch)) = &run.max_at {
        let at = &c["max_at"];
        let ours_ch = c["channels"][at[2].as_u64().unwrap() as usize]
            .as_str()
            .unwrap()
            .to_string();
        let theirs_ch = match suffix_only {
            true => ch.rsplit('.').next().unwrap().to_string(),
            false => ch.clone(),
        };
        let ours = (at[0].as_i64().unwrap(), at[1].as_i64().unwrap(), ours_ch);
        if ours != (*x, *y, theirs_ch.clone()) {
            diffs.push(format!("max at {ours:?} vs idiff ({x}, {y}, {theirs_ch})"));
        }
    }
    (!diffs.is_empty()).then(|| diffs.join("; "))
}

/// One pair of files and how each semantics must relate to idiff.
struct Case {
    name: String,
    a: PathBuf,
    b: PathBuf,
    /// Extra `rayproof diff` arguments (`--layer NAME`).
    extra: Vec<String>,
    /// The files `--idiff-compat` must agree with idiff on (the pair itself, or the pair
    /// reduced to the layer `--layer` names).
    compat_files: (PathBuf, PathBuf),
    /// The files the default semantics must agree with idiff on, at every option set; `None`:
    /// a deliberate difference judged by the README's table alone.
    default_files: Option<(PathBuf, PathBuf)>,
    /// The layer the default semantics must report reading from both files.
    default_layer: Option<&'static str>,
    /// The option sets it is compared under.
    options: &'static [&'static [&'static str]],
}

impl Case {
    fn plain(name: &str, a: PathBuf, b: PathBuf) -> Case {
        let deliberate = DELIBERATE.contains(&name);
        Case {
            name: name.into(),
            compat_files: (a.clone(), b.clone()),
            default_files: (!deliberate).then(|| (a.clone(), b.clone())),
            a,
            b,
            extra: vec![],
            default_layer: None,
            options: &FILE_OPTIONS,
        }
    }
}

/// The pairs of scripts/idiff-pairs.
fn script_pairs(dir: &Path) -> Vec<Case> {
    let out = Command::new("python3")
        .arg(root().join("scripts/idiff-pairs"))
        .arg(dir)
        .output()
        .expect("python3 runs scripts/idiff-pairs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            Case {
                options: &OPTIONS,
                ..Case::plain(w[0], PathBuf::from(w[1]), PathBuf::from(w[2]))
            }
        })
        .collect()
}

/// The pairs made by the real oiiotool.
fn oiiotool_pairs(d: &Path) -> Vec<Case> {
    let combined =
        "ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B,ViewLayer.Combined.A";
    // Sources: uncompressed float noise, 64×48
    for (name, seed, n, names) in [
        ("s3", 1, "3", "R,G,B"),
        ("s4", 2, "4", "R,G,B,A"),
        (
            "s5",
            3,
            "5",
            &format!("{combined},ViewLayer.Depth.Z") as &str,
        ),
        ("sR", 4, "1", "R"),
        ("sY", 5, "1", "Y"),
        ("sZ", 6, "1", "Z"),
        ("sYA", 7, "2", "Y,A"),
    ] {
        let pattern = format!("noise:seed={seed}");
        oiio(
            d,
            &[
                "--pattern",
                &pattern,
                "64x48",
                n,
                "--chnames",
                names,
                "-d",
                "float",
                "--compression",
                "none",
                "-o",
                &format!("{name}.exr"),
            ],
        );
    }
    // Changed copies: all channels +2e-4, a 6×4 block +0.02 at (10, 10), one pixel +0.3 at
    // (40, 30); `depth`: only the last channel (Z) of s5
    let change = |src: &str, out: &str, add: [&str; 3]| {
        oiio(
            d,
            &[
                &format!("{src}.exr"),
                "--addc",
                add[1],
                "--cut",
                "6x4+10+10",
                "-o",
                "blk.exr",
            ],
        );
        oiio(
            d,
            &[
                &format!("{src}.exr"),
                "--addc",
                add[2],
                "--cut",
                "1x1+40+30",
                "-o",
                "pix.exr",
            ],
        );
        oiio(
            d,
            &[
                "pix.exr",
                "blk.exr",
                &format!("{src}.exr"),
                "--addc",
                add[0],
                "--paste",
                "+10+10",
                "--paste",
                "+40+30",
                "-d",
                "float",
                "--compression",
                "none",
                "-o",
                &format!("{out}.exr"),
            ],
        );
    };
    for s in ["s3", "s4", "s5", "sR", "sY", "sZ", "sYA"] {
        change(s, &format!("{s}t"), ["2e-4", "0.02", "0.3"]);
    }
    change("s5", "s5z", ["0,0,0,0,2e-4", "0,0,0,0,0.02", "0,0,0,0,0.3"]);

    let mut cases = vec![];
    // `name`: `oiiotool SRC.exr OPS… -o name-ref.EXT` and `SRCt.exr OPS… -o name-test.EXT`
    let mut pair =
        |name: &str, src: &str, test_src: &str, ref_ops: &[&str], test_ops: &[&str], ext: &str| {
            let (a, b) = (format!("{name}-ref.{ext}"), format!("{name}-test.{ext}"));
            let mut args = vec![format!("{src}.exr")];
            args.extend(ref_ops.iter().map(|s| s.to_string()));
            args.extend(["-o".into(), a.clone()]);
            oiio(d, &args.iter().map(String::as_str).collect::<Vec<_>>());
            let mut args = vec![format!("{test_src}.exr")];
            args.extend(test_ops.iter().map(|s| s.to_string()));
            args.extend(["-o".into(), b.clone()]);
            oiio(d, &args.iter().map(String::as_str).collect::<Vec<_>>());
            cases.push(Case::plain(name, d.join(a), d.join(b)));
        };
    let float = ["-d", "float"];
    let half = ["-d", "half"];
    pair("float", "s3", "s3t", &float, &float, "exr");
    pair("half", "s3", "s3t", &half, &half, "exr");
    pair("rgba-half", "s4", "s4t", &half, &half, "exr");
    let tiled = ["-d", "float", "--tile", "16", "16"];
    pair("tiled", "s3", "s3t", &tiled, &tiled, "exr");
    for c in [
        "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab",
    ] {
        // b44 and dwa compress half channels; pxr24 is lossy on float
        let t = if c.starts_with('b') || c.starts_with("dw") {
            "half"
        } else {
            "float"
        };
        let ops = ["-d", t, "--compression", c];
        pair(&format!("comp-{c}"), "s3", "s3t", &ops, &ops, "exr");
        if ["pxr24", "b44", "b44a", "dwaa", "dwab"].contains(&c) {
            // The lossy encoding against its uncompressed source: both tools decode it alike
            pair(
                &format!("lossy-{c}"),
                "s3",
                "s3",
                &["-d", t, "--compression", "none"],
                &ops,
                "exr",
            );
        }
    }
    pair(
        "tiled-piz-rgba",
        "s4",
        "s4t",
        &["-d", "half", "--tile", "32", "16", "--compression", "piz"],
        &["-d", "half", "--tile", "32", "16", "--compression", "piz"],
        "exr",
    );
    pair("single-R", "sR", "sRt", &float, &float, "exr");
    pair("single-Y", "sY", "sYt", &half, &half, "exr");
    pair("single-Z", "sZ", "sZt", &float, &float, "exr");
    pair(
        "png8",
        "s3",
        "s3t",
        &["-d", "uint8"],
        &["-d", "uint8"],
        "png",
    );
    pair(
        "png16",
        "s3",
        "s3t",
        &["-d", "uint16"],
        &["-d", "uint16"],
        "png",
    );
    pair(
        "png8-grey",
        "sY",
        "sYt",
        &["-d", "uint8"],
        &["-d", "uint8"],
        "png",
    );
    pair(
        "png16-grey",
        "sY",
        "sYt",
        &["-d", "uint16"],
        &["-d", "uint16"],
        "png",
    );
    pair(
        "png8-rgba",
        "s4",
        "s4t",
        &["-d", "uint8"],
        &["-d", "uint8"],
        "png",
    );
    pair(
        "png16-rgba",
        "s4",
        "s4t",
        &["-d", "uint16"],
        &["-d", "uint16"],
        "png",
    );
    pair(
        "png8-grey-alpha",
        "sYA",
        "sYAt",
        &["-d", "uint8"],
        &["-d", "uint8"],
        "png",
    );
    // An sRGB chunk (OpenImageIO associates alpha at gamma 1), a gAMA chunk alone (at its gamma)
    let srgb = ["--attrib", "oiio:ColorSpace", "sRGB", "-d", "uint8"];
    pair("png8-rgba-srgb", "s4", "s4t", &srgb, &srgb, "png");
    let g22 = [
        "--attrib",
        "oiio:Gamma",
        "2.2",
        "--attrib",
        "oiio:ColorSpace",
        "Gamma2.2",
        "-d",
        "uint8",
    ];
    pair("png8-rgba-gamma22", "s4", "s4t", &g22, &g22, "png");
    let g18 = [
        "--attrib",
        "oiio:Gamma",
        "1.8",
        "--attrib",
        "oiio:ColorSpace",
        "Gamma1.8",
        "-d",
        "uint16",
    ];
    pair("png16-rgba-gamma18", "s4", "s4t", &g18, &g18, "png");
    // An oFFs chunk: the data window's origin
    let offs = ["--origin", "+8+12", "-d", "uint8"];
    pair("png8-offset", "s3", "s3t", &offs, &offs, "png");
    // Data and display windows
    let origin = ["--origin", "+8+12", "-d", "float"];
    pair("origin", "s3", "s3t", &origin, &origin, "exr");
    let crop = ["--crop", "40x30+8+12", "-d", "float"];
    pair("crop", "s3", "s3t", &crop, &crop, "exr");
    pair("cropref", "s3", "s3t", &crop, &float, "exr");
    pair("croptest", "s3", "s3t", &float, &crop, "exr");
    pair(
        "cropboth",
        "s3",
        "s3t",
        &crop,
        &["--crop", "30x20+20+20", "-d", "float"],
        "exr",
    );
    // Issue 46 (6): data windows far apart in one display window, compared over their union
    // (3000 × 2000 pixels, of which the files hold 2 × 40 × 30) by walking only the pixels
    // the files hold; idiff walks the whole union
    pair(
        "far-apart",
        "s3",
        "s3t",
        &crop,
        &[
            "--crop",
            "40x30+8+12",
            "--origin",
            "+2960+1970",
            "-d",
            "float",
        ],
        "exr",
    );
    pair(
        "png8-far-offset",
        "s3",
        "s3t",
        &offs,
        &["--origin", "+2500-1800", "-d", "uint8"],
        "png",
    );
    let display = ["--fullsize", "80x60-8-6", "-d", "float"];
    pair("display", "s3", "s3t", &display, &display, "exr");
    pair(
        "display-moved",
        "s3",
        "s3t",
        &["--fullsize", "80x60-8-6", "--origin", "-4-3", "-d", "float"],
        &display,
        "exr",
    );
    let overscan = ["--fullsize", "48x32+8+8", "-d", "float"];
    pair("overscan", "s3", "s3t", &overscan, &overscan, "exr");
    pair("displaydiff", "s3", "s3t", &float, &display, "exr");
    pair(
        "rgba-crop-tiled",
        "s4",
        "s4t",
        &["--crop", "40x30+8+12", "-d", "half", "--tile", "16", "16"],
        &["-d", "half", "--compression", "piz"],
        "exr",
    );
    // Multilayer, Blender's channel names: every channel (idiff, --idiff-compat), the Combined
    // layer (rayproof's default), a layer by --layer; the layers alone, made by oiiotool --ch
    pair("multilayer", "s5", "s5t", &float, &float, "exr");
    pair("multilayer-depth", "s5", "s5z", &float, &float, "exr");
    pair(
        "multilayer-half-zip",
        "s5",
        "s5t",
        &["-d", "half", "--compression", "zip"],
        &["-d", "half", "--compression", "zip"],
        "exr",
    );
    let only = |case: &str, layer: &str, channels: &str| -> (PathBuf, PathBuf) {
        let mut out = vec![];
        for side in ["ref", "test"] {
            let f = format!("{case}-{side}.{layer}.exr");
            oiio(
                d,
                &[&format!("{case}-{side}.exr"), "--ch", channels, "-o", &f],
            );
            out.push(d.join(f));
        }
        (out[0].clone(), out[1].clone())
    };
    for c in cases
        .iter_mut()
        .filter(|c| c.name.starts_with("multilayer"))
    {
        let files = only(&c.name, "Combined", combined);
        c.default_files = Some(files);
        c.default_layer = Some("ViewLayer.Combined");
    }
    let mut layered = vec![];
    for (case, layer, short, channels) in [
        ("multilayer", "Depth", "Depth", "ViewLayer.Depth.Z"),
        (
            "multilayer-depth",
            "Depth",
            "ViewLayer.Depth",
            "ViewLayer.Depth.Z",
        ),
        ("multilayer", "Combined", "Combined", combined),
    ] {
        let files = only(case, layer, channels);
        let (a, b) = (
            d.join(format!("{case}-ref.exr")),
            d.join(format!("{case}-test.exr")),
        );
        layered.push(Case {
            name: format!("{case} --layer {short}"),
            a,
            b,
            extra: vec!["--layer".into(), short.into()],
            compat_files: files.clone(),
            default_files: Some(files),
            default_layer: Some(if layer == "Depth" {
                "ViewLayer.Depth"
            } else {
                "ViewLayer.Combined"
            }),
            options: &FILE_OPTIONS,
        });
    }
    cases.extend(layered);
    // A multipart file (idiff compares the first part; rayproof's default takes its first
    // RGB layer, the same part)
    oiio(
        d,
        &["s3.exr", "s4.exr", "--siappend", "-o", "multipart-ref.exr"],
    );
    oiio(
        d,
        &[
            "s3t.exr",
            "s4.exr",
            "--siappend",
            "-o",
            "multipart-test.exr",
        ],
    );
    let mut mp = Case::plain(
        "multipart",
        d.join("multipart-ref.exr"),
        d.join("multipart-test.exr"),
    );
    mp.default_layer = Some("subimage00");
    cases.push(mp);
    // A truncated file: both refuse it (exit 4)
    let full = std::fs::read(d.join("float-test.exr")).unwrap();
    std::fs::write(d.join("truncated-test.exr"), &full[..full.len() / 2]).unwrap();
    cases.push(Case::plain(
        "truncated",
        d.join("float-ref.exr"),
        d.join("truncated-test.exr"),
    ));
    cases
}

#[test]
fn rayproof_diff_agrees_with_the_real_idiff() {
    let (idiff_version, oiiotool_version) = (version("idiff"), version("oiiotool"));
    let d = std::env::temp_dir().join(format!("rayproof-idiff-live-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let mut cases = script_pairs(&d.join("pairs"));
    cases.extend(oiiotool_pairs(&d));

    // Every case × option set: --idiff-compat against idiff, the default semantics against
    // idiff on its files
    let mut bad = vec![];
    let mut table = vec![];
    let (mut runs, mut agree, mut default_checked, mut default_agree) = (0, 0, 0, 0);
    let mut compat_refused = 0;
    let mut at_defaults = std::collections::BTreeMap::new();
    for c in &cases {
        let (mut compat_col, mut default_col) = (String::new(), String::new());
        for &opts in c.options {
            // --idiff-compat
            let theirs = idiff(&d, &c.compat_files.0, &c.compat_files.1, opts);
            let (code, j) = rayproof(&c.a, &c.b, opts, &c.extra, true);
            runs += 1;
            // (with --layer, channels by their name within the layer, as rayproof names them)
            match disagreement(&theirs, code, &j, !c.extra.is_empty()) {
                None => {
                    agree += 1;
                    compat_col.push('=');
                }
                Some(_) if COMPAT_REFUSES.contains(&c.name.as_str()) && code == 4 => {
                    compat_refused += 1;
                    compat_col.push('r');
                }
                Some(why) => {
                    compat_col.push('X');
                    bad.push(format!(
                        "{} {opts:?} --idiff-compat: {why}\n{}",
                        c.name, theirs.stdout
                    ));
                }
            }
            // The default semantics
            let (code, j) = rayproof(&c.a, &c.b, opts, &c.extra, false);
            if opts.is_empty() && c.extra.is_empty() {
                at_defaults.insert(c.name.clone(), (code, theirs.exit));
            }
            let Some((a, b)) = &c.default_files else {
                default_col.push('d');
                continue;
            };
            let theirs = match (a, b) == (&c.compat_files.0, &c.compat_files.1) {
                true => theirs,
                false => idiff(&d, a, b, opts),
            };
            default_checked += 1;
            let mut why = disagreement(&theirs, code, &j, true);
            if let Some(layer) = c.default_layer {
                for k in 0..2 {
                    let got = &j["comparison"]["layers"][k]["name"];
                    if got.as_str() != Some(layer) {
                        why = Some(format!(
                            "{} layer {got} vs {layer}",
                            why.unwrap_or_default()
                        ));
                    }
                }
            }
            match why {
                None => {
                    default_agree += 1;
                    default_col.push(if (a, b) == (&c.a, &c.b) { '=' } else { '~' });
                }
                Some(why) => {
                    default_col.push('X');
                    bad.push(format!("{} {opts:?}: {why}\n{}", c.name, theirs.stdout));
                }
            }
        }
        table.push(format!("{:<42} {compat_col:<14} {default_col}", c.name));
    }

    // The README's table of deliberate differences, row by row, at idiff's defaults
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let rows = readme
        .split("<!-- idiff-differences -->")
        .nth(1)
        .and_then(|s| s.split("<!-- /idiff-differences -->").next())
        .expect("README has the table of deliberate differences");
    let word = |code: i32| match code {
        0 => "PASS".to_string(),
        1 => "WARNING".to_string(),
        2 => "FAILURE".to_string(),
        n => format!("refused (exit {n})"),
    };
    let mut seen = vec![];
    for line in rows.lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        // A row may name several pairs: `a`, `b`
        for pair in cells[1].split(',').map(|p| p.trim().trim_matches('`')) {
            let (ours, theirs) = at_defaults[pair];
            if !cells[3].starts_with(&word(theirs)) {
                bad.push(format!(
                    "README says idiff gives '{}' on {pair}; it gives {}",
                    cells[3],
                    word(theirs)
                ));
            }
            if !cells[4].starts_with(&word(ours)) {
                bad.push(format!(
                    "README says rayproof gives '{}' on {pair}; it gives {}",
                    cells[4],
                    word(ours)
                ));
            }
            seen.push(pair.to_string());
        }
    }
    seen.sort();
    let mut want: Vec<String> = DELIBERATE.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(
        seen, want,
        "the README table lists exactly the deliberate differences"
    );

    // The table
    println!(
        "\nrayproof diff against the real {idiff_version} (files made by oiiotool {oiiotool_version} and scripts/idiff-pairs)"
    );
    println!("one column per option set: = agrees with idiff on the same files; ~ agrees with idiff on the files reduced to the layer rayproof reports; d deliberate difference (README table, checked at the defaults); r refused by rayproof (exit 4) where idiff reads a broken file (README table); X disagrees");
    println!("{:<42} {:<14} default semantics", "pair", "--idiff-compat");
    for row in &table {
        println!("{row}");
    }
    println!(
        "--idiff-compat: {agree} of {runs} runs agree with idiff, {compat_refused} refused (a truncated file); default semantics: {default_agree} of {default_checked} runs agree, {} deliberate (README table: {} pairs, checked)",
        runs - default_checked,
        seen.len()
    );
    let _ = std::fs::remove_dir_all(&d);
    assert!(
        bad.is_empty(),
        "{} disagreements:\n{}",
        bad.len(),
        bad.join("\n")
    );
    assert_eq!(agree + compat_refused, runs);
}

/// `rayproof diff` as a drop-in for idiff (issue 48 item 1): the command lines of render test
/// scripts (Blender's `-fail X -failpercent Y`, OpenUSD's, `-q`, `-v`, `-o FILE -abs`) run
/// unchanged, with idiff's exit code on the same files; the difference image of `-o d.exr
/// -abs` matches idiff's; what rayproof does not do (`-p`, `-a`, `-od`, a signed or scaled or
/// PNG `-o`) and a typo are usage errors, exit 64 with one line, never a verdict's 0-4.
#[test]
fn idiff_command_lines_run_unchanged() {
    version("idiff");
    let d = crate::common::scratch("idiff-drop-in");
    let d = d.as_path();
    oiio(
        d,
        &[
            "--pattern",
            "noise:seed=1",
            "64x48",
            "3",
            "-d",
            "float",
            "-o",
            "a.exr",
        ],
    );
    oiio(
        d,
        &["a.exr", "--addc", "0.005", "-d", "float", "-o", "b.exr"],
    );
    let run = |prog: &str, argv: &[&str]| -> i32 {
        let mut c = if prog == "idiff" {
            Command::new("idiff")
        } else {
            let mut c = Command::new(env!("CARGO_BIN_EXE_rayproof"));
            c.arg("diff");
            c
        };
        c.args(argv)
            .current_dir(d)
            .output()
            .expect("runs")
            .status
            .code()
            .expect("an exit code")
    };
    let lines: [&[&str]; 9] = [
        &["-fail", "0.01", "-failpercent", "1", "a.exr", "b.exr"],
        &["-fail", "0.001", "a.exr", "b.exr"],
        &["-fail", "0.001", "-failpercent", "99.9", "a.exr", "b.exr"],
        &[
            "-warn",
            "0.001",
            "-warnpercent",
            "1",
            "-fail",
            "0.1",
            "a.exr",
            "b.exr",
        ],
        &["-hardfail", "0.004", "-fail", "1", "a.exr", "b.exr"],
        &["-allowfailures", "10000", "-fail", "0", "a.exr", "b.exr"],
        &["-q", "-fail", "0.01", "a.exr", "b.exr"],
        &[
            "-v",
            "-failrelative",
            "0.5",
            "-fail",
            "0.001",
            "a.exr",
            "b.exr",
        ],
        &["a.exr", "b.exr", "-fail", "0.001", "-hardwarn", "0.001"],
    ];
    let mut codes = vec![];
    for argv in lines {
        let (i, r) = (run("idiff", argv), run("rayproof", argv));
        assert_eq!(r, i, "{argv:?}: rayproof {r}, idiff {i}");
        codes.push(i);
    }
    // The lines cover more than one verdict
    codes.sort_unstable();
    codes.dedup();
    assert!(codes.len() >= 2, "{codes:?}");
    // -o d.exr -abs: idiff's difference image, as rayproof writes it
    assert_eq!(run("idiff", &["-o", "d1.exr", "-abs", "a.exr", "b.exr"]), 2);
    assert_eq!(
        run("rayproof", &["-o", "d2.exr", "-abs", "a.exr", "b.exr"]),
        2
    );
    assert_eq!(
        run("rayproof", &["-q", "-fail", "1e-7", "d1.exr", "d2.exr"]),
        0
    );
    // Refused with why, exit 64, one line; nothing written
    for (argv, why) in [
        (&["-p", "a.exr", "b.exr"][..], "-p"),
        (&["-a", "a.exr", "b.exr"], "-a"),
        (&["-od", "-o", "x.exr", "-abs", "a.exr", "b.exr"], "-od"),
        (&["-o", "x.exr", "a.exr", "b.exr"], "-abs"),
        (&["-o", "x.png", "-abs", "a.exr", "b.exr"], "-o x.png"),
        (
            &["-o", "x.exr", "-abs", "-scale", "7", "a.exr", "b.exr"],
            "scaled",
        ),
        (&["--fial", "0.1", "a.exr", "b.exr"], "--fial"),
        (&["-fail"], "-fail"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
            .arg("diff")
            .args(argv)
            .current_dir(d)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(64), "{argv:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{argv:?}: {err}");
        assert!(err.contains(why), "{argv:?}: {err}");
        assert!(!d.join("x.exr").exists() && !d.join("x.png").exists());
    }
}
