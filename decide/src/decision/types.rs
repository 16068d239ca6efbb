//! What goes into the decider (a deck observation) and what comes out (a decision, a forecast).

use deckwatch_common::messages::{DecisionReason, DecisionState};

/// What the decider sees of one frame: the deck's roll and pitch in W and the deck centre's
/// height in W (the heave; NaN when not measured).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeckObservation {
    pub roll_deg: f64,
    pub pitch_deg: f64,
    pub height_m: f64,
}

impl DeckObservation {
    pub fn new(roll_deg: f64, pitch_deg: f64, height_m: f64) -> Self {
        Self {
            roll_deg,
            pitch_deg,
            height_m,
        }
    }

    /// Roll and pitch, no height.
    pub fn angles(roll_deg: f64, pitch_deg: f64) -> Self {
        Self::new(roll_deg, pitch_deg, f64::NAN)
    }
}

/// A forecast of the deck at one instant ([`super::LandingDecider::forecast`]): roll, pitch (deg) and
/// the deck height (m), their rates, and the half-widths of the stated 95 % bands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeckForecast {
    pub value: [f64; 3],
    pub rate: [f64; 3],
    pub band95: [f64; 3],
    pub rate_band95: [f64; 3],
}

/// The two-sided 95 % quantile of the standard normal.
pub(crate) const Z95: f64 = 1.959_963_984_540_054;

/// One decision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decision {
    pub state: DecisionState,
    pub reason: DecisionReason,
    /// The next predicted calm window (start relative to `now`, length; s), if any.
    pub calm_window: Option<(f64, f64)>,
    /// This decision starts a new commitment (a new touchdown window begins now).
    pub new_commit: bool,
    /// The deck's vertical speed now by the heave model (m/s, up), trusted or not; NaN without
    /// one.
    pub heave_rate_mps: f64,
}
