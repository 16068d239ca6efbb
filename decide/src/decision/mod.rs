//! The landing decision: a state machine over the attitude stream with deck-motion prediction.
//!
//! - `NoDeck`: no valid attitude.
//! - `Hold`: a deck, but committing now is not safe (or not known to be safe: warm-up, stale
//!   data, a gap, a jump, a prediction that does not fit the history).
//! - `ClearToLand`: commit now. The deck is forecast to stay within the capacity (angles,
//!   tilt, rates) from now until the end of the touchdown at the accepted risk. Staying (until
//!   the committed touchdown is over) needs only `go_around_risk`, so it does not chatter on
//!   the edge; the last decision before the point of no return is judged as a clearance.
//! - `Abort`: a committed landing became unsafe (or unknowable); held for `abort_hold_s`.
//!
//! Time is the frames' capture time (seconds of one monotonic clock); `now` is when the
//! decision is made. Pure: no clock, no IPC; the stage and the evaluation harness drive it.
//!
//! [`Decider`] composes the parts, each in its own module: the input gate (`gate`), the
//! history of accepted samples (`history`), the forecaster ([`crate::forecast`]) and its upkeep
//! (`models`), the band's calibration (`band`, `rate_history`), the risk judge (`risk`) and the
//! commitment (`commitment`); [`LandingDecider`] is the one over the configured forecaster. The
//! configuration is in `config` and `forecast_config`.

use crate::forecast::{ChannelForecast, Forecaster};
use deckwatch_common::messages::{DecisionReason, DecisionState};

mod band;
mod commitment;
mod config;
mod coverage;
mod forecast_config;
mod gate;
mod history;
mod landing_decider;
mod models;
mod rate_history;
mod risk;
mod types;

pub use config::{
    moved_key, DecisionConfig, HeaveUse, AUTOPILOT_ATTITUDE_ERROR_DEG, AUTOPILOT_VERTICAL_SPEED_ERROR_MPS,
    MAX_FROZEN_INPUT_COUNT, MOVED_KEYS, SAFETY_BOUNDS,
};
pub use forecast_config::{ArForecastConfig, ForecastConfig, FORECAST_SAFETY_BOUNDS, MAX_EARLY_WINDOW_S};
pub use landing_decider::LandingDecider;
pub use risk::tilt_deg;
pub(crate) use types::Z95;
pub use types::{Decision, DeckForecast, DeckObservation};

use commitment::{missing_data, Commitment};
use gate::{Continuity, InputGate};
use history::History;
use models::{Models, Tracking};
use risk::{calm_window, predicted_within, Judgement};

/// The predicted channels, in this order: roll (deg), pitch (deg), and the deck's height (m)
/// when `[decide] heave = "required"`.
const ROLL: usize = 0;
const PITCH: usize = 1;
const HEAVE: usize = 2;

/// Window of the measured rate the capacity is checked against (s).
const RATE_WINDOW_S: f64 = 0.6;

/// How often decide's watchdog looks for a silence, at most (s): 50 times a second costs
/// nothing, and a touchdown's last chance comes that much earlier to leave room for it.
const WATCHDOG_PERIOD_S: f64 = 0.02;

/// The decision state machine over any forecaster `F` ([`LandingDecider`] is the one with the
/// configured forecaster).
pub struct Decider<F: Forecaster> {
    config: DecisionConfig,
    /// Channels predicted: 2 (roll, pitch) or 3 (and heave).
    channels: usize,
    gate: InputGate,
    history: History,
    tracking: Tracking<F>,
    commitment: Commitment,
    /// The calm window found at the last refit (absolute start, length), and that refit's time.
    calm_cache: Option<(f64, Option<(f64, f64)>)>,
}

impl<F: Forecaster> Decider<F> {
    /// The decider with another forecaster (the configuration's `[decide.forecast]` tuning
    /// still sets the window, the refits and the holds).
    pub fn with_forecaster(
        config: DecisionConfig,
        forecaster: F,
    ) -> Result<Self, deckwatch_common::InvalidField> {
        config.validate()?;
        Ok(Self {
            channels: if config.heave == HeaveUse::Required { 3 } else { 2 },
            config,
            gate: InputGate::default(),
            history: History::default(),
            tracking: Tracking::new(forecaster),
            commitment: Commitment::default(),
            calm_cache: None,
        })
    }

    pub fn config(&self) -> &DecisionConfig {
        &self.config
    }

    pub fn state(&self) -> DecisionState {
        self.commitment.state
    }

    /// Decides on the deck of a frame captured at `t` (None: no valid attitude), at time `now`.
    pub fn update(&mut self, t: f64, deck: Option<DeckObservation>, now: f64) -> Decision {
        self.decide(t, deck, now - t, now)
    }

    /// Decides on the deck of a frame captured at `t` that was `age_s` old when it arrived, on
    /// the frames' own timeline: the decision is made as of the capture time. Freshness is
    /// judged by `age_s` (one monotonic clock), everything else by `t` alone, so the same
    /// frames give the same decisions however long the pipeline took, in one process or in
    /// four (the stage uses this; `update` is for callers that model the delay themselves).
    pub fn update_at_capture(&mut self, t: f64, deck: Option<DeckObservation>, age_s: f64) -> Decision {
        self.decide(t, deck, age_s, t)
    }

    /// Refuses a frame's input for `reason` (say, its attitude could not be compensated for the
    /// vehicle's), deciding at `now`: never clear on it, abort a committed landing.
    pub fn refuse(&mut self, now: f64, reason: DecisionReason) -> Decision {
        self.gate.note_frame_time(now);
        let now = self.gate.clock(now);
        self.transition(Err(reason), now)
    }

    /// Why a frame captured at `t` that was `age_s` old on arrival cannot be decided on by its
    /// time alone (stale, or a clock that is no number or runs ahead), if it cannot.
    pub(crate) fn untimely(&self, t: f64, age_s: f64) -> Option<DecisionReason> {
        InputGate::untimely(t, age_s, &self.config)
    }

    fn decide(&mut self, t: f64, deck: Option<DeckObservation>, age_s: f64, now: f64) -> Decision {
        self.gate.note_frame_time(t);
        let now = self.gate.clock(now);
        let verdict = self.check(t, deck, age_s);
        self.transition(verdict, now)
    }

    /// Fits the motion model now when the next frame, expected `lead_s` after the newest
    /// sample, would fit it: called once a decision is out, the fit (a millisecond or more
    /// every `refit_interval_s`) runs between frames instead of on a frame's path. That frame
    /// then decides with the model fitted up to the sample before it, as every other frame
    /// decides with one fitted up to a second earlier. Does nothing during warm-up, in a gap,
    /// or before a first model (that fit stays with the frame that completes the warm-up).
    pub fn refit_ahead(&mut self, lead_s: f64) {
        if let Some(t) = self.refit_due(lead_s) {
            self.tracking.refit(&self.config, &self.history, self.channels, t);
        }
    }

    /// Whether [`Self::refit_ahead`] would fit now: the newest sample's time if so.
    pub fn refit_due(&self, lead_s: f64) -> Option<f64> {
        let f = self.config.ar();
        let (t, _) = self.history.newest()?;
        let span = self.history.span_to(t);
        // Half a frame to spare: a refit due exactly at the next frame (a retry 9 frames of
        // 1/30 s later) must not be missed by a rounding.
        let due = t + 1.5 * lead_s.max(0.0) - self.tracking.last_fit >= f.refit_interval_s;
        let ready = self.tracking.models.is_some() && t >= self.tracking.gap_until && span >= f.min_history_s;
        (due && ready && lead_s.is_finite()).then_some(t)
    }

    /// What the current forecast says of time `t` (None without one): the values and rates of
    /// roll, pitch (deg, deg/s) and the deck height (m, m/s; NaN without heave), and the
    /// half-width of the band it states for 95 % of outcomes, calibrated by its misses.
    pub fn forecast(&self, t: f64) -> Option<DeckForecast> {
        Some(self.tracking.models.as_ref()?.deck_forecast(t))
    }

    /// The time between the newest two frames (s), when it is a frame rate.
    pub fn frame_interval_s(&self) -> Option<f64> {
        self.gate.frame_interval_s()
    }

    /// Called when no input arrived, at least every [`Self::watchdog_period_s`]: once the
    /// newest attitude is older than `max_age_ms`, the decision becomes stale (`Abort` if
    /// committed, else `NoDeck`). Sooner for a committed touchdown whose last chance has not
    /// come: once the frame it waits for is overdue (half a frame late) and its point of no
    /// return would pass before the next call, the silence is judged now as a blind frame at
    /// its last chance (reason `gap`): the touchdown rides through if the model the last frame
    /// confirmed keeps the deck within the capacity at a clearance's risk, and goes around
    /// while that can still be flown if not. A pipeline that falls silent then does not carry
    /// a touchdown past the point on decisions judged at `go_around_risk` only, with an abort
    /// that comes too late to fly.
    pub fn timeout(&mut self, now: f64) -> Option<Decision> {
        if self.gate.input_stale_at(now, self.config.max_age_ms)? {
            return Some(self.transition(Err(DecisionReason::StaleData), now));
        }
        self.silent_before_no_return(now)
            .then(|| self.transition(Err(DecisionReason::Gap), now))
    }

    /// How often [`Self::timeout`] is to be called at least (s). A committed touchdown's last
    /// chance comes early enough to leave this much time for a silence after it to be noticed
    /// before the point of no return.
    pub fn watchdog_period_s(&self) -> f64 {
        // At least a millisecond: a freshness limit of microseconds must not make the process
        // (or the trials' runner) look without end.
        WATCHDOG_PERIOD_S.min(self.config.max_age_ms / 2e3).max(1e-3)
    }

    /// Whether a committed touchdown waits at `now` on an overdue frame (half a frame late; no
    /// frame rate known: half the freshness limit) that would come at or past its point of no
    /// return.
    fn silent_before_no_return(&self, now: f64) -> bool {
        let Some(last_frame_t) = self.gate.last_frame_t() else {
            return false;
        };
        let overdue_after_s = self
            .gate
            .frame_interval_s()
            .map_or(self.config.max_age_ms / 2e3, |interval_s| 1.5 * interval_s);
        let overdue = now - last_frame_t > overdue_after_s;
        self.commitment
            .silent_before_no_return(&self.config, now, overdue, self.watchdog_period_s())
    }

    /// The input gate, then the forecast's checks: whether a frame's deck may be decided on
    /// (Ok: the forecast explains it and is up to date), or why not.
    fn check(&mut self, t: f64, deck: Option<DeckObservation>, age_s: f64) -> Result<(), DecisionReason> {
        let c = &self.config;
        let heave = self.channels > HEAVE;
        let untimely = InputGate::untimely(t, age_s, c);
        let sample = InputGate::sample(deck, heave, untimely)?;
        // A valid deck's repeats are counted before its time is refused.
        if self.gate.frozen(&sample, c) {
            // What came while it was frozen is not the deck's motion: learn afresh after it.
            self.forget();
            return Err(DecisionReason::FrozenInput);
        }
        if let Some(reason) = untimely {
            return Err(reason);
        }
        let c = &self.config;
        match self.gate.continuity(t, &sample, self.history.newest(), heave, c) {
            Continuity::Backwards { restart } => {
                if restart {
                    self.forget();
                }
                return Err(DecisionReason::ClockJump);
            }
            Continuity::Follows { gap_from } => {
                if let Some(before) = gap_from {
                    self.tracking.gap(c, before, t);
                }
            }
            Continuity::Jump { gap_from, restart } => {
                if let Some(before) = gap_from {
                    self.tracking.gap(c, before, t);
                }
                if !restart {
                    return Err(DecisionReason::Jump);
                }
                self.forget();
            }
        }
        self.history.push(t, sample, self.config.ar().window_s);
        let committed = self.commitment.committed(t);
        self.tracking
            .check(&self.config, &self.history, self.channels, t, &sample, committed)
    }

    /// Forgets the history and the models: what follows is learnt afresh (warm-up).
    fn forget(&mut self) {
        self.commitment.early_since = None;
        self.history.clear();
        self.tracking.forget();
        self.gate.forget();
    }

    /// Whether the rates measured through the newest samples (`RATE_WINDOW_S`) are beyond the
    /// capacity, whatever the forecast says.
    fn measured_rate_outside(&self) -> bool {
        let c = &self.config;
        let Some((t, _)) = self.history.newest() else {
            return false;
        };
        self.history.line_rate(t, RATE_WINDOW_S).is_some_and(|rates| {
            rates[ROLL].abs() > c.max_abs_roll_rate_dps
                || rates[PITCH].abs() > c.max_abs_pitch_rate_dps
                || (self.channels > HEAVE && rates[HEAVE].abs() > c.max_abs_heave_rate_mps)
        })
    }

    /// The next frame is expected within this (s): half a frame to spare for jitter, and the
    /// watchdog's next look ([`Self::timeout`]) if it does not come.
    fn next_frame_s(&self) -> f64 {
        1.5 * self.gate.frame_interval_s().unwrap_or(0.0) + self.watchdog_period_s()
    }

    /// Whether a committed touchdown goes on through this refused input at `now`: only for
    /// missing data (`commitment::missing_data`), for at most `ride_through_ms` in a row, and
    /// only while the forecast the last good input confirmed keeps the deck within the capacity
    /// to the touchdown's end: at a clearance's risk when the blind budget left reaches the
    /// point of no return or this is the last decision before it, else at a seeing
    /// touchdown's. With every dropped frame judged as blind to contact, `decide-eval` with
    /// faults sent 21-23 touchdowns around for it, against 6.
    fn rides_through(&mut self, reason: DecisionReason, now: f64) -> bool {
        let (within_budget, budget_left_s) = self.commitment.ride_blind(&self.config, now);
        let next_frame_s = self.next_frame_s();
        let last_chance = self
            .commitment
            .last_chance(&self.config, now, next_frame_s, Some(budget_left_s));
        self.commitment.take_last_chance(last_chance);
        let c = &self.config;
        let bounded = self.tracking.models.as_ref().is_some_and(|m| {
            let judgement = if last_chance {
                Judgement::last_chance(c)
            } else {
                Judgement::stay(c)
            };
            predicted_within(c, m, now, self.commitment.commit_end, judgement)
        });
        missing_data(reason) && within_budget && bounded
    }

    /// The calm window, searched once per model (the search walks the whole horizon).
    fn cached_calm_window(
        &mut self,
        m: &Models<F::Channel>,
        now: f64,
        judgement: Judgement,
    ) -> Option<(f64, f64)> {
        let last_fit = self.tracking.last_fit;
        let fresh = match self.calm_cache {
            Some((fit, Some((start, len)))) => {
                fit == last_fit && now <= start + len - self.config.touchdown_s
            }
            Some((fit, None)) => fit == last_fit,
            None => false,
        };
        if !fresh {
            let w = calm_window(&self.config, m, now, judgement).map(|(s, l)| (now + s, l));
            self.calm_cache = Some((last_fit, w));
        }
        let (start, len) = self.calm_cache?.1?;
        let passed = (now - start).max(0.0);
        Some(((start - now).max(0.0), len - passed))
    }

    /// The decision on the verdict of `check` (or a refusal) at `now`: the commitment's state
    /// machine, each judgement of the forecast made by the risk judge.
    fn transition(&mut self, verdict: Result<(), DecisionReason>, now: f64) -> Decision {
        let committed = self.commitment.committed(now);
        let aborting = self.commitment.aborting(now);
        let mut decision = Decision {
            state: DecisionState::Hold,
            reason: DecisionReason::WithinCapacity,
            calm_window: None,
            new_commit: false,
            heave_rate_mps: f64::NAN,
        };
        let ride = match verdict {
            Err(reason) if committed => self.rides_through(reason, now),
            _ => false,
        };
        if committed {
            self.commitment.note_frame(now);
        }
        match verdict {
            Err(_) if ride => {
                decision.state = DecisionState::ClearToLand;
                decision.reason = DecisionReason::RideThrough;
            }
            Err(reason) => {
                decision.reason = reason;
                decision.state = if committed || aborting {
                    DecisionState::Abort
                } else if matches!(
                    reason,
                    DecisionReason::InvalidAttitude | DecisionReason::StaleData
                ) {
                    DecisionState::NoDeck
                } else {
                    DecisionState::Hold
                };
            }
            Ok(()) => {
                // Taken out and put back below, not cloned: no allocation per decision.
                let m = self.tracking.models.take().expect("checked");
                self.judge(&m, now, committed, aborting, &mut decision);
                self.tracking.models = Some(m);
            }
        }
        // What the heave model says now, whether or not it may be trusted to clear (shown to the
        // ground station and in the viewer).
        decision.heave_rate_mps = self
            .tracking
            .models
            .as_ref()
            .and_then(|m| m.forecasts.get(HEAVE))
            .map_or(f64::NAN, |h| h.rate(now));
        self.commitment
            .settle(&self.config, decision.state, decision.reason, now);
        decision
    }

    /// A frame the forecast explains, judged at `now`: stay committed or go around; hold a
    /// go-around; or clear a new touchdown, every refusal before it in turn.
    fn judge(
        &mut self,
        m: &Models<F::Channel>,
        now: f64,
        committed: bool,
        aborting: bool,
        decision: &mut Decision,
    ) {
        let c = self.config.clone();
        decision.calm_window = self.cached_calm_window(m, now, Judgement::entry(&c));
        if committed {
            // Staying needs only `go_around_risk`, until the last decision that can send the
            // touchdown around: that one is its clearance.
            let last_chance = self.commitment.last_chance(&c, now, self.next_frame_s(), None);
            self.commitment.take_last_chance(last_chance);
            let judgement = if last_chance {
                Judgement::last_chance(&c)
            } else {
                Judgement::stay(&c)
            };
            if predicted_within(&c, m, now, self.commitment.commit_end, judgement) {
                decision.state = DecisionState::ClearToLand;
            } else {
                decision.state = DecisionState::Abort;
                decision.reason = DecisionReason::PredictedOutside;
            }
        } else if aborting {
            // Held: still the reason the landing was aborted for.
            decision.state = DecisionState::Abort;
            decision.reason = self.commitment.abort_reason();
        } else if now - self.tracking.unexplained_at < c.ar().holdout_s {
            // The model just failed to explain a measurement, and its successor's band has no
            // track record of its own yet: the evidence behind the band is of the models before
            // (a noise-free heave cleared 1.1 s after such a miss into 0.635 m/s: unit test
            // `the_heave_rate_is_part_of_the_capacity`).
            // Named ahead of an unchecked band: the miss is the newer, more telling reason.
            decision.reason = DecisionReason::PredictionUnreliable;
        } else if !m.band_checked {
            // A band not yet checked against what came after is not cleared on (a held-out
            // trial cleared on one 3 s after the warm-up and touched down at 0.62 m/s of heave
            // rate).
            decision.reason = DecisionReason::Warmup;
        } else if self.measured_rate_outside() {
            // The deck is measured moving faster than the capacity now, whatever the model says
            // (a noise-free heave whose model was off by 0.06 m/s cleared at a measured 0.61 m/s
            // against 0.6).
            decision.reason = DecisionReason::OutsideCapacity;
        } else if self.clears(m, now) {
            decision.state = DecisionState::ClearToLand;
            decision.new_commit = true;
            self.commitment.begin(&c, now);
        } else {
            decision.reason = if predicted_within(&c, m, now, now, Judgement::MEAN) {
                DecisionReason::PredictedOutside
            } else {
                DecisionReason::OutsideCapacity
            };
        }
    }

    /// Whether a new touchdown may be cleared at `now`, every other check passed: the forecast
    /// keeps the deck within the capacity over it at a commitment's risk. The first time since
    /// the history began or the last go-around, this starts the early window.
    fn clears(&mut self, m: &Models<F::Channel>, now: f64) -> bool {
        self.commitment.could_clear(now);
        let c = &self.config;
        let judgement = Judgement::commit(c, self.commitment.early(c, now));
        predicted_within(c, m, now, now + c.touchdown_s, judgement)
    }
}

#[cfg(test)]
mod tests;
