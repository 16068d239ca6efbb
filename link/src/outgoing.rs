//! What deckwatch tells the autopilot and the ground station: its heartbeat, TIMESYNC requests,
//! and each landing decision as LANDING_TARGET and/or TARGET_RELATIVE (for precision landing;
//! `[link] target_messages`), NAMED_VALUE_FLOAT/INT (plotted by QGroundControl and Mission
//! Planner) and STATUSTEXT (on every change).

use crate::clock::ClockEstimate;
use crate::config::{LinkConfig, LANDING_TARGET_MESSAGE, TARGET_RELATIVE_MESSAGE};
use crate::dialect::{
    LandingTargetType, MavAutopilot, MavBool, MavFrame, MavMessage, MavModeFlag, MavSeverity, MavState,
    MavType, HEARTBEAT_DATA, LANDING_TARGET_DATA, NAMED_VALUE_FLOAT_DATA, NAMED_VALUE_INT_DATA,
    STATUSTEXT_DATA, TIMESYNC_DATA,
};
use crate::frames::{body_covariance, body_target};
use crate::incoming::LinkState;
use crate::target_relative::{relative_target, target_relative_message};
use deckwatch_common::messages::{DecisionReason, DecisionState, LandingDecision};
use deckwatch_common::vehicle::Compensation;
use deckwatch_common::{Quaternion, RotationMatrix};

/// The names of the NAMED_VALUE_FLOAT/INT deckwatch sends (at most 10 characters each).
pub mod names {
    /// Deck roll and pitch in W (deg).
    pub const ROLL: &str = "dw_roll";
    pub const PITCH: &str = "dw_pitch";
    /// The deck centre's height in W (m, on the autopilot's local origin) and its vertical
    /// speed (m/s, up); NaN when not measured.
    pub const HEAVE: &str = "dw_heave";
    pub const HEAVE_RATE: &str = "dw_hrate";
    /// Start and length of the next predicted calm window (s; -1: none).
    pub const CALM_START: &str = "dw_calm_s";
    pub const CALM_LENGTH: &str = "dw_calm_l";
    /// `DecisionState` and `DecisionReason` as their numbers.
    pub const STATE: &str = "dw_state";
    pub const REASON: &str = "dw_reason";
    /// `LinkState`: 0 waiting, 1 up, 2 no heartbeat, 3 no attitude.
    pub const LINK: &str = "dw_link";
}

/// The state deckwatch reports: the decision's, except that ClearToLand never goes out while the
/// link is not up (the attitude it rests on might be uncompensated).
pub fn reported_state(d: &LandingDecision, link: LinkState) -> DecisionState {
    if d.state == DecisionState::ClearToLand && link != LinkState::Up {
        DecisionState::Hold
    } else {
        d.state.get()
    }
}

/// What the link reports when decide has said nothing for longer than its freshness limit (or
/// nothing yet): NO-DECK for stale data, on the newest decision's frame, never a target. A
/// decision the link cannot see renewed is not one to act on.
pub fn stale_decision(last: Option<&LandingDecision>) -> LandingDecision {
    let mut d = last.copied().unwrap_or_default();
    d.state = DecisionState::NoDeck.into();
    d.reason = DecisionReason::StaleData.into();
    d.calm_window_start_s = f64::NAN;
    d.calm_window_length_s = f64::NAN;
    d.heave_rate_mps = f64::NAN;
    d.watchdog = true.into();
    d
}

/// The decision as the link may forward it at `now_ns` (`CLOCK_MONOTONIC`, the clock of its
/// capture stamp): one whose frame was captured more than `max_age_ns` ago, or at an unknown
/// time, is stale whatever it said (`stale_decision`). Judged by the capture's age, not by
/// when the decision arrived: a clearance that reached the link late is a clearance on an old
/// deck. decide's own stale decisions (`watchdog`) pass as they are.
pub fn forwardable(d: &LandingDecision, now_ns: u64, max_age_ns: u64) -> LandingDecision {
    let captured = d.stamp.times.captured_ns;
    let old = captured == 0 || now_ns.saturating_sub(captured) > max_age_ns;
    if old && !d.watchdog.get() {
        stale_decision(Some(d))
    } else {
        *d
    }
}

/// An autopilot time (ns) as MAVLink's `time_boot_ms`, which wraps after 49.7 days.
fn wrapped_ms(autopilot_ns: f64) -> u32 {
    ((autopilot_ns / 1e6).max(0.0) as u64) as u32
}

fn link_number(l: LinkState) -> i32 {
    match l {
        LinkState::Waiting => 0,
        LinkState::Up => 1,
        LinkState::NoHeartbeat => 2,
        LinkState::NoAttitude => 3,
    }
}

/// The sending side of the link: rates and what changed.
#[derive(Debug, Clone)]
pub struct Outgoing {
    target_period_ns: u64,
    telemetry_period_ns: u64,
    mount: RotationMatrix,
    last_target_ns: Option<u64>,
    last_telemetry_ns: Option<u64>,
    last_status: Option<(DecisionState, u8, LinkState)>,
    /// `[link] target_messages`.
    send_landing_target: bool,
    send_target_relative: bool,
    pub landing_targets: u64,
    pub target_relatives: u64,
}

fn period_ns(hz: f64) -> u64 {
    if hz > 0.0 {
        (1e9 / hz) as u64
    } else {
        0
    }
}

impl Outgoing {
    pub fn new(config: &LinkConfig, mount: RotationMatrix) -> Self {
        Self {
            target_period_ns: period_ns(config.landing_target_hz),
            // 0 Hz: off.
            telemetry_period_ns: if config.telemetry_hz > 0.0 {
                period_ns(config.telemetry_hz)
            } else {
                u64::MAX
            },
            mount,
            last_target_ns: None,
            last_telemetry_ns: None,
            last_status: None,
            send_landing_target: config.sends(LANDING_TARGET_MESSAGE),
            send_target_relative: config.sends(TARGET_RELATIVE_MESSAGE),
            landing_targets: 0,
            target_relatives: 0,
        }
    }

    /// Our HEARTBEAT: an onboard controller, no autopilot of its own.
    pub fn heartbeat(link: LinkState) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: if link == LinkState::Up {
                MavState::MAV_STATE_ACTIVE
            } else {
                MavState::MAV_STATE_STANDBY
            },
            mavlink_version: 3,
        })
    }

    /// A TIMESYNC request carrying our time `ts1` (ns).
    pub fn timesync_request(ts1: i64, target: Option<(u32, u8)>) -> MavMessage {
        let (system, target_component) = target.unwrap_or((0, 0));
        let target_system = u8::try_from(system).unwrap_or(0);
        MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 0,
            ts1,
            target_system,
            target_component,
        })
    }

    /// A status line for the ground station.
    pub fn status_text(severity: MavSeverity, text: &str) -> MavMessage {
        // 50 bytes, no terminator needed when full.
        let text: String = text.chars().take(50).collect();
        MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity,
            text: text.as_str().into(),
            id: 0,
            chunk_seq: 0,
        })
    }

    /// The messages for one decision, made at `now_ns`; `clock` puts times on the autopilot's
    /// clock, `boot_ms` is the autopilot's time now (ms) for the named values. Without the
    /// vehicle's attitude at the exposure ([`Self::decision_with_attitude`]).
    pub fn decision(
        &mut self,
        d: &LandingDecision,
        link: LinkState,
        clock: Option<&ClockEstimate>,
        now_ns: u64,
    ) -> Vec<MavMessage> {
        self.decision_with_attitude(d, link, clock, now_ns, None)
    }

    /// The same, with `vehicle_at_capture`: the vehicle's north-referenced attitude (`R_V`, body
    /// FLU to NWU) at the frame's mid-exposure from the autopilot's own stream, TARGET_RELATIVE's
    /// `q_sensor` (none: `q_sensor` is zero, and PX4 uses its own attitude; [`crate::target_relative`]).
    pub fn decision_with_attitude(
        &mut self,
        d: &LandingDecision,
        link: LinkState,
        clock: Option<&ClockEstimate>,
        now_ns: u64,
        vehicle_at_capture: Option<&Quaternion>,
    ) -> Vec<MavMessage> {
        let mut out = Vec::with_capacity(9);
        let a = &d.attitude;
        let remote = |local_ns: u64| clock.map(|c| c.to_remote_ns(local_ns as f64));
        let boot_ms = remote(now_ns).map_or(0, wrapped_ms);
        let state = reported_state(d, link);
        let status = (state, d.reason.get() as u8, link);
        // The target goes first: it is what the autopilot acts on soonest.
        let mut status_text = None;
        if self.last_status != Some(status) {
            self.last_status = Some(status);
            let severity = match state {
                DecisionState::Abort => MavSeverity::MAV_SEVERITY_WARNING,
                DecisionState::ClearToLand => MavSeverity::MAV_SEVERITY_NOTICE,
                _ => MavSeverity::MAV_SEVERITY_INFO,
            };
            let mut text = format!("deckwatch {}: {}", state.name(), d.reason.get().name());
            if link != LinkState::Up {
                text = format!("deckwatch {}: link {}", state.name(), link.name());
            }
            status_text = Some(Self::status_text(severity, &text));
        }
        // The target only when the deck is where the full pose says, in a compensated frame.
        let position = a.camera_position_m;
        let usable = !d.watchdog.get()
            && a.valid.get()
            && a.vehicle.compensation != Compensation::Missing
            && position.iter().all(|v| v.is_finite());
        let due = |last: Option<u64>, period: u64| last.is_none_or(|t| now_ns.saturating_sub(t) >= period);
        if usable && due(self.last_target_ns, self.target_period_ns) {
            self.last_target_ns = Some(now_ns);
            let r_v = a.vehicle.matrix();
            let t = body_target(position, &a.rpy.to_matrix(), &r_v, &self.mount);
            // Mid-exposure on the autopilot's clock; our own clock until it is known.
            let captured = d.stamp.times.captured_ns;
            let time_usec = remote(captured).map_or(captured as f64, |r| r.max(0.0)) / 1e3;
            let [x, y, z] = t.position_frd_m.map(|v| v as f32);
            if self.send_landing_target {
                self.landing_targets += 1;
                out.push(MavMessage::LANDING_TARGET(LANDING_TARGET_DATA {
                    time_usec: time_usec as u64,
                    angle_x: t.angle_rad[0] as f32,
                    angle_y: t.angle_rad[1] as f32,
                    distance: t.distance_m as f32,
                    size_x: 0.0,
                    size_y: 0.0,
                    target_num: 0,
                    frame: MavFrame::MAV_FRAME_BODY_FRD,
                    x,
                    y,
                    z,
                    q: t.orientation_frd.map(|v| v as f32),
                    mavtype: LandingTargetType::LANDING_TARGET_TYPE_VISION_FIDUCIAL,
                    position_valid: MavBool::MAV_BOOL_TRUE,
                }));
            }
            if self.send_target_relative {
                // The same instant as LANDING_TARGET's, on our own clock (PX4 moves it onto its
                // own: `target_relative_message`).
                let covariance_frd = body_covariance(&a.camera_position_covariance_m2, &r_v);
                if let Some(r) = relative_target(&t, a.rpy_std_deg, &covariance_frd, vehicle_at_capture) {
                    self.target_relatives += 1;
                    out.push(target_relative_message(&r, captured / 1_000));
                }
            }
        }
        let changed = status_text.is_some();
        out.extend(status_text);
        if due(self.last_telemetry_ns, self.telemetry_period_ns) || changed {
            self.last_telemetry_ns = Some(now_ns);
            let [roll, pitch, _] = if a.valid.get() {
                a.rpy.to_degrees()
            } else {
                [f64::NAN; 3]
            };
            let calm = |v: f64| if v.is_finite() { v } else { -1.0 };
            // The values at the instant they describe, the frame's mid-exposure on the
            // autopilot's clock (beside its own attitude in a log, not a pipeline's latency
            // later): the deck's, and the calm window's, which counts from the capture. The
            // states below when they are sent. 0 until the autopilot's clock is known.
            let captured_boot_ms = match d.stamp.times.captured_ns {
                0 => 0,
                captured => remote(captured).map_or(0, wrapped_ms),
            };
            for (name, value) in [
                (names::ROLL, roll),
                (names::PITCH, pitch),
                (
                    names::HEAVE,
                    if a.valid.get() { a.deck_height_m } else { f64::NAN },
                ),
                (names::HEAVE_RATE, d.heave_rate_mps),
                (names::CALM_START, calm(d.calm_window_start_s)),
                (names::CALM_LENGTH, calm(d.calm_window_length_s)),
            ] {
                out.push(MavMessage::NAMED_VALUE_FLOAT(NAMED_VALUE_FLOAT_DATA {
                    time_boot_ms: captured_boot_ms,
                    value: value as f32,
                    name: name.into(),
                }));
            }
            for (name, value) in [
                (names::STATE, state as i32),
                (names::REASON, d.reason.get() as i32),
                (names::LINK, link_number(link)),
            ] {
                out.push(MavMessage::NAMED_VALUE_INT(NAMED_VALUE_INT_DATA {
                    time_boot_ms: boot_ms,
                    value,
                    name: name.into(),
                }));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::Rpy;

    fn decision(state: DecisionState) -> LandingDecision {
        let mut d = LandingDecision {
            state: state.into(),
            reason: DecisionReason::WithinCapacity.into(),
            calm_window_start_s: f64::NAN,
            calm_window_length_s: f64::NAN,
            ..Default::default()
        };
        d.attitude.valid = true.into();
        d.attitude.rpy = Rpy::from_degrees(2.0, -1.0, 0.0);
        d.attitude.camera_position_m = [0.0, 0.0, 5.0];
        d.attitude.rpy_std_deg = [0.1, 0.1, 0.4];
        d.attitude.vehicle.compensation = Compensation::Frame.into();
        d.stamp.times.captured_ns = 1_000_000;
        d
    }

    #[test]
    fn a_clearance_on_an_old_capture_is_forwarded_as_stale() {
        let d = decision(DecisionState::ClearToLand);
        let max_age_ns = 300_000_000;
        // 0.2 s after capture: as it is.
        let fresh = forwardable(&d, 1_000_000 + 200_000_000, max_age_ns);
        assert_eq!(fresh.state.get(), DecisionState::ClearToLand);
        // 0.4 s after capture (however recently it arrived), or captured at an unknown time:
        // stale, never a clearance.
        let mut unknown = d;
        unknown.stamp.times.captured_ns = 0;
        for (d, now) in [(d, 1_000_000 + 400_000_000), (unknown, 2_000_000)] {
            let f = forwardable(&d, now, max_age_ns);
            assert_eq!(f.state.get(), DecisionState::NoDeck);
            assert_eq!(f.reason.get(), DecisionReason::StaleData);
        }
    }

    fn kinds(m: &[MavMessage]) -> Vec<&'static str> {
        m.iter()
            .map(|m| match m {
                MavMessage::LANDING_TARGET(_) => "target",
                MavMessage::TARGET_RELATIVE(_) => "relative",
                MavMessage::NAMED_VALUE_FLOAT(_) => "float",
                MavMessage::NAMED_VALUE_INT(_) => "int",
                MavMessage::STATUSTEXT(_) => "text",
                _ => "other",
            })
            .collect()
    }

    #[test]
    fn a_decision_not_renewed_is_reported_stale_without_a_target() {
        let mut o = Outgoing::new(&LinkConfig::default(), RotationMatrix::identity());
        let d = decision(DecisionState::ClearToLand);
        o.decision(&d, LinkState::Up, None, 10);
        let stale = stale_decision(Some(&d));
        assert_eq!(
            (stale.state.get(), stale.reason.get()),
            (DecisionState::NoDeck, DecisionReason::StaleData)
        );
        let m = o.decision(&stale, LinkState::Up, None, 400_000_010);
        assert_eq!(kinds(&m)[0], "text", "no target, the change said at once");
        match &m[0] {
            MavMessage::STATUSTEXT(s) => {
                assert_eq!(s.text.to_str().unwrap(), "deckwatch NO-DECK: stale-data")
            }
            _ => unreachable!(),
        }
        assert!(m.iter().any(|m| matches!(m, MavMessage::NAMED_VALUE_INT(v)
            if v.name.to_str().unwrap() == names::STATE && v.value == 0)));
        // Before any decision: the same.
        assert_eq!(stale_decision(None).state, DecisionState::NoDeck);
    }

    #[test]
    fn a_decision_becomes_target_values_and_a_status_on_change() {
        let mut o = Outgoing::new(&LinkConfig::default(), RotationMatrix::identity());
        let d = decision(DecisionState::ClearToLand);
        let m = o.decision(&d, LinkState::Up, None, 10);
        assert_eq!(
            kinds(&m),
            ["target", "text", "float", "float", "float", "float", "float", "float", "int", "int", "int"]
        );
        match &m[1] {
            MavMessage::STATUSTEXT(s) => {
                assert_eq!(s.text.to_str().unwrap(), "deckwatch CLEAR: within-capacity")
            }
            _ => unreachable!(),
        }
        match &m[0] {
            MavMessage::LANDING_TARGET(t) => {
                assert_eq!(t.frame, MavFrame::MAV_FRAME_BODY_FRD);
                assert_eq!(t.position_valid, MavBool::MAV_BOOL_TRUE);
                assert!((t.z - 5.0).abs() < 1e-6 && t.time_usec == 1_000);
            }
            _ => unreachable!(),
        }
        // 1 ms later: a target (every frame) but no telemetry (5 Hz) and no status (no change).
        let m = o.decision(&d, LinkState::Up, None, 1_000_010);
        assert_eq!(kinds(&m), ["target"]);
        // The link goes down: CLEAR is not reported, and the change is said at once.
        let m = o.decision(&d, LinkState::NoAttitude, None, 2_000_010);
        assert_eq!(kinds(&m)[..2], ["target", "text"]);
        match &m[1] {
            MavMessage::STATUSTEXT(s) => {
                assert_eq!(s.text.to_str().unwrap(), "deckwatch HOLD: link no-attitude")
            }
            _ => unreachable!(),
        }
        assert!(m.iter().any(|x| matches!(x, MavMessage::NAMED_VALUE_INT(v)
            if v.name.to_str().unwrap() == names::STATE && v.value == DecisionState::Hold as i32)));
        // Not compensated: no target.
        let mut u = decision(DecisionState::Hold);
        u.attitude.vehicle.compensation = Compensation::Missing.into();
        let m = o.decision(&u, LinkState::Up, None, 3_000_010);
        assert!(!kinds(&m).contains(&"target"));
    }

    /// The float values (the deck's, the calm window's) are stamped at the frame's mid-exposure on
    /// the autopilot's clock, the states when they are sent; 0 while that clock is unknown.
    #[test]
    fn named_values_are_stamped_at_what_they_describe() {
        let mut o = Outgoing::new(&LinkConfig::default(), RotationMatrix::identity());
        let mut d = decision(DecisionState::Hold);
        d.stamp.times.captured_ns = 5_000_000_000;
        // The autopilot's clock 2 s ahead of ours.
        let clock = ClockEstimate {
            offset_ns: 2e9,
            at_local_ns: 5e9,
            drift_ppm: 0.0,
            rtt_ns: 0,
            method: deckwatch_common::messages::ClockMethod::Timesync,
        };
        let now_ns = 5_080_000_000;
        let stamps: Vec<(String, u32)> = o
            .decision(&d, LinkState::Up, Some(&clock), now_ns)
            .iter()
            .filter_map(|m| match m {
                MavMessage::NAMED_VALUE_FLOAT(v) => {
                    Some((v.name.to_str().unwrap().to_string(), v.time_boot_ms))
                }
                MavMessage::NAMED_VALUE_INT(v) => {
                    Some((v.name.to_str().unwrap().to_string(), v.time_boot_ms))
                }
                _ => None,
            })
            .collect();
        assert_eq!(stamps.len(), 9, "{stamps:?}");
        for (name, ms) in &stamps {
            let expected = match name.as_str() {
                names::STATE | names::REASON | names::LINK => 7_080,
                _ => 7_000,
            };
            assert_eq!(*ms, expected, "{name}");
        }
        // No clock: 0 for all.
        let mut o = Outgoing::new(&LinkConfig::default(), RotationMatrix::identity());
        assert!(o
            .decision(&d, LinkState::Up, None, now_ns)
            .iter()
            .all(|m| match m {
                MavMessage::NAMED_VALUE_FLOAT(v) => v.time_boot_ms == 0,
                MavMessage::NAMED_VALUE_INT(v) => v.time_boot_ms == 0,
                _ => true,
            }));
    }

    /// TARGET_RELATIVE goes beside LANDING_TARGET when configured, under the same conditions, at
    /// the same rate and (no autopilot clock known yet: both on ours) with the same stamp; alone
    /// when LANDING_TARGET is not named.
    #[test]
    fn target_relative_follows_the_landing_target() {
        let both = LinkConfig {
            target_messages: vec![LANDING_TARGET_MESSAGE.into(), TARGET_RELATIVE_MESSAGE.into()],
            landing_target_hz: 10.0,
            ..LinkConfig::default()
        };
        let mut o = Outgoing::new(&both, RotationMatrix::identity());
        let d = decision(DecisionState::ClearToLand);
        // Heading 030: q_sensor is the vehicle's, the body position the deck straight below.
        let vehicle = crate::frames::vehicle_from_ned_euler(0.0, 0.0, 30f32.to_radians()).unwrap();
        let m = o.decision_with_attitude(&d, LinkState::Up, None, 10, Some(&vehicle));
        assert_eq!(kinds(&m)[..3], ["target", "relative", "text"]);
        let (MavMessage::LANDING_TARGET(l), MavMessage::TARGET_RELATIVE(r)) = (&m[0], &m[1]) else {
            unreachable!()
        };
        assert_eq!(r.timestamp, l.time_usec);
        assert_eq!([r.x, r.y, r.z], [l.x, l.y, l.z]);
        assert_eq!(r.q_target, l.q);
        assert_eq!(
            r.q_sensor,
            crate::frames::ned_quaternion_of_vehicle(&vehicle.to_matrix())
        );
        assert!((r.yaw_std - 0.4f32.to_radians()).abs() < 1e-7);
        // 50 ms later: neither (10 Hz); 100 ms: both.
        assert!(!kinds(&o.decision(&d, LinkState::Up, None, 50_000_010)).contains(&"relative"));
        assert_eq!(
            kinds(&o.decision(&d, LinkState::Up, None, 100_000_010)),
            ["target", "relative"]
        );
        // Without the attitude at the exposure: q_sensor zero ("ignored").
        let m = o.decision(&d, LinkState::Up, None, 200_000_010);
        let MavMessage::TARGET_RELATIVE(r) = &m[1] else {
            unreachable!()
        };
        assert_eq!(r.q_sensor, [0.0; 4]);
        // Never on a stale decision, nor an uncompensated frame.
        let stale = stale_decision(Some(&d));
        let m = o.decision_with_attitude(&stale, LinkState::Up, None, 400_000_010, Some(&vehicle));
        assert!(!kinds(&m).contains(&"relative") && !kinds(&m).contains(&"target"));
        let mut u = d;
        u.attitude.vehicle.compensation = Compensation::Missing.into();
        let m = o.decision_with_attitude(&u, LinkState::Up, None, 600_000_010, Some(&vehicle));
        assert!(!kinds(&m).contains(&"relative"));
        assert_eq!((o.landing_targets, o.target_relatives), (3, 3));
        // TARGET_RELATIVE alone.
        let alone = LinkConfig {
            target_messages: vec![TARGET_RELATIVE_MESSAGE.into()],
            ..LinkConfig::default()
        };
        let mut o = Outgoing::new(&alone, RotationMatrix::identity());
        let m = o.decision(&d, LinkState::Up, None, 10);
        assert_eq!(kinds(&m)[..2], ["relative", "text"]);
        assert_eq!((o.landing_targets, o.target_relatives), (0, 1));
    }
}
