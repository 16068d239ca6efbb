//! Every message's channel, named once. The transport's service between the processes and a
//! flight recording's topic both derive from that one name, so the two can never drift apart.

use super::*;

/// A message that travels on a channel of its own.
pub trait Channel {
    /// The channel's name (`markers`).
    const NAME: &'static str;
    /// The iceoryx2 service between the processes (`deckwatch/markers`).
    const SERVICE: &'static str;
    /// The MCAP topic of a flight recording (`/deckwatch/markers`).
    const TOPIC: &'static str;
}

/// `Type => "name"`: the type's [`Channel`], with the service and the topic spelled from the name.
macro_rules! channels {
    ($($ty:ident => $name:literal),+ $(,)?) => {$(
        impl Channel for $ty {
            const NAME: &'static str = $name;
            const SERVICE: &'static str = concat!("deckwatch/", $name);
            const TOPIC: &'static str = concat!("/deckwatch/", $name);
        }
    )+};
}

channels! {
    // A frame's header; on the bus its pixels ride with it in the same sample.
    FrameHeader => "frame",
    MarkerMessage => "markers",
    AttitudeMessage => "attitude",
    LandingDecision => "decision",
    // The vehicle's attitude samples from the autopilot (the link process).
    VehicleSample => "vehicle",
    // Every MAVLink frame the link sends and receives, while a recorder runs.
    LinkTraffic => "link",
    // The processes' stderr lines, passed on by the launcher while a recorder runs (recorded as
    // `foxglove.Log`).
    StageLog => "log",
    // Every stage process's heartbeat, which the launcher follows (never recorded).
    StageHeartbeat => "heartbeat",
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_channel_is_one_name_on_the_bus_and_in_a_recording() {
        assert_eq!(MarkerMessage::SERVICE, "deckwatch/markers");
        assert_eq!(MarkerMessage::TOPIC, "/deckwatch/markers");
        assert_eq!(FrameHeader::TOPIC, "/deckwatch/frame");
        let names = [
            FrameHeader::NAME,
            MarkerMessage::NAME,
            AttitudeMessage::NAME,
            LandingDecision::NAME,
            VehicleSample::NAME,
            LinkTraffic::NAME,
            StageLog::NAME,
            StageHeartbeat::NAME,
        ];
        let distinct: std::collections::BTreeSet<_> = names.iter().collect();
        assert_eq!(distinct.len(), names.len());
    }
}
