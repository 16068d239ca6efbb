//! The renderer's optics and textures: the blur kernel, each pixel's ray and its point on the deck,
//! vignetting gain, the undistortion grid, and the deck's and sea's procedural textures.

use super::*;

/// A Gaussian of standard deviation `sigma` (px) over +-3 sigma, summing to 1.
pub(super) fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    let r = (3.0 * sigma).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f64 = k.iter().sum();
    k.iter().map(|v| (v / sum) as f32).collect()
}

/// `dst` = `src` (w x h, row-major) convolved with the odd-length kernel `k` along x or y;
/// samples beyond the border count as 0.
#[inline(always)]
pub(super) fn convolve_axis(src: &[f32], dst: &mut [f32], w: usize, h: usize, k: &[f32], along_x: bool) {
    let r = k.len() / 2;
    // The taps in the same order as a per-pixel sum, but a whole row or run of a row at a
    // time, without a border test at every tap: the compiler vectorises these loops, which the
    // per-tap test kept it from (the blur was a fortieth of a trial frame's time).
    if along_x {
        for (src_row, dst_row) in src.chunks_exact(w).zip(dst.chunks_exact_mut(w)).take(h) {
            for (x, d) in dst_row.iter_mut().enumerate() {
                let from = x.saturating_sub(r);
                let to = (x + r + 1).min(w);
                let taps = &k[from + r - x..to + r - x];
                *d = taps
                    .iter()
                    .zip(&src_row[from..to])
                    .fold(0.0, |acc, (kv, s)| acc + kv * s);
            }
        }
    } else {
        for y in 0..h {
            let dst_row = &mut dst[y * w..(y + 1) * w];
            dst_row.fill(0.0);
            for (i, kv) in k.iter().enumerate() {
                let q = (y + i).wrapping_sub(r);
                if q < h {
                    for (d, s) in dst_row.iter_mut().zip(&src[q * w..(q + 1) * w]) {
                        *d += kv * s;
                    }
                }
            }
        }
    }
}

/// The viewing ray (x, y, 1) of a pixel (distorted pixel coordinates) and its change per pixel
/// along u and v: exact for a camera without distortion; with distortion, the lens model is
/// linearised over +-1/2 pixel (second-order error ~1e-7 px for usual lenses).
#[inline(always)]
pub(super) fn pixel_ray(
    camera: &CameraModel,
    u: f64,
    v: f64,
) -> Option<(Vector3<f64>, Vector3<f64>, Vector3<f64>)> {
    if camera.distortion.is_none() {
        return Some((
            Vector3::new((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0),
            Vector3::new(1.0 / camera.fx, 0.0, 0.0),
            Vector3::new(0.0, 1.0 / camera.fy, 0.0),
        ));
    }
    let c = camera.unproject([u, v])?;
    let (a, b) = (camera.unproject([u - 0.5, v])?, camera.unproject([u + 0.5, v])?);
    let (e, f) = (camera.unproject([u, v - 0.5])?, camera.unproject([u, v + 0.5])?);
    Some((
        Vector3::new(c[0], c[1], 1.0),
        Vector3::new(b[0] - a[0], b[1] - a[1], 0.0),
        Vector3::new(f[0] - e[0], f[1] - e[1], 0.0),
    ))
}

#[inline(always)]
pub(super) fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Homography from a viewing ray (x, y, 1) (normalised camera coordinates) to the deck plane:
/// `H (x, y, 1) = (X, Y, 1) / depth`. A deck point (X, Y, 0) is at
/// `p_cam = R_CW (R (X, Y, 0) - C) = A (X, Y, 1)` with `A = [R_CW R e1, R_CW R e2, -R_CW C]`.
#[inline(always)]
pub(super) fn ray_to_deck(s: &SceneGeometry) -> Option<Matrix3<f64>> {
    let a = Matrix3::from_columns(&[
        s.deck_to_camera(&Vector3::x()) - s.deck_to_camera(&Vector3::zeros()),
        s.deck_to_camera(&Vector3::y()) - s.deck_to_camera(&Vector3::zeros()),
        s.deck_to_camera(&Vector3::zeros()),
    ]);
    a.try_inverse()
}

/// Homography from undistorted pixel coordinates (u, v, 1) to the deck plane.
pub(super) fn pixel_to_deck(camera: &CameraModel, s: &SceneGeometry) -> Option<Matrix3<f64>> {
    let k_inv = Matrix3::new(
        1.0 / camera.fx,
        0.0,
        -camera.cx / camera.fx,
        0.0,
        1.0 / camera.fy,
        -camera.cy / camera.fy,
        0.0,
        0.0,
        1.0,
    );
    Some(ray_to_deck(s)? * k_inv)
}

/// Fixed-point unit of the gain map (gains stay below 1).
pub(super) const GAIN_ONE: f32 = 65535.0;

/// Illumination gradient (linear across the image) times cos^4 vignetting, per pixel.
pub(super) fn gain_map(camera: &CameraModel, o: &RenderOptions) -> Vec<u16> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let (gdx, gdy) = (o.illumination_direction.cos(), o.illumination_direction.sin());
    let diag = ((w * w + h * h) as f64).sqrt();
    let mut g = Vec::with_capacity(w * h);
    for y in 0..h {
        let yn = (y as f64 - camera.cy) / camera.fy;
        for x in 0..w {
            // t in [-1/2, 1/2] across the image along the gradient's direction.
            let t = ((x as f64 - w as f64 / 2.0) * gdx + (y as f64 - h as f64 / 2.0) * gdy) / diag;
            let light = 1.0 - o.illumination_gradient * (t + 0.5);
            let xn = (x as f64 - camera.cx) / camera.fx;
            let c2 = 1.0 / (1.0 + xn * xn + yn * yn);
            let vig = 1.0 - o.vignetting * (1.0 - c2 * c2);
            g.push(
                (light * vig * GAIN_ONE as f64)
                    .round()
                    .clamp(0.0, GAIN_ONE as f64) as u16,
            );
        }
    }
    g
}

/// Normalised undistorted coordinates of pixels on a coarse grid, bilinearly interpolated: the
/// background's map through a distorting lens (the discs use the exact model).
pub(super) struct UndistortGrid {
    pub(super) gw: usize,
    pub(super) grid: Vec<[f64; 2]>,
}

impl UndistortGrid {
    pub(super) fn new(camera: &CameraModel) -> Self {
        let gw = (camera.width as usize).div_ceil(UNDISTORT_STEP) + 2;
        let gh = (camera.height as usize).div_ceil(UNDISTORT_STEP) + 2;
        let mut grid = Vec::with_capacity(gw * gh);
        for gy in 0..gh {
            for gx in 0..gw {
                let uv = [(gx * UNDISTORT_STEP) as f64, (gy * UNDISTORT_STEP) as f64];
                // Beyond the model's valid field, fall back to the linear ray.
                grid.push(
                    camera
                        .unproject(uv)
                        .unwrap_or([(uv[0] - camera.cx) / camera.fx, (uv[1] - camera.cy) / camera.fy]),
                );
            }
        }
        Self { gw, grid }
    }

    /// The ray (x, y, 1) of pixel (x, y); x may be one past the last column.
    pub(super) fn ray(&self, x: usize, y: usize) -> Vector3<f64> {
        let (gx, gy) = (x / UNDISTORT_STEP, y / UNDISTORT_STEP);
        let tx = (x % UNDISTORT_STEP) as f64 / UNDISTORT_STEP as f64;
        let ty = (y % UNDISTORT_STEP) as f64 / UNDISTORT_STEP as f64;
        let g = |i: usize, j: usize| self.grid[j * self.gw + i];
        let (a, b, c, d) = (g(gx, gy), g(gx + 1, gy), g(gx, gy + 1), g(gx + 1, gy + 1));
        let lerp =
            |k: usize| (a[k] * (1.0 - tx) + b[k] * tx) * (1.0 - ty) + (c[k] * (1.0 - tx) + d[k] * tx) * ty;
        Vector3::new(lerp(0), lerp(1), 1.0)
    }
}

/// The deck and sea albedo textures with their placement.
pub(super) struct Textures<'a> {
    pub(super) half: f64,
    pub(super) deck_scale: f64,
    pub(super) sea_scale: f64,
    pub(super) deck: &'a [u8],
    pub(super) sea: &'a [u8],
    pub(super) deck_dn: f32,
    pub(super) sea_dn: f32,
    pub(super) amp: f32,
}

impl<'a> Textures<'a> {
    /// The deck's and the sea's textures placed and lit as `o` says.
    pub(super) fn placed(o: &RenderOptions, deck: &'a [u8], sea: &'a [u8]) -> Self {
        Self {
            half: o.deck_size_m / 2.0,
            deck_scale: TEX as f64 / o.deck_size_m,
            sea_scale: TEX as f64 / SEA_TILE_M,
            deck,
            sea,
            deck_dn: o.deck_dn as f32,
            sea_dn: o.sea_dn as f32,
            amp: o.texture as f32,
        }
    }

    /// Albedo (DN) at a deck-plane point: the deck square's texture, or the sea's.
    #[inline(always)]
    pub(super) fn albedo(&self, x: f64, y: f64) -> f32 {
        if x.abs() <= self.half && y.abs() <= self.half {
            let t = sample_clamped(
                self.deck,
                (x + self.half) * self.deck_scale,
                (y + self.half) * self.deck_scale,
            );
            self.deck_dn * (1.0 + self.amp * t)
        } else {
            let t = sample_wrapped(self.sea, x * self.sea_scale, y * self.sea_scale);
            self.sea_dn * (1.0 + self.amp * t)
        }
    }
}

/// Bilinear sample of a u8 texture whose bytes encode [-1, 1] as 0..=254 (a cache-friendly
/// 1 MB; 8 bits are plenty for a texture of at most 15 % contrast).
#[inline(always)]
pub(super) fn bilinear(tex: &[u8], x0: usize, y0: usize, x1: usize, y1: usize, fx: f32, fy: f32) -> f32 {
    let a = tex[y0 * TEX + x0] as f32;
    let b = tex[y0 * TEX + x1] as f32;
    let c = tex[y1 * TEX + x0] as f32;
    let d = tex[y1 * TEX + x1] as f32;
    let top = a + (b - a) * fx;
    let v = top + ((c + (d - c) * fx) - top) * fy;
    v * (1.0 / 127.0) - 1.0
}

#[inline(always)]
pub(super) fn sample_clamped(tex: &[u8], x: f64, y: f64) -> f32 {
    let max = (TEX - 1) as f64;
    let (x, y) = (x.clamp(0.0, max), y.clamp(0.0, max));
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(TEX - 1), (y0 + 1).min(TEX - 1));
    bilinear(
        tex,
        x0,
        y0,
        x1,
        y1,
        (x - x0 as f64) as f32,
        (y - y0 as f64) as f32,
    )
}

#[inline(always)]
pub(super) fn sample_wrapped(tex: &[u8], x: f64, y: f64) -> f32 {
    // The floor by truncation and a correction (`floor` and `%` on floats are calls into libm
    // without SSE4.1); beyond +-2^63 texels the cast saturates, which only shifts the pattern.
    let floor = |v: f64| (v as i64).saturating_sub((v < (v as i64) as f64) as i64);
    let (xf, yf) = (floor(x), floor(y));
    let (x0, y0) = (
        xf.rem_euclid(TEX as i64) as usize,
        yf.rem_euclid(TEX as i64) as usize,
    );
    let (x1, y1) = ((x0 + 1) % TEX, (y0 + 1) % TEX);
    // Clamped: where the cast saturated, the difference is no fraction.
    let frac = |v: f64, f: i64| (v - f as f64).clamp(0.0, 1.0) as f32;
    bilinear(tex, x0, y0, x1, y1, frac(x, xf), frac(y, yf))
}

/// A tileable value-noise texture (`n` x `n`, values roughly in [-1, 1]): octaves of random
/// lattice values, (cells across, amplitude), smoothly interpolated.
pub(super) fn value_noise(n: usize, seed: u64, octaves: &[(usize, f64)]) -> Vec<u8> {
    let mut tex = vec![0.0f32; n * n];
    let mut rng = SplitMix64::new(seed);
    for &(cells, amp) in octaves {
        let lattice: Vec<f64> = (0..cells * cells).map(|_| 2.0 * rng.next_f64() - 1.0).collect();
        let cell = n as f64 / cells as f64;
        for y in 0..n {
            let fy = y as f64 / cell;
            let (cy0, ty) = (fy.floor() as usize % cells, smooth(fy.fract()));
            let cy1 = (cy0 + 1) % cells;
            for x in 0..n {
                let fx = x as f64 / cell;
                let (cx0, tx) = (fx.floor() as usize % cells, smooth(fx.fract()));
                let cx1 = (cx0 + 1) % cells;
                let l = |i: usize, j: usize| lattice[j * cells + i];
                let top = l(cx0, cy0) + (l(cx1, cy0) - l(cx0, cy0)) * tx;
                let bottom = l(cx0, cy1) + (l(cx1, cy1) - l(cx0, cy1)) * tx;
                tex[y * n + x] += (amp * (top + (bottom - top) * ty)) as f32;
            }
        }
    }
    tex.iter()
        .map(|t| ((t.clamp(-1.0, 1.0) + 1.0) * 127.0).round() as u8)
        .collect()
}

pub(super) fn smooth(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}
