//! The pipeline in one process: the same stages as the processes of `deckwatch run`, called in
//! a row on each frame (capture, then the stages of [`FrameStages`] in pipeline order: detect ->
//! estimate -> decide) with no transport in between. `deckwatch inproc` and `deckwatch eval` run
//! it; for the same frames it gives the same attitudes and decisions as the processes (a test in
//! `tests/` holds it to that, bit for bit).

use crate::config::PipelineConfig;
use crate::row::StageRow;
use crate::stage::{Frame, RunError, Stage};
use crate::stages::capture::{complete_header, new_header};
use crate::stages::FrameStages;
use deckwatch_capture::source::{CaptureSource, SourceError};
use deckwatch_common::messages::{
    monotonic_ns, AttitudeMessage, DropCounts, FrameHeader, FrameSource, LandingDecision, MarkerMessage,
    PipelineStage, VehicleSample, STAGES,
};
use std::time::{Duration, Instant};

/// What every stage made of one frame, and how long each took.
#[derive(Debug, Clone)]
pub struct ChainOutput {
    pub markers: MarkerMessage,
    pub attitude: AttitudeMessage,
    pub decision: LandingDecision,
    /// Capture (render, decode or copy), then each stage in pipeline order ([`Self::cost_of`]).
    pub cost: [Duration; 1 + STAGES],
}

impl ChainOutput {
    /// What `stage` took.
    pub fn cost_of(&self, stage: PipelineStage) -> Duration {
        self.cost[1 + stage.index()]
    }
}

/// The stages of a pipeline configuration, chained in one process.
pub struct StageChain {
    source: CaptureSource,
    pixels: Vec<u8>,
    /// The stages, in pipeline order.
    pub stages: FrameStages,
    /// The source's next frame, and the next sequence number (bad frames get none).
    next_frame: u64,
    next_seq: u64,
    drops: DropCounts,
}

impl StageChain {
    /// Opens the configured source and builds the stages. The source runs as fast as the
    /// stages go: the chain paces nothing, so it takes sources that deliver on demand (the
    /// simulator, a replay), not a camera.
    pub fn new(config: &PipelineConfig) -> Result<Self, RunError> {
        if config.source.kind == FrameSource::Libcamera {
            return Err(SourceError::Config {
                key: "source.kind",
                problem: "the in-process chain takes the simulator or a replay, not a camera".into(),
            }
            .into());
        }
        Self::with_source(config, config.capture().open()?)
    }

    /// The stages of `config` behind a source opened elsewhere (say, the simulator rendering a
    /// closed-loop landing: `CaptureConfig::open_sim_with`).
    pub fn with_source(config: &PipelineConfig, source: CaptureSource) -> Result<Self, RunError> {
        Ok(Self {
            pixels: vec![0; source.frame_bytes()],
            source,
            stages: FrameStages::from_config(config, false)?,
            next_frame: 0,
            next_seq: 0,
            drops: DropCounts::default(),
        })
    }

    pub fn source(&self) -> &CaptureSource {
        &self.source
    }

    /// The newest frame's pixels (packed rows), as detect saw them.
    pub fn pixels(&self) -> &[u8] {
        &self.pixels
    }

    /// Frames the source could not deliver (counted and skipped).
    pub fn drops(&self) -> DropCounts {
        self.drops
    }

    /// A vehicle attitude sample from the autopilot, to the stages that follow the vehicle
    /// stream (estimate), as their processes are handed it.
    pub fn vehicle_sample(&mut self, sample: &VehicleSample) {
        self.stages.vehicle_sample(sample);
    }
}

/// The stages' clock when the chain runs faster (or slower) than its frames: every frame is
/// captured at `epoch_ns` plus its source time, and each stage takes `stage_latency_ns`. The
/// decisions then depend on the frames alone, however fast this machine is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedClock {
    pub epoch_ns: u64,
    pub stage_latency_ns: u64,
}

impl SimulatedClock {
    /// The clock's reading at a source time.
    pub fn at(&self, source_ns: u64) -> u64 {
        self.epoch_ns.saturating_add(source_ns)
    }
}

impl StageChain {
    /// The next frame through every stage, on `clock` (None: this machine's monotonic clock).
    /// `inject` sees the captured frame before detect does and may change it (a fault); when it
    /// returns false the frame is lost on the way (counted as a capture drop of the next frame,
    /// as a lost frame is) and `Ok(None)` comes back. None when the source is exhausted.
    pub fn next_frame(
        &mut self,
        clock: Option<SimulatedClock>,
        inject: impl FnOnce(&mut FrameHeader, &mut [u8]) -> bool,
    ) -> Option<Result<Option<ChainOutput>, SourceError>> {
        if self.source.len().is_some_and(|n| self.next_frame >= n) {
            return None;
        }
        let k = self.next_frame;
        self.next_frame += 1;
        let t0 = Instant::now();
        let mut header = new_header(&self.source, self.next_seq, self.drops);
        let width = header.width as usize;
        match self.source.capture(k, &mut self.pixels, width) {
            Ok(f) => complete_header(&mut header, &f),
            Err(e) => {
                self.drops.bad_frames += 1;
                return Some(Err(e));
            }
        }
        let source_ns = header.context.source_timestamp_ns;
        let now = |stage: u64, real: u64| match clock {
            Some(c) => c.at(source_ns) + stage * c.stage_latency_ns,
            None => real,
        };
        header.stamp.times.captured_ns = now(0, header.stamp.times.captured_ns);
        if !inject(&mut header, &mut self.pixels) {
            self.drops.capture += 1;
            return Some(Ok(None));
        }
        self.drops = header.stamp.drops;
        self.next_seq += 1;
        header.stamp.times.published_ns = now(0, monotonic_ns());
        let t1 = Instant::now();
        let frame = Frame {
            header: &header,
            pixels: &self.pixels,
        };
        let mut cost = [Duration::ZERO; 1 + STAGES];
        cost[0] = t1 - t0;
        let (mut lap_start, mut next) = (t1, 1);
        let mut lap = || {
            let t = Instant::now();
            if let Some(c) = cost.get_mut(next) {
                *c = t - lap_start;
            }
            (lap_start, next) = (t, next + 1);
        };
        // Each stage after the first receives its input when the one before finished it.
        let (markers, attitude, decision) = self.stages.step(
            frame,
            header.stamp.times.published_ns,
            &mut |k, finished_ns| now(k as u64, finished_ns),
            &mut lap,
        );
        // As the processes do once a decision is published (not counted in its cost).
        self.stages.after_outputs();
        Some(Ok(Some(ChainOutput {
            markers,
            attitude,
            decision,
            cost,
        })))
    }

    /// How often decide's watchdog looks while no attitude comes (s), as the process's tick.
    pub fn watchdog_period_s(&self) -> f64 {
        self.stages
            .last()
            .tick_period()
            .map_or(f64::INFINITY, |p| p.as_secs_f64())
    }

    /// What decide says when no attitude came for a while (its watchdog), at `now_ns` on the
    /// chain's clock.
    pub fn watchdog(&mut self, now_ns: u64) -> Option<LandingDecision> {
        self.stages.last_mut().tick(now_ns)
    }
}

/// Frame by frame: the next frame through every stage; None when the source is exhausted. A
/// frame the source cannot read is counted (`drops().bad_frames`) and reported as the error;
/// the chain goes on with the next one.
impl Iterator for StageChain {
    type Item = Result<ChainOutput, SourceError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            match self.next_frame(None, |_, _| true)? {
                Ok(Some(out)) => return Some(Ok(out)),
                Ok(None) => continue, // not without an injected fault
                Err(e) => return Some(Err(e)),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::DecisionState;

    #[test]
    fn simulated_frames_go_through_every_stage() {
        let mut c = PipelineConfig::default();
        c.sim.frames = 5;
        (c.image.width, c.image.height) = (Some(640), Some(480));
        let mut chain = StageChain::new(&c).unwrap();
        let mut n = 0;
        for out in chain.by_ref() {
            let out = out.unwrap();
            assert_eq!(out.decision.stamp.seq, n);
            assert!(out.attitude.valid.get(), "frame {n}: {:?}", out.attitude.failure);
            assert_eq!(out.decision.state, DecisionState::Hold);
            let t = out.decision.stamp.times;
            let decided_ns = t[PipelineStage::Decide].finished_ns;
            assert!(t.captured_ns <= t.published_ns && t.published_ns <= decided_ns);
            // Every stage of the row stamped the frame, each receiving it as the one before
            // finished it.
            let mut before_ns = t.published_ns;
            for s in PipelineStage::ALL {
                assert_eq!(t[s].received_ns, before_ns, "{}", s.name());
                assert!(t[s].finished_ns >= t[s].received_ns, "{}", s.name());
                before_ns = t[s].finished_ns;
            }
            assert_eq!(out.cost.len(), 1 + STAGES);
            n += 1;
        }
        assert_eq!(n, 5);
        assert_eq!(chain.drops().total(), 0);
    }
}
