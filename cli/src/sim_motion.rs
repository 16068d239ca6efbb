//! `deckwatch sim motion`: one of the ship-motion models (`sim::ship`) written as a motion file,
//! the `--motion-csv` format of `decide-eval`, `predict-eval` and `trials`.

use deckwatch_sim::motion_file::{write_motion_csv, MotionRow};
use deckwatch_sim::ship::{
    motion_rows, HullRaoMotion, HullRaoParams, SeaSpec, ShipMotionModel, ShipSea, ShortCrestedMotion,
    ShortCrestedParams, MAX_DURATION_S, MOTION_FILE_RATES_HZ,
};

#[derive(clap::Args)]
pub struct MotionArgs {
    /// The model: `spectrum` (today's long-crested JONSWAP sea), `nonlinear-roll` (its waves,
    /// pitch and heave; roll from a nonlinear equation of motion), `short-crested`
    /// (directionally spread waves, the ship under way on a wandering course, the pad aft),
    /// `hull-rao` (the spectrum sea's waves through a frigate's response table computed by
    /// Capytaine, under way); docs/ship-motion.md.
    #[arg(long, value_parser = ShipMotionModel::parse)]
    model: ShipMotionModel,
    /// Sea state (3-6: its significant wave height and peak period).
    #[arg(long, default_value_t = 6)]
    sea_state: u32,
    /// The waves' mean direction off the bow (deg; 0 head seas, 90 beam seas, 180 following).
    #[arg(long, default_value_t = 60.0, allow_negative_numbers = true)]
    heading_deg: f64,
    /// Seed of the waves (and of the course's wander).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Length of the motion (minutes; at most 360).
    #[arg(long, default_value_t = 30.0)]
    minutes: f64,
    /// Samples per second (10-1000 Hz).
    #[arg(long, default_value_t = 10.0)]
    rate_hz: f64,
    /// With `short-crested` and `hull-rao`: the ship's speed (kn; default 10).
    #[arg(long)]
    speed_kn: Option<f64>,
    /// With `short-crested`: the cos-2s spreading's s (default 10, a wind sea; 25 and 75 are
    /// swells, narrower).
    #[arg(long)]
    spreading_s: Option<f64>,
    /// The motion file to write (CSV: time_s,roll_deg,pitch_deg,heave_m,yaw_deg).
    #[arg(long)]
    out: std::path::PathBuf,
}

pub fn run(a: MotionArgs) -> Result<(), String> {
    let max_minutes = MAX_DURATION_S / 60.0;
    if !(a.minutes > 0.0 && a.minutes <= max_minutes) {
        return Err(format!("--minutes: within (0, {max_minutes}], got {}", a.minutes));
    }
    let (lowest_hz, highest_hz) = MOTION_FILE_RATES_HZ;
    if !(a.rate_hz >= lowest_hz && a.rate_hz <= highest_hz) {
        return Err(format!(
            "--rate-hz: within {lowest_hz}-{highest_hz} Hz (a motion file holds 10 Hz or more), got {}",
            a.rate_hz
        ));
    }
    let spec = SeaSpec {
        sea_state: a.sea_state,
        heading_deg: a.heading_deg,
        seed: a.seed,
        duration_s: a.minutes * 60.0,
    };
    let sea = match (a.model, a.speed_kn, a.spreading_s) {
        (ShipMotionModel::ShortCrested, speed_kn, spreading_s) => {
            let defaults = ShortCrestedParams::FRIGATE;
            let params = ShortCrestedParams {
                speed_kn: speed_kn.unwrap_or(defaults.speed_kn),
                spreading_s: spreading_s.unwrap_or(defaults.spreading_s),
                ..defaults
            };
            ShortCrestedMotion::new(&spec, &params).map(ShipSea::ShortCrested)
        }
        (ShipMotionModel::HullRao, Some(speed_kn), None) => {
            let params = HullRaoParams {
                speed_kn,
                ..HullRaoParams::FRIGATE
            };
            HullRaoMotion::new(&spec, &params).map(ShipSea::HullRao)
        }
        (model, None, None) => model.build(&spec),
        (model, _, _) => {
            return Err(format!(
                "--speed-kn is the short-crested sea's and the hull's, --spreading-s the short-crested sea's; `{}` has its own",
                model.name()
            ))
        }
    }
    .map_err(|e| format!("--model {}: {e}", a.model.name()))?;
    let rows = motion_rows(&sea, a.rate_hz, spec.duration_s).map_err(|e| e.to_string())?;
    let comments = vec![
        format!(
            "deckwatch sim motion --model {} --sea-state {} --heading-deg {} --seed {} --minutes {} --rate-hz {}{}{}",
            a.model.name(),
            a.sea_state,
            a.heading_deg,
            a.seed,
            a.minutes,
            a.rate_hz,
            a.speed_kn.map_or(String::new(), |v| format!(" --speed-kn {v}")),
            a.spreading_s.map_or(String::new(), |v| format!(" --spreading-s {v}")),
        ),
        format!("{}: {}", a.model.name(), a.model.description()),
        format!("deckwatch {}", env!("CARGO_PKG_VERSION")),
    ];
    write_motion_csv(&a.out, &comments, &rows).map_err(|e| e.to_string())?;
    let summary = Summary::of(&rows);
    errln!(
        "wrote {} samples ({} min at {} Hz) of `{}`, sea state {}, waves from {} deg off the bow, seed {}, to {}",
        rows.len(),
        a.minutes,
        a.rate_hz,
        a.model.name(),
        a.sea_state,
        a.heading_deg,
        a.seed,
        a.out.display()
    );
    for (name, unit, [sd, max]) in [
        ("roll", "deg", summary.roll),
        ("pitch", "deg", summary.pitch),
        ("yaw", "deg", summary.yaw),
        ("heave", "m", summary.heave),
    ] {
        errln!("  {name:<5} sd {sd:6.2} {unit}, largest {max:6.2} {unit}");
    }
    Ok(())
}

/// Each channel's standard deviation and largest magnitude.
struct Summary {
    roll: [f64; 2],
    pitch: [f64; 2],
    yaw: [f64; 2],
    heave: [f64; 2],
}

impl Summary {
    fn of(rows: &[MotionRow]) -> Self {
        let channel = |f: fn(&MotionRow) -> f64| {
            let n = rows.len().max(1) as f64;
            let mean = rows.iter().map(f).sum::<f64>() / n;
            let var = rows.iter().map(|r| (f(r) - mean).powi(2)).sum::<f64>() / n;
            let max = rows.iter().map(|r| f(r).abs()).fold(0.0, f64::max);
            [var.sqrt(), max]
        };
        Self {
            roll: channel(|r| r.roll_deg),
            pitch: channel(|r| r.pitch_deg),
            yaw: channel(|r| r.yaw_deg),
            heave: channel(|r| r.heave_m),
        }
    }
}
