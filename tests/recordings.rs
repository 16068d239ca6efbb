//! The committed recordings under tests/data: they are what the simulator's commands in
//! tests/data/README.md produce, and their frames agree with their ground truth.

use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::ErrorStats;
use deckwatch_detect::{identify, marker_pixels};
use deckwatch_estimate::{PaperEstimator, PaperVariant};
use deckwatch_formats::Recording;
use deckwatch_tests::{reference_blobs, workspace_binary};
use std::path::{Path, PathBuf};

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

/// The `deckwatch sim record ...` lines of tests/data/README.md.
fn recorded_commands() -> Vec<Vec<String>> {
    let readme = std::fs::read_to_string(data_dir().join("README.md")).unwrap();
    readme
        .lines()
        .filter(|l| l.starts_with("deckwatch sim record "))
        .map(|l| l.split_whitespace().skip(1).map(str::to_string).collect())
        .collect()
}

#[test]
fn committed_recordings_are_reproduced_by_their_commands() {
    let commands = recorded_commands();
    assert_eq!(commands.len(), 4, "tests/data/README.md lists the recordings");
    let tmp = tempfile::tempdir().unwrap();
    for args in commands {
        let out_at = args.iter().position(|a| a == "--out").unwrap() + 1;
        let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join(&args[out_at]);
        let fresh = tmp.path().join(committed.file_name().unwrap());
        let mut args = args.clone();
        args[out_at] = fresh.display().to_string();
        let out = std::process::Command::new(workspace_binary("deckwatch"))
            .args(&args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let (a, b) = (
            Recording::open(&committed).unwrap(),
            Recording::open(&fresh).unwrap(),
        );
        assert_eq!(a.camera, b.camera);
        assert_eq!(a.deck, b.deck);
        assert_eq!(a.frames.len(), b.frames.len());
        for (fa, fb) in a.frames.iter().zip(&b.frames) {
            assert_eq!(
                (fa.index, fa.timestamp_ns, &fa.file),
                (fb.index, fb.timestamp_ns, &fb.file)
            );
            for (x, y) in [
                (fa.truth.roll_deg, fb.truth.roll_deg),
                (fa.truth.alt_m, fb.truth.alt_m),
                (fa.truth.offset_y_m, fb.truth.offset_y_m),
            ] {
                assert_eq!(x.is_some(), y.is_some());
                assert!((x.unwrap_or(0.0) - y.unwrap_or(0.0)).abs() < 1e-9);
            }
            let (ia, ib) = (a.read_image(fa).unwrap(), b.read_image(fb).unwrap());
            // Identical on this machine; another libm may move a value across a rounding step.
            let off: Vec<i16> = ia
                .data
                .iter()
                .zip(&ib.data)
                .map(|(&p, &q)| p as i16 - q as i16)
                .filter(|d| *d != 0)
                .collect();
            assert!(
                off.iter().all(|d| d.abs() <= 1),
                "{}: a pixel differs by more than 1",
                fa.file
            );
            assert!(
                off.len() * 1000 <= ia.data.len(),
                "{}: {} pixels differ",
                fa.file,
                off.len()
            );
        }
    }
}

/// Through the reference centroids and the paper's estimator: (errors, frames without estimate).
fn estimate_recording(name: &str) -> (Vec<[f64; 3]>, usize) {
    let rec = Recording::open(data_dir().join(name)).unwrap();
    let est = PaperEstimator::new(rec.camera, rec.deck, PaperVariant::Atan2);
    let mut errors = Vec::new();
    let mut none = 0;
    for f in &rec.frames {
        let img = rec.read_image(f).unwrap();
        let blobs = reference_blobs(img.view(), 8, 2);
        let estimate = identify(&blobs, &rec.deck, &rec.camera)
            .ok()
            .and_then(|ids| est.estimate(&marker_pixels(&blobs, &ids), f.truth.alt_m).ok());
        match (estimate, f.truth.attitude()) {
            (Some(e), Some(t)) => errors.push(rpy_error_deg(&e.attitude.rpy, &t)),
            (Some(_), None) => panic!("{name} frame {}: an attitude without a deck in view", f.index),
            (None, _) => none += 1,
        }
    }
    (errors, none)
}

#[test]
fn committed_frames_agree_with_their_ground_truth() {
    // Full-size clean frames: as accurate as the synthetic Case 1 test.
    let (errors, none) = estimate_recording("case1-3280x2464");
    assert_eq!((errors.len(), none), (3, 0));
    for e in &errors {
        assert!(e.iter().all(|&x| x < 0.1), "{e:?}");
    }
    // 640x480 with noise: a ring of ~55 px radius, so tenths of a degree.
    for name in ["ship-640x480", "offset-640x480"] {
        let (errors, none) = estimate_recording(name);
        assert_eq!(none, 0, "{name}");
        let mut stats = ErrorStats::default();
        errors.iter().for_each(|e| stats.add(*e));
        println!("{name}: RMSE {:?} max {:?}", stats.rmse(), stats.max);
        assert!(
            stats.rmse().iter().all(|&r| r < 0.5),
            "{name}: {:?}",
            stats.rmse()
        );
    }
    // No deck: no attitude, ever.
    let (errors, none) = estimate_recording("nodeck-640x480");
    assert_eq!((errors.len(), none), (0, 3));
}
