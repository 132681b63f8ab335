//! Reintersection with teeth (issue 17 item 1): spawned rays judged against the ideal ray from
//! the exact hit. With the project's offset rule the robust methods of every surface never
//! re-hit; with the rule off or 1000× too weak some method of every surface does, so a broken
//! rule cannot pass unseen.

use rayproof::audit::robustness::offset::{ReintersectRow, Rule};
use rayproof::audit::robustness::reintersect::{reintersection_all, rows_of, table, NAMES};
use rayproof::numerics::Precision;
use std::sync::OnceLock;

/// Instances per decade and placement.
const PER_SCALE: u64 = 12;

fn rows() -> &'static [ReintersectRow] {
    static ROWS: OnceLock<Vec<ReintersectRow>> = OnceLock::new();
    ROWS.get_or_init(|| {
        let mut v = reintersection_all(1, PER_SCALE, Precision::F32);
        v.extend(reintersection_all(1, PER_SCALE, Precision::F64));
        println!("{}", table(&v));
        v
    })
}

#[test]
fn robust_methods_never_rehit_with_the_rule() {
    for r in rows() {
        assert!(
            r.rays > 0,
            "{} {} {}: no spawned rays",
            r.shape,
            r.method,
            r.precision
        );
        // Besides the hinge's neighbour crossings, which the exact answer for the spawned ray
        // confirms (the per-triangle rule's limit at a shared edge)
        if r.robust && r.rule == Rule::On.name() {
            assert_eq!(r.rehits, r.neighbour, "{r:?}");
        }
        if r.shape != "hinge" {
            assert_eq!(r.neighbour, 0, "{r:?}");
        }
    }
}

#[test]
fn every_surface_rehits_without_the_rule_or_with_it_too_weak() {
    for shape in NAMES {
        for rule in [Rule::Weak, Rule::Off] {
            let rehits: u64 = rows()
                .iter()
                .filter(|r| r.shape == shape && r.rule == rule.name())
                .map(|r| r.rehits - r.neighbour)
                .sum();
            assert!(
                rehits > 0,
                "{shape} rule {}: the test has no teeth",
                rule.name()
            );
        }
    }
}

#[test]
fn the_chapters_torus_methods_rehit_even_with_the_rule() {
    // Their t from the spawned origin cannot tell the root at −δ from +δ: known failures
    for prec in ["f32", "f64"] {
        for m in ["ferrari", "yuksel", "newton_bbox"] {
            let r = rows()
                .iter()
                .find(|r| {
                    (
                        r.shape.as_str(),
                        r.method.as_str(),
                        r.precision.as_str(),
                        r.rule.as_str(),
                    ) == ("torus", m, prec, "on")
                })
                .expect("row");
            assert!(r.rehits > r.rays / 20, "{r:?}");
        }
    }
}

#[test]
fn ill_posed_hits_are_rare() {
    // What is set aside (the self-hit zone, grazing chords, rays grazing within the normal's
    // turn over the reach, displaced far crossings) must not swallow the test. Measured at seed
    // 1: robust methods ≤ 13 % (the far f32 tori, where the offset reaches the tube's radius:
    // their tube is a few hundred ulps thick), others ≤ 23 % (ferrari f32, whose declared error
    // bound, and so its reach, is wide); everything else ≤ 6 %
    for r in rows().iter().filter(|r| r.rule == Rule::On.name()) {
        let limit = match (r.shape.as_str(), r.precision.as_str(), r.robust) {
            ("torus", "f32", true) => 15,
            ("torus", _, false) => 25,
            _ => 10,
        };
        assert!(r.ill_posed * 100 <= limit * r.rays, "{r:?}");
    }
}

#[test]
fn the_same_seed_gives_the_same_rows() {
    assert_eq!(
        rows_of("hinge", 5, 2, Precision::F32),
        rows_of("hinge", 5, 2, Precision::F32)
    );
}
