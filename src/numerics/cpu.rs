//! Which instruction sets rayproof's own kernels may use: what the CPU has, capped by the
//! environment variable `RAYPROOF_ISA`, so that every path can be run (and tested) on one
//! machine.
//!
//! - unset or `native`: whatever the CPU has;
//! - `avx2`: AVX2 and FMA at most (the sphere batch kernels' AVX2 path, the renderer's AVX2
//!   traversal, the `certified` method's FMA products), never AVX-512;
//! - `scalar`: the build's baseline (SSE2 on x86_64), no FMA: the portable batch kernel and the
//!   `certified` method's paths without fused products.
//!
//! The cap only ever takes sets away: `avx2` on a CPU without AVX2 is the baseline. A path with
//! FMA and one without give the same bits wherever rayproof claims so (`tests/certified.rs`,
//! `tests/batch.rs`); the cap is how a machine with the wider set tests the narrower path. The
//! command line refuses an unknown value with one line (exit 2, [`check_env`]); the library,
//! given one, uses the baseline (the narrowest: never an instruction the user did not allow).

use std::sync::OnceLock;

/// The environment variable that caps the instruction set.
pub const ENV: &str = "RAYPROOF_ISA";

/// The widest instruction set the kernels may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// The build's baseline, no FMA.
    Scalar,
    /// AVX2 with FMA.
    Avx2,
    /// AVX-512 (F, VL, DQ) with FMA.
    Avx512,
}

impl Level {
    /// Reads a cap as `RAYPROOF_ISA` spells it.
    pub fn parse(s: &str) -> Result<Level, String> {
        match s {
            "scalar" => Ok(Level::Scalar),
            "avx2" => Ok(Level::Avx2),
            "avx512" | "native" => Ok(Level::Avx512),
            other => {
                // One line of reasonable length, whatever was set
                let shown: String = other.chars().take(40).collect();
                let more = if other.chars().count() > 40 {
                    "…"
                } else {
                    ""
                };
                Err(format!(
                    "{ENV}={shown:?}{more} is not an instruction-set cap (scalar, avx2, avx512 or native)"
                ))
            }
        }
    }

    /// `scalar`, `avx2` or `avx512`.
    pub fn name(self) -> &'static str {
        match self {
            Level::Scalar => "scalar",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
        }
    }
}

/// The cap this process runs under (read once).
pub fn cap() -> Level {
    static CAP: OnceLock<Level> = OnceLock::new();
    *CAP.get_or_init(|| match std::env::var(ENV) {
        Ok(v) => Level::parse(&v).unwrap_or(Level::Scalar),
        Err(_) => Level::Avx512,
    })
}

/// An unknown `RAYPROOF_ISA`, as the one line the command line prints.
pub fn check_env() -> Result<(), String> {
    match std::env::var(ENV) {
        Ok(v) => Level::parse(&v).map(|_| ()),
        Err(std::env::VarError::NotPresent) => Ok(()),
        Err(_) => Err(format!("{ENV} is not valid UTF-8")),
    }
}

/// Whether FMA may be used (the CPU has it and the cap allows AVX2).
pub fn fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        cap() >= Level::Avx2 && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether AVX2 (with FMA) may be used.
pub fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        fma() && std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether AVX-512 F, VL and DQ (with FMA) may be used.
pub fn avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        cap() >= Level::Avx512
            && fma()
            && std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && std::arch::is_x86_feature_detected!("avx512dq")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The widest level this process may use (the CPU's, under the cap).
pub fn level() -> Level {
    if avx512() {
        Level::Avx512
    } else if avx2() {
        Level::Avx2
    } else {
        Level::Scalar
    }
}
