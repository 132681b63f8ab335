//! Ray–box, ray–ellipsoid, ray–cylinder and ellipsoid normals (seed 002 §2.2–2.4, §3): oracle
//! checks on hand-made cases, every method × precision × class audited and held to the
//! tolerance table, the harness's teeth, proptest stability suites and invalid inputs
//! (reintersection: `tests/reintersect.rs`).

use proptest::prelude::*;
use rayproof::audit::plan::Options;
use rayproof::audit::{audit_shape, table, Row, ShapeReport};
use rayproof::audit::{Answer, Shape, Truth};
use rayproof::numerics::exact;
use rayproof::numerics::Precision;
use rayproof::shapes::{aabb, quadric};
use rug::{Float, Rational};
use std::sync::OnceLock;

/// Cases per class of the audits below (small: the suite runs in seconds).
const CASES: u64 = 300;

fn audit_of(shape: &dyn Shape) -> ShapeReport {
    audit_shape(
        shape,
        &Options {
            cases: Some(CASES),
            seed: 1,
            precisions: Precision::ALL.to_vec(),
            methods: vec![],
            classes: vec![],
            ..Default::default()
        },
    )
    .expect("selection is valid")
}

macro_rules! report_fn {
    ($name:ident, $shape:expr) => {
        fn $name() -> &'static ShapeReport {
            static R: OnceLock<ShapeReport> = OnceLock::new();
            R.get_or_init(|| audit_of(&$shape))
        }
    };
}
report_fn!(box_report, aabb::BoxShape);
report_fn!(ellipsoid_report, quadric::ELLIPSOID);
report_fn!(cylinder_report, quadric::CYLINDER);
report_fn!(normal_report, quadric::EllipsoidNormalShape);

fn row<'a>(r: &'a ShapeReport, method: &str, prec: Precision, class: &str) -> &'a Row {
    r.rows
        .iter()
        .find(|x| x.method == method && x.precision == prec && x.class == class)
        .expect("row present")
}

// ---- oracle checks on hand-made cases ----

fn truth(shape: &dyn Shape, v: &[f64], prec: Precision) -> (u32, Vec<f64>, bool) {
    match shape.oracle(v, prec) {
        Truth::Answer(e) => (e.count, e.values, e.ill_posed),
        Truth::Invalid => panic!("valid input judged invalid: {v:?}"),
    }
}

#[test]
fn box_oracle_hand_cases() {
    let b = &aabb::BoxShape;
    let unit = |o: [f64; 3], d: [f64; 3]| [&o[..], &d[..], &[0.0; 3], &[1.0; 3]].concat();
    // Entry through x = 0 at t = 1 (exit at 2 is the other candidate)
    let (c, v, ill) = truth(b, &unit([-1.0, 0.5, 0.5], [1.0, 0.0, 0.0]), Precision::F64);
    assert_eq!((c, v, ill), (1, vec![1.0], false));
    // Inside: the exit
    assert_eq!(
        truth(b, &unit([0.5; 3], [1.0, 0.0, 0.0]), Precision::F32).1,
        vec![0.5]
    );
    // On a face going in: the exit, ill-posed (one ulp out makes it an entry)
    let (c, v, ill) = truth(b, &unit([0.0, 0.5, 0.5], [1.0, 0.0, 0.0]), Precision::F64);
    assert_eq!((c, v, ill), (1, vec![1.0], true));
    // On a face going out: a miss
    assert_eq!(
        truth(b, &unit([0.0, 0.5, 0.5], [-1.0, 0.0, 0.0]), Precision::F64).0,
        0
    );
    // t = 1/3 rounded correctly in both precisions
    let v = unit([-1.0, 0.5, 0.5], [3.0, 0.0, 0.0]);
    assert_eq!(truth(b, &v, Precision::F64).1, vec![1.0 / 3.0]);
    assert_eq!(truth(b, &v, Precision::F32).1, vec![(1.0f32 / 3.0) as f64]);
    // Zero direction component, origin exactly on the slab plane and outside in y: a miss
    let v = unit([0.0, 2.0, -1.0], [0.0, 0.0, 1.0]);
    assert_eq!(truth(b, &v, Precision::F64).0, 0);
    // Invalid: NaN, inverted box, flat box, zero direction
    for v in [
        unit([f64::NAN, 0.5, 0.5], [1.0, 0.0, 0.0]),
        [
            &[-1.0, 0.5, 0.5][..],
            &[1.0, 0.0, 0.0],
            &[1.0; 3],
            &[0.0; 3],
        ]
        .concat(),
        [
            &[-1.0, 0.5, 0.5][..],
            &[1.0, 0.0, 0.0],
            &[0.0; 3],
            &[1.0, 0.0, 1.0],
        ]
        .concat(),
        unit([-1.0, 0.5, 0.5], [0.0, -0.0, 0.0]),
    ] {
        assert_eq!(b.oracle(&v, Precision::F64), Truth::Invalid, "{v:?}");
    }
}

/// `a − √b` correctly rounded to `f64`, from MPFR at 256 bits.
fn minus_sqrt(a: f64, b: f64) -> f64 {
    let s = Float::with_val(256, b).sqrt();
    (Float::with_val(256, a) - s).to_f64()
}

#[test]
fn ellipsoid_oracle_hand_cases() {
    let e = &quadric::ELLIPSOID;
    let case = |o: [f64; 3], d: [f64; 3], p: [f64; 3]| [&o[..], &d[..], &p[..]].concat();
    // x² + 4y² + z² = 4 (r = 2, m = 2, n = 1): along y from −5 hits y = −1 at t = 4
    let v = case([0.0, -5.0, 0.0], [0.0, 1.0, 0.0], [2.0, 2.0, 1.0]);
    assert_eq!(truth(e, &v, Precision::F64), (1, vec![4.0], false));
    // Along x hits x = −2 at t = 3; with d = (2,0,0) at t = 1.5
    let v = case([-5.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 1.0]);
    assert_eq!(truth(e, &v, Precision::F32).1, vec![1.5]);
    // From the centre: the far root, z = 2 at t = 2
    let v = case([0.0; 3], [0.0, 0.0, 1.0], [2.0, 2.0, 1.0]);
    assert_eq!(truth(e, &v, Precision::F64).1, vec![2.0]);
    // Exactly tangent at (2, 0, 0): a hit at t = 5, ill-posed
    let v = case([2.0, 0.0, -5.0], [0.0, 0.0, 1.0], [2.0, 2.0, 1.0]);
    assert_eq!(truth(e, &v, Precision::F64), (1, vec![5.0], true));
    // Behind: a miss
    let v = case([0.0, 0.0, 5.0], [0.0, 0.0, 1.0], [2.0, 2.0, 1.0]);
    assert_eq!(truth(e, &v, Precision::F64).0, 0);
    // Irrational root: unit sphere, x = −√0.75 at t = 5 − √0.75
    let v = case([-5.0, 0.5, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    assert_eq!(truth(e, &v, Precision::F64).1, vec![minus_sqrt(5.0, 0.75)]);
    // Invalid: r, m, n not > 0; inf; d = 0
    for p in [[0.0, 1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, f64::NAN]] {
        let v = case([-5.0, 0.0, 0.0], [1.0, 0.0, 0.0], p);
        assert_eq!(e.oracle(&v, Precision::F64), Truth::Invalid);
    }
    let v = case([f64::INFINITY, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0; 3]);
    assert_eq!(e.oracle(&v, Precision::F32), Truth::Invalid);
    let v = case([-5.0, 0.0, 0.0], [0.0; 3], [1.0; 3]);
    assert_eq!(e.oracle(&v, Precision::F32), Truth::Invalid);
}

#[test]
fn cylinder_oracle_hand_cases() {
    let c = &quadric::CYLINDER;
    let case = |o: [f64; 3], d: [f64; 3], p: [f64; 3]| [&o[..], &d[..], &p[..]].concat();
    // x² + y² = 1, 0 ≤ z ≤ 2: from x = −5 at height 1, t = 4
    let v = case([-5.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 1.0, 2.0]);
    assert_eq!(truth(c, &v, Precision::F64), (1, vec![4.0], false));
    // Same ray above the top: a miss
    let v = case([-5.0, 0.0, 3.0], [1.0, 0.0, 0.0], [1.0, 1.0, 2.0]);
    assert_eq!(truth(c, &v, Precision::F64).0, 0);
    // In through the open top: the far (inner) wall at t = 5/3, z = 2.5 − 4/3
    let v = case([0.0, 0.0, 2.5], [0.6, 0.0, -0.8], [1.0, 1.0, 2.0]);
    let (n, t, _) = truth(c, &v, Precision::F64);
    assert_eq!(n, 1);
    assert!((t[0] - 5.0 / 3.0).abs() < 1e-15);
    // Elliptic x² + 4y² = 1: along y from −3 hits y = −1/2 at t = 2.5
    let v = case([0.0, -3.0, 1.0], [0.0, 1.0, 0.0], [1.0, 2.0, 2.0]);
    assert_eq!(truth(c, &v, Precision::F32).1, vec![2.5]);
    // Parallel to the axis, lying in the surface: no crossing, a miss
    let v = case([1.0, 0.0, -1.0], [0.0, 0.0, 1.0], [1.0, 1.0, 2.0]);
    assert_eq!(truth(c, &v, Precision::F64).0, 0);
    // Invalid: h = 0
    let v = case([-5.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]);
    assert_eq!(c.oracle(&v, Precision::F64), Truth::Invalid);
}

#[test]
fn normal_oracle_hand_cases() {
    let n = &quadric::EllipsoidNormalShape;
    let case = |o: [f64; 3], d: [f64; 3], p: [f64; 3]| [&o[..], &d[..], &p[..]].concat();
    // x² + 4y² + z² = 4 hit at (0, −1, 0): gradient (0, −8, 0), unit (0, −1, 0)
    let v = case([0.0, -5.0, 0.0], [0.0, 1.0, 0.0], [2.0, 2.0, 1.0]);
    assert_eq!(truth(n, &v, Precision::F64).1, vec![0.0, -1.0, 0.0]);
    // Unit sphere hit at (−0.6, 0.8, 0): the normal is the point
    let v = case([-5.0, 0.8, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    let want = vec![-0.6, 0.8, 0.0];
    assert_eq!(truth(n, &v, Precision::F64).1, want);
    let want32: Vec<f64> = want.iter().map(|&x| x as f32 as f64).collect();
    assert_eq!(truth(n, &v, Precision::F32).1, want32);
    // A miss has no normal
    let v = case([0.0, 0.0, 5.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]);
    assert_eq!(truth(n, &v, Precision::F64).0, 0);
}

#[test]
fn public_functions_agree_with_the_shapes() {
    // ellipsoid_robust with semi-axes (2, 1, 2) is x² + 4y² + z² = 4
    let t = quadric::ellipsoid_robust([0.0f32, -5.0, 0.0], [0.0, 1.0, 0.0], [2.0, 1.0, 2.0]);
    assert_eq!(t, Some(4.0));
    let g = quadric::ellipsoid_normal([0.0f64, -1.0, 0.0], [2.0, 1.0, 2.0]);
    assert_eq!(g, [0.0, -2.0, 0.0]);
    let t = quadric::cylinder_robust([-5.0f64, 0.0, 1.0], [1.0, 0.0, 0.0], 1.0, 2.0);
    assert_eq!(t, Some(4.0));
    let t = aabb::box_robust([0.5f32; 3], [1.0, 0.0, 0.0], [0.0; 3], [1.0; 3]);
    assert!(t.is_some_and(|t| (0.5..0.5 + 1e-6).contains(&t)), "{t:?}");
    // The NaN slab: origin on the plane x = 0 with dx = −0, y outside: a miss
    let o = [0.0f64, 2.0, -1.0];
    assert_eq!(
        aabb::box_robust(o, [-0.0, 0.0, 1.0], [0.0; 3], [1.0; 3]),
        None
    );
    // ... and inside the face's range in y: a touch of the closed box, the exit at z = 1
    let o = [0.0f64, 0.5, -1.0];
    assert!(aabb::box_robust(o, [-0.0, 0.0, 1.0], [0.0; 3], [1.0; 3]).is_some());
}

// ---- every row of every audit against the tolerance table ----

fn check_report(r: &ShapeReport) {
    let breaks = r.failures();
    assert!(breaks.is_empty(), "{}", breaks.join("\n"));
    for row in &r.rows {
        let what = format!(
            "{} {} {} {}",
            r.shape,
            row.method,
            row.precision.name(),
            row.class
        );
        assert_eq!(row.cases, CASES, "{what}");
        assert_eq!(row.generator_failures, 0, "{what}");
        assert_eq!(row.cap_reached, 0, "{what}: oracle reached its cap");
        if row.class == "invalid" {
            assert_eq!(
                row.invalid.cases, CASES,
                "{what}: every invalid case is invalid"
            );
        } else {
            assert_eq!(row.invalid.cases, 0, "{what}: a generated case is invalid");
            assert!(
                row.well_posed >= 90,
                "{what}: only {} well-posed",
                row.well_posed
            );
        }
        if row.robust {
            assert_eq!(row.invalid.rejected, row.invalid.cases, "{what}");
            assert_eq!(
                row.false_miss + row.wrong_root + row.nonfinite_t,
                0,
                "{what}"
            );
        }
    }
}

#[test]
fn box_audit_rows() {
    check_report(box_report());
}

#[test]
fn ellipsoid_audit_rows() {
    check_report(ellipsoid_report());
}

#[test]
fn cylinder_audit_rows() {
    check_report(cylinder_report());
}

#[test]
fn normal_audit_rows() {
    check_report(normal_report());
}

#[test]
fn robust_rows_are_exact_to_an_ulp_or_two() {
    for r in [ellipsoid_report(), cylinder_report(), normal_report()] {
        for row in r.rows.iter().filter(|x| x.robust) {
            assert_eq!(row.wrong(), 0, "{} {:?}", r.shape, row.class);
            assert!(
                row.ulps.max <= 2.0,
                "{} {} {}",
                r.shape,
                row.class,
                row.ulps.max
            );
        }
    }
    for row in box_report().rows.iter().filter(|x| x.robust) {
        // Conservative: false hits only along edges (the padding), never a false miss
        if row.class != "grazing_edge" {
            assert_eq!(row.wrong(), 0, "box {}", row.class);
        }
        assert_eq!(row.false_miss, 0, "box {}", row.class);
        assert!(row.ulps.max <= 16.0, "box {} {}", row.class, row.ulps.max);
    }
}

// ---- the harness has teeth ----

#[test]
fn teeth_classic_slab_nan() {
    for p in Precision::ALL {
        let r = row(box_report(), "slab", p, "zero_dir");
        assert!(
            r.nonfinite_t + r.false_hit > 0,
            "{p:?}: NaN slab not caught"
        );
        let r = row(box_report(), "slab", p, "on_face_plane");
        assert!(r.wrong() > 0, "{p:?}: t = 0 on a face not caught");
        // The robust slab survives both
        for class in ["zero_dir", "on_face_plane"] {
            assert_eq!(row(box_report(), "robust_slab", p, class).wrong(), 0);
        }
        // The chapter's face test has no exit: every inside case is a false miss
        let r = row(box_report(), "faces", p, "inside");
        assert_eq!(r.false_miss, r.well_posed);
    }
}

#[test]
fn teeth_robust_slab_padding_is_seen() {
    // By design a false hit within the padding: the audit must see some along edges
    let r = row(box_report(), "robust_slab", Precision::F64, "grazing_edge");
    assert!(r.false_hit > 0 && r.false_miss == 0);
}

#[test]
fn teeth_chapter_quadrics_f32() {
    for rep in [ellipsoid_report(), cylinder_report()] {
        let far = row(rep, "chapter", Precision::F32, "far_small");
        assert!(
            far.wrong_rate > 0.1,
            "{}: rate {}",
            rep.shape,
            far.wrong_rate
        );
        assert!(far.false_hit > 0 && far.false_miss > 0, "{}", rep.shape);
        let huge = row(rep, "chapter", Precision::F32, "huge");
        assert!(huge.ulps.max > 1e5, "{}: {}", rep.shape, huge.ulps.max);
        for class in ["far_small", "huge"] {
            let r = row(rep, "robust", Precision::F32, class);
            assert!(r.wrong() == 0 && r.ulps.max <= 2.0, "{} {class}", rep.shape);
        }
    }
}

#[test]
fn teeth_normals() {
    let r = row(normal_report(), "chapter", Precision::F32, "far_small");
    assert!(r.wrong() > 0);
    // An accurate t does not give an accurate normal far away: o + t·d cancels
    for p in Precision::ALL {
        let r = row(normal_report(), "robust_t", p, "far_small");
        assert!(r.ulps.max > 1e4, "{p:?}: {}", r.ulps.max);
        assert!(row(normal_report(), "robust", p, "far_small").ulps.max <= 2.0);
    }
}

// ---- invalid inputs never panic and are rejected by the robust methods ----

fn every_shape() -> [&'static dyn Shape; 4] {
    [
        &aabb::BoxShape,
        &quadric::ELLIPSOID,
        &quadric::CYLINDER,
        &quadric::EllipsoidNormalShape,
    ]
}

/// Runs the oracle and every method; checks the robust methods reject invalid input.
fn no_panic_and_reject(shape: &dyn Shape, v: &[f64], prec: Precision) {
    let truth = shape.oracle(v, prec);
    for (m, info) in shape.info().methods.iter().enumerate() {
        let a: Answer = shape.run(m, v, prec);
        if info.robust {
            if truth == Truth::Invalid {
                assert_eq!(a.count, 0, "{} {} accepted {v:?}", shape.name(), info.name);
            }
            assert!(
                a.values.iter().all(|x| x.is_finite()),
                "{} {v:?}",
                info.name
            );
        }
    }
}

#[test]
fn invalid_inputs_are_rejected() {
    let specials = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0, -1.0];
    for shape in every_shape() {
        let n = shape.info().args.len();
        for prec in Precision::ALL {
            for i in 0..n {
                for &x in &specials {
                    let mut v = vec![1.0; n];
                    v[0] = -5.0;
                    v[i] = x;
                    no_panic_and_reject(shape, &v, prec);
                }
            }
            // Zero direction
            let mut v = vec![1.0; n];
            v[3..6].fill(0.0);
            assert_eq!(shape.oracle(&v, prec), Truth::Invalid);
            no_panic_and_reject(shape, &v, prec);
        }
    }
}

// ---- proptest stability suites ----

fn finite_f32() -> impl Strategy<Value = f64> {
    (-1e3f32..1e3).prop_map(|x| x as f64)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(48), ..ProptestConfig::default() })]

    /// Any bit pattern (NaN, inf, subnormal, huge) through every method and oracle: no panic;
    /// robust methods reject what the oracle calls invalid.
    #[test]
    fn arbitrary_bits_never_panic(bits in prop::collection::vec(any::<u32>(), 12), which in 0usize..4) {
        let shape = every_shape()[which];
        let v: Vec<f64> = bits[..shape.info().args.len()].iter().map(|&b| f32::from_bits(b) as f64).collect();
        no_panic_and_reject(shape, &v, Precision::F32);
    }

    /// The robust ellipsoid agrees with the oracle on random cases (1 ulp unless ill-posed).
    #[test]
    fn ellipsoid_robust_matches_oracle(o in prop::array::uniform3(finite_f32()),
            d in prop::array::uniform3(-1f32..1.0), r in 0.01f32..100.0,
            m in 0.1f32..10.0, n in 0.1f32..10.0) {
        let v = [o[0], o[1], o[2], d[0] as f64, d[1] as f64, d[2] as f64, r as f64, m as f64, n as f64];
        agrees(&quadric::ELLIPSOID, &v)?;
    }

    /// The robust cylinder agrees with the oracle on random cases.
    #[test]
    fn cylinder_robust_matches_oracle(o in prop::array::uniform3(finite_f32()),
            d in prop::array::uniform3(-1f32..1.0), r in 0.01f32..100.0,
            m in 0.1f32..10.0, h in 0.01f32..100.0) {
        let v = [o[0], o[1], o[2], d[0] as f64, d[1] as f64, d[2] as f64, r as f64, m as f64, h as f64];
        agrees(&quadric::CYLINDER, &v)?;
    }

    /// The robust slab never misses a box the exact oracle says it hits (conservative).
    #[test]
    fn robust_slab_never_misses(o in prop::array::uniform3(finite_f32()),
            d in prop::array::uniform3(-1f32..1.0), c in prop::array::uniform3(finite_f32()),
            e in prop::array::uniform3(0.01f32..100.0)) {
        let lo: Vec<f64> = (0..3).map(|i| (c[i] as f32 - e[i]) as f64).collect();
        let hi: Vec<f64> = (0..3).map(|i| (c[i] as f32 + e[i]) as f64).collect();
        let v = [&o[..], &d.map(|x| x as f64)[..], &lo[..], &hi[..]].concat();
        if let Truth::Answer(t) = aabb::BoxShape.oracle(&v, Precision::F32) {
            let a = aabb::BoxShape.run(2, &v, Precision::F32);
            prop_assert!(a.count >= t.count, "false miss {v:?}");
        }
    }

    /// Scaling every position by a power of two scales t exactly (exact prescale, rounded once).
    #[test]
    fn robust_quadrics_scale_exactly(o in prop::array::uniform3(-10f64..10.0),
            d in prop::array::uniform3(-1f64..1.0), r in 0.5f64..4.0, m in 0.5f64..2.0,
            k in -60i32..60) {
        let s = 2f64.powi(k);
        let a = quadric::ellipsoid_robust_mn(o, d, r, m, 1.5);
        let b = quadric::ellipsoid_robust_mn(o.map(|x| x * s), d, r * s, m, 1.5);
        prop_assert_eq!(a.map(|t| t * s), b);
        let a = quadric::cylinder_robust_m(o, d, r, m, 3.0);
        let b = quadric::cylinder_robust_m(o.map(|x| x * s), d, r * s, m, 3.0 * s);
        prop_assert_eq!(a.map(|t| t * s), b);
    }

    /// The radii form of the public function agrees with the (r, m, n) form within an ulp.
    #[test]
    fn ellipsoid_radii_form_agrees(o in prop::array::uniform3(-10f32..10.0),
            d in prop::array::uniform3(-1f32..1.0), r in 0.5f32..4.0, a in -3i32..3, b in -3i32..3) {
        let (m, n) = (2f32.powi(-a), 2f32.powi(-b));
        let t1 = quadric::ellipsoid_robust(o, d, [r, r / m, r / n]);
        let t2 = quadric::ellipsoid_robust_mn(o, d, r, m, n);
        prop_assert_eq!(t1.is_some(), t2.is_some());
        if let (Some(x), Some(y)) = (t1, t2) {
            prop_assert!(exact::ulps(x as f64, y as f64, Precision::F32) <= 1);
        }
    }
}

/// The robust method (index 2) of a quadric shape against its oracle, in f32.
fn agrees(shape: &dyn Shape, v: &[f64]) -> Result<(), TestCaseError> {
    let Truth::Answer(e) = shape.oracle(v, Precision::F32) else {
        return Ok(());
    };
    if e.ill_posed {
        return Ok(());
    }
    let a = shape.run(2, v, Precision::F32);
    prop_assert_eq!(a.count, e.count, "{:?}", v);
    if e.count > 0 {
        prop_assert!(
            exact::ulps(a.values[0], e.values[0], Precision::F32) <= 1,
            "{:?}",
            v
        );
    }
    Ok(())
}

#[test]
fn exact_rationals_round_like_floats() {
    // The shared rounding helper the oracles use, on a value the box oracle produces
    let t = Rational::from((7, 3));
    assert_eq!(exact::round_q(&t, Precision::F32), (7.0f32 / 3.0) as f64);
}

#[test]
fn print_tables() {
    for r in [
        box_report(),
        ellipsoid_report(),
        cylinder_report(),
        normal_report(),
    ] {
        println!("{}", table::shape_table(r));
    }
}
