//! The decide stage's per-message step, without transport: the [`LandingDecider`] applied to
//! the attitude stream, and its watchdog for an attitude stream that stops.

use crate::decision::{DecisionConfig, LandingDecider};
use deckwatch_common::messages::{monotonic_ns, AttitudeMessage, GapCounter, LandingDecision};

/// The `[decide]` section of a pipeline configuration (TOML); errors name file, line, key.
pub fn config_from_toml(file: &str, text: &str) -> Result<DecisionConfig, String> {
    #[derive(serde::Deserialize)]
    struct Doc {
        #[serde(default)]
        decide: DecisionConfig,
    }
    let doc: Doc = toml::from_str(text).map_err(|e| format!("{file}: {e}"))?;
    doc.decide.validate().map_err(|e| format!("{file}: decide.{e}"))?;
    Ok(doc.decide)
}

/// State of the decide stage across messages.
pub struct DecideStage {
    decider: LandingDecider,
    gaps: GapCounter,
    last: Option<LandingDecision>,
    pub dropped: u64,
    pub processed: u64,
    pub watchdog_decisions: u64,
}

fn seconds(ns: u64) -> f64 {
    ns as f64 / 1e9
}

impl DecideStage {
    /// `joined_late`: the pipeline was already running (see [`GapCounter::new`]).
    pub fn new(config: DecisionConfig, joined_late: bool) -> Result<Self, String> {
        Ok(Self {
            decider: LandingDecider::new(config)?,
            gaps: GapCounter::new(joined_late),
            last: None,
            dropped: 0,
            processed: 0,
            watchdog_decisions: 0,
        })
    }

    /// How often the watchdog should be called.
    pub fn watchdog_period(&self) -> std::time::Duration {
        std::time::Duration::from_secs_f64(self.decider.config().max_age_ms / 2e3)
    }

    /// The decision on one attitude received at `received_ns`.
    pub fn process(&mut self, a: &AttitudeMessage, received_ns: u64) -> LandingDecision {
        self.dropped += self.gaps.observe(a.stamp.seq, a.stamp.drops.total());
        self.processed += 1;
        let attitude = a.valid.then(|| {
            let [r, p, _] = a.rpy.to_degrees();
            [r, p]
        });
        let captured = a.stamp.times.captured_ns;
        // A message without a capture time cannot be judged fresh.
        let t = if captured == 0 {
            f64::NAN
        } else {
            seconds(captured)
        };
        let d = self.decider.update(t, attitude, seconds(received_ns));
        let (start, length) = d.calm_window.unwrap_or((f64::NAN, f64::NAN));
        let mut out = LandingDecision {
            stamp: a.stamp,
            context: a.context,
            attitude: *a,
            state: d.state,
            reason: d.reason,
            calm_window_start_s: start,
            calm_window_length_s: length,
            watchdog: false,
        };
        out.stamp.drops.decide = self.dropped;
        out.stamp.times.decide_received_ns = received_ns;
        out.stamp.times.decide_finished_ns = monotonic_ns();
        self.last = Some(out);
        out
    }

    /// When no attitude came for too long: the stale decision to publish (once).
    pub fn watchdog(&mut self, now_ns: u64) -> Option<LandingDecision> {
        let d = self.decider.timeout(seconds(now_ns))?;
        let mut out = self.last?;
        out.state = d.state;
        out.reason = d.reason;
        out.calm_window_start_s = f64::NAN;
        out.calm_window_length_s = f64::NAN;
        out.watchdog = true;
        out.stamp.times.decide_received_ns = now_ns;
        out.stamp.times.decide_finished_ns = monotonic_ns();
        self.watchdog_decisions += 1;
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::{DecisionReason, DecisionState};
    use deckwatch_common::Rpy;

    #[test]
    fn invalid_stale_and_silence_never_clear() {
        let mut s = DecideStage::new(DecisionConfig::default(), false).unwrap();
        let mut a = AttitudeMessage {
            valid: true,
            rpy: Rpy::from_degrees(1.0, 1.0, 0.0),
            ..Default::default()
        };
        a.stamp.times.captured_ns = 1_000_000_000;
        let d = s.process(&a, 1_010_000_000);
        assert_eq!((d.state, d.reason), (DecisionState::Hold, DecisionReason::Warmup));
        a.stamp.seq = 1;
        a.stamp.times.captured_ns = 1_100_000_000;
        let d = s.process(&a, 2_000_000_000);
        assert_eq!(
            (d.state, d.reason),
            (DecisionState::NoDeck, DecisionReason::StaleData)
        );
        a.valid = false;
        a.stamp.seq = 2;
        assert_eq!(s.process(&a, 1_210_000_000).state, DecisionState::NoDeck);
        // Silence: the watchdog speaks once.
        assert!(s.watchdog(1_300_000_000).is_none());
        let w = s.watchdog(2_300_000_000).unwrap();
        assert!(w.watchdog && w.reason == DecisionReason::StaleData);
        assert!(s.watchdog(2_400_000_000).is_none());
        let e = config_from_toml("d.toml", "[decide]\nmax_age_ms = -1\n").unwrap_err();
        assert!(e.contains("decide.max_age_ms"), "{e}");
    }
}
