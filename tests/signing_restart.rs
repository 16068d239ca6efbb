//! Replays across a restart of the link, and relays from another address, against pymavlink
//! (issue 72, items 2 and 3). Three runs of the whole pipeline (`deckwatch run`, the link signed)
//! on the simulator, one after the other:
//!
//! 1. pymavlink's autopilot (tests/peers/autopilot.py) streams its signed attitude and captures
//!    its first 50 frames; every 10th attitude it sends from a second socket, as a relay on
//!    another host would. The relayed frames are authentic and believed, counted as from another
//!    address, and the relay's socket hears nothing: the replies stay with the autopilot.
//! 2. The link restarted, its signing state kept: pymavlink's attacker replays the captured
//!    frames. Every one is refused as a replay; no attitude reaches the pipeline; no CLEAR.
//! 3. The same restart with the kept state removed (the link as it was before it kept one): the
//!    same replay passes the signing, 50 frames believed. That is the attack the kept state
//!    stops.
//!
//! Needs python3 with pymavlink (`ci/peers.sh`).

use deckwatch_tests::{pipeline_output, workspace_binary, PipelineGuard};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const RATE_HZ: f64 = 20.0;

/// The link's closing line from a run's standard error.
fn link_line(stderr: &str) -> String {
    stderr
        .lines()
        .find(|l| l.contains("deckwatch-link:") && l.contains("frames admitted"))
        .unwrap_or_else(|| panic!("the link's closing line:\n{stderr}"))
        .to_string()
}

/// The number just before `what` in `line` ("12 attitudes (" -> 12).
fn number_before(line: &str, what: &str) -> u64 {
    line.split(what)
        .next()
        .and_then(|s| s.rsplit([' ', '(']).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no number before `{what}` in: {line}"))
}

/// The count of refusals for `cause` ("replay 250" -> 250; 0 when not named).
fn refused(line: &str, cause: &str) -> u64 {
    line.split(&format!("{cause} "))
        .nth(1)
        .and_then(|r| r.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

struct Setup {
    dir: tempfile::TempDir,
    port: u16,
    key_hex: String,
    state: PathBuf,
}

impl Setup {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let key: [u8; 32] = std::array::from_fn(|k| (k as u8).wrapping_mul(29).wrapping_add(0x61));
        deckwatch_tests::write_private_key(&dir.path().join("mavlink.key"), &key);
        let state = dir.path().join("signing.state");
        Self {
            port: deckwatch_tests::free_udp_port(),
            key_hex: key.iter().map(|b| format!("{b:02x}")).collect(),
            state,
            dir,
        }
    }

    /// One run of the pipeline for `frames` frames, returning its standard error and the
    /// decisions' states.
    fn run(&self, name: &str, frames: usize) -> (String, Vec<String>) {
        let domain = format!("t{}-{name}", std::process::id());
        let config = self.dir.path().join(format!("{name}.toml"));
        std::fs::write(
            &config,
            format!(
                "[bus]\ndomain = \"{domain}\"\n\
                 [sim]\nframes = {frames}\nrate = {RATE_HZ}\n\
                 [vehicle]\nattitude = \"autopilot\"\n\
                 [link]\nenabled = true\naddress = \"udpin:127.0.0.1:{}\"\nsigning = \"required\"\n\
                 signing_key_file = \"{}\"\nsigning_state_file = \"{}\"\n\
                 [rerun]\nsink = \"off\"\n",
                self.port,
                self.dir.path().join("mavlink.key").display(),
                self.state.display()
            ),
        )
        .unwrap();
        let decisions = self.dir.path().join(format!("{name}.csv"));
        let run = pipeline_output(
            Command::new(workspace_binary("deckwatch"))
                .args(["run", "--quiet", "--config"])
                .arg(&config)
                .arg("--decisions")
                .arg(&decisions),
            &domain,
        );
        let stderr = String::from_utf8_lossy(&run.stderr).to_string();
        assert!(run.status.success(), "deckwatch run ({name}) failed:\n{stderr}");
        let text = std::fs::read_to_string(&decisions).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let state = header.iter().position(|h| *h == "state").unwrap();
        let states = lines
            .map(|l| l.split(',').nth(state).unwrap_or_default().to_string())
            .collect();
        (stderr, states)
    }

    fn attacker(&self, captured: &Path) -> PipelineGuard {
        PipelineGuard::spawn_peer(
            Command::new(deckwatch_tests::pymavlink_python())
                .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/attacker.py"))
                .args(["--port", &self.port.to_string(), "--key-hex", &self.key_hex])
                .args(["--kinds", "replay", "--start-after-s", "1.5", "--duration-s", "4"])
                .arg("--replay")
                .arg(captured)
                .stdout(Stdio::piped()),
        )
    }
}

fn json(out: &std::process::Output, who: &str) -> serde_json::Value {
    assert!(out.status.success(), "{who} failed");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{who}'s JSON summary: {e}"))
}

#[test]
fn frames_captured_before_a_restart_are_refused_after_it_and_a_relay_takes_no_replies() {
    let s = Setup::new();
    let captured = s.dir.path().join("captured.hex");

    // 1. The autopilot's flight, a relay beside it.
    let mut autopilot = PipelineGuard::spawn_peer(
        Command::new(deckwatch_tests::pymavlink_python())
            .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/autopilot.py"))
            .args([
                "--port",
                &s.port.to_string(),
                "--stop-after-s",
                "7",
                "--linger-s",
                "1",
            ])
            .args(["--key-hex", &s.key_hex, "--relay-every", "10", "--tlog"])
            .arg(s.dir.path().join("flight.tlog"))
            .arg("--capture")
            .arg(&captured)
            .stdout(Stdio::piped()),
    );
    let (stderr, _) = s.run("flight", (8.0 * RATE_HZ) as usize);
    let seen = json(&autopilot.wait_with_output(), "the pymavlink autopilot");
    let line = link_line(&stderr);
    assert!(seen["relayed"].as_u64().unwrap() >= 20, "{seen}");
    assert_eq!(
        seen["relay_received"], 0,
        "deckwatch replied to the relay: {line}"
    );
    let elsewhere = number_before(&line, " from another address");
    assert!(
        elsewhere * 2 >= seen["relayed"].as_u64().unwrap(),
        "{elsewhere} frames counted from another address, {} relayed: {line}",
        seen["relayed"]
    );
    assert!(
        seen["counts"]["HEARTBEAT"].as_u64().unwrap_or(0) > 3,
        "replies reached the autopilot: {seen}"
    );
    assert!(line.contains("signing state kept in"), "{line}");
    let kept = std::fs::read_to_string(&s.state).unwrap();
    assert!(
        kept.contains("clean 1") && kept.contains("stream 1 1 1 "),
        "{kept}"
    );

    // 2. Restarted with the kept state: the replay is refused, frame for frame.
    let mut attacker = s.attacker(&captured);
    let (stderr, states) = s.run("restart", (7.0 * RATE_HZ) as usize);
    let attack = json(&attacker.wait_with_output(), "the pymavlink attacker");
    let line = link_line(&stderr);
    let sent = attack["sent"]["replay"].as_u64().unwrap();
    assert!(sent >= 100, "{attack}");
    assert!(
        refused(&line, "replay") >= sent * 9 / 10,
        "{sent} replayed: {line}"
    );
    assert_eq!(number_before(&line, " frames admitted"), 0, "{line}");
    assert_eq!(number_before(&line, " attitudes ("), 0, "{line}");
    assert!(
        !states.is_empty() && states.iter().all(|s| s != "CLEAR"),
        "{states:?}"
    );

    // 3. The same restart without the kept state: the replay is believed (the attack).
    std::fs::remove_file(&s.state).unwrap();
    let mut attacker = s.attacker(&captured);
    let (stderr, _) = s.run("forgetful", (7.0 * RATE_HZ) as usize);
    json(&attacker.wait_with_output(), "the pymavlink attacker");
    let line = link_line(&stderr);
    // Believed by the signing (the link's own checks of an attitude then judge its time).
    assert!(
        number_before(&line, " frames admitted") >= 40,
        "without the kept state the captured frames pass: {line}"
    );
}
