//! rerun logging for the pipeline, off the hot path: a stage hands small, owned log items to a
//! bounded crossbeam channel (never waiting: when the logging thread falls behind, items are
//! dropped and counted), and one logging thread per process turns them into rerun archetypes.
//! Every process logs into the same recording (same application and recording id, given by the
//! launcher), so the viewer shows one timeline of all stages.
//!
//! Entities: `camera/image` (the frame, downscaled), `camera/image/markers` (detected markers,
//! labelled), `camera/image/ellipse` (the paper's fitted ring ellipse), `camera/image/deck_model`
//! (the deck reprojected with the full pose), `attitude/{roll,pitch,yaw}/{estimate,
//! alternative,truth}` (scalars), `decision/state`, `decision/calm_window/{start_s,length_s}`
//! and `decision/log`. Timelines: `frame` (sequence number) and `capture_time`.

use crossbeam_channel::{bounded, Sender, TrySendError};
use rerun::{RecordingStream, RecordingStreamBuilder};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// The application id every deckwatch process logs under.
pub const APPLICATION_ID: &str = "deckwatch";
/// The viewer's default gRPC address.
pub const DEFAULT_ADDRESS: &str = "rerun+http://127.0.0.1:9876/proxy";

/// `[rerun]` of the pipeline configuration.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RerunConfig {
    /// `off`, `spawn` (start a viewer), `connect` (a viewer at `address`) or `save` (to `path`).
    pub sink: String,
    pub address: Option<String>,
    /// The `.rrd` file (`save`). Each process writes `<path>.<stage>.part`; the launcher merges
    /// them into `path` when it stops.
    pub path: Option<PathBuf>,
    /// Log every n-th frame's image (markers, ellipses and angles are logged for every frame).
    pub image_every: u32,
    /// Downscale logged images by this factor (1 = full resolution).
    pub image_downscale: u32,
    /// Log items queued per process before new ones are dropped.
    pub queue: usize,
    /// The recording all processes log into (the launcher sets one per run).
    pub recording_id: Option<String>,
}

impl Default for RerunConfig {
    fn default() -> Self {
        Self {
            sink: "off".into(),
            address: None,
            path: None,
            image_every: 1,
            image_downscale: 4,
            queue: 64,
            recording_id: None,
        }
    }
}

impl RerunConfig {
    /// The `[rerun]` section of a pipeline configuration (TOML); errors name file, line and key.
    pub fn from_toml(file: &str, text: &str) -> Result<Self, String> {
        #[derive(Deserialize)]
        struct Doc {
            #[serde(default)]
            rerun: RerunConfig,
        }
        let doc: Doc = toml::from_str(text).map_err(|e| format!("{file}: {e}"))?;
        doc.rerun.validate().map_err(|e| format!("{file}: rerun.{e}"))?;
        Ok(doc.rerun)
    }

    pub fn validate(&self) -> Result<(), String> {
        match self.sink.as_str() {
            "off" | "spawn" | "connect" => {}
            "save" if self.path.is_some() => {}
            "save" => return Err("path: required with sink = \"save\"".into()),
            other => return Err(format!("sink: unknown `{other}` (off, spawn, connect, save)")),
        }
        if !(1..=1000).contains(&self.image_every) {
            return Err(format!("image_every: must be 1..=1000, got {}", self.image_every));
        }
        if !(1..=16).contains(&self.image_downscale) {
            return Err(format!(
                "image_downscale: must be 1..=16, got {}",
                self.image_downscale
            ));
        }
        if !(1..=100_000).contains(&self.queue) {
            return Err(format!("queue: must be 1..=100000, got {}", self.queue));
        }
        Ok(())
    }

    /// The part file a process writes in `save` mode.
    pub fn part_path(path: &Path, stage: &str) -> PathBuf {
        let mut p = path.as_os_str().to_owned();
        p.push(format!(".{stage}.part"));
        PathBuf::from(p)
    }
}

/// One thing to log, owned (no reference into shared memory), at one frame.
#[derive(Debug, Clone)]
pub struct Item {
    pub seq: u64,
    pub captured_ns: u64,
    pub kind: ItemKind,
}

#[derive(Debug, Clone)]
pub enum ItemKind {
    /// An 8-bit gray image (already downscaled).
    Image {
        pixels: Vec<u8>,
        width: u32,
        height: u32,
    },
    /// Points in full-resolution pixels with labels.
    Points {
        entity: &'static str,
        points: Vec<[f32; 2]>,
        labels: Vec<String>,
    },
    /// Closed line strips in full-resolution pixels.
    Strips {
        entity: &'static str,
        strips: Vec<Vec<[f32; 2]>>,
    },
    /// Scalars by entity path.
    Scalars(Vec<(String, f64)>),
    /// A line of text on `decision/log`.
    Text(String),
}

/// A process's logger: the channel to its logging thread.
pub struct Logger {
    tx: Option<Sender<Item>>,
    thread: Option<JoinHandle<()>>,
    dropped: Arc<AtomicU64>,
    image_every: u32,
    downscale: u32,
}

impl Logger {
    /// Starts the logging thread for `stage` (None when the sink is `off`).
    pub fn start(config: &RerunConfig, stage: &str) -> Result<Option<Self>, String> {
        config.validate()?;
        let Some(rec) = open_stream(config, stage)? else {
            return Ok(None);
        };
        let (tx, rx) = bounded::<Item>(config.queue);
        let downscale = config.image_downscale as f32;
        let thread = std::thread::Builder::new()
            .name(format!("rerun-{stage}"))
            .spawn(move || {
                for item in rx {
                    log_item(&rec, &item, downscale);
                }
                // Dropping the stream flushes it (and writes the .rrd footer).
                let _ = rec.flush_blocking();
            })
            .map_err(|e| format!("rerun: cannot start the logging thread: {e}"))?;
        Ok(Some(Self {
            tx: Some(tx),
            thread: Some(thread),
            dropped: Arc::new(AtomicU64::new(0)),
            image_every: config.image_every,
            downscale: config.image_downscale,
        }))
    }

    /// Whether frame `seq`'s image should be logged.
    pub fn wants_image(&self, seq: u64) -> bool {
        seq.is_multiple_of(self.image_every as u64)
    }

    /// Queues an item; never waits (a full queue drops it, counted).
    pub fn log(&self, item: Item) {
        if let Some(tx) = &self.tx {
            if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = tx.try_send(item) {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// A downscaled copy of a frame for logging (every `downscale`-th pixel of every
    /// `downscale`-th row: cheap, and enough to see the deck).
    pub fn image(
        &self,
        seq: u64,
        captured_ns: u64,
        pixels: &[u8],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Item {
        let f = self.downscale as usize;
        let (w, h) = (width.div_ceil(f), height.div_ceil(f));
        let mut out = Vec::with_capacity(w * h);
        for y in (0..height).step_by(f) {
            let row = &pixels[y * stride..y * stride + width];
            out.extend(row.iter().step_by(f));
        }
        Item {
            seq,
            captured_ns,
            kind: ItemKind::Image {
                pixels: out,
                width: w as u32,
                height: h as u32,
            },
        }
    }

    /// Items dropped because the logging thread fell behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Flushes everything queued and stops the thread (the `.rrd` is complete afterwards).
    pub fn finish(mut self) {
        self.tx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Logger {
    fn drop(&mut self) {
        self.tx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The recording stream of the configured sink (None: off).
pub fn open_stream(config: &RerunConfig, stage: &str) -> Result<Option<RecordingStream>, String> {
    let mut builder = RecordingStreamBuilder::new(APPLICATION_ID);
    if let Some(id) = &config.recording_id {
        builder = builder.recording_id(id.clone());
    }
    let err = |e: rerun::RecordingStreamError| format!("rerun ({}): {e}", config.sink);
    let rec = match config.sink.as_str() {
        "off" => return Ok(None),
        "spawn" => builder.spawn().map_err(err)?,
        "connect" => builder
            .connect_grpc_opts(config.address.clone().unwrap_or_else(|| DEFAULT_ADDRESS.into()))
            .map_err(err)?,
        "save" => {
            let path = config
                .path
                .as_ref()
                .ok_or("rerun.path: required with sink = \"save\"")?;
            builder.save(RerunConfig::part_path(path, stage)).map_err(err)?
        }
        other => return Err(format!("rerun.sink: unknown `{other}`")),
    };
    Ok(Some(rec))
}

fn log_item(rec: &RecordingStream, item: &Item, downscale: f32) {
    rec.set_time_sequence("frame", item.seq as i64);
    rec.set_duration_secs("capture_time", item.captured_ns as f64 / 1e9);
    // Full-resolution pixel -> pixel of the downscaled image (pixel centres at integers).
    let scale = |p: &[f32; 2]| [(p[0] + 0.5) / downscale - 0.5, (p[1] + 0.5) / downscale - 0.5];
    let result = match &item.kind {
        ItemKind::Image {
            pixels,
            width,
            height,
        } => rec.log(
            "camera/image",
            &rerun::Image::from_l8(pixels.clone(), [*width, *height]),
        ),
        ItemKind::Points {
            entity,
            points,
            labels,
        } => {
            let pts: Vec<[f32; 2]> = points.iter().map(scale).collect();
            rec.log(
                *entity,
                &rerun::Points2D::new(pts)
                    .with_labels(labels.clone())
                    .with_radii([2.0]),
            )
        }
        ItemKind::Strips { entity, strips } => {
            let s: Vec<Vec<[f32; 2]>> = strips.iter().map(|st| st.iter().map(scale).collect()).collect();
            rec.log(*entity, &rerun::LineStrips2D::new(s))
        }
        ItemKind::Scalars(values) => {
            let mut r = Ok(());
            for (entity, v) in values {
                if v.is_finite() {
                    r = r.and(rec.log(entity.as_str(), &rerun::Scalars::single(*v)));
                }
            }
            r
        }
        ItemKind::Text(t) => rec.log("decision/log", &rerun::TextLog::new(t.clone())),
    };
    // A failed log call (e.g. a viewer that went away) must not stop the thread.
    let _ = result;
}

/// The viewer layout: the image with its overlays beside the angle plots, the decision below.
pub fn send_blueprint(rec: &RecordingStream) -> Result<(), String> {
    use rerun::blueprint::{
        Blueprint, BlueprintActivation, Horizontal, Spatial2DView, TextLogView, TimeSeriesView, Vertical,
    };
    let plots = Vertical::new([
        TimeSeriesView::new("roll (deg)")
            .with_origin("attitude/roll")
            .into(),
        TimeSeriesView::new("pitch (deg)")
            .with_origin("attitude/pitch")
            .into(),
        TimeSeriesView::new("yaw (deg)")
            .with_origin("attitude/yaw")
            .into(),
        TimeSeriesView::new("decision").with_origin("decision").into(),
    ]);
    let left = Vertical::new([
        Spatial2DView::new("camera").with_origin("camera/image").into(),
        TextLogView::new("decisions").with_origin("decision/log").into(),
    ])
    .with_row_shares([3.0, 1.0]);
    let blueprint = Blueprint::new(Horizontal::new([left.into(), plots.into()]));
    blueprint
        .send(rec, BlueprintActivation::default())
        .map_err(|e| format!("rerun: sending the blueprint: {e}"))
}

/// Merges the per-process part files of a `save` run into one `.rrd` (one stream header), and
/// removes the parts. Returns the number of messages written.
pub fn merge_parts(path: &Path, stages: &[&str]) -> Result<u64, String> {
    use rerun::external::re_build_info::CrateVersion;
    use rerun::external::re_log_encoding as enc;
    use rerun::external::re_log_types::LogMsg;
    let out = std::fs::File::create(path).map_err(|e| format!("{}: cannot create: {e}", path.display()))?;
    let mut encoder = enc::Encoder::new_eager(
        CrateVersion::LOCAL,
        enc::EncodingOptions::PROTOBUF_COMPRESSED,
        std::io::BufWriter::new(out),
    )
    .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut n = 0u64;
    let mut parts = Vec::new();
    for stage in stages {
        let part = RerunConfig::part_path(path, stage);
        if !part.exists() {
            continue;
        }
        let file = std::fs::File::open(&part).map_err(|e| format!("{}: {e}", part.display()))?;
        let decoder = enc::Decoder::<LogMsg>::decode_eager(std::io::BufReader::new(file))
            .map_err(|e| format!("{}: {e}", part.display()))?;
        for msg in decoder {
            let msg = msg.map_err(|e| format!("{}: {e}", part.display()))?;
            encoder
                .append(&msg)
                .map_err(|e| format!("{}: {e}", path.display()))?;
            n += 1;
        }
        parts.push(part);
    }
    encoder.finish().map_err(|e| format!("{}: {e}", path.display()))?;
    drop(encoder);
    for p in parts {
        let _ = std::fs::remove_file(p);
    }
    Ok(n)
}

/// Rows logged per entity of the recording (blueprint stores excluded), read back from an
/// `.rrd` file: what a test or a user checks a saved run with.
pub fn rrd_entity_rows(path: &Path) -> Result<std::collections::BTreeMap<String, u64>, String> {
    use rerun::external::re_log_encoding as enc;
    use rerun::external::re_log_types::{LogMsg, StoreKind};
    use rerun::log::Chunk;
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let decoder = enc::Decoder::<LogMsg>::decode_eager(std::io::BufReader::new(file))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut rows = std::collections::BTreeMap::new();
    for msg in decoder {
        let msg = msg.map_err(|e| format!("{}: {e}", path.display()))?;
        if let LogMsg::ArrowMsg(store, arrow) = &msg {
            if store.kind() != StoreKind::Recording {
                continue;
            }
            let chunk = Chunk::from_arrow_msg(arrow).map_err(|e| format!("{}: {e}", path.display()))?;
            *rows.entry(chunk.entity_path().to_string()).or_default() += chunk.num_rows() as u64;
        }
    }
    Ok(rows)
}
