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
