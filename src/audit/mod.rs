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

pub mod api;
pub mod exec;
pub mod hexfloat;
pub mod hist;
pub mod judge;
pub mod offline;
pub mod plan;
pub mod plugin;
pub mod probe;
pub mod report;
pub mod row;
pub mod run;
pub mod shape;
pub mod shard;
pub mod table;
pub mod tally;
pub mod tolerance;

pub use api::Audit;
pub use judge::{judge, Judgement};
pub use plan::audit_shape;
pub use report::{Report, ShapeReport, TOOL};
pub use row::Row;
pub use shape::probe_line;
pub use shape::{
    Answer, Builtin, Expected, Method, MethodInfo, Metric, PerCase, Shape, ShapeInfo, Truth,
};
