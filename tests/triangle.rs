use rayproof::audit::Precision;
use rayproof::routines::audit::{self, Options};
use rayproof::routines::triangle::{self, Triangle};

#[test]
fn print_audit() {
    let r = audit::run(&Triangle, &Options { cases: 300, seed: 1, precisions: Precision::ALL.to_vec(), methods: vec![], classes: vec![] }).unwrap();
    println!("{}", audit::table(&r));
    println!("{}", audit::worst_cases(&r, 2));
    for p in Precision::ALL { for row in triangle::watertight_test(1, 2000, p) { println!("{row:?}"); } }
    for p in Precision::ALL { for row in triangle::reintersection(1, 20, p) { println!("{row:?}"); } }
}
