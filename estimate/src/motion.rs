//! The deck's recent motion, for a rolling shutter: the deck's angular velocity and the camera's
//! velocity relative to the deck at a frame's instant, extrapolated from the last few poses.
//!
//! The vehicle's own rate comes from its attitude stream (a gyro's worth of samples); the deck's
//! is known only from the frames, which come 10-30 times a second. Ship motion has periods of
//! seconds, so the rates of the last frames, extrapolated linearly, are within a few per cent of
//! the rate at the next frame.

use deckwatch_common::rotation::angular_velocity;
use deckwatch_common::RotationMatrix;
use nalgebra::Vector3;
use std::collections::VecDeque;

/// One frame's pose, as the history keeps it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PoseSample {
    t_s: f64,
    /// The deck's attitude in W.
    deck: RotationMatrix,
    /// The camera's position relative to the deck centre in W (m).
    camera_m: Vector3<f64>,
}

/// The deck's rate and the camera's relative velocity at an instant (W, rad/s and m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeckRates {
    pub deck_rate_rad_s: Vector3<f64>,
    pub camera_velocity_mps: Vector3<f64>,
}

/// The last three poses of the deck, on the frames' own timeline.
#[derive(Debug, Clone, Default)]
pub struct DeckMotionHistory {
    samples: VecDeque<PoseSample>,
}

impl DeckMotionHistory {
    /// Poses further apart than this are not differenced (a gap: the rates are unknown).
    pub const MAX_SPAN_S: f64 = 0.5;

    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a frame's pose; a pose not after the newest (a replay loop, a clock jump) starts
    /// the history again, as does anything not finite.
    pub fn push(&mut self, t_s: f64, deck: &RotationMatrix, camera_m: Vector3<f64>) {
        let finite =
            t_s.is_finite() && deck.iter().all(|v| v.is_finite()) && camera_m.iter().all(|v| v.is_finite());
        if !finite {
            self.samples.clear();
            return;
        }
        if self.samples.back().is_some_and(|s| !(t_s > s.t_s)) {
            self.samples.clear();
        }
        if self.samples.len() == 3 {
            self.samples.pop_front();
        }
        self.samples.push_back(PoseSample {
            t_s,
            deck: *deck,
            camera_m,
        });
    }

    /// Forgets every pose.
    pub fn clear(&mut self) {
        self.samples.clear();
    }

    /// The rates at `t_s`: from the last two poses, extrapolated linearly with the third when
    /// there is one; none when the newest pose is more than [`Self::MAX_SPAN_S`] before
    /// `t_s` or two poses are that far apart.
    pub fn rates_at(&self, t_s: f64) -> Option<DeckRates> {
        let n = self.samples.len();
        if n < 2 || !t_s.is_finite() {
            return None;
        }
        let newest = self.samples[n - 1];
        if !(t_s - newest.t_s <= Self::MAX_SPAN_S && t_s >= newest.t_s - Self::MAX_SPAN_S) {
            return None;
        }
        // Rate between two poses, at their middle instant.
        let between = |a: &PoseSample, b: &PoseSample| -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
            let dt = b.t_s - a.t_s;
            (dt > 0.0 && dt <= Self::MAX_SPAN_S).then(|| {
                (
                    0.5 * (a.t_s + b.t_s),
                    angular_velocity(&a.deck, &b.deck, dt),
                    (b.camera_m - a.camera_m) / dt,
                )
            })
        };
        let (t2, w2, v2) = between(&self.samples[n - 2], &newest)?;
        let rates = match (n >= 3)
            .then(|| between(&self.samples[n - 3], &self.samples[n - 2]))
            .flatten()
        {
            Some((t1, w1, v1)) => {
                let k = (t_s - t2) / (t2 - t1);
                DeckRates {
                    deck_rate_rad_s: w2 + (w2 - w1) * k,
                    camera_velocity_mps: v2 + (v2 - v1) * k,
                }
            }
            None => DeckRates {
                deck_rate_rad_s: w2,
                camera_velocity_mps: v2,
            },
        };
        Some(rates)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::Rpy;

    #[test]
    fn a_steady_turn_is_extrapolated_and_gaps_and_reversals_forget() {
        // Roll at 0.1 rad/s plus a roll acceleration, the camera sinking at 0.5 m/s.
        let pose = |t: f64| {
            (
                Rpy::new(0.1 * t + 0.2 * t * t, 0.0, 0.0).to_matrix(),
                Vector3::new(0.0, 0.0, 5.0 - 0.5 * t),
            )
        };
        let mut h = DeckMotionHistory::new();
        assert!(h.rates_at(0.0).is_none());
        for t in [0.0, 0.1, 0.2] {
            let (r, c) = pose(t);
            h.push(t, &r, c);
        }
        // At t = 0.3 the roll rate is 0.1 + 0.4 * 0.3 = 0.22 rad/s: exact for a quadratic.
        let r = h.rates_at(0.3).unwrap();
        assert!((r.deck_rate_rad_s.x - 0.22).abs() < 1e-9, "{r:?}");
        assert!(r.deck_rate_rad_s.yz().norm() < 1e-12);
        assert!((r.camera_velocity_mps - Vector3::new(0.0, 0.0, -0.5)).norm() < 1e-9);
        // Too long after the newest pose: unknown.
        assert!(h.rates_at(0.8).is_none());
        // Time going backwards (a replay loop) starts again: one pose is not enough.
        let (r0, c0) = pose(0.0);
        h.push(0.05, &r0, c0);
        assert!(h.rates_at(0.1).is_none());
        // A pose that is not finite forgets everything.
        h.push(0.1, &r0, c0);
        assert!(h.rates_at(0.1).is_some());
        h.push(0.2, &r0, Vector3::new(f64::NAN, 0.0, 0.0));
        assert!(h.rates_at(0.2).is_none());
    }
}
