//! Faults that must never clear a landing (issue 16), as a user meets them: the whole pipeline
//! as processes (`deckwatch run`), the decisions CSV read back.

use deckwatch_tests::workspace_binary;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// (state, reason) -> count, from a decisions CSV.
fn decisions(csv: &Path) -> BTreeMap<(String, String), usize> {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (state, reason) = (col("state"), col("reason"));
    let mut out = BTreeMap::new();
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        *out.entry((f[state].to_string(), f[reason].to_string()))
            .or_default() += 1;
    }
    out
}

/// The frozen camera: a one-frame recording replayed in a loop (`[replay] loops = 0`,
/// 700 frames at 10 Hz on the recording's timeline) once gave 182 CLEAR. Every frame from the
/// third on is `frozen-input` now, and none is cleared.
#[test]
fn a_frozen_camera_never_clears() {
    let dir = tempfile::tempdir().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ship-640x480");
    let rec = dir.path().join("one-frame");
    std::fs::create_dir_all(rec.join("frames")).unwrap();
    std::fs::copy(data.join("camera.json"), rec.join("camera.json")).unwrap();
    let frames = std::fs::read_to_string(data.join("frames.csv")).unwrap();
    let first_two: Vec<&str> = frames.lines().take(2).collect();
    std::fs::write(rec.join("frames.csv"), first_two.join("\n") + "\n").unwrap();
    std::fs::copy(data.join("frames/000000.png"), rec.join("frames/000000.png")).unwrap();
    let config = dir.path().join("p.toml");
    // Heave off: the recording has no vehicle height (else every frame is `no-deck-heave`,
    // which hides what this test is about).
    std::fs::write(
        &config,
        format!(
            "[bus]\ndomain = \"t{}-frozen\"\n[source]\nkind = \"replay\"\n[replay]\nrecording = \"{}\"\n\
             loops = 0\nframes = 700\nrate_hz = 100\n[decide]\nheave = \"off\"\n[rerun]\nsink = \"off\"\n",
            std::process::id(),
            rec.display()
        ),
    )
    .unwrap();
    let csv = dir.path().join("decisions.csv");
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["run", "--quiet", "--config"])
        .arg(&config)
        .arg("--decisions")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let seen = decisions(&csv);
    let total: usize = seen.values().sum();
    let frozen = seen
        .get(&("HOLD".to_string(), "frozen-input".to_string()))
        .copied()
        .unwrap_or(0);
    assert!(
        seen.keys().all(|(state, _)| state != "CLEAR"),
        "cleared on a frozen camera: {seen:?}"
    );
    // Replay at 100 Hz may skip frames (latest-frame semantics); all but the first few of those
    // decided are frozen (and the watchdog's stale one at the end).
    assert!(total > 100 && frozen + 5 >= total, "{seen:?}");
}
