//! Reading a flight recording: one pass from start to end, streaming (files of many gigabytes
//! need no more memory than their largest chunk), and tolerant of a file whose writer was killed:
//! everything up to the last complete chunk is read, then the reader says where it ended.

use crate::{topics, FlightError, FlightMessage, ImageCodecError};
use deckwatch_common::messages::FrameHeader;
use foxglove::schemas::{CompressedImage, RawImage};
use foxglove::Decode;
use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A channel as the file declares it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    pub topic: String,
    pub schema_name: String,
    pub schema_encoding: String,
    pub schema_data: Vec<u8>,
    pub message_encoding: String,
}

/// One message.
#[derive(Debug, Clone)]
pub struct RecordedMessage {
    pub channel: Arc<ChannelInfo>,
    pub sequence: u32,
    /// UNIX ns.
    pub log_time: u64,
    pub data: Vec<u8>,
}

/// What the file holds, in file order.
#[derive(Debug, Clone)]
pub enum FlightRecord {
    Message(RecordedMessage),
    Metadata {
        name: String,
        entries: BTreeMap<String, String>,
    },
    Attachment {
        name: String,
        media_type: String,
        data: Vec<u8>,
        /// UNIX ns.
        log_time: u64,
    },
}

/// Largest record the reader accepts (a corrupt length must not allocate the machine away).
const RECORD_LIMIT: usize = 1 << 30;

/// A recording opened for reading; an iterator over its records.
pub struct FlightReader {
    path: PathBuf,
    file: File,
    reader: LinearReader,
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    channels: HashMap<u16, Arc<ChannelInfo>>,
    /// Why reading stopped before the end magic (a killed writer, a corrupt record).
    pub ended_early: Option<String>,
    done: bool,
}

impl FlightReader {
    pub fn open(path: &Path) -> Result<Self, FlightError> {
        let file = File::open(path).map_err(|e| FlightError::file(path, format!("cannot open: {e}")))?;
        let reader = LinearReader::new_with_options(
            LinearReaderOptions::default()
                .with_prevalidate_chunk_crcs(true)
                .with_record_length_limit(RECORD_LIMIT),
        );
        Ok(Self {
            path: path.to_path_buf(),
            file,
            reader,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            ended_early: None,
            done: false,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The channels seen so far.
    pub fn channels(&self) -> impl Iterator<Item = &ChannelInfo> {
        self.channels.values().map(|c| c.as_ref())
    }

    fn stop(&mut self, why: String) -> Option<Result<FlightRecord, FlightError>> {
        self.done = true;
        self.ended_early = Some(why);
        None
    }
}

impl Iterator for FlightReader {
    type Item = Result<FlightRecord, FlightError>;

    /// The next record; None at the end, or where a killed writer's file ends
    /// ([`FlightReader::ended_early`] says so). An I/O error is an error.
    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        loop {
            let event = match self.reader.next_event() {
                None => {
                    self.done = true;
                    return None;
                }
                Some(Err(e)) => return self.stop(e.to_string()),
                Some(Ok(event)) => event,
            };
            let (opcode, data) = match event {
                LinearReadEvent::ReadRequest(n) => {
                    let buf = self.reader.insert(n.min(16 << 20));
                    match self.file.read(buf) {
                        Ok(read) => self.reader.notify_read(read),
                        Err(e) => {
                            self.done = true;
                            return Some(Err(FlightError::file(&self.path, e)));
                        }
                    }
                    continue;
                }
                LinearReadEvent::Record { data, opcode } => (opcode, data),
            };
            let record = match mcap::parse_record(opcode, data) {
                Ok(r) => r,
                Err(e) => {
                    let why = format!("a bad record (opcode {opcode:#x}): {e}");
                    return self.stop(why);
                }
            };
            match record {
                Record::Schema { header, data } => {
                    self.schemas
                        .insert(header.id, (header.name, header.encoding, data.into_owned()));
                }
                Record::Channel(c) => {
                    let (schema_name, schema_encoding, schema_data) =
                        self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                    self.channels.insert(
                        c.id,
                        Arc::new(ChannelInfo {
                            topic: c.topic,
                            schema_name,
                            schema_encoding,
                            schema_data,
                            message_encoding: c.message_encoding,
                        }),
                    );
                }
                Record::Message { header, data } => {
                    let Some(channel) = self.channels.get(&header.channel_id).cloned() else {
                        let why = format!(
                            "message {} on channel {}, which was never declared",
                            header.sequence, header.channel_id
                        );
                        return self.stop(why);
                    };
                    return Some(Ok(FlightRecord::Message(RecordedMessage {
                        channel,
                        sequence: header.sequence,
                        log_time: header.log_time,
                        data: data.into_owned(),
                    })));
                }
                Record::Metadata(m) => {
                    return Some(Ok(FlightRecord::Metadata {
                        name: m.name,
                        entries: m.metadata,
                    }))
                }
                Record::Attachment { header, data, .. } => {
                    return Some(Ok(FlightRecord::Attachment {
                        name: header.name,
                        media_type: header.media_type,
                        data: data.into_owned(),
                        log_time: header.log_time,
                    }))
                }
                _ => {}
            }
        }
    }
}

impl RecordedMessage {
    pub fn topic(&self) -> &str {
        &self.channel.topic
    }

    fn error(&self, path: &Path, problem: impl std::fmt::Display) -> FlightError {
        FlightError::Message {
            path: path.to_path_buf(),
            topic: self.channel.topic.clone(),
            sequence: self.sequence,
            problem: problem.to_string(),
        }
    }

    /// The message as the pipeline message `M` (its channel must be `M`'s).
    pub fn decode<M: FlightMessage>(&self, path: &Path) -> Result<M, FlightError> {
        if self.channel.topic != M::TOPIC || self.channel.schema_name != M::SCHEMA {
            return Err(self.error(
                path,
                format!(
                    "schema {} is not {} of {}",
                    self.channel.schema_name,
                    M::SCHEMA,
                    M::TOPIC
                ),
            ));
        }
        let value: serde_json::Value = serde_json::from_slice(&self.data).map_err(|e| self.error(path, e))?;
        M::from_json(&value).map_err(|e| self.error(path, e))
    }

    /// A frame's pixels (packed rows) from `foxglove.RawImage` (`mono8`) or
    /// `foxglove.CompressedImage` (`png`, `jpeg`, grayscale): (width, height, pixels).
    pub fn decode_image(&self, path: &Path) -> Result<(u32, u32, Vec<u8>), FlightError> {
        match self.channel.schema_name.as_str() {
            "foxglove.RawImage" => {
                let img = RawImage::decode(self.data.as_slice()).map_err(|e| self.error(path, e))?;
                if img.encoding != "mono8" && img.encoding != "8UC1" {
                    return Err(self.error(
                        path,
                        format!("image encoding {} (deckwatch reads mono8)", img.encoding),
                    ));
                }
                deckwatch_common::camera::check_image_size(img.width, img.height)
                    .map_err(|e| self.error(path, e))?;
                let (w, h, step) = (img.width as usize, img.height as usize, img.step as usize);
                if step < w || img.data.len() < step.saturating_mul(h) {
                    return Err(self.error(
                        path,
                        format!("{} bytes for {w}x{h} with step {step}", img.data.len()),
                    ));
                }
                let pixels = if step == w {
                    img.data[..w * h].to_vec()
                } else {
                    (0..h)
                        .flat_map(|r| &img.data[r * step..r * step + w])
                        .copied()
                        .collect()
                };
                Ok((img.width, img.height, pixels))
            }
            "foxglove.CompressedImage" => {
                let img = CompressedImage::decode(self.data.as_slice()).map_err(|e| self.error(path, e))?;
                match img.format.as_str() {
                    "png" => decode_png(&img.data).map_err(|e| self.error(path, e)),
                    "jpeg" | "jpg" => decode_jpeg(&img.data).map_err(|e| self.error(path, e)),
                    other => Err(self.error(
                        path,
                        format!("image format {other} (deckwatch reads png and jpeg)"),
                    )),
                }
            }
            other => Err(self.error(path, format!("schema {other} is no image"))),
        }
    }
}

fn decode_png(data: &[u8]) -> Result<(u32, u32, Vec<u8>), ImageCodecError> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(data));
    decoder.set_transformations(png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().map_err(|e| ImageCodecError::new("png", e))?;
    let (w, h) = (reader.info().width, reader.info().height);
    // The header's size before the buffer: a few bytes can claim gigabytes.
    deckwatch_common::camera::check_image_size(w, h).map_err(|e| ImageCodecError::new("png", e))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| ImageCodecError::new("png", "the image is too large"))?;
    let mut buf = vec![0; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| ImageCodecError::new("png", e))?;
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Eight {
        return Err(ImageCodecError::new(
            "png",
            format!(
                "{:?} {:?} (deckwatch reads 8-bit grayscale)",
                info.color_type, info.bit_depth
            ),
        ));
    }
    buf.truncate(w as usize * h as usize);
    Ok((w, h, buf))
}

fn decode_jpeg(data: &[u8]) -> Result<(u32, u32, Vec<u8>), ImageCodecError> {
    deckwatch_common::jpeg::decode_gray(data).map_err(|e| ImageCodecError::new("jpeg", e.0))
}

/// The pipeline messages of a recording, decoded, in file order (frames without pixels).
#[derive(Debug, Clone, Default)]
pub struct FlightMessages {
    pub frames: Vec<FrameHeader>,
    pub markers: Vec<deckwatch_common::messages::MarkerMessage>,
    pub attitudes: Vec<deckwatch_common::messages::AttitudeMessage>,
    pub decisions: Vec<deckwatch_common::messages::LandingDecision>,
    pub vehicle: Vec<deckwatch_common::messages::VehicleSample>,
    pub link: Vec<deckwatch_common::messages::LinkTraffic>,
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Messages per channel.
    pub counts: BTreeMap<String, u64>,
    /// Where a killed writer's file ended.
    pub ended_early: Option<String>,
}

impl FlightMessages {
    /// Reads every pipeline message (images are skipped, not decoded).
    pub fn read(path: &Path) -> Result<Self, FlightError> {
        let mut out = Self::default();
        let mut reader = FlightReader::open(path)?;
        for record in reader.by_ref() {
            match record? {
                FlightRecord::Message(m) => {
                    *out.counts.entry(m.channel.topic.clone()).or_insert(0) += 1;
                    match m.topic() {
                        topics::FRAME => out.frames.push(m.decode(path)?),
                        topics::MARKERS => out.markers.push(m.decode(path)?),
                        topics::ATTITUDE => out.attitudes.push(m.decode(path)?),
                        topics::DECISION => out.decisions.push(m.decode(path)?),
                        topics::VEHICLE => out.vehicle.push(m.decode(path)?),
                        topics::LINK => out.link.push(m.decode(path)?),
                        _ => {}
                    }
                }
                FlightRecord::Metadata { name, entries } => {
                    out.metadata.insert(name, entries);
                }
                FlightRecord::Attachment { .. } => {}
            }
        }
        out.ended_early = reader.ended_early.take();
        Ok(out)
    }
}

/// A frame of a recording: its header and pixels (packed rows).
#[derive(Debug, Clone)]
pub struct RecordedFrame {
    pub header: FrameHeader,
    pub pixels: Vec<u8>,
}

/// Every frame of a recording that has pixels, with its header, in order; `max_bytes` bounds the
/// pixels held (an error names the limit). Also says where a killed writer's file ended.
pub fn read_frames(path: &Path, max_bytes: u64) -> Result<(Vec<RecordedFrame>, Option<String>), FlightError> {
    // A frame's image comes right after its header (the writer puts them together), so an image
    // belongs to the header before it; a header without an image is a frame recorded without
    // pixels.
    let mut pending: Option<FrameHeader> = None;
    let mut frames = Vec::new();
    let mut held = 0u64;
    let mut reader = FlightReader::open(path)?;
    for record in reader.by_ref() {
        let FlightRecord::Message(m) = record? else {
            continue;
        };
        match m.topic() {
            topics::FRAME => pending = Some(m.decode(path)?),
            topics::IMAGE | topics::IMAGE_COMPRESSED => {
                let Some(mut header) = pending.take() else {
                    return Err(m.error(path, "an image without its frame header before it"));
                };
                let (w, h, pixels) = m.decode_image(path)?;
                if (w, h) != (header.width, header.height) {
                    return Err(m.error(
                        path,
                        format!(
                            "image {w}x{h} but its header says {}x{}",
                            header.width, header.height
                        ),
                    ));
                }
                held += pixels.len() as u64;
                if held > max_bytes {
                    return Err(FlightError::file(
                        path,
                        format!("its frames need more than {} MiB", max_bytes >> 20),
                    ));
                }
                header.stride = header.width;
                frames.push(RecordedFrame { header, pixels });
            }
            _ => {}
        }
    }
    Ok((frames, reader.ended_early.take()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CRC-32 (IEEE) as PNG chunks carry it, bit by bit.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0xedb8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    /// A small PNG whose header claims 30 000 x 30 000 (900 MB of pixels) is refused from its
    /// header, before the buffer is allocated; a true one is read.
    #[test]
    fn a_huge_png_header_is_refused_before_its_buffer() {
        let mut png = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut png, 4, 4);
            encoder.set_color(png::ColorType::Grayscale);
            encoder.set_depth(png::BitDepth::Eight);
            encoder
                .write_header()
                .unwrap()
                .write_image_data(&[7; 16])
                .unwrap();
        }
        assert_eq!(decode_png(&png).unwrap(), (4, 4, vec![7; 16]));
        // IHDR: length (4) at 8, "IHDR" at 12, width and height at 16..24, its CRC at 29..33.
        png[16..24].copy_from_slice(&[0, 0, 0x75, 0x30, 0, 0, 0x75, 0x30]);
        let crc = crc32(&png[12..29]);
        png[29..33].copy_from_slice(&crc.to_be_bytes());
        let e = decode_png(&png).unwrap_err().to_string();
        assert!(e.contains("30000x30000"), "{e}");
    }
}
