//! The options that bring routines from outside the crate (`--plugin`, `--exec`, `--name`,
//! `--timeout`) and the routines they make: for `audit`, `probe`, `report` and `spawn`.

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use rayproof::numerics::Precision;

/// Routines from outside the crate, for `audit`, `probe`, `report` and `spawn` (and spawn rules
/// and intersectors made from their specs).
#[derive(Args, Debug, Clone)]
pub struct OutsideArgs {
    /// Audit a routine of a shared library through its C ABI, in batches: PATH:SYMBOL, with
    /// :f32 or :f64 unless the symbol ends so. Repeat it: symbols of one library that differ
    /// only in their _f32/_f64 suffix are one routine in two precisions; others are routines
    /// of their own, side by side. `rayproof header` prints the C signatures.
    #[arg(long, value_name = "PATH:SYMBOL")]
    pub plugin: Vec<String>,
    /// Audit a routine run by this command (`sh -c CMD`): cases as lines on its stdin, one
    /// answer line per case on its stdout (`rayproof header --exec`). Repeatable.
    #[arg(long, value_name = "CMD")]
    pub exec: Vec<String>,
    /// The outside routines' names in reports and tolerance rules, in order: the plugins' (in
    /// the order of their first --plugin), then the --exec commands' (default: the symbol
    /// without its precision suffix; `exec`, `exec2`, …).
    #[arg(long)]
    pub name: Vec<String>,
    /// Audit a C routine under several builds side by side: FILE.c:SYMBOL (the plugin
    /// signature, `rayproof header`; the precision from the symbol's `_f32`/`_f64` suffix or a
    /// third field). Each of the standard builds of `rayproof builds` (gcc and clang where
    /// installed; contraction off, contraction on with FMA, `-O3 -ffast-math`) is a routine of its
    /// own, named SYMBOL-STEM.BUILD (`tri.gcc-fma`); the build lines are printed. Repeatable.
    #[arg(long, value_name = "FILE.c:SYMBOL")]
    pub source: Vec<String>,
    /// Only these builds of each --source (`gcc-off`, `clang-fma`, …; repeat or comma-separate).
    #[arg(long, value_delimiter = ',', requires = "source")]
    pub build: Vec<String>,
    /// Run each --exec command once per batch of cases, its input closed at the batch's end
    /// (for a child that writes only when its input ends). Default: one child for the run when
    /// it answers its whole first batch with its input open, else one per batch.
    #[arg(long, requires = "exec", conflicts_with = "exec_keep")]
    pub exec_per_batch: bool,
    /// Keep one child per --exec command for the whole run, whatever its first batch shows (it
    /// must flush each answer line).
    #[arg(long, requires = "exec")]
    pub exec_keep: bool,
    /// Seconds a batch of cases may take before an --exec child or a --plugin worker is
    /// killed (the audit then stops, exit 4).
    #[arg(long = "timeout", alias = "exec-timeout", default_value_t = 60.0, value_parser = parse_seconds)]
    pub exec_timeout: f64,
}

/// An outside routine, and for a plugin the precisions it has symbols for.
pub type Outside = (
    Box<dyn rayproof::audit::Method + Send>,
    Option<Vec<Precision>>,
);

impl OutsideArgs {
    /// The routines of one-string specs (`--spawn-rule`, `--intersector`): `exec:CMD` and
    /// `plugin:PATH:SYMBOL` made into the options of this struct (named by `names`, each batch
    /// under `timeout` seconds), and the other specs, built-in names, returned as they are.
    pub fn from_specs(specs: &[String], names: &[String], timeout: f64) -> (Vec<String>, Self) {
        let mut builtin = vec![];
        let mut theirs = OutsideArgs {
            plugin: vec![],
            exec: vec![],
            name: names.to_vec(),
            source: vec![],
            build: vec![],
            exec_per_batch: false,
            exec_keep: false,
            exec_timeout: timeout,
        };
        for r in specs {
            if let Some(cmd) = r.strip_prefix("exec:") {
                theirs.exec.push(cmd.to_string());
            } else if let Some(spec) = r.strip_prefix("plugin:") {
                theirs.plugin.push(spec.to_string());
            } else {
                builtin.push(r.clone());
            }
        }
        (builtin, theirs)
    }

    /// The precisions of a run: those asked for (`asked`; none: both), which every plugin must
    /// have a symbol for; when none is asked, those every plugin has.
    pub fn precisions(asked: &[Precision], outside: &[Outside]) -> Result<Vec<Precision>> {
        let mut precs = match asked.is_empty() {
            true => Precision::ALL.to_vec(),
            false => asked.to_vec(),
        };
        for (m, has) in outside {
            if let Some(has) = has {
                match asked.is_empty() {
                    true => precs.retain(|p| has.contains(p)),
                    false => {
                        if let Some(p) = precs.iter().find(|p| !has.contains(p)) {
                            bail!("--plugin {}: no {} symbol", m.name(), p.name());
                        }
                    }
                }
            }
        }
        if precs.is_empty() {
            bail!("no precision every routine answers: give --precision");
        }
        Ok(precs)
    }

    /// The files the outside routines are made of, inputs no output may replace: each plugin's
    /// library, and each word of an --exec command that names an existing regular file (the
    /// script or program it runs; quotes stripped, words split at spaces).
    pub fn input_files(&self) -> Vec<std::path::PathBuf> {
        let plugins = self
            .plugin
            .iter()
            .filter_map(|spec| rayproof::audit::plugin::parse_spec(spec).ok())
            .map(|(path, _, _)| std::path::PathBuf::from(path));
        // Each word, the value of an `--opt=FILE` word, and each under the directories a `cd`
        // in the command moves to (`cd tools && ./guard`)
        let words = self.exec.iter().flat_map(|cmd| {
            let words: Vec<&str> = cmd
                .split_whitespace()
                .map(|w| w.trim_matches(|c| c == '\'' || c == '"'))
                .collect();
            let dirs: Vec<&str> = words
                .windows(2)
                .filter(|w| w[0] == "cd")
                .map(|w| w[1])
                .collect();
            words
                .iter()
                .flat_map(|w| [*w, w.rsplit_once('=').map_or("", |(_, v)| v)])
                .filter(|w| !w.is_empty())
                .flat_map(|w| {
                    std::iter::once(std::path::PathBuf::from(w))
                        .chain(dirs.iter().map(move |d| std::path::Path::new(d).join(w)))
                })
                .collect::<Vec<_>>()
        });
        let sources = self
            .source
            .iter()
            .filter_map(|spec| rayproof::audit::plugin::parse_spec(spec).ok())
            .map(|(path, _, _)| std::path::PathBuf::from(path));
        plugins
            .chain(words)
            .chain(sources)
            .filter(|p| p.metadata().is_ok_and(|m| m.is_file()))
            .collect()
    }

    /// Refuses a `--json` (or any output file) that is, or would replace, one of the routines'
    /// files ([`OutsideArgs::input_files`]), that is named twice or cannot be written.
    pub fn check_outputs(&self, files: &[&std::path::Path]) -> Result<()> {
        let inputs = self.input_files();
        let inputs: Vec<&std::path::Path> = inputs.iter().map(|p| p.as_path()).collect();
        rayproof::output::check_outputs(files, &[], &inputs)
    }

    /// [`OutsideArgs::check_outputs`] of a `--json` file, which may replace only JSON
    /// ([`rayproof::output::check_json_target`]).
    pub fn check_json(&self, p: &std::path::Path) -> Result<()> {
        self.check_outputs(&[p])?;
        rayproof::output::check_json_target(p)
    }

    /// Whether any outside routine is given.
    pub fn any(&self) -> bool {
        !self.plugin.is_empty() || !self.exec.is_empty() || !self.source.is_empty()
    }

    /// The outside routines, for a shape (or spawn rules: `rayproof::audit::robustness::spawn::INFO`),
    /// in order: plugins, then commands.
    pub fn methods(&self, shape: &rayproof::shapes::shape::ShapeInfo) -> Result<Vec<Outside>> {
        self.methods_with(shape, false)
    }

    /// [`OutsideArgs::methods`] for a run of one batch (`probe`): an `--exec` child then gets
    /// the batch and the end of its input at once (unless `--exec-keep`).
    pub fn methods_with(
        &self,
        shape: &rayproof::shapes::shape::ShapeInfo,
        one_batch: bool,
    ) -> Result<Vec<Outside>> {
        use rayproof::audit::plugin::{parse_spec, Plugin};
        let timeout = std::time::Duration::from_secs_f64(self.exec_timeout);
        // Plugin specs grouped into routines: one library's symbols that differ in precision
        let mut groups: Vec<((String, String), Vec<String>)> = vec![];
        for spec in &self.plugin {
            let (path, symbol, _) = parse_spec(spec).map_err(|e| anyhow!(e))?;
            let stem = symbol
                .trim_end_matches("_f32")
                .trim_end_matches("_f64")
                .to_string();
            match groups
                .iter_mut()
                .find(|(k, _)| *k == (path.clone(), stem.clone()))
            {
                Some((_, v)) => v.push(spec.clone()),
                None => groups.push(((path, stem), vec![spec.clone()])),
            }
        }
        let routines = groups.len() + self.exec.len();
        if self.name.len() > routines {
            bail!(
                "--name given {} times for {routines} outside routine(s)",
                self.name.len()
            );
        }
        let mut names = self.name.iter().map(String::as_str);
        let mut out: Vec<Outside> = vec![];
        if !groups.is_empty() {
            let worker =
                std::env::current_exe().context("cannot find rayproof's own executable")?;
            for (_, specs) in &groups {
                let p = Plugin::load(&specs[..], names.next(), shape, &worker, timeout)
                    .map_err(|e| anyhow!(e))?;
                let has = p.precisions();
                out.push((Box::new(p), Some(has)));
            }
        }
        for spec in &self.source {
            for (m, has) in super::builds::built(spec, &self.build, shape, timeout)? {
                out.push((m, Some(has)));
            }
        }
        for (i, cmd) in self.exec.iter().enumerate() {
            let default = if i == 0 {
                "exec".to_string()
            } else {
                format!("exec{}", i + 1)
            };
            let name = names.next().map(str::to_string).unwrap_or(default);
            let m = rayproof::audit::exec::Exec::new(
                &name,
                cmd,
                shape.name,
                timeout,
                match (self.exec_keep, self.exec_per_batch || one_batch) {
                    (true, _) => rayproof::audit::exec::Mode::Keep,
                    (_, true) => rayproof::audit::exec::Mode::PerBatch,
                    _ => rayproof::audit::exec::Mode::Auto,
                },
            );
            out.push((Box::new(m), None));
        }
        // A name is a table's row label and a tolerance rule's key: one plain word
        for (m, _) in &out {
            let name = m.name();
            let plain = |c: char| c.is_ascii_alphanumeric() || "_.+-".contains(c);
            let first = name.starts_with(|c: char| c.is_ascii_alphanumeric());
            if !first || name.len() > 64 || !name.chars().all(plain) {
                bail!(
                    "--name {:?}: a routine's name is 1 to 64 letters, digits or _ . + -, starting with a letter or digit (it labels table rows and tolerance rules)",
                    name.chars().take(70).collect::<String>()
                );
            }
        }
        // Names are unique among them
        for (i, (m, _)) in out.iter().enumerate() {
            if out[..i].iter().any(|(x, _)| x.name() == m.name()) {
                bail!(
                    "two outside routines are named {}: give each its own name (--name, or --guard-name for a guard, --spawn-name for a spawn rule)",
                    m.name()
                );
            }
        }
        Ok(out)
    }
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x > 0.0 && x <= 86_400.0 => Ok(x),
        _ => Err(format!("'{s}' is not a number of seconds in (0, 86400]")),
    }
}
