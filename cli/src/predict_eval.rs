//! `deckwatch predict-eval`: the deck-motion forecast against the true motion. For roll, pitch,
//! the deck height and their rates: the forecast error (RMS, 99th percentile) at several
//! horizons, per sea state and predictor, and the calibration of each predictor's stated 95 %
//! band (pointwise, and for the whole touchdown). The streams are `decide-eval`'s (the same
//! options, seas and faults); the predictors are the decider itself, fed frame by frame as the
//! decide stage feeds it, and persistence.

use crate::decide_eval::{measure, minutes, series, series_name, stream_model, DecideEvalArgs, Sea};
use deckwatch_decide::decision::DecisionConfig;
use deckwatch_decide::forecast_eval::{
    judge_forecasts, ForecastReport, Persistence, StreamForecaster, QUANTITIES, TAIL_SHARE, TAIL_Z,
};
use deckwatch_decide::LandingDecider;
use deckwatch_runtime::config::ConfigError;

#[derive(clap::Args)]
pub struct PredictEvalArgs {
    #[command(flatten)]
    stream: DecideEvalArgs,
    /// Forecast horizons (s).
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,4,8")]
    horizons: Vec<f64>,
    /// Predictors: `ar` (the decider's autoregressive forecast, with its calibrated band),
    /// `persistence` (the last measurement).
    #[arg(long, value_delimiter = ',', default_value = "persistence,ar")]
    predictors: Vec<String>,
    /// One forecast judged every this many seconds of each series.
    #[arg(long, default_value_t = 1.0)]
    every_s: f64,
    /// One line per series as well as the totals per sea state.
    #[arg(long)]
    per_series: bool,
}

fn forecaster(name: &str, config: &DecisionConfig) -> Result<Box<dyn StreamForecaster>, String> {
    match name {
        "ar" => Ok(Box::new(LandingDecider::new(config.clone()).map_err(|e| {
            ConfigError::in_section("the configuration", "decide", e).to_string()
        })?)),
        "persistence" => Ok(Box::new(Persistence::new(config.ar().window_s))),
        other => Err(format!("--predictors: unknown `{other}` (persistence, ar)")),
    }
}

fn print_report(label: &str, predictor: &str, r: &ForecastReport, touchdown_s: f64) {
    for (q, name) in QUANTITIES.iter().enumerate() {
        if r.errors[q].iter().all(|e| e.abs_errors.is_empty()) {
            continue;
        }
        let cells: Vec<String> = r.errors[q]
            .iter()
            .map(|e| {
                if e.abs_errors.is_empty() {
                    format!("{:>20}", "-")
                } else {
                    format!("{:>6.3} {:>6.3} {:>5.1}%", e.rms(), e.p99(), 100.0 * e.coverage())
                }
            })
            .collect();
        outln!(
            "{label:<10} {predictor:<12} {name:<15} {}  {:>5.1}%",
            cells.join(" "),
            100.0 * r.window_coverage(q)
        );
    }
    outln!(
        "{label:<10} {predictor:<12} {:<15} {} windows of {touchdown_s} s, every quantity inside: {:.1}%",
        "all",
        r.windows,
        100.0 * r.window_all_inside as f64 / r.windows.max(1) as f64
    );
}

pub fn run(a: PredictEvalArgs) -> Result<(), String> {
    let (pipeline, file) = crate::pipeline::load(a.stream.config.as_deref())?;
    let config: DecisionConfig = pipeline.decide;
    config
        .validate()
        .map_err(|e| ConfigError::in_section(&file, "decide", e).to_string())?;
    pipeline
        .vehicle
        .validate()
        .map_err(|e| ConfigError::in_section(&file, "vehicle", e).to_string())?;
    let model = stream_model(&a.stream, &pipeline.vehicle)?;
    let minutes = minutes(&a.stream)?;
    if a.horizons.is_empty()
        || !a
            .horizons
            .iter()
            .all(|h| h.is_finite() && *h >= 0.0 && *h <= 60.0)
    {
        return Err("--horizons: seconds in [0, 60]".into());
    }
    if !(a.every_s > 0.0) {
        return Err("--every-s must be positive".into());
    }
    for p in &a.predictors {
        forecaster(p, &config)?;
    }
    outln!(
        "{} min at {} Hz per series, {} motion; noise {} deg, camera height noise {} m, autopilot height noise {} m, drift {} m/s, fused over {} s, dropout {}, outliers {}; window {} s, touchdown {} s, risk per touchdown {}",
        minutes, a.stream.rate, a.stream.motion_csv.as_ref().map_or(a.stream.motion.name().to_string(), |p| p.display().to_string()), a.stream.noise_deg, a.stream.heave_noise_m,
        a.stream.vehicle_height_noise_m, a.stream.vehicle_height_drift_mps, pipeline.vehicle.height_fusion_s,
        a.stream.dropout, a.stream.outliers, config.ar().window_s, config.touchdown_s, config.risk_per_touchdown
    );
    let horizons: Vec<String> = a
        .horizons
        .iter()
        .map(|h| format!("{:>20}", format!("{h} s: rms p99 in95")))
        .collect();
    outln!(
        "{:<10} {:<12} {:<15} {}  {:>6}",
        "sea",
        "predictor",
        "quantity",
        horizons.join(" "),
        "window"
    );
    let all = series(&a.stream);
    let mut sea_states: Vec<u32> = all.iter().map(|s| s.0).collect();
    sea_states.dedup();
    let mut overall: Vec<ForecastReport> = vec![ForecastReport::default(); a.predictors.len()];
    for ss in sea_states {
        let mut totals: Vec<ForecastReport> = vec![ForecastReport::default(); a.predictors.len()];
        for &(_, seed, heading) in all.iter().filter(|s| s.0 == ss) {
            let sea = Sea::new(&a.stream, ss, seed, heading)?;
            let truth = |t: f64| sea.truth(t);
            let stream = measure(&model, &a.stream, minutes, &sea, ss, seed);
            for (k, name) in a.predictors.iter().enumerate() {
                let mut f = forecaster(name, &config)?;
                let r = judge_forecasts(
                    &truth,
                    f.as_mut(),
                    &stream,
                    &a.horizons,
                    config.touchdown_s,
                    a.every_s,
                );
                if a.per_series {
                    print_report(&series_name(ss, seed, heading), name, &r, config.touchdown_s);
                }
                totals[k].merge(&r);
            }
        }
        for (k, name) in a.predictors.iter().enumerate() {
            let label = if ss == 0 {
                "file".to_string()
            } else {
                format!("SS{ss}")
            };
            print_report(&label, name, &totals[k], config.touchdown_s);
            overall[k].merge(&totals[k]);
        }
    }
    for (k, name) in a.predictors.iter().enumerate() {
        print_report("all", name, &overall[k], config.touchdown_s);
    }
    // The tail the decision's risk lies in: the 95 % band holding 95 % says nothing of it.
    outln!(
        "share of truths beyond {TAIL_Z:.2} stated deviations, the tails the risk per touchdown is judged in (an honest normal band's: {:.2} %), at {} s, and at some instant of a whole touchdown (window)",
        100.0 * TAIL_SHARE,
        a.horizons.iter().map(|h| h.to_string()).collect::<Vec<_>>().join(", ")
    );
    for (k, name) in a.predictors.iter().enumerate() {
        for (q, quantity) in QUANTITIES.iter().enumerate() {
            let mut cells: Vec<String> = overall[k].errors[q]
                .iter()
                .map(|e| {
                    if e.abs_errors.is_empty() {
                        format!("{:>7}", "-")
                    } else {
                        format!("{:>6.2}%", 100.0 * e.tail_share())
                    }
                })
                .collect();
            let windows = overall[k].windows.max(1) as f64;
            cells.push(format!(
                "{:>6.2}%",
                100.0 * overall[k].window_beyond_tail[q] as f64 / windows
            ));
            if overall[k].errors[q].iter().any(|e| !e.abs_errors.is_empty()) {
                outln!("{:<10} {name:<12} {quantity:<15} {}", "tail", cells.join(" "));
            }
        }
    }
    Ok(())
}
