//! Marker detection: from a grayscale frame to the deck's markers. So far the last step, the
//! geometric identification of blobs as markers; the blob detector itself comes with its issue.

pub mod identify;

pub use identify::{identify, marker_pixels, Blob, IdentifyError};
