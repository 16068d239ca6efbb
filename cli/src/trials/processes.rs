//! A closed-loop approach through the real processes at real time: the launcher starts detect,
//! estimate, decide and the MAVLink link; this process is the rest of the world. It is the
//! camera (it renders the frames of the true deck and the vehicle's own path and publishes them
//! on the frame service, as capture would) and the autopilot: over MAVLink on a UDP socket it
//! streams HEARTBEAT, ATTITUDE_QUATERNION and LOCAL_POSITION_NED, answers TIMESYNC, and acts on
//! the decision state the link sends (`dw_state`, `dw_reason`) when it arrives.

use super::{fault_model, world_of, Setup, TrialsArgs};
use crate::launch::{launch, LaunchOptions};
use deckwatch_common::messages::{monotonic_ns, DecisionReason, DecisionState};
use deckwatch_common::wire::WireCode;
use deckwatch_link::dialect::{
    MavAutopilot, MavModeFlag, MavState, MavType, ATTITUDE_QUATERNION_DATA, HEARTBEAT_DATA,
    LOCAL_POSITION_NED_DATA, TIMESYNC_DATA,
};
use deckwatch_link::frames::ned_quaternion_of_vehicle;
use deckwatch_link::mavlink::{self, ConnectionAddress, MavConnection, MavlinkVersion};
use deckwatch_link::outgoing::names;
use deckwatch_link::signing::load_key;
use deckwatch_link::SigningMode;
use deckwatch_link::{MavHeader, MavMessage};
use deckwatch_runtime::bus::Bus;
use deckwatch_runtime::stages::capture::{complete_header, new_header};
use deckwatch_sim::landing::{FlightPath, SharedFlightPath};
use deckwatch_trials::{
    Approach, ApproachOutcome, ApproachWorld, DecisionFollower, FrameFaults, SimulatedAutopilot,
    TouchdownVerdict, VehicleHeightError,
};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::Duration;

/// What the autopilot hears from deckwatch: a decision state with its reason, when it came (ns).
type Heard = (u64, DecisionState, DecisionReason);

/// A free UDP port on the loopback (the link binds it: `udpin`).
fn free_port() -> Result<u16, String> {
    let s = std::net::UdpSocket::bind("127.0.0.1:0").map_err(|e| format!("a UDP port: {e}"))?;
    s.local_addr().map(|a| a.port()).map_err(|e| e.to_string())
}

/// The autopilot's receiving side: answers TIMESYNC (its clock is this machine's monotonic
/// clock) and passes on each `dw_state` with the `dw_reason` that follows it.
fn listen(conn: Arc<mavlink::Connection<MavMessage>>, stop: Arc<AtomicBool>, heard: mpsc::Sender<Heard>) {
    let header = MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    };
    let mut state: Option<(u64, DecisionState)> = None;
    while !stop.load(Ordering::Relaxed) {
        let Ok((_, message)) = conn.recv() else { continue };
        let now = monotonic_ns();
        match message {
            MavMessage::TIMESYNC(t) if t.tc1 == 0 => {
                let reply = MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: now as i64,
                    ts1: t.ts1,
                    ..Default::default()
                });
                let _ = conn.send(&header, &reply);
            }
            MavMessage::NAMED_VALUE_INT(v) => {
                let name = v.name.to_str().unwrap_or_default();
                if name == names::STATE {
                    state = Some((now, WireCode::<DecisionState>::from_code(v.value as u32).get()));
                } else if name == names::REASON {
                    if let Some((at, s)) = state.take() {
                        let reason = WireCode::<DecisionReason>::from_code(v.value as u32).get();
                        if heard.send((at, s, reason)).is_err() {
                            return;
                        }
                    }
                }
            }
            _ => {}
        }
    }
}

/// Flies `job`'s approach by the decision, through the processes.
pub(super) fn fly(job: Approach, setup: &Setup, a: &TrialsArgs) -> Result<ApproachOutcome, String> {
    let world = world_of(job, a, setup.recorded.as_ref())?;
    let port = free_port()?;
    let mut config = setup.pipeline.clone();
    config.link.enabled = true;
    config.link.address = format!("udpin:127.0.0.1:{port}");
    config.bus.domain = format!("dwtrial{}x{}", std::process::id(), job.index);
    config.record = Default::default();
    let stop = Arc::new(AtomicBool::new(false));
    let options = LaunchOptions {
        external_frames: true,
        stop: Some(stop.clone()),
        ..Default::default()
    };
    let launcher = {
        let config = config.clone();
        std::thread::spawn(move || launch(&config, "deckwatch trials", &options))
    };
    let result = fly_with(&world, setup, a, &config, port, &stop, job);
    stop.store(true, Ordering::Relaxed);
    let report = launcher
        .join()
        .map_err(|_| "the launcher's thread panicked".to_string())?;
    match (result, report) {
        (Ok(outcome), Ok(_)) => Ok(outcome),
        (Err(e), Err(pipeline)) => Err(format!("{e}: the pipeline: {pipeline}")),
        (Err(e), Ok(_)) => Err(e),
        (Ok(_), Err(pipeline)) => Err(format!("the pipeline: {pipeline}")),
    }
}

fn fly_with(
    world: &ApproachWorld,
    setup: &Setup,
    a: &TrialsArgs,
    config: &deckwatch_runtime::config::PipelineConfig,
    port: u16,
    stop: &Arc<AtomicBool>,
    job: Approach,
) -> Result<ApproachOutcome, String> {
    let model = setup.model;
    let path: SharedFlightPath = Arc::new(Mutex::new(FlightPath::hover(model.hover_m)));
    let mut source = config
        .capture()
        .open_sim_with(Box::new(world.scene(path.clone(), 0.0)))
        .map_err(|e| e.to_string())?;
    // Join once the launcher has started its stages (it refuses a domain with live nodes), and
    // publish once the first stage (detect) listens.
    let domain = &config.bus.domain;
    let deadline = monotonic_ns() + 20_000_000_000;
    let bus = loop {
        if stop.load(Ordering::Relaxed) || monotonic_ns() > deadline {
            return Err("the pipeline did not start".into());
        }
        let nodes = Bus::live_nodes(domain).map_err(|e| e.to_string())?;
        if nodes
            .iter()
            .any(|n| n == deckwatch_common::messages::PipelineStage::FIRST.name())
        {
            break Bus::join(&config.bus.settings(source.frame_bytes()), "trials-camera")
                .map_err(|e| e.to_string())?;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let publisher = bus.frame_publisher().map_err(|e| e.to_string())?;
    while bus
        .subscriber_count(
            <deckwatch_common::messages::FrameHeader as deckwatch_common::messages::Channel>::SERVICE,
        )
        .map_err(|e| e.to_string())?
        < 1
    {
        if monotonic_ns() > deadline {
            return Err("detect did not subscribe to the frames".into());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    // The autopilot's end of the link.
    let address =
        ConnectionAddress::parse_address(&format!("udpout:127.0.0.1:{port}")).map_err(|e| e.to_string())?;
    let address = match address {
        ConnectionAddress::Udp(u) => ConnectionAddress::Udp(u.read_timeout(Duration::from_millis(5))),
        other => other,
    };
    let mut conn =
        mavlink::Connectable::connect::<MavMessage>(&address).map_err(|e| format!("MAVLink: {e}"))?;
    conn.set_protocol_version(MavlinkVersion::V2);
    // The autopilot signs with the link's key when the link requires it (as PX4 or ArduPilot
    // do once given the same key), on a link id of its own.
    if config.link.signing == SigningMode::Required {
        let key = load_key(std::path::Path::new(&config.link.signing_key_file)).map_err(|e| e.to_string())?;
        conn.setup_signing(Some(mavlink::SigningConfig::new(key, 1, true, false)));
    }
    let conn = Arc::new(conn);
    let (tx, heard) = mpsc::channel();
    let listener = {
        let (conn, stop) = (conn.clone(), stop.clone());
        std::thread::spawn(move || listen(conn, stop, tx))
    };
    // The autopilot's streams, on a thread of their own (as an autopilot is a device of its own:
    // the camera's rendering never delays them).
    let start = monotonic_ns() + 2_000_000_000;
    let vehicle_out = Arc::new(AtomicBool::new(false));
    let streams = {
        let (conn, stop, out, path, world) = (
            conn.clone(),
            stop.clone(),
            vehicle_out.clone(),
            path.clone(),
            world.clone(),
        );
        let height_error = VehicleHeightError::new(&fault_model(a), job.approach_seed());
        std::thread::spawn(move || stream(&conn, &stop, &out, &path, &world, &height_error, start))
    };
    let width = source.camera().width as usize;
    let mut frame = vec![0; source.frame_bytes()];
    let mut autopilot = SimulatedAutopilot::new(model, path.clone());
    let mut follow = DecisionFollower::new(config.decide.touchdown_s);
    let mut faults = FrameFaults::new(&fault_model(a), a.rate, job.approach_seed());
    let mut out = ApproachOutcome::default();
    let heave = |t: f64| world.heave_m(t);
    let capacity = &config.decide;
    // Two seconds of the autopilot's stream before the first frame: the link comes up.
    let t_of = |ns: u64| (ns as f64 - start as f64) / 1e9;
    let (mut k, mut seq) = (0u64, 0u64);
    let mut drops = deckwatch_common::messages::DropCounts::default();
    let frame_period_ns = (1e9 / a.rate) as u64;
    let result = loop {
        let now = monotonic_ns();
        let t = t_of(now);
        if let Some(contact) = autopilot.contact_s().filter(|&c| c <= t) {
            let (r_d, r_v) = world.attitudes(contact);
            out.touchdown = Some(TouchdownVerdict {
                descent_mps: Some(autopilot.descent_mps),
                ..TouchdownVerdict::judge(&|t| world.truth(t), &r_d, &r_v, contact, capacity, &model)
            });
            break Ok(());
        }
        if t > model.max_approach_s || stop.load(Ordering::Relaxed) {
            break Ok(());
        }
        // The autopilot acts on what it heard, when it heard it.
        while let Ok((at, state, reason)) = heard.try_recv() {
            let t_heard = t_of(at);
            out.decisions += 1;
            out.count_decision(state, reason);
            let command = follow.command(state);
            let descending = autopilot.contact_s().is_some();
            if descending && command == deckwatch_trials::Command::GoAround {
                out.count_go_around_order(reason, autopilot.can_go_around(t_heard.max(0.0)));
            }
            autopilot.act(t_heard.max(0.0), heave(t_heard), command);
        }
        // The camera: frame k when it is due.
        let due = start + k * frame_period_ns;
        if now >= due {
            let tk = k as f64 / a.rate;
            vehicle_out.store(faults.vehicle_out(tk), Ordering::Relaxed);
            // The frame as the camera took it, then the faults on its way: the same draws in the
            // same order as in one process (`FrameFaults::inject`, as the stage chain calls it).
            // Lost on the way, the stages never see it (the next one says so in its drops).
            let captured = source.capture(k, &mut frame, width);
            let kept = captured.is_ok() && faults.inject(tk, &mut frame);
            match captured {
                Ok(f) if kept => {
                    let header = new_header(&source, seq, drops);
                    let published = publisher.publish(header, |h, pixels| {
                        if pixels.len() != frame.len() {
                            return Err(format!(
                                "a frame of {} bytes for a sample of {}",
                                frame.len(),
                                pixels.len()
                            ));
                        }
                        pixels.copy_from_slice(&frame);
                        complete_header(h, &f);
                        // Mid-exposure: when the frame was due (rendering took some of that time).
                        h.stamp.times.captured_ns = due;
                        Ok(())
                    });
                    if published.is_err() {
                        drops.capture += 1;
                    } else {
                        seq += 1;
                    }
                }
                _ => drops.capture += 1,
            }
            out.frames += 1;
            k += 1;
        }
        std::thread::sleep(Duration::from_millis(1));
    };
    stop.store(true, Ordering::Relaxed);
    let _ = listener.join();
    let _ = streams.join();
    out.commits = autopilot.commits;
    out.go_arounds = autopilot.go_arounds;
    result.map(|()| out)
}

/// The autopilot's streams until `stop`: HEARTBEAT at 1 Hz, ATTITUDE_QUATERNION at 100 Hz and
/// LOCAL_POSITION_NED at 50 Hz of the vehicle as it is (its sway, its flight path's height),
/// the last two not while `out` (an outage of the stream). Its clock is this machine's
/// monotonic one; the approach's t = 0 is `start`.
fn stream(
    conn: &mavlink::Connection<MavMessage>,
    stop: &AtomicBool,
    out: &AtomicBool,
    path: &SharedFlightPath,
    world: &ApproachWorld,
    height_error: &VehicleHeightError,
    start: u64,
) {
    let mut sequence = 0u8;
    let mut send = |m: MavMessage| {
        sequence = sequence.wrapping_add(1);
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence,
        };
        let _ = conn.send(&header, &m);
    };
    let (mut next_attitude, mut next_position, mut next_heartbeat) = (0u64, 0u64, 0u64);
    while !stop.load(Ordering::Relaxed) {
        let now = monotonic_ns();
        let t = (now as f64 - start as f64) / 1e9;
        let boot_ms = (now / 1_000_000) as u32;
        if now >= next_heartbeat {
            next_heartbeat = now + 1_000_000_000;
            send(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0,
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
                base_mode: MavModeFlag::empty(),
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }));
        }
        let streaming = !out.load(Ordering::Relaxed);
        if now >= next_attitude {
            next_attitude = now + 10_000_000;
            if streaming {
                let r_v = world.vehicle_attitude(t);
                send(MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
                    time_boot_ms: boot_ms,
                    ..quaternion(&r_v)
                }));
            }
        }
        if now >= next_position {
            next_position = now + 20_000_000;
            if streaming {
                // Height and vertical speed, as an autopilot's estimator gives them (the link
                // carries the height to each attitude sample by the speed).
                let (height_m, up_mps) = {
                    let path = path.lock().unwrap_or_else(|e| e.into_inner());
                    height_error.reported(|t| path.height_m(t, world.heave_m(t)), t)
                };
                send(MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                    time_boot_ms: boot_ms,
                    z: -height_m as f32,
                    vz: -up_mps as f32,
                    ..Default::default()
                }));
            }
        }
        let next = next_attitude.min(next_position).min(next_heartbeat);
        std::thread::sleep(Duration::from_nanos(
            next.saturating_sub(monotonic_ns()).min(5_000_000),
        ));
    }
}

/// ATTITUDE_QUATERNION's `q` of `R_V`.
fn quaternion(r_v: &deckwatch_common::RotationMatrix) -> ATTITUDE_QUATERNION_DATA {
    let q = ned_quaternion_of_vehicle(r_v);
    ATTITUDE_QUATERNION_DATA {
        q1: q[0],
        q2: q[1],
        q3: q[2],
        q4: q[3],
        ..Default::default()
    }
}
