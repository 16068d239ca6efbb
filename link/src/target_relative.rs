//! TARGET_RELATIVE (MAVLink development dialect, id 511) beside LANDING_TARGET, for PX4's Vision
//! Target Estimator (VTE, PX4 1.18; `[link] target_messages`).
//!
//! The frame is `TARGET_OBS_FRAME_BODY_FRD`: the deck centre and the deck's orientation in the
//! vehicle's body, as LANDING_TARGET has them ([`crate::frames::body_target`]), and `q_sensor` the
//! body's attitude (FRD to vehicle-carried NED) at the frame's mid-exposure. Why this frame:
//! - PX4's VTE rotates a vision report into NED by the report's own quaternion
//!   (`VTEPosition::processObsVision`, src/modules/vision_target_estimator/Position/VTEPosition.cpp:
//!   `rel_pos` and its variances turned by `fiducial_marker_pos_report.q`). PX4's documentation
//!   (docs/en/advanced_features/vision_target_estimator.md, "MAVLink Messages") says `q_sensor`,
//!   "when provided, rotates the measurement into vehicle-carried NED", and a body-frame report
//!   is otherwise rotated with the vehicle attitude. PX4's own example, the Gazebo ArUco plugin
//!   (PX4-SITL_gazebo-classic src/gazebo_aruco_plugin.cpp), sends the marker in the body frame
//!   with the attitude "when the frame was grabbed". PX4's receiver itself (mavlink_receiver.cpp)
//!   was not read: the frames it accepts are the documentation's word.
//! - The body-frame values do not depend on W's heading: deckwatch's W is the ship's mean heading
//!   with an autopilot (CONVENTIONS.md §6), not north, so a NED position (LOCAL_OFFSET_NED) would
//!   need the heading the decision does not carry. The north-referenced attitude comes from the
//!   autopilot's own stream instead (the link's samples at the capture instant); without one,
//!   `q_sensor` is (0, 0, 0, 0), which the message defines as "ignored", and PX4 turns a body
//!   report with its own attitude (at arrival, not at the exposure).

use crate::dialect::{LandingTargetType, MavMessage, TargetObsFrame, TARGET_RELATIVE_DATA};
use crate::frames::{ned_quaternion_of_vehicle, BodyTarget};
use deckwatch_common::Quaternion;

/// The position deviations sent when the estimate states none (an estimator without a full
/// pose's covariance): 0, which PX4's VTE raises to its floor `VTE_EVP_NOISE`
/// (`processObsVision` takes the larger of the report's variance and the floor's; a NaN would
/// make it refuse the report).
pub const UNKNOWN_POSITION_STD_M: [f64; 3] = [0.0; 3];

/// What TARGET_RELATIVE says about the deck, in PX4's terms (CONVENTIONS.md §7): body FRD.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativeTarget {
    /// The deck centre from the camera, body FRD (m).
    pub position_frd_m: [f64; 3],
    /// Its standard deviations along body FRD's axes (m; see [`UNKNOWN_POSITION_STD_M`]).
    pub position_std_m: [f64; 3],
    /// The deck heading's standard deviation (rad).
    pub yaw_std_rad: f64,
    /// The deck's orientation: deck axes (bow, starboard, down) to body FRD, w x y z.
    pub q_target: [f64; 4],
    /// Body FRD to vehicle-carried NED, w x y z; all zero when the attitude at the exposure is
    /// not known.
    pub q_sensor: [f64; 4],
}

/// TARGET_RELATIVE's content for a deck seen as `body` (the conversion LANDING_TARGET uses), the
/// estimate's roll, pitch, yaw deviations `rpy_std_deg` (deg), the covariance of the deck
/// centre's position in body FRD (m^2, [`crate::frames::body_covariance`]), and the vehicle's north-referenced
/// attitude at the frame's mid-exposure (`R_V`, body FLU to NWU, from the autopilot's stream).
/// None when the heading's deviation is not known: a report without one would be fused as exact
/// (an estimator without a full pose has no position either, and sends no target at all).
pub fn relative_target(
    body: &BodyTarget,
    rpy_std_deg: [f64; 3],
    position_covariance_frd_m2: &[[f64; 3]; 3],
    vehicle_nwu: Option<&Quaternion>,
) -> Option<RelativeTarget> {
    // Heading in W and heading in NED differ in sign only: the deviation is the same.
    let yaw_std_rad = rpy_std_deg[2].to_radians();
    if !(yaw_std_rad.is_finite() && yaw_std_rad >= 0.0) {
        return None;
    }
    let q_sensor = vehicle_nwu.map_or([0.0; 4], |q| {
        ned_quaternion_of_vehicle(&q.to_matrix()).map(f64::from)
    });
    let position_std_m = [0, 1, 2].map(|k| position_covariance_frd_m2[k][k].sqrt());
    let position_std_m = if position_std_m.iter().all(|v| v.is_finite()) {
        position_std_m
    } else {
        UNKNOWN_POSITION_STD_M
    };
    Some(RelativeTarget {
        position_frd_m: body.position_frd_m,
        position_std_m,
        yaw_std_rad,
        q_target: body.orientation_frd,
        q_sensor,
    })
}

/// The message, stamped `timestamp_us`: the frame's mid-exposure on this machine's
/// `CLOCK_MONOTONIC` (us). PX4's receiver maps a sender's stamps onto its own clock with the
/// offset it learns from TIMESYNC (`sync_stamp`, as its LANDING_TARGET handler does), and the link
/// answers PX4's TIMESYNC requests with `CLOCK_MONOTONIC`: a stamp already on the autopilot's
/// clock would be moved by that offset a second time.
pub fn target_relative_message(t: &RelativeTarget, timestamp_us: u64) -> MavMessage {
    let f = |v: [f64; 4]| v.map(|x| x as f32);
    let [x, y, z] = t.position_frd_m.map(|v| v as f32);
    MavMessage::TARGET_RELATIVE(TARGET_RELATIVE_DATA {
        timestamp: timestamp_us,
        x,
        y,
        z,
        pos_std: t.position_std_m.map(|v| v as f32),
        yaw_std: t.yaw_std_rad as f32,
        q_target: f(t.q_target),
        q_sensor: f(t.q_sensor),
        // One deck.
        id: 0,
        frame: TargetObsFrame::TARGET_OBS_FRAME_BODY_FRD,
        mavtype: LandingTargetType::LANDING_TARGET_TYPE_VISION_FIDUCIAL,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::body_target;
    use deckwatch_common::rotation::{rot_x, rot_z};
    use deckwatch_common::{RotationMatrix, Rpy};
    use mavlink::Message;
    use nalgebra::{Matrix3, Vector3};

    const STD_DEG: [f64; 3] = [0.2, 0.3, 0.5];
    /// No position covariance stated (an estimator without one).
    const NO_COV: [[f64; 3]; 3] = [[f64::NAN; 3]; 3];

    fn flip() -> RotationMatrix {
        Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
    }

    /// `q` (w x y z) as a matrix.
    fn matrix(q: [f64; 4]) -> RotationMatrix {
        Quaternion::new(q[0], q[1], q[2], q[3]).to_matrix()
    }

    fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < tol)
    }

    /// Equal as rotations (`q` and `-q` are the same rotation).
    fn same_rotation(a: [f64; 4], b: [f64; 4]) -> bool {
        let dot: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        (dot.abs() - 1.0).abs() < 1e-6
    }

    /// The deck centre in vehicle-carried NED, as PX4's VTE computes it: `q_sensor` turns the
    /// body-frame position.
    fn ned_position(t: &RelativeTarget) -> [f64; 3] {
        let v = matrix(t.q_sensor) * Vector3::from(t.position_frd_m);
        [v.x, v.y, v.z]
    }

    /// `R_V` (FLU to NWU) of MAVLink's Z-Y-X Euler angles (deg; FRD to NED).
    fn vehicle_of_ned_euler_deg(roll: f64, pitch: f64, yaw: f64) -> Quaternion {
        crate::frames::vehicle_from_ned_euler(
            roll.to_radians() as f32,
            pitch.to_radians() as f32,
            yaw.to_radians() as f32,
        )
        .unwrap()
    }

    #[test]
    fn a_level_vehicle_sees_the_deck_straight_below() {
        let i = RotationMatrix::identity();
        let body = body_target([0.0, 0.0, 5.0], &i, &i, &i);
        let t = relative_target(
            &body,
            STD_DEG,
            &NO_COV,
            Some(&Quaternion::new(1.0, 0.0, 0.0, 0.0)),
        )
        .unwrap();
        assert!(close(&t.position_frd_m, &[0.0, 0.0, 5.0], 1e-12), "{t:?}");
        assert!(same_rotation(t.q_target, [1.0, 0.0, 0.0, 0.0]));
        assert!(same_rotation(t.q_sensor, [1.0, 0.0, 0.0, 0.0]));
        assert!(close(&ned_position(&t), &[0.0, 0.0, 5.0], 1e-6));
        assert!((t.yaw_std_rad - 0.5f64.to_radians()).abs() < 1e-15);
        assert_eq!(t.position_std_m, [0.0; 3]);
        // No attitude at the exposure: q_sensor is the message's "ignored".
        let t = relative_target(&body, STD_DEG, &NO_COV, None).unwrap();
        assert_eq!(t.q_sensor, [0.0; 4]);
        // No heading deviation: no message.
        assert!(relative_target(&body, [0.2, 0.3, f64::NAN], &NO_COV, None).is_none());
    }

    /// Worked by hand: the vehicle heads 030 (NED yaw +30 deg), level; the deck centre is 2 m
    /// north of it and 5 m below, the deck heading 090 (east). In the body the deck is 2 cos 30
    /// ahead and 2 sin 30 to the left; its heading is 60 deg right of the nose. W turned by the
    /// ship's mean heading (CONVENTIONS.md §6) changes none of it.
    #[test]
    fn a_known_heading_and_offset() {
        let vehicle = vehicle_of_ned_euler_deg(0.0, 0.0, 30.0);
        // NWU (x north, y west): the camera is 2 m south of the deck centre, 5 m above; the
        // deck's heading 090 is NWU yaw -90.
        let deck_nwu = rot_z(-90f64.to_radians());
        for mean_heading_deg in [0.0, 57.0] {
            let to_w = rot_z(-f64::to_radians(mean_heading_deg));
            let camera_w = to_w * Vector3::new(-2.0, 0.0, 5.0);
            let body = body_target(
                [camera_w.x, camera_w.y, camera_w.z],
                &(to_w * deck_nwu),
                &(to_w * vehicle.to_matrix()),
                &RotationMatrix::identity(),
            );
            let t = relative_target(&body, STD_DEG, &NO_COV, Some(&vehicle)).unwrap();
            let (s30, c30) = 30f64.to_radians().sin_cos();
            assert!(
                close(&t.position_frd_m, &[2.0 * c30, -2.0 * s30, 5.0], 1e-6),
                "{mean_heading_deg}: {t:?}"
            );
            let (s15, c15) = 15f64.to_radians().sin_cos();
            assert!(same_rotation(t.q_sensor, [c15, 0.0, 0.0, s15]), "{t:?}");
            let (s30h, c30h) = 30f64.to_radians().sin_cos();
            assert!(same_rotation(t.q_target, [c30h, 0.0, 0.0, s30h]), "{t:?}");
            // PX4's VTE: the deck 2 m north, 5 m down; its heading 090.
            assert!(close(&ned_position(&t), &[2.0, 0.0, 5.0], 1e-6), "{t:?}");
            let deck_ned = matrix(t.q_sensor) * matrix(t.q_target);
            let heading_deg = deck_ned[(1, 0)].atan2(deck_ned[(0, 0)]).to_degrees();
            assert!((heading_deg - 90.0).abs() < 1e-5, "{heading_deg}");
        }
    }

    /// Worked by hand: right wing down 10 deg (NED roll +10), heading north, a level deck
    /// straight below at 5 m: in the body the deck lies 5 sin 10 to the right and 5 cos 10 down,
    /// turned -10 deg about x; q_sensor turns both back to north-east-down.
    #[test]
    fn a_rolled_vehicle() {
        let vehicle = vehicle_of_ned_euler_deg(10.0, 0.0, 0.0);
        // Roll keeps its sign between FRD/NED and FLU/NWU (CONVENTIONS.md §7).
        assert!((vehicle.to_rpy().to_degrees()[0] - 10.0).abs() < 1e-5);
        let i = RotationMatrix::identity();
        let body = body_target([0.0, 0.0, 5.0], &i, &vehicle.to_matrix(), &i);
        let t = relative_target(&body, STD_DEG, &NO_COV, Some(&vehicle)).unwrap();
        let (s10, c10) = 10f64.to_radians().sin_cos();
        assert!(
            close(&t.position_frd_m, &[0.0, 5.0 * s10, 5.0 * c10], 1e-6),
            "{t:?}"
        );
        let (s5, c5) = 5f64.to_radians().sin_cos();
        assert!(same_rotation(t.q_sensor, [c5, s5, 0.0, 0.0]), "{t:?}");
        assert!(same_rotation(t.q_target, [c5, -s5, 0.0, 0.0]), "{t:?}");
        assert!(close(&ned_position(&t), &[0.0, 0.0, 5.0], 1e-6));
        let deck_ned = matrix(t.q_sensor) * matrix(t.q_target);
        assert!((deck_ned - i).norm() < 1e-6, "{deck_ned}");
        // A rolled deck under a rolled vehicle: the deck's own roll comes back in NED.
        let deck = Rpy::from_degrees(3.0, 0.0, 0.0).to_matrix();
        let body = body_target([0.0, 0.0, 5.0], &deck, &vehicle.to_matrix(), &i);
        let t = relative_target(&body, STD_DEG, &NO_COV, Some(&vehicle)).unwrap();
        let deck_ned = matrix(t.q_sensor) * matrix(t.q_target);
        assert!((deck_ned - flip() * deck * flip()).norm() < 1e-6);
        assert!((deck_ned - rot_x(3f64.to_radians())).norm() < 1e-6);
    }

    /// Worked by hand: a position known to 3 cm north-south, 1 cm east-west and 5 cm in height
    /// in W, a vehicle heading 090 (east; NWU yaw -90): in the body the 3 cm lies across
    /// (y), the 1 cm along (x), the height down (z).
    #[test]
    fn the_position_covariance_is_turned_into_the_body() {
        let vehicle = vehicle_of_ned_euler_deg(0.0, 0.0, 90.0);
        let cov_w = [
            [0.03f64.powi(2), 0.0, 0.0],
            [0.0, 0.01f64.powi(2), 0.0],
            [0.0, 0.0, 0.05f64.powi(2)],
        ];
        let cov_frd = crate::frames::body_covariance(&cov_w, &vehicle.to_matrix());
        let i = RotationMatrix::identity();
        let body = body_target([0.0, 0.0, 5.0], &i, &vehicle.to_matrix(), &i);
        let t = relative_target(&body, STD_DEG, &cov_frd, Some(&vehicle)).unwrap();
        assert!(close(&t.position_std_m, &[0.01, 0.03, 0.05], 1e-9), "{t:?}");
    }

    /// The message carries the conversion as MAVLink's development dialect defines it, and reads
    /// back as sent through the mavlink crate's MAVLink 2 framing.
    #[test]
    fn the_message_round_trips() {
        let vehicle = vehicle_of_ned_euler_deg(4.0, -3.0, 120.0);
        let body = body_target(
            [0.3, -0.2, 6.0],
            &Rpy::from_degrees(1.0, 2.0, 3.0).to_matrix(),
            &vehicle.to_matrix(),
            &RotationMatrix::identity(),
        );
        let t = relative_target(&body, STD_DEG, &NO_COV, Some(&vehicle)).unwrap();
        let m = target_relative_message(&t, 1_234_567_890);
        let header = mavlink::MavHeader {
            system_id: 1,
            component_id: 191,
            sequence: 7,
        };
        let mut raw = mavlink::MAVLinkV2MessageRaw::new();
        raw.serialize_message(header, &m);
        assert_eq!(raw.message_id(), 511);
        let back = MavMessage::parse(mavlink::MavlinkVersion::V2, raw.message_id(), raw.payload()).unwrap();
        let MavMessage::TARGET_RELATIVE(r) = back else {
            panic!("{back:?}")
        };
        assert_eq!(r.timestamp, 1_234_567_890);
        assert_eq!(r.frame, TargetObsFrame::TARGET_OBS_FRAME_BODY_FRD);
        assert_eq!(r.mavtype, LandingTargetType::LANDING_TARGET_TYPE_VISION_FIDUCIAL);
        assert_eq!([r.x, r.y, r.z], t.position_frd_m.map(|v| v as f32));
        assert_eq!(r.q_sensor, t.q_sensor.map(|v| v as f32));
        assert_eq!(r.q_target, t.q_target.map(|v| v as f32));
        assert_eq!(r.yaw_std, t.yaw_std_rad as f32);
        assert_eq!(r.pos_std, [0.0; 3]);
    }
}
