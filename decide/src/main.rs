//! `deckwatch-decide`: the decide stage. Sleeps until estimate publishes an attitude, decides,
//! publishes the `LandingDecision`; when attitudes stop coming, its watchdog publishes a stale
//! decision (never `ClearToLand`). Runs until SIGINT/SIGTERM.

use clap::Parser;
use deckwatch_common::bus::{event_loop, quiet_logging, Bus, BusError, Flow, StageArgs, Wake};
use deckwatch_common::messages::{monotonic_ns, AttitudeMessage, LandingDecision};
use deckwatch_decide::stage::{config_from_toml, DecideStage};
use deckwatch_viz::{Item, ItemKind, Logger, RerunConfig};
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
    let logger = Logger::start(&RerunConfig::from_toml(&file, &text)?, "decide")?;
    let mut last_logged = None;
    let mut log = |d: &LandingDecision| {
        let Some(l) = &logger else { return };
        let item = |kind| Item {
            seq: d.stamp.seq,
            captured_ns: d.stamp.times.captured_ns,
            kind,
        };
        l.log(item(ItemKind::Scalars(vec![
            ("decision/state".into(), d.state as u32 as f64),
            ("decision/calm_window/start_s".into(), d.calm_window_start_s),
            ("decision/calm_window/length_s".into(), d.calm_window_length_s),
        ])));
        // The text log only on a change: the plot has every decision.
        if last_logged != Some((d.state, d.reason)) {
            last_logged = Some((d.state, d.reason));
            l.log(item(ItemKind::Text(format!(
                "{} ({})",
                d.state.name(),
                d.reason.name()
            ))));
        }
    };
    quiet_logging();
    let bus = Bus::join(&bus_config.settings(1), "decide").map_err(|e| e.to_string())?;
    let input = bus.subscriber::<AttitudeMessage>().map_err(|e| e.to_string())?;
    let output = bus.publisher::<LandingDecision>().map_err(|e| e.to_string())?;
    let period = stage.watchdog_period();
    event_loop(&[input.listener()], Some(period), |wake| {
        if wake == Wake::Tick {
            if let Some(stale) = stage.watchdog(monotonic_ns()) {
                output.send(&stale)?;
                log(&stale);
            }
        }
        while let Some(a) = input.receive()? {
            let d = stage.process(&a, monotonic_ns());
            output.send(&d)?;
            log(&d);
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
