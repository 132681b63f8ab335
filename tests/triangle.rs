//! Ray–triangle: the exact oracle on hand-made cases, one audit test per class (every method ×
//! precision checked against the tolerance table, the robust method held to zero), the teeth
//! (known failures are found), the closed-mesh watertightness test, and proptest suites (shared edges, arbitrary bit patterns).

use proptest::prelude::*;
use rayproof::audit::plan::Options;
use rayproof::audit::robustness::watertight::run as watertight_audit;
use rayproof::audit::{audit_shape, table, Row, ShapeReport};
use rayproof::audit::{judge, Shape, Truth};
use rayproof::numerics::exact::q;
use rayproof::numerics::Precision;
use rayproof::shapes::triangle::{
    self, exact_tri, moller_trumbore_hit, watertight, watertight_hit, watertight_wide_hit,
    ExactTri, Triangle, CLASSES, METHODS,
};
use rug::Rational;
use std::sync::OnceLock;

// ---- the oracle on hand-made cases ----

/// The unit right triangle in z = 0.
const TRI: [f64; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

fn case(o: [f64; 3], d: [f64; 3]) -> Vec<f64> {
    o.into_iter().chain(d).chain(TRI).collect()
}

fn answer(v: &[f64], prec: Precision) -> (u32, Vec<f64>, bool) {
    match triangle::truth(v, prec) {
        Truth::Answer(e) => (e.count, e.values, e.ill_posed),
        Truth::Invalid => panic!("valid case judged invalid"),
    }
}

#[test]
fn oracle_interior_hit_is_exact_and_well_posed() {
    let v = case([0.25, 0.25, 1.0], [0.0, 0.0, -1.0]);
    assert_eq!(answer(&v, Precision::F64), (1, vec![1.0], false));
    // t = 1/3 is rounded once in each precision
    let v = case([0.25, 0.25, 1.0], [0.0, 0.0, -3.0]);
    assert_eq!(answer(&v, Precision::F64).1, vec![1.0 / 3.0]);
    assert_eq!(answer(&v, Precision::F32).1, vec![(1.0f32 / 3.0) as f64]);
}

#[test]
fn oracle_edges_and_vertices_are_closed_and_ill_posed() {
    for o in [
        [0.5, 0.0, 1.0],
        [0.5, 0.5, 1.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 2.0],
    ] {
        let (count, _, ill) = answer(&case(o, [0.0, 0.0, -1.0]), Precision::F32);
        assert_eq!((count, ill), (1, true), "{o:?}");
        assert!(matches!(
            exact_tri(&case(o, [0.0, 0.0, -1.0])),
            ExactTri::Hit { boundary: true, .. }
        ));
    }
}

#[test]
fn oracle_misses() {
    // Outside, behind, and pointing away
    assert_eq!(
        answer(&case([1.0, 1.0, 1.0], [0.0, 0.0, -1.0]), Precision::F64).0,
        0
    );
    assert_eq!(
        answer(&case([0.25, 0.25, -1.0], [0.0, 0.0, -1.0]), Precision::F64).0,
        0
    );
    // In the plane: a miss (N·d = 0), ill-posed since tilting d by one ulp makes it a hit
    let (count, _, ill) = answer(&case([-1.0, 0.25, 0.0], [1.0, 0.0, 0.0]), Precision::F64);
    assert_eq!((count, ill), (0, true));
    // Origin on the triangle: t = 0 is not t > 0
    let (count, _, ill) = answer(&case([0.25, 0.25, 0.0], [0.0, 0.0, -1.0]), Precision::F64);
    assert_eq!((count, ill), (0, true));
}

#[test]
fn oracle_rejects_invalid_input() {
    let collinear = [
        0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 3.0, 3.0, 0.0,
    ];
    assert_eq!(triangle::truth(&collinear, Precision::F64), Truth::Invalid);
    let zero_dir = case([0.25, 0.25, 1.0], [0.0; 3]);
    assert_eq!(triangle::truth(&zero_dir, Precision::F64), Truth::Invalid);
    for bad in [f64::NAN, f64::INFINITY] {
        let mut v = case([0.25, 0.25, 1.0], [0.0, 0.0, -1.0]);
        v[7] = bad;
        assert_eq!(triangle::truth(&v, Precision::F32), Truth::Invalid);
    }
}

// ---- the audit: every method × precision × class ----

fn report() -> &'static ShapeReport {
    static R: OnceLock<ShapeReport> = OnceLock::new();
    R.get_or_init(|| {
        audit_shape(
            &Triangle,
            &Options {
                cases: Some(300),
                seed: 1,
                precisions: Precision::ALL.to_vec(),
                methods: vec![],
                classes: vec![],
                ..Default::default()
            },
        )
        .expect("audit runs")
    })
}

fn rows(class: &str) -> Vec<&'static Row> {
    report().rows.iter().filter(|r| r.class == class).collect()
}

fn row(method: &str, prec: Precision, class: &str) -> &'static Row {
    rows(class)
        .into_iter()
        .find(|r| r.method == method && r.precision == prec)
        .expect("row present")
}

/// One class: the tolerance table holds, the robust method is right on every well-posed case
/// and rejects every invalid one, and the oracle never hit its cap.
fn check_class(class: &str) {
    let one = ShapeReport {
        rows: rows(class).into_iter().cloned().collect(),
        ..report().clone()
    };
    let breaks = &one.failures();
    assert!(breaks.is_empty(), "{}", breaks.join("\n"));
    for r in &one.rows {
        assert_eq!(r.generator_failures, 0, "{} {class}", r.method);
        assert_eq!(r.cap_reached, 0);
        if r.robust {
            assert_eq!(r.wrong(), 0, "{} {:?} {class}", r.method, r.precision);
            assert_eq!(r.invalid.rejected, r.invalid.cases);
        }
        if !matches!(class, "degenerate" | "invalid") {
            assert!(
                r.well_posed >= 50,
                "{class} has {} well-posed",
                r.well_posed
            );
        } else {
            assert_eq!(r.invalid.cases, r.cases, "every {class} case is invalid");
        }
    }
}

macro_rules! class_tests {
    ($($class:ident),*) => {
        mod audit_class {
            $( #[test] fn $class() { super::check_class(stringify!($class)); } )*
        }
    };
}
class_tests!(generic, edge, vertex, parallel, degenerate, huge, tiny, far, invalid);

#[test]
fn every_class_has_a_test() {
    assert_eq!(CLASSES.len(), 9);
    assert_eq!(METHODS.len(), 4);
    assert_eq!(report().rows.len(), 9 * 4 * 2);
}

#[test]
fn default_seed_audit_passes_the_table() {
    let breaks = report().failures();
    assert!(breaks.is_empty(), "{}", breaks.join("\n"));
}

#[test]
fn print_audit_table() {
    println!("{}", table::shape_table(report()));
}

// ---- teeth: the known failures are found ----

#[test]
fn teeth_naive_methods_fail_where_known() {
    use Precision::*;
    let wrong = |m, p, c| row(m, p, c).wrong();
    // Overflow and underflow of products in f32
    assert!(wrong("chapter", F32, "huge") > 0);
    assert!(wrong("watertight", F32, "huge") > 0);
    assert!(wrong("chapter", F32, "tiny") > 0);
    // The absolute determinant epsilon of Möller–Trumbore
    assert!(wrong("moller_trumbore", F32, "tiny") > 0);
    assert!(wrong("moller_trumbore", F64, "tiny") > 0);
    // Rays a few ulps outside a vertex
    for m in ["chapter", "moller_trumbore", "watertight"] {
        assert!(wrong(m, F64, "vertex") > 0, "{m}");
    }
    // The chapter's cancellation far from the origin
    assert!(row("chapter", F64, "far").ulps.max > 1e5);
    // ... none of which the promoted watertight shows
    for p in Precision::ALL {
        for c in CLASSES {
            assert_eq!(wrong("watertight_wide", p, c), 0);
        }
    }
}

#[test]
fn teeth_judge_catches_a_planted_false_hit() {
    let v = case([1.0, 1.0, 1.0], [0.0, 0.0, -1.0]);
    let truth = Triangle.oracle(&v, Precision::F64);
    let planted = rayproof::shapes::shape::Answer::hit(vec![1.0]);
    assert!(judge(&truth, &planted, Triangle.info(), Precision::F64).is_wrong());
}

// ---- watertightness ----

#[test]
fn watertightness_finds_cracks_and_the_watertight_methods_have_none() {
    for prec in Precision::ALL {
        let rows = watertight_audit(7, 2000, prec);
        for r in &rows {
            println!(
                "{:<16} {} {:<5} {:<12} {:>5} rays {:>4} escaped {:>4} grazing (oracle checked {}, violations {})",
                r.method, r.precision, r.mesh, r.kind, r.rays, r.escaped, r.grazing,
                r.oracle_checked, r.oracle_violations
            );
            assert_eq!(
                r.oracle_violations, 0,
                "the oracle disagrees: origin not inside?"
            );
            if r.method.starts_with("watertight") {
                assert_eq!(r.escaped, 0, "{r:?}");
            }
            // Every escape carries its replay line
            assert_eq!(r.replay.is_some(), r.escaped + r.grazing > 0, "{r:?}");
        }
        // Teeth: the chapter's method leaks through the far mesh, Möller–Trumbore at edges
        let esc = |m: &str, mesh: &str, k: &str| {
            rows.iter()
                .find(|r| (r.method.as_str(), r.mesh.as_str(), r.kind.as_str()) == (m, mesh, k))
                .unwrap()
                .escaped
        };
        if prec == Precision::F32 {
            assert!(esc("chapter", "far", "random") > 0);
        }
        assert!(esc("chapter", "far", "edge") > 0);
        assert!(
            esc("moller_trumbore", "far", "edge") + esc("moller_trumbore", "far", "vertex") > 0
        );
    }
}

/// Issue 17's shared-edge "leak", reproduced deterministically (the proptest case cc 101eecd…):
/// the exact oracle hits both triangles of the fold, the f32 watertight method misses both, and
/// the shared edge is a silhouette seen from the ray's origin, so this is the `grazing` miss the
/// watertightness audit counts apart, not a crack (the method evaluates each edge function once
/// for both triangles, so it cannot pass between them where the edge is not a silhouette).
#[test]
fn the_shared_edge_case_of_issue_17_is_a_grazing_silhouette_miss() {
    let a = [4.389724041797666, 5.982470973707235, 3.3312154497454007];
    let b = [-9.959961968707576, 1.2574197903632554, -6.792091016966494];
    let c = [-1.7144788538768716, -5.728740143230774, -7.19836920814146];
    let e = [0.0, 0.0, 9.936290527886866];
    let o = [-5.944488346071514, 3.0326874459755744, -3.6828205591784964];
    let u = 0.3276310452225506f64;
    let e: [f64; 3] = std::array::from_fn(|i| b[i] + c[i] - a[i] + 0.3 * e[i] / 10.0);
    let [a, b, c, e, o] = [a, b, c, e, o].map(r32);
    let aim: [f32; 3] = std::array::from_fn(|i| b[i] + (c[i] - b[i]) * u as f32);
    let d: [f32; 3] = std::array::from_fn(|i| aim[i] - o[i]);
    let (tri_a, tri_b) = ([a, b, c], [c, b, e]);
    let flat = |p: [[f32; 3]; 3]| -> Vec<f64> {
        o.iter()
            .chain(&d)
            .chain(p.iter().flatten())
            .map(|&x| x as f64)
            .collect()
    };
    // The oracle: both hit; the f32 method: both miss; the promoted method: a hit
    assert!(exact_tri(&flat(tri_a)).t().is_some());
    assert!(exact_tri(&flat(tri_b)).t().is_some());
    assert!(watertight(o, d, tri_a).is_none() && watertight(o, d, tri_b).is_none());
    assert!(
        watertight_wide_hit(o, d, tri_a).is_some() || watertight_wide_hit(o, d, tri_b).is_some()
    );
    // A silhouette: both triangles lie on one side of the plane through o and the edge
    assert_eq!(side(o, b, c, a), side(o, b, c, e));
}

#[test]
fn public_watertight_matches_its_hit_record() {
    let (o, d) = ([0.25f32, 0.25, 1.0], [0.0f32, 0.0, -2.0]);
    let p = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(watertight(o, d, p), Some(0.5));
    let h = watertight_hit(o, d, p).unwrap();
    assert!((h.b.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    assert_eq!(
        watertight(
            [0.25f64, 0.25, 1.0],
            [0.0, 0.0, 1.0],
            p.map(|v| v.map(f64::from))
        ),
        None
    );
}

// ---- proptest suites ----

fn arb_point() -> impl Strategy<Value = [f64; 3]> {
    [-10.0..10.0f64, -10.0..10.0f64, -10.0..10.0f64]
}

fn r32(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// The exact sign of the orientation of `p` against the plane through `o`, `b`, `c`.
fn side(o: [f32; 3], b: [f32; 3], c: [f32; 3], p: [f32; 3]) -> i32 {
    let rel =
        |v: [f32; 3]| -> [Rational; 3] { std::array::from_fn(|i| q(v[i] as f64) - q(o[i] as f64)) };
    let [u, v, w] = [rel(b), rel(c), rel(p)];
    let minor = |i: usize, j: usize| Rational::from(&v[i] * &w[j]) - Rational::from(&v[j] * &w[i]);
    let det = &u[0] * minor(1, 2) - &u[1] * minor(0, 2) + &u[2] * minor(0, 1);
    det.cmp0() as i32
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, rng_seed: proptest::test_runner::RngSeed::Fixed(200), ..ProptestConfig::default() })]

    /// Two triangles sharing an edge: a ray the exact oracle sends through the middle part of the
    /// shared edge's neighbourhood hits at least one of them with the watertight method (f32),
    /// although it may miss both with Möller–Trumbore. Where the edge is a silhouette seen from
    /// the ray's origin (both triangles on one side of the plane through o and the edge), a
    /// grazing ray may rightly miss both, so those cases are not drawn (the case replayed below,
    /// cc 101eecd…, is one: the exact oracle hits both triangles, 2.4e-7 and 4.4e-8 from the edge).
    #[test]
    fn shared_edge_never_leaks(a in arb_point(), b in arb_point(), c in arb_point(),
                               e in arb_point(), o in arb_point(), u in 0.1..0.9f64) {
        // The far vertex across the shared edge b–c: a perturbed parallelogram
        let e: [f64; 3] = std::array::from_fn(|i| b[i] + c[i] - a[i] + 0.3 * e[i] / 10.0);
        let [a, b, c, e, o] = [a, b, c, e, o].map(r32);
        let tri_a = [a, b, c];
        let tri_b = [c, b, e];
        let aim: [f32; 3] = std::array::from_fn(|i| b[i] + (c[i] - b[i]) * u as f32);
        let d: [f32; 3] = std::array::from_fn(|i| aim[i] - o[i]);
        let flat = |p: [[f32; 3]; 3]| -> Vec<f64> {
            o.iter().chain(&d).chain(p.iter().flatten()).map(|&x| x as f64).collect()
        };
        let (ea, eb) = (exact_tri(&flat(tri_a)), exact_tri(&flat(tri_b)));
        prop_assume!(ea != ExactTri::Invalid && eb != ExactTri::Invalid);
        prop_assume!(ea.t().is_some() || eb.t().is_some());
        // Watertightness is owed only where the edge is not a silhouette seen from o
        prop_assume!(side(o, b, c, a) * side(o, b, c, e) < 0);
        let hit = watertight(o, d, tri_a).is_some() || watertight(o, d, tri_b).is_some();
        prop_assert!(hit, "leak: o {:?} d {:?} a {:?} b {:?}", o, d, tri_a, tri_b);
        let _ = moller_trumbore_hit(o, d, tri_a);
    }

    /// The promoted watertight method agrees with the oracle on every well-posed generic case.
    #[test]
    fn wide_agrees_with_the_oracle(o in arb_point(), d in arb_point(), a in arb_point(),
                                   b in arb_point(), c in arb_point()) {
        let v: Vec<f64> = [o, d, a, b, c].iter().flatten().map(|&x| x as f32 as f64).collect();
        let truth = triangle::truth(&v, Precision::F32);
        let got = Triangle.run(3, &v, Precision::F32);
        if let Truth::Answer(e) = &truth {
            if !e.ill_posed {
                prop_assert_eq!(got.count, e.count);
                if e.count == 1 {
                    prop_assert!(rayproof::numerics::exact::ulps(got.values[0], e.values[0], Precision::F32) <= 1);
                }
            }
        }
    }

    /// Arbitrary bit patterns: no method and no oracle panics, and the robust method rejects
    /// whatever the oracle calls invalid.
    #[test]
    fn arbitrary_bits_never_panic(bits in proptest::collection::vec(any::<u64>(), 15),
                                  small in any::<bool>()) {
        let v: Vec<f64> = bits.iter().map(|&b| {
            let x = f64::from_bits(b);
            if small { f32::from_bits(b as u32) as f64 } else { x }
        }).collect();
        let prec = if small { Precision::F32 } else { Precision::F64 };
        let truth = Triangle.oracle(&v, prec);
        for (m, info) in METHODS.iter().enumerate() {
            let a = Triangle.run(m, &v, prec);
            if info.robust && truth == Truth::Invalid {
                prop_assert_eq!(a.count, 0);
            }
        }
        let _ = watertight_wide_hit([v[0], v[1], v[2]], [v[3], v[4], v[5]],
            [[v[6], v[7], v[8]], [v[9], v[10], v[11]], [v[12], v[13], v[14]]]);
    }
}

/// The measurement behind the tolerance table (run with `--ignored --nocapture`).
#[test]
#[ignore = "measurement: 2,000 cases per class"]
fn measure_tolerance_table() {
    let r = audit_shape(
        &Triangle,
        &Options {
            cases: Some(2000),
            seed: 1,
            precisions: Precision::ALL.to_vec(),
            methods: vec![],
            classes: vec![],
            ..Default::default()
        },
    )
    .expect("audit runs");
    println!("{}", table::shape_table(&r));
    let breaks = &r.failures();
    assert!(breaks.is_empty(), "{}", breaks.join("\n"));
}

#[test]
fn fold_grazing_misses_of_the_watertight_methods_are_mostly_ill_posed() {
    // A well-posed grazing miss is a single-triangle false miss (the shear rounds by more than
    // one ulp of an input), reported and judged by the triangle rows; most are ill-posed
    for prec in Precision::ALL {
        for r in watertight_audit(7, 2000, prec)
            .iter()
            .filter(|r| r.mesh == "fold")
        {
            println!(
                "{} {}: {} grazing, {} well-posed",
                r.method, r.precision, r.grazing, r.grazing_well_posed
            );
            if r.method.starts_with("watertight") {
                assert!(r.grazing_well_posed * 10 <= r.grazing, "{r:?}");
            }
        }
    }
}
