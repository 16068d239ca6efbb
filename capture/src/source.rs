//! The capture stage's sources and its part of the pipeline configuration: the simulator, the
//! replay of a recording (at its recorded rate, at a given rate, or as fast as possible), or a
//! real camera through libcamera (the `libcamera` feature). A source fills a frame into the
//! caller's buffer (the loaned shared-memory sample), so each frame is written once.

use crate::camera::CameraConfig;
use deckwatch_common::messages::{FrameSource, VehicleAttitude};
use deckwatch_common::vehicle::VehicleConfig;
use deckwatch_common::{CameraModel, DeckLayout, GrayViewMut, GroundTruth};
use deckwatch_estimate::VehicleTrack;
use deckwatch_formats::{Recording, RecordingError};
use deckwatch_sim::scenario::SimulationArgs;
use deckwatch_sim::sim::ImageArgs;
use deckwatch_sim::{FrameSimulator, Renderer};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Duration;

/// Why a source cannot be opened, or a frame not be read.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// A configuration value: `section.key` and what is wrong with it.
    #[error("{key}: {problem}")]
    Config { key: &'static str, problem: String },
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The simulator's options (`[sim]`, `[image]`) do not make a simulation.
    #[error("{0}")]
    Simulator(String),
    /// The camera failed (libcamera), or this build has no camera support.
    #[error(transparent)]
    Camera(#[from] crate::camera::CameraError),
    /// One frame could not be read (it is counted and skipped; the source goes on).
    #[error("{0}")]
    BadFrame(String),
}

fn config_error(key: &'static str, problem: impl Into<String>) -> SourceError {
    SourceError::Config {
        key,
        problem: problem.into(),
    }
}

/// `[source]`: which source, and what it tells beside the pixels.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct SourceConfig {
    /// `sim`, `replay` or `libcamera`.
    pub kind: FrameSource,
    /// Publish the true altitude (simulator, a recording's `alt_m` column) as the altimeter
    /// reading; the paper's printed estimator needs one.
    pub altimeter: bool,
}

impl Default for SourceConfig {
    fn default() -> Self {
        Self {
            kind: FrameSource::Simulator,
            altimeter: true,
        }
    }
}

/// `[replay]`: replay of a recording.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReplayConfig {
    /// The recording folder.
    pub recording: Option<PathBuf>,
    /// Frames per second; absent: the recorded timestamps' rate; 0: as fast as possible.
    pub rate_hz: Option<f64>,
    /// Times through the recording; 0 = until stopped.
    pub loops: u32,
    /// Stop after this many frames (0: when the loops are done).
    pub frames: u64,
    /// Decode every frame before starting, so that capturing a frame is one copy (otherwise
    /// each frame's PNG is decoded straight into shared memory when it is due).
    pub preload: bool,
    /// Refuse to preload more than this many MiB.
    pub preload_limit_mib: u64,
}

impl Default for ReplayConfig {
    fn default() -> Self {
        Self {
            recording: None,
            rate_hz: None,
            loops: 1,
            frames: 0,
            preload: true,
            preload_limit_mib: 2048,
        }
    }
}

/// The capture stage's sections of the pipeline configuration.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(default)]
pub struct CaptureConfig {
    pub source: SourceConfig,
    pub sim: SimulationArgs,
    pub image: ImageArgs,
    pub replay: ReplayConfig,
    pub libcamera: CameraConfig,
    /// How far replay may interpolate a recording's `vehicle.csv` (`[vehicle] max_gap_ms`).
    pub vehicle: VehicleConfig,
}

impl CaptureConfig {
    /// Checks the configuration without opening the source (no rendering, no decoding): what
    /// the launcher does before it starts the stages.
    pub fn check(&self) -> Result<(), SourceError> {
        match self.source.kind {
            FrameSource::Simulator => {
                self.resolve_sim()?;
                Ok(())
            }
            FrameSource::Replay => {
                let path = self.recording()?;
                if is_flight_recording(path) {
                    // Only that it is one: its frames are read when the source opens.
                    deckwatch_flight::FlightReader::open(path)
                        .map_err(|e| config_error("replay.recording", e.to_string()))?;
                } else {
                    Recording::open(path)?;
                }
                self.replay_pace()?;
                Ok(())
            }
            FrameSource::Libcamera => {
                self.libcamera.validate()?;
                if let Some(size) = self.libcamera.requested_size()? {
                    self.libcamera.camera_model(size.0, size.1)?;
                }
                if !crate::camera::LIBCAMERA_BUILT_IN {
                    return Err(not_built());
                }
                Ok(())
            }
        }
    }

    /// The simulation and its image as configured.
    fn resolve_sim(
        &self,
    ) -> Result<
        (
            deckwatch_sim::scenario::Simulation,
            CameraModel,
            deckwatch_sim::RenderOptions,
        ),
        SourceError,
    > {
        let sim = self
            .sim
            .resolve()
            .map_err(|e| SourceError::Simulator(format!("[sim] {e}")))?;
        let (camera, options) = self
            .image
            .resolve(&sim)
            .map_err(|e| SourceError::Simulator(format!("[image] {e}")))?;
        Ok((sim, camera, options))
    }

    /// The recording to replay.
    fn recording(&self) -> Result<&std::path::Path, SourceError> {
        self.replay.recording.as_deref().ok_or(config_error(
            "replay.recording",
            "the recording folder is required for source.kind = \"replay\"",
        ))
    }

    fn replay_pace(&self) -> Result<Pace, SourceError> {
        Ok(match self.replay.rate_hz {
            None => Pace::Recorded,
            Some(0.0) => Pace::AsFastAsPossible,
            Some(hz) if (MIN_RATE_HZ..=MAX_RATE_HZ).contains(&hz) => Pace::Fixed((1e9 / hz).round() as u64),
            Some(hz) => {
                return Err(config_error(
                    "replay.rate_hz",
                    format!(
                    "must be 0 (as fast as possible) or within [{MIN_RATE_HZ}, {MAX_RATE_HZ}] Hz, got {hz}"
                ),
                ))
            }
        })
    }

    /// Opens the configured source.
    pub fn open(&self) -> Result<CaptureSource, SourceError> {
        match self.source.kind {
            FrameSource::Simulator => self.open_sim(),
            FrameSource::Replay => self.open_replay(),
            FrameSource::Libcamera => self.open_camera(),
        }
    }

    fn open_sim(&self) -> Result<CaptureSource, SourceError> {
        self.open_sim_with(self.sim.profile())
    }

    /// The configured simulator (camera, image, rate, seed) rendering `profile` instead of the
    /// configured scenario's motion: a closed-loop landing's scene
    /// ([`deckwatch_sim::landing::ClosedLoopScene`]).
    pub fn open_sim_with(
        &self,
        profile: Box<dyn deckwatch_sim::motion::MotionProfile + Send + Sync>,
    ) -> Result<CaptureSource, SourceError> {
        let (sim, camera, options) = self.resolve_sim()?;
        let renderer = Renderer::new(camera, sim.deck, options, self.sim.seed)
            .map_err(|e| SourceError::Simulator(format!("[image] {e}")))?;
        let frames = FrameSimulator::new(
            profile,
            renderer,
            self.sim.rate,
            self.image.exposure_ms / 1e3,
            8,
            self.sim.seed,
        )
        .map_err(|e| SourceError::Simulator(format!("[sim] {e}")))?;
        Ok(CaptureSource {
            // What the pipeline is told (the renderer keeps the lens itself).
            camera: self.image.calibrated(&camera),
            deck: sim.deck,
            altimeter: self.source.altimeter,
            inner: Inner::Sim {
                sim: Box::new(frames),
                frames: self.sim.frames as u64,
                period_ns: (1e9 / self.sim.rate).round() as u64,
            },
        })
    }

    #[cfg(not(feature = "libcamera"))]
    fn open_camera(&self) -> Result<CaptureSource, SourceError> {
        self.libcamera.validate()?;
        Err(not_built())
    }

    #[cfg(feature = "libcamera")]
    fn open_camera(&self) -> Result<CaptureSource, SourceError> {
        let camera = crate::camera::LibcameraSource::open(&self.libcamera)?;
        let (model, deck) = self.libcamera.camera_model(camera.width(), camera.height())?;
        Ok(CaptureSource {
            camera: model,
            deck,
            altimeter: false,
            inner: Inner::Camera {
                camera: Box::new(camera),
                frames: self.libcamera.frames,
            },
        })
    }

    fn open_replay(&self) -> Result<CaptureSource, SourceError> {
        let r = &self.replay;
        let dir = self.recording()?;
        if is_flight_recording(dir) {
            // A flight recording's frames are in memory once read.
            let deckwatch_flight::convert::ReplayableFlight {
                recording: rec,
                images,
                ended_early,
            } = deckwatch_flight::convert::recording_of(dir, r.preload_limit_mib.saturating_mul(1 << 20))
                .map_err(|e| config_error("replay.recording", e.to_string()))?;
            if let Some(why) = ended_early {
                deckwatch_common::say!(
                    "{}: the recording ends early ({why}); replaying its {} frames",
                    dir.display(),
                    rec.frames.len()
                );
            }
            let preloaded = Some(images.into_iter().map(Ok).collect());
            return self.replay_source(rec, preloaded);
        }
        let rec = Recording::open(dir)?;
        if rec.frames.is_empty() {
            return Err(config_error(
                "replay.recording",
                format!("{}: the recording has no frames", dir.display()),
            ));
        }
        let frame_bytes = rec.camera.width as u64 * rec.camera.height as u64;
        let preloaded = if r.preload {
            let mib = (frame_bytes * rec.frames.len() as u64).div_ceil(1 << 20);
            if mib > r.preload_limit_mib {
                return Err(config_error(
                    "replay.preload",
                    format!(
                        "{} frames need {mib} MiB, more than replay.preload_limit_mib = {}; \
                     raise the limit or set preload = false",
                        rec.frames.len(),
                        r.preload_limit_mib
                    ),
                ));
            }
            // A frame that cannot be read stays None: it is counted and skipped when due.
            let images = rec
                .frames
                .iter()
                .map(|f| rec.read_image(f).map(|img| img.data).map_err(|e| e.to_string()))
                .collect();
            Some(images)
        } else {
            None
        };
        self.replay_source(rec, preloaded)
    }

    fn replay_source(
        &self,
        rec: Recording,
        preloaded: Option<Vec<Result<Vec<u8>, String>>>,
    ) -> Result<CaptureSource, SourceError> {
        let r = &self.replay;
        let pace = self.replay_pace()?;
        let vehicle = rec.vehicle_samples.as_ref().map(|samples| {
            let mut track = VehicleTrack::new(samples.len());
            for &s in samples {
                track.push(s);
            }
            track
        });
        Ok(CaptureSource {
            camera: rec.camera,
            deck: rec.deck,
            altimeter: self.source.altimeter,
            inner: Inner::Replay {
                truth_known: rec.has_attitude_truth(),
                vehicle,
                max_gap_ns: self.vehicle.max_gap_ns(),
                rec: Box::new(rec),
                preloaded,
                pace,
                loops: r.loops,
                max_frames: r.frames,
            },
        })
    }
}

/// Whether a replay path is an MCAP flight recording (a file) rather than a recording folder.
pub fn is_flight_recording(path: &std::path::Path) -> bool {
    path.is_file()
}

/// Frame `k` of a replay (looping) on the recording's timeline, in ns after its first frame:
/// one loop lasts the recorded span plus one mean frame period, so time keeps going forward
/// across loops.
fn recorded_offset_ns(rec: &Recording, k: u64) -> u64 {
    let n = rec.frames.len() as u64;
    let t0 = rec.frames[0].timestamp_ns;
    let last = rec.frames[n as usize - 1].timestamp_ns.saturating_sub(t0);
    let period = if n > 1 { last / (n - 1) } else { 100_000_000 };
    let (lap, j) = (k / n, (k % n) as usize);
    // Saturating: recorded timestamps near u64::MAX, looped, must not wrap to the past.
    lap.saturating_mul(last.saturating_add(period))
        .saturating_add(rec.frames[j].timestamp_ns.saturating_sub(t0))
}

/// The error of a build without the `libcamera` feature asked for a camera.
fn not_built() -> SourceError {
    SourceError::Camera(crate::camera::CameraError::NotBuilt)
}

/// Frame rates a source accepts (Hz), the simulator's: defined with the simulation options.
pub use deckwatch_sim::scenario::{MAX_RATE_HZ, MIN_RATE_HZ};

/// How replay paces frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pace {
    Recorded,
    Fixed(u64),
    AsFastAsPossible,
}

/// What a source knows of a frame besides its pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct CapturedFrame {
    /// The frame's index at its source (recording index, simulator frame number).
    pub source_index: u64,
    /// The frame's time at its source (ns): simulated time, the recording's timestamps
    /// (continued across replay loops), the sensor timestamp.
    pub source_timestamp_ns: u64,
    pub truth: GroundTruth,
    /// Whether the source knows the truth (then a missing attitude means "no deck").
    pub truth_known: bool,
    /// The altimeter reading when the source has one.
    pub altitude_m: Option<f64>,
    /// The attitude of the camera's vehicle, and how the source knows it.
    pub vehicle: VehicleAttitude,
    /// When the frame was taken (CLOCK_MONOTONIC ns), when the source knows (a camera's sensor
    /// timestamp); None: the time it was captured into shared memory.
    pub captured_ns: Option<u64>,
    /// Frames the source lost just before this one (a camera's sequence gaps).
    pub dropped_before: u64,
}

enum Inner {
    Sim {
        sim: Box<FrameSimulator>,
        frames: u64,
        period_ns: u64,
    },
    Replay {
        rec: Box<Recording>,
        preloaded: Option<Vec<Result<Vec<u8>, String>>>,
        pace: Pace,
        loops: u32,
        max_frames: u64,
        truth_known: bool,
        /// `vehicle.csv`, preferred to the vehicle columns.
        vehicle: Option<VehicleTrack>,
        max_gap_ns: u64,
    },
    #[cfg(feature = "libcamera")]
    Camera {
        camera: Box<crate::camera::LibcameraSource>,
        frames: u64,
    },
}

/// An opened source.
pub struct CaptureSource {
    camera: CameraModel,
    deck: DeckLayout,
    altimeter: bool,
    inner: Inner,
}

impl CaptureSource {
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    pub fn deck(&self) -> &DeckLayout {
        &self.deck
    }

    pub fn kind(&self) -> FrameSource {
        match self.inner {
            Inner::Sim { .. } => FrameSource::Simulator,
            Inner::Replay { .. } => FrameSource::Replay,
            #[cfg(feature = "libcamera")]
            Inner::Camera { .. } => FrameSource::Libcamera,
        }
    }

    /// Bytes of one frame (tightly packed rows).
    pub fn frame_bytes(&self) -> usize {
        self.camera.width as usize * self.camera.height as usize
    }

    /// Frames the source will deliver; None = until stopped.
    pub fn len(&self) -> Option<u64> {
        match &self.inner {
            Inner::Sim { frames, .. } => (*frames > 0).then_some(*frames),
            Inner::Replay {
                rec,
                loops,
                max_frames,
                ..
            } => {
                let all = (*loops > 0).then(|| *loops as u64 * rec.frames.len() as u64);
                match (all, *max_frames) {
                    (a, 0) => a,
                    (None, m) => Some(m),
                    (Some(a), m) => Some(a.min(m)),
                }
            }
            #[cfg(feature = "libcamera")]
            Inner::Camera { frames, .. } => (*frames > 0).then_some(*frames),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == Some(0)
    }

    /// When frame `k` is due, in ns after the first; None = as fast as possible.
    pub fn due_ns(&self, k: u64) -> Option<u64> {
        match &self.inner {
            // Saturating: a run long enough to overflow is due "never", not at a wrapped time.
            Inner::Sim { period_ns, .. } => Some(k.saturating_mul(*period_ns)),
            Inner::Replay { rec, pace, .. } => match pace {
                Pace::AsFastAsPossible => None,
                Pace::Fixed(p) => Some(k.saturating_mul(*p)),
                Pace::Recorded => Some(recorded_offset_ns(rec, k)),
            },
            // A camera sets its own pace: frames are taken as they arrive.
            #[cfg(feature = "libcamera")]
            Inner::Camera { .. } => None,
        }
    }

    /// Waits up to `wait` until the next frame can be captured: at once for the simulator and
    /// replay; for a camera, until it delivers one (Ok(false): not yet, ask again). An error
    /// means the source failed (a camera that stopped delivering).
    pub fn wait_ready(&mut self, wait: Duration) -> Result<bool, SourceError> {
        match &mut self.inner {
            #[cfg(feature = "libcamera")]
            Inner::Camera { camera, .. } => Ok(camera.wait(wait)?),
            _ => {
                let _ = wait;
                Ok(true)
            }
        }
    }

    /// A line on what the source is (for a camera: the mode it opened).
    pub fn describe(&self) -> String {
        match &self.inner {
            Inner::Sim { period_ns, .. } => format!(
                "simulator, {}x{} at {:.1} fps",
                self.camera.width,
                self.camera.height,
                1e9 / *period_ns as f64
            ),
            Inner::Replay { rec, .. } => {
                format!("replay of {} ({} frames)", rec.dir.display(), rec.frames.len())
            }
            #[cfg(feature = "libcamera")]
            Inner::Camera { camera, .. } => camera.summary().to_string(),
        }
    }

    /// Writes frame `k` into `out` (`stride` bytes a row, at least `frame_bytes()` in all) and
    /// returns what is known of it. An error means the frame is bad (counted and skipped).
    pub fn capture(&mut self, k: u64, out: &mut [u8], stride: usize) -> Result<CapturedFrame, SourceError> {
        self.capture_frame(k, out, stride).map_err(SourceError::BadFrame)
    }

    fn capture_frame(&mut self, k: u64, out: &mut [u8], stride: usize) -> Result<CapturedFrame, String> {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        let altimeter = self.altimeter;
        #[cfg(feature = "libcamera")]
        let readout_s = self.camera.readout_s;
        match &mut self.inner {
            Inner::Sim { sim, .. } => {
                let mut view = GrayViewMut::new(out, w, h, stride).map_err(|e| e.to_string())?;
                let t = sim.render_frame(k, &mut view).map_err(|e| e.to_string())?;
                let truth = t.ground_truth();
                Ok(CapturedFrame {
                    source_index: k,
                    source_timestamp_ns: t.timestamp_ns,
                    altitude_m: if altimeter { truth.alt_m } else { None },
                    vehicle: t.vehicle(),
                    truth,
                    truth_known: true,
                    captured_ns: None,
                    dropped_before: 0,
                })
            }
            Inner::Replay {
                rec,
                preloaded,
                truth_known,
                vehicle,
                max_gap_ns,
                ..
            } => {
                let j = (k % rec.frames.len() as u64) as usize;
                let f = &rec.frames[j];
                if stride != w || out.len() < w * h {
                    return Err(format!(
                        "replay writes packed rows; got stride {stride} for width {w}"
                    ));
                }
                match preloaded {
                    Some(images) => match &images[j] {
                        Ok(px) => out[..w * h].copy_from_slice(px),
                        Err(e) => return Err(e.clone()),
                    },
                    None => rec
                        .read_image_into(f, &mut out[..w * h])
                        .map_err(|e| e.to_string())?,
                }
                Ok(CapturedFrame {
                    source_index: f.index,
                    // Continued across loops (see `recorded_offset_ns`): the decision's timeline.
                    source_timestamp_ns: rec.frames[0].timestamp_ns + recorded_offset_ns(rec, k),
                    truth: f.truth,
                    truth_known: *truth_known,
                    altitude_m: if altimeter { f.truth.alt_m } else { None },
                    // At the frame's own time on the recording's clock (not the looped one).
                    vehicle: {
                        let v = match vehicle {
                            Some(track) => track.vehicle_attitude_at(f.timestamp_ns, *max_gap_ns),
                            None => VehicleAttitude::from_rpy(f.truth.vehicle_attitude())
                                .with_rate_dps(f.truth.vehicle_rate_dps().unwrap_or([f64::NAN; 3])),
                        };
                        // The stream's height first, else the frame's column.
                        match f.truth.vehicle_height_m {
                            Some(h) if !v.height_m.is_finite() => v.with_height(h),
                            _ => v,
                        }
                    },
                    captured_ns: None,
                    dropped_before: 0,
                })
            }
            #[cfg(feature = "libcamera")]
            Inner::Camera { camera, .. } => {
                let _ = altimeter;
                let f = camera.take(out, stride).map_err(|e| e.to_string())?;
                // The sensor's start of frame -> the frame's instant (the vehicle's attitude
                // is taken there); a completion time is left as it is.
                let instant_ns = if f.sensor_timestamp {
                    crate::camera::frame_instant_ns(f.timestamp_ns, f.exposure_us, readout_s)
                } else {
                    f.timestamp_ns
                };
                Ok(CapturedFrame {
                    source_index: f.sequence.map_or(camera.delivered() - 1, u64::from),
                    source_timestamp_ns: instant_ns,
                    truth: GroundTruth::default(),
                    truth_known: false,
                    altitude_m: None,
                    vehicle: VehicleAttitude::LEVEL,
                    captured_ns: Some(instant_ns),
                    dropped_before: f.dropped_before,
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replay_without_a_recording_names_the_key() {
        let c = CaptureConfig {
            source: SourceConfig {
                kind: FrameSource::Replay,
                altimeter: true,
            },
            ..Default::default()
        };
        let e = c.open().err().unwrap();
        assert!(
            matches!(
                e,
                SourceError::Config {
                    key: "replay.recording",
                    ..
                }
            ),
            "{e}"
        );
        assert!(c.check().unwrap_err().to_string().contains("replay.recording"));
    }

    #[test]
    fn sim_source_paces_and_fills() {
        let mut c = CaptureConfig::default();
        c.sim.frames = 3;
        c.sim.rate = 20.0;
        (c.image.width, c.image.height) = (Some(160), Some(120));
        let mut src = c.open().unwrap();
        assert_eq!(src.len(), Some(3));
        assert_eq!(src.due_ns(2), Some(100_000_000));
        let mut buf = vec![0u8; src.frame_bytes()];
        let f = src.capture(1, &mut buf, 160).unwrap();
        assert_eq!(f.source_index, 1);
        assert!(f.truth_known && f.altitude_m.is_some());
        assert!(buf.iter().any(|&b| b != 0));
    }
}
