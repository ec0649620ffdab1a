//! The export: atlas pages from texel bytes (the existing cell layout of
//! `bake::atlas`), and writing the MobileNeRF layout with every page's two
//! PNGs encoded in parallel (the encoder is single-threaded per image, and
//! a g = 128 export has several pages).

use image::RgbaImage;
use rayon::prelude::*;
use std::path::Path;

use super::super::atlas::{Atlas, AtlasLayout, AtlasPage};
use crate::asset::{self, Asset, AssetError};

/// Both atlases, page by page: texel `t` of quad `q` (row-major in its
/// p×p cell) gets `texels[q·p² + t]` (feat0 RGBA then feat1 RGBA).
pub fn atlas(layout: &AtlasLayout, texels: &[[u8; 8]]) -> Atlas {
    let p = layout.patch as usize;
    let pages = layout
        .pages
        .iter()
        .enumerate()
        .map(|(pi, pl)| {
            let (pw, ph) = layout.page_size(pi);
            let fill = |half: usize| {
                let mut img = RgbaImage::new(pw, ph);
                let row_bytes = p * pw as usize * 4;
                img.as_mut()
                    .par_chunks_mut(row_bytes)
                    .enumerate()
                    .for_each(|(row, buf)| {
                        for (col, q) in pl.row_quads(row) {
                            for ty in 0..p {
                                for tx in 0..p {
                                    let Some(b) = texels.get(q * p * p + ty * p + tx) else {
                                        continue;
                                    };
                                    let at = (ty * pw as usize + col * p + tx) * 4;
                                    buf[at..at + 4].copy_from_slice(&b[4 * half..4 * half + 4]);
                                }
                            }
                        }
                    });
                img
            };
            let (feat0, feat1) = rayon::join(|| fill(0), || fill(1));
            AtlasPage { feat0, feat1 }
        })
        .collect();
    Atlas {
        layout: layout.clone(),
        pages,
    }
}

/// Writes `asset` in the export layout into `dir` (as `Asset::write`, each
/// file through a temporary name), encoding all PNGs and OBJs in parallel
/// first. Returns the bytes written.
pub fn write(asset: &Asset, dir: &Path) -> Result<u64, AssetError> {
    std::fs::create_dir_all(dir).map_err(|cause| AssetError::Io {
        path: dir.to_path_buf(),
        cause,
    })?;
    // (file name, bytes) of every shape file, encoded in parallel.
    let files: Vec<Result<(String, Vec<u8>), AssetError>> = asset
        .shapes
        .par_iter()
        .flat_map_iter(|s| {
            let [o, p0, p1] = asset::shape_files(s.index);
            [(o, 0u8), (p0, 1), (p1, 2)]
                .into_iter()
                .map(move |(n, k)| (s, n, k))
        })
        .map(|(s, name, k)| {
            let bytes = match k {
                0 => Ok(asset::obj::to_string(&s.quads).into_bytes()),
                1 => asset::png_io::encode_rgba8(s.atlas.feat0()),
                _ => asset::png_io::encode_rgba8(s.atlas.feat1()),
            }
            .map_err(|msg| AssetError::Png {
                path: dir.join(&name),
                msg,
            })?;
            Ok((name, bytes))
        })
        .collect();
    let json = asset::mlp_json::to_string(asset.mlp.weights(), asset.obj_num);
    let mut total = asset::write_atomic(&dir.join("mlp.json"), json.as_bytes())?;
    for f in files {
        let (name, bytes) = f?;
        total += asset::write_atomic(&dir.join(name), &bytes)?;
    }
    Ok(total)
}
