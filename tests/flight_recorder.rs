//! The flight recorder (issue 17) against readers nobody here wrote: a recorded run of the real
//! processes is read by the Python `mcap` package (every channel, its schema, the message counts)
//! and converted and verified by rerun-sdk's `rerun` command; the same build re-simulates it bit
//! for bit, a changed estimator shows where the outputs part, and it replays through the
//! processes; a recorder killed with SIGKILL leaves a file both readers read up to its last
//! complete chunk, which `deckwatch recover` completes, and the launcher restarts it into a new
//! file; a recording folder converts to MCAP and back unchanged.
//!
//! Needs the test peers of `ci/peers.sh` (mcap, rerun-sdk in ~/.cache/deckwatch-venv).

use deckwatch_tests::{peer_python, peer_rerun, pipeline_output, workspace_binary, PipelineGuard};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn domain(test: &str) -> String {
    format!("t{}-{test}", std::process::id())
}

fn deckwatch() -> PathBuf {
    workspace_binary("deckwatch")
}

fn ok(out: Output, what: &str) -> String {
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{what}: {}\nstdout: {text}\nstderr: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// What the Python `mcap` package finds in a file (tests/peers/mcap_check.py).
fn mcap_check(path: &Path) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers/mcap_check.py");
    let out = Command::new(peer_python("mcap"))
        .arg(script)
        .arg(path)
        .output()
        .expect("python");
    serde_json::from_str(&ok(out, "mcap_check.py")).expect("JSON from mcap_check.py")
}

fn count(v: &Value, topic: &str) -> u64 {
    v["channels"][topic]["count"].as_u64().unwrap_or(0)
}

/// A small simulator run's configuration (640x480 at 20 fps). The recorder may hold every frame
/// (`queue_frames`): its writer runs at idle priority, so on a loaded machine it falls behind and
/// would drop frames (counted, its answer to a slow disk), and these tests count what was
/// recorded. The queue is written out when the recorder stops.
fn config(dir: &Path, frames: u32, record: &Path) -> PathBuf {
    let path = dir.join("pipeline.toml");
    let text = format!(
        "[sim]\nframes = {frames}\nrate = 20.0\n[image]\nwidth = 640\nheight = 480\n[rerun]\nsink = \"off\"\n\
         [record]\npath = \"{}\"\nframes = \"raw\"\nqueue_frames = {}\n",
        record.display(),
        frames.clamp(1, 256)
    );
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_recorded_flight_opens_in_other_readers_and_resimulates_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.mcap");
    let cfg = config(dir.path(), 40, &a);
    let out = pipeline_output(
        Command::new(deckwatch())
            .args(["run", "--quiet", "--json", "--domain", &domain("rec")])
            .arg("--config")
            .arg(&cfg),
        &domain("rec"),
    );
    // The recorder and the launcher's log node left nothing in shared memory (seen when the
    // run ended, before the test's guard cleaned up).
    assert!(out.left_at_exit.is_empty(), "{:?}", out.left_at_exit);
    let report: Value = serde_json::from_str(&ok(out.into(), "deckwatch run --record")).unwrap();
    let decisions = report["decisions"].as_u64().unwrap();
    let recorded_rmse = report["rmse_deg"].clone();
    assert!(decisions >= 40, "{report}");

    // The Python reader: every channel with its schema, the counts the run reported.
    let v = mcap_check(&a);
    assert_eq!(v["summary"], true, "{v}");
    assert_eq!(v["stream_complete"], true, "{v}");
    for (topic, schema, encoding) in [
        ("/camera/image", "foxglove.RawImage", "protobuf"),
        ("/camera/calibration", "foxglove.CameraCalibration", "protobuf"),
        ("/deckwatch/log", "foxglove.Log", "protobuf"),
        ("/deckwatch/frame", "deckwatch.FrameHeader", "json"),
        ("/deckwatch/markers", "deckwatch.MarkerMessage", "json"),
        ("/deckwatch/attitude", "deckwatch.AttitudeMessage", "json"),
        ("/deckwatch/decision", "deckwatch.LandingDecision", "json"),
        ("/deckwatch/recorder", "deckwatch.RecorderStats", "json"),
    ] {
        let c = &v["channels"][topic];
        assert_eq!(c["schema"], schema, "{topic}: {v}");
        assert_eq!(c["message_encoding"], encoding, "{topic}");
        let schema_encoding = if encoding == "json" {
            "jsonschema"
        } else {
            "protobuf"
        };
        assert_eq!(c["schema_encoding"], schema_encoding, "{topic}");
        assert_eq!(
            v["iterated"][topic], c["count"],
            "{topic}: summary and messages agree"
        );
    }
    for topic in [
        "/camera/image",
        "/deckwatch/frame",
        "/deckwatch/markers",
        "/deckwatch/attitude",
    ] {
        assert_eq!(count(&v, topic), 40, "{topic}: every frame");
    }
    // Every decision the launcher saw, and the watchdog's last one, which comes after the launcher
    // stops listening (the recorder is stopped last).
    let recorded = count(&v, "/deckwatch/decision");
    assert!(
        (decisions..=decisions + 1).contains(&recorded),
        "{recorded} vs {decisions}"
    );
    // The launcher's line for each stage it started (kept for the recorder until it subscribes:
    // lost once in CI) and each stage's closing line are in the log (the lines themselves in the
    // message: a line lost on a loaded machine says which).
    let lines: Vec<&str> = v["log_lines"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    for expected in [
        "deckwatch: started record",
        "deckwatch: started capture",
        "deckwatch: started detect",
        "deckwatch: started estimate",
        "deckwatch: started decide",
        "deckwatch-capture: 40 frames published",
        "deckwatch-detect: 40 frames processed",
        "deckwatch-estimate: 40 marker sets",
        "deckwatch-decide: 40 attitudes",
    ] {
        assert!(
            lines.iter().any(|l| l.starts_with(expected)),
            "`{expected}` not in the log lines: {lines:#?}\n{v}"
        );
    }
    assert_eq!(
        v["first_json"]["/deckwatch/attitude"].as_array().unwrap().len(),
        19
    );
    for name in ["deckwatch", "deckwatch.clock", "deckwatch.camera"] {
        assert!(v["metadata"][name].is_object(), "metadata {name}: {v}");
    }
    assert_eq!(v["metadata"]["deckwatch"]["source"], "sim");
    assert_eq!(v["attachments"][0]["name"], "pipeline.toml");

    // rerun's own MCAP importer takes it, and finds the images and the log.
    let rerun = peer_rerun();
    let rrd = dir.path().join("a.rrd");
    ok(
        Command::new(&rerun)
            .args(["mcap", "convert"])
            .arg(&a)
            .arg("-o")
            .arg(&rrd)
            .output()
            .unwrap(),
        "rerun mcap convert",
    );
    ok(
        Command::new(&rerun)
            .args(["rrd", "verify"])
            .arg(&rrd)
            .output()
            .unwrap(),
        "rerun rrd verify",
    );
    let printed = ok(
        Command::new(&rerun)
            .args(["rrd", "print"])
            .arg(&rrd)
            .output()
            .unwrap(),
        "rerun rrd print",
    );
    // "Chunk(..) with 8 rows (2.4 MiB) - /camera/image - data columns: [.. Image:buffer ..]"
    let images: u64 = printed
        .lines()
        .filter(|l| l.contains("/camera/image") && l.contains("Image:buffer"))
        .filter_map(|l| {
            l.split(" with ")
                .nth(1)?
                .split(" rows")
                .next()?
                .trim()
                .parse::<u64>()
                .ok()
        })
        .sum();
    assert!(images >= 40, "rerun found {images} images:\n{printed}");
    assert!(printed
        .lines()
        .any(|l| l.contains("/deckwatch/log") && l.contains("TextLog")));
    assert!(printed
        .lines()
        .any(|l| l.contains("/camera/calibration") && l.contains("Pinhole")));

    // Re-simulation through the same build: the same outputs, every field.
    let b = dir.path().join("b.mcap");
    let text = ok(
        Command::new(deckwatch())
            .arg("replay")
            .arg(&a)
            .arg("--resim")
            .arg(&b)
            .output()
            .unwrap(),
        "deckwatch replay --resim",
    );
    for stage in ["detect", "estimate", "decide"] {
        assert!(
            text.lines()
                .any(|l| l.starts_with(stage) && l.contains("identical")),
            "{stage}:\n{text}"
        );
    }
    let diff = Command::new(deckwatch())
        .arg("diff")
        .arg(&a)
        .arg(&b)
        .output()
        .unwrap();
    assert!(diff.status.success(), "{}", String::from_utf8_lossy(&diff.stdout));
    assert_eq!(count(&mcap_check(&b), "/deckwatch/attitude"), 40);

    // Another estimator: `diff` says where the outputs part (exit status 1).
    let paper = dir.path().join("paper.toml");
    std::fs::write(&paper, "[estimate]\nestimator = \"paper-atan2\"\n").unwrap();
    let c = dir.path().join("c.mcap");
    ok(
        Command::new(deckwatch())
            .arg("replay")
            .arg(&a)
            .arg("--resim")
            .arg(&c)
            .arg("--config")
            .arg(&paper)
            .output()
            .unwrap(),
        "deckwatch replay --resim --config paper.toml",
    );
    let diff = Command::new(deckwatch())
        .arg("diff")
        .arg(&a)
        .arg(&c)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&diff.stdout);
    assert_eq!(diff.status.code(), Some(1), "{text}");
    assert!(text.contains("detect   identical"), "{text}");
    assert!(
        text.lines()
            .any(|l| l.starts_with("estimate") && l.contains("40 differ")),
        "{text}"
    );
    assert!(
        text.contains("attitude.estimator") || text.contains("estimator: A"),
        "{text}"
    );

    // The recorded flight through the processes again, at its recorded rate.
    let out = pipeline_output(
        Command::new(deckwatch())
            .args(["run", "--quiet", "--json", "--domain", &domain("replay")])
            .arg("--source")
            .arg("replay")
            .arg(&a),
        &domain("replay"),
    )
    .into();
    let report: Value = serde_json::from_str(&ok(out, "deckwatch run --source replay a.mcap")).unwrap();
    // Latest-frame semantics: a frame detect passes over on a busy machine is a counted drop.
    let valid = report["valid_attitudes"].as_u64().unwrap();
    let passed_over = report["drops"]["detect"].as_u64().unwrap();
    assert!(valid >= 20 && valid + passed_over == 40, "{report}");
    // The truth travels with the frames; when detect took every frame, the replay estimates
    // what the flight estimated.
    assert!(report["rmse_deg"].is_array(), "{report}");
    if passed_over == 0 {
        assert_eq!(report["rmse_deg"], recorded_rmse, "{report}");
    }
}

#[test]
fn a_killed_recorder_leaves_a_readable_file_and_is_restarted() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.mcap");
    let cfg = dir.path().join("pipeline.toml");
    std::fs::write(
        &cfg,
        format!(
            "[sim]\nframes = 400\nrate = 20.0\n[image]\nwidth = 640\nheight = 480\n[rerun]\nsink = \"off\"\n\
             [record]\npath = \"{}\"\nflush_interval_ms = 200\n",
            a.display()
        ),
    )
    .unwrap();
    let d = domain("kill");
    let mut run = PipelineGuard::spawn(
        Command::new(deckwatch())
            .args(["run", "--quiet", "--json", "--domain", &d])
            .arg("--config")
            .arg(&cfg)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped()),
        &d,
    );
    // Kill the recorder once a streaming read of its file finds 20 images (the run is 20 s
    // long): by what it flushed, not by a time, since its writer runs at idle priority and a
    // loaded machine's gets little.
    let started = Instant::now();
    let streamed_in = |v: &Value, topic: &str| v["streamed"][topic].as_u64().unwrap_or(0);
    let (recorder, images_before_kill, attitudes_before_kill) = loop {
        let found = deckwatch_runtime::stage::stage_processes(&d)
            .into_iter()
            .find(|(name, _)| name == "record");
        if let Some((_, pid)) = found.filter(|_| a.exists()) {
            let v = mcap_check(&a);
            let (images, attitudes) = (
                streamed_in(&v, "/camera/image"),
                streamed_in(&v, "/deckwatch/attitude"),
            );
            if images >= 20 && attitudes >= 20 {
                break (pid, images, attitudes);
            }
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "no recorder process, or nothing flushed"
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    // SAFETY: kill(2) on the recorder process of this test's own pipeline.
    unsafe { libc::kill(recorder as i32, libc::SIGKILL) };
    let out = run.wait_with_output();
    let report: Value = serde_json::from_str(&ok(out, "deckwatch run")).unwrap();
    let restarts = report["restarts"].as_array().unwrap();
    assert!(restarts.iter().any(|r| r[0] == "record" && r[1] == 1), "{report}");

    // The killed recorder's file: no summary, but a streaming read gets what it flushed.
    let v = mcap_check(&a);
    assert_eq!(v["summary"], false, "{v}");
    let streamed = |topic: &str| v["streamed"][topic].as_u64().unwrap_or(0);
    assert!(
        streamed("/camera/image") >= images_before_kill,
        "{images_before_kill} images read before the kill: {v}"
    );
    assert!(streamed("/deckwatch/attitude") >= attitudes_before_kill, "{v}");

    // `deckwatch recover` makes it complete: the same messages, with the index.
    let fixed = dir.path().join("fixed.mcap");
    let text = ok(
        Command::new(deckwatch())
            .arg("recover")
            .arg(&a)
            .arg(&fixed)
            .output()
            .unwrap(),
        "deckwatch recover",
    );
    assert!(text.contains("recovered"), "{text}");
    let f = mcap_check(&fixed);
    assert_eq!(f["summary"], true, "{f}");
    for (topic, n) in v["streamed"].as_object().unwrap() {
        assert_eq!(&f["channels"][topic]["count"], n, "{topic}: {f}");
    }

    // The restarted recorder wrote a file of its own beside it, complete.
    let restarted: Vec<PathBuf> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.to_string_lossy().contains("a.restart-"))
        .collect();
    assert_eq!(restarted.len(), 1, "{restarted:?}");
    let r = mcap_check(&restarted[0]);
    assert_eq!(r["summary"], true, "{r}");
    assert_eq!(r["metadata"]["deckwatch"]["restarted"], "true");
    assert!(count(&r, "/camera/image") >= 20, "{r}");
}

#[test]
fn a_recording_folder_converts_to_mcap_and_back() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ship-640x480");
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("ship.mcap");
    ok(
        Command::new(deckwatch())
            .arg("convert")
            .arg(&data)
            .arg(&m)
            .output()
            .unwrap(),
        "deckwatch convert DIR FILE.mcap",
    );
    let original = deckwatch_formats::Recording::open(&data).unwrap();
    let n = original.frames.len() as u64;
    let v = mcap_check(&m);
    assert_eq!(
        v["channels"]["/camera/image/compressed"]["schema"],
        "foxglove.CompressedImage"
    );
    assert_eq!(count(&v, "/camera/image/compressed"), n, "{v}");
    assert_eq!(count(&v, "/deckwatch/frame"), n);

    let back = dir.path().join("back");
    ok(
        Command::new(deckwatch())
            .arg("convert")
            .arg(&m)
            .arg(&back)
            .output()
            .unwrap(),
        "deckwatch convert FILE.mcap DIR",
    );
    let copy = deckwatch_formats::Recording::open(&back).unwrap();
    assert_eq!(copy.camera, original.camera);
    assert_eq!(copy.deck, original.deck);
    assert_eq!(copy.frames.len(), original.frames.len());
    assert_eq!(copy.has_attitude_truth(), original.has_attitude_truth());
    for (a, b) in original.frames.iter().zip(&copy.frames) {
        assert_eq!(a.timestamp_ns, b.timestamp_ns);
        let (ta, tb) = (a.truth.attitude(), b.truth.attitude());
        assert_eq!(ta.is_some(), tb.is_some(), "frame {}", a.index);
        if let (Some(x), Some(y)) = (ta, tb) {
            let e = deckwatch_common::rotation::rpy_error_deg(&x, &y);
            assert!(e.iter().all(|d| d.abs() < 1e-9), "frame {}: {e:?}", a.index);
        }
        assert_eq!(a.truth.alt_m, b.truth.alt_m);
        assert_eq!(
            original.read_image(a).unwrap().data,
            copy.read_image(b).unwrap().data,
            "frame {}: pixels",
            a.index
        );
    }
}
