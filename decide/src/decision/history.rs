//! The decider's history of accepted samples (time, roll, pitch, deck height) and the deck's
//! rates measured on it: a least-squares line (the rate at the samples' mean time) and a
//! parabola (the rate at one instant), without a model.

use std::collections::VecDeque;

/// The fit's samples are this far apart (s): one per point of its grid (ship motion is
/// below 0.5 Hz).
pub(super) const FIT_SPACING_S: f64 = 0.2;

/// Accepted samples, oldest first: (time s, [roll deg, pitch deg, deck height m or NaN]).
#[derive(Debug, Clone, Default)]
pub(super) struct History {
    pub(super) samples: VecDeque<(f64, [f64; 3])>,
}

/// The samples thinned for a fit: times and one series per channel.
pub(super) struct Thinned {
    pub(super) t: Vec<f64>,
    pub(super) y: Vec<Vec<f64>>,
}

impl History {
    pub(super) fn newest(&self) -> Option<(f64, [f64; 3])> {
        self.samples.back().copied()
    }

    /// Seconds from the oldest sample to `t` (0 without samples).
    pub(super) fn span_to(&self, t: f64) -> f64 {
        t - self.samples.front().map_or(t, |h| h.0)
    }

    /// Appends a sample and drops those more than `window_s` older.
    pub(super) fn push(&mut self, t: f64, sample: [f64; 3], window_s: f64) {
        self.samples.push_back((t, sample));
        while self.samples.front().is_some_and(|&(t0, _)| t - t0 > window_s) {
            self.samples.pop_front();
        }
    }

    pub(super) fn clear(&mut self) {
        self.samples.clear();
    }

    /// The samples a fit uses, `channels` of them: the newest, and for each point of the
    /// fit's grid before it (`FIT_SPACING_S` apart, counted back from the newest) the sample
    /// nearest to it among those within half a spacing (none where a lost frame leaves none:
    /// the grid is then interpolated across two spacings). The grid is resampled from these,
    /// so at a frame rate that is a multiple of 5 Hz its points fall on frames rather than
    /// between two, where interpolation smooths both the motion and the noise. (Kept
    /// when at least a spacing after the sample before, a frame stamped a hair early left the
    /// next one 0.3 s away at 10 Hz, half of them with 5 ms of jitter, and after a gap every
    /// grid point could fall between two samples: the band of a 10 Hz history with jitter
    /// held a point less of the rates.)
    pub(super) fn thinned(&self, channels: usize) -> Thinned {
        let mut t: Vec<f64> = Vec::new();
        let mut y: Vec<Vec<f64>> = vec![Vec::new(); channels];
        let Some(&(newest, _)) = self.samples.back() else {
            return Thinned { t, y };
        };
        // (grid point index, distance from it, sample) of the nearest sample to the current
        // grid point so far.
        let mut best: Option<(i64, f64, (f64, [f64; 3]))> = None;
        let mut keep = |sample: (f64, [f64; 3])| {
            t.push(sample.0);
            for (k, yk) in y.iter_mut().enumerate() {
                yk.push(sample.1[k]);
            }
        };
        for &(ti, v) in self.samples.iter().rev() {
            let steps = (newest - ti) / FIT_SPACING_S;
            let point = steps.round() as i64;
            let off = (steps - point as f64).abs();
            match best {
                Some((p, d, _)) if p == point => {
                    if off < d {
                        best = Some((point, off, (ti, v)));
                    }
                }
                _ => {
                    if let Some((_, _, sample)) = best {
                        keep(sample);
                    }
                    best = Some((point, off, (ti, v)));
                }
            }
        }
        if let Some((_, _, sample)) = best {
            keep(sample);
        }
        t.reverse();
        for yk in &mut y {
            yk.reverse();
        }
        Thinned { t, y }
    }

    /// Each channel's rate (per s) at `t` from a parabola through the samples of the last
    /// `window_s`; None with fewer than 5 samples or over less than half of it (a gap).
    pub(super) fn parabola_rate_now(&self, t: f64, window_s: f64) -> Option<[f64; 3]> {
        let recent = self.samples.iter().rev().take_while(|h| t - h.0 <= window_s);
        parabola_rate_at(recent, t)
            .filter(|p| p.count >= 5 && p.span_s >= 0.5 * window_s)
            .map(|p| p.rates)
    }

    /// Each channel's rate (per s) from a least-squares line through the samples of the last
    /// `window` seconds (the rate at their mean time); None with fewer than 4 samples.
    pub(super) fn line_rate(&self, t: f64, window: f64) -> Option<[f64; 3]> {
        let line = fit_line(self.samples.iter().rev().take_while(|h| t - h.0 <= window))?;
        (line.count >= 4).then_some(line.slopes)
    }

    /// Each channel's rate at `t` from a least-squares line through the samples within
    /// `half_s` of it, on both sides (None without samples that far on each side).
    pub(super) fn centred_rate(&self, t: f64, half_s: f64) -> Option<[f64; 3]> {
        let near = self
            .samples
            .iter()
            .rev()
            .skip_while(|h| h.0 > t + half_s)
            .take_while(|h| h.0 >= t - half_s);
        let line = fit_line(near)?;
        let both_sides = line.first_t <= t - 0.8 * half_s && line.last_t >= t + 0.8 * half_s;
        (line.count >= 5 && both_sides).then_some(line.slopes)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_is_kept_and_the_fit_sees_samples_a_spacing_apart() {
        let mut h = History::default();
        for k in 0..=300 {
            let t = k as f64 / 30.0;
            h.push(t, [t, -t, 0.5 * t], 5.0);
        }
        assert!((h.span_to(10.0) - 5.0).abs() < 1e-9);
        let thinned = h.thinned(2);
        assert_eq!(thinned.y.len(), 2);
        assert_eq!(thinned.t.last(), Some(&10.0), "the newest sample always");
        assert!(thinned
            .t
            .windows(2)
            .all(|w| (w[1] - w[0] - FIT_SPACING_S).abs() < 1e-9));
        // A line's slope is each channel's rate.
        let rates = h.line_rate(10.0, 0.6).unwrap();
        assert!(
            (rates[0] - 1.0).abs() < 1e-9 && (rates[1] + 1.0).abs() < 1e-9 && (rates[2] - 0.5).abs() < 1e-9
        );
        let rates = h.parabola_rate_now(10.0, 0.9).unwrap();
        assert!((rates[0] - 1.0).abs() < 1e-6);
        let rates = h.centred_rate(9.0, 0.5).unwrap();
        assert!((rates[2] - 0.5).abs() < 1e-9);
        assert!(
            h.centred_rate(10.0, 0.5).is_none(),
            "nothing after the newest sample"
        );
        h.clear();
        assert!(h.newest().is_none() && h.line_rate(10.0, 0.6).is_none());
    }

    /// Frames at 10 Hz whose stamps jitter by a few ms, with a gap that ends on a frame off
    /// the grid: the fit's samples are those on its grid, with their own values, a spacing
    /// apart on both sides of the gap.
    #[test]
    fn the_fits_samples_are_those_on_its_grid() {
        let mut h = History::default();
        let stamp = |k: usize| k as f64 / 10.0 + 0.008 * (((k * 7919) % 17) as f64 / 8.0 - 1.0);
        let value = |t: f64| [t.sin(), 2.0 * t, -t];
        // Frames 302..=310 lost: the last before the gap (301) is off the grid.
        for k in (0..=600).filter(|k| !(302..=310).contains(k)) {
            h.push(stamp(k), value(stamp(k)), 100.0);
        }
        let thinned = h.thinned(3);
        let newest = stamp(600);
        assert_eq!(thinned.t.last(), Some(&newest));
        for (i, &ti) in thinned.t.iter().enumerate() {
            assert_eq!([thinned.y[0][i], thinned.y[1][i], thinned.y[2][i]], value(ti));
        }
        assert!(thinned.t.contains(&stamp(300)), "the grid's frame before the gap");
        assert!(thinned.t.len() > 290, "{}", thinned.t.len());
        // Every one on a grid point, but the gap's edge where it is the only frame within
        // half a spacing of the grid point after it (a point in the gap, left unmeasured).
        let on_grid = |ti: f64| {
            let steps = (newest - ti) / FIT_SPACING_S;
            (steps - steps.round()).abs() < 0.1
        };
        for &ti in thinned.t.iter().filter(|&&ti| ti != stamp(301)) {
            assert!(on_grid(ti), "{ti} is between grid points");
        }
        let spacings: Vec<f64> = thinned.t.windows(2).map(|w| w[1] - w[0]).collect();
        let (near, gap): (Vec<f64>, Vec<f64>) = spacings.iter().partition(|&&d| d < 0.5);
        assert!(
            near.iter()
                .all(|d| (d - FIT_SPACING_S).abs() < 0.02 || (d - 0.1).abs() < 0.02),
            "{near:?}"
        );
        assert_eq!(gap.len(), 1, "{gap:?}");
    }
}
