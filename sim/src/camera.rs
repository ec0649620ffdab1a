//! Pinhole cameras and the NeRF-synthetic `transforms_*.json` format.
//!
//! Conventions (the NeRF-synthetic / Blender / OpenGL ones, used everywhere in
//! `nerflex-sim`):
//! - **world**: right-handed, z up (Blender); objects sit in the unit cube
//!   around the origin.
//! - **camera**: looks down its −z axis, y up, x right; `c2w` is the 4×4
//!   camera-to-world matrix of `transform_matrix`.
//! - **image**: pixel (i, j) covers `[i, i+1) × [j, j+1)`, j grows downward;
//!   its centre is (i + 0.5, j + 0.5).
//! - **intrinsics**: `fx = 0.5·w / tan(0.5·camera_angle_x)`, square pixels,
//!   principal point at the image centre unless `fl_x`, `fl_y`, `cx`, `cy`
//!   are given (file-level, or per frame, which the segmentation stage writes
//!   for its cropped-and-enlarged views).

use glam::{Mat4, Vec3, Vec4Swizzles};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Errors reading or interpreting a transforms file.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The JSON is malformed or a key is missing / of the wrong type.
    #[error("{path}: invalid transforms JSON: {source}")]
    Json {
        /// The file.
        path: PathBuf,
        /// The cause (serde names the line, column and field).
        source: serde_json::Error,
    },
    /// A value is present but unusable.
    #[error("{path}: {what}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the field or frame.
        what: String,
    },
}

/// Pinhole intrinsics in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels from the left edge.
    pub cx: f32,
    /// Principal point y, pixels from the top edge.
    pub cy: f32,
}

impl Intrinsics {
    /// Square pixels, centred principal point, horizontal field of view in radians.
    pub fn from_fov_x(fov_x_rad: f32, width: u32, height: u32) -> Self {
        let fx = 0.5 * width as f32 / (0.5 * fov_x_rad).tan();
        Self {
            width,
            height,
            fx,
            fy: fx,
            cx: 0.5 * width as f32,
            cy: 0.5 * height as f32,
        }
    }

    /// Horizontal field of view in radians (for a centred principal point).
    pub fn fov_x(&self) -> f32 {
        2.0 * (0.5 * self.width as f32 / self.fx).atan()
    }

    /// The same camera at another resolution (focal lengths and principal
    /// point scale with the image).
    pub fn resized(&self, width: u32, height: u32) -> Self {
        let sx = width as f32 / self.width as f32;
        let sy = height as f32 / self.height as f32;
        Self {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: self.cx * sx,
            cy: self.cy * sy,
        }
    }

    /// The intrinsics of the crop `[x0, x0+w) × [y0, y0+h)` (pixels) scaled
    /// up to `out_w × out_h`: the narrower field of view and shifted principal
    /// point that make an enlarged crop geometrically consistent.
    pub fn cropped(&self, x0: f32, y0: f32, w: f32, h: f32, out_w: u32, out_h: u32) -> Self {
        let sx = out_w as f32 / w;
        let sy = out_h as f32 / h;
        Self {
            width: out_w,
            height: out_h,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx - x0) * sx,
            cy: (self.cy - y0) * sy,
        }
    }
}

/// A posed pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Intrinsics in pixels.
    pub intrinsics: Intrinsics,
    /// Camera-to-world (OpenGL camera convention, see module docs).
    pub c2w: Mat4,
}

impl Camera {
    /// A camera at `distance` from `target`, at turntable angle `azimuth_deg`
    /// (counter-clockwise about world +z; 0° puts the camera on the −y side,
    /// like Blender's front view) and `elevation_deg` above the xy plane,
    /// looking at `target` with world z up.
    pub fn orbit(
        azimuth_deg: f32,
        elevation_deg: f32,
        distance: f32,
        target: Vec3,
        intrinsics: Intrinsics,
    ) -> Self {
        let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        let eye =
            target + distance * Vec3::new(el.cos() * az.sin(), -el.cos() * az.cos(), el.sin());
        Self::look_at(eye, target, Vec3::Z, intrinsics)
    }

    /// A camera at `eye` looking at `target`; `up` is the world's up hint.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, intrinsics: Intrinsics) -> Self {
        let back = (eye - target).normalize_or(Vec3::Z); // camera +z points away from the view
        let mut right = up.cross(back);
        if right.length_squared() < 1e-12 {
            right = Vec3::X; // looking straight along `up`
        }
        let right = right.normalize();
        let cam_up = back.cross(right);
        let c2w = Mat4::from_cols(
            right.extend(0.0),
            cam_up.extend(0.0),
            back.extend(0.0),
            eye.extend(1.0),
        );
        Self { intrinsics, c2w }
    }

    /// Camera position in world coordinates.
    pub fn position(&self) -> Vec3 {
        self.c2w.w_axis.xyz()
    }

    /// World-to-camera matrix.
    pub fn w2c(&self) -> Mat4 {
        self.c2w.inverse()
    }

    /// Projects a world point to continuous pixel coordinates and its depth
    /// along the viewing axis; `None` behind the camera.
    pub fn project(&self, world: Vec3) -> Option<(f32, f32, f32)> {
        let p = self.w2c().transform_point3(world);
        let depth = -p.z;
        if depth <= 1e-6 {
            return None;
        }
        let k = &self.intrinsics;
        Some((k.cx + k.fx * p.x / depth, k.cy - k.fy * p.y / depth, depth))
    }

    /// The world-space ray (origin, unit direction) through continuous pixel
    /// coordinates `(px, py)`; the centre of pixel (i, j) is (i + 0.5, j + 0.5).
    pub fn ray(&self, px: f32, py: f32) -> (Vec3, Vec3) {
        let k = &self.intrinsics;
        let d_cam = Vec3::new((px - k.cx) / k.fx, -(py - k.cy) / k.fy, -1.0);
        let d = self.c2w.transform_vector3(d_cam).normalize();
        (self.position(), d)
    }
}

/// One frame of a transforms file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FrameEntry {
    /// Image path relative to the file's folder, without extension (`./train/r_0`).
    pub file_path: String,
    /// Camera-to-world, row-major as in the dataset.
    pub transform_matrix: [[f64; 4]; 4],
    /// Per-frame focal length x (pixels at the image's own size), if not the file's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_x: Option<f64>,
    /// Per-frame focal length y.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_y: Option<f64>,
    /// Per-frame principal point x.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cx: Option<f64>,
    /// Per-frame principal point y.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cy: Option<f64>,
    /// Other keys (e.g. `rotation`), kept so a rewrite loses nothing.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// A `transforms_{train,test}.json` file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Transforms {
    /// Horizontal field of view, radians.
    pub camera_angle_x: f64,
    /// Optional file-level focal length x, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_x: Option<f64>,
    /// Optional file-level focal length y, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_y: Option<f64>,
    /// Optional file-level principal point x, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cx: Option<f64>,
    /// Optional file-level principal point y, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cy: Option<f64>,
    /// Optional image width the pixel intrinsics refer to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub w: Option<u32>,
    /// Optional image height the pixel intrinsics refer to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub h: Option<u32>,
    /// The frames.
    pub frames: Vec<FrameEntry>,
}

impl Transforms {
    /// Reads and validates a transforms file (finite values, 4×4 rigid
    /// camera-to-world matrices, positive field of view).
    pub fn read(path: &Path) -> Result<Self, CameraError> {
        let text = crate::validate::read_to_string(path).map_err(|source| CameraError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let t: Transforms = serde_json::from_str(&text).map_err(|source| CameraError::Json {
            path: path.to_path_buf(),
            source,
        })?;
        t.validate().map_err(|what| CameraError::Invalid {
            path: path.to_path_buf(),
            what,
        })?;
        Ok(t)
    }

    /// Writes the file as pretty JSON.
    pub fn write(&self, path: &Path) -> Result<(), CameraError> {
        let text = serde_json::to_string_pretty(self).map_err(|source| CameraError::Json {
            path: path.to_path_buf(),
            source,
        })?;
        crate::output::write_file(path, text.as_bytes())
            .map(|_| ())
            .map_err(|e| CameraError::Io {
                path: path.to_path_buf(),
                source: e.into_io(),
            })
    }

    fn validate(&self) -> Result<(), String> {
        if !(self.camera_angle_x.is_finite()
            && self.camera_angle_x > 0.0
            && self.camera_angle_x < std::f64::consts::PI)
        {
            return Err(format!(
                "camera_angle_x = {} is not an angle in (0, π)",
                self.camera_angle_x
            ));
        }
        check_intrinsics([self.fl_x, self.fl_y, self.cx, self.cy])?;
        if self.frames.is_empty() {
            return Err("no frames".into());
        }
        for (i, f) in self.frames.iter().enumerate() {
            let m = &f.transform_matrix;
            // Finite in f32 (the code's precision), not just in f64.
            for (r, row) in m.iter().enumerate() {
                for (c, &v) in row.iter().enumerate() {
                    crate::validate::f32_value(&format!("transform_matrix[{r}][{c}]"), v)
                        .map_err(|e| format!("frame {i} ({}): {e}", f.file_path))?;
                }
            }
            let last = m[3];
            if (last[0].abs() + last[1].abs() + last[2].abs() + (last[3] - 1.0).abs()) > 1e-4 {
                return Err(format!(
                    "frame {i} ({}): transform_matrix last row is {last:?}, expected [0, 0, 0, 1]",
                    f.file_path
                ));
            }
            // The rotation part must be orthonormal (a rigid camera pose).
            let cols: Vec<[f64; 3]> = (0..3).map(|c| [m[0][c], m[1][c], m[2][c]]).collect();
            for a in 0..3 {
                for b in 0..3 {
                    let dot: f64 = (0..3).map(|k| cols[a][k] * cols[b][k]).sum();
                    let want = if a == b { 1.0 } else { 0.0 };
                    if (dot - want).abs() > 1e-3 {
                        return Err(format!(
                            "frame {i} ({}): transform_matrix rotation is not orthonormal (column {a}·{b} = {dot:.4})",
                            f.file_path
                        ));
                    }
                }
            }
            check_intrinsics([f.fl_x, f.fl_y, f.cx, f.cy])
                .map_err(|e| format!("frame {i} ({}): {e}", f.file_path))?;
        }
        Ok(())
    }

    /// The camera of frame `index` for an image of `width × height` pixels.
    ///
    /// Pixel intrinsics (`fl_x` …) are taken per frame, then per file, then
    /// from `camera_angle_x`; when the file names its `w`/`h` and the image
    /// has another size they are rescaled.
    pub fn camera(&self, index: usize, width: u32, height: u32) -> Option<Camera> {
        let f = self.frames.get(index)?;
        let base = Intrinsics::from_fov_x(self.camera_angle_x as f32, width, height);
        let (sx, sy) = match (self.w, self.h) {
            (Some(w), Some(h)) if w > 0 && h > 0 => {
                (width as f64 / w as f64, height as f64 / h as f64)
            }
            _ => (1.0, 1.0),
        };
        let pick = |frame: Option<f64>, file: Option<f64>| frame.or(file);
        let intrinsics = Intrinsics {
            width,
            height,
            fx: pick(f.fl_x, self.fl_x).map_or(base.fx, |v| (v * sx) as f32),
            fy: pick(f.fl_y, self.fl_y)
                .or(pick(f.fl_x, self.fl_x))
                .map_or(base.fy, |v| (v * sy) as f32),
            cx: pick(f.cx, self.cx).map_or(base.cx, |v| (v * sx) as f32),
            cy: pick(f.cy, self.cy).map_or(base.cy, |v| (v * sy) as f32),
        };
        Some(Camera {
            intrinsics,
            c2w: mat4_from_rows(&f.transform_matrix),
        })
    }
}

/// A glam matrix from the dataset's row-major 4×4 array.
pub fn mat4_from_rows(m: &[[f64; 4]; 4]) -> Mat4 {
    Mat4::from_cols_array_2d(&[
        [
            m[0][0] as f32,
            m[1][0] as f32,
            m[2][0] as f32,
            m[3][0] as f32,
        ],
        [
            m[0][1] as f32,
            m[1][1] as f32,
            m[2][1] as f32,
            m[3][1] as f32,
        ],
        [
            m[0][2] as f32,
            m[1][2] as f32,
            m[2][2] as f32,
            m[3][2] as f32,
        ],
        [
            m[0][3] as f32,
            m[1][3] as f32,
            m[2][3] as f32,
            m[3][3] as f32,
        ],
    ])
}

/// The dataset's row-major 4×4 array from a glam matrix.
pub fn rows_from_mat4(m: &Mat4) -> [[f64; 4]; 4] {
    let c = m.to_cols_array_2d();
    let mut r = [[0.0f64; 4]; 4];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = c[j][i] as f64;
        }
    }
    r
}

/// Optional per-file or per-frame intrinsics `[fl_x, fl_y, cx, cy]`: finite,
/// and focal lengths positive.
fn check_intrinsics(values: [Option<f64>; 4]) -> Result<(), String> {
    for (name, v) in ["fl_x", "fl_y", "cx", "cy"].into_iter().zip(values) {
        if let Some(v) = v {
            crate::validate::f32_value(name, v)?;
            if name.starts_with("fl") && v <= 0.0 {
                return Err(format!("{name} = {v} is not valid"));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orbit_camera_sees_its_target_at_the_principal_point() {
        let k = Intrinsics::from_fov_x(0.69, 800, 600);
        let cam = Camera::orbit(30.0, 20.0, 4.0, Vec3::new(0.1, 0.2, 0.0), k);
        let (x, y, d) = cam.project(Vec3::new(0.1, 0.2, 0.0)).unwrap();
        assert!(
            (x - 400.0).abs() < 1e-3 && (y - 300.0).abs() < 1e-3,
            "{x} {y}"
        );
        assert!((d - 4.0).abs() < 1e-4);
        assert!(
            cam.position().z > 0.0,
            "positive elevation is above the ground"
        );
        // World up projects upward in the image (smaller y).
        let (_, y_up, _) = cam.project(Vec3::new(0.1, 0.2, 0.5)).unwrap();
        assert!(y_up < 300.0);
    }

    #[test]
    fn ray_and_project_are_inverse() {
        let k = Intrinsics::from_fov_x(0.8, 64, 48).cropped(10.0, 5.0, 30.0, 20.0, 64, 48);
        let cam = Camera::orbit(-70.0, 35.0, 3.0, Vec3::ZERO, k);
        let (o, d) = cam.ray(12.5, 40.25);
        let (x, y, _) = cam.project(o + 2.5 * d).unwrap();
        assert!(
            (x - 12.5).abs() < 1e-3 && (y - 40.25).abs() < 1e-3,
            "{x} {y}"
        );
    }

    #[test]
    fn crop_keeps_points_consistent() {
        let k = Intrinsics::from_fov_x(0.69, 800, 800);
        let cam = Camera::orbit(10.0, 30.0, 4.0, Vec3::ZERO, k);
        let crop = Camera {
            intrinsics: k.cropped(200.0, 300.0, 400.0, 200.0, 800, 800),
            ..cam
        };
        let p = Vec3::new(0.2, -0.1, 0.3);
        let (x, y, _) = cam.project(p).unwrap();
        let (xc, yc, _) = crop.project(p).unwrap();
        assert!((xc - (x - 200.0) * 2.0).abs() < 1e-2 && (yc - (y - 300.0) * 4.0).abs() < 1e-2);
    }

    #[test]
    fn real_lego_transforms_parse_and_round_trip() {
        let Some(data) = crate::data::require_data("lego transforms") else {
            return;
        };
        let path = data.join("nerf_synthetic/lego/transforms_train.json");
        let t = Transforms::read(&path).unwrap();
        assert_eq!(t.frames.len(), 20);
        let cam = t.camera(0, 800, 800).unwrap();
        // Lego cameras sit about 4 units from the origin and look at it.
        assert!((cam.position().length() - 4.03).abs() < 0.1);
        let (x, y, _) = cam.project(Vec3::ZERO).unwrap();
        assert!((x - 400.0).abs() < 40.0 && (y - 400.0).abs() < 40.0);
        let rows = rows_from_mat4(&cam.c2w);
        for (a, b) in rows
            .iter()
            .flatten()
            .zip(t.frames[0].transform_matrix.iter().flatten())
        {
            assert!((a - b).abs() < 1e-5);
        }
    }

    #[test]
    fn bad_transforms_name_the_problem() {
        let dir = std::env::temp_dir().join(format!("nerflex-cam-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("t.json");
        std::fs::write(&p, r#"{"camera_angle_x": 0.7, "frames": [{"file_path": "a", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}]}"#).unwrap();
        let e = Transforms::read(&p).unwrap_err().to_string();
        assert!(
            e.contains("t.json") && e.contains("transform_matrix") || e.contains("invalid length"),
            "{e}"
        );
        std::fs::write(&p, r#"{"camera_angle_x": 0.7, "frames": [{"file_path": "a", "transform_matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]}"#).unwrap();
        let e = Transforms::read(&p).unwrap_err().to_string();
        assert!(e.contains("orthonormal") && e.contains("frame 0"), "{e}");
        std::fs::write(&p, r#"{"frames": []}"#).unwrap();
        let e = Transforms::read(&p).unwrap_err().to_string();
        assert!(e.contains("camera_angle_x"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
