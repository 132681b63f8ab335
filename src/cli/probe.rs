//! `rayproof probe`: one case, the oracle's answer and every method's.

use super::*;
use crate::audit::sphere_probe;
use crate::numerics::Precision;
use anyhow::{anyhow, bail, Result};
use clap::{Args, Parser, Subcommand};

#[derive(Subcommand, Debug)]
pub enum ProbeCommand {
    /// One ray against one sphere.
    Sphere(ProbeSphereArgs),
    /// A routine of the game-math chapter: `probe SHAPE [--precision P] [--json] -- VALUES…`
    /// (`probe SHAPE --help` names the values).
    #[command(external_subcommand)]
    Routine(Vec<String>),
}

/// The arguments of `rayproof probe SHAPE` for a routine (parsed after the shape is known, so
/// the help names its values).
#[derive(Parser, Debug)]
pub struct ProbeShapeArgs {
    /// f32 or f64.
    #[arg(long, value_parser = parse_precision, default_value = "f64")]
    pub precision: Precision,
    /// Print the JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// The input values in the shape's order (decimal or hex floats, each rounded once to the
    /// precision); put them after `--` when the first is negative.
    #[arg(allow_hyphen_values = true)]
    pub values: Vec<String>,
}

#[derive(Args, Debug)]
pub struct ProbeSphereArgs {
    /// Ray origin X,Y,Z (decimal or hex floats, each rounded once to the precision).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub origin: [String; 3],
    /// Ray direction X,Y,Z, used as given (not renormalised).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub dir: [String; 3],
    /// Sphere centre X,Y,Z.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub center: [String; 3],
    /// Sphere radius.
    #[arg(long, value_parser = parse_number, allow_hyphen_values = true)]
    pub radius: String,
    /// f32 or f64.
    #[arg(long, value_parser = parse_precision, default_value = "f64")]
    pub precision: Precision,
    /// Print the JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `rayproof probe SHAPE …` for a routine.
pub(super) fn run_probe_routine(argv: &[String]) -> Result<u8> {
    use clap::{CommandFactory, FromArgMatches};
    let name = argv.first().map(String::as_str).unwrap_or("");
    let Some(shape) = crate::shapes::shape_by_name(name) else {
        bail!(
            "probe: unknown shape '{name}' (known: {})",
            shape_names().join(", ")
        );
    };
    let cmd = ProbeShapeArgs::command()
        .name(shape.name())
        .bin_name(format!("rayproof probe {name}"))
        .about(shape.about())
        .after_help(format!(
            "Values: {}\nOutputs: {}\nMethods: {}",
            shape.args().join(" "),
            shape.values().join(" "),
            shape
                .methods()
                .iter()
                .map(|m| m.name)
                .collect::<Vec<_>>()
                .join(", ")
        ));
    let parsed = cmd
        .try_get_matches_from(argv)
        .and_then(|m| ProbeShapeArgs::from_arg_matches(&m));
    let p = match parsed {
        Ok(p) => p,
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelp => {
            say_raw!("{e}");
            return Ok(0);
        }
        Err(e) => bail!("{}", one_line(&e).trim_start_matches("error: ")),
    };
    let input = crate::audit::shape::parse_values(shape, p.precision, &p.values)
        .map_err(|e| anyhow!("{e}"))?;
    say_raw!(
        "{}",
        crate::audit::generic::probe(shape, p.precision, &input, p.json)
    );
    Ok(0)
}

pub(super) fn run_probe(p: ProbeCommand) -> Result<u8> {
    match p {
        ProbeCommand::Routine(argv) => run_probe_routine(&argv),
        ProbeCommand::Sphere(p) => {
            say_raw!(
                "{}",
                sphere_probe::sphere(&p.origin, &p.dir, &p.center, &p.radius, p.precision, p.json)?
            );
            Ok(0)
        }
    }
}
