//! `deckwatch trials --shard K/N` and `trials merge`: the parts of a campaign flown apart (as a
//! cluster does) and merged give the report of one run, bit for bit (the same seeds, a
//! simulated clock); the safety case's exact bounds are in it.

use deckwatch_tests::{run_deckwatch as run, workspace_binary};
use std::process::Command;

const CAMPAIGN: &[&str] = &[
    "trials",
    "--sea-states",
    "3,5",
    "--seeds",
    "41",
    "--headings-deg",
    "20",
    "--approaches",
    "3",
    "--max-approach-s",
    "40",
    "--threads",
    "2",
    "--json",
];

#[test]
fn shards_merged_are_the_whole_run_bit_for_bit() {
    let whole = run(CAMPAIGN);
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    // Given out of order: the merge puts the approaches back in the job list's order.
    for k in [3, 1, 2] {
        let shard = format!("{k}/3");
        let part = run(&[CAMPAIGN, &["--shard", &shard]].concat());
        // Each part flew only its own jobs: k-1, k-1+3, ...
        for line in part.lines().filter(|l| l.starts_with("{\"approach\"")) {
            let v: serde_json::Value = serde_json::from_str(line).unwrap();
            assert_eq!(v["approach"]["job"].as_u64().unwrap() % 3, k - 1, "{line}");
        }
        let path = dir.path().join(format!("shard{k}.jsonl"));
        std::fs::write(&path, part).unwrap();
        files.push(path.to_string_lossy().to_string());
    }
    let args: Vec<&str> = ["trials", "merge", "--json"]
        .into_iter()
        .chain(files.iter().map(String::as_str))
        .collect();
    let merged = run(&args);
    assert_eq!(merged, whole, "merged shards differ from the whole run");
    // 2 sea states x 3 approaches x 3 rules.
    assert_eq!(
        whole.lines().filter(|l| l.starts_with("{\"approach\"")).count(),
        18
    );
    // The totals carry the safety case: the unsafe rate's exact one-sided 95 % bound.
    let totals: Vec<serde_json::Value> = whole
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .filter(|v: &serde_json::Value| v["sea_state"] == "all" && v["rule"] == "oracle")
        .collect();
    let case = &totals[0]["safety_case"];
    let touchdowns = totals[0]["summary"]["touchdowns"].as_f64().unwrap();
    let bound = case["unsafe_rate_upper_95"].as_f64().unwrap();
    // The oracle never lands unsafely: 0 in n, bound 1 - 0.05^(1/n).
    assert!(
        (bound - (1.0 - 0.05f64.powf(1.0 / touchdowns))).abs() < 1e-9,
        "{case}"
    );
    // A shard given twice is refused, not counted twice.
    let twice: Vec<&str> = ["trials", "merge", files[0].as_str(), files[0].as_str()].to_vec();
    let out = Command::new(workspace_binary("deckwatch"))
        .args(&twice)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("appears twice"));
    // A shard cut off in the middle of a line: the whole lines merged, the cut one named.
    let text = std::fs::read_to_string(&files[0]).unwrap();
    let cut = dir.path().join("cut.jsonl");
    let whole_lines = text.trim_end();
    let lines = whole_lines.lines().count();
    std::fs::write(&cut, format!("{whole_lines}\n{}", &text[..40])).unwrap();
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["trials", "merge", "--json", &cut.to_string_lossy()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{}: 1 line(s) not JSON skipped, the first at line {}",
            cut.display(),
            lines + 1
        )),
        "{stderr}"
    );
    // ... and the JSON report says so too, naming the file and the line.
    let skipped: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter_map(|v| v.get("skipped_lines").cloned())
        .collect();
    assert_eq!(skipped.len(), 1, "{skipped:?}");
    assert_eq!(skipped[0]["file"], cut.display().to_string());
    assert_eq!(skipped[0]["lines"], 1);
    assert_eq!(skipped[0]["first_line"], lines + 1);
}
