//! The reports of a comparison: idiff's text report (plus relMSE, ꟻLIP and the z-test) and the
//! JSON document of `rayproof diff`, with C's `%g` for the numbers.

use super::flip::FlipKind;
use super::io::{LayerInfo, LayerPick};
use super::metrics::{Comparison, Semantics, Thresholds, Verdict};
use super::ztest::ZTest;
use std::path::Path;

/// C's `%.{prec}g`: `prec` significant digits, trailing zeros dropped, exponent form when the
/// exponent is < −4 or ≥ `prec`; `inf`, `-inf`, `nan`.
pub fn fmt_g(x: f64, prec: usize) -> String {
    if x.is_nan() {
        return "nan".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf" } else { "-inf" }.into();
    }
    if x == 0.0 {
        return "0".into();
    }
    let p = prec.max(1);
    let sci = format!("{:.*e}", p - 1, x);
    let (mantissa, exp) = sci.split_once('e').expect("exponent");
    let exp: i32 = exp.parse().expect("exponent");
    let trim = |s: &str| -> String {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s.to_string()
        }
    };
    if exp < -4 || exp >= p as i32 {
        let sign = if exp < 0 { '-' } else { '+' };
        format!("{}e{sign}{:02}", trim(mantissa), exp.abs())
    } else {
        trim(&format!("{:.*}", (p as i32 - 1 - exp) as usize, x))
    }
}

/// `%g`: six significant digits.
fn g(x: f64) -> String {
    fmt_g(x, 6)
}

/// Which layer each image was read from, when one is a multilayer EXR: one line if both say
/// the same.
fn layer_lines(ref_name: &str, test_name: &str, c: &Comparison) -> String {
    let describe = |l: &LayerInfo| {
        let why = match l.pick {
            LayerPick::Named => "named by --layer",
            LayerPick::Combined => "the default: a Combined layer",
            LayerPick::FirstRgb => "the default: the one layer with colour channels; none is Combined",
            LayerPick::Every => "the default: every layer (several have colour channels and no single Combined has), as idiff; --layer NAME compares one",
            LayerPick::Only => "the file's only layer",
            LayerPick::All => "as idiff reads them; --layer NAME compares one layer",
        };
        let all: Vec<String> = l
            .layers
            .iter()
            .map(|n| {
                if n.is_empty() {
                    "\"\"".into()
                } else {
                    n.clone()
                }
            })
            .collect();
        (l.label(), format!("{why}; layers: {}", all.join(", ")))
    };
    match &c.layers {
        [None, None] => String::new(),
        [Some(a), Some(b)] if describe(a) == describe(b) => {
            let (name, why) = describe(a);
            format!("  Layer: {name}, in both files ({why})\n")
        }
        [a, b] => {
            let mut s = String::new();
            for (name, l) in [(ref_name, a), (test_name, b)] {
                match l {
                    Some(l) => {
                        let (layer, why) = describe(l);
                        s += &format!("  Layer of {name}: {layer} ({why})\n")
                    }
                    None => s += &format!("  Layer of {name}: its channels (no layers)\n"),
                }
            }
            s
        }
    }
}

/// idiff's report (plus relMSE and ꟻLIP) without the verdict line.
fn report_body(ref_name: &str, test_name: &str, c: &Comparison, t: &Thresholds) -> String {
    let pct = |n: u64| fmt_g(100.0 * n as f64 / c.npels.max(1) as f64, 4);
    let mut s = format!("Comparing \"{ref_name}\" and \"{test_name}\"\n");
    s += &layer_lines(ref_name, test_name, c);
    if c.window != c.display || c.display.x != 0 || c.display.y != 0 {
        s += &format!(
            "  Compared window {} (the union of the data windows; positions are absolute) in display window {}\n",
            c.window, c.display
        );
    }
    s += &format!("  Mean error = {}\n", g(c.mean_error));
    s += &format!("  RMS error = {}\n", g(c.rms_error));
    s += &format!("  Peak SNR = {}\n", g(c.psnr));
    if c.max_error == 0.0 {
        s += "  Max error  = 0\n";
    } else {
        let (x, y, _) = c.max_at;
        s += &format!(
            "  Max error  = {} @ ({x}, {y}, {})  values are {} vs {}\n",
            c.max_error, c.max_channel, c.max_values.0, c.max_values.1
        );
    }
    s += &format!(
        "  {} pixels ({}%) over {}\n",
        c.n_warn,
        pct(c.n_warn),
        g(t.warn)
    );
    s += &format!(
        "  {} pixels ({}%) over {}\n",
        c.n_fail,
        pct(c.n_fail),
        g(t.fail)
    );
    if c.n_nonfinite_mismatch > 0 {
        s += &format!(
            "  {} pixels ({}%) with a NaN/Inf mismatch{}\n",
            c.n_nonfinite_mismatch,
            pct(c.n_nonfinite_mismatch),
            match c.semantics {
                Semantics::Rayproof => {
                    " (counted as failing; idiff 2.4 counts neither a NaN nor the first Inf: --idiff-compat)"
                }
                Semantics::Idiff => " (idiff's rules: --idiff-compat)",
            }
        );
    }
    s += &format!("  relMSE = {}\n", g(c.rel_mse));
    if let (Some(m), Some(k)) = (c.flip_mean, c.flip_kind) {
        let name = if k == FlipKind::Hdr { "HDR" } else { "LDR" };
        s += &format!("  Mean {name}-FLIP = {}\n", g(m));
    }
    s
}

/// idiff's report (plus relMSE and ꟻLIP), ending with the verdict line.
pub fn report_text(ref_name: &str, test_name: &str, c: &Comparison, t: &Thresholds) -> String {
    report_body(ref_name, test_name, c, t) + c.verdict.label() + "\n"
}

/// The z-test's lines of the text report.
fn z_report(z: &ZTest) -> String {
    let (x, y, _) = z.min_p_at;
    let tests = z.pixels * z.channels.len() as u64;
    format!(
        "  z-test (spp {}, significance {}, Šidák alpha = {}):\n    min p-value = {} @ ({x}, {y}, {})\n    {} pixels ({}%) fail; {} of {} channel tests pass, {} needed\n",
        z.params.spp,
        g(z.params.significance),
        g(z.alpha),
        g(z.min_p),
        z.min_p_channel,
        z.failing_pixels,
        fmt_g(100.0 * z.failing_pixels as f64 / z.pixels.max(1) as f64, 4),
        z.passing_channels,
        tests,
        g((z.params.pixel_success_rate * tests as f64).ceil()),
    ) + &if z.beyond_noise > 0 {
        format!(
            "    {} pixels beyond any noise (a NaN/Inf mismatch, or a change in a channel the variance lacks): FAILURE whatever the success rate\n",
            z.beyond_noise
        )
    } else {
        String::new()
    }
}

/// What `rayproof diff` reports about one comparison.
pub struct DiffReport<'a> {
    /// The reference file, as named on the command line.
    pub reference: &'a Path,
    /// The test file, as named on the command line.
    pub test: &'a Path,
    /// Whether the reference and the test are display-referred (PNG).
    pub display_referred: [bool; 2],
    /// The metrics.
    pub comparison: &'a Comparison,
    /// The thresholds applied.
    pub thresholds: &'a Thresholds,
    /// The z-test, when a variance image was given; its verdict then decides.
    pub ztest: Option<&'a ZTest>,
}

impl DiffReport<'_> {
    /// The z-test's verdict if there is one, else idiff's.
    pub fn verdict(&self) -> Verdict {
        self.ztest.map_or(self.comparison.verdict, |z| z.verdict)
    }

    /// The JSON document of `--json`: the inputs, verdict, exit code, comparison, thresholds and
    /// z-test (`null` without one), pretty-printed, ending with a newline.
    pub fn json(&self) -> String {
        let verdict = self.verdict();
        let doc = serde_json::json!({
            "reference": self.reference.display().to_string(),
            "test": self.test.display().to_string(),
            "verdict": verdict,
            "exit_code": verdict.exit_code(),
            "comparison": self.comparison,
            "thresholds": self.thresholds,
            "ztest": self.ztest,
        });
        serde_json::to_string_pretty(&doc).expect("JSON") + "\n"
    }

    /// The text report: a note when one image is display-referred and the other is not, idiff's
    /// report, the z-test (with idiff's own verdict beside it), and the verdict line.
    pub fn text(&self) -> String {
        let (rn, tn) = (self.reference.display(), self.test.display());
        let c = self.comparison;
        // Note a PNG compared with an EXR
        let mut s = String::new();
        let [ref_png, test_png] = self.display_referred;
        if ref_png != test_png {
            let kind = |display_referred: bool| match display_referred {
                true => "display-referred (PNG)",
                false => "scene-linear (EXR)",
            };
            s += &format!(
                "note: {rn} is {} and {tn} is {}; they are compared as stored, without colour conversion\n",
                kind(ref_png),
                kind(test_png)
            );
        }
        // idiff's report, then the z-test, which decides
        s += &report_body(&rn.to_string(), &tn.to_string(), c, self.thresholds);
        if let Some(z) = self.ztest {
            s += &z_report(z);
            s += &format!(
                "  idiff verdict: {} (the z-test decides)\n",
                c.verdict.label()
            );
        }
        // The verdict line
        s += self.verdict().label();
        s += "\n";
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fmt_g_matches_c() {
        // printf("%g") of each value
        let cases = [
            (1e-6, "1e-06"),
            (0.0001, "0.0001"),
            (0.00012345678, "0.000123457"),
            (123456.0, "123456"),
            (1234567.0, "1.23457e+06"),
            (0.5, "0.5"),
            (33.979400086720375, "33.9794"),
            (100.0, "100"),
            (-2.5e-7, "-2.5e-07"),
        ];
        for (x, want) in cases {
            assert_eq!(fmt_g(x, 6), want, "{x}");
        }
        assert_eq!(fmt_g(18.75, 4), "18.75");
        assert_eq!(fmt_g(100.0 / 3.0, 4), "33.33");
        assert_eq!(fmt_g(f64::INFINITY, 6), "inf");
        assert_eq!(fmt_g(0.0, 6), "0");
    }
}
