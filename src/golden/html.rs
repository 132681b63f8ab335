//! The HTML report of `rayproof check`.

use super::rows::{Row, Status};

/// The HTML report in the style of Blender's render report: one row per scene × reference,
/// failures first; hovering over the new render shows the reference and vice versa.
pub fn html(rows: &[Row], title: &str) -> String {
    let esc = |s: &str| {
        s.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;")
    };
    // One table row per comparison: name and status, the three images, the metrics
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
        let warnings: String = r
            .warnings
            .iter()
            .map(|w| format!("<br><small class=\"w\">warning: {}</small>", esc(w)))
            .collect();
        let log = r
            .log
            .as_ref()
            .map(|l| format!("<br><a href=\"{}\">renderer log</a>", esc(l)))
            .unwrap_or_default();
        body += &format!(
            "<tr class=\"{class}\"><td><b>{}</b><br>vs {} ({})<br>{}<br><b>{}</b><br><small>{}</small>{warnings}{log}</td>{imgs}<td class=\"m\">{metrics}</td></tr>\n",
            esc(&r.test),
            esc(&r.reference),
            esc(&r.renderer),
            esc(&r.config),
            r.status.label(),
            esc(&r.note)
        );
    }
    // The page around the table
    let failed = rows.iter().filter(|r| r.status.is_failure()).count();
    format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{title}</title><style>\n\
         body {{ font-family: sans-serif; margin: 1em; }}\n\
         table {{ border-collapse: collapse; }}\n\
         td, th {{ border: 1px solid #ccc; padding: 4px; vertical-align: top; }}\n\
         img {{ width: 256px; image-rendering: pixelated; background: repeating-conic-gradient(#ddd 0 25%, #fff 0 50%) 0 0 / 16px 16px; }}\n\
         tr.fail {{ background: #f8d7da; }} tr.warn {{ background: #fff3cd; }} tr.xfail {{ background: #e2e3e5; }}\n\
         td.m {{ font-family: monospace; font-size: 90%; }} small.w {{ color: #8a5a00; }}\n\
         </style></head><body>\n<h1>{title}</h1>\n<p>{} comparisons, {failed} failing. Hover over an image to swap new and reference. \
         Heat map: HDR-ꟻLIP error (magma).</p>\n<table>\n<tr><th>Name</th><th>New</th><th>Reference</th><th>Diff (ꟻLIP)</th><th>Metrics</th></tr>\n{body}</table>\n</body></html>\n",
        rows.len()
    )
}
