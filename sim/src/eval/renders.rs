//! Pictures beside the numbers: one held-out view of each scene, the ground
//! truth next to every method's render, per device (`renders_<scene>_<device>.png`
//! in the output folder). The full-resolution renders of every held-out view
//! stay in the scene's work folder (`scenes/<scene>/renders/`, out of git).

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use image::RgbaImage;

use crate::bake::compare::{strip, Tile};
use crate::baselines::Method;
use crate::pipeline::views::ViewScores;

use super::plots::method_label;

/// The held-out view shown in the strips (the first: fixed, not picked).
pub const VIEW: usize = 0;

/// Longer side of a full view in the strip, pixels (tiles are cropped alike
/// to what any image covers, at this scale).
pub const TILE_SIDE: u32 = 400;

/// One method's render of the strip's view and its scores there.
pub struct Entry {
    /// The method.
    pub method: Method,
    /// Its realised plan's render folder (`test_<i>.png`).
    pub dir: PathBuf,
    /// Its scores of the view.
    pub scores: Option<ViewScores>,
    /// Baked megabytes of its plan.
    pub megabytes: f64,
}

/// The folder a realised plan's held-out renders go to: numbered by the
/// order plans are realised (a re-plan never overwrites an earlier plan's).
pub fn plan_dir(root: &Path, index: usize, method: Method, devices: &[&str]) -> PathBuf {
    let lower = method_label(method).to_lowercase();
    let slug = lower
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| !w.is_empty())
        .collect::<Vec<_>>()
        .join("-");
    root.join(format!("{index:02}-{slug}-{}", devices.join("+")))
}

/// The file name of a scene's strip on a device.
pub fn strip_name(scene: &str, device: &str) -> String {
    format!("renders_{scene}_{device}.png")
}

/// Writes the strip of `truth` and the entries' renders of [`VIEW`] to
/// `path`; entries whose render is missing are left out.
pub fn write_strip(truth: &RgbaImage, entries: &[Entry], path: &Path) -> anyhow::Result<()> {
    let mut images = Vec::new();
    for e in entries {
        let file = e.dir.join(format!("test_{VIEW}.png"));
        if !file.exists() {
            continue;
        }
        let img = image::open(&file)
            .with_context(|| format!("{}: cannot read", file.display()))?
            .to_rgba8();
        if img.dimensions() != truth.dimensions() {
            anyhow::bail!(
                "{}: {}×{} render, the truth is {}×{}",
                file.display(),
                img.width(),
                img.height(),
                truth.width(),
                truth.height()
            );
        }
        images.push((e, img));
    }
    let mut tiles = vec![Tile {
        image: truth,
        caption: vec![
            "ground truth".into(),
            format!("held-out view {VIEW}"),
            String::new(),
        ],
    }];
    for (e, img) in &images {
        let scores = e.scores.as_ref().map_or_else(
            || "not scored".to_string(),
            |s| format!("SSIM {:.4}  {:.2} dB", s.ssim, s.psnr),
        );
        tiles.push(Tile {
            image: img,
            caption: vec![
                method_label(e.method).to_string(),
                scores,
                format!("{:.1} MB", e.megabytes),
            ],
        });
    }
    let picture = strip(&tiles, Some(TILE_SIDE));
    let png = crate::asset::png_io::encode_rgba8(&picture)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    crate::output::create_parent(path)?;
    crate::output::write_file(path, &png)?;
    Ok(())
}

/// The strips present in `out`, sorted, with captions (for the report).
pub fn listed(out: &Path) -> Vec<(String, String)> {
    let Ok(dir) = std::fs::read_dir(out) else {
        return Vec::new();
    };
    let mut files: Vec<String> = dir
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.starts_with("renders_") && n.ends_with(".png"))
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|f| {
            let stem = f.trim_start_matches("renders_").trim_end_matches(".png");
            // Device names carry no '_'; scene names may.
            let (scene, device) = stem.rsplit_once('_').unwrap_or((stem, "?"));
            let caption = format!(
                "{scene}, {device} plans, held-out view {VIEW}: the ground truth, then each \
                 method's render with its SSIM and PSNR on this view and its baked MB"
            );
            (f, caption)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgba;

    #[test]
    fn a_strip_holds_the_truth_and_every_render_present() {
        let dir = tempfile::tempdir().unwrap();
        let truth = RgbaImage::from_pixel(40, 40, Rgba([0, 0, 0, 255]));
        let a = plan_dir(dir.path(), 0, Method::Dp, &["iphone13"]);
        std::fs::create_dir_all(&a).unwrap();
        image::save_buffer(
            a.join("test_0.png"),
            &[200u8; 40 * 40 * 4],
            40,
            40,
            image::ExtendedColorType::Rgba8,
        )
        .unwrap();
        let missing = plan_dir(dir.path(), 1, Method::Single, &["iphone13", "pixel4"]);
        let entries = [
            Entry {
                method: Method::Dp,
                dir: a,
                scores: None,
                megabytes: 1.0,
            },
            Entry {
                method: Method::Single,
                dir: missing,
                scores: None,
                megabytes: 2.0,
            },
        ];
        let out = dir.path().join(strip_name("scene4", "iphone13"));
        write_strip(&truth, &entries, &out).unwrap();
        let s = image::open(&out).unwrap().to_rgba8();
        // Two tiles of 40 px (the truth and the one render present).
        assert_eq!(s.width(), 8 + 40 + 8 + 40 + 8);
        assert_eq!(listed(dir.path()).len(), 1);
    }

    #[test]
    fn plan_folders_are_numbered_and_readable() {
        let d = plan_dir(Path::new("r"), 3, Method::Dp, &["iphone13", "pixel4"]);
        assert_eq!(d, Path::new("r/03-nerflex-dp-iphone13+pixel4"));
    }

    #[test]
    fn a_render_of_another_size_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let truth = RgbaImage::from_pixel(40, 40, Rgba([0, 0, 0, 255]));
        let a = plan_dir(dir.path(), 0, Method::Dp, &["pixel4"]);
        std::fs::create_dir_all(&a).unwrap();
        image::save_buffer(
            a.join("test_0.png"),
            &[200u8; 20 * 20 * 4],
            20,
            20,
            image::ExtendedColorType::Rgba8,
        )
        .unwrap();
        let e = Entry {
            method: Method::Dp,
            dir: a,
            scores: None,
            megabytes: 1.0,
        };
        let err = write_strip(&truth, &[e], &dir.path().join("x.png")).unwrap_err();
        assert!(format!("{err:#}").contains("test_0.png"), "{err:#}");
    }
}
