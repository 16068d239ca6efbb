//! A test that fails mid-fault leaves nothing on the machine: no deckwatch process, no shared
//! memory, no run folder (tests/support's `PipelineGuard`). A child test, run as its own process,
//! starts a pipeline, stops a stage and the launcher with SIGSTOP, and panics; the parent checks
//! what is left.

use deckwatch_tests::guard::{leftovers, running};
use deckwatch_tests::{workspace_binary, PipelineGuard};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Set by the parent for the child; without it the child does nothing (`--ignored` runs).
const CHILD_DOMAIN: &str = "DECKWATCH_TEST_PANIC_DOMAIN";

#[test]
fn a_test_that_panics_mid_fault_leaves_nothing() {
    let domain = format!("t{}-panics", std::process::id());
    let out = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "panics_mid_fault",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_DOMAIN, &domain)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "the child test must fail:\n{stdout}\n{stderr}"
    );
    assert!(stderr.contains("a failure mid-fault"), "{stdout}\n{stderr}");
    // The processes the child saw before it failed: the launcher and its stages, stopped.
    let pids: Vec<u32> = stdout
        .lines()
        .find_map(|l| l.split_once("pipeline pids: ").map(|(_, pids)| pids))
        .unwrap_or_else(|| panic!("no pids in\n{stdout}"))
        .split_whitespace()
        .map(|p| p.parse().unwrap())
        .collect();
    assert!(pids.len() >= 5, "launcher and four stages: {pids:?}");
    let alive: Vec<u32> = pids.iter().copied().filter(|&p| running(p)).collect();
    assert!(alive.is_empty(), "still running after the failed test: {alive:?}");
    let left = leftovers(&domain);
    assert!(left.is_empty(), "left behind: {left:?}");
    println!(
        "the failed child test left nothing: {} processes gone, no shared memory, no run folder",
        pids.len()
    );
}

/// The child: fails on purpose with the launcher and detect stopped (run by the test above).
#[test]
#[ignore = "a child of a_test_that_panics_mid_fault_leaves_nothing: fails on purpose"]
fn panics_mid_fault() {
    let Ok(domain) = std::env::var(CHILD_DOMAIN) else {
        return;
    };
    let mut launcher = PipelineGuard::spawn(
        Command::new(workspace_binary("deckwatch"))
            .args([
                "run", "--quiet", "--frames", "100000", "--rate", "10", "--rerun", "off",
            ])
            .args(["--domain", &domain])
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
        &domain,
    );
    let start = Instant::now();
    let stages = loop {
        let stages = deckwatch_runtime::stage::stage_processes(&domain);
        if stages.len() >= 4 {
            break stages;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the stages did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    // Mid-run, not mid-start: every stage has set up its node and is deciding.
    std::thread::sleep(Duration::from_secs(2));
    let launcher_pid = launcher.id();
    let mut pids = vec![launcher_pid];
    pids.extend(stages.iter().map(|(_, pid)| *pid));
    println!(
        "pipeline pids: {}",
        pids.iter().map(|p| p.to_string()).collect::<Vec<_>>().join(" ")
    );
    let detect = stages.iter().find(|(s, _)| s == "detect").expect("detect").1;
    // SAFETY: kill(2) on this test's own pipeline.
    unsafe {
        libc::kill(detect as i32, libc::SIGSTOP);
        libc::kill(launcher_pid as i32, libc::SIGSTOP);
    }
    let _ = launcher.child();
    panic!("a failure mid-fault (on purpose): launcher and detect stopped");
}
