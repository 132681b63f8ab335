//! `rayproof header`: the C header of `audit --plugin` routines.

use super::*;
use anyhow::Result;

pub(super) fn run_header() -> Result<u8> {
    say_raw!(
        "{}",
        crate::audit::plugin::header(&crate::shapes::registry())
    );
    Ok(0)
}
