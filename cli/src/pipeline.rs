//! `deckwatch run` and `deckwatch latency`: the command lines of the launcher.

use crate::launch::{launch, print_report, LaunchOptions, PipelineConfig};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct RunArgs {
    /// Pipeline configuration (TOML; see README). Command-line options override it.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Frame source: `sim` (default), `replay DIR`, or `libcamera`.
    #[arg(long, num_args = 1..=2, value_names = ["KIND", "DIR"])]
    source: Vec<String>,
    /// Frames to capture (sim: the run's length; replay, libcamera: stop after this many).
    #[arg(long)]
    frames: Option<u64>,
    /// Frame rate in Hz (replay: 0 = as fast as possible, default the recorded rate;
    /// libcamera: asked of the camera, 0 = its default).
    #[arg(long)]
    rate: Option<f64>,
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
}

/// Applies `--rerun MODE [ARG]`.
fn apply_rerun(c: &mut PipelineConfig, args: &[String]) -> Result<(), String> {
    let r = &mut c.rerun;
    match args {
        [] => {}
        [m] if m == "off" || m == "spawn" || m == "connect" => r.sink = m.clone(),
        [m, addr] if m == "connect" => {
            r.sink = m.clone();
            r.address = Some(addr.clone());
        }
        [m, path] if m == "save" => {
            r.sink = m.clone();
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

fn load(config: &Option<PathBuf>) -> Result<PipelineConfig, String> {
    match config {
        Some(p) => PipelineConfig::load(p),
        None => Ok(PipelineConfig::default()),
    }
}

fn finish(report: crate::launch::RunReport, json: bool) -> Result<(), String> {
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?
        );
    } else {
        print_report(&report);
    }
    Ok(())
}

pub fn run(a: RunArgs) -> Result<(), String> {
    let mut c = load(&a.config)?;
    match a.source.as_slice() {
        [] => {}
        [k] if k == "sim" || k == "libcamera" => c.source.kind = k.clone(),
        [k, dir] if k == "replay" => {
            c.source.kind = k.clone();
            c.replay.recording = Some(PathBuf::from(dir));
        }
        [k] if k == "replay" && c.replay.recording.is_some() => c.source.kind = k.clone(),
        other => {
            return Err(format!(
                "--source: expected `sim`, `replay DIR` or `libcamera`, got `{}`",
                other.join(" ")
            ))
        }
    }
    if let Some(n) = a.frames {
        match c.source.kind.as_str() {
            "replay" => c.replay.frames = n,
            "libcamera" => c.libcamera.frames = n,
            _ => c.sim.frames = n as usize,
        }
    }
    if let Some(hz) = a.rate {
        match c.source.kind.as_str() {
            "replay" => c.replay.rate_hz = Some(hz),
            "libcamera" => c.libcamera.frame_rate = hz,
            _ => c.sim.rate = hz,
        }
    }
    if let Some(d) = a.domain {
        c.bus.domain = d;
    }
    apply_rerun(&mut c, &a.rerun)?;
    if a.print_config {
        c.validate()?;
        print!("{}", toml::to_string(&c).map_err(|e| e.to_string())?);
        return Ok(());
    }
    let options = LaunchOptions {
        status: !a.quiet,
        decisions_csv: a.decisions,
        stage_dir: a.stage_dir,
    };
    finish(launch(&c, &options)?, a.json)
}

#[derive(clap::Args)]
pub struct LatencyArgs {
    /// The recording to replay.
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
}

pub fn latency(a: LatencyArgs) -> Result<(), String> {
    let mut c = load(&a.config)?;
    c.source.kind = "replay".into();
    c.replay.recording = Some(a.recording);
    c.replay.rate_hz = a.rate;
    c.replay.preload = !a.no_preload;
    if let Some(n) = a.frames {
        c.replay.loops = 0;
        c.replay.frames = n;
    }
    c.bus.domain = a.domain;
    apply_rerun(&mut c, &a.rerun)?;
    let options = LaunchOptions {
        status: false,
        decisions_csv: a.decisions,
        stage_dir: a.stage_dir,
    };
    finish(launch(&c, &options)?, a.json)
}
