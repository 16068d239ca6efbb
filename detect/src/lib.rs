//! Marker detection: from an 8-bit grayscale frame to the deck's markers ([`MarkerSet`]).
//! Pure algorithm: no IPC, no logging; the stage binary (`src/main.rs`) wires [`stage`] to
//! iceoryx2.
//!
//! [`MarkerSet`]: deckwatch_common::MarkerSet

pub mod detector;
pub mod identify;
pub mod stage;

pub use detector::{Detector, DetectorConfig};
pub use identify::{identify, marker_pixels, Blob, IdentifyError};
