//! The decide stage: the [`LandingDecider`] applied to the attitude stream, and its watchdog for
//! an attitude stream that stops.
//!
//! Time: the decider runs on the frames' own timeline (`FrameContext::source_timestamp_ns`:
//! simulated time, a recording's timestamps, the sensor's), and judges freshness by the age of
//! each attitude on arrival (capture -> receipt on `CLOCK_MONOTONIC`). So the same frames give
//! the same decisions in one process or in four, however long the hops took, as long as every
//! attitude is fresh; a stale one is never decided on.

use crate::config::{ConfigError, PipelineConfig};
use crate::stage::Stage;
use deckwatch_common::messages::{
    monotonic_ns, AttitudeMessage, GapCounter, LandingDecision, PipelineStage, StageSpan,
};
use deckwatch_decide::{DecisionConfig, FrameInput, LandingDecider};
use deckwatch_viz::Item;
use std::time::Duration;

/// State of the decide stage across messages.
pub struct DecideStage {
    decider: LandingDecider,
    gaps: GapCounter,
    last: Option<LandingDecision>,
    /// The newest input: its time on the frames' timeline (s) and when it arrived (ns).
    last_input: Option<(f64, u64)>,
    /// What the viewer was last shown (state changes, the calm window drawn ahead).
    view: deckwatch_viz::entities::DecisionView,
    pub dropped: u64,
    pub processed: u64,
    pub watchdog_decisions: u64,
}

impl DecideStage {
    /// `joined_late`: the pipeline was already running (see [`GapCounter::new`]).
    pub fn new(config: DecisionConfig, joined_late: bool) -> Result<Self, deckwatch_common::InvalidField> {
        let view =
            deckwatch_viz::entities::DecisionView::new(config.max_abs_roll_deg, config.max_abs_pitch_deg);
        Ok(Self {
            decider: LandingDecider::new(config)?,
            gaps: GapCounter::new(joined_late),
            last: None,
            last_input: None,
            view,
            dropped: 0,
            processed: 0,
            watchdog_decisions: 0,
        })
    }

    /// The decision on one attitude received at `received_ns`.
    pub fn process(&mut self, a: &AttitudeMessage, received_ns: u64) -> LandingDecision {
        self.dropped += self.gaps.observe(a.stamp.seq, a.stamp.drops.total());
        self.processed += 1;
        let frame = FrameInput::from_attitude(a, received_ns);
        let d = self.decider.decide_frame(&frame);
        self.last_input = Some((frame.t_s, received_ns));
        let (start, length) = d.calm_window.unwrap_or((f64::NAN, f64::NAN));
        let mut out = LandingDecision {
            stamp: a.stamp,
            context: a.context,
            attitude: *a,
            state: d.state.into(),
            reason: d.reason.into(),
            calm_window_start_s: start,
            calm_window_length_s: length,
            heave_rate_mps: d.heave_rate_mps,
            watchdog: false.into(),
        };
        out.stamp.drops[Self::PLACE] = self.dropped;
        out.stamp.times[Self::PLACE] = StageSpan {
            received_ns,
            finished_ns: monotonic_ns(),
        };
        self.last = Some(out);
        out
    }

    /// When no attitude came for too long: the stale decision to publish (once).
    pub fn watchdog(&mut self, now_ns: u64) -> Option<LandingDecision> {
        let (t, received_ns) = self.last_input?;
        // Now, on the frames' timeline: the newest frame's time plus what has passed since.
        let now = t + now_ns.saturating_sub(received_ns) as f64 / 1e9;
        let d = self.decider.timeout(now)?;
        let mut out = self.last?;
        out.state = d.state.into();
        out.reason = d.reason.into();
        out.calm_window_start_s = f64::NAN;
        out.calm_window_length_s = f64::NAN;
        out.heave_rate_mps = f64::NAN;
        out.watchdog = true.into();
        out.stamp.times[Self::PLACE] = StageSpan {
            received_ns: now_ns,
            finished_ns: monotonic_ns(),
        };
        self.watchdog_decisions += 1;
        Some(out)
    }
}

impl Stage for DecideStage {
    const PLACE: PipelineStage = PipelineStage::Decide;
    type Input = AttitudeMessage;
    type Output = LandingDecision;

    fn from_config(config: &PipelineConfig, joined_late: bool) -> Result<Self, ConfigError> {
        Self::new(config.decide.clone(), joined_late)
            .map_err(|e| ConfigError::in_section("the pipeline configuration", "decide", e))
    }

    fn step(&mut self, a: &AttitudeMessage, received_ns: u64) -> LandingDecision {
        self.process(a, received_ns)
    }

    fn after_outputs(&mut self) {
        let Some(lead) = self.decider.frame_interval_s() else {
            return;
        };
        if self.decider.refit_due(lead).is_some() {
            // The processes the decision just woke (the link, the launcher) go first where
            // they share this core: the refit is not on their path.
            std::thread::yield_now();
            self.decider.refit_between_frames();
        }
    }

    /// The decider's: often enough that a silence during a committed touchdown is noticed
    /// before its point of no return, and a stale one within 1.5 times the freshness limit.
    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_secs_f64(self.decider.watchdog_period_s()))
    }

    fn tick(&mut self, now_ns: u64) -> Option<LandingDecision> {
        self.watchdog(now_ns)
    }

    fn viewer_items(&mut self, d: &LandingDecision) -> Vec<Item> {
        self.view.items(d)
    }

    fn summary(&self) -> String {
        format!(
            "{} attitudes, {} dropped, {} watchdog decisions",
            self.processed, self.dropped, self.watchdog_decisions
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::VehicleAttitude;
    use deckwatch_common::messages::{DecisionReason, DecisionState};
    use deckwatch_common::vehicle::Compensation;
    use deckwatch_common::Rpy;

    /// The watchdog looks as often as the decider asks, often enough for a touchdown's point of
    /// no return (its unit test: `a_silence_before_the_last_chance_goes_around_while_it_can_be_flown`).
    #[test]
    fn the_watchdog_looks_as_often_as_the_decider_asks() {
        let s = DecideStage::new(DecisionConfig::default(), false).unwrap();
        let period = s.tick_period().unwrap();
        assert_eq!(period.as_secs_f64(), s.decider.watchdog_period_s());
        assert!(period <= Duration::from_millis(20), "{period:?}");
    }

    #[test]
    fn invalid_stale_and_silence_never_clear() {
        let mut s = DecideStage::new(DecisionConfig::default(), false).unwrap();
        let mut a = AttitudeMessage {
            valid: true.into(),
            rpy: Rpy::from_degrees(1.0, 1.0, 0.0),
            deck_height_m: 0.0,
            ..Default::default()
        };
        a.stamp.times.captured_ns = 1_000_000_000;
        let d = s.process(&a, 1_010_000_000);
        assert_eq!(
            (d.state.get(), d.reason.get()),
            (DecisionState::Hold, DecisionReason::Warmup)
        );
        // 900 ms old on arrival: stale.
        a.stamp.seq = 1;
        a.stamp.times.captured_ns = 1_100_000_000;
        let d = s.process(&a, 2_000_000_000);
        assert_eq!(
            (d.state.get(), d.reason.get()),
            (DecisionState::NoDeck, DecisionReason::StaleData)
        );
        a.valid = false.into();
        a.stamp.seq = 2;
        assert_eq!(s.process(&a, 1_210_000_000).state, DecisionState::NoDeck);
        // No capture time: never fresh. (Another attitude: a third repeat of the same one would
        // be a frozen input, whatever its time.)
        a.valid = true.into();
        a.rpy = Rpy::from_degrees(1.1, 1.0, 0.0);
        a.stamp.seq = 3;
        a.stamp.times.captured_ns = 0;
        assert_eq!(s.process(&a, 1_220_000_000).reason, DecisionReason::StaleData);
        // Silence: the watchdog speaks once.
        assert!(s.watchdog(1_300_000_000).is_none());
        let w = s.watchdog(2_300_000_000).unwrap();
        assert!(w.watchdog.get() && w.reason == DecisionReason::StaleData);
        assert!(s.watchdog(2_400_000_000).is_none());
        let e = PipelineConfig::from_toml("d.toml", "[decide]\nmax_age_ms = -1\n").unwrap();
        let e = DecideStage::from_config(&e, false).err().unwrap().to_string();
        assert!(e.contains("decide.max_age_ms"), "{e}");
    }

    /// A frame whose attitude could not be compensated for the vehicle's never clears; during a
    /// committed touchdown it is a missing attitude, ridden through for `ride_through_ms` (the
    /// touchdown goes on with the prediction), then an abort with its reason.
    #[test]
    fn an_uncompensated_frame_never_clears() {
        let mut s = DecideStage::new(DecisionConfig::default(), false).unwrap();
        let mut a = AttitudeMessage {
            valid: true.into(),
            vehicle: VehicleAttitude {
                compensation: Compensation::Stream.into(),
                ..Default::default()
            },
            ..Default::default()
        };
        let at = |a: &mut AttitudeMessage, k: u64| {
            let t = k as f64 * 0.1;
            a.rpy = Rpy::from_degrees(0.8 * (0.7 * t).sin(), 0.6 * (0.5 * t + 1.0).sin(), 0.0);
            a.deck_height_m = 0.3 * (0.6 * t).sin();
            a.stamp.seq = k;
            a.context.source_timestamp_ns = k * 100_000_000;
            a.stamp.times.captured_ns = 1_000_000_000 + k * 100_000_000;
        };
        // Never compensated: never clear.
        let mut never = DecideStage::new(DecisionConfig::default(), false).unwrap();
        let mut b = a;
        b.vehicle.compensation = Compensation::Missing.into();
        for k in 0..600u64 {
            at(&mut b, k);
            let d = never.process(&b, b.stamp.times.captured_ns + 5_000_000);
            assert_eq!(d.reason, DecisionReason::NoVehicleAttitude);
            assert_ne!(d.state, DecisionState::ClearToLand);
        }
        let mut cleared_at = None;
        for k in 0..600u64 {
            at(&mut a, k);
            if s.process(&a, a.stamp.times.captured_ns + 5_000_000).state == DecisionState::ClearToLand {
                cleared_at = Some(k);
                break;
            }
        }
        let k = cleared_at.expect("a calm sea clears");
        a.vehicle.compensation = Compensation::Missing.into();
        let reasons: Vec<(DecisionState, DecisionReason)> = (k + 1..k + 13)
            .map(|j| {
                at(&mut a, j);
                let d = s.process(&a, a.stamp.times.captured_ns + 5_000_000);
                (d.state.get(), d.reason.get())
            })
            .collect();
        // 1 s of them (10 frames at 10 Hz, the 11th on the edge), not 1.1 s.
        assert!(reasons[..10]
            .iter()
            .all(|r| *r == (DecisionState::ClearToLand, DecisionReason::RideThrough)));
        assert_eq!(
            reasons[11],
            (DecisionState::Abort, DecisionReason::NoVehicleAttitude)
        );
    }

    /// Attitudes that stop during a committed touchdown, before its last chance: the ticks
    /// (every `tick_period`, on the monotonic clock) judge that last chance before the point of
    /// no return on the frames' timeline, long before the freshness limit would speak.
    #[test]
    fn a_silence_before_the_last_chance_is_judged_before_the_point_of_no_return() {
        let mut s = DecideStage::new(DecisionConfig::default(), false).unwrap();
        let (touchdown_s, no_return_s) = {
            let c = s.decider.config();
            (c.touchdown_s, c.no_return_ms / 1e3)
        };
        let latency_ns = 25_000_000;
        let attitude = |k: u64| {
            let t = k as f64 * 0.1;
            let mut a = AttitudeMessage {
                valid: true.into(),
                rpy: Rpy::from_degrees(0.8 * (0.7 * t).sin(), 0.6 * (0.5 * t + 1.0).sin(), 0.0),
                deck_height_m: 0.3 * (0.6 * t).sin(),
                ..Default::default()
            };
            a.stamp.seq = k;
            a.context.source_timestamp_ns = k * 100_000_000;
            a.stamp.times.captured_ns = 3_000_000_000 + k * 100_000_000;
            a
        };
        let k = (0..600u64)
            .find(|&k| {
                let a = attitude(k);
                let d = s.process(&a, a.stamp.times.captured_ns + latency_ns);
                d.state == DecisionState::ClearToLand
            })
            .expect("a calm sea clears");
        let no_return_at = k as f64 * 0.1 + touchdown_s - no_return_s;
        // Frames on time while the point of no return is more than 2.5 frames away: the last
        // one is not the last chance (that would be the next, 1.5 frames and a tick from it).
        let mut last = k;
        while no_return_at - (last + 1) as f64 * 0.1 > 0.25 - 1e-9 {
            last += 1;
            let a = attitude(last);
            assert_eq!(
                s.process(&a, a.stamp.times.captured_ns + latency_ns).state,
                DecisionState::ClearToLand
            );
        }
        let received_ns = attitude(last).stamp.times.captured_ns + latency_ns;
        let period_ns = s.tick_period().unwrap().as_nanos() as u64;
        let (after_ns, w) = (1..100u64)
            .find_map(|m| {
                s.watchdog(received_ns + m * period_ns)
                    .map(|w| (m * period_ns, w))
            })
            .expect("the watchdog speaks");
        let judged_at = last as f64 * 0.1 + after_ns as f64 / 1e9;
        assert!(w.watchdog.get(), "{w:?}");
        assert!(
            matches!(
                (w.state.get(), w.reason.get()),
                (DecisionState::ClearToLand, DecisionReason::RideThrough)
                    | (DecisionState::Abort, DecisionReason::Gap)
            ),
            "{w:?}"
        );
        assert!(judged_at < no_return_at, "{judged_at} {no_return_at}");
        assert!(
            (after_ns as f64) < s.decider.config().max_age_ms * 1e6,
            "{after_ns}"
        );
    }

    /// The decision depends on the frames' timeline, not on when they arrived.
    #[test]
    fn same_frames_same_decisions_whatever_the_delay() {
        let run = |delay_ns: u64| {
            let mut s = DecideStage::new(DecisionConfig::default(), false).unwrap();
            (0..400u64)
                .map(|k| {
                    let t = k as f64 * 0.1;
                    let mut a = AttitudeMessage {
                        valid: true.into(),
                        rpy: Rpy::from_degrees(2.0 * (0.7 * t).sin(), 1.5 * (0.5 * t + 1.0).sin(), 0.0),
                        deck_height_m: 0.4 * (0.6 * t).sin(),
                        ..Default::default()
                    };
                    a.stamp.seq = k;
                    a.context.source_timestamp_ns = k * 100_000_000;
                    // Capture on the monotonic clock somewhere else entirely.
                    a.stamp.times.captured_ns = 5_000_000_000 + k * 100_000_000 + (k % 7) * 1_000_000;
                    let received = a.stamp.times.captured_ns + delay_ns + (k % 3) * 2_000_000;
                    let d = s.process(&a, received);
                    (
                        d.state,
                        d.reason,
                        d.calm_window_start_s.to_bits(),
                        d.calm_window_length_s.to_bits(),
                    )
                })
                .collect::<Vec<_>>()
        };
        let (a, b) = (run(1_000_000), run(40_000_000));
        assert_eq!(a, b);
        assert!(a.iter().any(|d| d.1 != DecisionReason::Warmup));
    }

    /// `decide-eval` (the decide crate's `decide_stream`) and this stage make the same decision
    /// on every frame of one stream with every kind of refusal in it: frozen images, an
    /// uncompensated camera, missing and stale attitudes, stamp jitter.
    #[test]
    fn the_evaluation_and_the_stage_decide_alike() {
        use deckwatch_common::messages::AttitudeFailure;
        use deckwatch_decide::DeckObservation;
        let mut frames = Vec::new();
        let mut messages = Vec::new();
        for k in 0..1500u64 {
            let jitter_ns = (k * 7919 % 11) * 1_000_000;
            let t_ns = k * 100_000_000 + jitter_ns;
            let t = t_ns as f64 / 1e9;
            let deck = Rpy::from_degrees(1.2 * (0.7 * t).sin(), 0.9 * (0.45 * t + 1.0).sin(), 0.0);
            let height_m = 0.2 * (0.6 * t).sin();
            let frozen_image = (400..440).contains(&(k % 500));
            let vehicle_missing = (200..215).contains(&(k % 300));
            let invalid = k % 37 == 0 || frozen_image;
            let late_ns = if k % 53 == 0 { 1_000_000_000 } else { 5_000_000 };
            let mut a = AttitudeMessage {
                valid: (!invalid).into(),
                rpy: deck,
                deck_height_m: height_m,
                ..Default::default()
            };
            if frozen_image {
                a.failure = AttitudeFailure::FrozenImage.into();
            }
            if vehicle_missing {
                a.vehicle.compensation = Compensation::Missing.into();
            }
            a.stamp.seq = k;
            a.context.source_timestamp_ns = t_ns;
            a.stamp.times.captured_ns = 3_000_000_000 + t_ns;
            let received_ns = a.stamp.times.captured_ns + late_ns;
            let [r, p, _] = deck.to_degrees();
            frames.push(deckwatch_decide::FrameInput {
                t_s: t,
                deck: (!invalid).then(|| DeckObservation::new(r, p, height_m)),
                age_s: late_ns as f64 / 1e9,
                vehicle_missing,
                frozen_image,
            });
            messages.push((a, received_ns));
        }
        let evaluated = deckwatch_decide::eval::decide_stream(&DecisionConfig::default(), &frames).unwrap();
        let mut stage = DecideStage::new(DecisionConfig::default(), false).unwrap();
        let mut reasons = std::collections::BTreeSet::new();
        for (k, ((a, received_ns), e)) in messages.iter().zip(&evaluated).enumerate() {
            let d = stage.process(a, *received_ns);
            stage.after_outputs();
            assert_eq!(
                (d.state.get(), d.reason.get()),
                (e.state, e.reason),
                "frame {k}: the stage and the evaluation disagree"
            );
            reasons.insert(e.reason.name());
        }
        for reason in [
            "frozen-input",
            "no-vehicle-attitude",
            "invalid-attitude",
            "stale-data",
            "within-capacity",
        ] {
            assert!(reasons.contains(reason), "{reason} never met: {reasons:?}");
        }
    }
}
