//! The decisions CSV (`--decisions FILE` of `deckwatch run`, `latency` and `inproc`): one row per
//! landing decision with its stage timestamps, attitude, truth and drop counts. Angles are
//! written in full (shortest round-trip form), so two runs can be compared bit for bit.

use deckwatch_common::messages::{DropCounts, LandingDecision, StageTimes};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The columns: the stage times and the drop counts named from the stage table
/// (`StageTimes::NAMES`; `drops_<name>` of `DropCounts::NAMES`, the bad frames' `drops_bad`).
pub fn header() -> String {
    let drops = DropCounts::NAMES.map(|n| format!("drops_{}", n.strip_suffix("_frames").unwrap_or(n)));
    format!(
        "seq,source_index,{},state,reason,valid,roll_deg,pitch_deg,yaw_deg,truth_roll_deg,truth_pitch_deg,\
         truth_yaw_deg,markers,{},calm_start_s,calm_length_s,watchdog,deck_height_m,truth_heave_m,\
         heave_rate_mps",
        StageTimes::NAMES.join(","),
        drops.join(",")
    )
}

/// A decisions CSV being written.
pub struct DecisionsCsv {
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl DecisionsCsv {
    pub fn create(path: &Path) -> Result<Self, String> {
        let f = std::fs::File::create(path).map_err(|e| format!("{}: cannot create: {e}", path.display()))?;
        let mut out = std::io::BufWriter::new(f);
        writeln!(out, "{}", header()).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            out,
        })
    }

    /// Appends a decision's row (flushed: a crash loses nothing written before it).
    pub fn write(&mut self, d: &LandingDecision) -> Result<(), String> {
        self.write_row(d)
            .and_then(|_| self.out.flush())
            .map_err(|e| format!("{}: {e}", self.path.display()))
    }

    fn write_row(&mut self, d: &LandingDecision) -> std::io::Result<()> {
        let (a, tr) = (&d.attitude, &d.context.truth);
        let [r, p, y] = if a.valid.get() {
            a.rpy.to_degrees()
        } else {
            [f64::NAN; 3]
        };
        let out = &mut self.out;
        write!(out, "{},{}", d.stamp.seq, d.context.source_index)?;
        for t in d.stamp.times.values() {
            write!(out, ",{t}")?;
        }
        write!(
            out,
            ",{},{},{},{r},{p},{y},{},{},{},{}",
            d.state.get().name(),
            d.reason.get().name(),
            a.valid.get() as u8,
            tr.roll_deg,
            tr.pitch_deg,
            tr.yaw_deg,
            a.markers_used,
        )?;
        for n in d.stamp.drops.values() {
            write!(out, ",{n}")?;
        }
        writeln!(
            out,
            ",{},{},{},{},{},{}",
            d.calm_window_start_s,
            d.calm_window_length_s,
            d.watchdog.get() as u8,
            if a.valid.get() { a.deck_height_m } else { f64::NAN },
            tr.deck_heave_m,
            d.heave_rate_mps
        )
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

    /// The columns spelled from the stage table are the ones tools read.
    #[test]
    fn the_header_is_the_one_tools_read() {
        assert_eq!(
            header(),
            "seq,source_index,captured_ns,published_ns,detect_received_ns,detect_finished_ns,\
estimate_received_ns,estimate_finished_ns,decide_received_ns,decide_finished_ns,state,reason,valid,\
roll_deg,pitch_deg,yaw_deg,truth_roll_deg,truth_pitch_deg,truth_yaw_deg,markers,\
drops_capture,drops_bad,drops_detect,drops_estimate,drops_decide,calm_start_s,calm_length_s,watchdog,\
deck_height_m,truth_heave_m,heave_rate_mps"
        );
    }
}
