//! Closed-loop landing trials: what a simulated autopilot does with deckwatch's decisions, and
//! how each touchdown is judged at contact against the true deck. Pure: `deckwatch trials`
//! renders the frames from the true motion, drives the stage chain (or the processes and the
//! MAVLink link) and feeds the decisions to [`SimulatedAutopilot`]; [`RuleSummary`] adds the
//! approaches up.
//!
//! An approach starts when the vehicle arrives in hover over the deck (the deck comes into
//! view: the decider's warm-up starts then) and ends at contact or after `max_approach_s`. A
//! vehicle may also hold over the deck before the landing is asked for
//! ([`fly::ApproachTiming::watch_before_s`]): the decider learns the motion then, nothing is
//! acted on, and the approach's times count from the request.

pub mod faults;
pub mod fly;
pub mod stats;
pub mod world;

pub use faults::{AttitudeStreamModel, Episodes, FrameFaultModel, FrameFaults, VehicleHeightError};
pub use fly::{fly_approach, naive_command, ApproachTiming, ClosedLoopPipeline, FrameStep, PipelineRule};
pub use world::{Approach, ApproachWorld, TrialSea, WorldError};

use deckwatch_common::messages::{DecisionReason, DecisionState, LandingDecision};
use deckwatch_common::RotationMatrix;
use deckwatch_decide::eval::{TrueDeck, TrueDeckState};
use deckwatch_decide::DecisionConfig;
use deckwatch_sim::landing::SharedFlightPath;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// How the simulated vehicle flies an approach.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ApproachModel {
    /// Where it waits: its camera's height over the deck (m) when it follows the deck, else, at
    /// the least, over the deck's mean level.
    pub hover_m: f64,
    /// While it waits it holds its camera `hover_m` over the deck on its range finder, rising and
    /// falling with the heave (ArduPilot's surface tracking, PX4's terrain following): the
    /// pattern stays in view, and a descent is about `hover_m` long. Else it holds a height in
    /// W (see `wait_clearance_m`).
    pub follow_deck: bool,
    /// Following the deck, its height lags the deck's by a first-order filter of this time
    /// constant (s; ArduPilot's `SURFTRAK_TC`, 1 s by default); 0 follows it exactly.
    pub follow_lag_s: f64,
    /// Holding a height in W, it keeps its camera at least this high over the highest the deck
    /// has been in the last [`RANGED_WINDOW_S`] (its range finder and altimeter measure the
    /// deck's height), so that at a swell's crest the whole pattern stays in view (m). It waits
    /// at `hover_m` where the sea is lower.
    pub wait_clearance_m: f64,
    /// The camera's height over the deck at contact (gear on the deck, m).
    pub contact_m: f64,
    /// From commit to contact (s): the decision's `touchdown_s`. The descent follows the deck
    /// (range finder), so contact comes exactly this long after the commit.
    pub touchdown_s: f64,
    /// Climb rate of a go-around back to the hover height (m/s).
    pub climb_mps: f64,
    /// A go-around ordered during a descent takes this long to begin (s: the autopilot's
    /// reaction, its jerk-limited ramp) ...
    pub go_around_reaction_s: f64,
    /// ... and arrests the descent at this acceleration (m/s^2). Ordered with less of the
    /// descent left than [`ApproachModel::no_return_s`], it cannot keep the vehicle off the deck:
    /// contact comes as planned.
    pub go_around_accel_mps2: f64,
    /// The largest tilt of the vehicle against the deck its gear takes at contact (deg).
    pub max_relative_tilt_deg: f64,
    /// An approach that has not touched down after this long ends (s).
    pub max_approach_s: f64,
}

impl ApproachModel {
    /// How much of a descent at `descent_mps` over the deck is left (s) when a go-around can
    /// no longer keep the vehicle off the deck: the reaction's distance and the braking
    /// distance `v^2 / (2 a)`, flown at `v`. The decision's `[decide] no_return_ms` must be at
    /// least this for the vehicle it flies.
    pub fn no_return_s(&self, descent_mps: f64) -> f64 {
        self.go_around_reaction_s + descent_mps / (2.0 * self.go_around_accel_mps2)
    }

    /// A small quadrotor that waits with its camera 3 m over the deck, following it, and touches
    /// down with its camera 0.25 m over it, `touchdown_s` after the commit.
    pub fn quadrotor(touchdown_s: f64) -> Self {
        Self {
            hover_m: 3.0,
            follow_deck: true,
            follow_lag_s: 1.0,
            wait_clearance_m: 2.5,
            contact_m: 0.25,
            touchdown_s,
            climb_mps: 1.5,
            // PX4's `MPC_ACC_UP_MAX` (4 m/s^2) after a tenth of a second.
            go_around_reaction_s: 0.1,
            go_around_accel_mps2: 4.0,
            max_relative_tilt_deg: 8.0,
            max_approach_s: 240.0,
        }
    }

    pub fn validate(&self) -> Result<(), deckwatch_common::InvalidOption> {
        let ok = self.hover_m > self.contact_m
            && self.wait_clearance_m > self.contact_m
            && self.follow_lag_s >= 0.0
            && self.contact_m > 0.0
            && self.touchdown_s > 0.0
            && self.climb_mps > 0.0
            && self.go_around_reaction_s >= 0.0
            && self.go_around_accel_mps2 > 0.0
            && self.max_relative_tilt_deg > 0.0
            && self.max_approach_s > self.touchdown_s;
        if ok {
            Ok(())
        } else {
            Err(deckwatch_common::InvalidOption::new(
                "approach",
                format!("hover height and wait clearance over contact height over 0, positive touchdown time, climb rate, go-around acceleration and tilt limit, a go-around reaction of 0 or more, an approach longer than a touchdown; got {self:?}"),
            ))
        }
    }
}

/// What the autopilot is told to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    Wait,
    Land,
    GoAround,
}

/// The autopilot's reading of deckwatch's decision state as it arrives (`dw_state` over
/// MAVLink, or the decision message): it commits at the start of a commitment only, goes
/// around on Abort, and waits on anything else. A clearance within a commitment holds only
/// the go-around's risk and covers a touchdown that started earlier than one begun now would:
/// never acted on. A commitment starts with a change into ClearToLand; on the decision message
/// also while ClearToLand goes on, where the decider commits again (a vehicle that did not
/// descend, say one that was not yet asked to land): at the first clearance on a frame a
/// touchdown's time or more after the last start ([`Self::command_on`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecisionFollower {
    previous: DecisionState,
    touchdown_s: f64,
    /// The frame time the current commitment started on (the decider's clock, s).
    commitment_start_s: f64,
}

impl DecisionFollower {
    /// For a decider whose touchdown lasts `touchdown_s` (`[decide] touchdown_s`).
    pub fn new(touchdown_s: f64) -> Self {
        Self {
            previous: DecisionState::NoDeck,
            touchdown_s,
            commitment_start_s: f64::NEG_INFINITY,
        }
    }

    /// The command on a decision state alone (`dw_state`): a change into ClearToLand commits.
    pub fn command(&mut self, state: DecisionState) -> Command {
        self.follow(state, None)
    }

    /// The command on a decision message, which also shows where a commitment starts while
    /// ClearToLand goes on: the decider ends a commitment at its frame time plus `touchdown_s`
    /// (the frame's time as the decider reads it, `FrameInput::from_attitude`) and
    /// judges the next frame afresh; a ride-through or a watchdog's decision never starts one.
    pub fn command_on(&mut self, d: &LandingDecision) -> Command {
        let frame_s = (!d.watchdog.get() && d.reason.get() != DecisionReason::RideThrough)
            .then(|| deckwatch_decide::FrameInput::from_attitude(&d.attitude, 0).t_s);
        self.follow(d.state.get(), frame_s)
    }

    fn follow(&mut self, state: DecisionState, frame_s: Option<f64>) -> Command {
        let clear = state == DecisionState::ClearToLand;
        let renewed = frame_s.is_some_and(|t| !(t < self.commitment_start_s + self.touchdown_s));
        let fresh = clear && (self.previous != DecisionState::ClearToLand || renewed);
        if fresh {
            // A start whose frame time is not known is never renewed: only the next change
            // into ClearToLand starts another.
            self.commitment_start_s = frame_s.unwrap_or(f64::INFINITY);
        }
        self.previous = state;
        match state {
            DecisionState::ClearToLand if fresh => Command::Land,
            DecisionState::Abort => Command::GoAround,
            _ => Command::Wait,
        }
    }
}

/// Where the vehicle is in its approach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Phase {
    Hover,
    /// Committed at `commit_s`; contact at `contact_s`.
    Descent {
        commit_s: f64,
        contact_s: f64,
    },
    /// Going around: back at the hover height at `ready_s`.
    Climb {
        ready_s: f64,
    },
}

/// How far back the waiting vehicle remembers the deck's highest (s): two swell periods at sea
/// state 6.
pub const RANGED_WINDOW_S: f64 = 30.0;

/// The waiting vehicle climbs as soon as it is this much below its waiting height (m)...
const WAIT_RAISE_M: f64 = 0.05;
/// ... and comes down only once it is this much above it (m), at [`WAIT_LOWER_MPS`]: the
/// crests of a swell come in groups, and a lull is no reason to go down and up again.
const WAIT_LOWER_M: f64 = 0.5;
const WAIT_LOWER_MPS: f64 = 0.5;
/// A vehicle following the deck with a lag moves to its lagged height within this long (s):
/// about a frame, when the autopilot hears from deckwatch.
const FOLLOW_STEP_S: f64 = 0.1;

/// The simulated autopilot: flies the shared [`deckwatch_sim::landing::FlightPath`] as the
/// commands come.
pub struct SimulatedAutopilot {
    pub model: ApproachModel,
    pub phase: Phase,
    path: SharedFlightPath,
    pub commits: u32,
    pub go_arounds: u32,
    /// The deck's height as ranged, (t s, m), over the last [`RANGED_WINDOW_S`], holding a
    /// height.
    ranged: std::collections::VecDeque<(f64, f64)>,
    /// The height in W it waits at (m), holding a height.
    waiting_m: f64,
    /// When (s) and where (m) its lagged surface tracking last put the deck.
    followed: Option<(f64, f64)>,
    /// The last descent's speed over the deck (m/s).
    pub descent_mps: f64,
}

impl SimulatedAutopilot {
    pub fn new(model: ApproachModel, path: SharedFlightPath) -> Self {
        Self {
            model,
            phase: Phase::Hover,
            path,
            commits: 0,
            go_arounds: 0,
            ranged: Default::default(),
            waiting_m: model.hover_m,
            followed: None,
            descent_mps: 0.0,
        }
    }

    /// Hovering at its height, able to commit at `t_s`.
    pub fn ready(&self, t_s: f64) -> bool {
        match self.phase {
            Phase::Hover => true,
            Phase::Climb { ready_s } => t_s >= ready_s,
            Phase::Descent { .. } => false,
        }
    }

    /// Whether a go-around ordered at `t_s` can still be flown: not descending (nothing to go
    /// around), or more of the descent left than its point of no return.
    pub fn can_go_around(&self, t_s: f64) -> bool {
        self.contact_s()
            .is_none_or(|contact_s| contact_s - t_s > self.model.no_return_s(self.descent_mps))
    }

    /// When it will touch the deck, while it descends.
    pub fn contact_s(&self) -> Option<f64> {
        match self.phase {
            Phase::Descent { contact_s, .. } => Some(contact_s),
            _ => None,
        }
    }

    /// The height it waits at now (m): over the deck when it follows the deck exactly, else in
    /// W.
    pub fn waiting_m(&self) -> f64 {
        self.waiting_target().0
    }

    /// Where it waits: a height (m), and whether over the deck (else in W).
    fn waiting_target(&self) -> (f64, bool) {
        match (self.model.follow_deck, self.followed) {
            (true, Some((_, deck_m))) if self.model.follow_lag_s > 0.0 => {
                (deck_m + self.model.hover_m, false)
            }
            (true, _) => (self.model.hover_m, true),
            (false, _) => (self.waiting_m, false),
        }
    }

    /// The deck ranged at `heave_m` at `t_s`: following the deck with a lag, its tracker moves on;
    /// holding a height, the waiting height follows the highest deck of the last
    /// [`RANGED_WINDOW_S`] (kept only then).
    fn range(&mut self, t_s: f64, heave_m: f64) {
        if self.model.follow_deck && self.model.follow_lag_s > 0.0 && heave_m.is_finite() {
            self.followed = Some(match self.followed {
                Some((t0, deck_m)) if t_s > t0 => {
                    let k = 1.0 - (-(t_s - t0) / self.model.follow_lag_s).exp();
                    (t_s, deck_m + k * (heave_m - deck_m))
                }
                Some(followed) => followed,
                // It arrives holding `hover_m` over the deck's mean level.
                None => (t_s, 0.0),
            });
        }
        if self.model.follow_deck {
            return;
        }
        if heave_m.is_finite() {
            self.ranged.push_back((t_s, heave_m));
        }
        while self
            .ranged
            .front()
            .is_some_and(|&(t, _)| t < t_s - RANGED_WINDOW_S)
        {
            self.ranged.pop_front();
        }
        let highest_m = self
            .ranged
            .iter()
            .map(|&(_, h)| h)
            .fold(f64::NEG_INFINITY, f64::max);
        let wanted_m = self.model.hover_m.max(highest_m + self.model.wait_clearance_m);
        if wanted_m > self.waiting_m + WAIT_RAISE_M || wanted_m < self.waiting_m - WAIT_LOWER_M {
            self.waiting_m = wanted_m;
        }
    }

    /// Acts on `command` at `t_s` (the deck being `heave_m` high then, as its range finder
    /// measures); true if it changed what the vehicle does (a commit or a go-around; a change
    /// of its waiting height is not).
    pub fn act(&mut self, t_s: f64, heave_m: f64, command: Command) -> bool {
        self.range(t_s, heave_m);
        let mut path = self.path.lock().unwrap_or_else(|e| e.into_inner());
        match command {
            Command::Land if self.ready(t_s) => {
                let from = path.over_deck_m(t_s, heave_m);
                let speed = (from - self.model.contact_m) / self.model.touchdown_s;
                path.move_to(t_s, heave_m, self.model.contact_m, speed, true);
                self.phase = Phase::Descent {
                    commit_s: t_s,
                    contact_s: t_s + self.model.touchdown_s,
                };
                self.descent_mps = speed;
                self.commits += 1;
                true
            }
            // Too late to keep off the deck: the descent goes on to contact.
            Command::GoAround if !self.can_go_around(t_s) => false,
            Command::GoAround if matches!(self.phase, Phase::Descent { .. }) => {
                let (to_m, over_deck) = self.waiting_target();
                path.move_to(t_s, heave_m, to_m, self.model.climb_mps, over_deck);
                self.phase = Phase::Climb {
                    ready_s: path.arrival_s(),
                };
                self.go_arounds += 1;
                true
            }
            _ => {
                if let Phase::Climb { ready_s } = self.phase {
                    if t_s >= ready_s {
                        self.phase = Phase::Hover;
                    }
                }
                let (to_m, over_deck) = self.waiting_target();
                if self.phase == Phase::Hover && path.target() != (to_m, over_deck) {
                    let now_m = path.height_m(t_s, heave_m) - if over_deck { heave_m } else { 0.0 };
                    let speed = if !over_deck && self.model.follow_deck {
                        // Tracking with a lag: there by the next frame.
                        ((to_m - now_m).abs() / FOLLOW_STEP_S).max(1e-3)
                    } else if to_m > now_m {
                        self.model.climb_mps
                    } else {
                        WAIT_LOWER_MPS
                    };
                    path.move_to(t_s, heave_m, to_m, speed, over_deck);
                }
                false
            }
        }
    }
}

/// A touchdown judged at contact against the true deck and the vehicle's true attitude.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TouchdownVerdict {
    /// Contact, on the approach's clock (s).
    pub t_s: f64,
    pub deck: TrueDeckState,
    /// The angle between the vehicle's and the deck's vertical axes (deg).
    pub relative_tilt_deg: f64,
    /// The limits broken (empty: a safe touchdown).
    pub violations: Vec<String>,
    /// The descent's speed over the deck, from the commit to contact (m/s); None where no
    /// descent was flown (the oracle's touchdowns).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub descent_mps: Option<f64>,
}

impl TouchdownVerdict {
    /// Judges contact at `t_s`: the deck (`truth`: roll, pitch deg and heave m over time) against
    /// `capacity`, the vehicle's attitude `r_v` against the deck's `r_d` (both body to W).
    pub fn judge(
        truth: TrueDeck,
        r_d: &RotationMatrix,
        r_v: &RotationMatrix,
        t_s: f64,
        capacity: &DecisionConfig,
        model: &ApproachModel,
    ) -> Self {
        let deck = TrueDeckState::at(truth, t_s);
        let up = nalgebra::Vector3::z();
        let cos = (r_d * up).dot(&(r_v * up)).clamp(-1.0, 1.0);
        let relative_tilt_deg = cos.acos().to_degrees();
        let mut violations: Vec<String> = deck.violations(capacity).into_iter().map(String::from).collect();
        if !(relative_tilt_deg <= model.max_relative_tilt_deg) {
            violations.push("relative-tilt".into());
        }
        Self {
            t_s,
            deck,
            relative_tilt_deg,
            violations,
            descent_mps: None,
        }
    }

    pub fn safe(&self) -> bool {
        self.violations.is_empty()
    }
}

/// One approach of one rule.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ApproachOutcome {
    pub commits: u32,
    pub go_arounds: u32,
    /// Why each go-around was ordered (the decision's reason), by name.
    pub abort_reasons: BTreeMap<String, u32>,
    /// Go-arounds ordered past the descent's point of no return (not flown: contact came as
    /// planned), by the decision's reason.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub too_late_reasons: BTreeMap<String, u32>,
    pub touchdown: Option<TouchdownVerdict>,
    /// Frames rendered, and decisions the autopilot received.
    pub frames: u64,
    pub decisions: u64,
    /// The decisions received, by state and reason (`HOLD warmup`, ...).
    pub decisions_by_reason: BTreeMap<String, u64>,
}

impl ApproachOutcome {
    /// A decision the autopilot received, counted by state and reason.
    pub fn count_decision(
        &mut self,
        state: DecisionState,
        reason: deckwatch_common::messages::DecisionReason,
    ) {
        let key = format!("{} {}", state.name(), reason.name());
        *self.decisions_by_reason.entry(key).or_default() += 1;
    }

    /// A go-around ordered during a descent, counted by its reason: as flown when ordered
    /// `in_time` ([`SimulatedAutopilot::can_go_around`]), else as ordered past the point of no
    /// return.
    pub fn count_go_around_order(
        &mut self,
        reason: deckwatch_common::messages::DecisionReason,
        in_time: bool,
    ) {
        let counts = if in_time {
            &mut self.abort_reasons
        } else {
            &mut self.too_late_reasons
        };
        *counts.entry(reason.name().into()).or_default() += 1;
    }
}

/// A rule's approaches added up.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RuleSummary {
    pub approaches: u64,
    pub commits: u64,
    pub touchdowns: u64,
    pub unsafe_touchdowns: u64,
    /// Limits broken at the unsafe touchdowns, by name.
    pub violations: BTreeMap<String, u64>,
    pub aborts: u64,
    pub abort_reasons: BTreeMap<String, u64>,
    /// Go-arounds ordered past a descent's point of no return, by reason (not flown).
    pub too_late_reasons: BTreeMap<String, u64>,
    /// Approaches that ended without a touchdown.
    pub timeouts: u64,
    /// Arrival to touchdown of each touchdown (s).
    pub arrival_to_touchdown_s: Vec<f64>,
    /// Each touchdown's descent speed over the deck (m/s).
    pub descent_mps: Vec<f64>,
    pub frames: u64,
    pub decisions_by_reason: BTreeMap<String, u64>,
}

impl RuleSummary {
    pub fn add(&mut self, o: &ApproachOutcome) {
        self.approaches += 1;
        self.commits += o.commits as u64;
        self.aborts += o.go_arounds as u64;
        self.frames += o.frames;
        for (k, v) in &o.abort_reasons {
            *self.abort_reasons.entry(k.clone()).or_default() += *v as u64;
        }
        for (k, v) in &o.too_late_reasons {
            *self.too_late_reasons.entry(k.clone()).or_default() += *v as u64;
        }
        for (k, v) in &o.decisions_by_reason {
            *self.decisions_by_reason.entry(k.clone()).or_default() += v;
        }
        match &o.touchdown {
            Some(v) => {
                self.touchdowns += 1;
                self.arrival_to_touchdown_s.push(v.t_s);
                self.descent_mps.extend(v.descent_mps);
                if !v.safe() {
                    self.unsafe_touchdowns += 1;
                    for name in &v.violations {
                        *self.violations.entry(name.clone()).or_default() += 1;
                    }
                }
            }
            None => self.timeouts += 1,
        }
    }

    pub fn merge(&mut self, other: &RuleSummary) {
        self.approaches += other.approaches;
        self.commits += other.commits;
        self.touchdowns += other.touchdowns;
        self.unsafe_touchdowns += other.unsafe_touchdowns;
        self.aborts += other.aborts;
        self.timeouts += other.timeouts;
        self.frames += other.frames;
        self.arrival_to_touchdown_s
            .extend_from_slice(&other.arrival_to_touchdown_s);
        self.descent_mps.extend_from_slice(&other.descent_mps);
        for (k, v) in &other.violations {
            *self.violations.entry(k.clone()).or_default() += v;
        }
        for (k, v) in &other.abort_reasons {
            *self.abort_reasons.entry(k.clone()).or_default() += v;
        }
        for (k, v) in &other.too_late_reasons {
            *self.too_late_reasons.entry(k.clone()).or_default() += v;
        }
        for (k, v) in &other.decisions_by_reason {
            *self.decisions_by_reason.entry(k.clone()).or_default() += v;
        }
    }

    /// Go-arounds per commit (NaN without commits).
    pub fn aborts_per_commit(&self) -> f64 {
        if self.commits == 0 {
            f64::NAN
        } else {
            self.aborts as f64 / self.commits as f64
        }
    }

    /// The safety case's figures (95 %): the unsafe-touchdown rate per touchdown with its exact
    /// one-sided upper bound, the landing rate per approach with its exact interval, go-arounds
    /// per commit, and arrival-to-touchdown percentiles.
    pub fn safety_case(&self) -> SafetyCase {
        let mut t = self.arrival_to_touchdown_s.clone();
        let p = deckwatch_common::stats::Percentiles::of(&mut t);
        SafetyCase {
            unsafe_rate: ratio(self.unsafe_touchdowns, self.touchdowns),
            unsafe_rate_upper_95: stats::upper_bound(self.unsafe_touchdowns, self.touchdowns, 0.95),
            landing_rate: ratio(self.touchdowns, self.approaches),
            landing_rate_95: stats::interval(self.touchdowns, self.approaches, 0.95),
            go_around_rate: self.aborts_per_commit(),
            arrival_to_touchdown_s_p50_p90_p99: p.map_or([f64::NAN; 3], |p| [p.p50, p.p90, p.p99]),
        }
    }

    /// The median time from arrival to touchdown (NaN without touchdowns).
    pub fn median_arrival_to_touchdown_s(&self) -> f64 {
        let mut t = self.arrival_to_touchdown_s.clone();
        t.sort_by(f64::total_cmp);
        match t.len() {
            0 => f64::NAN,
            n if n % 2 == 1 => t[n / 2],
            n => 0.5 * (t[n / 2 - 1] + t[n / 2]),
        }
    }
}

fn ratio(k: u64, n: u64) -> f64 {
    if n == 0 {
        f64::NAN
    } else {
        k as f64 / n as f64
    }
}

/// [`RuleSummary::safety_case`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SafetyCase {
    /// Unsafe touchdowns per touchdown (NaN without touchdowns).
    pub unsafe_rate: f64,
    /// Its exact (Clopper-Pearson) one-sided 95 % upper bound.
    pub unsafe_rate_upper_95: f64,
    /// Touchdowns per approach.
    pub landing_rate: f64,
    /// Its exact two-sided 95 % interval.
    pub landing_rate_95: [f64; 2],
    /// Go-arounds per commit.
    pub go_around_rate: f64,
    pub arrival_to_touchdown_s_p50_p90_p99: [f64; 3],
}

/// The oracle: knows the whole future motion, and commits the first time a touchdown would be
/// safe at contact (after the autopilot's `reaction_s`): the best any decision could do. It
/// needs no frames; `truth` and the attitudes are the approach's, `step_s` its frame interval.
pub fn oracle_approach(
    truth: TrueDeck,
    attitudes_at: &dyn Fn(f64) -> (RotationMatrix, RotationMatrix),
    capacity: &DecisionConfig,
    model: &ApproachModel,
    step_s: f64,
    reaction_s: f64,
) -> ApproachOutcome {
    let mut out = ApproachOutcome::default();
    let mut k = 0u64;
    loop {
        let t = k as f64 * step_s;
        if t + model.touchdown_s > model.max_approach_s {
            return out;
        }
        out.frames += 1;
        let contact = t + reaction_s + model.touchdown_s;
        let (r_d, r_v) = attitudes_at(contact);
        let v = TouchdownVerdict::judge(truth, &r_d, &r_v, contact, capacity, model);
        if v.safe() {
            out.commits = 1;
            out.touchdown = Some(v);
            return out;
        }
        k += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::Rpy;
    use deckwatch_sim::landing::FlightPath;
    use std::sync::{Arc, Mutex};

    /// ClearToLand that goes on past a touchdown's time holds a new commitment, which a
    /// follower of the decision message may take at its start (a vehicle not ready at the
    /// first); never in between, on a ride-through or on the watchdog's word.
    #[test]
    fn a_clearance_that_goes_on_is_renewed_a_touchdown_later() {
        let decision =
            |state: DecisionState, reason: DecisionReason, frame_s: f64, watchdog: bool| LandingDecision {
                state: state.into(),
                reason: reason.into(),
                attitude: deckwatch_common::messages::AttitudeMessage {
                    context: deckwatch_common::messages::FrameContext {
                        source_timestamp_ns: (frame_s * 1e9) as u64,
                        ..Default::default()
                    },
                    ..Default::default()
                },
                watchdog: watchdog.into(),
                ..Default::default()
            };
        let (clear, within) = (DecisionState::ClearToLand, DecisionReason::WithinCapacity);
        let mut follow = DecisionFollower::new(2.0);
        let commands: Vec<Command> = [
            (DecisionState::Hold, DecisionReason::PredictedOutside, 9.9, false),
            (clear, within, 10.0, false),
            (clear, within, 11.9, false),
            (clear, DecisionReason::RideThrough, 12.0, false),
            (clear, within, 12.05, true),
            (clear, within, 12.1, false),
            (clear, within, 14.0, false),
            (clear, within, 14.1, false),
        ]
        .into_iter()
        .map(|(state, reason, t, watchdog)| follow.command_on(&decision(state, reason, t, watchdog)))
        .collect();
        use Command::{Land, Wait};
        assert_eq!(commands, [Wait, Land, Wait, Wait, Wait, Land, Wait, Land]);
        // On the state alone (`dw_state`), only a change into ClearToLand commits; a start
        // without a frame time (the watchdog's) is not renewed by the frames after it.
        let mut follow = DecisionFollower::new(2.0);
        assert_eq!(follow.command(clear), Land);
        assert_eq!(follow.command(clear), Wait);
        assert_eq!(follow.command_on(&decision(clear, within, 20.0, false)), Wait);
        let mut follow = DecisionFollower::new(2.0);
        assert_eq!(follow.command_on(&decision(clear, within, 30.0, true)), Land);
        assert_eq!(follow.command_on(&decision(clear, within, 33.0, false)), Wait);
    }

    #[test]
    fn the_autopilot_commits_on_a_fresh_clearance_and_goes_around_on_abort() {
        let model = ApproachModel::quadrotor(2.0);
        let path = Arc::new(Mutex::new(FlightPath::hover(model.hover_m)));
        let mut ap = SimulatedAutopilot::new(model, path.clone());
        let mut follow = DecisionFollower::new(2.0);
        assert_eq!(follow.command(DecisionState::Hold), Command::Wait);
        assert_eq!(follow.command(DecisionState::ClearToLand), Command::Land);
        assert!(ap.act(10.0, 0.0, Command::Land));
        assert_eq!(ap.contact_s(), Some(12.0));
        // Still clear: no second commit.
        assert_eq!(follow.command(DecisionState::ClearToLand), Command::Wait);
        assert_eq!(follow.command(DecisionState::Abort), Command::GoAround);
        assert!(ap.act(11.0, 0.2, Command::GoAround));
        let over = path.lock().unwrap().over_deck_m(11.0, 0.2);
        assert!((over - (0.25 + 1.375)).abs() < 1e-9, "{over}");
        assert!(!ap.ready(11.5));
        // A clearance while it climbs is not acted on; once back at 3 m it may commit again.
        assert!(!ap.act(11.5, 0.0, Command::Land));
        let Phase::Climb { ready_s } = ap.phase else {
            panic!()
        };
        assert!(ap.ready(ready_s));
        assert!(ap.act(ready_s + 0.1, 0.0, Command::Land));
        assert_eq!((ap.commits, ap.go_arounds), (2, 1));
    }

    /// A go-around ordered with less of the descent left than its point of no return (the
    /// reaction, then braking from 1.375 m/s at 4 m/s^2: 0.27 s) is not flown: contact comes as
    /// planned. Ordered earlier, it is.
    #[test]
    fn a_go_around_ordered_past_the_point_of_no_return_is_not_flown() {
        let model = ApproachModel::quadrotor(2.0);
        let no_return_s = model.no_return_s(1.375);
        assert!((no_return_s - (0.1 + 1.375 / 8.0)).abs() < 1e-12, "{no_return_s}");
        // Every decision default covers this vehicle's fastest descents (1.66 m/s in trials).
        assert!(model.no_return_s(1.7) <= DecisionConfig::default().no_return_ms / 1e3);
        let path = Arc::new(Mutex::new(FlightPath::hover(model.hover_m)));
        let mut ap = SimulatedAutopilot::new(model, path.clone());
        assert!(ap.act(10.0, 0.0, Command::Land));
        assert!(ap.can_go_around(12.0 - no_return_s - 0.01));
        assert!(!ap.can_go_around(12.0 - no_return_s + 0.01));
        assert!(!ap.act(11.8, 0.0, Command::GoAround));
        assert_eq!(ap.contact_s(), Some(12.0));
        assert_eq!((ap.commits, ap.go_arounds), (1, 0));
        // Hovering, there is nothing to go around from.
        let mut hovering = SimulatedAutopilot::new(model, path.clone());
        assert!(hovering.can_go_around(0.0));
        assert!(!hovering.act(0.0, 0.0, Command::GoAround));
        // Earlier in the descent it is flown.
        let mut early =
            SimulatedAutopilot::new(model, Arc::new(Mutex::new(FlightPath::hover(model.hover_m))));
        assert!(early.act(10.0, 0.0, Command::Land));
        assert!(early.act(11.5, 0.0, Command::GoAround));
        assert_eq!((early.contact_s(), early.go_arounds), (None, 1));
    }

    #[test]
    fn holding_a_height_the_waiting_vehicle_keeps_its_clearance_over_a_swells_crests() {
        let model = ApproachModel {
            follow_deck: false,
            ..ApproachModel::quadrotor(2.0)
        };
        let run = |amplitude_m: f64| {
            let path = Arc::new(Mutex::new(FlightPath::hover(model.hover_m)));
            let mut ap = SimulatedAutopilot::new(model, path.clone());
            let heave = |t: f64| amplitude_m * (std::f64::consts::TAU * t / 12.0).sin();
            let mut least_over_deck_m = f64::INFINITY;
            for k in 0..600 {
                let t = k as f64 * 0.1;
                ap.act(t, heave(t), Command::Wait);
                least_over_deck_m = least_over_deck_m.min(path.lock().unwrap().over_deck_m(t, heave(t)));
            }
            let at_60_m = path.lock().unwrap().height_m(60.0, 0.0);
            (least_over_deck_m, ap.waiting_m(), at_60_m)
        };
        // A calm sea: it waits where it arrived.
        let (least_m, waiting_m, at_60_m) = run(0.2);
        assert!((least_m - 2.8).abs() < 1e-6 && waiting_m == 3.0 && at_60_m == 3.0);
        // A 2 m swell: it climbs with the first crest (1 m/s of heave against 1.5 m/s of climb,
        // a frame late) and waits 2.5 m over the crests (less its 5 cm of hysteresis), never
        // coming down between them.
        let (least_m, waiting_m, at_60_m) = run(2.0);
        assert!(least_m > 2.5 - 0.2, "{least_m}");
        assert!((4.45..=4.5).contains(&waiting_m), "{waiting_m}");
        assert!((at_60_m - waiting_m).abs() < 1e-9, "{at_60_m}");
        // A go-around climbs back to the waiting height, not to `hover_m`.
        let path = Arc::new(Mutex::new(FlightPath::hover(model.hover_m)));
        let mut ap = SimulatedAutopilot::new(model, path.clone());
        ap.act(0.0, 2.0, Command::Wait);
        assert!(ap.act(5.0, 0.0, Command::Land));
        assert!(
            (ap.descent_mps - (4.5 - 0.25) / 2.0).abs() < 1e-9,
            "{}",
            ap.descent_mps
        );
        assert!(ap.act(6.0, 0.0, Command::GoAround));
        let Phase::Climb { ready_s } = ap.phase else {
            panic!()
        };
        assert!((path.lock().unwrap().height_m(ready_s, 0.0) - 4.5).abs() < 1e-9);
    }

    #[test]
    fn following_the_deck_the_waiting_vehicle_rises_and_falls_with_it() {
        let model = ApproachModel {
            follow_lag_s: 0.0,
            ..ApproachModel::quadrotor(2.0)
        };
        assert!(model.follow_deck);
        let path = Arc::new(Mutex::new(FlightPath::hover(model.hover_m)));
        let mut ap = SimulatedAutopilot::new(model, path.clone());
        let heave = |t: f64| 2.0 * (std::f64::consts::TAU * t / 12.0).sin();
        for k in 0..600 {
            let t = k as f64 * 0.1;
            ap.act(t, heave(t), Command::Wait);
            let over_m = path.lock().unwrap().over_deck_m(t, heave(t));
            assert!((over_m - 3.0).abs() < 1e-9, "{t} s: {over_m}");
        }
        // Every descent is the same: 2.75 m in 2 s.
        assert!(ap.act(60.0, heave(60.0), Command::Land));
        assert!((ap.descent_mps - 2.75 / 2.0).abs() < 1e-9);
        // A go-around climbs back to 3 m over the deck.
        assert!(ap.act(61.0, heave(61.0), Command::GoAround));
        let Phase::Climb { ready_s } = ap.phase else {
            panic!()
        };
        let over_m = path.lock().unwrap().over_deck_m(ready_s, heave(ready_s));
        assert!((over_m - 3.0).abs() < 1e-9, "{over_m}");
    }

    #[test]
    fn following_the_deck_with_a_lag_the_waiting_vehicle_trails_the_swell() {
        let model = ApproachModel::quadrotor(2.0);
        assert_eq!((model.follow_deck, model.follow_lag_s), (true, 1.0));
        let path = Arc::new(Mutex::new(FlightPath::hover(model.hover_m)));
        let mut ap = SimulatedAutopilot::new(model, path.clone());
        // A 2 m swell of 12 s: a first-order lag of 1 s trails it by 2 wt / sqrt(1 + (wt)^2)
        // = 0.93 m at the most, plus the frame it takes to move.
        let w = std::f64::consts::TAU / 12.0;
        let heave = |t: f64| 2.0 * (w * t).sin();
        let (mut least_m, mut most_m) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..1200 {
            let t = k as f64 * 0.1;
            ap.act(t, heave(t), Command::Wait);
            let over_m = path.lock().unwrap().over_deck_m(t, heave(t));
            if t > 30.0 {
                least_m = least_m.min(over_m);
                most_m = most_m.max(over_m);
            }
        }
        let trail_m = 2.0 * w / (1.0 + w * w).sqrt();
        assert!((trail_m - 0.93).abs() < 0.01);
        assert!((3.0 - least_m - trail_m).abs() < 0.15, "{least_m}");
        assert!((most_m - 3.0 - trail_m).abs() < 0.15, "{most_m}");
        // A commit descends from where it is: at a rising deck, less than 2.75 m.
        let t = 120.0 + 0.25 / w; // just after an upward crossing of the mean
        ap.act(t, heave(t), Command::Wait);
        assert!(ap.act(t + 0.1, heave(t + 0.1), Command::Land));
        assert!(ap.descent_mps < 2.75 / 2.0 - 0.2, "{}", ap.descent_mps);
    }

    #[test]
    fn a_touchdown_is_judged_on_the_deck_and_the_tilt_between_them() {
        let c = DecisionConfig::default();
        let model = ApproachModel::quadrotor(c.touchdown_s);
        let level = RotationMatrix::identity();
        let calm = |t: f64| [1.0 * (0.5 * t).sin(), 0.5, 0.1 * t];
        let v = TouchdownVerdict::judge(&calm, &level, &level, 3.0, &c, &model);
        assert!(v.safe(), "{v:?}");
        // Heaving at 0.8 m/s: over the 0.6 m/s limit.
        let heaving = |t: f64| [0.0, 0.0, 0.8 * t];
        assert_eq!(
            TouchdownVerdict::judge(&heaving, &level, &level, 3.0, &c, &model).violations,
            vec!["heave-rate"]
        );
        // The vehicle 9 deg off a level deck.
        let tilted = Rpy::from_degrees(9.0, 0.0, 0.0).to_matrix();
        let v = TouchdownVerdict::judge(&calm, &level, &tilted, 3.0, &c, &model);
        assert_eq!(v.violations, vec!["relative-tilt"]);
        assert!((v.relative_tilt_deg - 9.0).abs() < 1e-9);
        let mut s = RuleSummary::default();
        for t in [30.0, 10.0, 20.0] {
            s.add(&ApproachOutcome {
                commits: 2,
                go_arounds: 1,
                touchdown: Some(TouchdownVerdict { t_s: t, ..v.clone() }),
                ..Default::default()
            });
        }
        assert_eq!(s.median_arrival_to_touchdown_s(), 20.0);
        assert_eq!((s.unsafe_touchdowns, s.aborts_per_commit()), (3, 0.5));
    }

    #[test]
    fn the_oracle_waits_for_the_first_safe_contact() {
        let c = DecisionConfig::default();
        let model = ApproachModel::quadrotor(c.touchdown_s);
        // Roll over the limit until t = 20 s, calm after.
        let sea = |t: f64| [if t < 20.0 { 8.0 } else { 1.0 }, 0.0, 0.0];
        let level = |_t: f64| (RotationMatrix::identity(), RotationMatrix::identity());
        let o = oracle_approach(&sea, &level, &c, &model, 0.1, 0.0);
        let t = o.touchdown.unwrap().t_s;
        assert!((20.0..20.2).contains(&t), "{t}");
    }
}
