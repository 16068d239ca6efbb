//! Real cameras through libcamera: the `[libcamera]` configuration, the pixel formats deckwatch
//! takes luminance from, and frame-sequence bookkeeping. These parts are plain Rust and build
//! everywhere; the libcamera calls themselves (`device`) are the `libcamera` cargo feature,
//! because they need libcamera >= 0.4 on the build machine (Debian 12 has 0.0.3).

#[cfg(feature = "libcamera")]
mod device;
#[cfg(feature = "libcamera")]
pub use device::{list_cameras, LibcameraSource};

use deckwatch_common::{CameraModel, DeckLayout, InvalidField};
use deckwatch_formats::recording::{read_camera_json, RecordingError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A frame's instant (its middle row's mid-exposure: `CameraModel::row_time_s`) from the
/// sensor's timestamp. libcamera's `SensorTimestamp` is the start of the frame on the CSI-2
/// link on Raspberry Pi (and most pipelines): the first row's readout, at the end of its
/// exposure. The middle row is read `readout_s / 2` later and was exposed over the
/// `exposure_us` before its readout; without the exposure (no metadata), half of it is not
/// taken off.
pub fn frame_instant_ns(sensor_timestamp_ns: u64, exposure_us: Option<u32>, readout_s: f64) -> u64 {
    let half_readout_ns = (readout_s.clamp(0.0, 1.0) * 0.5e9).round() as u64;
    let half_exposure_ns = exposure_us.map_or(0, |us| u64::from(us) * 500);
    (sensor_timestamp_ns + half_readout_ns).saturating_sub(half_exposure_ns)
}

/// Whether this build has the libcamera source (the `libcamera` feature).
pub const LIBCAMERA_BUILT_IN: bool = cfg!(feature = "libcamera");

/// What a build without the feature says when asked for a camera.
pub const NOT_BUILT: &str = "this build has no libcamera support: rebuild with `--features libcamera` \
     (needs libcamera >= 0.4, e.g. Raspberry Pi OS or Debian 13: see README, \"Real camera\")";

/// What went wrong with a camera, and where: its configuration, a libcamera call, a frame.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// A `[libcamera]` value that cannot work, or that this camera cannot meet: its key
    /// (without the section) and why.
    #[error("libcamera.{}: {}", .0.field, .0.problem)]
    Config(#[from] InvalidField),
    /// The calibration (`libcamera.calibration`) cannot be read.
    #[error("libcamera.calibration: {0}")]
    Calibration(#[from] RecordingError),
    /// libcamera sees no camera.
    #[error(
        "no camera found by libcamera (is it connected and enabled? `deckwatch cameras` lists what libcamera sees)"
    )]
    NoCamera,
    /// Another process has the camera open.
    #[error("camera `{camera}` is busy: another process has it open ({doing}: {source})")]
    Busy {
        camera: String,
        doing: &'static str,
        source: std::io::Error,
    },
    /// The camera went away (unplugged, its driver unbound).
    #[error("camera `{camera}` is gone ({doing}: {source})")]
    Gone {
        camera: String,
        doing: &'static str,
        source: std::io::Error,
    },
    /// A libcamera call failed: what deckwatch was doing, and what libcamera said.
    #[error("libcamera: {doing}: {message}")]
    Libcamera { doing: &'static str, message: String },
    /// The camera cannot deliver what deckwatch needs (no video stream, no format it reads, a
    /// configuration it rejects).
    #[error("camera `{camera}` {problem}")]
    Unsupported { camera: String, problem: String },
    /// The camera delivered no frame for `libcamera.timeout_ms`.
    #[error("camera `{camera}` delivered no frame for {waited_ms} ms (libcamera.timeout_ms)")]
    Timeout { camera: String, waited_ms: u64 },
    /// The camera's thread ended (the camera stopped or was closed).
    #[error("camera `{camera}`: the camera thread stopped")]
    Stopped { camera: String },
    /// One frame is not usable: the caller counts and skips it, the camera goes on.
    #[error("{0}")]
    BadFrame(String),
    /// A plane or frame buffer shorter than `height` rows of `row_bytes` at `stride` need.
    #[error("{what} buffer too small: {bytes} bytes for {height} rows of {row_bytes} (stride {stride})")]
    BufferTooSmall {
        what: &'static str,
        bytes: usize,
        height: usize,
        row_bytes: usize,
        stride: usize,
    },
    /// This build has no libcamera (the `libcamera` cargo feature is off).
    #[error("{}", NOT_BUILT)]
    NotBuilt,
}

/// `[libcamera]`: the camera, its mode and controls, and the calibration of that mode.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraConfig {
    /// The camera: its index in `deckwatch cameras`' list or its id; empty = the first.
    pub camera: String,
    /// Image size; 0 = the calibration's size, else the camera's default for video.
    pub width: u32,
    pub height: u32,
    /// `auto` (the first format the camera offers whose first plane is 8-bit luminance, else one
    /// deckwatch converts) or a libcamera name: NV12, NV21, YUV420, YVU420, NV16, NV61, YUV422,
    /// R8, YUYV, YVYU, UYVY, VYUY, RGB888, BGR888, XRGB8888, XBGR8888, ARGB8888, ABGR8888.
    pub pixel_format: String,
    /// Frames per second (0 = the camera's default). Set on the camera through
    /// FrameDurationLimits; a camera without that control is triggered at this rate instead.
    pub frame_rate: f64,
    /// Fixed exposure time in microseconds; absent = automatic exposure.
    pub exposure_us: Option<u32>,
    /// Fixed analogue gain (1.0 = none); absent = automatic.
    pub gain: Option<f64>,
    /// Frame buffers (0 = the camera's suggestion).
    pub buffers: u32,
    /// The calibration of this camera mode: a `camera.json` in the recording format (intrinsics,
    /// distortion and the deck), or a recording folder holding one.
    pub calibration: Option<PathBuf>,
    /// Without a calibration: the named camera preset (`rpi-v2`, `paper`) scaled to the image
    /// size (assumes the mode sees the full sensor), with the paper's deck.
    pub preset: String,
    /// Stop after this many frames (0: until stopped).
    pub frames: u64,
    /// A camera that delivers no frame for this long is an error (ms).
    pub timeout_ms: u64,
    /// libcamera's own log level: debug, info, warn, error, fatal.
    pub log_level: String,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            camera: String::new(),
            width: 0,
            height: 0,
            pixel_format: "auto".into(),
            frame_rate: 10.0,
            exposure_us: None,
            gain: None,
            buffers: 4,
            calibration: None,
            preset: "rpi-v2".into(),
            frames: 0,
            timeout_ms: 2000,
            log_level: "error".into(),
        }
    }
}

/// A `[libcamera]` key's bad value.
fn invalid(key: &str, problem: impl Into<String>) -> CameraError {
    CameraError::Config(InvalidField::new(key, problem))
}

/// Which camera of a list of ids `selector` names.
pub fn select_camera(selector: &str, ids: &[String]) -> Result<usize, CameraError> {
    if ids.is_empty() {
        return Err(CameraError::NoCamera);
    }
    if selector.is_empty() {
        return Ok(0);
    }
    if let Some(i) = ids.iter().position(|id| id == selector) {
        return Ok(i);
    }
    match selector.parse::<usize>() {
        Ok(i) if i < ids.len() => Ok(i),
        _ => Err(invalid(
            "camera",
            format!(
                "no camera `{selector}` (cameras: {})",
                ids.iter()
                    .enumerate()
                    .map(|(i, id)| format!("{i}: {id}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

impl CameraConfig {
    /// Checks the values that need no camera; errors name the key.
    pub fn validate(&self) -> Result<(), CameraError> {
        if (self.width == 0) != (self.height == 0) {
            return Err(invalid("width/height", "give both or neither"));
        }
        if self.pixel_format != "auto" && LumaLayout::for_format(&self.pixel_format).is_none() {
            return Err(invalid(
                "pixel_format",
                format!(
                    "`{}` is not one deckwatch reads (auto, {})",
                    self.pixel_format,
                    LumaLayout::FORMATS.join(", ")
                ),
            ));
        }
        if !(self.frame_rate.is_finite() && (0.0..=1000.0).contains(&self.frame_rate)) {
            return Err(invalid(
                "frame_rate",
                format!("must be 0..=1000, got {}", self.frame_rate),
            ));
        }
        if self.exposure_us == Some(0) {
            return Err(invalid(
                "exposure_us",
                "must be > 0 (leave it out for automatic exposure)",
            ));
        }
        if let Some(g) = self.gain {
            if !(g.is_finite() && g >= 1.0) {
                return Err(invalid("gain", format!("must be >= 1.0, got {g}")));
            }
        }
        if self.buffers > 32 {
            return Err(invalid(
                "buffers",
                format!("must be 0..=32, got {}", self.buffers),
            ));
        }
        if self.timeout_ms == 0 {
            return Err(invalid("timeout_ms", "must be > 0"));
        }
        if !["debug", "info", "warn", "error", "fatal"].contains(&self.log_level.as_str()) {
            return Err(invalid(
                "log_level",
                format!("unknown `{}` (debug, info, warn, error, fatal)", self.log_level),
            ));
        }
        Ok(())
    }

    /// The calibration (camera model and deck) when one is configured.
    pub fn read_calibration(&self) -> Result<Option<(CameraModel, DeckLayout)>, CameraError> {
        let Some(path) = &self.calibration else {
            return Ok(None);
        };
        let (dir, file) = if path.is_dir() {
            (path.clone(), path.join(deckwatch_formats::recording::CAMERA_FILE))
        } else if path
            .file_name()
            .is_some_and(|n| n == deckwatch_formats::recording::CAMERA_FILE)
        {
            (
                path.parent().unwrap_or(Path::new(".")).to_path_buf(),
                path.clone(),
            )
        } else {
            return Err(invalid(
                "calibration",
                format!(
                    "{}: give a `{}` or a recording folder",
                    path.display(),
                    deckwatch_formats::recording::CAMERA_FILE
                ),
            ));
        };
        if !file.exists() {
            return Err(invalid(
                "calibration",
                format!("{}: no such file", file.display()),
            ));
        }
        Ok(Some(read_camera_json(&dir)?))
    }

    /// The size to ask the camera for (None: the camera's default).
    pub fn requested_size(&self) -> Result<Option<(u32, u32)>, CameraError> {
        let calibration = self.read_calibration()?;
        Ok(match (self.width, calibration) {
            (0, Some((c, _))) => Some((c.width, c.height)),
            (0, None) => None,
            (w, _) => Some((w, self.height)),
        })
    }

    /// The camera model and deck for frames of `width` x `height`: the calibration (which must
    /// be of that size), else the preset scaled to it.
    pub fn camera_model(&self, width: u32, height: u32) -> Result<(CameraModel, DeckLayout), CameraError> {
        if let Some((camera, deck)) = self.read_calibration()? {
            if (camera.width, camera.height) != (width, height) {
                return Err(invalid(
                    "calibration",
                    format!(
                        "it is for {}x{} images but the camera delivers {width}x{height}; \
                         calibrate this mode or set libcamera.width/height to the calibrated size",
                        camera.width, camera.height
                    ),
                ));
            }
            return Ok((camera, deck));
        }
        let preset = CameraModel::preset(&self.preset).ok_or_else(|| {
            invalid(
                "preset",
                format!(
                    "unknown `{}` ({})",
                    self.preset,
                    deckwatch_common::camera::CAMERA_PRESETS.join(", ")
                ),
            )
        })?;
        let camera = if (preset.width, preset.height) == (width, height) {
            preset
        } else {
            preset.scaled_to(width, height)
        };
        Ok((camera, DeckLayout::paper()))
    }

    /// The frame period the camera is asked for (None: its default).
    pub fn frame_period_ns(&self) -> Option<u64> {
        (self.frame_rate > 0.0).then(|| (1e9 / self.frame_rate).round() as u64)
    }
}

/// Where the 8-bit luminance of a pixel format is, so that one pass copies it into a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LumaLayout {
    /// The first plane is 8-bit luminance (NV12, YUV420, R8, ...): a row copy.
    Plane,
    /// Packed 4:2:2, two bytes a pixel, luminance at `offset` (0: YUYV/YVYU, 1: UYVY/VYUY).
    Packed422 { offset: usize },
    /// Packed RGB, `bytes` a pixel, red/green/blue at these byte offsets: BT.601 luma.
    Rgb {
        bytes: usize,
        r: usize,
        g: usize,
        b: usize,
    },
}

impl LumaLayout {
    /// The formats deckwatch reads, best first (those with a luminance plane need no conversion).
    pub const FORMATS: [&'static str; 18] = [
        "NV12", "YUV420", "NV21", "YVU420", "NV16", "NV61", "YUV422", "R8", "YUYV", "YVYU", "UYVY", "VYUY",
        "RGB888", "BGR888", "XRGB8888", "XBGR8888", "ARGB8888", "ABGR8888",
    ];

    /// The layout of a libcamera format name. libcamera names follow DRM: `RGB888` is stored
    /// B, G, R in memory; `XRGB8888` is B, G, R, X.
    pub fn for_format(name: &str) -> Option<Self> {
        Some(match name {
            "NV12" | "NV21" | "YUV420" | "YVU420" | "NV16" | "NV61" | "YUV422" | "R8" => Self::Plane,
            "YUYV" | "YVYU" => Self::Packed422 { offset: 0 },
            "UYVY" | "VYUY" => Self::Packed422 { offset: 1 },
            "RGB888" => Self::Rgb {
                bytes: 3,
                r: 2,
                g: 1,
                b: 0,
            },
            "BGR888" => Self::Rgb {
                bytes: 3,
                r: 0,
                g: 1,
                b: 2,
            },
            "XRGB8888" | "ARGB8888" => Self::Rgb {
                bytes: 4,
                r: 2,
                g: 1,
                b: 0,
            },
            "XBGR8888" | "ABGR8888" => Self::Rgb {
                bytes: 4,
                r: 0,
                g: 1,
                b: 2,
            },
            _ => return None,
        })
    }

    /// Whether the format carries luminance as is (no arithmetic per pixel).
    pub fn is_luma_plane(&self) -> bool {
        matches!(self, Self::Plane)
    }

    /// The format `auto` picks among those a camera offers.
    pub fn pick<'a>(offered: impl IntoIterator<Item = &'a str> + Clone) -> Option<&'a str> {
        Self::FORMATS
            .iter()
            .find_map(|want| offered.clone().into_iter().find(|f| f == want))
    }

    /// Plane sizes of a frame of the libcamera format `name` (one of [`Self::FORMATS`]) whose
    /// first plane has `stride` bytes a row, for buffers deckwatch allocates itself. Chroma
    /// planes follow libcamera's layout: half the rows for 4:2:0, half the stride when planar.
    pub fn plane_lengths(name: &str, stride: u32, height: u32) -> Vec<u32> {
        let full = stride * height;
        let half_rows = stride * height.div_ceil(2);
        let quarter = stride.div_ceil(2) * height.div_ceil(2);
        match name {
            "NV12" | "NV21" => vec![full, half_rows],
            "YUV420" | "YVU420" => vec![full, quarter, quarter],
            "NV16" | "NV61" => vec![full, full],
            "YUV422" => vec![full, stride.div_ceil(2) * height, stride.div_ceil(2) * height],
            _ => vec![full],
        }
    }

    /// Bytes of the first plane's row for `width` pixels (before any padding).
    pub fn row_bytes(&self, width: usize) -> usize {
        match self {
            Self::Plane => width,
            Self::Packed422 { .. } => 2 * width,
            Self::Rgb { bytes, .. } => bytes * width,
        }
    }

    /// Copies the luminance of the first plane (`src`, `src_stride` bytes a row) into `out`
    /// (`out_stride` bytes a row). Errors when a plane is shorter than the frame needs.
    pub fn extract(
        &self,
        src: &[u8],
        src_stride: usize,
        width: usize,
        height: usize,
        out: &mut [u8],
        out_stride: usize,
    ) -> Result<(), CameraError> {
        let row = self.row_bytes(width);
        if height > 0 && (src_stride < row || src.len() < (height - 1) * src_stride + row) {
            return Err(CameraError::BufferTooSmall {
                what: "camera",
                bytes: src.len(),
                height,
                row_bytes: row,
                stride: src_stride,
            });
        }
        if height > 0 && (out_stride < width || out.len() < (height - 1) * out_stride + width) {
            return Err(CameraError::BufferTooSmall {
                what: "frame",
                bytes: out.len(),
                height,
                row_bytes: width,
                stride: out_stride,
            });
        }
        for y in 0..height {
            let s = &src[y * src_stride..y * src_stride + row];
            let o = &mut out[y * out_stride..y * out_stride + width];
            match *self {
                Self::Plane => o.copy_from_slice(s),
                Self::Packed422 { offset } => {
                    for (o, px) in o.iter_mut().zip(s.chunks_exact(2)) {
                        *o = px[offset];
                    }
                }
                Self::Rgb { bytes, r, g, b } => {
                    for (o, px) in o.iter_mut().zip(s.chunks_exact(bytes)) {
                        *o = deckwatch_common::image::luma_bt601(px[r], px[g], px[b]);
                    }
                }
            }
        }
        Ok(())
    }
}

/// Counts frames lost between delivered ones from the sensor's frame sequence numbers (32-bit,
/// wrapping). A sequence that goes backwards (the camera restarted) is a new start, not a loss.
#[derive(Debug, Clone, Default)]
pub struct SequenceTracker {
    last: Option<u32>,
    /// Frames lost so far.
    pub lost: u64,
}

impl SequenceTracker {
    /// Records frame `seq`; returns how many frames were lost just before it.
    pub fn record(&mut self, seq: u32) -> u64 {
        let gap = match self.last {
            None => 0,
            Some(last) => {
                let d = seq.wrapping_sub(last);
                // A step beyond half the range is a restart (or a frame from before one).
                if d == 0 || d > u32::MAX / 2 {
                    0
                } else {
                    (d - 1) as u64
                }
            }
        };
        self.last = Some(seq);
        self.lost += gap;
        gap
    }
}

/// One camera as libcamera describes it (`deckwatch cameras`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CameraDescription {
    pub index: usize,
    pub id: String,
    pub model: String,
    pub location: String,
    /// Pixel formats of the video stream with their sizes (`WxH` or `WxH-WxH` ranges).
    pub formats: Vec<(String, Vec<String>)>,
    /// Controls deckwatch sets, with their ranges, where the camera has them.
    pub controls: Vec<(String, String)>,
}

impl std::fmt::Display for CameraDescription {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{}: {} (model {}, {})",
            self.index, self.id, self.model, self.location
        )?;
        for (format, sizes) in &self.formats {
            let usable = match LumaLayout::for_format(format) {
                Some(l) if l.is_luma_plane() => "luminance plane",
                Some(_) => "converted",
                None => "not usable",
            };
            writeln!(f, "   {format:<10} {:<22} {}", usable, sizes.join(" "))?;
        }
        for (name, range) in &self.controls {
            writeln!(f, "   control {name}: {range}")?;
        }
        Ok(())
    }
}

#[cfg(not(feature = "libcamera"))]
/// Lists the cameras libcamera sees (this build has no libcamera: an error saying so).
pub fn list_cameras() -> Result<(String, Vec<CameraDescription>), CameraError> {
    Err(CameraError::NotBuilt)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_pi_calibration_reads_with_its_readout() {
        let config = CameraConfig {
            calibration: Some(PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../deploy/camera-module-3-2304x1296/camera.json"
            ))),
            ..CameraConfig::default()
        };
        let (camera, _) = config.read_calibration().unwrap().unwrap();
        assert_eq!((camera.width, camera.height), (2304, 1296));
        assert!((camera.readout_s - 0.0178).abs() < 1e-12, "{camera:?}");
    }

    #[test]
    fn the_frame_instant_is_the_middle_rows_mid_exposure() {
        // Readout 20 ms, exposure 4 ms: the middle row is read 10 ms after the first row and
        // exposed from 4 ms before that.
        assert_eq!(frame_instant_ns(1_000_000_000, Some(4000), 0.020), 1_008_000_000);
        assert_eq!(frame_instant_ns(1_000_000_000, None, 0.020), 1_010_000_000);
        // A global shutter: the exposure alone.
        assert_eq!(frame_instant_ns(1_000_000_000, Some(4000), 0.0), 998_000_000);
        assert_eq!(frame_instant_ns(1_000, Some(4000), 0.0), 0);
    }

    #[test]
    fn planar_formats_copy_rows_and_drop_padding() {
        let (w, h, stride) = (4, 2, 6);
        let src: Vec<u8> = (0..(stride * h) as u8).collect();
        let mut out = vec![0u8; w * h];
        LumaLayout::for_format("NV12")
            .unwrap()
            .extract(&src, stride, w, h, &mut out, w)
            .unwrap();
        assert_eq!(out, [0, 1, 2, 3, 6, 7, 8, 9]);
    }

    #[test]
    fn packed_yuv_takes_every_luma_byte() {
        // Y0 U Y1 V | Y2 U Y3 V
        let yuyv = [10, 128, 20, 128, 30, 128, 40, 128];
        let mut out = [0u8; 4];
        LumaLayout::for_format("YUYV")
            .unwrap()
            .extract(&yuyv, 8, 4, 1, &mut out, 4)
            .unwrap();
        assert_eq!(out, [10, 20, 30, 40]);
        let uyvy = [128, 10, 128, 20, 128, 30, 128, 40];
        LumaLayout::for_format("UYVY")
            .unwrap()
            .extract(&uyvy, 8, 4, 1, &mut out, 4)
            .unwrap();
        assert_eq!(out, [10, 20, 30, 40]);
    }

    #[test]
    fn rgb_gives_bt601_luma_and_gray_stays_gray() {
        // DRM RGB888 is B, G, R in memory.
        let px = [0u8, 0, 255, 0, 255, 0, 255, 0, 0, 77, 77, 77];
        let mut out = [0u8; 4];
        LumaLayout::for_format("RGB888")
            .unwrap()
            .extract(&px, 12, 4, 1, &mut out, 4)
            .unwrap();
        assert_eq!(out, [77, 149, 29, 77]); // red, green, blue (255 x weight / 256), gray
        let xrgb = [255u8, 0, 0, 0, 9, 9, 9, 255];
        let mut out = [0u8; 2];
        LumaLayout::for_format("XRGB8888")
            .unwrap()
            .extract(&xrgb, 8, 2, 1, &mut out, 2)
            .unwrap();
        assert_eq!(out, [29, 9]);
    }

    #[test]
    fn short_buffers_are_errors_not_panics() {
        let l = LumaLayout::for_format("YUYV").unwrap();
        let mut out = [0u8; 16];
        let e = l.extract(&[0u8; 10], 8, 4, 2, &mut out, 4).unwrap_err();
        assert!(
            matches!(
                e,
                CameraError::BufferTooSmall {
                    what: "camera",
                    bytes: 10,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("too small"), "{e}");
        let e = LumaLayout::Plane
            .extract(&[0u8; 16], 4, 4, 4, &mut out[..8], 4)
            .unwrap_err();
        assert!(e.to_string().contains("frame buffer"), "{e}");
    }

    #[test]
    fn plane_sizes_follow_the_chroma_layout() {
        assert_eq!(LumaLayout::plane_lengths("NV12", 640, 480), [307_200, 153_600]);
        assert_eq!(
            LumaLayout::plane_lengths("YUV420", 640, 480),
            [307_200, 76_800, 76_800]
        );
        assert_eq!(LumaLayout::plane_lengths("NV16", 640, 480), [307_200, 307_200]);
        assert_eq!(LumaLayout::plane_lengths("YUYV", 1280, 480), [614_400]);
    }

    #[test]
    fn auto_prefers_a_luminance_plane_then_converts() {
        assert_eq!(LumaLayout::pick(["YUYV", "NV12", "RGB888"]), Some("NV12"));
        assert_eq!(LumaLayout::pick(["RGB888", "UYVY"]), Some("UYVY"));
        assert_eq!(LumaLayout::pick(["SRGGB10", "MJPEG"]), None);
    }

    #[test]
    fn sequence_gaps_count_lost_frames_across_wrap_and_restart() {
        let mut t = SequenceTracker::default();
        assert_eq!(t.record(5), 0);
        assert_eq!(t.record(6), 0);
        assert_eq!(t.record(9), 2);
        assert_eq!(t.record(u32::MAX - 1), 0, "backwards: a restart");
        assert_eq!(t.record(1), 2, "wraps: MAX and 0 lost");
        assert_eq!(t.lost, 4);
    }

    #[test]
    fn camera_selection_by_index_or_id() {
        let ids = vec!["/base/imx219@10".to_string(), "Virtual0".to_string()];
        assert_eq!(select_camera("", &ids).unwrap(), 0);
        assert_eq!(select_camera("1", &ids).unwrap(), 1);
        assert_eq!(select_camera("Virtual0", &ids).unwrap(), 1);
        let e = select_camera("2", &ids).unwrap_err().to_string();
        assert!(e.contains("libcamera.camera") && e.contains("1: Virtual0"), "{e}");
        let e = select_camera("", &[]).unwrap_err();
        assert!(matches!(e, CameraError::NoCamera), "{e}");
        assert!(e.to_string().contains("no camera"), "{e}");
    }

    #[test]
    fn config_checks_name_the_key() {
        let ok = CameraConfig::default();
        ok.validate().unwrap();
        let bad = |f: &dyn Fn(&mut CameraConfig)| {
            let mut c = CameraConfig::default();
            f(&mut c);
            c.validate().unwrap_err().to_string()
        };
        assert!(bad(&|c| c.pixel_format = "MJPEG".into()).contains("libcamera.pixel_format"));
        assert!(bad(&|c| c.width = 640).contains("libcamera.width/height"));
        assert!(bad(&|c| c.gain = Some(0.5)).contains("libcamera.gain"));
        assert!(bad(&|c| c.frame_rate = -1.0).contains("libcamera.frame_rate"));
        assert!(bad(&|c| c.log_level = "loud".into()).contains("libcamera.log_level"));
    }

    #[test]
    fn model_from_preset_or_a_matching_calibration() {
        let c = CameraConfig::default();
        let (cam, deck) = c.camera_model(640, 480).unwrap();
        assert_eq!((cam.width, cam.height), (640, 480));
        assert_eq!(deck, DeckLayout::paper());
        let dir = std::env::temp_dir().join(format!("dw-cal-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let model = CameraModel::centred(320, 240, 300.0, 300.0);
        deckwatch_formats::recording::write_camera_json(&dir, &model, &DeckLayout::paper()).unwrap();
        let c = CameraConfig {
            calibration: Some(dir.clone()),
            ..Default::default()
        };
        assert_eq!(c.requested_size().unwrap(), Some((320, 240)));
        assert_eq!(c.camera_model(320, 240).unwrap().0, model);
        let e = c.camera_model(640, 480).unwrap_err().to_string();
        assert!(
            e.contains("libcamera.calibration") && e.contains("320x240") && e.contains("640x480"),
            "{e}"
        );
        let c = CameraConfig {
            calibration: Some(dir.join("nothing.json")),
            ..Default::default()
        };
        assert!(c
            .read_calibration()
            .unwrap_err()
            .to_string()
            .contains("libcamera.calibration"));
        std::fs::remove_dir_all(dir).unwrap();
    }
}
