//! The Cortex-M4 firmware (`targets/cortex-m4`) under QEMU against the host
//! build of the same core: it builds the firmware, runs it on QEMU's
//! `mps2-an386` machine, parses its line output and checks that the board
//! computed exactly what the host computes — the same configuration tables
//! (fitted profiles evaluated by the fixed-point profiler), the same plans
//! (choices and totals) and bit-identical shaded pixels, from both the exact
//! shader and the narrow one (16-bit, `SMLAD` on the M4, portable code on
//! the M0 and the host: all three must agree bit for bit).
//!
//! The Cortex-M0 build (`thumbv6m-none-eabi`, run on the same machine: ARMv6-M
//! is a subset of ARMv7-M) is checked the same way. Without
//! `qemu-system-arm` or the Rust target the tests print `SKIPPED …` and pass
//! (CI has both: `.ci/run` installs them).

#[path = "../../targets/cortex-m4/src/workload.rs"]
mod workload;

use nerflex_core::mck::{Config, Solver};
use nerflex_core::profiler::ConfigSpace;
use nerflex_core::shader::narrow::{check_samples, NarrowMlp, WeightBits};
use nerflex_core::shader::{FixedMlp, MlpWeights};
use nerflex_core::units::{Bytes, QualityQ};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

const M4: &str = "thumbv7em-none-eabihf";
const M0: &str = "thumbv6m-none-eabi";
/// A run takes about 0.1 s; this only guards against a hung machine.
const RUN_TIMEOUT: Duration = Duration::from_secs(60);

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

fn firmware_dir() -> PathBuf {
    repo_root().join("targets/cortex-m4")
}

/// Why the test cannot run here, if it cannot.
fn missing_prerequisite(target: &str) -> Option<String> {
    let qemu = Command::new("qemu-system-arm")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
    if !qemu.is_ok_and(|s| s.success()) {
        return Some("qemu-system-arm is not installed (apt-get install qemu-system-arm)".into());
    }
    let sysroot = Command::new(std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into()))
        .args(["--print", "sysroot"])
        .output()
        .ok()
        .map(|o| PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()));
    let installed = sysroot.is_some_and(|s| s.join("lib/rustlib").join(target).is_dir());
    if !installed {
        return Some(format!(
            "the Rust target {target} is not installed (rustup target add {target})"
        ));
    }
    None
}

/// Builds the firmware for `target` once per test run; the ELF path.
fn build(target: &str) -> Result<PathBuf, String> {
    static BUILDS: OnceLock<Mutex<BTreeMap<String, Result<PathBuf, String>>>> = OnceLock::new();
    let builds = BUILDS.get_or_init(Default::default);
    // One nested cargo at a time (they share the firmware's target folder).
    let mut done = builds.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(r) = done.get(target) {
        return r.clone();
    }
    let dir = firmware_dir();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let t0 = Instant::now();
    let out = Command::new(cargo)
        .current_dir(&dir) // picks up targets/cortex-m4/.cargo/config.toml
        .args(["build", "--release", "--locked", "--target", target])
        // The outer test run's settings must not leak into the firmware build.
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("CARGO_BUILD_TARGET")
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_MAKEFLAGS")
        .env_remove("MAKEFLAGS")
        .env_remove("MFLAGS")
        .output()
        .map_err(|e| format!("cannot start cargo: {e}"));
    let r = out.and_then(|o| {
        if o.status.success() {
            eprintln!(
                "built the firmware for {target} in {:.1} s",
                t0.elapsed().as_secs_f64()
            );
            Ok(dir
                .join("target")
                .join(target)
                .join("release/nerflex-firmware-m4"))
        } else {
            Err(format!(
                "firmware build for {target} failed (if its Cargo.lock is out of date after a \
                 change of the core's dependencies, run `cargo build` once in targets/cortex-m4 \
                 and commit the lock file):\n{}",
                String::from_utf8_lossy(&o.stderr)
            ))
        }
    });
    done.insert(target.to_string(), r.clone());
    r
}

/// Runs the ELF on QEMU; `append` is the semihosting command line.
fn run(elf: &Path, append: Option<&str>) -> (String, Option<i32>) {
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args(["-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic"])
        .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
    if let Some(a) = append {
        cmd.args(["-append", a]);
    }
    let mut child = cmd.spawn().expect("qemu-system-arm starts");
    let mut stdout = child.stdout.take().expect("piped stdout");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        stdout.read_to_string(&mut s).map(|_| s)
    });
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("waiting for qemu") {
            break s;
        }
        if t0.elapsed() > RUN_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("the firmware did not finish within {RUN_TIMEOUT:?} under QEMU");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let text = reader
        .join()
        .expect("reader thread")
        .expect("qemu output is UTF-8");
    (text, status.code())
}

/// One output line: `record key=value …`.
#[derive(Debug)]
struct Line {
    record: String,
    fields: BTreeMap<String, String>,
}

impl Line {
    fn get(&self, key: &str) -> &str {
        self.fields
            .get(key)
            .unwrap_or_else(|| panic!("`{}` line without `{key}`: {self:?}", self.record))
    }

    fn num(&self, key: &str) -> u64 {
        let v = self.get(key);
        v.parse()
            .unwrap_or_else(|_| panic!("`{}` {key}={v} is not a number", self.record))
    }
}

fn parse(text: &str) -> Vec<Line> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let mut words = l.split_whitespace();
            let record = words.next().unwrap_or_default().to_string();
            let fields = words
                .filter_map(|w| w.split_once('='))
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect();
            Line { record, fields }
        })
        .collect()
}

fn records<'a>(lines: &'a [Line], record: &str) -> Vec<&'a Line> {
    lines.iter().filter(|l| l.record == record).collect()
}

/// One object as the host computes it: name, (g, p) per index, table.
struct HostObject {
    name: String,
    gp: Vec<(u32, u32)>,
    table: Vec<Config>,
}

/// The host's configuration tables for the firmware's five profiles: the
/// same fitted parameters evaluated by the host build of the core's
/// fixed-point profiler.
fn host_objects() -> Vec<HostObject> {
    let path = repo_root().join("examples/scenes/five_objects_profile.json");
    let scene = nerflex_sim::scene_file::load(&path).expect("the example scene loads");
    scene
        .objects
        .iter()
        .map(|o| {
            let prof = o.profile.as_ref().expect("the example is in profile form");
            let space = ConfigSpace::new(&prof.g, &prof.p).expect("(g, p) lists");
            let mut table = vec![
                Config {
                    size: Bytes(0),
                    quality: QualityQ::ZERO
                };
                space.len()
            ];
            prof.fixed()
                .expect("profile in range")
                .fill_table(&space, &mut table)
                .expect("profile evaluates");
            // The planner's scene loader agrees with the direct evaluation.
            for (c, t) in o.configs.iter().zip(&table) {
                assert_eq!(c.size, t.size, "{}: scene_file size", o.name);
                assert_eq!(
                    QualityQ::from_f64(c.quality),
                    Ok(t.quality),
                    "{}: scene_file quality",
                    o.name
                );
            }
            HostObject {
                name: o.name.clone(),
                gp: space.iter().collect(),
                table,
            }
        })
        .collect()
}

/// The weights the firmware should have embedded, and their source name.
fn host_weights() -> (MlpWeights, &'static str) {
    match nerflex_sim::data::shared_data_dir() {
        Some(data) => {
            let path = data.join("mobilenerf/weights/lego_mlp.json");
            let (w, _) = nerflex_sim::asset::mlp_json::read(&path).expect("lego_mlp.json reads");
            (w, "lego_mlp.json")
        }
        None => {
            eprintln!("note: no shared data: expecting the synthetic weight set");
            (workload::synthetic_weights(), "synthetic")
        }
    }
}

/// The MLP the firmware should have embedded, and its source name.
fn host_mlp() -> (FixedMlp, &'static str) {
    let (w, source) = host_weights();
    (FixedMlp::from_weights(&w).expect("MLP converts"), source)
}

/// The narrow tables the build script should have chosen, their check
/// histogram and whether they pass (as `gen.rs` decides).
fn host_narrow() -> (NarrowMlp, [u64; 4], bool) {
    let (w, _) = host_weights();
    let samples = || check_samples(2048, 8);
    match NarrowMlp::choose(&w, samples).expect("converts") {
        Some((m, h)) => (m, h.counts, true),
        None => {
            let m = NarrowMlp::from_weights(&w, WeightBits::Sixteen).expect("converts");
            let h = m.error_histogram(&w, samples());
            (m, h.counts, false)
        }
    }
}

fn hex(px: &[[u8; 3]]) -> String {
    px.iter().flatten().map(|b| format!("{b:02x}")).collect()
}

/// Builds, runs and compares the firmware for `target`.
fn check(target: &str) {
    if let Some(why) = missing_prerequisite(target) {
        eprintln!("SKIPPED firmware on QEMU ({target}): {why}");
        return;
    }
    let elf = build(target).unwrap_or_else(|e| panic!("{e}"));
    let (text, code) = run(&elf, None);
    println!("{text}");
    assert_eq!(code, Some(0), "the firmware exits 0; output:\n{text}");
    let lines = parse(&text);
    assert!(
        records(&lines, "error").is_empty(),
        "firmware reported an error:\n{text}"
    );
    assert_eq!(
        lines.last().map(|l| l.record.as_str()),
        Some("done"),
        "the output ends with `done`"
    );
    let head = &records(&lines, "nerflex-firmware")[0];
    assert_eq!(head.get("target"), target);

    // 1. The configuration tables.
    let objects = host_objects();
    assert_eq!(objects.len(), workload::OBJECTS);
    let tables = records(&lines, "table");
    assert_eq!(
        tables.len(),
        workload::OBJECTS,
        "one `table` line per object"
    );
    for (i, (line, host)) in tables.iter().zip(&objects).enumerate() {
        assert_eq!(line.num("object"), i as u64);
        assert_eq!(line.get("name"), host.name);
        assert_eq!(line.num("configs"), host.table.len() as u64);
        let min = host.table.iter().map(|c| c.size.0).min().unwrap();
        let max = host.table.iter().map(|c| c.size.0).max().unwrap();
        assert_eq!((line.num("min_bytes"), line.num("max_bytes")), (min, max));
        assert_eq!(
            line.get("fnv"),
            format!("{:08x}", workload::table_hash(&host.table)),
            "object {i} ({}): the board's configuration table differs from the host's",
            host.name
        );
    }

    // 2. The plans: same choices and totals as the host's solver.
    let plans = records(&lines, "plan");
    let picks = records(&lines, "pick");
    assert_eq!(plans.len(), workload::DEVICES.len());
    let host_tables: Vec<&[Config]> = objects.iter().map(|o| o.table.as_slice()).collect();
    let mut solver = Box::new(Solver::<
        { workload::OBJECTS },
        { workload::CONFIGS },
        { workload::UNITS },
    >::new());
    for (line, device) in plans.iter().zip(&workload::DEVICES) {
        let s = solver
            .solve(&host_tables, device.budget, workload::UNIT)
            .expect("the host plans");
        assert_eq!(line.get("device"), device.name);
        assert_eq!(line.num("budget_bytes"), device.budget.0);
        assert_eq!(line.num("unit_bytes"), workload::UNIT.0);
        let choices: Vec<String> = s.choices.iter().map(|c| c.to_string()).collect();
        assert_eq!(
            line.get("choices"),
            choices.join(","),
            "{}: choices",
            device.name
        );
        assert_eq!(line.num("total_bytes"), s.total_size.0);
        assert_eq!(line.num("total_units"), s.total_units);
        assert_eq!(line.num("total_quality_q31"), s.total_quality.0);
        assert!(s.total_size <= device.budget);
        let mine: Vec<_> = picks
            .iter()
            .filter(|p| p.get("device") == device.name)
            .collect();
        assert_eq!(mine.len(), workload::OBJECTS);
        for (i, (p, &c)) in mine.iter().zip(s.choices).enumerate() {
            let o = &objects[i];
            let (g, pp) = o.gp[c as usize];
            let cfg = o.table[c as usize];
            assert_eq!(p.get("name"), o.name);
            assert_eq!(p.num("index"), u64::from(c));
            assert_eq!((p.num("g"), p.num("p")), (u64::from(g), u64::from(pp)));
            assert_eq!(p.num("size_bytes"), cfg.size.0);
            assert_eq!(p.num("quality_q31"), u64::from(cfg.quality.raw()));
        }
    }

    // 3. The shaded tile, bit for bit.
    let (mlp, source) = host_mlp();
    let m = &records(&lines, "mlp")[0];
    assert_eq!(m.get("source"), source, "weight set the firmware embedded");
    assert_eq!(
        m.get("fnv"),
        format!("{:08x}", workload::mlp_hash(&mlp)),
        "the firmware's fixed-point MLP tables differ from the host's"
    );
    let mut px = vec![[0u8; 3]; (workload::TILE_W * workload::TILE_H) as usize];
    workload::shade_tile(&mlp, &mut px);
    let rows = records(&lines, "row");
    assert_eq!(rows.len(), workload::TILE_H as usize);
    for (y, (line, host_row)) in rows
        .iter()
        .zip(px.chunks(workload::TILE_W as usize))
        .enumerate()
    {
        assert_eq!(line.num("y"), y as u64);
        assert_eq!(line.get("rgb"), hex(host_row), "tile row {y} differs");
    }
    let tile = &records(&lines, "tile")[0];
    assert_eq!(
        tile.get("fnv"),
        format!("{:08x}", workload::pixels_hash(&px))
    );

    // The same tile from the narrow shader, bit for bit.
    let (narrow, counts, passes) = host_narrow();
    let n = &records(&lines, "narrow")[0];
    assert_eq!(n.get("source"), source);
    assert_eq!(
        n.get("fnv"),
        format!("{:08x}", workload::narrow_hash(&narrow)),
        "the firmware's narrow tables differ from the host's"
    );
    let [c0, c1, c2, c3] = counts;
    assert_eq!(n.get("check"), format!("{c0},{c1},{c2},{c3}"));
    assert_eq!(n.num("passes"), u64::from(passes));
    workload::shade_tile_narrow(&narrow, &mut px);
    let rows = records(&lines, "nrow");
    assert_eq!(rows.len(), workload::TILE_H as usize);
    for (y, (line, host_row)) in rows
        .iter()
        .zip(px.chunks(workload::TILE_W as usize))
        .enumerate()
    {
        assert_eq!(line.num("y"), y as u64);
        assert_eq!(
            line.get("rgb"),
            hex(host_row),
            "narrow tile row {y} differs"
        );
    }
    assert_eq!(
        records(&lines, "ntile")[0].get("fnv"),
        format!("{:08x}", workload::pixels_hash(&px))
    );

    // 4. The measured costs are present and plausible.
    let stack = &records(&lines, "stack")[0];
    for key in [
        "profile_bytes",
        "solver_bytes",
        "shade_pixel_bytes",
        "shade_tile_bytes",
        "narrow_pixel_bytes",
        "narrow_tile_bytes",
    ] {
        let v = stack.num(key); // a `>=` (window exhausted) fails to parse
        assert!(v > 0 && v < 64 * 1024, "{key} = {v}");
    }
    let mem = &records(&lines, "memory")[0];
    assert_eq!(
        mem.num("solver_tables_bytes") as usize,
        Solver::<{ workload::OBJECTS }, { workload::CONFIGS }, { workload::UNITS }>::MEMORY_BYTES
    );
    assert_eq!(mem.num("solver_tables_bytes"), 32_285);
}

#[test]
fn cortex_m4_firmware_matches_the_host() {
    check(M4);
}

#[test]
fn cortex_m0_firmware_matches_the_host() {
    check(M0);
}

#[test]
fn firmware_panic_and_fault_exit_non_zero() {
    if let Some(why) = missing_prerequisite(M4) {
        eprintln!("SKIPPED firmware panic exit ({M4}): {why}");
        return;
    }
    let elf = build(M4).unwrap_or_else(|e| panic!("{e}"));
    let (text, code) = run(&elf, Some("panic"));
    assert_eq!(code, Some(1), "a panic exits 1; output:\n{text}");
    assert!(
        text.contains("panicked at"),
        "panic message printed: {text}"
    );
    assert!(!text.contains("done"));
    let (text, code) = run(&elf, Some("fault"));
    assert_eq!(code, Some(1), "a hard fault exits 1; output:\n{text}");
    assert!(
        text.starts_with("error hardfault"),
        "fault reported: {text}"
    );
}
