//! `[record]` of the pipeline configuration: the flight recorder (`deckwatch run --record`).

use deckwatch_common::InvalidField;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The largest `chunk_mib`: a reader holds a whole chunk (decompressed), so the reader's bound on
/// one record (`reader::MAX_RECORD_BYTES`) is this plus the frame that filled the chunk.
pub const MAX_CHUNK_MIB: u32 = 64;

/// How frames are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FrameEncoding {
    /// `foxglove.RawImage`, `mono8`: a copy of the pixels (the chunk compression applies).
    #[default]
    Raw,
    /// `foxglove.CompressedImage`, PNG: lossless, replays exactly, costs CPU.
    Png,
    /// `foxglove.CompressedImage`, JPEG at `jpeg_quality`: small, lossy.
    Jpeg,
    /// No pixels (headers and every other channel still).
    None,
}

/// How MCAP chunks are compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RecordCompression {
    /// Fast (hundreds of MB/s a core): the default, frames included.
    #[default]
    Lz4,
    /// Smaller, slower.
    Zstd,
    None,
}

impl RecordCompression {
    pub fn mcap(self) -> Option<mcap::Compression> {
        match self {
            Self::Lz4 => Some(mcap::Compression::Lz4),
            Self::Zstd => Some(mcap::Compression::Zstd),
            Self::None => None,
        }
    }
}

/// `[record]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RecordConfig {
    /// The MCAP file to write; absent: no recorder.
    pub path: Option<PathBuf>,
    pub frames: FrameEncoding,
    /// Write the pixels of every Nth frame (every frame's header is written).
    pub frame_every: u32,
    /// 1..=100.
    pub jpeg_quality: u8,
    pub compression: RecordCompression,
    /// Target size of a chunk (MiB before compression); a frame larger than it is a chunk.
    pub chunk_mib: u32,
    /// Frames copied out of shared memory and waiting for the writer; when it is full the
    /// recorder drops (and counts) frames instead of slowing anything down.
    pub queue_frames: u32,
    /// The open chunk is written out at least this often, so a killed recorder loses at most
    /// this much.
    pub flush_interval_ms: u64,
}

impl Default for RecordConfig {
    fn default() -> Self {
        Self {
            path: None,
            frames: FrameEncoding::Raw,
            frame_every: 1,
            jpeg_quality: 90,
            compression: RecordCompression::Lz4,
            chunk_mib: 4,
            queue_frames: 8,
            flush_interval_ms: 1000,
        }
    }
}

impl RecordConfig {
    pub fn enabled(&self) -> bool {
        self.path.is_some()
    }

    /// Whether the recorder subscribes to frames at all.
    pub fn records_frames(&self) -> bool {
        self.enabled() && self.frames != FrameEncoding::None
    }

    /// The first bad value: its key (without the section) and what is wrong.
    pub fn validate(&self) -> Result<(), InvalidField> {
        if self.frame_every == 0 {
            return Err(InvalidField::new("frame_every", "must be at least 1"));
        }
        if !(1..=100).contains(&self.jpeg_quality) {
            return Err(InvalidField::new(
                "jpeg_quality",
                format!("must be 1..=100, got {}", self.jpeg_quality),
            ));
        }
        if !(1..=MAX_CHUNK_MIB).contains(&self.chunk_mib) {
            return Err(InvalidField::new(
                "chunk_mib",
                format!("must be 1..={MAX_CHUNK_MIB}, got {}", self.chunk_mib),
            ));
        }
        if !(1..=256).contains(&self.queue_frames) {
            return Err(InvalidField::new(
                "queue_frames",
                format!("must be 1..=256, got {}", self.queue_frames),
            ));
        }
        if !(10..=60_000).contains(&self.flush_interval_ms) {
            return Err(InvalidField::new(
                "flush_interval_ms",
                format!("must be 10..=60000, got {}", self.flush_interval_ms),
            ));
        }
        if let Some(p) = &self.path {
            if p.as_os_str().is_empty() {
                return Err(InvalidField::new("path", "must not be empty"));
            }
        }
        Ok(())
    }
}
