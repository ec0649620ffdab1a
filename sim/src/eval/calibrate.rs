//! Calibrating a device's throughputs against one figure of the paper.
//!
//! The device files state peak-derived throughputs for the quad rate and
//! the MLP's multiply-add rate; what a WebGL viewer in a phone browser gets
//! of them is unknown. One efficiency factor `s` per device scales both
//! (the fixed frame overhead, the load rates and the limits are not
//! touched), chosen so that the simulated mean FPS of one scene equals the
//! paper's: NeRFlex (DP) on Scene 3, 35 FPS on the iPhone 13 and 25 FPS on
//! the Pixel 4. Everything else the simulator reports is a prediction.

use crate::device::Device;
use crate::pipeline::Realised;
use crate::simulate::assets::AssetScene;
use crate::simulate::{self, SimOptions, Turntable, TurntableSpec};
use anyhow::Context as _;
use serde::{Deserialize, Serialize};

/// The result of calibrating one device.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Device name.
    pub device: String,
    /// What was matched, e.g. `scene3 dp`.
    pub against: String,
    /// The paper's mean FPS.
    pub target_fps: f64,
    /// Mean FPS with the device file's throughputs.
    pub fps_with_file: f64,
    /// The factor on `mac_per_s` and `quads_per_s` that gives the target
    /// (1 when the file is already calibrated).
    pub scale: f64,
    /// `mac_per_s` × scale.
    pub mac_per_s: f64,
    /// `quads_per_s` × scale.
    pub quads_per_s: f64,
    /// Mean FPS at that scale (equals the target unless unreachable).
    pub fps_at_scale: f64,
}

/// How far from 1 the factor may be for the device file to count as
/// calibrated (1 %: the bisection's own tolerance is far below).
pub const MATCHED: f64 = 0.01;

impl Calibration {
    /// Whether the device file already makes this cell match the paper
    /// (the factor that would match is 1 within [`MATCHED`]).
    pub fn matched(&self) -> bool {
        (self.scale - 1.0).abs() <= MATCHED
    }
}

/// Finds the throughput scale that makes the mean FPS of `realised` on
/// `device` equal `target_fps` (bisection on a log scale; the mean FPS does
/// not decrease as throughputs grow).
pub fn calibrate(
    realised: &Realised,
    device: &Device,
    turntable: TurntableSpec,
    sim: SimOptions,
    target_fps: f64,
    against: &str,
) -> anyhow::Result<Calibration> {
    let assets = realised
        .objects
        .iter()
        .map(|o| {
            crate::asset::Asset::load(&o.asset)
                .with_context(|| format!("loading {}", o.asset.display()))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let scene = AssetScene::new(
        realised.objects.iter().map(|o| o.name.clone()).collect(),
        assets,
        realised.objects.iter().map(|o| o.file_bytes).collect(),
    );
    let items = scene.load_items();
    let tt = Turntable::new(turntable, device.viewer(), &scene);
    let at = |s: f64| -> anyhow::Result<f64> {
        let mut d = device.clone();
        d.throughput.mac_per_s *= s;
        d.throughput.quads_per_s *= s;
        Ok(simulate::simulate(&d, &items, &tt, sim)?.mean_fps)
    };
    let fps_with_file = at(1.0)?;
    let (mut lo, mut hi) = (1e-4f64, 1e4f64);
    let (f_lo, f_hi) = (at(lo)?, at(hi)?);
    let scale = if target_fps <= f_lo {
        lo
    } else if target_fps >= f_hi {
        hi
    } else {
        for _ in 0..60 {
            let mid = (lo * hi).sqrt();
            if at(mid)? < target_fps {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi / lo < 1.0 + 1e-6 {
                break;
            }
        }
        (lo * hi).sqrt()
    };
    Ok(Calibration {
        device: device.name.clone(),
        against: against.to_string(),
        target_fps,
        fps_with_file,
        scale,
        mac_per_s: device.throughput.mac_per_s * scale,
        quads_per_s: device.throughput.quads_per_s * scale,
        fps_at_scale: at(scale)?,
    })
}
