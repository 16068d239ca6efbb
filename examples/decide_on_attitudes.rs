//! The landing decision on a ship's motion from a CSV file (`time_s,roll_deg,pitch_deg,heave_m`,
//! docs/recording.md, "Ship motion from a file"), sampled at 10 Hz as a camera would see it: when it first
//! clears, and what it said how often. The decider alone: the same calls the decide stage makes.
//!
//!     cargo run --example decide_on_attitudes -- ship.csv
//!
//! Without a file it writes and reads a calm swell of its own.

use deckwatch_common::messages::DecisionState;
use deckwatch_decide::{DecisionConfig, DeckObservation, FrameInput, LandingDecider};
use deckwatch_sim::motion::MotionProfile;
use deckwatch_sim::motion_file::RecordedShipMotion;
use std::collections::BTreeMap;
use std::error::Error;
use std::path::Path;

/// The decisions on a motion: the first clearance's time (s) and the count of each state and
/// reason.
type Decisions = (Option<f64>, BTreeMap<String, u64>);

/// The decisions on the motion in `csv`.
fn decide_on(csv: &Path) -> Result<Decisions, Box<dyn Error>> {
    let motion = RecordedShipMotion::load(csv)?;
    let mut decider = LandingDecider::new(DecisionConfig::default())?;
    let (mut first_clear_s, mut counts) = (None, BTreeMap::new());
    let rate_hz = 10.0;
    for k in 0..(motion.duration_s() * rate_hz) as usize {
        let t_s = k as f64 / rate_hz;
        let sample = motion.sample(t_s);
        let [roll_deg, pitch_deg, _] = sample.attitude.to_degrees();
        // A fresh measurement, 5 ms old when decided on.
        let frame = FrameInput::measured(
            t_s,
            Some(DeckObservation::new(roll_deg, pitch_deg, sample.deck_heave_m)),
            0.005,
        );
        let d = decider.decide_frame(&frame);
        decider.refit_between_frames();
        if d.state == DecisionState::ClearToLand && first_clear_s.is_none() {
            first_clear_s = Some(t_s);
        }
        *counts
            .entry(format!("{} {}", d.state.name(), d.reason.name()))
            .or_insert(0) += 1;
    }
    Ok((first_clear_s, counts))
}

/// Two minutes of a calm swell (roll 1 deg, pitch 0.5 deg, heave 0.2 m) as a motion file.
fn write_calm_swell(path: &Path) -> std::io::Result<()> {
    let mut csv = String::from("time_s,roll_deg,pitch_deg,heave_m\n");
    for k in 0..=1200 {
        let t = k as f64 * 0.1;
        let tau = std::f64::consts::TAU;
        csv += &format!(
            "{t:.1},{:.5},{:.5},{:.5}\n",
            (tau * t / 9.0).sin(),
            0.5 * (tau * t / 6.0).sin(),
            0.2 * (tau * t / 9.5).sin()
        );
    }
    std::fs::write(path, csv)
}

fn main() -> Result<(), Box<dyn Error>> {
    let (first_clear_s, counts) = match std::env::args().nth(1) {
        Some(p) => decide_on(Path::new(&p))?,
        None => {
            let p = std::env::temp_dir().join(format!("deckwatch-calm-swell-{}.csv", std::process::id()));
            write_calm_swell(&p)?;
            let decided = decide_on(&p);
            std::fs::remove_file(&p)?;
            decided?
        }
    };
    match first_clear_s {
        Some(t) => println!("first CLEAR at {t:.1} s"),
        None => println!("never CLEAR"),
    }
    for (what, n) in counts {
        println!("{n:6}  {what}");
    }
    Ok(())
}

#[test]
fn a_calm_swell_clears_and_a_broken_file_says_where() {
    let dir = std::env::temp_dir().join(format!("deckwatch-example-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let calm = dir.join("calm.csv");
    write_calm_swell(&calm).unwrap();
    let (first_clear_s, counts) = decide_on(&calm).unwrap();
    assert!(
        first_clear_s.is_some_and(|t| t < 60.0),
        "{first_clear_s:?} {counts:?}"
    );
    let broken = dir.join("broken.csv");
    std::fs::write(&broken, "time_s,roll_deg,pitch_deg,heave_m\n0,1,x,0\n").unwrap();
    let e = decide_on(&broken).unwrap_err().to_string();
    assert!(e.contains("broken.csv:2"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
