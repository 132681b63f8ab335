//! `rayproof merge` as the library runs it: merged shards (see [`super::shard::merge`]) judged as
//! the unsharded audit is, with the tolerance rules the shards carry, and the robustness checks
//! of the shapes the shards covered whole. The result is byte for byte the unsharded
//! [`Report`] (`tests/shard.rs`).

use super::report::ShapeReport;
use super::robustness;
use super::run::Tallies;
use super::shard::{IncompatibleShards, Merged, UserTable};
use super::tolerance::{Known, Table};
use super::{Report, TOOL};
use crate::numerics::Precision;

impl Merged {
    /// Refuses a `--tolerances` file given to the merge that is not the table the shards were
    /// run with (the merge judges with the table the shards carry; none given: that one).
    pub fn check_table(&self, given: &Option<UserTable>) -> Result<(), IncompatibleShards> {
        let carried = self.tolerances.as_ref().map(|t| &t.sha256);
        match given {
            Some(g) if Some(&g.sha256) != carried => Err(IncompatibleShards(format!(
                "--tolerances {} is not the table the shards were run with ({})",
                g.file,
                UserTable::label(&self.tolerances)
            ))),
            _ => Ok(()),
        }
    }

    /// The names the tolerance table may use: every shape, method and class of the merge,
    /// outside methods included.
    pub fn known(&self) -> Known<'_> {
        let extra = self
            .shapes
            .iter()
            .flat_map(|t| t.methods.iter().map(|x| (t.shape.name(), x.name.clone())))
            .collect();
        let mut k = super::plan::known_names(extra);
        for r in &self.outside.spawn {
            if !k.spawn_rules.contains(&r.rule) {
                k.spawn_rules.push(r.rule.clone());
            }
        }
        for r in &self.outside.guard {
            if !k.guards.contains(&r.guard) {
                k.guards.push(r.guard.clone());
            }
        }
        k
    }

    /// The report of the unsharded audit: each shape judged by `table` (told to `each` as it is
    /// done: merged tallies have no wall time of their own), then the robustness checks of the
    /// shapes whose every built-in method and class the shards ran, with the outside routines'
    /// rows of shard 0.
    pub fn report(self, table: &Table, each: &mut dyn FnMut(&Tallies, &ShapeReport)) -> Report {
        let mut reports = vec![];
        for t in &self.shapes {
            let r = t.report(Some(table));
            each(t, &r);
            reports.push(r);
        }
        let precisions: Vec<Precision> = self
            .shapes
            .first()
            .map(|t| {
                let mut p: Vec<Precision> = t.groups.iter().map(|g| g.precision).collect();
                p.dedup();
                p
            })
            .unwrap_or_default();
        let names: Vec<&str> = self
            .shapes
            .iter()
            .filter(|t| {
                let mut classes: Vec<usize> = t.groups.iter().map(|g| g.class).collect();
                classes.sort_unstable();
                classes.dedup();
                let methods = t.methods.iter().map(|m| m.name.as_str());
                robustness::complete(t.shape, methods, classes.len())
            })
            .map(|t| t.shape.name())
            .collect();
        let robustness = robustness::with_outside(
            robustness::run(self.seed, &names, &precisions),
            self.seed,
            self.outside,
            &table.robustness,
        );
        Report {
            tool: TOOL,
            seed: self.seed,
            shard: "0/1".into(),
            shapes: reports,
            robustness,
        }
    }
}
