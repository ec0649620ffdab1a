//! Generates the firmware's embedded tables (`targets/cortex-m4/gen.rs`) so
//! that the counted work is exactly the firmware's.
use std::path::PathBuf;
use std::{env, fs};

#[path = "../cortex-m4/src/workload.rs"]
mod workload;

#[path = "../cortex-m4/gen.rs"]
mod gen;

fn main() {
    if let Err(e) = run() {
        eprintln!("nerflex-count build script: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo did not set OUT_DIR")?);
    let manifest = PathBuf::from(
        env::var_os("CARGO_MANIFEST_DIR").ok_or("cargo did not set CARGO_MANIFEST_DIR")?,
    );
    println!("cargo:rerun-if-changed=build.rs");
    let firmware = manifest.join("../cortex-m4");
    fs::write(out.join("generated.rs"), gen::generate(&firmware)?)?;
    Ok(())
}
