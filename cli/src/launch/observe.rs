//! Observation: the launcher follows the decision stream and keeps the run's metrics (latency
//! histograms, drops summed over stage restarts, states, accuracy against the truth), the live
//! status line and the decisions CSV.

use super::report::{DropReport, LatencyRow, RunReport};
use crate::decisions_csv::DecisionsCsv;
use deckwatch_common::messages::{
    DecisionState, DropCounts, GapCounter, LandingDecision, LatencyInterval, DROP_VALUES,
};
use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::stats::ErrorStats;
use hdrhistogram::Histogram;
use std::path::Path;
use std::time::Instant;

/// Sums a counter that restarts at 0 when its process is restarted.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct RestartingCounter {
    last: u64,
    pub total: u64,
}

impl RestartingCounter {
    pub fn update(&mut self, v: u64) {
        // Saturating: the values come from other processes.
        self.total = self
            .total
            .saturating_add(if v >= self.last { v - self.last } else { v });
        self.last = v;
    }
}

/// Drop counts of the stream, summed across the restarts of the stages that count them (one
/// counter per count of [`DropCounts`], in its order).
#[derive(Debug, Default, Clone, Copy)]
pub struct DropTotals([RestartingCounter; DROP_VALUES]);

impl DropTotals {
    pub fn update(&mut self, d: &DropCounts) {
        for (counter, n) in self.0.iter_mut().zip(d.values()) {
            counter.update(n);
        }
    }

    pub fn totals(&self) -> DropCounts {
        DropCounts::from_values(self.0.map(|c| c.total))
    }
}

/// One latency histogram per [`LatencyInterval`].
pub struct Histograms(Vec<Histogram<u64>>);

impl Histograms {
    pub fn new() -> Self {
        Self(
            LatencyInterval::ALL
                .iter()
                .map(|_| Histogram::new_with_bounds(1, 120_000_000_000, 3).expect("valid bounds"))
                .collect(),
        )
    }

    pub fn record(&mut self, d: &LandingDecision) {
        for (h, i) in self.0.iter_mut().zip(LatencyInterval::ALL) {
            if let Some(ns) = d.stamp.times.interval_ns(i) {
                // Out of the histogram's range (a clock gone wrong): not recorded.
                let _ = h.record(ns.max(1));
            }
        }
    }

    fn get(&self, i: LatencyInterval) -> &Histogram<u64> {
        &self.0[LatencyInterval::ALL.iter().position(|x| *x == i).expect("listed")]
    }

    fn quantile_ms(h: &Histogram<u64>, q: f64) -> f64 {
        if h.is_empty() {
            f64::NAN
        } else {
            h.value_at_quantile(q) as f64 / 1e6
        }
    }

    pub fn p50_ms(&self, i: LatencyInterval) -> f64 {
        Self::quantile_ms(self.get(i), 0.5)
    }

    pub fn rows(&self) -> Vec<LatencyRow> {
        LatencyInterval::ALL
            .iter()
            .map(|&i| {
                let h = self.get(i);
                LatencyRow {
                    interval: i.name().into(),
                    count: h.len(),
                    p50_ms: Self::quantile_ms(h, 0.5),
                    p90_ms: Self::quantile_ms(h, 0.9),
                    p99_ms: Self::quantile_ms(h, 0.99),
                    max_ms: if h.is_empty() {
                        f64::NAN
                    } else {
                        h.max() as f64 / 1e6
                    },
                }
            })
            .collect()
    }

    pub fn reset(&mut self) {
        self.0.iter_mut().for_each(Histogram::reset);
    }
}

/// Follows the decision stream.
pub struct Observer {
    decisions: u64,
    /// Decisions decide's watchdog issued because attitudes stopped coming.
    watchdog: u64,
    all: Histograms,
    recent: Histograms,
    recent_count: u64,
    drops: DropTotals,
    gaps: GapCounter,
    observer_missed: u64,
    states: [u64; DecisionState::ALL.len()],
    valid: u64,
    errors: ErrorStats,
    attitudes_without_deck: u64,
    last: Option<LandingDecision>,
    /// When the last decision on a frame arrived.
    pub last_at: Instant,
    csv: Option<DecisionsCsv>,
    /// Why the decisions CSV stopped being written (it is incomplete), with the rows written.
    pub csv_error: Option<(String, u64)>,
    csv_rows: u64,
}

impl Observer {
    pub fn new(csv: Option<&Path>) -> Result<Self, String> {
        Ok(Self {
            decisions: 0,
            watchdog: 0,
            all: Histograms::new(),
            recent: Histograms::new(),
            recent_count: 0,
            drops: DropTotals::default(),
            gaps: GapCounter::from_start(),
            observer_missed: 0,
            states: [0; DecisionState::ALL.len()],
            valid: 0,
            errors: ErrorStats::default(),
            attitudes_without_deck: 0,
            last: None,
            last_at: Instant::now(),
            csv: csv.map(DecisionsCsv::create).transpose()?,
            csv_error: None,
            csv_rows: 0,
        })
    }

    /// Follows one decision. A decisions CSV that cannot be written (disk full, read-only)
    /// is said once and given up; the pipeline goes on deciding, and the report says the file
    /// is incomplete.
    pub fn observe(&mut self, d: &LandingDecision) {
        if let Some(w) = &mut self.csv {
            match w.write(d) {
                Ok(()) => self.csv_rows += 1,
                Err(e) => {
                    super::say(format_args!(
                        "decisions CSV: {e}; it is incomplete after {} rows and no more are written (the pipeline goes on)",
                        self.csv_rows
                    ));
                    self.csv_error = Some((e, self.csv_rows));
                    self.csv = None;
                }
            }
        }
        self.last = Some(*d);
        if d.watchdog.get() {
            self.watchdog += 1;
            return;
        }
        self.decisions += 1;
        self.recent_count += 1;
        self.all.record(d);
        self.recent.record(d);
        let dr = d.stamp.drops;
        self.drops.update(&dr);
        self.observer_missed += self.gaps.observe(d.stamp.seq, dr.total());
        if let Some(i) = DecisionState::ALL.iter().position(|s| *s == d.state) {
            self.states[i] += 1;
        }
        let a = &d.attitude;
        if a.valid.get() {
            self.valid += 1;
            if let Some(t) = d.context.truth.attitude() {
                self.errors.add(rpy_error_deg(&a.rpy, &t));
            } else if d.context.truth.no_deck() {
                self.attitudes_without_deck += 1;
            }
        }
        self.last_at = Instant::now();
    }

    pub fn drops(&self) -> DropReport {
        DropReport {
            counts: self.drops.totals(),
            observer: self.observer_missed,
        }
    }

    /// The live status line over the last `period` seconds (and starts the next period).
    pub fn status_line(&mut self, elapsed: f64, period: f64) -> String {
        let fps = self.recent_count as f64 / period;
        let h = &self.recent;
        let decision = match &self.last {
            Some(d) => {
                // The predicted calm window: when it starts (from now) and how long it lasts.
                let window = if d.calm_window_start_s.is_finite() && d.calm_window_length_s.is_finite() {
                    format!(
                        " (calm in {:.1} s for {:.1} s)",
                        d.calm_window_start_s, d.calm_window_length_s
                    )
                } else {
                    String::new()
                };
                let state = format!("{} {}{window}", d.state.get().name(), d.reason.get().name());
                if d.attitude.valid.get() {
                    let [r, p, y] = d.attitude.rpy.to_degrees();
                    format!("{state} | r {r:+.2} p {p:+.2} y {y:+.1} deg")
                } else {
                    state
                }
            }
            None => "no decision yet".into(),
        };
        // Every interval, by its short name: `capture`, `hop`, each stage's, `e2e`.
        let p50: Vec<String> = LatencyInterval::ALL
            .iter()
            .map(|&i| {
                let name = match i {
                    LatencyInterval::Hop => "hop",
                    LatencyInterval::EndToEnd => "e2e",
                    i => i.name(),
                };
                format!("{name} {:.2}", h.p50_ms(i))
            })
            .collect();
        let line = format!(
            "[{elapsed:7.1} s] {fps:5.1} fps | p50 ms: {} | drops {} | {decision}",
            p50.join(" "),
            self.drops.totals().total().saturating_add(self.observer_missed),
        );
        self.recent.reset();
        self.recent_count = 0;
        line
    }

    /// The final report.
    pub fn report(&self, duration_s: f64, restarts: Vec<(String, u32)>, interrupted: bool) -> RunReport {
        RunReport {
            decisions: self.decisions,
            watchdog_decisions: self.watchdog,
            duration_s,
            latency: self.all.rows(),
            drops: self.drops(),
            restarts,
            states: DecisionState::ALL
                .iter()
                .zip(self.states)
                .map(|(s, c)| (s.name().to_string(), c))
                .collect(),
            valid_attitudes: self.valid,
            rmse_deg: (self.errors.n > 0).then(|| self.errors.rmse()),
            max_error_deg: (self.errors.n > 0).then_some(self.errors.max),
            attitudes_without_deck: self.attitudes_without_deck,
            interrupted,
            decisions_csv_error: self
                .csv_error
                .as_ref()
                .map(|(e, rows)| format!("incomplete after {rows} rows: {e}")),
            bad_decisions_skipped: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::{DecisionReason, PipelineStage, StageSpan, Truth};
    use deckwatch_common::Rpy;

    #[test]
    fn restarting_counter_sums_across_restarts() {
        let mut c = RestartingCounter::default();
        for v in [0, 2, 5, 5, 1, 3, 0, 4] {
            c.update(v);
        }
        // 0 -> 5 (5), restart -> 3 (3), restart -> 4 (4).
        assert_eq!(c.total, 12);
        c.update(u64::MAX);
        c.update(2);
        assert_eq!(c.total, u64::MAX, "saturates instead of overflowing");
    }

    fn decision(seq: u64, state: DecisionState, capture_drops: u64) -> LandingDecision {
        let mut d = LandingDecision {
            state: state.into(),
            reason: DecisionReason::Warmup.into(),
            ..Default::default()
        };
        d.stamp.seq = seq;
        d.stamp.drops.capture = capture_drops;
        d.stamp.times.captured_ns = 1_000;
        d.stamp.times.published_ns = 2_000;
        d.stamp.times[PipelineStage::Detect] = StageSpan {
            received_ns: 2_500,
            finished_ns: 3_000_000,
        };
        d.stamp.times[PipelineStage::Estimate].finished_ns = 4_000_000;
        d.stamp.times[PipelineStage::Decide].finished_ns = 5_000_000;
        d.attitude.valid = true.into();
        d.attitude.rpy = Rpy::from_degrees(1.0, 2.0, 3.0);
        d.context.truth = Truth {
            known: true.into(),
            roll_deg: 1.5,
            pitch_deg: 2.0,
            yaw_deg: 3.0,
            ..Truth::UNKNOWN
        };
        d
    }

    #[test]
    fn observer_counts_states_drops_latency_and_error() {
        let mut o = Observer::new(None).unwrap();
        o.observe(&decision(0, DecisionState::Hold, 0));
        // Frame 1 dropped by capture, frame 3 missed by the launcher itself.
        o.observe(&decision(2, DecisionState::ClearToLand, 1));
        o.observe(&decision(4, DecisionState::Hold, 1));
        let mut w = decision(4, DecisionState::NoDeck, 1);
        w.watchdog = true.into();
        o.observe(&w);
        let r = o.report(1.0, vec![("detect".into(), 2)], false);
        assert_eq!((r.decisions, r.watchdog_decisions, r.valid_attitudes), (3, 1, 3));
        assert_eq!(r.states[1], ("HOLD".to_string(), 2));
        assert_eq!(r.states[2], ("CLEAR".to_string(), 1));
        assert_eq!((r.drops.counts.capture, r.drops.observer), (1, 1));
        let e2e = r.latency.iter().find(|l| l.interval == "end-to-end").unwrap();
        assert_eq!(e2e.count, 3);
        assert!((e2e.p50_ms - 4.998).abs() < 0.01, "{}", e2e.p50_ms);
        assert!((r.rmse_deg.unwrap()[0] - 0.5).abs() < 1e-9);
        let line = o.status_line(1.0, 1.0);
        assert!(line.contains("3.0 fps") && line.contains("NO-DECK"), "{line}");
        assert!(
            line.contains(
                "| p50 ms: capture 0.00 hop 0.00 detect 3.00 estimate 1.00 decide 1.00 e2e 5.00 | drops 2 |"
            ),
            "{line}"
        );
        let drops: Vec<_> = r.drops.counts.named().into_iter().collect();
        assert_eq!(
            drops,
            [
                ("capture", 1),
                ("bad_frames", 0),
                ("detect", 0),
                ("estimate", 0),
                ("decide", 0)
            ]
        );
    }
}
