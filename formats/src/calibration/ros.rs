//! ROS `camera_calibration`'s camera_info YAML, as camera_calibration_parsers writes and reads
//! it (the fields of sensor_msgs/CameraInfo): `image_width`, `image_height`, `camera_name`,
//! `camera_matrix`, `distortion_model`, `distortion_coefficients`, `rectification_matrix`,
//! `projection_matrix`, each matrix as `{rows, cols, data}` (row-major).

use super::lens::Lens;
use super::node::{FileContext, Node};
use super::{
    camera_matrix_intrinsics, CalibrationError, CalibrationFormat, CalibrationProblem, ImportOptions,
    Located, Parsed,
};

/// How far from the identity a rectification matrix may be and still count as one (a file
/// written with 6 decimals keeps it exact; this absorbs a float32 round trip).
const IDENTITY_TOLERANCE: f64 = 1e-6;

pub(crate) fn parse(
    ctx: &FileContext,
    root: &Node,
    options: &ImportOptions,
) -> Result<Parsed, CalibrationError> {
    let width_node = ctx.required(root, "", "image_width")?;
    let width = ctx.whole_number(width_node, "image_width")?;
    let height = ctx.whole_number(ctx.required(root, "", "image_height")?, "image_height")?;
    let name_node = root.get("camera_name");
    let camera_name = name_node
        .map(|n| ctx.text(n, "camera_name").map(str::to_string))
        .transpose()?;
    if let Some(wanted) = &options.camera {
        if camera_name.as_deref() != Some(wanted.as_str()) {
            return Err(ctx.error(
                name_node.map(|n| n.line),
                "camera_name",
                CalibrationProblem::CameraNotFound {
                    wanted: wanted.clone(),
                    available: camera_name.map_or("one unnamed camera".into(), |n| format!("`{n}`")),
                },
            ));
        }
    }
    let k = ctx.matrix(ctx.required(root, "", "camera_matrix")?, "camera_matrix")?;
    let intrinsics = camera_matrix_intrinsics(ctx, &k, "camera_matrix")?;

    // camera_calibration_parsers read a file without `distortion_model` as plumb_bob.
    let (model, model_line) = match root.get("distortion_model") {
        Some(n) => (ctx.text(n, "distortion_model")?.to_string(), Some(n.line)),
        None => ("plumb_bob".to_string(), None),
    };
    let d_key = "distortion_coefficients";
    let d = ctx.matrix(ctx.required(root, "", d_key)?, d_key)?;
    let count = d.values.len();
    let (expected, lens) = match model.as_str() {
        "plumb_bob" => ("4 or 5 (k1 k2 p1 p2 [k3])", Lens::OpenCv(d.values.clone())),
        "rational_polynomial" => ("8 (k1 k2 p1 p2 k3 k4 k5 k6)", Lens::OpenCv(d.values.clone())),
        "equidistant" => (
            "4 (k1 k2 k3 k4)",
            Lens::Equidistant(d.values.as_slice().try_into().unwrap_or([0.0; 4])),
        ),
        other => {
            return Err(ctx.error(
                model_line,
                "distortion_model",
                CalibrationProblem::UnsupportedModel {
                    model: other.to_string(),
                    supported: "plumb_bob, rational_polynomial (k4..k6 zero) and equidistant (fitted)",
                },
            ))
        }
    };
    let count_fits = match model.as_str() {
        "plumb_bob" => count == 4 || count == 5,
        "rational_polynomial" => count == 8,
        _ => count == 4,
    };
    if !d.is_vector() || !count_fits {
        return Err(ctx.error(
            Some(d.line),
            d_key,
            CalibrationProblem::WrongShape {
                expected: format!("1 row of {expected} coefficients for `{model}`"),
                found: d.shape(),
            },
        ));
    }

    // A monocular camera_info's rectification is the identity; a stereo pair's rotates the
    // camera onto the common plane, a frame deckwatch's camera does not have.
    if let Some(r_node) = root.get("rectification_matrix") {
        let key = "rectification_matrix";
        let r = ctx.matrix(r_node, key)?;
        if (r.rows, r.cols) != (3, 3) {
            return Err(ctx.error(
                Some(r.line),
                key,
                CalibrationProblem::WrongShape {
                    expected: "a 3x3 matrix".into(),
                    found: r.shape(),
                },
            ));
        }
        let identity = r
            .values
            .iter()
            .enumerate()
            .all(|(i, &v)| (v - if i % 4 == 0 { 1.0 } else { 0.0 }).abs() <= IDENTITY_TOLERANCE);
        if !identity {
            return Err(ctx.error(
                Some(r.line),
                key,
                CalibrationProblem::NotRepresentable(format!(
                    "not the identity ({:?}): a stereo-rectified calibration is not represented \
                     (deckwatch's camera is one unrectified camera)",
                    r.values
                )),
            ));
        }
    }
    // The projection matrix describes the rectified image, which deckwatch does not use; its
    // shape is still checked so a garbled file is not half read.
    if let Some(p_node) = root.get("projection_matrix") {
        let p = ctx.matrix(p_node, "projection_matrix")?;
        if (p.rows, p.cols) != (3, 4) {
            return Err(ctx.error(
                Some(p.line),
                "projection_matrix",
                CalibrationProblem::WrongShape {
                    expected: "a 3x4 matrix".into(),
                    found: p.shape(),
                },
            ));
        }
    }
    Ok(Parsed {
        format: CalibrationFormat::RosCameraInfo,
        camera_name,
        image_size: Some(Located {
            value: (width, height),
            key: "image_width".into(),
            line: width_node.line,
        }),
        intrinsics,
        distortion_model: model,
        lens: Located {
            value: lens,
            key: d_key.into(),
            line: d.line,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::super::tests::{import_text, import_text_camera};

    const CAMERA_INFO: &str = "image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [ 580.46715,    0.     ,  315.27153,
            0.     ,  576.62721,  247.47257,
            0.     ,    0.     ,    1.     ]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.134462, -0.311908, 0.002304, 0.003083, 0.000000]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1., 0., 0., 0., 1., 0., 0., 0., 1.]
projection_matrix:
  rows: 3
  cols: 4
  data: [587.7, 0., 316.8, 0., 0., 585.7, 248.3, 0., 0., 0., 1., 0.]
";

    #[test]
    fn reads_a_camera_info() {
        let c = import_text("cam.yaml", CAMERA_INFO, None).unwrap();
        assert_eq!((c.camera.width, c.camera.height), (640, 480));
        assert_eq!(
            (c.camera.fx, c.camera.fy, c.camera.cx, c.camera.cy),
            (580.46715, 576.62721, 315.27153, 247.47257)
        );
        assert_eq!(
            c.camera.distortion.to_array(),
            [0.134462, -0.311908, 0.002304, 0.003083, 0.0]
        );
        assert_eq!(
            (c.camera_name.as_deref(), c.distortion_model.as_str()),
            (Some("narrow_stereo"), "plumb_bob")
        );
        // Without distortion_model (older files): plumb_bob.
        let old = CAMERA_INFO.replace("distortion_model: plumb_bob\n", "");
        assert_eq!(
            import_text("cam.yaml", &old, None).unwrap().distortion_model,
            "plumb_bob"
        );
        // rational_polynomial with k4..k6 zero.
        let rational = CAMERA_INFO
            .replace("plumb_bob", "rational_polynomial")
            .replace("cols: 5", "cols: 8")
            .replace("0.000000]", "0.01, 0., 0., 0.]");
        assert_eq!(
            import_text("cam.yaml", &rational, None)
                .unwrap()
                .camera
                .distortion
                .k3,
            0.01
        );
        // A YAML header (yaml-cpp can write one) does not make it OpenCV's.
        let headed = format!("%YAML 1.2\n---\n{CAMERA_INFO}");
        let c = import_text("cam.yaml", &headed, None).unwrap();
        assert_eq!(c.format, super::super::CalibrationFormat::RosCameraInfo);
        // --camera must name the file's camera.
        assert!(import_text_camera("cam.yaml", CAMERA_INFO, "narrow_stereo").is_ok());
        let e = import_text_camera("cam.yaml", CAMERA_INFO, "left")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "cam.yaml:3: key `camera_name`: no camera `left` in the file; it has `narrow_stereo`"
        );
    }

    #[test]
    fn bad_camera_infos_name_the_key_and_line() {
        let cases = [
            (
                CAMERA_INFO.replace("image_height: 480\n", ""),
                "cam.yaml: key `image_height`: missing",
            ),
            (
                CAMERA_INFO.replace(
                    "  rows: 3\n  cols: 3\n  data: [ 580",
                    "  rows: 2\n  cols: 3\n  data: [ 580",
                ),
                "cam.yaml:7: key `camera_matrix.data`: expected 2x3 = 6 values (rows x cols), found 9 values",
            ),
            (
                CAMERA_INFO.replace("576.62721", ".nan"),
                "cam.yaml:8: key `camera_matrix.data[4]`: `.nan` is not a finite number",
            ),
            (
                CAMERA_INFO.replace("plumb_bob", "fisheye"),
                "cam.yaml:10: key `distortion_model`: unsupported model `fisheye`",
            ),
            (
                CAMERA_INFO
                    .replace("cols: 5", "cols: 4")
                    .replace(", 0.000000]", "]")
                    .replace("plumb_bob", "rational_polynomial"),
                "cam.yaml:11: key `distortion_coefficients`: expected 1 row of 8",
            ),
            (
                CAMERA_INFO
                    .replace("0.000000]", "0.0, 0.0, 0.1, 0.0]")
                    .replace("cols: 5", "cols: 8")
                    .replace("plumb_bob", "rational_polynomial"),
                "k4, k5, k6 = [0.0, 0.1, 0.0] is not zero",
            ),
            (
                CAMERA_INFO.replace("[1., 0., 0., 0., 1.,", "[0.99, 0.1, 0., -0.1, 0.99,"),
                "cam.yaml:15: key `rectification_matrix`: not the identity",
            ),
            (
                CAMERA_INFO.replace("  cols: 4\n", "  cols: 3\n"),
                "key `projection_matrix.data`: expected 3x3",
            ),
            (
                CAMERA_INFO.replace("580.46715", "-580.46715"),
                "cam.yaml:4: key `camera_matrix`: the focal lengths",
            ),
            (
                CAMERA_INFO.replace("315.27153", "700.0"),
                "principal point (700, 247.47257) px is outside",
            ),
            (
                CAMERA_INFO[..CAMERA_INFO.find("576.62721").unwrap()].to_string(),
                "cam.yaml:8: the list's `[` is not closed",
            ),
        ];
        for (text, expected) in cases {
            let e = import_text("cam.yaml", &text, None).unwrap_err().to_string();
            assert!(e.contains(expected), "expected `{expected}` in `{e}`");
        }
    }
}
