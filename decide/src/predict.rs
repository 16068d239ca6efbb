//! Short-term prediction of one deck angle: the dominant sinusoids of a sliding window.
//!
//! Ship motion is narrow-band: a few periods of 5-20 s dominate roll and pitch. The model is
//! `y(t) = c + sum_k a_k cos(w_k (t - t0)) + b_k sin(w_k (t - t0))`, with `t0` the newest sample.
//! Fitting: the strongest frequency on a grid (least-squares periodogram of the residual), one
//! component at a time, each time re-solving all amplitudes jointly; then Gauss-Newton on every
//! parameter, frequencies included. Samples need not be uniform (dropped frames are fine).

use nalgebra::{DMatrix, DVector};
use std::f64::consts::TAU;

/// One fitted angle.
#[derive(Debug, Clone, PartialEq)]
pub struct SinusoidModel {
    /// Time origin (s): the newest sample of the fit.
    pub t0: f64,
    pub mean: f64,
    /// `(w, a, b)` per component: angular frequency (rad/s) and cosine/sine amplitudes.
    pub components: Vec<(f64, f64, f64)>,
    /// RMS of the fit residual over the window (same unit as the samples).
    pub fit_rms: f64,
}

impl SinusoidModel {
    pub fn value(&self, t: f64) -> f64 {
        let tau = t - self.t0;
        self.mean
            + self
                .components
                .iter()
                .map(|&(w, a, b)| {
                    let (s, c) = (w * tau).sin_cos();
                    a * c + b * s
                })
                .sum::<f64>()
    }

    /// Time derivative (unit per second).
    pub fn rate(&self, t: f64) -> f64 {
        let tau = t - self.t0;
        self.components
            .iter()
            .map(|&(w, a, b)| {
                let (s, c) = (w * tau).sin_cos();
                w * (b * c - a * s)
            })
            .sum()
    }

    /// Fits `components` sinusoids with frequencies in `[f_min_hz, f_max_hz]` to the samples
    /// (`t` increasing, seconds), weighting each by `exp(-age / memory_s)` (infinite: all
    /// alike) so that the fit follows the newest motion. None when there are too few samples
    /// or the solve fails.
    pub fn fit(
        t: &[f64],
        y: &[f64],
        components: usize,
        f_min_hz: f64,
        f_max_hz: f64,
        memory_s: f64,
    ) -> Option<Self> {
        let n = t.len();
        if n != y.len() || n < 4 * components + 4 || !(f_max_hz > f_min_hz && f_min_hz > 0.0) {
            return None;
        }
        let t0 = t[n - 1];
        let span = t0 - t[0];
        if !(span > 0.0) {
            return None;
        }
        let tau: Vec<f64> = t.iter().map(|&ti| ti - t0).collect();
        let w = weights(&tau, memory_s);
        let mut omegas: Vec<f64> = Vec::with_capacity(components);
        let mut params = linear_fit(&tau, y, &w, &omegas)?;
        // Grid fine enough to land within a quarter of the window's frequency resolution.
        let df = 0.25 / span;
        let steps = ((f_max_hz - f_min_hz) / df).ceil() as usize + 1;
        let grid: Vec<f64> = (0..steps)
            .map(|j| TAU * (f_min_hz + j as f64 * df).min(f_max_hz))
            .collect();
        for _ in 0..components {
            let residual = residuals(&tau, y, &omegas, &params);
            let gains = periodogram_gains(&tau, &residual, &w, &grid);
            let mut best = (0.0, f64::NAN);
            for (&om, &gain) in grid.iter().zip(&gains) {
                if omegas.iter().any(|&o| (o - om).abs() < 0.5 * TAU * df) {
                    continue;
                }
                if gain > best.0 {
                    best = (gain, om);
                }
            }
            if !best.1.is_finite() {
                break;
            }
            omegas.push(best.1);
            params = linear_fit(&tau, y, &w, &omegas)?;
        }
        let mut model = refine(&tau, y, &w, &omegas, &params, f_min_hz, f_max_hz);
        model.t0 = t0;
        Some(model)
    }
}

impl SinusoidModel {
    /// Refits to new samples starting from this model's frequencies (no grid search): cheap,
    /// for a sliding window that moved on by a little. None if the solve fails.
    pub fn refit(&self, t: &[f64], y: &[f64], f_min_hz: f64, f_max_hz: f64, memory_s: f64) -> Option<Self> {
        let n = t.len();
        if n != y.len() || n < 4 * self.components.len() + 4 {
            return None;
        }
        let t0 = t[n - 1];
        let tau: Vec<f64> = t.iter().map(|&ti| ti - t0).collect();
        let w = weights(&tau, memory_s);
        let omegas: Vec<f64> = self.components.iter().map(|c| c.0).collect();
        let params = linear_fit(&tau, y, &w, &omegas)?;
        let mut model = refine(&tau, y, &w, &omegas, &params, f_min_hz, f_max_hz);
        model.t0 = t0;
        Some(model)
    }
}

/// Weights of the samples (by age, `tau <= 0`).
fn weights(tau: &[f64], memory_s: f64) -> Vec<f64> {
    tau.iter()
        .map(|&t| {
            if memory_s.is_finite() {
                (t / memory_s).exp()
            } else {
                1.0
            }
        })
        .collect()
}

/// Weighted least-squares reduction of the residual by one sinusoid, for every frequency of
/// `grid` (evenly spaced but for a last one that may be closer). A sample's phasor is turned
/// from one frequency to the next by a multiplication (two trigonometric evaluations per sample
/// instead of one per sample and frequency; the rounding that accumulates over a grid of a few
/// hundred steps is ~1e-13, far below what separates two candidate frequencies).
fn periodogram_gains(tau: &[f64], r: &[f64], wts: &[f64], grid: &[f64]) -> Vec<f64> {
    let n = grid.len();
    // Per frequency: cc, ss, cs, rc, rs.
    let mut acc = vec![[0.0f64; 5]; n];
    let step = if n >= 2 { grid[1] - grid[0] } else { 0.0 };
    for ((&t, &v), &q) in tau.iter().zip(r).zip(wts) {
        let sq = q.sqrt();
        let v = v * sq;
        let (s0, c0) = (grid[0] * t).sin_cos();
        let (ds, dc) = (step * t).sin_cos();
        let (mut s, mut c) = (s0, c0);
        for (j, a) in acc.iter_mut().enumerate() {
            // The grid's last frequency is clamped to its upper end: evaluated directly.
            let (sj, cj) = if j + 1 == n && j > 0 && (grid[j] - grid[j - 1] - step).abs() > 1e-12 {
                (grid[j] * t).sin_cos()
            } else {
                (s, c)
            };
            let (sj, cj) = (sj * sq, cj * sq);
            a[0] += cj * cj;
            a[1] += sj * sj;
            a[2] += cj * sj;
            a[3] += v * cj;
            a[4] += v * sj;
            (s, c) = (s * dc + c * ds, c * dc - s * ds);
        }
    }
    acc.iter()
        .map(|&[cc, ss, cs, rc, rs]| {
            let det = cc * ss - cs * cs;
            if !(det.abs() > 1e-12) {
                return 0.0;
            }
            let a = (rc * ss - rs * cs) / det;
            let b = (rs * cc - rc * cs) / det;
            a * rc + b * rs
        })
        .collect()
}

/// Mean and amplitudes for fixed frequencies: `[c, a_1, b_1, ...]`.
fn linear_fit(tau: &[f64], y: &[f64], wts: &[f64], omegas: &[f64]) -> Option<Vec<f64>> {
    let m = 1 + 2 * omegas.len();
    let a = DMatrix::from_fn(tau.len(), m, |i, j| wts[i].sqrt() * basis(tau[i], omegas, j));
    let b = DVector::from_iterator(y.len(), y.iter().zip(wts).map(|(v, q)| v * q.sqrt()));
    let x = (a.transpose() * &a).cholesky()?.solve(&(a.transpose() * b));
    Some(x.iter().copied().collect())
}

fn basis(t: f64, omegas: &[f64], j: usize) -> f64 {
    if j == 0 {
        return 1.0;
    }
    let w = omegas[(j - 1) / 2];
    if j % 2 == 1 {
        (w * t).cos()
    } else {
        (w * t).sin()
    }
}

fn eval(t: f64, omegas: &[f64], p: &[f64]) -> f64 {
    p[0] + omegas
        .iter()
        .enumerate()
        .map(|(k, &w)| {
            let (s, c) = (w * t).sin_cos();
            p[1 + 2 * k] * c + p[2 + 2 * k] * s
        })
        .sum::<f64>()
}

fn residuals(tau: &[f64], y: &[f64], omegas: &[f64], p: &[f64]) -> Vec<f64> {
    tau.iter().zip(y).map(|(&t, &v)| v - eval(t, omegas, p)).collect()
}

/// `(sin, cos)` of `w_q t_i` for every sample `i` and component `q` (row-major by sample): the
/// one trigonometric evaluation per sample and component that the Jacobian, the residuals and
/// the cost of a parameter set all share.
fn phases(tau: &[f64], omegas: &[f64]) -> Vec<(f64, f64)> {
    tau.iter()
        .flat_map(|&t| omegas.iter().map(move |&w| (w * t).sin_cos()))
        .collect()
}

/// The weighted residuals `sqrt(q_i) (y_i - model(t_i))` from the phases of the model's
/// frequencies, and their weighted sum of squares.
fn weighted_residuals(y: &[f64], wts: &[f64], sc: &[(f64, f64)], k: usize, p: &[f64]) -> (Vec<f64>, f64) {
    let mut cost = 0.0;
    let r = y
        .iter()
        .zip(wts)
        .enumerate()
        .map(|(i, (&v, &q))| {
            let model = p[0]
                + (0..k)
                    .map(|c| {
                        let (s, co) = sc[i * k + c];
                        p[1 + 2 * c] * co + p[2 + 2 * c] * s
                    })
                    .sum::<f64>();
            let r = v - model;
            cost += q * r * r;
            q.sqrt() * r
        })
        .collect();
    (r, cost)
}

/// Levenberg-Marquardt on `[c, a_k, b_k]` and the frequencies together. The phases of the
/// current frequencies are kept from the step that accepted them: an iteration evaluates the
/// trigonometric functions once per sample and component (for its trial step) instead of for
/// every entry of the Jacobian.
fn refine(
    tau: &[f64],
    y: &[f64],
    wts: &[f64],
    omegas: &[f64],
    p: &[f64],
    f_min: f64,
    f_max: f64,
) -> SinusoidModel {
    let k = omegas.len();
    let (mut w, mut p) = (omegas.to_vec(), p.to_vec());
    let mut sc = phases(tau, &w);
    let (mut r, mut c) = weighted_residuals(y, wts, &sc, k, &p);
    let total_weight: f64 = wts.iter().sum();
    let mut lambda = 1e-3;
    for _ in 0..20 {
        // Parameters: p (1 + 2k) then w (k).
        let m = 1 + 3 * k;
        let jac = DMatrix::from_fn(tau.len(), m, |i, j| {
            let sw = wts[i].sqrt();
            if j == 0 {
                return sw;
            }
            if j < 1 + 2 * k {
                let (s, co) = sc[i * k + (j - 1) / 2];
                return sw * if j % 2 == 1 { co } else { s };
            }
            let q = j - 1 - 2 * k;
            let (s, co) = sc[i * k + q];
            sw * tau[i] * (p[2 + 2 * q] * co - p[1 + 2 * q] * s)
        });
        let jt = jac.transpose();
        let mut h = &jt * &jac;
        let g = &jt * DVector::from_column_slice(&r);
        for d in 0..m {
            h[(d, d)] *= 1.0 + lambda;
        }
        let Some(ch) = h.cholesky() else { break };
        let step = ch.solve(&g);
        let p2: Vec<f64> = p.iter().zip(step.iter()).map(|(a, d)| a + d).collect();
        let w2: Vec<f64> = w
            .iter()
            .enumerate()
            .map(|(q, a)| (a + step[1 + 2 * k + q]).clamp(TAU * f_min, TAU * f_max))
            .collect();
        let sc2 = phases(tau, &w2);
        let (r2, c2) = weighted_residuals(y, wts, &sc2, k, &p2);
        if c2 < c {
            let converged = (c - c2) < 1e-12 * c.max(1e-300);
            (p, w, c, r, sc) = (p2, w2, c2, r2, sc2);
            lambda = (lambda * 0.3).max(1e-9);
            if converged {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e6 {
                break;
            }
        }
    }
    SinusoidModel {
        t0: 0.0,
        mean: p[0],
        components: (0..k).map(|q| (w[q], p[1 + 2 * q], p[2 + 2 * q])).collect(),
        fit_rms: (c / total_weight).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth(t: f64) -> f64 {
        13.0 * (TAU * t / 11.0 + 0.3).sin()
            + 8.0 * (TAU * t / 8.3 + 2.0).sin()
            + 4.0 * (TAU * t / 14.7).sin()
            + 0.5
    }

    #[test]
    fn recovers_three_sinusoids_and_predicts() {
        let t: Vec<f64> = (0..600).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|&t| truth(t)).collect();
        let m = SinusoidModel::fit(&t, &y, 3, 0.03, 0.5, f64::INFINITY).unwrap();
        assert!(m.fit_rms < 1e-6, "rms {}", m.fit_rms);
        for dt in [0.5, 2.0, 5.0] {
            let tt = 59.9 + dt;
            assert!((m.value(tt) - truth(tt)).abs() < 1e-4, "dt {dt}");
        }
        let h = 1e-5;
        let numeric = (truth(61.0 + h) - truth(61.0 - h)) / (2.0 * h);
        assert!((m.rate(61.0) - numeric).abs() < 1e-3);
    }

    #[test]
    fn noise_and_gaps_still_predict_seconds_ahead() {
        let mut rng = 12345u64;
        let mut noise = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.2
        };
        let (mut t, mut y) = (Vec::new(), Vec::new());
        for i in 0..600 {
            if i % 7 == 3 {
                continue; // dropped frames
            }
            let ti = i as f64 * 0.1;
            t.push(ti);
            y.push(truth(ti) + noise());
        }
        let m = SinusoidModel::fit(&t, &y, 3, 0.03, 0.5, f64::INFINITY).unwrap();
        assert!(m.fit_rms < 0.1, "rms {}", m.fit_rms);
        for dt in [0.5, 1.0, 3.0] {
            let tt = 59.9 + dt;
            assert!(
                (m.value(tt) - truth(tt)).abs() < 0.1,
                "dt {dt}: {}",
                m.value(tt) - truth(tt)
            );
        }
    }

    #[test]
    fn refuses_too_few_samples() {
        assert!(SinusoidModel::fit(&[0.0, 1.0], &[0.0, 1.0], 3, 0.03, 0.5, 10.0).is_none());
    }
}

/// Rows of the fit per coefficient an autoregression over a history with gaps keeps at least
/// (one without gaps: two, the three samples per coefficient of a short history). With two, the
/// lowered fits of the fault options' gappy histories sent twice as many committed touchdowns
/// around as 48 lags did (105 against 53 on the development seeds); with four, 66 (BENCHMARKS.md,
/// "Forecasts from 19.2 s of lags").
const GAPPED_ROWS_PER_COEF: usize = 4;

/// An autoregressive predictor of one angle: the history resampled on a uniform grid, `x_k` as a
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
        // heave-rate forecast 0.33 m/s short of the truth 2 s ahead: BENCHMARKS.md, "An unsafe
        // commit in main on held-out seeds"). Each gap takes as many rows as there are lags, so
        // a history with gaps fits a lower order too, the highest that keeps `GAPPED_ROWS_PER_COEF`
        // rows per coefficient: with 96 lags the gaps of a frozen camera and a lost attitude
        // stream three times a minute left no fit at all (BENCHMARKS.md, "Forecasts from 19.2 s
        // of lags").
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
        let mut coef = truncated_solve(ata, &atb)?;
        let resid_sq: f64 = (0..n - order)
            .filter(|r| gap_rows.binary_search(r).is_err())
            .map(|r| {
                let predicted = coef[order] + (0..order).map(|i| coef[i] * x[r + order - 1 - i]).sum::<f64>();
                (x[r + order] - predicted).powi(2)
            })
            .sum();
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
        model.forecast_from(&x[newest..], &unmeasured[newest..], t[n_in - 1])
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

/// Singular values of the autoregressive fit's design below this share of the largest are
/// left out. A motion with fewer frequencies than the order leaves directions of the
/// coefficients the data do not fix; solved as they come, they take values that fit the window
/// exactly and then, fed the model's own forecasts, oscillate (a noise-free sea cleared into a
/// heave rate 10 % over the limit). A ridge fixes that too but damps every forecast.
const AR_CUTOFF: f64 = 1e-5;

/// Grid steps a forecast across a gap filters over beyond twice the order: the measured lags
/// before the gap, the gap, and the lags after it.
const GAP_FILTER_EXTRA_STEPS: usize = 8;

/// A measurement's variance in the gap filter, as a share of one innovation's.
const MEASUREMENT_SHARE: f64 = 1e-6;

/// `out = A P A'` for the recursion's companion matrix `A` (first row `a`, ones below the
/// diagonal): the state shifts by one, its newest value the recursion's. `O(p^2)` where a
/// product of dense matrices is `O(p^3)`.
fn propagate(p: &DMatrix<f64>, a: &DVector<f64>, out: &mut DMatrix<f64>) {
    let n = a.len();
    // P a: the covariance of the new value with each old component (P is symmetric).
    let pa = p * a;
    out[(0, 0)] = a.dot(&pa);
    for j in 1..n {
        out[(0, j)] = pa[j - 1];
        out[(j, 0)] = pa[j - 1];
    }
    out.view_mut((1, 1), (n - 1, n - 1))
        .copy_from(&p.view((0, 0), (n - 1, n - 1)));
}

/// The normal equations `(A^T A, A^T b)` of the autoregression of order `p` on `x`: row `r` of
/// `A` is `x[r + p - 1], ..., x[r], 1` and `b[r] = x[r + p]`. Built from lagged products
/// `S(u, v) = sum_r x[r + u] x[r + v]`, whose neighbours along a diagonal differ by one term at
/// each end: `O(n p)` instead of the `O(n p^2)` of multiplying the design out.
pub fn normal_equations(x: &[f64], p: usize) -> (DMatrix<f64>, DVector<f64>) {
    let rows = x.len() - p;
    // Lags 0..=p: lag p is the target's.
    let lags = p + 1;
    let mut s = DMatrix::<f64>::zeros(lags, lags);
    for v in 0..lags {
        s[(0, v)] = (0..rows).map(|r| x[r] * x[r + v]).sum();
    }
    for u in 1..lags {
        for v in u..lags {
            s[(u, v)] = s[(u - 1, v - 1)] - x[u - 1] * x[v - 1] + x[u - 1 + rows] * x[v - 1 + rows];
        }
    }
    let lagged = |u: usize, v: usize| s[(u.min(v), u.max(v))];
    let mut sums = vec![(0..rows).map(|r| x[r]).sum::<f64>(); lags];
    for u in 1..lags {
        sums[u] = sums[u - 1] - x[u - 1] + x[u - 1 + rows];
    }
    // Column i of A is lag p - 1 - i; the last column is the intercept's.
    let ata = DMatrix::from_fn(p + 1, p + 1, |i, j| match (i == p, j == p) {
        (true, true) => rows as f64,
        (true, false) => sums[p - 1 - j],
        (false, true) => sums[p - 1 - i],
        (false, false) => lagged(p - 1 - i, p - 1 - j),
    });
    let atb = DVector::from_fn(p + 1, |i, _| if i == p { sums[p] } else { lagged(p - 1 - i, p) });
    (ata, atb)
}

/// The rows of the autoregression of order `p` (row `r`: target `r + p`, lags `r..r + p`) with
/// a grid point not measured, in increasing order.
fn gap_rows(unmeasured: &[bool], p: usize) -> Vec<usize> {
    let rows = unmeasured.len().saturating_sub(p);
    let mut out = Vec::new();
    // The newest unmeasured point at or before each row's target, found in one pass.
    let mut last_unmeasured: Option<usize> = None;
    for (k, &u) in unmeasured.iter().enumerate().take(p) {
        if u {
            last_unmeasured = Some(k);
        }
    }
    for r in 0..rows {
        if unmeasured[r + p] {
            last_unmeasured = Some(r + p);
        }
        if last_unmeasured.is_some_and(|k| k >= r) {
            out.push(r);
        }
    }
    out
}

/// Row `r` of the design of [`normal_equations`] into `row` (length `p + 1`):
/// `x[r + p - 1], ..., x[r], 1`.
fn design_row(x: &[f64], p: usize, r: usize, row: &mut DVector<f64>) {
    for (i, v) in row.iter_mut().enumerate() {
        *v = if i == p { 1.0 } else { x[r + p - 1 - i] };
    }
}

/// The largest root an autoregressive fit may keep: motion that neither grows nor stays.
const MAX_ROOT_RADIUS: f64 = 0.999;

/// The solution of the normal equations `ata x = atb` (symmetric, positive semi-definite)
/// with the directions whose eigenvalue is below `AR_CUTOFF^2` of the largest left out; None
/// if they are not finite or the decomposition does not converge.
fn truncated_solve(ata: DMatrix<f64>, atb: &DVector<f64>) -> Option<DVector<f64>> {
    if !ata.iter().chain(atb.iter()).all(|v| v.is_finite()) {
        return None;
    }
    let eigen = nalgebra::linalg::SymmetricEigen::try_new(ata, f64::EPSILON, 1000)?;
    let largest = eigen.eigenvalues.max();
    if !(largest > 0.0) {
        return None;
    }
    let projected = eigen.eigenvectors.tr_mul(atb);
    let scaled = DVector::from_fn(atb.len(), |i, _| {
        let l = eigen.eigenvalues[i];
        if l > AR_CUTOFF * AR_CUTOFF * largest {
            projected[i] / l
        } else {
            0.0
        }
    });
    Some(&eigen.eigenvectors * scaled)
}

/// `a` scaled so that every root of `z^p - a_1 z^(p-1) - ... - a_p` is within
/// `MAX_ROOT_RADIUS` (unchanged if they are); None when [`root_radius_bound`] finds none.
fn with_roots_within_max_radius(a: &[f64]) -> Option<Vec<f64>> {
    let radius = root_radius_bound(a)?;
    let r = (MAX_ROOT_RADIUS / radius).min(1.0);
    Some(
        a.iter()
            .enumerate()
            .map(|(i, ai)| ai * r.powi(i as i32 + 1))
            .collect(),
    )
}

/// Relative width to which [`root_radius_bound`] brackets the roots' largest modulus.
const ROOT_RADIUS_TOLERANCE: f64 = 1e-9;

/// A radius that every root of `z^p - a_1 z^(p-1) - ... - a_p` lies within, at most
/// `ROOT_RADIUS_TOLERANCE` (relative) above the largest root's modulus, or `MAX_ROOT_RADIUS`
/// if they all lie within that; None if the coefficients are not finite, or if the step-down
/// cannot place the roots even at 256 times Cauchy's bound (rounding). Bisection with the
/// step-down test ([`roots_within`]), `O(p^2)` a step: the companion matrix's eigenvalues took
/// 2.3 ms at 96 lags, three quarters of a fit, and nalgebra's did not converge on some
/// matrices (a root at every 96th of the circle: BENCHMARKS.md, "The roots' radius by
/// bisection"). A test too close to call counts as roots outside: the bound errs high, and a
/// fit is then damped a hair more, never less.
fn root_radius_bound(a: &[f64]) -> Option<f64> {
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let within = |r: f64| roots_within(a, r) == Some(true);
    if within(MAX_ROOT_RADIUS) {
        return Some(MAX_ROOT_RADIUS);
    }
    // Cauchy's bound: every root lies within 1 + max |a_i|. Doubled while the test cannot
    // tell there (rounding), a few times at most.
    let mut hi = 1.0 + a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut doublings = 0;
    while !within(hi) {
        hi *= 2.0;
        doublings += 1;
        if doublings > 8 {
            return None;
        }
    }
    let mut lo = MAX_ROOT_RADIUS;
    while hi - lo > ROOT_RADIUS_TOLERANCE * hi {
        let mid = 0.5 * (lo + hi);
        if within(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi)
}

/// Reflection coefficients closer to 1 than this leave the step-down of [`roots_within`] to
/// rounding: it answers None, which [`root_radius_bound`] counts as roots outside.
const STEP_DOWN_MIN_GAP: f64 = 1e-9;

/// Whether every root of `z^p - a_1 z^(p-1) - ... - a_p` lies strictly within `radius`: the
/// Schur-Cohn test, `O(p^2)` where the companion matrix's eigenvalues are `O(p^3)`. With
/// `z = radius w` the roots in `w` must lie within the unit circle, which holds exactly when
/// every reflection coefficient of the step-down (Levinson's recursion run backwards) is below
/// 1 in size. None when that is too close to call or a value is not finite.
fn roots_within(a: &[f64], radius: f64) -> Option<bool> {
    if !(radius > 0.0) {
        return None;
    }
    let mut phi: Vec<f64> = a
        .iter()
        .enumerate()
        .map(|(i, ai)| ai / radius.powi(i as i32 + 1))
        .collect();
    let mut next = vec![0.0; phi.len()];
    for m in (1..=phi.len()).rev() {
        let k = phi[m - 1];
        if !k.is_finite() {
            return None;
        }
        let gap = 1.0 - k * k;
        if gap.abs() < STEP_DOWN_MIN_GAP {
            return None;
        }
        if gap < 0.0 {
            return Some(false);
        }
        for j in 0..m - 1 {
            next[j] = (phi[j] + k * phi[m - 2 - j]) / gap;
        }
        phi[..m - 1].copy_from_slice(&next[..m - 1]);
    }
    Some(true)
}

/// The largest modulus of the roots of `z^p - a_1 z^(p-1) - ... - a_p` (the eigenvalues of the
/// recursion's companion matrix); NaN if they cannot be found. The tests' judge of
/// [`root_radius_bound`].
#[cfg(test)]
fn companion_radius(a: &[f64]) -> f64 {
    let p = a.len();
    if !a.iter().all(|v| v.is_finite()) {
        return f64::NAN;
    }
    let companion = DMatrix::from_fn(p, p, |r, c| {
        if r == 0 {
            a[c]
        } else if r == c + 1 {
            1.0
        } else {
            0.0
        }
    });
    // A bounded number of iterations: the unbounded decomposition can loop for ever on some
    // matrices. NaN when it does not converge (the fit is then refused).
    match nalgebra::linalg::Schur::try_new(companion, f64::EPSILON, 1000) {
        Some(schur) => schur
            .complex_eigenvalues()
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max),
        None => f64::NAN,
    }
}

/// `n` values on a uniform grid of step `dt` ending at the newest sample, linearly interpolated
/// between samples (before the first sample, the first value), and which of them were not
/// measured: inside a gap (samples more than `max_bridge_s` apart) or before the first sample.
fn resample(t: &[f64], y: &[f64], dt: f64, n: usize, max_bridge_s: f64) -> (Vec<f64>, Vec<bool>) {
    let n_in = t.len();
    let t0 = t[n_in - 1];
    let mut x = vec![0.0; n];
    let mut unmeasured = vec![false; n];
    let mut j = n_in - 1;
    for (k, (xk, uk)) in x.iter_mut().zip(unmeasured.iter_mut()).enumerate().rev() {
        let g = t0 - (n - 1 - k) as f64 * dt;
        while j > 0 && t[j - 1] >= g {
            j -= 1;
        }
        (*xk, *uk) = if j == 0 {
            // (A grid point a rounding error before the first sample is that sample.)
            (y[0], g < t[0] - 1e-6 * dt)
        } else {
            let (ta, tb) = (t[j - 1], t[j]);
            let f = if tb > ta { (g - ta) / (tb - ta) } else { 1.0 };
            // A grid point on the sample that ends a gap (within a rounding) is that sample:
            // measured.
            (
                y[j - 1] + f.clamp(0.0, 1.0) * (y[j] - y[j - 1]),
                tb - ta > max_bridge_s && f < 1.0 - 1e-6,
            )
        };
    }
    (x, unmeasured)
}

#[cfg(test)]
mod ar_tests {
    use super::*;

    /// `n` values of the AR(2) process `x_k = a_1 x_{k-1} + a_2 x_{k-2} + sigma e_k`, its
    /// Gaussian innovations from a fixed stream (Box-Muller over SplitMix64's output function
    /// of the index plus `offset`: independent-looking values for consecutive indices).
    fn ar2_process(n: usize, [a1, a2]: [f64; 2], sigma: f64, offset: u64) -> Vec<f64> {
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

    #[test]
    fn the_normal_equations_from_lagged_products_are_the_designs() {
        // An irregular series with an offset: every lag and the intercept matter.
        let x: Vec<f64> = (0..90)
            .map(|k| 2.0 + (0.37 * k as f64).sin() + 0.1 * ((k * k) % 7) as f64)
            .collect();
        for p in [2usize, 5, 29] {
            let rows = x.len() - p;
            let a = DMatrix::from_fn(rows, p + 1, |r, i| if i == p { 1.0 } else { x[r + p - 1 - i] });
            let b = DVector::from_fn(rows, |r, _| x[r + p]);
            let (ata, atb) = normal_equations(&x, p);
            let scale = a.tr_mul(&a).amax();
            assert!((ata - a.tr_mul(&a)).amax() < 1e-12 * scale, "order {p}");
            assert!((atb - a.tr_mul(&b)).amax() < 1e-12 * scale, "order {p}");
        }
    }

    #[test]
    fn the_companion_radius_is_the_largest_roots_modulus() {
        // (z - 0.5)(z + 0.8) = z^2 + 0.3 z - 0.4: a_1 = -0.3, a_2 = 0.4.
        assert!((companion_radius(&[-0.3, 0.4]) - 0.8).abs() < 1e-12);
        // A damped oscillation, roots 0.95 e^(+-i 0.3), and a root at 0.2 beside it:
        // (z^2 - 2 r cos(w) z + r^2)(z - 0.2).
        let (r, w) = (0.95f64, 0.3f64);
        let (b1, b2) = (2.0 * r * w.cos(), -r * r);
        let a = [b1 + 0.2, b2 - 0.2 * b1, -0.2 * b2];
        assert!((companion_radius(&a) - 0.95).abs() < 1e-12);
        // Of order 96: x_k = 0.999 x_{k-96} has 96 roots of modulus 0.999^(1/96), evenly
        // around the circle. Nalgebra's Schur decomposition does not converge on it (NaN: no
        // fit); the step-down test places them.
        let mut a = vec![0.0; 96];
        a[95] = 0.999;
        let modulus = 0.999f64.powf(1.0 / 96.0);
        assert_eq!(roots_within(&a, modulus + 1e-7), Some(true));
        assert_eq!(roots_within(&a, modulus - 1e-7), Some(false));
        assert!(companion_radius(&[f64::NAN, 0.1]).is_nan());
    }

    #[test]
    fn the_step_down_test_agrees_with_the_roots() {
        assert_eq!(roots_within(&[-0.3, 0.4], 0.81), Some(true));
        assert_eq!(roots_within(&[-0.3, 0.4], 0.79), Some(false));
        assert_eq!(roots_within(&[f64::NAN, 0.4], 0.9), None);
        // Random recursions of every order up to 96, their roots on both sides of the radius;
        // and the fits of a sea-like series, whose roots crowd the unit circle.
        let mut state = 0x5EEDu64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut checked = [0usize; 2];
        for trial in 0..400 {
            let order = 1 + trial % 96;
            let size = 0.2 + 1.6 * uniform();
            let a: Vec<f64> = (0..order)
                .map(|i| (2.0 * uniform() - 1.0) * size / (i + 1) as f64)
                .collect();
            let radius = companion_radius(&a);
            for r in [0.9, MAX_ROOT_RADIUS, 1.1] {
                if (radius - r).abs() < 1e-6 {
                    continue;
                }
                if let Some(inside) = roots_within(&a, r) {
                    assert_eq!(inside, radius < r, "order {order}, radius {radius}, r {r}");
                    checked[inside as usize] += 1;
                }
            }
        }
        assert!(checked.iter().all(|&n| n > 100), "{checked:?}");
        let dt = 0.2;
        let t: Vec<f64> = (0..600).map(|k| k as f64 * dt).collect();
        for noise in [0.0, 0.01, 0.1] {
            let y: Vec<f64> = t
                .iter()
                .map(|&t| {
                    3.0 * (TAU * t / 9.0).sin()
                        + 1.2 * (TAU * t / 6.5 + 1.0).sin()
                        + noise * (uniform() - 0.5)
                })
                .collect();
            let fit = ArModel::fit(&t, &y, 96, dt, 2.0, 0.5).unwrap();
            let a = &fit.coef[..96];
            assert!(companion_radius(a) <= MAX_ROOT_RADIUS + 1e-9, "noise {noise}");
            // Before it was pulled inside: the swells' roots on the circle, a hair outside.
            let (ata, atb) = normal_equations(&y, 96);
            let raw = truncated_solve(ata, &atb).unwrap();
            let raw = &raw.as_slice()[..96];
            let (bound, radius) = (root_radius_bound(raw).unwrap(), companion_radius(raw));
            assert!(radius > MAX_ROOT_RADIUS, "noise {noise}: {radius}");
            assert!(
                bound >= radius - 1e-12 && bound <= radius * (1.0 + 1e-6),
                "noise {noise}: {bound} against {radius}"
            );
        }
        // The bound against the roots on the random recursions.
        for trial in 0..200 {
            let order = 1 + trial % 96;
            let a: Vec<f64> = (0..order)
                .map(|i| (2.0 * uniform() - 1.0) * 1.5 / (i + 1) as f64)
                .collect();
            let radius = companion_radius(&a);
            if radius.is_finite() {
                let bound = root_radius_bound(&a).unwrap();
                assert!(
                    bound >= radius.max(MAX_ROOT_RADIUS) - 1e-12,
                    "order {order}: {bound} against {radius}"
                );
                assert!(
                    bound <= radius.max(MAX_ROOT_RADIUS) * (1.0 + 1e-6),
                    "order {order}: {bound} against {radius}"
                );
            }
        }
        assert_eq!(root_radius_bound(&[f64::INFINITY]), None);
        // A recursion that grows is pulled inside, its frequencies kept.
        let (r, w) = (1.02f64, 0.3f64);
        let pulled = with_roots_within_max_radius(&[2.0 * r * w.cos(), -r * r]).unwrap();
        let radius = companion_radius(&pulled);
        assert!(
            radius <= MAX_ROOT_RADIUS + 1e-12 && radius > MAX_ROOT_RADIUS - 1e-8,
            "{radius}"
        );
        assert!((pulled[0] / (2.0 * pulled[1].abs().sqrt()) - w.cos()).abs() < 1e-12);
        let calm = [-0.3, 0.4];
        assert_eq!(with_roots_within_max_radius(&calm).unwrap(), calm);
    }

    #[test]
    fn the_truncated_solve_leaves_out_what_the_data_do_not_fix() {
        // Full rank: the exact solution.
        let ata = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let x = DVector::from_column_slice(&[1.0, -2.0, 0.5]);
        let solved = truncated_solve(ata.clone(), &(&ata * &x)).unwrap();
        assert!((solved - &x).amax() < 1e-12);
        // Two equal columns: the direction (1, -1, 0) is not fixed, and the solution has none
        // of it (the least-norm one), where an inverse would blow up.
        let ata = DMatrix::from_row_slice(3, 3, &[2.0, 2.0, 1.0, 2.0, 2.0, 1.0, 1.0, 1.0, 3.0]);
        let atb = DVector::from_column_slice(&[4.0, 4.0, 5.0]);
        let solved = truncated_solve(ata.clone(), &atb).unwrap();
        assert!((solved[0] - solved[1]).abs() < 1e-9);
        assert!((&ata * &solved - &atb).amax() < 1e-9);
        assert!(truncated_solve(DMatrix::zeros(2, 2), &DVector::zeros(2)).is_none());
        let mut bad = ata.clone();
        bad[(1, 2)] = f64::INFINITY;
        assert!(truncated_solve(bad, &atb).is_none());
    }
}
