//! `rayproof diff` as one library call ([`diff`]): the command line only parses and prints.

use super::{
    abs_diff, abs_error_map, align, compare_as, exr_to, flip_error, heatmap_rgb8, png_rgb8_to,
    read_image_layer, z_test, AlignError, DiffReport, LayerSelect, Semantics, SizeMismatch,
    Thresholds, ZParams, ZTestError,
};
use std::borrow::Cow;
use std::path::Path;

/// What to compare, under which rules, and which files to write.
pub struct DiffRequest<'a> {
    /// Reference image (OpenEXR or PNG).
    pub reference: &'a Path,
    /// Test image.
    pub test: &'a Path,
    /// Per-pixel variance of the test image: the verdict is then the z-test's.
    pub variance: Option<&'a Path>,
    /// The layer of a multilayer EXR to compare (default: see [`LayerSelect`]).
    pub layer: Option<&'a str>,
    /// idiff 2.4's rules exactly (see the README's deliberate differences).
    pub idiff_compat: bool,
    /// idiff's thresholds.
    pub thresholds: Thresholds,
    /// The z-test's settings.
    pub z: ZParams,
    /// Run ꟻLIP.
    pub flip: bool,
    /// Write |REF − TEST| as a float32 EXR.
    pub diff_exr: Option<&'a Path>,
    /// Write a heat map PNG.
    pub heatmap: Option<&'a Path>,
    /// Write the JSON report (`-`: to stdout, instead of the text).
    pub json: Option<&'a Path>,
    /// Only the verdict line on stdout.
    pub quiet: bool,
}

/// A verdict: its exit code (0 PASS, 1 WARNING, 2 FAILURE) and the text for stdout.
pub struct DiffOutcome {
    /// The exit code.
    pub code: u8,
    /// The report, the verdict line, or the JSON.
    pub stdout: String,
}

/// The exit code of a bad command line of `rayproof diff` (sysexits' `EX_USAGE`): never one
/// of the verdicts' 0–4.
pub const EXIT_USAGE: u8 = 64;
/// The exit code of an output `rayproof diff` cannot write (sysexits' `EX_CANTCREAT`).
pub const EXIT_CANNOT_WRITE: u8 = 73;

/// A diff without a verdict: the exit code ([`EXIT_CANNOT_WRITE`] an output that cannot be
/// written, 3 images that do not show one frame, 4 an unreadable input) and why.
#[derive(Debug)]
pub struct DiffError {
    /// The exit code.
    pub code: u8,
    /// Why, naming the file.
    pub message: String,
}

impl DiffError {
    fn new(code: u8, message: String) -> Self {
        DiffError { code, message }
    }
}

/// `rayproof diff` as one call: reads the images (the layer asked for), compares them by idiff's
/// metrics under rayproof's or idiff's rules, runs the z-test and ꟻLIP, writes the files asked
/// for (each checked before any image is read) and returns the verdict's exit code with the text
/// for stdout; what stops it is a [`DiffError`] with its exit code and one line.
pub fn diff(a: &DiffRequest) -> Result<DiffOutcome, DiffError> {
    let t = a.thresholds;
    let json_stdout = a.json == Some(Path::new("-"));

    // Outputs are checked before any work
    let mut inputs = vec![a.reference, a.test];
    inputs.extend(a.variance);
    let json_file = a.json.filter(|_| !json_stdout);
    let files: Vec<&Path> = [a.diff_exr, a.heatmap, json_file]
        .into_iter()
        .flatten()
        .collect();
    crate::output::check_outputs(&files, &[], &inputs)
        .map_err(|e| DiffError::new(EXIT_CANNOT_WRITE, e.to_string()))?;

    // Inputs: the layer asked for (idiff reads every channel)
    let select = match (a.layer, a.idiff_compat) {
        (Some(name), _) => LayerSelect::Named(name),
        (None, true) => LayerSelect::AsIdiff,
        (None, false) => LayerSelect::Default,
    };
    let read = |p: &Path, select| {
        read_image_layer(p, select).map_err(|e| DiffError::new(e.exit_code(), e.to_string()))
    };
    let reference = read(a.reference, select)?;
    let test = read(a.test, select)?;
    // The variance: the same layer as the images (`--layer NAME`: that layer of the variance
    // too, its checks included), else its own default
    let variance = match a.variance {
        Some(v) => Some(read(
            v,
            match select {
                LayerSelect::AsIdiff => LayerSelect::Default,
                s => s,
            },
        )?),
        None => None,
    };
    let (rn, tn) = (a.reference.display(), a.test.display());
    let mismatch = |e: SizeMismatch| DiffError::new(3, format!("{rn} and {tn}: {e}"));

    // Metrics, z-test, ꟻLIP (the last two need images of one shape). Both images over the
    // union of their data windows when they show one frame (rayproof's semantics refuse
    // anything else; idiff's compare anything over the union)
    let semantics = if a.idiff_compat {
        Semantics::Idiff
    } else {
        Semantics::Rayproof
    };
    let c = compare_as(&reference, &test, &t, semantics).map_err(mismatch)?;
    let per_pixel = a.flip || a.heatmap.is_some() || a.diff_exr.is_some() || variance.is_some();
    // Padded to the union only for a per-pixel product: the metrics need no padding (a
    // 1×1 window far from an 8192² one padded both to 16384², 9.45 GB, for plain `diff`)
    let aligned = match per_pixel {
        true => Some(align(&reference, &test)),
        false => None,
    };
    let (reference, test) = match aligned {
        None => (Cow::Borrowed(&reference), Cow::Borrowed(&test)),
        Some(Ok(pair)) => pair,
        // Windows far apart: the metrics above are all there is, unless a map is asked for
        Some(Err(e @ AlignError::FarApart { .. })) => {
            return Err(DiffError::new(3, format!("{rn} and {tn}: {e}")))
        }
        Some(Err(_)) => (Cow::Borrowed(&reference), Cow::Borrowed(&test)),
    };
    let mut c = c;
    let same_shape =
        reference.data_window() == test.data_window() && reference.channels == test.channels;
    // A variance image of the same frame, over the same window (0 outside its data window)
    let variance = variance.map(|v| match v.display == reference.display {
        true => v.padded(reference.data_window()),
        false => v,
    });
    let z = match &variance {
        Some(v) => Some(z_test(&reference, &test, v, &a.z).map_err(|e| {
            let vn = a.variance.unwrap_or(Path::new("")).display();
            match e {
                ZTestError::Size(e) => DiffError::new(
                    3,
                    format!(
                        "{rn} and variance {vn}: {e} (the variance needs the same size and R, G, B)"
                    ),
                ),
                // Like a NaN pixel in an image: a file rayproof cannot judge with (exit 4)
                e => DiffError::new(4, format!("variance {vn}: {e}")),
            }
        })?),
        None => None,
    };
    let flip_map = (a.flip && same_shape).then(|| {
        let (kind, m, map) = flip_error(&reference, &test);
        (c.flip_kind, c.flip_mean) = (Some(kind), Some(m));
        map
    });
    let report = DiffReport {
        reference: a.reference,
        test: a.test,
        display_referred: [reference.display_referred, test.display_referred],
        comparison: &c,
        thresholds: &t,
        ztest: z.as_ref(),
    };
    let verdict = report.verdict();

    // Files: all written, or none replaced
    let (w, h) = (reference.width, reference.height);
    let write_err = |e: anyhow::Error| DiffError::new(EXIT_CANNOT_WRITE, format!("{e:#}"));
    let mut files = crate::output::Outputs::new().reading(&inputs);
    if let Some(p) = a.diff_exr {
        let d = abs_diff(&reference, &test).map_err(mismatch)?;
        files
            .write_with(p, |tmp| exr_to(tmp, &d))
            .map_err(write_err)?;
    }
    if let Some(p) = a.heatmap {
        let map = match flip_map {
            Some(m) => m,
            None => abs_error_map(&reference, &test).map_err(mismatch)?,
        };
        let rgb = heatmap_rgb8(&map, w, h);
        files
            .write_with(p, |tmp| png_rgb8_to(tmp, w, h, &rgb))
            .map_err(write_err)?;
    }
    let mut stdout = String::new();
    if let Some(p) = a.json {
        let text = report.json();
        if json_stdout {
            stdout = text;
        } else {
            files.write(p, text.as_bytes()).map_err(write_err)?;
        }
    }
    files.commit().map_err(write_err)?;

    // Report
    if json_stdout {
    } else if a.quiet {
        // The verdict, and the layer read when a file has layers (a multilayer EXR)
        let layer = report
            .comparison
            .layers
            .iter()
            .flatten()
            .map(|l| l.label())
            .next();
        stdout = match layer {
            Some(l) => format!("{} (layer: {l})\n", verdict.label()),
            None => format!("{}\n", verdict.label()),
        };
    } else {
        stdout = report.text();
        // Asked for and not computed: said, not left out in silence (its map needs one frame
        // and one set of channels; --idiff-compat compares others and fails them)
        // (before the verdict, which stays the last line)
        if a.flip && !same_shape {
            let at = stdout.trim_end().rfind('\n').map_or(0, |i| i + 1);
            stdout.insert_str(
                at,
                "  ꟻLIP: not computed: the images differ in data window or channels\n",
            );
        }
    }
    Ok(DiffOutcome {
        code: verdict.exit_code(),
        stdout,
    })
}
