//! Landing decision: a state machine over the deck-attitude stream with deck-motion prediction
//! ([`decision`]), the forecasters it uses ([`forecast`]) and the evaluation harnesses that
//! measure it against the truth and the naive rule ([`eval`], [`forecast_eval`]). Pure
//! algorithm: no clock, no IPC, no logging; the runtime's decide stage drives it.

pub mod decision;
pub mod eval;
pub mod forecast;
pub mod forecast_eval;
pub mod frame;

pub use decision::{
    ArForecastConfig, Decision, DecisionConfig, DeckForecast, DeckObservation, ForecastConfig, HeaveUse,
    LandingDecider,
};
pub use frame::FrameInput;
