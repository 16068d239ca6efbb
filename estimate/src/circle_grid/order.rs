//! Ordering measured disc centres into the rows and columns of a circle grid whose origin is
//! marked by the one larger disc (as in a "modified circle grid" calibration target).

use super::{GridError, GridLayout};
use deckwatch_common::homography;

/// A disc counts as the origin's larger one at this multiple of the median radius or more.
const ORIGIN_RADIUS_RATIO: f64 = 1.4;
/// A point is taken for a predicted grid position within this fraction of the spacing.
const SNAP_FRACTION: f64 = 0.35;
/// The second axis's neighbour is at most this many times as far as the first's.
const AXIS_LENGTH_RATIO: f64 = 1.6;
/// A new point is predicted from the ordered points at most this many rows and columns away.
const LOCAL_CELLS: usize = 3;

/// The centres (px) of the grid's points in the layout's order (row-major: point `(i, j)`,
/// column `i` along the grid's x from the origin, at `j * cols + i`), chosen among `centres`
/// (with their radii, px). The origin is the largest disc; its two nearest neighbours in
/// different directions are `(1, 0)` and `(0, 1)`, the x axis the one that makes the image's
/// turn from x to y positive (u right, v down: clockwise on screen), so that every view of the
/// grid's front is labelled alike. The grid then grows one step at a time, each new point
/// where the homography of the points so far predicts it.
pub fn order_grid(
    centres: &[[f64; 2]],
    radii_px: &[f64],
    layout: &GridLayout,
) -> Result<Vec<[f64; 2]>, GridError> {
    let n = centres.len();
    if n != radii_px.len() || n < layout.cols * layout.rows {
        return Err(GridError::TooFewDiscs {
            found: n.min(radii_px.len()),
            expected: layout.cols * layout.rows,
        });
    }
    let mut sorted = radii_px.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[n / 2];
    // The origin: the largest disc from which a grid grows (a larger blob off the sheet does not).
    let mut origins: Vec<usize> = (0..n)
        .filter(|&o| radii_px[o] >= ORIGIN_RADIUS_RATIO * median)
        .collect();
    origins.sort_by(|&a, &b| radii_px[b].total_cmp(&radii_px[a]));
    let mut outcome = Err(GridError::NoOrigin);
    for origin in origins {
        outcome = grow_from(centres, origin, layout);
        if outcome.is_ok() {
            break;
        }
    }
    outcome
}

/// The grid grown from `origin` (see [`order_grid`]).
fn grow_from(centres: &[[f64; 2]], origin: usize, layout: &GridLayout) -> Result<Vec<[f64; 2]>, GridError> {
    let n = centres.len();
    let distance = |a: usize, b: usize| (centres[a][0] - centres[b][0]).hypot(centres[a][1] - centres[b][1]);
    let mut by_distance: Vec<usize> = (0..n).filter(|&k| k != origin).collect();
    by_distance.sort_by(|&a, &b| distance(origin, a).total_cmp(&distance(origin, b)));
    let direction = |k: usize| {
        [
            centres[k][0] - centres[origin][0],
            centres[k][1] - centres[origin][1],
        ]
    };
    let first = by_distance[0];
    let e1 = direction(first);
    // The second axis: the nearest point more than 45 deg from the first.
    let second = by_distance[1..]
        .iter()
        .copied()
        .find(|&k| {
            let e = direction(k);
            let cos = (e1[0] * e[0] + e1[1] * e[1]) / (e1[0].hypot(e1[1]) * e[0].hypot(e[1]));
            cos.abs() < std::f64::consts::FRAC_1_SQRT_2
                && e[0].hypot(e[1]) < AXIS_LENGTH_RATIO * e1[0].hypot(e1[1])
        })
        .ok_or(GridError::NoOrigin)?;
    let e2 = direction(second);
    let (x_axis, y_axis) = match e1[0] * e2[1] - e1[1] * e2[0] > 0.0 {
        true => (first, second),
        false => (second, first),
    };
    let spacing_px = 0.5 * (distance(origin, first) + distance(origin, second));
    let snap_px = SNAP_FRACTION * spacing_px;
    let (cols, rows) = (layout.cols, layout.rows);
    let mut assigned: Vec<Option<usize>> = vec![None; cols * rows];
    let mut used = vec![false; n];
    for (cell, k) in [(0, origin), (1, x_axis), (cols, y_axis)] {
        assigned[cell] = Some(k);
        used[k] = true;
    }
    let nearest_free = |p: [f64; 2], used: &[bool]| {
        (0..n)
            .filter(|&k| !used[k])
            .map(|k| (k, (centres[k][0] - p[0]).hypot(centres[k][1] - p[1])))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|&(_, d)| d <= snap_px)
            .map(|(k, _)| k)
    };
    // (1, 1) from the parallelogram of the first three: four points for a homography.
    let o = centres[origin];
    let diagonal = [
        centres[x_axis][0] + centres[y_axis][0] - o[0],
        centres[x_axis][1] + centres[y_axis][1] - o[1],
    ];
    let k = nearest_free(diagonal, &used).ok_or(GridError::Incomplete {
        found: 3,
        expected: cols * rows,
    })?;
    assigned[cols + 1] = Some(k);
    used[k] = true;
    loop {
        let mut grew = false;
        for cell in 0..cols * rows {
            if assigned[cell].is_some() {
                continue;
            }
            let (i, j) = (cell % cols, cell / cols);
            let beside = (i > 0 && assigned[cell - 1].is_some())
                || (i + 1 < cols && assigned[cell + 1].is_some())
                || (j > 0 && assigned[cell - cols].is_some())
                || (j + 1 < rows && assigned[cell + cols].is_some());
            if !beside {
                continue;
            }
            // The homography of the points within LOCAL_CELLS of this one: the lens's
            // distortion bends the rows, and a fit over the whole grid so far extrapolates
            // the bend badly.
            let (grid, image): (Vec<[f64; 2]>, Vec<[f64; 2]>) = assigned
                .iter()
                .enumerate()
                .filter(|&(other, _)| {
                    (other % cols).abs_diff(i).max((other / cols).abs_diff(j)) <= LOCAL_CELLS
                })
                .filter_map(|(other, k)| {
                    k.map(|k| ([(other % cols) as f64, (other / cols) as f64], centres[k]))
                })
                .unzip();
            let Some(p) =
                homography::fit(&grid, &image).and_then(|h| homography::apply(&h, [i as f64, j as f64]))
            else {
                continue;
            };
            if let Some(k) = nearest_free(p, &used) {
                assigned[cell] = Some(k);
                used[k] = true;
                grew = true;
            }
        }
        if !grew {
            break;
        }
    }
    let found = assigned.iter().flatten().count();
    if found < cols * rows {
        return Err(GridError::Incomplete {
            found,
            expected: cols * rows,
        });
    }
    Ok(assigned.iter().flatten().map(|&k| centres[k]).collect())
}
