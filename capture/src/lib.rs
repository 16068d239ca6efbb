//! Frame sources of deckwatch: the simulator of the paper's scene (motion profiles, named
//! scenarios, the image renderer and frame simulator, marker-level simulation, a deterministic
//! random generator) and the replay of recordings, behind one [`source::CaptureSource`] that the
//! capture stage (`src/main.rs`) publishes from.

pub mod autopilot;
pub mod camera;
pub mod landing;
pub mod motion;
pub mod motion_file;
pub mod render;
pub mod rng;
pub mod scenario;
pub mod sim;
pub mod source;
pub mod virtual_camera;

pub use motion::{
    Case1Sweep, DeckHeave, Heaving, LullCycle, Lulled, MotionProfile, MotionSample, ShipMotion, Swaying,
    TrackingError, VehicleSway,
};
pub use render::{RenderOptions, Renderer};
pub use scenario::{MarkerSimulator, Scenario};
pub use sim::{FrameSimulator, FrameTruth};
