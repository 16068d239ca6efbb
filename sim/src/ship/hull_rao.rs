//! The frigate's responses from a hydrodynamics code: heave, roll and pitch per metre of wave,
//! computed by Capytaine (boundary elements) for a hull of the frigate's size and mass
//! properties (`bench/hull_rao.py`, which wrote `sim/data/frigate_rao.csv`), driven by the
//! spectrum sea's waves met by a ship under way.

use super::course::{CourseKeeping, CourseKeepingParams};
use super::hull::{encounter_rad_s, knots_to_mps, Hull};
use super::{SeaSpec, ShipMotionError};
use crate::motion::{MotionProfile, MotionSample, SpectrumShipMotion, TrackingError};
use deckwatch_common::Rpy;
use nalgebra::{Complex, Vector3};
use std::sync::OnceLock;

/// The table `bench/hull_rao.py` wrote, compiled in: no file is read at run time.
const FRIGATE_TABLE: &str = include_str!("../../data/frigate_rao.csv");

/// The table's header, its columns in order.
const HEADER: &str = "omega_rad_s,heading_deg,heave_m_per_m,heave_phase_deg,roll_deg_per_m,roll_phase_deg,\
                      pitch_deg_per_m,pitch_phase_deg";

/// Beyond the table's highest frequency the responses taper linearly to nothing at this many
/// times it (1.6 to 2 rad/s: waves of 24 to 15 m, about the beam). The table stops where its
/// panels would be too coarse for the waves; a beam sea of sea state 3 or 4, whose spectrum
/// reaches 2.5 rad/s, loses some of its heave and roll here.
const TAPER_END: f64 = 1.25;

/// Why a table of responses cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RaoTableError {
    #[error("no header line (`{HEADER}`)")]
    NoHeader,
    #[error("line {line}: the header is `{found}`, not `{HEADER}`")]
    Header { line: usize, found: String },
    #[error("line {line}: {count} columns, not 8")]
    Columns { line: usize, count: usize },
    #[error("line {line}, column {column}: `{text}` is not a finite number")]
    NotANumber {
        line: usize,
        column: usize,
        text: String,
    },
    #[error("line {line}: {what}")]
    Row { line: usize, what: &'static str },
    #[error("not a grid: {0}")]
    NotAGrid(&'static str),
}

/// Heave (m), roll and pitch (rad) per metre of wave amplitude, as complex numbers: the motion
/// is `Re(r a exp(i (w t + e)))` for the elevation at G `Re(a exp(i (w t + e)))` (the phase is
/// the lead over the elevation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Responses {
    pub heave_m_per_m: Complex<f64>,
    pub roll_rad_per_m: Complex<f64>,
    pub pitch_rad_per_m: Complex<f64>,
}

impl Responses {
    /// A resting ship's response to an infinitely long wave: it rises and falls with the water
    /// and does not tilt.
    const STATIC: Self = Self {
        heave_m_per_m: Complex::new(1.0, 0.0),
        roll_rad_per_m: Complex::new(0.0, 0.0),
        pitch_rad_per_m: Complex::new(0.0, 0.0),
    };

    fn map(self, f: impl Fn(Complex<f64>) -> Complex<f64>) -> Self {
        Self {
            heave_m_per_m: f(self.heave_m_per_m),
            roll_rad_per_m: f(self.roll_rad_per_m),
            pitch_rad_per_m: f(self.pitch_rad_per_m),
        }
    }

    /// `self (1 - u) + other u`.
    fn lerp(self, other: Self, u: f64) -> Self {
        let mix = |a: Complex<f64>, b: Complex<f64>| a * (1.0 - u) + b * u;
        Self {
            heave_m_per_m: mix(self.heave_m_per_m, other.heave_m_per_m),
            roll_rad_per_m: mix(self.roll_rad_per_m, other.roll_rad_per_m),
            pitch_rad_per_m: mix(self.pitch_rad_per_m, other.pitch_rad_per_m),
        }
    }
}

/// A table of responses on a grid of wave frequencies (rad/s, increasing) and headings (deg
/// off the bow, 0 head seas to 180 following, waves from port), for a hull symmetric about its
/// centre plane.
#[derive(Debug, Clone, PartialEq)]
pub struct RaoTable {
    omegas_rad_s: Vec<f64>,
    headings_deg: Vec<f64>,
    /// `[omega index * headings + heading index]`.
    responses: Vec<Responses>,
}

impl RaoTable {
    /// The frigate's table (`sim/data/frigate_rao.csv`), parsed once.
    pub fn frigate() -> Result<&'static Self, RaoTableError> {
        static TABLE: OnceLock<Result<RaoTable, RaoTableError>> = OnceLock::new();
        TABLE
            .get_or_init(|| Self::parse(FRIGATE_TABLE))
            .as_ref()
            .map_err(Clone::clone)
    }

    /// A table from its CSV text (`bench/hull_rao.py`'s format): lines starting with `#` are
    /// comments; after the header, one row per frequency and heading, frequency-major, the same
    /// headings for every frequency, from 0 to 180 deg.
    pub fn parse(text: &str) -> Result<Self, RaoTableError> {
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let (line, header) = lines.next().ok_or(RaoTableError::NoHeader)?;
        if header != HEADER {
            return Err(RaoTableError::Header {
                line,
                found: header.to_string(),
            });
        }
        let mut rows: Vec<(f64, f64, Responses)> = Vec::new();
        for (line, text) in lines {
            let fields: Vec<&str> = text.split(',').map(str::trim).collect();
            if fields.len() != 8 {
                return Err(RaoTableError::Columns {
                    line,
                    count: fields.len(),
                });
            }
            let mut values = [0.0; 8];
            for (column, (value, field)) in values.iter_mut().zip(&fields).enumerate() {
                *value = field
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| RaoTableError::NotANumber {
                        line,
                        column: column + 1,
                        text: field.to_string(),
                    })?;
            }
            let [omega, heading, heave, heave_phase, roll, roll_phase, pitch, pitch_phase] = values;
            if !(omega > 0.0) {
                return Err(RaoTableError::Row {
                    line,
                    what: "the frequency must be positive",
                });
            }
            if !(0.0..=180.0).contains(&heading) {
                return Err(RaoTableError::Row {
                    line,
                    what: "the heading must be within 0-180 deg",
                });
            }
            if heave < 0.0 || roll < 0.0 || pitch < 0.0 {
                return Err(RaoTableError::Row {
                    line,
                    what: "an amplitude is negative",
                });
            }
            let polar =
                |amplitude: f64, phase_deg: f64| Complex::from_polar(amplitude, phase_deg.to_radians());
            rows.push((
                omega,
                heading,
                Responses {
                    heave_m_per_m: polar(heave, heave_phase),
                    roll_rad_per_m: polar(roll.to_radians(), roll_phase),
                    pitch_rad_per_m: polar(pitch.to_radians(), pitch_phase),
                },
            ));
        }
        Self::from_rows(rows)
    }

    /// Checks that the rows are a grid and keeps them.
    fn from_rows(rows: Vec<(f64, f64, Responses)>) -> Result<Self, RaoTableError> {
        let Some(&(first_omega, _, _)) = rows.first() else {
            return Err(RaoTableError::NotAGrid("no rows"));
        };
        let headings_deg: Vec<f64> = rows
            .iter()
            .take_while(|(omega, _, _)| *omega == first_omega)
            .map(|(_, heading, _)| *heading)
            .collect();
        let n = headings_deg.len();
        if n < 2 || headings_deg[0] != 0.0 || headings_deg[n - 1] != 180.0 {
            return Err(RaoTableError::NotAGrid(
                "each frequency's headings must run from 0 to 180 deg",
            ));
        }
        if headings_deg.windows(2).any(|h| h[1] <= h[0]) {
            return Err(RaoTableError::NotAGrid("the headings must increase"));
        }
        if !rows.len().is_multiple_of(n) || rows.len() < 2 * n {
            return Err(RaoTableError::NotAGrid(
                "every frequency must have the same headings, and there must be two frequencies or more",
            ));
        }
        let mut omegas_rad_s = Vec::with_capacity(rows.len() / n);
        for block in rows.chunks(n) {
            let omega = block[0].0;
            if block.iter().any(|(w, _, _)| *w != omega) {
                return Err(RaoTableError::NotAGrid(
                    "every frequency must have the same headings",
                ));
            }
            if block
                .iter()
                .zip(&headings_deg)
                .any(|((_, h, _), expected)| h != expected)
            {
                return Err(RaoTableError::NotAGrid(
                    "every frequency must have the same headings",
                ));
            }
            if omegas_rad_s.last().is_some_and(|&last| omega <= last) {
                return Err(RaoTableError::NotAGrid("the frequencies must increase"));
            }
            omegas_rad_s.push(omega);
        }
        Ok(Self {
            omegas_rad_s,
            headings_deg,
            responses: rows.into_iter().map(|(_, _, r)| r).collect(),
        })
    }

    /// The frequencies (rad/s) and headings (deg) of the grid.
    pub fn omegas_rad_s(&self) -> &[f64] {
        &self.omegas_rad_s
    }

    pub fn headings_deg(&self) -> &[f64] {
        &self.headings_deg
    }

    /// The grid's responses at frequency index `i` and heading index `j`.
    pub fn at_grid(&self, i: usize, j: usize) -> Responses {
        self.responses[i * self.headings_deg.len() + j]
    }

    /// The responses to a wave met at `omega_rad_s` from `heading_deg` off the bow (to port
    /// positive; any angle), bilinear in frequency and heading on the complex values. A
    /// negative frequency (a wave the ship overtakes) gives the conjugate, as a real system's
    /// response does. Waves from starboard roll the ship the other way (the hull is symmetric).
    /// Below the table's lowest frequency the heave goes linearly to the water's (1, in phase)
    /// at 0 and roll and pitch as the wave's slope, `omega^2`; above its highest they taper to
    /// nothing at [`TAPER_END`] times it.
    pub fn response(&self, omega_rad_s: f64, heading_deg: f64) -> Responses {
        let off_bow_deg = (heading_deg + 180.0).rem_euclid(360.0) - 180.0;
        let from_starboard = off_bow_deg < 0.0;
        let r = self.at(omega_rad_s.abs(), off_bow_deg.abs());
        let r = if from_starboard {
            Responses {
                roll_rad_per_m: -r.roll_rad_per_m,
                ..r
            }
        } else {
            r
        };
        if omega_rad_s < 0.0 {
            r.map(|c| c.conj())
        } else {
            r
        }
    }

    /// The response at `omega_rad_s` >= 0 and `heading_deg` within 0-180.
    fn at(&self, omega_rad_s: f64, heading_deg: f64) -> Responses {
        let omegas = &self.omegas_rad_s;
        let (lowest, highest) = (omegas[0], omegas[omegas.len() - 1]);
        let (j, v) = bracket(&self.headings_deg, heading_deg);
        let row = |i: usize| self.at_grid(i, j).lerp(self.at_grid(i, j + 1), v);
        if omega_rad_s < lowest {
            let u = omega_rad_s / lowest;
            let first = row(0);
            return Responses {
                heave_m_per_m: Responses::STATIC.heave_m_per_m * (1.0 - u) + first.heave_m_per_m * u,
                roll_rad_per_m: first.roll_rad_per_m * (u * u),
                pitch_rad_per_m: first.pitch_rad_per_m * (u * u),
            };
        }
        if omega_rad_s > highest {
            let end = TAPER_END * highest;
            let fade = ((end - omega_rad_s) / (end - highest)).max(0.0);
            return row(omegas.len() - 1).map(|c| c * fade);
        }
        let (i, u) = bracket(omegas, omega_rad_s);
        row(i).lerp(row(i + 1), u)
    }
}

/// The interval of `grid` (increasing, two points or more) that holds `x` (clamped to it):
/// its first index and where `x` falls in it (0-1).
fn bracket(grid: &[f64], x: f64) -> (usize, f64) {
    let i = grid.partition_point(|&g| g <= x).clamp(1, grid.len() - 1) - 1;
    let u = ((x - grid[i]) / (grid[i + 1] - grid[i])).clamp(0.0, 1.0);
    (i, u)
}

/// The hull-RAO sea's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HullRaoParams {
    /// The ship's speed through the water (kn): the waves are met at their encounter
    /// frequencies.
    pub speed_kn: f64,
    /// How far aft of the centre of gravity the pad is (m; the table's heave is G's).
    pub pad_aft_m: f64,
    /// How the ship keeps its course (the wander, the autopilot's yaw).
    pub course: CourseKeepingParams,
}

impl HullRaoParams {
    /// The frigate at 10 kn, the pad 40 m aft, the short-crested sea's course keeping.
    pub const FRIGATE: Self = Self {
        speed_kn: 10.0,
        pad_aft_m: Hull::FRIGATE.pad_aft_m,
        course: CourseKeepingParams::FRIGATE,
    };

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), ShipMotionError> {
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
        if !(self.pad_aft_m.is_finite() && self.pad_aft_m.abs() <= 0.5 * Hull::FRIGATE.length_m) {
            return bad(
                "pad_aft_m",
                self.pad_aft_m,
                "within half the frigate's length (60 m)",
            );
        }
        self.course.validate()
    }
}

/// One wave as the ship meets it: the elevation at G is `a cos(rate t + phase)`, and each
/// motion `Re(c exp(i (rate t + phase)))` with `c` its response times the amplitude, stored as
/// the coefficients of the phase's cosine and sine (`[c.re, -c.im]`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct MetWave {
    rate: f64,
    phase: f64,
    heave_m: [f64; 2],
    roll_rad: [f64; 2],
    pitch_rad: [f64; 2],
}

impl MetWave {
    fn new(rate: f64, phase: f64, amplitude_m: f64, r: Responses) -> Self {
        let coefficients = |c: Complex<f64>| [amplitude_m * c.re, -amplitude_m * c.im];
        Self {
            rate,
            phase,
            heave_m: coefficients(r.heave_m_per_m),
            roll_rad: coefficients(r.roll_rad_per_m),
            pitch_rad: coefficients(r.pitch_rad_per_m),
        }
    }
}

/// The spectrum sea's waves ([`SpectrumShipMotion`] of the same sea state, heading and seed:
/// their frequencies, amplitudes and phases; long-crested from the mean heading, without the
/// spectrum sea's wander) met by the frigate under way, each at its encounter frequency
/// `w + k U cos(heading)` ([`encounter_rad_s`]) and answered by the table's responses at that
/// frequency and heading: the zero-speed responses taken at the encounter frequency, the usual
/// first approximation for a ship under way (it leaves out the speed's change of the radiated
/// waves and of the flow about the hull). The yaw is the autopilot's and the course's wander
/// (`CourseKeeping`), and does not change the heading the waves are answered at. The heave is
/// the pad's: G's plus the pad's height in the deck's attitude, `pad_aft_m` aft.
#[derive(Debug, Clone, PartialEq)]
pub struct HullRaoMotion {
    waves: Vec<MetWave>,
    course: CourseKeeping,
    pad_aft_m: f64,
    pub tracking: TrackingError,
}

impl HullRaoMotion {
    pub fn new(spec: &SeaSpec, params: &HullRaoParams) -> Result<Self, ShipMotionError> {
        let (hs_m, _) = spec.validate()?;
        params.validate()?;
        let table = RaoTable::frigate()?;
        let sea = SpectrumShipMotion::sea_state_from(spec.sea_state, spec.seed, spec.heading_deg)
            .ok_or(ShipMotionError::NoSeaState(spec.sea_state))?;
        let speed_mps = knots_to_mps(params.speed_kn);
        let from_bow_rad = spec.heading_deg.to_radians();
        let waves = sea
            .encounters()
            .map(|w| {
                let rate = encounter_rad_s(w.wave_rad_s, speed_mps, from_bow_rad);
                let r = table.response(rate, spec.heading_deg);
                MetWave::new(rate, w.phase_rad, w.amplitude_m, r)
            })
            .collect();
        let course = params.course.build(hs_m, speed_mps, spec.duration_s, spec.seed);
        Ok(Self {
            waves,
            course,
            pad_aft_m: params.pad_aft_m,
            tracking: TrackingError::hover(5.0),
        })
    }

    /// Roll, pitch (rad) and G's heave (m) at `t_s`.
    fn motion(&self, t_s: f64) -> [f64; 3] {
        let mut m = [0.0; 3];
        for w in &self.waves {
            let (sin, cos) = (w.rate * t_s + w.phase).sin_cos();
            let at = |c: [f64; 2]| c[0] * cos + c[1] * sin;
            m[0] += at(w.roll_rad);
            m[1] += at(w.pitch_rad);
            m[2] += at(w.heave_m);
        }
        m
    }
}

impl MotionProfile for HullRaoMotion {
    fn sample(&self, t_s: f64) -> MotionSample {
        let [roll, pitch, heave_m] = self.motion(t_s);
        let attitude = Rpy::new(roll, pitch, self.course.yaw_deg(t_s).to_radians());
        // The pad, `pad_aft_m` aft of G, in the deck's attitude: a bow-down pitch raises it.
        let pad = attitude.to_matrix() * Vector3::new(-self.pad_aft_m, 0.0, 0.0);
        MotionSample {
            t_s,
            attitude,
            viewpoint: self.tracking.at(t_s),
            deck_heave_m: heave_m + pad.z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::sea_state_waves;
    use crate::ship::hull::wavenumber_rad_m;
    use std::f64::consts::{FRAC_PI_2, TAU};

    fn table() -> &'static RaoTable {
        RaoTable::frigate().unwrap()
    }

    #[test]
    fn the_frigates_table_is_the_scripts_grid() {
        let t = table();
        let omegas = t.omegas_rad_s();
        assert_eq!((omegas[0], omegas[omegas.len() - 1]), (0.2, 1.6));
        assert!(omegas.len() >= 25, "{}", omegas.len());
        let headings: Vec<f64> = (0..=12).map(|j| 15.0 * j as f64).collect();
        assert_eq!(t.headings_deg(), headings.as_slice());
        // Small enough to keep in the repository.
        assert!(FRIGATE_TABLE.len() < 40_000);
    }

    #[test]
    fn heave_tends_to_the_water_and_pitch_to_the_slope_at_long_waves() {
        let t = table();
        for (j, &heading_deg) in t.headings_deg().iter().enumerate() {
            let r = t.at_grid(0, j);
            // A 1.5 km wave lifts the ship with the water, in phase.
            assert!(
                (r.heave_m_per_m - Complex::new(1.0, 0.0)).norm() < 0.01,
                "{heading_deg}: {r:?}"
            );
            // Head and following seas pitch it by the wave's slope along the ship, k cos.
            let slope = wavenumber_rad_m(0.2) * heading_deg.to_radians().cos().abs();
            assert!((r.pitch_rad_per_m.norm() - slope).abs() < 0.02 * wavenumber_rad_m(0.2));
        }
        // Below the table the static limit is reached smoothly.
        let r = t.response(0.0, 60.0);
        assert_eq!(r, Responses::STATIC);
        let (below, at) = (t.response(0.2 - 1e-9, 60.0), t.response(0.2, 60.0));
        assert!((below.heave_m_per_m - at.heave_m_per_m).norm() < 1e-6);
        assert!((below.pitch_rad_per_m - at.pitch_rad_per_m).norm() < 1e-9);
    }

    #[test]
    fn the_roll_peaks_near_the_natural_period_in_beam_seas() {
        let t = table();
        let natural = Hull::FRIGATE.natural_roll_rad_s();
        let (mut peak_rad_s, mut peak) = (0.0, 0.0);
        for k in 0..=1400 {
            let w = 0.2 + 0.001 * k as f64;
            let roll = t.response(w, 90.0).roll_rad_per_m.norm();
            if roll > peak {
                (peak_rad_s, peak) = (w, roll);
            }
        }
        assert!(
            (peak_rad_s / natural - 1.0).abs() < 0.05,
            "{peak_rad_s} vs {natural}"
        );
        // A damping ratio of 0.1 lifts it about five times over the wave's slope there.
        let slope = wavenumber_rad_m(peak_rad_s);
        assert!(
            peak > 2.5 * slope && peak < 6.0 * slope,
            "{peak} vs slope {slope}"
        );
        // Long waves from port roll it with their slope, raising port as the water rises there:
        // a quarter period ahead of the crest at G. Less the resonance's lift, the share of the
        // slope is the effective slope coefficient: 0.97 here, the IMO code's 0.86 for this hull.
        let (w, natural) = (0.2, Hull::FRIGATE.natural_roll_rad_s());
        let long = t.response(w, 90.0).roll_rad_per_m;
        assert!((long.arg() - FRAC_PI_2).abs() < 0.15, "{}", long.arg());
        let share = long.norm() / wavenumber_rad_m(w) * (1.0 - (w / natural).powi(2));
        assert!((0.8..1.05).contains(&share), "{share}");
        // Nothing rolls it in head or following seas (the hull is symmetric).
        for w in [0.3, 0.62, 1.0] {
            assert!(t.response(w, 0.0).roll_rad_per_m.norm() < 1e-9);
            assert!(t.response(w, 180.0).roll_rad_per_m.norm() < 1e-9);
        }
    }

    #[test]
    fn responses_by_symmetry_and_beyond_the_table() {
        let t = table();
        let a = t.response(0.7, 60.0);
        assert_eq!(t.response(-0.7, 60.0), a.map(|c| c.conj()));
        assert_eq!(t.response(0.7, 60.0 + 360.0), a);
        let starboard = t.response(0.7, -60.0);
        assert_eq!(starboard.roll_rad_per_m, -a.roll_rad_per_m);
        assert_eq!(starboard.pitch_rad_per_m, a.pitch_rad_per_m);
        assert_eq!(starboard.heave_m_per_m, a.heave_m_per_m);
        // Between the grid's rows and columns it interpolates; on them it is the row.
        assert_eq!(t.response(t.omegas_rad_s()[3], 45.0), t.at_grid(3, 3));
        let mid = t.response(0.5 * (t.omegas_rad_s()[3] + t.omegas_rad_s()[4]), 45.0);
        let expected = t.at_grid(3, 3).lerp(t.at_grid(4, 3), 0.5);
        assert!((mid.roll_rad_per_m - expected.roll_rad_per_m).norm() < 1e-12);
        // Past the highest frequency the responses taper to nothing.
        let (at, past) = (t.response(1.6, 90.0), t.response(1.6 + 1e-9, 90.0));
        assert!((at.heave_m_per_m - past.heave_m_per_m).norm() < 1e-6);
        assert!(t.response(2.0, 90.0).heave_m_per_m.norm() < 1e-12);
        assert_eq!(t.response(5.0, 90.0).roll_rad_per_m, Complex::new(0.0, 0.0));
    }

    #[test]
    fn bad_tables_are_refused_with_their_line() {
        let good = format!("# comment\n{HEADER}\n0.5,0,1,0,0,0,1,-90\n0.5,180,1,0,0,0,1,90\n1,0,0.5,0,0,0,1,-90\n1,180,0.5,0,0,0,1,90\n");
        let table = RaoTable::parse(&good).unwrap();
        assert_eq!(table.omegas_rad_s(), &[0.5, 1.0]);
        let bad = |text: &str| RaoTable::parse(text).unwrap_err();
        assert_eq!(bad("# only a comment\n"), RaoTableError::NoHeader);
        assert!(matches!(
            bad("omega,heading\n"),
            RaoTableError::Header { line: 1, .. }
        ));
        let swap = |from: &str, to: &str| good.replacen(from, to, 1);
        assert_eq!(
            bad(&swap("0.5,180,1,0", "0.5,180,x,0")),
            RaoTableError::NotANumber {
                line: 4,
                column: 3,
                text: "x".into()
            }
        );
        assert_eq!(
            bad(&swap("1,180,0.5,0,0,0,1,90", "1,180,0.5,0,0,0,1")),
            RaoTableError::Columns { line: 6, count: 7 }
        );
        assert!(matches!(
            bad(&swap("0.5,180,1,", "0.5,180,-1,")),
            RaoTableError::Row { line: 4, .. }
        ));
        assert!(matches!(
            bad(&swap("1,180,", "1,190,")),
            RaoTableError::Row { line: 6, .. }
        ));
        assert!(matches!(
            bad(&swap("1,180,", "1,90,")),
            RaoTableError::NotAGrid(_)
        ));
        assert!(matches!(
            bad(&swap("1,0,", "0.4,0,").replacen("1,180,", "0.4,180,", 1)),
            RaoTableError::NotAGrid(_)
        ));
        assert!(matches!(
            bad(&format!("{HEADER}\n0.5,0,1,0,0,0,1,-90\n0.5,180,1,0,0,0,1,90\n")),
            RaoTableError::NotAGrid(_)
        ));
        assert!(matches!(
            bad(&swap("0.5,0,1,0,0,0,1,-90", "0.5,0,1,0,0,0,1,nan")),
            RaoTableError::NotANumber { .. }
        ));
    }

    #[test]
    fn one_wave_moves_the_deck_as_the_table_says_with_deckwatchs_signs() {
        // A long wave from port at rest: the deck rolls with the water's slope across it
        // (positive roll raises port, where the water rises), heaves with the elevation.
        let (w, amplitude_m, phase) = (0.3, 1.0, 0.4);
        let r = table().response(w, 90.0);
        let sea = HullRaoMotion {
            waves: vec![MetWave::new(w, phase, amplitude_m, r)],
            course: CourseKeeping::new(0.0, 120.0, 0.0, 25.0, 0.0, 100.0, 1),
            pad_aft_m: 0.0,
            tracking: TrackingError::hover(5.0),
        };
        let k = wavenumber_rad_m(w);
        let (mut roll_slope, mut slope2, mut heave_elevation, mut elevation2) = (0.0, 0.0, 0.0, 0.0);
        for i in 0..2000 {
            let t_s = i as f64 * TAU / w / 1000.0;
            let s = sea.sample(t_s);
            // Waves from port run to starboard: the elevation at y is a cos(w t + phase + k y).
            let elevation = amplitude_m * (w * t_s + phase).cos();
            let slope_to_port = -amplitude_m * k * (w * t_s + phase).sin();
            roll_slope += s.attitude.roll * slope_to_port;
            slope2 += slope_to_port * slope_to_port;
            heave_elevation += s.deck_heave_m * elevation;
            elevation2 += elevation * elevation;
        }
        assert!(roll_slope / slope2 > 0.8, "{}", roll_slope / slope2);
        assert!((heave_elevation / elevation2 - 1.0).abs() < 0.02);
        // Exactly the table's response: Re(r a exp(i (w t + phase))).
        let expected = (r.roll_rad_per_m * Complex::from_polar(amplitude_m, w * 1.0 + phase)).re;
        assert!((sea.sample(1.0).attitude.roll - expected).abs() < 1e-12);
    }

    fn spec(sea_state: u32, heading_deg: f64, seed: u64) -> SeaSpec {
        SeaSpec {
            sea_state,
            heading_deg,
            seed,
            duration_s: 3600.0,
        }
    }

    /// Standard deviations of roll and pitch (deg) and of the pad's heave (m) over an hour.
    fn deviations(sea: &HullRaoMotion) -> [f64; 3] {
        let n = 14_400;
        let mut sums = [0.0; 3];
        for k in 0..n {
            let s = sea.sample(k as f64 * 0.25);
            let [roll, pitch, _] = s.attitude.to_degrees();
            for (sum, v) in sums.iter_mut().zip([roll, pitch, s.deck_heave_m]) {
                *sum += v * v;
            }
        }
        sums.map(|s| (s / n as f64).sqrt())
    }

    #[test]
    fn the_sea_is_a_sea_states_and_the_headings_trade_roll_for_pitch() {
        let params = HullRaoParams::FRIGATE;
        let sea = |ss, heading| HullRaoMotion::new(&spec(ss, heading, 3), &params).unwrap();
        let (hs, _) = sea_state_waves(6).unwrap();
        let [head_roll, head_pitch, head_heave] = deviations(&sea(6, 0.0));
        let [beam_roll, beam_pitch, beam_heave] = deviations(&sea(6, 90.0));
        // Frigates roll 20-30 deg at most in sea state 6 on the beam (sd 5-10), pitch 2-4 deg
        // (sd about 1-1.5) head on; the pad heaves a metre or two.
        assert!((4.0..12.0).contains(&beam_roll), "beam roll {beam_roll}");
        assert!((0.7..3.0).contains(&head_pitch), "head pitch {head_pitch}");
        assert!(beam_roll > 5.0 * head_roll && head_pitch > 3.0 * beam_pitch);
        for heave in [head_heave, beam_heave] {
            assert!(4.0 * heave > 0.3 * hs && 4.0 * heave < 1.5 * hs, "{heave}");
        }
        // The pad 40 m aft heaves more than G in head seas.
        let at_g = HullRaoMotion::new(
            &spec(6, 0.0, 3),
            &HullRaoParams {
                pad_aft_m: 0.0,
                ..params
            },
        )
        .unwrap();
        assert!(head_heave > 1.1 * deviations(&at_g)[2], "{head_heave}");
        // A calm sea state 3 barely moves it.
        let [roll, pitch, heave] = deviations(&sea(3, 90.0));
        assert!(roll < 2.0 && pitch < 0.5 && heave < 0.3, "{roll} {pitch} {heave}");
    }

    #[test]
    fn bad_parameters_are_refused() {
        for params in [
            HullRaoParams {
                speed_kn: -1.0,
                ..HullRaoParams::FRIGATE
            },
            HullRaoParams {
                pad_aft_m: f64::NAN,
                ..HullRaoParams::FRIGATE
            },
            HullRaoParams {
                course: CourseKeepingParams {
                    wander_time_s: 0.0,
                    ..CourseKeepingParams::FRIGATE
                },
                ..HullRaoParams::FRIGATE
            },
        ] {
            assert!(HullRaoMotion::new(&spec(5, 0.0, 1), &params).is_err());
        }
    }
}
