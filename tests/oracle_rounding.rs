//! Teeth for the oracle's rounding (issue 17, item 4, for the sphere): hand-derived rays whose
//! exact nearest root is a tie between two floats (round-half-even must pick the even one), a
//! value just either side of a tie, a subnormal result and one that overflows to inf, in f32 and
//! f64. The ray starts at 0 along +x and the sphere sits on the x axis, so the exact root is
//! c − r, a difference of two floats the test can choose bit by bit.

use std::process::Command;

/// The oracle's correctly rounded `t` for the ray (0, 0, 0) + t·(d, 0, 0) and the sphere at
/// (c, 0, 0) of radius r, as `rayproof probe` prints it.
fn oracle_t(prec: &str, d: &str, c: &str, r: &str) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .args([
            "probe",
            "sphere",
            "--precision",
            prec,
            "--",
            "0",
            "0",
            "0",
            d,
            "0",
            "0",
            c,
            "0",
            "0",
            r,
        ])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    let line = out
        .lines()
        .find(|l| l.starts_with("oracle:"))
        .unwrap_or_else(|| panic!("no oracle line:\n{out}"));
    line.rsplit(' ').next().unwrap().to_string()
}

#[test]
fn f32_ties_round_to_even_and_near_ties_to_nearest() {
    let cases = [
        // t = 1 + 2⁻²⁴: halfway between 1 (even) and 1 + 2⁻²³ (odd) → 1
        ("1", "2", "0x1.fffffep-1", "0x1p+0"),
        // t = 1 + 3·2⁻²⁴: halfway between 1 + 2⁻²³ (odd) and 1 + 2⁻²² (even) → up
        ("1", "2", "0x1.fffffap-1", "0x1.000004p+0"),
        // t = 1 + 2⁻²⁵: below the tie → 1
        ("1", "0x1.8p+0", "0x1.fffffep-2", "0x1p+0"),
        // t = 1 + 3·2⁻²⁵: above the tie → 1 + 2⁻²³
        ("1", "0x1.8p+0", "0x1.fffffap-2", "0x1.000002p+0"),
        // t = 2⁻¹²⁷: a subnormal, exact
        ("1", "0x1p-126", "0x1p-127", "0x1p-127"),
        // t = 2¹⁴⁷ − 2²⁰: beyond the largest f32 → inf
        ("0x1p-20", "0x1p+127", "1", "inf"),
    ];
    for (d, c, r, want) in cases {
        assert_eq!(oracle_t("f32", d, c, r), want, "d {d} c {c} r {r}");
    }
}

#[test]
fn f64_ties_round_to_even_and_near_ties_to_nearest() {
    let cases = [
        ("1", "2", "0x1.fffffffffffffp-1", "0x1p+0"),
        ("1", "2", "0x1.ffffffffffffdp-1", "0x1.0000000000002p+0"),
        ("1", "0x1.8p+0", "0x1.fffffffffffffp-2", "0x1p+0"),
        (
            "1",
            "0x1.8p+0",
            "0x1.ffffffffffffdp-2",
            "0x1.0000000000001p+0",
        ),
        ("1", "0x1p-1022", "0x1p-1023", "0x1p-1023"),
        ("0x1p-20", "0x1p+1023", "1", "inf"),
    ];
    for (d, c, r, want) in cases {
        assert_eq!(oracle_t("f64", d, c, r), want, "d {d} c {c} r {r}");
    }
}

// ---- every other rounding path (issue 17 item 4) ----
//
// The routine families round their exact values through three helpers: `round_q` (an exact
// rational: triangle, box, reflect/refract, rcp), `sturm::round_root` (a polynomial root:
// quadratic, cubic, quartic, Newton, torus) and `ziv` (an MPFR enclosure: rsqrt and the
// quadrics' square roots). The first is driven through two families' oracles; the other two
// directly, because a root of a polynomial with f32 or f64 coefficients is never exactly a tie
// of that precision (rational root theorem: its odd numerator would divide a coefficient's odd
// mantissa, which has fewer bits) and a square root is a tie only when it is exact.

use rayproof::numerics::exact::{q, sqrt_encl, ziv, ZIV_CAP};
use rayproof::numerics::real::hex_float;
use rayproof::numerics::Precision;
use rayproof::shapes::oracle::sturm::{real_roots, round_root};
use rayproof::shapes::shape::Truth;
use rayproof::shapes::{aabb, triangle};
use rug::Rational;

fn first(t: Truth) -> f64 {
    match t {
        Truth::Answer(e) if e.count > 0 => e.values[0],
        other => panic!("no hit: {other:?}"),
    }
}

/// `2^e` exactly, subnormals included (`powi` loses them).
fn pow2(e: i32) -> f64 {
    if e < -1000 {
        2f64.powi(-1000) * 2f64.powi(e + 1000)
    } else {
        2f64.powi(e)
    }
}

/// `(plane p, origin depth e, dz, want)`: the ray (¼, ¼, −e) + t·(0, 0, dz) meets the plane
/// z = p at t = (p + e)/dz exactly.
fn plane_cases(prec: Precision) -> Vec<(f64, f64, f64, f64)> {
    let (m, emin, emax, k) = match prec {
        Precision::F32 => (24, -149, 127, 30),
        Precision::F64 => (53, -1074, 1023, 60),
    };
    let u = pow2(-m);
    let big = 1.5 * pow2(emax);
    vec![
        // A tie between 1 (even) and 1 + 2u (odd) → 1
        (1.0, u, 1.0, 1.0),
        // A tie between 1 + 2u (odd) and 1 + 4u (even) → up
        (1.0, 3.0 * u, 1.0, 1.0 + 4.0 * u),
        // Just below and just above the first tie
        (1.0, 0.5 * u, 1.0, 1.0),
        (1.0, u + 2.0 * u * u, 1.0, 1.0 + 2.0 * u),
        // A subnormal tie, 3·2^(emin−1) between 2^emin (odd) and 2^(emin+1) (even) → up
        (0.0, 3.0 * pow2(-k), pow2(1 - k - emin), pow2(emin + 1)),
        // 3·2^emax: beyond the largest finite value → inf
        (big, big, 1.0, f64::INFINITY),
    ]
}

#[test]
fn triangle_and_box_oracles_round_exact_rationals_to_nearest_even() {
    for prec in Precision::ALL {
        for (p, e, dz, want) in plane_cases(prec) {
            let (o, d) = ([0.25, 0.25, -e], [0.0, 0.0, dz]);
            let tri: Vec<f64> = [o, d, [0.0, 0.0, p], [1.0, 0.0, p], [0.0, 1.0, p]].concat();
            let hi = if p == 0.0 { 1.0 } else { p + p / 8.0 };
            let bx: Vec<f64> = [o, d, [0.0, 0.0, p], [1.0, 1.0, hi]].concat();
            assert!(bx
                .iter()
                .chain(&tri)
                .all(|&x| rayproof::numerics::exact::representable(x, prec)));
            let got = first(triangle::truth(&tri, prec));
            assert_eq!(
                got,
                want,
                "triangle {prec:?} p {} e {}: {}",
                hex_float(p),
                hex_float(e),
                hex_float(got)
            );
            let got = first(aabb::oracle(&bx, prec));
            assert_eq!(
                got,
                want,
                "box {prec:?} p {} e {}: {}",
                hex_float(p),
                hex_float(e),
                hex_float(got)
            );
        }
    }
}

#[test]
fn polynomial_roots_round_to_nearest_even() {
    for prec in Precision::ALL {
        for (p, e, dz, want) in plane_cases(prec) {
            // (x − r)(x + 1) with r = (p + e)/dz exactly: ascending coefficients
            let r = (q(p) + q(e)) / q(dz);
            let c = [
                Rational::from(-&r),
                Rational::from(1 - &r),
                Rational::from(1),
            ];
            let roots = real_roots(&c);
            let top = roots.last().expect("two roots");
            let got = round_root(&c, top, prec);
            assert_eq!(
                got,
                want,
                "{prec:?} root {}: {}",
                r.to_f64(),
                hex_float(got)
            );
        }
    }
}

#[test]
fn polynomial_roots_next_to_the_overflow_threshold() {
    for prec in Precision::ALL {
        let (max, ulp) = match prec {
            Precision::F32 => (f32::MAX as f64, pow2(104)),
            Precision::F64 => (f64::MAX, pow2(971)),
        };
        // Below max + ulp/2 a root rounds to max; from it on, to inf (IEEE's overflow rule)
        for (r, want) in [
            (q(max) + q(ulp) / 4u32, max),
            (q(max) + q(ulp) * 3u32 / 4u32, f64::INFINITY),
            (q(max) + q(ulp) / 2u32, f64::INFINITY),
        ] {
            let c = [
                Rational::from(-&r),
                Rational::from(1 - &r),
                Rational::from(1),
            ];
            let top = real_roots(&c).pop().expect("two roots");
            assert_eq!(round_root(&c, &top, prec), want, "{prec:?}");
        }
    }
}

#[test]
fn ziv_rounds_exact_square_roots_to_nearest_even() {
    for prec in Precision::ALL {
        // Square roots that are exactly a tie, or just either side (overflow has no square root)
        for (p, e, dz, want) in plane_cases(prec).into_iter().filter(|c| c.3.is_finite()) {
            let r = (q(p) + q(e)) / q(dz);
            let sq = Rational::from(&r * &r);
            let got = ziv(prec, ZIV_CAP, |bits| sqrt_encl(&sq, bits)).expect("decided");
            assert_eq!(
                got,
                want,
                "{prec:?} sqrt of {}²: {}",
                r.to_f64(),
                hex_float(got)
            );
        }
    }
}
