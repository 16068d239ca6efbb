//! `[decide.forecast]`: which forecaster the decision uses and its tuning, one table per kind
//! (`kind = "ar"`, the autoregression, is the one there is). These keys are a forecaster's
//! tuning, measured on the development seas; an operator states the capacity, the risk and the
//! autopilot in `[decide]` ([`super::DecisionConfig`]).

use super::config::{invalid, DecisionConfig};
use deckwatch_common::InvalidField;
use serde::{Deserialize, Serialize};

/// The forecaster (`[decide.forecast]`, tagged by `kind`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ForecastConfig {
    /// Autoregressive: one linear recursion per channel on the recent history; follows an
    /// irregular sea and states its uncertainty (a band that widens with the horizon).
    Ar(ArForecastConfig),
}

impl Default for ForecastConfig {
    fn default() -> Self {
        Self::Ar(ArForecastConfig::default())
    }
}

/// The autoregressive forecaster's tuning (`[decide.forecast] kind = "ar"`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ArForecastConfig {
    /// Lags of each recursion, on a 5 Hz grid: 96 span 19.2 s, about two roll periods; a
    /// shorter history, or one with gaps, fits a lower order. Against 48 lags, 96 used 41.0 ->
    /// 46.9 % of the calm windows on the development seas and landed more often at sea state 6
    /// (docs/history.md).
    pub order: usize,
    /// Lags of the other channels each channel's recursion may read (on the same grid; at
    /// most `order`; 0: every channel alone). A channel keeps them only where they explain
    /// more than their number costs (docs/ALGORITHMS.md, "The joint autoregression").
    pub cross_order: usize,
    /// History the fit estimates its coefficients on (s). 97 coefficients on 120 s (600 rows on
    /// the 5 Hz grid) carry enough of their own error to widen the band; 240 s used 40.7 -> 42.9 %
    /// of the calm windows on the development ship-motion files. With the channels reading one
    /// another the cross lags want more rows: 600 s used 45.6 -> 48.2 % there (sea state 6: 30.2
    /// -> 35.8 %; go-arounds held out 124 -> 147 of 21 512 commits), and since the joint fit's
    /// blocks are built from lagged products its refit costs less than 240 s's did before
    /// (docs/history.md, "A 600 s fit window"). It matters only after that long over the deck:
    /// an approach that lands within two minutes has less history than either.
    pub window_s: f64,
    /// No clearance before this much history: the wait after the deck comes into view (s). A
    /// short history fits a lower order and states the larger uncertainty that comes with it.
    pub min_history_s: f64,
    /// Refit the forecast this often (s); in between it is run forward from each new sample.
    pub refit_interval_s: f64,
    /// Each fit is judged on the samples of this many seconds after it: its held-out misses
    /// calibrate the band, and after a measurement the forecast did not explain no new
    /// clearance comes for this long.
    pub holdout_s: f64,
    /// How far ahead calm windows are searched (s).
    pub horizon_s: f64,
    /// After a gap, no clearance for this long (s): the forecast's band carries the gap's
    /// unmeasured lags itself.
    pub gap_recovery_s: f64,
    /// The forecast is wrong if a new attitude is further than this from it (deg) and than 4 of
    /// its calibrated deviations...
    pub max_innovation_deg: f64,
    /// ... or a new deck height (m)...
    pub max_heave_innovation_m: f64,
    /// ... or if its rate differs from the measured rate by more than this (deg/s).
    pub max_rate_innovation_dps: f64,
    /// The risk a new clearance must meet instead of `risk_per_touchdown` for the first
    /// `early_window_s` after the decision could first clear (its warm-up over, its history
    /// restarted, or a touchdown gone around). The first clearance the band allows comes just
    /// under `risk_per_touchdown` and is marginal by construction; a few seconds later the sea
    /// often offers a deeper calm, and a touchdown cleared with room to spare is less often
    /// sent around at its last chance. 1e-4 over 15 s: held-out trials' go-arounds from 3.8 to
    /// 3.2 % of commits at 30 Hz and from 3.4 to 2.6 % at 10 Hz, the same landings, the median
    /// wait 1-3 s longer (docs/history.md).
    pub early_risk_per_touchdown: f64,
    /// How long `early_risk_per_touchdown` applies (s; 0: never), from when the decision could
    /// first clear; at most [`MAX_EARLY_WINDOW_S`].
    pub early_window_s: f64,
}

impl Default for ArForecastConfig {
    fn default() -> Self {
        Self {
            order: 96,
            cross_order: 24,
            window_s: 600.0,
            min_history_s: 8.0,
            refit_interval_s: 1.0,
            holdout_s: 2.0,
            horizon_s: 20.0,
            gap_recovery_s: 1.0,
            max_innovation_deg: 1.0,
            max_heave_innovation_m: 0.2,
            max_rate_innovation_dps: 1.0,
            early_risk_per_touchdown: 1e-4,
            early_window_s: 15.0,
        }
    }
}

/// The longest `early_window_s` (s): a vehicle over the deck has minutes of battery, and a
/// longer one is a mistake for `risk_per_touchdown`.
pub const MAX_EARLY_WINDOW_S: f64 = 120.0;

/// The largest value each `[decide.forecast]` key may take, and why (see
/// [`super::SAFETY_BOUNDS`]).
pub const FORECAST_SAFETY_BOUNDS: &[(&str, f64, &str)] = &[
    ("window_s", 1800.0, "a duration"),
    ("min_history_s", 600.0, "a duration"),
    (
        "refit_interval_s",
        10.0,
        "a model older than this follows a sea no longer",
    ),
    ("holdout_s", 300.0, "a duration"),
    ("horizon_s", 600.0, "a duration"),
    ("gap_recovery_s", 600.0, "a duration"),
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
];

impl ArForecastConfig {
    /// A numeric key of [`FORECAST_SAFETY_BOUNDS`] (None for any other).
    pub fn field_mut(&mut self, key: &str) -> Option<&mut f64> {
        Some(match key {
            "window_s" => &mut self.window_s,
            "min_history_s" => &mut self.min_history_s,
            "refit_interval_s" => &mut self.refit_interval_s,
            "holdout_s" => &mut self.holdout_s,
            "horizon_s" => &mut self.horizon_s,
            "gap_recovery_s" => &mut self.gap_recovery_s,
            "max_innovation_deg" => &mut self.max_innovation_deg,
            "max_heave_innovation_m" => &mut self.max_heave_innovation_m,
            "max_rate_innovation_dps" => &mut self.max_rate_innovation_dps,
            _ => return None,
        })
    }

    /// Checks every key, against the rest of `[decide]` where they meet; the error names the
    /// key as `forecast.KEY`.
    pub(super) fn validate(&self, decide: &DecisionConfig) -> Result<(), InvalidField> {
        let key = |k: &str| format!("forecast.{k}");
        for (k, v) in [
            ("window_s", self.window_s),
            ("min_history_s", self.min_history_s),
            ("refit_interval_s", self.refit_interval_s),
            ("holdout_s", self.holdout_s),
            ("horizon_s", self.horizon_s),
            ("max_innovation_deg", self.max_innovation_deg),
            ("max_heave_innovation_m", self.max_heave_innovation_m),
            ("max_rate_innovation_dps", self.max_rate_innovation_dps),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(key(k), format!("must be positive, got {v}")));
            }
        }
        for (k, v) in [
            ("gap_recovery_s", self.gap_recovery_s),
            ("early_window_s", self.early_window_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(key(k), format!("must be >= 0, got {v}")));
            }
        }
        let mut fields = self.clone();
        for &(k, max, why) in FORECAST_SAFETY_BOUNDS {
            let v = fields.field_mut(k).map_or(f64::NAN, |v| *v);
            if !(v <= max) {
                return Err(invalid(key(k), format!("must be at most {max} ({why}), got {v}")));
            }
        }
        if self.horizon_s < decide.touchdown_s {
            return Err(invalid(
                "forecast.horizon_s",
                format!(
                    "must be at least touchdown_s ({}): a calm window is a touchdown long",
                    decide.touchdown_s
                ),
            ));
        }
        if !(self.early_risk_per_touchdown > 1e-9
            && self.early_risk_per_touchdown <= decide.risk_per_touchdown)
        {
            return Err(invalid(
                "forecast.early_risk_per_touchdown",
                format!(
                    "must be in (1e-9, risk_per_touchdown] ((1e-9, {}]), got {}",
                    decide.risk_per_touchdown, self.early_risk_per_touchdown
                ),
            ));
        }
        if !(self.early_window_s <= MAX_EARLY_WINDOW_S) {
            return Err(invalid(
                "forecast.early_window_s",
                format!(
                    "must be at most {MAX_EARLY_WINDOW_S} s, got {}",
                    self.early_window_s
                ),
            ));
        }
        if !(2..=100).contains(&self.order) {
            return Err(invalid(
                "forecast.order",
                format!("must be 2..=100, got {}", self.order),
            ));
        }
        if self.cross_order > self.order {
            return Err(invalid(
                "forecast.cross_order",
                format!("must be at most order ({}), got {}", self.order, self.cross_order),
            ));
        }
        if self.min_history_s > self.window_s {
            return Err(invalid("forecast.min_history_s", "must not exceed window_s"));
        }
        if self.holdout_s * 2.0 > self.min_history_s {
            return Err(invalid(
                "forecast.holdout_s",
                "must be at most half of min_history_s",
            ));
        }
        Ok(())
    }
}
