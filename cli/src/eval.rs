//! `deckwatch eval RECORDING...`: detection, then every estimator on the same markers, against
//! the recordings' ground truth: per recording and estimator the RMSE and maximum error of roll,
//! pitch, yaw (and altitude and offset where the estimator gives them), frames without an
//! estimate although a deck was in view, attitudes on frames without a deck, and the cost. It
//! runs the pipeline's stage chain (`deckwatch_runtime::chain`) on each recording.

use deckwatch_capture::source::ReplayConfig;
use deckwatch_common::messages::{EstimatorKind, FrameSource, PipelineStage};
use deckwatch_common::rotation::rpy_signed_error_deg;
use deckwatch_common::stats::{ErrorStats, Percentiles};
use deckwatch_common::vehicle::Compensation;
use deckwatch_estimate::EstimateConfig;
use deckwatch_runtime::chain::StageChain;
use deckwatch_runtime::config::PipelineConfig;
use deckwatch_runtime::stage::Stage;
use deckwatch_runtime::stages::EstimateStage;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct EvalArgs {
    /// Recordings (folders with camera.json, frames.csv and frames).
    #[arg(required = true)]
    recordings: Vec<PathBuf>,
    /// Write one row per frame and estimator to this CSV file (`err_*_deg`: the estimate less the
    /// truth, with its sign).
    #[arg(long)]
    csv: Option<PathBuf>,
}

const ESTIMATORS: [EstimatorKind; 2] = [EstimatorKind::FullPose, EstimatorKind::PaperAtan2];

/// One row of the table per recording: an estimator and whether it corrects for a rolling
/// shutter. A rolling-shutter recording gets the full pose twice, with and without.
fn rows(rolling_shutter: bool) -> Vec<(String, EstimateConfig)> {
    let config = |estimator, rolling_shutter| EstimateConfig {
        estimator,
        compare: false,
        rolling_shutter,
    };
    let mut rows: Vec<(String, EstimateConfig)> = ESTIMATORS
        .iter()
        .map(|&k| (k.name().to_string(), config(k, true)))
        .collect();
    if rolling_shutter {
        rows.insert(1, ("full-pose-gs".into(), config(EstimatorKind::FullPose, false)));
    }
    rows
}

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
    /// Deck height (heave) error (m): where the recording has the vehicle's height.
    heave: ErrorStats,
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
                "recording,index,estimator,valid,roll_deg,pitch_deg,yaw_deg,err_roll_deg,err_pitch_deg,err_yaw_deg,altitude_m,offset_x_m,offset_y_m,deck_height_m,truth_heave_m,std_roll_deg,std_pitch_deg,std_yaw_deg,cost_us"
            )
            .map_err(|e| e.to_string())?;
            Some(w)
        }
        None => None,
    };
    outln!(
        "{:<28} {:<12} {:>6} {:>6} {:>6} {:>6} {:>26} {:>26} {:>22} {:>14}",
        "recording",
        "estimator",
        "frames",
        "estim",
        "missed",
        "nodeck",
        "RMSE roll pitch yaw (deg)",
        "max roll pitch yaw (deg)",
        "RMSE alt off heave (m)",
        "cost p50/p99 us"
    );
    for dir in &a.recordings {
        // The stage chain on the recording, the first estimator as the chain's own; the others
        // run as estimate stages of their own on the same markers.
        let mut config = PipelineConfig::default();
        config.source.kind = FrameSource::Replay;
        config.replay = ReplayConfig {
            recording: Some(dir.clone()),
            rate_hz: Some(0.0),
            preload: false,
            ..ReplayConfig::default()
        };
        let rolling =
            deckwatch_formats::recording::read_camera_json(dir).is_ok_and(|(c, _)| c.readout_s > 0.0);
        let rows = rows(rolling);
        config.estimate = rows[0].1.clone();
        let mut chain = StageChain::new(&config).map_err(|e| e.to_string())?;
        let mut others: Vec<EstimateStage> = rows[1..]
            .iter()
            .map(|(_, c)| EstimateStage::new(c, &config.vehicle, false))
            .collect();
        let mut tallies: Vec<Tally> = rows.iter().map(|_| Tally::default()).collect();
        let name = dir
            .file_name()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        for out in chain.by_ref() {
            let out = match out {
                Ok(o) => o,
                Err(e) => {
                    errln!("deckwatch eval: skipped: {e}");
                    continue;
                }
            };
            let markers = &out.markers;
            let f = &markers.context;
            let truth = f.truth.attitude();
            let cost = out.cost_of(PipelineStage::Estimate);
            let mut results = vec![(out.attitude, cost.as_secs_f64() * 1e6)];
            for stage in &mut others {
                let clock = Instant::now();
                let a = stage.step(markers, 0);
                results.push((a, clock.elapsed().as_secs_f64() * 1e6));
            }
            for (((est, _), t), (a, cost)) in rows.iter().zip(&mut tallies).zip(results) {
                t.frames += 1;
                if markers.markers.count > 0 {
                    t.cost_us.push(cost);
                }
                let mut err = [f64::NAN; 3];
                let [x, y, z] = a.camera_position_m;
                // An attitude not compensated for the vehicle is not the deck's: a miss.
                let usable = a.valid.get() && a.vehicle.compensation != Compensation::Missing;
                match (usable, truth) {
                    (true, Some(tr)) => {
                        t.estimated += 1;
                        // Signed in the CSV; the RMSE and the largest error are the same.
                        err = rpy_signed_error_deg(&a.rpy, &tr);
                        t.angles.add(err);
                        let tr = &f.truth;
                        if z.is_finite() && tr.altitude_m.is_finite() && tr.offset_x_m.is_finite() {
                            let off = (x - tr.offset_x_m).hypot(y - tr.offset_y_m);
                            t.position.add([z - tr.altitude_m, off, 0.0]);
                        }
                        if a.deck_height_m.is_finite() && tr.deck_heave_m.is_finite() {
                            t.heave.add([a.deck_height_m - tr.deck_heave_m, 0.0, 0.0]);
                        }
                    }
                    (true, None) => {
                        t.estimated += 1;
                        if f.truth.known.get() {
                            t.false_attitudes += 1;
                        }
                    }
                    (false, Some(_)) => t.missed += 1,
                    (false, None) => {}
                }
                if let Some(w) = &mut csv {
                    let (rpy, sd) = if a.valid.get() {
                        (a.rpy.to_degrees(), a.rpy_std_deg)
                    } else {
                        ([f64::NAN; 3], [f64::NAN; 3])
                    };
                    writeln!(
                        w,
                        "{name},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{z:.5},{x:.5},{y:.5},{:.5},{:.5},{:.6},{:.6},{:.6},{cost:.1}",
                        f.source_index,
                        est,
                        a.valid.get() as u8,
                        rpy[0],
                        rpy[1],
                        rpy[2],
                        err[0],
                        err[1],
                        err[2],
                        a.deck_height_m,
                        f.truth.deck_heave_m,
                        sd[0],
                        sd[1],
                        sd[2]
                    )
                    .map_err(|e| e.to_string())?;
                }
            }
        }
        for ((est, _), t) in rows.iter().zip(&mut tallies) {
            let (rmse, max) = if t.angles.n > 0 {
                (fmt3(t.angles.rmse(), 4), fmt3(t.angles.max, 4))
            } else {
                ("-".into(), "-".into())
            };
            let pos = if t.position.n > 0 {
                let r = t.position.rmse();
                let heave = if t.heave.n > 0 {
                    format!("{:.4}", t.heave.rmse()[0])
                } else {
                    "-".into()
                };
                format!("{:.4} {:.4} {heave}", r[0], r[1])
            } else {
                "-".into()
            };
            let cost =
                Percentiles::of(&mut t.cost_us).map_or("-".into(), |p| format!("{:.1}/{:.1}", p.p50, p.p99));
            outln!(
                "{:<28} {:<12} {:>6} {:>6} {:>6} {:>6} {:>26} {:>26} {:>22} {:>14}",
                name,
                est,
                t.frames,
                t.estimated,
                t.missed,
                t.false_attitudes,
                rmse,
                max,
                pos,
                cost
            );
        }
    }
    if let Some(w) = &mut csv {
        w.flush().map_err(|e| e.to_string())?;
    }
    Ok(())
}
