//! The command-line tools end to end: the marker-table pipe (`sim markers | estimate-table`), bad input rows, recording
//! checks and the sweep.

use deckwatch_common::{CameraModel, DeckLayout, GrayImage, GroundTruth};
use deckwatch_formats::RecordingWriter;
use deckwatch_tests::workspace_binary;
use std::io::Write;
use std::process::{Command, Stdio};

/// `deckwatch estimate-table ARGS` with `input` on stdin.
fn run_with_input(args: &[&str], input: &[u8]) -> std::process::Output {
    let mut child = Command::new(workspace_binary("deckwatch"))
        .arg("estimate-table")
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input).unwrap();
    child.wait_with_output().unwrap()
}

#[test]
fn capture_pipes_into_estimate_exactly() {
    let table = Command::new(workspace_binary("deckwatch"))
        .args([
            "sim",
            "markers",
            "--scenario",
            "offset",
            "--frames",
            "200",
            "--seed",
            "3",
        ])
        .output()
        .unwrap();
    assert!(
        table.status.success(),
        "{}",
        String::from_utf8_lossy(&table.stderr)
    );
    let out = run_with_input(&["--variant", "atan2"], &table.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let mut rows = 0;
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[col("status")], "ok", "{line}");
        for c in ["err_roll_deg", "err_pitch_deg", "err_yaw_deg"] {
            let e: f64 = f[col(c)].parse().unwrap();
            assert!(e.abs() < 1e-9, "{c} = {e} in {line}");
        }
        rows += 1;
    }
    assert_eq!(rows, 200);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("200 frames, 200 estimated"), "{stderr}");
}

#[test]
fn bad_rows_are_reported_counted_and_skipped() {
    let table = Command::new(workspace_binary("deckwatch"))
        .args(["sim", "markers", "--frames", "5"])
        .output()
        .unwrap();
    let text = String::from_utf8(table.stdout).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    // Line 3 of the file (the second data row): corrupt marker 2's u.
    let mut f: Vec<String> = lines[2].split(',').map(str::to_string).collect();
    f[7] = "oops".into();
    lines[2] = f.join(",");
    // Line 5: hide marker 0 (the centre): a valid row that is not estimable.
    let mut f: Vec<String> = lines[4].split(',').map(str::to_string).collect();
    f[3] = "nan".into();
    f[4] = "nan".into();
    lines[4] = f.join(",");
    let input = lines.join("\n") + "\n";
    let out = run_with_input(&[], input.as_bytes());
    assert_eq!(out.status.code(), Some(2), "bad rows make the exit code 2");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("stdin:3: field `m2_u`: `oops` is not a finite number"),
        "{stderr}"
    );
    assert!(stderr.contains("4 frames, 3 estimated"), "{stderr}");
    assert!(stderr.contains("the centre marker is not visible"), "{stderr}");
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert_eq!(stdout.lines().count(), 5, "header + 4 frames");
    assert!(stdout
        .lines()
        .any(|l| l.starts_with("3,") && l.contains("not_estimable")));
}

#[test]
fn recording_check_reads_every_image_and_names_bad_ones() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec");
    let cam = CameraModel::rpi_v2().scaled_to(32, 24);
    let mut w = RecordingWriter::create(
        &rec,
        &cam,
        &DeckLayout::paper(),
        deckwatch_formats::recording::LEVEL_TRUTH,
    )
    .unwrap();
    let img = GrayImage::new(32, 24);
    for i in 0..3 {
        let truth = GroundTruth {
            roll_deg: (i != 1).then_some(1.0),
            pitch_deg: (i != 1).then_some(2.0),
            yaw_deg: (i != 1).then_some(3.0),
            ..GroundTruth::default()
        };
        w.write_frame(i, i * 100_000_000, img.view(), &truth).unwrap();
    }
    w.finish().unwrap();
    let deckwatch = workspace_binary("deckwatch");
    let out = Command::new(&deckwatch)
        .args(["recording", "check"])
        .arg(&rec)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("3 frames of 32x24") && stdout.contains("1 frames without deck"),
        "{stdout}"
    );
    std::fs::write(rec.join("frames/000002.png"), b"junk").unwrap();
    let out = Command::new(&deckwatch)
        .args(["recording", "check"])
        .arg(&rec)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("000002.png") && stderr.contains("frames.csv line 4"),
        "{stderr}"
    );
}

/// A report whose reader has gone (`deckwatch eval REC | head -0`) ends with it, as Unix tools
/// do, instead of panicking on the closed pipe ("failed printing to stdout: Broken pipe").
#[test]
fn a_report_ends_quietly_when_its_reader_goes() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec");
    let made = Command::new(workspace_binary("deckwatch"))
        .args([
            "sim", "record", "--frames", "3", "--width", "640", "--height", "480", "--out",
        ])
        .arg(&rec)
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    let mut child = Command::new(workspace_binary("deckwatch"))
        .arg("eval")
        .arg(&rec)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes before the report is written.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        out.status.success() || out.status.signal() == Some(libc::SIGPIPE),
        "{:?}: {stderr}",
        out.status
    );
}

/// Output that cannot be written for another reason than a closed reader (a full disk) fails
/// the command and says so: the file it went to is incomplete.
#[test]
fn output_to_a_full_disk_fails_the_command() {
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["run", "--print-config"])
        .stdout(full)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("the output is incomplete") && !stderr.contains("panicked"),
        "{stderr}"
    );
}

#[test]
fn sweep_compares_the_variants() {
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["sweep", "--scenario", "case1", "--frames", "101", "--rate", "5"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    for v in ["printed", "fitted-major-axis", "atan2"] {
        assert!(
            stdout.lines().any(|l| l.starts_with(v) && l.contains("101/101")),
            "{stdout}"
        );
    }
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["sweep", "--scenario", "storm"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--scenario") && stderr.contains("storm"),
        "{stderr}"
    );
}

#[test]
fn inproc_replays_recordings_and_simulates() {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/");
    let deckwatch = workspace_binary("deckwatch");
    let out = Command::new(&deckwatch)
        .args([
            "inproc",
            "--source",
            "replay",
            "--recording",
            &format!("{data}ship-640x480"),
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("8 frames (0 bad, skipped): 8 ok"), "{stdout}");
    assert!(
        stdout.contains("attitude error vs ground truth (8 frames)"),
        "{stdout}"
    );
    for stage in ["capture:", "detect:", "estimate:"] {
        assert!(stdout.contains(stage), "{stdout}");
    }
    let out = Command::new(&deckwatch)
        .args([
            "inproc",
            "--source",
            "replay",
            "--recording",
            &format!("{data}nodeck-640x480"),
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("3 no deck") && stdout.contains("0 attitudes"),
        "{stdout}"
    );
    assert!(!stdout.contains("WARNING"), "{stdout}");
    // A bad frame in a recording is counted and skipped.
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec");
    let copy = |from: &str| {
        std::fs::create_dir_all(rec.join("frames")).unwrap();
        for f in ["camera.json", "frames.csv"] {
            std::fs::copy(format!("{data}{from}/{f}"), rec.join(f)).unwrap();
        }
        for e in std::fs::read_dir(format!("{data}{from}/frames")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), rec.join("frames").join(e.file_name())).unwrap();
        }
    };
    copy("offset-640x480");
    std::fs::write(rec.join("frames/000001.png"), b"broken").unwrap();
    let out = Command::new(&deckwatch)
        .args(["inproc", "--source", "replay", "--recording"])
        .arg(&rec)
        .output()
        .unwrap();
    assert!(out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("3 frames (1 bad, skipped): 3 ok"), "{stdout}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("000001.png"));
    // The simulator source, small and quick.
    let out = Command::new(&deckwatch)
        .args([
            "inproc", "--frames", "5", "--width", "640", "--height", "480", "--every", "0",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("5 frames (0 bad, skipped): 5 ok"));
}

/// `deckwatch doctor`: on this machine with the defaults everything a run needs is there; a
/// configuration with a serial port that does not exist, a viewer nobody runs and a recorder in
/// a folder that cannot be written is told what to fix, each by name, with exit status 1.
#[test]
fn doctor_says_what_to_fix() {
    let out = Command::new(workspace_binary("deckwatch"))
        .args(["doctor"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    for line in [
        "ok    configuration",
        "ok    stage binary deckwatch-capture",
        "ok    shared memory /dev/shm",
    ] {
        assert!(text.contains(line), "{line}:\n{text}");
    }
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("p.toml");
    // A port nobody listens on: bind one, note it, let it go.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    std::fs::write(
        &config,
        format!(
            "[link]\nenabled = true\naddress = \"serial:/dev/deckwatch-no-such-uart:921600\"\n\
             [rerun]\nsink = \"connect\"\naddress = \"rerun+http://127.0.0.1:{port}/proxy\"\n\
             [record]\npath = \"/proc/deckwatch-no/flight.mcap\"\n"
        ),
    )
    .unwrap();
    let out = Command::new(workspace_binary("deckwatch"))
        .arg("doctor")
        .arg("--config")
        .arg(&config)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    for fix in [
        "FIX   MAVLink endpoint serial:/dev/deckwatch-no-such-uart:921600: /dev/deckwatch-no-such-uart does not exist",
        &format!("FIX   rerun viewer at rerun+http://127.0.0.1:{port}/proxy"),
        "FIX   flight recorder /proc/deckwatch-no/flight.mcap",
    ] {
        assert!(text.contains(fix), "{fix}:\n{text}");
    }
    assert!(text.contains("3 to fix"), "{text}");
}

/// `sim record --distortion` takes the five coefficients as README writes them, a negative k1
/// first; four are refused by name.
#[test]
fn a_lens_distortion_is_given_as_five_comma_separated_coefficients() {
    let dir = tempfile::tempdir().unwrap();
    let record = |distortion: &str| {
        Command::new(workspace_binary("deckwatch"))
            .args([
                "sim",
                "record",
                "--scenario",
                "case1",
                "--width",
                "640",
                "--height",
                "480",
            ])
            .args(["--frames", "1", "--distortion", distortion, "--out"])
            .arg(dir.path().join("r"))
            .output()
            .unwrap()
    };
    let out = record("-0.2,0.05,0,0,0");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let camera = std::fs::read_to_string(dir.path().join("r/camera.json")).unwrap();
    assert!(camera.contains("-0.2"), "{camera}");
    let out = record("-0.2,0.05,0,0");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("--distortion"),
        "{stderr}"
    );
}
