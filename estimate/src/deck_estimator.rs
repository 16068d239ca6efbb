//! The estimation pipeline of one camera as a whole ([`DeckEstimator`]): from a frame's markers
//! to the deck's attitude in W, with everything around the estimators that makes the result
//! the deck's and not the camera's: the vehicle's attitude, the ship's heading, the deck's
//! height, the rolling shutter's motion, and a frozen image told from a still deck.

use crate::config::paper_variant;
use crate::vehicle_track::{MeanHeading, VehicleTrack};
use crate::{
    DeckMotionHistory, EstimateConfig, FrameMotion, NotEstimable, PaperEstimator, PaperVariant, PoseConfig,
    PoseError, PoseEstimator,
};
use deckwatch_common::markers::DetectionStatus;
use deckwatch_common::messages::{
    AlternativeAttitude, AttitudeFailure, AttitudeMessage, EstimatorKind, MarkerMessage, VehicleAttitude,
    VehicleSample, FROZEN_IMAGE_REPEATS,
};
use deckwatch_common::rotation::rot_z;
use deckwatch_common::vehicle::{Compensation, VehicleAttitudeSource, VehicleConfig, VehicleStateSample};
use deckwatch_common::{Attitude, RotationMatrix, Rpy};

fn paper_failure(e: &NotEstimable) -> AttitudeFailure {
    match e {
        NotEstimable::CentreMissing
        | NotEstimable::BowMissing
        | NotEstimable::TooFewRingMarkers { .. }
        | NotEstimable::AmbiguousDeckPlane
        | NotEstimable::WrongMarkerCount { .. } => AttitudeFailure::TooFewMarkers,
        NotEstimable::AltitudeRequired | NotEstimable::InvalidAltitude => AttitudeFailure::NoAltitude,
        _ => AttitudeFailure::Degenerate,
    }
}

fn pose_failure(e: &PoseError) -> AttitudeFailure {
    match e {
        PoseError::TooFewMarkers { .. }
        | PoseError::BowMissing
        | PoseError::BowOutlier
        | PoseError::WrongMarkerCount { .. } => AttitudeFailure::TooFewMarkers,
        PoseError::Undistortion { .. } | PoseError::Degenerate(_) => AttitudeFailure::Degenerate,
    }
}

/// The deck centre's height in W: the vehicle's height less the camera's height over the deck
/// centre (W's z is vertical whatever its heading, so the heading reference does not matter).
/// NaN when either is unknown.
fn deck_height_m(vehicle: &VehicleAttitude, e: &Estimate) -> f64 {
    vehicle.height_m - e.camera_position_m[2]
}

/// One estimator's attitude, as it goes into a message.
struct Estimate {
    attitude: deckwatch_common::Attitude,
    image_ellipse: Option<deckwatch_common::ellipse::Ellipse>,
    residual: f64,
    markers_used: u32,
    rpy_std_deg: [f64; 3],
    camera_position_m: [f64; 3],
    camera_position_covariance_m2: [[f64; 3]; 3],
}

impl Estimate {
    fn write(&self, out: &mut AttitudeMessage) {
        out.rpy = self.attitude.rpy;
        out.quaternion = self.attitude.quaternion;
        out.euler313 = self.attitude.euler313;
        out.has_image_ellipse = self.image_ellipse.is_some().into();
        out.image_ellipse = self.image_ellipse.unwrap_or_default();
        out.residual = self.residual;
        out.markers_used = self.markers_used;
        out.rpy_std_deg = self.rpy_std_deg;
        out.camera_position_m = self.camera_position_m;
        out.camera_position_covariance_m2 = self.camera_position_covariance_m2;
    }
}

struct Outcome {
    kind: EstimatorKind,
    result: Result<Estimate, AttitudeFailure>,
}

/// Both estimator families, built for the camera and deck of the frames.
struct Estimators {
    paper: PaperEstimator,
    pose: PoseEstimator,
}

/// The estimation pipeline of one camera, frame after frame: the configured estimator (and the
/// other family beside it with `compare`), the vehicle's attitude taken out (the frame's own,
/// the autopilot's stream interpolated to mid-exposure, or a level gimbal), the ship's mean
/// heading as W's x, the deck's height, the rolling shutter's motion and the frozen-image check.
/// What the estimate stage and `deckwatch inproc`/`resim` run; no IPC.
pub struct DeckEstimator {
    primary: EstimatorKind,
    secondary: Option<EstimatorKind>,
    estimators: Option<Estimators>,
    /// Correct the full pose for a rolling shutter (`[estimate] rolling_shutter`).
    rolling_shutter: bool,
    /// The deck's recent poses (in the vehicle attitude's frame), for its rate within a frame.
    deck_motion: DeckMotionHistory,
    /// Rolling-shutter frames whose motion was partly unknown (no vehicle rate, or no recent
    /// deck poses: the first frames, after a gap): that part was taken as still.
    pub motion_unknown: u64,
    vehicle: VehicleConfig,
    /// The autopilot's attitude samples (`[vehicle] attitude = "autopilot"`).
    track: VehicleTrack,
    /// The ship's mean heading from north: W's x with the autopilot's attitude.
    heading: MeanHeading,
    /// Frames whose vehicle attitude was missing (`Compensation::Missing`).
    pub uncompensated: u64,
    /// The newest marker set's bits, and how many times in a row it came again.
    repeated_markers: Option<(u64, u32)>,
    /// Frames refused as a frozen image.
    pub frozen: u64,
    /// Frames with a valid attitude.
    pub estimated: u64,
}

/// A marker set's fingerprint: every found marker's centre, bit for bit.
fn marker_bits(m: &MarkerMessage) -> u64 {
    // FNV-1a over the bits: identical sets give identical fingerprints; a collision of two real
    // (noisy) sets is as likely as any other 64-bit one.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |v: u64| {
        for b in v.to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for marker in m.markers.markers.iter().filter(|k| k.valid.get()) {
        eat(marker.u.to_bits());
        eat(marker.v.to_bits());
    }
    eat(m.markers.count as u64);
    h
}

impl DeckEstimator {
    pub fn new(config: &EstimateConfig, vehicle: &VehicleConfig) -> Self {
        Self {
            primary: config.estimator,
            secondary: config.secondary(),
            estimators: None,
            rolling_shutter: config.rolling_shutter,
            deck_motion: DeckMotionHistory::new(),
            motion_unknown: 0,
            vehicle: vehicle.clone(),
            track: VehicleTrack::with_height_fusion(512, vehicle.height_fusion_s),
            heading: MeanHeading::default(),
            uncompensated: 0,
            repeated_markers: None,
            frozen: 0,
            estimated: 0,
        }
    }

    /// Whether it needs the autopilot's attitude stream ([`Self::observe_vehicle`]).
    pub fn wants_vehicle(&self) -> bool {
        self.vehicle.attitude == VehicleAttitudeSource::Autopilot
    }

    /// The attitude of one frame's markers. The stamp is the markers' (the caller adds its own
    /// times and drop counts).
    pub fn estimate(&mut self, m: &MarkerMessage) -> AttitudeMessage {
        let mut out = AttitudeMessage {
            stamp: m.stamp,
            context: m.context,
            estimator: self.primary.into(),
            rpy_std_deg: [f64::NAN; 3],
            camera_position_m: [f64::NAN; 3],
            camera_position_covariance_m2: [[f64::NAN; 3]; 3],
            residual: f64::NAN,
            ..Default::default()
        };
        let vehicle = self.vehicle_for(m);
        let r_v = vehicle.matrix();
        let camera = self.vehicle.camera_attitude(&r_v);
        self.uncompensated += (vehicle.compensation == Compensation::Missing) as u64;
        // With the autopilot's north-referenced attitude, W's x is the ship's mean heading.
        let mut to_w = RotationMatrix::identity();
        let motion = self.frame_motion(m, &vehicle);
        let primary = self.run(self.primary, m, &camera, motion.as_ref());
        if let Ok(e) = &primary.result {
            if self.vehicle.attitude == VehicleAttitudeSource::Autopilot && vehicle.known() {
                let t_s = m.context.source_timestamp_ns as f64 / 1e9;
                let deck_heading = e.attitude.rpy.yaw;
                if let Some(h) = self
                    .heading
                    .update(t_s, deck_heading, self.vehicle.heading_time_constant_s)
                {
                    to_w = rot_z(-h);
                }
            }
        }
        out.vehicle = VehicleAttitude {
            rpy: Rpy::from_matrix(&(to_w * r_v)),
            ..vehicle
        };
        if primary.kind == EstimatorKind::FullPose {
            match &primary.result {
                Ok(e) => self.deck_motion.push(
                    m.context.source_timestamp_ns as f64 / 1e9,
                    &e.attitude.matrix,
                    nalgebra::Vector3::from(e.camera_position_m),
                ),
                Err(_) => self.deck_motion.clear(),
            }
        }
        match primary.result {
            Ok(mut e) => {
                out.camera_rpy = Rpy::from_matrix(&(camera.transpose() * e.attitude.matrix));
                e.attitude = Attitude::from_matrix(to_w * e.attitude.matrix);
                let [x, y, z] = e.camera_position_m;
                let c = to_w * nalgebra::Vector3::new(x, y, z);
                e.camera_position_m = [c.x, c.y, c.z];
                out.deck_height_m = deck_height_m(&vehicle, &e);
                e.write(&mut out)
            }
            Err(f) => out.failure = f.into(),
        }
        // The same markers again and again: a frozen image, not a still deck.
        let bits = marker_bits(m);
        let repeats = match self.repeated_markers {
            Some((b, n)) if b == bits && m.markers.markers.iter().any(|k| k.valid.get()) => {
                n.saturating_add(1)
            }
            _ => 0,
        };
        self.repeated_markers = Some((bits, repeats));
        if repeats >= FROZEN_IMAGE_REPEATS {
            out.failure = AttitudeFailure::FrozenImage.into();
            self.frozen += 1;
        }
        out.valid = (out.failure == AttitudeFailure::None).into();
        if let Some(kind) = self.secondary {
            let mut second = self.run(kind, m, &camera, motion.as_ref());
            if let Ok(e) = &mut second.result {
                e.attitude = Attitude::from_matrix(to_w * e.attitude.matrix);
                // The paper's method has no position: the full pose beside it gives the heave.
                if out.valid.get() && !out.deck_height_m.is_finite() {
                    out.deck_height_m = deck_height_m(&vehicle, e);
                }
            }
            // The paper's ring ellipse is worth drawing whichever estimator leads.
            if let Ok(Estimate {
                image_ellipse: Some(el),
                ..
            }) = &second.result
            {
                out.has_image_ellipse = true.into();
                out.image_ellipse = *el;
            }
            out.alternative = AlternativeAttitude {
                present: true.into(),
                estimator: second.kind.into(),
                valid: second.result.is_ok().into(),
                rpy: second.result.map(|e| e.attitude.rpy).unwrap_or_default(),
            };
        }
        self.estimated += out.valid.get() as u64;
        out
    }

    /// A vehicle attitude sample from the autopilot (kept for the frames to come).
    pub fn observe_vehicle(&mut self, sample: &VehicleSample) {
        if sample.link_up.get() {
            self.track.push(VehicleStateSample {
                time_ns: sample.time_ns,
                quaternion: sample.quaternion,
                height_m: Some(sample.height_m).filter(|h| h.is_finite()),
                vertical_speed_mps: Some(sample.vertical_speed_mps).filter(|v| v.is_finite()),
            });
        }
    }

    /// The vehicle attitude at the frame's mid-exposure, as `[vehicle] attitude` says.
    fn vehicle_for(&self, m: &MarkerMessage) -> VehicleAttitude {
        match self.vehicle.attitude {
            VehicleAttitudeSource::Level => VehicleAttitude::LEVEL,
            // What the source says (a recording without a vehicle: level).
            VehicleAttitudeSource::Frames => m.context.vehicle,
            // Mid-exposure: capture stamps it (the simulator renders an instant).
            VehicleAttitudeSource::Autopilot => self
                .track
                .vehicle_attitude_at(m.stamp.times.captured_ns, self.vehicle.max_gap_ns()),
        }
    }

    /// How the camera moved against the deck during a rolling shutter's readout: the vehicle's
    /// rate from its attitude, the deck's from its recent poses; None for a global shutter or
    /// with `rolling_shutter` off. What is unknown is taken as still (and counted).
    fn frame_motion(&mut self, m: &MarkerMessage, vehicle: &VehicleAttitude) -> Option<FrameMotion> {
        if !(self.rolling_shutter && m.context.camera.readout_s > 0.0) {
            return None;
        }
        let t_s = m.context.source_timestamp_ns as f64 / 1e9;
        let deck = self.deck_motion.rates_at(t_s);
        let vehicle_rate = vehicle.rate_rad_s();
        self.motion_unknown += (deck.is_none() || vehicle_rate.is_none()) as u64;
        let still = FrameMotion::STILL;
        Some(FrameMotion {
            vehicle_rate_rad_s: vehicle_rate.unwrap_or(still.vehicle_rate_rad_s),
            // Without it, a constant rate over the readout.
            vehicle_acceleration_rad_s2: vehicle
                .acceleration_rad_s2()
                .unwrap_or(still.vehicle_acceleration_rad_s2),
            deck_rate_rad_s: deck.map_or(still.deck_rate_rad_s, |d| d.deck_rate_rad_s),
            camera_velocity_mps: deck.map_or(still.camera_velocity_mps, |d| d.camera_velocity_mps),
        })
    }

    fn run(
        &mut self,
        kind: EstimatorKind,
        m: &MarkerMessage,
        camera_attitude: &RotationMatrix,
        motion: Option<&FrameMotion>,
    ) -> Outcome {
        let fail = |failure| Outcome {
            kind,
            result: Err(failure),
        };
        match m.markers.status.get() {
            DetectionStatus::NoDeck => return fail(AttitudeFailure::NoDeck),
            DetectionStatus::BadFrame => return fail(AttitudeFailure::BadFrame),
            DetectionStatus::Ok | DetectionStatus::Partial => {}
        }
        let (camera, deck) = (m.context.camera, m.context.deck);
        if camera.validate().is_err() || deck.validate().is_err() {
            return fail(AttitudeFailure::BadFrame);
        }
        let stale = self
            .estimators
            .as_ref()
            .is_none_or(|e| e.paper.camera() != &camera || e.paper.deck() != &deck);
        if stale {
            self.estimators = Some(Estimators {
                paper: PaperEstimator::new(camera, deck, PaperVariant::Atan2),
                pose: PoseEstimator::new(camera, deck, PoseConfig::default()),
            });
        }
        let est = self.estimators.as_ref().expect("set above");
        let pixels = m.markers.pixels(deck.marker_count());
        // Both estimators take the camera's attitude out (`R_V R_M`; identity: level).
        let vehicle = *camera_attitude;
        let level = vehicle == RotationMatrix::identity();
        match paper_variant(kind) {
            Some(variant) => {
                let paper = PaperEstimator::new(camera, deck, variant);
                let paper = if variant == PaperVariant::Atan2 {
                    &est.paper
                } else {
                    &paper
                };
                let altitude = m.context.altitude_m.is_finite().then_some(m.context.altitude_m);
                match paper.estimate_with_vehicle(&pixels, altitude, &vehicle) {
                    Ok(e) => Outcome {
                        kind,
                        result: Ok(Estimate {
                            attitude: e.attitude,
                            // Tilted, the ellipse is in a virtual level camera's pixels: not
                            // drawn on the image.
                            image_ellipse: e.image_ellipse.filter(|_| level),
                            residual: e.fit_rms_m,
                            markers_used: (e.ring_markers_used + 2) as u32,
                            rpy_std_deg: [f64::NAN; 3],
                            camera_position_m: [f64::NAN; 3],
                            camera_position_covariance_m2: [[f64::NAN; 3]; 3],
                        }),
                    },
                    Err(e) => fail(paper_failure(&e)),
                }
            }
            None => {
                // Tracked markers keep the identities of frames that had the bow.
                let centre_stds = m.markers.centre_stds_px();
                match est.pose.estimate_in_motion(
                    &pixels,
                    centre_stds.as_ref().map(|s| &s[..]),
                    m.markers.perspective_corrected.get(),
                    &vehicle,
                    motion,
                    !m.markers.tracked.get(),
                ) {
                    Ok(e) => Outcome {
                        kind,
                        result: Ok(Estimate {
                            attitude: e.attitude,
                            image_ellipse: None,
                            residual: e.reprojection_rms_px,
                            markers_used: e.markers_used(),
                            rpy_std_deg: e.rpy_std_deg(),
                            camera_position_covariance_m2: e.camera_position_covariance_m2,
                            camera_position_m: [
                                e.viewpoint.offset_x_m,
                                e.viewpoint.offset_y_m,
                                e.viewpoint.altitude_m,
                            ],
                        }),
                    },
                    Err(e) => fail(pose_failure(&e)),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::markers::{Marker, MarkerSet};
    use deckwatch_common::rotation::rpy_error_deg;
    use deckwatch_common::{CameraModel, DeckLayout, Rpy, SceneGeometry, Viewpoint};

    /// The marker message of a scene's exact projections.
    fn exact_markers(scene: &SceneGeometry, camera: CameraModel, deck: DeckLayout) -> MarkerMessage {
        let mut m = MarkerMessage::default();
        m.context.camera = camera;
        m.context.deck = deck;
        m.markers = MarkerSet {
            status: DetectionStatus::Ok.into(),
            perspective_corrected: true.into(),
            ..Default::default()
        };
        for (i, p) in scene.project_markers(&camera, &deck).iter().enumerate() {
            let [u, v] = p.unwrap();
            m.markers.markers[i] = Marker {
                valid: true.into(),
                u,
                v,
                ..Default::default()
            };
        }
        m
    }

    #[test]
    fn both_estimators_on_exact_markers_and_no_deck_gives_none() {
        let camera = CameraModel::preset("rpi-v2").unwrap();
        let deck = DeckLayout::paper();
        let truth = Rpy::from_degrees(3.0, -2.0, 10.0);
        let scene = SceneGeometry {
            attitude: truth.to_matrix(),
            viewpoint: Viewpoint::level(0.1, 0.0, 5.0),
        };
        let mut m = exact_markers(&scene, camera, deck);
        m.context.altitude_m = 5.0;
        let mut s = DeckEstimator::new(&EstimateConfig::default(), &VehicleConfig::default());
        let a = s.estimate(&m);
        assert!(a.valid.get() && a.estimator == EstimatorKind::FullPose);
        assert!(rpy_error_deg(&a.rpy, &truth).iter().all(|e| *e < 1e-8));
        assert!((a.camera_position_m[2] - 5.0).abs() < 1e-9 && (a.camera_position_m[0] - 0.1).abs() < 1e-9);
        assert!(a.alternative.present.get() && a.alternative.valid.get());
        assert_eq!(a.alternative.estimator, EstimatorKind::PaperAtan2);
        m.markers.status = DetectionStatus::NoDeck.into();
        // A fresh estimator: to the same one, the same markers again are a frozen image.
        let mut s = DeckEstimator::new(&EstimateConfig::default(), &VehicleConfig::default());
        let a = s.estimate(&m);
        assert!(!a.valid.get() && a.failure == AttitudeFailure::NoDeck);
        assert!(a.alternative.present.get() && !a.alternative.valid.get());
    }

    /// The same markers a second time in a row are a frozen image, whatever the vehicle does; a
    /// marker moving by the last bit of a pixel is not.
    #[test]
    fn a_frozen_image_is_refused() {
        let camera = CameraModel::preset("rpi-v2").unwrap();
        let scene = SceneGeometry {
            attitude: Rpy::from_degrees(1.0, -1.0, 0.0).to_matrix(),
            viewpoint: Viewpoint::level(0.0, 0.0, 3.0),
        };
        let mut m = exact_markers(&scene, camera, DeckLayout::paper());
        let mut s = DeckEstimator::new(&EstimateConfig::default(), &VehicleConfig::default());
        let failures: Vec<_> = (0..4).map(|_| s.estimate(&m).failure.get()).collect();
        use AttitudeFailure::{FrozenImage, None as Fine};
        assert_eq!(failures, [Fine, FrozenImage, FrozenImage, FrozenImage]);
        m.markers.markers[3].u = f64::from_bits(m.markers.markers[3].u.to_bits() + 1);
        let a = s.estimate(&m);
        assert!(a.valid.get(), "{:?}", a.failure);
        assert_eq!(s.frozen, 3);
    }

    /// With the autopilot's stream: samples around the capture instant are interpolated and the
    /// tilt taken out; without one close enough the attitude is marked not compensated.
    #[test]
    fn autopilot_samples_are_interpolated_to_the_frame() {
        use deckwatch_common::messages::VehicleSample;
        use deckwatch_common::vehicle::{Compensation, VehicleAttitudeSource, VehicleConfig};
        use deckwatch_common::Quaternion;
        let camera = CameraModel::preset("rpi-v2").unwrap();
        let deck = DeckLayout::paper();
        let truth = Rpy::from_degrees(3.0, -2.0, 0.0);
        // The vehicle rolls at 20 deg/s: 4 deg at the capture instant, between two samples.
        let vehicle_at = |t_ms: f64| Rpy::from_degrees(0.02 * t_ms, -3.0, 0.0);
        let scene = SceneGeometry {
            attitude: truth.to_matrix(),
            viewpoint: Viewpoint::level(0.0, 0.0, 5.0).with_vehicle_attitude(vehicle_at(200.0).to_matrix()),
        };
        let mut m = exact_markers(&scene, camera, deck);
        m.stamp.times.captured_ns = 1_200_000_000;
        let vehicle = VehicleConfig {
            attitude: VehicleAttitudeSource::Autopilot,
            ..VehicleConfig::default()
        };
        let mut s = DeckEstimator::new(&EstimateConfig::default(), &vehicle);
        assert!(s.wants_vehicle());
        let a = s.estimate(&m);
        assert_eq!(a.vehicle.compensation, Compensation::Missing);
        for t_ms in [190.0, 210.0] {
            s.observe_vehicle(&VehicleSample {
                time_ns: 1_000_000_000 + (t_ms * 1e6) as u64,
                quaternion: Quaternion::from_matrix(&vehicle_at(t_ms).to_matrix()),
                link_up: true.into(),
                ..Default::default()
            });
        }
        let a = s.estimate(&m);
        assert_eq!(a.vehicle.compensation, Compensation::Stream);
        assert!((a.vehicle.age_ms - 10.0).abs() < 1e-9);
        let e = rpy_error_deg(&a.rpy, &truth);
        // Slerp of a constant-rate roll is exact.
        assert!(e.iter().all(|v| *v < 1e-6), "{e:?}");
        let [vr, _, _] = a.vehicle.rpy.to_degrees();
        assert!((vr - 4.0).abs() < 1e-9);
        // A sample from a link that is down is not used.
        let mut t = DeckEstimator::new(&EstimateConfig::default(), &vehicle);
        t.observe_vehicle(&VehicleSample {
            time_ns: 1_200_000_000,
            link_up: false.into(),
            ..Default::default()
        });
        assert_eq!(t.estimate(&m).vehicle.compensation, Compensation::Missing);
    }
}
