//! The firmware's workload, defined once and shared verbatim (through
//! `#[path]`) by the firmware, its build script, the host comparison test
//! (`tests/tests/firmware_m4.rs`) and the host instruction counter
//! (`targets/callgrind/`), so that board and host run exactly the same
//! problem.
//!
//! - the plan: 5 fitted profiles evaluated into 5 × 45 configurations by
//!   the fixed-point profiler, the iPhone 13 (240 MB) and Pixel 4 (150 MB)
//!   budgets in 0.1 MB units (2400 units);
//! - the tile: 16 × 16 texels with deterministic feature values and view
//!   directions, shaded by the fixed-point MLP;
//! - the fallback weight set used when the real `lego_mlp.json` is absent;
//! - FNV-1a checksums of tables and pixels, printed by the firmware.
//!
//! `no_std`-clean: only `core` and `nerflex_core`.

#![allow(dead_code)] // each includer uses a different part

use nerflex_core::mck::Config;
use nerflex_core::profiler::{ConfigSpace, Params, Profile, ProfileError};
use nerflex_core::shader::narrow::{NarrowLayer, NarrowMlp};
use nerflex_core::shader::{FixedLayer, FixedMlp, MlpWeights, ViewDir};
use nerflex_core::units::Bytes;

/// Objects in the plan (the paper's five).
pub const OBJECTS: usize = 5;
/// Grid resolutions g per object.
pub const GRIDS: usize = 9;
/// Patch sizes p per object.
pub const PATCHES: usize = 5;
/// Configurations per object (9 grids × 5 patch sizes, the paper's 45).
pub const CONFIGS: usize = GRIDS * PATCHES;
/// The budget unit: 0.1 MB.
pub const UNIT: Bytes = Bytes(100_000);
/// Budget units of the largest budget (240 MB / 0.1 MB).
pub const UNITS: usize = 2400;

/// One object's fitted profile and its configuration space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectProfile {
    /// Object name.
    pub name: &'static str,
    /// Size model `S = k·(g+a)^e·(p+b)² + m`, bytes.
    pub size: Params,
    /// Quality model `Q = m − k/((g+a)^e·(p+b)²)`, SSIM.
    pub quality: Params,
    /// Grid resolutions.
    pub grids: [u32; GRIDS],
    /// Patch sizes.
    pub patches: [u32; PATCHES],
}

/// Evaluates the fitted profiles into configuration tables with the core's
/// fixed-point profiler, exactly as the firmware does on board. On error:
/// the object's index and the cause.
pub fn evaluate_profiles(
    profiles: &[ObjectProfile; OBJECTS],
    tables: &mut [[Config; CONFIGS]; OBJECTS],
) -> Result<(), (usize, ProfileError)> {
    for (i, (p, t)) in profiles.iter().zip(tables.iter_mut()).enumerate() {
        let profile = Profile::from_params(&p.size, &p.quality).map_err(|e| (i, e))?;
        let space = ConfigSpace::new(&p.grids, &p.patches).map_err(|e| (i, e))?;
        profile.fill_table(&space, t).map_err(|e| (i, e))?;
    }
    Ok(())
}

/// A device budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Device {
    /// Name printed by the firmware (`sim/devices/<name>.toml`).
    pub name: &'static str,
    /// Memory budget H.
    pub budget: Bytes,
}

/// The two budgets of the paper.
pub const DEVICES: [Device; 2] = [
    Device {
        name: "iphone13",
        budget: Bytes::from_mb_u64(240),
    },
    Device {
        name: "pixel4",
        budget: Bytes::from_mb_u64(150),
    },
];

/// Tile width in texels (pixels).
pub const TILE_W: u32 = 16;
/// Tile height in texels (pixels).
pub const TILE_H: u32 = 16;

/// xorshift32 step (never zero for a non-zero state).
const fn xorshift(mut s: u32) -> u32 {
    s ^= s << 13;
    s ^= s >> 17;
    s ^= s << 5;
    s
}

/// The two feature texels of tile pixel `(x, y)`: pseudo-random bytes,
/// always occupied (`feat0.R ≥ 1`), alphas spanning the full byte range.
pub fn texels(x: u32, y: u32) -> ([u8; 4], [u8; 4]) {
    let mut s = 0x9E37_79B9u32 ^ (y.wrapping_mul(TILE_W).wrapping_add(x)).wrapping_mul(0x85EB_CA6B);
    let mut byte = || {
        s = xorshift(s);
        (s >> 24) as u8
    };
    let f0 = [byte().max(1), byte(), byte(), byte()];
    let f1 = [byte(), byte(), byte(), byte()];
    (f0, f1)
}

/// The world-frame view direction of tile pixel `(x, y)`: rays of a pinhole
/// camera looking along +y and 30° down, the tile spanning about 40°.
pub fn view_dir(x: u32, y: u32) -> ViewDir {
    let u = (2.0 * f64::from(x) + 1.0) / f64::from(TILE_W) - 1.0; // (-1, 1)
    let v = 1.0 - (2.0 * f64::from(y) + 1.0) / f64::from(TILE_H);
    // Camera basis: forward (0, cos30, -sin30), right (1, 0, 0), up (0, sin30, cos30).
    let (c, s) = (0.866_025_403_784_438_6, 0.5);
    let t = 0.364; // tan(20°): half the tile's field of view
    let d = [u * t, c + v * t * s, -s + v * t * c];
    // Never zero (the forward component dominates): from_f64 succeeds.
    ViewDir::from_f64(d).unwrap_or_default()
}

/// The deterministic stand-in for `lego_mlp.json` when the data folder is
/// absent: weights uniform in ±0.6, biases in ±0.2 (a plausible
/// MobileNeRF-like range). Flagged as `synthetic` in the firmware output.
pub fn synthetic_weights() -> MlpWeights {
    let mut s = 0x2545_F491u32;
    let mut next = |scale: f32| {
        s = xorshift(s);
        ((s >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0) * scale
    };
    let mut w = MlpWeights::ZERO;
    w.w0.iter_mut().flatten().for_each(|v| *v = next(0.6));
    w.b0.iter_mut().for_each(|v| *v = next(0.2));
    w.w1.iter_mut().flatten().for_each(|v| *v = next(0.6));
    w.b1.iter_mut().for_each(|v| *v = next(0.2));
    w.w2.iter_mut().flatten().for_each(|v| *v = next(0.6));
    w.b2.iter_mut().for_each(|v| *v = next(0.2));
    w
}

/// FNV-1a, 32 bits: the checksum the firmware prints for tables and pixels.
#[derive(Clone, Copy, Debug)]
pub struct Fnv(pub u32);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0x811C_9DC5)
    }
}

impl Fnv {
    /// Feeds bytes.
    pub fn bytes(&mut self, data: &[u8]) {
        for &b in data {
            self.0 = (self.0 ^ u32::from(b)).wrapping_mul(0x0100_0193);
        }
    }

    /// Feeds a `u32`, little-endian.
    pub fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }

    /// Feeds a `u64`, little-endian.
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
}

fn hash_layer<const I: usize, const O: usize>(h: &mut Fnv, l: &FixedLayer<I, O>) {
    for row in &l.weights {
        for &w in row {
            h.u32(w as u32);
        }
    }
    for &b in &l.bias {
        h.u64(b as u64);
    }
    h.bytes(&[l.weight_frac, l.out_frac, l.shift]);
}

/// Checksum of the fixed-point MLP tables.
pub fn mlp_hash(m: &FixedMlp) -> u32 {
    let mut h = Fnv::default();
    hash_layer(&mut h, &m.l0);
    hash_layer(&mut h, &m.l1);
    hash_layer(&mut h, &m.l2);
    h.0
}

fn hash_narrow_layer<const P: usize, const G: usize, const N: usize>(
    h: &mut Fnv,
    l: &NarrowLayer<P, G, N>,
) {
    for &w in l.w.iter().flatten().flatten() {
        h.u32(w);
    }
    for &b in l.bias.iter().flatten() {
        h.u32(b as u32);
    }
}

/// Checksum of the narrow MLP tables.
pub fn narrow_hash(m: &NarrowMlp) -> u32 {
    let mut h = Fnv::default();
    hash_narrow_layer(&mut h, &m.l0);
    hash_narrow_layer(&mut h, &m.l1);
    hash_narrow_layer(&mut h, &m.l2);
    h.bytes(&[m.logit_lshift]);
    h.bytes(&m.weight_max.to_le_bytes());
    h.0
}

/// Checksum of one object's configuration table (sizes and raw qualities).
pub fn table_hash(table: &[Config]) -> u32 {
    let mut h = Fnv::default();
    for c in table {
        h.u64(c.size.0);
        h.u32(c.quality.raw());
    }
    h.0
}

/// Shades the whole tile row by row into `out` (`TILE_W · TILE_H` pixels).
pub fn shade_tile(mlp: &FixedMlp, out: &mut [[u8; 3]]) {
    let coords = (0..TILE_H).flat_map(|y| (0..TILE_W).map(move |x| (x, y)));
    for (px, (x, y)) in out.iter_mut().zip(coords) {
        let (f0, f1) = texels(x, y);
        *px = mlp.shade(f0, f1, view_dir(x, y));
    }
}

/// [`shade_tile`] with the narrow shader.
pub fn shade_tile_narrow(mlp: &NarrowMlp, out: &mut [[u8; 3]]) {
    let coords = (0..TILE_H).flat_map(|y| (0..TILE_W).map(move |x| (x, y)));
    for (px, (x, y)) in out.iter_mut().zip(coords) {
        let (f0, f1) = texels(x, y);
        *px = mlp.shade(f0, f1, view_dir(x, y));
    }
}

/// Checksum of shaded pixels.
pub fn pixels_hash(px: &[[u8; 3]]) -> u32 {
    let mut h = Fnv::default();
    for p in px {
        h.bytes(p);
    }
    h.0
}
