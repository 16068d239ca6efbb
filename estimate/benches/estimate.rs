//! Estimator speed per frame, one thread: `cargo bench -p deckwatch-estimate --bench estimate`.
//!
//! Nine markers of the Pi camera (rpi-v2, 3280x2464) seen from 5 m over a deck at 16 attitudes
//! within +-8 deg: the full planar pose (level camera, and on a tilted vehicle) and the paper's
//! estimator (corrected: the `atan2` variant, the pipeline's default; and as printed, with an
//! altimeter).

use criterion::Criterion;
use deckwatch_common::{CameraModel, DeckLayout, RotationMatrix, Rpy, SceneGeometry, Viewpoint};
use deckwatch_estimate::{PaperEstimator, PaperVariant, PoseConfig, PoseEstimator};
use std::hint::black_box;

fn main() {
    let camera = CameraModel::rpi_v2();
    let deck = DeckLayout::paper();
    let frames: Vec<Vec<Option<[f64; 2]>>> = (0..16)
        .map(|k| {
            let a = k as f64 * 0.4;
            SceneGeometry {
                attitude: Rpy::from_degrees(8.0 * a.sin(), 6.0 * (1.3 * a).cos(), 3.0 * a).to_matrix(),
                viewpoint: Viewpoint::centred(5.0),
            }
            .project_markers(&camera, &deck)
        })
        .collect();
    let pose = PoseEstimator::new(camera, deck, PoseConfig::default());
    let atan2 = PaperEstimator::new(camera, deck, PaperVariant::Atan2);
    let printed = PaperEstimator::new(camera, deck, PaperVariant::Printed);
    let tilted: RotationMatrix = Rpy::from_degrees(4.0, -3.0, 0.0).to_matrix();
    for m in &frames {
        assert!(pose.estimate(m, false).is_ok() && atan2.estimate(m, None).is_ok());
    }

    let mut c = Criterion::default().sample_size(50).configure_from_args();
    let mut group = c.benchmark_group("estimate_9_markers");
    let mut k = 0;
    let mut next = || {
        k = (k + 1) % frames.len();
        &frames[k]
    };
    group.bench_function("full_pose", |b| {
        b.iter(|| pose.estimate(black_box(next()), false))
    });
    group.bench_function("full_pose_tilted_vehicle", |b| {
        b.iter(|| pose.estimate_with_vehicle(black_box(next()), false, &tilted))
    });
    group.bench_function("paper_atan2", |b| {
        b.iter(|| atan2.estimate(black_box(next()), None))
    });
    group.bench_function("paper_printed_altimeter", |b| {
        b.iter(|| printed.estimate(black_box(next()), Some(5.0)))
    });
    group.finish();
    c.final_summary();
}
