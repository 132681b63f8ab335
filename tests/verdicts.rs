//! The audit's verdicts hold for any seed and any case count, and keep their teeth:
//! - unchanged code passes at other seeds and case counts (a small grid here; the note of the
//!   change that introduced it records the full grid, seeds 1–20 × 2,000 / 5,000 / 20,000);
//! - a robust method made naive, handed to the audit from outside the crate under the robust
//!   method's name, fails at 2,000 cases for every seed tried;
//! - a row with too few cases to show its known failure says so instead of passing or failing.

use rayproof::audit::plan::{Options, Plan};
use rayproof::audit::tolerance::{Status, Table};
use rayproof::audit::{audit_shape, Answer, Builtin, Method, PerCase, Shape, ShapeReport};
use rayproof::numerics::real::Real;
use rayproof::numerics::Precision;
use rayproof::shapes::{roots, shape_by_name, sphere::SphereShape};

fn options(seed: u64, cases: u64) -> Options {
    Options {
        cases: Some(cases),
        seed,
        ..Default::default()
    }
}

/// Every failing row, one line each, for a message.
fn failures(r: &ShapeReport) -> String {
    r.failures().join("\n")
}

#[test]
fn unchanged_code_passes_at_other_seeds_and_case_counts() {
    // The seeds and counts that broke the old fixed-rate table: sphere seed 2 and 3 at 20,000
    // (hearn_baker f32 far_small), 5,000 at seed 1 (rtg7 f32 huge); then fast shapes
    let grid: &[(&str, u64, u64)] = &[
        ("sphere", 2, 20_000),
        ("sphere", 3, 20_000),
        ("sphere", 1, 5_000),
        ("sphere", 7, 2_000),
        ("box", 4, 5_000),
        ("triangle", 5, 2_000),
        ("refract", 6, 5_000),
        ("rcp", 8, 5_000),
    ];
    for &(name, seed, cases) in grid {
        let shape = shape_by_name(name).unwrap();
        let r = audit_shape(shape, &options(seed, cases)).unwrap();
        assert!(
            r.failures().is_empty(),
            "{name} seed {seed}, {cases} cases:\n{}",
            failures(&r)
        );
    }
}

/// rtg7 with its discriminant made naive: `b² − a·c` in the working precision (the
/// perpendicular form removed), the stable root pair kept. Written outside the crate and handed
/// to the audit under the robust method's name, so the robust rows judge it.
struct NaiveRtg7;

fn naive_rtg7<F: Real>(v: &[f64]) -> Option<F> {
    let x: Vec<F> = v.iter().map(|&a| F::from_f64(a)).collect();
    let f = [x[0] - x[6], x[1] - x[7], x[2] - x[8]];
    let d = [x[3], x[4], x[5]];
    let dot = |a: [F; 3], b: [F; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (a, b, c) = (dot(d, d), dot(d, f), dot(f, f) - x[9] * x[9]);
    let disc = b * b - a * c;
    if disc.partial_cmp(&F::ZERO).is_none_or(|o| o.is_lt()) {
        return None;
    }
    let q = -(b + disc.sqrt().copysign(b));
    let (t0, t1) = (q / a, c / q);
    let (lo, hi) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    [lo, hi].into_iter().find(|t| *t > F::ZERO && t.is_finite())
}

impl PerCase for NaiveRtg7 {
    fn name(&self) -> &str {
        "rtg7"
    }
    fn robust(&self) -> bool {
        true
    }
    fn run(&self, input: &[f64], prec: Precision) -> Answer {
        let t = match prec {
            Precision::F32 => naive_rtg7::<f32>(input).map(|t| t as f64),
            Precision::F64 => naive_rtg7::<f64>(input),
        };
        t.map_or(Answer::miss(), |t| Answer::hit(vec![t]))
    }
}

/// The quadratic's textbook formula handed in as its robust method.
struct TextbookAsRobust(Builtin);

impl PerCase for TextbookAsRobust {
    fn name(&self) -> &str {
        "robust"
    }
    fn robust(&self) -> bool {
        true
    }
    fn run(&self, input: &[f64], prec: Precision) -> Answer {
        self.0.run(input, prec)
    }
}

/// Audits `shape` at `cases` with `method` in place of the built-in method of its name.
fn audit_with(
    shape: &'static dyn Shape,
    method: Box<dyn Method>,
    seed: u64,
    cases: u64,
) -> ShapeReport {
    let mut plan = Plan::new(&Options {
        shapes: vec![shape.name().into()],
        ..options(seed, cases)
    })
    .unwrap();
    let slot = plan.shapes[0]
        .methods
        .iter()
        .position(|m| m.name() == method.name())
        .expect("the built-in method to replace");
    plan.shapes[0].methods[slot] = method;
    let table = Table::load(None, &plan.known()).unwrap();
    plan.run_shape(0, false).unwrap().report(Some(&table))
}

#[test]
fn teeth_a_robust_method_made_naive_fails_at_2000_cases_for_every_seed() {
    for seed in [1, 2, 3] {
        let r = audit_with(&SphereShape, Box::new(NaiveRtg7), seed, 2_000);
        let failed: Vec<&str> = r
            .rows
            .iter()
            .filter(|x| x.method == "rtg7")
            .filter(|x| x.verdict.as_ref().unwrap().status == Status::Fail)
            .map(|x| x.class.as_str())
            .collect();
        // Near tangents and far-small f32 spheres the naive discriminant cancels
        assert!(
            failed.contains(&"tangent") && failed.contains(&"far_small"),
            "seed {seed}: naive rtg7 failed only on {failed:?}\n{}",
            failures(&r)
        );
        // The other methods are judged as ever: the built-in ones still pass
        assert!(r.rows.iter().filter(|x| x.method != "rtg7").all(|x| x
            .verdict
            .as_ref()
            .unwrap()
            .status
            != Status::Fail));
    }
    // A routine of the chapter: the quadratic's textbook formula as its robust method
    let textbook = Builtin {
        shape: &roots::QUADRATIC,
        index: 0,
    };
    assert_eq!(Method::name(&textbook), "textbook");
    for seed in [1, 2, 3] {
        let r = audit_with(
            &roots::QUADRATIC,
            Box::new(TextbookAsRobust(textbook)),
            seed,
            2_000,
        );
        let f = r.failures();
        assert!(
            f.iter().any(|l| l.contains("quadratic robust")),
            "seed {seed}: the textbook formula passed as robust\n{}",
            f.join("\n")
        );
    }
}

#[test]
fn a_known_failure_too_small_to_show_is_undecided_not_passed() {
    // 3 cases: algebraic f32 far_small (measured ~34 % wrong) may show no failure at all; the
    // row then says it cannot tell, and with failures it says they were shown
    for seed in 1..=40 {
        let r = audit_shape(
            &SphereShape,
            &Options {
                methods: vec!["algebraic".into()],
                classes: vec!["far_small".into()],
                precisions: vec![Precision::F32],
                ..options(seed, 3)
            },
        )
        .unwrap();
        let row = &r.rows[0];
        let v = row.verdict.as_ref().unwrap();
        if row.wrong() == 0 {
            assert_eq!(v.status, Status::Undecided, "{v:?}");
            assert!(v.notes[0].contains("too few to tell"), "{v:?}");
            return;
        }
        assert_eq!(v.status, Status::KnownFailure, "{v:?}");
    }
    panic!("no seed of 40 left the 3-case row without a failure");
}

#[test]
fn a_rate_fails_only_when_its_count_excludes_the_measurement() {
    // rtg7 f32 tangent: measured 7 wrong of 11,520 well-posed cases at seed 1
    let r = audit_shape(
        &SphereShape,
        &Options {
            methods: vec!["rtg7".into(), "algebraic".into()],
            classes: vec!["tangent".into()],
            precisions: vec![Precision::F32],
            ..options(1, 50)
        },
    )
    .unwrap();
    let table = Table::built_in();
    let with = |method: &str, wrong: u64, well: u64| {
        let mut row = r.rows.iter().find(|x| x.method == method).unwrap().clone();
        (
            row.false_hit,
            row.false_miss,
            row.wrong_root,
            row.nonfinite_t,
        ) = (0, wrong, 0, 0);
        row.well_posed = well;
        table.verdict("sphere", &row, false, |_| 0)
    };
    // The measured rate itself, and a little more, pass at any size
    for (k, n) in [(0, 2_000), (7, 11_520), (3, 2_000), (20, 20_000)] {
        assert_eq!(with("rtg7", k, n).status, Status::Pass, "{k} of {n}");
    }
    // Ten times the measured rate's upper bound fails, and says why with its probability
    let v = with("rtg7", 200, 20_000);
    assert_eq!(v.status, Status::Fail);
    assert!(
        v.reasons[0].contains("the measured 7 of 11520 allows at most"),
        "{v:?}"
    );
    // A known failure (algebraic, ~11 % measured): none in 20,000 is an alarm, none in 3 is
    // undecided, a few are shown
    assert_eq!(with("algebraic", 0, 20_000).status, Status::Fail);
    assert_eq!(with("algebraic", 0, 3).status, Status::Undecided);
    assert_eq!(with("algebraic", 2, 20).status, Status::KnownFailure);
    // ... and a rate far below the measurement's lower bound is an alarm too
    assert_eq!(with("algebraic", 5, 20_000).status, Status::Fail);
}

/// The seed sweep (issue 45): the default audit's whole selection at seeds 1–6 with 300 cases
/// per class gives every row the same verdict at every seed, and none out of tolerance (the
/// main CI job, `cargo run --release -- audit`, is the run at many cases: 20,000 per class for
/// most shapes). A rule tightened below what a seed's sample shows fails here: the rules hold
/// by what they measure (err/cond with an analysis, rates with their statistics), not by the
/// sample they were first measured on. Measured for the change: seeds 1–12 at 2,000 cases and
/// seed 1 at 20,000, 894 rows, every row one verdict.
#[test]
fn every_row_has_one_verdict_at_every_seed() {
    use std::collections::BTreeMap;
    let dir = crate::common::scratch("seed-sweep");
    let mut seen: BTreeMap<String, (u64, String)> = BTreeMap::new();
    let mut undecided = 0;
    for seed in 1..=6u64 {
        let json = dir.join(format!("s{seed}.json"));
        let o = crate::common::rayproof(&[
            "audit",
            "--cases",
            "300",
            "--seed",
            &seed.to_string(),
            "--worst",
            "0",
            "--json",
            crate::common::s(&json),
        ]);
        assert_eq!(
            o.status.code(),
            Some(0),
            "seed {seed}: {}",
            String::from_utf8_lossy(&o.stdout)
        );
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let mut rows = 0;
        for sh in v["shapes"].as_array().unwrap() {
            for r in sh["rows"].as_array().unwrap() {
                rows += 1;
                let key = format!(
                    "{} {} {} {}",
                    sh["shape"].as_str().unwrap_or("?"),
                    r["method"].as_str().unwrap(),
                    r["precision"].as_str().unwrap(),
                    r["class"].as_str().unwrap()
                );
                let status = r["verdict"]["status"].as_str().unwrap().to_string();
                assert_ne!(status, "fail", "seed {seed}: {key}: {}", r["verdict"]);
                // Too few cases to tell is the statistics' own answer for a small sample (a
                // rate row's count above its measurement's bound but not incompatible with it,
                // a known failure not shown): it depends on the sample by nature, and only a
                // measured row may give it. Every decided verdict is the same at every seed.
                if status == "undecided" {
                    assert!(r["verdict"]["count"].is_array(), "{key}: {}", r["verdict"]);
                    undecided += 1;
                    continue;
                }
                match seen.get(&key) {
                    Some((s0, st)) => assert_eq!(
                        *st, status,
                        "{key}: {st} at seed {s0}, {status} at seed {seed}"
                    ),
                    None => {
                        seen.insert(key, (seed, status));
                    }
                }
            }
        }
        assert!(rows > 800, "seed {seed}: {rows} rows");
    }
    // Rare: measured for the change, 9 of 6 × 894 rows at 300 cases (a measured rate's bound is
    // its measurement's 1e-6 Clopper–Pearson bound, far above its rate)
    assert!(undecided <= 6 * 5, "{undecided} undecided rows in 6 seeds");
    eprintln!("{undecided} undecided rows in 6 seeds");
    std::fs::remove_dir_all(&dir).ok();
}

/// The reflection rule is the analysis's bound and it is reached: a constructed f32 case (an
/// unnormalised L within 2⁻¹³ of a near-axis N) makes the FMA method and the chapter's err by
/// exactly 6 norm-ulps, the FMA rule's bound; a rule tightened below 6 would fail on it, and a
/// method worse than the analysis would exceed it.
#[test]
fn the_reflection_bound_is_reached_by_a_constructed_case() {
    use rayproof::audit::judge::{judge, value_error};
    use rayproof::audit::shape::Truth;
    let shape = shape_by_name("reflect").unwrap();
    let hex = [
        "0x1.000004p+0",
        "0x1.7fde3ep-13",
        "0x1.7ccc82p-13",
        "0x1.fffffap-1",
        "0x1.35c664p-12",
        "0x1.45fab4p-12",
    ];
    let input: Vec<f64> = hex
        .iter()
        .map(|h| rayproof::audit::hexfloat::parse_exact(h).unwrap())
        .collect();
    let prec = Precision::F32;
    let truth = shape.oracle(&input, prec);
    let Truth::Answer(e) = &truth else {
        panic!("a valid case")
    };
    let table = Table::built_in();
    for name in ["fma", "chapter"] {
        let m = shape
            .info()
            .methods
            .iter()
            .position(|m| m.name == name)
            .unwrap();
        let a = shape.run(m, &input, prec);
        assert!(
            judge(&truth, &a, shape.info(), prec).ulps().is_some(),
            "{name}: a right verdict"
        );
        let err = value_error(&e.values, &a.values, shape.info().metric, prec);
        assert_eq!(err, 6, "{name}");
        let rule = table.rule("reflect", name, prec, "unnormalised").unwrap();
        assert!(
            rule.max_ulps.unwrap() >= err,
            "{name}: the rule is below a reached case"
        );
    }
    assert_eq!(
        table
            .rule("reflect", "fma", prec, "unnormalised")
            .unwrap()
            .max_ulps,
        Some(6)
    );
}

/// The f64 promote rule follows its analysis, not a sample: a constructed well-posed case
/// (an origin within 2⁻⁵⁴ of the surface, cond 2·10¹⁶) puts double-double's C = |o−c|² − r² off by
/// enough to move t by 2 ulps, more than the old "≤ 1 ulp" rule allowed; the rule holds it.
#[test]
fn promote_in_f64_is_held_to_its_analysis_not_to_one_ulp() {
    use rayproof::audit::judge::{judge, value_error};
    use rayproof::audit::shape::Truth;
    let shape = shape_by_name("sphere").unwrap();
    let hex = "0x1.81966d64c70b0p+0 0x1.2b663812ca709p+0 -0x1.34b714041b60bp-1 -0x1.947e2a4777cf4p-2 -0x1.7ea7442acb322p-2 0x1.68668ff126141p-3 0x1.cfcbabf62b1edp-54 0x1.98f92d7a61d14p-54 0x1.a2acb02d79bc0p-57 0x1.ffffffffffffep+0";
    let input: Vec<f64> = hex
        .split(' ')
        .map(|h| rayproof::audit::hexfloat::parse_exact(h).unwrap())
        .collect();
    let prec = Precision::F64;
    let truth = shape.oracle(&input, prec);
    let Truth::Answer(e) = &truth else {
        panic!("a valid case")
    };
    assert!(!e.ill_posed);
    let m = shape
        .info()
        .methods
        .iter()
        .position(|m| m.name == "promote")
        .unwrap();
    let a = shape.run(m, &input, prec);
    assert!(judge(&truth, &a, shape.info(), prec).ulps().is_some());
    let err = value_error(&e.values, &a.values, shape.info().metric, prec);
    assert_eq!(err, 2);
    let rule = Table::built_in()
        .rule("sphere", "promote", prec, "on_surface")
        .cloned()
        .unwrap();
    assert!(rule.max_ulps.unwrap() >= err);
    let cond = e.cond.unwrap();
    assert!(
        err as f64 / cond.max(1.0) <= rule.max_err_over_cond.unwrap(),
        "cond {cond}"
    );
}

/// A routine of yours that no rule names is held to its shape's default goal (issue 49, F2):
/// before, its rows were "reported only" and an audit of a sphere routine whose t is 1.6 % too
/// far, or of one that misses everything, ended `verdict: pass`, exit 0. The same routine under
/// a rule that names it with only `why` is reported only; the certified method under another
/// name passes the goal; a built-in method no rule names is still reported only.
#[test]
fn a_routine_no_rule_names_is_held_to_the_default_goal() {
    use rayproof::audit::tolerance::DEFAULT_GOAL;
    use rayproof::audit::Audit;
    let certified = || {
        let b = Builtin::all(&SphereShape)
            .into_iter()
            .find(|b| PerCase::name(b) == "certified")
            .unwrap();
        move |x: &[f64], p: Precision| b.run(x, p)
    };
    let far = || {
        let c = certified();
        move |x: &[f64], p: Precision| {
            let mut a = c(x, p);
            for t in a.values.iter_mut() {
                *t = match p {
                    Precision::F32 => (*t * 1.016) as f32 as f64,
                    Precision::F64 => *t * 1.016,
                };
            }
            a
        }
    };
    let audit = |rules: Option<&str>| {
        let a = Audit::shape("sphere")
            .unwrap()
            .method("mine", certified())
            .method("far", far())
            .method("blind", |_: &[f64], _: Precision| Answer {
                count: 0,
                values: vec![],
                enclosure: None,
            })
            .precisions(&[Precision::F32, Precision::F64])
            .cases(200);
        match rules {
            Some(r) => a.tolerances(r),
            None => a,
        }
        .run()
        .unwrap()
    };
    let r = audit(None);
    let rows = |m: &'static str| r.rows.iter().filter(move |x| x.method == m);
    // Yours: every row judged by the default goal; the exact one passes it everywhere
    for x in rows("mine") {
        let v = x.verdict.as_ref().unwrap();
        assert_eq!(v.rule.as_deref(), Some(DEFAULT_GOAL), "{v:?}");
        assert_eq!(
            v.status,
            Status::Pass,
            "{} {}: {v:?}",
            x.precision.name(),
            x.class
        );
    }
    // t 1.6 % too far: errors thousands of times the sensitivity; missing everything: wrong
    // verdicts. Each fails on the classes with hits, and the audit fails
    for m in ["far", "blind"] {
        let failing = rows(m)
            .filter(|x| x.verdict.as_ref().unwrap().status == Status::Fail)
            .count();
        assert!(failing >= 4, "{m}: {failing} failing rows");
    }
    let failures = r.failures();
    assert!(
        failures
            .iter()
            .any(|f| f.starts_with("sphere far f32 inside: error") && f.contains(DEFAULT_GOAL)),
        "{failures:#?}"
    );
    assert!(
        failures
            .iter()
            .any(|f| f.starts_with("sphere blind f64 random:") && f.contains("wrong verdict")),
        "{failures:#?}"
    );
    // A rule naming them with only `why`: reported only, as a user asked
    let r = audit(Some(
        "[[rule]]\nshape = \"sphere\"\nmethod = [\"far\", \"blind\"]\nwhy = \"reported while I fix it\"\n",
    ));
    assert!(r.failures().is_empty(), "{:#?}", r.failures());
    for x in r.rows.iter().filter(|x| x.method != "mine") {
        assert_eq!(x.verdict.as_ref().unwrap().status, Status::Unchecked);
    }
    // A rule that gives one check keeps the rest of the goal (helper-19's finding 2: one
    // `max_false_misses = 0` passed a routine hitting everything at t = 1 and NaN hits): here
    // `far` misses nothing it should hit, and still fails on its values
    let r = audit(Some(
        "[[rule]]\nshape = \"sphere\"\nmethod = [\"far\", \"blind\"]\nmax_false_misses = 100000\nwhy = \"misses are what I watch\"\n",
    ));
    let failing = |m: &str| {
        r.rows
            .iter()
            .filter(|x| x.method == m && x.verdict.as_ref().unwrap().status == Status::Fail)
            .count()
    };
    assert!(failing("far") >= 4, "{:#?}", r.failures());
    assert_eq!(failing("mine"), 0);
    // Bounding false hits and misses, and values loosely, leaves wrong roots forbidden
    // (helper-20's finding 2: the far root passed such a rule)
    let r = audit(Some(
        "[[rule]]\nshape = \"sphere\"\nmethod = \"far\"\nmax_false_hits = 0\nmax_false_misses = 0\nmax_err_over_cond = 1e300\nwhy = \"hits and misses are what I watch\"\n",
    ));
    let f = r.failures();
    assert!(
        f.iter()
            .any(|l| l.starts_with("sphere far ") && l.contains("wrong root(s)")),
        "{f:#?}"
    );
    // NaN hits on ill-posed cases fail a routine of yours (helper-20's finding 1: they were
    // excused as disagreements), and only yours
    let mut row = r
        .rows
        .iter()
        .find(|x| x.method == "mine" && x.class == "tangent")
        .unwrap()
        .clone();
    let t = Table::built_in();
    row.ill_posed_nonfinite = 3;
    let v = t.verdict("sphere", &row, true, |_| 0);
    assert_eq!(v.status, Status::Fail, "{v:?}");
    assert!(
        v.reasons
            .iter()
            .any(|x| x.contains("(3 on ill-posed cases)")),
        "{v:?}"
    );
    row.method = "certified".into();
    assert_ne!(t.verdict("sphere", &row, false, |_| 0).status, Status::Fail);
}

/// The default goal is what the reviewed table proves for the shape's built-in methods, never
/// looser than any of them and derived from the built-in table only: sphere 31 × the case's
/// sensitivity (the interval method's midpoint), triangle 1 ulp (watertight_wide), box 10 ulps
/// (robust_slab); a user's rule for a built-in method cannot widen it.
#[test]
fn the_default_goal_is_the_loosest_proven_bound() {
    use rayproof::audit::plan::known_names;
    let goal = |t: &Table, shape: &str, p: Precision| {
        t.rule_of_yours(shape, "nobody", p, "random")
            .or_else(|| t.rule_of_yours(shape, "nobody", p, "generic"))
            .unwrap()
    };
    let t = Table::built_in();
    for p in Precision::ALL {
        let s = goal(&t, "sphere", p);
        assert_eq!((s.max_err_over_cond, s.max_ulps), (Some(31.0), None));
        assert_eq!(goal(&t, "triangle", p).max_ulps, Some(1));
        assert_eq!(goal(&t, "box", p).max_ulps, Some(10));
        // the quadratic's oracle gives the sensitivity, but its robust method is proven in ulps
        let q = goal(&t, "quadratic", p);
        assert_eq!((q.max_err_over_cond, q.max_ulps), (None, Some(4)));
        // the reciprocal bit tricks are not offered as robust: division and sqrt set the bound
        assert!(goal(&t, "rcp", p).max_ulps.unwrap() <= 2);
        assert!(goal(&t, "rsqrt", p).max_ulps.unwrap() <= 2);
    }
    for g in &t.yours {
        assert!(
            g.wrong.is_some() && g.reject_invalid && g.finite_hits,
            "{g:?}"
        );
    }
    let wide = "[[rule]]\nshape = \"sphere\"\nmethod = \"algebraic\"\nmax_err_over_cond = 1e9\nwhy = \"mine\"\n";
    let t = Table::load(Some(("user.toml", wide)), &known_names(vec![])).unwrap();
    assert_eq!(
        goal(&t, "sphere", Precision::F32).max_err_over_cond,
        Some(31.0)
    );
}
