//! The lens models the tools write, mapped onto deckwatch's only one: Brown-Conrady with
//! `[k1, k2, p1, p2, k3]` (`common::Distortion`). OpenCV's longer vectors map when their extra
//! terms are zero; an equidistant fisheye is replaced by the Brown-Conrady lens that images the
//! same rays to the same pixels over the whole image, when one does within
//! [`MAX_EQUIDISTANT_DIFFERENCE_PX`].

use super::CalibrationProblem;
use deckwatch_common::Distortion;
use nalgebra::{DMatrix, DVector};

/// The largest pixel difference accepted between an equidistant lens and its Brown-Conrady
/// fit, anywhere on the image (px): far below what detection resolves, so the pipeline sees
/// the calibrated lens.
pub const MAX_EQUIDISTANT_DIFFERENCE_PX: f64 = 0.01;
/// Pixels sampled per image side for the fit, and (denser, to catch the fit's wiggles between
/// those) for the check.
const FIT_GRID: usize = 33;
const CHECK_GRID: usize = 129;
/// Steps over the field at which the models are checked to be monotonic (a lens model that
/// folds back images two rays to one pixel).
const MONOTONIC_STEPS: usize = 1024;
/// Bisection steps for an angle: 1.6 rad / 2^64 is far below a double's resolution.
const BISECTION_STEPS: usize = 64;

/// A lens as the file gives it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Lens {
    /// Brown-Conrady in OpenCV's order: `k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]`.
    OpenCv(Vec<f64>),
    /// Equidistant fisheye (OpenCV's `cv::fisheye`, Kalibr's and ROS's `equidistant`):
    /// `theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)`.
    Equidistant([f64; 4]),
}

/// The intrinsics a lens is imaged through (px).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pinhole {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// How well Brown-Conrady stands in for an equidistant lens.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EquidistantFit {
    /// The file's `[k1, k2, k3, k4]`.
    pub fisheye_coefficients: [f64; 4],
    /// The largest distance between the two models' pixels of one ray, over the image (px).
    pub max_difference_px: f64,
    /// The largest angle off the optical axis the image sees (deg).
    pub max_field_angle_deg: f64,
    /// Pixels at which the difference was measured (a grid over the whole image).
    pub checked_pixels: usize,
}

/// OpenCV's coefficients as deckwatch's five, when the terms beyond them are zero.
pub(crate) fn opencv_distortion(c: &[f64]) -> Result<Distortion, CalibrationProblem> {
    if ![4, 5, 8, 12, 14].contains(&c.len()) {
        return Err(CalibrationProblem::WrongShape {
            expected: "4, 5, 8, 12 or 14 coefficients (OpenCV's order k1 k2 p1 p2 k3 ...)".into(),
            found: format!("{}", c.len()),
        });
    }
    let nonzero = |range: std::ops::Range<usize>| c.get(range).filter(|s| s.iter().any(|&k| k != 0.0));
    if let Some(k) = nonzero(5..8) {
        return Err(CalibrationProblem::NotRepresentable(format!(
            "the rational model's denominator k4, k5, k6 = {k:?} is not zero; deckwatch's Brown-Conrady \
             lens has no denominator"
        )));
    }
    if let Some(s) = nonzero(8..12) {
        return Err(CalibrationProblem::NotRepresentable(format!(
            "the thin-prism terms s1..s4 = {s:?} are not zero; deckwatch's lens has none"
        )));
    }
    if let Some(t) = nonzero(12..14) {
        return Err(CalibrationProblem::NotRepresentable(format!(
            "the tilted-sensor terms tau_x, tau_y = {t:?} are not zero; deckwatch's sensor is not tilted"
        )));
    }
    Ok(Distortion {
        k1: c[0],
        k2: c[1],
        p1: c[2],
        p2: c[3],
        k3: c.get(4).copied().unwrap_or(0.0),
    })
}

/// theta_d of an equidistant lens at angle theta.
fn equidistant_theta_d(k: &[f64; 4], theta: f64) -> f64 {
    let t2 = theta * theta;
    theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
}

/// A pixel's ray: the ideal normalised point and how many px one unit of radial change moves
/// the pixel (fx and fy differ).
struct Ray {
    u: f64,
    v: f64,
    x: f64,
    y: f64,
    /// The ideal radius tan(theta) and the distorted one theta_d.
    r: f64,
    r_distorted: f64,
    px_per_radius: f64,
}

/// The rays of an n x n grid of pixels spanning the image to its outer edges.
fn grid_rays(p: &Pinhole, n: usize, theta_of: &dyn Fn(f64) -> f64) -> Vec<Ray> {
    let mut rays = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            let u = -0.5 + f64::from(p.width) * i as f64 / (n - 1) as f64;
            let v = -0.5 + f64::from(p.height) * j as f64 / (n - 1) as f64;
            let (xd, yd) = ((u - p.cx) / p.fx, (v - p.cy) / p.fy);
            let theta_d = xd.hypot(yd);
            let (r, x, y, px_per_radius) = if theta_d > 0.0 {
                let r = theta_of(theta_d).tan();
                let (c, s) = (xd / theta_d, yd / theta_d);
                (r, xd * r / theta_d, yd * r / theta_d, (p.fx * c).hypot(p.fy * s))
            } else {
                (0.0, 0.0, 0.0, 0.0)
            };
            rays.push(Ray {
                u,
                v,
                x,
                y,
                r,
                r_distorted: theta_d,
                px_per_radius,
            });
        }
    }
    rays
}

/// Fits Brown-Conrady `k1, k2, k3` (no tangential terms: the equidistant lens has none) to an
/// equidistant lens by least squares in pixels over the image, and measures the largest pixel
/// difference. Refuses a lens whose image reaches 90 deg off axis (no pinhole can), whose model
/// folds, or whose fit is off by more than [`MAX_EQUIDISTANT_DIFFERENCE_PX`] somewhere.
pub(crate) fn fit_equidistant(
    p: &Pinhole,
    k: [f64; 4],
) -> Result<(Distortion, EquidistantFit), CalibrationProblem> {
    // The image's largest distorted radius is at a corner.
    let (u_edges, v_edges) = (
        [-0.5, f64::from(p.width) - 0.5],
        [-0.5, f64::from(p.height) - 0.5],
    );
    let corner_theta_d = u_edges
        .iter()
        .flat_map(|&u| v_edges.map(|v| ((u - p.cx) / p.fx).hypot((v - p.cy) / p.fy)))
        .fold(0.0f64, f64::max);
    // Walk theta up from 0 until theta_d passes the corner's, checking the model does not fold.
    let quarter_turn = std::f64::consts::FRAC_PI_2;
    let mut theta_max = None;
    let mut previous = 0.0;
    for step in 1..=MONOTONIC_STEPS {
        let theta = quarter_turn * step as f64 / MONOTONIC_STEPS as f64;
        let theta_d = equidistant_theta_d(&k, theta);
        if !(theta_d > previous) {
            return Err(CalibrationProblem::NotRepresentable(format!(
                "the equidistant model folds back at {:.1} deg off axis, inside the image: its \
                 coefficients are not a lens",
                theta.to_degrees()
            )));
        }
        if theta_d >= corner_theta_d && step < MONOTONIC_STEPS {
            theta_max = Some(theta);
            break;
        }
        previous = theta_d;
    }
    let Some(theta_max) = theta_max else {
        return Err(CalibrationProblem::EquidistantTooWide);
    };
    // theta of a theta_d by bisection on [0, theta_max], where the model is monotonic.
    let theta_of = |theta_d: f64| {
        let (mut lo, mut hi) = (0.0, theta_max);
        for _ in 0..BISECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            if equidistant_theta_d(&k, mid) < theta_d {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    let fit_rays = grid_rays(p, FIT_GRID, &theta_of);
    let r_max = fit_rays.iter().map(|ray| ray.r).fold(0.0f64, f64::max);
    let distortion = if r_max > 1e-12 {
        fit_radial(&fit_rays, r_max)?
    } else {
        Distortion::NONE
    };
    let check_rays = grid_rays(p, CHECK_GRID, &theta_of);
    let max_difference_px = check_rays
        .iter()
        .map(|ray| {
            let [x, y] = distortion.apply([ray.x, ray.y]);
            (p.fx * x + p.cx - ray.u).hypot(p.fy * y + p.cy - ray.v)
        })
        .fold(0.0f64, f64::max);
    let fit = EquidistantFit {
        fisheye_coefficients: k,
        max_difference_px,
        max_field_angle_deg: theta_of(corner_theta_d).to_degrees(),
        checked_pixels: check_rays.len(),
    };
    if !(max_difference_px <= MAX_EQUIDISTANT_DIFFERENCE_PX) {
        return Err(CalibrationProblem::EquidistantDoesNotFit {
            max_difference_px,
            limit_px: MAX_EQUIDISTANT_DIFFERENCE_PX,
            max_field_angle_deg: fit.max_field_angle_deg,
        });
    }
    // The fitted lens must be monotonic too, or `Distortion::remove` has two answers.
    for step in 1..=MONOTONIC_STEPS {
        let r2 = (r_max * step as f64 / MONOTONIC_STEPS as f64).powi(2);
        let slope = 1.0 + r2 * (3.0 * distortion.k1 + r2 * (5.0 * distortion.k2 + r2 * 7.0 * distortion.k3));
        if !(slope > 0.0) {
            return Err(CalibrationProblem::NotRepresentable(
                "the Brown-Conrady fit to this equidistant lens folds back inside the image".into(),
            ));
        }
    }
    Ok((distortion, fit))
}

/// Least squares for `k1, k2, k3` of `r_d = r (1 + k1 r^2 + k2 r^4 + k3 r^6)`, residuals in px.
/// Columns in `r / r_max` keep the system well conditioned.
fn fit_radial(rays: &[Ray], r_max: f64) -> Result<Distortion, CalibrationProblem> {
    let a = DMatrix::from_fn(rays.len(), 3, |i, j| {
        let ray = &rays[i];
        ray.px_per_radius * ray.r * (ray.r / r_max).powi(2 * j as i32 + 2)
    });
    let b = DVector::from_fn(rays.len(), |i, _| {
        let ray = &rays[i];
        ray.px_per_radius * (ray.r_distorted - ray.r)
    });
    let svd = nalgebra::linalg::SVD::try_new(a, true, true, f64::EPSILON, 1000).ok_or_else(|| {
        CalibrationProblem::Numerical("the least-squares fit (SVD) did not converge".into())
    })?;
    let largest = svd.singular_values.max();
    let scaled = svd
        .solve(&b, 1e-13 * largest)
        .map_err(|e| CalibrationProblem::Numerical(format!("the least-squares fit failed: {e}")))?;
    Ok(Distortion {
        k1: scaled[0] / r_max.powi(2),
        k2: scaled[1] / r_max.powi(4),
        k3: scaled[2] / r_max.powi(6),
        ..Distortion::NONE
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vga(f: f64) -> Pinhole {
        Pinhole {
            width: 640,
            height: 480,
            fx: f,
            fy: f,
            cx: 319.5,
            cy: 239.5,
        }
    }

    #[test]
    fn opencv_vectors_map_when_their_extra_terms_are_zero() {
        let d = opencv_distortion(&[0.1, -0.2, 1e-3, -2e-3]).unwrap();
        assert_eq!(d.to_array(), [0.1, -0.2, 1e-3, -2e-3, 0.0]);
        let mut rational = vec![0.1, -0.2, 1e-3, -2e-3, 0.05, 0.0, 0.0, 0.0];
        assert_eq!(opencv_distortion(&rational).unwrap().k3, 0.05);
        rational[6] = 0.01;
        let e = opencv_distortion(&rational).unwrap_err().to_string();
        assert!(e.contains("k4, k5, k6 = [0.0, 0.01, 0.0]"), "{e}");
        let mut tilted = vec![0.0; 14];
        tilted[13] = 1e-3;
        assert!(opencv_distortion(&tilted)
            .unwrap_err()
            .to_string()
            .contains("tilted"));
        let mut prism = vec![0.0; 12];
        prism[9] = 1e-3;
        assert!(opencv_distortion(&prism)
            .unwrap_err()
            .to_string()
            .contains("thin-prism"));
        let e = opencv_distortion(&[0.1; 6]).unwrap_err().to_string();
        assert!(
            e.contains("4, 5, 8, 12 or 14 coefficients") && e.contains("found 6"),
            "{e}"
        );
    }

    #[test]
    fn a_narrow_equidistant_lens_fits_and_matches_its_rays() {
        let k = [0.02, -0.01, 0.0, 0.0];
        let p = vga(800.0);
        let (d, fit) = fit_equidistant(&p, k).unwrap();
        assert!(fit.max_difference_px < MAX_EQUIDISTANT_DIFFERENCE_PX, "{fit:?}");
        assert!((fit.max_field_angle_deg - 28.52).abs() < 0.05, "{fit:?}");
        // An independent ray: project through both models.
        let (x, y) = (0.21f64, -0.17f64);
        let r = x.hypot(y);
        let s = equidistant_theta_d(&k, r.atan()) / r;
        let [bx, by] = d.apply([x, y]);
        assert!(((bx - x * s) * p.fx).hypot((by - y * s) * p.fy) < 0.01);
    }

    #[test]
    fn a_wide_fisheye_is_refused_with_its_difference() {
        // Kalibr's example camera: 752x480, f = 461 px, about 55 deg off axis at the corners.
        let p = Pinhole {
            width: 752,
            height: 480,
            fx: 461.6,
            fy: 460.2,
            cx: 362.7,
            cy: 246.0,
        };
        match fit_equidistant(&p, [-0.01316, 0.05008, -0.04506, 0.01241]) {
            Err(CalibrationProblem::EquidistantDoesNotFit {
                max_difference_px,
                max_field_angle_deg,
                ..
            }) => {
                assert!(max_difference_px > 1.0, "{max_difference_px}");
                assert!(
                    (50.0..60.0).contains(&max_field_angle_deg),
                    "{max_field_angle_deg}"
                );
            }
            other => panic!("{other:?}"),
        }
        // 160 deg across: beyond any pinhole.
        let e = fit_equidistant(&vga(150.0), [0.0; 4]).unwrap_err();
        assert!(matches!(e, CalibrationProblem::EquidistantTooWide), "{e:?}");
        // Coefficients that fold back inside the image.
        let e = fit_equidistant(&vga(300.0), [-1.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(e.to_string().contains("folds back"), "{e}");
    }
}
