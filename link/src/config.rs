//! `[link]` of the pipeline configuration.

use deckwatch_common::InvalidField;
use serde::{Deserialize, Serialize};

/// The MAVLink link to the autopilot (the `link` process).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct LinkConfig {
    /// Start the link process with the pipeline.
    pub enabled: bool,
    /// Where the autopilot is, in the mavlink crate's address form: `udpin:HOST:PORT` (listen;
    /// answer whoever speaks: mavlink-router or MAVProxy `--out` pointed at it),
    /// `udpout:HOST:PORT` (send to it), `serial:/dev/ttyAMA0:921600`.
    pub address: String,
    /// Our MAVLink system id; 0: the autopilot's (a companion computer joins its vehicle's
    /// system), taken from its first HEARTBEAT.
    pub system_id: u8,
    /// Our component id (191: MAV_COMP_ID_ONBOARD_COMPUTER).
    pub component_id: u8,
    pub heartbeat_hz: f64,
    /// TIMESYNC requests per second (0: never; the clock then comes from arrival times).
    pub timesync_hz: f64,
    /// LANDING_TARGET per second at most (0: one per frame).
    pub landing_target_hz: f64,
    /// Deck attitude and decision as NAMED_VALUE_FLOAT/INT per second (0: off).
    pub telemetry_hz: f64,
    /// The link is lost when no HEARTBEAT came for this long (ms).
    pub heartbeat_timeout_ms: f64,
    /// ... or no attitude for this long (ms).
    pub attitude_timeout_ms: f64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            address: "udpin:0.0.0.0:14540".into(),
            system_id: 0,
            component_id: 191,
            heartbeat_hz: 1.0,
            timesync_hz: 2.0,
            landing_target_hz: 0.0,
            telemetry_hz: 5.0,
            heartbeat_timeout_ms: 3000.0,
            attitude_timeout_ms: 200.0,
        }
    }
}

impl LinkConfig {
    pub fn validate(&self) -> Result<(), InvalidField> {
        let known = ["udpin:", "udpout:", "udpbcast:", "serial:", "tcpin:", "tcpout:"];
        if !known.iter().any(|p| self.address.starts_with(p)) {
            return Err(InvalidField::new(
                "address",
                format!("`{}`: must start with one of {}", self.address, known.join(" ")),
            ));
        }
        for (key, v, max) in [
            ("heartbeat_hz", self.heartbeat_hz, 50.0),
            ("timesync_hz", self.timesync_hz, 50.0),
            ("landing_target_hz", self.landing_target_hz, 1000.0),
            ("telemetry_hz", self.telemetry_hz, 100.0),
        ] {
            if !(v >= 0.0 && v <= max) {
                return Err(InvalidField::new(key, format!("must be in [0, {max}], got {v}")));
            }
        }
        if !(self.heartbeat_hz > 0.0) {
            return Err(InvalidField::new(
                "heartbeat_hz",
                "must be positive (the autopilot drops a silent component)",
            ));
        }
        for (key, v) in [
            ("heartbeat_timeout_ms", self.heartbeat_timeout_ms),
            ("attitude_timeout_ms", self.attitude_timeout_ms),
        ] {
            if !(v > 0.0 && v <= 60_000.0) {
                return Err(InvalidField::new(key, format!("must be in (0, 60000], got {v}")));
            }
        }
        if self.component_id == 0 {
            return Err(InvalidField::new(
                "component_id",
                "0 is the broadcast id, not a component",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_nonsense_is_named() {
        LinkConfig::default().validate().unwrap();
        let bad = LinkConfig {
            address: "14540".into(),
            ..LinkConfig::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "address");
        let bad = LinkConfig {
            telemetry_hz: f64::NAN,
            ..LinkConfig::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "telemetry_hz");
        let bad = LinkConfig {
            attitude_timeout_ms: 0.0,
            ..LinkConfig::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "attitude_timeout_ms");
    }
}
