//! `deckwatch inproc`: the pipeline in one process, frame by frame: capture (simulator or replay of
//! a recording) -> detect -> estimate, with per-stage timing and, where the source knows it,
//! accuracy against the ground truth: for profiling and debugging the algorithms without IPC (the
//! same library calls as the stage processes of `deckwatch run`).

use deckwatch_capture::scenario::SimulationArgs;
use deckwatch_capture::sim::ImageArgs;
use deckwatch_capture::source::{CaptureConfig, ReplayConfig, SourceConfig};
use deckwatch_common::markers::DetectionStatus;
use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::{ErrorStats, Percentiles};
use deckwatch_common::GrayImage;
use deckwatch_detect::{Detector, DetectorConfig};
use deckwatch_estimate::{PaperEstimator, PaperVariant};
use std::time::Instant;

#[derive(clap::Args)]
pub struct RunArgs {
    /// Frame source: `sim` (the simulator) or `replay` (a recording, see --recording).
    #[arg(long, default_value = "sim")]
    source: String,
    /// The recording to replay (with --source replay).
    #[arg(long)]
    recording: Option<std::path::PathBuf>,
    #[command(flatten)]
    sim: SimulationArgs,
    #[command(flatten)]
    image: ImageArgs,
    /// Estimator variant: printed, fitted-major-axis, atan2.
    #[arg(long, default_value = "atan2")]
    variant: String,
    /// Print one line every this many frames (0: summary only).
    #[arg(long, default_value_t = 10)]
    every: usize,
}

pub fn run(a: RunArgs) -> Result<(), String> {
    let variant = PaperVariant::from_name(&a.variant).ok_or_else(|| {
        format!(
            "--variant: unknown `{}` (printed, fitted-major-axis, atan2)",
            a.variant
        )
    })?;
    // The capture stage's own sources: replay as fast as possible, decoding frame by frame.
    if a.source == "replay" && a.recording.is_none() {
        return Err("--source replay needs --recording DIR".into());
    }
    let config = CaptureConfig {
        source: SourceConfig {
            kind: a.source.clone(),
            altimeter: true,
        },
        sim: a.sim.clone(),
        image: a.image.clone(),
        replay: ReplayConfig {
            recording: a.recording.clone(),
            rate_hz: Some(0.0),
            preload: false,
            ..ReplayConfig::default()
        },
        libcamera: Default::default(),
    };
    let mut source = config.open()?;
    let (camera, deck) = (*source.camera(), *source.deck());
    let n_frames = source.len().unwrap_or(0);
    match a.source.as_str() {
        "sim" => println!(
            "source: simulator, scenario {}, {}x{} ({}), {} frames at {} Hz, look {}",
            a.sim.scenario,
            camera.width,
            camera.height,
            a.sim.camera.as_deref().unwrap_or("the scenario's camera"),
            n_frames,
            a.sim.rate,
            a.image.look
        ),
        _ => println!(
            "source: replay of {} ({} frames, {}x{})",
            a.recording
                .as_ref()
                .map_or(String::new(), |d| d.display().to_string()),
            n_frames,
            camera.width,
            camera.height
        ),
    }
    let mut detector = Detector::new(camera, deck, DetectorConfig::for_camera(&camera, &deck));
    let estimator = PaperEstimator::new(camera, deck, variant);
    let mut img = GrayImage::new(camera.width as usize, camera.height as usize);
    let (mut t_capture, mut t_detect, mut t_estimate) = (Vec::new(), Vec::new(), Vec::new());
    let mut accuracy = ErrorStats::default();
    let (
        mut frames,
        mut bad,
        mut ok,
        mut partial,
        mut no_deck,
        mut tracked,
        mut estimated,
        mut false_attitudes,
    ) = (0, 0, 0, 0, 0, 0, 0, 0);
    for k in 0..n_frames {
        let t0 = Instant::now();
        let captured = match source.capture(k, &mut img.data, camera.width as usize) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("skipped a bad frame: {e}");
                bad += 1;
                continue;
            }
        };
        let t1 = Instant::now();
        let set = detector.detect(img.view());
        let t2 = Instant::now();
        let estimate = match set.status {
            DetectionStatus::Ok | DetectionStatus::Partial => estimator
                .estimate(&set.pixels(deck.marker_count()), captured.truth.alt_m)
                .ok(),
            _ => None,
        };
        let t3 = Instant::now();
        t_capture.push((t1 - t0).as_secs_f64() * 1e3);
        t_detect.push((t2 - t1).as_secs_f64() * 1e3);
        t_estimate.push((t3 - t2).as_secs_f64() * 1e3);
        frames += 1;
        match set.status {
            DetectionStatus::Ok => ok += 1,
            DetectionStatus::Partial => partial += 1,
            _ => no_deck += 1,
        }
        tracked += usize::from(set.tracked);
        let truth = captured.truth.attitude();
        let err = match (&estimate, truth) {
            (Some(e), Some(t)) => {
                let err = rpy_error_deg(&e.attitude.rpy, &t);
                accuracy.add(err);
                Some(err)
            }
            // The source says no deck was in view, yet an attitude came out.
            (Some(_), None) if captured.truth_known => {
                false_attitudes += 1;
                None
            }
            _ => None,
        };
        estimated += usize::from(estimate.is_some());
        if a.every > 0 && frames % a.every == 1 {
            let att = estimate.map_or("no attitude".to_string(), |e| {
                let [r, p, y] = e.attitude.rpy.to_degrees();
                format!("roll {r:+7.3} pitch {p:+7.3} yaw {y:+7.3} deg")
            });
            let err = err.map_or(String::new(), |e| {
                format!(", error {:.3}/{:.3}/{:.3}", e[0], e[1], e[2])
            });
            println!(
                "frame {:5} t {:8.3} s: {:?} {} markers{} | {att}{err}",
                captured.source_index,
                captured.source_timestamp_ns as f64 / 1e9,
                set.status,
                set.count,
                if set.tracked { " (tracked)" } else { "" },
            );
        }
    }
    println!(
        "{frames} frames ({bad} bad, skipped): {ok} ok, {partial} partial, {no_deck} no deck; {tracked} tracked; \
         {estimated} attitudes"
    );
    if accuracy.n > 0 {
        let (r, m) = (accuracy.rmse(), accuracy.max);
        println!(
            "attitude error vs ground truth ({} frames): RMSE roll {:.4} pitch {:.4} yaw {:.4} deg, max {:.4} {:.4} {:.4}",
            accuracy.n, r[0], r[1], r[2], m[0], m[1], m[2]
        );
    }
    if false_attitudes > 0 {
        println!("WARNING: {false_attitudes} attitudes on frames without a deck in view");
    }
    for (stage, times) in [
        ("capture", &mut t_capture),
        ("detect", &mut t_detect),
        ("estimate", &mut t_estimate),
    ] {
        if let Some(p) = Percentiles::of(times) {
            println!(
                "{stage:>9}: p50 {:8.3} ms  p90 {:8.3} ms  p99 {:8.3} ms  max {:8.3} ms",
                p.p50, p.p90, p.p99, p.max
            );
        }
    }
    if frames == 0 {
        return Err("no frame could be processed".into());
    }
    Ok(())
}
