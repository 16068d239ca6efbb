//! Forecasters of the deck's motion: what the decider fits on the recent history of each channel
//! (roll, pitch, the deck's height) and judges the coming touchdown by.
//!
//! A forecaster is two traits: [`Forecaster`] fits the channels' samples and returns a
//! [`ChannelForecast`] for each, which gives the value, the rate and the standard deviation it states for
//! each, at any time after the newest sample. The decider calibrates the stated deviations by the
//! forecast's own held-out misses (`decision::band`), so a forecaster states what it believes and
//! the decider measures how far to trust it. Adding one: ARCHITECTURE.md, "Adding a forecaster".

pub mod ar;
mod ar_numerics;
pub mod joint;

pub use ar::{ArForecaster, ArModel};
pub use ar_numerics::normal_equations;
pub use joint::{ArChannel, JointAr};

/// One channel's fitted forecast: the value and rate it predicts at any time from its newest
/// sample on, and the standard deviation of each that it states.
pub trait ChannelForecast: Clone + std::fmt::Debug {
    /// The newest sample's time (s): where the forecast starts.
    fn t0(&self) -> f64;
    /// The predicted value at `t` (the channel's unit: deg or m).
    fn value(&self, t: f64) -> f64;
    /// The predicted rate at `t` (deg/s or m/s).
    fn rate(&self, t: f64) -> f64;
    /// The stated standard deviation of [`Self::value`]'s error at `t`. It must be positive at
    /// [`Self::t0`] (the newest value's own uncertainty, say one innovation): a forecast that
    /// states 0 there is taken to state none, is never calibrated (the band's misses are counted
    /// in stated deviations) and never cleared on.
    fn std(&self, t: f64) -> f64;
    /// The stated standard deviation of [`Self::rate`]'s error at `t`.
    fn rate_std(&self, t: f64) -> f64;
    /// The same model run forward from the newest samples `t` (increasing times, s) and `y`
    /// (every channel's values at them, in the order they were fitted; a forecast reads its own
    /// channel's, and a joint one the others' too): the forecast then starts from the deck as
    /// just measured. None when it cannot be (the decider keeps the model as it was).
    fn advanced(&self, t: &[f64], y: &[&[f64]]) -> Option<Self>;
}

/// Fits the channels' forecasts on their samples.
pub trait Forecaster: Clone + std::fmt::Debug {
    type Channel: ChannelForecast;
    /// Fits on samples `t` (increasing, s; thinned to the decider's fit spacing) and `y` (each
    /// channel's values at them), forecasting at least `horizon_s` past the newest sample: one
    /// forecast per channel, in order; None when the samples cannot be fitted.
    fn fit(&self, t: &[f64], y: &[&[f64]], horizon_s: f64) -> Option<Vec<Self::Channel>>;
    /// How much of the newest history [`ChannelForecast::advanced`] needs (s).
    fn state_span_s(&self) -> f64;
    /// Every channel's forecast run forward from the newest samples (as
    /// [`ChannelForecast::advanced`], a forecast that cannot be keeping what it was); a
    /// forecaster whose channels share a recursion runs it once here.
    fn advance_all(&self, forecasts: &mut [Self::Channel], t: &[f64], y: &[&[f64]]) {
        for forecast in forecasts.iter_mut() {
            if let Some(next) = forecast.advanced(t, y) {
                *forecast = next;
            }
        }
    }
}
