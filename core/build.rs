//! Sets `cfg(nerflex_smlad)` on ARMv7E-M targets (Cortex-M4/M7), whose DSP
//! extension has `SMLAD`. Stable Rust exposes no ARM `target_feature` cfg,
//! so the target name decides; every other target uses the portable code.
fn main() {
    println!("cargo::rustc-check-cfg=cfg(nerflex_smlad)");
    println!("cargo::rerun-if-changed=build.rs");
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7em") {
        println!("cargo::rustc-cfg=nerflex_smlad");
    }
}
