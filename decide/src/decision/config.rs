//! The decision's configuration: `[decide]` holds what an operator states (the vehicle's
//! capacity, the touchdown, the accepted risk, the autopilot's errors, what input is too old or
//! broken), `[decide.forecast]` the forecaster and its tuning ([`ForecastConfig`]).

use super::forecast_config::{ArForecastConfig, ForecastConfig};
use deckwatch_common::InvalidField;
use serde::{Deserialize, Serialize};

/// What the decision needs to know (the `[decide]` section of the pipeline configuration).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct DecisionConfig {
    /// The quadrotor's capacity at touchdown: deck tilt...
    pub max_abs_roll_deg: f64,
    pub max_abs_pitch_deg: f64,
    /// ... the deck's whole tilt from level (roll and pitch together, deg): what the gear takes
    /// against a level deck less what the vehicle itself leans at contact. 5.5: a gear that
    /// takes 8 deg against the deck, a vehicle leaning up to 2.5 deg in wind (a deck at 4.3 deg
    /// roll and 3.9 deg pitch, each within its limit, is tilted 5.8 deg: with the vehicle's lean
    /// it broke the 8 deg) ...
    pub max_tilt_deg: f64,
    /// ... and tilt rates.
    pub max_abs_roll_rate_dps: f64,
    pub max_abs_pitch_rate_dps: f64,
    /// Whether the deck's heave is part of the capacity: `required` (a frame without a deck
    /// height is refused, `no-deck-heave`) or `off` (roll and pitch only: a camera with no
    /// vehicle height, or the paper's method alone).
    pub heave: HeaveUse,
    /// ... and the deck's vertical speed (m/s): a small quadrotor's gear; ship-helicopter
    /// operating limits are about 1 m/s.
    pub max_abs_heave_rate_mps: f64,
    /// Time from commit to contact (s): the deck must stay within capacity all that time.
    pub touchdown_s: f64,
    /// How long before contact a go-around can no longer keep the vehicle off the deck (ms):
    /// the autopilot's reaction and the time to arrest the descent, the vehicle's own figure
    /// (descending at `v` m/s and climbing away at `a` m/s^2 after `r` s: about `r + v / (2 a)`
    /// of its descent is left to contact). The last decision that can act before that point
    /// (the next frame is expected after it, or a blind spell could reach it) judges the rest
    /// of the touchdown as a new clearance would (`risk_per_touchdown`), not at
    /// `go_around_risk`: no later frame can send it around. 350: a quadrotor descending at 1.6
    /// m/s that arrests at 4 m/s^2 (PX4's `MPC_ACC_UP_MAX`) after 0.1 s needs 0.3 s.
    pub no_return_ms: f64,
    /// A committed touchdown goes on through missing attitudes (no deck seen, no vehicle
    /// attitude to compensate with, no deck height, the gap they leave) for this long in a
    /// row (ms; 0: abort on the first), on the prediction the last good attitude confirmed,
    /// while that prediction keeps the deck within the capacity to the touchdown's end: at
    /// `go_around_risk` while a frame, or the budget's end, comes before the point of no return,
    /// at `risk_per_touchdown` once the budget left reaches that point (`ride-through`).
    /// The final metres of a descent are blind: the ring leaves a camera's view about 1 m over
    /// the deck. Never entered on such data, and never through a stale, frozen, jumping or
    /// unpredictable input.
    pub ride_through_ms: f64,
    /// How long `Abort` is held (s).
    pub abort_hold_s: f64,
    /// The accepted probability that the deck leaves the capacity during one touchdown, bounded
    /// from above: for each of the six limits (roll, pitch, the tilt, the two rates, the heave
    /// rate) the largest probability, over the touchdown, that the forecast (mean and
    /// calibrated standard deviation) is beyond it, summed over the limits.
    pub risk_per_touchdown: f64,
    /// ... and once committed: the touchdown goes on while that probability, by the newest
    /// forecast, stays at or below this; above it, a go-around. Larger than
    /// `risk_per_touchdown`, so a commitment is not given up for a forecast that moved by a hair
    /// (a go-around has its own risks). 0.1: at 0.2 a held-out campaign's touchdown went on at
    /// a risk of 0.13 and met the deck at 0.606 m/s against 0.6; at 0.05 `decide-eval` sent
    /// 2.8-3.8 % of its commits around against 0.7-1.8 % at 0.1 (docs/history.md).
    pub go_around_risk: f64,
    /// The autopilot's vertical-speed error (m/s, standard deviation; slow, so one value over a
    /// touchdown). The deck's height is the vehicle's less the camera's over the deck, so this
    /// error is a bias of the measured heave rate that the forecast's band, fitted to the
    /// measurements, cannot contain: it is added to the heave rate's band in quadrature. 0
    /// trusts the autopilot's vertical speed as exact ([`AUTOPILOT_VERTICAL_SPEED_ERROR_MPS`]).
    pub vertical_speed_error_mps: f64,
    /// The autopilot's roll and pitch error (deg, standard deviation; slow, so one value over a
    /// touchdown), with the camera's mounting calibration's. The deck's attitude is the
    /// camera's measurement composed with the vehicle's, so this error is a bias of the measured
    /// deck angles that the forecast's band cannot contain: it is added to the roll and pitch
    /// bands in quadrature (tilt too). 0 trusts the autopilot's attitude as exact
    /// ([`AUTOPILOT_ATTITUDE_ERROR_DEG`]).
    pub vehicle_attitude_error_deg: f64,
    /// An attitude older than this when decided on is stale (capture -> decision).
    pub max_age_ms: f64,
    /// A longer interval between valid attitudes is a gap.
    pub max_gap_ms: f64,
    /// This many bit-identical inputs in a row (roll, pitch and deck height) are a frozen input:
    /// refused (`frozen-input`), and the history is learnt afresh once it moves again.
    pub frozen_input_count: u32,
    /// A change between consecutive attitudes faster than this is a jump (a bad estimate).
    pub max_plausible_rate_dps: f64,
    /// The forecaster and its tuning (`[decide.forecast]`).
    pub forecast: ForecastConfig,
}

impl Default for DecisionConfig {
    fn default() -> Self {
        Self {
            max_abs_roll_deg: 5.0,
            max_abs_pitch_deg: 5.0,
            max_tilt_deg: 5.5,
            max_abs_roll_rate_dps: 5.0,
            max_abs_pitch_rate_dps: 5.0,
            heave: HeaveUse::Required,
            max_abs_heave_rate_mps: 0.6,
            touchdown_s: 2.0,
            no_return_ms: 350.0,
            ride_through_ms: 1000.0,
            abort_hold_s: 2.0,
            risk_per_touchdown: 1e-3,
            go_around_risk: 0.1,
            vertical_speed_error_mps: AUTOPILOT_VERTICAL_SPEED_ERROR_MPS,
            vehicle_attitude_error_deg: AUTOPILOT_ATTITUDE_ERROR_DEG,
            max_age_ms: 300.0,
            max_gap_ms: 500.0,
            frozen_input_count: 3,
            max_plausible_rate_dps: 40.0,
            forecast: ForecastConfig::Ar(ArForecastConfig::default()),
        }
    }
}

/// Whether the deck's heave is part of the capacity (`[decide] heave`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum HeaveUse {
    /// Every frame needs a deck height; its predicted vertical speed must stay within
    /// `max_abs_heave_rate_mps`.
    Required,
    /// Roll and pitch only.
    Off,
}

deckwatch_common::named_enum!(HeaveUse, [Required => "required", Off => "off"]);

/// A `[decide]` value out of range: the key (without the section) and what is wrong; the same
/// error as every other section's.
pub(super) fn invalid(key: impl Into<String>, problem: impl Into<String>) -> InvalidField {
    InvalidField::new(key, problem)
}

/// `vertical_speed_error_mps` by default (m/s): a GNSS-aided estimator's vertical-speed error,
/// a few cm/s and slow. With 0.05 m/s RMS of it and nothing to cover it, `decide-eval` cleared
/// unsafe touchdowns (docs/history.md). An autopilot with a better vertical speed (RTK) may
/// state less.
pub const AUTOPILOT_VERTICAL_SPEED_ERROR_MPS: f64 = 0.05;

/// `vehicle_attitude_error_deg` by default (deg): a GNSS-aided estimator's roll and pitch error
/// after its accelerometer biases are learnt, a few tenths of a degree and slow. With the
/// autopilot's roll and pitch biased by 0.3 deg, 5-7 % of `decide-eval`'s clearances had the
/// true roll or pitch beyond 3.09 of the forecast's deviations during the touchdown, against
/// 0.8-1.0 % with an exact autopilot (docs/history.md). An autopilot with a better attitude (a
/// calibrated, quiet IMU) may state less.
pub const AUTOPILOT_ATTITUDE_ERROR_DEG: f64 = 0.2;

/// At most this many bit-identical inputs in a row before they count as a frozen input.
pub const MAX_FROZEN_INPUT_COUNT: u32 = 30;

/// Keys `[decide]` had before the forecaster's tuning moved to `[decide.forecast]`, and where
/// each is now: an old configuration file gets this as its error, not "unknown field".
pub const MOVED_KEYS: &[(&str, &str)] = &[
    (
        "predictor",
        "is now [decide.forecast] kind (\"ar\"; the sinusoid fit was removed)",
    ),
    (
        "ar_order",
        "is now [decide.forecast] order (the table starts with kind = \"ar\")",
    ),
    (
        "window_s",
        "is now [decide.forecast] window_s (the table starts with kind = \"ar\")",
    ),
    (
        "min_history_s",
        "is now [decide.forecast] min_history_s (the table starts with kind = \"ar\")",
    ),
    (
        "refit_interval_s",
        "is now [decide.forecast] refit_interval_s (the table starts with kind = \"ar\")",
    ),
    (
        "holdout_s",
        "is now [decide.forecast] holdout_s (the table starts with kind = \"ar\")",
    ),
    (
        "horizon_s",
        "is now [decide.forecast] horizon_s (the table starts with kind = \"ar\")",
    ),
    (
        "gap_recovery_s",
        "is now [decide.forecast] gap_recovery_s (the table starts with kind = \"ar\")",
    ),
    (
        "max_innovation_deg",
        "is now [decide.forecast] max_innovation_deg (the table starts with kind = \"ar\")",
    ),
    (
        "max_heave_innovation_m",
        "is now [decide.forecast] max_heave_innovation_m (the table starts with kind = \"ar\")",
    ),
    (
        "max_rate_innovation_dps",
        "is now [decide.forecast] max_rate_innovation_dps (the table starts with kind = \"ar\")",
    ),
    (
        "early_risk_per_touchdown",
        "is now [decide.forecast] early_risk_per_touchdown (the table starts with kind = \"ar\")",
    ),
    (
        "early_window_s",
        "is now [decide.forecast] early_window_s (the table starts with kind = \"ar\")",
    ),
    (
        "margin_deg",
        "was removed: state the capacity (max_abs_*_deg, max_tilt_deg) less the margin",
    ),
    (
        "rate_margin_dps",
        "was removed: state the rate capacity less the margin",
    ),
    (
        "heave_rate_margin_mps",
        "was removed: state max_abs_heave_rate_mps less the margin",
    ),
    ("components", "was removed with the sinusoid fit"),
    ("fit_memory_s", "was removed with the sinusoid fit"),
    ("max_holdout_error_deg", "was removed with the sinusoid fit"),
    ("max_holdout_error_m", "was removed with the sinusoid fit"),
    ("error_factor", "was removed with the sinusoid fit"),
    ("error_memory_s", "was removed with the sinusoid fit"),
];

/// Where an old `[decide]` key is now ([`MOVED_KEYS`]); None for any other key.
pub fn moved_key(key: &str) -> Option<&'static str> {
    MOVED_KEYS.iter().find(|(k, _)| *k == key).map(|(_, to)| *to)
}

impl DecisionConfig {
    /// The naive baseline the state machine is measured against: the deck's current roll and
    /// pitch are within the capacity. It looks at one instant only; it is not a clearance.
    /// Non-finite angles are never within.
    pub fn naive_within(&self, roll_deg: f64, pitch_deg: f64) -> bool {
        roll_deg.abs() <= self.max_abs_roll_deg && pitch_deg.abs() <= self.max_abs_pitch_deg
    }

    /// The capacity's six limits in the order the risk judge takes them (`risk::exceedance_risk`):
    /// roll, pitch, tilt (deg), roll rate, pitch rate (deg/s), heave rate (m/s).
    pub(crate) fn capacity_limits(&self) -> [f64; 6] {
        [
            self.max_abs_roll_deg,
            self.max_abs_pitch_deg,
            self.max_tilt_deg,
            self.max_abs_roll_rate_dps,
            self.max_abs_pitch_rate_dps,
            self.max_abs_heave_rate_mps,
        ]
    }

    /// The autoregressive forecaster's tuning.
    pub fn ar(&self) -> &ArForecastConfig {
        let ForecastConfig::Ar(ar) = &self.forecast;
        ar
    }

    /// The same, to change it.
    pub fn ar_mut(&mut self) -> &mut ArForecastConfig {
        let ForecastConfig::Ar(ar) = &mut self.forecast;
        ar
    }

    /// Checks every field; the error names it (`forecast.KEY` for the forecaster's).
    pub fn validate(&self) -> Result<(), InvalidField> {
        let positive = [
            ("max_abs_roll_deg", self.max_abs_roll_deg),
            ("max_abs_pitch_deg", self.max_abs_pitch_deg),
            ("max_tilt_deg", self.max_tilt_deg),
            ("max_abs_roll_rate_dps", self.max_abs_roll_rate_dps),
            ("max_abs_pitch_rate_dps", self.max_abs_pitch_rate_dps),
            ("max_abs_heave_rate_mps", self.max_abs_heave_rate_mps),
            ("touchdown_s", self.touchdown_s),
            ("max_age_ms", self.max_age_ms),
            ("max_gap_ms", self.max_gap_ms),
            ("max_plausible_rate_dps", self.max_plausible_rate_dps),
        ];
        for (k, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(k, format!("must be positive, got {v}")));
            }
        }
        for (k, v) in [
            ("vertical_speed_error_mps", self.vertical_speed_error_mps),
            ("vehicle_attitude_error_deg", self.vehicle_attitude_error_deg),
            ("abort_hold_s", self.abort_hold_s),
            ("ride_through_ms", self.ride_through_ms),
            ("no_return_ms", self.no_return_ms),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(k, format!("must be >= 0, got {v}")));
            }
        }
        // Upper bounds. Durations size loops, buffers and timers: beyond these they are
        // mistakes. Capacities and check thresholds are bounded by what a small quadrotor's
        // gear and a ship's deck can physically be: a larger value does not describe a
        // vehicle, it switches a check off (`SAFETY_BOUNDS`).
        let mut fields = self.clone();
        for &(k, max, why) in SAFETY_BOUNDS {
            let v = fields.field_mut(k).map_or(f64::NAN, |v| *v);
            if !(v <= max) {
                return Err(invalid(k, format!("must be at most {max} ({why}), got {v}")));
            }
        }
        if self.max_plausible_rate_dps <= self.max_abs_roll_rate_dps.max(self.max_abs_pitch_rate_dps) {
            return Err(invalid(
                "max_plausible_rate_dps",
                format!(
                    "must exceed max_abs_roll_rate_dps and max_abs_pitch_rate_dps ({}): a deck within capacity would read as a jump",
                    self.max_abs_roll_rate_dps.max(self.max_abs_pitch_rate_dps)
                ),
            ));
        }
        if !(2..=MAX_FROZEN_INPUT_COUNT).contains(&self.frozen_input_count) {
            return Err(invalid(
                "frozen_input_count",
                format!(
                    "must be 2..={MAX_FROZEN_INPUT_COUNT} (more repeats of a frozen camera pass unnoticed), got {}",
                    self.frozen_input_count
                ),
            ));
        }
        if !(self.risk_per_touchdown > 1e-9) {
            return Err(invalid(
                "risk_per_touchdown",
                format!("must be above 1e-9, got {}", self.risk_per_touchdown),
            ));
        }
        if !(self.go_around_risk >= self.risk_per_touchdown && self.go_around_risk <= MAX_GO_AROUND_RISK) {
            return Err(invalid(
                "go_around_risk",
                format!(
                    "must be in [risk_per_touchdown, {MAX_GO_AROUND_RISK}] ([{}, {MAX_GO_AROUND_RISK}]): a touchdown carried on while its forecast puts the deck outside the capacity more often than that is a go-around made unreachable, got {}",
                    self.risk_per_touchdown, self.go_around_risk
                ),
            ));
        }
        if !(self.no_return_ms >= MIN_NO_RETURN_MS) {
            return Err(invalid(
                "no_return_ms",
                format!(
                    "must be at least {MIN_NO_RETURN_MS} ms: no vehicle reverses a descent faster than it reacts (0.1 s), and a decision that believes it can go around at contact orders go-arounds that cannot be flown; got {}",
                    self.no_return_ms
                ),
            ));
        }
        if self.ride_through_ms > 1e3 * self.touchdown_s {
            return Err(invalid(
                "ride_through_ms",
                format!(
                    "must not exceed the touchdown ({} ms), got {}",
                    1e3 * self.touchdown_s,
                    self.ride_through_ms
                ),
            ));
        }
        if self.no_return_ms >= 1e3 * self.touchdown_s {
            return Err(invalid(
                "no_return_ms",
                format!(
                    "must be shorter than the touchdown ({} ms): a descent that cannot be given up is not a commitment a decision can hold, got {}",
                    1e3 * self.touchdown_s,
                    self.no_return_ms
                ),
            ));
        }
        let ForecastConfig::Ar(ar) = &self.forecast;
        ar.validate(self)
    }

    /// A numeric key of [`SAFETY_BOUNDS`] (None for any other).
    pub fn field_mut(&mut self, key: &str) -> Option<&mut f64> {
        Some(match key {
            "max_abs_roll_deg" => &mut self.max_abs_roll_deg,
            "max_abs_pitch_deg" => &mut self.max_abs_pitch_deg,
            "max_tilt_deg" => &mut self.max_tilt_deg,
            "max_abs_roll_rate_dps" => &mut self.max_abs_roll_rate_dps,
            "max_abs_pitch_rate_dps" => &mut self.max_abs_pitch_rate_dps,
            "max_abs_heave_rate_mps" => &mut self.max_abs_heave_rate_mps,
            "touchdown_s" => &mut self.touchdown_s,
            "max_age_ms" => &mut self.max_age_ms,
            "max_gap_ms" => &mut self.max_gap_ms,
            "max_plausible_rate_dps" => &mut self.max_plausible_rate_dps,
            "risk_per_touchdown" => &mut self.risk_per_touchdown,
            "abort_hold_s" => &mut self.abort_hold_s,
            "ride_through_ms" => &mut self.ride_through_ms,
            _ => return None,
        })
    }
}

/// The most `go_around_risk` may be: a committed touchdown goes on while its newest forecast
/// leaves the capacity with at most this probability. The default is 0.1; 0.25 gives a
/// go-around only when the forecast says one in four.
pub const MAX_GO_AROUND_RISK: f64 = 0.25;
/// The least `no_return_ms` may be (ms): a multirotor's reaction to a climb order (the trials'
/// vehicle model and the default's first term, `trials::fly`).
pub const MIN_NO_RETURN_MS: f64 = 100.0;

/// The largest value each `[decide]` key may take, and why: no configuration may switch a
/// safety check off by making it unreachable. Capacities: twice what ships allow a helicopter
/// (a small quadrotor's wide gear may take more than a helicopter's, not more than that): the
/// standard design limits for helicopter operations are 5 deg of roll, 3 deg of pitch and 2 m/s
/// of vertical velocity at the pad (significant amplitudes; NPS Total Ship Systems Engineering
/// studies), and the UK CAA's CAP 437 helideck limits 3-4 deg and a heave rate of about 1.3 m/s.
/// Check thresholds: a few times their defaults, far beyond which they no longer catch what
/// they are for. The forecaster's keys have theirs (`forecast_config::FORECAST_SAFETY_BOUNDS`).
pub const SAFETY_BOUNDS: &[(&str, f64, &str)] = &[
    (
        "max_abs_roll_deg",
        10.0,
        "twice a helicopter's 5 deg deck-roll limit (helicopter operations' standard design limits)",
    ),
    (
        "max_abs_pitch_deg",
        10.0,
        "more than three times a helicopter's 3 deg deck-pitch limit",
    ),
    ("max_tilt_deg", 12.0, "the roll and pitch bounds together"),
    (
        "max_abs_roll_rate_dps",
        30.0,
        "a deck rolling faster throws the vehicle off",
    ),
    (
        "max_abs_pitch_rate_dps",
        30.0,
        "a deck pitching faster throws the vehicle off",
    ),
    (
        "max_abs_heave_rate_mps",
        2.0,
        "helicopter operations' design limit of the pad's vertical speed (CAP 437's helideck limit is about 1.3 m/s); a deck rising faster strikes the gear",
    ),
    ("touchdown_s", 30.0, "a touchdown is seconds long"),
    ("max_age_ms", 1000.0, "older attitudes are stale"),
    ("max_gap_ms", 2000.0, "a longer pause in the attitudes is a gap"),
    (
        "max_plausible_rate_dps",
        120.0,
        "a faster change is a bad estimate, not a deck",
    ),
    (
        "risk_per_touchdown",
        0.01,
        "one touchdown in a hundred is not a safe clearance",
    ),
    ("abort_hold_s", 600.0, "a duration"),
    (
        "ride_through_ms",
        2000.0,
        "longer blind is not riding through, it is flying blind",
    ),
];
