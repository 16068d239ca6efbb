//! `deckwatch inproc` and the four processes of `deckwatch latency` run the same stage chain:
//! on the same recording they give bit-identical attitudes and decisions (the decision runs on
//! the frames' own timeline, so the hops' timing does not enter it).

use deckwatch_tests::{pipeline_output, workspace_binary};
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// Per frame (`seq`): the columns that must agree, as written (angles in full precision).
type Outcomes = BTreeMap<u64, Vec<String>>;

const COMPARED: [&str; 10] = [
    "source_index",
    "valid",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "markers",
    "state",
    "reason",
    "calm_start_s",
    "calm_length_s",
];

/// The compared columns of every decision on a frame, and the total of the drop columns.
fn outcomes(csv: &Path) -> (Outcomes, u64) {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (mut out, mut drops) = (Outcomes::new(), 0);
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), header.len(), "{line}");
        if f[col("watchdog")] == "1" {
            continue; // decide's watchdog after the last frame answers no frame
        }
        for d in [
            "drops_capture",
            "drops_bad",
            "drops_detect",
            "drops_estimate",
            "drops_decide",
        ] {
            drops += f[col(d)].parse::<u64>().unwrap();
        }
        let seq = f[col("seq")].parse().unwrap();
        out.insert(seq, COMPARED.iter().map(|c| f[col(c)].to_string()).collect());
    }
    (out, drops)
}

fn deckwatch(args: &[&str]) {
    let out = Command::new(workspace_binary("deckwatch"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "deckwatch {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn inproc_and_processes_agree_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec");
    let rec_s = rec.to_str().unwrap();
    // 15 s of sea state 6, long enough for the decision to leave its warm-up (shortened here).
    deckwatch(&[
        "sim",
        "record",
        "--scenario",
        "ship",
        "--frames",
        "150",
        "--rate",
        "10",
        "--width",
        "640",
        "--height",
        "480",
        "--out",
        rec_s,
    ]);
    let config = dir.path().join("pipeline.toml");
    std::fs::write(
        &config,
        "[decide.forecast]\nkind = \"ar\"\nmin_history_s = 6.0\nwindow_s = 20.0\n",
    )
    .unwrap();
    let config_s = config.to_str().unwrap();

    let inproc_csv = dir.path().join("inproc.csv");
    deckwatch(&[
        "inproc",
        "--config",
        config_s,
        "--source",
        "replay",
        "--recording",
        rec_s,
        "--every",
        "0",
        "--decisions",
        inproc_csv.to_str().unwrap(),
    ]);
    let (inproc, inproc_drops) = outcomes(&inproc_csv);
    assert_eq!(inproc.len(), 150);
    assert_eq!(inproc_drops, 0);
    let reasons: std::collections::BTreeSet<&str> = inproc.values().map(|v| v[7].as_str()).collect();
    assert!(
        reasons.iter().any(|r| *r != "warmup"),
        "the decision never left its warm-up: {reasons:?}"
    );

    // The processes may drop a frame on a loaded machine (latest-frame semantics), which
    // changes the detector's tracking: compare a run without drops, slower if need be.
    let mut compared = false;
    for rate in ["25", "10"] {
        let csv = dir.path().join(format!("processes-{rate}.csv"));
        let domain = format!("t{}-same-{rate}", std::process::id());
        let out = pipeline_output(
            Command::new(workspace_binary("deckwatch")).args([
                "latency",
                rec_s,
                "--rate",
                rate,
                "--config",
                config_s,
                "--domain",
                &domain,
                "--json",
                "--decisions",
                csv.to_str().unwrap(),
            ]),
            &domain,
        );
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let (processes, drops) = outcomes(&csv);
        if drops > 0 || processes.len() != inproc.len() {
            eprintln!("{rate} Hz: {drops} frames dropped; trying slower");
            continue;
        }
        for (seq, row) in &inproc {
            assert_eq!(&processes[seq], row, "frame {seq}: {COMPARED:?}");
        }
        compared = true;
        break;
    }
    assert!(compared, "every multi-process run dropped frames");
}
