//! The library's layers point one way (issue 34): numbers and process control at the bottom,
//! then the routine families, the audit and the renderer, golden-image CI, reports, and the
//! command line on top. Each `crate::…` and `super::…` path in `src/` is read as text (comments
//! left out) and resolved to the file it names; a folder that names a folder at its own level or
//! above, or a circle of files, fails here with the file and the line that made it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Top-level modules from the bottom up: a module may use only modules of a lower layer (and
/// itself). `cli/` and `main.rs` are the binary: they reach the library as `rayproof::…`.
const LAYERS: &[&[&str]] = &[
    &["numerics", "input", "process"],
    &["output"],
    &["shapes", "images", "implicit"],
    &["audit", "render"],
    &["golden"],
    &["report"],
];

fn layer(top: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&top))
}

/// A path as the tree names it (`src/audit/run.rs`).
fn shown(p: &Path) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    p.strip_prefix(root).unwrap_or(p).display().to_string()
}

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("src/ is readable") {
        let p = e.expect("a directory entry").path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module path of a source file (`src/audit/run.rs` → `["audit", "run"]`).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut m: Vec<String> = rel
        .iter()
        .map(|c| c.to_string_lossy().into_owned())
        .collect();
    if m.last().is_some_and(|l| l == "mod" || l == "lib") {
        m.pop();
    }
    m
}

/// The file of a module path: the longest prefix that is a file in the tree.
fn file_of(files: &BTreeMap<Vec<String>, PathBuf>, path: &[String]) -> Option<PathBuf> {
    (1..=path.len())
        .rev()
        .find_map(|n| files.get(&path[..n]).cloned())
}

/// The text without comments (line comments and doc comments; block comments are not used)
/// and without the unit tests at the end of a file (`#[cfg(test)] mod …`, whose `super` is the
/// file itself).
fn code(text: &str) -> String {
    let text = text.find("#[cfg(test)]\nmod ").map_or(text, |i| &text[..i]);
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every `crate::a::b` / `super::a` path in `text` with the line it starts on, a brace group
/// (`crate::a::{b, c::d}`) giving one path per member.
fn paths(text: &str) -> Vec<(usize, Vec<String>)> {
    let mut out = vec![];
    let b = text.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut i = 0;
    while i < b.len() {
        let start_ok = i == 0 || !(ident(b[i - 1]) || b[i - 1] == b':' || b[i - 1] == b'$');
        let head = ["crate::", "super::"]
            .into_iter()
            .find(|h| b[i..].starts_with(h.as_bytes()));
        if !start_ok || head.is_none() {
            i += 1;
            continue;
        }
        let line = text[..i].matches('\n').count() + 1;
        let mut segs = vec![];
        let mut j = i;
        loop {
            let s = j;
            while j < b.len() && ident(b[j]) {
                j += 1;
            }
            if j > s {
                segs.push(text[s..j].to_string());
            }
            if text[j..].starts_with("::") {
                j += 2;
                if text[j..].starts_with('{') {
                    let end = text[j..].find('}').map_or(b.len(), |e| j + e);
                    for member in text[j + 1..end].split(',') {
                        let m: Vec<String> = member
                            .split("::")
                            .map(|s| s.trim().trim_start_matches('{').trim().to_string())
                            .take_while(|s| !s.is_empty() && s.bytes().all(ident))
                            .collect();
                        let mut p = segs.clone();
                        p.extend(m.into_iter().filter(|s| s != "self"));
                        out.push((line, p));
                    }
                    j = end;
                    segs.clear();
                    break;
                }
            } else {
                break;
            }
        }
        if !segs.is_empty() {
            out.push((line, segs));
        }
        i = j.max(i + 1);
    }
    out
}

struct Arrow {
    from: PathBuf,
    to: PathBuf,
    line: usize,
}

fn arrows() -> Vec<Arrow> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut list = vec![];
    sources(&src, &mut list);
    // The library only: the binary (main.rs, cli/) sits on top of everything
    list.retain(|f| {
        let m = module_of(&src, f);
        !(m == ["main"] || m.first().is_some_and(|t| t == "cli"))
    });
    let files: BTreeMap<Vec<String>, PathBuf> = list
        .iter()
        .map(|f| (module_of(&src, f), f.clone()))
        .collect();
    let mut out = vec![];
    for f in &list {
        let me = module_of(&src, f);
        for (line, p) in paths(&code(&std::fs::read_to_string(f).unwrap())) {
            // `super` is the parent of the file's module (for a.rs and for a/mod.rs alike)
            let mut abs: Vec<String> = match p[0].as_str() {
                "crate" => vec![],
                _ => me[..me.len().saturating_sub(1)].to_vec(),
            };
            for s in &p[1..] {
                if s == "super" {
                    abs.pop();
                } else {
                    abs.push(s.clone());
                }
            }
            if let Some(to) = file_of(&files, &abs) {
                if &to != f {
                    out.push(Arrow {
                        from: f.clone(),
                        to,
                        line,
                    });
                }
            }
        }
    }
    out
}

fn top(src: &Path, f: &Path) -> String {
    module_of(src, f).first().cloned().unwrap_or_default()
}

#[test]
fn folders_only_use_the_layers_below_them() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut bad = vec![];
    let all = arrows();
    for a in &all {
        let (from, to) = (top(&src, &a.from), top(&src, &a.to));
        if from == to || to.is_empty() || from.is_empty() {
            continue;
        }
        let (lf, lt) = (layer(&from), layer(&to));
        let ok = matches!((lf, lt), (Some(lf), Some(lt)) if lt < lf);
        if !ok {
            bad.push(format!(
                "{}:{} uses {} ({from} is layer {lf:?}, {to} layer {lt:?})",
                shown(&a.from),
                a.line,
                shown(&a.to)
            ));
        }
    }
    assert!(
        all.len() > 300,
        "the reader found only {} arrows: it no longer reads the tree",
        all.len()
    );
    assert!(
        bad.is_empty(),
        "imports that run up or across:\n{}",
        bad.join("\n")
    );
}

#[test]
fn no_circle_of_files() {
    let mut next: BTreeMap<PathBuf, BTreeSet<PathBuf>> = BTreeMap::new();
    for a in arrows() {
        next.entry(a.from).or_default().insert(a.to);
    }
    // Depth-first search for a back edge; a file's own `mod` children are not arrows (only paths
    // written `crate::…` / `super::…` are)
    fn visit(
        f: &PathBuf,
        next: &BTreeMap<PathBuf, BTreeSet<PathBuf>>,
        state: &mut BTreeMap<PathBuf, u8>,
        stack: &mut Vec<PathBuf>,
    ) -> Option<Vec<PathBuf>> {
        state.insert(f.clone(), 1);
        stack.push(f.clone());
        for t in next.get(f).into_iter().flatten() {
            match state.get(t) {
                Some(1) => {
                    let i = stack.iter().position(|s| s == t).unwrap();
                    let mut c = stack[i..].to_vec();
                    c.push(t.clone());
                    return Some(c);
                }
                Some(_) => {}
                None => {
                    if let Some(c) = visit(t, next, state, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        state.insert(f.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for f in next.keys() {
        if !state.contains_key(f) {
            let c = visit(f, &next, &mut state, &mut vec![]);
            assert!(
                c.is_none(),
                "a circle of files: {}",
                c.unwrap()
                    .iter()
                    .map(|p| shown(p))
                    .collect::<Vec<_>>()
                    .join(" -> ")
            );
        }
    }
}

#[test]
fn the_reader_resolves_paths_and_groups() {
    let p = paths(
        "use crate::audit::{run::generate, shape::{Answer, Shape}};\nlet x = super::a::b(1);",
    );
    assert_eq!(
        p[0],
        (
            1,
            vec![
                "crate".into(),
                "audit".into(),
                "run".into(),
                "generate".into()
            ]
        )
    );
    assert_eq!(
        p[1],
        (
            1,
            vec![
                "crate".into(),
                "audit".into(),
                "shape".into(),
                "Answer".into()
            ]
        )
    );
    assert!(p.iter().any(|(l, s)| *l == 2 && s == &["super", "a", "b"]));
    assert!(paths("$crate::numerics::Precision").is_empty());
}
