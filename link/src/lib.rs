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
//! - [`target_relative`]: the decision's deck as TARGET_RELATIVE, for PX4's Vision Target
//!   Estimator (`[link] target_messages`).
//! - [`admission`]: which received frames are believed (rate limit, checksum, MAVLink 2 signing,
//!   the pinned autopilot), every refusal counted by cause; the frames sent, signed.
//! - [`signing`]: MAVLink 2 signing, its key and its timestamps kept across restarts.
//! - [`config`]: `[link]` of the pipeline configuration.

pub mod admission;
pub mod clock;
pub mod config;
pub mod frames;
pub mod incoming;
pub mod outgoing;
pub mod signing;
pub mod target_relative;

pub use config::{Endpoint, LinkConfig, SigningMode};
/// The MAVLink messages deckwatch speaks.
pub use dialect::MavMessage;
/// The MAVLink implementation (connections), for the process that opens the socket.
pub use mavlink;
/// The MAVLink dialect deckwatch speaks (MAVLink 2), named once: every module and test takes its
/// messages from here. The development dialect: common (which it includes, message for message)
/// and TARGET_RELATIVE, which PX4's Vision Target Estimator reads ([`target_relative`]).
pub use mavlink::dialects::development as dialect;
pub use mavlink::MavHeader;

/// A frame as the recorder keeps it (`LinkTraffic`): as sent or received, signature included.
pub fn traffic(
    time_ns: u64,
    outgoing: bool,
    message: &MavMessage,
    frame: &[u8],
) -> deckwatch_common::messages::LinkTraffic {
    use mavlink::Message;
    deckwatch_common::messages::LinkTraffic::new(
        time_ns,
        outgoing,
        message.message_id(),
        message.message_name(),
        frame,
    )
}
