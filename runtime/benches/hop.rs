//! Publish -> receive latency between two processes, side by side in one run:
//! - an 8 MB (3280x2464) frame through deckwatch's frame path (iceoryx2 `[u8]` sample with its
//!   header, event notification, subscriber woken in a WaitSet), zero-copy;
//! - a 64 B payload through exactly the same path;
//! - the same 8 MB frame through a Unix domain socket (written and read in full).
//!
//! The latency is the receiver's `CLOCK_MONOTONIC` time when it has the frame (iceoryx2: the
//! sample in hand and its first and last byte read; socket: every byte read) minus the sender's
//! time just before sending. The frame contents are written before the clock starts (capture
//! renders into the sample; that cost is the capture stage's, reported by `deckwatch latency`).
//!
//! `cargo bench -p deckwatch-runtime --bench hop` (optionally `-- --samples N --rate HZ`).

use deckwatch_common::messages::{monotonic_ns, FrameHeader};
use deckwatch_common::stats::Percentiles;
use deckwatch_runtime::bus::{event_loop, quiet_logging, Bus, BusConfig, BusError, BusSettings, Flow, Wake};
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::process::{Command, Stdio};
use std::time::Duration;

const FRAME: (u32, u32) = (3280, 2464);
const CHILD_ENV: &str = "DECKWATCH_HOP_CHILD";

fn arg(name: &str, default: u64) -> u64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The pipeline's default bus settings on `domain` for frames of up to `max_frame_bytes`.
fn settings(domain: &str, max_frame_bytes: usize) -> BusSettings {
    BusConfig {
        domain: domain.to_string(),
        ..Default::default()
    }
    .settings(max_frame_bytes)
}

fn header(width: u32, height: u32, seq: u64) -> FrameHeader {
    let mut h = FrameHeader {
        width,
        height,
        stride: width,
        ..Default::default()
    };
    h.stamp.seq = seq;
    h
}

/// Receiver of the iceoryx2 cases: prints one latency (ns) per line, then exits.
fn child_iceoryx2(domain: &str, samples: u64) {
    quiet_logging();
    let bus = Bus::join(&settings(domain, 1), "hop-rx").unwrap();
    let frames = bus.frame_subscriber().unwrap();
    let mut latencies = Vec::new();
    let mut checksum = 0u64;
    let mut last = false;
    let mut expected = 0;
    let mut at_last_tick = 0;
    // A tick without samples ends the run should the last sample be lost.
    event_loop(&[frames.listener()], Some(Duration::from_secs(10)), |wake| {
        while let Some((f, passed)) = frames.receive_latest()? {
            if passed > 0 {
                eprintln!("passed over {passed} before seq {}", f.header().stamp.seq);
            }
            let seq = f.header().stamp.seq;
            if seq != expected {
                eprintln!("gap: expected {expected}, got {seq}");
            }
            expected = seq + 1;
            let px = f.pixels();
            checksum += px[0] as u64 + px[px.len() - 1] as u64;
            latencies.push(monotonic_ns() - f.header().stamp.times.published_ns);
            last |= f.header().stamp.seq + 1 == samples;
        }
        let idle = wake == Wake::Tick && latencies.len() == at_last_tick;
        if wake == Wake::Tick {
            at_last_tick = latencies.len();
        }
        Ok::<Flow, BusError>(if last || idle { Flow::Stop } else { Flow::Continue })
    })
    .unwrap();
    let mut out = std::io::stdout().lock();
    for l in latencies {
        writeln!(out, "{l}").unwrap();
    }
    eprintln!("checksum {checksum}");
}

/// Receiver of the socket case.
fn child_socket(path: &str, samples: u64, bytes: usize) {
    let mut s = UnixStream::connect(path).unwrap();
    let mut buf = vec![0u8; bytes + 8];
    let mut latencies = Vec::new();
    for _ in 0..samples {
        s.read_exact(&mut buf).unwrap();
        let sent = u64::from_le_bytes(buf[..8].try_into().unwrap());
        latencies.push(monotonic_ns() - sent);
    }
    let mut out = std::io::stdout().lock();
    for l in latencies {
        writeln!(out, "{l}").unwrap();
    }
}

fn spawn_child(mode: &str, param: &str, samples: u64, bytes: usize) -> std::process::Child {
    Command::new(std::env::current_exe().unwrap())
        .env(CHILD_ENV, format!("{mode}|{param}|{samples}|{bytes}"))
        .stdout(Stdio::piped())
        .spawn()
        .unwrap()
}

fn collect(child: std::process::Child) -> Vec<f64> {
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| l.parse::<f64>().unwrap() / 1e3)
        .collect()
}

fn run_iceoryx2(label: &str, width: u32, height: u32, samples: u64, period: Duration) -> (String, Vec<f64>) {
    let domain = format!("hop{}", std::process::id());
    let bytes = (width * height) as usize;
    let bus = Bus::join(&settings(&domain, bytes), "hop-tx").unwrap();
    let publisher = bus.frame_publisher().unwrap();
    let child = spawn_child("iceoryx2", &domain, samples, bytes);
    while bus
        .subscriber_count(deckwatch_runtime::bus::services::FRAMES)
        .unwrap()
        < 1
    {
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(100));
    for seq in 0..samples {
        let delivered = publisher
            .publish(header(width, height, seq), |_, px| {
                px.fill(seq as u8);
                Ok::<(), String>(())
            })
            .unwrap();
        if delivered != 1 {
            eprintln!("seq {seq} delivered to {delivered}");
        }
        std::thread::sleep(period);
    }
    let lat = collect(child);
    drop(publisher);
    drop(bus);
    let _ = Bus::remove_idle_domain(&domain);
    (label.to_string(), lat)
}

fn run_socket(samples: u64, period: Duration) -> (String, Vec<f64>) {
    let bytes = (FRAME.0 * FRAME.1) as usize;
    let path = std::env::temp_dir().join(format!("deckwatch-hop-{}.sock", std::process::id()));
    let _ = std::fs::remove_file(&path);
    let listener = UnixListener::bind(&path).unwrap();
    let child = spawn_child("socket", path.to_str().unwrap(), samples, bytes);
    let (mut s, _) = listener.accept().unwrap();
    let mut frame = vec![0u8; bytes + 8];
    for seq in 0..samples {
        frame[8..].fill(seq as u8);
        let t = monotonic_ns();
        frame[..8].copy_from_slice(&t.to_le_bytes());
        s.write_all(&frame).unwrap();
        std::thread::sleep(period);
    }
    let lat = collect(child);
    let _ = std::fs::remove_file(&path);
    ("8 MB frame, Unix domain socket".into(), lat)
}

fn main() {
    if let Ok(spec) = std::env::var(CHILD_ENV) {
        let p: Vec<&str> = spec.split('|').collect();
        let samples: u64 = p[2].parse().unwrap();
        match p[0] {
            "iceoryx2" => child_iceoryx2(p[1], samples),
            _ => child_socket(p[1], samples, p[3].parse().unwrap()),
        }
        return;
    }
    quiet_logging();
    let samples = arg("--samples", 500);
    let period = Duration::from_nanos(1_000_000_000 / arg("--rate", 50).max(1));
    println!(
        "publish -> receive between two processes, {samples} samples at {:.0} Hz each (us)",
        1.0 / period.as_secs_f64()
    );
    let results = [
        run_iceoryx2("64 B payload, iceoryx2 event path", 64, 1, samples, period),
        run_iceoryx2(
            "8 MB frame (3280x2464), iceoryx2 event path",
            FRAME.0,
            FRAME.1,
            samples,
            period,
        ),
        run_socket(samples, period),
    ];
    println!(
        "{:<46} {:>6} {:>9} {:>9} {:>9} {:>9}",
        "case", "n", "p50", "p90", "p99", "max"
    );
    for (label, mut lat) in results {
        let n = lat.len();
        let p = Percentiles::of(&mut lat).unwrap();
        println!(
            "{label:<46} {n:>6} {:>9.1} {:>9.1} {:>9.1} {:>9.1}",
            p.p50, p.p90, p.p99, p.max
        );
    }
}
