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

// The bounds of what one file may make the reader hold, checked against each length field
// before what it claims is allocated: a corrupt or crafted length must not allocate the machine
// away. Each is well beyond what a deckwatch recorder writes.
/// The largest message (bytes): a raw frame of the most pixels deckwatch reads
/// (`camera::MAX_IMAGE_PIXELS`), with room for its other fields.
pub const MAX_MESSAGE_BYTES: usize = deckwatch_common::camera::MAX_IMAGE_PIXELS as usize + (1 << 20);
/// The largest record (bytes), a chunk decompressed included: the largest chunk a recorder
/// writes (`[record] chunk_mib`, at most [`crate::config::MAX_CHUNK_MIB`]) and the message
/// that filled it. The MCAP reader allocates a chunk's buffer from its header's size.
pub const MAX_RECORD_BYTES: usize = ((crate::config::MAX_CHUNK_MIB as usize) << 20) + MAX_MESSAGE_BYTES;
/// The largest schema, channel or metadata record (bytes): deckwatch's largest schema is ~4 KB.
pub const MAX_DECLARATION_BYTES: usize = 64 << 10;
/// The most schemas, channels and metadata records a file may have (each is kept while the
/// file is read): deckwatch writes ten or so.
pub const MAX_DECLARATIONS: usize = 256;
/// The largest attachment (bytes): deckwatch attaches its pipeline configuration, at most 1 MiB.
pub const MAX_ATTACHMENT_BYTES: usize = 16 << 20;
/// The largest JSON message decoded (bytes): deckwatch's are ~1 KB, and parsing JSON holds up to
/// ~16 times its bytes.
pub const MAX_JSON_MESSAGE_BYTES: usize = 1 << 20;

/// The bound on a record of `opcode` (outside a chunk or in one), and what the record is.
fn record_bound(opcode: u8) -> (usize, &'static str) {
    use mcap::records::op;
    match opcode {
        op::MESSAGE => (MAX_MESSAGE_BYTES, "message"),
        op::SCHEMA => (MAX_DECLARATION_BYTES, "schema"),
        op::CHANNEL => (MAX_DECLARATION_BYTES, "channel"),
        op::METADATA => (MAX_DECLARATION_BYTES, "metadata"),
        op::ATTACHMENT => (MAX_ATTACHMENT_BYTES, "attachment"),
        _ => (MAX_RECORD_BYTES, "record"),
    }
}

/// A recording opened for reading; an iterator over its records.
pub struct FlightReader {
    path: PathBuf,
    file: File,
    reader: LinearReader,
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    channels: HashMap<u16, Arc<ChannelInfo>>,
    metadata_records: usize,
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
                .with_record_length_limit(MAX_RECORD_BYTES),
        );
        Ok(Self {
            path: path.to_path_buf(),
            file,
            reader,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            metadata_records: 0,
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

    /// Reading ends with an error: the file passes a bound (not a killed writer's cut).
    fn refuse(&mut self, problem: String) -> Option<Result<FlightRecord, FlightError>> {
        self.done = true;
        Some(Err(FlightError::file(&self.path, problem)))
    }
}

/// Whether a file that declared `known` schemas, channels or metadata records may declare one
/// more.
fn check_declarations(path: &Path, kind: &str, known: usize) -> Result<(), FlightError> {
    if known >= MAX_DECLARATIONS {
        return Err(FlightError::file(
            path,
            format!("more than {MAX_DECLARATIONS} {kind} records, the most deckwatch reads"),
        ));
    }
    Ok(())
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
                // A length beyond the bounds is refused from the length, before its buffer.
                Some(Err(mcap::McapError::RecordTooLarge { opcode, len })) => {
                    return self.refuse(format!(
                        "a record (opcode {opcode:#04x}) of {len} bytes, more than the \
                         {MAX_RECORD_BYTES} bytes deckwatch reads in one record"
                    ))
                }
                Some(Err(mcap::McapError::ChunkTooLarge(len))) => {
                    return self.refuse(format!(
                        "a chunk of {len} bytes, more than the {MAX_RECORD_BYTES} bytes deckwatch \
                         reads in one chunk"
                    ))
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
            let (max_bytes, kind) = record_bound(opcode);
            if data.len() > max_bytes {
                let len = data.len();
                return self.refuse(format!(
                    "a {kind} record of {len} bytes, more than the {max_bytes} bytes deckwatch reads in one"
                ));
            }
            let record = match mcap::parse_record(opcode, data) {
                Ok(r) => r,
                Err(e) => {
                    let why = format!("a bad record (opcode {opcode:#x}): {e}");
                    return self.stop(why);
                }
            };
            match record {
                Record::Schema { header, data } => {
                    if !self.schemas.contains_key(&header.id) {
                        if let Err(e) = check_declarations(&self.path, "schema", self.schemas.len()) {
                            self.done = true;
                            return Some(Err(e));
                        }
                    }
                    self.schemas
                        .insert(header.id, (header.name, header.encoding, data.into_owned()));
                }
                Record::Channel(c) => {
                    if !self.channels.contains_key(&c.id) {
                        if let Err(e) = check_declarations(&self.path, "channel", self.channels.len()) {
                            self.done = true;
                            return Some(Err(e));
                        }
                    }
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
                    if let Err(e) = check_declarations(&self.path, "metadata", self.metadata_records) {
                        self.done = true;
                        return Some(Err(e));
                    }
                    self.metadata_records += 1;
                    return Some(Ok(FlightRecord::Metadata {
                        name: m.name,
                        entries: m.metadata,
                    }));
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
        if self.data.len() > MAX_JSON_MESSAGE_BYTES {
            return Err(self.error(
                path,
                format!(
                    "{} bytes of JSON, more than the {MAX_JSON_MESSAGE_BYTES} deckwatch decodes",
                    self.data.len()
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

    /// An MCAP file of `records` (opcode, body) after the magic and an empty header record.
    fn mcap_of(records: &[(u8, Vec<u8>)]) -> Vec<u8> {
        let mut file = mcap::MAGIC.to_vec();
        // Header: profile and library, two empty strings.
        let mut all = vec![(mcap::records::op::HEADER, vec![0u8; 8])];
        all.extend_from_slice(records);
        for (opcode, body) in all {
            file.push(opcode);
            file.extend_from_slice(&(body.len() as u64).to_le_bytes());
            file.extend_from_slice(&body);
        }
        file
    }

    fn read_all(dir: &Path, bytes: &[u8]) -> Result<usize, FlightError> {
        let path = dir.join("crafted.mcap");
        std::fs::write(&path, bytes).unwrap();
        FlightReader::open(&path)?.try_fold(0, |n, r| r.map(|_| n + 1))
    }

    /// Lengths that claim more than the bounds are refused from the length, as errors that name
    /// the file and the size: before a buffer of that size is allocated, not read as a file that
    /// ends early.
    #[test]
    fn lengths_beyond_the_bounds_are_refused_before_their_buffers() {
        let dir = tempfile::tempdir().unwrap();
        let huge: u64 = 10 << 30;
        // A record claiming 10 GiB, in a file of a few bytes.
        let mut file = mcap_of(&[]);
        file.push(mcap::records::op::MESSAGE);
        file.extend_from_slice(&huge.to_le_bytes());
        file.extend_from_slice(&[0; 32]);
        let e = read_all(dir.path(), &file).unwrap_err().to_string();
        assert!(
            e.contains("crafted.mcap") && e.contains("10737418240 bytes"),
            "{e}"
        );
        assert!(e.contains(&MAX_RECORD_BYTES.to_string()), "{e}");
        // A zstd chunk whose header claims 10 GiB decompressed (the reader would allocate it).
        let mut chunk = Vec::new();
        chunk.extend_from_slice(&0u64.to_le_bytes()); // message start time
        chunk.extend_from_slice(&0u64.to_le_bytes()); // message end time
        chunk.extend_from_slice(&huge.to_le_bytes()); // uncompressed size
        chunk.extend_from_slice(&1u32.to_le_bytes()); // uncompressed CRC (checked first)
        chunk.extend_from_slice(&4u32.to_le_bytes());
        chunk.extend_from_slice(b"zstd");
        chunk.extend_from_slice(&16u64.to_le_bytes()); // compressed size
        chunk.extend_from_slice(&[0; 16]);
        let e = read_all(dir.path(), &mcap_of(&[(mcap::records::op::CHUNK, chunk)]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("a chunk of 10737418240 bytes"), "{e}");
        // A schema of 100 KB (deckwatch's are ~4 KB), within the record bound.
        let mut schema = 1u16.to_le_bytes().to_vec();
        schema.extend_from_slice(&[0; 8]); // name and encoding, empty
        schema.extend_from_slice(&100_000u32.to_le_bytes());
        schema.extend_from_slice(&vec![b'x'; 100_000]);
        let e = read_all(dir.path(), &mcap_of(&[(mcap::records::op::SCHEMA, schema)]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("a schema record of 100014 bytes"), "{e}");
        // More channels than a recording declares.
        let channels: Vec<_> = (0..=MAX_DECLARATIONS as u16)
            .map(|id| {
                let mut c = id.to_le_bytes().to_vec();
                c.extend_from_slice(&[0; 2 + 4 + 4 + 4]); // schema id, topic, encoding, metadata
                (mcap::records::op::CHANNEL, c)
            })
            .collect();
        let e = read_all(dir.path(), &mcap_of(&channels)).unwrap_err().to_string();
        assert!(e.contains("more than 256 channel records"), "{e}");
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
