//! The stages' outputs: detect's markers, estimate's attitude, decide's decision, and the
//! autopilot's attitude samples the link publishes.

use super::*;

/// Detect's output for one frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.MarkerMessage.v5")
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

// Full pose first: the reports' order.
wire_enum!(
    EstimatorKind,
    on_bad_code: PaperAtan2,
    [
        FullPose => "full-pose",
        PaperAtan2 => "paper-atan2",
        PaperPrinted => "paper-printed",
        PaperFittedMajorAxis => "paper-fitted-major-axis",
    ]
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

/// Repeats of a marker set (after the first) that make an image frozen: the first repeat, the
/// second bit-identical set in a row. A repeated image is one captured earlier, stamped now and
/// compensated with the vehicle's attitude and height of now: not the deck at any instant.
/// The detector's tracking places its windows from the frame before, so a frozen camera's
/// first repeated image gives marker centres a little different from the original's, and only
/// the repeats after it are bit-identical: in the closed-loop trials that first repeat, during
/// a descent, moved the deck's height by 0.14 m and its roll by 0.3 deg, and a touchdown went
/// around on it for `predicted-outside`; the next one, which passed too while the third set in
/// a row was the first refused, is now refused (docs/history.md, "A rate's band cleared on
/// only with misses of its own"). Catching the first repeat needs the image's own fingerprint.
pub const FROZEN_IMAGE_REPEATS: u32 = 1;

/// Estimate's output for one frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.AttitudeMessage.v6")
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
    /// Covariance of `camera_position_m` in the world frame (m^2) when the estimator gives one
    /// (full pose), else NaN.
    pub camera_position_covariance_m2: [[f64; 3]; 3],
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
            camera_position_covariance_m2: [[f64::NAN; 3]; 3],
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

wire_enum!(
    DecisionState,
    on_bad_code: NoDeck,
    [NoDeck => "NO-DECK", Hold => "HOLD", ClearToLand => "CLEAR", Abort => "ABORT"]
);

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
        WithinCapacity => "within-capacity",
        InvalidAttitude => "invalid-attitude",
        StaleData => "stale-data",
        Gap => "gap",
        Jump => "jump",
        OutsideCapacity => "outside-capacity",
        Warmup => "warmup",
        PredictionUnreliable => "prediction-unreliable",
        PredictedOutside => "predicted-outside",
        NoVehicleAttitude => "no-vehicle-attitude",
        NoDeckHeave => "no-deck-heave",
        FrozenInput => "frozen-input",
        ClockJump => "clock-jump",
        RideThrough => "ride-through",
    ]
);

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
/// machine's `CLOCK_MONOTONIC`. By default every measured value is unknown (NaN), so that a
/// sample built from the default never passes off a 0 as a height or a speed.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.VehicleSample.v3")
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
    /// The height's rate by the autopilot's estimator (m/s, up; LOCAL_POSITION_NED's -vz), NaN
    /// unknown.
    pub vertical_speed_mps: f64,
    /// autopilot time - monotonic time (ns), and how it was estimated.
    pub clock_offset_ns: i64,
    pub clock_method: WireCode<ClockMethod>,
    /// Drift of the autopilot's clock against this machine's (parts per million).
    pub clock_drift_ppm: f64,
    /// The link: a heartbeat and attitude came within the configured time.
    pub link_up: WireBool,
}

impl Default for VehicleSample {
    fn default() -> Self {
        Self {
            seq: 0,
            time_ns: 0,
            autopilot_time_us: 0,
            received_ns: 0,
            quaternion: Quaternion::default(),
            altitude_m: f64::NAN,
            height_m: f64::NAN,
            vertical_speed_mps: f64::NAN,
            clock_offset_ns: 0,
            clock_method: WireCode::default(),
            clock_drift_ppm: 0.0,
            link_up: WireBool::FALSE,
        }
    }
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
