//! The check on exact synthetic photographs: marker centres projected through a lens with
//! distortion, disc areas integrated along the projected outline (not through the conic the
//! check uses), for prints true to size, stretched in one axis, and scaled alike in both.

use super::*;
use deckwatch_common::{Distortion, Marker, Rpy, Viewpoint};

fn camera() -> CameraModel {
    CameraModel {
        distortion: Distortion::from_array([-0.12, 0.03, 0.0005, -0.0003, 0.0]),
        ..CameraModel::centred(1640, 1232, 1290.0, 1296.0)
    }
}

/// An oblique view: the deck tilted by tens of degrees, the camera off its centre.
fn oblique() -> SceneGeometry {
    SceneGeometry {
        attitude: Rpy::from_degrees(18.0, -24.0, 35.0).to_matrix(),
        viewpoint: Viewpoint::level(0.4, -0.3, 2.6),
    }
}

/// The markers a perfect detector reports for a print of `layout` through `print` (configured
/// deck coordinates to the sheet's, metres) seen from `scene`.
fn photograph(layout: &DeckLayout, print: Matrix2<f64>, scene: &SceneGeometry) -> MarkerSet {
    let cam = camera();
    let mut set = MarkerSet {
        perspective_corrected: true.into(),
        ..MarkerSet::default()
    };
    let project = |p: Vector2<f64>| {
        scene
            .project_deck_point(&cam, &Vector3::new(p.x, p.y, 0.0))
            .unwrap()
    };
    for i in 0..layout.marker_count() {
        let p = layout.marker_position(i);
        let centre = print * Vector2::new(p.x, p.y);
        let [u, v] = project(centre);
        // The shoelace area of the printed disc's projected outline.
        let r = layout.disc_radius(i);
        let outline: Vec<[f64; 2]> = (0..4000)
            .map(|k| {
                let a = 2.0 * std::f64::consts::PI * k as f64 / 4000.0;
                project(centre + print * Vector2::new(r * a.cos(), r * a.sin()))
            })
            .collect();
        let area_px = 0.5
            * outline
                .iter()
                .zip(outline.iter().cycle().skip(1))
                .map(|(a, b)| a[0] * b[1] - a[1] * b[0])
                .sum::<f64>()
                .abs();
        set.markers[i] = Marker {
            valid: true.into(),
            u,
            v,
            area_px,
            ..Marker::default()
        };
    }
    set.count = layout.marker_count() as u32;
    set
}

fn errors(check: &PatternCheck) -> Vec<(Quantity, f64)> {
    check
        .dimensions
        .iter()
        .filter_map(|d| Some((d.quantity, d.error_pct()?)))
        .collect()
}

#[test]
fn a_print_true_to_size_measures_true_in_every_dimension() {
    let layout = DeckLayout::paper();
    let scene = oblique();
    let set = photograph(&layout, Matrix2::identity(), &scene);
    let distance = scene.deck_to_camera(&Vector3::zeros()).norm();
    for distance_m in [None, Some(distance)] {
        let check = check_pattern(&set, &camera(), &layout, &PatternCheckConfig { distance_m }).unwrap();
        for (quantity, e) in errors(&check) {
            assert!(e.abs() < 2e-3, "{quantity:?}: {e} %");
        }
        assert_eq!(check.found_mask, 0x1ff);
        assert!(check.plane_residual_px < 1e-6, "{}", check.plane_residual_px);
        assert!((check.distance_if_true_size_m - distance).abs() < 1e-6);
        assert!(
            check.view_tilt_deg > 20.0,
            "an oblique view: {}",
            check.view_tilt_deg
        );
        let ring = check.get(Quantity::RingRadius).unwrap();
        match distance_m {
            Some(_) => {
                assert_eq!(ring.basis, Basis::Absolute);
                assert!((check.scale.unwrap() - 1.0).abs() < 1e-8);
            }
            None => assert_eq!(
                (ring.basis, ring.measured, check.scale),
                (Basis::NeedsDistance, None, None)
            ),
        }
        assert_eq!(check.off(0.01).count(), 0);
    }
}

/// 3 % too large along the deck's x (a printer's feed direction): the aspect says so, with its
/// axis, and so do the markers' distances; a rigid pose would have tilted some of it away.
#[test]
fn a_print_stretched_in_one_axis_is_measured_exactly() {
    let layout = DeckLayout::paper();
    let stretch = Matrix2::new(1.03, 0.0, 0.0, 1.0);
    let check = check_pattern(
        &photograph(&layout, stretch, &oblique()),
        &camera(),
        &layout,
        &PatternCheckConfig::default(),
    )
    .unwrap();
    let aspect = check.get(Quantity::Aspect).unwrap();
    assert!((aspect.measured.unwrap() - 1.03).abs() < 1e-8, "{aspect:?}");
    assert!(check.aspect_axis_deg.abs() < 1e-5, "{}", check.aspect_axis_deg);
    // Along x (the bow, marker 1, and marker 5) the ring is 3 % wider than along y (3, 7).
    let distance = |i| check.get(Quantity::MarkerDistance(i)).unwrap().measured.unwrap();
    assert!((distance(1) / distance(3) - 1.03).abs() < 1e-8);
    assert!((distance(5) / distance(7) - 1.03).abs() < 1e-8);
    // A stretched disc has the area of a circle sqrt(1.03) times larger.
    let disc = |i| check.get(Quantity::DiscDiameter(i)).unwrap().measured.unwrap();
    assert!((disc(0) / distance(3) / (0.1 / 0.5) - 1.03f64.sqrt()).abs() < 1e-5);
    let off: Vec<Quantity> = check.off(0.5).map(|d| d.quantity).collect();
    assert!(
        off.contains(&Quantity::Aspect) && off.contains(&Quantity::MarkerDistance(1)),
        "{off:?}"
    );
}

/// Scaled alike in x and y (a "fit to page"): invisible without a distance, measured with one.
#[test]
fn a_uniformly_scaled_print_needs_the_distance() {
    let layout = DeckLayout::paper();
    let scene = oblique();
    let set = photograph(&layout, Matrix2::identity() * 0.97, &scene);
    let relative = check_pattern(&set, &camera(), &layout, &PatternCheckConfig::default()).unwrap();
    assert_eq!(
        relative.off(0.01).count(),
        0,
        "the print's own proportions are right"
    );
    // The pose puts the camera 3 % nearer than it is.
    let distance = scene.deck_to_camera(&Vector3::zeros()).norm();
    assert!((relative.distance_if_true_size_m / distance - 1.0 / 0.97).abs() < 1e-6);
    let config = PatternCheckConfig {
        distance_m: Some(distance),
    };
    let absolute = check_pattern(&set, &camera(), &layout, &config).unwrap();
    assert!((absolute.scale.unwrap() - 0.97).abs() < 1e-8);
    for (quantity, e) in errors(&absolute) {
        match quantity {
            Quantity::RingRadius | Quantity::MarkerDistance(_) | Quantity::DiscDiameter(_) => {
                assert!((e + 3.0).abs() < 2e-3, "{quantity:?}: {e}")
            }
            _ => assert!(e.abs() < 2e-3, "{quantity:?}: {e}"),
        }
    }
}

/// A misplaced disc (moved 1 % of the ring's radius along the ring) and a small one.
#[test]
fn a_misplaced_or_small_disc_is_named() {
    let layout = DeckLayout::paper();
    let scene = oblique();
    let mut set = photograph(&layout, Matrix2::identity(), &scene);
    // Marker 4's disc 2 % too small: 4 % less area.
    set.markers[4].area_px *= 0.98f64.powi(2);
    // Marker 6 moved along the ring by 0.005 m: project it again.
    let p = layout.marker_position(6);
    let tangent = Vector3::new(-p.y, p.x, 0.0).normalize();
    let [u, v] = scene
        .project_deck_point(&camera(), &(p + 0.005 * tangent))
        .unwrap();
    (set.markers[6].u, set.markers[6].v) = (u, v);
    let check = check_pattern(&set, &camera(), &layout, &PatternCheckConfig::default()).unwrap();
    let off: Vec<Quantity> = check.off(0.5).map(|d| d.quantity).collect();
    assert!(off.contains(&Quantity::DiscDiameter(4)), "{off:?}");
    assert!(
        off.contains(&Quantity::Spacing(5)) && off.contains(&Quantity::Spacing(6)),
        "{off:?}"
    );
    assert!(check.plane_residual_px > 0.1);
}

#[test]
fn too_few_markers_and_bad_input_are_errors() {
    let layout = DeckLayout::paper();
    let full = photograph(&layout, Matrix2::identity(), &oblique());
    let without = |indices: &[usize]| {
        let mut set = full;
        for &i in indices {
            set.markers[i].valid = false.into();
        }
        check_pattern(&set, &camera(), &layout, &PatternCheckConfig::default())
    };
    assert!(matches!(
        without(&[BOW]),
        Err(PatternCheckError::TooFewMarkers { bow: false, .. })
    ));
    assert!(matches!(
        without(&[2, 3, 4, 5]),
        Err(PatternCheckError::TooFewMarkers { found: 5, .. })
    ));
    // Three ring markers missing still measures the rest.
    let partial = without(&[2, 4, 7]).unwrap();
    assert!(partial.get(Quantity::DiscDiameter(2)).is_none());
    assert!(errors(&partial).iter().all(|(_, e)| e.abs() < 2e-3));
    for bad in [0.0, -1.0, f64::NAN] {
        let config = PatternCheckConfig {
            distance_m: Some(bad),
        };
        assert!(matches!(
            check_pattern(&full, &camera(), &layout, &config),
            Err(PatternCheckError::BadDistance(_))
        ));
    }
}
