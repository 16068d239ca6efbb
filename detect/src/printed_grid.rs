//! The discs of a printed pattern, dark on a light sheet (a camera calibration target),
//! measured by the detector's disc measurement on the image inverted (the discs bright, as the
//! deck's markers are).

use crate::detector::{Detector, MeasuredDisc};
use deckwatch_common::image::GrayView;
use deckwatch_common::GrayImage;

/// The discs of a printed pattern in `frame`, dark discs on light paper, each measured by the detector's disc measurement on the inverted
/// image; centres in `frame`'s pixels. The detector's own search takes one threshold for the
/// frame (the deck's markers are alike); a printed sheet's discs range from black to light grey
/// under uneven light, so here each disc is seeded by a local minimum at least the detector's
/// least contrast below its surroundings, and its region is its own half-way component grown
/// by the detector's margin.
pub fn find_printed_discs(detector: &mut Detector, frame: GrayView<'_>) -> Vec<MeasuredDisc> {
    let (w, h) = (frame.width(), frame.height());
    let (x0, y0, x1, y1) = (0, 0, w, h);
    let mut inverted = GrayImage::new(w, h);
    for y in 0..h {
        for (out, &p) in inverted.data[y * w..(y + 1) * w].iter_mut().zip(frame.row(y)) {
            *out = 255 - p;
        }
    }
    let config = detector.config().clone();
    let max_area = std::f64::consts::PI * config.max_radius_px * config.max_radius_px;
    let box_extreme = |x: usize, y: usize, r: usize, darkest: bool| {
        let (xa, xb, ya, yb) = (
            x.saturating_sub(r),
            (x + r + 1).min(w),
            y.saturating_sub(r),
            (y + r + 1).min(h),
        );
        let mut e = frame.get(x, y);
        for yy in ya..yb {
            for &p in &frame.row(yy)[xa..xb] {
                e = if darkest { e.min(p) } else { e.max(p) };
            }
        }
        e
    };
    // Seeds: pixels darkest within SEED_RADIUS_PX, darker than the brightest within
    // SURROUND_RADIUS_PX (paper beyond even the largest disc) by the least contrast.
    let mut seeds = Vec::new();
    for y in y0..y1 {
        for x in x0..x1 {
            let p = frame.get(x, y);
            if p == box_extreme(x, y, SEED_RADIUS_PX, true) {
                let surround = box_extreme(x, y, SURROUND_RADIUS_PX, false);
                if f64::from(surround) - f64::from(p) >= config.min_contrast {
                    seeds.push((p, x, y, surround));
                }
            }
        }
    }
    seeds.sort_unstable();
    let mut taken = vec![false; w * h];
    let mut stack = Vec::new();
    let mut discs = Vec::new();
    for (p, x, y, surround) in seeds {
        if taken[y * w + x] {
            continue;
        }
        // The seed's component at or below half way to its surroundings.
        let level = ((u16::from(p) + u16::from(surround)) / 2) as u8;
        let (mut area, mut bx) = (0usize, (x, y, x, y));
        taken[y * w + x] = true;
        stack.clear();
        stack.push((x, y));
        while let Some((cx, cy)) = stack.pop() {
            area += 1;
            bx = (bx.0.min(cx), bx.1.min(cy), bx.2.max(cx), bx.3.max(cy));
            let next = [
                (cx > x0).then(|| (cx - 1, cy)),
                (cx + 1 < x1).then(|| (cx + 1, cy)),
                (cy > y0).then(|| (cx, cy - 1)),
                (cy + 1 < y1).then(|| (cx, cy + 1)),
            ];
            for (nx, ny) in next.into_iter().flatten() {
                if !taken[ny * w + nx] && frame.get(nx, ny) <= level {
                    taken[ny * w + nx] = true;
                    stack.push((nx, ny));
                }
            }
        }
        if area as f64 > max_area {
            continue;
        }
        let roi = (
            bx.0.saturating_sub(REGION_MARGIN_PX).max(x0),
            bx.1.saturating_sub(REGION_MARGIN_PX).max(y0),
            (bx.2 + 1 + REGION_MARGIN_PX).min(x1),
            (bx.3 + 1 + REGION_MARGIN_PX).min(y1),
        );
        discs.extend(detector.measure_disc(inverted.view(), roi));
    }
    discs
}

/// A seed is the darkest pixel within this distance (px) ...
const SEED_RADIUS_PX: usize = 3;
/// ... and darker than the brightest within this one by the detector's least contrast.
const SURROUND_RADIUS_PX: usize = 12;
/// A disc's region: its half-way component grown by this (px), the detector's margin around a
/// candidate at its smallest coarse step (2 px for discs of 2 px radius or more: step + 3 is 5;
/// one less here, so that the 6 px gaps of the most foreshortened grids hold no neighbour).
const REGION_MARGIN_PX: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::{CameraModel, DeckLayout};

    /// A light sheet with dark discs on a dark table: every disc on it is found, within a
    /// twentieth of a pixel, and nothing of the table.
    #[test]
    fn finds_the_dark_discs_of_a_light_sheet() {
        let (w, h) = (200usize, 150usize);
        let mut img = GrayImage::new(w, h);
        let centres: Vec<[f64; 2]> = (0..3)
            .flat_map(|j| (0..4).map(move |i| [70.0 + 20.0 * i as f64, 50.0 + 20.0 * j as f64]))
            .collect();
        for y in 0..h {
            for x in 0..w {
                let on_sheet = (50..150).contains(&x) && (30..110).contains(&y);
                let in_disc = centres
                    .iter()
                    .any(|c| (x as f64 - c[0]).hypot(y as f64 - c[1]) <= 5.0);
                img.data[y * w + x] = match (on_sheet, in_disc) {
                    (true, false) => 230,
                    (true, true) => 40,
                    (false, _) => 25,
                };
            }
        }
        let cam = CameraModel::centred(w as u32, h as u32, 200.0, 200.0);
        let deck = DeckLayout::paper();
        let mut config = crate::DetectorConfig::for_camera(&cam, &deck);
        (config.min_radius_px, config.max_radius_px) = (2.0, 12.0);
        let mut det = Detector::new(cam, deck, config);
        let discs = find_printed_discs(&mut det, img.view());
        assert_eq!(discs.len(), centres.len());
        for d in &discs {
            assert!(
                centres
                    .iter()
                    .any(|c| (d.u_px - c[0]).hypot(d.v_px - c[1]) < 0.05),
                "{d:?}"
            );
        }
    }
}
