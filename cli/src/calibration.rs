//! `deckwatch calibration import FILE --out camera.json`: a calibration written by ROS, OpenCV
//! or Kalibr, converted by `formats::calibration` and written as camera.json by the recording
//! format's own writer, with a summary of what was imported.

use deckwatch_common::DeckLayout;
use deckwatch_formats::calibration::{
    import_calibration_file, ImportOptions, ImportedCalibration, MAX_EQUIDISTANT_DIFFERENCE_PX,
};
use deckwatch_formats::recording::{read_camera_json, write_camera_json, CAMERA_FILE};
use std::path::{Path, PathBuf};

#[derive(clap::Subcommand)]
pub enum CalibrationCommand {
    /// Convert a calibration into camera.json: ROS camera_calibration's camera_info YAML,
    /// OpenCV FileStorage (YAML or XML) or a Kalibr camchain (the format is recognised from the
    /// content). Refuses what deckwatch's pinhole + Brown-Conrady camera cannot represent:
    /// nonzero rational k4..k6, thin-prism or tilt terms, skew, a stereo rectification, and an
    /// equidistant (fisheye) lens whose Brown-Conrady fit is off by more than 0.01 px.
    Import(ImportArgs),
}

#[derive(clap::Args)]
pub struct ImportArgs {
    /// The calibration file (at most 1 MiB).
    file: PathBuf,
    /// Where to write: a path ending in camera.json, or a folder to write camera.json in.
    #[arg(long)]
    out: PathBuf,
    /// The camera to take from a file with several (Kalibr's cam0, cam1, ...).
    #[arg(long)]
    camera: Option<String>,
    /// The image size in px, for a file without one (OpenCV files need not have
    /// image_width/image_height); when the file has one, they must agree.
    #[arg(long, value_name = "WxH", value_parser = parse_image_size)]
    image_size: Option<(u32, u32)>,
    /// Rolling shutter: the time to read the rows out, top to bottom (ms; 0 = a global
    /// shutter), written as camera.json's readout_ms.
    #[arg(long, default_value_t = 0.0)]
    readout_ms: f64,
    /// Take the deck (camera.json's `deck`) from this camera.json or recording folder instead
    /// of the paper's deck.
    #[arg(long, value_name = "CAMERA_JSON")]
    deck_from: Option<PathBuf>,
    /// Replace an existing camera.json.
    #[arg(long)]
    force: bool,
}

/// `640x480` as (640, 480).
fn parse_image_size(text: &str) -> Result<(u32, u32), String> {
    let parsed = text
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)));
    parsed.ok_or_else(|| format!("expected WIDTHxHEIGHT in px, e.g. 1640x1232, got `{text}`"))
}

/// The folder whose camera.json `path` names: the folder itself (existing, or new when the
/// name has no extension), or the parent of a path ending in camera.json (the only name the
/// readers look for).
fn camera_json_folder(path: &Path, option: &str) -> Result<PathBuf, String> {
    if path.is_dir() || (!path.exists() && path.extension().is_none()) {
        Ok(path.to_path_buf())
    } else if path.file_name().is_some_and(|n| n == CAMERA_FILE) {
        Ok(match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        })
    } else {
        Err(format!(
            "{option} {}: give a path ending in {CAMERA_FILE} or a folder",
            path.display()
        ))
    }
}

pub fn run(command: CalibrationCommand) -> Result<(), String> {
    let CalibrationCommand::Import(a) = command;
    let options = ImportOptions {
        camera: a.camera.clone(),
        image_size_px: a.image_size,
        readout_s: a.readout_ms / 1e3,
    };
    let imported = import_calibration_file(&a.file, &options).map_err(|e| e.to_string())?;
    let (deck, deck_source) = match &a.deck_from {
        Some(path) => {
            let dir = camera_json_folder(path, "--deck-from")?;
            let (_, deck) = read_camera_json(&dir).map_err(|e| e.to_string())?;
            (deck, format!("from {}", dir.join(CAMERA_FILE).display()))
        }
        None => (
            DeckLayout::paper(),
            "the paper's; --deck-from takes another".to_string(),
        ),
    };
    let out_dir = camera_json_folder(&a.out, "--out")?;
    let out_file = out_dir.join(CAMERA_FILE);
    if out_file.exists() && !a.force {
        return Err(format!("{} exists: --force replaces it", out_file.display()));
    }
    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: cannot create: {e}", out_dir.display()))?;
    print_summary(&a.file, &imported);
    write_camera_json(&out_dir, &imported.camera, &deck).map_err(|e| e.to_string())?;
    outln!("wrote {} (deck: {deck_source})", out_file.display());
    Ok(())
}

fn print_summary(file: &Path, imported: &ImportedCalibration) {
    let c = &imported.camera;
    let name = imported
        .camera_name
        .as_ref()
        .map_or(String::new(), |n| format!(", camera `{n}`"));
    outln!("imported {} ({}{name})", file.display(), imported.format.name());
    outln!(
        "  model: pinhole; lens `{}` -> Brown-Conrady [k1, k2, p1, p2, k3]",
        imported.distortion_model
    );
    outln!("  image: {}x{} px", c.width, c.height);
    outln!(
        "  fx {:?}  fy {:?}  cx {:?}  cy {:?} (px)",
        c.fx,
        c.fy,
        c.cx,
        c.cy
    );
    outln!("  distortion: {:?}", c.distortion.to_array());
    if let Some(fit) = &imported.equidistant_fit {
        outln!(
            "  equidistant k1..k4 {:?} fitted: max difference {:.4} px over the image (limit \
             {MAX_EQUIDISTANT_DIFFERENCE_PX} px; {:.1} deg off axis at the corners; {} pixels checked)",
            fit.fisheye_coefficients,
            fit.max_difference_px,
            fit.max_field_angle_deg,
            fit.checked_pixels
        );
    }
    if c.readout_s > 0.0 {
        outln!("  readout: {} ms (rolling shutter)", c.readout_s * 1e3);
    } else {
        outln!("  readout: 0 ms (a global shutter; --readout-ms sets a rolling shutter's)");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_sizes_parse() {
        assert_eq!(parse_image_size("1640x1232"), Ok((1640, 1232)));
        assert_eq!(parse_image_size("640X480"), Ok((640, 480)));
        for bad in ["640", "640x", "x480", "-640x480", "640x480x3"] {
            assert!(
                parse_image_size(bad).unwrap_err().contains("WIDTHxHEIGHT"),
                "{bad}"
            );
        }
    }

    #[test]
    fn out_names_camera_json_or_a_folder() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(camera_json_folder(dir.path(), "--out").unwrap(), dir.path());
        assert_eq!(
            camera_json_folder(Path::new("calib/camera.json"), "--out").unwrap(),
            Path::new("calib")
        );
        assert_eq!(
            camera_json_folder(Path::new("camera.json"), "--out").unwrap(),
            Path::new(".")
        );
        assert_eq!(
            camera_json_folder(Path::new("calib/new"), "--out").unwrap(),
            Path::new("calib/new")
        );
        let e = camera_json_folder(Path::new("calib/cam.json"), "--out").unwrap_err();
        assert!(e.contains("ending in camera.json"), "{e}");
    }
}
