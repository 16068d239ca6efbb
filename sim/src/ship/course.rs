//! The ship's course as its autopilot keeps it: a slow wander of the course and the yaw the
//! autopilot leaves in waves, and the track they sail.

use super::ShipMotionError;
use crate::motion::Sinusoid;
use crate::rng::SplitMix64;
use std::f64::consts::TAU;

/// The ship's heading off its mean course over time (deg; positive turns the bow to port,
/// CONVENTIONS.md §2), and the track it sails at a constant speed.
///
/// The course wanders as a first-order Gauss-Markov process (standard deviation
/// `wander_deg`, correlation time `wander_time_s`): its Lorentzian spectrum
/// `2 sigma^2 tau / (1 + (w tau)^2)` realised as a sum of sinusoids, so it is defined at any
/// time and the same for a seed. The autopilot's yaw is a narrow band about its period.
#[derive(Debug, Clone, PartialEq)]
pub struct CourseKeeping {
    wander_deg: Vec<Sinusoid>,
    autopilot_deg: Vec<Sinusoid>,
    speed_mps: f64,
    /// The track in the mean course's frame (x ahead, y to port; m) at `k TRACK_STEP_S`.
    track_m: Vec<[f64; 2]>,
}

/// Components of the course's wander and of the autopilot's yaw.
const WANDER_COMPONENTS: usize = 48;
const AUTOPILOT_COMPONENTS: usize = 6;
/// The track's step (s): the heading turns a few degrees a minute, the track is straight over
/// a quarter second to far better than a millimetre.
const TRACK_STEP_S: f64 = 0.25;

/// How a ship keeps its course, as a model's parameters state it: the course's wander, a
/// first-order Gauss-Markov process (a helmsman's or autopilot's slow drift off the ordered
/// course), and the yaw an autopilot leaves in waves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CourseKeepingParams {
    /// The wander's standard deviation (deg) and correlation time (s).
    pub wander_deg: f64,
    pub wander_time_s: f64,
    /// The autopilot's yaw: its standard deviation (deg) at sea state 6 (it scales with the
    /// significant wave height) and its period (s).
    pub autopilot_yaw_deg: f64,
    pub autopilot_yaw_period_s: f64,
}

impl CourseKeepingParams {
    /// A frigate's: the course wandering 2 deg over 2 min, the autopilot's yaw 1 deg at 25 s
    /// in sea state 6.
    pub const FRIGATE: Self = Self {
        wander_deg: 2.0,
        wander_time_s: 120.0,
        autopilot_yaw_deg: 1.0,
        autopilot_yaw_period_s: 25.0,
    };

    /// Every parameter within its bounds: the standard deviations 0-30 deg, the wander's
    /// correlation time and the autopilot's period 1-3600 s.
    pub fn validate(&self) -> Result<(), ShipMotionError> {
        let bad = |name, value, expected| {
            Err(ShipMotionError::BadParameter {
                name,
                value,
                expected,
            })
        };
        for (name, value) in [
            ("course_wander_deg", self.wander_deg),
            ("autopilot_yaw_deg", self.autopilot_yaw_deg),
        ] {
            if !(0.0..=30.0).contains(&value) {
                return bad(name, value, "within 0-30 deg");
            }
        }
        for (name, value) in [
            ("course_wander_time_s", self.wander_time_s),
            ("autopilot_yaw_period_s", self.autopilot_yaw_period_s),
        ] {
            if !(1.0..=3600.0).contains(&value) {
                return bad(name, value, "within 1-3600 s");
            }
        }
        Ok(())
    }

    /// The course kept in a sea of significant wave height `hs_m`, sailed at `speed_mps`, its
    /// track precomputed over `duration_s`; phases and frequencies from `seed`.
    pub fn build(&self, hs_m: f64, speed_mps: f64, duration_s: f64, seed: u64) -> CourseKeeping {
        CourseKeeping::new(
            self.wander_deg,
            self.wander_time_s,
            self.autopilot_yaw_deg * hs_m / 5.0,
            self.autopilot_yaw_period_s,
            speed_mps,
            duration_s,
            seed,
        )
    }
}

impl CourseKeeping {
    /// A course wandering by `wander_deg` (standard deviation) over `wander_time_s`, an
    /// autopilot's yaw of `autopilot_deg` (standard deviation) at about `autopilot_period_s`,
    /// sailed at `speed_mps`; the track precomputed over `duration_s`. Phases and frequencies
    /// from `seed`.
    pub fn new(
        wander_deg: f64,
        wander_time_s: f64,
        autopilot_deg: f64,
        autopilot_period_s: f64,
        speed_mps: f64,
        duration_s: f64,
        seed: u64,
    ) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0xC0_5E_C0_A5);
        // Log-spaced bands from 1/100 to 30 times the corner frequency hold 96 % of the
        // Lorentzian's variance; the amplitudes are scaled to the whole of it.
        let (lo, hi) = ((0.01 / wander_time_s).ln(), (30.0 / wander_time_s).ln());
        let band = (hi - lo) / WANDER_COMPONENTS as f64;
        let mut bands: Vec<(f64, f64)> = (0..WANDER_COMPONENTS)
            .map(|i| {
                let (a, b) = ((lo + i as f64 * band).exp(), (lo + (i + 1) as f64 * band).exp());
                let w = a + (b - a) * rng.next_f64();
                (w, (b - a) * wander_time_s / (1.0 + (w * wander_time_s).powi(2)))
            })
            .collect();
        let total: f64 = bands.iter().map(|(_, e)| e).sum();
        let wander_deg = bands
            .drain(..)
            .map(|(w, e)| Sinusoid {
                amplitude: wander_deg * (2.0 * e / total).sqrt(),
                period_s: TAU / w,
                phase: TAU * rng.next_f64(),
            })
            .collect();
        let autopilot_deg = (0..AUTOPILOT_COMPONENTS)
            .map(|_| Sinusoid {
                amplitude: autopilot_deg * (2.0 / AUTOPILOT_COMPONENTS as f64).sqrt(),
                period_s: autopilot_period_s * (1.0 + 0.15 * (2.0 * rng.next_f64() - 1.0)),
                phase: TAU * rng.next_f64(),
            })
            .collect();
        let mut course = Self {
            wander_deg,
            autopilot_deg,
            speed_mps,
            track_m: Vec::new(),
        };
        // The track by the trapezoid rule on the heading's cosine and sine.
        let steps = (duration_s / TRACK_STEP_S).ceil() as usize + 1;
        let mut track = Vec::with_capacity(steps + 1);
        let mut at = [0.0, 0.0];
        let mut previous = course.velocity_mps(0.0);
        track.push(at);
        for k in 1..=steps {
            let v = course.velocity_mps(k as f64 * TRACK_STEP_S);
            at = [
                at[0] + 0.5 * TRACK_STEP_S * (previous[0] + v[0]),
                at[1] + 0.5 * TRACK_STEP_S * (previous[1] + v[1]),
            ];
            track.push(at);
            previous = v;
        }
        course.track_m = track;
        course
    }

    /// The heading off the mean course (deg) at `t_s`.
    pub fn yaw_deg(&self, t_s: f64) -> f64 {
        self.wander_deg
            .iter()
            .chain(&self.autopilot_deg)
            .map(|s| s.at(t_s))
            .sum()
    }

    /// The ship's velocity in the mean course's frame (m/s).
    fn velocity_mps(&self, t_s: f64) -> [f64; 2] {
        let (sin, cos) = self.yaw_deg(t_s).to_radians().sin_cos();
        [self.speed_mps * cos, self.speed_mps * sin]
    }

    /// Where the ship is at `t_s` (m: ahead along the mean course, to port of it), from where
    /// it was at t = 0; before 0 and past the precomputed track it sails straight on at the
    /// heading of the track's end.
    pub fn position_m(&self, t_s: f64) -> [f64; 2] {
        let last = self.track_m.len().saturating_sub(1);
        let end_s = last as f64 * TRACK_STEP_S;
        let straight = |from_s: f64, from: [f64; 2]| {
            let v = self.velocity_mps(from_s);
            [from[0] + v[0] * (t_s - from_s), from[1] + v[1] * (t_s - from_s)]
        };
        let (Some(&first), Some(&end)) = (self.track_m.first(), self.track_m.last()) else {
            return straight(0.0, [0.0, 0.0]);
        };
        if !(t_s > 0.0) {
            return straight(0.0, first);
        }
        if t_s >= end_s {
            return straight(end_s, end);
        }
        let i = ((t_s / TRACK_STEP_S) as usize).min(last.saturating_sub(1));
        let u = t_s / TRACK_STEP_S - i as f64;
        let (a, b) = (self.track_m[i], self.track_m[i + 1]);
        [a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1])]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_course_wanders_as_asked_and_the_track_follows_it() {
        let course = CourseKeeping::new(3.0, 120.0, 1.0, 25.0, 5.0, 3600.0, 4);
        // The standard deviation of the yaw: the wander's and the autopilot's together.
        let n = 36_000;
        let var = (0..n)
            .map(|k| course.yaw_deg(k as f64 * 0.1).powi(2))
            .sum::<f64>()
            / n as f64;
        let expected = 3.0f64.hypot(1.0);
        assert!(
            (var.sqrt() / expected - 1.0).abs() < 0.35,
            "{} vs {expected}",
            var.sqrt()
        );
        // An hour at 5 m/s: 18 km along the course, a little less for the wander.
        let [x, y] = course.position_m(3600.0);
        assert!(x < 18_000.0 && x > 17_900.0, "{x}");
        assert!(y.abs() < 3600.0 * 5.0 * 0.1, "{y}");
        // The track is the heading's integral: its finite difference is the velocity.
        let t = 1234.56;
        let (a, b) = (course.position_m(t - 0.5), course.position_m(t + 0.5));
        let v = course.velocity_mps(t);
        assert!((b[0] - a[0] - v[0]).abs() < 1e-3 && (b[1] - a[1] - v[1]).abs() < 1e-3);
        // Straight on outside the precomputed span, continuous at its ends.
        let end = course.position_m(3600.25);
        assert!((course.position_m(3600.2500001)[0] - end[0]).abs() < 1e-3);
        assert!(course.position_m(-10.0)[0] < 0.0);
        assert!(course.position_m(f64::NAN)[0].is_nan());
    }
}
