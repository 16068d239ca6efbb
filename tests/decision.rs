//! The landing decision against the true deck motion over long simulated series (30 min at
//! 10 Hz; irregular, regular and wave-spectrum seas; noise, dropped frames, outliers and faults):
//! the state machine never clears a landing during which the true deck leaves the capacity, and
//! still lands; the naive rule ("current angles within the limits") does clear unsafe ones.
//! Through the `deckwatch decide-eval` command (its JSON output).

use deckwatch_tests::workspace_binary;
use std::process::Command;

fn eval(args: &[&str]) -> Vec<serde_json::Value> {
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["decide-eval", "--json", "--minutes", "30"])
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn check(series: &[serde_json::Value]) {
    for s in series {
        let (smart, naive) = (&s["state_machine"], &s["naive"]);
        assert_eq!(smart["unsafe_commits"], 0, "unsafe clearance: {s}");
        assert!(naive["unsafe_commits"].as_u64().unwrap() > 0, "{s}");
        assert!(
            smart["calm_windows_used"].as_u64().unwrap() > 0,
            "never lands: {s}"
        );
        assert_eq!(s["frames"], 18000);
    }
}

#[test]
fn irregular_seas_no_unsafe_clearance() {
    check(&eval(&[
        "--motion",
        "irregular",
        "--sea-states",
        "4,5",
        "--seeds",
        "1,3",
    ]));
}

#[test]
fn regular_seas_no_unsafe_clearance() {
    check(&eval(&[
        "--motion",
        "regular",
        "--sea-states",
        "4,5,6",
        "--seeds",
        "2",
    ]));
}

/// Seas that are not the predictor's model (a JONSWAP spectrum through a ship response, with a
/// wandering heading), with faults on top: NaN, stale and frozen input, timing jitter, and a
/// swaying vehicle whose autopilot stream is biased, late and interrupted. Still no unsafe
/// clearance, and still landings at sea states 3 and 4.
#[test]
fn spectrum_seas_with_faults_no_unsafe_clearance() {
    check(&eval(&[
        "--motion",
        "jonswap",
        "--sea-states",
        "3,4",
        "--seeds",
        "1",
        "--nan-share",
        "0.01",
        "--stale-share",
        "0.01",
        "--frozen-per-min",
        "1",
        "--frozen-s",
        "3",
        "--jitter-ms",
        "5",
        "--vehicle",
        "sway",
        "--vehicle-noise-deg",
        "0.2",
        "--vehicle-bias-deg",
        "0.3,-0.3",
        "--vehicle-time-error-ms",
        "5",
        "--vehicle-outages-per-min",
        "2",
    ]));
}

/// The default scenario (`lulls`) shows the decision's whole cycle within the README's 60 s
/// run: HOLD while warming up, CLEAR in the lull, HOLD again once the sea builds; and every
/// clearance is safe on the true motion. On the true angles (with the estimator's noise), the
/// way the decide stage sees them; the pipeline run itself is in tests/pipeline.rs.
#[test]
fn lulls_scenario_shows_the_whole_cycle() {
    use deckwatch_common::messages::{DecisionReason, DecisionState};
    use deckwatch_decide::{DecisionConfig, DeckObservation, LandingDecider};
    use deckwatch_sim::{MotionProfile, Scenario};
    let config = DecisionConfig::default();
    for seed in [1, 2, 3] {
        let profile = Scenario::Lulls.profile(seed, 1.0);
        let mut decider = LandingDecider::new(config.clone()).unwrap();
        let mut changes: Vec<(f64, DecisionState, DecisionReason)> = Vec::new();
        let rate_hz = 10.0;
        let mut noise = 0.0f64;
        for k in 0..600 {
            let t = k as f64 / rate_hz;
            let s = profile.sample(t);
            let [roll, pitch, _] = s.attitude.to_degrees();
            // A deterministic +-0.02 deg wobble standing in for the estimator's noise.
            noise = (noise * 1.7 + 0.37).fract();
            let e = 0.04 * (noise - 0.5);
            let d = decider.update(t, Some(DeckObservation::new(roll + e, pitch - e, e)), t + 0.005);
            if changes.last().is_none_or(|c| (c.1, c.2) != (d.state, d.reason)) {
                changes.push((t, d.state, d.reason));
            }
            if d.new_commit {
                // The true deck stays within the capacity during the whole touchdown.
                for j in 0..=20 {
                    let u = profile.sample(t + j as f64 * config.touchdown_s / 20.0);
                    let [r, p, _] = u.attitude.to_degrees();
                    assert!(
                        config.naive_within(r, p),
                        "seed {seed}: unsafe clearance at {t} s ({r:.2}, {p:.2} deg)"
                    );
                }
            }
        }
        let timeline: Vec<String> = changes
            .iter()
            .map(|(t, s, r)| format!("{t:.1}s {} ({})", s.name(), r.name()))
            .collect();
        println!("seed {seed}: {}", timeline.join(" -> "));
        let first_clear = changes
            .iter()
            .position(|c| c.1 == DecisionState::ClearToLand)
            .unwrap_or_else(|| panic!("seed {seed}: never CLEAR: {timeline:?}"));
        assert_eq!(changes[0].1, DecisionState::Hold, "{timeline:?}");
        assert_eq!(changes[0].2, DecisionReason::Warmup, "{timeline:?}");
        assert!(changes[first_clear].0 < 40.0, "seed {seed}: {timeline:?}");
        let hold_after = changes[first_clear..]
            .iter()
            .rev()
            .find(|c| c.1 != DecisionState::ClearToLand)
            .unwrap_or_else(|| panic!("seed {seed}: no HOLD after CLEAR: {timeline:?}"));
        assert!(hold_after.0 < 60.0, "{timeline:?}");
        // The run ends in the rough stretch: not clear.
        assert_ne!(
            changes.last().unwrap().1,
            DecisionState::ClearToLand,
            "{timeline:?}"
        );
    }
}

/// A ship's own recorded motion (a CSV file, non-uniform 10 Hz): `decide-eval` decides over the
/// file's whole length, never unsafely; asks for more than the file holds or a broken file get
/// an error naming the file, line and column; `predict-eval` judges the forecasts on it.
#[test]
fn ship_motion_from_a_file() {
    let dir = std::env::temp_dir().join(format!("deckwatch-motion-csv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("ship.csv");
    let mut text = String::from("# a ship's motion sensor\ntime_s,roll_deg,pitch_deg,heave_m,yaw_deg\n");
    for k in 0..6001u64 {
        // 10 Hz with up to 8 ms of jitter; a moderate sea of five swells.
        let t = 1000.0 + k as f64 * 0.1 + (k % 5) as f64 * 0.002;
        let w = |p: f64| std::f64::consts::TAU / p * t;
        let roll = 3.0 * w(11.0).sin() + 1.2 * (w(8.3) + 1.0).sin();
        let pitch = 1.0 * (w(6.4) + 0.5).sin() + 0.5 * w(8.9).sin();
        let heave = 0.4 * (w(9.5) + 0.3).sin();
        text += &format!(
            "{t:.3},{roll:.4},{pitch:.4},{heave:.4},{:.3}\n",
            0.2 * w(30.0).sin()
        );
    }
    std::fs::write(&file, text).unwrap();
    let run = |args: &[&str]| {
        Command::new(workspace_binary("deckwatch"))
            .args(args)
            .arg("--motion-csv")
            .arg(&file)
            .output()
            .unwrap()
    };
    let out = run(&["decide-eval", "--json", "--seeds", "1"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let series: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(series.len(), 1);
    let s = &series[0];
    assert_eq!(s["frames"], 6001, "the whole 10 min of the file: {s}");
    assert_eq!(s["state_machine"]["unsafe_commits"], 0, "{s}");
    assert!(s["state_machine"]["commits"].as_u64().unwrap() > 0, "{s}");
    let out = run(&["decide-eval", "--minutes", "20"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && e.contains("min of motion, --minutes asks for 20"),
        "{e}"
    );
    let out = run(&[
        "predict-eval",
        "--seeds",
        "1",
        "--horizons",
        "1,2",
        "--minutes",
        "5",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for predictor in ["persistence", "ar"] {
        assert!(
            text.lines()
                .any(|l| l.starts_with("all") && l.contains(predictor) && l.contains("roll_deg")),
            "{text}"
        );
        // The tail the risk per touchdown lies in: a share per horizon, and over a whole
        // touchdown.
        assert!(
            text.lines().any(|l| l.starts_with("tail")
                && l.contains(predictor)
                && l.contains("heave_rate_mps")
                && l.matches('%').count() == 3),
            "{text}"
        );
    }
    std::fs::write(
        &file,
        "time_s,roll_deg,pitch_deg,heave_m\n0,1,2,0.1\n0.1,x,2,0.1\n",
    )
    .unwrap();
    let out = run(&["decide-eval"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && e.contains("ship.csv:3:2: `x` is not a number"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
