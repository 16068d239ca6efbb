//! `deckwatch-decide`: the decide stage. Sleeps until estimate publishes an attitude, decides,
//! publishes the `LandingDecision`; when attitudes stop coming, its watchdog publishes a stale
//! decision (never `ClearToLand`). Runs until SIGINT/SIGTERM.

use clap::Parser;
use deckwatch_common::bus::{event_loop, quiet_logging, Bus, BusError, Flow, StageArgs, Wake};
use deckwatch_common::messages::{monotonic_ns, AttitudeMessage, LandingDecision};
use deckwatch_decide::stage::{config_from_toml, DecideStage};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    version,
    about = "deckwatch decide stage: landing decision from the deck attitude"
)]
struct Args {
    #[command(flatten)]
    stage: StageArgs,
}

fn run(a: Args) -> Result<(), String> {
    let (file, text) = a.stage.read_config()?;
    let bus_config = a.stage.bus_config(&file, &text)?;
    let mut stage = DecideStage::new(config_from_toml(&file, &text)?, a.stage.restarted)?;
    quiet_logging();
    let bus = Bus::join(&bus_config.settings(1), "decide").map_err(|e| e.to_string())?;
    let input = bus.subscriber::<AttitudeMessage>().map_err(|e| e.to_string())?;
    let output = bus.publisher::<LandingDecision>().map_err(|e| e.to_string())?;
    let period = stage.watchdog_period();
    event_loop(&[input.listener()], Some(period), |wake| {
        if wake == Wake::Tick {
            if let Some(stale) = stage.watchdog(monotonic_ns()) {
                output.send(&stale)?;
            }
        }
        while let Some(a) = input.receive()? {
            output.send(&stage.process(&a, monotonic_ns()))?;
        }
        Ok::<Flow, BusError>(Flow::Continue)
    })
    .map_err(|e| e.to_string())?;
    eprintln!(
        "deckwatch-decide: {} attitudes, {} dropped",
        stage.processed, stage.dropped
    );
    Ok(())
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("deckwatch-decide: {e}");
            ExitCode::FAILURE
        }
    }
}
