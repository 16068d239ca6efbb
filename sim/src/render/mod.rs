//! The image renderer of the simulator: 8-bit grayscale frames of the deck as the camera sees it.
//!
//! Pixels are inverse-mapped to the deck plane through the homography of the current pose (and
//! through the lens model when it has distortion). The deck (a `deck_size_m` square) and the sea
//! around it have a procedural albedo texture; the marker discs are bright. Near the markers
//! (each disc's patch and a margin as wide as the detector's search around it) the background
//! is mapped on a lattice of every pixel or two (at most two texels apart); elsewhere on a grid
//! of `BACKGROUND_STEP` pixels; bilinear between. Disc edges are anti-aliased by supersampling
//! each edge pixel (`supersample`^2 samples, counted row by row on the pixel's affine map),
//! averaged over the sub-exposures of the motion-blur window, then blurred by a Gaussian (optical
//! blur). Illumination gradient, vignetting, shot and read noise are applied last. All of it happens in one pass over the
//! caller's buffer; buffers are allocated when the renderer is made (or grow once when a marker
//! appears larger than before), never per frame.
//!
//! Approximations, all far below a pixel or the noise: optical and motion blur act on the marker
//! discs (where the image has edges); the deck texture is band-limited (coarser than a few
//! pixels) and is neither blurred nor smeared; away from the markers its finest octave (2 cm)
//! is smoothed by the grid; the noise of a row is a window of one table of normal draws.

use crate::rng::SplitMix64;
use deckwatch_common::image::{GrayViewMut, ImageError};
use deckwatch_common::{CameraModel, DeckLayout, InvalidField, SceneGeometry};
use nalgebra::{Matrix3, Vector3};
use std::sync::{Arc, Mutex, OnceLock};

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
/// Standard normal draws in the process's noise table (`normal_draws`): the widest image
/// accepted (16384 px) fits in it many times over.
const NORMAL_DRAWS: usize = 1 << 20;
/// Steps of a normal draw per standard deviation (+-3.5 fits a byte).
const DRAW_STEPS_PER_SIGMA: f32 = 32.0;
/// Grid step (pixels) of the stored undistortion map used for the background.
const UNDISTORT_STEP: usize = 8;
/// Most background pixels between exact evaluations of the albedo near the markers.
const MAX_CHUNK: usize = 8;
/// The grid step (pixels, both ways) of the background's albedo away from the markers: its
/// finest octave (2 cm on the paper's deck, 3-4 px at 3 m over it at 640x480) is smoothed there,
/// below the read noise.
const BACKGROUND_STEP: usize = 8;
/// Least margin (pixels) around a marker's patch in which the background stays exact.
const EXACT_MARGIN_PX: usize = 8;

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

/// The share of an edge pixel's `n` x `n` samples (steps `su`, `sv` in the deck's homogeneous
/// coordinates from the pixel centre `b`, whose `z` is positive) that fall in the disc of squared
/// radius `rho2` around `centre`. Over one pixel the perspective map is affine to well below a
/// micrometre on the deck: each row of samples then leaves the disc where a quadratic in the
/// sample's index changes sign, so a row is counted from its two roots, not sample by sample
/// (the sample-by-sample count, a division each, was a third of a frame's time).
#[inline(always)]
fn edge_coverage(
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

/// `out` from `left` in steps of `step` per pixel: the background between two exact samples.
/// Blocks of eight against a constant ramp: the compiler vectorises that, where converting each
/// index to a float went lane by lane (the fill was a fourteenth of a trial frame's time).
#[inline(always)]
fn fill_linear(out: &mut [f32], left: f32, step: f32) {
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
fn quantised(signal_dn: f32) -> u8 {
    const ROUNDER: f32 = 12_582_912.0;
    (signal_dn.clamp(0.0, 255.0) + ROUNDER).to_bits() as u8
}

/// The process's table of standard normal draws, made once, in steps of 1/`DRAW_STEPS_PER_SIGMA`
/// (a byte each: 1 MB). A frame's row
/// reads its noise from a window of it at a random place: rows and frames get different noise,
/// which repeats only where two windows happen to overlap (about one pair of rows in 800 of a
/// 640 px frame, shifted; no pattern a detector could lock on to).
fn normal_draws() -> &'static [i8] {
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

/// The deck's and the sea's textures of `seed`: made once per seed and process, then shared (a
/// trials run makes a renderer per approach, and the two 1024 x 1024 textures took 5 % of its
/// time). The last few seeds are kept.
fn textures(seed: u64) -> (Arc<[u8]>, Arc<[u8]>) {
    type Made = Vec<(u64, Arc<[u8]>, Arc<[u8]>)>;
    static MADE: Mutex<Made> = Mutex::new(Vec::new());
    const KEPT: usize = 4;
    let found = |made: &Made| {
        made.iter()
            .find(|m| m.0 == seed)
            .map(|m| (m.1.clone(), m.2.clone()))
    };
    if let Some(t) = found(&MADE.lock().unwrap_or_else(|e| e.into_inner())) {
        return t;
    }
    // Made outside the lock: a renderer of another seed need not wait.
    let deck: Arc<[u8]> = value_noise(TEX, seed, &[(8, 0.5), (32, 0.3), (128, 0.15), (512, 0.05)]).into();
    let sea: Arc<[u8]> = value_noise(TEX, seed ^ 0x5ea, &[(4, 0.45), (16, 0.35), (64, 0.2)]).into();
    let mut made = MADE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(t) = found(&made) {
        return t;
    }
    if made.len() >= KEPT {
        made.remove(0);
    }
    made.push((seed, deck.clone(), sea.clone()));
    (deck, sea)
}

/// Renders frames for one camera, deck and set of options.
pub struct Renderer {
    camera: CameraModel,
    deck: DeckLayout,
    options: RenderOptions,
    /// The deck's and the sea's albedo textures (shared by the renderers of one seed).
    deck_tex: Arc<[u8]>,
    sea_tex: Arc<[u8]>,
    blur_kernel: Vec<f32>,
    /// The halo's Gaussian (empty: no halo).
    halo_kernel: Vec<f32>,
    /// Normalised undistorted coordinates on a grid (only with lens distortion).
    undistort_grid: Option<UndistortGrid>,
    /// Illumination gradient x vignetting per pixel, fixed point (GAIN_ONE = 1); None = even.
    gain: Option<Vec<u16>>,
    patches: Vec<Patch>,
    blur_tmp: Vec<f32>,
    /// The row being composited: the background's albedo, then the discs over it (DN).
    row_signal: Vec<f32>,
    /// The background's albedo on the two grid rows around the row being composited.
    grid_upper: Vec<f32>,
    grid_lower: Vec<f32>,
    /// Per marker, the region where the background stays exact...
    near_markers: Vec<ExactRegion>,
    /// ...and the exact albedo there, each region's lattice after the one before. Grows to the
    /// largest frame's need, then is reused: a frame-sized lattice would be 64 MB at full
    /// resolution.
    lattice: Vec<f32>,
}

/// A region near a marker where the background's albedo is exact on a lattice of every
/// `chunk`-th pixel both ways (the global lattice's points within it).
#[derive(Debug, Clone, Copy)]
struct ExactRegion {
    /// x0, y0, x1, y1 (pixels; x1, y1 excluded).
    rect: [usize; 4],
    /// The lattice's first column and row, and its width (points).
    first_gx: usize,
    first_gy: usize,
    lattice_w: usize,
    /// Where its lattice starts in `Renderer::lattice` (row-major).
    offset: usize,
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
        let (deck_tex, sea_tex) = textures(seed);
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
            blur_kernel,
            halo_kernel,
            undistort_grid,
            gain,
            patches: vec![Patch::default(); deck.marker_count()],
            blur_tmp: Vec::new(),
            row_signal: vec![0.0; width],
            grid_upper: Vec::new(),
            grid_lower: Vec::new(),
            near_markers: Vec::new(),
            lattice: Vec::new(),
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

    /// The checks before a frame is drawn (its size, finite poses, a deck in view), and the
    /// pixel-to-deck map and scene of the exposure's middle.
    fn checked_exposure(
        &self,
        exposure: &Exposure<'_>,
        out: &GrayViewMut<'_>,
    ) -> Result<(Matrix3<f64>, SceneGeometry), RenderError> {
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
        Ok((h_mid, mid))
    }

    /// Renders one frame of any shutter into `out` (see [`Exposure`]).
    pub fn render_exposure(
        &mut self,
        exposure: Exposure<'_>,
        noise_seed: u64,
        out: &mut GrayViewMut<'_>,
    ) -> Result<(), RenderError> {
        let (h_mid, mid) = self.checked_exposure(&exposure, out)?;
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: this CPU has AVX2 (checked just above), all `paint_avx2` requires.
            unsafe { self.paint_avx2(&h_mid, &mid, &exposure, noise_seed, out) };
            return Ok(());
        }
        self.paint(&h_mid, &mid, &exposure, noise_seed, out);
        Ok(())
    }

    /// The frame's pixels: the markers' patches, then the one pass over the frame, then the
    /// glints. Inlined into the two entries below, compiled for each.
    #[inline(always)]
    fn paint(
        &mut self,
        h_px: &Matrix3<f64>,
        scene: &SceneGeometry,
        exposure: &Exposure<'_>,
        noise_seed: u64,
        out: &mut GrayViewMut<'_>,
    ) {
        self.draw_patches(exposure);
        self.blur_patches();
        self.composite(h_px, scene, exposure, noise_seed, out);
        self.draw_glints(noise_seed, out);
    }

    /// [`Self::paint`] compiled for x86-64 CPUs with AVX2 (every PC and cloud CPU since about
    /// 2015), picked at run time: the per-pixel loops (patches, background, noise and
    /// quantisation) run 8 lanes wide instead of SSE2's 4. The same operations on the same
    /// values in IEEE arithmetic (no FMA, nothing reassociated): the same frames bit for bit
    /// (`the_avx2_and_baseline_paths_give_the_same_frames`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn paint_avx2(
        &mut self,
        h_px: &Matrix3<f64>,
        scene: &SceneGeometry,
        exposure: &Exposure<'_>,
        noise_seed: u64,
        out: &mut GrayViewMut<'_>,
    ) {
        self.paint(h_px, scene, exposure, noise_seed, out);
    }

    /// Saturated specular spots (drawn last: a glint clips whatever is under it).
    #[inline(always)]
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
    #[inline(always)]
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
    #[inline(always)]
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
        // every pixel or two of the frame took half a trial frame's time; BENCHMARKS "Faster
        // trials").
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

    /// The row-by-row count of an edge pixel's samples inside a disc agrees with mapping every
    /// sample through the perspective division, on pixels seen obliquely and straight on.
    #[test]
    fn edge_coverage_counts_the_samples_inside_the_disc() {
        let camera = small_camera();
        let deck = DeckLayout::paper();
        for (rpy, vp) in [
            (Rpy::from_degrees(0.0, 0.0, 0.0), Viewpoint::level(0.0, 0.0, 3.0)),
            (
                Rpy::from_degrees(14.0, -9.0, 30.0),
                Viewpoint::level(0.3, -0.2, 1.6),
            ),
        ] {
            let s = scene(rpy, vp);
            let hm = ray_to_deck(&s).unwrap();
            for m in 0..deck.marker_count() {
                let c = deck.marker_position(m);
                let rho = deck.disc_radius(m);
                let [u, v] = s
                    .project_deck_point(&camera, &(c + Vector3::new(rho, 0.0, 0.0)))
                    .unwrap();
                let n = 16;
                // Pixels across the disc's edge.
                for (du_px, dv_px) in [(-0.7, 0.0), (0.0, 0.3), (0.4, -0.2), (1.1, 0.6)] {
                    let (ray, du, dv) = pixel_ray(&camera, u.round() + du_px, v.round() + dv_px).unwrap();
                    let b = hm * ray;
                    let (su, sv) = (hm * du / n as f64, hm * dv / n as f64);
                    let mut inside = 0;
                    for j in 0..n {
                        for i in 0..n {
                            let q = b + su * (i as f64 - 7.5) + sv * (j as f64 - 7.5);
                            let (ex, ey) = (q.x / q.z - c.x, q.y / q.z - c.y);
                            inside += (ex * ex + ey * ey <= rho * rho) as usize;
                        }
                    }
                    let counted = edge_coverage(b, su, sv, [c.x, c.y], rho * rho, n);
                    // Samples within micrometres of the edge may fall either way.
                    assert!(
                        (counted - inside as f32 / 256.0).abs() <= 1.0 / 256.0,
                        "marker {m} at ({du_px}, {dv_px}): {counted} vs {inside}/256"
                    );
                }
            }
        }
    }

    #[test]
    fn the_sea_texture_wraps_with_its_period_either_side_of_zero() {
        let (_, sea) = textures(9);
        // The same as the point brought into the texture's first period by a float modulo (in
        // there the floor is the truncation), and the texture's period either way.
        let reference =
            |x: f64, y: f64| sample_wrapped(&sea, x.rem_euclid(TEX as f64), y.rem_euclid(TEX as f64));
        for (x, y) in [
            (0.0, 0.0),
            (-0.25, 3.5),
            (-1.0, -1.0),
            (1023.75, -1024.5),
            (-5000.3, 777.7),
            (1e9 + 0.5, -1e9),
        ] {
            let v = sample_wrapped(&sea, x, y);
            assert!((v - reference(x, y)).abs() < 1e-5, "({x}, {y})");
            assert!((v - sample_wrapped(&sea, x + TEX as f64, y - 3.0 * TEX as f64)).abs() < 1e-5);
        }
        // On a texel: its byte; a texel before the first (-1, -2): the last column's.
        let texel = |x: usize, y: usize| sea[y * TEX + x] as f32 / 127.0 - 1.0;
        assert!((sample_wrapped(&sea, 3.0, 5.0) - texel(3, 5)).abs() < 1e-6);
        assert!((sample_wrapped(&sea, -1.0, -2.0) - texel(TEX - 1, TEX - 2)).abs() < 1e-6);
        // Far beyond the horizon's texels: a value of the texture, no panic.
        for v in [1e30, -1e30, f64::MAX] {
            assert!(sample_wrapped(&sea, v, v).abs() <= 1.0);
        }
    }

    #[test]
    fn quantising_rounds_to_the_nearest_value_and_clips() {
        for (signal, dn) in [
            (-3.0, 0),
            (0.0, 0),
            (0.49, 0),
            (0.51, 1),
            (127.4, 127),
            (254.6, 255),
            (300.0, 255),
        ] {
            assert_eq!(quantised(signal), dn, "{signal}");
        }
    }

    /// Away from the markers the background is a bilinear grid of exact samples: within the
    /// texture's finest detail of the exact map, and exact near the markers.
    #[test]
    fn the_background_away_from_the_markers_stays_close_to_the_exact_map() {
        let camera = small_camera();
        let clean = RenderOptions::default();
        let mut r = Renderer::new(camera, DeckLayout::paper(), clean.clone(), 3).unwrap();
        let s = scene(
            Rpy::from_degrees(3.0, -2.0, 10.0),
            Viewpoint::level(0.1, 0.0, 3.0),
        );
        let mut img = GrayImage::new(640, 480);
        r.render(&[s], 1, &mut img.view_mut()).unwrap();
        let hm = pixel_to_deck(&camera, &s).unwrap();
        let o = &clean;
        let tex = Textures::placed(o, &r.deck_tex, &r.sea_tex);
        let near_marker = |x: usize, y: usize| {
            r.patches.iter().any(|p| {
                p.w > 0 && x + 2 >= p.x0 && x < p.x0 + p.w + 2 && y + 2 >= p.y0 && y < p.y0 + p.h + 2
            })
        };
        let (mut worst_far, mut worst_near, mut sum_sq, mut n) = (0.0f32, 0.0f32, 0.0f64, 0);
        for y in (0..480).step_by(3) {
            for x in (0..640).step_by(3) {
                let p = hm * Vector3::new(x as f64, y as f64, 1.0);
                let exact = tex.albedo(p.x / p.z, p.y / p.z);
                let err = (img.view().row(y)[x] as f32 - exact).abs();
                if near_marker(x, y) {
                    continue; // the disc itself
                }
                let in_exact_region = r
                    .near_markers
                    .iter()
                    .any(|q| x >= q.rect[0] && x < q.rect[2] && y >= q.rect[1] && y < q.rect[3]);
                if in_exact_region {
                    worst_near = worst_near.max(err);
                } else {
                    worst_far = worst_far.max(err);
                    sum_sq += (err as f64).powi(2);
                    n += 1;
                }
            }
        }
        // Near the markers: as exact as before (the chunk's interpolation and the rounding).
        assert!(worst_near <= 1.5, "near the markers {worst_near} DN");
        // Away: the finest octave smoothed, a few DN at most, far less on average.
        assert!(worst_far <= 6.0, "away from the markers {worst_far} DN");
        assert!(
            (sum_sq / n as f64).sqrt() <= 1.5,
            "RMS {} DN",
            (sum_sq / n as f64).sqrt()
        );
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

    /// The AVX2 build of the pixel loops draws exactly what the baseline one does: realistic
    /// frames near and far, with motion blur, lens distortion and a rolling shutter.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_and_baseline_paths_give_the_same_frames() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("this CPU has no AVX2: only the baseline path runs here");
            return;
        }
        let deck = DeckLayout::paper();
        let mut distorted = small_camera();
        distorted.distortion = deckwatch_common::Distortion::from_array([-0.2, 0.05, 0.0, 0.0, 0.0]);
        let mut rolling_cam = small_camera();
        rolling_cam.readout_s = 0.02;
        let tilted = |roll_deg: f64, height_m: f64| {
            scene(
                Rpy::from_degrees(roll_deg, -4.0, 7.0),
                Viewpoint::level(0.1, -0.2, height_m),
            )
        };
        let swaying = |dt: f64| tilted(3.0 + 40.0 * dt, 2.0);
        let poses = [tilted(5.0, 1.5), tilted(5.3, 1.5), tilted(5.6, 1.5)];
        let far = [tilted(-8.0, 12.0)];
        let cases: [(CameraModel, Exposure<'_>); 4] = [
            (small_camera(), Exposure::Global(&poses)),
            (small_camera(), Exposure::Global(&far)),
            (distorted, Exposure::Global(&poses[..1])),
            (
                rolling_cam,
                Exposure::Rolling {
                    scene_at: &swaying,
                    exposure_s: 0.004,
                    steps: 2,
                },
            ),
        ];
        for (k, (camera, exposure)) in cases.into_iter().enumerate() {
            let mut r = Renderer::new(camera, deck, RenderOptions::realistic(), 2).unwrap();
            let (mut baseline, mut avx2) = (GrayImage::new(640, 480), GrayImage::new(640, 480));
            let (h_mid, mid) = r.checked_exposure(&exposure, &baseline.view_mut()).unwrap();
            r.paint(&h_mid, &mid, &exposure, 17 + k as u64, &mut baseline.view_mut());
            // SAFETY: the CPU has AVX2 (checked above).
            unsafe { r.paint_avx2(&h_mid, &mid, &exposure, 17 + k as u64, &mut avx2.view_mut()) };
            assert!(baseline == avx2, "case {k}: the two paths differ");
            // And it is a frame: markers and background, not a blank.
            let view = baseline.view();
            let (lo, hi) = (0..480)
                .flat_map(|y| view.row(y).iter().copied())
                .fold((u8::MAX, 0), |(lo, hi), v| (lo.min(v), hi.max(v)));
            assert!(hi > lo + 100, "case {k}: {lo}..{hi}");
        }
    }
}
