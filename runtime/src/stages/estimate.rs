//! The estimate stage: from a [`MarkerMessage`] to the [`AttitudeMessage`] that goes to decide,
//! through [`DeckEstimator`] (the estimation pipeline lives there); this adapter adds the
//! stage's stamps, drop counts and viewer items. With `compare`, the other family's result rides
//! along (`AttitudeMessage::alternative`).

use crate::config::{ConfigError, PipelineConfig};
use crate::stage::Stage;
use deckwatch_common::messages::{
    monotonic_ns, AttitudeMessage, Channel, GapCounter, MarkerMessage, PipelineStage, StageSpan,
    VehicleSample,
};
use deckwatch_common::vehicle::VehicleConfig;
use deckwatch_estimate::{DeckEstimator, EstimateConfig};
use deckwatch_viz::Item;

/// State of the estimate stage across frames.
pub struct EstimateStage {
    estimator: DeckEstimator,
    gaps: GapCounter,
    pub dropped: u64,
    pub processed: u64,
    /// The viewer's configuration: which frames' deck crop is drawn on (None: none).
    viewer: Option<deckwatch_viz::RerunConfig>,
    /// The newest input's deck crop (the same as detect's: a function of the markers).
    crop: Option<deckwatch_viz::entities::DeckCrop>,
}

impl EstimateStage {
    /// `joined_late`: the pipeline was already running (see [`GapCounter::new`]).
    pub fn new(config: &EstimateConfig, vehicle: &VehicleConfig, joined_late: bool) -> Self {
        Self {
            estimator: DeckEstimator::new(config, vehicle),
            gaps: GapCounter::new(joined_late),
            dropped: 0,
            processed: 0,
            viewer: None,
            crop: None,
        }
    }

    /// The estimator's counters (frozen images, uncompensated frames, attitudes).
    pub fn estimator(&self) -> &DeckEstimator {
        &self.estimator
    }

    /// The attitude of one frame's markers, received at `received_ns`.
    pub fn process(&mut self, m: &MarkerMessage, received_ns: u64) -> AttitudeMessage {
        self.dropped += self.gaps.observe(m.stamp.seq, m.stamp.drops.total());
        self.processed += 1;
        let mut out = self.estimator.estimate(m);
        out.stamp.drops[Self::PLACE] = self.dropped;
        out.stamp.times[Self::PLACE] = StageSpan {
            received_ns,
            finished_ns: monotonic_ns(),
        };
        out
    }

    /// A vehicle attitude sample from the autopilot (kept for the frames to come).
    pub fn observe_vehicle(&mut self, sample: &VehicleSample) {
        self.estimator.observe_vehicle(sample)
    }
}

impl Stage for EstimateStage {
    const PLACE: PipelineStage = PipelineStage::Estimate;
    type Input = MarkerMessage;
    type Output = AttitudeMessage;
    const SIDE_INPUTS: &'static [&'static str] = &[VehicleSample::SERVICE];

    fn from_config(config: &PipelineConfig, joined_late: bool) -> Result<Self, ConfigError> {
        let mut stage = Self::new(&config.estimate, &config.vehicle, joined_late);
        stage.viewer = Some(config.rerun.clone()).filter(|r| r.logs_image(0));
        Ok(stage)
    }

    fn wants_vehicle(&self) -> bool {
        self.estimator.wants_vehicle()
    }

    fn vehicle_sample(&mut self, sample: &VehicleSample) {
        self.observe_vehicle(sample)
    }

    fn step(&mut self, m: &MarkerMessage, received_ns: u64) -> AttitudeMessage {
        self.crop = self
            .viewer
            .as_ref()
            .filter(|v| v.logs_image(m.stamp.seq))
            .and_then(|_| {
                let camera = &m.context.camera;
                deckwatch_viz::entities::DeckCrop::of(&m.markers, camera.width, camera.height)
            });
        self.process(m, received_ns)
    }

    fn viewer_items(&mut self, a: &AttitudeMessage) -> Vec<Item> {
        deckwatch_viz::entities::attitude_items(a, self.crop.take())
    }

    fn summary(&self) -> String {
        let e = &self.estimator;
        let motion = if e.motion_unknown > 0 {
            format!(
                ", {} rolling-shutter frames with part of their motion unknown",
                e.motion_unknown
            )
        } else {
            String::new()
        };
        format!(
            "{} marker sets, {} attitudes, {} dropped, {} not compensated for the vehicle, {} frozen images{motion}",
            self.processed, e.estimated, self.dropped, e.uncompensated, e.frozen
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::markers::{DetectionStatus, Marker, MarkerSet};
    use deckwatch_common::messages::{AttitudeFailure, DecisionReason};
    use deckwatch_common::{CameraModel, DeckLayout};

    /// A frozen image found by the estimator reaches decide as a frozen input (not a missing
    /// one: a committed touchdown aborts), and the stage stamps what it passes on. (The markers
    /// need not make a deck: a repeated set is a frozen image whatever it shows; the estimator's
    /// own tests cover real decks.)
    #[test]
    fn a_frozen_image_is_refused_and_decide_says_so() {
        let mut m = MarkerMessage::default();
        m.context.camera = CameraModel::preset("rpi-v2").unwrap();
        m.context.deck = DeckLayout::paper();
        m.markers = MarkerSet {
            status: DetectionStatus::Partial.into(),
            ..Default::default()
        };
        for (i, [u, v]) in [[1200.5, 900.25], [1300.0, 950.75]].into_iter().enumerate() {
            m.markers.markers[i] = Marker {
                valid: true.into(),
                u,
                v,
                ..Default::default()
            };
        }
        let mut s = EstimateStage::new(&EstimateConfig::default(), &VehicleConfig::default(), false);
        let out: Vec<AttitudeMessage> = (0..3).map(|k| s.process(&m, 1000 + k)).collect();
        assert_ne!(out[0].failure, AttitudeFailure::FrozenImage);
        assert_eq!(out[1].failure, AttitudeFailure::FrozenImage, "the first repeat");
        assert_eq!(out[2].failure, AttitudeFailure::FrozenImage);
        assert_eq!(out[1].stamp.times[PipelineStage::Estimate].received_ns, 1001);
        assert!(out[1].stamp.times[PipelineStage::Estimate].finished_ns > 0);
        assert_eq!((s.processed, s.estimator().frozen), (3, 2));
        let mut d =
            crate::stages::DecideStage::new(deckwatch_decide::DecisionConfig::default(), false).unwrap();
        let mut frozen = out[2];
        frozen.stamp.times.captured_ns = 1_000_000_000;
        let decided = d.process(&frozen, 1_010_000_000);
        assert_eq!(decided.reason, DecisionReason::FrozenInput);
    }
}
