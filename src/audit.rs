//! `rayproof audit`: every selected method × precision × class against the oracle.
//!
//! Cases are generated and judged in parallel, collected in index order and aggregated
//! sequentially, so the report depends only on the seed and the selection, never on the number
//! of threads. Nothing time-dependent goes into the JSON.

use crate::real::Real;
use crate::sphere::cases::{self, Class};
use crate::sphere::methods::{Method, PickPrecision};
use crate::sphere::oracle::{self, Case, Truth};
use crate::sphere::{enclosure_holds, judge, Judgement};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;

/// Which arithmetic a row is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Precision {
    F32,
    F64,
}

impl Precision {
    pub const ALL: [Precision; 2] = [Precision::F32, Precision::F64];
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

/// What to audit.
#[derive(Clone, Debug)]
pub struct AuditOptions {
    pub cases: u64,
    pub seed: u64,
    pub methods: Vec<&'static Method>,
    pub precisions: Vec<Precision>,
    pub classes: Vec<Class>,
    /// `(k, n)`: only cases whose index ≡ k (mod n); `(0, 1)` is the whole run.
    pub shard: (u64, u64),
    pub progress: bool,
}

/// Summary of a sample of non-negative numbers.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Stats {
    pub count: u64,
    pub max: f64,
    pub median: f64,
    pub p99: f64,
    pub mean: f64,
}

impl Stats {
    pub fn of(mut v: Vec<f64>) -> Stats {
        if v.is_empty() {
            return Stats::default();
        }
        v.sort_by(|a, b| a.total_cmp(b));
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        Stats {
            count: v.len() as u64,
            max: *v.last().unwrap(),
            median: q(0.5),
            p99: q(0.99),
            mean,
        }
    }
}

/// A case worth replaying, with the command that replays it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Example {
    /// worst_ulps, false_hit, false_miss, wrong_root, nonfinite_t, worst_residual,
    /// enclosure_violation, invalid_nan_t, invalid_hit
    pub kind: &'static str,
    pub index: u64,
    pub probe: String,
    pub method_t: Option<String>,
    pub oracle_t: Option<String>,
    pub ulps: Option<u64>,
}

/// What happened on invalid inputs.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct InvalidStats {
    pub cases: u64,
    pub rejected: u64,
    pub nonfinite_t: u64,
    pub hit: u64,
}

/// Enclosure checks for methods that return one.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct EnclosureStats {
    pub checked: u64,
    pub violations: u64,
    /// Width `hi − lo` in ulps of the precision.
    pub width_ulps: Stats,
}

/// One row: a method in a precision on a class.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Row {
    pub method: &'static str,
    pub precision: Precision,
    pub class: Class,
    pub cases: u64,
    /// Cases for which the generator found no member (a broken generator shows here).
    pub generator_failures: u64,
    pub ill_posed: u64,
    pub well_posed: u64,
    /// Well-posed valid cases whose exact answer is a hit.
    pub oracle_hits: u64,
    /// Oracle precision cap reached (the root's rounding could not be made certain).
    pub cap_reached: u64,
    pub false_hit: u64,
    pub false_miss: u64,
    pub wrong_root: u64,
    pub nonfinite_t: u64,
    /// Wrong verdicts / well-posed valid cases.
    pub wrong_rate: f64,
    /// Ill-posed cases on which the method's verdict differs from the exact one (not failures).
    pub ill_posed_disagree: u64,
    /// `t` error in ulps over right-verdict hits of well-posed cases.
    pub ulps: Stats,
    /// Herbie's bits of error, log2(1 + ulps).
    pub bits: Stats,
    /// Error relative to the case's sensitivity: ulps / max(1, condition ulps). Near 1: as accurate
    /// as the inputs allow; large: the method lost digits the case did not force it to lose.
    pub err_over_cond: Stats,
    /// |hit-point residual| `||o + t·d − c| − r|` in ulps of r.
    pub residual_ulps: Stats,
    pub invalid: InvalidStats,
    pub enclosure: Option<EnclosureStats>,
    pub examples: Vec<Example>,
}

/// The whole audit.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    pub tool: &'static str,
    pub seed: u64,
    pub cases_per_class: u64,
    pub shard: String,
    pub rows: Vec<Row>,
}

/// CPU time spent in the oracle (all threads), for the terminal summary only (never in JSON).
pub static ORACLE_NANOS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Everything recorded about one case for one method.
struct Sample {
    judgement: Judgement,
    cond: Option<f64>,
    residual: Option<f64>,
    enclosure: Option<(bool, u64)>,
    t_hex: Option<String>,
}

/// One case with its truth and every method's sample.
struct CaseResult {
    index: u64,
    probe: String,
    truth: Option<Truth>,
    oracle_t_hex: Option<String>,
    samples: Vec<Sample>,
}

fn evaluate<F: PickPrecision>(
    seed: u64,
    class: Class,
    index: u64,
    methods: &[&'static Method],
) -> CaseResult {
    let Some(case) = cases::generate::<F>(seed, class, index) else {
        return CaseResult {
            index,
            probe: String::new(),
            truth: None,
            oracle_t_hex: None,
            samples: vec![],
        };
    };
    let clock = std::time::Instant::now();
    let truth = oracle::truth(&case);
    ORACLE_NANOS.fetch_add(
        clock.elapsed().as_nanos() as u64,
        std::sync::atomic::Ordering::Relaxed,
    );
    let cond = oracle::condition_ulps(&case, &truth);
    let (ray, sphere) = (case.ray(), case.sphere());
    let samples = methods
        .iter()
        .map(|m| {
            let hit = F::pick(m)(&ray, &sphere);
            let judgement = judge(&truth, hit);
            let residual = match (judgement, hit) {
                (Judgement::Ok { ulps: Some(_) }, Some(h)) => {
                    Some(oracle::residual_ulps(&case, h.t).abs())
                }
                _ => None,
            };
            let enclosure = match (judgement, hit) {
                (Judgement::Ok { ulps: Some(_) }, Some(h)) => h
                    .enclosure
                    .map(|e| (enclosure_holds(&truth, e), e[1].ulps_between(e[0]))),
                _ => None,
            };
            Sample {
                judgement,
                cond,
                residual,
                enclosure,
                t_hex: hit.map(|h| h.t.hex()),
            }
        })
        .collect();
    CaseResult {
        index,
        probe: probe_line(&case),
        oracle_t_hex: truth.t_in::<F>().map(|t| t.hex()),
        truth: Some(truth),
        samples,
    }
}

/// The full replay command of a case.
pub fn probe_line<F: Real>(case: &Case<F>) -> String {
    format!("rayproof probe sphere {}", case.probe_args())
}

/// Runs the audit. `tick` is called once per finished case (for a progress bar).
pub fn run(opts: &AuditOptions) -> Report {
    let per_combo = opts.cases;
    let total =
        per_combo * opts.classes.len() as u64 * opts.precisions.len() as u64 / opts.shard.1.max(1);
    let bar = if opts.progress {
        ProgressBar::new(total)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} audit {bar:40} {pos}/{len} cases  {per_sec}  eta {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut rows = Vec::new();
    for &prec in &opts.precisions {
        for &class in &opts.classes {
            let indices: Vec<u64> = (0..opts.cases)
                .filter(|i| i % opts.shard.1 == opts.shard.0)
                .collect();
            let results: Vec<CaseResult> = indices
                .par_iter()
                .map(|&i| {
                    let r = match prec {
                        Precision::F32 => evaluate::<f32>(opts.seed, class, i, &opts.methods),
                        Precision::F64 => evaluate::<f64>(opts.seed, class, i, &opts.methods),
                    };
                    bar.inc(1);
                    r
                })
                .collect();
            for (k, m) in opts.methods.iter().enumerate() {
                rows.push(aggregate(m, prec, class, &results, k));
            }
        }
    }
    bar.finish_and_clear();
    let shard = format!("{}/{}", opts.shard.0, opts.shard.1);
    Report {
        tool: concat!("rayproof ", env!("CARGO_PKG_VERSION")),
        seed: opts.seed,
        cases_per_class: opts.cases,
        shard,
        rows,
    }
}

/// How many examples of each kind a row keeps.
const EXAMPLES_PER_KIND: usize = 1;

fn aggregate(
    m: &Method,
    precision: Precision,
    class: Class,
    results: &[CaseResult],
    k: usize,
) -> Row {
    let mut row = Row {
        method: m.name,
        precision,
        class,
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
        err_over_cond: Stats::default(),
        residual_ulps: Stats::default(),
        invalid: InvalidStats::default(),
        enclosure: None,
        examples: vec![],
    };
    let (mut ulps, mut residuals, mut widths, mut relc) = (vec![], vec![], vec![], vec![]);
    let mut enc = EnclosureStats::default();
    let mut has_enc = false;
    // Worst cases, first one wins ties (index order)
    let mut worst_ulps: Option<(u64, &CaseResult)> = None;
    let mut worst_res: Option<(f64, &CaseResult)> = None;
    let mut examples: Vec<Example> = vec![];
    let example =
        |kind: &'static str, r: &CaseResult, ulps: Option<u64>, list: &mut Vec<Example>| {
            if list.iter().filter(|e| e.kind == kind).count() < EXAMPLES_PER_KIND {
                list.push(Example {
                    kind,
                    index: r.index,
                    probe: r.probe.clone(),
                    method_t: r.samples[k].t_hex.clone(),
                    oracle_t: r.oracle_t_hex.clone(),
                    ulps,
                });
            }
        };
    for r in results {
        let Some(truth) = &r.truth else {
            row.generator_failures += 1;
            continue;
        };
        let s = &r.samples[k];
        row.cap_reached += truth.cap_reached as u64;
        // Invalid input
        match s.judgement {
            Judgement::Rejected => {
                row.invalid.cases += 1;
                row.invalid.rejected += 1;
                continue;
            }
            Judgement::InvalidNanT => {
                row.invalid.cases += 1;
                row.invalid.nonfinite_t += 1;
                example("invalid_nan_t", r, None, &mut examples);
                continue;
            }
            Judgement::InvalidHit => {
                row.invalid.cases += 1;
                row.invalid.hit += 1;
                example("invalid_hit", r, None, &mut examples);
                continue;
            }
            _ => {}
        }
        // Ill-posed cases are reported apart
        if truth.ill_posed {
            row.ill_posed += 1;
            row.ill_posed_disagree += !matches!(s.judgement, Judgement::Ok { .. }) as u64;
            continue;
        }
        row.well_posed += 1;
        row.oracle_hits += truth.verdict.is_hit() as u64;
        match s.judgement {
            Judgement::FalseHit => {
                row.false_hit += 1;
                example("false_hit", r, None, &mut examples);
            }
            Judgement::FalseMiss => {
                row.false_miss += 1;
                example("false_miss", r, None, &mut examples);
            }
            Judgement::WrongRoot => {
                row.wrong_root += 1;
                example("wrong_root", r, None, &mut examples);
            }
            Judgement::NonfiniteT => {
                row.nonfinite_t += 1;
                example("nonfinite_t", r, None, &mut examples);
            }
            Judgement::Ok { ulps: Some(u) } => {
                ulps.push(u as f64);
                if let Some(c) = s.cond {
                    relc.push(u as f64 / c.max(1.0));
                }
                if worst_ulps.is_none_or(|(w, _)| u > w) {
                    worst_ulps = Some((u, r));
                }
                if let Some(res) = s.residual {
                    residuals.push(res);
                    if worst_res.is_none_or(|(w, _)| res > w) {
                        worst_res = Some((res, r));
                    }
                }
                if let Some((holds, width)) = s.enclosure {
                    has_enc = true;
                    enc.checked += 1;
                    widths.push(width as f64);
                    if !holds {
                        enc.violations += 1;
                        example("enclosure_violation", r, Some(u), &mut examples);
                    }
                }
            }
            _ => {}
        }
    }
    if let Some((u, r)) = worst_ulps {
        example("worst_ulps", r, Some(u), &mut examples);
    }
    if let Some((_, r)) = worst_res {
        example("worst_residual", r, None, &mut examples);
    }
    let wrong = row.false_hit + row.false_miss + row.wrong_root + row.nonfinite_t;
    row.wrong_rate = if row.well_posed > 0 {
        wrong as f64 / row.well_posed as f64
    } else {
        0.0
    };
    row.bits = Stats::of(ulps.iter().map(|u| (1.0 + u).log2()).collect());
    row.ulps = Stats::of(ulps);
    row.err_over_cond = Stats::of(relc);
    row.residual_ulps = Stats::of(residuals);
    if has_enc {
        enc.width_ulps = Stats::of(widths);
        row.enclosure = Some(enc);
    }
    row.examples = examples;
    row
}

impl Row {
    pub fn wrong(&self) -> u64 {
        self.false_hit + self.false_miss + self.wrong_root + self.nonfinite_t
    }
}

/// Formats a ratio: two decimals below 10, else as [`num`].
fn ratio(x: f64) -> String {
    if x < 10.0 {
        format!("{x:.2}")
    } else {
        num(x)
    }
}

/// Formats a count compactly for the table.
fn num(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x < 1e5 {
        format!("{}", x.round() as u64)
    } else {
        format!("{x:.1e}")
    }
}

/// The human-readable table, one block per precision and class.
pub fn table(report: &Report) -> String {
    let mut out = String::new();
    out += &format!(
        "rayproof audit — seed {}, {} cases per class (shard {})\n\
         well = well-posed cases; ill = ill-posed (a 1-ulp input change flips the exact verdict), reported apart\n\
         wrong = false hit / false miss / wrong root / non-finite t on well-posed cases\n\
         ulps = t error against the correctly rounded root; bits = log2(1+ulps); resid = |o+t·d−c|−r in ulps of r\n\
         err/cond = max of ulps / (ulps t moves when every input moves 1 ulp): ≈1 is as good as the inputs allow\n\
         invalid = invalid inputs: rejected / NaN t / hit\n",
        report.seed, report.cases_per_class, report.shard
    );
    let mut key = None;
    for row in &report.rows {
        if key != Some((row.precision, row.class)) {
            key = Some((row.precision, row.class));
            out += &format!(
                "\n{} · {}\n  {:<12} {:>6} {:>5} {:>17} {:>9} {:>8} {:>7} {:>6} {:>8} {:>9} {:>12} {}\n",
                row.precision.name(),
                row.class.name(),
                "method",
                "well",
                "ill",
                "wrong fh/fm/wr/nf",
                "rate",
                "max ulp",
                "p99",
                "bits99",
                "err/cond",
                "resid max",
                "invalid",
                "enclosure"
            );
        }
        let inv = if row.invalid.cases > 0 {
            format!(
                "{}/{}/{}",
                row.invalid.rejected, row.invalid.nonfinite_t, row.invalid.hit
            )
        } else {
            "-".into()
        };
        let enc = row
            .enclosure
            .as_ref()
            .map(|e| {
                format!(
                    "{} viol, width med {}",
                    e.violations,
                    num(e.width_ulps.median)
                )
            })
            .unwrap_or_default();
        out += &format!(
            "  {:<12} {:>6} {:>5} {:>17} {:>8.4}% {:>8} {:>7} {:>6.1} {:>8} {:>9} {:>12} {}\n",
            row.method,
            row.well_posed,
            row.ill_posed,
            format!(
                "{}/{}/{}/{}",
                row.false_hit, row.false_miss, row.wrong_root, row.nonfinite_t
            ),
            row.wrong_rate * 100.0,
            num(row.ulps.max),
            num(row.ulps.p99),
            row.bits.p99,
            ratio(row.err_over_cond.max),
            num(row.residual_ulps.max),
            inv,
            enc
        );
    }
    out
}

/// The worst cases of every row, as replayable probe commands.
pub fn worst_cases(report: &Report, limit_per_row: usize) -> String {
    let mut out = String::new();
    for row in &report.rows {
        for e in row
            .examples
            .iter()
            .filter(|e| e.kind != "worst_residual")
            .take(limit_per_row)
        {
            out += &format!(
                "{} {} {} {}: t = {} (oracle {}){}\n  {}\n",
                row.precision.name(),
                row.class.name(),
                row.method,
                e.kind,
                e.method_t.as_deref().unwrap_or("miss"),
                e.oracle_t.as_deref().unwrap_or("miss"),
                e.ulps.map(|u| format!(", {u} ulps")).unwrap_or_default(),
                e.probe
            );
        }
    }
    out
}

/// The oracle alone on a class (cases per second, for the README).
pub fn oracle_only<F: Real>(seed: u64, class: Class, n: u64) -> usize {
    (0..n)
        .into_par_iter()
        .filter_map(|i| cases::generate::<F>(seed, class, i))
        .map(|c| oracle::truth(&c).prec as usize)
        .count()
}

/// The table as Markdown: one row per method × precision × class.
pub fn markdown(report: &Report) -> String {
    let mut out = format!(
        "# rayproof audit\n\nSeed {}, {} cases per class, shard {}.\n\n\
         | precision | class | method | well-posed | ill-posed | false hit | false miss | wrong root | non-finite t | wrong % | max ulps | p99 ulps | median ulps | p99 bits | max err/cond | max residual (ulps of r) | invalid rejected/NaN/hit |\n\
         |---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n",
        report.seed, report.cases_per_class, report.shard
    );
    for r in &report.rows {
        out += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.4} | {} | {} | {} | {:.1} | {} | {} | {} |\n",
            r.precision.name(),
            r.class.name(),
            r.method,
            r.well_posed,
            r.ill_posed,
            r.false_hit,
            r.false_miss,
            r.wrong_root,
            r.nonfinite_t,
            r.wrong_rate * 100.0,
            num(r.ulps.max),
            num(r.ulps.p99),
            num(r.ulps.median),
            r.bits.p99,
            ratio(r.err_over_cond.max),
            num(r.residual_ulps.max),
            if r.invalid.cases > 0 { format!("{}/{}/{}", r.invalid.rejected, r.invalid.nonfinite_t, r.invalid.hit) } else { "-".into() }
        );
    }
    out
}
