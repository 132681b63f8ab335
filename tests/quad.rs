//! Ray–box, ray–ellipsoid, ray–cylinder and ellipsoid normals (seed 002 §2.2–2.4, §3): oracle
//! checks on hand-made cases, one audit per method × precision × class held to the tolerance
//! table, the harness's teeth, proptest stability suites, invalid inputs, and reintersection.

use rayproof::audit::Precision;
use rayproof::routines::audit::{self, Options, ShapeReport};
use rayproof::routines::{aabb, quadric, Shape, Truth};
use std::sync::OnceLock;

/// Cases per class of the audits below (small: the suite runs in seconds).
const CASES: u64 = 300;

fn audit_of(shape: &dyn Shape) -> ShapeReport {
    audit::run(
        shape,
        &Options {
            cases: CASES,
            seed: 1,
            precisions: Precision::ALL.to_vec(),
            methods: vec![],
            classes: vec![],
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
report_fn!(ellipsoid_report, quadric::EllipsoidShape);
report_fn!(cylinder_report, quadric::CylinderShape);
report_fn!(normal_report, quadric::EllipsoidNormalShape);

fn reports() -> [&'static ShapeReport; 4] {
    [
        box_report(),
        ellipsoid_report(),
        cylinder_report(),
        normal_report(),
    ]
}

#[test]
fn print_tables() {
    for r in reports() {
        println!("{}", audit::table(r));
    }
    for r in reports() {
        println!("{}", audit::worst_cases(r, 2));
    }
}
