//! A disc's centre from its edge profile, the profile's shape estimated from the disc's own
//! pixels: no point-spread shape, width, sharpening or tone curve assumed.
//!
//! The coverage-weighted centroid of [`super::blurred`] is unbiased for any symmetric point
//! spread, but every pixel of its window weighs alike in the centre's noise, those deep in the
//! tail (little signal, the background's full noise, the widest lever arm) too. Here each pixel
//! weighs by how much its level moves when the centre does: the slope of the disc's radial
//! profile where the pixel lies. The profile is measured, not modelled: the coverage averaged
//! in thin elliptical rings (the disc's own shape) about the current centre. A disc blurred by
//! any point-symmetric spread is point-symmetric about its centre, and so is a profile taken
//! about that centre: the fit's step is zero there, whatever the profile's shape.

use super::Coverage;
use deckwatch_common::image::GrayView;

/// Width of one ring of the measured profile (px): a blurred edge changes little within it,
/// and a ring at a 4 px radius holds about 12 pixels.
const PROFILE_RING_PX: f64 = 0.5;
/// At most this many rings (a wider annulus takes wider rings).
const MAX_RINGS: usize = 96;
/// The fit stops when its step is below this (px): the fit converges about quadratically, and
/// the step after one this short moves the centre by about a thousandth of a pixel...
const PROFILE_CONVERGED_PX: f64 = 2e-2;
/// ... within this many steps; a fit still moving after them gives no centre.
const PROFILE_MAX_STEPS: usize = 5;
/// A centre further than this from where the fit started (px) is not this disc's (a neighbour,
/// a cut): no centre. The pixels are gathered once, this much inside the window.
const PROFILE_MAX_DRIFT_PX: f64 = 0.5;
/// The profile is fitted only where it may slope: from this many deviations of the edge's
/// blur inside the disc's edge (and a pixel more) outward; deeper pixels tell nothing of the
/// centre and only cost time.
const PROFILE_INNER_PER_EDGE_SIGMA: f64 = 3.0;
/// ... and out to as far as the window reaches (3 deviations beyond the edge, less the drift),
/// at most this many deviations and a pixel beyond the edge.
const PROFILE_OUTER_PER_EDGE_SIGMA: f64 = 3.5;

/// The centre from the edge profile, and its deviation (px, per axis) from the fit's own
/// residual: the pixels' noise as measured about the disc, the shot noise of its bright
/// pixels and what the profile does not explain included.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ProfileCentre {
    pub(super) u: f64,
    pub(super) v: f64,
    pub(super) std_px: f64,
}

/// What [`edge_profile_centre`] fits: the disc's window and its shape.
pub(super) struct ProfileWindow<'a> {
    /// The disc's background and plateau (as its centroid was measured with).
    pub(super) coverage: &'a Coverage,
    /// The region the pixels may come from (half-open).
    pub(super) roi: (usize, usize, usize, usize),
    /// Where the fit starts (px).
    pub(super) start: (f64, f64),
    /// The window's radius about `start` (px): it holds the blur's tail.
    pub(super) reach_px: f64,
    /// The disc's second moments (its half-way mask's): xx, xy, yy (px^2).
    pub(super) moments: [f64; 3],
    /// The edge's blur, a deviation (px).
    pub(super) edge_sigma_px: f64,
}

/// The rings of a profile: even in rho^2 (no square root a pixel), [`PROFILE_RING_PX`] wide at
/// the disc's edge, from `inner_q` to `outer_q` (px^2).
struct Rings {
    inner_q: f64,
    outer_q: f64,
    inv_width_q: f64,
    count: usize,
}

impl Rings {
    /// The ring a pixel at `q` = rho^2 lies in, in ring widths from the inner edge; None
    /// outside the rings.
    #[inline(always)]
    fn position(&self, q: f64) -> Option<f64> {
        let t = (q - self.inner_q) * self.inv_width_q;
        (t >= 0.0 && q < self.outer_q).then_some(t)
    }
}

/// Sums of the coverage per ring, for the profile about one centre.
struct RingSums {
    sum: [f64; MAX_RINGS],
    count: [u32; MAX_RINGS],
}

impl RingSums {
    fn new() -> Self {
        Self {
            sum: [0.0; MAX_RINGS],
            count: [0; MAX_RINGS],
        }
    }

    #[inline(always)]
    fn add(&mut self, rings: &Rings, t: f64, c: f64) {
        let k = (t as usize).min(rings.count - 1);
        self.sum[k] += c;
        self.count[k] += 1;
    }

    /// The profile: each ring's mean (an empty ring takes the one inside it), and its slope
    /// per px^2 of rho^2. None when every ring is empty.
    fn profile(&self, rings: &Rings) -> Option<([f64; MAX_RINGS], [f64; MAX_RINGS])> {
        let n = rings.count;
        let first = self.count[..n].iter().position(|&c| c > 0)?;
        let mut level = [0.0; MAX_RINGS];
        let mut held = self.sum[first] / f64::from(self.count[first]);
        for ((l, &sum), &count) in level.iter_mut().zip(&self.sum).zip(&self.count).take(n) {
            if count > 0 {
                held = sum / f64::from(count);
            }
            *l = held;
        }
        let mut slope = [0.0; MAX_RINGS];
        for (k, s) in slope.iter_mut().enumerate().take(n) {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            *s = (level[b] - level[a]) * rings.inv_width_q / (b - a) as f64;
        }
        Some((level, slope))
    }
}

/// The centre of the disc of `window`: a Gauss-Newton fit of its two coordinates to the
/// pixels' coverage, the radial profile measured again about each step's centre (a step uses
/// the profile of the step before: one pass over the pixels a step). `pixels`: scratch space,
/// kept between calls. None when the fit does not settle on a disc.
pub(super) fn edge_profile_centre(
    frame: GrayView<'_>,
    window: &ProfileWindow<'_>,
    pixels: &mut Vec<[f32; 3]>,
) -> Option<ProfileCentre> {
    let [cxx, cxy, cyy] = window.moments;
    let det = cxx * cyy - cxy * cxy;
    if !(det > 0.0) || !window.reach_px.is_finite() {
        return None;
    }
    // The radius in the disc's own shape, in px at its mean radius: rho^2 = d' S d with S the
    // moments' inverse scaled to a unit determinant (a circle: S = I).
    let root = det.sqrt();
    let shape = [cyy / root, -cxy / root, cxx / root];
    let half_trace = 0.5 * (shape[0] + shape[2]);
    let least = half_trace - (half_trace * half_trace - 1.0).max(0.0).sqrt();
    let mean_radius_px = 2.0 * root.sqrt();
    let inner = (mean_radius_px - PROFILE_INNER_PER_EDGE_SIGMA * window.edge_sigma_px - 1.0).max(0.0);
    // The ellipse rho = outer lies in the window about any centre the fit may reach, and
    // holds the blur's tail as far as it slopes.
    let outer = ((window.reach_px - PROFILE_MAX_DRIFT_PX) * least.sqrt())
        .min(mean_radius_px + PROFILE_OUTER_PER_EDGE_SIGMA * window.edge_sigma_px + 1.0);
    if !(outer > inner + 4.0 * PROFILE_RING_PX) {
        return None;
    }
    let (inner_q, outer_q) = (inner * inner, outer * outer);
    let width_q = (2.0 * mean_radius_px * PROFILE_RING_PX).max((outer_q - inner_q) / MAX_RINGS as f64);
    let rings = Rings {
        inner_q,
        outer_q,
        inv_width_q: 1.0 / width_q,
        count: (((outer_q - inner_q) / width_q).ceil() as usize).clamp(2, MAX_RINGS),
    };
    // A drift of PROFILE_MAX_DRIFT_PX moves a pixel's rho by up to this much.
    let drift_rho = PROFILE_MAX_DRIFT_PX / least.sqrt();
    let mut sums = gather(frame, window, shape, &rings, drift_rho, pixels);

    let (mut ox, mut oy) = (0.0f64, 0.0f64);
    for _ in 0..PROFILE_MAX_STEPS {
        let (level, slope) = sums.profile(&rings)?;
        sums = RingSums::new();
        let (mut a00, mut a01, mut a11, mut b0, mut b1) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut squares, mut n) = (0.0, 0usize);
        for &[px, py, c] in pixels.iter() {
            let (dx, dy) = (f64::from(px) - ox, f64::from(py) - oy);
            let (sx, sy) = (shape[0] * dx + shape[1] * dy, shape[1] * dx + shape[2] * dy);
            let Some(t) = rings.position(dx * sx + dy * sy) else {
                continue;
            };
            let c = f64::from(c);
            sums.add(&rings, t, c);
            // Linear between the rings' middles.
            let t = (t - 0.5).clamp(0.0, (rings.count - 1) as f64);
            let k = (t as usize).min(rings.count - 2);
            let f = t - k as f64;
            let residual = c - (level[k] + f * (level[k + 1] - level[k]));
            // Moving the centre by e moves rho^2 by -2 (S d) . e.
            let d = -2.0 * (slope[k] + f * (slope[k + 1] - slope[k]));
            let (jx, jy) = (d * sx, d * sy);
            a00 += jx * jx;
            a01 += jx * jy;
            a11 += jy * jy;
            b0 += jx * residual;
            b1 += jy * residual;
            squares += residual * residual;
            n += 1;
        }
        let det = a00 * a11 - a01 * a01;
        if !(det > 0.0) || n <= rings.count + 2 {
            return None;
        }
        let (ex, ey) = ((a11 * b0 - a01 * b1) / det, (a00 * b1 - a01 * b0) / det);
        let moved = ex.hypot(ey);
        (ox, oy) = (ox + ex, oy + ey);
        if !(ox.hypot(oy) <= PROFILE_MAX_DRIFT_PX) {
            return None;
        }
        // Per axis: the mean of the two variances, the residual's variance over the pixels
        // less the profile's rings and the two coordinates.
        let variance = squares / (n - rings.count - 2) as f64;
        let centre = ProfileCentre {
            u: window.start.0 + ox,
            v: window.start.1 + oy,
            std_px: (variance * 0.5 * (a00 + a11) / det).sqrt(),
        };
        // A residual of exactly zero (no noise at all) states no deviation: no weight can
        // follow from it.
        if !(centre.std_px.is_finite() && centre.std_px > 0.0) {
            return None;
        }
        if moved < PROFILE_CONVERGED_PX {
            return Some(centre);
        }
    }
    None
}

/// The pixels of the window's circle about its start (inside its region) whose radius in the
/// disc's shape lies within the rings, widened by what the fit's drift may move it
/// (`drift_rho`): their offsets from the start and their coverage; and the ring sums about
/// the start.
fn gather(
    frame: GrayView<'_>,
    window: &ProfileWindow<'_>,
    shape: [f64; 3],
    rings: &Rings,
    drift_rho: f64,
    pixels: &mut Vec<[f32; 3]>,
) -> RingSums {
    pixels.clear();
    let mut sums = RingSums::new();
    let (x0, y0, x1, y1) = window.roi;
    let ((cx, cy), reach) = (window.start, window.reach_px);
    let (inner, outer) = (rings.inner_q.sqrt() - drift_rho, rings.outer_q.sqrt() + drift_rho);
    let (inner2, outer2) = (inner.max(0.0).powi(2), outer * outer);
    let ya = (cy - reach).ceil().max(y0 as f64) as usize;
    let yb = (cy + reach).floor().min(y1 as f64 - 1.0);
    if yb < ya as f64 {
        return sums;
    }
    for y in ya..=yb as usize {
        let dy = y as f64 - cy;
        let half = (reach * reach - dy * dy).max(0.0).sqrt();
        let xa = (cx - half).ceil().max(x0 as f64) as usize;
        let xb = (cx + half).floor().min(x1 as f64 - 1.0);
        if xb < xa as f64 {
            continue;
        }
        let row = window.coverage.row(y);
        for (x, &pixel) in (xa..=xb as usize).zip(&frame.row(y)[xa..=xb as usize]) {
            let dx = x as f64 - cx;
            let q = dx * (shape[0] * dx + shape[1] * dy) + dy * (shape[1] * dx + shape[2] * dy);
            if q >= inner2 && q <= outer2 {
                let c = row.unclamped(x, pixel);
                pixels.push([dx as f32, dy as f32, c as f32]);
                if let Some(t) = rings.position(q) {
                    sums.add(rings, t, f64::from(c as f32));
                }
            }
        }
    }
    sums
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::GrayImage;

    const SIDE: usize = 48;

    /// A disc of radius `r` at `(u, v)` on 40 DN, 150 DN brighter, its edge a Gaussian of 2 px
    /// (8 x 8 samples a pixel), rounded to 8 bits.
    fn blurred_disc(u: f64, v: f64, r: f64) -> GrayImage {
        let mut img = GrayImage::new(SIDE, SIDE);
        for (i, p) in img.data.iter_mut().enumerate() {
            let (x, y) = ((i % SIDE) as f64, (i / SIDE) as f64);
            let cover: f64 = (0..64)
                .map(|k| {
                    let d =
                        (x + ((k % 8) as f64 - 3.5) / 8.0 - u).hypot(y + ((k / 8) as f64 - 3.5) / 8.0 - v);
                    0.5 * libm_erfc((d - r) / (2.0 * std::f64::consts::SQRT_2))
                })
                .sum::<f64>()
                / 64.0;
            *p = (40.0 + 150.0 * cover).round() as u8;
        }
        img
    }

    /// erfc by Abramowitz and Stegun 7.1.26 (1.5e-7): enough for a test's picture.
    fn libm_erfc(x: f64) -> f64 {
        let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
        let poly = t
            * (0.254_829_592
                + t * (-0.284_496_736 + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
        let e = poly * (-x * x).exp();
        if x >= 0.0 {
            e
        } else {
            2.0 - e
        }
    }

    fn fit(
        img: &GrayImage,
        start: (f64, f64),
        roi: (usize, usize, usize, usize),
        moments: [f64; 3],
        reach: f64,
    ) -> Option<ProfileCentre> {
        let coverage = Coverage::new([40.0, 0.0, 0.0], [190.0, 0.0, 0.0], (roi.0, roi.1), start);
        let window = ProfileWindow {
            coverage: &coverage,
            roi,
            start,
            reach_px: reach,
            moments,
            edge_sigma_px: 2.0,
        };
        edge_profile_centre(img.view(), &window, &mut Vec::new())
    }

    /// From a start 0.2 px off, the fit settles on the disc's centre (within 0.005 px) and
    /// states a positive, finite deviation; a circle of radius 6 px has moments r^2 / 4.
    #[test]
    fn the_fit_settles_on_the_centre_from_a_start_off_it() {
        let (u, v, r) = (23.37, 24.81, 6.0);
        let img = blurred_disc(u, v, r);
        let moments = [r * r / 4.0, 0.0, r * r / 4.0];
        let Some(c) = fit(&img, (u + 0.2, v - 0.15), (0, 0, SIDE, SIDE), moments, r + 7.0) else {
            panic!("the fit did not settle")
        };
        assert!((c.u - u).hypot(c.v - v) < 0.005, "{c:?} against ({u}, {v})");
        assert!(c.std_px.is_finite() && c.std_px > 0.0, "{c:?}");
    }

    /// Nothing to fit gives no centre, and no input panics: a flat frame, moments that are no
    /// ellipse's, a window too small for a profile, a region cut by the frame's border, and a
    /// start beyond the frame.
    #[test]
    fn degenerate_windows_give_no_centre_and_do_not_panic() {
        let flat = GrayImage::new(SIDE, SIDE);
        let disc = blurred_disc(23.5, 24.5, 6.0);
        let circle = [9.0, 0.0, 9.0];
        assert_eq!(fit(&flat, (23.5, 24.5), (0, 0, SIDE, SIDE), circle, 13.0), None);
        for moments in [
            [0.0; 3],
            [-1.0, 0.0, 9.0],
            [9.0, 9.0, 9.0],
            [f64::NAN, 0.0, 9.0],
            [f64::INFINITY, 0.0, 9.0],
        ] {
            assert_eq!(
                fit(&disc, (23.5, 24.5), (0, 0, SIDE, SIDE), moments, 13.0),
                None,
                "{moments:?}"
            );
        }
        for reach in [0.0, 1.0, -3.0, f64::NAN, f64::INFINITY] {
            assert_eq!(
                fit(&disc, (23.5, 24.5), (0, 0, SIDE, SIDE), circle, reach),
                None,
                "reach {reach}"
            );
        }
        // The region cut: whatever comes back is finite.
        for (start, roi) in [
            ((23.5, 24.5), (20, 0, SIDE, SIDE)),
            ((2.0, 3.0), (0, 0, SIDE, SIDE)),
            ((-40.0, 90.0), (0, 0, SIDE, SIDE)),
        ] {
            if let Some(c) = fit(&disc, start, roi, circle, 13.0) {
                assert!(c.u.is_finite() && c.v.is_finite() && c.std_px > 0.0, "{c:?}");
            }
        }
    }
}
