//! deckwatch's file formats: a flight recording's folder (`camera.json`, `frames.csv` with its
//! optional ground-truth columns, the PNG frames, `vehicle.csv`) and the marker table that
//! `deckwatch sim markers` writes and `deckwatch estimate-table` reads; and the calibrations of
//! other tools (ROS, OpenCV, Kalibr) that `deckwatch calibration import` converts. Every error names the
//! file and, where it applies, the line and the field. Apart from the algorithms: detection,
//! estimation and the decision compile none of this.

pub mod calibration;
pub mod deck_pattern;
pub mod marker_table;
pub mod recording;

pub use recording::{Recording, RecordingError, RecordingWriter};
