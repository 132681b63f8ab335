//! Ray–sphere: oracle checks on hand-derived cases, one test per method × precision × class
//! against the tolerance table, the harness's teeth, and proptest stability suites.

use proptest::prelude::*;
use rayproof::audit::plan::Options;
use rayproof::audit::run::judge_all;
use rayproof::audit::tally::Sample;
use rayproof::audit::tolerance::{Status, Table, Wrong};
use rayproof::audit::{
    audit_shape, judge, Answer, Builtin, Judgement, Method, Row, Shape, ShapeReport, Truth,
};
use rayproof::numerics::real::Real;
use rayproof::numerics::Precision;
use rayproof::shapes::sphere::cases::{self, Class};
use rayproof::shapes::sphere::methods::METHODS;
use rayproof::shapes::sphere::oracle::{self, Case, Verdict};
use rayproof::shapes::sphere::SphereShape;
use std::sync::OnceLock;

/// The precision of `F`.
fn precision<F: Real>() -> Precision {
    if F::MANT_BITS == 24 {
        Precision::F32
    } else {
        Precision::F64
    }
}

/// The case as the audit's flat input.
fn input<F: Real>(c: &Case<F>) -> Vec<f64> {
    c.scalars().iter().map(|x| x.to_f64()).collect()
}

/// The oracle and every built-in method (or only the robust ones) on one case, as the audit
/// judges them: `(truth, [(method, sample)])`.
fn run_case<F: Real>(c: &Case<F>, robust_only: bool) -> (Truth, Vec<(&'static str, Sample)>) {
    let all = Builtin::all(&SphereShape);
    let chosen: Vec<&Builtin> = all.iter().filter(|m| !robust_only || m.robust()).collect();
    let methods: Vec<&dyn Method> = chosen.iter().map(|m| *m as &dyn Method).collect();
    let (truth, samples) = judge_all(&SphereShape, &methods, &input(c), precision::<F>())
        .expect("built-in methods do not fail");
    let names = chosen.iter().map(|m| METHODS[m.index].name);
    (truth, names.zip(samples).collect())
}

// ---- the default audit, run once for every row test ----

/// The audit the table was measured on: seed 1, 20,000 cases per class, all methods.
fn default_report() -> &'static ShapeReport {
    static REPORT: OnceLock<ShapeReport> = OnceLock::new();
    REPORT.get_or_init(|| {
        audit_shape(
            &SphereShape,
            &Options {
                cases: Some(20_000),
                ..Default::default()
            },
        )
        .expect("a valid selection")
    })
}

fn row(method: &str, precision: Precision, class: Class) -> &'static Row {
    default_report()
        .rows
        .iter()
        .find(|r| r.method == method && r.precision == precision && r.class == class.name())
        .expect("row present")
}

/// Checks one row against its tolerance-table entry, and that the oracle behaved.
fn check_row(method: &str, precision: Precision, class: Class) {
    let r = row(method, precision, class);
    let v = r.verdict.as_ref().expect("judged");
    assert!(v.status != Status::Fail, "{}", v.reasons.join("\n"));
    assert_eq!(
        r.generator_failures, 0,
        "generator could not fill the class"
    );
    assert_eq!(r.cap_reached, 0, "oracle hit its precision cap");
    assert!(r.cases == 20_000, "every case generated");
    if class != Class::Invalid {
        assert!(
            r.well_posed > 5_000,
            "class {class:?} is mostly ill-posed: {} well-posed",
            r.well_posed
        );
    }
}

/// One test per class for a method, both precisions (named `<method>::<class>`).
macro_rules! class_tests {
    ($method:ident: $($class:ident => $variant:ident),*) => {
        mod $method {
            use super::*;
            $(
                #[test]
                fn $class() {
                    check_row(stringify!($method), Precision::F32, Class::$variant);
                    check_row(stringify!($method), Precision::F64, Class::$variant);
                }
            )*
        }
    };
}

macro_rules! row_tests {
    ($($method:ident),*) => {
        $(class_tests!($method: inside => Inside, on_surface => OnSurface, tangent => Tangent, behind => Behind,
            far_small => FarSmall, huge => Huge, grazing => Grazing, random => Random, invalid => Invalid);)*
    };
}
row_tests!(
    algebraic,
    geometric,
    press,
    hearn_baker,
    rtg7,
    promote,
    interval
);

#[test]
fn every_method_has_rows_in_every_class() {
    for m in METHODS {
        for p in Precision::ALL {
            for c in Class::ALL {
                assert!(row(m.name, p, c).cases > 0);
            }
        }
    }
}

// ---- the harness has teeth ----

#[test]
fn teeth_algebraic_f32_fails_on_far_small() {
    let r = row("algebraic", Precision::F32, Class::FarSmall);
    assert!(
        r.wrong_rate > 0.1,
        "expected the textbook discriminant to fail: rate {}",
        r.wrong_rate
    );
    assert!(r.false_hit > 0 && r.false_miss > 0);
    // ... and the harness blames the method, not the case: error ≫ the case's sensitivity
    assert!(
        r.err_over_cond.as_ref().unwrap().max > 100.0,
        "err/cond {:?}",
        r.err_over_cond
    );
    let robust = row("rtg7", Precision::F32, Class::FarSmall);
    assert!(robust.err_over_cond.as_ref().unwrap().max < 8.0);
    // Every failure is replayable
    let ex = r
        .examples
        .iter()
        .find(|e| e.kind == "false_miss")
        .expect("an example");
    assert!(
        ex.probe
            .starts_with("rayproof probe sphere --precision f32 -- ")
            && ex.probe.split_whitespace().count() == 16,
        "{}",
        ex.probe
    );
}

#[test]
fn teeth_algebraic_f32_fails_on_huge() {
    let r = row("algebraic", Precision::F32, Class::Huge);
    assert!(r.wrong() > 0, "expected wrong roots on a huge floor sphere");
    assert!(r.wrong_root > 0);
    assert!(
        r.ulps.max > 1e6,
        "expected a near root off by most of its value, got {} ulps",
        r.ulps.max
    );
    // promote gets every one of them right
    let p = row("promote", Precision::F32, Class::Huge);
    assert_eq!(p.wrong(), 0);
    assert!(p.ulps.max <= 1.0);
}

#[test]
fn teeth_seed_methods_fail_near_tangents_in_both_precisions() {
    for m in ["algebraic", "geometric", "press"] {
        for p in Precision::ALL {
            assert!(row(m, p, Class::Tangent).wrong_rate > 0.05, "{m} {p:?}");
        }
    }
}

#[test]
fn teeth_the_table_raises_an_alarm_when_a_known_failure_passes() {
    let mut r: Row = row("algebraic", Precision::F32, Class::FarSmall).clone();
    (r.false_hit, r.false_miss, r.wrong_root, r.nonfinite_t) = (0, 0, 0, 0);
    let v = Table::built_in().verdict("sphere", &r, false, |_| 0);
    assert_eq!(v.status, Status::Fail);
    assert!(
        v.reasons.iter().any(|b| b.contains("harness broken")),
        "{v:?}"
    );
}

#[test]
fn teeth_a_wrong_answer_is_judged_wrong() {
    // Unit sphere, ray from z = −5: exact t = 4
    let case = Case::<f32> {
        o: [0.0, 0.0, -5.0],
        d: [0.0, 0.0, 1.0],
        c: [0.0; 3],
        r: 1.0,
    };
    let (f32_, info) = (Precision::F32, SphereShape.info());
    let t = SphereShape.oracle(&input(&case), f32_);
    let hit = |t: f32| Answer::hit(vec![t as f64]);
    assert_eq!(
        judge(&t, &hit(4.0), info, f32_),
        Judgement::Ok { ulps: Some(0) }
    );
    assert_eq!(
        judge(&t, &hit(4.0f32.next_up()), info, f32_),
        Judgement::Ok { ulps: Some(1) }
    );
    assert_eq!(judge(&t, &hit(6.0), info, f32_), Judgement::WrongRoot);
    assert_eq!(judge(&t, &Answer::miss(), info, f32_), Judgement::FalseMiss);
    assert_eq!(judge(&t, &hit(f32::NAN), info, f32_), Judgement::NonfiniteT);
}

// ---- oracle on hand-derived cases ----

#[test]
fn oracle_exact_on_surface_and_tangent_cases() {
    // (2,3,6) has length 7: the origin lies exactly on the sphere of radius 7
    let on = Case::<f64> {
        o: [2.0, 3.0, 6.0],
        d: [-2.0, -3.0, -6.0],
        c: [0.0; 3],
        r: 7.0,
    };
    let t = oracle::truth(&on);
    assert_eq!(
        (t.verdict, t.t_f64, t.ill_posed),
        (Verdict::Far, Some(2.0), true)
    );
    // Pointing outward from the surface: a miss (t = 0 is not a hit)
    let out = Case::<f64> {
        d: [2.0, 3.0, 6.0],
        ..on
    };
    assert_eq!(oracle::truth(&out).verdict, Verdict::Miss);
    // Exact tangent of the sphere r = 5 at (3,4,0), ray along z
    let tan = Case::<f32> {
        o: [3.0, 4.0, -10.0],
        d: [0.0, 0.0, 1.0],
        c: [0.0; 3],
        r: 5.0,
    };
    let t = oracle::truth(&tan);
    assert_eq!(
        (t.verdict, t.t_f32, t.ill_posed),
        (Verdict::Near, Some(10.0), true)
    );
    // Roots as 45-digit decimals: 1/3 and 5/9 for o = (0,0,−4), d = (0,0,9), r = 1
    let third = Case::<f64> {
        o: [0.0, 0.0, -4.0],
        d: [0.0, 0.0, 9.0],
        c: [0.0; 3],
        r: 1.0,
    };
    let roots = oracle::roots_decimal(&third, 45);
    assert!(
        roots[0].starts_with("3.33333333333333333333333333333333333333333333"),
        "{}",
        roots[0]
    );
    assert_eq!(
        roots[1],
        "5.55555555555555555555555555555555555555555556e-1"
    );
}

#[test]
fn oracle_confirms_every_class_membership() {
    for class in Class::ALL {
        for i in 0..200 {
            if let Some(c) = cases::generate::<f32>(3, class, i) {
                assert!(
                    cases::is_member(&c, class),
                    "{class:?} case {i} is not a member"
                );
            }
        }
    }
}

#[test]
fn cases_are_reproducible_alone() {
    for class in Class::ALL {
        let a = cases::generate::<f64>(9, class, 1234);
        let b = cases::generate::<f64>(9, class, 1234);
        assert_eq!(a, b);
    }
}

// ---- proptest stability suites ----

/// A case of `class` drawn from proptest's seed: the class generator, confirmed by the oracle.
fn class_case<F: Real>(class: Class) -> impl Strategy<Value = Case<F>> {
    any::<u64>().prop_filter_map("no class member", move |seed| {
        cases::generate::<F>(seed, class, 0)
    })
}

/// Every method whose table entry is strict gives the right verdict, within its bounds.
fn assert_strict_rows<F: Real>(case: &Case<F>, class: Class) -> Result<(), TestCaseError> {
    let precision = precision::<F>();
    let (truth, rows) = run_case(case, false);
    let Truth::Answer(e) = &truth else {
        return Ok(());
    };
    if e.ill_posed {
        return Ok(());
    }
    let probe = rayproof::audit::probe_line("sphere", precision, &input(case));
    let table = Table::built_in();
    for (name, s) in rows {
        let Some(rule) = table.rule("sphere", name, precision, class.name()) else {
            continue;
        };
        if rule.wrong != Some(Wrong::None) {
            continue;
        }
        let j = s.judgement;
        prop_assert!(!j.is_wrong(), "{name} {precision:?}: {j:?}\n  {probe}");
        if let Judgement::Ok { ulps: Some(u) } = j {
            if let Some(max) = rule.max_ulps {
                prop_assert!(u <= max, "{name}: {u} ulps > {max}\n  {probe}");
            }
            if let (Some(max), Some(c)) = (rule.max_err_over_cond, e.cond) {
                let rel = u as f64 / c.max(1.0);
                prop_assert!(rel <= max, "{name}: err/cond {rel} > {max}\n  {probe}");
            }
        }
    }
    Ok(())
}

macro_rules! stability {
    ($($name:ident => $class:ident),*) => {
        $(
            proptest! {
                #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(256), failure_persistence: None, ..ProptestConfig::default() })]
                #[test]
                fn $name(c32 in class_case::<f32>(Class::$class), c64 in class_case::<f64>(Class::$class)) {
                    assert_strict_rows(&c32, Class::$class)?;
                    assert_strict_rows(&c64, Class::$class)?;
                }
            }
        )*
    };
}
stability!(stable_inside => Inside, stable_on_surface => OnSurface, stable_tangent => Tangent,
    stable_behind => Behind, stable_far_small => FarSmall, stable_huge => Huge,
    stable_grazing => Grazing, stable_random => Random, stable_invalid => Invalid);

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, rng_seed: proptest::test_runner::RngSeed::Fixed(2000), failure_persistence: None, ..ProptestConfig::default() })]
    /// Any bit patterns at all: no method, and not the oracle, panics; robust methods never
    /// answer an invalid input with a hit.
    #[test]
    fn arbitrary_bits_never_panic(b32 in prop::array::uniform10(any::<u32>()), b64 in prop::array::uniform10(any::<u64>())) {
        let c32 = Case::<f32>::from_scalars(b32.map(f32::from_bits));
        let c64 = Case::<f64>::from_scalars(b64.map(f64::from_bits));
        for (name, s) in run_case(&c32, true).1.into_iter().chain(run_case(&c64, true).1) {
            let j = s.judgement;
            prop_assert!(!matches!(j, Judgement::InvalidHit | Judgement::InvalidNanT), "{name} {j:?}");
        }
    }
}

#[test]
fn named_invalid_inputs_are_rejected_by_robust_methods() {
    let base = Case::<f64> {
        o: [0.0, 0.0, -5.0],
        d: [0.0, 0.0, 1.0],
        c: [0.0; 3],
        r: 1.0,
    };
    let variants = [
        Case {
            o: [f64::NAN, 0.0, -5.0],
            ..base
        },
        Case {
            o: [0.0, 0.0, f64::NEG_INFINITY],
            ..base
        },
        Case {
            d: [0.0; 3],
            ..base
        },
        Case {
            d: [f64::INFINITY, 0.0, 1.0],
            ..base
        },
        Case { r: 0.0, ..base },
        Case { r: -1.0, ..base },
        Case {
            r: f64::NAN,
            ..base
        },
        Case {
            c: [0.0, f64::NAN, 0.0],
            ..base
        },
    ];
    for v in variants {
        for (name, s) in run_case(&v, true).1 {
            assert_eq!(
                s.judgement,
                Judgement::Rejected,
                "{name} on {}: {:?}",
                v.probe_args(),
                s.values
            );
        }
    }
}
