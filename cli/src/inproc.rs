//! `deckwatch inproc`: the pipeline in one process, frame by frame: capture (simulator or replay of
//! a recording) -> detect -> estimate, with per-stage timing and, where the source knows it,
//! accuracy against the ground truth: for profiling and debugging the algorithms without IPC (the
//! same library calls as the stage processes of `deckwatch run`).

use deckwatch_capture::scenario::SimulationArgs;
use deckwatch_capture::sim::ImageArgs;
use deckwatch_capture::{FrameSimulator, Renderer};
use deckwatch_common::markers::DetectionStatus;
use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::{ErrorStats, Percentiles};
use deckwatch_common::{CameraModel, DeckLayout, GrayImage, GroundTruth, Recording};
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

enum Source {
    Sim(Box<FrameSimulator>, u64, u64),
    Replay(Recording, usize),
}

/// One captured frame's metadata.
struct Captured {
    index: u64,
    timestamp_ns: u64,
    truth: GroundTruth,
}

impl Source {
    /// The next frame into `img`; Some(Err) for a frame that could not be read (it is skipped).
    fn next(&mut self, img: &mut GrayImage) -> Option<Result<Captured, String>> {
        match self {
            Source::Sim(sim, k, n) => {
                if *k >= *n {
                    return None;
                }
                let index = *k;
                *k += 1;
                Some(
                    sim.render_frame(index, &mut img.view_mut())
                        .map_err(|e| e.to_string())
                        .map(|t| Captured {
                            index,
                            timestamp_ns: t.timestamp_ns,
                            truth: t.ground_truth(),
                        }),
                )
            }
            Source::Replay(rec, k) => {
                let f = rec.frames.get(*k)?.clone();
                *k += 1;
                Some(
                    rec.read_image_into(&f, &mut img.data)
                        .map_err(|e| e.to_string())
                        .map(|_| Captured {
                            index: f.index,
                            timestamp_ns: f.timestamp_ns,
                            truth: f.truth,
                        }),
                )
            }
        }
    }
}

pub fn run(a: RunArgs) -> Result<(), String> {
    let variant = PaperVariant::from_name(&a.variant).ok_or_else(|| {
        format!(
            "--variant: unknown `{}` (printed, fitted-major-axis, atan2)",
            a.variant
        )
    })?;
    let (mut source, camera, deck): (Source, CameraModel, DeckLayout) = match a.source.as_str() {
        "sim" => {
            let sim = a.sim.resolve()?;
            let (camera, options) = a.image.resolve(&sim)?;
            let renderer = Renderer::new(camera, sim.deck, options, a.sim.seed)?;
            let frames = FrameSimulator::new(
                sim.scenario.profile(a.sim.seed),
                renderer,
                a.sim.rate,
                a.image.exposure_ms / 1e3,
                8,
                a.sim.seed,
            )?;
            println!(
                "source: simulator, scenario {}, {}x{} ({}), {} frames at {} Hz, look {}",
                sim.scenario.name(),
                camera.width,
                camera.height,
                sim.camera_name,
                a.sim.frames,
                a.sim.rate,
                a.image.look
            );
            (
                Source::Sim(Box::new(frames), 0, a.sim.frames as u64),
                camera,
                sim.deck,
            )
        }
        "replay" => {
            let dir = a
                .recording
                .as_ref()
                .ok_or("--source replay needs --recording DIR")?;
            let rec = Recording::open(dir).map_err(|e| e.to_string())?;
            println!(
                "source: replay of {} ({} frames, {}x{})",
                dir.display(),
                rec.frames.len(),
                rec.camera.width,
                rec.camera.height
            );
            let (camera, deck) = (rec.camera, rec.deck);
            (Source::Replay(rec, 0), camera, deck)
        }
        other => return Err(format!("--source: unknown `{other}` (sim, replay)")),
    };
    // Whether a missing attitude truth means "no deck in view" (not merely "unknown").
    let knows_deck = match &source {
        Source::Sim(..) => true,
        Source::Replay(rec, _) => rec.has_attitude_truth(),
    };
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
    loop {
        let t0 = Instant::now();
        let Some(captured) = source.next(&mut img) else {
            break;
        };
        let captured = match captured {
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
            (Some(_), None) if knows_deck => {
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
                captured.index,
                captured.timestamp_ns as f64 / 1e9,
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
