//! The stage abstraction and its one runner.
//!
//! A stage is a per-message step from one input to one output ([`Stage::step`]) with an
//! optional periodic [`Stage::tick`]; it knows nothing of processes or shared memory. The same
//! value runs in a process of its own ([`main`]: setup, the event loop, logging, drop counting,
//! exit codes) and in the in-process chain ([`crate::chain`]), so both compute the same thing.
//!
//! Adding a stage: implement [`Stage`] (in `stages/`), add a binary of a few lines
//! (`src/bin/deckwatch-<name>.rs` calling [`main`]), and list it in [`STAGES`].

use crate::bus::{
    event_loop, quiet_logging, services, Bus, BusError, Flow, FrameSubscriber, Listener, Message,
    MessagePublisher, MessageSubscriber, Rejections, Wake,
};
use crate::config::{ConfigError, PipelineConfig, DEFAULTS};
use deckwatch_common::messages::{monotonic_ns, FrameHeader, LandingDecision, StageHeartbeat, VehicleSample};
use deckwatch_viz::{Item, Logger};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// A frame as a stage sees it: header and pixels, wherever they are (shared memory, or a buffer
/// of the in-process chain).
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    pub header: &'a FrameHeader,
    pub pixels: &'a [u8],
}

/// One step of the pipeline.
pub trait Stage: Sized {
    /// The stage's name: its node, its binary (`deckwatch-<NAME>`), its log lines.
    const NAME: &'static str;
    /// What it consumes: [`Frames`] or a [`Message`] type.
    type Input: Input;
    type Output: Message;

    /// The stage as the configuration says; `joined_late`: it joins a running pipeline (a
    /// restart), so frames before the first it sees are not its drops.
    fn from_config(config: &PipelineConfig, joined_late: bool) -> Result<Self, ConfigError>;

    /// The output for one input received at `received_ns` (`CLOCK_MONOTONIC`).
    fn step(&mut self, input: <Self::Input as Input>::View<'_>, received_ns: u64) -> Self::Output;

    /// How often [`Stage::tick`] wants to run (None: never).
    fn tick_period(&self) -> Option<Duration> {
        None
    }

    /// Called every [`Stage::tick_period`]: an output to publish although no input came.
    fn tick(&mut self, _now_ns: u64) -> Option<Self::Output> {
        None
    }

    /// Whether the stage follows the vehicle's attitude stream ([`VehicleSample`], from the link
    /// process) besides its input.
    fn wants_vehicle(&self) -> bool {
        false
    }

    /// A vehicle attitude sample; every sample that arrived is handed over before the inputs
    /// that arrived with it.
    fn vehicle_sample(&mut self, _sample: &VehicleSample) {}

    /// Work that can wait until the outputs of the inputs at hand are published (the decider's
    /// model refit): run before the next input is taken.
    fn after_outputs(&mut self) {}

    /// What was wrong with the last input, if anything (said once, on stderr).
    fn take_warning(&mut self) -> Option<String> {
        None
    }

    /// The viewer's items for an output.
    fn viewer_items(&mut self, output: &Self::Output) -> Vec<Item>;

    /// A line on what the stage did (printed when it stops).
    fn summary(&self) -> String;
}

/// What a stage consumes: frames, or a message type.
pub trait Input {
    /// How one input is lent to [`Stage::step`].
    type View<'a>;
    /// The transport's receiving end.
    type Port: InputPort<Self>;
    /// The service whose subscriber count says the stage is listening.
    const SERVICE: &'static str;
    fn subscribe(bus: &Bus) -> Result<Self::Port, BusError>;
}

/// The receiving end of an [`Input`].
pub trait InputPort<I: Input + ?Sized> {
    fn listener(&self) -> &Listener;
    /// The inputs skipped because they held a bad enum or boolean.
    fn rejections(&self) -> &Rejections;
    /// Hands every input due now to `step`, and each result to `emit` once the input is
    /// released (a frame goes back to shared memory before anything is published).
    fn drain<O>(
        &self,
        step: impl for<'a> FnMut(I::View<'a>) -> O,
        emit: impl FnMut(O) -> Result<(), BusError>,
    ) -> Result<(), BusError>;
}

/// The input of a stage that consumes camera frames (detect).
pub struct Frames;

impl Input for Frames {
    type View<'a> = Frame<'a>;
    type Port = FrameSubscriber;
    const SERVICE: &'static str = services::FRAMES;
    fn subscribe(bus: &Bus) -> Result<FrameSubscriber, BusError> {
        bus.frame_subscriber()
    }
}

impl InputPort<Frames> for FrameSubscriber {
    fn listener(&self) -> &Listener {
        FrameSubscriber::listener(self)
    }

    fn rejections(&self) -> &Rejections {
        FrameSubscriber::rejections(self)
    }

    /// Latest-frame semantics: only the newest queued frame; the ones passed over show up as
    /// sequence gaps, which the stage counts.
    fn drain<O>(
        &self,
        mut step: impl for<'a> FnMut(Frame<'a>) -> O,
        mut emit: impl FnMut(O) -> Result<(), BusError>,
    ) -> Result<(), BusError> {
        while let Some((sample, _passed_over)) = self.receive_latest()? {
            let out = step(Frame {
                header: sample.header(),
                pixels: sample.pixels(),
            });
            drop(sample);
            emit(out)?;
        }
        Ok(())
    }
}

impl<M: Message> Input for M {
    type View<'a> = &'a M;
    type Port = MessageSubscriber<M>;
    const SERVICE: &'static str = <M as Message>::SERVICE;
    fn subscribe(bus: &Bus) -> Result<MessageSubscriber<M>, BusError> {
        bus.subscriber::<M>()
    }
}

impl<M: Message> InputPort<M> for MessageSubscriber<M> {
    fn listener(&self) -> &Listener {
        MessageSubscriber::listener(self)
    }

    fn rejections(&self) -> &Rejections {
        MessageSubscriber::rejections(self)
    }

    /// Every queued message, in order.
    fn drain<O>(
        &self,
        mut step: impl for<'a> FnMut(&'a M) -> O,
        mut emit: impl FnMut(O) -> Result<(), BusError>,
    ) -> Result<(), BusError> {
        while let Some(m) = self.receive()? {
            emit(step(&m))?;
        }
        Ok(())
    }
}

/// A stage the launcher runs: its name and the service it listens on once it is up (None: the
/// source, which listens on nothing), with the subscriber count that says so.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StageInfo {
    pub name: &'static str,
    pub ready_service: Option<&'static str>,
    pub ready_subscribers: usize,
}

/// The stages in start order: each one's input service has a subscriber before the stage
/// upstream of it starts, so no frame is published into the void. The recorder comes first, so
/// that it sees everything; then the link: the vehicle's attitude must flow before the first
/// frame needs it.
pub const STAGES: [StageInfo; 6] = [
    // The first subscriber of the markers (estimate comes later): it is up at one.
    StageInfo {
        name: crate::stages::record::NAME,
        ready_service: Some(<deckwatch_common::messages::MarkerMessage as crate::bus::Message>::SERVICE),
        ready_subscribers: 1,
    },
    // The link listens to the decisions, which the launcher follows too: it is up at two.
    StageInfo {
        name: crate::stages::link::NAME,
        ready_service: Some(<LandingDecision as crate::bus::Message>::SERVICE),
        ready_subscribers: 2,
    },
    StageInfo {
        name: crate::stages::DecideStage::NAME,
        ready_service: Some(<<crate::stages::DecideStage as Stage>::Input as Input>::SERVICE),
        ready_subscribers: 1,
    },
    StageInfo {
        name: crate::stages::EstimateStage::NAME,
        ready_service: Some(<<crate::stages::EstimateStage as Stage>::Input as Input>::SERVICE),
        ready_subscribers: 1,
    },
    StageInfo {
        name: crate::stages::DetectStage::NAME,
        ready_service: Some(<<crate::stages::DetectStage as Stage>::Input as Input>::SERVICE),
        ready_subscribers: 1,
    },
    StageInfo {
        name: crate::stages::capture::NAME,
        ready_service: None,
        ready_subscribers: 1,
    },
];

/// The stages a configuration runs, in start order (the link only with `[link] enabled`, the
/// recorder only with `[record] path`). With a recorder, which subscribes to every service
/// before the others start, each later stage is up at one subscriber more.
pub fn active_stages(config: &PipelineConfig) -> Vec<StageInfo> {
    let recording = config.record.enabled();
    STAGES
        .into_iter()
        .filter(|s| s.name != crate::stages::link::NAME || config.link.enabled)
        .filter(|s| s.name != crate::stages::record::NAME || recording)
        .map(|mut s| {
            let recorded =
                |service: &str| service != crate::bus::services::FRAMES || config.record.records_frames();
            if recording && s.name != crate::stages::record::NAME && s.ready_service.is_some_and(recorded) {
                s.ready_subscribers += 1;
            }
            s
        })
        .collect()
}

/// The command line of every stage binary: the pipeline configuration and the domain.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    version,
    about = "A deckwatch stage process (the launcher, `deckwatch run`, starts it)"
)]
pub struct StageArgs {
    /// Pipeline configuration (TOML); each stage reads its own sections. Default: built-in
    /// defaults.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// iceoryx2 domain (overrides `bus.domain`).
    #[arg(long)]
    pub domain: Option<String>,
    /// This stage joins a running pipeline (the launcher restarted it): frames before the
    /// first one it sees are not its drops.
    #[arg(long)]
    pub restarted: bool,
}

impl StageArgs {
    /// The configuration with the `--domain` override applied (not yet validated).
    pub fn config(&self) -> Result<PipelineConfig, ConfigError> {
        let mut c = PipelineConfig::load_or_default(self.config.as_deref())?;
        if let Some(d) = &self.domain {
            c.bus.domain = d.clone();
        }
        Ok(c)
    }

    /// The configuration's name in messages.
    pub fn config_name(&self) -> String {
        self.config
            .as_ref()
            .map_or(DEFAULTS.to_string(), |p| p.display().to_string())
    }
}

/// The stage processes running on this machine in `domain`, as (stage name, process id): every
/// `deckwatch-<stage> ... --domain <domain>` in /proc (for tools and tests that watch or signal
/// them; the launcher knows its own children).
pub fn stage_processes(domain: &str) -> Vec<(String, u32)> {
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for entry in entries.flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(cmdline) = std::fs::read(entry.path().join("cmdline")) else {
            continue;
        };
        let args: Vec<String> = cmdline
            .split(|&b| b == 0)
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        let ours = args.windows(2).any(|w| w[0] == "--domain" && w[1] == domain);
        let stage = args
            .first()
            .and_then(|a| std::path::Path::new(a).file_name())
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_prefix("deckwatch-"));
        if let (true, Some(stage)) = (ours, stage) {
            out.push((stage.to_string(), pid));
        }
    }
    out
}

/// Why a stage process stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Bus(#[from] BusError),
    #[error(transparent)]
    Viewer(#[from] deckwatch_viz::VizError),
    #[error(transparent)]
    Source(#[from] deckwatch_capture::source::SourceError),
    /// Publishing a frame failed for another reason than a full queue or a bad frame.
    #[error("{0}")]
    Publish(String),
    /// The MAVLink connection to the autopilot could not be set up.
    #[error("{0}")]
    Link(String),
    /// The flight recorder could not write its file.
    #[error("{0}")]
    Record(String),
}

/// Runs the stage binary: parse the command line, run, report; the exit code says how it went.
pub fn main<S: Stage>() -> ExitCode {
    let args = <StageArgs as clap::Parser>::parse();
    exit_code(S::NAME, run::<S>(&args))
}

/// The exit code of a stage process, with its closing line on stderr.
pub fn exit_code(name: &str, result: Result<String, RunError>) -> ExitCode {
    match result {
        Ok(summary) => {
            // Lines lost to a full stderr (a stopped launcher: `deckwatch_common::diag`).
            let dropped = deckwatch_common::diag::dropped_lines();
            if dropped > 0 {
                deckwatch_common::say!("deckwatch-{name}: {summary}; {dropped} stderr lines dropped");
            } else {
                deckwatch_common::say!("deckwatch-{name}: {summary}");
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            deckwatch_common::say!("deckwatch-{name}: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The configuration of a stage process, checked (a stage may be started by hand, not only by
/// the launcher, which checks it too).
pub(crate) fn checked_config(args: &StageArgs) -> Result<PipelineConfig, RunError> {
    let config = args.config()?;
    config.validate(&args.config_name())?;
    Ok(config)
}

/// What every stage process sets up: its logger and its node.
pub(crate) fn setup(
    name: &str,
    config: &PipelineConfig,
    max_frame_bytes: usize,
) -> Result<(Option<Logger>, Bus), RunError> {
    // Its own part file per process: a restarted stage must not overwrite its predecessor's.
    let logger = Logger::start(&config.rerun, &format!("{name}-{}", std::process::id()))?;
    quiet_logging();
    let bus = Bus::join(&config.bus.settings(max_frame_bytes), name)?;
    Ok((logger, bus))
}

/// This process's heartbeat ([`StageHeartbeat`]): call [`Self::beat`] from the loop that does
/// the work, as often as convenient; it sends at most every half period.
pub struct Heartbeat {
    publisher: MessagePublisher<StageHeartbeat>,
    pid: u32,
    seq: u64,
    last_ns: u64,
}

impl Heartbeat {
    /// How often a loop must turn (at the latest) for its beats to be on time.
    pub const PERIOD: Duration = Duration::from_nanos(StageHeartbeat::PERIOD_NS);

    pub fn new(bus: &Bus) -> Result<Self, BusError> {
        Ok(Self {
            publisher: bus.publisher()?,
            pid: std::process::id(),
            seq: 0,
            last_ns: 0,
        })
    }

    pub fn beat(&mut self) {
        let now = monotonic_ns();
        if self.seq > 0 && now.saturating_sub(self.last_ns) < StageHeartbeat::PERIOD_NS / 2 {
            return;
        }
        // A lost beat is not an error here: the launcher notices if they all stop.
        let _ = self.publisher.send(&StageHeartbeat {
            pid: self.pid,
            seq: self.seq,
            sent_ns: now,
        });
        self.seq += 1;
        self.last_ns = now;
    }
}

/// The stage's life in its process: until SIGINT/SIGTERM, wake on input (or the tick), step,
/// publish, log.
pub fn run<S: Stage>(args: &StageArgs) -> Result<String, RunError> {
    let config = checked_config(args)?;
    // The subscriber side does not size frames; 1 is a placeholder the publisher never sees.
    let (logger, bus) = setup(S::NAME, &config, 1)?;
    let mut stage = S::from_config(&config, args.restarted)?;
    let input = S::Input::subscribe(&bus)?;
    let output = bus.publisher::<S::Output>()?;
    let log = |items: Vec<Item>| {
        if let Some(l) = &logger {
            items.into_iter().for_each(|i| l.log(i));
        }
    };
    let mut heartbeat = Heartbeat::new(&bus)?;
    heartbeat.beat();
    // The loop turns at least every heartbeat period; the stage's own tick may be faster.
    let period = Some(
        stage
            .tick_period()
            .map_or(Heartbeat::PERIOD, |p| p.min(Heartbeat::PERIOD)),
    );
    let vehicle = if stage.wants_vehicle() {
        Some(bus.subscriber::<VehicleSample>()?)
    } else {
        None
    };
    let mut listeners = vec![input.listener()];
    listeners.extend(vehicle.as_ref().map(|v| v.listener()));
    event_loop(&listeners, period, |wake| {
        heartbeat.beat();
        if let Some(v) = &vehicle {
            while let Some(sample) = v.receive()? {
                stage.vehicle_sample(&sample);
            }
        }
        if wake == Wake::Tick {
            if let Some(o) = stage.tick(monotonic_ns()) {
                output.send(&o)?;
                log(stage.viewer_items(&o));
            }
        }
        input.drain(
            |view| {
                let o = stage.step(view, monotonic_ns());
                let warning = stage.take_warning();
                let items = if logger.is_some() {
                    stage.viewer_items(&o)
                } else {
                    Vec::new()
                };
                (o, warning, items)
            },
            |(o, warning, items)| {
                if let Some(w) = warning {
                    deckwatch_common::say!("deckwatch-{}: {w}", S::NAME);
                }
                output.send(&o)?;
                log(items);
                Ok(())
            },
        )?;
        stage.after_outputs();
        let rejections = std::iter::once(input.rejections()).chain(vehicle.as_ref().map(|v| v.rejections()));
        for r in rejections {
            if let Some(line) = r.report(monotonic_ns()) {
                deckwatch_common::say!("deckwatch-{}: {line}", S::NAME);
            }
        }
        Ok::<Flow, BusError>(Flow::Continue)
    })?;
    let dropped_items = logger.as_ref().map_or(0, |l| l.dropped());
    let bad_messages = input.rejections().count() + vehicle.as_ref().map_or(0, |v| v.rejections().count());
    Ok(format!(
        "{}; {dropped_items} log items dropped; {bad_messages} bad messages skipped",
        stage.summary()
    ))
}
