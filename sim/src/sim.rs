//! The frame simulator: a motion profile, sampled over each frame's exposure, drawn by the
//! renderer straight into the caller's buffer, with the frame's ground truth.

use crate::motion::{MotionProfile, MotionSample};
use crate::render::isp::{ImagePipeline, Psf};
use crate::render::{Exposure, RenderError, RenderOptions, Renderer};
use crate::scenario::Simulation;
use deckwatch_common::image::GrayViewMut;
use deckwatch_common::messages::VehicleAttitude;
use deckwatch_common::{CameraModel, DeckLayout, Distortion, GroundTruth, InvalidOption, SceneGeometry};

/// One rendered frame's truth.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameTruth {
    pub index: u64,
    pub timestamp_ns: u64,
    /// The scene at the middle of the exposure.
    pub sample: MotionSample,
    /// Whether any marker centre lies on the sensor.
    pub deck_in_view: bool,
    /// Exact pixels of the marker centres (None when off the sensor); with a rolling shutter,
    /// where each appears: at the instant of its own row.
    pub markers: Vec<Option<[f64; 2]>>,
    /// The vehicle's angular velocity in W at the frame's instant (deg/s).
    pub vehicle_rate_dps: [f64; 3],
    /// Its change (deg/s^2).
    pub vehicle_acceleration_dps2: [f64; 3],
}

impl FrameTruth {
    /// The vehicle's attitude as the frame carries it: its own (none for a level camera), with
    /// its height, rate and acceleration.
    pub fn vehicle(&self) -> VehicleAttitude {
        let truth = self.ground_truth();
        VehicleAttitude::from_rpy(truth.vehicle_attitude())
            .with_height(truth.vehicle_height_m.unwrap_or(f64::NAN))
            .with_rate_dps(self.vehicle_rate_dps)
            .with_acceleration_dps2(self.vehicle_acceleration_dps2)
    }
}

impl FrameTruth {
    /// The recording's ground truth: attitude only when the deck is in view (`nan` otherwise);
    /// altitude and offset always (the altimeter and the tracking error are known).
    pub fn ground_truth(&self) -> GroundTruth {
        let [roll, pitch, yaw] = self.sample.attitude.to_degrees();
        let v = self.sample.viewpoint;
        let vehicle = deckwatch_common::Rpy::from_matrix(&v.vehicle_attitude).to_degrees();
        let seen = |x: f64| self.deck_in_view.then_some(x);
        GroundTruth {
            roll_deg: seen(roll),
            pitch_deg: seen(pitch),
            yaw_deg: seen(yaw),
            alt_m: Some(v.altitude_m),
            offset_x_m: Some(v.offset_x_m),
            offset_y_m: Some(v.offset_y_m),
            vehicle_roll_deg: Some(vehicle[0]),
            vehicle_pitch_deg: Some(vehicle[1]),
            vehicle_yaw_deg: Some(vehicle[2]),
            vehicle_height_m: Some(self.sample.vehicle_height_m()),
            deck_heave_m: Some(self.sample.deck_heave_m),
            vehicle_rate_x_dps: Some(self.vehicle_rate_dps[0]),
            vehicle_rate_y_dps: Some(self.vehicle_rate_dps[1]),
            vehicle_rate_z_dps: Some(self.vehicle_rate_dps[2]),
        }
    }
}

/// Renders the frames of a motion profile.
pub struct FrameSimulator {
    profile: Box<dyn MotionProfile + Send + Sync>,
    renderer: Renderer,
    rate_hz: f64,
    exposure_s: f64,
    exposure_steps: usize,
    seed: u64,
    poses: Vec<SceneGeometry>,
}

impl FrameSimulator {
    /// `exposure_s` > 0 blurs motion over that window, sampled at `exposure_steps` instants.
    pub fn new(
        profile: Box<dyn MotionProfile + Send + Sync>,
        renderer: Renderer,
        rate_hz: f64,
        exposure_s: f64,
        exposure_steps: usize,
        seed: u64,
    ) -> Result<Self, InvalidOption> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(InvalidOption::new(
                "frame rate",
                format!("must be positive, got {rate_hz}"),
            ));
        }
        if !(exposure_s.is_finite() && exposure_s >= 0.0 && exposure_s <= 1.0 / rate_hz) {
            return Err(InvalidOption::new(
                "exposure",
                format!("must be within [0, 1/rate] s, got {exposure_s}"),
            ));
        }
        let readout_s = renderer.camera().readout_s;
        if readout_s > 1.0 / rate_hz {
            return Err(InvalidOption::new(
                "readout",
                format!(
                    "the rolling shutter's readout ({} ms) must fit in a frame time ({} ms)",
                    readout_s * 1e3,
                    1e3 / rate_hz
                ),
            ));
        }
        let steps = if exposure_s > 0.0 {
            exposure_steps.clamp(2, 64)
        } else {
            1
        };
        Ok(Self {
            profile,
            renderer,
            rate_hz,
            exposure_s,
            exposure_steps: steps,
            seed,
            poses: Vec::with_capacity(steps),
        })
    }

    pub fn camera(&self) -> &CameraModel {
        self.renderer.camera()
    }
    pub fn deck(&self) -> &DeckLayout {
        self.renderer.deck()
    }

    /// The scene `t_s` seconds into the run.
    fn scene_at(&self, t_s: f64) -> SceneGeometry {
        scene_of(self.profile.as_ref(), t_s)
    }

    /// Renders frame `index` (at t = index / rate: the middle row's mid-exposure) into `out` and
    /// returns its truth.
    pub fn render_frame(&mut self, index: u64, out: &mut GrayViewMut<'_>) -> Result<FrameTruth, RenderError> {
        let t = index as f64 / self.rate_hz;
        // Noise differs per frame and per seed, and is reproducible frame by frame.
        let noise_seed = self.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index;
        let camera = *self.renderer.camera();
        if camera.readout_s > 0.0 {
            // The renderer is borrowed mutably beside the profile.
            let (profile, renderer) = (&self.profile, &mut self.renderer);
            let scene_at = |dt: f64| scene_of(profile.as_ref(), t + dt);
            renderer.render_exposure(
                Exposure::Rolling {
                    scene_at: &scene_at,
                    exposure_s: self.exposure_s,
                    steps: self.exposure_steps,
                },
                noise_seed,
                out,
            )?;
        } else {
            self.poses.clear();
            for k in 0..self.exposure_steps {
                let dt = if self.exposure_steps == 1 {
                    0.0
                } else {
                    self.exposure_s * (k as f64 / (self.exposure_steps - 1) as f64 - 0.5)
                };
                let scene = self.scene_at(t + dt);
                self.poses.push(scene);
            }
            self.renderer.render(&self.poses, noise_seed, out)?;
        }
        let sample = self.profile.sample(t);
        let deck = *self.renderer.deck();
        // Each marker where it appears: at its own row's instant (a fixed point: the row moves
        // by far less than a pixel per iteration).
        let scene_t = self.scene_at(t);
        let markers: Vec<Option<[f64; 2]>> = (0..deck.marker_count())
            .map(|m| {
                let p = deck.marker_position(m);
                let mut uv = scene_t.project_deck_point(&camera, &p)?;
                if camera.readout_s > 0.0 {
                    for _ in 0..4 {
                        uv = self
                            .scene_at(t + camera.row_time_s(uv[1]))
                            .project_deck_point(&camera, &p)?;
                    }
                }
                camera.contains(uv).then_some(uv)
            })
            .collect();
        // The vehicle's rate and its change, by central differences over +-1 ms.
        let rate_at = |t: f64| {
            let dt = 1e-3;
            let (a, b) = (
                self.profile.vehicle_attitude(t - dt),
                self.profile.vehicle_attitude(t + dt),
            );
            deckwatch_common::rotation::angular_velocity(&a, &b, 2.0 * dt)
        };
        let w = rate_at(t);
        let a = (rate_at(t + 1e-3) - rate_at(t - 1e-3)) / 2e-3;
        let (vehicle_rate_dps, vehicle_acceleration_dps2) = (
            [w.x, w.y, w.z].map(f64::to_degrees),
            [a.x, a.y, a.z].map(f64::to_degrees),
        );
        Ok(FrameTruth {
            index,
            timestamp_ns: (t * 1e9).round() as u64,
            sample,
            deck_in_view: markers.iter().any(Option::is_some),
            markers,
            vehicle_rate_dps,
            vehicle_acceleration_dps2,
        })
    }
}

/// A motion profile's scene at `t_s`.
fn scene_of(profile: &(dyn MotionProfile + Send + Sync), t_s: f64) -> SceneGeometry {
    let s = profile.sample(t_s);
    SceneGeometry {
        attitude: s.attitude.to_matrix(),
        viewpoint: s.viewpoint,
    }
}

/// Command-line choice of the image: resolution, look and lens (and the `[image]` section of
/// the pipeline's configuration).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct ImageArgs {
    /// Image width (the camera preset is scaled to it); default: the preset's.
    #[cfg_attr(feature = "cli", arg(long))]
    pub width: Option<u32>,
    /// Image height; default: the preset's.
    #[cfg_attr(feature = "cli", arg(long))]
    pub height: Option<u32>,
    /// Starting point of the look: `clean` (sharp, noiseless, even light), `realistic` (blur,
    /// noise, uneven light, vignetting) or `night` (lights on a dark deck); the options below
    /// override it.
    #[cfg_attr(feature = "cli", arg(long, default_value = "realistic"))]
    pub look: Look,
    /// Optical blur, Gaussian sigma in pixels.
    #[cfg_attr(feature = "cli", arg(long))]
    pub blur_px: Option<f64>,
    /// Exposure time for motion blur, milliseconds (0 = none).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.0))]
    pub exposure_ms: f64,
    /// Read noise (DN, standard deviation).
    #[cfg_attr(feature = "cli", arg(long))]
    pub read_noise: Option<f64>,
    /// Shot noise (DN^2 of variance per DN of signal).
    #[cfg_attr(feature = "cli", arg(long))]
    pub shot_noise: Option<f64>,
    /// Vignetting strength, 0-1.
    #[cfg_attr(feature = "cli", arg(long))]
    pub vignetting: Option<f64>,
    /// Illumination gradient across the image, 0-1.
    #[cfg_attr(feature = "cli", arg(long))]
    pub gradient: Option<f64>,
    /// Deck and sea texture contrast, 0-1.
    #[cfg_attr(feature = "cli", arg(long))]
    pub texture: Option<f64>,
    /// Marker contrast against the deck, relative to the look's (1 = unchanged; 0.3 = a dull,
    /// wet or shadowed deck).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contrast: Option<f64>,
    /// Hide this marker (index; 0 = centre, 1 = bow) as if something deck-coloured covered it.
    #[cfg_attr(feature = "cli", arg(long))]
    pub occlude: Option<usize>,
    /// Specular glints per frame (saturated spots at random places).
    #[cfg_attr(feature = "cli", arg(long))]
    pub glints: Option<u32>,
    /// The glow around each marker light, as a fraction of its brightness (0 = none; the night
    /// look has 0.15).
    #[cfg_attr(feature = "cli", arg(long))]
    pub halo: Option<f64>,
    /// Lens distortion k1,k2,p1,p2,k3 (OpenCV order).
    #[cfg_attr(feature = "cli", arg(long, value_delimiter = ',', allow_hyphen_values = true))]
    pub distortion: Option<Vec<f64>>,
    /// Rolling shutter: the time to read the rows out, top to bottom (ms; 0 = a global
    /// shutter). The Pi cameras take about 20-30 ms at full resolution.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.0))]
    pub readout_ms: f64,
    /// The pipeline is told a calibration this far off the lens that renders the frames
    /// (`ImageArgs::calibrated`): 1 = focal lengths 0.3 % off, the principal point 0.2 % of
    /// the width and 0.15 % of the height off, k1 +0.01, k2 -0.002; 0 = exact.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.0))]
    pub calibration_error: f64,
    /// Another lens's blur, after the look's: out of focus, a uniform disc of this radius (px).
    /// One point-spread function at a time (this, `--motion-psf` or `--psf-file`).
    #[cfg_attr(feature = "cli", arg(long))]
    pub defocus_px: Option<f64>,
    /// ... or a line: the camera shaking during the exposure, LENGTH_PX,ANGLE_DEG (deg from the
    /// image's +u toward +v).
    #[cfg_attr(
        feature = "cli",
        arg(long, value_delimiter = ',', value_name = "LENGTH_PX,ANGLE_DEG")
    )]
    pub motion_psf: Option<Vec<f64>>,
    /// ... or a measured kernel from a text file: rows of weights (spaces, commas or tabs), an
    /// odd side up to 63, `#` comments.
    #[cfg_attr(feature = "cli", arg(long))]
    pub psf_file: Option<std::path::PathBuf>,
    /// Through a Bayer sensor: an RGGB mosaic of unequal sensitivities, white balance,
    /// bilinear demosaicing and luma (the path of a colour camera's frames to grey).
    #[cfg_attr(feature = "cli", arg(long))]
    pub bayer: bool,
    /// The Bayer path's raw bit depth (8 or 10).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 8))]
    pub raw_bits: u32,
    /// The ISP's denoising: a Gaussian of this sigma (px; 0 = none).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.0))]
    pub denoise_px: f64,
    /// The ISP's sharpening: an unsharp mask of this amount (0 = none).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.0))]
    pub sharpen: f64,
    /// Tone curve: the output is `255 (x / 255)^(1 / gamma)` (1 = linear; 2.2 about a
    /// display's).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1.0))]
    pub gamma: f64,
    /// Each frame compressed as a streamed JPEG of this quality (0 = none; 1-100).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0))]
    pub jpeg_quality: u8,
}

/// The starting point of a rendered image's look (`--look`, `[image] look`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Look {
    /// Sharp, noiseless, even light.
    Clean,
    /// Blur, noise, uneven light, vignetting.
    Realistic,
    /// Night: the markers are lights (saturated cores, a glow around them) on a dark deck,
    /// a noisy high gain.
    Night,
}

impl Look {
    pub fn name(&self) -> &'static str {
        match self {
            Self::Clean => "clean",
            Self::Realistic => "realistic",
            Self::Night => "night",
        }
    }
}

impl Default for ImageArgs {
    /// The command line's defaults (a test checks that they agree).
    fn default() -> Self {
        let pipeline = ImagePipeline::default();
        Self {
            width: None,
            height: None,
            look: Look::Realistic,
            blur_px: None,
            exposure_ms: 0.0,
            read_noise: None,
            shot_noise: None,
            vignetting: None,
            gradient: None,
            texture: None,
            contrast: None,
            occlude: None,
            glints: None,
            halo: None,
            distortion: None,
            readout_ms: 0.0,
            calibration_error: 0.0,
            defocus_px: None,
            motion_psf: None,
            psf_file: None,
            // The pipeline's own defaults (nothing changed).
            bayer: pipeline.bayer,
            raw_bits: pipeline.raw_bits,
            denoise_px: pipeline.denoise_px,
            sharpen: pipeline.sharpen,
            gamma: pipeline.gamma,
            jpeg_quality: pipeline.jpeg_quality,
        }
    }
}

impl ImageArgs {
    /// The calibration the pipeline is told for frames `camera` renders: `camera` itself, or
    /// off by `calibration_error` (the same pattern of errors for every lens, scaled).
    pub fn calibrated(&self, camera: &CameraModel) -> CameraModel {
        let e = self.calibration_error;
        if e == 0.0 {
            return *camera;
        }
        let mut c = *camera;
        c.fx *= 1.0 + 0.003 * e;
        c.fy *= 1.0 + 0.003 * e;
        c.cx += 0.002 * e * f64::from(c.width);
        c.cy -= 0.0015 * e * f64::from(c.height);
        c.distortion.k1 += 0.01 * e;
        c.distortion.k2 -= 0.002 * e;
        c
    }

    /// The image pipeline after the sensor the options ask for.
    fn pipeline(&self) -> Result<ImagePipeline, InvalidOption> {
        let given = [
            self.defocus_px.is_some(),
            self.motion_psf.is_some(),
            self.psf_file.is_some(),
        ];
        if given.iter().filter(|g| **g).count() > 1 {
            return Err(InvalidOption::new(
                "--defocus-px/--motion-psf/--psf-file",
                "one point-spread function at a time",
            ));
        }
        let psf = if let Some(radius_px) = self.defocus_px {
            Psf::Defocus { radius_px }
        } else if let Some(m) = &self.motion_psf {
            let [length_px, angle_deg] = m
                .as_slice()
                .try_into()
                .map_err(|_| InvalidOption::new("--motion-psf", "give LENGTH_PX,ANGLE_DEG"))?;
            Psf::Motion { length_px, angle_deg }
        } else if let Some(path) = &self.psf_file {
            // A 63 x 63 kernel of 20-digit weights is ~80 KB; a megabyte is no kernel.
            const MAX_PSF_FILE_BYTES: u64 = 1 << 20;
            let text = deckwatch_common::files::read_bounded_to_string(path, MAX_PSF_FILE_BYTES)
                .map_err(|e| InvalidOption::new("--psf-file", e.to_string()))?;
            Psf::kernel_from_text(&text)
                .map_err(|e| InvalidOption::new("--psf-file", format!("{}: {e}", path.display())))?
        } else {
            Psf::None
        };
        let pipeline = ImagePipeline {
            psf,
            bayer: self.bayer,
            raw_bits: self.raw_bits,
            denoise_px: self.denoise_px,
            sharpen: self.sharpen,
            gamma: self.gamma,
            jpeg_quality: self.jpeg_quality,
        };
        pipeline
            .validate()
            .map_err(|e| InvalidOption::new("image pipeline", e.to_string()))?;
        Ok(pipeline)
    }

    /// The camera (preset scaled to the resolution, with the lens) and the render options.
    pub fn resolve(&self, sim: &Simulation) -> Result<(CameraModel, RenderOptions), InvalidOption> {
        let mut camera = sim.camera;
        let (w, h) = (
            self.width.unwrap_or(camera.width),
            self.height.unwrap_or(camera.height),
        );
        if w == 0 || h == 0 || w > 16384 || h > 16384 {
            return Err(InvalidOption::new(
                "--width/--height",
                format!("{w}x{h} is not a usable image size"),
            ));
        }
        if (w, h) != (camera.width, camera.height) {
            camera = camera.scaled_to(w, h);
        }
        if let Some(d) = &self.distortion {
            let a: [f64; 5] = d
                .as_slice()
                .try_into()
                .map_err(|_| InvalidOption::new("--distortion", "give k1,k2,p1,p2,k3"))?;
            camera.distortion = Distortion::from_array(a);
        }
        camera.readout_s = self.readout_ms / 1e3;
        if !(self.calibration_error.is_finite() && self.calibration_error.abs() <= 10.0) {
            return Err(InvalidOption::new(
                "--calibration-error",
                format!("must be within [-10, 10], got {}", self.calibration_error),
            ));
        }
        self.calibrated(&camera)
            .validate()
            .map_err(|e| InvalidOption::new("--calibration-error", format!("the calibration told: {e}")))?;
        camera
            .validate()
            .map_err(|e| InvalidOption::new("camera", e.to_string()))?;
        let mut o = match self.look {
            Look::Clean => RenderOptions::default(),
            Look::Realistic => RenderOptions::realistic(),
            Look::Night => RenderOptions::night(),
        };
        // The glow's spread is the optics': it scales with the image.
        o.halo_px = RenderOptions::night().halo_px * f64::from(camera.width) / 3280.0;
        let set = |field: &mut f64, v: Option<f64>| {
            if let Some(v) = v {
                *field = v;
            }
        };
        set(&mut o.optical_blur_px, self.blur_px);
        set(&mut o.read_noise_dn, self.read_noise);
        set(&mut o.shot_noise_dn, self.shot_noise);
        set(&mut o.vignetting, self.vignetting);
        set(&mut o.illumination_gradient, self.gradient);
        set(&mut o.texture, self.texture);
        set(&mut o.halo, self.halo);
        if let Some(c) = self.contrast {
            if !(c.is_finite() && c > 0.0 && c <= 2.0) {
                return Err(InvalidOption::new(
                    "--contrast",
                    format!("must be within (0, 2], got {c}"),
                ));
            }
            o.marker_dn = (o.deck_dn + c * (o.marker_dn - o.deck_dn)).min(255.0);
        }
        if let Some(m) = self.occlude {
            if m >= sim.deck.marker_count() {
                return Err(InvalidOption::new(
                    "--occlude",
                    format!("marker {m} does not exist (0..{})", sim.deck.marker_count()),
                ));
            }
            o.occluded_marker = Some(m);
        }
        o.glints = self.glints.unwrap_or(0);
        o.pipeline = self.pipeline()?;
        o.validate()
            .map_err(|e| InvalidOption::new("render options", e.to_string()))?;
        Ok((camera, o))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{Scenario, SimulationArgs};
    use deckwatch_common::GrayImage;

    fn sim_args(scenario: &str) -> SimulationArgs {
        SimulationArgs {
            scenario: crate::Scenario::from_name(scenario).unwrap(),
            frames: 3,
            rate: 10.0,
            seed: 5,
            ..SimulationArgs::default()
        }
    }

    #[test]
    fn frames_carry_their_truth_and_no_deck_frames_have_none() {
        for (name, in_view) in [("ship", true), ("nodeck", false)] {
            let sim = sim_args(name).resolve().unwrap();
            let cam = sim.camera.scaled_to(320, 240);
            let r = Renderer::new(cam, sim.deck, RenderOptions::realistic(), 5).unwrap();
            let mut fs = FrameSimulator::new(sim.scenario.profile(5, 1.0), r, 10.0, 0.01, 4, 5).unwrap();
            let mut img = GrayImage::new(320, 240);
            let t = fs.render_frame(7, &mut img.view_mut()).unwrap();
            assert_eq!(t.timestamp_ns, 700_000_000);
            assert_eq!(t.deck_in_view, in_view, "{name}");
            let gt = t.ground_truth();
            assert_eq!(gt.attitude().is_some(), in_view);
            assert!(gt.alt_m.is_some());
            if !in_view {
                // Only the sea: nothing near the marker brightness.
                assert!(img.data.iter().all(|&v| v < 120), "{name}");
            }
        }
        assert_eq!(Scenario::from_name("nodeck"), Some(Scenario::NoDeck));
    }

    #[test]
    fn image_args_resolve_and_validate() {
        let sim = sim_args("case1").resolve().unwrap();
        let mut a = ImageArgs {
            width: Some(640),
            height: Some(480),
            look: Look::Clean,
            blur_px: Some(1.0),
            contrast: Some(0.5),
            occlude: Some(4),
            glints: Some(3),
            distortion: Some(vec![-0.1, 0.0, 0.0, 0.0, 0.0]),
            ..ImageArgs::default()
        };
        let (cam, o) = a.resolve(&sim).unwrap();
        assert_eq!((cam.width, cam.height, cam.distortion.k1), (640, 480, -0.1));
        assert_eq!(o.optical_blur_px, 1.0);
        assert_eq!((o.occluded_marker, o.glints), (Some(4), 3));
        assert_eq!(
            o.marker_dn,
            o.deck_dn + 0.5 * (RenderOptions::default().marker_dn - o.deck_dn)
        );
        assert_eq!(o.read_noise_dn, 0.0);
        a.vignetting = Some(3.0);
        assert!(a.resolve(&sim).unwrap_err().to_string().contains("`vignetting`"));
    }

    /// A sparse kernel file beyond its bound is refused from its size, unread.
    #[test]
    fn a_psf_file_beyond_its_bound_is_refused_unread() {
        let sim = sim_args("case1").resolve().unwrap();
        let path = std::env::temp_dir().join(format!("deckwatch-huge-psf-{}.txt", std::process::id()));
        std::fs::File::create(&path).unwrap().set_len(10 << 30).unwrap();
        let a = ImageArgs {
            psf_file: Some(path.clone()),
            ..ImageArgs::default()
        };
        let e = a.resolve(&sim).map(|_| ()).unwrap_err().to_string();
        let _ = std::fs::remove_file(&path);
        assert!(
            e.contains("--psf-file") && e.contains("deckwatch-huge-psf-"),
            "{e}"
        );
        assert!(
            e.contains("10737418240 bytes") && e.contains("1048576 bytes"),
            "{e}"
        );
    }
}
