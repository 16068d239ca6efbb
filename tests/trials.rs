//! Closed-loop landings (`deckwatch trials`): a simulated vehicle lands on a spectrum sea through
//! the stage chain, judged at contact against the true deck; the same approach through the real
//! processes and the MAVLink link (signed: MAVLink 2 signing required) at real time lands alike; the first approach's rerun recording
//! is one the rerun CLI verifies.

use deckwatch_tests::{workspace_binary, PipelineGuard};
use std::process::{Command, Stdio};

/// `deckwatch trials --json`'s output, a value per line.
fn json_lines(stdout: Vec<u8>) -> Vec<serde_json::Value> {
    String::from_utf8(stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// One approach flown again alone (`trials --json --shard`): the run succeeds, its record is
/// approach `index`, and it did not touch down unsafely (no violation, no unsafe touchdown).
fn assert_flown_safely(out: std::process::Output, index: u64) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let lines = json_lines(out.stdout);
    let approach = lines
        .iter()
        .find_map(|l| l.get("approach"))
        .unwrap_or_else(|| panic!("no approach record: {lines:?}"));
    assert_eq!(approach["index"], index, "{approach}");
    if let Some(touchdown) = approach["outcome"]["touchdown"].as_object() {
        assert_eq!(touchdown["violations"], serde_json::json!([]), "{approach}");
    }
    assert!(
        lines.iter().all(|l| l.get("unsafe_touchdown").is_none()),
        "{lines:?}"
    );
}

#[test]
fn closed_loop_landings_touch_down_safely_in_one_process_and_through_the_processes() {
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("trial.rrd");
    // The link through the processes requires MAVLink 2 signing; the trial's autopilot signs with
    // the same key (the mavlink crate's signing; tests/mavlink_link.rs has pymavlink's).
    let key_file = dir.path().join("mavlink.key");
    deckwatch_tests::write_private_key(
        &key_file,
        &std::array::from_fn::<u8, 32, _>(|k| (k as u8).wrapping_mul(53).wrapping_add(0x8b)),
    );
    let config = dir.path().join("signed.toml");
    std::fs::write(
        &config,
        format!(
            "[link]\nsigning = \"required\"\nsigning_key_file = \"{}\"\nsigning_state_file = \"{}\"\n",
            key_file.display(),
            dir.path().join("signing.state").display()
        ),
    )
    .unwrap();
    let mut cmd = Command::new(workspace_binary("deckwatch"));
    cmd.arg("trials").arg("--config").arg(&config);
    cmd.args([
        "--json",
        "--sea-states",
        "3",
        "--seeds",
        "1",
        "--headings-deg",
        "30",
        "--approaches",
        "2",
        // The Pi camera's 640x480: at 320x240 the attitudes are noisy enough that this
        // approach's motion model is unreliable and it never lands (in either way).
        // Two minutes, the trials' own measure: the chain's first approach lands 41.9 s after
        // arrival, and through the processes on a loaded machine (CI's tests beside it) it once
        // went around (stale frames refused beside it) and did not touch down within 60 s.
        "--max-approach-s",
        "120",
        "--processes",
        "1",
    ])
    .arg("--rrd")
    .arg(&rrd)
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    // `--processes` runs each approach's stages on a domain named after the trials process.
    let mut trials = PipelineGuard::spawn(&mut cmd, "dwtrial-none");
    let pid = trials.id();
    for job in 0..2 {
        trials.also_domain(format!("dwtrial{pid}x{job}"));
    }
    let out = trials.wait_with_output();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let lines = json_lines(out.stdout);
    let rule = |name: &str| {
        lines
            .iter()
            .find(|l| l["sea_state"] == "all" && l["rule"] == name)
            .unwrap_or_else(|| panic!("no {name} totals: {lines:?}"))["summary"]
            .clone()
    };
    let deckwatch = rule("deckwatch");
    assert_eq!(deckwatch["approaches"], 2);
    assert_eq!(deckwatch["unsafe_touchdowns"], 0, "{deckwatch}");
    assert_eq!(deckwatch["touchdowns"], 2, "{deckwatch}");
    // The blind last metre of each descent rides through instead of aborting.
    assert!(
        deckwatch["decisions_by_reason"]["CLEAR ride-through"]
            .as_u64()
            .unwrap()
            > 0,
        "{deckwatch}"
    );
    let oracle = rule("oracle");
    assert_eq!(
        oracle["touchdowns"], 2,
        "the oracle always finds a safe contact: {oracle}"
    );
    assert_eq!(rule("naive")["approaches"], 2);
    // The first approach through the processes: it lands as it did in one process, in the same
    // calm spell. Not to the frame: the processes run at real time, the chain on a simulated
    // clock, and the vehicle's attitude reaches them through the link's clock estimate (the
    // compensated deck differed by up to 0.2 deg during the descent); the decision, without
    // fixed margins, then commits a frame or a second earlier or later (the chain lands at
    // 41.9 s on this seed now; before the gap filter, six runs through the processes gave 15.5
    // to 19.3 s against the chain's 17.8 s).
    let agreement = lines
        .iter()
        .find_map(|l| l.get("agreement"))
        .unwrap_or_else(|| panic!("no agreement line: {lines:?}\n{stderr}"));
    let contact = |side: &str| agreement[side]["touchdown"]["t_s"].as_f64();
    let (in_process, processes) = (contact("in_process"), contact("processes"));
    assert!(in_process.is_some(), "{agreement}");
    assert!(
        processes.is_some(),
        "through the processes: {agreement}\n{stderr}"
    );
    // The processes keep real time only when the machine keeps up with them: a loaded machine
    // (CI beside another build) makes frames late, the decision then rightly refuses
    // ("NO-DECK stale-data") and lands in a later calm spell. That is the safety rule working,
    // not a disagreement, so the times are compared only on a run that never went stale; the
    // safe contact above and below is asserted either way.
    let went_stale = agreement["processes"]["decisions_by_reason"]
        .as_object()
        .is_some_and(|reasons| reasons.keys().any(|r| r.ends_with("stale-data")));
    if went_stale {
        eprintln!(
            "the processes fell behind real time (stale data refused); contact times not compared: {agreement}"
        );
    } else {
        assert!(
            (in_process.unwrap() - processes.unwrap()).abs() <= 3.0,
            "the processes land within 3 s of the chain: {agreement}"
        );
    }
    for side in ["in_process", "processes"] {
        assert_eq!(
            agreement[side]["touchdown"]["violations"],
            serde_json::json!([]),
            "{agreement}"
        );
    }
    // The recording of the first approach: complete, and what the view shows is in it.
    #[cfg(feature = "rerun")]
    {
        let rows = deckwatch_viz::rrd_entity_rows(&rrd).unwrap();
        // Every frame of the approach (at 10 Hz; it lands after its 8 s warm-up, the band
        // checked on the warm-up's backtests: 10 s or more).
        assert!(rows.get("/camera/image").copied().unwrap_or(0) >= 80, "{rows:?}");
        for entity in [
            "/camera/image",
            "/heave/vehicle_over_deck_m",
            "/decision/state",
            "/decision_now",
            "/decision_log",
            "/attitude/roll/truth",
        ] {
            assert!(rows.contains_key(entity), "{entity} missing: {rows:?}");
        }
        // rerun's own reader: the file verifies.
        deckwatch_tests::assert_rrd_verifies(&rrd);
    }
}

/// The first unsafe touchdown any trial met (a 480-approach campaign on fresh seeds;
/// docs/history.md, "The first clearance after the warm-up"): sea state 6, seed 26, waves from
/// ahead, approach 16. It cleared 0.2 s after the warm-up, on heave-rate bands not yet checked
/// against what followed, and touched down into 0.678 m/s of heave rate. Flown again alone (the
/// last of 17 shards is that approach): it must not touch down unsafely. The campaign's vehicle
/// held 3 m over the deck's mean level; `--hold-height` with a clearance too small to matter
/// flies that approach again.
#[test]
fn the_campaigns_unsafe_approach_waits_for_its_rate_bands_evidence() {
    let out = Command::new(workspace_binary("deckwatch"))
        .args([
            "trials",
            "--json",
            "--rules",
            "deckwatch",
            "--sea-states",
            "6",
            "--seeds",
            "26",
            "--headings-deg",
            "0",
            "--approaches",
            "17",
            "--shard",
            "17/17",
            "--max-approach-s",
            "60",
            "--hold-height",
            "--wait-clearance-m",
            "0.3",
        ])
        .output()
        .unwrap();
    assert_flown_safely(out, 16);
}

/// An unsafe touchdown in main on fresh held-out seas (docs/history.md, "A rate's misses stand
/// for its error once they span 8 s"): sea state 5, seed 84, waves at 160 deg, approach 2 (the
/// third of six shards). It cleared 13.8 s after arrival on a heave-rate spread measured from
/// misses within 3 s (0.086 m/s) and touched down at 15.8 s into -0.689 m/s. Flown again
/// alone for as long: it must not touch down unsafely.
#[test]
fn a_rates_misses_from_the_first_seconds_do_not_clear_a_crest() {
    let out = Command::new(workspace_binary("deckwatch"))
        .args([
            "trials",
            "--json",
            "--rules",
            "deckwatch",
            "--sea-states",
            "5",
            "--seeds",
            "84",
            "--headings-deg",
            "160",
            "--approaches",
            "6",
            "--shard",
            "3/6",
            "--max-approach-s",
            "30",
        ])
        .output()
        .unwrap();
    assert_flown_safely(out, 2);
}

/// Landings on ship motion that is not the forecaster's spectrum sea (issue 70): a motion file
/// written by `deckwatch sim motion` for the nonlinear roll and for short-crested seas under way
/// (sea state 5, beam and quartering waves), flown by `trials --motion-csv`. Nothing touches
/// down unsafely.
#[test]
fn landings_on_other_ship_motion_models_touch_down_safely() {
    let dir = tempfile::tempdir().unwrap();
    for (model, heading) in [("nonlinear-roll", "90"), ("short-crested", "135")] {
        let file = dir.path().join(format!("{model}.csv"));
        let out = Command::new(workspace_binary("deckwatch"))
            .args([
                "sim",
                "motion",
                "--model",
                model,
                "--sea-state",
                "5",
                "--heading-deg",
                heading,
            ])
            .args(["--seed", "11", "--minutes", "4", "--out"])
            .arg(&file)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let out = Command::new(workspace_binary("deckwatch"))
            .args(["trials", "--json", "--rules", "deckwatch", "--motion-csv"])
            .arg(&file)
            .args(["--seeds", "1", "--approaches", "2", "--max-approach-s", "60"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{model}: {stderr}");
        let lines = json_lines(out.stdout);
        let approaches: Vec<_> = lines.iter().filter_map(|l| l.get("approach")).collect();
        assert_eq!(approaches.len(), 2, "{model}: {lines:?}");
        for approach in approaches {
            if let Some(touchdown) = approach["outcome"]["touchdown"].as_object() {
                assert_eq!(
                    touchdown["violations"],
                    serde_json::json!([]),
                    "{model}: {approach}"
                );
            }
        }
        assert!(
            lines.iter().all(|l| l.get("unsafe_touchdown").is_none()),
            "{model}: {lines:?}"
        );
    }
}

/// `--watch-before-s` is checked before anything flies: a negative or non-finite watch, and a
/// watch with approaches through the processes (which start on arrival), are refused by name.
#[test]
fn a_watch_before_the_request_is_checked_before_anything_flies() {
    for args in [
        vec!["--watch-before-s=-1"],
        vec!["--watch-before-s", "NaN"],
        vec!["--watch-before-s", "30", "--processes", "1"],
    ] {
        let out = Command::new(workspace_binary("deckwatch"))
            .args([
                "trials",
                "--rules",
                "deckwatch",
                "--seeds",
                "1",
                "--sea-states",
                "3",
            ])
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains("--watch-before-s"), "{args:?}: {stderr}");
    }
}
