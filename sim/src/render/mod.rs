//! The image renderer of the simulator: 8-bit grayscale frames of the deck as the camera sees it.
//!
//! Every pixel is inverse-mapped to the deck plane through the homography of the current pose
//! (and through the lens model when it has distortion). The deck (a `deck_size_m` square) and the
//! sea around it have a procedural albedo texture; the marker discs are bright. Disc edges are
//! anti-aliased by supersampling each edge pixel (`supersample`^2 samples, each mapped exactly),
//! averaged over the sub-exposures of the motion-blur window, then blurred by a Gaussian (optical
//! blur). Illumination gradient, vignetting, shot and read noise are applied last. All of it
//! happens in one pass over the caller's buffer; buffers are allocated when the renderer is made
//! (or grow once when a marker appears larger than before), never per frame.
//!
//! Approximations, all far below a pixel: optical and motion blur act on the marker discs (where
//! the image has edges); the deck texture is band-limited (coarser than a few pixels) and is
//! neither blurred nor smeared.

use crate::rng::SplitMix64;
use deckwatch_common::image::{GrayViewMut, ImageError};
use deckwatch_common::{CameraModel, DeckLayout, InvalidField, SceneGeometry};
use nalgebra::{Matrix3, Vector3};

mod optics;

use optics::*;

/// What the renderer draws, and how.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Edge supersampling per axis (samples per edge pixel = supersample^2).
    pub supersample: u32,
    /// Standard deviation of the Gaussian optical blur, pixels (0 = sharp).
    pub optical_blur_px: f64,
    /// Signal of a marker disc at the image centre (digital numbers, 0-255).
    pub marker_dn: f64,
    /// Mean signal of the deck surface.
    pub deck_dn: f64,
    /// Mean signal of the sea around the deck.
    pub sea_dn: f64,
    /// Contrast of the deck and sea textures (relative amplitude, 0 = flat).
    pub texture: f64,
    /// Illumination falls off linearly across the image by this fraction (0 = even light)...
    pub illumination_gradient: f64,
    /// ...toward this direction in the image (radians from +u toward +v).
    pub illumination_direction: f64,
    /// Strength of cos^4 vignetting (0 = none, 1 = the full natural falloff).
    pub vignetting: f64,
    /// Read noise, standard deviation in DN.
    pub read_noise_dn: f64,
    /// Shot noise: variance in DN^2 per DN of signal (1 / conversion gain; 0 = none).
    pub shot_noise_dn: f64,
    /// Side of the square flight deck, metres (the paper: 10 m).
    pub deck_size_m: f64,
    /// A marker hidden under something deck-coloured (a person, a chock): not drawn.
    pub occluded_marker: Option<usize>,
    /// Specular glints per frame: saturated spots of 2-40 px radius at random places (seeded
    /// per frame), some of them marker-sized.
    pub glints: u32,
    /// A glow around each marker (the bloom and halo of a light at night): the light's
    /// coverage spread by a Gaussian, times this fraction of `marker_dn` (0 = none)...
    pub halo: f64,
    /// ...and its Gaussian spread in pixels.
    pub halo_px: f64,
}

impl Default for RenderOptions {
    /// A clean frame: sharp, noiseless, evenly lit, textured.
    fn default() -> Self {
        Self {
            supersample: 16,
            optical_blur_px: 0.0,
            marker_dn: 230.0,
            deck_dn: 70.0,
            sea_dn: 35.0,
            texture: 0.15,
            illumination_gradient: 0.0,
            illumination_direction: 0.0,
            vignetting: 0.0,
            read_noise_dn: 0.0,
            shot_noise_dn: 0.0,
            deck_size_m: 10.0,
            occluded_marker: None,
            glints: 0,
            halo: 0.0,
            halo_px: 0.0,
        }
    }
}

impl RenderOptions {
    /// A realistic camera frame: optical blur, shot and read noise of a small sensor, uneven
    /// light and a lens that vignettes.
    pub fn realistic() -> Self {
        Self {
            optical_blur_px: 0.8,
            illumination_gradient: 0.25,
            illumination_direction: 0.6,
            vignetting: 0.5,
            read_noise_dn: 1.5,
            shot_noise_dn: 0.25,
            ..Self::default()
        }
    }

    /// The deck at night: the markers are lights (overexposed: saturated cores), with a glow
    /// around them, on a dark deck and sea; a high gain (noisy) for a short exposure. The glow's
    /// spread is for a full-resolution (3280 px wide) image.
    pub fn night() -> Self {
        Self {
            optical_blur_px: 1.0,
            marker_dn: 900.0,
            deck_dn: 6.0,
            sea_dn: 2.0,
            texture: 0.3,
            vignetting: 0.5,
            read_noise_dn: 3.0,
            shot_noise_dn: 1.0,
            halo: 0.15,
            halo_px: 8.0,
            ..Self::default()
        }
    }

    /// Checks the options; the error names the field.
    pub fn validate(&self) -> Result<(), InvalidField> {
        if !(1..=64).contains(&self.supersample) {
            return Err(InvalidField::new(
                "supersample",
                format!("must be within 1..=64, got {}", self.supersample),
            ));
        }
        let fields = [
            ("optical_blur_px", self.optical_blur_px, 0.0, 20.0),
            // Lights overexpose: up to 16x the sensor's full scale, clipped to 255.
            ("marker_dn", self.marker_dn, 0.0, 4080.0),
            ("deck_dn", self.deck_dn, 0.0, 255.0),
            ("sea_dn", self.sea_dn, 0.0, 255.0),
            ("texture", self.texture, 0.0, 1.0),
            ("illumination_gradient", self.illumination_gradient, 0.0, 1.0),
            ("vignetting", self.vignetting, 0.0, 1.0),
            ("read_noise_dn", self.read_noise_dn, 0.0, 100.0),
            ("shot_noise_dn", self.shot_noise_dn, 0.0, 100.0),
            ("deck_size_m", self.deck_size_m, 0.0, 1e4),
            ("halo", self.halo, 0.0, 1.0),
            ("halo_px", self.halo_px, 0.0, 100.0),
        ];
        for (name, v, lo, hi) in fields {
            if !(v >= lo && v <= hi) {
                return Err(InvalidField::new(
                    name,
                    format!("must be within [{lo}, {hi}], got {v}"),
                ));
            }
        }
        if !self.illumination_direction.is_finite() {
            return Err(InvalidField::new("illumination_direction", "must be finite"));
        }
        Ok(())
    }
}

/// Why a frame could not be rendered.
#[derive(Debug, Clone, PartialEq)]
pub enum RenderError {
    /// The output view's size differs from the camera's.
    SizeMismatch {
        expected: (usize, usize),
        got: (usize, usize),
    },
    /// No sub-exposure was given, or a pose is not finite.
    InvalidScene,
    Image(ImageError),
}

impl std::fmt::Display for RenderError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::SizeMismatch { expected, got } => write!(
                f,
                "output is {}x{}, the camera is {}x{}",
                got.0, got.1, expected.0, expected.1
            ),
            Self::InvalidScene => write!(f, "no pose, or a pose that is not finite"),
            Self::Image(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RenderError {}

/// Texture side in texels; deck texels are `deck_size_m / TEX` metres.
const TEX: usize = 1024;
/// The sea texture tiles every this many metres.
const SEA_TILE_M: f64 = 16.0;
/// Gaussian table size (inverse CDF at (i + 0.5) / N): 12-bit indices, five per random word.
const GAUSS_BITS: u32 = 12;
/// Grid step (pixels) of the stored undistortion map used for the background.
const UNDISTORT_STEP: usize = 8;
/// Most background pixels between exact evaluations of the albedo.
const MAX_CHUNK: usize = 8;

/// The marker-disc coverage of one marker's patch of the image.
#[derive(Debug, Default, Clone)]
struct Patch {
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
    /// Coverage in [0, 1], row-major w x h.
    cov: Vec<f32>,
    /// The glow: the coverage blurred by the halo's Gaussian (empty without a halo).
    halo: Vec<f32>,
}

/// The scene over one frame's exposure, as the renderer samples it.
#[derive(Clone, Copy)]
pub enum Exposure<'a> {
    /// A global shutter: every row sees the same poses, at evenly spaced instants of the
    /// exposure window (one pose: no motion blur).
    Global(&'a [SceneGeometry]),
    /// A rolling shutter (`CameraModel::readout_s`): row `v` is exposed around its own instant
    /// `CameraModel::row_time_s(v)`; `scene_at(dt_s)` gives the scene `dt_s` after the frame's
    /// instant. The exposure window (`exposure_s`) is sampled at `steps` instants (1: no blur).
    Rolling {
        scene_at: &'a dyn Fn(f64) -> SceneGeometry,
        exposure_s: f64,
        steps: usize,
    },
}

impl Exposure<'_> {
    fn steps(&self) -> usize {
        match self {
            Self::Global(poses) => poses.len(),
            Self::Rolling { steps, .. } => *steps,
        }
    }

    fn is_rolling(&self) -> bool {
        matches!(self, Self::Rolling { .. })
    }

    /// The scene of sub-exposure `sub` as row `row` sees it.
    fn scene(&self, camera: &CameraModel, row: f64, sub: usize) -> SceneGeometry {
        match self {
            Self::Global(poses) => poses[sub],
            Self::Rolling {
                scene_at,
                exposure_s,
                steps,
            } => {
                let dt = if *steps <= 1 {
                    0.0
                } else {
                    exposure_s * (sub as f64 / (*steps - 1) as f64 - 0.5)
                };
                scene_at(camera.row_time_s(row) + dt)
            }
        }
    }

    /// The scene of the middle sub-exposure as row `row` sees it (the background's).
    fn mid(&self, camera: &CameraModel, row: f64) -> SceneGeometry {
        self.scene(camera, row, self.steps() / 2)
    }
}

/// Renders frames for one camera, deck and set of options.
pub struct Renderer {
    camera: CameraModel,
    deck: DeckLayout,
    options: RenderOptions,
    deck_tex: Vec<u8>,
    sea_tex: Vec<u8>,
    gauss: Vec<f32>,
    blur_kernel: Vec<f32>,
    /// The halo's Gaussian (empty: no halo).
    halo_kernel: Vec<f32>,
    /// Normalised undistorted coordinates on a grid (only with lens distortion).
    undistort_grid: Option<UndistortGrid>,
    /// Illumination gradient x vignetting per pixel, fixed point (GAIN_ONE = 1); None = even.
    gain: Option<Vec<u16>>,
    patches: Vec<Patch>,
    blur_tmp: Vec<f32>,
    row_signal: Vec<f32>,
    row_albedo: Vec<f32>,
}

impl Renderer {
    /// Makes a renderer; `seed` sets the deck and sea textures.
    pub fn new(
        camera: CameraModel,
        deck: DeckLayout,
        options: RenderOptions,
        seed: u64,
    ) -> Result<Self, InvalidField> {
        camera.validate()?;
        deck.validate()?;
        options.validate()?;
        let deck_tex = value_noise(TEX, seed, &[(8, 0.5), (32, 0.3), (128, 0.15), (512, 0.05)]);
        let sea_tex = value_noise(TEX, seed ^ 0x5ea, &[(4, 0.45), (16, 0.35), (64, 0.2)]);
        let n = 1usize << GAUSS_BITS;
        let gauss = (0..n)
            .map(|i| deckwatch_common::stats::normal_quantile((i as f64 + 0.5) / n as f64) as f32)
            .collect();
        let blur_kernel = if options.optical_blur_px > 0.0 {
            gaussian_kernel(options.optical_blur_px)
        } else {
            vec![1.0]
        };
        let halo_kernel = if options.halo > 0.0 && options.halo_px > 0.0 {
            gaussian_kernel(options.halo_px)
        } else {
            Vec::new()
        };
        let undistort_grid = (!camera.distortion.is_none()).then(|| UndistortGrid::new(&camera));
        let gain = (options.illumination_gradient > 0.0 || options.vignetting > 0.0)
            .then(|| gain_map(&camera, &options));
        let width = camera.width as usize;
        Ok(Self {
            camera,
            deck,
            options,
            deck_tex,
            sea_tex,
            gauss,
            blur_kernel,
            halo_kernel,
            undistort_grid,
            gain,
            patches: vec![Patch::default(); deck.marker_count()],
            blur_tmp: Vec::new(),
            row_signal: vec![0.0; width],
            row_albedo: vec![0.0; width],
        })
    }

    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }
    pub fn deck(&self) -> &DeckLayout {
        &self.deck
    }
    pub fn options(&self) -> &RenderOptions {
        &self.options
    }

    /// Renders one frame into `out`. `exposure` holds the poses at evenly spaced instants of the
    /// exposure window (one pose: no motion blur); the background uses the middle one.
    /// `noise_seed` makes the noise of this frame reproducible.
    pub fn render(
        &mut self,
        exposure: &[SceneGeometry],
        noise_seed: u64,
        out: &mut GrayViewMut<'_>,
    ) -> Result<(), RenderError> {
        self.render_exposure(Exposure::Global(exposure), noise_seed, out)
    }

    /// Renders one frame of any shutter into `out` (see [`Exposure`]).
    pub fn render_exposure(
        &mut self,
        exposure: Exposure<'_>,
        noise_seed: u64,
        out: &mut GrayViewMut<'_>,
    ) -> Result<(), RenderError> {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        if (out.width(), out.height()) != (w, h) {
            return Err(RenderError::SizeMismatch {
                expected: (w, h),
                got: (out.width(), out.height()),
            });
        }
        let finite = |s: &SceneGeometry| {
            s.attitude.iter().all(|v| v.is_finite()) && s.viewpoint.position().iter().all(|v| v.is_finite())
        };
        let steps = exposure.steps();
        let checked: &[f64] = if exposure.is_rolling() {
            &[0.0, 0.5, 1.0]
        } else {
            &[]
        };
        let rows_finite = checked
            .iter()
            .all(|f| (0..steps).all(|k| finite(&exposure.scene(&self.camera, f * (h as f64 - 1.0), k))));
        let all_finite = match exposure {
            Exposure::Global(poses) => poses.iter().all(finite),
            Exposure::Rolling { .. } => rows_finite,
        };
        if steps == 0 || !all_finite {
            return Err(RenderError::InvalidScene);
        }
        let mid = exposure.mid(&self.camera, self.camera.cy);
        let Some(h_mid) = pixel_to_deck(&self.camera, &mid) else {
            return Err(RenderError::InvalidScene);
        };
        self.draw_patches(&exposure);
        self.blur_patches();
        self.composite(&h_mid, &mid, &exposure, noise_seed, out);
        self.draw_glints(noise_seed, out);
        Ok(())
    }

    /// Saturated specular spots (drawn last: a glint clips whatever is under it).
    fn draw_glints(&self, noise_seed: u64, out: &mut GrayViewMut<'_>) {
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

    /// Disc coverage of every marker in its patch, averaged over the sub-exposures.
    fn draw_patches(&mut self, exposure: &Exposure<'_>) {
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
                            let (su, sv) = (hm * du * inv_n, hm * dv * inv_n);
                            let start = b + (su + sv) * (0.5 - 0.5 * n as f64);
                            let mut inside = 0u32;
                            let mut row = start;
                            for _ in 0..n {
                                let mut q = row;
                                for _ in 0..n {
                                    if q.z > 0.0 {
                                        let iz = 1.0 / q.z;
                                        let (ex, ey) = (q.x * iz - mx, q.y * iz - my);
                                        inside += (ex * ex + ey * ey <= rho2) as u32;
                                    }
                                    q += su;
                                }
                                row += sv;
                            }
                            inside as f32 / (n * n) as f32
                        };
                        patch.cov[py * pw + px] += c / n_sub;
                    }
                }
            }
        }
    }

    /// Separable Gaussian blur of each patch's coverage (the patch is padded by the kernel
    /// radius, so nothing is cut at its border but at the image's), and the halo's wider one.
    fn blur_patches(&mut self) {
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

    /// The one pass over the frame: background albedo through the homography, marker patches,
    /// light falloff, noise, quantisation.
    fn composite(
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
        let tex = Textures {
            half: o.deck_size_m / 2.0,
            deck_scale: TEX as f64 / o.deck_size_m,
            sea_scale: TEX as f64 / SEA_TILE_M,
            deck: &self.deck_tex,
            sea: &self.sea_tex,
            deck_dn: o.deck_dn as f32,
            sea_dn,
            amp: o.texture as f32,
        };
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
        let noisy = o.read_noise_dn > 0.0 || o.shot_noise_dn > 0.0;
        let sigma_lut: [f32; 256] = std::array::from_fn(|dn| {
            (o.read_noise_dn * o.read_noise_dn + o.shot_noise_dn * dn as f64).sqrt() as f32
        });
        let mut rng = SplitMix64::new(noise_seed);
        let gmask = (1u64 << GAUSS_BITS) - 1;
        for y in 0..h {
            // A rolling shutter's row sees the scene of its own instant.
            let row_maps = exposure.is_rolling().then(|| {
                let s = exposure.mid(&self.camera, y as f64);
                (pixel_to_deck(&self.camera, &s), ray_to_deck(&s))
            });
            let (h_px, ray_h) = match &row_maps {
                Some((Some(hp), rh)) => (hp, rh),
                Some((None, _)) => (h_px, &None),
                None => (h_px, &ray_h),
            };
            // Background albedo along the row: exact at every `chunk`-th pixel, linear in
            // between. The chunk spans at most two texels (a slight smoothing of the finest
            // texture octave), and the perspective map's curvature over it is far
            // below a micrometre on the deck.
            let base = h_px * Vector3::new(0.0, y as f64, 1.0);
            let step = h_px.column(0).into_owned();
            let albedo_at = |x: usize| -> f32 {
                let p = match (&self.undistort_grid, ray_h) {
                    (None, _) => base + step * x as f64,
                    (Some(grid), Some(rh)) => rh * grid.ray(x, y),
                    (Some(_), None) => return sea_dn,
                };
                if p.z > 0.0 {
                    tex.albedo(p.x / p.z, p.y / p.z)
                } else {
                    sea_dn // beyond the horizon
                }
            };
            let mut x = 0;
            let mut left = albedo_at(0);
            while x < w {
                let end = (x + chunk).min(w);
                let right = albedo_at(end);
                let d = (right - left) / (end - x) as f32;
                for (i, a) in self.row_albedo[x..end].iter_mut().enumerate() {
                    *a = left + d * i as f32;
                }
                left = right;
                x = end;
            }
            // Marker discs over the background.
            self.row_signal.copy_from_slice(&self.row_albedo);
            for p in self
                .patches
                .iter()
                .filter(|p| p.w > 0 && y >= p.y0 && y < p.y0 + p.h)
            {
                let row = (y - p.y0) * p.w..(y - p.y0 + 1) * p.w;
                let cov = &p.cov[row.clone()];
                let (sig, alb) = (
                    &mut self.row_signal[p.x0..p.x0 + p.w],
                    &self.row_albedo[p.x0..p.x0 + p.w],
                );
                for ((s, a), c) in sig.iter_mut().zip(alb).zip(cov) {
                    *s += c.min(1.0) * (marker_dn - a);
                }
                if !p.halo.is_empty() {
                    for (s, g) in sig.iter_mut().zip(&p.halo[row]) {
                        *s += halo_dn * g;
                    }
                }
            }
            // Light falloff (camera-fixed gain map), noise, quantisation.
            if let Some(gain) = &self.gain {
                for (s, g) in self.row_signal.iter_mut().zip(&gain[y * w..(y + 1) * w]) {
                    *s *= *g as f32 * (1.0 / GAIN_ONE);
                }
            }
            let row = out.row_mut(y);
            if noisy {
                // Five 12-bit Gaussian table indices per random word.
                let noisy_px = |px: &mut u8, s: f32, bits: u64| {
                    let g = self.gauss[(bits & gmask) as usize];
                    let n = s + sigma_lut[s.clamp(0.0, 255.0) as usize] * g;
                    *px = (n + 0.5).clamp(0.0, 255.0) as u8;
                };
                let mut pxs = row.chunks_exact_mut(5);
                let mut sig = self.row_signal.chunks_exact(5);
                for (p5, s5) in (&mut pxs).zip(&mut sig) {
                    let mut bits = rng.next_u64();
                    for (px, &s) in p5.iter_mut().zip(s5) {
                        noisy_px(px, s, bits);
                        bits >>= GAUSS_BITS;
                    }
                }
                let mut bits = rng.next_u64();
                for (px, &s) in pxs.into_remainder().iter_mut().zip(sig.remainder()) {
                    noisy_px(px, s, bits);
                    bits >>= GAUSS_BITS;
                }
            } else {
                for (px, &s) in row.iter_mut().zip(&self.row_signal) {
                    *px = (s + 0.5).clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::{GrayImage, Rpy, Viewpoint};

    fn scene(rpy: Rpy, vp: Viewpoint) -> SceneGeometry {
        SceneGeometry {
            attitude: rpy.to_matrix(),
            viewpoint: vp,
        }
    }

    fn small_camera() -> CameraModel {
        CameraModel::rpi_v2().scaled_to(640, 480)
    }

    #[test]
    fn homography_maps_marker_images_back_to_the_deck() {
        let cam = CameraModel::paper();
        let deck = DeckLayout::paper();
        let s = scene(
            Rpy::from_degrees(18.0, -7.0, 4.0),
            Viewpoint::level(0.3, -0.1, 4.7),
        );
        let h = pixel_to_deck(&cam, &s).unwrap();
        for i in 0..deck.marker_count() {
            let p = deck.marker_position(i);
            let [u, v] = s.project_deck_point(&cam, &p).unwrap();
            let q = h * Vector3::new(u, v, 1.0);
            assert!(q.z > 0.0);
            assert!((q.x / q.z - p.x).abs() < 1e-12 && (q.y / q.z - p.y).abs() < 1e-12);
        }
    }

    #[test]
    fn clean_frame_has_discs_where_the_markers_project() {
        let cam = small_camera();
        let deck = DeckLayout::paper();
        let opts = RenderOptions {
            texture: 0.0,
            ..RenderOptions::default()
        };
        let mut r = Renderer::new(cam, deck, opts, 1).unwrap();
        let s = scene(Rpy::from_degrees(10.0, 5.0, 0.0), Viewpoint::centred(5.0));
        let mut img = GrayImage::new(640, 480);
        r.render(&[s], 0, &mut img.view_mut()).unwrap();
        for i in 0..deck.marker_count() {
            let [u, v] = s.project_deck_point(&cam, &deck.marker_position(i)).unwrap();
            assert_eq!(
                img.view().get(u.round() as usize, v.round() as usize),
                230,
                "marker {i}"
            );
        }
        // Between markers: the deck; far corner: the deck too (the view is 10 m deck wide).
        assert_eq!(img.view().get(5, 5), 70);
        // Total brightness above the deck level = disc areas x (230 - 70): check the centre
        // disc's area against its projection (pi r^2 f^2 / Z^2 on a nearly level deck).
        let c = s.project_deck_point(&cam, &Vector3::zeros()).unwrap();
        let mut sum = 0.0;
        for y in (c[1] as usize - 12)..(c[1] as usize + 13) {
            for x in (c[0] as usize - 12)..(c[0] as usize + 13) {
                sum += (img.view().get(x, y) as f64 - 70.0) / 160.0;
            }
        }
        let p = s.deck_to_camera(&Vector3::zeros());
        let n = s.attitude * Vector3::z();
        let expect = std::f64::consts::PI * 0.05 * 0.05 * cam.fx * cam.fy / (p.z * p.z) * n.z;
        assert!((sum - expect).abs() < 0.02 * expect + 1.0, "{sum} vs {expect}");
    }

    #[test]
    fn a_rolling_shutter_draws_each_row_at_its_own_instant() {
        let deck = DeckLayout::paper();
        let opts = RenderOptions::realistic();
        let still = scene(Rpy::from_degrees(8.0, -3.0, 20.0), Viewpoint::centred(5.0));
        // A still scene: the rolling shutter changes nothing, pixel for pixel.
        let rolling_cam = CameraModel {
            readout_s: 0.025,
            ..small_camera()
        };
        let mut global = Renderer::new(small_camera(), deck, opts.clone(), 3).unwrap();
        let mut rolling = Renderer::new(rolling_cam, deck, opts, 3).unwrap();
        let (mut a, mut b) = (GrayImage::new(640, 480), GrayImage::new(640, 480));
        global
            .render(&[still, still, still], 9, &mut a.view_mut())
            .unwrap();
        let at = |_: f64| still;
        let exposure = Exposure::Rolling {
            scene_at: &at,
            exposure_s: 0.004,
            steps: 3,
        };
        rolling.render_exposure(exposure, 9, &mut b.view_mut()).unwrap();
        assert_eq!(a, b);
        // The camera rolling at 60 deg/s: a marker's disc lies where its row's instant puts it
        // (its centroid within 0.05 px of that), not where the frame's instant would.
        let clean = RenderOptions {
            texture: 0.0,
            ..RenderOptions::default()
        };
        let mut rolling = Renderer::new(rolling_cam, deck, clean, 3).unwrap();
        let turning = |dt: f64| SceneGeometry {
            viewpoint: Viewpoint::centred(5.0)
                .with_vehicle_attitude(Rpy::new(60f64.to_radians() * dt, 0.0, 0.0).to_matrix()),
            ..still
        };
        let exposure = Exposure::Rolling {
            scene_at: &turning,
            exposure_s: 0.0,
            steps: 1,
        };
        rolling.render_exposure(exposure, 0, &mut b.view_mut()).unwrap();
        // The bow's row and the stern's (marker 5) are read 5 ms apart.
        for m in [1, 5] {
            let p = deck.marker_position(m);
            let frame_instant = turning(0.0).project_deck_point(&rolling_cam, &p).unwrap();
            let mut uv = frame_instant;
            for _ in 0..5 {
                uv = turning(rolling_cam.row_time_s(uv[1]))
                    .project_deck_point(&rolling_cam, &p)
                    .unwrap();
            }
            let (mut sum, mut su, mut sv) = (0.0, 0.0, 0.0);
            for y in (uv[1] as usize - 10)..(uv[1] as usize + 11) {
                for x in (uv[0] as usize - 10)..(uv[0] as usize + 11) {
                    let w = (b.view().get(x, y) as f64 - 70.0).max(0.0);
                    (sum, su, sv) = (sum + w, su + w * x as f64, sv + w * y as f64);
                }
            }
            let centroid = [su / sum, sv / sum];
            assert!(dist(centroid, uv) < 0.05, "marker {m}: {centroid:?} vs {uv:?}");
            assert!(
                dist(frame_instant, uv) > 0.5,
                "marker {m} moved: {frame_instant:?} {uv:?}"
            );
        }
    }

    #[test]
    fn deterministic_for_a_seed_and_noise_has_the_requested_spread() {
        let cam = small_camera();
        let opts = RenderOptions {
            texture: 0.0,
            read_noise_dn: 3.0,
            ..RenderOptions::default()
        };
        let mut r = Renderer::new(cam, DeckLayout::paper(), opts, 1).unwrap();
        let s = scene(Rpy::default(), Viewpoint::centred(5.0));
        let mut a = GrayImage::new(640, 480);
        let mut b = GrayImage::new(640, 480);
        r.render(&[s], 42, &mut a.view_mut()).unwrap();
        r.render(&[s], 42, &mut b.view_mut()).unwrap();
        assert_eq!(a, b);
        r.render(&[s], 43, &mut b.view_mut()).unwrap();
        assert_ne!(a, b);
        // Corner region is plain deck at 70 DN.
        let vals: Vec<f64> = (0..100)
            .flat_map(|y| (0..100).map(move |x| (x, y)))
            .map(|(x, y)| a.view().get(x, y) as f64)
            .collect();
        let mean = vals.iter().sum::<f64>() / vals.len() as f64;
        let sd = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / vals.len() as f64).sqrt();
        assert!((mean - 70.0).abs() < 0.2, "{mean}");
        assert!((sd - 3.0).abs() < 0.15, "{sd}");
    }

    #[test]
    fn blur_and_motion_blur_spread_the_disc_but_keep_its_energy() {
        let cam = small_camera();
        let deck = DeckLayout::paper();
        let base = RenderOptions {
            texture: 0.0,
            ..RenderOptions::default()
        };
        let energy = |img: &GrayImage| img.data.iter().map(|&v| v as f64 - 70.0).sum::<f64>();
        let s0 = scene(Rpy::from_degrees(3.0, 0.0, 0.0), Viewpoint::centred(5.0));
        let mut sharp = GrayImage::new(640, 480);
        Renderer::new(cam, deck, base.clone(), 1)
            .unwrap()
            .render(&[s0], 0, &mut sharp.view_mut())
            .unwrap();
        let mut blurred = GrayImage::new(640, 480);
        let opts = RenderOptions {
            optical_blur_px: 1.5,
            ..base.clone()
        };
        Renderer::new(cam, deck, opts, 1)
            .unwrap()
            .render(&[s0], 0, &mut blurred.view_mut())
            .unwrap();
        assert!((energy(&blurred) - energy(&sharp)).abs() < 0.01 * energy(&sharp));
        let max = |img: &GrayImage| *img.data.iter().max().unwrap();
        assert_eq!(max(&sharp), 230);
        // Motion: the deck yaws 14 deg during the exposure; the ring discs smear along the ring.
        let exposure: Vec<SceneGeometry> = (0..8)
            .map(|k| {
                scene(
                    Rpy::from_degrees(3.0, 0.0, -7.0 + 2.0 * k as f64),
                    Viewpoint::centred(5.0),
                )
            })
            .collect();
        let mut smeared = GrayImage::new(640, 480);
        Renderer::new(cam, deck, base, 1)
            .unwrap()
            .render(&exposure, 0, &mut smeared.view_mut())
            .unwrap();
        let lit = |img: &GrayImage| img.data.iter().filter(|&&v| v > 75).count();
        assert!(lit(&smeared) > lit(&sharp));
        assert!((energy(&smeared) - energy(&sharp)).abs() < 0.03 * energy(&sharp));
    }

    #[test]
    fn lens_distortion_moves_the_discs_as_the_camera_model_says() {
        let mut cam = small_camera();
        cam.distortion = deckwatch_common::Distortion::from_array([-0.25, 0.08, 0.0, 0.0, 0.0]);
        let deck = DeckLayout::paper();
        let opts = RenderOptions {
            texture: 0.0,
            ..RenderOptions::default()
        };
        let mut r = Renderer::new(cam, deck, opts, 1).unwrap();
        let s = scene(Rpy::from_degrees(8.0, -4.0, 30.0), Viewpoint::centred(3.0));
        let mut img = GrayImage::new(640, 480);
        r.render(&[s], 0, &mut img.view_mut()).unwrap();
        for i in 0..deck.marker_count() {
            let [u, v] = s.project_deck_point(&cam, &deck.marker_position(i)).unwrap();
            assert_eq!(
                img.view().get(u.round() as usize, v.round() as usize),
                230,
                "marker {i}"
            );
        }
    }

    #[test]
    fn bad_calls_are_errors() {
        let cam = small_camera();
        let mut r = Renderer::new(cam, DeckLayout::paper(), RenderOptions::default(), 1).unwrap();
        let mut img = GrayImage::new(64, 48);
        let s = scene(Rpy::default(), Viewpoint::centred(5.0));
        assert!(matches!(
            r.render(&[s], 0, &mut img.view_mut()),
            Err(RenderError::SizeMismatch { .. })
        ));
        let mut img = GrayImage::new(640, 480);
        assert_eq!(
            r.render(&[], 0, &mut img.view_mut()),
            Err(RenderError::InvalidScene)
        );
        let mut bad = s;
        bad.viewpoint.altitude_m = f64::NAN;
        assert_eq!(
            r.render(&[bad], 0, &mut img.view_mut()),
            Err(RenderError::InvalidScene)
        );
        let e = RenderOptions {
            supersample: 0,
            ..RenderOptions::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(e.field, "supersample");
        let e = RenderOptions {
            vignetting: 2.0,
            ..RenderOptions::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(e.field, "vignetting");
    }
}
