//! One camera calibrated over all views of the grid: Zhang's closed form from the views'
//! homographies (zero skew), each view's pose from its homography, then Levenberg-Marquardt
//! on every parameter at once over the pixel residuals (OpenCV's distortion model: k1, k2,
//! p1, p2; k3 fixed at 0).

use super::{fit_view_homography, lm, point_distances, rms, GridError, GridLayout};
use deckwatch_common::camera::Distortion;
use deckwatch_common::homography;
use nalgebra::{DVector, Matrix3, Rotation3, SMatrix, SVector, Vector3};

/// The intrinsics' parameters in the joint fit: fx, fy, cx, cy, k1, k2, p1, p2.
const INTRINSICS: usize = 8;
/// Per view: rotation vector (rad) and translation (mm).
const POSE: usize = 6;

/// A calibration over all views and each view's residuals (px).
#[derive(Debug, Clone, PartialEq)]
pub struct GridCalibration {
    /// Focal lengths and principal point (px).
    pub fx_px: f64,
    pub fy_px: f64,
    pub cx_px: f64,
    pub cy_px: f64,
    pub distortion: Distortion,
    /// Per view: the target's rotation into the camera and its origin in the camera (mm).
    pub poses: Vec<(Rotation3<f64>, Vector3<f64>)>,
    /// Per view, RMS and largest distance (px) of the measured centres from the projections.
    pub rms_px: Vec<f64>,
    pub max_px: Vec<f64>,
    /// RMS over all points of all views (px).
    pub overall_rms_px: f64,
    pub iterations: usize,
}

impl GridCalibration {
    /// The intrinsic matrix.
    pub fn k(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.fx_px, 0.0, self.cx_px, 0.0, self.fy_px, self.cy_px, 0.0, 0.0, 1.0,
        )
    }
}

/// Calibrates a camera of `width` x `height` pixels from views of the grid (each the grid's
/// points' centres in the layout's order, px; a point not measured is NaN and left out).
pub fn calibrate(
    views: &[Vec<[f64; 2]>],
    layout: &GridLayout,
    width: u32,
    height: u32,
) -> Result<GridCalibration, GridError> {
    let target = layout.points_mm();
    for (view, points) in views.iter().enumerate() {
        if points.len() != target.len() {
            return Err(GridError::ViewSize {
                view,
                found: points.len(),
                expected: target.len(),
            });
        }
    }
    let hs = views
        .iter()
        .map(|v| fit_view_homography(&target, v).map(|f| f.h))
        .collect::<Result<Vec<_>, _>>()?;
    let k = closed_form_intrinsics(&hs, width, height)?;
    let mut start = vec![k[(0, 0)], k[(1, 1)], k[(0, 2)], k[(1, 2)], 0.0, 0.0, 0.0, 0.0];
    let k_inv = k.try_inverse().ok_or(GridError::Intrinsics)?;
    for h in &hs {
        let (rotation, t) = pose_from_homography(&k_inv, h).ok_or(GridError::Intrinsics)?;
        start.extend(rotation.scaled_axis().iter().chain(t.iter()));
    }
    let start = DVector::from_vec(start);
    // Parameter sizes for the finite differences: focal length for the intrinsics, 0.1 for the
    // distortion and the rotation (rad), the distance for the translation.
    let f = 0.5 * (k[(0, 0)] + k[(1, 1)]);
    let scale = DVector::from_fn(start.len(), |i, _| match i {
        0..4 => f,
        4..INTRINSICS => 0.1,
        _ if (i - INTRINSICS) % POSE < 3 => 0.1,
        _ => start[i].abs().max(layout.spacing_mm),
    });
    let residuals = |p: &DVector<f64>| reprojection_residuals(p, views, &target);
    let fit = lm::minimise(start, &scale, &residuals).ok_or(GridError::Refinement)?;
    let p = &fit.params;
    // The points measured, per view.
    let per_view: Vec<Vec<f64>> = point_distances(&residuals(p))
        .chunks(target.len())
        .zip(views)
        .map(|(d, v)| {
            d.iter()
                .zip(v)
                .filter(|(_, m)| m[0].is_finite())
                .map(|(d, _)| *d)
                .collect()
        })
        .collect();
    let distances: Vec<f64> = per_view.concat();
    Ok(GridCalibration {
        fx_px: p[0],
        fy_px: p[1],
        cx_px: p[2],
        cy_px: p[3],
        distortion: Distortion::from_array([p[4], p[5], p[6], p[7], 0.0]),
        poses: (0..views.len()).map(|v| pose_of(p, v)).collect(),
        rms_px: per_view.iter().map(|d| rms(d)).collect(),
        max_px: per_view
            .iter()
            .map(|d| d.iter().copied().fold(0.0, f64::max))
            .collect(),
        overall_rms_px: rms(&distances),
        iterations: fit.iterations,
    })
}

/// Per view, the largest distance (px) between the centre of a disc's image and the image of
/// its centre (CONVENTIONS.md C6) for discs of `radius_mm` under the calibration's poses (the
/// lens's distortion left out: it moves both alike to first order).
pub fn perspective_bias_px(cal: &GridCalibration, layout: &GridLayout, radius_mm: f64) -> Vec<f64> {
    let k = cal.k();
    let target = layout.points_mm();
    cal.poses
        .iter()
        .map(|(rotation, t)| {
            let r = rotation.matrix();
            let h = k * Matrix3::from_columns(&[r.column(0).into_owned(), r.column(1).into_owned(), *t]);
            target
                .iter()
                .filter_map(|&c| homography::imaged_circle_centre(&h, c, radius_mm))
                .map(|(centre, image)| (centre[0] - image[0]).hypot(centre[1] - image[1]))
                .fold(0.0, f64::max)
        })
        .collect()
}

fn pose_of(p: &DVector<f64>, view: usize) -> (Rotation3<f64>, Vector3<f64>) {
    let o = INTRINSICS + POSE * view;
    (
        Rotation3::new(Vector3::new(p[o], p[o + 1], p[o + 2])),
        Vector3::new(p[o + 3], p[o + 4], p[o + 5]),
    )
}

/// Every view's (du, dv) per point, stacked.
fn reprojection_residuals(p: &DVector<f64>, views: &[Vec<[f64; 2]>], target: &[[f64; 2]]) -> DVector<f64> {
    let distortion = Distortion::from_array([p[4], p[5], p[6], p[7], 0.0]);
    let mut r = DVector::zeros(2 * target.len() * views.len());
    for (v, points) in views.iter().enumerate() {
        let (rotation, t) = pose_of(p, v);
        for (k, (x, m)) in target.iter().zip(points).enumerate() {
            let c = rotation * Vector3::new(x[0], x[1], 0.0) + t;
            let [xd, yd] = distortion.apply([c.x / c.z, c.y / c.z]);
            let i = 2 * (v * target.len() + k);
            if m[0].is_finite() {
                r[i] = p[0] * xd + p[2] - m[0];
                r[i + 1] = p[1] * yd + p[3] - m[1];
            }
        }
    }
    r
}

/// Zhang's closed form for the intrinsics with zero skew, from homographies target -> image,
/// conditioned by mapping the image to about [-1, 1] first.
fn closed_form_intrinsics(hs: &[Matrix3<f64>], width: u32, height: u32) -> Result<Matrix3<f64>, GridError> {
    let s = 0.5 * (width + height) as f64;
    let (cx, cy) = (0.5 * width as f64, 0.5 * height as f64);
    let n = Matrix3::new(1.0 / s, 0.0, -cx / s, 0.0, 1.0 / s, -cy / s, 0.0, 0.0, 1.0);
    // v_ij^T b = h_i^T B h_j over b = (B11, B12, B22, B13, B23, B33).
    let v = |h: &Matrix3<f64>, i: usize, j: usize| {
        let (a, b) = (h.column(i), h.column(j));
        SVector::<f64, 6>::from([
            a[0] * b[0],
            a[0] * b[1] + a[1] * b[0],
            a[1] * b[1],
            a[2] * b[0] + a[0] * b[2],
            a[2] * b[1] + a[1] * b[2],
            a[2] * b[2],
        ])
    };
    let mut vtv = SMatrix::<f64, 6, 6>::zeros();
    for h in hs {
        let h = n * h;
        let h = h / h.norm();
        for row in [v(&h, 0, 1), v(&h, 0, 0) - v(&h, 1, 1)] {
            vtv += row * row.transpose();
        }
    }
    // Zero skew: B12 = 0, as one more equation with a large weight.
    let skew = SVector::<f64, 6>::from([0.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
    vtv += 1e3 * vtv.norm() * skew * skew.transpose();
    let eig = nalgebra::SymmetricEigen::new(vtv);
    let k_min = (0..6)
        .min_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]))
        .ok_or(GridError::Intrinsics)?;
    let b = eig.eigenvectors.column(k_min);
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let den = b11 * b22 - b12 * b12;
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha = (lambda / b11).sqrt();
    let beta = (lambda * b11 / den).sqrt();
    let u0 = -b13 * alpha * alpha / lambda;
    let kn = Matrix3::new(alpha, 0.0, u0, 0.0, beta, v0, 0.0, 0.0, 1.0);
    let k = n.try_inverse().ok_or(GridError::Intrinsics)? * kn;
    match k.iter().all(|x| x.is_finite()) && alpha > 0.0 && beta > 0.0 {
        true => Ok(k),
        false => Err(GridError::Intrinsics),
    }
}

/// A view's pose from its homography: `K^-1 H = lambda [r1 r2 t]`, the rotation made
/// orthonormal, the target in front of the camera.
fn pose_from_homography(k_inv: &Matrix3<f64>, h: &Matrix3<f64>) -> Option<(Rotation3<f64>, Vector3<f64>)> {
    let a = k_inv * h;
    let mut lambda = 1.0 / a.column(0).norm();
    if a[(2, 2)] * lambda < 0.0 {
        lambda = -lambda;
    }
    let (r1, r2) = (a.column(0) * lambda, a.column(1) * lambda);
    let t = a.column(2) * lambda;
    let r = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    let svd = r.try_svd(true, true, 1e-12, 100)?;
    let mut rotation = svd.u? * svd.v_t?;
    if rotation.determinant() < 0.0 {
        rotation = -rotation;
    }
    Some((Rotation3::from_matrix_unchecked(rotation), t.into_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Views of the grid through a known camera (with distortion) are calibrated back to it,
    /// with zero residual.
    #[test]
    fn recovers_a_known_camera() {
        let layout = GridLayout {
            cols: 10,
            rows: 10,
            spacing_mm: 25.4,
        };
        let target = layout.points_mm();
        let distortion = Distortion::from_array([-0.12, 0.05, 0.001, -0.0008, 0.0]);
        let (fx, fy, cx, cy) = (560.0, 555.0, 318.0, 245.0);
        let views: Vec<Vec<[f64; 2]>> = [
            [0.1, -0.2, 0.05],
            [-0.3, 0.1, 0.2],
            [0.25, 0.3, -0.1],
            [0.0, -0.35, 1.2],
            [-0.2, -0.2, -0.6],
        ]
        .iter()
        .enumerate()
        .map(|(k, rv)| {
            let rotation = Rotation3::new(Vector3::from(*rv));
            let t = Vector3::new(-110.0 + 10.0 * k as f64, -100.0, 600.0 + 40.0 * k as f64);
            target
                .iter()
                .map(|x| {
                    let c = rotation * Vector3::new(x[0], x[1], 0.0) + t;
                    let [xd, yd] = distortion.apply([c.x / c.z, c.y / c.z]);
                    [fx * xd + cx, fy * yd + cy]
                })
                .collect()
        })
        .collect();
        let cal = calibrate(&views, &layout, 640, 480).unwrap();
        assert!(cal.overall_rms_px < 1e-4, "{}", cal.overall_rms_px);
        assert!(
            (cal.fx_px - fx).abs() < 0.01 && (cal.cy_px - cy).abs() < 0.01,
            "{cal:?}"
        );
        assert!(
            (cal.distortion.k1 - distortion.k1).abs() < 1e-4,
            "{:?}",
            cal.distortion
        );
        let bias = perspective_bias_px(&cal, &layout, 5.0);
        assert!(bias.iter().all(|&b| b > 0.0 && b < 0.5), "{bias:?}");
    }
}
