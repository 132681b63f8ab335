//! `rayproof audit --shape NAME`: every method × precision × class of a routine family against
//! its oracle. Cases are evaluated in parallel and aggregated in index order, so the report
//! depends only on the seed and the selection.

use super::shape::{hex_text, judge, probe_line, Answer, Expect, Metric, Shape, Truth};
use super::sphere_run::{InvalidStats, Stats};
use crate::numerics::{exact, Precision};
use crate::shapes::sphere::Judgement;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use serde_json::{json, Value};
use sha2::{Digest, Sha256};

/// A case worth replaying.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Example {
    /// worst_ulps, false_hit, false_miss, wrong_root, nonfinite_t, invalid_nan_t, invalid_hit
    pub kind: &'static str,
    pub index: u64,
    pub probe: String,
    pub method_values: Vec<String>,
    pub oracle_values: Vec<String>,
    pub ulps: Option<u64>,
}

/// One row: a method in a precision on a class.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Row {
    pub method: &'static str,
    pub robust: bool,
    pub precision: Precision,
    pub class: &'static str,
    pub cases: u64,
    pub generator_failures: u64,
    pub ill_posed: u64,
    pub well_posed: u64,
    /// Well-posed valid cases whose exact count is not 0.
    pub oracle_hits: u64,
    pub cap_reached: u64,
    pub false_hit: u64,
    pub false_miss: u64,
    pub wrong_root: u64,
    pub nonfinite_t: u64,
    pub wrong_rate: f64,
    pub ill_posed_disagree: u64,
    /// Value error (by the shape's metric) over right-verdict answers of well-posed cases.
    pub ulps: Stats,
    /// Herbie's bits of error, log2(1 + ulps).
    pub bits: Stats,
    pub invalid: InvalidStats,
    pub examples: Vec<Example>,
}

impl Row {
    pub fn wrong(&self) -> u64 {
        self.false_hit + self.false_miss + self.wrong_root + self.nonfinite_t
    }
}

/// One shape's audit.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ShapeReport {
    pub shape: &'static str,
    pub about: &'static str,
    pub metric: &'static str,
    pub seed: u64,
    pub cases_per_class: u64,
    pub rows: Vec<Row>,
}

/// What to audit.
pub struct Options {
    pub cases: u64,
    pub seed: u64,
    pub precisions: Vec<Precision>,
    /// Method names (empty: all).
    pub methods: Vec<String>,
    /// Class names (empty: all).
    pub classes: Vec<String>,
}

/// The generator of case `index`: a ChaCha8 stream keyed by seed, shape, class, precision and
/// index, so any case is generated alone.
pub fn case_rng(seed: u64, shape: &str, class: &str, prec: Precision, index: u64) -> ChaCha8Rng {
    let mut h = Sha256::new();
    h.update(seed.to_le_bytes());
    h.update(shape.as_bytes());
    h.update([0]);
    h.update(class.as_bytes());
    h.update([0]);
    h.update(prec.name().as_bytes());
    h.update(index.to_le_bytes());
    ChaCha8Rng::from_seed(h.finalize().into())
}

/// Generates case `index` of a class (public for tests and benches).
pub fn generate(
    shape: &dyn Shape,
    seed: u64,
    class: usize,
    prec: Precision,
    index: u64,
) -> Option<Vec<f64>> {
    let mut rng = case_rng(seed, shape.name(), shape.classes()[class], prec, index);
    let v = shape.generate(class, prec, &mut rng)?;
    debug_assert!(v.iter().all(|&x| exact::representable(x, prec)));
    Some(v)
}

struct CaseResult {
    index: u64,
    input: Vec<f64>,
    truth: Option<Truth>,
    answers: Vec<(Answer, Judgement)>,
}

fn evaluate(
    shape: &dyn Shape,
    seed: u64,
    class: usize,
    prec: Precision,
    index: u64,
    methods: &[usize],
) -> CaseResult {
    let Some(input) = generate(shape, seed, class, prec, index) else {
        return CaseResult {
            index,
            input: vec![],
            truth: None,
            answers: vec![],
        };
    };
    let truth = shape.oracle(&input, prec);
    let answers = methods
        .iter()
        .map(|&m| {
            let a = shape.run(m, &input, prec);
            let j = judge(&truth, &a, shape.metric(), prec);
            (a, j)
        })
        .collect();
    CaseResult {
        index,
        input,
        truth: Some(truth),
        answers,
    }
}

/// Resolves names against a list, or all when empty.
fn select(names: &[String], all: &[&'static str], what: &str) -> Result<Vec<usize>, String> {
    if names.is_empty() {
        return Ok((0..all.len()).collect());
    }
    names
        .iter()
        .map(|n| {
            all.iter()
                .position(|a| a == n)
                .ok_or_else(|| format!("unknown {what} '{n}' (known: {})", all.join(", ")))
        })
        .collect()
}

/// Checks a selection without running it (for the command line's early error).
pub fn validate(shape: &dyn Shape, opts: &Options) -> Result<(), String> {
    let names: Vec<&'static str> = shape.methods().iter().map(|m| m.name).collect();
    select(&opts.methods, &names, "method")?;
    select(&opts.classes, shape.classes(), "class")?;
    Ok(())
}

/// Runs the audit of one shape.
pub fn run(shape: &dyn Shape, opts: &Options) -> Result<ShapeReport, String> {
    let names: Vec<&'static str> = shape.methods().iter().map(|m| m.name).collect();
    let methods = select(&opts.methods, &names, "method")?;
    let classes = select(&opts.classes, shape.classes(), "class")?;
    let mut rows = vec![];
    for &prec in &opts.precisions {
        for &class in &classes {
            // Evaluate in parallel, collect in index order
            let results: Vec<CaseResult> = (0..opts.cases)
                .into_par_iter()
                .map(|i| evaluate(shape, opts.seed, class, prec, i, &methods))
                .collect();
            // Aggregate sequentially
            for (k, &m) in methods.iter().enumerate() {
                rows.push(aggregate(shape, m, k, prec, class, &results));
            }
        }
    }
    Ok(ShapeReport {
        shape: shape.name(),
        about: shape.about(),
        metric: match shape.metric() {
            Metric::Ulps => "ulps",
            Metric::NormUlps => "norm_ulps",
        },
        seed: opts.seed,
        cases_per_class: opts.cases,
        rows,
    })
}

fn aggregate(
    shape: &dyn Shape,
    m: usize,
    k: usize,
    prec: Precision,
    class: usize,
    results: &[CaseResult],
) -> Row {
    let info = shape.methods()[m];
    let mut row = Row {
        method: info.name,
        robust: info.robust,
        precision: prec,
        class: shape.classes()[class],
        cases: results.len() as u64,
        generator_failures: 0,
        ill_posed: 0,
        well_posed: 0,
        oracle_hits: 0,
        cap_reached: 0,
        false_hit: 0,
        false_miss: 0,
        wrong_root: 0,
        nonfinite_t: 0,
        wrong_rate: 0.0,
        ill_posed_disagree: 0,
        ulps: Stats::default(),
        bits: Stats::default(),
        invalid: InvalidStats::default(),
        examples: vec![],
    };
    let mut ulps = vec![];
    let mut worst: Option<(u64, &CaseResult)> = None;
    let mut first: Vec<(&'static str, &CaseResult)> = vec![];
    let mut note = |kind: &'static str, c| {
        if !first.iter().any(|(k, _)| *k == kind) {
            first.push((kind, c));
        }
    };
    for c in results {
        let Some(truth) = &c.truth else {
            row.generator_failures += 1;
            continue;
        };
        let (_, j) = &c.answers[k];
        let e = match truth {
            Truth::Invalid => {
                row.invalid.cases += 1;
                match j {
                    Judgement::Rejected => row.invalid.rejected += 1,
                    Judgement::InvalidNanT => {
                        row.invalid.nonfinite_t += 1;
                        note("invalid_nan_t", c)
                    }
                    _ => {
                        row.invalid.hit += 1;
                        note("invalid_hit", c)
                    }
                }
                continue;
            }
            Truth::Answer(e) => e,
        };
        row.cap_reached += e.cap_reached as u64;
        if e.ill_posed {
            row.ill_posed += 1;
            row.ill_posed_disagree += j.is_wrong() as u64;
            continue;
        }
        row.well_posed += 1;
        row.oracle_hits += (e.count > 0) as u64;
        match j {
            Judgement::Ok { ulps: Some(u) } => {
                ulps.push(*u as f64);
                if worst.is_none_or(|(w, _)| *u > w) {
                    worst = Some((*u, c));
                }
            }
            Judgement::FalseHit => {
                row.false_hit += 1;
                note("false_hit", c)
            }
            Judgement::FalseMiss => {
                row.false_miss += 1;
                note("false_miss", c)
            }
            Judgement::WrongRoot => {
                row.wrong_root += 1;
                note("wrong_root", c)
            }
            Judgement::NonfiniteT => {
                row.nonfinite_t += 1;
                note("nonfinite_t", c)
            }
            _ => {}
        }
    }
    row.wrong_rate = row.wrong() as f64 / row.well_posed.max(1) as f64;
    row.bits = Stats::of(ulps.iter().map(|u| (1.0 + u).log2()).collect());
    row.ulps = Stats::of(ulps);
    // Examples: the worst value error first, then the first case of each failure kind
    let example = |kind, c: &CaseResult| {
        let (a, j) = &c.answers[k];
        let oracle_values = match &c.truth {
            Some(Truth::Answer(e)) => e.values.iter().map(|&v| hex_text(v)).collect(),
            _ => vec![],
        };
        Example {
            kind,
            index: c.index,
            probe: probe_line(shape, prec, &c.input),
            method_values: a.values.iter().map(|&v| hex_text(v)).collect(),
            oracle_values,
            ulps: match j {
                Judgement::Ok { ulps } => *ulps,
                _ => None,
            },
        }
    };
    if let Some((u, c)) = worst.filter(|(u, _)| *u > 0) {
        let _ = u;
        row.examples.push(example("worst_ulps", c));
    }
    for (kind, c) in first {
        row.examples.push(example(kind, c));
    }
    row
}

/// Rows that break the shape's tolerance table, one line each.
pub fn check(shape: &dyn Shape, report: &ShapeReport) -> Vec<String> {
    let mut out = vec![];
    let classes = shape.classes();
    for r in &report.rows {
        let Some(m) = shape.methods().iter().position(|x| x.name == r.method) else {
            continue;
        };
        let Some(c) = classes.iter().position(|x| *x == r.class) else {
            continue;
        };
        let e: Expect = shape.expect(m, r.precision, c);
        let what = format!(
            "{} {} {} {}",
            report.shape,
            r.method,
            r.precision.name(),
            r.class
        );
        let invalid_bad = r.invalid.hit + r.invalid.nonfinite_t;
        if e.must_fail {
            if r.wrong() == 0 && r.ulps.max <= e.max_ulps as f64 && r.well_posed >= 50 {
                out.push(format!(
                    "{what}: known failure not reproduced ({} well-posed cases, 0 wrong, max {} ulps)",
                    r.well_posed, r.ulps.max
                ));
            }
            continue;
        }
        if e.max_wrong != u64::MAX && r.wrong() > e.max_wrong {
            out.push(format!(
                "{what}: {} wrong verdicts (allowed {})",
                r.wrong(),
                e.max_wrong
            ));
        }
        if e.max_wrong != u64::MAX && invalid_bad > 0 {
            out.push(format!(
                "{what}: {invalid_bad} invalid inputs answered with a hit"
            ));
        }
        if e.max_ulps != u64::MAX && r.ulps.max > e.max_ulps as f64 {
            out.push(format!(
                "{what}: max {} ulps (allowed {})",
                r.ulps.max, e.max_ulps
            ));
        }
    }
    out
}

/// The terminal table of one shape.
pub fn table(report: &ShapeReport) -> String {
    let mut s = format!(
        "\n{} — {}  (errors in {}; {} cases per class)\n",
        report.shape, report.about, report.metric, report.cases_per_class
    );
    s += &format!(
        "{:<14} {:<4} {:<16} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} {:>9} {:>10} {:>8} {:>7}\n",
        "method",
        "prec",
        "class",
        "well",
        "ill",
        "f.hit",
        "f.miss",
        "w.root",
        "nonfin",
        "wrong%",
        "max ulps",
        "p99",
        "invalid"
    );
    for r in &report.rows {
        s += &format!(
            "{:<14} {:<4} {:<16} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6} {:>8.3}% {:>10} {:>8} {:>7}\n",
            r.method,
            r.precision.name(),
            r.class,
            r.well_posed,
            r.ill_posed,
            r.false_hit,
            r.false_miss,
            r.wrong_root,
            r.nonfinite_t,
            100.0 * r.wrong_rate,
            fmt_ulps(r.ulps.max),
            fmt_ulps(r.ulps.p99),
            if r.invalid.cases == 0 {
                "-".to_string()
            } else {
                format!("{}/{}", r.invalid.rejected, r.invalid.cases)
            }
        );
    }
    s
}

fn fmt_ulps(u: f64) -> String {
    if u >= 1e6 {
        format!("{u:.2e}")
    } else {
        format!("{u}")
    }
}

/// The Markdown table of one shape.
pub fn markdown(report: &ShapeReport) -> String {
    let mut s = format!(
        "### {} — {}\n\nErrors in {}; {} cases per class.\n\n",
        report.shape, report.about, report.metric, report.cases_per_class
    );
    s += "| method | prec | class | well-posed | ill-posed | false hit | false miss | wrong root | non-finite | wrong % | max ulps | p99 ulps | invalid rejected |\n";
    s += "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in &report.rows {
        s += &format!(
            "| {}{} | {} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {} | {} | {} |\n",
            r.method,
            if r.robust { " (robust)" } else { "" },
            r.precision.name(),
            r.class,
            r.well_posed,
            r.ill_posed,
            r.false_hit,
            r.false_miss,
            r.wrong_root,
            r.nonfinite_t,
            100.0 * r.wrong_rate,
            fmt_ulps(r.ulps.max),
            fmt_ulps(r.ulps.p99),
            if r.invalid.cases == 0 {
                "-".to_string()
            } else {
                format!("{}/{}", r.invalid.rejected, r.invalid.cases)
            }
        );
    }
    s
}

/// The worst cases of every row, with their probe lines.
pub fn worst_cases(report: &ShapeReport, per_row: usize) -> String {
    let mut s = String::new();
    for r in &report.rows {
        for e in r.examples.iter().take(per_row) {
            s += &format!(
                "{} {} {} {} (case {}): method {:?} oracle {:?}{}\n  {}\n",
                report.shape,
                r.method,
                r.precision.name(),
                e.kind,
                e.index,
                e.method_values,
                e.oracle_values,
                e.ulps.map(|u| format!(", {u} ulps")).unwrap_or_default(),
                e.probe
            );
        }
    }
    s
}

/// `rayproof probe <shape>`: the oracle and every method on one input, as text or JSON.
pub fn probe(shape: &dyn Shape, prec: Precision, input: &[f64], as_json: bool) -> String {
    let truth = shape.oracle(input, prec);
    let (verdict, values, ill) = match &truth {
        Truth::Invalid => ("invalid".to_string(), vec![], false),
        Truth::Answer(e) => (
            format!("count {}", e.count),
            e.values.iter().map(|&v| hex_text(v)).collect::<Vec<_>>(),
            e.ill_posed,
        ),
    };
    let rows: Vec<Value> = shape
        .methods()
        .iter()
        .enumerate()
        .map(|(m, info)| {
            let a = shape.run(m, input, prec);
            let j = judge(&truth, &a, shape.metric(), prec);
            json!({
                "method": info.name,
                "robust": info.robust,
                "count": a.count,
                "values": a.values.iter().map(|&v| hex_text(v)).collect::<Vec<_>>(),
                "judgement": j.verdict_word(),
                "ulps": match j { Judgement::Ok { ulps } => ulps, _ => None },
            })
        })
        .collect();
    let inputs: Vec<Value> = shape
        .args()
        .iter()
        .zip(input)
        .map(|(n, &x)| json!({ "name": n, "value": hex_text(x) }))
        .collect();
    if as_json {
        let v = json!({
            "shape": shape.name(),
            "precision": prec.name(),
            "inputs": inputs,
            "value_names": shape.values(),
            "oracle": { "verdict": verdict, "values": values, "ill_posed": ill },
            "methods": rows,
        });
        return serde_json::to_string_pretty(&v).unwrap_or_default() + "\n";
    }
    let mut s = format!("{} in {} — {}\n", shape.name(), prec.name(), shape.about());
    for (n, &x) in shape.args().iter().zip(input) {
        s += &format!("  {n:>6} = {}\n", hex_text(x));
    }
    s += &format!(
        "oracle: {verdict}{}  values ({}): {}\n",
        if ill {
            " (ill-posed: changes under one-ulp moves)"
        } else {
            ""
        },
        shape.values().join(", "),
        values.join(" ")
    );
    for r in rows {
        s += &format!(
            "  {:<14} {:<12} count {} values {}{}\n",
            r["method"].as_str().unwrap_or(""),
            r["judgement"].as_str().unwrap_or(""),
            r["count"],
            r["values"]
                .as_array()
                .map(|v| v
                    .iter()
                    .filter_map(|x| x.as_str())
                    .collect::<Vec<_>>()
                    .join(" "))
                .unwrap_or_default(),
            r["ulps"]
                .as_u64()
                .map(|u| format!("  ({u} ulps)"))
                .unwrap_or_default()
        );
    }
    s
}
