//! The one pass over the frame: the background's albedo (exact near the markers, bilinear
//! between exact samples elsewhere), the marker patches over it, light falloff, noise and
//! quantisation; then the glints.

use super::optics::*;
use super::{
    Exposure, Renderer, BACKGROUND_STEP, DRAW_STEPS_PER_SIGMA, EXACT_MARGIN_PX, MAX_CHUNK, NORMAL_DRAWS, TEX,
};
use crate::rng::SplitMix64;
use deckwatch_common::image::GrayViewMut;
use deckwatch_common::SceneGeometry;
use nalgebra::{Matrix3, Vector3};
use std::sync::OnceLock;

/// `out` from `left` in steps of `step` per pixel: the background between two exact samples.
/// Blocks of eight against a constant ramp: the compiler vectorises that, where converting each
/// index to a float went lane by lane (the fill was a fourteenth of a trial frame's time).
#[inline(always)]
pub(super) fn fill_linear(out: &mut [f32], left: f32, step: f32) {
    const RAMP: [f32; 8] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
    for (k, block) in out.chunks_mut(RAMP.len()).enumerate() {
        let start = left + step * (k * RAMP.len()) as f32;
        for (a, r) in block.iter_mut().zip(RAMP) {
            *a = start + step * r;
        }
    }
}

/// A signal (DN) as the nearest 8-bit value, clipped to 0-255. Rounded by adding 1.5 x 2^23,
/// which leaves the nearest integer in the low bits of the sum: plain arithmetic that the
/// compiler vectorises, where a float-to-integer cast went lane by lane (a fifth of a trial
/// frame's time).
#[inline(always)]
pub(super) fn quantised(signal_dn: f32) -> u8 {
    const ROUNDER: f32 = 12_582_912.0;
    (signal_dn.clamp(0.0, 255.0) + ROUNDER).to_bits() as u8
}

/// The process's table of standard normal draws, made once, in steps of 1/`DRAW_STEPS_PER_SIGMA`
/// (a byte each: 1 MB). A frame's row
/// reads its noise from a window of it at a random place: rows and frames get different noise,
/// which repeats only where two windows happen to overlap (about one pair of rows in 800 of a
/// 640 px frame, shifted; no pattern a detector could lock on to).
pub(super) fn normal_draws() -> &'static [i8] {
    static DRAWS: OnceLock<Vec<i8>> = OnceLock::new();
    DRAWS.get_or_init(|| {
        // The inverse normal CDF at 4096 evenly spaced levels (within +-3.5), indexed by 12
        // random bits.
        const LEVELS: usize = 1 << 12;
        let levels: Vec<i8> = (0..LEVELS)
            .map(|i| {
                let z = deckwatch_common::stats::normal_quantile((i as f64 + 0.5) / LEVELS as f64);
                (z * DRAW_STEPS_PER_SIGMA as f64).round() as i8
            })
            .collect();
        let mut rng = SplitMix64::new(0x000D_15EA_5E0F_5EED);
        (0..NORMAL_DRAWS)
            .map(|_| levels[(rng.next_u64() >> 52) as usize])
            .collect()
    })
}

/// A region near a marker where the background's albedo is exact on a lattice of every
/// `chunk`-th pixel both ways (the global lattice's points within it).
#[derive(Debug, Clone, Copy)]
pub(super) struct ExactRegion {
    /// x0, y0, x1, y1 (pixels; x1, y1 excluded).
    pub(super) rect: [usize; 4],
    /// The lattice's first column and row, and its width (points).
    pub(super) first_gx: usize,
    pub(super) first_gy: usize,
    pub(super) lattice_w: usize,
    /// Where its lattice starts in `Renderer::lattice` (row-major).
    pub(super) offset: usize,
}

impl Renderer {
    /// Saturated specular spots (drawn last: a glint clips whatever is under it).
    #[inline(always)]
    pub(super) fn draw_glints(&self, noise_seed: u64, out: &mut GrayViewMut<'_>) {
        let mut rng = SplitMix64::new(noise_seed ^ 0x0006_11A7_5EED);
        let (w, h) = (out.width() as f64, out.height() as f64);
        for _ in 0..self.options.glints {
            let (cu, cv) = (rng.next_f64() * w, rng.next_f64() * h);
            let r = 2.0 + 38.0 * rng.next_f64().powi(2);
            let (y0, y1) = (
                (cv - r).floor().max(0.0) as usize,
                ((cv + r).ceil().min(h - 1.0)) as usize,
            );
            let (x0, x1) = (
                (cu - r).floor().max(0.0) as usize,
                ((cu + r).ceil().min(w - 1.0)) as usize,
            );
            for y in y0..=y1 {
                let row = out.row_mut(y);
                for (x, px) in row.iter_mut().enumerate().take(x1 + 1).skip(x0) {
                    let d = ((x as f64 - cu).powi(2) + (y as f64 - cv).powi(2)).sqrt();
                    // One pixel of soft edge.
                    let c = (r + 0.5 - d).clamp(0.0, 1.0);
                    if c > 0.0 {
                        *px = (*px as f64 + c * (250.0 - *px as f64)).round() as u8;
                    }
                }
            }
        }
    }

    /// The one pass over the frame: background albedo through the homography, marker patches,
    /// light falloff, noise, quantisation.
    #[inline(always)]
    pub(super) fn composite(
        &mut self,
        h_px: &Matrix3<f64>,
        scene: &SceneGeometry,
        exposure: &Exposure<'_>,
        noise_seed: u64,
        out: &mut GrayViewMut<'_>,
    ) {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        let o = &self.options;
        let (sea_dn, marker_dn) = (o.sea_dn as f32, o.marker_dn as f32);
        let halo_dn = (o.halo * o.marker_dn) as f32;
        let tex = Textures::placed(o, &self.deck_tex, &self.sea_tex);
        let ray_h = ray_to_deck(scene);
        // Pixels per two texels at the image centre -> the interpolation step (1, 2, 4 or 8).
        let chunk = {
            let c = h_px * Vector3::new(self.camera.cx, self.camera.cy, 1.0);
            let d = h_px * Vector3::new(self.camera.cx + 1.0, self.camera.cy, 1.0);
            let metres_per_px = ((c.x / c.z - d.x / d.z).powi(2) + (c.y / c.z - d.y / d.z).powi(2)).sqrt();
            let px_per_two_texels = 2.0 * o.deck_size_m / TEX as f64 / metres_per_px;
            // The largest power of two not above it (NaN compares false: 1).
            let mut chunk = 1;
            while chunk < MAX_CHUNK && (2 * chunk) as f64 <= px_per_two_texels {
                chunk *= 2;
            }
            chunk
        };
        let rolling = exposure.is_rolling();
        // The maps of row `y`: a rolling shutter's row sees the scene of its own instant.
        let maps_at = |y: usize| -> (Matrix3<f64>, Option<Matrix3<f64>>) {
            if rolling {
                let s = exposure.mid(&self.camera, y as f64);
                match pixel_to_deck(&self.camera, &s) {
                    Some(hp) => (hp, ray_to_deck(&s)),
                    None => (*h_px, None),
                }
            } else {
                (*h_px, ray_h)
            }
        };
        let (undistort, tex) = (self.undistort_grid.as_ref(), &tex);
        // Row y's sampler: without distortion the map is affine along a row in homogeneous
        // coordinates (the row's start plus x times the first column).
        let row_sampler = |maps: (Matrix3<f64>, Option<Matrix3<f64>>), y: usize| {
            let base = maps.0 * Vector3::new(0.0, y as f64, 1.0);
            let step = maps.0.column(0).into_owned();
            move |x: usize| -> f32 {
                let p = match (undistort, &maps.1) {
                    (None, _) => base + step * x as f64,
                    (Some(grid), Some(rh)) => rh * grid.ray(x, y),
                    (Some(_), None) => return sea_dn,
                };
                if p.z > 0.0 {
                    let iz = 1.0 / p.z;
                    tex.albedo(p.x * iz, p.y * iz)
                } else {
                    sea_dn // beyond the horizon
                }
            }
        };
        // The background's albedo, exact on a grid of every `BACKGROUND_STEP` pixels both ways
        // and bilinear between, away from the markers; near them (each marker's patch and a
        // margin around it, where the detector measures the disc and the deck beside it) exact
        // on a finer lattice, every `chunk`-th pixel both ways, as everywhere before (mapping
        // every pixel or two of the frame took half a trial frame's time; docs/history.md, "Faster trials").
        let step_px = BACKGROUND_STEP;
        let grid_w = w.div_ceil(step_px) + 1;
        let grid_row = |gy: usize, out: &mut Vec<f32>| {
            let y = (gy * step_px).min(h);
            let albedo_at = row_sampler(maps_at(y), y);
            out.clear();
            out.extend((0..grid_w).map(|gx| albedo_at((gx * step_px).min(w))));
        };
        let mut upper = std::mem::take(&mut self.grid_upper);
        let mut lower = std::mem::take(&mut self.grid_lower);
        let mut band = None;
        // Each marker's exact region: its patch and a margin (half its size, at least
        // `EXACT_MARGIN_PX`) around it.
        let mut near_markers = std::mem::take(&mut self.near_markers);
        near_markers.clear();
        let mut lattice = std::mem::take(&mut self.lattice);
        lattice.clear();
        for p in self.patches.iter().filter(|p| p.w > 0) {
            let margin = EXACT_MARGIN_PX.max(p.w.max(p.h) / 2);
            let rect = [
                p.x0.saturating_sub(margin),
                p.y0.saturating_sub(margin),
                (p.x0 + p.w + margin).min(w),
                (p.y0 + p.h + margin).min(h),
            ];
            // The exact albedo on the lattice points that cover the region. Between them,
            // bilinear: the chunk spans at most two texels (a slight smoothing of the finest
            // texture octave) and the perspective map's curvature over it is far below a
            // micrometre on the deck. (Exact on every row, linear only along it, these samples
            // were a fifth of the renderer's time.) Where regions overlap, both compute the
            // same points.
            let region = ExactRegion {
                rect,
                first_gx: rect[0] / chunk,
                first_gy: rect[1] / chunk,
                lattice_w: rect[2].div_ceil(chunk) - rect[0] / chunk + 1,
                offset: lattice.len(),
            };
            for gy in region.first_gy..=rect[3].div_ceil(chunk) {
                let y = (gy * chunk).min(h);
                let albedo_at = row_sampler(maps_at(y), y);
                let columns = region.first_gx..region.first_gx + region.lattice_w;
                lattice.extend(columns.map(|gx| albedo_at((gx * chunk).min(w))));
            }
            near_markers.push(region);
        }
        let noisy = o.read_noise_dn > 0.0 || o.shot_noise_dn > 0.0;
        let (read_var, shot_var_per_dn) =
            ((o.read_noise_dn * o.read_noise_dn) as f32, o.shot_noise_dn as f32);
        let mut rng = SplitMix64::new(noise_seed);
        for y in 0..h {
            let gy = y / step_px;
            if band != Some(gy) {
                // The band below the last one starts on the last one's lower grid row.
                if band.map(|b| b + 1) == Some(gy) {
                    std::mem::swap(&mut upper, &mut lower);
                } else {
                    grid_row(gy, &mut upper);
                }
                grid_row(gy + 1, &mut lower);
                band = Some(gy);
            }
            // Between the band's two grid rows, then along the row.
            let ty = (y - gy * step_px) as f32 / step_px as f32;
            for (gx, x0) in (0..w).step_by(step_px).enumerate() {
                let left = upper[gx] + (lower[gx] - upper[gx]) * ty;
                let right = upper[gx + 1] + (lower[gx + 1] - upper[gx + 1]) * ty;
                let end = (x0 + step_px).min(w);
                fill_linear(
                    &mut self.row_signal[x0..end],
                    left,
                    (right - left) / step_px as f32,
                );
            }
            // Near the markers: bilinear between the lattice's exact points (where regions
            // overlap, both write the same values).
            let lty = (y % chunk) as f32 / chunk as f32;
            for r in near_markers.iter().filter(|r| y >= r.rect[1] && y < r.rect[3]) {
                let upper = r.offset + (y / chunk - r.first_gy) * r.lattice_w;
                let (upper, lower) = (
                    &lattice[upper..upper + r.lattice_w],
                    &lattice[upper + r.lattice_w..upper + 2 * r.lattice_w],
                );
                let at = |i: usize| upper[i] + (lower[i] - upper[i]) * lty;
                let mut x = r.rect[0];
                while x < r.rect[2] {
                    let gx = x / chunk;
                    let end = ((gx + 1) * chunk).min(r.rect[2]);
                    let i = gx - r.first_gx;
                    let (left, right) = (at(i), at(i + 1));
                    let step = (right - left) / chunk as f32;
                    fill_linear(
                        &mut self.row_signal[x..end],
                        left + step * (x - gx * chunk) as f32,
                        step,
                    );
                    x = end;
                }
            }
            // Marker discs over the background (over each other where patches overlap).
            for p in self
                .patches
                .iter()
                .filter(|p| p.w > 0 && y >= p.y0 && y < p.y0 + p.h)
            {
                let row = (y - p.y0) * p.w..(y - p.y0 + 1) * p.w;
                let sig = &mut self.row_signal[p.x0..p.x0 + p.w];
                for (s, c) in sig.iter_mut().zip(&p.cov[row.clone()]) {
                    *s += c.min(1.0) * (marker_dn - *s);
                }
                if !p.halo.is_empty() {
                    for (s, g) in sig.iter_mut().zip(&p.halo[row]) {
                        *s += halo_dn * g;
                    }
                }
            }
            // Light falloff (camera-fixed gain map), noise and quantisation in one pass.
            let row = out.row_mut(y);
            let gain = self.gain.as_ref().map(|g| &g[y * w..(y + 1) * w]);
            let lit = |s: f32, g: u16| s * (g as f32 * (1.0 / GAIN_ONE));
            let noisy_px = |s: f32, n: i8| {
                let sigma = (read_var + shot_var_per_dn * s.clamp(0.0, 255.0)).sqrt();
                quantised(s + sigma * (n as f32 * (1.0 / DRAW_STEPS_PER_SIGMA)))
            };
            if noisy {
                // The row's standard normal draws: a window of the process's table at a random
                // place (drawn pixel by pixel, they took a sixth of a trial frame's time).
                let draws = normal_draws();
                let start = (rng.next_u64() % (draws.len() - w + 1) as u64) as usize;
                let row_noise = &draws[start..start + w];
                match gain {
                    Some(gain) => {
                        for (((px, &s), &g), &n) in
                            row.iter_mut().zip(&self.row_signal).zip(gain).zip(row_noise)
                        {
                            *px = noisy_px(lit(s, g), n);
                        }
                    }
                    None => {
                        for ((px, &s), &n) in row.iter_mut().zip(&self.row_signal).zip(row_noise) {
                            *px = noisy_px(s, n);
                        }
                    }
                }
            } else {
                match gain {
                    Some(gain) => {
                        for ((px, &s), &g) in row.iter_mut().zip(&self.row_signal).zip(gain) {
                            *px = quantised(lit(s, g));
                        }
                    }
                    None => {
                        for (px, &s) in row.iter_mut().zip(&self.row_signal) {
                            *px = quantised(s);
                        }
                    }
                }
            }
        }
        self.grid_upper = upper;
        self.grid_lower = lower;
        self.near_markers = near_markers;
        self.lattice = lattice;
    }
}
