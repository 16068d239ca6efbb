//! What a channel's history alone says of its rate to come, without a model: the second judge
//! of a rate whose forecast band has proved unreliable.

use super::history::FIT_SPACING_S;
use deckwatch_common::stats::chi_square_quantile;

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
/// clearance went on it, and the deck fell at 0.676 m/s (docs/history.md, "A history's regression bounded by the seconds it spans"). The upper quartile: at 0.9 the development
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
            // around it (the fit's samples are about 0.2 s apart), not across a gap.
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
