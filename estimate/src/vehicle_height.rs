//! The vehicle's height from the autopilot's height and vertical speed together.
//!
//! The deck's height is the vehicle's height less the camera's height over the deck, so every
//! error of the vehicle's height goes into the heave and the heave rate the decision forecasts.
//! An autopilot's height (barometer, GNSS, their estimator) can carry centimetres of
//! sample-to-sample noise, while its vertical speed (the estimator's integrated accelerometer)
//! is smooth. [`HeightFusion`] is a complementary filter: the height follows the integrated
//! vertical speed over periods shorter than its time constant and the reported height over
//! longer ones. An error that the height and the speed share (a drift of the estimator) passes
//! through unchanged; white noise on the height is averaged over the time constant.

pub use deckwatch_common::vehicle::HEIGHT_FUSION_TIME_CONSTANT_S;

/// Samples farther apart than this restart the filter from the reported height (s): the
/// integrated speed of a long gap is not worth more than the height.
const MAX_STEP_S: f64 = 0.5;

/// A complementary filter of height (m) and vertical speed (m/s), both z up.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightFusion {
    time_constant_s: f64,
    /// The last sample: its time (ns), the fused height and the vertical speed.
    last: Option<(u64, f64, f64)>,
}

impl Default for HeightFusion {
    fn default() -> Self {
        Self::new(HEIGHT_FUSION_TIME_CONSTANT_S)
    }
}

impl HeightFusion {
    /// A filter of this time constant; 0 (or less, or not finite) passes heights through.
    pub fn new(time_constant_s: f64) -> Self {
        Self {
            time_constant_s: if time_constant_s.is_finite() {
                time_constant_s.max(0.0)
            } else {
                0.0
            },
            last: None,
        }
    }

    /// The fused height for a sample at `time_ns` (later than the last one). Without a finite
    /// height there is none, and the filter starts again at the next; without a finite speed the
    /// reported height is returned and the filter starts again from it. A sample not after the
    /// last one restarts the filter too.
    pub fn update(
        &mut self,
        time_ns: u64,
        height_m: Option<f64>,
        vertical_speed_mps: Option<f64>,
    ) -> Option<f64> {
        let Some(height_m) = height_m.filter(|h| h.is_finite()) else {
            self.last = None;
            return None;
        };
        let Some(speed_mps) = vertical_speed_mps.filter(|v| v.is_finite()) else {
            self.last = None;
            return Some(height_m);
        };
        let fused = match self.last {
            Some((t0, h0, v0)) if time_ns > t0 && self.time_constant_s > 0.0 => {
                let dt_s = (time_ns - t0) as f64 / 1e9;
                if dt_s > MAX_STEP_S {
                    height_m
                } else {
                    // Carried by the mean speed over the step, then pulled toward the report
                    // with the discrete first-order gain.
                    let predicted = h0 + 0.5 * (v0 + speed_mps) * dt_s;
                    let gain = dt_s / (self.time_constant_s + dt_s);
                    predicted + gain * (height_m - predicted)
                }
            }
            _ => height_m,
        };
        self.last = Some((time_ns, fused, speed_mps));
        Some(fused)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_sim::rng::SplitMix64;

    const PERIOD_NS: u64 = 20_000_000;

    /// Runs the filter over a 50 Hz stream of `t -> (height, speed)`; the fused heights.
    fn fuse(f: &mut HeightFusion, seconds: f64, sample: impl Fn(f64, usize) -> (f64, f64)) -> Vec<f64> {
        let n = (seconds * 50.0) as usize;
        (0..n)
            .map(|k| {
                let (h, v) = sample(k as f64 * 0.02, k);
                f.update(k as u64 * PERIOD_NS, Some(h), Some(v)).unwrap()
            })
            .collect()
    }

    #[test]
    fn a_consistent_height_and_speed_pass_through() {
        // A 10 s heave of 1 m and a drift shared by both: the fused height is the reported one.
        let w = std::f64::consts::TAU / 10.0;
        let truth = |t: f64| ((w * t).sin() + 0.05 * t, w * (w * t).cos() + 0.05);
        let fused = fuse(&mut HeightFusion::default(), 30.0, |t, _| truth(t));
        for (k, h) in fused.iter().enumerate() {
            let err = (h - truth(k as f64 * 0.02).0).abs();
            assert!(err < 2e-4, "{k}: {err}");
        }
    }

    #[test]
    fn white_noise_on_the_height_is_averaged_out() {
        // 2 cm of white noise on each 50 Hz height, an exact speed: what is left is about
        // sigma sqrt(dt / (2 tau)) = 2 mm.
        let mut g = SplitMix64::new(7);
        let noise: Vec<f64> = (0..3000).map(|_| 0.02 * g.next_gaussian()).collect();
        let w = std::f64::consts::TAU / 8.0;
        let fused = fuse(&mut HeightFusion::default(), 60.0, |t, k| {
            ((w * t).sin() + noise[k], w * (w * t).cos())
        });
        let errors: Vec<f64> = fused
            .iter()
            .enumerate()
            .skip(250)
            .map(|(k, h)| h - (w * k as f64 * 0.02).sin())
            .collect();
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        assert!((0.001..0.003).contains(&rms), "rms {rms}");
        // The rate between frames (0.1 s apart) is what the heave forecast differences.
        let rate_rms = (errors
            .windows(5)
            .map(|p| ((p[4] - p[0]) / 0.1).powi(2))
            .sum::<f64>()
            / (errors.len() - 4) as f64)
            .sqrt();
        assert!(
            rate_rms < 0.02,
            "rate rms {rate_rms} m/s (the raw heights': 0.28)"
        );
    }

    #[test]
    fn a_bias_of_the_speed_leaves_an_offset_not_a_rate() {
        // 0.1 m/s of speed bias over a still height: the fused height settles tau * bias above
        // it and then stays, so the rate it reports is right.
        let fused = fuse(&mut HeightFusion::default(), 20.0, |_, _| (5.0, 0.1));
        let last = fused[fused.len() - 1];
        assert!((last - 5.1).abs() < 2e-3, "{last}");
        assert!((fused[fused.len() - 1] - fused[fused.len() - 51]).abs() < 1e-4);
    }

    #[test]
    fn missing_values_gaps_and_no_filter_restart_from_the_height() {
        let mut f = HeightFusion::default();
        assert_eq!(f.update(0, Some(1.0), Some(0.0)), Some(1.0));
        assert_eq!(f.update(PERIOD_NS, None, Some(0.0)), None);
        assert_eq!(f.update(2 * PERIOD_NS, Some(f64::NAN), Some(0.0)), None);
        // Restarted: the report itself.
        assert_eq!(f.update(3 * PERIOD_NS, Some(2.0), Some(0.0)), Some(2.0));
        // No speed: the report, and a restart.
        assert_eq!(f.update(4 * PERIOD_NS, Some(3.0), None), Some(3.0));
        assert_eq!(f.update(5 * PERIOD_NS, Some(4.0), Some(0.0)), Some(4.0));
        // A gap of more than half a second, or a sample not after the last: the report.
        assert_eq!(f.update(2_000_000_000, Some(7.0), Some(0.0)), Some(7.0));
        assert_eq!(f.update(2_000_000_000, Some(8.0), Some(0.0)), Some(8.0));
        // A time constant of 0 passes heights through.
        let mut off = HeightFusion::new(0.0);
        off.update(0, Some(1.0), Some(10.0));
        assert_eq!(off.update(PERIOD_NS, Some(1.5), Some(10.0)), Some(1.5));
        assert_eq!(HeightFusion::new(f64::NAN), HeightFusion::new(0.0));
    }
}
