//! `deckwatch eval` on the committed recordings: the full-pose estimator beats the paper's on
//! the same detections, gives altitude and offset without an altimeter, and never an attitude
//! on a frame without a deck; `--csv` writes one row per frame and estimator.

use deckwatch_tests::workspace_binary;
use std::process::Command;

#[test]
fn full_pose_and_paper_side_by_side() {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/");
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("frames.csv");
    let out = Command::new(workspace_binary("deckwatch"))
        .arg("eval")
        .args(["case1-3280x2464", "ship-640x480", "nodeck-640x480"].map(|r| format!("{data}{r}")))
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let row = |rec: &str, est: &str| -> Vec<String> {
        text.lines()
            .find(|l| l.starts_with(rec) && l.split_whitespace().nth(1) == Some(est))
            .unwrap_or_else(|| panic!("{rec} {est} in\n{text}"))
            .split_whitespace()
            .map(str::to_string)
            .collect()
    };
    // Columns: recording estimator frames estim missed nodeck rmse(3) max(3) alt off cost.
    let num = |r: &[String], i: usize| r[i].parse::<f64>().unwrap();
    for rec in ["case1-3280x2464", "ship-640x480"] {
        let (pose, paper) = (row(rec, "full-pose"), row(rec, "paper-atan2"));
        assert_eq!(pose[4], "0", "no misses: {pose:?}");
        for i in 6..9 {
            assert!(
                num(&pose, i) <= num(&paper, i) + 1e-4,
                "{rec}: full pose worse than the paper\n{text}"
            );
        }
        assert!(num(&pose, 12) < 0.01, "altitude within 1 cm: {pose:?}");
    }
    let case1 = row("case1-3280x2464", "full-pose");
    assert!((6..9).all(|i| num(&case1, i) < 0.02), "{case1:?}");
    let nodeck = row("nodeck-640x480", "full-pose");
    assert_eq!((nodeck[3].as_str(), nodeck[5].as_str()), ("0", "0"));
    let rows = std::fs::read_to_string(&csv).unwrap().lines().count();
    assert_eq!(rows, 1 + 2 * (3 + 8 + 3));
    // Each row's errors are the estimate less the truth, with their sign (a bias or an error
    // growing with the angle shows only so), and the table's RMSE is theirs.
    let truth: std::collections::HashMap<String, _> =
        deckwatch_tests::read_csv_rows(std::path::Path::new(&format!("{data}ship-640x480/frames.csv")))
            .into_iter()
            .map(|r| (r["index"].clone(), r))
            .collect();
    let (mut negative, mut sum_sq, mut n) = (0, [0.0; 3], 0);
    for r in deckwatch_tests::read_csv_rows(&csv) {
        if !r["recording"].starts_with("ship-640x480") || r["estimator"] != "full-pose" {
            continue;
        }
        n += 1;
        for (k, axis) in ["roll", "pitch", "yaw"].iter().enumerate() {
            let column = format!("{axis}_deg");
            let e: f64 = r[&format!("err_{column}")].parse().unwrap();
            let estimate: f64 = r[&column].parse().unwrap();
            let true_deg: f64 = truth[&r["index"]][&column].parse().unwrap();
            assert!((e - (estimate - true_deg)).abs() < 1e-5, "{axis}: {r:?}");
            negative += usize::from(e < 0.0);
            sum_sq[k] += e * e;
        }
    }
    assert!(
        negative > 0 && negative < 3 * n,
        "{negative} of {} errors negative",
        3 * n
    );
    let ship = row("ship-640x480", "full-pose");
    for (k, sum_sq) in sum_sq.iter().enumerate() {
        let rmse = (sum_sq / n as f64).sqrt();
        assert!((rmse - num(&ship, 6 + k)).abs() < 1e-4, "{rmse} against {ship:?}");
    }
}
