//! The HTML report of `rayproof check`.

use super::rows::{counts, Row, Status};

/// Escapes text for HTML content and attribute values.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&#39;")
}

/// A file name as a relative URL: every byte but `A-Z a-z 0-9 - _ . ~` percent-encoded (a
/// reference's name may hold a space, `#` or `?`).
fn url(name: &str) -> String {
    name.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => {
                (b as char).to_string()
            }
            b => format!("%{b:02X}"),
        })
        .collect()
}

/// The HTML report in the style of Blender's render report: one row per scene × reference,
/// failures first; hovering over the new render shows the reference and vice versa. Beside
/// them, the views that show where the images differ however small the difference: the failing
/// pixels (red over the dimmed test image), the |difference| normalised to its maximum (whose
/// value the page prints: a 1e-6 change fills the colour scale) and the ꟻLIP heat map; the
/// largest difference is ringed on the first two. The header gives the run's counts as the
/// terminal does (`2 failing, 1 refused`).
pub fn html(rows: &[Row], title: &str, platform: Option<&str>) -> String {
    let title = esc(title);
    let platform = platform
        .map(|p| format!(" Platform: <b>{}</b>.", esc(p)))
        .unwrap_or_default();
    let mut body = String::new();
    for r in rows {
        body += &row(r);
    }
    format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{title}</title><style>\n\
         body {{ font-family: sans-serif; margin: 1em; }}\n\
         table {{ border-collapse: collapse; }}\n\
         td, th {{ border: 1px solid #ccc; padding: 4px; vertical-align: top; }}\n\
         img {{ width: 200px; display: block; image-rendering: pixelated; background: repeating-conic-gradient(#ddd 0 25%, #fff 0 50%) 0 0 / 16px 16px; }}\n\
         .pic {{ position: relative; display: inline-block; }}\n\
         .max {{ position: absolute; width: 14px; height: 14px; margin: -9px 0 0 -9px; border: 2px solid #0f0; border-radius: 50%; box-shadow: 0 0 0 1px #000; pointer-events: none; }}\n\
         small.cap {{ display: block; max-width: 200px; }}\n\
         tr.fail {{ background: #f8d7da; }} tr.warn {{ background: #fff3cd; }} tr.xfail {{ background: #e2e3e5; }}\n\
         td.m {{ font-family: monospace; font-size: 90%; }} small.w {{ color: #8a5a00; }}\n\
         td:first-child {{ max-width: 22em; overflow-wrap: anywhere; }}\n\
         </style></head><body>\n<h1>{title}</h1>\n<p class=\"counts\">{} comparisons: {}.{platform}</p>\n\
         <p>Hover over an image to swap new and reference. Failing pixels: red where the comparison \
         counts a pixel over <code>fail</code> (or, when a z-test decides, where it fails), over the new render in grey. |New − Reference|: \
         the largest channel difference per pixel, black 0 to pale yellow at the maximum printed \
         below it, cyan for NaN/Inf mismatches. The green ring marks the maximum. ꟻLIP: the \
         perceptual error (magma). A test's mask, under its failing pixels: striped magenta where \
         pixels are left out, blue where their tolerance is scaled.</p>\n\
         <table>\n<tr><th>Name</th><th>New</th><th>Reference</th><th>Failing pixels</th>\
         <th>|New − Reference|</th><th>Diff (ꟻLIP)</th><th>Metrics</th></tr>\n{body}</table>\n</body></html>\n",
        rows.len(),
        counts(rows)
    )
}

/// One table row: name and status, the five images, the metrics.
fn row(r: &Row) -> String {
    let class = match r.status {
        s if s.is_failure() => "fail",
        Status::Warning => "warn",
        Status::KnownFailure => "xfail",
        _ => "pass",
    };
    let c = r.comparison.as_ref();
    // The ring on the largest difference, in percent of the image
    let ring = match c {
        Some(c) if c.max_error > 0.0 && c.width > 0 && c.height > 0 => format!(
            "<span class=\"max\" style=\"left: {:.3}%; top: {:.3}%\" title=\"max at ({}, {})\"></span>",
            100.0 * (c.max_at.0 as f64 + 0.5) / c.width as f64,
            100.0 * (c.max_at.1 as f64 + 0.5) / c.height as f64,
            c.max_at.0,
            c.max_at.1
        ),
        _ => String::new(),
    };
    let imgs = match (&r.images, c) {
        (Some(i), Some(c)) => {
            // URL-encoded names hold no quote: safe inside the handlers' strings too
            let (new, reference) = (url(&i.new), url(&i.reference));
            let masked = match (&i.masked, r.mask) {
                (Some(m), Some(n)) => format!(
                    "<img class=\"masked\" src=\"{}\"><small class=\"cap\">mask: {} px left out, {} px at scaled tolerance</small>",
                    url(m),
                    n.excluded,
                    n.scaled
                ),
                _ => String::new(),
            };
            let scale = if i.diff_scale > 0.0 {
                format!("scale: pale yellow = {:.3e} (max |d|)", i.diff_scale)
            } else if c.n_nonfinite_mismatch > 0 {
                "no finite difference; cyan: NaN/Inf mismatch".to_string()
            } else {
                "identical: no difference".to_string()
            };
            format!(
                "<td><img class=\"new\" src=\"{new}\" onmouseover=\"this.src='{reference}'\" onmouseout=\"this.src='{new}'\"></td>\
                 <td><img class=\"reference\" src=\"{reference}\" onmouseover=\"this.src='{new}'\" onmouseout=\"this.src='{reference}'\"></td>\
                 <td><div class=\"pic\"><img class=\"mask\" src=\"{}\">{ring}</div><small class=\"cap\">{}</small>{masked}</td>\
                 <td><div class=\"pic\"><img class=\"diff\" src=\"{}\">{ring}</div><small class=\"cap\">{scale}</small></td>\
                 <td><img class=\"flip\" src=\"{}\"></td>",
                url(&i.mask),
                match &r.ztest {
                    Some(_) => format!("{} px fail the z-test (it decides)", i.mask_pixels),
                    None => format!("{} px over fail {}", i.mask_pixels, r.rule.idiff.fail),
                },
                url(&i.diff),
                url(&i.flip),
            )
        }
        _ => "<td colspan=\"5\"><small>no images: nothing was compared</small></td>".into(),
    };
    let metrics = match c {
        Some(c) => format!(
            "mean {:.3e}<br>RMS {:.3e}<br>PSNR {:.1} dB<br>{}<br>{} px ({:.3} %) &gt; {}<br>{} px &gt; warn {}<br>{} {}",
            c.mean_error,
            c.rms_error,
            c.psnr,
            // No position for a maximum of 0: there is no largest difference to point at
            if c.max_error == 0.0 && c.n_nonfinite_mismatch == 0 {
                "max 0 (identical)".to_string()
            } else {
                format!(
                    "max {:.3e} @ ({}, {}, {})",
                    c.max_error,
                    c.max_at.0,
                    c.max_at.1,
                    esc(&c.max_channel)
                )
            },
            c.n_fail,
            100.0 * c.n_fail as f64 / c.pixels.max(1) as f64,
            r.rule.idiff.fail,
            c.n_warn,
            r.rule.idiff.warn,
            match c.flip_kind {
                Some(crate::images::FlipKind::Ldr) => "LDR-ꟻLIP",
                _ => "HDR-ꟻLIP",
            },
            c.flip_mean.map(|v| format!("{v:.4}")).unwrap_or("-".into())
        ),
        None => "-".into(),
    };
    // The name cell: no empty parentheses or lines for what a row does not have
    let mut name = format!("<b>{}</b><br>vs {}", esc(&r.test), esc(&r.reference));
    if !r.renderer.is_empty() {
        name += &format!(" ({})", esc(&r.renderer));
    }
    if !r.config.is_empty() {
        name += &format!("<br>{}", esc(&r.config));
    }
    name += &format!("<br><b>{}</b>", r.status.label());
    if !r.note.is_empty() {
        name += &format!("<br><small>{}</small>", esc(&r.note));
    }
    for w in &r.warnings {
        name += &format!("<br><small class=\"w\">warning: {}</small>", esc(w));
    }
    if let Some(l) = &r.log {
        name += &format!("<br><a href=\"{}\">renderer log</a>", esc(l));
    }
    let mut metrics = metrics;
    if let Some(z) = &r.ztest {
        let worst = z.shift_z.iter().fold(0f64, |m, v| m.max(v.abs()));
        metrics += &format!(
            "<br>z-test: {} px fail at α {:.1e}<br>mean shift {worst:.1} σ (limit {:.1e})",
            z.failing_pixels, z.alpha, z.shift_alpha
        );
    }
    format!(
        "<tr class=\"{class}\" id=\"{}\"><td>{name}</td>{imgs}<td class=\"m\">{metrics}</td></tr>\n",
        super::ci::anchor(r)
    )
}
