//! The launcher: starts the four stage processes (decide, estimate, detect, then capture, each
//! once the previous one listens), supervises them (a crashed stage is restarted with backoff
//! while the others keep running), follows the decisions they produce (live status line,
//! latency histograms, drops, accuracy against the ground truth) and stops everything cleanly
//! on Ctrl-C/SIGTERM or when the source is exhausted.

use deckwatch_capture::camera::CameraConfig;
use deckwatch_capture::scenario::SimulationArgs;
use deckwatch_capture::sim::ImageArgs;
use deckwatch_capture::source::{CaptureConfig, ReplayConfig, SourceConfig};
use deckwatch_common::bus::{event_loop, quiet_logging, services, Bus, BusConfig, BusError, Flow, Wake};
use deckwatch_common::messages::{DecisionState, GapCounter, LandingDecision, LatencyInterval};
use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::ErrorStats;
use deckwatch_decide::decision::DecisionConfig;
use deckwatch_estimate::stage::EstimateConfig;
use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};
use std::io::{IsTerminal, Write};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// `[supervisor]`: how the launcher runs the stages.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct SupervisorConfig {
    /// First restart delay of a crashed stage; doubles with each further crash in a row.
    pub restart_backoff_ms: u64,
    pub max_backoff_ms: u64,
    /// Restarts allowed per stage before the run is given up (0: never restart).
    pub max_restarts: u32,
    /// A stage that ran this long before crashing starts its backoff afresh.
    pub healthy_after_ms: u64,
    /// How long a stage may take to connect at start.
    pub ready_timeout_ms: u64,
    /// How long a stage may take to exit after SIGTERM before it is killed.
    pub stop_timeout_ms: u64,
    /// After the source is exhausted: stop once no decision came for this long.
    pub drain_ms: u64,
    /// Live status line period.
    pub status_interval_ms: u64,
}

impl Default for SupervisorConfig {
    fn default() -> Self {
        Self {
            restart_backoff_ms: 250,
            max_backoff_ms: 8000,
            max_restarts: 10,
            healthy_after_ms: 10_000,
            ready_timeout_ms: 10_000,
            stop_timeout_ms: 3000,
            drain_ms: 500,
            status_interval_ms: 1000,
        }
    }
}

/// The whole pipeline configuration (TOML). Each stage reads its own sections from the same
/// file; the launcher checks all of them, unknown keys included, before starting anything.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct PipelineConfig {
    pub bus: BusConfig,
    pub source: SourceConfig,
    pub sim: SimulationArgs,
    pub image: ImageArgs,
    pub replay: ReplayConfig,
    pub libcamera: CameraConfig,
    pub estimate: EstimateConfig,
    pub decide: DecisionConfig,
    pub supervisor: SupervisorConfig,
    pub rerun: deckwatch_viz::RerunConfig,
}

impl PipelineConfig {
    /// Parses and validates; errors name the file, line and key.
    pub fn from_toml(file: &str, text: &str) -> Result<Self, String> {
        let c: Self = toml::from_str(text).map_err(|e| format!("{file}: {e}"))?;
        Ok(c)
    }

    pub fn load(path: &Path) -> Result<Self, String> {
        let text =
            std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
        Self::from_toml(&path.display().to_string(), &text)
    }

    /// Checks every section the way its stage will (without opening the source).
    pub fn validate(&self) -> Result<(), String> {
        deckwatch_common::bus::validate_domain(&self.bus.domain).map_err(|e| format!("bus.{e}"))?;
        self.bus.settings(1).validate().map_err(|e| format!("bus.{e}"))?;
        self.capture().check()?;
        self.estimate.kind()?;
        self.decide.validate().map_err(|e| format!("decide.{e}"))?;
        self.rerun.validate().map_err(|e| format!("rerun.{e}"))?;
        let s = &self.supervisor;
        for (k, v) in [
            ("ready_timeout_ms", s.ready_timeout_ms),
            ("stop_timeout_ms", s.stop_timeout_ms),
            ("status_interval_ms", s.status_interval_ms),
            ("restart_backoff_ms", s.restart_backoff_ms),
        ] {
            if v == 0 {
                return Err(format!("supervisor.{k}: must be positive"));
            }
        }
        Ok(())
    }

    pub fn capture(&self) -> CaptureConfig {
        CaptureConfig {
            source: self.source.clone(),
            sim: self.sim.clone(),
            image: self.image.clone(),
            replay: self.replay.clone(),
            libcamera: self.libcamera.clone(),
        }
    }
}

/// How the launcher reports while it runs.
#[derive(Debug, Clone, Default)]
pub struct LaunchOptions {
    /// Print the live status line.
    pub status: bool,
    /// Write every decision as a CSV row to this file.
    pub decisions_csv: Option<PathBuf>,
    /// Where the stage binaries are (default: beside this executable).
    pub stage_dir: Option<PathBuf>,
}

/// The stages in start order: each one's input service must have a subscriber before the
/// stage upstream of it starts, so no frame is published into the void.
const STAGES: [(&str, Option<&str>); 4] = [
    ("decide", Some(services::ATTITUDE)),
    ("estimate", Some(services::MARKERS)),
    ("detect", Some(services::FRAMES)),
    ("capture", None),
];

struct StageProcess {
    name: &'static str,
    binary: PathBuf,
    child: Option<Child>,
    started: Instant,
    restarts: u32,
    failures_in_a_row: u32,
    restart_at: Option<Instant>,
    finished: bool,
}

fn say(msg: impl std::fmt::Display) {
    eprintln!("deckwatch: {msg}");
}

impl StageProcess {
    fn spawn(&mut self, config: &Path, domain: &str) -> Result<(), String> {
        let mut cmd = Command::new(&self.binary);
        cmd.arg("--config")
            .arg(config)
            .arg("--domain")
            .arg(domain)
            .stdin(Stdio::null());
        if self.restarts > 0 {
            cmd.arg("--restarted");
        }
        // Own process group: Ctrl-C reaches the launcher only, which stops the stages in order.
        cmd.process_group(0);
        // SAFETY: prctl is async-signal-safe; it makes the kernel send SIGTERM to the stage if
        // the launcher dies, so no stage outlives it.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                Ok(())
            });
        }
        let child = cmd
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", self.binary.display()))?;
        say(format_args!("started {} (pid {})", self.name, child.id()));
        self.child = Some(child);
        self.started = Instant::now();
        self.restart_at = None;
        Ok(())
    }

    fn signal(&self, sig: i32) {
        if let Some(c) = &self.child {
            // SAFETY: kill(2) on our own child's pid.
            unsafe { libc::kill(c.id() as i32, sig) };
        }
    }
}

fn describe(status: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(s)) => format!("signal {s}"),
        _ => "unknown status".into(),
    }
}

/// Sums a counter that restarts at 0 when its process is restarted.
#[derive(Debug, Default, Clone, Copy)]
struct RestartingCounter {
    last: u64,
    total: u64,
}

impl RestartingCounter {
    fn update(&mut self, v: u64) {
        self.total += if v >= self.last { v - self.last } else { v };
        self.last = v;
    }
}

/// Latency percentiles of one interval (milliseconds).
#[derive(Debug, Clone, Serialize)]
pub struct LatencyRow {
    pub interval: String,
    pub count: u64,
    pub p50_ms: f64,
    pub p90_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

/// Frames lost, by where.
#[derive(Debug, Clone, Default, Serialize)]
pub struct DropReport {
    pub capture: u64,
    pub bad_frames: u64,
    pub detect: u64,
    pub estimate: u64,
    pub decide: u64,
    /// Decisions the launcher itself missed (its queue overflowed).
    pub observer: u64,
}

impl DropReport {
    pub fn total(&self) -> u64 {
        self.capture + self.bad_frames + self.detect + self.estimate + self.decide
    }
}

/// What a run did.
#[derive(Debug, Clone, Serialize)]
pub struct RunReport {
    pub decisions: u64,
    /// Stale-data decisions of decide's watchdog (no attitude in time), not answers to frames.
    pub watchdog_decisions: u64,
    pub duration_s: f64,
    pub latency: Vec<LatencyRow>,
    pub drops: DropReport,
    pub restarts: Vec<(String, u32)>,
    pub states: Vec<(String, u64)>,
    pub valid_attitudes: u64,
    /// Roll, pitch, yaw RMSE and max error (deg) over frames with truth and an attitude.
    pub rmse_deg: Option<[f64; 3]>,
    pub max_error_deg: Option<[f64; 3]>,
    /// Frames with an attitude although the source says no deck was in view.
    pub attitudes_without_deck: u64,
    /// Whether the run ended because of a signal (else: the source was exhausted).
    pub interrupted: bool,
}

struct Histograms(Vec<Histogram<u64>>);

impl Histograms {
    fn new() -> Self {
        Self(
            LatencyInterval::ALL
                .iter()
                .map(|_| Histogram::new_with_bounds(1, 120_000_000_000, 3).expect("valid bounds"))
                .collect(),
        )
    }

    fn record(&mut self, d: &LandingDecision) {
        for (h, i) in self.0.iter_mut().zip(LatencyInterval::ALL) {
            if let Some(ns) = d.stamp.times.interval_ns(i) {
                let _ = h.record(ns.max(1));
            }
        }
    }

    fn p50_ms(&self, i: LatencyInterval) -> f64 {
        let h = &self.0[LatencyInterval::ALL.iter().position(|x| *x == i).expect("listed")];
        if h.is_empty() {
            f64::NAN
        } else {
            h.value_at_quantile(0.5) as f64 / 1e6
        }
    }

    fn rows(&self) -> Vec<LatencyRow> {
        self.0
            .iter()
            .zip(LatencyInterval::ALL)
            .map(|(h, i)| {
                let q = |q: f64| {
                    if h.is_empty() {
                        f64::NAN
                    } else {
                        h.value_at_quantile(q) as f64 / 1e6
                    }
                };
                LatencyRow {
                    interval: i.name().into(),
                    count: h.len(),
                    p50_ms: q(0.5),
                    p90_ms: q(0.9),
                    p99_ms: q(0.99),
                    max_ms: if h.is_empty() {
                        f64::NAN
                    } else {
                        h.max() as f64 / 1e6
                    },
                }
            })
            .collect()
    }

    fn reset(&mut self) {
        for h in &mut self.0 {
            h.reset();
        }
    }
}

/// Follows the decision stream.
struct Observer {
    decisions: u64,
    /// Decisions decide's watchdog issued because attitudes stopped coming.
    watchdog: u64,
    all: Histograms,
    recent: Histograms,
    recent_count: u64,
    counters: [RestartingCounter; 5],
    gaps: GapCounter,
    observer_missed: u64,
    states: [u64; 4],
    valid: u64,
    errors: ErrorStats,
    attitudes_without_deck: u64,
    last: Option<LandingDecision>,
    last_at: Instant,
    csv: Option<std::io::BufWriter<std::fs::File>>,
}

const CSV_HEADER: &str = "seq,source_index,captured_ns,published_ns,detect_received_ns,detect_finished_ns,\
estimate_received_ns,estimate_finished_ns,decide_received_ns,decide_finished_ns,state,reason,valid,\
roll_deg,pitch_deg,yaw_deg,truth_roll_deg,truth_pitch_deg,truth_yaw_deg,markers,\
drops_capture,drops_bad,drops_detect,drops_estimate,drops_decide,calm_start_s,calm_length_s,watchdog";

impl Observer {
    fn new(csv: Option<&Path>) -> Result<Self, String> {
        let csv = match csv {
            Some(p) => {
                let f =
                    std::fs::File::create(p).map_err(|e| format!("{}: cannot create: {e}", p.display()))?;
                let mut w = std::io::BufWriter::new(f);
                writeln!(w, "{CSV_HEADER}").map_err(|e| format!("{}: {e}", p.display()))?;
                Some(w)
            }
            None => None,
        };
        Ok(Self {
            decisions: 0,
            watchdog: 0,
            all: Histograms::new(),
            recent: Histograms::new(),
            recent_count: 0,
            counters: Default::default(),
            gaps: GapCounter::from_start(),
            observer_missed: 0,
            states: [0; 4],
            valid: 0,
            errors: ErrorStats::default(),
            attitudes_without_deck: 0,
            last: None,
            last_at: Instant::now(),
            csv,
        })
    }

    fn observe(&mut self, d: &LandingDecision) -> Result<(), String> {
        if d.watchdog {
            self.watchdog += 1;
            self.write_csv(d)?;
            self.last = Some(*d);
            return Ok(());
        }
        self.decisions += 1;
        self.recent_count += 1;
        self.all.record(d);
        self.recent.record(d);
        let dr = d.stamp.drops;
        for (c, v) in
            self.counters
                .iter_mut()
                .zip([dr.capture, dr.bad_frames, dr.detect, dr.estimate, dr.decide])
        {
            c.update(v);
        }
        self.observer_missed += self.gaps.observe(d.stamp.seq, dr.total());
        self.states[d.state as usize] += 1;
        let a = &d.attitude;
        if a.valid {
            self.valid += 1;
            if let Some(t) = d.context.truth.attitude() {
                self.errors.add(rpy_error_deg(&a.rpy, &t));
            } else if d.context.truth.no_deck() {
                self.attitudes_without_deck += 1;
            }
        }
        self.write_csv(d)?;
        self.last = Some(*d);
        self.last_at = Instant::now();
        Ok(())
    }

    fn write_csv(&mut self, d: &LandingDecision) -> Result<(), String> {
        let (a, dr) = (&d.attitude, d.stamp.drops);
        if let Some(w) = &mut self.csv {
            let t = d.stamp.times;
            let [r, p, y] = if a.valid {
                a.rpy.to_degrees()
            } else {
                [f64::NAN; 3]
            };
            let tr = &d.context.truth;
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{r:.6},{p:.6},{y:.6},{:.6},{:.6},{:.6},{},{},{},{},{},{},{:.3},{:.3},{}",
                d.stamp.seq,
                d.context.source_index,
                t.captured_ns,
                t.published_ns,
                t.detect_received_ns,
                t.detect_finished_ns,
                t.estimate_received_ns,
                t.estimate_finished_ns,
                t.decide_received_ns,
                t.decide_finished_ns,
                d.state.name(),
                d.reason.name(),
                a.valid as u8,
                tr.roll_deg,
                tr.pitch_deg,
                tr.yaw_deg,
                a.markers_used,
                dr.capture,
                dr.bad_frames,
                dr.detect,
                dr.estimate,
                dr.decide,
                d.calm_window_start_s,
                d.calm_window_length_s,
                d.watchdog as u8
            )
            .and_then(|_| w.flush())
            .map_err(|e| format!("decisions CSV: {e}"))?;
        }
        Ok(())
    }

    fn drops(&self) -> DropReport {
        let c = &self.counters;
        DropReport {
            capture: c[0].total,
            bad_frames: c[1].total,
            detect: c[2].total,
            estimate: c[3].total,
            decide: c[4].total,
            observer: self.observer_missed,
        }
    }

    fn status_line(&mut self, elapsed: f64, period: f64) -> String {
        let fps = self.recent_count as f64 / period;
        let h = &self.recent;
        let decision = match &self.last {
            Some(d) if d.attitude.valid => {
                let [r, p, y] = d.attitude.rpy.to_degrees();
                format!(
                    "{} {} | r {r:+.2} p {p:+.2} y {y:+.1} deg",
                    d.state.name(),
                    d.reason.name()
                )
            }
            Some(d) => format!("{} {}", d.state.name(), d.reason.name()),
            None => "no decision yet".into(),
        };
        let line = format!(
            "[{elapsed:7.1} s] {fps:5.1} fps | p50 ms: capture {:.2} hop {:.2} detect {:.2} estimate {:.2} decide {:.2} e2e {:.2} | drops {} | {decision}",
            h.p50_ms(LatencyInterval::Capture),
            h.p50_ms(LatencyInterval::CaptureToDetect),
            h.p50_ms(LatencyInterval::Detect),
            h.p50_ms(LatencyInterval::Estimate),
            h.p50_ms(LatencyInterval::Decide),
            h.p50_ms(LatencyInterval::EndToEnd),
            self.drops().total() + self.observer_missed,
        );
        self.recent.reset();
        self.recent_count = 0;
        line
    }
}

fn stage_binary(dir: &Option<PathBuf>, name: &str) -> Result<PathBuf, String> {
    let dir = match dir {
        Some(d) => d.clone(),
        None => std::env::current_exe()
            .map_err(|e| format!("cannot locate the deckwatch executable: {e}"))?
            .parent()
            .map(Path::to_path_buf)
            .ok_or("the deckwatch executable has no folder")?,
    };
    let p = dir.join(format!("deckwatch-{name}"));
    if p.is_file() {
        Ok(p)
    } else {
        Err(format!(
            "stage binary {} not found; build all binaries with `cargo build --release --workspace --bins`",
            p.display()
        ))
    }
}

/// Runs the pipeline until the source is exhausted or a signal arrives.
pub fn launch(config: &PipelineConfig, options: &LaunchOptions) -> Result<RunReport, String> {
    config.validate()?;
    let domain = config.bus.domain.clone();
    quiet_logging();
    Bus::cleanup_dead_nodes(&domain).map_err(|e| e.to_string())?;
    let alive = Bus::live_nodes(&domain).map_err(|e| e.to_string())?;
    if !alive.is_empty() {
        return Err(format!(
            "domain `{domain}` is in use by running nodes ({}); stop that pipeline or choose another --domain",
            alive.join(", ")
        ));
    }
    let mut stages = Vec::new();
    for (name, _) in STAGES {
        stages.push(StageProcess {
            name,
            binary: stage_binary(&options.stage_dir, name)?,
            child: None,
            started: Instant::now(),
            restarts: 0,
            failures_in_a_row: 0,
            restart_at: None,
            finished: false,
        });
    }
    // rerun: every process logs into one recording. With `spawn` the launcher starts the viewer
    // and the stages connect to it; with `save` each process writes a part, merged at the end.
    let mut config = config.clone();
    let viewer = start_viewer(&mut config)?;
    let config = &config;
    // The stages read the same configuration, as the launcher resolved it.
    let run_dir = std::env::temp_dir().join(format!("deckwatch-{domain}-{}", std::process::id()));
    std::fs::create_dir_all(&run_dir).map_err(|e| format!("{}: {e}", run_dir.display()))?;
    let config_path = run_dir.join("pipeline.toml");
    let text = toml::to_string(config).map_err(|e| format!("configuration: {e}"))?;
    std::fs::write(&config_path, text).map_err(|e| format!("{}: {e}", config_path.display()))?;

    let result = supervise(config, options, &mut stages, &config_path);
    stop_all(
        &mut stages,
        Duration::from_millis(config.supervisor.stop_timeout_ms),
    );
    let _ = std::fs::remove_dir_all(&run_dir);
    match Bus::cleanup_dead_nodes(&domain) {
        Ok(r) if r.removed > 0 => say(format_args!("removed the resources of {} dead nodes", r.removed)),
        Ok(_) => {}
        Err(e) => say(e),
    }
    if let Err(e) = Bus::remove_idle_domain(&domain) {
        say(e);
    }
    if let Some(v) = viewer {
        v.close(); // flushes the launcher's part (the blueprint)
    }
    if config.rerun.sink == "save" {
        if let Some(path) = &config.rerun.path {
            match deckwatch_viz::merge_parts(path, &["launcher", "capture", "detect", "estimate", "decide"]) {
                Ok(n) => say(format_args!("rerun recording: {} ({n} messages)", path.display())),
                Err(e) => say(format_args!(
                    "rerun: could not merge the parts into {}: {e}",
                    path.display()
                )),
            }
        }
    }
    result
}

/// Opens the launcher's own rerun stream (which carries the blueprint) and points the stages at
/// the same recording.
fn start_viewer(config: &mut PipelineConfig) -> Result<Option<deckwatch_viz::Viewer>, String> {
    let r = &mut config.rerun;
    if r.sink == "off" {
        return Ok(None);
    }
    if r.recording_id.is_none() {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        r.recording_id = Some(format!("deckwatch-{}-{}", now.as_secs(), std::process::id()));
    }
    let viewer = deckwatch_viz::open_viewer(r, "launcher")?;
    if r.sink == "spawn" {
        // The viewer is up: the stages connect to it rather than spawning their own.
        r.sink = "connect".into();
        r.address = Some(deckwatch_viz::DEFAULT_ADDRESS.into());
    }
    Ok(viewer)
}

fn stop_all(stages: &mut [StageProcess], timeout: Duration) {
    // Capture first, so no new frames enter while the others stop.
    for s in stages.iter().rev() {
        s.signal(libc::SIGTERM);
    }
    let deadline = Instant::now() + timeout;
    for s in stages.iter_mut().rev() {
        let Some(mut child) = s.child.take() else { continue };
        loop {
            match child.try_wait() {
                Ok(Some(_)) => break,
                Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(10)),
                _ => {
                    say(format_args!("{} did not stop in time; killing it", s.name));
                    let _ = child.kill();
                    let _ = child.wait();
                    break;
                }
            }
        }
    }
}

fn supervise(
    config: &PipelineConfig,
    options: &LaunchOptions,
    stages: &mut [StageProcess],
    config_path: &Path,
) -> Result<RunReport, String> {
    let sup = &config.supervisor;
    let domain = &config.bus.domain;
    let bus = Bus::join(&config.bus.settings(1), "launcher").map_err(|e| e.to_string())?;
    let decisions = bus.subscriber::<LandingDecision>().map_err(|e| e.to_string())?;
    let mut observer = Observer::new(options.decisions_csv.as_deref())?;
    let start = Instant::now();

    // Start downstream first; wait until each listens before starting the one feeding it.
    for (i, (_, ready_service)) in STAGES.iter().enumerate() {
        stages[i].spawn(config_path, domain)?;
        if let Some(service) = ready_service {
            let deadline = Instant::now() + Duration::from_millis(sup.ready_timeout_ms);
            loop {
                if bus.subscriber_count(service).map_err(|e| e.to_string())? >= 1 {
                    break;
                }
                if let Some(status) = stages[i].child.as_mut().and_then(|c| c.try_wait().ok().flatten()) {
                    return Err(format!(
                        "{} exited at start ({})",
                        stages[i].name,
                        describe(status)
                    ));
                }
                if Instant::now() > deadline {
                    return Err(format!(
                        "{} did not connect within {} ms",
                        stages[i].name, sup.ready_timeout_ms
                    ));
                }
                if !bus.sleep(Duration::from_millis(5)) {
                    return Err("interrupted while starting".into());
                }
            }
        }
    }

    let tty = std::io::stdout().is_terminal();
    let status_period = Duration::from_millis(sup.status_interval_ms);
    let mut next_status = Instant::now() + status_period;
    let mut source_done: Option<Instant> = None;
    let mut failure: Option<String> = None;
    let end = event_loop(&[decisions.listener()], Some(Duration::from_millis(50)), |wake| {
        if wake == Wake::Input(0) {
            while let Some(d) = decisions.receive()? {
                if let Err(e) = observer.observe(&d) {
                    failure = Some(e);
                    return Ok(Flow::Stop);
                }
            }
            return Ok(Flow::Continue);
        }
        let now = Instant::now();
        for s in stages.iter_mut() {
            let exited = s.child.as_mut().and_then(|c| c.try_wait().ok().flatten());
            if let Some(status) = exited {
                s.child = None;
                if s.name == "capture" && status.success() {
                    say("capture finished its source");
                    s.finished = true;
                    source_done = Some(now);
                    continue;
                }
                if s.started.elapsed() >= Duration::from_millis(sup.healthy_after_ms) {
                    s.failures_in_a_row = 0;
                }
                s.failures_in_a_row += 1;
                if s.restarts >= sup.max_restarts {
                    failure = Some(format!(
                        "{} stopped ({}) and has used its {} restarts",
                        s.name,
                        describe(status),
                        sup.max_restarts
                    ));
                    return Ok(Flow::Stop);
                }
                let shift = (s.failures_in_a_row - 1).min(16);
                let backoff = (sup.restart_backoff_ms << shift).min(sup.max_backoff_ms);
                say(format_args!(
                    "{} stopped ({}); restarting in {backoff} ms (restart {} of {})",
                    s.name,
                    describe(status),
                    s.restarts + 1,
                    sup.max_restarts
                ));
                s.restart_at = Some(now + Duration::from_millis(backoff));
            }
            if s.restart_at.is_some_and(|t| now >= t) {
                s.restarts += 1;
                if let Err(e) = s.spawn(config_path, domain) {
                    failure = Some(e);
                    return Ok(Flow::Stop);
                }
            }
        }
        if now >= next_status {
            next_status = now + status_period;
            let line = observer.status_line(start.elapsed().as_secs_f64(), status_period.as_secs_f64());
            if options.status {
                if tty {
                    print!("\r\x1b[2K{line}");
                    let _ = std::io::stdout().flush();
                } else {
                    println!("{line}");
                }
            }
        }
        if let Some(done) = source_done {
            let quiet_since = done.max(observer.last_at);
            if now.duration_since(quiet_since) >= Duration::from_millis(sup.drain_ms) {
                return Ok(Flow::Stop);
            }
        }
        Ok::<Flow, BusError>(Flow::Continue)
    })
    .map_err(|e| e.to_string())?;
    if options.status && tty {
        println!();
    }
    if let Some(e) = failure {
        return Err(e);
    }
    let duration_s = start.elapsed().as_secs_f64();
    let names = ["NO-DECK", "HOLD", "CLEAR", "ABORT"];
    debug_assert_eq!(DecisionState::Abort as usize, 3);
    Ok(RunReport {
        decisions: observer.decisions,
        watchdog_decisions: observer.watchdog,
        duration_s,
        latency: observer.all.rows(),
        drops: observer.drops(),
        restarts: stages.iter().map(|s| (s.name.to_string(), s.restarts)).collect(),
        states: names
            .iter()
            .zip(observer.states)
            .map(|(n, c)| (n.to_string(), c))
            .collect(),
        valid_attitudes: observer.valid,
        rmse_deg: (observer.errors.n > 0).then(|| observer.errors.rmse()),
        max_error_deg: (observer.errors.n > 0).then_some(observer.errors.max),
        attitudes_without_deck: observer.attitudes_without_deck,
        interrupted: matches!(end, deckwatch_common::bus::LoopEnd::Signal),
    })
}

/// The report as a table for people.
pub fn print_report(r: &RunReport) {
    println!(
        "{} decisions in {:.1} s ({:.1} per s){}",
        r.decisions,
        r.duration_s,
        r.decisions as f64 / r.duration_s.max(1e-9),
        if r.interrupted { ", stopped by signal" } else { "" }
    );
    println!("latency (ms)        count      p50      p90      p99      max");
    for l in &r.latency {
        println!(
            "  {:<16} {:>7} {:>8.3} {:>8.3} {:>8.3} {:>8.3}",
            l.interval, l.count, l.p50_ms, l.p90_ms, l.p99_ms, l.max_ms
        );
    }
    let d = &r.drops;
    println!(
        "drops: {} (capture {}, bad frames {}, detect {}, estimate {}, decide {}); decisions missed by the launcher: {}",
        d.total(),
        d.capture,
        d.bad_frames,
        d.detect,
        d.estimate,
        d.decide,
        d.observer
    );
    let states: Vec<String> = r.states.iter().map(|(n, c)| format!("{n} {c}")).collect();
    println!(
        "decisions: {}; watchdog (stale) decisions: {}",
        states.join(", "),
        r.watchdog_decisions
    );
    let restarts: Vec<String> = r.restarts.iter().map(|(n, c)| format!("{n} {c}")).collect();
    println!("restarts: {}", restarts.join(", "));
    if let (Some(rmse), Some(max)) = (r.rmse_deg, r.max_error_deg) {
        println!(
            "attitude vs truth (deg): RMSE roll {:.4} pitch {:.4} yaw {:.4}; max {:.4} {:.4} {:.4}",
            rmse[0], rmse[1], rmse[2], max[0], max[1], max[2]
        );
    }
    println!(
        "valid attitudes: {} of {}; attitudes on frames without a deck: {}",
        r.valid_attitudes, r.decisions, r.attitudes_without_deck
    );
}
