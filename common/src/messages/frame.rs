//! What a frame's pixels mean: its source, pixel format, ground truth, the vehicle's attitude
//! at the frame, and the frame header capture publishes.

use super::*;

/// Where frames come from (also `[source] kind` of the pipeline configuration).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FrameSource {
    #[default]
    #[serde(rename = "sim")]
    Simulator = 0,
    Replay = 1,
    Libcamera = 2,
}

wire_enum!(
    FrameSource,
    on_bad_code: Simulator,
    [Simulator => "sim", Replay => "replay", Libcamera => "libcamera"]
);

/// Layout of a frame's pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PixelFormat {
    /// 8-bit luminance, one byte a pixel, rows `stride` bytes apart.
    #[default]
    Gray8 = 0,
}

wire_enum!(PixelFormat, on_bad_code: Gray8, [Gray8]);

/// Ground truth as plain data (NaN = unknown). All attitude angles NaN with `deck_in_view`
/// true means "not known"; `deck_in_view` false means the frame shows no deck.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.Truth.v2"))]
pub struct Truth {
    /// Whether the source knows the truth at all (simulator, recordings with truth columns).
    pub known: WireBool,
    pub roll_deg: f64,
    pub pitch_deg: f64,
    pub yaw_deg: f64,
    pub altitude_m: f64,
    pub offset_x_m: f64,
    pub offset_y_m: f64,
    /// The deck centre's height in W (m, z up; 0 = its mean): the heave.
    pub deck_heave_m: f64,
}

impl Default for Truth {
    fn default() -> Self {
        Self::UNKNOWN
    }
}

impl Truth {
    pub const UNKNOWN: Self = Self {
        known: WireBool::FALSE,
        roll_deg: f64::NAN,
        pitch_deg: f64::NAN,
        yaw_deg: f64::NAN,
        altitude_m: f64::NAN,
        offset_x_m: f64::NAN,
        offset_y_m: f64::NAN,
        deck_heave_m: f64::NAN,
    };

    /// From a recording's or the simulator's truth; `known` says whether the source has truth
    /// columns (then missing angles mean "no deck in view").
    pub fn from_ground_truth(t: &GroundTruth, known: bool) -> Self {
        let f = |v: Option<f64>| v.unwrap_or(f64::NAN);
        Self {
            known: known.into(),
            roll_deg: f(t.roll_deg),
            pitch_deg: f(t.pitch_deg),
            yaw_deg: f(t.yaw_deg),
            altitude_m: f(t.alt_m),
            offset_x_m: f(t.offset_x_m),
            offset_y_m: f(t.offset_y_m),
            deck_heave_m: f(t.deck_heave_m),
        }
    }

    /// The true attitude, when known.
    pub fn attitude(&self) -> Option<Rpy> {
        let ok = self.known.get() && self.roll_deg.is_finite() && self.pitch_deg.is_finite();
        (ok && self.yaw_deg.is_finite())
            .then(|| Rpy::from_degrees(self.roll_deg, self.pitch_deg, self.yaw_deg))
    }

    /// The source knows that no deck is in view.
    pub fn no_deck(&self) -> bool {
        self.known.get() && self.attitude().is_none()
    }
}

/// The attitude of the vehicle that carried the camera when the frame was taken (`R_V`, body
/// to world; CONVENTIONS.md §5), and how it is known.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.VehicleAttitude.v4")
)]
pub struct VehicleAttitude {
    /// `Level`: none (the camera is level, as the paper assumes, or the source has no vehicle);
    /// `Frame`: the frame's own (simulator, recording columns); `Stream`: interpolated from a
    /// stream of samples (`vehicle.csv`, the autopilot); `Missing`: a stream with no sample close
    /// enough.
    pub compensation: WireCode<Compensation>,
    pub rpy: Rpy,
    /// From the frame's instant to the nearest sample used (ms): 0 for the frame's own, NaN when
    /// there is none.
    pub age_ms: f64,
    /// The vehicle's height in W (m, z up, from a fixed origin: the autopilot's local position,
    /// the simulator's deck mean), NaN when unknown. With the full pose it gives the deck's
    /// heave (`AttitudeMessage::deck_height_m`).
    pub height_m: f64,
    /// The vehicle's angular velocity in W (deg/s, `dR_V/dt = [w]x R_V`), NaN when unknown: a
    /// rolling shutter's rows see the camera turned by it (`estimate::FrameMotion`).
    pub rate_dps: [f64; 3],
    /// The rate's change (deg/s^2 in W), NaN when unknown: a hovering quadrotor's sway turns
    /// its rate around within a readout (300 deg/s^2 at 1.7 Hz is 0.02 deg over 12 ms).
    pub acceleration_dps2: [f64; 3],
}

impl Default for VehicleAttitude {
    fn default() -> Self {
        Self::LEVEL
    }
}

impl VehicleAttitude {
    pub const LEVEL: Self = Self {
        compensation: WireCode::from_code(Compensation::Level as u32),
        rpy: Rpy {
            roll: 0.0,
            pitch: 0.0,
            yaw: 0.0,
        },
        age_ms: f64::NAN,
        height_m: f64::NAN,
        rate_dps: [f64::NAN; 3],
        acceleration_dps2: [f64::NAN; 3],
    };

    pub const MISSING: Self = Self {
        compensation: WireCode::from_code(Compensation::Missing as u32),
        ..Self::LEVEL
    };

    /// The frame's own attitude when there is one, else level.
    pub fn from_rpy(rpy: Option<Rpy>) -> Self {
        match rpy {
            Some(rpy) => Self {
                compensation: Compensation::Frame.into(),
                rpy,
                age_ms: 0.0,
                height_m: f64::NAN,
                rate_dps: [f64::NAN; 3],
                acceleration_dps2: [f64::NAN; 3],
            },
            None => Self::LEVEL,
        }
    }

    /// The same with the vehicle's height in W (NaN: unknown).
    pub fn with_height(self, height_m: f64) -> Self {
        Self { height_m, ..self }
    }

    /// The same with the vehicle's angular velocity in W (deg/s; NaN: unknown).
    pub fn with_rate_dps(self, rate_dps: [f64; 3]) -> Self {
        Self { rate_dps, ..self }
    }

    /// The same with the rate's change (deg/s^2 in W; NaN: unknown).
    pub fn with_acceleration_dps2(self, acceleration_dps2: [f64; 3]) -> Self {
        Self {
            acceleration_dps2,
            ..self
        }
    }

    /// The angular velocity in W (rad/s) when known (a level camera does not turn).
    pub fn rate_rad_s(&self) -> Option<nalgebra::Vector3<f64>> {
        self.radians_if_known(&self.rate_dps)
    }

    /// The angular acceleration in W (rad/s^2) when known.
    pub fn acceleration_rad_s2(&self) -> Option<nalgebra::Vector3<f64>> {
        self.radians_if_known(&self.acceleration_dps2)
    }

    fn radians_if_known(&self, v: &[f64; 3]) -> Option<nalgebra::Vector3<f64>> {
        match self.compensation.get() {
            Compensation::Level => Some(nalgebra::Vector3::zeros()),
            _ if v.iter().all(|x| x.is_finite()) => Some(nalgebra::Vector3::from(v.map(f64::to_radians))),
            _ => None,
        }
    }

    /// Whether there is an attitude to compensate with (`Frame` or `Stream`).
    pub fn known(&self) -> bool {
        matches!(
            self.compensation.get(),
            Compensation::Frame | Compensation::Stream
        )
    }

    /// `R_V` when known, else the identity (a level camera).
    pub fn matrix(&self) -> crate::RotationMatrix {
        if self.known() {
            self.rpy.to_matrix()
        } else {
            crate::RotationMatrix::identity()
        }
    }
}

/// What a frame's pixels mean, carried from capture to decide with every message.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.FrameContext.v4"))]
pub struct FrameContext {
    pub source: WireCode<FrameSource>,
    /// Index of the frame at its source: recording frame index, camera sequence, simulator
    /// frame number (differs from `FrameStamp::seq` when replay loops or frames are skipped).
    pub source_index: u64,
    /// The frame's own timestamp at its source (recording time, sensor timestamp), ns.
    pub source_timestamp_ns: u64,
    /// Altimeter reading (m) when known, else NaN.
    pub altitude_m: f64,
    pub camera: CameraModel,
    pub deck: DeckLayout,
    pub truth: Truth,
    /// The vehicle's attitude at the frame, which the estimators compensate.
    pub vehicle: VehicleAttitude,
}

impl FrameContext {
    /// The frame's truth and vehicle attitude as a recording's columns: the inverse of what
    /// capture puts into a frame from a recording (`Truth::from_ground_truth`, the vehicle
    /// columns); NaN and an unknown vehicle become absent values.
    pub fn ground_truth(&self) -> GroundTruth {
        let f = |v: f64| v.is_finite().then_some(v);
        let t = &self.truth;
        let vehicle = self.vehicle.known().then(|| self.vehicle.rpy.to_degrees());
        GroundTruth {
            roll_deg: f(t.roll_deg),
            pitch_deg: f(t.pitch_deg),
            yaw_deg: f(t.yaw_deg),
            alt_m: f(t.altitude_m),
            offset_x_m: f(t.offset_x_m),
            offset_y_m: f(t.offset_y_m),
            vehicle_roll_deg: vehicle.map(|v| v[0]),
            vehicle_pitch_deg: vehicle.map(|v| v[1]),
            vehicle_yaw_deg: vehicle.map(|v| v[2]),
            vehicle_height_m: f(self.vehicle.height_m),
            deck_heave_m: f(t.deck_heave_m),
            vehicle_rate_x_dps: f(self.vehicle.rate_dps[0]).filter(|_| self.vehicle.known()),
            vehicle_rate_y_dps: f(self.vehicle.rate_dps[1]).filter(|_| self.vehicle.known()),
            vehicle_rate_z_dps: f(self.vehicle.rate_dps[2]).filter(|_| self.vehicle.known()),
        }
    }
}

/// The user header of a frame sample; the payload is the `[u8]` pixel buffer itself.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.FrameHeader.v4"))]
pub struct FrameHeader {
    pub stamp: FrameStamp,
    pub context: FrameContext,
    pub width: u32,
    pub height: u32,
    /// Bytes from one row to the next (>= width).
    pub stride: u32,
    pub pixel_format: WireCode<PixelFormat>,
}

impl FrameHeader {
    /// Bytes of pixel data the header describes (the payload must hold at least this many).
    pub fn required_len(&self) -> usize {
        if self.height == 0 {
            return 0;
        }
        (self.height as usize - 1) * self.stride as usize + self.width as usize
    }
}
