//! The recording format (README; the columns' meaning in CONVENTIONS.md §9): a folder with
//! - `camera.json`: `width, height, fx, fy, cx, cy, distortion` (`[k1,k2,p1,p2,k3]`) and `deck`
//!   (`ring_radius_m, marker_radius_m, bow_marker_radius_m, n_ring, markers_deck_xyz_m`);
//!   unknown extra keys are ignored;
//! - `frames.csv`: a header row, then `index,timestamp_ns,file` and optionally
//!   `roll_deg,pitch_deg,yaw_deg,alt_m,offset_x_m,offset_y_m` (ground truth / altimeter) and
//!   `vehicle_roll_deg,vehicle_pitch_deg,vehicle_yaw_deg` (the camera's vehicle),
//!   `vehicle_height_m` (the vehicle's height in W) and `deck_heave_m` (the true heave), in any
//!   column order, further columns ignored; `nan` (or an empty field) where a value is unknown,
//!   e.g. the attitude when no deck is in view;
//! - 8-bit grayscale PNG images at the relative paths named in `file`;
//! - optionally `vehicle.csv`: the vehicle's attitude at the autopilot's rate, a header row then
//!   `timestamp_ns,qw,qx,qy,qz` (`R_V` body to world as a unit quaternion, on the frames'
//!   clock) and optionally `height_m` (the vehicle's height in W), increasing in time; replay
//!   and eval interpolate it (slerp; height linearly) to each frame and prefer it to the frames'
//!   vehicle columns.
//!
//! Every error names the file and, where it applies, the line and the field.

pub use deckwatch_common::truth::{
    with_heave_truth, GroundTruth, TruthColumns, ALL_TRUTH, LEVEL_TRUTH, NO_TRUTH, TRUTH_COLUMNS,
};
pub use deckwatch_common::vehicle::VehicleStateSample;
use deckwatch_common::{CameraModel, DeckLayout, Distortion, GrayImage, GrayView, Quaternion};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Component, Path, PathBuf};

mod images;
mod writer;

pub use images::{decode_gray_png, encode_gray_png};
pub use writer::RecordingWriter;

pub const CAMERA_FILE: &str = "camera.json";
pub const FRAMES_FILE: &str = "frames.csv";
pub const VEHICLE_FILE: &str = "vehicle.csv";
/// The header of `vehicle.csv` (then optionally [`VEHICLE_HEIGHT_COLUMN`]).
pub const VEHICLE_COLUMNS: [&str; 5] = ["timestamp_ns", "qw", "qx", "qy", "qz"];
pub const VEHICLE_HEIGHT_COLUMN: &str = "height_m";

// The bounds of what a recording folder's files may hold, checked before anything is read or
// allocated (`deckwatch_common::files`): each well beyond any recording deckwatch makes.
/// The largest `camera.json` read (bytes): the paper's deck makes ~1.5 KB.
pub const MAX_CAMERA_JSON_BYTES: u64 = 1 << 20;
/// The most frames a recording folder lists: 2.3 h at 60 fps, each a PNG file in the folder. A
/// row costs ~300 bytes once read, so this also bounds what opening a recording holds.
pub const MAX_RECORDING_FRAMES: usize = 500_000;
/// The largest `frames.csv` read (bytes): a row with every column is ~350 bytes, so this holds
/// [`MAX_RECORDING_FRAMES`] rows with room to spare.
pub const MAX_FRAMES_CSV_BYTES: u64 = 256 << 20;
/// The most samples of `vehicle.csv`: 5.5 h at 100 Hz.
pub const MAX_VEHICLE_SAMPLES: usize = 2_000_000;
/// The largest `vehicle.csv` read (bytes): a row is ~120 bytes, so this holds
/// [`MAX_VEHICLE_SAMPLES`] rows.
pub const MAX_VEHICLE_CSV_BYTES: u64 = 256 << 20;
/// The longest line of a CSV file deckwatch reads (bytes): a row of every column is under 2 KB,
/// a marker table's row for 100 markers ~5 KB; a CSV parser holds a whole line.
pub const MAX_CSV_LINE_BYTES: u64 = 64 << 10;

/// Folder (inside the recording) the writer puts images in.
pub const IMAGES_DIR: &str = "frames";

/// A problem with a recording, located as precisely as possible.
#[derive(Debug)]
pub struct RecordingError {
    pub path: PathBuf,
    /// 1-based line in the file, where it applies.
    pub line: Option<u64>,
    /// The field (JSON key or CSV column), where it applies.
    pub field: Option<String>,
    pub message: String,
}

impl RecordingError {
    fn new(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            line: None,
            field: None,
            message: message.into(),
        }
    }
    /// An error at an optional line and field.
    pub(crate) fn at(
        path: impl Into<PathBuf>,
        line: Option<u64>,
        field: Option<&str>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            path: path.into(),
            line,
            field: field.map(str::to_string),
            message: message.into(),
        }
    }

    /// A CSV syntax error (e.g. a row with the wrong number of fields), at its line; or the
    /// bound of the file it was read from.
    pub(crate) fn csv(path: &Path, e: &csv::Error) -> Self {
        if let csv::ErrorKind::Io(io) = e.kind() {
            if let Some(bound) = deckwatch_common::files::bound_in(io) {
                return Self::at(bound.path(), bound.line(), None, bound.problem());
            }
        }
        Self::at(path, e.position().map(|p| p.line()), None, format!("{e}"))
    }

    fn at_line(mut self, line: u64) -> Self {
        self.line = Some(line);
        self
    }
    fn field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }
}

/// A file that cannot be read, or passes its bound.
impl From<deckwatch_common::files::FileReadError> for RecordingError {
    fn from(e: deckwatch_common::files::FileReadError) -> Self {
        Self::at(e.path(), e.line(), None, e.problem())
    }
}

impl fmt::Display for RecordingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": field `{field}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for RecordingError {}

// ---------------------------------------------------------------------------------------------
// camera.json

#[derive(Serialize, Deserialize)]
struct CameraJson {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    distortion: Vec<f64>,
    /// Rolling-shutter readout (ms); absent = 0, a global shutter.
    #[serde(default, skip_serializing_if = "is_zero")]
    readout_ms: f64,
    deck: DeckJson,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

#[derive(Serialize, Deserialize)]
struct DeckJson {
    ring_radius_m: f64,
    marker_radius_m: f64,
    bow_marker_radius_m: f64,
    n_ring: usize,
    markers_deck_xyz_m: Vec<[f64; 3]>,
}

/// Writes `camera.json` for a camera and deck.
pub fn write_camera_json(dir: &Path, camera: &CameraModel, deck: &DeckLayout) -> Result<(), RecordingError> {
    let path = dir.join(CAMERA_FILE);
    let json = CameraJson {
        width: camera.width,
        height: camera.height,
        fx: camera.fx,
        fy: camera.fy,
        cx: camera.cx,
        cy: camera.cy,
        distortion: camera.distortion.to_array().to_vec(),
        readout_ms: camera.readout_s * 1e3,
        deck: DeckJson {
            ring_radius_m: deck.ring_radius_m,
            marker_radius_m: deck.marker_radius_m,
            bow_marker_radius_m: deck.bow_marker_radius_m,
            n_ring: deck.n_ring,
            markers_deck_xyz_m: deck.marker_positions().iter().map(|p| [p.x, p.y, p.z]).collect(),
        },
    };
    let text = serde_json::to_string_pretty(&json).expect("camera.json serialises");
    std::fs::write(&path, text + "\n").map_err(|e| RecordingError::new(&path, format!("cannot write: {e}")))
}

/// Reads and validates `camera.json` in `dir`.
pub fn read_camera_json(dir: &Path) -> Result<(CameraModel, DeckLayout), RecordingError> {
    let path = dir.join(CAMERA_FILE);
    let text = deckwatch_common::files::read_bounded_to_string(&path, MAX_CAMERA_JSON_BYTES)?;
    parse_camera_json(&path, &text)
}

fn parse_camera_json(path: &Path, text: &str) -> Result<(CameraModel, DeckLayout), RecordingError> {
    let json: CameraJson = serde_json::from_str(text).map_err(|e| {
        // serde_json names missing and mistyped keys in its message and knows the line.
        RecordingError::new(path, format!("{e}")).at_line(e.line() as u64)
    })?;
    if json.distortion.len() != 5 {
        return Err(RecordingError::new(
            path,
            format!(
                "expected 5 coefficients [k1, k2, p1, p2, k3], got {}",
                json.distortion.len()
            ),
        )
        .field("distortion"));
    }
    let camera = CameraModel {
        width: json.width,
        height: json.height,
        fx: json.fx,
        fy: json.fy,
        cx: json.cx,
        cy: json.cy,
        distortion: Distortion::from_array(json.distortion.as_slice().try_into().expect("length checked")),
        readout_s: json.readout_ms / 1e3,
    };
    camera
        .validate()
        .map_err(|m| RecordingError::new(path, m.to_string()))?;
    let d = &json.deck;
    let deck = DeckLayout {
        ring_radius_m: d.ring_radius_m,
        marker_radius_m: d.marker_radius_m,
        bow_marker_radius_m: d.bow_marker_radius_m,
        n_ring: d.n_ring,
    };
    deck.validate()
        .map_err(|m| RecordingError::new(path, format!("in `deck`: {m}")))?;
    // The explicit marker list is for readers in other languages; it must agree with the layout.
    if d.markers_deck_xyz_m.len() != deck.marker_count() {
        return Err(RecordingError::new(
            path,
            format!(
                "{} markers listed, the layout has {}",
                d.markers_deck_xyz_m.len(),
                deck.marker_count()
            ),
        )
        .field("deck.markers_deck_xyz_m"));
    }
    for (i, listed) in d.markers_deck_xyz_m.iter().enumerate() {
        let p = deck.marker_position(i);
        let dist = ((listed[0] - p.x).powi(2) + (listed[1] - p.y).powi(2) + (listed[2] - p.z).powi(2)).sqrt();
        if !(dist <= 1e-6) {
            return Err(RecordingError::new(
                path,
                format!(
                    "{listed:?} does not match the ring layout's [{:.6}, {:.6}, {:.6}] (marker index order: \
                     0 centre, 1 bow, then counter-clockwise)",
                    p.x, p.y, p.z
                ),
            )
            .field(format!("deck.markers_deck_xyz_m[{i}]")));
        }
    }
    Ok((camera, deck))
}

// ---------------------------------------------------------------------------------------------
// frames.csv

/// One row of `frames.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    pub index: u64,
    pub timestamp_ns: u64,
    /// Image path relative to the recording folder.
    pub file: String,
    pub truth: GroundTruth,
    /// Line of `frames.csv` the row came from (for error messages).
    pub line: u64,
}

/// A recording opened for reading: camera, deck and the frame list; images are decoded on demand.
#[derive(Debug, Clone)]
pub struct Recording {
    pub dir: PathBuf,
    pub camera: CameraModel,
    pub deck: DeckLayout,
    pub frames: Vec<FrameRecord>,
    /// Which optional ground-truth columns the recording has (in [`TRUTH_COLUMNS`] order).
    pub truth_columns: TruthColumns,
    /// `vehicle.csv`, when the recording has one.
    pub vehicle_samples: Option<Vec<VehicleStateSample>>,
}

impl Recording {
    /// Opens a recording folder: reads and validates `camera.json` and `frames.csv` (images are
    /// not decoded here).
    pub fn open(dir: impl AsRef<Path>) -> Result<Self, RecordingError> {
        let dir = dir.as_ref().to_path_buf();
        if !dir.is_dir() {
            return Err(RecordingError::new(
                &dir,
                "not a recording folder (no such directory)",
            ));
        }
        let (camera, deck) = read_camera_json(&dir)?;
        let path = dir.join(FRAMES_FILE);
        let file = deckwatch_common::files::open_bounded(&path, MAX_FRAMES_CSV_BYTES)?
            .with_max_line_bytes(MAX_CSV_LINE_BYTES);
        let (frames, truth_columns) = parse_frames_csv(&path, BufReader::new(file))?;
        let vehicle_path = dir.join(VEHICLE_FILE);
        let vehicle_samples = if vehicle_path.exists() {
            Some(read_vehicle_csv(&vehicle_path)?)
        } else {
            None
        };
        Ok(Self {
            dir,
            camera,
            deck,
            frames,
            truth_columns,
            vehicle_samples,
        })
    }

    /// True when the recording says whether a deck is in view (it has the attitude columns).
    pub fn has_attitude_truth(&self) -> bool {
        self.truth_columns[..3].iter().all(|&c| c)
    }

    /// Full path of a frame's image.
    pub fn image_path(&self, frame: &FrameRecord) -> PathBuf {
        self.dir.join(&frame.file)
    }

    /// Decodes a frame's image into `out` (tightly packed, `width * height` bytes, sized from
    /// `camera.json`); checks it is an 8-bit grayscale PNG of the recording's size.
    pub fn read_image_into(&self, frame: &FrameRecord, out: &mut [u8]) -> Result<(), RecordingError> {
        let path = self.image_path(frame);
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        if out.len() != w * h {
            return Err(RecordingError::new(
                &path,
                format!("output buffer has {} bytes, the frame needs {}", out.len(), w * h),
            ));
        }
        decode_gray_png(&path, Some((w, h)), out).map(|_| ())
    }

    /// Decodes a frame's image into a new buffer.
    pub fn read_image(&self, frame: &FrameRecord) -> Result<GrayImage, RecordingError> {
        let mut img = GrayImage::new(self.camera.width as usize, self.camera.height as usize);
        self.read_image_into(frame, &mut img.data)?;
        Ok(img)
    }
}

/// Reads `vehicle.csv`: every row a timestamp after the previous one and a unit quaternion; an
/// error names the file, the line and the column.
pub fn read_vehicle_csv(path: &Path) -> Result<Vec<VehicleStateSample>, RecordingError> {
    let file = deckwatch_common::files::open_bounded(path, MAX_VEHICLE_CSV_BYTES)?
        .with_max_line_bytes(MAX_CSV_LINE_BYTES);
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_reader(BufReader::new(file));
    let header = reader
        .headers()
        .map_err(|e| RecordingError::csv(path, &e))?
        .clone();
    let column = |name: &str| {
        header.iter().position(|h| h.trim() == name).ok_or_else(|| {
            RecordingError::new(
                path,
                format!("no `{name}` column (needs {})", VEHICLE_COLUMNS.join(",")),
            )
            .at_line(1)
        })
    };
    let columns = VEHICLE_COLUMNS.map(column);
    let mut idx = [0usize; 5];
    for (i, c) in columns.into_iter().enumerate() {
        idx[i] = c?;
    }
    let height = header.iter().position(|h| h.trim() == VEHICLE_HEIGHT_COLUMN);
    let mut out: Vec<VehicleStateSample> = Vec::new();
    for (k, record) in reader.records().enumerate() {
        let line = k as u64 + 2;
        let record = record.map_err(|e| match RecordingError::csv(path, &e) {
            known if known.line.is_some() => known,
            unknown => unknown.at_line(line),
        })?;
        if out.len() == MAX_VEHICLE_SAMPLES {
            return Err(RecordingError::new(
                path,
                format!("more than {MAX_VEHICLE_SAMPLES} samples, the most deckwatch reads"),
            )
            .at_line(line));
        }
        let get = |i: usize| record.get(idx[i]).unwrap_or("").trim();
        let t: u64 = get(0).parse().map_err(|_| {
            RecordingError::new(path, format!("`{}` is not a time in ns", get(0)))
                .at_line(line)
                .field("timestamp_ns")
        })?;
        if out.last().is_some_and(|prev| t <= prev.time_ns) {
            return Err(RecordingError::new(path, "not after the previous sample")
                .at_line(line)
                .field("timestamp_ns"));
        }
        let mut q = [0.0; 4];
        for (j, v) in q.iter_mut().enumerate() {
            *v = parse_optional_number(path, Some(line), VEHICLE_COLUMNS[j + 1], get(j + 1))?.ok_or_else(
                || {
                    RecordingError::new(path, "a sample needs all four components")
                        .at_line(line)
                        .field(VEHICLE_COLUMNS[j + 1])
                },
            )?;
        }
        let q = Quaternion::new(q[0], q[1], q[2], q[3]);
        if (q.norm() - 1.0).abs() > 1e-3 {
            return Err(
                RecordingError::new(path, format!("not a unit quaternion (norm {})", q.norm()))
                    .at_line(line)
                    .field("qw"),
            );
        }
        let height_m = match height {
            Some(i) => parse_optional_number(
                path,
                Some(line),
                VEHICLE_HEIGHT_COLUMN,
                record.get(i).unwrap_or("").trim(),
            )?,
            None => None,
        };
        out.push(VehicleStateSample {
            time_ns: t,
            quaternion: q.normalized().unwrap_or(q),
            height_m,
            // vehicle.csv has no vertical speed: its heights are used as they are.
            vertical_speed_mps: None,
        });
    }
    Ok(out)
}

/// Writes `vehicle.csv` into a recording folder (with the height column when any sample has a
/// height).
pub fn write_vehicle_csv(dir: &Path, samples: &[VehicleStateSample]) -> Result<(), RecordingError> {
    let path = dir.join(VEHICLE_FILE);
    let fail = |e: std::io::Error| RecordingError::new(&path, format!("cannot write: {e}"));
    let mut w = BufWriter::new(File::create(&path).map_err(fail)?);
    let heights = samples.iter().any(|s| s.height_m.is_some());
    write!(w, "{}", VEHICLE_COLUMNS.join(",")).map_err(fail)?;
    if heights {
        write!(w, ",{VEHICLE_HEIGHT_COLUMN}").map_err(fail)?;
    }
    writeln!(w).map_err(fail)?;
    for s in samples {
        let (t, q) = (s.time_ns, s.quaternion);
        // Rust's shortest round-trip form: the quaternion reads back bit for bit.
        write!(w, "{t},{},{},{},{}", q.w, q.x, q.y, q.z).map_err(fail)?;
        if heights {
            match s.height_m {
                Some(h) => write!(w, ",{h}"),
                None => write!(w, ",nan"),
            }
            .map_err(fail)?;
        }
        writeln!(w).map_err(fail)?;
    }
    w.flush().map_err(fail)
}

/// A number that may be unknown: `nan` or an empty field give None; anything else must be a
/// finite number.
pub(crate) fn parse_optional_number(
    path: &Path,
    line: Option<u64>,
    field: &str,
    raw: &str,
) -> Result<Option<f64>, RecordingError> {
    let t = raw.trim();
    if t.is_empty() || t.eq_ignore_ascii_case("nan") {
        return Ok(None);
    }
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(Some(v)),
        _ => Err(RecordingError::at(
            path,
            line,
            Some(field),
            format!("`{t}` is not a finite number (write nan for unknown)"),
        )),
    }
}

fn check_relative_path(path: &Path, line: u64, file: &str) -> Result<(), RecordingError> {
    let p = Path::new(file);
    let bad = file.is_empty()
        || p.components()
            .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir));
    if bad {
        return Err(RecordingError::new(
            path,
            format!("`{file}` must be a relative path inside the recording folder"),
        )
        .at_line(line)
        .field("file"));
    }
    Ok(())
}

/// Parses `frames.csv` from any reader; `path` is used in error messages.
pub fn parse_frames_csv(
    path: &Path,
    reader: impl std::io::Read,
) -> Result<(Vec<FrameRecord>, TruthColumns), RecordingError> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(false)
        .trim(csv::Trim::All)
        .from_reader(reader);
    let csv_err = |e: csv::Error| RecordingError::csv(path, &e);
    let headers = rdr.headers().map_err(csv_err)?.clone();
    let find = |name: &str| -> Result<Option<usize>, RecordingError> {
        let hits: Vec<usize> = headers
            .iter()
            .enumerate()
            .filter(|(_, h)| *h == name)
            .map(|(i, _)| i)
            .collect();
        match hits.len() {
            0 => Ok(None),
            1 => Ok(Some(hits[0])),
            _ => Err(RecordingError::new(path, "column appears more than once")
                .at_line(1)
                .field(name)),
        }
    };
    let required = |name: &str| -> Result<usize, RecordingError> {
        find(name)?.ok_or_else(|| {
            RecordingError::new(path, "required column missing from the header")
                .at_line(1)
                .field(name)
        })
    };
    let (c_index, c_ts, c_file) = (required("index")?, required("timestamp_ns")?, required("file")?);
    let mut truth_cols = [None; TRUTH_COLUMNS.len()];
    for (i, name) in TRUTH_COLUMNS.iter().enumerate() {
        truth_cols[i] = find(name)?;
    }
    let mut frames = Vec::new();
    let mut record = csv::StringRecord::new();
    let mut prev: Option<(u64, u64)> = None;
    while rdr.read_record(&mut record).map_err(csv_err)? {
        let line = record.position().map(|p| p.line()).unwrap_or(0);
        if frames.len() == MAX_RECORDING_FRAMES {
            return Err(RecordingError::new(
                path,
                format!("more than {MAX_RECORDING_FRAMES} frames, the most deckwatch reads"),
            )
            .at_line(line));
        }
        let get = |c: usize| record.get(c).unwrap_or("");
        let index: u64 = get(c_index).parse().map_err(|_| {
            RecordingError::new(path, format!("`{}` is not a non-negative integer", get(c_index)))
                .at_line(line)
                .field("index")
        })?;
        let timestamp_ns: u64 = get(c_ts).parse().map_err(|_| {
            RecordingError::new(
                path,
                format!("`{}` is not a non-negative integer (nanoseconds)", get(c_ts)),
            )
            .at_line(line)
            .field("timestamp_ns")
        })?;
        if let Some((pi, pt)) = prev {
            if index <= pi {
                return Err(RecordingError::new(
                    path,
                    format!("{index} does not follow the previous index {pi}"),
                )
                .at_line(line)
                .field("index"));
            }
            if timestamp_ns < pt {
                return Err(RecordingError::new(
                    path,
                    format!("{timestamp_ns} is earlier than the previous frame's {pt}"),
                )
                .at_line(line)
                .field("timestamp_ns"));
            }
        }
        prev = Some((index, timestamp_ns));
        let file = get(c_file).to_string();
        check_relative_path(path, line, &file)?;
        let mut truth = GroundTruth::default();
        for (i, col) in truth_cols.iter().enumerate() {
            if let Some(c) = col {
                truth.set(
                    i,
                    parse_optional_number(path, Some(line), TRUTH_COLUMNS[i], get(*c))?,
                );
            }
        }
        frames.push(FrameRecord {
            index,
            timestamp_ns,
            file,
            truth,
            line,
        });
    }
    Ok((frames, truth_cols.map(|c| c.is_some())))
}

// ---------------------------------------------------------------------------------------------
// PNG

// ---------------------------------------------------------------------------------------------
// Writer

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::Rpy;

    fn parse(text: &str) -> Result<(Vec<FrameRecord>, TruthColumns), RecordingError> {
        parse_frames_csv(Path::new("rec/frames.csv"), text.as_bytes())
    }

    /// Each file of a recording folder beyond its bound (a sparse 10 GB file) is refused from
    /// its size, unread, naming the file and the bound; a line beyond its bound names its line.
    #[test]
    fn files_beyond_their_bounds_are_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        let rec_dir = dir.path().join("rec");
        let cam = CameraModel::rpi_v2().scaled_to(64, 48);
        let mut w = RecordingWriter::create(&rec_dir, &cam, &DeckLayout::paper(), NO_TRUTH).unwrap();
        w.write_frame(0, 0, GrayImage::new(64, 48).view(), &GroundTruth::default())
            .unwrap();
        w.finish().unwrap();
        write_vehicle_csv(&rec_dir, &[]).unwrap();
        Recording::open(&rec_dir).unwrap();
        let sparse = |name: &str| {
            let path = rec_dir.join(name);
            let keep = std::fs::read(&path).unwrap();
            File::create(&path).unwrap().set_len(10 << 30).unwrap();
            let e = Recording::open(&rec_dir).unwrap_err().to_string();
            std::fs::write(&path, keep).unwrap();
            assert!(e.contains(&path.display().to_string()), "{e}");
            assert!(e.contains("10737418240 bytes"), "{e}");
            e
        };
        assert!(sparse(CAMERA_FILE).contains("1048576 bytes"));
        assert!(sparse(FRAMES_FILE).contains(&format!("{MAX_FRAMES_CSV_BYTES} bytes")));
        assert!(sparse(VEHICLE_FILE).contains(&format!("{MAX_VEHICLE_CSV_BYTES} bytes")));
        Recording::open(&rec_dir).unwrap();
        // One line of a megabyte, in a file well within its bound.
        let frames = rec_dir.join(FRAMES_FILE);
        let mut text = std::fs::read_to_string(&frames).unwrap();
        text += &format!("1,1,{}\n", "f".repeat(1 << 20));
        std::fs::write(&frames, text).unwrap();
        let e = Recording::open(&rec_dir).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}:3: a line longer than 65536 bytes", frames.display())),
            "{e}"
        );
    }

    #[test]
    fn round_trip_with_truth_and_no_deck_frames() {
        let dir = tempfile::tempdir().unwrap();
        let rec_dir = dir.path().join("rec");
        let cam = CameraModel::rpi_v2().scaled_to(64, 48);
        let deck = DeckLayout::paper();
        let mut w = RecordingWriter::create(&rec_dir, &cam, &deck, ALL_TRUTH).unwrap();
        let mut img = GrayImage::new(64, 48);
        for (i, px) in img.data.iter_mut().enumerate() {
            *px = (i * 7 % 251) as u8;
        }
        let t0 = GroundTruth {
            roll_deg: Some(0.1 + 0.2),
            pitch_deg: Some(-7.25),
            yaw_deg: Some(1e-17),
            alt_m: Some(5.0),
            offset_x_m: Some(0.3),
            offset_y_m: Some(-0.3),
            vehicle_roll_deg: Some(4.5),
            vehicle_pitch_deg: Some(-1.0 / 3.0),
            vehicle_yaw_deg: Some(170.0),
            vehicle_height_m: Some(6.25),
            deck_heave_m: Some(-0.75),
            vehicle_rate_x_dps: Some(12.5),
            vehicle_rate_y_dps: Some(-0.1),
            vehicle_rate_z_dps: Some(3e-5),
        };
        let t1 = GroundTruth {
            alt_m: Some(5.5),
            ..GroundTruth::default()
        };
        w.write_frame(0, 1_000, img.view(), &t0).unwrap();
        w.write_frame(3, 2_000, img.view(), &t1).unwrap();
        // Out of order frames are refused.
        assert!(w.write_frame(3, 3_000, img.view(), &t1).is_err());
        assert!(w.write_frame(4, 1_999, img.view(), &t1).is_err());
        assert_eq!(w.finish().unwrap(), 2);

        let rec = Recording::open(&rec_dir).unwrap();
        assert_eq!(rec.camera, cam);
        assert_eq!(rec.deck, deck);
        assert!(rec.has_attitude_truth());
        assert_eq!(rec.frames.len(), 2);
        assert_eq!(rec.frames[0].truth, t0, "floats round-trip exactly");
        assert_eq!(rec.truth_columns, ALL_TRUTH);
        assert!(rec.frames[0].truth.vehicle_attitude().is_some());
        assert!(rec.frames[1].truth.vehicle_attitude().is_none(), "nan: unknown");
        assert_eq!(rec.frames[1].truth, t1);
        assert!(rec.frames[1].truth.attitude().is_none(), "nan attitude = no deck");
        assert_eq!(rec.frames[1].index, 3);
        assert_eq!(rec.read_image(&rec.frames[1]).unwrap(), img);
        // A second writer refuses to overwrite.
        assert!(RecordingWriter::create(&rec_dir, &cam, &deck, LEVEL_TRUTH).is_err());
    }

    #[test]
    fn strided_images_are_written_row_by_row() {
        let dir = tempfile::tempdir().unwrap();
        let cam = CameraModel::rpi_v2().scaled_to(5, 3);
        let mut w = RecordingWriter::create(dir.path(), &cam, &DeckLayout::paper(), NO_TRUTH).unwrap();
        let buf: Vec<u8> = (0..8 * 3).map(|i| i as u8).collect();
        let view = GrayView::new(&buf, 5, 3, 8).unwrap();
        w.write_frame(0, 0, view, &GroundTruth::default()).unwrap();
        w.finish().unwrap();
        let rec = Recording::open(dir.path()).unwrap();
        assert!(!rec.has_attitude_truth());
        let img = rec.read_image(&rec.frames[0]).unwrap();
        assert_eq!(img.data, [0, 1, 2, 3, 4, 8, 9, 10, 11, 12, 16, 17, 18, 19, 20]);
    }

    #[test]
    fn columns_in_any_order_and_extra_columns_ignored() {
        let (frames, cols) =
            parse("file,comment,timestamp_ns,index,yaw_deg\na.png,hi,10,0,nan\nb.png,,20,1,2.5\n").unwrap();
        assert_eq!(
            cols,
            [
                false, false, true, false, false, false, false, false, false, false, false, false, false,
                false
            ]
        );
        assert_eq!(frames[1].file, "b.png");
        assert_eq!(frames[1].truth.yaw_deg, Some(2.5));
        assert_eq!(frames[0].truth.yaw_deg, None);
        assert_eq!(frames[1].line, 3);
    }

    #[test]
    fn vehicle_csv_round_trips_and_errors_name_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        let q = Quaternion::from_matrix(&Rpy::from_degrees(3.0, -2.0, 17.0).to_matrix());
        let mut samples = vec![
            VehicleStateSample::attitude(0, Quaternion::IDENTITY),
            VehicleStateSample::attitude(10_000_000, q),
        ];
        write_vehicle_csv(dir.path(), &samples).unwrap();
        let path = dir.path().join(VEHICLE_FILE);
        assert_eq!(read_vehicle_csv(&path).unwrap(), samples);
        // With heights: the column is written, an unknown one as `nan`.
        samples[1].height_m = Some(-12.125);
        write_vehicle_csv(dir.path(), &samples).unwrap();
        assert!(std::fs::read_to_string(&path)
            .unwrap()
            .contains(",height_m\n0,1,0,0,0,nan\n"));
        assert_eq!(read_vehicle_csv(&path).unwrap(), samples);
        for (text, line, column) in [
            ("timestamp_ns,qw,qx,qy\n", 1, None),
            (
                "timestamp_ns,qw,qx,qy,qz\n5,1,0,0,0\n5,1,0,0,0\n",
                3,
                Some("timestamp_ns"),
            ),
            ("timestamp_ns,qw,qx,qy,qz\nx,1,0,0,0\n", 2, Some("timestamp_ns")),
            ("timestamp_ns,qw,qx,qy,qz\n5,2,0,0,0\n", 2, Some("qw")),
            ("timestamp_ns,qw,qx,qy,qz\n5,1,0,nan,0\n", 2, Some("qy")),
            (
                "timestamp_ns,qw,qx,qy,qz,height_m\n5,1,0,0,0,up\n",
                2,
                Some("height_m"),
            ),
        ] {
            std::fs::write(&path, text).unwrap();
            let e = read_vehicle_csv(&path).unwrap_err();
            assert_eq!((e.line, e.field.as_deref()), (Some(line), column), "{text}: {e}");
            assert!(e.to_string().contains(VEHICLE_FILE), "{e}");
        }
    }

    #[test]
    fn csv_errors_name_line_and_field() {
        let msg = |t: &str| parse(t).unwrap_err().to_string();
        let e = msg("index,file\n0,a.png\n");
        assert!(
            e.contains("rec/frames.csv:1: field `timestamp_ns`: required column"),
            "{e}"
        );
        let e = msg("index,timestamp_ns,file,roll_deg\n0,5,a.png,1\n1,6,b.png,abc\n");
        assert!(
            e.contains(":3: field `roll_deg`: `abc` is not a finite number"),
            "{e}"
        );
        let e = msg("index,timestamp_ns,file\n0,5,a.png\n0,6,b.png\n");
        assert!(e.contains(":3: field `index`"), "{e}");
        let e = msg("index,timestamp_ns,file\n0,5,a.png\n1,4,b.png\n");
        assert!(e.contains(":3: field `timestamp_ns`"), "{e}");
        let e = msg("index,timestamp_ns,file\n-1,5,a.png\n");
        assert!(e.contains(":2: field `index`"), "{e}");
        let e = msg("index,timestamp_ns,file\n0,5,../etc/passwd\n");
        assert!(e.contains(":2: field `file`"), "{e}");
        let e = msg("index,timestamp_ns,file\n0,5,/abs.png\n");
        assert!(e.contains(":2: field `file`"), "{e}");
        let e = msg("index,timestamp_ns,file\n0,5,a.png,extra\n");
        assert!(e.contains("rec/frames.csv:2"), "{e}");
        let e = msg("index,timestamp_ns,file,index\n");
        assert!(e.contains("field `index`: column appears more than once"), "{e}");
        let e = msg("index,timestamp_ns,file,alt_m\n0,5,a.png,inf\n");
        assert!(e.contains("field `alt_m`"), "{e}");
    }

    #[test]
    fn camera_json_errors_name_the_field() {
        let good = {
            let dir = tempfile::tempdir().unwrap();
            write_camera_json(dir.path(), &CameraModel::paper(), &DeckLayout::paper()).unwrap();
            std::fs::read_to_string(dir.path().join(CAMERA_FILE)).unwrap()
        };
        let p = Path::new("rec/camera.json");
        let (cam, deck) = parse_camera_json(p, &good).unwrap();
        assert_eq!(cam, CameraModel::paper());
        assert_eq!(deck, DeckLayout::paper());
        // Unknown keys are ignored.
        let extra = good.replacen('{', "{\n  \"sensor\": \"imx219\",", 1);
        assert!(parse_camera_json(p, &extra).is_ok());
        let e = parse_camera_json(p, &good.replace("\"fx\"", "\"focal\""))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("missing field `fx`") && e.starts_with("rec/camera.json"),
            "{e}"
        );
        let e = parse_camera_json(p, &good.replace("\"width\": 3280", "\"width\": \"wide\"")).unwrap_err();
        assert_eq!(e.line, Some(2), "{e}");
        let e = parse_camera_json(p, &good.replace("\"n_ring\": 8", "\"n_ring\": 7"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`n_ring`"), "{e}");
        let e = parse_camera_json(
            p,
            &good.replace("\"ring_radius_m\": 0.5", "\"ring_radius_m\": 0.6"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("field `deck.markers_deck_xyz_m[1]`"), "{e}");
        let mut cam = CameraModel::paper();
        cam.fx = 0.0;
        let dir = tempfile::tempdir().unwrap();
        write_camera_json(dir.path(), &cam, &DeckLayout::paper()).unwrap();
        let e = read_camera_json(dir.path()).unwrap_err().to_string();
        assert!(e.contains("field `fx`"), "{e}");
        let e = parse_camera_json(
            p,
            &good.replacen("0.0,\n    0.0,\n    0.0,\n    0.0,\n    0.0", "0.0", 1),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("field `distortion`"), "{e}");
    }

    #[test]
    fn bad_images_are_reported_with_their_file() {
        let dir = tempfile::tempdir().unwrap();
        let cam = CameraModel::rpi_v2().scaled_to(4, 4);
        let mut w = RecordingWriter::create(dir.path(), &cam, &DeckLayout::paper(), NO_TRUTH).unwrap();
        let img = GrayImage::new(4, 4);
        w.write_frame(0, 0, img.view(), &GroundTruth::default()).unwrap();
        w.write_frame(1, 1, img.view(), &GroundTruth::default()).unwrap();
        w.write_frame(2, 2, img.view(), &GroundTruth::default()).unwrap();
        w.finish().unwrap();
        // Corrupt one image, make another the wrong size, remove the third.
        std::fs::write(dir.path().join("frames/000000.png"), b"not a png").unwrap();
        let small = GrayImage::new(2, 2);
        encode_gray_png(&dir.path().join("frames/000001.png"), small.view()).unwrap();
        std::fs::remove_file(dir.path().join("frames/000002.png")).unwrap();
        let rec = Recording::open(dir.path()).unwrap();
        let e = rec.read_image(&rec.frames[0]).unwrap_err().to_string();
        assert!(
            e.contains("000000.png") && e.contains("not a readable PNG"),
            "{e}"
        );
        let e = rec.read_image(&rec.frames[1]).unwrap_err().to_string();
        assert!(e.contains("000001.png") && e.contains("2x2"), "{e}");
        let e = rec.read_image(&rec.frames[2]).unwrap_err().to_string();
        assert!(e.contains("000002.png"), "{e}");
        // Missing folder and missing camera.json.
        assert!(Recording::open(dir.path().join("nope")).is_err());
        std::fs::remove_file(dir.path().join(CAMERA_FILE)).unwrap();
        let e = Recording::open(dir.path()).unwrap_err().to_string();
        assert!(e.contains("camera.json"), "{e}");
    }
}
