//! The RISC-V firmware (`targets/riscv32`, QEMU `virt`, `riscv32imac`)
//! against the host build of the same core: configuration tables, plans,
//! and both shaders' 16 × 16 tiles bit for bit. Without
//! `qemu-system-riscv32` (Debian `qemu-system-misc`) or the Rust target it
//! prints `SKIPPED …` and passes (CI has both: `.ci/run` installs them).

#[path = "../../targets/cortex-m4/src/workload.rs"]
mod workload;

use nerflex_core::mck::{Config, Solver};
use nerflex_core::profiler::ConfigSpace;
use nerflex_core::shader::narrow::{check_samples, NarrowMlp, WeightBits};
use nerflex_core::shader::{FixedMlp, MlpWeights};
use nerflex_core::units::{Bytes, QualityQ};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const TARGET: &str = "riscv32imac-unknown-none-elf";

fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

fn missing_prerequisite() -> Option<String> {
    let qemu = Command::new("qemu-system-riscv32")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
    if !qemu.is_ok_and(|s| s.success()) {
        return Some(
            "qemu-system-riscv32 is not installed (apt-get install qemu-system-misc)".into(),
        );
    }
    let sysroot = Command::new(std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into()))
        .args(["--print", "sysroot"])
        .output()
        .ok()
        .map(|o| PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()));
    if !sysroot.is_some_and(|s| s.join("lib/rustlib").join(TARGET).is_dir()) {
        return Some(format!(
            "the Rust target {TARGET} is not installed (rustup target add {TARGET})"
        ));
    }
    None
}

/// Builds and runs the firmware; its output and exit code.
fn build_and_run() -> (String, Option<i32>) {
    let dir = repo_root().join("targets/riscv32");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let o = Command::new(cargo)
        .current_dir(&dir)
        .args(["build", "--release", "--locked"])
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("CARGO_BUILD_TARGET")
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_MAKEFLAGS")
        .env_remove("MAKEFLAGS")
        .env_remove("MFLAGS")
        .output()
        .expect("cargo starts");
    assert!(
        o.status.success(),
        "RISC-V firmware build failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let elf = dir
        .join("target")
        .join(TARGET)
        .join("release/nerflex-firmware-riscv32");
    let mut child = Command::new("qemu-system-riscv32")
        .args(["-machine", "virt", "-nographic", "-bios", "none", "-kernel"])
        .arg(&elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("qemu-system-riscv32 starts");
    let mut stdout = child.stdout.take().expect("piped");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut stdout, &mut s).map(|_| s)
    });
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("waiting for qemu") {
            break s;
        }
        if t0.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("the RISC-V firmware did not finish within 60 s");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    (
        reader.join().expect("reader").expect("UTF-8"),
        status.code(),
    )
}

/// `record key=value …` lines: (record, fields).
fn parse(text: &str) -> Vec<(String, BTreeMap<String, String>)> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let mut w = l.split_whitespace();
            let r = w.next().unwrap_or_default().to_string();
            let f = w
                .filter_map(|x| x.split_once('='))
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect();
            (r, f)
        })
        .collect()
}

fn records<'a>(
    lines: &'a [(String, BTreeMap<String, String>)],
    r: &str,
) -> Vec<&'a BTreeMap<String, String>> {
    lines
        .iter()
        .filter(|(x, _)| x == r)
        .map(|(_, f)| f)
        .collect()
}

fn host_weights() -> (MlpWeights, &'static str) {
    match nerflex_sim::data::shared_data_dir() {
        Some(d) => {
            let (w, _) =
                nerflex_sim::asset::mlp_json::read(&d.join("mobilenerf/weights/lego_mlp.json"))
                    .expect("lego_mlp.json reads");
            (w, "lego_mlp.json")
        }
        None => (workload::synthetic_weights(), "synthetic"),
    }
}

fn host_tables() -> Vec<Vec<Config>> {
    let path = repo_root().join("examples/scenes/five_objects_profile.json");
    let scene = nerflex_sim::scene_file::load(&path).expect("the example scene loads");
    scene
        .objects
        .iter()
        .map(|o| {
            let prof = o.profile.as_ref().expect("profile form");
            let space = ConfigSpace::new(&prof.g, &prof.p).expect("(g, p) lists");
            let mut t = vec![
                Config {
                    size: Bytes(0),
                    quality: QualityQ::ZERO
                };
                space.len()
            ];
            prof.fixed()
                .expect("in range")
                .fill_table(&space, &mut t)
                .expect("evaluates");
            t
        })
        .collect()
}

fn hex(px: &[[u8; 3]]) -> String {
    px.iter()
        .map(|p| format!("{:02x}{:02x}{:02x}", p[0], p[1], p[2]))
        .collect()
}

#[test]
fn riscv_firmware_matches_the_host() {
    if let Some(why) = missing_prerequisite() {
        println!("SKIPPED riscv_firmware_matches_the_host: {why}");
        return;
    }
    let (text, code) = build_and_run();
    assert_eq!(code, Some(0), "the firmware exits 0:\n{text}");
    let lines = parse(&text);
    assert!(records(&lines, "error").is_empty(), "{text}");
    assert_eq!(lines.last().map(|(r, _)| r.as_str()), Some("done"));
    assert_eq!(records(&lines, "nerflex-firmware")[0]["target"], TARGET);

    // Tables and plans.
    let tables = host_tables();
    let lines_t = records(&lines, "table");
    assert_eq!(lines_t.len(), tables.len());
    for (l, t) in lines_t.iter().zip(&tables) {
        assert_eq!(l["fnv"], format!("{:08x}", workload::table_hash(t)));
    }
    let refs: Vec<&[Config]> = tables.iter().map(|t| t.as_slice()).collect();
    let mut solver = Box::new(Solver::<
        { workload::OBJECTS },
        { workload::CONFIGS },
        { workload::UNITS },
    >::new());
    let plans = records(&lines, "plan");
    assert_eq!(plans.len(), workload::DEVICES.len());
    for (l, d) in plans.iter().zip(&workload::DEVICES) {
        let s = solver
            .solve(&refs, d.budget, workload::UNIT)
            .expect("plans");
        let c: Vec<String> = s.choices.iter().map(|c| c.to_string()).collect();
        assert_eq!(l["device"], d.name);
        assert_eq!(l["choices"], c.join(","));
        assert_eq!(l["total_bytes"], s.total_size.0.to_string());
        assert_eq!(l["total_quality_q31"], s.total_quality.0.to_string());
    }

    // Both shaders' tiles, bit for bit.
    let (w, source) = host_weights();
    let exact = FixedMlp::from_weights(&w).expect("converts");
    let narrow = match NarrowMlp::choose(&w, || check_samples(2048, 8)).expect("converts") {
        Some((m, _)) => m,
        None => NarrowMlp::from_weights(&w, WeightBits::Sixteen).expect("converts"),
    };
    assert_eq!(records(&lines, "mlp")[0]["source"], source);
    assert_eq!(
        records(&lines, "mlp")[0]["fnv"],
        format!("{:08x}", workload::mlp_hash(&exact))
    );
    assert_eq!(
        records(&lines, "narrow")[0]["fnv"],
        format!("{:08x}", workload::narrow_hash(&narrow))
    );
    let n = (workload::TILE_W * workload::TILE_H) as usize;
    let mut px = vec![[0u8; 3]; n];
    for (tag, tile) in [("row", "tile"), ("nrow", "ntile")] {
        if tag == "row" {
            workload::shade_tile(&exact, &mut px);
        } else {
            workload::shade_tile_narrow(&narrow, &mut px);
        }
        let rows = records(&lines, tag);
        assert_eq!(rows.len(), workload::TILE_H as usize);
        for (y, (l, host)) in rows
            .iter()
            .zip(px.chunks(workload::TILE_W as usize))
            .enumerate()
        {
            assert_eq!(l["rgb"], hex(host), "{tag} {y} differs from the host");
        }
        assert_eq!(
            records(&lines, tile)[0]["fnv"],
            format!("{:08x}", workload::pixels_hash(&px))
        );
    }
}
