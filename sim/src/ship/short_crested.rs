//! Short-crested seas: waves from a spread of directions, met by a ship under way whose course
//! wanders, each wave at its own encounter frequency; the pad aft of the centre of gravity.

use super::course::{CourseKeeping, CourseKeepingParams};
use super::hull::{encounter_rad_s, knots_to_mps, low_pass, resonance, wavenumber_rad_m, Hull};
use super::{SeaSpec, ShipMotionError};
use crate::motion::{MotionProfile, MotionSample, TrackingError};
use crate::rng::SplitMix64;
use deckwatch_common::Rpy;
use nalgebra::{Complex, Vector3};
use std::f64::consts::{PI, TAU};

/// The short-crested sea's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShortCrestedParams {
    pub hull: Hull,
    /// The ship's speed through the water (kn). Flight operations are flown at 10-15 kn, enough
    /// for steerage and for the wind over the deck.
    pub speed_kn: f64,
    /// The spreading's `s` of `D(theta) ~ cos^(2s)((theta - theta_0) / 2)` (Longuet-Higgins,
    /// Cartwright and Smith 1963; Mitsuyasu et al. 1975): 10 for wind seas, 25 for a young
    /// swell, 75 for a long swell (Goda, Random Seas and Design of Maritime Structures, 2000).
    /// One `s` for every frequency (Mitsuyasu's narrows at the peak).
    pub spreading_s: f64,
    /// Wave components, each with its own frequency and direction ("single summation", which
    /// never repeats in space or time).
    pub components: usize,
    /// The roll's damping ratio (linear, equivalent: a frigate with bilge keels at speed).
    pub roll_damping_ratio: f64,
    /// How the ship keeps its course (the wander, the autopilot's yaw).
    pub course: CourseKeepingParams,
}

impl ShortCrestedParams {
    /// The frigate at 10 kn in a wind sea: `s` 10, course wander 2 deg over 2 min, the
    /// autopilot's yaw 1 deg at 25 s in sea state 6.
    pub const FRIGATE: Self = Self {
        hull: Hull::FRIGATE,
        speed_kn: 10.0,
        spreading_s: 10.0,
        components: 800,
        roll_damping_ratio: 0.1,
        course: CourseKeepingParams::FRIGATE,
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
        if !(self.speed_kn >= 0.0 && self.speed_kn <= 40.0) {
            return bad("speed_kn", self.speed_kn, "within 0-40 kn");
        }
        if !(self.spreading_s > 0.0 && self.spreading_s <= 10_000.0) {
            return bad("spreading_s", self.spreading_s, "within (0, 10000]");
        }
        if !(1..=100_000).contains(&self.components) {
            return bad("components", self.components as f64, "within 1-100000");
        }
        if !(self.roll_damping_ratio > 0.0 && self.roll_damping_ratio < 1.0) {
            return bad("roll_damping_ratio", self.roll_damping_ratio, "within (0, 1)");
        }
        self.course.validate()
    }
}

/// The corner periods (s) of the pitch and heave low-passes in the encounter frequency (the
/// ship's heave and pitch are heavily damped resonances near 5-6 s): the spectrum sea's
/// (`motion::SpectrumShipMotion`).
const PITCH_CORNER_S: f64 = 6.0;
const HEAVE_CORNER_S: f64 = 8.0;

/// The share of a wave's elevation that heaves a ship of length `L` and of its slope along the
/// ship that pitches it, for the wavenumber along the ship `k_x` (rad/m): with `x = k_x L / 2`,
/// heave `sin x / x` and pitch `3 (sin x - x cos x) / x^3`, both 1 for long waves and small once
/// the ship spans a wave (Jensen, Mansour and Olsen 2004, "Estimation of ship motions using
/// closed-form expressions", Ocean Engineering 31: a box hull's heave and pitch excitation).
/// Without them a short wave met head on at speed would pitch and heave a 120 m ship as much as
/// a long one.
fn length_shares(k_along_rad_m: f64, length_m: f64) -> (f64, f64) {
    let x = 0.5 * k_along_rad_m.abs() * length_m;
    if x < 1e-3 {
        // The series' first terms: sin x / x = 1 - x^2/6, 3 (sin x - x cos x) / x^3 = 1 - x^2/10.
        return (1.0 - x * x / 6.0, 1.0 - x * x / 10.0);
    }
    let (sin, cos) = x.sin_cos();
    (sin / x, 3.0 * (sin - x * cos) / (x * x * x))
}

/// One wave: `elevation = amplitude cos(w t + k (x cos theta + y sin theta) + phase)` at the
/// ship's position (x, y) in the mean course's frame, coming from `theta` off the mean course.
#[derive(Debug, Clone, Copy, PartialEq)]
struct DirectionalWave {
    w_rad_s: f64,
    k_rad_m: f64,
    amplitude_m: f64,
    /// cos and sin of the direction it comes from, off the mean course (to port positive).
    from: [f64; 2],
    phase_rad: f64,
    /// Roll per radian of its slope across the ship ([`Hull::roll_slope_share`]).
    roll_share: f64,
}

/// A short-crested sea met by a ship under way ([`ShortCrestedParams`]): for each wave, its
/// phase at the ship's position on its track, its direction off the ship's heading at the
/// moment (the mean plus the course's wander and the autopilot's yaw), its encounter frequency
/// `w + k U cos(off the bow)` ([`encounter_rad_s`]) and the ship's response there (roll a
/// resonance at the hull's natural period; pitch and heave low-passes, each with its phase,
/// of the shares of the wave's slope and elevation a ship of its length feels).
/// The deck's heave is the pad's: the centre of gravity's plus what pitch and roll add at the
/// pad, [`Hull::pad_aft_m`] aft.
#[derive(Debug, Clone, PartialEq)]
pub struct ShortCrestedMotion {
    waves: Vec<DirectionalWave>,
    course: CourseKeeping,
    speed_mps: f64,
    hull: Hull,
    roll_damping_ratio: f64,
    pub tracking: TrackingError,
}

/// Points of the spreading function's cumulative distribution, over -pi..pi.
const SPREADING_GRID: usize = 4001;

impl ShortCrestedMotion {
    /// The sea of `spec` with `params`: JONSWAP (peak enhancement 3.3) of the sea state's Hs and
    /// Tp over 0.5-3 times the peak frequency, each component's direction drawn from the
    /// spreading about `spec.heading_deg`.
    pub fn new(spec: &SeaSpec, params: &ShortCrestedParams) -> Result<Self, ShipMotionError> {
        let (hs_m, tp_s) = spec.validate()?;
        params.validate()?;
        let mut rng = SplitMix64::new(spec.seed ^ 0x5407_C2E5_7ED0);
        let wp = TAU / tp_s;
        let spectrum = |w: f64| {
            let sigma = if w <= wp { 0.07 } else { 0.09 };
            let r = (-(w - wp).powi(2) / (2.0 * sigma * sigma * wp * wp)).exp();
            w.powi(-5) * (-1.25 * (wp / w).powi(4)).exp() * 3.3f64.powf(r)
        };
        let directions = Spreading::new(params.spreading_s);
        let (w_lo, w_hi) = (0.5 * wp, 3.0 * wp);
        let dw = (w_hi - w_lo) / params.components as f64;
        let mean_from = spec.heading_deg.to_radians();
        let mut waves: Vec<DirectionalWave> = (0..params.components)
            .map(|i| {
                let w = w_lo + (i as f64 + rng.next_f64()) * dw;
                let k = wavenumber_rad_m(w);
                let theta = mean_from + directions.draw(rng.next_f64());
                DirectionalWave {
                    w_rad_s: w,
                    k_rad_m: k,
                    amplitude_m: (2.0 * spectrum(w) * dw).sqrt(),
                    from: [theta.cos(), theta.sin()],
                    phase_rad: TAU * rng.next_f64(),
                    roll_share: params.hull.roll_slope_share(k),
                }
            })
            .collect();
        // Scaled so that 4 sqrt(m0) = Hs.
        let m0: f64 = waves.iter().map(|w| 0.5 * w.amplitude_m * w.amplitude_m).sum();
        let scale = hs_m / (4.0 * m0.sqrt());
        for w in &mut waves {
            w.amplitude_m *= scale;
        }
        let speed_mps = knots_to_mps(params.speed_kn);
        let course = params.course.build(hs_m, speed_mps, spec.duration_s, spec.seed);
        Ok(Self {
            waves,
            course,
            speed_mps,
            hull: params.hull,
            roll_damping_ratio: params.roll_damping_ratio,
            tracking: TrackingError::hover(5.0),
        })
    }

    /// Roll, pitch, yaw (rad) and the centre of gravity's heave (m) at `t_s`.
    fn motion(&self, t_s: f64) -> ([f64; 3], f64) {
        let yaw_rad = self.course.yaw_deg(t_s).to_radians();
        let (sin_yaw, cos_yaw) = yaw_rad.sin_cos();
        let [x_m, y_m] = self.course.position_m(t_s);
        let natural = self.hull.natural_roll_rad_s();
        let (pitch_corner, heave_corner) = (TAU / PITCH_CORNER_S, TAU / HEAVE_CORNER_S);
        let (mut roll, mut pitch, mut heave) = (0.0, 0.0, 0.0);
        for w in &self.waves {
            let [cos_from, sin_from] = w.from;
            // Off the bow now: the direction it comes from less the ship's heading.
            let cos_off = cos_from * cos_yaw + sin_from * sin_yaw;
            let sin_off = sin_from * cos_yaw - cos_from * sin_yaw;
            let encounter = w.w_rad_s + w.k_rad_m * self.speed_mps * cos_off;
            let phase = w.w_rad_s * t_s + w.k_rad_m * (x_m * cos_from + y_m * sin_from) + w.phase_rad;
            let (sin, cos) = phase.sin_cos();
            let wave = Complex::new(cos, sin);
            let slope = w.k_rad_m * w.amplitude_m;
            // The surface's slope along the ship is -k a cos(off) sin(phase) and across it
            // -k a sin(off) sin(phase): the deck follows them, lowering the bow (positive
            // pitch) where the surface falls ahead, raising port (positive roll) where it rises
            // to port (CONVENTIONS.md §2).
            roll -= w.roll_share
                * slope
                * sin_off
                * (resonance(encounter, natural, self.roll_damping_ratio) * wave).im;
            let (heave_share, pitch_share) = length_shares(w.k_rad_m * cos_off, self.hull.length_m);
            pitch += pitch_share * slope * cos_off * (low_pass(encounter, pitch_corner) * wave).im;
            heave += heave_share * w.amplitude_m * (low_pass(encounter, heave_corner) * wave).re;
        }
        ([roll, pitch, yaw_rad], heave)
    }

    /// The pad's heave (m): the centre of gravity's and the pad's height in the deck's attitude,
    /// `pad_aft_m` aft of it (a bow-down pitch raises it).
    fn pad_heave_m(&self, attitude: &Rpy, centre_heave_m: f64) -> f64 {
        let pad = attitude.to_matrix() * Vector3::new(-self.hull.pad_aft_m, 0.0, 0.0);
        centre_heave_m + pad.z
    }

    /// The encounter frequency (rad/s) of a wave of `w_rad_s` from `from_bow_deg` off the bow,
    /// at this sea's speed ([`encounter_rad_s`]).
    pub fn encounter_rad_s(&self, w_rad_s: f64, from_bow_deg: f64) -> f64 {
        encounter_rad_s(w_rad_s, self.speed_mps, from_bow_deg.to_radians())
    }
}

impl MotionProfile for ShortCrestedMotion {
    fn sample(&self, t_s: f64) -> MotionSample {
        let ([roll, pitch, yaw], heave_m) = self.motion(t_s);
        let attitude = Rpy::new(roll, pitch, yaw);
        MotionSample {
            t_s,
            attitude,
            viewpoint: self.tracking.at(t_s),
            deck_heave_m: self.pad_heave_m(&attitude, heave_m),
        }
    }
}

/// The cos-2s spreading's distribution of directions off its mean, drawn by its inverse
/// cumulative distribution on a grid.
struct Spreading {
    /// Cumulative probability at `-pi + i 2 pi / (SPREADING_GRID - 1)`.
    cumulative: Vec<f64>,
}

impl Spreading {
    fn new(s: f64) -> Self {
        let step = TAU / (SPREADING_GRID - 1) as f64;
        let density = |i: usize| (0.5 * (-PI + i as f64 * step)).cos().max(0.0).powf(2.0 * s);
        let mut cumulative = Vec::with_capacity(SPREADING_GRID);
        let mut sum = 0.0;
        cumulative.push(0.0);
        for i in 1..SPREADING_GRID {
            sum += 0.5 * (density(i - 1) + density(i));
            cumulative.push(sum);
        }
        // The density is 1 at the mean, so the sum is positive for any s.
        for c in &mut cumulative {
            *c /= sum;
        }
        Self { cumulative }
    }

    /// The direction off the mean (rad) at cumulative probability `u` in [0, 1).
    fn draw(&self, u: f64) -> f64 {
        let step = TAU / (SPREADING_GRID - 1) as f64;
        let i = self
            .cumulative
            .partition_point(|&c| c <= u)
            .clamp(1, SPREADING_GRID - 1);
        let (a, b) = (self.cumulative[i - 1], self.cumulative[i]);
        let within = if b > a {
            ((u - a) / (b - a)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        -PI + (i as f64 - 1.0 + within) * step
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::sea_state_waves;

    fn spec(sea_state: u32, heading_deg: f64, seed: u64) -> SeaSpec {
        SeaSpec {
            sea_state,
            heading_deg,
            seed,
            duration_s: 3600.0,
        }
    }

    /// Times the signal crosses zero upwards, interpolated.
    fn up_crossings(values: &[f64], dt_s: f64) -> Vec<f64> {
        values
            .windows(2)
            .enumerate()
            .filter(|(_, p)| p[0] < 0.0 && p[1] >= 0.0)
            .map(|(k, p)| (k as f64 + p[0] / (p[0] - p[1])) * dt_s)
            .collect()
    }

    #[test]
    fn one_wave_is_met_at_the_encounter_frequency_the_formula_gives() {
        // One wave, a narrow spreading, a steady course, the pad at the centre of gravity: the
        // heave is one sinusoid at the encounter frequency.
        let params = ShortCrestedParams {
            components: 1,
            spreading_s: 10_000.0,
            course: CourseKeepingParams {
                wander_deg: 0.0,
                autopilot_yaw_deg: 0.0,
                ..CourseKeepingParams::FRIGATE
            },
            hull: Hull {
                pad_aft_m: 0.0,
                ..Hull::FRIGATE
            },
            ..ShortCrestedParams::FRIGATE
        };
        // 30 kn overtakes the waves from astern: met backwards (a negative encounter frequency).
        for speed_kn in [0.0, 7.0, 15.0, 30.0] {
            for heading_deg in [0.0, 45.0, 90.0, 180.0] {
                let sea = ShortCrestedMotion::new(
                    &spec(4, heading_deg, 2),
                    &ShortCrestedParams { speed_kn, ..params },
                )
                .unwrap();
                let wave = sea.waves[0];
                let from_bow_deg = wave.from[1].atan2(wave.from[0]).to_degrees();
                let off_deg = (from_bow_deg - heading_deg + 540.0).rem_euclid(360.0) - 180.0;
                assert!(off_deg.abs() < 3.0, "{from_bow_deg}");
                let expected = sea.encounter_rad_s(wave.w_rad_s, from_bow_deg).abs();
                let dt = 0.02;
                let heave: Vec<f64> = (0..60_000)
                    .map(|k| sea.sample(k as f64 * dt).deck_heave_m)
                    .collect();
                let crossings = up_crossings(&heave, dt);
                let periods = (crossings.len() - 1) as f64;
                let measured = TAU * periods / (crossings[crossings.len() - 1] - crossings[0]);
                assert!(
                    (measured / expected - 1.0).abs() < 2e-3,
                    "{speed_kn} kn from {heading_deg} deg: {measured} vs {expected} rad/s"
                );
                // And it moved as the formula says: faster head on, slower from astern.
                let shift = wave.k_rad_m * knots_to_mps(speed_kn);
                if heading_deg == 0.0 {
                    assert!((expected - (wave.w_rad_s + shift)).abs() < 1e-3 * shift.max(1e-3));
                }
            }
        }
    }

    #[test]
    fn a_long_ship_averages_short_waves_out() {
        let (heave, pitch) = length_shares(0.0, 120.0);
        assert_eq!((heave, pitch), (1.0, 1.0));
        // Continuous where the series takes over.
        let (a, b) = (
            length_shares(1e-3 / 60.0 * 0.999, 120.0),
            length_shares(1e-3 / 60.0 * 1.001, 120.0),
        );
        assert!((a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9);
        // A wave as long as the ship (x = pi) heaves it not at all; a 240 m swell mostly.
        let k_ship = TAU / 120.0;
        assert!(length_shares(k_ship, 120.0).0.abs() < 1e-12);
        let (heave, pitch) = length_shares(0.5 * k_ship, 120.0);
        assert!(
            (heave - 2.0 / PI).abs() < 1e-12 && pitch > 0.7 && pitch < 0.8,
            "{pitch}"
        );
        // Its sign does not depend on which way the wave runs along the ship.
        assert_eq!(length_shares(-0.03, 120.0), length_shares(0.03, 120.0));
    }

    #[test]
    fn the_spreading_draws_its_distribution() {
        // cos^2s(x/2) about 0: for s = 10 the directions' standard deviation is about
        // 2 / sqrt(2 s + 1) = 0.436 rad (25 deg); a large s is nearly long-crested.
        let mut rng = SplitMix64::new(5);
        for (s, sd) in [(10.0, 0.436), (75.0, 0.163)] {
            let spreading = Spreading::new(s);
            let n = 20_000;
            let draws: Vec<f64> = (0..n).map(|_| spreading.draw(rng.next_f64())).collect();
            let mean = draws.iter().sum::<f64>() / n as f64;
            let var = draws.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n as f64;
            assert!(mean.abs() < 0.02, "{mean}");
            assert!((var.sqrt() / sd - 1.0).abs() < 0.06, "s {s}: {}", var.sqrt());
        }
        assert!(Spreading::new(1.0).draw(0.999_999).abs() <= PI);
    }

    #[test]
    fn the_pad_aft_heaves_with_the_pitch_and_the_motion_is_plausible() {
        // Head seas in sea state 6: the pad 40 m aft heaves more than the centre of gravity
        // by what the pitch adds; roll, pitch and heave within what frigates do.
        let stats = |sea: &ShortCrestedMotion| {
            let n = 12_000;
            let (mut heave2, mut max) = (0.0, [0.0f64; 3]);
            for k in 0..n {
                let s = sea.sample(k as f64 * 0.25);
                heave2 += s.deck_heave_m.powi(2);
                for (m, a) in max.iter_mut().zip(s.attitude.to_degrees()) {
                    *m = m.max(a.abs());
                }
            }
            (4.0 * (heave2 / n as f64).sqrt(), max)
        };
        let (hs, _) = sea_state_waves(6).unwrap();
        let at_pad = ShortCrestedMotion::new(&spec(6, 20.0, 1), &ShortCrestedParams::FRIGATE).unwrap();
        let at_centre = ShortCrestedMotion::new(
            &spec(6, 20.0, 1),
            &ShortCrestedParams {
                hull: Hull {
                    pad_aft_m: 0.0,
                    ..Hull::FRIGATE
                },
                ..ShortCrestedParams::FRIGATE
            },
        )
        .unwrap();
        let (pad_hs, [roll, pitch, yaw]) = stats(&at_pad);
        let (centre_hs, _) = stats(&at_centre);
        assert!(pad_hs > 1.2 * centre_hs, "{pad_hs} vs {centre_hs}");
        assert!(centre_hs > 0.3 * hs && centre_hs < 1.1 * hs, "{centre_hs}");
        assert!(pad_hs < 2.5 * hs, "{pad_hs}");
        assert!((1.0..15.0).contains(&roll), "roll {roll}");
        assert!((2.0..12.0).contains(&pitch), "pitch {pitch}");
        assert!((0.5..15.0).contains(&yaw), "yaw {yaw}");
        // Beam seas roll the ship, more than head seas, within what frigates do at sea state 6.
        let beam = ShortCrestedMotion::new(&spec(6, 90.0, 1), &ShortCrestedParams::FRIGATE).unwrap();
        let (_, [beam_roll, _, _]) = stats(&beam);
        assert!(
            beam_roll > roll && (10.0..45.0).contains(&beam_roll),
            "{beam_roll}"
        );
        // A calm sea state 3 barely moves it.
        let calm = ShortCrestedMotion::new(&spec(3, 90.0, 1), &ShortCrestedParams::FRIGATE).unwrap();
        let (calm_hs, [calm_roll, calm_pitch, _]) = stats(&calm);
        assert!(
            calm_roll < 10.0 && calm_pitch < 3.0 && calm_hs < 1.5,
            "{calm_roll} {calm_pitch} {calm_hs}"
        );
    }

    #[test]
    fn bad_parameters_are_refused() {
        for params in [
            ShortCrestedParams {
                speed_kn: -1.0,
                ..ShortCrestedParams::FRIGATE
            },
            ShortCrestedParams {
                spreading_s: 0.0,
                ..ShortCrestedParams::FRIGATE
            },
            ShortCrestedParams {
                components: 0,
                ..ShortCrestedParams::FRIGATE
            },
            ShortCrestedParams {
                course: CourseKeepingParams {
                    wander_time_s: f64::NAN,
                    ..CourseKeepingParams::FRIGATE
                },
                ..ShortCrestedParams::FRIGATE
            },
        ] {
            assert!(ShortCrestedMotion::new(&spec(5, 0.0, 1), &params).is_err());
        }
    }
}
