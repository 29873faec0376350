//! Puts `memory.x` on the linker search path for the thumb builds (cortex-m-rt's `link.x`
//! includes it) and links defmt's script into the firmware binary only. `-Tlink.x` itself
//! is given once, in `.cargo/config.toml`.
use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("memory.x is at the package root");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bin=firmware=-Tdefmt.x");
}
