//! Ship motion from a file: what a ship's own motion sensor recorded, replayed as the deck's
//! motion (`--motion-csv` of `decide-eval`, `predict-eval` and `trials`).
//!
//! The file is CSV with a header naming the columns `time_s`, `roll_deg`, `pitch_deg`,
//! `heave_m` and optionally `yaw_deg`, in any order. Angles are the deck's attitude in W, the
//! roll/pitch/yaw of docs/recording.md's "Recording format" (the ground truth's convention); heave is the deck centre's height (m, up). Times strictly increase
//! and no step is longer than [`MAX_STEP_S`] (at least 10 Hz, not necessarily uniform). Lines
//! starting with `#` and blank lines are skipped. Between samples the motion is a cubic
//! Hermite curve whose slopes are the neighbours' finite differences, so rates are continuous.
//! [`write_motion_csv`] writes the same format (all five columns, `deckwatch sim motion`),
//! checking each value by the reader's rules.

use crate::motion::{MotionProfile, MotionSample, TrackingError};
use deckwatch_common::Rpy;
use std::path::Path;

/// The longest step between two samples (s): 10 Hz with 10 % jitter.
pub const MAX_STEP_S: f64 = 0.11;

/// The largest motion file read (bytes): a row is ~60 bytes, so a 30-minute series at 50 Hz
/// is ~5 MB and this bound holds six hours at 50 Hz; larger is no ship's motion record.
pub const MAX_MOTION_FILE_BYTES: u64 = 64 << 20;

/// A motion file that cannot be used: where (line and column, counted from 1; 0 for the file
/// as a whole) and what.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{line}:{column}: {problem}")]
pub struct MotionFileError {
    pub file: String,
    pub line: usize,
    pub column: usize,
    pub problem: String,
}

/// The deck's motion as recorded, between its first and last sample.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedShipMotion {
    t: Vec<f64>,
    /// roll, pitch, yaw (deg), heave (m) per sample.
    v: Vec<[f64; 4]>,
    pub tracking: TrackingError,
}

const COLUMNS: [&str; 5] = ["time_s", "roll_deg", "pitch_deg", "heave_m", "yaw_deg"];

/// Whether `x` can be column `c` of [`COLUMNS`]: finite and within its range (deg, m, s).
fn check_value(c: usize, x: f64) -> Result<(), String> {
    let limit = match c {
        0 => 1e9,
        1..=2 => 90.0,
        3 => 100.0,
        _ => 360.0,
    };
    if x.is_finite() && x.abs() <= limit {
        Ok(())
    } else {
        Err(format!(
            "{} = {x} is not a finite value within +-{limit}",
            COLUMNS[c]
        ))
    }
}

/// Whether a sample at `t_s` may follow one at `previous_s`: later, by at most [`MAX_STEP_S`].
fn check_step(previous_s: f64, t_s: f64) -> Result<(), String> {
    let step = t_s - previous_s;
    if !(step > 0.0) {
        return Err(format!("time {t_s} does not follow {previous_s}"));
    }
    if step > MAX_STEP_S {
        return Err(format!(
            "{step:.3} s after the sample before: the motion must be sampled at 10 Hz or faster (steps up to {MAX_STEP_S} s)"
        ));
    }
    Ok(())
}

impl RecordedShipMotion {
    /// Reads a motion file.
    pub fn load(path: &Path) -> Result<Self, MotionFileError> {
        let name = path.display().to_string();
        let text =
            deckwatch_common::files::read_bounded_to_string(path, MAX_MOTION_FILE_BYTES).map_err(|e| {
                MotionFileError {
                    file: name.clone(),
                    line: e.line().unwrap_or(0) as usize,
                    column: 0,
                    problem: e.problem(),
                }
            })?;
        Self::parse(&text, &name)
    }

    /// Parses the text of a motion file named `file` (for the errors).
    pub fn parse(text: &str, file: &str) -> Result<Self, MotionFileError> {
        let error = |line: usize, column: usize, problem: String| MotionFileError {
            file: file.to_string(),
            line,
            column,
            problem,
        };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let (header_line, header) = lines.next().ok_or_else(|| {
            error(
                0,
                0,
                "empty: no header (time_s,roll_deg,pitch_deg,heave_m)".into(),
            )
        })?;
        // Which field holds each column.
        let mut index = [None; 5];
        for (i, name) in header.split(',').map(str::trim).enumerate() {
            let Some(c) = COLUMNS.iter().position(|c| *c == name) else {
                return Err(error(
                    header_line,
                    i + 1,
                    format!("unknown column `{name}` (time_s, roll_deg, pitch_deg, heave_m, yaw_deg)"),
                ));
            };
            if index[c].is_some() {
                return Err(error(header_line, i + 1, format!("column `{name}` twice")));
            }
            index[c] = Some(i);
        }
        for (c, name) in COLUMNS.iter().enumerate().take(4) {
            if index[c].is_none() {
                return Err(error(header_line, 0, format!("no `{name}` column")));
            }
        }
        let width = header.split(',').count();
        let (mut t, mut v) = (Vec::new(), Vec::new());
        for (line, row) in lines {
            let fields: Vec<&str> = row.split(',').map(str::trim).collect();
            if fields.len() != width {
                return Err(error(
                    line,
                    0,
                    format!("{} fields, the header has {width}", fields.len()),
                ));
            }
            let mut values = [0.0; 5];
            for (c, value) in values.iter_mut().enumerate() {
                let Some(i) = index[c] else { continue };
                let x: f64 = fields[i]
                    .parse()
                    .map_err(|_| error(line, i + 1, format!("`{}` is not a number", fields[i])))?;
                check_value(c, x).map_err(|problem| error(line, i + 1, problem))?;
                *value = x;
            }
            if let Some(&previous) = t.last() {
                check_step(previous, values[0])
                    .map_err(|problem| error(line, index[0].map_or(0, |i| i + 1), problem))?;
            }
            t.push(values[0]);
            v.push([values[1], values[2], values[4], values[3]]);
        }
        if t.len() < 2 {
            return Err(error(0, 0, "fewer than two samples".into()));
        }
        Ok(Self {
            t,
            v,
            tracking: TrackingError::hover(5.0),
        })
    }

    /// The first and last sample's time (s).
    pub fn span_s(&self) -> (f64, f64) {
        (self.t[0], self.t[self.t.len() - 1])
    }

    /// The recorded motion's length (s).
    pub fn duration_s(&self) -> f64 {
        let (a, b) = self.span_s();
        b - a
    }

    /// The slope of channel `c` at sample `i` (finite differences of the neighbours).
    fn slope(&self, i: usize, c: usize) -> f64 {
        let n = self.t.len();
        let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
        (self.v[b][c] - self.v[a][c]) / (self.t[b] - self.t[a])
    }

    /// roll, pitch, yaw (deg) and heave (m) at `t_s` after the first sample (held beyond the
    /// ends).
    pub fn at(&self, t_s: f64) -> [f64; 4] {
        let t = (self.t[0] + t_s).clamp(self.t[0], self.t[self.t.len() - 1]);
        let i = self.t.partition_point(|&x| x <= t).clamp(1, self.t.len() - 1) - 1;
        let h = self.t[i + 1] - self.t[i];
        let s = ((t - self.t[i]) / h).clamp(0.0, 1.0);
        let (s2, s3) = (s * s, s * s * s);
        let (h00, h10, h01, h11) = (
            2.0 * s3 - 3.0 * s2 + 1.0,
            s3 - 2.0 * s2 + s,
            -2.0 * s3 + 3.0 * s2,
            s3 - s2,
        );
        [0, 1, 2, 3].map(|c| {
            h00 * self.v[i][c]
                + h10 * h * self.slope(i, c)
                + h01 * self.v[i + 1][c]
                + h11 * h * self.slope(i + 1, c)
        })
    }
}

/// One sample of a motion file: the deck's attitude in W (deg, CONVENTIONS.md §2) and its
/// centre's height (m, up) at `time_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionRow {
    pub time_s: f64,
    pub roll_deg: f64,
    pub pitch_deg: f64,
    pub yaw_deg: f64,
    pub heave_m: f64,
}

impl MotionRow {
    /// The deck of a simulated sample.
    pub fn of(sample: &MotionSample) -> Self {
        let [roll_deg, pitch_deg, yaw_deg] = sample.attitude.to_degrees();
        Self {
            time_s: sample.t_s,
            roll_deg,
            pitch_deg,
            yaw_deg,
            heave_m: sample.deck_heave_m,
        }
    }

    /// The values in [`COLUMNS`]' order.
    fn values(&self) -> [f64; 5] {
        [
            self.time_s,
            self.roll_deg,
            self.pitch_deg,
            self.heave_m,
            self.yaw_deg,
        ]
    }
}

/// Decimals a written motion file keeps of every value (s, deg, m): it reads back within
/// `0.5e-6` of what was written.
pub const WRITTEN_DECIMALS: usize = 6;

/// The text of a motion file holding `rows` (all five columns), after `comments` (each line of
/// them as a `# ` line, which readers skip): the format [`RecordedShipMotion::parse`] reads. Each
/// value is checked as written (rounded to [`WRITTEN_DECIMALS`]) by the reader's own rules, so
/// what is written is read; `file` names the file in the errors, whose lines are the file's.
pub fn motion_csv_text(
    comments: &[String],
    rows: &[MotionRow],
    file: &str,
) -> Result<String, MotionFileError> {
    let mut text = String::new();
    let mut line = 0;
    for comment in comments {
        for part in comment.lines() {
            text += &format!("# {part}\n");
            line += 1;
        }
    }
    text += &COLUMNS.join(",");
    text.push('\n');
    line += 1;
    let error = |line: usize, column: usize, problem: String| MotionFileError {
        file: file.to_string(),
        line,
        column,
        problem,
    };
    if rows.len() < 2 {
        return Err(error(0, 0, "fewer than two samples".into()));
    }
    let mut previous_s = None;
    for row in rows {
        line += 1;
        let mut fields = Vec::with_capacity(COLUMNS.len());
        for (c, x) in row.values().into_iter().enumerate() {
            let field = format!("{x:.WRITTEN_DECIMALS$}");
            // What the reader will see: the rounded value (NaN and infinities fail its check).
            let written: f64 = field.parse().unwrap_or(f64::NAN);
            check_value(c, written).map_err(|problem| error(line, c + 1, problem))?;
            if c == 0 {
                if let Some(previous_s) = previous_s {
                    check_step(previous_s, written).map_err(|problem| error(line, 1, problem))?;
                }
                previous_s = Some(written);
            }
            fields.push(field);
        }
        text += &fields.join(",");
        text.push('\n');
    }
    Ok(text)
}

/// Writes [`motion_csv_text`] of `rows` to `path`.
pub fn write_motion_csv(path: &Path, comments: &[String], rows: &[MotionRow]) -> Result<(), MotionFileError> {
    let name = path.display().to_string();
    let text = motion_csv_text(comments, rows, &name)?;
    std::fs::write(path, text).map_err(|e| MotionFileError {
        file: name,
        line: 0,
        column: 0,
        problem: format!("cannot write: {e}"),
    })
}

impl MotionProfile for RecordedShipMotion {
    /// Time counts from the file's first sample.
    fn sample(&self, t_s: f64) -> MotionSample {
        let [r, p, y, heave] = self.at(t_s);
        MotionSample {
            t_s,
            attitude: Rpy::from_degrees(r, p, y),
            viewpoint: self.tracking.at(t_s),
            deck_heave_m: heave,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_file_and_interpolates_smoothly() {
        let mut text = String::from("# from the ship's motion sensor\nheave_m,time_s,pitch_deg,roll_deg\n");
        for k in 0..200 {
            let t = 100.0 + k as f64 * 0.1 + if k % 2 == 0 { 0.0 } else { 0.005 };
            text += &format!(
                "{},{t},{},{}\n",
                0.5 * (0.6 * t).sin(),
                (0.5 * t).cos(),
                2.0 * (0.7 * t).sin()
            );
        }
        let m = RecordedShipMotion::parse(&text, "ship.csv").unwrap();
        assert!((m.duration_s() - 19.905).abs() < 1e-9);
        let t = 5.03;
        let [r, p, y, h] = m.at(t);
        let tt = 100.0 + t;
        assert!((r - 2.0 * (0.7 * tt).sin()).abs() < 1e-3, "{r}");
        assert!((p - (0.5 * tt).cos()).abs() < 1e-3);
        assert!((h - 0.5 * (0.6 * tt).sin()).abs() < 1e-3);
        assert_eq!(y, 0.0);
        // Rates by central difference match the truth's (continuous slopes).
        let d = 1e-3;
        let rate = (m.at(t + d)[0] - m.at(t - d)[0]) / (2.0 * d);
        assert!((rate - 1.4 * (0.7 * tt).cos()).abs() < 0.02, "{rate}");
        let s = m.sample(t);
        assert!((s.attitude.to_degrees()[0] - r).abs() < 1e-9 && s.deck_heave_m == h);
    }

    #[test]
    fn a_written_file_reads_back_as_written() {
        // An irrational-ish motion at 25 Hz (steps that are not exact in decimal), with yaw.
        let rows: Vec<MotionRow> = (0..500)
            .map(|k| {
                let t = k as f64 / 25.0;
                MotionRow {
                    time_s: t,
                    roll_deg: 20.0 * (0.61 * t).sin() + 1e-7,
                    pitch_deg: -3.0 * (0.9 * t + 0.3).cos(),
                    yaw_deg: 1.5 * (0.05 * t).sin(),
                    heave_m: 1.2 * (0.7 * t).sin() - 0.4 * (1.3 * t).cos(),
                }
            })
            .collect();
        let comments = vec!["deckwatch sim motion\nsecond line".to_string()];
        let text = motion_csv_text(&comments, &rows, "m.csv").unwrap();
        assert!(text.starts_with("# deckwatch sim motion\n# second line\ntime_s,roll_deg,"));
        let read = RecordedShipMotion::parse(&text, "m.csv").unwrap();
        assert_eq!(read.t.len(), rows.len());
        let tolerance = 0.5e-6 + 1e-12;
        for (k, row) in rows.iter().enumerate() {
            assert!((read.t[k] - row.time_s).abs() <= tolerance);
            // At its own samples the curve is the samples: roll, pitch, yaw, heave.
            let [r, p, y, h] = read.at(read.t[k] - read.t[0]);
            for (got, want) in [
                (r, row.roll_deg),
                (p, row.pitch_deg),
                (y, row.yaw_deg),
                (h, row.heave_m),
            ] {
                assert!((got - want).abs() <= tolerance, "row {k}: {got} vs {want}");
            }
        }
        // Through a file too.
        let path = std::env::temp_dir().join(format!("deckwatch-motion-{}.csv", std::process::id()));
        write_motion_csv(&path, &comments, &rows).unwrap();
        let loaded = RecordedShipMotion::load(&path);
        let _ = std::fs::remove_file(&path);
        assert_eq!(loaded.unwrap(), read);
    }

    #[test]
    fn what_the_reader_would_refuse_is_not_written() {
        let row = |t: f64, roll: f64| MotionRow {
            time_s: t,
            roll_deg: roll,
            pitch_deg: 0.0,
            yaw_deg: 0.0,
            heave_m: 0.0,
        };
        let e = |rows: &[MotionRow]| motion_csv_text(&[], rows, "w.csv").unwrap_err().to_string();
        assert!(e(&[row(0.0, 0.0)]).contains("fewer than two samples"));
        assert!(e(&[row(0.0, 0.0), row(0.1, 91.0)]).contains("w.csv:3:2: roll_deg = 91"));
        assert!(e(&[row(0.0, 0.0), row(0.1, f64::NAN)]).contains("w.csv:3:2"));
        assert!(e(&[row(0.0, 0.0), row(0.2, 0.0)]).contains("w.csv:3:1: 0.200 s after"));
        // Times that round to the same microsecond do not follow each other.
        assert!(e(&[row(0.0, 0.0), row(1e-7, 0.0)]).contains("does not follow"));
        let e = write_motion_csv(
            Path::new("/nonexistent/m.csv"),
            &[],
            &[row(0.0, 0.0), row(0.1, 0.0)],
        );
        assert!(e.unwrap_err().to_string().contains("cannot write"));
    }

    /// A sparse motion file beyond [`MAX_MOTION_FILE_BYTES`] is refused from its size, unread.
    #[test]
    fn a_motion_file_beyond_its_bound_is_refused_unread() {
        let path = std::env::temp_dir().join(format!("deckwatch-huge-motion-{}.csv", std::process::id()));
        std::fs::File::create(&path).unwrap().set_len(10 << 30).unwrap();
        let e = RecordedShipMotion::load(&path);
        let _ = std::fs::remove_file(&path);
        let e = e.unwrap_err().to_string();
        assert!(e.contains("deckwatch-huge-motion-"), "{e}");
        assert!(
            e.contains("10737418240 bytes") && e.contains("67108864 bytes"),
            "{e}"
        );
    }

    #[test]
    fn bad_files_say_where() {
        let e = |text: &str| RecordedShipMotion::parse(text, "f.csv").unwrap_err().to_string();
        assert!(e("").contains("f.csv:0:0: empty"));
        assert!(e("time_s,roll_deg,pitch_deg\n").contains("no `heave_m` column"));
        assert!(e("time_s,roll_deg,pitch_deg,heave_m,speed\n").contains("f.csv:1:5: unknown column `speed`"));
        let head = "time_s,roll_deg,pitch_deg,heave_m\n";
        assert!(e(&format!("{head}0,1,2,0.1\n0.1,x,2,0.1\n")).contains("f.csv:3:2: `x` is not a number"));
        assert!(e(&format!("{head}0,1,2,0.1\n0.1,1,2\n")).contains("f.csv:3:0: 3 fields"));
        assert!(e(&format!("{head}0,1,2,0.1\n0.1,1,95,0.1\n")).contains("f.csv:3:3: pitch_deg = 95"));
        assert!(e(&format!("{head}0,1,2,0.1\n0.1,1,NaN,0.1\n")).contains("f.csv:3:3"));
        assert!(e(&format!("{head}0,1,2,0.1\n0,1,2,0.1\n")).contains("f.csv:3:1: time 0 does not follow 0"));
        assert!(e(&format!("{head}0,1,2,0.1\n0.5,1,2,0.1\n")).contains("f.csv:3:1: 0.500 s after"));
        assert!(e(&format!("{head}0,1,2,0.1\n")).contains("fewer than two samples"));
        let e = RecordedShipMotion::load(Path::new("/nonexistent/ship.csv")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("/nonexistent/ship.csv:0:0: cannot read"),
            "{e}"
        );
    }
}
