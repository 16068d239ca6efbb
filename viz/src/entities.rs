//! Every rerun entity path, label and colour deckwatch logs, in one place, and the conversion of
//! the pipeline's messages into log items. The stages call these; the sink and the blueprint
//! use the same paths.

use crate::{Item, ItemKind};
use deckwatch_common::markers::MarkerSet;
use deckwatch_common::messages::{
    AttitudeMessage, DecisionReason, DecisionState, EstimatorKind, LandingDecision, LatencyInterval,
    MarkerMessage, PipelineStage, Truth,
};
use deckwatch_common::scene::{SceneGeometry, Viewpoint};

/// The frame (downscaled).
pub const IMAGE: &str = "camera/image";
/// Detected markers (the detector's output).
pub const MARKERS: &str = "camera/image/markers";
/// The paper's fitted ring ellipse.
pub const ELLIPSE: &str = "camera/image/ellipse";
/// The deck's markers reprojected with the full pose (the model the detections are compared
/// with).
pub const DECK_MODEL: &str = "camera/image/deck_model";
/// The deck's ring reprojected with the full pose.
pub const DECK_MODEL_RING: &str = "camera/image/deck_model/ring";
/// The deck region of the frame at full resolution; every overlay of [`IMAGE`] is also drawn
/// here, under the same name ([`crop_entity`]).
pub const DECK_CROP: &str = "camera/deck";
/// Root of the angle plots: `attitude/<axis>/<series>`.
pub const ATTITUDE: &str = "attitude";
/// The angle axes, in the order of `Rpy::to_degrees`.
pub const AXES: [&str; 3] = ["roll", "pitch", "yaw"];
/// The series of the true angles (the estimators' series are their names).
pub const TRUTH_SERIES: &str = "truth";
/// The capacity's limits on the roll and pitch plots: `attitude/<axis>/capacity_{max,min}`.
pub const CAPACITY_SERIES: [&str; 2] = ["capacity_max", "capacity_min"];
/// Root of the error plots: `error/<axis>/<estimator>` (estimate - truth, deg).
pub const ERROR: &str = "error";
/// The decision: its state, its reason and the predicted calm window, as lanes of a state
/// timeline, the current one as a text, the changes as a log.
pub const DECISION: &str = "decision";
pub const DECISION_STATE: &str = "decision/state";
pub const DECISION_REASON: &str = "decision/reason";
/// The predicted calm window, drawn at the times it is predicted for (ahead of the decision).
pub const CALM_WINDOW: &str = "decision/calm_window";
/// The newest decision in words (a text document: readable at any time of the timeline).
pub const DECISION_NOW: &str = "decision_now";
/// State changes as text.
pub const DECISION_LOG: &str = "decision_log";
/// The deck's heave: its height in W as measured and true (m), and its predicted vertical
/// speed (m/s).
pub const HEAVE: &str = "heave";
pub const HEAVE_MEASURED: &str = "heave/deck_height_m";
pub const HEAVE_TRUTH: &str = "heave/truth_m";
pub const HEAVE_RATE: &str = "heave/rate_mps";
/// A closed-loop trial's vehicle: its camera's height over the deck centre (m).
pub const VEHICLE_OVER_DECK: &str = "heave/vehicle_over_deck_m";
/// Per-stage latency of each decided frame (ms): `latency/<interval>`.
pub const LATENCY: &str = "latency";
/// Frames lost so far, by where (cumulative): `drops/<where>`.
pub const DROPS: &str = "drops";
/// The vehicle's attitude from the autopilot (deg; north-west-up) and the link's clock.
/// How many markers were found, and how many the found ones put outside the image (the pattern
/// leaving the view, low over the deck).
pub const MARKERS_FOUND: &str = "detection/markers_found";
pub const MARKERS_OUT_OF_VIEW: &str = "detection/markers_out_of_view";
pub const VEHICLE_ROLL: &str = "vehicle/roll";
pub const VEHICLE_PITCH: &str = "vehicle/pitch";
pub const LINK_CLOCK_OFFSET: &str = "link/clock_offset_ms";
pub const LINK_UP: &str = "link/up";
/// Frames the link refused, by cause: `link/refused/<cause>` (running totals).
pub const LINK_REFUSED: &str = "link/refused";

/// Colours (RGBA). Detections are large yellow discs, the model small green dots drawn over
/// them with its ring: where they agree, a green dot sits in a yellow disc.
pub const MARKER_COLOUR: [u8; 4] = [255, 200, 0, 255];
pub const ELLIPSE_COLOUR: [u8; 4] = [0, 200, 255, 255];
pub const DECK_MODEL_COLOUR: [u8; 4] = [60, 255, 60, 255];
/// Sizes on screen (UI points, whatever the zoom).
pub const MARKER_RADIUS_UI: f32 = 6.0;
pub const DECK_MODEL_RADIUS_UI: f32 = 2.5;
/// The decision states' and reasons' colours in the state timeline.
pub const STATE_COLOURS: [(DecisionState, [u8; 4]); 4] = [
    (DecisionState::NoDeck, [140, 140, 140, 255]),
    (DecisionState::Hold, [240, 170, 0, 255]),
    (DecisionState::ClearToLand, [40, 200, 70, 255]),
    (DecisionState::Abort, [230, 40, 40, 255]),
];
pub const CALM_WINDOW_LABEL: &str = "predicted calm";
/// Series colours: the truth grey, the estimators their own, the capacity red.
pub const TRUTH_COLOUR: [u8; 4] = [200, 200, 200, 255];
pub const CAPACITY_COLOUR: [u8; 4] = [230, 40, 40, 255];
pub fn estimator_colour(kind: EstimatorKind) -> [u8; 4] {
    match kind {
        EstimatorKind::FullPose => [255, 120, 0, 255],
        EstimatorKind::PaperAtan2 => [0, 170, 255, 255],
        EstimatorKind::PaperPrinted => [170, 90, 255, 255],
        EstimatorKind::PaperFittedMajorAxis => [0, 220, 200, 255],
    }
}

/// `attitude/<axis>`: one angle's plot.
pub fn attitude_axis_path(axis: &str) -> String {
    format!("{ATTITUDE}/{axis}")
}

/// `attitude/<axis>/<series>`: one series of an angle's plot.
pub fn attitude_path(axis: &str, series: &str) -> String {
    format!("{ATTITUDE}/{axis}/{series}")
}

/// `error/<axis>`: one angle's error plot.
pub fn error_axis_path(axis: &str) -> String {
    format!("{ERROR}/{axis}")
}

/// `latency/<interval>` (the interval's name as a path part: `capture->detect` is
/// `capture_to_detect`).
pub fn latency_path(interval: LatencyInterval) -> String {
    format!(
        "{LATENCY}/{}",
        interval.name().replace("->", "_to_").replace('-', "_")
    )
}

/// The same overlay in the deck crop: `camera/image/x` -> `camera/deck/x`.
pub fn crop_entity(entity: &str) -> Option<String> {
    entity
        .strip_prefix(IMAGE)
        .filter(|rest| rest.starts_with('/'))
        .map(|rest| format!("{DECK_CROP}{rest}"))
}

/// The label of marker `index` (0 = centre, 1 = bow, then the ring).
pub fn marker_label(index: usize) -> String {
    match index {
        0 => "centre".to_string(),
        1 => "bow".to_string(),
        k => format!("ring {k}"),
    }
}

/// The region of a frame around the detected deck, cut out at full resolution (every `step`-th
/// pixel when it is larger than [`DeckCrop::MAX_SIDE_PX`]): the markers are legible in it.
/// A pure function of the frame's markers, so each process that draws on it (detect, estimate)
/// places its overlays in the same crop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeckCrop {
    /// Top-left corner in the frame (full-resolution pixels).
    pub x0: u32,
    pub y0: u32,
    /// Size in the frame (full-resolution pixels).
    pub width: u32,
    pub height: u32,
    /// Pixels of the frame per pixel of the crop.
    pub step: u32,
}

impl DeckCrop {
    /// The crop image is at most this many pixels on a side.
    pub const MAX_SIDE_PX: u32 = 512;

    /// The deck's region: the detected markers' bounding box with a margin of half its size
    /// (at least 32 px), within the frame. None without two valid markers.
    pub fn of(markers: &MarkerSet, frame_width: u32, frame_height: u32) -> Option<Self> {
        let points: Vec<(f64, f64)> = markers
            .markers
            .iter()
            .filter(|m| m.valid.get() && m.u.is_finite() && m.v.is_finite())
            .map(|m| (m.u, m.v))
            .collect();
        if points.len() < 2 || frame_width == 0 || frame_height == 0 {
            return None;
        }
        let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for (u, v) in points {
            (u0, v0, u1, v1) = (u0.min(u), v0.min(v), u1.max(u), v1.max(v));
        }
        let side = (u1 - u0).max(v1 - v0);
        let margin = (0.5 * side).max(32.0);
        let clamp = |x: f64, max: u32| x.clamp(0.0, max as f64) as u32;
        let (x0, y0) = (clamp(u0 - margin, frame_width), clamp(v0 - margin, frame_height));
        let (x1, y1) = (
            clamp(u1 + margin + 1.0, frame_width),
            clamp(v1 + margin + 1.0, frame_height),
        );
        let (width, height) = (x1.checked_sub(x0)?, y1.checked_sub(y0)?);
        if width < 2 || height < 2 {
            return None;
        }
        let step = width.max(height).div_ceil(Self::MAX_SIDE_PX).max(1);
        Some(Self {
            x0,
            y0,
            width,
            height,
            step,
        })
    }

    /// The crop's pixels (8-bit gray) from the frame's: (pixels, width, height).
    pub fn cut(&self, pixels: &[u8], stride: usize) -> Option<(Vec<u8>, u32, u32)> {
        let step = self.step as usize;
        let (w, h) = (self.width.div_ceil(self.step), self.height.div_ceil(self.step));
        let mut out = Vec::with_capacity(w as usize * h as usize);
        for y in (self.y0 as usize..(self.y0 + self.height) as usize).step_by(step) {
            let start = y.checked_mul(stride)? + self.x0 as usize;
            let row = pixels.get(start..start + self.width as usize)?;
            out.extend(row.iter().step_by(step));
        }
        Some((out, w, h))
    }

    /// A full-resolution pixel in the crop's pixels (pixel centres at integers).
    pub fn map(&self, [u, v]: [f32; 2]) -> [f32; 2] {
        let s = self.step as f32;
        [
            (u - self.x0 as f32 + 0.5) / s - 0.5,
            (v - self.y0 as f32 + 0.5) / s - 0.5,
        ]
    }
}

fn item(seq: u64, time_ns: u64, kind: ItemKind) -> Item {
    Item {
        frame: Some(seq),
        time_ns,
        kind,
    }
}

/// The detected markers as labelled points (labels shown in the deck crop, where there is
/// room for them); `crop`: this frame's deck crop, when its image is logged.
pub fn marker_items(m: &MarkerMessage, crop: Option<DeckCrop>) -> Vec<Item> {
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
        radius_ui: MARKER_RADIUS_UI,
        crop,
    };
    let counts = ItemKind::Scalars(vec![
        (MARKERS_FOUND.into(), f64::from(m.markers.count)),
        (
            MARKERS_OUT_OF_VIEW.into(),
            f64::from(m.markers.out_of_view.count_ones()),
        ),
    ]);
    vec![
        item(m.stamp.seq, m.stamp.times.captured_ns, kind),
        item(m.stamp.seq, m.stamp.times.captured_ns, counts),
    ]
}

/// The crop of the deck region of a frame as an image item.
pub fn crop_image_item(seq: u64, time_ns: u64, crop: DeckCrop, pixels: &[u8], stride: usize) -> Option<Item> {
    let (pixels, width, height) = crop.cut(pixels, stride)?;
    Some(item(
        seq,
        time_ns,
        ItemKind::Image {
            entity: DECK_CROP,
            pixels,
            width,
            height,
        },
    ))
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

/// An angle difference in (-180, 180] deg (the yaw wraps).
fn wrapped_deg(d: f64) -> f64 {
    let w = d.rem_euclid(360.0);
    if w > 180.0 {
        w - 360.0
    } else {
        w
    }
}

/// The angles of both estimators and their errors against the truth (when the frame has one),
/// the paper's ellipse and the deck reprojected with the full pose; `crop`: this frame's deck
/// crop, when its image is logged.
pub fn attitude_items(a: &AttitudeMessage, crop: Option<DeckCrop>) -> Vec<Item> {
    let (seq, captured_ns) = (a.stamp.seq, a.stamp.times.captured_ns);
    let mut out = Vec::with_capacity(4);
    let mut scalars = Vec::new();
    let truth = &a.context.truth;
    let truth_deg = truth
        .known
        .get()
        .then_some([truth.roll_deg, truth.pitch_deg, truth.yaw_deg]);
    let mut angles = |estimator: &str, rpy_deg: [f64; 3]| {
        for (k, (axis, v)) in AXES.iter().zip(rpy_deg).enumerate() {
            scalars.push((attitude_path(axis, estimator), v));
            if let Some(t) = truth_deg {
                let e = wrapped_deg(v - t[k]);
                scalars.push((format!("{ERROR}/{axis}/{estimator}"), e));
            }
        }
    };
    if a.valid.get() {
        angles(a.estimator.get().name(), a.rpy.to_degrees());
    }
    let alt = &a.alternative;
    if alt.present.get() && alt.valid.get() {
        angles(alt.estimator.get().name(), alt.rpy.to_degrees());
    }
    if a.valid.get() && a.deck_height_m.is_finite() {
        scalars.push((HEAVE_MEASURED.into(), a.deck_height_m));
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
            crop,
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
        out.push(item(
            seq,
            captured_ns,
            ItemKind::Points {
                entity: DECK_MODEL,
                points,
                labels: Vec::new(),
                colour: DECK_MODEL_COLOUR,
                radius_ui: DECK_MODEL_RADIUS_UI,
                crop,
            },
        ));
        out.push(item(
            seq,
            captured_ns,
            ItemKind::Strips {
                entity: DECK_MODEL_RING,
                strips: vec![ring],
                colour: DECK_MODEL_COLOUR,
                crop,
            },
        ));
    }
    out
}

/// A vehicle attitude sample from the autopilot as plotted values.
pub fn vehicle_items(v: &deckwatch_common::messages::VehicleSample) -> Vec<Item> {
    let [roll, pitch, _] = v.quaternion.to_rpy().to_degrees();
    vec![Item {
        frame: None,
        time_ns: v.time_ns,
        kind: ItemKind::Scalars(vec![
            (VEHICLE_ROLL.into(), roll),
            (VEHICLE_PITCH.into(), pitch),
            (LINK_CLOCK_OFFSET.into(), v.clock_offset_ns as f64 / 1e6),
            (LINK_UP.into(), f64::from(u8::from(v.link_up.get()))),
        ]),
    }]
}

/// The link's refused frames so far, one running total per cause (`bad-signature`, ...).
pub fn link_refusal_items(time_ns: u64, by_cause: &[(&str, u64)]) -> Vec<Item> {
    vec![Item {
        frame: None,
        time_ns,
        kind: ItemKind::Scalars(
            by_cause
                .iter()
                .map(|(cause, n)| (format!("{LINK_REFUSED}/{cause}"), *n as f64))
                .collect(),
        ),
    }]
}

/// What a reason means, in a few words (the decision's text).
pub fn reason_text(reason: DecisionReason) -> &'static str {
    match reason {
        DecisionReason::WithinCapacity => "the deck is predicted to stay within the capacity",
        DecisionReason::InvalidAttitude => "no valid attitude for this frame",
        DecisionReason::StaleData => "the newest attitude is too old",
        DecisionReason::Gap => "the attitude stream had a gap",
        DecisionReason::Jump => "the attitude jumped more than a deck can move",
        DecisionReason::OutsideCapacity => "roll or pitch (or their rates) outside the capacity",
        DecisionReason::Warmup => "learning the deck's motion (not enough history yet)",
        DecisionReason::PredictionUnreliable => "the motion model does not fit the recent motion",
        DecisionReason::PredictedOutside => "the deck is predicted to leave the capacity during touchdown",
        DecisionReason::NoVehicleAttitude => "the vehicle's attitude is missing",
        DecisionReason::NoDeckHeave => "no deck height for the heave",
        DecisionReason::FrozenInput => "the input repeats itself (frozen)",
        DecisionReason::ClockJump => "the frames' clock jumped",
        DecisionReason::RideThrough => "committed: no attitude this frame, going on with the last prediction",
    }
}

/// What the decide stage logs, and what it remembers to log only changes: the state and reason
/// lanes change only when they do, the predicted calm window is drawn ahead when it appears or
/// moves.
#[derive(Debug, Clone)]
pub struct DecisionView {
    /// The capacity's roll and pitch limits (deg), drawn on the angle plots.
    capacity_deg: [f64; 2],
    last: Option<(DecisionState, DecisionReason)>,
    /// The calm window drawn last: its start and end on the capture clock (ns).
    window_ns: Option<(u64, u64)>,
}

impl DecisionView {
    /// A drawn window is redrawn when the prediction moves it by more than this (ns).
    const WINDOW_TOLERANCE_NS: u64 = 1_000_000_000;

    pub fn new(max_abs_roll_deg: f64, max_abs_pitch_deg: f64) -> Self {
        Self {
            capacity_deg: [max_abs_roll_deg, max_abs_pitch_deg],
            last: None,
            window_ns: None,
        }
    }

    /// The items of one decision. A watchdog's decision belongs to no frame: it is logged at
    /// the time it was made.
    pub fn items(&mut self, d: &LandingDecision) -> Vec<Item> {
        let (state, reason) = (d.state.get(), d.reason.get());
        let watchdog = d.watchdog.get();
        let (frame, time_ns) = if watchdog {
            (None, d.stamp.times[PipelineStage::Decide].received_ns)
        } else {
            (Some(d.stamp.seq), d.stamp.times.captured_ns)
        };
        let at = |kind| Item { frame, time_ns, kind };
        let mut scalars = vec![(HEAVE_RATE.to_string(), d.heave_rate_mps)];
        for (axis, limit) in AXES.iter().zip(self.capacity_deg) {
            scalars.push((attitude_path(axis, CAPACITY_SERIES[0]), limit));
            scalars.push((attitude_path(axis, CAPACITY_SERIES[1]), -limit));
        }
        if !watchdog {
            let times = &d.stamp.times;
            for interval in LatencyInterval::ALL {
                if let Some(ns) = times.interval_ns(interval) {
                    scalars.push((latency_path(interval), ns as f64 / 1e6));
                }
            }
            for (name, n) in d.stamp.drops.named() {
                scalars.push((format!("{DROPS}/{name}"), n as f64));
            }
        }
        let mut out = vec![at(ItemKind::Scalars(scalars))];
        let window = (d.calm_window_start_s.is_finite() && d.calm_window_length_s.is_finite()).then(|| {
            let start = time_ns.saturating_add((d.calm_window_start_s.max(0.0) * 1e9) as u64);
            (
                start,
                start.saturating_add((d.calm_window_length_s.max(0.0) * 1e9) as u64),
            )
        });
        let changed = self.last != Some((state, reason));
        if changed {
            self.last = Some((state, reason));
            out.push(at(ItemKind::State {
                entity: DECISION_STATE,
                state: Some(state.name().to_string()),
            }));
            out.push(at(ItemKind::State {
                entity: DECISION_REASON,
                state: Some(reason.name().to_string()),
            }));
            out.push(at(ItemKind::Text(format!(
                "{} ({}): {}",
                state.name(),
                reason.name(),
                reason_text(reason)
            ))));
        }
        let moved = match (window, self.window_ns) {
            (Some((s, e)), Some((s0, e0))) => {
                s.abs_diff(s0) > Self::WINDOW_TOLERANCE_NS || e.abs_diff(e0) > Self::WINDOW_TOLERANCE_NS
            }
            (Some(_), None) => true,
            _ => false,
        };
        if let (true, Some((start, end))) = (moved, window) {
            let lane = |time_ns, state: Option<&str>| Item {
                frame: None,
                time_ns,
                kind: ItemKind::State {
                    entity: CALM_WINDOW,
                    state: state.map(str::to_string),
                },
            };
            out.push(lane(start, Some(CALM_WINDOW_LABEL)));
            // A window that now lasts longer than the one drawn: its old end is no end (the
            // later row at the same time wins).
            if let Some((s0, e0)) = self.window_ns {
                if start <= e0 && s0 <= end && end > e0 {
                    out.push(lane(e0, Some(CALM_WINDOW_LABEL)));
                }
            }
            out.push(lane(end, None));
            self.window_ns = Some((start, end));
        }
        if changed || moved {
            let window_text = match window {
                Some(_) => format!(
                    "next calm window: in {:.1} s, for {:.1} s",
                    d.calm_window_start_s, d.calm_window_length_s
                ),
                None => "no calm window predicted".to_string(),
            };
            let text = format!(
                "## {}\n\n**{}**: {}\n\n{}{}",
                state.name(),
                reason.name(),
                reason_text(reason),
                window_text,
                if watchdog {
                    "\n\n(watchdog: no attitude arrived in time)"
                } else {
                    ""
                }
            );
            out.push(at(ItemKind::Document {
                entity: DECISION_NOW,
                markdown: text,
            }));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::markers::Marker;

    #[test]
    fn paths_and_labels() {
        assert_eq!(attitude_path(AXES[1], TRUTH_SERIES), "attitude/pitch/truth");
        assert_eq!(marker_label(1), "bow");
        assert_eq!(marker_label(5), "ring 5");
        assert!(MARKERS.starts_with(IMAGE) && DECISION_STATE.starts_with(DECISION));
        assert_eq!(crop_entity(MARKERS).as_deref(), Some("camera/deck/markers"));
        assert_eq!(crop_entity(IMAGE), None);
        assert_eq!(latency_path(LatencyInterval::Hop), "latency/capture_to_detect");
        assert_eq!(latency_path(LatencyInterval::EndToEnd), "latency/end_to_end");
        let mut truth = Truth::UNKNOWN;
        assert!(truth_items(0, 0, &truth).is_empty());
        truth.known = true.into();
        assert_eq!(truth_items(3, 7, &truth).len(), 1);
        assert_eq!(wrapped_deg(359.0), -1.0);
        assert_eq!(wrapped_deg(-181.0), 179.0);
    }

    #[test]
    fn the_crop_holds_the_markers_and_cuts_within_the_frame() {
        let mut set = MarkerSet::default();
        assert_eq!(DeckCrop::of(&set, 640, 480), None);
        for (k, (u, v)) in [(100.0, 120.0), (300.0, 200.0), (630.0, 470.0)]
            .into_iter()
            .enumerate()
        {
            set.markers[k] = Marker {
                valid: true.into(),
                u,
                v,
                ..Marker::default()
            };
        }
        let crop = DeckCrop::of(&set, 640, 480).unwrap();
        assert_eq!((crop.x0, crop.y0), (0, 0));
        assert_eq!((crop.width, crop.height), (640, 480));
        assert_eq!(crop.step, 2);
        let pixels: Vec<u8> = (0..640 * 480).map(|i| (i % 251) as u8).collect();
        let (cut, w, h) = crop.cut(&pixels, 640).unwrap();
        assert_eq!((w, h), (320, 240));
        assert_eq!(cut.len(), 320 * 240);
        assert_eq!(cut[1], pixels[2]);
        assert_eq!(crop.map([2.0, 4.0]), [0.75, 1.75]);
        // A frame shorter than the crop says so instead of reading past it.
        assert!(crop.cut(&pixels[..1000], 640).is_none());
        set.markers[2].valid = false.into();
        let small = DeckCrop::of(&set, 640, 480).unwrap();
        assert_eq!((small.x0, small.y0, small.step), (0, 20, 1));
        assert_eq!((small.width, small.height), (401, 281));
    }

    #[test]
    fn the_decision_view_logs_changes_and_the_window_ahead() {
        let mut view = DecisionView::new(5.0, 4.0);
        let mut d = LandingDecision::default();
        d.stamp.seq = 7;
        d.stamp.times.captured_ns = 10_000_000_000;
        d.state = DecisionState::Hold.into();
        d.reason = DecisionReason::Warmup.into();
        d.calm_window_start_s = f64::NAN;
        d.calm_window_length_s = f64::NAN;
        let first = view.items(&d);
        // Scalars, state, reason, text, document.
        assert_eq!(first.len(), 5);
        let ItemKind::Scalars(s) = &first[0].kind else {
            panic!()
        };
        assert!(s.contains(&("attitude/pitch/capacity_min".to_string(), -4.0)));
        assert_eq!(view.items(&d).len(), 1);
        d.state = DecisionState::ClearToLand.into();
        d.reason = DecisionReason::WithinCapacity.into();
        d.calm_window_start_s = 0.0;
        d.calm_window_length_s = 3.0;
        let items = view.items(&d);
        let ahead: Vec<&Item> = items.iter().filter(|i| i.frame.is_none()).collect();
        assert_eq!(ahead.len(), 2);
        assert_eq!(ahead[1].time_ns, 13_000_000_000);
        // The same window a frame later is not drawn again.
        d.stamp.times.captured_ns += 100_000_000;
        d.calm_window_length_s = 2.9;
        assert_eq!(view.items(&d).len(), 1);
        // The watchdog's decision is at the time it was made, on no frame.
        d.watchdog = true.into();
        d.calm_window_start_s = f64::NAN;
        d.calm_window_length_s = f64::NAN;
        d.state = DecisionState::NoDeck.into();
        d.reason = DecisionReason::StaleData.into();
        d.stamp.times[PipelineStage::Decide].received_ns = 12_000_000_000;
        let items = view.items(&d);
        assert!(items
            .iter()
            .all(|i| i.frame.is_none() && i.time_ns == 12_000_000_000));
    }
}
