//! Frame sources of deckwatch behind one [`source::CaptureSource`] that the capture stage
//! publishes from: the simulator (rendered by `deckwatch-sim`), the replay of recordings
//! (folders and MCAP flight recordings), libcamera cameras (feature `libcamera`) and the virtual
//! camera that feeds recorded frames to a V4L2 loopback.

pub mod camera;
pub mod source;
pub mod virtual_camera;
