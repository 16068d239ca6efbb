//! Frame sources of deckwatch. So far the simulator of the paper's scene: motion profiles (deck
//! attitude and camera position over time), named scenarios, the image renderer and frame
//! simulator, marker-level simulation (exact marker pixels) and a deterministic random
//! generator. Replay and libcamera sources come with their issues.

pub mod motion;
pub mod render;
pub mod rng;
pub mod scenario;
pub mod sim;

pub use motion::{Case1Sweep, MotionProfile, MotionSample, ShipMotion, TrackingError};
pub use render::{RenderOptions, Renderer};
pub use scenario::{MarkerSimulator, Scenario};
pub use sim::{FrameSimulator, FrameTruth};
