//! A tolerance file's `[[robustness]]` rules: what a user holds a routine's reintersection,
//! watertightness and spawn-rule rows to, instead of the default (no self-hit under the offset
//! rule, no escape through a closed mesh or a fold, for robust built-in methods and every
//! outside routine; no self-hit and no ray behind the surface for `audit --spawn-rule` rules of
//! the user's and for `pbrt`).
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
//! # reported = true          # instead of a bound: the rows are reported only
//! why = "where the numbers came from"
//! ```
//! The first rule that names a row's method, test and precision judges it; rows of the offset
//! rule's controls (`weak`, `off`) stay controls.

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
}

/// The names that have rows of each test in an audit.
#[derive(Clone, Debug, Default)]
pub struct Tested {
    /// Methods with reintersection rows.
    pub reintersection: Vec<String>,
    /// Methods with watertightness rows.
    pub watertight: Vec<String>,
    /// Spawn rules (`audit --spawn-rule`).
    pub spawn: Vec<String>,
}

impl Tested {
    fn has(&self, name: &str, t: Test) -> bool {
        let list = match t {
            Test::Reintersection => &self.reintersection,
            Test::Watertight => &self.watertight,
            Test::Spawn => &self.spawn,
        };
        list.iter().any(|x| x == name)
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

    /// The verdict of a row of `test` with `count` escapes or self-hits.
    pub fn verdict(&self, test: Test, count: u64) -> &'static str {
        let bound = match test {
            Test::Watertight => self.max_escapes,
            Test::Reintersection | Test::Spawn => self.max_self_hits,
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
        let shadowed = r.methods.iter().all(|m| {
            tests.iter().all(|&t| {
                precs
                    .iter()
                    .all(|p| rules[..i].iter().any(|e| e.applies(m, t, p.name())))
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
                Some("reintersection") => Some(Test::Reintersection),
                Some("watertight") => Some(Test::Watertight),
                Some("spawn") => Some(Test::Spawn),
                Some(t) => {
                    return bad(format!(
                        "test = \"{t}\" (\"reintersection\", \"watertight\" or \"spawn\")"
                    ))
                }
            };
            if test == Some(Test::Spawn) {
                if let Some(m) = methods.iter().find(|m| !tested.spawn.contains(m)) {
                    return bad(format!(
                        "no spawn rule '{m}' in this audit (an audit's --spawn-rule gives one; this audit's: {})",
                        if tested.spawn.is_empty() { "none".into() } else { tested.spawn.join(", ") }
                    ));
                }
            } else if let Some(m) = methods.iter().find(|m| !known_methods.contains(&m.as_str())) {
                return bad(format!(
                    "no method '{m}' in this audit (known: {})",
                    known_methods.join(", ")
                ));
            }
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
                    Some(Test::Spawn) => "spawn rows",
                    None => "reintersection or watertightness rows (a spawn rule's rule says test = \"spawn\")",
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
            let bounds = r.max_escapes.is_some() || r.max_self_hits.is_some();
            if reported == bounds {
                return bad(
                    "give reported = true or a bound (max_escapes, max_self_hits), exactly one".into(),
                );
            }
            // Every test the rule names is bounded: a rule for both needs both bounds
            let needs_escapes = test.is_none() || test == Some(Test::Watertight);
            let needs_self_hits = test != Some(Test::Watertight);
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
                reported,
            })
        })
        .collect()
}
