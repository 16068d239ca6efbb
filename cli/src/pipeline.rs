//! `deckwatch run` and `deckwatch latency`: the command lines of the launcher, and how their
//! options override the configuration file.

use crate::launch::{launch, print_report, LaunchOptions, RunReport};
use deckwatch_common::messages::FrameSource;
use deckwatch_runtime::config::{PipelineConfig, DEFAULTS};
use deckwatch_viz::RerunSink;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct RunArgs {
    /// Pipeline configuration (TOML; see README). Command-line options override it.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Frame source: `sim` (default), `replay DIR` (a recording folder or a flight recording,
    /// FILE.mcap), or `libcamera`.
    #[arg(long, num_args = 1..=2, value_names = ["KIND", "DIR"])]
    pub source: Vec<String>,
    /// Frames to capture (sim: the run's length; replay, libcamera: stop after this many).
    #[arg(long)]
    frames: Option<u64>,
    /// Frame rate in Hz (replay: 0 = as fast as possible, default the recorded rate;
    /// libcamera: asked of the camera, 0 = its default).
    #[arg(long)]
    rate: Option<f64>,
    /// The simulated scenario: `lulls` (default: a moderate sea with calm spells, the
    /// decision's whole cycle in 60 s), `ship` (sea state 6), `case1`, `offset` or `nodeck`;
    /// sets `[sim] scenario`.
    #[arg(long, value_enum)]
    scenario: Option<deckwatch_sim::Scenario>,
    /// iceoryx2 domain (isolates concurrent pipelines).
    #[arg(long)]
    domain: Option<String>,
    /// Write every landing decision (with its stage timestamps) as a CSV row to this file.
    #[arg(long)]
    decisions: Option<PathBuf>,
    /// No live status line.
    #[arg(long)]
    quiet: bool,
    /// Folder of the stage binaries (default: beside this executable).
    #[arg(long)]
    stage_dir: Option<PathBuf>,
    /// Print the resolved configuration (TOML) and exit.
    #[arg(long)]
    print_config: bool,
    /// Print the final report as JSON.
    #[arg(long)]
    json: bool,
    /// rerun logging: `off`, `spawn` (start a viewer), `connect [ADDR]`, `save FILE.rrd`.
    #[arg(long, num_args = 1..=2, value_names = ["MODE", "ARG"])]
    rerun: Vec<String>,
    /// Start the MAVLink link to the autopilot at this address (`udpin:127.0.0.1:14540`,
    /// `udpout:HOST:PORT`, `serial:/dev/ttyAMA0:921600`); sets `[link]`.
    #[arg(long, value_name = "ADDRESS")]
    link: Option<String>,
    /// Where the vehicle's attitude comes from: `frames`, `autopilot` (the link) or `level`.
    #[arg(long, value_name = "SOURCE")]
    vehicle_attitude: Option<String>,
    /// Whether the deck's heave is part of the landing capacity: `required` (default) or
    /// `off` (roll and pitch alone: no vehicle height, or the paper's method alone); sets
    /// `[decide] heave`.
    #[arg(long, value_name = "USE")]
    heave: Option<String>,
    /// Record the flight: every message (and frame, as `[record]` says) into this MCAP file by
    /// a recorder process; sets `[record] path`.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
}

/// Applies `--heave required|off`.
pub fn apply_heave(c: &mut PipelineConfig, heave: Option<&str>) -> Result<(), String> {
    use deckwatch_decide::HeaveUse;
    if let Some(h) = heave {
        c.decide.heave = HeaveUse::parse(h).map_err(|e| format!("--heave: {e}"))?;
    }
    Ok(())
}

/// Applies `--link ADDRESS` and `--vehicle-attitude SOURCE`.
pub fn apply_link(
    c: &mut PipelineConfig,
    link: Option<String>,
    vehicle_attitude: Option<&str>,
) -> Result<(), String> {
    use deckwatch_common::vehicle::VehicleAttitudeSource;
    if let Some(address) = link {
        c.link.enabled = true;
        c.link.address = address;
    }
    if let Some(v) = vehicle_attitude {
        c.vehicle.attitude =
            VehicleAttitudeSource::parse(v).map_err(|e| format!("--vehicle-attitude: {e}"))?;
    }
    Ok(())
}

/// Applies `--rerun MODE [ARG]`.
pub fn apply_rerun(c: &mut PipelineConfig, args: &[String]) -> Result<(), String> {
    let r = &mut c.rerun;
    let words: Vec<&str> = args.iter().map(String::as_str).collect();
    match words.as_slice() {
        [] => {}
        ["off"] => r.sink = RerunSink::Off,
        ["spawn"] => r.sink = RerunSink::Spawn,
        ["connect"] => r.sink = RerunSink::Connect,
        ["connect", addr] => {
            r.sink = RerunSink::Connect;
            r.address = Some(addr.to_string());
        }
        ["save", path] => {
            r.sink = RerunSink::Save;
            r.path = Some(PathBuf::from(path));
        }
        other => {
            return Err(format!(
                "--rerun: expected `off`, `spawn`, `connect [ADDR]` or `save FILE.rrd`, got `{}`",
                other.join(" ")
            ))
        }
    }
    Ok(())
}

/// Applies `--source KIND [DIR]`.
pub fn apply_source(c: &mut PipelineConfig, args: &[String]) -> Result<(), String> {
    let words: Vec<&str> = args.iter().map(String::as_str).collect();
    match words.as_slice() {
        [] => {}
        ["sim"] => c.source.kind = FrameSource::Simulator,
        ["libcamera"] => c.source.kind = FrameSource::Libcamera,
        ["replay", dir] => {
            c.source.kind = FrameSource::Replay;
            c.replay.recording = Some(PathBuf::from(dir));
        }
        ["replay"] if c.replay.recording.is_some() => c.source.kind = FrameSource::Replay,
        other => {
            return Err(format!(
                "--source: expected `sim`, `replay DIR` or `libcamera`, got `{}`",
                other.join(" ")
            ))
        }
    }
    Ok(())
}

/// Applies `--frames` and `--rate` to the configured source.
pub fn apply_frames_and_rate(c: &mut PipelineConfig, frames: Option<u64>, rate: Option<f64>) {
    if let Some(n) = frames {
        match c.source.kind {
            FrameSource::Replay => c.replay.frames = n,
            FrameSource::Libcamera => c.libcamera.frames = n,
            FrameSource::Simulator => c.sim.frames = n as usize,
        }
    }
    if let Some(hz) = rate {
        match c.source.kind {
            FrameSource::Replay => c.replay.rate_hz = Some(hz),
            FrameSource::Libcamera => c.libcamera.frame_rate = hz,
            FrameSource::Simulator => c.sim.rate = hz,
        }
    }
}

/// The configuration file (or the defaults) and its name for messages.
pub fn load(config: Option<&Path>) -> Result<(PipelineConfig, String), String> {
    let name = config.map_or(DEFAULTS.to_string(), |p| p.display().to_string());
    let c = PipelineConfig::load_or_default(config).map_err(|e| e.to_string())?;
    Ok((c, name))
}

/// Prints the report; a decisions CSV that could not be written to the end fails the command
/// (after the report), so no script takes the incomplete file for the whole run.
fn finish(report: RunReport, json: bool, csv: Option<&Path>) -> Result<(), String> {
    if json {
        outln!(
            "{}",
            serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?
        );
    } else {
        print_report(&report);
    }
    match (&report.decisions_csv_error, csv) {
        (Some(e), Some(path)) => Err(format!("the decisions CSV {} is {e}", path.display())),
        (Some(e), None) => Err(format!("the decisions CSV is {e}")),
        _ => Ok(()),
    }
}

pub fn run(a: RunArgs) -> Result<(), String> {
    let (mut c, file) = load(a.config.as_deref())?;
    apply_source(&mut c, &a.source)?;
    apply_frames_and_rate(&mut c, a.frames, a.rate);
    if let Some(scenario) = a.scenario {
        c.sim.scenario = scenario;
    }
    if let Some(d) = a.domain {
        c.bus.domain = d;
    }
    apply_rerun(&mut c, &a.rerun)?;
    apply_link(&mut c, a.link, a.vehicle_attitude.as_deref())?;
    apply_heave(&mut c, a.heave.as_deref())?;
    if let Some(p) = a.record {
        c.record.path = Some(p);
    }
    if a.print_config {
        c.validate(&file).map_err(|e| e.to_string())?;
        out!("{}", c.to_toml());
        return Ok(());
    }
    let options = LaunchOptions {
        status: !a.quiet,
        decisions_csv: a.decisions,
        stage_dir: a.stage_dir,
        ..Default::default()
    };
    finish(
        launch(&c, &file, &options)?,
        a.json,
        options.decisions_csv.as_deref(),
    )
}

#[derive(clap::Args)]
pub struct LatencyArgs {
    /// The recording to replay (a folder, or a flight recording FILE.mcap).
    recording: PathBuf,
    /// Replay rate in Hz (default: the recorded rate; 0: as fast as possible).
    #[arg(long)]
    rate: Option<f64>,
    /// Frames to replay, looping the recording as needed (default: the recording once).
    #[arg(long)]
    frames: Option<u64>,
    /// Pipeline configuration for the other sections (estimator, decision, bus).
    #[arg(long)]
    config: Option<PathBuf>,
    /// iceoryx2 domain.
    #[arg(long, default_value = "latency")]
    domain: String,
    /// Decode each frame when it is due instead of before the run.
    #[arg(long)]
    no_preload: bool,
    /// Write every decision as CSV to this file.
    #[arg(long)]
    decisions: Option<PathBuf>,
    /// Folder of the stage binaries (default: beside this executable).
    #[arg(long)]
    stage_dir: Option<PathBuf>,
    /// Machine-readable output.
    #[arg(long)]
    json: bool,
    /// rerun logging (default off): `spawn`, `connect [ADDR]`, `save FILE.rrd`.
    #[arg(long, num_args = 1..=2, value_names = ["MODE", "ARG"])]
    rerun: Vec<String>,
    /// Record the run into this MCAP file (`[record]` of the configuration says how).
    #[arg(long, value_name = "FILE.mcap")]
    record: Option<PathBuf>,
}

pub fn latency(a: LatencyArgs) -> Result<(), String> {
    let (mut c, file) = load(a.config.as_deref())?;
    c.source.kind = FrameSource::Replay;
    c.replay.recording = Some(a.recording);
    c.replay.rate_hz = a.rate;
    c.replay.preload = !a.no_preload;
    if let Some(n) = a.frames {
        c.replay.loops = 0;
        c.replay.frames = n;
    }
    c.bus.domain = a.domain;
    apply_rerun(&mut c, &a.rerun)?;
    if let Some(p) = a.record {
        c.record.path = Some(p);
    }
    let options = LaunchOptions {
        status: false,
        decisions_csv: a.decisions,
        stage_dir: a.stage_dir,
        ..Default::default()
    };
    finish(
        launch(&c, &file, &options)?,
        a.json,
        options.decisions_csv.as_deref(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn command_line_overrides_the_file() {
        let file = "[source]\nkind = \"replay\"\n[replay]\nrecording = \"from-file\"\nrate_hz = 5.0\n\
                    [sim]\nframes = 7\n[rerun]\nsink = \"save\"\npath = \"a.rrd\"\n";
        let mut c = PipelineConfig::from_toml("f.toml", file).unwrap();
        // `--source replay` alone keeps the file's recording; --frames/--rate go to the replay.
        apply_source(&mut c, &words("replay")).unwrap();
        apply_frames_and_rate(&mut c, Some(40), Some(0.0));
        assert_eq!(c.replay.recording.as_deref(), Some(Path::new("from-file")));
        assert_eq!((c.replay.frames, c.replay.rate_hz), (40, Some(0.0)));
        assert_eq!(c.sim.frames, 7, "the simulator's section is left alone");
        // Switching to the simulator: the same options now set its frames and rate.
        apply_source(&mut c, &words("sim")).unwrap();
        apply_frames_and_rate(&mut c, Some(12), Some(30.0));
        assert_eq!(
            (c.source.kind, c.sim.frames, c.sim.rate),
            (FrameSource::Simulator, 12, 30.0)
        );
        apply_source(&mut c, &words("replay other")).unwrap();
        assert_eq!(c.replay.recording.as_deref(), Some(Path::new("other")));
        apply_rerun(&mut c, &words("connect rerun+http://h:1/proxy")).unwrap();
        assert_eq!(c.rerun.sink, RerunSink::Connect);
        assert_eq!(c.rerun.address.as_deref(), Some("rerun+http://h:1/proxy"));
        apply_rerun(&mut c, &[]).unwrap();
        assert_eq!(
            c.rerun.sink,
            RerunSink::Connect,
            "no option: the file's value stays"
        );
        c.validate("f.toml").unwrap_err(); // the recordings do not exist
    }

    #[test]
    fn bad_options_are_named() {
        let mut c = PipelineConfig::default();
        assert!(apply_source(&mut c, &words("usb"))
            .unwrap_err()
            .contains("--source"));
        // `--source replay` needs a recording from the file or the command line.
        assert!(apply_source(&mut c, &words("replay")).is_err());
        assert!(apply_rerun(&mut c, &words("save"))
            .unwrap_err()
            .contains("--rerun"));
        assert!(apply_rerun(&mut c, &words("print x")).is_err());
        let e = load(Some(Path::new("/nonexistent.toml"))).unwrap_err();
        assert!(e.contains("/nonexistent.toml"), "{e}");
    }
}
