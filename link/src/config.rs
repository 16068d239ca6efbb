//! `[link]` of the pipeline configuration.

use deckwatch_common::InvalidField;
use serde::{Deserialize, Serialize};

/// The MAVLink link to the autopilot (the `link` process).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct LinkConfig {
    /// Start the link process with the pipeline.
    pub enabled: bool,
    /// Where the autopilot is: `udpin:HOST:PORT` (listen, on the loopback unless
    /// `listen_beyond_loopback`: mavlink-router or MAVProxy `--out` pointed at it; replies go to
    /// `peer`, or to the autopilot's own address once three of its frames passed every check),
    /// `udpout:HOST:PORT` (a socket connected to it), `tcpout:HOST:PORT`,
    /// `serial:/dev/ttyAMA0:921600`.
    pub address: String,
    /// `udpin` on an address other than the loopback: anyone on that network can then reach the
    /// link; say so here, and require signing.
    pub listen_beyond_loopback: bool,
    /// `udpout` or `tcpout` to another host without signing: frames to and from that network
    /// unauthenticated. For a bench only; refused otherwise, logged as a warning at every start.
    pub unsigned_beyond_loopback: bool,
    /// With `udpin`: the only address replies go to (`HOST:PORT`); empty: the autopilot's.
    pub peer: String,
    /// The autopilot's MAVLink system id: attitude, position, height and TIMESYNC are taken from
    /// it alone.
    pub autopilot_system_id: u8,
    /// ... and its component id (1: MAV_COMP_ID_AUTOPILOT1).
    pub autopilot_component_id: u8,
    /// MAVLink 2 message signing: `required` (every frame received must be signed with the key,
    /// newer than its stream's last; every frame sent is signed) or `off`.
    pub signing: SigningMode,
    /// The 32-byte key (raw, or 64 hex digits), in a file only its owner can read; the same key
    /// as the autopilot's (README: PX4 and ArduPilot). Set exactly when `signing = "required"`.
    pub signing_key_file: String,
    /// Where each signing stream's newest timestamp is kept across restarts (a replay of frames
    /// captured before a restart is refused after it). Empty: `signing-KEYID.state` in
    /// `$STATE_DIRECTORY` (systemd's `StateDirectory=`), `$XDG_STATE_HOME/deckwatch` or
    /// `~/.local/state/deckwatch`.
    pub signing_state_file: String,
    /// Our link id in the signature (one stream per link id, system and component).
    pub signing_link_id: u8,
    /// Frames a second taken from any one sender (UDP address); the rest are dropped before
    /// any check and counted (`rate-limited`). An autopilot sends a few hundred.
    pub sender_rate_hz: f64,
    /// Our MAVLink system id; 0: the autopilot's (a companion computer joins its vehicle's
    /// system).
    pub system_id: u8,
    /// Our component id (191: MAV_COMP_ID_ONBOARD_COMPUTER).
    pub component_id: u8,
    pub heartbeat_hz: f64,
    /// TIMESYNC requests per second (0: never; the clock then comes from arrival times).
    pub timesync_hz: f64,
    /// LANDING_TARGET (and TARGET_RELATIVE) per second at most (0: one per frame).
    pub landing_target_hz: f64,
    /// The target messages each usable decision sends, at `landing_target_hz` and never on a
    /// stale one: `"landing_target"` (LANDING_TARGET, common dialect: ArduPilot's precision
    /// landing, PX4's landing target estimator) and `"target_relative"` (TARGET_RELATIVE, the
    /// development dialect: PX4 1.18's Vision Target Estimator; README, "PX4's Vision Target
    /// Estimator").
    pub target_messages: Vec<String>,
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
            address: "udpin:127.0.0.1:14540".into(),
            listen_beyond_loopback: false,
            unsigned_beyond_loopback: false,
            peer: String::new(),
            autopilot_system_id: 1,
            autopilot_component_id: 1,
            signing: SigningMode::Off,
            signing_key_file: String::new(),
            signing_state_file: String::new(),
            signing_link_id: 0,
            sender_rate_hz: 2000.0,
            system_id: 0,
            component_id: 191,
            heartbeat_hz: 1.0,
            timesync_hz: 2.0,
            landing_target_hz: 0.0,
            target_messages: vec![LANDING_TARGET_MESSAGE.into()],
            telemetry_hz: 5.0,
            heartbeat_timeout_ms: 3000.0,
            attitude_timeout_ms: 200.0,
        }
    }
}

/// `[link] target_messages`: LANDING_TARGET.
pub const LANDING_TARGET_MESSAGE: &str = "landing_target";
/// `[link] target_messages`: TARGET_RELATIVE.
pub const TARGET_RELATIVE_MESSAGE: &str = "target_relative";

/// `[link] signing`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SigningMode {
    Off,
    Required,
}

/// Where the link's bytes go: `[link] address`, read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// Listen on this UDP address.
    UdpIn(String),
    /// A UDP socket connected to this address.
    UdpOut(String),
    /// A TCP connection to this address.
    TcpOut(String),
    /// A serial port and its baud rate.
    Serial { port: String, baud: u32 },
}

impl Endpoint {
    /// `[link] address` read; the error says what is wrong with it.
    pub fn parse(address: &str) -> Result<Endpoint, String> {
        let (kind, rest) = address
            .split_once(':')
            .ok_or_else(|| format!("`{address}`: must be udpin:HOST:PORT, udpout:HOST:PORT, tcpout:HOST:PORT or serial:DEVICE:BAUD"))?;
        let host_port = |rest: &str| -> Result<String, String> {
            match rest.rsplit_once(':') {
                Some((host, port)) if !host.is_empty() && port.parse::<u16>().is_ok() => Ok(rest.to_string()),
                _ => Err(format!("`{address}`: `{rest}` is not HOST:PORT")),
            }
        };
        match kind {
            "udpin" => Ok(Endpoint::UdpIn(host_port(rest)?)),
            "udpout" => Ok(Endpoint::UdpOut(host_port(rest)?)),
            "tcpout" => Ok(Endpoint::TcpOut(host_port(rest)?)),
            "serial" => {
                let (port, baud) = rest
                    .rsplit_once(':')
                    .ok_or_else(|| format!("`{address}`: must be serial:DEVICE:BAUD"))?;
                let baud = baud
                    .parse::<u32>()
                    .ok()
                    .filter(|b| *b > 0)
                    .ok_or_else(|| format!("`{address}`: `{baud}` is not a baud rate"))?;
                Ok(Endpoint::Serial {
                    port: port.to_string(),
                    baud,
                })
            }
            "udpbcast" | "tcpin" => Err(format!(
                "`{address}`: {kind} answers whoever connects or listens; use udpin (with a pinned peer) or udpout"
            )),
            _ => Err(format!(
                "`{address}`: must be udpin:HOST:PORT, udpout:HOST:PORT, tcpout:HOST:PORT or serial:DEVICE:BAUD"
            )),
        }
    }
}

/// True when `host_port`'s host is a loopback address (`127.x`, `::1`, `localhost`).
fn is_loopback(host_port: &str) -> bool {
    let host = host_port
        .rsplit_once(':')
        .map_or(host_port, |(h, _)| h)
        .trim_start_matches('[')
        .trim_end_matches(']');
    host == "localhost" || host.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

impl LinkConfig {
    /// Whether `[link] target_messages` names `message` ([`LANDING_TARGET_MESSAGE`],
    /// [`TARGET_RELATIVE_MESSAGE`]).
    pub fn sends(&self, message: &str) -> bool {
        self.target_messages.iter().any(|m| m == message)
    }

    pub fn endpoint(&self) -> Result<Endpoint, InvalidField> {
        Endpoint::parse(&self.address).map_err(|e| InvalidField::new("address", e))
    }

    pub fn validate(&self) -> Result<(), InvalidField> {
        let endpoint = self.endpoint()?;
        if let Endpoint::UdpIn(listen) = &endpoint {
            if !is_loopback(listen) && !self.listen_beyond_loopback {
                return Err(InvalidField::new(
                    "address",
                    format!("`{}` listens beyond the loopback: anyone on that network reaches the link; run behind mavlink-router on 127.0.0.1, or set listen_beyond_loopback = true (with signing)", self.address),
                ));
            }
            if self.listen_beyond_loopback && !is_loopback(listen) && self.signing == SigningMode::Off {
                return Err(InvalidField::new(
                    "signing",
                    "must be \"required\" when listen_beyond_loopback = true: an unsigned link open to a network can be fed a false attitude",
                ));
            }
        }
        if let Endpoint::UdpOut(to) | Endpoint::TcpOut(to) = &endpoint {
            let unsigned = self.signing == SigningMode::Off;
            if unsigned && !is_loopback(to) && !self.unsigned_beyond_loopback {
                return Err(InvalidField::new(
                    "signing",
                    format!("must be \"required\" for `{}`: frames to and from another host unsigned can be forged by anyone on that network; for a bench, set unsigned_beyond_loopback = true", self.address),
                ));
            }
        }
        if self.unsigned_beyond_loopback && self.signing == SigningMode::Required {
            return Err(InvalidField::new(
                "unsigned_beyond_loopback",
                "contradicts signing = \"required\"",
            ));
        }
        if !self.peer.is_empty() {
            if !matches!(endpoint, Endpoint::UdpIn(_)) {
                return Err(InvalidField::new(
                    "peer",
                    "only for a udpin address (others have their one peer in `address`)",
                ));
            }
            if self.peer.parse::<std::net::SocketAddr>().is_err() {
                return Err(InvalidField::new(
                    "peer",
                    format!("`{}` is not IP:PORT", self.peer),
                ));
            }
        }
        match (self.signing, self.signing_key_file.is_empty()) {
            (SigningMode::Required, true) => {
                return Err(InvalidField::new(
                    "signing_key_file",
                    "must name the key's file when signing = \"required\"",
                ))
            }
            (SigningMode::Off, false) => {
                return Err(InvalidField::new(
                    "signing",
                    "must be \"required\" when a signing_key_file is configured (a key that is not used protects nothing)",
                ))
            }
            _ => {}
        }
        for (key, id) in [
            ("autopilot_system_id", self.autopilot_system_id),
            ("autopilot_component_id", self.autopilot_component_id),
        ] {
            if id == 0 {
                return Err(InvalidField::new(key, "0 is the broadcast id, not one sender"));
            }
        }
        if !(self.sender_rate_hz >= 100.0 && self.sender_rate_hz <= 100_000.0) {
            return Err(InvalidField::new(
                "sender_rate_hz",
                format!(
                    "must be in [100, 100000] (an autopilot sends a few hundred frames a second), got {}",
                    self.sender_rate_hz
                ),
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
        let known = [LANDING_TARGET_MESSAGE, TARGET_RELATIVE_MESSAGE];
        if let Some(m) = self.target_messages.iter().find(|m| !known.contains(&m.as_str())) {
            return Err(InvalidField::new(
                "target_messages",
                format!("`{m}` is not a target message: \"{LANDING_TARGET_MESSAGE}\" or \"{TARGET_RELATIVE_MESSAGE}\""),
            ));
        }
        if self.target_messages.is_empty() {
            return Err(InvalidField::new(
                "target_messages",
                format!("is empty: the autopilot would be told of no deck; name \"{LANDING_TARGET_MESSAGE}\", \"{TARGET_RELATIVE_MESSAGE}\" or both"),
            ));
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

    #[test]
    fn target_messages_are_named_ones() {
        let d = LinkConfig::default();
        assert!(d.sends(LANDING_TARGET_MESSAGE) && !d.sends(TARGET_RELATIVE_MESSAGE));
        for list in [&["landing_target", "target_relative"][..], &["target_relative"]] {
            let c = LinkConfig {
                target_messages: list.iter().map(|s| s.to_string()).collect(),
                ..LinkConfig::default()
            };
            c.validate().unwrap();
            assert!(c.sends(TARGET_RELATIVE_MESSAGE));
        }
        for (list, said) in [
            (&["landing_target", "target_relativ"][..], "`target_relativ`"),
            (&["LANDING_TARGET"], "`LANDING_TARGET`"),
            (&[], "empty"),
        ] {
            let e = LinkConfig {
                target_messages: list.iter().map(|s| s.to_string()).collect(),
                ..LinkConfig::default()
            }
            .validate()
            .unwrap_err();
            assert_eq!(e.field, "target_messages");
            assert!(e.problem.contains(said), "{e:?}");
        }
    }

    /// Sending to another host is as open as listening beyond the loopback: unsigned, refused
    /// unless a bench says so; the loopback and a serial wire need no signing.
    #[test]
    fn an_unsigned_link_to_another_host_is_refused() {
        let field = |c: LinkConfig| c.validate().map_or_else(|e| e.field, |_| "ok".to_string());
        for address in [
            "udpout:192.0.2.1:14550",
            "tcpout:[2001:db8::1]:5760",
            "udpout:fc.local:14550",
        ] {
            let out = LinkConfig {
                address: address.into(),
                ..LinkConfig::default()
            };
            assert_eq!(field(out.clone()), "signing", "{address}");
            let e = out.validate().unwrap_err();
            assert!(e.to_string().contains("unsigned_beyond_loopback"), "{e}");
            let bench = LinkConfig {
                unsigned_beyond_loopback: true,
                ..out.clone()
            };
            assert_eq!(field(bench.clone()), "ok", "{address}: a bench's opt-in");
            let signed = LinkConfig {
                signing: SigningMode::Required,
                signing_key_file: "/etc/deckwatch/mavlink.key".into(),
                ..out
            };
            assert_eq!(field(signed.clone()), "ok", "{address}");
            let both = LinkConfig {
                unsigned_beyond_loopback: true,
                ..signed
            };
            assert_eq!(field(both), "unsigned_beyond_loopback");
        }
        for address in [
            "udpout:127.0.0.1:14550",
            "tcpout:localhost:5760",
            "serial:/dev/ttyAMA0:921600",
        ] {
            let near = LinkConfig {
                address: address.into(),
                ..LinkConfig::default()
            };
            assert_eq!(field(near), "ok", "{address}");
        }
    }

    #[test]
    fn a_link_open_to_anyone_must_be_said_and_signed() {
        let field = |c: LinkConfig| c.validate().map_or_else(|e| e.field, |_| "ok".to_string());
        let wide = LinkConfig {
            address: "udpin:0.0.0.0:14540".into(),
            ..LinkConfig::default()
        };
        assert_eq!(field(wide.clone()), "address");
        let said = LinkConfig {
            listen_beyond_loopback: true,
            ..wide.clone()
        };
        assert_eq!(field(said.clone()), "signing");
        let signed = LinkConfig {
            signing: SigningMode::Required,
            signing_key_file: "/etc/deckwatch/mavlink.key".into(),
            ..said
        };
        assert_eq!(field(signed.clone()), "ok");
        assert_eq!(
            field(LinkConfig {
                signing_key_file: String::new(),
                ..signed.clone()
            }),
            "signing_key_file"
        );
        assert_eq!(
            field(LinkConfig {
                signing: SigningMode::Off,
                ..signed
            }),
            "signing",
            "a key is configured: signing is required"
        );
        for address in [
            "tcpin:0.0.0.0:5760",
            "udpbcast:255.255.255.255:14550",
            "udpin:14540",
        ] {
            let e = LinkConfig {
                address: address.into(),
                ..LinkConfig::default()
            }
            .validate()
            .unwrap_err();
            assert_eq!(e.field, "address", "{address}");
        }
        assert_eq!(
            field(LinkConfig {
                address: "udpout:127.0.0.1:14550".into(),
                peer: "127.0.0.1:14550".into(),
                ..LinkConfig::default()
            }),
            "peer"
        );
        assert_eq!(
            field(LinkConfig {
                autopilot_system_id: 0,
                ..LinkConfig::default()
            }),
            "autopilot_system_id"
        );
        assert_eq!(
            Endpoint::parse("serial:/dev/ttyAMA0:921600"),
            Ok(Endpoint::Serial {
                port: "/dev/ttyAMA0".into(),
                baud: 921_600
            })
        );
        assert_eq!(
            field(LinkConfig {
                address: "udpin:[::1]:14540".into(),
                ..LinkConfig::default()
            }),
            "ok"
        );
    }
}
