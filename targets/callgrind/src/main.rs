//! The firmware's workload on the host, one operation per run, so that
//! `valgrind --tool=callgrind --collect-atstart=no --toggle-collect=…`
//! counts the instructions of exactly that operation (see
//! `targets/callgrind.sh`):
//!
//! - `solve-iphone13`, `solve-pixel4`: one exact MCK solve of the 5-object,
//!   45-configuration plan in 0.1 MB units (`count_solve`);
//! - `pixel`: one shaded pixel, the fixed-point lego MLP alone
//!   (`count_pixel`);
//! - `tile`: the firmware's 16 × 16 tile including the per-pixel inputs
//!   (`count_tile`).
//!
//! It prints its result, so the work cannot be optimised away, and the
//! firmware's line for it, so a reader can compare.

#[path = "../../cortex-m4/src/workload.rs"]
mod workload;

#[allow(clippy::all, dead_code)]
mod generated {
    use super::config;
    use crate::workload::{FitParams, ObjectProfile};
    use nerflex_core::mck::Config;
    use nerflex_core::shader::{FixedLayer, FixedMlp};
    include!(concat!(env!("OUT_DIR"), "/generated.rs"));
}

use nerflex_core::mck::{Config, MckError, Solver};
use nerflex_core::shader::{FixedMlp, ViewDir};
use nerflex_core::units::{Bytes, QualityQ};
use std::hint::black_box;
use std::process::ExitCode;
use workload::{Device, CONFIGS, OBJECTS, TILE_H, TILE_W, UNIT, UNITS};

type PaperSolver = Solver<OBJECTS, CONFIGS, UNITS>;

const fn config(size_bytes: u64, quality_q31: u32) -> Config {
    Config {
        size: Bytes(size_bytes),
        quality: match QualityQ::from_raw(quality_q31) {
            Some(q) => q,
            None => QualityQ::ZERO,
        },
    }
}

#[inline(never)]
fn count_solve(
    solver: &mut PaperSolver,
    tables: &[[Config; CONFIGS]; OBJECTS],
    device: &Device,
) -> Result<(Vec<u8>, u64, u64), MckError> {
    let s = solver.solve(tables, device.budget, UNIT)?;
    Ok((s.choices.to_vec(), s.total_size.0, s.total_quality.0))
}

#[inline(never)]
fn count_pixel(mlp: &FixedMlp, f0: [u8; 4], f1: [u8; 4], dir: ViewDir) -> [u8; 3] {
    mlp.shade(f0, f1, dir)
}

#[inline(never)]
fn count_tile(mlp: &FixedMlp, out: &mut [[u8; 3]]) {
    workload::shade_tile(mlp, out);
}

fn main() -> ExitCode {
    let mode = std::env::args().nth(1).unwrap_or_default();
    let mlp = black_box(&generated::MLP);
    let tables = black_box(&generated::TABLES);
    match mode.as_str() {
        "solve-iphone13" | "solve-pixel4" => {
            let name = mode.trim_start_matches("solve-");
            let Some(device) = workload::DEVICES.iter().find(|d| d.name == name) else {
                return ExitCode::FAILURE;
            };
            let mut solver = Box::new(PaperSolver::new());
            match count_solve(&mut solver, tables, device) {
                Ok((choices, bytes, q)) => println!(
                    "plan device={} choices={choices:?} total_bytes={bytes} total_quality_q31={q}",
                    device.name
                ),
                Err(e) => {
                    eprintln!("plan failed: {e}");
                    return ExitCode::FAILURE;
                }
            }
        }
        "pixel" => {
            let (f0, f1) = workload::texels(3, 5);
            let dir = workload::view_dir(3, 5);
            let rgb = count_pixel(mlp, black_box(f0), black_box(f1), black_box(dir));
            println!(
                "pixel x=3 y=5 rgb={rgb:?} (mlp source={})",
                generated::MLP_SOURCE
            );
        }
        "tile" => {
            let mut px = vec![[0u8; 3]; (TILE_W * TILE_H) as usize];
            count_tile(mlp, &mut px);
            println!(
                "tile width={TILE_W} height={TILE_H} fnv={:08x} (mlp source={})",
                workload::pixels_hash(&px),
                generated::MLP_SOURCE
            );
        }
        _ => {
            eprintln!("usage: nerflex-count solve-iphone13|solve-pixel4|pixel|tile");
            return ExitCode::FAILURE;
        }
    }
    ExitCode::SUCCESS
}
