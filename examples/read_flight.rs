//! Read a flight recording (the MCAP file `deckwatch run --record` writes): what each channel
//! holds, how the decision went, and the deck's attitude when it first cleared.
//!
//!     cargo run --example read_flight -- flight.mcap
//!
//! The same file opens in Foxglove Studio and in any MCAP reader; deckwatch's own messages are
//! JSON with a JSON Schema (every field).

use deckwatch_common::messages::DecisionState;
use deckwatch_flight::reader::FlightMessages;
use std::collections::BTreeMap;
use std::error::Error;
use std::path::Path;

/// What a flight recording says, in short.
#[derive(Debug, Default)]
struct FlightSummary {
    messages_per_channel: BTreeMap<String, u64>,
    decisions_per_state: BTreeMap<&'static str, u64>,
    /// The deck's roll and pitch (deg) on the first CLEAR, and when its frame was taken on the
    /// frames' own timeline (s; CONVENTIONS.md §8).
    first_clear: Option<([f64; 2], f64)>,
}

fn summarise(path: &Path) -> Result<FlightSummary, Box<dyn Error>> {
    let flight = FlightMessages::read(path)?;
    if let Some(where_) = &flight.ended_early {
        eprintln!("the writer was stopped: read up to {where_}");
    }
    let mut summary = FlightSummary {
        messages_per_channel: flight.counts.clone(),
        ..Default::default()
    };
    for d in &flight.decisions {
        *summary
            .decisions_per_state
            .entry(d.state.get().name())
            .or_insert(0) += 1;
        if d.state == DecisionState::ClearToLand && summary.first_clear.is_none() {
            let [roll, pitch, _] = d.attitude.rpy.to_degrees();
            summary.first_clear = Some(([roll, pitch], d.context.source_timestamp_ns as f64 / 1e9));
        }
    }
    Ok(summary)
}

fn main() -> Result<(), Box<dyn Error>> {
    let path = std::env::args().nth(1).ok_or("usage: read_flight FLIGHT.mcap")?;
    let s = summarise(Path::new(&path))?;
    for (channel, n) in &s.messages_per_channel {
        println!("{n:8}  {channel}");
    }
    for (state, n) in &s.decisions_per_state {
        println!("{n:8}  decisions {state}");
    }
    match s.first_clear {
        Some(([roll, pitch], t_s)) => {
            println!("first CLEAR at {t_s:.2} s: deck roll {roll:.2}, pitch {pitch:.2} deg")
        }
        None => println!("never CLEAR"),
    }
    Ok(())
}

#[test]
fn a_written_recording_reads_back() {
    use deckwatch_common::messages::LandingDecision;
    use deckwatch_common::Rpy;
    use deckwatch_flight::writer::{FlightWriter, WriterOptions};
    let dir = std::env::temp_dir().join(format!("deckwatch-example-flight-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("flight.mcap");
    let mut writer = FlightWriter::create(&path, WriterOptions::default()).unwrap();
    for k in 0..30u64 {
        let mut d = LandingDecision::default();
        d.stamp.seq = k;
        d.context.source_timestamp_ns = k * 100_000_000;
        d.stamp.times.captured_ns = 1_000_000_000 + k * 100_000_000;
        d.state = if k >= 20 {
            DecisionState::ClearToLand
        } else {
            DecisionState::Hold
        }
        .into();
        d.attitude.rpy = Rpy::from_degrees(0.1 * k as f64, -0.5, 0.0);
        writer.write(&d).unwrap();
    }
    writer.finish().unwrap();
    let s = summarise(&path).unwrap();
    assert_eq!(s.decisions_per_state.get("CLEAR"), Some(&10), "{s:?}");
    assert_eq!(s.decisions_per_state.get("HOLD"), Some(&20), "{s:?}");
    let ([roll, pitch], t_s) = s.first_clear.unwrap();
    assert!((roll - 2.0).abs() < 1e-9 && (pitch + 0.5).abs() < 1e-9);
    assert!((t_s - 2.0).abs() < 1e-12);
    assert_eq!(s.messages_per_channel.values().sum::<u64>(), 30);
    std::fs::remove_dir_all(&dir).unwrap();
}
