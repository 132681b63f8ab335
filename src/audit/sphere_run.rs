//! `rayproof audit`: every selected method × precision × class against the oracle.
//!
//! Cases are generated and judged in parallel, collected in index order and aggregated
//! sequentially, so the report depends only on the seed and the selection, never on the number
//! of threads. Nothing time-dependent goes into the JSON.
//!
//! The run has two steps: evaluation (one `CaseResult` per case, with one `Sample` per
//! method) and aggregation (`group_rows`: the case results of a precision × class, in index
//! order, become its rows). Aggregation sees nothing else, which is what makes sharding exact.
//! Shard `K/N` evaluates the cases whose index ≡ K (mod N); with `--shard-out` its raw case
//! results go to a [`Shard`] file (format [`SHARD_FORMAT`], version [`SHARD_FORMAT_VERSION`];
//! floats as hex text, see `Exact`). [`merge`] checks that the files are the shards 0/N …
//! N−1/N of one audit (same tool version, seed, cases, selection and N; each shard once),
//! interleaves their case results back into index order and aggregates them as the unsharded
//! run does: its report is the unsharded report, byte for byte, with `shard` "0/1".

use crate::numerics::real::{hex_float, parse_f64, Real};
use crate::numerics::Precision;
use crate::shapes::sphere::cases::{self, Class};
use crate::shapes::sphere::methods::{method_by_name, Method, PickPrecision};
use crate::shapes::sphere::oracle::{self, Case, Verdict};
use crate::shapes::sphere::{enclosure_holds, judge, Judgement};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

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

/// The `tool` field of reports and shard files.
pub const TOOL: &str = concat!("rayproof ", env!("CARGO_PKG_VERSION"));

/// The oracle's findings about one case that aggregation uses.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseTruth {
    verdict: Verdict,
    ill_posed: bool,
    cap_reached: bool,
}

/// Everything recorded about one case for one method. In a shard file it is the array
/// `[judgement, t, residual, enclosure]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "SampleWire", into = "SampleWire")]
struct Sample {
    judgement: Judgement,
    /// The method's `t`, exactly (an `f32` widened to `f64`).
    t: Option<f64>,
    residual: Option<f64>,
    /// Whether the enclosure holds, and its width in ulps.
    enclosure: Option<(bool, u64)>,
}

#[derive(Clone, Copy, Serialize, Deserialize)]
struct SampleWire(Judgement, Option<Exact>, Option<Exact>, Option<(bool, u64)>);

impl From<Sample> for SampleWire {
    fn from(s: Sample) -> Self {
        let x = |v: Option<f64>| v.map(Exact);
        SampleWire(s.judgement, x(s.t), x(s.residual), s.enclosure)
    }
}

impl From<SampleWire> for Sample {
    fn from(w: SampleWire) -> Self {
        let x = |v: Option<Exact>| v.map(|e| e.0);
        Sample {
            judgement: w.0,
            t: x(w.1),
            residual: x(w.2),
            enclosure: w.3,
        }
    }
}

/// An `f64` that survives JSON exactly: a C99 hex float (`0x1.8p+1`, `-0x0p+0`, `inf`), and a
/// NaN as its bit pattern (`nan:0x7ff8000000000000`). Decimal JSON numbers are not used because
/// a JSON reader need not parse them exactly.
#[derive(Clone, Copy, Debug)]
struct Exact(f64);

impl Exact {
    fn text(self) -> String {
        if self.0.is_nan() {
            format!("nan:{:#018x}", self.0.to_bits())
        } else {
            hex_float(self.0)
        }
    }
    fn parse(s: &str) -> Option<f64> {
        match s.strip_prefix("nan:0x") {
            Some(bits) => u64::from_str_radix(bits, 16)
                .ok()
                .map(f64::from_bits)
                .filter(|x| x.is_nan()),
            None => parse_f64(s).filter(|x| !x.is_nan()),
        }
    }
}

impl Serialize for Exact {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.text())
    }
}

impl<'de> Deserialize<'de> for Exact {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = <std::borrow::Cow<str>>::deserialize(d)?;
        Exact::parse(&s)
            .map(Exact)
            .ok_or_else(|| serde::de::Error::custom(format!("'{s}' is not an exact float")))
    }
}

/// `Option<f64>` fields written as [`Exact`].
mod exact_opt {
    use super::Exact;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    pub fn serialize<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        v.map(Exact).serialize(s)
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        Ok(Option::<Exact>::deserialize(d)?.map(|e| e.0))
    }
}

/// One case with its truth and every method's sample (`truth` is `None`, and there are no
/// samples, when the generator found no member).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseResult {
    index: u64,
    probe: String,
    truth: Option<CaseTruth>,
    /// The correctly rounded root in the case's precision, exactly.
    #[serde(with = "exact_opt")]
    oracle_t: Option<f64>,
    /// The case's sensitivity in ulps of `t` (see [`oracle::condition_ulps`]).
    #[serde(with = "exact_opt")]
    cond: Option<f64>,
    samples: Vec<Sample>,
}

/// The results of one precision × class, in index order.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Group {
    precision: Precision,
    #[serde(with = "class_name")]
    class: Class,
    cases: Vec<CaseResult>,
}

/// A [`Class`] by its name.
mod class_name {
    use crate::shapes::sphere::cases::Class;
    use serde::{Deserialize, Deserializer, Serializer};
    pub fn serialize<S: Serializer>(c: &Class, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(c.name())
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Class, D::Error> {
        let s = <std::borrow::Cow<str>>::deserialize(d)?;
        Class::from_name(&s).ok_or_else(|| serde::de::Error::custom(format!("unknown class '{s}'")))
    }
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
            oracle_t: None,
            cond: None,
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
                t: hit.map(|h| h.t.to_f64()),
                residual,
                enclosure,
            }
        })
        .collect();
    CaseResult {
        index,
        probe: probe_line(&case),
        oracle_t: truth.t_in::<F>().map(|t| t.to_f64()),
        cond,
        truth: Some(CaseTruth {
            verdict: truth.verdict,
            ill_posed: truth.ill_posed,
            cap_reached: truth.cap_reached,
        }),
        samples,
    }
}

/// The full replay command of a case.
pub fn probe_line<F: Real>(case: &Case<F>) -> String {
    format!("rayproof probe sphere {}", case.probe_args())
}

/// The indices of shard `(k, n)` among `0..cases`: `k, k + n, k + 2n, …`.
fn shard_indices(cases: u64, (k, n): (u64, u64)) -> impl Iterator<Item = u64> {
    (k..cases).step_by(usize::try_from(n.max(1)).unwrap_or(usize::MAX))
}

/// How many indices shard `(k, n)` has among `0..cases`.
fn shard_len(cases: u64, (k, n): (u64, u64)) -> u64 {
    if k >= cases {
        0
    } else {
        (cases - k - 1) / n.max(1) + 1
    }
}

/// Runs the audit.
pub fn run(opts: &AuditOptions) -> Report {
    run_inner(opts, false).0
}

/// Runs the audit and also returns its raw results, for `--shard-out` and [`merge`].
pub fn run_shard(opts: &AuditOptions) -> (Report, Shard) {
    let (report, groups) = run_inner(opts, true);
    let shard = Shard {
        tool: TOOL.to_string(),
        seed: opts.seed,
        cases: opts.cases,
        methods: opts.methods.clone(),
        precisions: opts.precisions.clone(),
        classes: opts.classes.clone(),
        shard: opts.shard,
        groups,
    };
    (report, shard)
}

/// Evaluates every precision × class in turn and aggregates it at once; the case results are
/// kept only when `keep` (otherwise one group's results are in memory at a time).
fn run_inner(opts: &AuditOptions, keep: bool) -> (Report, Vec<Group>) {
    // Progress bar over this shard's cases
    let per_group = shard_len(opts.cases, opts.shard);
    let total = per_group * opts.classes.len() as u64 * opts.precisions.len() as u64;
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
    let (mut rows, mut kept) = (Vec::new(), Vec::new());
    for &precision in &opts.precisions {
        for &class in &opts.classes {
            // Evaluate in parallel, collect in index order
            let indices: Vec<u64> = shard_indices(opts.cases, opts.shard).collect();
            let cases: Vec<CaseResult> = indices
                .par_iter()
                .map(|&i| {
                    let r = match precision {
                        Precision::F32 => evaluate::<f32>(opts.seed, class, i, &opts.methods),
                        Precision::F64 => evaluate::<f64>(opts.seed, class, i, &opts.methods),
                    };
                    bar.inc(1);
                    r
                })
                .collect();
            let group = Group {
                precision,
                class,
                cases,
            };
            // Aggregate sequentially
            rows.extend(group_rows(&opts.methods, &group));
            if keep {
                kept.push(group);
            }
        }
    }
    bar.finish_and_clear();
    let report = Report {
        tool: TOOL,
        seed: opts.seed,
        cases_per_class: opts.cases,
        shard: format!("{}/{}", opts.shard.0, opts.shard.1),
        rows,
    };
    (report, kept)
}

/// The rows of one precision × class, one per method. Depends only on the case results (in
/// index order): an unsharded run and a merge of its shards give the same rows.
fn group_rows(methods: &[&'static Method], group: &Group) -> Vec<Row> {
    methods
        .iter()
        .enumerate()
        .map(|(k, m)| aggregate(m, group.precision, group.class, &group.cases, k))
        .collect()
}

/// The tag in the `format` field of a shard file.
pub const SHARD_FORMAT: &str = "rayproof-audit-shard";
/// The version in the `format_version` field; a reader refuses any other.
pub const SHARD_FORMAT_VERSION: u32 = 1;

/// One shard's raw case results, as written by `rayproof audit --shard K/N --shard-out FILE`
/// and read by `rayproof merge`.
#[derive(Debug)]
pub struct Shard {
    pub tool: String,
    pub seed: u64,
    pub cases: u64,
    pub methods: Vec<&'static Method>,
    pub precisions: Vec<Precision>,
    pub classes: Vec<Class>,
    /// `(k, n)`.
    pub shard: (u64, u64),
    groups: Vec<Group>,
}

impl Shard {
    /// The ulps of every right-verdict hit on a well-posed case of one row, in index order:
    /// the sample that row's `ulps` summarises (for histograms and pooled quantiles).
    pub fn ulps(&self, method: &str, precision: Precision, class: Class) -> Vec<u64> {
        let Some(k) = self.methods.iter().position(|m| m.name == method) else {
            return vec![];
        };
        self.groups
            .iter()
            .filter(|g| g.precision == precision && g.class == class)
            .flat_map(|g| &g.cases)
            .filter(|c| c.truth.as_ref().is_some_and(|t| !t.ill_posed))
            .filter_map(|c| match c.samples.get(k)?.judgement {
                Judgement::Ok { ulps: Some(u) } => Some(u),
                _ => None,
            })
            .collect()
    }
}

/// `k` and `n` of a shard file.
#[derive(Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShardId {
    k: u64,
    n: u64,
}

/// The shard file's JSON object (field order is the file's).
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShardFile<G> {
    format: String,
    format_version: u32,
    tool: String,
    seed: u64,
    cases_per_class: u64,
    methods: Vec<String>,
    precisions: Vec<Precision>,
    classes: Vec<String>,
    shard: ShardId,
    groups: G,
}

/// Just the tag of a file, to tell "not a shard" from "a corrupt shard".
#[derive(Deserialize)]
struct FormatTag {
    format: Option<serde_json::Value>,
    format_version: Option<serde_json::Value>,
}

impl Shard {
    /// The shard file: one line of JSON, every float exact (hex text; a NaN by its bits).
    pub fn to_json(&self) -> String {
        let file = ShardFile {
            format: SHARD_FORMAT.into(),
            format_version: SHARD_FORMAT_VERSION,
            tool: self.tool.clone(),
            seed: self.seed,
            cases_per_class: self.cases,
            methods: self.methods.iter().map(|m| m.name.to_string()).collect(),
            precisions: self.precisions.clone(),
            classes: self.classes.iter().map(|c| c.name().to_string()).collect(),
            shard: ShardId {
                k: self.shard.0,
                n: self.shard.1,
            },
            groups: &self.groups,
        };
        serde_json::to_string(&file).expect("a shard serialises") + "\n"
    }

    /// Reads a shard file, checking that it is complete and consistent in itself: every
    /// precision × class of its selection, every index of its shard, one sample per method.
    /// The error is one line.
    pub fn from_json(bytes: &[u8]) -> Result<Shard, String> {
        let file: ShardFile<Vec<Group>> = match serde_json::from_slice(bytes) {
            Ok(f) => f,
            Err(e) => {
                // Tell a file of another kind from a damaged shard
                let tag = serde_json::from_slice::<FormatTag>(bytes).ok();
                let json = serde_json::from_slice::<serde::de::IgnoredAny>(bytes).is_ok();
                return Err(match tag {
                    Some(t) if t.format != Some(SHARD_FORMAT.into()) => {
                        format!("not a rayproof audit shard (no \"format\": \"{SHARD_FORMAT}\")")
                    }
                    Some(t) if t.format_version != Some(SHARD_FORMAT_VERSION.into()) => {
                        format!(
                            "shard format version {}, but this rayproof reads version {SHARD_FORMAT_VERSION}",
                            t.format_version.map(|v| v.to_string()).unwrap_or("(none)".into())
                        )
                    }
                    None if json => {
                        format!("not a rayproof audit shard (no \"format\": \"{SHARD_FORMAT}\")")
                    }
                    _ if e.is_eof() => format!("truncated shard ({e})"),
                    _ => format!("corrupt shard ({e})"),
                });
            }
        };
        if file.format != SHARD_FORMAT {
            return Err(format!(
                "not a rayproof audit shard (no \"format\": \"{SHARD_FORMAT}\")"
            ));
        }
        if file.format_version != SHARD_FORMAT_VERSION {
            return Err(format!(
                "shard format version {}, but this rayproof reads version {SHARD_FORMAT_VERSION}",
                file.format_version
            ));
        }
        let corrupt = |what: String| Err(format!("corrupt shard: {what}"));
        let ShardId { k, n } = file.shard;
        if n == 0 || k >= n {
            return corrupt(format!("shard {k}/{n} is not K/N with 0 ≤ K < N"));
        }
        let mut methods = vec![];
        for name in &file.methods {
            match method_by_name(name) {
                Some(m) => methods.push(m),
                None => return corrupt(format!("unknown method '{name}'")),
            }
        }
        let mut classes = vec![];
        for name in &file.classes {
            match Class::from_name(name) {
                Some(c) => classes.push(c),
                None => return corrupt(format!("unknown class '{name}'")),
            }
        }
        if methods.is_empty() || classes.is_empty() || file.precisions.is_empty() {
            return corrupt("empty selection".into());
        }
        // Every precision × class in selection order, every index of the shard, in order
        let expected: Vec<(Precision, Class)> = file
            .precisions
            .iter()
            .flat_map(|&p| classes.iter().map(move |&c| (p, c)))
            .collect();
        let got: Vec<(Precision, Class)> =
            file.groups.iter().map(|g| (g.precision, g.class)).collect();
        if got != expected {
            return corrupt(format!(
                "{} precision × class groups where the selection has {}",
                got.len(),
                expected.len()
            ));
        }
        let per_group = shard_len(file.cases_per_class, (k, n));
        for g in &file.groups {
            let at = format!("{} {}", g.precision.name(), g.class.name());
            if g.cases.len() as u64 != per_group {
                return corrupt(format!(
                    "{at}: {} cases where shard {k}/{n} of {} has {per_group}",
                    g.cases.len(),
                    file.cases_per_class
                ));
            }
            for (c, i) in g
                .cases
                .iter()
                .zip(shard_indices(file.cases_per_class, (k, n)))
            {
                if c.index != i {
                    return corrupt(format!("{at}: case {} where {i} belongs", c.index));
                }
                let want = if c.truth.is_some() { methods.len() } else { 0 };
                if c.samples.len() != want {
                    return corrupt(format!(
                        "{at} case {i}: {} samples for {want} methods",
                        c.samples.len()
                    ));
                }
            }
        }
        Ok(Shard {
            tool: file.tool,
            seed: file.seed,
            cases: file.cases_per_class,
            methods,
            precisions: file.precisions,
            classes,
            shard: (k, n),
            groups: file.groups,
        })
    }
}

/// Shards that are each sound but do not make up one audit: different tool version, seed,
/// cases or selection, or a shard missing or given twice. The CLI exits 3 on it.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct IncompatibleShards(pub String);

/// Combines the shards `0/N … N−1/N` of one audit (each given once, in any order, with a name
/// for messages) into exactly the report the unsharded audit gives.
pub fn merge(shards: Vec<(String, Shard)>) -> Result<Report, IncompatibleShards> {
    let fail = |s: String| Err(IncompatibleShards(s));
    let Some((first_name, first)) = shards.first() else {
        return fail("no shard given".into());
    };
    // Same tool, seed, cases, selection and N everywhere
    for (name, s) in &shards {
        if s.tool != TOOL {
            return fail(format!(
                "{name} was written by {}, but this is {TOOL}",
                s.tool
            ));
        }
    }
    let names = |ms: &[&'static Method]| ms.iter().map(|m| m.name).collect::<Vec<_>>().join(",");
    let classes = |cs: &[Class]| cs.iter().map(|c| c.name()).collect::<Vec<_>>().join(",");
    let precisions = |ps: &[Precision]| ps.iter().map(|p| p.name()).collect::<Vec<_>>().join(",");
    let key = |s: &Shard| {
        [
            ("seed", s.seed.to_string()),
            ("cases per class", s.cases.to_string()),
            ("methods", names(&s.methods)),
            ("precisions", precisions(&s.precisions)),
            ("classes", classes(&s.classes)),
            ("shard count N", s.shard.1.to_string()),
        ]
    };
    let want = key(first);
    for (name, s) in &shards[1..] {
        for ((what, a), (_, b)) in want.iter().zip(key(s)) {
            if *a != b {
                return fail(format!(
                    "{first_name} and {name} are not shards of one audit: {what} {a} vs {b}"
                ));
            }
        }
    }
    // Each of 0/N … N−1/N exactly once
    let n = first.shard.1;
    let mut by_k = std::collections::BTreeMap::new();
    for (name, s) in &shards {
        let k = s.shard.0;
        if let Some(other) = by_k.insert(k, name) {
            return fail(format!("shard {k}/{n} given twice: {other} and {name}"));
        }
    }
    if (by_k.len() as u64) < n {
        let missing: Vec<String> = (0..n)
            .filter(|k| !by_k.contains_key(k))
            .take(4)
            .map(|k| format!("{k}/{n}"))
            .collect();
        let more = if n - by_k.len() as u64 > missing.len() as u64 {
            ", …"
        } else {
            ""
        };
        return fail(format!(
            "missing shard {}{more}: a merge needs each of 0/{n} … {}/{n} once",
            missing.join(", "),
            n - 1
        ));
    }
    // Interleave by index, group by group, and aggregate as an unsharded run does
    let (seed, cases, methods) = (first.seed, first.cases, first.methods.clone());
    let mut parts: Vec<Shard> = shards.into_iter().map(|(_, s)| s).collect();
    parts.sort_by_key(|s| s.shard.0);
    let mut groups: Vec<std::vec::IntoIter<Group>> =
        parts.into_iter().map(|s| s.groups.into_iter()).collect();
    let mut rows = vec![];
    while let Some(first_group) = groups[0].next() {
        let (precision, class) = (first_group.precision, first_group.class);
        let mut streams = vec![first_group.cases.into_iter()];
        for g in &mut groups[1..] {
            streams.push(g.next().expect("validated: same groups").cases.into_iter());
        }
        let cases: Vec<CaseResult> = (0..cases)
            .map(|i| {
                streams[(i % n) as usize]
                    .next()
                    .expect("validated: every index")
            })
            .collect();
        rows.extend(group_rows(
            &methods,
            &Group {
                precision,
                class,
                cases,
            },
        ));
    }
    Ok(Report {
        tool: TOOL,
        seed,
        cases_per_class: cases,
        shard: "0/1".into(),
        rows,
    })
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
                    method_t: r.samples[k].t.map(hex_float),
                    oracle_t: r.oracle_t.map(hex_float),
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
                if let Some(c) = r.cond {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::sphere::methods::METHODS;

    fn round_trip(x: f64) -> f64 {
        let text = serde_json::to_string(&Exact(x)).unwrap();
        serde_json::from_str::<Exact>(&text).unwrap().0
    }

    #[test]
    fn floats_round_trip_exactly_through_shard_json() {
        let specials = [
            0.0,
            -0.0,
            0.1,
            -3.5,
            f64::MIN_POSITIVE,
            f64::from_bits(1),
            -f64::from_bits(0x000f_ffff_ffff_ffff),
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
            f64::from_bits(0x7ff0_0000_0000_0001),
            0.1f32 as f64,
        ];
        for x in specials {
            assert_eq!(round_trip(x).to_bits(), x.to_bits(), "{}", Exact(x).text());
        }
        // A sweep of bit patterns over every exponent
        let mut h = 0x243f_6a88_85a3_08d3u64;
        for _ in 0..20_000 {
            h = h
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let x = f64::from_bits(h);
            assert_eq!(round_trip(x).to_bits(), h, "{}", Exact(x).text());
        }
        assert_eq!(Exact(f64::NAN).text(), "nan:0x7ff8000000000000");
        for bad in ["\"0x1.zzp+1\"", "\"nan:0x0\"", "\"\"", "1.5", "null"] {
            assert!(serde_json::from_str::<Exact>(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_shard_survives_its_file_and_merges_into_the_run() {
        let opts = |shard| AuditOptions {
            cases: 25,
            seed: 9,
            methods: METHODS.iter().collect(),
            precisions: Precision::ALL.to_vec(),
            classes: vec![Class::Tangent, Class::Invalid],
            shard,
            progress: false,
        };
        let full = run(&opts((0, 1)));
        let mut shards = vec![];
        for k in [1, 0] {
            let (report, shard) = run_shard(&opts((k, 2)));
            assert_eq!(report.shard, format!("{k}/2"));
            let text = shard.to_json();
            let back = Shard::from_json(text.as_bytes()).unwrap();
            assert_eq!(back.to_json(), text);
            shards.push((format!("s{k}"), back));
        }
        assert_eq!(merge(shards).unwrap(), full);
    }
}
