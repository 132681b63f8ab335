//! Ray–torus (§2.5) and its normal (§3): the oracle on hand-made cases with known exact answers,
//! every method × precision × class of the default audit against the tolerance table, the
//! harness's teeth, the reintersection error bound, proptest stability suites, and invalid
//! inputs (reintersection itself: `tests/reintersect.rs`).

use proptest::prelude::*;
use rayproof::audit::plan::Options;
use rayproof::audit::tolerance::Table;
use rayproof::audit::Judgement;
use rayproof::audit::{audit_shape, table, Row, ShapeReport};
use rayproof::audit::{judge, Answer, Shape, Truth};
use rayproof::numerics::Precision;
use rayproof::shapes::torus::{
    cases, methods, oracle, torus_normal, torus_robust, torus_robust_hit, Torus, TorusNormal,
    ERR_GAMMA, METHODS,
};
use rug::{Float, Rational};
use std::sync::OnceLock;

// ---- the default audit, run once for every row test ----

/// Cases per class of the default audit (seed 1).
const CASES: u64 = 300;

fn opts() -> Options {
    Options {
        cases: Some(CASES),
        seed: 1,
        precisions: Precision::ALL.to_vec(),
        methods: vec![],
        classes: vec![],
        ..Default::default()
    }
}

fn torus_report() -> &'static ShapeReport {
    static R: OnceLock<ShapeReport> = OnceLock::new();
    R.get_or_init(|| audit_shape(&Torus, &opts()).expect("valid selection"))
}

fn normal_report() -> &'static ShapeReport {
    static R: OnceLock<ShapeReport> = OnceLock::new();
    R.get_or_init(|| audit_shape(&TorusNormal, &opts()).expect("valid selection"))
}

fn row(report: &'static ShapeReport, method: &str, p: Precision, class: &str) -> &'static Row {
    report
        .rows
        .iter()
        .find(|r| r.method == method && r.precision == p && r.class == class)
        .expect("row present")
}

/// Every row of a method, both shapes: the tolerance table holds, the generator filled the
/// class, the oracle never hit its cap, and valid classes are mostly well-posed.
fn check_method(method: &str) {
    for (shape, report) in [
        (&Torus as &dyn Shape, torus_report()),
        (&TorusNormal, normal_report()),
    ] {
        let rows: Vec<Row> = report
            .rows
            .iter()
            .filter(|r| r.method == method)
            .cloned()
            .collect();
        assert_eq!(rows.len(), 2 * cases::CLASSES.len());
        let single = ShapeReport {
            rows: rows.clone(),
            ..report.clone()
        };
        let breaks = &single.failures();
        assert!(breaks.is_empty(), "{}", breaks.join("\n"));
        for r in &rows {
            assert_eq!(r.generator_failures, 0, "{} {}", shape.name(), r.class);
            assert_eq!(r.cap_reached, 0, "{} {} cap", shape.name(), r.class);
            if r.class != "invalid" {
                assert!(
                    r.well_posed >= CASES * 9 / 10,
                    "{} {:?}: {} well-posed",
                    r.class,
                    r.precision,
                    r.well_posed
                );
            } else {
                assert_eq!(r.invalid.cases, CASES);
            }
        }
    }
}

#[test]
fn rows_ferrari() {
    check_method("ferrari");
}

#[test]
fn rows_yuksel() {
    check_method("yuksel");
}

#[test]
fn rows_newton_bbox() {
    check_method("newton_bbox");
}

#[test]
fn rows_robust() {
    check_method("robust");
    // The robust anchor: no wrong verdict anywhere, every invalid input rejected
    for report in [torus_report(), normal_report()] {
        for r in report.rows.iter().filter(|r| r.robust) {
            assert_eq!(
                r.wrong(),
                0,
                "{} {:?} {}",
                report.shape,
                r.precision,
                r.class
            );
            assert_eq!(r.invalid.rejected, r.invalid.cases);
        }
    }
}

#[test]
fn default_audit_passes_the_table() {
    for report in [torus_report(), normal_report()] {
        let breaks = report.failures();
        assert!(breaks.is_empty(), "{}", breaks.join("\n"));
    }
}

/// `cargo test --release --test integration torus::print_tables -- --nocapture` prints the measured tables.
#[test]
fn print_tables() {
    for report in [torus_report(), normal_report()] {
        println!("{}", table::shape_table(report));
        println!("{}", table::worst_cases(report, 1));
    }
}

// ---- the harness has teeth ----

#[test]
fn teeth_ferrari_f32_fails_where_robust_does_not() {
    let t = torus_report();
    for class in ["far", "thin"] {
        let f = row(t, "ferrari", Precision::F32, class);
        let r = row(t, "robust", Precision::F32, class);
        assert!(
            f.wrong_rate > 0.1 && f.false_hit > 0 && f.false_miss > 0,
            "{class}: ferrari f32 wrong rate {}",
            f.wrong_rate
        );
        assert_eq!(r.wrong(), 0);
        // Every failure is replayable
        let ex = f
            .examples
            .iter()
            .find(|e| e.kind == "false_miss")
            .expect("example");
        assert!(ex
            .probe
            .starts_with("rayproof probe torus --precision f32 -- "));
    }
    // Where Ferrari's verdicts are right, its roots are not: thousands of ulps against a few
    for class in ["generic", "hole", "fat"] {
        let f = row(t, "ferrari", Precision::F32, class);
        let r = row(t, "robust", Precision::F32, class);
        assert!(
            f.ulps.max > 1000.0 && r.ulps.max <= 8.0,
            "{class}: {} vs {}",
            f.ulps.max,
            r.ulps.max
        );
    }
    // And the normals from its hit points are off by far more than the robust method's
    let n = normal_report();
    let f = row(n, "ferrari", Precision::F32, "generic");
    let r = row(n, "robust", Precision::F32, "generic");
    assert!(f.ulps.max > 1000.0 * r.ulps.max.max(1.0));
}

#[test]
fn teeth_newton_from_the_box_finds_a_wrong_root_or_none() {
    let t = torus_report();
    for p in Precision::ALL {
        // From the box entry, Newton converges to a root that is not the first
        let g = row(t, "newton_bbox", p, "generic");
        assert!(g.wrong_root > 0, "{p:?}: no wrong root");
        // From inside the tube it starts at t = 0 and runs to a root behind the origin
        let i = row(t, "newton_bbox", p, "inside_tube");
        assert!(
            i.false_miss as f64 > 0.3 * i.well_posed as f64,
            "{p:?}: {}",
            i.false_miss
        );
        // Near a tangent it stalls at the quartic's minimum, or steps over it
        let z = row(t, "newton_bbox", p, "grazing");
        assert!(z.false_miss > 0 && z.wrong() > row(t, "robust", p, "grazing").wrong());
    }
}

#[test]
fn teeth_the_table_raises_an_alarm_when_a_known_failure_passes() {
    let table = Table::built_in();
    let mut r = row(torus_report(), "ferrari", Precision::F32, "far").clone();
    (r.false_hit, r.false_miss, r.wrong_root, r.nonfinite_t) = (0, 0, 0, 0);
    r.ulps.max = 0.0;
    let v = table.verdict("torus", &r, false, |_| 0);
    assert!(
        v.reasons.iter().any(|b| b.contains("known failure lost")),
        "{v:?}"
    );
    // And a robust row with one wrong verdict breaks the table
    let mut r = row(torus_report(), "robust", Precision::F64, "far").clone();
    r.false_miss = 1;
    let v = table.verdict("torus", &r, false, |_| 0);
    assert_eq!(v.status, rayproof::audit::tolerance::Status::Fail, "{v:?}");
}

// ---- the oracle on hand-made cases ----

fn truth(x: [f64; 8], p: Precision) -> rayproof::shapes::shape::Expected {
    match Torus.oracle(&x, p) {
        Truth::Answer(e) => e,
        Truth::Invalid => panic!("valid case judged invalid"),
    }
}

#[test]
fn oracle_axis_ray_crosses_four_times() {
    // r1 = 2, r2 = 1, from x = −10 along +x: the surface at x = −3, −1, 1, 3
    let e = truth([-10.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0], Precision::F64);
    assert_eq!(
        (e.count, e.values.clone(), e.others.clone()),
        (1, vec![7.0], vec![9.0, 11.0, 13.0])
    );
    assert!(!e.ill_posed && !e.cap_reached);
    // A direction of length 2 halves every t
    let e = truth([-10.0, 0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 1.0], Precision::F32);
    assert_eq!((e.values[0], e.others.clone()), (3.5, vec![4.5, 5.5, 6.5]));
    // From the centre of the hole: t = 1 and 3 ahead, the others behind
    let e = truth([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0], Precision::F64);
    assert_eq!((e.values.clone(), e.others.clone()), (vec![1.0], vec![3.0]));
}

#[test]
fn oracle_irrational_root_is_correctly_rounded() {
    // Along the diagonal from the centre: ρ = t·√2 = 1, t = 1/√2
    for p in Precision::ALL {
        let e = truth([0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 2.0, 1.0], p);
        let want = match p {
            Precision::F32 => 0.5f32.sqrt() as f64,
            Precision::F64 => 0.5f64.sqrt(),
        };
        assert_eq!(e.values, vec![want]);
    }
}

#[test]
fn oracle_misses_tangents_and_surface_origins() {
    // Down the axis through the hole: a miss, well-posed
    let e = truth([0.0, 0.0, 5.0, 0.0, 0.0, -1.0, 2.0, 1.0], Precision::F64);
    assert_eq!((e.count, e.ill_posed), (0, false));
    // Along the top of the tube (z = r2): double roots at x = ±2, t = 8 and 12; ill-posed
    let e = truth([-10.0, 0.0, 1.0, 1.0, 0.0, 0.0, 2.0, 1.0], Precision::F64);
    assert_eq!(
        (e.count, e.values.clone(), e.ill_posed),
        (1, vec![8.0], true)
    );
    // Origin on the outer equator, leaving: the root t = 0 does not count; ill-posed
    let e = truth([3.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0], Precision::F32);
    assert_eq!((e.count, e.ill_posed), (0, true));
    // Origin on the outer equator, entering: t = 2 (inner wall) is next after t = 0
    let e = truth([3.0, 0.0, 0.0, -1.0, 0.0, 0.0, 2.0, 1.0], Precision::F64);
    assert_eq!(
        (e.count, e.values.clone(), e.ill_posed),
        (1, vec![2.0], true)
    );
}

#[test]
fn oracle_rejects_invalid_shapes_and_rays() {
    let ok = [-10.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0];
    let broken = |i: usize, v: f64| {
        let mut x = ok;
        x[i] = v;
        x
    };
    let bad = [
        broken(0, f64::NAN),
        broken(4, f64::INFINITY),
        broken(7, 0.0),
        broken(7, -1.0),
        broken(6, -2.0),
        broken(7, 2.0), // r2 = r1: a horn torus
        broken(7, 3.0), // r2 > r1: a spindle torus
        [-10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 1.0],
    ];
    for x in bad {
        for shape in [&Torus as &dyn Shape, &TorusNormal] {
            assert_eq!(shape.oracle(&x, Precision::F64), Truth::Invalid, "{x:?}");
        }
    }
}

fn normal_truth(x: [f64; 8], p: Precision) -> rayproof::shapes::shape::Expected {
    match TorusNormal.oracle(&x, p) {
        Truth::Answer(e) => e,
        Truth::Invalid => panic!("valid case judged invalid"),
    }
}

#[test]
fn normal_oracle_on_known_points() {
    // Outer equator at (−3, 0, 0): normal −x
    let e = normal_truth([-10.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0], Precision::F32);
    assert_eq!((e.count, e.values.clone()), (1, vec![-1.0, 0.0, 0.0]));
    // Straight down onto the top of the tube at (2, 0, 1): normal +z (ρ = r1 exactly)
    let e = normal_truth([2.0, 0.0, 5.0, 0.0, 0.0, -1.0, 2.0, 1.0], Precision::F64);
    assert_eq!(e.values, vec![0.0, 0.0, 1.0]);
    // From the centre along the diagonal: the inner wall at ρ = 1, normal −(1, 1, 0)/√2
    let e = normal_truth([0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 2.0, 1.0], Precision::F64);
    let h = -(0.5f64.sqrt());
    assert_eq!(e.values, vec![h, h, 0.0]);
    // A 3-4-5 point: tube angle with cos = 3/5 on the outer half, at θ = 0
    // p = (2 + 3/5, 0, 4/5) for r2 = 1; reached from above along −z at x = 2.6
    let e = normal_truth([2.6, 0.0, 5.0, 0.0, 0.0, -1.0, 2.0, 1.0], Precision::F64);
    assert!(
        (e.values[0] - 0.6).abs() < 1e-15
            && e.values[1] == 0.0
            && (e.values[2] - 0.8).abs() < 1e-15
    );
    // A miss has no normal
    let e = normal_truth([0.0, 0.0, 5.0, 0.0, 0.0, -1.0, 2.0, 1.0], Precision::F64);
    assert_eq!(e.count, 0);
}

#[test]
fn a_wrong_answer_is_judged_wrong() {
    let x = [-10.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0];
    let t = Torus.oracle(&x, Precision::F32);
    let j = |a: Answer| judge(&t, &a, Torus.info(), Precision::F32);
    assert_eq!(j(Answer::hit(vec![7.0])), Judgement::Ok { ulps: Some(0) });
    assert_eq!(
        j(Answer::hit(vec![(7.0f32).next_up() as f64])),
        Judgement::Ok { ulps: Some(1) }
    );
    assert_eq!(j(Answer::hit(vec![9.0])), Judgement::WrongRoot);
    assert_eq!(j(Answer::miss()), Judgement::FalseMiss);
    assert_eq!(j(Answer::hit(vec![f64::NAN])), Judgement::NonfiniteT);
}

// ---- the public functions the renderer calls ----

#[test]
fn public_robust_and_normal() {
    let (o, d) = ([-10.0f32, 0.0, 0.0], [1.0f32, 0.0, 0.0]);
    assert_eq!(torus_robust(o, d, 2.0, 1.0), Some(7.0));
    let (t, p) = torus_robust_hit([-10.0f64, 0.0, 0.5], [1.0, 0.0, 0.0], 2.0, 1.0).expect("hit");
    assert!(t > 7.0 && t < 8.0);
    let n = torus_normal(p, 2.0, 1.0);
    // Outward and of length r2 on the surface
    assert!(n[0] < 0.0 && n[2] > 0.0);
    assert!(((n[0] * n[0] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-12);
    // Parallel to the chapter's gradient
    let g = methods::gradient(p, 2.0, 1.0);
    let cross = n[0] * g[2] - n[2] * g[0];
    assert!(cross.abs() < 1e-12 * (g[0].abs() + g[2].abs()));
    // Behind, missing, invalid
    assert_eq!(
        torus_robust([-10.0f64, 0.0, 0.0], [-1.0, 0.0, 0.0], 2.0, 1.0),
        None
    );
    assert_eq!(
        torus_robust([-10.0f64, 0.0, 5.0], [1.0, 0.0, 0.0], 2.0, 1.0),
        None
    );
    assert_eq!(
        torus_robust([-10.0f64, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0, 2.0),
        None
    );
    assert_eq!(
        torus_robust([f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], 2.0, 1.0),
        None
    );
}

// ---- reintersection ----

/// `ERR_GAMMA` is measured: the robust hit point's exact distance to the surface, over every
/// valid class, stays below half of `γ(K)·(r1 + r2)`.
#[test]
fn reintersection_error_bound_is_measured() {
    for p in Precision::ALL {
        let mut worst = 0f64;
        for class in 0..cases::CLASSES.len() - 1 {
            for i in 0..200 {
                let x = rayproof::audit::run::generate(&Torus, 2, class, p, i).expect("case");
                let ratio = match p {
                    Precision::F32 => sdf_ratio::<f32>(&x),
                    Precision::F64 => sdf_ratio::<f64>(&x),
                };
                worst = worst.max(ratio);
            }
        }
        println!("{p:?}: max |sdf(p)| = {worst:.2} u·(r1 + r2)");
        assert!(2.0 * worst <= ERR_GAMMA as f64, "{p:?}: {worst}");
    }
}

/// `|sdf(p)| / (u·(r1 + r2))` at the robust hit point (256-bit evaluation), `u = 2^−p`.
fn sdf_ratio<F: rayproof::numerics::real::Real>(x: &[f64]) -> f64 {
    let f = |i: usize| F::from_f64(x[i]);
    let Some((_, p)) = torus_robust_hit([f(0), f(1), f(2)], [f(3), f(4), f(5)], f(6), f(7)) else {
        return 0.0;
    };
    let b = 256;
    let v = |y: F| Float::with_val(b, y.to_f64());
    let rho = (v(p[0]).square() + v(p[1]).square()).sqrt();
    let u = rho - x[6];
    let dist = (u.square() + v(p[2]).square()).sqrt() - x[7];
    let unit = 2f64.powi(-(F::MANT_BITS as i32)) * (x[6] + x[7]);
    dist.to_f64().abs() / unit
}

// ---- invalid inputs never panic ----

#[test]
fn special_values_never_panic_and_robust_rejects_invalid() {
    let base = [-3.0, 0.5, 0.25, 1.0, -0.125, 0.0625, 2.0, 0.75];
    let specials = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        0.0,
        -0.0,
        f64::MIN_POSITIVE / 8.0,
        f64::MAX,
        -f64::MAX,
        1e30,
    ];
    for p in Precision::ALL {
        for i in 0..8 {
            for s in specials {
                let mut x = base;
                x[i] = cases::round_to(s, p);
                for shape in [&Torus as &dyn Shape, &TorusNormal] {
                    let truth = shape.oracle(&x, p);
                    for (m, info) in METHODS.iter().enumerate() {
                        let a = shape.run(m, &x, p);
                        if info.robust {
                            let j = judge(&truth, &a, shape.info(), p);
                            assert!(!j.is_wrong(), "{} {i} {s} {p:?}: {j:?}", shape.name());
                            if truth == Truth::Invalid {
                                assert_eq!(a.count, 0);
                            }
                        }
                    }
                }
            }
        }
    }
    // Every invalid-class case is rejected by the robust method
    for r in torus_report().rows.iter().filter(|r| r.class == "invalid") {
        assert_eq!(r.invalid.cases, CASES);
        if r.robust {
            assert_eq!(r.invalid.rejected, CASES);
        }
    }
}

// ---- proptest stability suites ----

fn any_input(p: Precision) -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(any::<u64>(), 8).prop_map(move |bits| {
        bits.into_iter()
            .map(|b| match p {
                Precision::F32 => f32::from_bits(b as u32) as f64,
                Precision::F64 => f64::from_bits(b),
            })
            .collect()
    })
}

fn class_input(class: usize, p: Precision) -> impl Strategy<Value = Vec<f64>> {
    any::<u64>().prop_filter_map("generator", move |seed| {
        rayproof::audit::run::generate(&Torus, seed, class, p, 0)
    })
}

/// Whether an error of `u` ulps on a case of sensitivity `cond` is within the robust rule of
/// `class` (its ulp bound or its err/cond bound; it must have one).
fn within_robust_rule(
    shape: &dyn Shape,
    p: Precision,
    class: usize,
    u: u64,
    cond: Option<f64>,
) -> bool {
    let m = METHODS.iter().find(|m| m.robust).expect("robust");
    let info = shape.info();
    let table = Table::built_in();
    let r = table
        .rule(info.name, m.name, p, info.classes[class])
        .expect("the robust rows have a rule");
    assert!(
        r.max_ulps.is_some() || r.max_err_over_cond.is_some(),
        "the robust rows hold a bound"
    );
    r.max_ulps.is_none_or(|b| u <= b)
        && r.max_err_over_cond
            .is_none_or(|b| cond.is_none() || u as f64 / cond.unwrap_or(1.0).max(1.0) <= b)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(64), failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary bit patterns: no method panics; the robust method answers a finite `t > 0` or
    /// nothing, and nothing on invalid input.
    #[test]
    fn arbitrary_bits_never_panic(x32 in any_input(Precision::F32), x64 in any_input(Precision::F64)) {
        for (x, p) in [(x32, Precision::F32), (x64, Precision::F64)] {
            for (m, info) in METHODS.iter().enumerate() {
                let _ = TorusNormal.run(m, &x, p);
                let a = Torus.run(m, &x, p);
                if info.robust && a.count > 0 {
                    prop_assert!(oracle::valid_f64(&x));
                    prop_assert!(a.values[0].is_finite() && a.values[0] > 0.0);
                }
            }
        }
    }

    /// Mirroring the scene in z (or x) leaves every rounding the same: the robust `t` is
    /// bit-identical.
    #[test]
    fn mirror_symmetry(x in class_input(0, Precision::F64), y in class_input(4, Precision::F32)) {
        for (x, p) in [(x, Precision::F64), (y, Precision::F32)] {
            let t = Torus.run(3, &x, p);
            for axis in [0usize, 2] {
                let mut z = x.clone();
                z[axis] = -z[axis];
                z[3 + axis] = -z[3 + axis];
                prop_assert_eq!(Torus.run(3, &z, p), t.clone());
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, rng_seed: proptest::test_runner::RngSeed::Fixed(12), failure_persistence: None, ..ProptestConfig::default() })]

    /// Fresh cases of every valid class: the robust method's verdict is right on well-posed
    /// cases, its `t` and normal within the table's bounds.
    #[test]
    fn robust_is_stable_on_fresh_cases(seed in any::<u64>()) {
        for class in 0..cases::CLASSES.len() - 1 {
            for p in Precision::ALL {
                let x = rayproof::audit::run::generate(&Torus, seed, class, p, 0).expect("case");
                for shape in [&Torus as &dyn Shape, &TorusNormal] {
                    let truth = shape.oracle(&x, p);
                    let Truth::Answer(e) = &truth else { prop_assert!(false, "invalid"); unreachable!() };
                    if e.ill_posed {
                        continue;
                    }
                    let j = judge(&truth, &shape.run(3, &x, p), shape.info(), p);
                    let probe = rayproof::shapes::shape::probe_line(shape.name(), p, &x);
                    prop_assert!(!j.is_wrong(), "{:?}: {}", j, probe);
                    if let Judgement::Ok { ulps: Some(u) } = j {
                        prop_assert!(within_robust_rule(shape, p, class, u, e.cond), "{} ulps (cond {:?}): {}", u, e.cond, probe);
                    }
                }
            }
        }
    }
}

// ---- exact helpers ----

#[test]
fn encloser_narrows_to_the_root() {
    // t² − 2 on (1, 2]: √2
    let p = vec![Rational::from(-2), Rational::new(), Rational::from(1)];
    let mut e = oracle::Encloser::new(p, Rational::from(1), Rational::from(2));
    e.narrow(100);
    let w = Rational::from(&e.hi - &e.lo);
    assert!(w <= Rational::from((1, 1u64 << 50)) / Rational::from(1u64 << 49));
    let two = Rational::from(2);
    assert!(Rational::from(e.lo.square_ref()) < two && two < Rational::from(e.hi.square_ref()));
}
