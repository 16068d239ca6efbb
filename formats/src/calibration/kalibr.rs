//! Kalibr's camchain YAML: one mapping per camera (`cam0`, `cam1`, ...) with `camera_model`,
//! `intrinsics` (`[fu, fv, pu, pv]` for a pinhole), `distortion_model` (`radtan`: `[k1, k2, r1,
//! r2]`; `equidistant`: `[k1, k2, k3, k4]`; `none`), `distortion_coeffs` and `resolution`
//! (`[width, height]`). Extrinsics (`T_cn_cnm1`, `T_cam_imu`) are not a camera's intrinsics and
//! are not read.

use super::lens::Lens;
use super::node::{join_key, FileContext, Node, Value};
use super::{CalibrationError, CalibrationFormat, CalibrationProblem, ImportOptions, Located, Parsed};

/// Whether a top-level entry is a camera (a mapping with Kalibr's camera keys).
pub(crate) fn is_camera(node: &Node) -> bool {
    node.get("camera_model").is_some() || node.get("intrinsics").is_some()
}

pub(crate) fn parse(
    ctx: &FileContext,
    root: &Node,
    options: &ImportOptions,
) -> Result<Parsed, CalibrationError> {
    let Value::Map(entries) = &root.value else {
        return Err(ctx.error(
            Some(root.line),
            "",
            CalibrationProblem::WrongType {
                expected: "a mapping of cameras",
                found: root.describe(),
            },
        ));
    };
    let cameras: Vec<&str> = entries
        .iter()
        .filter(|(_, n)| is_camera(n))
        .map(|(k, _)| k.as_str())
        .collect();
    let available = cameras
        .iter()
        .map(|c| format!("`{c}`"))
        .collect::<Vec<_>>()
        .join(", ");
    let name = match (&options.camera, cameras.as_slice()) {
        (Some(wanted), _) if cameras.contains(&wanted.as_str()) => wanted.clone(),
        (Some(wanted), _) => {
            return Err(ctx.error(
                None,
                wanted,
                CalibrationProblem::CameraNotFound {
                    wanted: wanted.clone(),
                    available,
                },
            ))
        }
        (None, [only]) => only.to_string(),
        (None, _) => return Err(ctx.error(None, "", CalibrationProblem::CameraNeeded { available })),
    };
    let camera = ctx.required(root, "", &name)?;
    let key = |k: &str| join_key(&name, k);

    let model_node = ctx.required(camera, &name, "camera_model")?;
    let model = ctx.text(model_node, &key("camera_model"))?;
    if model != "pinhole" {
        return Err(ctx.error(
            Some(model_node.line),
            &key("camera_model"),
            CalibrationProblem::UnsupportedModel {
                model: model.to_string(),
                supported: "pinhole (omni, ds and eucm are not pinhole cameras)",
            },
        ));
    }
    let intrinsics_node = ctx.required(camera, &name, "intrinsics")?;
    let intrinsics = ctx.numbers(intrinsics_node, &key("intrinsics"))?;
    let Ok([fu, fv, pu, pv]) = <[f64; 4]>::try_from(intrinsics.as_slice()) else {
        return Err(ctx.error(
            Some(intrinsics_node.line),
            &key("intrinsics"),
            CalibrationProblem::WrongShape {
                expected: "4 values [fu, fv, pu, pv] (pinhole)".into(),
                found: format!("{}", intrinsics.len()),
            },
        ));
    };

    let d_model_node = ctx.required(camera, &name, "distortion_model")?;
    let d_model = ctx.text(d_model_node, &key("distortion_model"))?.to_string();
    let d_node = ctx.required(camera, &name, "distortion_coeffs")?;
    let coefficients = ctx.numbers(d_node, &key("distortion_coeffs"))?;
    let (expected, lens) = match d_model.as_str() {
        "radtan" => (4, Lens::OpenCv(coefficients.clone())),
        "equidistant" => (
            4,
            Lens::Equidistant(coefficients.as_slice().try_into().unwrap_or([0.0; 4])),
        ),
        "none" => (0, Lens::OpenCv(vec![0.0; 4])),
        other => {
            return Err(ctx.error(
                Some(d_model_node.line),
                &key("distortion_model"),
                CalibrationProblem::UnsupportedModel {
                    model: other.to_string(),
                    supported: "radtan, equidistant (fitted) and none",
                },
            ))
        }
    };
    if coefficients.len() != expected {
        return Err(ctx.error(
            Some(d_node.line),
            &key("distortion_coeffs"),
            CalibrationProblem::WrongShape {
                expected: format!("{expected} coefficients for `{d_model}`"),
                found: format!("{}", coefficients.len()),
            },
        ));
    }

    let resolution_node = ctx.required(camera, &name, "resolution")?;
    let size = match &resolution_node.value {
        Value::Seq(items) if items.len() == 2 => (
            ctx.whole_number(&items[0], &format!("{}[0]", key("resolution")))?,
            ctx.whole_number(&items[1], &format!("{}[1]", key("resolution")))?,
        ),
        _ => {
            return Err(ctx.error(
                Some(resolution_node.line),
                &key("resolution"),
                CalibrationProblem::WrongShape {
                    expected: "[width, height]".into(),
                    found: resolution_node.describe(),
                },
            ))
        }
    };
    Ok(Parsed {
        format: CalibrationFormat::KalibrCamchain,
        camera_name: Some(name.clone()),
        image_size: Some(Located {
            value: size,
            key: key("resolution"),
            line: resolution_node.line,
        }),
        intrinsics: Located {
            value: [fu, fv, pu, pv],
            key: key("intrinsics"),
            line: intrinsics_node.line,
        },
        distortion_model: d_model,
        lens: Located {
            value: lens,
            key: key("distortion_coeffs"),
            line: d_node.line,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::super::tests::{import_text, import_text_camera};

    const CAMCHAIN: &str = "cam0:
  camera_model: pinhole
  intrinsics: [461.629, 460.152, 362.680, 246.049]
  distortion_model: radtan
  distortion_coeffs: [-0.27695497, 0.06712482, 0.00087538, 0.00011556]
  T_cam_imu:
  - [0.01779318, 0.99967549, -0.01822936, 0.07008565]
  - [-0.9998017, 0.01795239, 0.00860714, -0.01771023]
  - [0.00893160, 0.01807260, 0.99979678, 0.00399246]
  - [0.0, 0.0, 0.0, 1.0]
  timeshift_cam_imu: -8.121e-05
  rostopic: /cam0/image_raw
  resolution: [752, 480]
  cam_overlaps: [1]
cam1:
  camera_model: pinhole
  intrinsics: [1600.0, 1600.0, 319.5, 239.5]
  distortion_model: equidistant
  distortion_coeffs: [0.02, -0.01, 0.0, 0.0]
  T_cn_cnm1:
  - [1.0, 0.0, 0.0, -0.11]
  - [0.0, 1.0, 0.0, 0.0]
  - [0.0, 0.0, 1.0, 0.0]
  - [0.0, 0.0, 0.0, 1.0]
  resolution: [640, 480]
  rostopic: /cam1/image_raw
";

    #[test]
    fn reads_the_chosen_camera() {
        let c = import_text_camera("chain.yaml", CAMCHAIN, "cam0").unwrap();
        assert_eq!(
            (c.camera.width, c.camera.height, c.camera.fx, c.camera.cy),
            (752, 480, 461.629, 246.049)
        );
        assert_eq!(
            c.camera.distortion.to_array(),
            [-0.27695497, 0.06712482, 0.00087538, 0.00011556, 0.0]
        );
        assert_eq!(
            (c.camera_name.as_deref(), c.distortion_model.as_str()),
            (Some("cam0"), "radtan")
        );
        let c = import_text_camera("chain.yaml", CAMCHAIN, "cam1").unwrap();
        assert!(c.equidistant_fit.unwrap().max_difference_px < 0.01);
        // One camera needs no --camera.
        let single = &CAMCHAIN[..CAMCHAIN.find("cam1:").unwrap()];
        assert_eq!(import_text("chain.yaml", single, None).unwrap().camera.width, 752);
    }

    #[test]
    fn bad_camchains_name_the_key_and_line() {
        let cases = [
            (
                CAMCHAIN.to_string(),
                None,
                "chain.yaml: the file holds several cameras (`cam0`, `cam1`)",
            ),
            (
                CAMCHAIN.to_string(),
                Some("cam2"),
                "chain.yaml: key `cam2`: no camera `cam2` in the file; it has `cam0`, `cam1`",
            ),
            (
                CAMCHAIN.replacen("  intrinsics: [461.629, 460.152, 362.680, 246.049]\n", "", 1),
                Some("cam0"),
                "chain.yaml:1: key `cam0.intrinsics`: missing",
            ),
            (
                CAMCHAIN.replacen("camera_model: pinhole", "camera_model: omni", 1),
                Some("cam0"),
                "chain.yaml:2: key `cam0.camera_model`: unsupported model `omni`",
            ),
            (
                CAMCHAIN.replacen("distortion_model: radtan", "distortion_model: fov", 1),
                Some("cam0"),
                "chain.yaml:4: key `cam0.distortion_model`: unsupported model `fov`",
            ),
            (
                CAMCHAIN.replacen(", 0.00011556]", "]", 1),
                Some("cam0"),
                "chain.yaml:5: key `cam0.distortion_coeffs`: expected 4 coefficients for `radtan`, found 3",
            ),
            (
                CAMCHAIN.replacen("460.152", "NaN", 1),
                Some("cam0"),
                "chain.yaml:3: key `cam0.intrinsics[1]`: `NaN` is not a finite number",
            ),
            (
                CAMCHAIN.replacen("[752, 480]", "[752]", 1),
                Some("cam0"),
                "chain.yaml:13: key `cam0.resolution`: expected [width, height]",
            ),
            (
                CAMCHAIN.replacen("[752, 480]", "[752.5, 480]", 1),
                Some("cam0"),
                "key `cam0.resolution[0]`: expected a whole number",
            ),
            (
                CAMCHAIN.replace("1600.0, 1600.0", "300.0, 300.0"),
                Some("cam1"),
                "chain.yaml:19: key `cam1.distortion_coeffs`: the best Brown-Conrady fit",
            ),
            (
                CAMCHAIN[..CAMCHAIN.find("0.06712482").unwrap()].to_string(),
                Some("cam0"),
                "chain.yaml:5: the list's `[` is not closed",
            ),
        ];
        for (text, camera, expected) in cases {
            let result = match camera {
                Some(c) => import_text_camera("chain.yaml", &text, c),
                None => import_text("chain.yaml", &text, None),
            };
            let e = result.map(|_| ()).unwrap_err().to_string();
            assert!(e.contains(expected), "expected `{expected}` in `{e}`");
        }
    }
}
