//! Flight recordings: every message of a deckwatch run in one MCAP file, the robotics ecosystem's
//! recording format (Foxglove, Lichtblick, rerun, the `mcap` command-line and Python libraries
//! open it), and reading them back.
//!
//! What a recording holds (the channels, [`topics`]):
//! - camera frames as Foxglove's `foxglove.RawImage` (`mono8`) or `foxglove.CompressedImage`
//!   (`png`, lossless, or `jpeg`), every one or every Nth, and the camera as
//!   `foxglove.CameraCalibration`;
//! - every frame's header and every stage's output (markers, attitudes, decisions) and the
//!   vehicle's attitude samples as JSON with a JSON Schema of deckwatch's own ([`json`]): every
//!   field, so that deckwatch reads them back exactly (re-simulation, `deckwatch diff`);
//! - the stages' log lines as `foxglove.Log`, the recorder's own counts;
//! - the configuration, versions, source and camera as MCAP metadata and attachments.
//!
//! Times: an MCAP message's log and publish time are UNIX nanoseconds (what the tools show). The
//! pipeline's clock is `CLOCK_MONOTONIC`; the recorder measures the offset between the two once
//! and keeps it in the metadata ([`TimeBase`]); the messages keep their own monotonic times.
//!
//! Pure library: files in, files out; the recorder process and the commands are in `runtime`
//! and `cli`.

pub mod config;
pub mod convert;
pub mod diff;
pub mod json;
pub mod reader;
pub mod writer;

pub use config::{FrameEncoding, RecordCompression, RecordConfig};
pub use json::{FieldError, JsonField};
pub use reader::{FlightMessages, FlightReader, FlightRecord, RecordedFrame};
pub use writer::{FlightWriter, WriterOptions};

use deckwatch_common::messages::{
    AttitudeMessage, Channel, FrameHeader, LandingDecision, MarkerMessage, PipelineStage, VehicleSample,
};
use std::path::{Path, PathBuf};

/// The channels of a flight recording, one place. A pipeline message's topic is its
/// [`Channel`]'s (the name it has on the bus too).
pub mod topics {
    use deckwatch_common::messages::*;
    /// `foxglove.RawImage`, `mono8`.
    pub const IMAGE: &str = "/camera/image";
    /// `foxglove.CompressedImage`, `png` or `jpeg`.
    pub const IMAGE_COMPRESSED: &str = "/camera/image/compressed";
    /// `foxglove.CameraCalibration`, with the first frame.
    pub const CALIBRATION: &str = "/camera/calibration";
    /// Every frame's header (`deckwatch.FrameHeader`), recorded or not.
    pub const FRAME: &str = FrameHeader::TOPIC;
    pub const MARKERS: &str = MarkerMessage::TOPIC;
    pub const ATTITUDE: &str = AttitudeMessage::TOPIC;
    pub const DECISION: &str = LandingDecision::TOPIC;
    pub const VEHICLE: &str = VehicleSample::TOPIC;
    /// Every MAVLink frame the link sent or received (`deckwatch.LinkTraffic`).
    pub const LINK: &str = LinkTraffic::TOPIC;
    /// `foxglove.Log`: what the stages said.
    pub const LOG: &str = StageLog::TOPIC;
    pub const RECORDER: &str = "/deckwatch/recorder";
}

/// A recording that cannot be written or read: the file, and what went wrong.
#[derive(Debug, thiserror::Error)]
pub enum FlightError {
    #[error("{path}: {problem}")]
    File { path: PathBuf, problem: String },
    /// A message that does not decode (the channel, its sequence number, the field).
    #[error("{path}: channel {topic}, message {sequence}: {problem}")]
    Message {
        path: PathBuf,
        topic: String,
        sequence: u32,
        problem: String,
    },
}

/// An image that cannot be encoded or decoded: which codec (`png`, `jpeg`), and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{codec}: {problem}")]
pub struct ImageCodecError {
    pub codec: &'static str,
    pub problem: String,
}

impl ImageCodecError {
    pub(crate) fn new(codec: &'static str, problem: impl std::fmt::Display) -> Self {
        Self {
            codec,
            problem: problem.to_string(),
        }
    }
}

impl FlightError {
    pub(crate) fn file(path: &Path, problem: impl std::fmt::Display) -> Self {
        Self::File {
            path: path.to_path_buf(),
            problem: problem.to_string(),
        }
    }
}

/// A pipeline message that a recording carries on its [`Channel`]'s topic, as JSON.
pub trait FlightMessage: JsonField + Channel {
    /// The schema's name (`deckwatch.<Type>`).
    const SCHEMA: &'static str;
    /// When the message came into being (`CLOCK_MONOTONIC` ns): its MCAP log time, converted.
    fn produced_ns(&self) -> u64;
}

impl FlightMessage for FrameHeader {
    const SCHEMA: &'static str = "deckwatch.FrameHeader";
    fn produced_ns(&self) -> u64 {
        self.stamp.times.published_ns
    }
}

impl FlightMessage for MarkerMessage {
    const SCHEMA: &'static str = "deckwatch.MarkerMessage";
    fn produced_ns(&self) -> u64 {
        self.stamp.times[PipelineStage::Detect].finished_ns
    }
}

impl FlightMessage for AttitudeMessage {
    const SCHEMA: &'static str = "deckwatch.AttitudeMessage";
    fn produced_ns(&self) -> u64 {
        self.stamp.times[PipelineStage::Estimate].finished_ns
    }
}

impl FlightMessage for LandingDecision {
    const SCHEMA: &'static str = "deckwatch.LandingDecision";
    fn produced_ns(&self) -> u64 {
        self.stamp.times[PipelineStage::Decide].finished_ns
    }
}

impl FlightMessage for VehicleSample {
    const SCHEMA: &'static str = "deckwatch.VehicleSample";
    fn produced_ns(&self) -> u64 {
        self.received_ns
    }
}

impl FlightMessage for deckwatch_common::messages::LinkTraffic {
    const SCHEMA: &'static str = "deckwatch.LinkTraffic";
    fn produced_ns(&self) -> u64 {
        self.time_ns
    }
}

/// The recorder's own counts, written every second and at the end.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RecorderStats {
    /// `CLOCK_MONOTONIC` ns.
    pub time_ns: u64,
    /// Frames whose pixels were written.
    pub frames_written: u64,
    /// Frames skipped on purpose (`frame_every`).
    pub frames_skipped: u64,
    /// Frames dropped because the writer was behind (its queue full) or never seen (the
    /// recorder's subscriber queue overflowed).
    pub frames_dropped: u64,
    /// Messages of every other channel written.
    pub messages_written: u64,
    /// Messages dropped because the writer was behind.
    pub messages_dropped: u64,
    /// Bytes of the file so far.
    pub bytes_written: u64,
}

impl RecorderStats {
    pub const SCHEMA: &'static str = "deckwatch.RecorderStats";

    pub fn json_schema() -> serde_json::Value {
        let mut properties = serde_json::Map::new();
        for k in [
            "time_ns",
            "frames_written",
            "frames_skipped",
            "frames_dropped",
            "messages_written",
            "messages_dropped",
            "bytes_written",
        ] {
            properties.insert(k.into(), serde_json::json!({"type": "integer"}));
        }
        serde_json::json!({"type": "object", "properties": properties})
    }
}

/// The offset from monotonic to UNIX time (kept in a recording's metadata `deckwatch.clock`).
pub use deckwatch_common::messages::TimeBase;

/// The deckwatch version that wrote a recording (metadata `deckwatch`).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
