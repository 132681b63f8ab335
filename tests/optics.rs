use rayproof::audit::Precision;
use rayproof::routines::audit::{self, Options};
use rayproof::routines::optics::{Reflect, Refract};
use rayproof::routines::Shape;

#[test]
fn print_audit() {
    for s in [&Reflect as &dyn Shape, &Refract] {
        let r = audit::run(s, &Options { cases: 1000, seed: 1, precisions: Precision::ALL.to_vec(), methods: vec![], classes: vec![] }).unwrap();
        println!("{}", audit::table(&r));
        println!("{}", audit::worst_cases(&r, 1));
    }
}
