//! `rayproof probe SHAPE --precision P -- VALUES…`: the oracle and every method on one case,
//! as text or JSON. Every worst case of an audit prints the line that replays it here.
//!
//! ```sh
//! cargo run --release -- probe sphere --precision f32 --json -- \
//!     0x1p+0 -1 0  1 0 0  0x1p+20 -1 0  0x1p-3
//! ```
//!
//! One probe serves every shape: `probe SHAPE --precision P [--json] -- VALUES…` with the shape's
//! inputs in order (`probe SHAPE --help` names them; for the sphere `ox oy oz dx dy dz cx cy cz r`).
//! Numbers may be decimal or C99 hex floats, each rounded once to the precision. It prints the
//! oracle's verdict and correctly rounded values, whether the case is ill-posed, the shape's own
//! detail (for the sphere, both exact roots to 45 significant digits and `t` in f32 and f64), and
//! each method's values, verdict (`ok`, `false_hit`, `false_miss`, `wrong_root`, `nonfinite_t`,
//! `invalid`), error in ulps, residual and enclosure. Every worst case in an audit prints its probe
//! line. In the case above, the sphere is 2^20 away with radius 1/8: in f32 `algebraic` and the
//! conservative `interval` report a false miss, `geometric` and `press` hit 2 ulps off, and
//! `hearn_baker`, `rtg7` and `promote` return the correctly rounded root.
//!
//! An outside routine replays with it too: `rayproof probe … --exec CMD --name N -- …` or
//! `rayproof probe … --plugin PATH:SYMBOL:f32 --name N -- …` (see [`super::exec`],
//! [`super::plugin`]).

use super::contract;
use super::judge::Judgement;
use super::run::judge_all;
use crate::numerics::Precision;
use crate::shapes::shape::{hex_text, Answer, Method, Shape, Truth};
use serde_json::{json, Value};

/// Parses probe values (decimal or hex, each rounded once to the precision).
pub fn parse_values(
    shape: &dyn Shape,
    prec: Precision,
    text: &[String],
) -> Result<Vec<f64>, String> {
    let info = shape.info();
    if text.len() != info.args.len() {
        return Err(format!(
            "probe {} takes {} values ({}), got {}",
            info.name,
            info.args.len(),
            info.args.join(" "),
            text.len()
        ));
    }
    text.iter()
        .zip(info.args)
        .map(|(s, name)| {
            crate::numerics::real::parse_number_in(s, prec.name())
                .map_err(|e| format!("{name}: {e}"))
        })
        .collect()
}

/// The probe's answer as a JSON value.
pub fn probe_json(
    shape: &dyn Shape,
    methods: &[&dyn Method],
    prec: Precision,
    input: &[f64],
) -> Result<Value, String> {
    let info = shape.info();
    let (truth, samples) = judge_all(shape, methods, input, prec)?;
    // The oracle's side
    let hex = |v: &[f64]| v.iter().map(|&x| hex_text(x)).collect::<Vec<_>>();
    let oracle = match &truth {
        Truth::Invalid => {
            json!({ "verdict": "invalid", "count": 0, "values": [], "ill_posed": false, "cap_reached": false })
        }
        Truth::Answer(e) => json!({
            "verdict": if e.count == 0 { "miss".to_string() } else { format!("count {}", e.count) },
            "count": e.count,
            "values": hex(&e.values),
            "ill_posed": e.ill_posed,
            "cap_reached": e.cap_reached,
            "value_f64": e.value_f64.map(hex_text),
            "cond_ulps": e.cond,
        }),
    };
    let detail: Vec<Value> = shape
        .oracle_detail(input, prec)
        .into_iter()
        .map(|(k, v)| json!({ "name": k, "value": v }))
        .collect();
    // Every method's side
    let rows: Vec<Value> = methods
        .iter()
        .zip(&samples)
        .map(|(m, s)| {
            json!({
                "method": m.name(),
                "robust": m.robust(),
                "count": s.count,
                "values": hex(&s.values),
                "judgement": s.judgement.verdict_word(),
                "finding": match s.judgement {
                    Judgement::Rejected => Some("rejected".to_string()),
                    Judgement::InvalidNanT => Some("nan_value".to_string()),
                    Judgement::InvalidHit => Some("hit_on_invalid".to_string()),
                    Judgement::NonfiniteT => Some("nonfinite_value".to_string()),
                    Judgement::OutOfRange => Some(contract::interval(info).to_string()),
                    Judgement::Malformed => contract::malformed(
                        info,
                        &Answer { count: s.count, values: s.values.clone(), enclosure: None },
                    ),
                    _ => None,
                },
                "ulps": s.judgement.ulps(),
                "residual_ulps": s.residual,
                "enclosure_holds": s.enclosure.map(|e| e.0),
                "enclosure_width_ulps": s.enclosure.map(|e| e.1),
            })
        })
        .collect();
    Ok(json!({
        "shape": info.name,
        "precision": prec.name(),
        "inputs": info.args.iter().zip(input).map(|(n, &x)| json!({ "name": n, "value": hex_text(x) })).collect::<Vec<_>>(),
        "value_names": info.values,
        "oracle": oracle,
        "oracle_detail": detail,
        "methods": rows,
    }))
}

/// The probe's answer as text: the oracle's verdict, correctly rounded values and
/// ill-posedness, then each method's answer and error (what `rayproof probe` prints).
///
/// ```
/// use rayproof::audit::probe::probe_text;
/// use rayproof::audit::{Builtin, Method};
/// use rayproof::numerics::Precision;
/// use rayproof::shapes::sphere::SphereShape;
///
/// // From the origin along +x, a sphere of radius 1 at (4, 0, 0): t = 3 = 0x1.8p+1
/// let builtins = Builtin::all(&SphereShape);
/// let methods: Vec<&dyn Method> = builtins.iter().map(|b| b as &dyn Method).collect();
/// let input = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 4.0, 0.0, 0.0, 1.0];
/// let text = probe_text(&SphereShape, &methods, Precision::F64, &input).unwrap();
/// assert!(text.contains("0x1.8p+1"), "{text}");
/// ```
pub fn probe_text(
    shape: &dyn Shape,
    methods: &[&dyn Method],
    prec: Precision,
    input: &[f64],
) -> Result<String, String> {
    let v = probe_json(shape, methods, prec, input)?;
    let info = shape.info();
    let strs = |x: &Value| {
        x.as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .unwrap_or_default()
    };
    // The case
    let mut s = format!("{} in {} — {}\n", info.name, prec.name(), info.about);
    for (n, &x) in info.args.iter().zip(input) {
        s += &format!("  {n:>6} = {}\n", hex_text(x));
    }
    // The oracle
    let o = &v["oracle"];
    s += &format!(
        "oracle: {}{}{}  values ({}): {}\n",
        o["verdict"].as_str().unwrap_or(""),
        if o["ill_posed"] == true {
            " (ill-posed: changes under one-ulp moves)"
        } else {
            ""
        },
        if o["cap_reached"] == true {
            " (precision cap reached)"
        } else {
            ""
        },
        info.values.join(", "),
        strs(&o["values"])
    );
    for d in v["oracle_detail"].as_array().into_iter().flatten() {
        s += &format!(
            "  {} = {}\n",
            d["name"].as_str().unwrap_or(""),
            d["value"].as_str().unwrap_or("")
        );
    }
    // Each method, in a column that fits the longest name
    let methods = v["methods"].as_array().map_or(&[][..], |m| m.as_slice());
    let w = methods
        .iter()
        .map(|r| r["method"].as_str().map_or(0, |m| m.chars().count()))
        .fold(16, usize::max);
    for r in methods {
        let mut extra = String::new();
        if let Some(u) = r["ulps"].as_u64() {
            extra += &format!("  ({u} ulps)");
        }
        if let Some(x) = r["residual_ulps"].as_f64() {
            extra += &format!("  residual {x:.3} ulps");
        }
        if let (Some(f), "out_of_range" | "malformed") =
            (r["finding"].as_str(), r["judgement"].as_str().unwrap_or(""))
        {
            extra += &format!("  (count {}: {f})", r["count"]);
        }
        if let Some(h) = r["enclosure_holds"].as_bool() {
            extra += if h {
                "  enclosure holds"
            } else {
                "  ENCLOSURE VIOLATED"
            };
        }
        s += &format!(
            "  {:<w$} {:<12} values {}{}\n",
            r["method"].as_str().unwrap_or(""),
            r["judgement"].as_str().unwrap_or(""),
            {
                let v = strs(&r["values"]);
                if v.is_empty() {
                    "-".to_string()
                } else {
                    v
                }
            },
            extra
        );
    }
    Ok(s)
}
