//! The firmware's workload on the host, one operation per run, so that
//! `valgrind --tool=callgrind --collect-atstart=no --toggle-collect=…`
//! counts the instructions of exactly that operation (see
//! `targets/callgrind.sh`):
//!
//! - `profiles`: the five fitted profiles evaluated into 5 × 45
//!   configurations by the fixed-point profiler (`count_profiles`);
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
    use crate::workload::ObjectProfile;
    use nerflex_core::profiler::{Family, Params};
    use nerflex_core::shader::narrow::{NarrowLayer, NarrowMlp};
    use nerflex_core::shader::{FixedLayer, FixedMlp};
    include!(concat!(env!("OUT_DIR"), "/generated.rs"));
}

use nerflex_core::mck::{Config, MckError, Solver};
use nerflex_core::profiler::ProfileError;
use nerflex_core::shader::{FixedMlp, ViewDir};
use nerflex_core::units::{Bytes, QualityQ};
use std::hint::black_box;
use std::process::ExitCode;
use workload::ObjectProfile;
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
fn count_profiles(
    profiles: &[ObjectProfile; OBJECTS],
    tables: &mut [[Config; CONFIGS]; OBJECTS],
) -> Result<(), (usize, ProfileError)> {
    workload::evaluate_profiles(profiles, tables)
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
fn count_narrow_pixel(
    mlp: &nerflex_core::shader::narrow::NarrowMlp,
    f0: [u8; 4],
    f1: [u8; 4],
    dir: ViewDir,
) -> [u8; 3] {
    mlp.shade(f0, f1, dir)
}

/// Eight pixels through the AVX2 batch (inputs packed first, as `render` does).
#[inline(never)]
fn count_narrow_batch(
    mlp: &nerflex_core::shader::narrow::NarrowMlp,
    px: &[([u8; 4], [u8; 4], ViewDir); 8],
) -> [[u8; 3]; 8] {
    use nerflex_core::shader::narrow::batch;
    let mut x = [[0u32; batch::LANES]; nerflex_core::shader::narrow::INPUT_PAIRS];
    for (lane, &(f0, f1, d)) in px.iter().enumerate() {
        batch::set_lane(&mut x, lane, f0, f1, d);
    }
    // SAFETY: only called after AVX2 was detected.
    #[allow(unsafe_code)]
    unsafe {
        batch::avx2::shade(mlp, &x)
    }
}

#[inline(never)]
fn count_tile(mlp: &FixedMlp, out: &mut [[u8; 3]]) {
    workload::shade_tile(mlp, out);
}

fn main() -> ExitCode {
    let mode = std::env::args().nth(1).unwrap_or_default();
    let mlp = black_box(&generated::MLP);
    let profiles = black_box(&generated::PROFILES);
    let mut tables = Box::new([[config(0, 0); CONFIGS]; OBJECTS]);
    let evaluated = if mode == "profiles" {
        count_profiles(profiles, &mut tables)
    } else {
        workload::evaluate_profiles(profiles, &mut tables)
    };
    if let Err((i, e)) = evaluated {
        eprintln!("profile of object {i}: {e}");
        return ExitCode::FAILURE;
    }
    let tables = black_box(&*tables);
    match mode.as_str() {
        "profiles" => {
            for (p, t) in profiles.iter().zip(tables) {
                println!(
                    "table name={} configs={} fnv={:08x}",
                    p.name,
                    t.len(),
                    workload::table_hash(t)
                );
            }
        }
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
        "narrow-pixel" => {
            let (f0, f1) = workload::texels(3, 5);
            let dir = workload::view_dir(3, 5);
            let narrow = black_box(&generated::NARROW);
            let rgb = count_narrow_pixel(narrow, black_box(f0), black_box(f1), black_box(dir));
            println!(
                "narrow pixel x=3 y=5 rgb={rgb:?} (mlp source={})",
                generated::MLP_SOURCE
            );
        }
        "narrow-batch" => {
            if !std::arch::is_x86_feature_detected!("avx2") {
                eprintln!("this CPU has no AVX2");
                return ExitCode::FAILURE;
            }
            let px: [_; 8] = std::array::from_fn(|i| {
                let (f0, f1) = workload::texels(i as u32, 5);
                (f0, f1, workload::view_dir(i as u32, 5))
            });
            let rgb = count_narrow_batch(black_box(&generated::NARROW), black_box(&px));
            println!("narrow batch y=5 x=0..8 rgb={rgb:?}");
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
            eprintln!("usage: nerflex-count profiles|solve-iphone13|solve-pixel4|pixel|narrow-pixel|narrow-batch|tile");
            return ExitCode::FAILURE;
        }
    }
    ExitCode::SUCCESS
}
