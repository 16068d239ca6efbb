//! Judging measured centres of a planar circle grid by geometry alone, for images without
//! ground truth (photographs of a printed calibration target): the residual of the centres to
//! the best plane-to-image homography of each view, and to one camera calibrated over all
//! views (pinhole, k1, k2, p1, p2; Zhang's closed form refined by Levenberg-Marquardt). The
//! same judge serves any detector's centres, so that two detectors compare on one geometry.

mod calibrate;
mod lm;
mod order;

pub use calibrate::{calibrate, perspective_bias_px, GridCalibration};
pub use order::order_grid;

use deckwatch_common::homography;
use nalgebra::{DVector, Matrix3};

/// A planar grid of `cols` x `rows` circles `spacing_mm` apart; point `(i, j)` is at
/// `(i * spacing_mm, j * spacing_mm)` on the target, stored row-major at `j * cols + i`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridLayout {
    pub cols: usize,
    pub rows: usize,
    pub spacing_mm: f64,
}

impl GridLayout {
    /// The grid's points on the target (mm), row-major.
    pub fn points_mm(&self) -> Vec<[f64; 2]> {
        (0..self.rows)
            .flat_map(|j| {
                (0..self.cols).map(move |i| [i as f64 * self.spacing_mm, j as f64 * self.spacing_mm])
            })
            .collect()
    }
}

/// Why a view could not be ordered or fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    #[error("{found} discs measured, the grid has {expected}")]
    TooFewDiscs { found: usize, expected: usize },
    #[error("no origin: no disc markedly larger than the others with two neighbours at an angle")]
    NoOrigin,
    #[error("only {found} of the grid's {expected} points ordered")]
    Incomplete { found: usize, expected: usize },
    #[error("the homography fit is degenerate")]
    Homography,
    #[error("view {view} has {found} points, the grid has {expected}")]
    ViewSize {
        view: usize,
        found: usize,
        expected: usize,
    },
    #[error("the closed-form intrinsics are not real (fewer than 3 views, or views too alike)")]
    Intrinsics,
    #[error("the least-squares refinement failed (residuals not finite)")]
    Refinement,
}

/// The best homography from the target (mm) to one view (px) and its residuals (px).
#[derive(Debug, Clone, PartialEq)]
pub struct HomographyFit {
    /// Target (mm) -> image (px), normalised so that `h[(2, 2)] = 1`.
    pub h: Matrix3<f64>,
    /// Per point, the distance from the homography's image of the point to the measured centre.
    pub residuals_px: Vec<f64>,
    pub rms_px: f64,
    pub max_px: f64,
}

/// The homography minimising the pixel residuals of `image_px` to the target's `target_mm`:
/// the normalised DLT, then Levenberg-Marquardt on its eight free entries.
pub fn fit_homography(target_mm: &[[f64; 2]], image_px: &[[f64; 2]]) -> Result<HomographyFit, GridError> {
    let dlt = homography::fit(target_mm, image_px).ok_or(GridError::Homography)?;
    let start = DVector::from_iterator(8, dlt.iter().take(8).copied().map(|v| v / dlt[(2, 2)]));
    // nalgebra is column-major: entries 0..8 of `iter` are h00 h10 h20 h01 h11 h21 h02 h12.
    let matrix = |p: &DVector<f64>| Matrix3::new(p[0], p[3], p[6], p[1], p[4], p[7], p[2], p[5], 1.0);
    let residuals = |p: &DVector<f64>| {
        let h = matrix(p);
        let mut r = DVector::zeros(2 * target_mm.len());
        for (k, (s, d)) in target_mm.iter().zip(image_px).enumerate() {
            let q = homography::apply(&h, *s).unwrap_or([f64::NAN; 2]);
            (r[2 * k], r[2 * k + 1]) = (q[0] - d[0], q[1] - d[1]);
        }
        r
    };
    let scale = start.map(|v| v.abs().max(1e-6));
    let fit = lm::minimise(start, &scale, &residuals).ok_or(GridError::Refinement)?;
    let h = matrix(&fit.params);
    let residuals_px = point_distances(&residuals(&fit.params));
    Ok(HomographyFit {
        h,
        rms_px: rms(&residuals_px),
        max_px: residuals_px.iter().copied().fold(0.0, f64::max),
        residuals_px,
    })
}

/// [`fit_homography`] of one view whose points are in the target's order, NaN where a point was
/// not measured: on the points measured.
pub fn fit_view_homography(target_mm: &[[f64; 2]], view_px: &[[f64; 2]]) -> Result<HomographyFit, GridError> {
    let (t, m): (Vec<[f64; 2]>, Vec<[f64; 2]>) = target_mm
        .iter()
        .zip(view_px)
        .filter(|(_, m)| m[0].is_finite())
        .map(|(t, m)| (*t, *m))
        .unzip();
    fit_homography(&t, &m)
}

/// The distances of stacked (du, dv) residual pairs.
fn point_distances(r: &DVector<f64>) -> Vec<f64> {
    r.as_slice().chunks(2).map(|d| d[0].hypot(d[1])).collect()
}

/// Root mean square of distances.
fn rms(d: &[f64]) -> f64 {
    (d.iter().map(|v| v * v).sum::<f64>() / d.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact projections of a grid through a homography, shuffled, with a large origin disc and
    /// two stray blobs: ordered back exactly, and fitted with zero residual.
    #[test]
    fn orders_and_fits_an_exact_view() {
        let layout = GridLayout {
            cols: 10,
            rows: 10,
            spacing_mm: 25.4,
        };
        let h = Matrix3::new(0.7, 0.1, 250.0, -0.05, 0.68, 120.0, 2e-4, 3e-4, 1.0);
        let truth: Vec<[f64; 2]> = layout
            .points_mm()
            .iter()
            .map(|p| homography::apply(&h, *p).unwrap())
            .collect();
        let mut centres = truth.clone();
        let mut radii = vec![4.0; centres.len()];
        radii[0] = 8.0;
        centres.extend([[20.0, 30.0], [600.0, 400.0]]);
        radii.extend([4.0, 4.0]);
        // A fixed shuffle.
        let order: Vec<usize> = (0..centres.len()).map(|k| (k * 37) % centres.len()).collect();
        let shuffled: Vec<[f64; 2]> = order.iter().map(|&k| centres[k]).collect();
        let shuffled_radii: Vec<f64> = order.iter().map(|&k| radii[k]).collect();
        let ordered = order_grid(&shuffled, &shuffled_radii, &layout).unwrap();
        assert_eq!(ordered, truth);
        let fit = fit_homography(&layout.points_mm(), &ordered).unwrap();
        assert!(fit.max_px < 1e-6, "{}", fit.max_px);
    }
}
