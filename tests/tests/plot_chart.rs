//! Charts: picture size, data landing where the axes say, legend, bars, files.

use nerflex_sim::plot::{
    BarChart, Chart, LegendPosition, Pixmap, PlotError, Rgb, Scale, Series, PALETTE,
};
use std::path::PathBuf;

fn rgb_at(p: &Pixmap, x: f32, y: f32) -> Rgb {
    let c = p
        .pixel(x.round() as u32, y.round() as u32)
        .expect("inside the picture");
    // Charts are opaque, so premultiplied = straight colour.
    assert_eq!(c.alpha(), 255);
    Rgb(c.red(), c.green(), c.blue())
}

/// Where example pictures go: `$NERFLEX_PLOT_DIR` if set (to look at them),
/// else a temporary folder.
fn out_dir() -> (PathBuf, Option<tempfile::TempDir>) {
    match std::env::var_os("NERFLEX_PLOT_DIR") {
        Some(d) => {
            std::fs::create_dir_all(&d).unwrap();
            (PathBuf::from(d), None)
        }
        None => {
            let t = tempfile::tempdir().unwrap();
            (t.path().to_owned(), Some(t))
        }
    }
}

fn ssim_chart() -> Chart {
    let g = [16.0, 32.0, 64.0, 128.0, 256.0, 512.0];
    let measured = [0.712, 0.781, 0.842, 0.889, 0.907, 0.915];
    let fit = |g: f64| 0.925 - 0.21 * (24.0 / g).powf(0.9);
    Chart::new("lego: SSIM vs grid size")
        .x_label("grid g (log scale)")
        .y_label("SSIM")
        .x_log2()
        .series(Series::scatter(
            "measured, p = 17",
            g.iter().copied().zip(measured),
        ))
        .series(Series::line(
            "fit Q(g)",
            (0..=60)
                .map(|i| 16.0 * 2f64.powf(i as f64 / 12.0))
                .map(|x| (x, fit(x))),
        ))
        .series(
            Series::horizontal("MobileNeRF (0.907)", 0.907)
                .dashed()
                .color(Rgb(0x88, 0x88, 0x88)),
        )
}

#[test]
fn line_chart_pixels_land_where_the_axes_say() {
    let chart = ssim_chart();
    let (w, h) = (800, 500);
    let pix = chart.render(w, h).unwrap();
    assert_eq!((pix.width(), pix.height()), (w, h));
    let layout = chart.layout(w, h).unwrap();
    assert!(
        layout.left > 0.0
            && layout.right < w as f32
            && layout.top > 0.0
            && layout.bottom < h as f32
    );

    // Ticks at the powers of two, equally spaced.
    let labels: Vec<&str> = layout.x_ticks().iter().map(|(_, s)| s.as_str()).collect();
    assert_eq!(labels, ["16", "32", "64", "128", "256", "512"]);
    // Every measured point: its marker centre has the series colour.
    for (g, q) in [(16.0, 0.712), (128.0, 0.889), (512.0, 0.915)] {
        let (px, py) = layout.to_pixel(g, q).unwrap();
        assert!(px > layout.left && px < layout.right && py > layout.top && py < layout.bottom);
        assert_eq!(rgb_at(&pix, px, py), PALETTE[0], "marker at g = {g}");
    }
    // Doubling g moves the same distance on the log axis.
    let x = |g| layout.to_pixel(g, 0.8).unwrap().0;
    assert!(((x(32.0) - x(16.0)) - (x(512.0) - x(256.0))).abs() < 0.01);
    // The fitted line passes through its own values.
    let (px, py) = layout
        .to_pixel(90.0, 0.925 - 0.21 * (24.0f64 / 90.0).powf(0.9))
        .unwrap();
    assert_eq!(rgb_at(&pix, px, py), PALETTE[1]);
    // Higher SSIM is higher in the picture.
    assert!(layout.to_pixel(64.0, 0.9).unwrap().1 < layout.to_pixel(64.0, 0.8).unwrap().1);
    // Outside the plot area the background is white.
    assert_eq!(rgb_at(&pix, 2.0, 2.0), Rgb::WHITE);
}

#[test]
fn dashed_average_has_gaps_and_legend_avoids_data() {
    // Per-frame FPS with a dashed average line.
    let fps: Vec<(f64, f64)> = (0..120)
        .map(|i| (i as f64, 55.0 + 5.0 * ((i as f64) / 9.0).sin()))
        .collect();
    let avg = fps.iter().map(|p| p.1).sum::<f64>() / fps.len() as f64;
    let chart = Chart::new("Pixel 4: FPS per frame")
        .x_label("frame")
        .y_label("FPS")
        .y_range(0.0, 70.0)
        .series(Series::line("FPS", fps))
        .series(
            Series::horizontal(format!("average {avg:.1}"), avg)
                .dashed()
                .color(Rgb::BLACK),
        )
        .legend(LegendPosition::BottomRight);
    let pix = chart.render(640, 400).unwrap();
    let layout = chart.layout(640, 400).unwrap();
    let y = layout.to_pixel(0.0, avg).unwrap().1;
    // Along the dashed line some pixels are dark and some are not.
    let row: Vec<Rgb> = (layout.left as u32 + 4..layout.right as u32 - 4)
        .map(|x| rgb_at(&pix, x as f32, y))
        .collect();
    let dark = row
        .iter()
        .filter(|c| c.0 < 100 && c.1 < 100 && c.2 < 100)
        .count();
    assert!(
        dark > row.len() / 4 && dark < row.len() * 9 / 10,
        "dashed: {dark} of {}",
        row.len()
    );
    // A fixed y range puts 0 on the bottom edge.
    assert!((layout.to_pixel(0.0, 0.0).unwrap().1 - layout.bottom).abs() < 0.01);
    assert_eq!(layout.y_ticks().first().map(|t| t.1.as_str()), Some("0"));
}

#[test]
fn grouped_bars_have_the_right_heights() {
    let chart = BarChart::new("SSIM by scene")
        .categories(["scene 1", "scene 2", "scene 3"])
        .series("NeRFlex", [0.91, 0.88, 0.90])
        .series("MobileNeRF", [0.80, f64::NAN, 0.85])
        .series("uniform", [0.70, 0.72, 0.74])
        .y_label("SSIM")
        .value_labels(true);
    let (w, h) = (720, 420);
    let pix = chart.render(w, h).unwrap();
    let layout = chart.layout(w, h).unwrap();
    let base = layout.y_pixel(0.0).unwrap();
    assert!((base - layout.bottom).abs() < 0.01, "bars start at 0");
    for (s, c, v) in [(0, 0, 0.91), (1, 2, 0.85), (2, 1, 0.72)] {
        let (x0, x1) = layout.bar_columns(s, c).unwrap();
        let top = layout.y_pixel(v).unwrap();
        let cx = (x0 + x1) / 2.0;
        assert_eq!(
            rgb_at(&pix, cx, top + 3.0),
            PALETTE[s],
            "inside bar ({s}, {c})"
        );
        assert_eq!(rgb_at(&pix, cx, (top + base) / 2.0), PALETTE[s]);
        assert_ne!(
            rgb_at(&pix, cx, top - 8.0),
            PALETTE[s],
            "above bar ({s}, {c})"
        );
    }
    // The missing bar is not drawn.
    let (x0, x1) = layout.bar_columns(1, 1).unwrap();
    assert_ne!(rgb_at(&pix, (x0 + x1) / 2.0, base - 5.0), PALETTE[1]);
    // Bars of one group sit side by side, groups in order.
    assert!(layout.bar_columns(0, 0).unwrap().1 <= layout.bar_columns(1, 0).unwrap().0 + 0.01);
    assert!(layout.bar_columns(2, 0).unwrap().1 < layout.bar_columns(0, 1).unwrap().0);
    assert_eq!(layout.bar_columns(3, 0), None);
}

#[test]
fn saves_png_and_names_the_file_on_error() {
    let (dir, _keep) = out_dir();
    let path = dir.join("ssim_vs_g.png");
    ssim_chart().save(&path).unwrap();
    let back = Pixmap::load_png(&path).unwrap();
    assert_eq!(
        (back.width(), back.height()),
        nerflex_sim::plot::DEFAULT_SIZE
    );
    assert!(!dir.join("ssim_vs_g.png.tmp").exists());

    let bars = BarChart::new("Evaluation: SSIM per scene and method")
        .categories(["scene1", "scene2", "scene3", "scene4", "lego+chair"])
        .series("NeRFlex", [0.912, 0.897, 0.905, 0.889, 0.874])
        .series("MobileNeRF", [0.915, 0.901, f64::NAN, f64::NAN, 0.880])
        .series("uniform g", [0.861, 0.842, 0.851, 0.830, 0.812])
        .y_label("SSIM")
        .x_label("scene")
        .value_labels(true)
        .size(900, 480);
    bars.save(&dir.join("bars.png")).unwrap();

    let fps: Vec<(f64, f64)> = (0..300)
        .map(|i| {
            (
                i as f64,
                48.0 + 6.0 * ((i as f64) / 17.0).sin() + if i % 41 == 0 { -12.0 } else { 0.0 },
            )
        })
        .collect();
    let avg = fps.iter().map(|p| p.1).sum::<f64>() / fps.len() as f64;
    Chart::new("Pixel 4, scene4: FPS over a turntable")
        .x_label("frame")
        .y_label("FPS")
        .series(Series::line("NeRFlex", fps).width(1.5))
        .series(Series::horizontal(format!("average {avg:.1} FPS"), avg).dashed())
        .size(800, 400)
        .save(&dir.join("fps.png"))
        .unwrap();

    let size = Chart::new("chair: data size vs grid")
        .x_label("grid g")
        .y_label("size (bytes)")
        .x_scale(Scale::Log2)
        .y_scale(Scale::Log10)
        .series(Series::line_points(
            "p = 5",
            [
                (16.0, 2.1e5),
                (32.0, 8.0e5),
                (64.0, 3.1e6),
                (128.0, 1.2e7),
                (256.0, 4.9e7),
            ],
        ))
        .series(Series::line_points(
            "p = 17",
            [
                (16.0, 1.9e6),
                (32.0, 7.7e6),
                (64.0, 3.0e7),
                (128.0, 1.2e8),
                (256.0, 4.8e8),
            ],
        ))
        .size(600, 420);
    size.save(&dir.join("size_vs_g.png")).unwrap();

    let missing = dir.join("no/such/folder/chart.png");
    let err = ssim_chart().save(&missing).unwrap_err();
    assert!(matches!(err, PlotError::Write { .. }));
    assert!(err.to_string().contains("chart.png"), "{err}");
    assert!(matches!(
        ssim_chart().render(0, 10),
        Err(PlotError::InvalidSize { .. })
    ));
}

#[test]
fn empty_and_awkward_data_do_not_panic() {
    let charts = [
        Chart::new(""),
        Chart::new("one point").series(Series::scatter("p", [(3.0, 3.0)])),
        Chart::new("log with zero and NaN")
            .x_log2()
            .series(Series::line(
                "s",
                [(0.0, 1.0), (4.0, f64::NAN), (8.0, 2.0), (16.0, 3.0)],
            )),
        Chart::new("reversed range")
            .x_range(10.0, 0.0)
            .series(Series::line("s", [(1.0, 1.0), (2.0, 5.0)])),
        Chart::new("only a horizontal line").series(Series::horizontal("h", 2.0)),
        Chart::new("negative").series(Series::line("s", [(-5.0, -1e-4), (5.0, 3e-4)])),
    ];
    for c in &charts {
        let p = c.render(300, 200).unwrap();
        assert_eq!((p.width(), p.height()), (300, 200));
    }
    let b = BarChart::new("no data").render(300, 200).unwrap();
    assert_eq!(b.width(), 300);
    let neg = BarChart::new("negative")
        .categories(["a", "b"])
        .series("s", [-1.0, 2.0]);
    let layout = neg.layout(400, 300).unwrap();
    assert!(
        layout.y_pixel(0.0).unwrap() < layout.bottom,
        "0 is inside when values go negative"
    );
    neg.render(400, 300).unwrap();
}
