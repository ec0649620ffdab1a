//! Reading the PNGs the metrics compare, with errors that name the file.

use super::MetricsError;
use image::RgbaImage;
use std::path::Path;

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// Reads a PNG file (any bit depth or colour type) as 8-bit RGBA.
///
/// Errors name the file: missing/unreadable, not a PNG, or broken PNG data.
pub fn read_png(path: &Path) -> Result<RgbaImage, MetricsError> {
    let bytes = crate::validate::read(path).map_err(|error| MetricsError::Io {
        path: path.to_owned(),
        error,
    })?;
    if !bytes.starts_with(&PNG_SIGNATURE) {
        return Err(MetricsError::NotPng {
            path: path.to_owned(),
            message: "not a PNG file (no PNG signature)".to_owned(),
        });
    }
    let img =
        image::load_from_memory_with_format(&bytes, image::ImageFormat::Png).map_err(|e| {
            MetricsError::NotPng {
                path: path.to_owned(),
                message: format!("broken PNG: {e}"),
            }
        })?;
    Ok(img.to_rgba8())
}
