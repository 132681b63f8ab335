//! A tolerance file's `[[robustness]]` rules: what a user holds a routine's reintersection,
//! watertightness, spawn-rule and seam rows to, instead of the default (no self-hit under the
//! offset rule, no escape through a closed mesh or a fold, for robust built-in methods and every
//! outside routine; no self-hit and no ray behind the surface for `audit --spawn-rule` rules of
//! the user's and for `pbrt`; for the seams between routines, no lost box for `ize` and every
//! `--guard` of yours, every ray reported once for `watertight_wide` and every outside triangle
//! routine, no wrong verdict in the `ideal` transform mode for the robust built-ins and every
//! outside routine).
//!
//! ```toml
//! [[robustness]]
//! method = "mine"            # one name or a list: built-in or outside (`--name`, `--spawn-name`)
//! test = "watertight"        # or "reintersection" or "spawn"; left out: reintersection and
//!                            # watertightness
//! precision = "f32"          # left out: both
//! max_escapes = 3            # watertightness: escapes allowed per row
//! max_self_hits = 0          # reintersection: self-hits allowed per row (beyond the neighbour's);
//!                            # spawn: self-hits, and rays behind the surface, allowed per row
//! max_gap_ulps = 64          # spawn only: the widest resolved gap allowed per row, in ulps of
//!                            # max|p| (left out: the gap is reported)
//! max_failures = 0           # guard, once, transform: failures allowed per row (guard: boxes
//!                            # lost; once: rays leaked, split or hit wrongly; transform: false
//!                            # hits and misses on well-posed cases). A bad t fails any row.
//! mode = "matrix"            # transform only: one mode or a list (left out: every mode)
//! # reported = true          # instead of a bound: the rows are reported only
//! why = "where the numbers came from"
//! ```
//! The first rule that names a row's method, test and precision (and a transform row's mode)
//! judges it; rows of the offset rule's controls (`weak`, `off`) stay controls. A rule for a
//! spawn rule or a seam names its `test`; one without `test` is for reintersection and
//! watertightness.

use crate::numerics::Precision;
use serde::Deserialize;

/// The two tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Test {
    /// Rays spawned from a computed hit must not hit their own surface.
    Reintersection,
    /// Rays through a closed mesh or a fold must not escape.
    Watertight,
    /// A spawn rule's rays must not re-hit their surface nor start behind it (`audit
    /// --spawn-rule`).
    Spawn,
    /// A box test before the primitive must not cull a box holding the hit (`audit --guard`).
    Guard,
    /// A closed mesh must report each ray through a shared edge or vertex exactly once.
    Once,
    /// A shape behind an instance transform must keep the exact verdict.
    Transform,
}

impl Test {
    /// The name a rule's `test` gives.
    pub fn name(self) -> &'static str {
        match self {
            Test::Reintersection => "reintersection",
            Test::Watertight => "watertight",
            Test::Spawn => "spawn",
            Test::Guard => "guard",
            Test::Once => "once",
            Test::Transform => "transform",
        }
    }

    /// Whether its rows are bounded by `max_failures` (a seam's).
    fn is_seam(self) -> bool {
        matches!(self, Test::Guard | Test::Once | Test::Transform)
    }
}

/// Every test, in the order a rule's error names them.
const ALL: [Test; 6] = [
    Test::Reintersection,
    Test::Watertight,
    Test::Spawn,
    Test::Guard,
    Test::Once,
    Test::Transform,
];

/// The names that have rows of each test in an audit.
#[derive(Clone, Debug, Default)]
pub struct Tested {
    /// Methods with reintersection rows.
    pub reintersection: Vec<String>,
    /// Methods with watertightness rows.
    pub watertight: Vec<String>,
    /// Spawn rules (`audit --spawn-rule`).
    pub spawn: Vec<String>,
    /// Guards with rows (the built-ins with the box shape, `audit --guard`).
    pub guard: Vec<String>,
    /// Triangle routines with exactly-once rows.
    pub once: Vec<String>,
    /// Sphere and triangle routines with transform rows.
    pub transform: Vec<String>,
}

impl Tested {
    fn list(&self, t: Test) -> &[String] {
        match t {
            Test::Reintersection => &self.reintersection,
            Test::Watertight => &self.watertight,
            Test::Spawn => &self.spawn,
            Test::Guard => &self.guard,
            Test::Once => &self.once,
            Test::Transform => &self.transform,
        }
    }

    fn has(&self, name: &str, t: Test) -> bool {
        self.list(t).iter().any(|x| x == name)
    }
}

/// A rule as written in the file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobustRuleText {
    method: OneOrMany,
    test: Option<String>,
    precision: Option<OneOrMany>,
    max_escapes: Option<u64>,
    max_self_hits: Option<u64>,
    max_gap_ulps: Option<f64>,
    max_failures: Option<u64>,
    mode: Option<OneOrMany>,
    reported: Option<bool>,
    why: String,
}

/// One name or a list of names.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum OneOrMany {
    One(String),
    Many(Vec<String>),
}

impl OneOrMany {
    fn list(&self) -> Vec<String> {
        match self {
            OneOrMany::One(s) => vec![s.clone()],
            OneOrMany::Many(v) => v.clone(),
        }
    }
}

/// A rule, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct RobustRule {
    /// Where it was read: `FILE robustness rule N`.
    pub origin: String,
    /// The methods it applies to.
    pub methods: Vec<String>,
    /// The test (`None`: both).
    pub test: Option<Test>,
    /// The precisions (`None`: both).
    pub precisions: Option<Vec<Precision>>,
    /// Escapes allowed per watertightness row.
    pub max_escapes: Option<u64>,
    /// Self-hits allowed per reintersection row, beyond those at a neighbouring triangle; per
    /// spawn row, self-hits and rays behind the surface.
    pub max_self_hits: Option<u64>,
    /// The widest resolved gap allowed per spawn row, in ulps of `max|p|`.
    pub max_gap_ulps: Option<f64>,
    /// Failures allowed per guard, once or transform row.
    pub max_failures: Option<u64>,
    /// The transform modes it names (`None`: every mode).
    pub modes: Option<Vec<String>>,
    /// The rows are reported, not judged.
    pub reported: bool,
}

impl RobustRule {
    /// Whether the rule names this row.
    pub fn applies(&self, method: &str, test: Test, precision: &str) -> bool {
        self.methods.iter().any(|m| m == method)
            && self.test.is_none_or(|t| t == test)
            && self
                .precisions
                .as_ref()
                .is_none_or(|ps| ps.iter().any(|p| p.name() == precision))
    }

    /// Whether the rule names some row of `r`: a rule of the user's file that names none is
    /// said in a `note:` line, so that its silence is not read as its pass (helper-21 F4).
    pub fn names_a_row(&self, r: &super::Robustness) -> bool {
        let a = |m: &str, t: Test, p: &str| self.applies(m, t, p);
        r.reintersection
            .iter()
            .any(|x| a(&x.method, Test::Reintersection, &x.precision))
            || r.watertight
                .iter()
                .any(|x| a(&x.method, Test::Watertight, &x.precision))
            || r.spawn
                .iter()
                .any(|x| a(&x.rule, Test::Spawn, &x.precision))
            || r.guard
                .iter()
                .any(|x| a(&x.guard, Test::Guard, &x.precision))
            || r.once
                .iter()
                .any(|x| a(&x.routine, Test::Once, &x.precision))
            || r.transform
                .iter()
                .any(|x| a(&x.routine, Test::Transform, &x.precision) && self.names_mode(&x.mode))
    }

    /// Whether the rule names a transform row's mode (every mode when it names none).
    pub fn names_mode(&self, mode: &str) -> bool {
        self.modes
            .as_ref()
            .is_none_or(|ms| ms.iter().any(|m| m == mode))
    }

    /// The verdict of a row of `test` with `count` escapes, self-hits or failures.
    pub fn verdict(&self, test: Test, count: u64) -> &'static str {
        let bound = match test {
            Test::Watertight => self.max_escapes,
            Test::Reintersection | Test::Spawn => self.max_self_hits,
            Test::Guard | Test::Once | Test::Transform => self.max_failures,
        };
        match bound {
            _ if self.reported => "reported",
            Some(b) if count > b => "fail",
            Some(_) => "pass",
            // Checked at load: a rule that judges a test bounds it
            None => "reported",
        }
    }

    /// The goal of a spawn row (`None`: reported).
    pub fn spawn_goal(&self) -> Option<super::spawn::Goal> {
        match (self.reported, self.max_self_hits) {
            (false, Some(m)) => Some(super::spawn::Goal {
                max_self_hits: m,
                max_gap_ulps: self.max_gap_ulps,
            }),
            _ => None,
        }
    }
}

/// The tests a rule without `test` names: reintersection and watertightness (a spawn rule's
/// rows are named explicitly).
const BOTH: [Test; 2] = [Test::Reintersection, Test::Watertight];

/// Checks the rules of `file` against the methods the audit knows. Errors are one line.
pub fn parse(
    texts: Vec<RobustRuleText>,
    file: &str,
    known_methods: &[&str],
    tested: &Tested,
) -> Result<Vec<RobustRule>, String> {
    let rules = parse_each(texts, file, known_methods, tested)?;
    // A rule every row of which an earlier rule takes judges nothing
    for (i, r) in rules.iter().enumerate() {
        let tests = r.test.map_or(BOTH.to_vec(), |t| vec![t]);
        let precs = r
            .precisions
            .clone()
            .unwrap_or(vec![Precision::F32, Precision::F64]);
        let modes: Vec<&str> = match &r.modes {
            Some(ms) => ms.iter().map(|m| m.as_str()).collect(),
            None => super::transform::MODES.to_vec(),
        };
        let shadowed = r.methods.iter().all(|m| {
            tests.iter().all(|&t| {
                precs.iter().all(|p| {
                    modes.iter().all(|mode| {
                        rules[..i].iter().any(|e| {
                            e.applies(m, t, p.name())
                                && (t != Test::Transform || e.names_mode(mode))
                        })
                    })
                })
            })
        });
        if shadowed {
            return Err(format!(
                "{}: every row it names is judged by an earlier rule (shadowed): the rule could never judge a row",
                r.origin
            ));
        }
    }
    Ok(rules)
}

/// Each rule checked on its own.
fn parse_each(
    texts: Vec<RobustRuleText>,
    file: &str,
    known_methods: &[&str],
    tested: &Tested,
) -> Result<Vec<RobustRule>, String> {
    texts
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            let origin = format!("{file} robustness rule {}", i + 1);
            let bad = |what: String| Err(format!("{origin}: {what}"));
            let methods = r.method.list();
            if methods.is_empty() {
                return bad("name at least one method".into());
            }
            let test = match r.test.as_deref() {
                None => None,
                Some(t) => match ALL.into_iter().find(|x| x.name() == t) {
                    Some(x) => Some(x),
                    None => {
                        let names: Vec<String> =
                            ALL.iter().map(|x| format!("\"{}\"", x.name())).collect();
                        return bad(format!("test = \"{t}\" ({})", names.join(", ")));
                    }
                },
            };
            if let Some(t) = test.filter(|t| *t == Test::Spawn || t.is_seam()) {
                // A spawn rule's or a seam's names are those with rows of that test
                let list = tested.list(t);
                if let Some(m) = methods.iter().find(|m| !list.contains(m)) {
                    let (what, hint) = match t {
                        Test::Spawn => ("spawn rule", "an audit's --spawn-rule gives one"),
                        Test::Guard => (
                            "guard",
                            "the box shape's audit runs the built-ins; --guard gives one",
                        ),
                        Test::Once => (
                            "triangle routine with exactly-once rows",
                            "the triangle's built-ins and yours have them",
                        ),
                        _ => (
                            "routine with transform rows",
                            "the sphere's and the triangle's default methods and yours have them",
                        ),
                    };
                    return bad(format!(
                        "no {what} '{m}' in this audit ({hint}; known: {})",
                        if list.is_empty() {
                            "none".into()
                        } else {
                            list.join(", ")
                        }
                    ));
                }
            } else if let Some(m) = methods.iter().find(|m| !known_methods.contains(&m.as_str())) {
                return bad(format!(
                    "no method '{m}' in this audit (known: {})",
                    known_methods.join(", ")
                ));
            }
            let seam = test.is_some_and(|t| t.is_seam());
            if r.max_failures.is_some() && !seam {
                return bad("max_failures bounds a seam's rows (test = \"guard\", \"once\" or \"transform\")".into());
            }
            if seam && (r.max_escapes.is_some() || r.max_self_hits.is_some()) {
                return bad("a seam's rows are bounded by max_failures (not max_escapes or max_self_hits)".into());
            }
            let modes = match &r.mode {
                None => None,
                Some(_) if test != Some(Test::Transform) => {
                    return bad("mode names transform rows (test = \"transform\")".into())
                }
                Some(m) => {
                    let list = m.list();
                    if let Some(x) = list
                        .iter()
                        .find(|x| !super::transform::MODES.contains(&x.as_str()))
                    {
                        return bad(format!(
                            "mode = \"{x}\" ({})",
                            super::transform::MODES.join(", ")
                        ));
                    }
                    if list.is_empty() {
                        return bad("mode: name at least one".into());
                    }
                    Some(list)
                }
            };
            let precisions = match &r.precision {
                None => None,
                Some(n) => Some(
                    n.list()
                        .iter()
                        .map(|p| match p.as_str() {
                            "f32" => Ok(Precision::F32),
                            "f64" => Ok(Precision::F64),
                            _ => Err(format!("{origin}: unknown precision '{p}' (f32, f64)")),
                        })
                        .collect::<Result<Vec<_>, _>>()?,
                ),
            };
            // A rule must be able to judge some row: each method has rows of a test it names
            let tests: Vec<Test> = test.map_or(BOTH.to_vec(), |t| vec![t]);
            if let Some(m) = methods.iter().find(|m| !tests.iter().any(|&t| tested.has(m, t))) {
                let what = match test {
                    Some(Test::Reintersection) => "reintersection rows (they run for the built-in methods of the box, sphere, ellipsoid, cylinder, torus and triangle, and for outside sphere and triangle routines)",
                    Some(Test::Watertight) => "watertightness rows (they run for triangle routines)",
                    Some(t) => &format!("{} rows", t.name()),
                    None => "reintersection or watertightness rows (a spawn rule's or a seam's rule names its test)",
                };
                return bad(format!("method '{m}' has no {what}: the rule could never judge a row"));
            }
            let reported = r.reported.unwrap_or(false);
            if r.why.trim().is_empty() {
                return bad("say why (where its numbers came from)".into());
            }
            if test == Some(Test::Reintersection) && r.max_escapes.is_some() {
                return bad("max_escapes bounds the watertightness test, not reintersection".into());
            }
            if test == Some(Test::Watertight) && r.max_self_hits.is_some() {
                return bad("max_self_hits bounds the reintersection test, not watertightness".into());
            }
            if test == Some(Test::Spawn) && r.max_escapes.is_some() {
                return bad("max_escapes bounds the watertightness test, not spawn rules".into());
            }
            if let Some(g) = r.max_gap_ulps {
                if test != Some(Test::Spawn) {
                    return bad("max_gap_ulps bounds a spawn rule's rows (test = \"spawn\")".into());
                }
                if !(g >= 0.0 && g.is_finite()) {
                    return bad(format!("max_gap_ulps = {g}: a number of ulps (finite, >= 0)"));
                }
                if r.max_self_hits.is_none() {
                    return bad("max_gap_ulps goes with max_self_hits (the self-hits a row may have)".into());
                }
            }
            let bounds =
                r.max_escapes.is_some() || r.max_self_hits.is_some() || r.max_failures.is_some();
            if reported == bounds {
                return bad(
                    "give reported = true or a bound (max_escapes, max_self_hits, max_failures), exactly one".into(),
                );
            }
            // Every test the rule names is bounded: a rule for both needs both bounds
            let needs_escapes = test.is_none() || test == Some(Test::Watertight);
            let needs_self_hits = test.is_none_or(|t| !t.is_seam() && t != Test::Watertight);
            if bounds
                && ((needs_escapes && r.max_escapes.is_none())
                    || (needs_self_hits && r.max_self_hits.is_none()))
            {
                return bad(
                    "a rule for both tests bounds both (max_escapes and max_self_hits), or names its test".into(),
                );
            }
            Ok(RobustRule {
                origin,
                methods,
                test,
                precisions,
                max_escapes: r.max_escapes,
                max_self_hits: r.max_self_hits,
                max_gap_ulps: r.max_gap_ulps,
                max_failures: r.max_failures,
                modes,
                reported,
            })
        })
        .collect()
}
