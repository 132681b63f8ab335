//! Reflection and refraction vectors: exact oracles on hand-made cases, one audit test per class
//! (every method × precision against the tolerance table, robust methods held to zero), the
//! teeth (TIR decisions flipping near the critical angle), and proptest property checks
//! (length and angle of R, Snell's law and unit length of T).

use proptest::prelude::*;
use rayproof::audit::plan::Options;
use rayproof::audit::{audit_shape, table, ShapeReport};
use rayproof::audit::{Shape, Truth};
use rayproof::numerics::Precision;
use rayproof::shapes::optics::{
    self, reflect_chapter, reflect_fma, refract_chapter, refract_pbrt, refract_wide, Reflect,
    Refract,
};
use std::sync::OnceLock;

fn answer(t: Truth) -> (u32, Vec<f64>, bool) {
    match t {
        Truth::Answer(e) => (e.count, e.values, e.ill_posed),
        Truth::Invalid => panic!("valid case judged invalid"),
    }
}

// ---- oracles on hand-made cases ----

#[test]
fn reflect_oracle_exact_cases() {
    let t = optics::reflect_truth(&[0.75, 0.0, 0.5, 0.0, 0.0, 1.0], Precision::F64);
    assert_eq!(answer(t), (1, vec![-0.75, 0.0, 0.5], false));
    // Not unit: the formula is applied to the values as given: 2·(N·L)N − L with N·L = 2
    let t = optics::reflect_truth(&[1.0, 0.0, 1.0, 0.0, 0.0, 2.0], Precision::F32);
    assert_eq!(answer(t).1, vec![-1.0, 0.0, 7.0]);
    for bad in [
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        [1.0, 0.0, f64::NAN, 0.0, 0.0, 1.0],
    ] {
        assert_eq!(optics::reflect_truth(&bad, Precision::F64), Truth::Invalid);
    }
}

#[test]
fn refract_oracle_exact_cases() {
    // Normal incidence: T = −N for any η (radicand 1)
    let t = optics::refract_truth(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.5], Precision::F64);
    assert_eq!(answer(t), (1, vec![0.0, 0.0, -1.0], false));
    // η = 1 passes straight through: T = −L
    let t = optics::refract_truth(&[0.75, 0.0, 0.5, 0.0, 0.0, 1.0, 1.0], Precision::F32);
    assert_eq!(answer(t).1, vec![-0.75, 0.0, -0.5]);
    // η = 2 at N·L = 1/2: radicand 1 − 4·3/4 = −2 < 0, total internal reflection
    let t = optics::refract_truth(&[0.75, 0.0, 0.5, 0.0, 0.0, 1.0, 2.0], Precision::F64);
    assert_eq!(answer(t), (0, vec![], false));
    // An irrational T: η = 1/2, L = (0.75, 0, 0.5): radicand 1 − (1 − 1/4)/4 = 13/16
    let t = optics::refract_truth(&[0.75, 0.0, 0.5, 0.0, 0.0, 1.0, 0.5], Precision::F64);
    let v = answer(t).1;
    assert_eq!(v[0], -0.375);
    // T_z = (η·c − √rad) − η·L_z = 1/4 − √13/4 − 1/4 (sqrt correctly rounded, /4 exact)
    assert_eq!(v[2], -(13.0f64).sqrt() / 4.0);
    // Invalid: η ≤ 0, zero N, NaN
    for bad in [
        [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, -1.5],
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.5],
        [f64::NAN, 0.0, 1.0, 0.0, 0.0, 1.0, 1.5],
    ] {
        assert_eq!(optics::refract_truth(&bad, Precision::F64), Truth::Invalid);
    }
}

#[test]
fn refract_oracle_flags_the_critical_angle_as_ill_posed() {
    // η·sinθ ≈ 1 to within an ulp: some one-ulp move flips TIR
    let eta = 1.5f32;
    let c = (1.0 - 1.0 / (eta * eta)).sqrt();
    let s = (1.0 - c * c).sqrt();
    let v = [s as f64, 0.0, c as f64, 0.0, 0.0, 1.0, eta as f64];
    assert!(answer(optics::refract_truth(&v, Precision::F32)).2);
}

// ---- the audits ----

fn report(shape: &'static dyn Shape) -> &'static ShapeReport {
    static R: OnceLock<[ShapeReport; 2]> = OnceLock::new();
    let all = R.get_or_init(|| {
        [&Reflect as &dyn Shape, &Refract].map(|s| {
            audit_shape(
                s,
                &Options {
                    cases: Some(1000),
                    seed: 1,
                    precisions: Precision::ALL.to_vec(),
                    methods: vec![],
                    classes: vec![],
                    ..Default::default()
                },
            )
            .expect("audit runs")
        })
    });
    &all[(shape.name() == "refract") as usize]
}

fn check_class(shape: &'static dyn Shape, class: &str) {
    let one = ShapeReport {
        rows: report(shape)
            .rows
            .iter()
            .filter(|r| r.class == class)
            .cloned()
            .collect(),
        ..report(shape).clone()
    };
    assert!(!one.rows.is_empty());
    let breaks = &one.failures();
    assert!(breaks.is_empty(), "{}", breaks.join("\n"));
    for r in &one.rows {
        assert_eq!(r.cap_reached, 0);
        if r.robust {
            assert_eq!(r.wrong(), 0, "{} {:?} {class}", r.method, r.precision);
            assert_eq!(r.invalid.rejected, r.invalid.cases);
        }
        if class == "invalid" {
            assert_eq!(r.invalid.cases, r.cases);
        } else {
            assert!(r.well_posed >= 500, "{class}: {} well-posed", r.well_posed);
        }
    }
}

macro_rules! class_tests {
    ($module:ident, $shape:expr, $($class:ident),*) => {
        mod $module {
            $( #[test] fn $class() { super::check_class($shape, stringify!($class)); } )*
        }
    };
}
class_tests!(
    reflect_class,
    &super::Reflect,
    generic,
    grazing,
    normal_incidence,
    unnormalised,
    invalid
);
class_tests!(
    refract_class,
    &super::Refract,
    generic,
    critical,
    grazing,
    normal_incidence,
    eta_one,
    unnormalised,
    invalid
);

#[test]
fn default_seed_audits_pass_their_tables() {
    for s in [&Reflect as &'static dyn Shape, &Refract] {
        let breaks = report(s).failures();
        assert!(breaks.is_empty(), "{}", breaks.join("\n"));
        println!("{}", table::shape_table(report(s)));
    }
}

// ---- teeth ----

#[test]
fn teeth_tir_flips_near_the_critical_angle() {
    let row = |m: &str, p| {
        report(&Refract)
            .rows
            .iter()
            .find(|r| r.method == m && r.precision == p && r.class == "critical")
            .unwrap()
    };
    // The exact decision sees well-posed cases on both sides...
    let r = row("wide", Precision::F32);
    assert!(r.oracle_hits > 100 && r.oracle_hits + 100 < r.well_posed);
    // ... which the chapter's and pbrt's f32 decisions get wrong, and the wide one does not
    assert!(row("chapter", Precision::F32).wrong() > 0);
    assert!(row("chapter", Precision::F32).ulps.max > 1000.0);
    assert!(row("pbrt", Precision::F32).ulps.max > 1000.0);
    assert_eq!(r.wrong(), 0);
    // The chapter's reflection has no guard: NaN inputs come back as NaN vectors
    let inv = report(&Reflect)
        .rows
        .iter()
        .find(|r| r.method == "chapter" && r.class == "invalid")
        .unwrap();
    assert!(inv.invalid.nonfinite_t > 0);
}

// ---- properties ----

fn unit() -> impl Strategy<Value = [f64; 3]> {
    [-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64]
        .prop_filter("not too short", |v| dot(*v, *v) > 0.01)
        .prop_map(|v| {
            let n = dot(v, v).sqrt();
            v.map(|x| x / n)
        })
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross_len(a: [f64; 3], b: [f64; 3]) -> f64 {
    let c = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    dot(c, c).sqrt()
}
fn f32v(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}
fn f64v(v: [f32; 3]) -> [f64; 3] {
    v.map(|x| x as f64)
}

/// `ε` of f32.
const E: f64 = f32::EPSILON as f64;

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, rng_seed: proptest::test_runner::RngSeed::Fixed(400), ..ProptestConfig::default() })]

    /// |R| = |L| and N·R = N·L hold exactly for unit N; with inputs rounded to f32 (|N|² within
    /// 3ε of 1) and the f32 evaluation (dot 3ε, then 2 roundings per component), both hold
    /// within 16ε (a 2× margin over the sum of those terms).
    #[test]
    fn reflection_keeps_length_and_angle(l in unit(), n in unit()) {
        let (l, n) = (f32v(l), f32v(n));
        prop_assume!(dot(f64v(l), f64v(n)) > 0.0);
        for r in [reflect_chapter(l, n).unwrap(), reflect_fma(l, n).unwrap()] {
            let (r, l, n) = (f64v(r), f64v(l), f64v(n));
            prop_assert!((dot(r, r).sqrt() - 1.0).abs() <= 16.0 * E, "|R| = {}", dot(r, r).sqrt());
            prop_assert!((dot(n, r) - dot(n, l)).abs() <= 16.0 * E);
        }
    }

    /// Snell: N×T = −η·N×L exactly for the chapter's T (the N component drops out), so
    /// |N×T| = η|N×L| up to rounding: the wide method's T is within an ulp per component
    /// (|N×T| within 4ε·|N|), the f32 methods add a few roundings of η·L (8ε·η). |T| = 1 for
    /// unit inputs; with inputs rounded to f32 it is within 8ε·(1 + η²) for the wide method.
    #[test]
    fn refraction_obeys_snell_and_stays_unit(l in unit(), n in unit(), eta in 0.3..3.0f64) {
        let (l, n, eta) = (f32v(l), f32v(n), eta as f32);
        prop_assume!(dot(f64v(l), f64v(n)) > 0.0);
        let want = eta as f64 * cross_len(f64v(n), f64v(l));
        let tw = refract_wide(l, n, eta);
        if let Some(t) = tw {
            let t = f64v(t);
            prop_assert!((cross_len(f64v(n), t) - want).abs() <= 4.0 * E * (1.0 + eta as f64));
            let bound = 8.0 * E * (1.0 + (eta * eta) as f64);
            prop_assert!((dot(t, t).sqrt() - 1.0).abs() <= bound, "|T| = {}", dot(t, t).sqrt());
        }
        for t in [refract_chapter(l, n, eta), refract_pbrt(l, n, eta)].into_iter().flatten() {
            let t = f64v(t);
            prop_assert!((cross_len(f64v(n), t) - want).abs() <= 8.0 * E * (1.0 + eta as f64));
        }
    }

    /// Arbitrary bit patterns: no method or oracle panics; the robust methods reject what the
    /// oracles call invalid.
    #[test]
    fn arbitrary_bits_never_panic(bits in proptest::collection::vec(any::<u32>(), 7)) {
        let v: Vec<f64> = bits.iter().map(|&b| f32::from_bits(b) as f64).collect();
        for (shape, robust) in [(&Reflect as &dyn Shape, 1usize), (&Refract, 2)] {
            let input = &v[..shape.info().args.len()];
            let truth = shape.oracle(input, Precision::F32);
            for m in 0..shape.info().methods.len() {
                let a = shape.run(m, input, Precision::F32);
                if m == robust && truth == Truth::Invalid {
                    prop_assert_eq!(a.count, 0);
                }
            }
        }
    }
}
