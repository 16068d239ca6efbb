//! The pipeline's messages: what capture, detect, estimate and decide exchange over iceoryx2
//! shared memory. All are `#[repr(C)]` plain data (no pointers), so they are valid in every
//! process that maps them; each type has a versioned iceoryx2 type name, so a stage built from an
//! incompatible revision fails to connect instead of misreading bytes.
//!
//! Every message starts with a [`FrameStamp`]: the frame's sequence number, when it was captured,
//! and when each stage received and finished it (one monotonic clock for all processes), so any
//! consumer downstream can compute per-stage latency. A [`FrameContext`] travels with it: the
//! camera and deck the pixels refer to, the altimeter reading and, for simulated or recorded
//! frames, the ground truth.

mod channels;
mod diagnostics;
mod fields;
mod frame;
mod pipeline;
mod stages;
mod time;
mod wire_checks;

pub use channels::Channel;
pub use diagnostics::*;
pub use frame::*;
pub use pipeline::*;
pub use stages::{PipelineStage, SOURCE, STAGES};
pub use time::*;

use crate::camera::CameraModel;
use crate::deck::DeckLayout;
use crate::ellipse::Ellipse;
use crate::markers::MarkerSet;
use crate::rotation::{Euler313, Quaternion, Rpy};
use crate::truth::GroundTruth;
use crate::vehicle::Compensation;
use crate::wire::{WireBool, WireCode};
use crate::wire_enum;
#[cfg(feature = "shm")]
use iceoryx2::prelude::ZeroCopySend;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_lines_get_a_level_and_survive_any_length() {
        let level = |l: &str| LogLevel::of_line(l);
        assert_eq!(
            level("deckwatch-detect: 60 frames processed, 0 dropped, 0 bad"),
            LogLevel::Info
        );
        assert_eq!(
            level("deckwatch-detect: 60 frames processed, 3 dropped, 0 bad"),
            LogLevel::Warning
        );
        assert_eq!(
            level("deckwatch: detect stopped (signal 9); restarting in 250 ms"),
            LogLevel::Warning
        );
        assert_eq!(level("deckwatch-record: cannot create x.mcap"), LogLevel::Error);
        let long = "é".repeat(400);
        let l = StageLog::new(1, 2, &"n".repeat(40), &long);
        assert_eq!(l.name().len(), StageLog::NAME_BYTES);
        assert!(l.text().len() <= StageLog::TEXT_BYTES && l.text().chars().all(|c| c == 'é'));
        let mut bad = l;
        bad.text_len = u32::MAX;
        assert_eq!(bad.text().len(), StageLog::TEXT_BYTES);
    }

    #[test]
    fn gap_counter_counts_only_its_own_misses() {
        let mut g = GapCounter::from_start();
        // Frames 0 and 1 missed before the first one seen.
        assert_eq!(g.observe(2, 0), 2);
        let mut g = GapCounter::joining();
        assert_eq!(g.observe(500, 3), 0);
        let mut g = GapCounter::from_start();
        assert_eq!(g.observe(0, 0), 0);
        assert_eq!(g.observe(1, 0), 0);
        // 2 and 3 missing, upstream says it dropped one of them.
        assert_eq!(g.observe(4, 1), 1);
        assert_eq!(g.observe(5, 1), 0);
        // Capture restarted: sequence starts again.
        assert_eq!(g.observe(0, 0), 0);
        assert_eq!(g.observe(3, 0), 2);
    }

    #[test]
    fn intervals_need_both_ends() {
        let mut t = StageTimes {
            captured_ns: 100,
            published_ns: 150,
            ..Default::default()
        };
        t[PipelineStage::Detect] = StageSpan {
            received_ns: 160,
            finished_ns: 200,
        };
        assert_eq!(t.interval_ns(LatencyInterval::Capture), Some(50));
        assert_eq!(t.interval_ns(LatencyInterval::Hop), Some(10));
        assert_eq!(
            t.interval_ns(LatencyInterval::Stage(PipelineStage::Detect)),
            Some(40)
        );
        assert_eq!(
            t.interval_ns(LatencyInterval::Stage(PipelineStage::Estimate)),
            None
        );
        assert_eq!(t.interval_ns(LatencyInterval::EndToEnd), None);
        t[PipelineStage::Estimate].finished_ns = 260;
        t[PipelineStage::Decide].finished_ns = 300;
        assert_eq!(
            t.interval_ns(LatencyInterval::Stage(PipelineStage::Estimate)),
            Some(60)
        );
        assert_eq!(
            t.interval_ns(LatencyInterval::Stage(PipelineStage::Decide)),
            Some(40)
        );
        assert_eq!(t.interval_ns(LatencyInterval::EndToEnd), Some(150));
    }

    /// The names a user reads, spelled from the stage table, are the ones the fields had; the
    /// values are in the order of the bytes (the layout of `deckwatch.StageTimes.v1` and
    /// `deckwatch.DropCounts.v1`: a `u64` per name).
    #[test]
    fn per_stage_values_are_named_from_the_table_in_the_order_of_their_bytes() {
        assert_eq!(
            StageTimes::NAMES,
            [
                "captured_ns",
                "published_ns",
                "detect_received_ns",
                "detect_finished_ns",
                "estimate_received_ns",
                "estimate_finished_ns",
                "decide_received_ns",
                "decide_finished_ns",
            ]
        );
        assert_eq!(
            DropCounts::NAMES,
            ["capture", "bad_frames", "detect", "estimate", "decide"]
        );
        let names: Vec<&str> = LatencyInterval::ALL.iter().map(|i| i.name()).collect();
        assert_eq!(
            names,
            [
                "capture",
                "capture->detect",
                "detect",
                "estimate",
                "decide",
                "end-to-end"
            ]
        );
        let values: [u64; TIME_VALUES] = std::array::from_fn(|i| 1 + i as u64);
        let t = StageTimes::from_values(values);
        assert_eq!(
            *bytemuck::from_bytes::<StageTimes>(bytemuck::bytes_of(&values)),
            t
        );
        assert_eq!(t.values(), values);
        assert_eq!(t[PipelineStage::Estimate].finished_ns, 6);
        assert_eq!(t.named()[3], ("detect_finished_ns", 4));
        let counts: [u64; DROP_VALUES] = std::array::from_fn(|i| 10 + i as u64);
        let d = DropCounts::from_values(counts);
        assert_eq!(
            *bytemuck::from_bytes::<DropCounts>(bytemuck::bytes_of(&counts)),
            d
        );
        assert_eq!((d.capture, d.bad_frames, d[PipelineStage::Decide]), (10, 11, 14));
        assert_eq!(d.total(), 60);
        assert_eq!(
            serde_json::to_string(&d).unwrap(),
            r#"{"capture":10,"bad_frames":11,"detect":12,"estimate":13,"decide":14}"#
        );
    }

    #[test]
    fn truth_round_trip() {
        let g = GroundTruth {
            roll_deg: Some(1.0),
            pitch_deg: Some(-2.0),
            yaw_deg: Some(3.0),
            alt_m: Some(5.0),
            ..GroundTruth::default()
        };
        let t = Truth::from_ground_truth(&g, true);
        assert_eq!(
            t.attitude().unwrap().to_degrees().map(|v| v.round()),
            [1.0, -2.0, 3.0]
        );
        assert!(!t.no_deck());
        let none = Truth::from_ground_truth(&GroundTruth::default(), true);
        assert!(none.no_deck());
        assert!(!Truth::UNKNOWN.no_deck());
    }

    #[test]
    fn frame_header_length() {
        let h = FrameHeader {
            width: 10,
            height: 3,
            stride: 16,
            ..Default::default()
        };
        assert_eq!(h.required_len(), 2 * 16 + 10);
    }
}
