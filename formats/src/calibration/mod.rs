//! Importing a camera calibration another tool wrote, as deckwatch's [`CameraModel`] (pinhole
//! with Brown-Conrady `[k1, k2, p1, p2, k3]`, OpenCV's convention):
//! - ROS `camera_calibration`'s camera_info YAML (`ros`): plumb_bob, rational_polynomial,
//!   equidistant; the rectification matrix must be the identity (a monocular camera);
//! - OpenCV FileStorage, YAML (`%YAML:1.0`, `!!opencv-matrix`) or XML (`<opencv_storage>`)
//!   (`opencv`): `camera_matrix`, `distortion_coefficients`, `image_width`, `image_height`;
//! - Kalibr camchain YAML (`kalibr`): a pinhole camera, radtan, equidistant or none.
//!
//! What deckwatch cannot represent is refused, never approximated silently: OpenCV's rational,
//! thin-prism and tilt terms unless zero, skew, stereo rectification, and an equidistant fisheye
//! whose best Brown-Conrady fit is off by more than [`MAX_EQUIDISTANT_DIFFERENCE_PX`] somewhere
//! on the image (`lens`). Pure: no printing; every error names the file, and where known the
//! line and the key.

mod kalibr;
mod lens;
mod node;
mod opencv;
mod ros;
mod xml;
mod yaml;

pub use lens::{EquidistantFit, MAX_EQUIDISTANT_DIFFERENCE_PX};

use deckwatch_common::camera::check_image_size;
use deckwatch_common::CameraModel;
use lens::{fit_equidistant, opencv_distortion, Lens, Pinhole};
use node::{FileContext, Matrix, Node, Value};
use std::fmt;
use std::path::{Path, PathBuf};

/// The largest calibration file read (bytes): the biggest of these formats is a few kB (an
/// OpenCV file with per-view extrinsics of a hundred views, ~30 kB).
pub const MAX_CALIBRATION_FILE_BYTES: u64 = 1 << 20;

/// The formats read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibrationFormat {
    RosCameraInfo,
    OpenCvYaml,
    OpenCvXml,
    KalibrCamchain,
}

impl CalibrationFormat {
    /// The format's name for people.
    pub fn name(self) -> &'static str {
        match self {
            Self::RosCameraInfo => "ROS camera_info YAML",
            Self::OpenCvYaml => "OpenCV FileStorage YAML",
            Self::OpenCvXml => "OpenCV FileStorage XML",
            Self::KalibrCamchain => "Kalibr camchain YAML",
        }
    }
}

/// What the caller adds to the file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImportOptions {
    /// The camera to take from a file with several (Kalibr's `cam0`, ...); a ROS file's
    /// `camera_name` must match it when given.
    pub camera: Option<String>,
    /// The image size (px) for a file without one (OpenCV files need not have it); when the
    /// file has one, they must agree.
    pub image_size_px: Option<(u32, u32)>,
    /// Rolling-shutter readout (s) for the camera model; 0 = a global shutter.
    pub readout_s: f64,
}

/// A calibration read and converted.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedCalibration {
    /// The camera, validated.
    pub camera: CameraModel,
    pub format: CalibrationFormat,
    /// The camera's name in the file (ROS `camera_name`, Kalibr's key), if it has one.
    pub camera_name: Option<String>,
    /// The file's lens model as the file names it (`plumb_bob`, `radtan`, `equidistant`, ...).
    pub distortion_model: String,
    /// For an equidistant lens: how closely the Brown-Conrady lens stands in for it.
    pub equidistant_fit: Option<EquidistantFit>,
}

/// What was wrong with a calibration file.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationProblem {
    #[error("cannot read: {0}")]
    Read(String),
    #[error("{bytes} bytes: a calibration file may have at most {max_bytes}")]
    TooLarge { bytes: u64, max_bytes: u64 },
    #[error("not UTF-8 text")]
    NotUtf8,
    #[error("{0}")]
    Syntax(String),
    #[error(
        "not a calibration this importer reads: expected a ROS camera_info YAML (camera_matrix, \
         distortion_model), an OpenCV FileStorage YAML or XML (camera_matrix and \
         distortion_coefficients as opencv-matrix) or a Kalibr camchain YAML (cam0: intrinsics)"
    )]
    UnknownFormat,
    #[error("missing")]
    MissingKey,
    #[error("expected {expected}, found {found}")]
    WrongType { expected: &'static str, found: String },
    #[error("expected {expected}, found {found}")]
    WrongShape { expected: String, found: String },
    #[error("`{text}` is not a finite number")]
    NotFinite { text: String },
    #[error("unsupported model `{model}`: deckwatch imports {supported}")]
    UnsupportedModel { model: String, supported: &'static str },
    #[error("{0}")]
    NotRepresentable(String),
    #[error(
        "the image reaches 90 deg or more off the optical axis: a wide fisheye, which deckwatch's \
         pinhole + Brown-Conrady camera cannot represent"
    )]
    EquidistantTooWide,
    #[error(
        "the best Brown-Conrady fit to this equidistant (fisheye) lens is off by up to \
         {max_difference_px:.3} px on the image, more than the {limit_px} px accepted: the image \
         reaches {max_field_angle_deg:.1} deg off axis, a fisheye too wide for deckwatch's pinhole + \
         Brown-Conrady camera to represent"
    )]
    EquidistantDoesNotFit {
        max_difference_px: f64,
        limit_px: f64,
        max_field_angle_deg: f64,
    },
    #[error("{0}")]
    Numerical(String),
    #[error("the file has no image size (image_width, image_height): give it with --image-size WxH")]
    ImageSizeMissing,
    #[error("the file's image is {file_width}x{file_height}, the given size {given_width}x{given_height}")]
    ImageSizeDisagrees {
        file_width: u32,
        file_height: u32,
        given_width: u32,
        given_height: u32,
    },
    #[error("the focal lengths must be positive, got fx {fx} px, fy {fy} px")]
    FocalNotPositive { fx: f64, fy: f64 },
    #[error(
        "the principal point ({cx}, {cy}) px is outside the {width}x{height} image (a calibration \
         for another size or a cropped image?)"
    )]
    PrincipalPointOutside {
        cx: f64,
        cy: f64,
        width: u32,
        height: u32,
    },
    #[error("{0}")]
    Invalid(String),
    #[error("no camera `{wanted}` in the file; it has {available}")]
    CameraNotFound { wanted: String, available: String },
    #[error("the file holds several cameras ({available}): choose one with --camera NAME")]
    CameraNeeded { available: String },
}

/// A calibration file's problem, located: `path[:line][: key `k`]: problem`.
#[derive(Debug)]
pub struct CalibrationError {
    pub path: PathBuf,
    /// 1-based line, where known.
    pub line: Option<usize>,
    /// The key (`camera_matrix.data[4]`, `cam0.intrinsics`), where one applies.
    pub key: Option<String>,
    pub problem: CalibrationProblem,
}

impl fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(key) = &self.key {
            write!(f, ": key `{key}`")?;
        }
        write!(f, ": {}", self.problem)
    }
}

impl std::error::Error for CalibrationError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.problem)
    }
}

/// A value with the key and line it came from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Located<T> {
    pub value: T,
    pub key: String,
    pub line: usize,
}

/// What a format's reader found, before the lens is mapped and the camera checked.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Parsed {
    pub format: CalibrationFormat,
    pub camera_name: Option<String>,
    pub image_size: Option<Located<(u32, u32)>>,
    /// `[fx, fy, cx, cy]` (px).
    pub intrinsics: Located<[f64; 4]>,
    pub distortion_model: String,
    pub lens: Located<Lens>,
}

/// Reads and converts a calibration file (at most [`MAX_CALIBRATION_FILE_BYTES`]); the format
/// is recognised from the content.
pub fn import_calibration_file(
    path: &Path,
    options: &ImportOptions,
) -> Result<ImportedCalibration, CalibrationError> {
    use deckwatch_common::files::{read_bounded_to_string, FileReadError};
    let ctx = FileContext { path };
    let text = read_bounded_to_string(path, MAX_CALIBRATION_FILE_BYTES).map_err(|e| match e {
        FileReadError::TooLarge {
            size_bytes,
            max_bytes,
            ..
        } => ctx.error(
            None,
            "",
            CalibrationProblem::TooLarge {
                bytes: size_bytes,
                max_bytes,
            },
        ),
        FileReadError::NotUtf8 { line, .. } => {
            ctx.error(Some(line as usize), "", CalibrationProblem::NotUtf8)
        }
        other => ctx.error(
            other.line().map(|l| l as usize),
            "",
            CalibrationProblem::Read(other.problem()),
        ),
    })?;
    import_calibration_text(path, &text, options)
}

/// Converts a calibration file's text; `path` names it in errors.
pub fn import_calibration_text(
    path: &Path,
    text: &str,
    options: &ImportOptions,
) -> Result<ImportedCalibration, CalibrationError> {
    let ctx = FileContext { path };
    if text.len() as u64 > MAX_CALIBRATION_FILE_BYTES {
        return Err(ctx.error(
            None,
            "",
            CalibrationProblem::TooLarge {
                bytes: text.len() as u64,
                max_bytes: MAX_CALIBRATION_FILE_BYTES,
            },
        ));
    }
    let parsed = if text.trim_start_matches('\u{feff}').trim_start().starts_with('<') {
        let root = xml::parse(text)
            .map_err(|e| ctx.error(Some(e.line), "", CalibrationProblem::Syntax(e.message)))?;
        opencv::parse(&ctx, &root, CalibrationFormat::OpenCvXml, options)?
    } else {
        let root = yaml::parse(text)
            .map_err(|e| ctx.error(Some(e.line), "", CalibrationProblem::Syntax(e.message)))?;
        match yaml_format(text, &root) {
            Some(CalibrationFormat::KalibrCamchain) => kalibr::parse(&ctx, &root, options)?,
            Some(CalibrationFormat::RosCameraInfo) => ros::parse(&ctx, &root, options)?,
            Some(format) => opencv::parse(&ctx, &root, format, options)?,
            None => return Err(ctx.error(None, "", CalibrationProblem::UnknownFormat)),
        }
    };
    finish(&ctx, parsed, options)
}

/// Which tool wrote a YAML file: Kalibr's cameras are mappings with `camera_model` or
/// `intrinsics`; OpenCV tags its matrices (and starts with `%YAML`); ROS has keys of its own.
fn yaml_format(text: &str, root: &Node) -> Option<CalibrationFormat> {
    let Value::Map(entries) = &root.value else {
        return None;
    };
    if entries.iter().any(|(_, n)| kalibr::is_camera(n)) {
        return Some(CalibrationFormat::KalibrCamchain);
    }
    let has = |keys: &[&str]| keys.iter().any(|k| root.get(k).is_some());
    let ros_only = has(&[
        "distortion_model",
        "camera_name",
        "rectification_matrix",
        "projection_matrix",
    ]);
    let tagged = entries
        .iter()
        .any(|(_, n)| n.tag.as_deref() == Some("opencv-matrix"));
    let opencv_header = text.trim_start_matches('\u{feff}').starts_with("%YAML");
    if tagged || (opencv_header && !ros_only) {
        Some(CalibrationFormat::OpenCvYaml)
    } else if ros_only || has(&["camera_matrix", "distortion_coefficients"]) {
        Some(CalibrationFormat::RosCameraInfo)
    } else {
        None
    }
}

/// `[fx, fy, cx, cy]` of a 3x3 camera matrix `[fx s cx; 0 fy cy; 0 0 1]`; refuses skew.
pub(crate) fn camera_matrix_intrinsics(
    ctx: &FileContext,
    k: &Matrix,
    key: &str,
) -> Result<Located<[f64; 4]>, CalibrationError> {
    let fail = |problem| ctx.error(Some(k.line), key, problem);
    if (k.rows, k.cols) != (3, 3) {
        return Err(fail(CalibrationProblem::WrongShape {
            expected: "a 3x3 matrix".into(),
            found: k.shape(),
        }));
    }
    let v = &k.values;
    if v[3] != 0.0 || v[6] != 0.0 || v[7] != 0.0 || (v[8] - 1.0).abs() > 1e-9 {
        return Err(fail(CalibrationProblem::NotRepresentable(format!(
            "not a camera matrix [fx 0 cx; 0 fy cy; 0 0 1]: its lower rows are [{}, {}, {}; {}, {}, {}]",
            v[3], v[4], v[5], v[6], v[7], v[8]
        ))));
    }
    // OpenCV's calibrations fix the skew at 0 unless told otherwise.
    if v[1].abs() > 1e-9 * v[0].abs().max(1.0) {
        return Err(fail(CalibrationProblem::NotRepresentable(format!(
            "skew {} px (row 1, column 2): deckwatch's camera has perpendicular pixel axes",
            v[1]
        ))));
    }
    Ok(Located {
        value: [v[0], v[4], v[2], v[5]],
        key: key.into(),
        line: k.line,
    })
}

/// The image size, the intrinsics' checks, the lens mapped (fitted), the camera validated.
fn finish(
    ctx: &FileContext,
    parsed: Parsed,
    options: &ImportOptions,
) -> Result<ImportedCalibration, CalibrationError> {
    let (size_key, size_line) = parsed
        .image_size
        .as_ref()
        .map_or((String::new(), None), |s| (s.key.clone(), Some(s.line)));
    let (width, height) = match (&parsed.image_size, options.image_size_px) {
        (Some(file), None) => file.value,
        (None, Some(given)) => given,
        (Some(file), Some(given)) if file.value == given => given,
        (Some(file), Some((given_width, given_height))) => {
            return Err(ctx.error(
                size_line,
                &size_key,
                CalibrationProblem::ImageSizeDisagrees {
                    file_width: file.value.0,
                    file_height: file.value.1,
                    given_width,
                    given_height,
                },
            ))
        }
        (None, None) => return Err(ctx.error(None, "", CalibrationProblem::ImageSizeMissing)),
    };
    check_image_size(width, height)
        .map_err(|m| ctx.error(size_line, &size_key, CalibrationProblem::Invalid(m)))?;
    let intrinsics = &parsed.intrinsics;
    let at_intrinsics = |problem| ctx.error(Some(intrinsics.line), &intrinsics.key, problem);
    let [fx, fy, cx, cy] = intrinsics.value;
    if !(fx > 0.0 && fy > 0.0) {
        return Err(at_intrinsics(CalibrationProblem::FocalNotPositive { fx, fy }));
    }
    // Pixel centres at integers: the image spans -0.5 ..= size - 0.5.
    let inside = |c: f64, size: u32| (-0.5..=f64::from(size) - 0.5).contains(&c);
    if !(inside(cx, width) && inside(cy, height)) {
        return Err(at_intrinsics(CalibrationProblem::PrincipalPointOutside {
            cx,
            cy,
            width,
            height,
        }));
    }
    let pinhole = Pinhole {
        width,
        height,
        fx,
        fy,
        cx,
        cy,
    };
    let lens = &parsed.lens;
    let (distortion, equidistant_fit) = match &lens.value {
        Lens::OpenCv(c) => opencv_distortion(c).map(|d| (d, None)),
        Lens::Equidistant(k) => fit_equidistant(&pinhole, *k).map(|(d, fit)| (d, Some(fit))),
    }
    .map_err(|p| ctx.error(Some(lens.line), &lens.key, p))?;
    let camera = CameraModel {
        width,
        height,
        fx,
        fy,
        cx,
        cy,
        distortion,
        readout_s: options.readout_s,
    };
    camera.validate().map_err(|e| {
        let (line, key) = match e.field.as_str() {
            "width" | "height" => (size_line, size_key.as_str()),
            "readout_s" => (None, ""),
            f if f.starts_with("distortion") => (Some(lens.line), lens.key.as_str()),
            _ => (Some(intrinsics.line), intrinsics.key.as_str()),
        };
        ctx.error(line, key, CalibrationProblem::Invalid(e.to_string()))
    })?;
    Ok(ImportedCalibration {
        camera,
        format: parsed.format,
        camera_name: parsed.camera_name,
        distortion_model: parsed.distortion_model,
        equidistant_fit,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Imports text named `name`, with an image size when given.
    pub(crate) fn import_text(
        name: &str,
        text: &str,
        image_size_px: Option<(u32, u32)>,
    ) -> Result<ImportedCalibration, CalibrationError> {
        let options = ImportOptions {
            image_size_px,
            ..ImportOptions::default()
        };
        import_calibration_text(Path::new(name), text, &options)
    }

    /// Imports the camera `camera` of text named `name`.
    pub(crate) fn import_text_camera(
        name: &str,
        text: &str,
        camera: &str,
    ) -> Result<ImportedCalibration, CalibrationError> {
        let options = ImportOptions {
            camera: Some(camera.into()),
            ..ImportOptions::default()
        };
        import_calibration_text(Path::new(name), text, &options)
    }

    #[test]
    fn files_are_bounded_and_must_be_text() {
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.yaml");
        std::fs::write(&big, vec![b'#'; MAX_CALIBRATION_FILE_BYTES as usize + 1]).unwrap();
        let e = import_calibration_file(&big, &ImportOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with("big.yaml: 1048577 bytes: a calibration file may have at most 1048576"),
            "{e}"
        );
        let binary = dir.path().join("bin.yaml");
        std::fs::write(&binary, b"image_width: 640\n\xff\xfe\n").unwrap();
        let e = import_calibration_file(&binary, &ImportOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.ends_with("bin.yaml:2: not UTF-8 text"), "{e}");
        let e = import_calibration_file(&dir.path().join("none.yaml"), &ImportOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.yaml: cannot read"), "{e}");
    }

    #[test]
    fn unknown_files_say_what_is_read() {
        for text in ["name: deck\nsize: 3\n", "- 1\n- 2\n"] {
            let e = import_text("x.yaml", text, None).unwrap_err().to_string();
            assert!(
                e.starts_with("x.yaml: not a calibration this importer reads"),
                "{e}"
            );
        }
    }

    #[test]
    fn the_readout_is_checked_with_the_camera() {
        let text = "cam0:\n  camera_model: pinhole\n  intrinsics: [500, 500, 320, 240]\n  \
                    distortion_model: none\n  distortion_coeffs: []\n  resolution: [640, 480]\n";
        let options = ImportOptions {
            readout_s: 0.02,
            ..ImportOptions::default()
        };
        let c = import_calibration_text(Path::new("k.yaml"), text, &options).unwrap();
        assert_eq!((c.camera.readout_s, c.camera.distortion.is_none()), (0.02, true));
        let options = ImportOptions {
            readout_s: 5.0,
            ..ImportOptions::default()
        };
        let e = import_calibration_text(Path::new("k.yaml"), text, &options)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("k.yaml: field `readout_s`: must be within"), "{e}");
    }
}
