//! The decision's configuration (`[decide]`): the vehicle's capacity, the touchdown, the
//! accepted risk, the predictor and its settings, and their checks.

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
    /// it broke the 8 deg, BENCHMARKS.md "Deck-motion prediction") ...
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
    /// An attitude older than this when decided on is stale (capture -> decision).
    pub max_age_ms: f64,
    /// A longer interval between valid attitudes is a gap.
    pub max_gap_ms: f64,
    /// After a gap, no clearance for this long (the autoregressive forecast's band carries the
    /// gap's unmeasured lags itself).
    pub gap_recovery_s: f64,
    /// A change between consecutive attitudes faster than this is a jump (a bad estimate).
    pub max_plausible_rate_dps: f64,
    /// This many bit-identical inputs in a row (roll, pitch and deck height) are a frozen input:
    /// refused (`frozen-input`), and the history is learnt afresh once it moves again.
    pub frozen_input_count: u32,
    /// History used for the prediction (the autoregressive fit estimates its coefficients on
    /// all of it; the sinusoid fit wants about 40 s, a few periods).
    pub window_s: f64,
    /// No clearance before this much history: the wait after the deck comes into view. The
    /// autoregressive predictor fits a lower order on a short history and states the larger
    /// uncertainty that comes with it (the sinusoid fit wants about 20 s).
    pub min_history_s: f64,
    /// Refit the motion model this often (s).
    pub refit_interval_s: f64,
    /// `ar` (autoregressive, with the uncertainty it states: the default) or `sinusoids`
    /// (dominant sinusoids of the window with a held-out error bound: exact for a regular sea;
    /// use it with `window_s = 40`, `min_history_s = 20` and the margins 0.5 / 0.5 / 0.1).
    pub predictor: Predictor,
    /// Order of the autoregressive predictor (on a 5 Hz grid: 96 spans 19.2 s, about two roll
    /// periods); a shorter history, or one with gaps, fits a lower one. From twice the span of
    /// 48 lags the best linear forecast of a spectrum sea uses about 10 points more of the calm
    /// windows; fitted, order 96 used 41.0 -> 46.9 % of them on the development seas, and
    /// landed more often at sea state 6 (BENCHMARKS.md, "Forecasts from 19.2 s of lags").
    pub ar_order: usize,
    /// With a predictor that states its uncertainty (`ar`): the accepted probability that the
    /// deck leaves the capacity during one touchdown, bounded from above: for each of the six
    /// limits (roll, pitch, the tilt, the two rates, the heave rate) the largest probability,
    /// over the touchdown, that the forecast (mean and stated standard deviation) is beyond
    /// it, summed over the limits.
    pub risk_per_touchdown: f64,
    /// ... and once committed: the touchdown goes on while that probability, by the newest
    /// forecast, stays at or below this; above it, a go-around. Larger than
    /// `risk_per_touchdown`, so a commitment is not given up for a forecast that moved by a hair
    /// (a go-around has its own risks). 0.1: at 0.2 a held-out campaign's touchdown went on at
    /// a risk of 0.13 and met the deck at 0.606 m/s against 0.6; at 0.1 the development trials'
    /// go-arounds were unchanged (1 of 70 commits) and `decide-eval`'s went from 0.7 % to 1.8 %
    /// of its commits, at 0.05 to 2.8 % and 3.8 % (BENCHMARKS.md, "A rate's band cleared on
    /// only with misses of its own"; in 2026-11, with a coarser predictor, 0.05 sent 7.5 % of
    /// the trials' commits around).
    pub go_around_risk: f64,
    /// With `ar`: the risk a new clearance must meet instead of `risk_per_touchdown` for the
    /// first `early_window_s` after the decision could first clear (its warm-up over, its
    /// history restarted, or a touchdown gone around). The first clearance the band allows
    /// comes just under `risk_per_touchdown` and is marginal by construction; a few seconds
    /// later the sea often offers a deeper calm, and a touchdown cleared with room to spare
    /// is less often sent around at its last chance. 1e-4 over 15 s: held-out trials' go-arounds
    /// from 3.8 to 3.2 % of commits at 30 Hz and from 3.4 to 2.6 % at 10 Hz, the same landings,
    /// the median wait 1-3 s longer (BENCHMARKS.md, "A deeper calm for the first clearances");
    /// with an unreliable angle band widened too, 4.6 to 2.6 % at 10 Hz (BENCHMARKS.md,
    /// "Issue 33's bars on fresh seeds (2026-12-05, second session)").
    /// `early_window_s = 0` clears at `risk_per_touchdown` from the start.
    pub early_risk_per_touchdown: f64,
    /// How long `early_risk_per_touchdown` applies (s), from when the decision could first
    /// clear; at most `MAX_EARLY_WINDOW_S`.
    pub early_window_s: f64,
    /// Sinusoids per angle.
    pub components: usize,
    /// Samples weigh `exp(-age / fit_memory_s)` in the fit: the newest motion counts most.
    pub fit_memory_s: f64,
    /// Safety margin on the predicted angles to enter `ClearToLand` (deg), added to the
    /// prediction's error (its band, or the sinusoid fit's held-out bound). 0 by default: the
    /// band is the margin; a fixed one is for what the band does not know (an estimator bias).
    pub margin_deg: f64,
    /// The same for rates (deg/s).
    pub rate_margin_dps: f64,
    /// The same for the heave rate (m/s).
    pub heave_rate_margin_mps: f64,
    /// The autopilot's vertical-speed error (m/s, standard deviation; slow, so one value over a
    /// touchdown). The deck's height is the vehicle's less the camera's over the deck, so this
    /// error is a bias of the measured heave rate that the forecast's band, fitted to the
    /// measurements, cannot contain. With `ar` it is added to the heave rate's band in
    /// quadrature; 0 trusts the autopilot's vertical speed as exact
    /// ([`AUTOPILOT_VERTICAL_SPEED_ERROR_MPS`]).
    pub vertical_speed_error_mps: f64,
    /// The autopilot's roll and pitch error (deg, standard deviation; slow, so one value over a
    /// touchdown), with the camera's mounting calibration's. The deck's attitude is the
    /// camera's measurement composed with the vehicle's, so this error is a bias of the measured
    /// deck angles that the forecast's band, fitted to the measurements, cannot contain. With
    /// `ar` it is added to the roll and pitch bands in quadrature (tilt too); 0 trusts the
    /// autopilot's attitude as exact ([`AUTOPILOT_ATTITUDE_ERROR_DEG`]).
    pub vehicle_attitude_error_deg: f64,
    /// The prediction is unreliable if it misses the newest seconds of history by more.
    pub max_holdout_error_deg: f64,
    /// ... or the heave by more (m).
    pub max_holdout_error_m: f64,
    /// Seconds of history held out to measure the prediction error.
    pub holdout_s: f64,
    /// The prediction error bound is this factor times the largest held-out error of the last
    /// `error_memory_s` (the error of an irregular sea varies from minute to minute). 1.3: with
    /// 1.2, one clearance in 12 x 30 min of irregular sea overshot the roll limit by 0.05 deg at
    /// the end of its touchdown (BENCHMARKS.md, "Seas that are not the model").
    pub error_factor: f64,
    pub error_memory_s: f64,
    /// ... or if a new attitude is further than this from the model's value.
    pub max_innovation_deg: f64,
    /// ... or a new deck height (m).
    pub max_heave_innovation_m: f64,
    /// ... or if the model's rate differs from the measured rate by more than this (deg/s).
    pub max_rate_innovation_dps: f64,
    /// How far ahead calm windows are searched (s).
    pub horizon_s: f64,
    /// How long `Abort` is held.
    pub abort_hold_s: f64,
    /// A committed touchdown goes on through missing attitudes (no deck seen, no vehicle
    /// attitude to compensate with, no deck height, the gap they leave) for this long in a
    /// row (ms; 0: abort on the first), on the prediction the last good attitude confirmed,
    /// while that prediction keeps the deck within the capacity to the touchdown's end: at
    /// `go_around_risk` while more of the touchdown is left than of this budget, at
    /// `risk_per_touchdown` once the budget left reaches the touchdown's end (`ride-through`).
    /// The final metres of a descent are blind: the ring leaves a camera's view about 1 m over
    /// the deck (BENCHMARKS.md, "Closed-loop trials"). Never entered on such data, and never
    /// through a stale, frozen, jumping or unpredictable input.
    pub ride_through_ms: f64,
    /// How long before contact a go-around can no longer keep the vehicle off the deck (ms):
    /// the autopilot's reaction and the time to arrest the descent, the vehicle's own figure
    /// (descending at `v` m/s and climbing away at `a` m/s^2 after `r` s: about `r + v / (2 a)`
    /// of its descent is left to contact). The last decision that can act before that point
    /// (the next frame is expected after it, or a blind spell could reach it) judges the rest
    /// of the touchdown as a new clearance would (`risk_per_touchdown`), not at
    /// `go_around_risk`: no later frame can send it around. 350: a quadrotor descending at 1.6
    /// m/s that arrests at 4 m/s^2 (PX4's `MPC_ACC_UP_MAX`) after 0.1 s needs 0.3 s.
    pub no_return_ms: f64,
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
            max_age_ms: 300.0,
            max_gap_ms: 500.0,
            gap_recovery_s: 1.0,
            max_plausible_rate_dps: 40.0,
            frozen_input_count: 3,
            // The predictor's own (`with_predictor_defaults`, below).
            window_s: f64::NAN,
            min_history_s: f64::NAN,
            refit_interval_s: 1.0,
            predictor: Predictor::Ar,
            ar_order: 96,
            risk_per_touchdown: 1e-3,
            go_around_risk: 0.1,
            early_risk_per_touchdown: 1e-4,
            early_window_s: 15.0,
            components: 4,
            fit_memory_s: 10.0,
            margin_deg: f64::NAN,
            rate_margin_dps: f64::NAN,
            heave_rate_margin_mps: f64::NAN,
            vertical_speed_error_mps: AUTOPILOT_VERTICAL_SPEED_ERROR_MPS,
            vehicle_attitude_error_deg: AUTOPILOT_ATTITUDE_ERROR_DEG,
            max_holdout_error_deg: 2.0,
            max_holdout_error_m: 0.3,
            holdout_s: 2.0,
            error_factor: 1.3,
            error_memory_s: 30.0,
            max_innovation_deg: 1.0,
            max_heave_innovation_m: 0.2,
            max_rate_innovation_dps: 1.0,
            horizon_s: 20.0,
            abort_hold_s: 2.0,
            ride_through_ms: 1000.0,
            no_return_ms: 350.0,
        }
        .with_predictor_defaults(|_| false)
    }
}

/// The deck-motion predictor (`[decide] predictor`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Predictor {
    /// Autoregressive: follows an irregular sea, and states its uncertainty (a band that
    /// widens with the horizon, scaled by how well it held of late).
    Ar,
    /// Dominant sinusoids of the window: exact for a regular sea.
    Sinusoids,
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
fn invalid(key: &'static str, problem: impl Into<String>) -> InvalidField {
    InvalidField::new(key, problem)
}

/// The longest `early_window_s` (s): a vehicle over the deck has minutes of battery, and a
/// longer one is a mistake for `risk_per_touchdown`.
const MAX_EARLY_WINDOW_S: f64 = 120.0;

/// `vertical_speed_error_mps` by default (m/s): a GNSS-aided estimator's vertical-speed error,
/// a few cm/s and slow. With 0.05 m/s RMS of it and nothing to cover it, `decide-eval` cleared
/// unsafe touchdowns (BENCHMARKS.md, "The vehicle's height fused with the autopilot's vertical
/// speed"). An autopilot with a better vertical speed (RTK) may state less.
pub const AUTOPILOT_VERTICAL_SPEED_ERROR_MPS: f64 = 0.05;

/// `vehicle_attitude_error_deg` by default (deg): a GNSS-aided estimator's roll and pitch error
/// after its accelerometer biases are learnt, a few tenths of a degree and slow. With the
/// autopilot's roll and pitch biased by 0.3 deg, 5-7 % of `decide-eval`'s clearances had the
/// true roll or pitch beyond 3.09 of the forecast's deviations during the touchdown, against
/// 0.8-1.0 % with an exact autopilot (BENCHMARKS.md, "The autopilot's attitude error in the
/// angle bands"). An autopilot with a better attitude (a calibrated, quiet IMU) may state less.
pub const AUTOPILOT_ATTITUDE_ERROR_DEG: f64 = 0.2;

impl DecisionConfig {
    /// The naive baseline the state machine is measured against: the deck's current roll and
    /// pitch are within the capacity. It looks at one instant only; it is not a clearance.
    /// Non-finite angles are never within.
    pub fn naive_within(&self, roll_deg: f64, pitch_deg: f64) -> bool {
        roll_deg.abs() <= self.max_abs_roll_deg && pitch_deg.abs() <= self.max_abs_pitch_deg
    }

    /// The capacity's six limits in the order the envelope judges them
    /// (`LandingDecider::exceedance_risk`): roll, pitch, tilt (deg), roll rate, pitch rate
    /// (deg/s), heave rate (m/s).
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

    /// The sinusoid predictor with the settings it was measured with: a 40 s window, 20 s of
    /// warm-up, fixed margins on top of its held-out error bound.
    pub fn sinusoid_defaults() -> Self {
        Self {
            predictor: Predictor::Sinusoids,
            ..Self::default()
        }
        .with_predictor_defaults(|_| false)
    }

    /// The autoregressive predictor with the settings it was developed and measured with
    /// (BENCHMARKS.md, "Deck-motion prediction"): the defaults.
    pub fn ar_defaults() -> Self {
        Self::default()
    }

    /// This configuration with each key whose default depends on the predictor, unless `given`
    /// says it was set explicitly, at its own predictor's default: `predictor = "sinusoids"`
    /// alone in a file gives the sinusoid fit as it was measured. Those keys: an autoregressive
    /// fit wants a longer window and states its own band (no fixed margins); the sinusoid fit a
    /// shorter window, a longer warm-up and margins on its held-out error bound.
    pub fn with_predictor_defaults(mut self, given: impl Fn(&str) -> bool) -> Self {
        let (window_s, min_history_s, margin_deg, rate_margin_dps, heave_rate_margin_mps) =
            match self.predictor {
                Predictor::Ar => (120.0, 8.0, 0.0, 0.0, 0.0),
                Predictor::Sinusoids => (40.0, 20.0, 0.5, 0.5, 0.1),
            };
        for (key, field, value) in [
            ("window_s", &mut self.window_s, window_s),
            ("min_history_s", &mut self.min_history_s, min_history_s),
            ("margin_deg", &mut self.margin_deg, margin_deg),
            ("rate_margin_dps", &mut self.rate_margin_dps, rate_margin_dps),
            (
                "heave_rate_margin_mps",
                &mut self.heave_rate_margin_mps,
                heave_rate_margin_mps,
            ),
        ] {
            if !given(key) {
                *field = value;
            }
        }
        self
    }

    /// Checks every field; the error names it.
    pub fn validate(&self) -> Result<(), InvalidField> {
        let positive = [
            ("max_abs_roll_deg", self.max_abs_roll_deg),
            ("max_abs_pitch_deg", self.max_abs_pitch_deg),
            ("max_tilt_deg", self.max_tilt_deg),
            ("max_abs_roll_rate_dps", self.max_abs_roll_rate_dps),
            ("max_abs_pitch_rate_dps", self.max_abs_pitch_rate_dps),
            ("max_abs_heave_rate_mps", self.max_abs_heave_rate_mps),
            ("max_holdout_error_m", self.max_holdout_error_m),
            ("max_heave_innovation_m", self.max_heave_innovation_m),
            ("touchdown_s", self.touchdown_s),
            ("max_age_ms", self.max_age_ms),
            ("max_gap_ms", self.max_gap_ms),
            ("max_plausible_rate_dps", self.max_plausible_rate_dps),
            ("window_s", self.window_s),
            ("min_history_s", self.min_history_s),
            ("refit_interval_s", self.refit_interval_s),
            ("max_holdout_error_deg", self.max_holdout_error_deg),
            ("holdout_s", self.holdout_s),
            ("error_factor", self.error_factor),
            ("fit_memory_s", self.fit_memory_s),
            ("error_memory_s", self.error_memory_s),
            ("max_innovation_deg", self.max_innovation_deg),
            ("horizon_s", self.horizon_s),
            ("max_rate_innovation_dps", self.max_rate_innovation_dps),
        ];
        for (k, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(k, format!("must be positive, got {v}")));
            }
        }
        for (k, v) in [
            ("margin_deg", self.margin_deg),
            ("rate_margin_dps", self.rate_margin_dps),
            ("heave_rate_margin_mps", self.heave_rate_margin_mps),
            ("vertical_speed_error_mps", self.vertical_speed_error_mps),
            ("vehicle_attitude_error_deg", self.vehicle_attitude_error_deg),
            ("gap_recovery_s", self.gap_recovery_s),
            ("abort_hold_s", self.abort_hold_s),
            ("ride_through_ms", self.ride_through_ms),
            ("no_return_ms", self.no_return_ms),
            ("early_window_s", self.early_window_s),
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
        if self.error_factor < 1.0 {
            return Err(invalid(
                "error_factor",
                format!(
                    "must be at least 1 (below, the bound is smaller than the error it measured), got {}",
                    self.error_factor
                ),
            ));
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
        if self.horizon_s < self.touchdown_s {
            return Err(invalid(
                "horizon_s",
                format!(
                    "must be at least touchdown_s ({}): a calm window is a touchdown long",
                    self.touchdown_s
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
        if !(self.go_around_risk >= self.risk_per_touchdown && self.go_around_risk <= 0.5) {
            return Err(invalid(
                "go_around_risk",
                format!(
                    "must be in [risk_per_touchdown, 0.5] ([{}, 0.5]), got {}",
                    self.risk_per_touchdown, self.go_around_risk
                ),
            ));
        }
        if !(self.early_risk_per_touchdown > 1e-9 && self.early_risk_per_touchdown <= self.risk_per_touchdown)
        {
            return Err(invalid(
                "early_risk_per_touchdown",
                format!(
                    "must be in (1e-9, risk_per_touchdown] ((1e-9, {}]), got {}",
                    self.risk_per_touchdown, self.early_risk_per_touchdown
                ),
            ));
        }
        if !(self.early_window_s <= MAX_EARLY_WINDOW_S) {
            return Err(invalid(
                "early_window_s",
                format!(
                    "must be at most {MAX_EARLY_WINDOW_S} s, got {}",
                    self.early_window_s
                ),
            ));
        }
        if !(2..=100).contains(&self.ar_order) {
            return Err(invalid(
                "ar_order",
                format!("must be 2..=100, got {}", self.ar_order),
            ));
        }
        if !(1..=8).contains(&self.components) {
            return Err(invalid(
                "components",
                format!("must be 1..=8, got {}", self.components),
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
        if self.min_history_s > self.window_s {
            return Err(invalid("min_history_s", "must not exceed window_s"));
        }
        if self.holdout_s * 2.0 > self.min_history_s {
            return Err(invalid("holdout_s", "must be at most half of min_history_s"));
        }
        Ok(())
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
            "gap_recovery_s" => &mut self.gap_recovery_s,
            "max_plausible_rate_dps" => &mut self.max_plausible_rate_dps,
            "window_s" => &mut self.window_s,
            "min_history_s" => &mut self.min_history_s,
            "refit_interval_s" => &mut self.refit_interval_s,
            "risk_per_touchdown" => &mut self.risk_per_touchdown,
            "fit_memory_s" => &mut self.fit_memory_s,
            "max_holdout_error_deg" => &mut self.max_holdout_error_deg,
            "max_holdout_error_m" => &mut self.max_holdout_error_m,
            "holdout_s" => &mut self.holdout_s,
            "error_factor" => &mut self.error_factor,
            "error_memory_s" => &mut self.error_memory_s,
            "max_innovation_deg" => &mut self.max_innovation_deg,
            "max_heave_innovation_m" => &mut self.max_heave_innovation_m,
            "max_rate_innovation_dps" => &mut self.max_rate_innovation_dps,
            "horizon_s" => &mut self.horizon_s,
            "abort_hold_s" => &mut self.abort_hold_s,
            "ride_through_ms" => &mut self.ride_through_ms,
            _ => return None,
        })
    }
}

/// The largest value each key may take, and why: no configuration may switch a safety check off
/// by making it unreachable. Capacities: what a small quadrotor's gear could take at most (a
/// ship helicopter's deck limits are 3-8 deg and about 1 m/s); check thresholds: a few times
/// their defaults, far beyond which they no longer catch what they are for.
pub const SAFETY_BOUNDS: &[(&str, f64, &str)] = &[
    ("max_abs_roll_deg", 15.0, "no landing gear takes a steeper deck"),
    ("max_abs_pitch_deg", 15.0, "no landing gear takes a steeper deck"),
    ("max_tilt_deg", 20.0, "no landing gear takes a steeper deck"),
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
        3.0,
        "a deck rising faster strikes the gear",
    ),
    ("touchdown_s", 30.0, "a touchdown is seconds long"),
    ("max_age_ms", 1000.0, "older attitudes are stale"),
    ("max_gap_ms", 2000.0, "a longer pause in the attitudes is a gap"),
    ("gap_recovery_s", 600.0, "a duration"),
    (
        "max_plausible_rate_dps",
        120.0,
        "a faster change is a bad estimate, not a deck",
    ),
    ("window_s", 600.0, "a duration"),
    ("min_history_s", 600.0, "a duration"),
    (
        "refit_interval_s",
        10.0,
        "a model older than this follows a sea no longer",
    ),
    (
        "risk_per_touchdown",
        0.01,
        "one touchdown in a hundred is not a safe clearance",
    ),
    ("fit_memory_s", 3600.0, "a duration"),
    (
        "max_holdout_error_deg",
        10.0,
        "a larger miss is an unreliable prediction",
    ),
    (
        "max_holdout_error_m",
        1.5,
        "a larger miss is an unreliable prediction",
    ),
    ("holdout_s", 300.0, "a duration"),
    ("error_factor", 10.0, "a bound"),
    ("error_memory_s", 3600.0, "a duration"),
    (
        "max_innovation_deg",
        5.0,
        "a larger surprise is a model that missed",
    ),
    (
        "max_heave_innovation_m",
        1.0,
        "a larger surprise is a model that missed",
    ),
    (
        "max_rate_innovation_dps",
        10.0,
        "a larger surprise is a model that missed",
    ),
    ("horizon_s", 600.0, "a duration"),
    ("abort_hold_s", 600.0, "a duration"),
    (
        "ride_through_ms",
        2000.0,
        "longer blind is not riding through, it is flying blind",
    ),
];

/// At most this many bit-identical inputs in a row before they count as a frozen input.
pub const MAX_FROZEN_INPUT_COUNT: u32 = 30;
