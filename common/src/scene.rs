//! Where the camera is and how the deck is turned: the geometry that links the deck to pixels.
//!
//! World frame W: origin at the deck centre, x = bow of the level deck, y = port, z = up.
//! The camera's optical centre is at `C = (offset_x, offset_y, altitude)` in W. It is fixed to
//! the vehicle, whose attitude is `R_V` (body to world; body x forward, y left, z up;
//! `R_V = Rx(roll) Ry(pitch) Rz(yaw)`, the deck's X-Y-Z order), looking straight down with image
//! up = body forward: `p_cam = R_CW0 R_V^T (P_world - C)` with
//! `R_CW0 = [[0,-1,0],[-1,0,0],[0,0,-1]]` ([`camera_from_world`]). `R_V = I` is the paper's level
//! camera (image up = bow, image left = port). CONVENTIONS.md §5.

use crate::camera::CameraModel;
use crate::deck::DeckLayout;
use crate::rotation::RotationMatrix;
use nalgebra::{Matrix3, Vector3};

/// Rotation from world to camera coordinates of the level, downward camera (`R_CW0`; with a
/// level vehicle, body = world).
pub fn camera_from_world() -> Matrix3<f64> {
    Matrix3::new(0.0, -1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0)
}

/// The camera's optical centre in the world frame: the quadrotor's position over the deck.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Viewpoint {
    /// Horizontal offset from the deck centre along world x (bow), metres.
    pub offset_x_m: f64,
    /// Horizontal offset from the deck centre along world y (port), metres.
    pub offset_y_m: f64,
    /// Height of the optical centre above the deck centre, metres.
    pub altitude_m: f64,
    /// The vehicle's attitude `R_V` (body to world) that carries the camera; identity: level.
    pub vehicle_attitude: RotationMatrix,
}

impl Viewpoint {
    /// Straight above the deck centre, level.
    pub fn centred(altitude_m: f64) -> Self {
        Self::level(0.0, 0.0, altitude_m)
    }

    /// At an offset and altitude, level (the paper's camera).
    pub fn level(offset_x_m: f64, offset_y_m: f64, altitude_m: f64) -> Self {
        Self {
            offset_x_m,
            offset_y_m,
            altitude_m,
            vehicle_attitude: RotationMatrix::identity(),
        }
    }

    /// The same position with the vehicle at attitude `r_v` (body to world).
    pub fn with_vehicle_attitude(self, r_v: RotationMatrix) -> Self {
        Self {
            vehicle_attitude: r_v,
            ..self
        }
    }

    /// `R_CW = R_CW0 R_V^T`: world to camera coordinates of this viewpoint's camera.
    pub fn camera_from_world(&self) -> Matrix3<f64> {
        camera_from_world() * self.vehicle_attitude.transpose()
    }

    pub fn position(&self) -> Vector3<f64> {
        Vector3::new(self.offset_x_m, self.offset_y_m, self.altitude_m)
    }

    /// Camera coordinates of a world point.
    pub fn world_to_camera(&self, p_world: &Vector3<f64>) -> Vector3<f64> {
        self.camera_from_world() * (p_world - self.position())
    }

    /// World coordinates of a camera-frame point.
    pub fn camera_to_world(&self, p_cam: &Vector3<f64>) -> Vector3<f64> {
        self.camera_from_world().transpose() * p_cam + self.position()
    }
}

/// A deck attitude seen from a viewpoint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneGeometry {
    /// `P_world = attitude * P_deck`.
    pub attitude: RotationMatrix,
    pub viewpoint: Viewpoint,
}

impl SceneGeometry {
    /// Camera coordinates of a point given in the deck frame.
    pub fn deck_to_camera(&self, p_deck: &Vector3<f64>) -> Vector3<f64> {
        self.viewpoint.world_to_camera(&(self.attitude * p_deck))
    }

    /// Exact pixel of a deck point (None behind the camera).
    pub fn project_deck_point(&self, camera: &CameraModel, p_deck: &Vector3<f64>) -> Option<[f64; 2]> {
        camera.project(&self.deck_to_camera(p_deck))
    }

    /// Exact pixels of every marker centre, in marker-index order; None for a marker behind the
    /// camera or off the sensor.
    pub fn project_markers(&self, camera: &CameraModel, deck: &DeckLayout) -> Vec<Option<[f64; 2]>> {
        (0..deck.marker_count())
            .map(|i| {
                self.project_deck_point(camera, &deck.marker_position(i))
                    .filter(|&uv| camera.contains(uv))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::Rpy;

    #[test]
    fn image_axes_follow_the_convention() {
        let cam = CameraModel::paper();
        let scene = SceneGeometry {
            attitude: RotationMatrix::identity(),
            viewpoint: Viewpoint::centred(5.0),
        };
        let deck = DeckLayout::paper();
        let px = scene.project_markers(&cam, &deck);
        let c = px[0].unwrap();
        assert_eq!(c, [cam.cx, cam.cy]);
        // Bow (+x) images up (smaller v), port (+y, marker 3) images left (smaller u).
        let bow = px[1].unwrap();
        assert!(bow[1] < c[1] && (bow[0] - c[0]).abs() < 1e-9);
        let port = px[3].unwrap();
        assert!(port[0] < c[0] && (port[1] - c[1]).abs() < 1e-9);
        // Distance: fy * 0.5 / 5 pixels.
        assert!((c[1] - bow[1] - cam.fy * 0.1).abs() < 1e-9);
    }

    #[test]
    fn world_camera_round_trip_and_depth() {
        let v = Viewpoint::level(0.3, -0.1, 4.5);
        let p = Vector3::new(0.2, 0.4, 0.1);
        let c = v.world_to_camera(&p);
        assert!((c.z - (4.5 - 0.1)).abs() < 1e-15, "depth is h - Pz");
        assert!((v.camera_to_world(&c) - p).norm() < 1e-15);
    }

    #[test]
    fn a_tilted_vehicle_moves_the_image_the_other_way() {
        let cam = CameraModel::rpi_v2();
        let deck = DeckLayout::paper();
        let level = SceneGeometry {
            attitude: RotationMatrix::identity(),
            viewpoint: Viewpoint::centred(5.0),
        };
        // The vehicle rolls 5 deg (port side up): its belly, and the camera, turn to port (+y),
        // so the deck centre below images toward starboard = image right (larger u).
        let tilted = SceneGeometry {
            viewpoint: level
                .viewpoint
                .with_vehicle_attitude(Rpy::from_degrees(5.0, 0.0, 0.0).to_matrix()),
            ..level
        };
        let c0 = level.project_markers(&cam, &deck)[0].unwrap();
        let c1 = tilted.project_markers(&cam, &deck)[0].unwrap();
        let expected = cam.fx * 5f64.to_radians().tan();
        assert!((c1[0] - c0[0] - expected).abs() < 1e-9, "{c0:?} {c1:?}");
        assert!((c0[1] - c1[1]).abs() < 1e-9);
        // Pitched nose down 5 deg: the camera looks backward (-x), the deck images toward the
        // bow = image up (smaller v).
        let nose_down = SceneGeometry {
            viewpoint: level
                .viewpoint
                .with_vehicle_attitude(Rpy::from_degrees(0.0, 5.0, 0.0).to_matrix()),
            ..level
        };
        let c2 = nose_down.project_markers(&cam, &deck)[0].unwrap();
        assert!(
            (c0[1] - c2[1] - cam.fy * 5f64.to_radians().tan()).abs() < 1e-9,
            "{c2:?}"
        );
        // A world point goes to the camera and back.
        let v = tilted.viewpoint;
        let p = Vector3::new(0.2, -0.4, 0.1);
        assert!((v.camera_to_world(&v.world_to_camera(&p)) - p).norm() < 1e-14);
    }

    #[test]
    fn raised_port_side_images_larger() {
        // Positive roll raises the port side: closer to the camera, so farther from the centre.
        let cam = CameraModel::rpi_v2();
        let deck = DeckLayout::paper();
        let scene = SceneGeometry {
            attitude: Rpy::from_degrees(20.0, 0.0, 0.0).to_matrix(),
            viewpoint: Viewpoint::centred(5.0),
        };
        let px = scene.project_markers(&cam, &deck);
        let c = px[0].unwrap();
        let port = (px[3].unwrap()[0] - c[0]).abs();
        let starboard = (px[7].unwrap()[0] - c[0]).abs();
        assert!(port > starboard);
    }
}
