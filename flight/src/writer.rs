//! Writing a flight recording.

use crate::config::{FrameEncoding, RecordCompression};
use crate::{topics, FlightError, FlightMessage, ImageCodecError, RecorderStats, TimeBase};
use deckwatch_common::camera::CameraModel;
use deckwatch_common::messages::FrameHeader;
use foxglove::schemas::{CameraCalibration, CompressedImage, Log, RawImage, Timestamp};
use foxglove::Encode;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// How a recording is written.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WriterOptions {
    pub compression: RecordCompression,
    /// Target chunk size before compression, bytes.
    pub chunk_bytes: u64,
    pub time_base: TimeBase,
}

impl Default for WriterOptions {
    fn default() -> Self {
        Self {
            compression: RecordCompression::Lz4,
            chunk_bytes: 4 << 20,
            time_base: TimeBase::IDENTITY,
        }
    }
}

/// Counts the bytes that reach the file.
struct CountingFile {
    inner: BufWriter<File>,
    bytes: Arc<AtomicU64>,
}

impl Write for CountingFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.bytes.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for CountingFile {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// An MCAP flight recording being written. Channels are created with their first message.
pub struct FlightWriter {
    mcap: mcap::Writer<CountingFile>,
    path: PathBuf,
    time_base: TimeBase,
    channels: HashMap<String, u16>,
    sequences: HashMap<u16, u32>,
    /// Messages written per channel.
    counts: BTreeMap<String, u64>,
    buffer: Vec<u8>,
    bytes: Arc<AtomicU64>,
}

/// The frame of reference Foxglove's image messages name.
pub const CAMERA_FRAME_ID: &str = "camera";

impl FlightWriter {
    pub fn create(path: &Path, options: WriterOptions) -> Result<Self, FlightError> {
        let file = File::create(path).map_err(|e| FlightError::file(path, format!("cannot create: {e}")))?;
        let bytes = Arc::new(AtomicU64::new(0));
        let out = CountingFile {
            inner: BufWriter::with_capacity(1 << 20, file),
            bytes: bytes.clone(),
        };
        let mcap = mcap::WriteOptions::new()
            .compression(options.compression.mcap())
            .chunk_size(Some(options.chunk_bytes))
            .profile("")
            .library(format!("deckwatch {}", crate::VERSION))
            .create(out)
            .map_err(|e| FlightError::file(path, e))?;
        Ok(Self {
            mcap,
            path: path.to_path_buf(),
            time_base: options.time_base,
            channels: HashMap::new(),
            sequences: HashMap::new(),
            counts: BTreeMap::new(),
            buffer: Vec::new(),
            bytes,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn time_base(&self) -> TimeBase {
        self.time_base
    }

    /// Messages written per channel so far.
    pub fn counts(&self) -> &BTreeMap<String, u64> {
        &self.counts
    }

    /// Bytes in the file so far (what the buffers have passed on).
    pub fn bytes_written(&self) -> u64 {
        self.bytes.load(Ordering::Relaxed)
    }

    fn error(&self, e: impl std::fmt::Display) -> FlightError {
        FlightError::file(&self.path, e)
    }

    fn channel(
        &mut self,
        topic: &str,
        schema_name: &str,
        schema_encoding: &str,
        schema: &[u8],
        message_encoding: &str,
    ) -> Result<u16, FlightError> {
        if let Some(&id) = self.channels.get(topic) {
            return Ok(id);
        }
        let schema_id = self
            .mcap
            .add_schema(schema_name, schema_encoding, schema)
            .map_err(|e| self.error(e))?;
        let id = self
            .mcap
            .add_channel(schema_id, topic, message_encoding, &BTreeMap::new())
            .map_err(|e| self.error(e))?;
        self.channels.insert(topic.to_string(), id);
        Ok(id)
    }

    fn write_raw(&mut self, channel: u16, topic: &str, unix_ns: u64) -> Result<(), FlightError> {
        let sequence = self.sequences.entry(channel).or_insert(0);
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: *sequence,
            log_time: unix_ns,
            publish_time: unix_ns,
        };
        *sequence = sequence.wrapping_add(1);
        let buffer = std::mem::take(&mut self.buffer);
        let result = self.mcap.write_to_known_channel(&header, &buffer);
        self.buffer = buffer;
        result.map_err(|e| self.error(e))?;
        match self.counts.get_mut(topic) {
            Some(n) => *n += 1,
            None => {
                self.counts.insert(topic.to_string(), 1);
            }
        }
        Ok(())
    }

    /// Encodes a Foxglove message into the buffer (its channel created with its first message,
    /// `extra` bytes reserved beyond it); the channel.
    fn encode_foxglove<T: Encode>(
        &mut self,
        topic: &'static str,
        message: &T,
        extra: usize,
    ) -> Result<u16, FlightError> {
        let schema = T::get_schema().ok_or_else(|| self.error("a Foxglove type without a schema"))?;
        let channel = self.channel(
            topic,
            &schema.name,
            &schema.encoding,
            &schema.data,
            &T::get_message_encoding(),
        )?;
        self.buffer.clear();
        self.buffer.reserve(message.encoded_len().unwrap_or(0) + extra);
        message
            .encode(&mut self.buffer)
            .map_err(|e| FlightError::file(&self.path, format!("encoding {topic}: {e}")))?;
        Ok(channel)
    }

    fn foxglove<T: Encode>(
        &mut self,
        topic: &'static str,
        message: &T,
        unix_ns: u64,
    ) -> Result<(), FlightError> {
        let channel = self.encode_foxglove(topic, message, 0)?;
        self.write_raw(channel, topic, unix_ns)
    }

    fn json(
        &mut self,
        topic: &'static str,
        schema_name: &str,
        schema: impl FnOnce() -> serde_json::Value,
        value: &serde_json::Value,
        unix_ns: u64,
    ) -> Result<(), FlightError> {
        let channel = match self.channels.get(topic) {
            Some(&id) => id,
            None => {
                let schema = schema().to_string();
                self.channel(topic, schema_name, "jsonschema", schema.as_bytes(), "json")?
            }
        };
        self.buffer.clear();
        serde_json::to_writer(&mut self.buffer, value).map_err(|e| self.error(e))?;
        self.write_raw(channel, topic, unix_ns)
    }

    /// A pipeline message on its channel, at the time it was produced.
    pub fn write<M: FlightMessage>(&mut self, message: &M) -> Result<(), FlightError> {
        let unix_ns = self.time_base.to_unix_ns(message.produced_ns());
        self.json(M::TOPIC, M::SCHEMA, M::json_schema, &message.to_json(), unix_ns)
    }

    /// A frame's pixels (`header` describes them; its own channel gets the header through
    /// [`Self::write`]). `jpeg_quality` applies to [`FrameEncoding::Jpeg`].
    pub fn write_frame(
        &mut self,
        header: &FrameHeader,
        pixels: &[u8],
        encoding: FrameEncoding,
        jpeg_quality: u8,
    ) -> Result<(), FlightError> {
        let (w, h, stride) = (
            header.width as usize,
            header.height as usize,
            header.stride as usize,
        );
        if stride < w || pixels.len() < header.required_len() {
            return Err(self.error(format!(
                "frame {}: {} bytes for {w}x{h} with stride {stride}",
                header.stamp.seq,
                pixels.len()
            )));
        }
        let unix_ns = self.time_base.to_unix_ns(header.stamp.times.captured_ns);
        let timestamp = Some(timestamp(unix_ns));
        // Rows packed (a RawImage's step may pad, but a PNG or JPEG takes packed rows).
        let packed: std::borrow::Cow<'_, [u8]> = if stride == w {
            std::borrow::Cow::Borrowed(&pixels[..w * h])
        } else {
            std::borrow::Cow::Owned(
                (0..h)
                    .flat_map(|r| &pixels[r * stride..r * stride + w])
                    .copied()
                    .collect(),
            )
        };
        match encoding {
            FrameEncoding::None => Ok(()),
            FrameEncoding::Raw => {
                let image = RawImage {
                    timestamp,
                    frame_id: CAMERA_FRAME_ID.into(),
                    width: w as u32,
                    height: h as u32,
                    encoding: "mono8".into(),
                    step: w as u32,
                    data: Default::default(),
                };
                self.raw_image(&image, &packed, unix_ns)
            }
            FrameEncoding::Png | FrameEncoding::Jpeg => {
                let (data, format) = if encoding == FrameEncoding::Png {
                    (encode_png(&packed, w, h).map_err(|e| self.error(e))?, "png")
                } else {
                    (
                        encode_jpeg(&packed, w, h, jpeg_quality).map_err(|e| self.error(e))?,
                        "jpeg",
                    )
                };
                let image = CompressedImage {
                    timestamp,
                    frame_id: CAMERA_FRAME_ID.into(),
                    data: data.into(),
                    format: format.into(),
                };
                self.foxglove(topics::IMAGE_COMPRESSED, &image, unix_ns)
            }
        }
    }

    /// A `foxglove.RawImage` whose pixels are appended to its encoded header as its `data` field
    /// (protobuf allows fields in any order): one copy of the pixels instead of three (into the
    /// message, the message into the buffer).
    fn raw_image(&mut self, image: &RawImage, pixels: &[u8], unix_ns: u64) -> Result<(), FlightError> {
        let channel = self.encode_foxglove(topics::IMAGE, image, pixels.len() + 16)?;
        // Field 6 (`data`), wire type 2 (length-delimited), then the length as a varint.
        self.buffer.push((6 << 3) | 2);
        let mut len = pixels.len() as u64;
        while len >= 0x80 {
            self.buffer.push((len as u8) | 0x80);
            len >>= 7;
        }
        self.buffer.push(len as u8);
        self.buffer.extend_from_slice(pixels);
        self.write_raw(channel, topics::IMAGE, unix_ns)
    }

    /// The camera model as `foxglove.CameraCalibration` (pinhole with plumb-bob distortion).
    pub fn write_calibration(&mut self, camera: &CameraModel, monotonic_ns: u64) -> Result<(), FlightError> {
        let unix_ns = self.time_base.to_unix_ns(monotonic_ns);
        let d = &camera.distortion;
        let c = CameraCalibration {
            timestamp: Some(timestamp(unix_ns)),
            frame_id: CAMERA_FRAME_ID.into(),
            width: camera.width,
            height: camera.height,
            distortion_model: "plumb_bob".into(),
            d: vec![d.k1, d.k2, d.p1, d.p2, d.k3],
            k: vec![
                camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0,
            ],
            r: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: vec![
                camera.fx, 0.0, camera.cx, 0.0, 0.0, camera.fy, camera.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
            ],
        };
        self.foxglove(topics::CALIBRATION, &c, unix_ns)
    }

    /// A log line (`level`: 1 debug, 2 info, 3 warning, 4 error) of the process `name`.
    pub fn write_log(
        &mut self,
        monotonic_ns: u64,
        level: i32,
        name: &str,
        message: &str,
    ) -> Result<(), FlightError> {
        let unix_ns = self.time_base.to_unix_ns(monotonic_ns);
        let log = Log {
            timestamp: Some(timestamp(unix_ns)),
            level,
            message: message.into(),
            name: name.into(),
            file: String::new(),
            line: 0,
        };
        self.foxglove(topics::LOG, &log, unix_ns)
    }

    pub fn write_stats(&mut self, stats: &RecorderStats) -> Result<(), FlightError> {
        let unix_ns = self.time_base.to_unix_ns(stats.time_ns);
        let value = serde_json::to_value(stats).map_err(|e| self.error(e))?;
        self.json(
            topics::RECORDER,
            RecorderStats::SCHEMA,
            RecorderStats::json_schema,
            &value,
            unix_ns,
        )
    }

    /// An MCAP metadata record (string pairs).
    pub fn write_metadata(
        &mut self,
        name: &str,
        entries: BTreeMap<String, String>,
    ) -> Result<(), FlightError> {
        self.mcap
            .write_metadata(&mcap::records::Metadata {
                name: name.into(),
                metadata: entries,
            })
            .map_err(|e| self.error(e))
    }

    /// An attachment (a file's contents, e.g. the configuration).
    pub fn attach(
        &mut self,
        name: &str,
        media_type: &str,
        data: &[u8],
        monotonic_ns: u64,
    ) -> Result<(), FlightError> {
        let t = self.time_base.to_unix_ns(monotonic_ns);
        self.attach_at(name, media_type, data, t)
    }

    /// An attachment at a UNIX time.
    pub fn attach_at(
        &mut self,
        name: &str,
        media_type: &str,
        data: &[u8],
        t: u64,
    ) -> Result<(), FlightError> {
        self.mcap
            .attach(&mcap::Attachment {
                log_time: t,
                create_time: t,
                name: name.into(),
                media_type: media_type.into(),
                data: std::borrow::Cow::Borrowed(data),
            })
            .map_err(|e| self.error(e))
    }

    /// A message read from another recording, on a channel of the same topic and schema, at
    /// its recorded time (recovery of a cut file).
    pub fn write_recorded(&mut self, m: &crate::reader::RecordedMessage) -> Result<(), FlightError> {
        let c = &m.channel;
        let channel = self.channel(
            &c.topic,
            &c.schema_name,
            &c.schema_encoding,
            &c.schema_data,
            &c.message_encoding,
        )?;
        self.buffer.clear();
        self.buffer.extend_from_slice(&m.data);
        self.write_raw(channel, &c.topic, m.log_time)
    }

    /// Writes out the open chunk and flushes the file: what is written so far survives a kill.
    pub fn flush(&mut self) -> Result<(), FlightError> {
        self.mcap.flush().map_err(|e| self.error(e))
    }

    /// Writes the summary (indexes, statistics) and closes the file; the bytes written.
    pub fn finish(mut self) -> Result<u64, FlightError> {
        self.mcap.finish().map_err(|e| self.error(e))?;
        let mut out = self.mcap.into_inner();
        out.flush().map_err(|e| FlightError::file(&self.path, e))?;
        Ok(self.bytes.load(Ordering::Relaxed))
    }
}

fn timestamp(unix_ns: u64) -> Timestamp {
    let sec = (unix_ns / 1_000_000_000).min(u32::MAX as u64) as u32;
    Timestamp::new(sec, (unix_ns % 1_000_000_000) as u32)
}

/// An 8-bit grayscale PNG of packed rows.
pub fn encode_png(packed: &[u8], width: usize, height: usize) -> Result<Vec<u8>, ImageCodecError> {
    let mut out = Vec::with_capacity(packed.len() / 4);
    {
        let mut e = png::Encoder::new(&mut out, width as u32, height as u32);
        e.set_color(png::ColorType::Grayscale);
        e.set_depth(png::BitDepth::Eight);
        e.set_compression(png::Compression::Fast);
        let mut w = e.write_header().map_err(|e| ImageCodecError::new("png", e))?;
        w.write_image_data(packed)
            .map_err(|e| ImageCodecError::new("png", e))?;
    }
    Ok(out)
}

/// A grayscale JPEG of packed rows (`common::jpeg`).
pub fn encode_jpeg(
    packed: &[u8],
    width: usize,
    height: usize,
    quality: u8,
) -> Result<Vec<u8>, ImageCodecError> {
    deckwatch_common::jpeg::encode_gray(packed, width, height, quality)
        .map_err(|e| ImageCodecError::new("jpeg", e.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reader::{read_frames, FlightMessages, FlightReader, FlightRecord};
    use deckwatch_common::camera::CameraModel;
    use deckwatch_common::messages::{AttitudeMessage, DecisionState, LandingDecision};

    fn header(seq: u64, w: u32, h: u32) -> FrameHeader {
        let mut hd = FrameHeader::default();
        hd.stamp.seq = seq;
        hd.stamp.times.captured_ns = 1_000 + seq * 100_000_000;
        hd.stamp.times.published_ns = hd.stamp.times.captured_ns + 5;
        (hd.width, hd.height, hd.stride) = (w, h, w);
        hd.context.camera = CameraModel::default();
        hd
    }

    fn write_sample(path: &Path, encoding: FrameEncoding, frames: u64) -> Vec<Vec<u8>> {
        let mut w = FlightWriter::create(
            path,
            WriterOptions {
                chunk_bytes: 4096,
                ..Default::default()
            },
        )
        .unwrap();
        w.write_metadata(
            "deckwatch",
            [("version".to_string(), crate::VERSION.to_string())].into(),
        )
        .unwrap();
        w.attach("pipeline.toml", "application/toml", b"[sim]\n", 0)
            .unwrap();
        let mut images = Vec::new();
        for seq in 0..frames {
            let h = header(seq, 64, 48);
            let px: Vec<u8> = (0..64 * 48).map(|i| ((i as u64 * 7 + seq) % 251) as u8).collect();
            w.write(&h).unwrap();
            w.write_frame(&h, &px, encoding, 90).unwrap();
            let mut a = AttitudeMessage {
                stamp: h.stamp,
                ..Default::default()
            };
            a.rpy.roll = seq as f64 * 1e-3;
            w.write(&a).unwrap();
            let d = LandingDecision {
                stamp: h.stamp,
                state: DecisionState::Hold.into(),
                ..Default::default()
            };
            w.write(&d).unwrap();
            w.write_log(h.stamp.times.captured_ns, 2, "detect", "a line")
                .unwrap();
            images.push(px);
        }
        w.finish().unwrap();
        images
    }

    #[test]
    fn raw_and_png_frames_and_messages_read_back_exactly() {
        let dir = tempfile::tempdir().unwrap();
        for encoding in [FrameEncoding::Raw, FrameEncoding::Png] {
            let path = dir.path().join("f.mcap");
            let images = write_sample(&path, encoding, 6);
            let (frames, ended) = read_frames(&path, 1 << 30).unwrap();
            assert_eq!(ended, None);
            assert_eq!(frames.len(), 6);
            for (f, px) in frames.iter().zip(&images) {
                assert_eq!(&f.pixels, px);
            }
            let m = FlightMessages::read(&path).unwrap();
            assert_eq!((m.frames.len(), m.attitudes.len(), m.decisions.len()), (6, 6, 6));
            assert_eq!(m.attitudes[5].rpy.roll, 5e-3);
            assert_eq!(m.metadata["deckwatch"]["version"], crate::VERSION);
            assert_eq!(m.counts[topics::LOG], 6);
        }
        // JPEG is lossy, but close.
        let path = dir.path().join("j.mcap");
        let images = write_sample(&path, FrameEncoding::Jpeg, 2);
        let (frames, _) = read_frames(&path, 1 << 30).unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].pixels.len(), images[0].len());
    }

    /// A writer killed mid-file: whatever was flushed reads, and the reader says where the
    /// file ended; no cut makes it panic.
    #[test]
    fn a_cut_file_reads_up_to_its_last_complete_chunk() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.mcap");
        write_sample(&path, FrameEncoding::Raw, 8);
        let whole = std::fs::read(&path).unwrap();
        let cut = dir.path().join("cut.mcap");
        let mut last = 0;
        for len in (0..whole.len()).step_by(97) {
            std::fs::write(&cut, &whole[..len]).unwrap();
            let Ok(reader) = FlightReader::open(&cut) else {
                continue;
            };
            let mut reader = reader;
            let n = reader
                .by_ref()
                .filter(|r| matches!(r, Ok(FlightRecord::Message(_))))
                .count();
            assert!(reader.ended_early.is_some(), "cut at {len}");
            assert!(n >= last, "cut at {len}: {n} messages, {last} at a shorter cut");
            last = n;
        }
        assert!(last > 30, "most messages survive a late cut: {last}");
        // Recovery makes a complete file of what survived.
        std::fs::write(&cut, &whole[..whole.len() * 3 / 4]).unwrap();
        let fixed = dir.path().join("fixed.mcap");
        let r = crate::convert::recover(&cut, &fixed, WriterOptions::default()).unwrap();
        assert!(r.ended_early.is_some() && r.messages > 10, "{r:?}");
        let mut reader = FlightReader::open(&fixed).unwrap();
        let n = reader
            .by_ref()
            .filter(|r| matches!(r, Ok(FlightRecord::Message(_))))
            .count();
        assert_eq!((n as u64, reader.ended_early.clone()), (r.messages, None));
        assert!(!read_frames(&fixed, 1 << 30).unwrap().0.is_empty());
    }
}
