//! Ellipse through points: the paper's eq. (3) conic least squares (x^2 coefficient fixed to 1),
//! solved with faer, and the ellipse parameters with the corrections of CONVENTIONS.md C3.

pub use deckwatch_common::ellipse::Ellipse;
use faer::linalg::solvers::SolveLstsq;
use faer::Mat;
use std::f64::consts::{FRAC_PI_2, PI};

/// Why no ellipse could be fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EllipseFitError {
    /// Eq. (3) has 5 unknowns.
    TooFewPoints(usize),
    /// A coordinate is NaN or infinite.
    NonFinite,
    /// The points do not determine a conic (e.g. collinear, or all on a line pair).
    Degenerate,
    /// The fitted conic is a hyperbola, parabola or imaginary ellipse.
    NotAnEllipse,
}

impl std::fmt::Display for EllipseFitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewPoints(n) => write!(f, "{n} points; an ellipse needs at least 5"),
            Self::NonFinite => write!(f, "a point is not finite"),
            Self::Degenerate => write!(f, "the points do not determine a conic"),
            Self::NotAnEllipse => write!(f, "the fitted conic is not an ellipse"),
        }
    }
}

impl std::error::Error for EllipseFitError {}

/// The result of fitting: the ellipse and the conic `x^2 + b xy + c y^2 + d x + e y + f = 0`
/// (eq. (2) with a = 1) in the original coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EllipseFit {
    pub ellipse: Ellipse,
    /// `[a, b, c, d, e, f]` with `a = 1`.
    pub conic: [f64; 6],
}

impl EllipseFit {
    /// Least-squares conic through `points` (eq. (3)), then its ellipse parameters.
    ///
    /// The points are centred and scaled to unit RMS radius before the solve (and the conic is
    /// mapped back), so pixel and metre coordinates are equally well conditioned; with exact
    /// points the result is the same conic.
    pub fn fit(points: &[[f64; 2]]) -> Result<Self, EllipseFitError> {
        let n = points.len();
        if n < 5 {
            return Err(EllipseFitError::TooFewPoints(n));
        }
        if points.iter().any(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return Err(EllipseFitError::NonFinite);
        }
        let (mx, my) = points.iter().fold((0.0, 0.0), |(a, b), p| (a + p[0], b + p[1]));
        let (mx, my) = (mx / n as f64, my / n as f64);
        let rms = (points
            .iter()
            .map(|p| (p[0] - mx).powi(2) + (p[1] - my).powi(2))
            .sum::<f64>()
            / n as f64)
            .sqrt();
        if !(rms > 0.0) {
            return Err(EllipseFitError::Degenerate);
        }
        let s = 1.0 / rms;
        // Eq. (3): [xy, y^2, x, y, 1] [b', c', d', e', f']^T = -x^2.
        let a = Mat::from_fn(n, 5, |i, j| {
            let (x, y) = ((points[i][0] - mx) * s, (points[i][1] - my) * s);
            match j {
                0 => x * y,
                1 => y * y,
                2 => x,
                3 => y,
                _ => 1.0,
            }
        });
        let rhs = Mat::from_fn(n, 1, |i, _| -((points[i][0] - mx) * s).powi(2));
        let qr = a.col_piv_qr();
        // Rank check on R's diagonal (pivoted, so it decreases): the columns are O(1) here.
        let r = qr.thin_R();
        let r00 = r[(0, 0)].abs();
        if !(r00 > 0.0) || (0..5).any(|k| !(r[(k, k)].abs() > 1e-10 * r00)) {
            return Err(EllipseFitError::Degenerate);
        }
        let sol = qr.solve_lstsq(&rhs);
        let (b, c, d, e, f) = (sol[(0, 0)], sol[(1, 0)], sol[(2, 0)], sol[(3, 0)], sol[(4, 0)]);
        let ellipse_n = ellipse_from_conic([1.0, b, c, d, e, f])?;
        let ellipse = Ellipse {
            centre: [ellipse_n.centre[0] / s + mx, ellipse_n.centre[1] / s + my],
            semi_major: ellipse_n.semi_major / s,
            semi_minor: ellipse_n.semi_minor / s,
            angle: ellipse_n.angle,
        };
        // The conic in original coordinates: substitute x_n = s (x - mx), y_n = s (y - my) and
        // divide by s^2 so that a stays 1.
        let conic = {
            let (s2, x0, y0) = (s * s, mx, my);
            let cb = b;
            let cc = c;
            let cd = (-2.0 * x0 - b * y0) + d / s;
            let ce = (-b * x0 - 2.0 * c * y0) + e / s;
            let cf = x0 * x0 + b * x0 * y0 + c * y0 * y0 - (d * x0 + e * y0) / s + f / s2;
            [1.0, cb, cc, cd, ce, cf]
        };
        Ok(Self { ellipse, conic })
    }
}

/// Ellipse parameters of `a x^2 + b xy + c y^2 + d x + e y + f = 0`.
///
/// The paper's printed m, n, p, q are for `A x^2 + 2B xy + C y^2 + 2D x + 2E y + F`; the xy, x, y
/// coefficients are halved first, and its m (which has f where e belongs) is corrected. Since
/// p >= q by construction, eq. (4)'s cases are moot: the major axis's angle from +x is
/// `0.5 atan2(-b, c - a)` (full b), mapped into (-90, 90] deg.
pub fn ellipse_from_conic([a, b, c, d, e, f]: [f64; 6]) -> Result<Ellipse, EllipseFitError> {
    let (aa, bb, cc, dd, ee, ff) = (a, b / 2.0, c, d / 2.0, e / 2.0, f);
    let den = bb * bb - aa * cc;
    if !(den < 0.0) {
        return Err(EllipseFitError::NotAnEllipse);
    }
    let m = (cc * dd - bb * ee) / den;
    let n = (aa * ee - bb * dd) / den;
    let num = 2.0 * (aa * ee * ee + cc * dd * dd + ff * bb * bb - 2.0 * bb * dd * ee - aa * cc * ff);
    let root = ((aa - cc).powi(2) + 4.0 * bb * bb).sqrt();
    let p2 = num / (den * (root - (aa + cc)));
    let q2 = num / (den * (-root - (aa + cc)));
    if !(p2 > 0.0 && q2 > 0.0 && p2.is_finite() && q2.is_finite()) {
        return Err(EllipseFitError::NotAnEllipse);
    }
    let mut angle = 0.5 * (-b).atan2(c - a);
    if angle <= -FRAC_PI_2 {
        angle += PI; // atan2(-0, negative) = -pi: keep (-90, 90]
    }
    let (p, q) = (p2.sqrt(), q2.sqrt());
    Ok(Ellipse {
        centre: [m, n],
        semi_major: p.max(q),
        semi_minor: p.min(q),
        angle,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ellipse_points(e: &Ellipse, n: usize, phase: f64) -> Vec<[f64; 2]> {
        let (s, c) = e.angle.sin_cos();
        (0..n)
            .map(|k| {
                let t = phase + 2.0 * PI * k as f64 / n as f64;
                let (x, y) = (e.semi_major * t.cos(), e.semi_minor * t.sin());
                [e.centre[0] + c * x - s * y, e.centre[1] + s * x + c * y]
            })
            .collect()
    }

    fn assert_same(a: &Ellipse, b: &Ellipse, tol: f64) {
        assert!(
            (a.centre[0] - b.centre[0]).abs() < tol * (1.0 + b.centre[0].abs()),
            "{a:?} {b:?}"
        );
        assert!(
            (a.centre[1] - b.centre[1]).abs() < tol * (1.0 + b.centre[1].abs()),
            "{a:?} {b:?}"
        );
        assert!(
            (a.semi_major - b.semi_major).abs() < tol * b.semi_major,
            "{a:?} {b:?}"
        );
        assert!(
            (a.semi_minor - b.semi_minor).abs() < tol * b.semi_major,
            "{a:?} {b:?}"
        );
        // An axis direction is defined modulo 180 deg.
        let d = (a.angle - b.angle).rem_euclid(PI);
        assert!(d.min(PI - d) < tol, "{a:?} {b:?}");
    }

    #[test]
    fn recovers_exact_ellipses() {
        for angle_deg in [-89.0, -45.0, -10.0, 0.0, 3.0, 60.0, 90.0] {
            for (cx, cy, scale) in [(0.01, -0.02, 0.5), (1639.5, 1231.5, 400.0)] {
                let e = Ellipse {
                    centre: [cx, cy],
                    semi_major: scale,
                    semi_minor: scale * 0.8,
                    angle: f64::to_radians(angle_deg),
                };
                let fit = EllipseFit::fit(&ellipse_points(&e, 8, 0.3)).unwrap();
                assert_same(&fit.ellipse, &e, 1e-12);
                // The returned conic vanishes on the points.
                let [a, b, c, d, ee, f] = fit.conic;
                for p in ellipse_points(&e, 5, 1.1) {
                    let (x, y) = (p[0], p[1]);
                    let v = a * x * x + b * x * y + c * y * y + d * x + ee * y + f;
                    assert!(v.abs() < 1e-9 * (x * x + y * y + 1.0), "{v}");
                }
            }
        }
    }

    #[test]
    fn five_points_suffice_and_circle_works() {
        let e = Ellipse {
            centre: [0.0, 0.0],
            semi_major: 0.5,
            semi_minor: 0.5,
            angle: 0.0,
        };
        let fit = EllipseFit::fit(&ellipse_points(&e, 5, 0.0)).unwrap();
        assert!((fit.ellipse.semi_major - 0.5).abs() < 1e-14);
        assert!((fit.ellipse.semi_minor - 0.5).abs() < 1e-14);
    }

    #[test]
    fn degenerate_inputs_are_refused() {
        assert_eq!(
            EllipseFit::fit(&[[0.0, 0.0]; 4]).unwrap_err(),
            EllipseFitError::TooFewPoints(4)
        );
        assert_eq!(
            EllipseFit::fit(&[[1.0, 1.0]; 6]).unwrap_err(),
            EllipseFitError::Degenerate
        );
        let line: Vec<[f64; 2]> = (0..8).map(|i| [i as f64, 2.0 * i as f64]).collect();
        assert_eq!(EllipseFit::fit(&line).unwrap_err(), EllipseFitError::Degenerate);
        let mut pts = ellipse_points(
            &Ellipse {
                centre: [0.0, 0.0],
                semi_major: 1.0,
                semi_minor: 0.5,
                angle: 0.0,
            },
            6,
            0.0,
        );
        pts[2][0] = f64::NAN;
        assert_eq!(EllipseFit::fit(&pts).unwrap_err(), EllipseFitError::NonFinite);
        // Points on a hyperbola x^2 - y^2 = 1.
        let hyp: Vec<[f64; 2]> = [-2.0, -1.0, 0.0, 0.5, 1.0, 2.0]
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                let x = f64::cosh(t);
                [if i % 2 == 0 { x } else { -x }, f64::sinh(t)]
            })
            .collect();
        assert_eq!(EllipseFit::fit(&hyp).unwrap_err(), EllipseFitError::NotAnEllipse);
    }

    #[test]
    fn residual_is_distance_on_the_axes() {
        let e = Ellipse {
            centre: [1.0, 2.0],
            semi_major: 2.0,
            semi_minor: 1.0,
            angle: 0.0,
        };
        assert!((e.radial_residual([1.0 + 2.5, 2.0]) - 0.5).abs() < 1e-15);
        assert!((e.radial_residual([1.0, 2.0 + 0.9]) + 0.1).abs() < 1e-15);
        let b = e.boundary(16);
        assert_eq!(b.len(), 17);
        assert!(b.iter().all(|&p| e.radial_residual(p).abs() < 1e-12));
    }
}
