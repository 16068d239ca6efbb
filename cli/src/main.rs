//! `deckwatch`: the command line of the deck-attitude pipeline.
//!
//! - `deckwatch run`: the pipeline as four processes over iceoryx2 (capture, detect, estimate,
//!   decide) on the simulator (default) or a recording, supervised, with a live status line.
//! - `deckwatch latency RECORDING`: per-stage latency of the four processes on recorded frames.
//! - `deckwatch replay FILE.mcap`, `diff`, `convert`, `recover`: flight recordings (MCAP).
//! - `deckwatch inproc`: the same stages in one process, for profiling the algorithms.
//! - `deckwatch soak`: a long run on full-size frames, watching memory and drops.
//! - `deckwatch budget`: each process's CPU and memory per frame at 10 and 30 fps, and on a Pi 5.
//! - `deckwatch sim markers` / `deckwatch estimate-table`: the marker-table tools.
//! - `deckwatch sweep`: simulate a scenario at the level of marker points and run every variant of
//!   the paper's estimator on it, side by side (accuracy and per-frame cost).
//! - `deckwatch sim motion`: a ship-motion model's deck motion as a motion file (`--motion-csv`).
//! - `deckwatch sim record`: render a scenario into a recording with ground truth (optionally
//!   also as frames for libcamera's virtual camera).
//! - `deckwatch cameras`: the cameras libcamera sees, their formats and controls.
//! - `deckwatch recording check DIR`: validate a recording (camera.json, frames.csv, every image).

use clap::{Parser, Subcommand};
use deckwatch_capture::virtual_camera::VirtualCameraWriter;
use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::{ErrorStats, Percentiles};
use deckwatch_common::GrayImage;
use deckwatch_estimate::{PaperEstimator, PaperVariant};
use deckwatch_formats::{Recording, RecordingWriter};
use deckwatch_sim::scenario::SimulationArgs;
use deckwatch_sim::sim::ImageArgs;
use deckwatch_sim::{FrameSimulator, Renderer};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "deckwatch",
    version,
    about = "Deck attitude from camera frames for landing a quadrotor on a ship"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[macro_use]
mod console;
mod budget;
mod calibration;
mod decide_eval;
mod decisions_csv;
mod doctor;
mod eval;
mod flight;
mod inproc;
mod launch;
mod pattern;
mod pipeline;
mod predict_eval;
mod sim_motion;
mod soak;
mod tables;
mod trials;

#[derive(Subcommand)]
enum Command {
    /// Run the pipeline: capture, detect, estimate and decide as supervised processes over
    /// iceoryx2 shared memory, with a live status line; stops on Ctrl-C or at the source's end.
    Run(pipeline::RunArgs),
    /// Replay a recording through the four processes and report per-stage latency and drops.
    Latency(pipeline::LatencyArgs),
    /// Replay a flight recording (FILE.mcap) through the pipeline at its recorded rate (or
    /// `--rate`); `--resim OUT.mcap` re-simulates it in this process on its recorded timing and
    /// compares the outputs with the recorded ones.
    Replay(flight::ReplayArgs),
    /// Where two flight recordings' outputs part: per stage (detect, estimate, decide) and
    /// frame, the fields that differ and by how much. Exit status 1 when they differ.
    Diff(flight::DiffArgs),
    /// Convert a recording folder to a flight recording (MCAP) or back (frames, timestamps,
    /// truth, the vehicle's attitude).
    Convert(flight::ConvertArgs),
    /// Check what a deployment needs with this configuration: the stage binaries, shared
    /// memory, the camera, the MAVLink endpoint, the rerun viewer, the recorder's disk; says
    /// what to fix (exit status 1 when anything needs fixing).
    Doctor(doctor::DoctorArgs),
    /// Complete the flight recording of a recorder that was killed: everything up to its last
    /// complete chunk, with the index MCAP tools expect.
    Recover(flight::RecoverArgs),
    /// The stages in one process, frame by frame (no IPC): per-stage cost and accuracy.
    Inproc(Box<inproc::RunArgs>),
    /// Detection and every estimator on recordings, against their ground truth: RMSE and max
    /// error of the angles (and altitude/offset), misses, attitudes without a deck, cost.
    Eval(eval::EvalArgs),
    /// The pipeline for a long time (default 30 min) at camera rate on 3280x2464 frames (a looped
    /// replay), printing each process's resident memory and the domain's shared memory as it
    /// runs; fails if memory grows or frames are dropped.
    Soak(soak::SoakArgs),
    /// Each process's CPU (user, system), context switches, private and shared memory per frame
    /// at 10 and 30 fps of 3280x2464 frames (a looped replay), and the estimate for a Raspberry
    /// Pi 5.
    Budget(budget::BudgetArgs),
    /// Evaluate the landing decision on long simulated ship-motion series against the truth,
    /// beside the naive rule: unsafe clearances and availability.
    DecideEval(decide_eval::DecideEvalArgs),
    /// Evaluate the deck-motion forecast against the truth: errors at several horizons per sea
    /// state and predictor, and whether each predictor's stated 95 % band holds.
    PredictEval(predict_eval::PredictEvalArgs),
    /// Closed-loop landing trials: a simulated vehicle lands on the spectrum seas through the
    /// stage chain, judged at contact; beside the naive rule and an oracle.
    Trials(trials::TrialsArgs),
    /// Run the paper's estimator on a marker table (CSV), one attitude row per frame.
    EstimateTable(tables::EstimateTableArgs),
    /// Simulate a scenario (exact marker pixels, optional noise) and compare the estimator variants.
    Sweep(Box<SweepArgs>),
    /// The simulator of the paper's scene.
    Sim {
        #[command(subcommand)]
        command: SimCommand,
    },
    /// List the cameras libcamera sees: id, model, the video stream's pixel formats and sizes
    /// (and whether deckwatch reads each), and the frame-rate, exposure and gain controls.
    /// Needs a build with `--features libcamera`.
    Cameras {
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Record frames from the configured camera (`[libcamera]` of the pipeline configuration)
    /// into a recording (camera.json, frames.csv with the frame times, PNGs): for replay,
    /// calibration or a look at what the camera delivers. Needs `--features libcamera`.
    CameraRecord {
        /// Pipeline configuration whose `[libcamera]` section names the camera and its mode.
        #[arg(long)]
        config: Option<std::path::PathBuf>,
        /// Frames to record.
        #[arg(long, default_value_t = 10)]
        frames: u64,
        /// Output folder (must not hold a recording yet).
        #[arg(long)]
        out: std::path::PathBuf,
    },
    /// Camera calibrations from other tools (ROS camera_info, OpenCV FileStorage, Kalibr).
    Calibration {
        #[command(subcommand)]
        command: calibration::CalibrationCommand,
    },
    /// Work with recordings.
    Recording {
        #[command(subcommand)]
        command: RecordingCommand,
    },
    /// The deck's marker pattern as SVG at true scale for printing or painting (`--out`,
    /// `--tile A4` for pages), and `pattern check PHOTO`: a photograph of the printed or
    /// painted pattern measured against the configured layout (exit status 1 when off).
    Pattern(Box<pattern::PatternArgs>),
    /// Remove what a killed launcher left behind in a domain: the shared memory of its dead
    /// processes and the domain, its temporary run folders, and (with `--rerun FILE.rrd`) that
    /// recording's part files. Refuses while a pipeline runs in the domain. `deckwatch run` does
    /// the same for its own domain when it starts.
    Clean {
        /// The iceoryx2 domain.
        #[arg(long, default_value = deckwatch_runtime::bus::DEFAULT_DOMAIN)]
        domain: String,
        /// The `.rrd` of a `--rerun save` run whose parts to remove.
        #[arg(long, value_name = "FILE.rrd")]
        rerun: Option<std::path::PathBuf>,
    },
}

#[derive(Subcommand)]
enum SimCommand {
    /// Render a scenario's frames into a recording (camera.json, frames.csv with ground truth,
    /// 8-bit grayscale PNGs).
    Record(Box<RecordArgs>),
    /// Write a scenario's exact (or noisy) marker pixels with ground truth as a marker table.
    Markers(Box<tables::MarkersArgs>),
    /// Write a ship-motion model's deck motion as a motion file (`--motion-csv` of decide-eval,
    /// predict-eval and trials): `spectrum`, `nonlinear-roll`, `short-crested`, `hull-rao`.
    Motion(Box<sim_motion::MotionArgs>),
}

#[derive(clap::Args)]
struct RecordArgs {
    #[command(flatten)]
    sim: SimulationArgs,
    #[command(flatten)]
    image: ImageArgs,
    /// Sub-exposures sampled for motion blur (with --exposure-ms).
    #[arg(long, default_value_t = 8)]
    exposure_steps: usize,
    /// Output folder (must not hold a recording yet).
    #[arg(long)]
    out: std::path::PathBuf,
    /// Also write the frames as `virtual/frames/0.jpg, 1.jpg, ...` and `virtual/virtual.yaml`, a
    /// libcamera virtual camera with this id that plays them (install the yaml as
    /// /usr/share/libcamera/pipeline/virtual/virtual.yaml; libcamera >= 0.4).
    #[arg(long, value_name = "ID")]
    virtual_camera: Option<String>,
}

fn record(a: RecordArgs) -> Result<(), String> {
    let sim = a.sim.resolve()?;
    let (camera, options) = a.image.resolve(&sim)?;
    let renderer = Renderer::new(camera, sim.deck, options, a.sim.seed)?;
    let mut frames = FrameSimulator::new(
        a.sim.profile(),
        renderer,
        a.sim.rate,
        a.image.exposure_ms / 1e3,
        a.exposure_steps,
        a.sim.seed,
    )?;
    // camera.json holds the calibration the pipeline is told (the frames are the lens's).
    let mut writer = RecordingWriter::create(
        &a.out,
        &a.image.calibrated(&camera),
        &sim.deck,
        a.sim.truth_columns(),
    )
    .map_err(|e| e.to_string())?;
    let mut virtual_camera = a
        .virtual_camera
        .as_deref()
        .map(|id| VirtualCameraWriter::create(&a.out.join("virtual"), id))
        .transpose()
        .map_err(|e| e.to_string())?;
    let mut img = GrayImage::new(camera.width as usize, camera.height as usize);
    let bar = indicatif::ProgressBar::new(a.sim.frames as u64).with_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} frames, {per_sec}, eta {eta}")
            .expect("valid template"),
    );
    bar.set_message(format!("recording {}", a.out.display()));
    let started = Instant::now();
    let mut render_s = 0.0;
    let mut no_deck = 0;
    for k in 0..a.sim.frames as u64 {
        let t0 = Instant::now();
        let truth = frames
            .render_frame(k, &mut img.view_mut())
            .map_err(|e| format!("frame {k}: {e}"))?;
        render_s += t0.elapsed().as_secs_f64();
        no_deck += usize::from(!truth.deck_in_view);
        writer
            .write_frame(k, truth.timestamp_ns, img.view(), &truth.ground_truth())
            .map_err(|e| e.to_string())?;
        if let Some(v) = &mut virtual_camera {
            v.write_frame(img.view()).map_err(|e| format!("frame {k}: {e}"))?;
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    // The autopilot's view of a vehicle that is not level, over the frames' span and a period
    // beyond (interpolation needs a sample after the last frame).
    if a.sim.vehicle != deckwatch_sim::scenario::VehicleMotion::Level {
        let end_s = a.sim.frames as f64 / a.sim.rate + 0.1;
        let samples = a
            .sim
            .autopilot
            .samples(a.sim.profile().as_ref(), end_s, a.sim.seed);
        if !samples.is_empty() {
            deckwatch_formats::recording::write_vehicle_csv(&a.out, &samples).map_err(|e| e.to_string())?;
            errln!(
                "vehicle.csv: {} autopilot samples at {} Hz (noise {} deg, bias {:?} deg, time error {} ms)",
                samples.len(),
                a.sim.autopilot.rate_hz,
                a.sim.autopilot.noise_deg,
                a.sim.autopilot.bias_deg,
                a.sim.autopilot.time_error_ms
            );
        }
    }
    let n = writer.finish().map_err(|e| e.to_string())?;
    errln!(
        "wrote {n} frames ({}x{}, {} without deck) to {} in {:.1} s; rendering {:.1} ms/frame",
        camera.width,
        camera.height,
        no_deck,
        a.out.display(),
        started.elapsed().as_secs_f64(),
        1e3 * render_s / n.max(1) as f64
    );
    if let Some(v) = virtual_camera {
        let yaml = v.finish(a.sim.rate).map_err(|e| e.to_string())?;
        errln!(
            "virtual camera: {} (with {n} JPEG frames beside it)",
            yaml.display()
        );
    }
    Ok(())
}

fn camera_record(
    config: Option<std::path::PathBuf>,
    frames: u64,
    out: &std::path::Path,
) -> Result<(), String> {
    let (mut c, _) = pipeline::load(config.as_deref())?;
    c.source.kind = deckwatch_common::messages::FrameSource::Libcamera;
    c.libcamera.frames = frames;
    let mut source = c.capture().open().map_err(|e| e.to_string())?;
    errln!("{}", source.describe());
    let (camera, deck) = (*source.camera(), *source.deck());
    let mut writer = RecordingWriter::create(out, &camera, &deck, deckwatch_formats::recording::NO_TRUTH)
        .map_err(|e| e.to_string())?;
    let mut img = GrayImage::new(camera.width as usize, camera.height as usize);
    let (mut k, mut bad) = (0, 0);
    while k < frames {
        if !source
            .wait_ready(std::time::Duration::from_millis(100))
            .map_err(|e| e.to_string())?
        {
            continue;
        }
        let width = img.width;
        match source.capture(k, &mut img.data, width) {
            Ok(f) => {
                writer
                    .write_frame(k, f.source_timestamp_ns, img.view(), &f.truth)
                    .map_err(|e| e.to_string())?;
                k += 1;
            }
            Err(e) => {
                bad += 1;
                errln!("frame skipped: {e}");
            }
        }
    }
    let n = writer.finish().map_err(|e| e.to_string())?;
    errln!("wrote {n} frames to {} ({bad} bad frames skipped)", out.display());
    Ok(())
}

fn cameras(json: bool) -> Result<(), String> {
    let (version, cameras) = deckwatch_capture::camera::list_cameras().map_err(|e| e.to_string())?;
    if json {
        let doc = serde_json::json!({ "libcamera": version, "cameras": cameras });
        outln!(
            "{}",
            serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())?
        );
        return Ok(());
    }
    outln!("libcamera {version}: {} camera(s)", cameras.len());
    for c in &cameras {
        out!("{c}");
    }
    if cameras.is_empty() {
        outln!("(none: is the camera connected, enabled and not held by another process?)");
    }
    Ok(())
}

#[derive(Subcommand)]
enum RecordingCommand {
    /// Read camera.json, frames.csv and decode every image; report the first problem with its
    /// file, line and field.
    Check { dir: std::path::PathBuf },
}

#[derive(clap::Args)]
struct SweepArgs {
    #[command(flatten)]
    sim: SimulationArgs,
    /// Gaussian pixel noise on the marker centres (standard deviation per axis, pixels).
    #[arg(long, default_value_t = 0.0)]
    noise_px: f64,
    /// Relative altimeter error, e.g. 0.001 for a reading 0.1 % high.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    altimeter_error: f64,
}

fn sweep(a: SweepArgs) -> Result<(), String> {
    let sim = a.sim.resolve()?;
    if !(a.altimeter_error.is_finite() && a.altimeter_error > -1.0) {
        return Err(format!(
            "--altimeter-error: must be > -1, got {}",
            a.altimeter_error
        ));
    }
    let rows = a.sim.marker_rows(&sim, a.noise_px)?;
    outln!(
        "scenario {}, camera {}, {} frames at {} Hz, seed {}, pixel noise {} px, altimeter error {:+.3} %",
        sim.scenario.name(),
        sim.camera_name,
        a.sim.frames,
        a.sim.rate,
        a.sim.seed,
        a.noise_px,
        100.0 * a.altimeter_error
    );
    outln!(
        "{:<18} {:>10}  {:>30}  {:>30}  {:>17}",
        "variant",
        "estimated",
        "RMSE roll/pitch/yaw (deg)",
        "max roll/pitch/yaw (deg)",
        "us p50/p99"
    );
    for v in PaperVariant::ALL {
        let est = PaperEstimator::new(sim.camera, sim.deck, v);
        let mut stats = ErrorStats::default();
        let mut times = Vec::with_capacity(rows.len());
        for row in &rows {
            let alt = row.truth.alt_m.map(|h| h * (1.0 + a.altimeter_error));
            let t0 = Instant::now();
            let r = est.estimate(&row.markers, alt);
            times.push(t0.elapsed().as_secs_f64() * 1e6);
            if let (Ok(e), Some(truth)) = (r, row.truth.attitude()) {
                stats.add(rpy_error_deg(&e.attitude.rpy, &truth));
            }
        }
        let [r0, r1, r2] = stats.rmse();
        let [m0, m1, m2] = stats.max;
        let t = Percentiles::of(&mut times).expect("at least one frame");
        outln!(
            "{:<18} {:>10}  {:>9.2e} {:>9.2e} {:>9.2e}  {:>9.2e} {:>9.2e} {:>9.2e}  {:>8.1} {:>8.1}",
            v.name(),
            format!("{}/{}", stats.n, rows.len()),
            r0,
            r1,
            r2,
            m0,
            m1,
            m2,
            t.p50,
            t.p99
        );
    }
    Ok(())
}

fn check_recording(dir: &std::path::Path) -> Result<(), String> {
    let rec = Recording::open(dir).map_err(|e| e.to_string())?;
    let mut img = deckwatch_common::GrayImage::new(rec.camera.width as usize, rec.camera.height as usize);
    for f in &rec.frames {
        rec.read_image_into(f, &mut img.data)
            .map_err(|e| format!("{e} (frames.csv line {})", f.line))?;
    }
    let no_deck = rec.frames.iter().filter(|f| f.truth.attitude().is_none()).count();
    outln!(
        "{}: {} frames of {}x{} (fx {:.2}, fy {:.2}), deck {} ring markers on {} m; attitude truth: {}",
        dir.display(),
        rec.frames.len(),
        rec.camera.width,
        rec.camera.height,
        rec.camera.fx,
        rec.camera.fy,
        rec.deck.n_ring,
        rec.deck.ring_radius_m,
        if rec.has_attitude_truth() {
            format!("yes ({no_deck} frames without deck)")
        } else {
            "no".into()
        }
    );
    Ok(())
}

/// Whether a command only reports (reads files or simulates, writes what it found): such a command
/// piped into `head` ends with its reader. The launcher's commands (`run`, `replay`, `latency`,
/// `soak`, `budget`, `camera-record`, `clean`) supervise processes or shared memory and keep
/// Rust's default, the signal ignored: they run to their end and shut down as they should, their
/// lines to the closed pipe dropped (`console`); `trials` may run a cluster.
fn is_report(command: &Command) -> bool {
    matches!(
        command,
        Command::Diff(_)
            | Command::Convert(_)
            | Command::Recover(_)
            | Command::Doctor(_)
            | Command::Inproc(_)
            | Command::DecideEval(_)
            | Command::PredictEval(_)
            | Command::Eval(_)
            | Command::EstimateTable(_)
            | Command::Sweep(_)
            | Command::Sim { .. }
            | Command::Recording { .. }
            | Command::Calibration { .. }
            | Command::Cameras { .. }
            | Command::Pattern(_)
    )
}

/// A report whose reader has gone (`deckwatch eval REC | head -1`) ends there, as Unix tools do:
/// the pipe's signal keeps its default action. Rust ignores it, and a report would go on computing
/// what nobody reads.
fn end_with_a_closed_pipe() {
    // SAFETY: `signal` with a valid signal number and `SIG_DFL`, called at start-up on the main
    // thread before any other thread or handler exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if is_report(&cli.command) {
        end_with_a_closed_pipe();
    }
    let result = match cli.command {
        Command::Run(a) => pipeline::run(a),
        Command::Latency(a) => pipeline::latency(a),
        Command::Replay(a) => flight::replay(a),
        Command::Diff(a) => match flight::diff_command(a) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::from(1),
            Err(e) => Err(e),
        },
        Command::Convert(a) => flight::convert(a),
        Command::Recover(a) => flight::recover(a),
        Command::Doctor(a) => match doctor::run(a) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::from(1),
            Err(e) => Err(e),
        },
        Command::Inproc(a) => inproc::run(*a),
        Command::DecideEval(a) => decide_eval::run(a),
        Command::PredictEval(a) => predict_eval::run(a),
        Command::Trials(a) => match &a.command {
            Some(trials::TrialsCommand::Merge(m)) => trials::merge(m),
            None => trials::run(a),
        },
        Command::Soak(a) => soak::run(a),
        Command::Budget(a) => budget::run(a),
        Command::Eval(a) => eval::run(a),
        Command::EstimateTable(a) => match tables::estimate_table(a) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::from(2), // finished, but some rows were bad
            Err(e) => Err(e),
        },
        Command::Sim {
            command: SimCommand::Markers(a),
        } => tables::markers(*a),
        Command::Sweep(a) => sweep(*a),
        Command::Sim {
            command: SimCommand::Record(a),
        } => record(*a),
        Command::Sim {
            command: SimCommand::Motion(a),
        } => sim_motion::run(*a),
        Command::Recording {
            command: RecordingCommand::Check { dir },
        } => check_recording(&dir),
        Command::Calibration { command } => calibration::run(command),
        Command::Cameras { json } => cameras(json),
        Command::Clean { domain, rerun } => launch::clean(&domain, rerun.as_deref()).map(|c| {
            outln!(
                "domain `{domain}`: {} dead processes' resources removed{}",
                c.dead_nodes,
                if c.domain_removed {
                    ", the domain removed"
                } else {
                    ""
                }
            );
            for p in &c.paths {
                outln!("removed {}", p.display());
            }
        }),
        Command::CameraRecord { config, frames, out } => camera_record(config, frames, &out),
        Command::Pattern(a) => match pattern::run(*a) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::from(1),
            Err(e) => Err(e),
        },
    };
    match result.and_then(|()| match console::lost_output() {
        Some(e) => Err(format!("the output is incomplete: writing it failed ({e})")),
        None => Ok(()),
    }) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            errln!("deckwatch: {e}");
            ExitCode::FAILURE
        }
    }
}
