//! The joint autoregression (`[decide.forecast] cross_order`): each channel's recursion reads
//! the other channels' newest lags beside its own. Roll, pitch and the deck's height answer the
//! same waves, and a pad away from the centre of gravity heaves with the roll and the pitch: one
//! channel's recent past tells of another's next seconds. A channel keeps the other channels'
//! lags only when they explain more than their number costs (Akaike's information criterion
//! in its small-sample form, AICc, on its one-step residuals); otherwise its recursion is its
//! own autoregression's.
//!
//! The joint model runs all channels forward together; its stated uncertainty is the vector
//! recursion's (the impulse responses `Psi_j`, the innovations' covariance `Sigma`): the error
//! `h` steps ahead has covariance `sum_{j<h} Psi_j Sigma Psi_j'`. A forecast whose newest lags
//! lie in a gap is the channel's own autoregression's, which filters across it
//! ([`ArModel`]'s notes).

use super::ar::{ArModel, OwnSystem};
use super::ar_numerics::{dot, gap_rows, lagged_products, resample, truncated_solve};
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// A joint forecast whose stated variance at its longest step exceeds this many times the
/// series' own variance grows without bound (a recursion with a root outside the unit circle,
/// which the vector fit does not pull in as the per-channel one does): it is not used.
const UNSTABLE_VARIANCE_RATIO: f64 = 4.0;

/// The joint recursion of every channel, fitted on one history.
#[derive(Debug, Clone, PartialEq)]
pub struct JointAr {
    pub dt: f64,
    /// Lags of a channel's own values in its recursion.
    pub order: usize,
    /// Lags of each other channel's values.
    pub cross_order: usize,
    /// Per channel: its own lags 1..=order, then each other channel's (in channel order) lags
    /// 1..=cross_order, then the intercept. A channel that kept no other channel's lags has
    /// those coefficients 0 and its own autoregression's elsewhere.
    pub coef: Vec<Vec<f64>>,
    /// Which channels read the others' lags.
    pub joint: Vec<bool>,
    /// Per channel, the stated variance of the value's forecast error at each grid step.
    pub variance: Vec<Vec<f64>>,
    /// Per channel, the stated variance of the rate's (central difference) error at each step.
    pub rate_variance: Vec<Vec<f64>>,
    pub max_bridge_s: f64,
}

impl JointAr {
    /// Fits beside the channels' own autoregressions `own` (fitted on the same samples, with
    /// the systems they solved): each channel's system is extended by the other channels'
    /// `cross_order` lags and solved by its Schur complement (the own normal equations'
    /// decomposition reused: a 48-column solve where the whole system would be 145). On a
    /// history too short for the own order and the cross lags together (two rows per
    /// coefficient, as the own fit keeps), the joint fit takes fewer own lags of its own. None
    /// when there is nothing joint to gain: one channel, `cross_order` 0, own fits of unequal
    /// order, too few rows, no channel whose residual the cross lags lower enough, or a
    /// recursion that grows.
    pub(super) fn fit(own: &[(ArModel, OwnSystem)], cross_order: usize, horizon_s: f64) -> Option<Self> {
        let channels = own.len();
        let first = &own.first()?.0;
        let (dt, order, max_bridge_s) = (first.dt, first.coef.len() - 1, first.max_bridge_s);
        let q = cross_order.min(order);
        let n = own[0].1.x.len();
        let equal = own
            .iter()
            .all(|(m, s)| m.coef.len() == order + 1 && s.x.len() == n);
        if channels < 2 || q == 0 || !equal {
            return None;
        }
        let unmeasured = &own[0].1.unmeasured;
        let cross = (channels - 1) * q;
        let kept_rows = |p: usize, gaps: &[usize]| -> Vec<usize> {
            (0..n.saturating_sub(p))
                .filter(|r| gaps.binary_search(r).is_err())
                .collect()
        };
        // The own lags the joint fit can afford, and its systems: the own fits' where the rows
        // allow, else re-solved at the lower order.
        let (joint_order, rebuilt) = if kept_rows(order, &own[0].1.gap_rows).len() >= 2 * (order + cross + 1)
        {
            (order, None)
        } else {
            let p = (q..order)
                .rev()
                .find(|&p| kept_rows(p, &gap_rows(unmeasured, p)).len() >= 2 * (p + cross + 1))?;
            let systems = own
                .iter()
                .map(|(_, s)| {
                    OwnSystem::solve(s.x.clone(), s.unmeasured.clone(), gap_rows(unmeasured, p), p)
                        .map(|(s, _)| s)
                })
                .collect::<Option<Vec<OwnSystem>>>()?;
            (p, Some(systems))
        };
        let systems: Vec<&OwnSystem> = match &rebuilt {
            Some(s) => s.iter().collect(),
            None => own.iter().map(|(_, s)| s).collect(),
        };
        let p = joint_order;
        let rows = kept_rows(p, &systems[0].gap_rows);
        let m = rows.len() as f64;
        // The own fits' rows and residuals: the baseline each channel's joint fit must beat.
        let own_rows = kept_rows(order, &own[0].1.gap_rows).len() as f64;
        // The information criterion on the mean squared residual per row: AICc's price,
        // `2 k m / (m - k - 1)` for k coefficients, the joint fit's less the own fit's, both on
        // the joint fit's m rows. On the 600 s window it is about Akaike's 2 a coefficient (the
        // Bayesian `ln m`, about 8, used fewer calm windows there); on a minute's history, where
        // the joint fit keeps two rows a coefficient, it is steeper (108 coefficients on 217
        // rows: 80 against the Bayesian 59), which keeps that history from overfitting
        // (docs/history.md, "Cross lags priced by AICc"). A price that is not finite (no row to
        // spare) keeps no cross lag.
        let aicc_price = |k: f64| match m - k - 1.0 > 0.0 {
            true => 2.0 * k * m / (m - k - 1.0),
            false => f64::INFINITY,
        };
        let price = aicc_price((p + cross + 1) as f64) - aicc_price((order + 1) as f64);
        let params = order + cross + 1;
        // Every pair of channels' lagged products over the kept rows (`products[a][b]` for
        // a <= b; the other order is its transpose): the joint normal equations' blocks.
        let gaps = &systems[0].gap_rows;
        let mut products = vec![Vec::new(); channels];
        let mut sums = Vec::with_capacity(channels);
        for a in 0..channels {
            for b in a..channels {
                let (s, lagged_sums) = lagged_products(&systems[a].x, &systems[b].x, p, gaps);
                products[a].push(s);
                if a == b {
                    sums.push(lagged_sums);
                }
            }
        }
        let product = |a: usize, b: usize, u: usize, v: usize| match a <= b {
            true => products[a][b - a][(u, v)],
            false => products[b][a - b][(v, u)],
        };
        let mut coef = Vec::with_capacity(channels);
        let mut joint = Vec::with_capacity(channels);
        for c in 0..channels {
            let system = systems[c];
            let x = &system.x;
            // Cross column k: channel `others[k / q]`'s lag `k % q + 1`, offset `p - 1 - k % q`
            // from a row's first grid point (own column i: offset `p - 1 - i`; the target: `p`).
            let others: Vec<usize> = (0..channels).filter(|&j| j != c).collect();
            let cross_of = |k: usize| (others[k / q], p - 1 - k % q);
            // [[A, B], [B', D]] [own; cross] = [a; d], with A's pseudo-inverse known: the cross
            // lags' coefficients solve the Schur complement S = D - B' A+ B.
            let between = DMatrix::from_fn(p + 1, cross, |col, k| {
                let (o, v) = cross_of(k);
                match col == p {
                    true => sums[o][v],
                    false => product(c, o, p - 1 - col, v),
                }
            });
            let cross_gram = DMatrix::from_fn(cross, cross, |k, l| {
                let ((o, u), (j, v)) = (cross_of(k), cross_of(l));
                product(o, j, u, v)
            });
            let cross_target = DVector::from_fn(cross, |k, _| {
                let (o, u) = cross_of(k);
                product(o, c, u, p)
            });
            let a_inv_between = system.inverse.apply(&between);
            let schur = cross_gram - between.transpose() * &a_inv_between;
            let rhs = cross_target - a_inv_between.transpose() * &system.atb;
            let solved = truncated_solve(schur, &rhs).map(|cross_coef| {
                let own_coef = system.inverse.apply(&system.atb) - &a_inv_between * &cross_coef;
                // The coefficients oldest lag first, as the grids run: each part a dot product.
                let own_reversed: Vec<f64> = (0..p).rev().map(|i| own_coef[i]).collect();
                let cross_reversed: Vec<Vec<f64>> = cross_coef
                    .as_slice()
                    .chunks(q)
                    .map(|lags| lags.iter().rev().copied().collect())
                    .collect();
                let rss: f64 = rows
                    .iter()
                    .map(|&r| {
                        let predicted = own_coef[p]
                            + dot(&own_reversed, &x[r..r + p])
                            + others
                                .iter()
                                .zip(&cross_reversed)
                                .map(|(&o, lags)| dot(lags, &systems[o].x[r + p - q..r + p]))
                                .sum::<f64>();
                        (x[r + p] - predicted).powi(2)
                    })
                    .sum();
                (own_coef, cross_coef, rss)
            });
            let rss_own = own[c].1.resid_sq;
            let keeps = solved.as_ref().is_some_and(|(_, _, rss)| {
                price.is_finite()
                    && rss_own > 0.0
                    && *rss > 0.0
                    && m * ((rss / m) / (rss_own / own_rows)).ln() + price < 0.0
            });
            let mut all = vec![0.0; params];
            match solved.filter(|_| keeps) {
                Some((own_coef, cross_coef, _)) => {
                    all[..p].copy_from_slice(&own_coef.as_slice()[..p]);
                    all[order..order + cross].copy_from_slice(cross_coef.as_slice());
                    all[params - 1] = own_coef[p];
                }
                // Its own autoregression (the roots it keeps pulled in), the cross lags 0.
                None => {
                    all[..order].copy_from_slice(&own[c].0.coef[..order]);
                    all[params - 1] = own[c].0.coef[order];
                }
            }
            coef.push(all);
            joint.push(keeps);
        }
        if !joint.iter().any(|&k| k) {
            return None;
        }
        // The innovations' covariance, from every channel's one-step residuals on the rows
        // of the own fits (where every lag of every recursion is measured).
        let grids: Vec<&[f64]> = systems.iter().map(|s| s.x.as_slice()).collect();
        let targets: Vec<usize> = kept_rows(order, &own[0].1.gap_rows)
            .iter()
            .map(|r| r + order)
            .collect();
        let residuals: Vec<Vec<f64>> = (0..channels)
            .map(|c| {
                targets
                    .iter()
                    .map(|&k| grids[c][k] - Self::one_step(&coef[c], order, q, c, &grids, k))
                    .collect()
            })
            .collect();
        let m = targets.len() as f64;
        let used = |c: usize| if joint[c] { p + cross + 1 } else { order + 1 } as f64;
        let sigma = DMatrix::from_fn(channels, channels, |a, b| {
            let dof = ((m - used(a)).max(1.0) * (m - used(b)).max(1.0)).sqrt();
            let inflation = ((1.0 + used(a) / m) * (1.0 + used(b) / m)).sqrt();
            residuals[a]
                .iter()
                .zip(&residuals[b])
                .map(|(u, v)| u * v)
                .sum::<f64>()
                / dof
                * inflation
        });
        let mut model = Self {
            dt,
            order,
            cross_order: q,
            coef,
            joint,
            variance: Vec::new(),
            rate_variance: Vec::new(),
            max_bridge_s,
        };
        let steps = ((horizon_s / dt).ceil() as usize).max(1);
        model.state_variances(&sigma, steps);
        let grows = (0..channels).any(|c| {
            let (last, own) = (model.variance[c][steps], &own[c].0);
            !last.is_finite() || last > UNSTABLE_VARIANCE_RATIO * own.series_var.max(own.variance[steps])
        });
        (!grows).then_some(model)
    }

    /// Channel `c`'s recursion (`coef`, laid out as [`Self::coef`]) at grid point `k` of the
    /// channels' grids `x`: its one-step prediction.
    fn one_step(coef: &[f64], order: usize, cross_order: usize, c: usize, x: &[&[f64]], k: usize) -> f64 {
        let own: f64 = (0..order).map(|i| coef[i] * x[c][k - 1 - i]).sum();
        let others = x.iter().enumerate().filter(|(j, _)| *j != c).map(|(_, s)| s);
        let cross: f64 = others
            .enumerate()
            .map(|(slot, s)| {
                let base = order + slot * cross_order;
                (0..cross_order)
                    .map(|i| coef[base + i] * s[k - 1 - i])
                    .sum::<f64>()
            })
            .sum();
        own + cross + coef[coef.len() - 1]
    }

    /// The lag-`lag` coefficient matrix `A_lag` (channels x channels) of the vector recursion.
    fn lag_matrix(&self, lag: usize) -> DMatrix<f64> {
        let channels = self.coef.len();
        DMatrix::from_fn(channels, channels, |c, j| {
            if c == j {
                self.coef[c][lag - 1]
            } else if lag <= self.cross_order {
                let slot = if j < c { j } else { j - 1 };
                self.coef[c][self.order + slot * self.cross_order + lag - 1]
            } else {
                0.0
            }
        })
    }

    /// The stated variances of every channel's value and rate, `steps` grid steps ahead.
    fn state_variances(&mut self, sigma: &DMatrix<f64>, steps: usize) {
        let channels = self.coef.len();
        let lags: Vec<DMatrix<f64>> = (1..=self.order).map(|l| self.lag_matrix(l)).collect();
        // Psi_0 = I, Psi_h = sum_{i=1..min(h, order)} A_i Psi_{h-i}.
        let mut psi = vec![DMatrix::<f64>::identity(channels, channels)];
        for h in 1..steps + 2 {
            let mut next = DMatrix::<f64>::zeros(channels, channels);
            for i in 1..=h.min(self.order) {
                next.gemm(1.0, &lags[i - 1], &psi[h - i], 1.0);
            }
            psi.push(next);
        }
        let diagonal = |m: &DMatrix<f64>| -> Vec<f64> {
            let v = m * sigma * m.transpose();
            (0..channels).map(|c| v[(c, c)]).collect()
        };
        let innovation: Vec<f64> = (0..channels).map(|c| sigma[(c, c)]).collect();
        let four_dt2 = 4.0 * self.dt * self.dt;
        self.variance = innovation.iter().map(|&s| vec![s]).collect();
        self.rate_variance = innovation.iter().map(|&s| vec![s / four_dt2]).collect();
        let mut acc = vec![0.0; channels];
        for p in psi.iter().take(steps) {
            for (c, d) in diagonal(p).into_iter().enumerate() {
                acc[c] += d;
                self.variance[c].push(acc[c].max(innovation[c]));
            }
        }
        // The rate at step h is (x_{h+1} - x_{h-1}) / 2dt: its error weighs the innovations by
        // D_j = Psi_j - Psi_{j-2}.
        let mut acc: Vec<f64> = diagonal(&psi[0])
            .iter()
            .zip(diagonal(&psi[1]))
            .map(|(a, b)| a + b)
            .collect();
        for h in 1..=steps {
            if h >= 2 {
                for (c, d) in diagonal(&(&psi[h] - &psi[h - 2])).into_iter().enumerate() {
                    acc[c] += d;
                }
            }
            for (rates, a) in self.rate_variance.iter_mut().zip(&acc) {
                rates.push(a / four_dt2);
            }
        }
    }

    /// Every channel's predicted grid values, `[0]` the newest measured, run forward from the
    /// newest `order` grid values of each channel (`x[c]`, oldest first).
    fn predict(&self, x: &[&[f64]]) -> Option<Vec<Vec<f64>>> {
        let channels = self.coef.len();
        let steps = self.variance.first()?.len() - 1;
        if x.len() != channels || x.iter().any(|s| s.len() < self.order) {
            return None;
        }
        let mut series: Vec<Vec<f64>> = x.iter().map(|s| s[s.len() - self.order..].to_vec()).collect();
        let mut predicted: Vec<Vec<f64>> = series.iter().map(|s| vec![s[self.order - 1]]).collect();
        for _ in 0..steps {
            let lags: Vec<&[f64]> = series.iter().map(Vec::as_slice).collect();
            let k = lags[0].len();
            let next: Vec<f64> = (0..channels)
                .map(|c| Self::one_step(&self.coef[c], self.order, self.cross_order, c, &lags, k))
                .collect();
            for (c, v) in next.into_iter().enumerate() {
                series[c].push(v);
                predicted[c].push(v);
            }
        }
        predicted
            .iter()
            .flatten()
            .all(|v| v.is_finite())
            .then_some(predicted)
    }
}

/// One channel's forecast of the autoregressive forecaster: its own autoregression, and the
/// joint recursion's path for it when there is one and its newest lags were all measured.
#[derive(Debug, Clone, PartialEq)]
pub struct ArChannel {
    /// Which channel of the samples this forecasts.
    pub channel: usize,
    /// The channel's own autoregression (across a gap, the forecast).
    pub own: ArModel,
    /// The joint recursion, shared by every channel's forecast of one fit.
    pub joint: Option<Arc<JointAr>>,
    /// The joint recursion's forecast of this channel from the newest samples; None when a
    /// lag of any channel lay in a gap (the own forecast is then used).
    pub path: Option<ArModel>,
}

impl ArChannel {
    /// The forecast in use: the joint path where there is one, else the own.
    pub fn active(&self) -> &ArModel {
        self.path.as_ref().unwrap_or(&self.own)
    }

    /// This channel's forecast along the joint recursion's `paths` (from [`JointAr::paths`]).
    fn along(&self, paths: &JointPaths) -> ArModel {
        let (joint, c, own) = (&paths.joint, self.channel, &self.own);
        // Field by field: `..own.clone()` would copy the own forecast's paths every frame only
        // to drop them.
        ArModel {
            t0: paths.t0,
            dt: own.dt,
            predicted: paths.predicted[c].clone(),
            fit_rms: own.fit_rms,
            variance: joint.variance[c].clone(),
            rate_variance: joint.rate_variance[c].clone(),
            coef: own.coef.clone(),
            before_t0: paths.before_t0[c],
            series_var: own.series_var,
            max_bridge_s: own.max_bridge_s,
        }
    }

    /// Every channel's forecast from one fit on samples `t`, `y`: the own autoregressions
    /// (with their systems), and the joint recursion beside them when it explains more.
    pub(super) fn fitted(
        t: &[f64],
        y: &[&[f64]],
        own: Vec<(ArModel, OwnSystem)>,
        cross_order: usize,
        horizon_s: f64,
    ) -> Vec<Self> {
        let joint = JointAr::fit(&own, cross_order, horizon_s).map(Arc::new);
        let paths = joint.as_ref().and_then(|j| j.paths(t, y));
        own.into_iter()
            .enumerate()
            .map(|(channel, (own, _))| {
                let mut forecast = Self {
                    channel,
                    own,
                    joint: joint.clone(),
                    path: None,
                };
                forecast.path = paths.as_ref().map(|p| forecast.along(p));
                forecast
            })
            .collect()
    }

    /// Run forward from the newest samples of every channel (`t` increasing): the own
    /// autoregression as [`ArModel::advance`], the joint path where its lags were measured.
    pub fn advance(&self, t: &[f64], y: &[&[f64]]) -> Option<Self> {
        let paths = self.joint.as_ref().and_then(|j| j.paths(t, y));
        self.advanced_along(t, y, paths.as_ref())
    }

    /// [`Self::advance`] with the joint recursion's paths given (run once for every channel).
    fn advanced_along(&self, t: &[f64], y: &[&[f64]], paths: Option<&JointPaths>) -> Option<Self> {
        // Built afresh: cloning `self` would copy the old own forecast and path every frame.
        let mut next = Self {
            channel: self.channel,
            own: self.own.advance(t, y.get(self.channel)?)?,
            joint: self.joint.clone(),
            path: None,
        };
        next.path = paths.map(|p| next.along(p));
        Some(next)
    }

    /// Every channel's forecast of one fit run forward from the newest samples together: the
    /// joint recursion once for all of them (per channel, it would run once for each). A
    /// forecast that cannot be run forward stays as it was.
    pub fn advance_all(forecasts: &mut [Self], t: &[f64], y: &[&[f64]]) {
        let shared = forecasts.first().and_then(|f| f.joint.clone());
        let one_joint = forecasts.iter().all(|f| match (&f.joint, &shared) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        });
        if !one_joint {
            for f in forecasts.iter_mut() {
                if let Some(next) = f.advance(t, y) {
                    *f = next;
                }
            }
            return;
        }
        let paths = shared.and_then(|j| j.paths(t, y));
        for f in forecasts.iter_mut() {
            if let Some(next) = f.advanced_along(t, y, paths.as_ref()) {
                *f = next;
            }
        }
    }
}

/// The joint recursion run forward from the newest samples: every channel's predicted grid
/// values and the grid value before the newest (for the rate at the start).
#[derive(Debug, Clone)]
struct JointPaths {
    joint: Arc<JointAr>,
    t0: f64,
    predicted: Vec<Vec<f64>>,
    before_t0: Vec<f64>,
}

impl JointAr {
    /// The recursion run forward from the samples `t`, `y` (every channel), ending at the
    /// newest: None when a needed lag lies in a gap (or there are too few samples).
    fn paths(self: &Arc<Self>, t: &[f64], y: &[&[f64]]) -> Option<JointPaths> {
        let n_in = t.len();
        if n_in < 2 || y.len() != self.coef.len() || y.iter().any(|c| c.len() != n_in) {
            return None;
        }
        let n = (((t[n_in - 1] - t[0]) / self.dt).floor() as usize + 1).min(self.order + 1);
        if n < self.order + 1 {
            return None;
        }
        let grids: Vec<(Vec<f64>, Vec<bool>)> = y
            .iter()
            .map(|c| resample(t, c, self.dt, n, self.max_bridge_s))
            .collect();
        if grids
            .iter()
            .any(|(_, unmeasured)| unmeasured[n - self.order..].iter().any(|&u| u))
        {
            return None;
        }
        let x: Vec<&[f64]> = grids.iter().map(|g| g.0.as_slice()).collect();
        Some(JointPaths {
            joint: Arc::clone(self),
            t0: t[n_in - 1],
            predicted: self.predict(&x)?,
            before_t0: x.iter().map(|c| c[n - 2]).collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::ar::tests::ar2_process;
    use crate::forecast::{ArForecaster, ChannelForecast, Forecaster};

    const DT: f64 = 0.2;

    fn forecaster() -> ArForecaster {
        ArForecaster {
            order: 24,
            cross_order: 8,
            grid_step_s: DT,
            max_bridge_s: 0.5,
        }
    }

    /// A narrow-band motion (an 8 s period) and a noisy copy of it a second late: what the
    /// second channel does next, the first did already.
    fn led_and_following(n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let (r, w) = (0.98_f64, std::f64::consts::TAU * DT / 8.0);
        let lead = ar2_process(n, [2.0 * r * w.cos(), -r * r], 0.1, 0);
        let noise = ar2_process(n, [0.0, 0.0], 0.05, 1 << 40);
        let follow = (0..n)
            .map(|k| if k >= 5 { 0.8 * lead[k - 5] } else { 0.0 } + noise[k])
            .collect();
        let t = (0..n).map(|k| k as f64 * DT).collect();
        (t, lead, follow)
    }

    #[test]
    fn a_channel_that_follows_another_reads_its_lags_and_states_what_it_misses() {
        let (t, lead, follow) = led_and_following(6000);
        let (window, ahead) = (1200, 10);
        let (mut own_sq, mut joint_sq, mut stated_sq, mut count) = (0.0, 0.0, 0.0, 0.0);
        for end in (window..t.len() - ahead).step_by(97) {
            let range = end - window..end;
            let y = [&lead[range.clone()], &follow[range.clone()]];
            let fits = forecaster().fit(&t[range], &y, 5.0).unwrap();
            let joint = fits[1].joint.as_ref().expect("a joint model");
            assert_eq!(
                joint.joint,
                vec![false, true],
                "only the follower gains from the other's lags"
            );
            let at = t[end - 1] + ahead as f64 * DT;
            let truth = follow[end - 1 + ahead];
            own_sq += (fits[1].own.value(at) - truth).powi(2);
            joint_sq += (fits[1].value(at) - truth).powi(2);
            stated_sq += fits[1].std(at).powi(2);
            count += 1.0;
            // The leader's forecast is its own autoregression's, run by the joint recursion.
            assert!((fits[0].value(at) - fits[0].own.value(at)).abs() < 1e-9);
        }
        let (own, joint, stated) = (
            (own_sq / count).sqrt(),
            (joint_sq / count).sqrt(),
            (stated_sq / count).sqrt(),
        );
        assert!(joint < 0.7 * own, "2 s ahead: joint {joint:.4}, own {own:.4}");
        assert!(
            (0.75..1.33).contains(&(stated / joint)),
            "stated {stated:.4}, missed {joint:.4}"
        );
    }

    /// The joint fit's blocks come from lagged products summed over the runs of rows between
    /// gaps; its coefficients must be the extended system's least squares over the rows that
    /// have every lag measured, as if the design were written out.
    #[test]
    fn the_joint_coefficients_are_the_least_squares_of_the_written_out_design() {
        let (t, lead, follow) = led_and_following(1500);
        // A 3 s gap (samples dropped) makes a run of unmeasured grid points.
        let kept: Vec<usize> = (0..t.len()).filter(|k| !(600..615).contains(k)).collect();
        let t: Vec<f64> = kept.iter().map(|&k| t[k]).collect();
        let y: Vec<Vec<f64>> = [&lead, &follow]
            .iter()
            .map(|c| kept.iter().map(|&k| c[k]).collect())
            .collect();
        let (order, cross_order) = (12, 4);
        let own: Vec<_> = y
            .iter()
            .map(|c| super::ArModel::fit_keeping_system(&t, c, order, DT, 5.0, 0.5).unwrap())
            .collect();
        assert!(!own[0].1.gap_rows.is_empty(), "the gap leaves rows out");
        let joint = super::JointAr::fit(&own, cross_order, 5.0).expect("a joint fit");
        assert_eq!(joint.joint, vec![false, true]);
        let (x, other) = (&own[1].1.x, &own[0].1.x);
        let rows: Vec<usize> = (0..x.len() - order)
            .filter(|r| own[0].1.gap_rows.binary_search(r).is_err())
            .collect();
        let columns = order + cross_order + 1;
        let design = nalgebra::DMatrix::from_fn(rows.len(), columns, |i, col| {
            let r = rows[i];
            match col {
                c if c < order => x[r + order - 1 - c],
                c if c < order + cross_order => other[r + order - 1 - (c - order)],
                _ => 1.0,
            }
        });
        let target = nalgebra::DVector::from_fn(rows.len(), |i, _| x[rows[i] + order]);
        let solved = design.svd(true, true).solve(&target, 1e-12).unwrap();
        for (col, (&fitted, &written)) in joint.coef[1].iter().zip(solved.iter()).enumerate() {
            assert!(
                (fitted - written).abs() < 1e-8,
                "coefficient {col}: {fitted} against {written}"
            );
        }
    }

    #[test]
    fn a_history_too_short_for_every_lag_reads_the_other_channel_with_fewer_of_its_own() {
        // A minute on the grid: the own fits take 96 lags, too many to add 24 of the other's.
        let (t, lead, follow) = led_and_following(300);
        let forecaster = ArForecaster {
            order: 96,
            cross_order: 24,
            ..forecaster()
        };
        let fits = forecaster.fit(&t, &[&lead, &follow], 5.0).unwrap();
        assert_eq!(fits[1].own.coef.len(), 97);
        let joint = fits[1].joint.as_ref().expect("a joint model on a minute");
        assert_eq!(joint.joint, vec![false, true]);
        let own_lags = joint.coef[1][..96].iter().rposition(|&a| a != 0.0).unwrap() + 1;
        assert!((24..96).contains(&own_lags), "{own_lags} own lags");
        // The leader keeps its own recursion, all 96 lags.
        assert_eq!(joint.coef[0][..96], fits[0].own.coef[..96]);
        assert!(fits[1].path.is_some());
    }

    #[test]
    fn unrelated_channels_keep_their_own_recursions() {
        let n = 1200;
        let (r, w) = (0.98_f64, std::f64::consts::TAU * DT / 8.0);
        let a = ar2_process(n, [2.0 * r * w.cos(), -r * r], 0.1, 0);
        let b = ar2_process(n, [2.0 * r * w.cos(), -r * r], 0.1, 1 << 40);
        let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
        let fits = forecaster().fit(&t, &[&a, &b], 5.0).unwrap();
        assert!(fits.iter().all(|f| f.joint.is_none() && f.path.is_none()));
        assert_eq!(fits[0].active(), &fits[0].own);
    }

    #[test]
    fn a_gap_in_the_newest_lags_falls_back_to_the_channels_own_forecast() {
        let (t, lead, follow) = led_and_following(1400);
        let fits = forecaster()
            .fit(&t[..1200], &[&lead[..1200], &follow[..1200]], 5.0)
            .unwrap();
        assert!(fits[1].path.is_some());
        // The next 200 samples, the last second but one missing (a frozen camera).
        let kept: Vec<usize> = (1100..1400).filter(|&k| !(1390..1396).contains(&k)).collect();
        let pick = |v: &[f64]| kept.iter().map(|&k| v[k]).collect::<Vec<f64>>();
        let (tk, lk, fk) = (pick(&t), pick(&lead), pick(&follow));
        let advanced = fits[1].advanced(&tk, &[&lk, &fk]).unwrap();
        assert!(advanced.path.is_none(), "a lag in the gap: no joint path");
        assert_eq!(advanced.active(), &advanced.own);
        assert!(advanced.std(advanced.t0() + 1.0) > fits[1].own.std(fits[1].own.t0 + 1.0));
        // Measured again: the joint path is back.
        let whole: Vec<usize> = (1100..1400).collect();
        let pick = |v: &[f64]| whole.iter().map(|&k| v[k]).collect::<Vec<f64>>();
        let advanced = fits[1]
            .advanced(&pick(&t), &[&pick(&lead), &pick(&follow)])
            .unwrap();
        assert!(advanced.path.is_some());
    }
}
