//! The calibrated forecast the decision judges by ([`Models`]: one fitted forecast per channel
//! and how far its stated band is to be trusted), and the forecast's upkeep ([`Tracking`]):
//! when to refit, running it forward from each new sample, checking each measurement against
//! it, and the holds after a gap or a measurement it did not explain.

use super::band::{BandCalibration, BandScale, MAX_BAND_SCALE, RATE_CHECK_HALF_WINDOW_S, SUSPECT_BAND_SCALE};
use super::coverage::BandCoverage;
use super::history::{History, FIT_SPACING_S};
use super::rate_history::{rate_histories, RateHistory};
use super::{DecisionConfig, DeckForecast, HEAVE, PITCH, ROLL, Z95};
use crate::forecast::{ChannelForecast, Forecaster};
use deckwatch_common::messages::DecisionReason;
use std::collections::VecDeque;

/// A measurement this many of the model's calibrated standard deviations away is an innovation
/// the model does not explain.
const INNOVATION_Z: f64 = 4.0;
/// The model's heave rate must match the measured one within this (m/s).
const MAX_HEAVE_RATE_INNOVATION_MPS: f64 = 0.2;
/// After a model misses, the next refit comes this soon (s).
const RETRY_S: f64 = 0.3;
/// The measured rate is checked against the model's at most this often (s): the measured rate
/// hardly changes from one frame to the next, while the model's, re-forecast from the newest
/// noisy lags on every frame, is a fresh draw of its noise. Checked on every frame at 30 Hz, a
/// pitch rate the deck did not have was "unexplained" five times as often per second as at 10
/// Hz.
const RATE_CHECK_INTERVAL_S: f64 = 0.1;
/// The rate the model's is checked against: a parabola's slope at the newest sample, through
/// the samples of this many seconds. A line's slope is the rate at the samples' mean time, and
/// carrying the model's rate back there by the model's own acceleration put the newest noisy
/// lag into the comparison twice over: at 30 Hz the check fired 27 times as often as at 10 Hz
/// on the development seas, the model's rate no worse.
const RATE_CHECK_WINDOW_S: f64 = 0.9;

/// The forecast of every channel in use, with its band's calibration.
#[derive(Debug, Clone)]
pub(super) struct Models<C> {
    /// One per channel in use.
    pub(super) forecasts: Vec<C>,
    /// Per channel: what the forecaster's stated standard deviation is multiplied by so that
    /// its band held what happened (`MIN_VALUE_BAND_SCALE` or more; see
    /// [`BandCalibration::scale`]).
    pub(super) band_scale: [f64; 3],
    /// The same for each channel's rate (1 or more).
    pub(super) rate_band_scale: [f64; 3],
    /// Per channel, its value's scale as the guards read it (`BandScale::value_guards`; 1 or
    /// more): a measurement unexplained, a band suspect or unreliable, an unreliable angle
    /// widened, a rate taken as far off as its value. `band_scale` is the band's width only:
    /// judged on it (down to 0.7, the rate bands then at 95 % too), 4 211 frames of the
    /// development files were held as unexplained against 2 204 on this; and a band read at
    /// 3.4 before would read about 3, no longer unreliable (the 95th percentile of a normal's
    /// misses is 0.875 of its 97.5th).
    pub(super) guard_scale: [f64; 3],
    /// Per channel, the spread of its rate's recent held-out misses in its own unit, whatever
    /// each fit stated (NaN without the evidence): the least deviation its forecast is given.
    pub(super) rate_miss_std: [f64; 3],
    /// Every channel's band, value and rate, has been checked against what followed.
    pub(super) band_checked: bool,
    /// Per channel, what its history alone says of its rate to come (no model).
    pub(super) rate_history: [RateHistory; 3],
    /// Per quantity (roll, pitch, heave, their rates), what the touchdowns judged so far say the
    /// band is further to be widened by ([`BandCoverage`]; 1 or more).
    pub(super) widening: [f64; 6],
}

impl<C: ChannelForecast> Models<C> {
    /// Whether channel `k`'s band, value or rate, has been measured more than `MAX_BAND_SCALE`
    /// times too narrow: its stated deviations are not the forecast's error.
    pub(super) fn band_unreliable(&self, k: usize) -> bool {
        self.widest_band_scale(k) > MAX_BAND_SCALE
    }

    /// How many times too narrow channel `k`'s band has been measured, its value's or its
    /// rate's, whichever is more.
    fn widest_band_scale(&self, k: usize) -> f64 {
        self.guard_scale[k].max(self.rate_band_scale[k])
    }

    /// Whether channel `k`'s band is suspect: measured more than `SUSPECT_BAND_SCALE` times too
    /// narrow (value or rate) but not yet unreliable, and its rate without misses of its own to
    /// stand for its error. A few more misses make it unreliable, and its rate is then judged by
    /// its history as well: a new clearance must hold so judged too.
    pub(super) fn band_suspect(&self, k: usize) -> bool {
        self.judged_by_history_above(k, SUSPECT_BAND_SCALE) && !self.judged_by_history(k)
    }

    /// Whether channel `k`'s rate is also judged as its history alone forecasts it
    /// ([`RateHistory`]): its band is unreliable and its rate's own misses are not yet measured.
    pub(super) fn judged_by_history(&self, k: usize) -> bool {
        self.judged_by_history_above(k, MAX_BAND_SCALE)
    }

    /// The same with the band taken as unreliable beyond `unreliable_scale` (a clearance's
    /// judgement of a suspect band, `Judgement::unreliable_band_scale`).
    pub(super) fn judged_by_history_above(&self, k: usize, unreliable_scale: f64) -> bool {
        k < self.forecasts.len()
            && self.widest_band_scale(k) > unreliable_scale
            && !self.rate_miss_std[k].is_finite()
    }

    /// The standard deviation the decision gives channel `k`'s rate at `t`: the stated one
    /// scaled by how honest it has been; for a channel whose band is unreliable, never less
    /// than the spread of the rate's recent misses in its own unit. A nearly noise-free
    /// measurement (the camera's deck height) lets the autoregressive fit state deviations of
    /// millimetres per second, 4 to 80 times short of its misses and varying from fit to fit;
    /// the misses themselves do not depend on what each fit stated.
    pub(super) fn rate_std(&self, k: usize, t: f64) -> f64 {
        self.rate_std_judging(k, t, false)
    }

    /// [`Self::rate_std`], with `as_value` (a new commitment's `Judgement::rate_as_value`) the
    /// rate of a channel whose band is unreliable scaled at least as much as its value's band:
    /// one model states both, from one innovation, and a value that missed by 15 of its
    /// deviations says its rate may too. The spread of its misses stays the floor.
    pub(super) fn rate_std_judging(&self, k: usize, t: f64, as_value: bool) -> f64 {
        let unreliable = self.band_unreliable(k);
        // Each band widened by its own touchdowns' coverage, then compared.
        let rate_scale = self.widening[3 + k] * self.rate_band_scale[k];
        let scale = match unreliable && as_value {
            true => rate_scale.max(self.widening[k] * self.guard_scale[k]),
            false => rate_scale,
        };
        let scaled = scale * self.forecasts[k].rate_std(t);
        if unreliable {
            scaled.max(self.rate_miss_std[k])
        } else {
            scaled
        }
    }

    /// Whether measurement `sample` at `t` is further from the forecast than the configured
    /// limits and than `INNOVATION_Z` of its calibrated deviations: the forecast is wrong.
    pub(super) fn misses(&self, c: &DecisionConfig, t: f64, sample: &[f64; 3]) -> bool {
        let f = c.ar();
        let outside = |k: usize, limit: f64| {
            let track = &self.forecasts[k];
            (track.value(t) - sample[k]).abs() > limit.max(INNOVATION_Z * self.guard_scale[k] * track.std(t))
        };
        outside(ROLL, f.max_innovation_deg)
            || outside(PITCH, f.max_innovation_deg)
            || (self.forecasts.len() > HEAVE && outside(HEAVE, f.max_heave_innovation_m))
    }

    /// The standard deviation the decision gives channel `k`'s value at `t` (before the
    /// autopilot's errors): the stated one, scaled by the held-out misses and widened by the
    /// touchdowns judged.
    pub(super) fn value_std(&self, k: usize, t: f64) -> f64 {
        self.widening[k] * self.band_scale[k] * self.forecasts[k].std(t)
    }

    /// [`Self::value_std`] with the value's scale as the guards read it (`guard_scale`, at least
    /// the band's width): the deviation of an angle whose band is unreliable.
    pub(super) fn guarded_value_std(&self, k: usize, t: f64) -> f64 {
        self.widening[k] * self.guard_scale[k] * self.forecasts[k].std(t)
    }

    /// The forecast at `t` as the decision judges it: values, rates and their 95 % bands (NaN
    /// for a channel not predicted).
    pub(super) fn deck_forecast(&self, t: f64) -> DeckForecast {
        let mut f = DeckForecast {
            value: [f64::NAN; 3],
            rate: [f64::NAN; 3],
            band95: [f64::NAN; 3],
            rate_band95: [f64::NAN; 3],
        };
        for (k, track) in self.forecasts.iter().enumerate() {
            f.value[k] = track.value(t);
            f.rate[k] = track.rate(t);
            f.band95[k] = Z95 * self.value_std(k, t);
            f.rate_band95[k] = Z95 * self.rate_std(k, t);
        }
        f
    }
}

/// The forecast's upkeep: the fitted models, the fits kept to be judged on what came after
/// them, the band's calibration, and the times that schedule refits and hold clearances.
#[derive(Debug, Clone)]
pub(super) struct Tracking<F: Forecaster> {
    pub(super) forecaster: F,
    pub(super) models: Option<Models<F::Channel>>,
    /// Earlier fits (newest last), to measure how well they predicted what came after.
    pub(super) past: VecDeque<Vec<F::Channel>>,
    pub(super) band: BandCalibration,
    pub(super) coverage: BandCoverage,
    /// When the forecast was last fitted (s).
    pub(super) last_fit: f64,
    /// No clearance before this (s): the recovery after a gap.
    pub(super) gap_until: f64,
    /// When a measurement the model did not explain came (s).
    pub(super) unexplained_at: f64,
    /// When the measured rate was last checked against the model's (`RATE_CHECK_INTERVAL_S`).
    pub(super) rate_checked_at: f64,
}

impl<F: Forecaster> Tracking<F> {
    pub(super) fn new(forecaster: F) -> Self {
        Self {
            forecaster,
            models: None,
            past: VecDeque::new(),
            band: BandCalibration::default(),
            coverage: BandCoverage::default(),
            last_fit: f64::NEG_INFINITY,
            gap_until: f64::NEG_INFINITY,
            unexplained_at: f64::NEG_INFINITY,
            rate_checked_at: f64::NEG_INFINITY,
        }
    }

    /// Forgets the models, their track record and the holds: what follows is learnt afresh.
    pub(super) fn forget(&mut self) {
        self.models = None;
        self.past.clear();
        self.band.clear();
        self.coverage.forget_pending();
        self.unexplained_at = f64::NEG_INFINITY;
        self.rate_checked_at = f64::NEG_INFINITY;
        // A gap on the old timeline (say, to a time in the future) means nothing on the new one.
        self.gap_until = f64::NEG_INFINITY;
    }

    /// The warm-up is not over: no models, no track record (the holds stay).
    pub(super) fn warming_up(&mut self) {
        self.models = None;
        self.past.clear();
        self.band.clear();
    }

    /// A gap in the samples, from `before` to `t` (s): no clearance for `gap_recovery_s`. The
    /// hold after an unexplained measurement (`holdout_s`) waits for the new model's band to be
    /// checked, and only measurements check it: what the gap took of the hold is held after
    /// it. A 3 s frozen camera right after a miss let a clearance through 0.2 s after the gap on
    /// a heave-rate band of 0.05 m/s that the deck then left by 0.3 m/s.
    pub(super) fn gap(&mut self, c: &DecisionConfig, before: f64, t: f64) {
        let f = c.ar();
        self.gap_until = t + f.gap_recovery_s;
        let held_s = before - self.unexplained_at;
        if held_s < f.holdout_s {
            self.unexplained_at = t - held_s.max(0.0);
        }
    }

    /// Whether the measured rate (a parabola through the newest samples) is checked now, and if
    /// so whether it differs from the model's by more than the configured limits and
    /// `INNOVATION_Z` of the model's rate deviation scaled as its value's: a fit that turns the
    /// motion around where the deck does not is caught here. Judged on the value's scale (1 or
    /// more), not the rate band's own: the measured rate has its noise too (with the rate
    /// band's scale, six times as many frames were "unexplained" on the development seas).
    pub(super) fn rate_unexplained(&mut self, c: &DecisionConfig, history: &History, t: f64) -> bool {
        let Some(m) = self.models.as_ref() else {
            return false;
        };
        let due = t - self.rate_checked_at >= RATE_CHECK_INTERVAL_S - 1e-6;
        let Some(rates) = history.parabola_rate_now(t, RATE_CHECK_WINDOW_S).filter(|_| due) else {
            return false;
        };
        self.rate_checked_at = t;
        let outside = |k: usize, limit: f64| {
            let track = &m.forecasts[k];
            (track.rate(t) - rates[k]).abs() > limit.max(INNOVATION_Z * m.guard_scale[k] * track.rate_std(t))
        };
        let max_rate_innovation_dps = c.ar().max_rate_innovation_dps;
        outside(ROLL, max_rate_innovation_dps)
            || outside(PITCH, max_rate_innovation_dps)
            || (m.forecasts.len() > HEAVE && outside(HEAVE, MAX_HEAVE_RATE_INNOVATION_MPS))
    }

    /// The forecast's verdict on the newest sample (`t`, `sample`, already in `history`): Err
    /// during the recovery after a gap, during the warm-up, or when the forecast (refitted if
    /// due) does not explain it; else the forecast is run forward from it. `committed`: a
    /// committed touchdown is under way at `t`.
    pub(super) fn check(
        &mut self,
        c: &DecisionConfig,
        history: &History,
        channels: usize,
        t: f64,
        sample: &[f64; 3],
        committed: bool,
    ) -> Result<(), DecisionReason> {
        let f = c.ar();
        self.coverage
            .judge(history, c.touchdown_s, RATE_CHECK_HALF_WINDOW_S);
        if let Some(m) = self.models.as_mut() {
            m.widening = self.coverage.widening();
        }
        if t < self.gap_until {
            // Still a measurement: one the model misses is not a gap to ride through.
            if self.models.as_ref().is_some_and(|m| m.misses(c, t, sample)) {
                return Err(DecisionReason::PredictionUnreliable);
            }
            return Err(DecisionReason::Gap);
        }
        if history.span_to(t) < f.min_history_s {
            self.warming_up();
            return Err(DecisionReason::Warmup);
        }
        if self.models.is_none() || t - self.last_fit >= f.refit_interval_s {
            self.refit(c, history, channels, t);
        }
        let m = self.models.as_ref().ok_or(DecisionReason::PredictionUnreliable)?;
        let missed = m.misses(c, t, sample);
        if missed || self.rate_unexplained(c, history, t) {
            return self.unexplained(c, history, channels, t, committed);
        }
        self.advance(history);
        self.state_touchdown(c, t);
        Ok(())
    }

    /// States the touchdown from `t` as the forecast now sees it, for [`BandCoverage`] to judge
    /// once it has come.
    fn state_touchdown(&mut self, c: &DecisionConfig, t: f64) {
        if let Some(m) = self.models.as_ref() {
            self.coverage.state(t, c.touchdown_s, |tk| m.deck_forecast(tk));
        }
    }

    /// A measurement the model does not explain. Not committed: the prediction is unreliable
    /// (refit soon). During a committed touchdown a difference between model and measurement is
    /// no reason to go around by itself: the model is refitted now, on the history that
    /// includes the measurement, and the touchdown goes on only if that model keeps the deck
    /// within its band to contact (the commitment's judgement).
    fn unexplained(
        &mut self,
        c: &DecisionConfig,
        history: &History,
        channels: usize,
        t: f64,
        committed: bool,
    ) -> Result<(), DecisionReason> {
        self.unexplained_at = t;
        if !committed {
            self.refit_soon(c, t);
            return Err(DecisionReason::PredictionUnreliable);
        }
        self.refit(c, history, channels, t);
        if self.models.is_none() {
            return Err(DecisionReason::PredictionUnreliable);
        }
        self.advance(history);
        Ok(())
    }

    /// The model missed: refit within `RETRY_S` (not at once: a refit every frame would cost
    /// milliseconds per decision while the motion is unpredictable).
    pub(super) fn refit_soon(&mut self, c: &DecisionConfig, t: f64) {
        self.last_fit = self.last_fit.min(t - c.ar().refit_interval_s + RETRY_S);
    }

    /// Fits the models now, on the history up to its newest sample (`t`).
    pub(super) fn refit(&mut self, c: &DecisionConfig, history: &History, channels: usize, t: f64) {
        self.last_fit = t;
        self.models = self.fit(c, history, channels);
    }

    /// One forecast per channel on the thinned samples `t`, `y` (the first `t.len()` of each),
    /// forecasting `horizon_s`; None when a channel cannot be fitted.
    fn fit_channels(&self, t: &[f64], y: &[Vec<f64>], horizon_s: f64) -> Option<Vec<F::Channel>> {
        let y: Vec<&[f64]> = y.iter().map(|yk| &yk[..t.len()]).collect();
        self.forecaster
            .fit(t, &y, horizon_s)
            .filter(|f| f.len() == y.len())
    }

    fn fit(&mut self, c: &DecisionConfig, history: &History, channels: usize) -> Option<Models<F::Channel>> {
        let f = c.ar();
        let thinned = history.thinned(channels);
        let (t, y) = (&thinned.t, &thinned.y);
        let end = *t.last()?;
        let forecasts = self.fit_channels(t, y, f.horizon_s + c.touchdown_s + f.holdout_s)?;
        // How the fits of `holdout_s` ago fared on the samples since, in their own stated
        // standard deviations: how honest their band has been. Checked once the rates of the
        // whole held-out span are measured too (a second of samples centred on each): checked
        // at `holdout_s`, a fit refitted every second was 2.0 s old, and its rates' misses came
        // only when a frame's rounding made it the one 3 s old (the heave rate had 12 misses
        // where its value had 20).
        let banded_span_s = f.holdout_s + RATE_CHECK_HALF_WINDOW_S;
        let old_banded = self.past.iter().rev().find(|m| end - m[0].t0() >= banded_span_s);
        if let Some(old) = old_banded.filter(|old| old[0].std(old[0].t0()) > 0.0) {
            let found = BandCalibration::misses_of(old, history, f.holdout_s);
            self.band.misses.extend(found);
        } else {
            // No fit old enough to have been checked yet (the first `holdout_s` after a
            // warm-up): the band is checked on fits the decider would have made earlier.
            let mut band = std::mem::take(&mut self.band);
            let fits_until = |n: usize, horizon_s: f64| self.fit_channels(&t[..n], y, horizon_s);
            band.backtest(fits_until, t, end, history, f.holdout_s, c.touchdown_s);
            self.band = band;
        }
        self.band.forget_before(end);
        let BandScale {
            values: band_scale,
            rates: rate_band_scale,
            value_guards: guard_scale,
            rate_miss_std,
            checked: band_checked,
        } = self.band.scale(channels);
        self.past.push_back(forecasts.clone());
        // Kept until checked: the band's check wants them `banded_span_s` old.
        while self
            .past
            .front()
            .is_some_and(|m| end - m[0].t0() > banded_span_s + 2.0 * f.refit_interval_s)
        {
            self.past.pop_front();
        }
        let mut models = Models {
            forecasts,
            band_scale,
            rate_band_scale,
            guard_scale,
            rate_miss_std,
            band_checked,
            rate_history: std::array::from_fn(|_| RateHistory::unknown()),
            widening: self.coverage.widening(),
        };
        // Regressed only where it is used, as far ahead as a model is used for: its age at most
        // (a refit interval) and a touchdown. Every channel's regressed cost the slowest
        // decision of a second 5-11 % more.
        let regressed_s = std::array::from_fn(|k| {
            if models.judged_by_history(k) || models.band_suspect(k) {
                f.refit_interval_s + c.touchdown_s
            } else {
                0.0
            }
        });
        models.rate_history = rate_histories(t, y, regressed_s);
        Some(models)
    }

    /// Runs the models forward from the newest samples (the coefficients and the stated
    /// variance stay those of the last fit): the forecast starts from the deck as just
    /// measured, not as it was at the last refit.
    pub(super) fn advance(&mut self, history: &History) {
        let span_s = self.forecaster.state_span_s();
        let Some(m) = self.models.as_mut() else { return };
        let Some((newest, _)) = history.newest() else {
            return;
        };
        let samples = &history.samples;
        let recent = samples
            .iter()
            .rev()
            .take_while(|h| newest - h.0 <= span_s)
            .count();
        let start = samples.len() - recent;
        let t: Vec<f64> = samples.range(start..).map(|h| h.0).collect();
        let y: Vec<Vec<f64>> = (0..m.forecasts.len())
            .map(|k| samples.range(start..).map(|h| h.1[k]).collect())
            .collect();
        let y: Vec<&[f64]> = y.iter().map(Vec::as_slice).collect();
        self.forecaster.advance_all(&mut m.forecasts, &t, &y);
        // The history's forecast of each rate starts from the newest rate too, measured as its
        // regression's were: across two fit spacings (a gap leaves the fit's).
        let newest_sample = history.newest();
        let span_s = 2.0 * FIT_SPACING_S;
        let before = samples
            .iter()
            .rev()
            .find(|h| newest - h.0 >= span_s - 1e-6)
            .copied();
        if let (Some(new), Some(old)) = (newest_sample, before) {
            if new.0 - old.0 <= 2.0 * span_s {
                for (k, h) in m.rate_history.iter_mut().enumerate() {
                    h.measured(old.0, old.1[k], new.0, new.1[k]);
                }
            }
        }
    }
}
