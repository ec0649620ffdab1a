//! Device descriptions (TOML) and the device model the simulator runs:
//! memory limits, load bandwidths and the throughputs that turn a frame's
//! work into time.
//!
//! **1 MB = 10^6 bytes** in every field and message (the paper's 240 MB
//! budget is 240 000 000 bytes).
//!
//! Built-in devices are compiled in from `sim/devices/*.toml`: `iphone13`
//! (budget 240 MB, loading fails above 240 MB) and `pixel4` (150 MB; above
//! it frames slow by about 15 FPS). Their comments say which of the NeRFlex
//! paper's figures calibrated which value; `docs/device.md` derives the
//! model.
//!
//! ```toml
//! name = "iphone13"
//! budget_mb = 240.0
//! hard_limit_mb = 240.0          # optional: above it loading fails
//! # [soft_limit]                 # optional: above `mb`, FPS drops by `fps_penalty`
//! # mb = 150.0
//! # fps_penalty = 15.0
//! [throughput]
//! mac_per_s = 4.0e11             # multiply-adds per second for the MLP shader
//! quads_per_s = 6.0e8            # quads rasterised per second
//! frame_overhead_ms = 2.0        # fixed cost per frame
//! load_mb_per_s = 150.0          # reading the baked files (asynchronous)
//! decode_mb_per_s = 400.0        # optional: decoding + uploading, MB of resident data per second
//! [display]
//! refresh_hz = 60.0
//! width_px = 1170
//! height_px = 2532
//! # [viewer]                     # optional: the render target of the viewer
//! # width_px = 800               #   (default 800 × 800, MobileNeRF's canvas)
//! # height_px = 800
//! ```
//!
//! Unknown fields are errors; every error names the file and the field.
//! The fields added by the simulator (`decode_mb_per_s`, `[viewer]`) are
//! optional, so device files written for `nerflex plan` still load.
//!
//! # The model (see `docs/device.md`)
//!
//! - **Frame time** `t = overhead + quads / quads_per_s +
//!   pixels_shaded · 480 / mac_per_s` ([`Device::frame_cost`]): every quad
//!   in view is set up and rasterised into the deferred G-buffer,
//!   then every covered pixel runs the 11→16→16→3 MLP once
//!   ([`MLP_MACS_PER_PIXEL`] = 11·16 + 16·16 + 16·3 multiply-adds).
//! - **FPS** of a frame is `min(1/t, refresh_hz)`; above the soft limit
//!   the device loses `fps_penalty` frames per second (never below 0)
//!   ([`Device::fps`]).
//! - **Loading** ([`Device::load_check`]): data (file bytes) above the hard
//!   limit fails to load; GPU-resident bytes ([`resident_bytes`]) are the
//!   decoded atlas pages, the vertex buffers and the deferred G-buffer.

use nerflex_core::units::Bytes;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;

/// Built-in devices: name and TOML text.
const BUILTIN: &[(&str, &str)] = &[
    ("iphone13", include_str!("../devices/iphone13.toml")),
    ("pixel4", include_str!("../devices/pixel4.toml")),
];

/// Names of the built-in devices.
pub fn builtin_names() -> impl Iterator<Item = &'static str> {
    BUILTIN.iter().map(|(n, _)| *n)
}

/// A device.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Device {
    /// Short name, e.g. `iphone13`.
    pub name: String,
    /// Memory budget H for a scene's baked data, MB.
    pub budget_mb: f64,
    /// Above this total, loading fails (MB).
    #[serde(default)]
    pub hard_limit_mb: Option<f64>,
    /// Above this total, rendering slows down.
    #[serde(default)]
    pub soft_limit: Option<SoftLimit>,
    /// Throughput figures.
    pub throughput: Throughput,
    /// The screen.
    pub display: Display,
    /// The viewer's render target (default [`Viewer::DEFAULT`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viewer: Option<Viewer>,
}

/// A memory level above which rendering slows down.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SoftLimit {
    /// The level, MB.
    pub mb: f64,
    /// Frames per second lost above it.
    pub fps_penalty: f64,
}

/// What the device computes per second.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Throughput {
    /// Multiply-adds per second available to the MLP shader.
    pub mac_per_s: f64,
    /// Quads rasterised per second.
    pub quads_per_s: f64,
    /// Fixed cost of one frame, milliseconds.
    pub frame_overhead_ms: f64,
    /// Load bandwidth: file bytes read (or downloaded) per second, MB/s.
    /// Reading is asynchronous: frames keep rendering meanwhile.
    pub load_mb_per_s: f64,
    /// Decoding and uploading: resident bytes (decoded atlas pages and
    /// vertex buffers) produced per second on the viewer's main thread, MB/s
    /// (default [`DEFAULT_DECODE_MB_PER_S`]). This work blocks frames: it
    /// is the loading stutter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decode_mb_per_s: Option<f64>,
}

/// Decode + upload rate when a device file gives none, MB of resident data
/// per second (an assumption: the paper gives no load timings).
pub const DEFAULT_DECODE_MB_PER_S: f64 = 400.0;

/// The render target of the viewer (the deferred G-buffer's size).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Viewer {
    /// Width, pixels.
    pub width_px: u32,
    /// Height, pixels.
    pub height_px: u32,
}

impl Viewer {
    /// MobileNeRF's viewer draws the synthetic scenes into an 800 × 800 canvas.
    pub const DEFAULT: Viewer = Viewer {
        width_px: 800,
        height_px: 800,
    };

    /// Pixels of the render target.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width_px) * u64::from(self.height_px)
    }
}

/// The screen.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Display {
    /// Refresh rate, Hz (frame rate cap).
    pub refresh_hz: f64,
    /// Width, pixels.
    pub width_px: u32,
    /// Height, pixels.
    pub height_px: u32,
}

/// A device file problem: which file, which field, what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceError {
    /// The file (as given) or the built-in name.
    pub origin: String,
    /// The field, e.g. `throughput.mac_per_s` (empty when unknown).
    pub field: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for DeviceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.field.is_empty() {
            write!(f, "{}: {}", self.origin, self.message)
        } else {
            write!(f, "{}: {}: {}", self.origin, self.field, self.message)
        }
    }
}

impl std::error::Error for DeviceError {}

impl Device {
    /// A built-in device by name (`iphone13`, `pixel4`; case-insensitive).
    pub fn builtin(name: &str) -> Option<Device> {
        let (n, text) = BUILTIN.iter().find(|(n, _)| n.eq_ignore_ascii_case(name))?;
        // The built-in files are tested to parse.
        Device::from_toml_str(text, &format!("built-in device {n}")).ok()
    }

    /// A built-in device by name, or else a TOML file at that path.
    pub fn lookup(spec: &str) -> Result<Device, DeviceError> {
        if let Some(d) = Device::builtin(spec) {
            return Ok(d);
        }
        let path = Path::new(spec);
        if path.is_file() {
            return Device::load(path);
        }
        Err(DeviceError {
            origin: spec.to_string(),
            field: String::new(),
            message: format!(
                "not a built-in device ({}) and no such file",
                builtin_names().collect::<Vec<_>>().join(", ")
            ),
        })
    }

    /// Reads a device TOML file.
    pub fn load(path: &Path) -> Result<Device, DeviceError> {
        let origin = path.display().to_string();
        let text = crate::validate::read_to_string(path).map_err(|e| DeviceError {
            origin: origin.clone(),
            field: String::new(),
            message: format!("cannot read: {e}"),
        })?;
        Device::from_toml_str(&text, &origin)
    }

    /// Parses and validates device TOML; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Device, DeviceError> {
        let device: Device = toml::from_str(text).map_err(|e| {
            let message = e.message().trim().to_string();
            let (field, location) = match e.span() {
                Some(span) => {
                    let line = text
                        .get(..span.start)
                        .map_or(0, |before| before.matches('\n').count());
                    (
                        toml_field(text, line, &message),
                        format!(" (line {})", line + 1),
                    )
                }
                None => (String::new(), String::new()),
            };
            DeviceError {
                origin: origin.to_string(),
                field,
                message: format!("{message}{location}"),
            }
        })?;
        device.validate(origin)?;
        Ok(device)
    }

    fn validate(&self, origin: &str) -> Result<(), DeviceError> {
        let bad = |field: &str, message: String| DeviceError {
            origin: origin.to_string(),
            field: field.to_string(),
            message,
        };
        if self.name.trim().is_empty() {
            return Err(bad("name", "empty name".into()));
        }
        let non_negative = |field: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(bad(
                    field,
                    format!("must be a non-negative number of MB, got {v}"),
                ))
            }
        };
        let positive = |field: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(bad(field, format!("must be a positive number, got {v}")))
            }
        };
        non_negative("budget_mb", self.budget_mb)?;
        Bytes::from_mb(self.budget_mb).map_err(|e| bad("budget_mb", e.to_string()))?;
        if let Some(h) = self.hard_limit_mb {
            non_negative("hard_limit_mb", h)?;
        }
        if let Some(s) = self.soft_limit {
            non_negative("soft_limit.mb", s.mb)?;
            non_negative("soft_limit.fps_penalty", s.fps_penalty)?;
        }
        let t = &self.throughput;
        positive("throughput.mac_per_s", t.mac_per_s)?;
        positive("throughput.quads_per_s", t.quads_per_s)?;
        non_negative("throughput.frame_overhead_ms", t.frame_overhead_ms)?;
        positive("throughput.load_mb_per_s", t.load_mb_per_s)?;
        if let Some(d) = t.decode_mb_per_s {
            positive("throughput.decode_mb_per_s", d)?;
        }
        if let Some(v) = self.viewer {
            if !(1..=16_384).contains(&v.width_px) || !(1..=16_384).contains(&v.height_px) {
                return Err(bad(
                    "viewer",
                    format!(
                        "width_px and height_px must be 1..=16384, got {} × {}",
                        v.width_px, v.height_px
                    ),
                ));
            }
        }
        positive("display.refresh_hz", self.display.refresh_hz)?;
        if self.display.width_px == 0 || self.display.height_px == 0 {
            return Err(bad(
                "display",
                "width_px and height_px must be positive".into(),
            ));
        }
        Ok(())
    }

    /// The memory budget H in bytes (validated on load).
    pub fn budget(&self) -> Bytes {
        Bytes::from_mb(self.budget_mb).unwrap_or(Bytes::ZERO)
    }

    /// The hard load limit in bytes, if any.
    pub fn hard_limit(&self) -> Option<Bytes> {
        self.hard_limit_mb.and_then(|mb| Bytes::from_mb(mb).ok())
    }

    /// The soft limit in bytes and its FPS penalty, if any.
    pub fn soft_limit_bytes(&self) -> Option<(Bytes, f64)> {
        let s = self.soft_limit?;
        Some((Bytes::from_mb(s.mb).ok()?, s.fps_penalty))
    }

    /// The viewer's render target ([`Viewer::DEFAULT`] unless the file sets one).
    pub fn viewer(&self) -> Viewer {
        self.viewer.unwrap_or(Viewer::DEFAULT)
    }

    /// Decode + upload rate, MB of resident data per second.
    pub fn decode_mb_per_s(&self) -> f64 {
        self.throughput
            .decode_mb_per_s
            .unwrap_or(DEFAULT_DECODE_MB_PER_S)
    }

    /// Bytes of the deferred G-buffer at the viewer's resolution.
    pub fn gbuffer_bytes(&self) -> Bytes {
        Bytes(self.viewer().pixels() * GBUFFER_BYTES_PER_PIXEL)
    }

    /// Time of one frame, split into its three terms. Negative or NaN work
    /// counts as none; infinite work takes forever.
    pub fn frame_cost(&self, work: &FrameWork) -> FrameCost {
        let t = &self.throughput;
        let quads = work.quads.max(0.0);
        let pixels = work.pixels_shaded.max(0.0);
        FrameCost {
            overhead_s: t.frame_overhead_ms / 1e3,
            raster_s: quads / t.quads_per_s,
            shade_s: pixels * MLP_MACS_PER_PIXEL as f64 / t.mac_per_s,
        }
    }

    /// Frames per second of a frame that took `frame_s` seconds: capped by
    /// the refresh rate, minus the soft-limit penalty when the loaded data
    /// is over the soft limit, never below 0. Always finite.
    pub fn fps(&self, frame_s: f64, over_soft_limit: bool) -> f64 {
        let raw = if frame_s.is_nan() || frame_s <= 0.0 {
            f64::INFINITY
        } else {
            1.0 / frame_s
        };
        let capped = raw.min(self.display.refresh_hz);
        let penalty = match self.soft_limit {
            Some(s) if over_soft_limit => s.fps_penalty,
            _ => 0.0,
        };
        (capped - penalty).max(0.0)
    }

    /// Whether `data` bytes are over the soft limit (`false` without one).
    pub fn over_soft_limit(&self, data: Bytes) -> bool {
        self.soft_limit_bytes()
            .is_some_and(|(limit, _)| data > limit)
    }

    /// Whether a scene of `data` bytes (its baked files) loads: above the
    /// hard limit it does not (the paper: WebGL on the iPhone 13 fails to
    /// load more than 240 MB).
    pub fn load_check(&self, data: Bytes) -> Result<(), LoadFailure> {
        match self.hard_limit() {
            Some(limit) if data > limit => Err(LoadFailure {
                device: self.name.clone(),
                data_bytes: data.0,
                limit_bytes: limit.0,
            }),
            _ => Ok(()),
        }
    }
}

/// Multiply-adds of the 11→16→16→3 MLP for one pixel: 11·16 + 16·16 + 16·3.
pub const MLP_MACS_PER_PIXEL: u64 = 11 * 16 + 16 * 16 + 16 * 3;

/// Vertex-buffer bytes per quad on the GPU: the viewer's OBJ loader
/// de-indexes each quad into two triangles (6 vertices) of position
/// (3 × f32) and texture coordinates (2 × f32).
pub const VERTEX_BYTES_PER_QUAD: u64 = 6 * (3 + 2) * 4;

/// Deferred G-buffer bytes per pixel: two RGBA8 feature targets and a
/// 32-bit depth buffer (MobileNeRF's viewer).
pub const GBUFFER_BYTES_PER_PIXEL: u64 = 4 + 4 + 4;

/// GPU-resident bytes of loaded objects: decoded atlas pages (RGBA8, two
/// per shape) plus vertex buffers ([`VERTEX_BYTES_PER_QUAD`]). The
/// G-buffer ([`Device::gbuffer_bytes`]) comes on top, once per viewer.
pub fn resident_bytes(atlas_bytes: u64, quads: u64) -> Bytes {
    Bytes(atlas_bytes.saturating_add(quads.saturating_mul(VERTEX_BYTES_PER_QUAD)))
}

/// The work of one frame at the viewer's resolution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameWork {
    /// Quads set up and rasterised: every quad in the view (the viewer
    /// draws whole meshes; a quad smaller than a pixel still costs its setup).
    pub quads: f64,
    /// Covered pixels, each shaded once by the MLP.
    pub pixels_shaded: f64,
}

/// The time of one frame, by term (seconds).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameCost {
    /// Fixed cost (submission, compositing).
    pub overhead_s: f64,
    /// Rasterising the quads into the G-buffer.
    pub raster_s: f64,
    /// Running the MLP on every covered pixel.
    pub shade_s: f64,
}

impl FrameCost {
    /// The frame's time.
    pub fn total_s(&self) -> f64 {
        self.overhead_s + self.raster_s + self.shade_s
    }
}

/// A scene too large for a device to load.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LoadFailure {
    /// The device.
    pub device: String,
    /// The scene's data (file bytes).
    pub data_bytes: u64,
    /// The device's hard limit, bytes.
    pub limit_bytes: u64,
}

impl fmt::Display for LoadFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:.2} MB of data is over the {:.2} MB that {} can load (the viewer fails to load it)",
            Bytes(self.data_bytes).as_mb(),
            Bytes(self.limit_bytes).as_mb(),
            self.device
        )
    }
}

impl std::error::Error for LoadFailure {}

/// The dotted field a TOML error at 0-based `line` is about: the table
/// header above it plus the key on that line (or, for a missing field, the
/// name in the message).
fn toml_field(text: &str, line: usize, message: &str) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let here = lines.get(line).map_or("", |l| l.trim());
    let header = |l: &str| {
        let l = l.trim();
        (l.starts_with('[') && l.ends_with(']'))
            .then(|| l.trim_matches(['[', ']']).trim().to_string())
    };
    let missing = message
        .strip_prefix("missing field `")
        .and_then(|rest| rest.split('`').next());
    // A missing field is reported at the start of its table.
    let (table, key) = match (header(here), missing) {
        (Some(t), Some(m)) => (Some(t), m.to_string()),
        (None, Some(m)) => (None, m.to_string()),
        (Some(t), None) => return t,
        (None, None) => {
            let table = lines.iter().take(line).rev().find_map(|l| header(l));
            (
                table,
                here.split('=').next().unwrap_or("").trim().to_string(),
            )
        }
    };
    match table {
        Some(t) => format!("{t}.{key}"),
        None => key,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_parse_with_the_papers_budgets() {
        let i = Device::builtin("iphone13").unwrap();
        assert_eq!(i.budget(), Bytes(240_000_000));
        assert_eq!(i.hard_limit(), Some(Bytes(240_000_000)));
        let p = Device::lookup("Pixel4").unwrap();
        assert_eq!(p.budget(), Bytes(150_000_000));
        assert_eq!(p.soft_limit_bytes(), Some((Bytes(150_000_000), 15.0)));
        for name in builtin_names() {
            assert!(Device::builtin(name).is_some(), "{name}");
        }
    }

    #[test]
    fn errors_name_the_field() {
        let text = include_str!("../devices/pixel4.toml");
        let mac_line = text
            .lines()
            .find(|l| l.starts_with("mac_per_s"))
            .unwrap()
            .to_string();
        let e = Device::from_toml_str(&text.replace(&mac_line, "mac_per_s = -1.0"), "x.toml")
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.toml: throughput.mac_per_s: must be a positive number, got -1"
        );
        let e =
            Device::from_toml_str(&format!("{text}\n[extra]\nfoo = 1\n"), "x.toml").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("x.toml: extra: unknown field `extra`"),
            "{e}"
        );
        let e = Device::from_toml_str(
            &text.replace("budget_mb = 150.0", "budget_mb = \"lots\""),
            "x.toml",
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("x.toml: budget_mb: "), "{e}");
        let e =
            Device::from_toml_str(&text.replace("budget_mb = 150.0", ""), "x.toml").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("x.toml: budget_mb: missing field `budget_mb`"),
            "{e}"
        );
        let e = Device::from_toml_str(&text.replace(&mac_line, ""), "x.toml").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("x.toml: throughput.mac_per_s: missing field"),
            "{e}"
        );
        let e = Device::from_toml_str(&text.replace("quads_per_s", "quads"), "x.toml").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("x.toml: throughput.quads: unknown field `quads`"),
            "{e}"
        );
        let e = Device::lookup("nosuch").unwrap_err();
        assert!(
            e.to_string()
                .contains("not a built-in device (iphone13, pixel4)"),
            "{e}"
        );
    }
}
