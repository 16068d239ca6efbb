//! A simulated autopilot's attitude stream: what the vehicle's attitude looks like once it has
//! gone through an autopilot's estimator and a link (CONVENTIONS.md §5). Samples at the
//! autopilot's rate, each the true `R_V` turned by a constant bias and Gaussian noise (both
//! small rotations in the body frame), stamped with a timing error: what latency and clock
//! synchronisation leave in a timestamp once it is on the frames' clock (TIMESYNC leaves about
//! half the round trip's asymmetry, arrival times the whole latency).

use crate::motion::MotionProfile;
use crate::rng::SplitMix64;
use deckwatch_common::vehicle::VehicleStateSample;
use deckwatch_common::InvalidOption;
use deckwatch_common::{Quaternion, Rpy};
use serde::{Deserialize, Serialize};

/// `[sim.autopilot]`, `--autopilot-*`: the stream `sim record` writes as `vehicle.csv`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct AutopilotArgs {
    /// Attitude samples per second (PX4 and ArduPilot stream 50-200 Hz); 0: no stream.
    #[cfg_attr(feature = "cli", arg(long = "autopilot-rate-hz", default_value_t = 100.0))]
    pub rate_hz: f64,
    /// Noise of each angle (deg, one standard deviation).
    #[cfg_attr(feature = "cli", arg(long = "autopilot-noise-deg", default_value_t = 0.0))]
    pub noise_deg: f64,
    /// Constant error of roll, pitch, yaw (deg): a misaligned IMU, an estimator's bias.
    #[cfg_attr(
        feature = "cli",
        arg(long = "autopilot-bias-deg", value_delimiter = ',', allow_negative_numbers = true, default_values_t = [0.0, 0.0, 0.0])
    )]
    pub bias_deg: Vec<f64>,
    /// Error of every timestamp on the frames' clock (ms; positive: stamped late).
    #[cfg_attr(
        feature = "cli",
        arg(
            long = "autopilot-time-error-ms",
            default_value_t = 0.0,
            allow_negative_numbers = true
        )
    )]
    pub time_error_ms: f64,
}

impl Default for AutopilotArgs {
    fn default() -> Self {
        Self {
            rate_hz: 100.0,
            noise_deg: 0.0,
            bias_deg: vec![0.0; 3],
            time_error_ms: 0.0,
        }
    }
}

impl AutopilotArgs {
    /// Checks the values; errors name the option.
    pub fn validate(&self) -> Result<(), InvalidOption> {
        if !(self.rate_hz >= 0.0 && self.rate_hz <= 1000.0) {
            return Err(InvalidOption::new(
                "--autopilot-rate-hz",
                format!("must be in [0, 1000], got {}", self.rate_hz),
            ));
        }
        if !(self.noise_deg >= 0.0 && self.noise_deg <= 10.0) {
            return Err(InvalidOption::new(
                "--autopilot-noise-deg",
                format!("must be in [0, 10], got {}", self.noise_deg),
            ));
        }
        if self.bias_deg.len() != 3 || !self.bias_deg.iter().all(|b| b.is_finite() && b.abs() <= 10.0) {
            return Err(InvalidOption::new(
                "--autopilot-bias-deg",
                format!("three angles within +-10 deg, got {:?}", self.bias_deg),
            ));
        }
        if !(self.time_error_ms.abs() <= 1000.0) {
            return Err(InvalidOption::new(
                "--autopilot-time-error-ms",
                format!("must be within +-1000, got {}", self.time_error_ms),
            ));
        }
        Ok(())
    }

    /// The stream over `[0, end_s]` of the vehicle in `profile`: timestamp on the frames' clock,
    /// measured `R_V` and the vehicle's height in W (exact: an autopilot's height is good to
    /// centimetres over a landing), increasing in time. Empty at rate 0.
    pub fn samples(&self, profile: &dyn MotionProfile, end_s: f64, seed: u64) -> Vec<VehicleStateSample> {
        if !(self.rate_hz > 0.0) {
            return Vec::new();
        }
        let mut rng = SplitMix64::new(seed ^ 0xA0_70_91_10);
        let bias = match self.bias_deg[..] {
            [r, p, y] => [r, p, y],
            _ => [0.0; 3],
        };
        let n = (end_s * self.rate_hz).floor() as u64 + 1;
        let offset_s = self.time_error_ms / 1e3;
        let mut out = Vec::with_capacity(n as usize);
        for j in 0..n {
            let t = j as f64 / self.rate_hz;
            let noise = [0; 3].map(|_| self.noise_deg * rng.next_gaussian());
            let error = Rpy::from_degrees(bias[0] + noise[0], bias[1] + noise[1], bias[2] + noise[2]);
            let truth = profile.sample(t);
            let measured = truth.viewpoint.vehicle_attitude * error.to_matrix();
            let stamp_s = t + offset_s;
            if stamp_s < 0.0 {
                continue;
            }
            out.push(VehicleStateSample {
                time_ns: (stamp_s * 1e9).round() as u64,
                quaternion: Quaternion::from_matrix(&measured),
                height_m: Some(truth.vehicle_height_m()),
                vertical_speed_mps: None,
            });
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::{ShipMotion, Swaying, VehicleSway};
    use deckwatch_common::rotation::rotation_angle_between;

    #[test]
    fn exact_stream_is_the_vehicle_and_errors_are_what_was_asked() {
        let profile = Swaying {
            inner: ShipMotion::sea_state_6(1),
            sway: VehicleSway::hover(1, 1.0),
        };
        let exact = AutopilotArgs::default().samples(&profile, 2.0, 1);
        assert_eq!(exact.len(), 201);
        for s in &exact {
            let truth = profile.sample(s.time_ns as f64 / 1e9);
            let q = s.quaternion;
            assert!(rotation_angle_between(&q.to_matrix(), &truth.viewpoint.vehicle_attitude) < 1e-9);
            assert_eq!(s.height_m, Some(truth.vehicle_height_m()));
        }
        let noisy = AutopilotArgs {
            noise_deg: 0.3,
            bias_deg: vec![0.5, 0.0, 0.0],
            time_error_ms: 5.0,
            ..AutopilotArgs::default()
        };
        let s = noisy.samples(&profile, 20.0, 1);
        assert_eq!(s[0].time_ns, 5_000_000, "stamped 5 ms late");
        // The roll error about the body's x: mean = bias, spread = noise.
        let errors: Vec<f64> = s
            .iter()
            .map(|s| {
                let truth = profile
                    .sample(s.time_ns as f64 / 1e9 - 0.005)
                    .viewpoint
                    .vehicle_attitude;
                Rpy::from_matrix(&(truth.transpose() * s.quaternion.to_matrix()))
                    .roll
                    .to_degrees()
            })
            .collect();
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        let sd = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / errors.len() as f64).sqrt();
        assert!(
            (mean - 0.5).abs() < 0.03 && (sd - 0.3).abs() < 0.03,
            "{mean} {sd}"
        );
        assert!(AutopilotArgs {
            bias_deg: vec![1.0],
            ..AutopilotArgs::default()
        }
        .validate()
        .is_err());
    }
}
