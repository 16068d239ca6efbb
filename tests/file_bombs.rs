//! Files that claim far more than they hold (security issue 72, item 5): a flight recording
//! whose image says it is 30000 x 30000, a sparse 10 GB pipeline configuration, a sparse motion
//! file and trials report. Each command refuses the file with an error that names it and the
//! size, ends without a panic, and stays small: the child's peak resident memory is measured
//! (wait4's rusage: the command and the stage processes it reaped) and printed.

use deckwatch_flight::reader::{FlightReader, FlightRecord};
use deckwatch_flight::{topics, FlightWriter, RecordCompression, WriterOptions};
use deckwatch_tests::workspace_binary;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The side the crafted images claim (px): 900 million pixels, 14 times `MAX_IMAGE_PIXELS`.
const CLAIMED_SIDE_PX: u32 = 30_000;
/// The most a command may hold refusing a file (MiB): the crafted image alone would be 858 MiB.
const MAX_PEAK_MIB: f64 = 200.0;
/// A sparse file's size: no disk blocks, and far beyond every bound.
const SPARSE_BYTES: u64 = 10 << 30;

/// How a command ended: its exit code (None: a signal), its output, its peak resident memory.
struct Measured {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    peak_mib: f64,
}

/// Runs `deckwatch ARGS` to its end (killed, with the processes it started, after `timeout`),
/// measuring its peak resident memory: wait4 reports the largest of the process's own and of
/// the children it reaped (the pipeline's stage processes).
fn run_measured(args: &[&str], timeout: Duration) -> Measured {
    use std::os::unix::process::CommandExt;
    let dir = tempfile::tempdir().unwrap();
    let (out_path, err_path) = (dir.path().join("stdout"), dir.path().join("stderr"));
    let mut cmd = Command::new(workspace_binary("deckwatch"));
    cmd.args(args)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_path).unwrap())
        .stderr(std::fs::File::create(&err_path).unwrap());
    // SAFETY: prctl is async-signal-safe; a test killed outright takes the command along.
    unsafe {
        cmd.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
            Ok(())
        });
    }
    // Reaped by wait4 below, not by `Child::wait`: wait4 also gives its resource usage.
    #[allow(clippy::zombie_processes)]
    let pid = cmd.spawn().unwrap().id() as libc::pid_t;
    let end = Instant::now() + timeout;
    let mut status = 0;
    // SAFETY: a plain C struct, filled by wait4.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    loop {
        // SAFETY: wait4 on this test's own child, with valid pointers to fill.
        let reaped = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        assert!(reaped >= 0, "wait4: {}", std::io::Error::last_os_error());
        if reaped == pid {
            break;
        }
        if Instant::now() > end {
            for p in deckwatch_tests::guard::descendants(pid as u32) {
                // SAFETY: kill(2) on a process this command started.
                unsafe { libc::kill(p as libc::pid_t, libc::SIGKILL) };
            }
            // SAFETY: as above, on the command itself, then reaped.
            unsafe {
                libc::kill(pid, libc::SIGKILL);
                libc::wait4(pid, &mut status, 0, &mut usage);
            }
            panic!("deckwatch {args:?} did not end within {timeout:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let read = |p: &Path| String::from_utf8_lossy(&std::fs::read(p).unwrap()).into_owned();
    Measured {
        code: libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status)),
        stdout: read(&out_path),
        stderr: read(&err_path),
        // ru_maxrss is in KiB on Linux.
        peak_mib: usage.ru_maxrss as f64 / 1024.0,
    }
}

/// The command failed as a command does (exit status 1, no panic) with an error naming every
/// one of `names`, in little memory, and within a minute.
fn assert_refused(what: &str, args: &[&str], names: &[&str]) -> Measured {
    let started = Instant::now();
    let m = run_measured(args, Duration::from_secs(120));
    println!(
        "{what}: deckwatch {} -> exit {:?} in {:.1} s, peak resident {:.1} MiB\n  {}",
        args.join(" "),
        m.code,
        started.elapsed().as_secs_f64(),
        m.peak_mib,
        m.stderr.trim().replace('\n', "\n  ")
    );
    assert_eq!(
        m.code,
        Some(1),
        "{what}: stdout {}\nstderr {}",
        m.stdout,
        m.stderr
    );
    assert!(!m.stderr.contains("panicked"), "{what}: {}", m.stderr);
    for name in names {
        assert!(m.stderr.contains(name), "{what}: no `{name}` in {}", m.stderr);
    }
    assert!(
        m.peak_mib < MAX_PEAK_MIB,
        "{what}: {:.1} MiB at peak (at most {MAX_PEAK_MIB})",
        m.peak_mib
    );
    m
}

/// Walks a protobuf message and overwrites the `fixed32` fields of `tags` with `value`:
/// `foxglove.RawImage`'s width (2), height (3) and step (5).
fn patch_fixed32(message: &mut [u8], tags: &[u64], value: u32) {
    let varint = |bytes: &[u8], at: &mut usize| {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = bytes[*at];
            *at += 1;
            v |= u64::from(b & 0x7f) << shift;
            if b & 0x80 == 0 {
                break;
            }
        }
        v
    };
    let mut at = 0;
    while at < message.len() {
        let key = varint(message, &mut at);
        match key & 7 {
            0 => {
                varint(message, &mut at);
            }
            1 => at += 8,
            2 => at += varint(message, &mut at) as usize,
            5 => {
                if tags.contains(&(key >> 3)) {
                    message[at..at + 4].copy_from_slice(&value.to_le_bytes());
                }
                at += 4;
            }
            other => panic!("wire type {other} in a foxglove image"),
        }
    }
}

/// CRC-32 (IEEE), as PNG chunks carry it.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// The PNG inside a `foxglove.CompressedImage` claims `side` x `side`: its IHDR's width and
/// height, and the chunk's CRC, so that the PNG decoder reads the header as valid.
fn patch_png(message: &mut [u8], side: u32) {
    const SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";
    let png = message
        .windows(SIGNATURE.len())
        .position(|w| w == SIGNATURE)
        .expect("a PNG in the image message");
    // After the signature: the IHDR's length (4), "IHDR" at 12, width and height at 16..24,
    // the rest of its 13 bytes, then its CRC at 29..33 (over the type and the data).
    let ihdr = &mut message[png..];
    assert_eq!(&ihdr[12..16], b"IHDR");
    ihdr[16..20].copy_from_slice(&side.to_be_bytes());
    ihdr[20..24].copy_from_slice(&side.to_be_bytes());
    let crc = crc32(&ihdr[12..29]);
    ihdr[29..33].copy_from_slice(&crc.to_be_bytes());
}

/// A recording folder of the tests' data.
fn data_recording() -> &'static str {
    concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/ship-640x480")
}

/// A valid recording (the ship recording, converted by `deckwatch convert` with `frames`
/// images) rewritten with every image claiming [`CLAIMED_SIDE_PX`] a side: everything else (the
/// headers, the calibration, the metadata and configuration) as it was.
fn crafted_recording(dir: &Path, frames: &str) -> PathBuf {
    let data = data_recording();
    let valid = dir.join(format!("valid-{frames}.mcap"));
    let converted = Command::new(workspace_binary("deckwatch"))
        .args(["convert", data, valid.to_str().unwrap(), "--frames", frames])
        .output()
        .unwrap();
    assert!(
        converted.status.success(),
        "{}",
        String::from_utf8_lossy(&converted.stderr)
    );
    let crafted = dir.join(format!("crafted-{frames}.mcap"));
    let mut writer = FlightWriter::create(
        &crafted,
        WriterOptions {
            compression: RecordCompression::None,
            ..Default::default()
        },
    )
    .unwrap();
    let mut images = 0;
    for record in FlightReader::open(&valid).unwrap() {
        match record.unwrap() {
            FlightRecord::Message(mut m) => {
                match m.topic() {
                    topics::IMAGE => patch_fixed32(&mut m.data, &[2, 3, 5], CLAIMED_SIDE_PX),
                    topics::IMAGE_COMPRESSED => patch_png(&mut m.data, CLAIMED_SIDE_PX),
                    _ => {}
                }
                images += usize::from(matches!(m.topic(), topics::IMAGE | topics::IMAGE_COMPRESSED));
                writer.write_recorded(&m).unwrap();
            }
            FlightRecord::Metadata { name, entries } => writer.write_metadata(&name, entries).unwrap(),
            FlightRecord::Attachment {
                name,
                media_type,
                data,
                log_time,
            } => writer.attach_at(&name, &media_type, &data, log_time).unwrap(),
        }
    }
    writer.finish().unwrap();
    assert!(images > 0, "{} has no images", valid.display());
    crafted
}

/// Every command that takes a flight recording (`convert`, `replay`, `latency`) refuses one
/// whose images claim 30000 x 30000, raw or PNG, by the file's name and the claimed size,
/// without allocating it.
#[test]
fn a_recording_whose_images_claim_900_megapixels_is_refused_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let claimed = format!("{CLAIMED_SIDE_PX}x{CLAIMED_SIDE_PX}");
    // The capture stage refuses the file when it opens it, with the exit code of a refused
    // input: the launcher does not restart it (it would read the same file again).
    for frames in ["raw", "png"] {
        let crafted = crafted_recording(dir.path(), frames);
        let file = crafted.to_str().unwrap();
        let folder = dir.path().join(format!("converted-{frames}"));
        let domain = format!("filebombs{}{frames}", std::process::id());
        assert_refused(
            &format!("convert ({frames})"),
            &["convert", file, folder.to_str().unwrap()],
            &[file, &claimed],
        );
        assert!(!folder.join("frames.csv").exists(), "nothing converted");
        assert_refused(
            &format!("replay ({frames})"),
            &["replay", file, "--quiet", "--domain", &domain],
            &[file, &claimed, "not restarted"],
        );
        assert_refused(
            &format!("latency ({frames})"),
            &["latency", file, "--domain", &domain],
            &[file, &claimed, "not restarted"],
        );
        assert!(
            deckwatch_tests::guard::leftovers(&domain).is_empty(),
            "{:?}",
            deckwatch_tests::guard::leftovers(&domain)
        );
    }
}

/// A sparse 10 GB file where a small text file belongs is refused from its size, unread, by the
/// command that takes it: the pipeline configuration (`run --config`), the motion file (`trials
/// --motion-csv`), the benchmark's base configuration (`budget --config`), a marker table
/// (`estimate-table`) and a trials shard's report (`trials merge`).
#[test]
fn sparse_10_gb_text_files_are_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let sparse = |name: &str| {
        let path = dir.path().join(name);
        std::fs::File::create(&path)
            .unwrap()
            .set_len(SPARSE_BYTES)
            .unwrap();
        path.to_str().unwrap().to_string()
    };
    let size = format!("{SPARSE_BYTES} bytes");
    let config = sparse("pipeline.toml");
    assert_refused(
        "run --config",
        &["run", "--config", &config],
        &[&config, &size, "1048576 bytes"],
    );
    let motion = sparse("ship-motion.csv");
    assert_refused(
        "trials --motion-csv",
        &[
            "trials",
            "--motion-csv",
            &motion,
            "--approaches",
            "1",
            "--seeds",
            "1",
        ],
        &["--motion-csv", &motion, &size, "67108864 bytes"],
    );
    // The benchmark reads its base configuration before it starts anything (a recording is
    // named, so none is rendered).
    assert_refused(
        "budget --config",
        &["budget", "--recording", data_recording(), "--config", &config],
        &[&config, &size],
    );
    let table = sparse("markers.csv");
    assert_refused("estimate-table", &["estimate-table", &table], &[&table, &size]);
    let shard = sparse("shard.jsonl");
    assert_refused("trials merge", &["trials", "merge", &shard], &[&shard, &size]);
}
