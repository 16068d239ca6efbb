//! Every rerun entity path, label and colour deckwatch logs, in one place, and the conversion of
//! the pipeline's messages into log items. The stages call these; the sink and the blueprint
//! use the same paths.

use crate::{Item, ItemKind};
use deckwatch_common::messages::{AttitudeMessage, LandingDecision, MarkerMessage, Truth};
use deckwatch_common::scene::{SceneGeometry, Viewpoint};

/// The frame (downscaled).
pub const IMAGE: &str = "camera/image";
/// Detected markers, labelled.
pub const MARKERS: &str = "camera/image/markers";
/// The paper's fitted ring ellipse.
pub const ELLIPSE: &str = "camera/image/ellipse";
/// The deck's markers reprojected with the full pose.
pub const DECK_MODEL: &str = "camera/image/deck_model";
/// The deck's ring reprojected with the full pose.
pub const DECK_MODEL_RING: &str = "camera/image/deck_model/ring";
/// Root of the angle plots: `attitude/<axis>/<series>`.
pub const ATTITUDE: &str = "attitude";
/// The angle axes, in the order of `Rpy::to_degrees`.
pub const AXES: [&str; 3] = ["roll", "pitch", "yaw"];
/// The series of the true angles (the estimators' series are their names).
pub const TRUTH_SERIES: &str = "truth";
/// Root of the decision plots.
pub const DECISION: &str = "decision";
pub const DECISION_STATE: &str = "decision/state";
pub const CALM_WINDOW_START: &str = "decision/calm_window/start_s";
pub const CALM_WINDOW_LENGTH: &str = "decision/calm_window/length_s";
/// State changes as text.
pub const DECISION_LOG: &str = "decision/log";
/// The vehicle's attitude from the autopilot (deg; north-west-up) and the link's clock.
/// The deck's heave: its height in W as measured and true (m), and its predicted vertical
/// speed (m/s).
pub const HEAVE: &str = "heave";
pub const HEAVE_MEASURED: &str = "heave/deck_height_m";
pub const HEAVE_TRUTH: &str = "heave/truth_m";
pub const HEAVE_RATE: &str = "heave/rate_mps";
pub const VEHICLE_ROLL: &str = "vehicle/roll";
pub const VEHICLE_PITCH: &str = "vehicle/pitch";
pub const LINK_CLOCK_OFFSET: &str = "link/clock_offset_ms";
pub const LINK_UP: &str = "link/up";

/// Colours (RGBA): detections stand out from the model they are compared with.
pub const MARKER_COLOUR: [u8; 4] = [255, 200, 0, 255];
pub const ELLIPSE_COLOUR: [u8; 4] = [0, 200, 255, 255];
pub const DECK_MODEL_COLOUR: [u8; 4] = [80, 255, 80, 255];

/// `attitude/<axis>`: one angle's plot.
pub fn attitude_axis_path(axis: &str) -> String {
    format!("{ATTITUDE}/{axis}")
}

/// `attitude/<axis>/<series>`: one series of an angle's plot.
pub fn attitude_path(axis: &str, series: &str) -> String {
    format!("{ATTITUDE}/{axis}/{series}")
}

/// The label of marker `index` (0 = centre, 1 = bow, then the ring).
pub fn marker_label(index: usize) -> String {
    match index {
        0 => "centre".to_string(),
        1 => "bow".to_string(),
        k => format!("ring {k}"),
    }
}

fn item(seq: u64, captured_ns: u64, kind: ItemKind) -> Item {
    Item {
        seq,
        captured_ns,
        kind,
    }
}

/// The detected markers as labelled points.
pub fn marker_items(m: &MarkerMessage) -> Vec<Item> {
    let (mut points, mut labels) = (Vec::new(), Vec::new());
    for (i, mk) in m
        .markers
        .markers
        .iter()
        .enumerate()
        .filter(|(_, mk)| mk.valid.get())
    {
        points.push([mk.u as f32, mk.v as f32]);
        labels.push(marker_label(i));
    }
    let kind = ItemKind::Points {
        entity: MARKERS,
        points,
        labels,
        colour: MARKER_COLOUR,
    };
    vec![item(m.stamp.seq, m.stamp.times.captured_ns, kind)]
}

/// The true angles of a frame, when its source knows them.
pub fn truth_items(seq: u64, captured_ns: u64, truth: &Truth) -> Vec<Item> {
    if !truth.known.get() {
        return Vec::new();
    }
    let values = [truth.roll_deg, truth.pitch_deg, truth.yaw_deg];
    let mut scalars: Vec<(String, f64)> = AXES
        .iter()
        .zip(values)
        .map(|(axis, v)| (attitude_path(axis, TRUTH_SERIES), v))
        .collect();
    if truth.deck_heave_m.is_finite() {
        scalars.push((HEAVE_TRUTH.into(), truth.deck_heave_m));
    }
    vec![item(seq, captured_ns, ItemKind::Scalars(scalars))]
}

/// The angles of both estimators, the paper's ellipse and the deck reprojected with the full
/// pose.
pub fn attitude_items(a: &AttitudeMessage) -> Vec<Item> {
    let (seq, captured_ns) = (a.stamp.seq, a.stamp.times.captured_ns);
    let mut out = Vec::with_capacity(4);
    let mut scalars = Vec::new();
    if a.valid.get() {
        for (axis, v) in AXES.iter().zip(a.rpy.to_degrees()) {
            scalars.push((attitude_path(axis, a.estimator.get().name()), v));
        }
        if a.deck_height_m.is_finite() {
            scalars.push((HEAVE_MEASURED.into(), a.deck_height_m));
        }
    }
    let alt = &a.alternative;
    if alt.present.get() && alt.valid.get() {
        for (axis, v) in AXES.iter().zip(alt.rpy.to_degrees()) {
            scalars.push((attitude_path(axis, alt.estimator.get().name()), v));
        }
    }
    out.push(item(seq, captured_ns, ItemKind::Scalars(scalars)));
    let camera = &a.context.camera;
    if a.has_image_ellipse.get() {
        let strip = a
            .image_ellipse
            .boundary(64)
            .iter()
            .map(|&p| camera.distort_pixel(p))
            .map(|[u, v]| [u as f32, v as f32])
            .collect();
        let kind = ItemKind::Strips {
            entity: ELLIPSE,
            strips: vec![strip],
            colour: ELLIPSE_COLOUR,
        };
        out.push(item(seq, captured_ns, kind));
    }
    let [x, y, z] = a.camera_position_m;
    if a.valid.get() && z.is_finite() {
        let scene = SceneGeometry {
            attitude: a.rpy.to_matrix(),
            viewpoint: Viewpoint::level(x, y, z).with_vehicle_attitude(a.context.vehicle.matrix()),
        };
        let deck = &a.context.deck;
        let points: Vec<[f32; 2]> = scene
            .project_markers(camera, deck)
            .into_iter()
            .flatten()
            .map(|[u, v]| [u as f32, v as f32])
            .collect();
        let ring: Vec<[f32; 2]> = (0..=64)
            .filter_map(|k| {
                let t = std::f64::consts::TAU * k as f64 / 64.0;
                let r = deck.ring_radius_m;
                let p = nalgebra::Vector3::new(r * t.cos(), r * t.sin(), 0.0);
                scene
                    .project_deck_point(camera, &p)
                    .map(|[u, v]| [u as f32, v as f32])
            })
            .collect();
        let labels = vec![String::new(); points.len()];
        out.push(item(
            seq,
            captured_ns,
            ItemKind::Points {
                entity: DECK_MODEL,
                points,
                labels,
                colour: DECK_MODEL_COLOUR,
            },
        ));
        out.push(item(
            seq,
            captured_ns,
            ItemKind::Strips {
                entity: DECK_MODEL_RING,
                strips: vec![ring],
                colour: DECK_MODEL_COLOUR,
            },
        ));
    }
    out
}

/// A vehicle attitude sample from the autopilot as plotted values.
pub fn vehicle_items(v: &deckwatch_common::messages::VehicleSample) -> Vec<Item> {
    let [roll, pitch, _] = v.quaternion.to_rpy().to_degrees();
    vec![item(
        v.seq,
        v.time_ns,
        ItemKind::Scalars(vec![
            (VEHICLE_ROLL.into(), roll),
            (VEHICLE_PITCH.into(), pitch),
            (LINK_CLOCK_OFFSET.into(), v.clock_offset_ns as f64 / 1e6),
            (LINK_UP.into(), f64::from(u8::from(v.link_up.get()))),
        ]),
    )]
}

/// The decision as plotted values; with `state_changed`, also a line of text.
pub fn decision_items(d: &LandingDecision, state_changed: bool) -> Vec<Item> {
    let (seq, captured_ns) = (d.stamp.seq, d.stamp.times.captured_ns);
    let mut out = vec![item(
        seq,
        captured_ns,
        ItemKind::Scalars(vec![
            (DECISION_STATE.into(), d.state.get() as u32 as f64),
            (CALM_WINDOW_START.into(), d.calm_window_start_s),
            (CALM_WINDOW_LENGTH.into(), d.calm_window_length_s),
            (HEAVE_RATE.into(), d.heave_rate_mps),
        ]),
    )];
    if state_changed {
        let text = format!("{} ({})", d.state.get().name(), d.reason.get().name());
        out.push(item(seq, captured_ns, ItemKind::Text(text)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_and_labels() {
        assert_eq!(attitude_path(AXES[1], TRUTH_SERIES), "attitude/pitch/truth");
        assert_eq!(marker_label(1), "bow");
        assert_eq!(marker_label(5), "ring 5");
        assert!(MARKERS.starts_with(IMAGE) && DECISION_STATE.starts_with(DECISION));
        let mut truth = Truth::UNKNOWN;
        assert!(truth_items(0, 0, &truth).is_empty());
        truth.known = true.into();
        assert_eq!(truth_items(3, 7, &truth).len(), 1);
    }
}
