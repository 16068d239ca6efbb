//! Landing decision: a state machine over the deck-attitude stream with deck-motion prediction
//! ([`decision`]), the predictors it uses ([`predict`]) and the evaluation harness that measures
//! it against the truth and the naive rule ([`eval`]). Pure algorithm: no clock, no IPC, no
//! logging; the runtime's decide stage drives it.

pub mod decision;
pub mod eval;
pub mod predict;

pub use decision::{
    Decision, DecisionConfig, DecisionConfigError, DeckObservation, HeaveUse, LandingDecider, Predictor,
};
