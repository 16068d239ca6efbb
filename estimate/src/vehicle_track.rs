//! The vehicle's attitude at a frame's mid-exposure from the autopilot's attitude stream: the
//! newest samples on one clock, interpolated (slerp) to any instant between them, with the
//! angular rate and its change from a fit through them (what compensation and the rolling
//! shutter need); and the ship's mean heading. Used by the estimation pipeline
//! (`DeckEstimator`) and by replay of a recording's `vehicle.csv`.

use crate::vehicle_height::HeightFusion;
use deckwatch_common::vehicle::{Compensation, VehicleStateSample};
use deckwatch_common::Quaternion;
use std::collections::VecDeque;

/// The vehicle's attitude at one instant, from a [`VehicleTrack`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackAttitude {
    pub quaternion: Quaternion,
    /// The height, linear between two samples that have one; beyond the newest (or before the
    /// oldest) carried by that sample's vertical speed when it has one, else held.
    pub height_m: Option<f64>,
    /// From the instant to the nearest sample used (ns).
    pub age_ns: u64,
}

/// Why a [`VehicleTrack`] has no attitude for an instant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum TrackMiss {
    #[error("no vehicle attitude sample yet")]
    Empty,
    /// The nearest sample is farther than the allowed gap (ns).
    #[error("the nearest vehicle attitude sample is {distance_ns} ns away")]
    TooFar { distance_ns: u64 },
}

/// The newest vehicle attitude samples on one clock (ns), interpolated (slerp) to any instant
/// between them. Their heights are the autopilot's height fused with its vertical speed where
/// the samples carry one ([`HeightFusion`]).
#[derive(Debug, Clone)]
pub struct VehicleTrack {
    samples: VecDeque<VehicleStateSample>,
    capacity: usize,
    height_fusion: HeightFusion,
    /// Samples refused: not after the newest, or not a rotation.
    pub rejected: u64,
}

impl VehicleTrack {
    /// Keeps the newest `capacity` samples (at 200 Hz, 512 are 2.5 s: longer than any frame
    /// takes through the pipeline).
    pub fn new(capacity: usize) -> Self {
        Self {
            samples: VecDeque::with_capacity(capacity.max(2)),
            capacity: capacity.max(2),
            height_fusion: HeightFusion::default(),
            rejected: 0,
        }
    }

    /// The same, with the height fused over `time_constant_s` (0: the reported heights as they
    /// are).
    pub fn with_height_fusion(capacity: usize, time_constant_s: f64) -> Self {
        Self {
            height_fusion: HeightFusion::new(time_constant_s),
            ..Self::new(capacity)
        }
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The newest sample's time.
    pub fn newest_ns(&self) -> Option<u64> {
        self.samples.back().map(|s| s.time_ns)
    }

    /// Adds a sample; false (and counted) when it is not after the newest or not a rotation. A
    /// height that is not finite is dropped (the attitude is kept); a height with a vertical
    /// speed is kept fused with it.
    pub fn push(&mut self, sample: VehicleStateSample) -> bool {
        let q = sample.quaternion;
        let ok = self.newest_ns().is_none_or(|t| sample.time_ns > t) && (q.norm() - 1.0).abs() < 1e-3;
        match q.normalized().filter(|_| ok) {
            Some(quaternion) => {
                if self.samples.len() == self.capacity {
                    self.samples.pop_front();
                }
                let height_m =
                    self.height_fusion
                        .update(sample.time_ns, sample.height_m, sample.vertical_speed_mps);
                self.samples.push_back(VehicleStateSample {
                    quaternion,
                    height_m,
                    ..sample
                });
                true
            }
            None => {
                self.rejected += 1;
                false
            }
        }
    }

    /// The vehicle's attitude for a frame at `t_ns`, as a frame carries it: `Stream` with the
    /// interpolated attitude, or `Missing`.
    pub fn vehicle_attitude_at(
        &self,
        t_ns: u64,
        max_gap_ns: u64,
    ) -> deckwatch_common::messages::VehicleAttitude {
        let motion = self.motion_at(t_ns, max_gap_ns);
        match self.at(t_ns, max_gap_ns) {
            Ok(a) => deckwatch_common::messages::VehicleAttitude {
                compensation: Compensation::Stream.into(),
                rpy: a.quaternion.to_rpy(),
                age_ms: a.age_ns as f64 / 1e6,
                height_m: a.height_m.unwrap_or(f64::NAN),
                rate_dps: motion.map_or([f64::NAN; 3], |(w, _)| [w.x, w.y, w.z].map(f64::to_degrees)),
                acceleration_dps2: motion
                    .map_or([f64::NAN; 3], |(_, a)| [a.x, a.y, a.z].map(f64::to_degrees)),
            },
            Err(_) => deckwatch_common::messages::VehicleAttitude::MISSING,
        }
    }

    /// Samples within this of an instant give its angular velocity and acceleration: a
    /// rolling shutter's readout (up to 30 ms) with some margin.
    pub const MOTION_WINDOW_NS: u64 = 25_000_000;

    /// The angular velocity (rad/s) and acceleration (rad/s^2) in W at `t_ns`: a quadratic
    /// least-squares fit of the rotation from the attitude at `t_ns` to each sample within
    /// [`Self::MOTION_WINDOW_NS`] (or twice that for a slow stream; at least four samples),
    /// which averages the samples' noise
    /// instead of differencing it; none when there are fewer or no attitude at `t_ns`.
    pub fn motion_at(
        &self,
        t_ns: u64,
        max_gap_ns: u64,
    ) -> Option<(nalgebra::Vector3<f64>, nalgebra::Vector3<f64>)> {
        let r0 = self.at(t_ns, max_gap_ns).ok()?.quaternion.to_matrix();
        // A slower stream (50 Hz) gets a wider window.
        let window_ns = [Self::MOTION_WINDOW_NS, 2 * Self::MOTION_WINDOW_NS]
            .into_iter()
            .find(|w| {
                let (lo, hi) = (t_ns.saturating_sub(*w), t_ns.saturating_add(*w));
                let first = self.samples.partition_point(|s| s.time_ns < lo);
                self.samples
                    .range(first..)
                    .take_while(|s| s.time_ns <= hi)
                    .count()
                    >= 4
            })?;
        let lo = t_ns.saturating_sub(window_ns);
        let hi = t_ns.saturating_add(window_ns);
        let first = self.samples.partition_point(|s| s.time_ns < lo);
        let window = self.samples.range(first..).take_while(|s| s.time_ns <= hi);
        // theta(s) = c + w s + a s^2 / 2 per axis: normal equations of the three unknowns.
        let (mut ata, mut atb) = (
            nalgebra::Matrix3::<f64>::zeros(),
            nalgebra::Matrix3::<f64>::zeros(),
        );
        let mut count = 0;
        for sample in window {
            let s = (sample.time_ns as f64 - t_ns as f64) / 1e9;
            let theta =
                nalgebra::Rotation3::from_matrix_unchecked(sample.quaternion.to_matrix() * r0.transpose())
                    .scaled_axis();
            let row = nalgebra::Vector3::new(1.0, s, 0.5 * s * s);
            ata += row * row.transpose();
            atb += row * theta.transpose();
            count += 1;
        }
        if count < 4 {
            return None;
        }
        let x = ata.cholesky()?.solve(&atb);
        Some((x.row(1).transpose(), x.row(2).transpose()))
    }

    /// The attitude at `t_ns`: slerp between the samples around it, or the nearest sample when
    /// `t_ns` is outside them; none when the nearest sample used is more than `max_gap_ns` away.
    /// Outside them the height is carried by the nearest sample's vertical speed: a frame is
    /// often newer than the newest autopilot sample, and a held height put a sawtooth of up to
    /// 8 mm on the deck's height at 30 frames a second during a descent at 1.2 m/s (100 Hz
    /// samples), a heave rate of 0.1-0.2 m/s between frames that the deck did not have. The
    /// attitude is held: an angular rate from a few noisy samples would add more than it takes.
    pub fn at(&self, t_ns: u64, max_gap_ns: u64) -> Result<TrackAttitude, TrackMiss> {
        let (first, last) = match (self.samples.front(), self.samples.back()) {
            (Some(f), Some(l)) => (*f, *l),
            _ => return Err(TrackMiss::Empty),
        };
        let hold = |s: VehicleStateSample| {
            let distance_ns = s.time_ns.abs_diff(t_ns);
            if distance_ns <= max_gap_ns {
                let ahead_s = (t_ns as f64 - s.time_ns as f64) / 1e9;
                let rate_mps = s.vertical_speed_mps.filter(|v| v.is_finite()).unwrap_or(0.0);
                Ok(TrackAttitude {
                    quaternion: s.quaternion,
                    height_m: s.height_m.map(|h| h + rate_mps * ahead_s),
                    age_ns: distance_ns,
                })
            } else {
                Err(TrackMiss::TooFar { distance_ns })
            }
        };
        if t_ns >= last.time_ns {
            return hold(last);
        }
        if t_ns <= first.time_ns {
            return hold(first);
        }
        // The first sample after t_ns (samples are strictly increasing in time).
        let i = self.samples.partition_point(|s| s.time_ns <= t_ns);
        let (a, b) = (self.samples[i - 1], self.samples[i]);
        let distance_ns = (t_ns - a.time_ns).min(b.time_ns - t_ns);
        if distance_ns > max_gap_ns {
            return Err(TrackMiss::TooFar { distance_ns });
        }
        let s = (t_ns - a.time_ns) as f64 / (b.time_ns - a.time_ns) as f64;
        Ok(TrackAttitude {
            quaternion: a.quaternion.slerp(&b.quaternion, s),
            height_m: a.height_m.zip(b.height_m).map(|(ha, hb)| ha + s * (hb - ha)),
            age_ns: distance_ns,
        })
    }
}

/// The ship's mean heading from north (rad, counter-clockwise seen from above), a circular
/// exponential average: with an autopilot's north-referenced attitude, W's x is this heading, so
/// deck roll and pitch are about the ship's own axes whatever its course (CONVENTIONS.md §6).
#[derive(Debug, Clone, Default)]
pub struct MeanHeading {
    /// Unit vector of the mean and the time of the last update (s).
    state: Option<([f64; 2], f64)>,
}

impl MeanHeading {
    /// Adds the deck's heading at `t_s` and returns the mean; `time_constant_s` is how quickly
    /// it follows a turn. Non-finite inputs leave it unchanged.
    pub fn update(&mut self, t_s: f64, heading_rad: f64, time_constant_s: f64) -> Option<f64> {
        if !(t_s.is_finite() && heading_rad.is_finite()) {
            return self.value();
        }
        let h = [heading_rad.cos(), heading_rad.sin()];
        let next = match self.state {
            None => h,
            Some((m, t0)) => {
                let dt = (t_s - t0).max(0.0);
                let a = 1.0 - (-dt / time_constant_s).exp();
                [m[0] + a * (h[0] - m[0]), m[1] + a * (h[1] - m[1])]
            }
        };
        self.state = Some((next, t_s));
        self.value()
    }

    pub fn value(&self) -> Option<f64> {
        self.state.map(|([c, s], _)| s.atan2(c)).filter(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::Rpy;

    fn q(roll_deg: f64, pitch_deg: f64, yaw_deg: f64) -> Quaternion {
        Quaternion::from_matrix(&Rpy::from_degrees(roll_deg, pitch_deg, yaw_deg).to_matrix())
    }

    #[test]
    fn the_track_gives_the_rate_and_its_change_through_noise() {
        // A sway: roll 3 deg at 1.7 Hz about a tilted attitude, sampled at 200 Hz with 0.02 deg
        // of noise on each angle (about what an autopilot's estimate carries).
        let omega = std::f64::consts::TAU * 1.7;
        let attitude = |t: f64| Rpy::from_degrees(3.0 * (omega * t).sin() + 5.0, -4.0, 30.0).to_matrix();
        let mut track = VehicleTrack::new(512);
        let mut rng = 12345u64;
        let mut noise = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.02 * 12f64.sqrt()
        };
        for k in 0..200u64 {
            let t = k as f64 * 0.005;
            let r = attitude(t) * Rpy::from_degrees(noise(), noise(), noise()).to_matrix();
            track.push(VehicleStateSample::attitude(
                k * 5_000_000,
                Quaternion::from_matrix(&r),
            ));
        }
        let t = 0.4321;
        let (w, a) = track.motion_at((t * 1e9) as u64, 20_000_000).unwrap();
        // The true rate and acceleration about W's x (the roll axis is W's x for X-Y-Z angles).
        let w_true = 3f64.to_radians() * omega * (omega * t).cos();
        let a_true = -3f64.to_radians() * omega * omega * (omega * t).sin();
        assert!(
            (w.x - w_true).abs() < 0.05 * w_true.abs().max(0.1),
            "{w:?} vs {w_true}"
        );
        assert!(w.yz().norm() < 0.02, "{w:?}");
        assert!((a.x - a_true).abs() < 0.25 * a_true.abs(), "{a:?} vs {a_true}");
        // The attitude the frame carries has them in deg/s and deg/s^2.
        let v = track.vehicle_attitude_at((t * 1e9) as u64, 20_000_000);
        assert!((v.rate_dps[0] - w.x.to_degrees()).abs() < 1e-9);
        assert!((v.acceleration_dps2[0] - a.x.to_degrees()).abs() < 1e-9);
        // Too few samples near the instant: unknown.
        assert!(track.motion_at(10_000_000_000, 20_000_000).is_none());
    }

    /// A frame newer than the newest sample (or older than the oldest), during a descent: the
    /// height follows the sample's vertical speed, exact for a steady descent.
    #[test]
    fn the_height_beyond_the_samples_follows_the_vertical_speed() {
        let mut t = VehicleTrack::with_height_fusion(16, 1.0);
        let height = |ns: u64| 3.0 - 1.2 * ns as f64 / 1e9;
        for k in 0..8u64 {
            let ns = k * 10_000_000;
            assert!(t.push(VehicleStateSample {
                time_ns: ns,
                quaternion: q(0.0, 0.0, 0.0),
                height_m: Some(height(ns)),
                vertical_speed_mps: Some(-1.2),
            }));
        }
        // 30 frames a second fall 3.3 and 6.7 ms after a 100 Hz sample.
        for ns in [73_333_333u64, 76_666_667, 80_000_000] {
            let a = t.at(ns, 20_000_000).unwrap();
            assert!((a.height_m.unwrap() - height(ns)).abs() < 1e-9, "{ns}: {a:?}");
        }
        let a = t.at(0, 20_000_000).unwrap();
        assert!((a.height_m.unwrap() - height(0)).abs() < 1e-9);
    }

    #[test]
    fn track_interpolates_holds_and_refuses() {
        let mut t = VehicleTrack::new(4);
        assert_eq!(t.at(0, 10), Err(TrackMiss::Empty));
        // 100 Hz roll ramp of 1 deg per sample.
        for k in 0..6u64 {
            assert!(t.push(VehicleStateSample {
                time_ns: k * 10_000_000,
                quaternion: q(k as f64, 0.0, 0.0),
                height_m: Some(10.0 + k as f64),
                vertical_speed_mps: None,
            }));
        }
        assert_eq!(t.len(), 4, "the oldest are dropped");
        let push = |t: &mut VehicleTrack, ns, q| t.push(VehicleStateSample::attitude(ns, q));
        assert!(
            !push(&mut t, 50_000_000, q(0.0, 0.0, 0.0)),
            "not after the newest"
        );
        assert!(!push(&mut t, 60_000_000, Quaternion::new(2.0, 0.0, 0.0, 0.0)));
        assert!(!push(
            &mut t,
            70_000_000,
            Quaternion::new(f64::NAN, 0.0, 0.0, 0.0)
        ));
        assert_eq!(t.rejected, 3);
        let a = t.at(32_500_000, 20_000_000).unwrap();
        assert!((a.quaternion.to_rpy().to_degrees()[0] - 3.25).abs() < 1e-9);
        assert!((a.height_m.unwrap() - 13.25).abs() < 1e-9, "height: linear");
        assert_eq!(a.age_ns, 2_500_000);
        // After the newest: held while close (the height too: no vertical speed), refused beyond.
        let h = t.at(55_000_000, 10_000_000).unwrap();
        assert!((h.quaternion.to_rpy().to_degrees()[0] - 5.0).abs() < 1e-9 && h.age_ns == 5_000_000);
        assert_eq!(h.height_m, Some(15.0));
        assert_eq!(
            t.at(80_000_000, 10_000_000),
            Err(TrackMiss::TooFar {
                distance_ns: 30_000_000
            })
        );
        // Before the oldest kept sample (20 ms).
        assert!(t.at(5_000_000, 10_000_000).is_err());
        // A hole in the stream wider than allowed.
        let mut g = VehicleTrack::new(8);
        push(&mut g, 0, q(0.0, 0.0, 0.0));
        push(&mut g, 200_000_000, q(1.0, 0.0, 0.0));
        assert_eq!(g.at(1_000_000, 30_000_000).unwrap().height_m, None);
        assert_eq!(
            g.at(100_000_000, 30_000_000),
            Err(TrackMiss::TooFar {
                distance_ns: 100_000_000
            })
        );
    }

    #[test]
    fn mean_heading_averages_across_north() {
        let mut h = MeanHeading::default();
        assert_eq!(h.value(), None);
        // Yawing +-10 deg about 179 deg: the mean stays near 179 across the +-180 seam.
        let mut v = 0.0;
        for k in 0..3000 {
            let t = k as f64 * 0.1;
            let psi = (179.0 + 10.0 * (0.5 * t).sin()).to_radians();
            v = h.update(t, psi, 30.0).unwrap();
        }
        let d = deckwatch_common::rotation::angle_difference(v, 179f64.to_radians()).to_degrees();
        assert!(d.abs() < 0.5, "{d}");
        assert_eq!(h.update(1e4, f64::NAN, 30.0), Some(v));
    }
}
