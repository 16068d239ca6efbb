//! The detect stage: from a frame (header and pixels, read in place) to the [`MarkerMessage`]
//! that goes to estimate, with the stage's timing and drop counts. A frame that does not match
//! its header is answered with `BadFrame`, never a panic.

use crate::config::{ConfigError, PipelineConfig};
use crate::stage::{Frame, Frames, Stage};
use deckwatch_common::markers::{DetectionStatus, MarkerSet};
use deckwatch_common::messages::{
    monotonic_ns, FrameHeader, GapCounter, MarkerMessage, PipelineStage, PixelFormat, StageSpan,
};
use deckwatch_common::GrayView;
use deckwatch_common::InvalidField;
use deckwatch_detect::{Detector, DetectorConfig};
use deckwatch_viz::entities::{crop_image_item, DeckCrop};
use deckwatch_viz::{Item, RerunConfig};

/// State of the detect stage across frames.
#[derive(Default)]
pub struct DetectStage {
    detector: Option<Detector>,
    /// The viewer's configuration: which frames' deck crop is logged (None: nothing is).
    viewer: Option<RerunConfig>,
    /// The newest frame's deck crop and its image, for the viewer.
    crop: Option<(DeckCrop, Option<Item>)>,
    gaps: GapCounter,
    /// Frames this stage never processed (cumulative).
    pub dropped: u64,
    /// Frames that did not match their header (answered with `BadFrame`).
    pub bad_frames: u64,
    pub processed: u64,
    warning: Option<String>,
}

impl Stage for DetectStage {
    const PLACE: PipelineStage = PipelineStage::Detect;
    type Input = Frames;
    type Output = MarkerMessage;

    fn from_config(config: &PipelineConfig, joined_late: bool) -> Result<Self, ConfigError> {
        let mut stage = Self::new(joined_late);
        stage.viewer = Some(config.rerun.clone()).filter(|r| r.logs_image(0));
        Ok(stage)
    }

    fn step(&mut self, frame: Frame<'_>, received_ns: u64) -> MarkerMessage {
        let (message, problem) = self.process(frame.header, frame.pixels, received_ns);
        self.warning = problem.map(|p| format!("bad {p}"));
        // The deck region of the frames whose image is logged, cut while the pixels are here.
        let seq = message.stamp.seq;
        self.crop = self
            .viewer
            .as_ref()
            .filter(|v| v.logs_image(seq) && problem_free(&message))
            .and_then(|_| DeckCrop::of(&message.markers, frame.header.width, frame.header.height))
            .map(|crop| {
                let t = message.stamp.times.captured_ns;
                let stride = frame.header.stride as usize;
                (crop, crop_image_item(seq, t, crop, frame.pixels, stride))
            });
        message
    }

    fn take_warning(&mut self) -> Option<String> {
        self.warning.take()
    }

    fn viewer_items(&mut self, m: &MarkerMessage) -> Vec<Item> {
        let (crop, image) = match self.crop.take() {
            Some((crop, image)) => (Some(crop), image),
            None => (None, None),
        };
        let mut items: Vec<Item> = image.into_iter().collect();
        items.extend(deckwatch_viz::entities::marker_items(m, crop));
        items
    }

    fn summary(&self) -> String {
        let searches = self.detector.as_ref().map(|d| d.searches()).unwrap_or_default();
        format!(
            "{} frames processed, {} dropped, {} bad; markers found by tracking {}, around the \
             last pattern {}, in the whole frame {}",
            self.processed, self.dropped, self.bad_frames, searches.tracked, searches.window, searches.full
        )
    }
}

/// A marker set worth cropping around (a bad frame's markers are not).
fn problem_free(m: &MarkerMessage) -> bool {
    m.markers.status.get() != DetectionStatus::BadFrame
}

impl DetectStage {
    /// `joined_late`: the pipeline was already running (see [`GapCounter::new`]).
    pub fn new(joined_late: bool) -> Self {
        Self {
            gaps: GapCounter::new(joined_late),
            ..Self::default()
        }
    }

    /// Detects the markers of one frame received at `received_ns`; the second value says what
    /// was wrong with a bad frame.
    pub fn process(
        &mut self,
        header: &FrameHeader,
        pixels: &[u8],
        received_ns: u64,
    ) -> (MarkerMessage, Option<String>) {
        self.dropped += self.gaps.observe(header.stamp.seq, header.stamp.drops.total());
        self.processed += 1;
        let (markers, problem) = match self.detect(header, pixels) {
            Ok(m) => (m, None),
            Err(e) => {
                self.bad_frames += 1;
                let set = MarkerSet {
                    status: DetectionStatus::BadFrame.into(),
                    ..MarkerSet::default()
                };
                (set, Some(format!("frame {}: {e}", header.stamp.seq)))
            }
        };
        let mut stamp = header.stamp;
        stamp.drops[Self::PLACE] = self.dropped;
        stamp.times[Self::PLACE] = StageSpan {
            received_ns,
            finished_ns: monotonic_ns(),
        };
        let message = MarkerMessage {
            stamp,
            context: header.context,
            markers,
        };
        (message, problem)
    }

    /// The markers of a frame whose header checks out; else the header's field that does not
    /// (the frame is counted and reported as a bad frame).
    fn detect(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<MarkerSet, InvalidField> {
        let camera = h.context.camera;
        let deck = h.context.deck;
        if h.pixel_format != PixelFormat::Gray8 {
            return Err(InvalidField::new(
                "pixel_format",
                format!("{:?} is not supported", h.pixel_format),
            ));
        }
        if (h.width, h.height) != (camera.width, camera.height) {
            return Err(InvalidField::new(
                "width/height",
                format!(
                    "the frame is {}x{} but its camera is {}x{}",
                    h.width, h.height, camera.width, camera.height
                ),
            ));
        }
        camera
            .validate()
            .map_err(|e| InvalidField::new(format!("camera.{}", e.field), e.problem))?;
        deck.validate()
            .map_err(|e| InvalidField::new(format!("deck.{}", e.field), e.problem))?;
        let view = GrayView::new(pixels, h.width as usize, h.height as usize, h.stride as usize)
            .map_err(|e| InvalidField::new("pixels", e.to_string()))?;
        let fresh = match &self.detector {
            Some(d) => d.camera() != &camera || d.deck() != &deck,
            None => true,
        };
        if fresh {
            self.detector = Some(Detector::new(
                camera,
                deck,
                DetectorConfig::for_camera(&camera, &deck),
            ));
        }
        Ok(self.detector.as_mut().expect("set above").detect(view))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::FrameStamp;
    use deckwatch_common::{CameraModel, DeckLayout};

    fn header(seq: u64, w: u32, h: u32) -> FrameHeader {
        let mut hd = FrameHeader {
            width: w,
            height: h,
            stride: w,
            ..Default::default()
        };
        hd.stamp = FrameStamp {
            seq,
            ..Default::default()
        };
        hd.context.camera = CameraModel::preset("rpi-v2").unwrap().scaled_to(w, h);
        hd.context.deck = DeckLayout::paper();
        hd
    }

    #[test]
    fn bad_frames_are_answered_and_counted() {
        let mut s = DetectStage::new(false);
        let px = vec![0u8; 64 * 48];
        let (m, p) = s.process(&header(0, 64, 48), &px, 1);
        assert_eq!(m.markers.status, DetectionStatus::NoDeck);
        assert!(p.is_none());
        // Payload shorter than the header says.
        let (m, p) = s.process(&header(1, 64, 48), &px[..100], 2);
        assert_eq!(m.markers.status, DetectionStatus::BadFrame);
        assert!(p.unwrap().contains("pixels"));
        // Size differs from the camera's.
        let mut h = header(2, 64, 48);
        h.width = 32;
        let (m, _) = s.process(&h, &px, 3);
        assert_eq!(m.markers.status, DetectionStatus::BadFrame);
        assert_eq!(s.bad_frames, 2);
        // Frames 3 and 4 never arrived.
        let (m, _) = s.process(&header(5, 64, 48), &px, 4);
        assert_eq!(m.stamp.drops[PipelineStage::Detect], 2);
        assert_eq!(m.stamp.times[PipelineStage::Detect].received_ns, 4);
        assert!(m.stamp.times[PipelineStage::Detect].finished_ns >= 4);
    }
}
