//! The marker table: one CSV row per frame with the markers' pixel centres, in marker-index order.
//! It is what the offline capture and estimate tools exchange (`deckwatch-capture | deckwatch-estimate`)
//! and what an engineer with detections of their own (OpenCV, a hand-labelled image) feeds in.
//!
//! Columns: `index,timestamp_ns,alt_m,m0_u,m0_v,m1_u,m1_v,...` (alt_m = altimeter, `nan` when
//! unknown; `nan` for a marker not seen), then optionally the ground truth columns of the
//! recording format (`roll_deg,pitch_deg,yaw_deg,offset_x_m,offset_y_m`); further columns are
//! ignored. Errors name the source, line and column.

use crate::recording::{GroundTruth, RecordingError};
pub use deckwatch_common::markers::MarkerRow;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

fn u_col(i: usize) -> String {
    format!("m{i}_u")
}
fn v_col(i: usize) -> String {
    format!("m{i}_v")
}

fn fmt(v: Option<f64>) -> String {
    v.map_or_else(|| "nan".into(), |x| format!("{x:?}"))
}

/// Writes marker rows as CSV.
pub struct MarkerTableWriter<W: Write> {
    csv: csv::Writer<W>,
    n_markers: usize,
}

impl<W: Write> MarkerTableWriter<W> {
    pub fn new(out: W, n_markers: usize) -> std::io::Result<Self> {
        let mut csv = csv::Writer::from_writer(out);
        let mut header = vec!["index".to_string(), "timestamp_ns".into(), "alt_m".into()];
        for i in 0..n_markers {
            header.push(u_col(i));
            header.push(v_col(i));
        }
        for c in ["roll_deg", "pitch_deg", "yaw_deg", "offset_x_m", "offset_y_m"] {
            header.push(c.into());
        }
        csv.write_record(&header)?;
        Ok(Self { csv, n_markers })
    }

    pub fn write(&mut self, row: &MarkerRow) -> std::io::Result<()> {
        assert_eq!(row.markers.len(), self.n_markers, "marker count");
        let t = &row.truth;
        let mut rec = vec![row.index.to_string(), row.timestamp_ns.to_string(), fmt(t.alt_m)];
        for m in &row.markers {
            rec.push(fmt(m.map(|p| p[0])));
            rec.push(fmt(m.map(|p| p[1])));
        }
        for v in [t.roll_deg, t.pitch_deg, t.yaw_deg, t.offset_x_m, t.offset_y_m] {
            rec.push(fmt(v));
        }
        self.csv.write_record(&rec)?;
        Ok(())
    }

    pub fn flush(&mut self) -> std::io::Result<()> {
        self.csv.flush()
    }
}

/// The largest marker table read from a file (bytes): a row of 20 markers with its truth is
/// ~1 KB, so this is ten hours at 30 fps. Rows are streamed (what is held is a line, at most
/// [`MAX_CSV_LINE_BYTES`](crate::recording::MAX_CSV_LINE_BYTES)); the bound stops a file that
/// never ends.
pub const MAX_MARKER_TABLE_BYTES: u64 = 1 << 30;

/// A marker table file opened for [`MarkerTableReader`], within its bounds (its size,
/// [`MAX_MARKER_TABLE_BYTES`], checked before it is read; each line's).
pub fn open_marker_table(path: &Path) -> Result<deckwatch_common::files::BoundedFile, RecordingError> {
    Ok(
        deckwatch_common::files::open_bounded(path, MAX_MARKER_TABLE_BYTES)?
            .with_max_line_bytes(crate::recording::MAX_CSV_LINE_BYTES),
    )
}

/// Reads marker rows from CSV, one at a time (so a pipe streams).
pub struct MarkerTableReader<R: Read> {
    source: PathBuf,
    csv: csv::Reader<R>,
    n_markers: usize,
    cols: Vec<(usize, usize)>,
    index_col: usize,
    ts_col: usize,
    truth_cols: [Option<usize>; crate::recording::TRUTH_COLUMNS.len()],
    record: csv::StringRecord,
}

impl<R: Read> MarkerTableReader<R> {
    /// `source` names the input in error messages (a path, or "stdin").
    pub fn new(source: impl AsRef<Path>, input: R, n_markers: usize) -> Result<Self, RecordingError> {
        let source = source.as_ref().to_path_buf();
        let mut csv = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(input);
        let headers = csv
            .headers()
            .map_err(|e| RecordingError::csv(&source, &e))?
            .clone();
        let col = |name: &str| headers.iter().position(|h| h == name);
        let need = |name: &str| {
            col(name).ok_or_else(|| {
                RecordingError::at(
                    &source,
                    Some(1),
                    Some(name),
                    "required column missing from the header",
                )
            })
        };
        let index_col = need("index")?;
        let ts_col = need("timestamp_ns")?;
        let mut cols = Vec::with_capacity(n_markers);
        for i in 0..n_markers {
            cols.push((need(&u_col(i))?, need(&v_col(i))?));
        }
        let truth_cols = crate::recording::TRUTH_COLUMNS.map(col);
        Ok(Self {
            source,
            csv,
            n_markers,
            cols,
            index_col,
            ts_col,
            truth_cols,
            record: csv::StringRecord::new(),
        })
    }

    /// The next row; None at the end of the input.
    pub fn next_row(&mut self) -> Option<Result<MarkerRow, RecordingError>> {
        match self.csv.read_record(&mut self.record) {
            Ok(false) => None,
            Err(e) => Some(Err(RecordingError::csv(&self.source, &e))),
            Ok(true) => Some(self.parse()),
        }
    }

    fn parse(&self) -> Result<MarkerRow, RecordingError> {
        let r = &self.record;
        let line = r.position().map(|p| p.line());
        let src = &self.source;
        let int = |c: usize, name: &str| -> Result<u64, RecordingError> {
            let s = r.get(c).unwrap_or("");
            s.parse().map_err(|_| {
                RecordingError::at(
                    src,
                    line,
                    Some(name),
                    format!("`{s}` is not a non-negative integer"),
                )
            })
        };
        let num = |c: usize, name: &str| -> Result<Option<f64>, RecordingError> {
            crate::recording::parse_optional_number(src, line, name, r.get(c).unwrap_or(""))
        };
        let mut markers = Vec::with_capacity(self.n_markers);
        for (i, &(cu, cv)) in self.cols.iter().enumerate() {
            let u = num(cu, &u_col(i))?;
            let v = num(cv, &v_col(i))?;
            markers.push(match (u, v) {
                (Some(u), Some(v)) => Some([u, v]),
                (None, None) => None,
                _ => {
                    return Err(RecordingError::at(
                        src,
                        line,
                        Some(&u_col(i)),
                        format!("marker {i} has only one of u and v"),
                    ))
                }
            });
        }
        let mut truth = GroundTruth::default();
        for (k, c) in self.truth_cols.iter().enumerate() {
            if let Some(c) = c {
                truth.set(k, num(*c, crate::recording::TRUTH_COLUMNS[k])?);
            }
        }
        Ok(MarkerRow {
            index: int(self.index_col, "index")?,
            timestamp_ns: int(self.ts_col, "timestamp_ns")?,
            markers,
            truth,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sparse marker table beyond its bound is refused from its size; a line beyond its bound
    /// is a bad row at its line, and the file ends there.
    #[test]
    fn a_table_beyond_its_bounds_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("huge.csv");
        std::fs::File::create(&path).unwrap().set_len(10 << 30).unwrap();
        let e = open_marker_table(&path).err().unwrap().to_string();
        assert!(e.contains("huge.csv") && e.contains("10737418240 bytes"), "{e}");
        assert!(e.contains(&format!("{MAX_MARKER_TABLE_BYTES} bytes")), "{e}");
        let text = format!("index,timestamp_ns,alt_m\n0,0,{}\n1,1,nan\n", "9".repeat(1 << 17));
        std::fs::write(&path, text).unwrap();
        let mut table = MarkerTableReader::new(&path, open_marker_table(&path).unwrap(), 0).unwrap();
        let e = table.next_row().unwrap().unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}:2: a line longer than", path.display())),
            "{e}"
        );
        assert!(table.next_row().is_none());
    }

    #[test]
    fn round_trip() {
        let rows = vec![
            MarkerRow {
                index: 0,
                timestamp_ns: 100,
                markers: vec![Some([1.5, 2.25]), None, Some([1e-17, 3279.5])],
                truth: GroundTruth {
                    roll_deg: Some(1.0),
                    pitch_deg: Some(-2.0),
                    yaw_deg: Some(0.1 + 0.2),
                    alt_m: Some(5.0),
                    offset_x_m: None,
                    offset_y_m: Some(0.3),
                    ..GroundTruth::default()
                },
            },
            MarkerRow {
                index: 1,
                timestamp_ns: 200,
                markers: vec![None; 3],
                truth: GroundTruth::default(),
            },
        ];
        let mut buf = Vec::new();
        {
            let mut w = MarkerTableWriter::new(&mut buf, 3).unwrap();
            for r in &rows {
                w.write(r).unwrap();
            }
            w.flush().unwrap();
        }
        let mut rd = MarkerTableReader::new("mem", buf.as_slice(), 3).unwrap();
        let mut back = Vec::new();
        while let Some(r) = rd.next_row() {
            back.push(r.unwrap());
        }
        assert_eq!(back, rows);
    }

    #[test]
    fn errors_name_line_and_column() {
        let e = MarkerTableReader::new("in.csv", "index,timestamp_ns,m0_u,m0_v\n".as_bytes(), 2)
            .err()
            .unwrap()
            .to_string();
        assert_eq!(
            e,
            "in.csv:1: field `m1_u`: required column missing from the header"
        );
        let text = "index,timestamp_ns,m0_u,m0_v\n0,1,2,3\n1,2,x,3\n";
        let mut rd = MarkerTableReader::new("in.csv", text.as_bytes(), 1).unwrap();
        assert!(rd.next_row().unwrap().is_ok());
        let e = rd.next_row().unwrap().unwrap_err().to_string();
        assert!(e.starts_with("in.csv:3: field `m0_u`"), "{e}");
        let text = "index,timestamp_ns,m0_u,m0_v\n0,1,2,nan\n";
        let mut rd = MarkerTableReader::new("in.csv", text.as_bytes(), 1).unwrap();
        let e = rd.next_row().unwrap().unwrap_err().to_string();
        assert!(e.contains("only one of u and v"), "{e}");
    }
}
