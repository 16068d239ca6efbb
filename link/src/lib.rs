//! deckwatch's MAVLink link to the autopilot (PX4 or ArduPilot), as a pure library: what the
//! link process (`deckwatch-link`, in the runtime crate) does with each message, without the
//! socket or shared memory.
//!
//! - [`frames`]: MAVLink's NED/FRD frames against deckwatch's (CONVENTIONS.md §7), one place.
//! - [`clock`]: the autopilot's clock on this machine's `CLOCK_MONOTONIC` (TIMESYNC, or arrival
//!   times when the autopilot does not answer).
//! - [`incoming`]: HEARTBEAT, ATTITUDE_QUATERNION/ATTITUDE, TIMESYNC, DISTANCE_SENSOR and
//!   LOCAL_POSITION_NED in; vehicle samples and TIMESYNC answers out; the link's health.
//! - [`outgoing`]: a landing decision as LANDING_TARGET, NAMED_VALUE_FLOAT/INT and STATUSTEXT,
//!   at the configured rates; our HEARTBEAT and TIMESYNC requests.
//! - [`config`]: `[link]` of the pipeline configuration.

pub mod clock;
pub mod config;
pub mod frames;
pub mod incoming;
pub mod outgoing;

pub use config::LinkConfig;
/// The MAVLink implementation (connections), for the process that opens the socket.
pub use mavlink;
/// The MAVLink messages deckwatch speaks (the common dialect, MAVLink 2).
pub use mavlink::dialects::common::MavMessage;
pub use mavlink::MavHeader;

/// A message as the recorder keeps it: its MAVLink 2 frame as sent or received (`LinkTraffic`).
pub fn traffic(
    time_ns: u64,
    outgoing: bool,
    header: &MavHeader,
    message: &MavMessage,
) -> deckwatch_common::messages::LinkTraffic {
    use mavlink::Message;
    let mut frame = Vec::with_capacity(deckwatch_common::messages::LinkTraffic::FRAME_BYTES);
    // Writing into a Vec cannot fail.
    let _ = mavlink::write_v2_msg(&mut frame, *header, message);
    deckwatch_common::messages::LinkTraffic::new(
        time_ns,
        outgoing,
        message.message_id(),
        message.message_name(),
        &frame,
    )
}
