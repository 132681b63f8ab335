//! Ray–sphere: oracle checks on hand-derived cases, one test per method × precision × class
//! against the tolerance table, the harness's teeth, and proptest stability suites.

use proptest::prelude::*;
use rayproof::audit::sphere_run::{self as audit, AuditOptions, Report, Row};
use rayproof::numerics::real::Real;
use rayproof::numerics::Precision;
use rayproof::shapes::sphere::cases::{self, Class};
use rayproof::shapes::sphere::methods::{PickPrecision, METHODS};
use rayproof::shapes::sphere::oracle::{self, Case, Verdict};
use rayproof::shapes::sphere::{judge, run_case, tolerance, Judgement};
use std::sync::OnceLock;

// ---- the default audit, run once for every row test ----

/// The audit the table was measured on: seed 1, 20,000 cases per class, all methods.
fn default_report() -> &'static Report {
    static REPORT: OnceLock<Report> = OnceLock::new();
    REPORT.get_or_init(|| {
        audit::run(&AuditOptions {
            cases: 20_000,
            seed: 1,
            methods: METHODS.iter().collect(),
            precisions: Precision::ALL.to_vec(),
            classes: Class::ALL.to_vec(),
            shard: (0, 1),
            progress: false,
        })
    })
}

fn row(method: &str, precision: Precision, class: Class) -> &'static Row {
    default_report()
        .rows
        .iter()
        .find(|r| r.method == method && r.precision == precision && r.class == class)
        .expect("row present")
}

/// Checks one row against its tolerance-table entry, and that the oracle behaved.
fn check_row(method: &str, precision: Precision, class: Class) {
    let r = row(method, precision, class);
    let single = Report {
        rows: vec![r.clone()],
        ..default_report().clone()
    };
    let breaks = tolerance::check(&single);
    assert!(breaks.is_empty(), "{}", breaks.join("\n"));
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
        r.err_over_cond.max > 100.0,
        "err/cond {}",
        r.err_over_cond.max
    );
    let robust = row("rtg7", Precision::F32, Class::FarSmall);
    assert!(robust.err_over_cond.max < 8.0);
    // Every failure is replayable
    let ex = r
        .examples
        .iter()
        .find(|e| e.kind == "false_miss")
        .expect("an example");
    assert!(
        ex.probe.starts_with("rayproof probe sphere --origin 0x")
            || ex.probe.contains("--origin -0x")
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
    let mut r = row("algebraic", Precision::F32, Class::FarSmall).clone();
    (r.false_hit, r.false_miss, r.wrong_root, r.nonfinite_t) = (0, 0, 0, 0);
    let report = Report {
        rows: vec![r],
        ..default_report().clone()
    };
    let breaks = tolerance::check(&report);
    assert!(
        breaks.iter().any(|b| b.contains("harness broken")),
        "{breaks:?}"
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
    let t = oracle::truth(&case);
    let hit = |t: f32| Some(rayproof::shapes::sphere::methods::SphereHit { t, enclosure: None });
    assert_eq!(judge::<f32>(&t, hit(4.0)), Judgement::Ok { ulps: Some(0) });
    assert_eq!(
        judge::<f32>(&t, hit(4.0f32.next_up())),
        Judgement::Ok { ulps: Some(1) }
    );
    assert_eq!(judge::<f32>(&t, hit(6.0)), Judgement::WrongRoot);
    assert_eq!(judge::<f32>(&t, None), Judgement::FalseMiss);
    assert_eq!(judge::<f32>(&t, hit(f32::NAN)), Judgement::NonfiniteT);
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
fn assert_strict_rows<F: PickPrecision>(
    case: &Case<F>,
    class: Class,
    precision: Precision,
) -> Result<(), TestCaseError> {
    let methods: Vec<_> = METHODS.iter().collect();
    let (truth, rows) = run_case(case, &methods);
    if truth.ill_posed {
        return Ok(());
    }
    let cond = oracle::condition_ulps(case, &truth);
    for (name, _, j) in rows {
        let e = tolerance::entry(name, precision, class);
        if e.max_wrong_rate != Some(0.0) {
            continue;
        }
        prop_assert!(
            !j.is_wrong(),
            "{name} {:?}: {:?}\n  rayproof probe sphere {}",
            precision,
            j,
            case.probe_args()
        );
        if let Judgement::Ok { ulps: Some(u) } = j {
            if let Some(max) = e.max_ulps {
                prop_assert!(
                    u <= max,
                    "{name}: {u} ulps > {max}\n  rayproof probe sphere {}",
                    case.probe_args()
                );
            }
            if let (Some(max), Some(c)) = (e.max_err_over_cond, cond) {
                let rel = u as f64 / c.max(1.0);
                prop_assert!(
                    rel <= max,
                    "{name}: err/cond {rel} > {max}\n  rayproof probe sphere {}",
                    case.probe_args()
                );
            }
        }
    }
    Ok(())
}

macro_rules! stability {
    ($($name:ident => $class:ident),*) => {
        $(
            proptest! {
                #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]
                #[test]
                fn $name(c32 in class_case::<f32>(Class::$class), c64 in class_case::<f64>(Class::$class)) {
                    assert_strict_rows(&c32, Class::$class, Precision::F32)?;
                    assert_strict_rows(&c64, Class::$class, Precision::F64)?;
                }
            }
        )*
    };
}
stability!(stable_inside => Inside, stable_on_surface => OnSurface, stable_tangent => Tangent,
    stable_behind => Behind, stable_far_small => FarSmall, stable_huge => Huge,
    stable_grazing => Grazing, stable_random => Random, stable_invalid => Invalid);

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, failure_persistence: None, ..ProptestConfig::default() })]
    /// Any bit patterns at all: no method, and not the oracle, panics; robust methods never
    /// answer an invalid input with a hit.
    #[test]
    fn arbitrary_bits_never_panic(b32 in prop::array::uniform10(any::<u32>()), b64 in prop::array::uniform10(any::<u64>())) {
        let c32 = Case::<f32>::from_scalars(b32.map(f32::from_bits));
        let c64 = Case::<f64>::from_scalars(b64.map(f64::from_bits));
        let methods: Vec<_> = METHODS.iter().collect();
        for (name, _, j) in run_case(&c32, &methods).1 {
            let robust = rayproof::shapes::sphere::methods::method_by_name(name).unwrap().robust;
            prop_assert!(!(robust && matches!(j, Judgement::InvalidHit | Judgement::InvalidNanT)), "{name} f32 {j:?}");
        }
        for (name, _, j) in run_case(&c64, &methods).1 {
            let robust = rayproof::shapes::sphere::methods::method_by_name(name).unwrap().robust;
            prop_assert!(!(robust && matches!(j, Judgement::InvalidHit | Judgement::InvalidNanT)), "{name} f64 {j:?}");
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
    let methods: Vec<_> = METHODS.iter().filter(|m| m.robust).collect();
    for v in variants {
        for (name, hit, j) in run_case(&v, &methods).1 {
            assert_eq!(
                j,
                Judgement::Rejected,
                "{name} on {}: {hit:?}",
                v.probe_args()
            );
        }
    }
}
