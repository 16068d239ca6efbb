//! Motion profiles of the simulated scene: how the deck turns and where the quadrotor's camera is,
//! as functions of time. Deterministic for a seed.

use crate::rng::SplitMix64;
use deckwatch_common::{RotationMatrix, Rpy, Viewpoint};
use std::f64::consts::TAU;

/// The scene at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionSample {
    pub t_s: f64,
    /// True deck attitude (X-Y-Z roll/pitch/yaw, CONVENTIONS.md §2).
    pub attitude: Rpy,
    /// True camera position over the deck.
    pub viewpoint: Viewpoint,
    /// The deck centre's height in W (m, z up; 0: its mean): the heave. The viewpoint is
    /// relative to the deck, so the vehicle's height in W is the two added.
    pub deck_heave_m: f64,
}

impl MotionSample {
    /// The vehicle's (camera's) height in W (m).
    pub fn vehicle_height_m(&self) -> f64 {
        self.viewpoint.altitude_m + self.deck_heave_m
    }
}

/// A deck-and-camera trajectory.
pub trait MotionProfile {
    fn sample(&self, t_s: f64) -> MotionSample;

    /// The vehicle's attitude (body to W) at `t_s`, as [`Self::sample`] gives it. A profile
    /// that can give it alone, cheaper than the whole sample, says so here: the simulator
    /// differentiates it six times a frame for the vehicle's rate.
    fn vehicle_attitude(&self, t_s: f64) -> RotationMatrix {
        self.sample(t_s).viewpoint.vehicle_attitude
    }
}

impl<P: MotionProfile + ?Sized> MotionProfile for Box<P> {
    fn sample(&self, t_s: f64) -> MotionSample {
        (**self).sample(t_s)
    }

    fn vehicle_attitude(&self, t_s: f64) -> RotationMatrix {
        (**self).vehicle_attitude(t_s)
    }
}

/// The paper's Case 1: every angle changes in one direction, linearly over `duration_s`:
/// roll -20 -> 20 deg, pitch -10 -> 10 deg, yaw -5 -> 5 deg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Case1Sweep {
    pub duration_s: f64,
    /// Where the camera is (the paper: hovering centred at 5 m).
    pub tracking: TrackingError,
}

impl Case1Sweep {
    /// The paper's setting: 5 m altitude; a 20 s sweep (the paper does not give the duration).
    pub fn paper() -> Self {
        Self {
            duration_s: 20.0,
            tracking: TrackingError::hover(5.0),
        }
    }

    pub fn with_tracking(mut self, tracking: TrackingError) -> Self {
        self.tracking = tracking;
        self
    }
}

impl MotionProfile for Case1Sweep {
    fn sample(&self, t_s: f64) -> MotionSample {
        let u = (t_s / self.duration_s).clamp(0.0, 1.0);
        let lerp = |a: f64, b: f64| a + (b - a) * u;
        MotionSample {
            t_s,
            attitude: Rpy::from_degrees(lerp(-20.0, 20.0), lerp(-10.0, 10.0), lerp(-5.0, 5.0)),
            viewpoint: self.tracking.at(t_s),
            deck_heave_m: 0.0,
        }
    }
}

/// One sinusoid: amplitude (degrees or metres), period (s), phase (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sinusoid {
    pub amplitude: f64,
    pub period_s: f64,
    pub phase: f64,
}

impl Sinusoid {
    pub fn at(&self, t_s: f64) -> f64 {
        self.amplitude * (TAU * t_s / self.period_s + self.phase).sin()
    }

    /// Its rate of change at `t_s` (per second).
    pub fn rate(&self, t_s: f64) -> f64 {
        self.amplitude * TAU / self.period_s * (TAU * t_s / self.period_s + self.phase).cos()
    }
}

/// Sinusoids of a table of (amplitude, period s), amplitudes times `scale`, phases drawn in
/// table order from `rng`.
fn sinusoids(rng: &mut SplitMix64, table: &[(f64, f64)], scale: f64) -> Vec<Sinusoid> {
    table
        .iter()
        .map(|&(a, p)| Sinusoid {
            amplitude: a * scale,
            period_s: p,
            phase: TAU * rng.next_f64(),
        })
        .collect()
}

fn sum(components: &[Sinusoid], t_s: f64) -> f64 {
    components.iter().map(|c| c.at(t_s)).sum()
}

/// Ship rotation as a sum of sinusoids per axis (degrees). |angle| never exceeds the sum of its
/// amplitudes.
#[derive(Debug, Clone, PartialEq)]
pub struct ShipMotion {
    pub roll_deg: Vec<Sinusoid>,
    pub pitch_deg: Vec<Sinusoid>,
    pub yaw_deg: Vec<Sinusoid>,
    /// Where the camera is (tracking error of the quadrotor).
    pub tracking: TrackingError,
}

/// (amplitude deg, period s) of the sea-state-6-like model; phases come from the seed.
///
/// Roll: a frigate-size ship rolls near its natural period (about 10-12 s) with energy spread
/// over 8-15 s wave periods; the amplitudes sum to 25 deg, the "up to about +-25"
/// (the paper's introduction quotes about +-30 deg at sea state 6). Pitch: shorter periods
/// (5-9 s), sum 8 deg. Yaw: slow, 9-17 s, sum 5 deg.
pub const SEA_STATE_6_ROLL: [(f64, f64); 3] = [(13.0, 11.0), (8.0, 8.3), (4.0, 14.7)];
pub const SEA_STATE_6_PITCH: [(f64, f64); 3] = [(4.5, 6.4), (2.5, 8.9), (1.0, 5.1)];
pub const SEA_STATE_6_YAW: [(f64, f64); 3] = [(3.0, 12.6), (1.5, 17.3), (0.5, 9.4)];

impl ShipMotion {
    /// The sea-state-6-like model with phases drawn from `seed`, camera hovering centred at 5 m.
    pub fn sea_state_6(seed: u64) -> Self {
        Self::scaled(seed, 1.0)
    }

    /// The same spectrum with every amplitude multiplied by `scale` (a calmer or rougher sea).
    pub fn scaled(seed: u64, scale: f64) -> Self {
        let mut rng = SplitMix64::new(seed);
        Self {
            roll_deg: sinusoids(&mut rng, &SEA_STATE_6_ROLL, scale),
            pitch_deg: sinusoids(&mut rng, &SEA_STATE_6_PITCH, scale),
            yaw_deg: sinusoids(&mut rng, &SEA_STATE_6_YAW, scale),
            tracking: TrackingError::hover(5.0),
        }
    }

    /// An irregular sea with the same energy: each sinusoid of the sea-state-6 model becomes
    /// `spread` components with periods within +-12 % of it and random shares of its energy,
    /// so the motion beats and changes from one minute to the next (harder to predict than
    /// three clean sinusoids). Amplitudes scaled by `scale`.
    pub fn irregular(seed: u64, scale: f64, spread: usize) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0x5EA5_7A7E);
        let spread = spread.max(1);
        let mut axis = |table: &[(f64, f64)]| -> Vec<Sinusoid> {
            let mut out = Vec::new();
            for &(a, p) in table {
                let energy: Vec<f64> = (0..spread).map(|_| -(1.0 - rng.next_f64()).ln()).collect();
                let total: f64 = energy.iter().sum();
                for e in energy {
                    out.push(Sinusoid {
                        amplitude: a * scale * (e / total).sqrt(),
                        period_s: p * (1.0 + 0.12 * (2.0 * rng.next_f64() - 1.0)),
                        phase: TAU * rng.next_f64(),
                    });
                }
            }
            out
        };
        Self {
            roll_deg: axis(&SEA_STATE_6_ROLL),
            pitch_deg: axis(&SEA_STATE_6_PITCH),
            yaw_deg: axis(&SEA_STATE_6_YAW),
            tracking: TrackingError::hover(5.0),
        }
    }

    pub fn with_tracking(mut self, tracking: TrackingError) -> Self {
        self.tracking = tracking;
        self
    }

    /// Bound on |roll|, |pitch|, |yaw| (degrees).
    pub fn amplitude_bounds_deg(&self) -> [f64; 3] {
        let b = |c: &[Sinusoid]| c.iter().map(|s| s.amplitude.abs()).sum();
        [b(&self.roll_deg), b(&self.pitch_deg), b(&self.yaw_deg)]
    }
}

impl MotionProfile for ShipMotion {
    fn sample(&self, t_s: f64) -> MotionSample {
        MotionSample {
            t_s,
            attitude: Rpy::from_degrees(
                sum(&self.roll_deg, t_s),
                sum(&self.pitch_deg, t_s),
                sum(&self.yaw_deg, t_s),
            ),
            viewpoint: self.tracking.at(t_s),
            deck_heave_m: 0.0,
        }
    }
}

/// The quadrotor's tracking error: its camera circles the deck centre at a fixed horizontal
/// offset and bobs in altitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingError {
    /// Horizontal distance of the camera from the deck centre (m).
    pub offset_m: f64,
    /// Period of one circle around the centre (s); the direction starts at `phase`.
    pub offset_period_s: f64,
    pub altitude_mean_m: f64,
    /// Altitude varies within mean +- this (m).
    pub altitude_amplitude_m: f64,
    pub altitude_period_s: f64,
    pub phase: f64,
}

impl TrackingError {
    /// Perfect hover over the deck centre.
    pub fn hover(altitude_m: f64) -> Self {
        Self {
            offset_m: 0.0,
            offset_period_s: 1.0,
            altitude_mean_m: altitude_m,
            altitude_amplitude_m: 0.0,
            altitude_period_s: 1.0,
            phase: 0.0,
        }
    }

    /// 0.3 m from the deck centre, altitude 4.5-5.5 m: the offset case.
    pub fn offset_0_3m(seed: u64) -> Self {
        Self {
            offset_m: 0.3,
            offset_period_s: 23.0,
            altitude_mean_m: 5.0,
            altitude_amplitude_m: 0.5,
            altitude_period_s: 9.0,
            phase: TAU * SplitMix64::new(seed ^ 0x7261_636b).next_f64(),
        }
    }

    pub fn at(&self, t_s: f64) -> Viewpoint {
        let a = TAU * t_s / self.offset_period_s + self.phase;
        Viewpoint::level(
            self.offset_m * a.cos(),
            self.offset_m * a.sin(),
            self.altitude_mean_m
                + self.altitude_amplitude_m * (TAU * t_s / self.altitude_period_s + self.phase).sin(),
        )
    }
}

/// (amplitude deg, period s) of a hovering quadrotor's sway: it tilts to hold its position in
/// wind and gusts, at 0.2-2 Hz. Roll up to 9.1 deg, pitch up to 7.8 deg; the largest rates
/// (amplitude x 2 pi / period, summed) are 29 and 22 deg/s. Heading wanders slowly (5 deg).
pub const HOVER_SWAY_ROLL: [(f64, f64); 3] = [(6.0, 4.0), (2.4, 1.25), (0.7, 0.6)];
pub const HOVER_SWAY_PITCH: [(f64, f64); 3] = [(5.0, 5.0), (2.2, 1.45), (0.6, 0.67)];
pub const HOVER_SWAY_YAW: [(f64, f64); 2] = [(4.0, 50.0), (1.0, 10.0)];

/// The attitude of the vehicle that carries the camera (`R_V`, body to world; CONVENTIONS.md §5)
/// over time: a sum of sinusoids per axis with phases from the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSway {
    pub roll_deg: Vec<Sinusoid>,
    pub pitch_deg: Vec<Sinusoid>,
    pub yaw_deg: Vec<Sinusoid>,
}

impl VehicleSway {
    /// A hovering quadrotor ([`HOVER_SWAY_ROLL`] ...), amplitudes times `scale`.
    pub fn hover(seed: u64, scale: f64) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0x0D_0A_0E_5E);
        Self {
            roll_deg: sinusoids(&mut rng, &HOVER_SWAY_ROLL, scale),
            pitch_deg: sinusoids(&mut rng, &HOVER_SWAY_PITCH, scale),
            yaw_deg: sinusoids(&mut rng, &HOVER_SWAY_YAW, scale),
        }
    }

    /// The same sway about a constant tilt (deg; a hover in wind leans into it): the constant
    /// is a sinusoid of infinite period at its crest.
    pub fn with_tilt(mut self, [roll, pitch, yaw]: [f64; 3]) -> Self {
        let constant = |amplitude| Sinusoid {
            amplitude,
            period_s: f64::INFINITY,
            phase: std::f64::consts::FRAC_PI_2,
        };
        self.roll_deg.push(constant(roll));
        self.pitch_deg.push(constant(pitch));
        self.yaw_deg.push(constant(yaw));
        self
    }

    /// No sway at all.
    pub fn still() -> Self {
        Self {
            roll_deg: Vec::new(),
            pitch_deg: Vec::new(),
            yaw_deg: Vec::new(),
        }
    }

    pub fn attitude(&self, t_s: f64) -> Rpy {
        Rpy::from_degrees(
            sum(&self.roll_deg, t_s),
            sum(&self.pitch_deg, t_s),
            sum(&self.yaw_deg, t_s),
        )
    }
}

/// A motion profile with the camera carried by a swaying vehicle: the inner profile's deck and
/// position, the vehicle's attitude from the sway.
pub struct Swaying<P> {
    pub inner: P,
    pub sway: VehicleSway,
}

impl<P: MotionProfile> MotionProfile for Swaying<P> {
    fn sample(&self, t_s: f64) -> MotionSample {
        let mut s = self.inner.sample(t_s);
        s.viewpoint = s
            .viewpoint
            .with_vehicle_attitude(self.sway.attitude(t_s).to_matrix());
        s
    }
}

/// A sea whose strength rises and falls: spells of calm between stretches of a moderate sea
/// (waves come in groups with lulls between them; a lull of half a minute or more is what a
/// ship's crew waits for to land a helicopter). The sea's amplitudes are multiplied by a
/// factor that holds `calm` for `calm_s`, rises smoothly to `rough` over `ramp_s`, holds it for
/// `rough_s`, falls back over `ramp_s`, and repeats.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LullCycle {
    pub calm: f64,
    pub rough: f64,
    pub calm_s: f64,
    pub ramp_s: f64,
    pub rough_s: f64,
}

impl LullCycle {
    /// The `lulls` scenario: a lull (0.15 of the sea-state-6 amplitudes: roll within 3.8 deg,
    /// pitch within 1.2 deg) for 40 s, then a moderate sea (0.6: roll up to 15 deg, pitch up to
    /// 4.8 deg) for 30 s, with 8 s between: one cycle is 86 s. With the decider's 20 s of
    /// warm-up, a 60 s run shows HOLD (warm-up), CLEAR in the lull, and HOLD as the sea builds.
    pub const DEMO: Self = Self {
        calm: 0.15,
        rough: 0.6,
        calm_s: 40.0,
        ramp_s: 8.0,
        rough_s: 30.0,
    };

    pub fn period_s(&self) -> f64 {
        self.calm_s + 2.0 * self.ramp_s + self.rough_s
    }

    /// The amplitude factor at `t_s` (smoothstep ramps: the motion's rate changes gently).
    pub fn factor(&self, t_s: f64) -> f64 {
        let period = self.period_s();
        if !(period > 0.0 && t_s.is_finite()) {
            return self.calm;
        }
        let t = t_s.rem_euclid(period);
        let smooth = |u: f64| {
            let u = u.clamp(0.0, 1.0);
            u * u * (3.0 - 2.0 * u)
        };
        let up = if self.ramp_s > 0.0 {
            let rise = smooth((t - self.calm_s) / self.ramp_s);
            let fall = smooth((t - self.calm_s - self.ramp_s - self.rough_s) / self.ramp_s);
            rise - fall
        } else if t >= self.calm_s && t < self.calm_s + self.rough_s {
            1.0
        } else {
            0.0
        };
        self.calm + (self.rough - self.calm) * up
    }
}

/// A motion profile whose sea follows a [`LullCycle`]: the inner profile's deck angles and
/// heave times the cycle's factor (the camera keeps its height in W, as with [`Heaving`]).
pub struct Lulled<P> {
    pub inner: P,
    pub cycle: LullCycle,
}

impl<P: MotionProfile> MotionProfile for Lulled<P> {
    fn sample(&self, t_s: f64) -> MotionSample {
        let mut s = self.inner.sample(t_s);
        let f = self.cycle.factor(t_s);
        s.attitude = Rpy::new(s.attitude.roll * f, s.attitude.pitch * f, s.attitude.yaw * f);
        // The camera's height over the deck is the inner one's with the heave's share removed.
        s.viewpoint.altitude_m += s.deck_heave_m * (1.0 - f);
        s.deck_heave_m *= f;
        s
    }
}

/// A descent onto the deck: the camera's height over the deck centre goes from `from_m` to
/// `to_m` over `duration_s`, slowing as it nears the deck (`to + (from - to) (1 - t/T)^2`), then
/// holds; the inner profile's deck motion and horizontal offset are kept.
pub struct Descent<P> {
    pub inner: P,
    pub from_m: f64,
    pub to_m: f64,
    pub duration_s: f64,
}

impl<P> Descent<P> {
    /// 20 m down to 1 m in 60 s: the whole approach, through the altitudes where the ring
    /// leaves a Pi camera's view (below about 1.5 m).
    pub fn approach(inner: P) -> Self {
        Self {
            inner,
            from_m: 20.0,
            to_m: 1.0,
            duration_s: 60.0,
        }
    }

    /// The camera's height over the deck centre at `t_s` (m).
    pub fn altitude_m(&self, t_s: f64) -> f64 {
        let u = (t_s / self.duration_s).clamp(0.0, 1.0);
        self.to_m + (self.from_m - self.to_m) * (1.0 - u).powi(2)
    }
}

impl<P: MotionProfile> MotionProfile for Descent<P> {
    fn sample(&self, t_s: f64) -> MotionSample {
        let mut s = self.inner.sample(t_s);
        s.viewpoint.altitude_m = self.altitude_m(t_s);
        s
    }
}

/// (amplitude m, period s) of the deck's heave at sea state 6 for a frigate-size ship: periods
/// near the roll's waves (7-13 s), amplitudes summing to 1.2 m; the largest vertical speed
/// (amplitude x 2 pi / period, summed) is 0.84 m/s. Ship-helicopter operating limits put the
/// touchdown heave rate at about 1 m/s.
pub const SEA_STATE_6_HEAVE: [(f64, f64); 3] = [(0.8, 9.5), (0.3, 7.2), (0.1, 12.8)];

/// The deck's heave as a sum of sinusoids (m).
#[derive(Debug, Clone, PartialEq)]
pub struct DeckHeave {
    pub heave_m: Vec<Sinusoid>,
}

impl DeckHeave {
    /// [`SEA_STATE_6_HEAVE`] with amplitudes times `scale`, phases from the seed.
    pub fn sea_state_6(seed: u64, scale: f64) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0x4EA7_E000);
        Self {
            heave_m: sinusoids(&mut rng, &SEA_STATE_6_HEAVE, scale),
        }
    }

    pub fn at(&self, t_s: f64) -> f64 {
        sum(&self.heave_m, t_s)
    }

    /// The vertical speed (m/s).
    pub fn rate(&self, t_s: f64) -> f64 {
        self.heave_m.iter().map(|c| c.rate(t_s)).sum()
    }
}

/// A motion profile whose deck heaves while the vehicle holds its height in W: the camera's
/// height over the deck is the inner profile's less the heave.
pub struct Heaving<P> {
    pub inner: P,
    pub heave: DeckHeave,
}

impl<P: MotionProfile> MotionProfile for Heaving<P> {
    fn sample(&self, t_s: f64) -> MotionSample {
        let mut s = self.inner.sample(t_s);
        let h = self.heave.at(t_s);
        s.deck_heave_m += h;
        s.viewpoint.altitude_m -= h;
        s
    }
}

/// A sea state's significant wave height (m) and modal (peak) period (s), as NATO STANAG 4194
/// tabulates them for the open ocean (sea states 3-6).
pub fn sea_state_waves(sea_state: u32) -> Option<(f64, f64)> {
    match sea_state {
        3 => Some((0.88, 7.5)),
        4 => Some((1.88, 8.8)),
        5 => Some((3.25, 9.7)),
        6 => Some((5.0, 12.4)),
        _ => None,
    }
}

/// Ship motion from a wave spectrum rather than a few sinusoids (so not the family the
/// decider's predictor fits): a JONSWAP spectrum (peak enhancement 3.3) of `COMPONENTS` waves
/// with random frequencies and phases, seen from a ship at 5 m/s (encounter frequencies), through
/// a simple ship response: roll a damped resonance at an 11 s natural period (damping 0.1) of
/// the wave slope across the ship, pitch the wave slope along it low-passed at 6 s, heave the
/// elevation low-passed at 8 s. The heading relative to the waves wanders (+-25 deg over 10 min
/// about 60 deg), so roll and pitch trade places slowly.
///
/// `bench/predict_bound.py` replicates this model in numpy (its spectrum, response and heading)
/// to bound what a forecast could clear on: a change here belongs there too.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectrumShipMotion {
    /// The waves as the ship meets them.
    waves: Vec<EncounteredWave>,
    yaw_deg: Vec<Sinusoid>,
    /// The waves' mean heading off the bow (rad).
    mean_heading: f64,
    pub tracking: TrackingError,
}

/// One wave of a spectrum sea as the ship meets it: roll, pitch and heave answer it at its
/// encounter frequency, each with its amplitude and a phase of its own; stored as the
/// coefficients of `sin` and `cos` of the wave's phase, so a sample takes one `sin_cos` per
/// wave rather than a `sin` per wave and motion (a trial samples the sea some 40 times a frame).
#[derive(Debug, Clone, PartialEq)]
struct EncounteredWave {
    /// Encounter angular frequency (rad/s) and phase (rad).
    rate: f64,
    phase: f64,
    /// Roll, deg per unit sin of the heading: `roll_deg sin(phase)`.
    roll_deg: f64,
    /// Pitch, deg per unit cos of the heading: `pitch_deg[0] sin + pitch_deg[1] cos`.
    pitch_deg: [f64; 2],
    /// Heave: `heave_m[0] sin + heave_m[1] cos`.
    heave_m: [f64; 2],
    /// The wave itself: its angular frequency (rad/s) and amplitude (m), for a roll model of its
    /// own on the same waves ([`WaveEncounter`]).
    wave_rate: f64,
    amplitude_m: f64,
}

/// One wave of a spectrum sea as the ship meets it: what a response model of its own needs
/// (`ship::nonlinear_roll` forces its roll equation with these waves' slopes, so its pitch and
/// heave stay the spectrum sea's). The wave's slope across the ship goes as
/// `sin(encounter_rad_s t + phase_rad)`, as the spectrum sea's roll does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveEncounter {
    /// The wave's own angular frequency (rad/s) and amplitude (m).
    pub wave_rad_s: f64,
    pub amplitude_m: f64,
    /// Its encounter angular frequency (rad/s) and phase (rad).
    pub encounter_rad_s: f64,
    pub phase_rad: f64,
}

impl EncounteredWave {
    /// `amplitude sin(phase + offset)` as the coefficients of `sin(phase)` and `cos(phase)`.
    fn shifted(amplitude: f64, offset: f64) -> [f64; 2] {
        [amplitude * offset.cos(), amplitude * offset.sin()]
    }

    /// `(sin, cos)` of the wave's phase at `t_s`.
    fn phase_sin_cos(&self, t_s: f64) -> (f64, f64) {
        (self.rate * t_s + self.phase).sin_cos()
    }

    /// Its heave (m), from `(sin, cos)` of its phase.
    fn heave_m(&self, (sin, cos): (f64, f64)) -> f64 {
        self.heave_m[0] * sin + self.heave_m[1] * cos
    }
}

const COMPONENTS: usize = 300;
const GRAVITY: f64 = 9.81;

impl SpectrumShipMotion {
    /// The JONSWAP sea of significant wave height `hs_m` and peak period `tp_s`, phases and
    /// frequencies from `seed`.
    pub fn jonswap(hs_m: f64, tp_s: f64, seed: u64) -> Self {
        Self::jonswap_from(hs_m, tp_s, seed, 60.0)
    }

    /// The same with the waves coming from `mean_heading_deg` off the bow on average (0: head
    /// seas, mostly pitch; 90: beam seas, mostly roll).
    pub fn jonswap_from(hs_m: f64, tp_s: f64, seed: u64, mean_heading_deg: f64) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0x0005_EA5B_EC7A);
        let wp = TAU / tp_s;
        let spectrum = |w: f64| {
            let sigma = if w <= wp { 0.07 } else { 0.09 };
            let r = (-(w - wp).powi(2) / (2.0 * sigma * sigma * wp * wp)).exp();
            w.powi(-5) * (-1.25 * (wp / w).powi(4)).exp() * 3.3f64.powf(r)
        };
        // Random frequencies (so the sum never repeats) over the band that holds the energy.
        let (w_lo, w_hi) = (0.5 * wp, 3.0 * wp);
        let dw = (w_hi - w_lo) / COMPONENTS as f64;
        let waves: Vec<(f64, f64)> = (0..COMPONENTS)
            .map(|i| {
                let w = w_lo + (i as f64 + rng.next_f64()) * dw;
                (w, spectrum(w) * dw)
            })
            .collect();
        // Scaled so that 4 sqrt(m0) = Hs.
        let m0: f64 = waves.iter().map(|(_, e)| e).sum();
        let scale = (hs_m / 4.0).powi(2) / m0;
        let (speed_mps, mean_heading) = (5.0, mean_heading_deg.to_radians());
        let (wr, zeta, wpitch, wheave) = (TAU / 11.0, 0.1, TAU / 6.0, TAU / 8.0);
        let mut encountered = Vec::with_capacity(waves.len());
        for (w, e) in waves {
            let a = (2.0 * e * scale).sqrt();
            let k = w * w / GRAVITY;
            // Encounter frequency for waves from `mean_heading` off the bow.
            let we = (w - k * speed_mps * mean_heading.cos()).abs().max(0.05);
            let slope_deg = (k * a).to_degrees();
            let u = we / wr;
            let resonance = 1.0 / ((1.0 - u * u).powi(2) + (2.0 * zeta * u).powi(2)).sqrt();
            let low_pass = |wc: f64| 1.0 / (1.0 + (we / wc).powi(4)).sqrt();
            let phase = TAU * rng.next_f64();
            encountered.push(EncounteredWave {
                rate: we,
                phase,
                roll_deg: slope_deg * resonance,
                pitch_deg: EncounteredWave::shifted(0.6 * slope_deg * low_pass(wpitch), 0.5),
                heave_m: EncounteredWave::shifted(a * low_pass(wheave), -0.3),
                wave_rate: w,
                amplitude_m: a,
            });
        }
        let yaw_deg = sinusoids(&mut rng, &SEA_STATE_6_YAW, hs_m / 5.0);
        Self {
            waves: encountered,
            yaw_deg,
            mean_heading,
            tracking: TrackingError::hover(5.0),
        }
    }

    /// The sea state's JONSWAP sea ([`sea_state_waves`]).
    pub fn sea_state(sea_state: u32, seed: u64) -> Option<Self> {
        sea_state_waves(sea_state).map(|(hs, tp)| Self::jonswap(hs, tp, seed))
    }

    /// The same with the waves from `mean_heading_deg` off the bow.
    pub fn sea_state_from(sea_state: u32, seed: u64, mean_heading_deg: f64) -> Option<Self> {
        sea_state_waves(sea_state).map(|(hs, tp)| Self::jonswap_from(hs, tp, seed, mean_heading_deg))
    }

    /// The waves as the ship meets them.
    pub fn encounters(&self) -> impl Iterator<Item = WaveEncounter> + '_ {
        self.waves.iter().map(|w| WaveEncounter {
            wave_rad_s: w.wave_rate,
            amplitude_m: w.amplitude_m,
            encounter_rad_s: w.rate,
            phase_rad: w.phase,
        })
    }

    /// The heading of the waves off the bow (rad): wandering +-25 deg over 10 min about the mean.
    pub fn wave_heading_rad(&self, t_s: f64) -> f64 {
        self.mean_heading + (25.0 * (TAU * t_s / 600.0).sin()).to_radians()
    }

    /// Roll (deg per unit sin of the heading), pitch (deg per unit cos of the heading) and heave
    /// (m) at `t_s`.
    fn motion(&self, t_s: f64) -> [f64; 3] {
        let mut m = [0.0; 3];
        for w in &self.waves {
            let (sin, cos) = w.phase_sin_cos(t_s);
            m[0] += w.roll_deg * sin;
            m[1] += w.pitch_deg[0] * sin + w.pitch_deg[1] * cos;
            m[2] += w.heave_m((sin, cos));
        }
        m
    }

    /// The deck's heave (m).
    pub fn heave_m(&self, t_s: f64) -> f64 {
        self.waves.iter().map(|w| w.heave_m(w.phase_sin_cos(t_s))).sum()
    }
}

impl MotionProfile for SpectrumShipMotion {
    fn sample(&self, t_s: f64) -> MotionSample {
        let chi = self.wave_heading_rad(t_s);
        let [roll, pitch, heave_m] = self.motion(t_s);
        MotionSample {
            t_s,
            attitude: Rpy::from_degrees(chi.sin() * roll, chi.cos() * pitch, sum(&self.yaw_deg, t_s)),
            viewpoint: self.tracking.at(t_s),
            deck_heave_m: heave_m,
        }
    }
}

/// Samples a profile at `rate_hz` for `n` frames starting at t = 0.
pub fn sample_series(profile: &dyn MotionProfile, rate_hz: f64, n: usize) -> Vec<MotionSample> {
    (0..n).map(|k| profile.sample(k as f64 / rate_hz)).collect()
}

#[cfg(test)]
mod tests {

    #[test]
    fn spectrum_seas_have_their_wave_height_and_plausible_motion() {
        // Roll up to a few degrees at sea state 3, tens at 6 (frigates roll 20-30 deg in it).
        for (ss, roll_range) in [(3, 0.5..10.0), (6, 10.0..45.0)] {
            let sea = SpectrumShipMotion::sea_state(ss, 1).unwrap();
            let (hs, _) = sea_state_waves(ss).unwrap();
            let n = 60_000;
            let (mut heave2, mut roll_max) = (0.0, 0.0f64);
            for k in 0..n {
                let s = sea.sample(k as f64 * 0.1);
                heave2 += s.deck_heave_m * s.deck_heave_m;
                roll_max = roll_max.max(s.attitude.to_degrees()[0].abs());
            }
            // The heave is the low-passed elevation: a bit under the waves' own 4 sigma.
            let heave_hs = 4.0 * (heave2 / n as f64).sqrt();
            assert!(
                heave_hs > 0.3 * hs && heave_hs < 1.1 * hs,
                "SS{ss}: {heave_hs} vs {hs}"
            );
            assert!(
                roll_range.contains(&roll_max),
                "SS{ss}: roll up to {roll_max} deg"
            );
        }
        assert!(SpectrumShipMotion::sea_state(7, 1).is_none());
    }

    #[test]
    fn hover_sway_stays_within_its_bounds_and_rates() {
        let sway = VehicleSway::hover(3, 1.0);
        let (mut max_tilt, mut max_rate) = ([0.0f64; 2], [0.0f64; 2]);
        let dt = 0.001;
        for k in 0..120_000 {
            let t = k as f64 * dt;
            let a = sway.attitude(t).to_degrees();
            let b = sway.attitude(t + dt).to_degrees();
            for i in 0..2 {
                max_tilt[i] = max_tilt[i].max(a[i].abs());
                max_rate[i] = max_rate[i].max((b[i] - a[i]).abs() / dt);
            }
        }
        assert!(max_tilt[0] > 6.0 && max_tilt[0] <= 9.1 + 1e-9, "{max_tilt:?}");
        assert!(max_tilt[1] > 5.0 && max_tilt[1] <= 7.8 + 1e-9, "{max_tilt:?}");
        assert!(max_rate[0] > 15.0 && max_rate[0] <= 30.0, "{max_rate:?}");
        assert!(max_rate[1] <= 30.0, "{max_rate:?}");
        let s = Swaying {
            inner: Case1Sweep::paper(),
            sway,
        }
        .sample(2.0);
        let expected = VehicleSway::hover(3, 1.0).attitude(2.0).to_matrix();
        assert_eq!(s.viewpoint.vehicle_attitude, expected);
        assert_eq!(s.attitude, Case1Sweep::paper().sample(2.0).attitude);
    }

    use super::*;

    #[test]
    fn case1_spans_the_paper_ranges() {
        let c = Case1Sweep::paper();
        assert_eq!(c.sample(0.0).attitude.to_degrees(), [-20.0, -10.0, -5.0]);
        let end = c.sample(20.0).attitude.to_degrees();
        assert!(
            (end[0] - 20.0).abs() < 1e-12 && (end[1] - 10.0).abs() < 1e-12 && (end[2] - 5.0).abs() < 1e-12
        );
        let mid = c.sample(10.0).attitude.to_degrees();
        assert_eq!(mid, [0.0, 0.0, 0.0], "the sweep passes through the level deck");
    }

    #[test]
    fn ship_motion_is_deterministic_and_bounded() {
        let a = ShipMotion::sea_state_6(7);
        assert_eq!(a, ShipMotion::sea_state_6(7));
        assert_ne!(a, ShipMotion::sea_state_6(8));
        assert_eq!(a.amplitude_bounds_deg(), [25.0, 8.0, 5.0]);
        let series = sample_series(&a, 10.0, 36_000); // one hour at 10 Hz
        let max = |f: fn(&MotionSample) -> f64| series.iter().map(f).fold(0.0f64, |m, v| m.max(v.abs()));
        let roll = max(|s| s.attitude.roll.to_degrees());
        let pitch = max(|s| s.attitude.pitch.to_degrees());
        let yaw = max(|s| s.attitude.yaw.to_degrees());
        assert!(roll <= 25.0 && roll > 20.0, "roll {roll}");
        assert!(pitch <= 8.0 && pitch > 6.0, "pitch {pitch}");
        assert!(yaw <= 5.0 && yaw > 4.0, "yaw {yaw}");
    }

    #[test]
    fn offset_tracking_stays_in_its_box() {
        let t = TrackingError::offset_0_3m(1);
        for k in 0..1000 {
            let v = t.at(k as f64 * 0.1);
            assert!((v.offset_x_m.hypot(v.offset_y_m) - 0.3).abs() < 1e-12);
            assert!((4.5..=5.5).contains(&v.altitude_m));
        }
    }

    #[test]
    fn the_lulls_calm_and_build_and_calm_again() {
        let c = LullCycle::DEMO;
        assert_eq!(c.period_s(), 86.0);
        assert_eq!(c.factor(0.0), 0.15);
        assert_eq!(c.factor(39.9), 0.15);
        assert!((c.factor(44.0) - 0.375).abs() < 1e-12); // half way up
        assert_eq!(c.factor(60.0), 0.6);
        assert_eq!(c.factor(86.0 + 10.0), 0.15); // the next lull
        assert_eq!(c.factor(f64::NAN), 0.15);
        // The factor moves smoothly: no step between frames.
        let steps = (0..8600).map(|k| (c.factor(k as f64 / 100.0) - c.factor((k + 1) as f64 / 100.0)).abs());
        assert!(steps.fold(0.0, f64::max) < 0.001);
        // Angles and heave scale together; the camera keeps its height in W.
        let heaving = Heaving {
            inner: ShipMotion::sea_state_6(3),
            heave: DeckHeave::sea_state_6(3, 1.0),
        };
        let plain = heaving.sample(60.0);
        let lulled = Lulled {
            inner: heaving,
            cycle: c,
        }
        .sample(60.0);
        assert!((lulled.attitude.roll - 0.6 * plain.attitude.roll).abs() < 1e-12);
        assert!((lulled.deck_heave_m - 0.6 * plain.deck_heave_m).abs() < 1e-12);
        assert!((lulled.vehicle_height_m() - plain.vehicle_height_m()).abs() < 1e-12);
    }
}
