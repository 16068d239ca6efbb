//! Deck attitude estimators: pure algorithms, no IPC and no logging; the runtime's estimate
//! stage wires them to the pipeline.
//!
//! - [`deck_estimator`]: [`DeckEstimator`], the estimation pipeline of one camera around the
//!   estimators (vehicle attitude, heading, deck height, rolling shutter, frozen images).
//! - [`paper`]: the paper's ellipse method with the corrections of CONVENTIONS.md.
//! - [`ellipse`]: the eq. (3) conic fit both use.
//! - [`vehicle_height`]: the vehicle's height from the autopilot's height and vertical speed.

pub mod circle_grid;
pub mod config;
pub mod deck_estimator;
pub mod ellipse;
pub mod motion;
pub mod paper;
pub mod pattern_check;
pub mod pose;
pub mod vehicle_height;
pub mod vehicle_track;

pub use config::EstimateConfig;
pub use deck_estimator::DeckEstimator;
pub use ellipse::{Ellipse, EllipseFit, EllipseFitError};
pub use motion::DeckMotionHistory;
pub use paper::{NotEstimable, PaperEstimate, PaperEstimator, PaperVariant};
pub use pose::{FrameMotion, PoseConfig, PoseError, PoseEstimate, PoseEstimator};
pub use vehicle_height::{HeightFusion, HEIGHT_FUSION_TIME_CONSTANT_S};
pub use vehicle_track::{MeanHeading, TrackAttitude, TrackMiss, VehicleTrack};
