//! Newton refinement of 1/x and 1/√x (src/newton.rs): facts that can fail.

use rayproof::numerics::real::{hex_float, parse_f64};
use rayproof::shapes::recip::newton::*;
use std::sync::OnceLock;

/// The fast table (every 97th input), computed once for all tests.
fn rows() -> &'static [NewtonRow] {
    static ROWS: OnceLock<Vec<NewtonRow>> = OnceLock::new();
    ROWS.get_or_init(|| table(&NewtonOpts::fast()))
}

fn row(v: Variant) -> &'static NewtonRow {
    rows()
        .iter()
        .find(|r| r.variant == v)
        .unwrap_or_else(|| panic!("no row for {}", v.label()))
}

fn newton(func: Func, start: Start, steps: u32) -> Variant {
    Variant::Newton { func, start, steps }
}

const U: f64 = 1.0 / (1u64 << 24) as f64;

#[test]
fn table_has_every_variant_once() {
    let all = Variant::all();
    assert_eq!(all.len(), 18);
    assert_eq!(rows().len(), all.len());
    for v in all {
        assert_eq!(rows().iter().filter(|r| r.variant == v).count(), 1);
        let r = row(v);
        assert!(r.inputs > 80_000, "{}: {} inputs", v.label(), r.inputs);
        assert!(r.ns.median_ns > 0.0 && r.ns.min_ns <= r.ns.median_ns);
    }
}

#[test]
fn division_is_correctly_rounded() {
    let r = row(Variant::Reference(Func::Rcp));
    assert!(
        r.max_ulps <= 0.5,
        "1/x: {} ulps at {}",
        r.max_ulps,
        r.worst_input
    );
    // A correctly rounded result is off by almost half an ulp somewhere
    assert!(r.max_ulps > 0.49, "{}", r.max_ulps);
}

#[test]
fn reciprocal_of_rounded_sqrt_within_one_and_a_half_ulps() {
    let r = row(Variant::Reference(Func::Rsqrt));
    assert!(
        r.max_ulps <= 1.5,
        "1/sqrt: {} ulps at {}",
        r.max_ulps,
        r.worst_input
    );
    // Two roundings: worse than correct rounding somewhere
    assert!(r.max_ulps > 0.5, "{}", r.max_ulps);
}

#[test]
fn mpfr_reference_agrees_with_f64_division() {
    // f64 division of an f32 is correctly rounded too, so both must agree exactly
    for x in inputs(1.0, 2.0, 4099) {
        let (m, d) = (Func::Rcp.exact(x), 1.0 / x as f64);
        assert_eq!(
            m,
            d,
            "1/{}: MPFR {} f64 {}",
            hex_float(x as f64),
            hex_float(m),
            hex_float(d)
        );
    }
    // 1/sqrt(4) is exact
    assert_eq!(Func::Rsqrt.exact(4.0), 0.5);
}

#[test]
fn hardware_estimate_within_intel_bound() {
    // Intel SDM, RCPSS/RSQRTSS: |relative error| <= 1.5 * 2^-12
    for func in Func::ALL {
        let r = row(newton(func, Start::Hardware, 0));
        assert!(
            r.max_rel <= 1.5 * 2f64.powi(-12),
            "{} hardware: relative error {:e} at {} (native: {})",
            func.name(),
            r.max_rel,
            r.worst_input,
            r.native
        );
        // An estimate, not a correctly rounded value: hundreds of ulps off
        assert!(r.max_ulps > 100.0, "{}", r.max_ulps);
    }
}

#[test]
fn each_newton_step_roughly_squares_the_error() {
    for func in Func::ALL {
        for start in Start::ALL {
            let e: Vec<f64> = (0..=MAX_STEPS)
                .map(|k| row(newton(func, start, k)).max_rel)
                .collect();
            for k in 0..e.len() - 1 {
                // The step's exact map plus its roundings
                let next = match func {
                    Func::Rcp => e[k] * e[k] + 4.0 * U,
                    Func::Rsqrt => 1.5 * e[k] * e[k] + 0.5 * e[k].powi(3) + 4.0 * U,
                };
                assert!(
                    e[k + 1] <= next,
                    "{} {} step {}: {:e} after {:e}",
                    func.name(),
                    start.name(),
                    k + 1,
                    e[k + 1],
                    e[k]
                );
                // Strictly better until the rounding floor
                if e[k] > 8.0 * U {
                    assert!(
                        e[k + 1] < e[k] / 10.0,
                        "{} {} {:?}",
                        func.name(),
                        start.name(),
                        e
                    );
                }
            }
            // Three steps reach the rounding floor from either start (measured: < 2.2 ulps)
            let r = row(newton(func, start, 3));
            assert!(
                r.max_ulps < 2.5,
                "{}: {} ulps",
                r.variant.label(),
                r.max_ulps
            );
        }
    }
}

#[test]
fn bit_trick_starts_as_published() {
    // rsqrt 0x5f3759df: 3.4% (Lomont 2003; Drobot "~3.4%"); then the Quake figure 0.175%
    let r0 = row(newton(Func::Rsqrt, Start::Bits, 0)).max_rel;
    let r1 = row(newton(Func::Rsqrt, Start::Bits, 1)).max_rel;
    assert!((0.034..0.035).contains(&r0), "{r0}");
    assert!((0.0017..0.0018).contains(&r1), "{r1}");
    // rcp 0x7EF311C3: 5.05% before any step (not Drobot's "< 0.4%" for NR0), 0.26% after one
    let c0 = row(newton(Func::Rcp, Start::Bits, 0)).max_rel;
    let c1 = row(newton(Func::Rcp, Start::Bits, 1)).max_rel;
    assert!((0.050..0.051).contains(&c0), "{c0}");
    assert!((0.0025..0.0026).contains(&c1), "{c1}");
}

#[test]
fn derived_bit_trick_bound_holds_and_is_tight() {
    for func in Func::ALL {
        let bound = bits_start_bound::<f32>(func);
        let got = row(newton(func, Start::Bits, 0)).max_rel;
        assert!(got <= bound, "{}: {got:e} > {bound:e}", func.name());
        assert!(got >= 0.99 * bound, "{}: {got:e} << {bound:e}", func.name());
    }
}

#[test]
fn every_row_within_its_documented_bound() {
    for r in rows() {
        assert!(
            r.max_ulps <= r.bound_ulps && r.max_rel <= r.variant.bound_rel(),
            "{}: {} ulps (bound {}), relative {:e} (bound {:e}) at {}",
            r.variant.label(),
            r.max_ulps,
            r.bound_ulps,
            r.max_rel,
            r.variant.bound_rel(),
            r.worst_input
        );
    }
}

#[test]
fn worst_input_reproduces_the_maximum() {
    for r in rows() {
        let x = parse_f64(&r.worst_input).expect("hex float") as f32;
        let a = eval(r.variant, x);
        assert_eq!(hex_float(a as f64), r.worst_output, "{}", r.variant.label());
        let v = r.variant.func().exact(x);
        let ulps = (a as f64 - v).abs() / ulp_f32_at(v);
        assert_eq!(
            ulps,
            r.max_ulps,
            "{} at {}",
            r.variant.label(),
            r.worst_input
        );
    }
}

#[test]
fn scale_invariant_over_binades() {
    // approx(x * 2^k) == approx(x) * 2^-k (1/x), approx(x * 4^j) == approx(x) * 2^-j (1/sqrt x)
    for v in Variant::all() {
        let func = v.func();
        let (lo, hi) = func.range();
        for x in inputs(lo, hi, 7919) {
            for j in [-60i32, -9, -1, 1, 9, 60] {
                let (scale_in, scale_out) = match func {
                    Func::Rcp => (2f32.powi(j), 2f32.powi(-j)),
                    Func::Rsqrt => (4f32.powi(j), 2f32.powi(-j)),
                };
                let (a, b) = (eval(v, x * scale_in), eval(v, x) * scale_out);
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "{} at {} scaled by {}: {} vs {}",
                    v.label(),
                    hex_float(x as f64),
                    hex_float(scale_in as f64),
                    hex_float(a as f64),
                    hex_float(b as f64)
                );
            }
        }
    }
}

#[test]
fn rcp_start_outside_zero_two_over_r_diverges() {
    for r in start_bound_table() {
        match (r.inside, r.outcome) {
            (true, Outcome::Converged { .. }) => {}
            (false, Outcome::Diverged { step: 1 }) => {}
            _ => panic!("{} k={}: {:?} ({:?})", r.function, r.k, r.outcome, r.scaled),
        }
        let last = *r.scaled.last().unwrap();
        if r.function == "rcp" && !r.inside {
            // e -> e^2 with |e| > 1: runs off to -inf
            assert!(last < -1e6, "{}: {last}", r.k);
        }
    }
    // Near the limit the first step lands near 0 and recovery is slow
    let near = start_bound_demo(Func::Rcp, 3.0, &[1.99], 24);
    assert!(matches!(near[0].outcome, Outcome::Converged { step } if step > 8));
    // 1/sqrt: past sqrt(3) the iteration settles on the other root
    let past = start_bound_demo(Func::Rsqrt, 3.0, &[1.74], 40);
    assert!((past[0].scaled.last().unwrap() + 1.0).abs() < 1e-12);
    // Exactly at the limit x1 = 0 and stays there
    let at = start_bound_demo(Func::Rcp, 4.0, &[2.0], 3);
    assert_eq!(at[0].scaled[1..], [0.0, 0.0, 0.0]);
}

#[test]
fn bad_inputs_do_not_panic() {
    let bad = [
        0.0,
        -0.0,
        -1.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        f32::from_bits(1),
        f32::MAX,
        f32::MIN_POSITIVE,
    ];
    for v in Variant::all() {
        let mut out = [0f32; 9];
        assert!(eval_slice(v, &bad, &mut out).is_ok());
        assert!(eval_slice(v, &bad, &mut out[..3]).is_err());
    }
    assert_eq!(eval(Variant::Reference(Func::Rcp), 0.0), f32::INFINITY);
    // Too many steps is clamped, a zero stride is one, an empty range is empty
    let x = 1.37f32;
    assert_eq!(
        eval(newton(Func::Rcp, Start::Bits, 9), x),
        eval(newton(Func::Rcp, Start::Bits, MAX_STEPS), x)
    );
    assert_eq!(inputs(1.0, 2.0, 0).len(), 1 << 23);
    assert!(inputs(2.0, 1.0, 1).is_empty());
    let acc = accuracy(Variant::Reference(Func::Rcp), &[], &[]);
    assert_eq!(acc.inputs, 0);
    // NaN answers count as infinitely wrong
    let acc = accuracy(Variant::Reference(Func::Rcp), &[f32::NAN], &[1.0]);
    assert_eq!(acc.max_ulps, f64::INFINITY);
}

#[cfg(target_arch = "x86_64")]
#[test]
fn packed_estimate_matches_scalar_instruction() {
    use std::arch::x86_64::{_mm_cvtss_f32, _mm_rcp_ss, _mm_rsqrt_ss, _mm_set_ss};
    const { assert!(HARDWARE_IS_NATIVE) };
    for x in inputs(1.0, 4.0, 997) {
        // SAFETY: SSE is part of the x86_64 baseline
        let (ss_rcp, ss_rsqrt) = unsafe {
            (
                _mm_cvtss_f32(_mm_rcp_ss(_mm_set_ss(x))),
                _mm_cvtss_f32(_mm_rsqrt_ss(_mm_set_ss(x))),
            )
        };
        let h = hex_float(x as f64);
        assert_eq!(
            hardware_estimate(Func::Rcp, x).to_bits(),
            ss_rcp.to_bits(),
            "{h}"
        );
        assert_eq!(
            hardware_estimate(Func::Rsqrt, x).to_bits(),
            ss_rsqrt.to_bits(),
            "{h}"
        );
    }
}

#[test]
fn f64_bit_tricks_refine_the_same_way() {
    use rug::Float;
    let u = f64::EPSILON / 2.0;
    for func in Func::ALL {
        let bound = bits_start_bound::<f64>(func);
        let mut e = vec![0f64; 5];
        // Every 2^40-th f64 of [1, 4)
        let (lo, hi) = (1f64.to_bits(), 4f64.to_bits());
        for bits in (lo..hi).step_by(1 << 40) {
            let x = f64::from_bits(bits);
            let mut exact = Float::with_val(53, x);
            match func {
                Func::Rcp => exact.recip_mut(),
                Func::Rsqrt => exact.recip_sqrt_mut(),
            }
            let v = exact.to_f64();
            let mut y = bits_start(func, x);
            for (k, ek) in e.iter_mut().enumerate() {
                if k > 0 {
                    y = func.step(x, y);
                }
                *ek = ek.max((y - v).abs() / v);
            }
        }
        assert!(
            e[0] <= bound && e[0] >= 0.99 * bound,
            "{}: {:e} vs {bound:e}",
            func.name(),
            e[0]
        );
        for k in 0..4 {
            let next = match func {
                Func::Rcp => e[k] * e[k],
                Func::Rsqrt => 1.5 * e[k] * e[k] + 0.5 * e[k].powi(3),
            } + 5.0 * u;
            assert!(
                e[k + 1] <= next,
                "{} f64 step {}: {:?}",
                func.name(),
                k + 1,
                e
            );
        }
        // Four steps from the trick reach f64's rounding floor
        assert!(e[4] < 4.0 * u, "{}: {:?}", func.name(), e);
    }
}

/// The report's exhaustive table (about 4 s in release): every row within its bound, and the
/// division correctly rounded on all 2^23 inputs. Run with `-- --ignored`.
#[test]
#[ignore]
fn exhaustive_table_within_bounds() {
    let rows = table(&NewtonOpts::exhaustive());
    for r in &rows {
        assert!(
            r.max_ulps <= r.bound_ulps && r.max_rel <= r.variant.bound_rel(),
            "{}: {} ulps (bound {}), relative {:e} (bound {:e}) at {}",
            r.variant.label(),
            r.max_ulps,
            r.bound_ulps,
            r.max_rel,
            r.variant.bound_rel(),
            r.worst_input
        );
        println!(
            "{:14} {:>12.4} ulps (bound {:>12.4}) at {:16} mean {:>12.4} rel {:.4e} {}",
            r.variant.label(),
            r.max_ulps,
            r.bound_ulps,
            r.worst_input,
            r.mean_ulps,
            r.max_rel,
            r.ns.label()
        );
    }
    let inputs: Vec<u64> = rows.iter().map(|r| r.inputs).collect();
    assert!(
        inputs.iter().all(|&n| n == 1 << 23 || n == 1 << 24),
        "{inputs:?}"
    );
    // Correct rounding: never beyond half an ulp, and (no midpoint being a reciprocal) close to it
    let d = &rows[0];
    assert!(d.max_ulps <= 0.5 && d.max_ulps > 0.4999, "{}", d.max_ulps);
}
