//! Encoding a baked object in the MobileNeRF export layout.
//!
//! One shape file per atlas page: `shape{i}.obj` (4 `v`, 4 `vt` and the
//! faces (1,2,4), (1,4,3) per quad, 1-based and local to the file, vertices
//! written as (x, z, −y), `vt` v = 1 − y with UVs on texel centres),
//! `shape{i}.pngfeat0.png`, `shape{i}.pngfeat1.png`, and one `mlp.json`
//! (`{0,1,2}_weights` `W[in][out]`, `{0,1,2}_bias`, `obj_num`).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context as _;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ImageEncoder, RgbaImage};
use rayon::prelude::*;

use super::mlp_fit::MlpWeights;
use super::BakedObject;

/// One encoded file of the export: name and bytes.
#[derive(Debug, Clone)]
pub struct EncodedFile {
    /// File name inside the asset folder.
    pub name: String,
    /// Contents.
    pub bytes: Vec<u8>,
}

/// Encodes every file of the export in memory (pages in parallel).
pub fn encode(obj: &BakedObject) -> anyhow::Result<Vec<EncodedFile>> {
    let layout = &obj.atlas.layout;
    let per_page: Vec<anyhow::Result<Vec<EncodedFile>>> = obj
        .atlas
        .pages
        .par_iter()
        .enumerate()
        .map(|(i, page)| {
            let pl = &layout.pages[i];
            let (pw, ph) = layout.page_size(i);
            let mut text = String::with_capacity(pl.quads * 200);
            for (n, q) in obj.quads[pl.first_quad..pl.first_quad + pl.quads]
                .iter()
                .enumerate()
            {
                let cell = layout
                    .cell(pl.first_quad + n)
                    .context("quad outside the atlas layout")?;
                let last = (layout.patch - 1) as f32;
                let corners = q.corners();
                // Texel offsets of the corners: (0,0), (0,p−1), (p−1,0), (p−1,p−1).
                let tex = [(0.0, 0.0), (0.0, last), (last, 0.0), (last, last)];
                for c in corners {
                    let _ = writeln!(text, "v {:.6} {:.6} {:.6}", c.x, c.z, -c.y);
                }
                for (tx, ty) in tex {
                    let u = (cell.x as f32 + tx + 0.5) / pw as f32;
                    let v = 1.0 - (cell.y as f32 + ty + 0.5) / ph as f32;
                    let _ = writeln!(text, "vt {u:.6} {v:.6}");
                }
                let b = 4 * n + 1;
                let _ = writeln!(text, "f {b}/{b} {}/{} {}/{}", b + 1, b + 1, b + 3, b + 3);
                let _ = writeln!(text, "f {b}/{b} {}/{} {}/{}", b + 3, b + 3, b + 2, b + 2);
            }
            Ok(vec![
                EncodedFile {
                    name: format!("shape{i}.obj"),
                    bytes: text.into_bytes(),
                },
                EncodedFile {
                    name: format!("shape{i}.pngfeat0.png"),
                    bytes: png_bytes(&page.feat0)?,
                },
                EncodedFile {
                    name: format!("shape{i}.pngfeat1.png"),
                    bytes: png_bytes(&page.feat1)?,
                },
            ])
        })
        .collect();
    let mut files = Vec::new();
    for p in per_page {
        files.extend(p?);
    }
    files.push(EncodedFile {
        name: "mlp.json".into(),
        bytes: mlp_json(&obj.mlp, obj.atlas.pages.len())?.into_bytes(),
    });
    Ok(files)
}

fn png_bytes(img: &RgbaImage) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Default, FilterType::Adaptive)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgba8,
        )
        .context("encoding an atlas page as PNG")?;
    Ok(out)
}

/// The `mlp.json` text.
pub fn mlp_json(mlp: &MlpWeights, obj_num: usize) -> anyhow::Result<String> {
    let v = serde_json::json!({
        "0_weights": mlp.w0.iter().map(|r| r.to_vec()).collect::<Vec<_>>(),
        "0_bias": mlp.b0.to_vec(),
        "1_weights": mlp.w1.iter().map(|r| r.to_vec()).collect::<Vec<_>>(),
        "1_bias": mlp.b1.to_vec(),
        "2_weights": mlp.w2.iter().map(|r| r.to_vec()).collect::<Vec<_>>(),
        "2_bias": mlp.b2.to_vec(),
        "obj_num": obj_num,
    });
    Ok(serde_json::to_string(&v)?)
}

/// Writes the encoded files into `dir` (created if needed), each through a
/// temporary file and a rename so a crash never leaves a half-written file.
pub fn write(files: &[EncodedFile], dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    for f in files {
        let path = dir.join(&f.name);
        let tmp = dir.join(format!(".{}.tmp", f.name));
        std::fs::write(&tmp, &f.bytes)
            .with_context(|| format!("{}: cannot write", tmp.display()))?;
        std::fs::rename(&tmp, &path)
            .with_context(|| format!("{}: cannot rename into place", path.display()))?;
    }
    Ok(())
}

/// Total bytes of the encoded files.
pub fn file_bytes(files: &[EncodedFile]) -> u64 {
    files.iter().map(|f| f.bytes.len() as u64).sum()
}
