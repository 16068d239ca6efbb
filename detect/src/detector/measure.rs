//! Measuring one candidate disc: its sub-pixel centre, size and contrast against a fitted
//! background plane, and the perspective bias of its centre (CONVENTIONS.md C6).

use super::*;

mod blurred;
mod coverage;
mod profile;

use blurred::{
    BlurredCentre, DiscShape, BLURRED_BACKGROUND_RING_PX, BLURRED_EDGE_SIGMA_PX,
    BLURRED_ISOLATION_PER_EDGE_SIGMA, SAME_DISC_PX,
};
use coverage::{Coverage, RowCoverage};

impl Detector {
    /// Measures the blob in a region (x0, y0, x1, y1), half-open.
    ///
    /// Every pass is a straight loop over row slices (the compiler vectorises the peak, the
    /// mask and the erosion), and the costly per-pixel work, the coverage ratio with its
    /// division, is done only for pixels that are not deep inside the disc: a tracked frame's
    /// nine regions cost about as much as reading them.
    pub(super) fn measure(
        &mut self,
        frame: GrayView<'_>,
        roi: (usize, usize, usize, usize),
    ) -> Result<Candidate, Rejection> {
        self.measure_in(frame, roi, true)
    }

    /// [`Self::measure`]; `may_grow`: a blurred disc whose tail the region cuts is measured
    /// again, once, in a region that holds it (see [`Self::blurred_centre`]).
    fn measure_in(
        &mut self,
        frame: GrayView<'_>,
        roi: (usize, usize, usize, usize),
        may_grow: bool,
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
        let (bg, noise_dn) = fit_border_plane(frame, roi, peak);
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
        // A small disc's plateau: the interior's mean level, with the background's slope
        // scaled to it (uneven light multiplies both). A plane fitted to a few interior pixels
        // tilts with the noise and with the blur's tail in its outer ones, unevenly as the disc
        // sits on the pixel grid, and that tilt moves the centre. A large disc's interior
        // fixes its own slope, better than the background's, which the deck's texture tilts
        // and the scaling would magnify.
        let small = 2.0 * l1.sqrt() < SMALL_DISC_PX;
        let scaled_plateau = {
            let [n, sx, sy, .., sz, _, _] = pn.s.map(|v| v as f64);
            match n > 0.0 {
                true => {
                    let (zbar, xb, yb) = (sz / n, sx / n, sy / n);
                    let b = b_at(x0, y0) + bg[1] * xb + bg[2] * yb;
                    let scale = if b > 1.0 { zbar / b } else { 0.0 };
                    let (gx, gy) = (bg[1] * scale, bg[2] * scale);
                    [zbar - gx * xb - gy * yb, gx, gy]
                }
                false => [peak as f64, 0.0, 0.0],
            }
        };
        let plateau_plane = match small {
            true => scaled_plateau,
            false => pn.solve().unwrap_or([peak as f64, 0.0, 0.0]),
        };
        let p_at = |x: usize, y: usize| {
            plateau_plane[0] + plateau_plane[1] * (x - x0) as f64 + plateau_plane[2] * (y - y0) as f64
        };
        // Coverage-weighted centre in a window reaching beyond the disc as far as its edge's
        // blur does: pixels 3 deep count as fully covered (no interior noise; integer sums),
        // the rest by (I - background) / (plateau - background); pixels 2 deep as covered
        // unless the blur reaches them. Every pixel beyond the edge
        // adds the background's noise and texture with a lever arm of the disc's radius, and
        // cutting the blur's tail short moves the centre too: the reach is measured per disc
        // (`edge_sigma_px`). The sums are kept per band of distance beyond the disc, so one
        // pass over the widest window serves whatever reach the edge asks for.
        let a = 2.0 * l1.sqrt();
        let b_axis = 2.0 * l2.max(0.0).sqrt();
        let disc = DiscWindow {
            roi,
            region_width: rw,
            reach: a + REACH_BANDS_PX[BANDS - 1],
            band_r2: REACH_BANDS_PX.map(|d| (a + d) * (a + d)),
            // Ramanujan's perimeter of the ellipse.
            perimeter: std::f64::consts::PI
                * (3.0 * (a + b_axis) - ((3.0 * a + b_axis) * (a + 3.0 * b_axis)).sqrt()),
            background: bg,
            plateau: plateau_plane,
        };
        // A small disc's window is centred again on the centre its first pass gives: the
        // mask's centroid is off by a tenth of a pixel there, and the window's edge then cuts
        // the blur's tail unevenly.
        let mut window = self.window_centre(frame, &disc, (x0 as f64 + mx, y0 as f64 + my))?;
        if small {
            window = self.window_centre(frame, &disc, (window.u, window.v))?;
        }
        let plateau = p_at(seed.0, seed.1);
        let contrast = plateau - b_at(seed.0, seed.1);
        let std_of = |w: &WindowCentre| centre_std_px(w.weighed, [w.u, w.v], w.coverage, noise_dn / contrast);
        let mut centre = [window.u, window.v, std_of(&window)];
        // A large disc blurred as widely is measured the same way where its pattern leaves room
        // for the wide window and the background's ring clear of its neighbours' tails (the
        // widest window, 6 deviations, and 3 more for the neighbour's tail); in a crowded
        // pattern the neighbours' tails in that ring moved the centres by tenths of a pixel, and
        // the banded window stands.
        let isolated = a * self.least_gap_per_radius
            >= BLURRED_ISOLATION_PER_EDGE_SIGMA * window.edge_sigma_px + BLURRED_BACKGROUND_RING_PX;
        if (small || isolated) && window.edge_sigma_px > BLURRED_EDGE_SIGMA_PX {
            // The plateau is the interior's level with a slope: a blurred disc has no flat
            // interior, and a plane fitted to its dome tilts as the dome sits on the pixel grid.
            // A small disc's slope is the background's scaled to it (its plateau already); a
            // large one's the light's across the pattern, which the deck's texture does not
            // tilt (`Self::blurred_plateau`).
            let blurred_disc = DiscWindow {
                plateau: match small {
                    true => scaled_plateau,
                    false => self.blurred_plateau(scaled_plateau, (mx, my)),
                },
                ..disc
            };
            let mut pixels = std::mem::take(&mut self.profile_pixels);
            let measured = self.blurred_centre(
                frame,
                &blurred_disc,
                &window,
                &DiscShape {
                    semi_major_px: a,
                    axis_ratio: roundness,
                    moments: [cxx, cxy, cyy],
                },
                &mut pixels,
            );
            self.profile_pixels = pixels;
            match measured {
                BlurredCentre::Measured(wide, profile) => {
                    // Only the centre and the blur's width: the area stays the banded
                    // window's, which identification's size check is measured on (the wide
                    // window's sum follows the tone curve's lift of the tail: a filmic curve
                    // left no pattern identified).
                    centre = match profile {
                        // The edge profile's centre where its fit settles: it weighs each
                        // pixel by what it tells of the centre, and its deviation is its own
                        // residual's (`measure/profile.rs`).
                        Some(p) => [p.u, p.v, p.std_px],
                        None => blurred::combined_centre(centre, [wide.u, wide.v, std_of(&wide)]),
                    };
                    window.edge_sigma_px = wide.edge_sigma_px;
                }
                BlurredCentre::Cut(grown) if may_grow => {
                    // Its centre measured again in a region that holds the blur's tail, its
                    // border (the background) beyond it (the rest as measured here, as
                    // identification knows it); where that finds no disc (another one in the
                    // region), the banded window's centre stands.
                    match self.measure_in(frame, grown, false) {
                        // The same disc (the grown region's brightest may be another's).
                        Ok(c) if (c.u - centre[0]).hypot(c.v - centre[1]) < SAME_DISC_PX => {
                            centre = [c.u, c.v, c.centre_std_px];
                            window.edge_sigma_px = c.edge_sigma_px;
                        }
                        _ => {}
                    }
                }
                BlurredCentre::Cut(_) => {}
            }
        }
        let [u, v, centre_std_px] = centre;
        Ok(Candidate {
            u,
            v,
            area: window.coverage,
            plateau,
            contrast,
            roundness,
            radius: (area / std::f64::consts::PI).sqrt(),
            centre_std_px,
            edge_sigma_px: window.edge_sigma_px,
        })
    }

    /// A large blurred disc's plateau (about its region's corner): the interior's level at its
    /// centroid `at` (px about the corner), as `scaled` has it, with the slope of the light
    /// across the pattern (`light::LightModel`, measured within `MAX_LIGHT_AGE_FRAMES`), and
    /// without one, none. Not the slope of `scaled` (the region border's plane scaled to the
    /// disc): it carries what is painted on the deck there, and on the simulator's textured
    /// deck moved a centre by 0.36 px (`light::tests`).
    fn blurred_plateau(&self, scaled: [f64; 3], at: (f64, f64)) -> [f64; 3] {
        let level = scaled[0] + scaled[1] * at.0 + scaled[2] * at.1;
        let (rx, ry) = match self.light {
            Some((light, age)) if age <= MAX_LIGHT_AGE_FRAMES => light.relative_slope(),
            _ => (0.0, 0.0),
        };
        let (gx, gy) = (level * rx, level * ry);
        [level - gx * at.0 - gy * at.1, gx, gy]
    }

    /// The coverage-weighted centre of a disc in a window around `(cx, cy)` (see `measure`),
    /// its reach from the edge's measured blur.
    fn window_centre(
        &self,
        frame: GrayView<'_>,
        disc: &DiscWindow,
        (cx, cy): (f64, f64),
    ) -> Result<WindowCentre, Rejection> {
        let (x0, y0, x1, y1) = disc.roi;
        let (rw, reach, band_r2) = (disc.region_width, disc.reach, disc.band_r2);
        let wx0 = ((cx - reach).floor().max(x0 as f64)) as usize;
        let wx1 = ((cx + reach).ceil().min((x1 - 1) as f64)) as usize;
        let wy0 = ((cy - reach).floor().max(y0 as f64)) as usize;
        let wy1 = ((cy + reach).ceil().min((y1 - 1) as f64)) as usize;
        let (mut full_n, mut full_x, mut full_y) = (0u64, 0u64, 0u64);
        // The pixels that are not full: per band (the inner pixels, 2 deep, about 1.5 px inside
        // the edge, as band `INNER`), their count and moments (x, x^2, y, y^2) for the
        // centre's noise; their coverage with its x and y moments; and the sum of c (1 - c),
        // the edge's width (for a Gaussian edge of deviation s, s / sqrt(pi) per pixel of
        // perimeter).
        let mut sums = WindowSums::default();
        let plane_coverage = Coverage::new(disc.background, disc.plateau, (x0, y0), (cx, cy));
        for y in wy0..=wy1 {
            let dy = y as f64 - cy;
            let dy2 = dy * dy;
            // The row's pixels within reach: a chord. (No `floor` or `ceil`: without SSE4.1
            // they are library calls.)
            let h2 = reach * reach - dy2;
            if h2 < 0.0 {
                continue;
            }
            let h = h2.sqrt();
            let xa = ceil_at_least(cx - h, wx0);
            let Some(xb) = floor_at_most(cx + h, wx1) else {
                continue;
            };
            if xa > xb {
                continue;
            }
            let mrow = &self.mask[(y - y0) * rw + (xa - x0)..=(y - y0) * rw + (xb - x0)];
            let row = &frame.row(y)[xa..=xb];
            // The full pixels in a pass of their own (vectorised).
            let [rn, rxl] = if mrow.len() <= 1024 {
                full_row_sums::<u32>(mrow).map(u64::from)
            } else {
                full_row_sums::<u64>(mrow)
            };
            let yu = y as u64;
            full_n += rn;
            full_x += rxl + rn * xa as u64;
            full_y += rn * yu;
            // The others: the row's two ends up to its first and last full pixel, and between
            // them only where the mask has a hole (checked vectorised).
            let mut row_sums = RowSums::default();
            let at = RowPixels {
                coverage: plane_coverage.row(y),
                dy2,
                band_r2,
            };
            match mrow.iter().position(|&m| m >= 3) {
                None => row_sums.add(&at, xa, mrow, row),
                Some(first) => {
                    let last = mrow.len() - 1 - mrow.iter().rev().position(|&m| m >= 3).unwrap_or(0);
                    row_sums.add(&at, xa, &mrow[..first], &row[..first]);
                    if !mrow[first..=last].iter().fold(true, |all, &m| all & (m >= 3)) {
                        row_sums.add(&at, xa + first, &mrow[first..=last], &row[first..=last]);
                    }
                    row_sums.add(&at, xa + last + 1, &mrow[last + 1..], &row[last + 1..]);
                }
            }
            sums.add_row(&row_sums, y);
        }
        // The edge's deviation from its width over the ellipse's perimeter (Ramanujan), the
        // inner pixels' part counted once the blur reaches them (a sharp edge's inner pixels
        // are covered, and their noise would read as width); and the reach it asks for: each
        // band counts by the share of it within the reach.
        let sigma_of = |partial: f64| std::f64::consts::PI.sqrt() * partial / disc.perimeter.max(1.0);
        let outer_partial: f64 = sums.partial[..BANDS].iter().sum();
        let mut edge_sigma_px = sigma_of(outer_partial);
        if REACH_PER_EDGE_SIGMA * edge_sigma_px > INNER_MEASURED_FROM_PX - BAND_LOOKAHEAD_PX {
            edge_sigma_px = sigma_of(outer_partial + sums.partial[INNER]);
        }
        let wanted =
            (REACH_PER_EDGE_SIGMA * edge_sigma_px).clamp(REACH_BANDS_PX[0], REACH_BANDS_PX[BANDS - 1]);
        let share = |k: usize| match k {
            0 => 1.0,
            _ => ((wanted - REACH_BANDS_PX[k - 1]) / (REACH_BANDS_PX[k] - REACH_BANDS_PX[k - 1]))
                .clamp(0.0, 1.0),
        };
        let (inner, inner_cover) = (sums.counts[INNER], sums.cover[INNER]);
        let (edge, cover) = (&sums.counts, &sums.cover);
        let (mut cw, mut cu, mut cv) = (full_n as f64, full_x as f64, full_y as f64);
        // The pixels 2 deep by their coverage as far as the blur reaches them (from none
        // at 2 deviations of 0.75 px to all at 2 of 1 px), as covered for the rest.
        let measured_inner = ((REACH_PER_EDGE_SIGMA * edge_sigma_px - INNER_MEASURED_FROM_PX)
            / INNER_MEASURED_SPAN_PX)
            .clamp(0.0, 1.0);
        let [n_in, x_in, _, y_in, _] = inner.map(|v| v as f64);
        let f = measured_inner;
        cw += f * inner_cover[0] + (1.0 - f) * n_in;
        cu += f * inner_cover[1] + (1.0 - f) * x_in;
        cv += f * inner_cover[2] + (1.0 - f) * y_in;
        let mut weighed = inner.map(|v| f * f * v as f64);
        for k in 0..BANDS {
            let f = share(k);
            (cw, cu, cv) = (cw + f * cover[k][0], cu + f * cover[k][1], cv + f * cover[k][2]);
            // A pixel counted by f moves the centre f times as much: its noise by f^2.
            for (acc, v) in weighed.iter_mut().zip(edge[k]) {
                *acc += f * f * v as f64;
            }
        }
        if !(cw > 0.0) {
            return Err(Rejection::Shape);
        }
        Ok(WindowCentre {
            u: cu / cw,
            v: cv / cw,
            coverage: cw,
            weighed,
            edge_sigma_px,
        })
    }
}

/// What a disc's window needs beyond its centre: its region (x0, y0, x1, y1) and width, the
/// widest reach and the bands' squared radii, the ellipse's perimeter, and the background and
/// plateau planes.
struct DiscWindow {
    roi: (usize, usize, usize, usize),
    region_width: usize,
    reach: f64,
    band_r2: [f64; BANDS],
    perimeter: f64,
    background: [f64; 3],
    plateau: [f64; 3],
}

/// A disc's coverage-weighted centre, its total coverage, the moments of its weighed pixels
/// (for the centre's noise) and its edge's blur.
struct WindowCentre {
    u: f64,
    v: f64,
    coverage: f64,
    weighed: [f64; 5],
    edge_sigma_px: f64,
}

/// The smallest integer at least `v`, and at least `min`.
#[inline(always)]
fn ceil_at_least(v: f64, min: usize) -> usize {
    if !(v > min as f64) {
        return min;
    }
    let t = v as usize;
    t + usize::from((t as f64) < v)
}

/// The largest integer at most `v`, and at most `max`; None below 0.
#[inline(always)]
fn floor_at_most(v: f64, max: usize) -> Option<usize> {
    match v < max as f64 {
        true => (v >= 0.0).then_some(v as usize),
        false => Some(max),
    }
}

/// What a row's pixels need to be summed: their coverage, and the bands' bounds.
struct RowPixels {
    coverage: RowCoverage,
    dy2: f64,
    band_r2: [f64; BANDS],
}

/// A row's pixels that are not full, per band (the last, `INNER`, the pixels 2 deep): count,
/// x and x^2; coverage and its x moment; the sum of c (1 - c).
#[derive(Default)]
struct RowSums {
    counts: [[u64; 3]; BANDS + 1],
    cover: [[f64; 2]; BANDS + 1],
    partial: [f64; BANDS + 1],
}

impl RowSums {
    /// Adds the pixels of a run starting at column `x0` (full pixels skipped).
    #[inline(always)]
    fn add(&mut self, at: &RowPixels, x0: usize, mask: &[u8], pixels: &[u8]) {
        for ((x, &m), &pixel) in (x0..).zip(mask).zip(pixels) {
            if m >= 3 {
                continue;
            }
            let xf = x as f64;
            let dx = xf - at.coverage.cx;
            let d2 = dx * dx + at.dy2;
            let band = match m == 2 {
                true => INNER,
                false => at.band_r2[..BANDS - 1]
                    .iter()
                    .map(|&r2| usize::from(d2 > r2))
                    .sum(),
            };
            let c = at.coverage.at(x, pixel);
            let cc = c.max(0.0);
            let xu = x as u64;
            self.partial[band] += cc * (1.0 - cc);
            let n = &mut self.counts[band];
            *n = [n[0] + 1, n[1] + xu, n[2] + xu * xu];
            let w = &mut self.cover[band];
            *w = [w[0] + c, w[1] + c * xf];
        }
    }
}

/// A window's pixels that are not full, per band as in [`RowSums`]: count, x, x^2, y, y^2;
/// coverage and its x and y moments; the sum of c (1 - c).
#[derive(Default)]
struct WindowSums {
    counts: [[u64; 5]; BANDS + 1],
    cover: [[f64; 3]; BANDS + 1],
    partial: [f64; BANDS + 1],
}

impl WindowSums {
    #[inline(always)]
    fn add_row(&mut self, row: &RowSums, y: usize) {
        let (yu, yf) = (y as u64, y as f64);
        for k in 0..=BANDS {
            let [n, sx, sxx] = row.counts[k];
            for (acc, v) in self.counts[k].iter_mut().zip([n, sx, sxx, n * yu, n * yu * yu]) {
                *acc += v;
            }
            let [c, cx] = row.cover[k];
            for (acc, v) in self.cover[k].iter_mut().zip([c, cx, c * yf]) {
                *acc += v;
            }
            self.partial[k] += row.partial[k];
        }
    }
}

/// The bands of distance beyond the disc's half-level edge (pixels) over which the coverage is
/// summed: the reach is chosen among them, interpolated, per disc.
const REACH_BANDS_PX: [f64; BANDS] = [1.0, 1.5, 2.0, 3.0];
const BANDS: usize = 4;
/// Discs with a semi-major axis below this (pixels) are small: their plateau's slope is the
/// background's, and their window is centred a second time (see `measure`).
const SMALL_DISC_PX: f64 = 10.0;
/// The inner pixels' index in the per-band sums.
const INNER: usize = BANDS;
const BAND_LOOKAHEAD_PX: f64 = 0.25;
/// Twice the edge's deviation from which the pixels 2 deep (1.5 px inside the edge or more)
/// count by their measured coverage rather than as covered, and over what span fully.
const INNER_MEASURED_FROM_PX: f64 = 1.5;
const INNER_MEASURED_SPAN_PX: f64 = 0.5;
/// The reach in deviations of the edge's blur: a Gaussian edge's coverage is 2 % at 2 deviations.
const REACH_PER_EDGE_SIGMA: f64 = 2.0;

/// The standard deviation per axis of a coverage-weighted centre `(u, v)` of total weight
/// `coverage`, from the noise of each edge pixel's coverage (`coverage_noise`: the pixel noise
/// over the contrast). A pixel's coverage moves the centre by `(x - u) / coverage`, so the
/// variance is `coverage_noise^2 sum (x - u)^2 / coverage^2` over the edge pixels (count, x,
/// x^2, y, y^2 in `edge`, each pixel by the square of its share), the mean of the two axes'. Pixels deep inside count as covered,
/// without noise.
pub(super) fn centre_std_px(edge: [f64; 5], [u, v]: [f64; 2], coverage: f64, coverage_noise: f64) -> f64 {
    let [n, sx, sxx, sy, syy] = edge;
    // sum (x - u)^2 = sum x^2 - 2 u sum x + n u^2, and the same for y: never negative in
    // exact arithmetic; the clamp keeps rounding from making it so.
    let spread = (sxx - 2.0 * u * sx + n * u * u).max(0.0) + (syy - 2.0 * v * sy + n * v * v).max(0.0);
    (0.5 * spread).sqrt() * coverage_noise.abs() / coverage
}

/// Where a homography (deck plane -> pixels) puts a deck point, and the determinant of its
/// Jacobian there (image area per deck area; negative for the deck seen from above). None
/// at the horizon.
pub(super) fn disc_image(h: &nalgebra::Matrix3<f64>, [x, y]: [f64; 2]) -> Option<([f64; 2], f64)> {
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
pub(super) fn mask_row_sums<T>(mask: &[u8]) -> [T; 3]
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

/// Count and x (from the row's start) of the pixels 3 or more deep in a mask row.
pub(super) fn full_row_sums<T>(mask: &[u8]) -> [T; 2]
where
    T: Copy + Default + From<u8> + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    let (mut n, mut sx) = (T::default(), T::default());
    let mut x = T::default();
    let one = T::from(1);
    for &m in mask {
        let w = T::from((m >= 3) as u8);
        n = n + w;
        sx = sx + w * x;
        x = x + one;
    }
    [n, sx]
}

/// Sums over the pixels 2 or more deep in a mask row (`mask`, with the pixels `z` under it):
/// count, x, x^2, z, x z, with x counted from the row's start.
pub(super) fn deep_row_sums<T>(mask: &[u8], z: &[u8]) -> [T; 5]
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
pub(super) struct PlaneFit {
    pub(super) s: [i64; 9],
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
/// pixels at least as bright as half the way to the peak (parts of other blobs), and the
/// pixels' deviation from it (DN): the frame's noise there (with any texture of the deck),
/// at least that of 8-bit quantisation.
pub(super) fn fit_border_plane(
    frame: GrayView<'_>,
    (x0, y0, x1, y1): (usize, usize, usize, usize),
    peak: u8,
) -> ([f64; 3], f64) {
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
    let mut szz = 0i64;
    border(&mut |x, y| {
        let z = frame.get(x, y);
        if (z as f64) < cut {
            fit.add(x - x0, y - y0, z);
            szz += i64::from(z) * i64::from(z);
        }
    });
    let plane = fit.solve().unwrap_or([median, 0.0, 0.0]);
    // The residual's sum of squares from the normal equations' sums: sum z^2 - p . (sum z,
    // sum x z, sum y z), over n - 3 degrees of freedom.
    let [n, .., sz, sxz, syz] = fit.s.map(|v| v as f64);
    let ssr = szz as f64 - (plane[0] * sz + plane[1] * sxz + plane[2] * syz);
    const QUANTISATION_DN2: f64 = 1.0 / 12.0;
    let noise_dn = match n > 3.0 {
        true => (ssr / (n - 3.0)).max(QUANTISATION_DN2).sqrt(),
        false => QUANTISATION_DN2.sqrt(),
    };
    // Back to frame coordinates.
    let plane = [
        plane[0] - plane[1] * x0 as f64 - plane[2] * y0 as f64,
        plane[1],
        plane[2],
    ];
    (plane, noise_dn)
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::{CameraModel, DeckLayout, GrayImage};

    /// Standard normal distribution function (Abramowitz and Stegun 7.1.26, within 1.5e-7).
    fn normal_cdf(x: f64) -> f64 {
        let z = x.abs() / std::f64::consts::SQRT_2;
        let t = 1.0 / (1.0 + 0.327_591_1 * z);
        let poly = t
            * (0.254_829_592
                + t * (-0.284_496_736 + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
        let erf = 1.0 - poly * (-z * z).exp();
        0.5 * (1.0 + erf.copysign(x))
    }

    /// A deterministic standard normal stream (xorshift and Box-Muller).
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn next(&mut self) -> f64 {
            let (a, b) = (self.uniform(), self.uniform());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        }
    }

    /// A disc of radius `r` at (u, v) on a 48 x 48 frame, its edge blurred by a Gaussian of
    /// deviation `blur` (0: sharp), each pixel integrated over 8 x 8 samples; 60 DN of
    /// background, 150 of contrast, `noise` DN of normal noise, rounded to 8 bits.
    fn disc_frame(u: f64, v: f64, r: f64, blur: f64, noise: f64, rng: &mut Normal) -> GrayImage {
        let mut img = GrayImage::new(48, 48);
        for y in 0..48 {
            for x in 0..48 {
                let mut cover = 0.0;
                for k in 0..64 {
                    let (sx, sy) = (
                        x as f64 + ((k % 8) as f64 - 3.5) / 8.0,
                        y as f64 + ((k / 8) as f64 - 3.5) / 8.0,
                    );
                    let d = (sx - u).hypot(sy - v);
                    cover += match blur > 0.0 {
                        true => normal_cdf((r - d) / blur),
                        false => f64::from(u8::from(d <= r)),
                    };
                }
                let value = 60.0 + 150.0 * cover / 64.0 + noise * rng.next();
                img.data[y * 48 + x] = value.round().clamp(0.0, 255.0) as u8;
            }
        }
        img
    }

    fn detector() -> Detector {
        let cam = CameraModel::rpi_v2().scaled_to(640, 480);
        let deck = DeckLayout::paper();
        Detector::new(cam, deck, DetectorConfig::for_camera(&cam, &deck))
    }

    /// The edge's measured blur is the painted one, with the pixel's own width added
    /// (variance 1/12): sharp, a binned camera's lens, a defocused one.
    #[test]
    fn the_edge_blur_is_measured_from_the_image() {
        let mut det = detector();
        let mut rng = Normal(7);
        for blur in [0.0, 0.8, 1.5] {
            let img = disc_frame(23.3, 24.6, 7.0, blur, 0.0, &mut rng);
            let Ok(c) = det.measure(img.view(), (0, 0, 48, 48)) else {
                panic!("the disc was not measured")
            };
            let expected = (blur * blur + 1.0 / 12.0).sqrt();
            assert!(
                (c.edge_sigma_px / expected - 1.0).abs() < 0.12,
                "blur {blur}: measured {} against {expected}",
                c.edge_sigma_px
            );
        }
    }

    /// The stated deviation of a centre is the noise's part of the centres' scatter over many
    /// frames of the same disc (sub-pixel positions drawn anew each time): each position is
    /// measured with noise and without, and the scatter without (the estimator's own
    /// sub-pixel error, which it does not state) is taken out. For a small and a larger disc,
    /// sharp and blurred; and the centre is unbiased.
    #[test]
    fn the_centres_stated_deviation_is_its_scatter() {
        let mut det = detector();
        let mut rng = Normal(11);
        for (r, blur, noise) in [(4.0, 0.8, 6.0), (8.0, 0.0, 4.0), (8.0, 1.5, 4.0)] {
            let (mut noisy_sq, mut clean_sq, mut sum_err, mut stated) = (0.0, 0.0, [0.0; 2], 0.0);
            let n = 300;
            for _ in 0..n {
                let (u, v) = (23.0 + rng.uniform(), 24.0 + rng.uniform());
                for (level, sq) in [(noise, &mut noisy_sq), (0.0, &mut clean_sq)] {
                    let img = disc_frame(u, v, r, blur, level, &mut rng);
                    let Ok(c) = det.measure(img.view(), (0, 0, 48, 48)) else {
                        panic!("the disc was not measured")
                    };
                    *sq += (c.u - u).powi(2) + (c.v - v).powi(2);
                    if level > 0.0 {
                        sum_err[0] += c.u - u;
                        sum_err[1] += c.v - v;
                        stated += c.centre_std_px * c.centre_std_px;
                    }
                }
            }
            let n = n as f64;
            let scatter = (noisy_sq / (2.0 * n)).sqrt();
            let noise_part = ((noisy_sq - clean_sq).max(0.0) / (2.0 * n)).sqrt();
            let stated = (stated / n).sqrt();
            let context = format!(
                "r {r}, blur {blur}, noise {noise}: stated {stated:.4} px, noise's part {noise_part:.4} px \\
                 (scatter {scatter:.4} px)"
            );
            assert!((0.75..1.2).contains(&(stated / noise_part)), "{context}");
            for e in sum_err {
                assert!(
                    (e / n).abs() < 3.0 * scatter / n.sqrt() + 0.01,
                    "bias {}: {context}",
                    e / n
                );
            }
        }
    }
}
