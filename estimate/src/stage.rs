//! The estimate stage's per-frame step, without transport: from a [`MarkerMessage`] to the
//! [`AttitudeMessage`] that goes to decide, and the stage's `[estimate]` configuration.

use crate::{NotEstimable, PaperEstimator, PaperVariant};
use deckwatch_common::markers::DetectionStatus;
use deckwatch_common::messages::{
    monotonic_ns, AttitudeFailure, AttitudeMessage, EstimatorKind, GapCounter, MarkerMessage,
};
use serde::{Deserialize, Serialize};

/// `[estimate]` of the pipeline configuration.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct EstimateConfig {
    /// `paper-atan2` (default), `paper-printed` or `paper-fitted-major-axis`.
    pub estimator: String,
}

impl Default for EstimateConfig {
    fn default() -> Self {
        Self {
            estimator: EstimatorKind::PaperAtan2.name().into(),
        }
    }
}

impl EstimateConfig {
    /// The `[estimate]` section of a pipeline configuration (TOML); errors name file, line, key.
    pub fn from_toml(file: &str, text: &str) -> Result<Self, String> {
        #[derive(Deserialize)]
        struct Doc {
            #[serde(default)]
            estimate: EstimateConfig,
        }
        let doc: Doc = toml::from_str(text).map_err(|e| format!("{file}: {e}"))?;
        doc.estimate.kind()?;
        Ok(doc.estimate)
    }

    pub fn kind(&self) -> Result<EstimatorKind, String> {
        ESTIMATORS
            .iter()
            .find(|(k, _)| k.name() == self.estimator)
            .map(|(k, _)| *k)
            .ok_or_else(|| {
                let names: Vec<&str> = ESTIMATORS.iter().map(|(k, _)| k.name()).collect();
                format!(
                    "estimate.estimator: unknown `{}` ({})",
                    self.estimator,
                    names.join(", ")
                )
            })
    }
}

const ESTIMATORS: [(EstimatorKind, PaperVariant); 3] = [
    (EstimatorKind::PaperAtan2, PaperVariant::Atan2),
    (EstimatorKind::PaperPrinted, PaperVariant::Printed),
    (EstimatorKind::PaperFittedMajorAxis, PaperVariant::FittedMajorAxis),
];

fn failure_of(e: &NotEstimable) -> AttitudeFailure {
    match e {
        NotEstimable::CentreMissing
        | NotEstimable::BowMissing
        | NotEstimable::TooFewRingMarkers { .. }
        | NotEstimable::AmbiguousDeckPlane
        | NotEstimable::WrongMarkerCount { .. } => AttitudeFailure::TooFewMarkers,
        NotEstimable::AltitudeRequired | NotEstimable::InvalidAltitude => AttitudeFailure::NoAltitude,
        _ => AttitudeFailure::Degenerate,
    }
}

/// State of the estimate stage across frames.
pub struct EstimateStage {
    kind: EstimatorKind,
    variant: PaperVariant,
    estimator: Option<PaperEstimator>,
    gaps: GapCounter,
    pub dropped: u64,
    pub processed: u64,
    pub estimated: u64,
}

impl EstimateStage {
    /// `joined_late`: the pipeline was already running (see [`GapCounter::new`]).
    pub fn new(config: &EstimateConfig, joined_late: bool) -> Result<Self, String> {
        let kind = config.kind()?;
        let variant = ESTIMATORS
            .iter()
            .find(|(k, _)| *k == kind)
            .map(|(_, v)| *v)
            .expect("listed");
        Ok(Self {
            kind,
            variant,
            estimator: None,
            gaps: GapCounter::new(joined_late),
            dropped: 0,
            processed: 0,
            estimated: 0,
        })
    }

    /// The attitude of one frame's markers, received at `received_ns`.
    pub fn process(&mut self, m: &MarkerMessage, received_ns: u64) -> AttitudeMessage {
        self.dropped += self.gaps.observe(m.stamp.seq, m.stamp.drops.total());
        self.processed += 1;
        let mut out = AttitudeMessage {
            stamp: m.stamp,
            context: m.context,
            estimator: self.kind,
            ..Default::default()
        };
        out.stamp.drops.estimate = self.dropped;
        out.stamp.times.estimate_received_ns = received_ns;
        out.failure = match m.markers.status {
            DetectionStatus::NoDeck => AttitudeFailure::NoDeck,
            DetectionStatus::BadFrame => AttitudeFailure::BadFrame,
            DetectionStatus::Ok | DetectionStatus::Partial => self.estimate(m, &mut out),
        };
        out.valid = out.failure == AttitudeFailure::None;
        self.estimated += out.valid as u64;
        out.stamp.times.estimate_finished_ns = monotonic_ns();
        out
    }

    fn estimate(&mut self, m: &MarkerMessage, out: &mut AttitudeMessage) -> AttitudeFailure {
        let (camera, deck) = (m.context.camera, m.context.deck);
        if camera.validate().is_err() || deck.validate().is_err() {
            return AttitudeFailure::BadFrame;
        }
        let stale = self
            .estimator
            .as_ref()
            .is_none_or(|e| e.camera() != &camera || e.deck() != &deck);
        if stale {
            self.estimator = Some(PaperEstimator::new(camera, deck, self.variant));
        }
        let est = self.estimator.as_ref().expect("set above");
        let altitude = m.context.altitude_m.is_finite().then_some(m.context.altitude_m);
        match est.estimate(&m.markers.pixels(deck.marker_count()), altitude) {
            Ok(e) => {
                out.rpy = e.attitude.rpy;
                out.quaternion = e.attitude.quaternion;
                out.euler313 = e.attitude.euler313;
                out.has_image_ellipse = e.image_ellipse.is_some();
                out.image_ellipse = e.image_ellipse.unwrap_or_default();
                out.residual = e.fit_rms_m;
                out.markers_used = (e.ring_markers_used + 2) as u32;
                AttitudeFailure::None
            }
            Err(e) => failure_of(&e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::markers::{Marker, MarkerSet};
    use deckwatch_common::rotation::rpy_error_deg;
    use deckwatch_common::{CameraModel, DeckLayout, Rpy, SceneGeometry, Viewpoint};

    #[test]
    fn config_names_the_key() {
        let e = EstimateConfig::from_toml("x.toml", "[estimate]\nestimator = \"magic\"\n").unwrap_err();
        assert!(e.contains("estimate.estimator") && e.contains("magic"), "{e}");
        let e = EstimateConfig::from_toml("x.toml", "[estimate]\nestimatr = 1\n").unwrap_err();
        assert!(e.contains("x.toml") && e.contains("estimatr"), "{e}");
    }

    #[test]
    fn exact_markers_give_the_attitude_and_no_deck_gives_none() {
        let camera = CameraModel::preset("rpi-v2").unwrap();
        let deck = DeckLayout::paper();
        let truth = Rpy::from_degrees(3.0, -2.0, 10.0);
        let scene = SceneGeometry {
            attitude: truth.to_matrix(),
            viewpoint: Viewpoint {
                offset_x_m: 0.0,
                offset_y_m: 0.0,
                altitude_m: 5.0,
            },
        };
        let mut m = MarkerMessage::default();
        m.context.camera = camera;
        m.context.deck = deck;
        m.context.altitude_m = 5.0;
        m.markers = MarkerSet {
            status: DetectionStatus::Ok,
            ..Default::default()
        };
        for (i, p) in scene.project_markers(&camera, &deck).iter().enumerate() {
            let [u, v] = p.unwrap();
            m.markers.markers[i] = Marker {
                valid: true,
                u,
                v,
                ..Default::default()
            };
        }
        let mut s = EstimateStage::new(&EstimateConfig::default(), false).unwrap();
        let a = s.process(&m, 7);
        assert!(a.valid);
        assert!(rpy_error_deg(&a.rpy, &truth).iter().all(|e| *e < 1e-9));
        assert!(a.has_image_ellipse);
        m.markers.status = DetectionStatus::NoDeck;
        let a = s.process(&m, 8);
        assert!(!a.valid);
        assert_eq!(a.failure, AttitudeFailure::NoDeck);
    }
}
