//! How well the deck-motion forecast predicts, and whether the uncertainty it states is honest:
//! for roll, pitch, the deck height and their rates, the forecast error at several horizons and
//! the share of true values inside the stated 95 % band, pointwise and over a whole touchdown.
//! Pure: the caller supplies the true motion and the measured stream (`deckwatch predict-eval`).
//!
//! The forecasts judged are the decider's own ([`LandingDecider::forecast`], fed frame by frame
//! as the decide stage feeds it) and persistence (the last measurement, with a band from how much
//! the history moved over the same horizon) as the baseline that knows nothing of the sea.

use crate::decision::{DecisionConfig, DeckForecast, LandingDecider, Z95};
use crate::eval::{TrueDeck, TrueDeckState};
use crate::frame::FrameInput;
use std::collections::VecDeque;

/// The six forecast quantities, in the order of [`ForecastReport`]'s rows.
pub const QUANTITIES: [&str; 6] = [
    "roll_deg",
    "pitch_deg",
    "heave_m",
    "roll_rate_dps",
    "pitch_rate_dps",
    "heave_rate_mps",
];

/// Something that forecasts the deck from the measured stream.
pub trait StreamForecaster {
    /// Takes one frame (in order).
    fn observe(&mut self, frame: &FrameInput);
    /// The forecast for time `t` as of the frames seen so far (None: it has none yet).
    fn forecast(&self, t: f64) -> Option<DeckForecast>;
}

impl StreamForecaster for LandingDecider {
    fn observe(&mut self, frame: &FrameInput) {
        self.decide_frame(frame);
        self.refit_between_frames();
    }
    fn forecast(&self, t: f64) -> Option<DeckForecast> {
        LandingDecider::forecast(self, t)
    }
}

/// The last measurement, held. Its band at horizon `h` is 1.96 times the RMS change of the
/// measured history over `h` (an honest band for a process that does not change its character);
/// rates are differences over `RATE_SPAN_S` of the measurements, held the same way.
pub struct Persistence {
    window_s: f64,
    /// Valid frames: (time, [roll, pitch, height]).
    history: VecDeque<(f64, [f64; 3])>,
}

/// Half the span of the measured rate (s).
const RATE_SPAN_S: f64 = 0.3;

impl Persistence {
    pub fn new(window_s: f64) -> Self {
        Self {
            window_s,
            history: VecDeque::new(),
        }
    }

    /// The history as two series on its own times: values and central-difference rates.
    fn rates(&self) -> Vec<(f64, [f64; 3])> {
        let h: Vec<&(f64, [f64; 3])> = self.history.iter().collect();
        let mut out = Vec::new();
        let mut lo = 0;
        let mut hi = 0;
        for i in 0..h.len() {
            let t = h[i].0;
            while h[lo].0 < t - RATE_SPAN_S {
                lo += 1;
            }
            while hi + 1 < h.len() && h[hi + 1].0 <= t + RATE_SPAN_S {
                hi += 1;
            }
            if hi < i {
                hi = i;
            }
            let (a, b) = (h[lo], h[hi]);
            if b.0 - a.0 >= RATE_SPAN_S {
                out.push((t, [0, 1, 2].map(|k| (b.1[k] - a.1[k]) / (b.0 - a.0))));
            }
        }
        out
    }
}

/// The value at `t` of a series (the nearest sample at or before).
fn at_or_before(series: &[(f64, [f64; 3])], t: f64) -> Option<[f64; 3]> {
    let i = series.partition_point(|s| s.0 <= t);
    (i > 0).then(|| series[i - 1].1)
}

/// 1.96 times the RMS change of each channel of `series` over `h` seconds.
fn change_band(series: &[(f64, [f64; 3])], h: f64) -> [f64; 3] {
    let mut sum = [0.0; 3];
    let mut n = 0usize;
    for &(t, v) in series {
        if t + h > series.last().map_or(f64::NEG_INFINITY, |s| s.0) {
            break;
        }
        if let Some(w) = at_or_before(series, t + h) {
            for k in 0..3 {
                sum[k] += (w[k] - v[k]).powi(2);
            }
            n += 1;
        }
    }
    if n < 10 {
        return [f64::NAN; 3];
    }
    sum.map(|s| 1.959_963_984_540_054 * (s / n as f64).sqrt())
}

impl StreamForecaster for Persistence {
    fn observe(&mut self, frame: &FrameInput) {
        let Some(d) = frame.deck else { return };
        if frame.vehicle_missing || frame.frozen_image || !frame.t_s.is_finite() {
            return;
        }
        if self.history.back().is_some_and(|h| h.0 >= frame.t_s) {
            return;
        }
        self.history
            .push_back((frame.t_s, [d.roll_deg, d.pitch_deg, d.height_m]));
        while self
            .history
            .front()
            .is_some_and(|h| frame.t_s - h.0 > self.window_s)
        {
            self.history.pop_front();
        }
    }

    fn forecast(&self, t: f64) -> Option<DeckForecast> {
        let &(t_last, last) = self.history.back()?;
        let h = (t - t_last).max(0.0);
        let values: Vec<(f64, [f64; 3])> = self.history.iter().copied().collect();
        let rates = self.rates();
        let &(_, rate_now) = rates.last()?;
        Some(DeckForecast {
            value: last,
            rate: rate_now,
            band95: change_band(&values, h),
            rate_band95: change_band(&rates, h + RATE_SPAN_S),
        })
    }
}

/// The errors at one horizon, for one quantity.
#[derive(Debug, Clone, Default)]
pub struct HorizonErrors {
    pub abs_errors: Vec<f64>,
    /// Truths inside the stated 95 % band.
    pub inside: u64,
    /// Truths beyond `TAIL_Z` stated deviations (the 95 % band's half-width over 1.96): the
    /// tails the decision's risk per touchdown lies in, which the 95 % band's coverage says
    /// nothing of. An honest normal band leaves `TAIL_SHARE` of the truths there.
    pub beyond_tail: u64,
}

/// A normal error is beyond this many deviations either way with probability `TAIL_SHARE`:
/// 1e-3 each side, the default risk per touchdown (the decision judges each limit's tail
/// with the normal distribution).
pub const TAIL_Z: f64 = 3.090_232_306_167_813;
pub const TAIL_SHARE: f64 = 2e-3;

impl HorizonErrors {
    pub fn rms(&self) -> f64 {
        (self.abs_errors.iter().map(|e| e * e).sum::<f64>() / self.abs_errors.len() as f64).sqrt()
    }
    pub fn p99(&self) -> f64 {
        let mut e = self.abs_errors.clone();
        deckwatch_common::stats::Percentiles::of(&mut e).map_or(f64::NAN, |p| p.p99)
    }
    /// Share of truths inside the stated band.
    pub fn coverage(&self) -> f64 {
        self.inside as f64 / self.abs_errors.len() as f64
    }
    /// Share of truths beyond `TAIL_Z` stated deviations (an honest normal band's:
    /// `TAIL_SHARE`).
    pub fn tail_share(&self) -> f64 {
        self.beyond_tail as f64 / self.abs_errors.len() as f64
    }
}

/// One forecaster over one stream.
#[derive(Debug, Clone, Default)]
pub struct ForecastReport {
    /// The horizons (s).
    pub horizons_s: Vec<f64>,
    /// `[quantity][horizon]`, quantities as [`QUANTITIES`].
    pub errors: Vec<Vec<HorizonErrors>>,
    /// Forecast instants judged over a whole touchdown.
    pub windows: u64,
    /// Per quantity: windows whose truth stayed inside the band all through the touchdown.
    pub window_inside: [u64; 6],
    /// Per quantity: windows whose truth went beyond `TAIL_Z` stated deviations at some step.
    pub window_beyond_tail: [u64; 6],
    /// Windows whose truth stayed inside every quantity's band.
    pub window_all_inside: u64,
}

impl ForecastReport {
    pub fn window_coverage(&self, quantity: usize) -> f64 {
        self.window_inside[quantity] as f64 / self.windows as f64
    }

    /// Adds another stream's report (the same horizons).
    pub fn merge(&mut self, other: &ForecastReport) {
        if self.errors.is_empty() {
            *self = other.clone();
            return;
        }
        for (mine, theirs) in self.errors.iter_mut().zip(&other.errors) {
            for (a, b) in mine.iter_mut().zip(theirs) {
                a.abs_errors.extend_from_slice(&b.abs_errors);
                a.inside += b.inside;
                a.beyond_tail += b.beyond_tail;
            }
        }
        self.windows += other.windows;
        for k in 0..6 {
            self.window_inside[k] += other.window_inside[k];
            self.window_beyond_tail[k] += other.window_beyond_tail[k];
        }
        self.window_all_inside += other.window_all_inside;
    }
}

/// The true quantities at `t`, as [`QUANTITIES`].
fn truth_at(truth: TrueDeck, t: f64) -> [f64; 6] {
    let s = TrueDeckState::at(truth, t);
    [
        s.roll_deg,
        s.pitch_deg,
        truth(t)[2],
        s.roll_rate_dps,
        s.pitch_rate_dps,
        s.heave_rate_mps,
    ]
}

/// A forecast's quantities and bands, as [`QUANTITIES`].
fn forecast_quantities(f: &DeckForecast) -> ([f64; 6], [f64; 6]) {
    (
        [
            f.value[0], f.value[1], f.value[2], f.rate[0], f.rate[1], f.rate[2],
        ],
        [
            f.band95[0],
            f.band95[1],
            f.band95[2],
            f.rate_band95[0],
            f.rate_band95[1],
            f.rate_band95[2],
        ],
    )
}

/// Step of the touchdown window's check (s).
const WINDOW_STEP_S: f64 = 0.05;

/// One forecast judged over a whole touchdown `[t, t + touchdown_s]`, per quantity (as
/// [`QUANTITIES`]): whether it was forecast with a band, whether the truth stayed inside the
/// stated 95 % band at every step, and whether it went beyond `TAIL_Z` stated deviations at
/// some step (the tail the risk per touchdown is judged in).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowVerdict {
    pub judged: [bool; 6],
    pub inside: [bool; 6],
    pub beyond_tail: [bool; 6],
}

impl WindowVerdict {
    pub fn judge(
        truth: TrueDeck,
        forecast: impl Fn(f64) -> Option<DeckForecast>,
        t: f64,
        touchdown_s: f64,
    ) -> Self {
        let steps = (touchdown_s / WINDOW_STEP_S).ceil() as usize;
        let mut w = Self {
            judged: [false; 6],
            inside: [true; 6],
            beyond_tail: [false; 6],
        };
        for k in 0..=steps {
            let tk = t + (k as f64 * WINDOW_STEP_S).min(touchdown_s);
            let Some(f) = forecast(tk) else {
                continue;
            };
            let (mean, band) = forecast_quantities(&f);
            let truth = truth_at(truth, tk);
            for q in 0..6 {
                if mean[q].is_finite() && band[q].is_finite() {
                    let e = (mean[q] - truth[q]).abs();
                    w.judged[q] = true;
                    w.inside[q] &= e <= band[q];
                    w.beyond_tail[q] |= e > TAIL_Z * band[q] / Z95;
                }
            }
        }
        w
    }
}

/// Runs `forecaster` over `stream` and, every `every_s` of the stream once it forecasts, judges
/// its forecasts at `horizons_s` after the frame's time, and over the touchdown
/// `[t, t + touchdown_s]`. Quantities a forecaster does not forecast (NaN: the heave when the
/// decider does not use it) are not counted.
pub fn judge_forecasts(
    truth: TrueDeck,
    forecaster: &mut dyn StreamForecaster,
    stream: &[FrameInput],
    horizons_s: &[f64],
    touchdown_s: f64,
    every_s: f64,
) -> ForecastReport {
    let mut report = ForecastReport {
        horizons_s: horizons_s.to_vec(),
        errors: vec![vec![HorizonErrors::default(); horizons_s.len()]; 6],
        ..Default::default()
    };
    let mut next = f64::NEG_INFINITY;
    for frame in stream {
        forecaster.observe(frame);
        let t = frame.t_s;
        if !(t.is_finite() && t >= next) {
            continue;
        }
        if forecaster.forecast(t).is_none() {
            continue;
        }
        next = t + every_s;
        for (j, &h) in horizons_s.iter().enumerate() {
            let Some(f) = forecaster.forecast(t + h) else {
                continue;
            };
            let (mean, band) = forecast_quantities(&f);
            let truth = truth_at(truth, t + h);
            for q in 0..6 {
                if !(mean[q].is_finite() && band[q].is_finite()) {
                    continue;
                }
                let e = (mean[q] - truth[q]).abs();
                let errors = &mut report.errors[q][j];
                errors.abs_errors.push(e);
                errors.inside += u64::from(e <= band[q]);
                errors.beyond_tail += u64::from(e > TAIL_Z * band[q] / Z95);
            }
        }
        let w = WindowVerdict::judge(truth, |tk| forecaster.forecast(tk), t, touchdown_s);
        report.windows += 1;
        for q in 0..6 {
            report.window_inside[q] += u64::from(w.judged[q] && w.inside[q]);
            report.window_beyond_tail[q] += u64::from(w.judged[q] && w.beyond_tail[q]);
        }
        report.window_all_inside += u64::from((0..6).all(|q| !w.judged[q] || w.inside[q]));
    }
    report
}

/// The decider configured as `config`, as a forecaster.
pub fn decider(config: &DecisionConfig) -> Result<LandingDecider, deckwatch_common::InvalidField> {
    LandingDecider::new(config.clone())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decision::DeckObservation;
    use std::f64::consts::TAU;

    fn sea(t: f64) -> [f64; 3] {
        [
            2.0 * (TAU * t / 9.0).sin() + 0.7 * (TAU * t / 6.3 + 1.0).sin(),
            1.0 * (TAU * t / 7.0 + 0.4).sin(),
            0.3 * (TAU * t / 8.0).sin(),
        ]
    }

    fn stream(noise: f64) -> Vec<FrameInput> {
        // Uniform noise of standard deviation `noise` from a hash of the frame's index.
        let uniform = |k: u64, salt: u64| {
            let mut z = (k * 4 + salt).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            (((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
        };
        (0..1800u64)
            .map(|k| {
                let t = k as f64 * 0.1;
                let [r, p, h] = sea(t);
                let deck = DeckObservation::new(
                    r + noise * uniform(k, 1),
                    p + noise * uniform(k, 2),
                    h + noise / 10.0 * uniform(k, 3),
                );
                FrameInput::measured(t, Some(deck), 0.005)
            })
            .collect()
    }

    /// On a clean sum of sinusoids the autoregressive forecast is close and its band covers
    /// the truth; persistence errs by about the motion itself over the horizon.
    #[test]
    fn forecasts_of_a_regular_sea_are_judged() {
        let config = DecisionConfig::default();
        let s = stream(0.02);
        let horizons = [0.5, 2.0];
        let mut ar = decider(&config).unwrap();
        let r = judge_forecasts(&sea, &mut ar, &s, &horizons, 2.0, 1.0);
        assert!(r.windows > 100, "{}", r.windows);
        let roll_2s = &r.errors[0][1];
        eprintln!(
            "AR roll at 2 s: rms {:.3}, covered {:.3}; window {:.3}",
            roll_2s.rms(),
            roll_2s.coverage(),
            r.window_coverage(0)
        );
        assert!(roll_2s.rms() < 0.5, "AR roll rms at 2 s: {}", roll_2s.rms());
        assert!(
            roll_2s.coverage() > 0.9,
            "AR roll coverage at 2 s: {}",
            roll_2s.coverage()
        );
        let mut held = Persistence::new(40.0);
        let p = judge_forecasts(&sea, &mut held, &s, &horizons, 2.0, 1.0);
        assert!(p.errors[0][1].rms() > 5.0 * roll_2s.rms());
        // Persistence's band is the motion's own spread: wide, and so it covers.
        assert!(p.errors[0][1].coverage() > 0.8, "{}", p.errors[0][1].coverage());
    }

    /// A forecaster that knows the truth and misses it by a fixed number of its own stated
    /// deviations: every miss is inside the 95 % band, beyond it, or beyond the tail, as
    /// chosen.
    struct OffBy {
        deviations: f64,
    }

    impl StreamForecaster for OffBy {
        fn observe(&mut self, _frame: &FrameInput) {}
        fn forecast(&self, t: f64) -> Option<DeckForecast> {
            let std = [0.1, 0.2, 0.01];
            let truth = sea(t);
            Some(DeckForecast {
                value: std::array::from_fn(|k| truth[k] + self.deviations * std[k]),
                rate: [f64::NAN; 3],
                band95: std.map(|s| Z95 * s),
                rate_band95: [f64::NAN; 3],
            })
        }
    }

    /// The tail share counts the misses beyond `TAIL_Z` stated deviations, and only those: a
    /// miss of 2.5 deviations is outside the 95 % band but not in the tail, one of 3.2 in both.
    #[test]
    fn the_tail_share_counts_the_misses_beyond_the_tail() {
        // 1e-3 each side of a normal error.
        assert!((libm::erfc(TAIL_Z / std::f64::consts::SQRT_2) - TAIL_SHARE).abs() < 1e-12);
        let s = stream(0.0);
        for (deviations, coverage, tail) in [(1.0, 1.0, 0.0), (2.5, 0.0, 0.0), (3.2, 0.0, 1.0)] {
            let mut f = OffBy { deviations };
            let r = judge_forecasts(&sea, &mut f, &s, &[0.5, 2.0], 2.0, 1.0);
            for q in 0..3 {
                for e in &r.errors[q] {
                    assert!(e.abs_errors.len() > 100, "{deviations}: {}", e.abs_errors.len());
                    assert_eq!(e.coverage(), coverage, "{deviations} deviations, quantity {q}");
                    assert_eq!(e.tail_share(), tail, "{deviations} deviations, quantity {q}");
                }
            }
            // Rates not forecast are not judged.
            assert!(r.errors[3..].iter().flatten().all(|e| e.abs_errors.is_empty()));
            // A whole touchdown the same: inside all through at 1 deviation, beyond the tail
            // at some instant at 3.2; the rates not judged.
            assert_eq!(
                r.window_inside[..3],
                [(coverage as u64) * r.windows; 3],
                "{deviations}"
            );
            assert_eq!(
                r.window_beyond_tail[..3],
                [(tail as u64) * r.windows; 3],
                "{deviations}"
            );
            assert_eq!(r.window_beyond_tail[3..], [0; 3]);
            let w = WindowVerdict::judge(&sea, |t| f.forecast(t), 100.0, 2.0);
            assert_eq!(w.judged, [true, true, true, false, false, false]);
            assert_eq!(w.beyond_tail[..3], [tail == 1.0; 3], "{deviations}");
        }
    }
}
