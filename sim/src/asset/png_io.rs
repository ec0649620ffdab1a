//! Strict RGBA8 PNG reading and writing for atlas pages.
//!
//! The export format stores each page as an 8-bit RGBA PNG; anything else
//! (grey, RGB, palette, 16-bit) is rejected with the file's name rather
//! than silently converted, because the alpha channel carries features.

use super::AssetError;
use image::RgbaImage;
use std::io::BufReader;
use std::path::Path;

/// Largest page side accepted, texels.
pub const MAX_SIDE: u32 = nerflex_core::raster::MAX_SIDE;

/// Reads an 8-bit RGBA PNG.
pub fn read_rgba8(path: &Path) -> Result<RgbaImage, AssetError> {
    let err = |msg: String| AssetError::Png {
        path: path.to_path_buf(),
        msg,
    };
    let file = crate::validate::regular_file(path)
        .and_then(|()| std::fs::File::open(path))
        .map_err(|cause| AssetError::Io {
            path: path.to_path_buf(),
            cause,
        })?;
    let mut dec = png::Decoder::new(BufReader::new(file));
    // A 16384² RGBA8 page is 1 GiB: allow that, not more.
    dec.set_limits(png::Limits {
        bytes: (MAX_SIDE as usize).pow(2) * 4 + (1 << 20),
    });
    let mut reader = dec
        .read_info()
        .map_err(|e| err(format!("not a readable PNG: {e}")))?;
    let info = reader.info();
    let (w, h) = (info.width, info.height);
    let (ct, bd) = (info.color_type, info.bit_depth);
    if ct != png::ColorType::Rgba || bd != png::BitDepth::Eight {
        return Err(err(format!(
            "colour type {ct:?} at {} bits; an atlas page must be 8-bit RGBA",
            bd as u8
        )));
    }
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(err(format!(
            "wrong size {w}×{h}: sides must be 1..={MAX_SIDE}"
        )));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| err("image too large".into()))?;
    let mut buf = vec![0u8; size];
    let out = reader
        .next_frame(&mut buf)
        .map_err(|e| err(format!("cannot decode: {e}")))?;
    buf.truncate(out.buffer_size());
    RgbaImage::from_raw(w, h, buf)
        .ok_or_else(|| err("decoded size does not match the header".into()))
}

/// Encodes an RGBA8 image as PNG (default "balanced" compression).
pub fn encode_rgba8(img: &RgbaImage) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, img.width(), img.height());
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| e.to_string())?;
        w.write_image_data(img.as_raw())
            .map_err(|e| e.to_string())?;
        w.finish().map_err(|e| e.to_string())?;
    }
    Ok(out)
}
