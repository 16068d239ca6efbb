//! `deckwatch-capture`: the capture stage. For now it simulates at the level of points: it writes
//! the marker table (exact marker pixels with ground truth, optionally noisy) for a scenario to
//! stdout or a file, e.g. `deckwatch-capture --scenario ship | deckwatch-estimate`.

use clap::Parser;
use deckwatch_capture::scenario::SimulationArgs;
use deckwatch_common::marker_table::MarkerTableWriter;
use std::io::Write;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    version,
    about = "Simulated marker pixels of the paper's scene, as a marker table (CSV)"
)]
struct Args {
    #[command(flatten)]
    sim: SimulationArgs,
    /// Gaussian pixel noise on the marker centres (standard deviation per axis, pixels).
    #[arg(long, default_value_t = 0.0)]
    noise_px: f64,
    /// Output file (default: stdout).
    #[arg(long)]
    out: Option<std::path::PathBuf>,
}

fn run(a: Args) -> Result<(), String> {
    let sim = a.sim.resolve()?;
    let out: Box<dyn Write> = match &a.out {
        Some(p) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| format!("{}: cannot create: {e}", p.display()))?,
        )),
        None => Box::new(std::io::BufWriter::new(std::io::stdout().lock())),
    };
    let io = |e: std::io::Error| format!("cannot write the marker table: {e}");
    let mut table = MarkerTableWriter::new(out, sim.deck.marker_count()).map_err(io)?;
    for row in a.sim.marker_rows(&sim, a.noise_px)? {
        table.write(&row).map_err(io)?;
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
