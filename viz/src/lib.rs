//! rerun logging for the pipeline, off the hot path: a stage hands small, owned log items to a
//! bounded crossbeam channel (never waiting: when the logging thread falls behind, items are
//! dropped and counted), and one logging thread per process turns them into rerun archetypes.
//! Every process logs into the same recording (same application and recording id, given by the
//! launcher), so the viewer shows one timeline of all stages.
//!
//! The entities, their labels and colours, and the conversion of messages into log items are in
//! [`entities`]. Timelines: `frame` (sequence number) and `capture_time`.

pub mod entities;

use crossbeam_channel::{bounded, Sender, TrySendError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

// The rerun SDK is the `rerun` feature (on in every binary's defaults). Without it the same API
// is there, `off` works and every other sink is refused with an error saying why: a lean build
// for a drone or a chroot, where rerun's build would take longest.
#[cfg(feature = "rerun")]
#[path = "sink.rs"]
mod sink;
#[cfg(not(feature = "rerun"))]
#[path = "no_sink.rs"]
mod sink;
pub use sink::{merge_parts, open_viewer, Viewer};
#[cfg(feature = "rerun")]
pub use sink::{rrd_entity_rows, send_blueprint, send_trial_blueprint};

/// Which views the viewer opens with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Layout {
    /// A pipeline's run: the frame, the decision, angles, errors, latency.
    #[default]
    Pipeline,
    /// A closed-loop landing trial (`deckwatch trials --rrd`): the frame, the decision and the
    /// touchdown's verdict, the deck's angles against the capacity, the vehicle's height over
    /// the deck beside the heave.
    Trial,
}

/// Whether this build can log to rerun (the `rerun` feature).
pub const RERUN_BUILT_IN: bool = cfg!(feature = "rerun");

/// The application id every deckwatch process logs under.
pub const APPLICATION_ID: &str = "deckwatch";
/// The viewer's default gRPC address.
pub const DEFAULT_ADDRESS: &str = "rerun+http://127.0.0.1:9876/proxy";

/// What went wrong with logging.
#[derive(Debug, thiserror::Error)]
pub enum VizError {
    /// A `[rerun]` value: the key (without the section) and what is wrong with it.
    #[error("rerun.{}: {}", .0.field, .0.problem)]
    Config(#[from] deckwatch_common::InvalidField),
    /// The rerun SDK refused (a viewer that cannot be spawned or reached, a file that cannot
    /// be written, ...).
    #[error("rerun ({sink}): {message}")]
    Sink { sink: &'static str, message: String },
    /// Reading or writing an `.rrd` file.
    #[error("{}: {message}", path.display())]
    File { path: PathBuf, message: String },
    /// This build has no rerun (the `rerun` feature is off).
    #[error("rerun.sink = \"{sink}\": this build has no rerun logging (it was built without the `rerun` feature, which is on by default); rebuild with it or set rerun.sink = \"off\"")]
    NotBuilt { sink: &'static str },
    #[error("rerun: cannot start the logging thread: {0}")]
    Thread(String),
}

/// Where the log goes (`[rerun] sink`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RerunSink {
    Off,
    /// Start a viewer.
    Spawn,
    /// A viewer at `address`.
    Connect,
    /// Into the `.rrd` file at `path`.
    Save,
}

impl RerunSink {
    pub fn name(&self) -> &'static str {
        match self {
            Self::Off => "off",
            Self::Spawn => "spawn",
            Self::Connect => "connect",
            Self::Save => "save",
        }
    }
}

/// `[rerun]` of the pipeline configuration.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RerunConfig {
    /// `off`, `spawn` (start a viewer), `connect` (a viewer at `address`) or `save` (to `path`).
    pub sink: RerunSink,
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
    /// The views the recording opens with (not a configuration key: a trial's own).
    #[serde(skip)]
    pub layout: Layout,
}

impl Default for RerunConfig {
    fn default() -> Self {
        Self {
            sink: RerunSink::Off,
            address: None,
            path: None,
            image_every: 1,
            image_downscale: 4,
            queue: 64,
            recording_id: None,
            layout: Layout::Pipeline,
        }
    }
}

impl RerunConfig {
    /// The first bad value: its key (without the section) and what is wrong.
    pub fn validate(&self) -> Result<(), deckwatch_common::InvalidField> {
        let invalid = |key, problem: String| Err(deckwatch_common::InvalidField::new(key, problem));
        if self.sink == RerunSink::Save && self.path.is_none() {
            return invalid("path", "required with sink = \"save\"".into());
        }
        if !(1..=1000).contains(&self.image_every) {
            return invalid(
                "image_every",
                format!("must be 1..=1000, got {}", self.image_every),
            );
        }
        if !(1..=16).contains(&self.image_downscale) {
            return invalid(
                "image_downscale",
                format!("must be 1..=16, got {}", self.image_downscale),
            );
        }
        if !(1..=100_000).contains(&self.queue) {
            return invalid("queue", format!("must be 1..=100000, got {}", self.queue));
        }
        Ok(())
    }

    /// Whether frame `seq`'s image is logged (and the overlays of its deck crop with it).
    pub fn logs_image(&self, seq: u64) -> bool {
        self.sink != RerunSink::Off && seq.is_multiple_of(self.image_every.max(1) as u64)
    }

    /// The part file a process writes in `save` mode: `FILE.rrd.<part>.part`, where a stage
    /// process's part is `<stage>-<pid>` (a restarted stage writes a new part instead of
    /// overwriting its predecessor's) and the launcher's is `launcher`.
    pub fn part_path(path: &Path, part: &str) -> PathBuf {
        let mut p = path.as_os_str().to_owned();
        p.push(format!(".{part}.part"));
        PathBuf::from(p)
    }

    /// Every part file of `stage` beside `path` (`FILE.rrd.<stage>.part` and
    /// `FILE.rrd.<stage>-<pid>.part`), oldest first.
    pub fn parts_of(path: &Path, stage: &str) -> Vec<PathBuf> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let Some(file) = path.file_name().and_then(|f| f.to_str()) else {
            return Vec::new();
        };
        let Ok(entries) = std::fs::read_dir(&dir) else {
            return Vec::new();
        };
        let ours = |name: &str| {
            let Some(rest) = name
                .strip_prefix(file)
                .and_then(|r| r.strip_prefix('.'))
                .and_then(|r| r.strip_prefix(stage))
                .and_then(|r| r.strip_suffix(".part"))
            else {
                return false;
            };
            rest.is_empty()
                || rest
                    .strip_prefix('-')
                    .is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
        };
        let mut parts: Vec<(std::time::SystemTime, PathBuf)> = entries
            .flatten()
            .filter(|e| e.file_name().to_str().is_some_and(ours))
            .map(|e| {
                let modified = e
                    .metadata()
                    .and_then(|m| m.modified())
                    .unwrap_or(std::time::UNIX_EPOCH);
                (modified, e.path())
            })
            .collect();
        parts.sort();
        parts.into_iter().map(|(_, p)| p).collect()
    }
}

/// One thing to log, owned (no reference into shared memory), at one time.
#[derive(Debug, Clone)]
pub struct Item {
    /// The frame it belongs to (the `frame` timeline); None for what belongs to no frame (a
    /// watchdog's decision, a calm window predicted ahead, an autopilot sample).
    pub frame: Option<u64>,
    /// Its time on the capture clock (the `capture_time` timeline; `CLOCK_MONOTONIC` ns).
    pub time_ns: u64,
    pub kind: ItemKind,
}

#[derive(Debug, Clone)]
pub enum ItemKind {
    /// An 8-bit gray image: the frame ([`entities::IMAGE`], downscaled) or its deck region
    /// ([`entities::DECK_CROP`]).
    Image {
        entity: &'static str,
        pixels: Vec<u8>,
        width: u32,
        height: u32,
    },
    /// Points in full-resolution pixels with labels (shown in the deck crop only), drawn
    /// `radius_ui` UI points large; also drawn in `crop` when given.
    Points {
        entity: &'static str,
        points: Vec<[f32; 2]>,
        labels: Vec<String>,
        colour: [u8; 4],
        radius_ui: f32,
        crop: Option<entities::DeckCrop>,
    },
    /// Closed line strips in full-resolution pixels; also drawn in `crop` when given.
    Strips {
        entity: &'static str,
        strips: Vec<Vec<[f32; 2]>>,
        colour: [u8; 4],
        crop: Option<entities::DeckCrop>,
    },
    /// Scalars by entity path.
    Scalars(Vec<(String, f64)>),
    /// A line of text on [`entities::DECISION_LOG`].
    Text(String),
    /// A lane of a state timeline enters `state` (None: leaves it).
    State {
        entity: &'static str,
        state: Option<String>,
    },
    /// A markdown document (the newest one is shown).
    Document { entity: &'static str, markdown: String },
}

/// What the recording is, for the viewer: its name and properties (the launcher's).
#[derive(Debug, Clone, Default)]
pub struct RunDescription {
    /// The recording's name in the viewer.
    pub name: String,
    /// (key, value): version, source, estimator, host, ...
    pub properties: Vec<(String, String)>,
    /// The run's whole configuration.
    pub configuration_toml: String,
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
    pub fn start(config: &RerunConfig, stage: &str) -> Result<Option<Self>, VizError> {
        config.validate()?;
        if config.sink == RerunSink::Off {
            return Ok(None);
        }
        let (tx, rx) = bounded::<Item>(config.queue);
        let thread = sink::spawn_logging_thread(config, stage, rx)?;
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
            frame: Some(seq),
            time_ns: captured_ns,
            kind: ItemKind::Image {
                entity: entities::IMAGE,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stage_has_a_part_per_process() {
        let dir = std::env::temp_dir().join(format!("deckwatch-viz-parts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rrd = dir.join("run.rrd");
        for part in [
            "detect-10",
            "detect-9",
            "detect",
            "detect-x",
            "detector-1",
            "estimate-3",
        ] {
            std::fs::write(RerunConfig::part_path(&rrd, part), b"").unwrap();
        }
        std::fs::write(dir.join("other.rrd.detect-1.part"), b"").unwrap();
        let mut names: Vec<String> = RerunConfig::parts_of(&rrd, "detect")
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(
            names,
            [
                "run.rrd.detect-10.part",
                "run.rrd.detect-9.part",
                "run.rrd.detect.part"
            ]
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
