//! `deckwatch-capture`: the capture stage. For now it simulates at the level of points: it writes
//! the marker table (exact marker pixels with ground truth, optionally noisy) for a scenario to
//! stdout or a file, e.g. `deckwatch-capture --scenario ship | deckwatch-estimate`.

use clap::Parser;
use deckwatch_capture::motion::sample_series;
use deckwatch_capture::{MarkerSimulator, Scenario};
use deckwatch_common::marker_table::MarkerTableWriter;
use deckwatch_common::{CameraModel, DeckLayout};
use std::io::Write;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    version,
    about = "Simulated marker pixels of the paper's scene, as a marker table (CSV)"
)]
struct Args {
    /// Scenario: case1, ship or offset.
    #[arg(long, default_value = "ship")]
    scenario: String,
    /// Number of frames.
    #[arg(long, default_value_t = 600)]
    frames: usize,
    /// Frame rate (Hz).
    #[arg(long, default_value_t = 10.0)]
    rate: f64,
    /// Camera preset (paper, rpi-v2); default: the scenario's.
    #[arg(long)]
    camera: Option<String>,
    /// Seed of the sea's phases and of the pixel noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Gaussian pixel noise (standard deviation per axis, pixels).
    #[arg(long, default_value_t = 0.0)]
    noise_px: f64,
    /// Output file (default: stdout).
    #[arg(long)]
    out: Option<std::path::PathBuf>,
}

fn run(a: Args) -> Result<(), String> {
    let scenario = Scenario::from_name(&a.scenario)
        .ok_or_else(|| format!("--scenario: unknown `{}` (case1, ship, offset)", a.scenario))?;
    let cam_name = a.camera.as_deref().unwrap_or(scenario.default_camera());
    let camera = CameraModel::preset(cam_name)
        .ok_or_else(|| format!("--camera: unknown `{cam_name}` (paper, rpi-v2)"))?;
    if !(a.rate.is_finite() && a.rate > 0.0) {
        return Err(format!("--rate: must be a positive number of Hz, got {}", a.rate));
    }
    if !(a.noise_px.is_finite() && a.noise_px >= 0.0) {
        return Err(format!("--noise-px: must be >= 0, got {}", a.noise_px));
    }
    let deck = DeckLayout::paper();
    let out: Box<dyn Write> = match &a.out {
        Some(p) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| format!("{}: cannot create: {e}", p.display()))?,
        )),
        None => Box::new(std::io::BufWriter::new(std::io::stdout().lock())),
    };
    let io = |e: std::io::Error| format!("cannot write the marker table: {e}");
    let mut table = MarkerTableWriter::new(out, deck.marker_count()).map_err(io)?;
    let mut sim = MarkerSimulator::new(camera, deck, a.noise_px, a.seed);
    let profile = scenario.profile(a.seed);
    for (k, s) in sample_series(profile.as_ref(), a.rate, a.frames)
        .iter()
        .enumerate()
    {
        table.write(&sim.row(k as u64, s)).map_err(io)?;
    }
    table.flush().map_err(io)
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("deckwatch-capture: {e}");
            ExitCode::FAILURE
        }
    }
}
