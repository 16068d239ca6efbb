//! Measuring a printed or painted deck pattern in one photograph: the ring's radius, each disc's
//! diameter, the ring markers' spacing and the print's aspect (a printer that scales x and y
//! differently), against the configured layout.
//!
//! What one photograph of a flat pattern can tell, with the camera's calibration:
//! - its *shape up to a scale*, exactly: the plane-to-image map of the markers (a homography,
//!   `H ~ [r1 r2 t] A` in normalised coordinates for a print that is the layout through a linear
//!   map `A`) gives `A^T A` up to a factor from its first two columns, since `r1`, `r2` are
//!   orthonormal. So the aspect and its axis, every ratio of distances (a disc's diameter to
//!   the ring's radius, the bow disc's to an ordinary one's), the angles between ring markers,
//!   whatever the view's tilt. A rigid pose of the configured layout could not express a
//!   stretched print: the pose's tilt would absorb part of the stretch.
//! - *not* its absolute size: a print twice as large twice as far looks the same. The scale
//!   needs a length known in the scene: the camera's distance to the centre marker measured
//!   with a tape (`distance_m`), or a ruler on the sheet's check bar. A print scaled by the
//!   printer scales its check bar too, so the bar cannot be measured in the photograph.
//!
//! The rigid pose ([`PoseEstimator`], the configured layout) says where the camera is: the
//! view's tilt and its distance if the print were true to size.

use crate::pose::{PoseConfig, PoseError, PoseEstimate, PoseEstimator};
use deckwatch_common::deck::{BOW, CENTRE};
use deckwatch_common::markers::MarkerSet;
use deckwatch_common::{homography, CameraModel, DeckLayout, InvalidField, SceneGeometry};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Least markers a check uses: the centre, the bow and four more of the ring (as the detector's
/// partial set), so that the plane map (8 unknowns) has 12 equations.
pub const MIN_MARKERS: usize = 6;

/// Points on a disc's imaged outline whose polygon gives its area through the lens.
const OUTLINE_POINTS: usize = 256;

/// How a photograph is measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PatternCheckConfig {
    /// The distance from the camera's optical centre to the centre marker's centre, measured
    /// (m): what gives sizes in metres. None: sizes relative to the ring's radius.
    pub distance_m: Option<f64>,
}

/// What a row of the check measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// The ring's radius: the ring markers' mean distance from the centre marker (m).
    RingRadius,
    /// One ring marker's distance from the centre marker (m), by marker index.
    MarkerDistance(usize),
    /// The angle from ring marker `index` to the next one counter-clockwise (deg).
    Spacing(usize),
    /// A disc's diameter (m), by marker index: the diameter of the circle of the disc's area.
    DiscDiameter(usize),
    /// The bow disc's diameter over the ordinary discs' mean.
    BowDiscRatio,
    /// The print's larger scale over its smaller: 1 when x and y are printed alike.
    Aspect,
}

/// What a measured value rests on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Basis {
    /// Metres from the measured distance (`PatternCheckConfig::distance_m`).
    Absolute,
    /// Metres scaled so that the measured ring radius is the configured one: the print's own
    /// proportions, blind to a print scaled alike in x and y.
    RelativeToRing,
    /// A ratio or an angle: no scale needed.
    ScaleFree,
    /// Not measurable without a distance (the ring radius).
    NeedsDistance,
}

/// One measured dimension against the configured layout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dimension {
    pub quantity: Quantity,
    pub basis: Basis,
    /// The configured value (unit as the quantity says).
    pub nominal: f64,
    /// The measured value; None when not measurable (see `basis`) or not measured (a disc
    /// without an area).
    pub measured: Option<f64>,
}

impl Dimension {
    /// The measured value's error relative to the configured one, in percent.
    pub fn error_pct(&self) -> Option<f64> {
        self.measured.map(|m| 100.0 * (m / self.nominal - 1.0))
    }
}

/// The measured pattern.
#[derive(Debug, Clone, PartialEq)]
pub struct PatternCheck {
    /// Ring radius, the markers' distances, the spacings, the discs, the bow's ratio, the
    /// aspect, in that order.
    pub dimensions: Vec<Dimension>,
    /// Markers found (bit i = marker i).
    pub found_mask: u32,
    /// The rigid pose of the configured layout: where the camera would be if the print were
    /// true to size.
    pub pose: PoseEstimate,
    /// The angle between the camera's optical axis and the pattern's normal (deg).
    pub view_tilt_deg: f64,
    /// The camera's distance from the centre marker if the print were true to size (m).
    pub distance_if_true_size_m: f64,
    /// The print's size over the configured one (the ring's), from the measured distance.
    pub scale: Option<f64>,
    /// The direction of the print's larger scale, from the deck's +x toward +y (deg, in
    /// (-90, 90]).
    pub aspect_axis_deg: f64,
    /// The markers' RMS distance from the fitted plane map (px): what no flat print of any
    /// proportions explains (a warped sheet, a misplaced disc, a poor calibration).
    pub plane_residual_px: f64,
}

impl PatternCheck {
    /// The measured dimensions off by more than `tolerance_pct`.
    pub fn off(&self, tolerance_pct: f64) -> impl Iterator<Item = &Dimension> {
        self.dimensions
            .iter()
            .filter(move |d| d.error_pct().is_some_and(|e| !(e.abs() <= tolerance_pct)))
    }

    /// The row of `quantity`, if the check has one (a disc not found has none).
    pub fn get(&self, quantity: Quantity) -> Option<&Dimension> {
        self.dimensions.iter().find(|d| d.quantity == quantity)
    }
}

/// Why a photograph could not be measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PatternCheckError {
    #[error("deck layout: {0}")]
    Layout(InvalidField),
    #[error("distance_m: must be a positive number of metres, got {0}")]
    BadDistance(f64),
    #[error(
        "{found} markers found (centre {}, bow {}): the check needs the centre, the bow and at \
         least {MIN_MARKERS} markers in all",
        if *centre { "found" } else { "missing" },
        if *bow { "found" } else { "missing" }
    )]
    TooFewMarkers { found: usize, centre: bool, bow: bool },
    #[error("marker {index}'s pixel lies where the lens model does not invert")]
    Undistortion { index: usize },
    #[error("pose: {0}")]
    Pose(PoseError),
    #[error("the markers determine no plane map (collinear, or a degenerate view)")]
    Degenerate,
}

/// Measures the pattern whose markers a photograph shows (`markers`: the detector's, centres
/// free of the perspective bias as it gives them) with the camera's calibration, against
/// `layout`.
pub fn check_pattern(
    markers: &MarkerSet,
    camera: &CameraModel,
    layout: &DeckLayout,
    config: &PatternCheckConfig,
) -> Result<PatternCheck, PatternCheckError> {
    layout.validate().map_err(PatternCheckError::Layout)?;
    if let Some(d) = config.distance_m {
        if !(d.is_finite() && d > 0.0) {
            return Err(PatternCheckError::BadDistance(d));
        }
    }
    let n = layout.marker_count();
    let pixels = markers.pixels(n);
    let found: Vec<usize> = (0..n).filter(|&i| pixels[i].is_some()).collect();
    let (centre, bow) = (pixels[CENTRE].is_some(), pixels[BOW].is_some());
    if !centre || !bow || found.len() < MIN_MARKERS {
        return Err(PatternCheckError::TooFewMarkers {
            found: found.len(),
            centre,
            bow,
        });
    }
    // Every marker stays: a misprinted one is what is measured, not an outlier.
    let pose_config = PoseConfig {
        max_reprojection_px: 1e9,
        ..PoseConfig::default()
    };
    let pose = PoseEstimator::new(*camera, *layout, pose_config)
        .estimate(&pixels, markers.perspective_corrected.get())
        .map_err(PatternCheckError::Pose)?;
    let scene = SceneGeometry {
        attitude: pose.attitude.matrix,
        viewpoint: pose.viewpoint,
    };
    let origin = scene.deck_to_camera(&Vector3::zeros());
    let normal = scene.deck_to_camera(&Vector3::z()) - origin;
    let view_tilt_deg = (normal.z.abs() / normal.norm())
        .clamp(0.0, 1.0)
        .acos()
        .to_degrees();

    let plane = PlaneMap::fit(&pixels, &found, camera, layout)?;
    let (eigen_small, eigen_large, axis) = plane.principal_scales();
    let aspect = (eigen_large / eigen_small).sqrt();
    // The print's vectors from its centre, in the plane map's units (one factor from metres).
    let centre_at = plane.located[CENTRE].ok_or(PatternCheckError::Degenerate)?;
    let print_vector = |i: usize| plane.located[i].map(|p| plane.sqrt_g * (p - centre_at));
    let ring: Vec<(usize, Vector2<f64>)> = (1..n).filter_map(|i| Some((i, print_vector(i)?))).collect();
    let ring_units = ring.iter().map(|(_, d)| d.norm()).sum::<f64>() / ring.len() as f64;
    let nominal_ring = layout.ring_radius_m;
    // Map units per metre: from the distance (|H (p, 1)| = lambda |t|), else from the ring.
    let (units_per_m, basis) = match config.distance_m {
        Some(d) => {
            let h_centre = plane.h * Vector3::new(centre_at.x, centre_at.y, 1.0);
            (h_centre.norm() / d, Basis::Absolute)
        }
        None => (ring_units / nominal_ring, Basis::RelativeToRing),
    };
    let mut dimensions = vec![Dimension {
        quantity: Quantity::RingRadius,
        basis: if basis == Basis::Absolute {
            Basis::Absolute
        } else {
            Basis::NeedsDistance
        },
        nominal: nominal_ring,
        measured: (basis == Basis::Absolute).then_some(ring_units / units_per_m),
    }];
    for (i, d) in &ring {
        dimensions.push(Dimension {
            quantity: Quantity::MarkerDistance(*i),
            basis,
            nominal: nominal_ring,
            measured: Some(d.norm() / units_per_m),
        });
    }
    let step_deg = 360.0 / layout.n_ring as f64;
    for i in 1..n {
        let next = layout.ring_index(i);
        if let (Some(a), Some(b)) = (print_vector(i), print_vector(next)) {
            dimensions.push(Dimension {
                quantity: Quantity::Spacing(i),
                basis: Basis::ScaleFree,
                nominal: step_deg,
                measured: Some((a.x * b.y - a.y * b.x).atan2(a.dot(&b)).to_degrees()),
            });
        }
    }
    let g_per_m2 = plane.g / (units_per_m * units_per_m);
    let mut diameters = vec![None; n];
    for &i in &found {
        let area_px = markers.markers[i].area_px;
        let diameter = plane.disc_diameter(camera, &g_per_m2, i, area_px, layout.disc_radius(i));
        diameters[i] = diameter;
        dimensions.push(Dimension {
            quantity: Quantity::DiscDiameter(i),
            basis,
            nominal: 2.0 * layout.disc_radius(i),
            measured: diameter,
        });
    }
    let ordinary: Vec<f64> = (0..n)
        .filter(|&i| i != BOW)
        .filter_map(|i| diameters[i])
        .collect();
    let ratio = match (diameters[BOW], ordinary.is_empty()) {
        (Some(bow_d), false) => Some(bow_d * ordinary.len() as f64 / ordinary.iter().sum::<f64>()),
        _ => None,
    };
    dimensions.push(Dimension {
        quantity: Quantity::BowDiscRatio,
        basis: Basis::ScaleFree,
        nominal: layout.bow_marker_radius_m / layout.marker_radius_m,
        measured: ratio,
    });
    dimensions.push(Dimension {
        quantity: Quantity::Aspect,
        basis: Basis::ScaleFree,
        nominal: 1.0,
        measured: Some(aspect),
    });
    Ok(PatternCheck {
        dimensions,
        found_mask: found.iter().fold(0, |m, &i| m | 1 << i),
        pose,
        view_tilt_deg,
        distance_if_true_size_m: origin.norm(),
        scale: (basis == Basis::Absolute).then(|| ring_units / units_per_m / nominal_ring),
        aspect_axis_deg: axis,
        plane_residual_px: plane.residual_px,
    })
}

/// The plane-to-image map of the found markers and what it says of the print.
struct PlaneMap {
    /// Configured deck coordinates (m) to normalised image coordinates.
    h: Matrix3<f64>,
    /// `M^T M` of its first two columns `M`: the print's metric in configured coordinates, up
    /// to a factor (`A^T A` for a print `A p`).
    g: Matrix2<f64>,
    /// Its symmetric square root: configured coordinates to the print's own (up to a turn).
    sqrt_g: Matrix2<f64>,
    /// Where each found marker's centre lies in configured coordinates (the map's inverse
    /// of its pixel), by marker index.
    located: Vec<Option<Vector2<f64>>>,
    residual_px: f64,
}

impl PlaneMap {
    fn fit(
        pixels: &[Option<[f64; 2]>],
        found: &[usize],
        camera: &CameraModel,
        layout: &DeckLayout,
    ) -> Result<Self, PatternCheckError> {
        let mut deck = Vec::with_capacity(found.len());
        let mut image = Vec::with_capacity(found.len());
        for &index in found {
            let uv = pixels[index].ok_or(PatternCheckError::Degenerate)?;
            let xy = camera
                .unproject(uv)
                .ok_or(PatternCheckError::Undistortion { index })?;
            let p = layout.marker_position(index);
            deck.push([p.x, p.y]);
            image.push(xy);
        }
        let h = homography::fit(&deck, &image).ok_or(PatternCheckError::Degenerate)?;
        let h_inv = h.try_inverse().ok_or(PatternCheckError::Degenerate)?;
        let mut located = vec![None; pixels.len()];
        let mut squares = 0.0;
        for (k, &index) in found.iter().enumerate() {
            let p = homography::apply(&h_inv, image[k]).ok_or(PatternCheckError::Degenerate)?;
            located[index] = Some(Vector2::new(p[0], p[1]));
            let xy = homography::apply(&h, deck[k]).ok_or(PatternCheckError::Degenerate)?;
            let uv = camera
                .project(&Vector3::new(xy[0], xy[1], 1.0))
                .ok_or(PatternCheckError::Degenerate)?;
            let measured = pixels[index].ok_or(PatternCheckError::Degenerate)?;
            squares += (uv[0] - measured[0]).powi(2) + (uv[1] - measured[1]).powi(2);
        }
        let columns = h.fixed_view::<3, 2>(0, 0);
        let g = columns.transpose() * columns;
        let eigen = g.symmetric_eigen();
        if !(eigen.eigenvalues.min() > 0.0) {
            return Err(PatternCheckError::Degenerate);
        }
        let roots = Matrix2::from_diagonal(&eigen.eigenvalues.map(f64::sqrt));
        let sqrt_g = eigen.eigenvectors * roots * eigen.eigenvectors.transpose();
        Ok(Self {
            h,
            g,
            sqrt_g,
            located,
            residual_px: (squares / found.len() as f64).sqrt(),
        })
    }

    /// The metric's eigenvalues (smaller, larger) and the larger one's direction from +x
    /// toward +y (deg, in (-90, 90]).
    fn principal_scales(&self) -> (f64, f64, f64) {
        let eigen = self.g.symmetric_eigen();
        let (small, large) = match eigen.eigenvalues[0] <= eigen.eigenvalues[1] {
            true => (0, 1),
            false => (1, 0),
        };
        let v = eigen.eigenvectors.column(large);
        let mut axis = v[1].atan2(v[0]).to_degrees();
        if axis <= -90.0 {
            axis += 180.0;
        } else if axis > 90.0 {
            axis -= 180.0;
        }
        (eigen.eigenvalues[small], eigen.eigenvalues[large], axis)
    }

    /// The diameter (m) of the printed circle around marker `index` whose image has the disc's
    /// measured area (`area_px`), in the print's metric `g_per_m2` (configured coordinates to
    /// metres squared). None when the area is missing or the disc's image is no ellipse.
    fn disc_diameter(
        &self,
        camera: &CameraModel,
        g_per_m2: &Matrix2<f64>,
        index: usize,
        area_px: f64,
        nominal_radius_m: f64,
    ) -> Option<f64> {
        let centre = self.located.get(index).copied().flatten()?;
        if !(area_px.is_finite() && area_px > 0.0) {
            return None;
        }
        // The image's area grows as the radius squared but for perspective (the square of the
        // disc's size over its distance): a few fixed-point steps converge.
        let mut radius = nominal_radius_m;
        for _ in 0..8 {
            let predicted = self.imaged_disc_area_px(camera, g_per_m2, centre, radius)?;
            radius *= (area_px / predicted).sqrt();
        }
        (radius.is_finite() && radius > 0.0).then_some(2.0 * radius)
    }

    /// The pixel area of the image of the printed circle of `radius_m` around `centre`
    /// (configured coordinates): the exact ellipse in normalised coordinates (the image of a
    /// conic) carried through the lens and the intrinsics.
    fn imaged_disc_area_px(
        &self,
        camera: &CameraModel,
        g_per_m2: &Matrix2<f64>,
        centre: Vector2<f64>,
        radius_m: f64,
    ) -> Option<f64> {
        let gc = g_per_m2 * centre;
        #[rustfmt::skip]
        let disc = Matrix3::new(
            g_per_m2[(0, 0)], g_per_m2[(0, 1)], -gc.x,
            g_per_m2[(1, 0)], g_per_m2[(1, 1)], -gc.y,
            -gc.x, -gc.y, centre.dot(&gc) - radius_m * radius_m,
        );
        let h_inv = self.h.try_inverse()?;
        let mut conic = h_inv.transpose() * disc * h_inv;
        if conic[(0, 0)] + conic[(1, 1)] < 0.0 {
            conic = -conic;
        }
        let quadratic = conic.fixed_view::<2, 2>(0, 0).into_owned();
        let linear = Vector2::new(conic[(0, 2)], conic[(1, 2)]);
        let det = quadratic.determinant();
        if !(det > 0.0) {
            return None; // the disc reaches the horizon: no ellipse
        }
        let ellipse_centre = -(quadratic.try_inverse()? * linear);
        let level = conic[(2, 2)] + linear.dot(&ellipse_centre);
        if !(level < 0.0) {
            return None;
        }
        // The ellipse's outline through the lens (which no affine map describes over a large
        // disc): a polygon of its points, its area scaled by what an inscribed polygon of an
        // ellipse misses.
        let axes = quadratic.symmetric_eigen();
        let half_axes = axes.eigenvalues.map(|e| (-level / e).sqrt());
        let mut outline = [[0.0; 2]; OUTLINE_POINTS];
        for (k, point) in outline.iter_mut().enumerate() {
            let angle = std::f64::consts::TAU * k as f64 / OUTLINE_POINTS as f64;
            let local = Vector2::new(half_axes[0] * angle.cos(), half_axes[1] * angle.sin());
            let xy = ellipse_centre + axes.eigenvectors * local;
            *point = camera.project(&Vector3::new(xy.x, xy.y, 1.0))?;
        }
        let twice_area: f64 = (0..OUTLINE_POINTS)
            .map(|k| {
                let (a, b) = (outline[k], outline[(k + 1) % OUTLINE_POINTS]);
                a[0] * b[1] - a[1] * b[0]
            })
            .sum();
        let n = OUTLINE_POINTS as f64;
        let inscribed = n * (std::f64::consts::TAU / n).sin() / std::f64::consts::TAU;
        Some(0.5 * twice_area.abs() / inscribed)
    }
}

#[cfg(test)]
mod tests;
