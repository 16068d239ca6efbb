//! The simulator through pixels: render frames, find the marker centres with a simple reference
//! method, run the paper's estimator, compare with the ground truth.

use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::ErrorStats;
use deckwatch_common::{CameraModel, DeckLayout, GrayImage};
use deckwatch_detect::{identify, marker_pixels};
use deckwatch_estimate::{PaperEstimator, PaperVariant};
use deckwatch_sim::{FrameSimulator, RenderOptions, Renderer, Scenario};
use deckwatch_tests::reference_blobs;

/// Case 1 frames at full resolution through the reference centroids and the paper's estimator.
fn case1_through_pixels(options: RenderOptions, frames: u64) -> (ErrorStats, f64) {
    let cam = CameraModel::paper();
    let deck = DeckLayout::paper();
    let renderer = Renderer::new(cam, deck, options, 1).unwrap();
    // The 20 s sweep sampled evenly, ends included.
    let rate = (frames - 1) as f64 / 20.0;
    let mut sim = FrameSimulator::new(Scenario::Case1.profile(1, 1.0), renderer, rate, 0.0, 1, 1).unwrap();
    let est = PaperEstimator::new(cam, deck, PaperVariant::Atan2);
    let mut img = GrayImage::new(cam.width as usize, cam.height as usize);
    let mut stats = ErrorStats::default();
    let mut centroid_ss = 0.0;
    let mut n_centroids = 0;
    for k in 0..frames {
        let truth = sim.render_frame(k, &mut img.view_mut()).unwrap();
        let blobs = reference_blobs(img.view(), 50, 3);
        let ids = identify(&blobs, &deck, &cam).unwrap_or_else(|e| panic!("frame {k}: {e}"));
        let px = marker_pixels(&blobs, &ids);
        for (m, t) in px.iter().zip(&truth.markers) {
            let (m, t) = (m.unwrap(), t.unwrap());
            centroid_ss += (m[0] - t[0]).powi(2) + (m[1] - t[1]).powi(2);
            n_centroids += 1;
        }
        let e = est
            .estimate(&px, Some(truth.sample.viewpoint.altitude_m))
            .unwrap();
        let err = rpy_error_deg(&e.attitude.rpy, &truth.sample.attitude);
        println!(
            "frame {k}: truth {:?} error {err:?}",
            truth.sample.attitude.to_degrees()
        );
        stats.add(err);
    }
    (stats, (centroid_ss / n_centroids as f64).sqrt())
}

#[test]
fn case1_clean_full_frames_are_within_0_05_deg() {
    let (stats, centroid_rms) = case1_through_pixels(RenderOptions::default(), 21);
    println!(
        "RMSE {:?} deg, max {:?}, centroid RMS {centroid_rms:.4} px",
        stats.rmse(),
        stats.max
    );
    for (axis, rmse) in ["roll", "pitch", "yaw"].iter().zip(stats.rmse()) {
        assert!(rmse < 0.05, "{axis} RMSE {rmse} deg");
    }
}
