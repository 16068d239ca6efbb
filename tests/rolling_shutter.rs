//! A rolling shutter on a swaying quadrotor (issue 19): the simulator reads the rows out over
//! 25 ms while the vehicle sways (up to 29 deg/s) and the deck rolls; the full pose that takes
//! each marker at its row's instant is as accurate as with a global shutter on the same motion,
//! and the one that does not is off by degrees. Both ways the vehicle's rate reaches the
//! estimator are checked: the autopilot-like stream of a recording (`vehicle.csv`, replayed by
//! `deckwatch eval`) and the simulator's own frames (`deckwatch inproc`).

use deckwatch_tests::{eval_table_row, run_deckwatch as run};
use std::path::Path;

/// The RMSE of roll, pitch and yaw in an eval table's row.
fn rmse(table: &str, recording: &str, estimator: &str) -> [f64; 3] {
    let row = eval_table_row(table, recording, estimator);
    assert_eq!(row[4], "0", "no misses: {row:?}");
    [6, 7, 8].map(|i| row[i].parse().unwrap())
}

/// A binned mode (1640x1232) of the Pi camera, sea state 6 under a swaying vehicle.
const SIM: [&str; 12] = [
    "--scenario",
    "ship",
    "--vehicle",
    "sway",
    "--frames",
    "40",
    "--rate",
    "10",
    "--width",
    "1640",
    "--height",
    "1232",
];

#[test]
fn the_rolling_shutter_is_corrected_to_the_global_shutters_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_string_lossy().to_string();
    for readout in ["0", "25"] {
        let mut args = vec!["sim", "record"];
        args.extend(SIM);
        let out = path(&format!("readout-{readout}"));
        args.extend(["--readout-ms", readout, "--seed", "4", "--out", &out]);
        run(&args);
    }
    let camera = std::fs::read_to_string(Path::new(&path("readout-25")).join("camera.json")).unwrap();
    assert!(camera.contains("\"readout_ms\": 25"), "{camera}");
    let table = run(&["eval", &path("readout-0"), &path("readout-25")]);
    let global = rmse(&table, "readout-0", "full-pose");
    let corrected = rmse(&table, "readout-25", "full-pose");
    let ignored = rmse(&table, "readout-25", "full-pose-gs");
    assert!(
        !table.contains("readout-0                    full-pose-gs"),
        "a global shutter has one full-pose row\n{table}"
    );
    for axis in 0..2 {
        assert!(
            corrected[axis] <= 2.0 * global[axis] + 0.002,
            "axis {axis}: {corrected:?} vs the global shutter's {global:?}\n{table}"
        );
        assert!(
            ignored[axis] >= 10.0 * global[axis],
            "axis {axis}: ignoring the readout should cost: {ignored:?}\n{table}"
        );
    }
    // The live simulator: the vehicle's rate and its change come with each frame.
    let mut args = vec!["inproc"];
    args.extend(SIM);
    args.extend(["--readout-ms", "25", "--seed", "4"]);
    let text = run(&args);
    let line = text
        .lines()
        .find(|l| l.starts_with("attitude error vs ground truth"))
        .unwrap_or_else(|| panic!("{text}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = |name: &str| -> f64 {
        let i = words.iter().position(|w| *w == name).unwrap();
        words[i + 1].parse().unwrap()
    };
    let live = [at("roll"), at("pitch")];
    for axis in 0..2 {
        assert!(
            live[axis] <= 2.0 * global[axis] + 0.002,
            "live: {line} vs the global shutter's {global:?}"
        );
    }
}
