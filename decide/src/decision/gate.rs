//! The input gate: what a frame must be before its deck is believed. Its time (a number, not in
//! the future, not stale), its values (finite; a deck height when the heave is required), not
//! frozen (bit-identical repeats), in order, and continuous with the history (a gap or a jump is
//! named, and three in a row restart the history).

use super::{DecisionConfig, DeckObservation, HEAVE, PITCH, ROLL};
use deckwatch_common::messages::DecisionReason;

/// A capture stamped further in the future than this (s) is a clock jump.
const MAX_FUTURE_S: f64 = 0.05;
/// No ship deck rises or falls faster (m/s): a faster change of the deck height is a jump.
const PLAUSIBLE_HEAVE_RATE_MPS: f64 = 5.0;
/// This many samples in a row that go back in time, or that jump, restart the history: they
/// agree with each other, not with what came before.
const RESTART_RUN: u32 = 3;

/// The gate's memory of the frames before.
#[derive(Debug, Clone, Default)]
pub(super) struct InputGate {
    /// The newest decision time (s): the clock of a frame whose own time is not a number.
    last_input: Option<f64>,
    /// The newest input's bits and how many times in a row it came.
    repeated: Option<([u64; 3], u32)>,
    /// Inputs in a row whose time went backwards.
    backwards_run: u32,
    /// Inputs in a row that jumped.
    jump_run: u32,
    /// The newest frame's time, and the interval before it (s): when the next frame is
    /// expected.
    last_frame_t: Option<f64>,
    frame_interval_s: Option<f64>,
}

/// How a sample follows the newest one of the history.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Continuity {
    /// It follows (or is the first); `gap_from`: the newest sample's time, where a gap between
    /// them starts.
    Follows { gap_from: Option<f64> },
    /// Its time does not advance: out of order or repeated; `restart` for the third in a row
    /// (the clock jumped back, or an earlier time was in the future).
    Backwards { restart: bool },
    /// It moved faster than a deck can (a bad estimate); `restart` for the third in a row.
    Jump { gap_from: Option<f64>, restart: bool },
}

impl InputGate {
    /// Remembers a frame's time (whatever is decided on it), before its decision: the interval
    /// to the next frame is the lead of the refit between frames and tells whether a committed
    /// touchdown's next decision comes before its point of no return. Intervals of 1 s or more
    /// are not a frame rate; a time that is not a number is not a frame's.
    pub(super) fn note_frame_time(&mut self, t: f64) {
        if !t.is_finite() {
            return;
        }
        if let Some(previous) = self.last_frame_t {
            self.frame_interval_s = Some(t - previous).filter(|dt| *dt > 0.0 && *dt < 1.0);
        }
        self.last_frame_t = Some(t);
    }

    pub(super) fn last_frame_t(&self) -> Option<f64> {
        self.last_frame_t
    }

    /// The time between the newest two frames (s), when it is a frame rate.
    pub(super) fn frame_interval_s(&self) -> Option<f64> {
        self.frame_interval_s
    }

    /// The time a decision at `now` is made at: `now`, or, when that is not a number, the
    /// newest decision's (a committed landing must still see itself committed and abort, not
    /// forget it).
    pub(super) fn clock(&mut self, now: f64) -> f64 {
        if now.is_finite() {
            self.last_input = Some(now);
            now
        } else {
            self.last_input.unwrap_or(f64::NEG_INFINITY)
        }
    }

    /// Whether the newest input is older than `max_age_ms` at `now` (None: no input yet, or the
    /// stale one was already reported); a stale one is forgotten, so it is reported once.
    pub(super) fn input_stale_at(&mut self, now: f64, max_age_ms: f64) -> Option<bool> {
        let last = self.last_input?;
        let stale = now - last > max_age_ms / 1e3;
        if stale {
            self.last_input = None;
        }
        Some(stale)
    }

    /// Why a frame captured at `t` and `age_s` old cannot be decided on for its time, if so.
    /// Judged for every frame, one without a deck included: a late frame without a deck is
    /// late, not missing (ridden through, 400 ms old frames with no deck kept a committed
    /// touchdown clear).
    pub(super) fn untimely(t: f64, age_s: f64, c: &DecisionConfig) -> Option<DecisionReason> {
        if !(t.is_finite() && age_s >= -MAX_FUTURE_S) {
            Some(DecisionReason::ClockJump)
        } else if !(age_s <= c.max_age_ms / 1e3) {
            Some(DecisionReason::StaleData)
        } else {
            None
        }
    }

    /// The sample of a deck (roll, pitch, and the height with `heave`, else NaN), or why there
    /// is none: its time's reason first, else the invalid attitude or the missing height.
    pub(super) fn sample(
        deck: Option<DeckObservation>,
        heave: bool,
        untimely: Option<DecisionReason>,
    ) -> Result<[f64; 3], DecisionReason> {
        let Some(deck) = deck.filter(|d| d.roll_deg.is_finite() && d.pitch_deg.is_finite()) else {
            return Err(untimely.unwrap_or(DecisionReason::InvalidAttitude));
        };
        if heave && !deck.height_m.is_finite() {
            return Err(untimely.unwrap_or(DecisionReason::NoDeckHeave));
        }
        Ok([
            deck.roll_deg,
            deck.pitch_deg,
            if heave { deck.height_m } else { f64::NAN },
        ])
    }

    /// Whether `sample` is the `frozen_input_count`th bit-identical one in a row. A real sensor
    /// never repeats itself bit for bit: a frozen one must not look calm. Every repeat counts,
    /// also one refused for its time (stale, out of order): a frozen camera's frames may come
    /// late and still be the same frame.
    pub(super) fn frozen(&mut self, sample: &[f64; 3], c: &DecisionConfig) -> bool {
        let bits = sample.map(f64::to_bits);
        let count = match self.repeated {
            Some((b, n)) if b == bits => n.saturating_add(1),
            _ => 1,
        };
        self.repeated = Some((bits, count));
        count >= c.frozen_input_count
    }

    /// How `sample` at `t` follows `newest`, the history's newest sample.
    pub(super) fn continuity(
        &mut self,
        t: f64,
        sample: &[f64; 3],
        newest: Option<(f64, [f64; 3])>,
        heave: bool,
        c: &DecisionConfig,
    ) -> Continuity {
        let mut gap_from = None;
        if let Some((tp, prev)) = newest {
            let dt = t - tp;
            if !(dt > 0.0) {
                self.backwards_run += 1;
                return Continuity::Backwards {
                    restart: self.backwards_run >= RESTART_RUN,
                };
            }
            if dt > c.max_gap_ms / 1e3 {
                gap_from = Some(tp);
            }
            let rate = (sample[ROLL] - prev[ROLL])
                .abs()
                .max((sample[PITCH] - prev[PITCH]).abs())
                / dt;
            let heave_rate = if heave {
                (sample[HEAVE] - prev[HEAVE]).abs() / dt
            } else {
                0.0
            };
            if rate > c.max_plausible_rate_dps || heave_rate > PLAUSIBLE_HEAVE_RATE_MPS {
                self.jump_run += 1;
                let restart = self.jump_run >= RESTART_RUN;
                if restart {
                    self.jump_run = 0;
                    self.backwards_run = 0;
                }
                return Continuity::Jump { gap_from, restart };
            }
        }
        self.jump_run = 0;
        self.backwards_run = 0;
        Continuity::Follows { gap_from }
    }

    /// The history restarts: runs counted against it end.
    pub(super) fn forget(&mut self) {
        self.backwards_run = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frames_time_is_judged_before_its_deck() {
        let c = DecisionConfig::default();
        assert_eq!(InputGate::untimely(1.0, 0.01, &c), None);
        assert_eq!(
            InputGate::untimely(1.0, 0.31, &c),
            Some(DecisionReason::StaleData)
        );
        assert_eq!(
            InputGate::untimely(1.0, -0.1, &c),
            Some(DecisionReason::ClockJump)
        );
        assert_eq!(
            InputGate::untimely(f64::NAN, 0.01, &c),
            Some(DecisionReason::ClockJump)
        );
        assert_eq!(
            InputGate::untimely(1.0, f64::NAN, &c),
            Some(DecisionReason::ClockJump)
        );
        // A stale frame without a deck is stale, not missing.
        assert_eq!(
            InputGate::sample(None, true, Some(DecisionReason::StaleData)),
            Err(DecisionReason::StaleData)
        );
        assert_eq!(
            InputGate::sample(None, true, None),
            Err(DecisionReason::InvalidAttitude)
        );
        let flat = DeckObservation::angles(1.0, 2.0);
        assert_eq!(
            InputGate::sample(Some(flat), true, None),
            Err(DecisionReason::NoDeckHeave)
        );
        let s = InputGate::sample(Some(flat), false, None).unwrap();
        assert_eq!((s[0], s[1]), (1.0, 2.0));
        assert!(s[2].is_nan());
    }

    #[test]
    fn repeats_bit_for_bit_are_frozen_from_the_configured_count() {
        let c = DecisionConfig::default();
        let mut gate = InputGate::default();
        let s = [1.0, 2.0, 0.1];
        assert!(!gate.frozen(&s, &c));
        assert!(!gate.frozen(&s, &c));
        assert!(gate.frozen(&s, &c), "the third of {}", c.frozen_input_count);
        assert!(!gate.frozen(&[1.0, 2.0, 0.1 + 1e-12], &c));
    }

    #[test]
    fn order_gaps_and_jumps_are_named_and_three_in_a_row_restart() {
        let c = DecisionConfig::default();
        let mut gate = InputGate::default();
        let s = [1.0, 1.0, 0.0];
        let newest = Some((10.0, s));
        assert_eq!(
            gate.continuity(10.0, &s, None, true, &c),
            Continuity::Follows { gap_from: None }
        );
        assert_eq!(
            gate.continuity(10.1, &s, newest, true, &c),
            Continuity::Follows { gap_from: None }
        );
        assert_eq!(
            gate.continuity(11.0, &s, newest, true, &c),
            Continuity::Follows { gap_from: Some(10.0) }
        );
        for k in 1..=3 {
            assert_eq!(
                gate.continuity(9.0, &s, newest, true, &c),
                Continuity::Backwards { restart: k == 3 }
            );
        }
        gate.forget();
        let jumped = [1.0 + 20.0, 1.0, 0.0];
        let heaved = [1.0, 1.0, 1.0];
        assert_eq!(
            gate.continuity(10.1, &jumped, newest, true, &c),
            Continuity::Jump {
                gap_from: None,
                restart: false
            }
        );
        assert_eq!(
            gate.continuity(10.1, &heaved, newest, true, &c),
            Continuity::Jump {
                gap_from: None,
                restart: false
            }
        );
        // A deck height is not judged without the heave.
        assert_eq!(
            gate.continuity(10.1, &heaved, newest, false, &c),
            Continuity::Follows { gap_from: None }
        );
        let far = [1.0 + 60.0, 1.0, 0.0];
        assert_eq!(
            gate.continuity(11.0, &far, newest, true, &c),
            Continuity::Jump {
                gap_from: Some(10.0),
                restart: false
            }
        );
        assert_eq!(
            gate.continuity(10.1, &jumped, newest, true, &c),
            Continuity::Jump {
                gap_from: None,
                restart: false
            }
        );
        assert_eq!(
            gate.continuity(10.1, &jumped, newest, true, &c),
            Continuity::Jump {
                gap_from: None,
                restart: true
            }
        );
    }

    #[test]
    fn the_frame_interval_is_a_frame_rate_or_none() {
        let mut gate = InputGate::default();
        gate.note_frame_time(1.0);
        assert_eq!(gate.frame_interval_s(), None);
        gate.note_frame_time(1.1);
        assert!((gate.frame_interval_s().unwrap() - 0.1).abs() < 1e-12);
        gate.note_frame_time(f64::NAN);
        assert_eq!(gate.last_frame_t(), Some(1.1));
        gate.note_frame_time(3.0);
        assert_eq!(gate.frame_interval_s(), None, "two seconds is a gap, not a rate");
        assert_eq!(gate.clock(f64::NAN), f64::NEG_INFINITY);
        assert_eq!(gate.clock(5.0), 5.0);
        assert_eq!(gate.clock(f64::NAN), 5.0);
        assert_eq!(gate.input_stale_at(5.2, 300.0), Some(false));
        assert_eq!(gate.input_stale_at(5.4, 300.0), Some(true));
        assert_eq!(gate.input_stale_at(5.5, 300.0), None);
    }
}
