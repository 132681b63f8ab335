//! What a `rayproof audit` covers: shapes, methods, classes and precisions resolved from names
//! (an unknown name is a one-line error), the case count per shape, and whether the
//! robustness tests (reintersection, watertightness) and the seams between routines (box
//! guards, exactly one hit per mesh, instance transforms) run with a shape.

use super::report::{Report, ShapeReport, TOOL};
use super::robustness;
use super::run::{Selection, Tallies};
use super::tolerance::{Known, Table};
use crate::numerics::Precision;
use crate::shapes::shape::{Builtin, Method, Shape};
use crate::shapes::{registry, shape_by_name, shape_names};

/// What a run tells as it goes (for progress lines; the report holds the results).
pub enum Progress<'a> {
    /// A shape is done: its tallies, its report and its wall time in seconds.
    Shape(&'a Tallies, &'a ShapeReport, f64),
    /// The reintersection and watertightness tests are done, in this many seconds.
    Robustness(f64),
}

/// The audit as asked for on the command line.
#[derive(Clone, Debug)]
pub struct Options {
    /// Shape names, or `all` (empty: every shape, or the sphere alone when methods or classes
    /// are named).
    pub shapes: Vec<String>,
    /// Method names of the one shape (empty: all).
    pub methods: Vec<String>,
    /// Class names of the one shape (empty: all).
    pub classes: Vec<String>,
    /// Empty: both.
    pub precisions: Vec<Precision>,
    /// Cases per class (`None`: each shape's default).
    pub cases: Option<u64>,
    /// Seed of the case streams.
    pub seed: u64,
    /// `(k, n)`: only the cases whose index ≡ k (mod n).
    pub shard: (u64, u64),
}

impl Default for Options {
    /// Every shape, method, class and precision at each shape's default case count, seed 1,
    /// unsharded.
    fn default() -> Options {
        Options {
            shapes: vec![],
            methods: vec![],
            classes: vec![],
            precisions: vec![],
            cases: None,
            seed: 1,
            shard: (0, 1),
        }
    }
}

/// One shape's part of the audit.
pub struct ShapePlan {
    /// The shape.
    pub shape: &'static dyn Shape,
    /// The methods under audit: the shape's own, or any [`Method`] from outside the crate.
    pub methods: Vec<Box<dyn Method>>,
    /// Class indices to run.
    pub classes: Vec<usize>,
    /// Cases per class and precision.
    pub cases: u64,
}

/// The resolved audit.
pub struct Plan {
    /// Each shape's part, in audit order.
    pub shapes: Vec<ShapePlan>,
    /// Precisions to run.
    pub precisions: Vec<Precision>,
    /// Seed of the case streams.
    pub seed: u64,
    /// `(k, n)`: only the cases whose index ≡ k (mod n); `(0, 1)` is the whole run.
    pub shard: (u64, u64),
    /// Every shape is audited: the reintersection and watertightness tests run too.
    pub every_shape: bool,
    /// Spawn rules audited beside the shapes (`audit --spawn-rule`): their rows are run whole
    /// with the outside routines' robustness rows.
    pub spawn_rules: Vec<Box<dyn robustness::spawn::SpawnRule>>,
    /// Box guards audited beside the shapes (`audit --guard`): run whole like the spawn rules.
    pub guards: Vec<robustness::guard::Owned>,
    /// The seams (exactly once, transforms) run for the outside routines too (`audit` runs them unless `--no-seams`; the library's plan does not unless this is set).
    pub outside_seams: bool,
}

/// Resolves names against a list, or all when empty.
fn select(names: &[String], all: &[&str], what: &str, shape: &str) -> Result<Vec<usize>, String> {
    if names.is_empty() {
        return Ok((0..all.len()).collect());
    }
    // A name given twice is one selection (`--class a,a` audits `a` once)
    let mut picked = vec![];
    for n in names {
        let k = all.iter().position(|a| a == n).ok_or_else(|| {
            format!(
                "--{what}: unknown {what} '{n}' of {shape} (known: {})",
                all.join(", ")
            )
        })?;
        if !picked.contains(&k) {
            picked.push(k);
        }
    }
    Ok(picked)
}

impl Plan {
    /// Resolves the options; an unknown name is an error of one line.
    pub fn new(o: &Options) -> Result<Plan, String> {
        // Which shapes
        let narrowed = !o.methods.is_empty() || !o.classes.is_empty();
        let all = o.shapes.iter().any(|s| s == "all");
        let every_shape = all || (o.shapes.is_empty() && !narrowed);
        let mut shapes: Vec<&'static dyn Shape> = vec![];
        if every_shape {
            shapes = registry();
        } else if o.shapes.is_empty() {
            shapes.push(shape_by_name("sphere").expect("the sphere is registered"));
        } else {
            for name in &o.shapes {
                let s = shape_by_name(name).ok_or_else(|| {
                    format!(
                        "--shape: unknown shape '{name}' (known: all, {})",
                        shape_names().join(", ")
                    )
                })?;
                if !shapes.iter().any(|x| x.name() == s.name()) {
                    shapes.push(s);
                }
            }
        }
        if narrowed && shapes.len() != 1 {
            return Err(
                "--method and --class name one shape's methods and classes: give a single --shape"
                    .into(),
            );
        }
        // Each shape's methods, classes and case count
        let mut plans = vec![];
        for shape in shapes {
            let info = shape.info();
            let names: Vec<&str> = info.methods.iter().map(|m| m.name).collect();
            let methods = select(&o.methods, &names, "method", info.name)?;
            let classes = select(&o.classes, info.classes, "class", info.name)?;
            plans.push(ShapePlan {
                shape,
                methods: methods
                    .into_iter()
                    .map(|index| Box::new(Builtin { shape, index }) as Box<dyn Method>)
                    .collect(),
                classes,
                cases: o.cases.unwrap_or(info.default_cases),
            });
        }
        Ok(Plan {
            shapes: plans,
            precisions: if o.precisions.is_empty() {
                Precision::ALL.to_vec()
            } else {
                let mut once = vec![];
                for &x in &o.precisions {
                    if !once.contains(&x) {
                        once.push(x);
                    }
                }
                once
            },
            seed: o.seed,
            shard: o.shard,
            every_shape,
            spawn_rules: vec![],
            guards: vec![],
            outside_seams: false,
        })
    }

    /// The selection of shape `i`, for [`super::run::run`].
    pub fn selection(&self, i: usize) -> Selection<'_> {
        let p = &self.shapes[i];
        Selection {
            shape: p.shape,
            methods: p.methods.iter().map(|m| m.as_ref()).collect(),
            precisions: self.precisions.clone(),
            classes: p.classes.clone(),
            cases: p.cases,
            seed: self.seed,
            shard: self.shard,
        }
    }

    /// Runs shape `i` (its outside methods stay open: [`Plan::finish`] ends them).
    pub fn run_shape(&self, i: usize, progress: bool) -> Result<Tallies, super::run::MethodFailed> {
        super::run::run(&self.selection(i), progress)
    }

    /// Every shape in turn, each judged by `table` when given; `each` hears of each shape as it
    /// finishes. Outside methods stay open ([`Plan::finish`]).
    pub fn run_shapes(
        &self,
        table: Option<&Table>,
        progress: bool,
        each: &mut dyn FnMut(Progress),
    ) -> Result<(Vec<Tallies>, Vec<ShapeReport>), super::run::MethodFailed> {
        let (mut runs, mut reports) = (vec![], vec![]);
        for i in 0..self.shapes.len() {
            let start = std::time::Instant::now();
            let t = self.run_shape(i, progress)?;
            let r = t.report(table);
            each(Progress::Shape(&t, &r, start.elapsed().as_secs_f64()));
            runs.push(t);
            reports.push(r);
        }
        Ok((runs, reports))
    }

    /// The whole audit, judged by `table`: every shape, then the reintersection and
    /// watertightness tests of the shapes audited completely and of outside routines; outside
    /// methods are finished. Its verdict is [`Report::outcome`].
    ///
    /// ```no_run
    /// use rayproof::audit::plan::{Options, Plan};
    /// use rayproof::audit::tolerance::Table;
    /// let plan = Plan::new(&Options::default())?;
    /// let table = Table::load(None, &plan.known())?;
    /// let report = plan.run(&table, false, &mut |_| {}).map_err(|e| e.0)?;
    /// let outcome = report.outcome();
    /// println!("verdict: {}", if outcome.passed() { "pass" } else { "fail" });
    /// # Ok::<(), String>(())
    /// ```
    pub fn run(
        &self,
        table: &Table,
        progress: bool,
        each: &mut dyn FnMut(Progress),
    ) -> Result<Report, super::run::MethodFailed> {
        let judged = self.shard == (0, 1);
        let (_, shapes) = self.run_shapes(judged.then_some(table), progress, each)?;
        let start = std::time::Instant::now();
        let robustness = self.robustness(table)?;
        self.finish()?;
        if robustness.is_some() {
            each(Progress::Robustness(start.elapsed().as_secs_f64()));
        }
        Ok(Report {
            tool: TOOL,
            seed: self.seed,
            shard: format!("{}/{}", self.shard.0, self.shard.1),
            shapes,
            robustness,
        })
    }

    /// Ends the run's outside methods (a child kept for the run is closed and how it ended is
    /// checked): once the run has no more cases, robustness tests included.
    pub fn finish(&self) -> Result<(), super::run::MethodFailed> {
        for p in &self.shapes {
            for m in &p.methods {
                m.finish().map_err(super::run::MethodFailed)?;
            }
        }
        Ok(())
    }

    /// The reintersection and watertightness tests of the shapes audited completely (every
    /// built-in method and class; `None`: none has them).
    pub fn robustness(
        &self,
        table: &Table,
    ) -> Result<Option<robustness::Robustness>, super::run::MethodFailed> {
        let names: Vec<&str> = self
            .shapes
            .iter()
            .filter(|p| {
                robustness::complete(p.shape, p.methods.iter().map(|m| m.name()), p.classes.len())
            })
            .map(|p| p.shape.name())
            .collect();
        let r = robustness::run(self.seed, &names, &self.precisions);
        Ok(robustness::with_outside(
            r,
            self.seed,
            self.outside_robustness()?,
            &table.robustness,
        ))
    }

    /// The reintersection rows of the sphere and triangle routines from outside the crate, and
    /// the watertightness rows of the triangle routines (none: empty).
    pub fn outside_robustness(&self) -> Result<robustness::Outside, super::run::MethodFailed> {
        let mut rows = robustness::Outside::default();
        for p in &self.shapes {
            let info = p.shape.info();
            let outside: Vec<&dyn Method> = p
                .methods
                .iter()
                .filter(|m| !info.methods.iter().any(|b| b.name == m.name()))
                .map(|m| m.as_ref())
                .collect();
            if outside.is_empty() {
                continue;
            }
            let name = p.shape.name();
            if self.outside_seams && robustness::seams::run_for(&info, p.classes.len()) {
                let (once, transform) =
                    robustness::seams::outside_seams(self.seed, name, &self.precisions, &outside)
                        .map_err(super::run::MethodFailed)?;
                rows.once.extend(once);
                rows.transform.extend(transform);
            }
            rows.reintersection.extend(
                robustness::outside_reintersection(self.seed, name, &self.precisions, &outside)
                    .map_err(super::run::MethodFailed)?,
            );
            if name == "triangle" {
                rows.watertight.extend(
                    robustness::outside_watertight(self.seed, &self.precisions, &outside)
                        .map_err(super::run::MethodFailed)?,
                );
            }
        }
        let rules: Vec<&dyn robustness::spawn::SpawnRule> =
            self.spawn_rules.iter().map(|r| r.as_ref()).collect();
        rows.spawn = robustness::spawn_rows(self.seed, &self.precisions, &rules)
            .map_err(super::run::MethodFailed)?;
        let guards: Vec<robustness::guard::Guard> = self.guards.iter().map(|g| g.guard()).collect();
        rows.guard = robustness::seams::guard_rows(self.seed, &self.precisions, &guards)
            .map_err(super::run::MethodFailed)?;
        Ok(rows)
    }

    /// The names a tolerance table may use: every registered shape with its methods and
    /// classes, and the methods of this audit.
    pub fn known(&self) -> Known<'static> {
        let mut k = known_names(
            self.shapes
                .iter()
                .flat_map(|p| {
                    p.methods
                        .iter()
                        .map(|m| (p.shape.name(), m.name().to_string()))
                })
                .collect(),
        );
        k.spawn_rules = self
            .spawn_rules
            .iter()
            .map(|r| r.name().to_string())
            .collect();
        k.guards = self
            .guards
            .iter()
            .map(|g| g.guard().name().to_string())
            .collect();
        k
    }
}

/// Every registered shape's built-in method and class names, plus `extra` (shape, method).
pub fn known_names(extra: Vec<(&'static str, String)>) -> Known<'static> {
    Known {
        shapes: registry()
            .into_iter()
            .map(|s| {
                let info = s.info();
                let mut methods: Vec<String> =
                    info.methods.iter().map(|m| m.name.to_string()).collect();
                for (shape, m) in &extra {
                    if *shape == info.name && !methods.contains(m) {
                        methods.push(m.clone());
                    }
                }
                (info.name, methods, info.classes.to_vec())
            })
            .collect(),
        with_cond: registry()
            .into_iter()
            .filter(|s| s.info().reports_cond)
            .map(|s| s.info().name)
            .collect(),
        spawn_rules: vec![],
        guards: vec![],
    }
}

/// Audits one registered shape with the options' selection of its built-in methods, classes and
/// precisions, judged by the built-in tolerance table (a shard's rows are not judged).
pub fn audit_shape(shape: &dyn Shape, opts: &Options) -> Result<ShapeReport, String> {
    let plan = Plan::new(&Options {
        shapes: vec![shape.name().to_string()],
        ..opts.clone()
    })?;
    let table = Table::load(None, &plan.known())?;
    let judged = opts.shard == (0, 1);
    let tallies = plan.run_shape(0, false).map_err(|e| e.0)?;
    plan.finish().map_err(|e| e.0)?;
    Ok(tallies.report(judged.then_some(&table)))
}

impl Table {
    /// The built-in table alone, checked against every registered shape (a unit test keeps it
    /// valid).
    pub fn built_in() -> Table {
        Table::load(None, &known_names(vec![])).expect("the built-in table is valid")
    }
}
