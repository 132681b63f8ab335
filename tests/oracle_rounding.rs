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
