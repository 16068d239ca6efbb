//! Detect the deck's markers in one image and estimate the deck's attitude with both estimator
//! families, beside the recording's truth. The libraries alone: no processes, no configuration.
//! A recording of a camera on a tilting vehicle carries the vehicle's attitude per frame
//! (CONVENTIONS.md §5, §9); both estimators take it out, so the attitude is the deck's in W.
//!
//!     cargo run --example detect_and_estimate -- [RECORDING_FOLDER [FRAME_INDEX]]
//!
//! (default: the repository's `tests/data/ship-640x480`, frame 0).

use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::RotationMatrix;
use deckwatch_detect::{Detector, DetectorConfig};
use deckwatch_estimate::{PaperEstimator, PaperVariant, PoseConfig, PoseEstimator};
use deckwatch_formats::recording::Recording;
use std::error::Error;
use std::path::Path;

/// One frame's result: the deck's roll, pitch, yaw (deg) by the full pose and by the paper's
/// method, the camera's height over the deck (m), and the full pose's error against the truth.
struct FrameResult {
    markers_found: u32,
    full_pose_deg: [f64; 3],
    camera_height_m: f64,
    /// None when the paper's method cannot estimate this frame (it needs the centre, the bow
    /// and five ring markers).
    paper_deg: Option<[f64; 3]>,
    full_pose_error_deg: Option<[f64; 3]>,
}

/// Frame `index` of the recording in `dir`, detected and estimated.
fn detect_and_estimate(dir: &Path, index: usize) -> Result<FrameResult, Box<dyn Error>> {
    let recording = Recording::open(dir)?;
    let frame = recording.frames.get(index).ok_or("no such frame")?;
    let image = recording.read_image(frame)?;
    let (camera, deck) = (recording.camera, recording.deck);

    let mut detector = Detector::new(camera, deck, DetectorConfig::for_camera(&camera, &deck));
    let markers = detector.detect(image.view());
    let pixels = markers.pixels(deck.marker_count());

    // The vehicle's attitude at the frame (body to W); none: a level camera.
    let vehicle = frame
        .truth
        .vehicle_attitude()
        .map_or(RotationMatrix::identity(), |r| r.to_matrix());
    let pose = PoseEstimator::new(camera, deck, PoseConfig::default()).estimate_with_vehicle(
        &pixels,
        markers.perspective_corrected.get(),
        &vehicle,
    )?;
    let paper = PaperEstimator::new(camera, deck, PaperVariant::Atan2)
        .estimate_with_vehicle(&pixels, None, &vehicle)
        .ok();
    Ok(FrameResult {
        markers_found: markers.count,
        full_pose_deg: pose.attitude.rpy.to_degrees(),
        camera_height_m: pose.viewpoint.altitude_m,
        paper_deg: paper.map(|p| p.attitude.rpy.to_degrees()),
        full_pose_error_deg: frame
            .truth
            .attitude()
            .map(|truth| rpy_error_deg(&pose.attitude.rpy, &truth)),
    })
}

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let dir = args
        .next()
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/ship-640x480").into());
    let index = args.next().map(|s| s.parse()).transpose()?.unwrap_or(0);
    let r = detect_and_estimate(Path::new(&dir), index)?;
    let [roll, pitch, yaw] = r.full_pose_deg;
    println!("{} markers found", r.markers_found);
    println!(
        "full pose:     roll {roll:7.3}  pitch {pitch:7.3}  yaw {yaw:7.3} deg, camera {:.3} m over the deck",
        r.camera_height_m
    );
    match r.paper_deg {
        Some([roll, pitch, yaw]) => {
            println!("paper (atan2): roll {roll:7.3}  pitch {pitch:7.3}  yaw {yaw:7.3} deg")
        }
        None => println!("paper (atan2): too few markers for the paper's method"),
    }
    if let Some([roll, pitch, yaw]) = r.full_pose_error_deg {
        println!("full pose against the truth: {roll:.4} {pitch:.4} {yaw:.4} deg");
    }
    Ok(())
}

#[test]
fn one_ship_frame_within_a_few_tenths_of_a_degree() {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/ship-640x480"));
    let r = detect_and_estimate(dir, 0).unwrap();
    assert_eq!(r.markers_found, 9);
    let error = r.full_pose_error_deg.unwrap();
    assert!(error.iter().all(|e| e.abs() < 0.5), "{error:?}");
    let (full, paper) = (r.full_pose_deg, r.paper_deg.unwrap());
    assert!(
        (full[0] - paper[0]).abs() < 1.0 && (full[1] - paper[1]).abs() < 1.0,
        "{full:?} {paper:?}"
    );
    assert!((r.camera_height_m - 5.0).abs() < 0.1, "{}", r.camera_height_m);
}
