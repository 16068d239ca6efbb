//! The band's coverage over a touchdown, kept honest on the sea it meets: every few tenths of a
//! second the forecast of the next touchdown is stated (its mean and 95 % band per quantity);
//! once the touchdown and the samples that measure its rates have come, each quantity is judged
//! on whether the measurements stayed inside the stated band all through it; and each
//! quantity's band is widened or narrowed back by the outcome (adaptive conformal inference,
//! Gibbs and Candès 2021): up by `COVERAGE_STEP` times 0.95 after a miss, down by
//! `COVERAGE_STEP` times 0.05 after a hold, so that over any long run the share of touchdowns
//! the band missed is within `(ln MAX_WIDENING + COVERAGE_STEP) / (COVERAGE_STEP n)` of 5 %,
//! whatever the sea, with no model of it.
//!
//! Why on top of the held-out misses (`band`): those measure each sample's miss 1-2 s after a
//! fit, a pointwise band; the decision's risk is over the touchdown's instants, and a band that
//! holds 95 % of the instants holds fewer of the touchdowns. On ship-motion models it was not
//! developed on, the stated 95 % band held 85-90 % of the touchdowns cleared on
//! (BENCHMARKS.md, "Ship motion it was not built on"). The widening never goes below 1: every
//! band stays at least what the held-out misses say.

use super::history::History;
use super::types::DeckForecast;
use std::collections::VecDeque;

/// The share of touchdowns a 95 % band may miss.
pub(super) const COVERAGE_MISS_SHARE: f64 = 0.04;
/// The step of the log-widening per judged touchdown.
pub(super) const COVERAGE_STEP: f64 = 0.02;
/// The widest the coverage widens a band (beyond, the band is far off in any case and the
/// held-out misses' own scale says so: `band::MAX_BAND_SCALE`).
pub(super) const MAX_WIDENING: f64 = 3.0;
/// A touchdown's forecast is stated this often (s): consecutive touchdowns overlap, and more
/// would judge nearly the same motion again.
pub(super) const STATED_EVERY_S: f64 = 0.2;
/// What a measurement's noise reaches over a touchdown, in its standard deviations: the
/// largest of 21 independent values' (2 s at 10 Hz) in 95 % of touchdowns, and of a rate
/// measured over a second, about three independent ones' (values, rates).
const NOISE_WINDOW_Z: [f64; 2] = [3.03, 2.39];
/// The stated forecast's instants are this far apart (s); judged in between by interpolation.
const STATED_GRID_S: f64 = 0.1;

/// A touchdown's forecast as stated at `t0_s`: the forecast at `t0_s + i STATED_GRID_S`.
#[derive(Debug, Clone)]
struct StatedTouchdown {
    t0_s: f64,
    points: Vec<DeckForecast>,
}

impl StatedTouchdown {
    /// Per quantity (roll, pitch, heave, their rates), the mean and band half-width at `t`.
    fn at(&self, t: f64) -> ([f64; 6], [f64; 6]) {
        let x = ((t - self.t0_s) / STATED_GRID_S).max(0.0);
        let i = (x.floor() as usize).min(self.points.len() - 1);
        let j = (i + 1).min(self.points.len() - 1);
        let share = (x - i as f64).clamp(0.0, 1.0);
        let (a, b) = (&self.points[i], &self.points[j]);
        let lerp = |u: f64, v: f64| u + share * (v - u);
        let mean = std::array::from_fn(|q| {
            let (u, v) = if q < 3 {
                (a.value[q], b.value[q])
            } else {
                (a.rate[q - 3], b.rate[q - 3])
            };
            lerp(u, v)
        });
        let band = std::array::from_fn(|q| {
            let (u, v) = if q < 3 {
                (a.band95[q], b.band95[q])
            } else {
                (a.rate_band95[q - 3], b.rate_band95[q - 3])
            };
            lerp(u, v)
        });
        (mean, band)
    }
}

/// The stated touchdowns waiting to be judged, and what the judged ones said of each band.
#[derive(Debug, Clone)]
pub(super) struct BandCoverage {
    /// Per quantity (roll, pitch, heave, their rates), the log of the widening (0 to
    /// `ln MAX_WIDENING`).
    log_widening: [f64; 6],
    pending: VecDeque<StatedTouchdown>,
    last_stated_s: f64,
    /// Per quantity, the touchdowns judged and those the band held (for tests and reports).
    pub(super) judged: [u64; 6],
    pub(super) held: [u64; 6],
    /// Whether outcomes move the widening (tests that compare two deciders fit for fit hold it
    /// at 1: [`Self::held_at_one`]).
    adapting: bool,
}

impl Default for BandCoverage {
    fn default() -> Self {
        Self {
            log_widening: [0.0; 6],
            pending: VecDeque::new(),
            last_stated_s: f64::NEG_INFINITY,
            judged: [0; 6],
            held: [0; 6],
            adapting: true,
        }
    }
}

impl BandCoverage {
    /// A coverage that judges but never widens.
    #[cfg(test)]
    pub(super) fn held_at_one() -> Self {
        Self {
            adapting: false,
            ..Self::default()
        }
    }

    /// Per quantity, what the band's half-width is multiplied by (1 to `MAX_WIDENING`).
    pub(super) fn widening(&self) -> [f64; 6] {
        self.log_widening.map(f64::exp)
    }

    /// Forgets the touchdowns not yet judged (their measurements will not come on this
    /// timeline); what the judged ones taught stays: it is the same ship on the same sea.
    pub(super) fn forget_pending(&mut self) {
        self.pending.clear();
        self.last_stated_s = f64::NEG_INFINITY;
    }

    /// States the touchdown from `t` (s) as `forecast` sees it now, if one has not been stated
    /// within `STATED_EVERY_S`.
    pub(super) fn state(&mut self, t: f64, touchdown_s: f64, forecast: impl Fn(f64) -> DeckForecast) {
        if t - self.last_stated_s < STATED_EVERY_S - 1e-6 && t >= self.last_stated_s {
            return;
        }
        self.last_stated_s = t;
        let steps = (touchdown_s / STATED_GRID_S).ceil() as usize;
        let points = (0..=steps)
            .map(|i| forecast(t + (i as f64 * STATED_GRID_S).min(touchdown_s)))
            .collect();
        self.pending.push_back(StatedTouchdown { t0_s: t, points });
    }

    /// Judges every stated touchdown whose measurements have all come by the newest sample: a
    /// quantity's band held if every sample over the touchdown (a rate: the deck's rate
    /// measured around each sample, `rate_half_s` either side) lay inside it.
    pub(super) fn judge(&mut self, history: &History, touchdown_s: f64, rate_half_s: f64) {
        let Some((newest, _)) = history.newest() else {
            return;
        };
        while let Some(stated) = self.pending.front() {
            let end = stated.t0_s + touchdown_s;
            if newest < end + rate_half_s {
                break;
            }
            // Each measurement carries its noise, which is no miss of the forecast's: judged
            // against the band widened in quadrature by what the noise reaches over a touchdown
            // (`NOISE_WINDOW_Z`; a calm sea's forecast states rate bands narrower than the
            // noise of a rate measured over a second, and every touchdown would count as a
            // miss).
            let noise = measurement_noise(history, stated.t0_s - rate_half_s, end + rate_half_s, rate_half_s);
            let mut judged = [false; 6];
            let mut outside = [false; 6];
            let over = history
                .samples
                .iter()
                .rev()
                .skip_while(|h| h.0 > end)
                .take_while(|h| h.0 >= stated.t0_s);
            for &(ti, v) in over {
                let (mean, band) = stated.at(ti);
                let rates = history.centred_rate(ti, rate_half_s);
                for q in 0..6 {
                    let measured = if q < 3 {
                        Some(v[q])
                    } else {
                        rates.map(|r| r[q - 3])
                    };
                    let Some(measured) = measured.filter(|m| m.is_finite()) else {
                        continue;
                    };
                    if mean[q].is_finite() && band[q].is_finite() {
                        judged[q] = true;
                        let allowed = band[q].hypot(NOISE_WINDOW_Z[q / 3] * noise[q]);
                        outside[q] |= (measured - mean[q]).abs() > allowed;
                    }
                }
            }
            for q in 0..6 {
                if judged[q] {
                    self.judged[q] += 1;
                    self.held[q] += u64::from(!outside[q]);
                    if !self.adapting {
                        continue;
                    }
                    let step = COVERAGE_STEP * (f64::from(u8::from(outside[q])) - COVERAGE_MISS_SHARE);
                    self.log_widening[q] = (self.log_widening[q] + step).clamp(0.0, MAX_WIDENING.ln());
                }
            }
            self.pending.pop_front();
        }
    }
}

/// Per quantity, the measurement noise's standard deviation over `[from, to]` (s): of each
/// channel's samples, from their second differences (where three samples are about evenly
/// spaced; the median, robust to the motion's own curvature and to an outlier), and of its
/// rate as a line through `rate_half_s` either side measures it. 0 where it cannot be told.
fn measurement_noise(history: &History, from: f64, to: f64, rate_half_s: f64) -> [f64; 6] {
    let near: Vec<&(f64, [f64; 3])> = history
        .samples
        .iter()
        .rev()
        .skip_while(|h| h.0 > to)
        .take_while(|h| h.0 >= from)
        .collect();
    let mut noise = [0.0; 6];
    let mut spacing: Vec<f64> = near.windows(2).map(|w| w[0].0 - w[1].0).collect();
    if spacing.len() < 4 {
        return noise;
    }
    let middle = spacing.len() / 2;
    let dt = *spacing.select_nth_unstable_by(middle, f64::total_cmp).1;
    for k in 0..3 {
        let mut d2: Vec<f64> = near
            .windows(3)
            .filter(|w| {
                let (a, b) = (w[0].0 - w[1].0, w[1].0 - w[2].0);
                (a - b).abs() <= 0.1 * a.max(b)
            })
            .map(|w| (w[0].1[k] - 2.0 * w[1].1[k] + w[2].1[k]).abs())
            .filter(|d| d.is_finite())
            .collect();
        if d2.len() < 3 {
            continue;
        }
        let middle = d2.len() / 2;
        let median = *d2.select_nth_unstable_by(middle, f64::total_cmp).1;
        // |N(0, 6 s^2)|'s median is 0.6745 sqrt(6) s.
        noise[k] = median / (0.674_5 * 6f64.sqrt());
        // A line through n evenly spaced samples: its slope's deviation is s / sqrt(sum of
        // (t - mean t)^2) = s / sqrt(n (n^2 - 1) dt^2 / 12).
        let n = (2.0 * rate_half_s / dt).floor() + 1.0;
        noise[3 + k] = noise[k] / (n * (n * n - 1.0) * dt * dt / 12.0).sqrt();
    }
    noise
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decision::history::History;

    /// A forecast of a flat deck at zero with a fixed band half-width.
    fn flat(band: f64) -> impl Fn(f64) -> DeckForecast {
        move |_| DeckForecast {
            value: [0.0; 3],
            rate: [0.0; 3],
            band95: [band; 3],
            rate_band95: [band; 3],
        }
    }

    /// Feeds `seconds` of samples at 10 Hz from `deck(t)`, stating a touchdown on each with a
    /// band of `base` times the widening, judging as it goes.
    fn run(cov: &mut BandCoverage, deck: impl Fn(f64) -> [f64; 3], base: f64, seconds: f64) {
        let mut h = History::default();
        for i in 0..(seconds * 10.0) as usize {
            let t = i as f64 * 0.1;
            h.push(t, deck(t), 10.0);
            cov.judge(&h, 2.0, 0.5);
            let w = cov.widening()[0];
            cov.state(t, 2.0, flat(base * w));
        }
    }

    /// Normal noise from a SplitMix64-like stream (Box-Muller).
    fn normals(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        let mut next = move || {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        move || {
            let (u, v) = (next().max(1e-300), next());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    #[test]
    fn a_band_too_narrow_is_widened_until_it_holds_its_share_of_touchdowns() {
        // A smooth Gaussian deviation (40 waves of random phase, periods 3-15 s, deviation 1)
        // judged by a band of half-width 1.96: it holds 95 % of the instants but fewer of the
        // 2 s touchdowns. The widening must bring the touchdowns held to 1 - COVERAGE_MISS_SHARE.
        let mut noise = normals(7);
        let waves: Vec<(f64, f64)> = (0..40)
            .map(|i| {
                let period_s = 3.0 + 12.0 * i as f64 / 39.0;
                (
                    std::f64::consts::TAU / period_s,
                    std::f64::consts::PI * (1.0 + noise()),
                )
            })
            .collect();
        let amplitude = (2.0 / waves.len() as f64).sqrt();
        let deck = |t: f64| {
            let v: f64 = waves
                .iter()
                .map(|(w, phase)| amplitude * (w * t + phase).sin())
                .sum();
            [v, v, v]
        };
        let mut cov = BandCoverage::default();
        run(&mut cov, deck, 1.96, 4000.0);
        let held = cov.held[0] as f64 / cov.judged[0] as f64;
        let target = 1.0 - COVERAGE_MISS_SHARE;
        assert!((held - target).abs() < 0.01, "held {held} of {}", cov.judged[0]);
        let w = cov.widening()[0];
        assert!((1.05..1.6).contains(&w), "widening {w}");
        // Held at one, the same band holds fewer.
        let mut fixed = BandCoverage::held_at_one();
        run(&mut fixed, deck, 1.96, 4000.0);
        assert!((fixed.held[0] as f64) < 0.95 * fixed.judged[0] as f64);
    }

    #[test]
    fn a_band_wide_enough_is_left_as_it_is() {
        let mut cov = BandCoverage::default();
        run(&mut cov, |t| [0.1 * t.sin(), 0.0, 0.0], 1.0, 300.0);
        assert!(cov.judged[0] > 1000 && cov.held[0] == cov.judged[0]);
        assert_eq!(
            cov.widening()[0],
            1.0,
            "never narrower than the held-out misses say"
        );
    }

    #[test]
    fn a_touchdown_is_judged_only_once_its_rates_are_measured() {
        let mut cov = BandCoverage::default();
        let mut h = History::default();
        for i in 0..=24 {
            h.push(i as f64 * 0.1, [0.0; 3], 10.0);
        }
        cov.state(0.0, 2.0, flat(1.0));
        cov.judge(&h, 2.0, 0.5);
        assert_eq!(
            cov.judged, [0; 6],
            "2.4 s: the rate at 2.0 s needs samples to 2.5 s"
        );
        h.push(2.5, [0.0; 3], 10.0);
        cov.judge(&h, 2.0, 0.5);
        assert_eq!(cov.judged, [1; 6]);
        assert_eq!(cov.held, [1; 6]);
        cov.forget_pending();
        assert!(cov.pending.is_empty());
    }
}
