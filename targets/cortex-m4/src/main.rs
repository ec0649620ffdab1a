//! nerflex-core on a Cortex-M4F (QEMU `mps2-an386`): the core's real work
//! on board, printed over semihosting in a line format that
//! `tests/tests/firmware_m4.rs` parses and compares with the host build.
//!
//! 1. the five objects' fitted profiles evaluated into configuration
//!    tables (5 × 45 configurations) by the fixed-point profiler;
//! 2. the exact MCK plan for the iPhone 13 (240 MB) and Pixel 4 (150 MB)
//!    budgets in 0.1 MB units, with `Solver<5, 45, 2400>` in a static;
//! 3. a 16 × 16 tile of texels shaded by the fixed-point lego MLP
//!    (converted from `lego_mlp.json` at build time), once with the exact
//!    shader (`FixedMlp`, 32 × 32 → 64-bit products) and once with the
//!    narrow one (`NarrowMlp`, 16-bit, `SMLAD` on ARMv7E-M);
//! 4. the peak stack of the profiler, the solver and the shader (stack
//!    painting) and the sizes of the tables.
//!
//! Every line is `<record> key=value …`. The run ends with `done` and exit
//! status 0; any error prints `error …` and exits 1, and so does a panic
//! (`panic-semihosting` with `exit`) or a fault. The semihosting command
//! line `panic` (QEMU `-append panic`) panics on purpose and `fault`
//! executes an undefined instruction, to test that.

#![no_std]
#![no_main]

mod stack;
mod workload;

use core::mem::size_of;

use cortex_m as _; // critical-section implementation
use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::{debug, hprintln, nr, syscall1};
use nerflex_core::mck::{Config, MckError, Solver};
use nerflex_core::profiler::ProfileError;
use nerflex_core::shader::narrow::NarrowMlp;
use nerflex_core::shader::FixedMlp;
use nerflex_core::units::{Bytes, QualityQ};
use panic_semihosting as _;
use workload::{Device, ObjectProfile, CONFIGS, OBJECTS, TILE_H, TILE_W, UNIT, UNITS};

#[allow(clippy::all, dead_code)]
mod generated {
    use crate::workload::ObjectProfile;
    use nerflex_core::profiler::{Family, Params};
    use nerflex_core::shader::narrow::{NarrowLayer, NarrowMlp};
    use nerflex_core::shader::{FixedLayer, FixedMlp};
    include!(concat!(env!("OUT_DIR"), "/generated.rs"));
}

/// The paper's solver: 5 objects, 45 configurations, 2400 units of 0.1 MB.
type PaperSolver = Solver<OBJECTS, CONFIGS, UNITS>;

const PIXELS: usize = (TILE_W * TILE_H) as usize;

/// A configuration from raw values (for the generated tables).
const fn config(size_bytes: u64, quality_q31: u32) -> Config {
    Config {
        size: Bytes(size_bytes),
        quality: match QualityQ::from_raw(quality_q31) {
            Some(q) => q,
            None => QualityQ::ZERO,
        },
    }
}

/// One plan, copied out of the solver.
struct Plan {
    choices: [u8; OBJECTS],
    total_bytes: u64,
    total_units: u64,
    total_quality_q31: u64,
}

#[inline(never)]
fn evaluate_profiles(
    profiles: &[ObjectProfile; OBJECTS],
    tables: &mut [[Config; CONFIGS]; OBJECTS],
) -> Result<(), (usize, ProfileError)> {
    workload::evaluate_profiles(profiles, tables)
}

#[inline(never)]
fn plan(
    solver: &mut PaperSolver,
    tables: &[[Config; CONFIGS]; OBJECTS],
    device: &Device,
) -> Result<Plan, MckError> {
    let s = solver.solve(tables, device.budget, UNIT)?;
    let mut choices = [0u8; OBJECTS];
    for (c, &s) in choices.iter_mut().zip(s.choices) {
        *c = s;
    }
    Ok(Plan {
        choices,
        total_bytes: s.total_size.0,
        total_units: s.total_units,
        total_quality_q31: s.total_quality.0,
    })
}

/// One pixel's shading, with the peak stack of the MLP call alone (its
/// inputs are built before the measurement).
fn shade_one(mlp: &FixedMlp, x: u32, y: u32) -> ([u8; 3], stack::Peak) {
    let (f0, f1) = workload::texels(x, y);
    let dir = workload::view_dir(x, y);
    // `FixedMlp::shade` is not inlined (see its docs): it runs below.
    stack::measure(|| mlp.shade(core::hint::black_box(f0), f1, dir))
}

#[inline(never)]
fn shade_tile(mlp: &FixedMlp, out: &mut [[u8; 3]; PIXELS]) {
    workload::shade_tile(mlp, out);
}

/// [`shade_one`] with the narrow shader.
fn shade_one_narrow(mlp: &NarrowMlp, x: u32, y: u32) -> ([u8; 3], stack::Peak) {
    let (f0, f1) = workload::texels(x, y);
    let dir = workload::view_dir(x, y);
    // `NarrowMlp::shade` is not inlined either.
    stack::measure(|| mlp.shade(core::hint::black_box(f0), f1, dir))
}

#[inline(never)]
fn shade_tile_narrow(mlp: &NarrowMlp, out: &mut [[u8; 3]; PIXELS]) {
    workload::shade_tile_narrow(mlp, out);
}

/// Prints the tile as `<tag> y=… rgb=<hex>` lines.
fn print_rows(tag: &str, px: &[[u8; 3]; PIXELS]) {
    for y in 0..TILE_H {
        let mut hex = [0u8; 6 * TILE_W as usize];
        let row = px
            .get((y * TILE_W) as usize..((y + 1) * TILE_W) as usize)
            .unwrap_or(&[]);
        for (h, p) in hex.chunks_exact_mut(6).zip(row) {
            for (pair, &v) in h.chunks_exact_mut(2).zip(p) {
                const DIGITS: &[u8; 16] = b"0123456789abcdef";
                pair[0] = DIGITS[(v >> 4) as usize];
                pair[1] = DIGITS[(v & 15) as usize];
            }
        }
        hprintln!(
            "{} y={} rgb={}",
            tag,
            y,
            core::str::from_utf8(&hex).unwrap_or("?")
        );
    }
}

/// The semihosting command line holds `word`.
fn cmdline_has(word: &[u8]) -> bool {
    let mut buf = [0u8; 128];
    let mut block = [buf.as_mut_ptr() as usize, buf.len()];
    // SAFETY: SYS_GET_CMDLINE writes at most `block[1]` bytes into `buf`
    // and the length back into `block[1]`; both live until we read them.
    let r = unsafe { syscall1(nr::GET_CMDLINE, block.as_mut_ptr() as usize) };
    // SAFETY: reading back what the host wrote.
    let len = unsafe { core::ptr::read_volatile(&block[1]) };
    if r != 0 || len > buf.len() {
        return false;
    }
    let line = buf.get(..len).unwrap_or(&[]);
    line.split(|&b| b == b' ').any(|w| w == word)
}

fn fail(what: &str, e: &dyn core::fmt::Display) -> ! {
    hprintln!("error {what}: {e}");
    debug::exit(debug::EXIT_FAILURE);
    // Not reached: the exit above stops QEMU; a fault here exits 1.
    cortex_m::asm::udf()
}

#[entry]
fn main() -> ! {
    // cortex-m-rt turns these into `&'static mut`, placed in .bss / .data.
    static mut SOLVER: PaperSolver = PaperSolver::new();
    static mut PIXEL_BUF: [[u8; 3]; PIXELS] = [[0; 3]; PIXELS];
    static mut NARROW_BUF: [[u8; 3]; PIXELS] = [[0; 3]; PIXELS];
    static mut TABLE_BUF: [[Config; CONFIGS]; OBJECTS] = [[config(0, 0); CONFIGS]; OBJECTS];

    if cmdline_has(b"panic") {
        panic!("deliberate panic (semihosting command line `panic`)");
    }
    if cmdline_has(b"fault") {
        // An undefined instruction: the HardFault handler must exit 1.
        cortex_m::asm::udf();
    }

    hprintln!(
        "nerflex-firmware target={} machine=mps2-an386",
        env!("FIRMWARE_TARGET")
    );

    // 1. Configuration tables: the fitted profiles evaluated on board.
    let profiles: &[ObjectProfile; OBJECTS] = &generated::PROFILES;
    let (r, profile_peak) = stack::measure(|| evaluate_profiles(profiles, TABLE_BUF));
    if let Err((i, e)) = r {
        hprintln!("error profile object={}", i);
        fail(profiles.get(i).map_or("profile", |p| p.name), &e);
    }
    let tables: &[[Config; CONFIGS]; OBJECTS] = TABLE_BUF;
    for (i, (t, p)) in tables.iter().zip(profiles).enumerate() {
        let (min, max) = t.iter().fold((u64::MAX, 0), |(lo, hi), c| {
            (lo.min(c.size.0), hi.max(c.size.0))
        });
        hprintln!(
            "table object={} name={} configs={} min_bytes={} max_bytes={} fnv={:08x}",
            i,
            p.name,
            t.len(),
            min,
            max,
            workload::table_hash(t)
        );
    }

    // 2. Plans.
    let mut solver_peak = stack::Peak::Bytes(0);
    for device in &workload::DEVICES {
        let (r, peak) = stack::measure(|| plan(SOLVER, tables, device));
        solver_peak = match (solver_peak, peak) {
            (stack::Peak::Bytes(a), stack::Peak::Bytes(b)) => stack::Peak::Bytes(a.max(b)),
            (_, p @ stack::Peak::AtLeast(_)) | (p @ stack::Peak::AtLeast(_), _) => p,
        };
        let p = match r {
            Ok(p) => p,
            Err(e) => {
                hprintln!("error plan device={}", device.name);
                fail(device.name, &e)
            }
        };
        hprintln!(
            "plan device={} budget_bytes={} unit_bytes={} choices={},{},{},{},{} total_bytes={} total_units={} total_quality_q31={}",
            device.name,
            device.budget.0,
            UNIT.0,
            p.choices[0],
            p.choices[1],
            p.choices[2],
            p.choices[3],
            p.choices[4],
            p.total_bytes,
            p.total_units,
            p.total_quality_q31
        );
        for (i, (&c, prof)) in p.choices.iter().zip(profiles).enumerate() {
            let np = prof.patches.len();
            let (g, pp) = (
                prof.grids.get(c as usize / np).copied().unwrap_or(0),
                prof.patches.get(c as usize % np).copied().unwrap_or(0),
            );
            let cfg = tables[i].get(c as usize).copied().unwrap_or(config(0, 0));
            hprintln!(
                "pick device={} object={} name={} index={} g={} p={} size_bytes={} quality_q31={}",
                device.name,
                i,
                prof.name,
                c,
                g,
                pp,
                cfg.size.0,
                cfg.quality.raw()
            );
        }
    }

    // 3. The shaded tile.
    let mlp = &generated::MLP;
    hprintln!(
        "mlp source={} fnv={:08x} weight_frac={},{},{} out_frac={},{},{}",
        generated::MLP_SOURCE,
        workload::mlp_hash(mlp),
        mlp.l0.weight_frac,
        mlp.l1.weight_frac,
        mlp.l2.weight_frac,
        mlp.l0.out_frac,
        mlp.l1.out_frac,
        mlp.l2.out_frac
    );
    let px: &mut [[u8; 3]; PIXELS] = PIXEL_BUF;
    let ((), tile_peak) = stack::measure(|| shade_tile(mlp, px));
    print_rows("row", px);
    hprintln!(
        "tile width={} height={} fnv={:08x}",
        TILE_W,
        TILE_H,
        workload::pixels_hash(px)
    );

    // The same tile with the narrow shader.
    let narrow = &generated::NARROW;
    let [c0, c1, c2, c3] = generated::NARROW_CHECK;
    hprintln!(
        "narrow source={} fnv={:08x} weight_max={} logit_lshift={} check={},{},{},{} passes={}",
        generated::MLP_SOURCE,
        workload::narrow_hash(narrow),
        narrow.weight_max,
        narrow.logit_lshift,
        c0,
        c1,
        c2,
        c3,
        u8::from(generated::NARROW_PASSES)
    );
    let npx: &mut [[u8; 3]; PIXELS] = NARROW_BUF;
    let ((), narrow_tile_peak) = stack::measure(|| shade_tile_narrow(narrow, npx));
    print_rows("nrow", npx);
    hprintln!(
        "ntile width={} height={} fnv={:08x}",
        TILE_W,
        TILE_H,
        workload::pixels_hash(npx)
    );

    // 4. Costs.
    let (_, pixel_peak) = shade_one(mlp, 3, 5);
    let (_, narrow_pixel_peak) = shade_one_narrow(narrow, 3, 5);
    hprintln!(
        "stack profile_bytes={} solver_bytes={} shade_pixel_bytes={} shade_tile_bytes={} narrow_pixel_bytes={} narrow_tile_bytes={}",
        profile_peak,
        solver_peak,
        pixel_peak,
        tile_peak,
        narrow_pixel_peak,
        narrow_tile_peak
    );
    hprintln!(
        "memory solver_tables_bytes={} solver_static_bytes={} config_tables_bytes={} mlp_tables_bytes={} narrow_tables_bytes={}",
        PaperSolver::MEMORY_BYTES,
        size_of::<PaperSolver>(),
        size_of::<[[Config; CONFIGS]; OBJECTS]>(),
        size_of::<FixedMlp>(),
        size_of::<NarrowMlp>()
    );
    hprintln!("done");
    debug::exit(debug::EXIT_SUCCESS);
    // Not reached: the exit above stops QEMU; a fault here exits 1.
    cortex_m::asm::udf()
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    hprintln!("error hardfault pc={:#010x}", ef.pc());
    debug::exit(debug::EXIT_FAILURE);
    // Not reached: the exit above stops QEMU; a fault here exits 1.
    cortex_m::asm::udf()
}

#[exception]
unsafe fn DefaultHandler(irq: i16) {
    hprintln!("error unexpected exception irq={}", irq);
    debug::exit(debug::EXIT_FAILURE);
}
