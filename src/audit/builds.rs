//! The compiler's contraction, side by side (issue 49 item 3): one C routine compiled under
//! several named builds — GCC and Clang, contraction off, contraction on with FMA (as GPU and ARM
//! compilers build by default), `-O3 -ffast-math` — each loaded as a plugin ([`super::plugin`])
//! and given the same cases, judged by the exact oracle.
//!
//! Per build: the wrong verdicts and the worst error in ulps, as an audit row counts them; then,
//! against the first build (contraction off, the routine as its source says), the cases where
//! the build says hit and the first says miss or the reverse (flips), and the largest error a
//! build adds to a case the first answered right (ulps of this build minus ulps of the first).
//! Every flipped case is kept with its inputs as hex floats, replayable with `rayproof probe`
//! and the build line printed beside it.

use crate::numerics::Precision;
use crate::shapes::shape::{Answer, Method, Shape};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// One named build of the routine: the compiler and its flags (besides `-shared -fPIC`).
#[derive(Clone, Debug)]
pub struct Build {
    /// `gcc-off`, `clang-fma`, …
    pub name: String,
    /// The compiler's command.
    pub compiler: String,
    /// The flags that make the build what it is.
    pub flags: Vec<String>,
}

impl Build {
    fn new(name: &str, compiler: &str, flags: &[&str]) -> Build {
        Build {
            name: name.into(),
            compiler: compiler.into(),
            flags: flags.iter().map(|f| f.to_string()).collect(),
        }
    }

    /// The command that makes `out` from `source`, as a shell would take it.
    pub fn line(&self, source: &Path, out: &Path) -> String {
        let w = |s: &str| crate::audit::exec::shell_word(s);
        let mut v = vec![w(&self.compiler)];
        v.extend(self.flags.iter().map(|f| w(f)));
        v.extend(["-shared".into(), "-fPIC".into()]);
        v.push(w(&source.display().to_string()));
        v.extend(["-o".into(), w(&out.display().to_string()), "-lm".into()]);
        v.join(" ")
    }
}

/// A compiler's name in build names and library files: its file name (`/usr/bin/gcc-12` →
/// `gcc-12`), anything but letters, digits, `.`, `+` and `-` as `_`.
pub fn compiler_name(compiler: &str) -> String {
    let base = Path::new(compiler)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| compiler.to_string());
    base.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '+' | '-') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The standard builds, for each of `gcc` and `clang` given as installed: contraction off (the
/// baseline, first), contraction on with FMA, and `-O3 -ffast-math` with FMA. `fma`: whether
/// this machine runs FMA instructions (else the FMA builds are left out; on x86_64 `-mfma` is
/// what enables them).
pub fn standard(compilers: &[&str], fma: bool) -> Vec<Build> {
    let mfma: &[&str] = if cfg!(target_arch = "x86_64") {
        &["-mfma"]
    } else {
        &[]
    };
    let mut v = vec![];
    for &c in compilers {
        let name = compiler_name(c);
        v.push(Build::new(
            &format!("{name}-off"),
            c,
            &["-O2", "-ffp-contract=off"],
        ));
        if fma {
            let on: Vec<&str> = ["-O2", "-ffp-contract=fast"]
                .iter()
                .chain(mfma)
                .copied()
                .collect();
            v.push(Build::new(&format!("{name}-fma"), c, &on));
            let fast: Vec<&str> = ["-O3", "-ffast-math"].iter().chain(mfma).copied().collect();
            v.push(Build::new(&format!("{name}-fast-math"), c, &fast));
        }
    }
    v
}

/// Compiles `source` under `b` into `dir`: the library's path, or one line (the compiler's
/// reason) when it fails. The compiler runs under the crate's rules for outside commands (its own
/// process group, a deadline of 120 s, capped output).
pub fn compile(b: &Build, source: &Path, dir: &Path) -> Result<PathBuf, String> {
    let out = dir.join(format!("lib{}.so", b.name));
    let line = b.line(source, &out);
    crate::process::run_with_timeout(
        &format!("build {}", b.name),
        &line,
        None,
        String::new(),
        Duration::from_secs(120),
    )?;
    Ok(out)
}

/// One build of a C routine loaded as a plugin (`--source FILE.c:SYMBOL` of `audit`, `probe`,
/// `once`, `transform`, `report`), named `STEM.BUILD`; the directory of its library is kept while
/// it lives (a plugin's worker loads the library again after a crash). Its replay lines name the
/// source and the build, which every command with `--source` builds again.
pub struct Built {
    plugin: crate::audit::plugin::Plugin,
    replay: String,
    _dir: std::sync::Arc<crate::output::ScratchDir>,
}

impl Method for Built {
    fn name(&self) -> &str {
        self.plugin.name()
    }
    fn about(&self) -> &str {
        self.plugin.about()
    }
    fn replay(&self) -> Option<String> {
        Some(self.replay.clone())
    }
    fn identity(&self) -> Option<String> {
        self.plugin.identity()
    }
    fn answer(&self, prec: Precision, inputs: &[Vec<f64>]) -> Result<Vec<Answer>, String> {
        self.plugin.answer(prec, inputs)
    }
    fn finish(&self) -> Result<(), String> {
        self.plugin.finish()
    }
    fn own_nanos(&self, prec: Precision) -> Option<u64> {
        self.plugin.own_nanos(prec)
    }
}

impl Built {
    /// The precisions it answers (its symbol's).
    pub fn precisions(&self) -> Vec<Precision> {
        self.plugin.precisions()
    }
}

/// Compiles `source` (given as `spec`, `FILE.c:SYMBOL[:PREC]`) under each build of `list` into one
/// scratch directory and loads each build's `symbol` as a routine of `shape` named `name(build)`
/// (workers: `worker`, each batch under `timeout`), with each build's command line.
#[allow(clippy::too_many_arguments)]
pub fn load_all(
    spec: &str,
    source: &Path,
    symbol: &str,
    prec: Precision,
    list: &[Build],
    shape: &crate::shapes::shape::ShapeInfo,
    worker: &Path,
    timeout: Duration,
    name: &dyn Fn(&Build) -> String,
) -> Result<Vec<(Built, String)>, String> {
    let dir = std::sync::Arc::new(
        crate::output::ScratchDir::new("builds").map_err(|e| format!("{e:#}"))?,
    );
    let mut out = vec![];
    for b in list {
        let lib = compile(b, source, &dir.0)?;
        let line = b.line(source, &lib);
        let name = name(b);
        let lib_spec = format!("{}:{symbol}:{}", lib.display(), prec.name());
        let plugin =
            crate::audit::plugin::Plugin::load(&[lib_spec], Some(&name), shape, worker, timeout)?;
        let replay = format!(
            "--source {} --build {}",
            crate::audit::exec::shell_word(spec),
            b.name
        );
        out.push((
            Built {
                plugin,
                replay,
                _dir: dir.clone(),
            },
            line,
        ));
    }
    Ok(out)
}

/// One build's row.
#[derive(Clone, Debug, Serialize)]
pub struct BuildRow {
    /// The build's name.
    pub build: String,
    /// The command that made it.
    pub line: String,
    /// Cases with a valid input, given to every build.
    pub cases: u64,
    /// Wrong verdicts (and malformed answers) against the oracle.
    pub wrong: u64,
    /// The worst error of a right answer, in ulps.
    pub worst_ulps: u64,
    /// Cases where this build says hit and the first build miss, or the reverse.
    pub flips: u64,
    /// Of the flips, those where this build is the one the oracle agrees with.
    pub flips_right: u64,
    /// The largest number of ulps this build adds to a case both it and the first answered
    /// right (its error minus the first's).
    pub added_ulps: u64,
}

/// A case where the builds disagree on hit or miss.
#[derive(Clone, Debug, Serialize)]
pub struct Flip {
    /// The case's class.
    pub class: String,
    /// Hit (true) or miss per build, in the builds' order.
    pub hits: Vec<bool>,
    /// Whether the exact answer is a hit.
    pub exact_hit: bool,
    /// `rayproof probe …` of the case, its inputs as hex floats.
    pub probe: String,
}

/// The side-by-side comparison.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// The shape.
    pub shape: String,
    /// `f32` or `f64`.
    pub precision: String,
    /// One per build, the baseline first.
    pub rows: Vec<BuildRow>,
    /// Every case on which two builds disagree.
    pub flips: Vec<Flip>,
}

/// Gives `cases` cases of every class of `shape` in `prec` (seed `seed`, as `audit` makes them)
/// to each of `builds` (the first is the baseline) and compares them.
pub fn compare(
    shape: &dyn Shape,
    builds: &[(&str, String, &dyn Method)],
    prec: Precision,
    seed: u64,
    cases: u64,
) -> Result<Comparison, String> {
    use crate::audit::judge::judge;
    use crate::shapes::shape::Truth;
    let info = shape.info();
    let n = builds.len();
    let mut rows: Vec<BuildRow> = builds
        .iter()
        .map(|(name, line, _)| BuildRow {
            build: name.to_string(),
            line: line.clone(),
            cases: 0,
            wrong: 0,
            worst_ulps: 0,
            flips: 0,
            flips_right: 0,
            added_ulps: 0,
        })
        .collect();
    let methods: Vec<&dyn Method> = builds.iter().map(|(_, _, m)| *m).collect();
    let mut flips = vec![];
    for (class, &class_name) in info.classes.iter().enumerate() {
        let inputs: Vec<Vec<f64>> = (0..cases)
            .filter_map(|i| crate::shapes::shape::generate(shape, seed, class, prec, i))
            .collect();
        for chunk in inputs.chunks(crate::audit::run::CHUNK as usize) {
            let truths: Vec<Truth> = chunk.iter().map(|x| shape.oracle(x, prec)).collect();
            let answers = crate::audit::run::answers(&methods, prec, chunk)?;
            for (i, input) in chunk.iter().enumerate() {
                let Truth::Answer(exact) = &truths[i] else {
                    continue; // invalid input: not a question of contraction
                };
                let judged: Vec<_> = (0..n)
                    .map(|k| judge(&truths[i], &answers[k][i], info, prec))
                    .collect();
                let hits: Vec<bool> = (0..n).map(|k| answers[k][i].count > 0).collect();
                let exact_hit = exact.count > 0;
                for k in 0..n {
                    let r = &mut rows[k];
                    r.cases += 1;
                    r.wrong += judged[k].is_wrong() as u64;
                    if let Some(u) = judged[k].ulps() {
                        r.worst_ulps = r.worst_ulps.max(u);
                        if let Some(u0) = judged[0].ulps() {
                            r.added_ulps = r.added_ulps.max(u.saturating_sub(u0));
                        }
                    }
                    if hits[k] != hits[0] {
                        r.flips += 1;
                        r.flips_right += (hits[k] == exact_hit) as u64;
                    }
                }
                if hits.iter().any(|&h| h != hits[0]) {
                    flips.push(Flip {
                        class: class_name.to_string(),
                        hits,
                        exact_hit,
                        probe: crate::shapes::shape::probe_line_with(info.name, prec, None, input),
                    });
                }
            }
        }
    }
    for (_, _, m) in builds {
        m.finish()?;
    }
    Ok(Comparison {
        shape: info.name.to_string(),
        precision: prec.name().to_string(),
        rows,
        flips,
    })
}

/// Whether this machine runs the FMA builds: x86_64 with FMA (whatever `RAYPROOF_ISA` caps for
/// rayproof's own kernels: the user's library is another program), or AArch64, where it is base.
pub fn machine_has_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        cfg!(target_arch = "aarch64")
    }
}
