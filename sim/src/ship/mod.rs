//! A family of ship-motion models, each named, each deterministic for a sea state, a wave
//! heading and a seed, each giving the deck's roll, pitch, yaw (deg) and the pad's heave (m) at
//! any time, and each able to become a motion file (`motion_file`, `deckwatch sim motion`) that
//! `decide-eval` and `trials` read with `--motion-csv`. docs/ship-motion.md describes them.
//!
//! - [`ShipMotionModel::Spectrum`]: today's spectrum sea ([`SpectrumShipMotion`]): a
//!   long-crested JONSWAP sea through a linear response.
//! - [`ShipMotionModel::NonlinearRoll`]: the same waves and pitch and heave, the roll from an
//!   equation of motion with linear and quadratic damping and a softening righting arm
//!   ([`NonlinearRollMotion`]): its period grows with its amplitude and it is not Gaussian.
//! - [`ShipMotionModel::ShortCrested`]: waves from a spread of directions, the ship under way
//!   with its course wandering and its autopilot's yaw, each wave met at its own encounter
//!   frequency, the pad aft of the centre of gravity ([`ShortCrestedMotion`]).
//! - [`ShipMotionModel::HullRao`]: the spectrum sea's waves met under way, the frigate's heave,
//!   roll and pitch from a hydrodynamics code's response amplitude operators
//!   (`sim/data/frigate_rao.csv`, made by `bench/hull_rao.py` with Capytaine;
//!   [`HullRaoMotion`]).

mod course;
pub mod hull;
pub mod hull_rao;
pub mod nonlinear_roll;
pub mod short_crested;

pub use course::{CourseKeeping, CourseKeepingParams};
pub use hull::Hull;
pub use hull_rao::{HullRaoMotion, HullRaoParams, RaoTable, RaoTableError, Responses};
pub use nonlinear_roll::{NonlinearRollMotion, NonlinearRollParams, RollEquation};
pub use short_crested::{ShortCrestedMotion, ShortCrestedParams};

use crate::motion::{sea_state_waves, MotionProfile, MotionSample, SpectrumShipMotion};
use crate::motion_file::MotionRow;

/// The ship-motion models, by name (`deckwatch sim motion --model NAME`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShipMotionModel {
    Spectrum,
    NonlinearRoll,
    ShortCrested,
    HullRao,
}
deckwatch_common::named_enum!(ShipMotionModel, [
    Spectrum => "spectrum",
    NonlinearRoll => "nonlinear-roll",
    ShortCrested => "short-crested",
    HullRao => "hull-rao",
]);

impl ShipMotionModel {
    /// What the model is, in a line.
    pub fn description(&self) -> &'static str {
        match self {
            Self::Spectrum => "long-crested JONSWAP sea through a linear response (the spectrum sea)",
            Self::NonlinearRoll => {
                "the spectrum sea's waves, pitch and heave; roll from a nonlinear equation of motion"
            }
            Self::ShortCrested => {
                "directionally spread waves, the ship under way on a wandering course, pad aft of G"
            }
            Self::HullRao => {
                "the spectrum sea's waves met under way, the frigate's responses from a BEM code (Capytaine)"
            }
        }
    }

    /// The model's sea for `spec`, with the model's default parameters.
    pub fn build(self, spec: &SeaSpec) -> Result<ShipSea, ShipMotionError> {
        match self {
            Self::Spectrum => spec.validate().and_then(|_| {
                SpectrumShipMotion::sea_state_from(spec.sea_state, spec.seed, spec.heading_deg)
                    .map(ShipSea::Spectrum)
                    .ok_or(ShipMotionError::NoSeaState(spec.sea_state))
            }),
            Self::NonlinearRoll => {
                NonlinearRollMotion::new(spec, &NonlinearRollParams::FRIGATE).map(ShipSea::NonlinearRoll)
            }
            Self::ShortCrested => {
                ShortCrestedMotion::new(spec, &ShortCrestedParams::FRIGATE).map(ShipSea::ShortCrested)
            }
            Self::HullRao => HullRaoMotion::new(spec, &HullRaoParams::FRIGATE).map(ShipSea::HullRao),
        }
    }
}

/// The longest motion a model precomputes (s): 6 hours (the nonlinear roll keeps 100 samples
/// a second, 35 MB for that long).
pub const MAX_DURATION_S: f64 = 6.0 * 3600.0;

/// What every model's sea is made of: which sea, from where, which realisation, how long.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeaSpec {
    /// The sea state (3-6, [`sea_state_waves`]: its significant wave height and peak period).
    pub sea_state: u32,
    /// The waves' mean direction off the bow (deg; 0 head seas, 90 beam seas, 180 following).
    pub heading_deg: f64,
    /// The seed of the waves' frequencies, directions and phases and of the course's wander.
    pub seed: u64,
    /// How long the motion is needed from t = 0 (s): the models that integrate in time
    /// (nonlinear roll, the short-crested sea's track) precompute it and hold their state
    /// beyond it. At most [`MAX_DURATION_S`].
    pub duration_s: f64,
}

impl SeaSpec {
    /// Checks the heading and duration; the sea state's waves (Hs m, Tp s).
    pub fn validate(&self) -> Result<(f64, f64), ShipMotionError> {
        if !self.heading_deg.is_finite() {
            return Err(ShipMotionError::BadParameter {
                name: "heading_deg",
                value: self.heading_deg,
                expected: "a finite angle (deg)",
            });
        }
        if !(self.duration_s > 0.0 && self.duration_s <= MAX_DURATION_S) {
            return Err(ShipMotionError::BadParameter {
                name: "duration_s",
                value: self.duration_s,
                expected: "positive, at most 6 hours (21600 s)",
            });
        }
        sea_state_waves(self.sea_state).ok_or(ShipMotionError::NoSeaState(self.sea_state))
    }
}

/// Why a model's sea cannot be made or sampled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShipMotionError {
    #[error("sea state {0} has no sea (3, 4, 5, 6)")]
    NoSeaState(u32),
    #[error("{name} = {value}: must be {expected}")]
    BadParameter {
        name: &'static str,
        value: f64,
        expected: &'static str,
    },
    #[error("the table of responses: {0}")]
    RaoTable(#[from] RaoTableError),
}

/// One model's sea, ready to sample.
#[derive(Debug, Clone, PartialEq)]
pub enum ShipSea {
    Spectrum(SpectrumShipMotion),
    NonlinearRoll(NonlinearRollMotion),
    ShortCrested(ShortCrestedMotion),
    HullRao(HullRaoMotion),
}

impl MotionProfile for ShipSea {
    fn sample(&self, t_s: f64) -> MotionSample {
        match self {
            Self::Spectrum(s) => s.sample(t_s),
            Self::NonlinearRoll(s) => s.sample(t_s),
            Self::ShortCrested(s) => s.sample(t_s),
            Self::HullRao(s) => s.sample(t_s),
        }
    }
}

/// The lowest and highest rate a motion file is written at (Hz): the reader needs 10 Hz or
/// more; above 1 kHz the file's microsecond times would no longer step evenly.
pub const MOTION_FILE_RATES_HZ: (f64, f64) = (10.0, 1000.0);

/// `profile`'s deck from t = 0 to `duration_s` (inclusive, when it falls on a sample) at
/// `rate_hz`: the rows of a motion file.
pub fn motion_rows(
    profile: &dyn MotionProfile,
    rate_hz: f64,
    duration_s: f64,
) -> Result<Vec<MotionRow>, ShipMotionError> {
    let (lowest, highest) = MOTION_FILE_RATES_HZ;
    if !(rate_hz >= lowest && rate_hz <= highest) {
        return Err(ShipMotionError::BadParameter {
            name: "rate_hz",
            value: rate_hz,
            expected: "within 10-1000 Hz (a motion file holds 10 Hz or more)",
        });
    }
    if !(duration_s > 0.0 && duration_s <= MAX_DURATION_S) {
        return Err(ShipMotionError::BadParameter {
            name: "duration_s",
            value: duration_s,
            expected: "positive, at most 6 hours (21600 s)",
        });
    }
    // The tolerance keeps a duration that is a whole number of steps (1800 s at 10 Hz) whole.
    let steps = (duration_s * rate_hz + 1e-6).floor() as usize;
    Ok((0..=steps)
        .map(|k| MotionRow::of(&profile.sample(k as f64 / rate_hz)))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion_file::{motion_csv_text, RecordedShipMotion};

    fn spec(seed: u64) -> SeaSpec {
        SeaSpec {
            sea_state: 5,
            heading_deg: 60.0,
            seed,
            duration_s: 300.0,
        }
    }

    #[test]
    fn every_model_is_named_and_deterministic_for_its_seed() {
        for model in ShipMotionModel::ALL {
            assert_eq!(ShipMotionModel::from_name(model.name()), Some(model));
            let a = model.build(&spec(7)).unwrap();
            let rows = |sea: &ShipSea| motion_rows(sea, 10.0, 300.0).unwrap();
            let first = rows(&a);
            assert_eq!(first.len(), 3001, "{}", model.name());
            // Same seed, same samples, bit for bit; another seed, other samples.
            assert_eq!(first, rows(&model.build(&spec(7)).unwrap()), "{}", model.name());
            let other = rows(&model.build(&spec(8)).unwrap());
            let differ = first
                .iter()
                .zip(&other)
                .filter(|(x, y)| x.roll_deg != y.roll_deg && x.heave_m != y.heave_m)
                .count();
            assert!(differ > 2900, "{}: {differ}", model.name());
        }
        assert!(ShipMotionModel::parse("sinusoid")
            .unwrap_err()
            .to_string()
            .contains("spectrum, nonlinear-roll, short-crested"));
    }

    #[test]
    fn every_model_writes_a_file_that_reads_back() {
        for model in ShipMotionModel::ALL {
            let sea = model.build(&spec(3)).unwrap();
            let rows = motion_rows(&sea, 20.0, 120.0).unwrap();
            let text = motion_csv_text(&[model.name().to_string()], &rows, "sea.csv").unwrap();
            let read = RecordedShipMotion::parse(&text, "sea.csv").unwrap();
            assert!((read.duration_s() - 120.0).abs() < 1e-9);
            for row in rows.iter().step_by(37) {
                let [r, p, y, h] = read.at(row.time_s);
                let close = |a: f64, b: f64| (a - b).abs() <= 0.5e-6 + 1e-12;
                assert!(
                    close(r, row.roll_deg) && close(p, row.pitch_deg) && close(y, row.yaw_deg),
                    "{}",
                    model.name()
                );
                assert!(close(h, row.heave_m), "{}", model.name());
            }
        }
    }

    #[test]
    fn bad_specs_are_refused_by_every_model() {
        for model in ShipMotionModel::ALL {
            let bad = |s: SeaSpec| model.build(&s).unwrap_err();
            assert_eq!(
                bad(SeaSpec {
                    sea_state: 7,
                    ..spec(1)
                }),
                ShipMotionError::NoSeaState(7)
            );
            for spec in [
                SeaSpec {
                    heading_deg: f64::NAN,
                    ..spec(1)
                },
                SeaSpec {
                    duration_s: 0.0,
                    ..spec(1)
                },
                SeaSpec {
                    duration_s: 1e9,
                    ..spec(1)
                },
            ] {
                assert!(matches!(bad(spec), ShipMotionError::BadParameter { .. }));
            }
        }
        let sea = ShipMotionModel::Spectrum.build(&spec(1)).unwrap();
        for (rate, duration) in [
            (9.0, 10.0),
            (f64::NAN, 10.0),
            (2000.0, 10.0),
            (10.0, -1.0),
            (10.0, f64::INFINITY),
        ] {
            assert!(motion_rows(&sea, rate, duration).is_err(), "{rate} {duration}");
        }
    }
}
