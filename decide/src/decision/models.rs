//! The deck-motion models the decision predicts with: their fit on the recent history (a
//! sinusoid fit or an autoregressive model per channel), how far each is advanced, and the
//! calibration of their stated bands by their own held-out misses.

use super::*;
use deckwatch_common::stats::{chi_square_quantile, normal_quantile};

#[derive(Debug, Clone)]
pub(super) struct Models {
    /// One per channel in use.
    pub(super) tracks: Vec<Track>,
    /// Bound on the prediction error of the angles (deg): `error_factor` times the largest
    /// error, over the last `error_memory_s`, of a model fitted `holdout_s` earlier on the
    /// samples since.
    pub(super) holdout_error: f64,
    /// The same for the heave (m; 0 without heave).
    pub(super) heave_error: f64,
    /// Per channel: what the predictor's stated standard deviation is multiplied by so that
    /// its band held what happened (1 or more; see [`LandingDecider::band_scale`]).
    pub(super) band_scale: [f64; 3],
    /// The same for each channel's rate (see [`LandingDecider::band_scale`]).
    pub(super) rate_band_scale: [f64; 3],
    /// Per channel, the spread of its rate's recent held-out misses in its own unit, whatever
    /// each fit stated (NaN without the evidence): the least deviation its forecast is given.
    pub(super) rate_miss_std: [f64; 3],
    /// Every channel's band, value and rate, has been checked against what followed
    /// (`MIN_BAND_EVIDENCE` misses of its own).
    pub(super) band_checked: bool,
    /// Per channel, what its history alone says of its rate to come (no model).
    pub(super) rate_history: [RateHistory; 3],
}

impl Models {
    /// Whether channel `k`'s band, value or rate, has been measured more than `MAX_BAND_SCALE`
    /// times too narrow: its stated deviations are not the forecast's error.
    pub(super) fn band_unreliable(&self, k: usize) -> bool {
        self.widest_band_scale(k) > MAX_BAND_SCALE
    }

    /// How many times too narrow channel `k`'s band has been measured, its value's or its
    /// rate's, whichever is more.
    fn widest_band_scale(&self, k: usize) -> f64 {
        self.band_scale[k].max(self.rate_band_scale[k])
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
    /// judgement of a suspect band, `Margins::unreliable_band_scale`).
    pub(super) fn judged_by_history_above(&self, k: usize, unreliable_scale: f64) -> bool {
        k < self.tracks.len()
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

    /// [`Self::rate_std`], with `as_value` (a new commitment's `Margins::rate_as_value`) the
    /// rate of a channel whose band is unreliable scaled at least as much as its value's band:
    /// one model states both, from one innovation, and a value that missed by 15 of its
    /// deviations says its rate may too. The spread of its misses stays the floor.
    pub(super) fn rate_std_judging(&self, k: usize, t: f64, as_value: bool) -> f64 {
        let unreliable = self.band_unreliable(k);
        let scale = match unreliable && as_value {
            true => self.rate_band_scale[k].max(self.band_scale[k]),
            false => self.rate_band_scale[k],
        };
        let scaled = scale * self.tracks[k].rate_std(t);
        if unreliable {
            scaled.max(self.rate_miss_std[k])
        } else {
            scaled
        }
    }
}

/// One sample after a fit, judged by that fit's band: how far the measurement fell from the
/// forecast (roll, pitch, heave, then their rates; NaN where not measured), in the stated
/// standard deviations and in the channels' own units (deg, m, deg/s, m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct BandMiss {
    pub(super) t_s: f64,
    pub(super) z: [f64; 6],
    pub(super) abs: [f64; 6],
}

impl BandMiss {
    /// A miss known only in stated deviations (no absolute misses).
    #[cfg(test)]
    pub(super) fn new(t_s: f64, z: [f64; 6]) -> Self {
        Self {
            t_s,
            z,
            abs: [f64::NAN; 6],
        }
    }
}

/// What the held-out misses say of each channel's band ([`LandingDecider::band_scale`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct BandScale {
    /// Per channel, the factor on the stated standard deviation of its value...
    pub(super) values: [f64; 3],
    /// ... and of its rate.
    pub(super) rates: [f64; 3],
    /// Per channel, the rate's recent misses in its own unit (deg/s, m/s) as a normal
    /// deviation (NaN without `MIN_BAND_EVIDENCE` of them).
    pub(super) rate_miss_std: [f64; 3],
    /// Every channel's value and rate has its evidence.
    pub(super) checked: bool,
}

/// The `BAND_EVIDENCE_QUANTILE` of `values` (reordered; at least one).
fn evidence_quantile(values: &mut [f64]) -> f64 {
    let i = ((values.len() as f64 * BAND_EVIDENCE_QUANTILE).ceil() as usize).min(values.len()) - 1;
    *values.select_nth_unstable_by(i, f64::total_cmp).1
}

/// The deviation of a normal whose two-sided band holds `BAND_EVIDENCE_QUANTILE`, per unit:
/// what a band's misses at that quantile are in standard deviations.
pub(super) fn evidence_z() -> f64 {
    normal_quantile(0.5 + 0.5 * BAND_EVIDENCE_QUANTILE)
}

/// What a channel's history alone says of its rate to come, with no model: its rate by
/// central differences on the fitted samples, regressed on the newest of them at each lag of
/// the fit spacing (a least-squares coefficient and the spread of what it leaves, raised to
/// its upper bound over the seconds the pairs span: `upper_bound_factor`), up to a
/// refit interval and a touchdown for a channel judged by it; beyond, or without pairs
/// enough, the rate's spread with a mean of zero. The newest rate says most of the next
/// second (a swell's rate changes little in it), nothing of one a quarter period away; the
/// regression measures which, on this sea.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RateHistory {
    /// The RMS of the rate over the history; NaN with fewer than three samples.
    pub(super) spread: f64,
    /// The newest rate measured and its time (s).
    pub(super) newest: f64,
    pub(super) newest_t: f64,
    /// Per lag of `k + 1` fit spacings: the coefficient on the newest rate and the deviation
    /// of what it leaves.
    pub(super) lags: Vec<(f64, f64)>,
}

impl RateHistory {
    /// Nothing known (fewer than three samples): no spread, so nothing to clear on.
    pub(super) fn unknown() -> Self {
        Self {
            spread: f64::NAN,
            newest: f64::NAN,
            newest_t: f64::NAN,
            lags: Vec::new(),
        }
    }

    /// Only a spread (`spread`), no regression: what is known with too short a history.
    #[cfg(test)]
    pub(super) fn spread_only(spread: f64) -> Self {
        Self {
            spread,
            ..Self::unknown()
        }
    }

    /// A newer rate measured: the slope from `(t0, y0)` to `(t1, y1)`, at their mean time.
    pub(super) fn measured(&mut self, t0: f64, y0: f64, t1: f64, y1: f64) {
        let rate = (y1 - y0) / (t1 - t0);
        let at = 0.5 * (t0 + t1);
        if rate.is_finite() && !(at <= self.newest_t) {
            (self.newest, self.newest_t) = (rate, at);
        }
    }

    /// The rate at `t` (s) as (mean, standard deviation). Within a fit spacing of the newest
    /// rate, the first lag's: that rate is itself measured with about that error.
    pub(super) fn forecast(&self, t: f64) -> (f64, f64) {
        let lags = (t - self.newest_t) / FIT_SPACING_S;
        if self.lags.is_empty() || !(lags <= self.lags.len() as f64) {
            return (0.0, self.spread);
        }
        let lags = lags.max(1.0);
        let below = lags.floor() as usize;
        let share = lags - below as f64;
        let (a0, s0) = self.lags[below - 1];
        let (a1, s1) = self.lags.get(below).copied().unwrap_or((a0, s0));
        ((a0 + share * (a1 - a0)) * self.newest, s0 + share * (s1 - s0))
    }
}

/// Pairs a lag's regression needs (fewer: the lags from there on are not regressed).
const MIN_RATE_LAG_PAIRS: usize = 20;
/// The seconds of a history taken as one piece of evidence of its rate's regression, and the
/// confidence of the upper bound its deviation is raised to (`upper_bound_factor`). As
/// measured, 13 s of a sea state 6 stated the heave rate 2 s ahead at -0.10 +- 0.13 m/s, a
/// clearance went on it, and the deck fell at 0.676 m/s (BENCHMARKS.md, "A history's
/// regression bounded by the seconds it spans"). The upper quartile: at 0.9 the development
/// trials' median wait at sea state 3 grew from 10.2 s to 14.2 s, at 0.75 to 11.1 s, their
/// landings the same.
const HISTORY_EVIDENCE_BLOCK_S: f64 = 1.0;
const HISTORY_BOUND_CONFIDENCE: f64 = 0.75;

/// The factor from a deviation measured on samples spanning `span_s` to its upper bound at
/// `HISTORY_BOUND_CONFIDENCE`: the samples of one `HISTORY_EVIDENCE_BLOCK_S` are taken as one
/// piece of evidence (chi-square with one degree of freedom per block). A swell's rate
/// measured 0.2 s apart is nearly the same; what a second of a sea says of the next is what
/// counts.
pub(super) fn upper_bound_factor(span_s: f64) -> f64 {
    let blocks = (span_s / HISTORY_EVIDENCE_BLOCK_S).floor().max(1.0);
    (blocks / chi_square_quantile(1.0 - HISTORY_BOUND_CONFIDENCE, blocks)).sqrt()
}

/// Each channel's [`RateHistory`] over samples `t` (s) and `y` (one series per channel, the
/// samples about `FIT_SPACING_S` apart), regressed up to `max_lag_s` (per channel; 0: only
/// its spread and newest rate).
pub(super) fn rate_histories(t: &[f64], y: &[Vec<f64>], max_lag_s: [f64; 3]) -> [RateHistory; 3] {
    let mut out = std::array::from_fn(|_| RateHistory::unknown());
    // (time, rate) by central differences, on the first channel's clock.
    let times: Vec<(usize, f64)> = (1..t.len().saturating_sub(1))
        .filter(|&i| t[i + 1] > t[i - 1])
        .map(|i| (i, t[i]))
        .collect();
    for (k, yk) in y.iter().enumerate().take(3) {
        let max_lags = (max_lag_s[k] / FIT_SPACING_S).ceil().max(0.0) as usize;
        let rates: Vec<(f64, f64)> = times
            .iter()
            .map(|&(i, ti)| (ti, (yk[i + 1] - yk[i - 1]) / (t[i + 1] - t[i - 1])))
            .filter(|(_, r)| r.is_finite())
            .collect();
        let Some(&(newest_t, newest)) = rates.last() else {
            continue;
        };
        let spread = (rates.iter().map(|(_, r)| r * r).sum::<f64>() / rates.len() as f64).sqrt();
        let mut lags = Vec::with_capacity(max_lags);
        for lag in 1..=max_lags {
            let lag_s = lag as f64 * FIT_SPACING_S;
            // Each rate paired with the rate `lag_s` later, interpolated between the two samples
            // around it (the fit's samples are 0.2-0.3 s apart), not across a gap.
            let (mut xx, mut xy, mut yy, mut n) = (0.0, 0.0, 0.0, 0usize);
            let (mut first_at, mut last_at) = (f64::INFINITY, f64::NEG_INFINITY);
            let mut j = 0;
            for &(ti, ri) in &rates {
                let at = ti + lag_s;
                while j + 1 < rates.len() && rates[j + 1].0 < at {
                    j += 1;
                }
                let Some(&(t1, r1)) = rates.get(j + 1) else {
                    break;
                };
                let (t0, r0) = rates[j];
                if !(t0 <= at && t1 - t0 <= 2.0 * FIT_SPACING_S) {
                    continue;
                }
                let later = r0 + (r1 - r0) * (at - t0) / (t1 - t0);
                first_at = first_at.min(at);
                last_at = last_at.max(at);
                xx += ri * ri;
                xy += ri * later;
                yy += later * later;
                n += 1;
            }
            if n < MIN_RATE_LAG_PAIRS || !(xx > 0.0) {
                break;
            }
            let coefficient = xy / xx;
            // What the regression leaves: sum (later - c r)^2 = yy - c xy; raised to its upper
            // bound over the seconds its pairs span (see `upper_bound_factor`).
            let left = (yy - coefficient * xy).max(0.0);
            let bound = upper_bound_factor(last_at - first_at);
            lags.push((coefficient, bound * (left / (n - 1) as f64).sqrt()));
        }
        out[k] = RateHistory {
            spread,
            newest,
            newest_t,
            lags,
        };
    }
    out
}

/// One channel's predictor.
#[derive(Debug, Clone)]
pub(super) enum Track {
    Sinusoids(SinusoidModel),
    Autoregressive(ArModel),
}

impl Track {
    pub(super) fn t0(&self) -> f64 {
        match self {
            Self::Sinusoids(m) => m.t0,
            Self::Autoregressive(m) => m.t0,
        }
    }
    pub(super) fn value(&self, t: f64) -> f64 {
        match self {
            Self::Sinusoids(m) => m.value(t),
            Self::Autoregressive(m) => m.value(t),
        }
    }
    pub(super) fn rate(&self, t: f64) -> f64 {
        match self {
            Self::Sinusoids(m) => m.rate(t),
            Self::Autoregressive(m) => m.rate(t),
        }
    }
    /// The same model run forward from the newest samples (the sinusoid fit has no state to
    /// run forward: None).
    pub(super) fn advanced(&self, t: &[f64], y: &[f64]) -> Option<Self> {
        match self {
            Self::Sinusoids(_) => None,
            Self::Autoregressive(m) => m.advance(t, y).map(Self::Autoregressive),
        }
    }
    /// The model's own standard deviation of its value at `t` (0: it states none; the
    /// sinusoid fit's error is bounded by the held-out error instead).
    pub(super) fn std(&self, t: f64) -> f64 {
        match self {
            Self::Sinusoids(_) => 0.0,
            Self::Autoregressive(m) => m.std(t),
        }
    }
    pub(super) fn rate_std(&self, t: f64) -> f64 {
        match self {
            Self::Sinusoids(_) => 0.0,
            Self::Autoregressive(m) => m.rate_std(t),
        }
    }
}

/// What a prediction must keep clear of the capacity's limits: fixed margins, plus `z` times
/// the model's own standard deviation at each instant (a predictor that states one).
#[derive(Debug, Clone, Copy)]
pub(super) struct Margins {
    pub(super) angle_deg: f64,
    pub(super) rate_dps: f64,
    pub(super) heave_rate_mps: f64,
    /// With a stated uncertainty: the accepted probability of leaving the capacity (see
    /// `LandingDecider::exceedance_risk`); None: the forecast's mean is judged as it is.
    pub(super) risk: Option<f64>,
    /// A channel's band measured more than this many times too narrow, its rate without misses
    /// of its own, has its rate judged by its history too (`Models::judged_by_history_above`).
    pub(super) unreliable_band_scale: f64,
    /// What the deviation of an angle (roll, pitch) whose value band has been measured more
    /// than `MAX_BAND_SCALE` times too narrow is multiplied by, on top of its measured scale
    /// (1: judged as measured; a new commitment's: `UNRELIABLE_ANGLE_FACTOR`).
    pub(super) unreliable_angle_factor: f64,
    /// Whether the rate of a channel whose band is unreliable is scaled at least as much as its
    /// value's band (`Models::rate_std_judging`; a new commitment's).
    pub(super) rate_as_value: bool,
}

impl Margins {
    pub(super) const NONE: Self = Self {
        angle_deg: 0.0,
        rate_dps: 0.0,
        heave_rate_mps: 0.0,
        risk: None,
        unreliable_band_scale: MAX_BAND_SCALE,
        unreliable_angle_factor: 1.0,
        rate_as_value: false,
    };
}

impl LandingDecider {
    pub(super) fn fit(&mut self) -> Option<Models> {
        let c = self.config.clone();
        let channels = self.channels;
        let mut t = Vec::new();
        let mut y: Vec<Vec<f64>> = vec![Vec::new(); channels];
        // Newest sample always in; older ones thinned to the fit spacing.
        for &(ti, v) in self.history.iter().rev() {
            if t.last().is_none_or(|&last: &f64| last - ti >= FIT_SPACING_S) {
                t.push(ti);
                for (k, yk) in y.iter_mut().enumerate() {
                    yk.push(v[k]);
                }
            }
        }
        t.reverse();
        for yk in &mut y {
            yk.reverse();
        }
        let end = *t.last()?;
        let tracks: Vec<Track> = if c.predictor == Predictor::Sinusoids {
            let warm: Option<Vec<SinusoidModel>> = match self.past.back() {
                Some(prev) if end - self.last_grid < REGRID_INTERVAL_S => prev
                    .iter()
                    .zip(&y)
                    .map(|(p, yk)| match p {
                        Track::Sinusoids(m0) => m0.refit(&t, yk, F_MIN_HZ, F_MAX_HZ, c.fit_memory_s),
                        Track::Autoregressive(_) => None,
                    })
                    .collect(),
                _ => None,
            };
            let models = match warm {
                Some(m) => m,
                None => {
                    self.last_grid = end;
                    y.iter()
                        .map(|yk| {
                            SinusoidModel::fit(&t, yk, c.components, F_MIN_HZ, F_MAX_HZ, c.fit_memory_s)
                        })
                        .collect::<Option<Vec<_>>>()?
                }
            };
            models.into_iter().map(Track::Sinusoids).collect()
        } else {
            self.autoregressive_tracks(&t, &y, c.horizon_s + c.touchdown_s + c.holdout_s)?
        };
        // How well did the fit of `holdout_s` ago predict the samples since? (angles, heave)
        let old = self.past.iter().rev().find(|m| end - m[0].t0() >= c.holdout_s);
        let misses = old.map(|old| {
            let t0 = old[0].t0();
            self.history
                .iter()
                .filter(|h| h.0 > t0 && h.0 <= t0 + c.holdout_s)
                .map(|&(ti, v)| channel_misses(old, ti, &v))
                .fold((0.0, 0.0), |(a, b), (x, y)| (f64::max(a, x), f64::max(b, y)))
        });
        // Only a measured miss is remembered: a fit with no track record yet (the first
        // `holdout_s` after warm-up) is unreliable itself, but remembering that as an infinite
        // error would hold every decision for `error_memory_s` after each warm-up.
        if let Some((angle_miss, heave_miss)) = misses {
            self.errors.push_back((end, angle_miss, heave_miss));
        }
        // The same held-out samples in the old fit's own standard deviations (a predictor that
        // states one): how honest its band has been.
        // Checked once the rates of its whole held-out span are measured too (a second of
        // samples centred on each): checked at `holdout_s`, a fit refitted every second was
        // 2.0 s old, and its rates' misses came only when a frame's rounding made it the one
        // 3 s old (the heave rate had 12 misses where its value had 20).
        let banded_span_s = c.holdout_s + RATE_CHECK_HALF_WINDOW_S;
        let old_banded = self.past.iter().rev().find(|m| end - m[0].t0() >= banded_span_s);
        if let Some(old) = old_banded.filter(|old| old[0].std(old[0].t0()) > 0.0) {
            let found = self.band_misses_of(old);
            self.band_misses.extend(found);
        } else if c.predictor == Predictor::Ar {
            // No fit old enough to have been checked yet (the first `holdout_s` after a
            // warm-up): the band is checked on fits the decider would have made earlier.
            self.backtest_band(&t, &y, end);
        }
        while self
            .band_misses
            .front()
            .is_some_and(|m| end - m.t_s > BAND_MEMORY_S)
        {
            self.band_misses.pop_front();
        }
        while self
            .backtest_misses
            .front()
            .is_some_and(|m| end - m.t_s > BAND_MEMORY_S)
        {
            self.backtest_misses.pop_front();
        }
        let BandScale {
            values: band_scale,
            rates: rate_band_scale,
            rate_miss_std,
            checked: band_checked,
        } = self.band_scale();
        while self
            .errors
            .front()
            .is_some_and(|&(te, _, _)| end - te > c.error_memory_s)
        {
            self.errors.pop_front();
        }
        // Consecutive fits must agree on the coming touchdown; a disagreement is an error of one
        // of them and widens the bound like one.
        let disagreement = match self.past.back() {
            Some(prev) => (0..=20)
                .map(|k| end + c.touchdown_s * k as f64 / 20.0)
                .map(|ti| {
                    let now: Vec<f64> = tracks.iter().map(|m| m.value(ti)).collect();
                    let mut v = [f64::NAN; 3];
                    v[..now.len()].copy_from_slice(&now);
                    channel_misses(prev, ti, &v)
                })
                .fold((0.0, 0.0), |(a, b), (x, y)| (f64::max(a, x), f64::max(b, y))),
            None => (f64::INFINITY, f64::INFINITY),
        };
        let (recent_angle, recent_heave) = match misses {
            Some(_) => self
                .errors
                .iter()
                .fold((0.0, 0.0), |(a, b), e| (f64::max(a, e.1), f64::max(b, e.2))),
            None => (f64::INFINITY, f64::INFINITY), // no track record yet
        };
        let holdout_error = c.error_factor * recent_angle.max(disagreement.0);
        let heave_error = c.error_factor * recent_heave.max(disagreement.1);
        self.past.push_back(tracks.clone());
        // Kept until checked: the band's check wants them `banded_span_s` old.
        while self
            .past
            .front()
            .is_some_and(|m| end - m[0].t0() > banded_span_s + 2.0 * c.refit_interval_s)
        {
            self.past.pop_front();
        }
        let mut models = Models {
            tracks,
            holdout_error,
            heave_error,
            band_scale,
            rate_band_scale,
            rate_miss_std,
            band_checked,
            rate_history: std::array::from_fn(|_| RateHistory::unknown()),
        };
        // Regressed only where it is used, as far ahead as a model is used for: its age at most
        // (a refit interval) and a touchdown. Every channel's regressed cost the slowest
        // decision of a second 5-11 % more.
        let regressed_s = std::array::from_fn(|k| {
            if models.judged_by_history(k) || models.band_suspect(k) {
                c.refit_interval_s + c.touchdown_s
            } else {
                0.0
            }
        });
        models.rate_history = rate_histories(&t, &y, regressed_s);
        Some(models)
    }

    /// One autoregressive model per channel on samples `t` and the first `t.len()` of each of
    /// `y` (one series per channel), forecasting `horizon_s`; None when a channel cannot be
    /// fitted.
    fn autoregressive_tracks(&self, t: &[f64], y: &[Vec<f64>], horizon_s: f64) -> Option<Vec<Track>> {
        let c = &self.config;
        y.iter()
            .map(|yk| {
                ArModel::fit(
                    t,
                    &yk[..t.len()],
                    c.ar_order,
                    FIT_SPACING_S,
                    horizon_s,
                    c.max_gap_ms / 1e3,
                )
                .map(Track::Autoregressive)
            })
            .collect()
    }

    /// How far the samples after `old` (a fit `holdout_s` or more ago) fell from its forecast,
    /// in its own stated standard deviations: the evidence of [`Self::band_scale`].
    fn band_misses_of(&self, old: &[Track]) -> Vec<BandMiss> {
        let c = &self.config;
        let t0 = old[0].t0();
        // The last half of the held-out span: the band matters most at the touchdown's far
        // end, and a model's error outgrows its stated one with the horizon (the last quarter
        // alone took two fits more to gather the evidence a clearance needs).
        let from = t0 + 0.5 * c.holdout_s;
        let until = t0 + c.holdout_s;
        // The rates from the last quarter alone: scaled on the whole last half, the rate
        // bands held 92-94 % 2 s ahead and a held-out sea cleared into 0.61 m/s of heave rate
        // (BENCHMARKS.md, "Deck-motion prediction").
        let far_from = t0 + 0.75 * c.holdout_s;
        let mut found = Vec::new();
        for &(ti, v) in self.history.iter().filter(|h| h.0 > from && h.0 <= until) {
            // Values, then rates against the deck's rate measured around `ti` (a line through
            // the samples of a second centred on it: unbiased by the deck's acceleration; its
            // noise only makes the misses look larger).
            let mut miss = BandMiss {
                t_s: ti,
                z: [f64::NAN; 6],
                abs: [f64::NAN; 6],
            };
            let measured_rate = (ti >= far_from)
                .then(|| self.centred_rate(ti, RATE_CHECK_HALF_WINDOW_S))
                .flatten();
            for (k, track) in old.iter().enumerate() {
                miss.abs[k] = (v[k] - track.value(ti)).abs();
                miss.z[k] = miss.abs[k] / track.std(ti);
                if let Some(rates) = measured_rate {
                    let rate_std = track.rate_std(ti);
                    miss.abs[3 + k] = (rates[k] - track.rate(ti)).abs();
                    miss.z[3 + k] = miss.abs[3 + k] / rate_std;
                }
            }
            found.push(miss);
        }
        found
    }

    /// The band's first evidence, before any fit is `holdout_s` old: the fits the decider would
    /// have made `WARMUP_BACKTESTS` times before (every `WARMUP_BACKTEST_STEP_S`, the newest
    /// old enough for its rates to be measured all through its held-out span), each on the
    /// history up to its own time, judged on the samples after it like any earlier fit. They
    /// fit shorter histories than the fit they vouch for, so they miss by more, not less:
    /// without them the first clearance waited for two refits' worth of misses, 11.7 s after
    /// the deck came into view (issue 33 asks for 10 s).
    fn backtest_band(&mut self, t: &[f64], y: &[Vec<f64>], end: f64) {
        let holdout_s = self.config.holdout_s;
        let horizon = self.config.touchdown_s + holdout_s;
        for k in 0..WARMUP_BACKTESTS {
            let origin = end - holdout_s - RATE_CHECK_HALF_WINDOW_S - k as f64 * WARMUP_BACKTEST_STEP_S;
            let n = t.partition_point(|&ti| ti <= origin);
            if n < 2 || origin - t[0] < WARMUP_BACKTEST_MIN_HISTORY_S {
                break;
            }
            let fits = self.autoregressive_tracks(&t[..n], y, horizon);
            if let Some(fits) = fits.filter(|f| f[0].std(f[0].t0()) > 0.0) {
                let found = self.band_misses_of(&fits);
                self.backtest_misses.extend(found);
            }
        }
    }

    /// Per channel, the factor on the predictor's stated standard deviation that makes its 95 %
    /// band hold `BAND_EVIDENCE_QUANTILE` of the held-out misses of the last `BAND_MEMORY_S`
    /// (never below 1), and the same for its rate; each rate's misses in its own unit
    /// (`BandScale::rate_miss_std`, from real fits' misses only); and whether every channel's
    /// value and rate has that evidence (no clearance before). Until the real fits have
    /// `MIN_BAND_EVIDENCE` misses of a quantity the warm-up's backtests add theirs; with fewer
    /// than that in all there is no track record yet: `PRIOR_BAND_SCALE`, and for a rate at
    /// least its value's scale (shown in forecasts, never cleared on).
    pub(super) fn band_scale(&self) -> BandScale {
        let mut scale = [PRIOR_BAND_SCALE; 6];
        let mut rate_miss_std = [f64::NAN; 3];
        let mut checked = true;
        for k in 0..6 {
            if k % 3 >= self.channels {
                continue;
            }
            let real = |k: usize| {
                self.band_misses
                    .iter()
                    .map(move |m| m.z[k])
                    .filter(|z| z.is_finite())
            };
            // The warm-up's backtests stand in only while the real fits' misses of the same
            // quantity are too few (they fit shorter histories and miss by more: beside the
            // real misses they held the development trials at sea state 4 ten seconds longer).
            // A rate's real misses come half as many per fit as its value's (the last quarter
            // of the held-out span, not the last half), so its backtests stand in two fits
            // longer; with none, a rate would have no evidence of its own for those fits and
            // nothing could clear.
            let on_backtests = real(k).count() < MIN_BAND_EVIDENCE;
            let judged = || {
                let backtests = self.backtest_misses.iter().filter(move |_| on_backtests);
                self.band_misses
                    .iter()
                    .chain(backtests)
                    .filter(move |m| m.z[k].is_finite())
            };
            let mut z: Vec<f64> = judged().map(|m| m.z[k]).collect();
            if z.len() < MIN_BAND_EVIDENCE {
                // No clearance on a band without misses of its own, a rate's neither: on the
                // value's scale (its misses all from the two seconds before), a held-out
                // sea state 6 cleared with the heave rate's band at 0.058 m/s and touched down
                // at 0.48 m/s beyond its forecast, while the rate's own misses were 12
                // (BENCHMARKS.md, "A rate's band cleared on only with misses of its own").
                checked = false;
                if k >= 3 {
                    // The rates' evidence comes later (each needs a second of samples around
                    // it). Until then a forecast shows a rate's band as far off as its value's
                    // has been measured to be: on the prior scale alone a fresh sea cleared
                    // 0.2 s after the warm-up with the heave's value band 3.9 times too
                    // narrow and its rate's stated at 5 mm/s; 2 s later the deck fell at
                    // 0.678 m/s against 0.6 (BENCHMARKS.md, "The first clearance after the
                    // warm-up").
                    scale[k] = scale[k].max(scale[k - 3]);
                }
                continue;
            }
            // Never narrower than stated, a rate's band neither: the scale is measured at the
            // 97.5th percentile of about a hundred misses and read at 3 standard deviations.
            // Rate bands allowed down to 0.75 of their stated deviation cleared twice into a
            // heave rate beyond the capacity at the touchdown's end on fresh seas, both with the
            // band at 0.77-0.78 (BENCHMARKS.md, "A rate's misses in its own unit").
            scale[k] = (evidence_quantile(&mut z) / Z95).max(1.0);
            if k >= 3 && !on_backtests {
                // The same misses in m/s or deg/s, whatever each fit stated: the deviation
                // whose normal band holds `BAND_EVIDENCE_QUANTILE` of them. Of real fits only:
                // the warm-up's four backtests gave 24 misses of at most 0.031 m/s, and the
                // first clearance on them touched down 0.083 m/s beyond its forecast.
                let measured = || judged().filter(move |m| m.abs[k].is_finite());
                let mut abs: Vec<f64> = measured().map(|m| m.abs[k]).collect();
                let (first, last) = measured().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), m| {
                    (a.min(m.t_s), b.max(m.t_s))
                });
                if abs.len() >= MIN_BAND_EVIDENCE && last - first >= MIN_RATE_EVIDENCE_SPAN_S {
                    rate_miss_std[k - 3] = evidence_quantile(&mut abs) / evidence_z();
                }
            }
        }
        BandScale {
            values: [scale[0], scale[1], scale[2]],
            rates: [scale[3], scale[4], scale[5]],
            rate_miss_std,
            checked,
        }
    }

    /// Whether the rates measured through the newest samples (`RATE_WINDOW_S`) are beyond the
    /// capacity.
    pub(super) fn measured_rate_outside(&self) -> bool {
        let c = &self.config;
        let Some(&(t, _)) = self.history.back() else {
            return false;
        };
        self.measured_rate(t, RATE_WINDOW_S).is_some_and(|rates| {
            rates[ROLL].abs() > c.max_abs_roll_rate_dps
                || rates[PITCH].abs() > c.max_abs_pitch_rate_dps
                || (self.channels > HEAVE && rates[HEAVE].abs() > c.max_abs_heave_rate_mps)
        })
    }

    /// Each channel's rate at `t` from a least-squares line through the samples within
    /// `half_s` of it, on both sides (None without samples that far on each side).
    pub(super) fn centred_rate(&self, t: f64, half_s: f64) -> Option<[f64; 3]> {
        let near = self
            .history
            .iter()
            .rev()
            .skip_while(|h| h.0 > t + half_s)
            .take_while(|h| h.0 >= t - half_s);
        let line = fit_line(near)?;
        let both_sides = line.first_t <= t - 0.8 * half_s && line.last_t >= t + 0.8 * half_s;
        (line.count >= 5 && both_sides).then_some(line.slopes)
    }

    /// The margins to enter `ClearToLand`: the configured ones plus the prediction's error
    /// (its stated band for a predictor that states one, else the held-out error bound).
    pub(super) fn entry_margins(&self, m: &Models) -> Margins {
        let c = &self.config;
        let banded = c.predictor == Predictor::Ar;
        Margins {
            angle_deg: c.margin_deg + if banded { 0.0 } else { m.holdout_error },
            rate_dps: c.rate_margin_dps,
            heave_rate_mps: c.heave_rate_margin_mps,
            risk: banded.then_some(c.risk_per_touchdown),
            // Bands judged as measured.
            ..Margins::NONE
        }
    }

    /// The margins of a new commitment at `now`: an entry's, with a suspect band
    /// (`Models::band_suspect`) judged as an unreliable one, an unreliable angle's band widened
    /// (`UNRELIABLE_ANGLE_FACTOR`) and an unreliable channel's rate taken as far off as its
    /// value (`Margins::rate_as_value`), and within `early_window_s` of when the decision could
    /// first clear (`LandingDecider::early_since`) at `early_risk_per_touchdown`. The
    /// touchdown's last chance judges the band as it is measured then, and a suspect one's next
    /// misses often make it unreliable.
    pub(super) fn commit_margins(&self, m: &Models, now: f64) -> Margins {
        let c = &self.config;
        let entry = self.entry_margins(m);
        let early = self
            .early_since
            .is_none_or(|since| now - since < c.early_window_s);
        Margins {
            unreliable_band_scale: SUSPECT_BAND_SCALE,
            unreliable_angle_factor: UNRELIABLE_ANGLE_FACTOR,
            rate_as_value: true,
            risk: entry.risk.map(|r| {
                if early {
                    r.min(c.early_risk_per_touchdown)
                } else {
                    r
                }
            }),
            ..entry
        }
    }

    /// The margins to stay committed: the prediction's own error (band or bound) only. A
    /// committed touchdown is given up when the newest model puts the deck outside the capacity
    /// within that band, not because it differs from the one that committed.
    pub(super) fn stay_margins(&self, m: &Models) -> Margins {
        if self.config.predictor == Predictor::Ar {
            Margins {
                risk: Some(self.config.go_around_risk),
                ..Margins::NONE
            }
        } else {
            Margins {
                angle_deg: m.holdout_error,
                ..Margins::NONE
            }
        }
    }

    /// The margins of a committed touchdown's last chance before its point of no return
    /// (`LandingDecider::last_chance`, seeing or blind): a clearance's. A committed touchdown
    /// goes on up to `go_around_risk` because the frames still to come can call a go-around;
    /// past the point of no return none can, so the last decision before it judges the rest of
    /// the touchdown as a new clearance would be. On a seeing touchdown's margins, three held-out
    /// approaches at sea state 6 rode through their last 0.5 s on forecasts at a risk of 0.1
    /// or less and met the deck falling at 0.606, 0.635 and 0.90 m/s against 0.6
    /// (BENCHMARKS.md, "Blind to contact, a touchdown goes on only as a clearance would").
    pub(super) fn last_chance_margins(&self, m: &Models) -> Margins {
        self.entry_margins(m)
    }
}

/// A least-squares line through samples (time s, roll, pitch, height) per channel. Its slopes
/// are the rates at the samples' mean time.
pub(super) struct LineFit {
    pub(super) slopes: [f64; 3],
    pub(super) count: usize,
    pub(super) first_t: f64,
    pub(super) last_t: f64,
}

/// The line through `samples` (in any order); None without two distinct times. Two passes over
/// the iterator and no allocation: the decision fits one on every frame.
pub(super) fn fit_line<'a>(samples: impl Iterator<Item = &'a (f64, [f64; 3])> + Clone) -> Option<LineFit> {
    let (mut count, mut sum_t, mut sum_v) = (0usize, 0.0, [0.0; 3]);
    let (mut first_t, mut last_t) = (f64::INFINITY, f64::NEG_INFINITY);
    for &(t, v) in samples.clone() {
        count += 1;
        sum_t += t;
        for k in 0..3 {
            sum_v[k] += v[k];
        }
        first_t = first_t.min(t);
        last_t = last_t.max(t);
    }
    let n = count as f64;
    let mean_t = sum_t / n;
    let mean_v = sum_v.map(|s| s / n);
    let (mut stt, mut stv) = (0.0, [0.0; 3]);
    for &(t, v) in samples {
        let dt = t - mean_t;
        stt += dt * dt;
        for k in 0..3 {
            stv[k] += dt * (v[k] - mean_v[k]);
        }
    }
    (stt > 0.0).then(|| LineFit {
        slopes: stv.map(|s| s / stt),
        count,
        first_t,
        last_t,
    })
}

/// Each channel's rate at one instant from a least-squares parabola through samples (time s,
/// roll, pitch, height), and how many samples over how long a span it rests on.
pub(super) struct ParabolaRate {
    pub(super) rates: [f64; 3],
    pub(super) count: usize,
    pub(super) span_s: f64,
}

/// The parabola through `samples` (in any order), per channel, and its slope at `at`: the rate
/// at the newest sample without a line's lag to the samples' mean time. None without three
/// distinct times. One pass and no allocation (the decision fits one every 0.1 s).
pub(super) fn parabola_rate_at<'a>(
    samples: impl Iterator<Item = &'a (f64, [f64; 3])>,
    at: f64,
) -> Option<ParabolaRate> {
    // Normal equations in time relative to `at` (a second or so: well conditioned).
    let mut powers = [0.0; 5];
    let mut moments = [[0.0; 3]; 3];
    let (mut count, mut first_t, mut last_t) = (0usize, f64::INFINITY, f64::NEG_INFINITY);
    for &(t, v) in samples {
        let x = t - at;
        let xs = [1.0, x, x * x, x * x * x, x * x * x * x];
        for (p, xp) in powers.iter_mut().zip(xs) {
            *p += xp;
        }
        for (k, &vk) in v.iter().enumerate() {
            for (i, row) in moments.iter_mut().enumerate() {
                row[k] += vk * xs[i];
            }
        }
        count += 1;
        first_t = first_t.min(t);
        last_t = last_t.max(t);
    }
    let normal = nalgebra::Matrix3::from_fn(|i, j| powers[i + j]);
    let cholesky = normal.cholesky()?;
    let mut rates = [f64::NAN; 3];
    for (k, rate) in rates.iter_mut().enumerate() {
        let rhs = nalgebra::Vector3::new(moments[0][k], moments[1][k], moments[2][k]);
        *rate = cholesky.solve(&rhs)[1];
    }
    (count >= 3).then_some(ParabolaRate {
        rates,
        count,
        span_s: last_t - first_t,
    })
}

/// How far `tracks` are from the values `v` at `ti`: the largest angle miss (deg) and the heave
/// miss (m; 0 without a heave track).
pub(super) fn channel_misses(tracks: &[Track], ti: f64, v: &[f64; 3]) -> (f64, f64) {
    let miss = |k: usize| (tracks[k].value(ti) - v[k]).abs();
    let heave = if tracks.len() > HEAVE { miss(HEAVE) } else { 0.0 };
    (miss(ROLL).max(miss(PITCH)), heave)
}
