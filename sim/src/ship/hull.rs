//! The ship the motion models move, and the responses they share.

use nalgebra::Complex;

/// Gravity (m/s^2).
pub const GRAVITY_MPS2: f64 = 9.81;

/// A frigate or large patrol vessel of about 4000 t (120 m long, 14 m beam, 4.5 m draft), the
/// size of ship a quadrotor lands on at sea. Its roll follows the IMO's stability code, the
/// only public formula that ties a hull's dimensions to its roll period and wave moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hull {
    /// Waterline length (m).
    pub length_m: f64,
    /// Beam (m).
    pub beam_m: f64,
    /// Draft (m).
    pub draft_m: f64,
    /// Metacentric height GM (m): the small-angle righting arm per radian. Warships carry
    /// 1-1.5 m (more would make them roll stiffly; less, tender).
    pub gm_m: f64,
    /// Height of the centre of gravity above the waterline, OG (m; negative below it).
    pub og_m: f64,
    /// How far aft of the centre of gravity the landing pad's centre is (m): a frigate's flight
    /// deck is at the stern, about a third of the length aft.
    pub pad_aft_m: f64,
}

impl Hull {
    /// The frigate the models use by default.
    pub const FRIGATE: Self = Self {
        length_m: 120.0,
        beam_m: 14.0,
        draft_m: 4.5,
        gm_m: 1.2,
        og_m: 1.0,
        pad_aft_m: 40.0,
    };

    /// The roll's radius of gyration with the water's added inertia (m): `C B`, with the IMO
    /// 2008 Intact Stability Code's (Part A 2.3.4, the weather criterion) roll-period
    /// coefficient `C = 0.373 + 0.023 B/d - 0.043 L/100` (0.39 for the frigate: 5.5 m).
    pub fn roll_gyradius_m(&self) -> f64 {
        let c = 0.373 + 0.023 * self.beam_m / self.draft_m - 0.043 * self.length_m / 100.0;
        c * self.beam_m
    }

    /// The natural roll frequency (rad/s): `sqrt(g GM) / k`, the code's `T = 2 C B / sqrt(GM)`
    /// (10.0 s for the frigate; frigates roll at 8-12 s).
    pub fn natural_roll_rad_s(&self) -> f64 {
        (GRAVITY_MPS2 * self.gm_m).sqrt() / self.roll_gyradius_m()
    }

    /// The share of a long wave's slope that rolls the ship: the IMO code's effective wave slope
    /// coefficient `r = 0.73 + 0.6 OG/d` (0.86 for the frigate), kept within 0.5-1.
    pub fn effective_slope_coefficient(&self) -> f64 {
        (0.73 + 0.6 * self.og_m / self.draft_m).clamp(0.5, 1.0)
    }

    /// The share of a wave of wavenumber `k_rad_m` (rad/m) whose slope reaches the hull: its
    /// pressure decays as `exp(-k z)`, taken at half the draft (the Smith effect); short waves
    /// roll the ship less than their slope says.
    pub fn depth_attenuation(&self, k_rad_m: f64) -> f64 {
        (-k_rad_m * 0.5 * self.draft_m).exp()
    }

    /// Roll (rad) per radian of a wave's slope across the ship, at wavenumber `k_rad_m`:
    /// [`Self::effective_slope_coefficient`] x [`Self::depth_attenuation`].
    pub fn roll_slope_share(&self, k_rad_m: f64) -> f64 {
        self.effective_slope_coefficient() * self.depth_attenuation(k_rad_m)
    }

    /// Checks that every dimension is a positive length and the pad is on the ship.
    pub fn validate(&self) -> Result<(), super::ShipMotionError> {
        use super::ShipMotionError::BadParameter;
        for (name, value) in [
            ("hull length_m", self.length_m),
            ("hull beam_m", self.beam_m),
            ("hull draft_m", self.draft_m),
            ("hull gm_m", self.gm_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(BadParameter {
                    name,
                    value,
                    expected: "a positive length (m)",
                });
            }
        }
        if !(self.og_m.is_finite() && self.og_m.abs() < self.length_m) {
            return Err(BadParameter {
                name: "hull og_m",
                value: self.og_m,
                expected: "a finite height within the ship (m)",
            });
        }
        if !(self.pad_aft_m.is_finite() && self.pad_aft_m.abs() <= 0.5 * self.length_m) {
            return Err(BadParameter {
                name: "hull pad_aft_m",
                value: self.pad_aft_m,
                expected: "a distance within half the ship's length (m)",
            });
        }
        // The code's coefficient is positive for any ship-like proportions, not for all numbers.
        if !(self.roll_gyradius_m() > 0.0) {
            return Err(BadParameter {
                name: "hull length_m",
                value: self.length_m,
                expected: "ship-like proportions (the IMO roll-period coefficient is not positive)",
            });
        }
        Ok(())
    }
}

/// A damped resonance at `natural_rad_s` with damping ratio `zeta`, unit gain at rest:
/// `w0^2 / (w0^2 - w^2 + 2 i zeta w0 w)` at `w_rad_s` (negative frequencies give the conjugate,
/// as a real system's response does).
pub fn resonance(w_rad_s: f64, natural_rad_s: f64, zeta: f64) -> Complex<f64> {
    let w0 = natural_rad_s;
    let denominator = Complex::new(w0 * w0 - w_rad_s * w_rad_s, 2.0 * zeta * w0 * w_rad_s);
    Complex::new(w0 * w0, 0.0) / denominator
}

/// A second-order Butterworth low-pass at `corner_rad_s`: `1 / (1 - u^2 + i sqrt(2) u)`,
/// `u = w / corner`. Its gain `1 / sqrt(1 + u^4)` is the spectrum sea's pitch and heave filter
/// (`motion::SpectrumShipMotion`); this one has its phase lag too.
pub fn low_pass(w_rad_s: f64, corner_rad_s: f64) -> Complex<f64> {
    let u = w_rad_s / corner_rad_s;
    Complex::new(1.0, 0.0) / Complex::new(1.0 - u * u, std::f64::consts::SQRT_2 * u)
}

/// A wave's wavenumber (rad/m) in deep water: `w^2 / g`.
pub fn wavenumber_rad_m(w_rad_s: f64) -> f64 {
    w_rad_s * w_rad_s / GRAVITY_MPS2
}

/// The angular frequency (rad/s) at which a ship at `speed_mps` meets a wave of `w_rad_s`
/// coming from `from_bow_rad` off its bow (0: head seas, pi: following seas): `w + k U cos`,
/// the textbook `w - w^2 U cos(beta) / g` with `beta = pi - from_bow` the angle between the
/// ship's course and the wave's direction of travel (180 deg head seas). Negative in following
/// seas that overtake the ship more slowly than it sails (the ship overtakes the waves).
pub fn encounter_rad_s(w_rad_s: f64, speed_mps: f64, from_bow_rad: f64) -> f64 {
    w_rad_s + wavenumber_rad_m(w_rad_s) * speed_mps * from_bow_rad.cos()
}

/// Knots to m/s.
pub fn knots_to_mps(knots: f64) -> f64 {
    knots * 1852.0 / 3600.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frigate_rolls_at_about_ten_seconds() {
        let hull = Hull::FRIGATE;
        hull.validate().unwrap();
        let period_s = std::f64::consts::TAU / hull.natural_roll_rad_s();
        assert!((9.5..10.5).contains(&period_s), "{period_s}");
        assert!((5.0..6.0).contains(&hull.roll_gyradius_m()));
        assert!((hull.effective_slope_coefficient() - 0.8633).abs() < 1e-3);
        let bad = Hull { gm_m: 0.0, ..hull };
        assert!(bad.validate().is_err());
        let bad = Hull {
            pad_aft_m: f64::NAN,
            ..hull
        };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn responses_and_the_encounter_frequency() {
        let w0 = 0.6;
        assert!((resonance(0.0, w0, 0.1) - Complex::new(1.0, 0.0)).norm() < 1e-12);
        // At resonance the gain is 1 / (2 zeta), a quarter period late.
        let at = resonance(w0, w0, 0.1);
        assert!((at.norm() - 5.0).abs() < 1e-12 && (at.arg() + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(resonance(-0.4, w0, 0.1), resonance(0.4, w0, 0.1).conj());
        let lp = low_pass(1.3, 0.8);
        assert!((lp.norm() - 1.0 / (1.0 + (1.3f64 / 0.8).powi(4)).sqrt()).abs() < 1e-12);
        // 10 kn into a 10 s wave (k = 0.0402 rad/m): met 0.21 rad/s faster head on, as much
        // slower from astern, unchanged on the beam.
        let (w, u) = (std::f64::consts::TAU / 10.0, knots_to_mps(10.0));
        let shift = w * w / GRAVITY_MPS2 * u;
        assert!((shift - 0.2069).abs() < 1e-3, "{shift}");
        assert!((encounter_rad_s(w, u, 0.0) - (w + shift)).abs() < 1e-12);
        assert!((encounter_rad_s(w, u, std::f64::consts::PI) - (w - shift)).abs() < 1e-12);
        assert!((encounter_rad_s(w, u, std::f64::consts::FRAC_PI_2) - w).abs() < 1e-12);
        assert_eq!(encounter_rad_s(w, 0.0, 0.3), w);
    }
}
