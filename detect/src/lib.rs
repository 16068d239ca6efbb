//! Marker detection: from an 8-bit grayscale frame to the deck's markers ([`MarkerSet`]).
//! Pure algorithm: no IPC, no logging; the runtime's detect stage wires it to the pipeline.
//!
//! [`MarkerSet`]: deckwatch_common::MarkerSet

pub mod detector;
pub mod identify;
pub mod printed_grid;

pub use detector::{Detector, DetectorConfig, MeasuredDisc, SearchCounts};
pub use identify::{identify, marker_pixels, Blob, IdentifyError};
