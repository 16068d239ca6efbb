//! Beyond the paper: the full planar pose from every visible marker and the known deck layout.
//!
//! The paper needs an altimeter and a camera centred over the deck, and takes yaw from one
//! marker. Here the marker centres (undistorted, normalised image coordinates) and their deck
//! positions give a homography (normalised DLT), which is decomposed into an initial pose; then
//! Levenberg-Marquardt minimises the reprojection error in pixels over the rotation vector and
//! the translation. A marker that reprojects worse than `max_reprojection_px` is dropped and the
//! pose re-solved (at least 4 markers, the bow among them, must remain). Each marker's residual
//! is weighed by the inverse of its centre's measured deviation where the detector gives one
//! (`Marker::centre_std_px`): a small or dim disc counts less. Centroids still biased
//! by perspective (CONVENTIONS.md C6) are corrected with the pose and the pose solved again. The
//! angles' covariance comes from the Jacobian at the optimum, scaled by the residual.
//!
//! Conventions as everywhere (`common::scene`): `p_cam = R_CW (R P_deck - C)`, so the deck
//! attitude is `R = R_CW^T R_cam_deck` and the camera position `C = -R_CW^T t` (offset and
//! altitude over the deck centre, no altimeter needed). The attitude is relative to the camera's
//! level frame: a tilted camera must be compensated with the vehicle's own attitude.

use deckwatch_common::deck::BOW;
use deckwatch_common::homography;
use deckwatch_common::scene::camera_from_world;
use deckwatch_common::{Attitude, CameraModel, DeckLayout, RotationMatrix, Rpy, Viewpoint};
use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, Vector3};

/// Settings of the full-pose estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseConfig {
    /// A marker reprojecting further than this (pixels) is an outlier.
    pub max_reprojection_px: f64,
    /// Remove the perspective bias of the centres with the pose (for centroids that were not
    /// corrected upstream).
    pub correct_perspective: bool,
    pub max_iterations: usize,
}

impl Default for PoseConfig {
    fn default() -> Self {
        Self {
            max_reprojection_px: 3.0,
            correct_perspective: true,
            max_iterations: 20,
        }
    }
}

/// Why no pose: never a guess.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoseError {
    /// Fewer than 4 usable markers (after dropping outliers).
    TooFewMarkers { usable: usize },
    /// The bow marker is needed to fix the yaw (and to trust the identification).
    BowMissing,
    /// The bow marker itself reprojects as an outlier.
    BowOutlier,
    /// The marker list does not have one entry per marker of the deck layout.
    WrongMarkerCount { expected: usize, got: usize },
    /// A marker's pixel lies where the lens model does not invert.
    Undistortion { index: usize },
    /// The markers determine no pose (collinear, deck behind the camera, no convergence).
    Degenerate(&'static str),
}

impl std::fmt::Display for PoseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewMarkers { usable } => write!(f, "{usable} usable markers, at least 4 are needed"),
            Self::BowMissing => write!(f, "the bow marker is not visible"),
            Self::BowOutlier => write!(f, "the bow marker does not fit the other markers"),
            Self::WrongMarkerCount { expected, got } => {
                write!(f, "{got} marker entries, the deck has {expected} markers")
            }
            Self::Undistortion { index } => {
                write!(f, "marker {index} lies outside the lens model's valid field")
            }
            Self::Degenerate(why) => write!(f, "degenerate marker geometry: {why}"),
        }
    }
}

impl std::error::Error for PoseError {}

/// The full pose of the deck relative to the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseEstimate {
    pub attitude: Attitude,
    /// The camera's position over the deck centre (world frame): offset and altitude.
    pub viewpoint: Viewpoint,
    /// RMS reprojection error of the markers used (pixels).
    pub reprojection_rms_px: f64,
    /// Markers used (bit i = marker i).
    pub used_mask: u32,
    /// Markers dropped as outliers (bit i = marker i).
    pub outlier_mask: u32,
    /// Covariance of roll, pitch, yaw (deg^2), from the weighted Jacobian scaled by the weighted
    /// residual (so the weights' scale does not matter, only their ratios), and
    /// widened for the residual's few degrees of freedom ([`t_widening`]): two deviations hold
    /// 95 % of the errors when the pixel noise is normal, whatever the number of markers.
    pub rpy_covariance_deg2: [[f64; 3]; 3],
    /// Covariance of the camera's position over the deck centre in the world frame (m^2), from
    /// the same Jacobian, scale and widening: what a target estimator (PX4's `TARGET_RELATIVE`
    /// `pos_std`) weighs the position with.
    pub camera_position_covariance_m2: [[f64; 3]; 3],
}

impl PoseEstimate {
    pub fn markers_used(&self) -> u32 {
        self.used_mask.count_ones()
    }

    /// Standard deviations of roll, pitch, yaw (deg).
    pub fn rpy_std_deg(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| self.rpy_covariance_deg2[i][i].max(0.0).sqrt())
    }
}

/// The factor on a variance estimated from `dof` degrees of freedom that makes 1.96 of its
/// deviations the 95 % bound of the error: the error over the estimated deviation is
/// Student-t, not normal (with 9 markers, 12 degrees of freedom: 2.18, not 1.96; with 4
/// markers, 2: 4.30). `(t_0.975(dof) / 1.96)^2`; a table to 10, a Cornish-Fisher expansion
/// beyond (within 0.002 of the table's values at 11-30).
pub fn t_widening(dof: f64) -> f64 {
    const Z: f64 = 1.959_963_984_540_054;
    const T975: [f64; 10] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
    ];
    let t = if dof < 1.0 {
        return f64::INFINITY;
    } else if dof <= 10.0 {
        T975[dof.round() as usize - 1]
    } else {
        let (z3, z5) = (Z.powi(3), Z.powi(5));
        Z + (z3 + Z) / (4.0 * dof) + (5.0 * z5 + 16.0 * z3 + 3.0 * Z) / (96.0 * dof * dof)
    };
    (t / Z).powi(2)
}

/// The full-pose estimator for one camera and deck layout.
#[derive(Debug, Clone)]
pub struct PoseEstimator {
    camera: CameraModel,
    deck: DeckLayout,
    config: PoseConfig,
}

type Pose = (Rotation3<f64>, Vector3<f64>);

struct Observation {
    index: usize,
    deck: Vector3<f64>,
    /// Measured, undistorted, normalised image coordinates.
    xy: [f64; 2],
    /// The residual's weight: the inverse of the centre's deviation (1 for all when unknown).
    weight: f64,
    /// The camera's motion between the frame's instant and this marker's row's
    /// ([`FrameMotion`]): `p_cam = turn_deck R P + turn_camera t + shift` for the frame's pose
    /// `(R, t)`; identity, identity, zero for a global shutter.
    turn_deck: Matrix3<f64>,
    turn_camera: Matrix3<f64>,
    shift: Vector3<f64>,
}

impl Observation {
    /// The marker in camera coordinates at its row's instant, for the frame's pose.
    fn camera_point(&self, (r, t): &Pose) -> Vector3<f64> {
        self.turn_deck * (r * self.deck) + self.turn_camera * t + self.shift
    }

    /// Deck plane (x, y) -> normalised image coordinates at this marker's row's instant.
    fn plane_homography(&self, (r, t): &Pose) -> Matrix3<f64> {
        let m = self.turn_deck * r.matrix();
        Matrix3::from_columns(&[
            m.column(0).into_owned(),
            m.column(1).into_owned(),
            self.turn_camera * t + self.shift,
        ])
    }
}

/// How the camera moved relative to the deck while a rolling shutter read the frame's rows
/// out (`CameraModel::readout_s`): every marker is seen at its own row's instant
/// (`CameraModel::row_time_s`), and the pose is solved for the frame's instant. Rates are
/// taken as constant over the readout (tens of milliseconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMotion {
    /// The vehicle's (and so the camera's) angular velocity in W (rad/s)...
    pub vehicle_rate_rad_s: Vector3<f64>,
    /// ...and its change (rad/s^2): a hovering quadrotor's rate turns around within a readout.
    pub vehicle_acceleration_rad_s2: Vector3<f64>,
    /// The deck's angular velocity in W (rad/s).
    pub deck_rate_rad_s: Vector3<f64>,
    /// The camera's velocity relative to the deck centre in W (m/s).
    pub camera_velocity_mps: Vector3<f64>,
}

impl FrameMotion {
    pub const STILL: Self = Self {
        vehicle_rate_rad_s: Vector3::new(0.0, 0.0, 0.0),
        vehicle_acceleration_rad_s2: Vector3::new(0.0, 0.0, 0.0),
        deck_rate_rad_s: Vector3::new(0.0, 0.0, 0.0),
        camera_velocity_mps: Vector3::new(0.0, 0.0, 0.0),
    };

    pub fn is_finite(&self) -> bool {
        [
            self.vehicle_rate_rad_s,
            self.vehicle_acceleration_rad_s2,
            self.deck_rate_rad_s,
            self.camera_velocity_mps,
        ]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()))
    }
}

impl PoseEstimator {
    pub fn new(camera: CameraModel, deck: DeckLayout, config: PoseConfig) -> Self {
        Self { camera, deck, config }
    }

    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }
    pub fn deck(&self) -> &DeckLayout {
        &self.deck
    }

    /// The pose from marker pixels by marker index (None = not seen), for a level camera.
    /// `centres_corrected`: the pixels are already free of the perspective bias (the
    /// detector's default).
    pub fn estimate(
        &self,
        markers: &[Option<[f64; 2]>],
        centres_corrected: bool,
    ) -> Result<PoseEstimate, PoseError> {
        self.estimate_with_vehicle(markers, centres_corrected, &RotationMatrix::identity())
    }

    /// The same for a camera carried by a vehicle at attitude `vehicle` (`R_V`, body to world,
    /// CONVENTIONS.md §5): the pose is solved in the camera (the deck relative to the camera is
    /// the same whatever the vehicle does) and composed with `R_V R_CW0^T`, so the deck's
    /// attitude and the camera's position come out in the world frame.
    pub fn estimate_with_vehicle(
        &self,
        markers: &[Option<[f64; 2]>],
        centres_corrected: bool,
        vehicle: &RotationMatrix,
    ) -> Result<PoseEstimate, PoseError> {
        self.estimate_in_motion(markers, None, centres_corrected, vehicle, None, true)
    }

    /// The same for a rolling shutter: with `motion`, each marker is taken at its row's instant
    /// and the pose is the frame's (the middle row's); without it (or with a global shutter,
    /// `readout_s` 0) every marker is taken at the frame's instant. `bow_required`: the bow
    /// must be among the markers (it is what identifies them); false only for markers whose
    /// identities were carried over from frames that had it (tracking, low over the deck when
    /// the bow has left the view). `centre_std_px`: each marker's centre deviation (pixels, by
    /// marker index, as [`MarkerSet::centre_stds_px`] gives them), to weigh the markers by;
    /// None, or any found marker's not finite and positive: every marker alike.
    ///
    /// [`MarkerSet::centre_stds_px`]: deckwatch_common::markers::MarkerSet::centre_stds_px
    pub fn estimate_in_motion(
        &self,
        markers: &[Option<[f64; 2]>],
        centre_std_px: Option<&[f64]>,
        centres_corrected: bool,
        vehicle: &RotationMatrix,
        motion: Option<&FrameMotion>,
        bow_required: bool,
    ) -> Result<PoseEstimate, PoseError> {
        let n = self.deck.marker_count();
        // Camera from world at the frame's instant: (R_V R_CW0^T)^T.
        let r_cw = (vehicle * camera_from_world().transpose()).transpose();
        let motion = motion.filter(|m| self.camera.readout_s > 0.0 && m.is_finite());
        if markers.len() != n {
            return Err(PoseError::WrongMarkerCount {
                expected: n,
                got: markers.len(),
            });
        }
        if bow_required && markers[BOW].is_none() {
            return Err(PoseError::BowMissing);
        }
        let measured = |i: usize| {
            centre_std_px
                .and_then(|s| s.get(i))
                .filter(|s| s.is_finite() && **s > 0.0)
                .copied()
        };
        let weighed = (0..n).all(|i| markers[i].is_none() || measured(i).is_some());
        let weight = |i: usize| match (weighed, measured(i)) {
            (true, Some(std)) => 1.0 / std,
            _ => 1.0,
        };
        let mut obs = Vec::with_capacity(n);
        for (index, m) in markers.iter().enumerate() {
            let Some(uv) = m else { continue };
            if !(uv[0].is_finite() && uv[1].is_finite()) {
                continue;
            }
            let xy = self
                .camera
                .unproject(*uv)
                .ok_or(PoseError::Undistortion { index })?;
            let (turn_deck, turn_camera, shift) = match motion {
                Some(m) => {
                    // p(tau) = B (R_CW exp(tau [w_d]x) R P + t0 - tau R_CW v): the camera turned
                    // by B = exp(-[R_CW (w_v tau + a_v tau^2 / 2)]x), the deck by its own rate,
                    // the camera moved.
                    let tau = self.camera.row_time_s(uv[1]);
                    let vehicle_turn =
                        m.vehicle_rate_rad_s * tau + m.vehicle_acceleration_rad_s2 * (0.5 * tau * tau);
                    let turn_camera = *Rotation3::from_scaled_axis(-(r_cw * vehicle_turn)).matrix();
                    let deck_turn = *Rotation3::from_scaled_axis(tau * (r_cw * m.deck_rate_rad_s)).matrix();
                    (
                        turn_camera * deck_turn,
                        turn_camera,
                        -tau * (turn_camera * (r_cw * m.camera_velocity_mps)),
                    )
                }
                None => (Matrix3::identity(), Matrix3::identity(), Vector3::zeros()),
            };
            obs.push(Observation {
                index,
                deck: self.deck.marker_position(index),
                xy,
                weight: weight(index),
                turn_deck,
                turn_camera,
                shift,
            });
        }
        let mut outliers = 0u32;
        let mut pose = loop {
            if obs.len() < 4 {
                return Err(PoseError::TooFewMarkers { usable: obs.len() });
            }
            let initial = self.initial_pose(&obs)?;
            let pose = self.refine(&obs, initial);
            let (worst, err) = self.worst(&obs, &pose);
            if err <= self.config.max_reprojection_px {
                break pose;
            }
            if obs[worst].index == BOW {
                return Err(PoseError::BowOutlier);
            }
            outliers |= 1 << obs[worst].index;
            obs.remove(worst);
        };
        if self.config.correct_perspective && !centres_corrected {
            let measured: Vec<[f64; 2]> = obs.iter().map(|o| o.xy).collect();
            for _ in 0..2 {
                for (o, m) in obs.iter_mut().zip(&measured) {
                    let h = o.plane_homography(&pose);
                    let c = [o.deck.x, o.deck.y];
                    if let Some((centre, image)) =
                        homography::imaged_circle_centre(&h, c, self.deck.disc_radius(o.index))
                    {
                        o.xy = [m[0] - (centre[0] - image[0]), m[1] - (centre[1] - image[1])];
                    }
                }
                pose = self.refine(&obs, pose);
            }
        }
        Ok(self.result(&obs, &pose, outliers, vehicle))
    }

    fn pixel_residuals(&self, obs: &[Observation], pose: &Pose) -> Option<Vec<f64>> {
        let mut res = Vec::with_capacity(2 * obs.len());
        for o in obs {
            let p = o.camera_point(pose);
            if !(p.z > 0.0) {
                return None;
            }
            res.push(self.camera.fx * (p.x / p.z - o.xy[0]));
            res.push(self.camera.fy * (p.y / p.z - o.xy[1]));
        }
        Some(res)
    }

    /// The residuals over each marker's deviation: what the fit minimises.
    fn weighted_residuals(&self, obs: &[Observation], pose: &Pose) -> Option<Vec<f64>> {
        let mut res = self.pixel_residuals(obs, pose)?;
        for (pair, o) in res.chunks_exact_mut(2).zip(obs) {
            pair[0] *= o.weight;
            pair[1] *= o.weight;
        }
        Some(res)
    }

    fn worst(&self, obs: &[Observation], pose: &Pose) -> (usize, f64) {
        let res = self
            .pixel_residuals(obs, pose)
            .unwrap_or_else(|| vec![f64::INFINITY; 2 * obs.len()]);
        (0..obs.len())
            .map(|i| (i, res[2 * i].hypot(res[2 * i + 1])))
            .fold((0, -1.0), |a, b| if b.1 > a.1 { b } else { a })
    }

    /// Pose from the plane homography: `H ~ [r1 r2 t]` in normalised coordinates.
    fn initial_pose(&self, obs: &[Observation]) -> Result<Pose, PoseError> {
        let src: Vec<[f64; 2]> = obs.iter().map(|o| [o.deck.x, o.deck.y]).collect();
        let dst: Vec<[f64; 2]> = obs.iter().map(|o| o.xy).collect();
        let h = homography::fit(&src, &dst).ok_or(PoseError::Degenerate("no homography"))?;
        let (h1, h2, h3) = (h.column(0), h.column(1), h.column(2));
        let scale = 2.0 / (h1.norm() + h2.norm());
        // The deck is in front of the camera: t_z > 0.
        let sign = if h3.z * scale > 0.0 { 1.0 } else { -1.0 };
        let (r1, r2, t) = (h1 * scale * sign, h2 * scale * sign, h3 * scale * sign);
        let m = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
        // Nearest rotation.
        let svd = m.svd(true, true);
        let (u, vt) = (
            svd.u.ok_or(PoseError::Degenerate("svd"))?,
            svd.v_t.ok_or(PoseError::Degenerate("svd"))?,
        );
        let mut r = u * vt;
        if r.determinant() < 0.0 {
            r = -r;
        }
        if !(t.z > 0.0) {
            return Err(PoseError::Degenerate("deck behind the camera"));
        }
        Ok((Rotation3::from_matrix_unchecked(r), t))
    }

    fn refine(&self, obs: &[Observation], start: Pose) -> Pose {
        let apply = |(r, t): &Pose, d: &SVector<f64, 6>| -> Pose {
            let dr = Rotation3::from_scaled_axis(Vector3::new(d[0], d[1], d[2]));
            (r * dr, t + Vector3::new(d[3], d[4], d[5]))
        };
        let cost = |p: &Pose| {
            self.weighted_residuals(obs, p)
                .map(|r| r.iter().map(|v| v * v).sum::<f64>())
        };
        let mut pose = start;
        let Some(mut c) = cost(&pose) else { return pose };
        let mut lambda = 1e-3;
        for _ in 0..self.config.max_iterations {
            let Some(jac) = self.jacobian(obs, &pose) else {
                break;
            };
            let res = self.weighted_residuals(obs, &pose).expect("cost was finite");
            let (mut jtj, mut jtr) = (SMatrix::<f64, 6, 6>::zeros(), SVector::<f64, 6>::zeros());
            for (row, r) in jac.iter().zip(&res) {
                jtj += row * row.transpose();
                jtr += row * *r;
            }
            let mut improved = false;
            while lambda < 1e8 {
                let mut a = jtj;
                for d in 0..6 {
                    a[(d, d)] += lambda * jtj[(d, d)].max(1e-12);
                }
                let Some(step) = a.cholesky().map(|ch| ch.solve(&(-jtr))) else {
                    break;
                };
                let trial = apply(&pose, &step);
                match cost(&trial) {
                    Some(c2) if c2 < c => {
                        let done = c - c2 < 1e-14 * c.max(1e-300) || step.norm() < 1e-13;
                        (pose, c) = (trial, c2);
                        lambda = (lambda * 0.2).max(1e-12);
                        improved = !done;
                        break;
                    }
                    _ => lambda *= 10.0,
                }
            }
            if !improved {
                break;
            }
        }
        pose
    }

    /// Jacobian rows (one per residual) of the weighted pixel residuals with respect to a right
    /// perturbation of the rotation and a shift of the translation (analytic).
    fn jacobian(&self, obs: &[Observation], (r, t): &Pose) -> Option<Vec<SVector<f64, 6>>> {
        let mut rows = Vec::with_capacity(2 * obs.len());
        for o in obs {
            let p = o.camera_point(&(*r, *t));
            if !(p.z > 0.0) {
                return None;
            }
            let iz = 1.0 / p.z;
            // d(x/z)/dp and d(y/z)/dp.
            let dx = Vector3::new(iz, 0.0, -p.x * iz * iz);
            let dy = Vector3::new(0.0, iz, -p.y * iz * iz);
            // dp/d(delta) for R exp([delta]x): -A R [P]x; dp/dt: B (A, B: the row's turns).
            let dp_dd = -(o.turn_deck * r.matrix() * o.deck.cross_matrix());
            let (wx, wy) = (o.weight * self.camera.fx, o.weight * self.camera.fy);
            let rx = dp_dd.transpose() * dx * wx;
            let ry = dp_dd.transpose() * dy * wy;
            let tx = o.turn_camera.transpose() * dx * wx;
            let ty = o.turn_camera.transpose() * dy * wy;
            rows.push(SVector::<f64, 6>::from_column_slice(&[
                rx.x, rx.y, rx.z, tx.x, tx.y, tx.z,
            ]));
            rows.push(SVector::<f64, 6>::from_column_slice(&[
                ry.x, ry.y, ry.z, ty.x, ty.y, ty.z,
            ]));
        }
        Some(rows)
    }

    fn result(
        &self,
        obs: &[Observation],
        pose: &Pose,
        outlier_mask: u32,
        vehicle: &RotationMatrix,
    ) -> PoseEstimate {
        // Camera to world: R_V R_CW0^T.
        let c = (vehicle * camera_from_world().transpose()).transpose();
        let r_deck = c.transpose() * pose.0.matrix();
        let position = -(c.transpose() * pose.1);
        let res = self.pixel_residuals(obs, pose).unwrap_or_default();
        let rms = (res.iter().map(|v| v * v).sum::<f64>() / obs.len().max(1) as f64).sqrt();
        let ssr: f64 = self
            .weighted_residuals(obs, pose)
            .unwrap_or_default()
            .iter()
            .map(|v| v * v)
            .sum();
        // Covariance of the perturbation: s^2 (J^T W J)^-1 with s^2 = SSR_W / (2N - 6).
        let dof = (2 * obs.len()).saturating_sub(6).max(1) as f64;
        let mut cov_rpy = [[f64::NAN; 3]; 3];
        let mut cov_position = [[f64::NAN; 3]; 3];
        if let Some(jac) = self.jacobian(obs, pose) {
            let jtj = jac
                .iter()
                .fold(SMatrix::<f64, 6, 6>::zeros(), |a, row| a + row * row.transpose());
            if let Some(inv) = jtj.try_inverse() {
                let scale = ssr / dof * t_widening(dof);
                let cov_d = inv.fixed_view::<3, 3>(0, 0) * scale;
                // The position is -(C^T t): its covariance is C^T cov(t) C.
                let cov_t = inv.fixed_view::<3, 3>(3, 3) * scale;
                let cp = c.transpose() * cov_t * c;
                cov_position = [0, 1, 2].map(|i| [0, 1, 2].map(|j| cp[(i, j)]));
                // d(rpy)/d(delta), numerically: rpy of C^T R exp([delta]x).
                let rpy0 = Rpy::from_matrix(&r_deck).to_degrees();
                let h = 1e-6;
                let mut a = Matrix3::zeros();
                for k in 0..3 {
                    let mut d = Vector3::zeros();
                    d[k] = h;
                    let rk = c.transpose() * (pose.0 * Rotation3::from_scaled_axis(d)).matrix();
                    let rpy = Rpy::from_matrix(&rk).to_degrees();
                    for i in 0..3 {
                        let mut diff = rpy[i] - rpy0[i];
                        diff -= 360.0 * (diff / 360.0).round(); // yaw wraps
                        a[(i, k)] = diff / h;
                    }
                }
                let cr = a * cov_d * a.transpose();
                cov_rpy = [0, 1, 2].map(|i| [0, 1, 2].map(|j| cr[(i, j)]));
            }
        }
        PoseEstimate {
            attitude: Attitude::from_matrix(r_deck),
            viewpoint: Viewpoint::level(position.x, position.y, position.z).with_vehicle_attitude(*vehicle),
            reprojection_rms_px: rms,
            used_mask: obs.iter().fold(0, |m, o| m | 1 << o.index),
            outlier_mask,
            rpy_covariance_deg2: cov_rpy,
            camera_position_covariance_m2: cov_position,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Student-t's 97.5 % points (tables): the widening holds them at every number of degrees
    /// of freedom, and tends to 1.
    #[test]
    fn the_widening_is_student_t() {
        let z = 1.959_963_984_540_054;
        for (dof, t) in [
            (2.0, 4.303),
            (4.0, 2.776),
            (12.0, 2.179),
            (20.0, 2.086),
            (30.0, 2.042),
            (120.0, 1.980),
        ] {
            let got = z * t_widening(dof).sqrt();
            assert!((got - t).abs() < 0.003, "{dof}: {got} against {t}");
        }
        assert!((t_widening(1e9) - 1.0).abs() < 1e-6);
    }
    use deckwatch_common::rotation::rpy_error_deg;
    use deckwatch_common::SceneGeometry;

    fn scene(rpy: Rpy, vp: Viewpoint) -> SceneGeometry {
        SceneGeometry {
            attitude: rpy.to_matrix(),
            viewpoint: vp,
        }
    }

    #[test]
    fn exact_markers_give_the_exact_pose_without_an_altimeter() {
        let cam = CameraModel::preset("rpi-v2").unwrap();
        let deck = DeckLayout::paper();
        let est = PoseEstimator::new(cam, deck, PoseConfig::default());
        for (rpy, vp) in [
            (Rpy::from_degrees(0.0, 0.0, 0.0), Viewpoint::centred(5.0)),
            (Rpy::from_degrees(14.0, -6.0, 170.0), Viewpoint::centred(4.5)),
            (
                Rpy::from_degrees(-20.0, 7.5, -35.0),
                Viewpoint::level(0.3, -0.2, 5.5),
            ),
        ] {
            let px = scene(rpy, vp).project_markers(&cam, &deck);
            let e = est.estimate(&px, true).unwrap();
            let err = rpy_error_deg(&e.attitude.rpy, &rpy);
            assert!(err.iter().all(|v| *v < 1e-8), "{err:?}");
            assert!((e.viewpoint.altitude_m - vp.altitude_m).abs() < 1e-9);
            assert!((e.viewpoint.offset_x_m - vp.offset_x_m).abs() < 1e-9);
            assert!((e.viewpoint.offset_y_m - vp.offset_y_m).abs() < 1e-9);
            assert!(e.reprojection_rms_px < 1e-6);
            assert_eq!(e.markers_used(), 9);
        }
    }

    /// A marker whose centre is stated to be less sure counts less: with one centre off by
    /// 0.4 px and stated 20 times less sure than the others, the pose is nearer the truth
    /// than with equal weights; only the deviations' ratios matter (all ten times larger:
    /// the same pose and covariance); one found marker without a deviation: equal weights.
    #[test]
    fn markers_are_weighed_by_their_centres_deviations() {
        let cam = CameraModel::preset("rpi-v2").unwrap();
        let deck = DeckLayout::paper();
        let est = PoseEstimator::new(cam, deck, PoseConfig::default());
        let truth = Rpy::from_degrees(8.0, -4.0, 30.0);
        let mut px = scene(truth, Viewpoint::level(0.2, -0.1, 5.0)).project_markers(&cam, &deck);
        let p = px[5].unwrap();
        px[5] = Some([p[0] + 0.4, p[1] - 0.3]);
        let level = RotationMatrix::identity();
        let solve = |stds: Option<&[f64]>| {
            est.estimate_in_motion(&px, stds, true, &level, None, true)
                .unwrap()
        };
        let error = |e: &PoseEstimate| {
            let err = rpy_error_deg(&e.attitude.rpy, &truth);
            err[0].hypot(err[1])
        };
        let equal = solve(None);
        let mut stds = vec![0.02; 9];
        stds[5] = 0.4;
        let weighed = solve(Some(&stds));
        assert!(
            error(&weighed) < 0.2 * error(&equal),
            "weighed {} deg, equal {} deg",
            error(&weighed),
            error(&equal)
        );
        let scaled: Vec<f64> = stds.iter().map(|s| 10.0 * s).collect();
        let tenfold = solve(Some(&scaled));
        assert!(rpy_error_deg(&tenfold.attitude.rpy, &weighed.attitude.rpy)
            .iter()
            .all(|d| *d < 1e-9));
        for (a, b) in tenfold
            .rpy_covariance_deg2
            .iter()
            .flatten()
            .zip(weighed.rpy_covariance_deg2.iter().flatten())
        {
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1e-12), "{a} against {b}");
        }
        let mut missing = stds.clone();
        missing[3] = f64::NAN;
        assert_eq!(solve(Some(&missing)).attitude, equal.attitude);
    }

    #[test]
    fn four_markers_with_the_bow_suffice_and_outliers_are_dropped() {
        let cam = CameraModel::preset("rpi-v2").unwrap();
        let deck = DeckLayout::paper();
        let est = PoseEstimator::new(cam, deck, PoseConfig::default());
        let truth = Rpy::from_degrees(5.0, 3.0, 20.0);
        let px = scene(truth, Viewpoint::centred(5.0)).project_markers(&cam, &deck);
        let mut four = vec![None; 9];
        for i in [0, 1, 3, 6] {
            four[i] = px[i];
        }
        let e = est.estimate(&four, true).unwrap();
        assert!(rpy_error_deg(&e.attitude.rpy, &truth).iter().all(|v| *v < 1e-7));
        // A misplaced marker (a glint taken for marker 5) is found and dropped.
        let mut bad = px.clone();
        let p = bad[5].unwrap();
        bad[5] = Some([p[0] + 40.0, p[1] - 25.0]);
        let e = est.estimate(&bad, true).unwrap();
        assert_eq!(e.outlier_mask, 1 << 5);
        assert!(rpy_error_deg(&e.attitude.rpy, &truth).iter().all(|v| *v < 1e-7));
        // Without the bow, or with three markers: not estimable.
        let mut no_bow = px.clone();
        no_bow[1] = None;
        assert_eq!(est.estimate(&no_bow, true).unwrap_err(), PoseError::BowMissing);
        // Identities carried over from frames that had the bow: the rest suffice.
        let tracked = est
            .estimate_in_motion(&no_bow, None, true, &RotationMatrix::identity(), None, false)
            .unwrap();
        assert!(rpy_error_deg(&tracked.attitude.rpy, &truth)
            .iter()
            .all(|v| *v < 1e-7));
        let mut three = vec![None; 9];
        for i in [0, 1, 3] {
            three[i] = px[i];
        }
        assert_eq!(
            est.estimate(&three, true).unwrap_err(),
            PoseError::TooFewMarkers { usable: 3 }
        );
    }

    #[test]
    fn perspective_bias_is_removed_and_noise_gives_a_covariance() {
        let cam = CameraModel::preset("rpi-v2").unwrap();
        let deck = DeckLayout::paper();
        let truth = Rpy::from_degrees(-12.0, 5.0, 60.0);
        let sc = scene(truth, Viewpoint::centred(4.5));
        // Biased centroids: the centres of the imaged discs (undistorted camera here).
        let k = Matrix3::new(cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0);
        let rc = camera_from_world() * sc.attitude;
        let tc = camera_from_world() * (-sc.viewpoint.position());
        let h = k * Matrix3::from_columns(&[rc.column(0).into_owned(), rc.column(1).into_owned(), tc]);
        let biased: Vec<Option<[f64; 2]>> = (0..9)
            .map(|i| {
                let p = deck.marker_position(i);
                homography::imaged_circle_centre(&h, [p.x, p.y], deck.disc_radius(i)).map(|(c, _)| c)
            })
            .collect();
        let est = PoseEstimator::new(cam, deck, PoseConfig::default());
        let raw = est.estimate(&biased, true).unwrap();
        let fixed = est.estimate(&biased, false).unwrap();
        let e_raw = rpy_error_deg(&raw.attitude.rpy, &truth);
        let e_fixed = rpy_error_deg(&fixed.attitude.rpy, &truth);
        assert!(
            e_fixed.iter().all(|v| *v < 1e-6),
            "{e_fixed:?} (uncorrected {e_raw:?})"
        );
        assert!(e_raw.iter().any(|v| *v > 1e-4), "the bias matters: {e_raw:?}");
        // Noisy pixels: a finite, positive spread.
        let noisy: Vec<Option<[f64; 2]>> = sc
            .project_markers(&cam, &deck)
            .iter()
            .enumerate()
            .map(|(i, p)| {
                p.map(|[u, v]| {
                    [
                        u + 0.3 * ((i * 7 % 5) as f64 - 2.0),
                        v - 0.2 * ((i * 3 % 4) as f64 - 1.5),
                    ]
                })
            })
            .collect();
        let e = est.estimate(&noisy, true).unwrap();
        let sd = e.rpy_std_deg();
        assert!(sd.iter().all(|s| s.is_finite() && *s > 0.0 && *s < 1.0), "{sd:?}");
    }

    /// The stated position deviation is the spread of the position over pixel noise: 300 draws
    /// of 0.5 px Gaussian noise, the camera 4.5 m over a rolled deck.
    #[test]
    fn the_position_covariance_matches_the_spread_over_pixel_noise() {
        let cam = CameraModel::preset("rpi-v2").unwrap();
        let deck = DeckLayout::paper();
        let sc = scene(Rpy::from_degrees(6.0, -4.0, 30.0), Viewpoint::centred(4.5));
        let exact = sc.project_markers(&cam, &deck);
        let est = PoseEstimator::new(cam, deck, PoseConfig::default());
        // A fixed-seed generator and Box-Muller: the test is the same on every run.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut gauss = move || (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos();
        let (mut positions, mut stated) = (Vec::new(), [0.0; 3]);
        let draws = 300;
        for _ in 0..draws {
            let noisy: Vec<Option<[f64; 2]>> = exact
                .iter()
                .map(|p| p.map(|[u, v]| [u + 0.5 * gauss(), v + 0.5 * gauss()]))
                .collect();
            let e = est.estimate(&noisy, true).unwrap();
            positions.push(e.viewpoint.position());
            for (k, s) in stated.iter_mut().enumerate() {
                *s += e.camera_position_covariance_m2[k][k] / draws as f64;
            }
        }
        for k in 0..3 {
            let mean = positions.iter().map(|p| p[k]).sum::<f64>() / draws as f64;
            let spread =
                (positions.iter().map(|p| (p[k] - mean).powi(2)).sum::<f64>() / (draws - 1) as f64).sqrt();
            let ratio = stated[k].sqrt() / spread;
            assert!((0.8..1.5).contains(&ratio), "axis {k}: stated / measured {ratio}");
        }
    }

    #[test]
    fn a_rolling_shutter_is_undone_by_the_frame_motion() {
        // A camera whose rows are read over 30 ms, turning at 30 deg/s with 300 deg/s^2 while
        // the deck rolls at 8 deg/s and the camera sinks towards it at 0.8 m/s.
        let cam = CameraModel {
            readout_s: 0.030,
            ..CameraModel::preset("rpi-v2").unwrap()
        };
        let deck = DeckLayout::paper();
        let est = PoseEstimator::new(cam, deck, PoseConfig::default());
        let motion = FrameMotion {
            vehicle_rate_rad_s: Vector3::new(0.3, -0.4, 0.1).normalize() * 30f64.to_radians(),
            vehicle_acceleration_rad_s2: Vector3::new(-300f64.to_radians(), 0.0, 0.0),
            deck_rate_rad_s: Vector3::new(8f64.to_radians(), 2f64.to_radians(), 0.0),
            camera_velocity_mps: Vector3::new(0.1, 0.0, -0.8),
        };
        let (deck_rpy, vehicle_rpy) = (
            Rpy::from_degrees(6.0, -3.0, 25.0),
            Rpy::from_degrees(4.0, -7.0, 10.0),
        );
        let scene_at = |tau: f64| {
            let turn = |w: Vector3<f64>| *Rotation3::from_scaled_axis(w).matrix();
            let vehicle = turn(
                motion.vehicle_rate_rad_s * tau + motion.vehicle_acceleration_rad_s2 * (0.5 * tau * tau),
            ) * vehicle_rpy.to_matrix();
            let c = Vector3::new(0.2, -0.1, 5.0) + motion.camera_velocity_mps * tau;
            SceneGeometry {
                attitude: turn(motion.deck_rate_rad_s * tau) * deck_rpy.to_matrix(),
                viewpoint: Viewpoint::level(c.x, c.y, c.z).with_vehicle_attitude(vehicle),
            }
        };
        // Each marker where it appears: at its own row's instant.
        let px: Vec<Option<[f64; 2]>> = (0..9)
            .map(|i| {
                let p = deck.marker_position(i);
                let mut uv = scene_at(0.0).project_deck_point(&cam, &p)?;
                for _ in 0..6 {
                    uv = scene_at(cam.row_time_s(uv[1])).project_deck_point(&cam, &p)?;
                }
                Some(uv)
            })
            .collect();
        let r_v = vehicle_rpy.to_matrix();
        let still = est.estimate_in_motion(&px, None, true, &r_v, None, true).unwrap();
        let moving = est
            .estimate_in_motion(&px, None, true, &r_v, Some(&motion), true)
            .unwrap();
        let e_still = rpy_error_deg(&still.attitude.rpy, &deck_rpy);
        let e_moving = rpy_error_deg(&moving.attitude.rpy, &deck_rpy);
        assert!(
            e_still.iter().any(|v| *v > 0.1),
            "the readout matters: {e_still:?}"
        );
        assert!(
            e_moving.iter().all(|v| *v < 1e-6),
            "{e_moving:?} (ignored: {e_still:?})"
        );
        assert!((moving.viewpoint.altitude_m - 5.0).abs() < 1e-6);
        // A global shutter ignores the motion.
        let global = PoseEstimator::new(
            CameraModel::preset("rpi-v2").unwrap(),
            deck,
            PoseConfig::default(),
        );
        let px0 = scene_at(0.0).project_markers(global.camera(), &deck);
        let e = global
            .estimate_in_motion(&px0, None, true, &r_v, Some(&motion), true)
            .unwrap();
        assert!(rpy_error_deg(&e.attitude.rpy, &deck_rpy)
            .iter()
            .all(|v| *v < 1e-8));
    }
}
