//! Geometric identification: which blob is which marker (CONVENTIONS.md §4 indices: 0 centre, 1 bow, then
//! counter-clockwise as seen from above). Centre = the blob nearest the centroid of the others,
//! bow = the clearly largest ring blob, the rest by their angle from the bow around the centre.

use deckwatch_common::{CameraModel, DeckLayout};
use std::f64::consts::TAU;

/// A bright blob: centre (pixels) and area (pixels, any consistent measure).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blob {
    pub u: f64,
    pub v: f64,
    pub area: f64,
}

/// Why blobs could not be identified as the deck's markers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IdentifyError {
    /// Fewer than the centre, the bow and 4 more ring markers.
    TooFewBlobs(usize),
    /// More blobs than the deck has markers (glints must be filtered first).
    TooManyBlobs(usize),
    /// A blob has a non-finite position or a non-positive area.
    InvalidBlob(usize),
    /// No ring blob is clearly larger than the others.
    AmbiguousBow,
    /// Two blobs fall in the same ring slot, or a blob lies between slots.
    RingMismatch,
}

impl std::fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewBlobs(n) => write!(f, "{n} blobs, at least 6 needed (centre, bow, 4 ring markers)"),
            Self::TooManyBlobs(n) => write!(f, "{n} blobs, more than the deck's markers"),
            Self::InvalidBlob(i) => write!(f, "blob {i} has an invalid position or area"),
            Self::AmbiguousBow => write!(f, "no ring blob is clearly the (larger) bow marker"),
            Self::RingMismatch => write!(f, "the ring blobs do not fall into distinct ring positions"),
        }
    }
}

impl std::error::Error for IdentifyError {}

/// The bow disc must be at least this much larger (area) than the median ring blob. The paper
/// deck's ratio is (0.08 / 0.05)^2 = 2.56; perspective changes areas by tens of percent.
const BOW_AREA_RATIO: f64 = 1.5;
/// A ring blob must lie within this fraction of the slot spacing from its slot's angle.
const SLOT_TOLERANCE: f64 = 0.35;

/// Identifies blobs as markers. Returns, by marker index, the index of the blob (None for a
/// marker not among the blobs).
pub fn identify(
    blobs: &[Blob],
    deck: &DeckLayout,
    camera: &CameraModel,
) -> Result<Vec<Option<usize>>, IdentifyError> {
    let n = blobs.len();
    if n < 6 {
        return Err(IdentifyError::TooFewBlobs(n));
    }
    if n > deck.marker_count() {
        return Err(IdentifyError::TooManyBlobs(n));
    }
    if let Some(i) = blobs
        .iter()
        .position(|b| !(b.u.is_finite() && b.v.is_finite() && b.area.is_finite() && b.area > 0.0))
    {
        return Err(IdentifyError::InvalidBlob(i));
    }
    // Normalised coordinates, so that non-square pixels do not distort angles.
    let xy = |b: &Blob| (b.u / camera.fx, b.v / camera.fy);
    let (sx, sy) = blobs
        .iter()
        .map(xy)
        .fold((0.0, 0.0), |(a, c), (x, y)| (a + x, c + y));
    let centre = (0..n)
        .min_by(|&a, &b| {
            let d = |i: usize| {
                let (x, y) = xy(&blobs[i]);
                let k = (n - 1) as f64;
                ((sx - x) / k - x).powi(2) + ((sy - y) / k - y).powi(2)
            };
            d(a).total_cmp(&d(b))
        })
        .expect("n >= 6");
    let ring: Vec<usize> = (0..n).filter(|&i| i != centre).collect();
    let bow = *ring
        .iter()
        .max_by(|&&a, &&b| blobs[a].area.total_cmp(&blobs[b].area))
        .expect("ring not empty");
    let mut areas: Vec<f64> = ring
        .iter()
        .filter(|&&i| i != bow)
        .map(|&i| blobs[i].area)
        .collect();
    areas.sort_by(f64::total_cmp);
    let median = areas[areas.len() / 2];
    if !(blobs[bow].area >= BOW_AREA_RATIO * median) {
        return Err(IdentifyError::AmbiguousBow);
    }
    let angle = |i: usize| ring_angle(xy(&blobs[i]), xy(&blobs[centre]));
    let mut out = vec![None; deck.marker_count()];
    out[0] = Some(centre);
    if !fill_ring_slots(&mut out, ring, angle, angle(bow), deck) {
        return Err(IdentifyError::RingMismatch);
    }
    Ok(out)
}

/// The angle of the image point `p` around `centre` (normalised coordinates): from the deck's
/// +x (image up) toward +y (image left), seen from above.
fn ring_angle(p: (f64, f64), centre: (f64, f64)) -> f64 {
    (-(p.0 - centre.0)).atan2(-(p.1 - centre.1))
}

/// Puts each of `members` into the ring slot its angle (`angle`, around the centre) from the
/// bow's (`bow_angle`) gives; false when one lies between slots (beyond `SLOT_TOLERANCE`) or
/// its slot is taken.
fn fill_ring_slots(
    ids: &mut [Option<usize>],
    members: impl IntoIterator<Item = usize>,
    angle: impl Fn(usize) -> f64,
    bow_angle: f64,
    deck: &DeckLayout,
) -> bool {
    let spacing = TAU / deck.n_ring as f64;
    members.into_iter().all(|i| {
        let rel = (angle(i) - bow_angle).rem_euclid(TAU) / spacing;
        let slot = rel.round();
        let index = deck.ring_index(slot as usize % deck.n_ring);
        if ids[index].is_none() && (rel - slot).abs() <= SLOT_TOLERANCE {
            ids[index] = Some(i);
            true
        } else {
            false
        }
    })
}

/// Identifications of a part of the pattern (low over the deck, where the ring leaves the view):
/// the centre, the bow and at least two more ring markers, every blob among them. Each pair of
/// blobs is tried as (bow, centre); the others take the ring slots their angle around the
/// centre gives. The angles from the centre's image are right up to the local affine
/// distortion of the deck plane's view (lines through the centre stay lines), whatever the
/// perspective elsewhere, so a partial ring falls into its slots as a whole one does. Several
/// hypotheses can pass: the caller checks each against the image (disc sizes, homography).
pub fn identify_partial(blobs: &[Blob], deck: &DeckLayout, camera: &CameraModel) -> Vec<Vec<Option<usize>>> {
    let n = blobs.len();
    let valid = blobs
        .iter()
        .all(|b| b.u.is_finite() && b.v.is_finite() && b.area.is_finite() && b.area > 0.0);
    if !(4..=deck.marker_count()).contains(&n) || !valid {
        return Vec::new();
    }
    let xy = |b: &Blob| (b.u / camera.fx, b.v / camera.fy);
    let mut out = Vec::new();
    for bow in 0..n {
        for centre in (0..n).filter(|&c| c != bow) {
            let angle = |i: usize| ring_angle(xy(&blobs[i]), xy(&blobs[centre]));
            let mut ids = vec![None; deck.marker_count()];
            ids[0] = Some(centre);
            ids[deck.ring_index(0)] = Some(bow);
            let others = (0..n).filter(|&i| i != bow && i != centre);
            if fill_ring_slots(&mut ids, others, angle, angle(bow), deck) {
                out.push(ids);
            }
        }
    }
    out
}

/// Identifications without the bow, from the ring's orientation known before: `bow_angle_rad`,
/// the image angle (around the centre, as [`ring_orientation`] measures it) at which the bow
/// was. Each blob is tried as the centre; the others take the ring slots their angle from that
/// orientation gives (the bow's slot too, if a blob falls there). At least the centre and three
/// ring markers. The ring alone is symmetric under a turn by its spacing: the orientation is
/// what tells the slots apart, so it must be within `SLOT_TOLERANCE` of a slot spacing of the
/// truth (the camera's yaw against the deck between the two frames: a hovering quadrotor and a
/// ship turn by a few degrees a second). The caller checks each hypothesis against the image.
pub fn identify_with_orientation(
    blobs: &[Blob],
    deck: &DeckLayout,
    camera: &CameraModel,
    bow_angle_rad: f64,
) -> Vec<Vec<Option<usize>>> {
    let n = blobs.len();
    let valid = blobs
        .iter()
        .all(|b| b.u.is_finite() && b.v.is_finite() && b.area.is_finite() && b.area > 0.0);
    if !(4..=deck.marker_count()).contains(&n) || !valid || !bow_angle_rad.is_finite() {
        return Vec::new();
    }
    let xy = |b: &Blob| (b.u / camera.fx, b.v / camera.fy);
    let mut out = Vec::new();
    for centre in 0..n {
        let angle = |i: usize| ring_angle(xy(&blobs[i]), xy(&blobs[centre]));
        let mut ids = vec![None; deck.marker_count()];
        ids[0] = Some(centre);
        if fill_ring_slots(
            &mut ids,
            (0..n).filter(|&i| i != centre),
            angle,
            bow_angle_rad,
            deck,
        ) {
            out.push(ids);
        }
    }
    out
}

/// The ring's orientation in the image: the angle (around the centre marker's image, in
/// normalised coordinates: 0 image up, increasing toward image left, the deck's +x to +y seen
/// from above) at which the bow is, from the centre and the ring markers identified (the
/// circular mean of each one's angle less its slot's); None without the centre or a ring
/// marker. `pixel`: a marker's pixel by its index (`MarkerSet::pixel`).
pub fn ring_orientation(
    pixel: impl Fn(usize) -> Option<[f64; 2]>,
    deck: &DeckLayout,
    camera: &CameraModel,
) -> Option<f64> {
    let [cu, cv] = pixel(0)?;
    let spacing = TAU / deck.n_ring as f64;
    let (mut sin, mut cos, mut count) = (0.0, 0.0, 0);
    for slot in 0..deck.n_ring {
        let Some([u, v]) = pixel(deck.ring_index(slot)) else {
            continue;
        };
        let a = ring_angle((u / camera.fx, v / camera.fy), (cu / camera.fx, cv / camera.fy))
            - slot as f64 * spacing;
        sin += a.sin();
        cos += a.cos();
        count += 1;
    }
    (count > 0 && (sin != 0.0 || cos != 0.0)).then(|| sin.atan2(cos))
}

/// Marker pixels by marker index, from blobs and an identification.
pub fn marker_pixels(blobs: &[Blob], ids: &[Option<usize>]) -> Vec<Option<[f64; 2]>> {
    ids.iter()
        .map(|id| id.map(|i| [blobs[i].u, blobs[i].v]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::{Rpy, SceneGeometry, Viewpoint};
    use proptest::prelude::*;

    /// Blobs at the exact marker images, with areas from the projected disc size.
    fn blobs_for(rpy: Rpy, vp: Viewpoint, cam: &CameraModel) -> Vec<Blob> {
        let deck = DeckLayout::paper();
        let scene = SceneGeometry {
            attitude: rpy.to_matrix(),
            viewpoint: vp,
        };
        let normal_z = rpy.to_matrix()[(2, 2)];
        (0..deck.marker_count())
            .map(|i| {
                let p = scene.deck_to_camera(&deck.marker_position(i));
                let uv = cam.project(&p).unwrap();
                let r = deck.disc_radius(i);
                let area = std::f64::consts::PI * r * r * cam.fx * cam.fy / (p.z * p.z) * normal_z;
                Blob {
                    u: uv[0],
                    v: uv[1],
                    area,
                }
            })
            .collect()
    }

    fn shuffle(v: &mut [Blob], seed: u64) -> Vec<usize> {
        // Fisher-Yates with a tiny LCG; returns the permutation (new position -> old index).
        let mut perm: Vec<usize> = (0..v.len()).collect();
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        for i in (1..v.len()).rev() {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let j = (s >> 33) as usize % (i + 1);
            v.swap(i, j);
            perm.swap(i, j);
        }
        perm
    }

    /// The ring measured with its bow gives the orientation; a later view without the bow (and
    /// one more ring marker) is named from it, a tilt's or a turn's 15 deg off included. An
    /// orientation a whole slot off names the ring wrongly: the symmetry the orientation
    /// breaks.
    #[test]
    fn without_the_bow_the_rings_orientation_names_the_slots() {
        let cam = CameraModel::rpi_v2();
        let deck = DeckLayout::paper();
        let blobs = blobs_for(
            Rpy::from_degrees(3.0, -2.0, 37.0),
            Viewpoint::level(0.1, -0.1, 5.0),
            &cam,
        );
        let pixels: Vec<Option<[f64; 2]>> = blobs.iter().map(|b| Some([b.u, b.v])).collect();
        let pixel = |i: usize| pixels.get(i).copied().flatten();
        let bow = ring_orientation(pixel, &deck, &cam).expect("a whole pattern");
        let kept: Vec<usize> = (0..blobs.len()).filter(|&i| i != 1 && i != 4).collect();
        let seen: Vec<Blob> = kept.iter().map(|&i| blobs[i]).collect();
        let right: Vec<Option<usize>> = (0..deck.marker_count())
            .map(|m| kept.iter().position(|&i| i == m))
            .collect();
        for error_deg in [-15.0f64, 0.0, 15.0] {
            let ids = identify_with_orientation(&seen, &deck, &cam, bow + error_deg.to_radians());
            assert!(ids.contains(&right), "{error_deg} deg off: {ids:?}");
        }
        let a_slot_off = identify_with_orientation(&seen, &deck, &cam, bow + TAU / deck.n_ring as f64);
        assert!(!a_slot_off.contains(&right));
        assert!(
            ring_orientation(|i| (i == 0).then(|| pixel(0)).flatten(), &deck, &cam).is_none(),
            "the centre alone"
        );
    }

    proptest! {
        #[test]
        fn identifies_shuffled_markers(roll in -25.0..25.0f64, pitch in -10.0..10.0f64, yaw in -180.0..180.0f64,
                                       ox in -0.3..0.3f64, oy in -0.3..0.3f64, h in 4.0..6.0f64,
                                       seed in 0u64..1000, hide in 0usize..10, paper_cam in any::<bool>()) {
            let cam = if paper_cam { CameraModel::paper() } else { CameraModel::rpi_v2() };
            let vp = Viewpoint::level(ox, oy, h);
            let mut blobs = blobs_for(Rpy::from_degrees(roll, pitch, yaw), vp, &cam);
            let mut original: Vec<usize> = (0..blobs.len()).collect();
            // Hide one ring marker other than the bow (hide >= 9: hide none).
            if (2..9).contains(&hide) {
                blobs.remove(hide);
                original.remove(hide);
            }
            let perm = shuffle(&mut blobs, seed);
            let ids = identify(&blobs, &DeckLayout::paper(), &cam).unwrap();
            for (marker, id) in ids.iter().enumerate() {
                match id {
                    Some(b) => prop_assert_eq!(original[perm[*b]], marker),
                    None => prop_assert_eq!(marker, hide),
                }
            }
        }

        #[test]
        fn never_panics_on_garbage(pts in proptest::collection::vec((-1e4..1e4f64, -1e4..1e4f64, -1.0..1e3f64), 0..12)) {
            let blobs: Vec<Blob> = pts.iter().map(|&(u, v, area)| Blob { u, v, area }).collect();
            let _ = identify(&blobs, &DeckLayout::paper(), &CameraModel::rpi_v2());
        }
    }

    #[test]
    fn a_partial_pattern_is_among_the_hypotheses() {
        // Low over the deck, tilted: the centre, the bow and two ring markers in view.
        let cam = CameraModel::rpi_v2();
        let deck = DeckLayout::paper();
        let all = blobs_for(
            Rpy::from_degrees(12.0, -6.0, 30.0),
            Viewpoint::level(0.1, 0.05, 1.2),
            &cam,
        );
        for keep in [vec![0, 1, 2, 8], vec![0, 1, 3, 4, 5], vec![1, 0, 7, 6, 2]] {
            let blobs: Vec<Blob> = keep.iter().map(|&i| all[i]).collect();
            let hypotheses = identify_partial(&blobs, &deck, &cam);
            let truth: Vec<Option<usize>> = (0..9).map(|m| keep.iter().position(|&k| k == m)).collect();
            assert!(hypotheses.contains(&truth), "{keep:?}: {hypotheses:?}");
        }
        // Too few, or garbage: none.
        assert!(identify_partial(&all[..3], &deck, &cam).is_empty());
        let mut bad = all[..5].to_vec();
        bad[2].area = -1.0;
        assert!(identify_partial(&bad, &deck, &cam).is_empty());
    }

    #[test]
    fn refuses_what_it_cannot_identify() {
        let cam = CameraModel::rpi_v2();
        let deck = DeckLayout::paper();
        let blobs = blobs_for(Rpy::from_degrees(5.0, 3.0, 1.0), Viewpoint::centred(5.0), &cam);
        assert_eq!(
            identify(&blobs[..5], &deck, &cam),
            Err(IdentifyError::TooFewBlobs(5))
        );
        let mut extra = blobs.clone();
        extra.push(Blob {
            u: 10.0,
            v: 10.0,
            area: 50.0,
        });
        assert_eq!(
            identify(&extra, &deck, &cam),
            Err(IdentifyError::TooManyBlobs(10))
        );
        // Without the bow, no blob is clearly larger.
        let mut no_bow = blobs.clone();
        no_bow.remove(1);
        assert_eq!(identify(&no_bow, &deck, &cam), Err(IdentifyError::AmbiguousBow));
        let mut bad = blobs.clone();
        bad[3].u = f64::NAN;
        assert_eq!(identify(&bad, &deck, &cam), Err(IdentifyError::InvalidBlob(3)));
        // Two ring blobs in one slot.
        let mut twins = blobs.clone();
        twins[4] = Blob {
            u: twins[3].u + 1.0,
            ..twins[3]
        };
        assert_eq!(identify(&twins, &deck, &cam), Err(IdentifyError::RingMismatch));
        let ids = identify(&blobs, &deck, &cam).unwrap();
        let px = marker_pixels(&blobs, &ids);
        assert_eq!(px[1], Some([blobs[1].u, blobs[1].v]));
    }
}
