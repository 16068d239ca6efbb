//! `deckwatch-capture`: the capture stage. Takes frames from the configured source (simulator,
//! replay or a libcamera camera), writes each straight into a loaned iceoryx2 sample and
//! publishes it, paced at the source's rate (a camera paces itself). If it falls behind, the
//! frames whose time has passed are skipped and counted, as a camera would drop them; a camera's
//! own sequence gaps count the same way. Exits when the source is exhausted or on SIGINT/SIGTERM.

use clap::Parser;
use deckwatch_capture::source::CaptureConfig;
use deckwatch_common::bus::{quiet_logging, Bus, PublishError, StageArgs};
use deckwatch_common::messages::{
    monotonic_ns, DropCounts, FrameContext, FrameHeader, FrameStamp, PixelFormat, StageTimes, Truth,
};
use deckwatch_viz::{Item, ItemKind, Logger, RerunConfig};
use std::process::ExitCode;
use std::time::Duration;

/// How long capture keeps its frames available after the source is exhausted.
const LINGER_MS: u64 = 1000;

#[derive(Parser)]
#[command(
    version,
    about = "deckwatch capture stage: frames into iceoryx2 shared memory"
)]
struct Args {
    #[command(flatten)]
    stage: StageArgs,
}

fn run(a: Args) -> Result<(), String> {
    let (file, text) = a.stage.read_config()?;
    let config = CaptureConfig::from_toml(&file, &text)?;
    let bus_config = a.stage.bus_config(&file, &text)?;
    let logger = Logger::start(&RerunConfig::from_toml(&file, &text)?, "capture")?;
    let mut source = config.open()?;
    eprintln!("deckwatch-capture: {}", source.describe());
    let camera = *source.camera();
    let deck = *source.deck();
    let (width, height) = (camera.width, camera.height);
    quiet_logging();
    let bus = Bus::join(&bus_config.settings(source.frame_bytes()), "capture").map_err(|e| e.to_string())?;
    let publisher = bus.frame_publisher().map_err(|e| e.to_string())?;

    let start = monotonic_ns();
    let mut drops = DropCounts::default();
    let (mut seq, mut k) = (0u64, 0u64);
    loop {
        if source.len().is_some_and(|n| k >= n) {
            break;
        }
        // A camera: wait for its next frame, in slices so that a stop request is seen.
        if !source.wait_ready(Duration::from_millis(100))? {
            if !bus.sleep(Duration::ZERO) {
                break;
            }
            continue;
        }
        // Pace: sleep (signal-aware) until frame k is due; skip frames whose time has passed.
        if let Some(due) = source.due_ns(k) {
            let now = monotonic_ns() - start;
            if now < due {
                if !bus.sleep(Duration::from_nanos(due - now)) {
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
        let header = FrameHeader {
            stamp: FrameStamp {
                seq,
                times: StageTimes {
                    captured_ns: monotonic_ns(),
                    ..Default::default()
                },
                drops,
            },
            context: FrameContext {
                source: source.kind(),
                camera,
                deck,
                ..Default::default()
            },
            width,
            height,
            stride: width,
            pixel_format: PixelFormat::Gray8,
        };
        let frame = k;
        let mut logged = None;
        let mut lost_before = 0;
        let result = publisher.publish(header, |h, pixels| {
            let f = source.capture(frame, pixels, width as usize)?;
            if let Some(t) = f.captured_ns {
                h.stamp.times.captured_ns = t;
            }
            lost_before = f.dropped_before;
            h.stamp.drops.capture += f.dropped_before;
            h.context.source_index = f.source_index;
            h.context.source_timestamp_ns = f.source_timestamp_ns;
            h.context.altitude_m = f.altitude_m.unwrap_or(f64::NAN);
            h.context.truth = Truth::from_ground_truth(&f.truth, f.truth_known);
            // For the viewer: the truth, and a downscaled copy of the image taken before the
            // frame is sent.
            if let Some(l) = &logger {
                let t = h.stamp.times.captured_ns;
                let image = l
                    .wants_image(seq)
                    .then(|| l.image(seq, t, pixels, width as usize, height as usize, width as usize));
                logged = Some((t, image, h.context.truth));
            }
            Ok::<(), String>(())
        });
        match result {
            Ok(_) => {
                drops.capture += lost_before;
                if let (Some(l), Some((t, image, truth))) = (&logger, logged) {
                    if let Some(image) = image {
                        l.log(image);
                    }
                    if truth.known {
                        let values = [
                            ("roll", truth.roll_deg),
                            ("pitch", truth.pitch_deg),
                            ("yaw", truth.yaw_deg),
                        ];
                        l.log(Item {
                            seq,
                            captured_ns: t,
                            kind: ItemKind::Scalars(
                                values
                                    .iter()
                                    .map(|(a, v)| (format!("attitude/{a}/truth"), *v))
                                    .collect(),
                            ),
                        });
                    }
                }
                seq += 1
            }
            Err(PublishError::NoSample(e)) => {
                drops.capture += 1;
                eprintln!("deckwatch-capture: frame {frame} dropped: {e}");
            }
            Err(PublishError::Fill(e)) => {
                drops.bad_frames += 1;
                eprintln!("deckwatch-capture: frame {frame} skipped: {e}");
            }
            Err(e) => return Err(e.to_string()),
        }
        k += 1;
    }
    // Frames still queued vanish with the publisher: give the consumers time to take them.
    if source.len().is_some_and(|n| k >= n) {
        bus.sleep(Duration::from_millis(LINGER_MS));
    }
    eprintln!(
        "deckwatch-capture: {seq} frames published, {} dropped, {} bad; {} log items dropped",
        drops.capture,
        drops.bad_frames,
        logger.as_ref().map_or(0, |l| l.dropped())
    );
    Ok(())
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("deckwatch-capture: {e}");
            ExitCode::FAILURE
        }
    }
}
