//! The fault matrix (issue 16): one `deckwatch run` on a calm simulated sea that clears
//! landings, and, one after the other, every fault a flight can meet: each process stopped
//! (SIGSTOP: hung) and killed (SIGKILL), the launcher stopped, corrupt messages in shared
//! memory, a capture stamped in the future and a source clock that jumps. For each, the test
//! follows the decisions on the bus as the autopilot's link does and asserts that none says
//! CLEAR while the fault lasts, and that fresh decisions come back without anyone's help; the
//! recovery times it prints are in BENCHMARKS.md. (A frozen camera and a full disk are in
//! `tests/faults.rs`, a killed launcher there too.)
//!
//! The flight recorder runs (headers and messages, no pixels): the launcher then reads every
//! stage's stderr through a pipe, the path a stopped launcher could stall. Every assertion
//! judges the pipeline against what it was given in the same run (frames captured, decisions
//! per frame before the fault), never against this machine's speed.

use deckwatch_common::messages::{
    monotonic_ns, AttitudeMessage, DecisionState, LandingDecision, MarkerMessage,
};
use deckwatch_common::wire::{WireBool, WireCode};
use deckwatch_runtime::bus::{Bus, BusConfig, MessagePublisher, MessageSubscriber};
use deckwatch_tests::{workspace_binary, PipelineGuard};
use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const RATE_HZ: f64 = 20.0;
/// `[decide] max_age_ms`: decisions received later than this after a fault began are on data
/// from after it (or watchdog ones).
const MAX_AGE_NS: u64 = 300_000_000;

/// A decision as the test received it.
#[derive(Debug, Clone, Copy)]
struct Seen {
    received_ns: u64,
    captured_ns: u64,
    state: DecisionState,
    watchdog: bool,
    decision: LandingDecision,
}

struct Follower {
    decisions: MessageSubscriber<LandingDecision>,
    /// Detect's and estimate's outputs as received (time, frame seq): per-stage counts.
    markers_in: MessageSubscriber<MarkerMessage>,
    attitudes_in: MessageSubscriber<AttitudeMessage>,
    markers_seen: Vec<(u64, u64)>,
    attitudes_seen: Vec<(u64, u64)>,
    attitudes: MessagePublisher<AttitudeMessage>,
    corrupt_decisions: MessagePublisher<LandingDecision>,
    seen: Vec<Seen>,
    _bus: Bus,
}

impl Follower {
    fn pump(&mut self) {
        while let Some(m) = self.markers_in.receive().unwrap() {
            self.markers_seen.push((monotonic_ns(), m.stamp.seq));
        }
        while let Some(a) = self.attitudes_in.receive().unwrap() {
            self.attitudes_seen.push((monotonic_ns(), a.stamp.seq));
        }
        while let Some(d) = self.decisions.receive().unwrap() {
            self.seen.push(Seen {
                received_ns: monotonic_ns(),
                captured_ns: d.stamp.times.captured_ns,
                state: d.state.get(),
                watchdog: d.watchdog.get(),
                decision: d,
            });
        }
    }

    /// Follows the decisions until `done` says so (true) or `timeout` passes (false).
    fn wait(&mut self, timeout: Duration, mut done: impl FnMut(&[Seen]) -> bool) -> bool {
        let end = Instant::now() + timeout;
        loop {
            self.pump();
            if done(&self.seen) {
                return true;
            }
            if Instant::now() > end {
                return false;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Until a fresh decision (on a frame captured after `after_ns`, not the watchdog's) comes:
    /// when it was received.
    fn fresh_after(&mut self, after_ns: u64, timeout: Duration) -> Option<u64> {
        let found = self.wait(timeout, |s| s.iter().any(|d| fresh(d, after_ns)));
        found.then(|| self.seen.iter().find(|d| fresh(d, after_ns)).unwrap().received_ns)
    }

    fn newest(&self) -> LandingDecision {
        self.seen.last().unwrap().decision
    }
}

/// On a frame captured after `after_ns` (and not in the future), not the watchdog's.
fn fresh(d: &Seen, after_ns: u64) -> bool {
    !d.watchdog && d.captured_ns > after_ns && d.captured_ns <= d.received_ns
}

/// The reasons of the decisions received since `since_ns`, counted: for failure messages.
fn reasons_since(seen: &[Seen], since_ns: u64) -> String {
    let mut counts = std::collections::BTreeMap::new();
    for d in seen.iter().filter(|d| d.received_ns > since_ns) {
        *counts
            .entry(format!("{} {}", d.state.name(), d.decision.reason.get().name()))
            .or_insert(0) += 1;
    }
    format!("{counts:?}")
}

/// The process id of a stage of this domain.
fn stage_pid(name: &str, domain: &str) -> Option<i32> {
    deckwatch_runtime::stage::stage_processes(domain)
        .into_iter()
        .find(|(stage, _)| stage == name)
        .map(|(_, pid)| pid as i32)
}

fn signal(pid: i32, sig: i32) {
    // SAFETY: kill(2) on a process of this test's pipeline.
    assert_eq!(unsafe { libc::kill(pid, sig) }, 0, "kill({pid}, {sig})");
}

/// What each stage produced in a time window: frames captured (the advance of capture's frame
/// counter, as the detections carry it), and the detections, attitudes and (fresh) decisions
/// received.
struct StageCounts {
    frames: u64,
    markers: u64,
    attitudes: u64,
    decisions: u64,
}

impl StageCounts {
    fn between(f: &Follower, from_ns: u64, to_ns: u64) -> Self {
        let newest_seq = |until: u64| {
            f.markers_seen
                .iter()
                .filter(|(t, _)| *t <= until)
                .map(|&(_, seq)| seq)
                .max()
                .unwrap_or(0)
        };
        let within = |t: u64| t > from_ns && t <= to_ns;
        Self {
            frames: newest_seq(to_ns).saturating_sub(newest_seq(from_ns)),
            markers: f.markers_seen.iter().filter(|(t, _)| within(*t)).count() as u64,
            attitudes: f.attitudes_seen.iter().filter(|(t, _)| within(*t)).count() as u64,
            decisions: f
                .seen
                .iter()
                .filter(|d| within(d.received_ns) && !d.watchdog)
                .count() as u64,
        }
    }
}

impl std::fmt::Display for StageCounts {
    fn fmt(&self, out: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            out,
            "{} frames captured, {} detections, {} attitudes, {} decisions",
            self.frames, self.markers, self.attitudes, self.decisions
        )
    }
}

/// Each stage process's threads as "stage: state wchan" (`/proc/PID/task/*/`): what a stopped
/// launcher could leave them waiting on (a full stderr pipe shows as `pipe_write`).
fn stage_states(domain: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (stage, pid) in deckwatch_runtime::stage::stage_processes(domain) {
        let mut threads = std::collections::BTreeMap::<String, usize>::new();
        for task in std::fs::read_dir(format!("/proc/{pid}/task"))
            .into_iter()
            .flatten()
            .flatten()
        {
            let state = std::fs::read_to_string(task.path().join("stat"))
                .ok()
                .and_then(|s| Some(s.rsplit_once(')')?.1.split_whitespace().next()?.to_string()))
                .unwrap_or_default();
            let wchan = std::fs::read_to_string(task.path().join("wchan")).unwrap_or_default();
            *threads.entry(format!("{state} {}", wchan.trim())).or_default() += 1;
        }
        out.push(format!("{stage} ({pid}): threads {threads:?}"));
    }
    out.sort();
    out
}

/// One fault's outcome.
struct Row {
    fault: String,
    start_ns: u64,
    /// Fault -> the first fresh decision (ms).
    recovery_ms: Option<f64>,
    /// Decisions while faulted (after the freshness limit, before the fresh one) and CLEARs
    /// among them.
    while_faulted: usize,
    cleared_while_faulted: usize,
}

#[test]
fn every_fault_is_survived_and_never_cleared_on() {
    let dir = tempfile::tempdir().unwrap();
    let domain = format!("t{}-matrix", std::process::id());
    let config = dir.path().join("p.toml");
    // A calm sea (a fifth of sea state 6) and a short warm-up, so that landings are cleared
    // within seconds and a fault has something to spoil; the link runs (nobody listens).
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    std::fs::write(
        &config,
        format!(
            "[bus]\ndomain = \"{domain}\"\n\
             [sim]\nscenario = \"ship\"\nframes = 100000\nrate = {RATE_HZ}\nsea_scale = 0.2\n\
             [decide]\nmax_age_ms = {}\n[decide.forecast]\nkind = \"ar\"\nmin_history_s = 10.0\n\
             [link]\nenabled = true\naddress = \"udpout:127.0.0.1:{port}\"\n\
             [record]\npath = \"{}\"\nframes = \"none\"\n\
             [rerun]\nsink = \"off\"\n",
            MAX_AGE_NS / 1_000_000,
            dir.path().join("flight.mcap").display()
        ),
    )
    .unwrap();
    // The launcher's and the stages' messages, to a file (read on failure, and at the end).
    let log = dir.path().join("launcher.err");
    // Whatever happens to the test, the guard leaves no process, shared memory or run folder.
    let mut launcher = PipelineGuard::spawn(
        Command::new(workspace_binary("deckwatch"))
            .args(["run", "--quiet", "--json", "--config"])
            .arg(&config)
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&log).unwrap()),
        &domain,
    );
    // Read the report as it comes (a full pipe would stop the launcher).
    let mut stdout = launcher.child().stdout.take().unwrap();
    let out_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });

    // Join the domain once the launcher has it (it refuses a domain with live nodes).
    let started = Instant::now();
    while stage_pid("capture", &domain).is_none() {
        if let Some(status) = launcher.child().try_wait().unwrap() {
            panic!(
                "the launcher stopped ({status}): {}",
                std::fs::read_to_string(&log).unwrap_or_default()
            );
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "the stages did not start"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let bus = Bus::join(
        &BusConfig {
            domain: domain.clone(),
            ..Default::default()
        }
        .settings(1),
        "fault-matrix",
    )
    .unwrap();
    let mut f = Follower {
        decisions: bus.subscriber().unwrap(),
        markers_in: bus.subscriber().unwrap(),
        attitudes_in: bus.subscriber().unwrap(),
        markers_seen: Vec::new(),
        attitudes_seen: Vec::new(),
        attitudes: bus.publisher().unwrap(),
        corrupt_decisions: bus.publisher().unwrap(),
        seen: Vec::new(),
        _bus: bus,
    };
    let clear_after = |after_ns: u64| {
        move |s: &[Seen]| {
            s.iter()
                .any(|d| d.state == DecisionState::ClearToLand && d.received_ns > after_ns)
        }
    };
    assert!(
        f.wait(Duration::from_secs(90), clear_after(0)),
        "the calm sea was never cleared: {:?}",
        f.seen.iter().map(|d| d.decision.reason.get()).collect::<Vec<_>>()
    );
    let mut rows: Vec<Row> = Vec::new();
    // Injects one fault while the deck is cleared (when `in_clear`), follows the pipeline back
    // to fresh decisions and records what it decided meanwhile.
    let mut run_fault =
        |f: &mut Follower, name: &str, in_clear: bool, inject: &mut dyn FnMut(&mut Follower)| {
            if in_clear {
                let since = monotonic_ns();
                let ok = f.wait(Duration::from_secs(60), |s| {
                    s.last()
                        .is_some_and(|d| d.state == DecisionState::ClearToLand && d.received_ns > since)
                });
                assert!(
                    ok,
                    "{name}: the pipeline did not clear again before the fault: {}\n{}",
                    reasons_since(&f.seen, since),
                    std::fs::read_to_string(&log).unwrap_or_default()
                );
            } else {
                let since = monotonic_ns();
                assert!(
                    f.fresh_after(since, Duration::from_secs(30)).is_some(),
                    "{name}: no fresh decisions before the fault"
                );
            }
            let start = monotonic_ns();
            inject(f);
            let fresh_at = f.fresh_after(start, Duration::from_secs(30));
            // A little more, to see what follows the recovery.
            let settle = monotonic_ns();
            f.wait(Duration::from_millis(500), |s| {
                s.last().is_some_and(|d| d.received_ns > settle + 400_000_000)
            });
            let end = fresh_at.unwrap_or(u64::MAX);
            let faulted: Vec<&Seen> = f
                .seen
                .iter()
                .filter(|d| d.received_ns > start + MAX_AGE_NS && d.received_ns < end)
                .collect();
            let cleared = faulted
                .iter()
                .filter(|d| d.state == DecisionState::ClearToLand)
                .count();
            let row = Row {
                fault: name.to_string(),
                start_ns: start,
                recovery_ms: fresh_at.map(|t| t.saturating_sub(start) as f64 / 1e6),
                while_faulted: faulted.len(),
                cleared_while_faulted: cleared,
            };
            println!(
                "{:<34} fresh decisions again after {:>8} ms; {} decisions while faulted, {} CLEAR",
                row.fault,
                row.recovery_ms.map_or("never".into(), |v| format!("{v:.0}")),
                row.while_faulted,
                row.cleared_while_faulted
            );
            rows.push(row);
        };

    // Hung and killed stages, while a landing is cleared.
    for (stage, sig, name) in [
        ("detect", libc::SIGSTOP, "detect SIGSTOP (hung)"),
        ("estimate", libc::SIGKILL, "estimate SIGKILL"),
        ("estimate", libc::SIGSTOP, "estimate SIGSTOP (hung)"),
        ("detect", libc::SIGKILL, "detect SIGKILL"),
    ] {
        let d = domain.clone();
        run_fault(&mut f, name, true, &mut |_| {
            signal(stage_pid(stage, &d).expect(stage), sig)
        });
    }
    // Corrupt messages: attitudes whose `valid` is the byte 2, decisions whose state is 9.
    run_fault(&mut f, "corrupt messages (20 + 20)", true, &mut |f| {
        let newest = f.newest();
        let mut bad = newest.attitude;
        bad.valid = WireBool::from_byte(2);
        let mut bad_decision = newest;
        bad_decision.state = WireCode::from_code(9);
        // Spaced out: the subscribers' queues hold 8.
        for _ in 0..20 {
            f.attitudes.send(&bad).unwrap();
            f.corrupt_decisions.send(&bad_decision).unwrap();
            f.wait(Duration::from_millis(20), |_| false);
        }
    });
    // A capture stamped 5 s in the future (a clock stepped on one machine): refused as a clock
    // jump, nothing else disturbed.
    run_fault(&mut f, "capture time 5 s in the future", true, &mut |f| {
        let mut a = f.newest().attitude;
        a.stamp.times.captured_ns = monotonic_ns() + 5_000_000_000;
        a.stamp.seq += 1;
        a.context.source_timestamp_ns += 1_000_000;
        f.attitudes.send(&a).unwrap();
    });
    // The launcher stopped for 3 s: the stages go on as before (it only watches; their stderr
    // lines go into a non-blocking pipe). Judged against the same pipeline in the 3 s before
    // the stop: the frames capture produced, and each stage's outputs per frame.
    let launcher_pid = launcher.id() as i32;
    let stop_domain = domain.clone();
    run_fault(&mut f, "launcher SIGSTOP for 3 s", true, &mut |f| {
        let before = monotonic_ns();
        f.wait(Duration::from_secs(3), |_| false);
        let stopped = monotonic_ns();
        signal(launcher_pid, libc::SIGSTOP);
        f.wait(Duration::from_millis(1500), |_| false);
        // What each stage is doing half-way through the stop.
        let states = stage_states(&stop_domain);
        f.wait(Duration::from_millis(1500), |_| false);
        let resumed = monotonic_ns();
        signal(launcher_pid, libc::SIGCONT);
        f.pump();
        let b = StageCounts::between(f, before, stopped);
        let d = StageCounts::between(f, stopped, resumed);
        println!("  3 s before the stop: {b}\n  3 s of the stop:     {d}");
        for s in &states {
            println!("  during the stop: {s}");
        }
        let on_pipe: Vec<&String> = states.iter().filter(|s| s.contains("pipe_w")).collect();
        assert!(on_pipe.is_empty(), "stages blocked on a pipe: {on_pipe:?}");
        assert!(
            d.frames > 0 && d.decisions > 0,
            "the pipeline stalled while the launcher was stopped: {d} (before: {b})\n{states:?}"
        );
        assert!(
            2 * d.frames >= b.frames,
            "capture slowed while the launcher was stopped: {d} (before: {b})\n{states:?}"
        );
        // Outputs per captured frame: at least half of what each stage kept up with before.
        for (stage, before_n, during_n) in [
            ("detect", b.markers, d.markers),
            ("estimate", b.attitudes, d.attitudes),
            ("decide", b.decisions, d.decisions),
        ] {
            assert!(
                2 * during_n * b.frames >= before_n * d.frames,
                "{stage} fell behind while the launcher was stopped: {d} (before: {b})\n{states:?}"
            );
        }
    });
    for (sig, name) in [
        (libc::SIGKILL, "link SIGKILL"),
        (libc::SIGSTOP, "link SIGSTOP (hung)"),
    ] {
        let d = domain.clone();
        run_fault(&mut f, name, true, &mut |f| {
            let old = stage_pid("link", &d).expect("link");
            signal(old, sig);
            // Decisions go on; the launcher replaces the link.
            let ok = f.wait(Duration::from_secs(10), |_| {
                stage_pid("link", &d).is_some_and(|p| p != old)
            });
            assert!(ok, "{name}: the link was not restarted");
        });
    }
    // The source's clock jumps 1000 s ahead for one frame: a gap, then three frames back in
    // time start a new timeline (warm-up again), without a restart.
    run_fault(&mut f, "source clock jumps 1000 s ahead", true, &mut |f| {
        let mut a = f.newest().attitude;
        a.stamp.times.captured_ns = monotonic_ns();
        a.context.source_timestamp_ns += 1_000_000_000_000;
        f.attitudes.send(&a).unwrap();
    });
    // Stages whose restart starts the decision's history afresh: no CLEAR until a new warm-up.
    for (stage, sig, name) in [
        ("decide", libc::SIGSTOP, "decide SIGSTOP (hung)"),
        ("decide", libc::SIGKILL, "decide SIGKILL"),
        ("capture", libc::SIGSTOP, "capture SIGSTOP (hung)"),
        ("capture", libc::SIGKILL, "capture SIGKILL"),
    ] {
        let d = domain.clone();
        run_fault(&mut f, name, false, &mut |_| {
            signal(stage_pid(stage, &d).expect(stage), sig)
        });
    }
    // After a restart of decide or capture the decisions warm up again: the first seconds of
    // fresh decisions are never CLEAR.
    let last_fault = f.seen.last().unwrap().received_ns;
    f.wait(Duration::from_secs(3), |_| false);
    let after: Vec<&Seen> = f.seen.iter().filter(|d| d.received_ns > last_fault).collect();
    assert!(after.len() > 20 && after.iter().all(|d| d.state != DecisionState::ClearToLand));

    // Stop the run and read its report.
    let seen = std::mem::take(&mut f.seen);
    drop(f);
    signal(launcher_pid, libc::SIGINT);
    let status = launcher.wait();
    let err = std::fs::read_to_string(&log).unwrap();
    let out = out_reader.join().unwrap();
    assert!(status.success(), "{err}");
    Bus::remove_idle_domain(&domain).unwrap();
    let report: serde_json::Value = serde_json::from_str(&out[out.find('{').expect(&out)..]).expect(&out);
    for r in &rows {
        assert!(r.recovery_ms.is_some(), "{}: never recovered\n{err}", r.fault);
        assert_eq!(r.cleared_while_faulted, 0, "{}: cleared while faulted", r.fault);
    }
    // When each fault's deck was cleared again (the next fault waited for it, or the end).
    for r in &rows {
        let again = seen
            .iter()
            .find(|d| d.received_ns > r.start_ns + MAX_AGE_NS && d.state == DecisionState::ClearToLand)
            .map(|d| (d.received_ns - r.start_ns) as f64 / 1e6);
        println!(
            "{:<34} CLEAR again after {}",
            r.fault,
            again.map_or("(not within the run)".into(), |v| format!("{v:.0} ms"))
        );
    }
    // The jump ahead starts a new timeline: clock-jump decisions, then a whole warm-up
    // (min_history_s, 10 s) before the next CLEAR.
    let jump = rows.iter().find(|r| r.fault.starts_with("source clock")).unwrap();
    let after_jump: Vec<&Seen> = seen.iter().filter(|d| d.received_ns > jump.start_ns).collect();
    assert!(after_jump
        .iter()
        .any(|d| d.decision.reason.get() == deckwatch_common::messages::DecisionReason::ClockJump));
    let first_clear = after_jump
        .iter()
        .find(|d| d.state == DecisionState::ClearToLand)
        .map(|d| d.received_ns - jump.start_ns);
    assert!(
        first_clear.is_none_or(|ns| ns > 10_000_000_000),
        "{first_clear:?}"
    );
    // Every stopped stage was noticed (within about a second) and every stopped or killed one
    // restarted: twice each.
    for stage in ["detect", "estimate", "decide", "capture", "link"] {
        assert!(
            err.contains(&format!("{stage} is not responding")),
            "{stage}'s hang was not noticed:\n{err}"
        );
    }
    let restarts: std::collections::HashMap<String, u64> = report["restarts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| (r[0].as_str().unwrap().to_string(), r[1].as_u64().unwrap()))
        .collect();
    for stage in ["detect", "estimate", "decide", "capture", "link"] {
        assert_eq!(restarts[stage], 2, "{stage}: {restarts:?}\n{err}");
    }
    // The corrupt messages were counted and skipped where they arrived.
    assert_eq!(report["bad_decisions_skipped"].as_u64(), Some(20), "{report}");
    assert!(
        err.contains("skipped a bad message on `deckwatch/attitude`"),
        "{err}"
    );
    assert!(
        err.contains("`AttitudeMessage.valid` holds 2, which is no bool"),
        "{err}"
    );
    assert!(
        err.contains("skipped a bad message on `deckwatch/decision`"),
        "{err}"
    );
}
