//! The link process: MAVLink to the autopilot (`deckwatch_link` does the protocol).
//!
//! Two threads: one blocks on the socket (or serial port), passes every frame through the
//! link's admission (rate limit, checksum, signature, the pinned autopilot) and publishes each
//! attitude as a [`VehicleSample`] (for estimate) the moment it arrives, answering the
//! autopilot's TIMESYNC requests; the other sleeps on the decisions and sends each one out at
//! once (LANDING_TARGET, named values, STATUSTEXT), and on a tick sends our HEARTBEAT and TIMESYNC
//! requests, watches the link and reports refused frames. Replies go to the configured peer
//! only: a connected socket, `[link] peer`, or the address of the autopilot's checked frames.
//! A [`Process`] but not a [`crate::stage::Stage`]: it has two inputs (the bus and a socket) and
//! no output on the bus but the vehicle samples and the traffic.

use crate::bus::{event_loop, Bus, BusError, Flow, MessagePublisher, Wake};
use crate::config::PipelineConfig;
use crate::stage::{setup, Heartbeat, Process, RunError, StageArgs};
use deckwatch_common::messages::{
    monotonic_ns, Channel, LandingDecision, LinkTraffic, PipelineStage, VehicleSample,
};
use deckwatch_common::stats::Percentiles;
use deckwatch_common::vehicle::VehicleStateSample;
use deckwatch_estimate::vehicle_track::VehicleTrack;
use deckwatch_link::admission::{self, Admission, Admitted, Refusal, RefusalCounts};
use deckwatch_link::incoming::{Incoming, LinkState};
use deckwatch_link::outgoing::{forwardable, stale_decision, Outgoing};
use deckwatch_link::signing::Signing;
use deckwatch_link::{Endpoint, LinkConfig, MavHeader, MavMessage};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs, UdpSocket};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The link process.
pub struct Link;

impl Process for Link {
    const NAME: &'static str = "link";
    const OUTPUTS: &'static [&'static str] = &[VehicleSample::SERVICE, LinkTraffic::SERVICE];
    fn inputs(_config: &PipelineConfig) -> Vec<&'static str> {
        vec![LandingDecision::SERVICE]
    }
    fn runs(config: &PipelineConfig) -> bool {
        config.link.enabled
    }
    fn run(config: PipelineConfig, _args: &StageArgs) -> Result<String, RunError> {
        run(config)
    }
}

/// The process's name: its node, its binary (`deckwatch-link`), its log lines.
pub const NAME: &str = <Link as Process>::NAME;

/// How long a blocking read waits, so the receiving thread notices nothing is coming.
const READ_TIMEOUT: Duration = Duration::from_millis(100);
/// The kernel's receive buffer asked for: a burst of a flood queues here rather than pushing
/// the autopilot's frames out (the kernel caps it at `net.core.rmem_max`).
const RECEIVE_BUFFER_BYTES: libc::c_int = 4 << 20;

/// The link's socket or serial port.
enum Transport {
    /// UDP: `connected` (udpout) sends to its one peer; otherwise replies go to `peer` (`[link]
    /// peer`) or the autopilot's checked address ([`Admission::reply_address`]).
    Udp {
        socket: UdpSocket,
        connected: bool,
        peer: Option<SocketAddr>,
    },
    /// A byte stream (TCP, serial): one peer by construction.
    Stream {
        read: Mutex<Box<dyn Read + Send>>,
        write: Mutex<Box<dyn Write + Send>>,
    },
}

fn link_error(address: &str, e: impl std::fmt::Display) -> RunError {
    RunError::Link(format!("link.address `{address}`: {e}"))
}

fn resolve(address: &str, host_port: &str) -> Result<SocketAddr, RunError> {
    host_port
        .to_socket_addrs()
        .map_err(|e| link_error(address, e))?
        .next()
        .ok_or_else(|| link_error(address, format!("`{host_port}` resolves to no address")))
}

/// Asks the kernel for a larger receive buffer (best effort: the kernel caps it).
fn enlarge_receive_buffer(socket: &UdpSocket) {
    use std::os::fd::AsRawFd;
    let size = RECEIVE_BUFFER_BYTES;
    // SAFETY: setsockopt reads `size_of::<c_int>()` bytes from a live c_int; the descriptor is
    // the socket's own, open for this call.
    unsafe {
        libc::setsockopt(
            socket.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&size as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        );
    }
}

impl Transport {
    fn open(config: &LinkConfig) -> Result<Transport, RunError> {
        let address = config.address.as_str();
        let endpoint = config
            .endpoint()
            .map_err(|e| RunError::Link(format!("link.{e}")))?;
        match endpoint {
            Endpoint::UdpIn(listen) => {
                let socket =
                    UdpSocket::bind(resolve(address, &listen)?).map_err(|e| link_error(address, e))?;
                socket
                    .set_read_timeout(Some(READ_TIMEOUT))
                    .map_err(|e| link_error(address, e))?;
                enlarge_receive_buffer(&socket);
                let peer = if config.peer.is_empty() {
                    None
                } else {
                    Some(
                        config
                            .peer
                            .parse()
                            .map_err(|e| RunError::Link(format!("link.peer `{}`: {e}", config.peer)))?,
                    )
                };
                Ok(Transport::Udp {
                    socket,
                    connected: false,
                    peer,
                })
            }
            Endpoint::UdpOut(to) => {
                let to = resolve(address, &to)?;
                let any: SocketAddr = if to.is_ipv4() {
                    ([0, 0, 0, 0], 0).into()
                } else {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                };
                let socket = UdpSocket::bind(any).map_err(|e| link_error(address, e))?;
                // Connected: the kernel drops datagrams from anyone else.
                socket.connect(to).map_err(|e| link_error(address, e))?;
                socket
                    .set_read_timeout(Some(READ_TIMEOUT))
                    .map_err(|e| link_error(address, e))?;
                enlarge_receive_buffer(&socket);
                Ok(Transport::Udp {
                    socket,
                    connected: true,
                    peer: Some(to),
                })
            }
            Endpoint::TcpOut(to) => {
                let stream =
                    TcpStream::connect(resolve(address, &to)?).map_err(|e| link_error(address, e))?;
                stream
                    .set_read_timeout(Some(READ_TIMEOUT))
                    .map_err(|e| link_error(address, e))?;
                let _ = stream.set_nodelay(true);
                let write = stream.try_clone().map_err(|e| link_error(address, e))?;
                Ok(Transport::Stream {
                    read: Mutex::new(Box::new(stream)),
                    write: Mutex::new(Box::new(write)),
                })
            }
            Endpoint::Serial { port, baud } => {
                let read = serialport::new(&port, baud)
                    .timeout(READ_TIMEOUT)
                    .open_native()
                    .map_err(|e| link_error(address, e))?;
                let write = read.try_clone_native().map_err(|e| link_error(address, e))?;
                Ok(Transport::Stream {
                    read: Mutex::new(Box::new(read)),
                    write: Mutex::new(Box::new(write)),
                })
            }
        }
    }

    /// Sends one frame to the peer; false when it could not go (no peer known yet on `udpin`,
    /// a full socket).
    fn send(&self, frame: &[u8], admission: &Mutex<Admission>) -> bool {
        match self {
            Transport::Udp {
                socket,
                connected: true,
                ..
            } => socket.send(frame).is_ok(),
            Transport::Udp { socket, peer, .. } => {
                let to = peer.or_else(|| lock(admission).reply_address());
                to.is_some_and(|to| socket.send_to(frame, to).is_ok())
            }
            Transport::Stream { write, .. } => lock(write).write_all(frame).is_ok(),
        }
    }

    /// Waits for bytes (up to [`READ_TIMEOUT`]) and hands them to admission: the frames that
    /// passed. An empty list on a timeout.
    fn receive(&self, buffer: &mut [u8], admission: &Mutex<Admission>) -> std::io::Result<Vec<Admitted>> {
        let quiet = |e: &std::io::Error| {
            matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock
                    | std::io::ErrorKind::TimedOut
                    | std::io::ErrorKind::Interrupted
            )
        };
        match self {
            Transport::Udp { socket, .. } => match socket.recv_from(buffer) {
                Ok((n, from)) => Ok(lock(admission).datagram(&buffer[..n], from, monotonic_ns())),
                Err(e) if quiet(&e) => Ok(Vec::new()),
                Err(e) => Err(e),
            },
            Transport::Stream { read, .. } => match lock(read).read(buffer) {
                Ok(0) => Err(std::io::ErrorKind::UnexpectedEof.into()),
                Ok(n) => Ok(lock(admission).stream(&buffer[..n], monotonic_ns())),
                Err(e) if quiet(&e) => Ok(Vec::new()),
                Err(e) => Err(e),
            },
        }
    }
}

/// A lock whose holder panicked is still the data: the link goes on.
fn lock<T: ?Sized>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Who we are on the link and how we sign, shared by both threads.
struct Sender {
    transport: Transport,
    admission: Mutex<Admission>,
    signing: Option<Arc<Signing>>,
    system_id: u8,
    component_id: u8,
    sequence: AtomicU64,
    failed: AtomicU64,
}

impl Sender {
    /// Sends, counting what could not go (no peer yet on `udpin`, a full socket): a lost message
    /// is not a reason to stop. With a recorder, the frame is published on `deckwatch/link` too.
    fn send(&self, m: &MavMessage, traffic: Traffic<'_>) {
        let header = MavHeader {
            system_id: u32::from(self.system_id),
            component_id: self.component_id,
            sequence: self.sequence.fetch_add(1, Ordering::Relaxed) as u8,
        };
        let frame = admission::frame(header, m, self.signing.as_deref());
        if !self.transport.send(&frame, &self.admission) {
            self.failed.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if let Some(p) = traffic {
            let _ = p.send(&deckwatch_link::traffic(monotonic_ns(), true, m, &frame));
        }
    }

    fn refused(&self) -> RefusalCounts {
        lock(&self.admission).refused
    }
}

/// Where the link's frames go for the recorder (None: no recorder runs).
type Traffic<'a> = Option<&'a MessagePublisher<LinkTraffic>>;

/// The vehicle samples the link made, on `CLOCK_MONOTONIC`: TARGET_RELATIVE's `q_sensor` is
/// their attitude at a frame's mid-exposure, interpolated as estimate compensates it (the
/// decision carries the attitude in W, whose x is the ship's mean heading, not north).
type Track = Arc<Mutex<VehicleTrack>>;

/// Samples kept (at 200 Hz, 2.5 s: longer than any frame takes through the pipeline).
const TRACK_SAMPLES: usize = 512;

/// The receiving thread: until the process ends.
fn receive(
    link: Arc<Sender>,
    incoming: Arc<Mutex<Incoming>>,
    track: Track,
    bus: Bus,
    recording: bool,
) -> Result<(), BusError> {
    let samples = bus.publisher::<VehicleSample>()?;
    let traffic = if recording {
        Some(bus.publisher::<LinkTraffic>()?)
    } else {
        None
    };
    let mut buffer = vec![0u8; 65_536];
    let mut reported_error = false;
    loop {
        let admitted = match link.transport.receive(&mut buffer, &link.admission) {
            Ok(a) => {
                reported_error = false;
                a
            }
            Err(e) => {
                // A closed TCP peer or an unplugged port: say it once, keep trying.
                if !reported_error {
                    deckwatch_common::say!("deckwatch-{NAME}: reading the link: {e}");
                    reported_error = true;
                }
                std::thread::sleep(Duration::from_millis(100));
                continue;
            }
        };
        for a in admitted {
            let now = monotonic_ns();
            if let Some(p) = &traffic {
                let _ = p.send(&deckwatch_link::traffic(now, false, &a.message, &a.frame));
            }
            let handled = lock(&incoming).handle(&a.header, &a.message, now);
            if let Some(s) = handled.sample {
                // As estimate takes them: only while the link is up.
                if s.link_up.get() {
                    lock(&track).push(VehicleStateSample::attitude(s.time_ns, s.quaternion));
                }
                samples.send(&s)?;
            }
            if let Some(r) = handled.reply {
                link.send(&r, traffic.as_ref());
            }
        }
    }
}

/// Runs the link process until SIGINT/SIGTERM.
fn run(config: PipelineConfig) -> Result<String, RunError> {
    let lc: LinkConfig = config.link.clone();
    let signing = Signing::configured(&lc).map_err(|e| RunError::Link(e.to_string()))?;
    if lc.unsigned_beyond_loopback {
        deckwatch_common::say!(
            "deckwatch-{NAME}: WARNING: unsigned_beyond_loopback = true: `{}` is another host and its frames are not authenticated; a bench only, never a flight",
            lc.address
        );
    }
    let (logger, bus) = setup(NAME, &config, 1)?;
    let link = Arc::new(Sender {
        transport: Transport::open(&lc)?,
        admission: Mutex::new(Admission::new(&lc, signing.clone())),
        signing,
        // A companion computer joins its vehicle's system.
        system_id: if lc.system_id == 0 {
            lc.autopilot_system_id
        } else {
            lc.system_id
        },
        component_id: lc.component_id,
        sequence: AtomicU64::new(0),
        failed: AtomicU64::new(0),
    });
    let incoming = Arc::new(Mutex::new(Incoming::new(&lc)));
    let track: Track = Arc::new(Mutex::new(VehicleTrack::new(TRACK_SAMPLES)));
    {
        let (link, incoming, track) = (link.clone(), incoming.clone(), track.clone());
        let settings = bus.settings().clone();
        let recording = config.record.enabled();
        std::thread::Builder::new()
            .name("link-rx".into())
            .spawn(move || {
                let result = Bus::join(&settings, "link-rx")
                    .and_then(|b| receive(link, incoming, track, b, recording));
                if let Err(e) = result {
                    deckwatch_common::say!("deckwatch-{NAME}: receiving stopped: {e}");
                }
            })
            .map_err(|e| RunError::Link(format!("starting the receiving thread: {e}")))?;
    }
    let decisions = bus.subscriber::<LandingDecision>()?;
    let traffic = if config.record.enabled() {
        Some(bus.publisher::<LinkTraffic>()?)
    } else {
        None
    };
    let traffic = traffic.as_ref();
    let mut outgoing = Outgoing::new(&lc, config.vehicle.mount());
    let period = |hz: f64| (hz > 0.0).then(|| (1e9 / hz) as u64);
    let heartbeat_period = period(lc.heartbeat_hz);
    let timesync_period = period(lc.timesync_hz);
    let (mut next_heartbeat, mut next_timesync) = (0u64, 0u64);
    let mut last_state = LinkState::Waiting;
    // Decision made -> received here, -> its first message (LANDING_TARGET when there is one) on
    // the socket, -> all its messages on the socket.
    let (mut hop_ns, mut first_ns, mut all_ns) = (Vec::new(), Vec::new(), Vec::new());
    let mut sent_decisions = 0u64;
    let mut last_logged_seq = u64::MAX;
    // Refused frames are reported (log line, rerun) at most once a second, when there are new.
    const REFUSAL_REPORT_NS: u64 = 1_000_000_000;
    let (mut reported_refusals, mut next_refusal_report) = (RefusalCounts::default(), 0u64);
    // The newest decision and the time it is aged from: one older than decide's freshness
    // limit (or none yet) is reported as NO-DECK stale-data, whatever it said.
    let mut newest_decision: Option<(LandingDecision, u64)> = None;
    let stale_after_ns = (config.decide.max_age_ms * 1e6) as u64;
    let tick = Duration::from_millis(50);
    // deckwatch's own heartbeat to the launcher (not MAVLink's HEARTBEAT to the autopilot).
    let mut alive = Heartbeat::new(&bus)?;
    // The signing state, kept on the disk once a second while it changes and at the stop: a
    // failed write is said once and counted, and the link goes on (the state in memory holds).
    let mut keep_failures = 0u64;
    let mut keep = |now: u64, stopping: bool| {
        if let Some(Err(e)) = link.signing.as_ref().map(|s| s.keep(now, stopping)) {
            if keep_failures == 0 {
                deckwatch_common::say!("deckwatch-{NAME}: keeping the signing state: {e}");
            }
            keep_failures += 1;
        }
    };
    event_loop(&[decisions.listener()], Some(tick), |wake| {
        alive.beat();
        let now = monotonic_ns();
        let (state, clock, autopilot, newest) = {
            let i = lock(&incoming);
            (i.state(now), i.clock.estimate(), i.autopilot, i.newest_sample())
        };
        if state != last_state {
            deckwatch_common::say!(
                "deckwatch-{NAME}: autopilot link {} (was {})",
                state.name(),
                last_state.name()
            );
            last_state = state;
        }
        if wake == Wake::Tick {
            keep(now, false);
            if heartbeat_period.is_some_and(|_| now >= next_heartbeat) {
                next_heartbeat = now + heartbeat_period.unwrap_or(u64::MAX);
                link.send(&Outgoing::heartbeat(state), traffic);
            }
            if let Some(p) = timesync_period.filter(|_| autopilot.is_some() && now >= next_timesync) {
                next_timesync = now + p;
                let ts1 = lock(&incoming).clock.request(monotonic_ns() as i64);
                link.send(&Outgoing::timesync_request(ts1, autopilot), traffic);
            }
            if newest_decision.is_none_or(|(_, at)| now.saturating_sub(at) > stale_after_ns) {
                let stale = stale_decision(newest_decision.as_ref().map(|(d, _)| d));
                for m in outgoing.decision(&stale, state, clock.as_ref(), now) {
                    link.send(&m, traffic);
                }
            }
            if now >= next_refusal_report {
                let refused = link.refused();
                let new = refused.since(&reported_refusals);
                if new.total() > 0 {
                    next_refusal_report = now + REFUSAL_REPORT_NS;
                    deckwatch_common::say!(
                        "deckwatch-{NAME}: refused {} frames: {}",
                        new.total(),
                        new.describe()
                    );
                    reported_refusals = refused;
                    if let Some(l) = &logger {
                        let by_cause: Vec<(&str, u64)> =
                            Refusal::ALL.iter().map(|r| (r.name(), refused.get(*r))).collect();
                        deckwatch_viz::entities::link_refusal_items(now, &by_cause)
                            .into_iter()
                            .for_each(|i| l.log(i));
                    }
                }
            }
            if let (Some(l), Some(s)) = (&logger, newest) {
                if s.seq != last_logged_seq {
                    last_logged_seq = s.seq;
                    deckwatch_viz::entities::vehicle_items(&s)
                        .into_iter()
                        .for_each(|i| l.log(i));
                }
            }
        }
        while let Some(d) = decisions.receive()? {
            let received = monotonic_ns();
            let d = forwardable(&d, received, stale_after_ns);
            let mut first = None;
            let at_capture = lock(&track)
                .at(d.stamp.times.captured_ns, config.vehicle.max_gap_ns())
                .ok()
                .map(|a| a.quaternion);
            for m in outgoing.decision_with_attitude(&d, state, clock.as_ref(), received, at_capture.as_ref())
            {
                link.send(&m, traffic);
                first.get_or_insert_with(monotonic_ns);
            }
            sent_decisions += 1;
            // Aged from its frame's capture (decide's own stale decisions from their arrival):
            // a clearance is not repeated past `max_age_ms` of its capture.
            let captured = d.stamp.times.captured_ns;
            let aged_from = if captured != 0 && !d.watchdog.get() {
                captured.min(received)
            } else {
                received
            };
            newest_decision = Some((d, aged_from));
            let made = d.stamp.times[PipelineStage::Decide].finished_ns;
            if made != 0 && !d.watchdog.get() {
                let since = |t: u64| t.saturating_sub(made) as f64;
                hop_ns.push(since(received));
                first_ns.push(since(first.unwrap_or(received)));
                all_ns.push(since(monotonic_ns()));
            }
        }
        if let Some(line) = decisions.rejections().report(monotonic_ns()) {
            deckwatch_common::say!("deckwatch-{NAME}: {line}");
        }
        Ok::<Flow, BusError>(Flow::Continue)
    })?;
    keep(monotonic_ns(), true);
    let kept = match link.signing.as_ref().and_then(|s| s.kept_file()) {
        Some(f) if keep_failures == 0 => format!("; signing state kept in {}", f.display()),
        Some(f) => format!(
            "; signing state NOT kept in {} ({keep_failures} writes failed)",
            f.display()
        ),
        None => String::new(),
    };
    let i = lock(&incoming);
    let c = i.counts;
    let clock = i.clock.estimate().map_or("no clock".to_string(), |e| {
        format!(
            "clock offset {:.3} ms ({:?}, drift {:.1} ppm, rtt {} us)",
            e.offset_ns / 1e6,
            e.method,
            e.drift_ppm,
            e.rtt_ns / 1000
        )
    });
    let pct = |v: &mut Vec<f64>| {
        Percentiles::of(v).map_or("-".to_string(), |p| {
            format!(
                "p50 {:.0} p99 {:.0} max {:.0} us",
                p.p50 / 1e3,
                p.p99 / 1e3,
                p.max / 1e3
            )
        })
    };
    let latency = format!(
        "decision -> link {}; -> first message sent {}; -> all sent {}",
        pct(&mut hop_ns),
        pct(&mut first_ns),
        pct(&mut all_ns)
    );
    let (admitted, refused, lost, elsewhere) = {
        let a = lock(&link.admission);
        (a.admitted, a.refused, a.autopilot_lost, a.from_other_address)
    };
    Ok(format!(
        "{admitted} frames admitted ({elsewhere} from another address than the replies'), {} refused ({}), {lost} of the autopilot's lost (sequence gaps); {} heartbeats, {} attitudes ({} refused), {} timesyncs, {} ranges, {} local positions in; {sent_decisions} decisions ({} bad ones skipped), {} landing targets and {} target relatives out ({} sends failed); {latency}; {clock}{kept}",
        refused.total(),
        refused.describe(),
        c.heartbeats,
        c.attitudes,
        c.refused,
        c.timesyncs,
        c.heights,
        c.positions,
        decisions.rejections().count(),
        outgoing.landing_targets,
        outgoing.target_relatives,
        link.failed.load(Ordering::Relaxed)
    ))
}
