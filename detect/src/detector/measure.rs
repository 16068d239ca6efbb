//! Measuring one candidate disc: its sub-pixel centre, size and contrast against a fitted
//! background plane, and the perspective bias of its centre (CONVENTIONS.md C6).

use super::*;

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
/// pixels at least as bright as half the way to the peak (parts of other blobs).
pub(super) fn fit_border_plane(
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
