//! `deckwatch-detect`: the detect stage. Sleeps until capture publishes a frame, reads the newest
//! frame in place in shared memory (older queued frames are skipped and counted), publishes the
//! markers to estimate. Runs until SIGINT/SIGTERM.

use clap::Parser;
use deckwatch_common::bus::{event_loop, quiet_logging, Bus, BusError, Flow, StageArgs};
use deckwatch_common::messages::{monotonic_ns, MarkerMessage};
use deckwatch_detect::stage::DetectStage;
use deckwatch_viz::{Item, ItemKind, Logger, RerunConfig};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    version,
    about = "deckwatch detect stage: markers from frames in shared memory"
)]
struct Args {
    #[command(flatten)]
    stage: StageArgs,
}

fn run(a: Args) -> Result<(), String> {
    let (file, text) = a.stage.read_config()?;
    let bus_config = a.stage.bus_config(&file, &text)?;
    let logger = Logger::start(&RerunConfig::from_toml(&file, &text)?, "detect")?;
    quiet_logging();
    // The subscriber side does not size frames; 1 is a placeholder the publisher never sees.
    let bus = Bus::join(&bus_config.settings(1), "detect").map_err(|e| e.to_string())?;
    let frames = bus.frame_subscriber().map_err(|e| e.to_string())?;
    let output = bus.publisher::<MarkerMessage>().map_err(|e| e.to_string())?;
    let mut stage = DetectStage::new(a.stage.restarted);
    event_loop(&[frames.listener()], None, |_| {
        while let Some((frame, _passed_over)) = frames.receive_latest()? {
            let received = monotonic_ns();
            let (message, problem) = stage.process(frame.header(), frame.pixels(), received);
            drop(frame); // release the shared-memory frame before publishing
            if let Some(p) = problem {
                eprintln!("deckwatch-detect: bad {p}");
            }
            output.send(&message)?;
            if let Some(l) = &logger {
                l.log(markers_item(&message));
            }
        }
        Ok::<Flow, BusError>(Flow::Continue)
    })
    .map_err(|e| e.to_string())?;
    eprintln!(
        "deckwatch-detect: {} frames processed, {} dropped, {} bad",
        stage.processed, stage.dropped, stage.bad_frames
    );
    Ok(())
}

/// The detected markers as labelled points for the viewer.
fn markers_item(m: &MarkerMessage) -> Item {
    let (mut points, mut labels) = (Vec::new(), Vec::new());
    for (i, mk) in m.markers.markers.iter().enumerate().filter(|(_, mk)| mk.valid) {
        points.push([mk.u as f32, mk.v as f32]);
        labels.push(match i {
            0 => "centre".to_string(),
            1 => "bow".to_string(),
            k => format!("ring {k}"),
        });
    }
    Item {
        seq: m.stamp.seq,
        captured_ns: m.stamp.times.captured_ns,
        kind: ItemKind::Points {
            entity: "camera/image/markers",
            points,
            labels,
        },
    }
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("deckwatch-detect: {e}");
            ExitCode::FAILURE
        }
    }
}
