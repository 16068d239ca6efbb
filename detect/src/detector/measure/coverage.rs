//! A pixel's coverage of a disc, from the background's and the plateau's planes.

/// A pixel's coverage, `(I - background) / (plateau - background)` (at most 1), both planes
/// known: the reciprocal of their difference, which changes little across a disc, taken to
/// first order about the disc's centre (relative error the square of the difference's
/// change over the window, below 1e-4 for a 1 % change), so that no pixel needs a division.
pub(super) struct Coverage {
    bg: [f64; 3],
    /// The reciprocal at the centre, and its change per pixel in x and y.
    inv: [f64; 3],
    centre: (f64, f64),
}

impl Coverage {
    /// `bg`: the background plane in frame coordinates; `plateau`: the plateau's, about the
    /// region's corner `(x0, y0)`; `centre`: the disc's centre.
    pub(super) fn new(bg: [f64; 3], plateau: [f64; 3], (x0, y0): (usize, usize), centre: (f64, f64)) -> Self {
        let (cx, cy) = centre;
        let span = plateau[0] + plateau[1] * (cx - x0 as f64) + plateau[2] * (cy - y0 as f64)
            - (bg[0] + bg[1] * cx + bg[2] * cy);
        let i0 = 1.0 / span;
        Self {
            bg,
            inv: [
                i0,
                -(plateau[1] - bg[1]) * i0 * i0,
                -(plateau[2] - bg[2]) * i0 * i0,
            ],
            centre,
        }
    }

    pub(super) fn row(&self, y: usize) -> RowCoverage {
        let yf = y as f64;
        RowCoverage {
            b0: self.bg[0] + self.bg[2] * yf,
            b1: self.bg[1],
            i0: self.inv[0] + self.inv[2] * (yf - self.centre.1),
            i1: self.inv[1],
            cx: self.centre.0,
        }
    }
}

/// [`Coverage`] on one row.
pub(super) struct RowCoverage {
    b0: f64,
    b1: f64,
    i0: f64,
    i1: f64,
    pub(super) cx: f64,
}

impl RowCoverage {
    #[inline(always)]
    pub(super) fn at(&self, x: usize, pixel: u8) -> f64 {
        self.unclamped(x, pixel).min(1.0)
    }

    /// The coverage not held to 1: a blurred disc's pixels are counted by their level alone.
    #[inline(always)]
    pub(super) fn unclamped(&self, x: usize, pixel: u8) -> f64 {
        let xf = x as f64;
        (pixel as f64 - self.b0 - self.b1 * xf) * (self.i0 + self.i1 * (xf - self.cx))
    }
}
