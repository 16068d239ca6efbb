//! Re-simulation: a recorded flight's frames through the stages again, in one process, on the
//! recording's own timing, so that the same build reproduces the recorded markers, attitudes and
//! decisions bit for bit, and a changed setting shows where the outputs part
//! (`deckwatch replay FILE.mcap --resim OUT.mcap`, then `deckwatch diff`).
//!
//! Each stage sees what it saw in the flight:
//! - detect, the frames it processed (those with a recorded marker message; the ones it passed
//!   over, latest-frame semantics, are passed over again), in order;
//! - estimate, the new marker messages in order, with the vehicle samples received by then;
//! - decide, the new attitudes and the watchdog's ticks, merged by their recorded times.
//!
//! Every input a stage takes from the clock is given its recorded value (the receipt time it is
//! stepped with), and every output's stage times are set to the recorded ones, so the messages
//! downstream are the flight's. What cannot be reproduced is said in [`Resimulation::gaps`]: a
//! processed frame whose pixels were not recorded (`frame_every`, drops) makes detect's tracking
//! differ from there on.

use crate::config::PipelineConfig;
use crate::stage::{Frame, RunError, Stage};
use crate::stages::{DecideStage, DetectStage, EstimateStage};
use deckwatch_common::messages::{AttitudeMessage, LandingDecision, MarkerMessage, PipelineStage};
use deckwatch_flight::reader::{FlightMessages, FlightReader, FlightRecord};
use deckwatch_flight::{topics, FlightError};
use std::collections::HashMap;
use std::path::Path;

/// What a re-simulation produced.
#[derive(Debug, Clone, Default)]
pub struct Resimulation {
    pub markers: Vec<MarkerMessage>,
    pub attitudes: Vec<AttitudeMessage>,
    pub decisions: Vec<LandingDecision>,
    /// Frames detect processed in the flight whose pixels are not in the recording.
    pub gaps: Vec<u64>,
}

/// Re-simulates `path` (read once for its messages, once streaming its frames) with the stages
/// of `config`.
pub fn resimulate(
    path: &Path,
    recorded: &FlightMessages,
    config: &PipelineConfig,
) -> Result<Resimulation, RunError> {
    let flight = |e: FlightError| RunError::Record(e.to_string());
    let mut detect = DetectStage::from_config(config, false)?;
    let mut estimate = EstimateStage::from_config(config, false)?;
    let mut decide = DecideStage::from_config(config, false)?;
    let mut out = Resimulation::default();

    // Detect: the frames it processed, streamed in file order.
    let processed: HashMap<u64, &MarkerMessage> = recorded.markers.iter().map(|m| (m.stamp.seq, m)).collect();
    let mut done = std::collections::HashSet::new();
    let mut pending = None;
    let mut reader = FlightReader::open(path).map_err(flight)?;
    for record in reader.by_ref() {
        let FlightRecord::Message(m) = record.map_err(flight)? else {
            continue;
        };
        match m.topic() {
            topics::FRAME => {
                pending = Some(
                    m.decode::<deckwatch_common::messages::FrameHeader>(path)
                        .map_err(flight)?,
                )
            }
            topics::IMAGE | topics::IMAGE_COMPRESSED => {
                let Some(mut header) = pending.take() else {
                    continue;
                };
                let Some(rec) = processed.get(&header.stamp.seq) else {
                    continue;
                };
                let (_, _, pixels) = m.decode_image(path).map_err(flight)?;
                header.stride = header.width;
                let frame = Frame {
                    header: &header,
                    pixels: &pixels,
                };
                let mut markers = detect.step(frame, rec.stamp.times[PipelineStage::Detect].received_ns);
                markers.stamp.times = rec.stamp.times;
                done.insert(header.stamp.seq);
                out.markers.push(markers);
            }
            _ => {}
        }
    }
    out.gaps = recorded
        .markers
        .iter()
        .map(|m| m.stamp.seq)
        .filter(|s| !done.contains(s))
        .collect();

    // Estimate: the markers in order, each with the vehicle samples received before it.
    let recorded_attitudes: HashMap<u64, &AttitudeMessage> =
        recorded.attitudes.iter().map(|a| (a.stamp.seq, a)).collect();
    let mut vehicle = recorded.vehicle.iter().peekable();
    for m in &out.markers {
        let Some(rec) = recorded_attitudes.get(&m.stamp.seq) else {
            continue;
        };
        let received = rec.stamp.times[PipelineStage::Estimate].received_ns;
        while let Some(s) = vehicle.next_if(|s| s.received_ns <= received) {
            estimate.observe_vehicle(s);
        }
        let mut a = estimate.step(m, received);
        a.stamp.times = rec.stamp.times;
        out.attitudes.push(a);
    }

    // Decide: the attitudes and the watchdog's ticks, by their recorded receipt times.
    let new_attitudes: HashMap<u64, &AttitudeMessage> =
        out.attitudes.iter().map(|a| (a.stamp.seq, a)).collect();
    for rec in &recorded.decisions {
        let received = rec.stamp.times[PipelineStage::Decide].received_ns;
        let d = if rec.watchdog.get() {
            decide.tick(received)
        } else {
            new_attitudes
                .get(&rec.stamp.seq)
                .map(|a| decide.step(a, received))
        };
        // As the process does once its decisions are out.
        decide.after_outputs();
        if let Some(mut d) = d {
            d.stamp.times = rec.stamp.times;
            out.decisions.push(d);
        }
    }
    Ok(out)
}

/// The pipeline configuration a recording was made with (its `pipeline.toml` attachment).
pub fn recorded_config(path: &Path) -> Result<Option<PipelineConfig>, RunError> {
    let mut reader = FlightReader::open(path).map_err(|e| RunError::Record(e.to_string()))?;
    for record in reader.by_ref() {
        if let FlightRecord::Attachment { name, data, .. } =
            record.map_err(|e| RunError::Record(e.to_string()))?
        {
            if name == "pipeline.toml" {
                // Held to the bound of a configuration file, not of an attachment.
                if data.len() as u64 > crate::config::MAX_CONFIG_FILE_BYTES {
                    return Err(RunError::Record(format!(
                        "{}: the attached pipeline.toml has {} bytes, more than the {} of a configuration",
                        path.display(),
                        data.len(),
                        crate::config::MAX_CONFIG_FILE_BYTES
                    )));
                }
                let text = String::from_utf8_lossy(&data);
                let file = format!("{} (attachment pipeline.toml)", path.display());
                return Ok(Some(PipelineConfig::from_toml(&file, &text)?));
            }
        }
    }
    Ok(None)
}
