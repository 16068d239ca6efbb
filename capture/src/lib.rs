//! Frame sources of deckwatch. So far: the simulator's motion profiles (deck attitude and camera
//! position over time), named scenarios, marker-level simulation (exact marker pixels) and a
//! deterministic random generator; the image renderer, replay and libcamera sources come with
//! their issues.

pub mod motion;
pub mod rng;
pub mod scenario;

pub use motion::{Case1Sweep, MotionProfile, MotionSample, ShipMotion, TrackingError};
pub use scenario::{MarkerSimulator, Scenario};
