//! `rayproof probe SHAPE [--precision P] [--json] -- VALUES…`: one case, the oracle's answer and
//! every method's. Every worst case of an audit prints the line that replays it.

use super::*;
use anyhow::{anyhow, bail, Result};
use clap::{Parser, Subcommand};
use rayproof::audit::probe::{parse_values, probe_json, probe_text};
use rayproof::audit::{Builtin, Method};
use rayproof::numerics::Precision;

#[derive(Subcommand, Debug)]
pub enum ProbeCommand {
    /// A shape: `probe SHAPE [--precision P] [--json] -- VALUES…` (`probe SHAPE --help` names
    /// the values).
    #[command(external_subcommand)]
    Shape(Vec<String>),
}

/// The arguments of `rayproof probe SHAPE` (parsed after the shape is known, so the help names
/// its values).
#[derive(Parser, Debug)]
pub struct ProbeShapeArgs {
    /// f32 or f64.
    #[arg(long, value_parser = parse_precision, default_value = "f64")]
    pub precision: Precision,
    /// Print the JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub outside: super::outside::OutsideArgs,
    /// The input values in the shape's order (decimal or hex floats, each rounded once to the
    /// precision); put them after `--` when the first is negative.
    #[arg(allow_hyphen_values = true)]
    pub values: Vec<String>,
}

/// An outside method's failure (exit 4).
fn failed(e: String) -> anyhow::Error {
    anyhow::Error::new(rayproof::audit::run::MethodFailed(e))
}

pub(super) fn run_probe(p: ProbeCommand) -> Result<u8> {
    use clap::{CommandFactory, FromArgMatches};
    let ProbeCommand::Shape(argv) = p;
    // The shape, then its arguments (so that --help names its values)
    let name = argv.first().map(String::as_str).unwrap_or("");
    let Some(shape) = rayproof::shapes::shape_by_name(name) else {
        bail!(
            "probe: unknown shape '{name}' (known: {})",
            rayproof::shapes::shape_names().join(", ")
        );
    };
    let info = shape.info();
    let cmd = ProbeShapeArgs::command()
        .name(info.name)
        .bin_name(format!("rayproof probe {name}"))
        .about(info.about)
        .after_help(format!(
            "Values: {}\nOutputs: {}\nMethods: {}",
            info.args.join(" "),
            info.values.join(" "),
            info.methods
                .iter()
                .map(|m| m.name)
                .collect::<Vec<_>>()
                .join(", ")
        ));
    let parsed = cmd
        .try_get_matches_from(&argv)
        .and_then(|m| ProbeShapeArgs::from_arg_matches(&m));
    let p = match parsed {
        Ok(p) => p,
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelp => {
            say_raw!("{e}");
            return Ok(0);
        }
        Err(e) => bail!("{}", one_line(&e).trim_start_matches("error: ")),
    };
    // The oracle and every built-in method on the case
    let input = parse_values(shape, p.precision, &p.values).map_err(|e| anyhow!("{e}"))?;
    let builtins = Builtin::all(shape);
    let outside = p.outside.methods_with(shape.info(), true)?;
    let methods: Vec<&dyn Method> = builtins
        .iter()
        .map(|m| m as &dyn Method)
        .chain(outside.iter().map(|(m, _)| m.as_ref() as &dyn Method))
        .collect();
    if p.json {
        let v = probe_json(shape, &methods, p.precision, &input).map_err(failed)?;
        say_raw!("{}", serde_json::to_string_pretty(&v)? + "\n");
    } else {
        say_raw!(
            "{}",
            probe_text(shape, &methods, p.precision, &input).map_err(failed)?
        );
    }
    Ok(0)
}
