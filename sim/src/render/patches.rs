//! The markers' discs: each marker's coverage of the pixels of its patch (exact inside and
//! outside the disc, counted on an edge pixel's samples), averaged over the exposure, blurred.

use super::optics::*;
use super::{Exposure, Renderer};
use nalgebra::Vector3;

/// The marker-disc coverage of one marker's patch of the image.
#[derive(Debug, Default, Clone)]
pub(super) struct Patch {
    pub(super) x0: usize,
    pub(super) y0: usize,
    pub(super) w: usize,
    pub(super) h: usize,
    /// Coverage in [0, 1], row-major w x h.
    pub(super) cov: Vec<f32>,
    /// The glow: the coverage blurred by the halo's Gaussian (empty without a halo).
    pub(super) halo: Vec<f32>,
}

/// The share of an edge pixel's `n` x `n` samples (steps `su`, `sv` in the deck's homogeneous
/// coordinates from the pixel centre `b`, whose `z` is positive) that fall in the disc of squared
/// radius `rho2` around `centre`. Over one pixel the perspective map is affine to well below a
/// micrometre on the deck: each row of samples then leaves the disc where a quadratic in the
/// sample's index changes sign, so a row is counted from its two roots, not sample by sample
/// (the sample-by-sample count, a division each, was a third of a frame's time).
#[inline(always)]
pub(super) fn edge_coverage(
    b: Vector3<f64>,
    su: Vector3<f64>,
    sv: Vector3<f64>,
    centre: [f64; 2],
    rho2: f64,
    n: usize,
) -> f32 {
    let iz = 1.0 / b.z;
    let (px, py) = (b.x * iz, b.y * iz);
    // The deck point's change per sample step along u and along v.
    let ju = [(su.x - px * su.z) * iz, (su.y - py * su.z) * iz];
    let jv = [(sv.x - px * sv.z) * iz, (sv.y - py * sv.z) * iz];
    let half = 0.5 * (n as f64 - 1.0);
    let a = ju[0] * ju[0] + ju[1] * ju[1];
    let inv_a = 1.0 / a; // once per pixel, not two divisions per row
    let last = (n - 1) as f64;
    let mut inside = 0usize;
    for j in 0..n {
        let dv = j as f64 - half;
        // The row's first sample (index 0), relative to the centre.
        let c = [
            px - centre[0] + jv[0] * dv - ju[0] * half,
            py - centre[1] + jv[1] * dv - ju[1] * half,
        ];
        // |c + ju i|^2 <= rho2: a i^2 + 2 bq i + cq <= 0.
        let bq = c[0] * ju[0] + c[1] * ju[1];
        let cq = c[0] * c[0] + c[1] * c[1] - rho2;
        if !(a > 0.0) {
            inside += if cq <= 0.0 { n } else { 0 };
            continue;
        }
        let disc = bq * bq - a * cq;
        if disc < 0.0 {
            continue;
        }
        let root = disc.sqrt();
        // The first and the last sample index inside, clamped to the row first: the casts
        // truncate toward zero, which is ceil and floor for what the clamps leave (a call into
        // libm each, without SSE4.1, was a twentieth of a frame's time).
        let (from, to) = (
            ((-bq - root) * inv_a).clamp(0.0, last + 1.0),
            ((-bq + root) * inv_a).clamp(-1.0, last),
        );
        let lo = from as usize + (from > (from as usize) as f64) as usize;
        let hi = to as i64 - (to < (to as i64) as f64) as i64;
        if hi >= lo as i64 {
            inside += (hi - lo as i64) as usize + 1;
        }
    }
    inside as f32 / (n * n) as f32
}

impl Renderer {
    /// Disc coverage of every marker in its patch, averaged over the sub-exposures.
    #[inline(always)]
    pub(super) fn draw_patches(&mut self, exposure: &Exposure<'_>) {
        let camera = self.camera;
        let (w, h) = (camera.width as i64, camera.height as i64);
        let pad = (self.blur_kernel.len().max(self.halo_kernel.len()) / 2) as i64 + 2;
        let steps = exposure.steps();
        let n_sub = steps as f32;
        let n = self.options.supersample as usize;
        let inv_n = 1.0 / n as f64;
        for m in 0..self.deck.marker_count() {
            if self.options.occluded_marker == Some(m) {
                self.patches[m].w = 0; // an empty patch is not drawn
                self.patches[m].h = 0;
                continue;
            }
            let centre = self.deck.marker_position(m);
            let (mx, my) = (centre.x, centre.y);
            let rho = self.deck.disc_radius(m);
            // Bounding box of the disc's image over the exposure. A rolling shutter's rows see
            // other instants: the box is grown with the scenes of the rows it spans until it
            // covers them (twice is plenty: a disc moves a few pixels during the readout).
            let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
            let mut behind = false;
            let passes = if exposure.is_rolling() { 5 } else { 1 };
            for pass in 0..passes {
                let row = match pass {
                    0 => camera.cy,
                    _ if v0 > v1 => break,
                    p => v0 + (v1 - v0) * (p - 1) as f64 / 3.0,
                };
                for k in 0..steps {
                    let s = exposure.scene(&camera, row, k);
                    for k in 0..48 {
                        let a = std::f64::consts::TAU * k as f64 / 48.0;
                        let p = centre + Vector3::new(rho * a.cos(), rho * a.sin(), 0.0);
                        match s.project_deck_point(&camera, &p) {
                            Some([u, v]) => {
                                u0 = u0.min(u);
                                v0 = v0.min(v);
                                u1 = u1.max(u);
                                v1 = v1.max(v);
                            }
                            None => behind = true,
                        }
                    }
                }
            }
            let patch = &mut self.patches[m];
            patch.w = 0;
            patch.h = 0;
            if behind || !(u0 <= u1 && v0 <= v1) {
                continue; // off to infinity or behind the camera: not drawn
            }
            let x0 = ((u0.floor() as i64) - pad).clamp(0, w);
            let y0 = ((v0.floor() as i64) - pad).clamp(0, h);
            let x1 = ((u1.ceil() as i64) + pad + 1).clamp(0, w);
            let y1 = ((v1.ceil() as i64) + pad + 1).clamp(0, h);
            if x1 <= x0 || y1 <= y0 {
                continue;
            }
            let (pw, ph) = ((x1 - x0) as usize, (y1 - y0) as usize);
            patch.x0 = x0 as usize;
            patch.y0 = y0 as usize;
            patch.w = pw;
            patch.h = ph;
            patch.cov.clear();
            patch.cov.resize(pw * ph, 0.0);
            for sub in 0..steps {
                let (uc, vc) = ((x0 + x1) as f64 / 2.0, (y0 + y1) as f64 / 2.0);
                let Some(hm_centre) = ray_to_deck(&exposure.scene(&camera, vc, sub)) else {
                    continue;
                };
                // The pixel's footprint on the deck (half its diagonal extent), from the map's
                // derivatives at the patch centre, with 10 % margin for the change of scale
                // across the patch.
                let foot = {
                    let hm = hm_centre;
                    match pixel_ray(&camera, uc, vc) {
                        Some((ray, du, dv)) => {
                            let b = hm * ray;
                            let (su, sv) = (hm * du, hm * dv);
                            let at = |v: Vector3<f64>| [v.x / v.z, v.y / v.z];
                            if b.z > 0.0 && (b + su).z > 0.0 && (b + sv).z > 0.0 {
                                0.55 * (dist(at(b), at(b + su)) + dist(at(b), at(b + sv)))
                            } else {
                                f64::INFINITY
                            }
                        }
                        None => f64::INFINITY,
                    }
                };
                let inner2 = if rho > foot { (rho - foot).powi(2) } else { -1.0 };
                let outer2 = (rho + foot).powi(2);
                let rho2 = rho * rho;
                for py in 0..ph {
                    // A rolling shutter's row sees its own instant.
                    let hm = if exposure.is_rolling() {
                        match ray_to_deck(&exposure.scene(&camera, (y0 as usize + py) as f64, sub)) {
                            Some(hm) => hm,
                            None => continue,
                        }
                    } else {
                        hm_centre
                    };
                    for px in 0..pw {
                        let (u, v) = ((x0 as usize + px) as f64, (y0 as usize + py) as f64);
                        // Ray of the pixel centre and its change per pixel (exact without
                        // distortion; with it, the lens model linearised over the pixel).
                        let Some((ray, du, dv)) = pixel_ray(&camera, u, v) else {
                            continue;
                        };
                        let b = hm * ray;
                        if !(b.z > 0.0) {
                            continue;
                        }
                        let d2 = (b.x / b.z - mx).powi(2) + (b.y / b.z - my).powi(2);
                        let c = if d2 >= outer2 {
                            0.0
                        } else if d2 <= inner2 {
                            1.0
                        } else {
                            edge_coverage(b, hm * du * inv_n, hm * dv * inv_n, [mx, my], rho2, n)
                        };
                        patch.cov[py * pw + px] += c / n_sub;
                    }
                }
            }
        }
    }

    /// Separable Gaussian blur of each patch's coverage (the patch is padded by the kernel
    /// radius, so nothing is cut at its border but at the image's), and the halo's wider one.
    #[inline(always)]
    pub(super) fn blur_patches(&mut self) {
        for p in self.patches.iter_mut().filter(|p| p.w > 0) {
            p.halo.clear();
            if self.blur_kernel.len() > 1 {
                self.blur_tmp.clear();
                self.blur_tmp.resize(p.w * p.h, 0.0);
                convolve_axis(&p.cov, &mut self.blur_tmp, p.w, p.h, &self.blur_kernel, true);
                convolve_axis(&self.blur_tmp, &mut p.cov, p.w, p.h, &self.blur_kernel, false);
            }
            if !self.halo_kernel.is_empty() {
                self.blur_tmp.clear();
                self.blur_tmp.resize(p.w * p.h, 0.0);
                p.halo.resize(p.w * p.h, 0.0);
                convolve_axis(&p.cov, &mut self.blur_tmp, p.w, p.h, &self.halo_kernel, true);
                convolve_axis(&self.blur_tmp, &mut p.halo, p.w, p.h, &self.halo_kernel, false);
            }
        }
    }
}
