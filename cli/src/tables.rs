//! The offline marker-table tools: `deckwatch sim markers` writes simulated marker pixels with
//! ground truth (a marker table, `deckwatch_formats::marker_table`), and `deckwatch
//! estimate-table` runs the paper's estimator on such a table, one attitude row per frame. A bad
//! row is reported (file, line, column), counted and skipped; the stream goes on.

use deckwatch_common::rotation::rpy_signed_error_deg;
use deckwatch_common::stats::Percentiles;
use deckwatch_common::{CameraModel, DeckLayout};
use deckwatch_estimate::{PaperEstimator, PaperVariant};
use deckwatch_formats::marker_table::{open_marker_table, MarkerTableReader, MarkerTableWriter};
use deckwatch_formats::recording::read_camera_json;
use deckwatch_sim::scenario::SimulationArgs;
use std::collections::BTreeMap;
use std::io::{BufRead, Write};
use std::time::Instant;

#[derive(clap::Args)]
pub struct MarkersArgs {
    #[command(flatten)]
    sim: SimulationArgs,
    /// Gaussian pixel noise on the marker centres (standard deviation per axis, pixels).
    #[arg(long, default_value_t = 0.0)]
    noise_px: f64,
    /// Output file (default: stdout).
    #[arg(long)]
    out: Option<std::path::PathBuf>,
}

pub fn markers(a: MarkersArgs) -> Result<(), String> {
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

#[derive(clap::Args)]
pub struct EstimateTableArgs {
    /// Marker table to read; `-` for stdin.
    #[arg(default_value = "-")]
    input: String,
    /// Camera preset (paper, rpi-v2, rpi-v3-wide), used when --recording is not given.
    #[arg(long, default_value = "rpi-v2")]
    camera: String,
    /// Take camera and deck from this recording's camera.json instead.
    #[arg(long)]
    recording: Option<std::path::PathBuf>,
    /// Estimator variant: printed, fitted-major-axis, atan2.
    #[arg(long, default_value = "atan2")]
    variant: String,
    /// Ignore the table's alt_m column (no altimeter).
    #[arg(long)]
    no_altimeter: bool,
}

fn fmt(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.12}")
    } else {
        "nan".into()
    }
}

pub fn estimate_table(a: EstimateTableArgs) -> Result<bool, String> {
    let variant = PaperVariant::parse(&a.variant).map_err(|e| format!("--variant: {e}"))?;
    let (camera, deck) = match &a.recording {
        Some(dir) => read_camera_json(dir).map_err(|e| e.to_string())?,
        None => (
            CameraModel::preset(&a.camera)
                .ok_or_else(|| format!("--camera: unknown `{}` (paper, rpi-v2)", a.camera))?,
            DeckLayout::paper(),
        ),
    };
    let input: Box<dyn BufRead> = if a.input == "-" {
        Box::new(std::io::stdin().lock())
    } else {
        Box::new(std::io::BufReader::new(
            open_marker_table(std::path::Path::new(&a.input)).map_err(|e| e.to_string())?,
        ))
    };
    let source = if a.input == "-" { "stdin" } else { a.input.as_str() };
    let mut table = MarkerTableReader::new(source, input, deck.marker_count()).map_err(|e| e.to_string())?;
    let est = PaperEstimator::new(camera, deck, variant);
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let io = |e: std::io::Error| format!("cannot write: {e}");
    writeln!(
        out,
        "index,timestamp_ns,status,roll_deg,pitch_deg,yaw_deg,alpha_deg,beta_deg,gamma_deg,qw,qx,qy,qz,fit_rms_m,err_roll_deg,err_pitch_deg,err_yaw_deg,reason"
    )
    .map_err(io)?;
    let (mut ok, mut bad_rows) = (0usize, 0usize);
    let mut not_estimable: BTreeMap<String, usize> = BTreeMap::new();
    let mut times_us = Vec::new();
    while let Some(row) = table.next_row() {
        let row = match row {
            Ok(r) => r,
            Err(e) => {
                errln!("deckwatch estimate-table: skipped: {e}");
                bad_rows += 1;
                continue;
            }
        };
        let alt = if a.no_altimeter { None } else { row.truth.alt_m };
        let t0 = Instant::now();
        let r = est.estimate(&row.markers, alt);
        times_us.push(t0.elapsed().as_secs_f64() * 1e6);
        match r {
            Ok(e) => {
                ok += 1;
                let att = e.attitude;
                let [r, p, y] = att.rpy.to_degrees();
                let [al, be, ga] = att.euler313.to_degrees();
                let q = att.quaternion;
                let err = row
                    .truth
                    .attitude()
                    .map(|t| rpy_signed_error_deg(&att.rpy, &t))
                    .unwrap_or([f64::NAN; 3]);
                let cols = [
                    r,
                    p,
                    y,
                    al,
                    be,
                    ga,
                    q.w,
                    q.x,
                    q.y,
                    q.z,
                    e.fit_rms_m,
                    err[0],
                    err[1],
                    err[2],
                ];
                let cols: Vec<String> = cols.iter().map(|&v| fmt(v)).collect();
                writeln!(out, "{},{},ok,{},", row.index, row.timestamp_ns, cols.join(",")).map_err(io)?;
            }
            Err(e) => {
                *not_estimable.entry(format!("{e}")).or_default() += 1;
                let nans = vec!["nan"; 14].join(",");
                writeln!(
                    out,
                    "{},{},not_estimable,{nans},\"{e}\"",
                    row.index, row.timestamp_ns
                )
                .map_err(io)?;
            }
        }
    }
    out.flush().map_err(io)?;
    let frames = ok + not_estimable.values().sum::<usize>();
    errln!(
        "deckwatch estimate-table: {frames} frames, {ok} estimated ({}), {bad_rows} bad rows skipped",
        variant.name()
    );
    for (why, n) in &not_estimable {
        errln!("  not estimable x{n}: {why}");
    }
    if let Some(p) = Percentiles::of(&mut times_us) {
        errln!(
            "  estimate time per frame (us): p50 {:.1} p90 {:.1} p99 {:.1} max {:.1}",
            p.p50,
            p.p90,
            p.p99,
            p.max
        );
    }
    Ok(bad_rows == 0)
}
