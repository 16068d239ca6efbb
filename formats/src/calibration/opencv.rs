//! OpenCV FileStorage (YAML or XML): `camera_matrix` and `distortion_coefficients` as
//! `opencv-matrix` (`rows, cols, dt, data`), the image size from `image_width` and
//! `image_height` as OpenCV's calibration sample writes them, and that sample's `fisheye_model`
//! flag (1: the coefficients are `cv::fisheye`'s four).

use super::lens::Lens;
use super::node::{FileContext, Matrix, Node};
use super::{
    camera_matrix_intrinsics, CalibrationError, CalibrationFormat, CalibrationProblem, ImportOptions,
    Located, Parsed,
};

/// FileStorage's one-channel element types: u c w s i f d, and h (float16) since OpenCV 5.
const ELEMENT_TYPES: [&str; 8] = ["u", "c", "w", "s", "i", "f", "d", "h"];

/// The matrix under `key`, checked to be an `opencv-matrix` of one channel.
fn opencv_matrix(ctx: &FileContext, root: &Node, key: &str) -> Result<Matrix, CalibrationError> {
    let node = ctx.required(root, "", key)?;
    if node.tag.as_deref() != Some("opencv-matrix") {
        return Err(ctx.error(
            Some(node.line),
            key,
            CalibrationProblem::WrongType {
                expected: "an opencv-matrix (`!!opencv-matrix` in YAML, `type_id=\"opencv-matrix\"` in XML)",
                found: node.describe(),
            },
        ));
    }
    let dt_key = format!("{key}.dt");
    let dt_node = ctx.required(node, key, "dt")?;
    let dt = ctx.text(dt_node, &dt_key)?;
    if !ELEMENT_TYPES.contains(&dt) {
        return Err(ctx.error(
            Some(dt_node.line),
            &dt_key,
            CalibrationProblem::WrongType {
                expected: "a one-channel element type (d, f, ...)",
                found: format!("`{dt}`"),
            },
        ));
    }
    ctx.matrix(node, key)
}

pub(crate) fn parse(
    ctx: &FileContext,
    root: &Node,
    format: CalibrationFormat,
    options: &ImportOptions,
) -> Result<Parsed, CalibrationError> {
    if let Some(wanted) = &options.camera {
        return Err(ctx.error(
            None,
            "",
            CalibrationProblem::CameraNotFound {
                wanted: wanted.clone(),
                available: "one unnamed camera".into(),
            },
        ));
    }
    let k = opencv_matrix(ctx, root, "camera_matrix")?;
    let intrinsics = camera_matrix_intrinsics(ctx, &k, "camera_matrix")?;
    let d_key = "distortion_coefficients";
    let d = opencv_matrix(ctx, root, d_key)?;
    if !d.is_vector() {
        return Err(ctx.error(
            Some(d.line),
            d_key,
            CalibrationProblem::WrongShape {
                expected: "one row or one column of coefficients".into(),
                found: d.shape(),
            },
        ));
    }
    let fisheye = match root.get("fisheye_model") {
        Some(n) => ctx.whole_number(n, "fisheye_model")? != 0,
        None => false,
    };
    let (model, lens) = if fisheye {
        let Ok(k) = <[f64; 4]>::try_from(d.values.as_slice()) else {
            return Err(ctx.error(
                Some(d.line),
                d_key,
                CalibrationProblem::WrongShape {
                    expected: "4 coefficients k1..k4 (`fisheye_model: 1`)".into(),
                    found: d.shape(),
                },
            ));
        };
        ("fisheye (equidistant)", Lens::Equidistant(k))
    } else {
        let model = match d.values.len() {
            4 => "k1 k2 p1 p2",
            5 => "k1 k2 p1 p2 k3",
            8 => "rational",
            12 => "rational + thin prism",
            _ => "rational + thin prism + tilted",
        };
        (model, Lens::OpenCv(d.values.clone()))
    };
    let image_size = match (root.get("image_width"), root.get("image_height")) {
        (Some(w), Some(h)) => Some(Located {
            value: (
                ctx.whole_number(w, "image_width")?,
                ctx.whole_number(h, "image_height")?,
            ),
            key: "image_width".into(),
            line: w.line,
        }),
        (None, None) => None,
        (Some(_), None) => return Err(ctx.error(None, "image_height", CalibrationProblem::MissingKey)),
        (None, Some(_)) => return Err(ctx.error(None, "image_width", CalibrationProblem::MissingKey)),
    };
    Ok(Parsed {
        format,
        camera_name: None,
        image_size,
        intrinsics,
        distortion_model: model.into(),
        lens: Located {
            value: lens,
            key: d_key.into(),
            line: d.line,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::super::tests::import_text;
    use super::super::CalibrationFormat;

    /// As OpenCV 4's FileStorage writes it (`%YAML:1.0`, wrapped data, a comment).
    const OPENCV_YAML: &str = "%YAML:1.0
---
calibration_time: \"Tue 03 Jun 2025 10:12:00 AM\"
image_width: 1640
image_height: 1232
flags: 0
fisheye_model: 0
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1.3001428222656250e+03, 0., 8.1947521972656250e+02, 0.,
       1.3007113037109375e+03, 6.1519915771484375e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ 1.9205e-01, -5.2541e-01, 1.2e-04, -3.1e-04,
       4.3119e-01 ]
# the re-projection error
avg_reprojection_error: 3.1e-01
";

    const OPENCV_XML: &str = "<?xml version=\"1.0\"?>
<opencv_storage>
<camera_matrix type_id=\"opencv-matrix\">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    500. 0. 320. 0. 501. 240. 0. 0. 1.</data></camera_matrix>
<distortion_coefficients type_id=\"opencv-matrix\">
  <rows>1</rows>
  <cols>8</cols>
  <dt>d</dt>
  <data>
    -0.1 0.05 0. 0. 0.01 0. 0. 0.</data></distortion_coefficients>
</opencv_storage>
";

    #[test]
    fn reads_opencv_yaml_and_xml() {
        let c = import_text("cal.yml", OPENCV_YAML, None).unwrap();
        assert_eq!(c.format, CalibrationFormat::OpenCvYaml);
        assert_eq!(
            (c.camera.width, c.camera.height, c.camera.fx),
            (1640, 1232, 1.300142822265625e3)
        );
        assert_eq!(
            c.camera.distortion.to_array(),
            [1.9205e-01, -5.2541e-01, 1.2e-04, -3.1e-04, 4.3119e-01]
        );
        // The XML has no image size: it must be given.
        let e = import_text("cal.xml", OPENCV_XML, None).unwrap_err().to_string();
        assert!(
            e.contains("cal.xml: the file has no image size") && e.contains("--image-size WxH"),
            "{e}"
        );
        let c = import_text("cal.xml", OPENCV_XML, Some((640, 480))).unwrap();
        assert_eq!(c.format, CalibrationFormat::OpenCvXml);
        assert_eq!(
            (c.camera.width, c.camera.cx, c.camera.distortion.k3),
            (640, 320.0, 0.01)
        );
        assert_eq!(c.distortion_model, "rational");
        // A given size must agree with the file's.
        let e = import_text("cal.yml", OPENCV_YAML, Some((640, 480)))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the file's image is 1640x1232, the given size 640x480"),
            "{e}"
        );
        // cv::fisheye coefficients, flagged as the calibration sample does.
        let fisheye = OPENCV_YAML
            .replace("fisheye_model: 0", "fisheye_model: 1")
            .replace("rows: 5", "rows: 4")
            .replace(",\n       4.3119e-01 ]", " ]")
            .replace("1.9205e-01, -5.2541e-01", "0.01, -0.005");
        let e = import_text("cal.yml", &fisheye, None).unwrap_err().to_string();
        assert!(
            e.contains("cal.yml:14: key `distortion_coefficients`: the best Brown-Conrady fit"),
            "{e}"
        );
        // The same lens with a long focal length (19 deg off axis at the corners) fits.
        let narrow = fisheye
            .replace("1.3001428222656250e+03", "3000.")
            .replace("1.3007113037109375e+03", "3000.");
        let c = import_text("cal.yml", &narrow, None).unwrap();
        let fit = c.equidistant_fit.unwrap();
        assert!(fit.max_difference_px < 0.01, "{fit:?}");
    }

    #[test]
    fn bad_opencv_files_name_the_key_and_line() {
        let cases = [
            (
                OPENCV_YAML.replace("camera_matrix: !!opencv-matrix", "camera_matrix:"),
                "cal.yml:8: key `camera_matrix`: expected an opencv-matrix",
            ),
            (
                OPENCV_YAML.replace("   dt: d\n   data: [ 1.3", "   dt: 3d\n   data: [ 1.3"),
                "cal.yml:11: key `camera_matrix.dt`: expected a one-channel",
            ),
            (
                OPENCV_YAML.replace("0., 0., 1. ]", "0., .Nan, 1. ]"),
                "cal.yml:13: key `camera_matrix.data[7]`: `.Nan` is not a finite number",
            ),
            (
                OPENCV_XML.replace(
                    "<rows>1</rows>\n  <cols>8</cols>",
                    "<rows>2</rows>\n  <cols>4</cols>",
                ),
                "cal.xml:9: key `distortion_coefficients`: expected one row or one column",
            ),
            (
                OPENCV_YAML.replace("image_height: 1232\n", ""),
                "cal.yml: key `image_height`: missing",
            ),
            (
                OPENCV_YAML.replace("0., 0., 1. ]", "0., 0.1, 1. ]"),
                "cal.yml:8: key `camera_matrix`: not a camera matrix",
            ),
            (
                OPENCV_YAML.replace("0., 8.1947521972656250e+02", "2.5, 8.1947521972656250e+02"),
                "skew",
            ),
            (
                OPENCV_YAML[..OPENCV_YAML.find("dt: d").unwrap()].to_string(),
                "cal.yml:8: key `camera_matrix.dt`: missing",
            ),
            (
                OPENCV_XML.replace("0.01 0. 0. 0.", "0.01 0.2 0. 0."),
                "cal.xml:9: key `distortion_coefficients`: the rational model's denominator",
            ),
            (
                OPENCV_XML.replace("<cols>8</cols>", "<cols>7</cols>"),
                "cal.xml:13: key `distortion_coefficients.data`: expected 1x7 = 7 values",
            ),
            (
                OPENCV_XML[..OPENCV_XML.find("0.05").unwrap()].to_string(),
                "ends inside `<data>` (opened on line 13): truncated?",
            ),
            (
                OPENCV_XML.replace("<camera_matrix type_id=\"opencv-matrix\">", "<camera_matrix>"),
                "cal.xml:3: key `camera_matrix`: expected an opencv-matrix",
            ),
        ];
        for (text, expected) in cases {
            let name = if text.starts_with('<') {
                "cal.xml"
            } else {
                "cal.yml"
            };
            let e = import_text(name, &text, Some((1640, 1232)))
                .map(|_| ())
                .unwrap_err()
                .to_string();
            assert!(e.contains(expected), "expected `{expected}` in `{e}`");
        }
    }
}
