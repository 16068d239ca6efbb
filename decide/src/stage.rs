//! The decide stage's per-message step, without transport, and its `[decide]` configuration.

use crate::LandingCapacity;
use deckwatch_common::messages::{
    monotonic_ns, AttitudeMessage, DecisionReason, DecisionState, GapCounter, LandingDecision,
};
use serde::{Deserialize, Serialize};

/// `[decide]` of the pipeline configuration.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct DecideConfig {
    pub max_abs_roll_deg: f64,
    pub max_abs_pitch_deg: f64,
    /// An attitude older than this (from capture to decide) is stale.
    pub max_age_ms: f64,
}

impl Default for DecideConfig {
    fn default() -> Self {
        Self {
            max_abs_roll_deg: 5.0,
            max_abs_pitch_deg: 5.0,
            max_age_ms: 300.0,
        }
    }
}

impl DecideConfig {
    /// The `[decide]` section of a pipeline configuration (TOML); errors name file, line, key.
    pub fn from_toml(file: &str, text: &str) -> Result<Self, String> {
        #[derive(Deserialize)]
        struct Doc {
            #[serde(default)]
            decide: DecideConfig,
        }
        let doc: Doc = toml::from_str(text).map_err(|e| format!("{file}: {e}"))?;
        doc.decide.validate().map_err(|e| format!("{file}: decide.{e}"))?;
        Ok(doc.decide)
    }

    pub fn validate(&self) -> Result<(), String> {
        self.capacity()
            .validate()
            .map_err(|e| e.replace("field `", "").replace('`', ""))?;
        if !(self.max_age_ms.is_finite() && self.max_age_ms > 0.0) {
            return Err(format!("max_age_ms: must be positive, got {}", self.max_age_ms));
        }
        Ok(())
    }

    pub fn capacity(&self) -> LandingCapacity {
        LandingCapacity {
            max_abs_roll_deg: self.max_abs_roll_deg,
            max_abs_pitch_deg: self.max_abs_pitch_deg,
        }
    }
}

/// State of the decide stage across messages.
pub struct DecideStage {
    config: DecideConfig,
    gaps: GapCounter,
    pub dropped: u64,
    pub processed: u64,
}

impl DecideStage {
    /// `joined_late`: the pipeline was already running (see [`GapCounter::new`]).
    pub fn new(config: DecideConfig, joined_late: bool) -> Result<Self, String> {
        config.validate()?;
        Ok(Self {
            config,
            gaps: GapCounter::new(joined_late),
            dropped: 0,
            processed: 0,
        })
    }

    /// The decision on one attitude received at `received_ns`.
    pub fn process(&mut self, a: &AttitudeMessage, received_ns: u64) -> LandingDecision {
        self.dropped += self.gaps.observe(a.stamp.seq, a.stamp.drops.total());
        self.processed += 1;
        let age_ms = received_ns.saturating_sub(a.stamp.times.captured_ns) as f64 / 1e6;
        let (state, reason) = if !a.valid {
            (DecisionState::NoDeck, DecisionReason::InvalidAttitude)
        } else if a.stamp.times.captured_ns == 0 || age_ms > self.config.max_age_ms {
            (DecisionState::Hold, DecisionReason::StaleData)
        } else if self.config.capacity().naive_within(&a.rpy) {
            (DecisionState::ClearToLand, DecisionReason::WithinCapacity)
        } else {
            (DecisionState::Hold, DecisionReason::OutsideCapacity)
        };
        let mut d = LandingDecision {
            stamp: a.stamp,
            context: a.context,
            attitude: *a,
            state,
            reason,
            calm_window_start_s: f64::NAN,
            calm_window_length_s: f64::NAN,
        };
        d.stamp.drops.decide = self.dropped;
        d.stamp.times.decide_received_ns = received_ns;
        d.stamp.times.decide_finished_ns = monotonic_ns();
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::Rpy;

    #[test]
    fn invalid_stale_and_outside_never_clear() {
        let mut s = DecideStage::new(DecideConfig::default(), false).unwrap();
        let mut a = AttitudeMessage {
            valid: true,
            rpy: Rpy::from_degrees(1.0, 1.0, 0.0),
            ..Default::default()
        };
        a.stamp.times.captured_ns = 1_000_000_000;
        let d = s.process(&a, 1_010_000_000);
        assert_eq!(d.state, DecisionState::ClearToLand);
        let d = s.process(&a, 2_000_000_000);
        assert_eq!(
            (d.state, d.reason),
            (DecisionState::Hold, DecisionReason::StaleData)
        );
        a.valid = false;
        assert_eq!(s.process(&a, 1_010_000_000).state, DecisionState::NoDeck);
        a.valid = true;
        a.rpy = Rpy::from_degrees(6.0, 0.0, 0.0);
        assert_eq!(
            s.process(&a, 1_010_000_000).reason,
            DecisionReason::OutsideCapacity
        );
        let e = DecideConfig::from_toml("d.toml", "[decide]\nmax_age_ms = -1\n").unwrap_err();
        assert!(e.contains("decide.max_age_ms"), "{e}");
    }
}
