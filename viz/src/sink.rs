//! The rerun side of the logging: recording streams, archetypes, the blueprint, `.rrd` files.

use crate::{entities, Item, ItemKind, RerunConfig, RerunSink, VizError, APPLICATION_ID, DEFAULT_ADDRESS};
use crossbeam_channel::Receiver;
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
    let rec = open_stream(config, stage)?.ok_or(VizError::Config {
        key: "sink",
        problem: "off: nothing to log to".into(),
    })?;
    let downscale = config.image_downscale as f32;
    std::thread::Builder::new()
        .name(format!("rerun-{stage}"))
        .spawn(move || {
            for item in rx {
                log_item(&rec, &item, downscale);
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
pub fn open_viewer(config: &RerunConfig, stage: &str) -> Result<Option<Viewer>, VizError> {
    let Some(stream) = open_stream(config, stage)? else {
        return Ok(None);
    };
    send_blueprint(&stream)?;
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
            let path = config.path.as_ref().ok_or(VizError::Config {
                key: "path",
                problem: "required with sink = \"save\"".into(),
            })?;
            builder.save(RerunConfig::part_path(path, stage)).map_err(err)?
        }
    };
    Ok(Some(rec))
}

fn log_item(rec: &RecordingStream, item: &Item, downscale: f32) {
    rec.set_time_sequence("frame", item.seq as i64);
    rec.set_duration_secs("capture_time", item.captured_ns as f64 / 1e9);
    // Full-resolution pixel -> pixel of the downscaled image (pixel centres at integers).
    let scale = |p: &[f32; 2]| [(p[0] + 0.5) / downscale - 0.5, (p[1] + 0.5) / downscale - 0.5];
    let result = match &item.kind {
        ItemKind::Image {
            pixels,
            width,
            height,
        } => rec.log(
            entities::IMAGE,
            &rerun::Image::from_l8(pixels.clone(), [*width, *height]),
        ),
        ItemKind::Points {
            entity,
            points,
            labels,
            colour,
        } => {
            let pts: Vec<[f32; 2]> = points.iter().map(scale).collect();
            rec.log(
                *entity,
                &rerun::Points2D::new(pts)
                    .with_labels(labels.clone())
                    .with_colors([rerun::Color::from_unmultiplied_rgba(
                        colour[0], colour[1], colour[2], colour[3],
                    )])
                    .with_radii([2.0]),
            )
        }
        ItemKind::Strips {
            entity,
            strips,
            colour,
        } => {
            let s: Vec<Vec<[f32; 2]>> = strips.iter().map(|st| st.iter().map(scale).collect()).collect();
            let c = rerun::Color::from_unmultiplied_rgba(colour[0], colour[1], colour[2], colour[3]);
            rec.log(*entity, &rerun::LineStrips2D::new(s).with_colors([c]))
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
    };
    // A failed log call (e.g. a viewer that went away) must not stop the thread.
    let _ = result;
}

/// The viewer layout: the image with its overlays beside the angle plots, the decision below.
pub fn send_blueprint(rec: &RecordingStream) -> Result<(), VizError> {
    use rerun::blueprint::{
        Blueprint, BlueprintActivation, Horizontal, Spatial2DView, TextLogView, TimeSeriesView, Vertical,
    };
    let plots = Vertical::new([
        TimeSeriesView::new("roll (deg)")
            .with_origin(entities::attitude_axis_path(entities::AXES[0]))
            .into(),
        TimeSeriesView::new("pitch (deg)")
            .with_origin(entities::attitude_axis_path(entities::AXES[1]))
            .into(),
        TimeSeriesView::new("yaw (deg)")
            .with_origin(entities::attitude_axis_path(entities::AXES[2]))
            .into(),
        TimeSeriesView::new("heave (m, m/s)")
            .with_origin(entities::HEAVE)
            .into(),
        TimeSeriesView::new("decision")
            .with_origin(entities::DECISION)
            .into(),
    ]);
    let left = Vertical::new([
        Spatial2DView::new("camera").with_origin(entities::IMAGE).into(),
        TextLogView::new("decisions")
            .with_origin(entities::DECISION_LOG)
            .into(),
    ])
    .with_row_shares([3.0, 1.0]);
    let blueprint = Blueprint::new(Horizontal::new([left.into(), plots.into()]));
    blueprint
        .send(rec, BlueprintActivation::default())
        .map_err(|e| VizError::Sink {
            sink: "blueprint",
            message: e.to_string(),
        })
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

/// Rows logged per entity of the recording (blueprint stores excluded), read back from an
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
            *rows.entry(chunk.entity_path().to_string()).or_default() += chunk.num_rows() as u64;
        }
    }
    Ok(rows)
}
