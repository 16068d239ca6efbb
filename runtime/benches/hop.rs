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
//! A control case sends the 64 B payload right after writing 8 MB elsewhere (what writing a
//! frame does to the caches), and a second table splits each iceoryx2 hop into its phases: the
//! sender's publish (send and notify), the receiver's wake-up after it, the receive and the read.
//!
//! `cargo bench -p deckwatch-runtime --bench hop` (optionally `-- --samples N --rate HZ --rounds R`).

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
    // Per sample: published, woken, received, read (ns).
    let mut phases = Vec::new();
    let mut checksum = 0u64;
    let mut last = false;
    let mut expected = 0;
    let mut at_last_tick = 0;
    // A tick without samples ends the run should the last sample be lost.
    event_loop(&[frames.listener()], Some(Duration::from_secs(10)), |wake| {
        let woke = monotonic_ns();
        while let Some((f, passed)) = frames.receive_latest()? {
            let received = monotonic_ns();
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
            let read = monotonic_ns();
            let published = f.header().stamp.times.published_ns;
            latencies.push(read - published);
            phases.push([published, woke, received, read]);
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
    for (l, [p, w, r, d]) in latencies.iter().zip(phases) {
        writeln!(out, "{l} {p} {w} {r} {d}").unwrap();
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

/// The receiver's lines: the latency (ns), then for iceoryx2 the instants published, woken,
/// received and read (ns).
fn collect(child: std::process::Child) -> Vec<Vec<u64>> {
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| l.split_whitespace().map(|v| v.parse::<u64>().unwrap()).collect())
        .collect()
}

/// One case's result: latencies (us), and for iceoryx2 the phases (us): publish (send and
/// notify, the sender's view), publish -> woken, woken -> received, received -> read.
struct Case {
    label: String,
    latency_us: Vec<f64>,
    phases_us: Option<[Vec<f64>; 4]>,
}

impl Case {
    fn merge(&mut self, other: Case) {
        self.latency_us.extend(other.latency_us);
        if let (Some(a), Some(b)) = (&mut self.phases_us, other.phases_us) {
            for (a, b) in a.iter_mut().zip(b) {
                a.extend(b);
            }
        }
    }
}

/// The iceoryx2 frame path with `width` x `height` frames; `scratch`: bytes written elsewhere just
/// before each frame is sent (the control case).
fn run_iceoryx2(
    label: &str,
    (width, height): (u32, u32),
    scratch: usize,
    samples: u64,
    period: Duration,
) -> Case {
    let domain = format!("hop{}", std::process::id());
    let bytes = (width * height) as usize;
    let bus = Bus::join(&settings(&domain, bytes), "hop-tx").unwrap();
    let publisher = bus.frame_publisher().unwrap();
    let child = spawn_child("iceoryx2", &domain, samples, bytes);
    while bus
        .subscriber_count(
            <deckwatch_common::messages::FrameHeader as deckwatch_common::messages::Channel>::SERVICE,
        )
        .unwrap()
        < 1
    {
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(100));
    let mut elsewhere = vec![0u8; scratch];
    let mut returned = Vec::with_capacity(samples as usize);
    for seq in 0..samples {
        elsewhere.fill(seq as u8);
        let delivered = publisher
            .publish(header(width, height, seq), |_, px| {
                px.fill(seq as u8);
                Ok::<(), String>(())
            })
            .unwrap();
        returned.push(monotonic_ns());
        if delivered != 1 {
            eprintln!("seq {seq} delivered to {delivered}");
        }
        std::thread::sleep(period);
    }
    let lines = collect(child);
    drop(publisher);
    drop(bus);
    let _ = Bus::remove_idle_domain(&domain);
    let us = |a: u64, b: u64| b.saturating_sub(a) as f64 / 1e3;
    let mut phases: [Vec<f64>; 4] = Default::default();
    // The receiver gets every sample in order (checked there), so line k is sample k.
    for (l, done) in lines.iter().zip(&returned) {
        let [p, w, r, d] = [l[1], l[2], l[3], l[4]];
        for (v, x) in phases
            .iter_mut()
            .zip([us(p, *done), us(p, w), us(w, r), us(r, d)])
        {
            v.push(x);
        }
    }
    Case {
        label: label.to_string(),
        latency_us: lines.iter().map(|l| l[0] as f64 / 1e3).collect(),
        phases_us: Some(phases),
    }
}

fn run_socket(samples: u64, period: Duration) -> Case {
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
    let lines = collect(child);
    let _ = std::fs::remove_file(&path);
    Case {
        label: "8 MB frame, Unix domain socket".into(),
        latency_us: lines.iter().map(|l| l[0] as f64 / 1e3).collect(),
        phases_us: None,
    }
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
        "publish -> receive between two processes, {samples} samples at {:.0} Hz each, the cases \
         taking turns in {} rounds (us)",
        1.0 / period.as_secs_f64(),
        arg("--rounds", 5).max(1)
    );
    // The cases take turns in rounds: this machine's wake-up latency drifts by tens of
    // microseconds over minutes (other tenants of the host), which would otherwise be read as a
    // difference between cases run one after the other.
    let rounds = arg("--rounds", 5).max(1);
    let per_round = samples.div_ceil(rounds);
    let frame_bytes = (FRAME.0 * FRAME.1) as usize;
    let mut results: Vec<Case> = Vec::new();
    for _ in 0..rounds {
        let round = [
            run_iceoryx2("64 B payload, iceoryx2 event path", (64, 1), 0, per_round, period),
            run_iceoryx2(
                "8 MB frame (3280x2464), iceoryx2 event path",
                FRAME,
                0,
                per_round,
                period,
            ),
            run_iceoryx2(
                "64 B payload after writing 8 MB elsewhere",
                (64, 1),
                frame_bytes,
                per_round,
                period,
            ),
            run_socket(per_round, period),
        ];
        for case in round {
            match results.iter_mut().find(|c| c.label == case.label) {
                Some(c) => c.merge(case),
                None => results.push(case),
            }
        }
    }
    println!(
        "{:<46} {:>6} {:>9} {:>9} {:>9} {:>9}",
        "case", "n", "p50", "p90", "p99", "max"
    );
    for case in &results {
        let mut lat = case.latency_us.clone();
        let n = lat.len();
        let p = Percentiles::of(&mut lat).unwrap();
        println!(
            "{:<46} {n:>6} {:>9.1} {:>9.1} {:>9.1} {:>9.1}",
            case.label, p.p50, p.p90, p.p99, p.max
        );
    }
    println!("\nphases of the iceoryx2 hops, p50 / p99 (us)");
    println!(
        "{:<46} {:>15} {:>15} {:>15} {:>15}",
        "case", "publish", "-> woken", "-> received", "-> read"
    );
    for case in &results {
        let Some(phases) = &case.phases_us else { continue };
        let cells: Vec<String> = phases
            .iter()
            .map(|v| {
                let mut v = v.clone();
                let p = Percentiles::of(&mut v).unwrap();
                format!("{:.1} / {:.1}", p.p50, p.p99)
            })
            .collect();
        println!(
            "{:<46} {:>15} {:>15} {:>15} {:>15}",
            case.label, cells[0], cells[1], cells[2], cells[3]
        );
    }
}
