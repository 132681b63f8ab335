//! Build script: one line saying where GMP and MPFR (the oracle's exact arithmetic) come from.
//! The choice is the `system-libs` feature, which `gmp-mpfr-sys` reads; a cargo feature cannot
//! be chosen by probing the machine, and `gmp-mpfr-sys` takes only GMP 6.3 or later and MPFR 4.2
//! or later (Debian 12 has GMP 6.2.1), so building them from source is the default.

fn main() {
    println!("cargo:rerun-if-changed=src/build.rs");
    if std::env::var_os("CARGO_FEATURE_SYSTEM_LIBS").is_some() {
        println!("cargo:warning=GMP and MPFR: the system's libraries (feature system-libs)");
    } else {
        println!(
            "cargo:warning=GMP and MPFR: built from source (gmp-mpfr-sys, cached per machine); `--features system-libs` links the system's (GMP >= 6.3, MPFR >= 4.2)"
        );
    }
}
