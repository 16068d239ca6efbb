//! The trials on a Ray cluster (cluster/run_trials.py, with the `ray` package nobody here wrote):
//! a local cluster of 2 workers started by the driver on this machine runs 3 shards of a small
//! campaign as Ray tasks, each the `deckwatch` binary; the merged report equals `deckwatch trials
//! --json` in one process, line for line and field for field, and the plot of the bound is a PNG.
//!
//! Needs python3 with ray and matplotlib (`ci/peers.sh` installs them; `DECKWATCH_PYTHON` names
//! the interpreter).

use deckwatch_tests::{peer_python, workspace_binary};
use std::process::Command;

const CAMPAIGN: &[&str] = &[
    "--sea-states",
    "3,5",
    "--seeds",
    "43",
    "--headings-deg",
    "110",
    "--approaches",
    "2",
    "--max-approach-s",
    "30",
];

#[test]
fn shards_on_a_local_ray_cluster_give_the_single_process_report() {
    let python = peer_python("ray");
    let deckwatch = workspace_binary("deckwatch");
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("campaign");
    let driver = Command::new(&python)
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/cluster/run_trials.py"))
        .arg("--deckwatch")
        .arg(&deckwatch)
        .args(["--shards", "3", "--workers", "2", "--out"])
        .arg(&out_dir)
        .arg("--")
        .args(CAMPAIGN)
        // Ray's own session files in the test's folder, not the user's /tmp/ray.
        .env("RAY_TMPDIR", dir.path())
        .output()
        .expect("start the Ray driver");
    let stderr = String::from_utf8_lossy(&driver.stderr);
    assert!(driver.status.success(), "the Ray driver failed:\n{stderr}");
    assert!(
        stderr.contains("shards 3/3"),
        "no progress line for the last shard:\n{stderr}"
    );
    let merged = std::fs::read_to_string(out_dir.join("report.jsonl")).unwrap();
    let single = Command::new(&deckwatch)
        .arg("trials")
        .args(CAMPAIGN)
        .args(["--json", "--threads", "1"])
        .output()
        .unwrap();
    assert!(single.status.success());
    let single = String::from_utf8(single.stdout).unwrap();
    let parse = |text: &str| -> Vec<serde_json::Value> {
        text.lines().map(|l| serde_json::from_str(l).unwrap()).collect()
    };
    let (m, s) = (parse(&merged), parse(&single));
    assert_eq!(m.len(), s.len(), "line counts");
    for (a, b) in m.iter().zip(&s) {
        assert_eq!(a, b, "field for field");
    }
    assert_eq!(merged, single, "byte for byte");
    // 2 sea states x 2 approaches x 3 rules; the plot is a PNG.
    assert_eq!(m.iter().filter(|v| v.get("approach").is_some()).count(), 12);
    let png = std::fs::read(out_dir.join("bound.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
}
