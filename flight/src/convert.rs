//! A flight recording to a recording folder (`camera.json`, `frames.csv` with the truth and
//! vehicle columns, PNGs). The other way, folder to MCAP, replays the folder through capture's
//! own replay source (`deckwatch convert` in `cli`), so that both directions share one
//! definition of a frame's header.

use crate::reader::{read_frames, FlightReader, FlightRecord};
use crate::writer::{FlightWriter, WriterOptions};
use crate::FlightError;
use deckwatch_common::image::GrayView;
use deckwatch_formats::recording::{FrameRecord, Recording, RecordingWriter, TruthColumns, NO_TRUTH};
use std::path::Path;

/// What a conversion wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Converted {
    pub frames: u64,
    /// Where a killed writer's file ended (everything before it was converted).
    pub ended_early: Option<String>,
}

/// A flight recording's frames as a recording (what replay takes): camera and deck of the
/// first frame, a row per frame with pixels (index: the frame's sequence number; timestamp: its
/// source timestamp; truth and the vehicle's attitude as columns), the pixels in order, and
/// where a killed writer's file ended. `max_bytes` bounds the pixels held.
pub fn recording_of(mcap: &Path, max_bytes: u64) -> Result<ReplayableFlight, FlightError> {
    let (frames, ended_early) = read_frames(mcap, max_bytes)?;
    let Some(first) = frames.first() else {
        return Err(FlightError::file(mcap, "holds no frame with pixels"));
    };
    let ctx = first.header.context;
    // The columns every frame can fill: truth when the source knew it, the vehicle's when any
    // frame carries one, the heave when any frame has it.
    let mut columns: TruthColumns = NO_TRUTH;
    let mut rows = Vec::with_capacity(frames.len());
    let mut images = Vec::with_capacity(frames.len());
    let mut last: Option<(u64, u64)> = None;
    for (k, f) in frames.into_iter().enumerate() {
        let h = &f.header;
        let c = &h.context;
        if (c.camera, c.deck) != (ctx.camera, ctx.deck) {
            return Err(FlightError::file(
                mcap,
                format!(
                    "frame {} has another camera or deck than the first frame",
                    h.stamp.seq
                ),
            ));
        }
        let (index, timestamp_ns) = (h.stamp.seq, c.source_timestamp_ns);
        if last.is_some_and(|(i, t)| index <= i || timestamp_ns < t) {
            return Err(FlightError::file(
                mcap,
                format!("frame {index} at {timestamp_ns} ns does not follow the frame before it"),
            ));
        }
        last = Some((index, timestamp_ns));
        let g = c.ground_truth();
        if c.truth.known.get() {
            columns[..6].iter_mut().for_each(|on| *on = true);
        }
        if g.vehicle_roll_deg.is_some() {
            columns[6..9].iter_mut().for_each(|on| *on = true);
        }
        if g.vehicle_height_m.is_some() || g.deck_heave_m.is_some() {
            columns[9..11].iter_mut().for_each(|on| *on = true);
        }
        if g.vehicle_rate_dps().is_some() {
            columns[11..14].iter_mut().for_each(|on| *on = true);
        }
        rows.push(FrameRecord {
            index,
            timestamp_ns,
            file: String::new(),
            truth: g,
            line: k as u64 + 1,
        });
        images.push(f.pixels);
    }
    let recording = Recording {
        dir: mcap.to_path_buf(),
        camera: ctx.camera,
        deck: ctx.deck,
        frames: rows,
        truth_columns: columns,
        vehicle_samples: None,
    };
    Ok(ReplayableFlight {
        recording,
        images,
        ended_early,
    })
}

/// A flight recording's frames as replay takes them ([`recording_of`]).
#[derive(Debug, Clone)]
pub struct ReplayableFlight {
    pub recording: Recording,
    /// Each frame's pixels (packed rows), in the recording's frame order.
    pub images: Vec<Vec<u8>>,
    /// Where a killed writer's file ended.
    pub ended_early: Option<String>,
}

/// Writes every frame of `mcap` that has pixels into the new recording folder `dir`.
pub fn mcap_to_folder(mcap: &Path, dir: &Path, max_bytes: u64) -> Result<Converted, FlightError> {
    let ReplayableFlight {
        recording: rec,
        images,
        ended_early,
    } = recording_of(mcap, max_bytes)?;
    let err = |e: deckwatch_formats::recording::RecordingError| FlightError::file(dir, e);
    let mut writer = RecordingWriter::create(dir, &rec.camera, &rec.deck, rec.truth_columns).map_err(err)?;
    let (w, h) = (rec.camera.width as usize, rec.camera.height as usize);
    for (f, px) in rec.frames.iter().zip(&images) {
        let view = GrayView::new(px, w, h, w)
            .map_err(|e| FlightError::file(mcap, format!("frame {}: {e}", f.index)))?;
        writer
            .write_frame(f.index, f.timestamp_ns, view, &f.truth)
            .map_err(err)?;
    }
    let frames = writer.finish().map_err(err)?;
    Ok(Converted { frames, ended_early })
}

/// What [`recover`] kept.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Recovered {
    pub messages: u64,
    /// Where the cut file ended.
    pub ended_early: Option<String>,
}

/// Rewrites a recording whose writer was killed (no summary, maybe a cut chunk) as a complete
/// file: every message, metadata record and attachment up to the last complete chunk.
pub fn recover(src: &Path, dst: &Path, options: WriterOptions) -> Result<Recovered, FlightError> {
    let mut reader = FlightReader::open(src)?;
    let mut writer = FlightWriter::create(dst, options)?;
    let mut messages = 0;
    for record in reader.by_ref() {
        match record? {
            FlightRecord::Message(m) => {
                writer.write_recorded(&m)?;
                messages += 1;
            }
            FlightRecord::Metadata { name, entries } => writer.write_metadata(&name, entries)?,
            FlightRecord::Attachment {
                name,
                media_type,
                data,
                log_time,
            } => writer.attach_at(&name, &media_type, &data, log_time)?,
        }
    }
    writer.finish()?;
    Ok(Recovered {
        messages,
        ended_early: reader.ended_early.take(),
    })
}
