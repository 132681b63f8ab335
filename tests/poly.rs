//! Root finders, Newton, rcp/rsqrt: oracle checks on exact cases, audit rows against the
//! tolerance tables, the harness's teeth, proptest stability suites and invalid inputs.

use rayproof::audit::Precision;
use rayproof::routines::audit::{self, Options, ShapeReport};
use rayproof::routines::{roots, Shape};

fn report(shape: &dyn Shape, cases: u64) -> ShapeReport {
    audit::run(
        shape,
        &Options {
            cases,
            seed: 1,
            precisions: Precision::ALL.to_vec(),
            methods: vec![],
            classes: vec![],
        },
    )
    .expect("known selection")
}

#[test]
#[ignore = "prints the measured tables"]
fn print_tables() {
    let n: u64 = std::env::var("CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(300);
    for s in [&roots::QUADRATIC as &dyn Shape, &roots::CUBIC, &roots::QUARTIC, &roots::NEWTON] {
        let r = report(s, n);
        println!("{}", audit::table(&r));
        println!("{}", audit::worst_cases(&r, 2));
    }
}

#[test]
#[ignore = "timing probe"]
fn probe_speed() {
    let shape: &dyn Shape = match std::env::var("SHAPE").as_deref() {
        Ok("quartic") => &roots::QUARTIC,
        Ok("newton") => &roots::NEWTON,
        _ => &roots::CUBIC,
    };
    for (ci, class) in shape.classes().iter().enumerate() {
        for prec in Precision::ALL {
            let t = std::time::Instant::now();
            for i in 0..20 {
                let input = audit::generate(shape, 1, ci, prec, i).unwrap();
                eprintln!("{}", rayproof::routines::probe_line(shape, prec, &input));
                let t1 = std::time::Instant::now();
                let _ = shape.oracle(&input, prec);
                let t2 = std::time::Instant::now();
                for m in 0..shape.methods().len() {
                    let _ = shape.run(m, &input, prec);
                }
                let t3 = std::time::Instant::now();
                if (t3 - t1).as_millis() > 200 {
                    println!("slow {class} {prec:?} {i}: oracle {:?} methods {:?} {}", t2 - t1, t3 - t2, rayproof::routines::probe_line(shape, prec, &input));
                }
            }
            println!("{class} {prec:?}: {:?}", t.elapsed());
        }
    }
}
