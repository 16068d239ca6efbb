//! The libcamera calls (the `libcamera` feature).
//!
//! libcamera's camera objects borrow the camera manager, so one thread owns them all: it opens,
//! configures and starts the camera, then only queues requests. A completed request (with its
//! buffer) travels to the capture thread through a channel; capture copies the luminance plane
//! straight into its loaned shared-memory sample and sends the request back to be queued again.

use super::{select_camera, CameraConfig, CameraDescription, CameraError, LumaLayout, SequenceTracker};
use deckwatch_common::messages::monotonic_ns;
use libcamera::{
    camera::{ActiveCamera, CameraConfigurationStatus},
    camera_manager::CameraManager,
    control::{ControlInfoMap, ControlList},
    control_value::ControlValue,
    controls::{self, ControlId},
    framebuffer::{AsFrameBuffer, FrameBufferPlane, FrameMetadataStatus, OwnedFrameBuffer},
    framebuffer_allocator::{FrameBuffer, FrameBufferAllocator},
    framebuffer_map::MemoryMappedFrameBuffer,
    geometry::Size,
    pixel_format::PixelFormat,
    properties,
    request::{Request, RequestStatus, ReuseFlag},
    stream::{Stream, StreamFormatsRef, StreamRole},
};
use std::any::Any;
use std::collections::VecDeque;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How frames are paced.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Pacing {
    /// The camera runs at the configured rate (FrameDurationLimits); all buffers stay queued.
    /// If it turns out to ignore the control (frames far faster), pacing becomes `Triggered`.
    Camera(Duration),
    /// The camera has no frame-duration control: one request is queued per period.
    Triggered(Duration),
    /// The camera's own rate.
    Free,
}

/// What the camera thread reports once the camera runs.
struct Started {
    id: String,
    stream: Stream,
    format: String,
    layout: LumaLayout,
    width: u32,
    height: u32,
    stride: u32,
    summary: String,
}

/// A completed request and when it completed.
struct Completed {
    request: Request,
    completed_ns: u64,
}

/// A frame's bookkeeping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraFrame {
    /// The sensor's frame sequence number, when the camera reports it.
    pub sequence: Option<u32>,
    /// The frame's time: the sensor timestamp (CLOCK_MONOTONIC, ns) when the camera gives one,
    /// else the time the request completed.
    pub timestamp_ns: u64,
    pub sensor_timestamp: bool,
    /// The frame's exposure time (the request's `ExposureTime` metadata), when reported.
    pub exposure_us: Option<u32>,
    /// Frames the sensor produced but deckwatch never got, just before this one.
    pub dropped_before: u64,
}

/// A running libcamera camera.
pub struct LibcameraSource {
    started: Started,
    frames: Option<mpsc::Receiver<Completed>>,
    recycle: Option<mpsc::Sender<Request>>,
    thread: Option<JoinHandle<()>>,
    ready: Option<Completed>,
    sequence: SequenceTracker,
    unreported_drops: u64,
    delivered: u64,
    timeout: Duration,
    last_frame: Instant,
}

impl LibcameraSource {
    /// Opens, configures and starts the camera of `config`.
    pub fn open(config: &CameraConfig) -> Result<Self, CameraError> {
        config.validate()?;
        let requested = config.requested_size()?;
        quiet_libcamera(&config.log_level);
        let (started_tx, started_rx) = mpsc::sync_channel(1);
        let (done_tx, done_rx) = mpsc::channel();
        let (recycle_tx, recycle_rx) = mpsc::channel();
        let cfg = config.clone();
        let thread = std::thread::Builder::new()
            .name("libcamera".into())
            .spawn(move || {
                if let Err(e) = run_camera(&cfg, requested, &started_tx, done_tx, recycle_rx) {
                    let _ = started_tx.send(Err(e));
                }
            })
            .map_err(|e| libcamera_error("starting the camera thread", e))?;
        let started = match started_rx.recv() {
            Ok(Ok(s)) => s,
            Ok(Err(e)) => {
                let _ = thread.join();
                return Err(e);
            }
            Err(_) => {
                let _ = thread.join();
                return Err(libcamera_error(
                    "starting the camera",
                    "the camera thread ended before the camera started",
                ));
            }
        };
        Ok(Self {
            started,
            frames: Some(done_rx),
            recycle: Some(recycle_tx),
            thread: Some(thread),
            ready: None,
            sequence: SequenceTracker::default(),
            unreported_drops: 0,
            delivered: 0,
            timeout: Duration::from_millis(config.timeout_ms),
            last_frame: Instant::now(),
        })
    }

    pub fn width(&self) -> u32 {
        self.started.width
    }

    pub fn height(&self) -> u32 {
        self.started.height
    }

    /// What was opened: camera, format, size, buffers, pacing and any control left unset.
    pub fn summary(&self) -> &str {
        &self.started.summary
    }

    /// Frames the sensor produced that deckwatch never received (from sequence gaps).
    pub fn lost(&self) -> u64 {
        self.sequence.lost
    }

    /// Waits up to `wait` for the next frame: Ok(false) if none came yet; an error when the
    /// camera delivered nothing for `timeout_ms` or its thread ended.
    pub fn wait(&mut self, wait: Duration) -> Result<bool, CameraError> {
        if self.ready.is_some() {
            return Ok(true);
        }
        let stopped = || CameraError::Stopped {
            camera: self.started.id.clone(),
        };
        let frames = self.frames.as_ref().ok_or_else(stopped)?;
        match frames.recv_timeout(wait) {
            Ok(c) => {
                self.ready = Some(c);
                self.last_frame = Instant::now();
                Ok(true)
            }
            Err(RecvTimeoutError::Timeout) if self.last_frame.elapsed() < self.timeout => Ok(false),
            Err(RecvTimeoutError::Timeout) => Err(CameraError::Timeout {
                camera: self.started.id.clone(),
                waited_ms: self.timeout.as_millis() as u64,
            }),
            Err(RecvTimeoutError::Disconnected) => Err(stopped()),
        }
    }

    /// Copies the waiting frame's luminance into `out` (`stride` bytes a row) and gives its
    /// buffer back to the camera. An error is a bad frame (counted and skipped by the caller).
    pub fn take(&mut self, out: &mut [u8], stride: usize) -> Result<CameraFrame, CameraError> {
        let c = self
            .ready
            .take()
            .ok_or_else(|| CameraError::BadFrame("no frame is waiting (take before wait)".into()))?;
        let result = self.copy(&c, out, stride);
        let mut request = c.request;
        request.reuse(ReuseFlag::REUSE_BUFFERS);
        if let Some(r) = &self.recycle {
            // The camera thread is gone only when stopping; the request is dropped then.
            let _ = r.send(request);
        }
        self.delivered += 1;
        result
    }

    fn copy(&mut self, c: &Completed, out: &mut [u8], stride: usize) -> Result<CameraFrame, CameraError> {
        let s = &self.started;
        if c.request.status() != RequestStatus::Complete {
            return Err(CameraError::BadFrame(format!(
                "request {:?} (not complete)",
                c.request.status()
            )));
        }
        let (planes, meta) = mapped_planes(&c.request, &s.stream).ok_or_else(|| {
            CameraError::BadFrame("the completed request carries no buffer for the stream".into())
        })?;
        let mut frame = CameraFrame {
            sequence: None,
            timestamp_ns: c.completed_ns,
            sensor_timestamp: false,
            exposure_us: None,
            dropped_before: 0,
        };
        if let Some((status, sequence, timestamp)) = meta {
            // Gaps count even when this frame turns out bad, so a loss is reported once.
            let gap = self.sequence.record(sequence);
            self.unreported_drops += gap;
            frame.sequence = Some(sequence);
            if status != FrameMetadataStatus::Success {
                return Err(CameraError::BadFrame(format!(
                    "the camera marked frame {sequence} {status:?}"
                )));
            }
            if plausible(timestamp, c.completed_ns) {
                frame.timestamp_ns = timestamp;
                frame.sensor_timestamp = true;
            }
        }
        if !frame.sensor_timestamp {
            if let Ok(t) = c.request.metadata().get::<controls::SensorTimestamp>() {
                if t.0 > 0 && plausible(t.0 as u64, c.completed_ns) {
                    frame.timestamp_ns = t.0 as u64;
                    frame.sensor_timestamp = true;
                }
            }
        }
        if let Ok(t) = c.request.metadata().get::<controls::ExposureTime>() {
            frame.exposure_us = u32::try_from(t.0).ok();
        }
        let first = planes
            .first()
            .ok_or_else(|| CameraError::BadFrame("the buffer has no planes".into()))?;
        s.layout.extract(
            first,
            s.stride as usize,
            s.width as usize,
            s.height as usize,
            out,
            stride,
        )?;
        frame.dropped_before = std::mem::take(&mut self.unreported_drops);
        Ok(frame)
    }

    /// Frames delivered so far (good and bad).
    pub fn delivered(&self) -> u64 {
        self.delivered
    }

    /// The pixel format read.
    pub fn format(&self) -> &str {
        &self.started.format
    }
}

impl Drop for LibcameraSource {
    fn drop(&mut self) {
        // Requests go back to libcamera (dropped while the camera still exists): first those
        // held here, then the channel, then the camera thread stops the camera (cancelled
        // requests are dropped in libcamera's completion callback, whose channel is closed).
        self.ready = None;
        if let Some(frames) = self.frames.take() {
            while frames.try_recv().is_ok() {}
        }
        self.recycle = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A sensor timestamp comparable with the completion time (same clock, not in the future,
/// within 10 s): otherwise it is not used for latency.
fn plausible(timestamp_ns: u64, completed_ns: u64) -> bool {
    timestamp_ns > 0 && timestamp_ns <= completed_ns && completed_ns - timestamp_ns < 10_000_000_000
}

type Meta = (FrameMetadataStatus, u32, u64);

/// The mapped planes of the stream's buffer, and its metadata when the camera filled it in.
fn mapped_planes<'a>(request: &'a Request, stream: &Stream) -> Option<(Vec<&'a [u8]>, Option<Meta>)> {
    fn get<'a, T: AsFrameBuffer + Any + 'static>(
        request: &'a Request,
        stream: &Stream,
    ) -> Option<(Vec<&'a [u8]>, Option<Meta>)> {
        let fb: &MemoryMappedFrameBuffer<T> = request.buffer(stream)?;
        let meta = fb.metadata().map(|m| (m.status(), m.sequence(), m.timestamp()));
        Some((fb.data(), meta))
    }
    get::<FrameBuffer>(request, stream).or_else(|| get::<OwnedFrameBuffer>(request, stream))
}

/// libcamera's own logging, unless the user set LIBCAMERA_LOG_LEVELS.
fn quiet_libcamera(level: &str) {
    if std::env::var_os("LIBCAMERA_LOG_LEVELS").is_none() {
        // Read by libcamera when its logger starts (with the first camera manager).
        std::env::set_var("LIBCAMERA_LOG_LEVELS", format!("*:{}", level.to_uppercase()));
    }
}

/// The id of a control by its name, when the camera has it (names, not typed ids: the exposure
/// and gain mode controls differ between libcamera 0.4 and 0.5+).
fn control_id(infos: &ControlInfoMap, name: &str) -> Option<u32> {
    infos
        .into_iter()
        .map(|(id, _)| id)
        .find(|&id| ControlId::try_from(id).is_ok_and(|c| c.name() == name))
}

/// A libcamera call on camera `id` that failed with `e`, while `doing`: busy and gone told
/// apart (the two a user can act on).
fn io_context(doing: &'static str, id: &str, e: std::io::Error) -> CameraError {
    let camera = id.to_string();
    match e.raw_os_error() {
        Some(libc::EBUSY) => CameraError::Busy {
            camera,
            doing,
            source: e,
        },
        Some(libc::ENODEV) => CameraError::Gone {
            camera,
            doing,
            source: e,
        },
        _ => CameraError::Libcamera {
            doing,
            message: format!("camera `{id}`: {e}"),
        },
    }
}

/// A libcamera call that failed while `doing`.
fn libcamera_error(doing: &'static str, message: impl std::fmt::Display) -> CameraError {
    CameraError::Libcamera {
        doing,
        message: message.to_string(),
    }
}

/// What camera `id` cannot do.
fn unsupported(id: &str, problem: impl Into<String>) -> CameraError {
    CameraError::Unsupported {
        camera: id.to_string(),
        problem: problem.into(),
    }
}

/// A `[libcamera]` key this camera cannot meet.
fn not_met(key: &str, problem: impl Into<String>) -> CameraError {
    CameraError::Config(deckwatch_common::InvalidField::new(key, problem))
}

/// memfd-backed buffers, for machines whose kernel has no dma-buf provider (no dma-heap, no
/// udmabuf), where the pipeline handler cannot export buffers itself.
fn memfd_buffer(plane_lens: &[u32], cookie: u64) -> std::io::Result<OwnedFrameBuffer> {
    let total: u64 = plane_lens.iter().map(|&l| l as u64).sum();
    // SAFETY: a fresh descriptor from memfd_create is owned by nothing else.
    let fd = unsafe { libc::memfd_create(c"deckwatch-frame".as_ptr(), libc::MFD_CLOEXEC) };
    if fd < 0 {
        return Err(std::io::Error::last_os_error());
    }
    let fd = unsafe { OwnedFd::from_raw_fd(fd) };
    if unsafe { libc::ftruncate(fd.as_raw_fd(), total as libc::off_t) } < 0 {
        return Err(std::io::Error::last_os_error());
    }
    let mut planes = Vec::new();
    let mut offset = 0u32;
    for &length in plane_lens {
        planes.push(FrameBufferPlane {
            fd: fd.try_clone()?,
            offset,
            length,
        });
        offset += length;
    }
    OwnedFrameBuffer::new(planes, Some(cookie))
}

/// The sizes a stream offers in `format`: its discrete sizes, else its range as `WxH-WxH`.
fn offered_sizes(formats: &StreamFormatsRef<'_>, format: PixelFormat) -> Vec<String> {
    let sizes = formats.sizes(format);
    if sizes.is_empty() {
        let r = formats.range(format);
        return vec![format!(
            "{}x{}-{}x{}",
            r.min.width, r.min.height, r.max.width, r.max.height
        )];
    }
    sizes
        .iter()
        .map(|s| format!("{}x{}", s.width, s.height))
        .collect()
}

fn make_requests<T: AsFrameBuffer + Any + 'static>(
    cam: &mut ActiveCamera<'_>,
    stream: &Stream,
    buffers: Vec<MemoryMappedFrameBuffer<T>>,
) -> Result<Vec<Request>, CameraError> {
    buffers
        .into_iter()
        .enumerate()
        .map(|(i, b)| {
            let mut r = cam
                .create_request(Some(i as u64))
                .ok_or_else(|| libcamera_error("creating a request", "no request"))?;
            r.add_buffer(stream, b)
                .map_err(|e| libcamera_error("adding a buffer to a request", e))?;
            Ok(r)
        })
        .collect()
}

/// The camera thread: opens and starts the camera, reports `Started`, then queues requests
/// (paced if need be) until the capture side closes the recycle channel.
fn run_camera(
    config: &CameraConfig,
    requested: Option<(u32, u32)>,
    started_tx: &mpsc::SyncSender<Result<Started, CameraError>>,
    done_tx: mpsc::Sender<Completed>,
    recycle_rx: mpsc::Receiver<Request>,
) -> Result<(), CameraError> {
    let manager = CameraManager::new().map_err(|e| libcamera_error("starting the camera manager", e))?;
    let cameras = manager.cameras();
    let ids: Vec<String> = cameras.iter().map(|c| c.id().to_string()).collect();
    let index = select_camera(&config.camera, &ids)?;
    let id = ids[index].clone();
    let camera = cameras
        .get(index)
        .ok_or_else(|| libcamera_error("listing the cameras", "the camera list changed"))?;
    let mut cam = camera.acquire().map_err(|e| io_context("acquire", &id, e))?;

    // Mode: pixel format and size.
    let mut cfgs = cam
        .generate_configuration(&[StreamRole::VideoRecording])
        .ok_or_else(|| unsupported(&id, "has no video stream configuration"))?;
    let offered: Vec<String> = {
        let c = cfgs
            .get(0)
            .ok_or_else(|| unsupported(&id, "gave an empty configuration"))?;
        c.formats()
            .pixel_formats()
            .into_iter()
            .map(|f| f.to_string())
            .collect()
    };
    let format = if config.pixel_format == "auto" {
        LumaLayout::pick(offered.iter().map(String::as_str))
            .ok_or_else(|| {
                unsupported(
                    &id,
                    format!(
                        "offers no pixel format deckwatch reads (it offers {}; deckwatch reads {})",
                        offered.join(", "),
                        LumaLayout::FORMATS.join(", ")
                    ),
                )
            })?
            .to_string()
    } else if offered.contains(&config.pixel_format) {
        config.pixel_format.clone()
    } else {
        return Err(not_met(
            "pixel_format",
            format!(
                "camera `{id}` does not offer {} (it offers {})",
                config.pixel_format,
                offered.join(", ")
            ),
        ));
    };
    let pixel_format = PixelFormat::parse(&format)
        .ok_or_else(|| libcamera_error("parsing a pixel format", format!("unknown format {format}")))?;
    let sizes_offered = {
        let c = cfgs
            .get(0)
            .ok_or_else(|| unsupported(&id, "gave an empty configuration"))?;
        offered_sizes(&c.formats(), pixel_format).join(", ")
    };
    {
        let mut s = cfgs
            .get_mut(0)
            .ok_or_else(|| unsupported(&id, "gave an empty configuration"))?;
        s.set_pixel_format(pixel_format);
        if let Some((width, height)) = requested {
            s.set_size(Size { width, height });
        }
        if config.buffers > 0 {
            s.set_buffer_count(config.buffers);
        }
    }
    if let CameraConfigurationStatus::Invalid = cfgs.validate() {
        return Err(unsupported(
            &id,
            format!("rejected the configuration {}", cfgs.to_string_repr()),
        ));
    }
    {
        let s = cfgs
            .get(0)
            .ok_or_else(|| unsupported(&id, "gave an empty configuration"))?;
        if s.get_pixel_format() != pixel_format {
            return Err(not_met(
                "pixel_format",
                format!(
                    "camera `{id}` cannot deliver {format} in this mode (it adjusted to {})",
                    s.get_pixel_format()
                ),
            ));
        }
        if let Some((width, height)) = requested {
            let got = s.get_size();
            if (got.width, got.height) != (width, height) {
                return Err(not_met(
                    "width/height",
                    format!(
                        "camera `{id}` has no {width}x{height} {format} mode (it offers {sizes_offered})"
                    ),
                ));
            }
        }
    }
    cam.configure(&mut cfgs)
        .map_err(|e| io_context("configure", &id, e))?;
    let (stream, size, stride) = {
        let s = cfgs
            .get(0)
            .ok_or_else(|| unsupported(&id, "gave an empty configuration"))?;
        (
            s.stream()
                .ok_or_else(|| unsupported(&id, "lost the configured stream"))?,
            s.get_size(),
            s.get_stride(),
        )
    };
    let layout = LumaLayout::for_format(&format)
        .ok_or_else(|| not_met("pixel_format", format!("deckwatch does not read {format}")))?;

    // Buffers: the camera's own (dma-buf) first, memfd where the kernel has no provider.
    let mut allocator = FrameBufferAllocator::new(&cam);
    let (requests, buffers_from) = match allocator.alloc(&stream) {
        Ok(buffers) => {
            let mapped = buffers
                .into_iter()
                .map(MemoryMappedFrameBuffer::new)
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| libcamera_error("mapping a buffer", format!("{e:?}")))?;
            (make_requests(&mut cam, &stream, mapped)?, "dma-buf")
        }
        Err(e) => {
            let count = cfgs.get(0).map_or(4, |s| s.get_buffer_count()).max(1);
            let lens = LumaLayout::plane_lengths(&format, stride, size.height);
            let mapped = (0..count)
                .map(|i| {
                    let fb = memfd_buffer(&lens, i as u64)
                        .map_err(|e| libcamera_error("making a memfd buffer", e))?;
                    MemoryMappedFrameBuffer::new(fb)
                        .map_err(|e| libcamera_error("mapping a memfd buffer", format!("{e:?}")))
                })
                .collect::<Result<Vec<_>, CameraError>>()?;
            deckwatch_common::say!(
                "deckwatch-capture: camera `{id}`: no dma-buf buffers ({e}); using memfd buffers"
            );
            (make_requests(&mut cam, &stream, mapped)?, "memfd")
        }
    };

    // Controls: frame rate, exposure and gain where the camera has them.
    let infos = cam.controls();
    let mut start_controls = ControlList::new();
    let mut notes = Vec::new();
    let pacing = match config.frame_period_ns() {
        None => Pacing::Free,
        Some(period) if infos.find(ControlId::FrameDurationLimits as u32).is_ok() => {
            let us = (period / 1000) as i64;
            start_controls
                .set(controls::FrameDurationLimits([us, us]))
                .map_err(|e| libcamera_error("setting FrameDurationLimits", format!("{e:?}")))?;
            Pacing::Camera(Duration::from_nanos(period))
        }
        Some(period) => Pacing::Triggered(Duration::from_nanos(period)),
    };
    let mut set_named = |name: &str, value: ControlValue| -> bool {
        match control_id(infos, name) {
            Some(cid) => start_controls.set_raw(cid, value).is_ok(),
            None => false,
        }
    };
    if let Some(us) = config.exposure_us {
        if set_named("ExposureTime", ControlValue::from(us.min(i32::MAX as u32) as i32)) {
            // Manual exposure: 0.4 has AeEnable, 0.5+ ExposureTimeMode (1 = manual).
            set_named("AeEnable", ControlValue::from(false));
            set_named("ExposureTimeMode", ControlValue::from(1i32));
        } else {
            notes.push("no ExposureTime control: libcamera.exposure_us not applied".to_string());
        }
    }
    if let Some(g) = config.gain {
        if set_named("AnalogueGain", ControlValue::from(g as f32)) {
            set_named("AnalogueGainMode", ControlValue::from(1i32));
        } else {
            notes.push("no AnalogueGain control: libcamera.gain not applied".to_string());
        }
    }

    let tx = done_tx;
    cam.on_request_completed(move |request| {
        // libcamera's thread: stamp and hand over, nothing else. A closed channel (stopping)
        // drops the request here, while the camera still exists.
        let _ = tx.send(Completed {
            request,
            completed_ns: monotonic_ns(),
        });
    });
    cam.start(Some(&start_controls))
        .map_err(|e| io_context("start", &id, e))?;

    let model = camera
        .properties()
        .get::<properties::Model>()
        .map(|m| m.0)
        .unwrap_or_default();
    let mut summary = format!(
        "camera `{id}` ({model}): {}x{} {format} (stride {stride}), {} {buffers_from} buffers, {}",
        size.width,
        size.height,
        requests.len(),
        match pacing {
            Pacing::Camera(_) => format!("{} fps set on the camera", config.frame_rate),
            Pacing::Triggered(_) => format!(
                "{} fps by queueing one request per period (the camera has no FrameDurationLimits)",
                config.frame_rate
            ),
            Pacing::Free => "the camera's own frame rate".into(),
        }
    );
    for n in &notes {
        summary.push_str("; ");
        summary.push_str(n);
    }
    let _ = started_tx.send(Ok(Started {
        id: id.clone(),
        stream,
        format,
        layout,
        width: size.width,
        height: size.height,
        stride,
        summary,
    }));

    let mut idle: VecDeque<Request> = requests.into();
    let queue = |cam: &ActiveCamera<'_>, r: Request| {
        if let Err((_, e)) = cam.queue_request(r) {
            deckwatch_common::say!("deckwatch-capture: camera `{id}`: queueing a request failed: {e}");
        }
    };
    let mut pacing = pacing;
    if !matches!(pacing, Pacing::Triggered(_)) {
        for r in idle.drain(..) {
            queue(&cam, r);
        }
    }
    let mut due = Instant::now();
    // Camera pacing is checked on the first frames: a camera that accepts FrameDurationLimits
    // but ignores it (libcamera 0.4's virtual camera completes a request as soon as it is
    // queued) would flood the pipeline.
    let (mut first_back, mut back) = (Instant::now(), 0u32);
    const CHECKED_FRAMES: u32 = 8;
    loop {
        if let Pacing::Triggered(period) = pacing {
            let now = Instant::now();
            if now >= due {
                if let Some(r) = idle.pop_front() {
                    queue(&cam, r);
                    // The next trigger one period on; after a stall, from now (no burst).
                    due = (due + period).max(now);
                }
            }
        }
        let got = match pacing {
            Pacing::Triggered(_) if !idle.is_empty() => {
                recycle_rx.recv_timeout(due.saturating_duration_since(Instant::now()))
            }
            _ => recycle_rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
        };
        let r = match got {
            Ok(r) => r,
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => break,
        };
        match pacing {
            Pacing::Triggered(_) => idle.push_back(r),
            Pacing::Free => queue(&cam, r),
            Pacing::Camera(period) => {
                back += 1;
                if back == 1 {
                    first_back = Instant::now();
                } else if back == CHECKED_FRAMES + 1 {
                    let took = first_back.elapsed();
                    if took < period * CHECKED_FRAMES / 2 {
                        deckwatch_common::say!(
                            "deckwatch-capture: camera `{id}` ignores FrameDurationLimits ({CHECKED_FRAMES} frames in \
                             {:.1} ms): pacing it by queueing one request per period",
                            took.as_secs_f64() * 1e3
                        );
                        pacing = Pacing::Triggered(period);
                        idle.push_back(r);
                        due = Instant::now() + period;
                        continue;
                    }
                }
                queue(&cam, r);
            }
        }
    }
    drop(idle);
    cam.stop().map_err(|e| io_context("stop", &id, e))?;
    drop(allocator);
    Ok(())
}

/// The libcamera version and the cameras it sees, with their video formats and the controls
/// deckwatch uses.
pub fn list_cameras() -> Result<(String, Vec<CameraDescription>), CameraError> {
    quiet_libcamera("error");
    let manager = CameraManager::new().map_err(|e| libcamera_error("starting the camera manager", e))?;
    let version = manager.version().to_string();
    let cameras = manager.cameras();
    let mut out = Vec::new();
    for (index, cam) in cameras.iter().enumerate() {
        let props = cam.properties();
        let model = props.get::<properties::Model>().map(|m| m.0).unwrap_or_default();
        let location = props
            .get::<properties::Location>()
            .map(|l| format!("{l:?}"))
            .unwrap_or_else(|_| "location unknown".into());
        let mut formats = Vec::new();
        if let Some(cfgs) = cam.generate_configuration(&[StreamRole::VideoRecording]) {
            if let Some(c) = cfgs.get(0) {
                let f = c.formats();
                for pf in f.pixel_formats().into_iter() {
                    formats.push((pf.to_string(), offered_sizes(&f, pf)));
                }
            }
        }
        let infos = cam.controls();
        let controls = [
            "FrameDurationLimits",
            "ExposureTime",
            "AnalogueGain",
            "AeEnable",
            "ExposureTimeMode",
            "AnalogueGainMode",
        ]
        .iter()
        .filter_map(|name| {
            let cid = control_id(infos, name)?;
            let info = infos.find(cid).ok()?;
            Some((
                name.to_string(),
                format!("{:?} to {:?} (default {:?})", info.min(), info.max(), info.def()),
            ))
        })
        .collect();
        out.push(CameraDescription {
            index,
            id: cam.id().to_string(),
            model,
            location,
            formats,
            controls,
        });
    }
    Ok((version, out))
}
