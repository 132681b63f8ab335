//! `rayproof cases` + `rayproof score`: code that cannot be called answers a file of cases, and
//! the score is exactly the judgement of a direct audit of the same routine.

use crate::common::{rayproof, scratch};
use rayproof::audit::{probe_line, Shape};
use rayproof::numerics::real::parse_f64;
use rayproof::numerics::Precision;
use rayproof::shapes::shape_by_name;
use std::path::Path;
use std::process::Output;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Answers every case line with built-in method `method` of the shape, as outside code would.
fn answer(shape: &dyn Shape, method: &str, cases: &str) -> String {
    let m = shape
        .info()
        .methods
        .iter()
        .position(|x| x.name == method)
        .unwrap();
    let mut out = String::from("# answers\n");
    for l in cases.lines().filter(|l| !l.starts_with('#')) {
        let w: Vec<&str> = l.split_whitespace().collect();
        let prec = if w[0] == "f32" {
            Precision::F32
        } else {
            Precision::F64
        };
        let input: Vec<f64> = w[3..]
            .iter()
            .map(|x| {
                if *x == "nan" {
                    f64::NAN
                } else {
                    parse_f64(x).unwrap()
                }
            })
            .collect();
        let a = shape.run(m, &input, prec);
        let vals: Vec<String> = a
            .values
            .iter()
            .map(|&v| rayproof::shapes::shape::hex_text(v))
            .collect();
        out += &format!("{} {}\n", a.count, vals.join(" "));
    }
    out
}

#[test]
fn cases_and_score_give_exactly_the_direct_audit() {
    for (shape, method, classes) in [
        ("sphere", "algebraic", "far_small,tangent,invalid"),
        ("triangle", "moller_trumbore", "vertex,tiny,generic"),
    ] {
        let dir = scratch(shape);
        let (cases, answers) = (dir.join("cases.txt"), dir.join("answers.txt"));
        let (scored, direct) = (dir.join("scored.json"), dir.join("direct.json"));
        let sel = [
            "--shape", shape, "--class", classes, "--cases", "300", "--seed", "4",
        ];
        // Write the cases, answer them outside, score the answers
        let mut args = vec!["cases"];
        args.extend(sel);
        args.extend(["-o", s(&cases)]);
        let o = rayproof(&args);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let text = std::fs::read_to_string(&cases).unwrap();
        std::fs::write(
            &answers,
            answer(shape_by_name(shape).unwrap(), method, &text),
        )
        .unwrap();
        let score = rayproof(&[
            "score",
            "--cases",
            s(&cases),
            "--answers",
            s(&answers),
            "--method",
            method,
            "--json",
            s(&scored),
        ]);
        // The same method audited directly
        let mut args = vec!["audit", "--method", method, "--json", s(&direct)];
        args.extend(sel);
        let audit = rayproof(&args);
        assert_eq!(score.status.code(), audit.status.code());
        assert_eq!(
            std::fs::read_to_string(&scored).unwrap(),
            std::fs::read_to_string(&direct).unwrap(),
            "{shape}: the score differs from the direct audit"
        );
        // ... and it found the method's known failures
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&scored).unwrap()).unwrap();
        let shown = v["shapes"][0]["rows"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|r| r["verdict"]["status"] == "known_failure")
            .count();
        assert!(shown > 0, "{shape}: no known failure shown");
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// A refusal: exit 2 and one line naming `what`.
fn refused(o: &Output, what: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains(what), "'{what}' not in {err}");
}

#[test]
fn bad_files_are_refused_with_one_line() {
    let dir = scratch("offline-bad");
    let cases = dir.join("cases.txt");
    let o = rayproof(&[
        "cases",
        "--shape",
        "box",
        "--class",
        "generic",
        "--cases",
        "5",
        "--precision",
        "f32",
        "-o",
        s(&cases),
    ]);
    assert_eq!(o.status.code(), Some(0));
    let text = std::fs::read_to_string(&cases).unwrap();
    let put = |name: &str, body: &str| {
        let p = dir.join(name);
        std::fs::write(&p, body).unwrap();
        p
    };
    let score = |c: &Path, a: &Path| rayproof(&["score", "--cases", s(c), "--answers", s(a)]);
    let good = put("good.txt", &"0\n".repeat(5));
    assert!(score(&cases, &good).status.code().is_some_and(|c| c <= 1));
    refused(
        &score(&cases, &put("short.txt", "0\n0\n")),
        "2 answers for 5 cases",
    );
    refused(
        &score(&cases, &put("long.txt", &"0\n".repeat(6))),
        "more answers than the 5 cases",
    );
    refused(
        &score(&cases, &put("count.txt", "x\n0\n0\n0\n0\n")),
        "line 1: 'x' is not a count",
    );
    refused(
        &score(&cases, &put("value.txt", "0\n1 zz\n0\n0\n0\n")),
        "line 2: 'zz' is not a number",
    );
    refused(
        &score(&cases, &put("negative.txt", "0\n-1 4\n0\n0\n0\n")),
        "line 2: '-1' is not a count",
    );
    // A hit without its value is an answer, a malformed one (tests/contract.rs): the row fails
    let o = score(&cases, &put("empty.txt", "0\n1\n0\n0\n0\n"));
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    refused(
        &score(&put("notcases.txt", "hello\n"), &good),
        "not a rayproof cases file",
    );
    // No case is no verdict (it was "verdict: pass")
    refused(
        &score(
            &put(
                "zero.txt",
                "# rayproof cases 1 shape=sphere seed=1 cases=0\n",
            ),
            &put("none.txt", ""),
        ),
        "cases=0: nothing to judge",
    );
    // An edited case is not the case rayproof generates
    let edited: String = text.replacen(" 0x", " -0x", 1);
    refused(
        &score(&put("edited.txt", &edited), &good),
        "is not the case this rayproof generates",
    );
    // A case missing
    let mut lines: Vec<&str> = text.lines().collect();
    lines.pop();
    refused(
        &score(
            &put("missing.txt", &(lines.join("\n") + "\n")),
            &put("four.txt", &"0\n".repeat(4)),
        ),
        "is missing",
    );
    refused(&score(&dir.join("absent.txt"), &good), "cannot read");
    let o = rayproof(&["cases", "--shape", "hexagon", "-o", s(&dir.join("x.txt"))]);
    refused(&o, "unknown shape 'hexagon'");
    let _ = probe_line("box", Precision::F32, &[]);
    std::fs::remove_dir_all(&dir).ok();
}
