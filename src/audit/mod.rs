//! The audit: every method × precision × class of a routine family against its exact oracle,
//! one framework for every shape.
//!
//! - [`shape`]: what a routine family is ([`Shape`]: fixed facts in a [`ShapeInfo`], plus
//!   `generate`, `oracle`, `run`) and what a method under audit is ([`Method`]: a shape's own
//!   [`Builtin`], or one written outside the crate);
//! - [`judge()`]: one rule turns (truth, answer) into a [`Judgement`];
//! - [`run`]: cases generated per `(seed, shape, class, precision, index)`, judged in parallel
//!   and added to mergeable [`tally::Tally`]s, so reports do not depend on the thread count and
//!   shards merge exactly ([`shard`]);
//! - [`report`], [`table`]: rows, JSON, the terminal table, Markdown and replayable worst
//!   cases; [`probe`] replays one case;
//! - [`tolerance`]: the one table of what every row must show, with verdicts that hold for any
//!   seed and any case count;
//! - [`plan`]: names on the command line resolved to the shapes, methods and classes to run;
//! - [`api`]: [`Audit`], auditing a routine written outside the crate from Rust;
//! - [`offline`]: `cases` and `score`, for code that cannot be called.
//!
//! # Running an audit
//!
//! `rayproof audit` runs every shape (the sphere, then the routines of Lengyel's ray-tracing
//! chapter, see [`crate::shapes`]): each method × {f32, f64} × class, with each shape's default case
//! count per class and precision (20,000 for the sphere), in parallel on all cores. A progress bar
//! shows on a terminal; off a terminal, one line per finished family goes to stderr. By default it
//! prints one screen: a line per family × precision (cases, the method with the most wrong
//! verdicts with its rate and worst class, and the rows' verdict), two lines for the
//! reintersection and watertightness tests, the tolerance table's counts, any failure with its
//! replay line, and the verdict as the last line. `--verbose` prints instead every shape's full
//! table in one layout (a block per precision × class, a row per method, with the tolerance
//! table's verdict), the worst case of each row as a replayable probe line (`--worst N`), and the
//! robustness tables; `--markdown` and `--json` always hold everything.
//!
//! ```text
//! rayproof audit [--shape S,..] [--method M,..] [--class C,..] [--precision f32,f64] [--cases N]
//!                [--seed S] [--shard K/N [--shard-out FILE]] [--tolerances FILE]
//!                [--json FILE] [--markdown FILE] [--verbose [--worst N]]
//!                [--exec CMD | --plugin PATH:SYMBOL [--name N] [--timeout S]]
//! rayproof merge SHARD.json... [--tolerances FILE] [--json FILE] [--markdown FILE] [--verbose]
//! ```
//!
//! The JSON depends only on the seed and the selection. It is byte-identical for any thread count,
//! and a test checks this with 1 and 2 threads. It contains no timings. Each row carries its
//! verdict (`pass`, `known_failure`, `undecided`, `unchecked` or `fail`, the rule that applied and
//! the reasons), so a CI job can read it without parsing the table.
//!
//! # Metrics, per method × precision × class
//!
//! Stated here for the sphere; every shape's rows have the same columns, with values judged by
//! the shape's metric (for vectors, ulps of the largest component: `norm_ulps`). The legend the
//! verbose table prints:
//!
//! ```text
//! well = well-posed cases; ill = ill-posed (a 1-ulp input change flips the exact verdict), reported apart
//! wrong = false hit / false miss / wrong root / non-finite value on well-posed cases; rate = wrong / well
//! ulps = error against the correctly rounded value (norm_ulps: in ulps of the largest component); bits = log2(1+ulps)
//! err/cond = max of ulps / (ulps the value moves when every input moves 1 ulp): ≈1 is as good as the inputs allow
//! resid = hit point's distance from the surface in ulps of its size; invalid = invalid inputs rejected / NaN / hit
//! verdict: ok within tolerance, xfail a known failure shown, ? too few cases to tell, - not checked, FAIL
//! ```
//!
//! - **Ill-posed** cases are those where a one-ulp change of any single input flips the exact
//!   verdict (hit ↔ miss, or which root is nearest). They are counted apart and never count as
//!   failures. An exact tangent is always ill-posed, and so is an origin exactly on the surface.
//! - **Wrong verdicts** on well-posed cases come in four kinds. A *false hit* is a hit where the
//!   exact answer is a miss; a *false miss* is the reverse. A *wrong root* is a hit nearer the
//!   other root of the quadratic. A *non-finite t* is a hit with NaN or infinite `t`.
//! - **ulps**: the distance, in units in the last place, from the correctly rounded nearest positive
//!   root (max, median, p99). **bits**: Herbie's log2(1 + ulps).
//! - **err/cond**: ulps divided by the first-order sensitivity of `t`, which is how many ulps `t`
//!   moves when every input moves one ulp. A value near 1 means the method is as accurate as its
//!   inputs allow; a large value means the method lost digits the case did not force it to lose.
//!   This is how the harness tells a bad method from a hard case.
//! - **residual**: `||o + t·d − c| − r|` at the method's `t`, with the point formed exactly, in
//!   ulps of r.
//! - **invalid**: for invalid inputs, what came back: rejected (a miss), NaN `t`, or a hit.
//! - **enclosure** (for `interval`): whether the exact root lies inside the returned interval, and
//!   how wide the interval is in ulps.
//!
//! # The harness has teeth
//!
//! `scripts/mutate` applies a documented list of deliberate breakages to a copy of the committed
//! tree, one at a time, rebuilds, and runs the tests and audits named with each; a breakage is
//! *caught* when one of them fails (the unmutated tree must pass them all first). Its output for
//! commit ef0fa6c (2026-11-23, one hour in all on 2 cores, about 4 minutes per breakage):
//!
//! | breakage | caught by |
//! |---|---|
//! | `spawn_origin`: offset × 0 | `tests/reintersect.rs`; `audit --shape box` |
//! | `spawn_origin`: offset × 1e-3 | `tests/reintersect.rs`; `audit --shape ellipsoid` |
//! | watertight: no wide re-evaluation of a 0 edge function | `wide_fallback_decides_underflowed_edge_functions` (17 underflowed edges it decides) |
//! | watertight: a 0 edge function rejects | `tests/triangle.rs` watertightness; `audit --shape triangle` |
//! | sphere oracle: f32 / f64 rounded up | `tests/oracle_rounding.rs` (ties, near ties, subnormal, overflow) |
//! | `round_q` rounded up (triangle, box, optics, rcp oracles) | `tests/oracle_rounding.rs` |
//! | `round_root`: a root at a tie goes up (polynomial, torus oracles) | `tests/oracle_rounding.rs` |
//! | `ziv` rounded up (rsqrt, quadric oracles) | `tests/oracle_rounding.rs` |
//! | `rtg7`: the textbook discriminant | `audit --shape sphere` |
//! | torus: no Newton refinement | `tests/torus.rs`; `audit --shape torus` |
//! | torus: hit-point error bound 16× too small | `tests/torus.rs` (the measured bound) |
//! | reintersection never counts a re-hit | `tests/reintersect.rs`; `audit --shape cylinder` |
//! | watertightness never counts an escape | `tests/triangle.rs` |
//!
//! 14 of 14 caught.

pub mod api;
pub mod builds;
pub mod contract;
pub mod exec;
pub mod hexfloat;
pub mod hist;
pub mod judge;
pub mod merge;
pub mod offline;
pub mod plan;
pub mod plugin;
pub mod probe;
pub mod report;
pub mod robustness;
pub mod row;
pub mod run;
pub mod shard;
pub mod table;
pub mod tally;
pub mod tolerance;

pub use crate::shapes::shape;

pub use api::Audit;
pub use judge::{judge, Judgement};
pub use plan::audit_shape;
pub use report::{Report, ShapeReport, TOOL};
pub use row::Row;
pub use shape::probe_line;
pub use shape::{
    Answer, Builtin, Expected, Method, MethodInfo, Metric, PerCase, Shape, ShapeInfo, Truth,
};
