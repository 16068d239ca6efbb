//! The autoregressive forecaster (`[decide.forecast] kind = "ar"`): one linear recursion per
//! channel, fitted on the recent history, run forward, and stating its own uncertainty.

use super::ar_numerics::{
    design_row, gap_rows, normal_equations, propagate, resample, with_roots_within_max_radius,
    TruncatedInverse, GAP_FILTER_EXTRA_STEPS, MEASUREMENT_SHARE,
};
use super::joint::ArChannel;
use nalgebra::{DMatrix, DVector};

/// Rows of the fit per coefficient an autoregression over a history with gaps keeps at least
/// (one without gaps: two, the three samples per coefficient of a short history). With two, the
/// lowered fits of the fault options' gappy histories sent twice as many committed touchdowns
/// around as 48 lags did (105 against 53 on the development seeds); with four, 66 (docs/history.md, "Forecasts from 19.2 s of lags").
const GAPPED_ROWS_PER_COEF: usize = 4;

/// An autoregressive predictor of one channel (an angle or the deck height): the history resampled on a uniform grid, `x_k` as a
/// linear combination of the `order` values before it (least squares over the window), run
/// forward to give the prediction. Narrow-band motion whose amplitudes drift (an irregular sea)
/// is followed locally, without resolving its frequencies.
///
/// It states its own uncertainty: with one-step innovations of variance `s^2` and the model's
/// impulse response `psi_j` (`psi_0 = 1`), the error of the forecast `h` steps ahead is
/// `sum_{j<h} psi_j e_{n+h-j}`, of variance `s^2 sum_{j<h} psi_j^2`. The rate is the central
/// difference of the forecasts, whose error has variance
/// `s^2 (1 + psi_1^2 + sum_{m<h-1} (psi_{m+2} - psi_m)^2) / (2 dt)^2`. `s^2` is the residual variance times
/// `n / (n - p - 1)` (unbiased) and `1 + (p + 1) / n` (the fitted coefficients' own error, to
/// first order).
///
/// Grid points inside a gap (samples more than `max_bridge_s` apart) are not interpolated: the
/// newest state is then a Kalman filter's over the grid, those points predicted, not measured,
/// and the uncertainty of the state it ends with (`P`) adds to the stated variance of every
/// forecast (`g_h' P g_h`, with `g_h` the state's weights in the forecast `h` steps ahead). A
/// forecast that starts across a gap states a wider band instead of a false one.
#[derive(Debug, Clone, PartialEq)]
pub struct ArModel {
    /// Time of the newest sample (s); `predicted[0]` is the (resampled) value there.
    pub t0: f64,
    pub dt: f64,
    pub predicted: Vec<f64>,
    /// RMS of the one-step-ahead residual over the window.
    pub fit_rms: f64,
    /// Forecast error variance at each step of `predicted` (`[0]`: the newest value's own, one
    /// innovation: the resampled value carries the measurement's noise).
    pub variance: Vec<f64>,
    /// Variance of the rate's forecast error on each step interval `[k, k + 1]`.
    pub rate_variance: Vec<f64>,
    /// `a_1 .. a_order`, then the intercept.
    pub coef: Vec<f64>,
    /// The grid value one step before `t0`: the rate at `t0` is a central difference too.
    pub before_t0: f64,
    /// The series' variance over the fitted window: what is known of a value nobody measured.
    pub series_var: f64,
    /// Samples further apart than this leave the grid points between them unmeasured (a gap),
    /// not interpolated.
    pub max_bridge_s: f64,
}

/// The least-squares system an [`ArModel`] was fitted by, kept for the joint fit, which
/// extends it by the other channels' lags ([`super::joint`]).
#[derive(Debug, Clone)]
pub(super) struct OwnSystem {
    /// The channel on the fit's grid, and which of its points were not measured.
    pub x: Vec<f64>,
    pub unmeasured: Vec<bool>,
    /// The rows (target `r + order`) left out for a grid point in a gap, increasing.
    pub gap_rows: Vec<usize>,
    /// The normal equations' truncated pseudo-inverse: columns the lags 1..=order, then the
    /// intercept.
    pub inverse: TruncatedInverse,
    pub atb: DVector<f64>,
    /// The residuals' sum of squares over the rows kept, before the roots were pulled in.
    pub resid_sq: f64,
}

impl OwnSystem {
    /// The least squares of the autoregression of `order` on the grid `x`, the rows
    /// `gap_rows` (those with a point in `unmeasured`, increasing) left out: the system, and
    /// its solution (lags 1..=order, then the intercept). None when it is not finite or its
    /// decomposition fails.
    pub(super) fn solve(
        x: Vec<f64>,
        unmeasured: Vec<bool>,
        gap_rows: Vec<usize>,
        order: usize,
    ) -> Option<(Self, DVector<f64>)> {
        let (mut ata, mut atb) = normal_equations(&x, order);
        // Each such row taken back out: a rank-one downdate in place, one row vector reused.
        let mut row = DVector::zeros(order + 1);
        for &r in &gap_rows {
            design_row(&x, order, r, &mut row);
            ata.ger(-1.0, &row, &row, 1.0);
            atb.axpy(-x[r + order], &row, 1.0);
        }
        // Least squares with the directions the data do not fix left out (see `AR_CUTOFF`):
        // the eigen-decomposition of the normal equations (the singular values squared: a
        // decomposition of (order + 1)^2 instead of one of the whole design, ten times cheaper).
        if !atb.iter().all(|v| v.is_finite()) {
            return None;
        }
        let inverse = TruncatedInverse::new(ata)?;
        let coef = inverse.apply(&atb);
        let resid_sq: f64 = (0..x.len() - order)
            .filter(|r| gap_rows.binary_search(r).is_err())
            .map(|r| {
                let predicted = coef[order] + (0..order).map(|i| coef[i] * x[r + order - 1 - i]).sum::<f64>();
                (x[r + order] - predicted).powi(2)
            })
            .sum();
        let system = Self {
            x,
            unmeasured,
            gap_rows,
            inverse,
            atb,
            resid_sq,
        };
        Some((system, coef))
    }
}

impl ArModel {
    /// Fits on samples `t` (increasing, s), resampled every `dt`, and predicts `horizon_s`: of
    /// `order`, or lower when the history is short (None below order 2). Samples more than
    /// `max_bridge_s` apart are a gap (see the type's notes).
    pub fn fit(
        t: &[f64],
        y: &[f64],
        order: usize,
        dt: f64,
        horizon_s: f64,
        max_bridge_s: f64,
    ) -> Option<Self> {
        Self::fit_keeping_system(t, y, order, dt, horizon_s, max_bridge_s).map(|(model, _)| model)
    }

    /// [`Self::fit`], and the least-squares system it solved (the joint fit extends it).
    pub(super) fn fit_keeping_system(
        t: &[f64],
        y: &[f64],
        order: usize,
        dt: f64,
        horizon_s: f64,
        max_bridge_s: f64,
    ) -> Option<(Self, OwnSystem)> {
        let n_in = t.len();
        if n_in < 2 || n_in != y.len() || !(dt > 0.0) || order == 0 || !(max_bridge_s > 0.0) {
            return None;
        }
        let n = ((t[n_in - 1] - t[0]) / dt).floor() as usize + 1;
        // A short history fits a lower order (at least three samples per coefficient): the
        // first forecasts after a warm-up are coarser, and their stated variance says so.
        let mut order = order.min(n.saturating_sub(2) / 3);
        let (x, unmeasured) = resample(t, y, dt, n, max_bridge_s);
        // x_k = c + sum_i a_i x_{k-i}: the intercept keeps an offset deck exact.
        // A row with a grid point inside a gap (its target or a lag) is left out: a gap's
        // straight line is no motion the deck made, and rows on it pulled the coefficients (a
        // heave-rate forecast 0.33 m/s short of the truth 2 s ahead: docs/history.md, "An unsafe commit in main on held-out seeds: a gap's rows left out of the fit"). Each gap takes as many rows as there are lags, so
        // a history with gaps fits a lower order too, the highest that keeps `GAPPED_ROWS_PER_COEF`
        // rows per coefficient: with 96 lags the gaps of a frozen camera and a lost attitude
        // stream three times a minute left no fit at all (docs/history.md, "Forecasts from 19.2 s of lags").
        let rows_per_coef = |gap_rows: &[usize]| match gap_rows.is_empty() {
            true => 2,
            false => GAPPED_ROWS_PER_COEF,
        };
        let mut gap_rows = self::gap_rows(&unmeasured, order);
        while order >= 2 && n - order - gap_rows.len() < rows_per_coef(&gap_rows) * (order + 1) {
            order -= 1;
            gap_rows = self::gap_rows(&unmeasured, order);
        }
        if order < 2 {
            return None;
        }
        let rows = n - order - gap_rows.len();
        let (system, mut coef) = OwnSystem::solve(x, unmeasured, gap_rows, order)?;
        let (x, unmeasured, resid_sq) = (&system.x, &system.unmeasured, system.resid_sq);
        let fit_rms = (resid_sq / rows as f64).sqrt();
        // A fit whose recursion grows (a root on or outside the unit circle) would forecast
        // without bound: its roots are pulled inside (a_i scaled by r^i moves every root z to
        // r z), which keeps its frequencies.
        let within = with_roots_within_max_radius(&coef.as_slice()[..order])?;
        coef.as_mut_slice()[..order].copy_from_slice(&within);
        let steps = ((horizon_s / dt).ceil() as usize).max(1);
        let params = (order + 1) as f64;
        let dof = (rows as f64 - params).max(1.0);
        let innovation_var = resid_sq / dof * (1.0 + params / rows as f64);
        // Impulse response: psi_j = sum_i a_i psi_{j-1-i}.
        let mut psi = vec![0.0; steps + 2];
        psi[0] = 1.0;
        for j in 1..psi.len() {
            psi[j] = (0..order.min(j)).map(|i| coef[i] * psi[j - 1 - i]).sum();
        }
        let mut variance = Vec::with_capacity(steps + 1);
        variance.push(innovation_var);
        let mut acc = 0.0;
        for p in psi.iter().take(steps) {
            acc += p * p;
            variance.push(innovation_var * acc.max(1.0));
        }
        // The rate at grid point h is the central difference (x_{h+1} - x_{h-1}) / 2dt (at h = 0
        // the forward one); its error, in the innovations: e_{h+1} - e_{h-1} weighs the newest
        // two by psi_0 = 1 and psi_1, the older ones by psi_{m+2} - psi_m.
        let mut rate_variance = Vec::with_capacity(steps + 1);
        rate_variance.push(innovation_var / (4.0 * dt * dt));
        let mut acc = 1.0 + psi[1] * psi[1];
        for h in 1..=steps {
            if h >= 2 {
                acc += (psi[h] - psi[h - 2]).powi(2);
            }
            rate_variance.push(innovation_var * acc / (4.0 * dt * dt));
        }
        let mean = x.iter().sum::<f64>() / n as f64;
        let series_var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
        let model = Self {
            t0: t[n_in - 1],
            dt,
            predicted: Vec::new(),
            fit_rms,
            variance,
            rate_variance,
            coef: coef.iter().copied().collect(),
            before_t0: f64::NAN,
            series_var,
            max_bridge_s,
        };
        let newest = n.saturating_sub(2 * order + GAP_FILTER_EXTRA_STEPS);
        let model = model.forecast_from(&x[newest..], &unmeasured[newest..], t[n_in - 1])?;
        Some((model, system))
    }

    /// The same coefficients and stated variance, run forward from the newest samples (`t`
    /// increasing, ending at the newest): between refits, every frame's forecast starts from
    /// the deck as last measured. None with too few samples for the model's order.
    ///
    /// Give it the samples of [`Self::state_span_s`]: a forecast whose newest lags lie in a gap
    /// runs its filter from the measured lags before it.
    pub fn advance(&self, t: &[f64], y: &[f64]) -> Option<Self> {
        let order = self.order();
        let n_in = t.len();
        if n_in < 2 || n_in != y.len() || ((t[n_in - 1] - t[0]) / self.dt).floor() + 1.0 < order as f64 {
            return None;
        }
        let n =
            (((t[n_in - 1] - t[0]) / self.dt).floor() as usize + 1).min(2 * order + GAP_FILTER_EXTRA_STEPS);
        let (x, unmeasured) = resample(t, y, self.dt, n, self.max_bridge_s);
        self.forecast_from(&x, &unmeasured, t[n_in - 1])
    }

    /// The span of samples a forecast may start from (s): the lags, and as many again before
    /// them for the filter across a gap among them.
    pub fn state_span_s(order: usize, dt: f64) -> f64 {
        (2 * order + GAP_FILTER_EXTRA_STEPS) as f64 * dt
    }

    fn order(&self) -> usize {
        self.coef.len() - 1
    }

    /// The forecast from grid values `x` (oldest first, at least `order` of them) ending at
    /// `t0`: from the newest `order` of them, or, when any of those is `unmeasured`, from the
    /// state a Kalman filter ends with over all of `x` (its uncertainty added to the band).
    fn forecast_from(&self, x: &[f64], unmeasured: &[bool], t0: f64) -> Option<Self> {
        let order = self.order();
        if x.len() < order || unmeasured.len() != x.len() {
            return None;
        }
        let n = x.len();
        if unmeasured[n - order..].iter().any(|&u| u) {
            return self.forecast_across_gap(x, unmeasured, t0);
        }
        self.forecast_from_lags(&x[n - order..], t0)
    }

    /// The forecast from the newest `order` grid values (oldest first), all measured.
    fn forecast_from_lags(&self, newest: &[f64], t0: f64) -> Option<Self> {
        let order = self.order();
        let steps = self.variance.len() - 1;
        let mut series = newest.to_vec();
        let mut predicted = Vec::with_capacity(steps + 1);
        predicted.push(*newest.last()?);
        for _ in 0..steps {
            let m = series.len();
            let next: f64 =
                self.coef[order] + (0..order).map(|i| self.coef[i] * series[m - 1 - i]).sum::<f64>();
            series.push(next);
            predicted.push(next);
        }
        let finite = predicted
            .iter()
            .chain(&self.variance)
            .chain(&self.rate_variance)
            .all(|v| v.is_finite());
        let before_t0 = if newest.len() >= 2 {
            newest[newest.len() - 2]
        } else {
            f64::NAN
        };
        finite.then(|| Self {
            t0,
            predicted,
            before_t0,
            ..self.clone()
        })
    }

    /// The forecast when some of the newest lags were not measured. The state (the newest
    /// `order` grid values, newest first) starts at the oldest `order` values of `x`, an
    /// unmeasured one with the series' variance; each later grid point is predicted by the
    /// recursion (one innovation's variance added) and, where measured, the state updated with
    /// it. The forecast runs from the mean the filter ends with; its band adds what the filter
    /// still does not know of the state, carried forward by the recursion.
    fn forecast_across_gap(&self, x: &[f64], unmeasured: &[bool], t0: f64) -> Option<Self> {
        let order = self.order();
        let (a, c) = (&self.coef[..order], self.coef[order]);
        let innovation_var = self.variance[0];
        // A measurement is the deck's value to within a sliver of an innovation (the noise is
        // in the innovations already); the sliver keeps the update's division away from zero.
        let measurement_var = MEASUREMENT_SHARE * innovation_var;
        // The filter starts `order` points before the gap that reaches into the newest lags (its
        // state then measured, where the grid reaches that far back).
        let n = x.len();
        let mut first_unmeasured = (n - order..n).find(|&k| unmeasured[k]).unwrap_or(n - order);
        while first_unmeasured > 0 && unmeasured[first_unmeasured - 1] {
            first_unmeasured -= 1;
        }
        let start = first_unmeasured.saturating_sub(order);
        let (x, unmeasured) = (&x[start..], &unmeasured[start..]);
        let mut state: Vec<f64> = x[..order].iter().rev().copied().collect();
        let mut cov = DMatrix::<f64>::zeros(order, order);
        for (i, &u) in unmeasured[..order].iter().rev().enumerate() {
            cov[(i, i)] = if u { self.series_var } else { 0.0 };
        }
        let a_vec = DVector::from_column_slice(a);
        let mut next_cov = DMatrix::<f64>::zeros(order, order);
        for (&xk, &u) in x[order..].iter().zip(&unmeasured[order..]) {
            let mean = c + a.iter().zip(&state).map(|(ai, si)| ai * si).sum::<f64>();
            state.rotate_right(1);
            state[0] = mean;
            propagate(&cov, &a_vec, &mut next_cov);
            std::mem::swap(&mut cov, &mut next_cov);
            cov[(0, 0)] += innovation_var;
            if !u {
                // The measured newest value: gain P e_0 / (P_00 + R), P -= gain (P e_0)'.
                let s = cov[(0, 0)] + measurement_var;
                let col0 = cov.column(0).clone_owned();
                let innovation = xk - state[0];
                for (si, g) in state.iter_mut().zip(col0.iter()) {
                    *si += g / s * innovation;
                }
                cov.ger(-1.0 / s, &col0, &col0, 1.0);
            }
        }
        let lags: Vec<f64> = state.iter().rev().copied().collect();
        let mut model = self.forecast_from_lags(&lags, t0)?;
        // The state's uncertainty carried forward. With P = L L', a column of L is a deviation
        // of the state; run through the recursion it gives a deviation of every forecast, and
        // the variance of the value h steps ahead is the sum of their squares (of the rate's
        // central difference likewise). `O(rank p H)`: cheaper than carrying P forward.
        // P is positive semi-definite (the measured lags' part is all but zero); rounding can
        // leave it a hair indefinite. A jitter on the diagonal, grown until the factor exists,
        // only widens the band. None (no forecast) if even the largest does not do.
        let trace = cov.trace().max(f64::MIN_POSITIVE);
        let factor = [1e-12, 1e-9, 1e-6].iter().find_map(|share| {
            let mut jittered = cov.clone();
            for i in 0..order {
                jittered[(i, i)] += share * trace;
            }
            nalgebra::linalg::Cholesky::new(jittered)
        })?;
        let factor = factor.unpack();
        let steps = model.variance.len();
        let negligible = 1e-9 * innovation_var;
        let dt2 = 4.0 * self.dt * self.dt;
        let mut series = vec![0.0; order + steps + 1];
        for column in factor.column_iter() {
            if column.norm_squared() < negligible {
                continue; // a measured lag's: nothing unknown to carry
            }
            // Oldest first: the state is newest first.
            for (i, v) in column.iter().enumerate() {
                series[order - 1 - i] = *v;
            }
            for k in order..series.len() {
                series[k] = (0..order).map(|i| a[i] * series[k - 1 - i]).sum();
            }
            for h in 0..steps {
                let now = order - 1 + h;
                model.variance[h] += series[now] * series[now];
                if let Some(v) = model.rate_variance.get_mut(h) {
                    let central = series[now + 1] - series[now - 1];
                    *v += central * central / dt2;
                }
            }
        }
        let finite = model
            .variance
            .iter()
            .chain(&model.rate_variance)
            .all(|v| v.is_finite());
        finite.then_some(model)
    }

    /// The forecast's standard deviation at `t` (the variance interpolated between steps).
    pub fn std(&self, t: f64) -> f64 {
        let s = ((t - self.t0) / self.dt).max(0.0);
        let k = (s.floor() as usize).min(self.variance.len() - 1);
        let k1 = (k + 1).min(self.variance.len() - 1);
        let f = (s - k as f64).clamp(0.0, 1.0);
        (self.variance[k] + f * (self.variance[k1] - self.variance[k])).sqrt()
    }

    /// The standard deviation of the rate's forecast at `t` (unit per second).
    pub fn rate_std(&self, t: f64) -> f64 {
        let s = ((t - self.t0) / self.dt).max(0.0);
        let last = self.rate_variance.len() - 1;
        let k = (s.floor() as usize).min(last);
        let k1 = (k + 1).min(last);
        let f = (s - k as f64).clamp(0.0, 1.0);
        self.rate_variance[k].max(self.rate_variance[k1]).sqrt() * (1.0 - f)
            + f * self.rate_variance[k1].sqrt()
    }

    /// The predicted value at `t` (clamped to the predicted span).
    pub fn value(&self, t: f64) -> f64 {
        let s = ((t - self.t0) / self.dt).max(0.0);
        let k = (s.floor() as usize).min(self.predicted.len() - 1);
        let k1 = (k + 1).min(self.predicted.len() - 1);
        let f = (s - k as f64).clamp(0.0, 1.0);
        self.predicted[k] + f * (self.predicted[k1] - self.predicted[k])
    }

    /// The predicted rate at `t` (unit per second).
    pub fn rate(&self, t: f64) -> f64 {
        // Central differences at the grid points, linearly interpolated: second-order accurate
        // (a forward difference held over a step is off by the rate's change over half a step).
        let s = ((t - self.t0) / self.dt).max(0.0);
        let last = self.predicted.len() - 1;
        let k = (s.floor() as usize).min(last);
        let k1 = (k + 1).min(last);
        let f = (s - k as f64).clamp(0.0, 1.0);
        self.grid_rate(k) + f * (self.grid_rate(k1) - self.grid_rate(k))
    }

    /// The rate at grid point `k`: central, or one-sided at the ends.
    fn grid_rate(&self, k: usize) -> f64 {
        let p = &self.predicted;
        let last = p.len() - 1;
        if k == 0 {
            if self.before_t0.is_finite() {
                (p[1] - self.before_t0) / (2.0 * self.dt)
            } else {
                (p[1] - p[0]) / self.dt
            }
        } else if k >= last {
            (p[last] - p[last - 1]) / self.dt
        } else {
            (p[k + 1] - p[k - 1]) / (2.0 * self.dt)
        }
    }
}

/// The autoregressive forecaster as the decider uses it: recursions of `order` lags on a grid
/// of `grid_step_s`, samples more than `max_bridge_s` apart a gap; with `cross_order` above 0,
/// each channel's recursion may read that many lags of the others too ([`super::joint`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArForecaster {
    pub order: usize,
    pub cross_order: usize,
    pub grid_step_s: f64,
    pub max_bridge_s: f64,
}

impl super::Forecaster for ArForecaster {
    type Channel = ArChannel;

    fn fit(&self, t: &[f64], y: &[&[f64]], horizon_s: f64) -> Option<Vec<ArChannel>> {
        let own = y
            .iter()
            .map(|yk| {
                ArModel::fit_keeping_system(t, yk, self.order, self.grid_step_s, horizon_s, self.max_bridge_s)
            })
            .collect::<Option<Vec<_>>>()?;
        Some(ArChannel::fitted(t, y, own, self.cross_order, horizon_s))
    }

    fn state_span_s(&self) -> f64 {
        ArModel::state_span_s(self.order, self.grid_step_s)
    }

    fn advance_all(&self, forecasts: &mut [ArChannel], t: &[f64], y: &[&[f64]]) {
        ArChannel::advance_all(forecasts, t, y);
    }
}

impl super::ChannelForecast for ArChannel {
    fn t0(&self) -> f64 {
        self.active().t0
    }
    fn value(&self, t: f64) -> f64 {
        self.active().value(t)
    }
    fn rate(&self, t: f64) -> f64 {
        self.active().rate(t)
    }
    fn std(&self, t: f64) -> f64 {
        self.active().std(t)
    }
    fn rate_std(&self, t: f64) -> f64 {
        self.active().rate_std(t)
    }
    fn advanced(&self, t: &[f64], y: &[&[f64]]) -> Option<Self> {
        self.advance(t, y)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// `n` values of the AR(2) process `x_k = a_1 x_{k-1} + a_2 x_{k-2} + sigma e_k`, its
    /// Gaussian innovations from a fixed stream (Box-Muller over SplitMix64's output function
    /// of the index plus `offset`: independent-looking values for consecutive indices).
    pub(in crate::forecast) fn ar2_process(
        n: usize,
        [a1, a2]: [f64; 2],
        sigma: f64,
        offset: u64,
    ) -> Vec<f64> {
        let uniform = |k: u64| {
            let mut z = (k + offset).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 + 0.5 / (1u64 << 53) as f64
        };
        let gaussian = |k: u64| (-2.0 * uniform(2 * k).ln()).sqrt() * (TAU * uniform(2 * k + 1)).cos();
        let mut x = vec![0.0; n];
        for k in 2..n {
            x[k] = a1 * x[k - 1] + a2 * x[k - 2] + sigma * gaussian(k as u64);
        }
        x
    }

    #[test]
    fn ar_predicts_a_sum_of_sinusoids() {
        let f = |t: f64| 4.0 * (TAU * t / 11.0).sin() + 2.0 * (TAU * t / 8.3 + 1.0).sin();
        let t: Vec<f64> = (0..400).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|&t| f(t)).collect();
        let m = ArModel::fit(&t, &y, 8, 0.25, 5.0, 0.5).unwrap();
        // Within 3 % of the 6 deg amplitude: the ridge (`AR_RIDGE`) damps a noise-free sum of
        // sinusoids a little (a noisy sea damps it more by itself).
        for dt in [0.5, 2.0, 3.0] {
            let tt = 39.9 + dt;
            assert!(
                (m.value(tt) - f(tt)).abs() < 0.2,
                "dt {dt}: {}",
                m.value(tt) - f(tt)
            );
        }
        let h = 1e-4;
        assert!((m.rate(41.0) - (f(41.0 + h) - f(41.0 - h)) / (2.0 * h)).abs() < 0.1);
    }

    /// An AR(2) process with known coefficients: the fitted model's stated forecast variance is
    /// the process's exact one, `s^2 sum_{j<h} psi_j^2`, and the truths of many forecasts fall
    /// inside its 95 % band 95 % of the time.
    #[test]
    fn ar_states_the_forecast_variance_of_an_ar_process() {
        let (a1, a2, sigma, dt) = (1.6, -0.8, 0.1, 0.2);
        let n = 60_000usize;
        let x = ar2_process(n, [a1, a2], sigma, 1);
        // Exact: psi_0 = 1, psi_1 = a1, psi_j = a1 psi_{j-1} + a2 psi_{j-2}.
        let mut psi = vec![1.0, a1];
        for j in 2..10 {
            psi.push(a1 * psi[j - 1] + a2 * psi[j - 2]);
        }
        let exact = |h: usize| sigma * sigma * psi[..h].iter().map(|p| p * p).sum::<f64>();
        let (mut inside, mut total) = (0, 0);
        let mut ratios = [0.0; 3];
        let mut fits = 0;
        for start in (400..n - 20).step_by(97) {
            let t: Vec<f64> = (start - 400..=start).map(|k| k as f64 * dt).collect();
            let y: Vec<f64> = (start - 400..=start).map(|k| x[k]).collect();
            let m = ArModel::fit(&t, &y, 2, dt, 2.0, 0.5).unwrap();
            let t0 = *t.last().unwrap();
            for (i, h) in [1usize, 3, 6].into_iter().enumerate() {
                let stated = m.std(t0 + h as f64 * dt).powi(2);
                ratios[i] += stated / exact(h);
                let e = (m.value(t0 + h as f64 * dt) - x[start + h]).abs();
                inside += usize::from(e <= 1.96 * stated.sqrt());
                total += 1;
            }
            fits += 1;
        }
        // One window's coefficients are estimates (400 samples): the stated variance is right
        // on average over many windows.
        for (i, r) in ratios.iter().enumerate() {
            let mean = r / fits as f64;
            assert!(
                (mean - 1.0).abs() < 0.1,
                "horizon #{i}: stated / exact variance {mean}"
            );
        }
        let share = inside as f64 / total as f64;
        assert!(
            (0.93..=0.975).contains(&share),
            "{inside} of {total} inside: {share}"
        );
    }

    /// The same AR(2) process with a gap among the newest lags (six grid points, ending one
    /// before the newest sample): the filter's band holds the truths 95 % of the time, where the
    /// band of a forecast from lags interpolated across the gap holds far fewer.
    #[test]
    fn a_forecast_across_a_gap_states_the_band_the_gap_leaves() {
        let (a1, a2, sigma, dt) = (1.6, -0.8, 0.1, 0.2);
        let n = 60_000usize;
        let x = ar2_process(n, [a1, a2], sigma, 7_000_000);
        // Grid points start-6 ..= start-1 are not measured.
        let in_gap = |k: usize, start: usize| (start - 6..start).contains(&k);
        let (mut inside_filtered, mut inside_bridged, mut total) = (0, 0, 0);
        let mut widened = 0.0;
        for start in (400..n - 20).step_by(97) {
            let kept: Vec<usize> = (start - 400..=start).filter(|&k| !in_gap(k, start)).collect();
            let t: Vec<f64> = kept.iter().map(|&k| k as f64 * dt).collect();
            let y: Vec<f64> = kept.iter().map(|&k| x[k]).collect();
            let filtered = ArModel::fit(&t, &y, 2, dt, 2.0, 0.5).unwrap();
            let bridged = ArModel::fit(&t, &y, 2, dt, 2.0, f64::INFINITY).unwrap();
            let t0 = *t.last().unwrap();
            for h in [1usize, 3, 6] {
                let at = t0 + h as f64 * dt;
                let truth = x[start + h];
                inside_filtered += usize::from((filtered.value(at) - truth).abs() <= 1.96 * filtered.std(at));
                inside_bridged += usize::from((bridged.value(at) - truth).abs() <= 1.96 * bridged.std(at));
                widened += filtered.std(at) / bridged.std(at);
                total += 1;
            }
        }
        let share = |inside: usize| inside as f64 / total as f64;
        assert!(
            (0.93..=0.975).contains(&share(inside_filtered)),
            "filtered: {inside_filtered} of {total} inside"
        );
        assert!(
            share(inside_bridged) < 0.9,
            "bridged: {inside_bridged} of {total} inside"
        );
        assert!(widened / total as f64 > 1.2, "widened {}", widened / total as f64);
    }

    /// Gaps inside the window (three of 2.5 s) leave their rows out of the fit: its coefficients
    /// are the least squares of the rows measured throughout, and its innovation the process's.
    /// Rows on a gap's straight line would have been fitted too (what `max_bridge_s` infinite
    /// does); on this process they understate the innovation.
    #[test]
    fn rows_inside_a_gap_are_left_out_of_the_fit() {
        // A step exact in binary: the resampling grid is then the samples' own times.
        let (a1, a2, sigma, dt) = (1.6, -0.8, 0.1, 0.25);
        let x = ar2_process(401, [a1, a2], sigma, 9_000_000);
        let in_gap = |k: usize| [100usize, 200, 300].iter().any(|&g| (g..g + 10).contains(&k));
        let kept: Vec<usize> = (0..401).filter(|&k| !in_gap(k)).collect();
        let t: Vec<f64> = kept.iter().map(|&k| k as f64 * dt).collect();
        let y: Vec<f64> = kept.iter().map(|&k| x[k]).collect();
        let fitted = ArModel::fit(&t, &y, 2, dt, 2.0, 0.5).unwrap();
        // Rows whose target and lags were all measured.
        let rows: Vec<usize> = (0..401 - 2)
            .filter(|&r| (r..=r + 2).all(|k| !in_gap(k)))
            .collect();
        let a = DMatrix::from_fn(
            rows.len(),
            3,
            |i, j| if j == 2 { 1.0 } else { x[rows[i] + 1 - j] },
        );
        let b = DVector::from_fn(rows.len(), |i, _| x[rows[i] + 2]);
        let exact = a.svd(true, true).solve(&b, 1e-12).unwrap();
        for (got, want) in fitted.coef.iter().zip(exact.iter()) {
            assert!((got - want).abs() < 1e-9, "{:?} vs {exact}", fitted.coef);
        }
        assert!(
            (fitted.fit_rms / sigma - 1.0).abs() < 0.15,
            "innovation {}",
            fitted.fit_rms
        );
        let bridged = ArModel::fit(&t, &y, 2, dt, 2.0, f64::INFINITY).unwrap();
        assert!(
            bridged.fit_rms < fitted.fit_rms,
            "bridged {} kept {}",
            bridged.fit_rms,
            fitted.fit_rms
        );
    }

    /// Gaps that leave too few rows for the order asked for lower the order instead of leaving
    /// no fit: 120 s on the 0.2 s grid with a 3 s gap every 20 s, where every row of 96 lags
    /// reaches into a gap. The fit is of the highest order with `GAPPED_ROWS_PER_COEF` rows per
    /// coefficient, and the same as asking for that order.
    #[test]
    fn gaps_that_leave_too_few_rows_lower_the_order() {
        let (a1, a2, sigma, dt) = (1.6, -0.8, 0.1, 0.2);
        let x = ar2_process(601, [a1, a2], sigma, 11_000_000);
        let in_gap = |k: usize| k % 100 >= 85;
        let kept: Vec<usize> = (0..601).filter(|&k| !in_gap(k)).collect();
        let t: Vec<f64> = kept.iter().map(|&k| k as f64 * dt).collect();
        let y: Vec<f64> = kept.iter().map(|&k| x[k]).collect();
        let lowered = ArModel::fit(&t, &y, 96, dt, 2.0, 0.5).expect("a lower order fits");
        let order = lowered.order();
        assert!((2..96).contains(&order), "order {order}");
        let rows = |p: usize| 601 - p - gap_rows(&resample(&t, &y, dt, 601, 0.5).1, p).len();
        let per_coef = GAPPED_ROWS_PER_COEF;
        assert!(
            rows(order) >= per_coef * (order + 1),
            "{} rows for order {order}",
            rows(order)
        );
        assert!(
            rows(order + 1) < per_coef * (order + 2),
            "order {} fits too",
            order + 1
        );
        let asked = ArModel::fit(&t, &y, order, dt, 2.0, 0.5).unwrap();
        assert_eq!(lowered.coef, asked.coef);
        // Without the gaps the order asked for fits.
        let all: Vec<f64> = (0..601).map(|k| k as f64 * dt).collect();
        assert_eq!(ArModel::fit(&all, &x, 96, dt, 2.0, 0.5).unwrap().order(), 96);
    }
}
