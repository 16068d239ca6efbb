use super::band::*;
use super::coverage::BandCoverage;
use super::history::{fit_line, parabola_rate_at, FIT_SPACING_S};
use super::models::Models;
use super::rate_history::{rate_histories, upper_bound_factor, RateHistory};
use super::risk::{
    exceedance_risk, outside_probability, predicted_within, tilt_outside_probability, Judgement, STEP_S,
};
use super::*;
use crate::forecast::ArChannel;
use crate::frame::FrameInput;
use std::f64::consts::TAU;

/// Roll, pitch (deg) and the deck's height (m): heave up to 0.33 m/s at scale 1.
fn sea(t: f64, scale: f64) -> DeckObservation {
    DeckObservation::new(
        scale * (4.0 * (TAU * t / 11.0).sin() + 2.0 * (TAU * t / 8.3 + 1.0).sin()),
        scale * (1.5 * (TAU * t / 6.4 + 0.5).sin() + 0.8 * (TAU * t / 8.9).sin()),
        scale * 0.5 * (TAU * t / 9.5 + 0.3).sin(),
    )
}

/// `d` as a camera measures it: the angles to a few hundredths of a degree, the height to a
/// few millimetres (a deterministic noise). A noise-free signal lets a fitted model state
/// an error of micrometres, which it then misses by many of them.
fn measured(d: DeckObservation, t: f64) -> DeckObservation {
    let noise = |k: f64| ((t * 12.9898 + k * 78.233).sin() * 43_758.545).fract();
    DeckObservation::new(
        d.roll_deg + 0.05 * noise(1.0),
        d.pitch_deg + 0.05 * noise(2.0),
        d.height_m + 0.005 * noise(3.0),
    )
}

fn heave_rate(t: f64, scale: f64) -> f64 {
    scale * 0.5 * TAU / 9.5 * (TAU * t / 9.5 + 0.3).cos()
}

/// The time of the first clearance among `run`'s decisions.
fn first_clearance(decisions: &[(f64, Decision)]) -> Option<f64> {
    decisions
        .iter()
        .find(|(_, r)| r.state == DecisionState::ClearToLand)
        .map(|(t, _)| *t)
}

fn run<F: crate::forecast::Forecaster>(
    decider: &mut Decider<F>,
    from: f64,
    to: f64,
    f: impl Fn(f64) -> Option<DeckObservation>,
) -> Vec<(f64, Decision)> {
    let mut out = Vec::new();
    let mut t = from;
    while t < to {
        out.push((t, decider.update(t, f(t), t + 0.005)));
        t += 0.1;
    }
    out
}

/// The measured rate is checked against the model's at most every `RATE_CHECK_INTERVAL_S`
/// whatever the frame rate (every third frame at 30 Hz), and on every frame at 10 Hz, the
/// rate it was developed at.
#[test]
fn the_rate_is_checked_at_most_ten_times_a_second() {
    let checks = |rate_hz: f64| {
        let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
        let mut checked = Vec::new();
        for k in 0..(40.0 * rate_hz) as usize {
            let t = k as f64 / rate_hz;
            d.update(t, Some(measured(sea(t, 0.8), t)), t + 0.005);
            if d.tracking.rate_checked_at == t {
                checked.push(t);
            }
        }
        checked
    };
    let at_30 = checks(30.0);
    assert!(at_30.len() > 250, "{}", at_30.len());
    assert!(at_30
        .windows(2)
        .all(|w| w[1] - w[0] >= 0.1 - 1e-6 && w[1] - w[0] < 0.14));
    let at_10 = checks(10.0);
    assert!(
        at_10.windows(2).all(|w| (w[1] - w[0] - 0.1).abs() < 1e-6),
        "every frame"
    );
    assert!(at_10.len() > 250);
}

/// The camera's rate gives the check more samples, not more false alarms: over the same
/// sea, the measurements the model is said not to explain are no more frequent per second
/// at 30 Hz than at 10 Hz. (With the line's rate carried to its mean time by the model's
/// acceleration: 56 at 30 Hz against 10 at 10 Hz; now none at either.)
#[test]
fn the_camera_rate_does_not_make_the_model_unexplained_more_often() {
    // A spectrum sea's roll and pitch: 24 waves of periods 6-14 s.
    let irregular = |t: f64| {
        let wave = |k: usize, phase: f64| {
            let period_s = 6.0 + 8.0 * k as f64 / 23.0;
            let amplitude = (1.0 - (period_s - 9.0).abs() / 6.0).max(0.1) / 3.0;
            amplitude * (TAU * t / period_s + phase * k as f64 * k as f64).sin()
        };
        let roll: f64 = (0..24).map(|k| 2.0 * wave(k, 0.7)).sum();
        let pitch: f64 = (0..24).map(|k| wave(k, 1.3)).sum();
        let noise = |k: f64| ((t * 12.9898 + k * 78.233).sin() * 43_758.545).fract();
        DeckObservation::new(
            roll + 0.1 * noise(1.0),
            pitch + 0.1 * noise(2.0),
            0.005 * noise(3.0),
        )
    };
    let unexplained = |rate_hz: f64| {
        let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
        let mut count = 0;
        for k in 0..(300.0 * rate_hz) as usize {
            let t = k as f64 / rate_hz;
            d.update(t, Some(irregular(t)), t + 0.005);
            count += usize::from(d.tracking.unexplained_at == t);
        }
        count
    };
    let (at_10, at_30) = (unexplained(10.0), unexplained(30.0));
    assert!(at_30 <= 2 * at_10 + 2, "{at_30} at 30 Hz, {at_10} at 10 Hz");
}

#[test]
fn a_parabola_through_samples_gives_each_channel_its_rate_at_the_instant() {
    let samples: Vec<(f64, [f64; 3])> = (0..10)
        .map(|k| {
            let t = 1000.0 + 0.1 * k as f64;
            let x = t - 1000.0;
            (t, [2.0 * t, -0.5 * x + 3.0, 3.0 * x * x - x])
        })
        .collect();
    let at = 1000.9;
    let p = parabola_rate_at(samples.iter().rev(), at).unwrap();
    assert_eq!(p.count, 10);
    assert!((p.span_s - 0.9).abs() < 1e-9);
    assert!((p.rates[0] - 2.0).abs() < 1e-6 && (p.rates[1] + 0.5).abs() < 1e-6);
    assert!((p.rates[2] - (6.0 * 0.9 - 1.0)).abs() < 1e-6, "{:?}", p.rates);
    // Two times only: no parabola.
    assert!(parabola_rate_at(samples[..2].iter(), at).is_none());
    assert!(parabola_rate_at([samples[0], samples[0], samples[1]].iter(), at).is_none());
}

#[test]
fn warms_up_then_clears_only_into_calm_windows() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    let out = run(&mut d, 0.0, 120.0, |t| Some(sea(t, 0.8)));
    let warmup_s = d.config().ar().min_history_s;
    assert!(out
        .iter()
        .take_while(|(t, _)| *t < warmup_s - 0.1)
        .all(|(_, d)| d.state == DecisionState::Hold && d.reason == DecisionReason::Warmup));
    let commits: Vec<f64> = out
        .iter()
        .filter(|(_, d)| d.new_commit)
        .map(|(t, _)| *t)
        .collect();
    assert!(!commits.is_empty(), "a moderate sea has calm windows");
    let c = d.config().clone();
    for tc in commits {
        let mut t = tc;
        while t <= tc + c.touchdown_s {
            let d = sea(t, 0.8);
            assert!(
                d.roll_deg.abs() <= c.max_abs_roll_deg
                    && d.pitch_deg.abs() <= c.max_abs_pitch_deg
                    && heave_rate(t, 0.8).abs() <= c.max_abs_heave_rate_mps,
                "unsafe at {t}"
            );
            t += 0.01;
        }
    }
    assert!(out.iter().any(|(_, d)| d.calm_window.is_some()));
}

/// Fitting between frames (`refit_ahead` after each decision, as the stage does) clears into
/// the same calm windows, only ever safe ones; before warm-up and with a lead that is no
/// number it does nothing.
#[test]
fn fitting_between_frames_decides_alike() {
    // The model runs forward from every frame, so a commitment a frame apart shifts the later
    // ones: both ways clear as often, and only ever safely. A calm sea: on a rougher one the
    // bands are measured more than `MAX_BAND_SCALE` times too narrow and the history's spread
    // holds nearly every clearance (too few to compare).
    fitting_between_frames_decides_alike_with(DecisionConfig::default(), false, 0.4);
}

fn fitting_between_frames_decides_alike_with(config: DecisionConfig, same_windows: bool, scale: f64) {
    let mut ahead = LandingDecider::new(config.clone()).unwrap();
    ahead.refit_ahead(f64::NAN);
    ahead.refit_ahead(0.1);
    assert!(ahead.tracking.models.is_none());
    let mut inline = LandingDecider::new(config).unwrap();
    let c = inline.config().clone();
    let (mut commits_ahead, mut commits_inline) = (Vec::new(), Vec::new());
    let mut t = 0.0;
    while t < 150.0 {
        let d = ahead.update(t, Some(measured(sea(t, scale), t)), t + 0.005);
        ahead.refit_ahead(0.1);
        if d.new_commit {
            commits_ahead.push(t);
        }
        if inline
            .update(t, Some(measured(sea(t, scale), t)), t + 0.005)
            .new_commit
        {
            commits_inline.push(t);
        }
        t += 0.1;
    }
    // The models are fitted up to the sample before the frame that would refit: the same
    // fits but for that sample, so nearly all the same windows, within a frame or two.
    let matched = |a: &[f64], b: &[f64]| {
        a.iter()
            .filter(|x| b.iter().any(|y| (*x - y).abs() <= 0.25))
            .count()
    };
    for (a, b) in [
        (&commits_ahead, &commits_inline),
        (&commits_inline, &commits_ahead),
    ] {
        assert!(
            a.len() >= 30 && (!same_windows || matched(a, b) * 10 >= a.len() * 9),
            "{a:?} vs {b:?}"
        );
    }
    for tc in commits_ahead {
        let mut t = tc;
        while t <= tc + c.touchdown_s {
            let d = sea(t, scale);
            assert!(d.roll_deg.abs() <= c.max_abs_roll_deg && d.pitch_deg.abs() <= c.max_abs_pitch_deg);
            t += 0.01;
        }
    }
}

#[test]
fn a_time_that_is_not_a_number_aborts_a_committed_landing() {
    // On the frames' own timeline, fresh on arrival, until the first clearance.
    let (mut d, committed) = committed(DecisionConfig::default());
    let r = d.update_at_capture(f64::NAN, Some(sea(committed, 0.8)), 0.01);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::Abort, DecisionReason::ClockJump)
    );
    // Nor does it stop the watchdog: silence after it is still noticed.
    assert!(d.timeout(committed + 1.0).is_some());
}

/// The first commit on a moderate sea, on the frames' own timeline: (decider, commit time).
fn committed(config: DecisionConfig) -> (LandingDecider, f64) {
    let mut d = LandingDecider::new(config).unwrap();
    let mut t = 0.0;
    loop {
        if d.update_at_capture(t, Some(sea(t, 0.8)), 0.01).new_commit {
            return (d, t);
        }
        t += 0.1;
        assert!(t < 120.0, "a moderate sea has calm windows");
    }
}

/// Scales a committed decider's capacity so that the risk from `now` to the touchdown's end
/// is just at or below `target` (the risk falls as the capacity grows: its scale bisected).
fn scale_capacity_to_risk(d: &mut LandingDecider, now: f64, target: f64) {
    let defaults = DecisionConfig::default();
    let set_scale = |c: &mut DecisionConfig, f: f64| {
        c.max_abs_roll_deg = f * defaults.max_abs_roll_deg;
        c.max_abs_pitch_deg = f * defaults.max_abs_pitch_deg;
        c.max_tilt_deg = f * defaults.max_tilt_deg;
        c.max_abs_roll_rate_dps = f * defaults.max_abs_roll_rate_dps;
        c.max_abs_pitch_rate_dps = f * defaults.max_abs_pitch_rate_dps;
        c.max_abs_heave_rate_mps = f * defaults.max_abs_heave_rate_mps;
    };
    let risk = |d: &LandingDecider| {
        let m = d.tracking.models.as_ref().expect("committed on a model");
        let steps = ((d.commitment.commit_end - now) / STEP_S).ceil() as usize;
        let times = (0..=steps).map(|k| (now + k as f64 * STEP_S).min(d.commitment.commit_end));
        exceedance_risk_as_measured(&d.config, m, times, &d.config.capacity_limits())
    };
    let (mut low, mut high) = (0.05, 3.0);
    for _ in 0..60 {
        let mid = 0.5 * (low + high);
        set_scale(&mut d.config, mid);
        if risk(d) > target {
            low = mid;
        } else {
            high = mid;
        }
    }
    set_scale(&mut d.config, high);
    let r = risk(d);
    assert!(r > 0.5 * target && r <= target, "{r}");
}

#[test]
fn a_line_through_samples_gives_each_channel_its_slope_at_their_mean_time() {
    let samples: Vec<(f64, [f64; 3])> = (0..6)
        .map(|k| {
            let t = 1000.0 + 0.1 * k as f64;
            (t, [2.0 * t, -0.5 * t + 3.0, (t - 1000.0).powi(2)])
        })
        .collect();
    let line = fit_line(samples.iter().rev()).unwrap();
    assert_eq!((line.count, line.first_t, line.last_t), (6, 1000.0, 1000.5));
    assert!((line.slopes[0] - 2.0).abs() < 1e-6 && (line.slopes[1] + 0.5).abs() < 1e-6);
    // A parabola's line has the parabola's slope at the mean time.
    assert!((line.slopes[2] - 2.0 * 0.25).abs() < 1e-6, "{:?}", line.slopes);
    // One time only: no line.
    assert!(fit_line(samples[..1].iter()).is_none());
}

#[test]
fn the_risk_of_leaving_a_limit_is_a_normal_tail_and_the_tilt_is_bounded_from_above() {
    // Two-sided: the 95 % band.
    assert!((outside_probability(0.0, 1.0, Z95) - 0.05).abs() < 1e-9);
    // One side dominates: P(N(3, 1) > 5) = P(N(0, 1) > 2).
    assert!((outside_probability(3.0, 1.0, 5.0) - 0.022_750_131_948_179).abs() < 1e-9);
    // A mean beyond the limit with no stated deviation is outside for sure; far inside, 0.
    assert_eq!(outside_probability(5.1, 0.0, 5.0), 1.0);
    assert_eq!(outside_probability(0.0, 0.1, 5.0), 0.0);
    // Roll and pitch centred, 1 deg each, independent: the tilt is about Rayleigh,
    // P(tilt > L) = exp(-L^2 / 2). The bound is above it: 2.4, 6.4 and 31 times at 2, 3 and
    // 4 deg (the square inside the disc; it holds whatever roll and pitch's correlation).
    for (limit, looser) in [(2.0_f64, 3.0), (3.0, 8.0), (4.0, 35.0)] {
        let rayleigh = (-limit * limit / 2.0).exp();
        let bound = tilt_outside_probability((0.0, 1.0), (0.0, 1.0), limit);
        assert!(
            bound >= rayleigh && bound <= looser * rayleigh,
            "{limit}: {bound} vs {rayleigh}"
        );
    }
    // Pitch certain at 0: the tilt is the roll's.
    let roll_only = tilt_outside_probability((3.0, 1.0), (0.0, 0.0), 5.0);
    assert!(
        (roll_only - outside_probability(3.0, 1.0, 5.0)).abs() < 1e-6,
        "{roll_only}"
    );
}

/// A committed touchdown rides through missing attitudes (the blind last metre) and a lone
/// implausible one for `ride_through_ms`, saying so, and aborts after; never through a late
/// or frozen input, and never into a clearance.
#[test]
fn a_committed_touchdown_rides_through_a_short_blind_spell_only() {
    let (mut d, t0) = committed(DecisionConfig::default());
    // Ten frames at 10 Hz without a deck ...
    for k in 1..=10 {
        let r = d.update_at_capture(t0 + 0.1 * k as f64, None, 0.01);
        assert_eq!(
            (r.state, r.reason),
            (DecisionState::ClearToLand, DecisionReason::RideThrough),
            "frame {k}"
        );
        assert!(!r.new_commit);
    }
    // ... and not after 1 s of it.
    let r = d.update_at_capture(t0 + 1.25, None, 0.01);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::Abort, DecisionReason::InvalidAttitude)
    );
    // The vehicle's attitude missing rides through too; a good frame ends the spell.
    let (mut d, t0) = committed(DecisionConfig::default());
    let r = d.refuse(t0 + 0.1, DecisionReason::NoVehicleAttitude);
    assert_eq!(r.reason, DecisionReason::RideThrough);
    let r = d.update_at_capture(t0 + 0.2, Some(sea(t0 + 0.2, 0.8)), 0.01);
    assert_eq!(r.state, DecisionState::ClearToLand);
    assert_ne!(r.reason, DecisionReason::RideThrough);
    // A stale frame is never ridden through, whatever else it lacks: a deck without the
    // vehicle's attitude captured longer ago than `max_age_ms` aborts as stale data.
    let (mut d, t0) = committed(DecisionConfig::default());
    let c = d.config().clone();
    let mut stale = FrameInput::measured(t0 + 0.1, Some(sea(t0 + 0.1, 0.8)), 2.0 * c.max_age_ms / 1e3);
    stale.vehicle_missing = true;
    let r = d.decide_frame(&stale);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::Abort, DecisionReason::StaleData)
    );
    // ... and a frozen image that is also stale, the same.
    let (mut d, t0) = committed(DecisionConfig::default());
    let mut stale = FrameInput::measured(t0 + 0.1, Some(sea(t0 + 0.1, 0.8)), 2.0 * c.max_age_ms / 1e3);
    stale.frozen_image = true;
    assert_eq!(d.decide_frame(&stale).reason, DecisionReason::StaleData);
    // One implausible sample is refused and ridden through; three that agree with each
    // other (the history was wrong, or the estimate changed) restart it and abort.
    let jumped = |d: &mut LandingDecider, t: f64| {
        let s = sea(t, 0.8);
        d.update_at_capture(
            t,
            Some(DeckObservation::new(s.roll_deg + 9.0, s.pitch_deg, s.height_m)),
            0.01,
        )
    };
    let (mut d, t0) = committed(DecisionConfig::default());
    for k in 1..=2 {
        let r = jumped(&mut d, t0 + 0.1 * k as f64);
        assert_eq!(
            (r.state, r.reason),
            (DecisionState::ClearToLand, DecisionReason::RideThrough),
            "jump {k}"
        );
    }
    assert_eq!(jumped(&mut d, t0 + 0.3).state, DecisionState::Abort);
    let (mut d, t0) = committed(DecisionConfig::default());
    assert_eq!(jumped(&mut d, t0 + 0.1).reason, DecisionReason::RideThrough);
    let r = d.update_at_capture(t0 + 0.2, Some(sea(t0 + 0.2, 0.8)), 0.01);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::ClearToLand, DecisionReason::WithinCapacity)
    );
    // A stale or frozen input aborts at once.
    let bad: [fn(&mut LandingDecider, f64) -> Decision; 2] = [
        |d: &mut LandingDecider, t: f64| d.update_at_capture(t, Some(sea(t, 0.8)), 0.9),
        |d: &mut LandingDecider, t: f64| d.refuse(t, DecisionReason::StaleData),
    ];
    for bad in bad {
        let (mut d, t0) = committed(DecisionConfig::default());
        assert_eq!(bad(&mut d, t0 + 0.1).state, DecisionState::Abort);
    }
    // Switched off: the first missing frame aborts.
    let (mut d, t0) = committed(DecisionConfig {
        ride_through_ms: 0.0,
        ..Default::default()
    });
    assert_eq!(
        d.update_at_capture(t0 + 0.1, None, 0.01).state,
        DecisionState::Abort
    );
    // Not committed (still warming up): a missing frame is no deck, as always.
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    run(&mut d, 0.0, 5.0, |t| Some(sea(t, 0.3)));
    assert_eq!(d.update_at_capture(5.0, None, 0.01).state, DecisionState::NoDeck);
    let too_long = DecisionConfig {
        ride_through_ms: 2500.0,
        ..Default::default()
    };
    assert_eq!(too_long.validate().unwrap_err().field, "ride_through_ms");
}

/// Blind to contact, a committed touchdown goes on only as a clearance would: with the
/// capacity set so that the forecast's risk over the rest of the touchdown is 0.01 (above
/// `risk_per_touchdown`, below `go_around_risk`), in its last second a frame that sees the
/// deck keeps the touchdown going and a frame without one sends it around. Earlier, with
/// more of the touchdown left than the blind budget, a missing frame is judged as a seeing
/// one: a frame or the budget's end comes before contact.
#[test]
fn blind_to_contact_a_touchdown_goes_on_only_at_a_clearances_risk() {
    // Committed, seen for `seen_s`, then the capacity scaled so that the risk from the next
    // frame to the touchdown's end is `target`.
    let at_risk = |target: f64, seen_s: f64| {
        let (mut d, t0) = committed(DecisionConfig::default());
        let mut t = t0;
        while t < t0 + seen_s - 1e-9 {
            t += 0.1;
            let r = d.update_at_capture(t, Some(sea(t, 0.8)), 0.01);
            assert_eq!(r.state, DecisionState::ClearToLand, "{r:?}");
        }
        let now = t + 0.1;
        scale_capacity_to_risk(&mut d, now, target);
        (d, now)
    };
    // The touchdown's last 0.7 s, within the blind budget left (0.9 s).
    let seen_s = 1.2;
    let (mut seeing, now) = at_risk(0.01, seen_s);
    let r = seeing.update_at_capture(now, Some(sea(now, 0.8)), 0.01);
    assert_eq!(r.state, DecisionState::ClearToLand, "{r:?}");
    let (mut blind, now) = at_risk(0.01, seen_s);
    let r = blind.update_at_capture(now, None, 0.01);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::Abort, DecisionReason::InvalidAttitude)
    );
    // At the clearance's own risk it rides through.
    let (mut blind, now) = at_risk(0.5 * DecisionConfig::default().risk_per_touchdown, seen_s);
    let r = blind.update_at_capture(now, None, 0.01);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::ClearToLand, DecisionReason::RideThrough)
    );
    // 1.9 s left: a missing frame is judged as a seeing one.
    let (mut dropped, now) = at_risk(0.01, 0.0);
    let r = dropped.update_at_capture(now, None, 0.01);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::ClearToLand, DecisionReason::RideThrough)
    );
}

/// Seeing to contact, the last decision before the point of no return (`no_return_ms`
/// before contact; the next frame 0.1 s later would be past it) judges the rest of the
/// touchdown as a clearance: at a seeing touchdown's risk the go-around would be ordered
/// when it can no longer be flown. Before it, and past it once it was taken, a seeing
/// touchdown's risk holds.
#[test]
fn the_last_decision_that_can_act_is_judged_as_a_clearance() {
    let config = DecisionConfig::default();
    let no_return_s = config.no_return_ms / 1e3;
    // Seen every 0.1 s while more than `last_seen_s` of the touchdown is left, then a frame
    // with `left_s` left, the capacity scaled so that the rest is at risk `target`.
    let at_risk_after = |config: DecisionConfig, target: f64, left_s: f64, last_seen_s: f64| {
        let (mut d, t0) = committed(config);
        let mut t = t0;
        while d.commitment.commit_end - (t + 0.1) > last_seen_s.max(left_s) + 1e-9 {
            t += 0.1;
            let r = d.update_at_capture(t, Some(sea(t, 0.8)), 0.01);
            assert_eq!(r.state, DecisionState::ClearToLand, "{r:?}");
        }
        let now = if last_seen_s > left_s {
            d.commitment.commit_end - left_s
        } else {
            t + 0.1
        };
        scale_capacity_to_risk(&mut d, now, target);
        let decision = d.update_at_capture(now, Some(sea(now, 0.8)), 0.01);
        (decision.state, decision.reason)
    };
    let at_risk =
        |config: DecisionConfig, target: f64, left_s: f64| at_risk_after(config, target, left_s, left_s);
    let last_s = no_return_s + 0.1;
    // The last frame before the point of no return, at ten times a clearance's risk: around.
    assert_eq!(
        at_risk(config.clone(), 0.01, last_s),
        (DecisionState::Abort, DecisionReason::PredictedOutside)
    );
    // At a clearance's risk it goes on.
    let clearance = 0.5 * config.risk_per_touchdown;
    assert_eq!(
        at_risk(config.clone(), clearance, last_s),
        (DecisionState::ClearToLand, DecisionReason::WithinCapacity)
    );
    // Two frames earlier a later frame can still call the go-around: a seeing touchdown's
    // risk holds.
    assert_eq!(
        at_risk(config.clone(), 0.01, last_s + 0.2),
        (DecisionState::ClearToLand, DecisionReason::WithinCapacity)
    );
    // Past the point of no return, its last chance taken, the go-around is no longer the
    // decision's to order: a seeing touchdown's risk holds again.
    assert_eq!(
        at_risk(config.clone(), 0.01, no_return_s - 0.1),
        (DecisionState::ClearToLand, DecisionReason::WithinCapacity)
    );
    // The frames before the point lost (0.3 s apart, not a gap): the first one past it is
    // the nearest to a last chance there is.
    assert_eq!(
        at_risk_after(config.clone(), 0.01, no_return_s - 0.1, no_return_s + 0.2),
        (DecisionState::Abort, DecisionReason::PredictedOutside)
    );
    // A vehicle said to go around up to contact (`no_return_ms = 0`) is refused: it would carry
    // every touchdown to contact at `go_around_risk`, ordering go-arounds no vehicle can fly.
    let no_return_0 = DecisionConfig {
        no_return_ms: 0.0,
        ..config.clone()
    };
    assert_eq!(no_return_0.validate().unwrap_err().field, "no_return_ms");
    // Nor may staying need a risk beyond `MAX_GO_AROUND_RISK` (0.5 made the go-around
    // practically unreachable).
    let reckless = DecisionConfig {
        go_around_risk: 0.5,
        ..config.clone()
    };
    assert_eq!(reckless.validate().unwrap_err().field, "go_around_risk");
    // A point of no return as long as the touchdown is refused: nothing could be given up.
    let too_long = DecisionConfig {
        no_return_ms: 1e3 * config.touchdown_s,
        ..config
    };
    assert_eq!(too_long.validate().unwrap_err().field, "no_return_ms");
}

/// A pipeline that falls silent during a committed touchdown, before its last chance: the
/// watchdog, called every `watchdog_period_s`, judges the silence as a blind frame at the
/// last chance before the point of no return, once the frame it waits for is overdue: on
/// at a clearance's risk, around (`gap`) at more, while that can still be flown. Frames on
/// time, or a silence after the last chance, leave it to the freshness limit.
#[test]
fn a_silence_before_the_last_chance_is_judged_while_a_go_around_can_be_flown() {
    let config = DecisionConfig::default();
    let (no_return_s, max_age_s) = (config.no_return_ms / 1e3, config.max_age_ms / 1e3);
    // Seen every 0.1 s until `last_left_s` of the touchdown is left, the capacity then
    // scaled so that the rest is at risk `target`, then silent: the first watchdog decision
    // (its time, its decision), the last frame's time and the point of no return.
    let silent_after = |last_left_s: f64, target: f64| {
        let (mut d, t0) = committed(config.clone());
        let period_s = d.watchdog_period_s();
        assert!(period_s > 0.0 && period_s <= 0.02, "{period_s}");
        let mut t = t0;
        while d.commitment.commit_end - (t + 0.1) >= last_left_s - 1e-9 {
            t += 0.1;
            let r = d.update_at_capture(t, Some(sea(t, 0.8)), 0.01);
            assert_eq!(r.state, DecisionState::ClearToLand);
            // Between frames on time the watchdog says nothing.
            assert!(d.timeout(t + 0.09).is_none());
        }
        scale_capacity_to_risk(&mut d, t, target);
        let no_return_at = d.commitment.commit_end - no_return_s;
        let mut now = t;
        let first = loop {
            now += period_s;
            if let Some(r) = d.timeout(now) {
                break (now, r);
            }
            assert!(now < t + 2.0 * max_age_s, "the freshness limit speaks");
        };
        (t, first, no_return_at)
    };
    let clearance = 0.5 * config.risk_per_touchdown;
    // The last frame just before the last chance would have come: the next one is overdue
    // 0.15 s later, and the silence is judged as late as a go-around can still be flown,
    // before the freshness limit (0.3 s): at ten times a clearance's risk, around.
    let (t, (now, r), no_return_at) = silent_after(no_return_s + 0.25, 0.01);
    assert_eq!((r.state, r.reason), (DecisionState::Abort, DecisionReason::Gap));
    assert!(now > t + 0.15 && now < no_return_at, "{t} {now} {no_return_at}");
    assert!(
        now + 0.02 >= no_return_at && now < t + max_age_s,
        "{t} {now} {no_return_at}"
    );
    // At a clearance's risk it rides through, and past the point the freshness limit
    // speaks (an abort there cannot be flown; it says what is true).
    let (_, (now, r), no_return_at) = silent_after(no_return_s + 0.25, clearance);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::ClearToLand, DecisionReason::RideThrough)
    );
    assert!(now < no_return_at, "{now} {no_return_at}");
    // Silent from further out: the freshness limit speaks first, before the point.
    let (t, (now, r), no_return_at) = silent_after(no_return_s + 0.6, clearance);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::Abort, DecisionReason::StaleData)
    );
    assert!(
        now > t + max_age_s && now < no_return_at,
        "{t} {now} {no_return_at}"
    );
    // After its last chance (judged on a frame, as a clearance) the touchdown goes on until
    // the freshness limit: the frames that would follow could not send it around.
    let (t, (now, r), no_return_at) = silent_after(no_return_s + 0.1, clearance);
    assert_eq!(r.reason, DecisionReason::StaleData);
    assert!(
        now > t + max_age_s && now > no_return_at,
        "{t} {now} {no_return_at}"
    );
}

/// The gap tests' decider: 48 lags (9.6 s). Their gap comes 82 s into the history, where
/// the default's 96 lags have 3 samples per coefficient and the gapped fit, without the
/// rows the gap touches, a lower order: two such fits differ by more than any gap's
/// widening, and the test would judge the fit's sampling error, not the gap. With a full
/// window 96 lags' gapped and steady forecasts agree as these do (docs/history.md, "Forecasts from 19.2 s of lags").
fn gap_test_config(config: DecisionConfig) -> DecisionConfig {
    let mut config = config;
    config.ar_mut().order = 48;
    config
}

/// The hold after a measurement the model missed (`holdout_s`) counts measured time: a gap
/// right after the miss does not serve it, and it resumes once the gap's recovery is over.
#[test]
fn a_gap_does_not_count_as_time_after_a_miss() {
    let observe = |t: f64| Some(measured(sea(t, 0.3), t));
    let first_clear_after_gap = |miss: bool| {
        let mut d = LandingDecider::new(gap_test_config(DecisionConfig::default())).unwrap();
        // To 81.9 (the run's steps of 0.1 s add up to just below 82).
        run(&mut d, 0.0, 81.95, observe);
        let mut deck = observe(82.0).unwrap();
        if miss {
            // 2 deg off the model: unexplained, not a jump.
            deck.roll_deg += 2.0;
        }
        d.update(82.0, Some(deck), 82.005);
        // 3 s without a valid attitude (a frozen camera refused upstream).
        run(&mut d, 82.1, 85.05, |_| None);
        let after = run(&mut d, 85.1, 95.0, observe);
        let first = first_clearance(&after).expect("a calm sea clears again");
        (first, after)
    };
    let c = DecisionConfig::default();
    let resumed = 85.1;
    // Without the miss: as soon as the gap's recovery is over.
    let (control, _) = first_clear_after_gap(false);
    assert!(
        control >= resumed + c.ar().gap_recovery_s - 1e-9 && control < resumed + c.ar().holdout_s - 0.3,
        "{control}"
    );
    // With it: the whole hold after the gap, saying why.
    let (held, after) = first_clear_after_gap(true);
    assert!(held >= resumed + c.ar().holdout_s - 1e-9, "cleared at {held}");
    assert!(after
        .iter()
        .filter(
            |(t, _)| *t >= resumed + c.ar().gap_recovery_s + 1e-9 && *t < resumed + c.ar().holdout_s - 1e-9
        )
        .all(|(_, r)| r.reason == DecisionReason::PredictionUnreliable));
}

#[test]
fn fail_safes_never_clear_and_say_why() {
    // A 40 s warm-up: at 30 s it has not committed yet, so each refusal shows as itself, not
    // as an abort.
    let mut d = LandingDecider::new(tuned(|f| f.min_history_s = 40.0)).unwrap();
    run(&mut d, 0.0, 30.0, |t| Some(sea(t, 0.3)));
    // Stale: decided long after capture.
    let r = d.update(30.0, Some(sea(30.0, 0.3)), 31.0);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::NoDeck, DecisionReason::StaleData)
    );
    // Invalid.
    let r = d.update(30.1, None, 30.105);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::NoDeck, DecisionReason::InvalidAttitude)
    );
    // A jump of 20 deg since the last accepted attitude (0.3 s ago).
    let s = sea(30.2, 0.3);
    let r = d.update(
        30.2,
        Some(DeckObservation {
            roll_deg: s.roll_deg + 20.0,
            ..s
        }),
        30.205,
    );
    assert_eq!(r.reason, DecisionReason::Jump);
    assert_ne!(r.state, DecisionState::ClearToLand);
    // A gap of 2 s.
    let r = d.update(32.3, Some(sea(32.3, 0.3)), 32.305);
    assert_eq!(r.reason, DecisionReason::Gap);
    // Watchdog: nothing arrives.
    assert!(d.timeout(32.4).is_none());
    let r = d.timeout(33.0).unwrap();
    assert_eq!(r.reason, DecisionReason::StaleData);
    assert_ne!(r.state, DecisionState::ClearToLand);
}

/// After a gap the autoregressive forecast carries its unmeasured lags: right after the
/// gap its stated band is wider than that of the same decider fed without the gap, the
/// deck's motion stays inside it, and the sea clears again once `gap_recovery_s` has passed
/// and the band allows, well within the lag span the decision used to wait out.
#[test]
fn a_gap_widens_the_band_and_no_longer_waits_out_the_lags() {
    let observe = |t: f64| Some(measured(sea(t, 0.3), t));
    // Both commit on the same frames (a committed decider refits on a measurement its model
    // misses, and the two are compared fit for fit): no early window, whose start differs.
    let config = gap_test_config(tuned(|f| f.early_window_s = 0.0));
    let mut gapped = LandingDecider::new(config.clone()).unwrap();
    let mut steady = LandingDecider::new(config).unwrap();
    // Compared fit for fit: the touchdowns the gap leaves unstated must not widen one of them.
    gapped.tracking.coverage = BandCoverage::held_at_one();
    steady.tracking.coverage = BandCoverage::held_at_one();
    let before = run(&mut gapped, 0.0, 80.0, observe);
    assert!(before.iter().any(|(_, r)| r.state == DecisionState::ClearToLand));
    run(&mut steady, 0.0, 82.0, observe);
    // 2 s without a valid attitude for one of them (a frozen camera refused upstream).
    let first = gapped.update(82.0, observe(82.0), 82.005);
    assert_eq!(first.reason, DecisionReason::Gap);
    steady.update(82.0, observe(82.0), 82.005);
    // The gap's recovery over (the models are run forward again from here on).
    let recovery = run(&mut gapped, 82.1, 83.05, observe);
    assert!(recovery.iter().all(|(_, r)| r.reason == DecisionReason::Gap));
    run(&mut steady, 82.1, 83.05, observe);
    let resumed = gapped.update(83.1, observe(83.1), 83.105);
    assert_ne!(resumed.reason, DecisionReason::Gap);
    steady.update(83.1, observe(83.1), 83.105);
    let stated = |d: &LandingDecider, k: usize, t: f64| {
        let m = &d.tracking.models.as_ref().unwrap().forecasts[k];
        (m.value(t), m.std(t), m.rate_std(t))
    };
    // From 1 s ahead: the newest value itself is measured, its deviation each fit's
    // innovation (the gapped fit's on the rows the gap leaves, a few per cent apart).
    for k in 0..3 {
        for ahead_s in [1.0, 2.0] {
            let t = 83.1 + ahead_s;
            let (value, std, rate_std) = stated(&gapped, k, t);
            let (steady_value, steady_std, steady_rate_std) = stated(&steady, k, t);
            assert!(
                std > steady_std && rate_std > steady_rate_std,
                "channel {k}, {ahead_s} s ahead: {std} / {rate_std} against {steady_std} / {steady_rate_std}"
            );
            // What the gap hid is within the widening: the forecast from the filtered
            // lags is the one from the measured lags to within the band's extra width.
            let extra = (std * std - steady_std * steady_std).sqrt();
            assert!(
                (value - steady_value).abs() < 3.0 * extra,
                "channel {k}, {ahead_s} s ahead: {value} against {steady_value} (extra std {extra})"
            );
        }
    }
    let after = run(&mut gapped, 83.2, 140.0, observe);
    let first_clear = first_clearance(&after).expect("the sea clears again");
    let lag_span_s = (gapped.config().ar().order as f64 + 3.0) * FIT_SPACING_S;
    assert!(
        first_clear >= 82.0 + gapped.config().ar().gap_recovery_s - 1e-9 && first_clear < 82.0 + lag_span_s,
        "cleared at {first_clear}"
    );
}

#[test]
fn a_changed_sea_is_unreliable_not_cleared() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    run(&mut d, 0.0, 40.0, |t| Some(sea(t, 0.3)));
    // The motion suddenly changes character (new frequencies, bigger): no clearance until the
    // model has learned it. (A touchdown committed when it changed is judged on a model
    // refitted with the new measurements: it goes around, `predicted-outside`.)
    let out = run(&mut d, 40.0, 44.0, |t| {
        Some(DeckObservation::new(3.0 * (TAU * t / 3.0).sin(), 0.0, 0.0))
    });
    assert!(out.iter().any(|(_, d)| matches!(
        d.reason,
        DecisionReason::PredictionUnreliable | DecisionReason::PredictedOutside
    )));
    for (t, dd) in &out {
        if dd.new_commit {
            panic!("cleared at {t} on an unknown motion");
        }
    }
}

#[test]
fn the_heave_rate_is_part_of_the_capacity() {
    // Gentle angles, but the deck rises and falls at up to 0.79 m/s (1.5 m, 12 s): cleared
    // only where the heave is slow (near its crests and troughs).
    let rough = |t: f64| {
        let calm = sea(t, 0.3);
        measured(
            DeckObservation {
                height_m: 1.5 * (TAU * t / 12.0).sin(),
                ..calm
            },
            t,
        )
    };
    let rate = |t: f64| 1.5 * TAU / 12.0 * (TAU * t / 12.0).cos();
    let c = DecisionConfig::default();
    let mut d = LandingDecider::new(c.clone()).unwrap();
    let out = run(&mut d, 0.0, 120.0, |t| Some(rough(t)));
    let commits: Vec<f64> = out
        .iter()
        .filter(|(_, d)| d.new_commit)
        .map(|(t, _)| *t)
        .collect();
    // Near its crests and troughs the heave is slow, but the autoregressive model's band on
    // this pure sine (with millimetres of noise) is measured about 15 times too narrow: its
    // forecast is not trusted where the history's spread (0.55 m/s RMS) reaches the
    // capacity (`an_unreliable_channel_is_judged_by_the_spread_of_its_history_too`), so it
    // may not clear at all; what it clears must be slow.
    for tc in commits {
        for k in 0..=200 {
            let t = tc + c.touchdown_s * k as f64 / 200.0;
            assert!(rate(t).abs() <= c.max_abs_heave_rate_mps, "heave too fast at {t}");
        }
    }
    assert!(out
        .iter()
        .any(|(_, d)| d.reason == DecisionReason::PredictedOutside
            || d.reason == DecisionReason::OutsideCapacity));
    // No deck height: refused, with its own reason, never cleared.
    let mut d = LandingDecider::new(c.clone()).unwrap();
    let out = run(&mut d, 0.0, 60.0, |t| {
        Some(DeckObservation {
            height_m: f64::NAN,
            ..sea(t, 0.3)
        })
    });
    assert!(out
        .iter()
        .all(|(_, d)| d.reason == DecisionReason::NoDeckHeave && d.state == DecisionState::Hold));
    // Heave off: angles only, a height is not needed.
    let mut d = LandingDecider::new(DecisionConfig {
        heave: HeaveUse::Off,
        ..c
    })
    .unwrap();
    let out = run(&mut d, 0.0, 120.0, |t| {
        Some(DeckObservation::angles(rough(t).roll_deg, rough(t).pitch_deg))
    });
    assert!(out.iter().filter(|(_, d)| d.new_commit).count() > 0);
}

/// A channel whose band has been measured more than `MAX_BAND_SCALE` times too narrow has
/// its rate judged also by the history's spread: the forecast may say the deck is still,
/// the history says how fast it moves (a campaign touched down three times into more than
/// 0.64 m/s of heave rate on bands scaled 3.4-200 times; docs/history.md, "A campaign of 2 016 approaches: three unsafe touchdowns into heave rate").
#[test]
fn an_unreliable_channel_is_judged_by_the_spread_of_its_history_too() {
    // The spread of a rate: a sine of amplitude A and angular frequency w has rate RMS
    // A w / sqrt(2).
    let t: Vec<f64> = (0..600).map(|k| k as f64 * 0.2).collect();
    let y = vec![
        t.iter().map(|&t| (0.5 * t).sin()).collect::<Vec<_>>(),
        vec![1.0; t.len()],
        t.iter().map(|&t| 2.0 * (0.25 * t).sin()).collect::<Vec<_>>(),
    ];
    let spread = rate_histories(&t, &y, [0.0; 3]).map(|h| h.spread);
    assert!((spread[0] - 0.5 / 2f64.sqrt()).abs() < 0.01, "{spread:?}");
    assert_eq!(spread[1], 0.0);
    assert!((spread[2] - 0.5 / 2f64.sqrt()).abs() < 0.01, "{spread:?}");
    // A decider's models on a calm sea, then the heave's band found 4 times too narrow.
    let (d, mut m, limits) = calm_sea_models();
    let c = d.config().clone();
    let times = || (0..=40).map(|k| 60.0 + 0.05 * k as f64);
    // Without the rates' misses in their own units (the case this test is about; see
    // `an_unreliable_rate_is_given_at_least_the_spread_of_its_own_misses` for the other).
    m.rate_miss_std = [f64::NAN; 3];
    let honest = exceedance_risk_as_measured(&d.config, &m, times(), &limits);
    assert!(
        honest < c.risk_per_touchdown,
        "a calm sea, honest bands: {honest}"
    );
    m.band_scale[2] = 4.0;
    m.guard_scale[2] = m.band_scale[2];
    let unreliable = exceedance_risk_as_measured(&d.config, &m, times(), &limits);
    let spread_alone = outside_probability(0.0, 0.5, c.max_abs_heave_rate_mps);
    assert!(unreliable >= spread_alone, "{unreliable} < {spread_alone}");
    assert!(unreliable > c.risk_per_touchdown);
    // Without a known spread, an unreliable channel clears nothing.
    m.rate_history[2] = RateHistory::spread_only(f64::NAN);
    assert!(exceedance_risk_as_measured(&d.config, &m, times(), &limits) >= 1.0);
    m.rate_history[2] = RateHistory::spread_only(0.5);
    // A scale of 3 or less is still a band to believe.
    m.band_scale[2] = MAX_BAND_SCALE;
    m.guard_scale[2] = m.band_scale[2];
    assert!(exceedance_risk_as_measured(&d.config, &m, times(), &limits) < c.risk_per_touchdown);
}

/// The history's own forecast of a rate (`RateHistory`): on a sine of angular frequency w
/// sampled as the fit samples it (0.2 and 0.3 s apart), the rate a lag L later regressed on
/// the rate now has coefficient cos(w L) and leaves |sin(w L)| of the rate's RMS; the
/// forecast starts from the newest rate, and beyond the lags regressed it is the spread
/// with a mean of zero. The decider keeps the newest rate as measured, frame by frame.
#[test]
fn the_history_forecasts_a_rate_from_its_newest_value() {
    let w = TAU / 9.0;
    let mut t = vec![0.0];
    while *t.last().unwrap() < 60.0 {
        let step = if t.len() % 3 == 0 { 0.3 } else { 0.2 };
        t.push(t.last().unwrap() + step);
    }
    let y = vec![t.iter().map(|&t| 2.0 * (w * t).sin()).collect::<Vec<_>>()];
    let [h, _, _] = rate_histories(&t, &y, [3.0; 3]);
    // Central differences over 0.4-0.5 s shrink a 9 s sine's rate by about 1 %; 60 s is not
    // a whole number of its periods.
    let rms = 2.0 * w / 2f64.sqrt();
    assert!((h.spread / rms - 1.0).abs() < 0.02, "{} against {rms}", h.spread);
    assert_eq!(h.lags.len(), 15);
    for (k, &(coefficient, left)) in h.lags.iter().enumerate() {
        let lag_s = (k + 1) as f64 * FIT_SPACING_S;
        assert!(
            (coefficient - (w * lag_s).cos()).abs() < 0.03,
            "lag {lag_s}: {coefficient}"
        );
        // What is left, raised to its bound over the seconds the pairs span (the first
        // pair's later rate at about 0.2 s + the lag, the last at the newest rate).
        let bound = upper_bound_factor(h.newest_t - 0.2 - lag_s);
        let expected = bound * (w * lag_s).sin().abs() * rms;
        assert!(
            (left - expected).abs() < 0.05 * expected + 0.01,
            "lag {lag_s}: {left} against {expected}"
        );
    }
    let (mean, std) = h.forecast(h.newest_t + 1.0);
    let (c5, s5) = h.lags[4];
    assert!((mean - c5 * h.newest).abs() < 1e-12 && (std - s5).abs() < 1e-12);
    // Within a spacing of the newest rate: the first lag's; beyond the regression: the spread.
    assert_eq!(
        h.forecast(h.newest_t + 0.05),
        (h.lags[0].0 * h.newest, h.lags[0].1)
    );
    assert_eq!(h.forecast(h.newest_t + 3.5), (0.0, h.spread));
    // A shorter history states more of what is left: its pairs are fewer pieces of
    // evidence (a second each).
    let bound = upper_bound_factor;
    assert!(bound(1.0) > bound(4.0) && bound(4.0) > bound(12.0) && bound(12.0) > bound(60.0));
    assert!(bound(60.0) > 1.0 && bound(60.0) < 1.1 && bound(4.0) > 1.3);
    let n = t.partition_point(|&ti| ti < 12.0);
    let [twelve, _, _] = rate_histories(&t[..n], &[y[0][..n].to_vec()], [3.0; 3]);
    let (lag, (_, left_60)) = (4, h.lags[4]);
    let left_12 = twelve.lags[lag].1;
    assert!(
        left_12 > 1.05 * left_60,
        "12 s of history state {left_12}, 60 s {left_60}"
    );
    // Too short a history for a lag's pairs: only the spread.
    let short = rate_histories(&t[..12], &[y[0][..12].to_vec()], [3.0; 3]);
    assert!(short[0].lags.is_empty() && short[0].spread > 0.0);
    assert_eq!(short[0].forecast(t[11]), (0.0, short[0].spread));
    assert_eq!(short[0].forecast(short[0].newest_t), (0.0, short[0].spread));

    // The decider measures the newest rate on every frame, between refits.
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    run(&mut d, 0.0, 60.05, |t| Some(sea(t, 0.3)));
    let m = d.tracking.models.as_ref().expect("fitted");
    let newest = &m.rate_history[HEAVE];
    assert!((newest.newest_t - 59.8).abs() < 1e-9, "{}", newest.newest_t);
    assert!(
        (newest.newest - heave_rate(59.8, 0.3)).abs() < 0.005,
        "{}",
        newest.newest
    );
}

/// An unreliable rate without misses of its own is judged from its newest value: a deck whose
/// heave rate was just measured small is cleared where the history's spread alone (0.5 m/s,
/// with a mean of zero) would not be; one measured near the limit is not.
#[test]
fn an_unreliable_rate_is_judged_from_its_newest_value() {
    let (d, mut m, limits) = calm_sea_models();
    let c = d.config().clone();
    let times = || (0..=40).map(|k| 60.0 + 0.05 * k as f64);
    m.rate_miss_std = [f64::NAN; 3];
    m.band_scale[HEAVE] = 4.0;
    m.guard_scale[HEAVE] = m.band_scale[HEAVE];
    assert!(exceedance_risk_as_measured(&d.config, &m, times(), &limits) > c.risk_per_touchdown);
    let regressed = |newest: f64| RateHistory {
        spread: 0.5,
        newest,
        newest_t: 59.9,
        lags: vec![(0.95, 0.05); 15],
    };
    m.rate_history[HEAVE] = regressed(0.05);
    assert!(exceedance_risk_as_measured(&d.config, &m, times(), &limits) < c.risk_per_touchdown);
    m.rate_history[HEAVE] = regressed(0.55);
    assert!(exceedance_risk_as_measured(&d.config, &m, times(), &limits) > 0.01);
    // Past the lags regressed (3 s after the newest rate), only the spread is known.
    m.rate_history[HEAVE] = regressed(0.05);
    let later = || (0..=40).map(|k| 63.0 + 0.05 * k as f64);
    assert!(exceedance_risk_as_measured(&d.config, &m, later(), &limits) > c.risk_per_touchdown);
}

/// The decider's band scales: values, rates, and whether every value and rate has its
/// evidence.
fn scales(d: &LandingDecider) -> ([f64; 3], [f64; 3], bool) {
    let BandScale {
        values,
        rates,
        checked,
        ..
    } = d.tracking.band.scale(d.channels);
    (values, rates, checked)
}

/// A decider after 60 s of a calm sea, its models with honest bands (scales 1) and rates'
/// spreads of 0.1 deg/s and 0.5 m/s, and the capacity's limits in `exceedance_risk`'s order.
fn calm_sea_models() -> (LandingDecider, Models<ArChannel>, [f64; 6]) {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    // Measured, with noise: a noise-free sea on the fit's grid is forecast exactly, and a
    // band of 1e-15 deg says nothing of the rules on it.
    run(&mut d, 0.0, 60.0, |t| Some(measured(sea(t, 0.3), t)));
    let mut m = d.tracking.models.clone().expect("fitted");
    let limits = d.config().capacity_limits();
    m.band_scale = [1.0; 3];
    m.guard_scale = m.band_scale;
    m.rate_band_scale = [1.0; 3];
    m.rate_history = [0.1, 0.1, 0.5].map(RateHistory::spread_only);
    // The rules on the band are tested on the band as the held-out misses scale it.
    m.widening = [1.0; 6];
    (d, m, limits)
}

/// For `early_window_s` after the decision could first clear, and again after a go-around,
/// a new clearance meets `early_risk_per_touchdown`; then `risk_per_touchdown`. A seeing
/// touchdown and its last chance are judged as before.
#[test]
fn the_first_clearances_look_for_a_deeper_calm() {
    let (mut d, _, _) = calm_sea_models();
    let c = d.config().clone();
    assert!(c.ar().early_risk_per_touchdown < c.risk_per_touchdown);
    d.commitment.early_since = None;
    assert_eq!(
        Judgement::commit(&d.config, d.commitment.early(&d.config, 60.0)).risk,
        Some(c.ar().early_risk_per_touchdown)
    );
    d.commitment.early_since = Some(40.0);
    let just_before = 40.0 + c.ar().early_window_s - 0.1;
    assert_eq!(
        Judgement::commit(&d.config, d.commitment.early(&d.config, just_before)).risk,
        Some(c.ar().early_risk_per_touchdown)
    );
    let after = 40.0 + c.ar().early_window_s + 0.1;
    assert_eq!(
        Judgement::commit(&d.config, d.commitment.early(&d.config, after)).risk,
        Some(c.risk_per_touchdown)
    );
    assert_eq!(Judgement::entry(&d.config).risk, Some(c.risk_per_touchdown));
    assert_eq!(Judgement::last_chance(&d.config).risk, Some(c.risk_per_touchdown));
    // A go-around starts the early window again.
    d.commitment.state = DecisionState::ClearToLand;
    d.commitment.commit_end = after + 1.0;
    let abort = d.transition(Err(DecisionReason::StaleData), after);
    assert_eq!(abort.state, DecisionState::Abort);
    assert_eq!(d.commitment.early_since, None);
    // Switched off, the first clearance is at `risk_per_touchdown`.
    let mut off = LandingDecider::new(tuned(|f| f.early_window_s = 0.0)).unwrap();
    off.commitment.early_since = Some(60.0);
    assert_eq!(
        Judgement::commit(&off.config, off.commitment.early(&off.config, 60.0)).risk,
        Some(c.risk_per_touchdown)
    );
    // On a stream, the decision first could clear before its first clearance, and the
    // first clearance comes no earlier than with the window switched off.
    let first_commit = |config: DecisionConfig| {
        let mut d = LandingDecider::new(config).unwrap();
        let mut first = None;
        for k in 0..1200 {
            let t = k as f64 * 0.1;
            let now = t + 0.005;
            if d.update(t, Some(sea(t, 0.3)), now).new_commit && first.is_none() {
                first = Some((now, d.commitment.early_since));
            }
        }
        first.expect("a calm sea is cleared within two minutes")
    };
    let (early_t, early_since) = first_commit(DecisionConfig::default());
    let (off_t, _) = first_commit(tuned(|f| f.early_window_s = 0.0));
    assert!(
        early_since.is_some_and(|since| since <= early_t),
        "{early_since:?} {early_t}"
    );
    assert!(early_t >= off_t, "{early_t} {off_t}");
}

/// A band measured between `SUSPECT_BAND_SCALE` and `MAX_BAND_SCALE` times too narrow, value
/// or rate, is suspect while its rate has no misses of its own; beyond, it is unreliable
/// (judged by its history), not suspect.
#[test]
fn a_band_within_reach_of_unreliable_is_suspect() {
    let (d, mut m, limits) = calm_sea_models();
    m.rate_miss_std = [f64::NAN; 3];
    assert!(!(0..3).any(|k| m.band_suspect(k)), "honest bands");
    m.band_scale[HEAVE] = 0.5 * (SUSPECT_BAND_SCALE + MAX_BAND_SCALE);
    m.guard_scale[HEAVE] = m.band_scale[HEAVE];
    assert!(m.band_suspect(HEAVE) && !m.band_suspect(ROLL));
    // A seeing touchdown believes the band; a new commitment judges the heave rate by the
    // history's spread (0.5 m/s) too, and does not clear on it.
    let times = || (0..=40).map(|k| 60.0 + 0.05 * k as f64);
    let risk = d.config().risk_per_touchdown;
    let judging = |unreliable_band_scale: f64| Judgement {
        unreliable_band_scale,
        ..Judgement::MEAN
    };
    assert!(exceedance_risk(&d.config, &m, times(), &limits, judging(MAX_BAND_SCALE)) < risk);
    assert!(exceedance_risk(&d.config, &m, times(), &limits, judging(SUSPECT_BAND_SCALE)) > risk);
    let commit = Judgement::commit(&d.config, d.commitment.early(&d.config, 60.0));
    assert!(!predicted_within(&d.config, &m, 60.0, 62.0, commit));
    assert!(predicted_within(
        &d.config,
        &m,
        60.0,
        62.0,
        Judgement::entry(&d.config)
    ));
    m.band_scale[HEAVE] = MAX_BAND_SCALE + 0.1;
    m.guard_scale[HEAVE] = m.band_scale[HEAVE];
    assert!(!m.band_suspect(HEAVE) && m.judged_by_history(HEAVE));
    m.band_scale[HEAVE] = 1.0;
    m.guard_scale[HEAVE] = m.band_scale[HEAVE];
    m.rate_band_scale[HEAVE] = MAX_BAND_SCALE;
    assert!(m.band_suspect(HEAVE));
    // Its rate's own misses stand for its error: nothing to suspect.
    m.rate_miss_std[HEAVE] = 0.05;
    assert!(!m.band_suspect(HEAVE));
}

/// A new commitment's judgement at 60 s with a band taken as unreliable where every other
/// judgement takes it (beyond `MAX_BAND_SCALE`, not `SUSPECT_BAND_SCALE`): what differs from
/// `Judgement::MEAN` on an unreliable band is then only how a commitment widens it.
fn widening_commit_judgement(d: &LandingDecider) -> Judgement {
    Judgement {
        unreliable_band_scale: MAX_BAND_SCALE,
        ..Judgement::commit(&d.config, d.commitment.early(&d.config, 60.0))
    }
}

/// A new commitment widens an angle whose band is unreliable by `UNRELIABLE_ANGLE_FACTOR`
/// on top of its measured scale (the same risk as the band that much wider, judged as
/// measured); an angle within `MAX_BAND_SCALE`, and every judgement but a commitment's, as
/// measured.
#[test]
fn a_new_commitment_widens_an_unreliable_angle_band() {
    let (d, mut m, limits) = calm_sea_models();
    let times = || (0..=40).map(|k| 60.0 + 0.05 * k as f64);
    let commit = widening_commit_judgement(&d);
    let as_measured = Judgement::MEAN;
    // Each angle's limit four unreliable deviations beyond its forecast's largest value:
    // near enough that a wider band costs risk.
    let unreliable = MAX_BAND_SCALE + 0.5;
    let mut tight = limits;
    for k in [ROLL, PITCH] {
        let track = &m.forecasts[k];
        let largest = times().map(|t| track.value(t).abs()).fold(0.0, f64::max);
        let widest = times().map(|t| track.std(t)).fold(0.0, f64::max);
        tight[k] = largest + 4.0 * unreliable * widest;
    }
    let risk = |m: &Models<ArChannel>, judgement: Judgement| {
        exceedance_risk(&d.config, m, times(), &tight, judgement)
    };
    for k in [ROLL, PITCH] {
        m.band_scale = [1.0; 3];
        m.guard_scale = m.band_scale;
        m.band_scale[k] = MAX_BAND_SCALE;
        m.guard_scale[k] = m.band_scale[k];
        assert_eq!(risk(&m, commit), risk(&m, as_measured), "within: as measured");
        m.band_scale[k] = unreliable;
        m.guard_scale[k] = m.band_scale[k];
        let widened = risk(&m, commit);
        assert!(widened > risk(&m, as_measured), "channel {k}");
        m.band_scale[k] = unreliable * UNRELIABLE_ANGLE_FACTOR;
        m.guard_scale[k] = m.band_scale[k];
        assert_eq!(widened, risk(&m, as_measured), "channel {k}");
    }
}

/// A new commitment takes the rate of a channel whose band is unreliable (here its value's,
/// measured more than `MAX_BAND_SCALE` times too narrow) as far off as its value: the same
/// risk as the rate's band measured that much too narrow; a channel within
/// `MAX_BAND_SCALE`, a rate band measured wider than the value's, and every judgement but
/// a commitment's, as measured; the spread of the rate's misses stays the floor.
#[test]
fn a_new_commitment_takes_an_unreliable_channels_rate_as_far_off_as_its_value() {
    let (d, m, limits) = calm_sea_models();
    // No autopilot errors: the rate's own deviation alone.
    let d = LandingDecider::new(DecisionConfig {
        vertical_speed_error_mps: 0.0,
        vehicle_attitude_error_deg: 0.0,
        ..d.config().clone()
    })
    .unwrap();
    let times = || (0..=40).map(|k| 60.0 + 0.05 * k as f64);
    let commit = widening_commit_judgement(&d);
    let as_measured = Judgement::MEAN;
    let unreliable = MAX_BAND_SCALE + 0.5;
    for k in [ROLL, PITCH, HEAVE] {
        let mut m = m.clone();
        let track = &m.forecasts[k];
        let largest = times().map(|t| track.rate(t).abs()).fold(0.0, f64::max);
        let widest = times().map(|t| track.rate_std(t)).fold(0.0, f64::max);
        // The angles out of reach, the rate's limit four of its stated deviations beyond
        // its largest forecast.
        let mut tight = limits;
        tight[..3].fill(1e3);
        tight[3 + k] = largest + 4.0 * widest;
        m.rate_miss_std[k] = 0.0;
        let risk = |m: &Models<ArChannel>, judgement: Judgement| {
            exceedance_risk(&d.config, m, times(), &tight, judgement)
        };
        m.band_scale[k] = MAX_BAND_SCALE;
        m.guard_scale[k] = m.band_scale[k];
        assert_eq!(
            risk(&m, commit),
            risk(&m, as_measured),
            "channel {k} within: as measured"
        );
        m.band_scale[k] = unreliable;
        m.guard_scale[k] = m.band_scale[k];
        let widened = risk(&m, commit);
        assert!(widened > 10.0 * risk(&m, as_measured), "channel {k}: {widened}");
        m.rate_band_scale[k] = unreliable;
        assert_eq!(widened, risk(&m, as_measured), "channel {k}");
        // A rate band measured wider than the value's: as measured.
        m.rate_band_scale[k] = 2.0 * unreliable;
        assert_eq!(risk(&m, commit), risk(&m, as_measured), "channel {k}");
        // The misses' spread wider still: it is the deviation either way.
        m.rate_band_scale[k] = 1.0;
        m.rate_miss_std[k] = 10.0 * unreliable * widest;
        assert_eq!(risk(&m, commit), risk(&m, as_measured), "channel {k}");
    }
}

/// A channel whose band is unreliable (measured more than `MAX_BAND_SCALE` times too
/// narrow) has its rate given at least the spread of its recent misses in its own unit,
/// whatever each fit stated; with that spread measured, it is judged by it rather than by
/// the history's spread (a nearly noise-free heave states mm/s; its misses are what it is
/// worth). An honest band is left as it is.
#[test]
fn an_unreliable_rate_is_given_at_least_the_spread_of_its_own_misses() {
    let (d, mut m, limits) = calm_sea_models();
    let c = d.config().clone();
    let times = || (0..=40).map(|k| 60.0 + 0.05 * k as f64);
    let stated = m.forecasts[HEAVE].rate_std(60.5);
    m.rate_miss_std = [10.0 * stated + 0.01; 3];
    assert_eq!(m.rate_std(HEAVE, 60.5), stated, "an honest band: as stated");
    // The heave's value band measured 20 times too narrow, its rate's misses 0.02 m/s: a
    // calm sea's forecast to believe at that spread, not at the history's 0.5 m/s.
    m.band_scale[HEAVE] = 20.0;
    m.guard_scale[HEAVE] = m.band_scale[HEAVE];
    assert_eq!(
        m.rate_std(HEAVE, 60.5),
        10.0 * stated + 0.01,
        "the misses' spread"
    );
    m.rate_miss_std[HEAVE] = 0.02;
    let small_misses = exceedance_risk_as_measured(&d.config, &m, times(), &limits);
    assert!(small_misses < c.risk_per_touchdown, "{small_misses}");
    // Misses of 0.3 m/s: the heave rate to come may well be beyond 0.6 m/s.
    m.rate_miss_std[HEAVE] = 0.3;
    let large_misses = exceedance_risk_as_measured(&d.config, &m, times(), &limits);
    assert!(large_misses > 0.01, "{large_misses}");
    // Without the spread of its misses, it falls back on the history's spread.
    m.rate_miss_std[HEAVE] = f64::NAN;
    let spread_alone = outside_probability(0.0, 0.5, c.max_abs_heave_rate_mps);
    assert!(exceedance_risk_as_measured(&d.config, &m, times(), &limits) >= spread_alone);
}

/// The autopilot's vertical-speed error is in every measured heave rate and in none of the
/// forecast's misses: stated (`vertical_speed_error_mps`), it widens the heave rate's
/// deviation in quadrature. A deck the forecast keeps 4 sigma inside the heave-rate limit is
/// cleared with the error stated as 0, and not with 0.1 m/s of it.
#[test]
fn the_autopilots_vertical_speed_error_widens_the_heave_rate_band() {
    let (d, m, mut limits) = calm_sea_models();
    let times = || (0..=40).map(|k| 60.0 + 0.05 * k as f64);
    let stating = |e: f64| {
        LandingDecider::new(DecisionConfig {
            vertical_speed_error_mps: e,
            ..d.config().clone()
        })
        .unwrap()
    };
    let heave = &m.forecasts[HEAVE];
    limits[5] = times()
        .map(|t| heave.rate(t).abs() + 4.0 * m.rate_std(HEAVE, t))
        .fold(0.0, f64::max);
    let risk = d.config().risk_per_touchdown;
    let exact = exceedance_risk_as_measured(&stating(0.0).config, &m, times(), &limits);
    assert!(exact < risk, "exact vertical speed: {exact}");
    let biased = exceedance_risk_as_measured(&stating(0.1).config, &m, times(), &limits);
    assert!(
        biased > risk && biased > 10.0 * exact,
        "0.1 m/s of error: {biased}"
    );
    assert!(DecisionConfig {
        vertical_speed_error_mps: -0.1,
        ..DecisionConfig::default()
    }
    .validate()
    .is_err());
}

/// The autopilot's roll and pitch error is in every measured deck angle and in none of the
/// forecast's misses: stated (`vehicle_attitude_error_deg`), it widens the angle bands in
/// quadrature, tilt too. A roll the forecast keeps 4 sigma inside its limit is cleared
/// with the error stated as 0, and not with 0.5 deg of it; the same for pitch, and for a
/// tilt a degree inside its limit.
#[test]
fn the_autopilots_attitude_error_widens_the_angle_bands() {
    let (d, m, limits) = calm_sea_models();
    let times = || (0..=40).map(|k| 60.0 + 0.05 * k as f64);
    let stating = |e: f64| {
        LandingDecider::new(DecisionConfig {
            vehicle_attitude_error_deg: e,
            ..d.config().clone()
        })
        .unwrap()
    };
    let risk = d.config().risk_per_touchdown;
    for k in [ROLL, PITCH] {
        let track = &m.forecasts[k];
        let mut tight = limits;
        tight[k] = times()
            .map(|t| track.value(t).abs() + 4.0 * m.band_scale[k] * track.std(t))
            .fold(0.0, f64::max);
        let exact = exceedance_risk_as_measured(&stating(0.0).config, &m, times(), &tight);
        assert!(exact < risk, "channel {k}, exact attitude: {exact}");
        let biased = exceedance_risk_as_measured(&stating(0.5).config, &m, times(), &tight);
        assert!(
            biased > risk && biased > 10.0 * exact,
            "channel {k}, 0.5 deg: {biased}"
        );
    }
    // Tilt: both angles' bands widen. (Its bound splits the limit between the angles in
    // steps: a degree beyond the forecast's tilt leaves room for the split.)
    let mut tilted = limits;
    tilted[2] = 1.0
        + times()
            .map(|t| tilt_deg(m.forecasts[ROLL].value(t), m.forecasts[PITCH].value(t)))
            .fold(0.0, f64::max);
    let exact = exceedance_risk_as_measured(&stating(0.0).config, &m, times(), &tilted);
    let biased = exceedance_risk_as_measured(&stating(0.5).config, &m, times(), &tilted);
    assert!(
        biased > risk && biased > 10.0 * exact,
        "tilt: {exact} -> {biased}"
    );
    assert!(DecisionConfig {
        vehicle_attitude_error_deg: f64::NAN,
        ..DecisionConfig::default()
    }
    .validate()
    .is_err());
}

/// The misses' spread is their `BAND_EVIDENCE_QUANTILE` in the rate's own unit as a normal
/// deviation, measured only with `MIN_BAND_EVIDENCE` of them spanning
/// `MIN_RATE_EVIDENCE_SPAN_S`.
#[test]
fn the_rates_misses_spread_is_measured_in_its_own_unit() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    let miss = |t: f64, heave_rate_mps: f64| BandMiss {
        t_s: t,
        z: [1.0, 1.0, 1.0, 1.0, 1.0, 100.0 * heave_rate_mps],
        abs: [0.1, 0.1, 0.01, 0.1, 0.1, heave_rate_mps],
    };
    let mut bunched = LandingDecider::new(DecisionConfig::default()).unwrap();
    for k in 0..2 * MIN_BAND_EVIDENCE {
        bunched.tracking.band.misses.push_back(miss(0.1 * k as f64, 0.01));
    }
    assert!(
        bunched.tracking.band.scale(bunched.channels).rate_miss_std[HEAVE].is_nan(),
        "all within 4 s"
    );
    for k in 0..MIN_BAND_EVIDENCE - 1 {
        d.tracking.band.misses.push_back(miss(0.25 * k as f64, 0.01));
    }
    assert!(
        d.tracking.band.scale(d.channels).rate_miss_std[HEAVE].is_nan(),
        "too few"
    );
    // 40 misses over 9.75 s: 39 of 0.01 m/s and one of 0.2 (beyond the 97.5th percentile).
    for k in MIN_BAND_EVIDENCE - 1..39 {
        d.tracking.band.misses.push_back(miss(0.25 * k as f64, 0.01));
    }
    d.tracking.band.misses.push_back(miss(4.0, 0.2));
    let z = evidence_z();
    assert!((z - 2.241_402_727_604_947).abs() < 1e-8, "Phi^-1(0.9875): {z}");
    let s = d.tracking.band.scale(d.channels);
    assert!((s.rate_miss_std[HEAVE] - 0.01 / z).abs() < 1e-12, "{s:?}");
    assert!((s.rate_miss_std[ROLL] - 0.1 / z).abs() < 1e-12, "{s:?}");
    // Two of 0.2: the 97.5th percentile of 41 is the 40th.
    d.tracking.band.misses.push_back(miss(4.1, 0.2));
    let s = d.tracking.band.scale(d.channels);
    assert!((s.rate_miss_std[HEAVE] - 0.2 / z).abs() < 1e-12, "{s:?}");
    // The warm-up's backtests are evidence of the band's scale, not of this spread.
    let mut fresh = LandingDecider::new(DecisionConfig::default()).unwrap();
    for k in 0..2 * MIN_BAND_EVIDENCE {
        fresh
            .tracking
            .band
            .backtests
            .push_back(miss(0.1 * k as f64, 0.01));
    }
    let s = fresh.tracking.band.scale(fresh.channels);
    assert!(s.checked, "{s:?}");
    assert!(s.rate_miss_std.iter().all(|x| x.is_nan()), "{s:?}");
}

/// A value band is scaled to hold `VALUE_BAND_EVIDENCE_QUANTILE` of its misses, narrower than
/// stated down to `MIN_VALUE_BAND_SCALE`; a rate band to hold `BAND_EVIDENCE_QUANTILE`, never
/// narrower than stated; the guards read a value band as a rate's (`BandScale::value_guards`).
#[test]
fn a_value_band_is_as_wide_as_its_misses_a_rate_band_never_narrower_than_stated() {
    let scaled = |step: f64| {
        let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
        // 100 misses of step, 2 step, ..., 100 step stated deviations, every quantity.
        for k in 1..=100 {
            let z = step * k as f64;
            d.tracking.band.misses.push_back(BandMiss {
                t_s: 0.1 * k as f64,
                z: [z; 6],
                abs: [z; 6],
            });
        }
        d.tracking.band.scale(d.channels)
    };
    // Misses within about half the stated deviations: the value bands are narrowed as far
    // as they may be, the rate bands are left as stated.
    let s = scaled(0.01);
    assert!(s.checked);
    assert_eq!(s.values, [MIN_VALUE_BAND_SCALE; 3], "{s:?}");
    assert_eq!(s.rates, [1.0; 3], "{s:?}");
    assert_eq!(s.value_guards, [1.0; 3], "the guards judge as before: {s:?}");
    // Misses wider than stated: the values at their 95th of 100 (2.85), the rates at their
    // 97.5th (the 98th, 2.94).
    let s = scaled(0.03);
    for k in 0..3 {
        assert!((s.values[k] - 2.85 / Z95).abs() < 1e-12, "{s:?}");
        assert!((s.rates[k] - 2.94 / Z95).abs() < 1e-12, "{s:?}");
        assert!((s.value_guards[k] - 2.94 / Z95).abs() < 1e-12, "{s:?}");
    }
    // A rate without misses of its own is as far off as its value as the guards read it: the
    // heave's misses 38 of 2 bands and 2 of 3.5 bands, its width 2, its guards 3.5.
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    for k in 0..40 {
        let heave = if k < 38 { 2.0 } else { 3.5 } * Z95;
        d.tracking.band.misses.push_back(BandMiss::new(
            0.1 * k as f64,
            [Z95, Z95, heave, f64::NAN, f64::NAN, f64::NAN],
        ));
    }
    let s = d.tracking.band.scale(d.channels);
    assert!(
        (s.values[HEAVE] - 2.0).abs() < 1e-12 && (s.value_guards[HEAVE] - 3.5).abs() < 1e-12,
        "{s:?}"
    );
    assert!(
        (s.rates[HEAVE] - 3.5).abs() < 1e-12,
        "unreliable, as before: {s:?}"
    );
    // Between: a value band at its misses, above the least.
    let s = scaled(0.015);
    assert!(
        (s.values[0] - 1.425 / Z95).abs() < 1e-12 && s.values[0] > MIN_VALUE_BAND_SCALE,
        "{s:?}"
    );
}

/// Until a rate's band has evidence of its own, it is taken to be as far off as its value's
/// has been measured to be (a campaign's sea cleared 0.2 s after the warm-up on the prior
/// scale alone, with the heave's value band 3.9 times too narrow, and touched down into
/// 0.678 m/s of heave rate; docs/history.md, "The first clearance after the warm-up"), and
/// nothing is cleared on it; once it has its own, that stands and clears.
#[test]
fn a_rate_band_without_evidence_is_as_far_off_as_its_value_band() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    assert_eq!(d.channels, 3);
    // The heave's values missed by three times their stated band, the angles' by their band;
    // no rate measured yet.
    let values_only = [Z95, Z95, 3.0 * Z95, f64::NAN, f64::NAN, f64::NAN];
    for k in 0..2 * MIN_BAND_EVIDENCE {
        d.tracking
            .band
            .misses
            .push_back(BandMiss::new(0.1 * k as f64, values_only));
    }
    let (values, rates, checked) = scales(&d);
    assert_eq!(values[..2], [1.0; 2]);
    assert!((values[2] - 3.0).abs() < 1e-12, "{values:?}");
    assert_eq!(rates[..2], [PRIOR_BAND_SCALE; 2], "honest values: the prior");
    assert!(
        (rates[2] - 3.0).abs() < 1e-12,
        "the heave's value scale: {rates:?}"
    );
    assert!(
        !checked,
        "every value has its evidence, no rate has: not cleared on"
    );
    // The rates' own evidence arrives: small misses, one short of enough for the heave rate.
    for k in 0..MIN_BAND_EVIDENCE {
        let heave_rate = if k + 1 < MIN_BAND_EVIDENCE { 0.5 } else { f64::NAN };
        d.tracking.band.misses.push_back(BandMiss::new(
            5.0 + 0.1 * k as f64,
            [Z95, Z95, 3.0 * Z95, 0.5, 0.5, heave_rate],
        ));
    }
    let (_, rates, checked) = scales(&d);
    assert_eq!(rates[..2], [1.0; 2], "measured small: never below the stated");
    assert!(
        (rates[2] - 3.0).abs() < 1e-12,
        "one short: still the value's {rates:?}"
    );
    assert!(
        !checked,
        "the heave rate one short of its own evidence: not cleared on"
    );
    d.tracking
        .band
        .misses
        .push_back(BandMiss::new(7.0, [Z95, Z95, 3.0 * Z95, 0.5, 0.5, 0.5]));
    let (_, rates, checked) = scales(&d);
    assert_eq!(rates[2], 1.0, "its own evidence stands");
    assert!(checked, "every value and rate has its own evidence");
}

/// Each fit checked against what followed gives its rates' misses as well as its values':
/// a fit is checked once the rates of its whole held-out span are measured. Checked at
/// `holdout_s` instead, a fit refitted every second gave rate misses only when a frame's
/// rounding made it the one 3 s old, and a rate's band cleared on its value's scale.
#[test]
fn every_checked_fit_measures_its_rates_misses_too() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    run(&mut d, 0.0, 60.0, |t| Some(measured(sea(t, 0.3), t)));
    let count = |k: usize| {
        d.tracking
            .band
            .misses
            .iter()
            .filter(|m| m.z[k].is_finite())
            .count()
    };
    let (values, rates) = (count(HEAVE), count(3 + HEAVE));
    // A fit a second at 10 Hz: its value's misses over the last half of the held-out span, its
    // rate's over the last quarter.
    let fits = BAND_MEMORY_S / d.config().ar().refit_interval_s;
    assert!(values as f64 >= 0.8 * fits * 10.0, "{values} value misses");
    assert!(
        2 * rates + 2 >= values && rates >= MIN_BAND_EVIDENCE,
        "{rates} rate misses against {values} value misses"
    );
    assert!(scales(&d).2, "checked on the real misses alone");
}

/// A fit is kept until it is old enough to be checked, however often the models are
/// refitted: at a refit every 0.1 s the fits were dropped 2.2 s old, before their check at
/// 2.5 s, and no band was ever checked.
#[test]
fn a_fast_refit_still_checks_its_band() {
    let config = tuned(|f| f.refit_interval_s = 0.1);
    let mut d = LandingDecider::new(config).unwrap();
    run(&mut d, 0.0, 40.0, |t| Some(measured(sea(t, 0.3), t)));
    assert!(scales(&d).2, "checked on its own misses");
    assert!(d.tracking.band.misses.iter().any(|m| m.z[3 + HEAVE].is_finite()));
}

/// The warm-up's backtests stand in for the real fits' misses of each quantity while those
/// are too few; then the real ones alone count.
#[test]
fn backtests_stand_in_only_until_the_real_misses_suffice() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    let far_off = [4.0 * Z95; 6];
    for k in 0..2 * MIN_BAND_EVIDENCE {
        d.tracking
            .band
            .backtests
            .push_back(BandMiss::new(0.1 * k as f64, far_off));
    }
    let (values, rates, checked) = scales(&d);
    for s in values.iter().chain(&rates) {
        assert!(
            (s - 4.0).abs() < 1e-12,
            "the backtests' scale: {values:?} {rates:?}"
        );
    }
    assert!(checked, "the backtests are evidence");
    // Real misses of the values, honest, and enough: they alone count for the values; the
    // rates, with no real misses of their own yet, are still judged on the backtests.
    for k in 0..MIN_BAND_EVIDENCE {
        d.tracking.band.misses.push_back(BandMiss::new(
            5.0 + 0.1 * k as f64,
            [Z95, Z95, Z95, f64::NAN, f64::NAN, f64::NAN],
        ));
    }
    let (values, rates, checked) = scales(&d);
    assert_eq!(values, [1.0; 3]);
    assert_eq!(
        rates, [4.0; 3],
        "the backtests' 4 until the rates' own misses suffice"
    );
    assert!(checked);
    // The rates' own misses, honest, and enough: they alone count.
    for k in 0..MIN_BAND_EVIDENCE {
        d.tracking
            .band
            .misses
            .push_back(BandMiss::new(7.0 + 0.1 * k as f64, [Z95; 6]));
    }
    let (values, rates, checked) = scales(&d);
    assert_eq!((values, rates), ([1.0; 3], [1.0; 3]));
    assert!(checked);
}

/// The band is checked at the first fit, on the fits the decider would have made before
/// (not two refits later): a calm sea clears within `holdout_s` of the warm-up's end, and
/// only into calm windows.
#[test]
fn the_warm_ups_backtests_check_the_band_at_the_first_fit() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    let c = d.config().clone();
    let mut out = run(&mut d, 0.0, c.ar().min_history_s + 0.15, |t| {
        Some(measured(sea(t, 0.3), t))
    });
    let m = d.tracking.models.as_ref().expect("fitted at the warm-up's end");
    assert!(m.band_checked, "checked at the first fit");
    assert!(d.tracking.band.misses.is_empty(), "no real fit is old enough yet");
    assert!(d.tracking.band.backtests.len() >= 2 * MIN_BAND_EVIDENCE);
    out.extend(run(&mut d, c.ar().min_history_s + 0.2, 30.0, |t| {
        Some(measured(sea(t, 0.3), t))
    }));
    let first = out.iter().find(|(_, d)| d.new_commit).map(|(t, _)| *t);
    assert!(
        first.is_some_and(|t| t >= c.ar().min_history_s && t < c.ar().min_history_s + c.ar().holdout_s),
        "first clearance {first:?}"
    );
    let tc = first.unwrap_or_default();
    let mut t = tc;
    while t <= tc + c.touchdown_s {
        let deck = sea(t, 0.3);
        assert!(deck.roll_deg.abs() <= c.max_abs_roll_deg && deck.pitch_deg.abs() <= c.max_abs_pitch_deg);
        assert!(
            heave_rate(t, 0.3).abs() <= c.max_abs_heave_rate_mps,
            "unsafe at {t}"
        );
        t += 0.01;
    }
}

/// The frozen camera: one image again and again, on a timeline that moves on. Never
/// cleared; once the input moves again, the history is learnt afresh.
#[test]
fn a_frozen_input_never_clears_and_is_learnt_afresh_after() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    run(&mut d, 0.0, 40.0, |t| Some(sea(t, 0.3)));
    let still = sea(40.0, 0.3);
    let out = run(&mut d, 40.0, 110.0, |_| Some(still));
    // The first value is the true one and the second its first repeat (a clearance may go
    // on through them); from the third identical input on it is frozen: never CLEAR.
    assert!(out[2..]
        .iter()
        .all(|(_, d)| d.state != DecisionState::ClearToLand));
    assert!(out[2..]
        .iter()
        .all(|(_, d)| d.reason == DecisionReason::FrozenInput));
    let out = run(&mut d, 110.0, 112.0, |t| Some(sea(t, 0.3)));
    assert!(out.iter().all(|(_, d)| d.reason == DecisionReason::Warmup));
    let c = DecisionConfig {
        frozen_input_count: 1,
        ..Default::default()
    };
    assert_eq!(c.validate().unwrap_err().field, "frozen_input_count");
}

/// One frame stamped far in the future, then the true timeline again: held with
/// `clock-jump`, then a new timeline after three, without a restart.
#[test]
fn a_clock_jump_is_recovered_from() {
    let mut d = LandingDecider::new(DecisionConfig::default()).unwrap();
    run(&mut d, 0.0, 30.0, |t| Some(sea(t, 0.3)));
    let r = d.update(1e6, Some(sea(30.0, 0.3)), 1e6 + 0.005);
    assert_ne!(r.state, DecisionState::ClearToLand);
    let out = run(&mut d, 30.1, 150.0, |t| Some(sea(t, 0.3)));
    let reasons: Vec<_> = out.iter().map(|(_, d)| d.reason).collect();
    assert_eq!(reasons[..3], [DecisionReason::ClockJump; 3]);
    assert_eq!(reasons[3], DecisionReason::Warmup);
    assert!(
        out.iter().any(|(_, d)| d.new_commit),
        "cleared again after a new warm-up: {:?}",
        &reasons[200..]
    );
    // A capture stamped in the future on the monotonic clock (negative age).
    let r = d.update_at_capture(150.1, Some(sea(150.1, 0.3)), -1.0);
    assert_eq!(r.reason, DecisionReason::ClockJump);
}

#[test]
fn config_errors_name_the_field() {
    let c = DecisionConfig {
        touchdown_s: -1.0,
        ..Default::default()
    };
    assert_eq!(c.validate().unwrap_err().field, "touchdown_s");
    // Bounded above too: these size loops, buffers and timers.
    for (c, key) in [
        (
            DecisionConfig {
                touchdown_s: 1e9,
                ..Default::default()
            },
            "touchdown_s",
        ),
        (tuned(|f| f.horizon_s = 1e12), "forecast.horizon_s"),
        (
            DecisionConfig {
                max_age_ms: 1e300,
                ..Default::default()
            },
            "max_age_ms",
        ),
        (tuned(|f| f.early_window_s = 1e6), "forecast.early_window_s"),
        (tuned(|f| f.early_window_s = -1.0), "forecast.early_window_s"),
        (
            DecisionConfig {
                vehicle_attitude_error_deg: -0.1,
                ..Default::default()
            },
            "vehicle_attitude_error_deg",
        ),
        (
            tuned(|f| f.early_risk_per_touchdown = 2e-3),
            "forecast.early_risk_per_touchdown",
        ),
    ] {
        assert_eq!(c.validate().unwrap_err().field, key);
    }
}

/// Late or stuck data cannot hold a committed touchdown open: frames with no deck that
/// arrive late abort (stale, not missing); a source clock that stops while no deck is seen
/// aborts; one ride-through budget per commitment, however it is split; a fresh
/// measurement during a gap's recovery that the model misses aborts.
#[test]
fn late_or_stuck_data_never_keeps_a_touchdown_clear() {
    // Late frames without a deck (400 ms, past max_age_ms = 300).
    let (mut d, t0) = committed(DecisionConfig::default());
    let r = d.update_at_capture(t0 + 0.1, None, 0.4);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::Abort, DecisionReason::StaleData)
    );
    let (mut d, t0) = committed(DecisionConfig::default());
    let r = d.update_at_capture(t0 + 0.1, Some(DeckObservation::new(0.0, 0.0, f64::NAN)), 0.4);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::Abort, DecisionReason::StaleData)
    );
    // A stuck source clock with no deck: the first blind frame rides through, the same
    // time again does not.
    let (mut d, t0) = committed(DecisionConfig::default());
    assert_eq!(
        d.update_at_capture(t0 + 0.1, None, 0.01).reason,
        DecisionReason::RideThrough
    );
    assert_eq!(
        d.update_at_capture(t0 + 0.1, None, 0.01).state,
        DecisionState::Abort
    );
    // Chained spells share one budget (1 s): 0.6 s blind, one good frame, 0.6 s blind.
    let (mut d, t0) = committed(DecisionConfig::default());
    let mut t = t0;
    let mut states = Vec::new();
    for k in 1..=13 {
        t = t0 + 0.1 * k as f64;
        let deck = (k == 7).then(|| sea(t, 0.8));
        states.push(d.update_at_capture(t, deck, 0.01).state);
    }
    assert!(
        states[..10].iter().all(|s| *s == DecisionState::ClearToLand),
        "{states:?}"
    );
    assert_eq!(states.last(), Some(&DecisionState::Abort), "{states:?} until {t}");
    // A gap during the touchdown, then a fresh measurement 7 deg off the model: abort.
    let (mut d, t0) = committed(DecisionConfig::default());
    let t = t0 + 0.7;
    let s = sea(t, 0.8);
    let r = d.update_at_capture(
        t,
        Some(DeckObservation::new(s.roll_deg + 7.0, s.pitch_deg, s.height_m)),
        0.01,
    );
    assert_eq!(r.state, DecisionState::Abort, "{r:?}");
    // ... while a measurement the model expects in the same gap rides through.
    let (mut d, t0) = committed(DecisionConfig::default());
    let r = d.update_at_capture(t0 + 0.7, Some(sea(t0 + 0.7, 0.8)), 0.01);
    assert_eq!(
        (r.state, r.reason),
        (DecisionState::ClearToLand, DecisionReason::RideThrough)
    );
}

/// No key can switch a check off: each is refused, by name, just past its bound (and a
/// NaN); the cross-key rules name the key that defeats the other.
#[test]
fn no_configuration_switches_a_safety_check_off() {
    for &(key, max, _) in SAFETY_BOUNDS {
        for bad in [max * 1.01 + 1e-9, f64::NAN] {
            let mut c = DecisionConfig::default();
            *c.field_mut(key).unwrap() = bad;
            let e = c.validate().unwrap_err();
            assert_eq!(e.field, key, "{key} = {bad}: {e}");
        }
    }
    for (c, key) in [
        (
            DecisionConfig {
                max_abs_roll_rate_dps: 25.0,
                max_plausible_rate_dps: 20.0,
                ..Default::default()
            },
            "max_plausible_rate_dps",
        ),
        (tuned(|f| f.horizon_s = 1.0), "forecast.horizon_s"),
        (tuned(|f| f.cross_order = 97), "forecast.cross_order"),
        (
            DecisionConfig {
                frozen_input_count: MAX_FROZEN_INPUT_COUNT + 1,
                ..Default::default()
            },
            "frozen_input_count",
        ),
        (
            DecisionConfig {
                ride_through_ms: 2500.0,
                touchdown_s: 5.0,
                ..Default::default()
            },
            "ride_through_ms",
        ),
    ] {
        assert_eq!(c.validate().unwrap_err().field, key);
    }
    for &(key, max, _) in FORECAST_SAFETY_BOUNDS {
        for bad in [max * 1.01 + 1e-9, f64::NAN] {
            let mut c = DecisionConfig::default();
            *c.ar_mut().field_mut(key).unwrap() = bad;
            let e = c.validate().unwrap_err();
            assert_eq!(e.field, format!("forecast.{key}"), "{key} = {bad}: {e}");
        }
    }
    // The defaults are within every bound.
    DecisionConfig::default().validate().unwrap();
}

/// [`exceedance_risk`] with bands judged as measured (every judgement's but a new commitment's).
fn exceedance_risk_as_measured(
    c: &DecisionConfig,
    m: &Models<ArChannel>,
    times: impl Iterator<Item = f64>,
    limits: &[f64; 6],
) -> f64 {
    exceedance_risk(c, m, times, limits, Judgement::MEAN)
}

/// The default configuration with the forecaster's tuning changed by `change`.
fn tuned(change: impl FnOnce(&mut ArForecastConfig)) -> DecisionConfig {
    let mut c = DecisionConfig::default();
    change(c.ar_mut());
    c
}

/// A forecaster of one's own (ARCHITECTURE.md, "Adding a forecaster"): persistence, the newest
/// sample held, its rate the newest difference, its deviation growing with the square root of
/// the horizon from the spread of one step's change. The decider calibrates its band and
/// judges it like any other: it clears a calm sea, only ever into touchdowns within the
/// capacity, and not a rough one.
#[derive(Debug, Clone)]
struct HeldForecaster;

#[derive(Debug, Clone)]
struct Held {
    channel: usize,
    t0: f64,
    value: f64,
    rate: f64,
    step_std: f64,
    step_s: f64,
}

impl crate::forecast::ChannelForecast for Held {
    fn t0(&self) -> f64 {
        self.t0
    }
    fn value(&self, t: f64) -> f64 {
        self.value + self.rate * (t - self.t0)
    }
    fn rate(&self, _t: f64) -> f64 {
        self.rate
    }
    fn std(&self, t: f64) -> f64 {
        self.step_std * ((t - self.t0).max(0.0) / self.step_s).sqrt().max(1.0)
    }
    fn rate_std(&self, t: f64) -> f64 {
        self.std(t) / self.step_s
    }
    fn advanced(&self, t: &[f64], y: &[&[f64]]) -> Option<Self> {
        let y = y.get(self.channel)?;
        let n = t.len();
        (n >= 2).then(|| Held {
            t0: t[n - 1],
            value: y[n - 1],
            rate: (y[n - 1] - y[n - 2]) / (t[n - 1] - t[n - 2]),
            ..self.clone()
        })
    }
}

impl crate::forecast::Forecaster for HeldForecaster {
    type Channel = Held;
    fn fit(&self, t: &[f64], y: &[&[f64]], _horizon_s: f64) -> Option<Vec<Held>> {
        let n = t.len();
        if n < 3 {
            return None;
        }
        let fit_one = |channel: usize, yk: &[f64]| {
            let steps: Vec<f64> = yk.windows(3).map(|w| w[2] - 2.0 * w[1] + w[0]).collect();
            let step_std = (steps.iter().map(|s| s * s).sum::<f64>() / steps.len() as f64).sqrt();
            let step_s = (t[n - 1] - t[0]) / (n - 1) as f64;
            Held {
                channel,
                t0: t[n - 1],
                value: yk[n - 1],
                rate: 0.0,
                step_std,
                step_s,
            }
            .advanced(t, y)
        };
        y.iter().enumerate().map(|(k, yk)| fit_one(k, yk)).collect()
    }
    fn state_span_s(&self) -> f64 {
        1.0
    }
}

#[test]
fn a_forecaster_of_ones_own_is_calibrated_and_judged_like_the_autoregression() {
    let c = DecisionConfig::default();
    let clearances = |scale: f64| {
        let mut d = Decider::with_forecaster(c.clone(), HeldForecaster).unwrap();
        let out = run(&mut d, 0.0, 300.0, |t| Some(measured(sea(t, scale), t)));
        assert!(d.forecast(299.95).is_some_and(|f| f.band95[ROLL] > 0.0));
        out.iter()
            .filter(|(_, r)| r.new_commit)
            .map(|(t, _)| *t)
            .collect::<Vec<f64>>()
    };
    let calm = clearances(0.1);
    assert!(!calm.is_empty(), "a calm sea is cleared");
    for t0 in calm {
        let mut t = t0;
        while t <= t0 + c.touchdown_s {
            let deck = sea(t, 0.1);
            assert!(deck.roll_deg.abs() <= c.max_abs_roll_deg && deck.pitch_deg.abs() <= c.max_abs_pitch_deg);
            t += 0.05;
        }
    }
    assert!(
        clearances(1.5).is_empty(),
        "a rough sea is not cleared on persistence"
    );
}
