//! The wire check of every message (a message received from shared memory is checked field by
//! field before any stage reads it), from the one list of their fields.

use super::*;
use crate::camera::Distortion;
use crate::markers::{Marker, RejectCounts};

crate::message_fields!(wire_check_struct);

use crate::wire_check_struct;
// A value per stage (`NAMES` names them): numbers, which hold any bytes.
wire_check_struct!(StageSpan {
    received_ns,
    finished_ns
});
wire_check_struct!(StageTimes {
    captured_ns,
    published_ns,
    stages
});
wire_check_struct!(DropCounts {
    capture,
    bad_frames,
    stages
});
wire_check_struct!(StageHeartbeat { pid, seq, sent_ns });
wire_check_struct!(StageLog {
    time_ns,
    pid,
    level,
    name,
    name_len,
    text,
    text_len
});
wire_check_struct!(LinkTraffic {
    time_ns,
    outgoing,
    msg_id,
    name,
    name_len,
    frame,
    frame_len
});

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::WireCheck;

    /// Every code is checked, however deep, and the error names the path to it.
    #[test]
    fn a_bad_code_anywhere_is_found_and_named() {
        let mut d = LandingDecision::default();
        assert_eq!(d.check_wire(), Ok(()));
        d.attitude.alternative.estimator = WireCode::from_code(99);
        let e = d.check_wire().unwrap_err();
        assert_eq!((e.field.as_str(), e.code), ("attitude.alternative.estimator", 99));

        let mut m = MarkerMessage::default();
        m.markers.markers[3].valid = WireBool::from_byte(2);
        assert_eq!(m.check_wire().unwrap_err().field, "markers.markers[3].valid");

        let mut h = FrameHeader::default();
        h.context.vehicle.compensation = WireCode::from_code(7);
        assert_eq!(h.check_wire().unwrap_err().field, "context.vehicle.compensation");

        let l = StageLog {
            level: WireCode::from_code(1000),
            ..Default::default()
        };
        assert_eq!(l.check_wire().unwrap_err().field, "level");
    }
}
