//! The closed-loop runner: one approach flown by a rule. The vehicle hovers over the deck; each
//! frame is rendered from the true deck and the vehicle's own path, goes through the perception
//! pipeline (a [`ClosedLoopPipeline`]: the stage chain in one process on a simulated clock, in
//! `deckwatch trials`), and the simulated autopilot acts on the decision state as it arrives:
//! commit on a fresh clearance, go around on an abort. Contact is judged against the true deck.
//! Pure: the pipeline is the caller's, this module only drives it.

use crate::faults::FrameFaults;
use crate::world::{ApproachWorld, TrialSea};
use crate::{
    ApproachModel, ApproachOutcome, Command, DecisionFollower, SimulatedAutopilot, TouchdownVerdict,
};
use deckwatch_common::messages::{AttitudeMessage, LandingDecision, VehicleSample};
use deckwatch_common::vehicle::Compensation;
use deckwatch_common::Quaternion;
use deckwatch_decide::DecisionConfig;
use deckwatch_sim::landing::{ClosedLoopScene, FlightPath, SharedFlightPath};
use std::sync::{Arc, Mutex};

/// The rules a pipeline flies: deckwatch's decision, or the naive rule on its attitudes (the
/// oracle needs no pipeline: [`crate::oracle_approach`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PipelineRule {
    Deckwatch,
    Naive,
}

/// The approach's clock: frame k is captured at `EPOCH_NS + k / rate_hz` (simulated
/// `CLOCK_MONOTONIC`), and each of capture, detect and estimate takes `stage_latency_ns`.
/// The approach's t = 0 is when the landing is asked for; the vehicle may have held over the
/// deck `watch_before_s` before that, its camera on and its decisions not acted on (frame 0 at
/// t = -`watch_before_s`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ApproachTiming {
    pub rate_hz: f64,
    pub stage_latency_ns: u64,
    pub watch_before_s: f64,
}

/// The simulated monotonic clock's reading at the first frame.
pub const EPOCH_NS: u64 = 1_000_000_000;

impl ApproachTiming {
    /// The simulated clock's reading at the approach's `t_s`.
    pub fn time_ns(&self, t_s: f64) -> u64 {
        EPOCH_NS.saturating_add(((t_s + self.watch_before_s).max(0.0) * 1e9) as u64)
    }

    /// The approach's time of frame `k`.
    pub fn frame_s(&self, k: u64) -> f64 {
        k as f64 / self.rate_hz - self.watch_before_s
    }

    /// Capture to the decision reaching the autopilot: three stages.
    pub fn reaction_s(&self) -> f64 {
        3.0 * self.stage_latency_ns as f64 / 1e9
    }
}

/// What became of one frame in the pipeline.
pub enum FrameStep {
    /// The source has no more frames.
    SourceEnded,
    /// The source could not deliver it (counted by the pipeline; nothing reaches the autopilot).
    Failed,
    /// Lost on its way (a fault): no decision on it.
    Lost,
    /// The decision on it (which carries the frame's attitude: the naive rule's input). Boxed:
    /// a decision is a few kilobytes, the other outcomes nothing.
    Decided(Box<LandingDecision>),
}

/// The perception pipeline an approach is flown through.
pub trait ClosedLoopPipeline {
    /// A sample of the autopilot's attitude stream (for the vehicle's compensation).
    fn observe_vehicle(&mut self, sample: &VehicleSample);
    /// The next frame, at the approach's `t_s`, through every stage; `inject` sees its pixels
    /// on the way to detect and returns false when the frame is lost.
    fn next_frame(&mut self, t_s: f64, inject: &mut dyn FnMut(&mut [u8]) -> bool) -> FrameStep;
    /// The decision when no frame came for too long (decide's watchdog), at `now_ns`.
    fn watchdog(&mut self, now_ns: u64) -> Option<LandingDecision>;
    /// How often decide's watchdog looks while nothing arrives (s): the runner calls
    /// [`Self::watchdog`] that often between the frames that were lost.
    fn watchdog_period_s(&self) -> f64;
    /// An event worth a line in a log: a commit, a go-around, the touchdown.
    fn note(&mut self, _time_ns: u64, _text: &str) {}
}

/// The command the naive rule gives on an attitude: land when the current angles are within
/// the limits (and the attitude is compensated), never go around.
pub fn naive_command(a: &AttitudeMessage, c: &DecisionConfig) -> Command {
    let [r, p, _] = a.rpy.to_degrees();
    if a.valid.get() && a.vehicle.compensation != Compensation::Missing && c.naive_within(r, p) {
        Command::Land
    } else {
        Command::Wait
    }
}

/// The autopilot acts on `command` at `(t_s, heave_m)`; a commit or a go-around gets a line in
/// the pipeline's log.
fn act_and_note<P: ClosedLoopPipeline>(
    autopilot: &mut SimulatedAutopilot,
    pipeline: &mut P,
    model: &ApproachModel,
    timing: ApproachTiming,
    (t_s, heave_m): (f64, f64),
    command: Command,
) {
    if !autopilot.act(t_s, heave_m, command) {
        return;
    }
    let what = if command == Command::Land {
        format!(
            "COMMIT at {t_s:.2} s: descending, contact at {:.2} s",
            t_s + model.touchdown_s
        )
    } else {
        let to = if model.follow_deck {
            format!("{} m over the deck", model.hover_m)
        } else {
            format!("{:.2} m", autopilot.waiting_m())
        };
        format!("GO-AROUND at {t_s:.2} s: climbing back to {to}")
    };
    pipeline.note(timing.time_ns(t_s), &what);
}

/// The autopilot's attitude stream: 100 Hz.
const VEHICLE_PERIOD_S: f64 = 0.01;

/// Flies one approach of `world` by `rule` through the pipeline `pipeline_for` makes of the
/// approach's scene; `faults` are injected on the way.
pub fn fly_approach<P: ClosedLoopPipeline, E>(
    rule: PipelineRule,
    world: &ApproachWorld,
    capacity: &DecisionConfig,
    model: &ApproachModel,
    timing: ApproachTiming,
    faults: &mut FrameFaults,
    pipeline_for: impl FnOnce(ClosedLoopScene<TrialSea>) -> Result<P, E>,
) -> Result<ApproachOutcome, E> {
    let path: SharedFlightPath = Arc::new(Mutex::new(FlightPath::hover(model.hover_m)));
    let mut pipeline = pipeline_for(world.scene(path.clone(), timing.frame_s(0)))?;
    let reaction_s = timing.reaction_s();
    let mut autopilot = SimulatedAutopilot::new(*model, path.clone());
    let mut follow = DecisionFollower::new(capacity.touchdown_s);
    let mut out = ApproachOutcome::default();
    let mut next_vehicle_s = timing.frame_s(0) - 0.05;
    let mut vehicle_seq = 0;
    // When decide last spoke or its watchdog last looked (s, the approach's time).
    let mut last_looked_s = f64::NEG_INFINITY;
    let heave = |t: f64| world.heave_m(t);
    let judge = |t: f64| {
        let (r_d, r_v) = world.attitudes(t);
        TouchdownVerdict::judge(&|t| world.truth(t), &r_d, &r_v, t, capacity, model)
    };
    for k in 0u64.. {
        let t = timing.frame_s(k);
        let t_decided = t + reaction_s;
        if let Some(contact) = autopilot.contact_s().filter(|&c| c <= t_decided) {
            out.touchdown = Some(TouchdownVerdict {
                descent_mps: Some(autopilot.descent_mps),
                ..judge(contact)
            });
            break;
        }
        if t > model.max_approach_s {
            break;
        }
        // The autopilot's attitude stream up to when estimate sees the frame.
        let out_now = faults.vehicle_out(t);
        while next_vehicle_s <= t + 1.5 * timing.stage_latency_ns as f64 / 1e9 {
            let tv = next_vehicle_s;
            next_vehicle_s += VEHICLE_PERIOD_S;
            if out_now {
                continue;
            }
            let r_v = world.vehicle_attitude(tv);
            let (height_m, vertical_speed_mps) = {
                let path = path.lock().unwrap_or_else(|e| e.into_inner());
                faults.vehicle_height.reported(|t| path.height_m(t, heave(t)), tv)
            };
            pipeline.observe_vehicle(&VehicleSample {
                seq: vehicle_seq,
                time_ns: timing.time_ns(tv),
                received_ns: timing.time_ns(tv),
                quaternion: Quaternion::from_matrix(&r_v),
                height_m,
                vertical_speed_mps,
                link_up: true.into(),
                ..Default::default()
            });
            vehicle_seq += 1;
        }
        let step = pipeline.next_frame(t, &mut |pixels| faults.inject(t, pixels));
        out.frames += 1;
        let follow_decision = |out: &mut ApproachOutcome,
                               follow: &mut DecisionFollower,
                               autopilot: &SimulatedAutopilot,
                               d: &LandingDecision,
                               at_s: f64| {
            out.count_decision(d.state.get(), d.reason.get());
            let c = follow.command_on(d);
            if c == Command::GoAround && autopilot.contact_s().is_some() {
                out.count_go_around_order(d.reason.get(), autopilot.can_go_around(at_s));
            }
            c
        };
        let command = match step {
            FrameStep::SourceEnded => break,
            FrameStep::Failed => Command::Wait,
            // Lost on the way: decide's watchdog looks every period since it last looked or
            // decided, as the process's tick does, up to when this frame's decision was due.
            FrameStep::Lost => {
                let period_s = pipeline.watchdog_period_s();
                let mut look_s = if period_s.is_finite() {
                    (last_looked_s + period_s).max(t_decided - 1.0)
                } else {
                    t_decided
                };
                let mut command = Command::Wait;
                while look_s <= t_decided + 1e-9 {
                    if let Some(d) = pipeline.watchdog(timing.time_ns(look_s)) {
                        if rule == PipelineRule::Deckwatch {
                            out.decisions += 1;
                            let c = follow_decision(&mut out, &mut follow, &autopilot, &d, look_s);
                            if c != Command::Wait && (0.0..t_decided).contains(&look_s) {
                                // Acted on when it was said, not at the frame's time.
                                act_and_note(
                                    &mut autopilot,
                                    &mut pipeline,
                                    model,
                                    timing,
                                    (look_s, heave(look_s)),
                                    c,
                                );
                            } else if c != Command::Wait {
                                command = c;
                            }
                        }
                    }
                    last_looked_s = look_s;
                    look_s += period_s;
                }
                command
            }
            FrameStep::Decided(decision) => {
                out.decisions += 1;
                last_looked_s = t_decided;
                match rule {
                    PipelineRule::Deckwatch => {
                        follow_decision(&mut out, &mut follow, &autopilot, &decision, t_decided)
                    }
                    PipelineRule::Naive => naive_command(&decision.attitude, capacity),
                }
            }
        };
        // Before the landing is asked for the decisions are followed (a clearance seen then is
        // not fresh after) but not acted on.
        let command = if t_decided < 0.0 { Command::Wait } else { command };
        act_and_note(
            &mut autopilot,
            &mut pipeline,
            model,
            timing,
            (t_decided, heave(t_decided)),
            command,
        );
    }
    out.commits = autopilot.commits;
    out.go_arounds = autopilot.go_arounds;
    if let Some(v) = &out.touchdown {
        let verdict = if v.safe() {
            "SAFE".to_string()
        } else {
            format!("UNSAFE ({})", v.violations.join(", "))
        };
        pipeline.note(
            timing.time_ns(v.t_s),
            &format!("TOUCHDOWN at {:.2} s: {verdict}", v.t_s),
        );
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::faults::FrameFaultModel;
    use crate::world::Approach;
    use deckwatch_common::Rpy;
    use deckwatch_decide::{FrameInput, LandingDecider};

    /// A perfect camera and estimator: the true deck (as the vehicle's compensation leaves it),
    /// 6 ms after capture, decided on by the decider itself. What the runner does with the
    /// decisions is then all that is tested.
    struct TruthPipeline<'a> {
        scene: ClosedLoopScene<TrialSea>,
        decider: LandingDecider,
        timing: ApproachTiming,
        seq: u64,
        noted: &'a mut Vec<String>,
        /// Every frame lost once this many followed the first clearance (a pipeline that
        /// falls silent during the touchdown), and how many have.
        silent_after_clear: Option<u32>,
        since_clear: Option<u32>,
    }

    impl ClosedLoopPipeline for TruthPipeline<'_> {
        /// The truth needs no compensation.
        fn observe_vehicle(&mut self, _sample: &VehicleSample) {}

        fn next_frame(&mut self, t_s: f64, inject: &mut dyn FnMut(&mut [u8]) -> bool) -> FrameStep {
            let mut pixels = [(self.seq % 256) as u8; 8];
            let silent = matches!((self.silent_after_clear, self.since_clear), (Some(n), Some(k)) if k >= n);
            if !inject(&mut pixels) || silent {
                return FrameStep::Lost;
            }
            let deck = self.scene.deck(t_s);
            let [r, p, _] = deck.attitude.to_degrees();
            let mut attitude = AttitudeMessage {
                valid: true.into(),
                rpy: Rpy::from_degrees(r, p, 0.0),
                deck_height_m: deck.deck_heave_m,
                ..Default::default()
            };
            attitude.vehicle.compensation = Compensation::Stream.into();
            attitude.stamp.seq = self.seq;
            attitude.context.source_timestamp_ns = ((t_s + self.timing.watch_before_s) * 1e9) as u64;
            attitude.stamp.times.captured_ns = self.timing.time_ns(t_s);
            self.seq += 1;
            let received_ns = attitude.stamp.times.captured_ns + 6_000_000;
            let d = self
                .decider
                .decide_frame(&FrameInput::from_attitude(&attitude, received_ns));
            self.decider.refit_between_frames();
            self.since_clear = match self.since_clear {
                Some(k) => Some(k + 1),
                None => (d.state == deckwatch_common::messages::DecisionState::ClearToLand).then_some(0),
            };
            let decision = LandingDecision {
                attitude,
                state: d.state.into(),
                reason: d.reason.into(),
                ..Default::default()
            };
            FrameStep::Decided(Box::new(decision))
        }

        fn watchdog_period_s(&self) -> f64 {
            self.decider.watchdog_period_s()
        }

        fn watchdog(&mut self, now_ns: u64) -> Option<LandingDecision> {
            let now_s = (now_ns - EPOCH_NS) as f64 / 1e9;
            let d = self.decider.timeout(now_s)?;
            Some(LandingDecision {
                state: d.state.into(),
                reason: d.reason.into(),
                ..Default::default()
            })
        }

        fn note(&mut self, _time_ns: u64, text: &str) {
            self.noted.push(text.to_string());
        }
    }

    fn fly(rule: PipelineRule, sea_state: u32, index: u32, faults: FrameFaultModel) -> ApproachOutcome {
        let approach = Approach {
            sea_state,
            seed: 101,
            heading_deg: 40.0,
            index,
        };
        fly_with(rule, DecisionConfig::default(), approach, faults)
    }

    /// One approach of perfect perception (seeing to contact) under `capacity`.
    fn fly_with(
        rule: PipelineRule,
        capacity: DecisionConfig,
        approach: Approach,
        faults: FrameFaultModel,
    ) -> ApproachOutcome {
        fly_through(rule, capacity, approach, faults, None, 0.0)
    }

    /// The same, the pipeline silent once `silent_after_clear` frames followed the first
    /// clearance, the vehicle over the deck `watch_before_s` before the landing is asked for.
    fn fly_through(
        rule: PipelineRule,
        capacity: DecisionConfig,
        approach: Approach,
        faults: FrameFaultModel,
        silent_after_clear: Option<u32>,
        watch_before_s: f64,
    ) -> ApproachOutcome {
        let model = ApproachModel {
            max_approach_s: 90.0,
            ..ApproachModel::quadrotor(capacity.touchdown_s)
        };
        let world =
            ApproachWorld::watched(approach, None, 0.3, model.max_approach_s, watch_before_s).unwrap();
        let timing = ApproachTiming {
            rate_hz: 10.0,
            stage_latency_ns: 2_000_000,
            watch_before_s,
        };
        let mut faults = FrameFaults::new(&faults, timing.rate_hz, approach.approach_seed());
        let mut noted = Vec::new();
        let out = fly_approach(rule, &world, &capacity, &model, timing, &mut faults, |scene| {
            Ok::<_, ()>(TruthPipeline {
                scene,
                decider: LandingDecider::new(capacity.clone()).unwrap(),
                timing,
                seq: 0,
                noted: &mut noted,
                silent_after_clear,
                since_clear: None,
            })
        })
        .unwrap();
        // Every commit and the touchdown were noted for the log.
        assert_eq!(
            noted.iter().filter(|n| n.starts_with("COMMIT")).count(),
            out.commits as usize,
            "{noted:?}"
        );
        assert_eq!(
            noted.iter().any(|n| n.starts_with("TOUCHDOWN")),
            out.touchdown.is_some()
        );
        out
    }

    /// On a moderate sea the decision commits, and contact is judged against the true deck: safe.
    #[test]
    fn the_decision_lands_safely_on_a_moderate_sea() {
        let out = fly(PipelineRule::Deckwatch, 3, 0, FrameFaultModel::default());
        let v = out.touchdown.as_ref().expect("a touchdown within 90 s");
        assert!(v.safe(), "{v:?}");
        // At 10 Hz, the 8 s warm-up at least.
        assert!(
            out.commits >= 1 && out.frames >= 80 && out.decisions == out.frames,
            "{out:?}"
        );
        assert!(out.decisions_by_reason.keys().any(|k| k.starts_with("CLEAR")));
    }

    /// A vehicle that held over the deck before the landing was asked for: nothing was acted on
    /// before the request, and the decider, warm by then, clears sooner than it could without
    /// the watch (its warm-up alone is 8 s).
    #[test]
    fn a_vehicle_that_watched_the_deck_is_cleared_sooner_once_asked() {
        let approach = Approach {
            sea_state: 3,
            seed: 101,
            heading_deg: 40.0,
            index: 0,
        };
        let cold = fly_through(
            PipelineRule::Deckwatch,
            DecisionConfig::default(),
            approach,
            FrameFaultModel::default(),
            None,
            0.0,
        );
        let warm = fly_through(
            PipelineRule::Deckwatch,
            DecisionConfig::default(),
            approach,
            FrameFaultModel::default(),
            None,
            60.0,
        );
        let (cold_s, warm_s) = (cold.touchdown.unwrap().t_s, warm.touchdown.as_ref().unwrap().t_s);
        let touchdown_s = DecisionConfig::default().touchdown_s;
        assert!(cold_s >= 8.0 + touchdown_s, "{cold_s}");
        assert!(warm.touchdown.as_ref().unwrap().safe());
        // Committed after the request (a descent takes the touchdown's time), sooner.
        assert!(warm_s >= touchdown_s && warm_s < cold_s, "{warm_s} {cold_s}");
        // Frames from 60 s before the request.
        assert!(warm.frames as f64 >= 10.0 * (60.0 + warm_s) - 1.0, "{warm:?}");
    }

    /// The naive rule commits on the current angles: on a rough sea some of its touchdowns break
    /// a limit at contact, which the runner reports.
    #[test]
    fn the_naive_rule_lands_unsafely_on_a_rough_sea() {
        let unsafe_touchdowns = (0..4)
            .filter(|&i| {
                let out = fly(PipelineRule::Naive, 6, i, FrameFaultModel::default());
                out.touchdown.is_some_and(|v| !v.safe())
            })
            .count();
        assert!(unsafe_touchdowns >= 1);
    }

    /// Perfect perception sees the deck to contact, so no frame is blind and, without a point
    /// of no return (`no_return_ms = 0`), every touchdown is judged at `go_around_risk` to its
    /// end: its go-arounds come when they can no longer be flown. With the default, the last
    /// decision that can act judges the rest as a clearance. Sea states 5 and 6, seeds 201 and
    /// 202, waves at 20 and 140 deg, 20 approaches each (160); figures in BENCHMARKS.md
    /// ("Closed-loop trials"). `cargo test --release -p deckwatch-trials --
    /// --ignored --nocapture`.
    #[test]
    #[ignore = "an evaluation: about a minute in release"]
    fn seeing_to_contact_a_go_around_comes_while_it_can_be_flown() {
        let run = |no_return_ms: f64| {
            let capacity = DecisionConfig {
                no_return_ms,
                ..DecisionConfig::default()
            };
            let mut sum = crate::RuleSummary::default();
            for sea_state in [5, 6] {
                for seed in [201, 202] {
                    for heading_deg in [20.0, 140.0] {
                        for index in 0..20 {
                            let approach = Approach {
                                sea_state,
                                seed,
                                heading_deg,
                                index,
                            };
                            let out = fly_with(
                                PipelineRule::Deckwatch,
                                capacity.clone(),
                                approach,
                                FrameFaultModel::default(),
                            );
                            sum.add(&out);
                        }
                    }
                }
            }
            let too_late: u64 = sum.too_late_reasons.values().sum();
            println!(
                "no_return_ms {no_return_ms}: {} approaches, {} commits, {} go-arounds flown, {too_late} ordered too late, {} touchdowns, {} unsafe {:?}",
                sum.approaches, sum.commits, sum.aborts, sum.touchdowns, sum.unsafe_touchdowns, sum.violations
            );
            (too_late, sum.unsafe_touchdowns)
        };
        assert_eq!(run(DecisionConfig::default().no_return_ms), (0, 0));
        let (too_late, _) = run(0.0);
        assert!(too_late > 0, "seeing to contact, some go-around comes too late");
    }

    /// The pipeline falls silent during a committed touchdown just before its last chance (the
    /// frame 0.15 s before the point of no return lost, and all after it). The watchdog, looking
    /// every 20 ms between the lost frames, judges that last chance before the point: the
    /// touchdown rides through at a clearance's risk or goes around (`gap`) in time to fly it.
    /// Only the freshness limit's stale decision, past the point, may come too late to be flown.
    #[test]
    fn a_silence_before_the_last_chance_is_judged_in_time() {
        let config = DecisionConfig::default();
        // Frames 0.1 s apart from the commit; the point of no return 1.65 s after it: frame 14
        // is 0.25 s before it, frame 15 (0.15 s before it) would be the last chance.
        assert_eq!((config.touchdown_s, config.no_return_ms), (2.0, 350.0));
        for index in 0..3 {
            let approach = Approach {
                sea_state: 3,
                seed: 101,
                heading_deg: 40.0,
                index,
            };
            let out = fly_through(
                PipelineRule::Deckwatch,
                config.clone(),
                approach,
                FrameFaultModel::default(),
                Some(14),
                0.0,
            );
            let rode = out.decisions_by_reason.contains_key("CLEAR ride-through");
            let around = out.abort_reasons.contains_key("gap");
            assert!(rode != around, "{out:?}");
            assert!(out.too_late_reasons.keys().all(|k| k == "stale-data"), "{out:?}");
            // Gone around on the judgement, or ridden through it; then the freshness limit's
            // abort, which this vehicle (its own point of no return about 0.25 s before contact,
            // the decider's 0.35 s) can sometimes still fly.
            assert!(out.touchdown.is_none() || rode, "{out:?}");
            assert!(out.touchdown.as_ref().is_none_or(|v| v.safe()), "{out:?}");
        }
    }

    /// Every frame lost: nothing to decide on, the watchdog's stale decisions only, no commit.
    #[test]
    fn no_frames_no_landing() {
        let all_lost = FrameFaultModel {
            drop_share: 1.0,
            ..Default::default()
        };
        let out = fly(PipelineRule::Deckwatch, 3, 0, all_lost);
        assert!(out.touchdown.is_none() && out.commits == 0, "{out:?}");
        assert!(
            out.decisions_by_reason.keys().all(|k| !k.starts_with("CLEAR")),
            "{out:?}"
        );
    }

    #[test]
    fn the_scene_follows_the_world() {
        let approach = Approach {
            sea_state: 5,
            seed: 3,
            heading_deg: 0.0,
            index: 2,
        };
        let world = ApproachWorld::new(approach, None, 0.3, 60.0).unwrap();
        let scene = world.scene(Arc::new(Mutex::new(FlightPath::hover(3.0))), 0.0);
        let [r, p, h] = world.truth(12.5);
        let s = scene.deck(12.5);
        let [sr, sp, _] = s.attitude.to_degrees();
        assert_eq!((r, p, h), (sr, sp, s.deck_heave_m));
        // A source that starts 30 s before the request shows the approach's 12.5 s at its 42.5.
        use deckwatch_sim::motion::MotionProfile;
        let early = world.scene(Arc::new(Mutex::new(FlightPath::hover(3.0))), -30.0);
        let s = early.sample(42.5);
        let [er, ep, _] = s.attitude.to_degrees();
        assert_eq!((er, ep, s.deck_heave_m, s.t_s), (r, p, h, 42.5));
        assert_eq!(
            ApproachWorld::new(
                Approach {
                    sea_state: 9,
                    ..approach
                },
                None,
                0.3,
                60.0
            )
            .err(),
            Some(crate::WorldError::NoSpectrumSea(9))
        );
    }
}
