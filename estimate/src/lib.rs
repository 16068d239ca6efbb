//! Deck attitude estimators: pure algorithms, no IPC and no logging; the runtime's estimate
//! stage wires them to the pipeline.
//!
//! - [`paper`]: the paper's ellipse method with the corrections of NOTES.md.
//! - [`ellipse`]: the eq. (3) conic fit both use.

pub mod config;
pub mod ellipse;
pub mod motion;
pub mod paper;
pub mod pose;

pub use config::EstimateConfig;
pub use ellipse::{Ellipse, EllipseFit, EllipseFitError};
pub use motion::DeckMotionHistory;
pub use paper::{NotEstimable, PaperEstimate, PaperEstimator, PaperVariant};
pub use pose::{FrameMotion, PoseConfig, PoseError, PoseEstimate, PoseEstimator};
