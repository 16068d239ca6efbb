//! The pipeline's stages: capture (the source), then detect, estimate and decide, each a
//! [`crate::stage::Stage`] around its algorithm crate.

pub mod capture;
pub mod decide;
pub mod detect;
pub mod estimate;
pub mod link;
pub mod record;

pub use decide::DecideStage;
pub use detect::DetectStage;
pub use estimate::EstimateStage;
