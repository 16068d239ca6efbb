//! The printable deck pattern end to end: its SVG rasterised by a renderer nobody here wrote
//! (resvg) and measured back with deckwatch's detector; its pages put together against the
//! single sheet; `pattern check` on a simulated photograph of the deck and on photographs of
//! the rasterised sheet (true, and printed 3 % too wide); the `deckwatch pattern` command.

use deckwatch_common::{CameraModel, DeckLayout, GrayImage, MarkerSet, Rpy, SceneGeometry, Viewpoint};
use deckwatch_detect::{Detector, DetectorConfig};
use deckwatch_estimate::pattern_check::{check_pattern, PatternCheck, PatternCheckConfig, Quantity};
use deckwatch_formats::deck_pattern::{PatternDrawing, TileOptions, TiledPattern};
use deckwatch_formats::recording::{encode_gray_png, write_camera_json};
use deckwatch_sim::{RenderOptions, Renderer};
use deckwatch_tests::workspace_binary;
use nalgebra::Vector3;
use resvg::{tiny_skia, usvg};
use std::path::Path;
use std::process::Command;

/// CSS pixels per millimetre: an SVG length in mm is this many of resvg's user pixels.
const CSS_PX_PER_MM: f64 = 96.0 / 25.4;

/// Renders the region (x, y, width, height; mm) of an SVG document at `px_per_mm`, as grey.
fn rasterise(svg: &str, px_per_mm: f64, [x0, y0, w, h]: [f64; 4]) -> GrayImage {
    let tree = usvg::Tree::from_str(svg, &usvg::Options::default()).expect("resvg reads the SVG");
    let (width, height) = ((w * px_per_mm).round() as u32, (h * px_per_mm).round() as u32);
    let mut pixmap = tiny_skia::Pixmap::new(width, height).unwrap();
    pixmap.fill(tiny_skia::Color::WHITE);
    let k = px_per_mm / CSS_PX_PER_MM;
    let transform = tiny_skia::Transform::from_row(
        k as f32,
        0.0,
        0.0,
        k as f32,
        (-x0 * px_per_mm) as f32,
        (-y0 * px_per_mm) as f32,
    );
    resvg::render(&tree, transform, &mut pixmap.as_mut());
    let mut image = GrayImage::new(width as usize, height as usize);
    for (out, p) in image.data.iter_mut().zip(pixmap.data().chunks_exact(4)) {
        // Opaque (a white sheet under everything): premultiplied is plain.
        *out = deckwatch_common::image::luma_bt601(p[0], p[1], p[2]);
    }
    image
}

/// The detector as `deckwatch pattern check` sets it up: any disc from 3 px to a third of the
/// image.
fn detect(image: &GrayImage, camera: &CameraModel, layout: &DeckLayout) -> MarkerSet {
    let mut config = DetectorConfig::for_camera(camera, layout);
    config.min_radius_px = 3.0;
    config.max_radius_px = image.width.min(image.height) as f64 / 3.0;
    Detector::new(*camera, *layout, config).detect_full(image.view())
}

fn worst_error_pct(check: &PatternCheck) -> (Quantity, f64) {
    check
        .dimensions
        .iter()
        .filter_map(|d| Some((d.quantity, d.error_pct()?)))
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap()
}

/// The sheet rendered by resvg at 1.5 px/mm (5.7 MP) and measured back by the detector: the
/// ring's radius and every disc's diameter within 0.1 % of the layout.
#[test]
fn the_svg_pattern_measured_back() {
    let layout = DeckLayout::paper();
    let drawing = PatternDrawing::new(&layout).unwrap();
    let svg = drawing.svg();
    let tree = usvg::Tree::from_str(&svg, &usvg::Options::default()).unwrap();
    // resvg takes the document for what its width and height say, in millimetres.
    assert!((f64::from(tree.size().width()) / CSS_PX_PER_MM - drawing.width_mm).abs() < 1e-2);
    assert!((f64::from(tree.size().height()) / CSS_PX_PER_MM - drawing.height_mm).abs() < 1e-2);
    let px_per_mm = 1.5;
    let image = rasterise(&svg, px_per_mm, [0.0, 0.0, drawing.width_mm, drawing.height_mm]);
    let camera = CameraModel::centred(image.width as u32, image.height as u32, 1000.0, 1000.0);
    let set = detect(&image, &camera, &layout);
    assert_eq!(set.count, 9, "{set:?}");
    let centre = set.pixel(0).unwrap();
    // Pixel centres are at integers: a sheet point at x mm is at x s - 0.5.
    let [cx, cy] = drawing.centre_mm.map(|v| v * px_per_mm - 0.5);
    assert!(
        (centre[0] - cx).abs() < 0.2 && (centre[1] - cy).abs() < 0.2,
        "{centre:?}"
    );
    let mut worst = 0.0f64;
    let mut ring_sum = 0.0;
    for i in 1..=8 {
        let p = set.pixel(i).unwrap();
        let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
        let radius_mm = dx.hypot(dy) / px_per_mm;
        ring_sum += radius_mm;
        let e = 100.0 * (radius_mm / 500.0 - 1.0);
        worst = worst.max(e.abs());
        assert!(
            e.abs() < 0.1,
            "marker {i} at {radius_mm} mm from the centre: {e} %"
        );
        // Counter-clockwise from the bow on the right, the sheet's y pointing down.
        let angle = (-dy).atan2(dx).to_degrees();
        let expected = 45.0 * (i - 1) as f64;
        let off = (angle - expected + 540.0).rem_euclid(360.0) - 180.0;
        assert!(off.abs() < 0.05, "marker {i} at {angle} deg");
    }
    let ring_error = 100.0 * (ring_sum / 8.0 / 500.0 - 1.0);
    assert!(ring_error.abs() < 0.1, "ring radius {ring_error} %");
    let mut worst_disc = 0.0f64;
    for i in 0..9 {
        let diameter_mm = 2.0 * (set.markers[i].area_px / std::f64::consts::PI).sqrt() / px_per_mm;
        let e = 100.0 * (diameter_mm / (2e3 * layout.disc_radius(i)) - 1.0);
        worst_disc = worst_disc.max(e.abs());
        // What resvg drew: its coverage summed around the disc. Its discs are polygons a
        // little inside the circle (-0.07 % at 75 px, -0.005 % at 120): the detector's area is
        // that coverage.
        let (u, v) = (set.markers[i].u, set.markers[i].v);
        let r_px = 1e3 * layout.disc_radius(i) * px_per_mm;
        let mut coverage = 0.0;
        for y in (v - r_px - 4.0) as usize..(v + r_px + 5.0) as usize {
            for x in (u - r_px - 4.0) as usize..(u + r_px + 5.0) as usize {
                coverage += f64::from(image.data[y * image.width + x]) / 255.0;
            }
        }
        let drawn = 100.0 * ((coverage / std::f64::consts::PI).sqrt() / r_px - 1.0);
        assert!(
            (e - drawn).abs() < 0.005,
            "disc {i}: measured {e} %, drawn {drawn} %"
        );
        assert!(e.abs() < 0.1, "disc {i}: {diameter_mm} mm, {e} %");
    }
    eprintln!(
        "measured back at {px_per_mm} px/mm: ring radius {ring_error:+.4} %, worst marker distance {worst:.4} %, worst disc diameter {worst_disc:.4} %"
    );
}

/// Every page's part that no neighbour overlaps (where no cut line or cross is drawn) is the
/// single sheet's at the same place: the pages put together make the sheet. resvg covers a
/// pixel in four sub-rows, and an edge that falls on a sub-row's boundary may round either way
/// on the page (a moved, clipped group) and on the sheet: edge pixels differ by up to a quarter
/// of full scale (64 DN); a part moved by a pixel or missing would differ by far more, and on
/// many more pixels.
#[test]
fn the_pages_put_together_are_the_sheet() {
    let drawing = PatternDrawing::new(&DeckLayout::paper()).unwrap();
    let options = TileOptions::default();
    let tiled = TiledPattern::new(&drawing, &options).unwrap();
    // 1 px/mm: every page's region starts on a whole millimetre, so pixels line up.
    let sheet = rasterise(
        &drawing.svg(),
        1.0,
        [0.0, 0.0, drawing.width_mm, drawing.height_mm],
    );
    let (m, o) = (options.margin_mm as usize, options.overlap_mm as usize);
    let (mut compared, mut dark, mut differing, mut largest) = (0usize, 0usize, 0usize, 0u8);
    for tile in &tiled.tiles {
        let [pw, ph] = tiled.page_mm;
        let page = rasterise(&tile.svg, 1.0, [0.0, 0.0, pw, ph]);
        let [x0, y0, w, h] = tile.region_mm.map(|v| v as usize);
        for y in o + 1..h - o - 1 {
            for x in o + 1..w - o - 1 {
                let (sx, sy) = (x0 + x, y0 + y);
                if sx >= sheet.width || sy >= sheet.height {
                    continue;
                }
                let a = page.data[(m + y) * page.width + m + x];
                let b = sheet.data[sy * sheet.width + sx];
                compared += 1;
                dark += usize::from(b < 128);
                differing += usize::from(a.abs_diff(b) > 2);
                largest = largest.max(a.abs_diff(b));
            }
        }
    }
    eprintln!(
        "pages against the sheet: {compared} pixels, {differing} differ by more than 2 DN, at most {largest}"
    );
    // Most of the sheet, and the black field with it.
    assert!(compared as f64 > 0.6 * sheet.data.len() as f64, "{compared}");
    assert!(dark as f64 > 0.4 * compared as f64, "{dark}");
    assert!(
        (differing as f64) < 1e-3 * compared as f64,
        "{differing} of {compared}"
    );
    assert!(largest <= 64, "{largest} DN");
}

/// A photograph the simulator renders of the deck (the paper's layout, true to size) from an
/// oblique viewpoint, with its blur, noise, vignetting and uneven light: `pattern check` finds it
/// within 0.5 % in every dimension, with and without the camera's distance.
#[test]
fn pattern_check_on_a_simulated_photograph_within_half_a_percent() {
    let camera = CameraModel::rpi_v2().scaled_to(1640, 1232);
    let layout = DeckLayout::paper();
    let scene = SceneGeometry {
        attitude: Rpy::from_degrees(8.0, -12.0, 30.0).to_matrix(),
        viewpoint: Viewpoint::level(0.6, -0.4, 2.2)
            .with_vehicle_attitude(Rpy::from_degrees(-8.0, 10.0, 0.0).to_matrix()),
    };
    assert!(scene
        .project_markers(&camera, &layout)
        .iter()
        .all(Option::is_some));
    let mut renderer = Renderer::new(camera, layout, RenderOptions::realistic(), 7).unwrap();
    let mut photo = GrayImage::new(1640, 1232);
    renderer.render(&[scene], 11, &mut photo.view_mut()).unwrap();
    let set = detect(&photo, &camera, &layout);
    assert_eq!(set.count, 9);
    let distance = scene.deck_to_camera(&Vector3::zeros()).norm();
    for distance_m in [None, Some(distance)] {
        let check = check_pattern(&set, &camera, &layout, &PatternCheckConfig { distance_m }).unwrap();
        let (quantity, e) = worst_error_pct(&check);
        eprintln!(
            "simulated photograph, view tilted {:.1} deg, distance {}: worst error {e:+.3} % ({quantity:?}); aspect {:+.3} %",
            check.view_tilt_deg,
            distance_m.map_or("not given".into(), |d| format!("{d:.3} m")),
            check.get(Quantity::Aspect).unwrap().error_pct().unwrap()
        );
        assert!(e.abs() < 0.5, "{quantity:?}: {e} %");
        assert!(check.view_tilt_deg > 15.0, "{}", check.view_tilt_deg);
    }
    // The command on the same photograph: within the default 0.5 %, exit status 0.
    let dir = tempfile::tempdir().unwrap();
    let photo_path = dir.path().join("photo.png");
    encode_gray_png(&photo_path, photo.view()).unwrap();
    write_camera_json(dir.path(), &camera, &layout).unwrap();
    let out = pattern_check(&photo_path, &dir.path().join("camera.json"), &[]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(text(&out).contains("result: all"), "{}", text(&out));
}

/// A photograph of the rasterised sheet printed through `print` (a linear map of the sheet, mm
/// to mm about the deck's centre): the field rasterised at 1.5 px/mm, seen through a pinhole
/// camera from an oblique viewpoint, 3 x 3 samples a pixel.
fn photograph_of_the_sheet(drawing: &PatternDrawing, stretch_x: f64, camera: &CameraModel) -> GrayImage {
    let px_per_mm = 1.5;
    let field = drawing.field_mm();
    let texture = rasterise(&drawing.svg(), px_per_mm, field);
    let scene = SceneGeometry {
        attitude: Rpy::from_degrees(0.0, 0.0, 20.0).to_matrix(),
        viewpoint: Viewpoint::level(0.7, 0.3, 2.4)
            .with_vehicle_attitude(Rpy::from_degrees(8.0, 26.0, 0.0).to_matrix()),
    };
    let r_cw = scene.viewpoint.camera_from_world();
    let (a, c) = (scene.attitude, scene.viewpoint.position());
    let sample = |u: f64, v: f64| -> f64 {
        let ray =
            r_cw.transpose() * Vector3::new((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
        // The ray meets the deck plane (deck z = 0) at P = A^T (C + s ray).
        let (c_deck, ray_deck) = (a.transpose() * c, a.transpose() * ray);
        let s = -c_deck.z / ray_deck.z;
        let p = c_deck + s * ray_deck;
        // The printed sheet is the drawing stretched along the deck's x about its centre.
        let [x, y] = drawing.deck_to_sheet_mm([p.x / stretch_x, p.y]);
        let (tx, ty) = ((x - field[0]) * px_per_mm - 0.5, (y - field[1]) * px_per_mm - 0.5);
        if !(tx >= 0.0 && ty >= 0.0 && tx < (texture.width - 1) as f64 && ty < (texture.height - 1) as f64) {
            return 120.0; // the table around the sheet
        }
        let (ix, iy) = (tx as usize, ty as usize);
        let (fx, fy) = (tx - ix as f64, ty - iy as f64);
        let at = |x: usize, y: usize| f64::from(texture.data[y * texture.width + x]);
        (1.0 - fy) * ((1.0 - fx) * at(ix, iy) + fx * at(ix + 1, iy))
            + fy * ((1.0 - fx) * at(ix, iy + 1) + fx * at(ix + 1, iy + 1))
    };
    let mut photo = GrayImage::new(camera.width as usize, camera.height as usize);
    for v in 0..photo.height {
        for u in 0..photo.width {
            let mut sum = 0.0;
            for k in 0..9 {
                let (du, dv) = ((k % 3) as f64 / 3.0 - 1.0 / 3.0, (k / 3) as f64 / 3.0 - 1.0 / 3.0);
                sum += sample(u as f64 + du, v as f64 + dv);
            }
            // A printed black is not black, nor paper white: 20 to 225.
            photo.data[v * photo.width + u] = (20.0 + sum / 9.0 * (205.0 / 255.0)).round() as u8;
        }
    }
    photo
}

/// The sheet photographed as printed (within 0.5 %) and printed 3 % too wide (flagged: the
/// aspect, and the markers' distances along x, by the library and by the command's exit
/// status).
#[test]
fn pattern_check_flags_a_print_3_percent_too_wide() {
    let layout = DeckLayout::paper();
    let drawing = PatternDrawing::new(&layout).unwrap();
    let camera = CameraModel::centred(1640, 1232, 1350.0, 1350.0);
    let dir = tempfile::tempdir().unwrap();
    write_camera_json(dir.path(), &camera, &layout).unwrap();
    for (stretch_x, name) in [(1.0, "true.png"), (1.03, "wide.png")] {
        let photo = photograph_of_the_sheet(&drawing, stretch_x, &camera);
        let set = detect(&photo, &camera, &layout);
        assert_eq!(set.count, 9, "{name}");
        let check = check_pattern(&set, &camera, &layout, &PatternCheckConfig::default()).unwrap();
        let aspect = check.get(Quantity::Aspect).unwrap().error_pct().unwrap();
        let (quantity, e) = worst_error_pct(&check);
        eprintln!(
            "photograph of the sheet stretched {stretch_x} in x, view tilted {:.1} deg: aspect {aspect:+.3} % along {:.1} deg, worst {e:+.3} % ({quantity:?})",
            check.view_tilt_deg, check.aspect_axis_deg
        );
        let path = dir.path().join(name);
        encode_gray_png(&path, photo.view()).unwrap();
        let out = pattern_check(&path, &dir.path().join("camera.json"), &[]);
        if stretch_x == 1.0 {
            assert!(e.abs() < 0.5, "{quantity:?}: {e} %");
            assert!(out.status.success(), "{}", text(&out));
        } else {
            assert!((aspect - 3.0).abs() < 0.3, "aspect {aspect} %");
            assert!(check.aspect_axis_deg.abs() < 3.0, "{}", check.aspect_axis_deg);
            let off: Vec<Quantity> = check.off(0.5).map(|d| d.quantity).collect();
            assert!(
                off.contains(&Quantity::Aspect) && off.contains(&Quantity::MarkerDistance(1)),
                "{off:?}"
            );
            assert_eq!(out.status.code(), Some(1), "{}", text(&out));
            let table = text(&out);
            let row = table.lines().find(|l| l.starts_with("aspect")).unwrap();
            assert!(row.contains("OFF"), "{row}");
        }
    }
}

fn pattern_check(photo: &Path, camera: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(workspace_binary("deckwatch"))
        .args(["pattern", "check"])
        .arg(photo)
        .arg("--camera")
        .arg(camera)
        .args(extra)
        .output()
        .expect("deckwatch runs")
}

fn text(out: &std::process::Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// `deckwatch pattern --out deck.svg --tile A4` with a configuration whose deck is a
/// recording's: the sheet at true scale of that deck, the pages and the overview, all read by
/// resvg, the pages A4.
#[test]
fn the_command_writes_the_configured_deck_and_its_pages() {
    let dir = tempfile::tempdir().unwrap();
    let layout = DeckLayout {
        ring_radius_m: 0.3,
        marker_radius_m: 0.03,
        bow_marker_radius_m: 0.05,
        n_ring: 8,
    };
    let recording = dir.path().join("recording");
    std::fs::create_dir(&recording).unwrap();
    write_camera_json(&recording, &CameraModel::rpi_v2(), &layout).unwrap();
    let config = dir.path().join("pipeline.toml");
    std::fs::write(
        &config,
        format!(
            "[source]\nkind = \"replay\"\n[replay]\nrecording = \"{}\"\n",
            recording.display()
        ),
    )
    .unwrap();
    let out_svg = dir.path().join("deck.svg");
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["pattern", "--tile", "A4", "--out"])
        .arg(&out_svg)
        .arg("--config")
        .arg(&config)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let sheet = std::fs::read_to_string(&out_svg).unwrap();
    let expected = PatternDrawing::new(&layout).unwrap();
    assert_eq!(sheet, expected.svg(), "the configured deck's sheet");
    let tree = usvg::Tree::from_str(&sheet, &usvg::Options::default()).unwrap();
    assert!((f64::from(tree.size().width()) / CSS_PX_PER_MM - expected.width_mm).abs() < 1e-2);
    let tiled = TiledPattern::new(&expected, &TileOptions::default()).unwrap();
    for tile in &tiled.tiles {
        let page =
            std::fs::read_to_string(dir.path().join(format!("deck-r{}c{}.svg", tile.row, tile.col))).unwrap();
        let tree = usvg::Tree::from_str(&page, &usvg::Options::default()).unwrap();
        let size =
            [tree.size().width(), tree.size().height()].map(|v| (f64::from(v) / CSS_PX_PER_MM).round());
        assert!(size == [210.0, 297.0] || size == [297.0, 210.0], "{size:?}");
    }
    let overview = std::fs::read_to_string(dir.path().join("deck-overview.svg")).unwrap();
    usvg::Tree::from_str(&overview, &usvg::Options::default()).unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(&format!("{} pages of A4", tiled.tiles.len())),
        "{stdout}"
    );
    // No page beyond the grid.
    let pages = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with("deck-r")
        })
        .count();
    assert_eq!(pages, tiled.rows * tiled.cols);
    // Bad page settings are named.
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["pattern", "--tile", "A4", "--margin-mm", "2", "--out"])
        .arg(&out_svg)
        .output()
        .unwrap();
    assert!(
        !out.status.success() && text(&out).contains("--margin-mm"),
        "{}",
        text(&out)
    );
}
