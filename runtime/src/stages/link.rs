//! The link process: MAVLink to the autopilot (`deckwatch_link` does the protocol).
//!
//! Two threads: one blocks on the MAVLink connection and publishes each attitude as a
//! [`VehicleSample`] (for estimate) the moment it arrives, answering TIMESYNC requests; the
//! other sleeps on the decisions and sends each one out at once (LANDING_TARGET, named values,
//! STATUSTEXT), and on a tick sends our HEARTBEAT and TIMESYNC requests and watches the link.
//! Not a [`crate::stage::Stage`]: it has two inputs (the bus and a socket) and no output on the
//! bus but the vehicle samples.

use crate::bus::{event_loop, Bus, BusError, Flow, MessagePublisher, Wake};
use crate::stage::{checked_config, exit_code, setup, Heartbeat, RunError, StageArgs};
use deckwatch_common::messages::{monotonic_ns, LandingDecision, LinkTraffic, VehicleSample};
use deckwatch_common::stats::Percentiles;
use deckwatch_link::incoming::{Incoming, LinkState};
use deckwatch_link::mavlink;
use deckwatch_link::outgoing::{forwardable, stale_decision, Outgoing};
use deckwatch_link::{LinkConfig, MavHeader, MavMessage};
use mavlink::error::MessageReadError;
use mavlink::{ConnectionAddress, MavConnection, MavlinkVersion};
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The process's name: its node, its binary (`deckwatch-link`), its log lines.
pub const NAME: &str = "link";

type Connection = mavlink::Connection<MavMessage>;

/// The connection, MAVLink 2, with a read timeout so the receiving thread notices a stop.
fn open(address: &str) -> Result<Connection, RunError> {
    let fail = |e: std::io::Error| RunError::Link(format!("link.address `{address}`: {e}"));
    let parsed = ConnectionAddress::parse_address(address).map_err(fail)?;
    let parsed = match parsed {
        ConnectionAddress::Udp(u) => ConnectionAddress::Udp(u.read_timeout(Duration::from_millis(100))),
        other => other,
    };
    let mut c = mavlink::Connectable::connect::<MavMessage>(&parsed).map_err(fail)?;
    c.set_protocol_version(MavlinkVersion::V2);
    Ok(c)
}

/// Who we are on the link, shared by both threads (0 = the autopilot's system, once known).
struct Identity {
    system_id: AtomicU64,
    component_id: u8,
    sequence: AtomicU64,
}

impl Identity {
    fn header(&self) -> MavHeader {
        MavHeader {
            system_id: self.system_id.load(Ordering::Relaxed) as u32,
            component_id: self.component_id,
            sequence: self.sequence.fetch_add(1, Ordering::Relaxed) as u8,
        }
    }
}

/// Sends, counting what could not go (no peer yet on `udpin`, a full socket): a lost message is
/// not a reason to stop. With a recorder, the frame is published on `deckwatch/link` too.
fn send(conn: &Connection, id: &Identity, m: &MavMessage, failed: &AtomicU64, traffic: Traffic<'_>) {
    let header = id.header();
    if conn.send(&header, m).is_err() {
        failed.fetch_add(1, Ordering::Relaxed);
        return;
    }
    if let Some(p) = traffic {
        let _ = p.send(&deckwatch_link::traffic(monotonic_ns(), true, &header, m));
    }
}

/// Where the link's frames go for the recorder (None: no recorder runs).
type Traffic<'a> = Option<&'a MessagePublisher<LinkTraffic>>;

/// The receiving thread: until the process ends.
fn receive(
    conn: Arc<Connection>,
    id: Arc<Identity>,
    incoming: Arc<Mutex<Incoming>>,
    bus: Bus,
    failed: Arc<AtomicU64>,
    configured_system: u8,
    recording: bool,
) -> Result<(), BusError> {
    let samples = bus.publisher::<VehicleSample>()?;
    let traffic = if recording {
        Some(bus.publisher::<LinkTraffic>()?)
    } else {
        None
    };
    loop {
        let (header, message) = match conn.recv() {
            Ok(m) => m,
            // Timeouts, and frames that are not MAVLink 2 of the common dialect: skip.
            Err(MessageReadError::Io(e))
                if e.kind() != std::io::ErrorKind::WouldBlock && e.kind() != std::io::ErrorKind::TimedOut =>
            {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
            Err(_) => continue,
        };
        let now = monotonic_ns();
        if let Some(p) = &traffic {
            let _ = p.send(&deckwatch_link::traffic(now, false, &header, &message));
        }
        let handled = {
            let mut i = incoming.lock().unwrap_or_else(|p| p.into_inner());
            let h = i.handle(&header, &message, now);
            if configured_system == 0 {
                if let Some((system, _)) = i.autopilot {
                    id.system_id.store(u64::from(system), Ordering::Relaxed);
                }
            }
            h
        };
        if let Some(s) = handled.sample {
            samples.send(&s)?;
        }
        if let Some(r) = handled.reply {
            send(&conn, &id, &r, &failed, traffic.as_ref());
        }
    }
}

/// Runs the link process until SIGINT/SIGTERM.
pub fn run(args: &StageArgs) -> Result<String, RunError> {
    let config = checked_config(args)?;
    let lc: LinkConfig = config.link.clone();
    let (logger, bus) = setup(NAME, &config, 1)?;
    let conn = Arc::new(open(&lc.address)?);
    // System 1 until the autopilot's is known (with `system_id = 0`).
    let id = Arc::new(Identity {
        system_id: AtomicU64::new(u64::from(lc.system_id.max(1))),
        component_id: lc.component_id,
        sequence: AtomicU64::new(0),
    });
    let incoming = Arc::new(Mutex::new(Incoming::new(&lc)));
    let failed = Arc::new(AtomicU64::new(0));
    {
        let (conn, id, incoming, failed) = (conn.clone(), id.clone(), incoming.clone(), failed.clone());
        let settings = bus.settings().clone();
        let system = lc.system_id;
        let recording = config.record.enabled();
        std::thread::Builder::new()
            .name("link-rx".into())
            .spawn(move || {
                let result = Bus::join(&settings, "link-rx")
                    .and_then(|b| receive(conn, id, incoming, b, failed, system, recording));
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
    // The newest decision and the time it is aged from: one older than decide's freshness
    // limit (or none yet) is reported as NO-DECK stale-data, whatever it said.
    let mut newest_decision: Option<(LandingDecision, u64)> = None;
    let stale_after_ns = (config.decide.max_age_ms * 1e6) as u64;
    let tick = Duration::from_millis(50);
    // deckwatch's own heartbeat to the launcher (not MAVLink's HEARTBEAT to the autopilot).
    let mut alive = Heartbeat::new(&bus)?;
    event_loop(&[decisions.listener()], Some(tick), |wake| {
        alive.beat();
        let now = monotonic_ns();
        let (state, clock, autopilot, newest) = {
            let i = incoming.lock().unwrap_or_else(|p| p.into_inner());
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
            if heartbeat_period.is_some_and(|_| now >= next_heartbeat) {
                next_heartbeat = now + heartbeat_period.unwrap_or(u64::MAX);
                send(&conn, &id, &Outgoing::heartbeat(state), &failed, traffic);
            }
            if let Some(p) = timesync_period.filter(|_| autopilot.is_some() && now >= next_timesync) {
                next_timesync = now + p;
                let ts1 = incoming
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .clock
                    .request(monotonic_ns() as i64);
                send(
                    &conn,
                    &id,
                    &Outgoing::timesync_request(ts1, autopilot),
                    &failed,
                    traffic,
                );
            }
            if newest_decision.is_none_or(|(_, at)| now.saturating_sub(at) > stale_after_ns) {
                let stale = stale_decision(newest_decision.as_ref().map(|(d, _)| d));
                for m in outgoing.decision(&stale, state, clock.as_ref(), now) {
                    send(&conn, &id, &m, &failed, traffic);
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
            for m in outgoing.decision(&d, state, clock.as_ref(), received) {
                send(&conn, &id, &m, &failed, traffic);
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
            let made = d.stamp.times.decide_finished_ns;
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
    let i = incoming.lock().unwrap_or_else(|p| p.into_inner());
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
    Ok(format!(
        "{} heartbeats, {} attitudes ({} refused), {} timesyncs, {} ranges, {} local positions in; {sent_decisions} decisions ({} bad ones skipped), {} landing targets out ({} sends failed); {latency}; {clock}",
        c.heartbeats,
        c.attitudes,
        c.refused,
        c.timesyncs,
        c.heights,
        c.positions,
        decisions.rejections().count(),
        outgoing.landing_targets,
        failed.load(Ordering::Relaxed)
    ))
}

/// The `deckwatch-link` binary.
pub fn main() -> ExitCode {
    let args = <StageArgs as clap::Parser>::parse();
    exit_code(NAME, run(&args))
}
