//! The frame loop.
//!
//! The viewer starts drawing at once and adds each object when its files
//! are in (as MobileNeRF's web viewer does):
//!
//! 1. **reading** — the objects' files arrive one after the other at the
//!    device's load bandwidth (`load_mb_per_s` of file bytes). Reading is
//!    asynchronous: frames go on meanwhile.
//! 2. **decoding** — an arrived object is decoded and uploaded on the
//!    viewer's main thread (`decode_mb_per_s` of resident bytes: atlas
//!    pages, vertex buffers). The frame during which that happens is late
//!    by the decode time: the stutter at the start of the paper's FPS
//!    curves, between which the partly loaded scene draws fast frames.
//! 3. **drawing** — from the next frame on, the object is drawn.
//!
//! Each frame: its angle is the turntable's at the frame's start time
//! (7.5 s per revolution), its work the coverage of the loaded objects at
//! that angle, its time the device's frame cost plus any decode it waited
//! for, at least one refresh interval; its FPS the device's
//! ([`Device::fps`]: capped by the refresh rate, minus the soft-limit
//! penalty while the loaded data is over the soft limit).
//!
//! A scene whose data is over the hard limit does not load: every frame has
//! FPS 0 and the simulation carries the reason.

use super::turntable::Turntable;
use crate::device::{Device, LoadFailure};
use nerflex_core::units::Bytes;
use serde::{Deserialize, Serialize};

/// One object as the viewer loads it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoadItem {
    /// Name (for reports).
    pub name: String,
    /// Bytes of its files (OBJ, PNG, JSON): what is read, and what the
    /// memory limits count (the paper's "data size").
    pub file_bytes: u64,
    /// Bytes resident once decoded: atlas pages + vertex buffers.
    pub resident_bytes: u64,
}

/// Simulation settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimOptions {
    /// Frames to simulate (the paper: 2000).
    pub frames: usize,
    /// Seconds per turntable revolution (the paper: 7.5).
    pub period_s: f64,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            frames: 2000,
            period_s: 7.5,
        }
    }
}

/// One simulated frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// Start time, seconds.
    pub t_s: f64,
    /// Duration (frame cost + decode stall, at least one refresh), seconds.
    pub frame_s: f64,
    /// Frames per second of this frame (0 when the scene failed to load).
    pub fps: f64,
    /// Objects drawn.
    pub objects_loaded: usize,
    /// Quads set up and rasterised (in view).
    pub quads: f64,
    /// Quads owning a final pixel.
    pub quads_visible: f64,
    /// Pixels shaded at the viewer's resolution.
    pub pixels_shaded: f64,
    /// Main-thread decode time this frame waited for, seconds.
    pub stall_s: f64,
}

/// The result of a simulation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Simulation {
    /// Device name.
    pub device: String,
    /// Settings.
    pub options: SimOptions,
    /// Scene data (file bytes) — the limits apply to it.
    pub data_bytes: u64,
    /// GPU-resident bytes once loaded: objects + the G-buffer.
    pub resident_bytes: u64,
    /// Why the scene did not load (then every frame has FPS 0).
    pub load_failure: Option<LoadFailure>,
    /// Whether the data is over the device's soft limit.
    pub over_soft_limit: bool,
    /// When the last object became drawable, seconds (`None`: never).
    pub loaded_at_s: Option<f64>,
    /// Mean of the per-frame FPS (the paper's dashed line).
    pub mean_fps: f64,
    /// Mean FPS of the frames after loading finished (0 if none).
    pub steady_fps: f64,
    /// Lowest per-frame FPS.
    pub min_fps: f64,
    /// Mean raster time of the frames after loading, milliseconds.
    pub steady_raster_ms: f64,
    /// Mean shading (MLP) time of the frames after loading, milliseconds.
    pub steady_shade_ms: f64,
    /// Coverage passes run.
    pub coverage_passes: usize,
    /// Every frame.
    pub frames: Vec<FrameRecord>,
}

/// Bytes of output text per frame (a CSV line is about 64, a JSON record
/// about 200): part of what a frame costs in memory.
const FRAME_TEXT_BYTES: u128 = 256;

/// Checks a simulation length before anything is loaded: at least 1, and
/// a frame log (with its CSV/JSON text) that fits in memory, since a failed
/// allocation aborts rather than errs.
pub fn check_frames(frames: usize) -> Result<(), String> {
    if frames == 0 {
        return Err("--frames: must be at least 1".into());
    }
    let per_frame = std::mem::size_of::<FrameRecord>() as u128 + FRAME_TEXT_BYTES;
    crate::validate::memory(
        &format!("--frames {frames}"),
        frames as u128 * per_frame,
        &format!("the per-frame log ({per_frame} B per frame with its CSV/JSON text)"),
    )
}

/// Runs the turntable on `device` for a scene whose objects load in the
/// order of `items` (which must match the turntable's objects).
pub fn simulate(
    device: &Device,
    items: &[LoadItem],
    turntable: &Turntable<'_>,
    options: SimOptions,
) -> anyhow::Result<Simulation> {
    if items.len() != turntable.objects() {
        anyhow::bail!(
            "{} load items for a scene of {} objects",
            items.len(),
            turntable.objects()
        );
    }
    if !(options.period_s.is_finite() && options.period_s > 0.0) {
        anyhow::bail!(
            "the turntable period must be a positive number of seconds, got {}",
            options.period_s
        );
    }
    check_frames(options.frames).map_err(anyhow::Error::msg)?;
    let data: u64 = items
        .iter()
        .fold(0u64, |s, i| s.saturating_add(i.file_bytes));
    let resident = items.iter().fold(device.gbuffer_bytes().0, |s, i| {
        s.saturating_add(i.resident_bytes)
    });
    let refresh_s = 1.0 / device.display.refresh_hz;
    let mut sim = Simulation {
        device: device.name.clone(),
        options,
        data_bytes: data,
        resident_bytes: resident,
        load_failure: None,
        over_soft_limit: device.over_soft_limit(Bytes(data)),
        loaded_at_s: None,
        mean_fps: 0.0,
        steady_fps: 0.0,
        min_fps: 0.0,
        steady_raster_ms: 0.0,
        steady_shade_ms: 0.0,
        coverage_passes: 0,
        frames: Vec::with_capacity(options.frames),
    };
    if let Err(failure) = device.load_check(Bytes(data)) {
        // Nothing is drawn: the paper plots these runs as FPS 0.
        sim.frames = (0..options.frames)
            .map(|i| FrameRecord {
                t_s: i as f64 * refresh_s,
                frame_s: refresh_s,
                fps: 0.0,
                objects_loaded: 0,
                quads: 0.0,
                quads_visible: 0.0,
                pixels_shaded: 0.0,
                stall_s: 0.0,
            })
            .collect();
        sim.load_failure = Some(failure);
        return Ok(sim);
    }

    // When each object's files have been read (sequentially, asynchronously).
    let load_bw = device.throughput.load_mb_per_s * 1e6;
    let decode_bw = device.decode_mb_per_s() * 1e6;
    let mut arrive = Vec::with_capacity(items.len());
    let mut t_read = 0.0;
    for it in items {
        t_read += it.file_bytes as f64 / load_bw;
        arrive.push(t_read);
    }
    let mut loaded = 0usize; // objects drawn
    let mut loaded_data = 0u64;
    let mut t = 0.0f64;
    for _ in 0..options.frames {
        let (work, visible) = turntable.work(loaded, t / options.period_s)?;
        let cost = device.frame_cost(&work).total_s();
        // Objects whose files are in by the time this frame would end are
        // decoded on the main thread during it: the frame waits.
        let mut stall = 0.0;
        let mut next = loaded;
        while next < items.len() && arrive[next] <= t + cost + stall {
            stall += items[next].resident_bytes as f64 / decode_bw;
            next += 1;
        }
        let frame_s = (cost + stall).max(refresh_s);
        let over_soft = device.over_soft_limit(Bytes(loaded_data));
        let fps = device.fps(cost + stall, over_soft);
        sim.frames.push(FrameRecord {
            t_s: t,
            frame_s,
            fps,
            objects_loaded: loaded,
            quads: work.quads,
            quads_visible: visible,
            pixels_shaded: work.pixels_shaded,
            stall_s: stall,
        });
        t += frame_s;
        for it in &items[loaded..next] {
            loaded_data = loaded_data.saturating_add(it.file_bytes);
        }
        if next == items.len() && loaded < items.len() {
            sim.loaded_at_s = Some(t);
        }
        loaded = next;
    }
    if items.is_empty() {
        sim.loaded_at_s = Some(0.0);
    }
    let n = sim.frames.len().max(1) as f64;
    sim.mean_fps = sim.frames.iter().map(|f| f.fps).sum::<f64>() / n;
    sim.min_fps = sim
        .frames
        .iter()
        .map(|f| f.fps)
        .fold(f64::INFINITY, f64::min);
    if !sim.min_fps.is_finite() {
        sim.min_fps = 0.0;
    }
    let steady: Vec<f64> = sim
        .frames
        .iter()
        .filter(|f| f.objects_loaded == items.len())
        .map(|f| f.fps)
        .collect();
    sim.steady_fps = if steady.is_empty() {
        0.0
    } else {
        steady.iter().sum::<f64>() / steady.len() as f64
    };
    let (mut raster, mut shade, mut n_steady) = (0.0, 0.0, 0usize);
    for f in sim
        .frames
        .iter()
        .filter(|f| f.objects_loaded == items.len())
    {
        let c = device.frame_cost(&crate::device::FrameWork {
            quads: f.quads,
            pixels_shaded: f.pixels_shaded,
        });
        raster += c.raster_s;
        shade += c.shade_s;
        n_steady += 1;
    }
    if n_steady > 0 {
        sim.steady_raster_ms = 1e3 * raster / n_steady as f64;
        sim.steady_shade_ms = 1e3 * shade / n_steady as f64;
    }
    sim.coverage_passes = turntable.passes();
    Ok(sim)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::simulate::{CoverageSource, TurntableSpec, ViewCoverage};

    struct Flat {
        objects: usize,
        per_object: ViewCoverage,
    }
    impl CoverageSource for Flat {
        fn objects(&self) -> usize {
            self.objects
        }
        fn coverage(&self, loaded: usize, _: &Camera) -> anyhow::Result<ViewCoverage> {
            let k = loaded as u64;
            Ok(ViewCoverage {
                quads_in_view: self.per_object.quads_in_view * k,
                quads_drawn: self.per_object.quads_drawn * k,
                quads_visible: self.per_object.quads_visible * k,
                pixels_covered: self.per_object.pixels_covered * k,
            })
        }
    }

    fn items(n: usize, mb: u64) -> Vec<LoadItem> {
        (0..n)
            .map(|i| LoadItem {
                name: format!("o{i}"),
                file_bytes: mb * 1_000_000,
                resident_bytes: 4 * mb * 1_000_000,
            })
            .collect()
    }

    #[test]
    fn loading_stutters_then_settles() {
        let d = Device::builtin("pixel4").unwrap();
        let src = Flat {
            objects: 5,
            per_object: ViewCoverage {
                quads_in_view: 100_000,
                quads_drawn: 90_000,
                quads_visible: 30_000,
                pixels_covered: 2_000,
            },
        };
        let tt = Turntable::new(TurntableSpec::DEFAULT, d.viewer(), &src);
        let sim = simulate(&d, &items(5, 25), &tt, SimOptions::default()).unwrap();
        assert_eq!(sim.frames.len(), 2000);
        assert!(sim.load_failure.is_none());
        let loaded_at = sim.loaded_at_s.unwrap();
        assert!(loaded_at > 0.0);
        // Frames that waited for a decode are slower than any steady frame.
        let stalled: Vec<_> = sim.frames.iter().filter(|f| f.stall_s > 0.0).collect();
        let total_stall: f64 = stalled.iter().map(|f| f.stall_s).sum();
        let expected = 5.0 * 100e6 / (d.decode_mb_per_s() * 1e6);
        assert!(
            (total_stall - expected).abs() < 1e-9,
            "{total_stall} vs {expected}"
        );
        let last = sim.frames.last().unwrap();
        assert_eq!(last.objects_loaded, 5);
        for f in &stalled {
            assert!(f.fps < last.fps, "{f:?} vs {last:?}");
        }
        // Before the first object is in, frames are empty and run at the cap.
        assert_eq!(sim.frames[0].fps, d.display.refresh_hz);
        assert!(sim.steady_fps > 0.0 && sim.steady_fps <= d.display.refresh_hz);
        assert!(sim.min_fps <= sim.mean_fps);
    }

    #[test]
    fn over_the_hard_limit_is_all_zeros() {
        let d = Device::builtin("iphone13").unwrap();
        let src = Flat {
            objects: 3,
            per_object: ViewCoverage::default(),
        };
        let tt = Turntable::new(TurntableSpec::DEFAULT, d.viewer(), &src);
        let sim = simulate(&d, &items(3, 81), &tt, SimOptions::default()).unwrap();
        let f = sim.load_failure.as_ref().unwrap();
        assert_eq!(f.data_bytes, 243_000_000);
        assert!(f.to_string().contains("243.00 MB"), "{f}");
        assert!(sim.frames.iter().all(|f| f.fps == 0.0));
        assert_eq!(sim.mean_fps, 0.0);
        assert_eq!(sim.coverage_passes, 0);
    }

    #[test]
    fn mismatched_items_are_an_error() {
        let d = Device::builtin("iphone13").unwrap();
        let src = Flat {
            objects: 3,
            per_object: ViewCoverage::default(),
        };
        let tt = Turntable::new(TurntableSpec::DEFAULT, d.viewer(), &src);
        assert!(simulate(&d, &items(2, 1), &tt, SimOptions::default()).is_err());
        let bad = SimOptions {
            period_s: 0.0,
            ..SimOptions::default()
        };
        assert!(simulate(&d, &items(3, 1), &tt, bad).is_err());
    }
}
