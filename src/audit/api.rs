//! Auditing your own routine from Rust: hand a function to [`Audit`] with a name and get the
//! same rows, tables, JSON, worst cases and tolerance verdicts as a built-in method.
//!
//! A routine receives a case's inputs in the shape's order (`rayproof probe SHAPE --help` names
//! them), each exactly representable in the case's precision, and answers with an [`Answer`]:
//! the count (0 for a miss; the number of distinct real roots for the polynomial shapes) and the
//! values (`t`, the roots in ascending order, or the vector's components).
//!
//! ```
//! use rayproof::audit::{Answer, Audit};
//! use rayproof::numerics::Precision;
//!
//! // A sloppy quadratic: the textbook formula in f32
//! fn sloppy(x: &[f64], _: Precision) -> Answer {
//!     let (a, b, c) = (x[0] as f32, x[1] as f32, x[2] as f32);
//!     let d = b * b - 4.0 * a * c;
//!     let r = [(-b - d.sqrt()) / (2.0 * a), (-b + d.sqrt()) / (2.0 * a)];
//!     let roots: Vec<f64> = match d {
//!         d if d > 0.0 => vec![r[0].min(r[1]) as f64, r[0].max(r[1]) as f64],
//!         d if d == 0.0 => vec![r[0] as f64],
//!         _ => vec![],
//!     };
//!     Answer { count: roots.len() as u32, values: roots, enclosure: None }
//! }
//! let rule = r#"[[rule]]
//! shape = "quadratic"
//! method = "sloppy"
//! wrong = "none"
//! max_ulps = 4
//! why = "held to what the robust method achieves"
//! "#;
//! let report = Audit::shape("quadratic")?
//!     .method("sloppy", sloppy)
//!     .precisions(&[Precision::F32])
//!     .cases(300)
//!     .tolerances(rule)
//!     .run()?;
//! println!("{}", rayproof::audit::table::shape_table(&report));
//! // Its known failures: errors far beyond 4 ulps where the roots are close or lopsided
//! let failures = report.failures();
//! assert!(failures.iter().any(|f| f.starts_with("quadratic sloppy f32 huge_range")));
//! # Ok::<(), String>(())
//! ```
//!
//! At seed 1 it fails its rule on six of the nine classes, e.g. `quadratic sloppy f32 huge_range:
//! max error 1249089459 ulps (allowed 4)` (the small root cancels to `-0x0p+0`), and `clustered`
//! and `kahan` by 1,106 and 654 ulps. `Audit::with_builtins()` puts the shape's own methods in the
//! same rows, `Audit::with` takes any `audit::Method`, and `Audit::probe` replays a worst case for
//! your methods (the printed `rayproof probe` lines replay the oracle and the built-in methods).
//! A tolerance rule that names a method not in the audit is an error.
//!
//! Routines that cannot be linked into a Rust program are audited the same way through a
//! subprocess ([`super::exec`]), a shared library ([`super::plugin`]), or offline files
//! ([`super::offline`]).

use super::plan::{Options, Plan};
use super::probe::probe_text;
use super::report::ShapeReport;
use super::tolerance::Table;
use crate::numerics::Precision;
use crate::shapes::shape::{Answer, Builtin, Method, PerCase, Shape};
use crate::shapes::{shape_by_name, shape_names};

/// A routine written outside the crate: a name and a function of the case's inputs.
pub struct FnMethod<F> {
    name: String,
    robust: bool,
    f: F,
}

impl<F: Fn(&[f64], Precision) -> Answer + Sync> PerCase for FnMethod<F> {
    fn name(&self) -> &str {
        &self.name
    }
    fn robust(&self) -> bool {
        self.robust
    }
    fn run(&self, input: &[f64], prec: Precision) -> Answer {
        (self.f)(input, prec)
    }
}

/// One shape's audit of methods written outside the crate (and, if asked, the shape's own
/// methods beside them).
pub struct Audit {
    shape: &'static dyn Shape,
    methods: Vec<Box<dyn Method>>,
    builtins: bool,
    options: Options,
    tolerances: Option<String>,
}

impl Audit {
    /// An audit of the shape of this name (`sphere`, `triangle`, `quadratic`, …).
    pub fn shape(name: &str) -> Result<Audit, String> {
        let shape = shape_by_name(name).ok_or_else(|| {
            format!(
                "unknown shape '{name}' (known: {})",
                shape_names().join(", ")
            )
        })?;
        Ok(Audit {
            shape,
            methods: vec![],
            builtins: false,
            options: Options {
                shapes: vec![name.to_string()],
                ..Options::default()
            },
            tolerances: None,
        })
    }

    /// Adds a routine under a name.
    pub fn method(
        self,
        name: &str,
        f: impl Fn(&[f64], Precision) -> Answer + Sync + 'static,
    ) -> Audit {
        self.with(Box::new(FnMethod {
            name: name.to_string(),
            robust: false,
            f,
        }))
    }

    /// Adds a routine offered as robust (invalid input must be rejected where the table says).
    pub fn robust_method(
        self,
        name: &str,
        f: impl Fn(&[f64], Precision) -> Answer + Sync + 'static,
    ) -> Audit {
        self.with(Box::new(FnMethod {
            name: name.to_string(),
            robust: true,
            f,
        }))
    }

    /// Adds any [`Method`] (e.g. one that calls into C).
    pub fn with(mut self, m: Box<dyn Method>) -> Audit {
        self.methods.push(m);
        self
    }

    /// Audits the shape's own methods too, in the same rows.
    pub fn with_builtins(mut self) -> Audit {
        self.builtins = true;
        self
    }

    /// Cases per class and precision (default: the shape's).
    pub fn cases(mut self, n: u64) -> Audit {
        self.options.cases = Some(n);
        self
    }

    /// The seed of the case streams (default 1): the same seed gives the same cases and rows.
    pub fn seed(mut self, seed: u64) -> Audit {
        self.options.seed = seed;
        self
    }

    /// The precisions (default: both).
    pub fn precisions(mut self, p: &[Precision]) -> Audit {
        self.options.precisions = p.to_vec();
        self
    }

    /// The classes by name (default: all).
    pub fn classes(mut self, names: &[&str]) -> Audit {
        self.options.classes = names.iter().map(|c| c.to_string()).collect();
        self
    }

    /// Tolerance rules for your methods, in the built-in table's format (tried first).
    pub fn tolerances(mut self, toml: &str) -> Audit {
        self.tolerances = Some(toml.to_string());
        self
    }

    /// The plan: the shape's classes and precisions, with these methods.
    fn plan(self) -> Result<(Plan, Option<String>), String> {
        let mut plan = Plan::new(&self.options)?;
        let mut methods: Vec<Box<dyn Method>> = if self.builtins {
            Builtin::all(self.shape)
                .into_iter()
                .map(|b| Box::new(b) as Box<dyn Method>)
                .collect()
        } else {
            vec![]
        };
        // Names are unique within an audit
        for m in self.methods {
            if methods.iter().any(|x| x.name() == m.name()) {
                return Err(format!("method '{}' is given twice", m.name()));
            }
            methods.push(m);
        }
        if methods.is_empty() {
            return Err("no method to audit".into());
        }
        plan.shapes[0].methods = methods;
        Ok((plan, self.tolerances))
    }

    /// Runs the audit, judged by your tolerance rules and then the built-in table.
    pub fn run(self) -> Result<ShapeReport, String> {
        let (plan, rules) = self.plan()?;
        let user = rules.as_deref().map(|t| ("tolerances", t));
        let table = Table::load(user, &plan.known())?;
        let tallies = plan.run_shape(0, false).map_err(|e| e.0)?;
        plan.finish().map_err(|e| e.0)?;
        Ok(tallies.report(Some(&table)))
    }

    /// The oracle and these methods on one case (what a worst case's replay line prints for
    /// the built-in methods, here for yours).
    pub fn probe(self, prec: Precision, input: &[f64]) -> Result<String, String> {
        let shape = self.shape;
        let (plan, _) = self.plan()?;
        let methods: Vec<&dyn Method> = plan.shapes[0].methods.iter().map(|m| m.as_ref()).collect();
        if input.len() != shape.info().args.len() {
            return Err(format!(
                "{} takes {} values, got {}",
                shape.name(),
                shape.info().args.len(),
                input.len()
            ));
        }
        probe_text(shape, &methods, prec, input)
    }
}
