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
use std::sync::{Arc, Mutex};

mod composite;
pub mod isp;
mod optics;
mod patches;

use composite::*;
use optics::*;
use patches::*;

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
    /// Optics and image processing after the sensor (another lens's blur, a Bayer sensor, an
    /// ISP, a tone curve, JPEG): [`isp::ImagePipeline`]; the default changes nothing.
    pub pipeline: isp::ImagePipeline,
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
            pipeline: isp::ImagePipeline::default(),
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
        self.pipeline.validate()
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
    /// The image pipeline after the sensor failed (JPEG).
    Pipeline(isp::PipelineError),
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
            Self::Pipeline(e) => write!(f, "{e}"),
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
        self.paint_dispatched(&h_mid, &mid, &exposure, noise_seed, out);
        if !self.options.pipeline.is_identity() {
            self.options.pipeline.apply(out).map_err(RenderError::Pipeline)?;
        }
        Ok(())
    }

    /// [`Self::paint`] on the widest lanes this CPU has.
    fn paint_dispatched(
        &mut self,
        h_px: &Matrix3<f64>,
        scene: &SceneGeometry,
        exposure: &Exposure<'_>,
        noise_seed: u64,
        out: &mut GrayViewMut<'_>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: this CPU has AVX2 (checked just above), all `paint_avx2` requires.
            unsafe { self.paint_avx2(h_px, scene, exposure, noise_seed, out) };
            return;
        }
        self.paint(h_px, scene, exposure, noise_seed, out);
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
