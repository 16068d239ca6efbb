//! Every disc the full search finds, measured but not identified as the deck's markers: what
//! judges the centre estimator on images of other patterns (a printed calibration grid).

use super::*;

/// A disc measured by the detector's full search (frame pixels, OpenCV's convention: the
/// centre of the top-left pixel is (0, 0)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredDisc {
    /// The coverage-weighted centre (px).
    pub u_px: f64,
    pub v_px: f64,
    /// The radius of a circle of the blob's area at the half-way level (px).
    pub radius_px: f64,
    /// The plateau over the background at the disc's brightest pixel (DN).
    pub contrast_dn: f64,
    /// Minor over major axis of the blob's moment ellipse.
    pub roundness: f64,
    /// The centre's standard deviation per axis from the pixel noise (px).
    pub centre_std_px: f64,
}

impl MeasuredDisc {
    fn of(c: &super::Candidate) -> Self {
        Self {
            u_px: c.u,
            v_px: c.v,
            radius_px: c.radius,
            contrast_dn: c.contrast,
            roundness: c.roundness,
            centre_std_px: c.centre_std_px,
        }
    }
}

impl Detector {
    /// The disc in a region (x0, y0, x1, y1), half-open, of the frame, bright on a darker
    /// background, measured as marker detection measures each candidate (the region must
    /// hold that disc alone and some background around it); None when it is not a disc of the
    /// configured size and shape.
    pub fn measure_disc(
        &mut self,
        frame: GrayView<'_>,
        roi: (usize, usize, usize, usize),
    ) -> Option<MeasuredDisc> {
        let roi = (roi.0, roi.1, roi.2.min(frame.width()), roi.3.min(frame.height()));
        if roi.0 >= roi.2 || roi.1 >= roi.3 {
            return None;
        }
        self.measure(frame, roi).ok().map(|c| MeasuredDisc::of(&c))
    }

    /// The discs (bright on a darker background) that the full-frame search finds and measures
    /// in a region (x0, y0, x1, y1), half-open, of the frame: the same global threshold, coarse
    /// scan and measurement as marker detection, without identification, perspective
    /// correction or tracking (the tracking state is left as it was). Empty when the region has
    /// no contrast or is mostly bright.
    pub fn find_discs(
        &mut self,
        frame: GrayView<'_>,
        window: (usize, usize, usize, usize),
    ) -> Vec<MeasuredDisc> {
        let (x1, y1) = (window.2.min(frame.width()), window.3.min(frame.height()));
        if window.0 >= x1 || window.1 >= y1 {
            return Vec::new();
        }
        // The threshold from the region alone: the frame beyond it may be brighter than the
        // discs (a dark-on-light pattern, inverted, on a dark table).
        let Ok(region) = GrayView::new(
            &frame.data()[window.1 * frame.stride() + window.0..],
            x1 - window.0,
            y1 - window.1,
            frame.stride(),
        ) else {
            return Vec::new();
        };
        let Some((threshold, _)) = self.global_threshold(region) else {
            return Vec::new();
        };
        if self
            .search_discs(frame, threshold, (window.0, window.1, x1, y1))
            .is_none()
        {
            self.candidates.clear();
            return Vec::new();
        }
        self.candidates.drain(..).map(|c| MeasuredDisc::of(&c)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::GrayImage;

    /// A grid of sharp discs (sub-pixel positions, each pixel integrated over 4 x 4 samples) is
    /// found whole, each centre within a twentieth of a pixel; outside the window, nothing.
    #[test]
    fn finds_and_measures_every_disc_of_a_grid() {
        let (w, h) = (160usize, 120usize);
        let mut img = GrayImage::new(w, h);
        let centres: Vec<[f64; 2]> = (0..4)
            .flat_map(|j| (0..5).map(move |i| [20.3 + 25.0 * i as f64, 18.7 + 24.0 * j as f64]))
            .collect();
        for y in 0..h {
            for x in 0..w {
                let mut cover = 0.0f64;
                for k in 0..16 {
                    let (sx, sy) = (
                        x as f64 + ((k % 4) as f64 - 1.5) / 4.0,
                        y as f64 + ((k / 4) as f64 - 1.5) / 4.0,
                    );
                    if centres.iter().any(|c| (sx - c[0]).hypot(sy - c[1]) <= 5.0) {
                        cover += 1.0 / 16.0;
                    }
                }
                img.data[y * w + x] = (30.0 + 170.0 * cover).round() as u8;
            }
        }
        let cam = CameraModel::centred(w as u32, h as u32, 200.0, 200.0);
        let deck = DeckLayout::paper();
        let mut config = DetectorConfig::for_camera(&cam, &deck);
        (config.min_radius_px, config.max_radius_px) = (2.0, 12.0);
        let mut det = Detector::new(cam, deck, config);
        let discs = det.find_discs(img.view(), (0, 0, w, h));
        assert_eq!(discs.len(), centres.len());
        for c in &centres {
            let nearest = discs
                .iter()
                .map(|d| (d.u_px - c[0]).hypot(d.v_px - c[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(nearest < 0.05, "{c:?}: {nearest}");
        }
        assert!(det.find_discs(img.view(), (0, 0, 8, 8)).is_empty());
        assert!(det.find_discs(img.view(), (200, 0, 300, 10)).is_empty());
    }
}
