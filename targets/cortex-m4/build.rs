//! Build script of the firmware: puts `memory.x` where the linker finds it
//! and generates the embedded tables (see `gen.rs`): the lego MLP in fixed
//! point, the five fitted profiles.
use std::path::PathBuf;
use std::{env, fs};

#[path = "src/workload.rs"]
mod workload;

#[path = "gen.rs"]
mod gen;

fn main() {
    if let Err(e) = run() {
        // A clear message instead of a backtrace.
        eprintln!("nerflex-firmware-m4 build script: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo did not set OUT_DIR")?);
    let manifest = PathBuf::from(
        env::var_os("CARGO_MANIFEST_DIR").ok_or("cargo did not set CARGO_MANIFEST_DIR")?,
    );
    fs::copy(manifest.join("memory.x"), out.join("memory.x"))
        .map_err(|e| format!("memory.x beside build.rs: {e}"))?;
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    // The firmware prints the target it was built for.
    let target = env::var("TARGET").map_err(|_| "cargo did not set TARGET")?;
    println!("cargo:rustc-env=FIRMWARE_TARGET={target}");
    fs::write(out.join("generated.rs"), gen::generate(&manifest)?)?;
    Ok(())
}
