//! Attitude conventions of deckwatch (CONVENTIONS.md): the single source of truth.
//!
//! `P_world = R * P_deck`, with
//! `R = Rz(alpha) Rx(beta) Rz(gamma)` (the paper's 3-1-3 sequence) `= Rx(roll) Ry(pitch) Rz(yaw)`.
//! The roll/pitch/yaw order is X-Y-Z, *not* the aerospace Z-Y-X: never use a library's
//! `from_euler_angles` for it. Quaternions are ordinary Hamilton quaternions of R (w, x, y, z);
//! the paper's printed quaternion differs (its q2 has the opposite sign), see
//! [`Euler313::to_quaternion`].
//!
//! All angles are radians unless a name ends in `_deg`.

#[cfg(feature = "shm")]
use iceoryx2::prelude::ZeroCopySend;
use nalgebra::Matrix3;
use std::f64::consts::{FRAC_PI_2, PI};

/// A rotation matrix taking deck coordinates to world coordinates (`P_world = R * P_deck`).
pub type RotationMatrix = Matrix3<f64>;

/// Rotation about x by `a`.
pub fn rot_x(a: f64) -> RotationMatrix {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

/// Rotation about y by `a`.
pub fn rot_y(a: f64) -> RotationMatrix {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

/// Rotation about z by `a`.
pub fn rot_z(a: f64) -> RotationMatrix {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Wraps an angle into (-pi, pi].
pub fn wrap_pi(a: f64) -> f64 {
    let w = a.rem_euclid(2.0 * PI); // [0, 2pi)
    if w > PI {
        w - 2.0 * PI
    } else {
        w
    }
}

/// Roll, pitch, yaw in the X-Y-Z order: `R = Rx(roll) Ry(pitch) Rz(yaw)`.
///
/// Positive roll raises the port side, positive pitch lowers the bow, positive yaw turns the bow
/// to port.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.Rpy.v1"))]
pub struct Rpy {
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
}

impl Rpy {
    pub fn new(roll: f64, pitch: f64, yaw: f64) -> Self {
        Self { roll, pitch, yaw }
    }

    pub fn from_degrees(roll_deg: f64, pitch_deg: f64, yaw_deg: f64) -> Self {
        Self::new(
            roll_deg.to_radians(),
            pitch_deg.to_radians(),
            yaw_deg.to_radians(),
        )
    }

    /// `[roll, pitch, yaw]` in degrees.
    pub fn to_degrees(&self) -> [f64; 3] {
        [
            self.roll.to_degrees(),
            self.pitch.to_degrees(),
            self.yaw.to_degrees(),
        ]
    }

    pub fn to_matrix(&self) -> RotationMatrix {
        rot_x(self.roll) * rot_y(self.pitch) * rot_z(self.yaw)
    }

    /// Inverse of [`Rpy::to_matrix`]: `pitch = asin(R02)` in [-90, 90] deg,
    /// `roll = atan2(-R12, R22)`, `yaw = atan2(-R01, R00)`.
    ///
    /// At pitch = +-90 deg (never reached by a deck) roll and yaw are not separable: roll is set
    /// to 0 and yaw carries their combination.
    pub fn from_matrix(r: &RotationMatrix) -> Self {
        let s = r[(0, 2)].clamp(-1.0, 1.0);
        // Below this, cos(pitch) is too small for the atan2 pairs to carry information.
        if 1.0 - s.abs() < 1e-15 {
            let pitch = FRAC_PI_2.copysign(s);
            // With cos(pitch) = 0: R10 = sin(roll + s*yaw)... choose roll = 0, yaw from R10, R11.
            let yaw = r[(1, 0)].atan2(r[(1, 1)]);
            return Self::new(0.0, pitch, yaw);
        }
        Self::new(
            (-r[(1, 2)]).atan2(r[(2, 2)]),
            s.asin(),
            (-r[(0, 1)]).atan2(r[(0, 0)]),
        )
    }
}

/// The paper's 3-1-3 Euler angles: `R = Rz(alpha) Rx(beta) Rz(gamma)`.
///
/// Canonical form, as the paper's estimator produces it: `alpha` is the direction of the deck's
/// tilt axis (the ring ellipse's major axis) in (-90, 90] deg, `beta` is the signed tilt in
/// (-180, 180], `gamma` in (-180, 180] deg. `(alpha, beta, gamma)` and
/// `(alpha + 180, -beta, gamma + 180)` are the same rotation; the canonical form picks the one
/// with alpha in (-90, 90].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.Euler313.v1"))]
pub struct Euler313 {
    pub alpha: f64,
    pub beta: f64,
    pub gamma: f64,
}

impl Euler313 {
    pub fn new(alpha: f64, beta: f64, gamma: f64) -> Self {
        Self { alpha, beta, gamma }
    }

    pub fn from_degrees(alpha_deg: f64, beta_deg: f64, gamma_deg: f64) -> Self {
        Self::new(
            alpha_deg.to_radians(),
            beta_deg.to_radians(),
            gamma_deg.to_radians(),
        )
    }

    /// `[alpha, beta, gamma]` in degrees.
    pub fn to_degrees(&self) -> [f64; 3] {
        [
            self.alpha.to_degrees(),
            self.beta.to_degrees(),
            self.gamma.to_degrees(),
        ]
    }

    pub fn to_matrix(&self) -> RotationMatrix {
        rot_z(self.alpha) * rot_x(self.beta) * rot_z(self.gamma)
    }

    /// Canonical 3-1-3 angles of `r` (see the type's docs).
    ///
    /// `R = [[ca cg - sa cb sg, ., sa sb], [sa cg + ca cb sg, ., -ca sb], [sb sg, sb cg, cb]]`.
    /// When the deck is level (beta = 0) alpha and gamma are not separable: alpha is set to 0 and
    /// gamma carries their sum.
    pub fn from_matrix(r: &RotationMatrix) -> Self {
        let sb_sa = r[(0, 2)];
        let sb_ca = -r[(1, 2)];
        let sb_sg = r[(2, 0)];
        let sb_cg = r[(2, 1)];
        let sin_beta = sb_sa.hypot(sb_ca).max(sb_sg.hypot(sb_cg));
        if sin_beta < 1e-15 {
            // Level (or upside down): R = Rz(alpha + gamma) or Rz(alpha) Rx(pi) Rz(gamma).
            let beta = if r[(2, 2)] > 0.0 { 0.0 } else { PI };
            // With alpha = 0: R = Rz(gamma), or diag(1, -1, -1) Rz(gamma) when upside down.
            let gamma = if beta == 0.0 {
                r[(1, 0)].atan2(r[(0, 0)])
            } else {
                (-r[(1, 0)]).atan2(r[(0, 0)])
            };
            return Self::new(0.0, beta, wrap_pi(gamma)).canonical();
        }
        let alpha = sb_sa.atan2(sb_ca);
        let gamma = sb_sg.atan2(sb_cg);
        let beta = sin_beta.atan2(r[(2, 2)]); // in (0, pi)
        Self::new(alpha, beta, gamma).canonical()
    }

    /// The equivalent angles with alpha in (-90, 90] deg (beta then takes the sign of the tilt).
    pub fn canonical(&self) -> Self {
        let mut alpha = wrap_pi(self.alpha);
        let mut beta = wrap_pi(self.beta);
        let mut gamma = wrap_pi(self.gamma);
        if alpha > FRAC_PI_2 || alpha <= -FRAC_PI_2 {
            alpha = wrap_pi(alpha + PI);
            beta = wrap_pi(-beta);
            gamma = wrap_pi(gamma + PI);
        }
        // wrap_pi(alpha + pi) may land exactly on -pi/2 through rounding; keep the interval.
        if alpha <= -FRAC_PI_2 {
            alpha += PI;
            beta = wrap_pi(-beta);
            gamma = wrap_pi(gamma + PI);
        }
        Self::new(alpha, beta, gamma)
    }

    /// The Hamilton quaternion of `Rz(alpha) Rx(beta) Rz(gamma)`, in closed form.
    ///
    /// This is the paper's printed formula with the sign of its q2 corrected (CONVENTIONS.md §2): the
    /// printed q2 `s(g/2)s(b/2)c(a/2) - c(g/2)s(b/2)s(a/2)` is the negative of the true y part.
    pub fn to_quaternion(&self) -> Quaternion {
        let (sa, ca) = (self.alpha / 2.0).sin_cos();
        let (sb, cb) = (self.beta / 2.0).sin_cos();
        let (sg, cg) = (self.gamma / 2.0).sin_cos();
        Quaternion::new(
            cg * cb * ca - sg * cb * sa,
            cg * sb * ca + sg * sb * sa,
            -(sg * sb * ca - cg * sb * sa),
            cg * cb * sa + sg * cb * ca,
        )
        .canonical()
    }
}

/// A Hamilton unit quaternion `w + x i + y j + z k` of a rotation matrix R.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.Quaternion.v1"))]
pub struct Quaternion {
    pub w: f64,
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Quaternion {
    pub const IDENTITY: Self = Self {
        w: 1.0,
        x: 0.0,
        y: 0.0,
        z: 0.0,
    };

    pub fn new(w: f64, x: f64, y: f64, z: f64) -> Self {
        Self { w, x, y, z }
    }

    pub fn norm(&self) -> f64 {
        (self.w * self.w + self.x * self.x + self.y * self.y + self.z * self.z).sqrt()
    }

    /// q and -q are the same rotation; the canonical one has w >= 0 (and, at w = 0, the first
    /// non-zero of x, y, z positive).
    pub fn canonical(&self) -> Self {
        let flip = if self.w != 0.0 {
            self.w < 0.0
        } else if self.x != 0.0 {
            self.x < 0.0
        } else if self.y != 0.0 {
            self.y < 0.0
        } else {
            self.z < 0.0
        };
        if flip {
            Self::new(-self.w, -self.x, -self.y, -self.z)
        } else {
            *self
        }
    }

    /// Unit quaternion (None for a zero or non-finite quaternion).
    pub fn normalized(&self) -> Option<Self> {
        let n = self.norm();
        if !(n.is_finite() && n > 0.0) {
            return None;
        }
        Some(Self::new(self.w / n, self.x / n, self.y / n, self.z / n))
    }

    /// The rotation matrix of a unit quaternion.
    pub fn to_matrix(&self) -> RotationMatrix {
        let Self { w, x, y, z } = *self;
        Matrix3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        )
    }

    /// The canonical quaternion of a rotation matrix (Shepperd's method: the largest of the four
    /// diagonal combinations is used as the pivot, so no branch divides by a small number).
    pub fn from_matrix(r: &RotationMatrix) -> Self {
        let tr = r[(0, 0)] + r[(1, 1)] + r[(2, 2)];
        let q = if tr >= r[(0, 0)].max(r[(1, 1)]).max(r[(2, 2)]) {
            let s = 2.0 * (1.0 + tr).sqrt(); // 4w
            Self::new(
                s / 4.0,
                (r[(2, 1)] - r[(1, 2)]) / s,
                (r[(0, 2)] - r[(2, 0)]) / s,
                (r[(1, 0)] - r[(0, 1)]) / s,
            )
        } else if r[(0, 0)] >= r[(1, 1)] && r[(0, 0)] >= r[(2, 2)] {
            let s = 2.0 * (1.0 + r[(0, 0)] - r[(1, 1)] - r[(2, 2)]).sqrt(); // 4x
            Self::new(
                (r[(2, 1)] - r[(1, 2)]) / s,
                s / 4.0,
                (r[(0, 1)] + r[(1, 0)]) / s,
                (r[(0, 2)] + r[(2, 0)]) / s,
            )
        } else if r[(1, 1)] >= r[(2, 2)] {
            let s = 2.0 * (1.0 - r[(0, 0)] + r[(1, 1)] - r[(2, 2)]).sqrt(); // 4y
            Self::new(
                (r[(0, 2)] - r[(2, 0)]) / s,
                (r[(0, 1)] + r[(1, 0)]) / s,
                s / 4.0,
                (r[(1, 2)] + r[(2, 1)]) / s,
            )
        } else {
            let s = 2.0 * (1.0 - r[(0, 0)] - r[(1, 1)] + r[(2, 2)]).sqrt(); // 4z
            Self::new(
                (r[(1, 0)] - r[(0, 1)]) / s,
                (r[(0, 2)] + r[(2, 0)]) / s,
                (r[(1, 2)] + r[(2, 1)]) / s,
                s / 4.0,
            )
        };
        q.normalized().unwrap_or(Self::IDENTITY).canonical()
    }

    /// Spherical linear interpolation from `self` (s = 0) to `other` (s = 1) along the shorter
    /// arc; both unit quaternions.
    pub fn slerp(&self, other: &Self, s: f64) -> Self {
        let mut b = *other;
        let mut dot = self.w * b.w + self.x * b.x + self.y * b.y + self.z * b.z;
        if dot < 0.0 {
            b = Self::new(-b.w, -b.x, -b.y, -b.z);
            dot = -dot;
        }
        // The same rotation to rounding: the chord is the arc (and sin(theta) would vanish).
        let (ka, kb) = if 1.0 - dot < 1e-12 {
            (1.0 - s, s)
        } else {
            let theta = dot.min(1.0).acos();
            let sin = theta.sin();
            (((1.0 - s) * theta).sin() / sin, (s * theta).sin() / sin)
        };
        let q = Self::new(
            ka * self.w + kb * b.w,
            ka * self.x + kb * b.x,
            ka * self.y + kb * b.y,
            ka * self.z + kb * b.z,
        );
        q.normalized().unwrap_or(*self)
    }

    /// Roll/pitch/yaw (X-Y-Z) of this quaternion, through its matrix.
    pub fn to_rpy(&self) -> Rpy {
        Rpy::from_matrix(&self.to_matrix())
    }
}

/// One attitude in every representation deckwatch publishes, all derived from one matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attitude {
    pub matrix: RotationMatrix,
    pub rpy: Rpy,
    pub euler313: Euler313,
    pub quaternion: Quaternion,
}

impl Attitude {
    pub fn from_matrix(matrix: RotationMatrix) -> Self {
        Self {
            matrix,
            rpy: Rpy::from_matrix(&matrix),
            euler313: Euler313::from_matrix(&matrix),
            quaternion: Quaternion::from_matrix(&matrix),
        }
    }

    /// The attitude of the given 3-1-3 angles; keeps them as given (not re-derived, so a level
    /// deck's alpha is preserved).
    pub fn from_euler313(e: Euler313) -> Self {
        let matrix = e.to_matrix();
        Self {
            matrix,
            rpy: Rpy::from_matrix(&matrix),
            euler313: e,
            quaternion: e.to_quaternion(),
        }
    }

    pub fn from_rpy(rpy: Rpy) -> Self {
        let matrix = rpy.to_matrix();
        Self {
            rpy,
            ..Self::from_matrix(matrix)
        }
    }
}

/// The angle of the rotation taking `a` to `b` (the geodesic distance), in radians.
/// The angular velocity (rad/s, in the frame both rotations map into) that turns `a` into `b`
/// in `dt_s`: `b = exp([w dt]x) a`.
pub fn angular_velocity(a: &RotationMatrix, b: &RotationMatrix, dt_s: f64) -> nalgebra::Vector3<f64> {
    nalgebra::Rotation3::from_matrix_unchecked(b * a.transpose()).scaled_axis() / dt_s
}

pub fn rotation_angle_between(a: &RotationMatrix, b: &RotationMatrix) -> f64 {
    let d = a.transpose() * b;
    // Robust for small angles: sin from the skew part, cos from the trace.
    let s = 0.5
        * ((d[(2, 1)] - d[(1, 2)]).powi(2)
            + (d[(0, 2)] - d[(2, 0)]).powi(2)
            + (d[(1, 0)] - d[(0, 1)]).powi(2))
        .sqrt();
    let c = 0.5 * (d.trace() - 1.0);
    s.atan2(c)
}

/// Signed difference `a - b` of two angles, wrapped into (-pi, pi].
pub fn angle_difference(a: f64, b: f64) -> f64 {
    wrap_pi(a - b)
}

/// |a - b| per axis (roll, pitch, yaw), wrapped, in degrees: how far an estimate is from the truth.
pub fn rpy_error_deg(a: &Rpy, b: &Rpy) -> [f64; 3] {
    rpy_signed_error_deg(a, b).map(f64::abs)
}

/// a - b per axis (roll, pitch, yaw), wrapped to (-180, 180], in degrees: an estimate's error
/// with its sign (a bias, or an error that grows with the angle, shows only in these).
pub fn rpy_signed_error_deg(a: &Rpy, b: &Rpy) -> [f64; 3] {
    [
        angle_difference(a.roll, b.roll).to_degrees(),
        angle_difference(a.pitch, b.pitch).to_degrees(),
        angle_difference(a.yaw, b.yaw).to_degrees(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn assert_mat_close(a: &RotationMatrix, b: &RotationMatrix, tol: f64) {
        let d = (a - b).abs().max();
        assert!(d <= tol, "matrices differ by {d:e}:\n{a}\n{b}");
    }

    #[test]
    fn sign_conventions_match_notes() {
        // Positive roll raises the port side (+y).
        let r = Rpy::from_degrees(10.0, 0.0, 0.0).to_matrix();
        assert!((r * nalgebra::Vector3::y()).z > 0.0);
        // Positive pitch lowers the bow (+x).
        let r = Rpy::from_degrees(0.0, 10.0, 0.0).to_matrix();
        assert!((r * nalgebra::Vector3::x()).z < 0.0);
        // Positive yaw turns the bow to port.
        let r = Rpy::from_degrees(0.0, 0.0, 10.0).to_matrix();
        assert!((r * nalgebra::Vector3::x()).y > 0.0);
    }

    #[test]
    fn xyz_is_not_aerospace_zyx() {
        // The same angles in Z-Y-X order give a different rotation on ship motion.
        let rpy = Rpy::from_degrees(25.0, 8.0, 5.0);
        let zyx = rot_z(rpy.yaw) * rot_y(rpy.pitch) * rot_x(rpy.roll);
        let deg = rotation_angle_between(&rpy.to_matrix(), &zyx).to_degrees();
        assert!(deg > 1.0, "X-Y-Z and Z-Y-X differ by only {deg} deg");
        // nalgebra's from_euler_angles is Z-Y-X (roll about x applied first); not ours.
        let na = nalgebra::Rotation3::from_euler_angles(rpy.roll, rpy.pitch, rpy.yaw);
        assert!(rotation_angle_between(&rpy.to_matrix(), na.matrix()) > 1e-3);
    }

    #[test]
    fn inverse_formula_of_notes() {
        let rpy = Rpy::from_degrees(-17.0, 6.5, 3.25);
        let r = rpy.to_matrix();
        assert!((r[(0, 2)].asin() - rpy.pitch).abs() < 1e-15);
        assert!(((-r[(1, 2)]).atan2(r[(2, 2)]) - rpy.roll).abs() < 1e-15);
        assert!(((-r[(0, 1)]).atan2(r[(0, 0)]) - rpy.yaw).abs() < 1e-15);
    }

    #[test]
    fn paper_example_20_roll_10_pitch_5_yaw() {
        // Fig. 7 of the paper: 20 roll, 10 pitch, 5 yaw; both routes agree.
        let rpy = Rpy::from_degrees(20.0, 10.0, 5.0);
        let e = Euler313::from_matrix(&rpy.to_matrix());
        assert_mat_close(&e.to_matrix(), &rpy.to_matrix(), 1e-15);
        let q = e.to_quaternion();
        let back = q.to_rpy().to_degrees();
        for (b, t) in back.iter().zip([20.0, 10.0, 5.0]) {
            assert!((b - t).abs() < 1e-12, "{back:?}");
        }
    }

    #[test]
    fn printed_quaternion_has_wrong_q2_sign() {
        let e = Euler313::from_degrees(30.0, 20.0, 10.0);
        let (sa, ca) = (e.alpha / 2.0).sin_cos();
        let (sb, cb) = (e.beta / 2.0).sin_cos();
        let (sg, cg) = (e.gamma / 2.0).sin_cos();
        let printed_q2 = sg * sb * ca - cg * sb * sa;
        let true_q = Quaternion::from_matrix(&e.to_matrix());
        assert!((printed_q2 + true_q.y).abs() < 1e-15);
        let _ = cb; // the other components are as printed
    }

    #[test]
    fn level_deck_313_is_defined() {
        let r = rot_z(0.3);
        let e = Euler313::from_matrix(&r);
        assert_eq!(e.alpha, 0.0);
        assert_eq!(e.beta, 0.0);
        assert!((e.gamma - 0.3).abs() < 1e-15);
        assert_mat_close(&e.to_matrix(), &r, 1e-15);
        let e = Euler313::from_matrix(&RotationMatrix::identity());
        assert_eq!((e.alpha, e.beta, e.gamma), (0.0, 0.0, 0.0));
    }

    #[test]
    fn canonical_313_alpha_interval() {
        for a_deg in [-270.0, -180.0, -90.0, -89.0, 0.0, 90.0, 91.0, 180.0, 270.0] {
            let e = Euler313::from_degrees(a_deg, 15.0, 40.0);
            let c = e.canonical();
            assert!(c.alpha > -FRAC_PI_2 && c.alpha <= FRAC_PI_2, "{a_deg}: {c:?}");
            assert_mat_close(&c.to_matrix(), &e.to_matrix(), 1e-14);
        }
    }

    #[test]
    fn gimbal_lock_rpy() {
        let r = Rpy::from_degrees(0.0, 90.0, 30.0).to_matrix();
        let rpy = Rpy::from_matrix(&r);
        assert_mat_close(&rpy.to_matrix(), &r, 1e-12);
    }

    #[test]
    fn quaternion_of_180_degree_rotations() {
        for r in [rot_x(PI), rot_y(PI), rot_z(PI), rot_x(PI) * rot_z(FRAC_PI_2)] {
            let q = Quaternion::from_matrix(&r);
            assert!((q.norm() - 1.0).abs() < 1e-15);
            assert_mat_close(&q.to_matrix(), &r, 1e-15);
        }
    }

    fn angle() -> impl Strategy<Value = f64> {
        -PI..PI
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn rpy_round_trip(roll in angle(), pitch in -1.5..1.5f64, yaw in angle()) {
            let rpy = Rpy::new(roll, pitch, yaw);
            let back = Rpy::from_matrix(&rpy.to_matrix());
            prop_assert!(angle_difference(back.roll, roll).abs() < 1e-12);
            prop_assert!(angle_difference(back.pitch, pitch).abs() < 1e-12);
            prop_assert!(angle_difference(back.yaw, yaw).abs() < 1e-12);
        }

        #[test]
        fn euler313_round_trip(alpha in angle(), beta in -3.1..3.1f64, gamma in angle()) {
            prop_assume!(beta.abs() > 1e-6);
            let e = Euler313::new(alpha, beta, gamma);
            let back = Euler313::from_matrix(&e.to_matrix());
            let c = e.canonical();
            prop_assert!(angle_difference(back.alpha, c.alpha).abs() < 1e-9, "{back:?} {c:?}");
            prop_assert!(angle_difference(back.beta, c.beta).abs() < 1e-9);
            prop_assert!(angle_difference(back.gamma, c.gamma).abs() < 1e-9);
            prop_assert!(back.alpha > -FRAC_PI_2 && back.alpha <= FRAC_PI_2);
        }

        #[test]
        fn matrix_round_trips(roll in angle(), pitch in -1.5..1.5f64, yaw in angle()) {
            let r = Rpy::new(roll, pitch, yaw).to_matrix();
            assert_mat_close(&Euler313::from_matrix(&r).to_matrix(), &r, 1e-14);
            assert_mat_close(&Quaternion::from_matrix(&r).to_matrix(), &r, 1e-14);
            let q = Quaternion::from_matrix(&r);
            prop_assert!(q.w >= 0.0);
            prop_assert!((q.norm() - 1.0).abs() < 1e-14);
            // Closed-form 3-1-3 quaternion agrees with the matrix route.
            let qe = Euler313::from_matrix(&r).to_quaternion();
            prop_assert!((qe.w - q.w).abs() < 1e-14 && (qe.x - q.x).abs() < 1e-14);
            prop_assert!((qe.y - q.y).abs() < 1e-14 && (qe.z - q.z).abs() < 1e-14);
            let rpy2 = q.to_rpy();
            assert_mat_close(&rpy2.to_matrix(), &r, 1e-14);
        }

        #[test]
        fn quaternion_round_trip(w in -1.0..1.0f64, x in -1.0..1.0f64, y in -1.0..1.0f64, z in -1.0..1.0f64) {
            let Some(q) = Quaternion::new(w, x, y, z).normalized() else { return Ok(()) };
            prop_assume!(q.norm() > 0.5);
            let back = Quaternion::from_matrix(&q.to_matrix());
            let c = q.canonical();
            prop_assert!((back.w - c.w).abs() < 1e-12 && (back.x - c.x).abs() < 1e-12);
            prop_assert!((back.y - c.y).abs() < 1e-12 && (back.z - c.z).abs() < 1e-12);
        }
    }
}
