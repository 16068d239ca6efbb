//! `deckwatch decide-eval`: the landing decision against the true deck motion over long
//! simulated ship-motion series (several seeds and sea states), side by side with the naive
//! rule. Measurements are the truth plus Gaussian noise, dropped frames and outliers, as the
//! estimate stage delivers them.

use deckwatch_common::vehicle::VehicleConfig;
use deckwatch_decide::decision::DecisionConfig;
use deckwatch_decide::eval::{evaluate, ClearanceBands, RuleOutcome};
use deckwatch_decide::forecast_eval::{QUANTITIES, TAIL_Z};
use deckwatch_decide::FrameInput;
use deckwatch_runtime::config::ConfigError;
use deckwatch_sim::motion::{DeckHeave, MotionProfile, ShipMotion, SpectrumShipMotion};
use deckwatch_sim::motion_file::RecordedShipMotion;
use deckwatch_sim::scenario::VehicleMotion;
use deckwatch_trials::AttitudeStreamModel;
use std::time::Instant;

/// The ship's motion model of `--motion`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SeaModel {
    Irregular,
    Regular,
    Jonswap,
}
deckwatch_common::named_enum!(SeaModel, [Irregular => "irregular", Regular => "regular", Jonswap => "jonswap"]);

#[derive(clap::Args)]
pub struct DecideEvalArgs {
    /// Minutes of ship motion per series (default 30; with `--motion-csv`, the file's whole
    /// length).
    #[arg(long)]
    pub(crate) minutes: Option<f64>,
    /// Attitude rate (Hz).
    #[arg(long, default_value_t = 10.0)]
    pub(crate) rate: f64,
    /// Seeds (sea phases, noise).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    pub(crate) seeds: Vec<u64>,
    /// Sea states: 4 (x0.25 of the sea-state-6 amplitudes), 5 (x0.5), 6 (x1); with
    /// `--motion jonswap` 3-6 (their significant wave heights and peak periods).
    #[arg(long, value_delimiter = ',', default_value = "4,5,6")]
    pub(crate) sea_states: Vec<u32>,
    /// `irregular` (each mode spread over 8 nearby periods), `regular` (three sinusoids), or
    /// `jonswap` (a wave spectrum of 300 components through a simple ship response, with a
    /// wandering heading: not the family the predictor fits).
    #[arg(long, default_value = "irregular", value_parser = SeaModel::parse)]
    pub(crate) motion: SeaModel,
    /// With `--motion jonswap`: the waves' mean heading off the bow (deg; 0 head seas, 90 beam
    /// seas), one series per heading.
    #[arg(long, value_delimiter = ',', default_value = "60")]
    pub(crate) headings: Vec<f64>,
    /// The ship's motion from a file (CSV: `time_s,roll_deg,pitch_deg,heave_m`, optional
    /// `yaw_deg`; docs/recording.md, "Ship motion from a file") instead of a simulated sea: one series per
    /// seed (the measurement's noise and faults), `--sea-states` and `--motion` unused.
    #[arg(long)]
    pub(crate) motion_csv: Option<std::path::PathBuf>,
    /// Attitude noise (deg, standard deviation per angle).
    #[arg(long, default_value_t = 0.05)]
    pub(crate) noise_deg: f64,
    /// Share of frames without a valid attitude.
    #[arg(long, default_value_t = 0.02)]
    pub(crate) dropout: f64,
    /// Share of frames with a gross error (5-15 deg on one angle).
    #[arg(long, default_value_t = 0.002)]
    pub(crate) outliers: f64,
    /// White noise of the camera's height over the deck from the full pose (m, standard
    /// deviation). The deck's height is the vehicle's less this one; the deck heaves as the
    /// sea state's `DeckHeave`. 5 mm is about 4 times what the simulator's realistic 640x480
    /// frames give at 4.7 m (1.2 mm), a margin for optics that are not the simulator's.
    #[arg(long, default_value_t = 0.005)]
    pub(crate) heave_noise_m: f64,
    /// The autopilot's height estimate, as `trials` models it: white noise on each 100 Hz
    /// sample (m)...
    #[arg(long, default_value_t = 0.02)]
    pub(crate) vehicle_height_noise_m: f64,
    /// ... and its slow error, as the standard deviation of its rate (m/s). The height is fused
    /// with the vertical speed as `[vehicle] height_fusion_s` of `--config` says.
    #[arg(long, default_value_t = 0.0)]
    pub(crate) vehicle_height_drift_mps: f64,
    /// The heave's amplitude relative to the sea state's (a swell from ahead heaves the ship
    /// more than it rolls it).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) heave_scale: f64,
    /// Frozen input: stretches a minute during which the measurement repeats itself bit for bit
    /// (a frozen camera), each `--frozen-s` long.
    #[arg(long, default_value_t = 0.0)]
    pub(crate) frozen_per_min: f64,
    #[arg(long, default_value_t = 2.0)]
    pub(crate) frozen_s: f64,
    /// Share of frames whose roll is NaN (a broken estimate that says it is valid).
    #[arg(long, default_value_t = 0.0)]
    pub(crate) nan_share: f64,
    /// Share of frames that arrive stale (1 s after capture).
    #[arg(long, default_value_t = 0.0)]
    pub(crate) stale_share: f64,
    /// Jitter of the frames' capture stamps (ms, standard deviation).
    #[arg(long, default_value_t = 0.0)]
    pub(crate) jitter_ms: f64,
    /// Capture -> decision latency (ms).
    #[arg(long, default_value_t = 5.0)]
    pub(crate) latency_ms: f64,
    /// The camera's vehicle: `level`, or `sway` (a hovering quadrotor's sway, which the
    /// estimate stage compensates with the autopilot's attitude: its errors below land in the
    /// deck attitude).
    #[arg(long, default_value = "level", value_enum)]
    pub(crate) vehicle: VehicleMotion,
    /// Noise of the autopilot's attitude (deg, per angle).
    #[arg(long, default_value_t = 0.0)]
    pub(crate) vehicle_noise_deg: f64,
    /// Bias of the autopilot's roll and pitch (deg).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true, default_values_t = [0.0, 0.0])]
    pub(crate) vehicle_bias_deg: Vec<f64>,
    /// Timing error of the autopilot's samples against the frames (ms): with a swaying vehicle
    /// the compensation is off by the sway over this time.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub(crate) vehicle_time_error_ms: f64,
    /// Outages of the autopilot's attitude stream per minute (frames in them are not
    /// compensated).
    #[arg(long, default_value_t = 0.0)]
    pub(crate) vehicle_outages_per_min: f64,
    /// Length of each outage (s).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) vehicle_outage_s: f64,
    /// Pipeline configuration whose `[decide]` section to use (default: built-in).
    #[arg(long)]
    pub(crate) config: Option<std::path::PathBuf>,
    /// One JSON object per series instead of the table.
    #[arg(long)]
    pub(crate) json: bool,
}

fn scale_of(sea_state: u32) -> Result<f64, String> {
    match sea_state {
        4 => Ok(0.25),
        5 => Ok(0.5),
        6 => Ok(1.0),
        s => Err(format!("--sea-states: {s} is not modelled (4, 5, 6)")),
    }
}

/// The bands the clearances were made on, judged over their touchdowns: per quantity the share
/// that held the truth all through (compare `predict-eval`'s "window" column, over every
/// instant) and the share that let it beyond the tail the risk is judged in.
fn print_clearance_bands(b: &ClearanceBands) {
    let share = |n: u64, q: usize| {
        if b.judged[q] == 0 {
            "-".to_string()
        } else {
            format!("{:.1}%", 100.0 * n as f64 / b.judged[q] as f64)
        }
    };
    let cells: Vec<String> = QUANTITIES
        .iter()
        .enumerate()
        .map(|(q, name)| {
            format!(
                "{name} {} / {}",
                share(b.inside[q], q),
                share(b.beyond_tail[q], q)
            )
        })
        .collect();
    outln!(
        "{:<10} at its {} clearances, the forecast over the touchdown inside its 95 % band / beyond {:.2} stated deviations: {}",
        "",
        b.judged[0],
        TAIL_Z,
        cells.join(", ")
    );
}

fn row(rule: &str, o: &RuleOutcome) -> String {
    format!(
        "{rule:<14} {:>8} {:>8} {:>9} {:>7} {:>8} {:>6} {:>8.1}%",
        o.commits,
        o.unsafe_commits,
        o.unsafe_touchdowns,
        o.aborts,
        o.calm_windows,
        o.calm_windows_used,
        100.0 * o.availability()
    )
}

/// One simulated sea: the deck's roll, pitch (deg) and heave (m) over time.
pub(crate) struct Sea {
    motion: Box<dyn MotionProfile>,
    /// The sinusoid models have no heave of their own: the sea state's `DeckHeave`.
    heave: Option<DeckHeave>,
    heave_scale: f64,
}

impl Sea {
    /// The sea `--motion` names, at sea state `ss`, waves from `heading_deg` off the bow (the
    /// spectrum sea only), phases from `seed`.
    pub(crate) fn new(a: &DecideEvalArgs, ss: u32, seed: u64, heading_deg: f64) -> Result<Self, String> {
        if let Some(path) = &a.motion_csv {
            let motion = RecordedShipMotion::load(path).map_err(|e| format!("--motion-csv: {e}"))?;
            return Ok(Self {
                motion: Box::new(motion),
                heave: None,
                heave_scale: a.heave_scale,
            });
        }
        let motion: Box<dyn MotionProfile> = match a.motion {
            SeaModel::Irregular => Box::new(ShipMotion::irregular(seed, scale_of(ss)?, 8)),
            SeaModel::Regular => Box::new(ShipMotion::scaled(seed, scale_of(ss)?)),
            SeaModel::Jonswap => Box::new(
                SpectrumShipMotion::sea_state_from(ss, seed, heading_deg)
                    .ok_or(format!("--sea-states: {ss} has no JONSWAP sea (3, 4, 5, 6)"))?,
            ),
        };
        let heave = match a.motion {
            SeaModel::Jonswap => None,
            _ => Some(DeckHeave::sea_state_6(seed, scale_of(ss)? * a.heave_scale)),
        };
        Ok(Self {
            motion,
            heave,
            heave_scale: a.heave_scale,
        })
    }

    /// The true deck at `t`: roll, pitch (deg), height (m).
    pub(crate) fn truth(&self, t: f64) -> [f64; 3] {
        let s = self.motion.sample(t);
        let [r, p, _] = s.attitude.to_degrees();
        let h = self
            .heave
            .as_ref()
            .map_or(self.heave_scale * s.deck_heave_m, |h| h.at(t));
        [r, p, h]
    }
}

/// The series `--sea-states`, `--seeds` and (for the spectrum sea) `--headings` ask for, in
/// order: (sea state, seed, heading off the bow in deg).
pub(crate) fn series(a: &DecideEvalArgs) -> Vec<(u32, u64, f64)> {
    if a.motion_csv.is_some() {
        return a.seeds.iter().map(|&seed| (0, seed, f64::NAN)).collect();
    }
    let headings: &[f64] = if a.motion == SeaModel::Jonswap {
        &a.headings
    } else {
        &[f64::NAN]
    };
    let mut out = Vec::new();
    for &ss in &a.sea_states {
        for &heading in headings {
            for &seed in &a.seeds {
                out.push((ss, seed, heading));
            }
        }
    }
    out
}

/// A series' name in the tables: `sea/seed`, and `@heading` for the spectrum sea.
pub(crate) fn series_name(ss: u32, seed: u64, heading: f64) -> String {
    if ss == 0 {
        format!("file/{seed}")
    } else if heading.is_finite() {
        format!("{ss}/{seed}@{heading}")
    } else {
        format!("{ss}/{seed}")
    }
}

/// The minutes of each series: `--minutes`, else 30, or a motion file's whole length (which
/// must be long enough for `--minutes`).
pub(crate) fn minutes(a: &DecideEvalArgs) -> Result<f64, String> {
    let Some(path) = &a.motion_csv else {
        return Ok(a.minutes.unwrap_or(30.0));
    };
    let file_min = RecordedShipMotion::load(path)
        .map_err(|e| format!("--motion-csv: {e}"))?
        .duration_s()
        / 60.0;
    match a.minutes {
        None => Ok(file_min),
        Some(m) if m <= file_min + 1e-9 => Ok(m),
        Some(m) => Err(format!(
            "--motion-csv: {} holds {:.2} min of motion, --minutes asks for {m}",
            path.display(),
            file_min
        )),
    }
}

/// The attitude stream the options describe (`trials::faults`: the one fault model).
pub(crate) fn stream_model(
    a: &DecideEvalArgs,
    vehicle: &VehicleConfig,
) -> Result<AttitudeStreamModel, String> {
    if !a.minutes.is_none_or(|m| m > 0.0) {
        return Err("--minutes must be positive".into());
    }
    if a.vehicle == VehicleMotion::Tilted {
        return Err(
            "--vehicle: `tilted` is the simulator's; the attitude stream models level and sway".into(),
        );
    }
    if a.headings.is_empty() || !a.headings.iter().all(|h| h.is_finite()) {
        return Err("--headings: finite angles (deg)".into());
    }
    let vehicle_bias_deg = match a.vehicle_bias_deg[..] {
        [r, p] => [r, p],
        _ => return Err("--vehicle-bias-deg: two finite angles (roll, pitch)".into()),
    };
    let model = AttitudeStreamModel {
        rate_hz: a.rate,
        noise_deg: a.noise_deg,
        heave_noise_m: a.heave_noise_m,
        vehicle_height_noise_m: a.vehicle_height_noise_m,
        vehicle_height_drift_mps: a.vehicle_height_drift_mps,
        height_fusion_s: vehicle.height_fusion_s,
        dropout: a.dropout,
        outliers: a.outliers,
        nan_share: a.nan_share,
        stale_share: a.stale_share,
        jitter_ms: a.jitter_ms,
        latency_ms: a.latency_ms,
        frozen_per_min: a.frozen_per_min,
        frozen_s: a.frozen_s,
        vehicle_sways: a.vehicle == VehicleMotion::Sway,
        vehicle_bias_deg,
        vehicle_noise_deg: a.vehicle_noise_deg,
        vehicle_time_error_ms: a.vehicle_time_error_ms,
        vehicle_outages_per_min: a.vehicle_outages_per_min,
        vehicle_outage_s: a.vehicle_outage_s,
    };
    model.validate().map_err(|e| e.to_string())?;
    if !(a.heave_scale >= 0.0) {
        return Err("--heave-scale must not be negative".into());
    }
    Ok(model)
}

/// Frames per series: `minutes` at `--rate`, and with a motion file the one at its end too.
pub(crate) fn frames(a: &DecideEvalArgs, minutes: f64) -> usize {
    (minutes * 60.0 * a.rate) as usize + usize::from(a.motion_csv.is_some())
}

/// The measured stream of one series: the truth plus the faults of `model`, from a random
/// stream of `seed` and `ss`.
pub(crate) fn measure(
    model: &AttitudeStreamModel,
    a: &DecideEvalArgs,
    minutes: f64,
    sea: &Sea,
    ss: u32,
    seed: u64,
) -> Vec<FrameInput> {
    model.measure(&|t| sea.truth(t), frames(a, minutes), seed, ss)
}

pub fn run(a: DecideEvalArgs) -> Result<(), String> {
    let (pipeline, file) = crate::pipeline::load(a.config.as_deref())?;
    let config: DecisionConfig = pipeline.decide;
    config
        .validate()
        .map_err(|e| ConfigError::in_section(&file, "decide", e).to_string())?;
    pipeline
        .vehicle
        .validate()
        .map_err(|e| ConfigError::in_section(&file, "vehicle", e).to_string())?;
    let model = stream_model(&a, &pipeline.vehicle)?;
    let minutes = minutes(&a)?;
    let n = frames(&a, minutes);
    if !a.json {
        outln!(
            "{} min at {} Hz per series, {} motion, noise {} deg, heave x{}: camera height noise {} m, autopilot height noise {} m, drift {} m/s, fused over {} s; dropout {}, outliers {}, NaN {}, stale {}, frozen {}/min of {} s, jitter {} ms; vehicle {} (autopilot noise {} deg, bias {:?} deg, timing {} ms, {} outages/min of {} s); capacity roll/pitch {}/{} deg, rates {}/{} deg/s, heave {:?} rate {} m/s, touchdown {} s; the decider states the autopilot's vertical-speed error {} m/s and attitude error {} deg",
            minutes, a.rate, a.motion_csv.as_ref().map_or(a.motion.name().to_string(), |p| p.display().to_string()), a.noise_deg, a.heave_scale, a.heave_noise_m, a.vehicle_height_noise_m, a.vehicle_height_drift_mps, pipeline.vehicle.height_fusion_s, a.dropout, a.outliers, a.nan_share, a.stale_share,
            a.frozen_per_min, a.frozen_s, a.jitter_ms, clap::ValueEnum::to_possible_value(&a.vehicle).map(|v| v.get_name().to_string()).unwrap_or_default(), a.vehicle_noise_deg,
            a.vehicle_bias_deg, a.vehicle_time_error_ms, a.vehicle_outages_per_min, a.vehicle_outage_s, config.max_abs_roll_deg,
            config.max_abs_pitch_deg, config.max_abs_roll_rate_dps, config.max_abs_pitch_rate_dps, config.heave,
            config.max_abs_heave_rate_mps, config.touchdown_s, config.vertical_speed_error_mps,
            config.vehicle_attitude_error_deg
        );
        // UNSAFE: clearances into a touchdown the true deck broke the capacity in; touched:
        // those of them not sent around before the point of no return.
        outln!(
            "{:<10} {:<14} {:>8} {:>8} {:>9} {:>7} {:>8} {:>6} {:>9}",
            "sea/seed",
            "rule",
            "commits",
            "UNSAFE",
            "touched",
            "aborts",
            "calm win",
            "used",
            "avail"
        );
    }
    let (mut total_smart, mut total_naive) = (RuleOutcome::default(), RuleOutcome::default());
    let mut oracle_share = Vec::new();
    for (ss, seed, heading) in series(&a) {
        let sea = Sea::new(&a, ss, seed, heading)?;
        let truth = |t: f64| sea.truth(t);
        let stream = measure(&model, &a, minutes, &sea, ss, seed);
        {
            let clock = Instant::now();
            let (smart, naive) = evaluate(&truth, &config, &stream).map_err(|e| e.to_string())?;
            oracle_share.push(smart.safe_time_share);
            let per_frame_us = clock.elapsed().as_secs_f64() * 1e6 / n as f64;
            if a.json {
                outln!(
                    "{}",
                    serde_json::json!({"sea_state": ss, "seed": seed, "heading_deg": heading.is_finite().then_some(heading), "frames": n, "state_machine": smart, "naive": naive, "us_per_frame": per_frame_us})
                );
            } else {
                let reasons: Vec<String> = smart
                    .abort_reasons
                    .iter()
                    .map(|(k, v)| format!("{k} {v}"))
                    .collect();
                outln!(
                    "{:<10} {}   aborts: {}; decision cost p50/p99/max {:.0}/{:.0}/{:.0} us",
                    series_name(ss, seed, heading),
                    row("state machine", &smart),
                    if reasons.is_empty() {
                        "-".to_string()
                    } else {
                        reasons.join(", ")
                    },
                    smart.update_us[0],
                    smart.update_us[1],
                    smart.update_us[2]
                );
                for u in &smart.unsafe_commit_details {
                    outln!("{:<10} UNSAFE commit at {u}", "");
                }
                outln!("{:<10} {}", "", row("naive", &naive));
            }
            for (t, o) in [(&mut total_smart, &smart), (&mut total_naive, &naive)] {
                for (k, v) in &o.abort_reasons {
                    *t.abort_reasons.entry(k.clone()).or_default() += v;
                }
                for (k, v) in &o.decisions {
                    *t.decisions.entry(k.clone()).or_default() += v;
                }
                t.commits += o.commits;
                t.unsafe_commits += o.unsafe_commits;
                t.unsafe_touchdowns += o.unsafe_touchdowns;
                t.at_clearances.merge(&o.at_clearances);
                t.aborts += o.aborts;
                t.calm_windows += o.calm_windows;
                t.calm_windows_used += o.calm_windows_used;
            }
        }
    }
    if !a.json {
        let d: Vec<String> = total_smart
            .decisions
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        outln!("state machine decisions: {}", d.join(", "));
        let reasons: Vec<String> = total_smart
            .abort_reasons
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        outln!(
            "{:<10} {}   aborts: {}",
            "all",
            row("state machine", &total_smart),
            reasons.join(", ")
        );
        outln!("{:<10} {}", "", row("naive", &total_naive));
        print_clearance_bands(&total_smart.at_clearances);
        // An oracle that knows the future commits into every truly calm window (availability
        // 100 %), and could commit this share of the time.
        let share = oracle_share.iter().sum::<f64>() / oracle_share.len().max(1) as f64;
        outln!(
            "{:<10} oracle (knows the future motion): {} calm windows, 100.0 % used; a commit would be safe {:.1} % of the time",
            "",
            total_smart.calm_windows,
            100.0 * share
        );
    }
    Ok(())
}
