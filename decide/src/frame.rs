//! One frame as the decision sees it, and the one code path that decides on it.
//!
//! The decide stage (on the pipeline's messages) and the evaluations (`decide-eval`, the
//! closed-loop trials, on simulated streams) both build a [`FrameInput`] and call
//! [`crate::LandingDecider::decide_frame`] and then [`crate::LandingDecider::refit_between_frames`], so what
//! is measured is what flies: the same refusals in the same order, on the frames' own timeline.

use crate::decision::{Decider, Decision, DeckObservation};
use crate::forecast::Forecaster;
use deckwatch_common::messages::{AttitudeFailure, AttitudeMessage, DecisionReason};
use deckwatch_common::vehicle::Compensation;

/// What the decision needs to know about one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameInput {
    /// Capture time on the frames' own timeline (s): simulated time, a recording's stamps, the
    /// sensor's clock. Everything but freshness is judged on it.
    pub t_s: f64,
    /// The measured deck; None when the frame has no valid attitude.
    pub deck: Option<DeckObservation>,
    /// Capture to decision on one monotonic clock (s): freshness. Infinite when unknown.
    pub age_s: f64,
    /// The vehicle's attitude was missing, so the deck attitude is relative to a camera that
    /// may be tilted: refused (`no-vehicle-attitude`).
    pub vehicle_missing: bool,
    /// The estimator found the image repeated bit for bit (a frozen camera): refused
    /// (`frozen-input`), and never ridden through.
    pub frozen_image: bool,
}

impl FrameInput {
    /// A fresh, valid frame: the common case of simulations.
    pub fn measured(t_s: f64, deck: Option<DeckObservation>, age_s: f64) -> Self {
        Self {
            t_s,
            deck,
            age_s,
            vehicle_missing: false,
            frozen_image: false,
        }
    }

    /// The decide stage's view of an attitude received at `received_ns` (`CLOCK_MONOTONIC`).
    /// A message without a capture time cannot be judged fresh.
    pub fn from_attitude(a: &AttitudeMessage, received_ns: u64) -> Self {
        let deck = a.valid.get().then(|| {
            let [r, p, _] = a.rpy.to_degrees();
            DeckObservation::new(r, p, a.deck_height_m)
        });
        let captured_ns = a.stamp.times.captured_ns;
        let age_s = if captured_ns == 0 {
            f64::INFINITY
        } else {
            (received_ns as f64 - captured_ns as f64) / 1e9
        };
        Self {
            t_s: a.context.source_timestamp_ns as f64 / 1e9,
            deck,
            age_s,
            vehicle_missing: a.vehicle.compensation == Compensation::Missing,
            frozen_image: a.failure == AttitudeFailure::FrozenImage,
        }
    }
}

impl<F: Forecaster> Decider<F> {
    /// Decides on one frame, as of its capture time. The refusals that come from outside the
    /// attitude stream go first: a deck seen by an uncompensated camera (the deck relative to
    /// a tilted camera is not the deck; ridden through during a committed touchdown like any
    /// missing attitude), then a frozen image (a broken camera: nothing rides through it). Then
    /// the decider's own checks (stale, clock, frozen input, jumps, gaps, warm-up, the
    /// prediction). A refused frame's time is judged first: one that is stale (or from a clock
    /// that jumped) is refused as such, so that stale data is never ridden through whatever
    /// else it lacks.
    pub fn decide_frame(&mut self, frame: &FrameInput) -> Decision {
        let outside = if frame.deck.is_some() && frame.vehicle_missing {
            Some(DecisionReason::NoVehicleAttitude)
        } else if frame.frozen_image {
            Some(DecisionReason::FrozenInput)
        } else {
            None
        };
        match outside {
            Some(reason) => {
                let reason = self.untimely(frame.t_s, frame.age_s).unwrap_or(reason);
                self.refuse(frame.t_s, reason)
            }
            None => self.update_at_capture(frame.t_s, frame.deck, frame.age_s),
        }
    }

    /// Once a frame's decision is out: the motion model's refit (a millisecond or more every
    /// `refit_interval_s`) runs now, between frames, instead of on the next frame's path.
    /// Returns whether it refitted.
    pub fn refit_between_frames(&mut self) -> bool {
        let Some(lead_s) = self.frame_interval_s() else {
            return false;
        };
        if self.refit_due(lead_s).is_none() {
            return false;
        }
        self.refit_ahead(lead_s);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decision::DecisionConfig;
    use crate::LandingDecider;
    use deckwatch_common::messages::DecisionState;
    use deckwatch_common::Rpy;

    #[test]
    fn an_attitude_message_becomes_its_frame_input() {
        let mut a = AttitudeMessage {
            valid: true.into(),
            rpy: Rpy::from_degrees(1.5, -2.0, 30.0),
            deck_height_m: 0.25,
            ..Default::default()
        };
        a.context.source_timestamp_ns = 2_500_000_000;
        a.stamp.times.captured_ns = 10_000_000_000;
        let f = FrameInput::from_attitude(&a, 10_020_000_000);
        assert!((f.t_s - 2.5).abs() < 1e-12);
        assert!((f.age_s - 0.02).abs() < 1e-9);
        let d = f.deck.unwrap();
        assert!((d.roll_deg - 1.5).abs() < 1e-9 && (d.pitch_deg + 2.0).abs() < 1e-9);
        assert_eq!(d.height_m, 0.25);
        assert!(!f.vehicle_missing && !f.frozen_image);
        a.stamp.times.captured_ns = 0;
        a.valid = false.into();
        a.failure = AttitudeFailure::FrozenImage.into();
        a.vehicle.compensation = Compensation::Missing.into();
        let f = FrameInput::from_attitude(&a, 10_020_000_000);
        assert!(f.age_s.is_infinite() && f.deck.is_none() && f.frozen_image && f.vehicle_missing);
    }

    #[test]
    fn outside_refusals_come_first_and_never_clear() {
        let mut decider = LandingDecider::new(DecisionConfig::default()).unwrap();
        let deck = Some(DeckObservation::new(0.5, 0.5, 0.0));
        let mut f = FrameInput::measured(1.0, deck, 0.01);
        f.vehicle_missing = true;
        let d = decider.decide_frame(&f);
        assert_eq!(
            (d.state, d.reason),
            (DecisionState::Hold, DecisionReason::NoVehicleAttitude)
        );
        f.vehicle_missing = false;
        f.frozen_image = true;
        assert_eq!(decider.decide_frame(&f).reason, DecisionReason::FrozenInput);
        // No deck and no vehicle attitude: the missing deck is the reason.
        let f = FrameInput {
            deck: None,
            vehicle_missing: true,
            ..FrameInput::measured(1.1, None, 0.01)
        };
        assert_eq!(decider.decide_frame(&f).reason, DecisionReason::InvalidAttitude);
    }
}
