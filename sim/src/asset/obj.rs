//! The OBJ part of a MobileNeRF export: read any triangle/polygon list with
//! texture coordinates, write quads as 4 `v` + 4 `vt` + 2 faces.
//!
//! Hand-written rather than `tobj` so that every error names its line.
//! Reading regroups consecutive triangles `(a, b, d), (a, d, c)` (the
//! export's pattern, also what a 4-gon fans into) into [`Quad`]s; any other
//! triangle becomes a lone one. Positions convert from the OBJ's
//! `(x, z, −y)` to the z-up world: `world = (x, −z, y)`.

use super::AssetError;
use nerflex_core::raster::{Quad, Vertex};
use std::fmt::Write as _;
use std::path::Path;

/// OBJ position `(x, y, z)` → world (z-up).
pub fn world_from_obj(p: [f32; 3]) -> [f32; 3] {
    [p[0], -p[2], p[1]]
}

/// World (z-up) → OBJ position `(x, z, −y)`.
pub fn obj_from_world(p: [f32; 3]) -> [f32; 3] {
    [p[0], p[2], -p[1]]
}

/// Reads and parses `path`.
pub fn read(path: &Path) -> Result<Vec<Quad>, AssetError> {
    let text = crate::validate::read_to_string(path).map_err(|cause| AssetError::Io {
        path: path.to_path_buf(),
        cause,
    })?;
    parse(&text).map_err(|(line, msg)| AssetError::Obj {
        path: path.to_path_buf(),
        line,
        msg,
    })
}

/// A corner reference: (position index, texture coordinate index), 0-based.
type Corner = (usize, usize);

fn floats<const N: usize>(
    rest: &mut std::str::SplitWhitespace,
    what: &str,
) -> Result<[f32; N], String> {
    let mut out = [0f32; N];
    for (k, o) in out.iter_mut().enumerate() {
        let tok = rest
            .next()
            .ok_or_else(|| format!("`{what}` needs {N} numbers, found {k}"))?;
        let v: f32 = tok
            .parse()
            .map_err(|_| format!("`{what}`: `{tok}` is not a number"))?;
        if !v.is_finite() {
            return Err(format!("`{what}`: `{tok}` is not finite"));
        }
        *o = v;
    }
    Ok(out)
}

/// Resolves a 1-based (or negative, relative) OBJ index against `count` items.
fn index(tok: &str, count: usize, what: &str) -> Result<usize, String> {
    let i: i64 = tok
        .parse()
        .map_err(|_| format!("face: {what} index `{tok}` is not an integer"))?;
    let resolved = if i > 0 {
        i - 1
    } else if i < 0 {
        count as i64 + i
    } else {
        -1
    };
    if resolved < 0 || resolved >= count as i64 {
        return Err(format!(
            "face: {what} index {i} out of range ({count} defined so far)"
        ));
    }
    Ok(resolved as usize)
}

/// Parses OBJ text; errors are (1-based line, message).
pub fn parse(text: &str) -> Result<Vec<Quad>, (usize, String)> {
    let mut pos: Vec<[f32; 3]> = Vec::new();
    let mut uv: Vec<[f32; 2]> = Vec::new();
    let mut tris: Vec<[Corner; 3]> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let lineno = n + 1;
        let err = |m: String| (lineno, m);
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => pos.push(world_from_obj(floats::<3>(&mut it, "v").map_err(err)?)),
            Some("vt") => uv.push(floats::<2>(&mut it, "vt").map_err(err)?),
            Some("f") => {
                let mut corners: Vec<Corner> = Vec::with_capacity(4);
                for tok in it {
                    let mut parts = tok.split('/');
                    let v = parts.next().unwrap_or("");
                    let t = parts.next().unwrap_or("");
                    if t.is_empty() {
                        return Err(err(format!(
                            "face corner `{tok}` has no texture coordinate (need v/vt)"
                        )));
                    }
                    corners.push((
                        index(v, pos.len(), "vertex").map_err(err)?,
                        index(t, uv.len(), "texture coordinate").map_err(err)?,
                    ));
                }
                if corners.len() < 3 {
                    return Err(err(format!(
                        "face has {} corners, needs at least 3",
                        corners.len()
                    )));
                }
                // Fan triangulation of polygons.
                for k in 1..corners.len() - 1 {
                    tris.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            // Comments, groups, smoothing, materials, normals, …: not needed.
            _ => {}
        }
    }
    let vertex = |c: Corner| Vertex {
        pos: pos[c.0],
        uv: uv[c.1],
    };
    let mut quads = Vec::with_capacity(tris.len() / 2 + 1);
    let mut i = 0;
    while i < tris.len() {
        let t = tris[i];
        if let Some(&u) = tris.get(i + 1) {
            // (a, b, d) then (a, d, c) → quad corners [a, b, c, d].
            let (a, b, d, c) = (t[0], t[1], t[2], u[2]);
            let distinct = a != b && a != c && a != d && b != c && b != d && c != d;
            if u[0] == a && u[1] == d && distinct {
                quads.push(Quad::new([a, b, c, d].map(vertex)));
                i += 2;
                continue;
            }
        }
        quads.push(Quad::triangle(vertex(t[0]), vertex(t[1]), vertex(t[2])));
        i += 1;
    }
    Ok(quads)
}

/// The export's OBJ text: per quad 4 `v`, 4 `vt`, faces (1, 2, 4), (1, 4, 3);
/// per lone triangle 3 `v`, 3 `vt`, one face. Floats are written in their
/// shortest exact form, so reading the text back gives the same `f32`s.
pub fn to_string(quads: &[Quad]) -> String {
    let mut s = String::with_capacity(quads.len() * 200);
    let mut base = 1usize;
    for q in quads {
        let n = if q.single_triangle { 3 } else { 4 };
        for c in q.corners.iter().take(n) {
            let [x, y, z] = obj_from_world(c.pos);
            let _ = writeln!(s, "v {x} {y} {z}");
        }
        for c in q.corners.iter().take(n) {
            let _ = writeln!(s, "vt {} {}", c.uv[0], c.uv[1]);
        }
        let f = |k: usize| base + k;
        if q.single_triangle {
            let _ = writeln!(s, "f {0}/{0} {1}/{1} {2}/{2}", f(0), f(1), f(2));
        } else {
            let _ = writeln!(s, "f {0}/{0} {1}/{1} {2}/{2}", f(0), f(1), f(3));
            let _ = writeln!(s, "f {0}/{0} {1}/{1} {2}/{2}", f(0), f(3), f(2));
        }
        base += n;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn export_pattern_becomes_quads_and_polygons_fan() {
        let text = "# test\nv 0 0 0\nv 0 1 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 0 1\nvt 1 0\nvt 1 1\n\
                    f 1/1 2/2 4/4\nf 1/1 4/4 3/3\nf 1/1 2/2 3/3\nf 1/1/1 2/2/1 4/4/1 3/3/1\n";
        let q = parse(text).unwrap();
        assert_eq!(q.len(), 3);
        assert!(!q[0].single_triangle && q[1].single_triangle && !q[2].single_triangle);
        // OBJ (1, 1, 0) = world (1, 0, 1).
        assert_eq!(q[0].corners[3].pos, [1.0, -0.0, 1.0]);
        assert_eq!(q[0], q[2]);
        assert_eq!(parse(&to_string(&q)).unwrap(), q);
    }

    #[test]
    fn errors_name_the_line() {
        let bad = [
            ("v 1 2\n", 1, "needs 3 numbers"),
            ("v 1 2 3\nvt 0 x\n", 2, "not a number"),
            ("v 1 2 3\nvt 0 0\nf 1/1 2/1 1/1\n", 3, "out of range"),
            ("v 1 2 3\nvt 0 0\nf 1 1 1\n", 3, "no texture coordinate"),
            ("v 1 2 3\nvt 0 0\nf 1/1 1/1\n", 3, "at least 3"),
            ("v 1 2 3\nvt 0 0\nf 0/1 1/1 1/1\n", 3, "out of range"),
            ("v 1 2 inf\n", 1, "not finite"),
            ("v 1 2 3\nvt 0 0\n\nf 1/a 1/1 1/1\n", 4, "not an integer"),
        ];
        for (text, line, msg) in bad {
            let (l, m) = parse(text).unwrap_err();
            assert_eq!(l, line, "{text:?}: {m}");
            assert!(m.contains(msg), "{text:?}: {m}");
        }
        // Negative (relative) indices are valid OBJ.
        assert_eq!(
            parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf -3/-1 -2/-1 -1/-1\n")
                .unwrap()
                .len(),
            1
        );
    }
}
