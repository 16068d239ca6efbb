//! Faults that must never clear a landing (issue 16), as a user meets them: the whole pipeline
//! as processes (`deckwatch run`), the decisions CSV read back.

use deckwatch_tests::guard::{children, running, walk};
use deckwatch_tests::{pipeline_output, workspace_binary, PipelineGuard};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
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
    let out = pipeline_output(
        Command::new(workspace_binary("deckwatch"))
            .args(["run", "--quiet", "--config"])
            .arg(&config)
            .arg("--decisions")
            .arg(&csv),
        &format!("t{}-frozen", std::process::id()),
    );
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

/// A decisions CSV on a full disk (`/dev/full`: every write fails with ENOSPC): said once, the
/// pipeline goes on deciding every frame, and the command fails at the end so that no script
/// takes the file for the whole run.
#[test]
fn a_full_disk_for_the_decisions_csv_does_not_stop_the_pipeline() {
    let domain = format!("t{}-full", std::process::id());
    let out = pipeline_output(
        Command::new(workspace_binary("deckwatch"))
            .args([
                // 10 Hz: a debug build renders the simulator's 3280x2464 frame in about 60 ms.
                "run", "--quiet", "--json", "--frames", "30", "--rate", "10", "--rerun", "off",
            ])
            .args(["--domain", &domain])
            .args(["--decisions", "/dev/full"]),
        &domain,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "an incomplete CSV must fail the command");
    assert!(
        stderr.contains("decisions CSV") && stderr.contains("incomplete after 0 rows"),
        "{stderr}"
    );
    // The pipeline went on after the first failed row: every frame capture published was
    // decided (capture itself drops the frames it renders too late on a slow machine).
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap_or_default();
    let decided = report["decisions"].as_u64().unwrap_or(0);
    let capture_drops = report["drops"]["capture"].as_u64().unwrap_or(u64::MAX);
    assert!(
        decided >= 10 && decided.saturating_add(capture_drops) >= 28,
        "still deciding:\n{stdout}\n{stderr}"
    );
}

/// The reader of the launcher's output goes before the run ends (`deckwatch run | head -1`): the
/// pipeline runs to its end regardless (its live status lines and report are for people), no
/// process panics, and nothing is left behind.
#[test]
fn a_run_whose_reader_goes_runs_to_its_end() {
    let domain = format!("t{}-reader", std::process::id());
    let mut launcher = PipelineGuard::spawn(
        Command::new(workspace_binary("deckwatch"))
            // Not `--quiet`: a status line a second, the first written after the reader went.
            .args(["run", "--frames", "30", "--rate", "10", "--rerun", "off"])
            .args(["--domain", &domain])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped()),
        &domain,
    );
    drop(launcher.child().stdout.take());
    let out = launcher.wait_with_output();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
    // The source ran out and every stage reported its frames at its end: the run was not cut
    // short (capture drops the frames it renders too late on a busy machine: counts vary).
    for stage in ["capture finished its source", "frames processed", "marker sets"] {
        assert!(stderr.contains(stage), "{stage}: {stderr}");
    }
    let left = deckwatch_tests::guard::leftovers(&domain);
    assert!(left.is_empty(), "left behind: {left:?}");
}

/// The launcher SIGKILLed mid-run: its stages exit on their own (PR_SET_PDEATHSIG), and
/// `deckwatch clean` removes what it left: the domain's shared memory and its run folder.
#[test]
fn a_killed_launcher_leaves_nothing_after_clean() {
    let dir = tempfile::tempdir().unwrap();
    let domain = format!("t{}-kill", std::process::id());
    let csv = dir.path().join("d.csv");
    // The user's runtime directory: the run folder goes there, private.
    let runtime = tempfile::tempdir().unwrap();
    let mut launcher = PipelineGuard::spawn(
        Command::new(workspace_binary("deckwatch"))
            .env("XDG_RUNTIME_DIR", runtime.path())
            .args([
                "run", "--quiet", "--frames", "100000", "--rate", "10", "--rerun", "off",
            ])
            .args(["--domain", &domain])
            .arg("--decisions")
            .arg(&csv)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null()),
        &domain,
    );
    let start = std::time::Instant::now();
    // Until decisions flow through every stage.
    while std::fs::read_to_string(&csv).map_or(0, |t| t.lines().count()) < 5 {
        assert!(start.elapsed().as_secs() < 120, "no decisions");
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let stages = children(launcher.id());
    assert_eq!(stages.len(), 4, "capture, detect, estimate, decide: {stages:?}");
    let run_dir = runtime
        .path()
        .join(format!("deckwatch-{domain}-{}", launcher.id()));
    use std::os::unix::fs::PermissionsExt;
    let mode = std::fs::metadata(&run_dir).map(|m| m.permissions().mode() & 0o777);
    assert_eq!(
        mode.ok(),
        Some(0o700),
        "{}: the run folder is private",
        run_dir.display()
    );
    launcher.child().kill().unwrap();
    launcher.wait();
    let killed = std::time::Instant::now();
    while stages.iter().any(|&p| running(p)) {
        assert!(killed.elapsed().as_secs() < 10, "stages outlived the launcher");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    println!(
        "every stage exited {} ms after the launcher was killed",
        killed.elapsed().as_millis()
    );
    assert!(run_dir.exists(), "a SIGKILL leaves the run folder");
    let out = Command::new(workspace_binary("deckwatch"))
        .env("XDG_RUNTIME_DIR", runtime.path())
        .args(["clean", "--domain", &domain])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains(&run_dir.display().to_string()), "{text}");
    assert!(!run_dir.exists());
    let prefix = deckwatch_runtime::bus::domain_prefix(&domain);
    // The killed launcher's iceoryx2 root: in the runtime directory it was given.
    let left: Vec<String> = [PathBuf::from("/dev/shm"), runtime.path().join("dw-ipc")]
        .iter()
        .flat_map(|d| walk(d))
        .filter(|name| name.contains(&prefix))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}
