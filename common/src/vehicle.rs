//! The vehicle that carries the camera (CONVENTIONS.md §5): where its attitude comes from, how the
//! camera is mounted on it, and one sample of its attitude stream. (How a stream of samples
//! becomes the attitude at one frame's mid-exposure is estimation: `estimate::vehicle_track`.)
//!
//! `R_V` is body to world (body x forward, y left, z up); the camera looks along the mount
//! `R_M` (body to "level-mounted camera", identity: straight down with image up = forward), so
//! the estimators and the simulator use `R_V · R_M` wherever a level camera had the identity.

use crate::error::InvalidField;
use crate::rotation::{Quaternion, RotationMatrix, Rpy};

/// Where the estimate stage takes the vehicle's attitude from (`[vehicle] attitude`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum VehicleAttitudeSource {
    /// From each frame: the simulator's vehicle, a recording's vehicle columns or `vehicle.csv`
    /// (none: a level camera, as a recording without them means).
    #[default]
    Frames,
    /// From the autopilot's attitude stream (the `link` process), interpolated to each frame's
    /// mid-exposure; a frame with no sample close enough is not compensated and never cleared.
    Autopilot,
    /// None: the camera is level by construction (a gimbal).
    Level,
}

crate::named_enum!(
    VehicleAttitudeSource,
    [Frames => "frames", Autopilot => "autopilot", Level => "level"]
);

/// `[vehicle]` of the pipeline configuration.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleConfig {
    pub attitude: VehicleAttitudeSource,
    /// The farthest a frame's mid-exposure may be from the attitude sample(s) it is compensated
    /// with (ms); the autopilot streams at 50-200 Hz, so a few periods.
    pub max_gap_ms: f64,
    /// The camera mount relative to the default (straight down, image up = body forward), as
    /// roll, pitch, yaw in degrees (`R_M = Rx Ry Rz`).
    pub mount_rpy_deg: [f64; 3],
    /// Autopilot attitude only (north-referenced heading): the time constant (s) of the ship's
    /// mean heading, which becomes W's x (CONVENTIONS.md §6).
    pub heading_time_constant_s: f64,
    /// Autopilot attitude only: the time constant (s) over which the vehicle's height follows
    /// the autopilot's integrated vertical speed rather than its reported height (LOCAL_POSITION_NED
    /// `vz` and `z`); 0 takes the reported heights as they are.
    pub height_fusion_s: f64,
}

/// `[vehicle] height_fusion_s` by default (s): one second averages a 50 Hz height's white noise
/// over about 100 samples (a tenth of its standard deviation is left) and is short beside the
/// heave's periods (5-15 s) and an estimator's drift (tens of seconds), which pass through as
/// the height reports them.
pub const HEIGHT_FUSION_TIME_CONSTANT_S: f64 = 1.0;

impl Default for VehicleConfig {
    fn default() -> Self {
        Self {
            attitude: VehicleAttitudeSource::Frames,
            max_gap_ms: 30.0,
            mount_rpy_deg: [0.0; 3],
            heading_time_constant_s: 30.0,
            height_fusion_s: HEIGHT_FUSION_TIME_CONSTANT_S,
        }
    }
}

/// The farthest a frame may be from the attitude samples it is compensated with (ms): five
/// periods of a 50 Hz autopilot stream. A quadrotor changes its attitude by degrees within a
/// tenth of a second; interpolated across a longer hole, the compensation is a guess.
pub const MAX_VEHICLE_GAP_MS: f64 = 100.0;

impl VehicleConfig {
    pub fn validate(&self) -> Result<(), InvalidField> {
        if !(self.max_gap_ms > 0.0 && self.max_gap_ms <= MAX_VEHICLE_GAP_MS) {
            return Err(InvalidField::new(
                "max_gap_ms",
                format!(
                    "must be in (0, {MAX_VEHICLE_GAP_MS}] (a quadrotor's attitude is not a straight line over longer), got {}",
                    self.max_gap_ms
                ),
            ));
        }
        if !self
            .mount_rpy_deg
            .iter()
            .all(|a| a.is_finite() && a.abs() <= 90.0)
        {
            return Err(InvalidField::new(
                "mount_rpy_deg",
                format!("each angle must be within +-90 deg, got {:?}", self.mount_rpy_deg),
            ));
        }
        if !(self.heading_time_constant_s > 0.0 && self.heading_time_constant_s.is_finite()) {
            return Err(InvalidField::new(
                "heading_time_constant_s",
                format!("must be positive, got {}", self.heading_time_constant_s),
            ));
        }
        if !(self.height_fusion_s >= 0.0 && self.height_fusion_s <= 60.0) {
            return Err(InvalidField::new(
                "height_fusion_s",
                format!(
                    "must be in [0, 60] (0: the autopilot's heights as they are), got {}",
                    self.height_fusion_s
                ),
            ));
        }
        Ok(())
    }

    /// The mount `R_M`.
    pub fn mount(&self) -> RotationMatrix {
        let [r, p, y] = self.mount_rpy_deg;
        Rpy::from_degrees(r, p, y).to_matrix()
    }

    /// What the estimators and the renderer use in place of a level camera's identity:
    /// `R_V · R_M`.
    pub fn camera_attitude(&self, vehicle: &RotationMatrix) -> RotationMatrix {
        vehicle * self.mount()
    }

    pub fn max_gap_ns(&self) -> u64 {
        (self.max_gap_ms * 1e6) as u64
    }
}

/// How a frame's attitude was compensated for the vehicle's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compensation {
    /// None needed: the camera is level (a gimbal, or a recording without a vehicle).
    #[default]
    Level = 0,
    /// With the vehicle attitude the frame carries (simulator, recording).
    Frame = 1,
    /// With the autopilot's attitude stream, interpolated to mid-exposure.
    Stream = 2,
    /// Needed but not possible (no attitude sample close enough): the deck attitude is relative
    /// to the camera only, and decide never clears on it.
    Missing = 3,
}

crate::wire_enum!(
    Compensation,
    on_bad_code: Missing,
    [Level => "level", Frame => "frame", Stream => "stream", Missing => "missing"]
);

/// One sample of the vehicle's state on one clock: its attitude `R_V` and, when known, its
/// height in W (a row of `vehicle.csv`; what the autopilot streams).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleStateSample {
    pub time_ns: u64,
    pub quaternion: Quaternion,
    /// m, z up, from a fixed origin (the autopilot's local frame).
    pub height_m: Option<f64>,
    /// The height's rate (m/s, up) by the autopilot's estimator, when it gives one: the
    /// estimate pipeline fuses it with the height (`HeightFusion`).
    pub vertical_speed_mps: Option<f64>,
}

impl VehicleStateSample {
    /// An attitude without a height.
    pub fn attitude(time_ns: u64, quaternion: Quaternion) -> Self {
        Self {
            time_ns,
            quaternion,
            height_m: None,
            vertical_speed_mps: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::rotation_angle_between;

    fn q(roll_deg: f64, pitch_deg: f64, yaw_deg: f64) -> Quaternion {
        Quaternion::from_matrix(&Rpy::from_degrees(roll_deg, pitch_deg, yaw_deg).to_matrix())
    }

    #[test]
    fn slerp_is_uniform_along_the_arc() {
        let (a, b) = (q(0.0, 0.0, 0.0), q(0.0, 0.0, 90.0));
        let m = a.slerp(&b, 0.25).to_rpy().to_degrees();
        assert!((m[2] - 22.5).abs() < 1e-9 && m[0].abs() < 1e-12, "{m:?}");
        // The shorter arc even when the quaternions are on opposite hemispheres.
        let minus_b = Quaternion::new(-b.w, -b.x, -b.y, -b.z);
        let m2 = a.slerp(&minus_b, 0.25).to_rpy().to_degrees();
        assert!((m2[2] - 22.5).abs() < 1e-9, "{m2:?}");
        // Ends are the ends.
        let e = rotation_angle_between(&a.slerp(&b, 1.0).to_matrix(), &b.to_matrix());
        assert!(e < 1e-12);
    }

    #[test]
    fn config_checks_and_mount() {
        let c = VehicleConfig::default();
        c.validate().unwrap();
        assert_eq!(
            c.camera_attitude(&RotationMatrix::identity()),
            RotationMatrix::identity()
        );
        for gap_ms in [0.0, MAX_VEHICLE_GAP_MS + 1.0, f64::NAN] {
            let bad = VehicleConfig {
                max_gap_ms: gap_ms,
                ..VehicleConfig::default()
            };
            assert_eq!(bad.validate().unwrap_err().field, "max_gap_ms");
        }
        let bad = VehicleConfig {
            mount_rpy_deg: [0.0, f64::NAN, 0.0],
            ..VehicleConfig::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "mount_rpy_deg");
    }
}
