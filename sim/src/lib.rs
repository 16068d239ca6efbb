//! deckwatch's simulator, pure: the deck's motion (sinusoid seas, spectrum seas, recorded ship
//! motion, heave; the family of named ship-motion models that become motion files, `ship`),
//! the vehicle's sway and its autopilot's attitude stream, named scenarios and marker-level
//! simulation, the image renderer and frame simulator, the landing path of the closed-loop
//! trials, and a deterministic random generator. Frame sources (`capture`) render through it;
//! the evaluations (`decide-eval`, `predict-eval`, `trials`) take their motion from it without
//! compiling any camera or recording code.

pub mod autopilot;
pub mod landing;
pub mod motion;
pub mod motion_file;
pub mod render;
pub mod rng;
pub mod scenario;
pub mod ship;
pub mod sim;

pub use motion::{
    Case1Sweep, DeckHeave, Heaving, LullCycle, Lulled, MotionProfile, MotionSample, ShipMotion, Swaying,
    TrackingError, VehicleSway,
};
pub use render::{RenderOptions, Renderer};
pub use scenario::{MarkerSimulator, Scenario};
pub use sim::{FrameSimulator, FrameTruth};
