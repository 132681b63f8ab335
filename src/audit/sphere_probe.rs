//! `rayproof probe sphere`: one case, the oracle's full answer and every method's.

use crate::numerics::real::Real;
use crate::numerics::Precision;
use crate::shapes::sphere::methods::{PickPrecision, METHODS};
use crate::shapes::sphere::oracle::{self, Case, Verdict};
use crate::shapes::sphere::{run_case, Judgement};
use anyhow::{anyhow, Result};
use serde_json::{json, Value};

/// Significant digits of the oracle's decimal roots.
const DIGITS: usize = 45;

/// Runs the probe; returns the text or JSON to print.
pub fn sphere(
    o: &[String; 3],
    d: &[String; 3],
    c: &[String; 3],
    r: &str,
    prec: Precision,
    as_json: bool,
) -> Result<String> {
    match prec {
        Precision::F32 => probe_in::<f32>(o, d, c, r, as_json),
        Precision::F64 => probe_in::<f64>(o, d, c, r, as_json),
    }
}

fn parse3<F: Real>(v: &[String; 3], what: &str) -> Result<[F; 3]> {
    let p = |s: &String| {
        F::parse(s).ok_or_else(|| anyhow!("--{what}: '{s}' is not a number in {}", F::NAME))
    };
    Ok([p(&v[0])?, p(&v[1])?, p(&v[2])?])
}

fn probe_in<F: PickPrecision>(
    o: &[String; 3],
    d: &[String; 3],
    c: &[String; 3],
    r: &str,
    as_json: bool,
) -> Result<String> {
    let case = Case::<F> {
        o: parse3(o, "origin")?,
        d: parse3(d, "dir")?,
        c: parse3(c, "center")?,
        r: F::parse(r).ok_or_else(|| anyhow!("--radius: '{r}' is not a number in {}", F::NAME))?,
    };
    let methods: Vec<_> = METHODS.iter().collect();
    let (truth, rows) = run_case(&case, &methods);
    let roots = oracle::roots_decimal(&case, DIGITS);
    let t_dec = match truth.verdict {
        Verdict::Near => roots.first().cloned(),
        Verdict::Far => roots.get(1).cloned(),
        _ => None,
    };
    let results: Vec<Value> = rows
        .iter()
        .map(|(name, hit, j)| {
            let ulps = match j {
                Judgement::Ok { ulps } => *ulps,
                _ => None,
            };
            json!({
                "method": name,
                "hit": hit.is_some(),
                "t": hit.map(|h| h.t.hex()),
                "ulp_error": ulps,
                "verdict": j.verdict_word(),
                "finding": match j {
                    Judgement::Rejected => Some("rejected"),
                    Judgement::InvalidNanT => Some("nan_t"),
                    Judgement::InvalidHit => Some("hit_on_invalid"),
                    Judgement::NonfiniteT => Some("nonfinite_t"),
                    _ => None,
                },
                "enclosure": hit.and_then(|h| h.enclosure).map(|e| [e[0].hex(), e[1].hex()]),
                "residual_ulps": match j {
                    Judgement::Ok { ulps: Some(_) } => hit.map(|h| oracle::residual_ulps(&case, h.t)),
                    _ => None,
                },
            })
        })
        .collect();
    let v = json!({
        "precision": F::NAME,
        "inputs": {
            "origin": case.o.map(|x| x.hex()),
            "dir": case.d.map(|x| x.hex()),
            "center": case.c.map(|x| x.hex()),
            "radius": case.r.hex(),
        },
        "oracle": {
            "valid": truth.verdict != Verdict::Invalid,
            "hit": truth.verdict.is_hit(),
            "verdict": truth.verdict,
            "roots": roots,
            "t": t_dec,
            "t_f32": truth.t_f32.map(|t| t.hex()),
            "t_f64": truth.t_f64.map(|t| t.hex()),
            "ill_posed": truth.ill_posed,
            "prec_bits": truth.prec,
            "cap_reached": truth.cap_reached,
        },
        "results": results,
    });
    if as_json {
        return Ok(serde_json::to_string_pretty(&v)? + "\n");
    }
    // Text form
    let mut out = format!("precision {}\n{}\n", F::NAME, case.probe_args());
    out += &format!(
        "oracle: {:?}{}\n",
        truth.verdict,
        if truth.ill_posed {
            " (ill-posed: a 1-ulp input change flips the verdict)"
        } else {
            ""
        }
    );
    for (i, root) in roots.iter().enumerate() {
        out += &format!("  root t{} = {root}\n", i + 1);
    }
    if let (Some(a), Some(b)) = (truth.t_f32, truth.t_f64) {
        out += &format!("  t (f32) = {}   t (f64) = {}\n", a.hex(), b.hex());
    }
    for (name, hit, j) in &rows {
        let t = hit
            .map(|h| format!("{} ({:e})", h.t.hex(), h.t.to_f64()))
            .unwrap_or_else(|| "miss".into());
        let u = match j {
            Judgement::Ok { ulps: Some(u) } => format!(", {u} ulps"),
            _ => String::new(),
        };
        out += &format!("  {name:<12} {t:<40} {}{u}\n", j.verdict_word());
    }
    Ok(out)
}
