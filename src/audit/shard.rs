//! Sharding: `rayproof audit --shard K/N --shard-out FILE` runs the cases whose index ≡ K
//! (mod N) of every shape selected and writes their tallies; `rayproof merge` checks that the
//! files are the shards 0/N … N−1/N of one audit and merges them into exactly the report of the
//! unsharded run (byte for byte: tallies merge exactly, see [`super::tally`]).
//!
//! # Running a sharded audit
//!
//! `--shard K/N` runs only the cases whose index ≡ K (mod N), in every shape × precision × class
//! selected, and `--shard-out FILE` writes that shard's tallies. `rayproof merge` combines the files
//! of shards 0/N … N−1/N into the unsharded audit: its JSON, Markdown, table and exit status are
//! byte for byte those of one `rayproof audit` with the same seed, `--cases` and selection (only
//! the timing lines differ). This holds for every shape and any selection of shapes, because a
//! row's tally merges exactly: counts add, value errors are kept as exact histograms, and the
//! worst cases are chosen by rules that do not depend on the order of the cases. On two CI
//! machines and a merge job:
//!
//! ```sh
//! rayproof audit --cases 200000 --shard 0/2 --shard-out shard-0.json   # machine 1
//! rayproof audit --cases 200000 --shard 1/2 --shard-out shard-1.json   # machine 2
//! rayproof merge shard-0.json shard-1.json --json audit.json --markdown audit.md
//! ```
//!
//! A shard run exits 0 and leaves the tolerance table to the merge, which judges the whole run.
//! **A shard carries its judgement**: the user's rules it was run with (`--tolerances FILE`: the
//! file's name, text and SHA-256) are in the file, and the merge judges with exactly them,
//! given `--tolerances` again or not, so a merged audit exits as the unsharded one does. Shards
//! run with different tables (or some with and some without) are not one audit (exit 3), and so
//! is a merge given a `--tolerances` file that is not the one the shards carry.
//! The merge takes the files in any order, and runs the reintersection and watertightness tests
//! and the built-in seam rows (box guards, exactly once, transforms) itself for the shapes whose
//! built-in methods and classes the audit covers (they are not sharded). The watertightness rows of triangle routines from
//! outside the crate are run whole by shard 0 and carried in its file, since the merge machine
//! need not have the routine. It refuses, with one line on stderr, a set that is not
//! exactly one audit's shards 0/N … N−1/N: a shard missing or given twice, or shards that differ
//! in rayproof version, seed, shapes, `--cases`, methods, precisions, classes (order included) or N
//! give exit 3. A file that is unreadable, truncated, corrupt or not a shard gives exit 2; each
//! file must hold every shape × precision × class of its selection, with one tally per method
//! holding exactly its shard's number of cases.
//!
//! # The shard file
//!
//! A shard file (format [`SHARD_FORMAT`], version [`SHARD_FORMAT_VERSION`]) is one line of JSON
//! with `"format": "rayproof-audit-shard"`, `"format_version": 8`, `tool`,
//! `seed`, `every_shape`, `"shard": {"k", "n"}`, `tolerances`, `shapes`, `spawn_rules`, `guards`
//! and `outside` (the reintersection, watertightness, exactly-once and transform rows of routines
//! from outside the crate, and the rows of `--spawn-rule` rules and `--guard` guards, unjudged:
//! shard 0 holds every one of them, the others none): per shape its selection
//! (`cases_per_class`, `methods` with their `robust` flag, `precisions`, `classes`) and `groups`,
//! one per precision × class in selection order, each with one tally per method (counts, the value
//! errors as a `{value: count}` histogram, err/cond and residuals as histograms of values rounded
//! to 8 significant bits with the exact maximum beside, and the candidate worst cases with their
//! inputs). Example inputs and values are hex text (`0x1.8p+1`, `-0x0p+0`, `inf`; a NaN by its
//! bits, `nan:0x7ff8000000000000`), so they round-trip exactly; counts are JSON integers. The
//! few floats of the `outside` rows (a watertightness row's rate, a spawn row's gap) are JSON
//! numbers, written shortest and read correctly rounded (serde_json's `float_roundtrip`): they
//! round-trip exactly too (a merge's JSON is byte-identical to the unsharded audit's).
//!
//! Measured on a 2-core machine with the default audit (every shape, seed 1) in 3 shards: each
//! shard took 47–53 s and wrote a file of 12.4 MB (4.3 MB gzipped); the files' size grows with the
//! number of distinct errors, not with the number of cases (most of it is the exact error
//! histograms of the naive sphere and `rcp`/`rsqrt` rows, whose errors are nearly all distinct).
//! The merge took 5.6 s, including the reintersection tests, and 104 MB of memory, and its JSON
//! and Markdown were byte-identical to the unsharded run's.

use super::run::{Group, MethodTag, Tallies};
use super::tally::Tally;
use crate::audit::robustness::Outside;
use crate::numerics::Precision;
use crate::shapes::shape::Shape;
use serde::{Deserialize, Serialize};

/// The tag in the `format` field of a shard file.
pub const SHARD_FORMAT: &str = "rayproof-audit-shard";
/// The version in the `format_version` field; a reader refuses any other.
pub const SHARD_FORMAT_VERSION: u32 = 8;

/// The user's tolerance rules a shard was run with (`--tolerances FILE`), carried whole so that
/// the merge judges with exactly them: the file's name as given (rule origins name it), its
/// text and the SHA-256 of the text.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UserTable {
    /// The file as the shard's command line named it.
    pub file: String,
    /// The SHA-256 of `text`, hex.
    pub sha256: String,
    /// The rules, as read.
    pub text: String,
}

impl UserTable {
    /// The table of a file named `file` with this text.
    pub fn new(file: &str, text: &str) -> UserTable {
        use sha2::{Digest, Sha256};
        let sha256 = Sha256::digest(text.as_bytes())
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        UserTable {
            file: file.to_string(),
            sha256,
            text: text.to_string(),
        }
    }
    /// One line naming it: the file and the start of its hash.
    pub fn label(t: &Option<UserTable>) -> String {
        match t {
            Some(t) => format!("--tolerances {} (sha256 {})", t.file, &t.sha256[..12]),
            None => "the built-in table alone (no --tolerances)".into(),
        }
    }
}

/// One precision × class of a shard: a tally per method.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct GroupFile {
    precision: Precision,
    class: String,
    tallies: Vec<Tally>,
    /// [`Group::digest`]: the cases this shard ran.
    digest: u64,
}

/// One shape of a shard.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeShard {
    /// The shape's name.
    pub shape: String,
    /// Cases per class and precision.
    pub cases_per_class: u64,
    /// The methods, in tally order.
    pub methods: Vec<MethodTag>,
    /// Precisions run.
    pub precisions: Vec<Precision>,
    /// Class names run.
    pub classes: Vec<String>,
    groups: Vec<GroupFile>,
}

/// `k` and `n` of a shard file.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShardId {
    k: u64,
    n: u64,
}

/// A shard file (field order is the file's).
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shard {
    format: String,
    format_version: u32,
    /// The tool and version that wrote the shard (merging refuses a mismatch).
    pub tool: String,
    /// Seed of the case streams.
    pub seed: u64,
    /// The audit covers every shape (the merge then adds the reintersection tests).
    pub every_shape: bool,
    shard: ShardId,
    /// The user's tolerance rules the shard was run with (`None`: the built-in table alone).
    pub tolerances: Option<UserTable>,
    /// One entry per shape, in audit order.
    pub shapes: Vec<ShapeShard>,
    /// The spawn rules the audit was run with (`--spawn-rule`), each as its name and, for a
    /// rule from outside the crate, how it was given: every shard names the same, and shard 0
    /// holds their rows.
    pub spawn_rules: Vec<String>,
    /// The box guards the audit was run with (`--guard`), named as the spawn rules are: every
    /// shard names the same, and shard 0 holds their rows.
    pub guards: Vec<String>,
    /// The seams were run for the outside routines (the default; not with `--no-seams`): shard 0 holds their rows.
    pub outside_seams: bool,
    /// The reintersection and watertightness rows of routines from outside the crate: run whole
    /// by shard 0 (the built-in methods' are run by the merge; an outside routine may be gone by
    /// then).
    pub outside: Outside,
}

/// Just the tag of a file, to tell "not a shard" from "a corrupt shard".
#[derive(Deserialize)]
struct FormatTag {
    format: Option<serde_json::Value>,
    format_version: Option<serde_json::Value>,
}

impl Shard {
    /// The shard of a run.
    pub fn new(
        tool: &str,
        seed: u64,
        every_shape: bool,
        (k, n): (u64, u64),
        tolerances: Option<UserTable>,
        parts: &[Tallies],
        [spawn_rules, guards]: [Vec<String>; 2],
        outside_seams: bool,
        outside: Outside,
    ) -> Shard {
        let shapes = parts
            .iter()
            .map(|p| {
                let info = p.shape.info();
                let mut precisions = vec![];
                let mut classes = vec![];
                for g in &p.groups {
                    if !precisions.contains(&g.precision) {
                        precisions.push(g.precision);
                    }
                    let c = info.classes[g.class].to_string();
                    if !classes.contains(&c) {
                        classes.push(c);
                    }
                }
                ShapeShard {
                    shape: info.name.to_string(),
                    cases_per_class: p.cases,
                    methods: p.methods.clone(),
                    precisions,
                    classes,
                    groups: p
                        .groups
                        .iter()
                        .map(|g| GroupFile {
                            precision: g.precision,
                            class: info.classes[g.class].to_string(),
                            tallies: g.tallies.clone(),
                            digest: g.digest,
                        })
                        .collect(),
                }
            })
            .collect();
        Shard {
            format: SHARD_FORMAT.into(),
            format_version: SHARD_FORMAT_VERSION,
            tool: tool.into(),
            seed,
            every_shape,
            shard: ShardId { k, n },
            tolerances,
            shapes,
            spawn_rules,
            guards,
            outside_seams,
            outside,
        }
    }

    /// `(k, n)`: this shard holds the cases whose index ≡ k (mod n).
    pub fn id(&self) -> (u64, u64) {
        (self.shard.k, self.shard.n)
    }

    /// The file: one line of JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a shard serialises") + "\n"
    }

    /// Reads a shard file, checking that it is complete and consistent in itself: every shape
    /// known, every precision × class of its selection in order, one tally per method, each
    /// tally holding this shard's number of cases. The error is one line.
    pub fn from_json(
        bytes: &[u8],
        shape_by_name: impl Fn(&str) -> Option<&'static dyn Shape>,
    ) -> Result<Shard, String> {
        let not_shard =
            || format!("not a rayproof audit shard (no \"format\": \"{SHARD_FORMAT}\")");
        let file: Shard = match serde_json::from_slice(bytes) {
            Ok(f) => f,
            Err(e) => {
                // Tell a file of another kind from a damaged shard
                let tag = serde_json::from_slice::<FormatTag>(bytes).ok();
                let json = serde_json::from_slice::<serde::de::IgnoredAny>(bytes);
                return Err(match tag {
                    Some(t) if t.format != Some(SHARD_FORMAT.into()) => not_shard(),
                    Some(t) if t.format_version != Some(SHARD_FORMAT_VERSION.into()) => format!(
                        "shard format version {}, but this rayproof reads version {SHARD_FORMAT_VERSION}",
                        t.format_version.map(|v| v.to_string()).unwrap_or("(none)".into())
                    ),
                    None if json.is_ok() => not_shard(),
                    _ if json.is_err_and(|j| j.is_eof()) => format!("truncated shard ({e})"),
                    _ => format!("corrupt shard ({e})"),
                });
            }
        };
        if file.format != SHARD_FORMAT {
            return Err(not_shard());
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
        if file.shapes.is_empty() {
            return corrupt("no shape".into());
        }
        if k != 0 && file.outside != Outside::default() {
            return corrupt(format!(
                "shard {k}/{n} carries outside routines' robustness rows (only shard 0 runs them)"
            ));
        }
        if let Some(r) = file
            .outside
            .reintersection
            .iter()
            .find(|r| r.rehits > r.rays || r.neighbour > r.rehits || r.ill_posed > r.rays)
        {
            return corrupt(format!(
                "reintersection row {} {} {} {}: counts a run cannot make",
                r.shape, r.method, r.precision, r.rule
            ));
        }
        if let Some(w) = file.outside.watertight.iter().find(|w| {
            w.escaped > w.rays
                || w.grazing_well_posed > w.grazing
                || w.rate != w.escaped as f64 / w.rays.max(1) as f64
        }) {
            return corrupt(format!(
                "watertightness row {} {} {} {}: counts a run cannot make",
                w.method, w.precision, w.mesh, w.kind
            ));
        }
        if let Some(r) = file.outside.spawn.iter().find(|r| {
            r.self_hits > r.rays
                || r.self_hits_intersector > r.rays
                || r.behind > r.rays
                || !(r.gap >= 0.0 && r.gap.is_finite())
                || !(r.gap_ulps >= 0.0)
                || !(r.gap_tilted >= r.gap && r.gap_tilted.is_finite())
                || !(r.gap_tilted_ulps >= 0.0)
                || !r.verdict.is_empty()
                // A replay line is kept exactly when its kind of ray was counted
                || (r.self_hits > 0) != r.self_hit_replay.is_some()
                || (r.behind > 0) != r.behind_replay.is_some()
                || (r.gap > 0.0) != r.gap_replay.is_some()
        }) {
            return corrupt(format!(
                "spawn row {} {} 1e{} {}: counts a run cannot make",
                r.rule, r.precision, r.scale, r.placement
            ));
        }
        // Shard 0 holds a row per spawn rule × precision × scene size × placement, in order
        if k == 0 {
            let precisions = file.shapes[0].precisions.clone();
            let want: Vec<(String, String, i32, String)> = file
                .spawn_rules
                .iter()
                .map(|r| r.split(' ').next().unwrap_or_default().to_string())
                .flat_map(|rule| {
                    let precisions = precisions.clone();
                    precisions.into_iter().flat_map(move |p| {
                        let rule = rule.clone();
                        crate::audit::robustness::spawn::SCALES.flat_map(move |e| {
                            let rule = rule.clone();
                            crate::audit::robustness::spawn::PLACEMENTS.map(move |pl| {
                                (rule.clone(), p.name().to_string(), e, pl.to_string())
                            })
                        })
                    })
                })
                .collect();
            let have: Vec<(String, String, i32, String)> = file
                .outside
                .spawn
                .iter()
                .map(|r| {
                    (
                        r.rule.clone(),
                        r.precision.clone(),
                        r.scale,
                        r.placement.clone(),
                    )
                })
                .collect();
            if have != want {
                return corrupt(format!(
                    "its spawn rows ({}) are not one per spawn rule ({}) × precision × scene size × placement",
                    have.len(),
                    file.spawn_rules.len()
                ));
            }
        }
        if k == 0 {
            crate::audit::robustness::seams::check_shard_rows(
                &file.outside,
                &match file.outside_seams {
                    true => outside_routines(&file),
                    false => vec![],
                },
                &file.guards,
                &file.shapes[0].precisions,
            )
            .map_err(|e| format!("corrupt shard: {e}"))?;
        }
        if let Some(t) = &file.tolerances {
            if UserTable::new(&t.file, &t.text).sha256 != t.sha256 {
                return corrupt(format!(
                    "its tolerance table ({}) does not match its SHA-256",
                    t.file
                ));
            }
        }
        for s in &file.shapes {
            let Some(shape) = shape_by_name(&s.shape) else {
                return corrupt(format!("unknown shape '{}'", s.shape));
            };
            let info = shape.info();
            if let Some(c) = s
                .classes
                .iter()
                .find(|c| !info.classes.contains(&c.as_str()))
            {
                return corrupt(format!("{}: unknown class '{c}'", s.shape));
            }
            if s.methods.is_empty() || s.classes.is_empty() || s.precisions.is_empty() {
                return corrupt(format!("{}: empty selection", s.shape));
            }
            // Every precision × class in selection order, one tally per method
            let expected: Vec<(Precision, &str)> = s
                .precisions
                .iter()
                .flat_map(|&p| s.classes.iter().map(move |c| (p, c.as_str())))
                .collect();
            let got: Vec<(Precision, &str)> = s
                .groups
                .iter()
                .map(|g| (g.precision, g.class.as_str()))
                .collect();
            if got.len() != expected.len() {
                return corrupt(format!(
                    "{}: {} precision × class groups where the selection has {}",
                    s.shape,
                    got.len(),
                    expected.len()
                ));
            }
            if let Some((i, (g, e))) = got
                .iter()
                .zip(&expected)
                .enumerate()
                .find(|(_, (g, e))| g != e)
            {
                return corrupt(format!(
                    "{}: precision × class group {} is {} {} where the selection's order has {} {}",
                    s.shape,
                    i + 1,
                    g.0.name(),
                    g.1,
                    e.0.name(),
                    e.1
                ));
            }
            let per_group = super::run::shard_len(s.cases_per_class, (k, n));
            for g in &s.groups {
                let at = format!("{} {} {}", s.shape, g.precision.name(), g.class);
                if g.tallies.len() != s.methods.len() {
                    return corrupt(format!(
                        "{at}: {} tallies for {} methods",
                        g.tallies.len(),
                        s.methods.len()
                    ));
                }
                if let Some(t) = g.tallies.iter().find(|t| t.cases != per_group) {
                    return corrupt(format!(
                        "{at}: {} cases where shard {k}/{n} of {} has {per_group}",
                        t.cases, s.cases_per_class
                    ));
                }
                // Counts that a run cannot make (an edited or damaged file) judge nothing
                for (t, m) in g.tallies.iter().zip(&s.methods) {
                    if let Err(e) = t.check() {
                        return corrupt(format!("{at} {}: {e}", m.name));
                    }
                }
            }
        }
        Ok(file)
    }
}

/// The routines from outside the crate that have seam rows in a shard run without `--no-seams`, as
/// `(shape, name)` ([`crate::audit::robustness::seams::run_for`]).
fn outside_routines(file: &Shard) -> Vec<(String, String)> {
    let mut out = vec![];
    for s in &file.shapes {
        let Some(info) = crate::shapes::shape_by_name(&s.shape).map(|x| x.info()) else {
            continue;
        };
        if !crate::audit::robustness::seams::run_for(&info, s.classes.len()) {
            continue;
        }
        let builtin: Vec<&str> = info.methods.iter().map(|m| m.name).collect();
        for m in s
            .methods
            .iter()
            .filter(|m| !builtin.contains(&m.name.as_str()))
        {
            out.push((s.shape.clone(), m.name.clone()));
        }
    }
    out
}

/// Shards that are each sound but do not make up one audit: different tool version, seed,
/// cases or selection, or a shard missing or given twice. The CLI exits 3 on it.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct IncompatibleShards(pub String);

/// Checks that the shards are the shards `0/N … N−1/N` of one audit, each given once.
fn check_one_audit(tool: &str, shards: &[(String, Shard)]) -> Result<(), IncompatibleShards> {
    let fail = |s: String| Err(IncompatibleShards(s));
    let Some((first_name, first)) = shards.first() else {
        return fail("no shard given".into());
    };
    // Same tool, seed, selection and N everywhere
    for (name, s) in shards {
        if s.tool != tool {
            return fail(format!(
                "{name} was written by {}, but this is {tool}",
                s.tool
            ));
        }
    }
    let key = |s: &Shard| {
        let sel = |f: &dyn Fn(&ShapeShard) -> String| {
            s.shapes.iter().map(f).collect::<Vec<_>>().join("; ")
        };
        [
            ("seed", s.seed.to_string()),
            ("shapes", sel(&|x| x.shape.clone())),
            ("cases per class", sel(&|x| x.cases_per_class.to_string())),
            (
                "methods",
                sel(&|x| {
                    x.methods
                        .iter()
                        .map(|m| match &m.identity {
                            Some(id) => format!("{} ({id})", m.name),
                            None => m.name.clone(),
                        })
                        .collect::<Vec<_>>()
                        .join(",")
                }),
            ),
            (
                "precisions",
                sel(&|x| {
                    x.precisions
                        .iter()
                        .map(|p| p.name())
                        .collect::<Vec<_>>()
                        .join(",")
                }),
            ),
            ("classes", sel(&|x| x.classes.join(","))),
            ("shard count N", s.shard.n.to_string()),
            ("tolerance table", UserTable::label(&s.tolerances)),
            ("spawn rules", s.spawn_rules.join("; ")),
            ("guards", s.guards.join("; ")),
            (
                "seams for outside routines (not --no-seams)",
                s.outside_seams.to_string(),
            ),
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
    let n = first.shard.n;
    let mut by_k = std::collections::BTreeMap::new();
    for (name, s) in shards {
        let k = s.shard.k;
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
    // Each shard holds the cases of its label: every case it kept as an example has an index
    // ≡ k (mod N), and no two shards ran the same cases (a copy relabelled is not another
    // shard)
    for (name, s) in shards {
        let k = s.shard.k;
        for sh in &s.shapes {
            for g in &sh.groups {
                let stray = g
                    .tallies
                    .iter()
                    .flat_map(|t| &t.examples)
                    .map(|(_, c)| c.index)
                    .find(|i| i % n.max(1) != k);
                if let Some(i) = stray {
                    return fail(format!(
                        "{name} is labelled shard {k}/{n} but holds case {i} of {} {} {} (shard {}/{n}'s)",
                        sh.shape,
                        g.precision.name(),
                        g.class,
                        i % n.max(1)
                    ));
                }
            }
        }
    }
    for (i, (a_name, a)) in shards.iter().enumerate() {
        for (b_name, b) in &shards[i + 1..] {
            let same = a.shapes.iter().zip(&b.shapes).any(|(x, y)| {
                x.groups.iter().zip(&y.groups).any(|(g, h)| {
                    g.digest == h.digest
                        && super::run::shard_len(x.cases_per_class, (a.shard.k, n)) > 0
                })
            });
            if same {
                return fail(format!(
                    "{a_name} and {b_name} ran the same cases (shards {}/{n} and {}/{n} cannot): one is a copy",
                    a.shard.k, b.shard.k
                ));
            }
        }
    }
    Ok(())
}

/// Combines the shards `0/N … N−1/N` of one audit (each given once, in any order, with a name
/// for messages).
pub fn merge(
    tool: &str,
    shards: Vec<(String, Shard)>,
    shape_by_name: impl Fn(&str) -> Option<&'static dyn Shape>,
) -> Result<Merged, IncompatibleShards> {
    check_one_audit(tool, &shards)?;
    // Merge the tallies group by group
    let (seed, every_shape) = (shards[0].1.seed, shards[0].1.every_shape);
    let tolerances = shards[0].1.tolerances.clone();
    let mut outside = Outside::default();
    let mut parts = shards.into_iter().map(|(_, mut s)| {
        outside.append(&mut s.outside);
        s.shapes
    });
    let mut shapes: Vec<Tallies> = vec![];
    for s in parts.next().expect("one shard") {
        let shape = shape_by_name(&s.shape).expect("checked when read");
        let class = |name: &str| {
            shape
                .info()
                .classes
                .iter()
                .position(|c| *c == name)
                .expect("checked when read")
        };
        shapes.push(Tallies {
            shape,
            cases: s.cases_per_class,
            methods: s.methods,
            groups: s
                .groups
                .into_iter()
                .map(|g| Group {
                    precision: g.precision,
                    class: class(&g.class),
                    tallies: g.tallies,
                    digest: g.digest,
                })
                .collect(),
            oracle_nanos: 0,
        });
    }
    for other in parts {
        for (m, s) in shapes.iter_mut().zip(other) {
            for (mine, g) in m.groups.iter_mut().zip(s.groups) {
                for (t, u) in mine.tallies.iter_mut().zip(&g.tallies) {
                    t.merge(u);
                }
                mine.digest = mine.digest.wrapping_add(g.digest);
            }
        }
    }
    Ok(Merged {
        seed,
        every_shape,
        tolerances,
        shapes,
        outside,
    })
}

/// A merged audit: what the unsharded run would have tallied.
pub struct Merged {
    /// Seed of the case streams.
    pub seed: u64,
    /// The audit covers every shape (the reintersection and watertightness tests are added).
    pub every_shape: bool,
    /// The user's tolerance rules every shard was run with: the merge judges with them.
    pub tolerances: Option<UserTable>,
    /// Each shape's merged tallies.
    pub shapes: Vec<Tallies>,
    /// The reintersection and watertightness rows of outside routines (from shard 0).
    pub outside: Outside,
}

#[cfg(test)]
mod tests {
    use super::super::hexfloat::{exact_text, parse_exact};

    fn round_trip(x: f64) -> f64 {
        parse_exact(&exact_text(x)).unwrap()
    }

    #[test]
    fn floats_round_trip_exactly_through_shard_text() {
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
            assert_eq!(round_trip(x).to_bits(), x.to_bits(), "{}", exact_text(x));
        }
        // A sweep of bit patterns over every exponent
        let mut h = 0x243f_6a88_85a3_08d3u64;
        for _ in 0..20_000 {
            h = h
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            assert_eq!(round_trip(f64::from_bits(h)).to_bits(), h);
        }
        assert_eq!(exact_text(f64::NAN), "nan:0x7ff8000000000000");
        for bad in ["0x1.zzp+1", "nan:0x0", "", "1.5e", "null"] {
            assert!(parse_exact(bad).is_none(), "{bad}");
        }
    }
}
