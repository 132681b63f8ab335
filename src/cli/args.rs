//! Value parsers shared by the commands' arguments (each error is one line).

use anyhow::Result;
use rayproof::numerics::Precision;
use rayproof::shapes::sphere::methods::{method_by_name, Method, METHODS};

pub(super) fn parse_spp(s: &str) -> Result<u32, String> {
    let n: u32 = s
        .parse()
        .map_err(|_| format!("'{s}' is not a number of samples"))?;
    let g = (n as f64).sqrt().round() as u32;
    if n == 0 || g * g != n {
        return Err(format!(
            "{n} is not a square (1, 4, 9, 16, …): the sub-pixel grid is n×n"
        ));
    }
    Ok(g)
}

pub(super) fn parse_method(s: &str) -> Result<&'static Method, String> {
    method_by_name(s).ok_or_else(|| {
        format!(
            "unknown method '{s}' (known: {})",
            METHODS
                .iter()
                .map(|m| m.name)
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

pub(super) fn parse_precision(s: &str) -> Result<Precision, String> {
    match s {
        "f32" => Ok(Precision::F32),
        "f64" => Ok(Precision::F64),
        _ => Err(format!("unknown precision '{s}' (known: f32, f64)")),
    }
}

pub(super) fn parse_shard(s: &str) -> Result<(u64, u64), String> {
    let bad = || format!("'{s}' is not a shard K/N with 0 ≤ K < N");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n): (u64, u64) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || k >= n {
        return Err(bad());
    }
    Ok((k, n))
}
