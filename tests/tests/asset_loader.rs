//! The MobileNeRF asset loader and writer: the real drums export, a
//! write → load round trip, and broken files made here (each error must
//! name the file, and the line or key).

use nerflex_core::raster::{Quad, Vertex};
use nerflex_core::shader::MlpWeights;
use nerflex_sim::asset::image::RgbaImage;
use nerflex_sim::asset::{mlp_json, Asset, AtlasPair, Mlp, Shape};
use std::path::Path;

/// A tiny asset built in code: two quads in 17 × 17 cells and one lone
/// triangle, a 34 × 17 atlas, shape index 1 of obj_num 2.
fn tiny_asset() -> Asset {
    let (w, h) = (34, 17);
    let cell = |x0: f32, p: [[f32; 3]; 4]| {
        Quad::new([
            Vertex::at_texel(p[0], x0 + 0.5, 0.5, w, h),
            Vertex::at_texel(p[1], x0 + 0.5, 16.5, w, h),
            Vertex::at_texel(p[2], x0 + 16.5, 0.5, w, h),
            Vertex::at_texel(p[3], x0 + 16.5, 16.5, w, h),
        ])
    };
    let quads = vec![
        cell(
            0.0,
            [
                [-0.5, 0.0, 0.5],
                [-0.5, 0.0, -0.5],
                [0.5, 0.0, 0.5],
                [0.5, 0.0, -0.5],
            ],
        ),
        cell(
            17.0,
            [
                [0.1, -0.2, 0.3],
                [0.1, 0.2, 0.3],
                [0.7, -0.2, 0.3],
                [0.7, 0.2, 0.3],
            ],
        ),
        Quad::triangle(
            Vertex::at_texel([0.0, 0.3, 0.0], 0.5, 0.5, w, h),
            Vertex::at_texel([0.2, 0.3, 0.0], 16.5, 0.5, w, h),
            Vertex::at_texel([0.0, 0.3, 0.2], 0.5, 16.5, w, h),
        ),
    ];
    let f0 = RgbaImage::from_fn(w, h, |x, y| {
        nerflex_sim::asset::image::Rgba([(x * 7 + y) as u8 | 1, (y * 13) as u8, 200, 128 + x as u8])
    });
    let f1 = RgbaImage::from_fn(w, h, |x, y| {
        nerflex_sim::asset::image::Rgba([(x * 3) as u8, (y * 5) as u8, (x ^ y) as u8, 255])
    });
    let mut weights = MlpWeights::ZERO;
    weights.w0[3][4] = -0.75;
    weights.w2[15][2] = 1.5e-3;
    weights.b1[7] = 0.125;
    Asset {
        mlp: Mlp::new(weights).unwrap(),
        obj_num: 2,
        shapes: vec![Shape {
            index: 1,
            quads,
            atlas: AtlasPair::new(f0, f1).unwrap(),
        }],
        file_bytes: 0,
    }
}

#[test]
fn real_drums_export_loads_with_the_documented_sizes() {
    let Some(data) = nerflex_sim::data::require_data("drums asset") else {
        return;
    };
    let dir = data.join("mobilenerf/drums");
    let a = Asset::load(&dir).unwrap();
    let r = a.report();
    println!("drums: {r}");
    assert_eq!(a.obj_num, 3);
    assert_eq!(r.missing_shapes, vec![0, 1]);
    assert_eq!((r.shapes, r.quads, r.lone_triangles), (1, 4748, 1530));
    assert_eq!((r.triangles, r.vertices), (11_026, 23_582));
    assert_eq!(r.atlas_pages, 2);
    assert_eq!(r.gpu_bytes, 2 * 4096 * 4096 * 4);
    let on_disk: u64 = [
        "mlp.json",
        "shape2.obj",
        "shape2.pngfeat0.png",
        "shape2.pngfeat1.png",
    ]
    .iter()
    .map(|f| std::fs::metadata(dir.join(f)).unwrap().len())
    .sum();
    assert_eq!(r.file_bytes, on_disk);
    // OBJ (x, y, z) = world (x, z, −y): the first vertex of the file is
    // `v -0.141178 -0.468320 0.656254`.
    let v0 = a.shapes[0].quads[0].corners[0];
    assert_eq!(v0.pos, [-0.141178, -0.656254, -0.468320]);
    assert_eq!(v0.uv, [0.000122, 0.999878]);
    // This shape is the floor-level part of the kit: world z (up) in
    // [−0.55, −0.41], x across ±1.14 (the dataset's units, cameras ≈ 4 away).
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for q in &a.shapes[0].quads {
        for c in &q.corners {
            for k in 0..3 {
                lo[k] = lo[k].min(c.pos[k]);
                hi[k] = hi[k].max(c.pos[k]);
            }
        }
    }
    println!("drums shape2 world bounds: min {lo:?} max {hi:?}");
    assert!(lo[2] > -0.55 && hi[2] < -0.41, "{lo:?} {hi:?}");
    assert!(lo[0] < -1.1 && hi[0] > 1.1, "{lo:?} {hi:?}");
    // The weights file is the same as weights/drums_mlp.json.
    let (w, n) = mlp_json::read(&data.join("mobilenerf/weights/drums_mlp.json")).unwrap();
    assert_eq!((&w, n), (a.mlp.weights(), 3));
}

#[test]
fn real_drums_write_then_load_round_trips() {
    let Some(data) = nerflex_sim::data::require_data("drums asset round trip") else {
        return;
    };
    let a = Asset::load(&data.join("mobilenerf/drums")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let written = a.write(tmp.path()).unwrap();
    let b = Asset::load(tmp.path()).unwrap();
    assert_eq!(b.file_bytes, written);
    assert_eq!(b.mlp, a.mlp);
    assert_eq!(b.shapes, a.shapes);
    // Same keys, same numbers as the original mlp.json.
    let orig: serde_json::Value =
        serde_json::from_slice(&std::fs::read(data.join("mobilenerf/drums/mlp.json")).unwrap())
            .unwrap();
    let ours: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.path().join("mlp.json")).unwrap()).unwrap();
    assert_eq!(orig, ours);
}

#[test]
fn code_built_asset_round_trips_in_the_export_layout() {
    let a = tiny_asset();
    let tmp = tempfile::tempdir().unwrap();
    let bytes = a.write(tmp.path()).unwrap();
    let mut names: Vec<String> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "mlp.json",
            "shape1.obj",
            "shape1.pngfeat0.png",
            "shape1.pngfeat1.png"
        ]
    );
    let obj = std::fs::read_to_string(tmp.path().join("shape1.obj")).unwrap();
    let kinds: String = obj
        .lines()
        .map(|l| {
            if l.starts_with("vt") {
                't'
            } else {
                l.as_bytes()[0] as char
            }
        })
        .collect();
    assert_eq!(kinds, "vvvvttttffvvvvttttffvvvtttf");
    assert!(obj.contains("f 1/1 2/2 4/4\nf 1/1 4/4 3/3\n") && obj.contains("f 9/9 10/10 11/11\n"));
    // World (−0.5, 0, 0.5) is written as (x, z, −y) = (−0.5, 0.5, −0).
    assert!(obj.starts_with("v -0.5 0.5 -0\n"), "{}", &obj[..40]);
    // UVs on texel centres, v = 1 − y/h: (0.5/34, 1 − 0.5/17).
    assert!(obj.contains(&format!("vt {} {}\n", 0.5f32 / 34.0, 1.0f32 - 0.5 / 17.0)));
    let b = Asset::load(tmp.path()).unwrap();
    assert_eq!(b.file_bytes, bytes);
    assert_eq!(
        (b.mlp.clone(), b.obj_num, b.shapes.clone()),
        (a.mlp.clone(), a.obj_num, a.shapes.clone())
    );
    assert_eq!(b.missing_shapes(), vec![0]);
    let r = b.report();
    assert_eq!(
        (r.quads, r.lone_triangles, r.triangles, r.vertices),
        (2, 1, 5, 11)
    );
    assert_eq!(r.gpu_bytes, 2 * 34 * 17 * 4);
    // Writing again over it works (temp file + rename).
    assert_eq!(a.write(tmp.path()).unwrap(), bytes);
    // Shape indices must be below obj_num.
    let mut bad = a.clone();
    bad.obj_num = 1;
    assert!(bad
        .write(&tmp.path().join("x"))
        .unwrap_err()
        .to_string()
        .contains("obj_num"));
}

// ---------------------------------------------------------------------------
// Broken inputs.

/// A PNG with stored (uncompressed) deflate blocks: any colour type and depth.
fn raw_png(w: u32, h: u32, color_type: u8, depth: u8, channels: usize) -> Vec<u8> {
    fn crc32(data: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut c = kind.to_vec();
        c.extend_from_slice(data);
        out.extend_from_slice(&c);
        out.extend_from_slice(&crc32(&c).to_be_bytes());
    }
    let row = 1 + w as usize * channels * (depth as usize / 8);
    let raw: Vec<u8> = (0..h as usize * row)
        .map(|i| if i % row == 0 { 0 } else { (i * 7) as u8 })
        .collect();
    let mut z = vec![0x78, 0x01];
    for (i, block) in raw.chunks(65535).enumerate() {
        let last = (i + 1) * 65535 >= raw.len();
        z.push(last as u8);
        z.extend_from_slice(&(block.len() as u16).to_le_bytes());
        z.extend_from_slice(&(!(block.len() as u16)).to_le_bytes());
        z.extend_from_slice(block);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in &raw {
        a = (a + x as u32) % 65521;
        b = (b + a) % 65521;
    }
    z.extend_from_slice(&((b << 16) | a).to_be_bytes());
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[depth, color_type, 0, 0, 0]);
    chunk(&mut out, b"IHDR", &ihdr);
    chunk(&mut out, b"IDAT", &z);
    chunk(&mut out, b"IEND", &[]);
    out
}

/// Writes the tiny asset and returns its folder.
fn written() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    tiny_asset().write(tmp.path()).unwrap();
    tmp
}

/// Loads `dir` expecting an error that mentions every `needle`.
fn load_err(dir: &Path, needles: &[&str]) -> String {
    let e = match Asset::load(dir) {
        Ok(_) => panic!(
            "{} loaded, expected an error mentioning {needles:?}",
            dir.display()
        ),
        Err(e) => e.to_string(),
    };
    for n in needles {
        assert!(e.contains(n), "error {e:?} should mention {n:?}");
    }
    e
}

fn edit(path: &Path, f: impl FnOnce(String) -> String) {
    let s = std::fs::read_to_string(path).unwrap();
    std::fs::write(path, f(s)).unwrap();
}

#[test]
fn our_raw_png_helper_makes_loadable_pngs() {
    let t = written();
    std::fs::write(
        t.path().join("shape1.pngfeat1.png"),
        raw_png(34, 17, 6, 8, 4),
    )
    .unwrap();
    Asset::load(t.path()).unwrap();
}

#[test]
fn broken_obj_lines_name_file_and_line() {
    // (1-based line of the tiny asset's OBJ to replace, new text, expected error parts)
    let cases: [(usize, &str, &[&str]); 6] = [
        (1, "v 1 2", &["shape1.obj:1:", "needs 3 numbers"]),
        (5, "vt 0.5 x", &["shape1.obj:5:", "not a number"]),
        (
            9,
            "f 1/1 2/2 40/4",
            &["shape1.obj:9:", "vertex index 40 out of range"],
        ),
        (
            10,
            "f 1/1 4/4 3/99",
            &["shape1.obj:10:", "texture coordinate index 99 out of range"],
        ),
        (9, "f 1 2 4", &["shape1.obj:9:", "no texture coordinate"]),
        (9, "f 1/1 2/2", &["shape1.obj:9:", "at least 3"]),
    ];
    for (line, text, needles) in cases {
        let t = written();
        edit(&t.path().join("shape1.obj"), |s| {
            s.lines()
                .enumerate()
                .map(|(i, l)| if i + 1 == line { text } else { l })
                .collect::<Vec<_>>()
                .join("\n")
        });
        load_err(t.path(), needles);
    }
}

#[test]
fn broken_pngs_name_the_file() {
    let t = written();
    std::fs::write(
        t.path().join("shape1.pngfeat1.png"),
        raw_png(33, 17, 6, 8, 4),
    )
    .unwrap();
    load_err(t.path(), &["shape1.pngfeat1.png", "wrong size 33×17"]);
    let t = written();
    std::fs::write(
        t.path().join("shape1.pngfeat0.png"),
        raw_png(34, 17, 2, 8, 3),
    )
    .unwrap();
    load_err(t.path(), &["shape1.pngfeat0.png", "Rgb", "8-bit RGBA"]);
    let t = written();
    std::fs::write(
        t.path().join("shape1.pngfeat0.png"),
        raw_png(34, 17, 6, 16, 4),
    )
    .unwrap();
    load_err(t.path(), &["shape1.pngfeat0.png", "16 bits", "8-bit RGBA"]);
    let t = written();
    std::fs::write(t.path().join("shape1.pngfeat1.png"), b"not a png at all").unwrap();
    load_err(t.path(), &["shape1.pngfeat1.png", "not a readable PNG"]);
    let t = written();
    let mut png = std::fs::read(t.path().join("shape1.pngfeat1.png")).unwrap();
    png.truncate(png.len() / 2);
    std::fs::write(t.path().join("shape1.pngfeat1.png"), png).unwrap();
    load_err(t.path(), &["shape1.pngfeat1.png"]);
    let t = written();
    std::fs::remove_file(t.path().join("shape1.pngfeat0.png")).unwrap();
    load_err(t.path(), &["shape1.pngfeat0.png", "missing"]);
}

#[test]
fn broken_mlp_json_names_file_and_key() {
    let t = written();
    let p = t.path().join("mlp.json");
    edit(&p, |s| s.replace("\"2_bias\"", "\"2_b\""));
    load_err(t.path(), &["mlp.json", "missing key `2_bias`"]);
    let t = written();
    let p = t.path().join("mlp.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["1_weights"][3].as_array_mut().unwrap().pop();
    std::fs::write(&p, v.to_string()).unwrap();
    load_err(
        t.path(),
        &["mlp.json", "`1_weights[3]` has 15 entries, expected 16"],
    );
    let t = written();
    let p = t.path().join("mlp.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["0_weights"] = serde_json::to_value([[1.0f64; 16]; 3]).unwrap();
    std::fs::write(&p, v.to_string()).unwrap();
    load_err(t.path(), &["mlp.json", "`0_weights` has 3 rows", "11×16"]);
    let t = written();
    let p = t.path().join("mlp.json");
    edit(&p, |s| s.replacen("[[0.0,", "[[1e39,", 1));
    load_err(t.path(), &["mlp.json", "does not fit an f32"]);
    // Finite but absurd weights: the fixed-point shader cannot hold them.
    let t = written();
    let p = t.path().join("mlp.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["0_weights"] = serde_json::to_value([[3.0e37f64; 16]; 11]).unwrap();
    v["1_weights"] = serde_json::to_value([[3.0e37f64; 16]; 16]).unwrap();
    std::fs::write(&p, v.to_string()).unwrap();
    load_err(t.path(), &["mlp.json", "not representable"]);
    let t = written();
    std::fs::write(t.path().join("mlp.json"), "{\"0_weights\": [").unwrap();
    load_err(t.path(), &["mlp.json", "invalid JSON", "line 1"]);
    let t = written();
    std::fs::remove_file(t.path().join("mlp.json")).unwrap();
    load_err(t.path(), &["mlp.json"]);
}

#[test]
fn missing_shapes_are_listed_and_no_shapes_is_an_error() {
    let t = written();
    let a = Asset::load(t.path()).unwrap();
    assert_eq!(a.missing_shapes(), vec![0]);
    std::fs::remove_file(t.path().join("shape1.obj")).unwrap();
    load_err(t.path(), &["no shape files", "obj_num = 2"]);
}
