//! Evaluation of landing rules against the true deck motion: how often a rule commits although
//! the true deck leaves the capacity during the touchdown (unsafe clearances: must be 0), which
//! of those the decision sent around before the touchdown's point of no return (the rest are
//! unsafe touchdowns), and how many of the truly calm windows it uses (availability). Pure:
//! the caller supplies the true motion and the measured attitude stream (with its noise,
//! dropouts and outliers).

use crate::decision::{Decision, DecisionConfig, LandingDecider};
use crate::forecast_eval::WindowVerdict;
use crate::frame::FrameInput;
use deckwatch_common::messages::DecisionState;

/// Outcome of one rule over one series.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct RuleOutcome {
    pub commits: u64,
    /// Commits during whose touchdown the true deck left the capacity.
    pub unsafe_commits: u64,
    /// Each of them: when it was made and what the true deck broke (to look into).
    pub unsafe_commit_details: Vec<UnsafeCommit>,
    /// Unsafe commits not sent around before their point of no return (`no_return_ms` before
    /// contact): the touchdowns that would have met the deck beyond the capacity. The naive
    /// rule never goes around: all of its unsafe commits.
    pub unsafe_touchdowns: u64,
    /// Commits later aborted (the state machine only).
    pub aborts: u64,
    /// Truly calm windows (at least one touchdown long).
    pub calm_windows: u64,
    /// Calm windows with a safe commit inside.
    pub calm_windows_used: u64,
    /// Share of the series' time during which a commit would truly have been safe.
    pub safe_time_share: f64,
    /// Aborts by the reason given (state machine only).
    pub abort_reasons: std::collections::BTreeMap<String, u64>,
    /// Decisions by state and reason (state machine only).
    pub decisions: std::collections::BTreeMap<String, u64>,
    /// Cost of one decision (us): p50, p99, max (state machine only).
    pub update_us: [f64; 3],
    /// The forecast each new commitment was cleared on, judged over its touchdown against the
    /// truth (state machine only): the band's honesty where the decision uses it, beside
    /// `predict-eval`'s over every instant (clearances might pick instants whose band is too
    /// narrow).
    pub at_clearances: ClearanceBands,
}

/// Per quantity (as [`crate::forecast_eval::QUANTITIES`]), of the forecasts new commitments
/// were cleared on: how many were judged, how many kept the truth inside their stated 95 % band
/// all through the touchdown, and how many let it beyond `TAIL_Z` stated deviations.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct ClearanceBands {
    pub judged: [u64; 6],
    pub inside: [u64; 6],
    pub beyond_tail: [u64; 6],
}

impl ClearanceBands {
    fn add(&mut self, w: &WindowVerdict) {
        for q in 0..6 {
            if w.judged[q] {
                self.judged[q] += 1;
                self.inside[q] += u64::from(w.inside[q]);
                self.beyond_tail[q] += u64::from(w.beyond_tail[q]);
            }
        }
    }

    pub fn merge(&mut self, other: &Self) {
        for q in 0..6 {
            self.judged[q] += other.judged[q];
            self.inside[q] += other.inside[q];
            self.beyond_tail[q] += other.beyond_tail[q];
        }
    }
}

/// An unsafe commit: when it was made, and the limit the true deck went furthest beyond during
/// its touchdown (by its share of the limit).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct UnsafeCommit {
    /// When the commit was made (s on the series' timeline).
    pub t_s: f64,
    /// `roll`, `pitch`, `tilt`, `roll-rate`, `pitch-rate` or `heave-rate`.
    pub limit: &'static str,
    /// The true value at its worst (deg, deg/s or m/s; signed) and the limit it broke.
    pub worst: f64,
    pub limit_value: f64,
    /// When the worst came, after the commit (s).
    pub after_s: f64,
    /// When the decision sent the touchdown around, after the commit (s), if it did before
    /// the point of no return.
    pub sent_around_after_s: Option<f64>,
}

impl std::fmt::Display for UnsafeCommit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:.1} s: {} {:.3} (limit {}) {:.2} s into the touchdown",
            self.t_s, self.limit, self.worst, self.limit_value, self.after_s
        )?;
        match self.sent_around_after_s {
            Some(s) => write!(f, "; sent around {s:.2} s in, before the point of no return"),
            None => write!(f, "; not sent around: an unsafe touchdown"),
        }
    }
}

impl RuleOutcome {
    pub fn availability(&self) -> f64 {
        if self.calm_windows == 0 {
            f64::NAN
        } else {
            self.calm_windows_used as f64 / self.calm_windows as f64
        }
    }
}

/// The true deck at an instant: roll, pitch (deg) and the deck centre's height (m).
pub type TrueDeck<'a> = &'a dyn Fn(f64) -> [f64; 3];

/// The true deck at an instant with its rates, from [`TrueDeck`] by central differences.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrueDeckState {
    pub roll_deg: f64,
    pub pitch_deg: f64,
    pub roll_rate_dps: f64,
    pub pitch_rate_dps: f64,
    pub heave_rate_mps: f64,
}

impl TrueDeckState {
    pub fn at(truth: TrueDeck, t: f64) -> Self {
        let h = 1e-3;
        let [r, p, _] = truth(t);
        let [r1, p1, z1] = truth(t + h);
        let [r0, p0, z0] = truth(t - h);
        Self {
            roll_deg: r,
            pitch_deg: p,
            roll_rate_dps: (r1 - r0) / (2.0 * h),
            pitch_rate_dps: (p1 - p0) / (2.0 * h),
            heave_rate_mps: (z1 - z0) / (2.0 * h),
        }
    }

    /// The capacity's limits this state breaks (none: within capacity). The capacity as the
    /// truth is judged by: angles, rates and the heave rate, always (the capacity is the
    /// vehicle's; `heave = "off"` only says the decider cannot see the heave).
    pub fn violations(&self, c: &DecisionConfig) -> Vec<&'static str> {
        self.limits(c)
            .into_iter()
            .filter(|(_, value, limit)| !(value.abs() <= *limit))
            .map(|(name, _, _)| name)
            .collect()
    }

    /// The limit this state goes furthest beyond, by its share of the limit: name, value and
    /// limit (None: within capacity).
    pub fn worst_violation(&self, c: &DecisionConfig) -> Option<(&'static str, f64, f64)> {
        self.limits(c)
            .into_iter()
            .filter(|(_, value, limit)| !(value.abs() <= *limit))
            .max_by(|a, b| (a.1.abs() / a.2).total_cmp(&(b.1.abs() / b.2)))
    }

    pub fn within(&self, c: &DecisionConfig) -> bool {
        self.limits(c)
            .iter()
            .all(|(_, value, limit)| value.abs() <= *limit)
    }

    /// Each limit's name, this state's value and the limit, in `capacity_limits`' order.
    fn limits(&self, c: &DecisionConfig) -> [(&'static str, f64, f64); 6] {
        let [roll, pitch, tilt, roll_rate, pitch_rate, heave_rate] = c.capacity_limits();
        [
            ("roll", self.roll_deg, roll),
            ("pitch", self.pitch_deg, pitch),
            (
                "tilt",
                crate::decision::tilt_deg(self.roll_deg, self.pitch_deg),
                tilt,
            ),
            ("roll-rate", self.roll_rate_dps, roll_rate),
            ("pitch-rate", self.pitch_rate_dps, pitch_rate),
            ("heave-rate", self.heave_rate_mps, heave_rate),
        ]
    }
}

fn truly_within(truth: TrueDeck, c: &DecisionConfig, t: f64) -> bool {
    TrueDeckState::at(truth, t).within(c)
}

const TRUTH_STEP_S: f64 = 0.02;

/// The truly calm intervals in [t0, t1] of at least `touchdown_s`.
fn calm_intervals(truth: TrueDeck, c: &DecisionConfig, t0: f64, t1: f64) -> (Vec<(f64, f64)>, f64) {
    let mut out = Vec::new();
    let mut start: Option<f64> = None;
    let mut safe_time = 0.0;
    let n = ((t1 - t0) / TRUTH_STEP_S) as usize;
    for k in 0..=n {
        let t = t0 + k as f64 * TRUTH_STEP_S;
        let ok = k < n && truly_within(truth, c, t);
        match (ok, start) {
            (true, None) => start = Some(t),
            (false, Some(s)) => {
                if t - s >= c.touchdown_s {
                    out.push((s, t));
                    safe_time += t - s - c.touchdown_s;
                }
                start = None;
            }
            _ => {}
        }
    }
    (out, safe_time / (t1 - t0))
}

/// A commit: when it was made (s) and, if the decision sent it around before its point of no
/// return, when.
#[derive(Debug, Clone, Copy)]
struct Commit {
    t_s: f64,
    sent_around_s: Option<f64>,
}

impl Commit {
    fn new(t_s: f64) -> Self {
        Self {
            t_s,
            sent_around_s: None,
        }
    }

    /// A go-around decided at `now`: it keeps the vehicle off the deck only before the
    /// touchdown's point of no return (`no_return_ms` before contact).
    fn sent_around(&mut self, now: f64, c: &DecisionConfig) {
        if self.sent_around_s.is_none() && now < self.t_s + c.touchdown_s - c.no_return_ms / 1e3 {
            self.sent_around_s = Some(now);
        }
    }
}

fn judge(
    truth: TrueDeck,
    c: &DecisionConfig,
    commits: &[Commit],
    outcome: &mut RuleOutcome,
    t0: f64,
    t1: f64,
) {
    let (calm, share) = calm_intervals(truth, c, t0, t1 + c.touchdown_s);
    outcome.calm_windows = calm.len() as u64;
    outcome.safe_time_share = share;
    outcome.commits = commits.len() as u64;
    let mut used = vec![false; calm.len()];
    for &Commit {
        t_s: tc,
        sent_around_s,
    } in commits
    {
        let steps = (c.touchdown_s / TRUTH_STEP_S).ceil() as usize;
        // The worst violation over the touchdown, if any (a NaN state counts as beyond).
        let worst = (0..=steps)
            .filter_map(|k| {
                let after_s = (k as f64 * TRUTH_STEP_S).min(c.touchdown_s);
                let (limit, worst, limit_value) =
                    TrueDeckState::at(truth, tc + after_s).worst_violation(c)?;
                Some(UnsafeCommit {
                    t_s: tc,
                    limit,
                    worst,
                    limit_value,
                    after_s,
                    sent_around_after_s: sent_around_s.map(|s| s - tc),
                })
            })
            .max_by(|a, b| (a.worst.abs() / a.limit_value).total_cmp(&(b.worst.abs() / b.limit_value)));
        if let Some(unsafe_commit) = worst {
            outcome.unsafe_commits += 1;
            outcome.unsafe_touchdowns += u64::from(sent_around_s.is_none());
            outcome.unsafe_commit_details.push(unsafe_commit);
            continue;
        }
        if let Some(i) = calm
            .iter()
            .position(|&(a, b)| a <= tc + 1e-9 && tc + c.touchdown_s <= b + 1e-9)
        {
            used[i] = true;
        }
    }
    outcome.calm_windows_used = used.iter().filter(|&&u| u).count() as u64;
}

/// The decisions on a stream, frame by frame, as the decide stage makes them: the same calls in
/// the same order (`decide_frame`, then the refit between frames).
pub fn decide_stream(
    config: &DecisionConfig,
    stream: &[FrameInput],
) -> Result<Vec<Decision>, deckwatch_common::InvalidField> {
    let mut decider = LandingDecider::new(config.clone())?;
    Ok(stream
        .iter()
        .map(|f| {
            let d = decider.decide_frame(f);
            decider.refit_between_frames();
            d
        })
        .collect())
}

/// When the decision on a frame is out (s, on the frames' timeline): its capture time plus its
/// age; the touchdown a commit starts is judged from then on.
fn decided_at(f: &FrameInput) -> f64 {
    f.t_s
        + if f.age_s.is_finite() {
            f.age_s.max(0.0)
        } else {
            0.0
        }
}

/// Runs the state machine and the naive rule ("current angles within the limits") over the
/// same measured stream; returns (state machine, naive).
pub fn evaluate(
    truth: TrueDeck,
    config: &DecisionConfig,
    stream: &[FrameInput],
) -> Result<(RuleOutcome, RuleOutcome), deckwatch_common::InvalidField> {
    let (Some(first), Some(last)) = (stream.first(), stream.last()) else {
        return Ok(Default::default());
    };
    let mut decider = LandingDecider::new(config.clone())?;
    let (mut commits, mut naive_commits) = (Vec::new(), Vec::new());
    let mut smart = RuleOutcome::default();
    let mut naive_until = f64::NEG_INFINITY;
    let mut previous = DecisionState::NoDeck;
    let mut cost_us = Vec::with_capacity(stream.len());
    for f in stream {
        // The cost on the frame's path; the refit after it is off the path (as in the stage).
        let clock = std::time::Instant::now();
        let d = decider.decide_frame(f);
        cost_us.push(clock.elapsed().as_secs_f64() * 1e6);
        if d.new_commit {
            // The model it was cleared on, before the refit between frames replaces it.
            let w = WindowVerdict::judge(truth, |t| decider.forecast(t), f.t_s, config.touchdown_s);
            smart.at_clearances.add(&w);
        }
        decider.refit_between_frames();
        *smart
            .decisions
            .entry(format!("{} {}", d.state.name(), d.reason.name()))
            .or_default() += 1;
        let now = decided_at(f);
        if d.new_commit {
            commits.push(Commit::new(now));
        }
        if d.state == DecisionState::Abort && previous != DecisionState::Abort {
            if let Some(last) = commits.last_mut() {
                last.sent_around(now, config);
            }
            smart.aborts += 1;
            *smart
                .abort_reasons
                .entry(d.reason.name().to_string())
                .or_default() += 1;
        }
        previous = d.state;
        // The naive rule commits whenever the current angles are within the limits and no
        // touchdown of its own is under way.
        if let Some(d) = f.deck.filter(|_| !f.vehicle_missing && !f.frozen_image) {
            if now >= naive_until && config.naive_within(d.roll_deg, d.pitch_deg) {
                naive_commits.push(Commit::new(now));
                naive_until = now + config.touchdown_s;
            }
        }
    }
    if let Some(p) = deckwatch_common::stats::Percentiles::of(&mut cost_us) {
        smart.update_us = [p.p50, p.p99, p.max];
    }
    let mut naive = RuleOutcome::default();
    judge(truth, config, &commits, &mut smart, first.t_s, last.t_s);
    judge(truth, config, &naive_commits, &mut naive, first.t_s, last.t_s);
    Ok((smart, naive))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decision::DeckObservation;
    use std::f64::consts::TAU;

    /// An unsafe clearance sent around before its point of no return is still an unsafe
    /// clearance, but no unsafe touchdown; one sent around later is both.
    #[test]
    fn a_go_around_before_the_point_of_no_return_keeps_an_unsafe_clearance_off_the_deck() {
        let c = DecisionConfig::default();
        // Level, and heaving at 1 m/s (beyond the capacity) from 11.9 s on.
        let truth = |t: f64| [0.0, 0.0, if t < 11.9 { 0.0 } else { t - 11.9 }];
        let no_return_s = c.touchdown_s - c.no_return_ms / 1e3;
        let mut early = Commit::new(10.0);
        early.sent_around(10.0 + no_return_s - 0.05, &c);
        let mut late = Commit::new(10.0);
        late.sent_around(10.0 + no_return_s + 0.05, &c);
        let mut safe = Commit::new(1.0);
        safe.sent_around(1.5, &c);
        let mut outcome = RuleOutcome::default();
        judge(
            &truth,
            &c,
            &[safe, early, late, Commit::new(10.0)],
            &mut outcome,
            0.0,
            30.0,
        );
        assert_eq!(outcome.commits, 4);
        assert_eq!(outcome.unsafe_commits, 3);
        assert_eq!(outcome.unsafe_touchdowns, 2);
        let sent: Vec<_> = outcome
            .unsafe_commit_details
            .iter()
            .map(|u| u.sent_around_after_s)
            .collect();
        assert!((sent[0].unwrap() - (no_return_s - 0.05)).abs() < 1e-9, "{sent:?}");
        assert_eq!(sent[1..], [None, None]);
        assert_eq!(outcome.unsafe_commit_details[0].limit, "heave-rate");
    }

    #[test]
    fn a_calm_sea_is_used_and_the_naive_rule_is_unsafe_on_a_rough_one() {
        let c = DecisionConfig::default();
        let calm = |t: f64| {
            [
                1.0 * (TAU * t / 9.0).sin(),
                0.5 * (TAU * t / 6.0).sin(),
                0.3 * (TAU * t / 9.5).sin(),
            ]
        };
        let observed = |[r, p, h]: [f64; 3]| Some(DeckObservation::new(r, p, h));
        let stream: Vec<FrameInput> = (0..1200)
            .map(|k| {
                let t = k as f64 * 0.1;
                FrameInput::measured(t, observed(calm(t)), 0.005)
            })
            .collect();
        let (smart, naive) = evaluate(&calm, &c, &stream).unwrap();
        assert_eq!(smart.unsafe_commits, 0);
        assert_eq!(smart.calm_windows, 1, "always calm: one long window");
        assert_eq!(smart.calm_windows_used, 1);
        assert_eq!(naive.unsafe_commits, 0);
        // Every clearance's forecast is judged over its touchdown, every quantity (heave too).
        // (Noise-free samples let the fit state bands of micrometres that the truth leaves: on
        // this stream most are left, far from any limit. The bands' honesty is measured on
        // noisy seas: BENCHMARKS.md.)
        let bands = &smart.at_clearances;
        assert!(smart.commits > 0);
        assert_eq!(bands.judged, [smart.commits; 6], "{bands:?}");
        assert!(
            (0..6).all(|q| bands.inside[q] + bands.beyond_tail[q] <= bands.judged[q]),
            "{bands:?}"
        );
        // The vehicle's attitude missing from 60 s on: nothing is cleared after that.
        let outage: Vec<FrameInput> = stream
            .iter()
            .map(|m| FrameInput {
                vehicle_missing: m.t_s >= 60.0,
                ..*m
            })
            .collect();
        let (smart, _) = evaluate(&calm, &c, &outage).unwrap();
        let refused: u64 = smart
            .decisions
            .iter()
            .filter(|(k, _)| k.ends_with("no-vehicle-attitude"))
            .map(|(k, v)| {
                assert!(!k.starts_with("CLEAR"), "{k}");
                *v
            })
            .sum();
        // A touchdown committed before the outage rides through its first second (11 frames at
        // most: 10 Hz, both ends); every other frame of it is refused.
        let ridden = smart.decisions.get("CLEAR ride-through").copied().unwrap_or(0);
        assert!(ridden <= 11, "{:?}", smart.decisions);
        assert_eq!(
            refused + ridden,
            600,
            "every frame of the outage: {:?}",
            smart.decisions
        );
        // Rough: angles pass through the limits fast; the naive rule commits on the way out.
        let rough = |t: f64| [9.0 * (TAU * t / 9.0).sin(), 0.5 * (TAU * t / 6.0).sin(), 0.0];
        let stream: Vec<FrameInput> = stream
            .iter()
            .map(|m| FrameInput {
                deck: observed(rough(m.t_s)),
                ..*m
            })
            .collect();
        let (smart, naive) = evaluate(&rough, &c, &stream).unwrap();
        assert_eq!(smart.unsafe_commits, 0);
        assert!(naive.unsafe_commits > 0);
        // Each unsafe commit says what the true deck broke, beyond its limit.
        assert_eq!(naive.unsafe_commit_details.len() as u64, naive.unsafe_commits);
        for u in &naive.unsafe_commit_details {
            assert!(
                u.worst.abs() > u.limit_value && (0.0..=c.touchdown_s).contains(&u.after_s),
                "{u}"
            );
        }
    }
}
