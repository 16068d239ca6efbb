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

use crate::identify::{identify, identify_partial, Blob};
use deckwatch_common::deck::MAX_MARKERS;
use deckwatch_common::homography;
use deckwatch_common::image::{GrayView, ImageError};
use deckwatch_common::markers::{DetectionStatus, Marker, MarkerSet, RejectCounts};
use deckwatch_common::{CameraModel, DeckLayout};

/// Samples at or above this level are taken as saturated (glints, not markers).
const SATURATED: usize = 248;
/// At most this many extra candidates (or missing markers) are searched for the pattern.
const MAX_EXTRAS: usize = 4;

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
    coarse: Vec<u8>,
    stack: Vec<(u32, u32)>,
    seeds: Vec<u32>,
    mask: Vec<u8>,
    /// One mask row, copied for the erosion.
    row_copy: Vec<u8>,
    candidates: Vec<Candidate>,
    searches: SearchCounts,
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
            deck,
            config,
            previous: None,
            coarse: Vec::new(),
            stack: Vec::new(),
            seeds: Vec::new(),
            mask: Vec::new(),
            row_copy: Vec::new(),
            candidates: Vec::new(),
            searches: SearchCounts::default(),
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

    /// Forgets the previous frame (the next frame is searched in full).
    pub fn reset_tracking(&mut self) {
        self.previous = None;
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
        (x0, y0, x1, y1): (usize, usize, usize, usize),
    ) -> MarkerSet {
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
            self.previous = None;
            return MarkerSet::default();
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
        let set = self.assemble(rejected, false);
        self.remember(&set);
        set
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

    /// Measures the blob in a region (x0, y0, x1, y1), half-open.
    ///
    /// Every pass is a straight loop over row slices (the compiler vectorises the peak, the
    /// mask and the erosion), and the costly per-pixel work, the coverage ratio with its
    /// division, is done only for pixels that are not deep inside the disc: a tracked frame's
    /// nine regions cost about as much as reading them.
    fn measure(
        &mut self,
        frame: GrayView<'_>,
        roi: (usize, usize, usize, usize),
    ) -> Result<Candidate, Rejection> {
        let (x0, y0, x1, y1) = roi;
        let (rw, rh) = (x1 - x0, y1 - y0);
        if rw < 3 || rh < 3 {
            return Err(Rejection::Area);
        }
        // Peak (the seed): a row's maximum first (vectorised), its position only in a row that
        // raises it.
        let (mut peak, mut seed) = (0u8, (x0, y0));
        for y in y0..y1 {
            let row = &frame.row(y)[x0..x1];
            let m = row.iter().fold(0u8, |a, &p| a.max(p));
            if m > peak {
                peak = m;
                seed = (x0 + row.iter().position(|&p| p == m).unwrap_or(0), y);
            }
        }
        let bg = fit_border_plane(frame, roi, peak);
        let b_at = |x: usize, y: usize| bg[0] + bg[1] * x as f64 + bg[2] * y as f64;
        let contrast = peak as f64 - b_at(seed.0, seed.1);
        if contrast < self.config.min_contrast {
            return Err(Rejection::Shape);
        }
        // The half-way level between the peak and the background under it.
        let level = (0.5 * (peak as f64 + b_at(seed.0, seed.1)))
            .ceil()
            .clamp(0.0, 255.0) as u8;
        // The mask of pixels at or above the level, and its integer moments, row by row over
        // the span between a row's first and last mask pixel. A region holds one marker (its
        // search box); anything else bright in it spoils the shape and is rejected below.
        self.mask.clear();
        self.mask.resize(rw * rh, 0);
        let (mut n, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
        let (mut bx0, mut by0, mut bx1, mut by1) = (rw, rh, 0, 0);
        for y in 0..rh {
            let row = &frame.row(y0 + y)[x0..x1];
            let mrow = &mut self.mask[y * rw..(y + 1) * rw];
            let mut any = 0u8;
            for (m, &p) in mrow.iter_mut().zip(row) {
                *m = (p >= level) as u8;
                any |= *m;
            }
            if any == 0 {
                continue;
            }
            let first = mrow.iter().position(|&m| m != 0).unwrap_or(0);
            let last = rw - 1 - mrow.iter().rev().position(|&m| m != 0).unwrap_or(0);
            let span = &mrow[first..=last];
            let [rn, rsxl, rsxxl] = if span.len() <= 1024 {
                mask_row_sums::<u32>(span).map(u64::from)
            } else {
                mask_row_sums::<u64>(span)
            };
            let f = first as u64;
            let (rsx, rsxx) = (rsxl + rn * f, rsxxl + 2 * f * rsxl + rn * f * f);
            let yy = y as u64;
            (n, sx, sxx) = (n + rn, sx + rsx, sxx + rsxx);
            (sy, syy, sxy) = (sy + rn * yy, syy + rn * yy * yy, sxy + rsx * yy);
            by0 = by0.min(y);
            by1 = y;
            bx0 = bx0.min(first);
            bx1 = bx1.max(last);
        }
        let touches = n > 0 && (bx0 == 0 || by0 == 0 || bx1 + 1 == rw || by1 + 1 == rh);
        let (area, sx, sy, sxx, syy, sxy) =
            (n as f64, sx as f64, sy as f64, sxx as f64, syy as f64, sxy as f64);
        if touches {
            // The blob fills its region: at the image border, a cut disc; elsewhere, too large.
            let at_border = x0 == 0 || y0 == 0 || x1 == frame.width() || y1 == frame.height();
            return Err(if at_border {
                Rejection::Border
            } else {
                Rejection::Area
            });
        }
        let (min_r, max_r) = (self.config.min_radius_px, self.config.max_radius_px);
        let min_area = 0.5 * std::f64::consts::PI * min_r * min_r;
        let max_area = std::f64::consts::PI * max_r * max_r;
        if area < min_area.max(3.0) || area > max_area {
            return Err(Rejection::Area);
        }
        let (mx, my) = (sx / area, sy / area);
        let (cxx, cyy, cxy) = (sxx / area - mx * mx, syy / area - my * my, sxy / area - mx * my);
        let tr = cxx + cyy;
        let disc = ((cxx - cyy).powi(2) + 4.0 * cxy * cxy).sqrt();
        let (l1, l2) = ((tr + disc) / 2.0, (tr - disc) / 2.0);
        let roundness = if l1 > 0.0 { (l2.max(0.0) / l1).sqrt() } else { 0.0 };
        // A filled ellipse of area A has moment eigenvalues a^2/4, b^2/4 with A = pi a b.
        let fill = area / (4.0 * std::f64::consts::PI * (l1 * l2).max(1e-12).sqrt());
        if roundness < self.config.min_roundness || (fill - 1.0).abs() > self.config.fill_tolerance {
            return Err(Rejection::Shape);
        }
        // Depth of each mask pixel inside the disc (0 outside, 1 at the edge, capped at 3), by
        // repeated 4-neighbour erosion over the component's box. A pixel is promoted from the
        // row's copy: promoting in place gives the same depths (a promoted neighbour still
        // qualifies), the copy lets the loop vectorise.
        let (xlo, xhi) = (bx0.max(1), bx1.min(rw - 2));
        let (ylo, yhi) = (by0.max(1), by1.min(rh - 2));
        if xlo <= xhi {
            let span = xhi - xlo + 1;
            for d in 2..=3u8 {
                for y in ylo..=yhi {
                    let (head, tail) = self.mask.split_at_mut(y * rw);
                    let up = &head[(y - 1) * rw + xlo..][..span];
                    let (cur, below) = tail.split_at_mut(rw);
                    let down = &below[xlo..][..span];
                    self.row_copy.clear();
                    self.row_copy.extend_from_slice(&cur[xlo - 1..xhi + 2]);
                    let (left, mid, right) = (
                        &self.row_copy[..span],
                        &self.row_copy[1..=span],
                        &self.row_copy[2..],
                    );
                    let out = &mut cur[xlo..=xhi];
                    for i in 0..span {
                        // `&`, not `&&`: no branches, so that the loop vectorises.
                        let deep = (mid[i] == d - 1)
                            & (left[i] >= d - 1)
                            & (right[i] >= d - 1)
                            & (up[i] >= d - 1)
                            & (down[i] >= d - 1);
                        out[i] = if deep { d } else { mid[i] };
                    }
                }
            }
        }
        // Plateau: a plane through the disc's interior (2 or more pixels deep), so that a light
        // gradient across the disc does not tilt the coverage. Sums per row, then per region.
        let mut pn = PlaneFit::default();
        for y in by0..=by1 {
            let mrow = &self.mask[y * rw + bx0..=y * rw + bx1];
            let row = &frame.row(y0 + y)[x0 + bx0..=x0 + bx1];
            // Sums over x from the box's left edge: 32-bit lanes (twice as many per vector) when
            // they cannot overflow (span^3 < 2^32), then moved to the region's x exactly.
            let [n, sxl, sxxl, sz, sxzl] = if mrow.len() <= 1024 {
                deep_row_sums::<u32>(mrow, row).map(u64::from)
            } else {
                deep_row_sums::<u64>(mrow, row)
            };
            let b = bx0 as u64;
            let sums = [n, sxl + n * b, sxxl + 2 * b * sxl + n * b * b, sz, sxzl + b * sz];
            pn.add_row(y as i64, sums.map(|v| v as i64));
        }
        let plateau_plane = pn.solve().unwrap_or([peak as f64, 0.0, 0.0]);
        let p_at = |x: usize, y: usize| {
            plateau_plane[0] + plateau_plane[1] * (x - x0) as f64 + plateau_plane[2] * (y - y0) as f64
        };
        // Coverage-weighted centre in a window reaching 2 pixels beyond the disc: pixels 2 deep
        // count as fully covered (no interior noise; integer sums), the rest by
        // (I - background) / (plateau - background).
        let a = 2.0 * l1.sqrt();
        let reach = a + 2.0;
        let (cx, cy) = (x0 as f64 + mx, y0 as f64 + my);
        let wx0 = ((cx - reach).floor().max(x0 as f64)) as usize;
        let wx1 = ((cx + reach).ceil().min((x1 - 1) as f64)) as usize;
        let wy0 = ((cy - reach).floor().max(y0 as f64)) as usize;
        let wy1 = ((cy + reach).ceil().min((y1 - 1) as f64)) as usize;
        let (mut full_n, mut full_x, mut full_y) = (0u64, 0u64, 0u64);
        let (mut cw, mut cu, mut cv) = (0.0, 0.0, 0.0);
        for y in wy0..=wy1 {
            let dy = y as f64 - cy;
            let inside = |x: usize| {
                let dx = x as f64 - cx;
                dx * dx + dy * dy <= reach * reach
            };
            // The row's pixels within reach: a run, trimmed from both ends.
            let (mut xa, mut xb) = (wx0, wx1);
            while xa <= xb && !inside(xa) {
                xa += 1;
            }
            while xb > xa && !inside(xb) {
                xb -= 1;
            }
            if xa > xb {
                continue;
            }
            let mrow = &self.mask[(y - y0) * rw + (xa - x0)..=(y - y0) * rw + (xb - x0)];
            let row = &frame.row(y)[xa..=xb];
            let (mut rn, mut rx) = (0u64, 0u64);
            let (mut rw_sum, mut ru) = (0.0, 0.0);
            for ((x, &m), &pixel) in (xa..).zip(mrow).zip(row) {
                if m >= 2 {
                    rn += 1;
                    rx += x as u64;
                } else {
                    let b = b_at(x, y);
                    let c = ((pixel as f64 - b) / (p_at(x, y) - b)).min(1.0);
                    rw_sum += c;
                    ru += c * x as f64;
                }
            }
            full_n += rn;
            full_x += rx;
            full_y += rn * y as u64;
            cw += rw_sum;
            cu += ru;
            cv += rw_sum * y as f64;
        }
        let (cw, cu, cv) = (cw + full_n as f64, cu + full_x as f64, cv + full_y as f64);
        if !(cw > 0.0) {
            return Err(Rejection::Shape);
        }
        let plateau = p_at(seed.0, seed.1);
        Ok(Candidate {
            u: cu / cw,
            v: cv / cw,
            area: cw,
            plateau,
            contrast: plateau - b_at(seed.0, seed.1),
            roundness,
            radius: (area / std::f64::consts::PI).sqrt(),
        })
    }

    /// Identifies the candidates (trying subsets when there are extras) and builds the set.
    fn assemble(&mut self, mut rejected: RejectCounts, tracked: bool) -> MarkerSet {
        let n_markers = self.deck.marker_count();
        let mut cands = std::mem::take(&mut self.candidates);
        // Too many candidates to search: drop the saturated ones first (specular glints clip;
        // markers of a properly exposed frame do not).
        if cands.len() > n_markers + MAX_EXTRAS {
            let before = cands.len();
            cands.retain(|c| c.plateau < SATURATED as f64 - 2.0);
            rejected.unassigned += (before - cands.len()) as u32;
        }
        // At most 4 extras (or missing markers) are searched: beyond, the frame is not a deck.
        let whole = |blobs: &[Blob]| identify(blobs, &self.deck, &self.camera).into_iter().collect();
        let partial = |blobs: &[Blob]| identify_partial(blobs, &self.deck, &self.camera);
        let mut best = self.best_subset(&cands, 6, &whole);
        // Low over the deck the ring leaves the view: the centre, the bow and part of the ring.
        if best.is_none() {
            best = self.best_subset(&cands, 4, &partial);
        }
        self.candidates = cands;
        match best {
            Some((k, _, assigned)) => {
                rejected.unassigned += (self.candidates.len() - k) as u32;
                self.build(&assigned, rejected, tracked)
            }
            None => {
                rejected.unassigned += self.candidates.len() as u32;
                MarkerSet {
                    rejected,
                    ..MarkerSet::default()
                }
            }
        }
    }

    /// The largest consistent identification of a subset of the candidates (at least
    /// `min_markers`, at most [`MAX_EXTRAS`] left out), the best fitting of that size:
    /// (markers, fit, assignment). `identify` gives each subset's identifications to try.
    fn best_subset(
        &self,
        cands: &[Candidate],
        min_markers: usize,
        identify: &dyn Fn(&[Blob]) -> Identifications,
    ) -> Option<(usize, f64, Assignment)> {
        let (n, n_markers) = (cands.len(), self.deck.marker_count());
        if n < min_markers || n > n_markers + MAX_EXTRAS {
            return None;
        }
        let mut best: Option<(usize, f64, Assignment)> = None;
        let min_size = min_markers.max(n.saturating_sub(MAX_EXTRAS));
        for size in (min_size..=n.min(n_markers)).rev() {
            for_each_subset(n, size, &mut |subset: &[usize]| {
                let blobs: Vec<Blob> = subset
                    .iter()
                    .map(|&i| Blob {
                        u: cands[i].u,
                        v: cands[i].v,
                        area: cands[i].area,
                    })
                    .collect();
                for ids in identify(&blobs) {
                    let assigned: Vec<(usize, Candidate)> = ids
                        .iter()
                        .enumerate()
                        .filter_map(|(m, id)| id.map(|b| (m, cands[subset[b]])))
                        .collect();
                    let Some(fit) = self.consistency(&assigned) else {
                        continue;
                    };
                    if best.as_ref().is_none_or(|(_, f, _)| fit < *f) {
                        best = Some((assigned.len(), fit, assigned));
                    }
                }
            });
            if best.is_some() {
                break; // the largest consistent set wins
            }
        }
        best
    }

    /// How well an identification fits the image (lower is better), or None when it does not:
    /// the homography through the markers must leave them within `max_residual_px` (with five
    /// or more), show the deck from above (not mirrored), and give every disc the size it was
    /// measured at, up to one scale common to all (blur and overexposure grow every disc
    /// alike). The ring alone is symmetric: the sizes are what tells the bow apart when
    /// perspective makes a near ring disc look large (low over a tilted deck), and a wrong
    /// slot when four markers fit any homography. Small discs' areas are uncertain by about
    /// twice their radius' (a pixel of edge), so the tolerance widens for them.
    fn consistency(&self, assigned: &[(usize, Candidate)]) -> Option<f64> {
        let (src, dst) = self.correspondences(assigned)?;
        let h = homography::fit(&src, &dst)?;
        let residual = homography::rms_residual(&h, &src, &dst);
        if !(residual <= self.config.max_residual_px) {
            return None;
        }
        let mut log_ratios = Vec::with_capacity(assigned.len());
        for (k, (m, c)) in assigned.iter().enumerate() {
            let (_, det) = disc_image(&h, src[k])?;
            // Deck +x is image up and +y image left from above: a negative determinant.
            if !(det < 0.0) {
                return None;
            }
            let r = self.deck.disc_radius(*m);
            let predicted = std::f64::consts::PI * r * r * -det;
            log_ratios.push((c.area / predicted).ln());
        }
        let mut sorted = log_ratios.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let spread = log_ratios.iter().map(|l| (l - median).abs()).fold(0.0, f64::max);
        let smallest_px = assigned
            .iter()
            .map(|(_, c)| c.radius)
            .fold(f64::INFINITY, f64::min);
        // Sizes within 35 % of one another (more for small discs), the common scale within 2x.
        let tolerance = 1.35f64.ln() + 2.0 / smallest_px.max(1.0);
        (spread <= tolerance && median.abs() <= 2f64.ln()).then_some(spread + residual)
    }

    /// RMS residual (pixels) of the deck-to-image homography through the assigned markers.
    fn fit_residual(&self, assigned: &[(usize, Candidate)]) -> Option<f64> {
        let (src, dst) = self.correspondences(assigned)?;
        let h = homography::fit(&src, &dst)?;
        Some(homography::rms_residual(&h, &src, &dst))
    }

    /// Deck points and undistorted image points of the assigned markers.
    fn correspondences(&self, assigned: &[(usize, Candidate)]) -> Option<(Points, Points)> {
        let mut src = Vec::with_capacity(assigned.len());
        let mut dst = Vec::with_capacity(assigned.len());
        for (m, c) in assigned {
            let p = self.deck.marker_position(*m);
            src.push([p.x, p.y]);
            dst.push(self.camera.undistort_pixel([c.u, c.v])?);
        }
        Some((src, dst))
    }

    /// The marker set of assigned candidates, with the perspective bias removed.
    fn build(&self, assigned: &[(usize, Candidate)], rejected: RejectCounts, tracked: bool) -> MarkerSet {
        let mut set = MarkerSet {
            rejected,
            tracked: tracked.into(),
            ..MarkerSet::default()
        };
        let fit = self.correspondences(assigned).and_then(|(src, dst)| {
            let h = homography::fit(&src, &dst)?;
            Some((h, src, dst))
        });
        set.perspective_corrected = (self.config.correct_perspective && fit.is_some()).into();
        for (k, (m, c)) in assigned.iter().enumerate() {
            let (mut u, mut v) = (c.u, c.v);
            let mut residual = 0.0;
            if let Some((h, src, dst)) = &fit {
                if let Some(p) = homography::apply(h, src[k]) {
                    residual = ((p[0] - dst[k][0]).powi(2) + (p[1] - dst[k][1]).powi(2)).sqrt();
                }
                if self.config.correct_perspective {
                    let r = self.deck.disc_radius(*m);
                    if let Some((centre, image)) = homography::imaged_circle_centre(h, src[k], r) {
                        let ideal = [
                            dst[k][0] - (centre[0] - image[0]),
                            dst[k][1] - (centre[1] - image[1]),
                        ];
                        [u, v] = self.camera.distort_pixel(ideal);
                    }
                }
            }
            let contrast_score = (c.contrast / (4.0 * self.config.min_contrast)).min(1.0);
            let residual_score = 1.0 / (1.0 + residual * residual);
            set.markers[*m] = Marker {
                valid: true.into(),
                u,
                v,
                area_px: c.area,
                mean_intensity: c.plateau,
                quality: (c.roundness * contrast_score * residual_score).clamp(0.0, 1.0),
            };
        }
        // The markers not found whose discs the found ones put (partly) outside the image.
        if let Some((h, _, _)) = &fit {
            let (w, hgt) = (f64::from(self.camera.width), f64::from(self.camera.height));
            for m in (0..self.deck.marker_count()).filter(|m| !set.markers[*m].valid.get()) {
                let p = self.deck.marker_position(m);
                if let Some((ideal, det)) = disc_image(h, [p.x, p.y]) {
                    let [u, v] = self.camera.distort_pixel(ideal);
                    let r = self.deck.disc_radius(m) * det.abs().sqrt();
                    if !(u - r >= -0.5 && v - r >= -0.5 && u + r <= w - 0.5 && v + r <= hgt - 0.5) {
                        set.out_of_view |= 1 << m;
                    }
                }
            }
        }
        set.count = assigned.len() as u32;
        set.status = if set.count as usize == self.deck.marker_count() {
            DetectionStatus::Ok.into()
        } else {
            DetectionStatus::Partial.into()
        };
        set
    }

    fn remember(&mut self, set: &MarkerSet) {
        if set.status == DetectionStatus::Ok || set.status == DetectionStatus::Partial {
            let mut prev = [None; MAX_MARKERS];
            for (p, m) in prev.iter_mut().zip(&set.markers) {
                if m.valid.get() {
                    *p = Some((m.u, m.v, (m.area_px / std::f64::consts::PI).sqrt()));
                }
            }
            self.previous = Some(prev);
        } else {
            self.previous = None;
        }
    }
}

/// Where a homography (deck plane -> pixels) puts a deck point, and the determinant of its
/// Jacobian there (image area per deck area; negative for the deck seen from above). None
/// at the horizon.
fn disc_image(h: &nalgebra::Matrix3<f64>, [x, y]: [f64; 2]) -> Option<([f64; 2], f64)> {
    let p = h * nalgebra::Vector3::new(x, y, 1.0);
    if !(p.z.abs() > 1e-12) {
        return None;
    }
    let (u, v) = (p.x / p.z, p.y / p.z);
    let j = [
        (h[(0, 0)] - u * h[(2, 0)]) / p.z,
        (h[(0, 1)] - u * h[(2, 1)]) / p.z,
        (h[(1, 0)] - v * h[(2, 0)]) / p.z,
        (h[(1, 1)] - v * h[(2, 1)]) / p.z,
    ];
    let det = j[0] * j[3] - j[1] * j[2];
    det.is_finite().then_some(([u, v], det))
}

/// Sums over the pixels of a mask row (values 0 or 1): count, x, x^2, with x counted from the
/// row's start.
fn mask_row_sums<T>(mask: &[u8]) -> [T; 3]
where
    T: Copy + Default + From<u8> + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    let (mut n, mut sx, mut sxx) = (T::default(), T::default(), T::default());
    let mut x = T::default();
    let one = T::from(1);
    for &m in mask {
        let o = T::from(m);
        n = n + o;
        sx = sx + o * x;
        sxx = sxx + o * x * x;
        x = x + one;
    }
    [n, sx, sxx]
}

/// Sums over the pixels 2 or more deep in a mask row (`mask`, with the pixels `z` under it):
/// count, x, x^2, z, x z, with x counted from the row's start.
fn deep_row_sums<T>(mask: &[u8], z: &[u8]) -> [T; 5]
where
    T: Copy + Default + From<u8> + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    let (mut n, mut sx, mut sxx, mut sz, mut sxz) = (
        T::default(),
        T::default(),
        T::default(),
        T::default(),
        T::default(),
    );
    let mut x = T::default();
    let one = T::from(1);
    for (&m, &p) in mask.iter().zip(z) {
        let w = T::from((m >= 2) as u8);
        let wz = w * T::from(p);
        n = n + w;
        sx = sx + w * x;
        sxx = sxx + w * x * x;
        sz = sz + wz;
        sxz = sxz + wz * x;
        x = x + one;
    }
    [n, sx, sxx, sz, sxz]
}

/// Least-squares plane `z = p0 + p1 x + p2 y` from its normal equations, over integer pixel
/// coordinates and values (exact integer sums: cheap per pixel, no rounding).
#[derive(Default)]
struct PlaneFit {
    s: [i64; 9],
}

impl PlaneFit {
    #[inline(always)]
    fn add(&mut self, x: usize, y: usize, z: u8) {
        let (x, y, z) = (x as i64, y as i64, z as i64);
        for (acc, v) in self
            .s
            .iter_mut()
            .zip([1, x, y, x * x, y * y, x * y, z, x * z, y * z])
        {
            *acc += v;
        }
    }

    /// The pixels of row `y`, from their sums over the row: count, x, x^2, z, x z.
    fn add_row(&mut self, y: i64, [n, sx, sxx, sz, sxz]: [i64; 5]) {
        for (acc, v) in self
            .s
            .iter_mut()
            .zip([n, sx, n * y, sxx, n * y * y, sx * y, sz, sxz, sz * y])
        {
            *acc += v;
        }
    }

    /// None with fewer than 3 points or a degenerate layout.
    fn solve(&self) -> Option<[f64; 3]> {
        let [n, sx, sy, sxx, syy, sxy, sz, sxz, syz] = self.s.map(|v| v as f64);
        if n < 3.0 {
            return None;
        }
        let m = nalgebra::Matrix3::new(n, sx, sy, sx, sxx, sxy, sy, sxy, syy);
        let p = m.lu().solve(&nalgebra::Vector3::new(sz, sxz, syz))?;
        p.iter().all(|v| v.is_finite()).then(|| [p[0], p[1], p[2]])
    }
}

/// Least-squares plane `b0 + b1 x + b2 y` through the border pixels of a region, leaving out
/// pixels at least as bright as half the way to the peak (parts of other blobs).
fn fit_border_plane(
    frame: GrayView<'_>,
    (x0, y0, x1, y1): (usize, usize, usize, usize),
    peak: u8,
) -> [f64; 3] {
    // First pass: the border's median level decides what is "bright".
    let mut vals = [0u32; 256];
    let border = |f: &mut dyn FnMut(usize, usize)| {
        for x in x0..x1 {
            f(x, y0);
            f(x, y1 - 1);
        }
        for y in y0 + 1..y1 - 1 {
            f(x0, y);
            f(x1 - 1, y);
        }
    };
    let mut n = 0u32;
    border(&mut |x, y| {
        vals[frame.get(x, y) as usize] += 1;
        n += 1;
    });
    let mut acc = 0;
    let median = vals
        .iter()
        .position(|&c| {
            acc += c;
            acc * 2 >= n
        })
        .unwrap_or(0) as f64;
    let cut = 0.5 * (median + peak as f64);
    // Coordinates relative to the region's corner, for conditioning.
    let mut fit = PlaneFit::default();
    border(&mut |x, y| {
        let z = frame.get(x, y);
        if (z as f64) < cut {
            fit.add(x - x0, y - y0, z);
        }
    });
    let plane = fit.solve().unwrap_or([median, 0.0, 0.0]);
    // Back to frame coordinates.
    [
        plane[0] - plane[1] * x0 as f64 - plane[2] * y0 as f64,
        plane[1],
        plane[2],
    ]
}

/// Calls `f` with every subset of `0..n` of size `k` (ascending indices).
fn for_each_subset(n: usize, k: usize, f: &mut dyn FnMut(&[usize])) {
    fn rec(start: usize, n: usize, k: usize, cur: &mut Vec<usize>, f: &mut dyn FnMut(&[usize])) {
        if cur.len() == k {
            f(cur);
            return;
        }
        for i in start..n {
            if n - i < k - cur.len() {
                break;
            }
            cur.push(i);
            rec(i + 1, n, k, cur, f);
            cur.pop();
        }
    }
    rec(0, n, k, &mut Vec::with_capacity(k), f);
}

#[cfg(test)]
mod tests {
    use super::*;

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
