//! Scratch (development only, not committed): a throwaway preview renderer.
use glam::Vec3;
use nerflex_sim::bake::*;
use nerflex_sim::camera::{Camera, Transforms};

fn load(split: &str, n: usize) -> (Vec<Camera>, Vec<image::RgbaImage>) {
    let dir = std::path::Path::new("/work/shared/data/nerf_synthetic")
        .join(std::env::var("OBJ").unwrap_or("lego".into()));
    let t = Transforms::read(&dir.join(format!("transforms_{split}.json"))).unwrap();
    let mut imgs = vec![];
    let mut cams = vec![];
    for i in 0..n.min(t.frames.len()) {
        let img = image::open(dir.join(format!("{}.png", t.frames[i].file_path)))
            .unwrap()
            .to_rgba8();
        cams.push(t.camera(i, img.width(), img.height()).unwrap());
        imgs.push(img);
    }
    (cams, imgs)
}

fn preview(obj: &BakedObject, cam: &Camera) -> image::RgbaImage {
    let (w, h) = (
        cam.intrinsics.width as usize,
        cam.intrinsics.height as usize,
    );
    let mut z = vec![f32::INFINITY; w * h];
    let mut col = vec![[255u8; 3]; w * h];
    let p = obj.params.patch as f32;
    let w2c = cam.w2c();
    let k = cam.intrinsics;
    for (qi, q) in obj.quads.iter().enumerate() {
        let cell = obj.atlas.layout.cell(qi).unwrap();
        let page = &obj.atlas.pages[cell.page];
        let cs = q.corners();
        let st = [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)];
        let mut s = [(0f32, 0f32, 0f32); 4];
        for i in 0..4 {
            let c = w2c.transform_point3(cs[i]);
            let d = -c.z;
            s[i] = (k.cx + k.fx * c.x / d, k.cy - k.fy * c.y / d, d);
        }
        for tri in [[0, 1, 3], [0, 3, 2]] {
            let (a, b, c) = (s[tri[0]], s[tri[1]], s[tri[2]]);
            let area = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
            if area.abs() < 1e-12 {
                continue;
            }
            let minx = a.0.min(b.0).min(c.0).floor().max(0.0) as usize;
            let miny = a.1.min(b.1).min(c.1).floor().max(0.0) as usize;
            let maxx = (a.0.max(b.0).max(c.0).ceil().max(0.0) as usize).min(w);
            let maxy = (a.1.max(b.1).max(c.1).ceil().max(0.0) as usize).min(h);
            for y in miny..maxy {
                for x in minx..maxx {
                    let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                    let wa = ((b.0 - px) * (c.1 - py) - (b.1 - py) * (c.0 - px)) / area;
                    let wb = ((c.0 - px) * (a.1 - py) - (c.1 - py) * (a.0 - px)) / area;
                    let wc = 1.0 - wa - wb;
                    if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                        continue;
                    }
                    let iz = wa / a.2 + wb / b.2 + wc / c.2;
                    let d = 1.0 / iz;
                    if d >= z[y * w + x] {
                        continue;
                    }
                    let ss = (wa * st[tri[0]].0 / a.2
                        + wb * st[tri[1]].0 / b.2
                        + wc * st[tri[2]].0 / c.2)
                        * d;
                    let tt = (wa * st[tri[0]].1 / a.2
                        + wb * st[tri[1]].1 / b.2
                        + wc * st[tri[2]].1 / c.2)
                        * d;
                    let tx = (ss * (p - 1.0) + 0.5).floor().clamp(0.0, p - 1.0) as u32;
                    let ty = (tt * (p - 1.0) + 0.5).floor().clamp(0.0, p - 1.0) as u32;
                    let f0 = page.feat0.get_pixel(cell.x + tx, cell.y + ty).0;
                    if f0[0] == 0 {
                        continue;
                    }
                    z[y * w + x] = d;
                    col[y * w + x] =
                        mlp_fit::shade_reference(&obj.mlp, f0, [0; 4], [0.0, 0.0, 1.0]);
                }
            }
        }
    }
    image::RgbaImage::from_fn(w as u32, h as u32, |x, y| {
        let c = col[y as usize * w + x as usize];
        image::Rgba([c[0], c[1], c[2], 255])
    })
}

fn over_white(img: &image::RgbaImage) -> image::RgbaImage {
    image::RgbaImage::from_fn(img.width(), img.height(), |x, y| {
        let p = img.get_pixel(x, y).0;
        let a = p[3] as f32 / 255.0;
        image::Rgba(
            [0, 1, 2]
                .map(|c| (p[c] as f32 * a + 255.0 * (1.0 - a)).round() as u8)
                .into_iter()
                .chain([255])
                .collect::<Vec<_>>()
                .try_into()
                .unwrap(),
        )
    })
}

fn psnr(a: &image::RgbaImage, b: &image::RgbaImage) -> f64 {
    let mut se = 0f64;
    let mut n = 0f64;
    for (p, q) in a.pixels().zip(b.pixels()) {
        for c in 0..3 {
            let d = p.0[c] as f64 - q.0[c] as f64;
            se += d * d;
            n += 1.0;
        }
    }
    10.0 * (255.0f64 * 255.0 / (se / n)).log10()
}

fn ssim(a: &image::RgbaImage, b: &image::RgbaImage) -> f64 {
    let (w, h) = (a.width() as usize, a.height() as usize);
    let g: Vec<f64> = (0..11)
        .map(|i| {
            let x = i as f64 - 5.0;
            (-x * x / (2.0 * 1.5 * 1.5)).exp()
        })
        .collect();
    let gs: f64 = g.iter().sum();
    let g: Vec<f64> = g.iter().map(|v| v / gs).collect();
    let blur = |img: &Vec<f64>| -> Vec<f64> {
        let mut t = vec![0.0; w * h];
        let mut o = vec![0.0; (w - 10) * (h - 10)];
        for y in 0..h {
            for x in 0..w - 10 {
                t[y * w + x] = (0..11).map(|k| g[k] * img[y * w + x + k]).sum();
            }
        }
        for y in 0..h - 10 {
            for x in 0..w - 10 {
                o[y * (w - 10) + x] = (0..11).map(|k| g[k] * t[(y + k) * w + x]).sum();
            }
        }
        o
    };
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    let mut tot = 0.0;
    for c in 0..3 {
        let x: Vec<f64> = a.pixels().map(|p| p.0[c] as f64).collect();
        let y: Vec<f64> = b.pixels().map(|p| p.0[c] as f64).collect();
        let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
        let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
        let xy: Vec<f64> = x.iter().zip(&y).map(|(a, b)| a * b).collect();
        let (mx, my, sxx, syy, sxy) = (blur(&x), blur(&y), blur(&xx), blur(&yy), blur(&xy));
        let mut s = 0.0;
        for i in 0..mx.len() {
            let (vx, vy, cxy) = (
                sxx[i] - mx[i] * mx[i],
                syy[i] - my[i] * my[i],
                sxy[i] - mx[i] * my[i],
            );
            s += ((2.0 * mx[i] * my[i] + c1) * (2.0 * cxy + c2))
                / ((mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2));
        }
        tot += s / mx.len() as f64;
    }
    tot / 3.0
}

#[test]
fn scratch() {
    let (cams, imgs) = load("train", 20);
    let (tcams, timgs) = load("test", 5);
    let views: Vec<BakeView> = cams
        .iter()
        .zip(&imgs)
        .map(|(c, i)| BakeView {
            camera: *c,
            image: i,
            silhouette: Silhouette::Alpha,
        })
        .collect();
    let configs: Vec<(u32, u32)> = std::env::var("GP")
        .unwrap_or("16:5,64:9,128:17".into())
        .split(',')
        .map(|s| {
            let v: Vec<u32> = s.split(':').map(|x| x.parse().unwrap()).collect();
            (v[0], v[1])
        })
        .collect();
    let lp = if std::env::var("LP").is_ok() {
        Some(
            nerflex_sim::metrics::Lpips::load(nerflex_sim::metrics::Lpips::default_path().unwrap())
                .unwrap(),
        )
    } else {
        None
    };
    for (g, p) in configs {
        let mut bp = BakeParams::new(g, p);
        if std::env::var("BOUNDARY").is_ok() {
            bp.geometry = Geometry::Boundary;
        }
        if let Ok(v) = std::env::var("FP") {
            bp.frontal_power = v.parse().unwrap();
        }
        let obj = bake(&views, &bp).unwrap();
        let mut ps = vec![];
        let mut ss = vec![];
        let mut ls = vec![];
        for (i, (c, gt)) in tcams.iter().zip(&timgs).enumerate() {
            let r = preview(&obj, c);
            let gtw = over_white(gt);
            let sc = nerflex_sim::metrics::Metrics::compare(&r, gt, lp.as_ref()).unwrap();
            ps.push(sc.psnr);
            ss.push(sc.ssim);
            ls.push(sc.lpips.unwrap_or(0.0));
            if i == 0 {
                r.save(format!("/tmp/bk/prev_{g}_{p}.png")).unwrap();
                gtw.save("/tmp/bk/gt0.png").unwrap();
                let d = image::RgbaImage::from_fn(r.width(), r.height(), |x, y| {
                    let a = r.get_pixel(x, y).0;
                    let b = gtw.get_pixel(x, y).0;
                    let rm = a[0] < 250 || a[1] < 250 || a[2] < 250;
                    let gm = gt.get_pixel(x, y).0[3] > 127;
                    image::Rgba([
                        if rm && !gm { 255 } else { 0 },
                        if gm && !rm { 255 } else { 0 },
                        (0..3)
                            .map(|c| (a[c] as i32 - b[c] as i32).unsigned_abs())
                            .max()
                            .unwrap()
                            .min(255) as u8,
                        255,
                    ])
                });
                d.save(format!("/tmp/bk/diff_{g}_{p}.png")).unwrap();
            }
        }
        println!(
            "g {g} p {p} quads {} psnr {:.2} ssim {:.4} lpips {:.4} {:?}",
            obj.quads.len(),
            ps.iter().sum::<f64>() / 5.0,
            ss.iter().sum::<f64>() / 5.0,
            ls.iter().sum::<f64>() / 5.0,
            ps.iter().map(|v| format!("{v:.2}")).collect::<Vec<_>>()
        );
    }
    let _ = Vec3::ZERO;
}
