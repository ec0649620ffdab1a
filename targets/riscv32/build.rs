//! Build script of the RISC-V firmware: puts the linker script where the
//! linker finds it and generates the embedded tables with the Cortex-M
//! firmware's generator (`../cortex-m4/gen.rs`: the lego MLP, exact and
//! narrow, and the five fitted profiles), so both boards embed the same.
use std::path::PathBuf;
use std::{env, fs};

#[path = "../cortex-m4/src/workload.rs"]
mod workload;

#[path = "../cortex-m4/gen.rs"]
mod gen;

fn main() {
    if let Err(e) = run() {
        eprintln!("nerflex-firmware-riscv32 build script: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo did not set OUT_DIR")?);
    let manifest = PathBuf::from(
        env::var_os("CARGO_MANIFEST_DIR").ok_or("cargo did not set CARGO_MANIFEST_DIR")?,
    );
    fs::copy(manifest.join("firmware.ld"), out.join("firmware.ld"))
        .map_err(|e| format!("firmware.ld beside build.rs: {e}"))?;
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=firmware.ld");
    println!("cargo:rerun-if-changed=build.rs");
    let target = env::var("TARGET").map_err(|_| "cargo did not set TARGET")?;
    println!("cargo:rustc-env=FIRMWARE_TARGET={target}");
    // gen.rs resolves its inputs from the Cortex-M firmware's folder (same depth).
    fs::write(
        out.join("generated.rs"),
        gen::generate(&manifest.join("../cortex-m4"))?,
    )?;
    Ok(())
}
