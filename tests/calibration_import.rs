//! `deckwatch calibration import` (issue 73) against files other tools wrote and OpenCV's own
//! projections: tests/peers/calibration_files.py writes OpenCV FileStorage YAML and XML with
//! cv2.FileStorage, ROS camera_info and Kalibr camchains in their documented layouts, and
//! projects points with cv2.projectPoints (cv2.fisheye.projectPoints for the equidistant lens);
//! deckwatch imports each file and projects the same points with `CameraModel::project`.
//! Broken and unrepresentable files are refused with the file, key and problem.

use deckwatch_common::DeckLayout;
use deckwatch_formats::recording::{read_camera_json, write_camera_json};
use deckwatch_tests::{peer_python, workspace_binary};
use std::collections::HashMap;
use std::path::Path;
use std::process::{Command, Output};

/// The largest pixel difference accepted between deckwatch's and OpenCV's projections (px).
const MAX_DIFFERENCE_PX: f64 = 0.01;

struct Peer {
    json: serde_json::Value,
}

impl Peer {
    fn write(dir: &Path) -> Self {
        let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/calibration_files.py");
        let out = Command::new(peer_python("cv2"))
            .arg(script)
            .arg(dir)
            .output()
            .expect("python runs");
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        Self {
            json: serde_json::from_slice(&out.stdout).expect("the peer's JSON"),
        }
    }

    fn bad(&self, name: &str) -> String {
        self.json["bad"][name]
            .as_str()
            .unwrap_or_else(|| panic!("bad file {name}"))
            .to_string()
    }
}

fn import(file: &str, out: &Path, args: &[&str]) -> Output {
    Command::new(workspace_binary("deckwatch"))
        .args(["calibration", "import", file, "--out"])
        .arg(out)
        .args(args)
        .output()
        .expect("deckwatch runs")
}

#[test]
fn imported_calibrations_project_as_opencv_does() {
    let dir = tempfile::tempdir().unwrap();
    let peer = Peer::write(&dir.path().join("files"));
    let mut differences = HashMap::new();
    for case in peer.json["cases"].as_array().unwrap() {
        let name = case["name"].as_str().unwrap();
        let file = case["file"].as_str().unwrap();
        let args: Vec<&str> = case["args"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a.as_str().unwrap())
            .collect();
        let out_dir = dir.path().join(name);
        let out = import(file, &out_dir.join("camera.json"), &args);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{name}: {}{stdout}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            stdout.contains("imported ") && stdout.contains("wrote "),
            "{name}: {stdout}"
        );
        let (camera, _) = read_camera_json(&out_dir).unwrap();
        let points = case["points"].as_array().unwrap();
        let pixels = case["pixels"].as_array().unwrap();
        let mut max_px = 0.0f64;
        for (p, px) in points.iter().zip(pixels) {
            let p = [0, 1, 2].map(|i| p[i].as_f64().unwrap());
            // nalgebra's Vector3 from an array (the tests' package does not name nalgebra).
            let [u, v] = camera.project(&p.into()).unwrap();
            let d = (u - px[0].as_f64().unwrap()).hypot(v - px[1].as_f64().unwrap());
            max_px = max_px.max(d);
        }
        println!(
            "{name}: {} points, max difference from OpenCV {max_px:.2e} px",
            points.len()
        );
        if name.contains("equidistant") {
            assert!(stdout.contains("fitted: max difference"), "{name}: {stdout}");
        }
        assert!(max_px <= MAX_DIFFERENCE_PX, "{name}: {max_px} px\n{stdout}");
        differences.insert(name.to_string(), max_px);
    }
    for name in [
        "opencv_yaml",
        "opencv_xml",
        "ros_plumb_bob",
        "ros_rational",
        "kalibr_radtan",
        "kalibr_equidistant",
    ] {
        assert!(differences.contains_key(name), "{name} was not imported");
    }
}

#[test]
fn bad_and_unrepresentable_files_are_refused_with_the_key_and_problem() {
    let dir = tempfile::tempdir().unwrap();
    let peer = Peer::write(&dir.path().join("files"));
    // A truncated OpenCV XML (cut inside the distortion data).
    let xml = std::fs::read_to_string(peer.bad("opencv_xml_no_size")).unwrap();
    let truncated = dir.path().join("truncated.xml");
    std::fs::write(&truncated, &xml[..xml.rfind("0.").unwrap()]).unwrap();
    let truncated = truncated.to_string_lossy().to_string();
    let cases: [(String, &[&str], &[&str]); 10] = [
        (
            peer.bad("opencv_yaml_nan"),
            &[],
            &["opencv_nan.yml:9: key `camera_matrix.data[0]`: `.Nan` is not a finite number"],
        ),
        (
            peer.bad("opencv_xml_3x4"),
            &[],
            &["opencv_3x4.xml:5: key `camera_matrix`: expected a 3x3 matrix, found 3x4"],
        ),
        (
            peer.bad("opencv_xml_no_size"),
            &[],
            &["opencv.xml: the file has no image size", "--image-size WxH"],
        ),
        (
            truncated,
            &["--image-size", "640x480"],
            &["truncated.xml:", "ends inside `<data>`", "truncated?"],
        ),
        (
            peer.bad("ros_missing_k"),
            &[],
            &["ros_missing_k.yaml: key `camera_matrix`: missing"],
        ),
        (
            peer.bad("ros_stereo"),
            &[],
            &[
                "ros_stereo.yaml:13: key `rectification_matrix`: not the identity",
                "stereo-rectified",
            ],
        ),
        (
            peer.bad("ros_rational_k5"),
            &[],
            &[
                "ros_rational_k5.yaml:9: key `distortion_coefficients`",
                "k4, k5, k6 = [0.0, 0.02, 0.0] is not zero",
            ],
        ),
        (
            peer.bad("kalibr_omni"),
            &[],
            &["kalibr_omni.yaml:2: key `cam0.camera_model`: unsupported model `omni`"],
        ),
        (
            peer.bad("kalibr_wide"),
            &[],
            &[
                "kalibr_wide.yaml:5: key `cam0.distortion_coeffs`",
                "equidistant (fisheye)",
                "px",
                "too wide",
            ],
        ),
        (
            dir.path()
                .join("files/kalibr_radtan.yaml")
                .to_string_lossy()
                .to_string(),
            &["--camera", "cam7"],
            &["no camera `cam7` in the file; it has `cam0`, `cam1`"],
        ),
    ];
    for (file, args, expected) in cases {
        let out_dir = dir.path().join("refused");
        let out = import(&file, &out_dir.join("camera.json"), args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{file} was accepted");
        for e in expected {
            assert!(stderr.contains(e), "expected `{e}` in: {stderr}");
        }
        assert!(
            !out_dir.join("camera.json").exists(),
            "{file}: a camera.json was written"
        );
    }
}

#[test]
fn an_existing_camera_json_is_replaced_only_when_asked_and_a_deck_can_be_kept() {
    let dir = tempfile::tempdir().unwrap();
    let peer = Peer::write(&dir.path().join("files"));
    let file = peer.json["cases"][0]["file"].as_str().unwrap().to_string();
    let out = dir.path().join("calib/camera.json");
    assert!(import(&file, &out, &["--readout-ms", "18.5"]).status.success());
    let (camera, deck) = read_camera_json(&dir.path().join("calib")).unwrap();
    assert_eq!((camera.readout_s, deck), (0.0185, DeckLayout::paper()));
    let again = import(&file, &out, &[]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("calib/camera.json exists: --force replaces it"));
    // The deck of another camera.json (say the ship's own), kept with --deck-from.
    let ship = dir.path().join("ship");
    std::fs::create_dir(&ship).unwrap();
    let ship_deck = DeckLayout {
        n_ring: 6,
        ring_radius_m: 2.5,
        ..DeckLayout::paper()
    };
    write_camera_json(&ship, &camera, &ship_deck).unwrap();
    let ship_json = ship.join("camera.json").to_string_lossy().to_string();
    let forced = import(&file, &out, &["--force", "--deck-from", &ship_json]);
    assert!(
        forced.status.success(),
        "{}",
        String::from_utf8_lossy(&forced.stderr)
    );
    let (camera, deck) = read_camera_json(&dir.path().join("calib")).unwrap();
    assert_eq!((camera.readout_s, deck), (0.0, ship_deck));
}
