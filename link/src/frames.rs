//! MAVLink's frames against deckwatch's (CONVENTIONS.md §7), defined once.
//!
//! MAVLink: body FRD (x forward, y right, z down) to NED (north, east, down). deckwatch: body FLU
//! (x forward, y left, z up) to a world with z up; with an autopilot that world is
//! north-west-up (NWU). Both changes of axes are `F = diag(1, -1, -1)`, a half turn about x, so
//! `R_V = F · R_ned · F`: roll keeps its sign, pitch and yaw change theirs (in the quaternion:
//! `(w, x, -y, -z)`).

use deckwatch_common::rotation::{rot_x, rot_y, rot_z};
use deckwatch_common::scene::camera_from_world;
use deckwatch_common::{Quaternion, RotationMatrix};
use nalgebra::{Matrix3, Vector3};

fn flip() -> RotationMatrix {
    Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
}

/// `R_V` (FLU to NWU) of an ATTITUDE_QUATERNION's `q` (w, x, y, z; FRD to NED); None when it is
/// not a rotation.
pub fn vehicle_from_ned_quaternion(q: [f32; 4]) -> Option<Quaternion> {
    let [w, x, y, z] = q.map(f64::from);
    let q = Quaternion::new(w, x, -y, -z);
    ((q.norm() - 1.0).abs() < 1e-3).then(|| q.normalized()).flatten()
}

/// `R_V` (FLU to NWU) of an ATTITUDE's Euler angles (rad; MAVLink's Z-Y-X: `Rz(yaw) Ry(pitch)
/// Rx(roll)`, FRD to NED); None when one is not finite.
pub fn vehicle_from_ned_euler(roll: f32, pitch: f32, yaw: f32) -> Option<Quaternion> {
    let [r, p, y] = [roll, pitch, yaw].map(f64::from);
    if !(r.is_finite() && p.is_finite() && y.is_finite()) {
        return None;
    }
    let ned = rot_z(y) * rot_y(p) * rot_x(r);
    Some(Quaternion::from_matrix(&(flip() * ned * flip())))
}

/// The inverse of [`vehicle_from_ned_quaternion`]: MAVLink's `q` (FRD to NED) of `R_V`.
pub fn ned_quaternion_of_vehicle(r_v: &RotationMatrix) -> [f32; 4] {
    let q = Quaternion::from_matrix(&(flip() * r_v * flip()));
    [q.w, q.x, q.y, q.z].map(|v| v as f32)
}

/// What LANDING_TARGET says about the deck, in the vehicle's body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyTarget {
    /// The deck centre from the camera, body FRD (m).
    pub position_frd_m: [f64; 3],
    /// The deck's orientation in body FRD (deck axes bow, starboard, down), w x y z.
    pub orientation_frd: [f64; 4],
    /// The deck centre's angular offset from the image centre along image x (right) and y
    /// (down), rad: `atan(x/z)`, `atan(y/z)` in the camera frame.
    pub angle_rad: [f64; 2],
    pub distance_m: f64,
}

/// The deck centre and attitude relative to the body, from the camera's position over the deck
/// centre in W (`camera_w_m`), the deck's attitude `r_d` and the vehicle's `r_v` in the same W,
/// and the camera mount `r_m`. The camera is taken to sit at the body origin (its lever arm is
/// centimetres; the autopilot adds its own offset, e.g. ArduPilot's `PLND_CAM_POS_*`).
pub fn body_target(
    camera_w_m: [f64; 3],
    r_d: &RotationMatrix,
    r_v: &RotationMatrix,
    r_m: &RotationMatrix,
) -> BodyTarget {
    let to_deck_w = -Vector3::from(camera_w_m);
    let flu = r_v.transpose() * to_deck_w;
    let camera = camera_from_world() * (r_v * r_m).transpose() * to_deck_w;
    let d = flip() * r_v.transpose() * r_d * flip();
    let q = Quaternion::from_matrix(&d);
    BodyTarget {
        position_frd_m: [flu.x, -flu.y, -flu.z],
        orientation_frd: [q.w, q.x, q.y, q.z],
        angle_rad: [camera.x.atan2(camera.z), camera.y.atan2(camera.z)],
        distance_m: to_deck_w.norm(),
    }
}

/// A covariance in W (m^2; the camera's position over the deck centre, or the deck centre's from
/// the camera: the same) as body FRD has it: `F R_V^T Σ R_V F`.
pub fn body_covariance(covariance_w_m2: &[[f64; 3]; 3], r_v: &RotationMatrix) -> [[f64; 3]; 3] {
    let w = Matrix3::from_fn(|i, j| covariance_w_m2[i][j]);
    let to_frd = flip() * r_v.transpose();
    let b = to_frd * w * to_frd.transpose();
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| b[(i, j)]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::rotation::rotation_angle_between;
    use deckwatch_common::Rpy;

    #[test]
    fn ned_and_deckwatch_agree_on_the_physical_motion() {
        // 10 deg right wing down in NED: the body's y (right) axis points down a little.
        let q = vehicle_from_ned_euler(10f32.to_radians(), 0.0, 0.0).unwrap();
        let r = q.to_matrix();
        // deckwatch: body y is left; right wing down = left wing up: left axis has +z in NWU.
        assert!(r[(2, 1)] > 0.17 && r[(2, 1)] < 0.18, "{r}");
        // Nose up 5 deg (MAVLink pitch +5): body x gets +z in NWU.
        let r = vehicle_from_ned_euler(0.0, 5f32.to_radians(), 0.0)
            .unwrap()
            .to_matrix();
        assert!(r[(2, 0)] > 0.08, "{r}");
        // Heading 90 deg (east) in NED: body x points east = -y in NWU.
        let r = vehicle_from_ned_euler(0.0, 0.0, 90f32.to_radians())
            .unwrap()
            .to_matrix();
        assert!((r[(1, 0)] + 1.0).abs() < 1e-6, "{r}");
        // The quaternion and Euler forms agree, and the inverse returns the quaternion.
        let e = (0.1f32, -0.2f32, 2.5f32);
        let from_euler = vehicle_from_ned_euler(e.0, e.1, e.2).unwrap().to_matrix();
        let ned = rot_z(e.2 as f64) * rot_y(e.1 as f64) * rot_x(e.0 as f64);
        let qn = Quaternion::from_matrix(&ned);
        let q = vehicle_from_ned_quaternion([qn.w, qn.x, qn.y, qn.z].map(|v| v as f32)).unwrap();
        assert!(rotation_angle_between(&q.to_matrix(), &from_euler) < 1e-6);
        let back = ned_quaternion_of_vehicle(&from_euler);
        let again = vehicle_from_ned_quaternion(back).unwrap();
        assert!(rotation_angle_between(&again.to_matrix(), &from_euler) < 1e-6);
        assert!(vehicle_from_ned_quaternion([0.0; 4]).is_none());
        assert!(vehicle_from_ned_euler(f32::NAN, 0.0, 0.0).is_none());
    }

    #[test]
    fn level_vehicle_over_the_deck_sees_it_straight_below() {
        let i = RotationMatrix::identity();
        let t = body_target([0.0, 0.0, 5.0], &i, &i, &i);
        assert!((t.position_frd_m[2] - 5.0).abs() < 1e-12 && t.position_frd_m[0].abs() < 1e-12);
        assert!(t.angle_rad.iter().all(|a| a.abs() < 1e-12));
        assert!((t.orientation_frd[0] - 1.0).abs() < 1e-12);
        // Camera 1 m aft of the deck centre (x = -1 in W, bow = x): the deck is 1 m ahead,
        // which is image up (negative image y).
        let t = body_target([-1.0, 0.0, 5.0], &i, &i, &i);
        assert!((t.position_frd_m[0] - 1.0).abs() < 1e-12);
        assert!(t.angle_rad[1] < -0.19, "{:?}", t.angle_rad);
        // A vehicle rolled right (FLU roll -> left up) sees a level deck rolled the other way.
        let r_v = Rpy::from_degrees(-5.0, 0.0, 0.0).to_matrix();
        let t = body_target([0.0, 0.0, 5.0], &i, &r_v, &i);
        let d = Quaternion::new(
            t.orientation_frd[0],
            t.orientation_frd[1],
            t.orientation_frd[2],
            t.orientation_frd[3],
        );
        let angle = rotation_angle_between(&d.to_matrix(), &i).to_degrees();
        assert!((angle - 5.0).abs() < 1e-9, "{angle}");
    }
}
