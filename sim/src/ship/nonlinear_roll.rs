//! Nonlinear roll: the roll from its equation of motion, forced by the spectrum sea's waves.
//!
//! `(I + A) phi'' + B1 phi' + B2 phi' |phi'| + Delta g GM f(phi) = Delta g GM r alpha(t)`,
//! divided through by the inertia:
//! `phi'' + 2 zeta w0 phi' + b2 phi' |phi'| + w0^2 f(phi) = w0^2 alpha_eff(t)`, with
//! `w0 = sqrt(g GM) / k` the natural roll frequency ([`Hull::natural_roll_rad_s`]),
//! `f(phi) = phi - phi^3 / phi_v^2` the righting arm over GM (it vanishes at `phi_v`), held at
//! its peak beyond it, and `alpha_eff` the waves' effective slope across the ship. The form is
//! the one-degree-of-freedom roll equation of the IMO weather criterion and of the parametric-
//! and synchronous-roll literature (e.g. Himeno 1981, "Prediction of ship roll damping: state
//! of the art"; ITTC Recommended Procedure 7.5-02-07-04.5, "Estimation of roll damping").

use super::hull::{wavenumber_rad_m, Hull};
use super::{SeaSpec, ShipMotionError};
use crate::motion::{MotionProfile, MotionSample, SpectrumShipMotion, WaveEncounter};
use deckwatch_common::Rpy;

/// The roll equation's parameters and how it is integrated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonlinearRollParams {
    pub hull: Hull,
    /// The linear damping's share of critical, `zeta` (1): wave-making and skin friction.
    pub linear_damping_ratio: f64,
    /// The quadratic damping over the inertia, `b2` (1/rad): eddies off the bilge keels, which
    /// grow with the roll rate. With 0.5 the damping's equivalent ratio at 15 deg is the
    /// linear share plus `4 / (3 pi) b2 amplitude` = 0.05 + 0.055 = 0.105, the 0.1 the spectrum
    /// sea's linear roll uses; decay tests of frigates with bilge keels give 0.05-0.15.
    pub quadratic_damping_per_rad: f64,
    /// Where the righting arm vanishes, `phi_v` (deg): the softening's scale (the arm peaks at
    /// `phi_v / sqrt(3)`: 40 deg for 70 deg, a frigate's curve of statical stability).
    /// Infinite: a linear arm.
    pub vanishing_angle_deg: f64,
    /// The integrator's step (s): fixed-step fourth-order Runge-Kutta.
    pub step_s: f64,
    /// The roll is integrated from rest this long before t = 0 (s), so t = 0 finds it rolling
    /// as the sea has made it (the damping forgets the start within a minute or two).
    pub spin_up_s: f64,
}

impl NonlinearRollParams {
    /// The frigate ([`Hull::FRIGATE`]): a 10 s natural period, damping 0.05 + 0.5/rad, the arm
    /// vanishing at 70 deg; 100 Hz RK4 after 5 minutes of spin-up.
    pub const FRIGATE: Self = Self {
        hull: Hull::FRIGATE,
        linear_damping_ratio: 0.05,
        quadratic_damping_per_rad: 0.5,
        vanishing_angle_deg: 70.0,
        step_s: 0.01,
        spin_up_s: 300.0,
    };

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), ShipMotionError> {
        self.hull.validate()?;
        let bad = |name, value, expected| {
            Err(ShipMotionError::BadParameter {
                name,
                value,
                expected,
            })
        };
        if !(self.linear_damping_ratio > 0.0 && self.linear_damping_ratio < 1.0) {
            return bad("linear_damping_ratio", self.linear_damping_ratio, "within (0, 1)");
        }
        if !(self.quadratic_damping_per_rad >= 0.0 && self.quadratic_damping_per_rad <= 100.0) {
            return bad(
                "quadratic_damping_per_rad",
                self.quadratic_damping_per_rad,
                "within 0-100 /rad",
            );
        }
        if !(self.vanishing_angle_deg >= 20.0) {
            return bad(
                "vanishing_angle_deg",
                self.vanishing_angle_deg,
                "at least 20 deg (infinite: a linear arm)",
            );
        }
        if !(self.step_s >= 1e-4 && self.step_s <= 0.05) {
            return bad("step_s", self.step_s, "within 0.0001-0.05 s");
        }
        if !(self.spin_up_s >= 0.0 && self.spin_up_s <= 3600.0) {
            return bad("spin_up_s", self.spin_up_s, "within 0-3600 s");
        }
        Ok(())
    }
}

/// The roll equation divided by the inertia: roll acceleration (rad/s^2) from the roll (rad),
/// its rate (rad/s) and the waves' effective slope (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RollEquation {
    pub natural_rad_s: f64,
    pub linear_damping_ratio: f64,
    pub quadratic_damping_per_rad: f64,
    /// `1 / phi_v^2` (1/rad^2) and the angle of the arm's peak, `phi_v / sqrt(3)` (rad).
    softening_per_rad2: f64,
    peak_rad: f64,
}

impl RollEquation {
    pub fn new(params: &NonlinearRollParams) -> Self {
        let vanishing_rad = params.vanishing_angle_deg.to_radians();
        Self {
            natural_rad_s: params.hull.natural_roll_rad_s(),
            linear_damping_ratio: params.linear_damping_ratio,
            quadratic_damping_per_rad: params.quadratic_damping_per_rad,
            softening_per_rad2: 1.0 / (vanishing_rad * vanishing_rad),
            peak_rad: vanishing_rad / 3f64.sqrt(),
        }
    }

    /// The righting arm over GM (rad): `phi - phi^3 / phi_v^2`, held at its peak beyond the
    /// peak's angle. A real arm falls to zero at `phi_v` and the ship capsizes past it; no sea
    /// a quadrotor lands in rolls a frigate past its peak, and holding it keeps the model
    /// bounded should a sea drive it there.
    pub fn righting_arm_rad(&self, roll_rad: f64) -> f64 {
        let phi = roll_rad.clamp(-self.peak_rad, self.peak_rad);
        phi - phi * phi * phi * self.softening_per_rad2
    }

    /// `phi''` (rad/s^2).
    pub fn acceleration(&self, roll_rad: f64, rate_rad_s: f64, slope_rad: f64) -> f64 {
        let w0 = self.natural_rad_s;
        w0 * w0 * (slope_rad - self.righting_arm_rad(roll_rad))
            - 2.0 * self.linear_damping_ratio * w0 * rate_rad_s
            - self.quadratic_damping_per_rad * rate_rad_s * rate_rad_s.abs()
    }

    /// One fourth-order Runge-Kutta step of `step_s` from `[roll, rate]`, with the slope at the
    /// step's start, middle and end.
    pub fn step(&self, [roll, rate]: [f64; 2], slopes_rad: [f64; 3], step_s: f64) -> [f64; 2] {
        let h = step_s;
        let f = |phi: f64, dphi: f64, alpha: f64| (dphi, self.acceleration(phi, dphi, alpha));
        let k1 = f(roll, rate, slopes_rad[0]);
        let k2 = f(roll + 0.5 * h * k1.0, rate + 0.5 * h * k1.1, slopes_rad[1]);
        let k3 = f(roll + 0.5 * h * k2.0, rate + 0.5 * h * k2.1, slopes_rad[1]);
        let k4 = f(roll + h * k3.0, rate + h * k3.1, slopes_rad[2]);
        [
            roll + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0),
            rate + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1),
        ]
    }
}

/// The waves' effective slope across the ship: `sum c_i sin(w_e,i t + phase_i)`, each wave's
/// sine and cosine carried from step to step by a rotation (four products rather than a
/// `sin_cos` per wave and half step), recomputed exactly every [`Self::RESYNC`] steps so the
/// rounding never accumulates.
struct RotatingSlopes {
    waves: Vec<RotatingWave>,
    /// The time of step 0 (s), the step (s) and how many steps were taken.
    start_s: f64,
    step_s: f64,
    steps: u64,
}

struct RotatingWave {
    /// Slope (rad), encounter frequency (rad/s), phase (rad).
    slope_rad: f64,
    rate: f64,
    phase: f64,
    /// `sin, cos` of its phase now, and of its turn over a step.
    now: (f64, f64),
    turn: (f64, f64),
}

impl RotatingSlopes {
    const RESYNC: u64 = 4096;

    fn new(waves: impl Iterator<Item = (f64, WaveEncounter)>, start_s: f64, step_s: f64) -> Self {
        let waves = waves
            .map(|(slope_rad, w)| RotatingWave {
                slope_rad,
                rate: w.encounter_rad_s,
                phase: w.phase_rad,
                now: (w.encounter_rad_s * start_s + w.phase_rad).sin_cos(),
                turn: (w.encounter_rad_s * step_s).sin_cos(),
            })
            .collect();
        Self {
            waves,
            start_s,
            step_s,
            steps: 0,
        }
    }

    /// The sum now.
    fn value(&self) -> f64 {
        self.waves.iter().map(|w| w.slope_rad * w.now.0).sum()
    }

    /// One step on.
    fn advance(&mut self) {
        self.steps += 1;
        let exact = self.steps.is_multiple_of(Self::RESYNC);
        let t_s = self.start_s + self.steps as f64 * self.step_s;
        for w in &mut self.waves {
            w.now = if exact {
                (w.rate * t_s + w.phase).sin_cos()
            } else {
                let ((s, c), (ds, dc)) = (w.now, w.turn);
                (s * dc + c * ds, c * dc - s * ds)
            };
        }
    }
}

/// The spectrum sea with the roll of [`RollEquation`]: the same waves (frequencies, phases,
/// encounter frequencies and the wandering heading), pitch, yaw and heave as
/// [`SpectrumShipMotion`] of the same sea state, heading and seed; the roll integrated from the
/// waves' slopes across the ship (`sin` of their heading off the bow x `r exp(-k d/2) k a`,
/// [`Hull::roll_slope_share`]) over the spec's duration and interpolated between steps
/// (cubic Hermite on roll and rate). Beyond the duration the roll holds its last value.
#[derive(Debug, Clone, PartialEq)]
pub struct NonlinearRollMotion {
    sea: SpectrumShipMotion,
    step_s: f64,
    /// Roll (rad) and its rate (rad/s) at `k step_s`, from t = 0 to the duration.
    roll: Vec<[f64; 2]>,
}

impl NonlinearRollMotion {
    pub fn new(spec: &SeaSpec, params: &NonlinearRollParams) -> Result<Self, ShipMotionError> {
        spec.validate()?;
        params.validate()?;
        let sea = SpectrumShipMotion::sea_state_from(spec.sea_state, spec.seed, spec.heading_deg)
            .ok_or(ShipMotionError::NoSeaState(spec.sea_state))?;
        let equation = RollEquation::new(params);
        let h = params.step_s;
        let spin_up_steps = (params.spin_up_s / h).ceil() as u64;
        let start_s = -(spin_up_steps as f64) * h;
        // Slopes at half steps: RK4 wants the start, middle and end of each step.
        let mut slopes = RotatingSlopes::new(
            sea.encounters().map(|w| {
                let k = wavenumber_rad_m(w.wave_rad_s);
                (params.hull.roll_slope_share(k) * k * w.amplitude_m, w)
            }),
            start_s,
            0.5 * h,
        );
        let across = |t_s: f64, sum: f64| sea.wave_heading_rad(t_s).sin() * sum;
        let steps = (spec.duration_s / h).ceil() as u64 + 1;
        let mut roll = Vec::with_capacity(steps as usize + 1);
        let mut state = [0.0, 0.0];
        let mut t_s = start_s;
        let mut at_start = across(t_s, slopes.value());
        for k in 0..spin_up_steps + steps {
            if k >= spin_up_steps {
                roll.push(state);
            }
            slopes.advance();
            let middle = across(t_s + 0.5 * h, slopes.value());
            slopes.advance();
            let end = across(t_s + h, slopes.value());
            state = equation.step(state, [at_start, middle, end], h);
            at_start = end;
            t_s = start_s + (k + 1) as f64 * h;
        }
        roll.push(state);
        Ok(Self { sea, step_s: h, roll })
    }

    /// The roll (rad) and its rate (rad/s) at `t_s` (held before 0 and past the duration).
    pub fn roll_at(&self, t_s: f64) -> [f64; 2] {
        let last = self.roll.len().saturating_sub(1);
        let (Some(&first), Some(&end)) = (self.roll.first(), self.roll.last()) else {
            return [0.0, 0.0];
        };
        let position = t_s / self.step_s;
        if !(position > 0.0) {
            return first;
        }
        if position >= last as f64 {
            return end;
        }
        let i = (position as usize).min(last - 1);
        let (a, b) = (self.roll[i], self.roll[i + 1]);
        let (s, h) = (position - i as f64, self.step_s);
        let (s2, s3) = (s * s, s * s * s);
        let roll = (2.0 * s3 - 3.0 * s2 + 1.0) * a[0]
            + (s3 - 2.0 * s2 + s) * h * a[1]
            + (-2.0 * s3 + 3.0 * s2) * b[0]
            + (s3 - s2) * h * b[1];
        let rate = (6.0 * s2 - 6.0 * s) / h * a[0]
            + (3.0 * s2 - 4.0 * s + 1.0) * a[1]
            + (-6.0 * s2 + 6.0 * s) / h * b[0]
            + (3.0 * s2 - 2.0 * s) * b[1];
        [roll, rate]
    }

    /// The largest roll over the duration (deg).
    pub fn max_roll_deg(&self) -> f64 {
        self.roll
            .iter()
            .fold(0.0f64, |m, r| m.max(r[0].abs()))
            .to_degrees()
    }
}

impl MotionProfile for NonlinearRollMotion {
    fn sample(&self, t_s: f64) -> MotionSample {
        let mut s = self.sea.sample(t_s);
        let [roll_rad, _] = self.roll_at(t_s);
        s.attitude = Rpy::new(roll_rad, s.attitude.pitch, s.attitude.yaw);
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(sea_state: u32, heading_deg: f64, seed: u64, duration_s: f64) -> SeaSpec {
        SeaSpec {
            sea_state,
            heading_deg,
            seed,
            duration_s,
        }
    }

    /// The free decay from `roll_deg`: the first half period (s) and the next peak (deg).
    fn half_period(equation: &RollEquation, roll_deg: f64) -> (f64, f64) {
        let h = 0.001;
        let mut state = [roll_deg.to_radians(), 0.0];
        let mut crossings = Vec::new();
        let mut peak = 0.0f64;
        for k in 0..40_000 {
            let next = equation.step(state, [0.0; 3], h);
            if next[0].signum() != state[0].signum() {
                crossings.push((k as f64 + state[0] / (state[0] - next[0])) * h);
            }
            if crossings.len() == 1 {
                peak = peak.max(next[0].abs());
            }
            state = next;
            if crossings.len() == 2 {
                break;
            }
        }
        (crossings[1] - crossings[0], peak.to_degrees())
    }

    #[test]
    fn the_free_roll_slows_as_it_grows_under_the_softening_arm() {
        let equation = RollEquation::new(&NonlinearRollParams::FRIGATE);
        let (small, _) = half_period(&equation, 2.0);
        let (large, next_peak) = half_period(&equation, 35.0);
        let natural_s = std::f64::consts::TAU / Hull::FRIGATE.natural_roll_rad_s();
        // Small rolls at the natural period (the damping lengthens it by sqrt(1 - zeta^2)).
        assert!(
            (2.0 * small / natural_s - 1.0).abs() < 0.01,
            "{small} vs {natural_s}"
        );
        // Large ones slower (Duffing's 3/8 (phi/phi_v)^2, less as the roll decays within the
        // half period): 3.7 % from 35 deg.
        assert!(large > 1.03 * small, "{large} vs {small}");
        // The quadratic damping takes more of a large roll: the next peak well under 35 deg.
        assert!(next_peak < 30.0, "{next_peak}");
        // A linear arm keeps the period.
        let linear = RollEquation::new(&NonlinearRollParams {
            vanishing_angle_deg: f64::INFINITY,
            ..NonlinearRollParams::FRIGATE
        });
        let (a, _) = half_period(&linear, 2.0);
        let (b, _) = half_period(&linear, 35.0);
        assert!((a / b - 1.0).abs() < 0.005, "{a} vs {b}");
        // The arm peaks and holds.
        let peak = equation.righting_arm_rad(1.0);
        assert!(equation.righting_arm_rad(1.5) == peak && equation.righting_arm_rad(-1.5) == -peak);
        assert!(peak > equation.righting_arm_rad(0.65) && peak < 0.7, "{peak}");
    }

    /// Excess kurtosis of a series.
    fn excess_kurtosis(x: &[f64]) -> f64 {
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let m2 = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        let m4 = x.iter().map(|v| (v - mean).powi(4)).sum::<f64>() / n;
        m4 / (m2 * m2) - 3.0
    }

    #[test]
    fn the_forced_roll_is_not_gaussian_and_its_size_is_a_frigates() {
        // Beam seas at sea state 6: the same waves through the linear equation (damping at
        // its equivalent ratio, a straight arm) and the nonlinear one.
        let duration_s = 3.0 * 3600.0;
        let nonlinear =
            NonlinearRollMotion::new(&spec(6, 90.0, 11, duration_s), &NonlinearRollParams::FRIGATE).unwrap();
        let linear_params = NonlinearRollParams {
            linear_damping_ratio: 0.105,
            quadratic_damping_per_rad: 0.0,
            vanishing_angle_deg: f64::INFINITY,
            ..NonlinearRollParams::FRIGATE
        };
        let linear = NonlinearRollMotion::new(&spec(6, 90.0, 11, duration_s), &linear_params).unwrap();
        let series = |m: &NonlinearRollMotion| -> Vec<f64> {
            (0..(duration_s * 2.0) as usize)
                .map(|k| m.sample(k as f64 * 0.5).attitude.roll.to_degrees())
                .collect()
        };
        let (a, b) = (series(&nonlinear), series(&linear));
        let (ka, kb) = (excess_kurtosis(&a), excess_kurtosis(&b));
        let sd = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        // The quadratic damping takes the tops off the large rolls: flatter than the linear
        // roll's distribution (-0.19 against 0.10 on this seed), as wide.
        assert!(ka < kb - 0.15, "{ka} vs {kb}");
        assert!((sd(&a) / sd(&b) - 1.0).abs() < 0.25, "{} vs {}", sd(&a), sd(&b));
        // Frigates roll 20-30 deg at most in sea state 6 beam seas.
        assert!(
            (10.0..45.0).contains(&nonlinear.max_roll_deg()),
            "{}",
            nonlinear.max_roll_deg()
        );
        // Pitch and heave are the spectrum sea's.
        let spectrum = SpectrumShipMotion::sea_state_from(6, 11, 90.0).unwrap();
        let (x, y) = (nonlinear.sample(1234.5), spectrum.sample(1234.5));
        assert_eq!(
            (x.attitude.pitch, x.attitude.yaw, x.deck_heave_m),
            (y.attitude.pitch, y.attitude.yaw, y.deck_heave_m)
        );
    }

    #[test]
    fn the_roll_is_smooth_between_steps_and_held_beyond_the_duration() {
        let m = NonlinearRollMotion::new(&spec(5, 70.0, 3, 120.0), &NonlinearRollParams::FRIGATE).unwrap();
        // The interpolated rate is the roll's derivative.
        let t = 61.2345;
        let d = 1e-4;
        let rate = (m.roll_at(t + d)[0] - m.roll_at(t - d)[0]) / (2.0 * d);
        assert!((rate - m.roll_at(t)[1]).abs() < 1e-5, "{rate}");
        assert_eq!(m.roll_at(500.0), m.roll_at(120.0 + 1.0));
        assert_eq!(m.roll_at(-3.0), m.roll_at(0.0));
        assert_eq!(m.roll_at(f64::NAN), m.roll_at(0.0));
        // Rolling already at t = 0 (the spin-up).
        assert!(m.roll.iter().take(1000).any(|r| r[0].abs() > 0.5f64.to_radians()));
        assert!(NonlinearRollMotion::new(
            &spec(5, 70.0, 3, 120.0),
            &NonlinearRollParams {
                step_s: 0.0,
                ..NonlinearRollParams::FRIGATE
            }
        )
        .is_err());
    }
}
