//! Named simulator scenarios, and marker-level simulation: the exact pixels of the marker centres
//! (optionally with Gaussian pixel noise) for a motion sample.

use crate::motion::{
    Case1Sweep, DeckHeave, Descent, Heaving, LullCycle, Lulled, MotionProfile, MotionSample, ShipMotion,
    TrackingError,
};
use crate::rng::SplitMix64;
use deckwatch_common::markers::MarkerRow;
use deckwatch_common::InvalidOption;
use deckwatch_common::{CameraModel, DeckLayout, GroundTruth, SceneGeometry};

/// A named motion scenario (`--scenario`, `[sim] scenario`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Scenario {
    /// The paper's Case 1 sweep, camera centred at 5 m.
    Case1,
    /// Sea-state-6-like ship motion, camera centred at 5 m.
    Ship,
    /// The same ship in a moderate sea with lulls ([`LullCycle::DEMO`]): 40 s calm enough to
    /// land, 30 s too rough, repeating. The default: a run shows the decision's whole cycle.
    Lulls,
    /// Ship motion with the camera 0.3 m off the deck centre at 4.5-5.5 m.
    Offset,
    /// The camera 30 m away from the deck at 5 m: only the sea in view.
    #[cfg_attr(feature = "cli", value(name = "nodeck"))]
    NoDeck,
    /// The approach: from 20 m over the deck down to 1 m in 60 s ([`Descent::approach`]),
    /// 0.15 m off the centre, over the sea of `lulls`; below about 1.5 m the ring leaves a Pi
    /// camera's view.
    Approach,
}

deckwatch_common::named_enum!(
    Scenario,
    [
        Case1 => "case1",
        Ship => "ship",
        Lulls => "lulls",
        Offset => "offset",
        NoDeck => "nodeck",
        Approach => "approach",
    ]
);

impl Scenario {
    /// The scenario's motion; `seed` sets the sea's phases (Case 1 has none), `sea_scale`
    /// multiplies the sea-state-6 amplitudes (1: sea state 6; Case 1 has no sea).
    pub fn profile(&self, seed: u64, sea_scale: f64) -> Box<dyn MotionProfile + Send + Sync> {
        self.profile_heaving(seed, sea_scale, None)
    }

    /// The same with the deck heaving by `heave` (the lulls calm the heave too).
    pub fn profile_heaving(
        &self,
        seed: u64,
        sea_scale: f64,
        heave: Option<DeckHeave>,
    ) -> Box<dyn MotionProfile + Send + Sync> {
        let sea = || ShipMotion::scaled(seed, sea_scale);
        let deck: Box<dyn MotionProfile + Send + Sync> = match self {
            Self::Case1 => Box::new(Case1Sweep::paper()),
            Self::Ship | Self::Lulls => Box::new(sea()),
            Self::Offset => Box::new(sea().with_tracking(TrackingError::offset_0_3m(seed))),
            Self::NoDeck => Box::new(sea().with_tracking(TrackingError {
                offset_m: 30.0,
                ..TrackingError::offset_0_3m(seed)
            })),
            Self::Approach => Box::new(Descent::approach(sea().with_tracking(TrackingError {
                offset_m: 0.15,
                altitude_amplitude_m: 0.0,
                ..TrackingError::offset_0_3m(seed)
            }))),
        };
        let deck: Box<dyn MotionProfile + Send + Sync> = match heave {
            Some(heave) => Box::new(Heaving { inner: deck, heave }),
            None => deck,
        };
        match self {
            Self::Lulls | Self::Approach => Box::new(Lulled {
                inner: deck,
                cycle: LullCycle::DEMO,
            }),
            _ => deck,
        }
    }

    /// The camera the scenario is usually run with: the paper's for Case 1, the Pi's otherwise.
    pub fn default_camera(&self) -> &'static str {
        match self {
            Self::Case1 => "paper",
            _ => "rpi-v2",
        }
    }
}

/// The command-line choice of a simulation, shared by every tool that simulates (and the
/// `[sim]` section of the pipeline's configuration).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct SimulationArgs {
    /// Scenario: lulls (a moderate sea with calm spells), ship (sea state 6), case1, offset,
    /// nodeck or approach (20 m down to 1 m).
    #[cfg_attr(feature = "cli", arg(long, default_value = "lulls"))]
    pub scenario: Scenario,
    /// Number of frames.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 600))]
    pub frames: usize,
    /// Frame rate (Hz).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 10.0))]
    pub rate: f64,
    /// Camera preset (paper, rpi-v2, rpi-v3-wide); default: the scenario's.
    #[cfg_attr(feature = "cli", arg(long))]
    pub camera: Option<String>,
    /// The vehicle carrying the camera: `level` (the paper's camera) or `sway` (a hovering
    /// quadrotor's sway, `VehicleSway::hover`).
    #[cfg_attr(feature = "cli", arg(long, default_value = "level"))]
    pub vehicle: VehicleMotion,
    /// The vehicle's constant tilt with `tilted` and `sway` (roll, pitch, yaw deg; a hover in
    /// wind leans into it).
    #[cfg_attr(
        feature = "cli",
        arg(long, value_delimiter = ',', allow_negative_numbers = true, default_values_t = [0.0, 0.0, 0.0])
    )]
    pub vehicle_tilt_deg: Vec<f64>,
    /// The deck heaves (sea-state-6 heave, `DeckHeave`, 1.2 m, up to 0.84 m/s) while the vehicle
    /// holds its height in W.
    #[cfg_attr(feature = "cli", arg(long))]
    pub heave: bool,
    /// The sea's amplitudes (roll, pitch, yaw and heave) times this: 1 is sea state 6, 0.2 a
    /// calm sea a landing fits in (0 to 2).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1.0))]
    pub sea_scale: f64,
    /// The autopilot's attitude stream of a non-level vehicle (`sim record` writes it as
    /// `vehicle.csv`).
    #[cfg_attr(feature = "cli", command(flatten))]
    pub autopilot: crate::autopilot::AutopilotArgs,
    /// Seed of the sea's phases, the textures and the noise.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1))]
    pub seed: u64,
}

impl Default for SimulationArgs {
    /// The command line's defaults (a test checks that they agree).
    fn default() -> Self {
        Self {
            scenario: Scenario::Lulls,
            frames: 600,
            rate: 10.0,
            camera: None,
            vehicle: VehicleMotion::Level,
            vehicle_tilt_deg: vec![0.0; 3],
            heave: false,
            sea_scale: 1.0,
            autopilot: crate::autopilot::AutopilotArgs::default(),
            seed: 1,
        }
    }
}

/// The motion of the vehicle carrying the camera (`--vehicle`, `[sim] vehicle`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum VehicleMotion {
    /// Level, as the paper assumes.
    Level,
    /// A constant tilt (`vehicle_tilt_deg`).
    Tilted,
    /// A hovering quadrotor's sway ([`crate::VehicleSway::hover`]).
    Sway,
}

/// A validated [`SimulationArgs`].
pub struct Simulation {
    pub scenario: Scenario,
    pub camera_name: String,
    pub camera: CameraModel,
    pub deck: DeckLayout,
}

/// Frame rates a source accepts (Hz): slower than one frame in 1000 s or faster than 10 kHz is
/// a mistake, and would overflow the pacing arithmetic at the extremes.
pub const MIN_RATE_HZ: f64 = 1e-3;
pub const MAX_RATE_HZ: f64 = 1e4;

impl SimulationArgs {
    /// Checks the choice; errors name the option.
    pub fn resolve(&self) -> Result<Simulation, InvalidOption> {
        let scenario = self.scenario;
        let camera_name = self
            .camera
            .as_deref()
            .unwrap_or(scenario.default_camera())
            .to_string();
        let camera = CameraModel::preset(&camera_name).ok_or_else(|| {
            InvalidOption::new("--camera", format!("unknown `{camera_name}` (paper, rpi-v2)"))
        })?;
        if !(MIN_RATE_HZ..=MAX_RATE_HZ).contains(&self.rate) {
            return Err(InvalidOption::new(
                "--rate",
                format!(
                    "must be within [{MIN_RATE_HZ}, {MAX_RATE_HZ}] Hz, got {}",
                    self.rate
                ),
            ));
        }
        if self.frames == 0 {
            return Err(InvalidOption::new("--frames", "must be at least 1"));
        }
        if !(0.0..=2.0).contains(&self.sea_scale) {
            return Err(InvalidOption::new(
                "--sea-scale",
                format!("must be within [0, 2], got {}", self.sea_scale),
            ));
        }
        self.autopilot.validate()?;
        let tilt_ok = self.vehicle_tilt_deg.len() == 3
            && self
                .vehicle_tilt_deg
                .iter()
                .all(|a| a.is_finite() && a.abs() <= 45.0);
        if !tilt_ok {
            return Err(InvalidOption::new(
                "--vehicle-tilt-deg",
                format!(
                    "three angles (roll, pitch, yaw) within +-45 deg, got {:?}",
                    self.vehicle_tilt_deg
                ),
            ));
        }
        Ok(Simulation {
            scenario,
            camera_name,
            camera,
            deck: DeckLayout::paper(),
        })
    }

    /// The run's motion: the scenario's deck (heaving with `heave`) and camera position, on the
    /// configured vehicle.
    pub fn profile(&self) -> Box<dyn MotionProfile + Send + Sync> {
        let heave = self
            .heave
            .then(|| crate::DeckHeave::sea_state_6(self.seed, self.sea_scale));
        let scenario = self.scenario.profile_heaving(self.seed, self.sea_scale, heave);
        let tilt = match self.vehicle_tilt_deg[..] {
            [r, p, y] => [r, p, y],
            _ => [0.0; 3], // refused by `resolve`
        };
        let sway = match self.vehicle {
            VehicleMotion::Level => return scenario,
            VehicleMotion::Tilted => crate::VehicleSway::still(),
            VehicleMotion::Sway => crate::VehicleSway::hover(self.seed, 1.0),
        };
        Box::new(crate::Swaying {
            inner: scenario,
            sway: sway.with_tilt(tilt),
        })
    }

    /// The ground-truth columns a recording of this simulation has: the vehicle's attitude only
    /// when it is not level, its height and the heave when it is not level or the deck heaves.
    pub fn truth_columns(&self) -> deckwatch_common::truth::TruthColumns {
        use deckwatch_common::truth::{with_heave_truth, ALL_TRUTH, LEVEL_TRUTH};
        match self.vehicle {
            VehicleMotion::Level if self.heave => with_heave_truth(LEVEL_TRUTH),
            VehicleMotion::Level => LEVEL_TRUTH,
            VehicleMotion::Tilted | VehicleMotion::Sway => ALL_TRUTH,
        }
    }

    /// The simulated marker rows (with ground truth) of the whole run, with Gaussian pixel noise
    /// of `noise_px` (standard deviation per axis) on the marker centres.
    pub fn marker_rows(&self, sim: &Simulation, noise_px: f64) -> Result<Vec<MarkerRow>, InvalidOption> {
        if !(noise_px.is_finite() && noise_px >= 0.0) {
            return Err(InvalidOption::new(
                "--noise-px",
                format!("must be >= 0, got {noise_px}"),
            ));
        }
        let mut markers = MarkerSimulator::new(sim.camera, sim.deck, noise_px, self.seed);
        let profile = sim.scenario.profile(self.seed, self.sea_scale);
        Ok(
            crate::motion::sample_series(profile.as_ref(), self.rate, self.frames)
                .iter()
                .enumerate()
                .map(|(k, s)| markers.row(k as u64, s))
                .collect(),
        )
    }
}

/// Simulates marker detections at the level of points: exact projected marker centres, plus
/// independent Gaussian noise of `noise_px` (standard deviation, per axis) when non-zero.
pub struct MarkerSimulator {
    pub camera: CameraModel,
    pub deck: DeckLayout,
    pub noise_px: f64,
    rng: SplitMix64,
}

impl MarkerSimulator {
    pub fn new(camera: CameraModel, deck: DeckLayout, noise_px: f64, seed: u64) -> Self {
        Self {
            camera,
            deck,
            noise_px,
            rng: SplitMix64::new(seed ^ 0x006e_6f69_7365),
        }
    }

    /// One frame's marker row with ground truth; markers off the sensor are None.
    pub fn row(&mut self, index: u64, s: &MotionSample) -> MarkerRow {
        let scene = SceneGeometry {
            attitude: s.attitude.to_matrix(),
            viewpoint: s.viewpoint,
        };
        let mut markers = scene.project_markers(&self.camera, &self.deck);
        if self.noise_px > 0.0 {
            for [u, v] in markers.iter_mut().flatten() {
                *u += self.noise_px * self.rng.next_gaussian();
                *v += self.noise_px * self.rng.next_gaussian();
            }
        }
        let [roll, pitch, yaw] = s.attitude.to_degrees();
        MarkerRow {
            index,
            timestamp_ns: (s.t_s * 1e9).round() as u64,
            markers,
            truth: GroundTruth {
                roll_deg: Some(roll),
                pitch_deg: Some(pitch),
                yaw_deg: Some(yaw),
                alt_m: Some(s.viewpoint.altitude_m),
                offset_x_m: Some(s.viewpoint.offset_x_m),
                offset_y_m: Some(s.viewpoint.offset_y_m),
                ..GroundTruth::default()
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_profiles_differ() {
        for s in Scenario::ALL {
            assert_eq!(Scenario::from_name(s.name()), Some(s));
            assert!(CameraModel::preset(s.default_camera()).is_some());
        }
        let off = Scenario::Offset.profile(1, 1.0).sample(3.0);
        assert!((off.viewpoint.offset_x_m.hypot(off.viewpoint.offset_y_m) - 0.3).abs() < 1e-12);
        let case1 = Scenario::Case1.profile(1, 1.0).sample(0.0);
        assert_eq!(case1.attitude.to_degrees(), [-20.0, -10.0, -5.0]);
    }

    #[test]
    fn noise_has_the_requested_spread() {
        let cam = CameraModel::rpi_v2();
        let s = Scenario::Ship.profile(1, 1.0).sample(1.0);
        let exact = MarkerSimulator::new(cam, DeckLayout::paper(), 0.0, 1).row(0, &s);
        let mut sim = MarkerSimulator::new(cam, DeckLayout::paper(), 0.5, 1);
        let mut ss = 0.0;
        let n = 2000;
        for k in 0..n {
            let r = sim.row(k, &s);
            let (a, b) = (r.markers[3].unwrap(), exact.markers[3].unwrap());
            ss += (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2);
        }
        let sigma = (ss / (2 * n) as f64).sqrt();
        assert!((sigma - 0.5).abs() < 0.03, "{sigma}");
        assert_eq!(exact.truth.alt_m, Some(5.0));
    }
}

/// The command line's defaults (clap attributes) and the configuration's (`Default`) are
/// written twice by necessity; this holds them together.
#[cfg(all(test, feature = "cli"))]
mod command_line_defaults {
    use super::SimulationArgs;
    use crate::sim::ImageArgs;

    #[derive(clap::Parser)]
    struct Both {
        #[command(flatten)]
        sim: SimulationArgs,
        #[command(flatten)]
        image: ImageArgs,
    }

    #[test]
    fn are_the_configuration_defaults() {
        let b = <Both as clap::Parser>::parse_from(["defaults"]);
        assert_eq!(b.sim, SimulationArgs::default());
        assert_eq!(b.image, ImageArgs::default());
        let b = <Both as clap::Parser>::parse_from(["x", "--scenario", "nodeck", "--look", "clean"]);
        assert_eq!(b.sim.scenario, crate::Scenario::NoDeck);
        assert_eq!(b.image.look, crate::sim::Look::Clean);
    }
}
