//! rayproof's integration tests, one binary (`cargo test --release --test integration`): a
//! module per concern, each `tests/NAME.rs` as before, linked once instead of once per file.
//! Run one module with its path as the filter, e.g. `cargo test --release --test integration
//! contract::`.

mod common;

mod batch;
mod bounds;
mod builds;
mod certified;
mod check;
mod cli;
mod contract;
mod deadline;
mod embree;
mod exec;
mod export;
mod exr_layers;
mod fuzz;
mod fuzz_surfaces;
mod golden_follow;
mod guard;
mod hostile;
mod idiff_live;
mod imgdiff;
mod implicit;
mod layers;
mod mpu;
mod newton;
mod offline;
mod optics;
mod oracle_filters;
mod oracle_rounding;
mod plugin;
mod poly;
mod povray_suite;
mod quad;
mod read_as_written;
mod reference;
mod reintersect;
mod render;
mod report;
mod reports;
mod reproducers;
mod routines;
mod sacred;
mod seams_audit;
mod shard;
mod signals;
mod spawn;
mod sphere;
mod suite;
mod teams;
mod torus;
mod triangle;
mod verdicts;
