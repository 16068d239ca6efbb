//! `[estimate]` of the pipeline configuration: which estimator leads, and whether the other
//! family runs beside it for comparison.

use crate::PaperVariant;
use deckwatch_common::messages::EstimatorKind;
use serde::{Deserialize, Serialize};

/// `[estimate]` of the pipeline configuration.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct EstimateConfig {
    /// `full-pose` (default: it measures better, BENCHMARKS.md), `paper-atan2`,
    /// `paper-printed` or `paper-fitted-major-axis`.
    pub estimator: EstimatorKind,
    /// Also run the other family (paper `atan2` beside the full pose, or the full pose beside
    /// a paper variant) and publish its result for comparison.
    pub compare: bool,
    /// With a rolling shutter (the camera's `readout_s` > 0), the full pose takes each marker
    /// at its row's instant, turned by the vehicle's rate and the deck's recent motion
    /// (`FrameMotion`); false: every marker at the frame's instant (for comparison).
    pub rolling_shutter: bool,
}

impl Default for EstimateConfig {
    fn default() -> Self {
        Self {
            estimator: EstimatorKind::FullPose,
            compare: true,
            rolling_shutter: true,
        }
    }
}

impl EstimateConfig {
    /// The estimator that runs beside the configured one (`compare`), if any.
    pub fn secondary(&self) -> Option<EstimatorKind> {
        self.compare
            .then_some(if self.estimator == EstimatorKind::FullPose {
                EstimatorKind::PaperAtan2
            } else {
                EstimatorKind::FullPose
            })
    }
}

/// The paper variant an estimator kind names (None: the full pose).
pub fn paper_variant(kind: EstimatorKind) -> Option<PaperVariant> {
    match kind {
        EstimatorKind::PaperAtan2 => Some(PaperVariant::Atan2),
        EstimatorKind::PaperPrinted => Some(PaperVariant::Printed),
        EstimatorKind::PaperFittedMajorAxis => Some(PaperVariant::FittedMajorAxis),
        EstimatorKind::FullPose => None,
    }
}
