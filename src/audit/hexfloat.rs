//! Floats in JSON as exact text: a C99 hex float (`0x1.8p+1`, `-0x0p+0`, `inf`), and a NaN as its
//! bit pattern (`nan:0x7ff8000000000000`). Decimal JSON numbers are not used for floats that
//! must survive a file exactly, because a JSON reader need not parse them exactly.

use crate::numerics::real::{hex_float, parse_f64};

/// An `f64` as exact text.
pub fn exact_text(x: f64) -> String {
    if x.is_nan() {
        format!("nan:{:#018x}", x.to_bits())
    } else {
        hex_float(x)
    }
}

/// Reads [`exact_text`].
pub fn parse_exact(s: &str) -> Option<f64> {
    match s.strip_prefix("nan:0x") {
        Some(bits) => u64::from_str_radix(bits, 16)
            .ok()
            .map(f64::from_bits)
            .filter(|x| x.is_nan()),
        None => parse_f64(s).filter(|x| !x.is_nan()),
    }
}

/// `Vec<f64>` fields written as [`exact_text`].
pub mod exact_vec {
    use serde::{de::Error, Deserialize, Deserializer, Serializer};
    /// Writes each value as its exact text.
    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.iter().map(|&x| super::exact_text(x)))
    }
    /// Reads values written by [`serialize`] (hex or decimal floats, `inf`, `nan`).
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Vec::<std::borrow::Cow<str>>::deserialize(d)?
            .iter()
            .map(|t| {
                super::parse_exact(t)
                    .ok_or_else(|| D::Error::custom(format!("'{t}' is not an exact float")))
            })
            .collect()
    }
}
