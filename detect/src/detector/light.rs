//! The light across the pattern, from the markers' own plateaus: what a blurred disc's plateau
//! slope is measured from.
//!
//! A blurred disc has no flat interior, so its plateau (the level full coverage reads as) is
//! its interior's mean level with a slope. Taken from the background around it (the region
//! border's plane, scaled by the disc's brightness over the background's), the slope carries
//! whatever is painted on the deck there: on the simulator's textured deck at 1640x1232 with a
//! 2 px blur that slope, the same under each marker in every frame, made a constant attitude
//! error of 0.05-0.08 deg (BENCHMARKS.md, "What the simulator's own 1640x1232 frames miss").
//! The discs are painted alike, so their levels differ mostly by the light: a plane fitted to
//! the log of the identified markers' levels gives each disc's slope without the deck's
//! texture. A plane only: the ring's markers lie on a circle, on which a vignetting's radial
//! term is a plane too, so the centre marker alone would set its curvature (a 0.5 % error in
//! its level put a radial slope error of 7e-5 per pixel, half the light's whole gradient, on
//! every ring marker).

use deckwatch_common::deck::MAX_MARKERS;

/// The light's log-level over the image: a plane through the markers' mean position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct LightModel {
    /// The markers' mean position (px) and mean log-level there.
    origin_px: (f64, f64),
    mean_log_level: f64,
    /// Per pixel in x and y: the relative change of the light (1/px).
    slope_per_px: (f64, f64),
}

/// Markers needed for the plane (after any is dropped).
const MIN_MARKERS: usize = 4;
/// The markers must spread at least this far (px, RMS) across their narrower direction for the
/// light's slope to be measured across them: an edge-on pattern says nothing of the light
/// across it.
const MIN_SPREAD_PX: f64 = 20.0;
/// A level at or above this (DN) may be clipped: not the light's.
const MAX_LEVEL_DN: f64 = 250.0;
/// A marker whose level is further than this from the plane (log, about 5 %) is not lit like
/// the others (a shadow, a glint, dirt on the disc): the furthest is dropped once and the
/// plane fitted again.
const MAX_LOG_RESIDUAL: f64 = 0.05;
/// No light changes by more than this share per pixel across a deck (1/px; the simulator's
/// strongest gradient and vignetting reach about 4e-4 at 1640x1232): a steeper fit is not the
/// light.
const MAX_SLOPE_PER_PX: f64 = 2e-3;

impl LightModel {
    /// Fits the model to markers' `(u, v, level)` (px, px, DN; the first `MAX_MARKERS`). None
    /// with fewer than `MIN_MARKERS` unclipped positive levels, too little spread, or a slope no
    /// light has. No allocation: it runs on every identified frame.
    pub(super) fn fit(markers: impl IntoIterator<Item = (f64, f64, f64)>) -> Option<Self> {
        let mut buffer = [(0.0, 0.0, 0.0); MAX_MARKERS];
        let mut n = 0;
        for m in markers
            .into_iter()
            .filter(|&(u, v, level)| u.is_finite() && v.is_finite() && level > 0.0 && level < MAX_LEVEL_DN)
            .take(MAX_MARKERS)
        {
            buffer[n] = m;
            n += 1;
        }
        let kept = &mut buffer[..n];
        let mut model = Self::plane(kept)?;
        let worst = kept
            .iter()
            .map(|&(u, v, level)| (level.ln() - model.log_level_at(u, v)).abs())
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, _)) = worst.filter(|w| w.1 > MAX_LOG_RESIDUAL) {
            kept.swap(i, n - 1);
            model = Self::plane(&kept[..n - 1])?;
        }
        let (gx, gy) = model.slope_per_px;
        (gx.hypot(gy) <= MAX_SLOPE_PER_PX).then_some(model)
    }

    /// The least-squares plane through the log-levels, about the markers' mean position.
    fn plane(markers: &[(f64, f64, f64)]) -> Option<Self> {
        let n = markers.len();
        if n < MIN_MARKERS {
            return None;
        }
        let (mu, mv) = markers
            .iter()
            .fold((0.0, 0.0), |(a, b), m| (a + m.0 / n as f64, b + m.1 / n as f64));
        let (mut sxx, mut syy, mut sxy, mut sxz, mut syz, mut sz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for &(u, v, level) in markers {
            let (x, y, z) = (u - mu, v - mv, level.ln());
            (sxx, syy, sxy) = (sxx + x * x, syy + y * y, sxy + x * y);
            (sxz, syz, sz) = (sxz + x * z, syz + y * z, sz + z);
        }
        // The spread's narrower direction: the smaller eigenvalue of its covariance.
        let narrow = 0.5 * (sxx + syy) - (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
        if !(narrow / n as f64 >= MIN_SPREAD_PX * MIN_SPREAD_PX) {
            return None;
        }
        // About the mean position the intercept separates: the slope from the 2x2 system.
        let det = sxx * syy - sxy * sxy;
        let slope_per_px = ((syy * sxz - sxy * syz) / det, (sxx * syz - sxy * sxz) / det);
        let model = Self {
            origin_px: (mu, mv),
            mean_log_level: sz / n as f64,
            slope_per_px,
        };
        (slope_per_px.0.is_finite() && slope_per_px.1.is_finite() && model.mean_log_level.is_finite())
            .then_some(model)
    }

    /// The plane's log-level at `(u, v)` (px).
    fn log_level_at(&self, u: f64, v: f64) -> f64 {
        let (gx, gy) = self.slope_per_px;
        self.mean_log_level + gx * (u - self.origin_px.0) + gy * (v - self.origin_px.1)
    }

    /// The light's relative change per pixel (the gradient of its log-level, 1/px; a plane's,
    /// the same everywhere).
    pub(super) fn relative_slope(&self) -> (f64, f64) {
        self.slope_per_px
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eight markers of the common size (the centre and seven of the ring: the bow is left out)
    /// lit by a known gradient, their levels with 0.3 % of noise: the slope comes back within
    /// a tenth of the gradient. A saturated level, a shadowed marker and too few or too close
    /// markers are handled.
    #[test]
    fn the_light_is_measured_from_the_markers_levels() {
        let gradient = (9e-5, -6e-5);
        let noise = [0.002, -0.003, 0.001, 0.003, -0.002, 0.0, -0.001, 0.002];
        let markers: Vec<(f64, f64, f64)> = (0..8)
            .map(|k| {
                let (u, v) = match k {
                    0 => (900.0, 500.0),
                    _ => {
                        let a = (k + 1) as f64 * std::f64::consts::TAU / 8.0;
                        (900.0 + 150.0 * a.cos(), 500.0 + 150.0 * a.sin())
                    }
                };
                let level = 180.0 * (gradient.0 * u + gradient.1 * v + noise[k]).exp();
                (u, v, level)
            })
            .collect();
        let close_to = |m: &LightModel| {
            let (gx, gy) = m.relative_slope();
            (gx - gradient.0).abs() < 1e-5 && (gy - gradient.1).abs() < 1e-5
        };
        let model = LightModel::fit(markers.iter().copied()).expect("eight markers");
        assert!(close_to(&model), "{model:?}");
        // A clipped level is left out; a marker 20 % darker (a shadow) is dropped.
        let mut odd = markers.clone();
        odd[3].2 = 255.0;
        odd[5].2 *= 0.8;
        assert!(
            close_to(&LightModel::fit(odd.iter().copied()).expect("six good markers")),
            "{odd:?}"
        );
        // Too few, too close, edge-on, or a level that is no light: no model.
        assert!(LightModel::fit(markers[..3].iter().copied()).is_none());
        let close: Vec<_> = markers
            .iter()
            .map(|m| (900.0 + 0.01 * m.0, 500.0 + 0.01 * m.1, m.2))
            .collect();
        assert!(LightModel::fit(close.iter().copied()).is_none());
        let edge_on: Vec<_> = markers.iter().map(|m| (m.0, 500.0 + 0.01 * m.1, m.2)).collect();
        assert!(LightModel::fit(edge_on.iter().copied()).is_none());
        let mut dark = markers.clone();
        for m in dark.iter_mut().take(5) {
            m.2 = 0.0;
        }
        assert!(LightModel::fit(dark.iter().copied()).is_none());
    }

    /// The simulator's deck at 1640x1232 through a 2 px blur, textured and not, the same pose,
    /// light and noise: once a frame has measured the light, every marker's centre is where the
    /// untextured frame puts it, to the texture's noise. With the slope of the region border's
    /// plane scaled to the disc (before), the texture moved one by 0.36 px, the same in every
    /// frame.
    #[test]
    fn a_blurred_discs_plateau_slope_is_the_lights_not_the_decks_texture() {
        use crate::{Detector, DetectorConfig};
        use deckwatch_common::{CameraModel, DeckLayout, GrayImage};
        use deckwatch_sim::{FrameSimulator, RenderOptions, Renderer, Scenario};
        let cam = CameraModel::rpi_v2().scaled_to(1640, 1232);
        let deck = DeckLayout::paper();
        let centres = |texture: f64| {
            let options = RenderOptions {
                optical_blur_px: 2.0,
                texture,
                ..RenderOptions::realistic()
            };
            let r = Renderer::new(cam, deck, options, 5).unwrap();
            let mut sim = FrameSimulator::new(Scenario::Ship.profile(5, 1.0), r, 1.0, 0.0, 1, 5).unwrap();
            let mut det = Detector::new(cam, deck, DetectorConfig::for_camera(&cam, &deck));
            let mut frame = GrayImage::new(1640, 1232);
            let mut sets = Vec::new();
            for k in 0..2 {
                sim.render_frame(k, &mut frame.view_mut()).unwrap();
                sets.push(det.detect(frame.view()));
            }
            sets
        };
        let (textured, flat) = (centres(0.3), centres(0.0));
        for (a, b) in textured.iter().zip(&flat) {
            assert_eq!((a.count, b.count), (9, 9));
        }
        let moved = |k: usize| {
            textured[k]
                .markers
                .iter()
                .zip(&flat[k].markers)
                .take(9)
                .map(|(a, b)| (a.u - b.u).hypot(a.v - b.v))
                .fold(0.0, f64::max)
        };
        // Measured: 0.040 px (before: 0.364; the first frame, before the light is measured: 0.038).
        assert!(moved(1) < 0.1, "the texture moved a centre by {} px", moved(1));
    }
}
