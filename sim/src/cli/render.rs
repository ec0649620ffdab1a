//! `nerflex render`: render a MobileNeRF-format asset to a PNG.

use crate::asset::{png_io, write_atomic, Asset};
use crate::camera::{Camera, Intrinsics, Transforms};
use crate::render::{render, RenderOptions};
use anyhow::{bail, Context};
use glam::Vec3;
use std::path::PathBuf;

/// Flags of `nerflex render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Export folder: mlp.json, shape{i}.obj, shape{i}.pngfeat{0,1}.png.
    #[arg(long)]
    pub asset: PathBuf,
    /// Orbit camera: turntable angle in degrees (counter-clockwise about +z; 0 = on the −y side).
    #[arg(long, default_value_t = 0.0, conflicts_with_all = ["transforms", "frame"])]
    pub angle: f32,
    /// Orbit camera: elevation above the ground plane, degrees.
    #[arg(long, default_value_t = 30.0, conflicts_with_all = ["transforms", "frame"])]
    pub elevation: f32,
    /// Orbit camera: distance from the origin, world units (NeRF-synthetic cameras sit at ≈ 4.03).
    #[arg(long, default_value_t = 4.031, conflicts_with_all = ["transforms", "frame"])]
    pub distance: f32,
    /// Orbit camera: horizontal field of view, degrees (NeRF-synthetic: 39.6).
    #[arg(long, default_value_t = 39.6, conflicts_with_all = ["transforms", "frame"])]
    pub fov: f32,
    /// NeRF-synthetic transforms_*.json to take the camera from (with --frame).
    #[arg(long, requires = "frame")]
    pub transforms: Option<PathBuf>,
    /// Frame index in --transforms.
    #[arg(long, requires = "transforms")]
    pub frame: Option<usize>,
    /// Image size: W or WxH pixels.
    #[arg(long, default_value = "800")]
    pub size: String,
    /// Shade with the f32 MLP instead of the fixed-point one.
    #[arg(long)]
    pub float: bool,
    /// Shade with the core's narrow (16-bit) fixed-point shader, eight
    /// pixels at a time (AVX2 when the CPU has it), where the weight set
    /// passes its accuracy check; the exact shader otherwise.
    #[arg(long, conflicts_with = "float")]
    pub narrow: bool,
    /// One sample per pixel instead of the default 2 × 2 supersampling
    /// (MobileNeRF's viewer: G-buffer at twice the side, features averaged,
    /// MLP once per pixel, edges blended); `--narrow` always renders one.
    #[arg(long)]
    pub no_supersample: bool,
    /// Output PNG.
    #[arg(long)]
    pub out: PathBuf,
}

/// Parses `W` or `WxH` (1..=16384 each).
pub fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let parse = |t: &str| -> anyhow::Result<u32> {
        let v: u32 = t
            .trim()
            .parse()
            .with_context(|| format!("--size {s:?}: `{t}` is not a whole number of pixels"))?;
        if !(1..=16384).contains(&v) {
            bail!("--size {s:?}: {v} is not in 1..=16384");
        }
        Ok(v)
    };
    match s.split_once(['x', 'X']) {
        Some((w, h)) => Ok((parse(w)?, parse(h)?)),
        None => {
            let w = parse(s)?;
            Ok((w, w))
        }
    }
}

/// The camera the flags describe.
pub fn camera(args: &Args, w: u32, h: u32) -> anyhow::Result<Camera> {
    if let (Some(path), Some(frame)) = (&args.transforms, args.frame) {
        let t = Transforms::read(path)?;
        return t.camera(frame, w, h).with_context(|| {
            format!(
                "--frame {frame}: {} has {} frames",
                path.display(),
                t.frames.len()
            )
        });
    }
    for (flag, v) in [
        ("--angle", args.angle),
        ("--elevation", args.elevation),
        ("--distance", args.distance),
        ("--fov", args.fov),
    ] {
        if !v.is_finite() {
            bail!("{flag} {v} is not a finite number");
        }
    }
    if args.distance <= 0.0 {
        bail!("--distance {} must be positive", args.distance);
    }
    if !(args.fov > 0.0 && args.fov < 179.0) {
        bail!("--fov {} must be in (0, 179) degrees", args.fov);
    }
    let k = Intrinsics::from_fov_x(args.fov.to_radians(), w, h);
    Ok(Camera::orbit(
        args.angle,
        args.elevation,
        args.distance,
        Vec3::ZERO,
        k,
    ))
}

/// Runs `nerflex render`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (w, h) = parse_size(&args.size)?;
    let supersample = !args.no_supersample && !args.narrow;
    let limit = 16384 / nerflex_core::raster::SUPERSAMPLE;
    if supersample && w.max(h) > limit {
        bail!(
            "--size {}: a supersampled render rasterizes at twice the side, so at most {limit} pixels a side; add --no-supersample for up to 16384",
            args.size
        );
    }
    let cam = camera(&args, w, h)?;
    let t0 = std::time::Instant::now();
    let asset = Asset::load(&args.asset)?;
    let load_time = t0.elapsed();
    println!("asset: {}", asset.report());
    println!("loaded in {:.2} s", load_time.as_secs_f64());
    let opts = RenderOptions {
        float: args.float,
        supersample,
    };
    let (img, stats) = if args.narrow {
        let tables = crate::render::narrow_tables(&[&asset])
            .map_err(|e| anyhow::anyhow!("{}: narrow shader: {e}", args.asset.display()))?;
        if tables.iter().any(Option::is_none) {
            println!("narrow shader: the weights fail its accuracy check; exact shader used");
        }
        crate::render::try_render_scene_narrow(&[&asset], &cam, &opts, &tables)
            .map_err(|e| anyhow::anyhow!("cannot render this camera: {e}"))?
    } else {
        let (img, stats) = render(&asset, &cam, &opts);
        if let Some(e) = stats.camera_error {
            bail!("cannot render this camera: {e}");
        }
        (img, stats)
    };
    let png =
        png_io::encode_rgba8(&img).map_err(|e| anyhow::anyhow!("{}: {e}", args.out.display()))?;
    write_atomic(&args.out, &png)?;
    println!(
        "{}×{} {} render: quads drawn {} of {} ({} visible), pixels shaded {}, time {:.1} ms -> {}",
        w,
        h,
        if args.float {
            "f32"
        } else if args.narrow {
            "narrow fixed-point"
        } else {
            "fixed-point"
        },
        stats.quads_drawn,
        stats.quads_total,
        stats.quads_visible,
        stats.pixels_shaded,
        stats.time.as_secs_f64() * 1e3,
        args.out.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_bad_ones_name_the_flag() {
        assert_eq!(parse_size("800").unwrap(), (800, 800));
        assert_eq!(parse_size("640x480").unwrap(), (640, 480));
        for bad in ["0", "800x", "x600", "abc", "99999", "-5"] {
            let e = parse_size(bad).unwrap_err().to_string();
            assert!(e.contains("--size"), "{bad}: {e}");
        }
    }

    fn args() -> Args {
        Args {
            asset: PathBuf::from("nowhere"),
            angle: 0.0,
            elevation: 30.0,
            distance: 4.031,
            fov: 39.6,
            transforms: None,
            frame: None,
            size: "8".into(),
            float: false,
            narrow: false,
            no_supersample: false,
            out: PathBuf::from("x.png"),
        }
    }

    #[test]
    fn a_supersampled_render_too_large_names_the_flags() {
        let mut a = args();
        a.size = "9000".into();
        let e = run(a).unwrap_err().to_string();
        assert!(
            e.contains("--size") && e.contains("--no-supersample"),
            "{e}"
        );
    }

    #[test]
    fn bad_camera_flags_are_errors() {
        let mut a = args();
        a.distance = -1.0;
        assert!(camera(&a, 8, 8)
            .unwrap_err()
            .to_string()
            .contains("--distance"));
        let mut a = args();
        a.fov = 180.0;
        assert!(camera(&a, 8, 8).unwrap_err().to_string().contains("--fov"));
        let mut a = args();
        a.angle = f32::NAN;
        assert!(camera(&a, 8, 8)
            .unwrap_err()
            .to_string()
            .contains("--angle"));
        let e = run(args()).unwrap_err();
        assert!(format!("{e:#}").contains("nowhere"), "{e:#}");
    }
}
