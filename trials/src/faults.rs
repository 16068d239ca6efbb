//! The fault models of the evaluations, defined once: what goes wrong between the sea and the
//! decision. `deckwatch trials` injects [`FrameFaults`] into rendered frames on their way to
//! detect (lost frames, a frozen camera, outages of the autopilot's attitude stream);
//! `decide-eval` and `predict-eval` draw the attitude stream the estimate stage would deliver
//! from [`AttitudeStreamModel`] (noise, dropouts, gross errors, NaN, stale and frozen frames,
//! stamp jitter, the vehicle compensation's errors and outages). Both time their episodes (a
//! frozen camera, an outage) with [`Episodes`].

use deckwatch_common::messages::FROZEN_IMAGE_REPEATS;
use deckwatch_common::InvalidOption;
use deckwatch_decide::{DeckObservation, FrameInput};
use deckwatch_estimate::HeightFusion;
use deckwatch_sim::motion::{Sinusoid, VehicleSway};
use deckwatch_sim::rng::SplitMix64;

/// Episodes that start at random (a Poisson process, drawn once per frame) and last a fixed
/// time each: a frozen camera, an outage of a stream. Overlapping episodes merge.
#[derive(Debug, Clone, PartialEq)]
pub struct Episodes {
    start_probability_per_frame: f64,
    duration_s: f64,
    until_s: f64,
}

impl Episodes {
    /// `per_min` episodes a minute on average, `duration_s` each, at `rate_hz` frames a second.
    pub fn new(per_min: f64, duration_s: f64, rate_hz: f64) -> Self {
        Self {
            start_probability_per_frame: per_min / 60.0 / rate_hz,
            duration_s,
            until_s: f64::NEG_INFINITY,
        }
    }

    /// Whether an episode is under way at the frame at `t_s` (one draw from `rng`).
    pub fn at(&mut self, t_s: f64, rng: &mut SplitMix64) -> bool {
        if rng.next_f64() < self.start_probability_per_frame {
            self.until_s = self.until_s.max(t_s + self.duration_s);
        }
        t_s < self.until_s
    }
}

fn require(ok: bool, option: &str, must: &str) -> Result<(), InvalidOption> {
    if ok {
        Ok(())
    } else {
        Err(InvalidOption::new(option, must))
    }
}

/// Faults of the closed-loop trials, on frames (`deckwatch trials --drop-share ...`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameFaultModel {
    /// Share of frames lost between capture and detect.
    pub drop_share: f64,
    /// A frozen camera (the same image again, with new timestamps) this often a minute...
    pub frozen_per_min: f64,
    /// ... for this long each (s).
    pub frozen_s: f64,
    /// Outages of the autopilot's attitude stream a minute...
    pub vehicle_outages_per_min: f64,
    /// ... each this long (s).
    pub vehicle_outage_s: f64,
    /// The autopilot's height estimate: white noise on each sample (m, standard deviation)...
    pub vehicle_height_noise_m: f64,
    /// ... and a slow error whose rate has this standard deviation (m/s): an estimator's
    /// vertical-speed error, which goes into the heave rate estimate measures.
    pub vehicle_height_drift_mps: f64,
}

/// No faults (episodes of the command line's default lengths, none of them starting).
impl Default for FrameFaultModel {
    fn default() -> Self {
        Self {
            drop_share: 0.0,
            frozen_per_min: 0.0,
            frozen_s: 2.0,
            vehicle_outages_per_min: 0.0,
            vehicle_outage_s: 1.0,
            vehicle_height_noise_m: 0.0,
            vehicle_height_drift_mps: 0.0,
        }
    }
}

impl FrameFaultModel {
    pub fn validate(&self) -> Result<(), InvalidOption> {
        require(
            (0.0..=1.0).contains(&self.drop_share),
            "--drop-share",
            "a share in [0, 1]",
        )?;
        require(
            self.frozen_per_min >= 0.0 && self.frozen_s > 0.0,
            "--frozen-per-min, --frozen-s",
            "not negative, and frozen spells must last",
        )?;
        require(
            self.vehicle_outages_per_min >= 0.0 && self.vehicle_outage_s > 0.0,
            "--vehicle-outages-per-min, --vehicle-outage-s",
            "not negative, and outages must last",
        )?;
        require(
            (0.0..=10.0).contains(&self.vehicle_height_noise_m)
                && (0.0..=10.0).contains(&self.vehicle_height_drift_mps),
            "--vehicle-height-noise-m, --vehicle-height-drift-mps",
            "in [0, 10]",
        )
    }
}

/// The autopilot's height samples in [`AttitudeStreamModel`] (s): 100 Hz, as the trials'
/// attitude stream.
const VEHICLE_HEIGHT_PERIOD_S: f64 = 0.01;

/// Periods of the slow part of [`VehicleHeightError`] (s): a barometer's and an estimator's
/// drift over tens of seconds to minutes.
const HEIGHT_DRIFT_PERIODS_S: [f64; 4] = [23.0, 41.0, 67.0, 113.0];

/// The error of the autopilot's height estimate in one approach ([`FrameFaultModel`]'s
/// `vehicle_height_*`): the sum of slow sinusoids of random phases whose rate has the stated
/// standard deviation, and white noise on each sample. A function of time, so that the
/// in-process runner and the processes' autopilot stream give the same error.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleHeightError {
    seed: u64,
    noise_m: f64,
    /// The slow components (m).
    drift: Vec<Sinusoid>,
}

impl VehicleHeightError {
    pub fn new(model: &FrameFaultModel, approach_seed: u64) -> Self {
        let mut rng = SplitMix64::new(approach_seed ^ 0x4E16);
        let n = HEIGHT_DRIFT_PERIODS_S.len() as f64;
        let drift = HEIGHT_DRIFT_PERIODS_S
            .iter()
            .map(|&period_s| {
                let w = std::f64::consts::TAU / period_s;
                // Each component's rate has RMS a w / sqrt(2); the n of them add to the stated one.
                Sinusoid {
                    amplitude: model.vehicle_height_drift_mps * (2.0 / n).sqrt() / w,
                    period_s,
                    phase: std::f64::consts::TAU * rng.next_f64(),
                }
            })
            .collect();
        Self {
            seed: approach_seed ^ 0x4E17,
            noise_m: model.vehicle_height_noise_m,
            drift,
        }
    }

    /// The error of the height estimate sampled at `t_s` (m).
    pub fn error_m(&self, t_s: f64) -> f64 {
        let slow: f64 = self.drift.iter().map(|c| c.at(t_s)).sum();
        if self.noise_m == 0.0 {
            return slow;
        }
        // The same sample time gives the same noise (microsecond stamps).
        let stamp_us = (t_s * 1e6).round() as i64 as u64;
        slow + self.noise_m
            * SplitMix64::new(self.seed ^ stamp_us.wrapping_mul(0x9E37_79B9_7F4A_7C15)).next_gaussian()
    }

    /// The error of the vertical speed estimate at `t_s` (m/s, up): the slow part's rate.
    pub fn rate_error_mps(&self, t_s: f64) -> f64 {
        self.drift.iter().map(|c| c.rate(t_s)).sum()
    }

    /// The height and the vertical speed (m, m/s, up) the autopilot reports at `t_s` of a
    /// vehicle whose true height `height_at` gives: each with its error. The true speed is the
    /// height's central difference over 10 ms.
    pub fn reported(&self, height_at: impl Fn(f64) -> f64, t_s: f64) -> (f64, f64) {
        const DT_S: f64 = 0.005;
        let speed_mps = (height_at(t_s + DT_S) - height_at(t_s - DT_S)) / (2.0 * DT_S);
        (
            height_at(t_s) + self.error_m(t_s),
            speed_mps + self.rate_error_mps(t_s),
        )
    }
}

/// [`FrameFaultModel`] applied to one approach's frames, from the approach's own random stream.
pub struct FrameFaults {
    rng: SplitMix64,
    drop_share: f64,
    frozen: Episodes,
    frozen_pixels: Option<Vec<u8>>,
    vehicle_outages: Episodes,
    /// The error of the autopilot's height estimate.
    pub vehicle_height: VehicleHeightError,
}

impl FrameFaults {
    pub fn new(model: &FrameFaultModel, rate_hz: f64, approach_seed: u64) -> Self {
        Self {
            rng: SplitMix64::new(approach_seed ^ 0xFA17),
            drop_share: model.drop_share,
            frozen: Episodes::new(model.frozen_per_min, model.frozen_s, rate_hz),
            frozen_pixels: None,
            vehicle_outages: Episodes::new(model.vehicle_outages_per_min, model.vehicle_outage_s, rate_hz),
            vehicle_height: VehicleHeightError::new(model, approach_seed),
        }
    }

    /// Whether the autopilot's attitude stream is out at frame time `t_s` (drawn once per frame).
    pub fn vehicle_out(&mut self, t_s: f64) -> bool {
        self.vehicle_outages.at(t_s, &mut self.rng)
    }

    /// The frame at `t_s` on its way to detect: frozen or as it was; false when it is lost.
    pub fn inject(&mut self, t_s: f64, pixels: &mut [u8]) -> bool {
        self.freeze(t_s, pixels);
        !self.lost()
    }

    /// Whether the next frame is lost on its way.
    fn lost(&mut self) -> bool {
        self.rng.next_f64() < self.drop_share
    }

    /// A frozen camera delivers its last image again and again, with new timestamps.
    fn freeze(&mut self, t_s: f64, pixels: &mut [u8]) {
        if self.frozen.at(t_s, &mut self.rng) {
            match &self.frozen_pixels {
                Some(p) if p.len() == pixels.len() => pixels.copy_from_slice(p),
                _ => self.frozen_pixels = Some(pixels.to_vec()),
            }
        } else {
            self.frozen_pixels = None;
        }
    }
}

/// The attitude stream the estimate stage would deliver on a sea, with its faults
/// (`decide-eval`, `predict-eval`).
#[derive(Debug, Clone, PartialEq)]
pub struct AttitudeStreamModel {
    /// Attitudes a second.
    pub rate_hz: f64,
    /// Noise of roll and pitch (deg, standard deviation each).
    pub noise_deg: f64,
    /// White noise of the camera's height over the deck from the full pose (m).
    pub heave_noise_m: f64,
    /// The autopilot's height estimate, which the deck's height is measured from: white noise
    /// on each sample (m) and a slow drift whose rate has this standard deviation (m/s), as
    /// trials model it ([`VehicleHeightError`])...
    pub vehicle_height_noise_m: f64,
    pub vehicle_height_drift_mps: f64,
    /// ... sampled at 100 Hz and fused with its vertical speed over this time constant (s), as
    /// the estimate pipeline fuses them (`[vehicle] height_fusion_s`; 0: not fused).
    pub height_fusion_s: f64,
    /// Share of frames without a valid attitude.
    pub dropout: f64,
    /// Share of frames with a gross error (5-15 deg on one angle).
    pub outliers: f64,
    /// Share of frames whose roll is NaN (a broken estimate that says it is valid).
    pub nan_share: f64,
    /// Share of frames that arrive 1 s late.
    pub stale_share: f64,
    /// Jitter of the capture stamps (ms, standard deviation).
    pub jitter_ms: f64,
    /// Capture to decision (ms).
    pub latency_ms: f64,
    /// A frozen camera this often a minute, for `frozen_s` each.
    pub frozen_per_min: f64,
    pub frozen_s: f64,
    /// The vehicle sways (a hovering quadrotor): the compensation's timing error then shows.
    pub vehicle_sways: bool,
    /// The autopilot attitude's bias (roll, pitch) and noise (deg).
    pub vehicle_bias_deg: [f64; 2],
    pub vehicle_noise_deg: f64,
    /// Timing error of the autopilot's samples against the frames (ms).
    pub vehicle_time_error_ms: f64,
    /// Outages of the autopilot's stream a minute, `vehicle_outage_s` each: not compensated.
    pub vehicle_outages_per_min: f64,
    pub vehicle_outage_s: f64,
}

impl AttitudeStreamModel {
    pub fn validate(&self) -> Result<(), InvalidOption> {
        require(self.rate_hz > 0.0, "--rate", "positive")?;
        require(
            matches!(self.vehicle_bias_deg, [r, p] if r.is_finite() && p.is_finite()),
            "--vehicle-bias-deg",
            "two finite angles (roll, pitch)",
        )?;
        require(
            self.vehicle_noise_deg >= 0.0
                && self.vehicle_outages_per_min >= 0.0
                && self.vehicle_outage_s > 0.0
                && self.vehicle_time_error_ms.is_finite()
                && self.heave_noise_m >= 0.0,
            "--vehicle-*, --heave-noise-m",
            "noise and outages must not be negative, outages must last",
        )?;
        // `height_fusion_s` comes from `[vehicle]`, which `VehicleConfig::validate` checks.
        self.vehicle_height().validate()?;
        let shares = [self.nan_share, self.stale_share, self.dropout, self.outliers];
        require(
            shares.iter().all(|v| (0.0..=1.0).contains(v)),
            "--nan-share, --stale-share, --dropout, --outliers",
            "shares in [0, 1]",
        )?;
        require(
            self.frozen_per_min >= 0.0 && self.frozen_s > 0.0 && self.jitter_ms >= 0.0,
            "--frozen-*, --jitter-ms",
            "not negative, and frozen spells must last",
        )
    }

    /// The autopilot's height error as the trials' fault model has it.
    fn vehicle_height(&self) -> FrameFaultModel {
        FrameFaultModel {
            vehicle_height_noise_m: self.vehicle_height_noise_m,
            vehicle_height_drift_mps: self.vehicle_height_drift_mps,
            ..FrameFaultModel::default()
        }
    }

    /// `frames` attitudes of the deck whose truth (roll, pitch in deg, height in m) `truth`
    /// gives, from a random stream of `seed` and `sea_state`.
    pub fn measure(
        &self,
        truth: &dyn Fn(f64) -> [f64; 3],
        frames: usize,
        seed: u64,
        sea_state: u32,
    ) -> Vec<FrameInput> {
        let bias = self.vehicle_bias_deg;
        let mut rng = SplitMix64::new(seed.wrapping_mul(0x9E37_79B9) ^ sea_state as u64);
        // What compensating with the autopilot's attitude leaves in the deck's roll and pitch:
        // the sway over the timing error, the autopilot's bias and noise.
        let hover = VehicleSway::hover(seed, 1.0);
        let dt = self.vehicle_time_error_ms / 1e3;
        let vehicle_error = |t: f64, rng: &mut SplitMix64| {
            let [r1, p1, _] = hover.attitude(t).to_degrees();
            let [r0, p0, _] = hover.attitude(t - dt).to_degrees();
            let timing = if self.vehicle_sways {
                [r1 - r0, p1 - p0]
            } else {
                [0.0; 2]
            };
            [0, 1].map(|i| timing[i] + bias[i] + self.vehicle_noise_deg * rng.next_gaussian())
        };
        // The deck's height is the vehicle's less the camera's over the deck: the autopilot's
        // height error, after the fusion with its vertical speed, enters it one for one.
        let height_error = VehicleHeightError::new(&self.vehicle_height(), seed ^ ((sea_state as u64) << 32));
        let mut fusion = HeightFusion::new(self.height_fusion_s);
        let mut next_height_sample = 0u64;
        // The newest sample: its time (s), fused error (m) and speed error (m/s).
        let mut newest = (0.0, 0.0, 0.0);
        let mut fused_error = |t: f64| {
            // Samples of the autopilot's stream (100 Hz) up to the frame; the error at the
            // frame is the newest sample's, carried by its speed error.
            while next_height_sample as f64 * VEHICLE_HEIGHT_PERIOD_S <= t + 1e-9 {
                let ts = next_height_sample as f64 * VEHICLE_HEIGHT_PERIOD_S;
                let rate = height_error.rate_error_mps(ts);
                let fused = fusion
                    .update(
                        (ts * 1e9).round() as u64,
                        Some(height_error.error_m(ts)),
                        Some(rate),
                    )
                    .unwrap_or(0.0);
                newest = (ts, fused, rate);
                next_height_sample += 1;
            }
            let (ts, fused, rate) = newest;
            fused + rate * (t - ts)
        };
        let mut outages = Episodes::new(self.vehicle_outages_per_min, self.vehicle_outage_s, self.rate_hz);
        let mut frozen = Episodes::new(self.frozen_per_min, self.frozen_s, self.rate_hz);
        let (mut frozen_deck, mut repeats) = (None, 0u32);
        (0..frames)
            .map(|k| {
                let t = k as f64 / self.rate_hz;
                let [r, p, h] = truth(t);
                let h = h + fused_error(t);
                let vehicle_missing = outages.at(t, &mut rng);
                let [er, ep] = vehicle_error(t, &mut rng);
                let (r, p) = (r + er, p + ep);
                let frozen_now = frozen.at(t, &mut rng);
                let deck = if rng.next_f64() < self.dropout {
                    None
                } else {
                    let mut m = [
                        r + self.noise_deg * rng.next_gaussian(),
                        p + self.noise_deg * rng.next_gaussian(),
                    ];
                    let height = h + self.heave_noise_m * rng.next_gaussian();
                    if rng.next_f64() < self.outliers {
                        let i = (rng.next_u64() % 2) as usize;
                        m[i] += (5.0 + 10.0 * rng.next_f64()) * if rng.next_f64() < 0.5 { -1.0 } else { 1.0 };
                    }
                    if rng.next_f64() < self.nan_share {
                        m[0] = f64::NAN;
                    }
                    Some(DeckObservation::new(m[0], m[1], height))
                };
                // A frozen camera: the same image again and again. The estimator sees the same
                // markers and, from the `FROZEN_IMAGE_REPEATS`-th repeat on (the first), says so
                // (no valid attitude).
                let (deck, frozen_image) = if frozen_now {
                    let frozen = *frozen_deck.get_or_insert(deck);
                    let seen = frozen.is_some() && repeats >= FROZEN_IMAGE_REPEATS;
                    repeats += 1;
                    (if seen { None } else { frozen }, seen)
                } else {
                    frozen_deck = None;
                    repeats = 0;
                    (deck, false)
                };
                let stamp = t + self.jitter_ms / 1e3 * rng.next_gaussian();
                let late = if rng.next_f64() < self.stale_share {
                    1.0
                } else {
                    0.0
                };
                FrameInput {
                    t_s: stamp,
                    deck,
                    age_s: self.latency_ms / 1e3 + late,
                    vehicle_missing,
                    frozen_image,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The height estimate's error: its slow part's rate has the stated deviation and is the
    /// derivative of its value; its noise has the stated deviation; the same approach and time
    /// give the same error (the in-process runner and the processes' stream agree).
    #[test]
    fn the_height_estimates_error_has_its_stated_size() {
        let model = FrameFaultModel {
            vehicle_height_drift_mps: 0.05,
            ..FrameFaultModel::default()
        };
        let slow = VehicleHeightError::new(&model, 3);
        let n = 200_000;
        let (mut rate2, mut worst_diff) = (0.0, 0.0f64);
        for k in 0..n {
            let t = k as f64 * 0.01;
            let r = slow.rate_error_mps(t);
            rate2 += r * r;
            let numeric = (slow.error_m(t + 1e-4) - slow.error_m(t - 1e-4)) / 2e-4;
            worst_diff = worst_diff.max((numeric - r).abs());
        }
        let rate_rms = (rate2 / n as f64).sqrt();
        assert!((rate_rms - 0.05).abs() < 0.01, "{rate_rms}");
        assert!(worst_diff < 1e-6, "{worst_diff}");
        let noisy = VehicleHeightError::new(
            &FrameFaultModel {
                vehicle_height_noise_m: 0.02,
                ..FrameFaultModel::default()
            },
            3,
        );
        let e: Vec<f64> = (0..n).map(|k| noisy.error_m(k as f64 * 0.01)).collect();
        let sd = (e.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
        assert!((sd - 0.02).abs() < 0.001, "{sd}");
        assert_eq!(noisy.error_m(12.34), noisy.error_m(12.34));
        assert_eq!(noisy.rate_error_mps(12.34), 0.0);
        assert_eq!(
            VehicleHeightError::new(&FrameFaultModel::default(), 3).error_m(5.0),
            0.0
        );
    }

    /// Episodes start at the stated rate and last their stated time: over an hour at 10 Hz,
    /// 2 a minute of 1.5 s each cover about 3 s a minute (less their overlaps).
    #[test]
    fn episodes_start_at_their_rate_and_last_their_time() {
        let mut rng = SplitMix64::new(7);
        let mut e = Episodes::new(2.0, 1.5, 10.0);
        let mut covered = 0;
        let mut longest_run = 0;
        let mut run = 0;
        for k in 0..36_000 {
            if e.at(k as f64 / 10.0, &mut rng) {
                covered += 1;
                run += 1;
                longest_run = longest_run.max(run);
            } else {
                run = 0;
            }
        }
        // Expected share 1 - exp(-rate * duration) = 1 - exp(-0.05) = 4.9 %.
        let share = covered as f64 / 36_000.0;
        assert!((0.040..0.058).contains(&share), "{share}");
        assert!(longest_run >= 15, "{longest_run}");
        let mut none = Episodes::new(0.0, 1.0, 10.0);
        assert!((0..1000).all(|k| !none.at(k as f64 / 10.0, &mut rng)));
    }

    /// A frozen camera repeats its first image bit for bit; a lost frame is lost at its share.
    #[test]
    fn frame_faults_freeze_and_lose() {
        let model = FrameFaultModel {
            drop_share: 0.1,
            frozen_per_min: 6.0,
            frozen_s: 2.0,
            ..Default::default()
        };
        model.validate().unwrap();
        let mut f = FrameFaults::new(&model, 10.0, 3);
        let (mut lost, mut frozen_frames) = (0, 0);
        for k in 0..6000u32 {
            let mut pixels = [(k % 251) as u8; 16];
            let kept = f.inject(k as f64 / 10.0, &mut pixels);
            lost += usize::from(!kept);
            frozen_frames += usize::from(pixels[0] != (k % 251) as u8);
        }
        assert!((450..750).contains(&lost), "{lost}");
        // 6 a minute of 2 s: about a sixth of the frames show an older image.
        assert!((600..1400).contains(&frozen_frames), "{frozen_frames}");
        let bad = FrameFaultModel {
            drop_share: 1.5,
            ..model
        };
        assert_eq!(bad.validate().unwrap_err().option, "--drop-share");
    }

    /// A 10 Hz stream without noise or faults, 5 ms late, its height fused over 1 s.
    fn fault_free_stream() -> AttitudeStreamModel {
        AttitudeStreamModel {
            rate_hz: 10.0,
            noise_deg: 0.0,
            heave_noise_m: 0.0,
            vehicle_height_noise_m: 0.0,
            vehicle_height_drift_mps: 0.0,
            height_fusion_s: 1.0,
            dropout: 0.0,
            outliers: 0.0,
            nan_share: 0.0,
            stale_share: 0.0,
            jitter_ms: 0.0,
            latency_ms: 5.0,
            frozen_per_min: 0.0,
            frozen_s: 2.0,
            vehicle_sways: false,
            vehicle_bias_deg: [0.0, 0.0],
            vehicle_noise_deg: 0.0,
            vehicle_time_error_ms: 0.0,
            vehicle_outages_per_min: 0.0,
            vehicle_outage_s: 1.0,
        }
    }

    /// The attitude stream: noise of the stated size, frozen frames refused from the repeat the
    /// estimator notices on, outages marked, the latency as the age.
    #[test]
    fn the_attitude_stream_carries_its_faults() {
        let model = AttitudeStreamModel {
            noise_deg: 0.1,
            frozen_per_min: 3.0,
            vehicle_outages_per_min: 1.0,
            ..fault_free_stream()
        };
        model.validate().unwrap();
        let truth = |t: f64| [2.0 * (0.5 * t).sin(), 1.0, 0.1 * t];
        let stream = model.measure(&truth, 12_000, 5, 4);
        assert_eq!(stream.len(), 12_000);
        let residuals: Vec<f64> = stream
            .iter()
            .filter(|f| !f.frozen_image)
            .filter_map(|f| f.deck.map(|d| d.pitch_deg - 1.0))
            .collect();
        let rms = (residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len() as f64).sqrt();
        assert!((0.09..0.13).contains(&rms), "{rms}");
        assert!(stream.iter().all(|f| (f.age_s - 0.005).abs() < 1e-12));
        let frozen = stream.iter().filter(|f| f.frozen_image).count();
        assert!(frozen > 0 && stream.iter().filter(|f| f.frozen_image).all(|f| f.deck.is_none()));
        let missing = stream.iter().filter(|f| f.vehicle_missing).count();
        assert!((100..400).contains(&missing), "{missing}");
        let bad = AttitudeStreamModel {
            dropout: -0.1,
            ..model
        };
        assert!(bad.validate().unwrap_err().option.contains("--dropout"));
    }

    /// The deck's height carries the autopilot's height error as the estimate pipeline sees it:
    /// 2 cm of white noise on each 100 Hz height, fused with the vertical speed over 1 s, leaves
    /// about 1.4 mm (sigma sqrt(dt / 2 tau)); not fused, all of it. The heave rate between
    /// frames is what the forecast differences.
    #[test]
    fn the_deck_height_carries_the_autopilots_fused_height_error() {
        let model = AttitudeStreamModel {
            vehicle_height_noise_m: 0.02,
            ..fault_free_stream()
        };
        let truth = |t: f64| [0.0, 0.0, (0.6 * t).sin()];
        let errors = |m: &AttitudeStreamModel| -> (f64, f64) {
            let e: Vec<f64> = m
                .measure(&truth, 6000, 9, 5)
                .iter()
                .enumerate()
                .skip(50)
                .map(|(k, f)| f.deck.unwrap().height_m - truth(k as f64 / 10.0)[2])
                .collect();
            let rms = |v: &mut dyn Iterator<Item = f64>| {
                let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
                (s / n as f64).sqrt()
            };
            (
                rms(&mut e.iter().copied()),
                rms(&mut e.windows(2).map(|p| (p[1] - p[0]) * 10.0)),
            )
        };
        let (fused, fused_rate) = errors(&model);
        assert!((0.0008..0.0025).contains(&fused), "{fused} m");
        assert!(fused_rate < 0.01, "{fused_rate} m/s");
        let (raw, raw_rate) = errors(&AttitudeStreamModel {
            height_fusion_s: 0.0,
            ..model.clone()
        });
        assert!((0.018..0.022).contains(&raw), "{raw} m");
        assert!(raw_rate > 0.25, "{raw_rate} m/s");
        // A drift the height and the speed share passes through the fusion.
        let drift = AttitudeStreamModel {
            vehicle_height_noise_m: 0.0,
            vehicle_height_drift_mps: 0.05,
            ..model
        };
        let (_, drift_rate) = errors(&drift);
        assert!((0.03..0.07).contains(&drift_rate), "{drift_rate} m/s");
    }
}
