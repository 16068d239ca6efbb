//! The rerun side of the logging: recording streams, archetypes, the blueprint, `.rrd` files.

use crate::{
    entities, Item, ItemKind, RerunConfig, RerunSink, RunDescription, VizError, APPLICATION_ID,
    DEFAULT_ADDRESS,
};
use crossbeam_channel::Receiver;
use deckwatch_common::messages::{EstimatorKind, LatencyInterval, TimeBase};
use deckwatch_common::InvalidField;
use rerun::{RecordingStream, RecordingStreamBuilder};
use std::path::Path;
use std::thread::JoinHandle;

/// An error reading or writing an `.rrd` file.
fn file_error(path: &Path, e: impl std::fmt::Display) -> VizError {
    VizError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Opens the stream, then starts the thread that logs what arrives on `rx` until it closes.
pub(crate) fn spawn_logging_thread(
    config: &RerunConfig,
    stage: &str,
    rx: Receiver<Item>,
) -> Result<JoinHandle<()>, VizError> {
    let rec = open_stream(config, stage)?.ok_or(VizError::Config(InvalidField::new(
        "sink",
        "off: nothing to log to",
    )))?;
    let downscale = config.image_downscale as f32;
    // Every process measures the offset itself: they agree to microseconds.
    let clock = TimeBase::measure();
    std::thread::Builder::new()
        .name(format!("rerun-{stage}"))
        .spawn(move || {
            for item in rx {
                log_item(&rec, &item, downscale, clock);
            }
            // Dropping the stream flushes it (and writes the .rrd footer).
            let _ = rec.flush_blocking();
        })
        .map_err(|e| VizError::Thread(e.to_string()))
}

/// The launcher's own stream, which carries the viewer layout; kept open while the pipeline runs.
pub struct Viewer {
    stream: RecordingStream,
}

impl Viewer {
    /// Flushes and closes the stream (a `save` part is complete afterwards).
    pub fn close(self) {
        let _ = self.stream.flush_blocking();
    }
}

/// Opens the launcher's stream of the configured sink and sends the blueprint (None: off).
pub fn open_viewer(
    config: &RerunConfig,
    stage: &str,
    about: &RunDescription,
) -> Result<Option<Viewer>, VizError> {
    let Some(stream) = open_stream(config, stage)? else {
        return Ok(None);
    };
    send_layout(&stream, config.layout)?;
    let sink_error = |e: rerun::RecordingStreamError| VizError::Sink {
        sink: config.sink.name(),
        message: e.to_string(),
    };
    send_styles(&stream).map_err(sink_error)?;
    send_properties(&stream, about).map_err(sink_error)?;
    Ok(Some(Viewer { stream }))
}

/// The recording stream of the configured sink (None: off).
fn open_stream(config: &RerunConfig, stage: &str) -> Result<Option<RecordingStream>, VizError> {
    let mut builder = RecordingStreamBuilder::new(APPLICATION_ID);
    if let Some(id) = &config.recording_id {
        builder = builder.recording_id(id.clone());
    }
    let err = |e: rerun::RecordingStreamError| VizError::Sink {
        sink: config.sink.name(),
        message: e.to_string(),
    };
    let rec = match config.sink {
        RerunSink::Off => return Ok(None),
        RerunSink::Spawn => builder.spawn().map_err(err)?,
        RerunSink::Connect => builder
            .connect_grpc_opts(config.address.clone().unwrap_or_else(|| DEFAULT_ADDRESS.into()))
            .map_err(err)?,
        RerunSink::Save => {
            let path = config.path.as_ref().ok_or(VizError::Config(InvalidField::new(
                "path",
                "required with sink = \"save\"",
            )))?;
            builder.save(RerunConfig::part_path(path, stage)).map_err(err)?
        }
    };
    Ok(Some(rec))
}

fn rgba(c: [u8; 4]) -> rerun::Color {
    rerun::Color::from_unmultiplied_rgba(c[0], c[1], c[2], c[3])
}

fn log_item(rec: &RecordingStream, item: &Item, downscale: f32, clock: TimeBase) {
    match item.frame {
        Some(seq) => rec.set_time_sequence("frame", seq as i64),
        None => rec.disable_timeline("frame"),
    }
    // Wall-clock time of the monotonic stamp: the viewer shows the time of day.
    rec.set_timestamp_nanos_since_epoch("capture_time", clock.to_unix_ns(item.time_ns) as i64);
    // Full-resolution pixel -> pixel of the downscaled image (pixel centres at integers).
    let scale = |p: &[f32; 2]| [(p[0] + 0.5) / downscale - 0.5, (p[1] + 0.5) / downscale - 0.5];
    let result = match &item.kind {
        ItemKind::Image {
            entity,
            pixels,
            width,
            height,
        } => rec.log(*entity, &rerun::Image::from_l8(pixels.clone(), [*width, *height])),
        ItemKind::Points {
            entity,
            points,
            labels,
            colour,
            radius_ui,
            crop,
        } => {
            let style = |pts: Vec<[f32; 2]>| {
                rerun::Points2D::new(pts)
                    .with_colors([rgba(*colour)])
                    .with_radii([rerun::Radius::new_ui_points(*radius_ui)])
            };
            let mut r = rec.log(*entity, &style(points.iter().map(scale).collect()));
            if let (Some(c), Some(path)) = (crop, entities::crop_entity(entity)) {
                let pts = points.iter().map(|p| c.map(*p)).collect();
                r = r.and(rec.log(path, &style(pts).with_labels(labels.clone())));
            }
            r
        }
        ItemKind::Strips {
            entity,
            strips,
            colour,
            crop,
        } => {
            let style = |s: Vec<Vec<[f32; 2]>>| rerun::LineStrips2D::new(s).with_colors([rgba(*colour)]);
            let s = strips.iter().map(|st| st.iter().map(scale).collect()).collect();
            let mut r = rec.log(*entity, &style(s));
            if let (Some(c), Some(path)) = (crop, entities::crop_entity(entity)) {
                let s = strips
                    .iter()
                    .map(|st| st.iter().map(|p| c.map(*p)).collect())
                    .collect();
                r = r.and(rec.log(path, &style(s)));
            }
            r
        }
        ItemKind::Scalars(values) => {
            let mut r = Ok(());
            for (entity, v) in values {
                if v.is_finite() {
                    r = r.and(rec.log(entity.as_str(), &rerun::Scalars::single(*v)));
                }
            }
            r
        }
        ItemKind::Text(t) => rec.log(entities::DECISION_LOG, &rerun::TextLog::new(t.clone())),
        // Leaving a state is an empty one (a null state is not valid data: `rerun rrd verify`
        // refuses it, and the viewer ignored it, so the lane never ended).
        ItemKind::State { entity, state } => rec.log(
            *entity,
            &rerun::StateChange::new().with_state([state.clone().unwrap_or_default()]),
        ),
        ItemKind::Document { entity, markdown } => rec.log(
            *entity,
            &rerun::TextDocument::new(markdown.clone()).with_media_type(rerun::MediaType::markdown()),
        ),
    };
    // A failed log call (e.g. a viewer that went away) must not stop the thread.
    let _ = result;
}

/// The series' names and colours, the decision lanes' labels and colours (static: they hold
/// for the whole recording).
fn send_styles(rec: &RecordingStream) -> rerun::RecordingStreamResult<()> {
    let line = |name: &str, colour: [u8; 4], width: f32| {
        rerun::SeriesLines::new()
            .with_names([name])
            .with_colors([rgba(colour)])
            .with_widths([width])
    };
    for axis in entities::AXES {
        rec.log_static(
            entities::attitude_path(axis, entities::TRUTH_SERIES),
            &line("truth", entities::TRUTH_COLOUR, 3.0),
        )?;
        for kind in EstimatorKind::ALL {
            let (name, colour) = (kind.name(), entities::estimator_colour(kind));
            rec.log_static(entities::attitude_path(axis, name), &line(name, colour, 1.5))?;
            rec.log_static(
                format!("{}/{name}", entities::error_axis_path(axis)),
                &line(name, colour, 1.5),
            )?;
        }
    }
    for axis in &entities::AXES[..2] {
        for series in entities::CAPACITY_SERIES {
            rec.log_static(
                entities::attitude_path(axis, series),
                &line("capacity", entities::CAPACITY_COLOUR, 1.0),
            )?;
        }
    }
    let states: Vec<&str> = entities::STATE_COLOURS.iter().map(|(s, _)| s.name()).collect();
    let colours: Vec<rerun::Color> = entities::STATE_COLOURS.iter().map(|(_, c)| rgba(*c)).collect();
    rec.log_static(
        entities::DECISION_STATE,
        &rerun::StateConfiguration::new()
            .with_values(states)
            .with_colors(colours),
    )?;
    rec.log_static(
        entities::CALM_WINDOW,
        &rerun::StateConfiguration::new()
            .with_values([entities::CALM_WINDOW_LABEL])
            .with_colors([rgba([40, 200, 70, 160])]),
    )?;
    Ok(())
}

/// The recording's name and properties: what ran, on what, with which configuration.
fn send_properties(rec: &RecordingStream, about: &RunDescription) -> rerun::RecordingStreamResult<()> {
    use rerun::components::Text;
    rec.send_recording_name(about.name.clone())?;
    let mut values = rerun::AnyValues::default();
    for (key, value) in &about.properties {
        // An empty key cannot name a field; it is left out.
        if let Ok(field) = rerun::ComponentIdentifier::try_new(key) {
            values = values.with_component::<Text>(field, [value.clone()]);
        }
    }
    rec.send_property("deckwatch", &values)?;
    rec.send_property(
        "configuration",
        &rerun::TextDocument::new(format!("```toml\n{}\n```", about.configuration_toml))
            .with_media_type(rerun::MediaType::markdown()),
    )
}

/// The viewer layout. Left: the frame and its deck region with their overlays, the decision's
/// lanes, the decision in words and its changes. Middle: the angles with the truth and the
/// capacity. Right: the errors against the truth, and latency, drops, heave and the vehicle
/// in tabs.
pub fn send_blueprint(rec: &RecordingStream) -> Result<(), VizError> {
    use rerun::blueprint::{
        Horizontal, Spatial2DView, StateTimelineView, Tabs, TextDocumentView, TextLogView, TimeSeriesView,
        Vertical,
    };
    let series = |name: &str, origin: String| TimeSeriesView::new(name).with_origin(origin).into();
    let camera = Horizontal::new([
        Spatial2DView::new("frame").with_origin(entities::IMAGE).into(),
        Spatial2DView::new("deck (full resolution)")
            .with_origin(entities::DECK_CROP)
            .into(),
    ])
    .with_column_shares([1.3, 1.0]);
    let words = Horizontal::new([
        TextDocumentView::new("decision now")
            .with_origin(entities::DECISION_NOW)
            .into(),
        TextLogView::new("decision changes")
            .with_origin(entities::DECISION_LOG)
            .into(),
    ]);
    let left = Vertical::new([
        camera.into(),
        StateTimelineView::new("decision")
            .with_origin(entities::DECISION)
            .into(),
        words.into(),
    ])
    .with_row_shares([3.0, 1.6, 1.3]);
    let angles = Vertical::new(
        entities::AXES
            .iter()
            .map(|axis| series(&format!("{axis} (deg)"), entities::attitude_axis_path(axis))),
    );
    let errors = entities::AXES
        .iter()
        .map(|axis| series(&format!("{axis} error (deg)"), entities::error_axis_path(axis)));
    let more = Tabs::new([
        // Without the capture itself (the simulator's rendering, tens of ms), which would
        // flatten the stages' fractions of a millisecond.
        TimeSeriesView::new("latency after capture (ms)")
            .with_origin(entities::LATENCY)
            .with_contents([
                "+ $origin/**".to_string(),
                format!("- /{}", entities::latency_path(LatencyInterval::Capture)),
            ])
            .into(),
        series("drops", entities::DROPS.into()),
        series("heave (m, m/s)", entities::HEAVE.into()),
        TimeSeriesView::new("vehicle (deg)")
            .with_origin("/")
            .with_contents([
                "+ vehicle/**".to_string(),
                "+ link/**".to_string(),
                format!("- {}/**", entities::LINK_REFUSED),
            ])
            .into(),
        // Running totals by cause, thousands under a flood: apart from the degrees.
        series("link refused (frames)", entities::LINK_REFUSED.into()),
    ]);
    let right = Vertical::new(errors.chain(std::iter::once(more.into())));
    let layout =
        Horizontal::new([left.into(), angles.into(), right.into()]).with_column_shares([2.2, 1.0, 1.0]);
    send_views(rec, layout)
}

/// Sends `layout` as the blueprint. The views get the whole window: the blueprint and selection
/// panels start hidden, the time panel collapsed to its controls (each opens with a click).
fn send_views(rec: &RecordingStream, layout: rerun::blueprint::Horizontal) -> Result<(), VizError> {
    use rerun::blueprint::{
        components::PanelState, Blueprint, BlueprintActivation, BlueprintPanel, SelectionPanel, TimePanel,
    };
    Blueprint::new(layout)
        .with_blueprint_panel(BlueprintPanel::new().with_state(PanelState::Hidden))
        .with_selection_panel(SelectionPanel::new().with_state(PanelState::Hidden))
        .with_time_panel(
            TimePanel::new()
                .with_timeline("capture_time")
                .with_state(PanelState::Collapsed),
        )
        .send(rec, BlueprintActivation::default())
        .map_err(|e| VizError::Sink {
            sink: "blueprint",
            message: e.to_string(),
        })
}

/// The blueprint of `layout`.
fn send_layout(rec: &RecordingStream, layout: crate::Layout) -> Result<(), VizError> {
    match layout {
        crate::Layout::Pipeline => send_blueprint(rec),
        crate::Layout::Trial => send_trial_blueprint(rec),
    }
}

/// The layout of a closed-loop trial: what the camera saw and what was decided on the left
/// (the verdict of the touchdown in "decision now" at the end), the deck's roll and pitch with
/// the truth and the capacity, and the vehicle's height over the deck beside the heave.
pub fn send_trial_blueprint(rec: &RecordingStream) -> Result<(), VizError> {
    use rerun::blueprint::{
        Horizontal, Spatial2DView, StateTimelineView, TextDocumentView, TextLogView, TimeSeriesView, Vertical,
    };
    let series = |name: &str, origin: String| TimeSeriesView::new(name).with_origin(origin).into();
    let left = Vertical::new([
        Spatial2DView::new("frame").with_origin(entities::IMAGE).into(),
        StateTimelineView::new("decision")
            .with_origin(entities::DECISION)
            .into(),
        TextDocumentView::new("touchdown")
            .with_origin(entities::DECISION_NOW)
            .into(),
        TextLogView::new("commits, go-arounds, decisions")
            .with_origin(entities::DECISION_LOG)
            .into(),
    ])
    .with_row_shares([2.0, 1.1, 2.1, 1.2]);
    let right = Vertical::new([
        series("roll (deg)", entities::attitude_axis_path("roll")),
        series("pitch (deg)", entities::attitude_axis_path("pitch")),
        series("vehicle over the deck, heave (m, m/s)", entities::HEAVE.into()),
    ]);
    send_views(
        rec,
        Horizontal::new([left.into(), right.into()]).with_column_shares([1.0, 1.3]),
    )
}

/// Merges the per-process part files of a `save` run into one `.rrd` (one stream header), and
/// removes the parts. Returns the number of messages written.
pub fn merge_parts(path: &Path, stages: &[&str]) -> Result<u64, VizError> {
    // Into a temporary file beside it, renamed once complete: a failed merge (disk full, a
    // corrupt part) leaves no partial .rrd under the user's name, and keeps the parts.
    let mut partial = path.as_os_str().to_owned();
    partial.push(".merging");
    let partial = std::path::PathBuf::from(partial);
    let result = merge_into(&partial, path, stages);
    match result {
        Ok((n, parts)) => {
            std::fs::rename(&partial, path)
                .map_err(|e| file_error(path, format!("cannot rename {}: {e}", partial.display())))?;
            for p in parts {
                let _ = std::fs::remove_file(p);
            }
            Ok(n)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&partial);
            Err(e)
        }
    }
}

/// Writes the parts of `path` into `out`: (messages, the parts read).
fn merge_into(
    out_path: &Path,
    path: &Path,
    stages: &[&str],
) -> Result<(u64, Vec<std::path::PathBuf>), VizError> {
    use rerun::external::re_build_info::CrateVersion;
    use rerun::external::re_log_encoding as enc;
    use rerun::external::re_log_types::LogMsg;
    let out =
        std::fs::File::create(out_path).map_err(|e| file_error(out_path, format!("cannot create: {e}")))?;
    let mut encoder = enc::Encoder::new_eager(
        CrateVersion::LOCAL,
        enc::EncodingOptions::PROTOBUF_COMPRESSED,
        std::io::BufWriter::new(out),
    )
    .map_err(|e| file_error(path, e))?;
    let mut n = 0u64;
    let mut parts = Vec::new();
    for part in stages.iter().flat_map(|stage| RerunConfig::parts_of(path, stage)) {
        let file = std::fs::File::open(&part).map_err(|e| file_error(&part, e))?;
        let decoder = enc::Decoder::<LogMsg>::decode_eager(std::io::BufReader::new(file))
            .map_err(|e| file_error(&part, e))?;
        for msg in decoder {
            let msg = msg.map_err(|e| file_error(&part, e))?;
            encoder.append(&msg).map_err(|e| file_error(out_path, e))?;
            n += 1;
        }
        parts.push(part);
    }
    encoder.finish().map_err(|e| file_error(out_path, e))?;
    // Flushed and synced here, where an error can still be reported (a drop would swallow it).
    let file = encoder
        .into_inner()
        .map_err(|e| file_error(out_path, e))?
        .into_inner()
        .map_err(|e| file_error(out_path, e.error().to_string()))?;
    file.sync_all().map_err(|e| file_error(out_path, e))?;
    Ok((n, parts))
}

/// Rows logged over time per entity of the recording (static data such as the series' styles
/// and the properties, and blueprint stores excluded), read back from an
/// `.rrd` file: what a test or a user checks a saved run with.
pub fn rrd_entity_rows(path: &Path) -> Result<std::collections::BTreeMap<String, u64>, VizError> {
    use rerun::external::re_log_encoding as enc;
    use rerun::external::re_log_types::{LogMsg, StoreKind};
    use rerun::log::Chunk;
    let file = std::fs::File::open(path).map_err(|e| file_error(path, e))?;
    let decoder = enc::Decoder::<LogMsg>::decode_eager(std::io::BufReader::new(file))
        .map_err(|e| file_error(path, e))?;
    let mut rows = std::collections::BTreeMap::new();
    for msg in decoder {
        let msg = msg.map_err(|e| file_error(path, e))?;
        if let LogMsg::ArrowMsg(store, arrow) = &msg {
            if store.kind() != StoreKind::Recording {
                continue;
            }
            let chunk = Chunk::from_arrow_msg(arrow).map_err(|e| file_error(path, e))?;
            if chunk.is_static() {
                continue;
            }
            *rows.entry(chunk.entity_path().to_string()).or_default() += chunk.num_rows() as u64;
        }
    }
    Ok(rows)
}
