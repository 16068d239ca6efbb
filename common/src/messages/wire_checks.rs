//! The wire checks of the messages that carry nested parts (a message received from shared
//! memory is checked field by field before any stage reads it).

use super::*;

impl WireCheck for StageHeartbeat {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        Ok(())
    }
}

impl WireCheck for Truth {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [known]; parts: [])
    }
}

impl WireCheck for VehicleAttitude {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [compensation]; parts: [])
    }
}

impl WireCheck for FrameContext {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [source]; parts: [truth, vehicle])
    }
}

impl WireCheck for FrameHeader {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [pixel_format]; parts: [context])
    }
}

impl WireCheck for MarkerMessage {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: []; parts: [context, markers])
    }
}

impl WireCheck for AlternativeAttitude {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [present, estimator, valid]; parts: [])
    }
}

impl WireCheck for AttitudeMessage {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(
            self;
            codes: [estimator, valid, failure, has_image_ellipse];
            parts: [context, alternative, vehicle]
        )
    }
}

impl WireCheck for VehicleSample {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(self; codes: [clock_method, link_up]; parts: [])
    }
}

impl WireCheck for LandingDecision {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        crate::check_wire_fields!(
            self;
            codes: [state, reason, watchdog];
            parts: [context, attitude]
        )
    }
}
