//! `deckwatch-estimate`: the estimate stage. Sleeps until detect publishes markers, estimates the
//! deck attitude of each marker set, publishes it to decide. Runs until SIGINT/SIGTERM.

use clap::Parser;
use deckwatch_common::bus::{event_loop, quiet_logging, Bus, BusError, Flow, StageArgs};
use deckwatch_common::messages::{monotonic_ns, AttitudeMessage, MarkerMessage};
use deckwatch_estimate::stage::{EstimateConfig, EstimateStage};
use std::process::ExitCode;

#[derive(Parser)]
#[command(version, about = "deckwatch estimate stage: deck attitude from markers")]
struct Args {
    #[command(flatten)]
    stage: StageArgs,
}

fn run(a: Args) -> Result<(), String> {
    let (file, text) = a.stage.read_config()?;
    let bus_config = a.stage.bus_config(&file, &text)?;
    let mut stage = EstimateStage::new(&EstimateConfig::from_toml(&file, &text)?, a.stage.restarted)?;
    quiet_logging();
    let bus = Bus::join(&bus_config.settings(1), "estimate").map_err(|e| e.to_string())?;
    let input = bus.subscriber::<MarkerMessage>().map_err(|e| e.to_string())?;
    let output = bus.publisher::<AttitudeMessage>().map_err(|e| e.to_string())?;
    event_loop(&[input.listener()], None, |_| {
        while let Some(m) = input.receive()? {
            output.send(&stage.process(&m, monotonic_ns()))?;
        }
        Ok::<Flow, BusError>(Flow::Continue)
    })
    .map_err(|e| e.to_string())?;
    eprintln!(
        "deckwatch-estimate: {} marker sets, {} attitudes, {} dropped",
        stage.processed, stage.estimated, stage.dropped
    );
    Ok(())
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("deckwatch-estimate: {e}");
            ExitCode::FAILURE
        }
    }
}
