//! `rayproof header`: the C header of `audit --plugin` routines.

use super::*;
use anyhow::Result;

pub(super) fn run_header(a: HeaderArgs) -> Result<u8> {
    let shapes = rayproof::shapes::registry();
    if a.spawn {
        say_raw!("{}", rayproof::audit::robustness::spawn::PROTOCOL);
        say_raw!(
            "\n{}",
            rayproof::audit::robustness::spawn::rules::C_SIGNATURE
        );
    } else if a.guard {
        say_raw!("{}", rayproof::audit::robustness::guard::PROTOCOL);
        say_raw!("\n{}", rayproof::audit::robustness::guard::C_SIGNATURE);
    } else if a.exec {
        say_raw!("{}", rayproof::audit::exec::protocol(&shapes));
    } else {
        say_raw!("{}", rayproof::audit::plugin::header(&shapes));
    }
    Ok(0)
}

#[derive(clap::Args, Debug)]
pub struct HeaderArgs {
    /// Print the --exec line protocol (input and answer lines, each shape's fields and answer
    /// contract) instead of the C header.
    #[arg(long)]
    pub exec: bool,
    /// Print the line protocol of a spawn rule run by `rayproof spawn --exec`.
    #[arg(long, conflicts_with = "exec")]
    pub spawn: bool,
    /// Print the line protocol and C signatures of a ray–box guard (`rayproof guard`).
    #[arg(long, conflicts_with_all = ["exec", "spawn"])]
    pub guard: bool,
}
