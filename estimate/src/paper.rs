//! The paper's estimator (Jang, Martinez Macias, Bewley), with the corrections of CONVENTIONS.md (C1-C5).
//!
//! 1. Marker pixels (undistorted) -> image coordinates from the principal point, Xp right, Yp up.
//! 2. "Corrected image" (eq. (7) re-derived, CONVENTIONS.md C2): each ring marker i with its opposite
//!    i' gives its 3D position in the world frame from the altimeter height h and the centre
//!    marker's image m0, exactly for a level camera even when it is offset from the deck centre.
//!    (Extension for occlusions: a ring marker whose opposite is hidden is placed where its
//!    viewing ray meets the deck plane spanned by the complete pairs.)
//! 3. Eq. (3): conic least squares through the corrected ring points' (x, y); ellipse parameters
//!    (CONVENTIONS.md C3). The major axis's angle is alpha.
//! 4. beta from the right triangle of Fig. 8, gamma from the isosceles triangle of Fig. 9 between
//!    the major-axis end OX' and the bow marker OX'' (CONVENTIONS.md C4); see [`PaperVariant`].
//! 5. `R = Rz(alpha) Rx(beta) Rz(gamma)` -> Hamilton quaternion and roll/pitch/yaw (X-Y-Z).

use crate::ellipse::{Ellipse, EllipseFit, EllipseFitError};
use deckwatch_common::deck::{BOW, CENTRE, MAX_MARKERS};
use deckwatch_common::scene::camera_from_world;
use deckwatch_common::{Attitude, CameraModel, DeckLayout, Distortion, Euler313, RotationMatrix};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// How beta and gamma are taken from the triangles of the paper's Figs. 8 and 9.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PaperVariant {
    /// As printed: `beta = s acos(q / r)`, gamma by the law of cosines with the known ring
    /// radius r. Needs an accurate altimeter (0.1 % altitude error: up to 2.5 deg in
    /// `deckwatch sweep --altimeter-error 0.001`; CONVENTIONS.md C5); loses
    /// half the digits near a level deck and near gamma = 0 (acos of ~1).
    Printed,
    /// CONVENTIONS.md C5: the fitted semi-major axis p in place of r in both formulas. Insensitive to
    /// altitude error; same conditioning as `Printed`.
    FittedMajorAxis,
    /// The same two triangles solved with atan2 from their legs: beta from the height of the
    /// corrected ring over its minor axis, gamma from the bow's components along and across the
    /// major axis. Insensitive to altitude error and exact to machine precision everywhere,
    /// including a level deck. The default.
    #[default]
    Atan2,
}

deckwatch_common::named_enum!(
    PaperVariant,
    [Printed => "printed", FittedMajorAxis => "fitted-major-axis", Atan2 => "atan2"]
);

impl PaperVariant {
    /// Whether the variant needs the altimeter reading (the others are scale-free).
    pub fn needs_altitude(&self) -> bool {
        matches!(self, Self::Printed)
    }
}

/// Why the paper's estimator gives no attitude for a frame. It never guesses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NotEstimable {
    /// The marker list does not have one entry per marker of the deck layout.
    WrongMarkerCount { expected: usize, got: usize },
    /// A marker's pixel coordinates are NaN or infinite.
    NonFinite { index: usize },
    /// A marker's pixel lies where the lens model does not invert.
    Undistortion { index: usize },
    /// The centre marker is needed by eq. (7).
    CentreMissing,
    /// The bow marker is needed for gamma (the yaw about the deck normal).
    BowMissing,
    /// Eq. (3) needs at least 5 ring markers.
    TooFewRingMarkers { visible: usize },
    /// This variant (or this occlusion pattern) needs the altimeter reading.
    AltitudeRequired,
    /// The altitude is not a positive number.
    InvalidAltitude,
    /// The markers' images are inconsistent with any deck attitude (e.g. misidentified markers).
    Degenerate(&'static str),
    /// Too few opposite pairs are visible and the deck plane has two plausible solutions.
    AmbiguousDeckPlane,
    /// The corrected ring points do not give an ellipse.
    Ellipse(EllipseFitError),
}

impl std::fmt::Display for NotEstimable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::WrongMarkerCount { expected, got } => {
                write!(f, "{got} marker entries, the deck has {expected} markers")
            }
            Self::NonFinite { index } => write!(f, "marker {index} has non-finite coordinates"),
            Self::Undistortion { index } => {
                write!(f, "marker {index} lies outside the lens model's valid field")
            }
            Self::CentreMissing => write!(f, "the centre marker is not visible"),
            Self::BowMissing => write!(f, "the bow marker is not visible"),
            Self::TooFewRingMarkers { visible } => {
                write!(f, "{visible} ring markers visible, at least 5 are needed")
            }
            Self::AltitudeRequired => write!(f, "an altimeter reading is required"),
            Self::InvalidAltitude => write!(f, "the altitude is not a positive number"),
            Self::Degenerate(why) => write!(f, "degenerate marker geometry: {why}"),
            Self::AmbiguousDeckPlane => {
                write!(f, "too few opposite marker pairs: the deck plane is ambiguous")
            }
            Self::Ellipse(e) => write!(f, "ellipse fit: {e}"),
        }
    }
}

impl std::error::Error for NotEstimable {}

/// The paper estimator's result: the attitude, and the ellipses for logging.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperEstimate {
    /// The deck attitude; `attitude.euler313` holds the (alpha, beta, gamma) as estimated.
    pub attitude: Attitude,
    /// Ellipse of the corrected ring points in the world x-y plane (metres): what alpha and the
    /// semi-axes come from.
    pub deck_ellipse: Ellipse,
    /// Ellipse through the ring markers' (undistorted) pixels, for drawing over the image.
    pub image_ellipse: Option<Ellipse>,
    /// Corrected 3D marker positions in the world frame (metres), by marker index.
    pub corrected: [Option<[f64; 3]>; MAX_MARKERS],
    /// Ring markers that entered the ellipse fit.
    pub ring_markers_used: usize,
    /// RMS distance of the corrected ring points from the fitted ellipse (metres): ~0 for exact
    /// markers; grows with pixel noise and misidentification.
    pub fit_rms_m: f64,
    /// Altitude used in eq. (7): the altimeter reading, or 1 (any scale) for the scale-free
    /// variants when none was given.
    pub altitude_m: f64,
    pub variant: PaperVariant,
}

/// The paper's estimator for one camera and deck layout.
#[derive(Debug, Clone)]
pub struct PaperEstimator {
    camera: CameraModel,
    deck: DeckLayout,
    variant: PaperVariant,
}

/// Below this many metres (at unit altitude) image distances are treated as zero.
const TINY: f64 = 1e-12;

impl PaperEstimator {
    pub fn new(camera: CameraModel, deck: DeckLayout, variant: PaperVariant) -> Self {
        Self {
            camera,
            deck,
            variant,
        }
    }

    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }
    pub fn deck(&self) -> &DeckLayout {
        &self.deck
    }
    pub fn variant(&self) -> PaperVariant {
        self.variant
    }

    /// Estimates the deck attitude from marker pixels in marker-index order (None = not seen;
    /// distorted pixels as detected) and the altimeter height of the camera over the deck centre.
    /// The same for a camera carried by a vehicle at attitude `vehicle` (`R_V`, body to world,
    /// CONVENTIONS.md §5). The method assumes a level camera, so the marker bearings are first
    /// turned into those of a virtual level camera at the same optical centre (a pure rotation
    /// of the viewing rays: `r_level = R_CW0 R_V R_CW0^T r_cam`), then estimated as usual; the
    /// altimeter's height is still the optical centre's. The image ellipse of the result is in
    /// the virtual level camera's (undistorted) pixels.
    pub fn estimate_with_vehicle(
        &self,
        markers: &[Option<[f64; 2]>],
        altitude_m: Option<f64>,
        vehicle: &RotationMatrix,
    ) -> Result<PaperEstimate, NotEstimable> {
        if *vehicle == RotationMatrix::identity() {
            return self.estimate(markers, altitude_m);
        }
        let (level_camera, level) = level_camera_pixels(&self.camera, vehicle, markers);
        PaperEstimator::new(level_camera, self.deck, self.variant).estimate(&level, altitude_m)
    }

    pub fn estimate(
        &self,
        markers: &[Option<[f64; 2]>],
        altitude_m: Option<f64>,
    ) -> Result<PaperEstimate, NotEstimable> {
        let n = self.deck.marker_count();
        if markers.len() != n {
            return Err(NotEstimable::WrongMarkerCount {
                expected: n,
                got: markers.len(),
            });
        }
        if let Some(h) = altitude_m {
            if !(h.is_finite() && h > 0.0) {
                return Err(NotEstimable::InvalidAltitude);
            }
        }
        if self.variant.needs_altitude() && altitude_m.is_none() {
            return Err(NotEstimable::AltitudeRequired);
        }
        let h = altitude_m.unwrap_or(1.0);
        let (fx, fy) = (self.camera.fx, self.camera.fy);

        // Step 1: image coordinates from the principal point, Xp right, Yp up (CONVENTIONS.md C1).
        let mut m = [None::<[f64; 2]>; MAX_MARKERS];
        for (i, uv) in markers.iter().enumerate() {
            let Some(uv) = uv else { continue };
            if !(uv[0].is_finite() && uv[1].is_finite()) {
                return Err(NotEstimable::NonFinite { index: i });
            }
            let [u, v] = self
                .camera
                .undistort_pixel(*uv)
                .ok_or(NotEstimable::Undistortion { index: i })?;
            m[i] = Some([u - self.camera.cx, self.camera.cy - v]);
        }
        let m0 = m[CENTRE].ok_or(NotEstimable::CentreMissing)?;
        if m[BOW].is_none() {
            return Err(NotEstimable::BowMissing);
        }
        let visible = (1..n).filter(|&i| m[i].is_some()).count();
        if visible < 5 {
            return Err(NotEstimable::TooFewRingMarkers { visible });
        }

        // Step 2: corrected 3D points (world frame, origin at the deck centre).
        let mut corrected = [None::<Vector3<f64>>; MAX_MARKERS];
        corrected[CENTRE] = Some(Vector3::zeros());
        let mut unpaired = [0usize; MAX_MARKERS];
        let mut n_unpaired = 0;
        for i in 1..n {
            let Some(mi) = m[i] else { continue };
            let opp = self.deck.opposite(i).expect("ring marker has an opposite");
            match m[opp] {
                Some(mo) => corrected[i] = Some(correct_pair(m0, mi, mo, h, fx, fy)?),
                None => {
                    unpaired[n_unpaired] = i;
                    n_unpaired += 1;
                }
            }
        }
        if n_unpaired > 0 {
            // The camera centre in W (from the centre marker's image) and each marker's ray.
            let c = Vector3::new(-m0[1] * h / fy, m0[0] * h / fx, h);
            let ray = |i: usize| {
                let [xp, yp] = m[i].expect("visible");
                Vector3::new(yp / fy, -xp / fx, -1.0)
            };
            let paired: ([Vector3<f64>; MAX_MARKERS], usize) = {
                let mut pts = [Vector3::zeros(); MAX_MARKERS];
                let mut k = 0;
                for p in corrected[1..n].iter().flatten() {
                    pts[k] = *p;
                    k += 1;
                }
                (pts, k)
            };
            let normal = if paired.1 >= 4 {
                // Two or more complete pairs span the deck plane (through the centre).
                let (normal, spread) = plane_through_origin(&paired.0[..paired.1]);
                if !(spread > 0.0) {
                    return Err(NotEstimable::Degenerate("opposite pairs are collinear"));
                }
                normal
            } else {
                // One pair or none: choose, for each unpaired marker, which of the two points at
                // the ring radius along its ray is on the deck, by coplanarity. Uses the true
                // scale, so it needs the altimeter.
                if altitude_m.is_none() {
                    return Err(NotEstimable::AltitudeRequired);
                }
                self.plane_from_ring_sphere(&paired.0[..paired.1], &unpaired[..n_unpaired], &c, &ray)?
            };
            for &i in &unpaired[..n_unpaired] {
                let w = ray(i);
                let depth = -normal.dot(&c) / normal.dot(&w);
                if !(depth.is_finite() && depth > 0.0) {
                    return Err(NotEstimable::Degenerate(
                        "a marker's ray does not meet the deck plane in front of the camera",
                    ));
                }
                corrected[i] = Some(c + depth * w);
            }
        }

        // Step 3: eq. (3) through the corrected ring points' (x, y).
        let mut xy = [[0.0; 2]; MAX_MARKERS];
        let mut k = 0;
        for p in corrected[1..n].iter().flatten() {
            xy[k] = [p.x, p.y];
            k += 1;
        }
        let fit = EllipseFit::fit(&xy[..k]).map_err(NotEstimable::Ellipse)?;
        let e = fit.ellipse;
        let alpha = e.angle;
        let (sa, ca) = alpha.sin_cos();
        let u_maj = Vector3::new(ca, sa, 0.0);
        let u_min = Vector3::new(-sa, ca, 0.0);

        // Step 4: beta and gamma.
        let bow = corrected[BOW].expect("bow is visible and corrected");
        // Height of the corrected ring against the distance across the major axis.
        let (mut zw, mut ww) = (0.0, 0.0);
        for p in corrected[1..n].iter().flatten() {
            let w = p.dot(&u_min);
            zw += p.z * w;
            ww += w * w;
        }
        if !(ww > TINY * TINY) {
            return Err(NotEstimable::Degenerate(
                "the ring has no extent across its major axis",
            ));
        }
        let sign = |x: f64| if x < 0.0 { -1.0 } else { 1.0 };
        let (beta, gamma) = match self.variant {
            PaperVariant::Printed | PaperVariant::FittedMajorAxis => {
                let r = if self.variant == PaperVariant::Printed {
                    self.deck.ring_radius_m
                } else {
                    e.semi_major
                };
                let beta = sign(zw) * (e.semi_minor / r).clamp(-1.0, 1.0).acos();
                let ox1 = r * u_maj;
                let c2 = (ox1 - bow).norm_squared();
                let cos_g = ((2.0 * r * r - c2) / (2.0 * r * r)).clamp(-1.0, 1.0);
                (beta, sign(bow.dot(&u_min)) * cos_g.acos())
            }
            PaperVariant::Atan2 => {
                // Fig. 8's triangle from its legs: tan(beta) = height / distance across the axis.
                let beta = zw.atan2(ww);
                // Fig. 9's angle from OX' to OX'': the bow's in-deck coordinates along and across
                // the major axis.
                let (sb, cb) = beta.sin_cos();
                let across = bow.dot(&u_min) * cb + bow.z * sb;
                (beta, across.atan2(bow.dot(&u_maj)))
            }
        };

        // Step 5: rotation, quaternion, roll/pitch/yaw.
        let attitude = Attitude::from_euler313(Euler313::new(alpha, beta, gamma));
        let image_ellipse = {
            let mut k = 0;
            for mi in m[1..n].iter().flatten() {
                // Back to pixel coordinates (u right, v down), undistorted.
                xy[k] = [mi[0] + self.camera.cx, self.camera.cy - mi[1]];
                k += 1;
            }
            EllipseFit::fit(&xy[..k]).ok().map(|f| f.ellipse)
        };
        let mut fit_ss = 0.0;
        let mut used = 0;
        for p in corrected[1..n].iter().flatten() {
            fit_ss += e.radial_residual([p.x, p.y]).powi(2);
            used += 1;
        }
        Ok(PaperEstimate {
            attitude,
            deck_ellipse: e,
            image_ellipse,
            corrected: corrected.map(|p| p.map(|v| [v.x, v.y, v.z])),
            ring_markers_used: used,
            fit_rms_m: (fit_ss / used as f64).sqrt(),
            altitude_m: h,
            variant: self.variant,
        })
    }

    /// Deck-plane normal when fewer than two opposite pairs are visible: each unpaired marker
    /// lies at the ring radius from the deck centre, i.e. at one of the two points where its
    /// ray meets that sphere; the combination that is coplanar (with the centre and any pair)
    /// wins, and must win clearly.
    fn plane_from_ring_sphere(
        &self,
        paired: &[Vector3<f64>],
        unpaired: &[usize],
        c: &Vector3<f64>,
        ray: &dyn Fn(usize) -> Vector3<f64>,
    ) -> Result<Vector3<f64>, NotEstimable> {
        // 2^k combinations; k <= 10 keeps this under a millisecond.
        if unpaired.len() > 10 {
            return Err(NotEstimable::AmbiguousDeckPlane);
        }
        let r = self.deck.ring_radius_m;
        let mut cands = [[Vector3::zeros(); 2]; MAX_MARKERS];
        for (slot, &i) in unpaired.iter().enumerate() {
            let w = ray(i);
            // |c + D w|^2 = r^2
            let (a, b, cc) = (w.norm_squared(), 2.0 * c.dot(&w), c.norm_squared() - r * r);
            let disc = b * b - 4.0 * a * cc;
            if !(disc >= 0.0) {
                return Err(NotEstimable::Degenerate(
                    "a marker's ray misses the ring (altitude or identification wrong)",
                ));
            }
            let sq = disc.sqrt();
            cands[slot] = [c + (-b - sq) / (2.0 * a) * w, c + (-b + sq) / (2.0 * a) * w];
        }
        let mut best = (f64::INFINITY, Vector3::zeros());
        let mut second = f64::INFINITY;
        let mut pts = [Vector3::zeros(); MAX_MARKERS];
        pts[..paired.len()].copy_from_slice(paired);
        for mask in 0u32..(1 << unpaired.len()) {
            for slot in 0..unpaired.len() {
                pts[paired.len() + slot] = cands[slot][((mask >> slot) & 1) as usize];
            }
            let all = &pts[..paired.len() + unpaired.len()];
            let (normal, _) = plane_through_origin(all);
            let resid: f64 = all.iter().map(|p| normal.dot(p).powi(2)).sum();
            if resid < best.0 {
                second = best.0;
                best = (resid, normal);
            } else if resid < second {
                second = resid;
            }
        }
        // The right combination is coplanar to rounding (or to noise); demand a clear margin.
        if !(second > 100.0 * best.0 + 1e-18 * r * r) {
            return Err(NotEstimable::AmbiguousDeckPlane);
        }
        Ok(best.1)
    }
}

/// Eq. (7), re-derived (CONVENTIONS.md C2): the world position of ring marker i from its image m_i,
/// its opposite's image m_i' and the centre's image m0 (Xp right, Yp up), camera level at height
/// h. Since P_i + P_i' = 0 and the three images are collinear, `depth_i = 2 h d_i' / (d_i + d_i')`.
fn correct_pair(
    m0: [f64; 2],
    mi: [f64; 2],
    mo: [f64; 2],
    h: f64,
    fx: f64,
    fy: f64,
) -> Result<Vector3<f64>, NotEstimable> {
    let (vx, vy) = (mi[0] - m0[0], mi[1] - m0[1]);
    let (ox, oy) = (mo[0] - m0[0], mo[1] - m0[1]);
    let di = vx.hypot(vy);
    let dio = ox.hypot(oy);
    if !(di > TINY && dio > TINY) {
        return Err(NotEstimable::Degenerate(
            "a ring marker images on the centre marker",
        ));
    }
    if vx * ox + vy * oy >= 0.0 {
        return Err(NotEstimable::Degenerate(
            "opposite ring markers image on the same side of the centre (misidentified?)",
        ));
    }
    let (cos_psi, sin_psi) = (vx / di, vy / di);
    let sum = di + dio;
    let (xp0, yp0) = (m0[0], m0[1]);
    Ok(Vector3::new(
        h * ((dio - di) * yp0 + 2.0 * di * dio * sin_psi) / (fy * sum),
        -h * ((dio - di) * xp0 + 2.0 * di * dio * cos_psi) / (fx * sum),
        h * (di - dio) / sum,
    ))
}

/// Least-squares plane through the origin: (unit normal, second-smallest eigenvalue of the
/// scatter, which is 0 when the points are collinear).
fn plane_through_origin(points: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let mut s = Matrix3::zeros();
    for p in points {
        s += p * p.transpose();
    }
    let eig = SymmetricEigen::new(s);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let mut normal: Vector3<f64> = eig.eigenvectors.column(order[0]).into();
    if normal.z < 0.0 {
        normal = -normal; // deck normal points up
    }
    let spread = eig.eigenvalues[order[1]] / eig.eigenvalues[order[2]].max(f64::MIN_POSITIVE);
    (normal, if spread > 1e-12 { spread } else { 0.0 })
}

/// Marker pixels as a level camera at the same optical centre would see them: each pixel's
/// viewing ray (undistorted) turned by `R_CW0 R_V R_CW0^T` and projected with the same focal
/// lengths and principal point. Returns that camera (no distortion: the pixels are undistorted)
/// and the pixels; a ray that would point above the virtual camera's horizon gives None.
pub fn level_camera_pixels(
    camera: &CameraModel,
    vehicle: &RotationMatrix,
    markers: &[Option<[f64; 2]>],
) -> (CameraModel, Vec<Option<[f64; 2]>>) {
    let c = camera_from_world();
    let turn = c * vehicle * c.transpose();
    let level_camera = CameraModel {
        distortion: Distortion::default(),
        ..*camera
    };
    let pixels = markers
        .iter()
        .map(|m| {
            let [x, y] = camera.unproject((*m)?)?;
            let r = turn * Vector3::new(x, y, 1.0);
            (r.z > 0.0).then(|| level_camera.project(&r)).flatten()
        })
        .collect();
    (level_camera, pixels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::{Rpy, SceneGeometry, Viewpoint};

    fn markers(rpy: Rpy, vp: Viewpoint, cam: &CameraModel) -> Vec<Option<[f64; 2]>> {
        SceneGeometry {
            attitude: rpy.to_matrix(),
            viewpoint: vp,
        }
        .project_markers(cam, &DeckLayout::paper())
    }

    fn max_err_deg(a: &Attitude, truth: Rpy) -> f64 {
        let e = deckwatch_common::rotation::rotation_angle_between(&a.matrix, &truth.to_matrix());
        e.to_degrees()
    }

    #[test]
    fn paper_figure_7_case() {
        let cam = CameraModel::paper();
        let truth = Rpy::from_degrees(20.0, 10.0, 5.0);
        let px = markers(truth, Viewpoint::centred(5.0), &cam);
        for v in PaperVariant::ALL {
            let est = PaperEstimator::new(cam, DeckLayout::paper(), v)
                .estimate(&px, Some(5.0))
                .unwrap();
            assert!(max_err_deg(&est.attitude, truth) < 1e-10, "{v:?}");
            let [r, p, y] = est.attitude.rpy.to_degrees();
            assert!((r - 20.0).abs() < 1e-10 && (p - 10.0).abs() < 1e-10 && (y - 5.0).abs() < 1e-10);
            // The deck ellipse: semi-major = r, semi-minor = r cos(beta).
            let e313 = Euler313::from_matrix(&truth.to_matrix());
            assert!((est.deck_ellipse.semi_major - 0.5).abs() < 1e-12);
            assert!((est.deck_ellipse.semi_minor - 0.5 * e313.beta.cos()).abs() < 1e-12);
            assert!((est.attitude.euler313.alpha - e313.alpha).abs() < 1e-12);
            assert!(est.fit_rms_m < 1e-12);
            // Corrected points are the true world positions.
            for (i, p) in est.corrected.iter().take(9).enumerate() {
                let t = truth.to_matrix() * DeckLayout::paper().marker_position(i);
                let p = p.unwrap();
                assert!((Vector3::from(p) - t).norm() < 1e-12);
            }
            assert!(est.image_ellipse.is_some());
        }
    }

    #[test]
    fn printed_needs_altitude_others_do_not() {
        let cam = CameraModel::rpi_v2();
        let truth = Rpy::from_degrees(-12.0, 4.0, -3.0);
        let px = markers(truth, Viewpoint::centred(5.0), &cam);
        let deck = DeckLayout::paper();
        assert_eq!(
            PaperEstimator::new(cam, deck, PaperVariant::Printed).estimate(&px, None),
            Err(NotEstimable::AltitudeRequired)
        );
        for v in [PaperVariant::FittedMajorAxis, PaperVariant::Atan2] {
            let est = PaperEstimator::new(cam, deck, v).estimate(&px, None).unwrap();
            assert!(max_err_deg(&est.attitude, truth) < 1e-9, "{v:?}");
        }
        for bad in [0.0, -5.0, f64::NAN] {
            assert_eq!(
                PaperEstimator::new(cam, deck, PaperVariant::Atan2).estimate(&px, Some(bad)),
                Err(NotEstimable::InvalidAltitude)
            );
        }
    }

    #[test]
    fn variant_names_round_trip() {
        for v in PaperVariant::ALL {
            assert_eq!(PaperVariant::from_name(v.name()), Some(v));
        }
        assert_eq!(PaperVariant::from_name("x"), None);
    }
}
