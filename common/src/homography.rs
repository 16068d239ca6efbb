//! Plane-to-image homographies: the normalised DLT fit, and the image of a circle.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// Applies `h` to a point; None at infinity.
pub fn apply(h: &Matrix3<f64>, [x, y]: [f64; 2]) -> Option<[f64; 2]> {
    let p = h * Vector3::new(x, y, 1.0);
    (p.z.abs() > 1e-300).then(|| [p.x / p.z, p.y / p.z])
}

/// Hartley normalisation: centroid to the origin, RMS distance sqrt(2).
fn normaliser(pts: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    let n = pts.len() as f64;
    let (mx, my) = pts.iter().fold((0.0, 0.0), |(a, b), p| (a + p[0], b + p[1]));
    let (mx, my) = (mx / n, my / n);
    let rms = (pts
        .iter()
        .map(|p| (p[0] - mx).powi(2) + (p[1] - my).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    if !(rms > 0.0) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / rms;
    Some(Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0))
}

/// The homography taking `src[i]` to `dst[i]` (least squares on the normalised DLT, >= 4
/// pairs); None for degenerate input.
pub fn fit(src: &[[f64; 2]], dst: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    if src.len() != dst.len() || src.len() < 4 {
        return None;
    }
    let (ts, td) = (normaliser(src)?, normaliser(dst)?);
    // A^T A accumulated row by row (fixed size: no allocation); the null vector of the DLT
    // system A h = 0 is its eigenvector with the smallest eigenvalue.
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (s, d) in src.iter().zip(dst) {
        let p = ts * Vector3::new(s[0], s[1], 1.0);
        let q = td * Vector3::new(d[0], d[1], 1.0);
        let (x, y, u, v) = (p.x, p.y, q.x, q.y);
        for row in [
            SVector::<f64, 9>::from([-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]),
            SVector::<f64, 9>::from([0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]),
        ] {
            ata += row * row.transpose();
        }
    }
    let eig = nalgebra::SymmetricEigen::new(ata);
    let k = (0..9).min_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]))?;
    let hv = eig.eigenvectors.column(k);
    let hn = Matrix3::new(hv[0], hv[1], hv[2], hv[3], hv[4], hv[5], hv[6], hv[7], hv[8]);
    let h = td.try_inverse()? * hn * ts;
    let h = h / h[(2, 2)];
    h.iter().all(|v| v.is_finite()).then_some(h)
}

/// RMS of |h(src) - dst| (pixels when dst are pixels).
pub fn rms_residual(h: &Matrix3<f64>, src: &[[f64; 2]], dst: &[[f64; 2]]) -> f64 {
    let ss: f64 = src
        .iter()
        .zip(dst)
        .map(|(s, d)| apply(h, *s).map_or(f64::INFINITY, |p| (p[0] - d[0]).powi(2) + (p[1] - d[1]).powi(2)))
        .sum();
    (ss / src.len().max(1) as f64).sqrt()
}

/// The centre of the image (under `h`) of the circle of radius `r` around `c`, and the image of
/// `c` itself. They differ: perspective moves the centre of an imaged disc away from the image
/// of the disc's centre (CONVENTIONS.md C6).
pub fn imaged_circle_centre(h: &Matrix3<f64>, c: [f64; 2], r: f64) -> Option<([f64; 2], [f64; 2])> {
    let circle = Matrix3::new(
        1.0,
        0.0,
        -c[0],
        0.0,
        1.0,
        -c[1],
        -c[0],
        -c[1],
        c[0] * c[0] + c[1] * c[1] - r * r,
    );
    let hi = h.try_inverse()?;
    let q = hi.transpose() * circle * hi;
    // Centre of the conic: [[A, B], [B, C]] x = -[D, E].
    let det = q[(0, 0)] * q[(1, 1)] - q[(0, 1)] * q[(1, 0)];
    if !(det.abs() > 0.0) {
        return None;
    }
    let x = (-q[(0, 2)] * q[(1, 1)] + q[(1, 2)] * q[(0, 1)]) / det;
    let y = (-q[(1, 2)] * q[(0, 0)] + q[(0, 2)] * q[(1, 0)]) / det;
    Some(([x, y], apply(h, c)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exact_homography() {
        let h = Matrix3::new(520.0, 30.0, 320.0, -12.0, 500.0, 240.0, 0.05, -0.08, 1.0);
        let src: Vec<[f64; 2]> = (0..9)
            .map(|i| [(i as f64 * 0.7).cos() * 0.5, (i as f64 * 0.7).sin() * 0.5])
            .collect();
        let dst: Vec<[f64; 2]> = src.iter().map(|s| apply(&h, *s).unwrap()).collect();
        let f = fit(&src, &dst).unwrap();
        assert!((f - h).abs().max() < 1e-8 * h.abs().max(), "{f}");
        assert!(rms_residual(&f, &src, &dst) < 1e-9);
        assert!(fit(&src[..3], &dst[..3]).is_none());
        assert!(fit(&[[0.0, 0.0]; 5], &dst[..5]).is_none());
    }

    #[test]
    fn circle_centre_shift_vanishes_for_an_affine_map_and_not_for_perspective() {
        let affine = Matrix3::new(500.0, 20.0, 300.0, -10.0, 450.0, 200.0, 0.0, 0.0, 1.0);
        let (centre, image) = imaged_circle_centre(&affine, [0.3, 0.1], 0.05).unwrap();
        assert!((centre[0] - image[0]).abs() < 1e-9 && (centre[1] - image[1]).abs() < 1e-9);
        let persp = Matrix3::new(500.0, 20.0, 300.0, -10.0, 450.0, 200.0, 0.1, 0.05, 1.0);
        let (centre, image) = imaged_circle_centre(&persp, [0.3, 0.1], 0.05).unwrap();
        let shift = ((centre[0] - image[0]).powi(2) + (centre[1] - image[1]).powi(2)).sqrt();
        assert!(shift > 1e-3, "{shift}");
    }
}
