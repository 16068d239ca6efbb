//! What the autopilot sends: its heartbeat, attitude, time and height; turned into vehicle
//! samples on this machine's clock, TIMESYNC answers, and the link's health.

use crate::clock::ClockSync;
use crate::config::LinkConfig;
use crate::dialect::{MavAutopilot, MavMessage, MavType, TIMESYNC_DATA};
use crate::frames::{vehicle_from_ned_euler, vehicle_from_ned_quaternion};
use deckwatch_common::messages::VehicleSample;
use deckwatch_common::Quaternion;
use mavlink::MavHeader;

/// The state of the link at one moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkState {
    /// No autopilot heard yet.
    Waiting,
    Up,
    /// The autopilot's HEARTBEAT stopped.
    NoHeartbeat,
    /// Its attitude stream stopped (or never started).
    NoAttitude,
}

impl LinkState {
    pub fn name(&self) -> &'static str {
        match self {
            Self::Waiting => "waiting",
            Self::Up => "up",
            Self::NoHeartbeat => "no-heartbeat",
            Self::NoAttitude => "no-attitude",
        }
    }
}

/// What was received, by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InCounts {
    pub heartbeats: u64,
    pub attitudes: u64,
    pub timesyncs: u64,
    /// DISTANCE_SENSOR readings used.
    pub heights: u64,
    /// LOCAL_POSITION_NED received (the vehicle's height in the local frame).
    pub positions: u64,
    /// Attitudes that were not rotations.
    pub refused: u64,
    /// Messages from anyone but the pinned autopilot (admission refuses them first; counted here
    /// should a caller hand one over).
    pub foreign: u64,
    pub other: u64,
}

/// What handling one message gives.
#[derive(Debug, Clone, Default)]
pub struct Handled {
    /// A vehicle attitude sample to publish.
    pub sample: Option<VehicleSample>,
    /// A message to send back at once (a TIMESYNC answer).
    pub reply: Option<MavMessage>,
}

/// A LOCAL_POSITION_NED further than this from an attitude sample gives it no height (ms).
const HEIGHT_MAX_AGE_MS: f64 = 200.0;

/// The receiving side of the link.
#[derive(Debug, Clone)]
pub struct Incoming {
    heartbeat_timeout_ns: u64,
    attitude_timeout_ns: u64,
    pub clock: ClockSync,
    /// The autopilot's system and component id (`[link]`), pinned.
    pinned: (u32, u8),
    /// The autopilot, once its first HEARTBEAT came.
    pub autopilot: Option<(u32, u8)>,
    last_heartbeat_ns: Option<u64>,
    last_attitude_ns: Option<u64>,
    /// ATTITUDE_QUATERNION seen: ATTITUDE (the same attitude, as angles) is then ignored.
    quaternions: bool,
    altitude_m: f64,
    /// The newest LOCAL_POSITION_NED: (time_boot_ms, height up m, vertical speed up m/s).
    local_height: Option<(u32, f64, f64)>,
    seq: u64,
    newest: Option<VehicleSample>,
    pub counts: InCounts,
}

impl Incoming {
    pub fn new(config: &LinkConfig) -> Self {
        Self {
            heartbeat_timeout_ns: (config.heartbeat_timeout_ms * 1e6) as u64,
            attitude_timeout_ns: (config.attitude_timeout_ms * 1e6) as u64,
            clock: ClockSync::default(),
            pinned: (
                u32::from(config.autopilot_system_id),
                config.autopilot_component_id,
            ),
            autopilot: None,
            last_heartbeat_ns: None,
            last_attitude_ns: None,
            quaternions: false,
            altitude_m: f64::NAN,
            local_height: None,
            seq: 0,
            newest: None,
            counts: InCounts::default(),
        }
    }

    /// The link at `now_ns`.
    pub fn state(&self, now_ns: u64) -> LinkState {
        let fresh = |t: Option<u64>, limit: u64| t.is_some_and(|t| now_ns.saturating_sub(t) <= limit);
        match self.last_heartbeat_ns {
            None => LinkState::Waiting,
            _ if !fresh(self.last_heartbeat_ns, self.heartbeat_timeout_ns) => LinkState::NoHeartbeat,
            _ if !fresh(self.last_attitude_ns, self.attitude_timeout_ns) => LinkState::NoAttitude,
            _ => LinkState::Up,
        }
    }

    /// The newest vehicle sample made.
    pub fn newest_sample(&self) -> Option<VehicleSample> {
        self.newest
    }

    fn is_autopilot(&self, h: &MavHeader) -> bool {
        self.autopilot == Some((h.system_id, h.component_id))
    }

    /// Handles one message received at `now_ns`: only the pinned autopilot's are used.
    pub fn handle(&mut self, h: &MavHeader, msg: &MavMessage, now_ns: u64) -> Handled {
        let mut out = Handled::default();
        if (h.system_id, h.component_id) != self.pinned {
            self.counts.foreign += 1;
            return out;
        }
        match msg {
            MavMessage::HEARTBEAT(hb) => {
                let is_autopilot = hb.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
                    && hb.mavtype != MavType::MAV_TYPE_GCS;
                if is_autopilot && self.autopilot.is_none() {
                    self.autopilot = Some(self.pinned);
                }
                if self.is_autopilot(h) {
                    self.counts.heartbeats += 1;
                    self.last_heartbeat_ns = Some(now_ns);
                } else {
                    self.counts.other += 1;
                }
            }
            MavMessage::ATTITUDE_QUATERNION(a) => {
                self.quaternions = true;
                let q = vehicle_from_ned_quaternion([a.q1, a.q2, a.q3, a.q4]);
                out.sample = self.attitude(h, a.time_boot_ms, q, now_ns);
            }
            MavMessage::ATTITUDE(a) if !self.quaternions => {
                let q = vehicle_from_ned_euler(a.roll, a.pitch, a.yaw);
                out.sample = self.attitude(h, a.time_boot_ms, q, now_ns);
            }
            MavMessage::TIMESYNC(t) if self.is_autopilot(h) => {
                self.counts.timesyncs += 1;
                if t.tc1 == 0 {
                    // A request (the autopilot syncing to us): answer with our time.
                    out.reply = Some(MavMessage::TIMESYNC(TIMESYNC_DATA {
                        tc1: now_ns as i64,
                        ts1: t.ts1,
                        target_system: u8::try_from(h.system_id).unwrap_or(0),
                        target_component: h.component_id,
                    }));
                } else if self.clock.is_ours(t.ts1) {
                    self.clock.answer(t.tc1, t.ts1, now_ns as i64);
                }
            }
            MavMessage::DISTANCE_SENSOR(d) if self.is_autopilot(h) => {
                // cm; 0 and out-of-range readings mean "nothing measured".
                let cm = d.current_distance;
                if cm > 0 && cm >= d.min_distance && (d.max_distance == 0 || cm <= d.max_distance) {
                    self.altitude_m = f64::from(cm) / 100.0;
                    self.counts.heights += 1;
                }
            }
            MavMessage::LOCAL_POSITION_NED(p) if self.is_autopilot(h) => {
                // Height above the local origin (home): the rangefinder is preferred when present.
                if self.counts.heights == 0 && p.z.is_finite() {
                    self.altitude_m = -f64::from(p.z);
                }
                if p.z.is_finite() && p.vz.is_finite() {
                    self.local_height = Some((p.time_boot_ms, -f64::from(p.z), -f64::from(p.vz)));
                    self.counts.positions += 1;
                }
            }
            _ => self.counts.other += 1,
        }
        out
    }

    /// The vehicle's height in the local frame at `time_boot_ms` and its vertical speed (m,
    /// m/s, up): the newest LOCAL_POSITION_NED carried there by its vertical speed (the
    /// autopilot sends positions more slowly than attitudes); NaN with none within
    /// `HEIGHT_MAX_AGE_MS`.
    fn height_at(&self, time_boot_ms: u32) -> (f64, f64) {
        match self.local_height {
            Some((t, h, v)) => {
                let dt_ms = f64::from(time_boot_ms) - f64::from(t);
                if dt_ms.abs() <= HEIGHT_MAX_AGE_MS {
                    (h + v * dt_ms / 1e3, v)
                } else {
                    (f64::NAN, f64::NAN)
                }
            }
            None => (f64::NAN, f64::NAN),
        }
    }

    fn attitude(
        &mut self,
        h: &MavHeader,
        time_boot_ms: u32,
        q: Option<Quaternion>,
        now_ns: u64,
    ) -> Option<VehicleSample> {
        let Some(q) = q.filter(|_| self.is_autopilot(h)) else {
            self.counts.refused += 1;
            return None;
        };
        self.counts.attitudes += 1;
        self.last_attitude_ns = Some(now_ns);
        let remote_ns = i64::from(time_boot_ms) * 1_000_000;
        self.clock.arrival(remote_ns, now_ns as i64);
        let clock = self.clock.estimate()?;
        let local = clock.to_local_ns(remote_ns as f64);
        let (height_m, vertical_speed_mps) = self.height_at(time_boot_ms);
        let sample = VehicleSample {
            seq: self.seq,
            // Never after its own arrival (an offset estimate can be off by the latency).
            time_ns: local.clamp(0.0, now_ns as f64) as u64,
            autopilot_time_us: u64::from(time_boot_ms) * 1000,
            received_ns: now_ns,
            quaternion: q,
            altitude_m: self.altitude_m,
            height_m,
            vertical_speed_mps,
            clock_offset_ns: clock.offset_at(local) as i64,
            clock_method: clock.method.into(),
            clock_drift_ppm: clock.drift_ppm,
            link_up: (self.state(now_ns) == LinkState::Up).into(),
        };
        self.seq += 1;
        self.newest = Some(sample);
        Some(sample)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{
        MavModeFlag, MavState, ATTITUDE_QUATERNION_DATA, HEARTBEAT_DATA, LOCAL_POSITION_NED_DATA,
    };
    use deckwatch_common::messages::ClockMethod;

    fn header(system_id: u32, component_id: u8) -> MavHeader {
        MavHeader {
            system_id,
            component_id,
            sequence: 0,
        }
    }

    fn heartbeat(autopilot: MavAutopilot, mavtype: MavType) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype,
            autopilot,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        })
    }

    fn attitude(ms: u32) -> MavMessage {
        MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms: ms,
            q1: 1.0,
            ..Default::default()
        })
    }

    #[test]
    fn link_comes_up_and_goes_down() {
        let mut i = Incoming::new(&LinkConfig::default());
        assert_eq!(i.state(0), LinkState::Waiting);
        let ap = header(1, 1);
        // Before the autopilot is known, attitudes are refused; a GCS heartbeat does not count.
        assert!(i.handle(&ap, &attitude(10), 1_000).sample.is_none());
        i.handle(
            &header(255, 190),
            &heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID, MavType::MAV_TYPE_GCS),
            1_000,
        );
        assert_eq!(i.autopilot, None);
        i.handle(
            &ap,
            &heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4, MavType::MAV_TYPE_QUADROTOR),
            2_000,
        );
        assert_eq!(i.autopilot, Some((1, 1)));
        assert_eq!(i.state(2_000), LinkState::NoAttitude);
        let s = i.handle(&ap, &attitude(5_000), 10_000_000).sample.unwrap();
        assert!(s.link_up.get() && s.clock_method == ClockMethod::Arrival);
        assert_eq!(s.time_ns, 10_000_000, "arrival offset: taken at its arrival");
        assert_eq!(i.state(10_000_000 + 150_000_000), LinkState::Up);
        assert_eq!(i.state(10_000_000 + 250_000_000), LinkState::NoAttitude);
        assert_eq!(i.state(4_000_000_000), LinkState::NoHeartbeat);
        // Another system's attitude, heartbeat or TIMESYNC is not ours, whatever it says.
        assert!(i
            .handle(&header(2, 1), &attitude(6_000), 11_000_000)
            .sample
            .is_none());
        i.handle(
            &header(1, 2),
            &heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4, MavType::MAV_TYPE_QUADROTOR),
            12_000_000,
        );
        let answer = i.handle(
            &header(2, 1),
            &MavMessage::TIMESYNC(TIMESYNC_DATA {
                tc1: 0,
                ts1: 5,
                target_system: 0,
                target_component: 0,
            }),
            13_000_000,
        );
        assert!(
            answer.reply.is_none(),
            "TIMESYNC is answered for the autopilot only"
        );
        assert_eq!((i.counts.refused, i.counts.foreign), (1, 4));
        assert_eq!(i.autopilot, Some((1, 1)));
    }

    #[test]
    fn local_position_gives_each_attitude_the_vehicles_height() {
        let mut i = Incoming::new(&LinkConfig::default());
        let ap = header(1, 1);
        i.handle(
            &ap,
            &heartbeat(
                MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                MavType::MAV_TYPE_QUADROTOR,
            ),
            1_000,
        );
        let s = i.handle(&ap, &attitude(1_000), 2_000_000).sample.unwrap();
        assert!(s.height_m.is_nan(), "no LOCAL_POSITION_NED yet");
        // NED: 12 m up, climbing at 0.5 m/s; an attitude 40 ms later is 2 cm higher.
        let position = MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: 1_010,
            z: -12.0,
            vz: -0.5,
            ..Default::default()
        });
        i.handle(&ap, &position, 3_000_000);
        let s = i.handle(&ap, &attitude(1_050), 4_000_000).sample.unwrap();
        assert!((s.height_m - 12.02).abs() < 1e-6, "{}", s.height_m);
        assert!((s.vertical_speed_mps - 0.5).abs() < 1e-6, "up");
        assert_eq!(i.counts.positions, 1);
        // Too far from the position: no height rather than a guess.
        let s = i.handle(&ap, &attitude(1_500), 5_000_000).sample.unwrap();
        assert!(s.height_m.is_nan() && s.vertical_speed_mps.is_nan());
    }

    #[test]
    fn timesync_requests_are_answered_and_answers_used() {
        let mut i = Incoming::new(&LinkConfig::default());
        let ap = header(1, 1);
        i.handle(
            &ap,
            &heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4, MavType::MAV_TYPE_QUADROTOR),
            1_000,
        );
        let reply = i
            .handle(
                &ap,
                &MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: 0,
                    ts1: 777,
                    target_system: 0,
                    target_component: 0,
                }),
                5_000,
            )
            .reply
            .unwrap();
        match reply {
            MavMessage::TIMESYNC(t) => assert_eq!((t.tc1, t.ts1), (5_000, 777)),
            other => panic!("{other:?}"),
        }
        let ts1 = i.clock.request(1_000_000);
        let answer = MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 9_000_000_000,
            ts1,
            target_system: 0,
            target_component: 0,
        });
        i.handle(&ap, &answer, 1_400_000);
        let e = i.clock.estimate().unwrap();
        assert_eq!(e.method, ClockMethod::Timesync);
        assert_eq!(e.offset_ns as i64, 9_000_000_000 - 1_200_000);
    }
}
