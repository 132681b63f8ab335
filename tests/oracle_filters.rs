//! The oracles' quick phases — the one-ulp box filter (`shapes::oracle::ulp_box`), which decides most
//! cases' ill-posedness in interval arithmetic before any exact move is made, and the roots
//! oracle's proved `f64` estimates (`shapes::oracle::quick_roots`) — must never change an answer: for
//! every routine family, class and precision, the oracle gives exactly the truth it gives with
//! every decision made exactly.

use rayproof::audit::run::generate;
use rayproof::numerics::Precision;
use rayproof::shapes::oracle::ulp_box::without_filter;
use rayproof::shapes::registry;

#[test]
fn the_quick_phases_never_change_an_oracles_truth() {
    for shape in registry() {
        let info = shape.info();
        // The torus's exact moves cost milliseconds each: fewer cases there
        let cases = if info.name.starts_with("torus") {
            40
        } else {
            150
        };
        let mut ill = 0;
        // A ray tangent to the torus's outer equator (r1 = 2, r2 = 1): a double root at t = 10,
        // ill-posed; the classes rarely draw one
        if info.name.starts_with("torus") {
            let v = [-10.0, 3.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0];
            for prec in Precision::ALL {
                let filtered = shape.oracle(&v, prec);
                assert_eq!(filtered, without_filter(|| shape.oracle(&v, prec)));
                match filtered {
                    rayproof::shapes::shape::Truth::Answer(e) => ill += e.ill_posed as u32,
                    t => panic!("{}: the tangent case is {t:?}", info.name),
                }
            }
        }
        for prec in Precision::ALL {
            for class in 0..info.classes.len() {
                for index in 0..cases {
                    let Some(v) = generate(shape, 7, class, prec, index) else {
                        continue;
                    };
                    let filtered = shape.oracle(&v, prec);
                    let exact = without_filter(|| shape.oracle(&v, prec));
                    assert_eq!(
                        filtered,
                        exact,
                        "{} {} {}: {}",
                        info.name,
                        prec.name(),
                        info.classes[class],
                        rayproof::shapes::shape::probe_line(info.name, prec, &v)
                    );
                    if let rayproof::shapes::shape::Truth::Answer(e) = exact {
                        ill += e.ill_posed as u32;
                    }
                }
            }
        }
        // The comparison means something only if both kinds of case occur (Newton's brackets
        // are drawn around one simple root: its cases here are all well-posed)
        println!("{}: {ill} ill-posed cases", info.name);
        let none_expected = ["newton", "rcp", "rsqrt", "reflect", "refract"];
        assert!(
            ill > 0 || none_expected.contains(&info.name),
            "{}: no ill-posed case to compare",
            info.name
        );
    }
}
