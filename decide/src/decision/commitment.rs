//! The commitment: a state machine over the decisions. `ClearToLand` commits a touchdown of
//! `touchdown_s`; while it lasts, missing input may be ridden through (a budget per
//! commitment), the newest forecast may send it around (`Abort`, held for `abort_hold_s`), and
//! the last decision before its point of no return judges the rest as a clearance would.
//! This module keeps that state and its rules of time; what each judgement asks of the forecast
//! is the risk judge's (`risk`).

use super::DecisionConfig;
use deckwatch_common::messages::{DecisionReason, DecisionState};

/// The state of the commitment.
#[derive(Debug, Clone)]
pub(super) struct Commitment {
    pub(super) state: DecisionState,
    /// When the committed touchdown ends (contact; s).
    pub(super) commit_end: f64,
    abort_until: f64,
    abort_reason: DecisionReason,
    /// Blind time the committed touchdown has ridden through so far (s): one budget per
    /// commitment, however many spells it comes in.
    ridden_s: f64,
    /// The committed touchdown has been judged on its last chance before its point of no
    /// return.
    last_chance_taken: bool,
    /// The newest frame's time during the commitment (any verdict): each blind frame adds the
    /// interval since.
    commit_last_frame: f64,
    /// When the decision could first clear (every check passed up to the forecast's), since
    /// the history began or the last go-around: `early_risk_per_touchdown` applies for
    /// `early_window_s` from then. None: not yet.
    pub(super) early_since: Option<f64>,
}

impl Default for Commitment {
    fn default() -> Self {
        Self {
            state: DecisionState::NoDeck,
            commit_end: f64::NEG_INFINITY,
            abort_until: f64::NEG_INFINITY,
            abort_reason: DecisionReason::PredictedOutside,
            ridden_s: 0.0,
            last_chance_taken: false,
            commit_last_frame: f64::NEG_INFINITY,
            early_since: None,
        }
    }
}

/// Why a refused frame may be ridden through by a committed touchdown: missing data, and a
/// single implausible sample (refused, not believed: a deck does not move 40 deg/s; a second in
/// a row rides on, the third restarts the history and aborts). Not an input that is late,
/// frozen or unpredictable.
pub(super) fn missing_data(reason: DecisionReason) -> bool {
    matches!(
        reason,
        DecisionReason::InvalidAttitude
            | DecisionReason::NoVehicleAttitude
            | DecisionReason::NoDeckHeave
            | DecisionReason::Gap
            | DecisionReason::Jump
    )
}

impl Commitment {
    /// A committed touchdown is under way at `now`.
    pub(super) fn committed(&self, now: f64) -> bool {
        self.state == DecisionState::ClearToLand && now < self.commit_end
    }

    /// A go-around is being held at `now`.
    pub(super) fn aborting(&self, now: f64) -> bool {
        self.state == DecisionState::Abort && now < self.abort_until
    }

    /// The reason the held go-around was called for.
    pub(super) fn abort_reason(&self) -> DecisionReason {
        self.abort_reason
    }

    /// When the committed touchdown passes its point of no return (s): `no_return_ms` before
    /// contact, a go-around can no longer keep the vehicle off the deck.
    pub(super) fn no_return_at(&self, c: &DecisionConfig) -> f64 {
        self.commit_end - c.no_return_ms / 1e3
    }

    /// Whether a decision at `now`, before the point of no return, may be the last that can
    /// send the touchdown around: the next frame is expected within `next_frame_s` (with jitter
    /// and the watchdog's period for noticing that it did not come) at or after that point, or,
    /// blind with `blind_budget_left_s` to ride through, no seeing frame need come before it.
    /// Such a decision judges the rest of the touchdown as a clearance: seeing to contact, a
    /// touchdown judged at `go_around_risk` to its end would go on at up to that risk, on the
    /// word of frames whose go-around could not be flown. Past the point, a go-around is no
    /// longer the decision's to order: the touchdown is judged as a seeing one again.
    pub(super) fn last_chance(
        &self,
        c: &DecisionConfig,
        now: f64,
        next_frame_s: f64,
        blind_budget_left_s: Option<f64>,
    ) -> bool {
        let to_no_return_s = self.no_return_at(c) - now;
        if to_no_return_s <= 0.0 {
            // Past it with no last chance taken (the frames before it lost): this is the
            // nearest to one there is.
            return !self.last_chance_taken;
        }
        to_no_return_s <= next_frame_s
            || blind_budget_left_s.is_some_and(|budget_s| to_no_return_s <= budget_s)
    }

    /// Records that the last chance was (or was not) taken now.
    pub(super) fn take_last_chance(&mut self, last_chance: bool) {
        self.last_chance_taken |= last_chance;
    }

    /// Whether a committed touchdown, its last chance not yet judged, waits at `now` on an
    /// overdue frame (`overdue`) that would have to come after the next watchdog call
    /// (`watchdog_period_s`), at or past its point of no return.
    pub(super) fn silent_before_no_return(
        &self,
        c: &DecisionConfig,
        now: f64,
        overdue: bool,
        watchdog_period_s: f64,
    ) -> bool {
        self.committed(now)
            && !self.last_chance_taken
            && overdue
            && now + watchdog_period_s >= self.no_return_at(c)
    }

    /// A blind frame at `now` during the commitment: adds the time since the last frame to the
    /// budget ridden, and says whether the budget still holds and how much of it is left (s).
    /// Time must move on: a frame whose time does not advance (a stuck source clock) adds
    /// nothing to the budget and would ride through for ever.
    pub(super) fn ride_blind(&mut self, c: &DecisionConfig, now: f64) -> (bool, f64) {
        let advancing = now > self.commit_last_frame;
        if advancing {
            self.ridden_s += now - self.commit_last_frame;
        }
        let budget_s = c.ride_through_ms / 1e3;
        let within = advancing && c.ride_through_ms > 0.0 && self.ridden_s <= budget_s;
        (within, budget_s - self.ridden_s)
    }

    /// A frame came at `now` (any verdict) during the commitment.
    pub(super) fn note_frame(&mut self, now: f64) {
        self.commit_last_frame = self.commit_last_frame.max(now);
    }

    /// The decision could clear at `now` (every check passed up to the forecast's): starts the
    /// early window the first time.
    pub(super) fn could_clear(&mut self, now: f64) {
        self.early_since.get_or_insert(now);
    }

    /// Whether a clearance at `now` is within the early window (`early_window_s` from when the
    /// decision could first clear).
    pub(super) fn early(&self, c: &DecisionConfig, now: f64) -> bool {
        self.early_since
            .is_none_or(|since| now - since < c.ar().early_window_s)
    }

    /// Commits a touchdown at `now`.
    pub(super) fn begin(&mut self, c: &DecisionConfig, now: f64) {
        self.commit_end = now + c.touchdown_s;
        self.last_chance_taken = false;
        self.ridden_s = 0.0;
        self.commit_last_frame = now;
    }

    /// Takes the state of the decision made at `now`; a new go-around is held for
    /// `abort_hold_s`, and the next clearance looks for a deeper calm again.
    pub(super) fn settle(
        &mut self,
        c: &DecisionConfig,
        state: DecisionState,
        reason: DecisionReason,
        now: f64,
    ) {
        if state == DecisionState::Abort && self.state != DecisionState::Abort {
            self.early_since = None;
            self.abort_reason = reason;
            self.abort_until = now + c.abort_hold_s;
            self.commit_end = f64::NEG_INFINITY;
        }
        self.state = state;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn committed_at(c: &DecisionConfig, now: f64) -> Commitment {
        let mut m = Commitment::default();
        m.begin(c, now);
        m.settle(c, DecisionState::ClearToLand, DecisionReason::WithinCapacity, now);
        m
    }

    #[test]
    fn a_commitment_lasts_a_touchdown_and_a_go_around_is_held() {
        let c = DecisionConfig::default();
        let mut m = committed_at(&c, 10.0);
        assert!(m.committed(11.9) && !m.committed(12.0));
        assert!((m.no_return_at(&c) - (12.0 - 0.35)).abs() < 1e-12);
        m.could_clear(5.0);
        m.settle(&c, DecisionState::Abort, DecisionReason::PredictedOutside, 11.0);
        assert!(m.aborting(12.9) && !m.aborting(13.0));
        assert_eq!(m.abort_reason(), DecisionReason::PredictedOutside);
        assert!(!m.committed(11.5), "a go-around ends the commitment");
        assert_eq!(m.early_since, None, "and starts the early window again");
    }

    #[test]
    fn the_last_chance_is_the_last_decision_before_the_point_of_no_return() {
        let c = DecisionConfig::default();
        let mut m = committed_at(&c, 10.0);
        let no_return = m.no_return_at(&c);
        // The next frame (0.1 s at 10 Hz, half a frame to spare, the watchdog's period) comes
        // before the point: not yet.
        assert!(!m.last_chance(&c, no_return - 0.3, 0.17, None));
        assert!(m.last_chance(&c, no_return - 0.1, 0.17, None));
        // Blind, a budget that reaches the point makes any decision the last chance.
        assert!(m.last_chance(&c, no_return - 0.6, 0.17, Some(0.7)));
        // Past it, the first decision is the nearest to one there is; then no more.
        assert!(m.last_chance(&c, no_return + 0.1, 0.17, None));
        m.take_last_chance(true);
        assert!(!m.last_chance(&c, no_return + 0.1, 0.17, None));
        assert!(!m.silent_before_no_return(&c, no_return - 0.01, true, 0.02));
    }

    #[test]
    fn one_blind_budget_per_commitment_and_only_while_time_moves() {
        let c = DecisionConfig::default();
        let mut m = committed_at(&c, 10.0);
        assert_eq!(m.ride_blind(&c, 10.5), (true, 0.5));
        m.note_frame(10.5);
        // The same time again adds nothing and is not ridden.
        assert!(!m.ride_blind(&c, 10.5).0);
        let (within, left) = m.ride_blind(&c, 11.1);
        assert!(!within && left < 0.0, "{left}");
        assert!(missing_data(DecisionReason::Gap) && missing_data(DecisionReason::Jump));
        assert!(!missing_data(DecisionReason::StaleData) && !missing_data(DecisionReason::FrozenInput));
        assert!(!missing_data(DecisionReason::PredictionUnreliable));
    }
}
