//! Auditing code that cannot be called (a GPU shader, a routine behind a build system): `rayproof
//! cases` writes an audit's cases to a text file, the user's code answers them in a second file,
//! and `rayproof score` judges the answers with the oracle as the audit would, through the same
//! rows, tables, JSON and verdicts.
//!
//! **Cases file.** A header line, then one case per line:
//! ```text
//! # rayproof cases 1 shape=sphere seed=1 cases=2000
//! f32 tangent 17 0x1p+0 -0x1.8p-3 …
//! ```
//! Each line is the precision, the class, the case's index within its class, and the shape's
//! inputs in order as C99 hex floats (`inf`, `-inf`, `nan` for the invalid class), exact in the
//! case's precision.
//!
//! **Answers file.** One line per case line, in the same order: the count, then the values,
//! e.g. `1 0x1.4p+2` or `2 -1.5 3` or `0` (decimal or hex floats, `nan`/`inf` allowed; an f32
//! answer is rounded once to f32). Blank lines and lines starting with `#` are skipped in both
//! files.
//!
//! # Example
//!
//! The judgement is exactly that of a direct audit of the same routine (`tests/offline.rs` checks
//! the JSON byte for byte):
//!
//! ```sh
//! rayproof cases --shape sphere --class far_small,tangent --precision f32 --cases 2000 -o cases.txt
//! #   cases.txt: a header, then per case "PRECISION CLASS INDEX INPUT…" in hex floats
//! your-renderer-test < cases.txt > answers.txt
//! #   answers.txt: per case, in order, "COUNT VALUE…" (decimal or hex; e.g. "1 0x1.4p+2", "0")
//! rayproof score --cases cases.txt --answers answers.txt --method mine --tolerances mine.toml
//! ```
//!
//! `score` prints the same table and verdict and takes `--json`, `--markdown` and `--worst`. A
//! cases file whose case is not the one this rayproof generates, a missing or extra answer, or a
//! malformed number gives one line naming the file and line, and exit 2.

use super::contract::{number, parse_line};
use super::plan::{Options, Plan};
use super::run::generate;
use crate::numerics::Precision;
use crate::shapes::shape::{hex_text, Answer, PerCase, Shape};
use std::collections::HashMap;

/// The tag and version on the first line of a cases file.
pub const CASES_HEADER: &str = "# rayproof cases 1";

/// Writes the cases of a plan's single shape as the cases file, line by line (memory does not
/// grow with the case count); returns how many cases it wrote. `exec_format`: the lines an
/// `--exec` child reads instead (precision and inputs, no header, no class or index), in the
/// same order, so one program can answer both.
pub fn write_cases(
    plan: &Plan,
    exec_format: bool,
    out: &mut dyn std::io::Write,
) -> std::io::Result<u64> {
    let p = &plan.shapes[0];
    let info = p.shape.info();
    if !exec_format {
        writeln!(
            out,
            "{CASES_HEADER} shape={} seed={} cases={}",
            info.name, plan.seed, p.cases
        )?;
    }
    let mut n = 0;
    for &prec in &plan.precisions {
        for &class in &p.classes {
            for index in 0..p.cases {
                let Some(input) = generate(p.shape, plan.seed, class, prec, index) else {
                    continue;
                };
                n += 1;
                if exec_format {
                    out.write_all(super::exec::case_line(prec, &input).as_bytes())?;
                    continue;
                }
                let vals: Vec<String> = input.iter().map(|&x| hex_text(x)).collect();
                writeln!(
                    out,
                    "{} {} {index} {}",
                    prec.name(),
                    info.classes[class],
                    vals.join(" ")
                )?;
            }
        }
    }
    Ok(n)
}

/// A cases file, read back.
pub struct CasesFile {
    /// The shape the cases are for.
    pub shape: &'static dyn Shape,
    /// The seed the cases were drawn with.
    pub seed: u64,
    /// Cases per class and precision.
    pub cases: u64,
    /// `(precision, class index, case index, inputs)` per line, in file order.
    pub lines: Vec<(Precision, usize, u64, Vec<f64>)>,
}

/// Lines that carry content, with their 1-based numbers.
fn content(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// Reads a cases file; the error is one line naming the file's line.
pub fn read_cases(
    text: &str,
    file: &str,
    shape_by_name: impl Fn(&str) -> Option<&'static dyn Shape>,
) -> Result<CasesFile, String> {
    // The header: shape, seed, cases per class
    let head = text.lines().next().unwrap_or("");
    let fields: HashMap<&str, &str> = head
        .strip_prefix(CASES_HEADER)
        .ok_or_else(|| format!("{file}: not a rayproof cases file (no \"{CASES_HEADER}\" line)"))?
        .split_whitespace()
        .filter_map(|f| f.split_once('='))
        .collect();
    let get = |k: &str| {
        fields
            .get(k)
            .copied()
            .ok_or_else(|| format!("{file} line 1: no {k}="))
    };
    let shape = shape_by_name(get("shape")?)
        .ok_or_else(|| format!("{file} line 1: unknown shape '{}'", fields["shape"]))?;
    let int = |k: &str| -> Result<u64, String> {
        get(k)?
            .parse()
            .map_err(|_| format!("{file} line 1: {k}= is not a whole number"))
    };
    let (seed, cases) = (int("seed")?, int("cases")?);
    // No case judged is no verdict: never a pass
    if cases == 0 {
        return Err(format!(
            "{file} line 1: cases=0: nothing to judge (a verdict needs at least one case)"
        ));
    }
    // The cases
    let info = shape.info();
    let mut lines = vec![];
    for (n, l) in content(text) {
        let at = |what: String| format!("{file} line {n}: {what}");
        let w: Vec<&str> = l.split_whitespace().collect();
        if w.len() != 3 + info.args.len() {
            return Err(at(format!(
                "{} fields where a {} case has {} (precision, class, index, {})",
                w.len(),
                info.name,
                3 + info.args.len(),
                info.args.join(" ")
            )));
        }
        let prec = match w[0] {
            "f32" => Precision::F32,
            "f64" => Precision::F64,
            p => return Err(at(format!("unknown precision '{p}'"))),
        };
        let class = info
            .classes
            .iter()
            .position(|c| *c == w[1])
            .ok_or_else(|| at(format!("unknown class '{}'", w[1])))?;
        let index: u64 = w[2]
            .parse()
            .map_err(|_| at(format!("'{}' is not a case index", w[2])))?;
        let input = w[3..]
            .iter()
            .map(|s| number(s).ok_or_else(|| at(format!("'{s}' is not a number"))))
            .collect::<Result<Vec<f64>, String>>()?;
        lines.push((prec, class, index, input));
    }
    Ok(CasesFile {
        shape,
        seed,
        cases,
        lines,
    })
}

/// Reads an answers file: one answer per case, in order; the error is one line.
pub fn read_answers(text: &str, file: &str, cases: &CasesFile) -> Result<Vec<Answer>, String> {
    let mut out = vec![];
    for (n, l) in content(text) {
        let at = |what: String| format!("{file} line {n}: {what}");
        let Some(&(prec, _, _, _)) = cases.lines.get(out.len()) else {
            return Err(at(format!(
                "more answers than the {} cases",
                cases.lines.len()
            )));
        };
        // The one parser of the text protocol (values rounded once to the case's precision);
        // the contract is the judge's
        out.push(parse_line(l, prec).map_err(at)?);
    }
    if out.len() < cases.lines.len() {
        return Err(format!(
            "{file}: {} answers for {} cases",
            out.len(),
            cases.lines.len()
        ));
    }
    Ok(out)
}

/// Answers given ahead of time: the method that returns them, by the case's inputs.
pub struct Answers {
    name: String,
    by_input: HashMap<(Precision, Vec<u64>), Answer>,
}

impl PerCase for Answers {
    fn name(&self) -> &str {
        &self.name
    }
    fn run(&self, input: &[f64], prec: Precision) -> Answer {
        let key = (prec, input.iter().map(|x| x.to_bits()).collect());
        self.by_input.get(&key).cloned().unwrap_or_default()
    }
}

/// The audit of the answers: the plan of the cases file with one method, `name`, that returns
/// the answers. Every case of the plan must be in the file as generated (the same inputs, bit
/// for bit), so the judgement is the one a direct audit of the same routine gives.
pub fn score_plan(cases: &CasesFile, answers: Vec<Answer>, name: &str) -> Result<Plan, String> {
    let info = cases.shape.info();
    // Which precisions and classes the file covers, in its order
    let (mut precisions, mut classes) = (vec![], vec![]);
    for &(p, c, _, _) in &cases.lines {
        if !precisions.contains(&p) {
            precisions.push(p);
        }
        if !classes.contains(&c) {
            classes.push(c);
        }
    }
    let mut plan = Plan::new(&Options {
        shapes: vec![info.name.to_string()],
        classes: classes
            .iter()
            .map(|&c| info.classes[c].to_string())
            .collect(),
        precisions,
        cases: Some(cases.cases),
        seed: cases.seed,
        ..Options::default()
    })?;
    // Every case of the plan has its line, as generated, bit for bit
    let mut given: HashMap<(Precision, usize, u64), (&Vec<f64>, Answer)> = HashMap::new();
    for ((prec, class, index, input), answer) in cases.lines.iter().zip(answers) {
        if given
            .insert((*prec, *class, *index), (input, answer))
            .is_some()
        {
            return Err(format!(
                "case {} {} {index} is given twice",
                prec.name(),
                info.classes[*class]
            ));
        }
    }
    let mut by_input = HashMap::new();
    for &prec in &plan.precisions {
        for &class in &plan.shapes[0].classes {
            for index in 0..cases.cases {
                let Some(want) = generate(cases.shape, cases.seed, class, prec, index) else {
                    continue;
                };
                let at = format!("case {} {} {index}", prec.name(), info.classes[class]);
                let (input, answer) = given
                    .remove(&(prec, class, index))
                    .ok_or_else(|| format!("{at} is missing from the cases file"))?;
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
                if bits(input) != bits(&want) {
                    return Err(format!(
                        "{at} is not the case this rayproof generates for seed {} (another version, or an edited file?)",
                        cases.seed
                    ));
                }
                by_input.insert((prec, bits(&want)), answer);
            }
        }
    }
    if let Some((prec, class, index)) = given.keys().next() {
        return Err(format!(
            "case {} {} {index} is not in the selection (seed {}, {} per class)",
            prec.name(),
            info.classes[*class],
            cases.seed,
            cases.cases
        ));
    }
    plan.shapes[0].methods = vec![Box::new(Answers {
        name: name.to_string(),
        by_input,
    })];
    Ok(plan)
}
