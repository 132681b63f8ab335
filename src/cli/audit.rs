//! `rayproof audit` and `rayproof merge`.

use super::outside::OutsideArgs;
use super::*;
use anyhow::{anyhow, bail, Result};
use clap::Args;
use rayproof::audit::plan::{Options, Plan, Progress};
use rayproof::audit::robustness::{self, guard, Robustness};
use rayproof::audit::shard::{self, Shard, UserTable};
use rayproof::audit::tolerance::{Known, Table};
use rayproof::audit::{table, Report, ShapeReport, TOOL};
use rayproof::numerics::Precision;
use rayproof::output::{check_outputs, Outputs};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct AuditArgs {
    /// Cases per class and precision (default: each shape's, 20000, or fewer where the oracle
    /// is slow, as the torus's is).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub cases: Option<u64>,
    /// Seed of every case generator; the same seed gives byte-identical JSON.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Shapes (routine families) to audit: sphere, the game-math chapter's routines (see
    /// `rayproof probe --help`), or all (repeat or comma-separate). Default: all, or only the
    /// sphere when --method or --class is given.
    #[arg(long, value_delimiter = ',')]
    pub shape: Vec<String>,
    /// Methods to audit (repeat or comma-separate); default: all. Names are the selected
    /// shape's (a single shape).
    #[arg(long, value_delimiter = ',')]
    pub method: Vec<String>,
    /// Precisions: f32, f64 (repeat or comma-separate); default: both.
    #[arg(long, value_delimiter = ',', value_parser = parse_precision)]
    pub precision: Vec<Precision>,
    /// Case classes (repeat or comma-separate); default: all. Names are the selected shape's.
    #[arg(long, value_delimiter = ',')]
    pub class: Vec<String>,
    /// Run only shard K of N (cases whose index ≡ K mod N), written as K/N.
    #[arg(long, value_parser = parse_shard, default_value = "0/1")]
    pub shard: (u64, u64),
    /// Write this shard's tallies for `rayproof merge` (the tolerance table is then checked by
    /// the merge, not here).
    #[arg(long, value_name = "FILE")]
    pub shard_out: Option<PathBuf>,
    /// Audit a spawn rule beside the shapes (repeatable): a built-in (pbrt, wachter_binder,
    /// tmin_1e-4, mitsuba2_epsilon, none), `exec:CMD` (a command speaking `rayproof header
    /// --spawn`) or `plugin:PATH:SYMBOL` (its C ABI, the same header). Its rows (precision × scene size × placement, as `rayproof spawn`'s) are judged
    /// by the tolerance file's `test = "spawn"` rules, else: yours and pbrt held to no self-hit
    /// and no ray behind the surface, the other built-ins reported.
    #[arg(long, value_name = "RULE")]
    pub spawn_rule: Vec<String>,
    /// The `plugin:` then the `exec:` spawn rules' names, in order (default: the symbol without
    /// its precision suffix; `exec`, `exec2`, …).
    #[arg(long, value_name = "NAME")]
    pub spawn_name: Vec<String>,
    /// Audit a box guard beside the shapes (repeatable): a built-in (naive_slab, williams,
    /// pbrt, ize), `exec:CMD` (a command speaking `rayproof header --guard`) or
    /// `plugin:PATH:SYMBOL` (its C ABI, the same header). Its rows (precision × class, as
    /// `rayproof guard`'s) are judged by the tolerance file's `test = "guard"` rules, else:
    /// yours and ize lose no box, the other built-ins reported. The box shape's audit runs the
    /// built-ins without it.
    #[arg(long, value_name = "GUARD")]
    pub guard: Vec<String>,
    /// The `plugin:` then the `exec:` guards' names, in order (default: the symbol without its
    /// precision suffix; `exec`, `exec2`, …).
    #[arg(long, value_name = "NAME")]
    pub guard_name: Vec<String>,
    /// Skip the seams for your routines: by default a sphere or triangle routine of yours, in an
    /// audit of the shape's every class, gets exactly-one-hit-per-mesh rows (a triangle
    /// routine) and instance-transform rows, judged like the built-ins'.
    #[arg(long)]
    pub no_seams: bool,
    /// The default (kept so that older command lines still run).
    #[arg(long, hide = true, conflicts_with = "no_seams")]
    pub seams: bool,
    #[command(flatten)]
    pub outside: OutsideArgs,
    #[command(flatten)]
    pub out: AuditOutput,
}

/// Puts the outside routines, if any, into a single-shape plan beside the shape's built-in
/// methods (all of them, or those --method names). Plugins are audited in the precisions every
/// one has symbols for (unless --precision asks for some, which each must have).
pub(super) fn add_outside(plan: &mut Plan, o: &OutsideArgs, precisions_given: bool) -> Result<()> {
    if !o.any() {
        return Ok(());
    }
    if plan.shapes.len() != 1 {
        bail!("--exec and --plugin audit one shape's routines: give a single --shape");
    }
    let outside = o.methods(plan.shapes[0].shape.info())?;
    for (m, has) in &outside {
        let Some(has) = has else { continue };
        if !precisions_given {
            plan.precisions.retain(|p| has.contains(p));
            if plan.precisions.is_empty() {
                bail!("the --plugin routines have no precision in common (give --precision)");
            }
        } else if let Some(p) = plan.precisions.iter().find(|p| !has.contains(p)) {
            bail!(
                "--plugin {} has no {} symbol (give --precision, or a :{} symbol)",
                m.name(),
                p.name(),
                p.name()
            );
        }
    }
    let p = &mut plan.shapes[0];
    for (m, _) in outside {
        if p.methods.iter().any(|x| x.name() == m.name()) {
            bail!(
                "routine name {}: a built-in method of {} has that name (a routine is named by --name, else by its symbol or command: give --name)",
                m.name(),
                p.shape.name()
            );
        }
        p.methods.push(m);
    }
    Ok(())
}

/// Keeps, of a single-shape plan with outside routines, the built-in methods `builtin` names and
/// the outside routines `outside` names; an outside name that is no routine is an error.
fn narrow_to(plan: &mut Plan, builtin: &[String], outside: &[String]) -> Result<()> {
    let p = &mut plan.shapes[0];
    let info = p.shape.info();
    for n in outside {
        if !p.methods.iter().any(|m| m.name() == n) {
            let known: Vec<&str> = info
                .methods
                .iter()
                .map(|m| m.name)
                .chain(
                    p.methods
                        .iter()
                        .map(|m| m.name())
                        .filter(|m| !info.methods.iter().any(|b| b.name == *m)),
                )
                .collect();
            bail!(
                "--method: unknown method '{n}' of {} (known: {})",
                info.name,
                known.join(", ")
            );
        }
    }
    p.methods.retain(|m| {
        let builtin_method = info.methods.iter().any(|b| b.name == m.name());
        if builtin_method {
            builtin.iter().any(|n| n == m.name())
        } else {
            outside.iter().any(|n| n == m.name())
        }
    });
    Ok(())
}

/// How `audit` and `merge` judge and write their report.
#[derive(Args, Debug)]
pub struct AuditOutput {
    /// Tolerance rules tried before the built-in table (TOML in the built-in table's format).
    /// A routine of yours that no rule names is held to its shape's default goal: no wrong
    /// verdict on a well-posed case, no NaN hit, invalid input rejected, values within the
    /// loosest bound the built-in table proves for a robust built-in method of the shape. A rule
    /// naming it replaces only the checks it gives; one with only `why` reports it unjudged.
    #[arg(long, value_name = "FILE")]
    pub tolerances: Option<PathBuf>,
    /// Write the full report as JSON (for `merge`: byte-identical to the unsharded audit's).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the table as Markdown.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
    /// Replayable worst cases to print per row with --verbose (0 for none).
    #[arg(long, default_value_t = 1)]
    pub worst: usize,
    /// Print every shape's full table and the robustness tables, not one line per family ×
    /// precision.
    #[arg(long, short)]
    pub verbose: bool,
}

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Shard files from `rayproof audit --shard K/N --shard-out FILE`: each K of 0 … N−1 once,
    /// in any order.
    #[arg(required = true, value_name = "SHARD")]
    pub shards: Vec<PathBuf>,
    #[command(flatten)]
    pub out: AuditOutput,
}

/// The user's tolerance file, read (its name as given, its text and hash).
fn read_user_table(user: &Option<PathBuf>) -> Result<Option<UserTable>> {
    user.as_ref()
        .map(|p| {
            let text = rayproof::input::read_text(
                p,
                rayproof::input::MAX_TEXT_BYTES,
                rayproof::input::Kind::Stream,
            )
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", p.display()))?;
            Ok(UserTable::new(&p.display().to_string(), &text))
        })
        .transpose()
}

/// The tolerance table, with the user's rules first; one line on any error.
fn table_of(user: &Option<UserTable>, known: &Known) -> Result<Table> {
    let file = user.as_ref().map(|t| (t.file.as_str(), t.text.as_str()));
    Table::load(file, known).map_err(|e| anyhow!("tolerances: {e}"))
}

/// The tolerance table, with the user's rules first; one line on any error.
pub(super) fn load_table(user: &Option<PathBuf>, known: &Known) -> Result<Table> {
    table_of(&read_user_table(user)?, known)
}

/// Prints a shape's summary, or with `--verbose` its table and worst cases.
pub(super) fn print_shape(r: &ShapeReport, out: &AuditOutput) {
    if !out.verbose {
        say_raw!("{}", table::summary(r));
        return;
    }
    say_raw!("{}", table::shape_table(r));
    if out.worst > 0 {
        say_raw!("{}", table::worst_cases(r, out.worst));
    }
}

/// The legend: one line, or with `--verbose` the table's.
pub(super) fn print_legend(seed: u64, shard: &str, out: &AuditOutput) {
    if out.verbose {
        say_raw!("{}", table::legend(seed, shard));
    } else {
        say_raw!("{}", table::short_legend(seed, shard));
    }
}

pub(super) fn run_audit(a: AuditArgs) -> Result<u8> {
    // --method names built-in methods, and may name outside routines (then only those named)
    let (builtin, outside_named): (Vec<String>, Vec<String>) = match a.shape.as_slice() {
        [one] if a.outside.any() => {
            let builtins: Vec<&str> = rayproof::shapes::shape_by_name(one)
                .map(|s| s.info().methods.iter().map(|m| m.name).collect())
                .unwrap_or_default();
            a.method
                .iter()
                .cloned()
                .partition(|m| builtins.contains(&m.as_str()))
        }
        _ => (a.method.clone(), vec![]),
    };
    // Resolve every name and the tolerance table before the long run
    let mut plan = Plan::new(&Options {
        shapes: a.shape.clone(),
        methods: builtin.clone(),
        classes: a.class.clone(),
        precisions: a.precision.clone(),
        cases: a.cases,
        seed: a.seed,
        shard: a.shard,
    })
    .map_err(|e| anyhow!(e))?;
    add_outside(&mut plan, &a.outside, !a.precision.is_empty())?;
    if !outside_named.is_empty() {
        narrow_to(&mut plan, &builtin, &outside_named)?;
    }
    let (spawn_rules, spawn_inputs) = spawn_rules_of(&a)?;
    plan.spawn_rules = spawn_rules;
    let (guards, guard_inputs) = guards_of(&a, &plan.precisions)?;
    // The box shape's audit runs the built-in guards: one named again would run twice
    let box_whole = plan.shapes.iter().any(|p| {
        p.shape.name() == "box"
            && robustness::complete(p.shape, p.methods.iter().map(|m| m.name()), p.classes.len())
    });
    if let Some(guard::Owned::BuiltIn(g)) = guards
        .iter()
        .find(|g| box_whole && matches!(g, guard::Owned::BuiltIn(_)))
    {
        bail!("--guard {g}: the box shape's audit runs the built-in guards already");
    }
    plan.guards = guards;
    plan.outside_seams = !a.no_seams;
    // A shard is judged by its merge: without its file it would end unjudged (exit 0)
    if a.shard.1 > 1 && a.shard_out.is_none() {
        bail!(
            "--shard {}/{} without --shard-out: a shard is judged by `rayproof merge` of every shard's file; give --shard-out FILE",
            a.shard.0,
            a.shard.1
        );
    }
    let user_table = read_user_table(&a.out.tolerances)?;
    let table = table_of(&user_table, &plan.known())?;
    let inputs: Vec<PathBuf> = a
        .out
        .tolerances
        .iter()
        .cloned()
        .chain(a.outside.input_files())
        .chain(spawn_inputs)
        .chain(guard_inputs)
        .collect();
    let mut outputs = a.out.outputs(&[&a.shard_out], &inputs)?;
    let shard_label = format!("{}/{}", a.shard.0, a.shard.1);
    // A shard is judged by its merge, not here
    let judge = a.shard_out.is_none() && a.shard == (0, 1);
    print_legend(a.seed, &shard_label, &a.out);
    // Each shape printed as it finishes; progress on stderr, off the report (after the run when
    // an outside routine is in it: its errors can come until its child is closed, and an error
    // is one line)
    let outside = a.outside.any()
        || a.spawn_rule
            .iter()
            .chain(&a.guard)
            .any(|r| r.starts_with("exec:") || r.starts_with("plugin:"));
    let mut progress: Vec<String> = vec![];
    let mut each = |p: Progress| {
        let line = match p {
            Progress::Shape(t, r, secs) => {
                print_shape(r, &a.out);
                let n = rayproof::audit::run::shard_len(t.cases, a.shard) * t.groups.len() as u64;
                format!(
                    "{}: {n} cases × {} methods in {secs:.1} s on {} threads ({:.0} cases/s; the oracle alone {:.1} s of CPU)",
                    r.shape,
                    t.methods.len(),
                    rayon::current_num_threads(),
                    n as f64 / secs.max(1e-9),
                    t.oracle_nanos as f64 * 1e-9,
                )
            }
            Progress::Robustness(secs) => format!(
                "robustness tests in {secs:.1} s on {} threads",
                rayon::current_num_threads()
            ),
        };
        if outside {
            progress.push(line);
        } else {
            eprintln!("{line}");
        }
    };
    let progress_bar = std::io::stderr().is_terminal();
    // A shard: its tallies go to the file for the merge, judged by the merge
    if let Some(p) = &a.shard_out {
        let (runs, reports) = plan.run_shapes(None, progress_bar, &mut each)?;
        let report = Report {
            tool: TOOL,
            seed: a.seed,
            shard: shard_label,
            shapes: reports,
            robustness: None,
        };
        write_files(&mut outputs, &report, &a.out)?;
        // The shard carries the rules it was run with: its merge judges with them
        // Outside routines' robustness tests are not sharded: shard 0 runs them whole
        let outside = if a.shard.0 == 0 {
            let mut o = plan.outside_robustness()?;
            robustness::seams::unjudged(&mut o);
            o
        } else {
            Default::default()
        };
        plan.finish()?;
        progress.iter().for_each(|l| eprintln!("{l}"));
        let file = Shard::new(
            TOOL,
            a.seed,
            plan.every_shape,
            a.shard,
            user_table,
            &runs,
            [
                plan.spawn_rules
                    .iter()
                    .map(|r| named_as_given(r.name(), r.replay()))
                    .collect(),
                plan.guards
                    .iter()
                    .map(|g| match g {
                        guard::Owned::BuiltIn(n) => n.to_string(),
                        guard::Owned::Outside(m) => named_as_given(m.name(), m.replay()),
                    })
                    .collect(),
            ],
            plan.outside_seams,
            outside,
        );
        outputs.write(p, file.to_json().as_bytes())?;
        outputs.commit()?;
        say!(
            "shard {}/{} written to {}; the tolerance table is checked by `rayproof merge`",
            a.shard.0,
            a.shard.1,
            p.display()
        );
        return Ok(0);
    }
    let report = plan.run(&table, progress_bar, &mut each)?;
    progress.iter().for_each(|l| eprintln!("{l}"));
    finish(report, judge.then_some(&table), outputs, &a.out)
}

/// A spawn rule's or a guard's name in a shard file: with how it was given, for one from outside
/// the crate (shards of one audit name the same).
fn named_as_given(name: &str, how: Option<String>) -> String {
    match how {
        Some(how) => format!("{name} ({how})"),
        None => name.to_string(),
    }
}

/// The built-in names and the outside routines of one-string specs `--FLAG SPEC` (`exec:CMD`,
/// `plugin:PATH:SYMBOL`, else a built-in's name), named by `--FLAG-name` (`--spawn-name` for
/// `--spawn-rule`); an empty command or more names than routines is one line.
fn specs_of(
    specs: &[String],
    names: &[String],
    flag: &str,
    timeout: f64,
) -> Result<(Vec<String>, OutsideArgs)> {
    if let Some(r) = specs
        .iter()
        .find(|r| r.strip_prefix("exec:").is_some_and(|c| c.trim().is_empty()))
    {
        bail!("--{flag} '{r}': give the command after exec:");
    }
    let (builtin, theirs) = OutsideArgs::from_specs(specs, names, timeout);
    let routines = theirs.plugin.len() + theirs.exec.len();
    if theirs.name.len() > routines {
        let name = format!("--{}-name", flag.trim_end_matches("-rule"));
        bail!(
            "{name} given {} times for {routines} plugin: or exec: {}(s)",
            theirs.name.len(),
            flag.replace('-', " ")
        );
    }
    Ok((builtin, theirs))
}

/// The box guards `--guard` names: built-ins, then `plugin:` and `exec:` guards (named by
/// `--guard-name`), each batch under the audit's `--timeout`; and their files, inputs of the run.
fn guards_of(a: &AuditArgs, precisions: &[Precision]) -> Result<(Vec<guard::Owned>, Vec<PathBuf>)> {
    let (builtin, theirs) = specs_of(&a.guard, &a.guard_name, "guard", a.outside.exec_timeout)?;
    let mut out = vec![];
    for n in &builtin {
        let g = guard::GUARDS
            .iter()
            .copied()
            .find(|g| g == n)
            .ok_or_else(|| {
                anyhow!(
                    "--guard {n}: not a guard (built-in: {}; or exec:CMD, plugin:PATH:SYMBOL)",
                    guard::GUARDS.join(", ")
                )
            })?;
        out.push(guard::Owned::BuiltIn(g));
    }
    for (m, has) in theirs.methods(&guard::INFO)? {
        if guard::GUARDS.contains(&m.name()) {
            bail!(
                "--guard-name {}: a built-in guard's name; give another",
                m.name()
            );
        }
        if let Some(p) = precisions
            .iter()
            .find(|p| has.as_ref().is_some_and(|h| !h.contains(p)))
        {
            bail!(
                "--guard plugin {}: no {} symbol (give --precision, or a :{} symbol)",
                m.name(),
                p.name(),
                p.name()
            );
        }
        out.push(guard::Owned::Outside(m));
    }
    for (i, g) in out.iter().enumerate() {
        let name = g.guard().name().to_string();
        if out[..i].iter().any(|x| x.guard().name() == name) {
            bail!("the guard {name} is named twice");
        }
    }
    Ok((out, theirs.input_files()))
}

/// The spawn rules `--spawn-rule` names: built-ins, then `plugin:` and `exec:` rules (named by
/// `--spawn-name`), each batch under the audit's `--timeout`; and their files, inputs of the run.
#[allow(clippy::type_complexity)]
fn spawn_rules_of(
    a: &AuditArgs,
) -> Result<(
    Vec<Box<dyn rayproof::audit::robustness::spawn::SpawnRule>>,
    Vec<PathBuf>,
)> {
    let (builtin, theirs) = specs_of(
        &a.spawn_rule,
        &a.spawn_name,
        "spawn-rule",
        a.outside.exec_timeout,
    )?;
    let precisions = if a.precision.is_empty() {
        Precision::ALL.to_vec()
    } else {
        a.precision.clone()
    };
    let rules = super::spawn::spawn_rules(&builtin, &theirs, &precisions, "--spawn-name")?;
    Ok((rules, theirs.input_files()))
}

/// Prints the reintersection and watertightness tests' summary (with `--verbose`, tables).
fn print_robustness(r: &Robustness, verbose: bool) {
    if verbose {
        say_raw!("{}", robustness::table(r, false));
    } else {
        say_raw!("{}", robustness::summary(r));
    }
}

pub(super) fn run_merge(m: MergeArgs) -> Result<u8> {
    let inputs: Vec<PathBuf> = m.shards.iter().chain(&m.out.tolerances).cloned().collect();
    let outputs = m.out.outputs(&[], &inputs)?;
    // Read and check each shard on its own (exit 2 on a bad file)
    let mut shards = vec![];
    for p in &m.shards {
        let bytes = rayproof::input::read_capped(
            p,
            rayproof::input::MAX_DATA_BYTES,
            rayproof::input::Kind::Stream,
        )
        .map_err(|e| anyhow!("cannot read {}: {e}", p.display()))?;
        let s = Shard::from_json(&bytes, rayproof::shapes::shape_by_name)
            .map_err(|e| anyhow!("{}: {e}", p.display()))?;
        shards.push((p.display().to_string(), s));
    }
    // Check that they make up one audit (exit 3), merge, and judge as the unsharded run does,
    // with the rules the shards carry (a --tolerances file here must be the same one)
    let count = shards.len();
    let merged = shard::merge(TOOL, shards, rayproof::shapes::shape_by_name)?;
    merged.check_table(&read_user_table(&m.out.tolerances)?)?;
    let table = table_of(&merged.tolerances, &merged.known())?;
    print_legend(merged.seed, "0/1", &m.out);
    let report = merged.report(&table, &mut |t, r| {
        print_shape(r, &m.out);
        eprintln!(
            "{}: {} cases × {} methods merged from {count} shards",
            r.shape,
            t.cases * t.groups.len() as u64,
            t.methods.len()
        );
    });
    finish(report, Some(&table), outputs, &m.out)
}

impl AuditOutput {
    /// The run's outputs: `--json`, `--markdown` and `extra`, checked before the run (none an
    /// input, none twice, each writable), to be committed together.
    pub(super) fn outputs(
        &self,
        extra: &[&Option<PathBuf>],
        inputs: &[PathBuf],
    ) -> Result<Outputs> {
        let files: Vec<&Path> = [&self.json, &self.markdown]
            .into_iter()
            .chain(extra.iter().copied())
            .flatten()
            .map(|p| p.as_path())
            .collect();
        let inputs: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
        check_outputs(&files, &[], &inputs)?;
        // Each replaces only what rayproof writes there: JSON (the report, a shard), the report
        for p in [&self.json]
            .into_iter()
            .chain(extra.iter().copied())
            .flatten()
        {
            rayproof::output::check_json_target(p)?;
        }
        if let Some(p) = &self.markdown {
            rayproof::output::check_markdown_target(p, table::MARKDOWN_HEADING)?;
        }
        Ok(Outputs::new().reading(&inputs))
    }
}

/// Stages `--json` and `--markdown`.
fn write_files(outputs: &mut Outputs, report: &Report, out: &AuditOutput) -> Result<()> {
    if let Some(p) = &out.json {
        outputs.write(p, (serde_json::to_string_pretty(report)? + "\n").as_bytes())?;
    }
    if let Some(p) = &out.markdown {
        outputs.write(p, table::markdown(report).as_bytes())?;
    }
    Ok(())
}

/// Prints the robustness tests' summary and the verdict, writes the files (together) and
/// returns the exit code (the same for `audit`, `merge` and `score`).
pub(super) fn finish(
    report: Report,
    table: Option<&Table>,
    mut outputs: Outputs,
    out: &AuditOutput,
) -> Result<u8> {
    if let Some(r) = &report.robustness {
        print_robustness(r, out.verbose);
    }
    write_files(&mut outputs, &report, out)?;
    outputs.commit()?;
    let Some(table) = table else {
        return Ok(0);
    };
    let o = report.outcome();
    for note in report.unused_rules(table) {
        say!("note: {note}");
    }
    say!(
        "\ntolerance table: {} rows — {} within their rule, {} known failures shown, {} reported only, {} too few cases to tell, {} out of tolerance",
        o.rows,
        o.pass,
        o.known_failures,
        o.unchecked,
        o.undecided.len(),
        o.out_of_tolerance
    );
    for u in &o.undecided {
        say!("  undecided: {u}");
    }
    // The failures, then the verdict as the last line
    for f in &o.failures {
        say!("  {f}");
    }
    if o.passed() && !o.undecided.is_empty() {
        // Exit 0 (nothing is incompatible with its rule), but not read as "every row shown ok"
        say!(
            "verdict: pass, with {} row(s) too few cases to tell (listed above)",
            o.undecided.len()
        );
    } else if o.passed() {
        say!("verdict: pass");
    } else {
        say!("verdict: {} failure(s) (listed above)", o.failures.len());
    }
    Ok(o.exit_code())
}
