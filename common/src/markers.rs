//! Detected markers: what detection hands to estimation, one fixed-size value per frame.

use crate::deck::MAX_MARKERS;
use crate::wire::{WireBool, WireCode};
#[cfg(feature = "shm")]
use iceoryx2::prelude::ZeroCopySend;

/// One detected marker.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.Marker.v2"))]
pub struct Marker {
    /// Whether this marker was found; the other fields are meaningless when false.
    pub valid: WireBool,
    /// Subpixel centre: the image of the disc's centre (pixels, distorted as in the frame).
    pub u: f64,
    pub v: f64,
    /// Disc area in pixels (sum of coverage).
    pub area_px: f64,
    /// Mean intensity over the disc's plateau (DN).
    pub mean_intensity: f64,
    /// Quality in [0, 1]: 1 = round, high contrast, on the fitted deck plane; below ~0.3 doubtful.
    pub quality: f64,
    /// The centre's standard deviation per image axis (pixels) that the frame's own noise
    /// gives it: the noise measured around the disc, through the coverage-weighted centre
    /// (CONVENTIONS.md §4). Not the error of the disc's edge model (blur, perspective). NaN
    /// or 0 when not measured (older recordings): the pose then weighs every marker alike.
    pub centre_std_px: f64,
}

/// Outcome of detecting the deck's markers in a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DetectionStatus {
    /// Every marker found.
    Ok = 0,
    /// The centre, the bow and at least 4 more ring markers found; some missing.
    Partial = 1,
    /// No deck: no marker set could be identified. No marker is valid.
    #[default]
    NoDeck = 2,
    /// The frame could not be read (size, stride); no marker is valid.
    BadFrame = 3,
}

crate::wire_enum!(DetectionStatus, on_bad_code: BadFrame, [Ok, Partial, NoDeck, BadFrame]);

/// Why candidate blobs were not used.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.RejectCounts.v1"))]
pub struct RejectCounts {
    /// Too small or too large for a marker at any plausible altitude.
    pub area: u32,
    /// Not a filled ellipse (elongated, ragged, hollow).
    pub shape: u32,
    /// Touching the image border (a cut disc has a biased centre).
    pub border: u32,
    /// Round and sized like a marker, but not part of the identified pattern (glints).
    pub unassigned: u32,
}

/// The markers of one frame, by marker index (0 centre, 1 bow, 2.. counter-clockwise).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.MarkerSet.v3"))]
pub struct MarkerSet {
    pub status: WireCode<DetectionStatus>,
    /// Number of valid markers.
    pub count: u32,
    /// Whether the markers' identities were carried over from earlier frames rather than found
    /// in this one alone: by tracking (regions around the previous frame's), or from the ring's
    /// orientation in an earlier frame (a pattern without its bow).
    pub tracked: WireBool,
    /// Whether the centres are free of the perspective bias of disc centroids (CONVENTIONS.md C6);
    /// false: raw centroids, an estimator should correct them.
    pub perspective_corrected: WireBool,
    pub markers: [Marker; MAX_MARKERS],
    pub rejected: RejectCounts,
    /// Markers not found that the found ones put outside the image (bit i = marker i): the
    /// pattern is leaving the view (low over the deck, or off to a side).
    pub out_of_view: u32,
}

// bytemuck has `AnyBitPattern` for arrays of `Pod` only, and `Marker` has padding (it is not
// `Pod`), so the derive cannot see through `[Marker; MAX_MARKERS]`; the fields are checked here.
const _: () = {
    const fn any_bit_pattern<T: bytemuck::AnyBitPattern>() {}
    any_bit_pattern::<WireCode<DetectionStatus>>();
    any_bit_pattern::<u32>();
    any_bit_pattern::<WireBool>();
    any_bit_pattern::<Marker>();
    any_bit_pattern::<RejectCounts>();
    any_bit_pattern::<u32>();
};
// SAFETY: `repr(C)` of fields that each accept any bytes (checked above): an array of such a
// type does too, and so does the struct; zero is a value of each.
unsafe impl bytemuck::Zeroable for MarkerSet {}
// SAFETY: as above.
unsafe impl bytemuck::AnyBitPattern for MarkerSet {}

impl MarkerSet {
    /// Marker pixels by marker index for `n` markers (None where not found), as the estimators
    /// take them.
    pub fn pixels(&self, n: usize) -> Vec<Option<[f64; 2]>> {
        (0..n.min(MAX_MARKERS)).map(|i| self.pixel(i)).collect()
    }

    /// The centres' standard deviations (pixels) by marker index (NaN where not found), for the
    /// pose's weights: None unless every found marker has one that is finite and positive.
    /// A fixed array: no allocation per frame.
    pub fn centre_stds_px(&self) -> Option<[f64; MAX_MARKERS]> {
        let std_of = |m: &Marker| match m.valid.get() {
            true => m.centre_std_px,
            false => f64::NAN,
        };
        let measured = |m: &Marker| !m.valid.get() || (m.centre_std_px.is_finite() && m.centre_std_px > 0.0);
        self.markers
            .iter()
            .all(measured)
            .then(|| self.markers.each_ref().map(std_of))
    }

    /// Marker `index`'s pixel, None when not found (or no such marker).
    pub fn pixel(&self, index: usize) -> Option<[f64; 2]> {
        let m = self.markers.get(index)?;
        m.valid.get().then_some([m.u, m.v])
    }
}

/// One frame's markers: a row of the marker table (`deckwatch_formats::marker_table`).
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerRow {
    pub index: u64,
    pub timestamp_ns: u64,
    /// Pixel centres by marker index (None = not seen).
    pub markers: Vec<Option<[f64; 2]>>,
    /// Ground truth; `alt_m` doubles as the altimeter reading.
    pub truth: crate::truth::GroundTruth,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The deviations go to the pose only when every found marker has one.
    #[test]
    fn centre_deviations_only_when_every_found_marker_has_one() {
        let mut set = MarkerSet::default();
        for (i, std) in [(0, 0.05), (1, 0.03), (4, 0.08)] {
            set.markers[i] = Marker {
                valid: true.into(),
                centre_std_px: std,
                ..Marker::default()
            };
        }
        let stds = set.centre_stds_px().unwrap();
        assert_eq!((stds[0], stds[1], stds[4]), (0.05, 0.03, 0.08));
        assert!(stds[2].is_nan(), "a marker not found has none");
        for unmeasured in [0.0, f64::NAN, -1.0, f64::INFINITY] {
            set.markers[4].centre_std_px = unmeasured;
            assert_eq!(set.centre_stds_px(), None, "{unmeasured}");
        }
    }
}
