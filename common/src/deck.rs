//! The marker layout on the flight deck and its index convention (CONVENTIONS.md §4):
//! index 0 = centre; index 1 + k (k = 0..n_ring) = ring marker at 360 k / n_ring degrees from +x
//! toward +y (counter-clockwise seen from above); index 1 is the bow marker. The opposite of ring
//! marker k is ring marker (k + n_ring / 2) mod n_ring.

#[cfg(feature = "shm")]
use iceoryx2::prelude::ZeroCopySend;
use nalgebra::Vector3;

/// Index of the centre marker.
pub const CENTRE: usize = 0;
/// Index of the bow marker (ring marker k = 0, on the deck's +x axis).
pub const BOW: usize = 1;
/// Most ring markers a layout may have; fixed-size messages are sized from it.
pub const MAX_RING_MARKERS: usize = 16;
/// Most markers (ring + centre) a layout may have.
pub const MAX_MARKERS: usize = MAX_RING_MARKERS + 1;

/// Geometry of the deck's markers, in metres, in the deck frame (z = deck normal).
/// `#[repr(C)]`: pipeline messages carry the layout their markers refer to.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.DeckLayout.v1"))]
pub struct DeckLayout {
    /// Radius of the ring the ring markers' centres lie on (paper: 0.5 m).
    pub ring_radius_m: f64,
    /// Disc radius of the centre and ordinary ring markers.
    pub marker_radius_m: f64,
    /// Disc radius of the bow marker (larger, so that it can be told apart).
    pub bow_marker_radius_m: f64,
    /// Number of ring markers: even (the paper's estimator pairs opposite markers).
    pub n_ring: usize,
}

impl Default for DeckLayout {
    fn default() -> Self {
        Self::paper()
    }
}

impl DeckLayout {
    /// The paper's deck: 8 markers on a 1 m ring plus the centre; disc radii as CONVENTIONS.md §4
    /// recommends for detection (0.05 m, bow 0.08 m).
    pub fn paper() -> Self {
        Self {
            ring_radius_m: 0.5,
            marker_radius_m: 0.05,
            bow_marker_radius_m: 0.08,
            n_ring: 8,
        }
    }

    /// Checks the layout; the error names the field.
    pub fn validate(&self) -> Result<(), crate::InvalidField> {
        for (name, v) in [
            ("ring_radius_m", self.ring_radius_m),
            ("marker_radius_m", self.marker_radius_m),
            ("bow_marker_radius_m", self.bow_marker_radius_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(crate::InvalidField::new(
                    name,
                    format!("must be a positive number, got {v}"),
                ));
            }
        }
        if self.n_ring < 4 || self.n_ring > MAX_RING_MARKERS || !self.n_ring.is_multiple_of(2) {
            return Err(crate::InvalidField::new(
                "n_ring",
                format!(
                    "must be even and within 4..={MAX_RING_MARKERS}, got {}",
                    self.n_ring
                ),
            ));
        }
        // Discs must not touch: neighbours on the ring, and the centre disc with the ring.
        let chord = 2.0 * self.ring_radius_m * (std::f64::consts::PI / self.n_ring as f64).sin();
        if chord <= self.marker_radius_m + self.bow_marker_radius_m {
            return Err(crate::InvalidField::new(
                "n_ring",
                format!(
                    "{} markers on a {} m ring overlap (neighbour spacing {chord:.4} m)",
                    self.n_ring, self.ring_radius_m
                ),
            ));
        }
        if self.ring_radius_m <= self.marker_radius_m + self.bow_marker_radius_m {
            return Err(crate::InvalidField::new(
                "ring_radius_m",
                format!("{} m is too small for the marker discs", self.ring_radius_m),
            ));
        }
        Ok(())
    }

    /// Number of markers including the centre.
    pub fn marker_count(&self) -> usize {
        self.n_ring + 1
    }

    /// Marker index of ring marker `k` (0-based around the ring).
    pub fn ring_index(&self, k: usize) -> usize {
        1 + k % self.n_ring
    }

    /// Marker index of the ring marker opposite to marker `index`; None for the centre.
    pub fn opposite(&self, index: usize) -> Option<usize> {
        (index >= 1 && index <= self.n_ring).then(|| self.ring_index(index - 1 + self.n_ring / 2))
    }

    /// Position of marker `index` in the deck frame.
    pub fn marker_position(&self, index: usize) -> Vector3<f64> {
        assert!(index < self.marker_count(), "marker index {index} out of range");
        if index == CENTRE {
            return Vector3::zeros();
        }
        let angle = 2.0 * std::f64::consts::PI * (index - 1) as f64 / self.n_ring as f64;
        Vector3::new(
            self.ring_radius_m * angle.cos(),
            self.ring_radius_m * angle.sin(),
            0.0,
        )
    }

    /// All marker positions in index order.
    pub fn marker_positions(&self) -> Vec<Vector3<f64>> {
        (0..self.marker_count())
            .map(|i| self.marker_position(i))
            .collect()
    }

    /// Disc radius of marker `index`.
    pub fn disc_radius(&self, index: usize) -> f64 {
        if index == BOW {
            self.bow_marker_radius_m
        } else {
            self.marker_radius_m
        }
    }

    /// A short label for logs and viewers: "centre", "bow", "ring3".
    pub fn marker_label(index: usize) -> String {
        match index {
            CENTRE => "centre".into(),
            BOW => "bow".into(),
            i => format!("ring{}", i - 1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_layout_positions() {
        let d = DeckLayout::paper();
        d.validate().unwrap();
        assert_eq!(d.marker_count(), 9);
        assert_eq!(d.marker_position(CENTRE), Vector3::zeros());
        assert_eq!(d.marker_position(BOW), Vector3::new(0.5, 0.0, 0.0));
        // Index 3 (k = 2) at 90 deg: port side (+y).
        let p = d.marker_position(3);
        assert!(p.x.abs() < 1e-15 && (p.y - 0.5).abs() < 1e-15);
        for i in 1..=8 {
            let o = d.opposite(i).unwrap();
            assert!((d.marker_position(i) + d.marker_position(o)).norm() < 1e-15);
            assert_eq!(d.opposite(o), Some(i));
        }
        assert_eq!(d.opposite(BOW), Some(5));
        assert_eq!(d.opposite(CENTRE), None);
        assert_eq!(d.opposite(9), None);
        assert_eq!(d.disc_radius(BOW), 0.08);
        assert_eq!(d.disc_radius(4), 0.05);
        assert_eq!(DeckLayout::marker_label(3), "ring2");
    }

    #[test]
    fn invalid_layouts_name_the_field() {
        let bad = |f: fn(&mut DeckLayout), field: &str| {
            let mut d = DeckLayout::paper();
            f(&mut d);
            let e = d.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        };
        bad(|d| d.n_ring = 7, "`n_ring`");
        bad(|d| d.n_ring = 2, "`n_ring`");
        bad(|d| d.n_ring = 18, "`n_ring`");
        bad(
            |d| {
                d.n_ring = 16;
                d.ring_radius_m = 0.3;
            },
            "`n_ring`",
        ); // discs overlap
        bad(|d| d.ring_radius_m = -0.5, "`ring_radius_m`");
        bad(|d| d.marker_radius_m = f64::NAN, "`marker_radius_m`");
        bad(|d| d.bow_marker_radius_m = 0.0, "`bow_marker_radius_m`");
    }
}
