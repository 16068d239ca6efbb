//! The capture stage, the pipeline's source. Takes frames from the configured source
//! (simulator, replay or a libcamera camera), writes each straight into a loaned iceoryx2 sample
//! and publishes it, paced at the source's rate (a camera paces itself). If it falls behind, the
//! frames whose time has passed are skipped and counted, as a camera would drop them; a camera's
//! own sequence gaps count the same way. Exits when the source is exhausted or on SIGINT/SIGTERM.
//!
//! Capture is a [`Process`] but not a [`crate::stage::Stage`]: it has no input and writes into
//! memory it loans from the transport. What it puts in a frame's header is defined once here ([`new_header`],
//! [`complete_header`]) and used by the in-process chain too.

use crate::bus::PublishError;
use crate::config::PipelineConfig;
use crate::stage::{setup, Heartbeat, Process, RunError, StageArgs};
use deckwatch_capture::source::{CaptureSource, CapturedFrame, SourceError};
use deckwatch_common::messages::{
    monotonic_ns, Channel, DropCounts, FrameContext, FrameHeader, FrameStamp, PixelFormat, StageTimes, Truth,
    SOURCE,
};
use std::time::Duration;

/// The capture process, the pipeline's source.
pub struct Capture;

impl Process for Capture {
    const NAME: &'static str = SOURCE;
    const OUTPUTS: &'static [&'static str] = &[FrameHeader::SERVICE];
    fn inputs(_config: &PipelineConfig) -> Vec<&'static str> {
        Vec::new()
    }
    fn run(config: PipelineConfig, _args: &StageArgs) -> Result<String, RunError> {
        run(config)
    }
}

/// The process's name (node, binary `deckwatch-capture`, log lines).
pub const NAME: &str = <Capture as Process>::NAME;

/// How long capture keeps its frames available after the source is exhausted.
const LINGER_MS: u64 = 1000;

/// The header of frame `seq` of `source`, before its pixels are captured.
pub fn new_header(source: &CaptureSource, seq: u64, drops: DropCounts) -> FrameHeader {
    let camera = *source.camera();
    FrameHeader {
        stamp: FrameStamp {
            seq,
            times: StageTimes {
                captured_ns: monotonic_ns(),
                ..Default::default()
            },
            drops,
        },
        context: FrameContext {
            source: source.kind().into(),
            camera,
            deck: *source.deck(),
            ..Default::default()
        },
        width: camera.width,
        height: camera.height,
        stride: camera.width,
        pixel_format: PixelFormat::Gray8.into(),
    }
}

/// What the source told of the frame it captured, into its header.
pub fn complete_header(h: &mut FrameHeader, f: &CapturedFrame) {
    if let Some(t) = f.captured_ns {
        h.stamp.times.captured_ns = t;
    }
    h.stamp.drops.capture += f.dropped_before;
    h.context.source_index = f.source_index;
    h.context.source_timestamp_ns = f.source_timestamp_ns;
    h.context.altitude_m = f.altitude_m.unwrap_or(f64::NAN);
    h.context.truth = Truth::from_ground_truth(&f.truth, f.truth_known);
    h.context.vehicle = f.vehicle;
}

/// Capture's life in its process.
fn run(config: PipelineConfig) -> Result<String, RunError> {
    let mut source = config.capture().open()?;
    deckwatch_common::say!("deckwatch-capture: {}", source.describe());
    let (logger, bus) = setup(NAME, &config, source.frame_bytes())?;
    let publisher = bus.frame_publisher()?;
    let (width, height) = (source.camera().width as usize, source.camera().height as usize);

    let mut heartbeat = Heartbeat::new(&bus)?;
    // Sleeps (signal-aware) in slices short enough for the heartbeat; false on a stop request.
    let sleep = |d: Duration, heartbeat: &mut Heartbeat| {
        let end = monotonic_ns().saturating_add(d.as_nanos().min(u64::MAX as u128) as u64);
        loop {
            heartbeat.beat();
            let left = end.saturating_sub(monotonic_ns());
            if !bus.sleep(Duration::from_nanos(left).min(Heartbeat::PERIOD)) {
                return false;
            }
            if left <= Heartbeat::PERIOD.as_nanos() as u64 {
                return true;
            }
        }
    };
    let start = monotonic_ns();
    let mut drops = DropCounts::default();
    let (mut seq, mut k) = (0u64, 0u64);
    loop {
        heartbeat.beat();
        if source.len().is_some_and(|n| k >= n) {
            break;
        }
        // A camera: wait for its next frame, in slices so that a stop request is seen.
        if !source
            .wait_ready(Duration::from_millis(100))
            .map_err(RunError::Source)?
        {
            if !bus.sleep(Duration::ZERO) {
                break;
            }
            continue;
        }
        // Pace: sleep (signal-aware) until frame k is due; skip frames whose time has passed.
        if let Some(due) = source.due_ns(k) {
            let now = monotonic_ns() - start;
            if now < due {
                if !sleep(Duration::from_nanos(due - now), &mut heartbeat) {
                    break;
                }
            } else {
                while source.due_ns(k + 1).is_some_and(|next| next <= now)
                    && source.len().is_none_or(|n| k + 1 < n)
                {
                    k += 1;
                    drops.capture += 1;
                }
            }
        } else if !bus.sleep(Duration::ZERO) {
            break;
        }
        let header = new_header(&source, seq, drops);
        let frame = k;
        let mut logged = None;
        let mut lost_before = 0;
        let result = publisher.publish(header, |h, pixels| {
            let f = source.capture(frame, pixels, width)?;
            complete_header(h, &f);
            lost_before = f.dropped_before;
            // For the viewer: the truth, and a downscaled copy of the image taken before the
            // frame is sent.
            if let Some(l) = &logger {
                let t = h.stamp.times.captured_ns;
                let image = l
                    .wants_image(seq)
                    .then(|| l.image(seq, t, pixels, width, height, width));
                logged = Some((t, image, h.context.truth));
            }
            Ok::<(), SourceError>(())
        });
        match result {
            Ok(_) => {
                drops.capture += lost_before;
                if let (Some(l), Some((t, image, truth))) = (&logger, logged) {
                    image.into_iter().for_each(|i| l.log(i));
                    for item in deckwatch_viz::entities::truth_items(seq, t, &truth) {
                        l.log(item);
                    }
                }
                seq += 1
            }
            Err(PublishError::NoSample(e)) => {
                drops.capture += 1;
                deckwatch_common::say!("deckwatch-capture: frame {frame} dropped: {e}");
            }
            Err(PublishError::Fill(e)) => {
                drops.bad_frames += 1;
                deckwatch_common::say!("deckwatch-capture: frame {frame} skipped: {e}");
            }
            Err(e) => return Err(RunError::Publish(e.to_string())),
        }
        k += 1;
    }
    // Frames still queued vanish with the publisher: give the consumers time to take them.
    if source.len().is_some_and(|n| k >= n) {
        sleep(Duration::from_millis(LINGER_MS), &mut heartbeat);
    }
    Ok(format!(
        "{seq} frames published, {} dropped, {} bad; {} log items dropped",
        drops.capture,
        drops.bad_frames,
        logger.as_ref().map_or(0, |l| l.dropped())
    ))
}
