//! `rayproof header`: the C header of `audit --plugin` routines.

use super::*;
use anyhow::Result;

pub(super) fn run_header() -> Result<u8> {
    say_raw!(
        "{}",
        rayproof::audit::plugin::header(&rayproof::shapes::registry())
    );
    Ok(0)
}
