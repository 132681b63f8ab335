//! `rayproof diff REF TEST`: the command line of the image comparison in [`rayproof::images`].
//!
//! Exit codes of `rayproof diff`:
//! - 0: PASS
//! - 1: WARNING
//! - 2: FAILURE
//! - 64 ([`EXIT_USAGE`]): bad usage, never a verdict's code (an unknown option, a bad value, an
//!   idiff option rayproof refuses: a CI must tell a typo from a regression)
//! - 73 ([`EXIT_CANNOT_WRITE`]): an output directory that does not exist, an output that
//!   cannot be written or is an input
//! - 3: the images, or the variance image, differ in display window, channels or layer
//!   (`--idiff-compat` compares them over the union of their data windows as idiff does; then
//!   only `--diff-exr` and `--variance` need them to show one frame)
//! - 4: an input file is unreadable: missing, empty, truncated, corrupt, not OpenEXR/PNG, over
//!   a limit; or it has no layer `--layer` names, or several layers and none the default takes
//!
//! Errors are one line on stderr, `error: …`, naming the file.
//!
//! The comparison, the files and the verdict are one library call, [`rayproof::images::diff::diff`].

use super::emit;
pub use rayproof::images::diff::EXIT_USAGE;
use rayproof::images::diff::{diff, DiffRequest};
use rayproof::images::{one_line, Thresholds, ZParams};
use std::ffi::OsString;
use std::io::Write;
use std::path::PathBuf;

fn parse_threshold(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a non-negative number (inf allowed)")),
    }
}

fn parse_unit_open(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v < 1.0 => Ok(v),
        _ => Err(format!("'{s}' is not a number strictly between 0 and 1")),
    }
}

fn parse_unit_closed(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not a number between 0 and 1")),
    }
}

/// `rayproof diff`: compare two images (OpenEXR or PNG) like OpenImageIO's idiff, which it
/// replaces on a command line: idiff's single-dash spellings are taken (`-fail 0.01`, `-q`,
/// `-o diff.exr -abs`; README, "rayproof diff for idiff").
///
/// Exit codes: 0 PASS, 1 WARNING, 2 FAILURE, 3 size, channel or layer mismatch, 4 unreadable
/// input (or no such layer), 64 bad usage, 73 an output that cannot be written.
#[derive(clap::Args, Debug, Clone)]
pub struct DiffArgs {
    /// Reference image (OpenEXR or PNG, recognised by content).
    pub reference: PathBuf,
    /// Test image.
    pub test: PathBuf,
    /// A pixel fails if some channel differs by more than this…
    #[arg(long, default_value_t = 1e-6, value_parser = parse_threshold)]
    pub fail: f64,
    /// …and by more than this relative to the mean of the two |values|.
    #[arg(long, default_value_t = 0.0, value_parser = parse_threshold)]
    pub failrelative: f64,
    /// FAILURE needs more than this percentage of pixels to fail.
    #[arg(long, default_value_t = 0.0, value_parser = parse_threshold)]
    pub failpercent: f64,
    /// FAILURE if the max error exceeds this, however few pixels fail.
    #[arg(long, default_value_t = f64::INFINITY, value_parser = parse_threshold)]
    pub hardfail: f64,
    /// PASS if at most this many pixels fail (overrides everything else).
    #[arg(long, default_value_t = 0)]
    pub allowfailures: u64,
    /// A pixel warns if some channel differs by more than this…
    #[arg(long, default_value_t = 1e-6, value_parser = parse_threshold)]
    pub warn: f64,
    /// …and by more than this relative to the mean of the two |values|.
    #[arg(long, default_value_t = 0.0, value_parser = parse_threshold)]
    pub warnrelative: f64,
    /// WARNING needs more than this percentage of pixels to warn.
    #[arg(long, default_value_t = 0.0, value_parser = parse_threshold)]
    pub warnpercent: f64,
    /// WARNING if the max error exceeds this.
    #[arg(long, default_value_t = f64::INFINITY, value_parser = parse_threshold)]
    pub hardwarn: f64,
    /// Write |REF − TEST| per channel as a float32 EXR (always, even if identical).
    #[arg(long, value_name = "FILE")]
    pub diff_exr: Option<PathBuf>,
    /// Write a magma heat map PNG of the ꟻLIP error (with --no-flip: of the largest channel
    /// |REF − TEST| × 16, clamped).
    #[arg(long, value_name = "FILE.png")]
    pub heatmap: Option<PathBuf>,
    /// Compute HDR-ꟻLIP (LDR-ꟻLIP for two PNGs) and print its mean; by default it is computed
    /// only for --heatmap (it costs several times the metrics).
    #[arg(long, conflicts_with = "no_flip")]
    pub flip: bool,
    /// Never compute ꟻLIP (a --heatmap then shows |REF − TEST| × 16).
    #[arg(long)]
    pub no_flip: bool,
    /// Write the metrics, thresholds and z-test as JSON ('-': stdout, instead of the text).
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Noise-aware mode: per-pixel variance of the test image (EXR); the verdict is then the
    /// z-test's (PASS or FAILURE).
    #[arg(long, value_name = "VAR.exr")]
    pub variance: Option<PathBuf>,
    /// Samples per pixel of the test image [default: 1]; with N > 1 the variance image is
    /// the per-sample variance, with 1 the variance of the pixel mean.
    #[arg(long, requires = "variance", value_parser = clap::value_parser!(u64).range(1..))]
    pub spp: Option<u64>,
    /// Family-wise significance of the z-test, Šidák-corrected over pixels [default: 0.01].
    #[arg(long, requires = "variance", value_parser = parse_unit_open)]
    pub significance: Option<f64>,
    /// Fraction of pixels that must pass the z-test [default: 0.9975].
    #[arg(long, requires = "variance", value_parser = parse_unit_closed)]
    pub pixel_success_rate: Option<f64>,
    /// The layer of a multilayer EXR to compare, in both images (`ViewLayer.Combined`, or its
    /// end when one layer ends so: `Combined`, `Depth`; "" for the channels without a layer
    /// name). Default: a Combined layer, else the first with R, G, B, else the only one; with
    /// --idiff-compat, every channel as idiff. The report says which layer was read.
    #[arg(long, value_name = "NAME")]
    pub layer: Option<String>,
    /// Print only the verdict line.
    #[arg(short, long)]
    pub quiet: bool,
    /// idiff 2.4's rules exactly, where rayproof is deliberately stricter: a NaN/Inf mismatch
    /// only sets the max error the first time (the next ones make mean, RMS and PSNR inf or
    /// nan), any infinity matches any infinity, images of different size, display window or
    /// channels are compared over the union of their data windows, missing values read as 0,
    /// percentages are of the reference's data window, and an EXR's every channel is compared
    /// unless --layer names one (README: deliberate differences).
    #[arg(long)]
    pub idiff_compat: bool,
}

impl DiffArgs {
    /// The idiff thresholds given on the command line.
    pub fn thresholds(&self) -> Thresholds {
        Thresholds {
            fail: self.fail,
            failrelative: self.failrelative,
            failpercent: self.failpercent,
            hardfail: self.hardfail,
            allowfailures: self.allowfailures,
            warn: self.warn,
            warnrelative: self.warnrelative,
            warnpercent: self.warnpercent,
            hardwarn: self.hardwarn,
        }
    }

    /// The z-test settings given on the command line.
    pub fn z_params(&self) -> ZParams {
        let d = ZParams::default();
        ZParams {
            spp: self.spp.unwrap_or(d.spp),
            significance: self.significance.unwrap_or(d.significance),
            pixel_success_rate: self.pixel_success_rate.unwrap_or(d.pixel_success_rate),
            ..d
        }
    }
}

/// Runs `rayproof diff`: prints the report (or only the verdict, or the JSON), writes the
/// requested files, and returns the exit code; errors are printed as one line on stderr.
pub fn run_diff(a: DiffArgs) -> u8 {
    let request = DiffRequest {
        reference: &a.reference,
        test: &a.test,
        variance: a.variance.as_deref(),
        layer: a.layer.as_deref(),
        idiff_compat: a.idiff_compat,
        thresholds: a.thresholds(),
        z: a.z_params(),
        flip: a.flip || (a.heatmap.is_some() && !a.no_flip),
        diff_exr: a.diff_exr.as_deref(),
        heatmap: a.heatmap.as_deref(),
        json: a.json.as_deref(),
        quiet: a.quiet,
    };
    match diff(&request) {
        Ok(out) => {
            say_raw!("{}", out.stdout);
            out.code
        }
        Err(e) => {
            let _ = writeln!(std::io::stderr(), "error: {}", one_line(&e.message));
            e.code
        }
    }
}

/// idiff's options that take a value and are rayproof's own with two dashes.
const IDIFF_VALUED: [&str; 9] = [
    "fail",
    "failrelative",
    "failpercent",
    "hardfail",
    "allowfailures",
    "warn",
    "warnrelative",
    "warnpercent",
    "hardwarn",
];

/// The command line with idiff's spellings of `rayproof diff` made rayproof's: `-fail X` …
/// `-hardwarn X` become `--fail X` …, `-v` is dropped (the full report is the default), `-o
/// FILE -abs` (with `-scale 1`) becomes `--diff-exr FILE` for an `.exr`; what rayproof does
/// not do is refused with why (an error line, exit [`EXIT_USAGE`]). Any other command line is
/// returned as it is.
pub fn idiff_spellings(args: Vec<OsString>) -> Result<Vec<OsString>, String> {
    if args.get(1).and_then(|a| a.to_str()) != Some("diff") {
        return Ok(args);
    }
    let mut out: Vec<OsString> = args[..2].to_vec();
    let (mut o, mut abs, mut scale) = (None::<OsString>, false, None::<String>);
    let mut it = args.into_iter().skip(2);
    let value = |it: &mut dyn Iterator<Item = OsString>, opt: &str| {
        it.next()
            .ok_or_else(|| format!("error: idiff's -{opt} takes a value"))
    };
    while let Some(a) = it.next() {
        let Some(text) = a.to_str() else {
            out.push(a);
            continue;
        };
        // After `--` everything is a file
        if text == "--" {
            out.push(a);
            out.extend(it.by_ref());
            break;
        }
        let Some(name) = text.strip_prefix('-').filter(|n| !n.starts_with('-')) else {
            out.push(a);
            continue;
        };
        match name {
            n if IDIFF_VALUED.contains(&n) => {
                out.push(format!("--{n}").into());
                out.push(value(&mut it, n)?);
            }
            "v" => {}
            "o" => o = Some(value(&mut it, "o")?),
            "abs" => abs = true,
            "scale" => scale = Some(value(&mut it, "scale")?.to_string_lossy().into_owned()),
            "od" => return Err("error: idiff's -od (write the difference image only when the images differ) is not supported: rayproof writes it whenever asked (-o FILE -abs, or --diff-exr FILE)".into()),
            "p" => return Err("error: idiff's -p (Yee's perceptual test) is not supported: rayproof's perceptual metric is HDR-ꟻLIP (--flip, and max_flip in a suite)".into()),
            "a" => return Err("error: idiff's -a (every subimage and MIP level) is not supported: rayproof compares one part and layer (--layer NAME)".into()),
            _ => out.push(a),
        }
    }
    if let Some(file) = o {
        let scale_one = scale
            .as_deref()
            .is_none_or(|x| x.trim().parse::<f64>() == Ok(1.0));
        let exr = file
            .to_string_lossy()
            .to_ascii_lowercase()
            .ends_with(".exr");
        if !abs || !scale_one || !exr {
            return Err(format!(
                "error: idiff's -o {} is supported as -o FILE.exr -abs (|REF - TEST| as float EXR, --diff-exr); rayproof writes no signed or scaled difference and no other format (for a picture of the difference: --heatmap FILE.png)",
                file.to_string_lossy()
            ));
        }
        out.push("--diff-exr".into());
        out.push(file);
    } else if abs || scale.is_some() {
        return Err("error: idiff's -abs and -scale go with -o FILE".into());
    }
    Ok(out)
}
