//! The flight recorder process (`deckwatch-record`, `[record]`): subscribes to every service
//! and writes an MCAP flight recording ([`deckwatch_flight`]).
//!
//! Off the hot path: it is one more subscriber of each service (safe overflow: a slow recorder
//! loses its own oldest samples, it never holds capture back). A frame is copied out of shared
//! memory at once (into a buffer that is reused) and the sample released; encoding, compression
//! and disk writes happen on a writer thread behind a bounded queue. When the writer is behind,
//! the recorder drops frames (their headers are still recorded) and counts them; a frame the
//! recorder never saw (its queue overflowed) is counted too.

use crate::bus::{
    event_loop, Bus, BusError, Flow, FrameSample, Listener, Message, MessageSubscriber, Rejections,
};
use crate::config::PipelineConfig;
use crate::stage::{Heartbeat, Process, RunError, StageArgs, LAUNCHER_OUTPUTS};
use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
use deckwatch_common::messages::{
    monotonic_ns, AttitudeMessage, Channel, FrameHeader, GapCounter, LandingDecision, LinkTraffic,
    MarkerMessage, StageLog, VehicleSample,
};
use deckwatch_flight::{FlightWriter, RecordConfig, RecorderStats, TimeBase, WriterOptions};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The flight recorder process.
pub struct Recorder;

impl Process for Recorder {
    const NAME: &'static str = "record";
    const OUTPUTS: &'static [&'static str] = &[];
    /// Every service of the topology ([`recorded_services`]): the first, markers, says the
    /// recorder is up (it subscribes to the frames, when it records them, before).
    fn inputs(config: &PipelineConfig) -> Vec<&'static str> {
        recorded_services(config)
    }
    fn runs(config: &PipelineConfig) -> bool {
        config.record.enabled()
    }
    fn run(config: PipelineConfig, args: &StageArgs) -> Result<String, RunError> {
        run(config, args)
    }
}

/// The process's name: its node, its binary (`deckwatch-record`), its log lines.
pub const NAME: &str = <Recorder as Process>::NAME;

/// What the recorder takes in under `config`, from the topology: every service a process of
/// [`super::PROCESSES`] puts out and the launcher's ([`LAUNCHER_OUTPUTS`]), each once, in the
/// topology's order; the frames only when their pixels are recorded, and then after the first
/// of the others (the first stage's output, markers), which says that the recorder is up.
pub fn recorded_services(config: &PipelineConfig) -> Vec<&'static str> {
    let mut services: Vec<&'static str> = Vec::new();
    let outputs = super::PROCESSES.iter().flat_map(|p| p.outputs.iter());
    for &service in outputs.chain(LAUNCHER_OUTPUTS.iter()) {
        if service != FrameHeader::SERVICE && !services.contains(&service) {
            services.push(service);
        }
    }
    if config.record.records_frames() {
        services.insert(services.len().min(1), FrameHeader::SERVICE);
    }
    services
}

/// A message the recorder writes: the writer's item for it.
trait Recorded: Message {
    fn item(self) -> Item;
}

macro_rules! recorded {
    ($($ty:ty => $variant:ident),+ $(,)?) => {$(
        impl Recorded for $ty {
            fn item(self) -> Item {
                Item::$variant(self)
            }
        }
    )+};
}

recorded!(
    MarkerMessage => Markers,
    AttitudeMessage => Attitude,
    LandingDecision => Decision,
    VehicleSample => Vehicle,
    LinkTraffic => Link,
    StageLog => Log,
);

/// A message service the recorder follows.
trait Followed {
    fn listener(&self) -> &Listener;
    /// Its messages skipped for a bad enum or boolean.
    fn rejections(&self) -> &Rejections;
    /// Its next message, as the writer's item.
    fn receive(&self) -> Result<Option<Item>, BusError>;
}

impl<M: Recorded> Followed for MessageSubscriber<M> {
    fn listener(&self) -> &Listener {
        MessageSubscriber::listener(self)
    }

    fn rejections(&self) -> &Rejections {
        MessageSubscriber::rejections(self)
    }

    fn receive(&self) -> Result<Option<Item>, BusError> {
        Ok(MessageSubscriber::receive(self)?.map(M::item))
    }
}

/// How the recorder subscribes to a service.
type Subscribe = fn(&Bus) -> Result<Box<dyn Followed>, BusError>;

fn follow<M: Recorded>(bus: &Bus) -> Result<Box<dyn Followed>, BusError> {
    Ok(Box::new(bus.subscriber::<M>()?))
}

/// How the recorder follows a message service of the topology (None: one whose messages it has
/// no writer for; a test holds every service of the topology to having one).
fn subscriber_for(service: &str) -> Option<Subscribe> {
    let subscribe: Subscribe = match service {
        MarkerMessage::SERVICE => follow::<MarkerMessage>,
        AttitudeMessage::SERVICE => follow::<AttitudeMessage>,
        LandingDecision::SERVICE => follow::<LandingDecision>,
        VehicleSample::SERVICE => follow::<VehicleSample>,
        LinkTraffic::SERVICE => follow::<LinkTraffic>,
        StageLog::SERVICE => follow::<StageLog>,
        _ => return None,
    };
    Some(subscribe)
}

/// What the writer thread is handed.
enum Item {
    Frame(FrameHeader, Option<Vec<u8>>),
    Markers(MarkerMessage),
    Attitude(AttitudeMessage),
    Decision(LandingDecision),
    Vehicle(VehicleSample),
    Link(LinkTraffic),
    Log(StageLog),
    Stats(RecorderStats),
}

/// The recorder's nice value (0 is the stages'; higher yields to them).
const RECORDER_NICE: libc::c_int = 10;

/// Frames the recorder holds in shared memory at once (the frame service's borrows per
/// subscriber) while detect works on them.
const MAX_HELD_FRAMES: usize = 2;
/// The longest a frame is held for detect (one it passes over gets no marker message).
const MAX_HOLD_NS: u64 = 20_000_000;

/// Small messages queued for the writer before the recorder drops them (a few seconds of every
/// channel at 30 fps).
const MESSAGE_QUEUE: usize = 4096;

/// The file a recorder writes: the configured one, or for a recorder the launcher restarted,
/// a new file beside it (`flight.mcap` -> `flight.restart-<pid>.mcap`), never over the first.
pub fn recording_path(config: &RecordConfig, restarted: bool) -> Option<PathBuf> {
    let path = config.path.clone()?;
    if !restarted {
        return Some(path);
    }
    let stem = path
        .file_stem()
        .map_or("flight".into(), |s| s.to_string_lossy().to_string());
    Some(path.with_file_name(format!("{stem}.restart-{}.mcap", std::process::id())))
}

/// Counts shared by the recorder's loop and its writer thread.
#[derive(Default)]
struct Counts {
    frames_written: AtomicU64,
    bytes_written: AtomicU64,
    messages_written: AtomicU64,
    /// Frame buffers the writer holds (queued or being written).
    frames_queued: AtomicU64,
}

/// Runs the recorder process until SIGINT/SIGTERM; then the queue is written out and the file
/// finished (its summary written), so MCAP tools read it with its index.
fn run(config: PipelineConfig, args: &StageArgs) -> Result<String, RunError> {
    let rc = config.record.clone();
    let path = recording_path(&rc, args.restarted)
        .ok_or_else(|| RunError::Record("record.path is not set: nothing to record to".into()))?;
    // Below the stages that make the decision: on a busy CPU the recorder waits, not them (its
    // writer thread, started below, inherits this).
    // SAFETY: setpriority on this thread (who = 0); a failure leaves the priority as it was.
    unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, RECORDER_NICE) };
    crate::bus::quiet_logging();
    let bus = Bus::join(&config.bus.settings(1), NAME)?;
    let services = recorded_services(&config);
    let frames = if services.contains(&FrameHeader::SERVICE) {
        Some(bus.frame_subscriber()?)
    } else {
        None
    };
    let mut channels: Vec<Box<dyn Followed>> = Vec::with_capacity(services.len());
    for &service in services.iter().filter(|&&s| s != FrameHeader::SERVICE) {
        let subscribe = subscriber_for(service)
            .ok_or_else(|| RunError::Record(format!("no writer for the messages of `{service}`")))?;
        channels.push(subscribe(&bus)?);
    }

    let started_ns = monotonic_ns();
    let time_base = TimeBase::measure();
    let writer = FlightWriter::create(
        &path,
        WriterOptions {
            compression: rc.compression,
            chunk_bytes: u64::from(rc.chunk_mib) << 20,
            time_base,
        },
    )
    .map_err(|e| RunError::Record(e.to_string()))?;
    let counts = Arc::new(Counts::default());
    let (tx, rx) = bounded::<Item>(MESSAGE_QUEUE + rc.queue_frames as usize);
    // Frame buffers go back to the loop for reuse: no 8 MB allocation per frame.
    let (spare_tx, spare_rx) = bounded::<Vec<u8>>(rc.queue_frames as usize + 1);
    let metadata = recording_metadata(&config, args, time_base);
    let toml = config.to_toml();
    let writer_thread = {
        let (counts, rc) = (counts.clone(), rc.clone());
        std::thread::Builder::new()
            .name("record-writer".into())
            .spawn(move || write_items(writer, rx, spare_tx, counts, &rc, metadata, toml))
            .map_err(|e| RunError::Record(format!("starting the writer thread: {e}")))?
    };
    deckwatch_common::say!("deckwatch-{NAME}: recording to {}", path.display());

    let mut stats = RecorderStats::default();
    let mut frame_gaps = GapCounter::default();
    let mut heartbeat = Heartbeat::new(&bus)?;
    heartbeat.beat();
    let mut next_stats_ns = monotonic_ns() + 1_000_000_000;
    let mut writer_gone = false;
    let mut listeners: Vec<&Listener> = channels.iter().map(|c| c.listener()).collect();
    if let Some(f) = &frames {
        listeners.push(f.listener());
    }
    let mut spare_pool: Vec<Vec<u8>> = Vec::new();
    let send_message = |item: Item, stats: &mut RecorderStats| match tx.try_send(item) {
        Ok(()) => true,
        Err(TrySendError::Full(_)) => {
            stats.messages_dropped += 1;
            true
        }
        Err(TrySendError::Disconnected(_)) => false,
    };
    // Frames are held in shared memory (up to the subscriber's borrows) until detect has done
    // with them, then copied: the copy does not compete with detect for the memory bus.
    let mut held: std::collections::VecDeque<(FrameSample, u64)> = std::collections::VecDeque::new();
    let mut detect_done: Option<u64> = None;
    let end = event_loop(&listeners, Some(Heartbeat::PERIOD), |wake| {
        heartbeat.beat();
        let _ = wake;
        let mut take = |sample: FrameSample, stats: &mut RecorderStats| {
            let header = *sample.header();
            stats.frames_dropped += frame_gaps.observe(header.stamp.seq, header.stamp.drops.total());
            let wanted = header.stamp.seq.is_multiple_of(u64::from(rc.frame_every));
            let room = counts.frames_queued.load(Ordering::Relaxed) < u64::from(rc.queue_frames);
            let pixels = if !wanted {
                stats.frames_skipped += 1;
                None
            } else if !room {
                stats.frames_dropped += 1;
                None
            } else {
                let src = sample.pixels();
                let len = header.required_len().min(src.len());
                let mut buf = spare_pool
                    .pop()
                    .or_else(|| spare_rx.try_recv().ok())
                    .unwrap_or_default();
                buf.clear();
                buf.extend_from_slice(&src[..len]);
                counts.frames_queued.fetch_add(1, Ordering::Relaxed);
                Some(buf)
            };
            drop(sample);
            match tx.try_send(Item::Frame(header, pixels)) {
                Ok(()) => {}
                // Never wait for the writer (the launcher would take a blocked loop for a hung
                // recorder): drop the frame, keep its buffer.
                Err(TrySendError::Full(Item::Frame(_, px))) => {
                    stats.frames_dropped += 1;
                    if let Some(px) = px {
                        counts.frames_queued.fetch_sub(1, Ordering::Relaxed);
                        spare_pool.push(px);
                    }
                }
                Err(_) => writer_gone = true,
            }
        };
        let mut ok = true;
        let drain = |channel: &dyn Followed, stats: &mut RecorderStats, detect_done: &mut Option<u64>| {
            let mut ok = true;
            while let Some(item) = channel.receive()? {
                if let Item::Markers(m) = &item {
                    *detect_done = Some(m.stamp.seq);
                }
                ok &= send_message(item, stats);
            }
            Ok::<bool, BusError>(ok)
        };
        // The first service (markers, from the stage that takes the frames in) before the
        // frames: a frame is held until detect has done with it.
        let (first, rest) = channels.split_at(channels.len().min(1));
        for channel in first {
            ok &= drain(channel.as_ref(), &mut stats, &mut detect_done)?;
        }
        if let Some(f) = &frames {
            let now = monotonic_ns();
            loop {
                if held.len() >= MAX_HELD_FRAMES {
                    if let Some((s, _)) = held.pop_front() {
                        take(s, &mut stats);
                    }
                }
                match f.receive()? {
                    Some(s) => held.push_back((s, now)),
                    None => break,
                }
            }
            while let Some((s, since)) = held.front() {
                let done = detect_done.is_some_and(|d| d >= s.header().stamp.seq);
                if !done && now.saturating_sub(*since) < MAX_HOLD_NS {
                    break;
                }
                if let Some((s, _)) = held.pop_front() {
                    take(s, &mut stats);
                }
            }
        }
        for channel in rest {
            ok &= drain(channel.as_ref(), &mut stats, &mut detect_done)?;
        }
        let now = monotonic_ns();
        if now >= next_stats_ns {
            next_stats_ns = now + 1_000_000_000;
            stats.time_ns = now;
            ok &= send_message(Item::Stats(stats), &mut stats);
        }
        if !ok || writer_gone {
            // The writer stopped (a write failed): it says why when joined.
            return Ok::<Flow, BusError>(Flow::Stop);
        }
        Ok(Flow::Continue)
    })?;
    // The frames still held were recorded as they were dropped here: count them.
    stats.frames_dropped += held.len() as u64;
    drop(held);
    stats.time_ns = monotonic_ns();
    let _ = tx.send(Item::Stats(stats));
    drop(tx);
    let result = writer_thread
        .join()
        .map_err(|_| RunError::Record("the writer thread panicked".into()))?;
    let bytes = result.map_err(|e| RunError::Record(e.to_string()))?;
    let rejected: u64 = channels.iter().map(|c| c.rejections().count()).sum::<u64>()
        + frames.as_ref().map_or(0, |f| f.rejections().count());
    let _ = end;
    let elapsed_s = (monotonic_ns().saturating_sub(started_ns)) as f64 / 1e9;
    let (user_s, system_s) = cpu_seconds();
    Ok(format!(
        "{}: {} frames written, {} skipped (frame_every), {} dropped; {} messages written, {} dropped; {} bad messages skipped; {:.1} MB ({:.1} MB/s); CPU {user_s:.2} s user + {system_s:.2} s system in {elapsed_s:.1} s ({:.0} % of a core)",
        path.display(),
        counts.frames_written.load(Ordering::Relaxed),
        stats.frames_skipped,
        stats.frames_dropped,
        counts.messages_written.load(Ordering::Relaxed),
        stats.messages_dropped,
        rejected,
        bytes as f64 / 1e6,
        bytes as f64 / 1e6 / elapsed_s.max(1e-9),
        100.0 * (user_s + system_s) / elapsed_s.max(1e-9)
    ))
}

/// This process's CPU time so far, user and system (s): every thread, the writer's included.
fn cpu_seconds() -> (f64, f64) {
    // SAFETY: getrusage fills the struct we pass; RUSAGE_SELF always exists.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    let s = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 / 1e6;
    (s(u.ru_utime), s(u.ru_stime))
}

/// The metadata records of a recording: versions, the run, the clock.
fn recording_metadata(
    config: &crate::config::PipelineConfig,
    args: &StageArgs,
    time_base: TimeBase,
) -> BTreeMap<String, BTreeMap<String, String>> {
    let mut out = BTreeMap::new();
    let mut run: BTreeMap<String, String> = config.run_properties().into_iter().collect();
    run.insert("configuration".to_string(), args.config_name());
    run.insert("restarted".to_string(), args.restarted.to_string());
    out.insert("deckwatch".to_string(), run);
    out.insert(
        "deckwatch.clock".to_string(),
        BTreeMap::from([
            (
                "unix_minus_monotonic_ns".to_string(),
                time_base.unix_minus_monotonic_ns.to_string(),
            ),
            (
                "note".to_string(),
                "log times are UNIX ns; the messages' own times are CLOCK_MONOTONIC ns".to_string(),
            ),
        ]),
    );
    out
}

/// The writer thread: writes until the queue closes, flushes the open chunk every
/// `flush_interval_ms`, finishes the file; the bytes written or why it stopped.
fn write_items(
    mut writer: FlightWriter,
    rx: Receiver<Item>,
    spare: Sender<Vec<u8>>,
    counts: Arc<Counts>,
    rc: &RecordConfig,
    metadata: BTreeMap<String, BTreeMap<String, String>>,
    toml: String,
) -> Result<u64, deckwatch_flight::FlightError> {
    // The writer (encoding, compression, the file) runs only when no stage wants the CPU: when it
    // falls behind, its queue fills and the recorder drops frames, counted; nothing else waits.
    // SAFETY: sched_setscheduler on this thread (pid 0) with a zeroed parameter, which SCHED_IDLE
    // requires; a failure leaves the thread at the recorder's nice value.
    unsafe {
        let param: libc::sched_param = std::mem::zeroed();
        libc::sched_setscheduler(0, libc::SCHED_IDLE, &param);
    }
    for (name, entries) in metadata {
        writer.write_metadata(&name, entries)?;
    }
    writer.attach(
        "pipeline.toml",
        "application/toml",
        toml.as_bytes(),
        monotonic_ns(),
    )?;
    let flush_every = Duration::from_millis(rc.flush_interval_ms);
    let mut last_flush = std::time::Instant::now();
    let mut camera_written = false;
    loop {
        let item = match rx.recv_timeout(flush_every) {
            Ok(item) => Some(item),
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => None,
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => break,
        };
        if let Some(item) = item {
            let message = !matches!(item, Item::Frame(..));
            write_item(&mut writer, item, rc, &spare, &counts, &mut camera_written)?;
            if message {
                counts.messages_written.fetch_add(1, Ordering::Relaxed);
            }
            counts
                .bytes_written
                .store(writer.bytes_written(), Ordering::Relaxed);
        }
        if last_flush.elapsed() >= flush_every {
            writer.flush()?;
            last_flush = std::time::Instant::now();
        }
    }
    writer.finish()
}

fn write_item(
    writer: &mut FlightWriter,
    item: Item,
    rc: &RecordConfig,
    spare: &Sender<Vec<u8>>,
    counts: &Counts,
    camera_written: &mut bool,
) -> Result<(), deckwatch_flight::FlightError> {
    match item {
        Item::Frame(header, pixels) => {
            if !*camera_written {
                *camera_written = true;
                writer.write_calibration(&header.context.camera, header.stamp.times.captured_ns)?;
                let camera = deckwatch_flight::JsonField::to_json(&header.context.camera).to_string();
                let deck = deckwatch_flight::JsonField::to_json(&header.context.deck).to_string();
                writer.write_metadata(
                    "deckwatch.camera",
                    BTreeMap::from([("camera".to_string(), camera), ("deck".to_string(), deck)]),
                )?;
            }
            writer.write(&header)?;
            if let Some(px) = pixels {
                let written = writer.write_frame(&header, &px, rc.frames, rc.jpeg_quality);
                counts.frames_queued.fetch_sub(1, Ordering::Relaxed);
                let _ = spare.try_send(px);
                written?;
                counts.frames_written.fetch_add(1, Ordering::Relaxed);
            }
        }
        Item::Markers(m) => writer.write(&m)?,
        Item::Attitude(m) => writer.write(&m)?,
        Item::Decision(m) => writer.write(&m)?,
        Item::Vehicle(m) => writer.write(&m)?,
        Item::Link(m) => writer.write(&m)?,
        Item::Log(l) => writer.write_log(l.time_ns, l.level.get() as i32, &l.name(), &l.text())?,
        Item::Stats(mut s) => {
            s.frames_written = counts.frames_written.load(Ordering::Relaxed);
            s.messages_written = counts.messages_written.load(Ordering::Relaxed);
            s.bytes_written = writer.bytes_written();
            writer.write_stats(&s)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::StageHeartbeat;
    use deckwatch_flight::FrameEncoding;

    fn recording(frames: FrameEncoding) -> PipelineConfig {
        let mut c = PipelineConfig::default();
        c.record.path = Some("flight.mcap".into());
        c.record.frames = frames;
        c
    }

    /// The recorder follows what the topology puts out, every service once and each with a
    /// writer: every process's outputs and the launcher's log lines; the frames only when their
    /// pixels are recorded, behind the markers, which say that it is up. Not the heartbeats.
    #[test]
    fn the_recorder_follows_every_service_of_the_topology() {
        let with_frames = recorded_services(&recording(FrameEncoding::Raw));
        assert_eq!(
            with_frames,
            [
                MarkerMessage::SERVICE,
                FrameHeader::SERVICE,
                AttitudeMessage::SERVICE,
                LandingDecision::SERVICE,
                VehicleSample::SERVICE,
                LinkTraffic::SERVICE,
                StageLog::SERVICE,
            ]
        );
        let headers_only = recorded_services(&recording(FrameEncoding::None));
        let without_frames: Vec<_> = with_frames
            .iter()
            .copied()
            .filter(|&s| s != FrameHeader::SERVICE)
            .collect();
        assert_eq!(headers_only, without_frames);
        let produced = super::super::PROCESSES.iter().flat_map(|p| p.outputs.iter());
        for service in produced.chain(LAUNCHER_OUTPUTS.iter()) {
            assert!(with_frames.contains(service), "{service} is not recorded");
        }
        for service in &without_frames {
            assert!(subscriber_for(service).is_some(), "no writer for {service}");
        }
        assert!(!with_frames.contains(&StageHeartbeat::SERVICE));
    }
}
