//! `rayproof report`: what accuracy costs in time, every number measured in this run.
//!
//! ```text
//! cargo run --release -- report            # → target/report/{index.html, report.md, report.json, *.svg, img/}
//! cargo run --release -- report --out DIR  # elsewhere; --quick for a smoke run of a few seconds
//! ```
//!
//! One command writes `DIR/report.md` (the source), `DIR/index.html` (the same, rendered by
//! pulldown-cmark), `DIR/report.json` (every number), SVG figures and PNG images:
//! 1. accuracy vs cost per method × precision (the audit's errors beside in-run ns/test), with
//!    Pareto plots of wrong-verdict rate, max ulps and p99 bits of error against ns/test;
//! 2. a per-class heat table of wrong-verdict rates and, per method, histograms of bits of error
//!    per class;
//! 3. the batched (SoA, auto-vectorised, bit-identical) kernel's throughput beside the scalar one;
//! 4. the render-level trade-off ([`renders`]): `fan30`, `far` and `floor` rendered by every
//!    method × precision, frame time against image error versus `promote` f64 and versus POV-Ray,
//!    with the images side by side;
//! 5. Fan, Shen, Wang & Feng's (1996) speed claim reproduced on `seed1996` ([`seed`]);
//! 6. the cost of Newton refinement for 1/x and 1/√x over every f32 of a range, against MPFR
//!    (Lengyel's ray-tracing chapter, §1.5);
//! 7. the built-in spawn rules, self-hits against the smallest resolved gap ([`spawn`]);
//! 8. the seams between routines ([`seams`]): the box guards' lost geometry and cost, the
//!    default routines behind instance transforms in each carrying mode, and exactly one hit
//!    per closed mesh for each built-in triangle routine.
//!
//! `--plugin PATH:SYMBOL` (one precision is enough; the audit and the timing then run in the
//! precisions it has) or `--exec CMD` puts your own ray–sphere routine beside the built-in
//! methods in section 1, with its own ns per test measured on the same batch: for a plugin, the
//! time its worker spends in the routine's calls, with the harness's overhead printed apart
//! (see [`crate::audit::plugin`]); a subprocess is timed whole, pipe included.
//!
//! The directory is built beside the target and renamed into place, so a failed run never
//! leaves a half-written report.
//!
//! # Results
//!
//! One run takes about 2.5 minutes on a 2-core machine. Timings are medians of repeated runs with
//! their spread ([`crate::numerics::timing`]); the machine is shared, so the report prefers
//! ratios. The run committed in `reference/report/` (`report.md`; AMD EPYC, 2 threads, 20,000
//! cases per class) gives the Pareto plot `reference/report/pareto-wrong-rate.svg` (wrong
//! verdicts against cost).
//!
//! **What accuracy costs.** Being fast and being right are different choices, and the plot shows
//! the trade-off. In f32 the naive methods (`geometric`, 3.2 ns per test; `algebraic`, 5.8 ns) give
//! a wrong verdict on about 6 % of the well-posed hard cases. The robust `rtg7` cuts that to 0.3 %
//! for about 3× the time of `geometric`. Being right on every case (`promote`, the same formula
//! evaluated in the next wider type) costs about 10× in f32 and about 100× in f64, where
//! double-double arithmetic replaces the hardware. In a frame the picture changes. On `fan30`,
//! every naive method gets 1.1–2.8 % of the pixels wrong against POV-Ray: acne from its automatic
//! offset. Every robust method gets none wrong. `rtg7` costs about the same as the naive methods
//! per frame in f32 (0.065 s against 0.067–0.079 s at 4 spp), and about 2× in f64 (0.12 s against
//! 0.06–0.08 s). `promote` f64 takes 0.83 s and is no closer to POV-Ray than `rtg7`. Fan et al.'s
//! 3.4× speed-up of the geometric test is 1.0–1.7× today ([`seed`]).

use crate::audit::robustness::spawn::SpawnRow;
pub mod plot;
pub mod renders;
pub mod seams;
pub mod seed;
pub mod spawn;

use crate::audit::plan::{Options, Plan};
use crate::audit::run::Tallies;
use crate::audit::ShapeReport;
use crate::numerics::timing::{measure, Timing};
use crate::numerics::Precision;
use crate::shapes::sphere::cases::{generate, Class};
use crate::shapes::sphere::methods::{Method, PickPrecision, Ray, Sphere, METHODS};
use anyhow::{Context, Result};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What to run.
pub struct ReportOptions {
    /// Output directory (replaced as a whole when the report is complete).
    pub out: PathBuf,
    /// Reference directory (`scenes/` and POV-Ray references).
    pub reference: PathBuf,
    /// Seed of the audit's case streams.
    pub seed: u64,
    /// Audit cases per class.
    pub cases: u64,
    /// Small everything (renders, repeats, strided Newton inputs): for tests and smoke runs.
    pub quick: bool,
    /// Progress lines on stderr.
    pub progress: bool,
    /// A ray–sphere routine from outside the crate (a plugin, a subprocess) to put beside the
    /// built-in methods in the accuracy-vs-cost section.
    pub outside: Option<std::sync::Arc<dyn crate::audit::Method + Send>>,
    /// The precisions the outside routine answers (the audit and the timing run in these).
    pub outside_precisions: Vec<Precision>,
}

/// The classes of the timing batch: the bench's mix.
use crate::shapes::sphere::batch::MIX;

/// One method × precision: the audit's errors beside the in-run cost.
#[derive(Clone, Debug, Serialize)]
pub struct CostRow {
    /// Method name.
    pub method: String,
    /// Precision.
    pub precision: Precision,
    /// Offered as robust.
    pub robust: bool,
    /// In-run cost per test on the timing batch, in ns (an outside plugin: its routine's own
    /// calls, timed in its worker).
    pub ns: Timing,
    /// An outside plugin's harness overhead per test (batch to the worker and back), in ns.
    pub harness_ns: Option<Timing>,
    /// Wrong verdicts / well-posed valid cases, over every class.
    pub wrong_rate: f64,
    /// Wrong verdicts on well-posed cases, over every class.
    pub wrong: u64,
    /// Well-posed valid cases, over every class.
    pub well_posed: u64,
    /// Largest value error in ulps over every class.
    pub max_ulps: f64,
    /// p99 of log2(1 + ulps) over every right-verdict hit of every class (pooled).
    pub p99_bits: f64,
}

/// Everything the report shows, for report.json.
#[derive(Serialize)]
struct Numbers<'a> {
    machine: &'a Machine,
    cost: &'a [CostRow],
    audit: &'a ShapeReport,
    batch: &'a [crate::shapes::sphere::batch::BatchRow],
    renders: &'a [renders::RenderRow],
    seed1996: &'a seed::SeedRepro,
    newton: &'a [crate::shapes::recip::newton::NewtonRow],
    newton_starts: &'a [crate::shapes::recip::newton::StartRow],
    spawn: &'a [SpawnRow],
    seams: &'a seams::Seams,
}

/// Where the numbers were measured.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// CPU model name.
    pub cpu: String,
    /// Threads available.
    pub threads: usize,
    /// Operating system (Rust's `std::env::consts::OS`).
    pub os: String,
    /// The tool and its version.
    pub tool: &'static str,
    /// UTC date of the run.
    pub date: String,
}

impl Machine {
    /// The machine this runs on, now.
    pub fn read() -> Machine {
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split(':').nth(1))
                    .map(|m| m.trim().to_string())
            })
            .unwrap_or_else(|| std::env::consts::ARCH.into());
        Machine {
            cpu,
            threads: rayon::current_num_threads(),
            os: std::env::consts::OS.into(),
            tool: concat!("rayproof ", env!("CARGO_PKG_VERSION")),
            date: crate::golden::utc_now(),
        }
    }
}

/// Runs everything and writes the report directory.
pub fn run(o: &ReportOptions) -> Result<()> {
    // Refuse early: every scene the report renders must load
    for name in renders::SCENES.iter().chain(&["seed1996"]) {
        let path = o.reference.join("scenes").join(format!("{name}.toml"));
        crate::render::scene::load(&path)?;
    }
    // Built in a staged directory that replaces the previous report whole at the end; a
    // directory rayproof did not make is refused before anything runs
    crate::output::check_outputs(&[], &[&o.out], &[&o.reference])?;
    let mut out = crate::output::Outputs::new().reading(&[&o.reference]);
    out.dir_with(&o.out, |dir| {
        std::fs::create_dir(dir.join("img"))
            .with_context(|| format!("cannot create {}", dir.display()))?;
        build(o, dir)
    })?;
    out.commit()
}

/// Progress: one line per step on stderr, on a terminal or not (the audit's bar only on one).
fn say(what: &str) {
    eprintln!("report: {what}");
}

fn build(o: &ReportOptions, dir: &Path) -> Result<()> {
    let machine = Machine::read();
    // 1. Audit with raw samples, and in-run timing of every method
    say("auditing every method × precision × class");
    let plan = Plan::new(&Options {
        shapes: vec!["sphere".into()],
        cases: Some(o.cases),
        seed: o.seed,
        shard: (0, 1),
        ..Default::default()
    })
    .map_err(|e| anyhow::anyhow!(e))?;
    let mut plan = plan;
    if let Some(m) = &o.outside {
        plan.shapes[0].methods.push(Box::new(Shared(m.clone())));
        // The audit runs in the precisions the routine answers
        plan.precisions.retain(|p| o.outside_precisions.contains(p));
        if plan.precisions.is_empty() {
            anyhow::bail!("report: the outside routine answers no precision");
        }
    }
    let tallies = plan.run_shape(0, o.progress)?;
    plan.finish()?;
    let report = tallies.report(None);
    say("timing every method × precision");
    let runs = if o.quick { 3 } else { 9 };
    let min_ns = if o.quick { 2e6 } else { 2e7 };
    let mut t32: Vec<(Timing, Option<Timing>)> = time_methods::<f32>(o.seed, runs, min_ns)
        .into_iter()
        .map(|t| (t, None))
        .collect();
    let mut t64: Vec<(Timing, Option<Timing>)> = time_methods::<f64>(o.seed, runs, min_ns)
        .into_iter()
        .map(|t| (t, None))
        .collect();
    if let Some(m) = &o.outside {
        for (p, t) in [(Precision::F32, &mut t32), (Precision::F64, &mut t64)] {
            if plan.precisions.contains(&p) {
                t.push(time_outside(m.as_ref(), p, o.seed, runs, min_ns)?);
            }
        }
    }
    let cost = cost_rows(&report, &tallies, &plan.precisions, &t32, &t64);
    // 2. Batched kernel, checked bit-identical before timing
    say("timing the batched kernel");
    let mut bopts = crate::shapes::sphere::batch::BatchOpts::report();
    if o.quick {
        bopts.runs = 3;
    }
    let batch = crate::shapes::sphere::batch::throughput_table(&bopts)
        .map_err(|m| anyhow::anyhow!("batched kernel differs from the scalar method: {m}"))?;
    // 3. Render-level trade-off
    say("rendering fan30, far, floor with every method × precision");
    let (w, g, rruns) = if o.quick {
        (Some(32), Some(2), 1)
    } else {
        (None, None, 3)
    };
    let rows = renders::run(&o.reference, &dir.join("img"), w, g, 2, rruns)?;
    // 4. Seed 000's claim
    say("reproducing seed 000's timing on seed1996");
    let sc = crate::render::scene::load(&o.reference.join("scenes/seed1996.toml"))?;
    let repro = seed::run(&sc, o.quick.then_some(64), if o.quick { 1 } else { 3 });
    for (label, img) in &repro.images {
        let rgb = crate::images::tonemap_rgb8(img);
        let name = format!("seed1996-{}.png", label.replace('/', "-"));
        crate::images::write_png_rgb8(&dir.join("img").join(name), img.width, img.height, &rgb)?;
    }
    // 5. Newton refinement
    say("measuring rcp/rsqrt Newton refinement over every f32 of the range");
    let newton = crate::shapes::recip::newton::table(&if o.quick {
        crate::shapes::recip::newton::NewtonOpts::fast()
    } else {
        crate::shapes::recip::newton::NewtonOpts::exhaustive()
    });
    let starts = crate::shapes::recip::newton::start_bound_table();
    // 6. Spawn rules
    say("auditing the five built-in spawn rules at every scale");
    let spawn_rows = spawn_rows(o.seed, if o.quick { 4 } else { 16 })?;
    // 8. The seams between routines
    say("auditing the box guards, the instance transforms and exactly one hit per mesh");
    let seams = seams::rows(o.seed, o.quick)?;
    // Write
    say("writing");
    let md = markdown(
        &machine,
        o.seed,
        &o.cases,
        &cost,
        &report,
        &tallies,
        &batch,
        &rows,
        &repro,
        &newton,
        &starts,
        &spawn_rows,
        &seams,
        dir,
    )?;
    let html = to_html(&md);
    let numbers = Numbers {
        machine: &machine,
        cost: &cost,
        audit: &report,
        batch: &batch,
        renders: &rows,
        seed1996: &repro,
        newton: &newton,
        newton_starts: &starts,
        spawn: &spawn_rows,
        seams: &seams,
    };
    crate::output::write_atomic(&dir.join("report.md"), md.as_bytes())?;
    crate::output::write_atomic(&dir.join("index.html"), html.as_bytes())?;
    crate::output::write_atomic(
        &dir.join("report.json"),
        (serde_json::to_string_pretty(&numbers)? + "\n").as_bytes(),
    )?;
    Ok(())
}

/// ns per test of every method in one precision, on the mix of hard classes.
fn time_methods<F: PickPrecision>(seed: u64, runs: usize, min_ns: f64) -> Vec<Timing> {
    let cases: Vec<_> = MIX
        .iter()
        .flat_map(|&c| (0..512).filter_map(move |i| generate::<F>(seed, c, i)))
        .collect();
    let rays: Vec<Ray<F>> = cases.iter().map(|c| c.ray()).collect();
    let spheres: Vec<Sphere<F>> = cases.iter().map(|c| c.sphere()).collect();
    METHODS
        .iter()
        .map(|m: &Method| {
            let f = F::pick(m);
            measure(rays.len(), runs, min_ns, || {
                rays.iter()
                    .zip(&spheres)
                    .filter(|(r, s)| f(std::hint::black_box(r), s).is_some())
                    .count()
            })
        })
        .collect()
}

/// A method shared between the audit and the timing.
struct Shared(std::sync::Arc<dyn crate::audit::Method + Send>);

impl crate::audit::Method for Shared {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn robust(&self) -> bool {
        self.0.robust()
    }
    fn replay(&self) -> Option<String> {
        self.0.replay()
    }
    fn answer(
        &self,
        prec: Precision,
        inputs: &[Vec<f64>],
    ) -> std::result::Result<Vec<crate::audit::Answer>, String> {
        self.0.answer(prec, inputs)
    }
    fn own_nanos(&self, prec: Precision) -> Option<u64> {
        self.0.own_nanos(prec)
    }
}

/// ns per test of an outside method on the same mix, one batch per call: the routine's own
/// calls where it can be timed where it runs (a plugin's worker times each call of its symbol),
/// and beside it the harness's overhead (handing the batch to the worker and back, checking the
/// answers) per test; a subprocess is timed whole (its figure includes the pipe).
fn time_outside(
    m: &dyn crate::audit::Method,
    prec: Precision,
    seed: u64,
    runs: usize,
    min_ns: f64,
) -> Result<(Timing, Option<Timing>)> {
    let inputs: Vec<Vec<f64>> = match prec {
        Precision::F32 => mix_inputs::<f32>(seed),
        Precision::F64 => mix_inputs::<f64>(seed),
    };
    // A failure shows before timing
    m.answer(prec, &inputs)
        .map_err(crate::audit::run::MethodFailed)?;
    let units = inputs.len() as f64;
    let (mut own, mut overhead) = (vec![], vec![]);
    for _ in 0..runs.max(1) {
        let (mut reps, mut elapsed) = (0u64, 0f64);
        let before = m.own_nanos(prec);
        let clock = std::time::Instant::now();
        while elapsed < min_ns || reps == 0 {
            m.answer(prec, std::hint::black_box(&inputs))
                .map_err(crate::audit::run::MethodFailed)?;
            reps += 1;
            elapsed = clock.elapsed().as_nanos() as f64;
        }
        let per = |ns: f64| ns / (reps as f64 * units);
        match (before, m.own_nanos(prec)) {
            (Some(a), Some(b)) => {
                let routine = b.saturating_sub(a) as f64;
                own.push(per(routine));
                overhead.push(per((elapsed - routine).max(0.0)));
            }
            _ => own.push(per(elapsed)),
        }
    }
    let overhead = (!overhead.is_empty()).then(|| Timing::of(overhead));
    Ok((Timing::of(own), overhead))
}

/// The timing batch's inputs (the bench's mix) as `f64` scalars.
fn mix_inputs<F: PickPrecision>(seed: u64) -> Vec<Vec<f64>> {
    MIX.iter()
        .flat_map(|&c| (0..512).filter_map(move |i| generate::<F>(seed, c, i)))
        .map(|c| c.scalars().iter().map(|x| x.to_f64()).collect())
        .collect()
}

/// Pools the audit over classes per method × precision and sets it beside the timing.
fn cost_rows(
    report: &ShapeReport,
    tallies: &Tallies,
    precisions: &[Precision],
    t32: &[(Timing, Option<Timing>)],
    t64: &[(Timing, Option<Timing>)],
) -> Vec<CostRow> {
    let mut out = vec![];
    for &p in precisions {
        for (k, m) in tallies.methods.iter().enumerate() {
            let rows: Vec<_> = report
                .rows
                .iter()
                .filter(|r| r.method == m.name && r.precision == p)
                .collect();
            let wrong: u64 = rows.iter().map(|r| r.wrong()).sum();
            let well_posed: u64 = rows.iter().map(|r| r.well_posed).sum();
            let mut bits: Vec<f64> = Class::ALL
                .iter()
                .flat_map(|&c| tallies.ulps(&m.name, p, c.name()))
                .map(|u| (1.0 + u as f64).log2())
                .collect();
            bits.sort_by(f64::total_cmp);
            let p99 = bits
                .get(((bits.len().max(1) - 1) as f64 * 0.99).round() as usize)
                .copied()
                .unwrap_or(0.0);
            out.push(CostRow {
                method: m.name.clone(),
                precision: p,
                robust: m.robust,
                ns: if p == Precision::F32 {
                    t32[k].0.clone()
                } else {
                    t64[k].0.clone()
                },
                harness_ns: if p == Precision::F32 {
                    t32[k].1.clone()
                } else {
                    t64[k].1.clone()
                },
                wrong_rate: wrong as f64 / well_posed.max(1) as f64,
                wrong,
                well_posed,
                max_ulps: rows.iter().map(|r| r.ulps.max).fold(0.0, f64::max),
                p99_bits: p99,
            });
        }
    }
    out
}

/// A method's position in [`METHODS`] (its colour in every plot); an outside method comes
/// after them.
fn method_index(name: &str) -> usize {
    METHODS
        .iter()
        .position(|m| m.name == name)
        .unwrap_or(METHODS.len())
}

/// Background colour of a heat-table cell: green at 0, through yellow, to red at ≥ 10 %.
fn heat(rate: f64) -> String {
    if rate == 0.0 {
        return "#c8ecc8".into();
    }
    // log scale from 1e-5 to 1e-1
    let x = ((rate.log10() + 5.0) / 4.0).clamp(0.0, 1.0);
    let (r, g) = if x < 0.5 {
        (255.0, 240.0 - 40.0 * x)
    } else {
        (255.0, 220.0 - 300.0 * (x - 0.5))
    };
    format!(
        "#{:02x}{:02x}{:02x}",
        r as u8,
        g as u8,
        (150.0 * (1.0 - x)) as u8
    )
}

fn pct(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x < 1e-4 {
        format!("{:.1e}%", 100.0 * x)
    } else {
        format!("{:.3}%", 100.0 * x)
    }
}

/// The report's Markdown (with inline HTML for the heat table and image grids).
#[allow(clippy::too_many_arguments)]
fn markdown(
    machine: &Machine,
    seed: u64,
    cases: &u64,
    cost: &[CostRow],
    report: &ShapeReport,
    tallies: &Tallies,
    batch: &[crate::shapes::sphere::batch::BatchRow],
    rows: &[renders::RenderRow],
    repro: &seed::SeedRepro,
    newton: &[crate::shapes::recip::newton::NewtonRow],
    starts: &[crate::shapes::recip::newton::StartRow],
    spawn_rows: &[SpawnRow],
    seams: &seams::Seams,
    dir: &Path,
) -> Result<String> {
    let mut md = Markdown {
        s: String::new(),
        dir,
    };
    // Header
    md.header(machine, seed, cases)?;
    // 1. Accuracy vs cost
    md.cost(cost)?;
    // 2. Wrong-verdict rates and bits of error per class: the audit's own data
    md.classes(report, tallies)?;
    // 3. Batched kernel
    md.batch(batch)?;
    // 4. Render-level trade-off
    md.renders(rows)?;
    // 5. Seed 000
    md.seed1996(repro)?;
    // 6. Newton
    md.newton(newton, starts);
    // 7. Spawn rules
    md.spawn(spawn_rows)?;
    // 8. The seams between routines
    md.s += &seams::markdown(seams)?;
    Ok(md.s)
}

/// The five built-in spawn rules' rows over both precisions, every scene size and placement,
/// `per_cell` triangles each, judged by their default goals (pbrt's: no self-hit).
fn spawn_rows(seed: u64, per_cell: u64) -> Result<Vec<SpawnRow>> {
    use crate::audit::robustness::spawn as sp;
    let cells = sp::cells(seed, &Precision::ALL, per_cell);
    let mut rows = vec![];
    for k in 0..sp::BUILT_IN.len() {
        rows.extend(sp::rows(&sp::BuiltIn(k), &cells).map_err(|e| anyhow::anyhow!(e))?);
    }
    sp::judge_rows(&mut rows, &|x| sp::default_goal(&x.rule, false));
    Ok(rows)
}

/// The report's Markdown as it is written, and the directory its figures go to.
struct Markdown<'a> {
    s: String,
    dir: &'a Path,
}

impl Markdown<'_> {
    /// Writes the figure `name` and links it.
    fn svg(&mut self, name: &str, body: String) -> Result<()> {
        crate::output::write_atomic(&self.dir.join(name), body.as_bytes())?;
        self.s += &format!("![{name}]({name})\n\n");
        Ok(())
    }

    /// Title, machine and what was measured.
    fn header(&mut self, machine: &Machine, seed: u64, cases: &u64) -> Result<()> {
        writeln!(
            self.s,
            "# rayproof report: what accuracy costs in time\n\n\
             Measured on **{}** ({} threads, {}) by {} on {}. Every number below was measured in \
             this run: the audit against the MPFR oracle (seed {}, {} cases per class), timings \
             as the median of repeated runs with ± half their spread. The machine is shared and \
             noisy: trust ratios between rows more than absolute nanoseconds; `cargo bench` \
             (criterion) is the precise tool.\n",
            machine.cpu, machine.threads, machine.os, machine.tool, machine.date, seed, cases
        )?;
        Ok(())
    }

    /// Section 1: the cost table and three Pareto plots.
    fn cost(&mut self, cost: &[CostRow]) -> Result<()> {
        // The table
        self.s += "## 1. Accuracy vs cost, per ray–sphere test\n\n\
              ns/test: one thread, the bench's mix of hard classes (random, inside, far_small, huge, \
              grazing, behind; 512 cases each). Errors: the audit over every class; wrong = false hit, \
              false miss, wrong root or non-finite t on a well-posed case; ulps and bits over \
              right-verdict hits.\n\n\
              | method | precision | robust | ns/test | × geometric | wrong verdicts | wrong rate | max ulps | p99 bits |\n\
              |---|---|---|---:|---:|---:|---:|---:|---:|\n";
        for r in cost {
            let geo = cost
                .iter()
                .find(|g| g.method == "geometric" && g.precision == r.precision)
                .map_or(f64::NAN, |g| g.ns.median_ns);
            writeln!(
                self.s,
                "| {} | {} | {} | {} | {:.2} | {} / {} | {} | {:.3e} | {:.2} |",
                r.method,
                r.precision.name(),
                if r.robust { "yes" } else { "no" },
                r.ns.label(),
                r.ns.median_ns / geo,
                r.wrong,
                r.well_posed,
                pct(r.wrong_rate),
                r.max_ulps,
                r.p99_bits
            )?;
        }
        for r in cost {
            if let Some(h) = &r.harness_ns {
                writeln!(
                    self.s,
                    "\n`{}` {}: ns/test is the routine's own calls, timed in its worker process; \
                     the harness (batch to the worker and back, answers checked) adds {} per test, \
                     not counted.",
                    r.method,
                    r.precision.name(),
                    h.label()
                )?;
            }
        }
        self.s += "\n";
        // The Pareto plots: cost against three error measures
        let pts = |y: &dyn Fn(&CostRow) -> f64| -> Vec<plot::Point> {
            cost.iter()
                .map(|r| plot::Point {
                    label: format!("{}/{}", r.method, r.precision.name()),
                    x: r.ns.median_ns,
                    y: y(r),
                    robust: r.robust,
                    colour: method_index(&r.method),
                    square: r.precision == Precision::F64,
                })
                .collect()
        };
        let floor_rate = 0.1 / cost.iter().map(|r| r.well_posed).max().unwrap_or(1).max(1) as f64;
        self.s +=
            "One colour per method; circles f32, triangles f64; filled marks the robust methods. \
              The red line is the Pareto front: nothing is both faster and more accurate than a \
              point on it. Zero errors are drawn on the grey line at the bottom.\n\n";
        self.svg(
            "pareto-wrong-rate.svg",
            plot::pareto_svg(
                "Wrong verdicts vs cost",
                "ns per test (log)",
                "wrong-verdict rate, well-posed cases (log)",
                &pts(&|r| r.wrong_rate),
                floor_rate,
            ),
        )?;
        self.svg(
            "pareto-max-ulps.svg",
            plot::pareto_svg(
                "Worst t error vs cost",
                "ns per test (log)",
                "max ulps of t (log)",
                &pts(&|r| r.max_ulps),
                0.1,
            ),
        )?;
        self.svg(
            "pareto-p99-bits.svg",
            plot::pareto_svg(
                "p99 bits of error vs cost",
                "ns per test (log)",
                "p99 of log2(1 + ulps) (log)",
                &pts(&|r| r.p99_bits),
                0.01,
            ),
        )
    }

    /// Section 2, from the audit's rows and raw samples: the heat table of wrong-verdict rates
    /// per class and the histograms of bits of error per class.
    fn classes(&mut self, report: &ShapeReport, tallies: &Tallies) -> Result<()> {
        // Heat table
        self.s += "## 2. Wrong-verdict rate per class\n\nGreen: none; yellow to red on a log scale up to 10 %. \
              Ill-posed cases (the exact answer is decided by less than the input's rounding) are \
              not counted.\n\n<table class=\"heat\"><tr><th>method</th><th>precision</th>";
        for c in Class::ALL {
            write!(self.s, "<th>{}</th>", c.name())?;
        }
        self.s += "</tr>\n";
        // The precisions audited (an outside routine of one precision narrows the audit)
        let audited: Vec<Precision> = Precision::ALL
            .into_iter()
            .filter(|&p| report.rows.iter().any(|r| r.precision == p))
            .collect();
        for &p in &audited {
            for m in &tallies.methods {
                write!(self.s, "<tr><td>{}</td><td>{}</td>", m.name, p.name())?;
                for c in Class::ALL {
                    match report
                        .rows
                        .iter()
                        .find(|r| r.method == m.name && r.precision == p && r.class == c.name())
                    {
                        Some(r) if r.well_posed > 0 => write!(
                            self.s,
                            "<td style=\"background:{}\" title=\"{} wrong of {}\">{}</td>",
                            heat(r.wrong_rate),
                            r.wrong(),
                            r.well_posed,
                            pct(r.wrong_rate)
                        )?,
                        _ => self.s += "<td>—</td>",
                    }
                }
                self.s += "</tr>\n";
            }
        }
        self.s += "</table>\n\n";
        // ULP histograms
        self.s +=
            "### Bits of error per class\n\nFor each method and precision: the share of right-verdict \
              hits per ⌈log2(1 + ulps)⌉, one line per class (0 = correctly rounded).\n\n";
        for m in &tallies.methods {
            for &p in &audited {
                let series: Vec<(String, Vec<f64>)> = Class::ALL
                    .iter()
                    .map(|&c| {
                        let b = tallies
                            .ulps(&m.name, p, c.name())
                            .into_iter()
                            .map(|u| (1.0 + u as f64).log2())
                            .collect();
                        (c.name().to_string(), b)
                    })
                    .filter(|(_, b): &(String, Vec<f64>)| !b.is_empty())
                    .collect();
                self.svg(
                    &format!("bits-{}-{}.svg", m.name, p.name()),
                    plot::bits_histogram_svg(&format!("{} / {}", m.name, p.name()), &series),
                )?;
            }
        }
        Ok(())
    }

    /// Section 3: the batched kernel's throughput beside the scalar one.
    fn batch(&mut self, batch: &[crate::shapes::sphere::batch::BatchRow]) -> Result<()> {
        self.s += "## 3. Batched (structure-of-arrays) kernel\n\nThe same 3,072 mix cases in ten columns, \
              lanes computed without branches (auto-vectorised; SSE2, and AVX2 or AVX-512 picked at run \
              time, no FMA). Every answer was checked bit-identical to the scalar method before timing. One \
              thread; speed-up = scalar ÷ batched.\n\n\
              | method | precision | instruction set | scalar ns/test | batched ns/test | speed-up |\n\
              |---|---|---|---:|---:|---:|\n";
        for b in batch {
            writeln!(
                self.s,
                "| {} | {} | {} | {} | {} | {:.2}× |",
                b.method,
                b.precision,
                b.isa,
                b.scalar.label(),
                b.batched.label(),
                b.speedup
            )?;
        }
        Ok(())
    }

    /// Section 4: per scene, time against image error, and the images.
    fn renders(&mut self, rows: &[renders::RenderRow]) -> Result<()> {
        self.s += "\n## 4. Render-level trade-off\n\n";
        self.s += &format!(
            "Each scene rendered by every method × precision at the references' size and grid (the \
             image compared and shown), and timed separately at 4 samples per pixel (wall seconds \
             per frame, all threads, median of interleaved runs; time is proportional to the \
             samples). Error: mean |Δ| and the share of pixels with a channel off by more than \
             0.05, against the {} {} render and against POV-Ray 3.7.\n\n",
            renders::BASELINE.0,
            renders::BASELINE.1
        );
        for name in renders::SCENES {
            let sr: Vec<&renders::RenderRow> = rows.iter().filter(|r| r.scene == name).collect();
            if sr.is_empty() {
                continue;
            }
            self.render_scene(name, &sr)?;
        }
        Ok(())
    }

    /// One scene of section 4: its table, its Pareto plot and its images.
    fn render_scene(&mut self, name: &str, sr: &[&renders::RenderRow]) -> Result<()> {
        // The table
        writeln!(
            self.s,
            "### {name}\n\n| method | precision | s per 4-spp frame | rays (image) | mean vs {b} | px > 0.05 vs {b} | mean vs POV-Ray | px > 0.05 vs POV-Ray |\n|---|---|---:|---:|---:|---:|---:|---:|",
            b = format!("{}/{}", renders::BASELINE.0, renders::BASELINE.1)
        )?;
        for r in sr {
            writeln!(
                self.s,
                "| {} | {} | {:.3} {} | {} | {:.2e} | {} | {} | {} |",
                r.method,
                r.precision,
                r.seconds.median_ns,
                r.seconds.plus_minus(),
                r.rays,
                r.vs_baseline_mean,
                pct(r.vs_baseline_fail),
                r.vs_povray_mean.map_or("—".into(), |v| format!("{v:.2e}")),
                r.vs_povray_fail.map_or("—".into(), pct)
            )?;
        }
        self.s += "\n";
        // The plot: frame time against the error to POV-Ray (or the baseline)
        let p: Vec<plot::Point> = sr
            .iter()
            .map(|r| plot::Point {
                label: format!("{}/{}", r.method, r.precision),
                x: r.seconds.median_ns,
                y: r.vs_povray_mean.unwrap_or(r.vs_baseline_mean),
                robust: r.robust,
                colour: method_index(r.method),
                square: r.precision == "f64",
            })
            .collect();
        let against = if sr.iter().all(|r| r.vs_povray_mean.is_some()) {
            "POV-Ray"
        } else {
            "the baseline"
        };
        self.svg(
            &format!("render-{name}.svg"),
            plot::pareto_svg(
                &format!("{name}: frame time vs image error"),
                "seconds per 4-spp frame (log)",
                &format!("mean |Δ| vs {against} (log)"),
                &p,
                1e-9,
            ),
        )?;
        // The images
        self.s += "<div class=\"grid\">";
        if sr.iter().any(|r| r.vs_povray_mean.is_some()) {
            write!(self.s, "<figure><img src=\"img/{name}-povray.png\"><figcaption>POV-Ray 3.7</figcaption></figure>")?;
        }
        for r in sr {
            write!(
                self.s,
                "<figure><img src=\"img/{}\"><figcaption>{}/{} — {} px</figcaption></figure>",
                r.png,
                r.method,
                r.precision,
                pct(r.vs_povray_fail.unwrap_or(r.vs_baseline_fail))
            )?;
        }
        self.s += "</div>\n\n";
        Ok(())
    }

    /// Section 5: seed 000's speed claim on `seed1996`, with the images.
    fn seed1996(&mut self, repro: &seed::SeedRepro) -> Result<()> {
        self.s += "## 5. Seed 000's speed claim, reproduced\n\n\
              Fan et al. (1996) report for 30 spheres at 1024×1024, d = 5, m = 2, about 15 M rays: \
              the algebraic method about 2 h and the geometric one about 35 min on an SGI \
              workstation. The scene `reference/scenes/seed1996.toml` was built to that budget; both \
              methods render it in both precisions, with every ray testing all 30 spheres (flat, as \
              in 1996) and with a BVH.\n\n";
        self.s += &repro.markdown();
        self.s += "\n<div class=\"grid\">";
        for (label, _) in &repro.images {
            write!(
                self.s,
                "<figure><img src=\"img/seed1996-{}.png\"><figcaption>{label}</figcaption></figure>",
                label.replace('/', "-")
            )?;
        }
        self.s += "</div>\n\n";
        self.s += &seed::explanation(repro);
        Ok(())
    }

    /// Section 7: the built-in spawn rules, both ways: self-hits and the smallest resolved gap.
    fn spawn(&mut self, rows: &[SpawnRow]) -> Result<()> {
        self.s += "\n## 7. Spawn rules: self-hits against the smallest resolved gap (issue 47)\n\n\
              Triangles of size 1e-4 … 1e7 near the origin and 10³–10⁵ sizes away, hit by \
              pbrt-v4's watertight test; 8 rays spawned from each hit under each rule. A self-hit \
              is judged by the exact oracle; the gap is the largest height above the surface at \
              which a spawned ray starts taking hits, exact: a parallel neighbour nearer than that \
              is skipped (`rayproof spawn` has the method and replay lines).\n\n";
        for (name, about) in crate::audit::robustness::spawn::BUILT_IN {
            let mine: Vec<&SpawnRow> = rows.iter().filter(|r| r.rule == name).collect();
            let rays: u64 = mine.iter().map(|r| r.rays).sum();
            let hits: u64 = mine.iter().map(|r| r.self_hits).sum();
            let (lo, hi) = mine
                .iter()
                .filter(|r| r.rays > 0)
                .fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
                    (lo.min(r.gap_ulps), hi.max(r.gap_ulps))
                });
            let ulps = |x: f64| {
                if x < 1e4 {
                    format!("{x:.1}")
                } else {
                    format!("{x:.2e}")
                }
            };
            writeln!(
                self.s,
                "- **{name}** ({about}): {hits} self-hits of {rays} rays; resolved gap {} … {} ulps of max|p|.",
                ulps(lo),
                ulps(hi)
            )?;
        }
        self.s += "\n";
        for (file, svg) in spawn::figures(rows) {
            self.svg(&format!("spawn-{file}"), svg)?;
        }
        self.s += "<details><summary>Every cell</summary>\n\n";
        self.s += &crate::audit::robustness::spawn::markdown(rows);
        self.s += "\n</details>\n\n";
        Ok(())
    }

    /// Section 6: Newton refinement of rcp/rsqrt.
    fn newton(
        &mut self,
        newton: &[crate::shapes::recip::newton::NewtonRow],
        starts: &[crate::shapes::recip::newton::StartRow],
    ) {
        self.s += "\n## 6. Accuracy cost of Newton refinement (seed 002 §1.5)\n\n";
        self.s += &newton_markdown(newton, starts);
    }
}

/// Markdown → a standalone HTML page.
fn to_html(md: &str) -> String {
    use pulldown_cmark::{html, Options, Parser};
    let mut body = String::new();
    html::push_html(&mut body, Parser::new_ext(md, Options::ENABLE_TABLES));
    format!(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>rayproof report</title><style>\n\
         body{{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}}\n\
         table{{border-collapse:collapse;margin:1em 0;font-size:13px}}td,th{{border:1px solid #ccc;padding:3px 7px}}\n\
         td{{text-align:right}}td:first-child,td:nth-child(2){{text-align:left}}\n\
         .grid{{display:flex;flex-wrap:wrap;gap:6px}}figure{{margin:0;font-size:11px;text-align:center}}\n\
         figure img{{width:160px;image-rendering:pixelated}}img{{max-width:100%}}\n\
         </style></head><body>\n{body}</body></html>\n"
    )
}

/// The Newton table and the start-value demonstration, Markdown.
fn newton_markdown(
    rows: &[crate::shapes::recip::newton::NewtonRow],
    starts: &[crate::shapes::recip::newton::StartRow],
) -> String {
    let mut s = String::from(
        "Every f32 of [1, 2) for 1/x and of [1, 4) for 1/√x (the methods repeat over binades), \
         against MPFR; error in ulps of f32 at the exact value. ns per value: one thread, a \
         fixed array of 4096 inputs, median of runs.\n\n\
         | function | start | Newton steps | inputs | max ulps | worst input | mean ulps | derived bound (ulps) | ns/value |\n\
         |---|---|---:|---:|---:|---|---:|---:|---:|\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.3} | `{}` | {:.3} | {:.3} | {} |",
            r.function,
            r.start,
            r.steps.map_or("—".into(), |n| n.to_string()),
            r.inputs,
            r.max_ulps,
            r.worst_input,
            r.mean_ulps,
            r.bound_ulps,
            r.ns.label()
        );
    }
    s += "\nThe chapter's condition on the start value, 0 < x₀ < 2/r for 1/x (0 < y₀ < √(3/r) for \
          1/√x): iterating from x₀ = k·(exact answer), in f64.\n\n\
          | function | r | k | inside the bound | outcome |\n|---|---:|---:|---|---|\n";
    for st in starts {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:?} |",
            st.function,
            st.r,
            st.k,
            if st.inside { "yes" } else { "no" },
            st.outcome
        );
    }
    s
}
