//! The landing decision's cost per attitude, one thread: `cargo bench -p deckwatch-decide --bench
//! decide`; and the autoregressive fit's parts.
//!
//! A deck rolling and pitching like a ship in a moderate sea (three swells each) at 30 frames a
//! second, fed one attitude at a time to the decider with its default configuration: the mean
//! includes the motion model's refits (about once a second), which the second case measures
//! alone as the worst single attitude.

use criterion::Criterion;
use deckwatch_decide::{DecisionConfig, DeckObservation, LandingDecider};
use std::hint::black_box;

/// The deck at `t_s`: roll, pitch (deg) and heave (m) of a few swells.
fn deck_at(t_s: f64) -> DeckObservation {
    let swell =
        |a: f64, period_s: f64, phase: f64| a * (std::f64::consts::TAU * t_s / period_s + phase).sin();
    DeckObservation::new(
        swell(3.0, 9.0, 0.0) + swell(1.2, 6.5, 1.0) + swell(0.5, 4.1, 2.0),
        swell(1.5, 7.5, 0.5) + swell(0.8, 5.2, 1.5) + swell(0.3, 3.7, 2.5),
        swell(0.6, 8.0, 0.2) + swell(0.2, 5.5, 1.1),
    )
}

fn main() {
    const RATE_HZ: f64 = 30.0;
    let mut c = Criterion::default().sample_size(50).configure_from_args();
    let mut group = c.benchmark_group("decide");
    // Warmed up over two minutes of deck motion, then one attitude per iteration.
    let warm = |decider: &mut LandingDecider| {
        for k in 0..(120.0 * RATE_HZ) as u64 {
            let t = k as f64 / RATE_HZ;
            decider.update(t, Some(deck_at(t)), t);
        }
        (120.0 * RATE_HZ) as u64
    };
    // The default (each channel may read the others' lags: `forecast::joint`) beside every
    // channel alone (`cross_order = 0`, the default before), in one run.
    let mut channels_alone = DecisionConfig::default();
    channels_alone.ar_mut().cross_order = 0;
    for (name, config) in [
        ("per_attitude_30hz", DecisionConfig::default()),
        ("per_attitude_30hz_channels_alone", channels_alone.clone()),
    ] {
        let mut decider = LandingDecider::new(config).expect("a valid configuration");
        let mut k = warm(&mut decider);
        group.bench_function(name, |b| {
            b.iter(|| {
                k += 1;
                let t = k as f64 / RATE_HZ;
                decider.update(t, Some(black_box(deck_at(t))), t)
            })
        });
    }
    // The attitude that refits the motion model: a fresh decider warmed to just before a refit
    // is not reachable from outside, so every attitude of a second is timed and the slowest
    // kept. Warmed over its whole fit window.
    for (name, config) in [
        ("slowest_attitude_of_a_second", DecisionConfig::default()),
        ("slowest_attitude_of_a_second_channels_alone", channels_alone),
    ] {
        let window_s = config.ar().window_s;
        let mut decider = LandingDecider::new(config).expect("a valid configuration");
        let mut k = 0u64;
        while (k as f64) < window_s * RATE_HZ {
            let t = k as f64 / RATE_HZ;
            decider.update(t, Some(deck_at(t)), t);
            k += 1;
        }
        group.bench_function(name, |b| {
            b.iter_custom(|iters| {
                let mut total = std::time::Duration::ZERO;
                for _ in 0..iters {
                    let mut slowest = std::time::Duration::ZERO;
                    for _ in 0..RATE_HZ as u64 {
                        k += 1;
                        let t = k as f64 / RATE_HZ;
                        let t0 = std::time::Instant::now();
                        black_box(decider.update(t, Some(deck_at(t)), t));
                        slowest = slowest.max(t0.elapsed());
                    }
                    total += slowest;
                }
                total
            })
        });
    }
    group.finish();
    // The autoregressive fit's normal equations for one channel (the default order on 120 s at
    // 5 Hz): from lagged products (what the fit uses) beside multiplying the design matrix out
    // (what it did before), in one run.
    let mut group = c.benchmark_group("ar_normal_equations");
    let x: Vec<f64> = (0..600).map(|k| deck_at(k as f64 * 0.2).roll_deg).collect();
    let order = DecisionConfig::default().ar().order;
    group.bench_function("lagged_products", |b| {
        b.iter(|| deckwatch_decide::forecast::normal_equations(black_box(&x), order))
    });
    group.bench_function("design_product", |b| {
        b.iter(|| {
            let x = black_box(&x);
            let rows = x.len() - order;
            let a = nalgebra::DMatrix::from_fn(rows, order + 1, |r, i| {
                if i == order {
                    1.0
                } else {
                    x[r + order - 1 - i]
                }
            });
            let y = nalgebra::DVector::from_fn(rows, |r, _| x[r + order]);
            (a.tr_mul(&a), a.tr_mul(&y))
        })
    });
    // One channel's whole fit (normal equations, eigen-decomposition, roots, forecast).
    let t: Vec<f64> = (0..1200).map(|k| k as f64 * 0.1).collect();
    let y: Vec<f64> = t.iter().map(|&t| deck_at(t).roll_deg).collect();
    group.bench_function("whole_fit_one_channel", |b| {
        b.iter(|| {
            deckwatch_decide::forecast::ArModel::fit(black_box(&t), black_box(&y), order, 0.2, 25.0, 0.5)
        })
    });
    // The same with a 2 s gap ending 1 s before the newest sample: the forecast starts from
    // the Kalman filter across the gap (`ArModel`'s notes).
    let (t_gap, y_gap): (Vec<f64>, Vec<f64>) = t
        .iter()
        .zip(&y)
        .filter(|(&t, _)| !(117.0..119.0).contains(&t))
        .map(|(&t, &y)| (t, y))
        .unzip();
    group.bench_function("whole_fit_one_channel_across_a_gap", |b| {
        b.iter(|| {
            deckwatch_decide::forecast::ArModel::fit(
                black_box(&t_gap),
                black_box(&y_gap),
                order,
                0.2,
                25.0,
                0.5,
            )
        })
    });
    // A refit of all three channels on the default window (600 s at 10 Hz) and on 240 s (the
    // default before: BENCHMARKS.md, "Ship motion it was not built on"), each alone and with the
    // other channels' lags (`cross_order`: `forecast::joint`).
    for window_s in [240usize, 600] {
        let t: Vec<f64> = (0..window_s * 10).map(|k| k as f64 * 0.1).collect();
        let decks: Vec<DeckObservation> = t.iter().map(|&t| deck_at(t)).collect();
        let channels: [Vec<f64>; 3] = [
            decks.iter().map(|d| d.roll_deg).collect(),
            decks.iter().map(|d| d.pitch_deg).collect(),
            decks.iter().map(|d| d.height_m).collect(),
        ];
        let y: Vec<&[f64]> = channels.iter().map(Vec::as_slice).collect();
        for cross_order in [0, 24] {
            let forecaster = deckwatch_decide::forecast::ArForecaster {
                order,
                cross_order,
                grid_step_s: 0.2,
                max_bridge_s: 0.5,
            };
            group.bench_function(
                format!("refit_three_channels_{window_s}s_cross_order_{cross_order}"),
                |b| {
                    b.iter(|| {
                        deckwatch_decide::forecast::Forecaster::fit(
                            &forecaster,
                            black_box(&t),
                            black_box(&y),
                            25.0,
                        )
                    })
                },
            );
        }
    }
    group.finish();
    c.final_summary();
}
