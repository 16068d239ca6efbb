//! `deckwatch inproc`: the pipeline in one process, frame by frame, through the same stage chain
//! as the processes of `deckwatch run` (`deckwatch_runtime::chain`): capture (simulator or
//! replay of a recording, as fast as the stages go) -> detect -> estimate -> decide, with
//! per-stage cost and, where the source knows it, accuracy against the ground truth. For
//! profiling and debugging the algorithms without IPC.

use crate::decisions_csv::DecisionsCsv;
use deckwatch_common::markers::DetectionStatus;
use deckwatch_common::messages::{DecisionState, EstimatorKind, FrameSource, PipelineStage, SOURCE, STAGES};
use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::{ErrorStats, Percentiles};
use deckwatch_estimate::paper::PaperVariant;
use deckwatch_runtime::chain::StageChain;
use deckwatch_sim::scenario::SimulationArgs;
use deckwatch_sim::sim::ImageArgs;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct RunArgs {
    /// Pipeline configuration (TOML) for the estimator, the decision and the replay; the
    /// simulation comes from the options below.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Frame source: `sim` (the simulator) or `replay` (a recording, see --recording).
    #[arg(long, default_value = "sim")]
    source: String,
    /// The recording to replay (with --source replay).
    #[arg(long)]
    recording: Option<PathBuf>,
    #[command(flatten)]
    sim: SimulationArgs,
    #[command(flatten)]
    image: ImageArgs,
    /// The estimator (default: the configuration's, full-pose).
    #[arg(long, value_parser = EstimatorKind::parse)]
    estimator: Option<EstimatorKind>,
    /// Shorthand for `--estimator paper-VARIANT` (printed, fitted-major-axis, atan2).
    #[arg(long, conflicts_with = "estimator", value_parser = PaperVariant::parse)]
    variant: Option<PaperVariant>,
    /// Write every decision as a CSV row to this file (the columns of `deckwatch run`'s).
    #[arg(long)]
    decisions: Option<PathBuf>,
    /// Print one line every this many frames (0: summary only).
    #[arg(long, default_value_t = 10)]
    every: usize,
}

pub fn run(a: RunArgs) -> Result<(), String> {
    let (mut config, _) = crate::pipeline::load(a.config.as_deref())?;
    config.sim = a.sim.clone();
    config.image = a.image.clone();
    match a.source.as_str() {
        "sim" => config.source.kind = FrameSource::Simulator,
        "replay" => {
            config.source.kind = FrameSource::Replay;
            if a.recording.is_some() {
                config.replay.recording = a.recording.clone();
            }
            if config.replay.recording.is_none() {
                return Err("--source replay needs --recording DIR".into());
            }
            // As fast as the stages go, decoding frame by frame.
            config.replay.rate_hz = Some(0.0);
            config.replay.preload = false;
        }
        other => return Err(format!("--source: unknown `{other}` (sim, replay)")),
    }
    if let Some(k) = a.estimator {
        config.estimate.estimator = k;
    }
    if let Some(v) = a.variant {
        let paper = |k: &EstimatorKind| deckwatch_estimate::config::paper_variant(*k) == Some(v);
        config.estimate.estimator = EstimatorKind::ALL.into_iter().find(paper).unwrap_or_default();
    }
    let mut csv = a.decisions.as_deref().map(DecisionsCsv::create).transpose()?;
    let mut chain = StageChain::new(&config).map_err(|e| e.to_string())?;
    let camera = *chain.source().camera();
    outln!(
        "source: {}, {}x{}; estimator {}",
        chain.source().describe(),
        camera.width,
        camera.height,
        config.estimate.estimator.name()
    );
    let mut costs: [Vec<f64>; 1 + STAGES] = Default::default();
    let mut accuracy = ErrorStats::default();
    let mut leaving = 0;
    let (mut frames, mut ok, mut partial, mut no_deck, mut tracked, mut estimated, mut false_attitudes) =
        (0, 0, 0, 0, 0, 0, 0);
    let mut states = [0u64; DecisionState::ALL.len()];
    for out in chain.by_ref() {
        let out = match out {
            Ok(o) => o,
            Err(e) => {
                errln!("skipped a bad frame: {e}");
                continue;
            }
        };
        for (c, d) in costs.iter_mut().zip(out.cost) {
            c.push(d.as_secs_f64() * 1e3);
        }
        if let Some(w) = &mut csv {
            w.write(&out.decision)?;
        }
        frames += 1;
        let set = &out.markers.markers;
        match set.status.get() {
            DetectionStatus::Ok => ok += 1,
            DetectionStatus::Partial => partial += 1,
            _ => no_deck += 1,
        }
        tracked += usize::from(set.tracked.get());
        leaving += usize::from(set.out_of_view != 0);
        if let Some(i) = DecisionState::ALL.iter().position(|s| *s == out.decision.state) {
            states[i] += 1;
        }
        let a_msg = &out.attitude;
        let truth = &out.markers.context.truth;
        let err = match (a_msg.valid.get(), truth.attitude()) {
            (true, Some(t)) => {
                let err = rpy_error_deg(&a_msg.rpy, &t);
                accuracy.add(err);
                Some(err)
            }
            (true, None) if truth.no_deck() => {
                false_attitudes += 1;
                None
            }
            _ => None,
        };
        estimated += usize::from(a_msg.valid.get());
        if a.every > 0 && frames % a.every == 1 {
            let att = if a_msg.valid.get() {
                let [r, p, y] = a_msg.rpy.to_degrees();
                format!("roll {r:+7.3} pitch {p:+7.3} yaw {y:+7.3} deg")
            } else {
                "no attitude".to_string()
            };
            let err = err.map_or(String::new(), |e| {
                format!(", error {:.3}/{:.3}/{:.3}", e[0], e[1], e[2])
            });
            let out_of_view = match set.out_of_view.count_ones() {
                0 => String::new(),
                n => format!(", {n} out of view"),
            };
            outln!(
                "frame {:5} t {:8.3} s: {:?} {} markers{}{out_of_view} | {att}{err} | {} ({})",
                out.markers.context.source_index,
                out.markers.context.source_timestamp_ns as f64 / 1e9,
                set.status,
                set.count,
                if set.tracked.get() { " (tracked)" } else { "" },
                out.decision.state.get().name(),
                out.decision.reason.get().name(),
            );
        }
    }
    let bad = chain.drops().bad_frames;
    outln!(
        "{frames} frames ({bad} bad, skipped): {ok} ok, {partial} partial ({leaving} with markers out of view), \
         {no_deck} no deck; {tracked} tracked; \
         {estimated} attitudes"
    );
    let states: Vec<String> = DecisionState::ALL
        .iter()
        .zip(states)
        .map(|(s, n)| format!("{} {n}", s.name()))
        .collect();
    outln!("decisions: {}", states.join(", "));
    if accuracy.n > 0 {
        let (r, m) = (accuracy.rmse(), accuracy.max);
        outln!(
            "attitude error vs ground truth ({} frames): RMSE roll {:.4} pitch {:.4} yaw {:.4} deg, max {:.4} {:.4} {:.4}",
            accuracy.n, r[0], r[1], r[2], m[0], m[1], m[2]
        );
    }
    if false_attitudes > 0 {
        outln!("WARNING: {false_attitudes} attitudes on frames without a deck in view");
    }
    let places = std::iter::once(SOURCE).chain(PipelineStage::ALL.map(PipelineStage::name));
    for (stage, times) in places.zip(&mut costs) {
        if let Some(p) = Percentiles::of(times) {
            outln!(
                "{stage:>9}: p50 {:8.3} ms  p90 {:8.3} ms  p99 {:8.3} ms  max {:8.3} ms",
                p.p50,
                p.p90,
                p.p99,
                p.max
            );
        }
    }
    if frames == 0 {
        return Err("no frame could be processed".into());
    }
    Ok(())
}
