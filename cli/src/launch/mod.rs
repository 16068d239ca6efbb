//! The launcher (`deckwatch run`, `deckwatch latency`): starts the stage processes, supervises
//! them, follows the decisions they produce, and stops everything cleanly on Ctrl-C/SIGTERM or
//! when the source is exhausted. By concern:
//! - [`process`]: starting, signalling and stopping a stage binary;
//! - [`supervise`]: start order, the restart rule, the main loop;
//! - [`observe`]: metrics of the decision stream, the status line, the decisions CSV;
//! - [`report`]: what a run did, printed at the end.

pub mod observe;
pub mod process;
pub mod report;
pub mod supervise;

use deckwatch_common::messages::{monotonic_ns, StageLog};
use deckwatch_runtime::bus::{quiet_logging, Bus};
use deckwatch_runtime::config::PipelineConfig;
use deckwatch_viz::RerunSink;
use process::{stage_binary, stop_all, StageProcess};
pub use report::{print_report, RunReport};
use std::path::{Path, PathBuf};
use std::time::Duration;
pub use supervise::LaunchOptions;
use supervise::{launched_stages, supervise, Supervised};

fn say(msg: impl std::fmt::Display) {
    let line = format!("deckwatch: {msg}");
    errln!("{line}");
    if let Some(tx) = LAUNCHER_LOG.get() {
        let tx = tx.lock().unwrap_or_else(|p| p.into_inner());
        let _ = tx.send(StageLog::new(
            monotonic_ns(),
            std::process::id(),
            "deckwatch",
            &line,
        ));
    }
}

/// Where the launcher's own lines go besides stderr, while a recorder runs.
static LAUNCHER_LOG: std::sync::OnceLock<std::sync::Mutex<std::sync::mpsc::Sender<StageLog>>> =
    std::sync::OnceLock::new();

/// The processes' stderr lines (and the launcher's own), published on `deckwatch/log` for the
/// recorder, from a node of their own that lives until the recorder is stopped.
pub struct LogForwarder {
    publisher: deckwatch_runtime::bus::MessagePublisher<StageLog>,
    lines: std::sync::mpsc::Receiver<StageLog>,
    /// Lines read before the recorder subscribed (it is started first, but connects only once it
    /// is up: the launcher's "started" lines went missing from a recording in CI), oldest first.
    pending: std::cell::RefCell<std::collections::VecDeque<StageLog>>,
    _bus: Bus,
}

/// Lines kept for a recorder that has not subscribed yet; beyond this the oldest go.
const MAX_PENDING_LOG_LINES: usize = 1024;

impl LogForwarder {
    fn start(config: &PipelineConfig, stages: &mut [Supervised]) -> Result<Self, String> {
        let bus = Bus::join(&config.bus.settings(1), "launcher-log").map_err(|e| e.to_string())?;
        let publisher = bus.publisher::<StageLog>().map_err(|e| e.to_string())?;
        let (tx, lines) = std::sync::mpsc::channel();
        for s in stages.iter_mut() {
            s.process.log = Some(tx.clone());
        }
        let _ = LAUNCHER_LOG.set(std::sync::Mutex::new(tx));
        Ok(Self {
            publisher,
            lines,
            pending: Default::default(),
            _bus: bus,
        })
    }

    /// Publishes the lines read so far; while nobody subscribes, keeps them for the recorder.
    pub fn forward(&self) {
        let mut pending = self.pending.borrow_mut();
        pending.extend(self.lines.try_iter());
        while let Some(line) = pending.front() {
            match self.publisher.send(line) {
                Ok(0) => break,
                // Sent, or lost: a lost line is no reason to stop the pipeline.
                _ => {
                    pending.pop_front();
                }
            }
        }
        let excess = pending.len().saturating_sub(MAX_PENDING_LOG_LINES);
        pending.drain(..excess);
    }
}

/// Runs the pipeline until the source is exhausted or a signal arrives. `file` names the
/// configuration in errors.
pub fn launch(config: &PipelineConfig, file: &str, options: &LaunchOptions) -> Result<RunReport, String> {
    config.validate(file).map_err(|e| e.to_string())?;
    if config.link.enabled {
        // The signing key, read now: a key others can read, or none, stops the start here
        // rather than the link stage at every restart.
        deckwatch_link::signing::Signing::configured(&config.link).map_err(|e| e.to_string())?;
    }
    let domain = config.bus.domain.clone();
    quiet_logging();
    Bus::cleanup_dead_nodes(&domain).map_err(|e| e.to_string())?;
    // What an earlier launcher of this domain, killed, left behind.
    for dir in stale_run_dirs(&domain) {
        if std::fs::remove_dir_all(&dir).is_ok() {
            say(format_args!(
                "removed {} (left by a killed launcher)",
                dir.display()
            ));
        }
    }
    let alive = Bus::live_nodes(&domain).map_err(|e| e.to_string())?;
    if !alive.is_empty() {
        return Err(format!(
            "domain `{domain}` is in use by running nodes ({}); stop that pipeline or choose another --domain",
            alive.join(", ")
        ));
    }
    let active = launched_stages(config, options);
    let mut stages = active
        .iter()
        .map(|s| {
            stage_binary(options.stage_dir.as_deref(), s.name)
                .map(|binary| Supervised::new(StageProcess::new(s.name, binary)))
        })
        .collect::<Result<Vec<_>, _>>()?;
    // rerun: every process logs into one recording. With `spawn` the launcher starts the viewer
    // and the stages connect to it; with `save` each process writes a part, merged at the end.
    let mut config = config.clone();
    if config.record.records_frames() {
        // The recorder is one more frame subscriber; the spare for a restarted stage stays.
        config.bus.frame_subscribers = (config.bus.frame_subscribers + 1).min(8);
    }
    let viewer = start_viewer(&mut config)?;
    let config = &config;
    // The stages read the same configuration, as the launcher resolved it.
    let run_dir = run_dir(&domain, std::process::id());
    let config_path = create_run_dir(&run_dir, &config.to_toml())?;

    let log = if config.record.enabled() {
        Some(LogForwarder::start(config, &mut stages)?)
    } else {
        None
    };
    let result = supervise(config, options, &mut stages, &config_path, log.as_ref());
    let (mut recorder, mut processes): (Vec<StageProcess>, Vec<StageProcess>) = stages
        .into_iter()
        .map(|s| s.process)
        .partition(|p| p.name == deckwatch_runtime::stages::record::NAME);
    let stop_timeout = Duration::from_millis(config.supervisor.stop_timeout_ms);
    for name in stop_all(&mut processes, stop_timeout) {
        say(format_args!("{name} did not stop in time; killed it"));
    }
    // The recorder last, once every other stage's closing line has been read from its stderr
    // and passed on (a fixed 100 ms wait lost a closing line on a loaded machine): it writes out
    // its queue and the file's summary. Killed, it leaves a file that `deckwatch recover`
    // completes.
    if let Some(l) = &log {
        for p in processes.iter_mut() {
            if !p.stderr_read(STDERR_READ_TIMEOUT) {
                say(format_args!(
                    "{}'s last stderr lines were not read in time",
                    p.name
                ));
            }
        }
        l.forward();
    }
    if !stop_all(&mut recorder, RECORDER_STOP_TIMEOUT).is_empty() {
        say(format_args!(
            "the recorder did not finish in {} s; killed it (`deckwatch recover` completes its file)",
            RECORDER_STOP_TIMEOUT.as_secs()
        ));
    }
    // Its node goes before the domain is cleaned up (a live node keeps the domain).
    drop(log);
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
    if config.rerun.sink == RerunSink::Save {
        if let Some(path) = &config.rerun.path {
            let mut parts = vec![LAUNCHER];
            parts.extend(active.iter().rev().map(|s| s.name));
            match deckwatch_viz::merge_parts(path, &parts) {
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

/// How long the recorder may take to write out its queue and finish its file.
const RECORDER_STOP_TIMEOUT: Duration = Duration::from_secs(30);

/// How long the launcher waits, after the stages stopped, for their last stderr lines.
const STDERR_READ_TIMEOUT: Duration = Duration::from_secs(2);

/// The launcher's name as a rerun part and iceoryx2 node.
const LAUNCHER: &str = "launcher";

/// The launcher's folder of a run (the configuration it hands the stages).
fn run_dir(domain: &str, pid: u32) -> PathBuf {
    deckwatch_runtime::bus::runtime_base().join(format!("deckwatch-{domain}-{pid}"))
}

/// True when `path` is a folder (not a link to one) owned by this user.
fn is_ours(path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid has no preconditions and cannot fail.
    let us = unsafe { libc::geteuid() };
    std::fs::symlink_metadata(path).is_ok_and(|m| m.is_dir() && m.uid() == us)
}

/// Creates the run folder fresh, readable by this user alone (0700), with the configuration in
/// it (0600). A folder of that name that is not ours (another user made it first, or a link)
/// is refused: the stages read their configuration from it, at every restart.
fn create_run_dir(dir: &Path, config_toml: &str) -> Result<PathBuf, String> {
    use std::io::Write;
    use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
    let create = || std::fs::DirBuilder::new().mode(0o700).create(dir);
    match create() {
        Ok(()) => {}
        // Ours, left by an earlier launcher with this pid: remove and make it again.
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && is_ours(dir) => {
            std::fs::remove_dir_all(dir)
                .and_then(|_| create())
                .map_err(|e| format!("run folder {}: {e}", dir.display()))?;
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            return Err(format!(
                "run folder {} exists and is not this user's folder: refusing to read the stages' configuration from it (remove it, or set XDG_RUNTIME_DIR)",
                dir.display()
            ))
        }
        Err(e) => return Err(format!("run folder {}: {e}", dir.display())),
    }
    let path = dir.join("pipeline.toml");
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&path)
        .and_then(|mut f| f.write_all(config_toml.as_bytes()))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}

/// Run folders of `domain` whose launcher is gone (a SIGKILL leaves them); only this user's.
fn stale_run_dirs(domain: &str) -> Vec<PathBuf> {
    let prefix = format!("deckwatch-{domain}-");
    let Ok(entries) = std::fs::read_dir(deckwatch_runtime::bus::runtime_base()) else {
        return Vec::new();
    };
    entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().to_string();
            let pid: i32 = name.strip_prefix(&prefix)?.parse().ok()?;
            // SAFETY: kill with signal 0 only checks that the process exists.
            let alive = pid > 0 && unsafe { libc::kill(pid, 0) } == 0;
            (!alive && is_ours(&e.path())).then(|| e.path())
        })
        .collect()
}

/// What `deckwatch clean` removed.
#[derive(Debug, Default)]
pub struct Cleaned {
    pub dead_nodes: u64,
    pub domain_removed: bool,
    pub paths: Vec<PathBuf>,
}

/// `deckwatch clean`: everything a killed launcher of `domain` left behind: the shared memory of
/// its dead processes and the domain itself, its run folders, and with `rrd` the rerun part
/// files (and an unfinished merge) of that recording. Refuses while the domain is in use.
pub fn clean(domain: &str, rrd: Option<&Path>) -> Result<Cleaned, String> {
    quiet_logging();
    let alive = Bus::live_nodes(domain).map_err(|e| e.to_string())?;
    if !alive.is_empty() {
        return Err(format!(
            "domain `{domain}` is in use by running nodes ({}): stop that pipeline first",
            alive.join(", ")
        ));
    }
    let mut out = Cleaned {
        dead_nodes: Bus::cleanup_dead_nodes(domain)
            .map_err(|e| e.to_string())?
            .removed,
        ..Cleaned::default()
    };
    out.domain_removed = Bus::remove_idle_domain(domain).map_err(|e| e.to_string())?;
    for dir in stale_run_dirs(domain) {
        if std::fs::remove_dir_all(&dir).is_ok() {
            out.paths.push(dir);
        }
    }
    if let Some(rrd) = rrd {
        let mut merging = rrd.as_os_str().to_owned();
        merging.push(".merging");
        let parts = std::iter::once(LAUNCHER)
            .chain(deckwatch_runtime::stages::PROCESSES.iter().map(|p| p.name))
            .flat_map(|stage| deckwatch_viz::RerunConfig::parts_of(rrd, stage))
            .chain(std::iter::once(PathBuf::from(merging)));
        for p in parts {
            if std::fs::remove_file(&p).is_ok() {
                out.paths.push(p);
            }
        }
    }
    Ok(out)
}

/// The recording's name in the viewer: what ran (the viewer shows when, from the recording's
/// start time).
fn run_name(config: &PipelineConfig) -> String {
    use deckwatch_common::messages::FrameSource;
    let what = match config.source.kind {
        FrameSource::Simulator => format!("simulator, {}", config.sim.scenario.name()),
        FrameSource::Replay => match &config.replay.recording {
            Some(p) => format!("replay of {}", p.display()),
            None => "replay".to_string(),
        },
        other => other.name().to_string(),
    };
    format!("deckwatch run: {what}")
}

/// Opens the launcher's own rerun stream (which carries the blueprint) and points the stages at
/// the same recording.
fn start_viewer(config: &mut PipelineConfig) -> Result<Option<deckwatch_viz::Viewer>, String> {
    let r = &mut config.rerun;
    if r.sink == RerunSink::Off {
        return Ok(None);
    }
    if r.recording_id.is_none() {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        r.recording_id = Some(format!("deckwatch-{}-{}", now.as_secs(), std::process::id()));
    }
    let about = deckwatch_viz::RunDescription {
        name: run_name(config),
        properties: config.run_properties(),
        configuration_toml: config.to_toml(),
    };
    let r = &mut config.rerun;
    let viewer = deckwatch_viz::open_viewer(r, LAUNCHER, &about).map_err(|e| e.to_string())?;
    if r.sink == RerunSink::Spawn {
        // The viewer is up: the stages connect to it rather than spawning their own.
        r.sink = RerunSink::Connect;
        r.address = Some(deckwatch_viz::DEFAULT_ADDRESS.into());
    }
    Ok(viewer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn the_run_folder_is_private_and_made_fresh() {
        let base = tempfile::tempdir().unwrap();
        let dir = base.path().join("deckwatch-x-1");
        let config = create_run_dir(&dir, "a = 1\n").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&dir), 0o700);
        assert_eq!(mode(&config), 0o600);
        // Left by an earlier launcher of ours (a different configuration): made again.
        std::fs::write(dir.join("left"), "x").unwrap();
        create_run_dir(&dir, "a = 2\n").unwrap();
        assert!(!dir.join("left").exists());
        assert_eq!(std::fs::read_to_string(&config).unwrap(), "a = 2\n");
        // A link planted under the name (to a folder someone else controls): refused.
        let elsewhere = base.path().join("elsewhere");
        std::fs::create_dir(&elsewhere).unwrap();
        let planted = base.path().join("deckwatch-x-2");
        std::os::unix::fs::symlink(&elsewhere, &planted).unwrap();
        let e = create_run_dir(&planted, "a = 3\n").unwrap_err();
        assert!(e.contains("not this user's folder"), "{e}");
        assert!(!elsewhere.join("pipeline.toml").exists());
    }
}
