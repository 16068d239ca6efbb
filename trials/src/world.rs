//! One approach's world: the sea (a spectrum sea or a recorded ship motion), the vehicle's sway,
//! and where in them the approach starts.

use deckwatch_common::RotationMatrix;
use deckwatch_sim::landing::{ClosedLoopScene, SharedFlightPath};
use deckwatch_sim::motion::{MotionProfile, MotionSample, SpectrumShipMotion, VehicleSway};
use deckwatch_sim::motion_file::RecordedShipMotion;
use std::sync::Arc;

/// One approach to fly: its sea state (0: a motion file), seed, wave heading and number.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    pub sea_state: u32,
    pub seed: u64,
    /// The waves' mean heading off the bow (deg); NaN with a motion file.
    pub heading_deg: f64,
    pub index: u32,
}

impl Approach {
    /// The seed of the approach's own randomness (its faults).
    pub fn approach_seed(&self) -> u64 {
        self.seed.wrapping_mul(0x9E37_79B9) ^ ((self.sea_state as u64) << 32) ^ self.index as u64
    }
}

/// The deck's motion in a trial: a spectrum sea, or a recorded one.
#[derive(Clone)]
pub enum TrialSea {
    Spectrum(SpectrumShipMotion),
    Recorded(Arc<RecordedShipMotion>),
}

impl MotionProfile for TrialSea {
    fn sample(&self, t_s: f64) -> MotionSample {
        match self {
            Self::Spectrum(s) => s.sample(t_s),
            Self::Recorded(r) => r.sample(t_s),
        }
    }
}

/// Why an approach's world cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorldError {
    #[error("sea state {0} has no spectrum sea (3, 4, 5, 6)")]
    NoSpectrumSea(u32),
    #[error("the motion holds {holds_s:.1} s, an approach needs {needs_s:.1} s")]
    MotionTooShort { holds_s: f64, needs_s: f64 },
}

/// One approach's world: the sea, the vehicle's sway and where the approach starts in them.
#[derive(Clone)]
pub struct ApproachWorld {
    sea: TrialSea,
    sway: VehicleSway,
    /// The approach's t = 0 in the sea's time (s).
    sea_offset_s: f64,
}

/// The deck's motion beyond the approach's end the decision may look at (s).
const LOOK_AHEAD_S: f64 = 10.0;

impl ApproachWorld {
    /// The world of `approach`: on `recorded` motion when given (approach k starts 421 k s into
    /// it, wrapped to fit its length), else on the spectrum sea of its sea state, seed and
    /// heading (approaches 7 min apart: its heading wanders over 10 min). `sway` scales a
    /// hovering quadrotor's sway.
    pub fn new(
        approach: Approach,
        recorded: Option<&Arc<RecordedShipMotion>>,
        sway: f64,
        max_approach_s: f64,
    ) -> Result<Self, WorldError> {
        Self::watched(approach, recorded, sway, max_approach_s, 0.0)
    }

    /// [`Self::new`] for a vehicle that holds over the deck `watch_before_s` before the landing
    /// is asked for: the motion must hold the watch too. On a motion file the requests are
    /// spread over what is left after the watch (approach k asked for 421 k s after it, wrapped
    /// to fit), so that no two approaches of a file share their instant whatever the watch
    /// (moving only the early ones to the watch's end had put 3 of 10 on one instant with a
    /// minute's watch, and 6 of 10 with eight minutes'); without a watch, as [`Self::new`]. On a
    /// spectrum sea an approach that would start earlier than the watch starts at its end.
    pub fn watched(
        approach: Approach,
        recorded: Option<&Arc<RecordedShipMotion>>,
        sway: f64,
        max_approach_s: f64,
        watch_before_s: f64,
    ) -> Result<Self, WorldError> {
        let sway = VehicleSway::hover(approach.seed.wrapping_mul(1000) + approach.index as u64, sway);
        let watch_s = watch_before_s.max(0.0);
        if let Some(motion) = recorded {
            // Each approach needs its whole length (and the decision's look ahead) of motion.
            let needs_s = max_approach_s + LOOK_AHEAD_S;
            let usable_s = motion.duration_s() - needs_s;
            if !(usable_s > 0.0 && usable_s >= watch_s) {
                return Err(WorldError::MotionTooShort {
                    holds_s: motion.duration_s(),
                    needs_s: needs_s + watch_s,
                });
            }
            return Ok(Self {
                sea: TrialSea::Recorded(motion.clone()),
                sway,
                sea_offset_s: watch_s + request_offset_s(approach.index, usable_s - watch_s),
            });
        }
        let sea = SpectrumShipMotion::sea_state_from(approach.sea_state, approach.seed, approach.heading_deg)
            .ok_or(WorldError::NoSpectrumSea(approach.sea_state))?;
        Ok(Self {
            sea: TrialSea::Spectrum(sea),
            sway,
            sea_offset_s: (60.0 + 421.0 * approach.index as f64).max(watch_s),
        })
    }

    /// What the camera sees from the vehicle flying `path`.
    /// The scene the camera sees, its first frame at the approach's `first_frame_s`.
    pub fn scene(&self, path: SharedFlightPath, first_frame_s: f64) -> ClosedLoopScene<TrialSea> {
        ClosedLoopScene {
            sea: self.sea.clone(),
            sway: self.sway.clone(),
            path,
            sea_offset_s: self.sea_offset_s,
            // Hovering a little off the centre, as a position hold does.
            offset_m: [0.08, -0.05],
            first_frame_s,
        }
    }

    /// The true deck: roll, pitch (deg) and heave (m) at the approach's t.
    pub fn truth(&self, t: f64) -> [f64; 3] {
        let s = self.sea.sample(t + self.sea_offset_s);
        let [r, p, _] = s.attitude.to_degrees();
        [r, p, s.deck_heave_m]
    }

    /// The deck's heave (m) at the approach's t (the sea's heave alone: the vehicle's height
    /// follows it 100 times a second).
    pub fn heave_m(&self, t: f64) -> f64 {
        match &self.sea {
            TrialSea::Spectrum(s) => s.heave_m(t + self.sea_offset_s),
            TrialSea::Recorded(r) => r.sample(t + self.sea_offset_s).deck_heave_m,
        }
    }

    /// The vehicle's attitude (body to W) at t: its sway alone.
    pub fn vehicle_attitude(&self, t: f64) -> RotationMatrix {
        self.sway.attitude(t + self.sea_offset_s).to_matrix()
    }

    /// The deck's and the vehicle's attitudes (body to W) at t.
    pub fn attitudes(&self, t: f64) -> (RotationMatrix, RotationMatrix) {
        let deck = self.sea.sample(t + self.sea_offset_s).attitude.to_matrix();
        (deck, self.vehicle_attitude(t))
    }
}

/// When approach `index` is asked for on a motion file, in seconds after the first instant it
/// may use: 421 s apart (a prime, so that wrapped instants rarely meet), wrapped into `span_s`.
fn request_offset_s(index: u32, span_s: f64) -> f64 {
    match span_s > 0.0 {
        true => (421.0 * index as f64) % span_s,
        false => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file_of(duration_s: f64) -> Arc<RecordedShipMotion> {
        let mut text = String::from("time_s,roll_deg,pitch_deg,heave_m\n");
        for k in 0..=(duration_s * 10.0) as usize {
            text += &format!("{},0,0,0\n", k as f64 / 10.0);
        }
        Arc::new(RecordedShipMotion::parse(&text, "test").unwrap())
    }

    fn starts(motion: &Arc<RecordedShipMotion>, watch_s: f64) -> Vec<f64> {
        (0..10)
            .map(|index| {
                let approach = Approach {
                    sea_state: 0,
                    seed: 1,
                    heading_deg: f64::NAN,
                    index,
                };
                ApproachWorld::watched(approach, Some(motion), 1.0, 120.0, watch_s)
                    .unwrap()
                    .sea_offset_s
            })
            .collect()
    }

    #[test]
    fn approaches_on_a_file_start_at_distinct_instants_after_any_watch() {
        let motion = file_of(1800.0);
        assert_eq!(
            starts(&motion, 0.0)[..3],
            [0.0, 421.0, 842.0],
            "no watch: as before"
        );
        for watch_s in [0.0, 60.0, 480.0, 900.0] {
            let starts = starts(&motion, watch_s);
            for (i, a) in starts.iter().enumerate() {
                assert!(
                    *a >= watch_s && *a + 120.0 + LOOK_AHEAD_S <= 1800.0,
                    "watch {watch_s}: start {a}"
                );
                for b in &starts[..i] {
                    assert!(
                        (a - b).abs() >= 1.0,
                        "watch {watch_s}: two approaches at {a} and {b}"
                    );
                }
            }
        }
    }
}
