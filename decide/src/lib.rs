//! Landing decision. So far: the quadrotor's landing capacity and the naive baseline rule
//! ("current angles within the limits") that the real decision (a state machine with deck-motion
//! prediction and fail-safes, in its own issue) is measured against. The naive rule looks at one
//! instant only; it is not a landing clearance.

pub mod decision;
pub mod eval;
pub mod predict;
pub mod stage;

use deckwatch_common::Rpy;

/// What the quadrotor can land on: deck tilt limits at touchdown.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandingCapacity {
    pub max_abs_roll_deg: f64,
    pub max_abs_pitch_deg: f64,
}

impl LandingCapacity {
    /// Checks the limits; the error names the field.
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [
            ("max_abs_roll_deg", self.max_abs_roll_deg),
            ("max_abs_pitch_deg", self.max_abs_pitch_deg),
        ] {
            if !(v.is_finite() && v > 0.0 && v < 90.0) {
                return Err(format!("field `{name}`: must be within (0, 90) degrees, got {v}"));
            }
        }
        Ok(())
    }

    /// The naive baseline: the deck's current roll and pitch are within the limits.
    /// Non-finite angles are never within.
    pub fn naive_within(&self, attitude: &Rpy) -> bool {
        let [roll, pitch, _] = attitude.to_degrees();
        roll.abs() <= self.max_abs_roll_deg && pitch.abs() <= self.max_abs_pitch_deg
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn naive_rule() {
        let c = LandingCapacity {
            max_abs_roll_deg: 5.0,
            max_abs_pitch_deg: 3.0,
        };
        c.validate().unwrap();
        assert!(c.naive_within(&Rpy::from_degrees(-4.9, 2.9, 170.0)));
        assert!(!c.naive_within(&Rpy::from_degrees(5.1, 0.0, 0.0)));
        assert!(!c.naive_within(&Rpy::from_degrees(0.0, -3.1, 0.0)));
        assert!(!c.naive_within(&Rpy::from_degrees(f64::NAN, 0.0, 0.0)));
        let bad = LandingCapacity {
            max_abs_roll_deg: -1.0,
            ..c
        };
        assert!(bad.validate().unwrap_err().contains("`max_abs_roll_deg`"));
    }
}
