//! The pipeline's messages: what capture, detect, estimate and decide exchange over iceoryx2
//! shared memory. All are `#[repr(C)]` plain data (no pointers), so they are valid in every
//! process that maps them; each type has a versioned iceoryx2 type name, so a stage built from an
//! incompatible revision fails to connect instead of misreading bytes.
//!
//! Every message starts with a [`FrameStamp`]: the frame's sequence number, when it was captured,
//! and when each stage received and finished it (one monotonic clock for all processes), so any
//! consumer downstream can compute per-stage latency. A [`FrameContext`] travels with it: the
//! camera and deck the pixels refer to, the altimeter reading and, for simulated or recorded
//! frames, the ground truth.

use crate::camera::CameraModel;
use crate::deck::DeckLayout;
use crate::ellipse::Ellipse;
use crate::markers::MarkerSet;
use crate::recording::GroundTruth;
use crate::rotation::{Euler313, Quaternion, Rpy};
use crate::vehicle::Compensation;
use crate::wire::{BadWireValue, WireBool, WireCheck, WireCode};
use crate::wire_enum;
#[cfg(feature = "shm")]
use iceoryx2::prelude::ZeroCopySend;

/// Nanoseconds of `CLOCK_MONOTONIC`: one clock for every process on the machine (unlike
/// `Instant`, its values can be compared across processes), never set back.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec we pass; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The offset from the pipeline's `CLOCK_MONOTONIC` to UNIX time, measured once (per flight
/// recording, per rerun logging thread): what turns the messages' times into wall-clock times.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TimeBase {
    pub unix_minus_monotonic_ns: i64,
}

impl TimeBase {
    /// Now: the system clock less the monotonic one.
    pub fn measure() -> Self {
        let unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as i64);
        Self {
            unix_minus_monotonic_ns: unix.saturating_sub(monotonic_ns() as i64),
        }
    }

    /// No offset: times are already what the file should show (a converted recording's).
    pub const IDENTITY: Self = Self {
        unix_minus_monotonic_ns: 0,
    };

    pub fn to_unix_ns(&self, monotonic_ns: u64) -> u64 {
        (monotonic_ns as i64)
            .saturating_add(self.unix_minus_monotonic_ns)
            .max(0) as u64
    }
}

/// When a frame passed each stage: `CLOCK_MONOTONIC` nanoseconds, 0 = not (yet) passed.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.StageTimes.v1"))]
pub struct StageTimes {
    /// The frame was captured: exposure (camera), start of rendering (simulator), start of
    /// reading (replay).
    pub captured_ns: u64,
    /// The frame was in shared memory and sent to detect.
    pub published_ns: u64,
    pub detect_received_ns: u64,
    pub detect_finished_ns: u64,
    pub estimate_received_ns: u64,
    pub estimate_finished_ns: u64,
    pub decide_received_ns: u64,
    pub decide_finished_ns: u64,
}

/// The latency intervals deckwatch reports, in pipeline order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LatencyInterval {
    /// Capturing the frame into shared memory (render, decode or copy).
    Capture,
    /// From publication to detect's receipt: the frame hop through shared memory.
    CaptureToDetect,
    Detect,
    /// Hop and processing: detect finished -> estimate finished.
    Estimate,
    /// Hop and processing: estimate finished -> decide finished.
    Decide,
    /// Frame published -> decision made: what the pipeline adds after the frame exists.
    EndToEnd,
}

impl LatencyInterval {
    pub const ALL: [LatencyInterval; 6] = [
        Self::Capture,
        Self::CaptureToDetect,
        Self::Detect,
        Self::Estimate,
        Self::Decide,
        Self::EndToEnd,
    ];

    pub fn name(&self) -> &'static str {
        match self {
            Self::Capture => "capture",
            Self::CaptureToDetect => "capture->detect",
            Self::Detect => "detect",
            Self::Estimate => "estimate",
            Self::Decide => "decide",
            Self::EndToEnd => "end-to-end",
        }
    }
}

impl StageTimes {
    /// The interval in nanoseconds, when both of its ends are stamped and in order.
    pub fn interval_ns(&self, which: LatencyInterval) -> Option<u64> {
        let (a, b) = match which {
            LatencyInterval::Capture => (self.captured_ns, self.published_ns),
            LatencyInterval::CaptureToDetect => (self.published_ns, self.detect_received_ns),
            LatencyInterval::Detect => (self.detect_received_ns, self.detect_finished_ns),
            LatencyInterval::Estimate => (self.detect_finished_ns, self.estimate_finished_ns),
            LatencyInterval::Decide => (self.estimate_finished_ns, self.decide_finished_ns),
            LatencyInterval::EndToEnd => (self.published_ns, self.decide_finished_ns),
        };
        (a != 0 && b >= a).then(|| b - a)
    }
}

/// Frames lost so far, by where (cumulative counts of the process that counted them; they
/// restart at 0 when that stage is restarted).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.DropCounts.v1"))]
pub struct DropCounts {
    /// Frames the source delivered that capture could not publish (no free shared-memory
    /// sample, or capture fell behind the camera).
    pub capture: u64,
    /// Frames capture could not read (bad file, decode error); skipped, not published.
    pub bad_frames: u64,
    /// Frames published but never processed by detect (it was busy; latest-frame semantics).
    pub detect: u64,
    pub estimate: u64,
    pub decide: u64,
}

impl DropCounts {
    /// Every frame lost before the stage that reports these counts. Saturating: the counts
    /// come from other processes over shared memory, and a corrupt one must not overflow here.
    pub fn total(&self) -> u64 {
        self.named()
            .iter()
            .fold(0u64, |sum, (_, n)| sum.saturating_add(*n))
    }

    /// The counts with their names, in pipeline order.
    pub fn named(&self) -> [(&'static str, u64); 5] {
        [
            ("capture", self.capture),
            ("bad_frames", self.bad_frames),
            ("detect", self.detect),
            ("estimate", self.estimate),
            ("decide", self.decide),
        ]
    }
}

/// Counts the frames a stage never saw: gaps in the sequence numbers of its input, minus the
/// gaps its upstream stages already counted.
#[derive(Debug, Default, Clone)]
pub struct GapCounter {
    last: Option<(u64, u64)>,
    from_start: bool,
}

impl GapCounter {
    /// For a stage that was there when capture started: frames before the first one it sees
    /// (from sequence 0) were missed too.
    pub fn from_start() -> Self {
        Self {
            last: None,
            from_start: true,
        }
    }

    /// For a stage that joined a running pipeline (a restart): counting starts at the first
    /// frame it sees.
    pub fn joining() -> Self {
        Self::default()
    }

    /// `joining()` or `from_start()`.
    pub fn new(joined_late: bool) -> Self {
        if joined_late {
            Self::joining()
        } else {
            Self::from_start()
        }
    }

    /// Feed the next input's sequence number and its upstream drop total; returns the frames
    /// this stage missed since the previous input. A sequence going backwards (capture was
    /// restarted) starts counting afresh.
    pub fn observe(&mut self, seq: u64, upstream_total: u64) -> u64 {
        let missed = match self.last {
            Some((last_seq, last_up)) if seq > last_seq => {
                let gap = seq - last_seq - 1;
                gap.saturating_sub(upstream_total.saturating_sub(last_up))
            }
            None if self.from_start => seq.saturating_sub(upstream_total),
            _ => 0,
        };
        self.last = Some((seq, upstream_total));
        missed
    }
}

/// Identity and timing of one frame, at the start of every message.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.FrameStamp.v1"))]
pub struct FrameStamp {
    /// Capture's count of published frames, from 0; consecutive unless frames were dropped.
    pub seq: u64,
    pub times: StageTimes,
    pub drops: DropCounts,
}

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

wire_enum!(FrameSource, on_bad_code: Simulator, [Simulator, Replay, Libcamera]);

impl FrameSource {
    pub fn name(&self) -> &'static str {
        match self {
            Self::Simulator => "sim",
            Self::Replay => "replay",
            Self::Libcamera => "libcamera",
        }
    }
}

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

/// Detect's output for one frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.MarkerMessage.v4")
)]
pub struct MarkerMessage {
    pub stamp: FrameStamp,
    pub context: FrameContext,
    pub markers: MarkerSet,
}

/// Which estimator produced an attitude (also `[estimate] estimator`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EstimatorKind {
    /// The paper's method (ellipse of the ring), `atan2` variant.
    #[default]
    PaperAtan2 = 0,
    /// The paper's method exactly as printed (acos, needs the altimeter).
    PaperPrinted = 1,
    /// The paper's method with the fitted ellipse's major axis (CONVENTIONS.md C5).
    PaperFittedMajorAxis = 2,
    /// Full planar pose from every visible marker (`estimate::pose`).
    FullPose = 3,
}

impl EstimatorKind {
    /// Every estimator.
    pub const ALL: [EstimatorKind; 4] = [
        Self::FullPose,
        Self::PaperAtan2,
        Self::PaperPrinted,
        Self::PaperFittedMajorAxis,
    ];

    pub fn name(&self) -> &'static str {
        match self {
            Self::PaperAtan2 => "paper-atan2",
            Self::PaperPrinted => "paper-printed",
            Self::PaperFittedMajorAxis => "paper-fitted-major-axis",
            Self::FullPose => "full-pose",
        }
    }
}

wire_enum!(
    EstimatorKind,
    on_bad_code: PaperAtan2,
    [PaperAtan2, PaperPrinted, PaperFittedMajorAxis, FullPose]
);

/// Why an attitude is not valid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AttitudeFailure {
    /// The attitude is valid.
    #[default]
    None = 0,
    /// Detection found no deck.
    NoDeck = 1,
    /// The frame could not be read.
    BadFrame = 2,
    /// Markers were found, but not enough (or not the needed ones) for this estimator.
    TooFewMarkers = 3,
    /// The estimator needs an altimeter reading and has none (or an invalid one).
    NoAltitude = 4,
    /// The marker geometry was degenerate or inconsistent.
    Degenerate = 5,
    /// The markers are bit for bit those of the frames before ([`FROZEN_IMAGE_REPEATS`] times):
    /// the camera delivers the same image again (frozen, a stuck driver). A real sensor's noise
    /// never repeats a sub-pixel centre to the bit; with the vehicle swaying, the compensated
    /// attitude of a frozen image moves and would not look frozen to the decision.
    FrozenImage = 6,
}

wire_enum!(
    AttitudeFailure,
    on_bad_code: Degenerate,
    [None, NoDeck, BadFrame, TooFewMarkers, NoAltitude, Degenerate, FrozenImage]
);

/// Repeats of a marker set (after the first) that make an image frozen: the third bit-identical
/// set in a row, as `[decide] frozen_input_count` = 3 is for attitudes.
pub const FROZEN_IMAGE_REPEATS: u32 = 2;

/// Estimate's output for one frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.AttitudeMessage.v5")
)]
pub struct AttitudeMessage {
    pub stamp: FrameStamp,
    pub context: FrameContext,
    pub estimator: WireCode<EstimatorKind>,
    /// Whether the angles below mean anything; `failure` says why not.
    pub valid: WireBool,
    pub failure: WireCode<AttitudeFailure>,
    pub rpy: Rpy,
    pub quaternion: Quaternion,
    pub euler313: Euler313,
    /// The ring's fitted ellipse in undistorted pixel coordinates (for drawing), when
    /// `has_image_ellipse`.
    pub has_image_ellipse: WireBool,
    pub image_ellipse: Ellipse,
    /// Estimator-specific fit residual: the paper's method gives the RMS distance (m) of the
    /// corrected ring points from their ellipse.
    pub residual: f64,
    /// Markers the estimate used.
    pub markers_used: u32,
    /// Standard deviation of roll, pitch, yaw (deg) when the estimator gives one (full pose),
    /// else NaN.
    pub rpy_std_deg: [f64; 3],
    /// The camera's position over the deck centre (offset x, offset y, altitude; m) when the
    /// estimator gives it (full pose), else NaN.
    pub camera_position_m: [f64; 3],
    /// The other estimator's result on the same markers, for comparison (when enabled).
    pub alternative: AlternativeAttitude,
    /// The vehicle attitude taken out of `rpy` (`R_V`, body to world; W's x is the ship's mean
    /// heading when it came from the autopilot) and how: `Missing` means `rpy` is relative to
    /// the camera and decide never clears on it.
    pub vehicle: VehicleAttitude,
    /// The deck relative to the body-level camera (`(R_V R_M)^T R_D`): what the camera alone
    /// sees.
    pub camera_rpy: Rpy,
    /// The deck centre's height in W (m, z up; the heave, on the vehicle height's origin): the
    /// vehicle's height less the camera's height over the deck centre from the full pose. NaN
    /// when either is unknown.
    pub deck_height_m: f64,
}

impl Default for AttitudeMessage {
    /// No attitude: not valid, and every measured quantity unknown (NaN), not zero.
    fn default() -> Self {
        Self {
            stamp: FrameStamp::default(),
            context: FrameContext::default(),
            estimator: WireCode::default(),
            valid: WireBool::FALSE,
            failure: WireCode::default(),
            rpy: Rpy::default(),
            quaternion: Quaternion::default(),
            euler313: Euler313::default(),
            has_image_ellipse: WireBool::FALSE,
            image_ellipse: Ellipse::default(),
            residual: f64::NAN,
            markers_used: 0,
            rpy_std_deg: [f64::NAN; 3],
            camera_position_m: [f64::NAN; 3],
            alternative: AlternativeAttitude::default(),
            vehicle: VehicleAttitude::default(),
            camera_rpy: Rpy::default(),
            deck_height_m: f64::NAN,
        }
    }
}

/// A second estimator's attitude for the same frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.AlternativeAttitude.v1")
)]
pub struct AlternativeAttitude {
    /// Whether a second estimator ran.
    pub present: WireBool,
    pub estimator: WireCode<EstimatorKind>,
    pub valid: WireBool,
    pub rpy: Rpy,
}

/// The decision state (see the decide crate for its meaning and transitions).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DecisionState {
    /// No valid attitude: do not land.
    #[default]
    NoDeck = 0,
    /// A deck is in view, but landing now is not safe.
    Hold = 1,
    /// Commit to landing now.
    ClearToLand = 2,
    /// A committed landing became unsafe: abort.
    Abort = 3,
}

wire_enum!(DecisionState, on_bad_code: NoDeck, [NoDeck, Hold, ClearToLand, Abort]);

impl DecisionState {
    /// Every state, in the order of their values.
    pub const ALL: [DecisionState; 4] = [Self::NoDeck, Self::Hold, Self::ClearToLand, Self::Abort];

    pub fn name(&self) -> &'static str {
        match self {
            Self::NoDeck => "NO-DECK",
            Self::Hold => "HOLD",
            Self::ClearToLand => "CLEAR",
            Self::Abort => "ABORT",
        }
    }
}

/// Why the decision is what it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DecisionReason {
    /// Within capacity (ClearToLand).
    #[default]
    WithinCapacity = 0,
    /// The attitude message is not valid.
    InvalidAttitude = 1,
    /// The newest attitude is older than the freshness limit.
    StaleData = 2,
    /// Too long a gap in the attitude stream.
    Gap = 3,
    /// The attitude jumped more than the deck can move.
    Jump = 4,
    /// Roll or pitch (or their rates) outside the capacity.
    OutsideCapacity = 5,
    /// Not enough history yet to predict the deck's motion.
    Warmup = 6,
    /// The motion model does not fit the recent history.
    PredictionUnreliable = 7,
    /// The deck is predicted to leave the capacity during the touchdown.
    PredictedOutside = 8,
    /// The vehicle's attitude was needed but missing (the autopilot's stream stopped or lags):
    /// the attitude is the deck relative to a tilted camera.
    NoVehicleAttitude = 9,
    /// The deck's heave is part of the capacity (`[decide] heave = "required"`) but this frame
    /// has no deck height (no vehicle height, or no full pose).
    NoDeckHeave = 10,
    /// The input repeats itself bit for bit (`[decide] frozen_input_count` attitudes in a row):
    /// a frozen camera or a stuck stage, never a calm deck.
    FrozenInput = 11,
    /// A frame's time went backwards, or its capture is stamped in the future: the clock jumped.
    /// Three in a row start a new timeline (history cleared, warm-up again).
    ClockJump = 12,
    /// ClearToLand: a committed touchdown goes on through a missing attitude (`[decide]
    /// ride_through_ms`), on the prediction the last good one confirmed.
    RideThrough = 13,
}

wire_enum!(
    DecisionReason,
    on_bad_code: InvalidAttitude,
    [
        WithinCapacity,
        InvalidAttitude,
        StaleData,
        Gap,
        Jump,
        OutsideCapacity,
        Warmup,
        PredictionUnreliable,
        PredictedOutside,
        NoVehicleAttitude,
        NoDeckHeave,
        FrozenInput,
        ClockJump,
        RideThrough,
    ]
);

impl DecisionReason {
    pub fn name(&self) -> &'static str {
        match self {
            Self::WithinCapacity => "within-capacity",
            Self::InvalidAttitude => "invalid-attitude",
            Self::StaleData => "stale-data",
            Self::Gap => "gap",
            Self::Jump => "jump",
            Self::OutsideCapacity => "outside-capacity",
            Self::Warmup => "warmup",
            Self::PredictionUnreliable => "prediction-unreliable",
            Self::PredictedOutside => "predicted-outside",
            Self::NoVehicleAttitude => "no-vehicle-attitude",
            Self::NoDeckHeave => "no-deck-heave",
            Self::FrozenInput => "frozen-input",
            Self::ClockJump => "clock-jump",
            Self::RideThrough => "ride-through",
        }
    }
}

/// How a vehicle sample's autopilot time was put on this machine's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ClockMethod {
    /// Not yet: no offset estimate.
    #[default]
    None = 0,
    /// MAVLink TIMESYNC round trips (offset and drift).
    Timesync = 1,
    /// Arrival times only (the autopilot does not answer TIMESYNC): late by the link latency.
    Arrival = 2,
}

wire_enum!(ClockMethod, on_bad_code: None, [None, Timesync, Arrival]);

/// One attitude sample of the vehicle, from the autopilot (the `link` process), on this
/// machine's `CLOCK_MONOTONIC`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.VehicleSample.v2")
)]
pub struct VehicleSample {
    /// The link's count of samples, from 0.
    pub seq: u64,
    /// When the autopilot measured it, on `CLOCK_MONOTONIC` (ns).
    pub time_ns: u64,
    /// The same instant on the autopilot's clock (us since its boot).
    pub autopilot_time_us: u64,
    /// When it arrived here (`CLOCK_MONOTONIC`, ns).
    pub received_ns: u64,
    /// `R_V`: body (x forward, y left, z up) to north-west-up.
    pub quaternion: Quaternion,
    /// Range to what is below (m; DISTANCE_SENSOR), NaN unknown.
    pub altitude_m: f64,
    /// The vehicle's height in the autopilot's local frame (m, z up; LOCAL_POSITION_NED's -z,
    /// interpolated to `time_ns`), NaN unknown.
    pub height_m: f64,
    /// autopilot time - monotonic time (ns), and how it was estimated.
    pub clock_offset_ns: i64,
    pub clock_method: WireCode<ClockMethod>,
    /// Drift of the autopilot's clock against this machine's (parts per million).
    pub clock_drift_ppm: f64,
    /// The link: a heartbeat and attitude came within the configured time.
    pub link_up: WireBool,
}

/// Decide's output for one frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.LandingDecision.v5")
)]
pub struct LandingDecision {
    pub stamp: FrameStamp,
    pub context: FrameContext,
    /// The attitude the decision was made on.
    pub attitude: AttitudeMessage,
    pub state: WireCode<DecisionState>,
    pub reason: WireCode<DecisionReason>,
    /// The next predicted calm window, relative to `stamp.times.captured_ns` (s); NaN when
    /// none is predicted.
    pub calm_window_start_s: f64,
    pub calm_window_length_s: f64,
    /// The deck's vertical speed by the heave model (m/s, up; `attitude.deck_height_m` is its
    /// height); NaN when heave is not part of the capacity or not yet predicted.
    pub heave_rate_mps: f64,
    /// Issued by decide's watchdog because no attitude arrived in time (the stamp and attitude
    /// are the last ones received), not in answer to a frame.
    pub watchdog: WireBool,
}

/// "This process is alive and its loop turns": every stage process sends one at least every
/// [`StageHeartbeat::PERIOD_NS`] from the loop that does its work (never from a helper thread,
/// which would beat on while the loop hangs). The launcher restarts a stage whose beats stop.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.StageHeartbeat.v1")
)]
pub struct StageHeartbeat {
    /// The sender's process id (the launcher knows its children by it).
    pub pid: u32,
    /// The sender's count of beats, from 0.
    pub seq: u64,
    /// When it was sent (`CLOCK_MONOTONIC`, ns).
    pub sent_ns: u64,
}

impl StageHeartbeat {
    pub const PERIOD_NS: u64 = 100_000_000;
}

/// How serious a [`StageLog`] line is (Foxglove's `Log` levels).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LogLevel {
    Debug = 1,
    #[default]
    Info = 2,
    Warning = 3,
    Error = 4,
}

wire_enum!(LogLevel, on_bad_code: Error, [Debug, Info, Warning, Error]);

impl LogLevel {
    /// A stage's line, judged by its words (the stages write plain lines on stderr): failures
    /// are errors; restarts, unresponsive stages and a nonzero count of dropped or skipped
    /// things are warnings ("0 dropped" in a summary is not).
    pub fn of_line(line: &str) -> Self {
        let l = line.to_ascii_lowercase();
        if ["error", "failed", "panicked", "cannot", "killing", "killed"]
            .iter()
            .any(|w| l.contains(w))
        {
            return Self::Error;
        }
        if ["not responding", "restart", "stale", "warning"]
            .iter()
            .any(|w| l.contains(w))
        {
            return Self::Warning;
        }
        let words: Vec<&str> = l
            .split(|c: char| !c.is_ascii_alphanumeric())
            .filter(|w| !w.is_empty())
            .collect();
        let counted = words.windows(2).any(|w| {
            ["dropped", "skipped", "bad", "missed"].contains(&w[1])
                && w[0].parse::<u64>().is_ok_and(|n| n > 0)
        });
        if counted {
            Self::Warning
        } else {
            Self::Info
        }
    }
}

/// One line a process of the pipeline wrote on stderr, which the launcher passes on
/// (`deckwatch/log`) when a recorder runs.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.StageLog.v1"))]
pub struct StageLog {
    /// When the launcher read it (`CLOCK_MONOTONIC`, ns).
    pub time_ns: u64,
    pub pid: u32,
    pub level: WireCode<LogLevel>,
    /// The process's name (UTF-8, `name_len` bytes; longer names are cut).
    pub name: [u8; StageLog::NAME_BYTES],
    pub name_len: u32,
    /// The line (UTF-8, `text_len` bytes; longer lines are cut).
    pub text: [u8; StageLog::TEXT_BYTES],
    pub text_len: u32,
}

impl Default for StageLog {
    fn default() -> Self {
        Self::new(0, 0, "", "")
    }
}

impl StageLog {
    pub const NAME_BYTES: usize = 24;
    pub const TEXT_BYTES: usize = 480;

    pub fn new(time_ns: u64, pid: u32, name: &str, line: &str) -> Self {
        let mut out = Self {
            time_ns,
            pid,
            level: LogLevel::of_line(line).into(),
            name: [0; Self::NAME_BYTES],
            name_len: 0,
            text: [0; Self::TEXT_BYTES],
            text_len: 0,
        };
        out.name_len = copy_cut(name, &mut out.name);
        out.text_len = copy_cut(line, &mut out.text);
        out
    }

    /// The name, as far as it is UTF-8 (a length past the array is read as the whole array).
    pub fn name(&self) -> String {
        lossy(&self.name, self.name_len)
    }

    pub fn text(&self) -> String {
        lossy(&self.text, self.text_len)
    }
}

/// Copies as much of `s` as fits, cut at a character boundary; the bytes copied.
fn copy_cut(s: &str, out: &mut [u8]) -> u32 {
    let mut n = s.len().min(out.len());
    while !s.is_char_boundary(n) {
        n -= 1;
    }
    out[..n].copy_from_slice(&s.as_bytes()[..n]);
    n as u32
}

fn lossy(bytes: &[u8], len: u32) -> String {
    let n = (len as usize).min(bytes.len());
    String::from_utf8_lossy(&bytes[..n]).into_owned()
}

impl WireCheck for StageLog {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [level]; parts: [])
    }
}

/// One MAVLink frame the link sent or received (`deckwatch/link`), for the recorder.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.LinkTraffic.v1"))]
pub struct LinkTraffic {
    /// When it was sent or received (`CLOCK_MONOTONIC`, ns).
    pub time_ns: u64,
    /// Sent by deckwatch (true) or received from the link (false).
    pub outgoing: WireBool,
    pub msg_id: u32,
    /// The message's name (`LANDING_TARGET`; ASCII, `name_len` bytes).
    pub name: [u8; LinkTraffic::NAME_BYTES],
    pub name_len: u32,
    /// The whole MAVLink 2 frame as on the wire (`frame_len` bytes).
    pub frame: [u8; LinkTraffic::FRAME_BYTES],
    pub frame_len: u32,
}

impl Default for LinkTraffic {
    fn default() -> Self {
        Self::new(0, false, 0, "", &[])
    }
}

impl LinkTraffic {
    pub const NAME_BYTES: usize = 48;
    /// The largest MAVLink 2 frame (280 bytes with a signature).
    pub const FRAME_BYTES: usize = 280;

    pub fn new(time_ns: u64, outgoing: bool, msg_id: u32, name: &str, frame: &[u8]) -> Self {
        let mut out = Self {
            time_ns,
            outgoing: outgoing.into(),
            msg_id,
            name: [0; Self::NAME_BYTES],
            name_len: 0,
            frame: [0; Self::FRAME_BYTES],
            frame_len: 0,
        };
        out.name_len = copy_cut(name, &mut out.name);
        let n = frame.len().min(Self::FRAME_BYTES);
        out.frame[..n].copy_from_slice(&frame[..n]);
        out.frame_len = n as u32;
        out
    }

    pub fn name(&self) -> String {
        lossy(&self.name, self.name_len)
    }

    /// The frame's bytes (a length past the array is read as the whole array).
    pub fn frame_bytes(&self) -> &[u8] {
        &self.frame[..(self.frame_len as usize).min(Self::FRAME_BYTES)]
    }
}

impl WireCheck for LinkTraffic {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [outgoing]; parts: [])
    }
}

impl WireCheck for StageHeartbeat {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        Ok(())
    }
}

impl WireCheck for Truth {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [known]; parts: [])
    }
}

impl WireCheck for VehicleAttitude {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [compensation]; parts: [])
    }
}

impl WireCheck for FrameContext {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [source]; parts: [truth, vehicle])
    }
}

impl WireCheck for FrameHeader {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [pixel_format]; parts: [context])
    }
}

impl WireCheck for MarkerMessage {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: []; parts: [context, markers])
    }
}

impl WireCheck for AlternativeAttitude {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [present, estimator, valid]; parts: [])
    }
}

impl WireCheck for AttitudeMessage {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(
            self;
            codes: [estimator, valid, failure, has_image_ellipse];
            parts: [context, alternative, vehicle]
        )
    }
}

impl WireCheck for VehicleSample {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [clock_method, link_up]; parts: [])
    }
}

impl WireCheck for LandingDecision {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(
            self;
            codes: [state, reason, watchdog];
            parts: [context, attitude]
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_lines_get_a_level_and_survive_any_length() {
        let level = |l: &str| LogLevel::of_line(l);
        assert_eq!(
            level("deckwatch-detect: 60 frames processed, 0 dropped, 0 bad"),
            LogLevel::Info
        );
        assert_eq!(
            level("deckwatch-detect: 60 frames processed, 3 dropped, 0 bad"),
            LogLevel::Warning
        );
        assert_eq!(
            level("deckwatch: detect stopped (signal 9); restarting in 250 ms"),
            LogLevel::Warning
        );
        assert_eq!(level("deckwatch-record: cannot create x.mcap"), LogLevel::Error);
        let long = "é".repeat(400);
        let l = StageLog::new(1, 2, &"n".repeat(40), &long);
        assert_eq!(l.name().len(), StageLog::NAME_BYTES);
        assert!(l.text().len() <= StageLog::TEXT_BYTES && l.text().chars().all(|c| c == 'é'));
        let mut bad = l;
        bad.text_len = u32::MAX;
        assert_eq!(bad.text().len(), StageLog::TEXT_BYTES);
    }

    #[test]
    fn gap_counter_counts_only_its_own_misses() {
        let mut g = GapCounter::from_start();
        // Frames 0 and 1 missed before the first one seen.
        assert_eq!(g.observe(2, 0), 2);
        let mut g = GapCounter::joining();
        assert_eq!(g.observe(500, 3), 0);
        let mut g = GapCounter::from_start();
        assert_eq!(g.observe(0, 0), 0);
        assert_eq!(g.observe(1, 0), 0);
        // 2 and 3 missing, upstream says it dropped one of them.
        assert_eq!(g.observe(4, 1), 1);
        assert_eq!(g.observe(5, 1), 0);
        // Capture restarted: sequence starts again.
        assert_eq!(g.observe(0, 0), 0);
        assert_eq!(g.observe(3, 0), 2);
    }

    #[test]
    fn intervals_need_both_ends() {
        let t = StageTimes {
            captured_ns: 100,
            published_ns: 150,
            detect_received_ns: 160,
            detect_finished_ns: 200,
            ..Default::default()
        };
        assert_eq!(t.interval_ns(LatencyInterval::Capture), Some(50));
        assert_eq!(t.interval_ns(LatencyInterval::CaptureToDetect), Some(10));
        assert_eq!(t.interval_ns(LatencyInterval::Detect), Some(40));
        assert_eq!(t.interval_ns(LatencyInterval::Estimate), None);
        assert_eq!(t.interval_ns(LatencyInterval::EndToEnd), None);
    }

    #[test]
    fn truth_round_trip() {
        let g = GroundTruth {
            roll_deg: Some(1.0),
            pitch_deg: Some(-2.0),
            yaw_deg: Some(3.0),
            alt_m: Some(5.0),
            ..GroundTruth::default()
        };
        let t = Truth::from_ground_truth(&g, true);
        assert_eq!(
            t.attitude().unwrap().to_degrees().map(|v| v.round()),
            [1.0, -2.0, 3.0]
        );
        assert!(!t.no_deck());
        let none = Truth::from_ground_truth(&GroundTruth::default(), true);
        assert!(none.no_deck());
        assert!(!Truth::UNKNOWN.no_deck());
    }

    #[test]
    fn frame_header_length() {
        let h = FrameHeader {
            width: 10,
            height: 3,
            stride: 16,
            ..Default::default()
        };
        assert_eq!(h.required_len(), 2 * 16 + 10);
    }
}
