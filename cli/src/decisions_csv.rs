//! The decisions CSV (`--decisions FILE` of `deckwatch run`, `latency` and `inproc`): one row per
//! landing decision with its stage timestamps, attitude, truth and drop counts. Angles are
//! written in full (shortest round-trip form), so two runs can be compared bit for bit.

use deckwatch_common::messages::LandingDecision;
use std::io::Write;
use std::path::{Path, PathBuf};

pub const HEADER: &str = "seq,source_index,captured_ns,published_ns,detect_received_ns,detect_finished_ns,\
estimate_received_ns,estimate_finished_ns,decide_received_ns,decide_finished_ns,state,reason,valid,\
roll_deg,pitch_deg,yaw_deg,truth_roll_deg,truth_pitch_deg,truth_yaw_deg,markers,\
drops_capture,drops_bad,drops_detect,drops_estimate,drops_decide,calm_start_s,calm_length_s,watchdog,\
deck_height_m,truth_heave_m,heave_rate_mps";

/// A decisions CSV being written.
pub struct DecisionsCsv {
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl DecisionsCsv {
    pub fn create(path: &Path) -> Result<Self, String> {
        let f = std::fs::File::create(path).map_err(|e| format!("{}: cannot create: {e}", path.display()))?;
        let mut out = std::io::BufWriter::new(f);
        writeln!(out, "{HEADER}").map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            out,
        })
    }

    /// Appends a decision's row (flushed: a crash loses nothing written before it).
    pub fn write(&mut self, d: &LandingDecision) -> Result<(), String> {
        let (a, dr, t, tr) = (&d.attitude, d.stamp.drops, d.stamp.times, &d.context.truth);
        let [r, p, y] = if a.valid.get() {
            a.rpy.to_degrees()
        } else {
            [f64::NAN; 3]
        };
        writeln!(
            self.out,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{r},{p},{y},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            d.stamp.seq,
            d.context.source_index,
            t.captured_ns,
            t.published_ns,
            t.detect_received_ns,
            t.detect_finished_ns,
            t.estimate_received_ns,
            t.estimate_finished_ns,
            t.decide_received_ns,
            t.decide_finished_ns,
            d.state.get().name(),
            d.reason.get().name(),
            a.valid.get() as u8,
            tr.roll_deg,
            tr.pitch_deg,
            tr.yaw_deg,
            a.markers_used,
            dr.capture,
            dr.bad_frames,
            dr.detect,
            dr.estimate,
            dr.decide,
            d.calm_window_start_s,
            d.calm_window_length_s,
            d.watchdog.get() as u8,
            if a.valid.get() { a.deck_height_m } else { f64::NAN },
            tr.deck_heave_m,
            d.heave_rate_mps
        )
        .and_then(|_| self.out.flush())
        .map_err(|e| format!("{}: {e}", self.path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::Rpy;

    #[test]
    fn rows_round_trip_the_angles_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.csv");
        let mut w = DecisionsCsv::create(&p).unwrap();
        let mut d = LandingDecision::default();
        d.attitude.valid = true.into();
        d.attitude.rpy = Rpy::from_degrees(1.0 / 3.0, -2.0e-7, 179.123456789);
        w.write(&d).unwrap();
        drop(w);
        let text = std::fs::read_to_string(&p).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let row: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(header.len(), row.len());
        let col = |name: &str| row[header.iter().position(|h| *h == name).unwrap()];
        for (name, v) in ["roll_deg", "pitch_deg", "yaw_deg"]
            .iter()
            .zip(d.attitude.rpy.to_degrees())
        {
            assert_eq!(col(name).parse::<f64>().unwrap().to_bits(), v.to_bits(), "{name}");
        }
        assert_eq!(col("state"), "NO-DECK");
    }
}
