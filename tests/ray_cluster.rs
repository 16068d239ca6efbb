//! The trials on a Ray cluster (cluster/run_trials.py, with the `ray` package nobody here wrote):
//! a local cluster of 2 workers started by the driver on this machine runs 3 shards of a small
//! campaign as Ray tasks, each the `deckwatch` binary. One Ray worker is killed while its shard
//! flies: its `deckwatch` dies with it, Ray runs the shard again, and the merged report still
//! equals `deckwatch trials --json` in one process, line for line and field for field (every
//! approach flown once, none counted twice); the plot of the bound is a PNG.
//!
//! Needs python3 with ray and matplotlib (`ci/peers.sh` installs them; `DECKWATCH_PYTHON` names
//! the interpreter).

use deckwatch_tests::{peer_python, workspace_binary, PipelineGuard};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A running shard: its `deckwatch` process (a `--shard` argument, this binary) and the Ray
/// worker whose child it is.
fn running_shard(deckwatch: &Path) -> Option<(i32, i32)> {
    let binary = std::fs::canonicalize(deckwatch).ok()?;
    std::fs::read_dir("/proc").ok()?.flatten().find_map(|entry| {
        let pid: i32 = entry.file_name().to_str()?.parse().ok()?;
        let cmdline = std::fs::read(entry.path().join("cmdline")).ok()?;
        let args: Vec<&[u8]> = cmdline.split(|&b| b == 0).collect();
        let exe = std::fs::canonicalize(std::str::from_utf8(args.first()?).ok()?).ok()?;
        let ours = exe == binary && args.contains(&&b"--shard"[..]);
        if !ours {
            return None;
        }
        // /proc/PID/stat: "pid (comm) state ppid ..."; comm may hold spaces, not ')'.
        let stat = std::fs::read_to_string(entry.path().join("stat")).ok()?;
        let ppid: i32 = stat.rsplit_once(')')?.1.split_whitespace().nth(1)?.parse().ok()?;
        let parent = std::fs::read(format!("/proc/{ppid}/cmdline")).ok()?;
        parent.starts_with(b"ray::").then_some((ppid, pid))
    })
}

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
    let mut driver = PipelineGuard::spawn_peer(
        Command::new(&python)
            .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/cluster/run_trials.py"))
            .arg("--deckwatch")
            .arg(&deckwatch)
            .args(["--shards", "3", "--workers", "2", "--out"])
            .arg(&out_dir)
            .arg("--")
            .args(CAMPAIGN)
            // Ray's own session files in the test's folder, not the user's /tmp/ray.
            .env("RAY_TMPDIR", dir.path())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    // Kill the Ray worker of the first shard seen flying.
    let (worker, shard) = loop {
        if let Some(found) = running_shard(&deckwatch) {
            break found;
        }
        if let Some(status) = driver.child().try_wait().unwrap() {
            let out = driver.wait_with_output();
            panic!(
                "the driver ended ({status}) before a shard was seen flying:\n{}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    // SAFETY: kill(2) on a pid; no memory is involved.
    assert_eq!(
        unsafe { libc::kill(worker, libc::SIGKILL) },
        0,
        "kill the Ray worker {worker}"
    );
    let killed_at = Instant::now();
    while Path::new(&format!("/proc/{shard}")).exists() && killed_at.elapsed() < Duration::from_secs(10) {
        // A zombie until Ray's raylet reaps it is dead too.
        let state = std::fs::read_to_string(format!("/proc/{shard}/stat")).unwrap_or_default();
        if state
            .rsplit_once(')')
            .is_some_and(|(_, rest)| rest.trim_start().starts_with('Z'))
        {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let shard_state = std::fs::read_to_string(format!("/proc/{shard}/stat")).unwrap_or_default();
    assert!(
        shard_state.is_empty()
            || shard_state
                .rsplit_once(')')
                .is_some_and(|(_, r)| r.trim_start().starts_with('Z')),
        "the killed worker's deckwatch {shard} still runs: {shard_state}"
    );
    let driver = driver.wait_with_output();
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
