//! `deckwatch eval RECORDING...`: detection, then every estimator on the same markers, against
//! the recordings' ground truth: per recording and estimator the RMSE and maximum error of roll,
//! pitch, yaw (and altitude and offset where the estimator gives them), frames without an
//! estimate although a deck was in view, attitudes on frames without a deck, and the cost.

use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::{ErrorStats, Percentiles};
use deckwatch_common::Recording;
use deckwatch_detect::{Detector, DetectorConfig};
use deckwatch_estimate::{PaperEstimator, PaperVariant, PoseConfig, PoseEstimator};
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct EvalArgs {
    /// Recordings (folders with camera.json, frames.csv and frames).
    #[arg(required = true)]
    recordings: Vec<PathBuf>,
    /// Write one row per frame and estimator to this CSV file.
    #[arg(long)]
    csv: Option<PathBuf>,
}

const ESTIMATORS: [&str; 2] = ["full-pose", "paper-atan2"];

#[derive(Default)]
struct Tally {
    frames: usize,
    estimated: usize,
    /// Deck in view (truth) but no estimate.
    missed: usize,
    /// An attitude although no deck was in view.
    false_attitudes: usize,
    angles: ErrorStats,
    /// Altitude error and horizontal offset error (m), full pose only.
    position: ErrorStats,
    cost_us: Vec<f64>,
}

fn fmt3(v: [f64; 3], digits: usize) -> String {
    format!("{:.d$} {:.d$} {:.d$}", v[0], v[1], v[2], d = digits)
}

pub fn run(a: EvalArgs) -> Result<(), String> {
    let mut csv = match &a.csv {
        Some(p) => {
            let mut w = std::io::BufWriter::new(
                std::fs::File::create(p).map_err(|e| format!("{}: cannot create: {e}", p.display()))?,
            );
            writeln!(
                w,
                "recording,index,estimator,valid,roll_deg,pitch_deg,yaw_deg,err_roll_deg,err_pitch_deg,err_yaw_deg,altitude_m,offset_x_m,offset_y_m,std_roll_deg,std_pitch_deg,std_yaw_deg,cost_us"
            )
            .map_err(|e| e.to_string())?;
            Some(w)
        }
        None => None,
    };
    println!(
        "{:<28} {:<12} {:>6} {:>6} {:>6} {:>6} {:>26} {:>26} {:>16} {:>14}",
        "recording",
        "estimator",
        "frames",
        "estim",
        "missed",
        "nodeck",
        "RMSE roll pitch yaw (deg)",
        "max roll pitch yaw (deg)",
        "RMSE alt off (m)",
        "cost p50/p99 us"
    );
    for dir in &a.recordings {
        let rec = Recording::open(dir).map_err(|e| e.to_string())?;
        let knows_deck = rec.has_attitude_truth();
        let (camera, deck) = (rec.camera, rec.deck);
        let mut detector = Detector::new(camera, deck, DetectorConfig::for_camera(&camera, &deck));
        let paper = PaperEstimator::new(camera, deck, PaperVariant::Atan2);
        let pose = PoseEstimator::new(camera, deck, PoseConfig::default());
        let mut tallies: Vec<Tally> = ESTIMATORS.iter().map(|_| Tally::default()).collect();
        let name = dir
            .file_name()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        let mut img = deckwatch_common::GrayImage::new(camera.width as usize, camera.height as usize);
        for f in &rec.frames {
            if let Err(e) = rec.read_image_into(f, &mut img.data) {
                eprintln!("deckwatch eval: skipped: {e}");
                continue;
            }
            let set = detector.detect(img.view());
            let pixels = set.pixels(deck.marker_count());
            let truth = f.truth.attitude();
            for (k, est) in ESTIMATORS.iter().enumerate() {
                let t = &mut tallies[k];
                t.frames += 1;
                let clock = Instant::now();
                let found = if set.count == 0 {
                    None
                } else if *est == "full-pose" {
                    pose.estimate(&pixels, set.perspective_corrected)
                        .ok()
                        .map(|e| (e.attitude.rpy, Some(e.viewpoint), e.rpy_std_deg()))
                } else {
                    paper
                        .estimate(&pixels, f.truth.alt_m)
                        .ok()
                        .map(|e| (e.attitude.rpy, None, [f64::NAN; 3]))
                };
                let cost = clock.elapsed().as_secs_f64() * 1e6;
                if set.count > 0 {
                    t.cost_us.push(cost);
                }
                let mut err = [f64::NAN; 3];
                match (&found, truth) {
                    (Some((rpy, vp, _)), Some(tr)) => {
                        t.estimated += 1;
                        err = rpy_error_deg(rpy, &tr);
                        t.angles.add(err);
                        if let (Some(v), Some(alt), Some(ox), Some(oy)) =
                            (vp, f.truth.alt_m, f.truth.offset_x_m, f.truth.offset_y_m)
                        {
                            let off = (v.offset_x_m - ox).hypot(v.offset_y_m - oy);
                            t.position.add([v.altitude_m - alt, off, 0.0]);
                        }
                    }
                    (Some(_), None) => {
                        t.estimated += 1;
                        if knows_deck {
                            t.false_attitudes += 1;
                        }
                    }
                    (None, Some(_)) => t.missed += 1,
                    (None, None) => {}
                }
                if let Some(w) = &mut csv {
                    let (rpy, vp, sd) = match &found {
                        Some((rpy, vp, sd)) => (rpy.to_degrees(), *vp, *sd),
                        None => ([f64::NAN; 3], None, [f64::NAN; 3]),
                    };
                    let (alt, ox, oy) = vp.map_or((f64::NAN, f64::NAN, f64::NAN), |v| {
                        (v.altitude_m, v.offset_x_m, v.offset_y_m)
                    });
                    writeln!(
                        w,
                        "{name},{},{est},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{alt:.5},{ox:.5},{oy:.5},{:.6},{:.6},{:.6},{cost:.1}",
                        f.index,
                        found.is_some() as u8,
                        rpy[0],
                        rpy[1],
                        rpy[2],
                        err[0],
                        err[1],
                        err[2],
                        sd[0],
                        sd[1],
                        sd[2]
                    )
                    .map_err(|e| e.to_string())?;
                }
            }
        }
        for (est, t) in ESTIMATORS.iter().zip(&mut tallies) {
            let (rmse, max) = if t.angles.n > 0 {
                (fmt3(t.angles.rmse(), 4), fmt3(t.angles.max, 4))
            } else {
                ("-".into(), "-".into())
            };
            let pos = if t.position.n > 0 {
                let r = t.position.rmse();
                format!("{:.4} {:.4}", r[0], r[1])
            } else {
                "-".into()
            };
            let cost =
                Percentiles::of(&mut t.cost_us).map_or("-".into(), |p| format!("{:.1}/{:.1}", p.p50, p.p99));
            println!(
                "{:<28} {:<12} {:>6} {:>6} {:>6} {:>6} {:>26} {:>26} {:>16} {:>14}",
                name, est, t.frames, t.estimated, t.missed, t.false_attitudes, rmse, max, pos, cost
            );
        }
    }
    if let Some(w) = &mut csv {
        w.flush().map_err(|e| e.to_string())?;
    }
    Ok(())
}
