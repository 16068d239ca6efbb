//! `deckwatch pattern --out deck.svg`: the configured deck's marker pattern as SVG at true
//! scale, for printing or painting, optionally cut into pages (`--tile A4`); and
//! `deckwatch pattern check PHOTO --camera camera.json`: a photograph of the printed or painted
//! pattern measured against the configuration (exit status 1 when a dimension is off).
//!
//! The drawing is `formats::deck_pattern`'s, the detection `detect::Detector`'s, the
//! measurement `estimate::pattern_check`'s; this file reads and writes the files and prints.

use clap::{Args, Subcommand, ValueEnum};
use deckwatch_common::messages::FrameSource;
use deckwatch_common::{CameraModel, DeckLayout, DetectionStatus, GrayImage};
use deckwatch_detect::{Detector, DetectorConfig};
use deckwatch_estimate::pattern_check::{
    check_pattern, Basis, Dimension, PatternCheck, PatternCheckConfig, Quantity,
};
use deckwatch_formats::deck_pattern::{Paper, PatternDrawing, PatternError, TileOptions, TiledPattern};
use std::path::{Path, PathBuf};

/// The smallest disc radius the check looks for (px): a photograph may show the pattern small.
const MIN_DISC_RADIUS_PX: f64 = 3.0;

#[derive(Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct PatternArgs {
    #[command(subcommand)]
    command: Option<PatternCommand>,
    /// The SVG to write: the whole pattern on one sheet at true scale. With `--tile`, the pages
    /// go beside it as STEM-r{row}c{col}.svg, with STEM-overview.svg.
    #[arg(long, value_name = "FILE.svg")]
    out: Option<PathBuf>,
    /// Pipeline configuration whose deck layout to draw: the simulator's, a replayed
    /// recording's camera.json or the camera's calibration (`[libcamera] calibration`);
    /// without one, the defaults' (the paper's deck).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Also cut the pattern into pages of this paper (portrait, or landscape when fewer).
    #[arg(long, value_enum, ignore_case = true, default_value_t = TileArg::None)]
    tile: TileArg,
    /// Blank margin round each page (mm): printers do not print to the edge.
    #[arg(long, default_value_t = TileOptions::default().margin_mm)]
    margin_mm: f64,
    /// How far neighbouring pages show the same part of the pattern (mm).
    #[arg(long, default_value_t = TileOptions::default().overlap_mm)]
    overlap_mm: f64,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum TileArg {
    #[value(name = "A4")]
    A4,
    #[value(name = "A3")]
    A3,
    #[value(name = "none")]
    None,
}

#[derive(Subcommand)]
enum PatternCommand {
    /// Measure a photograph of the printed or painted pattern against the configured layout:
    /// the ring's radius, each disc's diameter, the ring markers' spacing and the print's
    /// aspect, in mm (or degrees, or ratios) and %. Exit status 1 when one is off by more than
    /// the tolerance.
    Check(CheckArgs),
}

#[derive(Args)]
struct CheckArgs {
    /// The photograph (PNG or JPEG, grey or colour), at the calibration's size.
    photo: PathBuf,
    /// The camera's calibration: a camera.json (the recording format) or a folder holding one.
    #[arg(long, value_name = "camera.json")]
    camera: PathBuf,
    /// Pipeline configuration whose deck layout to check against (as for `pattern --out`).
    #[arg(long)]
    config: Option<PathBuf>,
    /// The distance from the camera's optical centre (a phone: its lens) to the centre
    /// marker's centre, measured with a tape (m): gives sizes in mm. Without it the sizes are
    /// relative to the ring's radius, which one photograph cannot measure.
    #[arg(long)]
    distance_m: Option<f64>,
    /// A dimension off by more than this fails the check (%).
    #[arg(long, default_value_t = 0.5)]
    tolerance_pct: f64,
}

/// Runs `deckwatch pattern`; false: a dimension of `pattern check` is off.
pub fn run(a: PatternArgs) -> Result<bool, String> {
    match a.command {
        Some(PatternCommand::Check(c)) => check(c),
        None => write_pattern(&a).map(|()| true),
    }
}

fn write_pattern(a: &PatternArgs) -> Result<(), String> {
    let out = a
        .out
        .as_deref()
        .ok_or("--out FILE.svg is required (or `deckwatch pattern check PHOTO`)")?;
    let (layout, source) = configured_layout(a.config.as_deref())?;
    let drawing = PatternDrawing::new(&layout).map_err(|e| e.to_string())?;
    write_file(out, &drawing.svg())?;
    outln!(
        "{}: the deck pattern of {source} at true scale, {:.0} x {:.0} mm (ring radius {} mm, {} ring markers, disc diameter {} mm, bow disc {} mm)",
        out.display(),
        drawing.width_mm,
        drawing.height_mm,
        1e3 * layout.ring_radius_m,
        layout.n_ring,
        2e3 * layout.marker_radius_m,
        2e3 * layout.bow_marker_radius_m,
    );
    let paper = match a.tile {
        TileArg::A4 => Paper::A4,
        TileArg::A3 => Paper::A3,
        TileArg::None => {
            outln!("print at 100 % (actual size) and measure the 100 mm check bar with a ruler");
            return Ok(());
        }
    };
    let options = TileOptions {
        paper,
        margin_mm: a.margin_mm,
        overlap_mm: a.overlap_mm,
    };
    let tiled = TiledPattern::new(&drawing, &options).map_err(|e| match e {
        PatternError::Page { option, problem } => format!("--{}: {problem}", option.replace('_', "-")),
        e => e.to_string(),
    })?;
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "deck".into());
    let dir = out.parent().unwrap_or(Path::new("."));
    for tile in &tiled.tiles {
        write_file(
            &dir.join(format!("{stem}-r{}c{}.svg", tile.row, tile.col)),
            &tile.svg,
        )?;
    }
    write_file(&dir.join(format!("{stem}-overview.svg")), &tiled.overview_svg)?;
    outln!(
        "{} pages of {} {} ({} rows x {} columns, {} mm overlap): {stem}-r1c1.svg ... {stem}-r{}c{}.svg, and {stem}-overview.svg (not to scale)",
        tiled.tiles.len(),
        paper.name(),
        if tiled.landscape { "landscape" } else { "portrait" },
        tiled.rows,
        tiled.cols,
        a.overlap_mm,
        tiled.rows,
        tiled.cols,
    );
    outln!(
        "print each page at 100 % (actual size, no fit to page) and measure its 100 mm bar with a ruler; \
         cut each page on its dashed lines and lay the cut edge on the neighbour's dotted line, the red crosses on each other"
    );
    Ok(())
}

fn write_file(path: &Path, text: &str) -> Result<(), String> {
    std::fs::write(path, text).map_err(|e| format!("{}: cannot write: {e}", path.display()))
}

/// The deck layout the configuration's source uses, and where it comes from.
fn configured_layout(config: Option<&Path>) -> Result<(DeckLayout, String), String> {
    let (c, name) = crate::pipeline::load(config)?;
    match c.source.kind {
        FrameSource::Simulator => {
            let sim = c.sim.resolve().map_err(|e| format!("{name}: [sim] {e}"))?;
            Ok((sim.deck, format!("the simulator (configuration {name})")))
        }
        FrameSource::Replay => {
            let recording = c
                .replay
                .recording
                .as_deref()
                .ok_or(format!("{name}: replay.recording is not set"))?;
            let deck = if recording.is_dir() {
                deckwatch_formats::recording::read_camera_json(recording)
                    .map_err(|e| e.to_string())?
                    .1
            } else {
                let source = c.capture().open().map_err(|e| format!("{name}: {e}"))?;
                *source.deck()
            };
            Ok((deck, format!("the recording {}", recording.display())))
        }
        FrameSource::Libcamera => match c
            .libcamera
            .read_calibration()
            .map_err(|e| format!("{name}: {e}"))?
        {
            Some((_, deck)) => Ok((deck, format!("the camera's calibration (configuration {name})"))),
            None => Ok((
                DeckLayout::paper(),
                format!("the paper's deck (no libcamera.calibration in {name})"),
            )),
        },
    }
}

fn check(a: CheckArgs) -> Result<bool, String> {
    if !(a.tolerance_pct.is_finite() && a.tolerance_pct > 0.0) {
        return Err(format!(
            "--tolerance-pct: must be a positive percentage, got {}",
            a.tolerance_pct
        ));
    }
    let (layout, source) = configured_layout(a.config.as_deref())?;
    let (camera, calibration_deck) = read_calibration(&a.camera)?;
    let photo = read_photo(&a.photo)?;
    let name = a.photo.display();
    let size = (photo.width as u32, photo.height as u32);
    if size != (camera.width, camera.height) {
        let turned = size == (camera.height, camera.width);
        return Err(format!(
            "{name} is {}x{}, the calibration {}x{}{}",
            size.0,
            size.1,
            camera.width,
            camera.height,
            if turned {
                ": turned by 90 degrees (a phone's orientation flag?); save it unrotated"
            } else {
                ": take the photograph with the calibrated camera and mode, uncropped"
            }
        ));
    }
    let mut config = DetectorConfig::for_camera(&camera, &layout);
    // The pattern may be near or far: any disc from a few pixels to a third of the image.
    config.min_radius_px = MIN_DISC_RADIUS_PX;
    config.max_radius_px = (photo.width.min(photo.height) as f64 / 3.0).max(2.0 * MIN_DISC_RADIUS_PX);
    let markers = Detector::new(camera, layout, config).detect_full(photo.view());
    if !matches!(
        markers.status.get(),
        DetectionStatus::Ok | DetectionStatus::Partial
    ) {
        return Err(format!(
            "{name}: no deck pattern found ({} round candidates rejected by size, {} by shape, {} at the border): \
             the black field should fill most of the photograph, evenly lit, every disc whole",
            markers.rejected.area, markers.rejected.shape, markers.rejected.border
        ));
    }
    let check = check_pattern(
        &markers,
        &camera,
        &layout,
        &PatternCheckConfig {
            distance_m: a.distance_m,
        },
    )
    .map_err(|e| format!("{name}: {e}"))?;
    if calibration_deck != layout {
        outln!(
            "note: {} describes another deck (ring radius {} m); checked against {source}",
            a.camera.display(),
            calibration_deck.ring_radius_m
        );
    }
    print_check(&check, &layout, &format!("{name}"), &source, a.tolerance_pct);
    Ok(check.off(a.tolerance_pct).count() == 0)
}

/// A camera.json or a folder holding one (as `[libcamera] calibration`).
fn read_calibration(path: &Path) -> Result<(CameraModel, DeckLayout), String> {
    let file = deckwatch_formats::recording::CAMERA_FILE;
    let dir = if path.is_dir() {
        path.to_path_buf()
    } else if path.file_name().is_some_and(|n| n == file) {
        path.parent().unwrap_or(Path::new(".")).to_path_buf()
    } else {
        return Err(format!(
            "--camera {}: give a {file} (the recording format) or a folder holding one",
            path.display()
        ));
    };
    deckwatch_formats::recording::read_camera_json(&dir).map_err(|e| e.to_string())
}

/// A PNG or JPEG photograph as 8-bit grey (Rec. 601 luma of a colour one).
fn read_photo(path: &Path) -> Result<GrayImage, String> {
    let err = |what: String| format!("{}: {what}", path.display());
    // A photograph of 64 MP (the most `check_image_size` lets through) is under 256 MiB even
    // as an uncompressed PNG; the header's size is checked again before decoding.
    const MAX_PHOTO_BYTES: u64 = 256 << 20;
    let bytes = deckwatch_common::files::read_bounded(path, MAX_PHOTO_BYTES).map_err(|e| e.to_string())?;
    if bytes.starts_with(b"\x89PNG") {
        decode_png(&bytes).map_err(err)
    } else if bytes.starts_with(&[0xff, 0xd8]) {
        decode_jpeg(&bytes).map_err(err)
    } else {
        Err(err("neither a PNG nor a JPEG".into()))
    }
}

/// Grey from packed pixels of `channels` bytes each (grey, grey + alpha, RGB, RGBA).
fn to_grey(pixels: &[u8], channels: usize, width: usize, height: usize) -> Result<GrayImage, String> {
    let mut image = GrayImage::new(width, height);
    if pixels.len() < width * height * channels {
        return Err("truncated pixel data".into());
    }
    for (out, p) in image.data.iter_mut().zip(pixels.chunks_exact(channels)) {
        *out = match channels {
            1 | 2 => p[0],
            _ => deckwatch_common::image::luma_bt601(p[0], p[1], p[2]),
        };
    }
    Ok(image)
}

fn decode_png(bytes: &[u8]) -> Result<GrayImage, String> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder
        .read_info()
        .map_err(|e| format!("not a readable PNG: {e}"))?;
    let (width, height) = (reader.info().width, reader.info().height);
    deckwatch_common::camera::check_image_size(width, height)?;
    let mut buf = vec![0; reader.output_buffer_size().ok_or("PNG too large")?];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("corrupt PNG data: {e}"))?;
    let channels = info.color_type.samples();
    to_grey(
        &buf[..info.buffer_size()],
        channels,
        width as usize,
        height as usize,
    )
}

fn decode_jpeg(bytes: &[u8]) -> Result<GrayImage, String> {
    let (width, height, grey) =
        deckwatch_common::jpeg::decode_to_gray(bytes).map_err(|e| format!("JPEG: {e}"))?;
    to_grey(&grey, 1, width as usize, height as usize)
}

/// A dimension's name as the table prints it.
fn quantity_name(quantity: Quantity, layout: &DeckLayout) -> String {
    let marker = |i: usize| format!("{i} ({})", DeckLayout::marker_label(i));
    match quantity {
        Quantity::RingRadius => "ring radius".into(),
        Quantity::MarkerDistance(i) => format!("marker {} to centre", marker(i)),
        Quantity::Spacing(i) => format!("angle marker {i} to {}", layout.ring_index(i)),
        Quantity::DiscDiameter(i) => format!("disc {} diameter", marker(i)),
        Quantity::BowDiscRatio => "bow / other disc diameter".into(),
        Quantity::Aspect => "aspect (larger/smaller scale)".into(),
    }
}

/// A value with its unit: millimetres for lengths, degrees for angles, a bare ratio.
fn value_text(quantity: Quantity, v: f64) -> String {
    match quantity {
        Quantity::RingRadius | Quantity::MarkerDistance(_) | Quantity::DiscDiameter(_) => {
            format!("{:.2} mm", 1e3 * v)
        }
        Quantity::Spacing(_) => format!("{v:.3} deg"),
        Quantity::BowDiscRatio | Quantity::Aspect => format!("{v:.4}"),
    }
}

fn basis_text(d: &Dimension, check: &PatternCheck) -> String {
    match d.basis {
        Basis::Absolute => "from --distance-m".into(),
        Basis::RelativeToRing => "relative to the ring".into(),
        Basis::NeedsDistance => "needs --distance-m (or a ruler on the check bar)".into(),
        Basis::ScaleFree if d.quantity == Quantity::Aspect => {
            format!("larger along {:.1} deg from +x", check.aspect_axis_deg)
        }
        Basis::ScaleFree => "scale-free".into(),
    }
}

fn print_check(check: &PatternCheck, layout: &DeckLayout, photo: &str, source: &str, tolerance_pct: f64) {
    let found = check.found_mask.count_ones();
    outln!(
        "{photo}: {found} of {} markers found; checked against the deck of {source}",
        layout.marker_count()
    );
    outln!(
        "view tilted {:.1} deg from square-on; the camera is {:.3} m from the centre marker if the print is true to size; \
         plane-map residual {:.2} px (rigid pose of the configured deck: {:.2} px)",
        check.view_tilt_deg,
        check.distance_if_true_size_m,
        check.plane_residual_px,
        check.pose.reprojection_rms_px
    );
    match check.scale {
        Some(scale) => outln!(
            "scale from --distance-m: the print is {:.2} % of the configured size",
            100.0 * scale
        ),
        None => outln!(
            "scale: none (no --distance-m): lengths are the print's own proportions, its ring radius taken as configured"
        ),
    }
    outln!();
    outln!(
        "{:<34} {:>14} {:>14} {:>9}  {:<4} basis",
        "dimension",
        "configured",
        "measured",
        "error",
        ""
    );
    for d in &check.dimensions {
        let (measured, error, verdict) = match (d.measured, d.error_pct()) {
            (Some(m), Some(e)) => (
                value_text(d.quantity, m),
                format!("{e:+.2} %"),
                if e.abs() <= tolerance_pct { "ok" } else { "OFF" },
            ),
            _ => ("-".into(), "-".into(), ""),
        };
        outln!(
            "{:<34} {:>14} {:>14} {:>9}  {:<4} {}",
            quantity_name(d.quantity, layout),
            value_text(d.quantity, d.nominal),
            measured,
            error,
            verdict,
            basis_text(d, check)
        );
    }
    outln!();
    let off: Vec<String> = check
        .off(tolerance_pct)
        .map(|d| quantity_name(d.quantity, layout))
        .collect();
    let measured = check.dimensions.iter().filter(|d| d.measured.is_some()).count();
    if off.is_empty() {
        outln!("result: all {measured} measured dimensions within {tolerance_pct} %");
    } else {
        outln!(
            "result: {} of {measured} measured dimensions off by more than {tolerance_pct} %: {}",
            off.len(),
            off.join(", ")
        );
    }
    outln!(
        "note: one photograph cannot tell a print's absolute size from its distance (twice as large twice as far looks the same). \
         Measure the 100 mm check bar with a ruler: a print scaled by the printer scales its bar too, so the photograph cannot check it. \
         --distance-m gives mm as accurate as the tape and the calibration's focal length."
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png_bytes(color: png::ColorType, width: u32, pixels: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let channels = color.samples();
        let height = (pixels.len() / channels) as u32 / width;
        let mut encoder = png::Encoder::new(&mut out, width, height);
        encoder.set_color(color);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.write_header().unwrap().write_image_data(pixels).unwrap();
        out
    }

    /// A colour photograph reads as its luma; grey and grey with alpha as their grey.
    #[test]
    fn colour_and_grey_pngs_read_as_grey() {
        let rgb = png_bytes(
            png::ColorType::Rgb,
            2,
            &[255, 0, 0, 0, 255, 0, 0, 0, 255, 200, 200, 200],
        );
        let image = decode_png(&rgb).unwrap();
        assert_eq!((image.width, image.height), (2, 2));
        assert_eq!(image.data, vec![77, 149, 29, 200]); // Rec. 601: 0.299, 0.587, 0.114
        let rgba = png_bytes(png::ColorType::Rgba, 1, &[10, 20, 30, 255, 255, 255, 255, 0]);
        assert_eq!(
            decode_png(&rgba).unwrap().data,
            vec![deckwatch_common::image::luma_bt601(10, 20, 30), 255]
        );
        let grey = png_bytes(png::ColorType::Grayscale, 3, &[0, 128, 255]);
        assert_eq!(decode_png(&grey).unwrap().data, vec![0, 128, 255]);
        let grey_alpha = png_bytes(png::ColorType::GrayscaleAlpha, 1, &[90, 255]);
        assert_eq!(decode_png(&grey_alpha).unwrap().data, vec![90]);
        assert!(decode_png(b"\x89PNG not really").is_err());
        assert!(decode_jpeg(&[0xff, 0xd8, 0, 0]).is_err());
    }

    #[test]
    fn a_calibration_is_a_camera_json_or_its_folder() {
        let dir = tempfile::tempdir().unwrap();
        deckwatch_formats::recording::write_camera_json(
            dir.path(),
            &CameraModel::rpi_v2(),
            &DeckLayout::paper(),
        )
        .unwrap();
        let (camera, deck) = read_calibration(dir.path()).unwrap();
        assert_eq!(
            (camera, deck),
            read_calibration(&dir.path().join("camera.json")).unwrap()
        );
        assert_eq!(deck, DeckLayout::paper());
        let e = read_calibration(&dir.path().join("other.json")).unwrap_err();
        assert!(e.contains("--camera") && e.contains("camera.json"), "{e}");
    }
}
