//! The stage abstraction and its one runner.
//!
//! A stage is a per-message step from one input to one output ([`Stage::step`]) with an
//! optional periodic [`Stage::tick`]; it knows nothing of processes or shared memory. The same
//! value runs in a process of its own ([`main`]: setup, the event loop, logging, drop counting,
//! exit codes) and in the in-process chain ([`crate::chain`]), so both compute the same thing.
//!
//! Every process of the pipeline is a [`Process`]: its inputs and outputs make the topology
//! ([`crate::stages::PROCESSES`]), from which the launcher derives the start order and when each
//! process is up ([`start_order`]); every binary is [`main`]. A [`Stage`] is a process through
//! [`run`]; the source and the sinks implement [`Process`] with loops of their own.
//!
//! Adding a stage (ARCHITECTURE.md): implement [`Stage`] in `stages/<name>.rs`, add
//! `src/bin/deckwatch-<name>.rs` calling [`main`], and in `stages/mod.rs` declare the module and
//! put it in its place in [`crate::stages::FrameStages`] (its place in the stage table,
//! [`PipelineStage`], is its [`Stage::PLACE`]); a process other than a stage goes in
//! [`crate::stages::PROCESSES`].

use crate::bus::{
    event_loop, quiet_logging, Bus, BusError, Flow, FrameSubscriber, Listener, Message, MessagePublisher,
    MessageSubscriber, Rejections, Wake,
};
use crate::config::{ConfigError, PipelineConfig, DEFAULTS};
use deckwatch_common::messages::{
    monotonic_ns, Channel, FrameHeader, LandingDecision, PipelineStage, StageHeartbeat, StageLog,
    VehicleSample,
};
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
    /// Its place in the pipeline (the stage table, [`PipelineStage`]): its name (its node, its
    /// binary `deckwatch-<name>`, its log lines) and the index of the times and the drop count
    /// it stamps on its output.
    const PLACE: PipelineStage;
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

    /// Services the stage may follow besides its input (see [`Process::SIDE_INPUTS`]).
    const SIDE_INPUTS: &'static [&'static str] = &[];

    /// Whether the stage follows the vehicle's attitude stream ([`VehicleSample`], from the link
    /// process) besides its input (it must then list it in [`Stage::SIDE_INPUTS`]).
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
    const RECEIVED_ON: &'static str;
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
    const RECEIVED_ON: &'static str = FrameHeader::SERVICE;
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
    const RECEIVED_ON: &'static str = <M as Channel>::SERVICE;
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

/// A process of the pipeline as the launcher sees it: its name, what it takes in and puts out
/// (the topology), whether a configuration runs it, and its life. [`Stage`]s are processes
/// through [`run`]; the source (capture) and the sinks (link, recorder) have loops of their own.
pub trait Process {
    /// Its node, its binary (`deckwatch-<NAME>`), its log lines.
    const NAME: &'static str;
    /// The services it publishes (besides its heartbeat).
    const OUTPUTS: &'static [&'static str];
    /// Services it may follow besides its inputs (the vehicle's attitude), which do not order
    /// the start: the vehicle stream comes from the link, which starts downstream of them.
    const SIDE_INPUTS: &'static [&'static str] = &[];
    /// The services it subscribes to under `config`; the first says, by its subscriber count,
    /// that the process is up.
    fn inputs(config: &PipelineConfig) -> Vec<&'static str>;
    /// Whether `config` runs it.
    fn runs(_config: &PipelineConfig) -> bool {
        true
    }
    /// Its life in its process, from the checked configuration to its summary line.
    fn run(config: PipelineConfig, args: &StageArgs) -> Result<String, RunError>;
}

impl<S: Stage> Process for S {
    const NAME: &'static str = S::PLACE.name();
    const OUTPUTS: &'static [&'static str] = &[<S::Output as Channel>::SERVICE];
    const SIDE_INPUTS: &'static [&'static str] = <S as Stage>::SIDE_INPUTS;
    fn inputs(_config: &PipelineConfig) -> Vec<&'static str> {
        vec![<S::Input as Input>::RECEIVED_ON]
    }
    fn run(config: PipelineConfig, args: &StageArgs) -> Result<String, RunError> {
        run::<S>(config, args)
    }
}

/// A [`Process`] as a value: one entry of the topology ([`crate::stages::PROCESSES`]).
#[derive(Clone, Copy)]
pub struct ProcessInfo {
    pub name: &'static str,
    pub outputs: &'static [&'static str],
    pub side_inputs: &'static [&'static str],
    pub inputs: fn(&PipelineConfig) -> Vec<&'static str>,
    pub runs: fn(&PipelineConfig) -> bool,
}

impl std::fmt::Debug for ProcessInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProcessInfo")
            .field("name", &self.name)
            .field("outputs", &self.outputs)
            .field("side_inputs", &self.side_inputs)
            .finish_non_exhaustive()
    }
}

/// The entry of `P` in the topology.
pub const fn process<P: Process>() -> ProcessInfo {
    ProcessInfo {
        name: P::NAME,
        outputs: P::OUTPUTS,
        side_inputs: P::SIDE_INPUTS,
        inputs: P::inputs,
        runs: P::runs,
    }
}

/// What the launcher subscribes to before it starts anything: the decisions it follows, and
/// the heartbeats.
pub const LAUNCHER_INPUTS: [&str; 2] = [LandingDecision::SERVICE, StageHeartbeat::SERVICE];

/// What the launcher publishes: the stages' log lines (while a recorder runs).
pub const LAUNCHER_OUTPUTS: [&str; 1] = [StageLog::SERVICE];

/// When the launcher starts a process and when it counts it as up: once `ready_service` has
/// `ready_subscribers` subscribers (None: a process that takes nothing in, the source).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StageInfo {
    pub name: &'static str,
    pub ready_service: Option<&'static str>,
    pub ready_subscribers: usize,
}

/// The processes `config` runs, in start order, each with the subscriber count that says it is
/// up: derived from the topology `processes`, never listed by hand.
///
/// Every process starts after those that take its outputs in (downstream first), so nothing is
/// published before its consumers listen: the recorder first (it takes everything in), then
/// the link (the decisions' consumer), decide, estimate, detect, and capture last. Side inputs
/// do not order (the vehicle stream flows from the link, upstream of nothing). Ties go in the
/// topology's order. A process is up when its first input has as many subscribers as the
/// processes started so far (itself included) and the launcher subscribe to it.
pub fn start_order(processes: &[ProcessInfo], config: &PipelineConfig) -> Vec<StageInfo> {
    let active: Vec<(ProcessInfo, Vec<&'static str>)> = processes
        .iter()
        .filter(|p| (p.runs)(config))
        .map(|p| (*p, (p.inputs)(config)))
        .collect();
    let mut placed = vec![false; active.len()];
    let mut order = Vec::with_capacity(active.len());
    while order.len() < active.len() {
        // The first process whose outputs' consumers have all started; with none (a cycle
        // through main inputs), the first left, so that a bad topology still starts.
        let waits_for = |i: usize| {
            active.iter().enumerate().any(|(j, (_, inputs))| {
                j != i && !placed[j] && inputs.iter().any(|s| active[i].0.outputs.contains(s))
            })
        };
        let next = (0..active.len())
            .find(|&i| !placed[i] && !waits_for(i))
            .or_else(|| (0..active.len()).find(|&i| !placed[i]))
            .unwrap_or_default();
        placed[next] = true;
        order.push(next);
    }
    order
        .iter()
        .enumerate()
        .map(|(k, &i)| {
            let (p, inputs) = &active[i];
            let ready_service = inputs.first().copied();
            let ready_subscribers = ready_service.map_or(0, |s| {
                let processes = order[..=k].iter().filter(|&&j| active[j].1.contains(&s)).count();
                processes + LAUNCHER_INPUTS.iter().filter(|&&l| l == s).count()
            });
            StageInfo {
                name: p.name,
                ready_service,
                ready_subscribers,
            }
        })
        .collect()
}

/// The stages a configuration runs, in start order (the link only with `[link] enabled`, the
/// recorder only with `[record] path`), from the pipeline's topology.
pub fn active_stages(config: &PipelineConfig) -> Vec<StageInfo> {
    start_order(&crate::stages::PROCESSES, config)
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

/// The exit code of a stage that refused its input (its configuration, a recording, the
/// simulator's options): sysexits' `EX_DATAERR`. The launcher does not restart it, since it would
/// read the same input again; a camera or a bus that failed is restarted as a crash is.
pub const EXIT_BAD_INPUT: u8 = 65;

impl RunError {
    /// Whether the error is in what the stage was given, not in what happened to it.
    pub fn is_bad_input(&self) -> bool {
        use deckwatch_capture::source::SourceError;
        match self {
            RunError::Config(_) => true,
            RunError::Source(e) => matches!(
                e,
                SourceError::Config { .. } | SourceError::Recording(_) | SourceError::Simulator(_)
            ),
            _ => false,
        }
    }
}

/// Runs a process's binary, every one of them the same way: parse the command line, check the
/// configuration, run, report; the exit code says how it went.
pub fn main<P: Process>() -> ExitCode {
    let args = <StageArgs as clap::Parser>::parse();
    exit_code(
        P::NAME,
        checked_config(&args).and_then(|config| P::run(config, &args)),
    )
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
            if e.is_bad_input() {
                ExitCode::from(EXIT_BAD_INPUT)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

/// The configuration of a stage process, checked (a stage may be started by hand, not only by
/// the launcher, which checks it too).
fn checked_config(args: &StageArgs) -> Result<PipelineConfig, RunError> {
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
pub fn run<S: Stage>(config: PipelineConfig, args: &StageArgs) -> Result<String, RunError> {
    let name = S::PLACE.name();
    // The subscriber side does not size frames; 1 is a placeholder the publisher never sees.
    let (logger, bus) = setup(name, &config, 1)?;
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
    // The topology says which stages may follow the vehicle stream: one that does must say so.
    debug_assert!(
        !stage.wants_vehicle() || S::SIDE_INPUTS.contains(&VehicleSample::SERVICE),
        "{name} follows the vehicle stream but does not list it in Stage::SIDE_INPUTS"
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
                    deckwatch_common::say!("deckwatch-{name}: {w}");
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
                deckwatch_common::say!("deckwatch-{name}: {line}");
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

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::{AttitudeMessage, MarkerMessage};

    fn config(recording: Option<deckwatch_flight::FrameEncoding>, link: bool) -> PipelineConfig {
        let mut c = PipelineConfig::default();
        c.link.enabled = link;
        if let Some(frames) = recording {
            c.record.path = Some("flight.mcap".into());
            c.record.frames = frames;
        }
        c
    }

    fn order(c: &PipelineConfig) -> Vec<(&'static str, Option<&'static str>, usize)> {
        active_stages(c)
            .into_iter()
            .map(|s| {
                (
                    s.name,
                    s.ready_service.filter(|_| s.ready_subscribers > 0),
                    s.ready_subscribers,
                )
            })
            .collect()
    }

    /// The order and readiness the launcher derives from the topology are the ones it was given
    /// by hand before: downstream first, the recorder before everything, the link before decide.
    #[test]
    fn the_start_order_and_readiness_follow_from_the_topology() {
        let (frame, markers, attitude, decision) = (
            FrameHeader::SERVICE,
            MarkerMessage::SERVICE,
            AttitudeMessage::SERVICE,
            LandingDecision::SERVICE,
        );
        let raw = Some(deckwatch_flight::FrameEncoding::Raw);
        assert_eq!(
            order(&config(raw, true)),
            [
                ("record", Some(markers), 1),
                ("link", Some(decision), 3),
                ("decide", Some(attitude), 2),
                ("estimate", Some(markers), 2),
                ("detect", Some(frame), 2),
                ("capture", None, 0),
            ]
        );
        // A recorder without pixels does not take frames in: detect is up at one.
        let headers_only = Some(deckwatch_flight::FrameEncoding::None);
        assert_eq!(order(&config(headers_only, false))[3], ("detect", Some(frame), 1));
        assert_eq!(
            order(&config(None, false)),
            [
                ("decide", Some(attitude), 1),
                ("estimate", Some(markers), 1),
                ("detect", Some(frame), 1),
                ("capture", None, 0),
            ]
        );
    }

    /// A process added to the topology finds its place with nothing else told: one that takes
    /// the decisions in starts before decide, and decide's readiness is unchanged (it is up on
    /// its own input); the link, on the decisions too, is now up at one subscriber more.
    #[test]
    fn an_added_process_finds_its_place() {
        struct Monitor;
        impl Process for Monitor {
            const NAME: &'static str = "monitor";
            const OUTPUTS: &'static [&'static str] = &[];
            fn inputs(_: &PipelineConfig) -> Vec<&'static str> {
                vec![LandingDecision::SERVICE]
            }
            fn run(_: PipelineConfig, _: &StageArgs) -> Result<String, RunError> {
                Ok(String::new())
            }
        }
        let mut processes = crate::stages::PROCESSES.to_vec();
        processes.push(process::<Monitor>());
        let names: Vec<_> = start_order(&processes, &config(None, true))
            .into_iter()
            .map(|s| (s.name, s.ready_subscribers))
            .collect();
        assert_eq!(
            names,
            [
                ("link", 2),
                ("monitor", 3),
                ("decide", 1),
                ("estimate", 1),
                ("detect", 1),
                ("capture", 0)
            ]
        );
    }
}
