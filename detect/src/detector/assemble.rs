//! From measured discs to a marker set: the best-fitting subset by the deck's geometry, its
//! consistency and residual, identities, and what tracking remembers for the next frame.

use super::light::LightModel;
use super::measure::disc_image;
use super::*;

impl Detector {
    /// Identifies the candidates (trying subsets when there are extras) and builds the set.
    pub(super) fn assemble(&mut self, mut rejected: RejectCounts, tracked: bool) -> MarkerSet {
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
        // ... and then the bow: its slot comes from the ring's orientation in an earlier frame
        // (identities carried over, as tracking carries them).
        let mut carried = tracked;
        if let Some((bow_angle, _)) = self
            .orientation
            .filter(|&(_, age)| best.is_none() && age <= MAX_ORIENTATION_AGE_FRAMES)
        {
            let (deck, camera) = (&self.deck, &self.camera);
            let oriented = |blobs: &[Blob]| identify_with_orientation(blobs, deck, camera, bow_angle);
            best = self.best_subset(&cands, ORIENTATION_MIN_MARKERS, &oriented);
            carried = carried || best.is_some();
        }
        self.candidates = cands;
        match best {
            Some((k, _, assigned)) => {
                rejected.unassigned += (self.candidates.len() - k) as u32;
                self.build(&assigned, rejected, carried)
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
    pub(super) fn best_subset(
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
    /// twice their radius' (a pixel of edge), so the tolerance widens for them; blurred discs'
    /// common scale by the edge's blur.
    pub(super) fn consistency(&self, assigned: &[(usize, Candidate)]) -> Option<f64> {
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
        // A blurred edge's apparent place depends on the camera's tone curve (a filmic curve
        // lifts the tail: twice the area at a 2.5 px blur on 5 px discs): the common scale
        // may grow by an edge shift of twice the blur beyond a pixel's. The spread stays: it
        // tells the bow marker apart.
        let blur_px = assigned.iter().map(|(_, c)| c.edge_sigma_px).fold(0.0, f64::max);
        let edge_shift_px = 2.0 * (blur_px - 1.0).max(0.0);
        let scale_limit = 2f64.ln() + 2.0 * (1.0 + edge_shift_px / smallest_px.max(1.0)).ln();
        (spread <= tolerance && median.abs() <= scale_limit).then_some(spread + residual)
    }

    /// RMS residual (pixels) of the deck-to-image homography through the assigned markers.
    pub(super) fn fit_residual(&self, assigned: &[(usize, Candidate)]) -> Option<f64> {
        let (src, dst) = self.correspondences(assigned)?;
        let h = homography::fit(&src, &dst)?;
        Some(homography::rms_residual(&h, &src, &dst))
    }

    /// Deck points and undistorted image points of the assigned markers.
    pub(super) fn correspondences(&self, assigned: &[(usize, Candidate)]) -> Option<(Points, Points)> {
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
    pub(super) fn build(
        &self,
        assigned: &[(usize, Candidate)],
        rejected: RejectCounts,
        tracked: bool,
    ) -> MarkerSet {
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
                centre_std_px: c.centre_std_px,
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

    pub(super) fn remember(&mut self, set: &MarkerSet) {
        if set.status == DetectionStatus::Ok || set.status == DetectionStatus::Partial {
            let mut prev = [None; MAX_MARKERS];
            for (p, m) in prev.iter_mut().zip(&set.markers) {
                if m.valid.get() {
                    *p = Some((m.u, m.v, (m.area_px / std::f64::consts::PI).sqrt()));
                }
            }
            self.previous = Some(prev);
            // The markers of the common size only: a larger disc (the bow) is less dimmed by the
            // blur at its centre, and its level would tilt the light toward it.
            let common_radius = self.deck.disc_radius(0);
            let levels = (0..self.deck.marker_count())
                .filter(|&i| (self.deck.disc_radius(i) - common_radius).abs() <= 1e-3 * common_radius)
                .map(|i| &set.markers[i])
                .filter(|m| m.valid.get())
                .map(|m| (m.u, m.v, m.mean_intensity));
            if let Some(light) = LightModel::fit(levels) {
                self.light = Some((light, 0));
            }
            if let Some(angle) = ring_orientation(|i| set.pixel(i), &self.deck, &self.camera) {
                self.orientation = Some((angle, 0));
            }
        } else {
            self.previous = None;
        }
    }
}

/// Calls `f` with every subset of `0..n` of size `k` (ascending indices).
pub(super) fn for_each_subset(n: usize, k: usize, f: &mut dyn FnMut(&[usize])) {
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
