//! [`LandingDecider`]: the decision with the forecaster its configuration names, what the decide
//! stage, the evaluations and the trials run.

use super::history::FIT_SPACING_S;
use super::{Decider, Decision, DecisionConfig, DeckForecast, DeckObservation, ForecastConfig};
use crate::forecast::ArForecaster;
use crate::frame::FrameInput;
use deckwatch_common::messages::{DecisionReason, DecisionState};

/// The decision state machine with the configured forecaster (`[decide.forecast]`). Its methods
/// are [`Decider`]'s, instantiated here, in the decide crate, which a debug build optimises
/// (Cargo.toml: a refit at opt-level 1 took four times as long): a generic decider would be
/// compiled into each crate that calls it, at that crate's opt-level.
pub struct LandingDecider(Decider<ArForecaster>);

impl LandingDecider {
    /// The decider with the forecaster its configuration names.
    pub fn new(config: DecisionConfig) -> Result<Self, deckwatch_common::InvalidField> {
        config.validate()?;
        let ForecastConfig::Ar(ar) = &config.forecast;
        let forecaster = ArForecaster {
            order: ar.order,
            cross_order: ar.cross_order,
            grid_step_s: FIT_SPACING_S,
            max_bridge_s: config.max_gap_ms / 1e3,
        };
        Decider::with_forecaster(config, forecaster).map(Self)
    }

    pub fn config(&self) -> &DecisionConfig {
        self.0.config()
    }

    pub fn state(&self) -> DecisionState {
        self.0.state()
    }

    /// [`Decider::update`].
    pub fn update(&mut self, t: f64, deck: Option<DeckObservation>, now: f64) -> Decision {
        self.0.update(t, deck, now)
    }

    /// [`Decider::update_at_capture`].
    pub fn update_at_capture(&mut self, t: f64, deck: Option<DeckObservation>, age_s: f64) -> Decision {
        self.0.update_at_capture(t, deck, age_s)
    }

    /// [`Decider::refuse`].
    pub fn refuse(&mut self, now: f64, reason: DecisionReason) -> Decision {
        self.0.refuse(now, reason)
    }

    /// [`Decider::decide_frame`].
    pub fn decide_frame(&mut self, frame: &FrameInput) -> Decision {
        self.0.decide_frame(frame)
    }

    /// [`Decider::refit_between_frames`].
    pub fn refit_between_frames(&mut self) -> bool {
        self.0.refit_between_frames()
    }

    /// [`Decider::refit_ahead`].
    pub fn refit_ahead(&mut self, lead_s: f64) {
        self.0.refit_ahead(lead_s)
    }

    /// [`Decider::refit_due`].
    pub fn refit_due(&self, lead_s: f64) -> Option<f64> {
        self.0.refit_due(lead_s)
    }

    /// [`Decider::forecast`].
    pub fn forecast(&self, t: f64) -> Option<DeckForecast> {
        self.0.forecast(t)
    }

    /// [`Decider::frame_interval_s`].
    pub fn frame_interval_s(&self) -> Option<f64> {
        self.0.frame_interval_s()
    }

    /// [`Decider::timeout`].
    pub fn timeout(&mut self, now: f64) -> Option<Decision> {
        self.0.timeout(now)
    }

    /// [`Decider::watchdog_period_s`].
    pub fn watchdog_period_s(&self) -> f64 {
        self.0.watchdog_period_s()
    }
}

/// The parts, for the decision's own tests.
#[cfg(test)]
impl std::ops::Deref for LandingDecider {
    type Target = Decider<ArForecaster>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

#[cfg(test)]
impl std::ops::DerefMut for LandingDecider {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.0
    }
}
