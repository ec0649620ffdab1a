//! A trained field on disk: one safetensors file.
//!
//! Tensors: `vertex` (U32, `[slots]`) — the linear lattice index of every
//! stored vertex, x fastest over `(res + 1)³`; `values` (F32, `[slots,
//! 4 | 16 | 32]`) — raw density, the K SH coefficients of R, G and B, zero
//! padding (the in-memory record, see `grid`). Metadata
//! (string → string): `format` = `nerflex-field-1`, `res`, `sh_degree`,
//! `cube_min`/`cube_max` (three numbers each, world units), `density` (how
//! raw density becomes σ), `settings` and `report` (JSON of the training
//! settings and report). The file is written to a temporary name beside
//! the destination and renamed into place, so a failure leaves no half file.

use std::collections::HashMap;
use std::path::Path;

use glam::Vec3;
use rayon::prelude::*;
use safetensors::tensor::TensorView;
use safetensors::{Dtype, SafeTensors};

use super::grid::{SparseGrid, DENSITY_SHIFT, EMPTY};
use super::sh;
use super::trainer::{TrainReport, TrainSettings, MAX_RES};
use crate::bake::Aabb;

/// The format tag in the metadata.
pub const FORMAT: &str = "nerflex-field-1";

/// Largest field file read (4 GiB).
const MAX_FILE_BYTES: u64 = 4 << 30;

/// A field file's problems, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum FieldError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not a valid field.
    #[error("{path}: not a nerflex field: {what}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        what: String,
    },
}

/// A field with what it was trained with.
#[derive(Debug, Clone)]
pub struct SavedField {
    /// The grid.
    pub grid: SparseGrid,
    /// The settings it was trained with.
    pub settings: Option<TrainSettings>,
    /// The training report.
    pub report: Option<TrainReport>,
}

fn vec3_str(v: Vec3) -> String {
    format!("{} {} {}", v.x, v.y, v.z)
}

/// Writes the field atomically.
pub fn save(
    path: &Path,
    grid: &SparseGrid,
    settings: &TrainSettings,
    report: &TrainReport,
) -> Result<(), FieldError> {
    let io = |source| FieldError::Io {
        path: path.display().to_string(),
        source,
    };
    let vertex: Vec<u8> = grid.vertex.iter().flat_map(|v| v.to_le_bytes()).collect();
    let values: Vec<u8> = grid.values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let cells: Vec<u8> = grid
        .cell_bits
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let len = grid.record_len();
    let tensors = [
        (
            "vertex",
            TensorView::new(Dtype::U32, vec![grid.slots()], &vertex)
                .map_err(|e| io(std::io::Error::other(e.to_string())))?,
        ),
        (
            "values",
            TensorView::new(Dtype::F32, vec![grid.slots(), len], &values)
                .map_err(|e| io(std::io::Error::other(e.to_string())))?,
        ),
        (
            "cells",
            TensorView::new(Dtype::U64, vec![grid.cell_bits.len()], &cells)
                .map_err(|e| io(std::io::Error::other(e.to_string())))?,
        ),
    ];
    let mut meta = HashMap::new();
    meta.insert("format".to_string(), FORMAT.to_string());
    meta.insert("res".to_string(), grid.res.to_string());
    meta.insert("sh_degree".to_string(), grid.sh_degree.to_string());
    meta.insert("cube_min".to_string(), vec3_str(grid.cube.min));
    meta.insert("cube_max".to_string(), vec3_str(grid.cube.max));
    meta.insert(
        "density".to_string(),
        format!("sigma = softplus(raw - {DENSITY_SHIFT}) * 256 / edge, per world unit"),
    );
    meta.insert(
        "settings".to_string(),
        serde_json::to_string(settings).unwrap_or_default(),
    );
    meta.insert(
        "report".to_string(),
        serde_json::to_string(report).unwrap_or_default(),
    );
    let bytes = safetensors::serialize(tensors, Some(meta))
        .map_err(|e| io(std::io::Error::other(e.to_string())))?;
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut tmp = tempfile::NamedTempFile::new_in(dir).map_err(io)?;
    std::io::Write::write_all(&mut tmp, &bytes).map_err(io)?;
    tmp.as_file().sync_all().map_err(io)?;
    // A temporary file is private (0600); a field is an ordinary output.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(io)?;
    }
    tmp.persist(path).map_err(|e| io(e.error))?;
    Ok(())
}

/// Reads a field, checking every number and index.
pub fn load(path: &Path) -> Result<SavedField, FieldError> {
    let name = path.display().to_string();
    let bad = |what: String| FieldError::Invalid {
        path: name.clone(),
        what,
    };
    let meta = std::fs::metadata(path).map_err(|source| FieldError::Io {
        path: name.clone(),
        source,
    })?;
    if !meta.is_file() {
        return Err(bad("not a regular file".into()));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(bad(format!("{} bytes, over the 4 GiB limit", meta.len())));
    }
    let bytes = std::fs::read(path).map_err(|source| FieldError::Io {
        path: name.clone(),
        source,
    })?;
    let (_, header) = SafeTensors::read_metadata(&bytes).map_err(|e| bad(e.to_string()))?;
    let st = SafeTensors::deserialize(&bytes).map_err(|e| bad(e.to_string()))?;
    let md = header.metadata().clone().unwrap_or_default();
    let get = |k: &str| {
        md.get(k)
            .ok_or_else(|| bad(format!("metadata `{k}` is missing")))
    };
    if get("format")? != FORMAT {
        return Err(bad(format!(
            "format is `{}`, expected `{FORMAT}`",
            get("format")?
        )));
    }
    let res: u32 = get("res")?
        .parse()
        .map_err(|_| bad("`res` is not a whole number".into()))?;
    if !(1..=MAX_RES).contains(&res) {
        return Err(bad(format!("res {res} outside 1..={MAX_RES}")));
    }
    let sh_degree: u32 = get("sh_degree")?
        .parse()
        .map_err(|_| bad("`sh_degree` is not a whole number".into()))?;
    if sh_degree > sh::MAX_DEGREE {
        return Err(bad(format!(
            "sh_degree {sh_degree} above {}",
            sh::MAX_DEGREE
        )));
    }
    let parse3 = |k: &str| -> Result<Vec3, FieldError> {
        let v: Vec<f32> = get(k)?
            .split_whitespace()
            .map(|s| s.parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad(format!("`{k}` is not three numbers")))?;
        match v.as_slice() {
            [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(*x, *y, *z)),
            _ => Err(bad(format!("`{k}` is not three finite numbers"))),
        }
    };
    let cube = Aabb {
        min: parse3("cube_min")?,
        max: parse3("cube_max")?,
    };
    let edge = cube.max - cube.min;
    if !(edge.min_element() > 0.0 && (edge.max_element() - edge.min_element()) <= 1e-4 * edge.x) {
        return Err(bad("cube_min/cube_max do not span a cube".into()));
    }
    let len = super::grid::record_len(sh_degree);
    let tensor = |k: &str, dtype: Dtype| {
        let t = st
            .tensor(k)
            .map_err(|_| bad(format!("tensor `{k}` is missing")))?;
        if t.dtype() != dtype {
            return Err(bad(format!(
                "tensor `{k}` is {:?}, expected {dtype:?}",
                t.dtype()
            )));
        }
        Ok(t)
    };
    let vt = tensor("vertex", Dtype::U32)?;
    let slots = match vt.shape() {
        [n] => *n,
        s => {
            return Err(bad(format!(
                "tensor `vertex` has shape {s:?}, expected [slots]"
            )))
        }
    };
    let val = tensor("values", Dtype::F32)?;
    if val.shape() != [slots, len] {
        return Err(bad(format!(
            "tensor `values` has shape {:?}, expected [{slots}, {len}]",
            val.shape()
        )));
    }
    let n = (res as usize + 1).pow(3);
    // Hundreds of MB: converted, checked and indexed on every core (the
    // first touches of fresh pages are most of this on a VM).
    let vertex: Vec<u32> = vt
        .data()
        .par_chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let values: Vec<f32> = val
        .data()
        .par_chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if let Some(i) = values.par_iter().position_first(|v| !v.is_finite()) {
        return Err(bad(format!("value {i} is not finite")));
    }
    let mut index: Vec<u32> = (0..n).into_par_iter().map(|_| EMPTY).collect();
    for (s, &v) in vertex.iter().enumerate() {
        let slot = index
            .get_mut(v as usize)
            .ok_or_else(|| bad(format!("vertex {v} outside the {n}-vertex lattice")))?;
        if *slot != EMPTY {
            return Err(bad(format!("vertex {v} is stored twice")));
        }
        *slot = s as u32;
    }
    let mut grid = SparseGrid {
        res,
        cube,
        sh_degree,
        index,
        vertex,
        values,
        cell_bits: Vec::new(),
    };
    grid.rebuild_cells();
    // The cells training left marching (pruning clears some): a subset of
    // those with a stored corner. Older files have none: all are marched.
    if let Ok(t) = st.tensor("cells") {
        let words = grid.cell_bits.len();
        if t.dtype() != Dtype::U64 || t.shape() != [words] {
            return Err(bad(format!(
                "tensor `cells` is {:?} {:?}, expected U64 [{words}]",
                t.dtype(),
                t.shape()
            )));
        }
        for (b, c) in grid.cell_bits.iter_mut().zip(t.data().chunks_exact(8)) {
            let w = u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
            *b &= w;
        }
    }
    let settings = md
        .get("settings")
        .and_then(|s| serde_json::from_str(s).ok());
    let report = md.get("report").and_then(|s| serde_json::from_str(s).ok());
    Ok(SavedField {
        grid,
        settings,
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small_grid() -> SparseGrid {
        let cube = Aabb {
            min: Vec3::new(-1.0, -0.5, 0.25),
            max: Vec3::new(1.0, 1.5, 2.25),
        };
        let mut g = SparseGrid::new(6, cube, 1, |i, j, k| (i + j + k) % 3 != 0);
        for (n, v) in g.values.iter_mut().enumerate() {
            *v = (n as f32 * 0.377).sin() * 3.0;
        }
        g
    }

    #[test]
    fn round_trip_is_bit_identical() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.safetensors");
        let g = small_grid();
        let s = TrainSettings::default();
        let r = TrainReport {
            total_s: 1.5,
            ..TrainReport::default()
        };
        save(&path, &g, &s, &r).unwrap();
        let back = load(&path).unwrap();
        assert_eq!(back.grid, g);
        assert_eq!(back.settings, Some(s.clone()));
        assert_eq!(back.report.map(|r| r.total_s), Some(1.5));
        // Pruned cells come back pruned.
        let mut pruned = g.clone();
        let len = pruned.record_len();
        for v in pruned.values.chunks_mut(len) {
            v[0] = -30.0;
        }
        assert!(pruned.prune_cells(1e-3) > 0);
        save(&path, &pruned, &s, &r).unwrap();
        assert_eq!(load(&path).unwrap().grid, pruned);
    }

    #[test]
    fn malformed_files_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.safetensors");
        for bytes in [&b""[..], b"not safetensors at all", &[255u8; 64]] {
            std::fs::write(&path, bytes).unwrap();
            let e = load(&path).unwrap_err().to_string();
            assert!(e.contains("bad.safetensors"), "{e}");
        }
        // A valid container with a broken field: a vertex outside the lattice.
        let mut g = small_grid();
        g.vertex[0] = u32::MAX - 1;
        save(
            &path,
            &g,
            &TrainSettings::default(),
            &TrainReport::default(),
        )
        .unwrap();
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("outside"), "{e}");
        // Non-finite values: the first is named (the check runs in parallel).
        let mut g = small_grid();
        let last = g.values.len() - 1;
        g.values[last] = f32::NAN;
        g.values[3] = f32::INFINITY;
        save(
            &path,
            &g,
            &TrainSettings::default(),
            &TrainReport::default(),
        )
        .unwrap();
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("value 3 is not finite"), "{e}");
        assert!(load(dir.path())
            .unwrap_err()
            .to_string()
            .contains("not a regular file"));
    }
}
