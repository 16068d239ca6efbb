//! The scene of a closed-loop landing: the sea's deck under a vehicle whose height is flown by a
//! simulated autopilot while the frames are rendered. The autopilot decides as the frames come,
//! so the profile reads a [`FlightPath`] it shares with whoever flies the vehicle; every command
//! takes effect from its own instant on, so a frame already rendered never changes.

use crate::motion::{MotionProfile, MotionSample, VehicleSway};
use deckwatch_common::{RotationMatrix, Viewpoint};
use std::sync::{Arc, Mutex};

/// One straight piece of the vehicle's height: from `t_s` at `from_m`, at `speed_mps` (signed)
/// until `target_m`, then held. Over the deck (the autopilot lands on its range finder and
/// follows the deck's heave) or in W (it holds its altitude while it hovers or climbs).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Leg {
    t_s: f64,
    from_m: f64,
    speed_mps: f64,
    target_m: f64,
    over_deck: bool,
}

impl Leg {
    fn value(&self, t_s: f64) -> f64 {
        let h = self.from_m + self.speed_mps * (t_s - self.t_s).max(0.0);
        if self.speed_mps < 0.0 {
            h.max(self.target_m)
        } else {
            h.min(self.target_m)
        }
    }
}

/// The vehicle's height over time, as commands change it. Heights are of the camera: in W over
/// the deck's mean level, or over the deck centre while the autopilot follows the deck.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightPath {
    legs: Vec<Leg>,
}

impl FlightPath {
    /// Hovering at `height_m` in W from the beginning of time.
    pub fn hover(height_m: f64) -> Self {
        Self {
            legs: vec![Leg {
                t_s: f64::NEG_INFINITY,
                from_m: height_m,
                speed_mps: 0.0,
                target_m: height_m,
                over_deck: false,
            }],
        }
    }

    fn leg(&self, t_s: f64) -> &Leg {
        // Legs are in time order; the first starts at -inf.
        let i = self.legs.partition_point(|l| l.t_s <= t_s);
        &self.legs[i.saturating_sub(1)]
    }

    /// The camera's height in W at `t_s`, the deck centre being `heave_m` high.
    pub fn height_m(&self, t_s: f64, heave_m: f64) -> f64 {
        let l = self.leg(t_s);
        l.value(t_s) + if l.over_deck { heave_m } else { 0.0 }
    }

    /// The camera's height over the deck centre.
    pub fn over_deck_m(&self, t_s: f64, heave_m: f64) -> f64 {
        self.height_m(t_s, heave_m) - heave_m
    }

    /// From `t_s` on (not before the last command), towards `target_m` at `speed_mps` (> 0),
    /// over the deck or in W; `heave_m` is the deck's height at `t_s`.
    pub fn move_to(&mut self, t_s: f64, heave_m: f64, target_m: f64, speed_mps: f64, over_deck: bool) {
        let t_s = t_s.max(self.legs.last().map_or(t_s, |l| l.t_s));
        let now_w = self.height_m(t_s, heave_m);
        let from_m = if over_deck { now_w - heave_m } else { now_w };
        let speed = speed_mps.abs();
        self.legs.push(Leg {
            t_s,
            from_m,
            speed_mps: if target_m < from_m { -speed } else { speed },
            target_m,
            over_deck,
        });
    }

    /// Where the last command sends it: a height (m), and whether over the deck (else in W).
    pub fn target(&self) -> (f64, bool) {
        let l = self.legs.last().expect("a path has a leg");
        (l.target_m, l.over_deck)
    }

    /// The leg's end: when it reaches its target (the start of time for a hover).
    pub fn arrival_s(&self) -> f64 {
        let l = self.legs.last().expect("a path has a leg");
        if l.speed_mps == 0.0 {
            l.t_s
        } else {
            l.t_s + (l.target_m - l.from_m) / l.speed_mps
        }
    }
}

/// A [`FlightPath`] shared by the renderer's profile and the autopilot that flies it.
pub type SharedFlightPath = Arc<Mutex<FlightPath>>;

/// The scene of one approach: the sea `sea_offset_s` into its motion (the approach's t = 0 is
/// when the landing is asked for, the vehicle over the deck), the camera `offset_m` from the
/// deck centre, carried by a swaying vehicle at the flight path's height. The source's first
/// frame is at the approach's `first_frame_s` (0, or before when the vehicle held over the deck
/// before the landing was asked for): a frame at the source's `t` shows the approach's
/// `t + first_frame_s`.
pub struct ClosedLoopScene<P> {
    pub sea: P,
    pub sway: VehicleSway,
    pub path: SharedFlightPath,
    pub sea_offset_s: f64,
    pub offset_m: [f64; 2],
    pub first_frame_s: f64,
}

impl<P: MotionProfile> ClosedLoopScene<P> {
    /// The deck's sample at the approach's `t_s` (its attitude and heave).
    pub fn deck(&self, t_s: f64) -> MotionSample {
        let mut s = self.sea.sample(t_s + self.sea_offset_s);
        s.t_s = t_s;
        s
    }
}

impl<P: MotionProfile> MotionProfile for ClosedLoopScene<P> {
    /// At the source's `source_t_s` (the sample keeps that time: the frame's).
    fn sample(&self, source_t_s: f64) -> MotionSample {
        let t_s = source_t_s + self.first_frame_s;
        let mut s = self.deck(t_s);
        s.t_s = source_t_s;
        // A poisoned lock only means a panic elsewhere; the path itself is still whole.
        let path = self.path.lock().unwrap_or_else(|e| e.into_inner());
        let altitude_m = path.over_deck_m(t_s, s.deck_heave_m);
        s.viewpoint = Viewpoint::level(self.offset_m[0], self.offset_m[1], altitude_m)
            .with_vehicle_attitude(self.vehicle_attitude(source_t_s));
        s
    }

    /// The sway alone (the sea need not be summed for it), at the source's time.
    fn vehicle_attitude(&self, source_t_s: f64) -> RotationMatrix {
        self.sway
            .attitude(source_t_s + self.first_frame_s + self.sea_offset_s)
            .to_matrix()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_descent_over_the_deck_follows_the_heave_and_a_climb_holds_in_w() {
        let mut p = FlightPath::hover(3.0);
        assert_eq!(p.height_m(-5.0, 0.4), 3.0);
        // Commit at t = 1 with the deck 0.5 m up: 2.5 m over it, down to 0.25 m in 2 s.
        p.move_to(1.0, 0.5, 0.25, 1.125, true);
        assert!((p.over_deck_m(1.0, 0.5) - 2.5).abs() < 1e-12);
        assert!(
            (p.over_deck_m(3.0, -0.3) - 0.25).abs() < 1e-12,
            "contact whatever the heave"
        );
        assert!((p.arrival_s() - 3.0).abs() < 1e-12);
        assert_eq!(p.height_m(0.5, 0.0), 3.0, "before the command: unchanged");
        // Go around at t = 2 (1.375 m over a deck at 0.1 m): back to 3 m in W at 1.5 m/s.
        p.move_to(2.0, 0.1, 3.0, 1.5, false);
        assert!((p.height_m(2.0, 0.1) - 1.475).abs() < 1e-12);
        assert!((p.height_m(10.0, -1.0) - 3.0).abs() < 1e-12);
        // A command dated before the last takes effect at the last: the past stays as it was.
        p.move_to(1.0, 0.1, 2.0, 1.0, false);
        assert!((p.height_m(1.5, 0.0) - 1.9375).abs() < 1e-12);
        assert!((p.height_m(2.5, 0.0) - 1.975).abs() < 1e-12);
    }
}
