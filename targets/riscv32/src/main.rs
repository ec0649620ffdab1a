//! nerflex-core on RISC-V (QEMU `virt`, `riscv32imac`): the Cortex-M
//! firmware's workload (`../cortex-m4/src/workload.rs`, same generated
//! tables) on a second instruction set, printed over the 16550 UART in the
//! same `record key=value …` lines, which `tests/tests/firmware_riscv.rs`
//! compares with the host build:
//!
//! 1. the five fitted profiles evaluated into 5 × 45 configurations;
//! 2. the MCK plans for the iPhone 13 and Pixel 4 budgets;
//! 3. the 16 × 16 tile shaded by the exact and the narrow lego MLP.
//!
//! The run ends with `done` and QEMU exits 0 (the `sifive_test` device);
//! an error or a panic prints `error …` and exits 1.

#![no_std]
#![no_main]

#[path = "../../cortex-m4/src/workload.rs"]
mod workload;

use core::fmt::Write;
use core::ptr::addr_of_mut;

use nerflex_core::mck::{Config, Solver};
use nerflex_core::shader::narrow::NarrowMlp;
use nerflex_core::shader::{FixedMlp, ViewDir};
use nerflex_core::units::{Bytes, QualityQ};
use workload::{ObjectProfile, CONFIGS, OBJECTS, TILE_H, TILE_W, UNIT, UNITS};

#[allow(clippy::all, dead_code)]
mod generated {
    use crate::workload::ObjectProfile;
    use nerflex_core::profiler::{Family, Params};
    use nerflex_core::shader::narrow::{NarrowLayer, NarrowMlp};
    use nerflex_core::shader::{FixedLayer, FixedMlp};
    include!(concat!(env!("OUT_DIR"), "/generated.rs"));
}

type PaperSolver = Solver<OBJECTS, CONFIGS, UNITS>;
const PIXELS: usize = (TILE_W * TILE_H) as usize;

// Entry: a stack, a zeroed .bss, then `main`.
core::arch::global_asm!(
    ".section .text.start, \"ax\"",
    ".global _start",
    "_start:",
    "    la sp, _stack_top",
    "    la t0, _sbss",
    "    la t1, _ebss",
    "1:  bgeu t0, t1, 2f",
    "    sw zero, 0(t0)",
    "    addi t0, t0, 4",
    "    j 1b",
    "2:  call main",
    "3:  j 3b",
);

/// The virt machine's 16550 UART.
struct Uart;
const UART: usize = 0x1000_0000;

impl Write for Uart {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for b in s.bytes() {
            // SAFETY: MMIO registers of the virt machine's UART: wait for
            // the transmit holding register (LSR bit 5), then write it.
            unsafe {
                while core::ptr::read_volatile((UART + 5) as *const u8) & 0x20 == 0 {}
                core::ptr::write_volatile(UART as *mut u8, b);
            }
        }
        Ok(())
    }
}

macro_rules! println {
    ($($t:tt)*) => {{
        let _ = writeln!(Uart, $($t)*);
    }};
}

/// Stops QEMU through the `sifive_test` device: 0 → success, else failure.
fn exit(code: u32) -> ! {
    let v = if code == 0 {
        0x5555
    } else {
        0x3333 | (code << 16)
    };
    // SAFETY: the virt machine's test device at 0x10_0000.
    unsafe { core::ptr::write_volatile(0x10_0000 as *mut u32, v) };
    loop {
        core::hint::spin_loop();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    println!("error panic {}", info.message());
    exit(1)
}

const fn config(size_bytes: u64, quality_q31: u32) -> Config {
    Config {
        size: Bytes(size_bytes),
        quality: match QualityQ::from_raw(quality_q31) {
            Some(q) => q,
            None => QualityQ::ZERO,
        },
    }
}

static mut SOLVER: PaperSolver = PaperSolver::new();
static mut TABLES: [[Config; CONFIGS]; OBJECTS] = [[config(0, 0); CONFIGS]; OBJECTS];
static mut PIXEL_BUF: [[u8; 3]; PIXELS] = [[0; 3]; PIXELS];

/// One pixel, exact shader: a call of its own so `targets/riscv-icount.sh`
/// can count its instructions.
#[inline(never)]
fn pixel_exact(m: &FixedMlp, f0: [u8; 4], f1: [u8; 4], d: ViewDir) -> [u8; 3] {
    m.shade(f0, f1, d)
}

/// One pixel, narrow shader (see [`pixel_exact`]).
#[inline(never)]
fn pixel_narrow(m: &NarrowMlp, f0: [u8; 4], f1: [u8; 4], d: ViewDir) -> [u8; 3] {
    m.shade(f0, f1, d)
}

/// The tile as `workload::shade_tile` shades it, one counted call per pixel.
fn shade_tile(out: &mut [[u8; 3]], shade: impl Fn([u8; 4], [u8; 4], ViewDir) -> [u8; 3]) {
    let coords = (0..TILE_H).flat_map(|y| (0..TILE_W).map(move |x| (x, y)));
    for (px, (x, y)) in out.iter_mut().zip(coords) {
        let (f0, f1) = workload::texels(x, y);
        *px = shade(f0, f1, workload::view_dir(x, y));
    }
}

fn print_rows(tag: &str, px: &[[u8; 3]]) {
    for (y, row) in px.chunks(TILE_W as usize).enumerate() {
        let _ = write!(Uart, "{tag} y={y} rgb=");
        for p in row {
            let _ = write!(Uart, "{:02x}{:02x}{:02x}", p[0], p[1], p[2]);
        }
        println!();
    }
}

#[no_mangle]
extern "C" fn main() -> ! {
    println!(
        "nerflex-firmware target={} machine=virt",
        env!("FIRMWARE_TARGET")
    );
    // SAFETY: single hart, no interrupts: these are the only references.
    let (solver, tables, px) = unsafe {
        (
            &mut *addr_of_mut!(SOLVER),
            &mut *addr_of_mut!(TABLES),
            &mut *addr_of_mut!(PIXEL_BUF),
        )
    };

    // 1. Configuration tables.
    let profiles: &[ObjectProfile; OBJECTS] = &generated::PROFILES;
    if let Err((i, e)) = workload::evaluate_profiles(profiles, tables) {
        println!("error profile object={i}: {e}");
        exit(1);
    }
    for (i, (t, p)) in tables.iter().zip(profiles).enumerate() {
        let (min, max) = t.iter().fold((u64::MAX, 0), |(lo, hi), c| {
            (lo.min(c.size.0), hi.max(c.size.0))
        });
        println!(
            "table object={i} name={} configs={} min_bytes={min} max_bytes={max} fnv={:08x}",
            p.name,
            t.len(),
            workload::table_hash(t)
        );
    }

    // 2. Plans.
    for device in &workload::DEVICES {
        let s = match solver.solve(tables, device.budget, UNIT) {
            Ok(s) => s,
            Err(e) => {
                println!("error plan device={}: {e}", device.name);
                exit(1)
            }
        };
        let c = s.choices;
        println!(
            "plan device={} budget_bytes={} unit_bytes={} choices={},{},{},{},{} total_bytes={} total_units={} total_quality_q31={}",
            device.name,
            device.budget.0,
            UNIT.0,
            c[0],
            c[1],
            c[2],
            c[3],
            c[4],
            s.total_size.0,
            s.total_units,
            s.total_quality.0
        );
    }

    // 3. The tile, exact then narrow.
    let mlp = &generated::MLP;
    println!(
        "mlp source={} fnv={:08x}",
        generated::MLP_SOURCE,
        workload::mlp_hash(mlp)
    );
    shade_tile(px, |f0, f1, d| pixel_exact(mlp, f0, f1, d));
    print_rows("row", px);
    println!(
        "tile width={TILE_W} height={TILE_H} fnv={:08x}",
        workload::pixels_hash(px)
    );
    let narrow: &NarrowMlp = &generated::NARROW;
    println!(
        "narrow source={} fnv={:08x} passes={}",
        generated::MLP_SOURCE,
        workload::narrow_hash(narrow),
        u8::from(generated::NARROW_PASSES)
    );
    shade_tile(px, |f0, f1, d| pixel_narrow(narrow, f0, f1, d));
    print_rows("nrow", px);
    println!(
        "ntile width={TILE_W} height={TILE_H} fnv={:08x}",
        workload::pixels_hash(px)
    );
    println!("done");
    exit(0)
}
