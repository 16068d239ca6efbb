//! Supervision: the order stages start in, and what happens when one stops.
//!
//! [`RestartPolicy`] is the rule (pure, tested alone): a crashed stage is restarted after a
//! backoff that doubles with each crash in a row (a stage that ran for `healthy_after_ms`
//! starts afresh), up to `max_restarts` per stage within a sliding `restart_window_ms`; then
//! the run is given up. [`supervise`]
//! applies it to the processes while the observer follows the decisions.

use super::observe::Observer;
use super::process::{describe, Poll, StageProcess};
use super::report::RunReport;
use super::say;
use deckwatch_common::messages::{monotonic_ns, LandingDecision, StageHeartbeat};
use deckwatch_runtime::bus::{event_loop, Bus, BusError, Flow, LoopEnd, Wake};
use deckwatch_runtime::config::{PipelineConfig, SupervisorConfig};
use deckwatch_runtime::stage::{active_stages, EXIT_BAD_INPUT};
use deckwatch_runtime::stages::capture;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What to do about a stage that stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CrashVerdict {
    /// Start it again after this long.
    RestartAfter(Duration),
    /// It has used its restarts: stop the run.
    GiveUp,
}

/// One stage's crash history.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CrashHistory {
    /// Restarts over the whole run (reported).
    pub restarts: u32,
    failures_in_a_row: u32,
    /// When the restarts within the window happened (time since the run began).
    recent: std::collections::VecDeque<Duration>,
}

/// The restart rule of `[supervisor]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RestartPolicy {
    pub backoff: Duration,
    pub max_backoff: Duration,
    pub max_restarts: u32,
    pub window: Duration,
    pub healthy_after: Duration,
}

impl RestartPolicy {
    pub fn new(c: &SupervisorConfig) -> Self {
        Self {
            backoff: Duration::from_millis(c.restart_backoff_ms),
            max_backoff: Duration::from_millis(c.max_backoff_ms),
            max_restarts: c.max_restarts,
            window: Duration::from_millis(c.restart_window_ms),
            healthy_after: Duration::from_millis(c.healthy_after_ms),
        }
    }

    /// A stage stopped at `now` (since the run began) after running for `ran_for`: restart it
    /// (when), or give up when it has used `max_restarts` within the last `window`.
    pub fn on_crash(&self, history: &mut CrashHistory, ran_for: Duration, now: Duration) -> CrashVerdict {
        if ran_for >= self.healthy_after {
            history.failures_in_a_row = 0;
        }
        history.failures_in_a_row = history.failures_in_a_row.saturating_add(1);
        while history
            .recent
            .front()
            .is_some_and(|&t| now.saturating_sub(t) > self.window)
        {
            history.recent.pop_front();
        }
        if history.recent.len() >= self.max_restarts as usize {
            return CrashVerdict::GiveUp;
        }
        history.recent.push_back(now);
        history.restarts = history.restarts.saturating_add(1);
        let shift = (history.failures_in_a_row - 1).min(16);
        let backoff = self.backoff.checked_mul(1 << shift).unwrap_or(Duration::MAX);
        CrashVerdict::RestartAfter(backoff.min(self.max_backoff))
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
    /// The frames come from this process, not from a capture process (a closed-loop trial's
    /// simulated camera, `deckwatch trials --processes`): no capture is started, and the run
    /// ends when `stop` is set.
    pub external_frames: bool,
    /// Set to end the run (as a signal would).
    pub stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
}

/// The stages this run starts, in start order.
pub fn launched_stages(
    config: &PipelineConfig,
    options: &LaunchOptions,
) -> Vec<deckwatch_runtime::stage::StageInfo> {
    active_stages(config)
        .into_iter()
        .filter(|s| !(options.external_frames && s.name == capture::NAME))
        .collect()
}

/// A stage process with its restart state.
pub struct Supervised {
    pub process: StageProcess,
    pub history: CrashHistory,
    restart_at: Option<Instant>,
    /// The newest heartbeat of the current process.
    last_beat: Option<Instant>,
    /// Killed by the launcher because its heartbeats stopped (for the restart message).
    hung: Option<Duration>,
}

impl Supervised {
    pub fn new(process: StageProcess) -> Self {
        Self {
            process,
            history: CrashHistory::default(),
            restart_at: None,
            last_beat: None,
            hung: None,
        }
    }

    /// Whether the running process has gone silent: no heartbeat for `hang` (or none at all
    /// within `startup` of its start). How long, if so.
    fn silent_for(&self, now: Instant, hang: Duration, startup: Duration) -> Option<Duration> {
        self.process.pid()?;
        let (since, limit) = match self.last_beat {
            Some(t) => (t, hang),
            None => (self.process.started, startup),
        };
        let silent = now.saturating_duration_since(since);
        (silent > limit).then_some(silent)
    }

    fn spawn(&mut self, config: &Path, domain: &str) -> Result<(), String> {
        self.process.restarts = self.history.restarts;
        let pid = self.process.spawn(config, domain)?;
        say(format_args!("started {} (pid {pid})", self.process.name));
        self.restart_at = None;
        self.last_beat = None;
        self.hung = None;
        Ok(())
    }
}

/// Starts the stages downstream first, each once the one before listens; then follows the
/// decisions, restarts crashed stages and prints the status line until the source is done (and
/// the pipeline drained), a signal arrives or a stage gives up.
pub fn supervise(
    config: &PipelineConfig,
    options: &LaunchOptions,
    stages: &mut [Supervised],
    config_path: &Path,
    log: Option<&super::LogForwarder>,
) -> Result<RunReport, String> {
    let sup = &config.supervisor;
    let policy = RestartPolicy::new(sup);
    let run_started = Instant::now();
    let domain = &config.bus.domain;
    let bus = Bus::join(&config.bus.settings(1), super::LAUNCHER).map_err(|e| e.to_string())?;
    let decisions = bus.subscriber::<LandingDecision>().map_err(|e| e.to_string())?;
    let heartbeats = bus.subscriber::<StageHeartbeat>().map_err(|e| e.to_string())?;

    let hang = Duration::from_millis(sup.hang_timeout_ms);
    let startup = Duration::from_millis(sup.ready_timeout_ms);
    let mut observer = Observer::new(options.decisions_csv.as_deref())?;
    let start = Instant::now();

    for (s, info) in stages.iter_mut().zip(launched_stages(config, options)) {
        s.spawn(config_path, domain)?;
        let Some(service) = info.ready_service else {
            continue;
        };
        let deadline = Instant::now() + Duration::from_millis(sup.ready_timeout_ms);
        while bus.subscriber_count(service).map_err(|e| e.to_string())? < info.ready_subscribers {
            if let Poll::Exited(status) = s.process.poll() {
                return Err(format!("{} exited at start ({})", info.name, describe(status)));
            }
            if Instant::now() > deadline {
                return Err(format!(
                    "{} did not connect within {} ms",
                    info.name, sup.ready_timeout_ms
                ));
            }
            if !bus.sleep(Duration::from_millis(5)) {
                return Err("interrupted while starting".into());
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
                observer.observe(&d);
            }
            if let Some(line) = decisions.rejections().report(monotonic_ns()) {
                say(line);
            }
            return Ok(Flow::Continue);
        }
        if let Some(l) = log {
            l.forward();
        }
        if options
            .stop
            .as_ref()
            .is_some_and(|s| s.load(std::sync::atomic::Ordering::Relaxed))
        {
            return Ok(Flow::Stop);
        }
        let now = Instant::now();
        while let Some(beat) = heartbeats.receive()? {
            if let Some(s) = stages.iter_mut().find(|s| s.process.pid() == Some(beat.pid)) {
                s.last_beat = Some(now);
            }
        }
        for s in stages.iter_mut() {
            // Stopped (SIGSTOP), deadlocked or stuck: killed here, restarted below like a crash.
            if s.hung.is_none() {
                if let Some(silent) = s.silent_for(now, hang, startup) {
                    say(format_args!(
                        "{} is not responding (no heartbeat for {} ms); killing it",
                        s.process.name,
                        silent.as_millis()
                    ));
                    s.hung = Some(silent);
                    s.process.kill();
                }
            }
        }
        for s in stages.iter_mut() {
            if let Poll::Exited(status) = s.process.poll() {
                if s.process.name == capture::NAME && status.success() {
                    say("capture finished its source");
                    source_done = Some(now);
                    continue;
                }
                let why = match s.hung {
                    Some(silent) => format!("not responding for {} ms, killed", silent.as_millis()),
                    None => describe(status),
                };
                if s.hung.is_none() && status.code() == Some(i32::from(EXIT_BAD_INPUT)) {
                    failure = Some(format!(
                        "{} refused its input ({why}): not restarted, it would read the same again",
                        s.process.name
                    ));
                    return Ok(Flow::Stop);
                }
                match policy.on_crash(&mut s.history, s.process.started.elapsed(), run_started.elapsed()) {
                    CrashVerdict::GiveUp => {
                        failure = Some(format!(
                            "{} stopped ({}) and has used its {} restarts within {} s",
                            s.process.name,
                            why,
                            policy.max_restarts,
                            policy.window.as_secs()
                        ));
                        return Ok(Flow::Stop);
                    }
                    CrashVerdict::RestartAfter(backoff) => {
                        say(format_args!(
                            "{} stopped ({}); restarting in {} ms (restart {}; {} of {} within {} s)",
                            s.process.name,
                            why,
                            backoff.as_millis(),
                            s.history.restarts,
                            s.history.recent.len(),
                            policy.max_restarts,
                            policy.window.as_secs()
                        ));
                        s.restart_at = Some(now + backoff);
                    }
                }
            }
            if s.restart_at.is_some_and(|t| now >= t) {
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
                    out!("\r\x1b[2K{line}");
                    let _ = std::io::stdout().flush();
                } else {
                    outln!("{line}");
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
        outln!();
    }
    if let Some(e) = failure {
        return Err(e);
    }
    let restarts = stages
        .iter()
        .map(|s| (s.process.name.to_string(), s.history.restarts))
        .collect();
    let mut report = observer.report(
        start.elapsed().as_secs_f64(),
        restarts,
        matches!(end, LoopEnd::Signal),
    );
    report.bad_decisions_skipped = decisions.rejections().count();
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn policy(max_restarts: u32) -> RestartPolicy {
        RestartPolicy::new(&SupervisorConfig {
            restart_backoff_ms: 250,
            max_backoff_ms: 1500,
            max_restarts,
            healthy_after_ms: 10_000,
            ..Default::default()
        })
    }

    fn ms(v: u64) -> Duration {
        Duration::from_millis(v)
    }

    #[test]
    fn backoff_doubles_caps_and_resets_after_a_healthy_run() {
        let p = policy(10);
        let mut h = CrashHistory::default();
        let quick = ms(100);
        let t = ms(0);
        let backoffs: Vec<CrashVerdict> = (0..5).map(|_| p.on_crash(&mut h, quick, t)).collect();
        assert_eq!(
            backoffs,
            [250, 500, 1000, 1500, 1500].map(|v| CrashVerdict::RestartAfter(ms(v)))
        );
        assert_eq!(h.restarts, 5);
        // It ran long enough to count as healthy: the backoff starts afresh.
        assert_eq!(
            p.on_crash(&mut h, ms(10_000), t),
            CrashVerdict::RestartAfter(ms(250))
        );
        assert_eq!(p.on_crash(&mut h, quick, t), CrashVerdict::RestartAfter(ms(500)));
    }

    #[test]
    fn the_restart_budget_ends_the_run() {
        let p = policy(2);
        let mut h = CrashHistory::default();
        let restart = |h: &mut CrashHistory, at_s: u64| p.on_crash(h, ms(1), ms(at_s * 1000));
        assert!(matches!(restart(&mut h, 0), CrashVerdict::RestartAfter(_)));
        assert!(matches!(restart(&mut h, 1), CrashVerdict::RestartAfter(_)));
        assert_eq!(restart(&mut h, 2), CrashVerdict::GiveUp);
        assert_eq!(h.restarts, 2);
        // A sliding window (10 min): a crash an hour on into a long mission is restarted.
        let mut h = CrashHistory::default();
        assert!(matches!(restart(&mut h, 0), CrashVerdict::RestartAfter(_)));
        assert!(matches!(restart(&mut h, 1), CrashVerdict::RestartAfter(_)));
        assert!(matches!(restart(&mut h, 3600), CrashVerdict::RestartAfter(_)));
        assert!(matches!(restart(&mut h, 3601), CrashVerdict::RestartAfter(_)));
        assert_eq!(restart(&mut h, 3602), CrashVerdict::GiveUp);
        assert_eq!(h.restarts, 4);
        // max_restarts = 0: never restart.
        assert_eq!(
            policy(0).on_crash(&mut CrashHistory::default(), ms(1), ms(0)),
            CrashVerdict::GiveUp
        );
    }

    #[test]
    fn backoff_never_overflows() {
        let p = RestartPolicy {
            backoff: Duration::from_secs(u32::MAX as u64),
            max_backoff: Duration::from_secs(1),
            max_restarts: u32::MAX,
            window: Duration::MAX,
            healthy_after: Duration::MAX,
        };
        let mut h = CrashHistory::default();
        for _ in 0..40 {
            assert_eq!(
                p.on_crash(&mut h, ms(1), ms(0)),
                CrashVerdict::RestartAfter(Duration::from_secs(1))
            );
        }
    }
}
