//! The marker detector: an 8-bit grayscale frame in, a [`MarkerSet`] out.
//!
//! Full frame: a threshold from a sparse histogram; a coarse scan of every `step`-th pixel of
//! every `step`-th row (a marker disc covers many such cells); connected cells form candidate
//! blobs. Each candidate is measured at full resolution in its region: background as a plane
//! fitted to the region's border, the disc's plateau level, a 4-connected component above the
//! half-way level (area, fill ratio, roundness from moments), and a subpixel centre weighted by
//! coverage `(I - background) / (plateau - background)` (insensitive to light gradients).
//! Identification is geometric (centre, bow, angles: [`crate::identify`]); with extra blobs
//! (glints) the subsets are tried and the one whose homography to the deck fits best wins.
//! Finally the perspective bias of disc centres (CONVENTIONS.md C6) is removed with that
//! homography: the centre of an imaged disc is not the image of the disc's centre.
//!
//! Tracking: the next frame first looks only in regions around the previous markers; when that
//! does not give a consistent marker set (a marker moved beyond its box: a swaying camera, a
//! jump), the same search as the full frame's runs in a window around the previous pattern (its
//! box grown by half its size), and only when that does not find as many markers the whole
//! frame is searched.

use crate::identify::{identify, identify_partial, identify_with_orientation, ring_orientation, Blob};
use deckwatch_common::deck::MAX_MARKERS;
use deckwatch_common::homography;
use deckwatch_common::image::{GrayView, ImageError};
use deckwatch_common::markers::{DetectionStatus, Marker, MarkerSet, RejectCounts};
use deckwatch_common::{CameraModel, DeckLayout};

mod assemble;
mod discs;
mod light;
mod measure;

pub use discs::MeasuredDisc;

/// Samples at or above this level are taken as saturated (glints, not markers).
const SATURATED: usize = 248;
/// At most this many extra candidates (or missing markers) are searched for the pattern.
const MAX_EXTRAS: usize = 4;
/// The ring's orientation from an earlier frame identifies a pattern without its bow for this
/// many frames after the last identified one (at 2 frames a second, 5 s: a hovering quadrotor
/// and a ship turn by a few degrees a second, the slots are 45 deg apart) ...
const MAX_ORIENTATION_AGE_FRAMES: u32 = 10;
/// ... with at least this many markers: the centre and three of the ring (at 1 m over the deck
/// a 1640x1232 frame holds four). Four fit any homography: the disc sizes and the orientation
/// are what check them.
const ORIENTATION_MIN_MARKERS: usize = 4;
/// The light measured on an earlier frame gives a blurred disc's plateau slope for this many
/// frames after it (light across a deck changes slowly; the pattern moves across the
/// vignetting as the vehicle sways).
const MAX_LIGHT_AGE_FRAMES: u32 = 10;

/// Tuning of the detector.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorConfig {
    /// Least brightness of a marker over its background (DN).
    pub min_contrast: f64,
    /// Smallest and largest plausible disc radius in pixels.
    pub min_radius_px: f64,
    pub max_radius_px: f64,
    /// Least minor/major axis ratio of a blob (a disc tilted by 70 deg has 0.34).
    pub min_roundness: f64,
    /// Area / area of the moment ellipse must be within 1 +- this.
    pub fill_tolerance: f64,
    /// Largest RMS residual (pixels) of the deck-to-image homography of an accepted marker set.
    pub max_residual_px: f64,
    /// How far (pixels) a marker may move between frames and still be tracked; beyond, the
    /// full-frame search finds it. Ship motion at 10 Hz moves markers by a few pixels.
    pub track_margin_px: f64,
    /// Remove the perspective bias of disc centres.
    pub correct_perspective: bool,
}

impl DetectorConfig {
    /// Defaults for a camera and deck: discs from 0.8 m to 25 m away (the whole approach,
    /// down to a camera about to touch down).
    pub fn for_camera(camera: &CameraModel, deck: &DeckLayout) -> Self {
        let f = camera.fx.min(camera.fy);
        Self {
            min_contrast: 25.0,
            min_radius_px: (f * deck.marker_radius_m / 25.0).max(1.0),
            max_radius_px: f * deck.bow_marker_radius_m / 0.8,
            min_roundness: 0.3,
            fill_tolerance: 0.3,
            max_residual_px: 2.0,
            track_margin_px: 8.0,
            correct_perspective: true,
        }
    }
}

/// A measured blob.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Candidate {
    u: f64,
    v: f64,
    /// Coverage area (pixels).
    area: f64,
    plateau: f64,
    contrast: f64,
    roundness: f64,
    /// Equivalent radius (pixels).
    radius: f64,
    /// The centre's standard deviation per axis from the pixel noise (pixels).
    centre_std_px: f64,
    /// The deviation of the disc edge's blur (pixels; a sharp edge's pixels alone give 0.29).
    edge_sigma_px: f64,
}

/// Marker index and the candidate assigned to it.
type Assignment = Vec<(usize, Candidate)>;
type Points = Vec<[f64; 2]>;
/// Identifications to try: per hypothesis, the blob of each marker index.
type Identifications = Vec<Vec<Option<usize>>>;

enum Rejection {
    Area,
    Shape,
    Border,
}

/// Detects the deck's markers in frames of one camera, keeping track between frames.
pub struct Detector {
    camera: CameraModel,
    deck: DeckLayout,
    config: DetectorConfig,
    /// The previous frame's markers (centre, radius) for tracking.
    previous: Option<[Option<(f64, f64, f64)>; MAX_MARKERS]>,
    /// The ring's orientation in the newest frame whose markers were identified (the bow's
    /// image angle around the centre, [`ring_orientation`]) and the frames since: what
    /// identifies a pattern whose bow is cut by the border or out of view when tracking cannot
    /// (a low frame rate, a jump), whatever the frame rate.
    orientation: Option<(f64, u32)>,
    /// The light across the pattern, from the newest identified set whose markers' levels
    /// gave one, and the frames since: a large blurred disc's plateau slope
    /// ([`light::LightModel`]).
    light: Option<(light::LightModel, u32)>,
    coarse: Vec<u8>,
    stack: Vec<(u32, u32)>,
    seeds: Vec<u32>,
    mask: Vec<u8>,
    /// One mask row, copied for the erosion.
    row_copy: Vec<u8>,
    /// Scratch for the edge profile's fit (`measure::profile`).
    profile_pixels: Vec<[f32; 3]>,
    candidates: Vec<Candidate>,
    searches: SearchCounts,
    /// The least gap between two markers' edges on the deck over the largest marker's radius:
    /// how far a disc's neighbour's edge is at least, in the disc's own radii.
    least_gap_per_radius: f64,
}

/// The least gap between two markers' edges over the largest marker's radius; infinite for a
/// single marker.
fn least_gap_per_radius(deck: &DeckLayout) -> f64 {
    let positions = deck.marker_positions();
    let largest_m = (0..positions.len())
        .map(|i| deck.disc_radius(i))
        .fold(0.0, f64::max);
    let mut least_m = f64::INFINITY;
    for i in 0..positions.len() {
        for j in i + 1..positions.len() {
            let gap_m = (positions[i] - positions[j]).norm() - deck.disc_radius(i) - deck.disc_radius(j);
            least_m = least_m.min(gap_m);
        }
    }
    match largest_m > 0.0 {
        true => (least_m / largest_m).max(0.0),
        false => 0.0,
    }
}

/// How a detector found the markers of its frames: counts of frames by the search that gave
/// their marker set.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SearchCounts {
    /// Boxes around the previous frame's markers.
    pub tracked: u64,
    /// The region around the previous frame's pattern, after tracking lost a marker.
    pub window: u64,
    /// The whole frame (no previous markers, or neither of the above found them).
    pub full: u64,
}

impl Detector {
    pub fn new(camera: CameraModel, deck: DeckLayout, config: DetectorConfig) -> Self {
        Self {
            camera,
            config,
            previous: None,
            orientation: None,
            light: None,
            coarse: Vec::new(),
            stack: Vec::new(),
            seeds: Vec::new(),
            mask: Vec::new(),
            row_copy: Vec::new(),
            profile_pixels: Vec::new(),
            candidates: Vec::new(),
            searches: SearchCounts::default(),
            least_gap_per_radius: least_gap_per_radius(&deck),
            deck,
        }
    }

    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    pub fn deck(&self) -> &DeckLayout {
        &self.deck
    }

    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// Forgets the previous frame (the next frame is searched in full; the ring's orientation
    /// is kept, to identify a pattern without its bow, and the light, for its age).
    pub fn reset_tracking(&mut self) {
        self.previous = None;
    }

    /// Forgets the previous frame, the ring's orientation and the light: the next pattern must
    /// show its bow to be identified (another deck, another camera mounting).
    pub fn reset(&mut self) {
        self.previous = None;
        self.orientation = None;
        self.light = None;
    }

    /// Detects markers in a frame given as bytes with its geometry; a geometry that does not fit
    /// the bytes is an error.
    pub fn detect_bytes(
        &mut self,
        data: &[u8],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<MarkerSet, ImageError> {
        Ok(self.detect(GrayView::new(data, width, height, stride)?))
    }

    /// Detects markers: tracked when the previous frame had a marker set, else (or when tracking
    /// fails) over the full frame. A frame whose size is not the camera's gives `BadFrame`.
    pub fn detect(&mut self, frame: GrayView<'_>) -> MarkerSet {
        if let Some((_, age)) = &mut self.orientation {
            *age = age.saturating_add(1);
        }
        if let Some((_, age)) = &mut self.light {
            *age = age.saturating_add(1);
        }
        if (frame.width(), frame.height()) != (self.camera.width as usize, self.camera.height as usize) {
            self.previous = None;
            return MarkerSet {
                status: DetectionStatus::BadFrame.into(),
                ..MarkerSet::default()
            };
        }
        if let Some(prev) = self.previous {
            if let Some(set) = self.detect_tracked(frame, &prev) {
                self.searches.tracked += 1;
                return set;
            }
            // Markers that moved beyond their boxes (a swaying camera) are still near the
            // pattern: search around it before the whole frame.
            if let Some(window) = self.search_window(frame, &prev) {
                let set = self.detect_in(frame, window);
                let before = prev.iter().flatten().count();
                if matches!(set.status.get(), DetectionStatus::Ok | DetectionStatus::Partial)
                    && set.count as usize >= before
                {
                    self.searches.window += 1;
                    return set;
                }
            }
        }
        self.detect_full(frame)
    }

    /// Full-frame detection (ignores and then replaces the tracking state).
    pub fn detect_full(&mut self, frame: GrayView<'_>) -> MarkerSet {
        self.searches.full += 1;
        self.detect_in(frame, (0, 0, frame.width(), frame.height()))
    }

    /// How often each kind of search gave the frame's markers so far.
    pub fn searches(&self) -> SearchCounts {
        self.searches
    }

    /// The region a search after lost tracking looks at first: the previous markers' box grown
    /// by half its size on every side (and by the tracking allowance); None when that is most of
    /// the frame anyway.
    fn search_window(
        &self,
        frame: GrayView<'_>,
        prev: &[Option<(f64, f64, f64)>; MAX_MARKERS],
    ) -> Option<(usize, usize, usize, usize)> {
        let (w, h) = (frame.width() as f64, frame.height() as f64);
        let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for &(u, v, r) in prev.iter().flatten() {
            (u0, v0, u1, v1) = (u0.min(u - r), v0.min(v - r), u1.max(u + r), v1.max(v + r));
        }
        let grow = 0.5 * (u1 - u0).max(v1 - v0) + self.config.track_margin_px;
        let window = (
            (u0 - grow).clamp(0.0, w) as usize,
            (v0 - grow).clamp(0.0, h) as usize,
            (u1 + grow).clamp(0.0, w).ceil() as usize,
            (v1 + grow).clamp(0.0, h).ceil() as usize,
        );
        let area = (window.2.saturating_sub(window.0) * window.3.saturating_sub(window.1)) as f64;
        (area > 0.0 && area < 0.5 * w * h).then_some(window)
    }

    /// Detection over a region of the frame (x0, y0, x1, y1), half-open; the threshold is the
    /// whole frame's.
    fn detect_in(&mut self, frame: GrayView<'_>, window: (usize, usize, usize, usize)) -> MarkerSet {
        let Some((threshold, unsaturated)) = self.global_threshold(frame) else {
            self.previous = None;
            return MarkerSet::default(); // no contrast: no deck
        };
        let set = self.detect_at(frame, threshold, window);
        // Saturated glints pull the threshold above dull markers: try again at the markers' level.
        match unsaturated {
            Some(t)
                if set.status == DetectionStatus::NoDeck
                    && threshold - t >= self.config.min_contrast / 2.0 =>
            {
                self.detect_at(frame, t, window)
            }
            _ => set,
        }
    }

    /// Detection at one global threshold over a region (x0, y0, x1, y1) of the frame.
    fn detect_at(
        &mut self,
        frame: GrayView<'_>,
        threshold: f64,
        window: (usize, usize, usize, usize),
    ) -> MarkerSet {
        let Some(rejected) = self.search_discs(frame, threshold, window) else {
            self.previous = None;
            return MarkerSet::default();
        };
        let set = self.assemble(rejected, false);
        self.remember(&set);
        set
    }

    /// The full search's candidates at one global threshold over a region (x0, y0, x1, y1):
    /// every blob of the coarse scan measured into `self.candidates`, with the counts of the
    /// rejected ones; None when too much of the region is bright to be a frame of markers.
    fn search_discs(
        &mut self,
        frame: GrayView<'_>,
        threshold: f64,
        (x0, y0, x1, y1): (usize, usize, usize, usize),
    ) -> Option<RejectCounts> {
        let mut rejected = RejectCounts::default();
        self.candidates.clear();
        let (w, h) = (frame.width(), frame.height());
        // Coarse scan: one cell per `step` x `step` pixels, sampled at its corner; the grid
        // covers the region, its cell (0, 0) at pixel (ox, oy).
        let step = self.coarse_step();
        let (ox, oy) = (x0 / step * step, y0 / step * step);
        let (gw, gh) = ((x1.min(w) - ox).div_ceil(step), (y1.min(h) - oy).div_ceil(step));
        self.coarse.clear();
        self.coarse.resize(gw * gh, 0);
        self.seeds.clear();
        let t = threshold as u8;
        // Most of a frame is below the threshold: a chunk of cells is skipped on its maximum
        // (a vectorised read of the row, as fast as memory), and only a chunk holding something
        // bright is sampled cell by cell.
        const CHUNK_CELLS: usize = 16;
        for gy in 0..gh {
            let row = &frame.row(oy + gy * step)[ox..(ox + gw * step).min(w)];
            let cells = &mut self.coarse[gy * gw..(gy + 1) * gw];
            for (k, chunk) in row.chunks(CHUNK_CELLS * step).enumerate() {
                if chunk.iter().fold(0u8, |a, &p| a.max(p)) < t {
                    continue;
                }
                let gx0 = k * CHUNK_CELLS;
                for (j, &p) in chunk.iter().step_by(step).enumerate() {
                    if p >= t {
                        cells[gx0 + j] = 1;
                        self.seeds.push((gy * gw + gx0 + j) as u32);
                    }
                }
            }
        }
        // Too many bright cells: not a frame of markers (e.g. over-exposed).
        let max_cells = 64 * MAX_MARKERS * (self.config.max_radius_px / step as f64).powi(2).ceil() as usize;
        if self.seeds.len() > max_cells {
            return None;
        }
        for i in 0..self.seeds.len() {
            let s = self.seeds[i] as usize;
            if self.coarse[s] != 1 {
                continue;
            }
            // Flood the coarse component, keeping its bounding box.
            let (mut x0, mut y0, mut x1, mut y1) = (s % gw, s / gw, s % gw, s / gw);
            self.coarse[s] = 2;
            self.stack.clear();
            self.stack.push(((s % gw) as u32, (s / gw) as u32));
            while let Some((x, y)) = self.stack.pop() {
                let (x, y) = (x as usize, y as usize);
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x);
                y1 = y1.max(y);
                for (nx, ny) in [
                    (x.wrapping_sub(1), y),
                    (x + 1, y),
                    (x, y.wrapping_sub(1)),
                    (x, y + 1),
                ] {
                    if nx < gw && ny < gh && self.coarse[ny * gw + nx] == 1 {
                        self.coarse[ny * gw + nx] = 2;
                        self.stack.push((nx as u32, ny as u32));
                    }
                }
            }
            let pad = step + 3;
            let roi = (
                (ox + x0 * step).saturating_sub(pad),
                (oy + y0 * step).saturating_sub(pad),
                (ox + (x1 + 1) * step + pad).min(w),
                (oy + (y1 + 1) * step + pad).min(h),
            );
            match self.measure(frame, roi) {
                Ok(c) => self.candidates.push(c),
                Err(Rejection::Area) => rejected.area += 1,
                Err(Rejection::Shape) => rejected.shape += 1,
                Err(Rejection::Border) => rejected.border += 1,
            }
        }
        Some(rejected)
    }

    /// The full search's coarse grid step (px): dense enough to hit the smallest disc.
    fn coarse_step(&self) -> usize {
        (self.config.min_radius_px.floor() as usize).clamp(1, 4)
    }

    /// Looks only around the previous markers; None when that does not give a consistent set
    /// with as many markers as before.
    fn detect_tracked(
        &mut self,
        frame: GrayView<'_>,
        prev: &[Option<(f64, f64, f64)>; MAX_MARKERS],
    ) -> Option<MarkerSet> {
        let (w, h) = (frame.width() as f64, frame.height() as f64);
        let step = self.coarse_step();
        let mut found = [None; MAX_MARKERS];
        // Markers whose region the image border cuts may leave the view (descending onto the
        // deck): tracking goes on without them while four remain (the bow too may go: the
        // identities are the previous frame's, which go back to a frame that had it).
        let mut expected = prev.iter().flatten().count();
        for (i, p) in prev.iter().enumerate() {
            let Some((u, v, r)) = p else { continue };
            // The disc, the background border the measurement needs, and the motion allowance;
            // where the disc is not in that, a region half a radius wider (near the deck a frame
            // moves the discs further, as they grow), the disc found there measured again in a
            // region as tight as the full search's (the background plane is fitted to the
            // region's border, so its size matters).
            let region = |u: f64, v: f64, half: f64| {
                let roi = (
                    (u - half).max(0.0) as usize,
                    (v - half).max(0.0) as usize,
                    ((u + half).ceil().min(w)) as usize,
                    ((v + half).ceil().min(h)) as usize,
                );
                (roi.2 > roi.0 + 2 && roi.3 > roi.1 + 2).then_some(roi)
            };
            let near = r + 4.0 + self.config.track_margin_px;
            let wide = near + 0.5 * r;
            let cut = u - wide < 0.0 || v - wide < 0.0 || u + wide > w || v + wide > h;
            let measured = region(*u, *v, near)
                .and_then(|roi| self.measure(frame, roi).ok())
                .or_else(|| {
                    let c = self.measure(frame, region(*u, *v, wide)?).ok()?;
                    self.measure(frame, region(c.u, c.v, c.radius + 2.0 * step as f64 + 3.0)?)
                        .ok()
                });
            match measured {
                Some(c) => found[i] = Some(c),
                None if cut => expected -= 1,
                None => return None,
            }
        }
        let n = self.deck.marker_count();
        let assigned: Vec<(usize, Candidate)> = (0..n).filter_map(|i| found[i].map(|c| (i, c))).collect();
        if assigned.len() < expected.max(4) {
            return None;
        }
        let residual = self.fit_residual(&assigned)?;
        if residual > self.config.max_residual_px {
            return None;
        }
        let set = self.build(&assigned, RejectCounts::default(), true);
        self.remember(&set);
        Some(set)
    }

    /// Median of a sparse sample of the frame plus half the way to its brightest sample (at least
    /// half the minimum contrast); None when the frame has no contrast.
    /// Threshold halfway between the frame's median (deck, sea) and its brightest samples
    /// (markers); and, when lower, halfway to the dimmest bright mode below saturation (the
    /// markers' level when saturated glints are the brightest things in view).
    fn global_threshold(&self, frame: GrayView<'_>) -> Option<(f64, Option<f64>)> {
        let (w, h) = (frame.width(), frame.height());
        let step = (((w * h) as f64 / 16384.0).sqrt() as usize).clamp(1, 16);
        let mut hist = [0u32; 256];
        let mut n = 0u32;
        for y in (step / 2..h).step_by(step) {
            for &p in frame.row(y).iter().skip(step / 2).step_by(step) {
                hist[p as usize] += 1;
                n += 1;
            }
        }
        let mut acc = 0;
        let median = hist.iter().position(|&c| {
            acc += c;
            acc * 2 >= n
        })? as f64;
        // The sample step is below a marker's diameter, so markers are among the samples.
        let top = hist.iter().rposition(|&c| c > 0)? as f64;
        if top - median < self.config.min_contrast {
            return None;
        }
        let threshold = |top: f64| median + ((top - median) / 2.0).max(self.config.min_contrast / 2.0);
        // The dimmest bright mode: the markers' level when brighter things (glints) exist.
        let lo = ((median + self.config.min_contrast).ceil() as usize).min(SATURATED);
        let bright: u32 = hist[lo..SATURATED].iter().sum();
        let smooth = |i: usize| hist[i.saturating_sub(3)..(i + 4).min(256)].iter().sum::<u32>();
        let dim_mode = (lo..SATURATED)
            .find(|&i| {
                let c = smooth(i);
                c * 20 >= bright.max(20) && c >= smooth(i + 1) && (i == 0 || c >= smooth(i - 1))
            })
            .map(|i| threshold(i as f64))
            .filter(|&t| t < threshold(top) - self.config.min_contrast / 2.0);
        Some((threshold(top), dim_mode))
    }
}

#[cfg(test)]
mod tests {
    use super::assemble::for_each_subset;
    use super::*;

    /// The paper's deck leaves at least 3.2 bow radii between two markers' edges (a ring marker
    /// beside the bow: 0.383 m apart less 0.05 and 0.08 m); a pattern of larger discs on the
    /// same ring, 0.12 and 0.18 m, leaves 0.46: there a blurred large disc keeps the banded
    /// window (`measure`'s wide-window gate).
    #[test]
    fn the_least_gap_between_markers_is_measured_in_the_largest_radius() {
        let paper = DeckLayout::paper();
        let gap = least_gap_per_radius(&paper);
        let expected = (2.0 * 0.5 * (std::f64::consts::PI / 8.0).sin() - 0.05 - 0.08) / 0.08;
        assert!((gap - expected).abs() < 1e-9, "{gap} against {expected}");
        let crowded = DeckLayout {
            marker_radius_m: 0.12,
            bow_marker_radius_m: 0.18,
            ..paper
        };
        let gap = least_gap_per_radius(&crowded);
        assert!(
            (gap - (0.765_366_864_7 * 0.5 - 0.30) / 0.18).abs() < 1e-6,
            "{gap}"
        );
    }

    /// A pattern that jumps beyond its tracking boxes (a swaying camera) is found again by the
    /// search around the previous pattern, exactly as the whole frame's search finds it.
    #[test]
    fn a_jump_beyond_the_boxes_is_found_around_the_pattern() {
        use deckwatch_common::GrayImage;
        use deckwatch_sim::{FrameSimulator, RenderOptions, Renderer, Scenario};
        let cam = CameraModel::rpi_v2();
        let deck = DeckLayout::paper();
        let r = Renderer::new(cam, deck, RenderOptions::realistic(), 3).unwrap();
        let mut sim = FrameSimulator::new(Scenario::Ship.profile(3, 1.0), r, 1.0, 0.0, 1, 3).unwrap();
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut first = GrayImage::new(w, h);
        sim.render_frame(0, &mut first.view_mut()).unwrap();
        // The same picture moved right and down by whole coarse cells (the grid then samples
        // the same pixels of every disc).
        let (dx, dy) = (120usize, 60usize);
        let mut moved = GrayImage::new(w, h);
        for y in 0..h {
            let src = first.view().row(y.saturating_sub(dy));
            let row = &mut moved.data[y * w..(y + 1) * w];
            row[dx..].copy_from_slice(&src[..w - dx]);
            row[..dx].fill(src[0]);
        }
        let mut det = Detector::new(cam, deck, DetectorConfig::for_camera(&cam, &deck));
        let a = det.detect(first.view());
        assert_eq!((a.count, det.searches().full), (9, 1));
        let b = det.detect(moved.view());
        assert_eq!(
            det.searches(),
            SearchCounts {
                tracked: 0,
                window: 1,
                full: 1
            }
        );
        assert_eq!(b.count, 9);
        for (ma, mb) in a.markers.iter().zip(&b.markers).take(9) {
            assert!((mb.u - ma.u - dx as f64).abs() < 1e-6 && (mb.v - ma.v - dy as f64).abs() < 1e-6);
        }
        let full = det.detect_full(moved.view());
        assert_eq!(
            full.markers, b.markers,
            "the window finds what the whole frame does"
        );
        // Now tracked.
        det.detect(moved.view());
        assert_eq!(det.searches().tracked, 1);
    }

    /// A camera whose tone curve lifts a blurred edge (a filmic S-curve, after a 2.5 px blur at
    /// 640x480) makes every disc measure about twice its area: the common scale is then beyond
    /// 2x, which the size check allows for in proportion to the measured blur. Without that
    /// the same frame lost most of its markers (the independent renderer's `filmic` model).
    #[test]
    fn a_tone_curve_that_grows_blurred_discs_keeps_them_identified() {
        use deckwatch_common::GrayImage;
        use deckwatch_sim::{FrameSimulator, RenderOptions, Renderer, Scenario};
        let cam = CameraModel::rpi_v2().scaled_to(640, 480);
        let deck = DeckLayout::paper();
        let options = RenderOptions {
            optical_blur_px: 2.5,
            ..RenderOptions::default()
        };
        let r = Renderer::new(cam, deck, options, 3).unwrap();
        let mut sim = FrameSimulator::new(Scenario::Ship.profile(3, 1.0), r, 1.0, 0.0, 1, 3).unwrap();
        let mut frame = GrayImage::new(640, 480);
        sim.render_frame(0, &mut frame.view_mut()).unwrap();
        // A logistic in log2 exposure about middle grey, rescaled to keep 0 and 1.
        let logistic = |x: f64| 1.0 / (1.0 + (-1.4 * (x.max(1e-6) / 0.18).log2()).exp());
        let (lo, hi) = (logistic(1e-6), logistic(1.0));
        for p in frame.data.iter_mut() {
            let x = f64::from(*p) / 255.0;
            *p = (255.0 * (logistic(x) - lo) / (hi - lo)).round().clamp(0.0, 255.0) as u8;
        }
        let mut det = Detector::new(cam, deck, DetectorConfig::for_camera(&cam, &deck));
        let set = det.detect(frame.view());
        assert_eq!(set.count, 9, "{:?}", set.status);
    }

    #[test]
    fn subsets() {
        let mut all = Vec::new();
        for_each_subset(5, 3, &mut |s| all.push(s.to_vec()));
        assert_eq!(all.len(), 10);
        assert_eq!(all[0], vec![0, 1, 2]);
        assert_eq!(all[9], vec![2, 3, 4]);
        let mut n = 0;
        for_each_subset(3, 3, &mut |_| n += 1);
        assert_eq!(n, 1);
    }
}

#[cfg(test)]
mod bad_input {
    use super::*;
    use proptest::prelude::*;

    fn detector(w: u32, h: u32) -> Detector {
        let cam = CameraModel::rpi_v2().scaled_to(w.max(1), h.max(1));
        let deck = DeckLayout::paper();
        Detector::new(cam, deck, DetectorConfig::for_camera(&cam, &deck))
    }

    #[test]
    fn uniform_frames_are_no_deck() {
        for value in [0u8, 1, 70, 254, 255] {
            let mut d = detector(320, 240);
            let frame = vec![value; 320 * 240];
            let set = d.detect_bytes(&frame, 320, 240, 320).unwrap();
            assert_eq!(set.status, DetectionStatus::NoDeck, "value {value}");
        }
        // Saturated: half the frame white.
        let mut d = detector(320, 240);
        let mut frame = vec![60u8; 320 * 240];
        frame[..320 * 120].fill(255);
        assert_eq!(
            d.detect_bytes(&frame, 320, 240, 320).unwrap().status,
            DetectionStatus::NoDeck
        );
    }

    #[test]
    fn geometry_errors_are_errors() {
        let mut d = detector(32, 24);
        let frame = vec![0u8; 32 * 24];
        assert!(matches!(
            d.detect_bytes(&[], 32, 24, 32),
            Err(ImageError::BufferTooSmall { .. })
        ));
        assert!(matches!(
            d.detect_bytes(&frame, 0, 24, 32),
            Err(ImageError::ZeroSize { .. })
        ));
        assert!(matches!(
            d.detect_bytes(&frame, 32, 24, 16),
            Err(ImageError::StrideTooSmall { .. })
        ));
        assert!(matches!(
            d.detect_bytes(&frame, 32, 25, 32),
            Err(ImageError::BufferTooSmall { .. })
        ));
        let set = d.detect_bytes(&frame, 16, 12, 32).unwrap();
        assert_eq!(
            set.status,
            DetectionStatus::BadFrame,
            "size differs from the camera's"
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        #[test]
        fn never_panics(w in 0usize..96, h in 0usize..72, pad in 0usize..8, seed in any::<u64>(),
                        spots in 0usize..12, len_cut in 0usize..4) {
            let stride = w + pad;
            let len = (stride * h).saturating_sub(len_cut);
            let mut rng = seed | 1;
            let mut next = || { rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17; rng };
            let mut frame: Vec<u8> = (0..len).map(|_| (next() % 256) as u8).collect();
            // Bright discs here and there, so the blob path runs too.
            for _ in 0..spots {
                if w < 4 || h < 4 { break; }
                let (cx, cy, r) = ((next() % w as u64) as i64, (next() % h as u64) as i64, 1 + (next() % 6) as i64);
                for y in (cy - r).max(0)..(cy + r).min(h as i64) {
                    for x in (cx - r).max(0)..(cx + r).min(w as i64) {
                        if (x - cx).pow(2) + (y - cy).pow(2) <= r * r && (y as usize * stride + (x as usize)) < len {
                            frame[y as usize * stride + x as usize] = 250;
                        }
                    }
                }
            }
            let mut d = detector(w as u32, h as u32);
            match d.detect_bytes(&frame, w, h, stride) {
                Ok(set) => {
                    prop_assert!(set.count as usize <= 9);
                    prop_assert_eq!(set.markers.iter().filter(|m| m.valid.get()).count(), set.count as usize);
                    if set.status == DetectionStatus::NoDeck || set.status == DetectionStatus::BadFrame {
                        prop_assert_eq!(set.count, 0);
                    }
                    // A second frame exercises the tracking path.
                    let _ = d.detect_bytes(&frame, w, h, stride);
                }
                Err(_) => prop_assert!(w == 0 || h == 0 || len < stride * h.saturating_sub(1) + w),
            }
        }
    }
}
