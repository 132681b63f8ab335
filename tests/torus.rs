//! Ray–torus: oracle checks on hand-made cases, audit rows per method × precision × class,
//! the harness's teeth, reintersection, proptest stability suites, invalid inputs.

use rayproof::audit::Precision;
use rayproof::routines::audit::{self, Options};
use rayproof::routines::torus::{Torus, TorusNormal};
use rayproof::routines::Shape;

fn opts(cases: u64) -> Options {
    Options {
        cases,
        seed: 1,
        precisions: Precision::ALL.to_vec(),
        methods: vec![],
        classes: vec![],
    }
}

#[test]
fn print_audit_tables() {
    for shape in [&Torus as &dyn Shape, &TorusNormal] {
        let r = audit::run(
            shape,
            &opts(
                std::env::var("TORUS_CASES")
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(100),
            ),
        )
        .unwrap();
        println!("{}", audit::table(&r));
        println!("{}", audit::worst_cases(&r, 2));
    }
}
