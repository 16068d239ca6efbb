//! The four processes on a committed recording with `--rerun save`: one `.rrd` comes out (the
//! per-process parts merged), and reading it back finds every entity with the right number of
//! rows: an image, the markers, the ellipse, the reprojected deck, the angles (both estimators
//! and the truth) and the decision for every frame.

use deckwatch_tests::{assert_rrd_verifies, peer_rerun, pipeline_output, workspace_binary};
use std::process::Command;

#[test]
fn saved_recording_holds_every_stage() {
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("run.rrd");
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/ship-640x480");
    let domain = format!("t{}-rerun", std::process::id());
    let out = pipeline_output(
        Command::new(workspace_binary("deckwatch"))
            .args([
                "latency", data, "--rate", "20", "--frames", "16", "--json", "--domain",
            ])
            .arg(&domain)
            .args(["--rerun", "save"])
            .arg(&rrd),
        &domain,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("rerun recording:"), "{stderr}");
    let parts: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(parts.len(), 1, "the parts are merged and removed: {parts:?}");
    let rows = deckwatch_viz::rrd_entity_rows(&rrd).unwrap();
    let get = |e: &str| rows.get(&format!("/{e}")).copied().unwrap_or(0);
    for e in [
        "camera/image",
        "camera/image/markers",
        "camera/image/ellipse",
        "camera/image/deck_model",
        "camera/image/deck_model/ring",
        "attitude/roll/full-pose",
        "attitude/pitch/paper-atan2",
        "attitude/yaw/truth",
    ] {
        assert_eq!(get(e), 16, "{e}: {rows:?}");
    }
    // Each estimator's error against the truth, and each decided frame's latency and drops.
    for e in [
        "error/roll/full-pose",
        "error/yaw/paper-atan2",
        "latency/end_to_end",
        "latency/detect",
        "drops/capture",
        "attitude/roll/capacity_max",
    ] {
        assert!(get(e) >= 16, "{e}: {rows:?}");
    }
    // The deck region of every frame (the image of each, the overlays of each).
    assert_eq!(get("camera/deck"), 16, "{rows:?}");
    assert_eq!(get("camera/deck/markers"), 16, "{rows:?}");
    assert_eq!(get("camera/deck/deck_model"), 16, "{rows:?}");
    // The decision's lanes change only when it does (warm-up, then the watchdog's stale one
    // after the last frame), its text with them.
    assert!(get("decision/state") >= 2, "{rows:?}");
    assert_eq!(get("decision/state"), get("decision/reason"), "{rows:?}");
    assert!(get("decision_now") >= 2, "{rows:?}");
    assert!(get("decision_log") >= 2, "{rows:?}");
    // rerun's own reader: the file verifies, and names the run with its properties.
    assert_rrd_verifies(&rrd);
    let rerun = peer_rerun();
    let print = Command::new(&rerun)
        .args(["rrd", "print", "-vvv"])
        .arg(&rrd)
        .output()
        .unwrap();
    assert!(
        print.status.success(),
        "{}",
        String::from_utf8_lossy(&print.stderr)
    );
    let printed = String::from_utf8_lossy(&print.stdout);
    assert!(printed.contains("RecordingInfo:name"), "no recording name");
    assert!(
        printed.contains("deckwatch run: replay of"),
        "the name says what ran"
    );
    for property in [
        "/__properties/deckwatch",
        "/__properties/configuration",
        "component: estimator",
    ] {
        assert!(printed.contains(property), "{property} missing");
    }
}
