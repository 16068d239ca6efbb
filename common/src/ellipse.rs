//! An ellipse's geometric parameters (fitted in the estimate stage, drawn by the viewers).

#[cfg(feature = "shm")]
use iceoryx2::prelude::ZeroCopySend;
use std::f64::consts::PI;

/// An ellipse: centre, semi-axes (`semi_major >= semi_minor`) and the major axis's angle from +x
/// in (-90, 90] degrees (radians here), measured toward +y of the coordinates it was fitted in.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.Ellipse.v1"))]
pub struct Ellipse {
    pub centre: [f64; 2],
    pub semi_major: f64,
    pub semi_minor: f64,
    pub angle: f64,
}

impl Ellipse {
    /// `n` points around the boundary (for drawing a line strip); the first is repeated last.
    pub fn boundary(&self, n: usize) -> Vec<[f64; 2]> {
        let (s, c) = self.angle.sin_cos();
        (0..=n)
            .map(|k| {
                let t = 2.0 * PI * k as f64 / n as f64;
                let (x, y) = (self.semi_major * t.cos(), self.semi_minor * t.sin());
                [self.centre[0] + c * x - s * y, self.centre[1] + s * x + c * y]
            })
            .collect()
    }

    /// Approximate distance of a point from the boundary (exact on the axes): the radial
    /// deviation in the ellipse's normalised frame, scaled back by the local radius.
    pub fn radial_residual(&self, [x, y]: [f64; 2]) -> f64 {
        let (s, c) = self.angle.sin_cos();
        let (dx, dy) = (x - self.centre[0], y - self.centre[1]);
        let (xe, ye) = (c * dx + s * dy, -s * dx + c * dy);
        let k = ((xe / self.semi_major).powi(2) + (ye / self.semi_minor).powi(2)).sqrt();
        if k == 0.0 {
            return self.semi_minor;
        }
        // The boundary point on the same ray is (xe, ye) / k.
        (1.0 - 1.0 / k) * (xe * xe + ye * ye).sqrt()
    }
}
