//! Landing decision: a state machine over the deck-attitude stream with deck-motion prediction
//! ([`decision`]), the predictors it uses ([`predict`]) and the evaluation harness that measures
//! it against the truth and the naive rule ([`eval`]). Pure algorithm: no clock, no IPC, no
//! logging; the runtime's decide stage drives it.

pub mod decision;
pub mod eval;
pub mod forecast_eval;
pub mod frame;
pub mod predict;

pub use decision::{
    Decision, DecisionConfig, DeckForecast, DeckObservation, HeaveUse, LandingDecider, Predictor,
};
pub use frame::FrameInput;
