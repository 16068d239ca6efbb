//! The risk judge: whether the forecast keeps the deck within the capacity over a touchdown at
//! the accepted risk (a union bound of normal tails per limit, with the band's calibration),
//! how each judgement treats the forecast ([`Judgement`]), and the next calm window.

use super::band::{MAX_BAND_SCALE, SUSPECT_BAND_SCALE, UNRELIABLE_ANGLE_FACTOR};
use super::models::Models;
use super::{DecisionConfig, HEAVE, PITCH, ROLL};
use crate::forecast::ChannelForecast;

/// The forecast is judged at instants this far apart (s).
pub(super) const STEP_S: f64 = 0.05;

/// How a judgement treats the forecast: the accepted risk (None: the forecast's mean is judged
/// as it is), and how far a band that proved too narrow is trusted.
#[derive(Debug, Clone, Copy)]
pub(super) struct Judgement {
    /// The accepted probability of leaving the capacity (see [`exceedance_risk`]); None: the
    /// forecast's mean is judged as it is.
    pub(super) risk: Option<f64>,
    /// A channel's band measured more than this many times too narrow, its rate without misses
    /// of its own, has its rate judged by its history too (`Models::judged_by_history_above`).
    pub(super) unreliable_band_scale: f64,
    /// What the deviation of an angle (roll, pitch) whose value band has been measured more
    /// than `MAX_BAND_SCALE` times too narrow is multiplied by, on top of its measured scale
    /// (1: judged as measured; a new commitment's: `UNRELIABLE_ANGLE_FACTOR`).
    pub(super) unreliable_angle_factor: f64,
    /// Whether the rate of a channel whose band is unreliable is scaled at least as much as its
    /// value's band (`Models::rate_std_judging`; a new commitment's).
    pub(super) rate_as_value: bool,
}

impl Judgement {
    /// The forecast's mean as it is, bands as measured.
    pub(super) const MEAN: Self = Self {
        risk: None,
        unreliable_band_scale: MAX_BAND_SCALE,
        unreliable_angle_factor: 1.0,
        rate_as_value: false,
    };

    /// To enter `ClearToLand` (and a touchdown's last chance before its point of no return):
    /// at `risk_per_touchdown`, bands judged as measured.
    pub(super) fn entry(c: &DecisionConfig) -> Self {
        Self {
            risk: Some(c.risk_per_touchdown),
            ..Self::MEAN
        }
    }

    /// A new commitment's: an entry's, with a suspect band (`Models::band_suspect`) judged as an
    /// unreliable one, an unreliable angle's band widened (`UNRELIABLE_ANGLE_FACTOR`) and an
    /// unreliable channel's rate taken as far off as its value (`rate_as_value`), and, while
    /// `early` (within `early_window_s` of when the decision could first clear), at
    /// `early_risk_per_touchdown`. The touchdown's last chance judges the band as it is
    /// measured then, and a suspect one's next misses often make it unreliable.
    pub(super) fn commit(c: &DecisionConfig, early: bool) -> Self {
        let entry = Self::entry(c);
        Self {
            unreliable_band_scale: SUSPECT_BAND_SCALE,
            unreliable_angle_factor: UNRELIABLE_ANGLE_FACTOR,
            rate_as_value: true,
            risk: entry.risk.map(|r| {
                if early {
                    r.min(c.ar().early_risk_per_touchdown)
                } else {
                    r
                }
            }),
        }
    }

    /// To stay committed: at `go_around_risk`. A committed touchdown is given up when the
    /// newest forecast puts the deck outside the capacity at that risk, not because it differs
    /// from the one that committed.
    pub(super) fn stay(c: &DecisionConfig) -> Self {
        Self {
            risk: Some(c.go_around_risk),
            ..Self::MEAN
        }
    }

    /// A committed touchdown's last chance before its point of no return (seeing or blind): a
    /// clearance's. A committed touchdown goes on up to `go_around_risk` because the frames
    /// still to come can call a go-around; past the point of no return none can, so the last
    /// decision before it judges the rest of the touchdown as a new clearance would be. On a
    /// seeing touchdown's judgement (`stay`), three held-out approaches at sea state 6 rode through their
    /// last 0.5 s on forecasts at a risk of 0.1 or less and met the deck falling at 0.606, 0.635
    /// and 0.90 m/s against 0.6 (docs/history.md).
    pub(super) fn last_chance(c: &DecisionConfig) -> Self {
        Self::entry(c)
    }
}

/// Whether the model keeps the deck within the capacity over [from, to]:
/// with a stated uncertainty, at the accepted risk; else its mean.
pub(super) fn predicted_within<C: ChannelForecast>(
    c: &DecisionConfig,
    m: &Models<C>,
    from: f64,
    to: f64,
    judgement: Judgement,
) -> bool {
    let steps = ((to - from) / STEP_S).ceil().max(0.0) as usize;
    let (roll, pitch) = (&m.forecasts[ROLL], &m.forecasts[PITCH]);
    let heave = m.forecasts.get(HEAVE);
    let limits = c.capacity_limits();
    let times = (0..=steps).map(|k| (from + k as f64 * STEP_S).min(to));
    if let Some(risk) = judgement.risk {
        return exceedance_risk(c, m, times, &limits, judgement) <= risk;
    }
    times.into_iter().all(|t| {
        let (r, p) = (roll.value(t).abs(), pitch.value(t).abs());
        r <= limits[0]
            && p <= limits[1]
            && tilt_deg(r, p) <= limits[2]
            && roll.rate(t).abs() <= limits[3]
            && pitch.rate(t).abs() <= limits[4]
            && heave.is_none_or(|h| h.rate(t).abs() <= limits[5])
    })
}

/// The risk that the deck leaves the capacity (`limits`: roll, pitch, tilt, roll rate,
/// pitch rate, heave rate) over `times`, as the model states it (mean and standard
/// deviation, scaled by how honest it has been): for each limit the largest probability
/// over the times that it is exceeded, summed over the limits. A limit far from the
/// forecast costs nothing, so the one that binds gets nearly all the risk (a fixed share
/// each would give it a sixth). Over the limits it is an upper bound; over the times it is
/// not (the largest instant's, not the whole touchdown's): honest bands left the truth
/// beyond 3.09 deviations at some instant of a touchdown 4 times as often as at its end
/// (BENCHMARKS.md, "The landing decision: decide-eval"). The
/// measured share of clearances into a broken limit stays below the risk: a rate band's
/// scale is read at the 97.5th percentile (a value band's at the 95th, its tails measured:
/// BENCHMARKS.md, "Ship motion it was not built on") and the limits' risks are summed. A band measured more
/// than `judgement.unreliable_band_scale` times too narrow has its rate judged by its history too
/// (`MAX_BAND_SCALE`; a new commitment's `SUSPECT_BAND_SCALE`: `Judgement::commit`); an angle
/// whose band is unreliable has its deviation widened by `judgement.unreliable_angle_factor`,
/// and with `judgement.rate_as_value` an unreliable channel's rate is scaled at least as much
/// as its value's band.
pub(super) fn exceedance_risk<C: ChannelForecast>(
    c: &DecisionConfig,
    m: &Models<C>,
    times: impl Iterator<Item = f64>,
    limits: &[f64; 6],
    judgement: Judgement,
) -> f64 {
    let unreliable_scale = judgement.unreliable_band_scale;
    let (roll, pitch) = (&m.forecasts[ROLL], &m.forecasts[PITCH]);
    let heave = m.forecasts.get(HEAVE);
    // An unreliable rate has a second judge (its misses in its own unit, its history); an
    // unreliable angle has none, and its band scaled by the past's misses is no bound on a
    // sea that is changing: scaled 5.96 and 7.27 times, roll and pitch bands cleared into
    // a true roll of 5.41 deg against 5 as a lull ended (docs/history.md, "An unreliable angle band widened by a new commitment"). A new commitment widens it again.
    // Its deviation is the one its scale as the guards read it gives (`Models::guard_scale`,
    // never the band's narrower width), widened.
    let angle_std = |k: usize, t: f64| match m.guard_scale[k] > MAX_BAND_SCALE {
        true => judgement.unreliable_angle_factor * m.guarded_value_std(k, t),
        false => m.value_std(k, t),
    };
    // A channel whose band has been measured far too narrow (value or rate) states
    // deviations that are not its forecast's error. A campaign cleared on heave bands scaled
    // 3.4-200 times, three times into more than 0.64 m/s of heave rate (docs/history.md, "A campaign of 2 016 approaches: three unsafe touchdowns into heave rate"). Its rate is given at least the spread of its own
    // recent misses (`Models::rate_std`); until those are measured, it is also judged as
    // the history knows it without a model, and the larger risk counts: from the newest
    // rate measured, as far as the history's regression reaches (`RateHistory`), else with
    // a mean of zero and the history's spread. With that spread alone, the touchdown's
    // last 0.4 s ridden through blind was judged as if nothing were known of the rate a
    // second before; 5 of 10 blind go-arounds on development seeds had only that reason
    // (docs/history.md, "The rate a second ago").
    // The autopilot's vertical-speed error is in every measured heave rate and in none of
    // the forecast's misses or the history's spread: independent of them, it adds in
    // quadrature to the heave rate's deviation.
    let bias_var = c.vertical_speed_error_mps.powi(2);
    // The same for the autopilot's roll and pitch error in the measured deck angles.
    let attitude_bias_var = c.vehicle_attitude_error_deg.powi(2);
    let with_attitude_error = |std: f64| (std * std + attitude_bias_var).sqrt();
    let with_vertical_speed_error = |k: usize, std: f64| {
        if k == HEAVE {
            (std * std + bias_var).sqrt()
        } else {
            std
        }
    };
    let history_tail = |k: usize, t: f64, limit: f64| -> f64 {
        match m.rate_history[k].forecast(t) {
            (mean, std) if std.is_finite() => {
                outside_probability(mean, with_vertical_speed_error(k, std), limit)
            }
            // No spread known (too few distinct sample times): nothing to clear on.
            _ => 1.0,
        }
    };
    // A new commitment takes an unreliable channel's rate as far off as its value: a heave
    // value band measured 15.5 times too narrow had its rate cleared on a band measured
    // 2.2 times, 0.053 m/s, and met a heave rate 0.6 m/s beyond its forecast (docs/history.md, "An unreliable channel's rate as far off as its value").
    let rate_std = |k: usize, t: f64| m.rate_std_judging(k, t, judgement.rate_as_value);
    let mut worst = [0.0f64; 6];
    for t in times {
        let (rm, rs) = (roll.value(t), with_attitude_error(angle_std(ROLL, t)));
        let (pm, ps) = (pitch.value(t), with_attitude_error(angle_std(PITCH, t)));
        let tails = [
            outside_probability(rm, rs, limits[0]),
            outside_probability(pm, ps, limits[1]),
            tilt_outside_probability((rm, rs), (pm, ps), limits[2]),
            outside_probability(roll.rate(t), rate_std(ROLL, t), limits[3]),
            outside_probability(pitch.rate(t), rate_std(PITCH, t), limits[4]),
            heave.map_or(0.0, |h| {
                outside_probability(
                    h.rate(t),
                    with_vertical_speed_error(HEAVE, rate_std(HEAVE, t)),
                    limits[5],
                )
            }),
        ];
        for (w, p) in worst.iter_mut().zip(tails) {
            *w = w.max(p);
        }
        for (k, w) in worst[3..].iter_mut().enumerate() {
            if m.judged_by_history_above(k, unreliable_scale) {
                *w = w.max(history_tail(k, t, limits[3 + k]));
            }
        }
    }
    worst.iter().sum()
}

/// The first window within the horizon in which a commit would be safe.
pub(super) fn calm_window<C: ChannelForecast>(
    c: &DecisionConfig,
    m: &Models<C>,
    now: f64,
    judgement: Judgement,
) -> Option<(f64, f64)> {
    let horizon_s = c.ar().horizon_s;
    let steps = (horizon_s / STEP_S) as usize;
    let ok: Vec<bool> = (0..=steps)
        .map(|k| {
            let t = now + k as f64 * STEP_S;
            predicted_within(c, m, t, t, judgement)
        })
        .collect();
    let need = (c.touchdown_s / STEP_S).ceil() as usize;
    let mut k = 0;
    while k < ok.len() {
        if ok[k] {
            let len = ok[k..].iter().take_while(|&&v| v).count();
            if len > need {
                return Some((k as f64 * STEP_S, len as f64 * STEP_S));
            }
            k += len;
        } else {
            k += 1;
        }
    }
    None
}

/// The probability that a normal value of `mean` and `std` is beyond `limit` either way (`std`
/// 0: whether the mean is).
pub(super) fn outside_probability(mean: f64, std: f64, limit: f64) -> f64 {
    if !(std > 0.0) {
        return if mean.abs() <= limit { 0.0 } else { 1.0 };
    }
    // Beyond 9 standard deviations the tail is below 1e-18: not worth an erfc (most of the
    // calm-window search is there).
    if mean.abs() + NEGLIGIBLE_Z * std <= limit {
        return 0.0;
    }
    let tail = |x: f64| 0.5 * libm::erfc(x / (std * std::f64::consts::SQRT_2));
    (tail(limit - mean) + tail(limit + mean)).min(1.0)
}

/// Standard deviations beyond which a tail probability counts as 0.
pub(super) const NEGLIGIBLE_Z: f64 = 9.0;

/// Splits of the tilt limit between roll and pitch tried by [`tilt_outside_probability`].
pub(super) const TILT_SPLITS: usize = 12;

/// An upper bound of the probability that roll and pitch (each `(mean, std)`, independent or
/// not) tilt the deck beyond `limit_deg`: within `a` of roll and `b` of pitch with
/// `tilt(a, b) = limit`, the tilt is within the limit, so the probability is at most that of
/// roll beyond `a` plus that of pitch beyond `b`; the least over a few splits.
pub(super) fn tilt_outside_probability(roll: (f64, f64), pitch: (f64, f64), limit_deg: f64) -> f64 {
    let far = |(mean, std): (f64, f64)| mean.abs() + NEGLIGIBLE_Z * std;
    if tilt_deg(far(roll), far(pitch)) <= limit_deg {
        return 0.0;
    }
    let cos_limit = limit_deg.to_radians().cos();
    (0..=TILT_SPLITS)
        .map(|i| {
            let a_deg = limit_deg * i as f64 / TILT_SPLITS as f64;
            // cos(tilt) = cos(roll) cos(pitch)
            let b_deg = (cos_limit / a_deg.to_radians().cos())
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            outside_probability(roll.0, roll.1, a_deg) + outside_probability(pitch.0, pitch.1, b_deg)
        })
        .fold(1.0, f64::min)
}

/// The tilt from level (deg) of a deck at `roll_deg` and `pitch_deg` (X-Y order: the angle of
/// its normal from the vertical, `acos(cos roll cos pitch)`).
pub fn tilt_deg(roll_deg: f64, pitch_deg: f64) -> f64 {
    (roll_deg.to_radians().cos() * pitch_deg.to_radians().cos())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_judgement_takes_its_own_risk() {
        let c = DecisionConfig::default();
        assert_eq!(Judgement::entry(&c).risk, Some(c.risk_per_touchdown));
        assert_eq!(Judgement::last_chance(&c).risk, Some(c.risk_per_touchdown));
        assert_eq!(Judgement::stay(&c).risk, Some(c.go_around_risk));
        assert_eq!(Judgement::MEAN.risk, None);
        let early = Judgement::commit(&c, true);
        assert_eq!(early.risk, Some(c.ar().early_risk_per_touchdown));
        assert_eq!(Judgement::commit(&c, false).risk, Some(c.risk_per_touchdown));
        assert!(early.rate_as_value && early.unreliable_band_scale == SUSPECT_BAND_SCALE);
        assert_eq!(Judgement::stay(&c).unreliable_band_scale, MAX_BAND_SCALE);
    }

    #[test]
    fn the_tilt_is_that_of_the_decks_normal() {
        assert!((tilt_deg(3.0, 0.0) - 3.0).abs() < 1e-9);
        assert!(tilt_deg(4.3, 3.9) > 5.5);
        assert_eq!(outside_probability(1.0, 0.0, 2.0), 0.0);
        assert_eq!(outside_probability(3.0, 0.0, 2.0), 1.0);
        assert!((outside_probability(0.0, 1.0, 1.959_963_984_540_054) - 0.05).abs() < 1e-9);
    }
}
